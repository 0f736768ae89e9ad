"""The validation layer: check helpers on synthetic spectra, the ensemble on every device, and
``mdroll validate --quick`` end to end (physics.md section 7)."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from reference import psd, to_numpy

from mdroll import Params, contact_force, rough_lines
from mdroll.validation.references import edge_quadratic_force
from mdroll.validation.checks import (CheckResult, Spectra, force_spectra, modulation_period_measured, paired_ratio,
                                      period_averaged_slope, period_bands, resonance_peak)
from mdroll.validation.report import format_table, slug

ROOT = Path(__file__).resolve().parents[1]
P = Params(L=0.5, dx=20e-6)


def _synthetic(values, params=P):
    q = 2 * np.pi * np.arange(params.n_points // 2 + 1) / params.length
    y = values(q)
    return Spectra(params, q, {"x": y}, {"x": np.zeros_like(y)}, {}, 1)


def test_modulation_period_of_a_synthetic_spectrum():
    a_true = 1.03 * P.a  # not the params' a: the estimate must come from the data
    s = _synthetic(lambda q: np.sin(q * a_true) ** 2 * np.maximum(q, 1.0) ** -(2 * P.H + 3))
    assert modulation_period_measured(s, "x") == pytest.approx(math.pi / a_true, rel=2e-3)


def test_period_averaged_slope_of_a_power_law():
    s = _synthetic(lambda q: np.sin(q * P.a) ** 2 * np.maximum(q, 1.0) ** -4.4)
    assert period_averaged_slope(s, "x", 1.5 * P.q_min, 8 * P.q_min) == pytest.approx(-4.4, abs=0.005)
    bands = period_bands(s.q, P.q_min, 8 * P.q_min, P.a)
    assert len(bands) == int((7 * P.q_min) / (math.pi / P.a))
    assert all(np.ptp(s.q[b]) < math.pi / P.a for b in bands)


def test_resonance_peak_of_a_synthetic_response():
    class Result:
        params = P
        omega = np.arange(0, 4000, 10.0)
        accel_psd = 1.0 / ((omega - 1533.0) ** 2 + 25.0)

    # a fifth of a bin (0.13 %), well inside the check's 1 %
    assert resonance_peak(Result) == pytest.approx(1533.0, abs=2.0)


def test_paired_ratio_by_hand():
    x = np.array([2.0, 4.0, 6.0])
    ratio, rel = paired_ratio(x, np.array([1.0, 2.0, 3.0]))
    assert ratio == 2.0 and rel == 0.0  # exactly proportional: no scatter
    ratio, rel = paired_ratio(x, 2.0)
    assert ratio == 2.0 and rel == pytest.approx(np.std(x, ddof=1) / math.sqrt(3) / 4.0)


def test_check_result_pass_rules_and_table():
    rows = [
        CheckResult("a", "eq 1", 1.02, 1.0, 0.03, "relative", "-", ""),
        CheckResult("b", "eq 2", 1.04, 1.0, 0.03, "relative", "-", ""),
        CheckResult("c", "eq 3", -4.35, -4.4, 0.1, "absolute", "-", ""),
        CheckResult("d", "eq 4", 29.0, 30.0, 0.0, "minimum", "dB", ""),
    ]
    assert [r.passed for r in rows] == [True, False, True, False]
    table = format_table(rows)
    assert "2/4 passed" in table and table.count("FAIL") == 2
    assert slug("eq 23 slope H=0.5") == "eq_23_slope_H0.5"


def test_validation_ensemble_on_every_device(device):
    p = Params(L=0.03, dx=10e-6)
    s = force_spectra(p, seed=5, n_real=3, algorithms=("direct", "tree"), device=device, eq48=True, batch=2)
    lines = to_numpy(rough_lines(p, 5, 3, device="cpu"))
    direct = contact_force(lines, p, "direct", "periodic")
    q, C = psd(direct, p.dx)
    # FFT rounding differs between devices: bins far below the peak compare at 1e-12 of the peak
    np.testing.assert_allclose(s.mean["direct"][1:], C.mean(axis=0)[1:], rtol=1e-9, atol=1e-12 * C.max())
    _, C48 = psd(edge_quadratic_force(p, lines), p.dx)
    np.testing.assert_allclose(s.mean["eq48"][1:], C48.mean(axis=0)[1:], rtol=1e-9, atol=1e-12 * C48.max())
    assert s.rows["direct"].shape == (3, np.searchsorted(q, 8.5 * p.q_min, side="right"))
    assert s.max_tree_direct <= 1e-12 * p.F_N


def test_mdroll_validate_quick_passes_and_writes_outputs(tmp_path):
    out = tmp_path / "val"
    proc = subprocess.run([sys.executable, "-m", "mdroll", "validate", "--quick", "--device", "cpu", "--out", str(out),
                           "--no-progress"], capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    record = json.loads((out / "validation.json").read_text())
    assert record["passed"] and record["size"] == "quick" and record["device_name"]
    names = [c["name"] for c in record["checks"]]
    for needle in ("tree == direct", "eq 40", "eq 48", "low band shape", "eq 58 factor", "eq 58 H", "eq 21", "eq 23 slope H=0.9",
                   "eq 26", "resonance", "eq 28", "coupled vs decoupled"):
        assert any(needle in n for n in names), needle
    assert all(c["passed"] for c in record["checks"])
    assert (out / "eq_40_high_band.png").read_bytes()[:4] == b"\x89PNG"
    assert "17/17 passed" in proc.stdout


def test_mdroll_validate_rejects_unknown_check():
    proc = subprocess.run([sys.executable, "-m", "mdroll", "validate", "--only", "eq99"], capture_output=True, text=True,
                          cwd=ROOT, timeout=300)
    assert proc.returncode == 2 and "eq99" in proc.stderr and "eq40" in proc.stderr
