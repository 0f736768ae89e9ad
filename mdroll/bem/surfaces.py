"""Rough surfaces for the boundary-element reference: a profile extruded across the track, and
random self-affine surfaces, isotropic or anisotropic, reproducible from (seed, index).

Grid: ``h[i, j]`` at ``x = i dx`` along the track (axis 0) and ``y = j dx`` across it (m).
Areal spectra are two-sided and normalized as in :mod:`mdroll.roughness.models`:
``<h^2> = integral d^2q C_2D(q)``, wavenumbers in rad/m; the MDR line with the same statistics
follows from Geike's rule ``C_1D(q) = pi |q| C_2D(|q|)`` (:data:`mdroll.roughness.GEIKE_LAMBDA`).
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..physics import TWO_PI
from .solver import array_module


def generator(seed: int, index: int) -> np.random.Generator:
    """The random generator of realization ``index`` under the master ``seed``: Philox keyed by
    ``SeedSequence((seed, index))``, so a surface depends on (seed, index) alone, whatever the
    batch it is made in."""
    for name, value in (("seed", seed), ("index", index)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < 2**64:
            raise ParameterError(f"{name} must be an integer in [0, 2^64), got {value!r}")
    return np.random.Generator(np.random.Philox(np.random.SeedSequence((int(seed), int(index)))))


def extruded(profile, width: int):
    """Case (a): a profile constant across the track, ``h[i, j] = profile[i]`` for j < width.

    Parameters: ``profile`` (L,) or (B, L) (m; e.g. lines of :func:`mdroll.rough_lines`),
    ``width`` cells across. Returns (L, width) or (B, L, width) float64 (m).
    """
    profile = np.asarray(profile, dtype=np.float64)
    if profile.ndim not in (1, 2) or isinstance(width, bool) or not isinstance(width, (int, np.integer)) or width < 1:
        raise ParameterError(f"extruded needs a profile (L,) or (B, L) and a width >= 1, got shape "
                             f"{profile.shape} and width {width!r}")
    return np.repeat(profile[..., None], width, axis=-1)


def areal_psd(qx, qy, H, q_min, q_max, anisotropy=1.0):
    """The self-affine areal PSD up to its level, ``C_2D ~ q_e^(-2H-2)`` for
    ``q_min <= q_e <= q_max`` (0 elsewhere), with the stretched wavenumber
    ``q_e = sqrt(q_x^2 + (q_y / gamma)^2)``, gamma = ``anisotropy`` >= 1.

    gamma = 1 is isotropic, case (b); gamma > 1, case (c), puts the cutoff across the track at
    gamma q_min: the correlation length across the track is 1/gamma of that along it.
    Parameters: ``qx``, ``qy`` (rad/m, broadcasting), ``H``, ``q_min``, ``q_max`` (rad/m),
    ``anisotropy``. Returns C_2D up to a constant (m^4 per unit level).
    """
    q = np.sqrt(qx * qx + (qy / anisotropy) ** 2)
    inside = (q >= q_min) & (q <= q_max)
    return np.where(inside, np.where(inside, q, 1.0) ** (-2.0 * H - 2.0), 0.0)


def self_affine(shape, dx, *, H, q_min, rms, seed, indices, q_max=None, anisotropy=1.0, device="cpu"):
    """Cases (b) and (c): random self-affine surfaces with the areal PSD of :func:`areal_psd`.

    On the grid of ``shape = (Lx, Ly)`` cells (wavenumbers ``2 pi k / (L dx)`` per axis),

        h = Re( sum_q sqrt(C_2D(q)) exp(i (q . r + phi_q)) ) * s,

    phi_q uniform in [0, 2 pi) from :func:`generator` (seed, index), made by one inverse 2-D
    FFT; the scale s makes the RMS over the grid exactly ``rms``.

    Parameters: ``shape`` (Lx, Ly) cells; ``dx`` (m); ``H`` Hurst exponent in (0, 1); ``q_min``,
    ``q_max`` (rad/m; q_max defaults to the Nyquist pi / dx); ``rms`` (m); ``seed``; ``indices``
    an int or a sequence of realization indices; ``anisotropy`` gamma >= 1; ``device`` where the
    inverse FFT runs: ``"cpu"`` (NumPy) or ``"cuda"``/``"cuda:N"`` (CuPy; the phases are drawn on
    the host either way, so a surface is the same on every device to rounding).
    Returns (Lx, Ly) for an int index, else (B, Lx, Ly), float64 (m), NumPy or CuPy.
    """
    if not (len(shape) == 2 and all(isinstance(s, (int, np.integer)) and s >= 2 for s in shape)):
        raise ParameterError(f"shape must be two cell counts >= 2, got {shape!r}")
    if not 0.0 < H < 1.0 or not rms > 0 or not dx > 0 or not q_min > 0 or not anisotropy >= 1.0:
        raise ParameterError(f"self_affine needs 0 < H < 1, rms > 0, dx > 0, q_min > 0 and anisotropy >= 1, got "
                             f"H={H!r}, rms={rms!r}, dx={dx!r}, q_min={q_min!r}, anisotropy={anisotropy!r}")
    q_max = np.pi / dx if q_max is None else q_max
    qx = TWO_PI * np.fft.fftfreq(shape[0], dx)
    qy = TWO_PI * np.fft.fftfreq(shape[1], dx)
    amplitude = np.sqrt(areal_psd(qx[:, None], qy[None, :], H, q_min, q_max, anisotropy))
    if not amplitude.any():
        raise ParameterError(f"no grid wavenumber lies in [q_min, q_max] = [{q_min!r}, {q_max!r}] rad/m")
    single = isinstance(indices, (int, np.integer))
    xp, context = array_module(device)
    surfaces = []
    with context:
        for index in [indices] if single else list(indices):
            phase = generator(seed, index).uniform(0.0, TWO_PI, size=shape)
            surface = xp.fft.ifft2(xp.asarray(amplitude * np.exp(1j * phase))).real
            surfaces.append(surface * (rms / xp.sqrt(xp.mean(surface * surface))))
        return surfaces[0] if single else xp.stack(surfaces)
