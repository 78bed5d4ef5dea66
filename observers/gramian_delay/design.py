r"""Design computations of Mazenc & Malisoff (2022): numpy/scipy only, no engine.

* :func:`observer_form` -- the change of coordinates of Section II from
  (M, N) of (1) to the form (2) (Remark 3), an :class:`ObserverForm`.
* :func:`lam` -- lambda(r) of (4).
* :func:`gramian_design` -- S (5), N, R, H (6) and the constants of (13), a
  :class:`GramianDesign` (augmented matrix exponential, or quadrature).
* :func:`c_Delta`, :func:`theorem1_bound` -- the constant (11) and the right
  side of the robustness bound (15).
* :func:`theorem2_constants` -- varsigma_1..4 (38), q1 and mu (41), condition
  (40), rate (43) and a1, a2 of Remark 4, a :class:`Theorem2Constants`.
* :func:`sampling_instants` -- instants obeying (36).

Examples
--------
>>> import numpy as np
>>> from observers.gramian_delay.design import gramian_design
>>> A1 = np.array([[-1.0, 15.0], [-36.4, -200.0]]); A2 = np.array([[1.0, 0.0]])   # (67)
>>> d = gramian_design(A1, A2, k=100.0, tau=0.1)                                  # (5)-(6)
>>> f"{d.cond_S:.3g}", np.round(d.R.ravel(), 3).tolist()
('1.41e+05', [104.025, -19.285])
"""
from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

import numpy as np
import scipy.integrate
import scipy.linalg
from scipy.linalg import expm as _expm

from .._common import matrix, scalar

__all__ = [
    "ObserverForm", "observer_form", "lam", "GramianDesign", "gramian_design",
    "c_Delta", "theorem1_bound", "Theorem2Constants", "theorem2_constants",
    "sampling_instants",
]


def _obsv_rank(A1, A2):
    """Rank of the observability matrix [A2; A2 A1; ...; A2 A1^{m-1}] (the appendix's argument)."""
    m = A1.shape[0]
    blocks, Ak = [], np.eye(m)
    for _ in range(m):
        blocks.append(A2 @ Ak)
        Ak = A1 @ Ak
    return np.linalg.matrix_rank(np.vstack(blocks))


# ----------------------------------------------------------------------------
# Section II: coordinates
# ----------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class ObserverForm:
    r"""System (1) written in the coordinates (2) of Section II.

    ``xi = T chi`` with ``T = [P; N]``: ``xi1 = P chi`` (unmeasured, n-q
    components) and ``xi2 = N chi`` (measured, q components). With
    ``T M T^{-1} = [[M11, M12], [M21, M22]]``:

    * ``A1 = M11``, ``A2 = M21``;
    * ``F1(y, t) = M12 y + P Psi(y, t)``;
    * ``F2(y, t) = (M22 + k I) y + N Psi(y, t)`` (the ``-k xi2`` of (2) is
      split off, as the paper says one may);
    * ``eps1 = P delta1``, ``eps2 = N delta1`` (Remark 3).

    Attributes
    ----------
    A1 : (n-q, n-q) array
    A2 : (q, n-q) array
    k : float
    P : (n-q, n) array
    N : (q, n) array
    T, T_inv : (n, n) arrays
    M_xi : (n, n) array
        ``T M T^{-1}``.
    Psi : callable or None
        ``Psi(y, t) -> (n,)``, the nonlinearity of (1); with ``Psi.batch =
        True`` it takes the last axis (``y`` (N, q), ``t`` (N,) -> (N, n)), and
        so do F1, F2 and F12.
    """

    A1: np.ndarray
    A2: np.ndarray
    k: float
    P: np.ndarray
    N: np.ndarray
    T: np.ndarray
    T_inv: np.ndarray
    M_xi: np.ndarray
    Psi: Callable | None = None

    @property
    def n(self):
        return self.T.shape[0]

    @property
    def q(self):
        return self.N.shape[0]

    @functools.cached_property
    def _L1(self):
        """M12: the linear part of F1 (computed once)."""
        m = self.n - self.q
        return self.M_xi[:m, m:].copy()

    @functools.cached_property
    def _L2(self):
        """M22 + k I: the linear part of F2 (computed once)."""
        m = self.n - self.q
        return self.M_xi[m:, m:] + self.k * np.eye(self.q)

    @property
    def _linear(self):
        """``(M12, M22 + k I)``: the linear parts of F1 and F2."""
        return self._L1, self._L2

    @functools.cached_property
    def _psi_batch(self):
        """Whether Psi takes the last axis (``Psi.batch = True``)."""
        return bool(getattr(self.Psi, "batch", False))

    def F1(self, y, t):
        """F1 of (2) at measured value ``y`` (q,) and time ``t``."""
        return self.F12(y, t)[0]

    def F2(self, y, t):
        """F2 of (2) at measured value ``y`` (q,) and time ``t``."""
        return self.F12(y, t)[1]

    def F12(self, y, t):
        """``(F1(y, t), F2(y, t))`` with one evaluation of Psi (what the observers call).

        On the last axis: ``y`` (N, q) with ``t`` (N,) gives (N, n-q) and
        (N, q) (a Psi declaring ``Psi.batch = True``).
        """
        y = np.asarray(y, dtype=float)
        if self.Psi is None:
            return y @ self._L1.T, y @ self._L2.T
        if y.ndim > 1 and not self._psi_batch:
            raise ValueError("F12 over a batch needs a Psi written on the last axis "
                             "(Psi.batch = True: (N, q) outputs and (N,) times)")
        ps = np.asarray(self.Psi(y, t), dtype=float)
        return y @ self._L1.T + ps @ self.P.T, y @ self._L2.T + ps @ self.N.T

    def to_xi(self, chi):
        """``xi = T chi``; ``chi`` is (n,) or time-major (N, n)."""
        return np.asarray(chi, dtype=float) @ self.T.T

    def to_chi(self, xi):
        """``chi = T^{-1} xi``; ``xi`` is (n,) or time-major (N, n)."""
        return np.asarray(xi, dtype=float) @ self.T_inv.T


def observer_form(M, N, Psi=None, *, P=None, k=None) -> ObserverForm:
    r"""Change of coordinates of Section II from (1) to the form (2).

    Parameters
    ----------
    M : (n, n) array_like
    N : (q, n) array_like
        Full row rank, with (M, N) observable.
    Psi : callable, optional
        ``Psi(y, t) -> (n,)``, the nonlinearity of (1) (a function of the
        measured ``y = N chi`` and t). With ``Psi.batch = True`` it takes the
        last axis (``(Y (N, q), t (N,)) -> (N, n)``): the observers' maps then
        take batches (:func:`hybridsim.simulate_many`).
    P : (n-q, n) array_like, optional
        Rows completing N to an invertible ``T = [P; N]``. Default: an
        orthonormal basis of the null space of N (so ``P N^T = 0``).
    k : float, optional
        The constant of (2). Default: the spectral radius of A1 plus 1,
        which makes ``A1 + k I`` invertible (the paper: "taking k larger
        than the spectral radius of A1").

    Returns
    -------
    ObserverForm

    Raises
    ------
    ValueError
        Bad shapes, N not of full row rank, (M, N) not observable, T
        singular, k <= 0, or A1 + kI singular.

    References
    ----------
    Mazenc & Malisoff (2022), Section II, eqs. (1)-(2) and Remark 3.
    """
    M = matrix("M", M)
    n = M.shape[0]
    if M.shape != (n, n):
        raise ValueError(f"M must be square, got shape {M.shape}")
    N = matrix("N", N, (None, n))
    q = N.shape[0]
    if not 1 <= q < n:
        raise ValueError(f"N must have between 1 and n-1 = {n - 1} rows, got {q}")
    if np.linalg.matrix_rank(N) < q:
        raise ValueError(f"N must have full row rank {q}, got rank {np.linalg.matrix_rank(N)}")
    if _obsv_rank(M, N) < n:
        raise ValueError("(M, N) must be observable; the observability matrix has "
                         f"rank {_obsv_rank(M, N)} < n = {n}")
    if Psi is not None and not callable(Psi):
        raise TypeError(f"Psi must be callable, got {type(Psi).__name__}")
    if P is None:
        P = scipy.linalg.null_space(N).T
    P = matrix("P", P, (n - q, n))
    T = np.vstack([P, N])
    if np.linalg.matrix_rank(T) < n:
        raise ValueError("P must complete N to an invertible [P; N]; got a singular matrix")
    T_inv = np.linalg.inv(T)
    M_xi = T @ M @ T_inv
    m = n - q
    A1, A2 = M_xi[:m, :m].copy(), M_xi[m:, :m].copy()
    if k is None:
        k = float(np.max(np.abs(np.linalg.eigvals(A1)))) + 1.0
    k = scalar("k", k, positive=True)
    _check_k(A1, k)
    return ObserverForm(A1=A1, A2=A2, k=k, P=P, N=N, T=T, T_inv=T_inv, M_xi=M_xi, Psi=Psi)


def _check_k(A1, k):
    B = A1 + k * np.eye(A1.shape[0])
    if np.linalg.cond(B) > 1e12:
        raise ValueError(f"k must make A1 + k I invertible; k = {k!r} gives "
                         f"cond(A1 + k I) = {np.linalg.cond(B):.3g}")


# ----------------------------------------------------------------------------
# Section III: lambda, S, N, R, H
# ----------------------------------------------------------------------------
def _check_pair(A1, A2):
    A1 = matrix("A1", A1)
    m = A1.shape[0]
    if A1.shape != (m, m):
        raise ValueError(f"A1 must be square, got shape {A1.shape}")
    A2 = matrix("A2", A2, (None, m))
    return A1, A2


def lam(r, A1, A2, k):
    r"""The function lambda(r) = A2 (A1 + kI)^{-1} [I - e^{(A1 + kI) r}] of (4).

    Parameters
    ----------
    r : float or (K,) array_like
    A1 : (m, m) array_like
    A2 : (q, m) array_like
    k : float

    Returns
    -------
    (q, m) array, or (K, q, m) array for an array ``r``.

    References
    ----------
    Mazenc & Malisoff (2022), eq. (4).
    """
    A1, A2 = _check_pair(A1, A2)
    k = scalar("k", k, positive=True)
    _check_k(A1, k)
    m = A1.shape[0]
    B = A1 + k * np.eye(m)
    G = np.linalg.solve(B.T, A2.T).T            # A2 (A1 + kI)^{-1}
    rr = np.asarray(r, dtype=float)
    if not np.all(np.isfinite(rr)):
        raise ValueError("r must be finite")
    out = np.array([G @ (np.eye(m) - _expm(B * ri)) for ri in rr.reshape(-1)])
    return out[0] if rr.ndim == 0 else out.reshape(rr.shape + G.shape)


@dataclasses.dataclass(frozen=True)
class GramianDesign:
    r"""The design matrices of Section III for one (A1, A2, k, tau).

    Attributes
    ----------
    A1, A2, k, tau
        The data of (2) and the delay.
    S : (m, m) array
        The Gramian (5), symmetric positive definite.
    N : (m, q) array
        ``int_{-tau}^0 lambda(m)^T dm`` (6) (the paper's calligraphic N).
    R : (m, q) array
        ``S^{-1} N`` (6).
    H : (m, q) array
        ``(A1 + kI)^{-T} A2^T`` (6).
    S_inv : (m, m) array
    cond_S : float
        2-norm condition number of S.
    method : str
        ``"expm"`` or ``"quad"``: how S and N were computed.
    E1 : float
        ``e^{-k tau}`` (13).
    E2 : (m, m) array
        ``e^{-(A1^T + 2kI) tau}`` (13).
    """

    A1: np.ndarray
    A2: np.ndarray
    k: float
    tau: float
    S: np.ndarray
    N: np.ndarray
    R: np.ndarray
    H: np.ndarray
    S_inv: np.ndarray
    cond_S: float
    method: str
    E1: float
    E2: np.ndarray

    @property
    def m(self):
        """n - q, the number of unmeasured components."""
        return self.A1.shape[0]

    @property
    def q(self):
        """The number of measured components."""
        return self.A2.shape[0]

    @property
    def S_bar(self):
        """``|S^{-1}|`` (11)."""
        return float(np.linalg.norm(self.S_inv, 2))

    @property
    def A_psi2(self):
        """``A1^T + 2kI``, the (negated) matrix of psi_2's flow in (7)."""
        return self.A1.T + 2.0 * self.k * np.eye(self.m)

    @property
    def psi2_growth(self):
        r"""Largest real part of the eigenvalues of -(A1^T + 2kI).

        Positive when 2k < -min Re eig(A1): psi_2 of (7) then grows like
        e^{psi2_growth t}, and (13) subtracts two growing terms whose
        difference stays bounded. In exact arithmetic nothing changes; in
        floating point the cancellation loses digits at that rate (on the
        DC motor, k = 75 gives +47.2: the estimate is lost after ~0.8 s).
        The paper does not mention it; choose k > -min Re eig(A1) / 2.
        """
        return float(np.max(np.linalg.eigvals(-self.A_psi2).real))

    @functools.cached_property
    def _lam_modes(self):
        """``(G, V, w, V^{-1})``: ``G = A2 (A1 + kI)^{-1}``, ``A1 + kI = V diag(w) V^{-1}``.

        None when the eigenvector matrix is ill conditioned (cond > 1e6):
        :meth:`lam` then calls :func:`lam` (``expm`` at every r).
        """
        B = self.A1 + self.k * np.eye(self.m)
        w, V = np.linalg.eig(B)
        if np.linalg.cond(V) > 1e6:
            return None
        return np.linalg.solve(B.T, self.A2.T).T, V, w, np.linalg.inv(V)

    def lam(self, r):
        """lambda(r) of (4) (see :func:`lam`), from the eigen-decomposition of A1 + kI.

        Computed once per design, so that the quadratures of (15) and (38)
        (thousands of r each) do not call ``expm`` at every r; it agrees
        with :func:`lam` to ~cond(V) ulp (tested).
        """
        modes = self._lam_modes
        if modes is None:
            return lam(r, self.A1, self.A2, self.k)
        G, V, w, Vi = modes
        rr = np.asarray(r, dtype=float)
        if not np.all(np.isfinite(rr)):
            raise ValueError("r must be finite")
        flat = rr.reshape(-1)
        E = (V[None, :, :] * np.exp(np.multiply.outer(flat, w))[:, None, :]) @ Vi
        if np.iscomplexobj(E):
            E = E.real
        out = G @ (np.eye(self.m) - E)
        return out[0] if rr.ndim == 0 else out.reshape(rr.shape + G.shape)

    @functools.cached_property
    def _psi2_modes(self):
        """``(V, w, V^{-1})`` with ``-(A1^T + 2kI) = V diag(w) V^{-1}``, or None.

        None when the eigenvector matrix is ill conditioned (cond > 1e6, a
        nearly defective A1): :meth:`decay` then calls ``expm``.
        """
        w, V = np.linalg.eig(-self.A_psi2)
        if np.linalg.cond(V) > 1e6:
            return None
        return V, w, np.linalg.inv(V)

    def decay(self, h):
        r"""``(e^{-k h}, e^{-(A1^T + 2kI) h})``: psi's free response over h.

        Returns ``(E1, E2)`` for ``h == tau`` without recomputing. For other
        windows (``h < tau`` before t0 + tau, decision 3) the matrix
        exponential comes from the eigen-decomposition of A1^T + 2kI,
        computed once (a 2 x 2 ``scipy.linalg.expm`` costs ~1 ms, and the
        sampled observer (39) needs one per flow evaluation before tau);
        it agrees with ``expm`` to ~cond(V) ulp (tested).
        """
        if h == self.tau:
            return self.E1, self.E2
        modes = self._psi2_modes
        if modes is None:
            return float(np.exp(-self.k * h)), _expm(-self.A_psi2 * h)
        V, w, Vi = modes
        E = (V * np.exp(w * h)) @ Vi
        return float(np.exp(-self.k * h)), (E.real if np.iscomplexobj(E) else E)

    def xi_e(self, xi1_hat, xi2_hat, psi1, psi2, psi1_del, psi2_del, y, h=None):
        r"""The estimate (13) from its ingredients.

        .. math::
            \xi_e = \hat\xi_1 + R(y - \hat\xi_2)
                    + S^{-1}[e^{-kh}\psi_1(t-h) - \psi_1(t)]
                    + S^{-1}[\psi_2(t) - e^{-(A_1^\top + 2kI)h}\psi_2(t-h)]

        with ``h = tau`` (the paper) or ``h = t - t0 < tau`` (decision 3 of
        the module docstring: the window truncated to [t0, t]).

        Parameters
        ----------
        xi1_hat, psi1, psi2, psi1_del, psi2_del : (m,) or (K, m) arrays
        xi2_hat, y : (q,) or (K, q) arrays
            ``y`` is xi_2(t) in the paper's (13), Y(t) or omega(t) in an
            implementable observer.
        h : float, optional
            The window length (default tau).

        Returns
        -------
        (m,) or (K, m) array (time-major).

        References
        ----------
        Mazenc & Malisoff (2022), eq. (13).
        """
        E1, E2 = self.decay(self.tau if h is None else h)
        v = (np.asarray(xi1_hat) + (np.asarray(y) - np.asarray(xi2_hat)) @ self.R.T
             + (E1 * np.asarray(psi1_del) - np.asarray(psi1) + np.asarray(psi2)
                - np.asarray(psi2_del) @ E2.T) @ self.S_inv.T)
        return v


def _SN_expm(A1, A2, k, tau):
    """S (5) and N (6) from augmented matrix exponentials (Van Loan)."""
    m = A1.shape[0]
    B = A1 + k * np.eye(m)
    G = np.linalg.solve(B.T, A2.T).T
    # lambda(-s) = C_a e^{A_a s} E on s in [0, tau], A_a = diag(0, -B), C_a = [G, -G], E = [I; I]
    Aa = scipy.linalg.block_diag(np.zeros((m, m)), -B)
    Ca = np.hstack([G, -G])
    E = np.vstack([np.eye(m), np.eye(m)])
    Q = Ca.T @ Ca
    Z = np.zeros((2 * m, 2 * m))
    F = scipy.linalg.expm(np.block([[-Aa.T, Q], [Z, Aa]]) * tau)
    W = F[2 * m:, 2 * m:].T @ F[:2 * m, 2 * m:]          # int_0^tau e^{Aa^T s} Q e^{Aa s} ds
    S = E.T @ W @ E
    S = 0.5 * (S + S.T)
    Fi = scipy.linalg.expm(np.block([[Aa, np.eye(2 * m)], [Z, Z]]) * tau)
    Int = Fi[:2 * m, 2 * m:]                               # int_0^tau e^{Aa s} ds
    Nn = E.T @ Int.T @ Ca.T
    return S, Nn


def _SN_quad(A1, A2, k, tau):
    """S (5) and N (6) by adaptive quadrature (scipy quad_vec) of lambda."""
    m, q = A1.shape[0], A2.shape[0]

    def integrand(r):
        L = lam(r, A1, A2, k)
        return np.concatenate([(L.T @ L).ravel(), L.T.ravel()])

    # relative accuracy on the largest entries; the small eigenvalue of S is
    # checked against the expm route in the tests
    val, _err = scipy.integrate.quad_vec(integrand, -tau, 0.0, epsabs=0.0, epsrel=1e-13,
                                         limit=2000, norm="max")
    S = val[:m * m].reshape(m, m)
    return 0.5 * (S + S.T), val[m * m:].reshape(m, q)


def gramian_design(A1, A2, k, tau, *, method="expm") -> GramianDesign:
    r"""S (5), N, R, H (6) and the constants of (13) for the observer (7).

    Parameters
    ----------
    A1 : (m, m) array_like
    A2 : (q, m) array_like
        (A1, A2) must be observable.
    k : float
        The constant of (2); A1 + kI must be invertible.
    tau : float
        The delay (> 0), the fixed convergence time of Theorem 1.
    method : {"expm", "quad"}
        ``"expm"``: S and N from one augmented matrix exponential each
        (Van Loan 1978), exact up to the exponential's rounding; ``"quad"``:
        adaptive quadrature of (5)-(6) with scipy's ``quad_vec``. The tests
        compare the two.

    Returns
    -------
    GramianDesign

    Raises
    ------
    ValueError
        Bad shapes, non-finite data, tau <= 0, k <= 0, A1 + kI singular,
        (A1, A2) not observable, or S numerically singular.

    Notes
    -----
    R = S^{-1} N is computed with a Cholesky solve; S's condition number
    is reported as ``cond_S`` (the appendix proves S invertible but says
    nothing on its conditioning: about 1.4e5 on the DC-motor example with
    k = 100 and tau = 0.1).

    References
    ----------
    Mazenc & Malisoff (2022), eqs. (4)-(6), (13), and the appendix.
    """
    A1, A2 = _check_pair(A1, A2)
    k = scalar("k", k, positive=True)
    tau = scalar("tau", tau, positive=True)
    if method not in ("expm", "quad"):
        raise ValueError(f"method must be 'expm' or 'quad', got {method!r}")
    _check_k(A1, k)
    m = A1.shape[0]
    if _obsv_rank(A1, A2) < m:
        raise ValueError(f"(A1, A2) must be observable; the observability matrix has rank "
                         f"{_obsv_rank(A1, A2)} < {m}")
    S, Nn = (_SN_expm if method == "expm" else _SN_quad)(A1, A2, k, tau)
    cond_S = float(np.linalg.cond(S))
    if not np.isfinite(cond_S) or cond_S > 1e14:
        raise ValueError(f"S (5) is numerically singular (cond(S) = {cond_S:.3g}) for "
                         f"k = {k}, tau = {tau}")
    cho = scipy.linalg.cho_factor(S)
    R = scipy.linalg.cho_solve(cho, Nn)
    S_inv = scipy.linalg.cho_solve(cho, np.eye(m))
    B = A1 + k * np.eye(m)
    H = np.linalg.solve(B.T, A2.T)                        # (A1 + kI)^{-T} A2^T
    E2 = scipy.linalg.expm(-(A1.T + 2 * k * np.eye(m)) * tau)
    return GramianDesign(A1=A1, A2=A2, k=k, tau=tau, S=S, N=Nn, R=R, H=H, S_inv=S_inv,
                         cond_S=cond_S, method=method, E1=float(np.exp(-k * tau)), E2=E2)


# ----------------------------------------------------------------------------
# Theorem 1's bound (15)
# ----------------------------------------------------------------------------
def _norm2(A):
    return float(np.linalg.norm(np.atleast_2d(A), 2))


def c_Delta(design: GramianDesign) -> float:
    r"""The constant c_Delta(tau) of (11).

    .. math::
        c_\Delta = \tau\bar S|A_2|e^{|A_1|\tau}
                   + \bar S|A_2(A_1+kI)^{-1}|(e^{|A_1|\tau} + 1)e^{|A_1|\tau}

    References
    ----------
    Mazenc & Malisoff (2022), eq. (11).
    """
    d = design
    eA = np.exp(_norm2(d.A1) * d.tau)
    return float(d.tau * d.S_bar * _norm2(d.A2) * eA + d.S_bar * _norm2(d.H.T) * (eA + 1) * eA)


def _signal_norms(fn, s, dim, name):
    """|fn(s_i)| on a grid; fn None means zero."""
    if fn is None:
        return np.zeros_like(s)
    if not callable(fn):
        raise TypeError(f"{name} must be callable t -> ({dim},) array or None, "
                        f"got {type(fn).__name__}")
    vals = np.array([np.asarray(fn(si), dtype=float).reshape(-1) for si in s])
    if vals.shape[1] != dim:
        raise ValueError(f"{name}(t) must have shape ({dim},), got ({vals.shape[1]},)")
    return np.linalg.norm(vals, axis=1)


def theorem1_bound(design: GramianDesign, t, *, eps1=None, eps2=None, delta2=None,
                   K1=0.0, K2=0.0, n_grid=801) -> float:
    r"""Right-hand side of the robustness bound (15) at time t >= tau.

    .. math::
        c_\Delta\!\int_{t-\tau}^t\!|\lambda(s-t)|\!\int_s^t\!\epsilon_1^\#
        + \bar S\!\int_{t-\tau}^t\!|\lambda(s-t)|\!\int_s^t\!\epsilon_2^\#
        + \bar S|H|\{1 + e^{|A_1^\top + 2kI|\tau}\}\!\int_{t-\tau}^t\!|\delta_2|

    with ``eps_i^#(m) = K_i |delta2(m)| + |eps_i(m)|`` (10).

    Parameters
    ----------
    design : GramianDesign
    t : float
        A time ``>= tau`` (the window [t - tau, t] must be past the start 0).
    eps1, eps2, delta2 : callable or None
        ``t -> (m,)``, ``t -> (q,)``, ``t -> (q,)`` disturbances of (2);
        None means zero.
    K1, K2 : float
        Lipschitz constants (3) of F1, F2.
    n_grid : int
        Odd number of Simpson nodes on [t - tau, t] (the integrands are
        smooth; with the default the quadrature error is far below the
        bound's own conservatism).

    Returns
    -------
    float

    References
    ----------
    Mazenc & Malisoff (2022), eqs. (10), (11), (15).
    """
    d = design
    t = float(t)
    if not np.isfinite(t) or t < d.tau:
        raise ValueError(f"t must be >= tau = {d.tau}, got {t!r}")
    K1 = scalar("K1", K1, nonneg=True)
    K2 = scalar("K2", K2, nonneg=True)
    if not isinstance(n_grid, (int, np.integer)) or n_grid < 3 or n_grid % 2 == 0:
        raise ValueError(f"n_grid must be an odd int >= 3, got {n_grid!r}")
    s = np.linspace(t - d.tau, t, n_grid)
    e1 = _signal_norms(eps1, s, d.m, "eps1")
    e2 = _signal_norms(eps2, s, d.q, "eps2")
    dl = _signal_norms(delta2, s, d.q, "delta2")
    f1, f2 = K1 * dl + e1, K2 * dl + e2                     # (10)
    lam_abs = np.array([_norm2(L) for L in d.lam(s - t)])

    def tail(f):                                           # int_s^t f(m) dm on the grid
        c = scipy.integrate.cumulative_trapezoid(f[::-1], -s[::-1], initial=0.0)
        return c[::-1]

    I1 = scipy.integrate.simpson(lam_abs * tail(f1), x=s)
    I2 = scipy.integrate.simpson(lam_abs * tail(f2), x=s)
    I3 = scipy.integrate.simpson(dl, x=s)
    beta = 1.0 + np.exp(_norm2(d.A_psi2) * d.tau)
    return float(c_Delta(d) * I1 + d.S_bar * I2 + d.S_bar * _norm2(d.H) * beta * I3)


# ----------------------------------------------------------------------------
# Theorem 2's constants
# ----------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Theorem2Constants:
    r"""The constants of Theorem 2 for one design and sampling bound.

    Attributes
    ----------
    varsigma : (4,) array
        varsigma_1..4 of (38).
    q1, q2 : float
        (41) and ``q2 = max(varsigma_1 + varsigma_3, varsigma_2)``.
    mu : float
        (41): ``|A2| q1 + k + K2`` (with q1 + |R| in place of q1 when the
        estimate uses omega, see ``estimate``).
    T_bar : float
    T_bar_mu : float
        ``T_bar * mu``; (40) asks ``< 1``.
    holds : bool
        Whether (40) holds.
    rate : float
        ``ln(T_bar mu) / (tau + T_bar)`` (43), negative iff (40) holds.
    T_bar_max : float
        ``1 / mu``, the largest T_bar allowed by (40).
    a1, a2 : float
        The constants of (42) given in Remark 4 (meaningful only when (40)
        holds).
    estimate : str
        ``"xi2"`` (the paper's (13), with q1 as in (41)) or ``"omega"``
        (implementable; q1 replaced by q1 + |R|).
    """

    varsigma: np.ndarray
    q1: float
    q2: float
    mu: float
    T_bar: float
    T_bar_mu: float
    holds: bool
    rate: float
    T_bar_max: float
    a1: float
    a2: float
    estimate: str


def theorem2_constants(design: GramianDesign, K1, K2, T_bar, *,
                       estimate="omega") -> Theorem2Constants:
    r"""Constants (38), (41), condition (40) and rate (43) of Theorem 2.

    Parameters
    ----------
    design : GramianDesign
    K1, K2 : float
        Lipschitz constants (3) of F1 and F2.
    T_bar : float
        Upper bound on the sampling intervals (36).
    estimate : {"omega", "xi2"}
        Which signal enters xi_e in (39) (decision 2 of the module
        docstring). For ``"omega"``, xi_1 - xi_e(omega) = xi_1 - xi_e(xi2)
        + R (xi2 - omega), so the proof's (58) holds with q1 + |R| in place
        of q1; mu and the rate use that value.

    Returns
    -------
    Theorem2Constants

    Notes
    -----
    The varsigma's are one-dimensional integrals of |lambda(s)| (2-norm)
    computed with adaptive quadrature (``scipy.integrate.quad``,
    ``epsrel=1e-10``). On the DC-motor example they are astronomically
    conservative: mu ~ 4e20 for k = 100 (varsigma_3 ~ 1e19 from the
    e^{2|A1| tau} = e^{41} factor and |S^{-1}| ~ 1.5e5), so (40) asks
    T_bar < 2.5e-21, while the observer converges with T = 0.1 (xi_2 in (13))
    or T < 0.017 (omega in (13)); see the periods figure
    (:func:`~observers.gramian_delay.periods_data`).

    References
    ----------
    Mazenc & Malisoff (2022), eqs. (38)-(43), Remark 4.
    """
    d = design
    K1 = scalar("K1", K1, nonneg=True)
    K2 = scalar("K2", K2, nonneg=True)
    T_bar = scalar("T_bar", T_bar, positive=True)
    if estimate not in ("omega", "xi2"):
        raise ValueError(f"estimate must be 'omega' or 'xi2', got {estimate!r}")
    k, tau, Sb = d.k, d.tau, d.S_bar
    nA1, nA2, nH = _norm2(d.A1), _norm2(d.A2), _norm2(d.H)
    eA = np.exp(nA1 * tau)

    def lam_abs(s):
        return _norm2(d.lam(s))

    def integ(g):
        return scipy.integrate.quad(lambda s: lam_abs(s) * g(s), -tau, 0.0,
                                    epsabs=0.0, epsrel=1e-10, limit=200)[0]

    # e^{ks} - ks - 1 loses digits for small |ks|: use expm1
    # (38): varsigma_1..varsigma_4
    vs1 = Sb * nA2 * eA / k**2 * integ(lambda s: np.expm1(k * s) - k * s)
    vs2 = Sb / k * integ(lambda s: -np.expm1(k * s))
    vs3 = Sb * tau * eA * nH * integ(lambda s: eA + np.exp(-k * s))
    vs4 = Sb * nH * (-np.expm1(-k * tau) / k + tau * np.exp(_norm2(d.A_psi2) * tau))
    q1 = (vs1 + vs3) * K1 + vs2 * K2 + vs4                # (41)
    if estimate == "omega":
        q1 = q1 + _norm2(d.R)
    q2 = max(vs1 + vs3, vs2)                               # after (58)
    mu = nA2 * q1 + k + K2                                 # (41)
    Tm = T_bar * mu                                        # (40): holds iff < 1
    rate = float(np.log(Tm) / (tau + T_bar))               # (43)
    T_sharp = T_bar * (nA2 * q2 + 1) + 1
    a1 = q1 * np.exp(-rate * tau)                          # Remark 4, (42)
    a2 = q2 + q1 * T_sharp / (1 - Tm) if Tm < 1 else np.inf
    return Theorem2Constants(varsigma=np.array([vs1, vs2, vs3, vs4]), q1=float(q1),
                             q2=float(q2), mu=float(mu), T_bar=T_bar, T_bar_mu=float(Tm),
                             holds=bool(Tm < 1), rate=rate, T_bar_max=float(1 / mu),
                             a1=float(a1), a2=float(a2), estimate=estimate)


def sampling_instants(T_min, T_max, t_end, *, seed=None, t0=0.0):
    r"""Sampling instants t_0 = t0 < t_1 < ... with T_min <= t_{k+1} - t_k <= T_max.

    The intervals are drawn uniformly in [T_min, T_max] (all equal to T_min
    when T_min == T_max: periodic sampling, as in the paper's Section V,
    although (36) writes T_bar > T_min strictly).

    Parameters
    ----------
    T_min, T_max : float
        ``0 < T_min <= T_max``.
    t_end : float
        The instants cover [t0, t_end] (the last one is >= t_end).
    seed : int or numpy Generator, optional
    t0 : float

    Returns
    -------
    (K,) array

    References
    ----------
    Mazenc & Malisoff (2022), eq. (36).
    """
    T_min = scalar("T_min", T_min, positive=True)
    T_max = scalar("T_max", T_max, positive=True)
    if T_max < T_min:
        raise ValueError(f"T_max must be >= T_min = {T_min}, got {T_max}")
    t_end = float(t_end)
    t0 = float(t0)
    if not np.isfinite(t_end) or t_end < t0:
        raise ValueError(f"t_end must be finite and >= t0 = {t0}, got {t_end}")
    rng = np.random.default_rng(seed)
    n = int(np.ceil((t_end - t0) / T_min)) + 2
    h = rng.uniform(T_min, T_max, size=n) if T_max > T_min else np.full(n, T_min)
    ts = t0 + np.concatenate([[0.0], np.cumsum(h)])
    last = int(np.searchsorted(ts, t_end)) + 1
    return ts[:last]
