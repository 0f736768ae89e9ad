"""The moving load over discrete supports: the static receptance along a bay against a direct
static solve of a finite rail and against the periodic model at low frequency; the equivalent
roughness's lines at the sleeper-passing frequency and its harmonics; a coupled run with
``track.parametric`` against the linear chain at the sleeper-passing frequency."""

import numpy as np
import pytest

from mdroll import ParameterError, Params, run_ensemble
from mdroll.ensemble import pipeline
from mdroll.physics import TWO_PI
from mdroll.statespace import ModalForm
from mdroll.track import Track
from mdroll.track.interaction import contact_filter
from mdroll.track.parametric import (equivalent_roughness, harmonics, moving_load_deflection, quasi_static_frequency,
                                     roughness_levels, static_receptance)
from mdroll.track.periodic import discrete_receptance, point_receptance

SOFT = Track.preset("ballasted-soft-pad")
EULER = SOFT.with_values(rail_shear_stiffness=float("inf"), rail_rotary_inertia=0.0)


def _element(length, EI, GA):
    """Beam element stiffness from the cantilever's tip flexibility (bending plus shear; theta =
    dw/dx) and the element's equilibrium: an independent derivation of the exact static element."""
    flexibility = np.array([[length**3 / (3 * EI) + length / GA, length**2 / (2 * EI)],
                            [length**2 / (2 * EI), length / EI]])
    k22 = np.linalg.inv(flexibility)
    gamma = np.array([[-1.0, 0.0], [-length, -1.0]])  # node 1's end forces from node 2's
    return np.block([[gamma @ k22 @ gamma.T, gamma @ k22], [k22 @ gamma.T, k22]])


def _finite_rail(track, x, bays=40):
    """Deflection under a unit load at x in (0, d) of a free-ended rail on 2 bays + 1 supports
    (x = 0 the middle one), assembled node by node and solved densely."""
    d = track.sleeper_spacing
    nodes = np.sort(np.concatenate([np.arange(-bays, bays + 1) * d, [x]]))
    K = np.zeros((2 * len(nodes), 2 * len(nodes)))
    for i, length in enumerate(np.diff(nodes)):
        K[2 * i:2 * i + 4, 2 * i:2 * i + 4] += _element(length, track.rail_EI, track.rail_shear_stiffness)
    support = track.pad_stiffness * track.ballast_stiffness / (track.pad_stiffness + track.ballast_stiffness)
    for i, node in enumerate(nodes):
        if np.isclose(node / d, round(node / d)) and node != x:
            K[2 * i, 2 * i] += support
    load = np.zeros(2 * len(nodes))
    at = int(np.flatnonzero(nodes == x)[0])
    load[2 * at] = 1.0
    return np.linalg.solve(K, load)[2 * at]


@pytest.mark.parametrize("track", [SOFT, EULER, Track.preset("slab")], ids=["timoshenko", "euler", "slab"])
def test_static_receptance_is_a_direct_static_solve(track):
    d = track.sleeper_spacing
    x = np.array([0.13, 0.25, 0.5, 0.91]) * d
    direct = [_finite_rail(track, p) for p in x]
    np.testing.assert_allclose(static_receptance(track, x), direct, rtol=1e-9)
    np.testing.assert_allclose(static_receptance(track, x + 3 * d), direct, rtol=1e-9)  # periodic


def test_static_receptance_is_the_periodic_model_at_low_frequency():
    # the dynamic model with small losses at 0.5 Hz: inertia changes it by (f / f_track)^2 ~ 1e-5;
    # hysteretic, whose stiffnesses are the stated ones at every frequency (the causal moduli are
    # so at their damping frequency only)
    quiet = SOFT.with_values(pad_loss=1e-3, ballast_loss=1e-3, rail_loss=1e-3, damping="hysteretic")
    d = SOFT.sleeper_spacing
    above, middle, quarter = static_receptance(SOFT, [0.0, d / 2, d / 4])
    dynamic_above = point_receptance(0.5, quiet, "sleeper").real
    dynamic_middle = point_receptance(0.5, quiet, "midspan").real
    dynamic_quarter = discrete_receptance(0.5, quiet, x0=d / 4).real
    np.testing.assert_allclose([dynamic_above, dynamic_middle, dynamic_quarter], [above, middle, quarter], rtol=3e-5)
    np.testing.assert_allclose(dynamic_middle - dynamic_above, middle - above, rtol=1e-3)
    np.testing.assert_allclose(dynamic_quarter - dynamic_above, quarter - above, rtol=1e-3)
    assert middle > quarter > above  # softer away from the support


def test_a_slow_moving_load_rides_on_the_static_deflection():
    # the exact steady state of the moving load on the periodic model (losses 1e-3, hysteretic as
    # above) at 0.5 m/s
    quiet = SOFT.with_values(pad_loss=1e-3, ballast_loss=1e-3, rail_loss=1e-3, damping="hysteretic")
    d = SOFT.sleeper_spacing
    static = static_receptance(SOFT, [0.0, d / 2])
    moving = moving_load_deflection(quiet, 1.0, 0.5, [0.0, d / 2])
    np.testing.assert_allclose(moving, static, rtol=1e-4)
    np.testing.assert_allclose(moving[1] - moving[0], static[1] - static[0], rtol=1e-3)


def test_equivalent_roughness_is_lines_at_the_sleeper_passing_frequency():
    d, load, v, bays = SOFT.sleeper_spacing, 40e3, 30.0, 10
    n = 60000  # L = 10 d at dx = 0.1 mm
    x = np.arange(n) * (bays * d / n)
    r = equivalent_roughness(SOFT, load, x)
    # sign and mean: heights towards the wheel, the rail lowest at mid-span
    alpha = static_receptance(SOFT, [0.0, d / 2])
    assert r[0] > 0 > r[n // (2 * bays)]
    np.testing.assert_allclose(r[0] - r[n // (2 * bays)], load * (alpha[1] - alpha[0]), rtol=1e-12)
    assert abs(r.mean()) < 1e-6 * np.max(np.abs(r))
    c = np.fft.rfft(r) / n
    f = np.arange(c.size) * v / (bays * d)
    lines = np.abs(c) > 1e-9 * np.max(np.abs(c))
    np.testing.assert_allclose(f[lines] / (v / d), np.round(f[lines] / (v / d)), atol=1e-12)  # n v / d only
    wavelength, rms = harmonics(SOFT, load, 5)
    np.testing.assert_allclose(wavelength, d / np.arange(1, 6))
    np.testing.assert_allclose(np.sqrt(2) * np.abs(c[bays * np.arange(1, 6)]), rms, rtol=1e-4)
    # the 630 mm band holds the fundamental alone, the 800 mm band nothing; levels scale as 20 lg F0
    levels = roughness_levels(SOFT, load, [800.0, 630.0, 315.0])
    np.testing.assert_allclose(levels[1:], 20 * np.log10(rms[:2] / 1e-6), rtol=1e-12)
    assert levels[0] == -np.inf
    np.testing.assert_allclose(roughness_levels(SOFT, 2 * load, [630.0]), levels[1] + 20 * np.log10(2), rtol=1e-12)


def test_parametric_needs_discrete_support():
    with pytest.raises(ParameterError, match="track.parametric = true is not allowed with track.support = 'continuous'"):
        Track(parametric=True)
    with pytest.raises(ParameterError, match="track.parametric = 'yes'"):
        Track.from_settings(["track=slab", "track.parametric=yes"])
    assert Track.from_settings(["track=slab", "track.parametric=True"]).parametric
    with pytest.raises(ParameterError, match="track.support = 'continuous' has no sleeper bays"):
        static_receptance(Track(), 0.0)
    with pytest.raises(ParameterError, match="track.support = 'continuous' has no sleeper bays"):
        quasi_static_frequency(Track())


def test_the_command_line_refuses_it_off_discrete_support(capsys, tmp_path):
    from mdroll import cli

    args = ["run", "--mode", "coupled", "--set", "track.parametric=true", "--set", "L=0.05", "--out", str(tmp_path)]
    assert cli.main(args) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "track.parametric = true is not allowed with track.support = 'continuous'" in err[0]


def _rail_as_one_mode(track, mass=300.0, damping=0.3):
    """The rail above a support as one damped mode of the static stiffness and ``mass`` (kg): a
    state space as the run steps it, without the rail fit's cost."""
    stiffness = 1.0 / static_receptance(track, 0.0)
    omega = np.sqrt(stiffness / mass)
    damped = omega * np.sqrt(1 - damping**2)
    return ModalForm(np.array([-damping * omega + 1j * damped]), np.array([1.0 / (2j * mass * damped)]))


def test_a_run_shows_the_sleeper_passing_peak_of_the_linear_chain(device, monkeypatch):
    # random roughness only below 5 mm and 1 nm RMS: the line at 50 Hz is the moving load's alone
    track = SOFT.with_values(parametric=True)
    rail = _rail_as_one_mode(track)
    stepped = []
    monkeypatch.setattr(pipeline, "contact_compliance", lambda structure, wheel: stepped.append(structure) or (rail, True))
    params = Params(L=6.0, dx=1e-4, v0=30.0, h0=1e-9)
    result = run_ensemble(params, seed=3, realizations=2, mode="coupled", track=track, device=device, progress=False)
    assert stepped == [track.structure()] and result.track["parametric"] is True
    assert result.contact_lost_steps == 0
    dq = result.q[1] - result.q[0]
    q1 = TWO_PI / track.sleeper_spacing
    k = int(round(q1 / dq))
    assert np.argmax(result.force_psd[1:4 * k]) + 1 in (k - 1, k, k + 1)  # the force's peak below 4 v / d
    # F = sinc(q a) r_p / (alpha_W + alpha_R + alpha_C) at f = v / d, alpha_R the rail the run steps
    f = params.v0 / track.sleeper_spacing
    alpha = (-1 / (params.m * (TWO_PI * f) ** 2) + 1 / params.k_contact
             + rail.discrete_response(np.array([f]), params.dt)[0])
    r1 = harmonics(track, params.F_N, 1)[1][0]
    predicted = (r1 * contact_filter(q1, params.a) / abs(alpha)) ** 2 / 2  # |F_1|^2: the line's power at +q
    measured = np.sum(result.force_psd[k - 2:k + 3]) * dq  # the Hann window's main lobe
    assert abs(10 * np.log10(measured / predicted)) < 0.1, 10 * np.log10(measured / predicted)
