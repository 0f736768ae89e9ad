"""Chapters 5.3 and 6 of the thesis: the low band of the force (Figure 13, eq 48), the
low-frequency plateau and its empirical law (Figures 14-20, eq 51-58) and the RMS force in the
plateau (eq 59-61).

All runs are periodic (physics.md section 6): the low band is 30-40 dB under the high band, and
an open series' leakage (see the taper study) would add to it. The plateau ``C_F0`` is defined
under the project's PSD convention (physics.md section 6, the thesis's eq 57 with our
normalization): the q -> 0 level of the two-sided force PSD, measured by fitting the
closed-form low band's shape by one factor (:func:`mdroll.studies.band_averages.plateau_level`); the
thesis's Fourier component is then ``B_F0 = sqrt(2 pi C_F0 / L)`` (eq 57) and its
``psi = B_F0 a / (E* R h0^2)`` (eq 51).
"""

from __future__ import annotations

import math

import numpy as np

from .. import physics
from ..ensemble import measure
from ..experiments import Figure
from ..params import Params
from .band_averages import plateau_level
from .closed_forms import band_rms_thesis, low_band as closed_low_band, plateau_thesis
from .core import Claim, StudyOutcome, claims_by, fit_line, fit_power_law, loglog, mark, ratio_stderr


# ---------------------------------------------------------------------------- low band (Fig 13)
def low_band(run, L: float, dx: float, realizations: int, q_min_factors=(0.5, 1.0, 2.0)) -> StudyOutcome:
    """Figure 13, eq 48: the exact force against eq 48 for three q_min, below q_min/2; and
    both against the closed-form low band. Eq 48 is computed by the edge kernel (eq 49): on a
    periodic line its linear term has no power below q_min, so there its PSD is eq 48's. Both
    share their lines, so the independent-error uncertainties are upper bounds."""
    base = Params(L=L, dx=dx)
    params = [base.replace(q_min=f * base.q_min) for f in q_min_factors]
    # the exact force (the registry's default, None) and eq 49
    specs = [run.spec(p, realizations, boundary="periodic", algorithm=alg) for p in params for alg in (None, "edge")]
    results = run.run(specs)
    claims, numbers = [], []
    for i, p in enumerate(params):
        exact, edge = results[2 * i], results[2 * i + 1]
        low = (exact.q > 0) & (exact.q < p.q_min / 2)
        ratio, rel = measure.binned_ratio(exact.force_psd, exact.force_psd_stderr, edge.force_psd, edge.force_psd_stderr, low)
        label = f"q_min = 2 pi / {2 * math.pi / p.q_min * 1e3:.3g} mm"
        claims.append(Claim(f"exact / eq 48 [{label}]", "Fig 13: below q_min the force spectrum is eq 48's "
                            "('very good correspondence')", ratio, rel * ratio, 1.0, "-", "thesis", allowance=0.03,
                            note="PSD sums on 0 < q < q_min/2"))
        closed = closed_low_band(p, exact.q[low])
        total, rel_total = measure.band_sum(exact.force_psd, exact.force_psd_stderr, low)
        claims.append(Claim(f"exact / closed form [{label}]", "physics.md sec 7: 4 c^2 cos^2(qa) C_h2(q) (not in the thesis)",
                            total / closed.sum(), rel_total * total / closed.sum(), 1.0, "-", "closed form", allowance=0.10))
        high = (exact.q >= 10 * p.q_min) & (exact.q < 20 * p.q_min)
        over, over_rel = measure.binned_ratio(edge.force_psd, edge.force_psd_stderr, exact.force_psd, exact.force_psd_stderr, high)
        claims.append(Claim(f"eq 49 / exact at [10, 20) q_min [{label}]", "Fig 13: no correspondence at high "
                            "frequencies (expected); eq 49 adds the linear term", over, over_rel * over, None, "-",
                            note="physics.md: eq 49 overshoots the high band (x1.08 at 10 q_min, x1.3 at 20)"))
        numbers.append({"q_min_rad_m": p.q_min, "exact_over_eq48": ratio, "rel_stderr": rel,
                        "exact_over_closed_form": total / closed.sum(), "eq49_over_exact_10_20": over})

    def draw(fig):
        top, bottom = fig.subplots(2, 1)
        for i, p in enumerate(params):
            exact, edge = results[2 * i], results[2 * i + 1]
            for ax in (top, bottom):
                keep = (exact.q > 0) & ((exact.q < p.q_min) if ax is bottom else True)
                loglog(ax, exact.q[keep], exact.force_psd[keep], None, f"exact, q_min = {p.q_min:.0f} rad/m", color=f"C{i}")
                ax.loglog(exact.q[keep], edge.force_psd[keep], ".", ms=1.5, color=f"C{i}")
        bottom.set_xlabel("q (rad/m)")
        for ax in (top, bottom):
            ax.set_ylabel("C_F (N^2 m)")
        top.legend(fontsize=7, loc="lower left")
        top.set_title("Fig 13: exact force PSD (lines) and eq 48 / eq 49 (dots); bottom: q < q_min", fontsize=9)

    return StudyOutcome(claims, {"per_q_min": numbers}, [Figure("low-band", "Exact force spectrum against eq 48 (Fig 13)",
                                                                  draw, (7.0, 6.5))],
                        "ratios of band sums of the same lines: uncertainties are upper bounds")


# ---------------------------------------------------------------------------- plateau (Fig 14-20)
def psi_closed_form(p: Params) -> float:
    """psi = B_F0 a / (E* R h0^2) (eq 51) of the closed-form low band at q = 0 for the discrete line
    (physics.md section 7; for q_max -> infinity ``sqrt(2 pi) H / sqrt((4H + 1) q_min L)``)."""
    at_zero = float(closed_low_band(p, np.zeros(1))[0])
    return math.sqrt(2 * math.pi * at_zero / p.length) * p.a / (p.E_star * p.R * p.h0 ** 2)


def _psi(level: float, rel: float, p: Params) -> tuple[float, float]:
    """psi (eq 51) from a measured C_F0 (N^2 m) and its relative error: ``B_F0 = sqrt(2 pi C_F0 / L)`` (eq 57)."""
    psi = math.sqrt(2 * math.pi * level / p.length) * p.a / (p.E_star * p.R * p.h0 ** 2)
    return psi, 0.5 * rel * psi


def plateau(run, L: float, dx: float, realizations: int, heights=(0.25e-6, 0.5e-6, 0.75e-6, 1e-6),
            length_factors=(0.5, 2.0), q_min_factors=(0.5, 1.0, 2.0),
            hursts=(0.3, 0.4, 0.5, 0.6, 0.7, 0.8)) -> StudyOutcome:
    """Figures 14-20, eq 51-58: the plateau B_F0 against h0 (exponent), against q_min and L varied
    independently (collapse onto q_min L), and against H at several q_min L (L fixed, q_min
    varied); refits psi(H) = beta + gamma H per q_min L, beta/gamma (thesis 0.277), and
    gamma(q_min L) = C (q_min L)^p (thesis p = -0.485, C = 2.863), each with a confidence interval
    from the ensembles' standard errors; side by side with eq 56/58 and the closed form, whose
    H / sqrt(4H + 1) is what the thesis's linear law approximates; and the convention factor
    eq 58 / measured C_F0."""
    base = Params(L=L, dx=dx)
    jobs = {("h0", h): base.replace(h0=h) for h in heights}
    jobs.update({("L", f): base.replace(L=f * base.L) for f in (*length_factors, 1.0)})
    jobs.update({("H", f, h): base.replace(q_min=f * base.q_min, H=h) for f in q_min_factors for h in (*hursts, base.H)})
    unique = list(dict.fromkeys(jobs.values()))  # the same parameters run once
    by_params = dict(zip(unique, run.run([run.spec(p, realizations, boundary="periodic") for p in unique])))
    results = {k: by_params[p] for k, p in jobs.items()}

    def level(key):
        result = results[key]
        c, rel, closed = plateau_level(result)
        return c, rel, closed, result.params

    claims, numbers = [], {}
    # --- h0 (Fig 14)
    rows = [level(("h0", h)) for h in heights]
    psi_h = [_psi(c, r, p) for c, r, _, p in rows]
    b_values = [psi * p.E_star * p.R * p.h0 ** 2 / p.a for (psi, _), (_, _, _, p) in zip(psi_h, rows)]
    exponent, err, _, _ = fit_power_law(heights, b_values, [0.5 * r for _, r, _, _ in rows])
    claims.append(Claim("B_F0 ~ h0^n", "Fig 14, eq 51: B_F0 is quadratic in h0", exponent, err, 2.0, "-", "thesis",
                        allowance=0.02))
    numbers["h0"] = {"h0_m": list(heights), "B_F0_N": b_values, "C_F0_N2m": [c for c, _, _, _ in rows],
                     "rel_stderr_C": [r for _, r, _, _ in rows], "exponent": exponent, "stderr": err}

    # --- q_min and L independently (Fig 15)
    q_rows = [level(("H", f, base.H)) for f in q_min_factors]
    l_rows = [level(("L", f)) for f in (*length_factors, 1.0)]
    collapse = {}
    for name, group in (("q_min", q_rows), ("L", l_rows)):
        x = [p.q_min * p.length for _, _, _, p in group]
        b = [math.sqrt(2 * math.pi * c / p.length) for c, _, _, p in group]
        slope_, slope_err, const, const_err = fit_power_law(x, b, [0.5 * r for _, r, _, _ in group])
        collapse[name] = {"q_min_L": x, "B_F0_N": b, "exponent": slope_, "stderr": slope_err}
    diff, diff_err = collapse["q_min"]["exponent"] - collapse["L"]["exponent"], math.hypot(collapse["q_min"]["stderr"],
                                                                                          collapse["L"]["stderr"])
    claims.append(Claim("collapse onto q_min L", "Fig 15: B_F0 depends on q_min and L only through q_min L "
                        "(exponent with q_min varied - with L varied)", diff, diff_err, 0.0, "-", "thesis", allowance=0.03))
    claims.append(Claim("B_F0 ~ (q_min L)^p", "eq 56: p = -0.485 (thesis fit; closed form: -1/2)",
                        collapse["q_min"]["exponent"], collapse["q_min"]["stderr"], -0.485, "-", "thesis", allowance=0.02,
                        note="q_min varied at fixed L"))
    numbers["collapse"] = collapse

    # --- H at several q_min L (Fig 16-20)
    per_qL, psi_table = [], {}
    for f in q_min_factors:
        rows = [level(("H", f, h)) for h in hursts]
        psi = [_psi(c, r, p) for c, r, _, p in rows]
        closed = [psi_closed_form(p) for _, _, _, p in rows]
        (beta, gamma), cov, chi2 = fit_line(hursts, [v for v, _ in psi], [e for _, e in psi])
        ratio, ratio_err = ratio_stderr(beta, math.sqrt(cov[0, 0]), gamma, math.sqrt(cov[1, 1]), cov[0, 1])
        (beta_c, gamma_c), _, _ = fit_line(hursts, closed, [e / v * c for (v, e), c in zip(psi, closed)])
        qL = rows[0][3].q_min * rows[0][3].length
        per_qL.append({"q_min_L": qL, "beta": beta, "gamma": gamma, "covariance": cov.tolist(), "reduced_chi2": chi2,
                       "beta_over_gamma": ratio, "beta_over_gamma_stderr": ratio_err, "closed_form_beta": beta_c,
                       "closed_form_gamma": gamma_c, "closed_form_beta_over_gamma": beta_c / gamma_c,
                       "psi": [v for v, _ in psi], "psi_stderr": [e for _, e in psi], "psi_closed_form": closed})
        psi_table[qL] = (psi, closed)
    weights = np.array([1 / r["beta_over_gamma_stderr"] ** 2 for r in per_qL])
    pooled = float(np.sum(weights * [r["beta_over_gamma"] for r in per_qL]) / weights.sum())
    pooled_err = float(1 / math.sqrt(weights.sum()))
    closed_ratio = float(np.mean([r["closed_form_beta_over_gamma"] for r in per_qL]))
    claims.append(Claim("beta / gamma", "eq 53: beta = 0.277 gamma (psi linear in H, eq 52)", pooled, pooled_err, 0.277,
                        "-", "thesis", allowance=0.02, resolution=0.02,
                        note=f"weighted mean over q_min L of the per-line fits; the closed form fitted the same way gives "
                             f"{closed_ratio:.3f}"))
    claims.append(Claim("beta / gamma vs closed form", "physics.md sec 7: the same linear fit of the closed form's "
                        "H/sqrt(4H+1)", pooled, pooled_err, closed_ratio, "-", "closed form", allowance=0.02,
                        resolution=0.02))
    gammas = [r["gamma"] for r in per_qL]
    gamma_rel = [math.sqrt(r["covariance"][1][1]) / r["gamma"] for r in per_qL]
    qLs = [r["q_min_L"] for r in per_qL]
    p_gamma, p_err, c_gamma, c_err = fit_power_law(qLs, gammas, gamma_rel)
    closed_p, _, closed_c, _ = fit_power_law(qLs, [r["closed_form_gamma"] for r in per_qL], gamma_rel)
    claims.append(Claim("gamma(q_min L) exponent", "Fig 19: gamma ~ (q_min L)^-0.485", p_gamma, p_err, -0.485, "-",
                        "thesis", allowance=0.02, note=f"closed form: {closed_p:.3f}"))
    claims.append(Claim("gamma(q_min L) constant", "Fig 19, eq 56: constant 2.863 (thesis normalization)", c_gamma,
                        c_err, 2.863, "-", "thesis", allowance=0.05 * 2.863,
                        known="the thesis's spectral normalization differs from physics.md's (see the convention "
                              "factor below): its constant is about sqrt(10) times ours",
                        note=f"closed form: {closed_c:.3f}; thesis / ours = {2.863 / c_gamma:.3f}"))

    # --- convention factor (eq 58) at the defaults and over H
    c0, rel0, _, p0 = level(("L", 1.0))
    factor = plateau_thesis(p0) / c0
    closed_factor = plateau_thesis(p0) / float(closed_low_band(p0, np.zeros(1))[0])
    claims.append(Claim("eq 58 / measured C_F0", "eq 58: C_F0 = 1.3 E*^2 R^2 h0^4 (0.277 + H)^2 / (a^2 q_min)",
                        factor, rel0 * factor, 1.0, "-", "thesis", allowance=0.1,
                        known="a convention factor: the thesis's spectral normalization is not recoverable from its "
                              "text; physics.md's closed form predicts it",
                        note=f"closed form predicts {closed_factor:.3f} at H = {p0.H:g}"))
    claims.append(Claim("convention factor vs closed form", "physics.md sec 7: eq 58 / C_F0 = 1.3 (0.277+H)^2 "
                        "(4H+1) / H^2 (about 10)", factor, rel0 * factor, closed_factor, "-", "closed form",
                        allowance=0.1 * closed_factor))
    middle = q_min_factors[len(q_min_factors) // 2]
    factors_h = [plateau_thesis(level(("H", middle, h))[3]) / level(("H", middle, h))[0] for h in hursts]
    numbers.update({"per_q_min_L": per_qL, "beta_over_gamma": pooled, "beta_over_gamma_stderr": pooled_err,
                    "closed_form_beta_over_gamma": closed_ratio, "gamma_exponent": p_gamma,
                    "gamma_exponent_stderr": p_err, "gamma_constant": c_gamma, "gamma_constant_stderr": c_err,
                    "closed_form_gamma_exponent": closed_p, "closed_form_gamma_constant": closed_c,
                    "convention_factor_defaults": factor, "convention_factor_closed_form": closed_factor,
                    "convention_factor_by_H": {"q_min_rad_m": middle * base.q_min, **dict(zip(map(str, hursts), factors_h))},
                    "plateau_definition": "C_F0: q -> 0 level of the two-sided force PSD (physics.md sec 6), the "
                                          "closed-form low band's shape fitted by one factor on 0 < q <= min(q_min/2, "
                                          "pi/(2a)); B_F0 = sqrt(2 pi C_F0 / L) (eq 57), psi = B_F0 a / (E* R h0^2)"})

    def draw(fig):
        left, right = fig.subplots(1, 2)
        h = np.linspace(min(hursts), max(hursts), 50)
        for i, (qL, (psi, closed)) in enumerate(psi_table.items()):
            r = per_qL[i]
            left.errorbar(hursts, [v for v, _ in psi], yerr=[e for _, e in psi], fmt="o", ms=3, color=f"C{i}",
                          label=f"q_min L = {qL:.0f}")
            left.plot(h, r["beta"] + r["gamma"] * h, color=f"C{i}", lw=0.8)
            left.plot(hursts, closed, "x", color=f"C{i}", ms=5)
            thesis = 2.863 * qL ** -0.485 * (physics.THESIS_HURST_OFFSET + h) / math.sqrt(factor)
            left.plot(h, thesis, ":", color=f"C{i}", lw=0.8)
        left.set_xlabel("H")
        left.set_ylabel("psi = B_F0 a / (E* R h0^2)")
        left.legend(fontsize=6, title="points: measured; lines: refit;\nx: closed form; dotted: eq 56 / sqrt(factor)",
                    title_fontsize=6)
        left.set_title("Fig 17/20: psi(H)", fontsize=9)
        for name, marker in (("q_min", "o"), ("L", "s")):
            c = collapse[name]
            right.loglog(c["q_min_L"], c["B_F0_N"], marker, ms=4, label=f"{name} varied")
        x = np.array(sorted(collapse["q_min"]["q_min_L"] + collapse["L"]["q_min_L"]))
        right.loglog(x, [psi_closed_form(base.replace(q_min=v / base.length)) * base.E_star * base.R * base.h0 ** 2 / base.a
                         for v in x], "k:", lw=0.8, label="closed form")
        right.set_xlabel("q_min L")
        right.set_ylabel("B_F0 (N)")
        right.legend(fontsize=7)
        right.set_title("Fig 15: collapse onto q_min L", fontsize=9)

    summary = (f"Under physics.md's convention the plateau is C_F0 = {c0:.3g} N^2 m at the defaults; eq 58 is "
               f"{factor:.2f} +- {rel0 * factor:.2f} times it (the closed form predicts {closed_factor:.2f}): a convention "
               f"factor, so eq 56's constant 2.863 is about sqrt({factor:.1f}) = {math.sqrt(factor):.2f} times ours "
               f"({c_gamma:.3f} +- {c_err:.3f}). The scalings hold: B_F0 ~ h0^{claims_by(claims, 'B_F0 ~ h0')[0]:.3f}, "
               f"a collapse onto q_min L (exponent difference {diff:.3f} +- {diff_err:.3f}), gamma ~ (q_min L)^"
               f"{p_gamma:.3f} +- {p_err:.3f} (thesis -0.485, closed form {closed_p:.3f}). The linear law psi = beta + "
               f"gamma H fits with beta/gamma = {pooled:.3f} +- {pooled_err:.3f} (thesis 0.277); the closed form's "
               f"H/sqrt(4H+1), fitted the same way over H = {min(hursts):g}..{max(hursts):g}, gives {closed_ratio:.3f}: "
               f"the thesis's (0.277 + H) is the linearization of the closed form's H dependence.")
    return StudyOutcome(claims, numbers, [Figure("plateau", "psi(H) per q_min L against eq 56 and the closed form "
                                                            "(Fig 17/20), and the q_min L collapse (Fig 15)", draw, (10.0, 4.5))],
                        f"beta/gamma to +-{3 * pooled_err:.3f}, gamma exponent to +-{3 * p_err:.3f} (3 sigma)", summary)


# ---------------------------------------------------------------------------- rms-force (eq 59-61)
#: The thesis's example (eq 61): a plateau band of width 2 kHz, q_min v0 at 30 kHz; its figures
#: are angular frequencies ("omega [1/s]"), so d_omega = 2000 rad/s and q_min v0 = 30000 rad/s.
EXAMPLE_BAND_RAD_S = 2000.0
EXAMPLE_TRANSITION_RAD_S = 30000.0


def rms_force(run, L: float, dx: float, realizations: int) -> StudyOutcome:
    """The thesis's eq 59-61: the RMS force in the plateau band of the thesis's example (band 0 < omega <= 2000
    rad/s, q_min v0 = 30000 rad/s, defaults otherwise), measured as ``sqrt(2 sum C_F(q_k) dq)`` (the
    RMS of the band-passed force: both signs of q, physics.md's convention) against eq 60-61's
    "about 1 N" and the closed form."""
    base = Params(L=L, dx=dx)
    p = base.replace(q_min=EXAMPLE_TRANSITION_RAD_S / base.v0)
    result, = run.run([run.spec(p, realizations, boundary="periodic")])
    dq_band = EXAMPLE_BAND_RAD_S / p.v0
    band = (result.q > 0) & (result.q <= dq_band)
    total, rel = measure.band_sum(result.force_psd, result.force_psd_stderr, band)
    bin_width = result.q[1] - result.q[0]
    measured = math.sqrt(2 * total * bin_width)
    closed = math.sqrt(2 * float(closed_low_band(p, result.q[band]).sum()) * bin_width)
    eq60 = band_rms_thesis(p, dq_band)
    eq61 = p.E_star * p.R * p.h0 ** 2 * (physics.THESIS_HURST_OFFSET + p.H) / (4 * p.a)
    claims = [
        Claim("band RMS force vs closed form", "physics.md sec 7: sqrt(2 sum 4 c^2 cos^2(qa) C_h2 dq)", measured,
              0.5 * rel * measured, closed, "N", "closed form", allowance=0.05 * closed),
        Claim("band RMS force vs eq 60", "eq 60: 1.14 E* R h0^2 (0.277 + H) / a sqrt(dq / q_min)", measured,
              0.5 * rel * measured, eq60, "N", "thesis", allowance=0.1 * eq60,
              known="eq 60 integrates eq 58 (about 10x physics.md's two-sided PSD) over one sign of q: it exceeds "
                    "the band-passed force's RMS by about sqrt(10 / 2)",
              note=f"ratio eq 60 / measured = {eq60 / measured:.3f}"),
        Claim("band RMS force vs 'about 1 N'", "eq 61: E* R h0^2 (0.277 + H) / (4a), 'an RMS force of 1 N'",
              measured, 0.5 * rel * measured, 1.0, "N", "thesis", allowance=0.5,
              known="eq 61 is 0.70 N at the defaults, rounded up to 'about 1 N'; its normalization (eq 58, one sign "
                    "of q) overstates the band-passed force's RMS by about sqrt(5)",
              note=f"eq 61 at the defaults: {eq61:.3f} N; band 0 < q <= {dq_band:g} rad/m, q_min = {p.q_min:g} rad/m"),
    ]

    def draw(fig):
        ax = fig.subplots()
        keep = (result.q > 0) & (result.q < 2 * p.q_min)
        loglog(ax, result.omega[keep], result.force_psd[keep], result.force_psd_stderr[keep], "force PSD", color="C0")
        low = keep & (result.q < p.q_min)
        loglog(ax, result.omega[low], closed_low_band(p, result.q[low]), None, "closed form", color="k", lw=0.8)
        ax.axvspan(result.omega[1], EXAMPLE_BAND_RAD_S, color="C2", alpha=0.2, label="eq 61 band")
        mark(ax, p.q_min * p.v0, "q_min v0")
        ax.set_xlabel("omega (rad/s)")
        ax.set_ylabel("C_F(q) (N^2 m)")
        ax.legend(fontsize=7)
        ax.set_title(f"eq 59-61: band RMS force {measured:.3f} N (eq 60: {eq60:.3f} N, eq 61: {eq61:.3f} N)", fontsize=9)

    summary = (f"The RMS of the force band-passed to 0 < omega <= {EXAMPLE_BAND_RAD_S:g} rad/s (q_min v0 = "
               f"{EXAMPLE_TRANSITION_RAD_S:g} rad/s) is {measured:.3f} +- {0.5 * rel * measured:.3f} N (closed form "
               f"{closed:.3f} N); eq 60 gives {eq60:.3f} N and eq 61 {eq61:.3f} N ('about 1 N'): the thesis's number "
               f"is {eq60 / measured:.2f} times the physical one. Eq 60 integrates eq 58, which carries the convention "
               f"factor of the plateau study, over one sign of q, and takes the plateau as flat where cos^2(q a) "
               f"already falls (q a up to {dq_band * p.a:.2f} in this band).")
    return StudyOutcome(claims, {"band_rad_m": dq_band, "q_min_rad_m": p.q_min, "rms_force_N": measured,
                                 "rms_force_stderr_N": 0.5 * rel * measured, "closed_form_N": closed, "eq60_N": eq60,
                                 "eq61_N": eq61, "bins": int(band.sum())},
                        [Figure("rms-force", "Force PSD and the plateau band of the thesis's example (eq 61)", draw)],
                        f"{int(band.sum())} bins in the band; RMS force to +-{150 * rel:.1f} % (3 sigma)", summary)
