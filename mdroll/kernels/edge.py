"""Edge-incremental approximation, O(1) per step (eq 36, 48, 49; physics.md section 4).

    F(x_w) = F_Hertz(d) + E* integral_{x_w-a}^{x_w+a} h(x) dx + E* R / (4a) (h(x_w+a)^2 + h(x_w-a)^2)

with ``a = sqrt(d R)`` and ``F_Hertz(d) = (4/3) E* a^3 / R``. Between springs h is the linear
interpolant, and the integral is taken over that same interpolant: whole cells by the trapezoid
rule from the prefix sums, the two fractional end cells exactly. Heights are read as
``h_i = S_{i+1} - S_i`` so that each step touches only the prefix-sum array.

Everything that depends on d alone (a, its cell split, the Hertz force, the tip coefficient)
is an :class:`EdgeGeometry`: computed once per launch at constant d (a square root and three
float64 divisions per step were the kernel's bottleneck), once per step in the coupled
dynamics.
"""

import warp as wp

from .common import Contact
from .dynamics import coupled_dynamics


@wp.struct
class EdgeGeometry:
    """The d-dependent constants of eq 49 at indentation d (m), contact half-width a = sqrt(d R).

    ``whole = floor(a / dx)`` and ``fraction = a / dx - whole`` place x_w +- a between springs;
    ``hertz = (4/3) E* a^3 / R`` (N); ``tip = E* R / (4 a)`` (N/m^2) multiplies the squared edge
    heights; ``dx_E_star = E* dx`` (N/m^2 times m) scales the integral in spring units.
    """

    whole: int
    fraction: wp.float64
    hertz: wp.float64
    tip: wp.float64
    dx_E_star: wp.float64


@wp.func
def edge_geometry(d: wp.float64, dx: wp.float64, R: wp.float64, E_star: wp.float64) -> EdgeGeometry:
    """:class:`EdgeGeometry` at indentation d (m), as :func:`mdroll.physics.contact_radius`,
    :func:`~mdroll.physics.hertz_force`, :func:`~mdroll.physics.edge_coefficient` and
    :func:`~mdroll.physics.spring_stiffness` give it on the host (the same operations in the
    same order: bit for bit)."""
    g = EdgeGeometry()
    a = wp.sqrt(d * R)
    alpha = a / dx
    g.whole = int(wp.floor(alpha))
    g.fraction = alpha - wp.float64(g.whole)
    # (4/3) E* a^3 / R, written without a literal 4/3 (Warp would fold it in float32)
    g.hertz = wp.float64(4.0) * E_star * a * a * a / (wp.float64(3.0) * R)
    g.tip = E_star * R / (wp.float64(4.0) * a)
    g.dx_E_star = E_star * dx
    return g


@wp.func
def force_edge(prefix: wp.array2d(dtype=wp.float64), r: int, c: int, g: EdgeGeometry) -> wp.float64:
    """Eq 49 (N) for the wheel at spring c (x_w = c dx), geometry g of the indentation.

    Needs springs ``c - g.whole - 1 .. c + g.whole + 1`` on the line.
    """
    half = wp.float64(0.5)
    one = wp.float64(1.0)
    f = g.fraction
    right = c + g.whole  # cell [right, right + 1] holds x_w + a
    left = c - g.whole - 1  # cell [left, left + 1] holds x_w - a
    h_r0 = prefix[r, right + 1] - prefix[r, right]
    h_r1 = prefix[r, right + 2] - prefix[r, right + 1]
    h_l0 = prefix[r, left + 1] - prefix[r, left]
    h_l1 = prefix[r, left + 2] - prefix[r, left + 1]
    # trapezoid over springs c-whole .. c+whole, plus the two partial cells, in units of dx
    middle = (prefix[r, right + 1] - prefix[r, left + 1]) - half * (h_l1 + h_r0)
    right_part = h_r0 * f + (h_r1 - h_r0) * f * f * half
    gap = one - f
    left_part = h_l0 * f + (h_l1 - h_l0) * (one - gap * gap) * half
    h_right = h_r0 + f * (h_r1 - h_r0)
    h_left = h_l0 + gap * (h_l1 - h_l0)
    return g.hertz + g.dx_E_star * (middle + right_part + left_part) + g.tip * (h_right * h_right + h_left * h_left)


@wp.kernel
def contact_force_edge(
    prefix: wp.array2d(dtype=wp.float64),
    first: int,
    geometry: EdgeGeometry,
    offset: wp.float64,
    force: wp.array2d(dtype=wp.float64),
):
    """``force[r, s] = F - offset`` (N): F by eq 49 with the wheel at spring ``first + s`` of row r."""
    r, s = wp.tid()
    force[r, s] = force_edge(prefix, r, first + s, geometry) - offset


@wp.func
def edge_lane_force(prefix: wp.array2d(dtype=wp.float64), r: int, c: int, d: wp.float64, contact: Contact, lane: int,
                    lanes: int):
    """Eq 49 (N) at indentation d (m), on lane 0 only (O(1) a step); 0 elsewhere and without
    contact; and the row r (:func:`~mdroll.kernels.dynamics.row_index`)."""
    if lane == 0 and d > wp.float64(0.0):
        return force_edge(prefix, r, c, edge_geometry(d, contact.dx, contact.R, contact.E_star)), r
    return wp.float64(0.0), r


#: Eq 13 with the edge formula (:func:`mdroll.kernels.dynamics.coupled_dynamics`).
coupled_edge = coupled_dynamics(wp.array2d(dtype=wp.float64), edge_lane_force)
