"""The realization count belongs to the run: Params holds none, one reader takes it out of a
parameters dict (``n_real``), and the old spelling of files, TOML and ``--set`` keeps working."""

import dataclasses
import json
import textwrap

import numpy as np
import pytest

import mdroll.plotting
from mdroll import EnsembleResult, Params, run_ensemble
from mdroll.cli import build_parser, main as cli_main
from mdroll.cli.common import build_params
from mdroll.ensemble.realizations import COUNT_KEY, DEFAULT_REALIZATIONS, check_count, read_params
from mdroll.errors import ParameterError
from mdroll.validation import checks_from_toml

TINY = {"L": 0.025, "dx": 2.5e-5}


def test_params_hold_no_count_and_the_reader_takes_it_out():
    assert COUNT_KEY not in {f.name for f in dataclasses.fields(Params)}
    params, count = read_params({**TINY, "n_real": np.int64(7)})
    assert params == Params(**TINY) and count == 7 and type(count) is int
    assert read_params(TINY) == (Params(**TINY), None)
    for bad in (0, -1, 2.5, True, "3"):
        with pytest.raises(ParameterError,
                           match=f"^n_real = {bad!r} is not allowed: it must be a positive integer \\(realizations\\)"):
            read_params({"n_real": bad})
    assert check_count("--realizations", 3) == 3
    assert DEFAULT_REALIZATIONS == 300  # the thesis's ensemble


def test_a_spectra_file_with_the_count_inside_its_params_loads(tmp_path):
    """A file of the old layout (``n_real`` among the parameters): the count is the result's."""
    result = run_ensemble(Params(**TINY), seed=2, realizations=3, device="cpu", progress=False)
    path = result.save(tmp_path / "new.npz")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays.pop("meta")))
    assert COUNT_KEY not in meta["params"] and meta["n_real"] == 3
    old = dict(meta, params={**meta["params"], "n_real": meta["n_real"]})
    del old["n_real"]
    np.savez(tmp_path / "old.npz", meta=json.dumps(old), **arrays)
    back = EnsembleResult.load(tmp_path / "old.npz")
    assert back.n_real == 3 and back.realizations == [0, 1, 2] and back.params == result.params
    np.testing.assert_array_equal(back.force_psd, result.force_psd)
    both = dict(meta, params={**meta["params"], "n_real": 3})
    np.savez(tmp_path / "both.npz", meta=json.dumps(both), **arrays)
    assert EnsembleResult.load(tmp_path / "both.npz").n_real == 3
    both["params"]["n_real"] = 4
    np.savez(tmp_path / "both.npz", meta=json.dumps(both), **arrays)
    with pytest.raises(ParameterError, match=r"both.npz: n_real = 4 in its parameters but 3 beside them"):
        EnsembleResult.load(tmp_path / "both.npz")


def _main(capsys, *args):
    code = cli_main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, [line for line in captured.err.splitlines() if "CUDA driver" not in line]


@pytest.mark.parametrize("spelling,expected", [
    (["--set", "n_real=2"], 2),
    (["--config", "{config}"], 3),  # n_real = 3 in the file
    (["--config", "{config}", "--realizations", "2"], 2),  # --realizations wins
    (["--set", "n_real=5", "--realizations", "1"], 1),
    (["--preset", "quick"], 8),
    ([], None),  # the run's default
])
def test_the_cli_spellings_of_the_count(tmp_path, spelling, expected):
    config = tmp_path / "c.toml"
    config.write_text(f"L = {TINY['L']}\ndx = {TINY['dx']}\nn_real = 3\n")
    args = build_parser().parse_args(["run", *(a.format(config=config) for a in spelling)])
    params, count = build_params(args)
    assert count == expected and params.dx == (TINY["dx"] if "--config" in spelling else Params().dx)


def test_a_cli_run_records_the_count_of_n_real(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(mdroll.plotting, "plot_psd", lambda result, quantity, path: path.write(b"\x89PNG"))
    out = tmp_path / "out"
    code, _, err = _main(capsys, "run", "--set", f"L={TINY['L']}", "--set", f"dx={TINY['dx']}", "--set", "n_real=2",
                         "--device", "cpu", "--no-progress", "--out", out)
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_real"] == 2 and COUNT_KEY not in summary["params"]
    assert EnsembleResult.load(out / "spectra.npz").realizations == [0, 1]


def test_the_cli_count_errors_and_the_params_table(tmp_path, capsys):
    for args, needle in ((["--set", "n_real=0"], "n_real = 0 is not allowed: it must be a positive integer (realizations)"),
                         (["--realizations", "0"], "--realizations 0: the number of realizations must be at least 1"),
                         (["--set", "n_real=2.5"], "--set n_real=2.5: not an integer")):
        code, _, err = _main(capsys, "run", *args, "--device", "cpu", "--out", tmp_path / "never")
        assert code == 2 and len(err) == 1 and needle in err[0], err
        assert not (tmp_path / "never").exists()
    rows = {line.split()[0]: line.split()[1] for line in _main(capsys, "params", "--preset", "quick")[1].splitlines()
            if line.startswith("  ")}
    assert rows["n_real"] == "8" and rows["L"] == "0.2"
    rows = {line.split()[0]: line.split()[1] for line in _main(capsys, "params")[1].splitlines() if line.startswith("  ")}
    assert rows["n_real"] == str(DEFAULT_REALIZATIONS)


def test_a_check_file_names_the_count_as_n_real_or_realizations(tmp_path):
    check = textwrap.dedent('''
        [[check]]
        name = "eq 40"
        prediction = "mdroll.validation.checks:eq40_psd"
        band = [1, 8]
        [check.spec]
        {spec}
        [check.spec.params]
        L = 0.03
        n_real = 3
        [check.reference]
        {reference}
        [check.reference.params]
        {reference_params}
    ''')
    path = tmp_path / "checks.toml"
    path.write_text(check.format(spec="", reference="", reference_params="h0 = 1e-6"))
    (only,) = checks_from_toml(path)
    assert only.spec.realizations == 3 and only.spec.params == Params(L=0.03)
    assert only.reference.realizations == 3 and only.reference.params == Params(L=0.03, h0=1e-6)
    path.write_text(check.format(spec="", reference="", reference_params="n_real = 5"))
    assert checks_from_toml(path)[0].reference.realizations == 5
    path.write_text(check.format(spec="realizations = 3", reference="realizations = 2", reference_params=""))
    (only,) = checks_from_toml(path)
    assert only.spec.realizations == 3 and only.reference.realizations == 2
    path.write_text(check.format(spec="realizations = 2", reference="", reference_params=""))
    with pytest.raises(ParameterError, match=r"check 1 \[spec\]: realizations = 2 and n_real = 3 in its params differ"):
        checks_from_toml(path)
