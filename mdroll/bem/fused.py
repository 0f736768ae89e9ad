"""The constrained conjugate gradients of :func:`mdroll.bem.solver.constrained_cg` on CUDA, fused:
the same iteration, on the same batch, in a few kernels per iteration replayed as a CUDA graph.

Layout. The pressure p and the conjugate direction t live in the top-left n x n corner of zero-padded
(B, 2n, 2n) buffers, so each convolution ``K * x`` is one batched 2-D real FFT of the padded grid
(a cached cuFFT plan), the product with the kernel's real spectrum (scaled by 1 / (2n)^2) and one
batched inverse FFT, with no padding or cropping copies; u = K p and r = K t stay in their padded
outputs. Per-member scalars (the approach, G, the conjugacy ratio, the step tau, the residual, the
iteration count and an ``active`` flag) stay on the device in a (B, fields) array.

One iteration (displacement control; load control adds the two passes in brackets):

    u = K p;  [count, sum_I (u + s)  ->  d];  sum_I g^2  ->  ratio;  t <- I (g + ratio t);
    r = K t;  sum_I r t, sum_I g t [, sum_I r, sum_I t]  ->  tau;
    p <- max(p - tau t, 0) (-tau g where it penetrates), sum p, sum |dp|, overlaps
    [ -> the load's scale;  p <- scale p, sum p, sum |dp|]  ->  residual, active.

Each reduction is a kernel over (chunks, members) blocks writing per-chunk partial sums, then one
block per member that adds them in a fixed order (the result does not depend on the batch) and
updates the member's scalars. A member that converged (or hit the iteration cap) is skipped by every
kernel, so it keeps its pressure. The host looks at the flags only after every :data:`CHECK_EVERY`
iterations (one graph replay): no synchronisation inside the iteration.
"""

from __future__ import annotations

import numpy as np

#: Iterations per graph replay, between two looks at the members' convergence flags.
CHECK_EVERY = 4
#: Cells per block of the element-wise kernels (256 threads, two cells each).
CELLS_PER_BLOCK = 512
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
        const long long q = 4 * nn * b + 2 * n * i + (c - i * n);                               \
        const long long e = nn * b + c;
#define END_CELLS }
#define CELLS CELLS_UNLESS(m[ACTIVE] == 0.0)
// a member that converged and moves to the next rolling position
#define ADVANCING (m[NEXT] == 0.0 || m[POSITION] + 1.0 >= m[STEPS])
#define PARTIALS block_sums(v, part + (long long)b * SUMS * gridDim.x + blockIdx.x, gridDim.x)

extern "C" __global__ void contact_sums(const double* U, const double* P, const double* S, const double* st,
                                        double* part, int n) {
    CELLS
        if (P[q] > 0.0) { v[0] += 1.0; v[1] += U[q] + S[e]; }
    END_CELLS
    PARTIALS;
}

extern "C" __global__ void gap_norm(const double* U, const double* P, const double* S, const double* st,
                                    double* part, int n) {
    CELLS
        if (P[q] > 0.0) { const double g = U[q] + S[e] - m[APPROACH]; v[0] += g * g; }
    END_CELLS
    PARTIALS;
}

extern "C" __global__ void direction(const double* U, const double* P, const double* S, double* T,
                                     const double* st, int n) {
    CELLS
        T[q] = P[q] > 0.0 ? (U[q] + S[e] - m[APPROACH]) + m[RATIO] * T[q] : 0.0;
    END_CELLS
}

extern "C" __global__ void step_sums(const double* U, const double* R, const double* P, const double* S,
                                     const double* T, const double* st, double* part, int n) {
    CELLS
        if (P[q] > 0.0) {
            const double t = T[q], r = R[q];
            v[0] += r * t; v[1] += (U[q] + S[e] - m[APPROACH]) * t; v[2] += r; v[3] += t;
        }
    END_CELLS
    PARTIALS;
}

// the step; the new pressure to P (displacement control) or, unscaled, over u in U (load control)
extern "C" __global__ void update(double* U, double* P, const double* S, const double* T, const double* st,
                                  double* part, int n, int load) {
    CELLS
        const double p = P[q], tau = m[TAU];
        double next = fmax(p - tau * T[q], 0.0);
        const double g = U[q] + S[e] - m[APPROACH];
        if (next == 0.0 && g < 0.0) { next = next - tau * g; v[2] += 1.0; }
        v[0] += next; v[1] += fabs(next - p); v[3] += next > 0.0;
        if (load) U[q] = next; else P[q] = next;
    END_CELLS
    PARTIALS;
}

extern "C" __global__ void rescale(const double* U, double* P, const double* st, double* part, int n) {
    CELLS
        const double next = m[SCALE] * U[q];
        v[0] += next; v[1] += fabs(next - P[q]); v[3] += next > 0.0;
        P[q] = next;
    END_CELLS
    PARTIALS;
}

extern "C" __global__ void multiply(double2* C, const double* spectrum, long long half, long long total) {
    for (long long k = (long long)blockIdx.x * blockDim.x + threadIdx.x; k < total;
         k += (long long)gridDim.x * blockDim.x) {
        const double w = spectrum[k % half];
        C[k].x *= w; C[k].y *= w;
    }
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

// one block per member: the partial sums added in a fixed order, then the member's scalars
extern "C" __global__ void scalars(double* st, const double* part, int chunks, int stage, int load) {
    double* m = st + (long long)blockIdx.x * FIELDS;
    if (m[ACTIVE] == 0.0) return;
    const double* own = part + (long long)blockIdx.x * SUMS * chunks;
    __shared__ double sums[SUMS];
    double v[SUMS];
    for (int k = 0; k < SUMS; ++k) {
        v[k] = 0.0;
        for (int c = threadIdx.x; c < chunks; c += THREADS) v[k] += own[k * chunks + c];
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

        self.cp, self.n, self.batch, self.load = cupy, op.n, batch, bool(load_control)
        n = op.n
        padded = (batch, 2 * n, 2 * n)
        self.p, self.t = cupy.zeros(padded), cupy.zeros(padded)
        self.u, self.r = cupy.empty(padded), cupy.empty(padded)
        self.spectra = cupy.empty((batch, 2 * n, n + 1), dtype=cupy.complex128)
        self.separation = cupy.empty((batch, n, n))
        self.state = cupy.zeros((batch, FIELDS))
        self.chunks = -(-n * n // CELLS_PER_BLOCK)
        self.partials = cupy.empty((batch, SUMS, self.chunks))
        self.kernel = cupy.ascontiguousarray(op.spectrum / (4.0 * n * n))
        self.cell_area = op.dx * op.dx
        self.forward = get_fft_plan(self.p, axes=(-2, -1), value_type="R2C")
        self.inverse = get_fft_plan(self.spectra, shape=(2 * n, 2 * n), axes=(-2, -1), value_type="C2R")
        module = cupy.RawModule(code=SOURCE)
        self.kernels = {name: module.get_function(name) for name in (
            "contact_sums", "gap_norm", "direction", "step_sums", "update", "rescale", "multiply", "scalars",
            "advance_cells", "advance_copy", "advance_state")}
        self.stream = cupy.cuda.Stream()
        self.graph = None

    def convolve(self, source, target):
        """``target = K * source`` on the padded grids (the crop is implicit: only the top-left n x n
        of ``target`` is read)."""
        from cupy.cuda import cufft

        self.forward.fft(source, self.spectra, cufft.CUFFT_FORWARD)
        total = self.spectra.size
        self.kernels["multiply"](((total + 255) // 256,), (256,),
                                 (self.spectra, self.kernel, np.int64(self.kernel.size), np.int64(total)))
        self.inverse.fft(self.spectra, target, cufft.CUFFT_INVERSE)

    def _reduce(self, stage):
        self.kernels["scalars"]((self.batch,), (256,),
                                (self.state, self.partials, np.int32(self.chunks), np.int32(stage), np.int32(self.load)))

    def _iteration(self):
        grid, block, n = (self.chunks, self.batch), (256,), np.int32(self.n)
        k, u, p, s, t, st, part = self.kernels, self.u, self.p, self.separation, self.t, self.state, self.partials
        self.convolve(p, u)
        if self.load:
            k["contact_sums"](grid, block, (u, p, s, st, part, n))
            self._reduce(0)
        k["gap_norm"](grid, block, (u, p, s, st, part, n))
        self._reduce(1)
        k["direction"](grid, block, (u, p, s, t, st, n))
        self.convolve(t, self.r)
        k["step_sums"](grid, block, (u, self.r, p, s, t, st, part, n))
        self._reduce(2)
        k["update"](grid, block, (u, p, s, t, st, part, n, np.int32(self.load)))
        self._reduce(3)
        if self.load:
            k["rescale"](grid, block, (u, p, st, part, n))
            self._reduce(4)

    def _replay(self):
        """:data:`CHECK_EVERY` iterations: the captured graph (captured on the first call)."""
        if self.graph is None:
            self.stream.begin_capture()
            try:
                for _ in range(CHECK_EVERY):
                    self._iteration()
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
        self.p[:, :n, :n] = pressure
        self.t[:, :n, :n] = 0.0

    def __call__(self, separation, control, pressure, tol, max_iter):
        cp, n = self.cp, self.n
        with self.stream:
            self._start(separation, control, pressure, tol, max_iter)
            done = 0
            while done < max_iter:
                self._replay()
                done += CHECK_EVERY
                if not bool(self.state[:, ACTIVE].any()):
                    break
            result = (self.p[:, :n, :n].copy(), self.state[:, APPROACH].copy(),
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
        grid, block, n, k = (self.chunks, self.batch), (256,), np.int32(self.n), self.kernels
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
                flags = self.state[:, ACTIVE:LOST + 1].get()
                lost = np.flatnonzero(flags[:, LOST - ACTIVE])
                if lost.size:
                    index = cp.asarray(lost)
                    self.p[index, :n, :n] = fresh(self.separation)[index]
                    self.state[index, LOST] = 0.0
                    self.state[index, ACTIVE] = 1.0
                elif not flags[:, 0].any():
                    break
            out, last = self.out.get(), self.p[:, :n, :n].get()
        force, approach, area, iterations, residual = out.transpose(1, 0, 2)
        return force, approach, area, iterations.astype(np.int64), residual, last
