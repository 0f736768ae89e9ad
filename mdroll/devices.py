"""Device selection and array interop between NumPy, Warp and CuPy.

Warp is initialised lazily (its start-up prints a banner and probes CUDA), and CuPy is only
imported on CUDA paths, so ``import mdroll`` stays cheap and works where neither CUDA nor
CuPy is installed.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import sys
from dataclasses import dataclass

import numpy as np

from .errors import DeviceError


@functools.cache
def warp():
    """The initialised ``warp`` module (quiet).

    Where no NVIDIA driver can be loaded, Warp's start-up prints a warning that GPU execution
    is unavailable; a CPU user did not ask for a GPU, so it is kept off stderr (a CUDA device
    asked for then fails in :func:`resolve_device` with one line that says why).
    """
    import logging

    import warp as wp

    wp.config.log_level = logging.WARNING  # no banner, no per-module load lines
    wp.config.enable_backward = False  # forward kernels only: halves compile time
    if cuda_driver_present():
        wp.init()
    else:
        with _native_stderr_silenced():
            wp.init()
    return wp


@functools.cache
def _cuda_driver():
    """The NVIDIA CUDA driver library (ctypes), loaded as Warp looks for it, or None."""
    names = ("nvcuda.dll",) if sys.platform == "win32" else ("libcuda.so", "libcuda.so.1")
    for name in names:
        try:
            return ctypes.CDLL(name)
        except OSError:
            pass
    return None


def cuda_driver_present() -> bool:
    """Whether the NVIDIA CUDA driver library loads (as Warp looks for it)."""
    return _cuda_driver() is not None


@contextlib.contextmanager
def _native_stderr_silenced():
    """Send what native code writes to file descriptor 2 to /dev/null for the duration."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def cpu_cores() -> int:
    """The CPU cores this process may run on."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def available_devices() -> list[str]:
    """Names of the Warp devices present: ``"cpu"`` and ``"cuda:N"`` for each GPU."""
    return [str(d) for d in warp().get_devices()]


def usable_devices() -> list[str]:
    """Devices an ensemble can run on: ``cpu`` always, each CUDA device when CuPy (cuFFT) is installed."""
    devices = ["cpu"]
    if warp().is_cuda_available():
        try:
            import cupy  # noqa: F401
        except ImportError:
            return devices
        devices += [d for d in available_devices() if d.startswith("cuda")]
    return devices


def resolve_device(device: str | None) -> str:
    """Turn ``"auto" | "cpu" | "cuda" | "cuda:N" | None`` into a concrete Warp device name.

    ``"auto"`` and ``None`` pick the first CUDA device when one is present, else the CPU.
    Raises :class:`DeviceError` naming the available devices when the device does not exist,
    and saying how to install CuPy when a CUDA device is asked for without it.
    """
    wp = warp()
    names = available_devices()
    if device is None or device == "auto":
        device = "cuda:0" if wp.is_cuda_available() else "cpu"
    if not isinstance(device, str):
        device = str(device)
    if device == "cuda":
        device = "cuda:0"
    if device not in names:
        why = "" if cuda_driver_present() or not device.startswith("cuda") else " (no NVIDIA driver is installed)"
        raise DeviceError(f"device {device!r} does not exist here{why}; available devices: {', '.join(names)}")
    if device.startswith("cuda"):
        _keep_pool(device)
        try:
            import cupy  # noqa: F401
        except ImportError as exc:  # pragma: no cover - depends on the machine
            raise DeviceError(
                f"device {device!r} needs CuPy for cuFFT: install it with pip install -e '.[cuda]' "
                "(or pip install cupy-cuda12x)"
            ) from exc
    return device


@functools.cache
def _keep_pool(device: str) -> None:
    """Let the CUDA memory pool keep up to half the device's memory on synchronize: freed batch
    buffers are then reused instead of unmapped and mapped again (which costs milliseconds per GB)."""
    wp = warp()
    if wp.is_mempool_supported(device):
        wp.set_mempool_release_threshold(device, 0.5)


@dataclass(frozen=True)
class DeviceLimits:
    """What a CUDA device's multiprocessors hold, for choosing a kernel's launch layout.

    Attributes
    ----------
    multiprocessors : int
        Streaming multiprocessors on the device.
    shared_per_multiprocessor : int
        Shared memory a multiprocessor holds (bytes), all its resident blocks together.
    shared_per_block : int
        Shared memory one block may take (bytes, the opt-in maximum).
    registers_per_multiprocessor : int
        32-bit registers a multiprocessor holds.
    lanes_per_multiprocessor : int
        Threads a multiprocessor keeps resident at once.
    """

    multiprocessors: int
    shared_per_multiprocessor: int
    shared_per_block: int
    registers_per_multiprocessor: int
    lanes_per_multiprocessor: int


#: The CUDA driver's device attributes (``CUdevice_attribute``) that :func:`device_limits` reads.
_MAX_THREADS_PER_MULTIPROCESSOR = 39
_MAX_SHARED_MEMORY_PER_MULTIPROCESSOR = 81
_MAX_REGISTERS_PER_MULTIPROCESSOR = 82


def _driver_attribute(driver, ordinal: int, attribute: int) -> int:
    """One ``cuDeviceGetAttribute`` of CUDA device ``ordinal``; a DeviceError if the driver refuses."""
    handle = ctypes.c_int()
    value = ctypes.c_int()
    status = driver.cuDeviceGet(ctypes.byref(handle), ctypes.c_int(ordinal))
    if status == 0:
        status = driver.cuDeviceGetAttribute(ctypes.byref(value), ctypes.c_int(attribute), handle)
    if status != 0:
        raise DeviceError(f"the CUDA driver gave error {status} for attribute {attribute} of device cuda:{ordinal}")
    return value.value


@functools.cache
def device_limits(device: str) -> DeviceLimits | None:
    """The :class:`DeviceLimits` of CUDA device ``device`` (None for the CPU), queried once per
    device: the multiprocessor count and a block's opt-in shared memory from Warp, the rest from
    the CUDA driver (``cuDeviceGetAttribute``, through ctypes)."""
    if not is_cuda(device):
        return None
    info = warp().get_device(device)
    driver = _cuda_driver()
    if driver is None or driver.cuInit(0) != 0:
        raise DeviceError(f"device {device!r}: the CUDA driver does not load or initialise")
    return DeviceLimits(
        multiprocessors=info.sm_count,
        shared_per_multiprocessor=_driver_attribute(driver, info.ordinal, _MAX_SHARED_MEMORY_PER_MULTIPROCESSOR),
        shared_per_block=info.max_shared_memory_per_block,
        registers_per_multiprocessor=_driver_attribute(driver, info.ordinal, _MAX_REGISTERS_PER_MULTIPROCESSOR),
        lanes_per_multiprocessor=_driver_attribute(driver, info.ordinal, _MAX_THREADS_PER_MULTIPROCESSOR),
    )


def is_cuda(device: str) -> bool:
    return device.startswith("cuda")


def device_of(array) -> str | None:
    """The Warp device an array lives on (``"cpu"`` for NumPy), or None if unknown."""
    if isinstance(array, np.ndarray):
        return "cpu"
    wp = warp()
    if isinstance(array, wp.array):
        return str(array.device)
    if hasattr(array, "__cuda_array_interface__"):
        return f"cuda:{array.device.id}" if hasattr(array, "device") else "cuda:0"
    return None


def to_warp(array, device: str, dtype=None):
    """A float64 Warp array on ``device`` viewing (or, across devices, copying) ``array``."""
    wp = warp()
    dtype = dtype or wp.float64
    if isinstance(array, wp.array):
        if str(array.device) == device:
            return array
        return wp.clone(array, device=device)
    if hasattr(array, "__cuda_array_interface__") and not isinstance(array, np.ndarray):
        out = wp.from_dlpack(array) if hasattr(array, "__dlpack__") else wp.array(array, dtype=dtype)
        return out if str(out.device) == device else wp.clone(out, device=device)
    host = np.ascontiguousarray(array, dtype=np.float64)
    if device == "cpu":
        return wp.array(host, dtype=dtype, device="cpu", copy=False)
    return wp.array(host, dtype=dtype, device=device)


def array_module(array):
    """``cupy`` for a CuPy array, else ``numpy``: the module whose functions apply to ``array``."""
    return __import__("cupy") if type(array).__module__.startswith("cupy") else np


def cupy_view(array):
    """A CuPy array sharing memory with a CUDA Warp array."""
    import cupy

    return cupy.asarray(array)


def cupy_stream(device: str):
    """A CuPy stream context bound to Warp's stream on ``device``, so that work interleaves in order."""
    import cupy

    stream = warp().get_stream(device)
    if hasattr(cupy.cuda.Stream, "from_external") and hasattr(stream, "__cuda_stream__"):
        return cupy.cuda.Stream.from_external(stream)
    return cupy.cuda.ExternalStream(stream.cuda_stream)


def queue_on(device: str):
    """The context in which CuPy work for ``device`` joins Warp's stream there, in order with
    the kernels (a no-op on the CPU, where NumPy runs at once)."""
    return cupy_stream(device) if is_cuda(device) else contextlib.nullcontext()


def synchronize(device: str) -> None:
    """Wait for all work queued on ``device``."""
    warp().synchronize_device(device)
