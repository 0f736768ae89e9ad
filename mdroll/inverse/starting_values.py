"""Data-driven starting values of the fit.

The likelihood has many local minima (the modulation of sin^2(q a) in a, a kink at every bin in
the cutoffs), so the search starts near the answer: the resonance as the sharpest peak of the
lower half of an acceleration spectrum (E* from it with m), H from a power law of the upper band,
a from the periodogram of the detrended log-spectrum (:func:`modulation_radius`), q_min and a by
scans, and the level (h0, or E* for a force) profiled out analytically.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.ndimage

from ..errors import ParameterError
from ..physics import TWO_PI, edge_displacement
from .band import find_resonance
from .forward_model import contact_radius_from_load
from .likelihood import HUGE, Problem


def starting_values(problem: Problem, start: dict) -> dict:
    """Data-driven starting values for the free parameters (``start`` overrides them)."""
    unknown = set(start) - set(problem.free)
    if unknown:
        raise ParameterError(f"start names {sorted(unknown)}, which are not free ({', '.join(problem.free)})")
    free = set(problem.free) - set(start)
    p = dict(problem.fixed)
    p.update({"H": 0.6, "q_min": problem.omega[0] / problem.v0, "a": 5e-3, "E_star": 1.15e11, "h0": 1e-6, "R": 0.5,
              "m": 500.0, "zeta": 0.02, "low_scale": 1.0, "noise": 0.0, "leak": 0.0, **problem.fixed})
    p.update(start)
    omega, data = problem.omega, problem.data
    v0 = problem.v0
    top = data[-max(1, data.size // 20):]
    # the shape of the blocked force's spectrum for the power law and the modulation: a known
    # track's gain (at the starting contact) divided out
    known_track = problem.setting.known_track
    shape = data if known_track is None else data / known_track.gain(omega, p, problem.spectrum.quantity,
                                                                     problem.setting.dt)

    # the resonance from the whole spectrum (the default band starts above it)
    spectrum = problem.spectrum
    # (none on a known track: the contact's resonance is the track's, damped)
    resonance = find_resonance(spectrum.omega, spectrum.psd) if spectrum.quantity == "accel" and \
        problem.setting.known_track is None else None
    # power law of the upper two thirds (log) of the band: P ~ omega^-(2H+3)
    upper = omega >= omega[0] * (omega[-1] / omega[0]) ** (1.0 / 3.0)
    upper &= data > 0
    if resonance is not None and known_track is None:
        upper &= omega > 3.0 * resonance
    if upper.sum() >= 8:
        x, y = np.log(omega[upper]), np.log(shape[upper])
        top_half = x >= 0.5 * (x[0] + x[-1])
        slope = np.polyfit(x[top_half], y[top_half], 1)[0]
        if "H" in free:
            p["H"] = float(np.clip((-slope - 3.0) / 2.0, 0.05, 0.95))
        if "a" in free:
            p["a"] = modulation_radius(omega[upper] / v0, np.log(shape[upper]), default=p["a"])
    if "a_jitter" in free:  # the edge displacement of eq 47 at the RMS height
        p["a_jitter"] = float(edge_displacement(p["h0"], p["R"], p["a"]))
    if "noise" in free:
        p["noise"] = 0.3 * float(np.median(top))
    if "leak" in free:
        p["leak"] = 0.01 * float(np.median(top)) * omega[-1] ** 2
    if "E_star" in free and resonance is not None and problem.spectrum.quantity == "accel":
        p["E_star"] = p["m"] * resonance**2 / (2.0 * p["a"])
    level = "h0" if "h0" in free else ("E_star" if "E_star" in free and problem.spectrum.quantity == "force" else None)

    def scaled(trial):  # the objective with the level profiled out analytically (S = s g)
        g = problem.model(_with_load(problem, trial))
        if not np.all(np.isfinite(g)) or np.any(g <= 0):
            return HUGE, 1.0
        s = float(np.mean(data / g))
        return float(np.mean(np.log(s * g) + data / (s * g))), s

    if "E_star" in free and resonance is None and spectrum.quantity == "accel":
        candidates = np.geomspace(1e9, 1e13, 41)
        p["E_star"] = float(candidates[int(np.argmin([scaled(dict(p, E_star=float(e)))[0] for e in candidates]))])
    if "q_min" in free:
        candidates = np.geomspace(omega[0] / v0, omega[-1] / v0 / 3.0, 48)
        scores = [scaled(dict(p, q_min=float(q)))[0] for q in candidates]
        p["q_min"] = float(candidates[int(np.argmin(scores))])
        # then at the bins' resolution: the likelihood has a kink at every bin, on which a
        # gradient method stalls
        bin_q = problem.setting.bin_width / v0
        fine = p["q_min"] + bin_q * np.arange(-0.1 * p["q_min"] / bin_q, 0.1 * p["q_min"] / bin_q, 0.5)
        fine = fine[fine > 0]
        scores = [scaled(dict(p, q_min=float(q)))[0] for q in fine]
        p["q_min"] = float(fine[int(np.argmin(scores))])
    if "a" in free:
        # a fine scan around the start, in steps of a quarter of the phase tolerance pi / (8 q_top)
        step = math.pi / (32.0 * omega[-1] / v0)
        trials = [a for a in p["a"] + step * np.arange(-16, 17) if a > 0]
        p["a"] = float(trials[int(np.argmin([scaled(dict(p, a=float(a)))[0] for a in trials]))])
    if level is not None:
        s = scaled(p)[1]
        p[level] *= math.sqrt(s)
    return _with_load(problem, p)


def _with_load(problem: Problem, p: dict) -> dict:
    if problem.load is not None:
        p = dict(p, a=float(contact_radius_from_load(problem.load, p["E_star"], p["R"])))
    return p


def modulation_radius(q, log_psd, default, smallest=1e-3):
    """a from the modulation of eq 40 and eq 48 (period pi / a in q, eq 26): ``log sin^2(q a)``
    less its running mean over 2 pi / ``smallest`` (m) is ``-2 sum_k cos(2 k q a) / k``, whose
    fundamental lies at a / pi cycles per rad/m: the peak of its periodogram (resampled on a
    uniform q grid, Hann taper, 8x zero padding), for a above ``smallest`` / 2."""
    if q.size < 16:
        return default
    size = min(q.size, 2**18)
    grid = np.linspace(q[0], q[-1], size)
    step = grid[1] - grid[0]
    values = np.interp(grid, q, log_psd)
    width = int(min(size // 4, max(3, round(TWO_PI / smallest / step)))) | 1
    r = values - scipy.ndimage.uniform_filter1d(values, width, mode="nearest")
    r = (r - r.mean()) * np.hanning(size)
    spectrum = np.abs(np.fft.rfft(r, 8 * size)) ** 2
    cycles = np.fft.rfftfreq(8 * size, step)
    radius = math.pi * cycles
    usable = (cycles > 4.0 / (q[-1] - q[0])) & (radius > 0.5 * smallest) & (cycles < 0.25 / step)
    if not usable.any():
        return default
    return float(radius[usable][np.argmax(spectrum[usable])])
