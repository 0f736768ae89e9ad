"""The moving load over discrete supports: the static receptance along a bay against a direct
static solve of a finite rail and against the periodic model at low frequency; the equivalent
roughness's lines at the sleeper-passing frequency and its harmonics; the exact moving load's
harmonics against its space-domain steady state, their quadrature's convergence and their slow
limit, the quasi-static line; a coupled run with ``track.parametric`` against the linear chain at
the sleeper-passing frequency and its second harmonic."""

import numpy as np
import pytest

from mdroll import ParameterError, Params, run_ensemble
from mdroll.ensemble import pipeline
from mdroll.physics import TWO_PI
from mdroll.statespace import ModalForm
from mdroll.track import Track
from mdroll.track.interaction import contact_filter
from mdroll.track import moving
from mdroll.track.parametric import (MOVING_HARMONICS, equivalent_roughness, harmonics, moving_load_deflection,
                                     roughness_levels, static_receptance)
from mdroll.track.periodic import discrete_receptance, point_receptance

SOFT = Track.preset("ballasted-soft-pad")
SLAB = Track.preset("slab")
EULER = SOFT.with_values(rail_shear_stiffness=float("inf"), rail_rotary_inertia=0.0)
#: The soft-pad track without losses: its moduli are the elastic ones at every frequency, whatever
#: the damping model, so a slow load on it rides on the static deflection.
LOSSLESS = SOFT.with_values(pad_loss=0.0, ballast_loss=0.0, rail_loss=0.0)


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
    # the dynamic model without losses at 0.5 Hz: inertia changes it by (f / f_track)^2 ~ 1e-5
    d = SOFT.sleeper_spacing
    above, middle, quarter = static_receptance(SOFT, [0.0, d / 2, d / 4])
    dynamic_above = point_receptance(0.5, LOSSLESS, "sleeper").real
    dynamic_middle = point_receptance(0.5, LOSSLESS, "midspan").real
    dynamic_quarter = discrete_receptance(0.5, LOSSLESS, x0=d / 4).real
    np.testing.assert_allclose([dynamic_above, dynamic_middle, dynamic_quarter], [above, middle, quarter], rtol=3e-5)
    np.testing.assert_allclose(dynamic_middle - dynamic_above, middle - above, rtol=1e-3)
    np.testing.assert_allclose(dynamic_quarter - dynamic_above, quarter - above, rtol=1e-3)
    assert middle > quarter > above  # softer away from the support


def test_a_slow_moving_load_rides_on_the_static_deflection():
    # the exact steady state of the moving load on the periodic model (no losses) at 0.5 m/s,
    # in space (moving_load_deflection) and harmonic by harmonic (the exact line)
    d, load = SOFT.sleeper_spacing, 40e3
    static = static_receptance(SOFT, [0.0, d / 2])
    moving_ = moving_load_deflection(LOSSLESS, 1.0, 0.5, [0.0, d / 2])
    np.testing.assert_allclose(moving_, static, rtol=1e-4)
    np.testing.assert_allclose(moving_[1] - moving_[0], static[1] - static[0], rtol=1e-3)
    # the exact line's harmonics are the quasi-static ones (inertia: 4e-5 at n = 8), and its line
    # the quasi-static one less the harmonics beyond MOVING_HARMONICS (sign, scale and interpolation)
    np.testing.assert_allclose(harmonics(LOSSLESS, load, 8, speed=0.5)[1], harmonics(SOFT, load, 8)[1], rtol=1e-4)
    x = np.linspace(0.0, 3 * d, 3001)
    exact, quasi = equivalent_roughness(LOSSLESS, load, x, speed=0.5), equivalent_roughness(SOFT, load, x)
    assert exact[0] > 0 > exact[500]
    rms = np.sqrt(np.mean(quasi**2))
    assert np.sqrt(np.mean((exact - quasi) ** 2)) < 2e-3 * rms
    assert np.max(np.abs(exact - quasi)) < 2e-2 * np.max(np.abs(quasi))


def test_the_exact_moving_load_is_its_space_domain_steady_state():
    # an Euler-Bernoulli rail on the slab's supports at 200 km/h: the harmonics (1/n^4: 16 hold it
    # to 1e-7) against the Floquet loads in space at two points; the space domain's uniform rule
    # errs by 2.8e-5 there
    track = SLAB.with_values(rail_shear_stiffness=float("inf"), rail_rotary_inertia=0.0)
    d, v = track.sleeper_spacing, 200 / 3.6
    x = np.array([0.0, d / 2])
    c = moving.moving_harmonics(track, v, 16)
    series = 2 * np.real(np.exp(2j * np.pi * np.outer(x, np.arange(1, 17)) / d) @ c)
    direct = moving_load_deflection(track, 1.0, v, x)
    variation = series[1] - series[0]
    np.testing.assert_allclose(direct[1] - direct[0], variation, rtol=1e-3)
    static = static_receptance(track, x)
    assert abs((static[1] - static[0]) / variation - 1) > 0.05  # the load's dynamics: 8.0 % here


def test_the_exact_moving_load_quadrature_converges(monkeypatch):
    # the slab at 300 km/h, its sharpest case: twice the nodes, twice the tail, rtol / 100
    default = moving.moving_harmonics(SLAB, 300 / 3.6, 8)
    monkeypatch.setattr(moving, "MOVING_NODES", 2 * moving.MOVING_NODES)
    monkeypatch.setattr(moving, "MOVING_TAIL_ZONES", 2 * moving.MOVING_TAIL_ZONES)
    finer = moving.moving_harmonics(SLAB, 300 / 3.6, 8, rtol=moving.MOVING_RTOL / 100)
    np.testing.assert_allclose(default, finer, rtol=1e-5)


def test_the_exact_line_levels_and_refusals():
    d, load, v = SLAB.sleeper_spacing, 40e3, 30.0
    wavelength, rms = harmonics(SLAB, load, 4, speed=v)
    np.testing.assert_allclose(wavelength, d / np.arange(1, 5))
    # the line's harmonics (of 64, through its samples) are the integral's (of 4) to its tolerance
    np.testing.assert_allclose(rms, np.sqrt(2) * np.abs(moving.moving_harmonics(SLAB, v, 4)) * load, rtol=1e-5)
    # the 630 mm band holds the fundamental (650 mm) alone, the 800 mm band nothing, 8 mm harmonics
    # beyond the exact line's
    levels = roughness_levels(SLAB, load, [800.0, 630.0, 8.0], speed=v)
    assert levels[0] == -np.inf and np.isnan(levels[2])
    np.testing.assert_allclose(levels[1], 20 * np.log10(rms[0] / 1e-6), rtol=1e-12)
    with pytest.raises(ParameterError, match=f"count = {MOVING_HARMONICS + 1} is not allowed"):
        harmonics(SLAB, load, MOVING_HARMONICS + 1, speed=v)
    with pytest.raises(ParameterError, match="speed = 0.0 m/s is not allowed"):
        moving.moving_harmonics(SLAB, 0.0, 4)
    with pytest.raises(ParameterError, match="too small for its resonances under the moving load"):
        moving.moving_harmonics(LOSSLESS, 30.0, 4)


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
        moving.moving_harmonics(Track(), 30.0, 4)


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


@pytest.mark.parametrize("track, speed", [(SOFT, 30.0), (SLAB, 200 / 3.6)], ids=["soft-108kmh", "slab-200kmh"])
def test_a_run_shows_the_sleeper_passing_peaks_of_the_linear_chain(device, monkeypatch, track, speed):
    # random roughness only below 5 mm and 1 nm RMS: the lines at n v / d are the moving load's alone
    track = track.with_values(parametric=True)
    rail = _rail_as_one_mode(track)
    stepped = []
    monkeypatch.setattr(pipeline, "contact_compliance", lambda structure, wheel: stepped.append(structure) or (rail, True))
    params = Params(L=10 * track.sleeper_spacing, dx=1e-4, v0=speed, h0=1e-9)  # n v / d on bin 10 n
    result = run_ensemble(params, seed=3, realizations=2, mode="coupled", track=track, device=device, progress=False)
    assert stepped == [track.structure()] and result.track["parametric"] is True
    assert result.contact_lost_steps == 0
    dq = result.q[1] - result.q[0]
    q1 = TWO_PI / track.sleeper_spacing
    k = int(round(q1 / dq))
    assert k == 10
    below = result.force_psd[1:4 * k + 3]  # bins 1 .. 4 k + 2
    lobes = sum(below[n * k - 3:n * k + 2].sum() for n in (1, 2, 3, 4))  # the Hann window's main lobes
    assert lobes > 0.99 * below.sum()  # the force up to 4 v / d is the lines at n v / d
    # F = sinc(q a) r_n / (alpha_W + alpha_R + alpha_C) at f = n v / d, alpha_R the rail the run
    # steps, r_n the exact line's harmonic at the run's speed
    exact = harmonics(track, params.F_N, 2, speed=speed)[1]
    assert np.all(np.abs(20 * np.log10(exact / harmonics(track, params.F_N, 2)[1])) > 0.2)  # not the quasi-static
    for n in (1, 2):
        f = n * params.v0 / track.sleeper_spacing
        alpha = (-1 / (params.m * (TWO_PI * f) ** 2) + 1 / params.k_contact
                 + rail.discrete_response(np.array([f]), params.dt)[0])
        predicted = (exact[n - 1] * contact_filter(n * q1, params.a) / abs(alpha)) ** 2 / 2  # |F_n|^2: power at +q
        measured = np.sum(result.force_psd[n * k - 2:n * k + 3]) * dq  # the Hann window's main lobe
        assert abs(10 * np.log10(measured / predicted)) < 0.1, (n, 10 * np.log10(measured / predicted))
