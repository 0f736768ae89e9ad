"""The constrained conjugate gradients of :func:`mdroll.bem.solver.constrained_cg` on CUDA, fused:
the same iteration, on the same batch, in a few kernels per iteration replayed as a CUDA graph.

Layout. The pressure p and the conjugate direction t live in the first n columns of zero-padded
(B, n, 2n) buffers. Each convolution ``K * x`` is three kernels: a batched real FFT of the n rows
(cuFFT, length 2n), the column transform of :mod:`mdroll.bem.columns` (every column of the row
spectra zero-padded, transformed, multiplied by the kernel's spectrum and transformed back in shared
memory) and the batched inverse real FFT of the rows. The zero rows of the padding are never
stored or transformed. u = K p and r = K t stay in
their padded outputs. Per-member scalars (the approach, G, the conjugacy ratio, the step tau, the
residual, the iteration count and an ``active`` flag) stay on the device in a (B, fields) array.

One iteration (displacement control; load control adds the two passes in brackets):

    u = K p;  [count, sum_I (u + s)  ->  d];  sum_I g^2  ->  ratio;  t <- I (g + ratio t);
    r = K t;  sum_I r t, sum_I g t [, sum_I r, sum_I t]  ->  tau;
    p <- max(p - tau t, 0) (-tau g where it penetrates), sum p, sum |dp|, overlaps
    [ -> the load's scale;  p <- scale p, sum p, sum |dp|]  ->  residual, active.

Each reduction is one kernel over (chunks, members) blocks writing per-chunk partial sums; the last
block of a member to finish adds them in a fixed order (the result does not depend on the batch)
and updates the member's scalars. A member that converged (or hit the iteration cap) is skipped by
every kernel but the row FFTs, so it keeps its pressure. Each graph replay runs :data:`CHECK_EVERY`
iterations and copies the scalars to pinned host memory; the host keeps two replays in flight and
looks at the flags of the older one, so the device does not wait for the host.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from .columns import COLUMN_SOURCE, COLUMN_THREADS, COLUMNS, MAX_CELLS, column_rows, column_spectrum, shared_bytes

#: Iterations per graph replay, between two looks at the members' convergence flags.
CHECK_EVERY = 8
#: Threads per block of the element-wise kernels.
THREADS = 256
#: Cells of a batch up to which the element-wise kernels take one cell a thread (about the threads
#: one wave of blocks holds); two above, so that larger batches launch half the blocks.
ONE_CELL_A_THREAD = 2**18
#: Partial sums per reduction.
SUMS = 4

TARGET, APPROACH, G_OLD, DELTA, ACTIVE, ITERATIONS, RESIDUAL, COUNT, G, RATIO, TAU, SCALE, TOL, MAX_ITER, \
    CELL_AREA, FORCE, AREA, NEXT, LOST, POSITION, STEPS = range(21)
FIELDS = 24

SOURCE = r"""
#define THREADS 256
#define SUMS 4
#define FIELDS 24
enum {TARGET, APPROACH, G_OLD, DELTA, ACTIVE, ITERATIONS, RESIDUAL, COUNT, G, RATIO, TAU, SCALE, TOL, MAX_ITER,
      CELL_AREA, FORCE, AREA, NEXT, LOST, POSITION, STEPS};

// the sums v[0..SUMS) over the block, written by thread 0 to out[k * stride]
__device__ void block_sums(double v[SUMS], double* out, int stride) {
    __shared__ double warps[THREADS / 32][SUMS];
    const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
#pragma unroll
    for (int k = 0; k < SUMS; ++k) {
        double x = v[k];
        for (int o = 16; o > 0; o >>= 1) x += __shfl_down_sync(0xffffffffu, x, o);
        if (lane == 0) warps[warp][k] = x;
    }
    __syncthreads();
    if (threadIdx.x == 0) {
        for (int k = 0; k < SUMS; ++k) {
            double x = 0.0;
            for (int w = 0; w < THREADS / 32; ++w) x += warps[w][k];
            out[k * stride] = x;
        }
    }
}

// member b = blockIdx.y (skipped where SKIP); its cells c of this block; q the padded index, e the plain one
#define CELLS_UNLESS(SKIP)                                                                      \
    const int b = blockIdx.y;                                                                   \
    const double* m = st + (long long)b * FIELDS;                                               \
    if (SKIP) return;                                                                           \
    const long long nn = (long long)n * n;                                                      \
    double v[SUMS] = {0.0, 0.0, 0.0, 0.0};                                                      \
    for (long long c = (long long)blockIdx.x * THREADS + threadIdx.x; c < nn;                  \
         c += (long long)gridDim.x * THREADS) {                                                 \
        const long long i = c / n;                                                              \
        const long long q = 2 * nn * b + 2 * n * i + (c - i * n);                               \
        const long long e = nn * b + c;
#define END_CELLS }
#define CELLS CELLS_UNLESS(m[ACTIVE] == 0.0)
// a member that converged and moves to the next rolling position
#define ADVANCING (m[NEXT] == 0.0 || m[POSITION] + 1.0 >= m[STEPS])
#define OWN_PARTIALS (part + (long long)b * SUMS * gridDim.x)
#define PARTIALS block_sums(v, OWN_PARTIALS + blockIdx.x, gridDim.x)
// the partial sums, then the member's scalars by its last block to finish
#define REDUCE(STAGE)                                                                           \
    PARTIALS;                                                                                   \
    if (last_block(arrivals + b)) scalars(st + (long long)b * FIELDS, OWN_PARTIALS, gridDim.x, STAGE, load)

// whether this block is the last of the member's blocks to arrive (then the counter is reset)
__device__ bool last_block(unsigned int* arrivals) {
    __shared__ bool last;
    __threadfence();
    __syncthreads();
    if (threadIdx.x == 0) {
        last = atomicAdd(arrivals, 1u) == gridDim.x - 1;
        if (last) *arrivals = 0u;
    }
    __syncthreads();
    return last;
}

// the end of an iteration: residual, count, force and area; a member that stops is flagged NEXT
__device__ void finish(double* m, const double* s) {
    const double change = s[0] > 0.0 ? s[1] / s[0] : 0.0;
    m[RESIDUAL] = change;
    m[ITERATIONS] += 1.0;
    m[G_OLD] = m[G];
    m[FORCE] = s[0] * m[CELL_AREA];
    m[AREA] = s[3] * m[CELL_AREA];
    m[ACTIVE] = (change >= m[TOL] && m[ITERATIONS] < m[MAX_ITER]) ? 1.0 : 0.0;
    m[NEXT] = 1.0 - m[ACTIVE];
}

// by one block: the member's partial sums added in a fixed order, then its scalars
__device__ void scalars(double* m, const double* own, int chunks, int stage, int load) {
    __shared__ double sums[SUMS];
    double v[SUMS];
    for (int k = 0; k < SUMS; ++k) {
        v[k] = 0.0;
        for (int c = threadIdx.x; c < chunks; c += THREADS) v[k] += __ldcg(own + k * chunks + c);
    }
    block_sums(v, sums, 1);
    __syncthreads();
    if (threadIdx.x != 0) return;
    const double* s = sums;
    if (stage == 0) {                 // contact set: its size and the approach (load control)
        m[COUNT] = fmax(s[0], 1.0);
        m[APPROACH] = s[1] / m[COUNT];
    } else if (stage == 1) {          // G and the conjugacy ratio
        m[G] = s[0];
        m[RATIO] = m[G_OLD] > 0.0 ? m[DELTA] * s[0] / m[G_OLD] : 0.0;
    } else if (stage == 2) {          // the step, r less its mean over I under load control
        const double curvature = s[0] - (load ? s[2] / m[COUNT] * s[3] : 0.0);
        m[TAU] = curvature > 0.0 ? s[1] / curvature : 0.0;
    } else if (stage == 3) {          // after the step
        m[DELTA] = s[2] > 0.0 ? 0.0 : 1.0;
        if (load) m[SCALE] = s[0] > 0.0 ? m[TARGET] / (m[CELL_AREA] * s[0]) : 0.0;
        else finish(m, s);
    } else {                          // after the rescaling to the load
        finish(m, s);
    }
}

extern "C" __global__ void contact_sums(const double* U, const double* P, const double* S, double* st,
                                        double* part, unsigned int* arrivals, int n, int load) {
    CELLS
        if (P[q] > 0.0) { v[0] += 1.0; v[1] += U[q] + S[e]; }
    END_CELLS
    REDUCE(0);
}

extern "C" __global__ void gap_norm(const double* U, const double* P, const double* S, double* st,
                                    double* part, unsigned int* arrivals, int n, int load) {
    CELLS
        if (P[q] > 0.0) { const double g = U[q] + S[e] - m[APPROACH]; v[0] += g * g; }
    END_CELLS
    REDUCE(1);
}

extern "C" __global__ void direction(const double* U, const double* P, const double* S, double* T,
                                     const double* st, int n) {
    CELLS
        T[q] = P[q] > 0.0 ? (U[q] + S[e] - m[APPROACH]) + m[RATIO] * T[q] : 0.0;
    END_CELLS
}

extern "C" __global__ void step_sums(const double* U, const double* R, const double* P, const double* S,
                                     const double* T, double* st, double* part, unsigned int* arrivals, int n,
                                     int load) {
    CELLS
        if (P[q] > 0.0) {
            const double t = T[q], r = R[q];
            v[0] += r * t; v[1] += (U[q] + S[e] - m[APPROACH]) * t; v[2] += r; v[3] += t;
        }
    END_CELLS
    REDUCE(2);
}

// the step; the new pressure to P (displacement control) or, unscaled, over u in U (load control)
extern "C" __global__ void update(double* U, double* P, const double* S, const double* T, double* st,
                                  double* part, unsigned int* arrivals, int n, int load) {
    CELLS
        const double p = P[q], tau = m[TAU];
        double next = fmax(p - tau * T[q], 0.0);
        const double g = U[q] + S[e] - m[APPROACH];
        if (next == 0.0 && g < 0.0) { next = next - tau * g; v[2] += 1.0; }
        v[0] += next; v[1] += fabs(next - p); v[3] += next > 0.0;
        if (load) U[q] = next; else P[q] = next;
    END_CELLS
    REDUCE(3);
}

extern "C" __global__ void rescale(const double* U, double* P, double* st, double* part,
                                   unsigned int* arrivals, int n, int load) {
    CELLS
        const double next = m[SCALE] * U[q];
        v[0] += next; v[1] += fabs(next - P[q]); v[3] += next > 0.0;
        P[q] = next;
    END_CELLS
    REDUCE(4);
}

// rolling: a member that converged records its position's results and moves one row on: its pressure
// shifted back one row (to U first), the next window's separation, t = 0
extern "C" __global__ void advance_cells(const double* P, double* U, double* S, double* T, const double* surface,
                                         const double* gap, const double* st, double* part, int n, int length,
                                         int width, int start, int column) {
    CELLS_UNLESS(ADVANCING)
        const long long j = c - i * n;
        const double shifted = i + 1 < n ? P[q + 2 * n] : 0.0;
        U[q] = shifted;
        T[q] = 0.0;
        const long long row = start + (long long)m[POSITION] + 1 + i;
        S[e] = gap[c] - surface[((long long)b * length + row) * width + column + j];
        v[0] += shifted;
    END_CELLS
    PARTIALS;
}

extern "C" __global__ void advance_copy(const double* U, double* P, const double* st, int n) {
    CELLS_UNLESS(ADVANCING)
        P[q] = U[q];
    END_CELLS
}

// one block per member: out (B, 5, steps) gets force, approach, area, iterations, residual; a member
// left without pressure waits (LOST) for the host's fresh start
extern "C" __global__ void advance_state(double* st, const double* part, double* out, int chunks) {
    double* m = st + (long long)blockIdx.x * FIELDS;
    if (m[NEXT] == 0.0) return;
    const double* own = part + (long long)blockIdx.x * SUMS * chunks;
    const bool moves = m[POSITION] + 1.0 < m[STEPS];
    double v[SUMS] = {0.0, 0.0, 0.0, 0.0};
    if (moves)
        for (int c = threadIdx.x; c < chunks; c += THREADS) v[0] += own[c];
    __shared__ double sums[SUMS];
    block_sums(v, sums, 1);
    __syncthreads();
    if (threadIdx.x != 0) return;
    const long long steps = (long long)m[STEPS], k = (long long)m[POSITION];
    double* row = out + (long long)blockIdx.x * 5 * steps + k;
    row[0] = m[FORCE]; row[steps] = m[APPROACH]; row[2 * steps] = m[AREA];
    row[3 * steps] = m[ITERATIONS]; row[4 * steps] = m[RESIDUAL];
    m[NEXT] = 0.0;
    if (!moves) return;
    m[POSITION] += 1.0;
    m[ITERATIONS] = 0.0; m[G_OLD] = 1.0; m[DELTA] = 0.0; m[RESIDUAL] = 1.0 / 0.0; m[APPROACH] = m[TARGET];
    if (sums[0] > 0.0) m[ACTIVE] = 1.0; else m[LOST] = 1.0;
}
"""


class FusedCG:
    """Solver state of one batch shape on one CUDA device: padded buffers, cuFFT plans, kernels and
    the CUDA graph of :data:`CHECK_EVERY` iterations, built once and reused for every call. Call it
    as ``(separation, control, pressure, tol, max_iter)``; it returns ``(p, d, iterations, residual)``
    like :func:`mdroll.bem.solver.constrained_cg`."""

    def __init__(self, op, batch: int, load_control: bool):
        import cupy
        from cupyx.scipy.fft import get_fft_plan

        if op.n > MAX_CELLS:
            raise ParameterError(f"the CUDA solver takes windows of at most {MAX_CELLS} cells across, got {op.n} "
                                 f"(solve it on device 'cpu')")
        self.cp, self.n, self.batch, self.load = cupy, op.n, batch, bool(load_control)
        n = op.n
        padded = (batch, n, 2 * n)
        self.p, self.t = cupy.zeros(padded), cupy.zeros(padded)
        self.u, self.r = cupy.empty(padded), cupy.empty(padded)
        self.spectra = cupy.empty((batch, n, n + 1), dtype=cupy.complex128)
        self.separation = cupy.empty((batch, n, n))
        self.state = cupy.zeros((batch, FIELDS))
        pinned = cupy.cuda.alloc_pinned_memory(self.state.nbytes)
        self.flags = np.frombuffer(pinned, np.float64, batch * FIELDS).reshape(batch, FIELDS)
        cells = THREADS * (1 if batch * n * n <= ONE_CELL_A_THREAD else 2)
        self.chunks = -(-n * n // cells)
        self.partials = cupy.empty((batch, SUMS, self.chunks))
        self.arrivals = cupy.zeros(batch, dtype=cupy.uint32)
        rows = column_rows(n)
        self.bits = rows.bit_length() - 1
        self.kernel = cupy.asarray(column_spectrum(op, rows))
        self.twiddle = cupy.asarray(np.exp(-2j * np.pi * np.arange(rows) / rows))
        self.cell_area = op.dx * op.dx
        self.forward = get_fft_plan(self.p, axes=(-1,), value_type="R2C")
        self.inverse = get_fft_plan(self.spectra, shape=(2 * n,), axes=(-1,), value_type="C2R")
        module = cupy.RawModule(code=SOURCE + COLUMN_SOURCE)
        self.kernels = {name: module.get_function(name) for name in (
            "contact_sums", "gap_norm", "direction", "step_sums", "update", "rescale", "columns",
            "advance_cells", "advance_copy", "advance_state")}
        self.shared = shared_bytes(rows)
        if self.shared > 48 * 1024:
            self.kernels["columns"].max_dynamic_shared_size_bytes = self.shared
        self.stream = cupy.cuda.Stream()
        self.events = [cupy.cuda.Event(disable_timing=True) for _ in range(2)]
        self.graph = None

    def convolve(self, source, target):
        """``target = K * source`` on the padded grids for the active members (only the first n
        columns of ``target`` are read)."""
        from cupy.cuda import cufft

        self.forward.fft(source, self.spectra, cufft.CUFFT_FORWARD)
        self.kernels["columns"]((-(-(self.n + 1) // COLUMNS), self.batch), (COLUMN_THREADS,),
                                (self.spectra, self.kernel, self.twiddle, self.state, np.int32(self.n),
                                 np.int32(self.bits)),
                                shared_mem=self.shared)
        self.inverse.fft(self.spectra, target, cufft.CUFFT_INVERSE)

    def _iteration(self):
        grid, block, n, load = (self.chunks, self.batch), (THREADS,), np.int32(self.n), np.int32(self.load)
        k, u, p, s, t, st, part = self.kernels, self.u, self.p, self.separation, self.t, self.state, self.partials
        arrivals = self.arrivals
        self.convolve(p, u)
        if self.load:
            k["contact_sums"](grid, block, (u, p, s, st, part, arrivals, n, load))
        k["gap_norm"](grid, block, (u, p, s, st, part, arrivals, n, load))
        k["direction"](grid, block, (u, p, s, t, st, n))
        self.convolve(t, self.r)
        k["step_sums"](grid, block, (u, self.r, p, s, t, st, part, arrivals, n, load))
        k["update"](grid, block, (u, p, s, t, st, part, arrivals, n, load))
        if self.load:
            k["rescale"](grid, block, (u, p, st, part, arrivals, n, load))

    def _replay(self):
        """:data:`CHECK_EVERY` iterations and the scalars' copy to ``flags``: the captured graph
        (captured on the first call)."""
        if self.graph is None:
            self.stream.begin_capture()
            try:
                for _ in range(CHECK_EVERY):
                    self._iteration()
                self.cp.cuda.runtime.memcpyAsync(self.flags.ctypes.data, self.state.data.ptr, self.state.nbytes,
                                                 self.cp.cuda.runtime.memcpyDeviceToHost, self.stream.ptr)
            finally:
                self.graph = self.stream.end_capture()
        self.graph.launch(self.stream)

    def _start(self, separation, control, pressure, tol, max_iter, steps=1):
        """Load a problem: every member active at its first iteration (on the solver's stream)."""
        n = self.n
        state = np.zeros((self.batch, FIELDS))
        state[:, TARGET] = state[:, APPROACH] = control
        state[:, G_OLD], state[:, ACTIVE], state[:, RESIDUAL], state[:, STEPS] = 1.0, 1.0, np.inf, steps
        state[:, TOL], state[:, MAX_ITER], state[:, CELL_AREA] = tol, max_iter, self.cell_area
        self.state.set(state)
        self.separation[...] = separation
        self.p[:, :, :n] = pressure
        self.t[:, :, :n] = 0.0

    def __call__(self, separation, control, pressure, tol, max_iter):
        cp, n = self.cp, self.n
        with self.stream:
            self._start(separation, control, pressure, tol, max_iter)
            replays, launched, seen = -(-max_iter // CHECK_EVERY), 0, 0
            while seen < launched or launched == 0:
                while launched < min(seen + 2, replays):
                    self._replay()
                    self.events[launched % 2].record(self.stream)
                    launched += 1
                self.events[seen % 2].synchronize()
                seen += 1
                if not self.flags[:, ACTIVE].any():
                    break
            result = (self.p[:, :, :n].copy(), self.state[:, APPROACH].copy(),
                      self.state[:, ITERATIONS].astype(cp.int64), self.state[:, RESIDUAL].copy())
        self.stream.synchronize()
        return result


class FusedRoll(FusedCG):
    """Rolling on the device: every member moves to its next position as soon as it converged (its
    pressure shifted back one row, the next window's separation from ``surface``), so a batch costs
    the members' mean iterations, not the slowest member's at every position. The host only looks at
    the flags between graph replays and gives a member left without pressure its fresh start."""

    def __init__(self, op, surface, gap, start: int, column: int, steps: int, load_control: bool):
        super().__init__(op, surface.shape[0], load_control)
        self.surface = self.cp.ascontiguousarray(surface, dtype=self.cp.float64)
        self.gap = self.cp.ascontiguousarray(gap, dtype=self.cp.float64)
        self.start, self.column, self.steps = start, column, steps
        self.out = self.cp.zeros((self.batch, 5, steps))

    def _iteration(self):
        super()._iteration()
        grid, block, n, k = (self.chunks, self.batch), (THREADS,), np.int32(self.n), self.kernels
        length, width = self.surface.shape[1:]
        k["advance_cells"](grid, block, (self.p, self.u, self.separation, self.t, self.surface, self.gap, self.state,
                                         self.partials, n, np.int32(length), np.int32(width), np.int32(self.start),
                                         np.int32(self.column)))
        k["advance_copy"](grid, block, (self.u, self.p, self.state, n))
        k["advance_state"]((self.batch,), block, (self.state, self.partials, self.out, np.int32(self.chunks)))

    def run(self, separation, control, pressure, tol, max_iter, fresh):
        """Roll from the first window's ``separation`` and ``pressure``; ``fresh(separation)`` gives
        the start of a member that lost contact. Returns the host arrays (B, steps) force, approach,
        area, iterations, residual and the last pressure (B, n, n)."""
        n, cp = self.n, self.cp
        with self.stream:
            self._start(separation, control, pressure, tol, max_iter, self.steps)
            while True:
                self._replay()
                self.stream.synchronize()
                flags = self.flags[:, ACTIVE:LOST + 1].copy()
                lost = np.flatnonzero(flags[:, LOST - ACTIVE])
                if lost.size:
                    index = cp.asarray(lost)
                    self.p[index, :, :n] = fresh(self.separation)[index]
                    self.state[index, LOST] = 0.0
                    self.state[index, ACTIVE] = 1.0
                elif not flags[:, 0].any():
                    break
            out, last = self.out.get(), self.p[:, :, :n].get()
        force, approach, area, iterations, residual = out.transpose(1, 0, 2)
        return force, approach, area, iterations.astype(np.int64), residual, last
