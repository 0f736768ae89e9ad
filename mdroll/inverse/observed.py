"""Averaged spectra to invert, and their readers (mdroll ``spectra.npz``, CSV and NPZ tables).

Every spectrum is held in one canonical form: angular frequency omega (rad/s, positive,
strictly increasing) and the **two-sided PSD per rad/s** of physics.md sections 3 and 6,
``<x^2> = integral over all omega (both signs) of C(omega) d omega``, with
``C(omega) = C(q) / v0`` at ``omega = q v0``. Units: (m/s^2)^2 s/rad for the acceleration,
N^2 s/rad for the force. Conversions from a table's declared convention:

    omega = 2 pi f                         (frequency in Hz)
    C_per_rad/s = C_per_Hz / (2 pi)        (since integral C df = integral C d omega, d omega = 2 pi df)
    C_two_sided = G_one_sided / 2          (the one-sided G carries both signs' power on f > 0)

and the same factors for a column of standard errors.
"""

from __future__ import annotations

import json
import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..arguments import check_integer
from ..ensemble.result import EnsembleResult
from ..ensemble.vibration import structures_of
from ..checks import first_negative_or_nonfinite
from ..files import atomic_write
from ..errors import ParameterError
from ..params import Params
from ..physics import TWO_PI
from .track_model import KnownTrack

QUANTITIES = ("accel", "force")
FREQUENCY_UNITS = ("Hz", "rad/s")
SIDES = ("one", "two")
DENSITIES = ("Hz", "rad/s")


def _choice(name: str, value, allowed) -> str:
    if value not in allowed:
        raise ParameterError(f"{name} = {value!r} is not allowed: use one of {', '.join(map(repr, allowed))}")
    return value


@dataclass(frozen=True)
class Spectrum:
    """An averaged PSD to invert, in the canonical form of this module.

    Attributes
    ----------
    omega : (n,) angular frequencies, rad/s, positive and strictly increasing.
    psd : (n,) two-sided PSD per rad/s, finite and >= 0: (m/s^2)^2 s/rad (``quantity="accel"``)
        or N^2 s/rad (``"force"``).
    quantity : "accel" or "force".
    passes : number K of averaged passes (realizations), or None when unknown.
    stderr : (n,) standard errors of ``psd`` (same units), or None.
    v0 : rolling speed (m/s) when the source states it (an mdroll spectrum), else None.
    dt : sample interval of the series (s) when known: the wheel's response is then the
        semi-implicit Euler one of the simulation (section 5.1), else the continuous one.
    window : True when the series had the Hann window of section 6 (the expected periodogram
        is then the spectrum smoothed by the 3-bin stencil [1/6, 2/3, 1/6]).
    line_length : length L of the generated rough line (m) when known (mdroll): eq 50 is then
        normalized on its grid 2 pi k / L, else in the continuum limit.
    truth : the generating parameters of an mdroll spectrum (a dict), kept only to compare
        estimates with; the fit never reads it.
    source : where it came from, for the record.
    unresolved : (n,) bool, True at the bins the record cannot resolve (an mdroll spectrum,
        :mod:`mdroll.ensemble.resolution`), or None when unknown.
    known_track : the track and wheel under the contact (:class:`~mdroll.inverse.track_model.KnownTrack`:
        a coupled mdroll run on a track records them; or given), or None: the rigid rail.
    """

    omega: np.ndarray
    psd: np.ndarray
    quantity: str = "accel"
    passes: int | None = None
    stderr: np.ndarray | None = None
    v0: float | None = None
    dt: float | None = None
    window: bool = False
    line_length: float | None = None
    truth: dict | None = None
    source: str = ""
    simulation: dict = field(default_factory=dict)
    unresolved: np.ndarray | None = None
    known_track: KnownTrack | None = None

    def __post_init__(self) -> None:
        _choice("quantity", self.quantity, QUANTITIES)
        omega = np.asarray(self.omega, dtype=np.float64)
        psd = np.asarray(self.psd, dtype=np.float64)
        object.__setattr__(self, "omega", omega)
        object.__setattr__(self, "psd", psd)
        if omega.ndim != 1 or psd.shape != omega.shape:
            raise ParameterError(f"frequency and PSD must be 1-D of the same length, got shapes {omega.shape} and {psd.shape}")
        if omega.size == 0:
            raise ParameterError("the spectrum has no rows")
        _check_frequencies(omega)
        _check_values("psd", psd, omega)
        if self.stderr is not None:
            err = np.asarray(self.stderr, dtype=np.float64)
            if err.shape != omega.shape:
                raise ParameterError(f"stderr must have the PSD's shape {omega.shape}, got {err.shape}")
            _check_values("stderr", err, omega)
            object.__setattr__(self, "stderr", err)
        if self.passes is not None:
            check_integer("passes", self.passes, 1, "averaged passes", MAX_PASSES)
        for name in ("v0", "dt", "line_length"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ParameterError(f"{name} = {value!r} is not allowed: it must be positive and finite")
        if self.window and not self.uniform:
            raise ParameterError("window = True needs a uniform frequency grid omega_k = k d omega (the Hann stencil "
                                 "acts between neighbouring bins)")

    @property
    def uniform(self) -> bool:
        """True when omega_k = k d omega for integers k (a DFT grid)."""
        if self.omega.size < 2:
            return False
        step = self.omega[1] - self.omega[0]
        k = self.omega / step
        return bool(np.allclose(k, np.rint(k), atol=1e-6) and np.allclose(np.diff(self.omega), step, rtol=1e-6))


def _check_frequencies(omega: np.ndarray) -> None:
    bad = ~np.isfinite(omega)
    if bad.any():
        i = int(np.argmax(bad))
        raise ParameterError(f"frequency at row {i} is {omega[i]!r}: frequencies must be finite")
    if (omega <= 0).any():
        i = int(np.argmax(omega <= 0))
        raise ParameterError(f"frequency at row {i} is {omega[i]:.6g} rad/s: frequencies must be positive "
                             "(a leading zero-frequency row is dropped by the readers)")
    steps = np.diff(omega)
    if (steps <= 0).any():
        i = int(np.argmax(steps <= 0)) + 1
        raise ParameterError(f"frequencies are not strictly increasing at row {i} ({omega[i]:.6g} rad/s after "
                             f"{omega[i - 1]:.6g} rad/s)")


def _check_values(name: str, values: np.ndarray, omega: np.ndarray) -> None:
    i = first_negative_or_nonfinite(values)
    if i is not None:
        raise ParameterError(f"{name} at row {i} (omega = {omega[i]:.6g} rad/s) is {values[i]!r}: a {name} must be "
                             "finite and >= 0")


def from_result(result, quantity: str = "accel", window: bool | None = None) -> Spectrum:
    """The spectrum of an :class:`mdroll.EnsembleResult` (two-sided per rad/m on q, section 6),
    as two-sided per rad/s on omega = q v0: ``C(omega) = C(q) / v0``. The q = 0 bin is dropped.

    ``window``: whether the run used the Hann window; None (default): as the result records it
    (a file from before the window was recorded: no window). ``unresolved`` holds the bins the
    record cannot resolve (:mod:`mdroll.ensemble.resolution`).
    """
    if not isinstance(result, EnsembleResult):
        raise ParameterError(f"result must be an mdroll.EnsembleResult, got {type(result).__name__}")
    if window is None:
        window = bool(result.window)
    _choice("quantity", quantity, QUANTITIES)
    p: Params = result.params
    psd = getattr(result, f"{quantity}_psd")
    err = getattr(result, f"{quantity}_psd_stderr")
    keep = result.q > 0
    unresolved = result.resolution.mask(quantity)[keep]
    return Spectrum(omega=result.omega[keep], psd=psd[keep] / p.v0, quantity=quantity, passes=int(result.n_real),
                    unresolved=unresolved,
                    stderr=err[keep] / p.v0 if result.n_real > 1 else None, v0=p.v0, dt=p.dt, window=bool(window),
                    line_length=p.length, truth=_truth(p), source="mdroll ensemble",
                    simulation={"boundary": result.boundary, "mode": result.mode, "algorithm": result.algorithm,
                                "seed": result.seed, "L": p.L, "dx": p.dx, "q_max": p.q_max, "E": p.E, "nu": p.nu},
                    known_track=KnownTrack(*structures_of(result)) if result.track or result.wheel else None)


def _truth(p: Params) -> dict:
    return {"H": p.H, "q_min": p.q_min, "q_max": p.q_max, "a": p.a, "E_star": p.E_star, "h0": p.h0, "R": p.R,
            "m": p.m, "v0": p.v0, "F_N": p.F_N, "lambda_A": p.lambda_A, "omega_0": p.omega_0}


def read_spectrum(path, quantity: str | None = None, window: bool | None = None, frequency_unit: str | None = None,
                  sided: str | None = None, density: str | None = None, passes: int | None = None) -> Spectrum:
    """Read an mdroll ``spectra.npz`` (it has ``q`` and ``meta``) or a table (:func:`read_table`).

    For an mdroll file ``quantity`` (default "accel") picks the acceleration or force PSD, and
    its own record says whether the run used the Hann window (``window`` True or False must agree
    with it); the table options must not be given. For a table ``window`` None means False.
    """
    path = _file(path)
    if path.suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as data:
                is_mdroll = "meta" in data.files and "q" in data.files
        except (OSError, EOFError, ValueError, zipfile.BadZipFile):
            raise ParameterError(f"{path} is not a readable NPZ file (truncated, or another format)") from None
        if is_mdroll:
            given = [n for n, v in (("frequency_unit", frequency_unit), ("sided", sided), ("density", density),
                                    ("passes", passes)) if v is not None]
            if given:
                raise ParameterError(f"{path} is an mdroll spectra.npz, whose units are known: {', '.join(given)} "
                                     "must not be given")
            result = EnsembleResult.load(path)
            return from_result(result, quantity or "accel", describable(result, path, window))
    return read_table(path, quantity=quantity, frequency_unit=frequency_unit, sided=sided, density=density,
                      passes=passes, window=bool(window))


def describable(result, path, window: bool | None) -> bool:
    """The window of the mdroll run at ``path``, after refusing what the forward model cannot
    describe (naming the file): a coupled run on the rigid rail (the model is the decoupled
    response of section 5.1; a coupled run on a track is the linear chain on its recorded track,
    :mod:`mdroll.inverse.track_model`), a roughness other than the power law (eq 33, the model's), a single realization (no
    spread to weigh the bins by), ``window`` that contradicts the run's record (a run that
    recorded no window at all takes the ``window`` given)."""
    if result.mode != "decoupled" and not (result.track or result.wheel):
        raise ParameterError(f"{path}: a {result.mode} run on the rigid rail; the inverse model is the decoupled "
                             "response (section 5.1) or the linear chain on a known track, so it would fit what it "
                             "cannot describe: invert a decoupled run or a coupled run on a track")
    if result.params.roughness != "powerlaw":
        raise ParameterError(f"{path}: roughness = {result.params.roughness!r}; the inverse model is the power law "
                             "of eq 33: invert a run with roughness = 'powerlaw'")
    if result.n_real < 2:
        raise ParameterError(f"{path}: one realization; the fit needs at least 2 averaged passes")
    if result.window is None:
        return bool(window)
    if window is not None and bool(window) != result.window:
        raise ParameterError(f"window = {window} for {path}, whose run was "
                             f"{'windowed' if result.window else 'not windowed'}: drop the window option")
    return bool(result.window)


def _file(path) -> Path:
    if not isinstance(path, (str, Path)):
        raise ParameterError(f"path must be a file name, got {type(path).__name__}")
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"spectrum file {str(path)!r} does not exist")
    return path


def read_table(path, quantity: str = "accel", frequency_unit: str | None = None, sided: str | None = None,
               density: str | None = None, passes: int | None = None, window: bool = False) -> Spectrum:
    """A table of frequency and PSD (optionally standard errors): CSV or NPZ.

    CSV: columns ``frequency, psd[, stderr]`` separated by commas, an optional header line, ``#``
    comments. NPZ: arrays ``frequency``, ``psd``, optional ``stderr``, and optionally the strings
    ``frequency_unit``, ``sided``, ``density``, ``quantity`` and the integer ``passes`` (what the
    arguments do not give). The convention must be declared, there is no default:
    ``frequency_unit`` "Hz" or "rad/s", ``sided`` "one" or "two", ``density`` "Hz" (per Hz) or
    "rad/s" (per rad/s); the PSD in SI units ((m/s^2)^2 or N^2 per unit frequency). A leading
    zero-frequency row is dropped. Converted as in the module docstring.
    """
    path = _file(path)
    declared: dict = {}
    if path.suffix == ".npz":
        columns = _read_npz(path, declared)
    elif path.suffix in (".csv", ".txt", ".tsv"):
        columns = _read_csv(path)
    else:
        raise ParameterError(f"{path}: unknown table format {path.suffix!r}; use .csv or .npz")
    frequency_unit = frequency_unit or declared.get("frequency_unit")
    sided = sided or declared.get("sided")
    density = density or declared.get("density")
    if quantity is not None and declared.get("quantity", quantity) != quantity:
        raise ParameterError(f"{path}: declares quantity {declared['quantity']!r}, but {quantity!r} was asked for")
    quantity = quantity or declared.get("quantity", "accel")
    passes = passes if passes is not None else declared.get("passes")
    if passes is not None and (isinstance(passes, bool) or not float(passes).is_integer()
                               or not 1 <= passes <= MAX_PASSES):
        raise ParameterError(f"{path}: passes = {passes!r} is not allowed: the number of averaged passes must be an "
                             f"integer from 1 to {MAX_PASSES}")
    for name, value, allowed in (("frequency_unit", frequency_unit, FREQUENCY_UNITS), ("sided", sided, SIDES),
                                 ("density", density, DENSITIES)):
        if value is None:
            raise ParameterError(f"{path}: {name} is not declared; give one of {', '.join(map(repr, allowed))}")
        _choice(name, value, allowed)
    return table_spectrum(*columns[:2], stderr=columns[2] if len(columns) > 2 else None, quantity=quantity,
                          frequency_unit=frequency_unit, sided=sided, density=density,
                          passes=None if passes is None else int(passes), window=window, source=str(path))


#: The most averaged passes K a spectrum may declare: more than any measurement campaign holds, and
#: what a bootstrap replicate or a correction ensemble simulates at most.
MAX_PASSES = 100_000
#: The largest table a fit reads (rows): a spectrum's bins, far more than any measured one has.
MAX_TABLE_ROWS = 1_000_000
#: The declared conventions an NPZ table may hold, each a text, and ``passes`` a number.
_DECLARED = ("frequency_unit", "sided", "density", "quantity", "passes")


def _read_npz(path: Path, declared: dict) -> list[np.ndarray]:
    """The columns of an NPZ table, its declarations into ``declared``; a truncated, pickled or
    malformed file is refused naming the file and the array."""
    try:
        with np.load(path, allow_pickle=False) as data:
            missing = [k for k in ("frequency", "psd") if k not in data.files]
            if missing:
                raise ParameterError(f"{path}: the table lacks the array(s) {missing} (it needs frequency and psd)")
            names = ["frequency", "psd"] + (["stderr"] if "stderr" in data.files else [])
            columns = [data[k] for k in names]
            for key in _DECLARED:
                if key in data.files:
                    value = data[key]
                    if value.size != 1:
                        raise ParameterError(f"{path}: {key} must be a single value, got an array of shape {value.shape}")
                    declared[key] = value.item()
    except ParameterError:
        raise
    except (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile):
        raise ParameterError(f"{path} is not a readable NPZ table (truncated, pickled objects or another format); it "
                             "needs the float arrays frequency and psd") from None
    for name, column in zip(names, columns):
        if column.ndim != 1 or column.dtype.kind not in "iuf":
            raise ParameterError(f"{path}: {name} must be a 1-D array of numbers, got {column.dtype} of shape "
                                 f"{column.shape}")
        if column.size != columns[0].size:
            raise ParameterError(f"{path}: {name} has {column.size} values, frequency {columns[0].size}")
        if column.size > MAX_TABLE_ROWS:
            raise ParameterError(f"{path}: {column.size} rows, more than the {MAX_TABLE_ROWS} a fit reads; bin the "
                                 "spectrum first")
    for key in ("frequency_unit", "sided", "density", "quantity"):
        if key in declared and not isinstance(declared[key], str):
            raise ParameterError(f"{path}: {key} must be a text, got {declared[key]!r}")
    if "passes" in declared and not isinstance(declared["passes"], (int, float)):
        raise ParameterError(f"{path}: passes must be a number, got {declared['passes']!r}")
    return columns


def _read_csv(path: Path) -> list[np.ndarray]:
    rows = []
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise ParameterError(f"{path}: not a text table (not UTF-8); a CSV of frequency, psd[, stderr]") from None
    for number, line in enumerate(text.splitlines(), start=1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        cells = [c.strip() for c in text.replace("\t", ",").split(",")]
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if not rows:  # a header line
                continue
            raise ParameterError(f"{path}, line {number}: {text!r} is not a row of numbers") from None
        if len(values) not in (2, 3) or (rows and len(values) != len(rows[0])):
            raise ParameterError(f"{path}, line {number}: expected 2 or 3 columns (frequency, psd[, stderr]) in every "
                                 f"row, got {len(values)}")
        if len(rows) >= MAX_TABLE_ROWS:
            raise ParameterError(f"{path}: more than the {MAX_TABLE_ROWS} rows a fit reads; bin the spectrum first")
        rows.append(values)
    if not rows:
        raise ParameterError(f"{path}: the table has no rows")
    return list(np.array(rows, dtype=np.float64).T)


def table_spectrum(frequency, psd, stderr=None, quantity: str = "accel", frequency_unit: str = "Hz",
                   sided: str = "one", density: str = "Hz", passes: int | None = None, window: bool = False,
                   source: str = "table") -> Spectrum:
    """A :class:`Spectrum` from arrays in a declared convention (see the module docstring)."""
    _choice("frequency_unit", frequency_unit, FREQUENCY_UNITS)
    _choice("sided", sided, SIDES)
    _choice("density", density, DENSITIES)
    frequency = np.asarray(frequency, dtype=np.float64)
    omega = frequency * (TWO_PI if frequency_unit == "Hz" else 1.0)
    factor = (1.0 / TWO_PI if density == "Hz" else 1.0) * (0.5 if sided == "one" else 1.0)
    psd = np.asarray(psd, dtype=np.float64) * factor
    err = None if stderr is None else np.asarray(stderr, dtype=np.float64) * factor
    if omega.size and omega[0] == 0.0:
        omega, psd, err = omega[1:], psd[1:], None if err is None else err[1:]
    return Spectrum(omega=omega, psd=psd, quantity=quantity, passes=passes, stderr=err, window=window, source=source)


def write_table(spectrum: Spectrum, path, frequency_unit: str = "Hz", sided: str = "one", density: str = "Hz") -> Path:
    """Write ``spectrum`` as a CSV table in a declared convention (the inverse of :func:`read_table`),
    atomically; the convention goes in a comment line."""
    _choice("frequency_unit", frequency_unit, FREQUENCY_UNITS)
    _choice("sided", sided, SIDES)
    _choice("density", density, DENSITIES)
    factor = (TWO_PI if density == "Hz" else 1.0) * (2.0 if sided == "one" else 1.0)
    frequency = spectrum.omega / (TWO_PI if frequency_unit == "Hz" else 1.0)
    columns = [frequency, spectrum.psd * factor] + ([spectrum.stderr * factor] if spectrum.stderr is not None else [])
    header = json.dumps({"quantity": spectrum.quantity, "frequency_unit": frequency_unit, "sided": sided,
                         "density": density, "passes": spectrum.passes})
    names = "frequency,psd" + (",stderr" if spectrum.stderr is not None else "")
    path = Path(path)
    with atomic_write(path, "w") as file:
        np.savetxt(file, np.column_stack(columns), delimiter=",", header=f"{header}\n{names}", fmt="%.17g")
    return path
