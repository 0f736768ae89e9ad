"""Shared fixtures: every test taking ``device`` runs once per available device (CPU always,
each CUDA device when CuPy is present), in the style of Warp's own test suite."""

import pytest

from mdroll.devices import usable_devices


def pytest_generate_tests(metafunc):
    if "device" in metafunc.fixturenames:
        metafunc.parametrize("device", usable_devices())


@pytest.fixture
def cuda_devices():
    return [d for d in usable_devices() if d.startswith("cuda")]
