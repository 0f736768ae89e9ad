"""The one experiment framework of the analyses: validation checks, thesis studies, railway
studies, the scaling study and the inverse round trips are each a small module of physics and
claims on top of it.

- :mod:`.ladder`: the size ladder ``test`` / ``quick`` / ``full``; each experiment states its own
  parameters per rung in a :class:`Ladder`.
- :mod:`.registry`: :class:`Registry`, experiments by name, with one error for an unknown name.
- :mod:`.record`: the JSON record's provenance (mdroll version, git commit, device, date,
  parameters, seed, size) and its atomic writer.
- :mod:`.table`: the one table writer (aligned text and Markdown).
- :mod:`.figures`: :class:`Figure` and the one PNG writer.
"""

from .figures import Figure, render_png, write_figure, write_figures
from .ladder import SIZES, Ladder
from .record import git_commit, provenance, write_json
from .registry import Registry
from .table import markdown_table, text_table

__all__ = ["SIZES", "Figure", "Ladder", "Registry", "git_commit", "markdown_table", "provenance", "render_png",
           "text_table", "write_figure", "write_figures", "write_json"]
