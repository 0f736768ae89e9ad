"""Generated inputs for the command line: whatever ``--set`` values and TOML files a
user writes, ``mdroll`` ends with exit 0 and finite outputs, or exit 2 and one line on stderr;
never a traceback, a hang or another exit code.

The CLI runs in this process (:func:`mdroll.cli.main`) on tiny lines; the host is made to look
small (64 MiB), so that any long line is refused by the memory check instead of computed."""

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
