"""mdroll validate with a user's checks: discovery by module:function, TOML and entry points, the
ensemble cache, JUnit XML parsed back, and the exit codes (0 pass, 1 a check failed, 2 bad input)."""

import json
import sys
import textwrap
import xml.etree.ElementTree as ET
from importlib.metadata import EntryPoint
from pathlib import Path

import numpy as np
import pytest

import mdroll._version
from mdroll import EnsembleSpec, Params
from mdroll.cli import main
from mdroll.validation import EnsembleCache, checks_from_toml, discovery, run_checks, select
from mdroll.validation.cache import CACHE_ENV, default_cache_dir

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "ci-check"

USER_CHECKS = '''
import numpy as np
from mdroll import EnsembleSpec, Params, physics
from mdroll.validation import Band, Check

SPEC = EnsembleSpec(Params(L=0.03, dx=10e-6), seed=3, realizations=4, boundary="periodic", window=False)
HIGH = Band(1, 8, whole_periods=True)


def eq40(q, p):
    return physics.force_psd_high_band(q, p.lambda_A, p.H, p.q_min, p.q_max, p.E_star, p.a)


def good():
    return Check("eq 40 mine", SPEC, eq40, HIGH, allowance=0.1, equation="eq 40")


def doubled(context):  # a provider may take the validation context
    return [Check("eq 40 doubled", SPEC, lambda q, p: 2 * eq40(q, p), HIGH, allowance=0.1)]


def raising():
    return Check("raises", SPEC, lambda q, p: 1 / 0, HIGH)


def nan():
    return Check("gives nan", SPEC, lambda q, p: q * np.nan, HIGH)
'''


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    """A module ``userchecks`` of check providers on sys.path, and a private cache directory."""
    (tmp_path / "userchecks.py").write_text(USER_CHECKS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    sys.modules.pop("userchecks", None)
    return tmp_path


def _validate(tmp_path, *args):
    return main(["validate", "--device", "cpu", "--no-progress", "--out", str(tmp_path / "out"), "--force", *args])


def test_module_function_checks_junit_xml_and_exit_codes(user_module, capsys):
    junit = user_module / "report.xml"
    assert _validate(user_module, "--check", "userchecks:good", "--junit-xml", str(junit)) == 0
    assert _validate(user_module, "--check", "userchecks:good", "--check", "userchecks:doubled",
                     "--junit-xml", str(junit)) == 1
    suite = ET.parse(junit).getroot().find("testsuite")
    assert suite.get("tests") == "2" and suite.get("failures") == "1"
    cases = {c.get("name"): c for c in suite.iter("testcase")}
    assert set(cases) == {"eq 40 mine", "eq 40 doubled"}
    props = {p.get("name"): p.get("value") for p in cases["eq 40 doubled"].iter("property")}
    record = {c["name"]: c for c in json.loads((user_module / "out" / "validation.json").read_text())["checks"]}
    # the properties are the JSON's numbers; the doubled prediction halves the ratio
    assert float(props["measured"]) == record["eq 40 doubled"]["measured"]
    assert float(props["measured"]) == pytest.approx(record["eq 40 mine"]["measured"] / 2, rel=1e-12)
    assert float(props["tolerance"]) == record["eq 40 doubled"]["tolerance"] and props["predicted"] == "1.0"
    failure = cases["eq 40 doubled"].find("failure")
    assert failure is not None and "ratio" in failure.get("message") and cases["eq 40 mine"].find("failure") is None
    assert not list(user_module.glob(".report.xml.*"))  # written atomically, no temporary left


@pytest.mark.parametrize("args, needle", [
    (["--only", "eq99"], "eq99"),
    (["--check", "userchecks:missing"], "no attribute 'missing'"),
    (["--check", "no_such_module:f"], "no_such_module"),
    (["--check", "userchecks"], "package.module:function"),
    (["--check", "userchecks:raising"], "check 'raises': its prediction raised ZeroDivisionError"),
    (["--check", "userchecks:nan"], "check 'gives nan': its prediction returned NaN"),
    (["--checks", "nowhere.toml"], "nowhere.toml"),
    (["--junit-xml", "/nonexistent/dir/r.xml"], "--junit-xml"),
])
def test_bad_input_is_one_line_and_exit_2(user_module, capsys, args, needle):
    assert _validate(user_module, *args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and "Traceback" not in err[0], err


def test_toml_checks(user_module):
    path = user_module / "checks.toml"
    path.write_text(textwrap.dedent('''
        providers = ["userchecks:good"]

        [[check]]
        name = "eq 40 from toml"
        prediction = "userchecks:eq40"
        band = [1, 8]
        whole_periods = true
        allowance = 0.1
        equation = "eq 40"

        [check.spec]
        seed = 3
        realizations = 4
        boundary = "periodic"
        [check.spec.params]
        L = 0.03
        dx = 1e-5

        [[check]]
        name = "h0 doubled"
        prediction = "userchecks:eq40"
        band = [1, 8]
        [check.spec]
        [check.reference]
        realizations = 2
    '''))
    first, second, third = checks_from_toml(path)
    assert callable(first)
    assert second.spec.params == Params(L=0.03, dx=1e-5) and second.spec.realizations == 4
    assert second.band.whole_periods and second.allowance == 0.1 and second.k == 3.0
    assert third.reference.realizations == 2 and third.spec.realizations == 1
    path.write_text(path.read_text().split("[[check]]")[0] + '[[check]]\nname = "x"\nbandd = [1, 2]\n')
    with pytest.raises(ValueError, match="check 1: unknown key.*bandd"):
        checks_from_toml(path)
    path.write_text('providers = ["userchecks:good"]\n[[check]]\nname = "eq 40 from toml"\nprediction = '
                    '"userchecks:eq40"\nband = [1, 8]\nwhole_periods = true\nallowance = 0.1\n[check.spec]\nseed = 3\n'
                    'realizations = 4\nboundary = "periodic"\n[check.spec.params]\nL = 0.03\ndx = 1e-5\n')
    assert _validate(user_module, "--checks", str(path)) == 0
    (user_module / "empty.toml").write_text("# nothing\n")
    with pytest.raises(ValueError, match="holds no"):
        select(files=[user_module / "empty.toml"])
    names = [c["name"] for c in json.loads((user_module / "out" / "validation.json").read_text())["checks"]]
    assert names == ["eq 40 mine", "eq 40 from toml"]


def test_entry_point_discovery(monkeypatch):
    # an installed package's checks, as importlib.metadata lists them (the example's pyproject declares this one)
    monkeypatch.syspath_prepend(str(EXAMPLE))
    point = EntryPoint(name="lowband", value="lowband_law.checks:checks", group=discovery.ENTRY_POINT_GROUP)
    monkeypatch.setattr(discovery, "entry_points", lambda group: [point] if group == discovery.ENTRY_POINT_GROUP else [])
    providers = select(installed=True)
    from lowband_law.checks import checks

    assert providers == [checks]
    assert 'lowband = "lowband_law.checks:checks"' in (EXAMPLE / "pyproject.toml").read_text()
    broken = EntryPoint(name="broken", value="no_such_package.x:y", group=discovery.ENTRY_POINT_GROUP)
    monkeypatch.setattr(discovery, "entry_points", lambda group: [broken])
    with pytest.raises(ValueError, match="entry point 'broken'.*failed to load"):
        select(installed=True)
    monkeypatch.setattr(discovery, "entry_points", lambda group: [])
    with pytest.raises(ValueError, match="no installed package declares checks"):  # not the built-ins instead
        select(installed=True)


def test_ensemble_cache_hit_miss_and_version(tmp_path, monkeypatch):
    spec = EnsembleSpec(Params(L=0.03, dx=10e-6), seed=1, realizations=2, boundary="periodic")
    cache = EnsembleCache(tmp_path / "c")
    runs = []

    def compute():
        runs.append(1)
        return spec.run(device="cpu")

    first = cache.result(spec, compute)
    again = cache.result(spec, compute)
    assert len(runs) == 1 and (cache.hits, cache.misses) == (1, 1)
    np.testing.assert_array_equal(again.force_psd, first.force_psd)
    assert cache.path(spec).name == spec.key() + ".npz"
    monkeypatch.setattr(mdroll._version, "__version__", "999.0")  # another mdroll: another key, a miss
    cache.result(spec, compute)
    assert len(runs) == 2 and len(list((tmp_path / "c").glob("*.npz"))) == 2
    monkeypatch.undo()
    cache.path(spec).write_bytes(b"truncated")  # unreadable: recomputed and replaced
    cache.result(spec, compute)
    assert len(runs) == 3 and cache.result(spec, compute).n_real == 2 and len(runs) == 3
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "env"))
    assert default_cache_dir() == tmp_path / "env" and EnsembleCache().directory == tmp_path / "env"


def test_validate_reuses_the_cache_and_no_cache_skips_it(user_module):
    cache = user_module / "c"
    for expected in ((0, 1), (1, 0)):
        assert _validate(user_module, "--check", "userchecks:good", "--cache-dir", str(cache)) == 0
        meta = json.loads((user_module / "out" / "validation.json").read_text())["cache"]
        assert (meta["hits"], meta["misses"]) == expected and meta["dir"] == str(cache)
    assert _validate(user_module, "--check", "userchecks:good", "--no-cache") == 0
    assert "cache" not in json.loads((user_module / "out" / "validation.json").read_text())
    assert not (user_module / "cache").exists()  # MDROLL_CACHE_DIR of the fixture: untouched


def test_run_checks_api_on_a_check_list(user_module):
    import userchecks

    (result,) = run_checks(providers=[userchecks.good()], device="cpu")
    assert result.passed and result.name == "eq 40 mine" and 0.9 < result.measured < 1.1
