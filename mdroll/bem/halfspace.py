"""The elastic half-space's surface response to pressure on square cells, free (non-periodic).

A pressure p_kl uniform on each square cell of side dx, on an N x N grid, displaces the surface
of an elastic half-space of composite modulus E* (physics.md section 1, eq 1-2) normally by

    u_ij = sum_kl K(x_i - x_k, y_j - y_l) p_kl                          (m; positive into the body)

with K Love's (1929) closed form for a uniform pressure on a rectangle (:func:`love_coefficient`).
The sum is a linear (not circular) convolution: the pressure is zero-padded to 2N x 2N and the
kernel sampled at the lags -N < i < N of that grid (Hockney's image decoupling), so one real FFT
pair of the padded grid gives the exact discrete sum on the N x N grid, without periodic images.

Arrays are NumPy on the CPU and CuPy on CUDA: the functions take the array module ``xp``.
"""

from __future__ import annotations

import numpy as np


def _love_term(s, t_plus, t_minus):
    """``s (asinh(t+ / |s|) - asinh(t- / |s|))``, 0 where s = 0 (its limit): one of the four
    terms of :func:`love_coefficient`, in the asinh form, which does not cancel far from the cell
    (``ln(t + sqrt(t^2 + s^2)) = asinh(t / |s|) + ln |s|``)."""
    s = np.asarray(s, dtype=np.float64)
    magnitude = np.where(s == 0.0, 1.0, np.abs(s))
    return np.where(s == 0.0, 0.0, s * (np.arcsinh(t_plus / magnitude) - np.arcsinh(t_minus / magnitude)))


def love_coefficient(x, y, half_x, half_y, E_star):
    """Love's influence coefficient: the normal surface displacement at (x, y) of an elastic
    half-space under a unit pressure uniform on the rectangle ``|x'| <= c, |y'| <= b`` (Johnson,
    *Contact Mechanics*, 1985, section 3.2), for two bodies of composite modulus E*::

        K = 1 / (pi E*) [ (x + c) ln(((y + b) + r(x+c, y+b)) / ((y - b) + r(x+c, y-b)))
                        + (y + b) ln(((x + c) + r(x+c, y+b)) / ((x - c) + r(x-c, y+b)))
                        + (x - c) ln(((y - b) + r(x-c, y-b)) / ((y + b) + r(x-c, y+b)))
                        + (y - b) ln(((x - c) + r(x-c, y-b)) / ((x + c) + r(x+c, y-b))) ],
        r(u, v) = sqrt(u^2 + v^2),

    evaluated as ``[f(x+c; y+b, y-b) + f(y+b; x+c, x-c) - f(x-c; y+b, y-b) - f(y-b; x+c, x-c)]
    / (pi E*)`` with ``f(s; t1, t2) = s (asinh(t1/|s|) - asinh(t2/|s|))``.

    Parameters: ``x``, ``y`` (m, arrays that broadcast), ``half_x`` c and ``half_y`` b the
    rectangle's half-sides (m), ``E_star`` (Pa). Returns K (m/Pa).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    total = (_love_term(x + half_x, y + half_y, y - half_y) + _love_term(y + half_y, x + half_x, x - half_x)
             - _love_term(x - half_x, y + half_y, y - half_y) - _love_term(y - half_y, x + half_x, x - half_x))
    return total / (np.pi * E_star)


def padded_kernel(n, dx, E_star, rows=None):
    """The influence coefficients of an n x n grid of square cells (side dx, m) on the padded
    grid of ``rows`` (default 2n; at least 2n - 1) by 2n cells, lag ``i`` at index ``i mod rows``
    (``i mod 2n`` along axis 1) for ``-n < i < n``; the other indices, never reached by pressure on
    the first n x n cells, hold the lags of :func:`numpy.fft.fftfreq`. Returns (rows, 2n) float64
    (m/Pa)."""
    rows = 2 * n if rows is None else rows
    lags_x = np.fft.fftfreq(rows, 1.0 / rows) * dx
    lags_y = np.fft.fftfreq(2 * n, 1.0 / (2 * n)) * dx
    return love_coefficient(lags_x[:, None], lags_y[None, :], 0.5 * dx, 0.5 * dx, E_star)


class HalfSpace:
    """The displacement operator ``u = K * p`` of an n x n grid (spacing dx, m), free boundary,
    on batches of pressures (..., n, n) in the array module ``xp``.

    The kernel is even in both lags, so its DFT is real: ``spectrum`` holds the (2n, n + 1) real
    half spectrum. One :meth:`displacement` is one forward and one inverse real 2-D FFT of the
    2n x 2n padded grid, each pruned to the rows that are not zero (forward: rows along axis -1
    on the n nonzero rows only; inverse: the axis -2 transform first, then axis -1 on the n rows
    that are kept).
    """

    def __init__(self, n: int, dx: float, E_star: float, xp=np):
        self.n = n
        self.dx = dx
        self.E_star = E_star
        self.xp = xp
        spectrum = np.fft.rfft2(padded_kernel(n, dx, E_star)).real
        self.spectrum = xp.asarray(spectrum)

    def displacement(self, pressure):
        """``u_ij = sum_kl K_(i-k)(j-l) p_kl`` (m) for pressures (..., n, n) (Pa)."""
        xp, n = self.xp, self.n
        rows = xp.fft.rfft(pressure, n=2 * n, axis=-1)
        transform = xp.fft.fft(rows, n=2 * n, axis=-2) * self.spectrum
        back = xp.fft.ifft(transform, axis=-2)[..., :n, :]
        return xp.fft.irfft(back, n=2 * n, axis=-1)[..., :n]
