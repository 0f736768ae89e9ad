"""How many realizations a run averages: the default count, its check, and the one reader of a
parameters dict (a TOML file, the CLI's ``--set`` values, a spectra file's or a spec's metadata),
which may name the count beside the :class:`~mdroll.Params` fields."""

from __future__ import annotations

from ..arguments import check_integer
from ..params import Params

#: Realizations a run averages when it names no count (``run_ensemble(realizations=None)``, the
#: CLI without ``--realizations``): the thesis's ensemble.
DEFAULT_REALIZATIONS = 300
#: The key of a parameters dict (a TOML file, ``--set``, a file written before the count left
#: :class:`~mdroll.Params`) that holds the run's realization count rather than a parameter.
COUNT_KEY = "n_real"


def check_count(name: str, value) -> int:
    """A realization count: an integer of at least 1, else a :class:`ParameterError` naming ``name``."""
    return check_integer(name, value, 1, "realizations")


def read_params(data) -> tuple[Params, int | None]:
    """The one reader of a parameters dict (a TOML table, the CLI's ``--set`` values, a spectra
    file's or a spec's metadata): the :class:`Params` of its fields, and the realization count
    its :data:`COUNT_KEY` names (checked by :func:`check_count`), or None where it names none."""
    values = dict(data)
    count = values.pop(COUNT_KEY, None)
    return Params(**values), None if count is None else check_count(COUNT_KEY, count)
