"""The inverse problem: roughness and contact parameters from a measured or simulated spectrum.

:func:`fit` estimates H, q_min, a, h0, E* (and whatever else is declared free) from an averaged
acceleration or force PSD. The modules, from the data up:

* :mod:`.observed`: the :class:`Spectrum` to invert; :func:`read_spectrum` reads mdroll
  ``spectra.npz`` files and tables.
* :mod:`.forward_model`: the expected PSD (eq 40 through the wheel's response, the low band of
  eq 48) and the parameters it takes.
* :mod:`.band`, :mod:`.likelihood`: the band fitted, the Whittle likelihood and the goodness of fit.
* :mod:`.starting_values`, :mod:`.intervals`, :mod:`.profiles`: where the search starts, the
  calibrated covariance and intervals at the estimate, and the profile likelihoods.
* :mod:`.correction`, :mod:`.discrepancy`, :mod:`.fill_check`: the simulated correction of the
  closed form, the model discrepancy of a table, and the check of the noise floor's trade with
  the contact-radius jitter.
* :mod:`.fit`: :func:`fit`, which runs them; :mod:`.result`: the :class:`FitResult` it returns.
* :mod:`.roundtrip`: the parametric bootstrap and the round trips that measure how well it all works.
"""

from .fit import fit
from .forward_model import PARAMETERS, default_free, expected_psd
from .observed import Spectrum, from_result, read_spectrum, read_table, table_spectrum, write_table
from .result import FitResult

__all__ = ["FitResult", "PARAMETERS", "Spectrum", "default_free", "expected_psd", "fit", "from_result",
           "read_spectrum", "read_table", "table_spectrum", "write_table"]
