"""Kernels that make and pre-process rough lines: random spectra, bounds, min/max tree.

All work on a batch of R lines stored as rows of a 2D float64 array.
"""

import warp as wp

from .common import TWO_PI

#: splitmix64 constants (Steele, Lea & Flood 2014): the golden-ratio increment and the two
#: multipliers of its output mix.
GOLDEN_GAMMA = wp.constant(wp.uint64(0x9E3779B97F4A7C15))
MIX_MULTIPLIER_1 = wp.constant(wp.uint64(0xBF58476D1CE4E5B9))
MIX_MULTIPLIER_2 = wp.constant(wp.uint64(0x94D049BB133111EB))

#: Threads sharing a row in the bounds reduction on CUDA, and the loads each has in flight: fewer
#: threads leave the loads' latency exposed, more leave more partials for each row's one thread
#: to combine (docs/performance.md, "Preparing the lines").
BOUNDS_THREADS = 512
BOUNDS_UNROLL = 8
#: Partials a thread combines in the middle stage of the bounds reduction (forces/prepared.py).
BOUNDS_GROUP = 32


@wp.func
def mix64(z: wp.uint64) -> wp.uint64:
    """The splitmix64 finalizer: a bijective 64-bit hash with full avalanche."""
    z = (z ^ (z >> wp.uint64(30))) * MIX_MULTIPLIER_1
    z = (z ^ (z >> wp.uint64(27))) * MIX_MULTIPLIER_2
    return z ^ (z >> wp.uint64(31))


@wp.func
def realization_key(seed: wp.uint64, realization: wp.int64) -> wp.uint64:
    """``key = mix64(seed + G (realization + 1))`` (G the golden gamma): the per-realization
    key of :func:`uniform_from_key`."""
    return mix64(seed + GOLDEN_GAMMA * (wp.uint64(realization) + wp.uint64(1)))


@wp.func
def uniform_from_key(key: wp.uint64, mode: int) -> wp.float64:
    """Uniform float64 in [0, 1) from the counter (seed, realization, mode) alone:
    ``u = mix64(key + G (mode + 1)) >> 11`` scaled by 2^-53, with ``key`` from
    :func:`realization_key`. A counter-based generator, so every phase depends only on (seed,
    realization index, mode), whatever the batch or the device.
    """
    z = mix64(key + GOLDEN_GAMMA * (wp.uint64(mode) + wp.uint64(1)))
    return wp.float64(z >> wp.uint64(11)) * wp.float64(1.1102230246251565e-16)


@wp.kernel
def mode_amplitudes(k_first: int, k_last: int, exponent: wp.float64, amplitudes: wp.array(dtype=wp.float64)):
    """``a_k = (k / k_first)^exponent`` for k_first <= k <= k_last, else 0: with ``exponent =
    -(H + 1/2)`` the amplitude of mode k follows ``sqrt(C_1D(q_k))``, ``C_1D ~ q^(-2H-1)`` (eq 33),
    up to the line's scale. The same for every row, so computed once per batch."""
    k = wp.tid()
    a = wp.float64(0.0)
    if k >= k_first and k <= k_last:
        a = wp.pow(wp.float64(k) / wp.float64(k_first), exponent)
    amplitudes[k] = a


@wp.kernel
def line_scales(
    realizations: wp.array(dtype=wp.int64),
    seed: wp.uint64,
    amplitudes: wp.array(dtype=wp.float64),
    nyquist: int,
    sum_of_squares: wp.array(dtype=wp.float64),
    target: wp.float64,
    absolute: int,
    scales: wp.array(dtype=wp.float64),
    keys: wp.array(dtype=wp.uint64),
):
    """The factor on each row's amplitudes that makes the line's RMS ``target`` (m; h0), by
    Parseval before the inverse FFT instead of a pass over the line after: for the unnormalized
    inverse (``mdroll.fft.irfft_rows``)
    ``mean(h^2) = scale^2 (2 sum_{0 < k < n/2} a_k^2 + (a_{n/2} cos phi_{n/2})^2)``, with
    ``sum_of_squares[0] = sum_k a_k^2`` over the whole half spectrum. Only the Nyquist mode
    (``nyquist`` = n/2 when the line has one, else -1) is real, so only its share depends on
    the phase. With ``absolute`` nonzero the amplitudes are already the physical ``B(q_k)`` of an
    absolute spectrum (``mdroll.roughness.line_grid.mode_amplitude_table``) and every scale is 1.
    Also writes each row's generator key (:func:`realization_key`), so that
    :func:`random_phase_spectrum` hashes once per mode, not twice."""
    r = wp.tid()
    key = realization_key(seed, realizations[r])
    keys[r] = key
    if absolute != 0:
        scales[r] = wp.float64(1.0)
        return
    total = wp.float64(2.0) * sum_of_squares[0]
    if nyquist > 0:
        a_nyquist = amplitudes[nyquist]
        a = a_nyquist * wp.cos(TWO_PI * uniform_from_key(key, nyquist))
        total += a * a - wp.float64(2.0) * a_nyquist * a_nyquist
    scales[r] = target / wp.sqrt(total)


@wp.func
def phase_mode(keys: wp.array(dtype=wp.uint64), amplitudes: wp.array(dtype=wp.float64), nyquist: int,
               scales: wp.array(dtype=wp.float64), r: int, k: int) -> wp.vec2d:
    """``X_k = scales[r] a_k exp(i phi_k)`` of row r (m), real at the Nyquist mode."""
    value = wp.vec2d(wp.float64(0.0), wp.float64(0.0))
    a = amplitudes[k]
    if a != wp.float64(0.0):
        amplitude = scales[r] * a
        phase = TWO_PI * uniform_from_key(keys[r], k)
        value = wp.vec2d(amplitude * wp.cos(phase), amplitude * wp.sin(phase))
        if k == nyquist:
            value = wp.vec2d(value[0], wp.float64(0.0))
    return value


@wp.kernel
def random_phase_spectrum(
    keys: wp.array(dtype=wp.uint64),
    amplitudes: wp.array(dtype=wp.float64),
    nyquist: int,
    scales: wp.array(dtype=wp.float64),
    spectrum: wp.array2d(dtype=wp.vec2d),
):
    """Half spectrum X_k (k = 0..n/2) of one rough line per row, for an inverse real FFT:
    ``X_k = scales[r] a_k exp(i phi_k)`` (a_k from :func:`mode_amplitudes`, or a table uploaded
    from the host for any other spectrum), with
    ``phi_k = 2 pi u(seed, realization, k)`` (eq 16-17; ``keys`` from :func:`line_scales`). The
    Nyquist mode (k = ``nyquist``) of a real line is real: ``X_{n/2} = scales[r] a_{n/2} cos(phi)``.

    Launched over ``(R, ceil(bins / 2))``: thread j makes modes 2j and 2j + 1, whose hashes and
    sines overlap (docs/performance.md, "Rough lines").
    """
    r, j = wp.tid()
    k = 2 * j
    first = phase_mode(keys, amplitudes, nyquist, scales, r, k)
    if k + 1 < spectrum.shape[1]:
        spectrum[r, k + 1] = phase_mode(keys, amplitudes, nyquist, scales, r, k + 1)
    spectrum[r, k] = first


@wp.kernel
def random_phase_spans(
    keys: wp.array(dtype=wp.uint64),
    amplitudes: wp.array(dtype=wp.float64),
    nyquist: int,
    scales: wp.array(dtype=wp.float64),
    span: int,
    spectrum: wp.array2d(dtype=wp.vec2d),
):
    """:func:`random_phase_spectrum`'s modes (the same values) for the CPU: thread j of row r
    makes modes ``j span .. (j + 1) span - 1``. Warp's CPU launch runs its threads one after
    another, so a thread for every two modes would spend its time on the launch's overhead."""
    r, j = wp.tid()
    for k in range(j * span, wp.min((j + 1) * span, spectrum.shape[1])):
        spectrum[r, k] = phase_mode(keys, amplitudes, nyquist, scales, r, k)


@wp.kernel
def row_min_max(partial: wp.array2d(dtype=wp.vec2d), n_blocks: int, bounds: wp.array(dtype=wp.vec2d)):
    """Min and max of each row from its block partials: ``bounds[r] = (min h, max h)``."""
    r = wp.tid()
    b0 = partial[r, 0]
    lo = b0[0]
    hi = b0[1]
    b = int(1)
    while b + BOUNDS_UNROLL <= n_blocks:  # BOUNDS_UNROLL loads in flight at once
        for u in range(BOUNDS_UNROLL):
            v = partial[r, b + u]
            lo = wp.min(lo, v[0])
            hi = wp.max(hi, v[1])
        b += BOUNDS_UNROLL
    for k in range(b, n_blocks):
        v = partial[r, k]
        lo = wp.min(lo, v[0])
        hi = wp.max(hi, v[1])
    bounds[r] = wp.vec2d(lo, hi)


@wp.kernel
def strided_min_max(h: wp.array2d(dtype=wp.float64), n: int, threads: int, out: wp.array2d(dtype=wp.vec2d)):
    """(min h, max h) over springs t, t + threads, ... of each row, for thread t: neighbouring
    threads read neighbouring springs (coalesced), the partials of the row bounds. A thread has
    BOUNDS_UNROLL loads in flight at once, so that the pass is bound by the memory's bandwidth,
    not by each load's latency."""
    r, t = wp.tid()
    lo = h[r, t]
    hi = lo
    i = t + threads
    while i + (BOUNDS_UNROLL - 1) * threads < n:
        for u in range(BOUNDS_UNROLL):
            v = h[r, i + u * threads]
            lo = wp.min(lo, v)
            hi = wp.max(hi, v)
        i += BOUNDS_UNROLL * threads
    for k in range(i, n, threads):
        lo = wp.min(lo, h[r, k])
        hi = wp.max(hi, h[r, k])
    out[r, t] = wp.vec2d(lo, hi)


@wp.kernel
def segment_min_max(h: wp.array2d(dtype=wp.float64), n: int, segment: int, out: wp.array2d(dtype=wp.vec2d)):
    """(min h, max h) of each segment of ``segment`` springs of each row: the leaves of the
    min/max tree."""
    r, j = wp.tid()
    start = j * segment
    end = wp.min(start + segment, n)
    lo = h[r, start]
    hi = lo
    for i in range(start + 1, end):
        lo = wp.min(lo, h[r, i])
        hi = wp.max(hi, h[r, i])
    out[r, j] = wp.vec2d(lo, hi)


@wp.kernel
def tree_parents(
    tree: wp.array2d(dtype=wp.vec2d),
    child_offset: int,
    child_count: int,
    parent_offset: int,
):
    """One level up the tree: node j covers children 2j and 2j+1 (the last may be missing)."""
    r, j = wp.tid()
    left = tree[r, child_offset + 2 * j]
    lo = left[0]
    hi = left[1]
    if 2 * j + 1 < child_count:
        right = tree[r, child_offset + 2 * j + 1]
        lo = wp.min(lo, right[0])
        hi = wp.max(hi, right[1])
    tree[r, parent_offset + j] = wp.vec2d(lo, hi)


@wp.kernel
def periodic_extend(h: wp.array2d(dtype=wp.float64), n: int, pad: int, extended: wp.array2d(dtype=wp.float64)):
    """``extended[r, i] = h[r, (i - pad) mod n]``: the line with ``pad`` wrapped springs each side."""
    r, i = wp.tid()
    j = (i - pad) % n
    if j < 0:
        j += n
    extended[r, i] = h[r, j]


@wp.kernel
def add_to_rows(h: wp.array2d(dtype=wp.float64), line: wp.array(dtype=wp.float64)):
    """``h[r, i] += line[i]``: one deterministic line added to every row."""
    r, i = wp.tid()
    h[r, i] = h[r, i] + line[i]
