"""A kernel that holds a CUDA stream for a set time, for timing on the device's clock
(:func:`mdroll.bench.study.device_timed`): work enqueued behind it starts only when it ends, so
the host's time to enqueue that work stays outside the events around it."""

import warp as wp


@wp.func_native("""
#if defined(__CUDA_ARCH__)
unsigned long long start, now;
asm volatile("mov.u64 %0, %%globaltimer;" : "=l"(start));
do {
    asm volatile("mov.u64 %0, %%globaltimer;" : "=l"(now));
} while (now - start < (unsigned long long)nanoseconds);
#endif
""")
def wait_nanoseconds(nanoseconds: wp.int64):
    """Spin on the GPU's global timer (ns) until ``nanoseconds`` have passed (CUDA; nothing on
    the CPU)."""
    ...


@wp.kernel(enable_backward=False)
def hold_stream(nanoseconds: wp.int64):
    """Launched with one lane: the stream is busy for ``nanoseconds`` (ns)."""
    wait_nanoseconds(nanoseconds)
