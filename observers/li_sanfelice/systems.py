"""The observers of Li & Sanfelice as :class:`hybridsim.HybridSystem` subclasses.

=================================  =============================================
(2) Luenberger observer            :class:`LuenbergerObserver`
(3), (10)-(12) H_n                 :class:`NominalObserver`
H_n with a jump window             :class:`WindowedNominalObserver` (``hs.explore``)
(7)-(9), (17)-(18) H_c             :class:`ConstantNoiseObserver`
Section IV-E H_pc                  :class:`PiecewiseConstantNoiseObserver`
bounded noise for batches          :class:`BoundedNoiseGenerator`
H_n on a family of designs         :class:`RotatingFamily` (falsification)
=================================  =============================================

Each observer's input is the measured output y = H x + m (decision 2), its
output the estimate x̄ = a1 x̂1 + a2 x̂2 (footnote 2). Run one with its plant
through :func:`observers.li_sanfelice.simulate`.

H_n, H_c, H_pc and :class:`BoundedNoiseGenerator` are ``vectorized``: their
maps also take batches (x of shape (N, r), t, j of shape (N,), y of shape
(N, p)), so a Monte Carlo of noise realisations (:func:`noise_batch`) runs
through :func:`hybridsim.simulate_many`'s batch integrator, all rows at once.

Examples
--------
>>> from observers.li_sanfelice import NominalObserver, example_VB
>>> obs = NominalObserver(example_VB())
>>> obs.state_dim, sorted(obs.slices)          # (x̂1, x̂2, tau, q) of (10)
(6, ['q', 'tau', 'xh1', 'xh2'])
"""
from __future__ import annotations

import functools
import math
import warnings

import numpy as np
from scipy.linalg import expm

import hybridsim as hs
from observers._common import matrix, vector

from .design import (
    _WARN_HT_INV,
    Design,
    L_tilde,
    Xi_matrix,
    _check_plant,
    _hidden_unstable_mode,
    alpha_max,
)

__all__ = [
    "NominalObserver",
    "WindowedNominalObserver",
    "ConstantNoiseObserver",
    "PiecewiseConstantNoiseObserver",
    "WindowedPiecewiseConstantNoiseObserver",
    "LuenbergerObserver",
    "BoundedNoiseGenerator",
    "RotatingFamily",
]


def _design_from_args(A, H, L1, L2, delta, a1, a2):
    if isinstance(A, Design):
        if any(v is not None for v in (H, L1, L2, delta)):
            raise TypeError("pass either a Design or (A, H, L1, L2, delta), not both")
        return A
    if delta is None:
        raise TypeError("delta is required when A is a matrix (or pass a Design)")
    return Design(A=A, H=H, L1=L1, L2=L2, delta=delta, a1=a1, a2=a2)


class _TwoCopyObserver(hs.HybridSystem):
    """Common part of H_n, H_c, H_pc: two copies x̂1, x̂2, the timer, the estimate x̄.

    State layout (time-major arcs): x̂1 (n), x̂2 (n), then the observer's own
    auxiliary states (see ``slices``). Input u = y (p,). Output x̄ = a1 x̂1 + a2 x̂2.
    """

    _has_xi = False
    _has_q = True
    vectorized = True       # the maps are written on the last axis: one state or a batch

    def __init__(self, A, H=None, L1=None, L2=None, delta=None, *, a1=0.5, a2=None):
        d = _design_from_args(A, H, L1, L2, delta, a1, a2)
        self.design = d
        n, p = d.n, d.p
        self.input_dim = p
        self.output_dim = n
        sl, k = {}, 0
        for name, size in (("xh1", n), ("xh2", n)) + ((("xi1", n * p), ("xi2", n * p), ("mhat", p))
                                                       if self._has_xi else ()) + (("tau", 1),) + \
                ((("q", 1),) if self._has_q else ()):
            sl[name] = slice(k, k + size)
            k += size
        self.slices = sl
        self.state_dim = k
        self._tau = sl["tau"].start
        self._q = sl["q"].start if self._has_q else None
        # flow matrices, and the one-jump guard: the timer reaches delta with q = 0
        self._Lt1, self._Lt2 = L_tilde(d.L1), L_tilde(d.L2)

    # -- sets -----------------------------------------------------------
    def jump_guard(self, x, t, j, u):
        h = x[..., self._tau] - self.design.delta
        return np.where(x[..., self._q] > 0.5, -1.0, h) if self._has_q else h

    def jump_set(self, x, t, j, u):
        inD = x[..., self._tau] >= self.design.delta
        return inD & (x[..., self._q] < 0.5) if self._has_q else inD

    def output(self, x, t, j):
        d = self.design
        return d.a1 * x[..., self.slices["xh1"]] + d.a2 * x[..., self.slices["xh2"]]

    # -- helpers --------------------------------------------------------
    def _jump_gains(self, x):
        """(K1, K2) of the jump from the state x (one state or a batch): the design's (12)."""
        return self.design.K1, self.design.K2

    def split(self, X):
        """Dict of the named parts of a state (n_state,) or time-major (N, n_state) array."""
        X = np.asarray(X, dtype=float)
        return {k: X[..., s] for k, s in self.slices.items()}

    def initial_state(self, xhat0, mhat0=None):
        """zeta(0, 0) in S_n / S_c / S_pc:
        x̂1 = x̂2 = xhat0, xi = 0, m̂ = mhat0 (default 0), tau = q = 0."""
        d = self.design
        z = np.zeros(self.state_dim)
        xh = vector("xhat0", xhat0, d.n)
        z[self.slices["xh1"]] = xh
        z[self.slices["xh2"]] = xh
        if self._has_xi and mhat0 is not None:
            z[self.slices["mhat"]] = vector("mhat0", mhat0, d.p)
        return z


class NominalObserver(_TwoCopyObserver):
    """H_n, the finite-time observer (10)-(12) (without noise compensation).

    State zeta = (x̂1, x̂2, tau, q) in R^{2n} x [0, delta] x {0, 1}; input y.
    Flow (11), with L_i H x read as L_i y (decision 2)::

        x̂_i' = F_i x̂_i + L_i y,  tau' = 1 - q,  q' = 0.

    Jump on D_n = {tau >= delta, q = 0} (12)::

        x̂_i+ = K1 x̂1 + K2 x̂2,  tau+ = 0,  q+ = 1 - q.

    It coincides with the observer (3) of Raff and Allgöwer (one reset at
    t = delta, none later), the observer of the paper's Section III
    ("Motivational example", Fig. 1): there is no separate class for it
    (decision 11). From S_n (x̂1 = x̂2, tau = q = 0) and m = 0 the error is
    exactly zero for t >= delta, j = 1 (Theorem 4.7).

    Parameters
    ----------
    A : Design or (n, n) array_like
    H, L1, L2, delta : see :class:`Design` (omit them when A is a Design)
    a1, a2 : float
        Weights of the estimate x̄ = a1 x̂1 + a2 x̂2 (the output).

    References
    ----------
    Li & Sanfelice, eqs. (3), (10)-(12), (14), Theorem 4.7.
    """

    def flow_map(self, x, t, j, u):
        d, n = self.design, self.design.n
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        dx = np.zeros(x.shape)
        dx[..., :n] = x[..., :n] @ d.F1.T + u @ d.L1.T                  # (11)
        dx[..., n:2 * n] = x[..., n:2 * n] @ d.F2.T + u @ d.L2.T
        dx[..., self._tau] = 1.0 - x[..., self._q]
        return dx

    def jump_map(self, x, t, j, u):
        n = self.design.n
        K1, K2 = self._jump_gains(x)
        R = x[..., :n] @ K1.T + x[..., n:2 * n] @ K2.T                  # (12)
        xn = np.empty(np.shape(x))
        xn[..., :n] = R
        xn[..., n:2 * n] = R
        xn[..., self._tau] = 0.0
        xn[..., self._q] = 1.0 - x[..., self._q]
        return xn


class _JumpWindow:
    """A jump anywhere in tau in [delta_lo, delta] with the gains (12) of that tau.

    Mixed into a two-copy observer: C and D overlap on [delta_lo, delta] (a
    hybrid inclusion whose solutions :func:`hybridsim.explore` enumerates);
    the sets are those of the observer with delta_lo for D's edge.
    """

    vectorized = False
    #: no compiled form: the lowered H_n / H_pc would jump at delta with fixed gains
    compiled_component = None

    def _window(self, delta_lo):
        self.delta_lo = float(delta_lo)
        if not 0.0 < self.delta_lo <= self.design.delta:
            raise ValueError(f"delta_lo must be in (0, delta = {self.design.delta}], "
                             f"got {delta_lo!r}")

    def gains(self, tau):
        """(K1, K2) of (12) for a jump at tau."""
        d = self.design
        K2 = np.linalg.inv(np.eye(d.n) - expm(d.F2 * tau) @ expm(-d.F1 * tau))
        return np.eye(d.n) - K2, K2

    def _jump_gains(self, x):
        return self.gains(x[self._tau])

    def _done(self, x):             # H_n: after its one jump (q = 1) it only flows
        return self._has_q and x[self._q] > 0.5

    def jump_guard(self, x, t, j, u):
        return -1.0 if self._done(x) else x[self._tau] - self.delta_lo

    def jump_set(self, x, t, j, u):
        return bool(not self._done(x) and x[self._tau] >= self.delta_lo)

    def flow_guard(self, x, t, j, u):
        return 1.0 if self._done(x) else self.design.delta - x[self._tau]

    def flow_set(self, x, t, j, u):
        return bool(self._done(x) or x[self._tau] <= self.design.delta)


class WindowedNominalObserver(_JumpWindow, NominalObserver):
    """H_n (10)-(12) whose one jump may happen at any tau in [delta_lo, delta],
    with the gains (12) of the tau it happens at: a hybrid inclusion (C and D
    overlap on [delta_lo, delta]) whose solutions :func:`hybridsim.explore`
    enumerates.

    Decision: the paper's H_n jumps at tau = delta; Assumption 4.1 A2 asks
    det(I - e^{F2 t} e^{-F1 t}) != 0 for every t in (0, delta], so the gains
    (12) exist for every jump time in (0, delta], and the proof of Theorem
    4.7 ((14) with delta := t) gives e(t, 1) = 0 for each.

    Parameters
    ----------
    d : Design
    delta_lo : float
        The window's start, in (0, delta].

    References
    ----------
    Li & Sanfelice, (10)-(12), Assumption 4.1, Theorem 4.7.
    """

    def __init__(self, d, delta_lo):
        super().__init__(d)
        self._window(delta_lo)


class _NoiseCompensating(_TwoCopyObserver):
    _has_xi = True

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.design.check_HT_invertible()   # Theorem 4.13 / 4.14: checked before any run
        if self.design.HT_inv_norm > _WARN_HT_INV:
            warnings.warn(
                f"|(H T - I)^-1| = {self.design.HT_inv_norm:.3g} "
                f"(cond {self.design.HT_cond:.3g}): the m̂ update of "
                "(18) amplifies integration and modelling errors by this factor",
                RuntimeWarning, stacklevel=2)

    def flow_map(self, x, t, j, u):
        d, n, p = self.design, self.design.n, self.design.p
        s = self.slices
        x = np.asarray(x, dtype=float)
        u, mh = np.asarray(u, dtype=float), x[..., s["mhat"]]
        dx = np.zeros(x.shape)
        for xh, L in ((slice(0, n), d.L1), (slice(n, 2 * n), d.L2)):       # (17)
            dx[..., xh] = x[..., xh] @ d.A.T + (u - x[..., xh] @ d.H.T - mh) @ L.T
        # diag_p(F_i) xi_i + L_tilde_i: each n-piece is driven by a column of L_i
        for xi, F, Lt in ((s["xi1"], d.F1, self._Lt1), (s["xi2"], d.F2, self._Lt2)):
            FX = F @ Xi_matrix(x[..., xi], n, p)                            # (..., n, p)
            dx[..., xi] = FX.swapaxes(-1, -2).reshape(x.shape[:-1] + (n * p,)) + Lt
        dx[..., self._tau] = 1.0 - x[..., self._q] if self._has_q else 1.0
        return dx

    def jump_map(self, x, t, j, u):
        d, n, p = self.design, self.design.n, self.design.p
        s = self.slices
        x = np.asarray(x, dtype=float)
        mh = x[..., s["mhat"]]
        K1, K2 = self._jump_gains(x)
        R = x[..., :n] @ K1.T + x[..., n:2 * n] @ K2.T                      # (18)
        T = K1 @ Xi_matrix(x[..., s["xi1"]], n, p) + K2 @ Xi_matrix(x[..., s["xi2"]], n, p)
        # (H T - I)^{-1}(H R - (y - m̂))
        rhs = R @ d.H.T - (np.asarray(u, dtype=float) - mh)
        w = np.linalg.solve(d.H @ T - np.eye(p), rhs[..., None])[..., 0]
        xn = np.zeros(x.shape)
        xn[..., :n] = xn[..., n:2 * n] = R - (T @ w[..., None])[..., 0]
        xn[..., s["mhat"]] = mh + w
        # xi1 = xi2 = 0, tau = 0
        if self._has_q:
            xn[..., self._q] = 1.0 - x[..., self._q]
        return xn


class ConstantNoiseObserver(_NoiseCompensating):
    """H_c, the observer (17)-(18) that is exact after one jump under constant noise.

    State zeta_c = (x̂1, x̂2, xi1, xi2, m̂, tau, q) in R^r x [0, delta] x {0, 1},
    r = 2n + (2n + 1) p; input y. Flow (17)::

        x̂_i' = A x̂_i + L_i (y - H x̂_i) - L_i m̂
        xi_i' = diag_p(F_i) xi_i + L_tilde_i,   m̂' = 0,  tau' = 1 - q,  q' = 0.

    Jump on D_c = {tau >= delta, q = 0} (18), R = K1 x̂1 + K2 x̂2,
    T = K1 Xi(xi1) + K2 Xi(xi2) (footnote 7, decision 3)::

        x̂_i+ = R - T (H T - I)^{-1} (H R - (y - m̂)),   xi_i+ = 0,
        m̂+ = m̂ + (H T - I)^{-1} (H R - (y - m̂)),     tau+ = 0,  q+ = 1 - q.

    H T(delta) - I must be invertible (Theorem 4.13): checked at construction
    (ValueError otherwise); ``design.HT_cond`` and ``design.HT_inv_norm`` report
    how much m̂'s update amplifies errors.

    References
    ----------
    Li & Sanfelice, eqs. (7)-(9) (scalar), (17)-(18), footnotes 6-7, Theorem 4.13.
    """


class PiecewiseConstantNoiseObserver(_NoiseCompensating):
    """H_pc (Section IV-E): H_c without q, jumping every delta.

    State zeta_pc = (x̂1, x̂2, xi1, xi2, m̂, tau) in R^r x [0, delta]; the flow
    is (17) with tau' = 1, the jump is (18) with tau+ = 0, D_pc = {tau >= delta}.
    Under piecewise-constant noise with switches more than 2 delta apart it is
    exact within 2 delta after each switch (Theorem 4.14, decisions 5-6).

    References
    ----------
    Li & Sanfelice, Section IV-E, Theorem 4.14.
    """

    _has_q = False


class WindowedPiecewiseConstantNoiseObserver(_JumpWindow, PiecewiseConstantNoiseObserver):
    """H_pc (Section IV-E) whose every jump may happen at any tau in [delta_lo, delta],
    with the gains (12) of the tau it happens at (K1, K2 in R and T of (18)).

    Decision (as for :class:`WindowedNominalObserver`): the proof of
    Theorem 4.14 uses one interval of constant noise between two jumps, H_c's
    Theorem 4.13 with delta := the gap; the gains exist for every gap in
    (0, delta] (Assumption 4.1 A2), and H T(gap) - I must be nonsingular for
    each (checked at every jump: a singular one is a map error of that
    solution). With delta < min(d_k - d_{k-1}) / 2, every solution is exact
    from the second jump after each switch of the noise until the next.

    Parameters
    ----------
    d : Design
    delta_lo : float
        The window's start, in (0, delta].

    References
    ----------
    Li & Sanfelice, Section IV-E, (17)-(18), Theorem 4.14.
    """

    def __init__(self, d, delta_lo):
        super().__init__(d)
        self._window(delta_lo)


class LuenbergerObserver(hs.HybridSystem):
    """The Luenberger observer (2): x̂0' = A x̂0 - L0 (H x̂0 - y) (no jumps).

    References
    ----------
    Li & Sanfelice, eq. (2).
    """

    def __init__(self, A, H, L0):
        A, H = _check_plant(A, H)
        n = A.shape[0]
        L0 = matrix("L0", L0, (n, H.shape[0]), what=" (n x p)")
        a = alpha_max(A - L0 @ H)
        if a >= 0:
            lam = _hidden_unstable_mode(A, H)
            if lam is not None:
                raise ValueError(
                    f"(A, H) is not detectable: the eigenvalue {lam:.6g} of A (Re >= 0) is "
                    "invisible in y = H x, so A - L0 H keeps it for every L0 and the Luenberger "
                    "observer (2) cannot converge")
            raise ValueError(f"A - L0 H is not Hurwitz (max Re eig = {a:.3g} >= 0); choose L0 so "
                             "that it is (the Luenberger observer (2) needs it)")
        self.A, self.H, self.L0 = A, H, L0
        self.state_dim = n
        self.input_dim = H.shape[0]

    def flow_map(self, x, t, j, u):
        return self.A @ x - self.L0 @ (self.H @ x - u)


@functools.cache
class BoundedNoiseGenerator(hs.HybridSystem):
    """A noise source whose (constant) state holds the noise's coefficients.

    For batches of realisations. State w = (a, omega, phi), each (p, K) flattened row-major
    (state_dim = 3 p K); flow 0, no jumps.
    Output m(t)_i = sum_k a_ik sin(omega_ik t + phi_ik), so |m|_inf <= sqrt(sum_i (sum_k |a_ik|)^2).
    Different initial states are different noise realisations, so :func:`hybridsim.simulate_many`
    runs a whole batch of them through one interconnection (see :func:`noise_batch`).
    """

    vectorized = True

    def __init__(self, p, K=3):
        self.p, self.K = int(p), int(K)
        self.state_dim = 3 * self.p * self.K
        self.output_dim = self.p

    def flow_map(self, x, t, j, u):
        return np.zeros(np.shape(x))

    def _parts(self, x):
        pk, shape = self.p * self.K, x.shape[:-1] + (self.p, self.K)
        return (x[..., :pk].reshape(shape), x[..., pk:2 * pk].reshape(shape),
                x[..., 2 * pk:].reshape(shape))

    def output(self, x, t, j):
        a, w, ph = self._parts(np.asarray(x, dtype=float))
        t = np.asarray(t, dtype=float)[..., None, None]       # a batch: each row's own t
        return np.sum(a * np.sin(w * t + ph), axis=-1)

    def callable(self, w0):
        """The realisation of the state w0 as a plain function t -> m(t)."""
        w0 = np.array(w0, dtype=float)
        return lambda t: self.output(w0, t, 0)

    def sup_bound(self, w0):
        """sqrt(sum_i (sum_k |a_ik|)^2) >= |m|_inf for the realisation w0."""
        a, _, _ = self._parts(np.asarray(w0, dtype=float))
        return float(np.linalg.norm(np.sum(np.abs(a), axis=1)))

    def random_states(self, N, m_max, *, w_max=5.0, seed=None):
        """N realisations with |m|_inf <= m_max
        (amplitudes scaled so the bound is m_max), (N, 3pK)."""
        rng = np.random.default_rng(seed)
        out = np.empty((N, self.state_dim))
        for r in range(N):
            a = rng.uniform(-1, 1, size=(self.p, self.K))
            a *= m_max / np.linalg.norm(np.sum(np.abs(a), axis=1))
            w = rng.uniform(0.0, w_max, size=(self.p, self.K))
            ph = rng.uniform(0, 2 * np.pi, size=(self.p, self.K))
            out[r] = np.concatenate([a.ravel(), w.ravel(), ph.ravel()])
        return out


# ---------------------------------------------------------------------------
# H_n on a family of designs, everything in the state (falsification.py)
# ---------------------------------------------------------------------------
_J = np.array([[0.0, 1.0], [-1.0, 0.0]])
_A = _J                                         # plant of Section V.B
_H = np.array([[1.0, 2.0], [2.0, 1.0]])
_HINV = np.linalg.inv(_H)

# state layout of RotatingFamily
_X, _XH1, _XH2, _C1, _C2 = slice(0, 2), slice(2, 4), slice(4, 6), slice(6, 8), slice(8, 10)
_TAU, _Q, _K1, _K2, _W1, _W2, _DELTA = 10, 11, 12, 13, 14, 15, 16
_NOISE = 17


def _F(k, w):
    """F = -k I + w J, stacked: (..., 2, 2)."""
    k, w = np.asarray(k, float), np.asarray(w, float)
    return np.stack([np.stack([-k, w], -1), np.stack([-w, -k], -1)], -2)


class RotatingFamily(hs.HybridSystem):
    """H_n (10)-(12) and plant (1) of V.B for F_i = -k_i I + w_i J, with noise.

    Its maps are written once, along the last axis (``x[..., k]``): the same
    methods take one state or a batch (N, r), and run compiled as written
    (``backend="auto"``, what :func:`hybridsim.falsification.batch_run` picks
    where numba is installed).

    State (17 + noise coefficients)::

        x (2), x̂1 (2), x̂2 (2)    plant and H_n fed y = H x + m (14), decision 2
        c1 (2), c2 (2)            a noise-free twin of H_n (y = H x): the solution with
                                  m = 0 from the same z_m(0, 0) (Theorem 4.9)
        tau, q                    H_n's timer and jump counter (both copies share them)
        k1, k2, w1, w2, delta     the design (constant)
        noise coefficients        constant; m(t) as described by ``noise``

    Flow (11): x' = A x, x̂_i' = F_i x̂_i + L_i y, tau' = 1 - q. Jump (12) on
    {tau >= delta, q = 0}: x̂_i+ = K1 x̂1 + K2 x̂2 (and likewise the twin),
    tau+ = 0, q+ = 1 - q.

    Parameters
    ----------
    noise : {"none", "pwc", "sin"}
        ``"pwc"``: the coordinates of a :class:`~hybridsim.falsification.PiecewiseConstant`
        (``pieces`` x 2 values, pieces of width ``t_end / pieces``, the last held);
        ``"sin"``: those of a :class:`~hybridsim.falsification.Sinusoids` of bound
        ``eps`` (amplitudes, frequencies in Hz, phases; ``terms`` per component).
    eps : float
        The noise class's bound (each component |m_i| <= eps).
    pieces, terms, t_end : int, int, float

    References
    ----------
    Li & Sanfelice, (1), (10)-(12), (14); Section V.B.

    Examples
    --------
    Without noise both copies of H_n equal the plant after the jump at delta
    (Theorem 4.7's finite-time convergence):

    >>> s = RotatingFamily("none")
    >>> x0 = s.state([0.3, 0.4], [-1.0, 1.0], (1.3, 1.4, -4.0, 4.0, 1.0))
    >>> arc = hs.simulate(s, x0, t_max=2.0, rtol=1e-10, atol=1e-12)
    >>> arc.jump_times.tolist(), bool(np.abs(arc.xf[2:6] - np.tile(arc.xf[:2], 2)).max() < 1e-8)
    ([1.0], True)
    """

    vectorized = True

    def __init__(self, noise="none", *, eps=0.0, pieces=8, terms=2, t_end=4.0):
        if noise not in ("none", "pwc", "sin"):
            raise ValueError(f"noise must be 'none', 'pwc' or 'sin', got {noise!r}")
        self.noise, self.eps = noise, float(eps)
        self.pieces, self.terms, self.t_end = int(pieces), int(terms), float(t_end)
        self.noise_size = {"none": 0, "pwc": 2 * self.pieces, "sin": 6 * self.terms}[noise]
        self.state_dim = _NOISE + self.noise_size

    # -- noise ------------------------------------------------------------
    def _noise(self, x, t):
        """(m_1(t), m_2(t)) of each row, on the last axis (x (..., r), t (...,))."""
        if self.noise == "pwc":
            width = self.t_end / self.pieces
            k = np.clip(np.floor(t / width), 0, self.pieces - 1).astype(np.int64)
            i0 = np.broadcast_to(_NOISE + 2 * k, x.shape[:-1])
            i1 = i0 + 1
            return (np.take_along_axis(x, i0[..., None], axis=-1)[..., 0],
                    np.take_along_axis(x, i1[..., None], axis=-1)[..., 0])
        if self.noise == "sin":
            n, amp = self.terms, self.eps / self.terms
            m0 = self._sinusoids(x, t, _NOISE, n)
            m1 = self._sinusoids(x, t, _NOISE + n, n)
            return amp * m0, amp * m1
        zero = np.zeros(np.shape(x[..., 0]))
        return zero, zero

    def _sinusoids(self, x, t, a, n):
        """sum_c a_c sin(2 pi f_c t + phi_c) over the ``n`` terms whose amplitudes start
        at x[..., a] (frequencies 2n, phases 4n further)."""
        acc = np.zeros(np.shape(x[..., 0]))
        for c in range(n):
            acc = acc + x[..., a + c] * np.sin(2 * np.pi * x[..., a + 2 * n + c] * t
                                               + x[..., a + 4 * n + c])
        return acc

    def m(self, x, t):
        """m(t) of each row: x (k, r), t (k,) or scalar -> (k, 2)."""
        x = np.atleast_2d(np.asarray(x, float))
        t = np.broadcast_to(np.asarray(t, float), (len(x),))
        return np.stack(self._noise(x, t), axis=-1)

    def sup_norms(self, x0, t_end):
        """(|m|_delta, |m|_inf over [0, t_end]) of the realisation in the state x0 (Euclidean).

        Exact for ``"pwc"`` (the pieces that meet [0, delta], [0, t_end]); for
        ``"sin"`` a maximum on a grid of step h = 1e-3 plus |m'|_max h / 2 (an
        upper bound, tight to |m'|_max h <= 3.6e-3 for the class searched:
        |m'| <= 2 pi 2 Hz sqrt(2) eps; as decision 13, with a coarser grid).
        """
        x0 = np.asarray(x0, float)
        delta = float(x0[_DELTA])
        z = x0[_NOISE:]
        if self.noise == "none":
            return 0.0, 0.0
        if self.noise == "pwc":
            width = self.t_end / self.pieces
            norms = np.linalg.norm(z.reshape(self.pieces, 2), axis=1)
            start = width * np.arange(self.pieces)
            m_inf = float(norms[start <= t_end].max())
            return float(norms[start <= delta].max()), m_inf
        a, f, _ = z.reshape(3, 2, self.terms)
        amp = self.eps / self.terms
        lip = float(np.linalg.norm(np.sum(np.abs(amp * a * 2 * np.pi * f), axis=1)))
        h = 1e-3
        ts = np.linspace(0.0, t_end, max(2, math.ceil(t_end / h) + 1))
        norms = np.linalg.norm(self.m(np.broadcast_to(x0, (len(ts), x0.size)), ts), axis=1)
        step = ts[1] - ts[0]
        m_inf = float(norms.max()) + lip * step / 2
        # [0, delta] ends up to one step past its last grid point: slack lip * step
        return min(float(norms[ts <= delta].max()) + lip * step, m_inf), m_inf

    # -- maps (one definition on the last axis: every path) -----------------
    def _copy_flow(self, x, b, k, w, y0, y1):
        """F x̂ + L y of (11) for the copy x[..., b:b + 2], F = -k I + w J,
        L = (A - F) H^-1."""
        f00, f01, f10, f11 = -k, w, -w, -k
        a00, a01, a10, a11 = _A[0, 0] - f00, _A[0, 1] - f01, _A[1, 0] - f10, _A[1, 1] - f11
        l00 = a00 * _HINV[0, 0] + a01 * _HINV[1, 0]
        l01 = a00 * _HINV[0, 1] + a01 * _HINV[1, 1]
        l10 = a10 * _HINV[0, 0] + a11 * _HINV[1, 0]
        l11 = a10 * _HINV[0, 1] + a11 * _HINV[1, 1]
        return ((f00 * x[..., b] + f01 * x[..., b + 1]) + (l00 * y0 + l01 * y1),
                (f10 * x[..., b] + f11 * x[..., b + 1]) + (l10 * y0 + l11 * y1))

    def flow_map(self, x, t):
        """(1) and (11): x' = A x, x̂_i' = F_i x̂_i + L_i (H x + m), the twin's with
        y = H x, tau' = 1 - q; on the last axis."""
        x0, x1 = x[..., 0], x[..., 1]
        y0 = _H[0, 0] * x0 + _H[0, 1] * x1
        y1 = _H[1, 0] * x0 + _H[1, 1] * x1
        m0, m1 = self._noise(x, t)
        k1, k2, w1, w2 = x[..., _K1], x[..., _K2], x[..., _W1], x[..., _W2]
        dx = np.zeros_like(x)
        dx[..., 0] = _A[0, 0] * x0 + _A[0, 1] * x1
        dx[..., 1] = _A[1, 0] * x0 + _A[1, 1] * x1
        dx[..., 2], dx[..., 3] = self._copy_flow(x, 2, k1, w1, y0 + m0, y1 + m1)
        dx[..., 4], dx[..., 5] = self._copy_flow(x, 4, k2, w2, y0 + m0, y1 + m1)
        dx[..., 6], dx[..., 7] = self._copy_flow(x, 6, k1, w1, y0, y1)
        dx[..., 8], dx[..., 9] = self._copy_flow(x, 8, k2, w2, y0, y1)
        dx[..., _TAU] = 1.0 - x[..., _Q]
        return dx

    def _gains(self, x):
        """The entries (row-major) of K1 and K2 of (12): M = I - s R(theta),
        s = e^{-(k2 - k1) delta}, theta = (w2 - w1) delta, K2 = M^-1, K1 = I - K2."""
        d = x[..., _DELTA]
        s = np.exp(-(x[..., _K2] - x[..., _K1]) * d)
        th = (x[..., _W2] - x[..., _W1]) * d
        c, sn = np.cos(th), np.sin(th)
        m00, m01, m10, m11 = 1.0 - s * c, -s * sn, s * sn, 1.0 - s * c
        det = m00 * m11 - m01 * m10
        b00, b01, b10, b11 = m11 / det, -m01 / det, -m10 / det, m00 / det
        return 1.0 - b00, -b01, -b10, 1.0 - b11, b00, b01, b10, b11

    def gains(self, x):
        """(K1, K2) of (12) for each row's design, (k, 2, 2) each."""
        g = np.stack(self._gains(np.atleast_2d(np.asarray(x, float))), axis=-1)
        return g[:, :4].reshape(-1, 2, 2), g[:, 4:].reshape(-1, 2, 2)

    def jump_map(self, x):
        """(12): both copies (and both of the twin) to K1 x̂1 + K2 x̂2, tau+ = 0,
        q+ = 1 - q; on the last axis."""
        a00, a01, a10, a11, b00, b01, b10, b11 = self._gains(x)
        xn = x.copy()
        for a, b in ((2, 4), (6, 8)):
            r0 = (a00 * x[..., a] + a01 * x[..., a + 1]) + (b00 * x[..., b] + b01 * x[..., b + 1])
            r1 = (a10 * x[..., a] + a11 * x[..., a + 1]) + (b10 * x[..., b] + b11 * x[..., b + 1])
            xn[..., a], xn[..., a + 1], xn[..., b], xn[..., b + 1] = r0, r1, r0, r1
        xn[..., _TAU] = 0.0
        xn[..., _Q] = 1.0 - x[..., _Q]
        return xn

    def jump_guard(self, x):
        h = x[..., _TAU] - x[..., _DELTA]
        return np.where(x[..., _Q] > 0.5, -1.0, h)

    def jump_set(self, x):
        return (x[..., _TAU] >= x[..., _DELTA]) & (x[..., _Q] < 0.5)

    def state(self, x0, xhat0, params, noise=()):
        """The initial state: plant x0, z_m(0, 0) in S_n (x̂1 = x̂2 = xhat0, tau = q = 0),
        the design (k1, k2, w1, w2, delta) and the noise coordinates."""
        z = np.zeros(self.state_dim)
        z[_X] = x0
        for sl in (_XH1, _XH2, _C1, _C2):
            z[sl] = xhat0
        z[_K1:_DELTA + 1] = params
        z[_NOISE:] = np.asarray(noise, float).ravel()
        return z
