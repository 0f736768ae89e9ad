"""The inverse fit with a known track: a round trip.

An ensemble is simulated in coupled mode on a compliant track (:func:`mdroll.run_ensemble` with
``track=``), its wheel-acceleration spectrum inverted with the track known (the forward model's
linear chain, :mod:`mdroll.inverse.track_model`, read from the run's record) and, for contrast,
with the track ignored (the rigid rail's model of section 5.1), and the estimates compared with
the truth as the round-trip study compares them (:func:`mdroll.inverse.roundtrip._compare`:
errors, 95 % intervals, coverage). The fit knows m, R, E, nu and v0 (a band above the contact
resonance tells E* from h0 only through the track's k_c) and fits H, q_min, a, h0 and a_jitter;
correction "none" (the simulated correction rolls on the rigid rail) with the closed form's
discrepancy prior of a table (:data:`mdroll.inverse.discrepancy.DISCREPANCY`), the roughness kept
small against d0, where the chain is linear. Open record with the Hann window.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

from ..ensemble.pipeline import run_ensemble
from ..experiments import Ladder, provenance
from ..params import Params
from ..physics import TWO_PI
from ..track import Track
from .discrepancy import DISCREPANCY
from .fit import fit
from .observed import from_result
from .roundtrip import KNOWN, _compare


@dataclass(frozen=True)
class KnownTrackSize:
    """A rung: the truth (its line), the realizations and the track preset."""

    truth: Params
    realizations: int
    track: str = "ballasted-soft-pad"


#: h0 = 0.1 um keeps the contact linear; the band (Hz) holds q_min (2 kHz at v0 = 10 m/s) and the
#: low band below it, where the soft-pad track changes the force by several dB.
_TRUTH = {"h0": 1e-7}
BAND_HZ = (300.0, 20000.0)
SIZES = Ladder(
    test=KnownTrackSize(Params(L=0.25, dx=1e-5, **_TRUTH), 8),
    quick=KnownTrackSize(Params(L=0.5, dx=1e-5, **_TRUTH), 32),
    full=KnownTrackSize(Params(L=5.24288, dx=5e-6, **_TRUTH), 300),
)


def known_track_round_trip(rung: str = "quick", seed: int = 0, device: str = "auto") -> dict:
    """The round trip of the module docstring at the rung ``rung`` of :data:`SIZES`: a JSON-ready
    record with one row for the track known and one for the track ignored (estimates, ci95,
    error, covered, gof)."""
    size = SIZES.rung(rung)
    truth = size.truth
    t0 = time.perf_counter()
    result = run_ensemble(truth, seed=seed, realizations=size.realizations, mode="coupled",
                          track=Track.preset(size.track), device=device, progress=False)
    spectrum = from_result(result, "accel")
    t1 = time.perf_counter()
    known = {k: getattr(truth, k) for k in (*KNOWN, "E", "nu")}
    rows = []
    for label, observed in (("known", spectrum), ("ignored", dataclasses.replace(spectrum, known_track=None))):
        start = time.perf_counter()
        fitted = fit(observed, known=known, band=tuple(TWO_PI * f for f in BAND_HZ), profile=False, correction="none",
                     discrepancy=DISCREPANCY, device=device)
        rows.append(_compare(fitted, spectrum.truth, {"track": label, "fit_s": time.perf_counter() - start,
                                                      "accepted": fitted.accepted}))
    return {**provenance(device, rung, seed, dataclasses.asdict(size)), "track": size.track,
            "realizations": size.realizations, "steps": result.steps, "contact_lost_steps": result.contact_lost_steps,
            "simulate_s": t1 - t0, "rows": rows}
