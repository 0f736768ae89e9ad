"""Kernels of the spectra stage (physics.md sections 5.1 and 6): one pass over each force series
for its sums and the decoupled wheel's final state, one pass over the half spectra for the PSDs
and their ensemble moments.

Complex numbers are ``wp.vec2d`` (real, imaginary), the layout of complex128.
"""

import functools

import warp as wp

from .. import physics
from .common import TWO_PI

#: 1 / sqrt(3/8): scales the Hann window to mean square 1, which keeps the total power.
HANN_NORM = wp.constant(wp.float64(physics.HANN_NORM))
#: Threads sharing one series in :func:`series_summary` on CUDA; their partial sums are added
#: in a fixed order, so the result does not depend on scheduling.
SUMMARY_THREADS = 1024
#: Steps each thread of :func:`series_summary` loads before adding them.
SUMMARY_LOADS = wp.constant(8)
summary_values = wp.types.vector(length=SUMMARY_LOADS, dtype=wp.float64)
#: Columns of :func:`series_summary`'s sums, read by :func:`psd_moments_kernel`'s kernels and the host.
SUM_DEVIATION = wp.constant(0)
SUM_SQUARES = wp.constant(1)
LOST = wp.constant(2)
NOT_FINITE = wp.constant(3)
FINAL_Y = wp.constant(4)
FINAL_V = wp.constant(5)
SUM_COLUMNS = 6


@wp.func
def complex_mul(a: wp.vec2d, b: wp.vec2d) -> wp.vec2d:
    return wp.vec2d(a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0])


@wp.func
def complex_div(a: wp.vec2d, b: wp.vec2d) -> wp.vec2d:
    return complex_mul(a, wp.vec2d(b[0], -b[1])) / wp.dot(b, b)


@wp.kernel
def euler_impulse_response(phi: wp.float64, dt: wp.float64, weights: wp.array(dtype=wp.vec2d)):
    """``weights[m] = A^m b``: the state (y, y') m steps after a unit input ``u`` (m/s^2) of one
    semi-implicit Euler step, ``x_{s+1} = A x_s + b u_s`` with ``A = [[1 - h^2, dt], [-h^2/dt, 1]]``,
    ``b = (dt^2, dt)``, h = omega dt (section 5.1).

    det A = 1 and tr A = 2 cos(phi) with ``phi = 2 asin(h / 2)``, so by Cayley-Hamilton
    ``A^m = (sin(m phi) A - sin((m - 1) phi) I) / sin(phi)``: exact for every m, where a
    recursion over 10^6 steps would accumulate rounding.
    """
    m = wp.tid()
    h2 = wp.float64(4.0) * wp.sin(phi * wp.float64(0.5)) * wp.sin(phi * wp.float64(0.5))
    s1 = wp.sin(phi)
    p = wp.sin(wp.float64(m) * phi) / s1
    q = wp.sin(wp.float64(m - 1) * phi) / s1
    # A b = ((1 - h^2) dt^2 + dt^2, -h^2 dt + dt) = dt (dt (2 - h^2), 1 - h^2)
    ab = dt * wp.vec2d(dt * (wp.float64(2.0) - h2), wp.float64(1.0) - h2)
    weights[m] = p * ab - q * wp.vec2d(dt * dt, dt)


@wp.func
def summary_add(u: wp.float64, weight: wp.vec2d, F_N: wp.float64, sums: wp.vec4d, state: wp.vec2d):
    """One step of :func:`series_summary`: ``sums += (u, u^2, u <= -F_N, 0)`` and
    ``state += u weight`` for a finite u, ``sums += (0, 0, 0, 1)`` otherwise."""
    if not wp.isfinite(u):
        sums = sums + wp.vec4d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0), wp.float64(1.0))
    else:
        lost = wp.float64(0.0)
        if u <= -F_N:
            lost = wp.float64(1.0)
        sums = sums + wp.vec4d(u, u * u, lost, wp.float64(0.0))
        state = state + u * weight
    return sums, state


@wp.func
def finish_summary(
    deviation: wp.array2d(dtype=wp.float64),
    weights: wp.array(dtype=wp.vec2d),
    with_state: int,
    r: int,
    t: int,
    s: int,
    steps: int,
    threads: int,
    F_N: wp.float64,
    inv_mass: wp.float64,
    sums: wp.vec4d,
    state: wp.vec2d,
    partial: wp.array3d(dtype=wp.float64),
):
    """The end of :func:`series_summary` for thread t of row r: steps s, s + threads, ... below
    ``steps`` added one at a time, then the thread's partial sums written."""
    while s < steps:
        w = wp.vec2d()
        if with_state == 1:
            w = weights[steps - 1 - s]
        sums, state = summary_add(deviation[r, s], w, F_N, sums, state)
        s += threads
    partial[r, t, SUM_DEVIATION] = sums[0]
    partial[r, t, SUM_SQUARES] = sums[1]
    partial[r, t, LOST] = sums[2]
    partial[r, t, NOT_FINITE] = sums[3]
    partial[r, t, FINAL_Y] = -inv_mass * state[0]
    partial[r, t, FINAL_V] = -inv_mass * state[1]


@wp.kernel
def series_summary(
    deviation: wp.array2d(dtype=wp.float64),
    steps: int,
    threads: int,
    F_N: wp.float64,
    inv_mass: wp.float64,
    weights: wp.array(dtype=wp.vec2d),
    with_state: int,
    partial: wp.array3d(dtype=wp.float64),
):
    """Partial sums of one series of force deviations ``u = F - F_N`` (N) per thread ``t`` of its
    row, over steps t, t + threads, ...:

    ``partial[r, t] = (sum u, sum u^2, #(u <= -F_N), #(u not finite), x_N)``,

    with ``x_N = -sum_s weights[N-1-s] u_s / m`` the decoupled wheel's state (y, y') (m, m/s)
    after the last step, started at rest (section 5.1; ``weights`` from
    :func:`euler_impulse_response`), when ``with_state`` is 1.

    The force kernels write ``u`` directly (their ``offset`` F_N): the spectra then see the
    ~1 N signal without the 40 kN mean, whose rounding would otherwise leak into every bin of
    the FFT, and this pass only reads. ``u <= -F_N`` is contact lost: it holds for every F <= 0
    (rounding is monotonic) and for no F above ulp(F_N)/2 (3.6e-12 N at 40 kN).

    Each thread loads ``SUMMARY_LOADS`` steps before it adds them (in order, so the sums are
    those of one step at a time): with one load in flight per thread the pass is bound by the
    loads' latency, with eight by the memory's bandwidth (docs/performance.md, "Spectra").
    """
    r, t = wp.tid()
    sums = wp.vec4d()
    state = wp.vec2d()
    s = t
    while s + (SUMMARY_LOADS - 1) * threads < steps:
        u = summary_values()
        weight_y = summary_values()
        weight_v = summary_values()
        for i in range(SUMMARY_LOADS):
            u[i] = deviation[r, s + i * threads]
        if with_state == 1:
            for i in range(SUMMARY_LOADS):
                w = weights[steps - 1 - s - i * threads]
                weight_y[i] = w[0]
                weight_v[i] = w[1]
        for i in range(SUMMARY_LOADS):
            sums, state = summary_add(u[i], wp.vec2d(weight_y[i], weight_v[i]), F_N, sums, state)
        s += SUMMARY_LOADS * threads
    finish_summary(deviation, weights, with_state, r, t, s, steps, threads, F_N, inv_mass, sums, state, partial)


@wp.kernel
def add_partials(partial: wp.array3d(dtype=wp.float64), threads: int, sums: wp.array2d(dtype=wp.float64)):
    """``sums[r, j] = sum_t partial[r, t, j]``, in the order of t."""
    r, j = wp.tid()
    acc = wp.float64(0.0)
    for t in range(threads):
        acc += partial[r, t, j]
    sums[r, j] = acc


@wp.kernel
def merge_moments(count: wp.float64, added: wp.float64, mean: wp.array(dtype=wp.float64), m2: wp.array(dtype=wp.float64),
                  moments: wp.array(dtype=wp.vec2d)):
    """Chan et al.'s merge of ``added`` samples of per-bin mean and M2 (``moments[k]``) into
    ``count`` samples' ``mean[k]`` and ``m2[k]``, in place: ``delta = mean_b - mean``,
    ``mean += delta added / total``, ``m2 += m2_b + delta^2 count added / total`` (the
    expressions of :meth:`mdroll.ensemble.psd.RunningMoments.merge`, in one pass)."""
    k = wp.tid()
    total = count + added
    batch = moments[k]
    delta = batch[0] - mean[k]
    mean[k] = mean[k] + delta * (added / total)
    m2[k] = m2[k] + batch[1] + delta * delta * (count * added / total)


@wp.struct
class ResponseBin:
    """Section 5.1 in the frequency domain at one bin, ``z = exp(2 pi i k / N)``: the DFT of the
    decoupled acceleration over N steps is ``Y = G U + c_y y_N + c_v y'_N`` with U the DFT of
    ``u = (F_N - F) / m`` and (y_N, y'_N) the state after the last step (from rest at s = 0).
    From ``z (X + x_N) = A X + b U`` and ``y'' = u - omega^2 y``:
    ``G = (z - 1)^2 / D``, ``c_y = omega^2 z (z - 1) / D``, ``c_v = omega^2 dt z / D``,
    ``D = (z - 1)^2 + h^2 z``, h = omega dt."""

    gain: wp.vec2d
    c_y: wp.vec2d
    c_v: wp.vec2d


@wp.func
def response_bin(j: int, steps: int, omega2: wp.float64, dt: wp.float64) -> ResponseBin:
    theta = TWO_PI * wp.float64(j) / wp.float64(steps)
    half = wp.sin(theta * wp.float64(0.5))
    z = wp.vec2d(wp.cos(theta), wp.sin(theta))
    # z - 1 with its real part -2 sin^2(theta/2): no cancellation at small theta
    zm1 = wp.vec2d(wp.float64(-2.0) * half * half, z[1])
    zm1_sq = complex_mul(zm1, zm1)
    denominator = zm1_sq + omega2 * dt * dt * z
    out = ResponseBin()
    out.gain = complex_div(zm1_sq, denominator)
    out.c_y = omega2 * complex_div(complex_mul(z, zm1), denominator)
    out.c_v = omega2 * dt * complex_div(z, denominator)
    return out


@wp.kernel
def response_table(steps: int, omega2: wp.float64, dt: wp.float64, table: wp.array(dtype=ResponseBin)):
    """``table[j] = response_bin(j, steps, omega2, dt)`` for the bins j of a half spectrum: the
    same for every batch of a run, so :func:`psd_moments_kernel` reads it instead of three sines
    and cosines a bin, the most expensive part of the launch on the CPU."""
    j = wp.tid()
    table[j] = response_bin(j, steps, omega2, dt)


@wp.func
def mirrored_bin(j: int, bins: int, steps: int) -> int:
    """The bin of a half spectrum (0..bins-1) that holds X_j, or its conjugate, for j in (-bins, steps)."""
    if j < 0:
        return -j
    if j >= bins:
        return steps - j
    return j


@wp.func
def bin_value(
    spectrum: wp.array2d(dtype=wp.vec2d),
    r: int,
    j: int,
    bins: int,
    steps: int,
    decoupled_accel: int,
    response: ResponseBin,
    inv_mass: wp.float64,
    state: wp.vec2d,
) -> wp.vec2d:
    """X_j of row r for any j in (-bins, steps), from a half spectrum of ``bins`` bins: Hermitian
    symmetry ``X_{-j} = X_{N-j} = conj(X_j)`` gives the bins it lacks, and ``X_0 = 0`` removes the
    mean. With ``decoupled_accel`` 1, the decoupled acceleration's Y_j (m/s^2) instead, from the
    force's X_j, the ``response`` of bin ``mirrored_bin(j)`` and the final ``state`` (:class:`ResponseBin`)."""
    k = mirrored_bin(j, bins, steps)
    if k == 0:
        return wp.vec2d()
    x = spectrum[r, k]
    if decoupled_accel == 1:
        x = complex_mul(response.gain, -inv_mass * x) + state[0] * response.c_y + state[1] * response.c_v
    if k != j:
        x = wp.vec2d(x[0], -x[1])
    return x


@wp.func
def is_finite_pair(v: wp.vec2d) -> bool:
    return wp.isfinite(v[0]) and wp.isfinite(v[1])


@wp.func
def add_deviation(psd: wp.vec2d, shift: wp.vec2d, r: int, not_finite: wp.array(dtype=wp.int32), sums: wp.vec2d,
                  squares: wp.vec2d):
    """Flag row r if ``psd`` is not finite; add ``psd - shift`` and its square to the sums."""
    if not is_finite_pair(psd):
        not_finite[r] = 1
    deviation = psd - shift
    return sums + deviation, squares + wp.cw_mul(deviation, deviation)


@functools.cache
def psd_moments_kernel(decoupled: bool, window: bool) -> wp.Kernel:
    """The PSD-moments kernel for one mode: ``decoupled`` (the acceleration's spectrum from the
    force's) or coupled (from its own), with or without the Hann ``window``; each pair is
    compiled apart (``wp.static``), so a kernel carries neither branch nor registers of the
    others, and each thread takes several rows at a time (docs/performance.md, "Spectra").

    Launched over the bins k, it writes per bin the mean and M2 (sum of squared deviations)
    over the rows of the two-sided PSDs ``C(q_k) = psd_scale |B_k|^2`` of the force (N^2 m) and
    the acceleration ((m/s^2)^2 m), ``psd_scale = dx / (2 pi N)`` for unnormalized spectra
    (section 6: ``L/(2 pi) |X/N|^2``).

    The force's X_k comes from ``force_spectrum`` (its mean removed by X_0 = 0); the
    acceleration's from ``accel_spectrum`` (coupled) or, decoupled, from the force's by
    :func:`bin_value` with ``states[r, FINAL_Y]``, ``states[r, FINAL_V]`` the final states
    (:func:`series_summary`) and ``responses`` (:func:`response_table`; read only when
    decoupled). The Hann window is a three-bin stencil. A row with a non-finite
    PSD sets ``not_finite[r]``.

    Per bin, the sums are of deviations from the first row's PSDs: the mean and M2 without a
    division per row, and exact where every row has the same PSD. Rows go four at a time, all
    loaded before any is added (in order, so the sums are the same).
    """

    @wp.func
    def row_psds(
        force_spectrum: wp.array2d(dtype=wp.vec2d),
        accel_spectrum: wp.array2d(dtype=wp.vec2d),
        states: wp.array2d(dtype=wp.float64),
        r: int,
        k: int,
        bins: int,
        steps: int,
        centre: ResponseBin,
        left: ResponseBin,
        right: ResponseBin,
        inv_mass: wp.float64,
        psd_scale: wp.float64,
    ) -> wp.vec2d:
        """(force PSD, acceleration PSD) of row r at bin k."""
        b_force = bin_value(force_spectrum, r, k, bins, steps, 0, centre, inv_mass, wp.vec2d())
        state = wp.vec2d(states[r, FINAL_Y], states[r, FINAL_V])
        if wp.static(decoupled):
            b_accel = bin_value(force_spectrum, r, k, bins, steps, 1, centre, inv_mass, state)
        else:
            b_accel = bin_value(accel_spectrum, r, k, bins, steps, 0, centre, inv_mass, wp.vec2d())
        if wp.static(window):
            # the Hann window (0.5 - 0.5 cos(2 pi s / N)) / sqrt(3/8), of mean square 1, is a
            # three-bin stencil: (X_k / 2 - X_{k-1} / 4 - X_{k+1} / 4) / sqrt(3/8)
            if wp.static(decoupled):
                a_sides = bin_value(force_spectrum, r, k - 1, bins, steps, 1, left, inv_mass, state) + bin_value(
                    force_spectrum, r, k + 1, bins, steps, 1, right, inv_mass, state)
            else:
                a_sides = bin_value(accel_spectrum, r, k - 1, bins, steps, 0, left, inv_mass, wp.vec2d()) + bin_value(
                    accel_spectrum, r, k + 1, bins, steps, 0, right, inv_mass, wp.vec2d())
            f_sides = bin_value(force_spectrum, r, k - 1, bins, steps, 0, left, inv_mass, wp.vec2d()) + bin_value(
                force_spectrum, r, k + 1, bins, steps, 0, right, inv_mass, wp.vec2d())
            b_force = HANN_NORM * (wp.float64(0.5) * b_force - wp.float64(0.25) * f_sides)
            b_accel = HANN_NORM * (wp.float64(0.5) * b_accel - wp.float64(0.25) * a_sides)
        return psd_scale * wp.vec2d(wp.dot(b_force, b_force), wp.dot(b_accel, b_accel))

    @wp.kernel(module="unique")
    def psd_moments(
        force_spectrum: wp.array2d(dtype=wp.vec2d),
        accel_spectrum: wp.array2d(dtype=wp.vec2d),
        states: wp.array2d(dtype=wp.float64),
        steps: int,
        psd_scale: wp.float64,
        responses: wp.array(dtype=ResponseBin),
        inv_mass: wp.float64,
        force_moments: wp.array(dtype=wp.vec2d),
        accel_moments: wp.array(dtype=wp.vec2d),
        not_finite: wp.array(dtype=wp.int32),
    ):
        k = wp.tid()
        rows = force_spectrum.shape[0]
        bins = force_spectrum.shape[1]
        centre = ResponseBin()
        left = centre
        right = centre
        if wp.static(decoupled):
            centre = responses[k]
            if wp.static(window):
                left = responses[mirrored_bin(k - 1, bins, steps)]
                right = responses[mirrored_bin(k + 1, bins, steps)]
        shift = row_psds(force_spectrum, accel_spectrum, states, 0, k, bins, steps, centre, left, right, inv_mass,
                         psd_scale)
        if not is_finite_pair(shift):
            not_finite[0] = 1
        sums = wp.vec2d()
        squares = wp.vec2d()
        r = int(1)
        while r + 3 < rows:
            a = row_psds(force_spectrum, accel_spectrum, states, r, k, bins, steps, centre, left, right, inv_mass,
                         psd_scale)
            b = row_psds(force_spectrum, accel_spectrum, states, r + 1, k, bins, steps, centre, left, right, inv_mass,
                         psd_scale)
            c = row_psds(force_spectrum, accel_spectrum, states, r + 2, k, bins, steps, centre, left, right, inv_mass,
                         psd_scale)
            e = row_psds(force_spectrum, accel_spectrum, states, r + 3, k, bins, steps, centre, left, right, inv_mass,
                         psd_scale)
            sums, squares = add_deviation(a, shift, r, not_finite, sums, squares)
            sums, squares = add_deviation(b, shift, r + 1, not_finite, sums, squares)
            sums, squares = add_deviation(c, shift, r + 2, not_finite, sums, squares)
            sums, squares = add_deviation(e, shift, r + 3, not_finite, sums, squares)
            r += 4
        while r < rows:
            a = row_psds(force_spectrum, accel_spectrum, states, r, k, bins, steps, centre, left, right, inv_mass,
                         psd_scale)
            sums, squares = add_deviation(a, shift, r, not_finite, sums, squares)
            r += 1
        count = wp.float64(rows)
        zero = wp.float64(0.0)
        force_moments[k] = wp.vec2d(shift[0] + sums[0] / count, wp.max(squares[0] - sums[0] * sums[0] / count, zero))
        accel_moments[k] = wp.vec2d(shift[1] + sums[1] / count, wp.max(squares[1] - sums[1] * sums[1] / count, zero))

    return psd_moments
