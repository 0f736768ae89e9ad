"""Small ``wp.func`` building blocks and constants shared by the force algorithms (physics.md section 2).

Geometry, in spring units: spring ``l`` sits at ``x_l = l dx``; the wheel centre is at spring
``c`` (``x_w = c dx``); the indentation is ``d`` (m). The MDR indenter (eq 7) lowers spring
``l`` by ``curvature * (l - c)^2`` with ``curvature = dx^2 / R`` (m), so its displacement is
``u_l = h_l + d - curvature (l - c)^2`` (eq 10) and the force ``F = k sum_l max(u_l, 0)``
(eq 11-12, ``k = E* dx``). The functions here return sums of displacements (m); the kernels
multiply by k once.

Offsets ``l - c`` are always formed relative to the wheel, in integers, so that closed-form sums
of squares stay exact (int64) instead of cancelling large absolute positions in float64.
"""

import warp as wp

from .. import physics

#: int32 stack of tree nodes for the explicit-stack traversal; its length (``tree_stack._length_``)
#: is the capacity the tree launch checks (see ``tree.py`` for the bound).
tree_stack = wp.types.vector(length=32, dtype=wp.int32)


#: Offsets |m| up to which the float64 closed forms below are exact: the products are integers
#: below 2^53 and the sums of squares below 2^50, where the rounded product by 1/6 is within
#: 0.2 of the integer it approximates.
MAX_CLOSED_FORM_OFFSET = 100_000

#: 1/6, rounded to float64 (a Warp literal without the wrapper would be float32).
ONE_SIXTH = wp.constant(wp.float64(1.0 / 6.0))

#: 2 pi in float64 for the kernels, from the one Python value (:data:`mdroll.physics.TWO_PI`).
TWO_PI = wp.constant(wp.float64(physics.TWO_PI))


@wp.func
def sum_of_squares(p: int, q: int) -> wp.float64:
    """``sum_{m=p}^{q} m^2`` for integer offsets p <= q + 1 (0 for an empty range).

    ``(Q(q) - Q(p-1)) / 6`` with ``Q(t) = t (t+1) (2t+1)``, which satisfies
    ``Q(t) - Q(t-1) = 6 t^2`` for every integer t, negative offsets included. For
    ``|t| <= MAX_CLOSED_FORM_OFFSET`` both products are integers below 2^53, their difference is
    exact, and the quotient (an integer below 2^50) is recovered exactly by rounding the product
    with 1/6: a multiply and a round instead of a float64 division (tens of instructions on a
    GPU; int64 division is slower still).
    """
    one = wp.float64(1.0)
    two = wp.float64(2.0)
    t = wp.float64(q)
    s = wp.float64(p - 1)
    return wp.round((t * (t + one) * (two * t + one) - s * (s + one) * (two * s + one)) * ONE_SIXTH)


@wp.func
def sum_of_offsets(p: int, q: int) -> wp.float64:
    """``sum_{m=p}^{q} m = (q (q+1) - (p-1) p) / 2`` for integer offsets p <= q + 1, exact in float64."""
    t = wp.float64(q)
    s = wp.float64(p - 1)
    return (t * (t + wp.float64(1.0)) - s * (s + wp.float64(1.0))) * wp.float64(0.5)


@wp.func
def full_contact_sum(
    prefix: wp.array2d(dtype=wp.float64),
    r: int,
    i: int,
    j: int,
    c: int,
    d: wp.float64,
    curvature: wp.float64,
) -> wp.float64:
    """Exact ``sum_{l=i}^{j-1} (h_l + d - curvature (l - c)^2)`` (m) for springs all in contact.

    The discrete form of eq 19-20: ``(S_j - S_i) + (j - i) d - curvature sum_{m=i-c}^{j-1-c} m^2``
    with the prefix sums ``S_j = sum_{l<j} h_l`` (eq 18). Returns 0 for ``j <= i``.
    """
    if j <= i:
        return wp.float64(0.0)
    return (prefix[r, j] - prefix[r, i]) + wp.float64(j - i) * d - curvature * sum_of_squares(i - c, j - 1 - c)


@wp.func
def spring_sum(
    h: wp.array2d(dtype=wp.float64),
    r: int,
    i: int,
    j: int,
    stride: int,
    c: int,
    d: wp.float64,
    curvature: wp.float64,
) -> wp.float64:
    """Direct ``sum_l max(h_l + d - curvature (l - c)^2, 0)`` (m) over ``l = i, i + stride, ... < j``,
    eq 10-12; ``stride > 1`` lets the lanes of a block share one range, each taking every
    ``stride``-th spring (adjacent lanes read adjacent springs)."""
    acc = wp.float64(0.0)
    zero = wp.float64(0.0)
    for l in range(i, j, stride):
        m = wp.float64(l - c)
        acc += wp.max(h[r, l] + d - curvature * m * m, zero)
    return acc


@wp.func
def reach_inclusive(level: wp.float64, curvature: wp.float64) -> int:
    """Largest m >= 0 with ``curvature m^2 <= level``; -1 if level < 0.

    With ``level = d + max h`` every spring farther than this from the wheel has u < 0: the
    window of possible contact (physics.md section 4).
    """
    if level < wp.float64(0.0):
        return -1
    m = int(wp.floor(wp.sqrt(level / curvature)))
    # sqrt may round either way: fix the last integer exactly
    while m > 0 and curvature * wp.float64(m) * wp.float64(m) > level:
        m -= 1
    while curvature * wp.float64(m + 1) * wp.float64(m + 1) <= level:
        m += 1
    return m


@wp.func
def reach_strict(level: wp.float64, curvature: wp.float64) -> int:
    """Largest m >= 0 with ``curvature m^2 < level``; -1 if level <= 0.

    With ``level = d + min h`` every spring at most this far from the wheel is in contact
    whatever h is: the certainly-full core. With ``level = h_i + d`` it is the sweep's reach
    M_i of spring i: the same test ``fl(h_i + d) > fl(fl(curvature m) m)`` that decides
    ``max(u, 0) > 0`` in :func:`spring_sum` (eq 10).

    A float32 square root guesses m (relative error below 2e-7, so within 0.02 of the root for
    the offsets up to ``MAX_CLOSED_FORM_OFFSET``); the float64 tests then settle it, moving it
    by at most one either way: no unbounded ``while`` loop, which costs several times more a call
    in Warp's CPU code (the sweep evaluates this twice a step).
    """
    if level <= wp.float64(0.0):
        return -1
    return settle_reach(int(wp.sqrt(wp.float32(level) / wp.float32(curvature))), level, curvature)


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return __longlong_as_double(0x4330000000000000LL + (long long)(unsigned)m) - 4503599627370496.0;
#else
return (double)m;
#endif
""")
def exact_double(m: int) -> wp.float64:
    """``m`` as a float64 (0 <= m < 2^31): on CUDA by placing it in the low mantissa bits of
    2^52 and subtracting 2^52, two full-rate instructions instead of a conversion, which a GPU
    multiprocessor issues at 1/8 of the rate of an add."""
    ...


@wp.func
def settle_reach(guess: int, level: wp.float64, curvature: wp.float64) -> int:
    """The largest m >= 0 with ``curvature m^2 < level`` (level > 0) from a guess within one of
    it (``guess >= 0``): the float64 tests ``fl(fl(curvature m) m) < level`` of the direct sum
    (eq 10) move it by at most one either way."""
    m = guess
    root = exact_double(guess)
    if curvature * root * root >= level:
        m -= 1
        root -= wp.float64(1.0)
    root += wp.float64(1.0)
    if curvature * root * root < level:
        m += 1
    return m


@wp.kernel
def indenter_lifts(d: wp.float64, curvature: wp.float64, origin: int, lifts: wp.array(dtype=wp.float64)):
    """``lifts[i] = d - curvature m^2`` (m) at offset ``m = i - origin``: the MDR indenter's
    profile (eq 7, 10) that :func:`blocked_spring_sum` reads."""
    i = wp.tid()
    m = wp.float64(i - origin)
    lifts[i] = d - curvature * m * m


#: Steps per thread in the blocked kernels, and offsets per block: for each block of BLOCK = 8
#: offsets a thread loads the 2 BLOCK - 1 = 15 heights that its 64 (step, offset) pairs need
#: once, into registers.
BLOCK = wp.constant(8)
BLOCK_HEIGHTS = wp.constant(2 * BLOCK - 1)
block_values = wp.types.vector(length=BLOCK, dtype=wp.float64)
block_heights = wp.types.vector(length=BLOCK_HEIGHTS, dtype=wp.float64)


@wp.struct
class Contact:
    """The indenter and springs of a run, constant over its steps: ``dx`` spring spacing (m),
    ``R`` wheel radius (m), ``E_star`` effective modulus (Pa), ``curvature = dx^2 / R`` (m; the
    MDR indenter lowers spring l by ``curvature (l - c)^2``, eq 7, 10) and ``k_spring = E* dx``
    (N/m, eq 11-12)."""

    dx: wp.float64
    R: wp.float64
    E_star: wp.float64
    curvature: wp.float64
    k_spring: wp.float64


@wp.func
def blocked_last_read(first_offset: int, blocks: int) -> int:
    """The largest offset from the wheel's first step c that :func:`blocked_spring_sum` reads for
    ``blocks`` blocks from ``first_offset`` (its smallest is ``first_offset``): the last offset
    summed, ``first_offset + BLOCK blocks - 1``, seen from the last of the BLOCK steps."""
    return first_offset + blocks * BLOCK - 1 + BLOCK - 1


@wp.func
def blocked_spring_sum(
    row: wp.array(dtype=wp.float64),
    c: int,
    first_offset: int,
    blocks: int,
    lifts: wp.array(dtype=wp.float64),
    lift_origin: int,
    d: wp.float64,
    curvature: wp.float64,
    acc: block_values,
) -> block_values:
    """Add ``sum_m max(h_{c+j+m} + d - curvature m^2, 0)`` to ``acc[j]`` for the 8 steps j = 0..7,
    over the offsets ``m = first_offset .. last = first_offset + 8 blocks - 1`` (eq 10-12).

    ``lifts[lift_origin + m] = d - curvature m^2`` (m), the indenter's profile, is the same for
    every thread: a broadcast load instead of three float64 operations per offset. Consecutive
    blocks share 7 of their 15 heights, which stay in registers: 8 loads per block.

    Uses ``max(u, 0) = (u + |u|) / 2``: the inner loop sums ``|u|`` and ``sum_m u`` is exact in
    closed form: the heights of step 0 summed once per block, slid to step j by the springs
    entering and leaving, plus ``8 blocks d - curvature sum m^2``. Cancellation is mild: the
    springs of the window that do not touch have ``|u| <= max h - min h``.

    The caller guarantees that every spring read (``c + first_offset .. c +``
    :func:`blocked_last_read`) lies on the row and every offset on the lift table.
    """
    absolute = block_values()
    heights_step0 = wp.float64(0.0)
    heights = block_heights()
    for i in range(BLOCK - 1):
        heights[BLOCK + i] = row[c + first_offset + i]
    for b in range(blocks):
        m0 = first_offset + b * BLOCK
        # the previous block's last 7 heights are this block's first 7
        for i in range(BLOCK - 1):
            heights[i] = heights[BLOCK + i]
        for i in range(BLOCK):
            heights[BLOCK - 1 + i] = row[c + m0 + BLOCK - 1 + i]
        lift = block_values()
        for k in range(BLOCK):
            lift[k] = lifts[lift_origin + m0 + k]
        # pairwise, for BLOCK = 8
        heights_step0 += ((heights[0] + heights[1]) + (heights[2] + heights[3])) + (
            (heights[4] + heights[5]) + (heights[6] + heights[7])
        )
        for j in range(BLOCK):
            for k in range(BLOCK):
                absolute[j] = absolute[j] + wp.abs(heights[j + k] + lift[k])
    last = first_offset + blocks * BLOCK - 1
    lift_sum = wp.float64(blocks * BLOCK) * d - curvature * sum_of_squares(first_offset, last)
    heights_sum = heights_step0
    half = wp.float64(0.5)
    for j in range(BLOCK):
        acc[j] = acc[j] + half * (heights_sum + lift_sum + absolute[j])
        if j < BLOCK - 1:
            heights_sum += row[c + j + last + 1] - row[c + j + first_offset]
    return acc
