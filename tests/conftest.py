"""Shared fixtures: every test taking ``device`` runs once per device an ensemble can use (CPU
always, each CUDA device when CuPy is present), one taking ``kernel_device`` once per device
Warp sees (the force kernels need no CuPy), in the style of Warp's own test suite; ``cli`` runs
``python -m mdroll`` and ``one_line_error`` checks a usage error."""

import subprocess
import sys
from pathlib import Path

import pytest

from mdroll.devices import available_devices, usable_devices

ROOT = Path(__file__).resolve().parents[1]


def pytest_generate_tests(metafunc):
    if "device" in metafunc.fixturenames:
        metafunc.parametrize("device", usable_devices())
    if "kernel_device" in metafunc.fixturenames:
        metafunc.parametrize("kernel_device", available_devices())


@pytest.fixture
def cuda_devices():
    return [d for d in usable_devices() if d.startswith("cuda")]


@pytest.fixture
def kernel_cuda_devices():
    """The CUDA devices Warp sees, with or without CuPy."""
    return [d for d in available_devices() if d.startswith("cuda")]


def _cli(*args, cwd=ROOT, **kwargs):
    return subprocess.run([sys.executable, "-m", "mdroll", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=300, **kwargs)


def _one_line_error(proc, needle):
    """Exit code 2 and exactly one line on stderr, containing ``needle``: no traceback, and no
    warning about a missing GPU when none was asked for."""
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and needle in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.fixture
def cli():
    """``cli(*args, cwd=ROOT, **subprocess options)``: run ``python -m mdroll *args``, output captured."""
    return _cli


@pytest.fixture
def one_line_error():
    return _one_line_error
