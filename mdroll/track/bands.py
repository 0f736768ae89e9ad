"""1/3-octave bands and levels (IEC 61260 base-10 bands; ISO 1683 reference values)."""

from __future__ import annotations

import numpy as np

from mdroll.physics import TWO_PI

#: ISO 1683 reference values: velocity 1 nm/s; force 1 N and 1 uN.
REF_VELOCITY = 1e-9
REF_FORCE = 1.0
REF_FORCE_MICRO = 1e-6


def third_octave_centres(f_lo, f_hi):
    """Exact base-10 1/3-octave centres ``1000 x 10^(n/10)`` Hz from the band holding f_lo to the
    one holding f_hi (nominal names: 100, 125, 160 ... Hz)."""
    n = np.arange(np.round(10 * np.log10(f_lo / 1000.0)), np.round(10 * np.log10(f_hi / 1000.0)) + 1)
    return 1000.0 * 10.0 ** (n / 10.0)


def per_hz_one_sided(psd_q, v):
    """A two-sided PSD per rad/m of wavenumber (unit^2 m) as a one-sided PSD per Hz (unit^2 / Hz)
    at speed v (m/s): ``G(f) = 2 C(q) dq/df = 4 pi C(q) / v``."""
    return 2.0 * TWO_PI * np.asarray(psd_q, dtype=np.float64) / v


def band_levels(f, psd_hz, centres, reference):
    """1/3-octave levels (dB re ``reference``) of a one-sided PSD per Hz sampled at increasing
    ``f`` (Hz), fine enough to resolve it: the mean square of each band, the trapezoid integral
    of the PSD between the band edges ``f_c 10^(-1/20)`` and ``f_c 10^(1/20)``, as
    ``10 log10(ms / reference^2)``. ``f`` must cover every band."""
    f = np.asarray(f, dtype=np.float64)
    psd_hz = np.asarray(psd_hz, dtype=np.float64)
    centres = np.asarray(centres, dtype=np.float64)
    lo, hi = centres * 10 ** (-1 / 20), centres * 10 ** (1 / 20)
    if lo[0] < f[0] or hi[-1] > f[-1]:
        raise ValueError(f"the PSD's frequencies [{f[0]:.4g}, {f[-1]:.4g}] Hz must cover the bands "
                         f"[{lo[0]:.4g}, {hi[-1]:.4g}] Hz")
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (psd_hz[1:] + psd_hz[:-1]) * np.diff(f))])
    mean_square = np.interp(hi, f, cumulative) - np.interp(lo, f, cumulative)
    return 10.0 * np.log10(mean_square / reference**2)
