"""The MDR against the 3-D boundary-element reference (``mdroll study mdr-vs-3d``,
docs/mdr-vs-3d.md): the problems both models solve (:mod:`.problems`), the band comparison
(:mod:`.compare`), the linear contact filters in closed form (:mod:`.linear`), the study
(:mod:`.study`) and its figures."""

from .study import mdr_vs_3d

__all__ = ["mdr_vs_3d"]
