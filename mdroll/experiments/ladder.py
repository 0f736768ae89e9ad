"""The size ladder every experiment climbs: ``test`` (seconds on a CPU, for the test suite),
``quick`` (minutes on a CPU) and ``full`` (the thesis's scale, on a GPU).

An experiment states what each rung means for it (its line lengths, realizations, sweeps) in a
:class:`Ladder`; it may leave a rung out where that size has no use (the scaling study has no
``test`` rung: its tests build their own tiny rung).
"""

from __future__ import annotations

from ..errors import ParameterError

#: The rungs, smallest first.
SIZES = ("test", "quick", "full")


class Ladder(dict):
    """An experiment's parameters per rung: ``Ladder(quick=..., full=...)``; ``ladder[size]``
    is the rung's parameters (any object the experiment reads), ``ladder.rung(size)`` the same
    with a one-line :class:`~mdroll.errors.ParameterError` for a size the ladder lacks."""

    def __init__(self, **rungs):
        unknown = [size for size in rungs if size not in SIZES]
        if unknown:
            raise ValueError(f"rungs {unknown} are not on the ladder {SIZES}")
        super().__init__((size, rungs[size]) for size in SIZES if size in rungs)

    def rung(self, size: str):
        """The parameters of ``size``, or ParameterError naming the sizes this ladder has."""
        if size not in self:
            raise ParameterError(f"size = {size!r} is not allowed: choose one of {', '.join(map(repr, self))}")
        return self[size]
