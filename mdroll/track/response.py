"""The rail's response for any :class:`~mdroll.track.Track`: its point receptance where the
wheel stands and its decay rate, by support model, and the EN ISO 3095 decay-rate limit."""

from __future__ import annotations

import numpy as np

from mdroll.errors import ParameterError

from .beam import continuous_decay_rate, continuous_receptance
from .periodic import discrete_decay_rate, point_receptance

#: Where the wheel stands on a discretely supported rail: above a support or at mid-span.
POSITIONS = ("sleeper", "midspan")

#: The lower limit of the vertical track decay rate of EN ISO 3095:2013 (its Figure 3), dB/m, per
#: 1/3-octave band centre (Hz), 250 Hz to 5 kHz: 2 dB/m at 250-315 Hz, 6 dB/m at 400-630 Hz,
#: 0.8 dB/m from 1 kHz (800 Hz on the straight line between them on log-log axes). As transcribed
#: from the standard's page by the open-source phonometry package (jmrplens/phonometry,
#: ``REFERENCE_TRACK_DECAY_LIMITS_DB_PER_M``), not checked here against a printed copy.
ISO3095_DECAY_BANDS_HZ = (250, 315, 400, 500, 630, 800, 1000, 1250, 1600, 2000, 2500, 3150, 4000, 5000)
ISO3095_DECAY_VERTICAL = (2.0, 2.0, 6.0, 6.0, 6.0, 2.19, 0.8, 0.8, 0.8, 0.8, 0.8, 0.8, 0.8, 0.8)

def receptance(track, f, position="sleeper"):
    """Vertical point receptance of the rail (m/N, complex) at frequencies ``f`` (Hz) for the
    wheel standing at ``position`` (:data:`POSITIONS`; the continuous and rigid tracks have no
    positions): zero for the rigid track, :func:`~mdroll.track.continuous_receptance` or
    :func:`~mdroll.track.periodic.point_receptance` (closed form, x0 = 0 or d / 2)."""
    if position not in POSITIONS:
        raise ParameterError(f"position = {position!r} is not allowed: choose one of {list(POSITIONS)}")
    f = np.asarray(f, dtype=np.float64)
    if track.support == "rigid":
        return np.zeros(f.shape, dtype=complex)
    if track.support == "continuous":
        return continuous_receptance(f, track)
    return point_receptance(f, track, position)


def decay_rate(track, f):
    """Decay rate of the rail (dB/m) at ``f`` (Hz): the least attenuated wave of the continuous
    model, or the least attenuated Floquet wave of the discrete one; infinite for the rigid
    track (nothing propagates)."""
    f = np.asarray(f, dtype=np.float64)
    if track.support == "rigid":
        return np.full(f.shape, np.inf)
    if track.support == "continuous":
        return continuous_decay_rate(f, track)
    return discrete_decay_rate(f, track)


def iso3095_decay_limit():
    """(band centre Hz, vertical decay-rate limit dB/m) of EN ISO 3095:2013 as float arrays."""
    return np.array(ISO3095_DECAY_BANDS_HZ, dtype=np.float64), np.array(ISO3095_DECAY_VERTICAL, dtype=np.float64)
