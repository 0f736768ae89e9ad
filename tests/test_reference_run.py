"""The spectra of small stored ensembles (``tests/make_reference_run.py``) are reproduced to
rounding on every device: a restructuring of the code must leave the physics as it was. To
rounding: within 1e-9 of each bin, or within 1e-13 of the spectrum's largest bin, whose rounding
a bin many decades below it carries in the coupled mode (the force feeds back into every step)."""

import numpy as np
import pytest

from make_reference_run import CASES, PATH, run_case


@pytest.mark.parametrize("name", sorted(CASES))
def test_reference_run_spectra_unchanged(name, device):
    stored = np.load(PATH)
    result = run_case(name, device)
    for quantity in ("force_psd", "accel_psd"):
        reference = stored[f"{name}/{quantity}"]
        assert getattr(result, quantity).shape == reference.shape
        np.testing.assert_allclose(getattr(result, quantity), reference, rtol=1e-9, atol=1e-13 * reference.max(),
                                   err_msg=f"{name} {quantity}")
