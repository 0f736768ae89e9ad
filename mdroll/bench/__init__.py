"""``mdroll bench``: the scaling study of the force algorithms (:mod:`.study`), its clocks
(:mod:`.clocks`) and its table and plot (:mod:`.report`)."""

from .clocks import HOLD_S, device_timed, timed
from .report import expected_exponent, format_table, plot_study, refinement_note, study_figure
from .study import (
    SIZES,
    ScalingSize,
    compile_time,
    fit_exponent,
    force_time,
    memory_per_realization,
    point_limit,
    run_study,
    thesis_scale,
)

__all__ = [
    "HOLD_S",
    "SIZES",
    "ScalingSize",
    "compile_time",
    "device_timed",
    "expected_exponent",
    "fit_exponent",
    "force_time",
    "format_table",
    "memory_per_realization",
    "plot_study",
    "point_limit",
    "refinement_note",
    "run_study",
    "study_figure",
    "thesis_scale",
    "timed",
]
