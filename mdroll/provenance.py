"""Where and with what a result was computed: device name, library versions, date (UTC)."""

from __future__ import annotations

import datetime
import platform

import numpy as np

from .devices import warp


def environment(device: str) -> dict:
    """Device, its name, mdroll / Warp / NumPy / Python (and CuPy, CUDA runtime) versions, platform, date."""
    from ._version import __version__

    wp = warp()
    info = {
        "device": device,
        "device_name": wp.get_device(device).name,
        "mdroll": __version__,
        "warp": wp.config.version,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
    if device.startswith("cuda"):
        import cupy

        info["cupy"] = cupy.__version__
        info["cuda_runtime"] = cupy.cuda.runtime.runtimeGetVersion()
    return info
