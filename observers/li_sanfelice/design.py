"""The design computations of Li & Sanfelice, and their bounds (numpy/scipy only).

Everything here is pure linear algebra on the paper's data (A, H, L1, L2,
delta); nothing simulates. Find an equation by its number:

=====================================  ==========================================
Section II-A (matrix measures)         :func:`mu_max`, :func:`mu_min`,
                                       :func:`alpha_max`, :func:`alpha_min`
Assumption 4.1 (A1): F_i = A - L_i H   :func:`F_matrices`
(3), (12): K1, K2                      :func:`gains_K`, :class:`Design`
Assumption 4.1 (A2), Remark 4.4        :func:`p_det`, :func:`admissible_delta`
Lemma 4.2                              :func:`lemma_4_2_condition`
footnote 7, (17): L_tilde, Xi          :func:`L_tilde`, :func:`Xi_matrix`, :func:`Xi_of_t`
(18), Theorem 4.13: H T - I            :class:`Design` (``T``, ``HT_minus_I``)
(6): scalar error after the jump       :func:`scalar_error_after_jump`
(15): error after the jump of H_n      :func:`error_after_jump`
(13): |z|_A                            :func:`dist_to_A`
Theorem 4.7                            :func:`theorem_4_7_bound`
Theorem 4.10                           :func:`theorem_4_10_bound`
Theorem 4.11, (16)                     :func:`theorem_4_11_bound`
Theorem 4.14: the noise m(t)           :class:`PiecewiseConstantNoise`, :func:`switch_jump_error`
=====================================  ==========================================

plus :func:`random_design` (seeded test designs). Inputs are checked with
:mod:`observers._common`; the decisions cited ("decision 5") are listed in
:data:`observers.li_sanfelice.DECISIONS`.

Examples
--------
>>> from observers.li_sanfelice.design import Design
>>> d = Design(A=[[-0.05]], H=[[1.0]], L1=[[0.1]], L2=[[0.2]], delta=1.0)   # Section V.A
>>> round(float(d.K2[0, 0]), 4)          # (12): 1 / (1 - e^{-0.1})
10.5083
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np
import scipy.integrate
import scipy.linalg
import scipy.optimize
import scipy.signal
from scipy.linalg import expm

from observers._common import matrix, scalar, unobservable_mode, vector

__all__ = [
    "Design",
    "F_matrices",
    "gains_K",
    "p_det",
    "admissible_delta",
    "lemma_4_2_condition",
    "mu_max",
    "mu_min",
    "alpha_max",
    "alpha_min",
    "Xi_of_t",
    "L_tilde",
    "Xi_matrix",
    "error_after_jump",
    "scalar_error_after_jump",
    "switch_jump_error",
    "theorem_4_7_bound",
    "theorem_4_10_bound",
    "theorem_4_11_bound",
    "dist_to_A",
    "PiecewiseConstantNoise",
    "random_design",
]

# A matrix whose condition number exceeds this is treated as singular (decision 10).
_SINGULAR_COND = 1e12
# H_c / H_pc warn when |(H T - I)^{-1}| exceeds this (decision 10).
_WARN_HT_INV = 1e6


def _check_plant(A, H):
    """(A, H) of plant (1): A square n x n, H p x n."""
    A = matrix("A", A, square=True, what=" (n x n)")
    n = A.shape[0]
    if n == 0:
        raise ValueError(f"A must be a non-empty n x n matrix (a state of n >= 1), got shape "
                         f"{A.shape}")
    H = matrix("H", H, (None, n), what=" (p x n)")
    if H.shape[0] == 0:
        raise ValueError(f"H must have at least one row (p >= 1 measured outputs), got shape "
                         f"{H.shape}")
    return A, H


def _check_distinct_gains(L1, L2, where):
    """L1 == L2 makes the two copies one observer: F1 = F2, so I - e^{F2 t} e^{-F1 t}
    vanishes for every t and no delta and no K2 exist (refused by name)."""
    if np.array_equal(L1, L2):
        raise ValueError(f"{where}: L1 == L2, so the two copies are one observer (F1 = F2) and "
                         f"I - exp(F2 t) exp(-F1 t) = 0 for every t: no delta and no reset "
                         f"gain K2 exist whatever delta is. Choose L1 != L2 with different "
                         f"spectra of F_i = A - L_i H (Lemma 4.2)")


def _check_plant_gains(A, H, L1, L2):
    """(A, H) of plant (1) and the gains L1, L2 (n x p) of (10)-(11)."""
    A, H = _check_plant(A, H)
    n, p = A.shape[0], H.shape[0]
    L1 = matrix("L1", L1, (n, p), what=" (n x p)")
    L2 = matrix("L2", L2, (n, p), what=" (n x p)")
    return A, H, L1, L2


# ---------------------------------------------------------------------------
# matrix measures (Section II-A)
# ---------------------------------------------------------------------------
def mu_max(F):
    """mu_bar(F) = max eig((F + F^T)/2), the logarithmic 2-norm (Section II-A)."""
    F = np.asarray(F, dtype=float)
    return float(np.max(np.linalg.eigvalsh((F + F.T) / 2)))


def mu_min(F):
    """mu_(F) = min eig((F + F^T)/2) (Section II-A)."""
    F = np.asarray(F, dtype=float)
    return float(np.min(np.linalg.eigvalsh((F + F.T) / 2)))


def alpha_max(F):
    """alpha_bar(F) = max Re eig(F) (Section II-A)."""
    return float(np.max(np.linalg.eigvals(np.asarray(F, dtype=float)).real))


def alpha_min(F):
    """alpha_(F) = min Re eig(F) (Section II-A)."""
    return float(np.min(np.linalg.eigvals(np.asarray(F, dtype=float)).real))


# ---------------------------------------------------------------------------
# design computations
# ---------------------------------------------------------------------------
def F_matrices(A, H, L1, L2, *, require_hurwitz=True):
    """F_i = A - L_i H, i = 1, 2 (Assumption 4.1, A1).

    Parameters
    ----------
    A : (n, n) array_like
    H : (p, n) array_like
    L1, L2 : (n, p) array_like
    require_hurwitz : bool
        Raise ValueError naming L1/L2 when F_i is not Hurwitz.

    Returns
    -------
    F1, F2 : (n, n) ndarray

    References
    ----------
    Li & Sanfelice, Assumption 4.1 (A1) and the definitions after (12).
    """
    A, H, L1, L2 = _check_plant_gains(A, H, L1, L2)
    F1, F2 = A - L1 @ H, A - L2 @ H
    if require_hurwitz:
        for name, F in (("L1", F1), ("L2", F2)):
            a = alpha_max(F)
            if a >= 0:
                raise ValueError(
                    f"F{name[1]} = A - {name} H is not Hurwitz (max Re eig = {a:.3g} >= 0); "
                    f"choose {name} so that A - {name} H is Hurwitz (Assumption 4.1, A1)"
                )
    return F1, F2


def _K_from_F(F1, F2, delta):
    n = F1.shape[0]
    E = expm(F2 * delta) @ expm(-F1 * delta)
    M = np.eye(n) - E
    # singular when sigma_min(I - E) <= 1e-12 max(1, |E|) (a scale-free condition number would miss
    # I - E ~ 0)
    smin = np.linalg.svd(M, compute_uv=False)[-1]
    if not np.all(np.isfinite(M)) or smin <= max(1.0, np.linalg.norm(E, 2)) / _SINGULAR_COND:
        raise ValueError(
            f"delta={delta:g}: I - exp(F2 delta) exp(-F1 delta) is singular "
            f"(smallest singular value {smin:.3g}), "
            "so K2 is undefined; choose delta below the first positive zero of "
            "det(I - exp(F2 t) exp(-F1 t)) (see admissible_delta, Remark 4.4)"
        )
    K2 = np.linalg.inv(M)
    K1 = np.eye(n) - K2
    return K1, K2


def gains_K(A, H, L1, L2, delta):
    """Reset gains K1, K2 of (12): K2 = (I - e^{F2 delta} e^{-F1 delta})^{-1}, K1 = I - K2.

    They make K1 e^{F1 delta} + K2 e^{F2 delta} = 0 and K1 + K2 = I, so the
    reset K1 x̂1 + K2 x̂2 cancels equal initial errors and passes x.

    Raises
    ------
    ValueError
        When F_i is not Hurwitz (naming L_i) or I - e^{F2 delta} e^{-F1 delta}
        is singular at ``delta`` (K2 undefined).

    References
    ----------
    Li & Sanfelice, eq. (3), (12), Assumption 4.1.
    """
    delta = scalar("delta", delta, positive=True)
    F1, F2 = F_matrices(A, H, L1, L2)
    return _K_from_F(F1, F2, delta)


def p_det(F1, F2, t):
    """p(t) = det(I - exp(F2 t) exp(-F1 t)) of Remark 4.4, for scalar or array t."""
    F1 = np.asarray(F1, dtype=float)
    F2 = np.asarray(F2, dtype=float)
    ts = np.atleast_1d(np.asarray(t, dtype=float))
    n = F1.shape[0]
    out = np.array([np.linalg.det(np.eye(n) - expm(F2 * s) @ expm(-F1 * s)) for s in ts])
    return out if np.ndim(t) else float(out[0])


def _smin(F1, F2, s):
    """Smallest singular value of I - e^{F2 s} e^{-F1 s},
    relative to max(1, |e^{F2 s} e^{-F1 s}|)."""
    n = F1.shape[0]
    M = expm(F2 * s) @ expm(-F1 * s)
    return np.linalg.svd(np.eye(n) - M, compute_uv=False)[-1] / max(1.0, np.linalg.norm(M, 2))


def _golden_min(fun, a, b, iters=90):
    """Golden-section minimum of a unimodal (possibly kinked) function on [a, b],
    to ~machine precision."""
    g = (math.sqrt(5) - 1) / 2
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = fun(c), fun(d)
    for _ in range(iters):
        if b - a <= 4 * np.finfo(float).eps * max(1.0, abs(a)):
            break
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = fun(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = fun(d)
    return (c, fc) if fc <= fd else (d, fd)


def _hidden_unstable_mode(A, H, rtol=1e-9):
    """An eigenvalue of A with Re >= 0 invisible through H (PBH test), or None: (A, H) detectable.

    The Luenberger observer (2) needs detectability only, which the shared
    :func:`observers._common.unobservable_mode` (every eigenvalue) does not
    decide; the threshold is the same: the smallest singular value of
    [A - lambda I; H] at most ``rtol * max(1, |A|, |H|)`` (2-norms).
    """
    n = A.shape[0]
    scale = max(1.0, np.linalg.norm(A, 2), np.linalg.norm(H, 2) if H.size else 0.0)
    for lam in np.linalg.eigvals(A):
        if lam.real < 0:
            continue
        s = np.linalg.svd(np.vstack([A - lam * np.eye(n), H.astype(complex)]), compute_uv=False)[-1]
        if s <= rtol * scale:
            return _real_if_close(lam, rtol * scale)
    return None


def _real_if_close(lam, atol):
    lam = complex(lam)
    return lam.real if abs(lam.imag) <= atol else lam


def _check_observable(A, H, what="the Li-Sanfelice observers"):
    """Raise ValueError when (A, H) is unobservable, saying why no delta can work."""
    lam = unobservable_mode(A, H)
    if lam is not None:
        lam = _real_if_close(lam, 1e-9 * max(1.0, np.linalg.norm(A, 2), np.linalg.norm(H, 2)))
        lam_s = f"{lam:.6g}" if isinstance(lam, float) else f"{lam.real:.6g}{lam.imag:+.6g}j"
        raise ValueError(
            f"(A, H) is not observable: the eigenvalue {lam_s} of A is invisible in y = H x (PBH "
            f"test: rank [A - lambda I; H] < n = {A.shape[0]}). Both copies F_i = A - L_i H keep "
            "this mode, so I - exp(F2 t) exp(-F1 t) is singular for every t > 0: no delta and no "
            f"reset gain K2 exist for {what} (Assumption 4.1, A2; Remark 4.3 needs (A, H) "
            "observable)"
        )


def _X_block(F1, F2):
    """The 2n x 2n matrix [[F1, F1 - F2], [0, F2]]:
    expm of it times t has X(t) = e^{F1 t} - e^{F2 t} top right."""
    n = F1.shape[0]
    B = np.zeros((2 * n, 2 * n))
    B[:n, :n], B[:n, n:], B[n:, n:] = F1, F1 - F2, F2
    return B


def _scan_p(F1, F2, ts):
    """sign(p(t_k)) and the relative smallest singular value s_X(t_k) on a uniform grid.

    p(t) = det(I - e^{F2 t} e^{-F1 t}) = det(X(t)) e^{-tr(F1) t} with
    X(t) = e^{F1 t} - e^{F2 t}, the upper-right block of
    G(t) = expm([[F1, F1 - F2], [0, F2]] t) (since X' = F1 X + (F1 - F2) e^{F2 t}).
    X involves only the decaying exponentials of the Hurwitz F_i: no
    e^{-F1 t} (which grows like e^{|alpha(F1)| t} and ruins
    e^{F2 t} e^{-F1 t} in double precision for large t) and no cancellation
    of I - (I + O(t)) near t = 0. s_X = sigma_min(X) / |G(t)|_F is the size of
    X's smallest singular value against the rounding level of its entries.
    The grid values G(t_k) are powers of one expm, formed by repeated doubling
    in batched products; determinants and singular values in one batched call.

    Returns
    -------
    detX : (num,) ndarray
        det(X(t_k)), of the sign of p(t_k).
    s : (num,) ndarray
        s_X(t_k).
    """
    n = F1.shape[0]
    num = ts.size
    G = np.empty((num, 2 * n, 2 * n))
    G[0] = expm(_X_block(F1, F2) * ts[0])
    m = 1
    while m < num:
        k = min(m, num - m)
        # G_{m+i} = G_i G_m (powers of one matrix commute)
        G[m:m + k] = G[:k] @ G[m - 1]
        m += k
    X = G[:, :n, n:]
    detX = np.linalg.det(X)
    smin = np.linalg.svd(X, compute_uv=False)[:, -1]
    return detX, smin / np.linalg.norm(G, axis=(1, 2))


def _X_at(F1, F2, t):
    n = F1.shape[0]
    G = expm(_X_block(F1, F2) * t)
    return G[:n, n:], G


def _det_X(F1, F2, t):
    """det(e^{F1 t} - e^{F2 t}): the sign of p(t),
    computed without cancellation or growing exponentials."""
    return float(np.linalg.det(_X_at(F1, F2, t)[0]))


def _s_X(F1, F2, t):
    """sigma_min(e^{F1 t} - e^{F2 t}) / |expm([[F1, F1 - F2], [0, F2]] t)|_F
    (see :func:`_scan_p`)."""
    X, G = _X_at(F1, F2, t)
    return float(np.linalg.svd(X, compute_uv=False)[-1] / np.linalg.norm(G))


def admissible_delta(A, H, L1, L2, *, t_max=20.0, num=2000, tol=1e-8):
    """First positive zero of p(t) = det(I - e^{F2 t} e^{-F1 t}) (Remark 4.4).

    Every delta in (0, t*) satisfies A2 of Assumption 4.1 when ``t*`` is
    returned; ``None`` means p has no zero in (0, t_max] (every delta up to
    t_max is admissible). p(0) = 0 always (delta > 0 is required), so t = 0 is
    excluded.

    Algorithm. p(t) = det(X(t)) e^{-tr(F1) t} with X(t) = e^{F1 t} - e^{F2 t}
    (I - e^{F2 t} e^{-F1 t} = X(t) e^{-F1 t}), so p and det X have the same
    zeros and signs; X is computed as a block of one matrix exponential of
    decaying modes only (no growing e^{-F1 t}, no cancellation near t = 0; see
    :func:`_scan_p`). On a grid of ``num`` points in (0, t_max], one batched
    pass gives det X and s(t) = sigma_min(X) / |expm([[F1, F1 - F2], [0, F2]] t)|,
    the smallest singular value against the rounding level of X's entries.
    The sign of p is trusted where s > 1e-12 (rounding perturbs det X by about
    n eps / s times itself).

    * The first sign change of p between adjacent trusted grid points is
      refined with brentq on det X (to 1e-14 in t).
    * Zeros where p touches 0 without changing sign (e.g. a complex pair of
      eigenvalues of e^{F2 t} e^{-F1 t} passing through 1) are dips of s to 0:
      a grid point no higher than its neighbours, with a neighbour higher by
      more than the rounding level (1e-12), whose minimum over the two adjacent
      grid cells can reach below ``tol`` (s_k - 2 (max neighbour - s_k) < tol)
      and that is deep enough to hide a zero (s_k <= max neighbour / 2: a zero
      between grid points leaves at most 1/3 for a V-shaped, 1/9 for a
      quadratic dip) is refined by golden-section search; it counts when the
      minimum is below ``tol`` and below 1e-3 times the higher neighbour (a
      zero of s, not a shallow wiggle of an s that is small throughout, as for
      single-output designs of large n where s stays near 1e-9 for long).
      Plateaus of s flat to rounding (hundreds of spurious local minima of
      rounding noise) are skipped without refinement, so a flat curve costs one
      grid pass (about 10 ms for n = 2, num = 2000).

    Where s is at rounding level over a stretch of grid points (near t = 0 when
    p < n: det X(t) ~ c t^N with N up to n^2, so X is singular to working
    precision for small t, and :class:`Design` rejects such delta as
    numerically singular) the sign of p cannot be resolved: a zero inside such
    a stretch is not reported, and a sign change across one (trusted points
    of opposite signs with untrusted points between them) is reported at the
    first untrusted point after the last trusted one (every smaller delta is
    then known to be admissible), as is a stretch of untrusted points at the
    end of the grid where the sign of det X differs from the last trusted one.
    A stretch at the start (before the first trusted point) is skipped: p(t)
    has the sign of its leading term c t^N there. When no grid point is
    trusted, ValueError says so.

    Parameters
    ----------
    A : (n, n) array_like
    H : (p, n) array_like
        (A, H) must be observable (otherwise p vanishes identically).
    L1, L2 : (n, p) array_like
        Gains; F_i = A - L_i H must be Hurwitz.
    t_max : float
        Search horizon.
    num : int
        Grid points (>= 3).
    tol : float
        Threshold on the relative smallest singular value for a touching zero.

    Returns
    -------
    float or None

    Raises
    ------
    ValueError
        Bad shapes, F_i not Hurwitz, (A, H) unobservable (naming the
        invisible eigenvalue: no delta exists then), or
        I - e^{F2 t} e^{-F1 t} numerically singular on the whole grid.

    References
    ----------
    Li & Sanfelice, Assumption 4.1 (A2), Remark 4.4.
    """
    t_max = scalar("t_max", t_max, positive=True)
    if isinstance(num, bool) or not isinstance(num, numbers.Integral) or num < 3:
        raise ValueError(f"num must be an integer >= 3, got {num!r}")
    tol = scalar("tol", tol, positive=True)
    A, H, L1, L2 = _check_plant_gains(A, H, L1, L2)
    _check_observable(A, H, "admissible_delta")
    _check_distinct_gains(L1, L2, "admissible_delta")
    F1, F2 = F_matrices(A, H, L1, L2)
    ts = np.linspace(t_max / num, t_max, num)
    p, s = _scan_p(F1, F2, ts)
    floor = 1.0 / _SINGULAR_COND
    # 1. first sign change of p between trusted grid points
    first = math.inf
    good = np.flatnonzero(s > floor)
    if good.size == 0:
        raise ValueError(
            f"I - exp(F2 t) exp(-F1 t) is numerically singular on all of (0, t_max={t_max:g}] "
            f"(smallest singular value of e^(F1 t) - e^(F2 t) at most {floor:g} relative to its "
            "scale at every grid point): the sign of p(t) cannot be resolved, so its zeros cannot "
            "be located, and no delta up to t_max gives a well-conditioned reset gain K2; F1 and "
            "F2 are too close (choose L1, L2 further apart) or t_max is too small"
        )
    if good[-1] < num - 1 and np.any(np.sign(p[good[-1] + 1:]) != np.sign(p[good[-1]])):
        first = float(ts[good[-1] + 1])     # p may change sign in an unresolved stretch at the end
    if good.size >= 2:
        sg = np.sign(p[good])
        ch = np.flatnonzero(sg[:-1] * sg[1:] < 0)
        if ch.size:
            ka, kb = good[ch[0]], good[ch[0] + 1]
            if kb > ka + 1:         # untrusted points in between: stop at the first of them
                first = min(first, float(ts[ka + 1]))
            else:
                fa, fb = _det_X(F1, F2, ts[ka]), _det_X(F1, F2, ts[kb])
                if fa * fb < 0:
                    first = min(first, scipy.optimize.brentq(lambda u: _det_X(F1, F2, u),
                                                             ts[ka], ts[kb], xtol=1e-14,
                                                             rtol=4 * np.finfo(float).eps))
                else:               # the accurate evaluation disagrees with the scan: p is ~0 there
                    first = min(first, float(ts[ka] if fa == 0 else ts[kb]))
    # 2. touching zeros: genuine dips of s (rounding-level plateaus skipped)
    sl, sc, sr = s[:-2], s[1:-1], s[2:]
    depth = np.maximum(sl, sr) - sc
    # a zero of s between grid points leaves s_k <= max(neighbours) / 3 (V-shaped) or / 9
    # (quadratic)
    dips = np.flatnonzero((sc <= sl) & (sc <= sr) & (depth > floor) & (sc - 2 * depth < tol)
                          & (sc <= 0.5 * np.maximum(sl, sr))) + 1
    for k in dips:
        if ts[k - 1] >= first:
            break
        tk, sk = _golden_min(lambda u: _s_X(F1, F2, u), ts[k - 1], ts[k + 1])
        if sk < tol and sk <= 1e-3 * max(s[k - 1], s[k + 1]):
            first = min(first, float(tk))
            break
    return None if math.isinf(first) else float(first)


def lemma_4_2_condition(A, H, L1, L2):
    """Lemma 4.2's sufficient condition: alpha_bar(F2) < alpha_(F1) and alpha_bar(F1) < 0.

    Returns
    -------
    bool

    References
    ----------
    Li & Sanfelice, Lemma 4.2, Remark 4.3.
    """
    F1, F2 = F_matrices(A, H, L1, L2, require_hurwitz=False)
    return bool(alpha_max(F2) < alpha_min(F1) and alpha_max(F1) < 0)


def Xi_of_t(F, L, t):
    """Xi(t) = int_0^t exp(F (t - s)) ds L, the n x p matrix reached by the xi flow.

    Computed from the block exponential expm([[F, L], [0, 0]] t). Its k-th
    column is the k-th piece of xi_i(t) (footnote 7), the solution of
    d/dt xi = diag_p(F) xi + L_tilde, xi(0) = 0 (17).
    """
    F = np.asarray(F, dtype=float)
    L = np.asarray(L, dtype=float)
    n, p = L.shape
    M = np.zeros((n + p, n + p))
    M[:n, :n] = F
    M[:n, n:] = L
    return expm(M * t)[:n, n:]


def L_tilde(L):
    """L_tilde = sum_k I_k^T L v_k = vec(L), the columns of L stacked (footnote 7, (17))."""
    L = np.asarray(L, dtype=float)
    return L.reshape(-1, order="F")


def Xi_matrix(xi, n, p):
    """sum_k I_k xi v_k^T: the k-th piece of xi in R^{np} as k-th column of an n x p matrix
    (footnote 7); xi of shape (..., np) gives (..., n, p)."""
    xi = np.asarray(xi, dtype=float)
    if xi.shape[-1] != n * p:
        raise ValueError(f"xi must have last dimension n*p = {n * p}, got {xi.shape}")
    return xi.reshape(xi.shape[:-1] + (p, n)).swapaxes(-1, -2)


@dataclass(frozen=True, eq=False)
class Design:
    """A validated design (A, H, L1, L2, delta, a1, a2) of the Li-Sanfelice observers.

    Attributes computed at construction: ``F1``, ``F2`` (Assumption 4.1),
    ``K1``, ``K2`` (12), ``Xi1``, ``Xi2`` (= Xi_i(delta), footnote 7),
    ``T = K1 Xi1 + K2 Xi2`` (n x p), ``HT_minus_I = H T - I`` (p x p,
    Theorem 4.13's matrix) and its condition number ``HT_cond`` (m̂'s update
    multiplies errors by (H T - I)^{-1}, of 2-norm ``HT_inv_norm``: when
    either is large the noise estimate is sensitive to integration error; for
    p = 1 the condition number is always 1 and ``HT_inv_norm`` = 1/|H T - 1|
    is the number to watch).

    Parameters
    ----------
    A : (n, n) array_like
    H : (p, n) array_like
    L1, L2 : (n, p) array_like
        Gains; F_i = A - L_i H must be Hurwitz.
    delta : float
        Jump period; I - e^{F2 delta} e^{-F1 delta} must be invertible.
    a1 : float
        Weight of x̂1 in the estimate x̄ = a1 x̂1 + a2 x̂2 (footnote 2).
    a2 : float or None
        Defaults to 1 - a1; a1 + a2 = 1 is required.

    Raises
    ------
    ValueError
        Shapes that do not match (A square n x n, H p x n, L_i n x p, each
        named); (A, H) unobservable (the invisible eigenvalue is named: both
        copies keep that mode, so no delta and no K2 exist); F_i not Hurwitz;
        delta too small (I - e^{F2 t} e^{-F1 t} singular to working precision
        on all of (0, delta]) or on a zero of p(t).

    References
    ----------
    Li & Sanfelice, (10)-(12), (17)-(18), footnotes 2 and 7, Assumption 4.1.
    """

    A: np.ndarray
    H: np.ndarray
    L1: np.ndarray
    L2: np.ndarray
    delta: float
    a1: float = 0.5
    a2: float | None = None

    def __post_init__(self):
        A, H, L1, L2 = _check_plant_gains(self.A, self.H, self.L1, self.L2)
        delta = scalar("delta", self.delta, positive=True)
        a1 = scalar("a1", self.a1)
        a2 = 1.0 - a1 if self.a2 is None else scalar("a2", self.a2)
        if not math.isclose(a1 + a2, 1.0, rel_tol=0, abs_tol=1e-12):
            raise ValueError(f"a1 + a2 must equal 1 (footnote 2), got a1 + a2 = {a1 + a2:g}")
        _check_observable(A, H, "Design")
        _check_distinct_gains(L1, L2, "Design")
        F1, F2 = F_matrices(A, H, L1, L2)
        try:
            K1, K2 = _K_from_F(F1, F2, delta)
        except ValueError as exc:
            # the true reason: delta inside the stretch near t = 0 where X(t) = e^{F1 t} - e^{F2 t}
            # is singular to working precision (det X ~ c t^N, N up to n^2 for p < n),
            # or a zero of p(t)
            sm = [_s_X(F1, F2, u) for u in np.linspace(delta / 16, delta, 16)]
            if max(sm) <= 1.0 / _SINGULAR_COND:
                raise ValueError(
                    f"delta={delta:g} is too small: I - exp(F2 t) exp(-F1 t) is singular to "
                    "working precision on all of (0, delta] (p(t) = det(...) vanishes to high "
                    f"order at t = 0 when p < n, here p = {H.shape[0]}, n = {A.shape[0]}), so K2 "
                    "is numerically undefined; choose a larger delta (see admissible_delta, "
                    "Remark 4.4)") from exc
            raise
        Xi1, Xi2 = Xi_of_t(F1, L1, delta), Xi_of_t(F2, L2, delta)
        T = K1 @ Xi1 + K2 @ Xi2
        HTI = H @ T - np.eye(H.shape[0])
        sv = np.linalg.svd(HTI, compute_uv=False)
        inv_norm = float(1.0 / sv[-1]) if sv[-1] > 0 else math.inf
        for k, v in dict(A=A, H=H, L1=L1, L2=L2, delta=delta, a1=a1, a2=a2, F1=F1, F2=F2, K1=K1,
                         K2=K2, Xi1=Xi1, Xi2=Xi2, T=T, HT_minus_I=HTI,
                         HT_cond=float(np.linalg.cond(HTI)),
                         HT_inv_norm=inv_norm).items():
            object.__setattr__(self, k, v)

    @property
    def n(self):
        """State dimension."""
        return self.A.shape[0]

    @property
    def p(self):
        """Output dimension."""
        return self.H.shape[0]

    def check_HT_invertible(self):
        """Raise ValueError when H T - I is singular (Theorem 4.13's condition).

        Singular means smallest singular value <= 1e-12 max(1, |H T|).
        Returns ``(HT_cond, HT_inv_norm)``.
        """
        scale = max(1.0, np.linalg.norm(self.H @ self.T, 2))
        if not np.isfinite(self.HT_inv_norm) or 1.0 / self.HT_inv_norm <= scale / _SINGULAR_COND:
            raise ValueError(
                f"H T - I is singular (smallest singular value {1 / self.HT_inv_norm:.3g}, "
                f"condition number {self.HT_cond:.3g}) for delta={self.delta:g}: "
                "the noise estimate m̂ of (18) is undefined (Theorem 4.13); change L1, L2 or delta"
            )
        return self.HT_cond, self.HT_inv_norm


# ---------------------------------------------------------------------------
# errors after the jump and bounds
# ---------------------------------------------------------------------------
def error_after_jump(design, m):
    """Error e1(delta, 1) = e2(delta, 1) of H_n under noise m, formula (15)::

        e(delta, 1) = K1 int_0^delta e^{F1 (delta - s)} L1 m(s) ds
                    + K2 int_0^delta e^{F2 (delta - s)} L2 m(s) ds,

    for any initial condition with x̂1(0,0) = x̂2(0,0) (the initial error
    cancels since K1 e^{F1 delta} + K2 e^{F2 delta} = 0).

    Parameters
    ----------
    design : Design
    m : (p,) array_like or callable
        Constant noise (then e = T m exactly, T = K1 Xi1 + K2 Xi2) or a
        callable s -> (p,) integrated with scipy's quad_vec.

    Returns
    -------
    (n,) ndarray

    References
    ----------
    Li & Sanfelice, eq. (15).
    """
    if not isinstance(design, Design):
        raise TypeError(f"design must be a Design, got {type(design).__name__}")
    d = design
    if callable(m):
        def integrand(s):
            ms = vector("m(s)", m(s), d.p)
            return (d.K1 @ expm(d.F1 * (d.delta - s)) @ d.L1
                    + d.K2 @ expm(d.F2 * (d.delta - s)) @ d.L2) @ ms
        # split the integral at the switches of a piecewise-constant noise inside (0, delta)
        pts = None
        if isinstance(m, PiecewiseConstantNoise):
            pts = [float(s) for s in m.d if 0.0 < s < d.delta] or None
        val, _ = scipy.integrate.quad_vec(integrand, 0.0, d.delta, epsabs=1e-13, epsrel=1e-11,
                                          points=pts)
        return np.asarray(val)
    return d.T @ vector("m", m, d.p)


def scalar_error_after_jump(a, L1, L2, delta, m):
    """Closed-form error after the jump of (3) for the scalar plant (5), formula (6).

    e1^+(delta) = m / (e^{ã2 delta} - e^{ã1 delta}) *
        [ L1/ã1 (e^{ã1 delta} e^{ã2 delta} - e^{ã2 delta})
        - L2/ã2 (e^{ã1 delta} e^{ã2 delta} - e^{ã1 delta}) ],  ã_i = a - L_i.

    Vectorised over ``delta`` and ``m``. Requires ã_i != 0 and ã1 != ã2.

    References
    ----------
    Li & Sanfelice, eq. (5)-(6).
    """
    a, L1, L2 = scalar("a", a), scalar("L1", L1), scalar("L2", L2)
    a1t, a2t = a - L1, a - L2
    if a1t == 0 or a2t == 0 or a1t == a2t:
        raise ValueError(f"formula (6) needs a - L1, a - L2 nonzero and distinct, "
                         f"got {a1t:g}, {a2t:g}")
    delta = np.asarray(delta, dtype=float)
    if np.any(delta <= 0):
        raise ValueError("delta must be positive")
    E1, E2 = np.exp(a1t * delta), np.exp(a2t * delta)
    return np.asarray(m, dtype=float) / (E2 - E1) * (L1 / a1t * (E1 * E2 - E2)
                                                     - L2 / a2t * (E1 * E2 - E1))


def switch_jump_error(design, c_old, c_new):
    """Error right after an H_pc jump that falls exactly on a noise switch c_old -> c_new.

    With the right-continuous noise of Theorem 4.14, the flow before the jump
    saw c_old (so x̂_i = x and m̂ = c_old before it) while y at the jump is
    H x + c_new, so (18) does not reset to x: with Delta = c_new - c_old,
    H R - (y - m̂) = -Delta.

    Returns
    -------
    e_plus : (n,) ndarray
        T (H T - I)^{-1} (c_new - c_old).
    m_plus : (p,) ndarray
        c_old - (H T - I)^{-1} (c_new - c_old).

    References
    ----------
    Li & Sanfelice, eq. (18), Theorem 4.14 (decision 5 of the module docstring).
    """
    d = design
    dc = vector("c_new", c_new, d.p) - vector("c_old", c_old, d.p)
    w = np.linalg.solve(d.HT_minus_I, dc)
    return d.T @ w, vector("c_old", c_old, d.p) - w


def _bound_hypotheses(design, theorem):
    d = design
    F1, F2 = d.F1, d.F2
    checks = [   # the one that needs rank H = n first, so its message can say so
        (mu_max(F2) < mu_min(F1), "mu_bar(F2) < mu_(F1)"),
        (alpha_max(F2) < alpha_min(F1), "alpha_bar(F2) < alpha_(F1)"),
        (alpha_max(F1) < 0, "alpha_bar(F1) < 0"),
        (mu_max(F1) < 0 and mu_max(F2) < 0, "F1 and F2 dissipative (mu_bar(F_i) < 0)"),
    ]
    for ok, what in checks:
        if not ok:
            extra = ""
            if what.startswith("mu_bar(F2)") and np.linalg.matrix_rank(d.H) < d.n:
                extra = " (impossible when rank H < n: it needs sym((L2 - L1) H) > 0)"
            raise ValueError(f"{theorem} needs {what}, which fails for this design{extra}")


def _gamma1_coeff(design):
    d = design
    w1 = 1.0 / (1.0 - math.exp((mu_max(d.F2) - mu_min(d.F1)) * d.delta))
    n1, n2 = np.linalg.norm(d.L1, 2), np.linalg.norm(d.L2, 2)
    return (1 + w1) * n1 / abs(mu_max(d.F1)) + w1 * n2 / abs(mu_max(d.F2))


def theorem_4_10_bound(design, m_inf):
    """Bound of Theorem 4.10 on |e1(delta, 1)|.

    |e1(delta,1)| <= ((1 + w1) |L1| / |mu_bar(F1)| + w1 |L2| / |mu_bar(F2)|) |m|_inf,
    w1 = 1 / (1 - exp((mu_bar(F2) - mu_(F1)) delta)).

    Raises ValueError naming the failing hypothesis (alpha_bar(F2) <
    alpha_(F1), alpha_bar(F1) < 0, F_i dissipative, mu_bar(F2) < mu_(F1)).
    The last one needs rank H = n (decision 8 of the module docstring).

    References
    ----------
    Li & Sanfelice, Theorem 4.10.
    """
    if not isinstance(design, Design):
        raise TypeError(f"design must be a Design, got {type(design).__name__}")
    m_inf = scalar("m_inf", m_inf, nonneg=True)
    _bound_hypotheses(design, "Theorem 4.10")
    return _gamma1_coeff(design) * m_inf


def theorem_4_11_bound(design, e0, m_delta, m_inf, t, j):
    """KL bound (16) of Theorem 4.11 on |ē(t, j)| for H_n under noise.

    (1-j) beta(|ē(0,0)|, min(t, delta)) + (1-j) gamma1(|m|_delta)
    + j beta(gamma1(|m|_delta), max(t - delta, 0)) + j gamma(|m|_inf),
    with beta(s,t) = s exp(mu_bar(F1) t), gamma(s) = max_i |L_i|/|mu_bar(F_i)| s,
    gamma1(s) = ((1 + w1)|L1|/|mu_bar(F1)| + w1 |L2|/|mu_bar(F2)|) s, and the
    whole multiplied by |a1| + |a2| (decision 7; = 1 for the paper's a1 = a2 = 1/2).

    Parameters
    ----------
    design : Design
    e0 : float
        |ē(0, 0)|.
    m_delta, m_inf : float
        sup of |m| over [0, delta] and over the whole run.
    t, j : float or array_like
        Hybrid times (j in {0, 1}).

    References
    ----------
    Li & Sanfelice, Theorem 4.11, eq. (16).
    """
    if not isinstance(design, Design):
        raise TypeError(f"design must be a Design, got {type(design).__name__}")
    _bound_hypotheses(design, "Theorem 4.11")
    d = design
    t = np.asarray(t, dtype=float)
    j = np.asarray(j, dtype=float)
    if np.any((j != 0) & (j != 1)):
        raise ValueError("j must be 0 or 1 (H_n jumps once)")
    mu1 = mu_max(d.F1)
    g1 = _gamma1_coeff(d) * m_delta
    g = max(np.linalg.norm(d.L1, 2) / abs(mu_max(d.F1)),
            np.linalg.norm(d.L2, 2) / abs(mu_max(d.F2))) * m_inf
    val = ((1 - j) * e0 * np.exp(mu1 * np.minimum(t, d.delta)) + (1 - j) * g1
           + j * g1 * np.exp(mu1 * np.maximum(t - d.delta, 0.0)) + j * g)
    return (abs(d.a1) + abs(d.a2)) * val


def theorem_4_7_bound(design, z0_dist, t, j, P1=None, P2=None):
    """Bound of Theorem 4.7 on |z_n(t, j)|_A for H_n without noise (with the sqrt(3) factor).

    (1 - j) sqrt(3) sqrt(c2/c1) |z_n(0,0)|_A exp(-lambda_min(P) t / (2 c2)),
    c1 = min eig(P1, P2), c2 = max eig(P1, P2), P = diag(-He(F1,P1), -He(F2,P2)).
    P_i default to the solutions of F_i^T P_i + P_i F_i = -I. He(F, P) is read
    as F^T P + P F (the OCR'd definition in Section II-A is garbled). The
    sqrt(3) is decision 9 of the module docstring (|z|_A vs |(e1, e2)|).

    References
    ----------
    Li & Sanfelice, Theorem 4.7, eq. (13).
    """
    d = design
    n = d.n
    Ps = []
    for name, F, P in (("P1", d.F1, P1), ("P2", d.F2, P2)):
        if P is None:
            P = scipy.linalg.solve_continuous_lyapunov(F.T, -np.eye(n))
        P = matrix(name, P, (n, n), what=" (n x n)")
        if not np.allclose(P, P.T) or np.min(np.linalg.eigvalsh(P)) <= 0:
            raise ValueError(f"{name} must be symmetric positive definite")
        Q = -(F.T @ P + P @ F)
        if np.min(np.linalg.eigvalsh((Q + Q.T) / 2)) <= 0:
            raise ValueError(f"-He(F{name[1]}, {name}) must be positive definite")
        Ps.append((P, Q))
    c1 = min(np.min(np.linalg.eigvalsh(P)) for P, _ in Ps)
    c2 = max(np.max(np.linalg.eigvalsh(P)) for P, _ in Ps)
    lam = min(np.min(np.linalg.eigvalsh((Q + Q.T) / 2)) for _, Q in Ps)
    t = np.asarray(t, dtype=float)
    j = np.asarray(j, dtype=float)
    return (1 - j) * math.sqrt(3 * c2 / c1) * z0_dist * np.exp(-lam * t / (2 * c2))


def dist_to_A(x, xh1, xh2):
    """|z|_A, the Euclidean distance of (x, x̂1, x̂2) to {x = x̂1 = x̂2} (13);
    time-major (N, n) or (n,)."""
    x, xh1, xh2 = (np.asarray(v, dtype=float) for v in (x, xh1, xh2))
    c = (x + xh1 + xh2) / 3
    return np.sqrt(np.sum((x - c) ** 2 + (xh1 - c) ** 2 + (xh2 - c) ** 2, axis=-1))


# ---------------------------------------------------------------------------
# noise
# ---------------------------------------------------------------------------
class PiecewiseConstantNoise:
    """m(t) = sum_k c_k chi_[d_{k-1}, d_k)(t), the noise of Theorem 4.14.

    Parameters
    ----------
    d : sequence of float
        Switch times d_1 < d_2 < ... (d_0 = 0 implied), all > 0.
    c : (K, p) array_like
        Values c_1, ..., c_K with K = len(d) + 1 (c_k on [d_{k-1}, d_k)).
    side : {"right", "left"}
        "right" (the paper's half-open B_k): m(d_k) = c_{k+1}; "left": m(d_k) = c_k.
    snap : float
        Times within ``snap`` of a switch count as on it (a jump located a
        few ulps before d_k still sees the value ``side`` prescribes).

    References
    ----------
    Li & Sanfelice, Theorem 4.14 (decision 5 of the module docstring).
    """

    def __init__(self, d, c, *, side="right", snap=1e-9):
        d = np.atleast_1d(np.asarray(d, dtype=float))
        c = np.asarray(c, dtype=float)
        if c.ndim == 1:
            c = c[:, None]
        if c.ndim != 2 or c.shape[0] != d.size + 1:
            raise ValueError(f"c must have len(d) + 1 = {d.size + 1} rows, got shape {c.shape}")
        if d.size and (np.any(d <= 0) or np.any(np.diff(d) <= 0)):
            raise ValueError(f"d must be positive and strictly increasing, got {d.tolist()}")
        if side not in ("right", "left"):
            raise ValueError(f"side must be 'right' or 'left', got {side!r}")
        self.d, self.c, self.side, self.snap = d, c, side, float(snap)

    @property
    def min_gap(self):
        """min_k (d_k - d_{k-1}) over the finite intervals (inf without switches)."""
        return float(np.min(np.diff(np.concatenate([[0.0], self.d])))) if self.d.size else math.inf

    def __call__(self, t):
        t = float(t)
        k = int(np.searchsorted(self.d, t, side="right"))  # number of d_i <= t
        # snap onto a switch within `snap`
        near = np.nonzero(np.abs(self.d - t) <= self.snap)[0]
        if near.size:
            i = int(near[0])
            k = i + 1 if self.side == "right" else i
        return self.c[k].copy()

    def sup_norm(self, a=0.0, b=math.inf):
        """sup of |m(t)| over [a, b]."""
        starts = np.concatenate([[0.0], self.d])
        ends = np.concatenate([self.d, [math.inf]])
        keep = (ends > a) & (starts <= b)
        return float(np.max(np.linalg.norm(self.c[keep], axis=1)))




def _int_arg(name, v, lo):
    if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < lo:
        raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
    return int(v)


def _ackermann_norm(A, O, P1, P2):
    """max |L_i| (Frobenius) of the single-output observer gains placing P1, P2.

    By Ackermann's formula.

    L = phi(A) O^{-1} e_n with phi the characteristic polynomial of the poles
    and O the observability matrix [H; H A; ...; H A^{n-1}].
    """
    n = A.shape[0]
    en = np.zeros(n)
    en[-1] = 1.0
    w = np.linalg.solve(O, en)
    out = 0.0
    for P in (P1, P2):
        c = np.poly(P)
        phi = np.zeros((n, n))
        for ck in c:                       # Horner: phi(A) = (...(A + c1 I) A + c2 I)...
            phi = phi @ A + ck * np.eye(n)
        out = max(out, float(np.linalg.norm(phi @ w)))
    return out


def _accept_design(A, H, L1, L2, deltas, tz, why):
    """First delta in ``deltas`` (below tz / 2) giving a Design with |K2|, |(H T - I)^{-1}| <= 1e3,
    else None."""
    for dl in deltas:
        if tz is not None and dl >= tz / 2:
            why["delta >= half the first zero of p"] += 1
            continue
        try:
            des = Design(A=A, H=H, L1=L1, L2=L2, delta=dl)
        except ValueError:
            why["I - exp(F2 delta) exp(-F1 delta) singular"] += 1
            continue
        if des.HT_inv_norm <= 1e3 and np.linalg.norm(des.K2, 2) <= 1e3:
            return des
        why["|K2| or |(H T - I)^-1| > 1e3"] += 1
    return None


def random_design(seed, n, p, *, delta=None, normal=False):
    """A seeded random observable (A, H) with gains from pole placement.

    F1 gets real poles in [-1.3, -1], F2 in [-2.8, -2.5] (Lemma 4.2 holds).
    ``normal=True`` (needs p == n) builds F_i = -alpha_i I + skew instead, so
    the hypotheses of Theorems 4.10-4.11 hold. delta defaults to the first of
    1, 1.5, 2, 3 below half the first zero of Remark 4.4's p(t) with
    |K2| <= 1e3 and |(H T - I)^{-1}| <= 1e3 (single-output designs with
    n >= 3 have huge K2 at small delta: the reset is ill-conditioned there).

    Up to 200 draws of A ~ N(0, 1/n), H ~ N(0, 1) are tried (rejecting those
    with sigma_min / sigma_max of the observability matrix below 0.05 or gains
    of Frobenius norm above 30). For single-output plants with n >= 4 such
    draws are rarely well conditioned, so when all 200 fail (and
    ``normal=False``) a second stage draws A in observer canonical form (first
    output e_1^T, random characteristic polynomial with real roots of modulus
    in [0.7, 1.5] and maybe a complex pair of such modulus: roots near 0 make
    |(H T - I)^{-1}| ~ |det F2| / |det A| large), mixed by a random orthogonal similarity,
    with the gains placing the same poles through the first output, and
    tries delta in 1, 1.5, 2, 3, 5, 8, 12 (the reset's |K2| decreases to 1 as
    delta grows, since |e^{F2 t} e^{-F1 t}| -> 0 under Lemma 4.2). Designs the
    first stage finds are unchanged by the second.

    Parameters
    ----------
    seed : int or None
        Seed of ``numpy.random.default_rng``.
    n : int
        State dimension (>= 1).
    p : int
        Output dimension (>= 1; ``normal=True`` needs p == n).
    delta : float, optional
        Use this jump period only (checked against the first zero of p(t)).
    normal : bool
        Dissipative F_i (Theorems 4.10-4.11's hypotheses).

    Returns
    -------
    Design

    Raises
    ------
    ValueError
        Bad n, p, delta, or ``normal=True`` with p != n.
    RuntimeError
        No acceptable design: the message counts why the draws were rejected
        (e.g. every tried delta gave |K2| > 1e3: pass a larger ``delta``).
    """
    n = _int_arg("n", n, 1)
    p = _int_arg("p", p, 1)
    if delta is not None:
        delta = scalar("delta", delta, positive=True)
    if normal and p != n:
        raise ValueError(f"normal=True needs p == n (F_i = A - L_i H set through H^-1), "
                         f"got n={n}, p={p}")
    rng = np.random.default_rng(seed)
    why = {"observability matrix ill-conditioned": 0, "gain norm > 30": 0,
           "delta >= half the first zero of p": 0,
           "I - exp(F2 delta) exp(-F1 delta) singular": 0, "|K2| or |(H T - I)^-1| > 1e3": 0,
           "normal: |det H| < 0.3": 0, "p(t) unresolved (numerically singular)": 0}
    for _ in range(200):
        A = rng.normal(size=(n, n)) / math.sqrt(n)
        H = rng.normal(size=(p, n))
        O = np.vstack([H @ np.linalg.matrix_power(A, k) for k in range(n)])
        sv = np.linalg.svd(O, compute_uv=False)
        if sv[-1] < 0.05 * sv[0]:
            why["observability matrix ill-conditioned"] += 1
            continue
        if normal:
            if p != n or abs(np.linalg.det(H)) < 0.3:
                why["normal: |det H| < 0.3"] += 1
                continue
            S = rng.normal(size=(n, n))
            F1 = -1.0 * np.eye(n) + 0.5 * (S - S.T)
            S = rng.normal(size=(n, n))
            F2 = -2.5 * np.eye(n) + 0.5 * (S - S.T)
            Hi = np.linalg.inv(H)
            L1, L2 = (A - F1) @ Hi, (A - F2) @ Hi
        else:
            P1 = -1.0 - 0.3 * np.linspace(0, 1, n)
            P2 = -2.5 - 0.3 * np.linspace(0, 1, n)
            if p == 1 and _ackermann_norm(A, O, P1, P2) > 31.0:
                # the single-output gain is unique: Ackermann's formula (cheap) says place_poles'
                # would fail too
                why["gain norm > 30"] += 1
                continue
            L1 = scipy.signal.place_poles(A.T, H.T, P1).gain_matrix.T
            L2 = scipy.signal.place_poles(A.T, H.T, P2).gain_matrix.T
        if max(np.linalg.norm(L1), np.linalg.norm(L2)) > 30:
            why["gain norm > 30"] += 1
            continue
        try:
            tz = admissible_delta(A, H, L1, L2, t_max=7.0, num=700)
        except ValueError:
            why["p(t) unresolved (numerically singular)"] += 1
            continue
        des = _accept_design(A, H, L1, L2, [delta] if delta is not None else [1.0, 1.5, 2.0, 3.0],
                             tz, why)
        if des is not None:
            return des
    if not normal:
        # second stage: observer canonical form mixed by an orthogonal similarity (well conditioned
        # for any n)
        P1 = -1.0 - 0.3 * np.linspace(0, 1, n)
        P2 = -2.5 - 0.3 * np.linspace(0, 1, n)
        c1, c2 = np.poly(P1)[1:], np.poly(P2)[1:]
        for _ in range(50):
            # |roots| in [0.7, 1.5]: |H T - I| tends to |det A| / |det F2| as delta grows (single
            # output), so roots near 0 make (H T - I)^{-1} huge
            roots = (rng.uniform(0.7, 1.5, size=n)
                     * rng.choice([-1.0, 1.0], size=n)).astype(complex)
            if n >= 2 and rng.uniform() < 0.5:
                r, th = rng.uniform(0.7, 1.5), rng.uniform(0.3, 2.5)
                roots[:2] = r * np.exp(1j * th), r * np.exp(-1j * th)
            a = np.real(np.poly(roots))[1:]
            Ac = np.zeros((n, n))
            Ac[:, 0] = -a
            Ac[:-1, 1:] = np.eye(n - 1)
            Hc = np.vstack([np.eye(n)[:1], rng.normal(size=(p - 1, n))])
            L1c, L2c = np.zeros((n, p)), np.zeros((n, p))
            L1c[:, 0], L2c[:, 0] = c1 - a, c2 - a
            Q, R = np.linalg.qr(rng.normal(size=(n, n)))
            Q = Q * np.sign(np.diag(R))
            A, H, L1, L2 = Q @ Ac @ Q.T, Hc @ Q.T, Q @ L1c, Q @ L2c
            try:
                tz = admissible_delta(A, H, L1, L2, t_max=25.0, num=1250)
            except ValueError:
                why["p(t) unresolved (numerically singular)"] += 1
                continue
            des = _accept_design(A, H, L1, L2, [delta] if delta is not None
                                 else [1.0, 1.5, 2.0, 3.0, 5.0, 8.0, 12.0], tz, why)
            if des is not None:
                return des
    reasons = "; ".join(f"{k}: {v}" for k, v in why.items() if v)
    hint = " (pass a larger delta)" if why["|K2| or |(H T - I)^-1| > 1e3"] else ""
    delta_s = ', delta=' + repr(delta) if delta else ''
    raise RuntimeError(f"no random design found for seed={seed}, n={n}, p={p}{delta_s}"
                       f", normal={normal}; rejections: {reasons}{hint}")


