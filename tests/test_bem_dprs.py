"""The distributed point-reacting spring model (mdroll.bem.dprs) against independent references:
a direct loop over realizations and positions in numpy from the coordinates in metres, the
linear force of a tiny corrugation against the closed form 2 J1(q a)/(q a), the closed-form
transfer against a quadrature of the uniform average over the ellipse, and the smooth static
contact against Hertz's patch and load (mdroll.bem.hertz_elliptical)."""

import math

import numpy as np
import pytest
from scipy import integrate, special

from mdroll.bem import extruded, hertz_elliptical
from mdroll.bem.dprs import Bed, gap, roll, transfer
from mdroll.errors import ParameterError
from mdroll.studies.mdr3d.problems import on_device

E_STAR = 115.4e9
LOAD = 50e3


def hertz_bed(radius_x, radius_y, load=LOAD):
    """The bed of a paraboloid at the load, from Hertz's approach and semi-axes."""
    probe = 1e-5
    approach = probe * (load / hertz_elliptical(probe, E_STAR, radius_x, radius_y)[3]) ** (2.0 / 3.0)
    semi_x, semi_y, _, force = hertz_elliptical(approach, E_STAR, radius_x, radius_y)
    assert force == pytest.approx(load, rel=1e-12)
    return Bed(float(semi_x), float(semi_y), approach, load)


def loop_force(surface, dx, bed, steps, n, start):
    """F = kappa dx^2 sum max(w, 0), one realization and one position at a time, the cell
    coordinates in metres: the indenter's lowest point at x_s = (start + s + (n - 1)/2) dx along
    the surface and above the middle of the n middle columns."""
    count, length, width = surface.shape
    first = (width - n) // 2
    out = np.zeros((count, steps))
    for b in range(count):
        for s in range(steps):
            centre_x, centre_y = (start + s + 0.5 * (n - 1)) * dx, (first + 0.5 * (n - 1)) * dx
            total = 0.0
            for i in range(start + s, start + s + n):
                for j in range(first, first + n):
                    x, y = i * dx - centre_x, j * dx - centre_y
                    w = bed.delta * (1.0 - x * x / bed.semi_x**2 - y * y / bed.semi_y**2) + surface[b, i, j]
                    total += max(w, 0.0)
            out[b, s] = 2.0 * bed.load / (math.pi * bed.semi_x * bed.semi_y * bed.delta) * dx * dx * total
    return out


def test_rolling_is_the_direct_loop(device):
    bed = Bed(1.1e-3, 0.8e-3, 40e-6, 2e3)
    dx, n, steps, start = 0.2e-3, 11, 7, 2
    rng = np.random.default_rng(5)
    surface = 30e-6 * rng.standard_normal((2, start + steps + n + 3, n + 4))  # the contact opens and closes
    got = roll(on_device(surface, device), dx, bed, steps=steps, window=n, start=start, device=device)
    reference = loop_force(surface, dx, bed, steps, n, start)
    assert 0.0 < reference.min() and np.ptp(reference) > 0.2 * reference.mean()
    assert np.allclose(got.force, reference, rtol=1e-12, atol=0)
    assert np.ptp(got.area) >= 4 * dx * dx  # springs open and close: the non-linear regime
    assert np.allclose(got.position, (start + np.arange(steps) + 5) * dx, rtol=1e-14)
    one = roll(surface[1], dx, bed, steps=steps, window=n, start=start)
    assert one.force.shape == (steps,) and np.allclose(one.force, reference[1], rtol=1e-12)


@pytest.mark.parametrize("radius_y", [0.46, 0.3])
def test_tiny_corrugation_gives_the_closed_form(radius_y, device):
    bed = hertz_bed(0.46, radius_y)
    dx = 2.0 * bed.semi_x / 61
    n, steps = 77, 16
    x = np.arange(steps + n - 1) * dx
    amplitude = 1e-4 * bed.delta
    waves = np.array([0.6, 2.5, 5.0]) / bed.semi_x
    profiles = np.stack([amplitude * f(q * x) for q in waves for f in (np.cos, np.sin)] + [0.0 * x])
    force = roll(on_device(extruded(profiles, n), device), dx, bed, steps=steps, device=device).force
    smooth = force[-1]
    assert np.allclose(smooth, smooth[0], rtol=1e-12) and smooth[0] == pytest.approx(LOAD, rel=1e-3)
    for j, q in enumerate(waves):
        swing = np.hypot(force[2 * j] - smooth, force[2 * j + 1] - smooth)
        closed = 2.0 * abs(special.j1(q * bed.semi_x)) / (q * bed.semi_x)
        assert swing == pytest.approx(np.full(steps, bed.stiffness * amplitude * closed), rel=0.02), q
        assert transfer(q, 0.0, bed.semi_x, bed.semi_y) == pytest.approx(closed**2, rel=1e-12)


def test_transfer_is_the_uniform_average_over_the_ellipse():
    a, b = 5.7e-3, 4.3e-3
    for qx, qy in [(0.0, 0.0), (300.0, 0.0), (700.0, 450.0), (0.0, 1500.0), (2500.0, -900.0)]:
        # (1 / (pi a b)) integral over the ellipse of cos(q . r), in polar coordinates of the unit disc
        inner = lambda t: integrate.quad(lambda r: r * math.cos(r * (qx * a * math.cos(t) + qy * b * math.sin(t))),  # noqa: E731
                                         0.0, 1.0, epsabs=1e-13)[0]
        mean = integrate.quad(inner, 0.0, 2.0 * math.pi, epsabs=1e-12, limit=200)[0] / math.pi
        assert transfer(qx, qy, a, b) == pytest.approx(mean * mean, rel=1e-8, abs=1e-14)


def test_smooth_static_contact_is_hertz():
    sphere = hertz_bed(0.46, 0.46)
    # a sphere's bed is the halved radii's gap z = x^2 / R (a Winkler bed under the sphere itself,
    # x^2 / (2 R), touches on 2 R d, twice Hertz's a^2 = R d)
    assert sphere.radii == pytest.approx((0.46, 0.46), rel=1e-12)
    assert sphere.kappa * math.pi * sphere.semi_x**2 == pytest.approx(2.0 * LOAD / sphere.delta, rel=1e-12)
    for bed in (sphere, hertz_bed(0.46, 0.3)):
        dx = 2.0 * bed.semi_x / 201
        n = 251
        run = roll(np.zeros((n, n)), dx, bed, steps=1)
        assert run.force[0] == pytest.approx(LOAD, rel=1e-4)
        assert run.area[0] == pytest.approx(math.pi * bed.semi_x * bed.semi_y, rel=2e-3)
        touching = bed.delta - gap(n, dx, bed) > 0
        x = (np.arange(n) - 0.5 * (n - 1)) * dx
        assert abs(np.abs(x[touching.any(axis=1)]).max() - bed.semi_x) < dx
        assert abs(np.abs(x[touching.any(axis=0)]).max() - bed.semi_y) < dx


def test_bad_inputs_are_one_line_errors():
    bed = Bed(1e-3, 1e-3, 1e-5, 1e3)
    with pytest.raises(ParameterError, match="semi_y"):
        Bed(1e-3, -1.0, 1e-5, 1e3)
    with pytest.raises(ParameterError, match="surface must be"):
        roll(np.zeros(5), 1e-4, bed, steps=1)
    with pytest.raises(ParameterError, match="steps"):
        roll(np.zeros((5, 5)), 1e-4, bed, steps=0)
    with pytest.raises(ParameterError, match="need a surface of at least"):
        roll(np.zeros((5, 5)), 1e-4, bed, steps=2)
    with pytest.raises(ParameterError, match="dx"):
        roll(np.zeros((5, 5)), 0.0, bed, steps=1)
    with pytest.raises(ParameterError, match="bed must be"):
        roll(np.zeros((5, 5)), 1e-4, "bed", steps=1)
