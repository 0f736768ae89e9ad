"""Batch sizing: how many realizations of a run fit in the memory of a device at once."""

from __future__ import annotations

import sys

from ..devices import is_cuda, warp
from ..errors import ParameterError
from ..params import Params

#: Bytes of device memory per spring of one realization in a batch of the decoupled mode (lines,
#: half spectrum, prefix sums, tree, force, acceleration and FFT work space), for sizing batches.
BYTES_PER_POINT = 96
#: The same in the coupled mode, whose spectra are transformed a few rows at a time
#: (:data:`~mdroll.ensemble.psd.SPECTRA_ROWS`): the line, its prefix sums, the force and the
#: acceleration (8 B each), the lines' cached FFT work space (up to 8 B) and the tree's nodes.
COUPLED_BYTES_PER_POINT = 48
#: Host bytes a run keeps per realization index (the int64 array, the Python list of the result
#: and its JSON text in the checkpoint and spectra file).
BYTES_PER_INDEX = 64


def realization_bytes(params: Params, mode: str = "decoupled") -> int:
    """Device (or host, on the CPU) bytes one realization of a batch of ``mode`` needs:
    :data:`BYTES_PER_POINT` a spring, :data:`COUPLED_BYTES_PER_POINT` in the coupled mode; a
    batch is sized to half the free memory."""
    return (COUPLED_BYTES_PER_POINT if mode == "coupled" else BYTES_PER_POINT) * params.n_points


def free_bytes(device: str) -> int:
    """Free memory of ``device`` (bytes): the CUDA device's, or the host's on the CPU."""
    return warp().get_device(device).free_memory if is_cuda(device) else host_available_bytes()


def check_count_fits(count: int) -> None:
    """Refuse a realization count whose indices alone would not fit in host memory (a MemoryError
    at 1e11), before any array of them is made."""
    need, have = count * BYTES_PER_INDEX, host_available_bytes()
    if need > have:
        raise ParameterError(f"realizations = {count} is not allowed: the run's list of realization indices alone "
                             f"needs {need / 2**30:.3g} GiB of host memory, {have / 2**30:.3g} GiB are available")


def check_run_fits(params: Params, device: str, memory_limit: int | None = None, mode: str = "decoupled") -> None:
    """Refuse, before any work, a line too long for one realization of ``mode`` to fit in half
    the free memory of ``device`` (or of ``memory_limit`` bytes), naming L and dx."""
    need = realization_bytes(params, mode)
    have = free_bytes(device)
    if is_cuda(device) and need > 0.5 * have:  # the pools' unused memory counts as used: hand it back first
        release_pools(device)
        have = free_bytes(device)
    where = f"the {have / 2**30:.3g} GiB free on {device}"
    if memory_limit is not None and memory_limit < have:
        have, where = memory_limit, f"the memory limit of {memory_limit / 2**30:.3g} GiB"
    if need > 0.5 * have:
        raise ParameterError(
            f"L = {params.L!r} m with dx = {params.dx!r} m is too large for {device}: one realization of "
            f"{params.n_points} springs needs {need / 2**30:.3g} GiB ({need // params.n_points} B a spring), more than half "
            f"{where}; reduce L or increase dx"
        )


def check_batch_fits(params: Params, batch: int, device: str, mode: str = "decoupled") -> None:
    """Refuse a batch (given, or kept by a resumed run) whose realizations of ``mode`` cannot fit
    in the free memory of ``device`` at all, naming it, before it fails to allocate."""
    need, have = batch * realization_bytes(params, mode), free_bytes(device)
    if is_cuda(device) and need > have:
        release_pools(device)
        have = free_bytes(device)
    if need > have:
        raise ParameterError(
            f"batch = {batch} is too large for {device}: {batch} realizations of {params.n_points} springs need "
            f"{need / 2**30:.3g} GiB, more than the {have / 2**30:.3g} GiB free; lower batch (or leave it to the "
            "free memory)"
        )


def default_batch(params: Params, device: str, memory_limit: int | None = None, wanted: int | None = None,
                  mode: str = "decoupled") -> int:
    """Realizations of ``mode`` per batch that fit in half the free memory of the device (host RAM
    on CPU), or in half of ``memory_limit`` bytes when that is smaller.

    On CUDA, memory that Warp's and CuPy's pools keep from earlier work counts as used by the
    driver; when that would split a run of ``wanted`` realizations, the pools hand their unused
    memory back first and the device is measured again (a run after larger ones would
    otherwise go in several batches: 2x the time of the coupled dynamics at 300 x 2^20), unless
    they keep the memory of the batch they last gave for the same sizes, which is then reused
    as it is (handing it back and taking it again costs milliseconds per GB), or
    ``memory_limit`` sets the batch.
    """
    per_realization = realization_bytes(params, mode)

    def fitting(free: int) -> int:
        if memory_limit is not None:
            free = min(free, memory_limit)
        return max(1, int(0.5 * free // per_realization))

    if not is_cuda(device):
        return fitting(host_available_bytes())
    global _last_sized
    free = free_bytes(device)
    batch = fitting(free)
    key = (device, per_realization, memory_limit)
    if wanted is not None and batch < wanted and (memory_limit is None or free < memory_limit):
        last_key, last_batch = _last_sized
        if last_key == key and batch < last_batch <= fitting(free + idle_pool_bytes(device)):
            batch = last_batch  # the pools hold the last batch's memory, as this run will use it again
        else:
            release_pools(device)
            batch = fitting(free_bytes(device))
    _last_sized = (key, batch)
    return batch


#: The last batch :func:`default_batch` gave on CUDA and its (device, bytes a realization, memory
#: limit): a next run of the same sizes finds that batch's memory idle in the pools, in the
#: pools its buffers come from, and reuses it without unmapping and mapping it again.
_last_sized: tuple = (None, 0)


def idle_pool_bytes(device: str) -> int:
    """Memory the pools of CUDA ``device`` keep without using it: the stream-ordered pool's
    reserved and unused bytes (Warp's arrays) and CuPy's free blocks."""
    import cupy

    runtime = cupy.cuda.runtime
    pool = runtime.deviceGetDefaultMemPool(warp().get_device(device).ordinal)
    reserved, used = (runtime.memPoolGetAttribute(pool, attribute) for attribute in
                      (runtime.cudaMemPoolAttrReservedMemCurrent, runtime.cudaMemPoolAttrUsedMemCurrent))
    return int(reserved - used) + cupy.get_default_memory_pool().free_bytes()


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
