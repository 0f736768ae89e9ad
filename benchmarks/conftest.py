"""pytest-benchmark suite configuration.

``pytest benchmarks/ --benchmark-only`` times every size in ``--bench-sizes`` (log2 of the points
per line, default 12,14,...,22). Any other run (the plain test command, CI) is the smoke mode: one
tiny size, each benchmark executed once with the timing disabled (``--benchmark-disable``), so the
suite is exercised without slowing or breaking the build.
"""

import pytest

from mdroll.devices import usable_devices

FULL_SIZES = "12,14,16,18,20,22"
SMOKE_SIZES = "12"


def pytest_addoption(parser):
    parser.addoption("--bench-sizes", default=None, help=f"log2 n values (default {FULL_SIZES}; smoke {SMOKE_SIZES})")


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config):
    if not config.getoption("benchmark_only", False):
        config.option.benchmark_disable = True


def bench_sizes(config) -> list[int]:
    text = config.getoption("--bench-sizes") or (FULL_SIZES if config.getoption("benchmark_only", False) else SMOKE_SIZES)
    return [int(x) for x in text.split(",")]


def pytest_generate_tests(metafunc):
    if "device" in metafunc.fixturenames:
        metafunc.parametrize("device", usable_devices())
    if "log2n" in metafunc.fixturenames:
        metafunc.parametrize("log2n", bench_sizes(metafunc.config))


def pytest_benchmark_update_machine_info(config, machine_info):
    from mdroll.provenance import environment

    machine_info["mdroll"] = {d: environment(d) for d in usable_devices()}
