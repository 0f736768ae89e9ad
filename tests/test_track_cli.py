"""``mdroll track receptance | decay`` against closed forms: the Euler-Bernoulli rail on a Winkler
foundation (receptance and decay rate), its files' columns, and its one-line errors."""

import csv

import numpy as np

from mdroll.physics import TWO_PI

#: An Euler-Bernoulli rail (no shear, no rotary inertia) on pads over a rigid base: the Winkler
#: beam with foundation stiffness k_p (1 + i eta_p) / d per length (hysteretic damping: the
#: closed form's).
WINKLER = ["track.support=continuous", "track.damping=hysteretic", "track.rail_shear_stiffness=inf", "track.rail_rotary_inertia=0",
           "track.rail_loss=0", "track.sleeper_mass=0", "track.ballast_stiffness=1e20", "track.ballast_loss=0",
           "track.pad_stiffness=1e8", "track.sleeper_spacing=0.6"]
EI, MASS = 210e9 * 3038.3e-8, 60.21


def _settings(items, pad_loss):
    return [arg for item in [*items, f"track.pad_loss={pad_loss}"] for arg in ("--set", item)]


def _rows(path):
    with open(path, newline="") as file:
        return list(csv.reader(file))


def test_receptance_csv_is_the_winkler_beam(cli, tmp_path):
    # undamped, below the cut-on sqrt(k / m): alpha = 1 / (8 EI beta^3), beta^4 = (k - m omega^2) / (4 EI)
    proc = cli("track", "receptance", *_settings(WINKLER, 0), "--f-max", "200", "--points", "30",
               "--out", str(tmp_path / "r"))
    assert proc.returncode == 0, proc.stderr
    rows = _rows(tmp_path / "r" / "receptance.csv")
    assert rows[0] == ["frequency_Hz", "re_m_per_N", "im_m_per_N"]
    f, re, im = np.array(rows[1:], dtype=float).T
    assert f[0] == 5.0 and f[-1] == 200.0 and len(f) == 30
    beta = ((1e8 / 0.6 - MASS * (TWO_PI * f) ** 2) / (4 * EI)) ** 0.25
    np.testing.assert_allclose(re, 1 / (8 * EI * beta**3), rtol=1e-8)
    assert np.all(np.abs(im) < 1e-12 * re)
    assert (tmp_path / "r" / "receptance.png").stat().st_size > 1000


def test_decay_csv_is_the_winkler_beam_and_its_verdict(cli, tmp_path):
    # decay of the least attenuated root of EI k^4 = m omega^2 - K_f, 20 log10(e) min Im k
    proc = cli("track", "decay", *_settings(WINKLER, 0.3), "--out", str(tmp_path / "d"))
    assert proc.returncode == 0, proc.stderr
    rows = _rows(tmp_path / "d" / "decay.csv")
    assert rows[0] == ["band_Hz", "decay_dB_per_m", "iso3095_limit_dB_per_m", "pass"]
    band = np.array([r[0] for r in rows[1:]], dtype=float)
    rate, limit = (np.array([r[i] for r in rows[1:]], dtype=float) for i in (1, 2))
    assert band[0] == 250 and band[-1] == 5000
    exact = 1000.0 * 10.0 ** (np.round(10 * np.log10(band / 1000.0)) / 10)
    expected = []
    for omega in TWO_PI * exact:
        k = np.roots([EI, 0, 0, 0, -(MASS * omega**2 - 1e8 * (1 + 0.3j) / 0.6)])
        expected.append(20 / np.log(10) * np.min(np.abs(k.imag)))
    np.testing.assert_allclose(rate, expected, rtol=1e-3)  # the CSV's 4 significant digits
    assert [r[3] for r in rows[1:]] == ["pass" if r >= lim else "fail" for r, lim in zip(rate, limit)]
    assert (tmp_path / "d" / "decay.png").stat().st_size > 1000


def _one_line(capsys, args, needle):
    """In process (the subprocess case is ``test_track_coupled.py``'s): exit code 2 and one line."""
    from mdroll import cli

    assert cli.main(args) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and needle in err[0], err


def test_bad_track_settings_end_in_one_line(capsys, tmp_path):
    out = str(tmp_path / "bad")
    for args, needle in [(["--set", "track.bogus=1"], "track.bogus"), (["--set", "track=nope"], "track = 'nope'"),
                         (["--set", "track.pad_loss=-1"], "track.pad_loss"), (["--set", "L=1"], "--set L=1"),
                         (["--set", "track=rigid"], "rigid"), (["--points", "0"], "--points 0"),
                         (["--f-min", "20", "--f-max", "10"], "--f-min 20")]:
        _one_line(capsys, ["track", "receptance", *args, "--out", out], needle)
    assert not (tmp_path / "bad" / "receptance.csv").exists()


# ----------------------------------------------------------------------------- TOML tables
def test_config_tables_equal_the_same_settings_on_the_command_line(tmp_path):
    from argparse import Namespace

    from mdroll.cli.common import build_structures

    config = tmp_path / "c.toml"
    config.write_text('L = 0.05\n[track]\npreset = "ballasted-stiff-pad"\npad_loss = 0.3\nsleeper_spacing = 0.65\n'
                      '[wheel]\npreset = "standard-920"\nmass = 550\n')
    from_file = build_structures(Namespace(config=str(config), set=["track.pad_loss=0.35"]))
    on_line = build_structures(Namespace(config=None, set=[
        "track=ballasted-stiff-pad", "track.pad_loss=0.3", "track.sleeper_spacing=0.65", "wheel=standard-920",
        "wheel.mass=550", "track.pad_loss=0.35"]))
    assert from_file == on_line
    track, wheel = from_file
    assert (track.pad_stiffness, track.pad_loss, track.sleeper_spacing) == (1e9, 0.35, 0.65)
    assert (wheel.kind, wheel.mass, len(wheel.modes)) == ("modal", 550.0, 5)


def test_bad_config_tables_end_in_one_line(capsys, tmp_path):
    config = tmp_path / "c.toml"
    for text, needle in [('[track]\npad_lossy = 0.3\n', "[track] track.pad_lossy"),
                         ('[track]\npreset = "nope"\n', "[track] track = 'nope'"),
                         ('[track]\npad_loss = true\n', "[track] track.pad_loss = True"),
                         ('[wheel]\nmass = -1\n', "[wheel] wheel.mass"), ('track = 3\n', "'track' must be a [track]"),
                         ('[rail]\nx = 1\n', "unknown table(s) ['rail']")]:
        config.write_text(text)
        _one_line(capsys, ["run", "--mode", "coupled", "--config", str(config), "--out", str(tmp_path / "o")], needle)
