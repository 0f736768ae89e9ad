"""The band of a spectrum that the fit reads: the default one, or a given one checked.

The default band of a simulated spectrum stops at :data:`SIMULATED_BAND_TOP` of its Nyquist
frequency, and that of an acceleration spectrum starts at :data:`RESONANCE_MARGIN` times its
contact resonance (:func:`find_resonance`); docs/inverse.md, "The band's ends", says why.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError
from .observed import Spectrum

#: Default top of the band of a simulated spectrum, as a fraction of its Nyquist frequency pi/dt
#: (25 q_min at the defaults, where physics.md finds eq 40 within 1 % of the direct sum): above
#: it the contact's non-linearity and the springs' discretization change the spectrum's slope,
#: which biases H the more, the higher the band reaches (docs/inverse.md, "The band's ends").
SIMULATED_BAND_TOP = 0.05
#: The default band of an acceleration spectrum starts at this multiple of its resonance: the
#: periodogram of a finite record of an (almost) undamped resonance is not |A/F|^2 times the
#: force's near omega_0 (the record's end states cancel part of the peak), while above it the
#: response's shape ((1 - omega_0^2 / omega^2)^-2: x1.78 at 2 omega_0) still fixes E* with m.
RESONANCE_MARGIN = 2.0


def resolve_band(band, spectrum: Spectrum) -> tuple[float, float]:
    """``band`` = (omega_lo, omega_hi) in rad/s, checked, or for None the default band of
    ``spectrum`` (the module docstring). A bad band ends with a ParameterError."""
    if band is None:
        top = spectrum.omega[-1] if spectrum.dt is None else min(spectrum.omega[-1], SIMULATED_BAND_TOP * math.pi / spectrum.dt)
        bottom = spectrum.omega[0]
        resonance = find_resonance(spectrum.omega, spectrum.psd) if spectrum.quantity == "accel" else None
        if resonance is not None:
            bottom = max(bottom, RESONANCE_MARGIN * resonance)
        return float(bottom), float(top)
    try:
        lo, hi = (float(b) for b in band)
    except (TypeError, ValueError):
        raise ParameterError(f"band = {band!r} is not allowed: give (omega_lo, omega_hi) in rad/s") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise ParameterError(f"band = ({lo!r}, {hi!r}) rad/s is not allowed: it needs 0 <= omega_lo < omega_hi, finite")
    return lo, hi


def find_resonance(omega, data, sharpness: float = 5.0):
    """The contact resonance of an acceleration spectrum (rad/s), or None: among the 500 largest
    local maxima of the lower half (log) of ``omega``, the one whose PSD exceeds most the larger of the
    medians over its neighbours within 5 % (at least 3 bins) below and above, if by ``sharpness``
    times: a resonance falls steeply on both sides; the onset of the high band at q_min v0 and
    the broad lobes of sin^2(q a) do not."""
    lower = np.flatnonzero(omega <= math.sqrt(omega[0] * omega[-1]))
    if lower.size < 3:
        return None
    lower = lower[(lower > 0) & (lower < data.size - 1)]
    peaks = lower[(data[lower] > data[lower - 1]) & (data[lower] >= data[lower + 1])]
    candidates = peaks[np.argsort(data[peaks])[-500:]]
    best, best_ratio = None, 0.0
    for k in candidates:
        width = max(3, int(np.searchsorted(omega, 1.05 * omega[k]) - k))
        left, right = data[max(0, k - width):k], data[k + 1:k + 1 + width]
        if left.size == 0 or right.size == 0:
            continue
        ratio = data[k] / max(float(np.median(left)), float(np.median(right)), 1e-300)
        if ratio > best_ratio and 0 < k < data.size - 1:
            best, best_ratio = k, ratio
    return float(omega[best]) if best is not None and best_ratio >= sharpness else None
