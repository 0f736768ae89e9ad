"""The law's checks for ``mdroll validate --check lowband_law.checks:checks`` (and the
``mdroll.checks`` entry point): one ensemble spec, the prediction, a band and a tolerance."""

from mdroll import EnsembleSpec, Params
from mdroll.validation import Band, Check

from . import low_band_psd

#: 16 periodic lines of 2 m at 20 um springs: about 2 s on one CPU core.
SPEC = EnsembleSpec(Params(L=2.0, dx=20e-6), seed=1, realizations=16, boundary="periodic")
#: The bins q < q_min / 20 (q a < 0.32), where the plateau should hold.
BAND = Band(0.0, 0.05, "q_min")


def checks():
    return [Check("corrected eq 58 plateau", SPEC, low_band_psd, BAND, allowance=0.10, equation="eq 58 / 9.6")]
