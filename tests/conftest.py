"""Shared fixtures: every test taking ``device`` runs once per available device (CPU always,
each CUDA device when present), in the style of Warp's own test suite."""

import pytest

from mdroll.devices import available_devices, warp


def test_devices() -> list[str]:
    wp = warp()
    devices = ["cpu"]
    if wp.is_cuda_available():
        try:
            import cupy  # noqa: F401

            devices += [d for d in available_devices() if d.startswith("cuda")]
        except ImportError:
            pass
    return devices


test_devices.__test__ = False  # a helper, not a test


def pytest_generate_tests(metafunc):
    if "device" in metafunc.fixturenames:
        metafunc.parametrize("device", test_devices())


@pytest.fixture
def cuda_devices():
    return [d for d in test_devices() if d.startswith("cuda")]
