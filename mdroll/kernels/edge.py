"""Edge-incremental approximation, O(1) per step (eq 36, 48, 49; physics.md section 4).

    F(x_w) = F_Hertz(d) + E* integral_{x_w-a}^{x_w+a} h(x) dx + E* R / (4a) (h(x_w+a)^2 + h(x_w-a)^2)

with ``a = sqrt(d R)`` and ``F_Hertz(d) = (4/3) E* a^3 / R``. Between springs h is the linear
interpolant, and the integral is taken over that same interpolant: whole cells by the trapezoid
rule from the prefix sums, the two fractional end cells exactly. Heights are read as
``h_i = S_{i+1} - S_i`` so that each step touches only the prefix-sum array.
"""

import warp as wp



@wp.func
def force_edge(
    prefix: wp.array2d(dtype=wp.float64),
    r: int,
    c: int,
    d: wp.float64,
    dx: wp.float64,
    R: wp.float64,
    E_star: wp.float64,
) -> wp.float64:
    """Eq 49 (N) for the wheel at spring c (x_w = c dx) and indentation d (m).

    Needs springs ``c - floor(a/dx) - 1 .. c + floor(a/dx) + 1`` on the line.
    """
    half = wp.float64(0.5)
    one = wp.float64(1.0)
    a = wp.sqrt(d * R)
    alpha = a / dx
    whole = int(wp.floor(alpha))
    f = alpha - wp.float64(whole)
    right = c + whole  # cell [right, right + 1] holds x_w + a
    left = c - whole - 1  # cell [left, left + 1] holds x_w - a
    h_r0 = prefix[r, right + 1] - prefix[r, right]
    h_r1 = prefix[r, right + 2] - prefix[r, right + 1]
    h_l0 = prefix[r, left + 1] - prefix[r, left]
    h_l1 = prefix[r, left + 2] - prefix[r, left + 1]
    # trapezoid over springs c-whole .. c+whole, plus the two partial cells, in units of dx
    middle = (prefix[r, c + whole + 1] - prefix[r, c - whole]) - half * (h_l1 + h_r0)
    right_part = h_r0 * f + (h_r1 - h_r0) * f * f * half
    g = one - f
    left_part = h_l0 * f + (h_l1 - h_l0) * (one - g * g) * half
    integral = dx * (middle + right_part + left_part)
    h_right = h_r0 + f * (h_r1 - h_r0)
    h_left = h_l0 + g * (h_l1 - h_l0)
    # (4/3) E* a^3 / R, written without a literal 4/3 (Warp would fold it in float32)
    hertz = wp.float64(4.0) * E_star * a * a * a / (wp.float64(3.0) * R)
    return hertz + E_star * integral + E_star * R / (wp.float64(4.0) * a) * (h_right * h_right + h_left * h_left)


@wp.kernel
def contact_force_edge(
    prefix: wp.array2d(dtype=wp.float64),
    first: int,
    d: wp.float64,
    dx: wp.float64,
    R: wp.float64,
    E_star: wp.float64,
    force: wp.array2d(dtype=wp.float64),
):
    """``force[r, s]`` (N) by eq 49 with the wheel at spring ``first + s`` of row r."""
    r, s = wp.tid()
    force[r, s] = force_edge(prefix, r, first + s, d, dx, R, E_star)
