r"""The design computations of paper 001 (Sections II and III), pure numpy/scipy.

Mazenc, Ahmed & Malisoff, *Reduced order finite time observers for
time-varying nonlinear systems*, CDC 2018. Every function names the
equation it computes; grep for "(20)" to find Lambda.

Section II (LTI, (2)-(15))
    :func:`reduced_coordinates` (4)-(5), :func:`is_observable`,
    :func:`M_tau` (6), :func:`choose_L_tau` (L and tau with M_tau (6)
    invertible), :func:`estimate_15` (15) by quadrature (a reference for the
    observer).
Section III (time-varying, nonlinear, (16)-(28))
    :func:`fundamental_matrix` Phi of (1) (the paper's *inverse* convention),
    :func:`phi_scalar` (Remark 2), :func:`Lambda` (20),
    :func:`check_assumption1` (Assumption 1), :func:`remark3` (Remark 3,
    (25)-(26)), :func:`D_of` (22), :func:`delta3`, :func:`delta4` (21),
    :func:`estimate_23` (23) / (27) by quadrature, :func:`noise_gain` the
    gain l(t) of (28).
Section IV (the chained-form example, (40)-(59))
    :data:`TAU_EXAMPLE`, :func:`example_data` the design data (47)-(48)
    (Lambda = 1 - e^{4 pi}), :func:`estimate_49` (49)/(50) by quadrature,
    :func:`sigma` (54), :func:`zeta_of` (52), :func:`v2_argument` and
    :func:`v2_feedback` (57), :func:`residual_58` (58) evaluated literally,
    :func:`example_gain_sup` the certified l_a of (28) on the example.

Only :func:`fundamental_matrix` runs the engine (the matrix ODE (1) with
re-anchoring jumps); everything else is closed-form or quadrature.

Examples
--------
>>> import numpy as np
>>> from observers.time_varying import design
>>> rc = design.reduced_coordinates([[0.0, 1.0], [-2.0, -3.0]], [[1.0, 0.0]])
>>> rc.A1.shape, rc.A2.shape                      # (5): ydot = A1 x_r + ..., x_r' = A2 x_r + ...
((1, 1), (1, 1))
>>> L, tau, M = design.choose_L_tau(rc.A2, rc.A1, tau=1.0)     # M_tau of (6) invertible
>>> bool(abs(M[0, 0]) > 0)
True
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import integrate, linalg
from scipy.signal import place_poles

import hybridsim as hs

from .._common import matrix, scalar

__all__ = [
    "ReducedCoordinates", "reduced_coordinates", "is_observable", "M_tau", "choose_L_tau",
    "estimate_15", "FundamentalMatrix", "fundamental_matrix", "phi_scalar", "Lambda",
    "check_assumption1", "Remark3Result", "remark3", "D_of", "delta3", "delta4", "estimate_23",
    "noise_gain", "TAU_EXAMPLE", "example_data", "estimate_49", "sigma", "zeta_of",
    "v2_argument", "v2_feedback", "residual_58", "GainSup", "example_gain_sup",
]


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
def _as_fun(F, name, shape):
    """A callable t -> (shape) array from a constant array or a callable."""
    if callable(F):
        size = int(np.prod(shape))

        def f(t, F=F):
            v = np.asarray(F(t), dtype=float)
            if v.size != size:
                raise ValueError(f"{name}(t) must return a {shape[0]} x {shape[1]} matrix, "
                                 f"got shape {v.shape} at t = {t:g}")
            return v.reshape(shape)
        return f
    A = matrix(name, F, shape)
    return lambda t, A=A: A


def _derivative(F):
    """4th-order central difference of a matrix function (h = 1e-3)."""
    h = 1e-3

    def dF(t):
        return (-F(t + 2 * h) + 8 * F(t + h) - 8 * F(t - h) + F(t - 2 * h)) / (12 * h)
    return dF


def _n2(M):
    """Spectral norm (fast path for 1 x 1)."""
    M = np.atleast_2d(M)
    return abs(float(M[0, 0])) if M.size == 1 else float(np.linalg.norm(M, 2))


def _rcond(M):
    """sigma_min / sigma_max of M (0 for M = 0); 1 x 1 without an SVD."""
    if M.shape == (1, 1):
        return 1.0 if M[0, 0] != 0 else 0.0
    s = np.linalg.svd(M, compute_uv=False)
    return 0.0 if s[0] == 0 else s[-1] / s[0]


# ---------------------------------------------------------------------------
# Section II: LTI systems
# ---------------------------------------------------------------------------
def _unobservable_text(A, C, tol=1e-9):
    """Words naming the rank of the observability matrix and an eigenvalue of A.

    The eigenvalue named is the one invisible through C (PBH test).
    """
    n = A.shape[0]
    O = [C]
    for _ in range(n - 1):
        O.append(O[-1] @ A)
    s = np.linalg.svd(np.vstack(O), compute_uv=False)
    r = int(np.sum(s > tol * s[0])) if s[0] > 0 else 0
    lam, best = None, np.inf
    for ev in np.linalg.eigvals(A):
        sv = np.linalg.svd(np.vstack([A - ev * np.eye(n), C.astype(complex)]), compute_uv=False)[-1]
        if sv < best:
            lam, best = ev, sv
    lam_s = f"{lam.real:.6g}" if abs(lam.imag) <= 1e-9 * max(1.0, abs(lam)) else f"{lam:.6g}"
    return (f"the observability matrix has rank {r} < n = {n}, and the eigenvalue {lam_s} of A "
            f"is invisible in y = C x (PBH test)")


def is_observable(A, C, tol=1e-9):
    """True when the pair (A, C) is observable (rank test on the observability matrix).

    Parameters
    ----------
    A : (n, n) array
    C : (p, n) array
    tol : float
        Relative tolerance on the singular values (scaled by the largest).
    """
    A = matrix("A", A, square=True)
    n = A.shape[0]
    C = matrix("C", C, (None, n))
    O = [C]
    for _ in range(n - 1):
        O.append(O[-1] @ A)
    s = np.linalg.svd(np.vstack(O), compute_uv=False)
    return bool(s[0] > 0 and np.sum(s > tol * s[0]) == n)


@dataclass(frozen=True)
class ReducedCoordinates:
    r"""The coordinate change (4) and the reduced system (5).

    x_T = C_T x = [y; x_r] with C_T = [C; N]; in these coordinates
    (2)-(3) read

        ydot  = A1 x_r + A11 y + C delta(t)     (delta1 = A11 y + C delta),
        x_rdot = A2 x_r + A21 y + N delta(t)    (delta2 = A21 y + N delta).

    Attributes
    ----------
    C_T, C_T_inv : (n, n) arrays
    A1 : (p, n-p) array
    A2 : (n-p, n-p) array
    A11 : (p, p) array
    A21 : (n-p, p) array
    C : (p, n) array
    N : (n-p, n) array
    """

    C_T: np.ndarray
    C_T_inv: np.ndarray
    A1: np.ndarray
    A2: np.ndarray
    A11: np.ndarray
    A21: np.ndarray
    C: np.ndarray
    N: np.ndarray

    @property
    def p(self):
        return self.C.shape[0]

    def x_r(self, x):
        """x_r = N x for states x of shape (n,) or time-major (K, n)."""
        return np.asarray(x) @ self.N.T

    def x_from(self, y, x_r):
        """The state x = C_T^{-1} [y; x_r] (each argument (p,) or time-major (K, p))."""
        return np.concatenate([np.asarray(y), np.asarray(x_r)], axis=-1) @ self.C_T_inv.T

    def delta1(self, delta=None):
        """delta1(t, y) of (5) for the disturbance ``delta`` (callable t -> (n,) or None)."""
        if delta is None:
            return lambda t, y: self.A11 @ y
        return lambda t, y: self.A11 @ y + self.C @ np.asarray(delta(t), dtype=float)

    def delta2(self, delta=None):
        """delta2(t, y) of (5) for the disturbance ``delta`` (callable t -> (n,) or None)."""
        if delta is None:
            return lambda t, y: self.A21 @ y
        return lambda t, y: self.A21 @ y + self.N @ np.asarray(delta(t), dtype=float)


def reduced_coordinates(A, C, N=None):
    """The linear change of coordinates (4) and the matrices of (5).

    Parameters
    ----------
    A : (n, n) array
        State matrix of (2).
    C : (p, n) array
        Output matrix of (3), full row rank, p < n, (A, C) observable.
    N : (n-p, n) array, optional
        Rows completing C into an invertible C_T = [C; N] (x_r = N x).
        Default: an orthonormal basis of ker C (so x_r is the part of x that
        C does not see).

    Returns
    -------
    ReducedCoordinates

    Raises
    ------
    ValueError
        Bad shapes, C not of full row rank, p = n (nothing to estimate),
        (A, C) not observable, C_T singular.

    References
    ----------
    [1] eqs. (2)-(5); (A2, A1) is then observable ([6, pp. 304-306]).
    """
    A = matrix("A", A, square=True)
    n = A.shape[0]
    C = matrix("C", C, (None, n))
    p = C.shape[0]
    if p >= n:
        raise ValueError(f"C must have fewer rows than n={n} (nothing left to estimate), got p={p}")
    if np.linalg.matrix_rank(C) != p:
        raise ValueError(f"C must have full row rank p={p}, got rank {np.linalg.matrix_rank(C)}")
    if not is_observable(A, C):
        raise ValueError(f"(A, C) must be observable: {_unobservable_text(A, C)}; "
                         "then (A2, A1) is unobservable too "
                         "and M_tau (6) is singular for every L and tau, "
                         "so no exact reduced estimate (15) exists")
    if N is None:
        N = linalg.null_space(C).T
    N = matrix("N", N, (n - p, n))
    C_T = np.vstack([C, N])
    if _rcond(C_T) < 1e-12:
        raise ValueError("C_T = [C; N] must be invertible: N's rows must complete C's")
    Ti = np.linalg.inv(C_T)
    P1, P2 = Ti[:, :p], Ti[:, p:]
    return ReducedCoordinates(C_T=C_T, C_T_inv=Ti, A1=C @ A @ P2, A2=N @ A @ P2,
                              A11=C @ A @ P1, A21=N @ A @ P1, C=C, N=N)


def M_tau(A2, A1, L, tau):
    r"""M_tau = e^{-A2 tau} - e^{-H tau} with H = A2 + L A1 (6).

    Parameters
    ----------
    A2 : (m, m) array
    A1 : (p, m) array
    L : (m, p) array
    tau : float > 0

    Returns
    -------
    (m, m) array

    References
    ----------
    [1] eq. (6).
    """
    A2 = matrix("A2", A2, square=True)
    m = A2.shape[0]
    A1 = matrix("A1", A1, (None, m))
    L = matrix("L", L, (m, A1.shape[0]))
    tau = scalar("tau", tau, positive=True)
    H = A2 + L @ A1
    return linalg.expm(-A2 * tau) - linalg.expm(-H * tau)


def _place_L(A2, A1, poles):
    """L with eig(A2 + L A1) = poles (pole placement on the dual pair)."""
    B = A1.T                                   # (m, p)
    U, s, Vt = np.linalg.svd(B, full_matrices=False)
    r = int(np.sum(s > 1e-12 * max(s[0], 1e-300)))
    if r == 0:
        raise ValueError("A1 must be nonzero for (A2, A1) to be observable")
    Br = U[:, :r] * s[:r]                      # (m, r), full column rank
    if A2.shape[0] == 1:
        Kr = np.linalg.lstsq(Br, (A2 - poles[0]).reshape(1, 1), rcond=None)[0]
    else:
        Kr = place_poles(A2.T, Br, poles).gain_matrix   # (r, m)
    K = Vt[:r].T @ Kr                          # (p, m): A2^T - B K has the poles
    return -K.T


def choose_L_tau(A2, A1, *, L=None, tau=None, poles=None, rcond_min=1e-8):
    r"""Choose (or check) L and tau such that M_tau of (6) is invertible.

    Parameters
    ----------
    A2 : (m, m) array
    A1 : (p, m) array
        (A2, A1) must be observable.
    L : (m, p) array, optional
        A user's gain: only checked. Default: placed so that H = A2 + L A1
        has the eigenvalues ``poles``.
    tau : float, optional
        The delay (the observer is exact from t = tau on). Default 1.0.
    poles : sequence of m distinct reals, optional
        Default -(1 + 0.5 k)/tau, k = 0..m-1; if M_tau is then too badly
        conditioned, the poles are scaled by 0.5, 2, 0.25, 4 in turn.
    rcond_min : float
        M_tau counts as invertible when sigma_min / sigma_max >= rcond_min.

    Returns
    -------
    L : (m, p) array
    tau : float
    M : (m, m) array
        M_tau of (6).

    Raises
    ------
    ValueError
        If (A2, A1) is not observable, or no tried (L, tau) gives an
        invertible M_tau (the message gives the reciprocal condition number).

    References
    ----------
    [1] eq. (6) and the sentence before it ([9, Lemma 1]).
    """
    A2 = matrix("A2", A2, square=True)
    m = A2.shape[0]
    A1 = matrix("A1", A1, (None, m))
    tau = 1.0 if tau is None else scalar("tau", tau, positive=True)
    if not is_observable(A2, A1):
        A2m, A1m = matrix("A2", A2), matrix("A1", A1)
        why = _unobservable_text(A2m, A1m).replace('of A ', 'of A2 ').replace('C x', 'A1 x_r')
        raise ValueError(f"(A2, A1) must be observable: {why}; "
                         "then M_tau (6) is singular for every L and tau")
    if L is not None:
        M = M_tau(A2, A1, L, tau)
        rc = _rcond(M)
        if rc < rcond_min:
            raise ValueError("M_tau (6) must be invertible: "
                             f"rcond = {rc:.3g} < rcond_min = {rcond_min:g}")
        return matrix("L", L), tau, M
    if poles is None:
        base = -(1.0 + 0.5 * np.arange(m)) / tau
        trials = [base * s for s in (1.0, 0.5, 2.0, 0.25, 4.0)]
    else:
        poles = np.asarray(poles, dtype=float).ravel()
        if poles.shape != (m,):
            raise ValueError(f"poles must have {m} entries, got {poles.size}")
        trials = [poles]
    best = 0.0
    for P in trials:
        Lc = _place_L(A2, A1, P)
        M = M_tau(A2, A1, Lc, tau)
        rc = _rcond(M)
        if rc >= rcond_min:
            return Lc, tau, M
        best = max(best, rc)
    raise ValueError(f"M_tau (6) must be invertible: no tried L gives rcond >= {rcond_min:g} "
                     f"(best {best:.3g}); pass poles= or another tau")


def estimate_15(t, y, A2, A1, L, tau, delta1=None, delta2=None, epsrel=1e-11):
    r"""The exact estimate (15) of x_r(t), t >= tau, by quadrature of a known y.

    An independent reference for the observer: it evaluates (15) as printed,
    integrating over [t - tau, t] with :func:`scipy.integrate.quad_vec`.

    Parameters
    ----------
    t : float
        Time, t >= tau (the window must lie in the measured past).
    y : callable
        s -> (p,) output y(s) on [t - tau, t].
    A2, A1, L : arrays (m, m), (p, m), (m, p)
    tau : float > 0
    delta1, delta2 : callable, optional
        (s, y) -> (p,), (m,); default zero.
    epsrel : float
        Relative tolerance of the quadrature.

    Returns
    -------
    (m,) array

    References
    ----------
    [1] eqs. (9), (13), (15); K = -(A2 + L A1) L.
    """
    A2 = matrix("A2", A2)
    m = A2.shape[0]
    A1 = matrix("A1", A1, (None, m))
    p = A1.shape[0]
    L = matrix("L", L, (m, p))
    tau = scalar("tau", tau, positive=True)
    if not callable(y):
        raise TypeError(f"y must be a callable s -> (p,) array, got {type(y).__name__}")
    if t < tau:
        raise ValueError(f"t must be >= tau = {tau} "
                         f"(the estimate (15) needs y on [t - tau, t]), got {t}")
    d1 = delta1 if delta1 is not None else (lambda s, yy: np.zeros(p))
    d2 = delta2 if delta2 is not None else (lambda s, yy: np.zeros(m))
    H = A2 + L @ A1
    K = -H @ L
    # eigen-free: expm at each node is cheap for small m
    def integrand(s):
        ys = np.asarray(y(s), dtype=float).reshape(p)
        a = linalg.expm(H * (t - s - tau)) @ (K @ ys + d2(s, ys) + L @ d1(s, ys))
        b = linalg.expm(A2 * (t - s - tau)) @ d2(s, ys)
        return -a + b
    I = integrate.quad_vec(integrand, t - tau, t, epsrel=epsrel, epsabs=1e-14)[0]
    rhs = (I + linalg.expm(-H * tau) @ L @ np.asarray(y(t), float)
           - L @ np.asarray(y(t - tau), float))
    return np.linalg.solve(M_tau(A2, A1, L, tau), rhs)


# ---------------------------------------------------------------------------
# Section III: time-varying systems
# ---------------------------------------------------------------------------
class FundamentalMatrix:
    r"""Phi_Omega(t, t0) of (1), computed on the engine (see :func:`fundamental_matrix`).

    Call it as ``Phi(t, t0)``. Internally the matrix ODE (1) is integrated
    from the anchors t_k = t_start + k h (a jump every h resets Phi to I), so
    that the arc's j-th flow gives Phi(t, t_k); then

        Phi(t, s) = Phi(t_{k+1}, s) Phi(t_{k+2}, t_{k+1}) ... Phi(t, t_K)

    with Phi(t_{k+1}, s) = Phi(s, t_k)^{-1} Phi(t_{k+1}, t_k) (semigroup
    identities of the proof of Thm 1). Each factor spans at most h, so
    nothing grows like exp(|t - t_start|).
    """

    def __init__(self, arc, m, t_start, h):
        self.arc, self.m, self.t_start, self.h = arc, m, float(t_start), float(h)
        self.t_end = float(arc.tf)
        iv = arc.flow_intervals
        self._starts = np.array([a for a, _, _ in iv])
        self._js = [jj for _, _, jj in iv]
        self._ends = [self._seg(b, k) for k, (_, b, _) in enumerate(iv)]
        self._nseg = len(iv)

    def _seg(self, t, k):
        x = self.arc.at(t, j=self._js[k])
        return np.asarray(x[: self.m * self.m]).reshape(self.m, self.m)

    def _k(self, t):
        k = int(np.searchsorted(self._starts, t, side="right")) - 1
        return min(max(k, 0), self._nseg - 1)

    def __call__(self, t, t0):
        t, t0 = float(t), float(t0)
        lo = self.t_start - 1e-9 * max(1, abs(self.t_start))
        hi = self.t_end + 1e-9 * max(1, abs(self.t_end))
        for name, v in (("t", t), ("t0", t0)):
            if not lo <= v <= hi:
                raise ValueError(f"{name} must lie in the computed range "
                                 f"[{self.t_start}, {self.t_end}], got {v}")
        # event times are located to ~1e-12: clip such overshoots into the range
        t, t0 = min(max(t, self.t_start), self.t_end), min(max(t0, self.t_start), self.t_end)
        if t < t0:
            return np.linalg.inv(self(t0, t))
        ks, kt = self._k(t0), self._k(t)
        if ks == kt:
            return np.linalg.solve(self._seg(t0, ks), self._seg(t, kt))
        out = np.linalg.solve(self._seg(t0, ks), self._ends[ks])
        for k in range(ks + 1, kt):
            out = out @ self._ends[k]
        return out @ self._seg(t, kt)


def fundamental_matrix(Omega, m, t_span, *, h=None, rtol=1e-11, atol=1e-13, method="DOP853"):
    r"""Phi_Omega(t, t0) of (1) computed numerically with :func:`hybridsim.simulate`.

    (1): dPhi/dt (t, t0) = -Phi(t, t0) Omega(t), Phi(t0, t0) = I. This is the
    *inverse* of the usual transition matrix of xdot = Omega(t) x (the paper's
    convention, kept here).

    Parameters
    ----------
    Omega : callable or (m, m) array
        t -> (m, m) matrix.
    m : int
        Dimension.
    t_span : (float, float)
        [t_start, t_end]: the returned callable answers for t, t0 in it.
    h : float, optional
        Re-anchoring period (a jump resets Phi to I every h); default
        (t_end - t_start)/8, at most 2 pi.
    rtol, atol, method
        Passed to :func:`hybridsim.simulate`.

    Returns
    -------
    FundamentalMatrix
        ``Phi(t, t0)``.

    References
    ----------
    [1] eq. (1) and the semigroup identities in the proof of Thm 1.
    """
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
        raise ValueError(f"m must be a positive int, got {m!r}")
    t_span = np.asarray(t_span, dtype=float)
    if t_span.shape != (2,) or not t_span[1] > t_span[0]:
        raise ValueError(f"t_span must be (t_start, t_end) with t_end > t_start, got {t_span}")
    Om = _as_fun(Omega, "Omega", (m, m))
    ta, tb = t_span
    if h is None:
        h = min((tb - ta) / 8.0, 2 * np.pi)
    h = float(h)
    if not h > 0:
        raise ValueError(f"h must be > 0, got {h}")
    mm = m * m
    I = np.eye(m).ravel()

    class _Phi(hs.HybridSystem):
        state_dim = mm + 1

        def flow_map(self, x, t, j, u):
            P = x[:mm].reshape(m, m)
            return np.concatenate([(-P @ Om(t)).ravel(), [1.0]])

        def jump_map(self, x, t, j, u):
            return np.concatenate([I, [0.0]])

        def jump_guard(self, x, t, j, u):
            return x[mm] - h

        def jump_set(self, x, t, j, u):
            return x[mm] >= h * (1 - 1e-12)

    nj = int(np.ceil((tb - ta) / h)) + 2
    arc = hs.simulate(_Phi(), np.concatenate([I, [0.0]]), t_max=tb, j_max=nj, t0=ta,
                      rtol=rtol, atol=atol, method=method, dense=True, progress=False)
    if not arc.success and arc.tf < tb:
        raise RuntimeError(f"fundamental_matrix: the run stopped at t={arc.tf}: "
                           f"{arc.termination.message}")
    return FundamentalMatrix(arc, m, ta, h)


def phi_scalar(Omega, epsrel=1e-12):
    r"""Phi_Omega(t, t0) = exp(-int_{t0}^t Omega(m) dm) for n - p = 1 (Remark 2), by quadrature.

    Parameters
    ----------
    Omega : callable t -> float or (1, 1) array

    Returns
    -------
    callable (t, t0) -> (1, 1) array

    References
    ----------
    [1] Remark 2.
    """
    if not callable(Omega):
        raise TypeError(f"Omega must be a callable t -> float, got {type(Omega).__name__}")
    f = lambda m: float(np.asarray(Omega(m), dtype=float).reshape(-1)[0])  # noqa: E731
    return lambda t, t0: np.array(
        [[np.exp(-integrate.quad(f, t0, t, epsrel=epsrel, limit=200)[0])]])


def Lambda(Phi_A2, Phi_H, t, tau):
    r"""Lambda(t) = Phi_{A2}(t, t - tau) - Phi_H(t, t - tau) (20).

    Parameters
    ----------
    Phi_A2, Phi_H : callable
        (t, t0) -> (m, m) arrays (convention (1)).
    t, tau : float

    Returns
    -------
    (m, m) array
    """
    tau = scalar("tau", tau, positive=True)
    A = np.atleast_2d(np.asarray(Phi_A2(t, t - tau), dtype=float))
    B = np.atleast_2d(np.asarray(Phi_H(t, t - tau), dtype=float))
    return A - B


def check_assumption1(Phi_A2, Phi_H, tau, t_grid, rcond_min=1e-12):
    r"""Check Assumption 1 (Lambda(t) of (20) invertible) on a grid of times.

    Parameters
    ----------
    Phi_A2, Phi_H : callable (t, t0) -> (m, m)
    tau : float > 0
    t_grid : 1-D array of times
    rcond_min : float
        Lambda(t) counts as invertible when sigma_min/sigma_max >= rcond_min.

    Returns
    -------
    rcond : (K,) array
        sigma_min / sigma_max of Lambda(t) on the grid.

    Raises
    ------
    ValueError
        If Lambda(t) is singular at some grid time (named in the message).

    References
    ----------
    [1] Assumption 1, eq. (20).
    """
    t_grid = np.atleast_1d(np.asarray(t_grid, dtype=float))
    if t_grid.ndim != 1 or t_grid.size == 0:
        raise ValueError(f"t_grid must be a non-empty 1-D array, got shape {t_grid.shape}")
    rc = np.array([_rcond(Lambda(Phi_A2, Phi_H, t, tau)) for t in t_grid])
    bad = np.nonzero(rc < rcond_min)[0]
    if bad.size:
        raise ValueError("Assumption 1 fails: Lambda(t) (20) is singular "
                         f"at t={t_grid[bad[0]]:.6g} (rcond {rc[bad[0]]:.3g} < {rcond_min:g})")
    return rc


@dataclass(frozen=True)
class Remark3Result:
    """Outcome of :func:`remark3`: varpi, whether < 1, and the bound on |Lambda^{-1}|."""

    varpi: float
    holds: bool
    Lambda_inv_bound: float
    swapped: bool


def remark3(Phi_A2, Phi_H, tau, t_grid, swapped=False):
    r"""Remark 3's sufficient condition for Assumption 1, on a grid of times.

    varpi = max_t |Phi_{A2}(t, t - tau)^{-1} Phi_H(t, t - tau)|; when
    varpi < 1, Lambda is invertible and
    |Lambda(t)^{-1}| <= |Phi_{A2}(t, t - tau)^{-1}| / (1 - varpi) (25)-(26).

    The condition is not symmetric: for the example of Section IV,
    |Phi_{A2}^{-1} Phi_H| = e^{4 pi} > 1 though Assumption 1 holds. With
    ``swapped=True`` the same argument is run on
    Lambda = -Phi_H (I - Phi_H^{-1} Phi_{A2}) (our addition; it covers the
    example, varpi = e^{-4 pi}), with the bound |Phi_H^{-1}| / (1 - varpi).

    Parameters
    ----------
    Phi_A2, Phi_H : callable (t, t0) -> (m, m)
    tau : float > 0
    t_grid : 1-D array
    swapped : bool

    Returns
    -------
    Remark3Result
        varpi (max over the grid), holds (varpi < 1), Lambda_inv_bound
        (max over the grid of the bound, inf when varpi >= 1).

    References
    ----------
    [1] Remark 3, eqs. (25)-(26).
    """
    tau = scalar("tau", tau, positive=True)
    t_grid = np.atleast_1d(np.asarray(t_grid, dtype=float))
    if t_grid.ndim != 1 or t_grid.size == 0:
        raise ValueError(f"t_grid must be a non-empty 1-D array, got shape {t_grid.shape}")
    vp, nb = 0.0, 0.0
    for t in t_grid:
        A = np.atleast_2d(np.asarray(Phi_A2(t, t - tau), float))
        B = np.atleast_2d(np.asarray(Phi_H(t, t - tau), float))
        if swapped:
            A, B = B, A
        Ai = np.linalg.inv(A)
        vp = max(vp, np.linalg.norm(Ai @ B, 2))
        nb = max(nb, np.linalg.norm(Ai, 2))
    holds = vp < 1
    return Remark3Result(varpi=float(vp), holds=bool(holds),
                         Lambda_inv_bound=float(nb / (1 - vp)) if holds else np.inf,
                         swapped=swapped)


def D_of(t, A1, A2, L, Ldot):
    r"""D(t) = Ldot(t) - H(t) L(t), H = A2 + L A1 (22). Arguments are callables t -> matrix."""
    Lt = L(t)
    return Ldot(t) - (A2(t) + Lt @ A1(t)) @ Lt


def delta3(t, z, L, delta1, delta2):
    r"""delta3(t, z) = L(t) delta1(t, z) + delta2(t, z) (21)."""
    return L(t) @ delta1(t, z) + delta2(t, z)


def delta4(t, z, A1, A2, L, Ldot, delta1, delta2):
    r"""delta4(t, z) = -[D(t) z + delta3(t, z)] (21)."""
    return -(D_of(t, A1, A2, L, Ldot) @ z + delta3(t, z, L, delta1, delta2))


def _tv_data(A1, A2, L, Ldot, p, m):
    """Uniform callables for A1 (p, m), A2 (m, m), L (m, p), Ldot (m, p)."""
    A1f = _as_fun(A1, "A1", (p, m))
    A2f = _as_fun(A2, "A2", (m, m))
    Lf = _as_fun(L, "L", (m, p))
    if Ldot is not None:
        Ldf = _as_fun(Ldot, "Ldot", (m, p))
    elif callable(L):
        Ldf = _derivative(Lf)
    else:
        Ldf = lambda t: np.zeros((m, p))  # noqa: E731
    return A1f, A2f, Lf, Ldf


def _dims(A1, A2, L, p, m):
    """(p, m) from the arguments when they are arrays, else from p, m."""
    if p is None and not callable(A1):
        p = np.atleast_2d(np.asarray(A1)).shape[0]
    if m is None and not callable(A2):
        m = np.atleast_2d(np.asarray(A2)).shape[0]
    if p is None and not callable(L):
        p = np.atleast_2d(np.asarray(L)).shape[1]
    if m is None and not callable(L):
        m = np.atleast_2d(np.asarray(L)).shape[0]
    if p is None or m is None:
        raise ValueError("p and m must be given when A1, A2 and L are all callables")
    return int(p), int(m)


def estimate_23(t, y, tau, A1, A2, L, Phi_A2, Phi_H, *, delta1=None, delta2=None, Ldot=None,
                eps=None, p=None, m=None, epsrel=1e-11):
    r"""The estimate (23) (``eps`` given) or the approximate observer (27) (``eps=None``).

    A literal evaluation of the paper's formula by quadrature from a known output signal,
    used as an independent reference for :class:`ReducedOrderObserver`.

    Parameters
    ----------
    t : float, t >= tau
    y : callable s -> (p,) measured output (17)
    tau : float > 0
    A1, A2, L : callables t -> (p, m), (m, m), (m, p) matrices, or constant arrays
    Phi_A2, Phi_H : callable (t, t0) -> (m, m) (convention (1))
    delta1, delta2 : callable (s, z) -> (p,), (m,), optional (default 0)
    Ldot : callable, optional
        Derivative of L; default 0 for a constant L, a 4th-order central
        difference (h = 1e-3) for a callable L.
    eps : callable s -> (p,), optional
        The known measurement disturbance: z = y - eps in (23). None: (27).
    p, m : int, optional
        Dimensions, needed only when A1, A2, L are all callables.

    Returns
    -------
    (m,) array

    References
    ----------
    [1] eqs. (20)-(23), (27).
    """
    tau = scalar("tau", tau, positive=True)
    if not callable(y):
        raise TypeError(f"y must be a callable s -> (p,) array, got {type(y).__name__}")
    if t < tau:
        raise ValueError(f"t must be >= tau = {tau} "
                         f"(the estimate (23) needs y on [t - tau, t]), got {t}")
    p, m = _dims(A1, A2, L, p, m)
    A1f, A2f, Lf, Ldf = _tv_data(A1, A2, L, Ldot, p, m)
    d1 = delta1 if delta1 is not None else (lambda s, z: np.zeros(p))
    d2 = delta2 if delta2 is not None else (lambda s, z: np.zeros(m))

    def z(s):
        v = np.asarray(y(s), dtype=float).reshape(p)
        return v if eps is None else v - np.asarray(eps(s), dtype=float).reshape(p)

    t0 = t - tau

    def integrand(s):
        zs = z(s)
        return (np.atleast_2d(Phi_A2(s, t0)) @ np.asarray(d2(s, zs), float).reshape(m)
                + np.atleast_2d(Phi_H(s, t0)) @ delta4(s, zs, A1f, A2f, Lf, Ldf, d1, d2))
    I = integrate.quad_vec(integrand, t0, t, epsrel=epsrel, epsabs=1e-14)[0]
    rhs = I + np.atleast_2d(Phi_H(t, t0)) @ Lf(t) @ z(t) - Lf(t0) @ z(t0)
    Lam = Lambda(Phi_A2, Phi_H, t, tau)
    return np.linalg.solve(Lam, rhs)


def noise_gain(t, tau, A1, A2, L, Phi_A2, Phi_H, *, lip1=0.0, lip2=0.0, Ldot=None, p=None, m=None,
               epsrel=1e-8):
    r"""The gain l(t) with |x*_r(t) - x_r(t)| <= l(t) |eps|_inf (Remark 4, (28)).

    Subtracting (23) from (27),

        x*_r - x_r = Lambda^{-1} [ int Phi_{A2}(m, t-tau) (delta2(m, y) - delta2(m, z))
                     + Phi_H(m, t-tau) (delta4(m, y) - delta4(m, z)) dm
                     + Phi_H(t, t-tau) L(t) eps(t) - L(t-tau) eps(t-tau) ],

    and delta4 is Lipschitz in z with constant |D(m)| + |L(m)| lip1 + lip2, so

        l(t) = |Lambda(t)^{-1}| [ int_{t-tau}^t |Phi_{A2}(m, t-tau)| lip2
               + |Phi_H(m, t-tau)| (|D(m)| + |L(m)| lip1 + lip2) dm
               + |Phi_H(t, t-tau) L(t)| + |L(t-tau)| ]

    (spectral norms). l_a of (28) is sup_{t >= tau} l(t): take the max over a
    grid covering the run (one period for periodic data).

    Parameters
    ----------
    t : float or 1-D array of times
    tau : float > 0
    A1, A2, L : callables or constant arrays
    Phi_A2, Phi_H : callable (t, t0) -> (m, m)
    lip1, lip2 : float >= 0
        Global Lipschitz constants of delta1, delta2 in z.
    Ldot, p, m : see :func:`estimate_23`.

    Returns
    -------
    float or (K,) array
        l(t).

    References
    ----------
    [1] Remark 4, eqs. (27)-(28).
    """
    tau = scalar("tau", tau, positive=True)
    for nm, v in (("lip1", lip1), ("lip2", lip2)):
        if not np.isfinite(v) or v < 0:
            raise ValueError(f"{nm} must be a finite number >= 0, got {v}")
    p, m = _dims(A1, A2, L, p, m)
    A1f, A2f, Lf, Ldf = _tv_data(A1, A2, L, Ldot, p, m)
    ts = np.atleast_1d(np.asarray(t, dtype=float))
    out = []
    for tt in ts:
        t0 = tt - tau

        def g(s, t0=t0):
            lip4 = (_n2(D_of(s, A1f, A2f, Lf, Ldf)) + _n2(Lf(s)) * lip1 + lip2)
            return (_n2(np.atleast_2d(Phi_A2(s, t0))) * lip2
                    + _n2(np.atleast_2d(Phi_H(s, t0))) * lip4)
        I = integrate.quad(g, t0, tt, epsrel=epsrel, limit=200)[0]
        Li = np.linalg.inv(Lambda(Phi_A2, Phi_H, tt, tau))
        val = _n2(Li) * (I + _n2(np.atleast_2d(Phi_H(tt, t0)) @ Lf(tt))
                                       + _n2(Lf(t0)))
        out.append(val)
    out = np.array(out)
    return out if np.ndim(t) else float(out[0])


# ---------------------------------------------------------------------------
# Section IV: the chained-form example
# ---------------------------------------------------------------------------
#: tau of the example (Section IV-B): the period 2 pi of A1(t) = 2 cos t.
TAU_EXAMPLE = 2.0 * np.pi


def example_data():
    r"""The design data (47)-(48) of the example, as a dict of callables and constants.

    Keys: ``A1`` (2 cos t), ``A2`` (0), ``L`` (-2 cos t), ``Ldot``
    (2 sin t), ``H`` (-4 cos^2 t), ``D`` (2 sin t - 8 cos^3 t, eq. 22),
    ``Phi_A2`` (1), ``Phi_H`` (e^{4 int_s^t cos^2} =
    e^{2(t - s) + sin 2t - sin 2s}, eq. 48), ``tau`` (2 pi), ``Lambda``
    (1 - e^{4 pi}). All matrices are 1 x 1.

    Examples
    --------
    >>> import numpy as np
    >>> ex = example_data()
    >>> bool(np.isclose(Lambda(ex["Phi_A2"], ex["Phi_H"], 1.0, ex["tau"])[0, 0], ex["Lambda"]))
    True

    References
    ----------
    [1] eqs. (45)-(48).
    """
    one = lambda v: np.array([[v]])  # noqa: E731
    return dict(
        A1=lambda t: one(2 * np.cos(t)),
        A2=lambda t: one(0.0),
        L=lambda t: one(-2 * np.cos(t)),
        Ldot=lambda t: one(2 * np.sin(t)),
        H=lambda t: one(-4 * np.cos(t) ** 2),
        D=lambda t: one(2 * np.sin(t) - 8 * np.cos(t) ** 3),
        Phi_A2=lambda t, s: one(1.0),
        Phi_H=lambda t, s: one(np.exp(2 * (t - s) + np.sin(2 * t) - np.sin(2 * s))),
        tau=TAU_EXAMPLE,
        Lambda=1.0 - np.exp(4 * np.pi),
    )


def _M(m, t):
    """script M(m, t) = 2(m - t + 2 pi) + sin 2m - sin 2t (after (58))."""
    return 2 * (m - t + 2 * np.pi) + np.sin(2 * m) - np.sin(2 * t)


def estimate_49(t, xi3, v2, epsrel=1e-11):
    r"""The estimate (49) of xi2(t), printed form, by quadrature.

    Parameters
    ----------
    t : float, t >= 2 pi
    xi3, v2 : callable s -> float
        The measured xi3 and the input v2 on [t - 2 pi, t].
    epsrel : float
        Relative tolerance of the quadrature.

    Returns
    -------
    float
        xhat_r(t); equals xi2(t) (50) when (45) holds on the whole window,
        i.e. for t >= 2 pi + sqrt|x1(0)| on the full system (44).

    Examples
    --------
    >>> import numpy as np
    >>> xi2 = 0.7                          # v2 = 0: xi2 constant, xi3' = 2 cos t xi2 (45)
    >>> round(estimate_49(7.0, lambda s: -0.3 + 2 * xi2 * np.sin(s), lambda s: 0.0), 10)
    0.7

    References
    ----------
    [1] eqs. (49)-(50).
    """
    if not (callable(xi3) and callable(v2)):
        raise TypeError("xi3 and v2 must be callables s -> float")
    if t < TAU_EXAMPLE:
        raise ValueError(f"t must be >= 2 pi (the window [t - 2 pi, t] must be measured), got {t}")
    c = 1.0 / (1.0 - np.exp(4 * np.pi))
    a = 2 * np.cos(t) * c * (-np.exp(4 * np.pi) * xi3(t) + xi3(t - TAU_EXAMPLE))
    f = lambda m: (c * (1 - np.exp(_M(m, t))) * v2(m)  # noqa: E731
                   + 2 * c * np.exp(_M(m, t)) * (4 * np.cos(m) ** 3 - np.sin(m)) * xi3(m))
    return float(a + integrate.quad(f, t - TAU_EXAMPLE, t, epsrel=epsrel, epsabs=1e-13,
                                    limit=400)[0])


def sigma(s):
    r"""The saturation sigma(s) = s / sqrt(1 + s^2) of (54): odd, |sigma(s)| < 1.

    Examples
    --------
    >>> float(sigma(0.75))
    0.6
    """
    s = np.asarray(s, dtype=float)
    return s / np.sqrt(1.0 + s * s)


def zeta_of(t, xi2, xi3, xi4):
    r"""(zeta1, zeta2, zeta3) of (52); arrays broadcast (time-major use: columns).

    Examples
    --------
    >>> zeta_of(0.0, 1.0, 2.0, 3.0).tolist()
    [2.0, 2.0, 1.0]
    """
    return np.array([xi4 - 2 * np.sin(t) * xi3 - np.cos(2 * t) * xi2,
                     xi3 - 2 * np.sin(t) * xi2,
                     xi2 * np.ones_like(np.asarray(t, float))])


def v2_argument(t, xi2, xi3, xi4):
    r"""The argument of sigma in (57), grouped form: v2 = sigma(v2_argument(...)).

    cos 2t xi4 + 2 [1 - cos 2t] sin t xi3 - [cos^2 2t + 4 sin^2 t + 1] xi2;
    arrays broadcast.

    Examples
    --------
    >>> float(v2_argument(0.0, 1.0, 0.0, 3.0))        # 3 - 2
    1.0

    References
    ----------
    [1] eq. (57) and the grouped form after it.
    """
    return (np.cos(2 * t) * xi4 + 2 * (1 - np.cos(2 * t)) * np.sin(t) * xi3
            - (np.cos(2 * t) ** 2 + 4 * np.sin(t) ** 2 + 1) * xi2)


def v2_feedback(t, xi2, xi3, xi4):
    r"""The bounded state feedback (57), grouped form.

    v2 = sigma(cos 2t xi4 + 2 [1 - cos 2t] sin t xi3
               - [cos^2 2t + 4 sin^2 t + 1] xi2).

    With xi2 replaced by the estimate (50) this is (58).

    Examples
    --------
    >>> round(float(v2_feedback(0.0, 1.0, 0.0, 3.0)), 6)      # sigma(1) = 1/sqrt 2
    0.707107

    References
    ----------
    [1] eqs. (54), (57), (58).
    """
    return sigma(v2_argument(t, xi2, xi3, xi4))


def residual_58(t, v2, xi3, xi4, *, points=None):
    r"""v2(t) minus the right-hand side of (58), evaluated literally by quadrature.

    The right-hand side integrates v2 and xi3 over [t - 2 pi, t] with
    adaptive quadrature, independently of any observer state.

    Parameters
    ----------
    t : float, t >= 2 pi
    v2, xi3, xi4 : callable s -> float
        The control and the measured states along a run (e.g. read off a
        dense arc, :func:`observers.time_varying.loop_functions`).
    points : sequence of float, optional
        Breakpoints inside the window (where v2 jumps, e.g. when the
        observer's window fills).

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> v = lambda s: 0.0                    # xi3, xi4 = 0 (and xi2 = 0): (58) gives v2 = 0
    >>> residual_58(7.0, v, v, v)
    0.0

    References
    ----------
    [1] eqs. (58)-(59).
    """
    if t < TAU_EXAMPLE:
        raise ValueError(f"t must be >= 2 pi (the window of (58) must lie in the run), got {t}")
    cL = (np.cos(2 * t) ** 2 + 4 * np.sin(t) ** 2 + 1) / (1 - np.exp(4 * np.pi))
    a = t - TAU_EXAMPLE
    pts = [s for s in (() if points is None else points) if a < s < t] or None
    I1 = integrate.quad(lambda s: (1 - np.exp(_M(s, t))) * v2(s), a, t, limit=400,
                        epsrel=1e-10, epsabs=1e-12, points=pts)[0]
    I2 = integrate.quad(lambda s: np.exp(_M(s, t)) * (4 * np.cos(s) ** 3 - np.sin(s)) * xi3(s),
                        a, t, limit=400, epsrel=1e-10, epsabs=1e-12, points=pts)[0]
    rhs = sigma(np.cos(2 * t) * xi4(t) + 2 * (1 - np.cos(2 * t)) * np.sin(t) * xi3(t)
                - cL * I1 - 2 * cL * I2
                - 2 * np.cos(t) * cL * (-np.exp(4 * np.pi) * xi3(t) + xi3(a)))
    return float(v2(t) - rhs)


@dataclass(frozen=True)
class GainSup:
    r"""A certified bracket of l_a = sup_t l(t) (:func:`example_gain_sup`).

    Attributes
    ----------
    lower : float
        max of l on the grid: a value l takes (at ``t``), so l_a >= lower.
    upper : float
        The Lipschitz certificate: l_a <= upper.
    t : float
        Where the grid's maximum is.
    h : float
        Grid spacing.
    """

    lower: float
    upper: float
    t: float
    h: float


def example_gain_sup(n=2 ** 18):
    r"""l_a of (28) on the example, certified: l_a in [lower, upper].

    On the example (delta1 = 0, delta2 = v2 independent of z, so lip1 =
    lip2 = 0) the gain of :func:`noise_gain` is, with E = e^{4 pi} and
    Phi_H(m, s) = g(m) / g(s), g(m) = e^{2m + sin 2m} (48)::

        l(t) = [I(t) + 2 (E + 1) |cos t|] / (E - 1),
        I(t) = int_{t-2pi}^t Phi_H(m, t - 2 pi) |D(m)| dm
             = [G(t) - G(t - 2 pi)] / g(t - 2 pi),   G(x) = int_0^x g |D|,

    with D = 2 sin - 8 cos^3 (22). l has period pi (Phi_H(m + pi, s + pi)
    = Phi_H(m, s), |D| and |cos| have period pi), so l_a = sup over
    [2 pi, 3 pi]. G is accumulated over a grid of spacing h = pi / n
    (3-point Gauss-Legendre per cell), which gives l on the grid t_k =
    2 pi + k h (to ~1e-12). Differentiating, I' = (E - 1)|D(t)| -
    (2 + 2 cos 2t) I, so almost everywhere

        |l'(t)| <= |D(t)| + 4 l(t) + 2 (E + 1) / (E - 1),

    and on each cell l <= (l_k + l_{k+1}) / 2 + (h / 2) sup |l'|. With
    D_max = max_k |D(t_k)| + 13 h (|D'| <= 26) and U = l_a this gives
    U <= M + (h / 2)(D_max + 4 U + c), i.e.

        upper = (M + h (D_max + c) / 2) / (1 - 2 h),

    M = max_k (l_k + l_{k+1}) / 2, c = 2 (E + 1) / (E - 1); lower =
    max_k l_k.

    Parameters
    ----------
    n : int
        Grid cells per period pi (default 2^18: h = 1.2e-5, upper - lower
        about 1.7e-4).

    Returns
    -------
    GainSup

    Examples
    --------
    >>> b = example_gain_sup(2 ** 12)
    >>> bool(b.lower <= b.upper < b.lower + 0.02), round(b.lower, 2)
    (True, 4.09)

    References
    ----------
    [1] Remark 4, eq. (28); (22), (48).
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 16:
        raise ValueError(f"n must be an int >= 16, got {n!r}")
    n = int(n)
    h = np.pi / n
    E = np.exp(4 * np.pi)

    def absD(m):
        return np.abs(2 * np.sin(m) - 8 * np.cos(m) ** 3)

    def g(m):
        return np.exp(2 * m + np.sin(2 * m))

    # G on x_k = k h, k = 0..3n, by 3-point Gauss-Legendre on each cell (in
    # blocks of cells: the default grid's temporaries were 50 MB at once)
    nodes, weights = np.polynomial.legendre.leggauss(3)
    cells = np.empty(3 * n)
    for s in range(0, 3 * n, 2 ** 14):
        a = np.arange(s, min(s + 2 ** 14, 3 * n)) * h
        acc = np.zeros(a.size)
        for x, w in zip(nodes, weights):
            m = a + 0.5 * h * (x + 1)
            acc += w * g(m) * absD(m)
        cells[s:s + a.size] = acc
    G = np.concatenate([[0.0], np.cumsum(0.5 * h * cells)])
    t = 2 * np.pi + np.arange(n + 1) * h               # one period [2 pi, 3 pi]
    I = (G[2 * n:] - G[:n + 1]) / g(t - 2 * np.pi)
    lk = (I + 2 * (E + 1) * np.abs(np.cos(t))) / (E - 1)
    k = int(np.argmax(lk))
    M = float(np.max(0.5 * (lk[1:] + lk[:-1])))
    c = 2 * (E + 1) / (E - 1)
    D_max = float(absD(t).max()) + 13 * h
    upper = (M + h * (D_max + c) / 2) / (1 - 2 * h)
    return GainSup(lower=float(lk[k]), upper=float(upper), t=float(t[k]), h=float(h))
