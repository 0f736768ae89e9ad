"""Random rough lines with the 1D MDR power spectrum (physics.md section 3; eq 16-17, 33, 50)."""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np

from ..devices import is_cuda, resolve_device, to_warp, warp
from ..arguments import check_params
from ..errors import ParameterError
from ..params import Params
from ..roughness.kinds import check_spectrum
from .. import buffers
from .batching import check_count_fits
from .realizations import check_count
from ..fft import irfft_rows

#: Modes a thread of the CPU's random spectrum makes (:func:`mdroll.kernels.lines.random_phase_spans`).
CPU_SPAN = 4096


#: The largest realization index (an int64).
MAX_INDEX = 2**63 - 1


def realization_indices(realizations) -> np.ndarray:
    """``int R`` -> 0..R-1; a sequence of distinct non-negative integers -> those indices (int64)."""
    if isinstance(realizations, (bool, np.bool_)):
        raise ParameterError(f"realizations must be an int or a sequence of ints, got {realizations!r}")
    if isinstance(realizations, (int, np.integer)):
        count = check_count("realizations", realizations)
        check_count_fits(count)
        return np.arange(count, dtype=np.int64)
    if not isinstance(realizations, (Sequence, np.ndarray, range)):
        raise ParameterError(f"realizations must be an int or a sequence of ints, got {type(realizations).__name__}")
    if isinstance(realizations, range):
        check_count_fits(len(realizations))
        if len(realizations) and max(realizations[0], realizations[-1]) > MAX_INDEX:
            raise ParameterError(f"realizations {realizations.start}..{realizations.stop - 1} is not allowed: an "
                                 f"index must be at most {MAX_INDEX} (2^63 - 1)")
    indices = np.asarray(realizations)
    if indices.ndim != 1 or indices.size == 0 or not np.issubdtype(indices.dtype, np.integer):
        raise ParameterError(f"realizations must be a non-empty 1D sequence of integers, got {realizations!r}")
    if indices.min() < 0:
        raise ParameterError(f"realizations must be non-negative indices, got minimum {indices.min()}")
    unique, counts = np.unique(indices, return_counts=True)
    if unique.size != indices.size:
        twice = int(np.argmax(counts > 1))
        raise ParameterError(f"realizations must not repeat an index (it would count twice): "
                             f"{int(unique[twice])} is given {int(counts[twice])} times")
    return indices.astype(np.int64)


def check_seed(seed) -> int:
    """The seed as an int in [0, 2^64), or a ParameterError naming it."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise ParameterError(f"seed must be an integer in [0, 2^64), got {seed!r}")
    if not 0 <= int(seed) < 2**64:
        raise ParameterError(f"seed = {seed!r} is not allowed: it must lie in [0, 2^64)")
    return int(seed)


def rough_lines(params: Params, seed: int, realizations, device: str = "cpu", roughness=None):
    """Rough lines h_r(x_i), one per realization, with RMS exactly ``params.h0`` (m), or with the
    absolute level of their spectrum.

    Exactly physics.md section 3. On the grid ``x_i = i dx`` (i = 0..n-1, ``n = params.n_points``)
    and wavenumbers ``q_k = 2 pi k / L`` (L = n dx),

        h(x) = sum_k B(q_k) exp(i (q_k x + phi_k)),   B(q) = sqrt(2 pi / L * C_1D(q)),
        C_1D(q) = lambda A |q|^(-2H-1) for q_min <= |q| <= q_max, else 0   (eq 33, two-sided),

    with fixed amplitudes and random phases phi_k uniform in [0, 2 pi) (eq 16-17), made by one
    inverse real FFT; each line is scaled so that its RMS over the n points is exactly h0 (to
    rounding), which fixes lambda A (eq 50; :attr:`Params.lambda_A`). The scale is set on the
    spectrum by Parseval's theorem (:func:`mdroll.kernels.lines.line_scales`), not by a pass
    over the line.

    The phase of mode k of realization j is a hash of (seed, j, k) alone (a counter-based
    generator, :func:`mdroll.kernels.lines.uniform_from_key`), so a line is the same to
    rounding whatever the batch it is made in and whatever the device.

    Any other spectrum (``params.roughness`` other than "powerlaw", or a ``roughness`` model of
    :mod:`mdroll.roughness`) replaces C_1D: its amplitudes ``B(q_k)`` on the grid are computed once
    per call on the host (:func:`mdroll.roughness.line_grid.mode_amplitude_table`) and uploaded; the
    phases are the same hashes, so lines stay reproducible from (seed, index). With the "rms" level
    (:func:`mdroll.roughness.line_grid.resolve_level`) each line is scaled to RMS h0 as above; with
    "absolute" it keeps the spectrum's level (its expected mean square ``2 dq sum_k C(q_k)``).

    Parameters
    ----------
    params : Params
    seed : int
        Master seed in [0, 2^64).
    realizations : int or sequence of int
        ``R`` for indices 0..R-1, or the realization indices themselves.
    device : str
        ``"cpu"``, ``"cuda"``, ``"cuda:N"`` or ``"auto"``.
    roughness : mdroll.roughness.kinds.RoughnessSpectrum, optional
        A spectrum instead of the one the roughness fields of ``params`` name (any model, a
        callable included).

    Returns
    -------
    lines : (R, n) float64, metres
        A NumPy array on the CPU; a Warp array (``.numpy()``, CuPy via ``cupy.asarray``) on CUDA.
    """
    device = resolve_device(device)
    return irfft_rows(random_spectra(params, seed, realizations, device, roughness), params.n_points, device)


def random_spectra(params: Params, seed: int, realizations, device: str, roughness=None):
    """The (R, n/2 + 1) half spectra (``wp.vec2d``, on ``device``) whose unnormalized inverse
    real FFTs (:func:`mdroll.fft.irfft_rows`) are the lines of :func:`rough_lines`,
    already scaled to RMS h0 (or at their absolute level)."""
    from ..kernels.lines import line_scales, random_phase_spans, random_phase_spectrum
    from ..roughness.line_grid import from_params, mode_amplitude_table, resolve_level

    wp = warp()
    check_params(params)
    check_spectrum(roughness)
    seed = check_seed(seed)
    indices = realization_indices(realizations)
    n = params.n_points
    bins = n // 2 + 1
    absolute = 0
    if roughness is None and params.roughness == "powerlaw":
        # the default spectrum (eq 33): its amplitudes made on the device, no table to upload
        k_first, k_last = params.mode_range
        nyquist = n // 2 if n % 2 == 0 and k_last == n // 2 else -1
        amplitudes, sum_of_squares = _power_law_amplitudes(bins, k_first, k_last, params.H, device)
    else:
        spectrum = from_params(params) if roughness is None else roughness
        table = mode_amplitude_table(params, spectrum)
        absolute = int(resolve_level(params, spectrum) == "absolute")
        nyquist = n // 2 if n % 2 == 0 and table[n // 2] != 0.0 else -1
        amplitudes = wp.array(table, dtype=wp.float64, device=device)
        sum_of_squares = _sum_of_squares(amplitudes, device)
    rows = wp.array(indices, dtype=wp.int64, device=device)
    scales = wp.empty(indices.size, dtype=wp.float64, device=device)
    keys = wp.empty(indices.size, dtype=wp.uint64, device=device)
    wp.launch(line_scales, dim=indices.size,
              inputs=[rows, wp.uint64(seed), amplitudes, nyquist, sum_of_squares, params.h0, absolute, scales, keys], device=device)
    spectrum = buffers.empty("spectrum", (indices.size, bins), wp.vec2d, device, aligned=True)
    if is_cuda(device):
        wp.launch(random_phase_spectrum, dim=(indices.size, (bins + 1) // 2),
                  inputs=[keys, amplitudes, nyquist, scales, spectrum], device=device)
    else:
        wp.launch(random_phase_spans, dim=(indices.size, -(-bins // CPU_SPAN)),
                  inputs=[keys, amplitudes, nyquist, scales, CPU_SPAN, spectrum], device=device)
    return spectrum


def parametric_line(params: Params, track, device: str):
    """The moving load's equivalent roughness, exact at the run's speed
    (:func:`mdroll.track.parametric.equivalent_roughness` at the static load F_N and the speed v0,
    x_i = i dx, x = 0 above a support) as a Warp array on ``device``, for :func:`add_line`; None
    unless ``track`` asks for it (``track.parametric``)."""
    if track is None or not track.parametric:
        return None
    from ..track.parametric import equivalent_roughness

    line = equivalent_roughness(track, params.F_N, np.arange(params.n_points) * params.dx, speed=params.v0)
    return warp().array(line, dtype=warp().float64, device=device)


def add_line(lines, line, device: str):
    """``lines`` (R, n) with the deterministic ``line`` (n) added to every row, in place (a Warp
    view of them); ``lines`` unchanged where ``line`` is None."""
    if line is None:
        return lines
    from ..kernels.lines import add_to_rows

    lines = to_warp(lines, device)
    warp().launch(add_to_rows, dim=lines.shape, inputs=[lines, line], device=device)
    return lines


@functools.lru_cache(maxsize=8)
def _power_law_amplitudes(bins: int, k_first: int, k_last: int, H: float, device: str):
    """The amplitudes ``a_k`` of the default spectrum on ``bins`` modes (eq 33, up to the line's
    scale; :func:`mdroll.kernels.lines.mode_amplitudes`) and their sum of squares, on ``device``:
    the same for every batch of a run, so made once (a power a mode)."""
    from ..kernels.lines import mode_amplitudes

    wp = warp()
    amplitudes = wp.empty(bins, dtype=wp.float64, device=device)
    wp.launch(mode_amplitudes, dim=bins, inputs=[k_first, k_last, -(H + 0.5), amplitudes], device=device)
    return amplitudes, _sum_of_squares(amplitudes, device)


def _sum_of_squares(amplitudes, device: str):
    """Parseval's sum of the very amplitudes the spectra use, kept on the device (a 1-array)."""
    wp = warp()
    total = wp.empty(1, dtype=wp.float64, device=device)
    wp.utils.array_inner(amplitudes, amplitudes, out=total)
    return total
