"""Validation: analytic predictions checked against ensembles (physics.md section 7).

The check API (:mod:`.api`): a :class:`Check` is an :class:`~mdroll.EnsembleSpec`, a prediction,
a :class:`Band`, a comparison and a tolerance; :func:`run_checks` runs the built-ins
(:mod:`.checks`) and any others (:mod:`.discovery`); :class:`EnsembleCache` keeps ensembles on
disk between runs; :mod:`.report` writes the table, ``validation.json`` and JUnit XML.
"""

from ..errors import PredictionError
from .api import BAND_UNITS, COMPARISONS, Band, Check, CheckResult
from .cache import EnsembleCache, default_cache_dir
from .checks import CHECKS, SIZES, Context, ValidationSize
from .discovery import ENTRY_POINT_GROUP, checks_from_toml, run_checks, select
from .ensembles import EnsembleSource

__all__ = ["BAND_UNITS", "CHECKS", "COMPARISONS", "ENTRY_POINT_GROUP", "SIZES", "Band", "Check", "CheckResult",
           "Context", "EnsembleCache", "EnsembleSource", "PredictionError", "ValidationSize", "checks_from_toml",
           "default_cache_dir", "run_checks", "select"]
