"""Track models in the frequency domain: a Timoshenko rail on pads, sleepers and ballast,
continuously or discretely supported; receptances, decay rates and the linear wheel/rail chain.

numpy only; imports :mod:`mdroll.physics` and :mod:`mdroll.params` and nothing above.
"""

from .bands import REF_FORCE, REF_FORCE_MICRO, REF_VELOCITY, band_levels, per_hz_one_sided, third_octave_centres
from .beam import continuous_decay_rate, continuous_receptance, cut_on_frequencies, support_stiffness
from .interaction import chain_for_params, contact_filter, linear_chain
from .parameters import PRESETS, SOURCES, SUPPORTS, UIC60, Track
from .periodic import discrete_decay_rate, discrete_receptance, floquet_multipliers, pinned_pinned_frequency
from .response import POSITIONS, decay_rate, iso3095_decay_limit, receptance

__all__ = ["POSITIONS", "PRESETS", "REF_FORCE", "REF_FORCE_MICRO", "REF_VELOCITY", "SOURCES", "SUPPORTS",
           "UIC60", "Track", "band_levels", "chain_for_params", "contact_filter", "continuous_decay_rate",
           "continuous_receptance", "cut_on_frequencies", "decay_rate", "discrete_decay_rate",
           "discrete_receptance", "floquet_multipliers", "iso3095_decay_limit", "linear_chain",
           "per_hz_one_sided", "pinned_pinned_frequency", "receptance", "support_stiffness",
           "third_octave_centres"]
