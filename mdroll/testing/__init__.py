"""Testing helpers for a user's own approximations, with the pytest plugin :mod:`mdroll.testing.plugin`.

A check in a user's test suite (the plugin is registered through the ``pytest11`` entry point,
or ``-p mdroll.testing.plugin``)::

    from mdroll import EnsembleSpec, Params
    from mdroll.testing import assert_spectrum_matches

    def my_low_band(q, params):          # the approximation under test: C_F(q) in N^2 m
        ...

    def test_my_low_band(mdroll_ensemble):
        spec = EnsembleSpec(Params(L=0.2, dx=2e-5), realizations=16, boundary="periodic", window=False)
        result = mdroll_ensemble(spec)   # run once, then read from the ensemble cache
        assert_spectrum_matches(result, my_low_band, (0.0, 0.5), allowance=0.10)

Nothing heavy is imported here: the check API is imported when an assertion runs.
"""

from __future__ import annotations

#: Bins listed in a failure message at most (those farthest from the prediction).
LISTED_BINS = 12


def assert_spectrum_matches(result, prediction, band, comparison: str = "ratio", allowance: float = 0.05,
                            k: float = 3.0, quantity: str = "force", reference=None, name: str | None = None):
    """Assert that ``result`` (an :class:`mdroll.EnsembleResult`) matches ``prediction`` on ``band``.

    ``prediction(x, params)``: the band's bins ``x`` (q in rad/m, or omega in rad/s for a band
    in omega_0 or rad/s) and the ensemble's :class:`mdroll.Params` -> a PSD on ``x`` (N^2 m
    for the force, (m/s^2)^2 m for the acceleration) or a scalar (slope, period, peak, or the
    ratio to a ``reference`` result). ``band``: a :class:`mdroll.validation.Band` or ``(lo, hi)``
    in multiples of q_min. ``comparison``, ``allowance``, ``k``, ``quantity``: as for
    :class:`mdroll.validation.Check` (tolerance: allowance + k standard errors, the ensemble's).

    Returns the :class:`~mdroll.validation.CheckResult`; raises AssertionError with measured vs
    predicted, the ratio, the tolerance and the bins when it fails.
    """
    __tracebackhide__ = True  # pytest shows the caller's line and this message, not this helper
    import numpy as np

    from ..validation.api import Band, Check
    from ..validation.report import message

    if not isinstance(band, Band):
        band = Band(*band)
    name = name or getattr(prediction, "__name__", "prediction")
    check = Check(name, None, prediction, band, comparison, allowance, k, quantity)
    outcome = check.evaluate(result, reference)
    if outcome.passed:
        return outcome
    x = band.axis(result)
    mask = band.mask(x, result.params)
    psd = getattr(result, f"{quantity}_psd")[mask]
    lines = [message(outcome), f"bins: {int(mask.sum())} in {band.text()} ({x[mask][0]:.6g} .. {x[mask][-1]:.6g} "
                               f"{'rad/s' if band.on_omega else 'rad/m'})"]
    predicted = np.asarray(prediction(x[mask], result.params), dtype=np.float64)
    if predicted.ndim:
        ratio = psd / predicted
        worst = np.sort(np.argsort(-np.abs(np.log(np.abs(ratio))))[:LISTED_BINS])
        lines.append(f"{'x':>14} {'measured':>14} {'predicted':>14} {'ratio':>9}   ({len(worst)} farthest bins)")
        lines += [f"{x[mask][i]:>14.6g} {psd[i]:>14.6g} {predicted[i]:>14.6g} {ratio[i]:>9.4f}" for i in worst]
    raise AssertionError("\n".join(lines))


__all__ = ["assert_spectrum_matches"]
