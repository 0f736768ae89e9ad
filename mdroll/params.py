"""Physical and numerical parameters of a rolling-contact ensemble (physics.md section 1).

All quantities are SI: pascal, metre, kilogram, newton, second; wavenumbers in rad/m.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, fields

import numpy as np

from . import physics
from .checks import check_number, check_positive
from .errors import ParameterError


#: The most springs a line may hold: one array dimension of Warp (32-bit).
MAX_POINTS = 2**31 - 1
#: The smallest RMS roughness (m): h0^2 scales every spectrum and must not underflow.
MIN_H0 = 1e-100
#: Modes per piece of the band summed for lambda_A (32 MiB of float64).
BAND_PIECE = 2**22


#: Roughness models of the ``roughness`` field (:mod:`mdroll.roughness`), the default first.
ROUGHNESS_MODELS = ("powerlaw", "rolloff", "table", "bands", "iso3095")
#: Which spectrum a roughness spectrum is: of the MDR line, of a line scan, or areal (isotropic).
SPECTRUM_KINDS = ("mdr", "profile", "areal")
#: Normalizations of the line: to RMS h0 (eq 50), or the spectrum's own absolute level.
ROUGHNESS_LEVELS = ("rms", "absolute")
#: Fields given as text (TOML strings, ``--set name=value`` taken verbatim).
TEXT_FIELDS = ("roughness", "roughness_table", "roughness_kind", "roughness_level")


@dataclass(frozen=True)
class Params:
    """Every parameter of physics.md section 1, with the thesis defaults (Table 1, Appendix A):
    the physics and the grid. How many realizations to average belongs to the run
    (``run_ensemble(params, realizations=N)``); :func:`mdroll.ensemble.realizations.read_params`
    reads a parameters dict that names it too.

    Attributes
    ----------
    E : float
        Young's modulus of wheel and rail (Pa). Default 210 GPa.
    nu : float
        Poisson's ratio, in (-1, 0.5). Default 0.3.
    R : float
        Wheel radius (m). Default 0.5 m.
    m : float
        Wheel mass (kg). Default 500 kg.
    F_N : float
        Normal load (N). Default 40 kN.
    v0 : float
        Rolling speed (m/s). Default 10 m/s.
    L : float
        Length of the generated rough line (m). Default 5 m. The grid has
        ``n_points = round(L / dx)`` springs; spectra use ``length = n_points * dx``.
    dx : float
        Spring spacing (m). Default 5 um.
    h0 : float
        RMS roughness of the 1D MDR line (m). Default 0.5 um.
    H : float
        Hurst exponent, in (0, 1). Default 0.7.
    q_min : float
        Long-wave cutoff (rad/m). Default 2 pi / 5 mm.
    q_max : float or None
        Short-wave cutoff (rad/m), at most the Nyquist wavenumber pi/dx. ``None`` (default)
        means pi/dx.
    roughness : str
        Roughness spectrum model (:mod:`mdroll.roughness`): ``"powerlaw"`` (default, eq 33 with
        hard cut-offs q_min, q_max), ``"rolloff"`` (eq 33 above ``q_r``, flat below it down to the
        grid's first wavenumber 2 pi / L), ``"table"`` (a PSD table (q, C) in ``roughness_table``),
        ``"bands"`` (1/3-octave levels (lambda_mm, L_r dB re 1 um) in ``roughness_table``),
        ``"iso3095"`` (the EN ISO 3095:2013 limit spectrum).
    q_r : float or None
        Roll-off wavenumber (rad/m) of ``roughness = "rolloff"``; ``None`` (default) means q_min.
    roughness_table : str
        File of the ``"table"`` / ``"bands"`` model (CSV with two columns, or NPY of shape (K, 2)).
    roughness_kind : str or None
        Which spectrum the table holds: ``"mdr"``, ``"profile"`` (a line scan) or ``"areal"``
        (isotropic C_2D); ``None`` means ``"profile"`` for table, bands and iso3095 (measurements
        are line scans) and ``"mdr"`` for the power-law models.
    roughness_level : str or None
        ``"rms"``: the line is scaled to RMS h0 (eq 50); ``"absolute"``: the spectrum's own level,
        no rescaling (h0 unused). ``None`` means ``"rms"`` for the power-law models (which carry no
        level of their own) and ``"absolute"`` for table, bands and iso3095.
    """

    E: float = 210e9
    nu: float = 0.3
    R: float = 0.5
    m: float = 500.0
    F_N: float = 40e3
    v0: float = 10.0
    L: float = 5.0
    dx: float = 5e-6
    h0: float = 0.5e-6
    H: float = 0.7
    q_min: float = physics.TWO_PI / 5e-3
    q_max: float | None = field(default=None)
    roughness: str = "powerlaw"
    q_r: float | None = None
    roughness_table: str = ""
    roughness_kind: str | None = None
    roughness_level: str | None = None

    def __post_init__(self) -> None:
        for name in ("E", "R", "m", "F_N", "v0", "L", "dx", "h0", "q_min"):
            check_positive(name, getattr(self, name))
        check_number("nu", self.nu, "in (-1, 0.5), the range of Poisson's ratio", lambda v: -1.0 < v < 0.5)
        check_number("H", self.H, "in (0, 1), the range of the Hurst exponent", lambda v: 0.0 < v < 1.0)
        if not self.L / self.dx < MAX_POINTS:
            raise ParameterError(
                f"L = {self.L!r} m is not allowed with dx = {self.dx!r} m: the line would hold {self.L / self.dx:.3g} "
                f"springs, more than the {MAX_POINTS} of one array (Warp's 32-bit dimensions); reduce L or increase dx"
            )
        if self.h0 < MIN_H0:
            raise ParameterError(
                f"h0 = {self.h0!r} m is not allowed: it must be at least {MIN_H0:g} m (below, its square, the "
                "scale of the spectra, is lost to float64 underflow)"
            )
        if self.h0 >= self.R:
            raise ParameterError(
                f"h0 = {self.h0!r} m is not allowed: the RMS roughness must be far below the wheel radius "
                f"R = {self.R!r} m (the window of possible contact would be absurd)"
            )
        if self.a / self.dx < 10.0:
            raise ParameterError(
                f"dx = {self.dx!r} m is not allowed: the contact radius a = {self.a:.4g} m spans only "
                f"{self.a / self.dx:.3g} springs; a/dx must be at least 10 (contact not resolved)"
            )
        nyquist_cutoff = self.q_max is None
        if nyquist_cutoff:
            object.__setattr__(self, "q_max", math.pi / self.dx)
        check_positive("q_max", self.q_max)
        nyquist = math.pi / self.dx
        if self.q_max > nyquist * (1.0 + 1e-12):
            raise ParameterError(
                f"q_max = {self.q_max!r} rad/m is not allowed: it must not exceed the Nyquist "
                f"wavenumber pi/dx = {nyquist:.6g} rad/m"
            )
        if self.q_min >= self.q_max and nyquist_cutoff:
            raise ParameterError(
                f"dx = {self.dx!r} m is not allowed with q_min = {self.q_min!r} rad/m: its Nyquist wavenumber "
                f"pi/dx = {nyquist:.6g} rad/m (the default q_max) must exceed q_min: dx must be below "
                f"pi/q_min = {math.pi / self.q_min:.4g} m"
            )
        if self.q_min >= self.q_max:
            raise ParameterError(
                f"q_min = {self.q_min!r} rad/m is not allowed: it must be below q_max = {self.q_max:.6g} rad/m"
            )
        if self.n_points < 2:
            raise ParameterError(f"L = {self.L!r} m is not allowed: it must hold at least two springs of dx = {self.dx!r} m")
        if self.omega_0 * self.dt >= 2.0:
            raise ParameterError(
                f"dx = {self.dx!r} m, v0 = {self.v0!r} m/s are not allowed: the step dt = dx/v0 = {self.dt:.4g} s gives "
                f"omega_0 dt = {self.omega_0 * self.dt:.4g}; it must stay below 2 for the semi-implicit Euler step "
                "(section 5) to be stable"
            )
        if self.L < 4.0 * self.a:
            raise ParameterError(
                f"L = {self.L!r} m is not allowed: it must be at least 4a = {4.0 * self.a:.4g} m "
                "(twice the contact width)"
            )
        if self._band_range() is None:
            raise ParameterError(
                f"q_min = {self.q_min!r}, q_max = {self.q_max!r} rad/m hold no wavenumber q_k = 2 pi k / L "
                f"of the grid (2 pi / L = {self.dq:.6g} rad/m)"
            )
        self._check_roughness()

    def _check_roughness(self) -> None:
        """The roughness fields: names from their allowed sets, q_r and the table where the model
        uses them (the table file itself is read, and checked, by :mod:`mdroll.roughness`)."""
        choices = {"roughness": ROUGHNESS_MODELS, "roughness_kind": (None,) + SPECTRUM_KINDS,
                   "roughness_level": (None,) + ROUGHNESS_LEVELS}
        for name, allowed in choices.items():
            value = getattr(self, name)
            if value not in allowed:
                raise ParameterError(f"{name} = {value!r} is not allowed: choose one of {list(allowed)}")
        if self.q_r is not None:
            if self.roughness != "rolloff":
                raise ParameterError(f"q_r = {self.q_r!r} is not allowed with roughness = {self.roughness!r}: "
                                     "the roll-off wavenumber belongs to roughness = 'rolloff'")
            check_positive("q_r", self.q_r)
            if not self.dq <= self.q_r < self.q_max:
                raise ParameterError(f"q_r = {self.q_r!r} rad/m is not allowed: it must lie in [2 pi / L, q_max) = "
                                     f"[{self.dq:.6g}, {self.q_max:.6g}) rad/m")
        if not isinstance(self.roughness_table, str):
            raise ParameterError(f"roughness_table must be a file name (str), got {self.roughness_table!r}")
        tabulated = self.roughness in ("table", "bands")
        if tabulated != bool(self.roughness_table):
            raise ParameterError(
                f"roughness_table = {self.roughness_table!r} is not allowed with roughness = {self.roughness!r}: "
                "roughness 'table' and 'bands' need a file, the other models none")
        if self.roughness in ("powerlaw", "rolloff"):
            if self.roughness_kind not in (None, "mdr"):
                raise ParameterError(f"roughness_kind = {self.roughness_kind!r} is not allowed with roughness = "
                                     f"{self.roughness!r}: the power-law models are MDR-line spectra ('mdr')")
            if self.roughness_level == "absolute":
                raise ParameterError(f"roughness_level = 'absolute' is not allowed with roughness = {self.roughness!r}: "
                                     "its level comes from h0 (eq 50); use 'rms'")
        if self.roughness == "iso3095" and self.roughness_kind not in (None, "profile"):
            raise ParameterError(f"roughness_kind = {self.roughness_kind!r} is not allowed with roughness = 'iso3095': "
                                 "the EN ISO 3095 limit is a profile (line-scan) spectrum")

    @property
    def spectrum_kind(self) -> str:
        """The kind of the roughness spectrum the fields name: ``roughness_kind`` resolved."""
        if self.roughness_kind is not None:
            return self.roughness_kind
        return "mdr" if self.roughness in ("powerlaw", "rolloff") else "profile"

    @property
    def level(self) -> str:
        """``roughness_level`` resolved: ``"rms"`` or ``"absolute"``."""
        if self.roughness_level is not None:
            return self.roughness_level
        return "rms" if self.roughness in ("powerlaw", "rolloff") else "absolute"

    # ------------------------------------------------------------------ derived quantities
    @property
    def E_star(self) -> float:
        """Effective modulus E* = E / (2 (1 - nu^2)) (Pa), eq 1-2: :func:`physics.effective_modulus`."""
        return float(physics.effective_modulus(self.E, self.nu))

    @property
    def d0(self) -> float:
        """Hertz indentation d0 = (3 F_N / (4 E* sqrt(R)))^(2/3) (m), eq 14: :func:`physics.hertz_indentation`."""
        return float(physics.hertz_indentation(self.F_N, self.E_star, self.R))

    @property
    def a(self) -> float:
        """Hertz contact radius a = sqrt(d0 R) (m), eq 15: :func:`physics.contact_radius`."""
        return float(physics.contact_radius(self.d0, self.R))

    @property
    def k_spring(self) -> float:
        """Stiffness of one MDR spring k = E* dx (N/m), section 2: :func:`physics.spring_stiffness`."""
        return float(physics.spring_stiffness(self.E_star, self.dx))

    @property
    def F_hertz(self) -> float:
        """Hertz force (4/3) E* a^3 / R at d0 (N); equals F_N: :func:`physics.hertz_force`."""
        return float(physics.hertz_force(self.d0, self.E_star, self.R))

    @property
    def k_contact(self) -> float:
        """Linearized contact stiffness k_c = dF/dd = 2 E* a (N/m), section 4.2: :func:`physics.contact_stiffness`."""
        return float(physics.contact_stiffness(self.E_star, self.a))

    @property
    def omega_0(self) -> float:
        """Contact resonance omega_0 = sqrt(k_c / m) = sqrt(2 a E* / m) (rad/s), section 4.2:
        :func:`physics.resonance_frequency`."""
        return float(physics.resonance_frequency(self.k_contact, self.m))

    @property
    def n_points(self) -> int:
        """Number of springs on the line, round(L / dx)."""
        return int(round(self.L / self.dx))

    @property
    def length(self) -> float:
        """Length of the discrete line n_points * dx (m); the L of every spectrum."""
        return self.n_points * self.dx

    @property
    def dq(self) -> float:
        """Wavenumber step of the line's grid, 2 pi / length (rad/m): ``q_k = k dq``."""
        return physics.TWO_PI / self.length

    @property
    def dt(self) -> float:
        """Time step dt = dx / v0 (s): the line moves one spring per step."""
        return self.dx / self.v0

    @property
    def springs_in_contact(self) -> float:
        """Number of springs in the smooth Hertz contact, 2 a / dx."""
        return 2.0 * self.a / self.dx

    def _band_range(self) -> tuple[int, int] | None:
        """First and last k in 1..n/2 with q_k = 2 pi k / length in the band (:meth:`in_band`), or
        None: from the cutoffs by division, then settled with :meth:`in_band` itself, so a
        wavenumber on a cutoff up to rounding counts as it does there; no array over the grid."""
        dq = self.dq
        top = self.n_points // 2

        def inside(k: int) -> bool:
            return 1 <= k <= top and bool(self.in_band(dq * k))

        first = max(1, math.ceil(self.q_min * (1.0 - 1e-12) / dq))
        while first > 1 and inside(first - 1):
            first -= 1
        while first <= top and not inside(first):
            first += 1
        last = min(top, math.floor(self.q_max * (1.0 + 1e-12) / dq))
        while last < top and inside(last + 1):
            last += 1
        while last >= first and not inside(last):
            last -= 1
        return (first, last) if first <= last else None

    def in_band(self, q) -> np.ndarray:
        """Mask of ``q_min <= |q| <= q_max`` (inclusive, to a relative 1e-12 so that a grid
        wavenumber landing on a cutoff up to rounding, e.g. q_k = 2 pi / 5 mm, is inside):
        :func:`physics.in_roughness_band`."""
        return physics.in_roughness_band(q, self.q_min, self.q_max)

    @property
    def mode_range(self) -> tuple[int, int]:
        """First and last index k (inclusive) of the generated modes q_k = 2 pi k / length."""
        return self._band_range()

    @property
    def lambda_A(self) -> float:
        """Prefactor lambda(H) A of C_1D(q) = lambda A |q|^(-2H-1) (m^(2-2H)), eq 33 and eq 50.

        The discrete normalization of physics.md section 3, which makes the two-sided PSD
        sum to the mean square height:
        ``lambda A = h0^2 / (2 (2 pi / L) sum_{q_min <= q_k <= q_max} q_k^(-2H-1))``
        (:func:`physics.lambda_A_discrete`).
        """
        first, last = self._band_range()
        # in pieces of BAND_PIECE modes, so that a long line's band needs no array over all of it:
        # lambda A = h0^2 / (2 dq sum), so its inverse adds up over the pieces
        pieces = [physics.lambda_A_discrete(self.h0, self.H, self.dq * np.arange(
            start, min(start + BAND_PIECE, last + 1), dtype=np.float64), self.dq)
            for start in range(first, last + 1, BAND_PIECE)]
        return pieces[0] if len(pieces) == 1 else 1.0 / sum(1.0 / piece for piece in pieces)

    def psd(self, q) -> np.ndarray:
        """Two-sided 1D MDR roughness PSD C_1D(q) = lambda A |q|^(-2H-1) on the band (m^3), eq 33:
        :func:`physics.roughness_psd`. ``q`` in rad/m; zero outside q_min <= |q| <= q_max.
        """
        return physics.roughness_psd(q, self.lambda_A, self.H, self.q_min, self.q_max)

    # ------------------------------------------------------------------ helpers
    def replace(self, **changes) -> "Params":
        """A copy with some fields changed (validated again).

        ``q_max`` follows a change of ``dx`` unless it is given explicitly or was set to
        something other than the Nyquist wavenumber.
        """
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise ParameterError(
                f"unknown parameter(s) {sorted(unknown)}; valid ones are {[f.name for f in fields(self)]}"
            )
        if "q_max" not in changes and math.isclose(self.q_max, math.pi / self.dx, rel_tol=1e-12):
            changes["q_max"] = None
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict:
        """The fields as a plain dict (q_max resolved)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def derived(self) -> dict:
        """Derived quantities as ``{name: (value, unit, description)}``."""
        return {
            "E_star": (self.E_star, "Pa", "effective modulus E/(2(1-nu^2))"),
            "d0": (self.d0, "m", "Hertz indentation (eq 14)"),
            "a": (self.a, "m", "contact radius sqrt(d0 R) (eq 15)"),
            "k_spring": (self.k_spring, "N/m", "spring stiffness E* dx"),
            "F_hertz": (self.F_hertz, "N", "Hertz force (4/3) E* a^3/R"),
            "k_contact": (self.k_contact, "N/m", "contact stiffness 2 E* a"),
            "omega_0": (self.omega_0, "rad/s", "contact resonance sqrt(2 a E*/m)"),
            "f_0": (self.omega_0 / physics.TWO_PI, "Hz", "contact resonance omega_0/(2 pi)"),
            "n_points": (self.n_points, "-", "springs on the line, L/dx"),
            "dt": (self.dt, "s", "time step dx/v0"),
            "springs_in_contact": (self.springs_in_contact, "-", "2a/dx"),
            "lambda_A": (self.lambda_A, "m^(2-2H)", "PSD prefactor (eq 50, discrete)"),
        }

