"""Host side of the sweep force (:mod:`mdroll.kernels.sweep`): its form, layout, band check, launch.

The sweep is exact and O(n) at a fixed indentation d (physics.md section 4). It reads the lines
and the row bounds ``(min h, max h)`` of a :class:`PreparedLines`, and, in its CPU and tiles
forms and its coupled step, their prefix sums (eq 18), built on first use.
On CUDA it runs as a stream: a block sweeps a long segment of a row chunk by chunk, its lanes
scattering and scanning the events together and carrying the totals and the pending events
from chunk to chunk (:mod:`mdroll.kernels.sweep_stream`); on the CPU, where Warp runs one lane a
thread, as a sequential sweep of each chunk of steps. The earlier CUDA form, independent tiles
of steps each with its own anchor, stays selectable (:data:`FORMS`; the kernels' docstrings
have the measurements that chose the defaults).
"""

from __future__ import annotations

import math

from .. import physics
from ..devices import is_cuda, warp
from ..params import ParameterError, Params

#: CUDA: lanes a block, the smallest tile (steps a block) and the springs a lane loads at once
#: (kernels/sweep.py). A lane scans ``tile / lanes`` consecutive bins; a tile takes 44 bytes of
#: shared memory a step (its bins and forces), ~36 KiB at 512 steps: 6 blocks of 128 lanes a
#: streaming multiprocessor. A tile of 4096 steps (184 KiB) leaves one block a multiprocessor,
#: so there the block takes ``tile / CUDA_BINS_PER_LANE`` lanes: 256, which took 3.50 ms
#: against 128's 5.66 ms at 64 x 2^20 springs, L = 0.25 m, on an H200; 2048 steps keep 128
#: lanes (1.57 ms against 256's 1.97 at 64 x 2^19) (docs/performance.md).
CUDA_BLOCK_DIM = 128
CUDA_BINS_PER_LANE = 16
CUDA_MIN_TILE = 512
CUDA_LOADS = 2
#: CPU: Warp runs a block as one lane; a longer tile reads the anchors' bands less often.
CPU_MIN_TILE = 4096
#: The sequential form: steps a thread, at least SEQUENTIAL_CHUNK_PER_BAND times the band (a
#: chunk reads the anchor's 2 band springs once, and its ring holds at least band + 1 slots).
SEQUENTIAL_CHUNK = 1 << 15
SEQUENTIAL_CHUNK_PER_BAND = 16
#: The ring's fewest slots. It needs band + 1, but a narrow ring revisits a slot every few steps,
#: and each step's read of its slot then waits on the read-modify-writes just recorded there: at
#: band 6 (2^13 springs on 0.25 m) one CPU core took 28.3 ns a step with 7 slots and 25.0 with 64,
#: as at the wide bands of finer lines (24-25 ns).
RING_MIN_SLOTS = 64
#: The sweep's forms and the one each kind of device runs by default.
FORMS = ("stream", "tiles", "sequential")
DEFAULT_FORM = {"cuda": "stream", "cpu": "sequential"}
#: A tile spans at least this many times the widest band (springs whose contact at the tile's
#: start is uncertain, one side): the band is read 2 + 2 x T / band times a tile, so the work a
#: step stays O(1) as the band grows under refinement.
TILE_PER_BAND = 4
#: The largest tile: its bins and forces take 44 x (4096 + lanes) bytes, 180-190 KiB, within the
#: 256 KiB CPU arena of Warp 1.19 and the 227 KiB of shared memory of an H100/H200 block.
MAX_TILE = {"cpu": 4096, "cuda": 4096}


def reach_strict(level: float, curvature: float) -> int:
    """Largest m >= 0 with ``curvature m^2 < level`` (-1 if level <= 0): the host twin of
    :func:`mdroll.kernels.common.reach_strict`, the reach M of a spring with ``h + d = level``."""
    if level <= 0:
        return -1
    m = int(math.floor(math.sqrt(level / curvature)))
    while m >= 0 and curvature * m * m >= level:
        m -= 1
    while curvature * (m + 1) * (m + 1) < level:
        m += 1
    return m


def sweep_tile(band: int, device: str, tile_steps: int | None = None, block_dim: int | None = None) -> tuple[int, int]:
    """``(tile_steps, block_dim)`` for a widest band of ``band`` springs: by default the smallest
    power of two >= max(minimum tile, TILE_PER_BAND x band), capped at MAX_TILE, and on CUDA
    ``max(CUDA_BLOCK_DIM, tile_steps / CUDA_BINS_PER_LANE)`` lanes (1 on the CPU)."""
    cuda = is_cuda(device)
    if tile_steps is None:
        wanted = max(CUDA_MIN_TILE if cuda else CPU_MIN_TILE, TILE_PER_BAND * band, block_dim or 1)
        tile_steps = min(1 << (wanted - 1).bit_length(), MAX_TILE["cuda" if cuda else "cpu"])
    if block_dim is None:
        block_dim = max(CUDA_BLOCK_DIM, tile_steps // CUDA_BINS_PER_LANE) if cuda else 1
    return tile_steps, block_dim


#: The stream form (kernels/sweep_stream.py) on CUDA: its layouts ``(lanes a block, steps a lane
#: a chunk, registers a lane)``, in order of preference, each first with the delay line; the
#: launch takes the first that keeps STREAM_MIN_WARPS warps resident on a multiprocessor (its ring
#: of ``lanes x steps + 2 outer`` bins, or ``+ band`` without the delay line, in shared memory,
#: its registers), else the one that keeps the most: a long reach drops the delay line, a wide
#: band (a fine line) trades steps a lane for lanes. 128 registers, where the kernel loads a
#: chunk ahead without spilling: 2.84 ms at thesis scale against 3.09 at 96; 256 lanes x 8 steps
#: at 2^22 springs on 0.25 m (two blocks a multiprocessor either way) 0.0140 ns a step against
#: 0.0165 at 96 (benchmarks/results/sweep_stream_H200.json, docs/performance.md s9).
STREAM_LAYOUTS = ((128, 8, 128), (256, 8, 128), (256, 4, 128))
STREAM_MIN_WARPS = 16
#: What an H100/H200 multiprocessor holds: shared memory (bytes; a block at most 227 KiB),
#: registers, lanes.
SM_SHARED = 228 * 1024
BLOCK_SHARED = 227 * 1024
SM_REGISTERS = 65536
SM_LANES = 2048
#: The CPU runs a block as one lane, ``STREAM_CPU_PER_LANE`` steps a chunk.
STREAM_CPU_PER_LANE = 16
#: Blocks a launch aims at: this many per resident block slot of the device, so that the last
#: wave's tail is short; a segment is never shorter than STREAM_SEGMENT_PER_BAND times the span
#: of its events (:func:`_span`: its anchor puts the events of up to that many springs in the
#: ring) nor than two chunks. Shorter segments (4, 2 or 1 span) made the short lines of the
#: distance study slower on an H200, not faster.
STREAM_WAVES = 4
STREAM_SEGMENT_PER_BAND = 16


def _ring(chunk: int, span: int, unit: int) -> tuple[int, int]:
    """The stream's ring for chunks of ``chunk`` steps and events up to ``span`` steps past a
    chunk's last (``chunk + span + 1`` bins, rounded up to ``unit``) and the shared memory its
    block takes (bytes: the bins and ~1 KiB of the warps' and the anchor's totals)."""
    from ..kernels.sweep_stream import BIN_BYTES

    ring = -(-(chunk + span + 1) // unit) * unit
    return ring, ring * BIN_BYTES + 1024


def _span(band: int, outer: int, delay: bool) -> int:
    """The steps past a chunk's last that its events reach: a spring's contact, 2 outer, with the
    delay line, else the band."""
    return max(2 * outer if delay else band, 0)


def _resident(shared: float, lanes: int, registers: int) -> int:
    """Blocks of ``lanes`` lanes at ``registers`` registers a lane and ``shared`` bytes of shared
    memory that a multiprocessor holds at once."""
    return int(min(SM_SHARED // shared, SM_REGISTERS // (lanes * registers), SM_LANES // lanes))


def stream_layout(band: int, outer: int, rows: int, steps: int, device: str, block_dim: int | None = None,
                  per_lane: int | None = None, segment: int | None = None, delay: bool | None = None) -> dict | None:
    """The stream form's launch for a widest band of ``band`` springs, a widest reach of
    ``outer`` springs and ``rows x steps`` steps: ``{"block_dim", "per_lane", "max_registers",
    "ring", "delay", "resident", "segment"}`` (``resident``: its blocks a multiprocessor holds),
    or None where no ring fits a block's shared memory (or the band passes MAX_STREAM_BAND). The delay line (a spring's leaving event put in the ring when
    it enters: one read and one reach a spring instead of two) needs a ring spanning the
    2 outer + 1 steps of a spring's contact, the other only its band's: each layout takes it
    where it still keeps STREAM_MIN_WARPS warps resident. ``block_dim``, ``per_lane`` and
    ``delay`` pick a layout, ``segment`` the steps a block."""
    from ..kernels.sweep_stream import MAX_STREAM_BAND, RING_UNIT

    if band > MAX_STREAM_BAND:
        return None
    wp = warp()
    delays = (True, False) if delay is None else (delay,)
    if not is_cuda(device):
        chunk = per_lane or STREAM_CPU_PER_LANE
        layout = None
        for delayed in delays:
            ring, shared = _ring(chunk, _span(band, outer, delayed), 32)
            if shared <= BLOCK_SHARED:
                layout = {"block_dim": 1, "per_lane": chunk, "max_registers": None, "ring": ring, "delay": delayed,
                          "resident": 1}
                break
        if layout is None:
            return None
        slots = 1
    else:
        best = None
        candidates = [(lanes, steps_a_lane, registers, delayed) for lanes, steps_a_lane, registers in STREAM_LAYOUTS
                      for delayed in delays
                      if not (block_dim and lanes != block_dim) and not (per_lane and steps_a_lane != per_lane)]
        if not candidates and block_dim and per_lane:  # a layout of the caller's own
            candidates = [(block_dim, per_lane, None, delayed) for delayed in delays]
        for lanes, steps_a_lane, registers, delayed in candidates:
            ring, shared = _ring(lanes * steps_a_lane, _span(band, outer, delayed), RING_UNIT)
            if shared > BLOCK_SHARED:
                continue
            resident = _resident(shared, lanes, registers) if registers else 1
            candidate = {"block_dim": lanes, "per_lane": steps_a_lane, "max_registers": registers, "ring": ring,
                         "delay": delayed, "resident": resident}
            if best is None or resident * lanes > best["resident"] * best["block_dim"]:
                best = candidate
            if resident * lanes >= 32 * STREAM_MIN_WARPS:  # (then it is best: the first to get there)
                break
        if best is None:
            return None
        layout = best
        slots = wp.get_device(device).sm_count * layout["resident"]
    chunk = layout["block_dim"] * layout["per_lane"]
    if segment is None:
        segment = max(-(-rows * steps // (STREAM_WAVES * slots)),
                      STREAM_SEGMENT_PER_BAND * _span(band, outer, layout["delay"]), 2 * chunk)
    layout["segment"] = -(-segment // chunk) * chunk
    return layout


def sweep_command(prepared, params: Params, d: float, device: str, out=None, offset: float = 0.0,
                  tile_steps: int | None = None, block_dim: int | None = None, loads: int | None = None,
                  form: str | None = None, chunk: int | None = None, per_lane: int | None = None,
                  segment: int | None = None, delay: bool | None = None):
    """The sweep's force launch, recorded (``wp.Launch``; run with ``.launch()``), and the
    (R, steps) array it writes: ``F - offset`` (N) at indentation d (m) for every step.

    ``prepared`` needs ``lines``, ``bounds``, ``h_low`` and ``h_top`` (see
    :func:`mdroll.ensemble.prepare.prepare_lines`); the forms that read prefix sums build them
    into it on first use. ``form`` (:data:`FORMS`) picks the kernel,
    by default :data:`DEFAULT_FORM` of the device's kind; for the stream ``block_dim``,
    ``per_lane``, ``segment`` and ``delay`` override the layout of :func:`stream_layout`; for the tiles
    ``tile_steps`` and ``block_dim`` override the defaults of :func:`sweep_tile` and ``loads``
    CUDA_LOADS (1 on the CPU); for the sequential form ``chunk`` overrides the default of
    max(SEQUENTIAL_CHUNK, SEQUENTIAL_CHUNK_PER_BAND x band). The force is the same to rounding
    whatever they are. A batch whose band of uncertain contact is too wide for the stream's ring
    in shared memory runs in the sequential form (exact at any band); the stream, or the tiles
    beyond :data:`mdroll.kernels.sweep.MAX_BAND`, asked for then are refused (ParameterError).
    """
    from ..kernels.sweep import MAX_BAND, contact_force_sequential, sweep_kernel

    wp = warp()
    p = prepared
    rows = p.lines.shape[0]
    curvature = physics.indenter_profile(params.dx, params.R)  # eq 7 at one spacing
    # the widest band of the batch (each row's own is narrower): from its lowest and highest spring
    outer = reach_strict(d + p.h_top, curvature)
    band = outer - max(reach_strict(d + p.h_low, curvature), 0)
    if form is None:
        form = DEFAULT_FORM["cuda" if is_cuda(device) else "cpu"]
        if form == "stream" and stream_layout(band, outer, rows, p.steps, device) is None:
            form = "sequential"
    if form not in FORMS:
        raise ParameterError(f"form = {form!r}: the sweep's forms are {', '.join(map(repr, FORMS))}")
    if form == "tiles" and band > MAX_BAND:
        raise ParameterError(
            f"the sweep's band of uncertain contact spans {band} springs a side at dx = {params.dx!r} m, d = {d:.4g} m "
            f"and heights {p.h_low:.4g} .. {p.h_top:.4g} m, beyond the {MAX_BAND} the tiles' exact int32 sums allow: "
            f"use form='sequential'"
        )
    force = out if out is not None else wp.empty((rows, p.steps), dtype=wp.float64, device=device)
    if form == "stream":
        from ..kernels.sweep_stream import stream_kernel

        layout = stream_layout(band, outer, rows, p.steps, device, block_dim, per_lane, segment, delay)
        if layout is None:
            if delay and stream_layout(band, outer, rows, p.steps, device, block_dim, per_lane, segment, False):
                raise ParameterError(f"delay=True: the sweep's reach of {outer} springs a side needs a ring of "
                                     f"2 x {outer} bins, more than the stream form's shared memory allows: use "
                                     f"delay=False or None")
            raise ParameterError(f"the sweep's band of uncertain contact spans {band} springs a side, wider than the "
                                 f"stream form's ring allows: use form='sequential'")
        for name, array in (("lines", p.lines), ("out", force)):  # the kernel walks rows by address
            if array.strides[1] != 8:
                raise ParameterError(f"{name}: the sweep's stream form needs rows of contiguous float64 values, "
                                     f"not {array.strides[1]} bytes apart")
        kernel = stream_kernel(layout["block_dim"], layout["per_lane"], layout["ring"], layout["max_registers"],
                               layout["delay"])
        inputs = [p.lines, p.bounds, p.n_work, p.first, p.steps, layout["segment"], d, curvature,
                  params.k_spring, offset, force]
        command = wp.launch_tiled(kernel, dim=(rows, -(-p.steps // layout["segment"])), inputs=inputs,
                                  block_dim=layout["block_dim"], device=device, record_cmd=True)
        return command, force
    from .prepare import ensure_prefix_sums  # (prepare imports the registry, which imports this)

    ensure_prefix_sums(p, device)  # the anchors' cores in closed form (eq 18-20)
    if form == "sequential":
        chunk = chunk or max(SEQUENTIAL_CHUNK, 1 << (SEQUENTIAL_CHUNK_PER_BAND * band - 1).bit_length())
        chunks = -(-p.steps // chunk)
        # a thread's ring: one slot a step for the band's steps ahead, and the current step's
        slots = max(band + 1, RING_MIN_SLOTS)
        ring_packed = wp.empty((rows, chunks, slots), dtype=wp.int64, device=device)
        ring_value = wp.empty((rows, chunks, slots), dtype=wp.float64, device=device)
        inputs = [p.lines, p.prefix, p.bounds, p.n_work, p.first, p.steps, chunk, d, curvature, params.k_spring,
                  offset, ring_packed, ring_value, force]
        command = wp.launch(contact_force_sequential, dim=(rows, chunks), inputs=inputs, device=device,
                            record_cmd=True)
        return command, force
    tile, lanes = sweep_tile(band, device, tile_steps, block_dim)
    inputs = [p.lines, p.prefix, p.bounds, p.n_work, p.first, p.steps, d, curvature, params.k_spring, offset, force]
    if loads is None:
        loads = CUDA_LOADS if is_cuda(device) else 1
    command = wp.launch_tiled(sweep_kernel(tile, lanes, loads), dim=(rows, -(-p.steps // tile)), inputs=inputs,
                              block_dim=lanes, device=device, record_cmd=True)
    return command, force


def sweep_launch(prepared, params: Params, d: float, offset: float, force, lifts, device: str):
    """The registry's ``force_launch`` of the sweep (:mod:`mdroll.ensemble.algorithms`): the
    recorded launch of :func:`sweep_command` in its device's default form and layout, writing
    ``force``."""
    return sweep_command(prepared, params, d, device, out=force, offset=offset)[0]


def sweep_coupled(prepared):
    """The registry's ``coupled`` of the sweep (:mod:`mdroll.ensemble.algorithms`): the eq 13
    kernel :data:`~mdroll.kernels.sweep.coupled_sweep` and its
    :class:`~mdroll.kernels.sweep.SweepLines` from prepared lines."""
    from ..kernels.sweep import SweepLines, coupled_sweep
    from .prepare import ensure_prefix_sums

    ensure_prefix_sums(prepared, str(prepared.lines.device))
    lines = SweepLines()
    lines.h, lines.prefix, lines.bounds, lines.n = prepared.lines, prepared.prefix, prepared.bounds, prepared.n_work
    return coupled_sweep, lines
