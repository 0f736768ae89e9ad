"""CUDA intrinsics for the kernels, in one place: shared-memory atomics, loads and stores by
address, barriers, warp shuffles, L2 and L1 prefetches and the GPU's global timer.

Each is a ``wp.func_native`` with a CPU fallback where the kernels also run on the CPU (there a
block is one lane: a warp's barrier or shuffle does nothing, a block's barrier is Warp's CPU
block barrier). Addresses are ``wp.uint64``: the kernels take them from Warp arrays and tiles
and index them with ``int`` offsets. The :data:`hold_stream` kernel uses the timer to hold a
CUDA stream for device-clock timing (:func:`mdroll.bench.study.device_timed`).
"""

import warp as wp


@wp.func_native("""
#if defined(__CUDA_ARCH__)
atomicAdd(((int*)base) + i, value);
#else
((int*)base)[i] += value;
#endif
""")
def shared_add(base: wp.uint64, i: int, value: int):
    """``base[i] += value`` on an int32 in shared memory, atomically between a block's lanes."""
    ...


@wp.func_native("""return ((int*)base)[i];""")
def shared_int(base: wp.uint64, i: int) -> int:
    """The int32 at ``base[i]`` in shared memory."""
    ...


@wp.func_native("""((int*)base)[i] = value;""")
def set_shared_int(base: wp.uint64, i: int, value: int):
    """``base[i] = value`` for an int32 in shared memory."""
    ...


@wp.func_native("""
int* words = (int*)base;
long long bits;
memcpy(&bits, &value, sizeof(bits));
words[i] = (int)bits;
words[i + stride] = (int)(bits >> 32);
""")
def set_shared_float_words(base: wp.uint64, i: int, stride: int, value: wp.float64):
    """A float64 into the int32 words ``base[i]`` (low half) and ``base[i + stride]`` (high half)
    in shared memory."""
    ...


@wp.func_native("""
const int* words = (const int*)base;
long long bits = ((long long)words[i + stride] << 32) | (unsigned)words[i];
double value;
memcpy(&value, &bits, sizeof(value));
return value;
""")
def shared_float_words(base: wp.uint64, i: int, stride: int) -> wp.float64:
    """The float64 of :func:`set_shared_float_words`."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
__syncwarp();
#endif
""")
def sync_warp():
    """A warp's barrier (CUDA; nothing on the CPU, where a block is one lane)."""
    ...


@wp.func_native("""return (uint64_t)(((char*)a.data) + (size_t)r * (size_t)a.strides[0]);""")
def row_address(a: wp.array2d(dtype=wp.float64), r: int) -> wp.uint64:
    """The address of ``a[r, 0]`` (rows contiguous: the launcher checks)."""
    ...


@wp.func_native("""return ((const double*)base)[i];""")
def load_float(base: wp.uint64, i: int) -> wp.float64:
    """``base[i]`` for a float64 in global memory (one address computation less than Warp's
    strided indexing a load)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
asm volatile("prefetch.global.L2 [%0];" :: "l"(((const double*)base) + i));
#endif
""")
def prefetch_float(base: wp.uint64, i: int):
    """Ask the L2 cache for the 128-byte line holding ``base[i]`` (CUDA; nothing on the CPU)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
asm volatile("prefetch.global.L1 [%0];" :: "l"(((const double*)base) + i));
#endif
""")
def prefetch_float_near(base: wp.uint64, i: int):
    """Ask the multiprocessor's L1 cache for the 128-byte line holding ``base[i]`` (CUDA;
    nothing on the CPU)."""
    ...


@wp.func_native("""((double*)base)[i] = value;""")
def store_float(base: wp.uint64, i: int, value: wp.float64):
    """``base[i] = value`` for a float64 in global memory."""
    ...


@wp.func_native("""((double*)base)[i] = value;""")
def set_shared_float(base: wp.uint64, i: int, value: wp.float64):
    """``base[i] = value`` for a float64 in shared memory."""
    ...


@wp.func_native("""return ((double*)base)[i];""")
def shared_float(base: wp.uint64, i: int) -> wp.float64:
    """The float64 at ``base[i]`` in shared memory."""
    ...


@wp.func_native("""return ((long long*)base)[i];""")
def shared_int64(base: wp.uint64, i: int) -> wp.int64:
    """The int64 at ``base[i]`` in shared memory."""
    ...


@wp.func_native("""((long long*)base)[i] = value;""")
def set_shared_int64(base: wp.uint64, i: int, value: wp.int64):
    """``base[i] = value`` for an int64 in shared memory."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return __shfl_up_sync(0xffffffffu, (long long)value, delta);
#else
return value;
#endif
""")
def shuffle_up(value: wp.int64, delta: int) -> wp.int64:
    """The value of the lane ``delta`` below in the warp (CUDA; every lane of the warp must call)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return __shfl_xor_sync(0xffffffffu, (long long)value, mask);
#else
return value;
#endif
""")
def shuffle_xor(value: wp.int64, mask: int) -> wp.int64:
    """The value of lane ``lane ^ mask`` of the warp (CUDA; every lane of the warp must call)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return __shfl_xor_sync(0xffffffffu, value, mask);
#else
return value;
#endif
""")
def shuffle_xor_float(value: wp.float64, mask: int) -> wp.float64:
    """The float64 of lane ``lane ^ mask`` of the warp (CUDA; every lane of the warp must call)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
#pragma unroll
for (int mask = 16; mask > 0; mask >>= 1) {
    value += __shfl_xor_sync(0xffffffffu, value, mask);
}
#endif
return value;
""")
def warp_sum_float(value: wp.float64) -> wp.float64:
    """The sum of a float64 over the 32 lanes of the warp, in every lane (CUDA; the value itself
    on the CPU, where a block is one lane; every lane of the warp must call): a butterfly of
    shuffles, each level adding the same two numbers in both lanes of a pair, in either order,
    so that every lane holds the same bits."""
    ...


#: Levels of a butterfly over the 32 lanes of a warp: the steps a sum takes through
#: :func:`pipelined_sums`.
PIPELINE_LEVELS = 5

#: The sums in flight through :func:`pipelined_sums`: entry i has had i levels.
PipelineSums = wp.types.vector(length=PIPELINE_LEVELS + 1, dtype=wp.float64)


@wp.func_native("""
constexpr int P = sizeof(sums.c) / sizeof(sums.c[0]);
#pragma unroll
for (int i = P - 1; i > 0; --i) {
#if defined(__CUDA_ARCH__)
    sums.c[i] = sums.c[i - 1] + __shfl_xor_sync(0xffffffffu, sums.c[i - 1], 32 >> i);
#else
    sums.c[i] = sums.c[i - 1];
#endif
}
sums.c[0] = 0.0;
return sums;
""")
def pipelined_sums(sums: PipelineSums) -> PipelineSums:
    """One level of the butterfly of :func:`warp_sum_float` for each of the sums in flight: entry
    i + 1 becomes entry i with level i + 1 done (lanes ``lane ^ (16 >> i)`` added, in either
    order, so that every lane holds the same bits), entry 0 zero for the next sum to enter;
    the last entry is a whole sum over the warp's 32 lanes, :data:`PIPELINE_LEVELS` calls after
    it entered (CUDA; the value itself, as late, on the CPU, where a block is one lane; every
    lane of the warp must call). The levels are independent of each other: a call costs one
    shuffle's latency, not five."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
double a = value.c[0], b = value.c[1];
#pragma unroll
for (int mask = 16; mask > 0; mask >>= 1) {
    a += __shfl_xor_sync(0xffffffffu, a, mask);
    b += __shfl_xor_sync(0xffffffffu, b, mask);
}
return wp::vec2d(a, b);
#else
return value;
#endif
""")
def warp_sum_float_pair(value: wp.vec2d) -> wp.vec2d:
    """:func:`warp_sum_float` of both components, interleaved (the second adds little latency)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
__syncthreads();
#else
WP_TILE_SYNC();
#endif
""")
def sync_block():
    """A block's barrier (``__syncthreads`` on CUDA, Warp's CPU block barrier otherwise)."""
    ...


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


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return (int)__ballot_sync(0xffffffffu, predicate);
#else
return predicate ? 1 : 0;
#endif
""")
def ballot(predicate: bool) -> int:
    """The bits of the lanes of the warp whose ``predicate`` holds (lane i: bit i; CUDA; on the
    CPU, where a block is one lane, bit 0; every lane of the warp must call)."""
    ...


@wp.func_native("""
unsigned bits = (unsigned)mask;
if (bits == 0u) return -1;
int i = 0;
#if defined(__CUDA_ARCH__)
i = __ffs(bits) - 1;
#else
while (!((bits >> i) & 1u)) ++i;
#endif
return i;
""")
def lowest_lane(mask: int) -> int:
    """The lowest lane whose bit is set in a :func:`ballot`'s ``mask``; -1 for none."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return __shfl_sync(0xffffffffu, value, source);
#else
return value;
#endif
""")
def broadcast_float(value: wp.float64, source: int) -> wp.float64:
    """The float64 of lane ``source`` (taken modulo 32) of the warp, in every lane (CUDA; the
    value itself on the CPU; every lane of the warp must call)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return __shfl_sync(0xffffffffu, value, source);
#else
return value;
#endif
""")
def broadcast_int(value: int, source: int) -> int:
    """The int of lane ``source`` (taken modulo 32) of the warp, in every lane (as
    :func:`broadcast_float`)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 800
return __reduce_add_sync(0xffffffffu, value);
#elif defined(__CUDA_ARCH__)
#pragma unroll
for (int mask = 16; mask > 0; mask >>= 1) {
    value += __shfl_xor_sync(0xffffffffu, value, mask);
}
return value;
#else
return value;
#endif
""")
def warp_sum_int(value: int) -> int:
    """The sum of an int over the 32 lanes of the warp, in every lane (one instruction from
    compute capability 8.0, a butterfly of shuffles before; the value itself on the CPU; every
    lane of the warp must call)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
float root;
asm("sqrt.approx.f32 %0, %1;" : "=f"(root) : "f"(value));
return root;
#else
return sqrtf(value);
#endif
""")
def rough_sqrt(value: wp.float32) -> wp.float32:
    """The square root of a float32 ``value >= 0`` to a relative error below 2^-22 (CUDA's
    approximate square root, one instruction without a slow path; ``sqrtf`` on the CPU): for
    guesses that an exact test then settles."""
    ...


@wp.func_native("""return ((volatile double*)base)[i];""")
def shared_volatile(base: wp.uint64, i: int) -> wp.float64:
    """The float64 at ``base[i]`` in shared memory, read anew (another warp may write it)."""
    ...


@wp.func_native("""((volatile double*)base)[i] = value;""")
def set_shared_volatile(base: wp.uint64, i: int, value: wp.float64):
    """``base[i] = value`` for a float64 in shared memory, written at once (another warp reads it)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
__threadfence_block();
#endif
""")
def fence_block():
    """Orders this lane's shared-memory writes (reads) before its later ones for the block's
    other warps (CUDA; nothing on the CPU, where a block is one lane)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
__nanosleep(32);
#endif
""")
def backoff():
    """A short pause in a lane's wait for another warp, leaving the issue slots to the warps
    that work (CUDA; nothing on the CPU)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return __ldg(((const double*)base) + i);
#else
return ((const double*)base)[i];
#endif
""")
def load_line(base: wp.uint64, i: int) -> wp.float64:
    """``base[i]`` for a float64 in global memory that no lane writes while the kernel runs (a
    line's heights or prefix sums): a global load through the read-only path."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
const unsigned at = (unsigned)__cvta_generic_to_shared(((double*)base) + 2 * i);
asm volatile("st.volatile.shared.v2.f64 [%0], {%1, %2};" :: "r"(at), "d"(first), "d"(second) : "memory");
#else
((volatile double*)base)[2 * i] = first;
((volatile double*)base)[2 * i + 1] = second;
#endif
""")
def set_shared_pair(base: wp.uint64, i: int, first: wp.float64, second: wp.float64):
    """The pair of float64 ``base[2 i], base[2 i + 1]`` in shared memory, in one 16-byte write
    (another warp reads it whole, :func:`shared_pair`)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
double first, second;
const unsigned at = (unsigned)__cvta_generic_to_shared(((double*)base) + 2 * i);
asm volatile("ld.volatile.shared.v2.f64 {%0, %1}, [%2];" : "=d"(first), "=d"(second) : "r"(at) : "memory");
return wp::vec2d(first, second);
#else
return wp::vec2d(((volatile double*)base)[2 * i], ((volatile double*)base)[2 * i + 1]);
#endif
""")
def shared_pair(base: wp.uint64, i: int) -> wp.vec2d:
    """The pair of float64 of :func:`set_shared_pair`, read anew in one 16-byte read."""
    ...
