r"""Fixed-time Gramian observers with a single delay (Mazenc & Malisoff, LCSYS 2022).

The paper builds reduced-order observers for systems affine in the
unmeasured state,

.. math::

    \dot\xi_1 = A_1\xi_1 + F_1(\xi_2, t) + \epsilon_1,\quad
    \dot\xi_2 = A_2\xi_1 - k\xi_2 + F_2(\xi_2, t) + \epsilon_2,\quad
    Y = \xi_2 + \delta_2,

(eq. (2)), with a dynamic extension (7) and an estimate (13) that reads the
extension at ``t - tau`` only. With continuous measurements the estimate is
exact for ``t >= tau`` (Theorem 1); with sampled measurements a variable
``omega`` is reset to each sample and the error decays exponentially when
``T_bar * mu < 1`` (Theorem 2).

Contents
--------
Design computations (numpy/scipy only):

* :func:`observer_form` -- the change of coordinates of Section II from
  (M, N) to the form (2), returned as an :class:`ObserverForm`.
* :func:`lam` -- the function lambda(r) of (4).
* :func:`gramian_design` -- S (5), N, R, H (6) as a :class:`GramianDesign`
  (augmented matrix exponential or adaptive quadrature).
* :func:`c_Delta`, :func:`theorem1_bound` -- the constant (11) and the
  right-hand side of the robustness bound (15).
* :func:`theorem2_constants` -- the constants (38), (41), the condition (40)
  and the rate (43) as a :class:`Theorem2Constants`.
* :func:`sampling_instants` -- instants with ``T_min <= t_{k+1} - t_k <= T_max``.

Hybrid systems (on :mod:`hybridsim`):

* :class:`Plant` -- system (1) (or (2) with M in block form), output Y.
* :class:`GramianObserver` -- the dynamic extension (7), input Y, D empty;
  :meth:`GramianObserver.estimate` evaluates (13) along its arc.
* :class:`SampledGramianObserver` -- the observer (39), omega reset at each
  sampling instant (timer or given list); the estimate (13) enters omega's
  flow through the run's history (a delay equation).
* :func:`dc_motor` -- the DC-motor example (64)-(67).
* :func:`reproduce` -- Figs. 1 and 2.

Decisions on the paper's ambiguities (each is tested in
``tests/test_gramian_delay.py``):

1. **Typo in (39) and (45).** The flow of the estimate of xi_2 is printed
   ``A2 xi2_hat - k xi2_hat``; ``A2`` is q x (n-q), so this cannot be
   evaluated when q != n - q and is inconsistent with (7) and with the error
   system (18). We use ``A2 xi1_hat - k xi2_hat + F2(omega, t)`` as in (7).
2. **Which xi_2 enters xi_e in (39).** (13) uses the unmeasured xi_2(t). The
   implementable observer uses omega(t) (``estimate="omega"``, the default);
   the literal reading (``estimate="xi2"``) needs xi_2(t) as an extra input
   and is kept as an oracle for comparison. With omega, the proof of Theorem
   2 goes through with q1 replaced by q1 + abs(R) (because
   xi_e(omega) = xi_e(xi2) - R (xi2 - omega)); :func:`theorem2_constants`
   reports both.
3. **The history before tau.** (13) reads psi_i(t - tau), undefined for
   t - tau < t0. We continue psi_i backwards by its free response (zero
   input), i.e. psi_1(s) = e^{-k(s-t0)} psi_1(t0); equivalently the
   integrals over [t - tau, t] behind (52)-(53) are truncated to [t0, t].
   The estimate for t < t0 + tau is then the truncated-window estimate (not
   exact, not claimed by the paper), and it never depends on psi_i(t0).
4. **Continuous-case estimate under noise.** (13) uses xi_2(t); the
   implementable estimate uses Y(t) = xi_2(t) + delta_2(t) and so differs
   by R delta_2(t). :meth:`GramianObserver.estimate` takes whichever signal
   is passed as ``y``; the bound (15) is for the literal (13).
5. **Sampling bounds.** (36) asks T_min < T_max strictly, yet Section V
   uses T_bar = T_min = 0.1 (periodic sampling). We allow T_min = T_max.
6. **Accuracy of S.** S is badly conditioned on the DC-motor example
   (cond(S) about 1.4e5 for k = 100, 5.9e6 for k = 75); we compute S and
   N from one augmented matrix exponential (Van Loan) and check them
   against adaptive quadrature; cond(S) is reported.
7. **k and the stability of psi_2 (not in the paper).** psi_2 of (7) flows
   with -(A1^T + 2kI), unstable when 2k < -min Re eig(A1) (k = 75 on the
   DC motor: growth +47.2/s). (13) is still exact in exact arithmetic, but
   it subtracts two growing terms: in floating point the estimate is lost
   after ~0.8 s (:attr:`GramianDesign.psi2_growth` reports the rate).

Measured (``reproduce``): Theorem 1's exactness holds to ~1e-10 for
t >= tau; Theorem 2's constants give T_bar mu ~ 4e19 for the paper's
T_bar = 0.1 (k = 100), yet the observer converges there with xi_2 in (13),
and with omega in (13) for periods up to ~0.017.

References
----------
.. [1] F. Mazenc, M. Malisoff, "New finite-time and fast converging
   observers with a single delay", IEEE Control Systems Letters 6 (2022)
   1561-1566, hal-03430682.
.. [2] C. Van Loan, "Computing integrals involving the matrix exponential",
   IEEE Trans. Automat. Control 23(3) (1978) 395-404.
"""
from __future__ import annotations

import dataclasses
import pathlib
from typing import Callable

import numpy as np
import scipy.integrate
import scipy.linalg

from scipy.linalg import expm as _expm

__all__ = [
    "ObserverForm", "observer_form", "lam", "GramianDesign", "gramian_design",
    "c_Delta", "theorem1_bound", "Theorem2Constants", "theorem2_constants",
    "sampling_instants",
]


# ----------------------------------------------------------------------------
# input checks
# ----------------------------------------------------------------------------
def _matrix(name, A, shape=None):
    """A finite 2-D float array; ``shape`` entries None are free."""
    try:
        A = np.array(A, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a real matrix, got {type(A).__name__}") from exc
    if A.ndim == 1 and shape is not None and shape[0] == 1:
        A = A[None, :]
    if A.ndim != 2:
        raise ValueError(f"{name} must be 2-dimensional, got shape {A.shape}")
    if shape is not None:
        for want, got in zip(shape, A.shape):
            if want is not None and want != got:
                want_s = ", ".join("*" if s is None else str(s) for s in shape)
                raise ValueError(f"{name} must have shape ({want_s}), got {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError(f"{name} must be finite, got non-finite entries")
    return A


def _positive(name, v, *, allow_zero=False):
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(v).__name__}")
    v = float(v)
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        want = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be finite and {want}, got {v!r}")
    return v


def _vector(name, v, n):
    v = np.asarray(v, dtype=float).reshape(-1)
    if v.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be finite")
    return v


def _obsv_rank(A1, A2):
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
        ``Psi(y, t) -> (n,)``, the nonlinearity of (1).
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

    def F1(self, y, t):
        """F1 of (2) at measured value ``y`` (q,) and time ``t``."""
        m = self.n - self.q
        out = self.M_xi[:m, m:] @ np.asarray(y, dtype=float)
        if self.Psi is not None:
            out = out + self.P @ np.asarray(self.Psi(y, t), dtype=float)
        return out

    def F2(self, y, t):
        """F2 of (2) at measured value ``y`` (q,) and time ``t``."""
        m = self.n - self.q
        y = np.asarray(y, dtype=float)
        out = self.M_xi[m:, m:] @ y + self.k * y
        if self.Psi is not None:
            out = out + self.N @ np.asarray(self.Psi(y, t), dtype=float)
        return out

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
        measured ``y = N chi`` and t).
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
    M = _matrix("M", M)
    n = M.shape[0]
    if M.shape != (n, n):
        raise ValueError(f"M must be square, got shape {M.shape}")
    N = _matrix("N", N, (None, n))
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
    P = _matrix("P", P, (n - q, n))
    T = np.vstack([P, N])
    if np.linalg.matrix_rank(T) < n:
        raise ValueError("P must complete N to an invertible [P; N]; got a singular matrix")
    T_inv = np.linalg.inv(T)
    M_xi = T @ M @ T_inv
    m = n - q
    A1, A2 = M_xi[:m, :m].copy(), M_xi[m:, :m].copy()
    if k is None:
        k = float(np.max(np.abs(np.linalg.eigvals(A1)))) + 1.0
    k = _positive("k", k)
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
    A1 = _matrix("A1", A1)
    m = A1.shape[0]
    if A1.shape != (m, m):
        raise ValueError(f"A1 must be square, got shape {A1.shape}")
    A2 = _matrix("A2", A2, (None, m))
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
    k = _positive("k", k)
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

    def lam(self, r):
        """lambda(r) of (4); see :func:`lam`."""
        return lam(r, self.A1, self.A2, self.k)

    def decay(self, h):
        r"""``(e^{-k h}, e^{-(A1^T + 2kI) h})``: psi's free response over h.

        Returns ``(E1, E2)`` for ``h == tau`` without recomputing.
        """
        if h == self.tau:
            return self.E1, self.E2
        return float(np.exp(-self.k * h)), _expm(-self.A_psi2 * h)

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
    m, q = A1.shape[0], A2.shape[0]
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
    k = _positive("k", k)
    tau = _positive("tau", tau)
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
    K1 = _positive("K1", K1, allow_zero=True)
    K2 = _positive("K2", K2, allow_zero=True)
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
    or T < 0.017 (omega in (13)); see :func:`reproduce`.

    References
    ----------
    Mazenc & Malisoff (2022), eqs. (38)-(43), Remark 4.
    """
    d = design
    K1 = _positive("K1", K1, allow_zero=True)
    K2 = _positive("K2", K2, allow_zero=True)
    T_bar = _positive("T_bar", T_bar)
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
    vs1 = Sb * nA2 * eA / k**2 * integ(lambda s: np.expm1(k * s) - k * s)
    vs2 = Sb / k * integ(lambda s: -np.expm1(k * s))
    vs3 = Sb * tau * eA * nH * integ(lambda s: eA + np.exp(-k * s))
    vs4 = Sb * nH * (-np.expm1(-k * tau) / k + tau * np.exp(_norm2(d.A_psi2) * tau))
    q1 = (vs1 + vs3) * K1 + vs2 * K2 + vs4
    if estimate == "omega":
        q1 = q1 + _norm2(d.R)
    q2 = max(vs1 + vs3, vs2)
    mu = nA2 * q1 + k + K2
    Tm = T_bar * mu
    rate = float(np.log(Tm) / (tau + T_bar))
    T_sharp = T_bar * (nA2 * q2 + 1) + 1
    a1 = q1 * np.exp(-rate * tau)
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
    T_min = _positive("T_min", T_min)
    T_max = _positive("T_max", T_max)
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


# ----------------------------------------------------------------------------
# Hybrid systems on the engine
# ----------------------------------------------------------------------------
import hybridsim as hs  # noqa: E402  (the design part above needs no engine)

__all__ += ["Plant", "GramianObserver", "SampledGramianObserver", "DCMotor", "dc_motor",
            "estimate_along", "reproduce"]


def _signal(name, fn, dim):
    """A callable t -> (dim,) array (None: zero)."""
    if fn is None:
        z = np.zeros(dim)
        return lambda t: z
    if not callable(fn):
        raise TypeError(f"{name} must be callable t -> ({dim},) array or None, "
                        f"got {type(fn).__name__}")
    return lambda t: np.asarray(fn(t), dtype=float).reshape(dim)


class Plant(hs.HybridSystem):
    r"""System (1): chi' = M chi + Psi(N chi, t) + delta1(t), Y = N chi + delta2(t).

    A hybrid system with empty jump set and no input (u(t) enters through
    Psi's time argument). Its output is Y (q,), or ``(Y, N chi)`` (2q,)
    when ``oracle=True`` (to feed the literal reading of (39), which needs
    the unmeasured xi_2 = N chi).

    Parameters
    ----------
    M : (n, n) array_like
    N : (q, n) array_like
    Psi : callable, optional
        ``Psi(y, t) -> (n,)``.
    delta1 : callable, optional
        ``t -> (n,)`` disturbance on the dynamics.
    delta2 : callable, optional
        ``t -> (q,)`` measurement disturbance.
    oracle : bool

    References
    ----------
    Mazenc & Malisoff (2022), eq. (1).
    """

    def __init__(self, M, N, Psi=None, *, delta1=None, delta2=None, oracle=False):
        self.M = _matrix("M", M)
        n = self.M.shape[0]
        if self.M.shape != (n, n):
            raise ValueError(f"M must be square, got shape {self.M.shape}")
        self.N = _matrix("N", N, (None, n))
        q = self.N.shape[0]
        if Psi is not None and not callable(Psi):
            raise TypeError(f"Psi must be callable, got {type(Psi).__name__}")
        self.Psi = Psi
        if Psi is not None:
            _probe_shape("Psi", lambda: Psi(np.zeros(q), 0.0), (n,), f"(n = {n} states)")
        self.delta1 = _signal("delta1", delta1, n)
        self.delta2 = _signal("delta2", delta2, q)
        self.oracle = bool(oracle)
        self.state_dim = n
        self.output_dim = 2 * q if oracle else q

    def flow_map(self, x, t):
        dx = self.M @ x + self.delta1(t)
        if self.Psi is not None:
            dx = dx + np.asarray(self.Psi(self.N @ x, t), dtype=float)
        return dx

    def output(self, x, t, j):
        y = self.N @ x
        Y = y + self.delta2(t)
        return np.concatenate([Y, y]) if self.oracle else Y


def _probe_shape(name, call, shape, what):
    """Call a user map once (at y = 0, t = 0) and check its output size; a map that raises is not judged here."""
    try:
        v = np.asarray(call(), dtype=float)
    except Exception:       # noqa: BLE001 -- the map may be undefined at the probe point; the run will tell
        return
    if v.size != int(np.prod(shape)):
        raise ValueError(f"{name}(y, t) must return shape {shape} {what}, got shape {v.shape}")


class _ObserverBase(hs.HybridSystem):
    """Shared checks and slicing of (xi1_hat, xi2_hat, psi1, psi2, ...)."""

    def __init__(self, design, F1, F2):
        if not isinstance(design, GramianDesign):
            raise TypeError(f"design must be a GramianDesign, got {type(design).__name__}")
        for name, F in (("F1", F1), ("F2", F2)):
            if not callable(F):
                raise TypeError(f"{name} must be callable (y, t) -> array, got {type(F).__name__}")
        self.design = design
        self.F1, self.F2 = F1, F2
        m, q = design.m, design.q
        # dimensions agree at construction, not as a broadcast error inside a run
        for name, F, dim in (("F1", F1, m), ("F2", F2, q)):
            _probe_shape(name, lambda F=F: F(np.zeros(q), 0.0), (dim,),
                         f"(n - q = {m} unmeasured states)" if name == "F1" else f"(q = {q} outputs)")
        self.sl_xi1 = slice(0, m)
        self.sl_xi2 = slice(m, m + q)
        self.sl_psi1 = slice(m + q, 2 * m + q)
        self.sl_psi2 = slice(2 * m + q, 3 * m + q)
        d = design
        self._mA2 = -d.A_psi2

    def _extension_flow(self, z, t, y):
        """Flows of (xi1_hat, xi2_hat, psi1, psi2) of (7) with measurement y."""
        d = self.design
        xi1, xi2 = z[self.sl_xi1], z[self.sl_xi2]
        innov = d.H @ (y - xi2)
        return np.concatenate([
            d.A1 @ xi1 + np.asarray(self.F1(y, t), dtype=float).reshape(d.m),
            d.A2 @ xi1 - d.k * xi2 + np.asarray(self.F2(y, t), dtype=float).reshape(d.q),
            -d.k * z[self.sl_psi1] + innov,
            self._mA2 @ z[self.sl_psi2] + innov])

    def _initial(self, xi1_hat0, xi2_hat0, psi10, psi20):
        d = self.design
        return np.concatenate([
            np.zeros(d.m) if xi1_hat0 is None else _vector("xi1_hat0", xi1_hat0, d.m),
            np.zeros(d.q) if xi2_hat0 is None else _vector("xi2_hat0", xi2_hat0, d.q),
            np.zeros(d.m) if psi10 is None else _vector("psi1_0", psi10, d.m),
            np.zeros(d.m) if psi20 is None else _vector("psi2_0", psi20, d.m)])


def _delayed(design, t, t0, psi_at):
    """psi_1, psi_2 at t - h and the window h (decision 3: h = min(tau, t - t0))."""
    h = min(design.tau, t - t0)
    if h < design.tau:
        return psi_at(t0), h
    return psi_at(t - design.tau), h


class GramianObserver(_ObserverBase):
    r"""The dynamic extension (7) for continuous measurements Y (Theorem 1).

    State ``z = (xi1_hat, xi2_hat, psi1, psi2)`` of length ``3(n-q) + q``
    (time-major arcs: ``arc.x`` is (N, 3(n-q)+q)); input ``u = Y`` (q,);
    empty jump set.

    .. math::
        \dot{\hat\xi}_1 = A_1\hat\xi_1 + F_1(Y, t),\quad
        \dot{\hat\xi}_2 = A_2\hat\xi_1 - k\hat\xi_2 + F_2(Y, t),\\
        \dot\psi_1 = -k\psi_1 + H(Y - \hat\xi_2),\quad
        \dot\psi_2 = -(A_1^\top + 2kI)\psi_2 + H(Y - \hat\xi_2).

    The estimate (13) reads psi at t - tau and Y(t); it is evaluated along
    a finished run by :meth:`estimate` (the engine's output map may not
    depend on the input).

    Parameters
    ----------
    design : GramianDesign
    F1, F2 : callable
        ``F1(y, t) -> (n-q,)``, ``F2(y, t) -> (q,)`` of (2).
    t0 : float
        Start of the runs (for the history rule before t0 + tau).

    References
    ----------
    Mazenc & Malisoff (2022), eqs. (7), (13), Theorem 1.
    """

    def __init__(self, design, F1, F2, *, t0=0.0):
        super().__init__(design, F1, F2)
        self.t0 = float(t0)
        self.state_dim = 3 * design.m + design.q
        self.input_dim = design.q

    def flow_map(self, z, t, j, u):
        return self._extension_flow(z, t, np.asarray(u, dtype=float))

    def initial_state(self, xi1_hat0=None, xi2_hat0=None, psi1_0=None, psi2_0=None):
        """The observer's initial state (zeros where not given)."""
        return self._initial(xi1_hat0, xi2_hat0, psi1_0, psi2_0)

    def estimate(self, arc, y, *, name=None):
        r"""xi_e (13) at every sample of ``arc``; time-major (N, n-q).

        Parameters
        ----------
        arc : HybridArc
            The run (of this observer alone, or of an interconnection with
            ``name`` naming this observer). Run it with ``dense=True``: the
            values at t - tau are then read from the solver's dense output
            (exact to the integrator), else they are interpolated linearly.
        y : (N, q) array_like or callable
            The measured signal at the samples: Y(t) (implementable), or
            xi_2(t) (the paper's (13)). A callable is ``(t) -> (q,)``.
        name : str, optional
            The observer's name in an interconnection.
        """
        return estimate_along(self, arc, y, name=name)


class SampledGramianObserver(_ObserverBase):
    r"""The observer (39) for measurements sampled at t_0 < t_1 < ... (Theorem 2).

    State ``z = (xi1_hat, xi2_hat, psi1, psi2, omega, sigma, kappa)``:
    (7)'s extension driven by omega instead of Y, omega (q,), a timer sigma
    (time since the last sample) and a sample counter kappa. Input ``u = Y``
    (q,) (or ``(Y, xi2)`` (2q,) with ``estimate="xi2"``), read at the jumps
    only. Flow (between samples):

    .. math::
        \dot{\hat\xi}_1 = A_1\hat\xi_1 + F_1(\omega, t),\quad
        \dot{\hat\xi}_2 = A_2\hat\xi_1 - k\hat\xi_2 + F_2(\omega, t),\\
        \dot\psi_i = \dots + H(\omega - \hat\xi_2),\quad
        \dot\omega = A_2\xi_e(t) - k\omega + F_2(\omega, t),

    with xi_e of (13) reading psi at t - tau through the run's history (a
    delay equation; ``max_step = tau``). Jump (a sample): omega^+ = Y,
    sigma^+ = 0, kappa^+ = kappa + 1.

    Decisions (module docstring): the xi2_hat flow uses ``A2 xi1_hat`` (the
    printed ``A2 xi2_hat`` of (39) is a typo); ``estimate="omega"`` puts
    omega(t) in place of the unmeasured xi_2(t) in (13).

    Parameters
    ----------
    design : GramianDesign
    F1, F2 : callable
        As in (2).
    period : float, optional
        Periodic sampling by the timer: D = {sigma >= period}.
    instants : (K,) array_like, optional
        Increasing sampling instants (e.g. :func:`sampling_instants`):
        D = {t >= instants[kappa]}. Exactly one of period, instants.
    estimate : {"omega", "xi2"}
    t0 : float
        Start of the runs (history rule before t0 + tau).

    References
    ----------
    Mazenc & Malisoff (2022), eqs. (36)-(39), Theorem 2.
    """

    def __init__(self, design, F1, F2, *, period=None, instants=None, estimate="omega",
                 t0=0.0):
        super().__init__(design, F1, F2)
        if (period is None) == (instants is None):
            raise ValueError("give exactly one of period and instants")
        if period is not None:
            self.period = _positive("period", period)
            self.instants = None
        else:
            ins = np.asarray(instants, dtype=float).reshape(-1)
            if ins.size == 0 or not np.all(np.isfinite(ins)):
                raise ValueError("instants must be a non-empty finite 1-D array")
            if np.any(np.diff(ins) <= 0):
                raise ValueError("instants must be strictly increasing")
            self.period, self.instants = None, ins
        if estimate not in ("omega", "xi2"):
            raise ValueError(f"estimate must be 'omega' or 'xi2', got {estimate!r}")
        self.estimate_source = estimate
        m, q = design.m, design.q
        self.t0 = float(t0)
        self.sl_omega = slice(3 * m + q, 3 * m + 2 * q)
        self.i_sigma = 3 * m + 2 * q
        self.i_kappa = self.i_sigma + 1
        self.state_dim = 3 * m + 2 * q + 2
        self.input_dim = q if estimate == "omega" else 2 * q
        self.max_step = design.tau
        self.needs_history = True
        # psi' jumps with omega at the samples, so psi(t - tau) has kinks at t_k + tau
        self.delays = (design.tau,)

    def initial_state(self, xi1_hat0=None, xi2_hat0=None, psi1_0=None, psi2_0=None,
                      omega0=None):
        """Initial state; the timer/counter are set so that a sample is taken at t0."""
        q = self.design.q
        w = np.zeros(q) if omega0 is None else _vector("omega0", omega0, q)
        sigma0 = self.period if self.period is not None else 0.0
        return np.concatenate([self._initial(xi1_hat0, xi2_hat0, psi1_0, psi2_0), w,
                               [sigma0, 0.0]])

    def _xi_e_now(self, z, t, u):
        d = self.design
        psi_del, h = _delayed(d, t, self.t0, self.history)
        y = z[self.sl_omega] if self.estimate_source == "omega" else np.asarray(u)[d.q:]
        return d.xi_e(z[self.sl_xi1], z[self.sl_xi2], z[self.sl_psi1], z[self.sl_psi2],
                      psi_del[self.sl_psi1], psi_del[self.sl_psi2], y, h=h)

    def flow_map(self, z, t, j, u):
        d = self.design
        w = z[self.sl_omega]
        ext = self._extension_flow(z, t, w)
        xe = self._xi_e_now(z, t, u)
        dw = d.A2 @ xe - d.k * w + np.asarray(self.F2(w, t), dtype=float).reshape(d.q)
        return np.concatenate([ext, dw, [1.0, 0.0]])

    def jump_guard(self, z, t, j, u):
        if self.period is not None:
            return z[self.i_sigma] - self.period
        kap = int(round(z[self.i_kappa]))
        if kap >= len(self.instants):
            return -1.0
        return t - self.instants[kap]

    def jump_map(self, z, t, j, u):
        z = np.array(z, dtype=float)
        z[self.sl_omega] = np.asarray(u, dtype=float)[:self.design.q]
        z[self.i_sigma] = 0.0
        z[self.i_kappa] += 1.0
        return z

    def estimate(self, arc, *, y=None, name=None):
        r"""xi_e (13) at every sample of ``arc`` as the observer used it.

        With ``estimate="omega"`` the signal in (13) is the arc's omega
        (default ``y``); pass ``y`` (e.g. the true xi_2) to evaluate (13)
        with another signal. Run with ``dense=True`` for exact delayed values.
        """
        if y is None:
            if self.estimate_source != "omega":
                raise ValueError("y must be given (the xi_2 samples) when estimate='xi2'")
            arc_o = arc.component(name) if name is not None else arc
            y = arc_o.x[:, self.sl_omega]
        return estimate_along(self, arc, y, name=name)


def estimate_along(observer, arc, y, *, name=None):
    r"""Evaluate xi_e (13) along a finished run of a Gramian observer.

    Parameters
    ----------
    observer : GramianObserver or SampledGramianObserver
    arc : HybridArc
        The run; with ``name``, an interconnection's run and the observer's
        component name.
    y : (N, q) array_like or callable t -> (q,)
        The signal that stands for xi_2(t) in (13), at the arc's samples.
    name : str, optional

    Returns
    -------
    (N, n-q) array, time-major.

    Notes
    -----
    psi at t - tau is read with ``arc.at`` (the solver's dense output when
    the run kept it). Before t0 + tau the window is truncated to [t0, t]
    (module docstring, decision 3).

    References
    ----------
    Mazenc & Malisoff (2022), eq. (13).
    """
    if not isinstance(observer, _ObserverBase):
        raise TypeError(f"observer must be a Gramian observer, got {type(observer).__name__}")
    d = observer.design
    if name is not None:
        sl = arc.components[name]
        Z = arc.x[:, sl]
        base = sl.start

        def psi_at(s):
            return arc.at(s)[base:base + sl.stop - sl.start]
    else:
        Z = arc.x
        psi_at = arc.at
    if Z.shape[1] != observer.state_dim:
        raise ValueError(f"arc must hold the observer's state of length {observer.state_dim}, "
                         f"got {Z.shape[1]} (pass name= for an interconnection)")
    if callable(y):
        Y = np.array([np.asarray(y(t), dtype=float).reshape(d.q) for t in arc.t])
    else:
        Y = np.asarray(y, dtype=float)
        if Y.shape != (len(arc.t), d.q):
            raise ValueError(f"y must have shape ({len(arc.t)}, {d.q}), got {Y.shape}")
    out = np.empty((len(arc.t), d.m))
    for i, t in enumerate(arc.t):
        z = Z[i]
        pd, h = _delayed(d, t, observer.t0, psi_at)
        out[i] = d.xi_e(z[observer.sl_xi1], z[observer.sl_xi2], z[observer.sl_psi1],
                        z[observer.sl_psi2], pd[observer.sl_psi1], pd[observer.sl_psi2],
                        Y[i], h=h)
    return out


# ----------------------------------------------------------------------------
# Section V: the DC motor (64)-(67)
# ----------------------------------------------------------------------------
@dataclasses.dataclass
class DCMotor:
    """The DC-motor example (65)-(67) with everything a run needs.

    Attributes
    ----------
    params : dict
        b0, b1, a1..a4 (the paper's values, "as in [6]").
    form : ObserverForm
        (65) in the coordinates (66): xi1 = (chi2, chi3), xi2 = chi1.
    design : GramianDesign
    plant : Plant
        (65) in chi coordinates, output Y = chi1 + delta2.
    K1, K2 : float
        Lipschitz constants a1 and k of F1, F2 (Section V).
    u, delta1, delta2 : callable
        Control and disturbances (our choices: the paper cites them from
        its ref. [6], which we do not have).
    chi0 : (3,) array
        Plant initial state (our choice).
    """

    params: dict
    form: ObserverForm
    design: GramianDesign
    plant: Plant
    K1: float
    K2: float
    u: Callable
    delta1: Callable
    delta2: Callable
    chi0: np.ndarray

    def xi(self, chi):
        """(66)'s coordinates of plant states (time-major (N, 3) or (3,))."""
        return self.form.to_xi(chi)

    def continuous_observer(self, t0=0.0):
        """The observer (7) of Theorem 1 for this motor."""
        return GramianObserver(self.design, self.form.F1, self.form.F2, t0=t0)

    def sampled_observer(self, **kw):
        """The observer (39) of Theorem 2 (keywords of SampledGramianObserver)."""
        return SampledGramianObserver(self.design, self.form.F1, self.form.F2, **kw)


DC_PARAMS = dict(b0=40.0, b1=15.0, a1=35.0, a2=1.0, a3=36.4, a4=200.0)


def dc_motor(k=100.0, tau=0.1, *, disturbed=True, u=None, delta1=None, delta2=None,
             chi0=None, oracle=False) -> DCMotor:
    r"""The single-link manipulator with DC motor (64)-(67).

    Parameters
    ----------
    k, tau : float
        The paper uses tau = 0.1 and k = 100 (Fig. 1), 75 and 150 (Fig. 2).
    disturbed : bool
        False: delta1 = delta2 = 0 (the setting of Theorem 1's exactness).
        True: our default disturbances (below) unless given.
    u, delta1, delta2 : callable, optional
        Control ``t -> float``, ``t -> (3,)`` and ``t -> (1,)``. The paper
        takes them from its ref. [6]; we choose (and say so in the figures):
        ``u(t) = 2 sin(2t)``, ``delta1(t) = (0, 0.5 sin(5t), 0.5 cos(3t))``
        and ``delta2(t) = 1e-3 sin(20t)``.
    chi0 : (3,) array_like, optional
        Plant initial state; default (our choice) (0.5, -1, 0.2).
    oracle : bool
        Plant output (Y, chi1) instead of Y (for estimate="xi2").

    Returns
    -------
    DCMotor

    References
    ----------
    Mazenc & Malisoff (2022), Section V, eqs. (64)-(67).
    """
    p = DC_PARAMS
    M = np.array([[0.0, 1.0, 0.0], [0.0, -p["a2"], p["b1"]], [0.0, -p["a3"], -p["a4"]]])
    Nmat = np.array([[1.0, 0.0, 0.0]])
    if u is None:
        u = lambda t: 2.0 * np.sin(2.0 * t)  # noqa: E731
    elif not callable(u):
        raise TypeError(f"u must be callable t -> float, got {type(u).__name__}")
    if disturbed:
        if delta1 is None:
            delta1 = lambda t: np.array([0.0, 0.5 * np.sin(5 * t), 0.5 * np.cos(3 * t)])  # noqa: E731
        if delta2 is None:
            delta2 = lambda t: np.array([1e-3 * np.sin(20 * t)])  # noqa: E731
    else:
        if delta1 is not None or delta2 is not None:
            raise ValueError("delta1 and delta2 must be None when disturbed=False")
        delta1 = lambda t: np.zeros(3)  # noqa: E731
        delta2 = lambda t: np.zeros(1)  # noqa: E731
    d1 = _signal("delta1", delta1, 3)
    d2 = _signal("delta2", delta2, 1)

    def Psi(y, t):
        return np.array([0.0, -p["a1"] * np.sin(y[0]), p["b0"] * float(u(t))])

    form = observer_form(M, Nmat, Psi, P=[[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], k=k)
    design = gramian_design(form.A1, form.A2, form.k, tau)
    plant = Plant(M, Nmat, Psi, delta1=d1, delta2=d2, oracle=oracle)
    chi0 = np.array([0.5, -1.0, 0.2]) if chi0 is None else _vector("chi0", chi0, 3)
    return DCMotor(params=dict(p), form=form, design=design, plant=plant, K1=p["a1"],
                   K2=float(k), u=u, delta1=d1, delta2=d2, chi0=chi0)


# ----------------------------------------------------------------------------
# Figures 1-2 of Section V
# ----------------------------------------------------------------------------
_RUN = dict(method="LSODA", rtol=1e-9, atol=1e-11, dense=True, progress=False)


def _run_dc(k, *, sampled, T=0.1, estimate="xi2", t_max=1.0, disturbed=True, max_norm=1e6):
    """One run of (66) with an observer; returns (t, error (N, 2), arc)."""
    ex = dc_motor(k, 0.1, disturbed=disturbed, oracle=sampled and estimate == "xi2")
    obs = (ex.sampled_observer(period=T, estimate=estimate) if sampled
           else ex.continuous_observer())
    sysc = hs.connect(ex.plant, obs, names=("plant", "obs"))
    x0 = sysc.stack(plant=ex.chi0, obs=obs.initial_state())
    arc = hs.simulate(sysc, x0, t_max=t_max, j_max=10**6, max_norm=max_norm, **_RUN)
    xi = ex.xi(arc["plant"].x)
    if sampled:
        xe = obs.estimate(arc, name="obs", y=None if estimate == "omega" else xi[:, 2:])
    else:
        xe = obs.estimate(arc, arc.outputs("plant"), name="obs")
    return arc.t, xi[:, :2] - xe, arc


def _err_at(t, e, s):
    i = min(int(np.searchsorted(t, s)), len(t) - 1)
    return float(np.linalg.norm(e[i]))


def _write(fig, outdir, name, caption):
    png = outdir / f"{name}.png"
    fig.savefig(png, dpi=110)
    (outdir / f"{name}.txt").write_text(caption.strip() + "\n")
    return png


_CHOICES = ("Our choices (the paper takes them from its ref. [6], which we do not have): "
            "u(t) = 2 sin(2t), chi(0) = (0.5, -1, 0.2), observer state 0 at t = 0, "
            "delta_1(t) = (0, 0.5 sin 5t, 0.5 cos 3t), delta_2(t) = 1e-3 sin 20t. "
            "From the paper: b0 = 40, b1 = 15, a1 = 35, a2 = 1, a3 = 36.4, a4 = 200, "
            "tau = 0.1, T_bar = T_min = 0.1 (periodic sampling).")


def reproduce(outdir) -> list:
    """Regenerate Figs. 1 and 2 of Section V (and one figure of ours) as PNG files.

    Fig. 1: error components of xi_{1,1} (red) and xi_{1,2} (blue) for
    Theorem 1 (left, continuous Y, estimate (13) with Y(t)) and Theorem 2
    (right, samples every 0.1, (13) with xi_2(t) as printed), k = 100.
    Fig. 2: the same for k = 75 (solid) and k = 150 (dashed).
    Fig. 3 (ours): the sampled observer with omega(t) in (13) (implementable)
    vs xi_2(t) (literal) as the sampling period grows.

    Parameters
    ----------
    outdir : str or pathlib.Path

    Returns
    -------
    list of pathlib.Path
        The PNG files (a ``.txt`` caption next to each).
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    outdir = pathlib.Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    paths = []
    t_max = 1.0

    # design numbers
    print("Mazenc-Malisoff (2022), DC motor (66), tau = 0.1")
    for k in (75.0, 100.0, 150.0):
        ex = dc_motor(k, 0.1)
        d = ex.design
        c = theorem2_constants(d, ex.K1, ex.K2, 0.1, estimate="xi2")
        print(f"  k = {k:5.0f}: cond(S) = {d.cond_S:.3g}, R = {d.R.ravel().round(3)}, "
              f"psi2 growth = {d.psi2_growth:+.1f}/s, mu = {c.mu:.3g}, T_bar mu = {c.T_bar_mu:.3g}"
              f" (40 {'holds' if c.holds else 'fails'}), T_bar max = {c.T_bar_max:.3g}")

    runs = {}
    for k in (100.0, 75.0, 150.0):
        runs["c", k] = _run_dc(k, sampled=False, t_max=t_max)
        runs["s", k] = _run_dc(k, sampled=True, T=0.1, estimate="xi2", t_max=t_max)
        for kind, name in (("c", "Theorem 1"), ("s", "Theorem 2")):
            t, e, arc = runs[kind, k]
            print(f"  k = {k:5.0f}, {name}: |error| at t = 0.15, 0.5, 1: "
                  f"{_err_at(t, e, 0.15):.3g}, {_err_at(t, e, 0.5):.3g}, {_err_at(t, e, 1.0):.3g}"
                  f" ({arc.termination.name} at t = {arc.tf:.3g}; later times read the last sample)")

    # Fig. 1
    fig, axs = plt.subplots(1, 2, figsize=(10, 3.8), sharey=False)
    for ax, kind, title in zip(axs, ("c", "s"), ("Theorem 1 (continuous Y)",
                                                 "Theorem 2 (samples every 0.1)")):
        t, e, _ = runs[kind, 100.0]
        ax.plot(t, e[:, 0], "r", label=r"$\xi_{1,1}-\xi_{e,1}$")
        ax.plot(t, e[:, 1], "b", label=r"$\xi_{1,2}-\xi_{e,2}$")
        ax.axvline(0.1, color="0.6", lw=0.8, ls=":")
        ax.set(title=title + ", k = 100", xlabel="t", ylim=(-3, 3))
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    paths.append(_write(fig, outdir, "gramian_delay_fig1", f"""
Fig. 1 (Mazenc & Malisoff 2022): observer error components for (66), k = 100, first
component (xi_{{1,1}}, red) and second (xi_{{1,2}}, blue). Left: Theorem 1, the observer (7)
with continuous measurement Y and the estimate (13) evaluated with Y(t) (implementable;
under delta_2 it differs from the printed (13) by R delta_2(t)). Right: Theorem 2, the
observer (39) with omega reset to Y(t_k) every 0.1 s and xi_e of (13) with xi_2(t) as
printed (the implementable omega version diverges at this period, see fig. 3). The dotted
line is t = tau = 0.1; before it the estimate uses the window [0, t] (our history rule).
{_CHOICES} Axis range [-3, 3] cuts the initial transient (before tau).
"""))
    plt.close(fig)

    # Fig. 2
    stops = ", ".join(f"{name} stopped at t = {runs[kind, 75.0][2].tf:.2f}"
                      for kind, name in (("c", "Theorem 1"), ("s", "Theorem 2"))
                      if runs[kind, 75.0][2].termination is hs.Termination.BLOWUP)
    fig, axs = plt.subplots(1, 2, figsize=(10, 3.8))
    for ax, kind, title in zip(axs, ("c", "s"), ("Theorem 1", "Theorem 2 (T = 0.1)")):
        for k, ls in ((75.0, "-"), (150.0, "--")):
            t, e, _ = runs[kind, k]
            ax.plot(t, e[:, 0], "r" + ls, lw=1, label=rf"$\xi_{{1,1}}$, k = {k:.0f}")
            ax.plot(t, e[:, 1], "b" + ls, lw=1, label=rf"$\xi_{{1,2}}$, k = {k:.0f}")
        ax.axvline(0.1, color="0.6", lw=0.8, ls=":")
        ax.set(title=title + ": k = 75 (solid), 150 (dashed)", xlabel="t", ylim=(-3, 3))
        ax.legend(loc="upper right", fontsize=7)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    paths.append(_write(fig, outdir, "gramian_delay_fig2", f"""
Fig. 2 (Mazenc & Malisoff 2022): as Fig. 1 with k = 75 (solid) and k = 150 (dashed).
With k = 75, -(A1^T + 2kI) has the eigenvalue +47.2: psi_2 of (7) grows like e^(47 t) and
(13) subtracts two growing terms; exact in exact arithmetic, the floating-point estimate is
lost after about 0.8 s (the paper does not mention this; it needs k > 98.6 here). Runs
stop when the interconnection's state exceeds 1e6 in norm (k = 75: {stops or "none"}).
{_CHOICES}
"""))
    plt.close(fig)

    # Fig. 3 (ours): omega vs xi2 in (13) as the sampling period grows, no disturbances
    periods = [0.005, 0.01, 0.015, 0.02, 0.05, 0.1]
    final = {"omega": [], "xi2": []}
    for est in final:
        for T in periods:
            t, e, arc = _run_dc(100.0, sampled=True, T=T, estimate=est, t_max=1.0,
                                disturbed=False, max_norm=1e3)
            ok = arc.termination is hs.Termination.T_MAX
            final[est].append(float(np.linalg.norm(e[t >= 0.8], axis=1).max()) if ok else np.inf)
    # largest period (on a finer grid) for which the omega version converges
    conv = [T for T, v in zip(periods, final["omega"]) if v < 1e-3]
    lo, hi = max(conv), min(T for T in periods if T > max(conv))
    for _ in range(4):
        mid = 0.5 * (lo + hi)
        t, e, arc = _run_dc(100.0, sampled=True, T=mid, estimate="omega", t_max=1.0,
                            disturbed=False, max_norm=1e3)
        good = arc.termination is hs.Termination.T_MAX and \
            np.linalg.norm(e[t >= 0.8], axis=1).max() < 1e-3
        lo, hi = (mid, hi) if good else (lo, mid)
    print(f"  sampled observer, k = 100, no disturbances: max |error| on [0.8, 1] per period "
          f"{periods}:")
    for est in final:
        print(f"    {est:5s}: " + ", ".join(f"{v:.2g}" for v in final[est]))
    print(f"  largest period with convergence (omega in (13)): between {lo:.4f} and {hi:.4f}"
          f" (Theorem 2 guarantees it only below {theorem2_constants(dc_motor(100.0).design, DC_PARAMS['a1'], 100.0, 0.1).T_bar_max:.2g})")
    fig, ax = plt.subplots(figsize=(6, 4))
    for est, mk in (("omega", "o-"), ("xi2", "s--")):
        v = np.array(final[est])
        ax.semilogy(periods, np.where(np.isfinite(v), np.maximum(v, 1e-16), 1e4), mk,
                    label={"omega": r"$\omega(t)$ in (13) (implementable)",
                           "xi2": r"$\xi_2(t)$ in (13) (as printed)"}[est])
    ax.axvspan(hi, max(periods), color="0.9")
    ax.set(xlabel="sampling period T", ylabel=r"max $|\xi_1-\xi_e|$ on [0.8, 1]",
           title="Observer (39), DC motor, k = 100, tau = 0.1")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    paths.append(_write(fig, outdir, "gramian_delay_periods", f"""
Ours (not in the paper): the sampled-measurement observer (39) on (66) without disturbances,
k = 100, tau = 0.1, periodic sampling with period T, error sup over t in [0.8, 1] (1e4 marks a
run stopped by blow-up, 1e-16 an error below double precision). omega(t) in (13) (what one
can implement) converges only for T up to about {lo:.4f}-{hi:.4f} (bisection; shaded: diverges);
the printed (13), with the unmeasured xi_2(t), converges at every period tried, including the
paper's 0.1. Theorem 2's sufficient condition (40) asks T < 1/mu ~ 2.5e-21.
u(t) = 2 sin(2t), chi(0) = (0.5, -1, 0.2): our choices.
"""))
    plt.close(fig)
    return paths
