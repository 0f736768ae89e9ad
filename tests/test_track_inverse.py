"""The inverse fit with a known track: the forward model's linear chain against the section 5.1
transfer (rigid track) and against mdroll.track.interaction (a compliant one), the readers, and
the round trip at its test rung."""

import dataclasses

import numpy as np
import pytest

from mdroll import ParameterError, Params
from mdroll.inverse.forward_model import Setting, expected_psd
from mdroll.inverse.track_model import KnownTrack
from mdroll.track import Track, linear_chain, receptance
from mdroll.wheel import Wheel

P = Params()
PARAMS = {"H": P.H, "q_min": P.q_min, "q_max": P.q_max, "a": P.a, "E_star": P.E_star, "h0": P.h0, "R": P.R,
          "m": P.m, "a_jitter": 0.0, "low_scale": 1.0, "zeta": 0.0, "noise": 0.0, "leak": 0.0}
OMEGA = 2 * np.pi * np.geomspace(50.0, 20000.0, 60)
RIGID = KnownTrack(Track.preset("rigid"), Wheel.preset("rigid"))
SOFT = KnownTrack(Track.preset("ballasted-soft-pad"), Wheel.preset("rigid"))


@pytest.mark.parametrize("dt", [None, P.dt])
def test_rigid_track_is_the_wheel_on_the_contact_spring(dt):
    """The chain on the rigid rail under the rigid wheel is section 5.1's transfer
    w~^4 / (k_c - m w~^2)^2 on the blocked force, with and without the simulation's step."""
    plain = Setting("accel", P.v0, dt)
    np.testing.assert_allclose(expected_psd(OMEGA, PARAMS, dataclasses.replace(plain, known_track=RIGID)),
                               expected_psd(OMEGA, PARAMS, plain), rtol=1e-9)


def test_compliant_track_is_the_linear_chain():
    """Force and wheel acceleration over the blocked force, against mdroll.track.linear_chain
    with the track's closed-form receptance (a measured spectrum: no dt)."""
    f = OMEGA / (2 * np.pi)
    alpha_w = -1.0 / (P.m * OMEGA**2)
    chain = linear_chain(f, np.ones_like(f), alpha_w, receptance(SOFT.track, f), P.k_contact, P.a, P.v0)
    ratio = chain["force"] / chain["blocked_force"]
    for quantity, expected in (("force", ratio), ("accel", ratio / P.m**2)):
        plain = Setting(quantity, P.v0)
        blocked = expected_psd(OMEGA, PARAMS, Setting("force", P.v0))
        got = expected_psd(OMEGA, PARAMS, dataclasses.replace(plain, known_track=SOFT)) / blocked
        np.testing.assert_allclose(got, expected, rtol=1e-9)
    assert np.max(np.abs(10 * np.log10(ratio))) > 3.0  # the track matters in this band


def test_simulated_correction_is_refused_on_a_track():
    from mdroll.inverse import fit
    from mdroll.inverse.observed import Spectrum

    spectrum = Spectrum(OMEGA, expected_psd(OMEGA, PARAMS, Setting("accel", P.v0)), v0=P.v0, passes=10,
                        known_track=SOFT)
    with pytest.raises(ParameterError, match="correction = 'simulated' is not allowed on a known track"):
        fit(spectrum, known={"m": P.m, "R": P.R}, correction="simulated")
