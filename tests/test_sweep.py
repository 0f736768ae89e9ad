"""The sweep (physics.md section 4): exact in O(n) at fixed d, against the direct sum (eq 10-12)."""

import itertools

import numpy as np
import pytest
from reference import contact_reach, direct_force, sweep_force, to_numpy

from mdroll import Params, contact_force, rough_lines, step_range
from mdroll.devices import to_warp
from mdroll.devices import DeviceLimits
from mdroll.forces.prepare import prepare_lines
from mdroll.forces.sweep import FORMS, stream_layout, sweep_command

SMALL = Params(L=0.03, dx=20e-6)  # 1500 springs, a/dx = 253


def _sweep(lines, p, boundary, d, device, block_dim=None, h_max=None, form=None, chunk=None, per_lane=None,
           segment=None):
    lines = to_warp(np.asarray(lines) if isinstance(lines, np.ndarray) else lines, device)  # on the device
    prepared = prepare_lines(lines, p, "sweep", boundary, d, device, h_max=h_max)
    command, force = sweep_command(prepared, p, d, device, block_dim=block_dim, form=form, chunk=chunk,
                                   per_lane=per_lane, segment=segment)
    command.launch()
    return to_numpy(force)


@pytest.mark.parametrize("H,h0", [(0.3, 5e-6), (0.7, 0.5e-6), (0.9, 2e-6)])
def test_numpy_sweep_equals_numpy_direct_sum(H, h0):
    """The difference-array sweep (tests/reference.py) against the brute-force spring sum, both
    NumPy, periodic line (three copies side by side), d != d0."""
    p = SMALL.replace(H=H, h0=h0)
    line = to_numpy(rough_lines(p, seed=2, realizations=1, device="cpu"))[0]
    tiled = np.tile(line, 3)
    wheel = p.n_points + np.arange(p.n_points)
    for d in (p.d0, 0.6 * p.d0):
        direct = direct_force(tiled, p, wheel * p.dx, d)
        assert np.max(np.abs(sweep_force(tiled, p, wheel, d) - direct)) <= 1e-14 * p.F_N


def test_reach_is_the_direct_sums_contact_decision(device):
    """The kernels' reach M (float32 guess, float64 tests; the stream's guess from the
    curvature's reciprocal and a rough square root) equals NumPy's largest m with
    ``h + d - kappa m^2 > 0``, at random levels and at levels on and next to ``kappa m^2``, where
    the last integer is decided by rounding."""
    import warp as wp

    from mdroll.kernels.common import reach_strict
    from mdroll.kernels.sweep_stream import reach_guessed

    @wp.kernel
    def reaches(level: wp.array(dtype=wp.float64), curvature: wp.float64, out: wp.array(dtype=int)):
        i = wp.tid()
        out[i] = reach_strict(level[i], curvature)
        guessed = reach_guessed(level[i], curvature, wp.float32(wp.float64(1.0) / curvature))
        if guessed != out[i]:
            out[i] = -2  # a disagreement shows as -2

    p = Params(dx=5e-6)
    kappa = p.dx**2 / p.R
    rng = np.random.default_rng(5)
    m = rng.integers(0, 100_000, 3000)
    edges = kappa * m * m
    levels = np.concatenate([rng.uniform(-1e-5, kappa * 1e10, 3000), edges, np.nextafter(edges, np.inf),
                             np.nextafter(edges, -np.inf), [0.0, -0.0, 5e-324]])
    out = wp.empty(levels.size, dtype=int, device=device)
    wp.launch(reaches, dim=levels.size, inputs=[wp.array(levels, dtype=wp.float64, device=device), kappa, out],
              device=device)
    np.testing.assert_array_equal(out.numpy(), contact_reach(levels, p, 0.0))


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("boundary", ["open", "periodic"])
@pytest.mark.parametrize("H", [0.3, 0.7, 0.9])
@pytest.mark.parametrize("h0", [0.5e-6, 5e-6])
def test_sweep_equals_direct(device, boundary, H, h0, form):
    """Both forms (stream, sequential) on every device, two indentations."""
    p = Params(L=0.04, dx=10e-6, H=H, h0=h0)
    lines = rough_lines(p, seed=7, realizations=3, device=device)
    for d in (p.d0, 0.8 * p.d0):
        direct = to_numpy(contact_force(lines, p, "direct", boundary, d=d, device=device))
        assert np.max(np.abs(_sweep(lines, p, boundary, d, device, form=form) - direct)) <= 1e-12 * p.F_N


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_sweep_with_gaps_shallow_indentation_and_odd_lines(device, boundary, form):
    """h0 = 5 um and d = 3 um < max h: the contact breaks into patches and the wheel loses it;
    an odd number of springs; against the independent NumPy references."""
    p = Params(L=0.03002, dx=20e-6, h0=5e-6, H=0.3)  # 1501 springs
    assert p.n_points % 2 == 1
    lines = to_numpy(rough_lines(p, seed=3, realizations=2, device="cpu"))
    # the second pair of lines lowered until only their highest peaks reach the wheel at d = 3 um
    lines = np.concatenate([lines, lines - lines.max(axis=1, keepdims=True) - 1e-6])
    for d in (p.d0, 3e-6):
        force = _sweep(lines, p, boundary, d, device, form=form)
        first, steps = step_range(p, boundary, d, lines.max())
        for r in range(4):
            if boundary == "open":
                ref = direct_force(lines[r], p, (first + np.arange(steps)) * p.dx, d)
            else:
                ref = direct_force(np.tile(lines[r], 3), p, (p.n_points + np.arange(steps)) * p.dx, d)
            assert np.max(np.abs(force[r] - ref)) <= 1e-12 * p.F_N
    assert np.min(force[2:]) == 0.0 < np.max(force[2:])  # the wheel lost contact, and found it again


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_tiny_line(device, boundary, form):
    """The shortest line Params allows (L = 4a) on a coarse grid: 207 springs, 101 of them in
    contact, 100 open steps."""
    p = Params(L=0.0207, dx=100e-6, h0=1e-6, H=0.9)
    lines = rough_lines(p, seed=9, realizations=2, device=device)
    direct = to_numpy(contact_force(lines, p, "direct", boundary, device=device))
    assert np.max(np.abs(_sweep(lines, p, boundary, p.d0, device, form=form) - direct)) <= 1e-12 * p.F_N


def test_same_force_whatever_the_form_the_block_the_chunk_or_the_batch(device):
    """Sequential chunks of 1 to 4096 steps (launched twice: each thread clears its ring), the
    stream's layouts, three lines at once or one by one: the same force to 1e-12 F_N, equal to
    the direct sum's."""
    p = SMALL.replace(h0=2e-6)
    lines = to_numpy(rough_lines(p, seed=4, realizations=3, device="cpu"))
    d = 0.9 * p.d0
    reference = _sweep(lines, p, "open", d, device, form="sequential")
    direct = to_numpy(contact_force(lines, p, "direct", "open", d=d, device=device))
    assert np.max(np.abs(reference - direct)) <= 1e-12 * p.F_N
    for chunk in (1, 7, 64, 4096):
        lines_here = to_warp(lines, device)
        prepared = prepare_lines(lines_here, p, "sweep", "open", d, device)
        command, force = sweep_command(prepared, p, d, device, form="sequential", chunk=chunk)
        for _ in range(2):
            command.launch()
            assert np.max(np.abs(to_numpy(force) - reference)) <= 1e-12 * p.F_N, chunk
    # the stream: segments of 2 chunks to the whole line, chunks of 1 to 16 steps (64 to 256 lanes
    # on CUDA, 1 to 16 steps a lane, rings that wrap mid-chunk), with and without the delay line;
    # launched twice
    streams = ([(1, 1, 2), (1, 3, 48), (1, 16, 4096)] if device == "cpu"
               else [(32, 1, 64), (64, 3, 384), (128, 8, 2048), (256, 4, None), (256, 2, 1024)])
    for (lanes, per_lane, segment), delay in itertools.product(streams, (True, False)):
        prepared = prepare_lines(to_warp(lines, device), p, "sweep", "open", d, device)
        command, force = sweep_command(prepared, p, d, device, form="stream", block_dim=lanes, per_lane=per_lane,
                                       segment=segment, delay=delay)
        for _ in range(2):
            command.launch()
            assert np.max(np.abs(to_numpy(force) - reference)) <= 1e-12 * p.F_N, (lanes, per_lane, segment, delay)
    # one by one, with the batch's wheel positions (h_max): each line's own bounds and scale
    alone = np.concatenate([_sweep(lines[r:r + 1], p, "open", d, device, h_max=lines.max()) for r in range(3)])
    assert np.max(np.abs(alone - reference)) <= 1e-12 * p.F_N


def test_prefix_sums_only_for_the_forms_that_read_them(device):
    """The sweep's prepared lines carry no prefix sums (the stream sums its anchors' cores spring
    by spring, so the CUDA build is the bounds pass alone); the sequential form and the coupled
    step build them on first use, equal to NumPy's cumulative sums, and every form
    gives the same force."""
    from mdroll.forces.sweep import sweep_coupled

    p = SMALL.replace(h0=2e-6)
    lines = to_numpy(rough_lines(p, seed=7, realizations=2, device="cpu"))
    prepared = prepare_lines(to_warp(lines, device), p, "sweep", "open", p.d0, device)
    assert prepared.prefix is None
    stream_command, stream = sweep_command(prepared, p, p.d0, device, form="stream")
    stream_command.launch()
    assert prepared.prefix is None
    command, force = sweep_command(prepared, p, p.d0, device, form="sequential")
    command.launch()
    prefix = to_numpy(prepared.prefix)
    np.testing.assert_allclose(prefix - prefix[:, :1], np.concatenate([np.zeros((2, 1)), np.cumsum(lines, axis=1)], axis=1),
                               rtol=0, atol=1e-18)
    assert np.max(np.abs(to_numpy(stream) - to_numpy(force))) <= 1e-12 * p.F_N
    again = prepare_lines(to_warp(lines, device), p, "sweep", "open", p.d0, device)
    sweep_coupled(again)
    assert again.prefix is not None


#: The limits of the GPUs the stream's layouts were tuned on (132 multiprocessors, 228 KiB of
#: shared memory each, 227 KiB a block), and of a GPU with less shared memory and fewer lanes.
TUNED = DeviceLimits(multiprocessors=132, shared_per_multiprocessor=228 * 1024, shared_per_block=227 * 1024,
                     registers_per_multiprocessor=65536, lanes_per_multiprocessor=2048)
SMALLER = DeviceLimits(multiprocessors=46, shared_per_multiprocessor=100 * 1024, shared_per_block=99 * 1024,
                       registers_per_multiprocessor=65536, lanes_per_multiprocessor=1536)


def test_stream_layout_keeps_the_multiprocessor_busy_as_the_band_grows():
    """On CUDA the first layout of STREAM_LAYOUTS, with the delay line where its ring (chunk +
    2 outer bins) allows, else without (chunk + band bins), that keeps 16 warps resident
    (shared memory, registers): 128 lanes x 8 steps with the delay line at the thesis's reach
    (~1030 springs), without it beyond ~2400 springs and up to bands of ~2000, then 256 lanes;
    None beyond a block's shared memory. Each segment spans at least 16 spans of events and two
    chunks; STREAM_WAVES waves of blocks where the lines allow. A layout asked for is kept."""
    import mdroll.forces.sweep as sweep

    thesis = stream_layout(42, 1034, 300, 2**20, TUNED)
    assert (thesis["block_dim"], thesis["per_lane"], thesis["ring"], thesis["delay"], thesis["resident"]) == (
        128, 8, 3328, True, 4)  # 1024 + 2069 bins, 53.6 KiB: 4 blocks, as the 128 registers a lane allow
    waves = sweep.STREAM_WAVES
    assert thesis["segment"] == -(-300 * 2**20 // (waves * 132 * 4) // 1024) * 1024
    undelayed = stream_layout(42, 1034, 300, 2**20, TUNED, delay=False)
    assert (undelayed["ring"], undelayed["delay"], undelayed["resident"]) == (1280, False, 4)
    wide = stream_layout(110, 2700, 256, 2**17, TUNED)  # 1024 + 5401 bins would leave 2 blocks
    assert (wide["block_dim"], wide["ring"], wide["delay"], wide["resident"]) == (128, 1280, False, 4)
    fine = stream_layout(2050, 50000, 256, 2**21, TUNED)
    assert (fine["block_dim"], fine["per_lane"], fine["ring"], fine["delay"], fine["resident"]) == (128, 8, 3328, False, 4)
    finer = stream_layout(4100, 100000, 256, 2**22, TUNED)
    assert (finer["block_dim"], finer["per_lane"], finer["ring"], finer["resident"]) == (256, 8, 6400, 2)
    assert finer["segment"] == -(-max(256 * 2**22 // (waves * 132 * 2), 16 * 4100) // 2048) * 2048
    assert stream_layout(13000, 200000, 64, 2**22, TUNED) is None  # 15 Ki bins: more than 227 KiB
    own = stream_layout(42, 1034, 300, 2**20, TUNED, block_dim=64, per_lane=8, delay=True)
    assert (own["block_dim"], own["per_lane"], own["ring"], own["delay"]) == (64, 8, 2816, True)
    cpu = stream_layout(42, 1034, 3, 1000, None)
    assert (cpu["block_dim"], cpu["ring"], cpu["delay"]) == (1, 2112, True)


def test_device_limits_are_queried_from_the_device(device):
    """The CPU has no multiprocessor limits (None: its own layout); a CUDA device reports its
    own, consistent with Warp's, and the thesis's band has a stream layout within them."""
    import warp as wp

    from mdroll.devices import device_limits

    limits = device_limits(device)
    if device == "cpu":
        assert limits is None
        return
    assert limits.multiprocessors == wp.get_device(device).sm_count > 0
    assert 0 < limits.shared_per_block <= limits.shared_per_multiprocessor
    assert limits.registers_per_multiprocessor > 0 and limits.lanes_per_multiprocessor >= 1024
    assert device_limits(device) is limits  # queried once
    assert stream_layout(42, 1034, 300, 2**20, limits) is not None


@pytest.mark.parametrize("band,outer", [(42, 1034), (110, 2700), (2050, 50000), (4100, 100000)])
def test_stream_layout_fits_the_limits_of_another_gpu(band, outer):
    """On a GPU with less shared memory and fewer lanes a multiprocessor, each layout's ring fits
    a block's shared memory and at least one block fits a multiprocessor (shared memory,
    registers, lanes), and its segments fill the device's block slots."""
    from mdroll.kernels.sweep_stream import BIN_BYTES

    layout = stream_layout(band, outer, 256, 2**20, SMALLER)
    assert layout is not None
    shared = layout["ring"] * BIN_BYTES + 1024
    lanes, registers, resident = layout["block_dim"], layout["max_registers"], layout["resident"]
    assert shared <= SMALLER.shared_per_block
    assert 1 <= resident <= SMALLER.shared_per_multiprocessor // shared
    assert resident * lanes * registers <= SMALLER.registers_per_multiprocessor
    assert resident * lanes <= SMALLER.lanes_per_multiprocessor
    assert layout["ring"] >= lanes * layout["per_lane"] + (2 * outer if layout["delay"] else band) + 1
    assert layout["segment"] % (lanes * layout["per_lane"]) == 0


def test_sweep_runs_decoupled_and_coupled_ensembles_as_the_tree():
    """run_ensemble with the sweep gives the tree's spectra in both modes (all exact: equal to
    rounding); the coupled mode runs the sweep's own step (core in closed form, bands summed)."""
    from mdroll import run_ensemble

    for mode in ("decoupled", "coupled"):
        p = Params(L=0.03)
        sweep = run_ensemble(p, realizations=3, seed=2, algorithm="sweep", mode=mode, device="cpu", progress=False)
        tree = run_ensemble(p, realizations=3, seed=2, algorithm="tree", mode=mode, device="cpu", progress=False)
        assert sweep.mode == mode
        np.testing.assert_allclose(sweep.force_psd, tree.force_psd, rtol=1e-9, atol=1e-12 * tree.force_psd.max())
        np.testing.assert_allclose(sweep.accel_psd, tree.accel_psd, rtol=1e-9, atol=1e-12 * tree.accel_psd.max())


def test_coupled_step_equals_the_direct_sum_where_the_wheel_leaves_the_rail(device):
    """The sweep's coupled step (core in closed form, bands summed) with 50 um roughness at
    30 m/s, where the wheel loses contact (F = 0) in places and d swings far from d0: the same
    force series as the direct sum's and the tree's coupled steps, to 1e-12 F_N."""
    from mdroll.ensemble.coupled import coupled_series

    rough = Params(L=0.05, h0=50e-6, q_min=2 * np.pi / 0.05, v0=30.0)
    lines = rough_lines(rough, seed=3, realizations=2, device=device)
    series = {}
    for algorithm in ("direct", "tree", "sweep"):
        prepared = prepare_lines(lines, rough, algorithm, "open", rough.d0, device)
        series[algorithm] = to_numpy(coupled_series(prepared, rough, algorithm, device)[0])
    assert (series["direct"] == 0).sum() > 50  # steps without contact
    for algorithm in ("tree", "sweep"):
        assert np.max(np.abs(series[algorithm] - series["direct"])) <= 1e-12 * rough.F_N, algorithm


def test_band_beyond_the_streams_int32_sums_runs_sequentially(device):
    """A band of uncertain contact wider than the stream's ring allows (a spring below the
    wheel's reach at every position makes the whole window uncertain) runs in the sequential
    form, equal to the tree; the stream asked for there, a form that does not exist, a stream
    asked to write into a strided ``out``, or the delay line asked for where its ring cannot
    hold a spring's reach, are refused with one clear line, before the kernel runs."""
    from mdroll.errors import ParameterError

    a = Params().a
    p = Params(L=4.2 * a, dx=a / (1.2 * 16383))  # a band of ~19,700 springs a side
    lines = np.zeros((1, p.n_points))
    lines[0, 0] = -2 * p.d0
    tree = to_numpy(contact_force(lines, p, "tree", device=device))
    assert np.max(np.abs(to_numpy(contact_force(lines, p, "sweep", device=device)) - tree)) <= 1e-12 * p.F_N
    with pytest.raises(ParameterError, match="the stream form's ring allows: use form='sequential'"):
        _sweep(lines, p, "open", p.d0, device, form="stream")
    # a smooth line (band 0) whose reach, ~8000 springs, is too long for the delay line's ring
    long_reach = Params(L=4.2 * a, dx=a / 8000)
    smooth = prepare_lines(to_warp(np.zeros((1, long_reach.n_points)), device), long_reach, "sweep", "open",
                           long_reach.d0, device)
    with pytest.raises(ParameterError, match=r"^delay=True: the sweep's reach of \d+ springs a side needs a ring of "
                                             r"2 x \d+ bins, more than the stream form's shared memory allows: use "
                                             r"delay=False or None$"):
        sweep_command(smooth, long_reach, long_reach.d0, device, form="stream", delay=True)
    sweep_command(smooth, long_reach, long_reach.d0, device, form="stream", delay=False)  # fits without it
    prepared = prepare_lines(to_warp(np.zeros((1, SMALL.n_points)), device), SMALL, "sweep", "periodic", SMALL.d0,
                             device)
    strided = to_warp(np.zeros((1, 2 * prepared.steps)), device)[:, ::2]
    with pytest.raises(ParameterError, match="^out: the sweep's stream form needs rows of contiguous float64 values, "
                                             "not 16 bytes apart$"):
        sweep_command(prepared, SMALL, SMALL.d0, device, out=strided, form="stream")
    with pytest.raises(ParameterError, match="form = 'rows': the sweep's forms are 'stream', 'sequential'"):
        _sweep(lines, p, "open", p.d0, device, form="rows")
