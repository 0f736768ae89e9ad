"""The mdroll pytest plugin (entry point ``pytest11``: ``mdroll = "mdroll.testing.plugin"``).

Fixtures
--------
``mdroll_ensemble``
    A factory: ``mdroll_ensemble(spec)`` returns the :class:`mdroll.EnsembleResult` of an
    :class:`mdroll.EnsembleSpec`, from the ensemble cache when it holds it, else run on
    ``mdroll_device`` and stored (:mod:`mdroll.validation.cache`; shared by a session).
``mdroll_device``
    The device the ensembles run on; a test using it (or ``mdroll_ensemble``) runs once per
    ``--mdroll-device`` given (``cpu`` by default).

Options: ``--mdroll-device cpu|cuda`` (repeatable), ``--mdroll-cache-dir DIR`` (default
``MDROLL_CACHE_DIR``, else ``~/.cache/mdroll/ensembles``), ``--mdroll-no-cache``.

Only pytest is imported with the plugin; mdroll's check API when a fixture is first used.
"""

from __future__ import annotations

import pytest

DEVICES = ("cpu", "cuda")


def pytest_addoption(parser):
    group = parser.getgroup("mdroll", "mdroll ensembles")
    group.addoption("--mdroll-device", action="append", choices=DEVICES, default=None,
                    help="device of the mdroll_ensemble fixture (repeatable: tests run once per device; default cpu)")
    group.addoption("--mdroll-cache-dir", default=None, metavar="DIR",
                    help="ensemble cache (default $MDROLL_CACHE_DIR, else ~/.cache/mdroll/ensembles)")
    group.addoption("--mdroll-no-cache", action="store_true", help="run every ensemble, store none")


def pytest_generate_tests(metafunc):
    if "mdroll_device" in metafunc.fixturenames:
        devices = metafunc.config.getoption("mdroll_device") or ["cpu"]
        metafunc.parametrize("mdroll_device", list(dict.fromkeys(devices)), scope="session")


@pytest.fixture(scope="session")
def _mdroll_sources(request):
    """One ensemble source per device for the session, sharing the cache."""
    from mdroll.validation.cache import EnsembleCache

    config = request.config
    cache = None if config.getoption("mdroll_no_cache") else EnsembleCache(config.getoption("mdroll_cache_dir"))
    return {"cache": cache}


@pytest.fixture
def mdroll_ensemble(mdroll_device, _mdroll_sources):
    """``mdroll_ensemble(spec) -> EnsembleResult`` on ``mdroll_device``, through the cache."""
    from mdroll.validation.ensembles import EnsembleSource

    if mdroll_device not in _mdroll_sources:
        _mdroll_sources[mdroll_device] = EnsembleSource(mdroll_device, cache=_mdroll_sources["cache"])
    return _mdroll_sources[mdroll_device].result
