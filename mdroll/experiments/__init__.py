"""The one experiment framework of the analyses: validation checks, thesis studies, railway
studies, the scaling study and the inverse round trips are each a small module of physics and
claims on top of it.

- :mod:`.ladder`: the size ladder ``test`` / ``quick`` / ``full``; each experiment states its own
  parameters per rung in a :class:`Ladder`.
- :mod:`.registry`: :class:`Registry`, experiments by name, with one error for an unknown name.
- :mod:`.record`: the JSON record's provenance (mdroll version, git commit, device, date,
  parameters, seed, size), its atomic writer and its checked reader (:class:`RecordKind`).
- :mod:`.table`: the one table writer (aligned text and Markdown).
- :mod:`.figures`: :class:`Figure` and the one PNG writer.

Adding an experiment: write its physics as a function of a rung's parameters (and the seed and
device) returning a JSON-ready dict or the package's own result records; state its rungs in a
``Ladder(test=..., quick=..., full=...)``; register it in its package's :class:`Registry`; start
its record with ``provenance(device, size, seed, rung)``; write the record with
:func:`write_json`, its tables with :func:`text_table` or :func:`markdown_table` and its
figures as :class:`Figure` objects with :func:`write_figure`; whatever reads records back states
their fields in a :class:`RecordKind` and reads them with :func:`read_record`. The thesis studies
(:mod:`mdroll.studies`) are the fullest example.
"""

from .figures import Figure, render_png, write_figure, write_figures
from .ladder import SIZES, Ladder
from .record import RecordKind, git_commit, provenance, read_record, write_json
from .registry import Registry
from .table import markdown_table, text_table

__all__ = ["SIZES", "Figure", "Ladder", "RecordKind", "Registry", "git_commit", "markdown_table", "provenance",
           "read_record", "render_png", "text_table", "write_figure", "write_figures", "write_json"]
