"""Batch sizing: how many realizations of a run fit in the memory of a device at once."""

from __future__ import annotations

import sys

from ..devices import is_cuda, warp
from ..params import Params

#: Bytes of device memory per spring of one realization in a batch (lines, half spectrum,
#: prefix sums, tree, force, acceleration and FFT work space), for sizing batches.
BYTES_PER_POINT = 96


def default_batch(params: Params, device: str, memory_limit: int | None = None, wanted: int | None = None) -> int:
    """Realizations per batch that fit in half the free memory of the device (host RAM on CPU),
    or in half of ``memory_limit`` bytes when that is smaller.

    On CUDA, memory that Warp's and CuPy's pools keep from earlier work counts as used by the
    driver; when that would split a run of ``wanted`` realizations, the pools hand their unused
    memory back first and the device is measured again (a run after larger ones would
    otherwise go in several batches: 2x the time of the coupled dynamics at 300 x 2^20).
    """
    per_realization = BYTES_PER_POINT * params.n_points

    def fitting(free: int) -> int:
        if memory_limit is not None:
            free = min(free, memory_limit)
        return max(1, int(0.5 * free // per_realization))

    if not is_cuda(device):
        return fitting(host_available_bytes())
    wp = warp()
    batch = fitting(wp.get_device(device).free_memory)
    if wanted is not None and batch < wanted:
        release_pools(device)
        batch = fitting(wp.get_device(device).free_memory)
    return batch


def release_pools(device: str) -> None:
    """Return the unused memory of CuPy's pool and of Warp's stream-ordered pool to the driver
    (Warp's pool trims to its release threshold at a synchronization)."""
    wp = warp()
    if "cupy" in sys.modules:
        sys.modules["cupy"].get_default_memory_pool().free_all_blocks()
    if wp.is_mempool_supported(device) and wp.is_mempool_enabled(device):
        threshold = wp.get_mempool_release_threshold(device)
        wp.set_mempool_release_threshold(device, 0)
        wp.synchronize_device(device)
        wp.set_mempool_release_threshold(device, threshold)


def host_available_bytes() -> int:
    """The kernel's estimate of the host memory available to a new process (MemAvailable), or 4 GiB
    where /proc/meminfo cannot be read."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 4 * 2**30
