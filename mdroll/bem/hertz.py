"""Hertz's smooth contacts, the references of the boundary-element solver (physics.md section 1;
Johnson, *Contact Mechanics*, 1985, sections 4.2 and 4.3). A rigid paraboloid
``z = x^2 / (2 R_x) + y^2 / (2 R_y)`` pressed by the approach d into a flat half-space of
composite modulus E*. The sphere's force and contact radius are :func:`mdroll.physics.hertz_force`
and :func:`mdroll.physics.contact_radius`; here the pressure and the elliptical contact.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize, special


def hertz_max_pressure(d, E_star, R):
    """Hertz's peak pressure of a sphere at approach d, ``p0 = 2 E* a / (pi R)`` with
    ``a = sqrt(d R)`` (so that ``F = (2/3) pi a^2 p0``).

    Parameters: ``d`` (m), ``E_star`` (Pa), ``R`` (m). Returns p0 (Pa).
    """
    return 2.0 * E_star * math.sqrt(d * R) / (math.pi * R)


def hertz_pressure(r, d, E_star, R):
    """Hertz's pressure of a sphere at approach d, ``p(r) = p0 sqrt(1 - r^2 / a^2)`` inside the
    contact radius ``a = sqrt(d R)``, 0 outside; p0 from :func:`hertz_max_pressure`.

    Parameters: ``r`` distance from the axis (m, any shape), ``d`` (m), ``E_star`` (Pa), ``R`` (m).
    Returns p (Pa).
    """
    a2 = d * R
    return hertz_max_pressure(d, E_star, R) * np.sqrt(np.maximum(1.0 - np.asarray(r) ** 2 / a2, 0.0))


def elliptical_ratio(radius_x, radius_y):
    """The semi-axis ratio k = b / a of Hertz's elliptical contact (a along the larger radius):
    the root in (0, 1] of

        R_large / R_small = (E(e) / k^2 - K(e)) / (K(e) - E(e)),   e^2 = 1 - k^2,

    K and E the complete elliptic integrals of the first and second kind of modulus e (the
    curvatures 1/(2R) are Johnson's A and B). Parameters: ``radius_x``, ``radius_y`` (m).
    Returns k (dimensionless; 1 for a sphere).
    """
    ratio = max(radius_x, radius_y) / min(radius_x, radius_y)
    if ratio == 1.0:
        return 1.0

    def mismatch(k):
        m = 1.0 - k * k
        big_k, big_e = special.ellipk(m), special.ellipe(m)
        return (big_e / (k * k) - big_k) / (big_k - big_e) - ratio

    return optimize.brentq(mismatch, 1e-6, 1.0 - 1e-12, xtol=1e-15, rtol=1e-15)


def hertz_elliptical(d, E_star, radius_x, radius_y):
    """Hertz's elliptical contact at approach d: semi-axes along x and y, peak pressure and force.

    With k = b / a from :func:`elliptical_ratio`, e^2 = 1 - k^2 and the displacement of the
    pressure ``p0 sqrt(1 - x^2/a^2 - y^2/b^2)`` inside the ellipse,

        d = p0 b K(e) / E*,    1 / (2 R_large) = p0 b (K(e) - E(e)) / (E* e^2 a^2),
        F = (2/3) pi a b p0,

    a the semi-axis along the larger radius. Parameters: ``d`` (m), ``E_star`` (Pa),
    ``radius_x``, ``radius_y`` (m). Returns ``(semi_x, semi_y, p0, F)`` (m, m, Pa, N).
    """
    k = elliptical_ratio(radius_x, radius_y)
    if k == 1.0:
        a = math.sqrt(d * radius_x)
        p0 = hertz_max_pressure(d, E_star, radius_x)
        return a, a, p0, 2.0 / 3.0 * math.pi * a * a * p0
    m = 1.0 - k * k
    big_k, big_e = special.ellipk(m), special.ellipe(m)
    curvature = 1.0 / (2.0 * max(radius_x, radius_y))
    a = math.sqrt(d * (big_k - big_e) / (big_k * m * curvature))
    b = k * a
    p0 = d * E_star / (b * big_k)
    semi_x, semi_y = (a, b) if radius_x >= radius_y else (b, a)
    return semi_x, semi_y, p0, 2.0 / 3.0 * math.pi * a * b * p0


def sphere_errors(cells, E_star, R, d, device="cpu"):
    """The solver's relative errors on Hertz's sphere at approach d with ``cells`` cells across the
    contact diameter 2a, on a grid 1.25 x wider: ``force`` at the approach, ``approach`` at Hertz's
    load, ``radius`` sqrt(area / pi), ``max_pressure``, and ``profile``, the largest pressure
    error inside r < 0.9 a relative to p0 (the edge, where p ~ sqrt(a - r), converges slower).

    Parameters: ``cells``, ``E_star`` (Pa), ``R`` (m), ``d`` (m), ``device``. Returns a dict of
    floats (dimensionless).
    """
    from ..physics import contact_radius, hertz_force
    from .solver import solve

    a = contact_radius(d, R)
    dx = 2.0 * a / cells
    n = int(1.25 * cells) // 2 * 2
    flat = np.zeros((n, n))
    force = hertz_force(d, E_star, R)
    by_approach = solve(flat, dx, R, E_star=E_star, approach=d, device=device)
    by_load = solve(flat, dx, R, E_star=E_star, load=force, device=device)
    x = (np.arange(n) - 0.5 * (n - 1)) * dx
    r = np.hypot(x[:, None], x[None, :])
    p0 = hertz_max_pressure(d, E_star, R)
    return {
        "force": float(by_approach.force / force - 1.0),
        "approach": float(by_load.approach / d - 1.0),
        "radius": math.sqrt(by_approach.area / math.pi) / a - 1.0,
        "max_pressure": float(by_approach.pressure.max() / p0 - 1.0),
        "profile": float(np.abs(by_approach.pressure - hertz_pressure(r, d, E_star, R))[r < 0.9 * a].max() / p0),
        "iterations": [by_approach.iterations, by_load.iterations],
    }
