"""The inverse problem: roughness and contact parameters from a measured or simulated spectrum.

:func:`fit` estimates H, q_min, a, h0, E* (and whatever else is declared free) from an averaged
acceleration or force PSD by the Whittle likelihood (:mod:`mdroll.inverse.fit`), with the forward
model of :mod:`mdroll.inverse.forward_model` (eq 40 through the wheel's response, the low band of eq 48);
:func:`read_spectrum` reads mdroll ``spectra.npz`` files and tables; :func:`bootstrap` refits
simulations at the estimate; :mod:`mdroll.inverse.roundtrip` measures how well it all works.
"""

from .fit import FitResult, fit
from .forward_model import PARAMETERS, default_free, expected_psd
from .observed import Spectrum, from_result, read_spectrum, read_table, table_spectrum, write_table

__all__ = ["FitResult", "PARAMETERS", "Spectrum", "default_free", "expected_psd", "fit", "from_result",
           "read_spectrum", "read_table", "table_spectrum", "write_table"]
