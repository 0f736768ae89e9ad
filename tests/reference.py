"""Independent NumPy references for the tests: written from physics.md, sharing no code with mdroll."""

import numpy as np

GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def to_numpy(array):
    """A NumPy copy of a NumPy, Warp or CuPy array."""
    if isinstance(array, np.ndarray):
        return array
    if hasattr(array, "numpy"):
        return array.numpy()
    return array.get()


def splitmix_mix(z):
    with np.errstate(over="ignore"):
        z = np.asarray(z, dtype=np.uint64)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


def uniform_phases(seed, realization, modes):
    """u in [0,1) for the counter (seed, realization, mode), as documented in kernels/lines.py."""
    with np.errstate(over="ignore"):
        key = splitmix_mix(np.uint64(seed) + GOLDEN * np.uint64(realization + 1))
        z = splitmix_mix(key + GOLDEN * (np.asarray(modes, dtype=np.uint64) + np.uint64(1)))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0**-53


def rough_line(params, seed, realization):
    """physics.md section 3, with numpy.fft: phases from the counter hash, RMS rescaled to h0."""
    n = params.n_points
    L = n * params.dx
    k = np.arange(n // 2 + 1)
    q = 2 * np.pi * k / L
    band = (q >= params.q_min * (1 - 1e-12)) & (q <= params.q_max * (1 + 1e-12))  # inclusive, to rounding
    B = np.zeros(n // 2 + 1)
    B[band] = q[band] ** (-(params.H + 0.5))
    phase = 2 * np.pi * uniform_phases(seed, realization, k)
    h = np.fft.irfft(B * np.exp(1j * phase), n=n)
    return h * params.h0 / np.sqrt(np.mean(h**2))


def direct_force(h, params, x_wheel, d):
    """F(x_w, d) = E* dx sum_i max(h_i + d - (x_i - x_w)^2 / R, 0) (eq 10-12), every spring on the line."""
    x = np.arange(h.size) * params.dx
    u = h[None, :] + d - (x[None, :] - np.asarray(x_wheel)[:, None]) ** 2 / params.R
    return params.E_star * params.dx * np.sum(np.maximum(u, 0.0), axis=1)


def psd(series, dx, window=False):
    """Two-sided PSD C(q_k) = L/(2 pi) |B_k|^2, B_k = (1/N) sum_s (F_s - mean) w_s e^{-i q_k x_s}
    (section 6), w = 1 or the Hann window 0.5 - 0.5 cos(2 pi s / N) scaled to mean square 1."""
    series = np.asarray(series, dtype=np.float64)
    n = series.shape[-1]
    w = np.ones(n)
    if window:
        w = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)
        w /= np.sqrt(np.mean(w * w))
    B = np.fft.rfft((series - series.mean(axis=-1, keepdims=True)) * w, axis=-1) / n
    q = 2 * np.pi * np.arange(n // 2 + 1) / (n * dx)
    return q, n * dx / (2 * np.pi) * np.abs(B) ** 2


def contact_reach(h, params, d):
    """M_i, the largest integer m >= 0 with ``h_i + d - (dx^2/R) m^2 > 0`` evaluated as the direct
    sum evaluates u (eq 10), -1 where ``h_i + d <= 0`` (physics.md section 4, sweep)."""
    kappa = params.dx**2 / params.R
    level = h + d
    m = np.floor(np.sqrt(np.maximum(level, 0.0) / kappa)).astype(np.int64)
    for _ in range(4):  # the square root may round either way: settle the last integer exactly
        m = np.where((m >= 0) & (level - kappa * m * m <= 0.0), m - 1, m)
        m = np.where(level - kappa * (m + 1) * (m + 1) > 0.0, m + 1, m)
    assert np.all(level - kappa * m * m > 0.0) or np.all((level - kappa * m * m > 0.0) | (m < 0))
    return np.where(level > 0.0, m, -1)


def sweep_force(h, params, wheel, d):
    """F(c) (N) for the wheel at the consecutive springs ``wheel`` of the line h by the sweep with
    difference arrays: spring i touches for c in [i - M_i, i + M_i], so the totals over the
    contact set (count, sum h, sum i, sum i^2) are cumulative sums of +1 events at ``i - M_i`` and
    -1 events at ``i + M_i + 1``, and F = k (sum h + N d - kappa sum (i - c)^2) (eq 10-12)."""
    kappa = params.dx**2 / params.R
    reach = contact_reach(h, params, d)
    i = np.nonzero(reach >= 0)[0]
    m = reach[i]
    lo = int((i - m).min())
    size = int((i + m).max()) + 2 - lo
    quantities = (np.ones_like(i), h[i], i, i * i)
    totals = []
    for q in quantities:
        diff = np.zeros(size, dtype=np.asarray(q).dtype)
        np.add.at(diff, i - m - lo, q)
        np.add.at(diff, i + m + 1 - lo, -q)
        totals.append(np.cumsum(diff))
    c = np.asarray(wheel, dtype=np.int64)
    at = np.clip(c - lo, 0, size - 1)
    inside = (c >= lo) & (c < lo + size)
    count, heights, first, second = (np.where(inside, t[at], 0) for t in totals)
    squares = second - 2 * c * first + c * c * count  # exact int64
    return params.E_star * params.dx * (heights + count * d - kappa * squares)
