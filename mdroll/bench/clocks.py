"""The clocks of the scaling study: the wall clock around device work (the device synchronized
before every read) and, on CUDA, the device's own clock between events (:func:`device_timed`)."""

from __future__ import annotations

import statistics
import time

from ..devices import synchronize, warp


def timed(fn, device: str, repeats: int, setup=None) -> tuple[float, list[float]]:
    """Median and all wall times (s) of ``fn(setup(i))`` for i in range(repeats): ``setup``
    makes fresh inputs outside the clock (the previous ones are dropped first, so two sets never
    share the device); the device is synchronized before each clock read."""
    times = []
    for i in range(repeats):
        arg = None  # the previous inputs go before the next are made
        arg = setup(i) if setup else None
        synchronize(device)
        t0 = time.perf_counter()
        fn(arg) if setup else fn()
        synchronize(device)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times


#: On CUDA a force launch is timed on the device's clock: events recorded around it, enqueued
#: behind a kernel that holds the stream this long (s), so that the host's time to enqueue the
#: launch and the events stays outside the events (NVIDIA's nvbench holds the stream the same
#: way, with a kernel that waits on a host flag).
HOLD_S = 200e-6
#: Tries a repeat gets when the host took longer than HOLD_S to enqueue it (a pause of the
#: interpreter): its events would then count host time.
HOLD_TRIES = 3
#: The clocks of :func:`force_time`.
CLOCKS = ("device", "wall")


def device_timed(fn, device: str, repeats: int, setup=None) -> tuple[float, list[float]]:
    """:func:`timed`, on CUDA on the device's clock: the seconds between events recorded just
    before and after ``fn``'s device work (see :data:`HOLD_S`; a repeat whose enqueueing
    outlasts the hold is made again, up to HOLD_TRIES times, then RuntimeError); on the CPU the
    wall clock."""
    if not device.startswith("cuda"):
        return timed(fn, device, repeats, setup)
    from ..kernels.intrinsics import hold_stream  # imported here: the kernel module loads Warp

    wp = warp()
    stream = wp.get_stream(device)
    times = []
    for i in range(repeats):
        for _ in range(HOLD_TRIES):
            arg = None  # the previous inputs go before the next are made
            arg = setup(i) if setup else None
            synchronize(device)
            start, end = wp.Event(device, enable_timing=True), wp.Event(device, enable_timing=True)
            wp.launch(hold_stream, dim=1, inputs=[int(HOLD_S * 1e9)], device=device)
            enqueued = time.perf_counter()
            stream.record_event(start)
            fn(arg) if setup else fn()
            stream.record_event(end)
            if time.perf_counter() - enqueued < HOLD_S:
                break
        else:
            raise RuntimeError(f"the host took longer than HOLD_S = {HOLD_S} s to enqueue the timed work "
                               f"{HOLD_TRIES} times: its events would count host time")
        times.append(wp.get_event_elapsed_time(start, end) / 1e3)
    return statistics.median(times), times
