"""The contact point's modal state space in the coupled dynamics (:mod:`mdroll.kernels.dynamics`),
stepped with an exact look-ahead that keeps the sum over a warp's lanes off the step's chain.

The zero-order-hold step of a modal state space (:class:`mdroll.statespace.ModalForm`), per mode
k ``q_k(t + 1) = phi_k q_k(t) + gamma_k u_t`` (complex) with output ``y_t = 2 Re sum_k q_k(t)``,
gives, m = :data:`LOOKAHEAD` steps ahead::

    y_{s+1} = P(s + 1 - m) + sum_{j<m} h_j u_{s-j},   P(t) = 2 Re sum_k phi_k^m q_k(t),
    h_j = 2 Re sum_k phi_k^j gamma_k,

exactly. A lane carries ``w_k = phi_k^m q_k`` of its modes (``w_k(t + 1) = phi_k w_k(t) +
phi_k^m gamma_k u_t``: the same step, its input scaled), so that its part of P(t) is ``2 Re
sum w_k``, known m - 1 steps before the output needs it: the sum over the warp's lanes takes
one butterfly level a step (:func:`~mdroll.kernels.intrinsics.pipelined_sums`), the levels of
the sums in flight independent of each other and of the step's force, and the step's chain
keeps only ``h_0 u_s``; the other taps weigh forces of steps already taken, added up ahead
(:func:`modal_update`). On the CPU, one lane a block, the sums pass the same pipeline
unchanged.
"""

import warp as wp

from .intrinsics import PIPELINE_LEVELS, PipelineSums

#: Steps ahead m of the look-ahead: a lane's part of P(t) enters the butterfly the step after it
#: is stepped, one level a step, and the whole sum enters the output of the step after its last
#: level.
LOOKAHEAD = PIPELINE_LEVELS + 1

#: The taps h_0 ... h_{m-1} of the look-ahead (m): the outputs' responses to a force held over
#: the step 1 ... m steps before.
ModalTaps = wp.types.vector(length=LOOKAHEAD, dtype=wp.float64)

#: The parts of the outputs to come known so far: those of y_{s+1} ... y_{s+m-1} at step s.
ModalComing = wp.types.vector(length=LOOKAHEAD - 1, dtype=wp.float64)


@wp.struct
class Modes:
    """A modal state space stepped with the look-ahead of :data:`LOOKAHEAD` steps (module
    docstring): per mode k ``phi_k`` and the input's coefficient ``phi_k^m gamma_k`` (complex),
    the taps ``h_j`` and the count of modes."""

    phi_re: wp.array(dtype=wp.float64)
    phi_im: wp.array(dtype=wp.float64)
    input_re: wp.array(dtype=wp.float64)
    input_im: wp.array(dtype=wp.float64)
    taps: ModalTaps
    n: int


#: Modes a lane keeps in registers over the steps (on CUDA 32 modes a realization: the causal
#: track presets' fits, :data:`mdroll.track.fit.FIT_ORDER`); the rest in the state array, read and
#: written every step. One: each more held mode's six registers cost the helped kernels, at
#: their register cap, more than its loads save (docs/performance.md, "Track").
HELD_MODES = 1
held_modes = wp.types.vector(length=6 * HELD_MODES, dtype=wp.float64)


@wp.func
def held_coefficients(modes: Modes, lane: int, lanes: int) -> held_modes:
    """The zero states and the step's coefficients ``(phi_re, phi_im, input_re, input_im)`` of
    this lane's first :data:`HELD_MODES` modes, in registers for :func:`modal_step`."""
    held = held_modes()
    for j in range(HELD_MODES):
        k = lane + j * lanes
        if k < modes.n:
            held[6 * j + 2] = modes.phi_re[k]
            held[6 * j + 3] = modes.phi_im[k]
            held[6 * j + 4] = modes.input_re[k]
            held[6 * j + 5] = modes.input_im[k]
    return held


@wp.func
def modal_step(modes: Modes, state: wp.array2d(dtype=wp.vec2d), r: int, u: wp.float64, lane: int, lanes: int,
               held: held_modes):
    """Steps the modes ``lane, lane + lanes, ...`` of realization r (their ``w_k``) over one
    time step under the force u (N), held over the step: the first :data:`HELD_MODES` in
    ``held`` (each its state re, im and :func:`held_coefficients`), the others in ``state[r,
    k]``. Returns this lane's part ``2 Re sum w_k`` (m) of P at the next step, and ``held``
    stepped."""
    part = wp.float64(0.0)
    for j in range(HELD_MODES):
        if lane + j * lanes < modes.n:
            re = held[6 * j + 2] * held[6 * j] - held[6 * j + 3] * held[6 * j + 1] + held[6 * j + 4] * u
            im = held[6 * j + 2] * held[6 * j + 1] + held[6 * j + 3] * held[6 * j] + held[6 * j + 5] * u
            held[6 * j] = re
            held[6 * j + 1] = im
            part += re
    for k in range(lane + HELD_MODES * lanes, modes.n, lanes):
        w = state[r, k]
        re = modes.phi_re[k] * w[0] - modes.phi_im[k] * w[1] + modes.input_re[k] * u
        im = modes.phi_re[k] * w[1] + modes.phi_im[k] * w[0] + modes.input_im[k] * u
        state[r, k] = wp.vec2d(re, im)
        part += re
    return wp.float64(2.0) * part, held


@wp.func
def modal_update(modes: Modes, state: wp.array2d(dtype=wp.vec2d), r: int, u: wp.float64, lane: int, lanes: int,
                 held: held_modes, sums: PipelineSums, coming: ModalComing):
    """Step s of the modal state space under its force u (N), ``sums`` advanced by one level at
    the top of the step (:func:`~mdroll.kernels.intrinsics.pipelined_sums`: its last entry the
    whole P(s + 2 - m)) and ``coming`` the parts of y_{s+1} ... y_{s+m-1} known before u.
    Returns y_{s+1} (m), the same in every lane, then ``held``, ``sums`` with this lane's part
    of P(s + 1) first, and ``coming`` for the next step."""
    y = coming[0] + modes.taps[0] * u
    after = ModalComing()
    for j in range(LOOKAHEAD - 2):
        after[j] = coming[j + 1] + modes.taps[j + 1] * u
    after[LOOKAHEAD - 2] = modes.taps[LOOKAHEAD - 1] * u
    after[0] += sums[LOOKAHEAD - 1]
    part, stepped = modal_step(modes, state, r, u, lane, lanes, held)
    sums[0] = part
    return y, stepped, sums, after
