"""A hostile user's corpus, one test per class of bad input: every file is built here (no shipped
binaries), every case ends in one line naming the file or argument (exit 2, ParameterError) or
in a correct result; never a traceback, a silent wrong result or an output folder left behind."""

import dataclasses
import errno
import json
import math
import os
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import mdroll
import mdroll.plotting
from mdroll import EnsembleResult, EnsembleSpec, Params, contact_force, rough_lines, run_ensemble, run_specs
from mdroll.cli import main as cli_main
from mdroll.ensemble import batching
from mdroll.ensemble.validity import parameter_concerns
from mdroll.inverse import fit, from_result, read_spectrum, table_spectrum
from mdroll.inverse import observed
from mdroll.inverse.roundtrip import run_study
from mdroll.plotting import plot_psd
from mdroll.roughness.line_grid import line_rms

TINY = ["--set", "L=0.025", "--set", "dx=2.5e-5", "--device", "cpu", "--no-progress"]
#: Library text that must never reach a user's error line.
INTERNALS = ("codec can't decode", "allow_pickle", "Object arrays", "could not convert", "broadcast", "unpack", "math domain",
             "Traceback", "object has no attribute", "not subscriptable", "Eigenvalues")


@pytest.fixture(autouse=True)
def small_plots(monkeypatch):
    """PNGs as a few bytes (the plots are not what these tests check), and a 64 MiB host."""
    monkeypatch.setattr(mdroll.plotting, "plot_psd", lambda result, quantity, path: path.write(b"\x89PNG"))
    monkeypatch.setattr(batching, "host_available_bytes", lambda: 64 * 2**20)


def _main(capsys, *args):
    code = cli_main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, [line for line in captured.err.splitlines() if "CUDA driver" not in line]


def _refused(capsys, needle, *args) -> str:
    code, _, err = _main(capsys, *args)
    assert code == 2 and len(err) == 1 and err[0].startswith("mdroll: error: "), (code, err)
    assert needle in err[0], err[0]
    assert not any(text in err[0] for text in INTERNALS), err[0]
    return err[0]


@pytest.fixture(scope="module")
def part(tmp_path_factory):
    """A finished decoupled power-law run of realizations 0 and 1 (a run directory)."""
    out = tmp_path_factory.mktemp("part") / "run"
    assert cli_main(["run", *TINY, "--realizations", "2", "--out", str(out)]) == 0
    return out


def _saved(tmp_path, result, name, meta_change=None, arrays_change=None) -> Path:
    """``result`` saved as ``name``, then its metadata and arrays edited as a hostile user would."""
    path = tmp_path / name
    result.save(path)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays.pop("meta")))
    (meta_change or (lambda m: None))(meta)
    (arrays_change or (lambda a: None))(arrays)
    np.savez(path, meta=json.dumps(meta), **arrays)
    return path


# ----------------------------------------------------------------------------- merge
MERGE_CASES = [
    ("realization list missing", lambda m: m.pop("realizations"), None, "realization list"),
    ("n_real disagrees", lambda m: m.update(n_real=3), None, "n_real = 3"),
    ("duplicate in a part", lambda m: m.update(realizations=[2, 2]), None, "distinct"),
    ("NaN bin", None, lambda a: a["force_psd"].__setitem__(3, np.nan), "force_psd[3]"),
    ("negative bin", None, lambda a: a["accel_psd"].__setitem__(2, -1.0), "accel_psd[2]"),
    ("negative stderr", None, lambda a: a["force_psd_stderr"].__setitem__(2, -1.0), "force_psd_stderr[2]"),
    ("other grid", None, lambda a: a.update(q=a["q"] * 1.01), "grid"),
    ("short array", None, lambda a: a.update(accel_psd=a["accel_psd"][:-1]), "accel_psd has shape"),
    ("other version", lambda m: m.update(mdroll_version="9.0.0"), None, "mdroll 0"),
    ("other seed", lambda m: m.update(seed=7), None, "seed: 0 vs 7"),
    ("same realizations", lambda m: m.update(realizations=[0, 1]), None, "share realizations [0, 1]"),
    ("pickled metadata", None, lambda a: a.update(force_psd=np.array([{}], dtype=object)), "not an mdroll spectra"),
]


@pytest.mark.parametrize("meta_change,arrays_change,needle", [c[1:] for c in MERGE_CASES], ids=[c[0] for c in MERGE_CASES])
def test_merge_checks_each_part_on_its_content(part, tmp_path, capsys, meta_change, arrays_change, needle):
    good = EnsembleResult.load(part / "spectra.npz")
    second = dataclasses.replace(good, realizations=[2, 3])
    bad = _saved(tmp_path, second, "bad.npz",
                 (lambda m: (m.update(realizations=[2, 3]), meta_change(m))) if meta_change else None, arrays_change)
    out = tmp_path / "merged"
    _refused(capsys, needle, "merge", part, bad, "--out", out)
    assert not out.exists()


def test_a_sound_merge_counts_each_realization_once(part, tmp_path, capsys):
    """The control: two sound parts merge to their per-bin mean (numpy on the two)."""
    good = EnsembleResult.load(part / "spectra.npz")
    other = _saved(tmp_path, dataclasses.replace(good, realizations=[2, 3], force_psd=2 * good.force_psd), "b.npz")
    assert _main(capsys, "merge", part, other, "--out", tmp_path / "m")[0] == 0
    merged = EnsembleResult.load(tmp_path / "m" / "spectra.npz")
    assert merged.realizations == [0, 1, 2, 3] and merged.n_real == 4
    np.testing.assert_allclose(merged.force_psd, 1.5 * good.force_psd, rtol=1e-12)


# ----------------------------------------------------------------------------- roughness validity
def _levels(tmp_path, level_db):
    path = tmp_path / "bands.csv"
    path.write_text("wavelength_mm,level_db\n" + "".join(f"{w},{level_db}\n" for w in (100, 50, 25, 12.5, 6.3, 3.15)))
    return path


def _table(tmp_path, scale):
    q = np.geomspace(10.0, 1e5, 40)
    path = tmp_path / "table.csv"
    np.savetxt(path, np.column_stack([q, scale * q**-3.0]), delimiter=",")
    return path


ROUGH_CASES = [
    ("iso3095", lambda tmp: {"roughness": "iso3095", "L": 1.0, "dx": 1e-4}),
    ("bands", lambda tmp: {"roughness": "bands", "roughness_table": str(_levels(tmp, 30.0)), "L": 0.5, "dx": 1e-4}),
    ("table", lambda tmp: {"roughness": "table", "roughness_table": str(_table(tmp, 1e-4)), "L": 0.5, "dx": 1e-4}),
]


@pytest.mark.parametrize("make", [c[1] for c in ROUGH_CASES], ids=[c[0] for c in ROUGH_CASES])
def test_the_validity_rule_holds_for_lines_of_their_own_level(tmp_path, capsys, make):
    """A spectrum of its own level is held to the h0 rule by the RMS of the lines it makes: the
    RMS the refusal quotes is that of the generated lines (numpy on rough_lines)."""
    values = make(tmp_path)
    params = Params(**values)
    lines = rough_lines(params, 0, 2)
    rms = float(np.sqrt(np.mean(lines**2)))
    assert line_rms(params) == pytest.approx(rms, rel=1e-6)
    assert rms > 0.1 * params.d0  # the case is outside the rule ...
    (concern,) = parameter_concerns(params)
    assert f"{rms:.4g} m" in concern and "% of F_N" in concern
    out = tmp_path / "out"
    _refused(capsys, f"RMS {rms:.4g} m", "run", *[a for k, v in values.items() for a in ("--set", f"{k}={v}")],
             "--realizations", "1", "--device", "cpu", "--out", out)
    assert not out.exists()
    small = params.replace(**({"L": 0.05, "dx": 5e-5} if values["roughness"] == "iso3095" else {"roughness_level": "rms"}))
    assert parameter_concerns(small) == []  # ... and the rule passes a small one


# ----------------------------------------------------------------------------- invert input
def _npz_table(tmp_path, scale=1e-3, **extra):
    f = np.geomspace(20.0, 2e4, 40)
    path = tmp_path / "t.npz"
    np.savez(path, frequency=f, psd=scale * f**-1.5, frequency_unit="Hz", sided="one", density="Hz", **extra)
    return path


INVERT_CASES = [
    ("coupled run", lambda tmp, r: _saved(tmp, dataclasses.replace(r, mode="coupled"), "s.npz"), [], "coupled run"),
    ("non-power-law", lambda tmp, r: _saved(tmp, r, "s.npz", lambda m: m["params"].update(roughness="iso3095")), [],
     "roughness = 'iso3095'"),
    ("one realization", lambda tmp, r: _saved(tmp, dataclasses.replace(r, n_real=1, realizations=[0]), "s.npz"), [],
     "one realization"),
    ("window not recorded", lambda tmp, r: _saved(tmp, dataclasses.replace(r, window=False), "s.npz"), ["--window"],
     "whose run was not windowed"),
    ("quantity contradicted", lambda tmp, r: _npz_table(tmp, quantity="force"), ["--quantity", "accel"],
     "declares quantity 'force'"),
    ("fractional passes", lambda tmp, r: _npz_table(tmp, passes=2.5), [], "passes = 2.5"),
    ("array of units", lambda tmp, r: _npz_table(tmp, passes=np.array([1, 2])), [], "single value"),
    ("pickled table", lambda tmp, r: _npz_table(tmp, stderr=np.array([None] * 40, dtype=object)), [],
     "not a readable NPZ table"),
    ("truncated table", lambda tmp, r: _truncated(_npz_table(tmp)), [], "not a readable NPZ"),
    ("not UTF-8", lambda tmp, r: _write(tmp / "t.csv", b"\xff\xfe1,2\n"), [], "not UTF-8"),
    ("no power", lambda tmp, r: _npz_table(tmp, scale=0.0), ["--known", "v0=20"], "0 bins with power"),
    ("denormal power", lambda tmp, r: _npz_table(tmp, scale=5e-324), ["--known", "v0=20"], "bins with power"),
    ("bootstrap unbounded", lambda tmp, r: tmp / "none.npz", ["--bootstrap", "1000000000"], "2 to 10000"),
    ("passes unbounded", lambda tmp, r: _npz_table(tmp), ["--passes", "1000000000"], "--passes: passes = 1000000000"),
    ("correction passes unbounded", lambda tmp, r: tmp / "none.npz", ["--correction-passes", "1000000000"],
     "from 1 to 100000"),
    ("correction passes on a table", lambda tmp, r: _npz_table(tmp), ["--correction-passes", "5"],
     "without the simulated correction"),
    ("bootstrap of a table", lambda tmp, r: _npz_table(tmp), ["--bootstrap", "5"], "is a table"),
    ("round-trip option", lambda tmp, r: _npz_table(tmp), ["--workers", "4"], "for --round-trip only"),
    ("scheduler without bootstrap", lambda tmp, r: _npz_table(tmp), ["--scheduler", "tcp://x:1"], "give --bootstrap"),
]


def _truncated(path):
    path.write_bytes(path.read_bytes()[:200])
    return path


def _write(path, data: bytes):
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("make,options,needle", [c[1:] for c in INVERT_CASES], ids=[c[0] for c in INVERT_CASES])
def test_invert_refuses_what_its_model_cannot_describe(part, tmp_path, capsys, make, options, needle):
    spectrum = make(tmp_path, EnsembleResult.load(part / "spectra.npz"))
    out = tmp_path / "out"
    _refused(capsys, needle, "invert", spectrum, "--known", "m=500", "--known", "R=0.5", *options, "--out", out)
    assert not out.exists()


ROUND_TRIP_CASES = [
    (["--workers", "1000"], "--workers: workers = 1000"),
    (["--repeats", "1000000000"], "from 1 to 1000 (seeds per truth)"),
    (["--correction-passes", "1000000000"], "--correction-passes: correction_passes = 1000000000"),
    (["--passes-list", "1,1000000000"], "--passes-list: passes = 1000000000"),
    (["--known", "v0=20"], "not for --round-trip"),
    (["--lengths", "1e300"], "--lengths: L = 1e+300 m is not allowed"),
]


@pytest.mark.parametrize("options,needle", ROUND_TRIP_CASES, ids=[c[1] for c in ROUND_TRIP_CASES])
def test_round_trip_counts_are_bounded_before_any_work(tmp_path, capsys, options, needle):
    line = _refused(capsys, needle, "invert", "--round-trip", *options, "--device", "cpu", "--out", tmp_path / "o")
    assert not (tmp_path / "o").exists()


def test_an_npz_table_is_fitted_as_the_quantity_it_declares(tmp_path):
    spectrum = read_spectrum(_npz_table(tmp_path, quantity="force", passes=4))
    assert spectrum.quantity == "force" and spectrum.passes == 4
    f = np.geomspace(20.0, 2e4, 40)
    np.testing.assert_allclose(spectrum.psd, 1e-3 * f**-1.5 / (2 * 2 * math.pi))  # one-sided per Hz -> eq above


def test_a_run_that_recorded_its_window_is_read_with_it(part, tmp_path):
    windowed = _saved(tmp_path, dataclasses.replace(EnsembleResult.load(part / "spectra.npz"), window=True), "w.npz")
    assert read_spectrum(windowed).window is True
    unknown = _saved(tmp_path, EnsembleResult.load(part / "spectra.npz"), "u.npz", lambda m: m.pop("window"))
    assert read_spectrum(unknown, window=True).window is True  # a file that does not say: the user's word


def test_an_optimizer_that_stops_early_is_shown(tmp_path, capsys, monkeypatch):
    fit_module = sys.modules["mdroll.inverse.fit"]

    real = fit_module._minimize

    def abnormal(problem, theta0):
        found = real(problem, theta0)
        found.success, found.message = False, "ABNORMAL: "
        return found

    monkeypatch.setattr(fit_module, "_minimize", abnormal)
    path = _npz_table(tmp_path)
    code, _, err = _main(capsys, "invert", path, "--known", "v0=20", "--known", "m=500", "--known", "R=0.5",
                         "--no-profile", "--correction", "none", "--fill-check", "off", "--out", tmp_path / "o")
    assert code == 0 and any("optimizer stopped without converging (ABNORMAL" in line for line in err), err


# ----------------------------------------------------------------------------- profiles
def _profile(tmp_path, h, x=None, name="p.csv"):
    path = tmp_path / name
    np.savetxt(path, h if x is None else np.column_stack([x, h]), delimiter=",")
    return path


X = 1e-4 * np.arange(512)
PROFILE_CASES = [
    ("micrometres", lambda tmp: _profile(tmp, 36 * np.sin(3e3 * X), X), [], "RMS height 25.4"),
    ("two columns with --dx", lambda tmp: _profile(tmp, 1e-6 * np.sin(3e3 * X), X), ["--dx", "1e-4"], "2 columns"),
    ("x in millimetres", lambda tmp: _profile(tmp, 1e-6 * np.sin(3e3 * X), 1e3 * X), [], "give x in metres"),
    ("dx in millimetres", lambda tmp: _profile(tmp, 1e-6 * np.sin(3e3 * X)), ["--dx", "0.1"], "spacing"),
    ("ragged rows", lambda tmp: _write(tmp / "p.csv", b"0,1e-6\n1e-4,2e-6,3\n"), [], "line 2"),
    ("not UTF-8", lambda tmp: _write(tmp / "p.csv", b"\xff\xfe\x00"), [], "not UTF-8"),
    ("pickled NPY", lambda tmp: _npy(tmp / "p.npy", np.array([{}], dtype=object)), ["--dx", "1e-4"], "pickled"),
    ("negative segment", lambda tmp: _profile(tmp, 1e-6 * np.sin(3e3 * X), X), ["--segment", "-1e-3"], "segment"),
    ("flat", lambda tmp: _profile(tmp, 1e-6 + 0 * X, X), [], "no roughness to estimate"),
    ("rows of text", lambda tmp: _write(tmp / "p.csv", b"x,h\n0,a\n1e-4,b\n"), [], "line 2: '0,a' is not a row"),
    ("a directory", lambda tmp: tmp, [], "a directory, not a file"),
]


def _npy(path, array):
    np.save(path, array, allow_pickle=True)
    return path


@pytest.mark.parametrize("make,options,needle", [c[1:] for c in PROFILE_CASES], ids=[c[0] for c in PROFILE_CASES])
def test_a_profile_in_the_wrong_units_or_shape_is_refused(tmp_path, capsys, make, options, needle):
    out = tmp_path / "out"
    _refused(capsys, needle, "roughness", "profile", make(tmp_path), *options, "--out", out)
    assert not out.exists()


# ----------------------------------------------------------------------------- OS errors on output
def _no_space(*args):
    raise OSError(errno.ENOSPC, "No space left on device")


OS_CASES = [
    ("merge", lambda part, tmp: ["merge", part, "--out", tmp / "o"]),
    ("run", lambda part, tmp: ["run", *TINY, "--realizations", "1", "--out", tmp / "o"]),
    ("profile", lambda part, tmp: ["roughness", "profile", _profile(tmp, 1e-6 * np.sin(3e3 * X), X), "--out",
                                   tmp / "o"]),
    ("filter", lambda part, tmp: ["roughness", "filter", "--out", tmp / "o"]),
]


def test_a_figure_saved_to_a_path_is_whole_or_absent(part, tmp_path, monkeypatch):
    """plot_psd to a path writes through the atomic writer: a full disk leaves neither a part of
    the PNG nor its temporary file; a sound write is a PNG (its signature)."""
    result = EnsembleResult.load(part / "spectra.npz")
    plot_psd(result, "force", tmp_path / "f.png")
    assert (tmp_path / "f.png").read_bytes()[:4] == b"\x89PNG"
    monkeypatch.setattr(os, "fsync", _no_space)
    with pytest.raises(OSError, match="No space left"):
        plot_psd(result, "accel", tmp_path / "a.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.png"]


@pytest.mark.parametrize("args", [c[1] for c in OS_CASES], ids=[c[0] for c in OS_CASES])
def test_a_full_disk_is_one_line_saying_what_was_kept(part, tmp_path, capsys, monkeypatch, args):
    monkeypatch.setattr(os, "fsync", _no_space)
    line = _refused(capsys, "No space left on device; that file was not written", *args(part, tmp_path))
    assert str(tmp_path / "o") in line and ".tmp" not in line
    assert not list((tmp_path / "o").glob(".*.tmp"))


def test_a_path_too_long_or_a_directory_for_a_file_is_one_line(part, tmp_path, capsys):
    _refused(capsys, "File name too long", "merge", part, "--out", tmp_path / ("x" * 300))
    out = tmp_path / "o"
    (out / "spectra.npz").mkdir(parents=True)
    _refused(capsys, "spectra.npz: Is a directory", "merge", part, "--out", out, "--force")


@pytest.mark.parametrize("command", [["run", *TINY, "--realizations", "1"], ["merge", "{part}"]], ids=["run", "merge"])
def test_stale_temporary_files_of_killed_writes_are_removed(part, tmp_path, capsys, command):
    out = tmp_path / "o"
    out.mkdir()
    stale = [out / ".summary.json.abc123.tmp", out / ".spectra.npz.def456.tmp"]
    for path in stale:
        path.write_bytes(b"partial")
    assert _main(capsys, *[a.format(part=part) for a in command], "--out", out, "--force")[0] == 0
    assert not any(path.exists() for path in stale)


# ----------------------------------------------------------------------------- the Python API
API_MISUSES = [
    (lambda r, s: rough_lines({"L": 0.05}, 0, 2), "params must be an mdroll.Params"),
    (lambda r, s: run_ensemble(Params(L=0.025, dx=2.5e-5), roughness="iso3095", progress=False), "roughness = 'iso3095'"),
    (lambda r, s: run_specs([Params()]), "specs[0] is a Params"),
    (lambda r, s: run_specs(Params()), "specs must be a list"),
    (lambda r, s: EnsembleSpec({"L": 1.0}), "params must be an mdroll.Params"),
    (lambda r, s: EnsembleSpec(Params(), seed=-1), "seed = -1"),
    (lambda r, s: EnsembleResult.merge(r), "results must be a list"),
    (lambda r, s: EnsembleResult.merge([r, 1]), "item 2 is a int"),
    (lambda r, s: fit(np.ones(10)), "spectrum must be an mdroll.inverse.Spectrum"),
    (lambda r, s: fit(s, passes=0), "passes = 0"),
    (lambda r, s: fit(s, passes=2.5), "passes = 2.5"),
    (lambda r, s: fit(s, known=[1.0]), "known must be a dict"),
    (lambda r, s: fit(s, free="H"), "free = 'H'"),
    (lambda r, s: fit(s, bin=0), "bin = 0"),
    (lambda r, s: read_spectrum(None), "path must be a file name"),
    (lambda r, s: contact_force([[0.0] * 10], Params()), "shape"),
    (lambda r, s: contact_force("abc", Params()), "lines must be an array of heights"),
    (lambda r, s: fit(s, passes=10**9), "passes = 1000000000 is not allowed: it must be an integer from 1 to 100000"),
    (lambda r, s: fit(s, correction_passes=10**9), "correction_passes = 1000000000"),
    (lambda r, s: table_spectrum(np.arange(1.0, 9.0), np.ones(8), passes=10**6), "from 1 to 100000"),
    (lambda r, s: from_result({}), "result must be an mdroll.EnsembleResult"),
    (lambda r, s: run_study("quick", workers=10**4), "workers = 10000"),
    (lambda r, s: run_study("quick", repeats=10**9), "repeats = 1000000000"),
    (lambda r, s: run_ensemble(Params(L=0.025, dx=2.5e-5), realizations=range(2**64, 2**64 + 1)), "at most 2^63"),
]


@pytest.mark.parametrize("call,needle", API_MISUSES, ids=[c[1] for c in API_MISUSES])
def test_the_api_names_the_misused_argument(part, call, needle):
    result = EnsembleResult.load(part / "spectra.npz")
    spectrum = table_spectrum(np.arange(1.0, 100.0), np.ones(99))
    with pytest.raises(mdroll.ParameterError, match=None) as raised:
        call(result, spectrum)
    assert needle in str(raised.value) or needle.replace("2^63", str(2**63 - 1)) in str(raised.value)


# ----------------------------------------------------------------------------- bounds and messages
def test_every_count_a_user_gives_is_bounded(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(observed, "MAX_TABLE_ROWS", 50)
    f = np.geomspace(1.0, 1e4, 60)
    path = tmp_path / "t.csv"
    np.savetxt(path, np.column_stack([f, f**-2]), delimiter=",")
    _refused(capsys, "more than the 50 rows", "invert", path, "--frequency-unit", "Hz", "--sided", "one",
             "--density", "Hz")
    _refused(capsys, "2 to 10000 replicates", "invert", path, "--bootstrap", "10001")


MESSAGE_CASES = [
    (["run", "--set", "n_real=x"], "--set n_real=x: not an integer"),
    (["run", "--set", "H=0.8.1"], "--set H=0.8.1: not a number"),
    (["invert", "--report", "{spectra}"], "not a JSON round-trip record"),
    (["invert", "--report", "{summary}"], "not a round-trip record"),
    (["invert", "--band", "1:2:3", "{spectra}"], "expected LO:HI"),
    (["run", "--config", "{binary}"], "not a text file (not UTF-8)"),
    (["run", "--seed", "-1", *TINY], "seed = -1"),
    (["run", "--batch", "-2", *TINY], "batch = -2"),
    (["invert", "--band", "-20:30", "{spectra}"], "--option=VALUE"),
    (["run", "--first", str(2**64), *TINY], "0 .. 9223372036854775807"),
    (["run", "--mode", "coupled", "--set", "wheel.mass=abc", *TINY], "wheel.mass = 'abc' is not allowed"),
    (["run", "--mode", "coupled", "--set", "wheel.m=1", *TINY], "the wheel keys are"),
    (["run", "--mode", "coupled", "--set", "track=nonsense", *TINY], "track = 'nonsense'"),
    (["run", "--scheduler", "nonsense", *TINY], "is not an address"),
    (["study", "coupling", "--test", "--seed", "-1"], "seed = -1"),
    (["study", "coupling", "--test", "--device", "bogus"], "device 'bogus'"),
    (["study", "list", "x"], "only `study report` takes a folder"),
    (["roughness", "check", "--only", "round_trip", "--seed", "-1"], "seed = -1"),
    (["validate", "--seed", "-1"], "seed = -1"),
]


@pytest.mark.parametrize("args,needle", MESSAGE_CASES, ids=[c[1] for c in MESSAGE_CASES])
def test_messages_name_the_file_or_option_not_library_internals(part, tmp_path, capsys, args, needle):
    binary = _write(tmp_path / "c.toml", b"\xff\xfeL = 1\n")
    names = {"spectra": part / "spectra.npz", "summary": part / "summary.json", "binary": binary}
    out = tmp_path / "out"
    _refused(capsys, needle, *[a.format(**{k: str(v) for k, v in names.items()}) for a in args], "--out", out)
    assert not out.exists()


def test_sigterm_in_another_command_does_not_point_at_run_resume(capsys, monkeypatch):
    from mdroll import cli

    def terminated(args):
        raise cli._Terminated

    monkeypatch.setattr(cli.invert, "execute", terminated)
    assert cli_main(["invert", "x.csv"]) == 143
    assert capsys.readouterr().err.strip() == "mdroll: terminated"


def test_library_warnings_stay_off_a_successful_run(tmp_path, capsys, monkeypatch):
    def warning_plot(result, quantity, path):
        warnings.warn("Data has no positive values, and therefore cannot be log-scaled.", UserWarning)
        path.write(b"\x89PNG")

    monkeypatch.setattr(mdroll.plotting, "plot_psd", warning_plot)
    code, _, err = _main(capsys, "run", *TINY, "--realizations", "1", "--out", tmp_path / "o")
    assert code == 0 and err == []


# ----------------------------------------------------------------------------- users' checks
def _module(tmp_path, monkeypatch, name, text):
    (tmp_path / f"{name}.py").write_text(text)
    monkeypatch.chdir(tmp_path)
    return name


CHECK_TOML = 'name = "c"\nprediction = "math:sqrt"\nband = [1, 4]\n'
CHECK_FILE_CASES = [
    ("band a number", CHECK_TOML.replace("[1, 4]", "5"), "band = 5"),
    ("band of three", CHECK_TOML.replace("[1, 4]", "[1, 2, 3]"), "[lo, hi], two numbers"),
    ("band of texts", CHECK_TOML.replace("[1, 4]", '["a", "b"]'), "two numbers"),
    ("allowance a text", CHECK_TOML + 'allowance = "5%"\n', "allowance = '5%'"),
    ("allowance over 100 %", CHECK_TOML + "allowance = 1.5\n", "below 1 (100 %)"),
    ("name a number", CHECK_TOML.replace('"c"', "3"), "name = 3"),
    ("prediction a number", CHECK_TOML.replace('"math:sqrt"', "3"), "prediction = 3"),
    ("params a text", CHECK_TOML + '[check.spec]\nparams = "L=1"\n', "must be a table"),
    ("seed a text", CHECK_TOML + '[check.spec]\nseed = "x"\n', "seed must be an integer"),
    ("whole_periods a number", CHECK_TOML + "whole_periods = 2\n", "true or false"),
]


@pytest.mark.parametrize("body,needle", [c[1:] for c in CHECK_FILE_CASES], ids=[c[0] for c in CHECK_FILE_CASES])
def test_a_checks_file_value_of_the_wrong_shape_or_type_is_named(tmp_path, capsys, body, needle):
    path = tmp_path / "checks.toml"
    path.write_text("[[check]]\n" + body)
    out = tmp_path / "out"
    _refused(capsys, needle, "validate", "--checks", path, "--device", "cpu", "--out", out)
    assert not out.exists()


PROVIDER_CASES = [
    ("sys.exit(0)", "import sys\ndef provider():\n    sys.exit(0)\n", "called sys.exit(0)"),
    ("syntax error", "def provider(:\n    pass\n", "line 1: a syntax error"),
    ("exit at import", "import sys\nsys.exit(0)\n", "called sys.exit(0)"),
    ("returns a number", "def provider():\n    return 5\n", "returned 5"),
    ("fails while yielding", "def provider():\n    yield 1 / 0\n", "ZeroDivisionError"),
]


@pytest.mark.parametrize("text,needle", [c[1:] for c in PROVIDER_CASES], ids=[c[0] for c in PROVIDER_CASES])
def test_a_users_provider_never_ends_validate_as_a_success(tmp_path, capsys, monkeypatch, text, needle):
    name = _module(tmp_path, monkeypatch, f"provider_{abs(hash(text))}", text)
    _refused(capsys, needle, "validate", "--check", f"{name}:provider", "--device", "cpu", "--out", tmp_path / "o")
    assert not (tmp_path / "o").exists()  # the folder is made only once there is a report to write


def test_a_prediction_returning_text_is_named_not_converted(tmp_path, capsys, monkeypatch):
    name = _module(tmp_path, monkeypatch, "text_prediction", "def text(x, params):\n    return 'abc'\n")
    path = tmp_path / "checks.toml"
    path.write_text("[[check]]\n" + CHECK_TOML.replace("math:sqrt", f"{name}:text") + "[check.spec]\nrealizations = 2\n"
                    "[check.spec.params]\nL = 0.025\ndx = 2.5e-5\n")
    _refused(capsys, "returned 'abc' (str), not a number", "validate", "--checks", path, "--device", "cpu",
             "--no-cache", "--no-progress", "--out", tmp_path / "o")
    assert not (tmp_path / "o").exists()


def test_a_prediction_that_exits_is_an_error_not_a_pass(part):
    from mdroll.validation import Band, Check
    from mdroll.errors import PredictionError

    def exits(x, params):
        raise SystemExit(0)

    result = EnsembleResult.load(part / "spectra.npz")
    with pytest.raises(PredictionError, match=r"called sys.exit\(0\)"):
        Check("c", None, exits, Band(1, 4)).evaluate(result)


RELATIVE_CASES = [(-0.9, 2.0, False), (0.0004, 1.5, False), (1.05, 0.1, True), (0.95, 0.1, True), (1.2, 0.1, False)]


@pytest.mark.parametrize("ratio,tolerance,passed", RELATIVE_CASES)
def test_a_relative_check_passes_only_a_positive_ratio_within_a_testable_tolerance(ratio, tolerance, passed):
    from mdroll.validation import CheckResult

    assert CheckResult("c", "", ratio * 2.0, 2.0, tolerance, "relative", "-", "").passed is passed


# ----------------------------------------------------------------------------- study records
def _study_record(tmp_path, change):
    """A copy of a recorded study (docs/studies/quick) with one field changed as a user might."""
    source = Path(__file__).resolve().parents[1] / "docs" / "studies" / "quick" / "coupling" / "coupling.json"
    record = json.loads(source.read_text())
    text = change(record)
    folder = tmp_path / "studies" / "coupling"
    folder.mkdir(parents=True)
    (folder / "coupling.json").write_text(text if isinstance(text, str) else json.dumps(record))
    return tmp_path / "studies"


STUDY_CASES = [
    ("another schema", lambda r: json.dumps({"rows": []}), "lacks 'study'"),
    ("truncated", lambda r: json.dumps(r)[:300], "not a JSON study record"),
    ("claims a table", lambda r: r.update(claims={}), "claims = '{}', expected a list"),
    ("claim without stderr", lambda r: r["claims"][0].pop("stderr") and None, "claims[0] lacks 'stderr'"),
    ("measured a text", lambda r: r["claims"][0].update(measured="1.0"), "claims[0].measured"),
    ("verdicts uncounted", lambda r: r.update(verdicts={}), "verdicts lacks 'agrees'"),
    ("spec without mode", lambda r: r["ensembles"][0]["spec"].pop("mode") and None, "ensembles[0].spec lacks 'mode'"),
]


@pytest.mark.parametrize("change,needle", [c[1:] for c in STUDY_CASES], ids=[c[0] for c in STUDY_CASES])
def test_study_report_reads_records_through_a_checked_reader(tmp_path, capsys, change, needle):
    folder = _study_record(tmp_path, change)
    _refused(capsys, needle, "study", "report", folder, "--page", tmp_path / "page.md")
    assert not (tmp_path / "page.md").exists()


@pytest.mark.parametrize("page,needle", [("{tmp}", "is a directory"), ("{tmp}/none/page.md", "does not exist"),
                                         ("{tmp}/" + "x" * 300 + ".md", "File name too long")])
def test_study_report_page_that_cannot_be_written_is_one_line(tmp_path, capsys, page, needle):
    folder = _study_record(tmp_path, lambda r: None)
    _refused(capsys, needle, "study", "report", folder, "--page", page.format(tmp=tmp_path))
