"""Roughness spectra beyond the pure power law, measured profiles, and railway-acoustics units.

The spectrum interface and its kinds (:mod:`.kinds`), the spectra given by a formula
(:mod:`.analytic`) or by data (:mod:`.tabulated`), their values on a line's grid
(:mod:`.line_grid`), the 1/3-octave bands (:mod:`.bands`), the railway reference tables
(:mod:`.tables`, shipped as ``railway_tables.tsv`` with their sources), measured profiles
(:mod:`.measured`) and the contact filter (:mod:`.filters`) are numpy/scipy only (the bottom
layer, beside :mod:`mdroll.params`); the line generator uses them. The ensemble studies
(spectrum checks, the dB round trip, eq 63, coupled vs decoupled) and the band outputs of a run
are in :mod:`mdroll.railway`, above the ensemble layer.
"""

from .analytic import BandLimited, FromCallable, PowerLaw, RollOff
from .kinds import GEIKE_LAMBDA, RoughnessSpectrum, areal_to_profile, mdr_to_profile_ratio
from .line_grid import from_description, from_params, grid_psd, line_rms, linear_force_psd, mode_amplitude_table, \
    resolve_level
from .tabulated import BandLevels, Tabulated, iso3095

__all__ = ["GEIKE_LAMBDA", "BandLevels", "BandLimited", "FromCallable", "PowerLaw", "RollOff", "RoughnessSpectrum",
           "Tabulated", "areal_to_profile", "from_description", "from_params", "grid_psd", "iso3095", "line_rms",
           "linear_force_psd", "mdr_to_profile_ratio", "mode_amplitude_table", "resolve_level"]
