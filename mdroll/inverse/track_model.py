"""A known track in the forward model: the force the wheel and the rail feed back on the contact.

On a compliant track the contact force is not the blocked force ``k_c sinc(q a) r`` of the model
(:mod:`mdroll.inverse.forward_model`) but the linear chain's (:mod:`mdroll.track.interaction`)::

    F = k_c sinc(q a) r / (1 + k_c (alpha_W + alpha_R)),     k_c = 2 E* a,

so the model's force PSD is multiplied by ``|1 + k_c (alpha_W + alpha_R)|^-2``, and the wheel's
acceleration at the contact is ``omega^4 |alpha_W|^2`` times the force's (for the rigid wheel
``1 / m^2``: the model's own transfer of section 5.1 with the track rigid). ``k_c`` and the
rigid wheel's mass follow the fitted parameters; the track and a modal wheel are known.

With the sample interval dt of a simulation (an mdroll spectrum), the receptances are those the
run stepped (:mod:`mdroll.ensemble.vibration`: the rail's fitted state space, the modal wheel's
modes, the semi-implicit mass ``-1 / (m w~^2)``); without it (a measured spectrum), the track's
closed-form receptance and the wheel's. The chain is linear: it holds where the contact is kept
and the roughness small against d0 (docs/track.md, the large-roughness study).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .. import physics
from ..track import Track, receptance
from ..ensemble.vibration import rail_form
from ..wheel import Wheel


@dataclass(frozen=True)
class KnownTrack:
    """The track (:class:`~mdroll.track.Track`) and wheel (:class:`~mdroll.wheel.Wheel`) under
    the contact of a spectrum: the module docstring's factor."""

    track: Track
    wheel: Wheel

    def describe(self) -> dict:
        """The track's and the wheel's fields, JSON-ready."""
        return {"track": self.track.as_dict(), "wheel": {"kind": self.wheel.kind, "mass": self.wheel.mass,
                                                         "modes": [list(m) for m in self.wheel.modes]}}

    def gain(self, omega, p: dict, quantity: str, dt: float | None) -> np.ndarray:
        """The factor on the blocked force's PSD at ``omega`` (rad/s, > 0) for parameters ``p``
        (E_star, a, m): the force's, or the wheel acceleration's for ``quantity`` "accel"."""
        omega = np.asarray(omega, dtype=np.float64)
        key = (omega.tobytes(), dt)
        alpha_r = _rail(self.track, key)
        if self.wheel.kind == "rigid":
            w = omega if dt is None else 2.0 * np.sin(0.5 * omega * dt) / dt
            alpha_w = -1.0 / (p["m"] * w**2)
            accel = 1.0 / p["m"] ** 2
        else:
            alpha_w = _wheel(self.wheel, key)
            accel = omega**4 * np.abs(alpha_w) ** 2
        k_c = physics.contact_stiffness(p["E_star"], p["a"])
        force = 1.0 / np.abs(1.0 + k_c * (alpha_w + alpha_r)) ** 2
        return force * accel if quantity == "accel" else force


@functools.lru_cache(maxsize=32)
def _rail(track: Track, key) -> np.ndarray:
    """alpha_R at the frequencies of ``key`` (omega bytes, dt): made once per grid."""
    omega_bytes, dt = key
    f = np.frombuffer(omega_bytes, dtype=np.float64) / physics.TWO_PI
    if track.support == "rigid":
        return np.zeros(f.shape, dtype=complex)
    return receptance(track, f) if dt is None else rail_form(track).discrete_response(f, dt)


@functools.lru_cache(maxsize=32)
def _wheel(wheel: Wheel, key) -> np.ndarray:
    omega_bytes, dt = key
    f = np.frombuffer(omega_bytes, dtype=np.float64) / physics.TWO_PI
    return wheel.receptance(f) if dt is None else wheel.modal_form().discrete_response(f, dt)
