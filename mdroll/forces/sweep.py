"""Host side of the sweep force (physics.md section 4): its form, the stream's layout, the launch.

The sweep is exact and O(n) at a fixed indentation d. It reads the lines and the row bounds
``(min h, max h)`` of a :class:`~mdroll.forces.prepared.PreparedLines`, and, in its sequential
form and its coupled step, their prefix sums (eq 18), built on first use. On CUDA it runs as a
stream: a block sweeps a long segment of a row chunk by chunk, its lanes scattering and
scanning the events together and carrying the totals and the pending events from chunk to
chunk (:mod:`mdroll.kernels.sweep_stream`); on the CPU, where Warp runs one lane a thread, as a
sequential sweep of each chunk of steps (:mod:`mdroll.kernels.sweep_sequential`). The stream's
layout is chosen from the device's limits (:func:`mdroll.devices.device_limits`); the tuning
behind the constants here is in docs/performance.md, "Sweep".
"""

from __future__ import annotations

from .. import physics
from ..devices import DeviceLimits, device_limits, is_cuda, warp
from ..kernels.sweep_coupled import SweepLines, coupled_sweep
from ..kernels.sweep_sequential import contact_force_sequential
from ..kernels.sweep_stream import BIN_BYTES, MAX_STREAM_BAND, RING_UNIT, stream_kernel
from ..errors import ParameterError
from ..params import Params
from .indenter import reach_strict
from .prepared import ensure_prefix_sums

#: The sequential form: steps a thread, at least SEQUENTIAL_CHUNK_PER_BAND times the band (a
#: chunk reads the anchor's 2 band springs once, and its ring holds at least band + 1 slots).
SEQUENTIAL_CHUNK = 1 << 15
SEQUENTIAL_CHUNK_PER_BAND = 16
#: The ring's fewest slots. It needs band + 1, but a narrow ring revisits a slot every few steps,
#: and each step's read of its slot then waits on the read-modify-writes just recorded there; a
#: ring of this many slots runs narrow bands as fast as wide ones.
RING_MIN_SLOTS = 64
#: The sweep's forms and the one each kind of device runs by default.
FORMS = ("stream", "sequential")
DEFAULT_FORM = {"cuda": "stream", "cpu": "sequential"}

#: The stream form on CUDA: its layouts ``(lanes a block, steps a lane a chunk, registers a
#: lane)``, in order of preference, each first with the delay line; the launch takes the first
#: that keeps STREAM_MIN_WARPS warps resident on a multiprocessor (its ring of ``lanes x steps +
#: 2 outer`` bins, or ``+ band`` without the delay line, in shared memory, its registers), else
#: the one that keeps the most: a long reach drops the delay line, a wide band (a fine line)
#: trades steps a lane for lanes. 128 registers a lane let the kernel load a chunk ahead without
#: spilling.
STREAM_LAYOUTS = ((128, 8, 128), (256, 8, 128), (256, 4, 128))
STREAM_MIN_WARPS = 16
#: The CPU runs a block as one lane, ``STREAM_CPU_PER_LANE`` steps a chunk, its ring within
#: CPU_BLOCK_SHARED bytes of Warp's CPU shared-memory arena.
STREAM_CPU_PER_LANE = 16
CPU_BLOCK_SHARED = 227 * 1024
#: Blocks a launch aims at: this many per resident block slot of the device, so that the last
#: wave's tail is short; a segment is never shorter than STREAM_SEGMENT_PER_BAND times the span
#: of its events (:func:`_span`: its anchor puts the events of up to that many springs in the
#: ring) nor than two chunks (shorter segments make short lines slower, not faster).
STREAM_WAVES = 4
STREAM_SEGMENT_PER_BAND = 16


def _ring(chunk: int, span: int, unit: int) -> tuple[int, int]:
    """The stream's ring for chunks of ``chunk`` steps and events up to ``span`` steps past a
    chunk's last (``chunk + span + 1`` bins, rounded up to ``unit``) and the shared memory its
    block takes (bytes: the bins and ~1 KiB of the warps' and the anchor's totals)."""
    ring = -(-(chunk + span + 1) // unit) * unit
    return ring, ring * BIN_BYTES + 1024


def _span(band: int, outer: int, delay: bool) -> int:
    """The steps past a chunk's last that its events reach: a spring's contact, 2 outer, with the
    delay line, else the band."""
    return max(2 * outer if delay else band, 0)


def _resident(limits: DeviceLimits, shared: float, lanes: int, registers: int) -> int:
    """Blocks of ``lanes`` lanes at ``registers`` registers a lane and ``shared`` bytes of shared
    memory that a multiprocessor of ``limits`` holds at once."""
    return int(min(limits.shared_per_multiprocessor // shared,
                   limits.registers_per_multiprocessor // (lanes * registers),
                   limits.lanes_per_multiprocessor // lanes))


def _cpu_layout(band: int, outer: int, delays, per_lane: int | None) -> dict | None:
    """The stream's layout on the CPU: one lane a block, the delay line where its ring fits."""
    chunk = per_lane or STREAM_CPU_PER_LANE
    for delayed in delays:
        ring, shared = _ring(chunk, _span(band, outer, delayed), 32)
        if shared <= CPU_BLOCK_SHARED:
            return {"block_dim": 1, "per_lane": chunk, "max_registers": None, "ring": ring, "delay": delayed,
                    "resident": 1}
    return None


def _cuda_layout(band: int, outer: int, delays, limits: DeviceLimits, block_dim: int | None,
                 per_lane: int | None) -> dict | None:
    """The stream's layout on a CUDA device of ``limits``: the first of STREAM_LAYOUTS (or the
    caller's own) that keeps STREAM_MIN_WARPS warps resident, else the one that keeps the most."""
    best = None
    candidates = [(lanes, steps_a_lane, registers, delayed) for lanes, steps_a_lane, registers in STREAM_LAYOUTS
                  for delayed in delays
                  if not (block_dim and lanes != block_dim) and not (per_lane and steps_a_lane != per_lane)]
    if not candidates and block_dim and per_lane:  # a layout of the caller's own
        candidates = [(block_dim, per_lane, None, delayed) for delayed in delays]
    for lanes, steps_a_lane, registers, delayed in candidates:
        ring, shared = _ring(lanes * steps_a_lane, _span(band, outer, delayed), RING_UNIT)
        if shared > limits.shared_per_block:
            continue
        resident = _resident(limits, shared, lanes, registers) if registers else 1
        if resident < 1:
            continue
        candidate = {"block_dim": lanes, "per_lane": steps_a_lane, "max_registers": registers, "ring": ring,
                     "delay": delayed, "resident": resident}
        if best is None or resident * lanes > best["resident"] * best["block_dim"]:
            best = candidate
        if resident * lanes >= 32 * STREAM_MIN_WARPS:  # (then it is best: the first to get there)
            break
    return best


def stream_layout(band: int, outer: int, rows: int, steps: int, limits: DeviceLimits | None,
                  block_dim: int | None = None, per_lane: int | None = None, segment: int | None = None,
                  delay: bool | None = None) -> dict | None:
    """The stream form's launch for a widest band of ``band`` springs, a widest reach of
    ``outer`` springs and ``rows x steps`` steps on a device of ``limits``
    (:func:`mdroll.devices.device_limits`; None: the CPU): ``{"block_dim", "per_lane",
    "max_registers", "ring", "delay", "resident", "segment"}`` (``resident``: its blocks a
    multiprocessor holds), or None where no ring fits a block's shared memory (or the band
    passes MAX_STREAM_BAND). The delay line (a spring's leaving event put in the ring when it
    enters: one read and one reach a spring instead of two) needs a ring spanning the
    2 outer + 1 steps of a spring's contact, the other only its band's: each layout takes it
    where it still keeps STREAM_MIN_WARPS warps resident. ``block_dim``, ``per_lane`` and
    ``delay`` pick a layout, ``segment`` the steps a block."""
    if band > MAX_STREAM_BAND:
        return None
    delays = (True, False) if delay is None else (delay,)
    if limits is None:
        layout = _cpu_layout(band, outer, delays, per_lane)
    else:
        layout = _cuda_layout(band, outer, delays, limits, block_dim, per_lane)
    if layout is None:
        return None
    slots = 1 if limits is None else limits.multiprocessors * layout["resident"]
    chunk = layout["block_dim"] * layout["per_lane"]
    if segment is None:
        segment = max(-(-rows * steps // (STREAM_WAVES * slots)),
                      STREAM_SEGMENT_PER_BAND * _span(band, outer, layout["delay"]), 2 * chunk)
    layout["segment"] = -(-segment // chunk) * chunk
    return layout


def _stream_command(p, params: Params, d: float, device: str, force, offset: float, band: int, outer: int,
                    curvature: float, block_dim, per_lane, segment, delay):
    """The stream form's recorded launch (see :func:`sweep_command`)."""
    rows = p.lines.shape[0]
    limits = device_limits(device)
    layout = stream_layout(band, outer, rows, p.steps, limits, block_dim, per_lane, segment, delay)
    if layout is None:
        if delay and stream_layout(band, outer, rows, p.steps, limits, block_dim, per_lane, segment, False):
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
    return warp().launch_tiled(kernel, dim=(rows, -(-p.steps // layout["segment"])), inputs=inputs,
                               block_dim=layout["block_dim"], device=device, record_cmd=True)


def _sequential_command(p, params: Params, d: float, device: str, force, offset: float, band: int,
                        curvature: float, chunk: int | None):
    """The sequential form's recorded launch (see :func:`sweep_command`)."""
    wp = warp()
    rows = p.lines.shape[0]
    ensure_prefix_sums(p, device)  # the anchors' cores in closed form (eq 18-20)
    chunk = chunk or max(SEQUENTIAL_CHUNK, 1 << (SEQUENTIAL_CHUNK_PER_BAND * band - 1).bit_length())
    chunks = -(-p.steps // chunk)
    # a thread's ring: one slot a step for the band's steps ahead, and the current step's
    slots = max(band + 1, RING_MIN_SLOTS)
    ring_packed = wp.empty((rows, chunks, slots), dtype=wp.int64, device=device)
    ring_value = wp.empty((rows, chunks, slots), dtype=wp.float64, device=device)
    inputs = [p.lines, p.prefix, p.bounds, p.n_work, p.first, p.steps, chunk, d, curvature, params.k_spring,
              offset, ring_packed, ring_value, force]
    return wp.launch(contact_force_sequential, dim=(rows, chunks), inputs=inputs, device=device, record_cmd=True)


def sweep_command(prepared, params: Params, d: float, device: str, out=None, offset: float = 0.0,
                  form: str | None = None, chunk: int | None = None, block_dim: int | None = None,
                  per_lane: int | None = None, segment: int | None = None, delay: bool | None = None):
    """The sweep's force launch, recorded (``wp.Launch``; run with ``.launch()``), and the
    (R, steps) array it writes: ``F - offset`` (N) at indentation d (m) for every step.

    ``prepared`` needs ``lines``, ``bounds``, ``h_low`` and ``h_top`` (see
    :func:`mdroll.forces.prepare.prepare_lines`); the sequential form builds the prefix sums
    into it on first use. ``form`` (:data:`FORMS`) picks the kernel, by default
    :data:`DEFAULT_FORM` of the device's kind; for the stream ``block_dim``, ``per_lane``,
    ``segment`` and ``delay`` override the layout of :func:`stream_layout`; for the sequential
    form ``chunk`` overrides the default of max(SEQUENTIAL_CHUNK, SEQUENTIAL_CHUNK_PER_BAND x
    band). The force is the same to rounding whatever they are. A batch whose band of uncertain
    contact is too wide for the stream's ring in shared memory runs in the sequential form
    (exact at any band); the stream asked for then is refused (ParameterError).
    """
    wp = warp()
    p = prepared
    curvature = physics.indenter_profile(params.dx, params.R)  # eq 7 at one spacing
    # the widest band of the batch (each row's own is narrower): from its lowest and highest spring
    outer = reach_strict(d + p.h_top, curvature)
    band = outer - max(reach_strict(d + p.h_low, curvature), 0)
    if form is None:
        form = DEFAULT_FORM["cuda" if is_cuda(device) else "cpu"]
        if form == "stream" and stream_layout(band, outer, p.lines.shape[0], p.steps, device_limits(device)) is None:
            form = "sequential"
    if form not in FORMS:
        raise ParameterError(f"form = {form!r}: the sweep's forms are {', '.join(map(repr, FORMS))}")
    force = out if out is not None else wp.empty((p.lines.shape[0], p.steps), dtype=wp.float64, device=device)
    if form == "stream":
        command = _stream_command(p, params, d, device, force, offset, band, outer, curvature, block_dim, per_lane,
                                  segment, delay)
    else:
        command = _sequential_command(p, params, d, device, force, offset, band, curvature, chunk)
    return command, force


def sweep_launch(prepared, params: Params, d: float, offset: float, force, lifts, device: str):
    """The registry's ``force_launch`` of the sweep (:mod:`mdroll.forces.registry`): the
    recorded launch of :func:`sweep_command` in its device's default form and layout, writing
    ``force``."""
    return sweep_command(prepared, params, d, device, out=force, offset=offset)[0]


def sweep_coupled(prepared):
    """The registry's ``coupled`` of the sweep (:mod:`mdroll.forces.registry`): the eq 13
    kernel :data:`~mdroll.kernels.sweep_coupled.coupled_sweep` and its
    :class:`~mdroll.kernels.sweep_coupled.SweepLines` from prepared lines."""
    ensure_prefix_sums(prepared, str(prepared.lines.device))
    lines = SweepLines()
    lines.h, lines.prefix, lines.bounds, lines.n = prepared.lines, prepared.prefix, prepared.bounds, prepared.n_work
    return coupled_sweep, lines
