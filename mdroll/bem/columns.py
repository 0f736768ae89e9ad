"""The column transform of the fused solver (:mod:`mdroll.bem.fused`) on CUDA: the middle of a
convolution ``K * x`` of an n x n grid, between the real FFTs of its rows.

The rows' spectra (B, n, n + 1) are taken column by column: each column, zero-padded to M rows (the
power of two >= 2n - 1, so the linear convolution's lags -n < i < n do not wrap), is transformed by
Stockham passes of radix 8 (then one of 4 or 2) in shared memory, multiplied by the kernel's real
spectrum on the M x 2n grid (:func:`mdroll.bem.halfspace.padded_kernel`, scaled by 1 / (2n M) for
the unnormalised inverse transforms) and transformed back; its first n rows are written back in
place. One kernel does it all, so the padded rows are never stored.
"""

from __future__ import annotations

import numpy as np

from .halfspace import padded_kernel

#: Columns of the row spectra per block.
COLUMNS = 2
#: Threads per block (a radix-8 pass of 512 rows: 64 a column).
COLUMN_THREADS = 128
#: Largest window (cells across) on CUDA: the transform's shared memory (below 227 KiB a block).
MAX_CELLS = 1024

COLUMN_SOURCE = f"#define COLUMNS {COLUMNS}\n" + r"""
__device__ double2 times(double2 a, double2 b) { return make_double2(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x); }
__device__ double2 plus(double2 a, double2 b) { return make_double2(a.x + b.x, a.y + b.y); }
__device__ double2 minus(double2 a, double2 b) { return make_double2(a.x - b.x, a.y - b.y); }
// a times i sign
__device__ double2 turn(double2 a, double sign) { return make_double2(-sign * a.y, sign * a.x); }

// the R-point DFT of v in registers, natural order in and out: exp(sign 2 pi i r k / R)
template <int R> __device__ void dft(double2* v, double sign);
template <> __device__ void dft<2>(double2* v, double sign) {
    const double2 a = v[0];
    v[0] = plus(a, v[1]); v[1] = minus(a, v[1]);
}
template <> __device__ void dft<4>(double2* v, double sign) {
    const double2 a0 = plus(v[0], v[2]), a1 = minus(v[0], v[2]), a2 = plus(v[1], v[3]),
                  a3 = turn(minus(v[1], v[3]), sign);
    v[0] = plus(a0, a2); v[1] = plus(a1, a3); v[2] = minus(a0, a2); v[3] = minus(a1, a3);
}
template <> __device__ void dft<8>(double2* v, double sign) {
    const double h = 0.70710678118654752440;
    const double2 a0 = plus(v[0], v[4]), a1 = minus(v[0], v[4]), a2 = plus(v[2], v[6]), a3 = minus(v[2], v[6]),
                  a4 = plus(v[1], v[5]), a5 = minus(v[1], v[5]), a6 = plus(v[3], v[7]), a7 = minus(v[3], v[7]);
    const double2 b0 = plus(a0, a2), b1 = plus(a1, turn(a3, sign)), b2 = minus(a0, a2),
                  b3 = minus(a1, turn(a3, sign)), b4 = plus(a4, a6), b5 = plus(a5, turn(a7, sign)),
                  b6 = minus(a4, a6), b7 = minus(a5, turn(a7, sign));
    const double2 t1 = times(make_double2(h, sign * h), b5), t2 = turn(b6, sign),
                  t3 = times(make_double2(-h, sign * h), b7);
    v[0] = plus(b0, b4); v[1] = plus(b1, t1); v[2] = plus(b2, t2); v[3] = plus(b3, t3);
    v[4] = minus(b0, b4); v[5] = minus(b1, t1); v[6] = minus(b2, t2); v[7] = minus(b3, t3);
}

// one Stockham pass of radix R over the block's columns (element i of column c at i * COLUMNS + c),
// from a to b: sub-transforms of length Ns become R Ns long; twiddle[k] = exp(-2 pi i k / M), k < M
template <int R>
__device__ void pass(const double2* a, double2* b, const double2* twiddle, int M, int Ns, double sign) {
    const int T = M / R, step = M / (Ns * R);
    for (int u = threadIdx.x; u < COLUMNS * T; u += blockDim.x) {
        const int c = u % COLUMNS, j = u / COLUMNS, k = j % Ns;
        double2 v[R];
#pragma unroll
        for (int r = 0; r < R; ++r) {
            const double2 w = twiddle[k * r * step];
            v[r] = times(a[(j + r * T) * COLUMNS + c], make_double2(w.x, sign * -w.y));
        }
        dft<R>(v, sign);
        const int base = (j / Ns) * Ns * R + k;
#pragma unroll
        for (int r = 0; r < R; ++r) b[(base + r * Ns) * COLUMNS + c] = v[r];
    }
}

// the block's columns in a transformed (b the scratch buffer): exp(sign 2 pi i ...); the buffer that
// holds the result, in natural order
__device__ double2* transform(double2* a, double2* b, const double2* twiddle, int bits, double sign) {
    for (int Ns = 1, left = bits; left > 0;) {
        __syncthreads();
        if (left >= 3) { pass<8>(a, b, twiddle, 1 << bits, Ns, sign); Ns *= 8; left -= 3; }
        else if (left == 2) { pass<4>(a, b, twiddle, 1 << bits, Ns, sign); Ns *= 4; left -= 2; }
        else { pass<2>(a, b, twiddle, 1 << bits, Ns, sign); Ns *= 2; left -= 1; }
        double2* swap = a; a = b; b = swap;
    }
    __syncthreads();
    return a;
}

// the columns of the row spectra C (B, n, n + 1), COLUMNS per block: each zero-padded to M = 2^bits
// rows, transformed (Stockham, radix 8 then 4 or 2), multiplied by the kernel's spectrum W
// (n + 1, M), transformed back, its first n rows written back. Shared memory: the columns twice
// (2 COLUMNS M double2), the twiddles (M double2) and the block's spectrum (COLUMNS M double), all
// read from global memory at the start. A member that is not active is skipped
extern "C" __global__ void columns(double2* C, const double* W, const double2* twiddle, const double* st, int n,
                                   int bits) {
    extern __shared__ double2 x[];
    if (st[(long long)blockIdx.y * FIELDS + ACTIVE] == 0.0) return;
    const int M = 1 << bits, k0 = blockIdx.x * COLUMNS;
    double2* own = C + (long long)blockIdx.y * n * (n + 1);
    double2* turns = x + 2 * COLUMNS * M;
    double* weights = (double*)(turns + M);
    for (int idx = threadIdx.x; idx < COLUMNS * M; idx += blockDim.x) {
        const int c = idx % COLUMNS, row = idx / COLUMNS, k = k0 + c;
        x[idx] = row < n && k <= n ? own[(long long)row * (n + 1) + k] : make_double2(0.0, 0.0);
        weights[idx] = k <= n ? W[(long long)k * M + row] : 0.0;
    }
    for (int idx = threadIdx.x; idx < M; idx += blockDim.x) turns[idx] = twiddle[idx];
    double2* a = transform(x, x + COLUMNS * M, turns, bits, -1.0);
    double2* b = a == x ? x + COLUMNS * M : x;
    for (int idx = threadIdx.x; idx < COLUMNS * M; idx += blockDim.x) {
        a[idx].x *= weights[idx]; a[idx].y *= weights[idx];
    }
    a = transform(a, b, turns, bits, 1.0);
    for (int idx = threadIdx.x; idx < COLUMNS * n; idx += blockDim.x) {
        const int c = idx % COLUMNS, row = idx / COLUMNS, k = k0 + c;
        if (k <= n) own[(long long)row * (n + 1) + k] = a[idx];
    }
}
"""


def column_rows(n: int) -> int:
    """M, the rows of the column transform of an n x n grid: the power of two >= 2n - 1 (a linear
    convolution's lags -n < i < n, without wrapping)."""
    return 1 << (2 * n - 2).bit_length()


def column_spectrum(op, rows: int):
    """The kernel's real spectrum on the ``rows`` x 2n padded grid, as (n + 1, rows) (one column of
    the row spectra a row), scaled by 1 / (2n rows) for the unnormalised inverse transforms."""
    n = op.n
    spectrum = np.fft.rfft2(padded_kernel(n, op.dx, op.E_star, rows=rows)).real
    return np.ascontiguousarray(spectrum.T / (2.0 * n * rows))


def shared_bytes(rows: int) -> int:
    """Shared memory of a block (bytes): its columns twice, the twiddles and its spectrum."""
    return (2 * COLUMNS + 1) * rows * 16 + COLUMNS * rows * 8
