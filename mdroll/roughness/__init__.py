"""Roughness spectra beyond the pure power law, measured profiles, and railway-acoustics units.

The models (:mod:`.models`), the 1/3-octave bands (:mod:`.bands`), the reference tables
(:mod:`.tables`), measured profiles (:mod:`.measured`) and the contact filter (:mod:`.filters`)
are numpy/scipy only (the bottom layer, beside :mod:`mdroll.params`); the line generator uses
them. The ensemble studies (spectrum checks, the dB round trip, eq 63, coupled vs decoupled) and
the band outputs of a run are in :mod:`mdroll.railway`, above the ensemble layer.
"""

from .models import (GEIKE_LAMBDA, BandLevels, BandLimited, FromCallable, PowerLaw, RollOff, RoughnessSpectrum,
                     Tabulated, areal_to_profile, from_params, grid_psd, iso3095, line_rms, linear_force_psd,
                     mdr_to_profile_ratio, mode_amplitude_table, resolve_level)

__all__ = ["GEIKE_LAMBDA", "BandLevels", "BandLimited", "FromCallable", "PowerLaw", "RollOff", "RoughnessSpectrum",
           "Tabulated", "areal_to_profile", "from_params", "grid_psd", "iso3095", "line_rms", "linear_force_psd",
           "mdr_to_profile_ratio", "mode_amplitude_table", "resolve_level"]
