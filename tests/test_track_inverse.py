"""The inverse fit with a known track: the forward model's linear chain against the section 5.1
transfer (rigid track) and against mdroll.track.interaction (a compliant one), the readers, and
the round trip at its test rung."""

import dataclasses

import numpy as np
import pytest

from mdroll import ParameterError, Params
from mdroll.inverse.forward_model import Setting, expected_psd
from mdroll.inverse.track_model import KnownTrack
from mdroll.track import Track, linear_chain, receptance
from mdroll.wheel import Wheel

P = Params()
PARAMS = {"H": P.H, "q_min": P.q_min, "q_max": P.q_max, "a": P.a, "E_star": P.E_star, "h0": P.h0, "R": P.R,
          "m": P.m, "a_jitter": 0.0, "low_scale": 1.0, "zeta": 0.0, "noise": 0.0, "leak": 0.0}
OMEGA = 2 * np.pi * np.geomspace(50.0, 20000.0, 60)
RIGID = KnownTrack(Track.preset("rigid"), Wheel.preset("rigid"))
SOFT = KnownTrack(Track.preset("ballasted-soft-pad"), Wheel.preset("rigid"))


@pytest.mark.parametrize("dt", [None, P.dt])
def test_rigid_track_is_the_wheel_on_the_contact_spring(dt):
    """The chain on the rigid rail under the rigid wheel is section 5.1's transfer
    w~^4 / (k_c - m w~^2)^2 on the blocked force, with and without the simulation's step."""
    plain = Setting("accel", P.v0, dt)
    np.testing.assert_allclose(expected_psd(OMEGA, PARAMS, dataclasses.replace(plain, known_track=RIGID)),
                               expected_psd(OMEGA, PARAMS, plain), rtol=1e-9)


def test_compliant_track_is_the_linear_chain():
    """Force and wheel acceleration over the blocked force, against mdroll.track.linear_chain
    with the track's closed-form receptance (a measured spectrum: no dt)."""
    f = OMEGA / (2 * np.pi)
    alpha_w = -1.0 / (P.m * OMEGA**2)
    chain = linear_chain(f, np.ones_like(f), alpha_w, receptance(SOFT.track, f), P.k_contact, P.a, P.v0)
    ratio = chain["force"] / chain["blocked_force"]
    for quantity, expected in (("force", ratio), ("accel", ratio / P.m**2)):
        plain = Setting(quantity, P.v0)
        blocked = expected_psd(OMEGA, PARAMS, Setting("force", P.v0))
        got = expected_psd(OMEGA, PARAMS, dataclasses.replace(plain, known_track=SOFT)) / blocked
        np.testing.assert_allclose(got, expected, rtol=1e-9)
    assert np.max(np.abs(10 * np.log10(ratio))) > 3.0  # the track matters in this band


def test_simulated_correction_is_refused_on_a_track():
    from mdroll.inverse import fit
    from mdroll.inverse.observed import Spectrum

    spectrum = Spectrum(OMEGA, expected_psd(OMEGA, PARAMS, Setting("accel", P.v0)), v0=P.v0, passes=10,
                        known_track=SOFT)
    with pytest.raises(ParameterError, match="correction = 'simulated' is not allowed on a known track"):
        fit(spectrum, known={"m": P.m, "R": P.R}, correction="simulated")


def test_invert_a_table_on_a_known_track(cli, one_line_error, tmp_path):
    """A noise-free table of the model on a continuously supported soft-pad track: the fit with
    the track given recovers the parameters; a setting other than the track's is one line."""
    track = KnownTrack(Track.preset("ballasted-soft-pad").with_values(support="continuous"), Wheel.preset("rigid"))
    omega = 2 * np.pi * np.arange(300.0, 20000.0, 10.0)
    psd = expected_psd(omega, PARAMS, Setting("accel", P.v0, known_track=track))
    table = tmp_path / "accel.csv"
    np.savetxt(table, np.column_stack([omega, psd]), delimiter=",")
    known = [f"--known={k}={v}" for k, v in (("v0", P.v0), ("m", P.m), ("R", P.R), ("E", P.E), ("nu", P.nu))]
    common = ["invert", str(table), "--frequency-unit", "rad/s", "--sided", "two", "--density", "rad/s",
              "--passes", "100", *known, "--free", "H,q_min,a,h0", "--band", "1200:19990Hz", "--no-profile",
              "--discrepancy", "0"]
    proc = cli(*common, "--set", "track=ballasted-soft-pad", "--set", "track.support=continuous",
               "--out", str(tmp_path / "inv"))
    assert proc.returncode == 0, proc.stderr
    import json

    record = json.loads((tmp_path / "inv" / "inverse.json").read_text())
    assert record["known_track"]["track"]["support"] == "continuous"
    for name, rel in (("H", 0.01), ("q_min", 1e-3), ("a", 1e-3), ("h0", 0.01)):
        assert record["estimates"][name] == pytest.approx(PARAMS[name], rel=rel), name
    one_line_error(cli(*common, "--set", "L=1", "--out", str(tmp_path / "bad")), "--set L=1")


def test_round_trip_on_a_track_recovers_what_ignoring_it_biases():
    from mdroll.inverse.track_roundtrip import known_track_round_trip

    record = known_track_round_trip("test", seed=0, device="cpu")
    known, ignored = record["rows"]
    assert (known["track"], ignored["track"]) == ("known", "ignored")
    assert known["covered"]["H"] and abs(known["error"]["H"]) < 0.02
    # the causal track changes the acceleration above 300 Hz less than the hysteretic one did: at
    # this rung's 8 short realizations ignoring it biases H by about twice the known fit's error
    assert abs(ignored["error"]["H"]) > 1.5 * abs(known["error"]["H"])
    assert known["gof"]["deviance_per_dof"] < ignored["gof"]["deviance_per_dof"]


def test_a_coupled_run_on_the_rigid_rail_is_still_refused(tmp_path):
    from mdroll import run_ensemble
    from mdroll.inverse import read_spectrum

    path = run_ensemble(Params(L=0.05), realizations=2, mode="coupled", device="cpu", progress=False).save(
        tmp_path / "spectra.npz")
    with pytest.raises(ParameterError, match="a coupled run on the rigid rail"):
        read_spectrum(path)
