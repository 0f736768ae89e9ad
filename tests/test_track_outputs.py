"""The outputs of a coupled run on a track: the wheel's and the rail's vibration spectra against
a direct time-domain filtering of the force record (scipy's lfilter of each stepped mode), the
small-roughness run against the linear frequency-domain chain with the track's own receptances,
and what ``mdroll run`` writes (tests/test_track_coupled.py runs it)."""

import dataclasses
import json

import numpy as np
import pytest
import scipy.signal

from mdroll import EnsembleResult, ParameterError, Params, rough_lines, run_ensemble
from mdroll.ensemble.coupled import contact_compliance, coupled_series
from mdroll.ensemble.pipeline import H_BOUND_SIGMAS
from mdroll.forces.prepare import prepare_lines
from mdroll.physics import TWO_PI
from mdroll.track import REF_FORCE, REF_VELOCITY, Track, band_levels, per_hz_one_sided, receptance, third_octave_centres
from mdroll.track.fit import rail_modal_form
from mdroll.wheel import Wheel
from reference import psd

#: Small roughness on a coarse grid that still resolves 5 kHz (Nyquist 25 kHz, bins of 8 Hz),
#: without contact loss.
SMALL = {"L": 2.5, "dx": 1e-4, "h0": 5e-9, "q_min": 30.0}
SOFT = Track.preset("ballasted-soft-pad")


def damped_wheel():
    """The standard wheel with modes damped to zeta = 0.01: decay times well inside the record."""
    wheel = Wheel.preset("standard-920")
    return wheel.with_values(modes=tuple((f, m, 0.01) for f, m, _ in wheel.modes))


def levels(f, psd_q, v, reference, lo=100.0):
    return band_levels(f, per_hz_one_sided(psd_q, v), third_octave_centres(lo, 5000), reference)


def stepped_output(form, u, dt):
    """y[n] = 2 Re sum_k q_k[n], q_k[n] = phi_k q_k[n-1] + gamma_k u[n-1]: each mode a first-order
    recursive filter (scipy.signal.lfilter), independent of the transfer-function formula."""
    phi, gamma = form.discretize(dt)
    y = np.zeros(u.shape)
    for k in range(form.order):
        y += 2.0 * scipy.signal.lfilter([0.0, gamma[k]], [1.0, -phi[k]], u.astype(complex), axis=-1).real
    return y


def test_vibration_spectra_are_the_filtered_force_record(device):
    # 4 Hz bins: the window's smoothing (4 bins) is narrow against the wheel's modes (2 zeta f_n)
    params = Params(**{**SMALL, "L": 2.5, "dx": 2e-4})
    wheel = damped_wheel()
    result = run_ensemble(params, seed=3, realizations=2, mode="coupled", track=SOFT, wheel=wheel, device=device,
                          progress=False)
    lines = rough_lines(params, 3, 2, device=device)
    prepared = prepare_lines(lines, params, result.algorithm, "open", params.d0, device,
                             h_max=H_BOUND_SIGMAS * params.h0)
    force, _ = coupled_series(prepared, params, result.algorithm, device, force_offset=params.F_N,
                              compliance=contact_compliance(SOFT, wheel))
    u = force.numpy() if hasattr(force, "numpy") else np.asarray(force)
    np.testing.assert_allclose(psd(u, params.dx, window=True)[1].mean(axis=0)[1:], result.force_psd[1:], rtol=1e-8)
    f = result.omega[1:] / TWO_PI
    vibration = result.vibration()
    for name, form, power in (("rail_velocity", rail_modal_form(SOFT), 2), ("wheel_velocity", wheel.modal_form(), 2),
                              ("accel", wheel.modal_form(), 4)):
        direct = result.omega[1:] ** power * psd(stepped_output(form, u, params.dt), params.dx, window=True)[1].mean(0)[1:]
        got = result.accel_psd[1:] if name == "accel" else vibration[name][0][1:]
        error = levels(f, got, params.v0, REF_VELOCITY, 200.0) - levels(f, direct, params.v0, REF_VELOCITY, 200.0)
        assert np.max(np.abs(error)) < 0.1, (name, np.round(error, 3))
    assert np.all(result.accel_psd_stderr[1:] > 0)


@pytest.mark.parametrize("name", ["ballasted-soft-pad", "ballasted-stiff-pad"])
def test_small_roughness_is_the_linear_chain_with_the_tracks_receptances(name, device):
    """The linear chain F = k_c sinc(qa) r / (k_c (alpha_W + alpha_R + alpha_C)), v = omega alpha F,
    with the track's closed-form receptance (not the run's fitted state space) and the blocked
    force k_c sinc(qa) r of the same realizations (the decoupled run on the rigid rail)."""
    track = Track.preset(name)
    params = Params(**SMALL)
    common = dict(seed=5, realizations=2, device=device, progress=False)
    blocked = run_ensemble(params, mode="decoupled", **common)
    coupled = run_ensemble(params, mode="coupled", track=track, **common)
    assert coupled.contact_lost_steps == 0
    keep = (coupled.omega > 0) & (coupled.omega < TWO_PI * 6000.0)  # the bands' bins: 100 Hz - 5.6 kHz
    omega = coupled.omega[keep]
    f = omega / TWO_PI
    alpha_w, alpha_r = -1.0 / (params.m * omega**2), receptance(track, f)
    force = blocked.force_psd[keep] / np.abs(params.k_contact * (alpha_w + alpha_r + 1.0 / params.k_contact)) ** 2
    vibration = coupled.vibration()
    for got, linear, ref in ((coupled.force_psd[keep], force, REF_FORCE),
                             (vibration["rail_velocity"][0][keep], np.abs(omega * alpha_r) ** 2 * force, REF_VELOCITY),
                             (vibration["wheel_velocity"][0][keep], np.abs(omega * alpha_w) ** 2 * force,
                              REF_VELOCITY)):
        error = levels(f, got, params.v0, ref) - levels(f, linear, params.v0, ref)
        assert np.max(np.abs(error)) < 0.5, error


def test_results_on_a_track_merge_and_record_it(tmp_path):
    params = Params(L=0.1, dx=1e-4, h0=5e-9, q_min=30.0)
    common = dict(mode="coupled", track=SOFT, device="cpu", progress=False)
    whole = run_ensemble(params, realizations=2, **common)
    parts = [run_ensemble(params, realizations=[i], **common) for i in (0, 1)]
    merged = EnsembleResult.merge([parts[0], EnsembleResult.load(parts[1].save(tmp_path / "b.npz"))])
    for name, (value, err) in whole.vibration().items():
        np.testing.assert_allclose(merged.vibration()[name][0], value, rtol=1e-9)
        np.testing.assert_allclose(merged.vibration()[name][1], err, rtol=1e-6)
    other = dataclasses.replace(parts[1], track={**parts[1].track, "pad_loss": 0.3})
    with pytest.raises(ParameterError, match="track: "):
        EnsembleResult.merge([parts[0], other])
    rigid = run_ensemble(params, realizations=1, mode="coupled", device="cpu", progress=False)
    assert (rigid.track, rigid.wheel, rigid.vibration()) == (None, None, {})


def test_distributed_run_refuses_a_track(cli, one_line_error, tmp_path):
    one_line_error(cli("run", "--workers", "1", "--mode", "coupled", "--set", "track=slab", "--out",
                       str(tmp_path / "d")), "--set track/wheel is not allowed with --workers")
