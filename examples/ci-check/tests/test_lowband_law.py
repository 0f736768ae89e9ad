"""The law checked with the mdroll pytest plugin: the ten lines a CI needs."""

from mdroll.testing import assert_spectrum_matches

from lowband_law import low_band_psd
from lowband_law.checks import BAND, SPEC


def test_corrected_plateau(mdroll_ensemble):
    result = mdroll_ensemble(SPEC)  # run once on --mdroll-device, then read from the ensemble cache
    assert_spectrum_matches(result, low_band_psd, BAND, allowance=0.10)
