"""The track study (mdroll.railway.track_study) at its test rung: at small roughness the coupled
run on the soft-pad track is the linear chain with the track's closed-form receptance on the same
realizations in every 1/3-octave band; at the EN ISO 3095 limit + 10 dB the rigid rail loses
contact and the chain does not hold in the contact filter's dips."""

import numpy as np
import pytest

from mdroll.railway import track_study
from mdroll.track import Track


@pytest.fixture(scope="module")
def study():
    record = track_study.track_study(track_study.SIZES["test"], seed=0, device="cpu")
    return record, {(c["track"], c["offset_dB"]): c for c in record["cases"]}


def test_track_study_small_roughness_is_the_chain(study):
    """Within 0.5 dB of the chain on the same realizations."""
    record, cases = study
    small = cases[("ballasted-soft-pad", -40.0)]
    assert record["passed"] and small["small_roughness_passed"]
    for values in small["same_realizations"].values():
        assert np.max(np.abs(values)) < track_study.SMALL_DB


def test_track_study_small_and_large_roughness(study):
    record, cases = study
    small = cases[("ballasted-soft-pad", -40.0)]
    assert small["contact_lost_fraction"] == 0.0
    # the bands the comparison covers: 125 Hz (3 bins of 10 Hz) to 5 kHz
    assert small["force"]["frequency_Hz"][0] == 125.0 and small["force"]["frequency_Hz"][-1] == 5000.0
    large = cases[("rigid", 10.0)]
    assert large["contact_lost_fraction"] > 0.01
    # the dips hold the linear chain's zeros: at small roughness only the estimator fills them,
    # at large roughness the lost contact fills them far above it
    for dip_small, dip_large in zip(cases[("rigid", -40.0)]["dips"], large["dips"]):
        assert dip_large["over_linear_dB"] > dip_small["over_linear_dB"] + 10.0


def test_chain_has_the_contact_filter_zeros():
    """The chain's force vanishes where sinc(q a) does, q = n pi / a, whatever the track."""
    p = track_study.SIZES["test"].params
    q = np.array([0.0, np.pi / p.a, 2 * np.pi / p.a, 1.5 * np.pi / p.a])
    force = track_study.chain(p, Track.preset("ballasted-soft-pad"), track_study.iso_spectrum(0.0), q)["force"]
    assert force[0] == 0.0 and force[3] > 0.0
    assert np.all(force[1:3] < 1e-25 * force[3])
