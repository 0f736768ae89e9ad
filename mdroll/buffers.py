"""Arrays that a CPU worker of the pipeline keeps from one chunk of realizations to the next.

Fresh memory is expensive on the CPU: a multi-megabyte array is new pages, each zeroed by the
operating system at its first touch (a minor page fault), and freed again when the array goes.
A CPU run whose stages made and dropped about ten such arrays a realization spent a large part
of its time in the system (docs/performance.md, "CPU"). Within :func:`reused`, :func:`empty` hands out
under each name the same memory again, so that a worker touches its pages once per run.

Only the stages of one chunk may hold such an array: whatever leaves the chunk (its sums and
moments) is made by ``wp.empty``.
"""

from __future__ import annotations

import contextlib
import threading

import numpy as np

from .devices import is_cuda, warp

_current = threading.local()


#: Bytes at which the rows of an ``aligned`` buffer start (FFTW's SIMD plans run on such rows
#: in place; on others they go through a copy).
ROW_ALIGNMENT = 64


class Buffers:
    """Named arrays on the CPU, each as large as the largest asked for under its name."""

    def __init__(self):
        self._arrays = {}

    def empty(self, name: str, shape: tuple, dtype, aligned: bool = False):
        """An uninitialized Warp array of ``shape``: the first rows of the one kept under
        ``name``, which is replaced by a larger one when it has too few rows or other columns.
        ``aligned`` (2D): each row starts at a multiple of :data:`ROW_ALIGNMENT` bytes (the
        array is then a strided view, its rows padded)."""
        wp = warp()
        rows, *columns = (int(s) for s in shape)
        if aligned:
            per_row = ROW_ALIGNMENT // wp.types.type_size_in_bytes(dtype)
            columns[-1] = -(-columns[-1] // per_row) * per_row
        kept = self._arrays.get(name)
        if kept is None or kept.dtype != dtype or list(kept.shape[1:]) != columns or kept.shape[0] < rows:
            kept = self._arrays[name] = _host_array((rows, *columns), dtype)
        view = kept if kept.shape[0] == rows else kept[:rows]
        return view[:, : shape[1]] if aligned and columns[-1] != shape[1] else view


def _host_array(shape: tuple, dtype):
    """A Warp CPU array of ``shape`` in memory from NumPy, aligned to :data:`ROW_ALIGNMENT`: NumPy
    asks Linux for transparent huge pages for arrays of 4 MiB and more (``madvise``), which
    Warp's own allocation does not, and FFTs into such memory run faster (docs/performance.md,
    "CPU")."""
    wp = warp()
    nbytes = int(np.prod(shape)) * wp.types.type_size_in_bytes(dtype)
    raw = np.empty(nbytes + ROW_ALIGNMENT, dtype=np.uint8)
    start = -raw.ctypes.data % ROW_ALIGNMENT
    array = wp.array(ptr=raw.ctypes.data + start, dtype=dtype, shape=shape, device="cpu")
    array._owner = raw  # the memory lives as long as the array
    return array


@contextlib.contextmanager
def reused(buffers: Buffers):
    """Within the block, this thread's :func:`empty` on the CPU draws from ``buffers``."""
    previous = getattr(_current, "buffers", None)
    _current.buffers = buffers
    try:
        yield buffers
    finally:
        _current.buffers = previous


def empty(name: str, shape: tuple, dtype, device: str, aligned: bool = False):
    """``wp.empty(shape, dtype, device)``, or, on the CPU within :func:`reused`, the memory kept
    under ``name`` (valid until this thread asks for ``name`` again). ``aligned``: see
    :meth:`Buffers.empty`."""
    buffers = getattr(_current, "buffers", None)
    if buffers is None or is_cuda(device):
        return warp().empty(shape, dtype=dtype, device=device)
    return buffers.empty(name, shape, dtype, aligned)
