"""Which bins of an ensemble's spectra a record of this length and this estimator cannot resolve
(docs/physics.md, "The default estimator and the resolution flags").

A record of S = N dx seen through a window w has bins d omega = 2 pi v0 / S apart, and its
periodogram is the true spectrum convolved with the window's kernel |W(delta)|^2 (delta: the
offset in bins). Three kinds of bin are flagged:

- *below the lowest resolvable bin*: k < the half-width of the kernel's main lobe (rectangle 1,
  Hann 2): the mean removal and the kernel at zero frequency decide these bins;
- *within the main lobe of omega_0*: |omega - omega_0| < the main lobe's half-width, for the
  acceleration (and for the force of a coupled run): the contact resonance is a line there;
- *leakage exceeds the signal*: the measured spectrum's own power leaked through the kernel's
  sidelobe envelope from bins at least :data:`LEAKAGE_REACH` main-lobe half-widths away is more
  than half of the bin's power (leakage > signal). The envelope is an upper bound (rectangle
  ``1 / (pi delta)^2``, Hann ``1 / (pi delta (delta^2 - 1))^2``), so the flag is conservative;
  an unwindowed record of a steep spectrum or of an undamped resonance is flagged over most of
  its range, a Hann-windowed one at most in the zeros of eq 39's modulation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Half-width (bins) of the main lobe of each estimator's kernel: rectangle (no window), Hann.
MAIN_LOBE = {False: 1, True: 2}
#: Leakage is summed from bins at least this many main-lobe half-widths away (nearer bins are
#: the bin's own neighbourhood, which a band average keeps).
LEAKAGE_REACH = 2
#: The reasons a bin is flagged, in the order they are tested (a bin takes the first that applies).
REASONS = ("below the lowest resolvable bin", "within the window's main lobe of omega_0", "leakage exceeds the signal")
#: Ranges of flagged bins a summary lists per quantity (the widest first); the counts cover all.
SUMMARY_RANGES = 12


def estimator_name(window: bool | None) -> str:
    """The estimator of a run with or without the Hann window (None: not recorded)."""
    if window is None:
        return "unknown (not recorded)"
    return "Hann window, normalized by mean w^2 (default)" if window else "open record, no window (the thesis's)"


def kernel_envelope(delta: np.ndarray, window: bool) -> np.ndarray:
    """Upper envelope of the estimator's kernel |W(delta)|^2 / |W(0)|^2 at offsets ``delta``
    (bins, |delta| beyond the main lobe)."""
    d = np.abs(np.asarray(delta, dtype=np.float64))
    with np.errstate(divide="ignore"):
        if window:
            return 1.0 / (np.pi * d * (d * d - 1.0)) ** 2
        return 1.0 / (np.pi * d) ** 2


def leakage(psd: np.ndarray, window: bool) -> np.ndarray:
    """Per bin, the power of ``psd`` (any unit) leaked into it through :func:`kernel_envelope`
    from the bins at least ``LEAKAGE_REACH x MAIN_LOBE`` away (both sides, a linear convolution)."""
    psd = np.nan_to_num(np.asarray(psd, dtype=np.float64), nan=0.0, posinf=0.0)
    n = psd.size
    reach = LEAKAGE_REACH * MAIN_LOBE[bool(window)]
    offsets = np.arange(-(n - 1), n, dtype=np.float64)
    kernel = np.where(np.abs(offsets) >= reach, kernel_envelope(np.maximum(np.abs(offsets), 1.0), window), 0.0)
    size = 1 << int(np.ceil(np.log2(3 * n)))
    full = np.fft.irfft(np.fft.rfft(psd, size) * np.fft.rfft(kernel, size), size)
    return np.maximum(full[n - 1: 2 * n - 1], 0.0)


@dataclass(frozen=True)
class Resolution:
    """Per quantity (``"force"``, ``"accel"``) a boolean mask over the bins (True: unresolved)
    and the index of the reason (into :data:`REASONS`, -1 where resolved)."""

    reasons: dict

    def mask(self, quantity: str) -> np.ndarray:
        return self.reasons[quantity] >= 0

    def summary(self, omega: np.ndarray) -> dict:
        """JSON-ready: per quantity, bins flagged per reason and the widest flagged ranges (rad/s)."""
        out = {}
        for quantity, reason in self.reasons.items():
            counts = {REASONS[i]: int(np.sum(reason == i)) for i in range(len(REASONS)) if np.any(reason == i)}
            edges = np.flatnonzero(np.diff(np.r_[-2, reason, -2]) != 0)
            runs = [(int(s), int(e)) for s, e in zip(edges[:-1], edges[1:]) if reason[s] >= 0]
            runs.sort(key=lambda r: r[0] - r[1])
            ranges = [{"omega_rad_s": [float(omega[s]), float(omega[e - 1])], "bins": e - s, "reason": REASONS[reason[s]]}
                      for s, e in runs[:SUMMARY_RANGES]]
            out[quantity] = {"unresolved_bins": int(np.sum(reason >= 0)), "of_bins": int(reason.size),
                             "per_reason": counts, "widest_ranges": sorted(ranges, key=lambda r: r["omega_rad_s"][0])}
        return out


def resolution(omega: np.ndarray, force_psd: np.ndarray, accel_psd: np.ndarray, omega_0: float, window: bool | None,
               mode: str) -> Resolution:
    """The flags of the module docstring for spectra on ``omega`` (rad/s, uniform from 0) of a
    run with (``window``) or without the Hann window (None: unknown, treated as without) whose
    resonance is ``omega_0`` (rad/s)."""
    window = bool(window)
    lobe = MAIN_LOBE[window]
    step = float(omega[1] - omega[0]) if omega.size > 1 else 1.0
    k = np.arange(omega.size)
    in_lobe = np.abs(omega - omega_0) < lobe * step
    reasons = {}
    for quantity, psd in (("force", force_psd), ("accel", accel_psd)):
        reason = np.full(omega.size, -1, dtype=np.int64)
        leaks = leakage(psd, window) > 0.5 * np.asarray(psd)
        reason[leaks] = 2
        if quantity == "accel" or mode == "coupled":
            reason[in_lobe] = 1
        reason[k < lobe] = 0
        reasons[quantity] = reason
    return Resolution(reasons)
