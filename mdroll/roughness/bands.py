"""1/3-octave bands (IEC 61260, base 10) and band levels in railway-acoustics units.

Bands: band n has the exact centre ``10^(n/10)`` times a reference (1 mm for wavelengths, 1 Hz
for frequencies) and the edges ``centre 10^(-1/20)``, ``centre 10^(+1/20)``; nominal labels are
the R10 preferred numbers (31.5 mm is band 15, exact centre 31.62 mm). A wavelength band maps to
wavenumbers ``q = 2 pi / lambda`` (its lower q edge is its upper wavelength edge), a frequency
band to ``q = 2 pi f / v0``.

Band-integration rule (one rule for every band spectrum of mdroll): the mean square of a series
in band b is the sum, over the grid wavenumbers ``q_k = k dq`` (k >= 1) whose q_k lies in the
band's edges ``[q_lo, q_hi)``, of the one-sided PSD times the bin width,
``ms_b = sum_k 2 C(q_k) dq`` (C two-sided, physics.md section 3: the factor 2 counts -q_k; the
same mean square per rad/s is ``sum 2 C(omega_k) d omega`` with ``C(omega) = C(q) / v0``).
A band with no grid wavenumber has no level (NaN). Levels:

* roughness ``L_r = 10 lg(ms / r0^2)``, r0 = 1 um (dB re 1 um), against wavelength;
* force ``L_F = 10 lg(ms / F0^2)``, F0 = 1 N (dB re 1 N), against frequency;
* acceleration ``L_a = 10 lg(ms / a0^2)``, a0 = 1e-6 m/s^2 (dB re 1e-6 m/s^2), against frequency;
* velocity ``L_v = 10 lg(ms / v0^2)``, v0 = 1 nm/s (dB re 1 nm/s, ISO 1683), against frequency.
"""

from __future__ import annotations

import math

import numpy as np

from .. import physics

#: References of the levels: roughness 1 um (m), force 1 N, acceleration 1e-6 m/s^2, velocity 1 nm/s.
REFERENCES = {"roughness": 1e-6, "force": 1.0, "acceleration": 1e-6, "velocity": 1e-9}
#: Half a 1/3-octave band (base 10) as a factor: the edges are centre * 10^(-+1/20).
HALF_BAND = 10.0 ** (1.0 / 20.0)
_R10 = (1.0, 1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0)


def band_numbers(centres) -> np.ndarray:
    """Band numbers n of 1/3-octave centres (nominal or exact, in the unit of the reference:
    mm or Hz): ``n = round(10 lg centre)``."""
    return np.rint(10.0 * np.log10(np.asarray(centres, dtype=np.float64))).astype(np.int64)


def band_centres(n) -> np.ndarray:
    """Exact centres ``10^(n/10)`` (mm or Hz) of bands n."""
    return 10.0 ** (np.asarray(n, dtype=np.float64) / 10.0)


def nominal(n) -> np.ndarray:
    """Nominal labels of bands n (R10 preferred numbers: 31.5, 12.5, 6.3, 0.8, ...)."""
    n = np.asarray(n, dtype=np.int64)
    return np.array([_R10[k % 10] * 10.0 ** (k // 10) for k in n.ravel()]).reshape(n.shape)


def wavelength_band_edges_q(n) -> tuple[np.ndarray, np.ndarray]:
    """Wavenumber edges (q_lo, q_hi) (rad/m) of wavelength bands n (centre 10^(n/10) mm):
    ``q_lo = 2 pi / (lambda_n 10^(1/20))``, ``q_hi = 2 pi / (lambda_n 10^(-1/20))``."""
    lam = band_centres(n) * 1e-3
    return physics.TWO_PI / (lam * HALF_BAND), physics.TWO_PI * HALF_BAND / lam


def frequency_band_edges_q(n, v0: float) -> tuple[np.ndarray, np.ndarray]:
    """Wavenumber edges (q_lo, q_hi) (rad/m) of frequency bands n (centre 10^(n/10) Hz) at speed v0
    (m/s): ``q = 2 pi f / v0``."""
    f = band_centres(n)
    return physics.TWO_PI * f / (HALF_BAND * v0), physics.TWO_PI * f * HALF_BAND / v0


def wavelength_bands_of_grid(dq: float, q_top: float) -> np.ndarray:
    """Wavelength band numbers (longest first) whose whole band lies on a grid of spacing dq up to
    q_top (rad/m): lowest edge at least dq, highest edge at most q_top."""
    longest = math.floor(10.0 * math.log10(physics.TWO_PI / dq * 1e3) - 0.5)
    shortest = math.ceil(10.0 * math.log10(physics.TWO_PI / q_top * 1e3) + 0.5)
    return np.arange(longest, shortest - 1, -1, dtype=np.int64)


def frequency_bands_of_grid(dq: float, q_top: float, v0: float) -> np.ndarray:
    """Frequency band numbers (lowest first) whose whole band lies on the grid: see
    :func:`wavelength_bands_of_grid`; f = q v0 / (2 pi)."""
    lowest = math.ceil(10.0 * math.log10(dq * v0 / physics.TWO_PI) + 0.5)
    highest = math.floor(10.0 * math.log10(q_top * v0 / physics.TWO_PI) - 0.5)
    return np.arange(lowest, highest + 1, dtype=np.int64)


def band_mean_squares(q, psd, dq: float, q_lo, q_hi) -> tuple[np.ndarray, np.ndarray]:
    """Mean squares ``sum 2 C(q_k) dq`` over the grid wavenumbers ``q_lo <= q_k < q_hi`` of each band
    (module docstring), and the number of bins in each (NaN where none).

    ``q`` (rad/m, the grid k dq), ``psd`` two-sided C at q (unit^2 m), ``dq`` (rad/m), ``q_lo``,
    ``q_hi`` band edges (rad/m). Returns (mean squares in unit^2, bin counts)."""
    q = np.asarray(q, dtype=np.float64)
    psd = np.asarray(psd, dtype=np.float64)
    cumulative = np.concatenate([[0.0], np.cumsum(2.0 * psd * dq)])
    lo = np.searchsorted(q, np.asarray(q_lo), side="left")
    hi = np.searchsorted(q, np.asarray(q_hi), side="left")
    counts = hi - lo
    out = cumulative[hi] - cumulative[lo]
    return np.where(counts > 0, out, np.nan), counts


def level_db(mean_square, reference: float) -> np.ndarray:
    """``10 lg(mean_square / reference^2)`` (dB re reference)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return 10.0 * np.log10(np.asarray(mean_square, dtype=np.float64) / reference**2)


def roughness_levels(q, psd, dq: float, n) -> tuple[np.ndarray, np.ndarray]:
    """Roughness levels L_r (dB re 1 um) of wavelength bands n from a roughness PSD (m^3) on the
    grid q; and the bin counts."""
    ms, counts = band_mean_squares(q, psd, dq, *wavelength_band_edges_q(n))
    return level_db(ms, REFERENCES["roughness"]), counts


def frequency_levels(q, psd, dq: float, n, v0: float, quantity: str) -> tuple[np.ndarray, np.ndarray]:
    """Levels of ``quantity`` ("force": dB re 1 N; "acceleration": dB re 1e-6 m/s^2; "velocity": dB
    re 1 nm/s) in frequency bands n (Hz) at speed v0 from its PSD per rad/m on the grid q; and the
    bin counts."""
    ms, counts = band_mean_squares(q, psd, dq, *frequency_band_edges_q(n, v0))
    return level_db(ms, REFERENCES[quantity]), counts
