"""Section 5.1, Figure 11: the full dynamics (eq 13, coupled) against the wheel's response to
the force at fixed d0 (decoupled), band by band. The thesis saw them "very similar" except left
of the resonance peak. Open runs, as the thesis's; the same lines in both modes, so the
independent-error uncertainties of their ratios are upper bounds.
"""

from __future__ import annotations

import math

from ..ensemble import measure
from ..params import Params
from .core import Claim, Figure, StudyOutcome, loglog, mark


def bands(p: Params) -> dict:
    """The bands of the comparison (rad/s): below the resonance, around it, the intermediate
    plateau, the power-law band."""
    w0, wt = p.omega_0, p.q_min * p.v0
    return {"below resonance": (0.0, 0.5 * w0), "resonance": (0.5 * w0, 2 * w0),
            "intermediate": (2 * w0, 0.5 * wt), "power law": (wt, 8 * wt)}


def coupling(run, L: float, dx: float, realizations: int) -> StudyOutcome:
    """Figure 11, section 5.1: coupled (semi-implicit Euler, physics.md section 5) against
    decoupled acceleration spectra, band by band; and the resonance peak of each."""
    p = Params(L=L, dx=dx)
    decoupled, coupled = run.run([run.spec(p, realizations), run.spec(p, realizations, mode="coupled")])
    claims, numbers = [], {}
    for name, (lo, hi) in bands(p).items():
        mask = (decoupled.omega > lo) & (decoupled.omega < hi)
        ratio, rel = measure.binned_ratio(coupled.accel_psd, coupled.accel_psd_stderr, decoupled.accel_psd,
                                          decoupled.accel_psd_stderr, mask)
        below = name == "below resonance"
        claims.append(Claim(f"coupled / decoupled, {name}",
                            "Fig 11: the two differ left of the resonance peak" if below else
                            "Fig 11: 'except for the lowest frequencies the spectra are very similar'",
                            ratio, rel * ratio, 1.0, "-", "physics.md" if below else "thesis", allowance=0.10,
                            known=("the thesis saw a difference below the resonance; physics.md's semi-implicit "
                                   "Euler step shows none (0.3 %): a verdict 'agrees' here contradicts the thesis's "
                                   "observation") if below else "",
                            note=f"accel PSD sums on ({lo:.4g}, {hi:.4g}) rad/s, {int(mask.sum())} bins"))
        numbers[name] = {"band_rad_s": [lo, hi], "ratio": ratio, "rel_stderr": rel, "bins": int(mask.sum())}
    dw = decoupled.omega[1]
    for label, result in (("coupled", coupled), ("decoupled", decoupled)):
        peak = measure.resonance_peak(result.omega, result.accel_psd, p.omega_0)
        claims.append(Claim(f"resonance peak, {label}", "sec 4.2: omega_0 = sqrt(2 a E*/m)", peak, dw / math.sqrt(12),
                            p.omega_0, "rad/s", "thesis", allowance=0.01 * p.omega_0,
                            note=f"bin width {dw:.3g} rad/s"))
        numbers[f"peak_{label}_rad_s"] = peak
    numbers["contact_lost_steps_coupled"] = coupled.contact_lost_steps

    def draw(fig):
        ax = fig.subplots()
        keep = decoupled.omega > 0
        loglog(ax, coupled.omega[keep], coupled.accel_psd[keep] / p.v0, None, "coupled (eq 13)", color="C2")
        loglog(ax, decoupled.omega[keep], decoupled.accel_psd[keep] / p.v0, None, "decoupled (section 5.1)", color="k",
               lw=0.5)
        mark(ax, p.omega_0, "omega_0")
        mark(ax, p.q_min * p.v0, "q_min v0")
        ax.set_xlabel("omega (rad/s)")
        ax.set_ylabel("C_a(omega) ((m/s^2)^2 s/rad)")
        ax.legend(fontsize=7, loc="lower left")
        ax.set_title("Fig 11: coupled against decoupled acceleration spectra", fontsize=9)

    return StudyOutcome(claims, numbers, [Figure("coupling", "Coupled and decoupled acceleration spectra (Fig 11)", draw)],
                        f"frequency resolution {dw:.3g} rad/s; {int(((decoupled.omega > 0) & (decoupled.omega < 0.5 * p.omega_0)).sum())} "
                        "bins below the resonance")
