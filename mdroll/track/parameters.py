"""The track's parameters: a frozen :class:`Track`, its presets, and its ``track.KEY=VALUE`` form.

The rail is a Timoshenko beam (Knothe & Grassie 1993; Grassie, Gregory, Harrison & Johnson 1982)
on rail pads, sleepers and ballast (Thompson, *Railway Noise and Vibration*, 2009, chapter 3).
Its section defaults are those of the 60E1 (UIC 60) rail of EN 13674-1: second moment of area
I = 3038.3 cm^4, cross-section A = 76.70 cm^2, mass 60.21 kg/m; steel E = 210 GPa, G = 81 GPa,
density 7850 kg/m^3; shear coefficient 0.4 for vertical bending of a flat-bottom rail (Thompson
2009, chapter 3; Grassie et al. 1982). Pad, sleeper and ballast values of the presets are
representative values inside the ranges Thompson 2009 (chapter 3) gives for ballasted tracks
with soft and stiff pads and for slab track, not a transcription of one of its tables
(:data:`SOURCES` says which range each stands for).
Units are SI; every stiffness and mass of the support is that of one support (one rail seat).

Damping: every stiffness k with loss factor eta (pads, ballast, the rail's E I and kappa G A) is a
complex modulus (:func:`mdroll.track.beam.modulus`), by default the causal constant-loss modulus,
whose storage stiffness is k at ``damping_frequency`` and grows as (f / f_r)^p, p = (2 / pi)
arctan(eta), as the Kramers-Kronig relations demand of a constant loss factor (pads, eta 0.25:
x1.43 a decade; ballast, eta 1: x3.16 a decade). The presets' stiffnesses and loss factors hold
at f_r = 100 Hz: the range of the sleeper-passing frequencies, where the moving load meets the
supports' stated stiffness, and inside the band where the presets' ranges are quoted. The
hysteretic modulus k (1 + i eta), the same at every frequency, is not causal (no passive, causal
state space follows it, so a coupled run steps a fit of it with a larger error: docs/track.md,
"State space"); it stays for comparison with chains that use it, such as TWINS.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from mdroll.checks import check_nonnegative, check_number, check_positive
from mdroll.errors import ParameterError
from mdroll.settings import Presettable

#: Support models: ``rigid`` (an immovable rail, zero receptance), ``continuous`` (the supports
#: smeared along the rail, per length k / sleeper_spacing), ``discrete`` (one support per sleeper).
SUPPORTS = ("rigid", "continuous", "discrete")

#: Damping models of every stiffness with a loss factor (:func:`mdroll.track.beam.modulus`):
#: ``causal`` (constant loss, storage stiffness growing with frequency) and ``hysteretic``.
DAMPINGS = ("causal", "hysteretic")

#: 60E1 (UIC 60) rail, EN 13674-1, with E = 210 GPa, G = 81 GPa, rho = 7850 kg/m^3.
UIC60 = {
    "rail_EI": 210e9 * 3038.3e-8,          # N m^2: E I, I = 3038.3 cm^4
    "rail_mass": 60.21,                    # kg/m
    "rail_shear_stiffness": 0.4 * 81e9 * 76.70e-4,  # N: kappa G A, kappa = 0.4, A = 76.70 cm^2
    "rail_rotary_inertia": 7850.0 * 3038.3e-8,      # kg m: rho I
}

#: Presets: values and where they come from. ``rigid`` is today's immovable rail.
PRESETS: dict[str, dict] = {
    "rigid": {"support": "rigid"},
    # concrete monobloc sleepers on ballast, soft (studded rubber) pads: Thompson 2009 ch. 3
    "ballasted-soft-pad": {"support": "discrete", "pad_stiffness": 120e6, "pad_loss": 0.25,
                           "sleeper_mass": 150.0, "ballast_stiffness": 100e6, "ballast_loss": 1.0,
                           "sleeper_spacing": 0.6},
    # the same track with stiff (EVA / HDPE) pads: Thompson 2009 ch. 3
    "ballasted-stiff-pad": {"support": "discrete", "pad_stiffness": 1000e6, "pad_loss": 0.25,
                            "sleeper_mass": 150.0, "ballast_stiffness": 100e6, "ballast_loss": 1.0,
                            "sleeper_spacing": 0.6},
    # direct-fixation slab track: a soft baseplate fastening on a stiff concrete slab, the
    # baseplate as the small intermediate mass: Thompson 2009 ch. 3 (slab and embedded tracks)
    "slab": {"support": "discrete", "pad_stiffness": 40e6, "pad_loss": 0.2,
             "sleeper_mass": 5.0, "ballast_stiffness": 5e9, "ballast_loss": 0.1,
             "sleeper_spacing": 0.65},
}

SOURCES = {
    "rigid": "no track: the immovable rail of physics.md section 1",
    "ballasted-soft-pad": "soft pads (about 100-200 MN/m), half monobloc sleepers (about 150 kg) and ballast "
                          "(about 50-100 MN/m, loss 1): ranges of Thompson 2009 ch. 3",
    "ballasted-stiff-pad": "stiff pads (about 1 GN/m and above), otherwise as the soft-pad track: Thompson 2009 ch. 3",
    "slab": "direct fixation: a soft baseplate fastening (about 20-60 MN/m) on a slab: Thompson 2009 ch. 3",
}


@dataclass(frozen=True)
class Track(Presettable):
    """A rail on rail pads, sleepers and ballast (SI units; pad, sleeper and ballast per support).

    Presets (:data:`PRESETS`, their sources in :data:`SOURCES`), copies and ``track.KEY=VALUE``
    settings: :class:`mdroll.settings.Presettable`.

    Attributes
    ----------
    support : str
        ``"rigid"``, ``"continuous"`` or ``"discrete"`` (:data:`SUPPORTS`). Default continuous.
    rail_EI : float
        Bending stiffness E I of the rail (N m^2). Default 60E1: 6.380e6 N m^2.
    rail_mass : float
        Rail mass per length rho A (kg/m). Default 60.21 kg/m.
    rail_shear_stiffness : float
        Shear stiffness kappa G A (N). Default 0.4 x 81 GPa x 76.70 cm^2 = 2.485e8 N; ``inf``
        gives the Euler-Bernoulli beam (with ``rail_rotary_inertia = 0``).
    rail_rotary_inertia : float
        Rotary inertia per length rho I (kg m). Default 0.2385 kg m.
    rail_loss : float
        Loss factor of the rail's moduli, E I (1 + i eta) and kappa G A (1 + i eta). Default 0.02.
    pad_stiffness, pad_loss : float
        Rail pad stiffness (N/m, one support) and loss factor. Default 200 MN/m, 0.25.
    sleeper_mass : float
        Mass on one support, half a sleeper (kg). Default 150 kg; 0 means none.
    ballast_stiffness, ballast_loss : float
        Ballast stiffness under one support (N/m) and loss factor. Default 100 MN/m, 1.0.
    sleeper_spacing : float
        Distance between supports (m). Default 0.6 m.
    damping : str
        ``"causal"`` (the default) or ``"hysteretic"`` (:data:`DAMPINGS`): the complex modulus of
        every stiffness with a loss factor (:func:`mdroll.track.beam.modulus`).
    damping_frequency : float
        The frequency f_r (Hz) at which the stated stiffnesses hold exactly under causal
        damping (module docstring). Default 100 Hz.
    parametric : bool
        A coupled run adds the moving load's parametric excitation, the exact steady-state
        equivalent roughness of :func:`mdroll.track.parametric.equivalent_roughness` at the static
        load and the run's speed v0 (x = 0 of the line above a support), to every realization's
        line. Only with ``support = "discrete"``. Default False.
    """

    support: str = "continuous"
    rail_EI: float = UIC60["rail_EI"]
    rail_mass: float = UIC60["rail_mass"]
    rail_shear_stiffness: float = UIC60["rail_shear_stiffness"]
    rail_rotary_inertia: float = UIC60["rail_rotary_inertia"]
    rail_loss: float = 0.02
    pad_stiffness: float = 200e6
    pad_loss: float = 0.25
    sleeper_mass: float = 150.0
    ballast_stiffness: float = 100e6
    ballast_loss: float = 1.0
    sleeper_spacing: float = 0.6
    damping: str = "causal"
    damping_frequency: float = 100.0
    parametric: bool = False

    PREFIX, PRESETS, TEXT_FIELDS, FLAG_FIELDS = "track", PRESETS, ("support", "damping"), ("parametric",)

    def __post_init__(self) -> None:
        if self.support not in SUPPORTS:
            raise ParameterError(f"track.support = {self.support!r} is not allowed: choose one of {list(SUPPORTS)}")
        if self.damping not in DAMPINGS:
            raise ParameterError(f"track.damping = {self.damping!r} is not allowed: choose one of {list(DAMPINGS)}")
        for name in ("rail_EI", "rail_mass", "pad_stiffness", "ballast_stiffness", "sleeper_spacing",
                     "damping_frequency"):
            check_positive(f"track.{name}", getattr(self, name))
        check_number("track.rail_shear_stiffness", self.rail_shear_stiffness, "positive (inf: Euler-Bernoulli)",
                     lambda v: v > 0)
        for name in ("rail_rotary_inertia", "rail_loss", "pad_loss", "sleeper_mass", "ballast_loss"):
            check_nonnegative(f"track.{name}", getattr(self, name))
        if not isinstance(self.parametric, bool):
            raise ParameterError(f"track.parametric = {self.parametric!r} is not allowed: it must be true or false")
        if self.parametric and self.support != "discrete":
            raise ParameterError(f"track.parametric = true is not allowed with track.support = {self.support!r}: the "
                                 "moving load's parametric excitation needs track.support = 'discrete'")

    @classmethod
    def from_record(cls, fields: dict) -> "Track":
        """The track of a result's record (:func:`dataclasses.asdict` of a track): a record
        without ``damping`` was written when every track was hysteretic, and stays so."""
        return cls(**{"damping": "hysteretic", **fields})

    def key_fields(self) -> dict:
        """The track's fields as they enter a run's checkpoint key: all of them, less ``parametric``
        when false and ``damping``, ``damping_frequency`` when hysteretic at the default frequency,
        so that such a track has the key written before these fields existed."""
        fields = dataclasses.asdict(self)
        if not self.parametric:
            del fields["parametric"]
        if self.damping == "hysteretic" and self.damping_frequency == Track.damping_frequency:
            del fields["damping"], fields["damping_frequency"]
        return fields

    def structure(self) -> "Track":
        """The track without the moving load's excitation (``parametric = False``): the structure
        whose receptances the coupled dynamics steps."""
        return dataclasses.replace(self, parametric=False) if self.parametric else self
