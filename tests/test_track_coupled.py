"""The coupled dynamics on a compliant track: the rigid track and wheel are today's eq 13 to the
bit; a state space of zero output leaves the kernel's numbers unchanged; at small roughness the
time-domain force equals the linear chain's in every 1/3-octave band 100 Hz - 5 kHz."""

import argparse
import dataclasses
import json

import numpy as np
import pytest

from mdroll import ParameterError, Params, run_ensemble
from mdroll.ensemble import pipeline
from mdroll.physics import TWO_PI
from mdroll.statespace import ModalForm
from mdroll.track import REF_FORCE, Track, band_levels, per_hz_one_sided, third_octave_centres
from mdroll.track.fit import rail_modal_form
from mdroll.wheel import Wheel
from make_reference_run import CASES, REALIZATIONS, SEED

COUPLED = [name for name in CASES if name.startswith("coupled")]


def _run(name, device, **extra):
    fields, options = CASES[name]
    return run_ensemble(Params(**fields), seed=SEED, realizations=REALIZATIONS, device=device, progress=False,
                        **options, **extra)


@pytest.mark.parametrize("name", COUPLED)
def test_rigid_presets_are_todays_coupled_run(name, device):
    """To the bit against the run without a track on the same device (the stored spectra, made on
    the CPU, are held to rounding by test_reference_run)."""
    today = _run(name, device)
    result = _run(name, device, track=Track.preset("rigid"), wheel=Wheel.preset("rigid"))
    np.testing.assert_array_equal(result.force_psd, today.force_psd)
    np.testing.assert_array_equal(result.accel_psd, today.accel_psd)


def test_silent_state_space_leaves_the_numbers(device, monkeypatch):
    # modes whose output is zero: the compliant kernel's d = d_w - 0 is the rigid kernel's d
    silent = ModalForm(np.array([-50.0 + 3000.0j, -20.0 + 9000.0j]), np.zeros(2, dtype=complex))
    name = COUPLED[0]
    today = _run(name, device)
    monkeypatch.setattr(pipeline, "contact_compliance", lambda track, wheel: (silent, True))
    result = _run(name, device)
    np.testing.assert_array_equal(result.force_psd, today.force_psd)
    np.testing.assert_array_equal(result.accel_psd, today.accel_psd)


def test_decoupled_mode_refuses_a_track():
    with pytest.raises(ParameterError, match="mode = 'coupled'"):
        _run("decoupled_direct_open", "cpu", track=Track.preset("ballasted-soft-pad"))


def band_error(f, psd, psd_ref, v):
    centres = third_octave_centres(100, 5000)
    return (band_levels(f, per_hz_one_sided(psd, v), centres, REF_FORCE)
            - band_levels(f, per_hz_one_sided(psd_ref, v), centres, REF_FORCE))


#: A small-roughness ensemble resolving 100 Hz (bins of v / L = 4 Hz) to 5 kHz, contact kept.
SMALL = {"L": 2.5, "dx": 5e-5, "h0": 5e-9, "q_min": 30.0}


def test_small_roughness_is_the_linear_chain(device):
    # the same realizations rigid and decoupled give the blocked force k_c sinc(qa) r; the
    # linear chain turns it into the contact force on the track: |1 / (k_c alpha_sum)|^2
    params = Params(**SMALL)
    track = Track.preset("ballasted-soft-pad")
    common = dict(seed=5, realizations=4, device=device, progress=False, boundary="open", window=True)
    blocked = run_ensemble(params, mode="decoupled", **common)
    coupled = run_ensemble(params, mode="coupled", track=track, **common)
    assert coupled.contact_lost_steps == 0
    f = coupled.omega[1:] / TWO_PI
    alpha = (-1 / (params.m * (TWO_PI * f) ** 2) + rail_modal_form(track).discrete_response(f, params.dt)
             + 1 / params.k_contact)
    linear = blocked.force_psd[1:] / np.abs(params.k_contact * alpha) ** 2
    error = band_error(f, coupled.force_psd[1:], linear, params.v0)
    assert np.max(np.abs(error)) < 0.5, error


def test_cli_track_settings(cli, one_line_error, tmp_path):
    proc = cli("run", "--mode", "coupled", "--set", "L=0.04", "--set", "dx=2e-5", "--realizations", "1",
               "--set", "track=ballasted-soft-pad", "--set", "track.pad_loss=0.3", "--device", "cpu",
               "--no-progress", "--out", str(tmp_path / "run"))
    assert proc.returncode == 0, proc.stderr
    check_vibration_outputs(tmp_path / "run")
    for setting, needle in [("track.bogus=1", "track.bogus"), ("wheel=nope", "wheel = 'nope'"),
                            ("track.pad_loss=-1", "track.pad_loss")]:
        one_line_error(cli("run", "--mode", "coupled", "--set", setting, "--out", str(tmp_path / "bad")), needle)


def test_cli_settings_give_the_track_and_the_wheel():
    from mdroll.cli.common import build_structures

    settings = ["H=0.6", "wheel.mass=400", "wheel=standard-920", "track.pad_loss=0.3"]
    track, wheel = build_structures(argparse.Namespace(set=settings))
    assert track == Track(pad_loss=0.3)
    assert wheel == Wheel.preset("standard-920").with_values(mass=400.0)
    assert build_structures(argparse.Namespace(set=["H=0.6"])) == (None, None)
def check_vibration_outputs(out):
    """A run on a track writes the wheel's and the rail's velocity spectra and their 1/3-octave
    levels (the band rule of mdroll.roughness.bands by hand: the sum of 2 C dq over the band's bins)."""
    summary = json.loads((out / "summary.json").read_text())
    assert summary["track"]["pad_loss"] == 0.3 and summary["wheel"]["kind"] == "rigid"
    vib = summary["bands"]["vibration"]
    with np.load(out / "spectra.npz") as data:
        q, dq = data["q"], data["q"][1] - data["q"][0]
        np.testing.assert_allclose(data["wheel_velocity_psd"][1:], data["force_psd"][1:] / (500.0 * q[1:] * 10.0) ** 2,
                                   rtol=1e-12)
        for name in ("wheel_velocity", "rail_velocity"):
            i = int(np.argmax(np.array(vib["bins"]) >= 3))
            f_c = vib["frequency_Hz"][i]
            inside = (q >= TWO_PI * f_c * 10 ** -0.05 / 10.0) & (q < TWO_PI * f_c * 10 ** 0.05 / 10.0)
            level = 10 * np.log10(np.sum(2 * data[f"{name}_psd"][inside] * dq) / 1e-18)
            assert vib[f"L_v_{name}_dB"][i] == pytest.approx(level, abs=1e-9)
    rows = (out / "bands.csv").read_text().splitlines()[1:]
    assert {row.split(",")[0] for row in rows} == {"roughness", "force", "acceleration", "wheel_velocity",
                                                   "rail_velocity"}


def test_checkpoint_key_keeps_a_hysteretic_track_and_tells_the_damping(tmp_path):
    """A hysteretic track at the default damping frequency writes the checkpoint key of a track
    before the damping fields existed (its old checkpoints resume); a causal track's differs."""
    from mdroll.ensemble.checkpoint import read_checkpoint

    params = Params(L=0.05, dx=1e-4, h0=5e-9, q_min=30.0)
    hysteretic = Track.preset("ballasted-soft-pad").with_values(damping="hysteretic")
    path = tmp_path / "checkpoint.npz"
    common = dict(realizations=2, mode="coupled", device="cpu", progress=False, checkpoint=path)
    run_ensemble(params, track=hysteretic, **common)
    before = {f: v for f, v in dataclasses.asdict(hysteretic).items()
              if f not in ("damping", "damping_frequency", "parametric")}
    assert read_checkpoint(path)[0]["track"] == before
    run_ensemble(params, track=hysteretic, resume=True, **common)
    with pytest.raises(ParameterError, match="cannot resume.*differs from the checkpoint: track"):
        run_ensemble(params, track=Track.preset("ballasted-soft-pad"), resume=True, **common)
