"""The launch shape of the register-blocked force kernels (direct sum, tree): a thread computes
BLOCK consecutive steps of a row (:mod:`mdroll.kernels.common`)."""

from __future__ import annotations

from ..devices import warp
from ..kernels.common import BLOCK


def blocked_launch(kernel, inputs, force, device):
    """The recorded launch of a kernel whose threads compute BLOCK consecutive steps of a row."""
    dim = (force.shape[0], -(-force.shape[1] // BLOCK))
    return warp().launch(kernel, dim=dim, inputs=inputs, device=device, record_cmd=True)
