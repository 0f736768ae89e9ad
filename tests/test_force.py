"""The three force algorithms (physics.md sections 2 and 4) against independent references."""

import numpy as np
import pytest
from reference import direct_force, psd, to_numpy

from mdroll.errors import ParameterError
from mdroll import Params, contact_force, rough_lines, step_range
from mdroll.devices import to_warp
from mdroll.forces.registry import REGISTRY

SMALL = Params(L=0.03, dx=20e-6)  # 1500 springs, a/dx = 253


def _lines(params, seed, count, device):
    """Lines generated on the CPU (on CUDA that needs CuPy, the kernels do not): NumPy for the
    CPU, else a Warp array on ``device``."""
    lines = rough_lines(params, seed=seed, realizations=count, device="cpu")
    return lines if device == "cpu" else to_warp(lines, device)


@pytest.mark.parametrize("boundary", ["open", "periodic"])
@pytest.mark.parametrize("h0,d_factor", [(0.5e-6, 1.0), (5e-6, 1.0), (2e-6, 0.9)])
def test_direct_matches_numpy_reference(kernel_device, boundary, h0, d_factor):
    p = SMALL.replace(h0=h0)
    d = p.d0 * d_factor
    lines = to_numpy(_lines(p, 11, 3, kernel_device))
    force = to_numpy(contact_force(lines if kernel_device == "cpu" else _lines(p, 11, 3, kernel_device), p, "direct", boundary, d=d, device=kernel_device))
    n = p.n_points
    first, steps = step_range(p, boundary, d, lines.max())
    assert force.shape == (3, steps)
    for r in range(3):
        if boundary == "open":
            x_wheel = (first + np.arange(steps)) * p.dx
            ref = direct_force(lines[r], p, x_wheel, d)
        else:  # a periodic line: the wheel sees three copies side by side
            tiled = np.tile(lines[r], 3)
            ref = direct_force(tiled, p, (n + np.arange(steps)) * p.dx, d)
        assert np.max(np.abs(force[r] - ref) / ref) <= 1e-12


@pytest.mark.parametrize("boundary", ["open", "periodic"])
@pytest.mark.parametrize("H", [0.3, 0.7, 0.9])
@pytest.mark.parametrize("h0", [0.5e-6, 5e-6])
def test_tree_equals_direct(kernel_device, boundary, H, h0):
    p = Params(L=0.04, dx=10e-6, H=H, h0=h0)
    lines = _lines(p, 7, 3, kernel_device)
    direct = to_numpy(contact_force(lines, p, "direct", boundary, device=kernel_device))
    heights = to_numpy(lines)
    curvature = p.dx**2 / p.R
    narrowest_band = min(int(np.sqrt((p.d0 + row.max()) / curvature)) - int(np.sqrt((p.d0 + row.min()) / curvature))
                         for row in heights)
    for leaf_size in (1, 3, 8, 32):
        # band_limit 0: every band by the shared 8-step traversal; 10^6: every band summed
        # directly; the narrowest row's band: the wider rows traverse, that one sums
        for band_limit in (0, narrowest_band, 10**6):
            tree = to_numpy(contact_force(lines, p, "tree", boundary, device=kernel_device, leaf_size=leaf_size,
                                          band_limit=band_limit))
            assert np.max(np.abs(tree - direct)) <= 1e-12 * p.F_N, (leaf_size, band_limit)


def test_tree_equals_direct_with_gaps_and_shallow_indentation(kernel_device):
    # h0 = 5 um on a 51 um indentation, and d = 3 um < max h: the contact breaks into patches
    p = Params(L=0.04, dx=10e-6, h0=5e-6, H=0.3)
    lines = _lines(p, 3, 2, kernel_device)
    for d in (p.d0, 3e-6):
        direct = to_numpy(contact_force(lines, p, "direct", "periodic", d=d, device=kernel_device))
        for band_limit in (0, 10**6):
            tree = to_numpy(contact_force(lines, p, "tree", "periodic", d=d, device=kernel_device, leaf_size=4,
                                          band_limit=band_limit))
            assert np.max(np.abs(tree - direct)) <= 1e-12 * p.F_N


EXACT = [name for name, entry in REGISTRY.items() if entry.exact and name != "direct"]


@pytest.mark.parametrize("algorithm", EXACT)
@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_every_exact_algorithm_equals_direct(kernel_device, algorithm, boundary):
    """Every algorithm the registry calls exact gives the direct sum to rounding, on rough lines
    and with contact broken into patches (d = 3 um < max h)."""
    p = Params(L=0.04, dx=10e-6, h0=5e-6, H=0.3)
    lines = _lines(p, 3, 2, kernel_device)
    for d in (p.d0, 3e-6):
        direct = to_numpy(contact_force(lines, p, "direct", boundary, d=d, device=kernel_device))
        other = to_numpy(contact_force(lines, p, algorithm, boundary, d=d, device=kernel_device))
        assert np.max(np.abs(other - direct)) <= 1e-12 * p.F_N


@pytest.mark.parametrize("dx", [5e-6, 20e-6])
def test_smooth_line_gives_hertz_force(kernel_device, dx):
    # Bound (Euler-Maclaurin on the spring sum with the kink at |x| = a):
    # (F_sum - F_Hertz)/F_Hertz lies in [-1/4, 1/8] (dx/a)^2 (+ higher order); the test uses 0.26 (dx/a)^2.
    p = Params(L=0.03, dx=dx)
    flat = np.zeros((1, p.n_points))
    bound = 0.26 * (p.dx / p.a) ** 2
    for algorithm in ("direct", *EXACT):
        force = to_numpy(contact_force(flat, p, algorithm, "periodic", device=kernel_device))
        assert np.max(np.abs(force / p.F_N - 1)) <= bound
        assert np.ptp(force) == 0.0 or np.ptp(force) <= 1e-12 * p.F_N
    edge = to_numpy(contact_force(flat, p, "edge", "periodic", device=kernel_device))
    np.testing.assert_allclose(edge, p.F_N, rtol=1e-12)


def test_edge_formula_against_numpy(kernel_device):
    """Eq 49 evaluated independently: the linear interpolant integrated by np.interp on a fine grid."""
    p = SMALL.replace(h0=1e-6)
    lines = to_numpy(_lines(p, 4, 2, kernel_device))
    edge = to_numpy(contact_force(lines if kernel_device == "cpu" else _lines(p, 4, 2, kernel_device), p, "edge", "open", device=kernel_device))
    first, steps = step_range(p, "open", p.d0, lines.max())
    x = np.arange(p.n_points) * p.dx
    for r in range(2):
        for s in (0, steps // 3, steps - 1):
            xw = (first + s) * p.dx
            fine = np.linspace(xw - p.a, xw + p.a, 400_001)
            hf = np.interp(fine, x, lines[r])
            integral = np.sum((hf[1:] + hf[:-1]) * 0.5 * np.diff(fine))
            quad = p.E_star * p.R / (4 * p.a) * (np.interp(xw + p.a, x, lines[r]) ** 2 + np.interp(xw - p.a, x, lines[r]) ** 2)
            ref = p.F_N + p.E_star * integral + quad
            assert abs(edge[r, s] - ref) < 1e-9 * p.F_N


def test_edge_against_direct_mean_shift_and_low_band():
    """Eq 48-49 on the thesis defaults (dx = 5 um), periodic: the mean force shift is the mean of
    the quadratic edge term (within 1 %), and the low band q < q_min/2 of the PSDs agrees (5 %)."""
    p = Params(L=0.2)
    lines = _lines(p, 21, 6, "cpu")
    direct = contact_force(lines, p, "tree", "periodic")  # equal to the direct sum (test_tree_equals_direct)
    edge = contact_force(lines, p, "edge", "periodic")
    smooth = contact_force(np.zeros((1, p.n_points)), p, "direct", "periodic")[0, 0]
    x = np.arange(p.n_points) * p.dx
    shifts = []
    for r in range(lines.shape[0]):
        right = np.interp((x + p.a) % p.length, x, lines[r], period=p.length)
        left = np.interp((x - p.a) % p.length, x, lines[r], period=p.length)
        shifts.append(p.E_star * p.R / (4 * p.a) * np.mean(right**2 + left**2))
    assert np.mean(direct) - smooth == pytest.approx(np.mean(shifts), rel=0.01)
    q, C_direct = psd(direct, p.dx)
    _, C_edge = psd(edge, p.dx)
    low = (q > 0) & (q < p.q_min / 2)
    assert np.mean(C_edge[:, low]) / np.mean(C_direct[:, low]) == pytest.approx(1.0, abs=0.05)


def _is_5_smooth(m):
    for p in (2, 3, 5):
        while m % p == 0:
            m //= p
    return m == 1


def test_fast_length_is_the_largest_5_smooth_length():
    from mdroll.fft import fast_length

    smooth = [m for m in range(1, 5001) if _is_5_smooth(m)]
    for limit in range(1, 5001):
        assert fast_length(limit) == max(m for m in smooth if m <= limit)
    assert fast_length(1_046_492) == 1_036_800
    with pytest.raises(ValueError, match="limit"):
        fast_length(0)


def test_open_boundary_geometry():
    p = SMALL
    lines = to_numpy(_lines(p, 2, 1, "cpu"))
    first, steps = step_range(p, "open", p.d0, lines.max())
    window = np.sqrt(p.R * (p.d0 + lines.max())) / p.dx
    assert first == int(np.floor(window))  # the first spring whose whole window lies on the line
    last_allowed = p.n_points - 1 - first  # the last spring whose window lies on the line
    assert first + steps - 1 <= last_allowed
    assert steps == max(m for m in range(1, last_allowed - first + 2) if _is_5_smooth(m))
    assert abs(first * p.dx - p.a) < 0.1 * p.a  # near x_w = a
    assert step_range(p, "periodic", p.d0, lines.max()) == (0, p.n_points)


def test_periodic_series_is_periodic_and_shift_invariant():
    p = SMALL
    lines = to_numpy(_lines(p, 8, 1, "cpu"))
    force = contact_force(lines, p, "tree", "periodic")
    rolled = contact_force(np.roll(lines, 37, axis=1), p, "tree", "periodic")
    np.testing.assert_allclose(np.roll(force, 37, axis=1), rolled, rtol=1e-13)


def test_cpu_and_cuda_agree(kernel_cuda_devices):
    if not kernel_cuda_devices:
        pytest.skip("no CUDA device")
    p = SMALL.replace(h0=2e-6)
    lines = to_numpy(_lines(p, 1, 3, "cpu"))
    for algorithm in ("direct", "tree", "edge"):
        cpu = contact_force(lines, p, algorithm, "open")
        for dev in kernel_cuda_devices:
            gpu = to_numpy(contact_force(lines, p, algorithm, "open", device=dev))
            assert np.max(np.abs(gpu - cpu)) <= 1e-12 * p.F_N


def test_closed_form_sums_are_exact_integers(kernel_device):
    """sum m^2 and sum m over offset ranges up to MAX_CLOSED_FORM_OFFSET (the tree's full-contact
    closed forms, eq 19-20) against Python's exact integers, empty ranges included."""
    import warp as wp

    from mdroll.kernels.common import MAX_CLOSED_FORM_OFFSET, sum_of_offsets, sum_of_squares

    @wp.kernel
    def sums(p: wp.array(dtype=int), q: wp.array(dtype=int), out: wp.array2d(dtype=wp.float64)):
        i = wp.tid()
        out[i, 0] = sum_of_squares(p[i], q[i])
        out[i, 1] = sum_of_offsets(p[i], q[i])

    rng = np.random.default_rng(4)
    top = MAX_CLOSED_FORM_OFFSET
    p = np.concatenate([[-top, -top, 0, 5, -3], rng.integers(-top, top, 2000)])
    q = np.concatenate([[top, -top - 1, 0, 4, -3], rng.integers(-top, top, 2000)])
    p, q = np.minimum(p, q + 1), np.maximum(q, p - 1)  # p <= q + 1
    out = wp.zeros((p.size, 2), dtype=wp.float64, device=kernel_device)
    wp.launch(sums, dim=p.size, inputs=[wp.array(p, dtype=int, device=kernel_device), wp.array(q, dtype=int, device=kernel_device),
                                        out], device=kernel_device)
    result = out.numpy()
    for (a, b), (squares, offsets) in zip(zip(p.tolist(), q.tolist()), result):
        # Python integers: the closed forms, checked by brute force on short ranges
        exact_squares = _exact_squares(b) - _exact_squares(a - 1)
        exact_offsets = (b * (b + 1) - (a - 1) * a) // 2
        if b - a < 2000:
            assert exact_squares == sum(m * m for m in range(a, b + 1)) and exact_offsets == sum(range(a, b + 1))
        assert (squares, offsets) == (exact_squares, exact_offsets), (a, b)


def _exact_squares(t: int) -> int:
    """sum_{m=1}^{t} m^2 in Python integers (0 for t = 0; the polynomial continues to t < 0)."""
    return t * (t + 1) * (2 * t + 1) // 6


@pytest.mark.parametrize("algorithm", [name for name, entry in REGISTRY.items() if entry.max_window is not None])
def test_window_beyond_the_exact_closed_forms_is_refused(algorithm):
    """A contact window wider than MAX_CLOSED_FORM_OFFSET springs a side would make the float64
    sums of squares inexact: refused before any kernel runs, naming dx; edge has no such sum."""
    from mdroll.kernels.common import MAX_CLOSED_FORM_OFFSET

    a = Params().a
    p = Params(L=4.2 * a, dx=a / (1.02 * MAX_CLOSED_FORM_OFFSET))
    lines = np.zeros((1, p.n_points))
    with pytest.raises(ParameterError, match=rf"dx = .* too fine for the {algorithm} kernel"):
        contact_force(lines, p, algorithm)
    assert contact_force(lines, p, "edge").shape[0] == 1


@pytest.mark.parametrize("threads", [1, 7, 64, 512])
def test_row_bounds_against_numpy(kernel_device, threads):
    """The bounds pass with ``threads`` a row on every device (CUDA takes 512): strided partials
    with 8 loads in flight a thread (rows of 5003 springs, so that threads of 64 and fewer loop
    over their unrolled body and then a remainder), combined in groups of 32 where they divide
    evenly, then per row: numpy's min and max, bit for bit."""
    import warp as wp

    from mdroll.forces.prepared import row_bounds

    host = np.random.default_rng(3).normal(size=(3, 5003))
    bounds = row_bounds(wp.array(host, dtype=wp.float64, device=kernel_device), kernel_device, threads)
    np.testing.assert_array_equal(bounds.numpy(), np.stack([host.min(axis=1), host.max(axis=1)], axis=1))


@pytest.mark.parametrize("boundary", ["open", "periodic"])
@pytest.mark.parametrize("h_max", [None, 6 * SMALL.h0])
def test_prepared_bounds_and_prefix_sums_against_numpy(kernel_device, boundary, h_max):
    """Row bounds equal numpy's min and max, whether from their own pass (coalesced partials on
    CUDA; h_max not given) or from the tree's root (h_max given); the prefix sums, one scan over
    the batch read as overlapping rows, give numpy's row-wise cumulative sums as differences
    S_j - S_0 (eq 18)."""
    from mdroll.forces.prepare import prepare_lines

    p = SMALL
    lines = _lines(p, 4, 3, kernel_device)
    prepared = prepare_lines(lines, p, "tree", boundary, p.d0, kernel_device, h_max=h_max)
    host, work = to_numpy(lines), to_numpy(prepared.lines)
    np.testing.assert_array_equal(to_numpy(prepared.bounds), np.stack([host.min(axis=1), host.max(axis=1)], axis=1))
    prefix = to_numpy(prepared.prefix)
    assert prefix.shape == (work.shape[0], work.shape[1] + 1)
    expected = np.concatenate([np.zeros((work.shape[0], 1)), np.cumsum(work, axis=1)], axis=1)
    assert np.max(np.abs((prefix - prefix[:, :1]) - expected)) <= 1e-12 * p.h0 * np.sqrt(work.shape[1])


@pytest.mark.parametrize("algorithm", list(REGISTRY))
def test_force_offset_is_subtracted_in_the_kernel(kernel_device, algorithm):
    """``launch_force(offset=F_N)`` writes F - F_N (the pipeline's series) to within the one
    rounding of the subtraction (a fused multiply-add may round k u - F_N once instead of twice)."""
    from mdroll.forces.force import launch_force
    from mdroll.forces.prepare import prepare_lines

    p = SMALL
    prepared = prepare_lines(_lines(p, 8, 3, kernel_device), p, algorithm, "open", p.d0, kernel_device)
    plain = to_numpy(launch_force(prepared, p, algorithm, p.d0, kernel_device))
    shifted = to_numpy(launch_force(prepared, p, algorithm, p.d0, kernel_device, offset=p.F_N))
    assert np.ptp(plain) > 1.0  # a rough line: the deviations are not all alike
    assert np.max(np.abs(shifted - (plain - p.F_N))) <= 2.0**-52 * p.F_N


def test_host_edge_geometry_is_the_kernels_bit_for_bit(kernel_device):
    """Eq 49's constants at d: the host's (from mdroll.physics, for the decoupled launch) and the
    kernel's (per step of the coupled dynamics) are the same operations in the same order."""
    import warp as wp

    from mdroll.forces.edge import edge_geometry as host_geometry
    from mdroll.kernels.edge import edge_geometry

    @wp.kernel
    def geometry(d: wp.array(dtype=wp.float64), dx: wp.float64, R: wp.float64, E_star: wp.float64,
                 out: wp.array2d(dtype=wp.float64)):
        i = wp.tid()
        g = edge_geometry(d[i], dx, R, E_star)
        out[i, 0] = wp.float64(g.whole)
        out[i, 1] = g.fraction
        out[i, 2] = g.hertz
        out[i, 3] = g.tip
        out[i, 4] = g.dx_E_star

    p = Params()
    depths = p.d0 * np.array([0.37, 0.9, 1.0, 1.13, 2.5])
    out = wp.zeros((depths.size, 5), dtype=wp.float64, device=kernel_device)
    wp.launch(geometry, dim=depths.size, inputs=[wp.array(depths, dtype=wp.float64, device=kernel_device), p.dx, p.R,
                                                 p.E_star, out], device=kernel_device)
    for d, row in zip(depths, out.numpy()):
        g = host_geometry(p, d)
        assert row.tolist() == [g.whole, g.fraction, g.hertz, g.tip, g.dx_E_star]


def test_host_reach_is_the_kernels(kernel_device):
    """The window of possible contact, largest m with curvature m^2 <= level: the host's
    (placing the wheel, sizing the lift table) equals the kernels', exact squares included."""
    import warp as wp

    from mdroll.forces.indenter import reach
    from mdroll.kernels.common import reach_inclusive

    @wp.kernel
    def reaches(level: wp.array(dtype=wp.float64), curvature: wp.array(dtype=wp.float64), out: wp.array(dtype=int)):
        i = wp.tid()
        out[i] = reach_inclusive(level[i], curvature[i])

    rng = np.random.default_rng(2)
    curvature = 10.0 ** rng.uniform(-13, -9, 400)
    level = np.concatenate([rng.uniform(-1e-6, 2e-4, 200), curvature[200:] * rng.integers(0, 4000, 200) ** 2])
    out = wp.zeros(level.size, dtype=int, device=kernel_device)
    wp.launch(reaches, dim=level.size, inputs=[wp.array(level, dtype=wp.float64, device=kernel_device),
                                               wp.array(curvature, dtype=wp.float64, device=kernel_device), out],
              device=kernel_device)
    assert out.numpy().tolist() == [reach(a, b) for a, b in zip(level.tolist(), curvature.tolist())]


def test_coupled_kernels_and_kernel_structs_are_float64():
    """The force path is float64 throughout: the coupled kernels (made per algorithm in
    kernels/dynamics.py) and the structs the kernels read take no float32 or float16, scalar or
    in an array; the check catches a float32 field (a struct defined here, never launched)."""
    import inspect

    import warp as wp

    from mdroll.kernels import common, direct, edge, tree
    from mdroll.kernels import sweep_coupled as sweep

    def low_precision(kind) -> bool:
        scalar = getattr(kind, "dtype", kind)
        return getattr(scalar, "_wp_scalar_type_", scalar) in (wp.float32, wp.float16) or kind is float

    def bad_fields(struct) -> list[str]:
        return [name for name, var in struct.vars.items() if low_precision(var.type)]

    for kernel in (direct.coupled_direct, edge.coupled_edge, tree.coupled_tree, sweep.coupled_sweep):
        for name, parameter in inspect.signature(kernel.func).parameters.items():
            kind = parameter.annotation
            assert not (bad_fields(kind) if hasattr(kind, "vars") else low_precision(kind)), name
    for struct in (common.Contact, direct.DirectLines, edge.EdgeGeometry, tree.TreeLines, sweep.SweepLines):
        assert bad_fields(struct) == [], struct.key

    @wp.struct
    class Mixed:
        x: wp.float64
        y: wp.array(dtype=wp.float32)

    assert bad_fields(Mixed) == ["y"]
