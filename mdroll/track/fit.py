"""The rail's point receptance as a stable modal state space (:mod:`mdroll.statespace`) for the
coupled time-domain dynamics: a vector fit over :data:`FIT_BAND`, made passive by residue
perturbation, with its error stated.

The coupled run steps the passive fit. A track with causal damping (the default,
:func:`mdroll.track.beam.modulus`) has a causal, passive receptance, which the passive fit
follows as closely as the plain one. With hysteretic damping, not causal, the plain vector fit
(``passive=False``) is closer to the closed form in the band, but only through negative losses
below it (``Im H > 0`` at a few Hz, where |H| exceeds the receptance by orders of magnitude):
driven through the contact spring by the wheel, that is an unstable loop, and the passive fit
pays for its passivity with a larger error (docs/track.md, "State space")."""

from __future__ import annotations

import functools

import numpy as np

from mdroll.errors import ParameterError
from mdroll.statespace import ModalForm, error_db, vector_fit

from .response import receptance

#: Band of the fit (Hz) and its samples: wider than the band it must hold (:data:`CHECK_BAND`),
#: so that the fit's edges fall outside it.
FIT_BAND = (25.0, 8000.0)
FIT_SAMPLES = 600
#: Band (Hz) over which the fit's error is stated, and the fit's iterations.
CHECK_BAND = (50.0, 5000.0)
FIT_ITERATIONS = 6
#: The fit's starting pole pairs by the track's damping (docs/track.md, "State space"). Causal:
#: few enough that the presets' fits keep at most 32 modes, one a lane of the coupled kernel's
#: warp (:data:`mdroll.kernels.modal.HELD_MODES`), and follow the closed form within 0.01 dB as
#: with twice as many. Hysteretic: as many as before causal damping existed, so that its runs and
#: their checkpoints stay as they were (fewer fit it worse).
FIT_ORDER = {"causal": 28, "hysteretic": 64}
#: The passive fit's samples reach down to this frequency (Hz), weighted by :data:`PASSIVE_LOW_WEIGHT`
#: below :data:`FIT_BAND`, so that the fit follows the passive receptance there, and its rounds of
#: residue perturbation (:func:`mdroll.statespace.passive_residues`).
PASSIVE_LOW_FREQUENCY = 5.0
PASSIVE_LOW_WEIGHT = 0.02
PASSIVITY_ROUNDS = 30


@functools.lru_cache(maxsize=16)
def rail_modal_form(track, position: str = "sleeper", passive: bool = True) -> ModalForm:
    """The modal form of the rail's point receptance (:func:`~mdroll.track.receptance`) where
    the wheel stands; its ``error_db`` is the largest complex error (dB,
    :func:`mdroll.statespace.error_db`) over :data:`CHECK_BAND` on a grid of 1000 frequencies.
    ``passive`` (the default, the form the coupled run steps): fitted from
    :data:`PASSIVE_LOW_FREQUENCY` and made passive
    (:meth:`~mdroll.statespace.ModalForm.is_passive`; for a hysteretic track at a larger error
    than the plain fit, ``passive=False``: module docstring); a track whose fit the rounds of
    :data:`PASSIVITY_ROUNDS` leave not passive is refused (ParameterError: its coupled loop could
    grow without bound). The rigid track has none (an empty form)."""
    if track.support == "rigid":
        return ModalForm(np.zeros(0, dtype=complex), np.zeros(0, dtype=complex))
    low = PASSIVE_LOW_FREQUENCY if passive else FIT_BAND[0]
    f = np.geomspace(low, FIT_BAND[1], FIT_SAMPLES + round(100 * np.log10(FIT_BAND[0] / low)))
    form = vector_fit(f, receptance(track, f, position), FIT_ORDER[track.damping], *FIT_BAND, iterations=FIT_ITERATIONS,
                      passivity_rounds=PASSIVITY_ROUNDS if passive else 0,
                      weight=np.where(f < FIT_BAND[0], PASSIVE_LOW_WEIGHT, 1.0))
    if passive and not form.is_passive():
        raise ParameterError(f"track = {track!r} is not allowed in a coupled run: its rail receptance "
                             f"({position}) could not be fitted passive in {PASSIVITY_ROUNDS} rounds, and "
                             "its loop with the wheel could grow without bound")
    check = np.geomspace(*CHECK_BAND, 1000)
    error = float(np.max(error_db(form.response(check), receptance(track, check, position))))
    return ModalForm(form.poles, form.residues, error)
