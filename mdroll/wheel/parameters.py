"""The wheel's radial (vertical) point receptance at the contact: a rigid mass, or a modal wheel.

Time dependence ``exp(i omega t)``; receptance = displacement per force (m/N), force positive
towards the wheel's centre. The modal wheel (Thompson, *Railway Noise and Vibration*, 2009,
ch. 5; Thompson & Jones 2000, J. Sound Vib. 231) adds to the unsprung mass M on the primary
suspension k_s (1 + i eta_s) the flexible modes n of natural frequency f_n, modal mass m_n (the
mass of the mode at the contact point) and damping ratio zeta_n::

    alpha_W(omega) = 1 / (k_s (1 + i eta_s) - M omega^2)
                     + sum_n 1 / (m_n (omega_n^2 - omega^2 + 2 i zeta_n omega_n omega)).

The rigid wheel is ``alpha_W = -1 / (m omega^2)``: the mass of physics.md section 1, today's model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mdroll.checks import check_nonnegative, check_positive
from mdroll.errors import ParameterError
from mdroll.physics import TWO_PI
from mdroll.settings import Presettable
from mdroll.statespace import ModalForm

KINDS = ("rigid", "modal")

#: Frequency (Hz) at which the modal form's viscous suspension damping equals the hysteretic
#: loss (:meth:`Wheel.modal_form`).
SUSPENSION_MATCH_HZ = 50.0

#: Radial modes (frequency Hz, modal mass kg at the contact, damping ratio) standing for a 920 mm
#: wheel: modes with one nodal circle and n = 2..6 nodal diameters between 2 and 5 kHz, the
#: families that dominate the radial point receptance in Thompson 2009, ch. 5. The frequencies
#: and modal masses are representative of that range, not transcribed from the book's table:
#: replace them by a wheel's finite-element modes before quantitative use. Damping ratio 1e-4,
#: the order of an untreated steel wheel's (Thompson 2009, ch. 5).
STANDARD_920_MODES = ((2210.0, 250.0, 1e-4), (2870.0, 150.0, 1e-4), (3540.0, 120.0, 1e-4),
                      (4210.0, 110.0, 1e-4), (4880.0, 100.0, 1e-4))

PRESETS: dict[str, dict] = {
    "rigid": {"kind": "rigid", "mass": 500.0},
    "standard-920": {"kind": "modal", "mass": 600.0, "suspension_stiffness": 1e6, "suspension_loss": 0.1,
                     "modes": STANDARD_920_MODES},
}

SOURCES = {
    "rigid": "physics.md section 1: the rigid 500 kg wheel",
    "standard-920": "representative radial modes of a 920 mm wheel (range of Thompson 2009 ch. 5, "
                    "not its table); half-wheelset unsprung mass 600 kg on a 1 MN/m primary suspension",
}


@dataclass(frozen=True)
class Wheel(Presettable):
    """A wheel's radial receptance model (SI units).

    :class:`mdroll.settings.Presettable` gives its presets (:data:`PRESETS`), changed copies and
    ``wheel=PRESET`` / ``wheel.KEY=VALUE`` settings.

    Attributes
    ----------
    kind : str
        ``"rigid"`` (a mass) or ``"modal"`` (unsprung mass on a suspension plus modes).
    mass : float
        The rigid wheel's mass, or the modal wheel's unsprung mass M (kg). Default 500 kg.
    suspension_stiffness, suspension_loss : float
        Primary suspension k_s (N/m) and its loss factor (modal wheel only). Default 1 MN/m, 0.1.
    modes : tuple of (f_n Hz, m_n kg, zeta_n)
        The modal wheel's modes. Default none.
    """

    kind: str = "rigid"
    mass: float = 500.0
    suspension_stiffness: float = 1e6
    suspension_loss: float = 0.1
    modes: tuple = field(default=())

    PREFIX, PRESETS, TEXT_FIELDS = "wheel", PRESETS, ("kind",)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ParameterError(f"wheel.kind = {self.kind!r} is not allowed: choose one of {list(KINDS)}")
        for name in ("mass", "suspension_stiffness"):
            check_positive(f"wheel.{name}", getattr(self, name))
        check_nonnegative("wheel.suspension_loss", self.suspension_loss)
        modes = np.asarray(self.modes, dtype=np.float64).reshape(-1, 3) if len(self.modes) else np.zeros((0, 3))
        if not (np.all(np.isfinite(modes)) and np.all(modes[:, :2] > 0) and np.all(modes[:, 2] >= 0)):
            raise ParameterError(f"wheel.modes = {self.modes!r} is not allowed: rows (f_n > 0 Hz, m_n > 0 kg, "
                                 "zeta_n >= 0), all finite")
        if self.kind == "rigid" and len(modes):
            raise ParameterError("wheel.modes is not allowed with wheel.kind = 'rigid': use kind 'modal'")

    def check_run_mass(self, m: float) -> None:
        """Refuses (ParameterError) a rigid wheel whose mass is not the run's mass ``m`` (kg): the
        rigid wheel is the mass of eq 13, ``Params.m``, in the run, its spectra and its summary."""
        if self.kind == "rigid" and self.mass != m:
            raise ParameterError(f"wheel.mass = {self.mass:g} kg is not allowed with m = {m:g} kg: the rigid wheel "
                                 "is the run's mass m; set m (or wheel.mass on the command line, which sets m)")

    def receptance(self, f):
        """Radial point receptance alpha_W (m/N, complex) at frequencies ``f`` (Hz, > 0): the
        module docstring's formula."""
        omega = TWO_PI * np.asarray(f, dtype=np.float64)
        if self.kind == "rigid":
            return -1.0 / (self.mass * omega**2) + 0j
        alpha = 1.0 / (self.suspension_stiffness * (1 + 1j * self.suspension_loss) - self.mass * omega**2)
        for f_n, m_n, zeta in self.modes:
            w_n = TWO_PI * f_n
            alpha = alpha + 1.0 / (m_n * (w_n**2 - omega**2 + 2j * zeta * w_n * omega))
        return alpha

    def modal_form(self) -> ModalForm:
        """The modal wheel's receptance as a modal state space: its modes exactly, and the
        primary suspension with the viscous damping c = eta_s k_s / omega_m that equals its
        hysteretic loss at omega_m = 2 pi :data:`SUSPENSION_MATCH_HZ` (a hysteretic loss is not
        causal; matched at the lower edge of the band the coupled dynamics resolves, it
        overdamps nothing below it and the suspension's share of alpha_W falls as omega^-4 above
        it). The rigid wheel is no state space (its mass is stepped by the coupled dynamics):
        ParameterError."""
        if self.kind == "rigid":
            raise ParameterError("wheel.kind = 'rigid' has no modal form: its mass is the coupled dynamics' own")
        modes = np.asarray(self.modes, dtype=np.float64).reshape(-1, 3)
        f_s = np.sqrt(self.suspension_stiffness / self.mass) / TWO_PI
        zeta_s = 0.5 * self.suspension_loss * f_s / SUSPENSION_MATCH_HZ
        return ModalForm.oscillators(np.concatenate([[f_s], modes[:, 0]]), np.concatenate([[self.mass], modes[:, 1]]),
                                     np.concatenate([[zeta_s], modes[:, 2]]))
