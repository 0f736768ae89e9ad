"""The wheel's and the rail's vibration at the contact in a coupled run on a track.

The rail and the wheel are linear systems driven by the contact force F; in the time domain
(:func:`mdroll.ensemble.coupled.coupled_series`) the rail's displacement at the contact is the
output of its fitted modal state space, stepped exactly for the force held over each step, and a
modal wheel's is the output of its modes. Their velocities are therefore the force filtered by
known transfers, realization by realization (signs as :mod:`mdroll.track.interaction`)::

    v_R = i omega alpha_R F,        v_W = -i omega alpha_W F,

and their spectra follow from the force's exactly, bin by bin of the realization-averaged PSD
(and its standard error, the same factor)::

    S_v(omega) = omega^2 |alpha(omega)|^2 S_F(omega).

``alpha_R`` is the stepped rail state space's transfer where the wheel stands
(:meth:`mdroll.statespace.ModalForm.discrete_response` of :func:`mdroll.track.fit.rail_modal_form`
at the run's dt: the rail the run integrated, within the fit's ``error_db`` of the track's
receptance); ``alpha_W`` the modal wheel's stepped transfer, or ``-1 / (m omega^2)`` for the
rigid wheel (the mass of eq 13, whose acceleration series the run records; its velocity is not a
vibration at omega = 0, set to 0 there). The wheel's acceleration at the contact is ``omega^2``
times its velocity: for a modal wheel the run's ``accel_psd`` is that (:func:`with_structures`),
for the rigid wheel it is the mass's, the same quantity.

Spectra keep the run's convention: two-sided per rad/m ((m/s)^2 m).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from ..params import Params
from ..physics import TWO_PI
from ..track import Track
from ..track.fit import rail_modal_form
from ..wheel import Wheel

#: The vibration spectra a run on a track writes beside force and acceleration (velocity PSDs).
VIBRATION = ("wheel_velocity", "rail_velocity")
#: Where the coupled run stands the wheel (:func:`mdroll.ensemble.coupled.contact_compliance`).
WHEEL_POSITION = "sleeper"


def rail_form(track: Track):
    """The rail's modal state space the coupled run steps (:func:`mdroll.track.fit.rail_modal_form`
    at :data:`WHEEL_POSITION`, called as the run calls it: one fit, cached)."""
    return rail_modal_form(track.structure(), WHEEL_POSITION)


def structures_record(track: Track | None, wheel: Wheel | None) -> tuple[dict, dict]:
    """The track's and the wheel's fields as JSON-ready dicts (the rigid ones where None), as a
    result and its file hold them."""
    return tuple(json.loads(json.dumps(dataclasses.asdict(x))) for x in (track or Track.preset("rigid"),
                                                                         wheel or Wheel.preset("rigid")))


def rigid_wheel(params: Params) -> Wheel:
    """The rigid wheel of a run: its mass is the run's m (eq 13)."""
    return Wheel.preset("rigid").with_values(mass=params.m)


def structures_of(result) -> tuple[Track, Wheel]:
    """The :class:`Track` and :class:`Wheel` a result records (the rigid ones where it records none,
    the rigid wheel of the run's mass m)."""
    track = Track.from_record(result.track) if result.track else Track.preset("rigid")
    if not result.wheel:
        return track, rigid_wheel(result.params)
    wheel = dict(result.wheel)
    wheel["modes"] = tuple(tuple(mode) for mode in wheel.get("modes", ()))
    return track, Wheel(**wheel)


def transfers(track: Track, wheel: Wheel, params: Params, f) -> dict:
    """``{"wheel": alpha_W, "rail": alpha_R}`` (m/N, complex) at ``f`` (Hz) as the run steps them
    (module docstring); the rigid track's rail transfer is zero."""
    f = np.asarray(f, dtype=np.float64)
    rail = rail_form(track).discrete_response(f, params.dt) if track.support != "rigid" else np.zeros(f.shape, complex)
    if wheel.kind == "rigid":
        omega2 = (TWO_PI * f) ** 2
        wheel_alpha = np.divide(-1.0, params.m * omega2, out=np.zeros(f.shape), where=omega2 > 0) + 0j
    else:
        wheel_alpha = wheel.modal_form().discrete_response(f, params.dt)
    return {"wheel": wheel_alpha, "rail": rail}


def vibration_spectra(result) -> dict:
    """``{"wheel_velocity": (psd, stderr), "rail_velocity": (psd, stderr)}`` of a coupled result on
    a track ((m/s)^2 m, two-sided per rad/m): ``omega^2 |alpha|^2`` times the force's (module
    docstring). The rail's only where the track is compliant."""
    track, wheel = structures_of(result)
    alpha = transfers(track, wheel, result.params, result.omega / TWO_PI)
    out = {}
    for name, key in (("wheel_velocity", "wheel"), ("rail_velocity", "rail")):
        if key == "rail" and track.support == "rigid":
            continue
        gain = np.abs(result.omega * alpha[key]) ** 2
        out[name] = (gain * result.force_psd, gain * result.force_psd_stderr)
    return out


def with_structures(result, track: Track | None, wheel: Wheel | None):
    """``result`` of a coupled run recording ``track`` and ``wheel`` (nothing where both are the
    rigid ones: today's result exactly); a modal wheel's ``accel_psd`` becomes the wheel's
    acceleration at the contact, ``omega^4 |alpha_W|^2 S_F`` (the run's series is its hub mass's,
    held still)."""
    rigid = (track is None or track.support == "rigid") and (wheel is None or wheel.kind == "rigid")
    if rigid:
        return result
    result.track, result.wheel = structures_record(track, wheel or rigid_wheel(result.params))
    if wheel is not None and wheel.kind != "rigid":
        gain = np.abs(result.omega**2 * transfers(*structures_of(result), result.params,
                                                   result.omega / TWO_PI)["wheel"]) ** 2
        result.accel_psd, result.accel_psd_stderr = gain * result.force_psd, gain * result.force_psd_stderr
    return result
