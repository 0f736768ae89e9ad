"""mdroll.wheel: the rigid wheel is today's mass; the modal wheel's receptance against its modes."""

import argparse
import json
import math

import numpy as np
import pytest

from mdroll import Params, run_ensemble
from mdroll.errors import ParameterError
from mdroll.wheel import PRESETS, STANDARD_920_MODES, Wheel


def test_rigid_wheel_is_the_mass_of_physics_md():
    f = np.geomspace(10, 5000, 50)
    alpha = Wheel.preset("rigid").receptance(f)
    np.testing.assert_allclose(alpha, -1 / (500.0 * (2 * math.pi * f) ** 2), rtol=1e-15)


def test_single_mode_peak_height_and_frequency():
    # one mode far above the suspension: |alpha| at f_n is 1 / (2 zeta m_n omega_n^2) plus the mass line
    wheel = Wheel(kind="modal", mass=600.0, modes=((2000.0, 100.0, 1e-3),))
    f = np.linspace(1900, 2100, 20001)
    alpha = wheel.receptance(f)
    assert f[np.argmax(np.abs(alpha))] == pytest.approx(2000.0, abs=0.05)
    omega_n = 2 * math.pi * 2000.0
    peak = 1 / (2e-3 * 100.0 * omega_n**2)
    assert np.max(np.abs(alpha)) == pytest.approx(peak, rel=0.01)


def test_modal_wheel_below_its_modes_and_at_them():
    wheel = Wheel.preset("standard-920")
    f = np.array([50.0, 200.0])
    # well below the modes: the unsprung mass on its suspension plus the modes' static compliance
    omega = 2 * math.pi * f
    static = sum(1 / (m_n * (2 * math.pi * f_n) ** 2) for f_n, m_n, _ in STANDARD_920_MODES)
    expected = 1 / (1e6 * (1 + 0.1j) - 600.0 * omega**2) + static
    np.testing.assert_allclose(wheel.receptance(f), expected, rtol=2e-3)
    peaks = [wheel.receptance(np.linspace(0.99 * fn, 1.01 * fn, 4001)) for fn, _, _ in STANDARD_920_MODES]
    for (fn, _, _), alpha in zip(STANDARD_920_MODES, peaks):
        grid = np.linspace(0.99 * fn, 1.01 * fn, 4001)
        assert grid[np.argmax(np.abs(alpha))] == pytest.approx(fn, rel=1e-4)


def test_presets():
    assert set(PRESETS) == {"rigid", "standard-920"}
    assert Wheel.preset("rigid").with_values(mass=400.0).mass == 400.0


@pytest.mark.parametrize("kwargs, key", [({"kind": "elastic"}, "wheel.kind"), ({"mass": 0.0}, "wheel.mass"),
                                         ({"suspension_loss": -1.0}, "wheel.suspension_loss"),
                                         ({"kind": "modal", "modes": ((2000.0, -1.0, 0.0),)}, "wheel.modes"),
                                         ({"modes": ((2000.0, 1.0, 0.0),)}, "wheel.modes")])
def test_bad_values_name_their_key(kwargs, key):
    with pytest.raises(ParameterError, match=key):
        Wheel(**kwargs)
    with pytest.raises(ParameterError, match="wheel.colour"):
        Wheel().with_values(colour=1)
    with pytest.raises(ParameterError, match="wheel = 'x'"):
        Wheel.preset("x")


def test_settings_apply_the_preset_then_the_keys():
    wheel = Wheel.from_settings(["wheel.mass=400", "wheel=standard-920", "wheel.suspension_loss=0.2"])
    assert (wheel.kind, wheel.mass, wheel.suspension_loss) == ("modal", 400.0, 0.2)
    assert wheel.modes == PRESETS["standard-920"]["modes"]
    with pytest.raises(ParameterError, match="wheel.mass = 'heavy' is not allowed: it must be a number"):
        Wheel.from_settings({"wheel.mass": "heavy"})
    with pytest.raises(ParameterError, match="wheel.suspension_loss = True .* not a bool"):
        Wheel(suspension_loss=True)


def test_rigid_wheel_mass_is_the_runs_mass(cli, tmp_path):
    """``--set wheel.mass`` of the rigid wheel is the run's m: the CLI's run equals the API's run with
    m = 600; an m given beside it that differs is refused, and so is the API's rigid wheel of
    another mass."""
    from mdroll.cli.common import rigid_wheel_mass

    proc = cli("run", "--mode", "coupled", "--set", "L=0.03", "--set", "dx=2e-5", "--realizations", "1",
               "--device", "cpu", "--no-progress", "--set", "wheel.mass=600", "--out", str(tmp_path / "run"))
    assert proc.returncode == 0, proc.stderr
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["params"]["m"] == 600.0
    params = Params(L=0.03, dx=2e-5)
    direct = run_ensemble(params.replace(m=600.0), seed=0, realizations=1, mode="coupled", device="cpu", progress=False)
    with np.load(tmp_path / "run" / "spectra.npz") as data:
        np.testing.assert_allclose(data["accel_psd"], direct.accel_psd, rtol=1e-12)
    given = argparse.Namespace(set=["m=500", "wheel.mass=600"])
    with pytest.raises(ParameterError, match="wheel.mass = 600 kg is not allowed with m = 500 kg"):
        rigid_wheel_mass(given, params, Wheel(mass=600.0))
    assert rigid_wheel_mass(argparse.Namespace(set=["m=700"]), params.replace(m=700.0), Wheel()) == (
        params.replace(m=700.0), Wheel(mass=700.0))
    with pytest.raises(ParameterError, match="wheel.mass = 600 kg"):
        run_ensemble(params, realizations=1, mode="coupled", wheel=Wheel(mass=600.0), device="cpu", progress=False)
