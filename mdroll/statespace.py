"""Receptances as state-space systems: a modal form (poles and residues), its rational fit by
vector fitting with passive residues, and its exact discretization for a constant time step.

numpy and scipy only.

The modal form of a receptance (displacement per force, m/N; time dependence ``exp(i omega t)``,
``s = i omega``) is::

    H(s) = sum_k [ r_k / (s - p_k) + conj(r_k) / (s - conj(p_k)) ],

one complex state ``q_k`` per term, ``q_k' = p_k q_k + r_k u``, output ``y = 2 Re sum_k q_k``
(a real pole p_k carries half its residue, r_k / 2). Every p_k has Re p_k < 0: it is stable
by construction.

Passive: a receptance is passive where its mobility ``s H(s)`` is positive real,
``Im H(i omega) <= 0`` for omega > 0, decided exactly by :meth:`ModalForm.is_passive`. With the
poles fixed, H is linear in the residues, so :func:`passive_residues` fits them by least squares
and then, where the exact test finds ``Im H > 0``, perturbs them by the least change of the fit
that removes the violations (residue perturbation), round after round until the form is passive
or the rounds are spent.

Vector fitting (Gustavsen & Semlyen 1999, "Rational approximation of frequency domain responses
by vector fitting", IEEE Trans. Power Delivery 14) relocates the poles: starting poles spread
over the band, each iteration solves the linear least-squares problem
``(sum c_k phi_k + d) - h sigma = h`` with ``sigma = 1 + sum c~_k phi_k``, and the zeros of sigma
become the next poles (unstable ones are reflected into the left half-plane).

Exact discretization (zero-order hold: the force constant over a step of length dt)::

    q_k[n+1] = phi_k q_k[n] + gamma_k u[n],   phi_k = exp(p_k dt),
    gamma_k = r_k (exp(p_k dt) - 1) / p_k,

exact for a force held over the step, whatever p_k dt; its transfer function is
``H_d(z) = 2 Re``-pair sum of ``gamma_k / (z - phi_k)`` at ``z = exp(i omega dt)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from mdroll.physics import TWO_PI

#: Largest ``Im H / |H|`` taken as rounding, not a loss of passivity (:meth:`ModalForm.is_passive`);
PASSIVITY_TOLERANCE = 1e-10
#: ``-Im H / |H|`` that :func:`passive_residues` asks for where it constrains: a margin that stops
#: its rounds from closing in on a violation band without ever reaching it.
PASSIVITY_MARGIN = 1e-6
#: Weight of the residues' change itself (scaled unknowns) beside the fit's change in
#: :func:`passive_residues`: it bounds the change in the directions the fitted band does not see.
PERTURBATION_REGULARIZATION = 1e-8
#: Largest ``|Re s| / |s|`` of a zero of ``H(s) - H(-s)`` taken as a candidate crossing of the
#: imaginary axis (:meth:`ModalForm.crossings`): generous, since the pencil's eigenvalues carry the
#: rounding of a fit's cancelling residues, and a candidate that is none only adds a probe to
#: :meth:`ModalForm.is_passive`.
CROSSING_TOLERANCE = 1e-3


@dataclass(frozen=True)
class ModalForm:
    """A receptance (m/N) as modal poles and residues (module docstring): ``poles`` (rad/s,
    complex, Re < 0, one of each conjugate pair: Im >= 0) and ``residues`` (m/(N s), complex;
    a real pole's is half its residue). ``error_db``: the fit's largest error over its check
    band (dB, :func:`error_db`), or 0 for an exact form."""

    poles: np.ndarray
    residues: np.ndarray
    error_db: float = 0.0

    @property
    def order(self) -> int:
        """Number of complex states (modes)."""
        return len(self.poles)

    def response(self, f):
        """H(i omega) (m/N, complex) at frequencies ``f`` (Hz)."""
        s = 1j * TWO_PI * np.asarray(f, dtype=np.float64)[..., None]
        p, r = self.poles, self.residues
        return np.sum(r / (s - p) + np.conj(r) / (s - np.conj(p)), axis=-1)

    def passivity_margin(self, f=None) -> float:
        """The largest ``Im H(i omega) / |H(i omega)|`` over ``f`` (Hz; default 0.001 Hz to
        10 MHz, 100 000 points): at most a rounding error above zero for a passive form."""
        f = np.geomspace(1e-3, 1e7, 100_000) if f is None else f
        h = self.response(f)
        return float(np.max(h.imag / np.abs(h)))

    def crossings(self) -> np.ndarray:
        """The frequencies (Hz, > 0, ascending) where ``Im H(i omega)`` may change sign: the
        (nearly, :data:`CROSSING_TOLERANCE`) imaginary zeros ``s = i omega`` of
        ``Phi(s) = H(s) - H(-s)``, the finite generalized eigenvalues of the pencil
        ``([[A_Phi, B_Phi], [C_Phi, 0]], diag(I, 0))`` of its realization
        ``A_Phi = diag(P, -P)``, ``B_Phi = 1``, ``C_Phi = [C, C]`` (P the poles and their
        conjugates, C their residues): the skew-Hamiltonian/Hamiltonian pencil test of passivity
        (Grivet-Talocia & Gustavsen, *Passive Macromodeling*, Wiley 2016) for a receptance,
        whose mobility ``s H`` has no direct term. The pencil is scaled to the poles' median
        magnitude and the residues' largest."""
        if self.order == 0:
            return np.zeros(0)
        scale = float(np.median(np.abs(self.poles)))
        poles = np.concatenate([self.poles, np.conj(self.poles)]) / scale
        res = np.concatenate([self.residues, np.conj(self.residues)])
        res = res / np.max(np.abs(res))
        n = 2 * len(poles)
        pencil = np.zeros((n + 1, n + 1), dtype=complex)
        pencil[:n, :n] = np.diag(np.concatenate([poles, -poles]))
        pencil[:n, n] = 1.0
        pencil[n, :n] = np.concatenate([res, res])
        mass = np.diag(np.concatenate([np.ones(n), [0.0]]))
        zeros = scipy.linalg.eigvals(pencil, mass)
        zeros = zeros[np.isfinite(zeros)] * scale
        on_axis = (np.abs(zeros.real) <= CROSSING_TOLERANCE * np.abs(zeros)) & (zeros.imag > 0)
        return np.unique(np.round(zeros.imag[on_axis] / TWO_PI, 9))

    def is_passive(self, edges=None) -> bool:
        """Whether ``Im H(i omega) <= 0`` at every omega > 0, decided exactly: Im H keeps its
        sign between two :meth:`crossings` (``edges``, computed if not given), so it is tested at
        one point of each interval between them (and below the first and above the last), with
        :data:`PASSIVITY_TOLERANCE` relative to |H| for rounding. Stability (every Re p < 0) is
        the modal form's own."""
        edges = self.crossings() if edges is None else edges
        if len(edges) == 0:
            probes = np.array([1.0])
        else:
            probes = np.concatenate([[edges[0] / 2], np.sqrt(edges[1:] * edges[:-1]), [2 * edges[-1]]])
        h = self.response(probes)
        return bool(np.all(self.poles.real < 0) and np.all(h.imag <= PASSIVITY_TOLERANCE * np.abs(h)))

    def discretize(self, dt: float):
        """(phi, gamma), complex arrays of the zero-order-hold step of length ``dt`` (s): module
        docstring."""
        phi = np.exp(self.poles * dt)
        return phi, self.residues * np.expm1(self.poles * dt) / self.poles

    def discrete_response(self, f, dt: float):
        """Transfer function (m/N) of :meth:`discretize`'s step at ``z = exp(i omega dt)``, the
        response of the stepped system to a force sampled every dt and held over the step
        (the output one step behind the force, as the coupled step uses it)."""
        phi, gamma = self.discretize(dt)
        z = np.exp(1j * TWO_PI * np.asarray(f, dtype=np.float64)[..., None] * dt)
        return np.sum(gamma / (z - phi) + np.conj(gamma) / (z - np.conj(phi)), axis=-1)

    @staticmethod
    def oscillators(frequency, mass, damping) -> "ModalForm":
        """The exact modal form of a sum of oscillators ``1 / (m (omega_n^2 - omega^2 + 2 i zeta
        omega_n omega))`` (``frequency`` Hz, ``mass`` kg, ``damping`` zeta < 1, arrays)."""
        w = TWO_PI * np.asarray(frequency, dtype=np.float64)
        zeta = np.asarray(damping, dtype=np.float64)
        wd = w * np.sqrt(1.0 - zeta**2)
        poles = -zeta * w + 1j * wd
        return ModalForm(poles, 1.0 / (2j * np.asarray(mass, dtype=np.float64) * wd))

    def __add__(self, other: "ModalForm") -> "ModalForm":
        return ModalForm(np.concatenate([self.poles, other.poles]), np.concatenate([self.residues, other.residues]),
                         max(self.error_db, other.error_db))


def error_db(fitted, reference):
    """The complex error of a fit in dB, ``20 log10(1 + |fit - ref| / |ref|)``: a bound on its
    magnitude error (in dB) that also counts the phase."""
    return 20.0 * np.log10(1.0 + np.abs(np.asarray(fitted) - reference) / np.abs(reference))


def _bases(s, poles):
    """Real-coefficient basis functions of the pole set (one column per real unknown): for a
    complex pair 1/(s-p) + 1/(s-p*) and i/(s-p) - i/(s-p*); for a real pole 1/(s-p)."""
    cols = []
    for p in poles:
        if p.imag == 0:
            cols.append(1.0 / (s - p))
        else:
            cols += [1.0 / (s - p) + 1.0 / (s - np.conj(p)), 1j / (s - p) - 1j / (s - np.conj(p))]
    return np.stack(cols, axis=1)


def _relocate(s, h, weight, poles):
    """One iteration of relaxed vector fitting (Gustavsen 2006, IEEE Trans. Power Delivery 21):
    sigma = d~ + sum c~_k phi_k with the non-triviality row ``Re sum_s sigma(s) = len(s)``; the
    zeros of sigma are the new poles, unstable ones reflected into the left half-plane."""
    phi = _bases(s, poles)
    n = phi.shape[1]
    sigma = np.concatenate([np.ones((len(s), 1)), phi], axis=1)
    lhs = np.concatenate([phi, np.ones((len(s), 1)), -h[:, None] * sigma], axis=1) * weight[:, None]
    a = np.concatenate([lhs.real, lhs.imag])
    relax = np.concatenate([np.zeros(n + 1), np.sum(sigma.real, axis=0)]) * np.linalg.norm(h * weight) / len(s)
    a = np.vstack([a, relax])
    b = np.zeros(len(a))
    b[-1] = np.linalg.norm(h * weight)
    scale = np.linalg.norm(a, axis=0)
    sol = np.linalg.lstsq(a / scale, b, rcond=None)[0] / scale
    d_sigma, c = sol[n + 1], sol[n + 2:]
    # state matrix of sigma / d~ - 1 in real form, minus b c^T / d~: its eigenvalues are sigma's zeros
    A = np.zeros((n, n))
    bvec = np.zeros(n)
    i = 0
    for p in poles:
        if p.imag == 0:
            A[i, i], bvec[i] = p.real, 1.0
            i += 1
        else:
            A[i:i + 2, i:i + 2] = [[p.real, p.imag], [-p.imag, p.real]]
            bvec[i] = 2.0
            i += 2
    zeros = np.linalg.eigvals(A - np.outer(bvec, c) / d_sigma)
    zeros = np.where(zeros.real > 0, -np.conj(zeros), zeros)  # reflect unstable zeros
    return np.sort_complex(zeros[zeros.imag >= 0])


def _residues(poles, x):
    """The residues (module docstring's convention) of the real unknowns x of :func:`_bases`."""
    residues, i = [], 0
    for p in poles:
        if p.imag == 0:
            residues.append(0.5 * x[i])
            i += 1
        else:
            residues.append(x[i] + 1j * x[i + 1])
            i += 2
    return np.array(residues, dtype=complex)


def _violations(form: ModalForm, crossings) -> np.ndarray:
    """Frequencies (Hz) where ``Im H > 0``: the local maxima of ``Im H / |H|`` on 200 points of
    each interval between the form's ``crossings`` (:meth:`ModalForm.crossings`) that violates
    and every tenth point where it does, and for an unbounded last interval also 2, 10, 100 and
    1000 times its start."""
    edges = np.concatenate([[0.0], crossings, [np.inf]])
    points = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        start = lo if lo > 0 else (1e-3 * hi if np.isfinite(hi) else 1e-3)
        grid = np.geomspace(start, hi if np.isfinite(hi) else 1e3 * max(lo, 1e4), 200)[1:-1]
        h = form.response(grid)
        v = np.concatenate([[-np.inf], h.imag / np.abs(h), [-np.inf]])
        bad = v[1:-1] > 0
        peaks = bad & (v[1:-1] >= v[:-2]) & (v[1:-1] >= v[2:])
        points += list(grid[peaks]) + list(grid[bad][::10])
        if peaks.any() and not np.isfinite(hi):
            points += list(lo * np.array([2.0, 10.0, 100.0, 1000.0]))
    return np.array(points)


def _least_distance(g, h):
    """The shortest y with ``g y >= h`` (Lawson & Hanson, *Solving Least Squares Problems*, 1974,
    ch. 23: the least-distance program through non-negative least squares)."""
    e = np.vstack([g.T, h[None, :]])
    f = np.zeros(len(e))
    f[-1] = 1.0
    u = scipy.optimize.nnls(e, f, maxiter=50 * len(e))[0]
    r = e @ u - f
    return -r[:-1] / r[-1]


def passive_residues(s, h, weight, poles, rounds: int):
    """Residues (module docstring's convention) of the least-squares fit of h(s) at the fixed
    ``poles`` (stable, Im >= 0), made passive by residue perturbation (Grivet-Talocia &
    Gustavsen, *Passive Macromodeling*, 2016, ch. 10): Im H is linear in the residues, so each
    round adds the constraints ``Im H <= -PASSIVITY_MARGIN |H|`` at the :func:`_violations`
    of the current form (and ``Im H <= 0`` as omega goes to infinity, the sum of the real parts
    of the residues) and takes the least change of the residues in the weighted fit's norm (plus
    a Tikhonov term of :data:`PERTURBATION_REGULARIZATION` in the scaled unknowns) that meets
    all constraints so far, until :meth:`ModalForm.is_passive` holds or ``rounds`` are spent
    (0: the plain least squares)."""
    basis = _bases(s, poles) * weight[:, None]
    a = np.concatenate([basis.real, basis.imag])
    scale = np.linalg.norm(a, axis=0)
    a = a / scale
    x0 = np.linalg.lstsq(a, np.concatenate([(h * weight).real, (h * weight).imag]), rcond=None)[0]
    form = ModalForm(poles, _residues(poles, x0 / scale))
    r_inv = np.linalg.inv(np.linalg.qr(np.vstack([a, PERTURBATION_REGULARIZATION * np.eye(len(x0))]), mode="r"))
    # -omega Im H as omega -> oo: 2 Re r_k of each pair, the unknown itself of a real pole
    at_infinity = np.concatenate([[1.0] if p.imag == 0 else [2.0, 0.0] for p in poles]) / scale
    points = np.zeros(0)
    for _ in range(rounds):
        edges = form.crossings()
        if form.is_passive(edges):
            break
        points = np.union1d(points, _violations(form, edges))
        rows = np.vstack([_bases(1j * TWO_PI * points, poles).imag / scale, -at_infinity])
        bound = PASSIVITY_MARGIN * np.abs(np.append(form.response(points), 0.0))
        # rows (x0 + r_inv y) <= -bound, i.e. (-rows r_inv) y >= bound + rows x0
        g = -rows @ r_inv
        norm = np.linalg.norm(g, axis=1)
        y = _least_distance(g / norm[:, None], (bound + rows @ x0) / norm)
        form = ModalForm(poles, _residues(poles, (x0 + r_inv @ y) / scale))
    return form.residues


def vector_fit(f, h, order: int, f_lo: float, f_hi: float, iterations: int = 20, passivity_rounds: int = 0,
               weight=None):
    """A stable :class:`ModalForm` of ``order`` pole pairs fitted to the receptance
    ``h`` (m/N, complex) sampled at ``f`` (Hz): vector fitting with relative weights 1/|h|
    (times ``weight``, an array like f, if given), starting poles log-spaced over [f_lo, f_hi] Hz
    with damping 1 %, then :func:`passive_residues` with ``passivity_rounds`` rounds of
    constraints (0: the plain least squares). ``error_db`` is the largest :func:`error_db` over
    the samples."""
    f = np.asarray(f, dtype=np.float64)
    h = np.asarray(h, dtype=complex)
    s = 1j * TWO_PI * f
    weight = (1.0 if weight is None else np.asarray(weight, dtype=np.float64)) / np.abs(h)
    w = TWO_PI * np.geomspace(f_lo, f_hi, order)
    poles = -0.01 * w + 1j * w
    for _ in range(iterations):
        poles = _relocate(s, h, weight, poles)
    form = ModalForm(poles, passive_residues(s, h, weight, poles, passivity_rounds))
    return ModalForm(form.poles, form.residues, float(np.max(error_db(form.response(f), h))))
