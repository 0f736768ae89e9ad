"""The validation layer: the check API's comparisons on synthetic spectra, the ensemble source on
every device against NumPy references, the checks' exactness and constants, and ``mdroll validate --quick`` end to
end (physics.md section 7)."""

import json
import math
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from reference import psd, to_numpy

from mdroll import EnsembleSpec, Params, contact_force, physics, rough_lines
from mdroll.forces import registry as algorithms
from mdroll.ensemble.measure import band_sum, paired_ratio, period_bands
from mdroll.errors import PredictionError
from mdroll.validation import Band, Check, CheckResult, EnsembleSource
from mdroll.validation.checks import SIZES, Context, check_exact_algorithms
from mdroll.validation.references import edge_quadratic_force
from mdroll.validation.report import format_table, slug

ROOT = Path(__file__).resolve().parents[1]
P = Params(L=0.5, dx=20e-6)


def _synthetic(values, params=P, stderr=None):
    """A result-like object with force PSD ``values(q)`` on the grid of ``params``."""
    q = 2 * np.pi * np.arange(params.n_points // 2 + 1) / params.length
    y = values(q)
    return SimpleNamespace(params=params, q=q, omega=q * params.v0, force_psd=y,
                           force_psd_stderr=np.zeros_like(y) if stderr is None else stderr(q), accel_psd=y,
                           accel_psd_stderr=np.zeros_like(y))


def test_period_comparison_of_a_synthetic_spectrum():
    a_true = 1.03 * P.a  # not the params' a: the estimate must come from the data
    s = _synthetic(lambda q: np.sin(q * a_true) ** 2 * np.maximum(q, 1.0) ** -(2 * P.H + 3))
    r = Check("period", None, lambda q, p: math.pi / a_true, Band(1, 24), "period", allowance=0.01).evaluate(s)
    assert r.measured == pytest.approx(math.pi / a_true, rel=2e-3) and r.passed and r.kind == "relative"


def test_slope_comparison_of_a_power_law():
    s = _synthetic(lambda q: np.sin(q * P.a) ** 2 * np.maximum(q, 1.0) ** -4.4)
    r = Check("slope", None, lambda q, p: -4.4, Band(1.5, 8), "slope", allowance=0.1).evaluate(s)
    assert r.measured == pytest.approx(-4.4, abs=0.005) and r.kind == "absolute" and r.tolerance == 0.1
    bands = period_bands(s.q, P.q_min, 8 * P.q_min, P.a)
    assert len(bands) == int((7 * P.q_min) / (math.pi / P.a))
    assert all(np.ptp(s.q[b]) < math.pi / P.a for b in bands)


def test_peak_comparison_of_a_synthetic_response():
    omega = np.arange(0, 4000, 10.0)
    result = SimpleNamespace(params=SimpleNamespace(omega_0=1529.0, q_min=1.0, v0=1.0, a=1.0), q=omega, omega=omega,
                             accel_psd=1.0 / ((omega - 1533.0) ** 2 + 25.0), accel_psd_stderr=0 * omega)
    r = Check("peak", None, lambda w, p: p.omega_0, Band(0.5, 2.0, "omega_0"), "peak", allowance=0.01,
              quantity="accel").evaluate(result)
    # a fifth of a bin (0.13 %), well inside the check's 1 %
    assert r.measured == pytest.approx(1533.0, abs=2.0) and r.predicted == 1529.0 and r.passed


def test_ratio_comparison_and_its_tolerance():
    # measured = 1.1 x predicted, stderr 1 % per bin: ratio 1.1 and allowance + k x the band's relative error
    s = _synthetic(lambda q: 1.1 * (q + 1.0) ** -3.0, stderr=lambda q: 0.011 * (q + 1.0) ** -3.0)
    band = Band(1, 2)
    mask = band.mask(s.q, P)
    r = Check("ratio", None, lambda q, p: (q + 1.0) ** -3.0, band, allowance=0.05, k=2.0).evaluate(s)
    assert r.measured == pytest.approx(1.1, rel=1e-12) and r.predicted == 1.0
    assert r.tolerance == pytest.approx(0.05 + 2.0 * band_sum(s.force_psd, s.force_psd_stderr, mask)[1], rel=1e-12)
    assert not r.passed  # 10 % off, tolerance 5 % + 2 x 0.1 %
    assert mask.sum() == np.count_nonzero((s.q >= P.q_min * (1 - 1e-12)) & (s.q < 2 * P.q_min))


@pytest.mark.parametrize("prediction, needle", [(lambda q, p: 1 / 0, "ZeroDivisionError"),
                                                (lambda q, p: np.full_like(q, np.nan), "NaN"),
                                                (lambda q, p: np.ones(3), "shape")])
def test_bad_predictions_are_named(prediction, needle):
    s = _synthetic(lambda q: q + 1.0)
    with pytest.raises(PredictionError, match=f"check 'mine'.*{needle}"):
        Check("mine", None, prediction, Band(1, 2)).evaluate(s)


def test_check_refuses_inconsistent_settings():
    for kwargs, needle in [({"comparison": "slope", "band": Band(1, 2, "omega_0")}, "measured on q"),
                           ({"paired": True, "quantity": "accel"}, "paired"),
                           ({"comparison": "mean"}, "comparison"), ({"allowance": -0.1}, "allowance"),
                           ({"band": (1, 2)}, "band")]:
        with pytest.raises(ValueError, match=needle):
            Check(**{"name": "c", "spec": None, "prediction": lambda q, p: 1.0, "band": Band(1, 2), **kwargs})
    with pytest.raises(ValueError, match="lo < hi"):
        Band(2, 1)


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
    exact = CheckResult("x == direct", "section 4", 2e-15, 0.0, 1e-12, "absolute", "F_N", "")
    assert exact.passed and exact.as_dict()["ratio"] is None and json.dumps(exact.as_dict(), allow_nan=False)
    assert format_table([exact]).splitlines()[2].split()[-3] == "-"


class _Differences:
    """A stand-in ensemble source whose exact algorithms differ from direct by ``diff`` F_N."""

    def __init__(self, diff):
        self.diff = diff
        self.asked = []

    def force_differences(self, spec, algorithms, reference):
        self.asked.append((list(algorithms), reference))
        return {name: self.diff * spec.params.F_N for name in algorithms}

    def result(self, spec):
        return SimpleNamespace(force_psd=np.ones(3), q=np.arange(3.0))


def test_exactness_check_predicts_zero_within_1e12(monkeypatch):
    # the check states max |dF| <= 1e-12 F_N: 1.5e-12 F_N must fail, not pass as predicted +- tolerance would
    results = check_exact_algorithms(Context(SIZES["quick"], 0, _Differences(1.5e-12)))
    assert results and all(r.predicted == 0.0 and r.tolerance == 1e-12 and not r.passed for r in results)
    assert all(r.passed for r in check_exact_algorithms(Context(SIZES["quick"], 0, _Differences(1e-12))))
    # every exact algorithm of the registry, from the registry (a new exact entry is checked too)
    monkeypatch.setitem(algorithms.REGISTRY, "exact-twin", algorithms.REGISTRY["tree"])
    source = _Differences(0.0)
    names = [r.name for r in check_exact_algorithms(Context(SIZES["quick"], 0, source))]
    exact = [n for n, e in algorithms.REGISTRY.items() if e.exact and n != "direct"]
    assert names == [f"{n} == direct" for n in exact] and "exact-twin == direct" in names
    assert source.asked == [(exact, "direct")]


def test_validation_constants_come_from_physics():
    # no literal pi/a or 0.277 in the validation layer (physics.modulation_period, THESIS_HURST_OFFSET)
    for path in (ROOT / "mdroll" / "validation").glob("*.py"):
        text = path.read_text()
        assert not re.search(r"math\.pi\s*/\s*\w+\.a\b", text) and "0.277" not in text, path


def test_ensemble_source_on_every_device(device):
    # the paired rows, the eq 48 rows and the force difference against NumPy references of the same lines
    p = Params(L=0.03, dx=10e-6)
    spec = EnsembleSpec(p, seed=5, realizations=3, algorithm="direct", boundary="periodic")
    source = EnsembleSource(device)
    paired = source.paired(spec)
    lines = to_numpy(rough_lines(p, 5, 3, device="cpu"))
    q, C = psd(contact_force(lines, p, "direct", "periodic"), p.dx)
    kept = paired.rows.shape[1]
    assert kept == np.searchsorted(q, 8.5 * p.q_min, side="right")
    # FFT rounding differs between devices: bins far below the peak compare at 1e-12 of the peak
    np.testing.assert_allclose(paired.rows[:, 1:], C[:, 1:kept], rtol=1e-9, atol=1e-12 * C.max())
    np.testing.assert_allclose(paired.result.force_psd[1:], C.mean(axis=0)[1:], rtol=1e-9, atol=1e-12 * C.max())
    rows48 = source.series_rows(spec, "eq48", edge_quadratic_force, 8.5 * p.q_min)
    _, C48 = psd(edge_quadratic_force(p, lines), p.dx)
    np.testing.assert_allclose(rows48[:, 1:], C48[:, 1:kept], rtol=1e-9, atol=1e-12 * C48.max())
    assert source.force_differences(spec, ["tree"]) == {"tree": pytest.approx(0.0, abs=1e-12 * p.F_N)}


def test_mdroll_validate_quick_passes_and_writes_outputs(tmp_path):
    out = tmp_path / "val"
    proc = subprocess.run([sys.executable, "-m", "mdroll", "validate", "--quick", "--device", "cpu", "--out", str(out),
                           "--no-progress", "--no-cache"], capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    record = json.loads((out / "validation.json").read_text())
    assert record["passed"] and record["size"] == "quick" and record["environment"]["device_name"]
    names = [c["name"] for c in record["checks"]]
    exact = [n for n, e in algorithms.REGISTRY.items() if e.exact and n != "direct"]
    for needle in [f"{n} == direct" for n in exact] + [
            "eq 40", "eq 48", "low band shape", "eq 58 factor", "eq 58 H", "eq 21", "eq 23 slope H=0.9", "eq 26",
            "resonance", "eq 28", "coupled vs decoupled"]:
        assert any(needle in n for n in names), needle
    assert all(c["passed"] for c in record["checks"])
    assert (out / "eq_40_high_band.png").read_bytes()[:4] == b"\x89PNG"
    assert f"{len(exact) + 16}/{len(exact) + 16} passed" in proc.stdout
