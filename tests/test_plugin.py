"""The pytest plugin (mdroll.testing.plugin) in a subprocess on examples/ci-check, its failure
message, its device parametrization, its cache, and that importing it stays light."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "ci-check"

WRONG_LAW = '''
from mdroll.testing import assert_spectrum_matches
from lowband_law import low_band_psd
from lowband_law.checks import BAND, SPEC


def test_doubled_law(mdroll_ensemble):
    assert_spectrum_matches(mdroll_ensemble(SPEC), lambda q, p: 2 * low_band_psd(q, p), BAND, allowance=0.10)
'''


def _pytest(*args, cwd, cache):
    # the plugin by -p, as a CI that has not installed mdroll's entry points would (autoload off: no double load)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(EXAMPLE), str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]), "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1",
           "MDROLL_CACHE_DIR": str(cache)}
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "mdroll.testing.plugin", "-p", "no:cacheprovider",
                           "-rN", *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=300)


def test_example_through_the_plugin(tmp_path):
    wrong = tmp_path / "test_wrong_law.py"
    wrong.write_text(WRONG_LAW)
    proc = _pytest(str(EXAMPLE / "tests"), str(wrong), "--mdroll-device", "cpu", "-v", cwd=tmp_path,
                   cache=tmp_path / "cache")
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1, out
    assert "test_corrected_plateau[cpu] PASSED" in out and "test_doubled_law[cpu] FAILED" in out
    # the failure shows measured vs predicted, the ratio, the tolerance and the bins
    message = out[out.index("AssertionError"):]
    for needle in ("measured 0.", "predicted 1", "ratio 0.", "tolerance +-", "bins: 20 in [0, 0.05] q_min",
                   "measured      predicted     ratio"):
        assert needle in message, (needle, message)
    # one ensemble for both tests, run once and cached under its spec's key
    sys.path.insert(0, str(EXAMPLE))
    try:
        from lowband_law.checks import SPEC
    finally:
        sys.path.remove(str(EXAMPLE))
    assert [p.name for p in (tmp_path / "cache").iterdir()] == [SPEC.key() + ".npz"]


def test_plugin_import_is_light():
    # beyond the package root (which imports Warp), the plugin imports no mdroll analysis and no plotting
    code = ("import sys, mdroll.testing.plugin, mdroll.testing; "
            "print(sorted(m for m in ('mdroll.validation', 'matplotlib') if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "[]", proc.stdout + proc.stderr


def test_plugin_fixture_names_leave_the_suites_alone():
    # tests/conftest.py parametrizes `device` and `kernel_device`: the plugin's names are all mdroll_-prefixed
    import mdroll.testing.plugin as plugin

    assert {n for n in vars(plugin) if "mdroll_" in n} == {"mdroll_ensemble", "_mdroll_sources"}
    assert not {"device", "kernel_device", "cli", "one_line_error"} & set(vars(plugin))
