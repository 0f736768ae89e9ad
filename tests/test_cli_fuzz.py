"""Generated inputs for the command line: whatever ``--set`` values and TOML files a
user writes, ``mdroll`` ends with exit 0 and finite outputs, or exit 2 and one line on stderr;
never a traceback, a hang or another exit code.

The CLI runs in this process (:func:`mdroll.cli.main`) on tiny lines; the host is made to look
small (64 MiB), so that any long line is refused by the memory check instead of computed."""

import dataclasses
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import mdroll.plotting
from mdroll import EnsembleResult, Params, cli
from mdroll.cli.common import PARAM_NAMES
from mdroll.ensemble import batching
from mdroll.params import ROUGHNESS_LEVELS, ROUGHNESS_MODELS, SPECTRUM_KINDS, TEXT_FIELDS

NAMES = PARAM_NAMES
TINY = {"L": 0.025, "dx": 2.5e-5}
DEFAULTS = {**Params().as_dict(), **TINY, "q_max": math.pi / TINY["dx"], "n_real": 1}
SPECIAL = [0.0, -1.0, 1e-300, 1e300, 1e100, float("nan"), float("inf"), -float("inf"), 5e-324]


ROUGHNESS_WORDS = [*ROUGHNESS_MODELS, *SPECTRUM_KINDS, *ROUGHNESS_LEVELS, "missing.csv"]


def _value(name: str):
    """A value for parameter ``name``: near its (tiny-run) default, an extreme, or any float; for a
    text field (the roughness model's) one of its words or any short text."""
    if name in TEXT_FIELDS:
        return st.one_of(st.sampled_from(ROUGHNESS_WORDS), st.text(max_size=4), st.floats())
    default = DEFAULTS[name] if DEFAULTS[name] is not None else DEFAULTS["q_min"]  # q_r: None means q_min
    near = st.floats(-3, 3).map(lambda exponent: default * 10.0**exponent)
    if name == "n_real":
        return st.one_of(st.integers(-2, 3), st.sampled_from([10**12, 2.5]))
    return st.one_of(near, near, st.sampled_from(SPECIAL), st.floats(allow_nan=True, allow_infinity=True))


def _settings_of(names):
    return st.fixed_dictionaries({}, optional={name: _value(name) for name in names})


TEXT = st.text(alphabet="0123456789.e+-xn", max_size=6)
SETS = st.lists(st.one_of(
    st.tuples(st.sampled_from(NAMES), st.one_of(_value("H"), _value("h0"), _value("dx"), _value("v0"))),
    st.tuples(st.sampled_from([*NAMES, "Hurst", ""]), TEXT),
).map(lambda kv: f"{kv[0]}={kv[1]!r}" if isinstance(kv[1], float) else f"{kv[0]}={kv[1]}"), max_size=3)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else "inf" if value == math.inf else "-inf" if value == -math.inf else repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    return str(value)


TOML_SCALAR = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 10**6), st.booleans(),
                        st.text(max_size=4))
TOML_FILE = st.tuples(
    _settings_of(NAMES),  # top level
    st.one_of(st.none(), _settings_of(NAMES)),  # a [params] table
    st.dictionaries(st.sampled_from(["run", "params2"]), st.dictionaries(st.sampled_from(NAMES), TOML_SCALAR), max_size=1),
    st.dictionaries(st.sampled_from(["Hurst", "seed", "params"]), TOML_SCALAR, max_size=1),  # stray keys
)


def _toml_text(top, table, others, stray) -> str:
    lines = [f"{k} = {_toml_value(v)}" for k, v in {**top, **stray}.items()]
    for name, body in ([("params", table)] if table is not None else []) + list(others.items()):
        lines.append(f"[{name}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in body.items()]
    return "\n".join(lines) + "\n"


@pytest.fixture
def small_host(monkeypatch):
    monkeypatch.setattr(batching, "host_available_bytes", lambda: 64 * 2**20)
    monkeypatch.setattr(mdroll.plotting, "plot_psd", lambda result, quantity, path: path.write(b"\x89PNG"))


def _check_outcome(capsys, args, out: Path):
    code = cli.main(args)
    captured = capsys.readouterr()
    err = [line for line in captured.err.splitlines() if "CUDA driver" not in line]
    assert "Traceback" not in captured.err, captured.err
    event(f"exit {code}")
    if code == 2:
        assert len(err) == 1 and err[0].startswith("mdroll: error: "), (args, err)
        return
    assert code == 0, (args, code, err)
    assert all(line.startswith("mdroll: warning: ") for line in err), err
    if args[0] == "run":
        result = EnsembleResult.load(out / "spectra.npz")
        for name in ("force_psd", "accel_psd", "force_psd_stderr", "accel_psd_stderr"):
            assert np.isfinite(getattr(result, name)).all(), name
        assert math.isfinite(result.force_mean) and math.isfinite(result.force_rms)
        summary = json.loads((out / "summary.json").read_text())
        assert math.isfinite(summary["force_rms_N"])


#: MDROLL_FUZZ_EXAMPLES=1000 for a deeper search than the suite's
FUZZ = settings(max_examples=int(os.environ.get("MDROLL_FUZZ_EXAMPLES", 25)), deadline=30_000, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                          HealthCheck.too_slow])


@FUZZ
@given(sets=SETS, command=st.sampled_from(["run", "params"]), force_physics=st.booleans(),
       choices=st.tuples(st.sampled_from(["tree", "direct", "edge"]), st.sampled_from(["decoupled", "coupled"]),
                         st.sampled_from(["open", "periodic"])))
def test_any_set_values_end_in_exit_0_or_one_line(small_host, capsys, sets, command, force_physics, choices):
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        args = [command, "--set", f"L={TINY['L']}", "--set", f"dx={TINY['dx']}"]
        args += [a for item in sets for a in ("--set", item)]
        if command == "run":
            args += ["--realizations", "1", "--device", "cpu", "--no-progress", "--out", str(out)]
            args += ["--algorithm", choices[0], "--mode", choices[1], "--boundary", choices[2]]
            args += ["--force-physics"] if force_physics else []
        _check_outcome(capsys, args, out)


@FUZZ
@given(toml=TOML_FILE, force_physics=st.booleans())
def test_any_toml_file_ends_in_exit_0_or_one_line(small_host, capsys, toml, force_physics):
    with tempfile.TemporaryDirectory() as tmp:
        config, out = Path(tmp) / "c.toml", Path(tmp) / "out"
        top, table, others, stray = toml
        # the tiny line unless the file sets L or dx itself
        if table is None:
            top = {**TINY, **top}
        else:
            table = {**TINY, **table}
        config.write_text(_toml_text(top, table, others, stray))
        args = ["run", "--config", str(config), "--realizations", "1", "--device", "cpu", "--no-progress",
                "--out", str(out)] + (["--force-physics"] if force_physics else [])
        _check_outcome(capsys, args, out)


# ----------------------------------------------------------------------------- files a user gives
#: Numbers as a file may hold them: ordinary, extreme, not finite, and text that is no number.
CELL = st.one_of(st.floats(1e-3, 1e4), st.floats(1e-3, 1e4), st.sampled_from(SPECIAL),
                 st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(["", "x", "1e", "--1"]))


def _csv(rows) -> str:
    return "\n".join(",".join(c if isinstance(c, str) else repr(c) for c in row) for row in rows) + "\n"


def _power_law_rows(n: int, columns: int) -> list:
    f = np.geomspace(20.0, 2e4, n)
    return [[float(x), float(1e-3 * x**-1.5), float(1e-4 * x**-1.5)][:columns] for x in f]


TABLE = st.tuples(st.one_of(st.just(36), st.integers(0, 40)), st.sampled_from([2, 2, 3, 3, 1, 4]),
                  st.lists(st.tuples(st.integers(0, 39), st.integers(0, 3), CELL), max_size=2))
FIT_OPTIONS = st.lists(st.sampled_from([[], [], [],
    ["--passes", "4"], ["--passes", "0"], ["--bin", "2"], ["--bin", "-1"], ["--band", "30:3000Hz"], ["--band", "5:1"],
    ["--known", "v0=-3"], ["--known", "H=0.8"], ["--free", "H,h0"], ["--free", "nope"], ["--quantity", "force"],
    ["--window"], ["--bootstrap", "3"], ["--passes", "2.5"]]), max_size=2)
#: A fit takes seconds: fewer examples than the other fuzz tests.
FEWER = settings(FUZZ, max_examples=max(1, FUZZ.max_examples // 2))


@FEWER
@given(table=TABLE, options=FIT_OPTIONS, declared=st.sampled_from([True, True, True, False]))
def test_any_invert_table_ends_in_exit_0_or_one_line(small_host, capsys, table, options, declared):
    """A CSV table with cells replaced by anything and rows of any width, fitted with any options."""
    rows_count, columns, edits = table
    rows = _power_law_rows(rows_count, min(columns, 3))
    for row, column, cell in edits:
        if row < len(rows):
            rows[row][min(column, len(rows[row]) - 1)] = cell
    if columns == 4 and rows:
        rows[0].append(1.0)
    with tempfile.TemporaryDirectory() as tmp:
        path, out = Path(tmp) / "t.csv", Path(tmp) / "out"
        path.write_text(_csv(rows))
        args = ["invert", str(path), "--known", "v0=20", "--known", "m=500", "--known", "R=0.5", "--no-profile",
                "--correction", "none", "--fill-check", "off", "--discrepancy", "0", "--device", "cpu", "--no-progress",
                "--out", str(out)]
        args += ["--frequency-unit", "Hz", "--sided", "one", "--density", "Hz"] if declared else []
        _check_outcome(capsys, args + [a for option in options for a in option], out)


@pytest.fixture(scope="module")
def part(tmp_path_factory):
    """A finished run of two realizations (the part every merge case starts from)."""
    out = tmp_path_factory.mktemp("part") / "run"
    args = ["run", "--set", f"L={TINY['L']}", "--set", f"dx={TINY['dx']}", "--realizations", "2", "--device", "cpu",
            "--no-progress", "--out", str(out)]
    assert cli.main(args) == 0
    return EnsembleResult.load(out / "spectra.npz")


META_EDITS = st.sampled_from([
    ("realizations", None), ("realizations", []), ("realizations", [0, 0]), ("realizations", [2, 3]),
    ("realizations", ["a", 1]), ("n_real", 3), ("n_real", 0), ("n_real", "2"), ("mdroll_version", "9.9"),
    ("seed", 1), ("window", True), ("params", {"L": 1}), ("params", {"n_real": 2}), ("params", {"n_real": 3}),
    ("steps", -1), (None, None)])
ARRAY_EDITS = st.tuples(st.sampled_from(["q", "force_psd", "accel_psd_stderr"]),
                        st.sampled_from(["nan", "negative", "short", "grid", "none"]))


@FUZZ
@given(edits=st.lists(st.tuples(META_EDITS, ARRAY_EDITS), min_size=1, max_size=3))
def test_any_merge_parts_end_in_a_sound_merge_or_one_line(small_host, capsys, part, edits):
    """Parts whose metadata or arrays were edited: merged only when their content is sound (then
    the merged count is the parts' realizations, each once), else one line."""
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for number, ((key, value), (name, damage)) in enumerate(edits):
            first = 2 * number
            result = dataclasses.replace(part, realizations=[first, first + 1])
            path = Path(tmp) / f"p{number}.npz"
            result.save(path)
            with np.load(path) as data:
                arrays = {k: data[k] for k in data.files}
            meta = json.loads(str(arrays.pop("meta")))
            if key is not None:
                meta[key] = value if key != "params" else {**meta["params"], **value}
            values = arrays[name]
            if damage == "nan":
                values[1] = np.nan
            elif damage == "negative":
                values[1] = -values[1] - 1.0
            elif damage == "short":
                arrays[name] = values[:-1]
            elif damage == "grid":
                values *= 1.5
            np.savez(path, meta=json.dumps(meta), **arrays)
            paths.append(str(path))
        out = Path(tmp) / "out"
        code = cli.main(["merge", *paths, "--out", str(out)])
        err = capsys.readouterr().err.splitlines()
        event(f"exit {code}")
        if code == 2:
            assert len(err) == 1 and err[0].startswith("mdroll: error: "), err
            return
        assert code == 0, err
        merged = EnsembleResult.load(out / "spectra.npz")
        assert merged.n_real == 2 * len(edits) == len(set(merged.realizations))
        assert np.isfinite(merged.force_psd).all() and (merged.force_psd >= 0).all()


PROFILE = st.tuples(st.integers(0, 300), st.sampled_from([1e-6, 1.0, 1e-3, 36.0]), st.integers(1, 3),
                    st.lists(st.tuples(st.integers(0, 299), CELL), max_size=3))


@FUZZ
@given(profile=PROFILE, dx=st.one_of(st.none(), st.sampled_from(["1e-4", "-1e-4", "0", "nan", "1e3", "1e-4x"])),
       segment=st.one_of(st.none(), st.sampled_from(["0.005", "-1", "1e9", "inf"])))
def test_any_profile_ends_in_exit_0_or_one_line(small_host, capsys, profile, dx, segment):
    """A profile of any length, scale and width, with cells replaced by anything, any --dx and --segment."""
    count, scale, columns, edits = profile
    x = 1e-4 * np.arange(count)
    h = scale * np.sin(x * 3e3)
    rows = [[float(a), float(b)][-columns:] if columns < 3 else [float(a), float(b), 0.0] for a, b in zip(x, h)]
    for row, cell in edits:
        if row < len(rows):
            rows[row][-1] = cell
    with tempfile.TemporaryDirectory() as tmp:
        path, out = Path(tmp) / "p.csv", Path(tmp) / "out"
        path.write_text(_csv(rows))
        args = ["roughness", "profile", str(path), "--out", str(out)]
        args += [f"--dx={dx}"] if dx is not None else []
        args += [f"--segment={segment}"] if segment is not None else []
        _check_outcome(capsys, args, out)
        if (out / "profile_psd.csv").exists():
            assert np.isfinite(np.loadtxt(out / "profile_psd.csv", delimiter=",", skiprows=2)).all()


CHECK_VALUE = st.one_of(TOML_SCALAR, st.lists(TOML_SCALAR, max_size=3), st.sampled_from(["math:sqrt", "ratio", "q_min"]))
CHECK_TABLE = st.dictionaries(
    st.sampled_from(["name", "prediction", "comparison", "band", "band_unit", "whole_periods", "allowance", "k",
                     "quantity", "paired", "equation", "unit", "note", "stray"]), CHECK_VALUE, max_size=6)


def _toml_any(value) -> str:
    return "[" + ", ".join(_toml_value(v) for v in value) + "]" if isinstance(value, list) else _toml_value(value)


@FUZZ
@given(tables=st.lists(st.tuples(CHECK_TABLE, st.dictionaries(st.sampled_from(["seed", "realizations", "mode", "params"]),
                                                               CHECK_VALUE, max_size=2)), max_size=2),
       providers=st.one_of(st.none(), CHECK_VALUE))
def test_any_checks_file_ends_in_one_line_before_any_work(small_host, capsys, monkeypatch, tables, providers):
    """A checks file of any keys and values of any type: refused in one line before an ensemble
    runs (the ensemble runner is made to fail, so that a file read as sound shows)."""
    import mdroll.cli.validate

    monkeypatch.setattr(mdroll.cli.validate, "run_checks", lambda *a, **k: pytest.fail("a checks file was accepted"))
    lines = [] if providers is None else [f"providers = {_toml_any(providers)}"]
    for table, spec in tables:
        table = {"name": "c", "prediction": "math:sqrt", "band": [1, 4], **table}
        lines += ["[[check]]"] + [f"{k} = {_toml_any(v)}" for k, v in table.items()]
        if spec:
            lines += ["[check.spec]"] + [f"{k} = {_toml_any(v)}" for k, v in spec.items()]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "checks.toml"
        path.write_text("\n".join(lines) + "\n")
        try:
            code = cli.main(["validate", "--checks", str(path), "--device", "cpu", "--out", str(Path(tmp) / "o")])
        except BaseException as exc:  # pytest.fail: only a sound file reaches the runner
            assert "accepted" in str(exc)
            return
        err = capsys.readouterr().err.splitlines()
        assert code == 2 and len(err) == 1 and err[0].startswith("mdroll: error: "), (lines, err)
