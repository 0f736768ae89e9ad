"""Measured roughness profiles: reading, detrending, the Welch PSD with its confidence band, and
the profile as a line of the MDR model.

A measured profile is a line scan along the rail (kind "profile"); by the rail assumption of
:mod:`mdroll.roughness.kinds` its spectrum is also the MDR line's.
"""

from __future__ import annotations

import math

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import signal, stats

from .. import physics
from ..errors import ParameterError
from ..params import Params
from .tabulated import Tabulated, read_numbers, read_two_columns


#: A measured profile's sample spacing (m): a trolley samples every millimetre or finer, never metres.
MIN_DX, MAX_DX = 1e-7, 0.01
#: The largest RMS height (m) a rail or wheel roughness profile has; above, the unit is wrong.
MAX_PROFILE_RMS = 1e-3
#: The most samples a profile may hold (a 100 km scan at 1 mm).
MAX_PROFILE_POINTS = 100_000_000


@dataclass(frozen=True)
class Profile:
    """A uniformly sampled, detrended profile: heights ``h`` (m) at ``x_i = i dx`` (dx in m)."""

    h: np.ndarray
    dx: float
    source: str = ""

    @property
    def length(self) -> float:
        return self.h.size * self.dx


def load_profile(path, dx: float | None = None) -> Profile:
    """A profile from a CSV or NPY file: two columns x (m), h (m) on a uniform grid, or one column
    h (m) with ``dx`` (m) given. The least-squares line is removed (scipy.signal.detrend)."""
    file = Path(path)
    if not file.is_file():
        raise ParameterError(f"profile = {str(path)!r}: " + ("a directory, not a file" if file.is_dir() else "no such file"))
    if dx is None:
        x, h = read_two_columns(file, "profile")
        steps = np.diff(x)
        if x.size < 16 or not np.all(np.isfinite(x)) or np.any(steps <= 0) or \
                not np.allclose(steps, steps.mean(), rtol=1e-6):
            raise ParameterError(f"profile = {str(path)!r}: x must increase uniformly over at least 16 points "
                                 "(resample it, or give one column h and dx)")
        dx = float(steps.mean())
        if not MIN_DX <= dx <= MAX_DX:
            raise ParameterError(f"profile = {str(path)!r}: x steps by {dx:.4g}, outside a profile's spacing "
                                 f"{MIN_DX:g} .. {MAX_DX:g} m: give x in metres")
    else:
        if not (isinstance(dx, (int, float)) and dx > 0 and np.isfinite(dx)):
            raise ParameterError(f"dx = {dx!r} is not allowed: the profile's spacing must be a positive length (m)")
        if not MIN_DX <= dx <= MAX_DX:
            raise ParameterError(f"dx = {dx!r} m is not allowed: a profile's spacing lies in {MIN_DX:g} .. {MAX_DX:g} m "
                                 "(give it in metres)")
        h = read_numbers(file, "profile")
        if h.ndim == 2 and h.shape[1] == 1:
            h = h[:, 0]
        if h.ndim != 1:
            raise ParameterError(f"profile = {str(path)!r} has {h.shape[1] if h.ndim == 2 else h.ndim} columns: --dx "
                                 "(dx) is for one column of heights; drop it to read the columns x, h")
    return make_profile(h, dx, str(path))


def make_profile(h, dx: float, source: str = "") -> Profile:
    """A :class:`Profile` from heights h (m) spaced dx (m), detrended (least-squares line removed)."""
    h = np.asarray(h, dtype=np.float64)
    if h.ndim != 1 or h.size < 16 or not np.all(np.isfinite(h)):
        raise ParameterError(f"profile {source!r}: heights must be a finite 1D series of at least 16 points")
    if h.size > MAX_PROFILE_POINTS:
        raise ParameterError(f"profile {source!r}: {h.size} points, more than {MAX_PROFILE_POINTS}; split it")
    scale = float(np.max(np.abs(h)))
    h = signal.detrend(h, type="linear")
    rms = float(np.sqrt(np.mean(h * h)))
    if rms <= 1e-12 * scale or rms == 0.0:  # rounding's residue of a line
        raise ParameterError(f"profile {source!r}: every height lies on one straight line (RMS 0 after removing "
                             "the trend): no roughness to estimate")
    if rms > MAX_PROFILE_RMS:
        raise ParameterError(f"profile {source!r}: RMS height {rms:.4g} m, above the {MAX_PROFILE_RMS:g} m of any rail "
                             "or wheel roughness: heights must be in metres (micrometres x 1e-6)")
    return Profile(h, float(dx), source)


@dataclass(frozen=True)
class WelchPSD:
    """Welch estimate of a profile's two-sided PSD ``C(q)`` (m^3) at ``q`` (rad/m, > 0), with its
    ``confidence`` band (lower, upper) and the equivalent degrees of freedom ``dof``."""

    q: np.ndarray
    psd: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    dof: float
    confidence: float
    segments: int

    def as_model(self) -> Tabulated:
        """The estimate as a tabulated profile spectrum (interpolated log-log, absolute)."""
        keep = self.psd > 0
        return Tabulated(self.q[keep], self.psd[keep], kind="profile", absolute=True, source="Welch estimate")


def welch_dof(window: np.ndarray, segments: int, step: int) -> float:
    """Equivalent degrees of freedom of a Welch average of ``segments`` windowed segments ``step``
    samples apart (Welch 1967; Percival & Walden 1993, section 7.1): ``nu = 2 K / (1 + 2 sum_{j=1}^{K-1} (1 - j/K)
    rho_j)``, ``rho_j = (sum_n w_n w_{n + j step})^2 / (sum_n w_n^2)^2``."""
    w = np.asarray(window, dtype=np.float64)
    energy = float(np.sum(w * w))
    total = 0.0
    for j in range(1, segments):
        shift = j * step
        if shift >= w.size:
            break
        total += (1.0 - j / segments) * (float(np.dot(w[:-shift], w[shift:])) / energy) ** 2
    return 2.0 * segments / (1.0 + 2.0 * total)


def welch_psd(profile: Profile, segment_length: float | None = None, confidence: float = 0.95) -> WelchPSD:
    """The two-sided PSD of a profile by Welch's method: Hann window, segments of
    ``segment_length`` (m; default an eighth of the profile) overlapping by half, averaged
    (scipy.signal.welch, one-sided density P(f) per cycle/m), converted to the convention of
    physics.md section 3: ``q = 2 pi f``, ``C(q) = P(f) / (4 pi)`` (so that
    ``2 integral_0^inf C dq = integral_0^inf P df = <h^2>``). Confidence band: ``nu C / chi2_{nu}(1 -+ alpha/2)``
    with the equivalent degrees of freedom nu of :func:`welch_dof` (scipy.stats.chi2)."""
    if not 0.0 < confidence < 1.0:
        raise ParameterError(f"confidence = {confidence!r} is not allowed: it must lie in (0, 1)")
    n = profile.h.size
    if segment_length is not None and not (isinstance(segment_length, (int, float)) and math.isfinite(segment_length)
                                           and segment_length > 0):
        raise ParameterError(f"segment_length = {segment_length!r} m is not allowed: it must be positive and finite")
    nperseg = n // 8 if segment_length is None else int(round(segment_length / profile.dx))
    if not 16 <= nperseg <= n:
        raise ParameterError(f"segment_length = {segment_length!r} m is not allowed: it must hold 16 .. {n} samples "
                             f"of dx = {profile.dx:.4g} m")
    step = nperseg - nperseg // 2
    f, P = signal.welch(profile.h, fs=1.0 / profile.dx, window="hann", nperseg=nperseg, noverlap=nperseg // 2,
                        detrend="constant", scaling="density", return_onesided=True)
    segments = 1 + (n - nperseg) // step
    dof = welch_dof(signal.get_window("hann", nperseg), segments, step)
    alpha = 1.0 - confidence
    q, C = physics.TWO_PI * f[1:], P[1:] / (2.0 * physics.TWO_PI)
    lower = dof * C / stats.chi2.ppf(1.0 - alpha / 2.0, dof)
    upper = dof * C / stats.chi2.ppf(alpha / 2.0, dof)
    return WelchPSD(q, C, lower, upper, dof, confidence, segments)


def synthetic_profile(spectrum, params: Params, seed: int = 0) -> np.ndarray:
    """A Gaussian random profile of known spectrum, as a measurement would be (numpy): on the grid
    of ``params`` (n points, dx), ``X_k = sqrt(dq C_p(q_k) / 2) (g_k + i g'_k)`` with independent
    standard normal g, g' (so ``<|X_k|^2> = dq C_p``, physics.md section 3), inverse real FFT times
    n. Unlike the model's lines (fixed amplitudes, eq 16-17) each bin scatters as chi-square with 2
    degrees of freedom, the statistics Welch's confidence band assumes. Heights in m."""
    rng = np.random.default_rng(seed)
    n = params.n_points
    q = params.dq * np.arange(n // 2 + 1)
    amplitude = np.sqrt(params.dq * spectrum.profile_psd(q) / 2.0)
    amplitude[0] = 0.0
    spectrum_k = amplitude * (rng.standard_normal(q.size) + 1j * rng.standard_normal(q.size))
    return np.fft.irfft(spectrum_k, n) * n


def profile_line(profile: Profile, params: Params) -> np.ndarray:
    """The profile as one line of the model: its first ``params.length`` metres interpolated
    (linearly) onto the grid ``x_i = i params.dx``, mean removed; shape (1, n), metres."""
    x = profile.dx * np.arange(profile.h.size)
    if x[-1] < (params.n_points - 1) * params.dx:
        raise ParameterError(f"profile {profile.source!r} is {profile.length:.4g} m long: it must cover L = "
                             f"{params.length:.4g} m to be rolled as one line")
    line = np.interp(params.dx * np.arange(params.n_points), x, profile.h)
    return (line - line.mean())[None, :]
