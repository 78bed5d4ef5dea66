r"""Design computations and bounds of paper 000 (pure numpy/scipy, no integrator).

Nekhoroshikh, Efimov, Polyakov, Perruquetti, Furtat, "On simple design of a
robust finite-time observer", CDC 2022.

==========================  ==================================================
:func:`rbar`                exponents ``rbar_i = (i+1) mu`` of the gains in (6)
:func:`weights`             homogeneous weights ``r_i = 1 - (i-1) mu`` (H of (10))
:func:`settling_time`       exact settling time (18), ``v(0)^mu / (mu gamma1)``
:func:`prescribed_v`        the gamma2 = 0 gain of Remark 1
:func:`prescribed_error`    closed-form error of (9) for gamma2 = 0, via (13)-(16)
:func:`beta`                the function beta of Proposition 4 (printed / corrected)
:func:`settling_time_bound` bound (17) for gamma2 > 0
:func:`homogeneous_norm`    the r-homogeneous norm of Section VI
:func:`gain_margin`         ``v - gamma2 |w|`` (z = v in (7) when >= 0)
:func:`iss_exponent`        small-disturbance exponent of the ISS gain (Prop. 5)
==========================  ==================================================

The gains L of (10) are computed in :mod:`observers.lmi` (``solve_lmi10``,
``check_gain_lmi10``).

Examples
--------
>>> from observers.dynamic_gain.design import settling_time, prescribed_v
>>> round(settling_time(1.0, 0.2, 1.0), 12)          # (18), Section VI's T = 5
5.0
>>> float(prescribed_v(5.0, 1.0, 0.2, 1.0))          # the gain vanishes at T
0.0
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from observers._common import scalar, vector
from observers.lmi import check_gain_lmi10, lmi10_matrices

__all__ = ["rbar", "weights", "settling_time", "prescribed_v", "prescribed_error", "beta",
           "settling_time_bound", "homogeneous_norm", "gain_margin", "iss_exponent",
           "check_gains", "check_mu"]


# ---------------------------------------------------------------------------
# argument checks shared by the package (on observers._common)
# ---------------------------------------------------------------------------
def check_gains(L):
    """The gains ``L = (L_0, ..., L_n)`` of (6) as a float vector, all < 0 (Section IV).

    Raises
    ------
    TypeError
        ``L`` is not numeric.
    ValueError
        Not a vector of length n+1 >= 2, non-finite, or an entry >= 0.

    Examples
    --------
    >>> check_gains([-1.0, 2.0])
    Traceback (most recent call last):
    ...
    ValueError: L must have finite, strictly negative entries (paper: L_i < 0), got [-1.  2.]
    """
    def short(shape):
        return ValueError(f"L must be a vector (L_0, ..., L_n) of length n+1 >= 2, "
                          f"got shape {shape}")
    if isinstance(L, (list, tuple, np.ndarray)) and np.ndim(L) != 1:
        raise short(np.shape(L))
    L = vector("L", L)
    if L.size < 2:
        raise short(L.shape)
    if np.any(L >= 0):
        raise ValueError(f"L must have finite, strictly negative entries (paper: L_i < 0), "
                         f"got {L}")
    return L


def check_mu(mu, n, *, strict):
    """``mu`` in Section IV's ``(0, 1/(n+1)]``, or Theorem 3's open interval when ``strict``.

    Examples
    --------
    >>> check_mu(0.25, 3, strict=True)
    Traceback (most recent call last):
    ...
    ValueError: mu must lie in (0, 0.25) for n = 3, got 0.25
    """
    mu = scalar("mu", mu, positive=True)
    hi = 1.0 / (n + 1)
    if not (mu < hi if strict else mu <= hi):
        interval = f"(0, {hi:g})" if strict else f"(0, {hi:g}]"
        raise ValueError(f"mu must lie in {interval} for n = {n}, got {mu}")
    return mu


# ---------------------------------------------------------------------------
# the paper's quantities
# ---------------------------------------------------------------------------
def rbar(n, mu):
    """Exponents ``rbar_i = (i+1) mu``, i = 0..n, of the gains ``z^{-rbar_i}`` in (6).

    Examples
    --------
    >>> rbar(3, 0.2).tolist()
    [0.2, 0.4, 0.6000000000000001, 0.8]
    """
    return (np.arange(n + 1) + 1.0) * float(mu)


def weights(n, mu):
    """Homogeneous weights ``r_i = 1 - (i-1) mu``, i = 1..n+1, of e (Section IV).

    They are the diagonal of H in (10); v has weight r_1 = 1.

    Examples
    --------
    >>> weights(3, 0.2).round(12).tolist()
    [1.0, 0.8, 0.6, 0.4]
    """
    return 1.0 - np.arange(n + 1) * float(mu)


def settling_time(v0, mu, gamma1):
    """Exact settling time ``T = v(0)^mu / (mu gamma1)`` of (18) (gamma2 = 0).

    Section VI prints ``v(0)/(mu gamma1)``; the two agree only for v(0) = 1 and (18)
    is what v' = -gamma1 v^{1-mu} gives (Remark 1), so (18) is used (erratum in
    :data:`observers.dynamic_gain.ERRATA`).

    Parameters
    ----------
    v0 : float
        v(0) > 0.
    mu : float
        In (0, 1).
    gamma1 : float
        > 0.

    Returns
    -------
    float

    Examples
    --------
    >>> round(settling_time(2.0, 0.2, 1.0), 4)          # (18); Section VI's formula: 10
    5.7435

    References
    ----------
    Nekhoroshikh et al., CDC 2022, eq. (18) and Remark 1.
    """
    v0 = scalar("v0", v0, positive=True)
    mu = scalar("mu", mu, positive=True)
    if mu >= 1:
        raise ValueError(f"mu must lie in (0, 1), got {mu}")
    return v0 ** mu / (mu * scalar("gamma1", gamma1, positive=True))


def prescribed_v(t, v0, mu, gamma1):
    """The gain of the prescribed-time observer, ``v(t) = max{0, v0^mu - mu gamma1 t}^{1/mu}``.

    Examples
    --------
    >>> prescribed_v([0.0, 5.0], 1.0, 0.2, 1.0).tolist()
    [1.0, 0.0]

    References
    ----------
    Nekhoroshikh et al., CDC 2022, Remark 1.
    """
    t = np.asarray(t, dtype=float)
    v0 = scalar("v0", v0, positive=True)
    gamma1 = scalar("gamma1", gamma1, positive=True)
    return np.maximum(0.0, v0 ** mu - mu * gamma1 * t) ** (1.0 / mu)


def prescribed_error(t, e0, v0, L, mu, gamma1):
    r"""Closed-form error of the prescribed-time observer (gamma2 = 0, d = 0).

    For gamma2 = 0 the auxiliary system (13) is linear, ``eps' = M eps`` with
    ``M = A + LC + gamma1 H``, and ``nu(tau) = v0 e^{-gamma1 tau}``.  Undoing the
    coordinate change (14) and the time change (16) gives, for t < T,

    .. math:: e(t) = D_r(v(t))\, e^{M \tau(t)}\, D_r(v_0)^{-1} e(0),\qquad
              \tau(t) = \ln(v_0 / v(t)) / \gamma_1,

    and e(t) = 0 for t >= T.  Since both matrices are invertible, e(t) != 0 for every
    t < T when e(0) != 0: the error reaches 0 at T and not before.

    Parameters
    ----------
    t : array_like, shape (N,)
    e0 : (n+1,) array_like
        ``(w(0), x(0) - x_hat(0))``.
    v0, mu, gamma1 : float
    L : (n+1,) array_like

    Returns
    -------
    (N, n+1) ndarray
        e(t), time-major.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.lmi import PAPER_L
    >>> e = prescribed_error([0.0, 5.0], [0.0, 10.0, 0.0, -5.0], 1.0, PAPER_L, 0.2, 1.0)
    >>> e[0].tolist(), e[1].tolist()
    ([0.0, 10.0, 0.0, -5.0], [0.0, 0.0, 0.0, 0.0])

    References
    ----------
    Nekhoroshikh et al., CDC 2022, (9), (13)-(16) with gamma2 = 0.
    """
    L = check_gains(L)
    n = L.size - 1
    e0 = np.asarray(e0, dtype=float)
    if e0.shape != (n + 1,):
        raise ValueError(f"e0 must have shape ({n + 1},), got {e0.shape}")
    A, C, H = lmi10_matrices(n, mu)
    M = A + np.outer(L, C[0]) + gamma1 * H                          # (13), gamma2 = 0
    r = weights(n, mu)
    eps0 = e0 / v0 ** r                                             # (14) inverted
    t = np.atleast_1d(np.asarray(t, dtype=float))
    v = prescribed_v(t, v0, mu, gamma1)
    out = np.zeros((t.size, n + 1))
    for k, vk in enumerate(v):
        if vk > 0:
            tau = np.log(v0 / vk) / gamma1                          # (16) inverted
            out[k] = vk ** r * (expm(M * tau) @ eps0)
    return out


def beta(eps_norm, alpha, L0, mu, gamma1, gamma2, *, corrected=True):
    r"""The function beta of Proposition 4 (17).

    Printed: ``beta(s) = alpha gamma2 (1+|L0|) s + 2 gamma1/(1-mu) (alpha gamma2 s)^{1-mu}``.
    ``corrected=True`` integrates the decay ``e^{-tau/2}`` that ``dV/dtau <= -V``
    actually gives (the proof writes ``e^{-tau}``):
    ``2 alpha gamma2 (1+|L0|) s + 4 gamma1/(1-mu) (alpha gamma2 s)^{1-mu}``, exactly
    twice the printed beta (both integrals double).

    Examples
    --------
    >>> beta(1.0, 1.0, -1.0, 0.5, 1.0, 1.0, corrected=False)      # 2 + 4
    6.0
    >>> beta(1.0, 1.0, -1.0, 0.5, 1.0, 1.0)                       # 4 + 8
    12.0

    References
    ----------
    Nekhoroshikh et al., CDC 2022, proof of Theorem 3 and Proposition 4.
    """
    s = float(eps_norm)
    a = alpha * gamma2 * s
    if corrected:   # int_0^inf e^{-sigma/2} = 2, int_0^inf e^{-(1-mu) sigma/2} = 2/(1-mu)
        return 2.0 * a * (1 + abs(L0)) + 2.0 * gamma1 * a ** (1 - mu) * 2.0 / (1 - mu)
    return a * (1 + abs(L0)) + 2.0 * gamma1 / (1 - mu) * a ** (1 - mu)


def settling_time_bound(e0, v0, L, mu, gamma1, gamma2, *, P=None, corrected=True,
                        log=False):
    r"""Upper bound (17) on the settling time of (9) for gamma2 > 0.

    .. math:: T \le \frac{v(0)^\mu}{\mu\gamma_1}
              \exp\big(\mu\,\beta(\|D_r^{-1}(v(0)) e(0)\|)\big)

    Parameters
    ----------
    e0 : (n+1,) array_like
        ``(w(0), x(0) - x_hat(0))``; Proposition 4 needs ``v(0) > gamma2 |w(0)|``.
    v0 : float
    L : (n+1,) array_like
    mu : float
        In the open interval (0, 1/(n+1)) (Theorem 3).
    gamma1, gamma2 : float
    P : (n+1, n+1) array_like, optional
        The P of (10) for this L (``alpha = sqrt(lambda_max/lambda_min)``).  When
        omitted, the least-conditioned P is found by :func:`observers.lmi.check_gain_lmi10`.
    corrected : bool
        See :func:`beta`.
    log : bool
        Return the natural logarithm of the bound (the bound itself overflows a
        float for the paper's example with ``corrected=True``).

    Returns
    -------
    float
        The bound, ``inf`` when it exceeds the float range (it may be astronomically
        large: it is reported, not assumed tight), or its log.

    Raises
    ------
    ValueError
        If L does not satisfy (10), if ``v(0) <= gamma2|w(0)|``, or bad shapes.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.lmi import PAPER_L
    >>> e0 = [0.0, 10.0, 0.0, -5.0]
    >>> settling_time_bound(e0, 1.0, PAPER_L, 0.2, 1.0, 0.0, P=np.eye(4))   # = (18)
    5.0

    References
    ----------
    Nekhoroshikh et al., CDC 2022, Proposition 4, eq. (17).
    """
    L = check_gains(L)
    n = L.size - 1
    mu = check_mu(mu, n, strict=True)
    gamma1 = scalar("gamma1", gamma1, positive=True)
    gamma2 = scalar("gamma2", gamma2, nonneg=True)
    v0 = scalar("v0", v0, positive=True)
    e0 = np.asarray(e0, dtype=float)
    if e0.shape != (n + 1,):
        raise ValueError(f"e0 must have shape ({n + 1},), got {e0.shape}")
    if not v0 > gamma2 * abs(e0[0]):
        raise ValueError(f"v0 must exceed gamma2 |w(0)| = {gamma2 * abs(e0[0]):g} "
                         f"(Proposition 4), got {v0}")
    if P is None:
        chk = check_gain_lmi10(L, mu, gamma1)
        if not chk["feasible"]:
            raise ValueError("L does not satisfy LMIs (10) for any P")
        P = chk["P"]
    P = np.asarray(P, dtype=float)
    if P.shape != (n + 1, n + 1):
        raise ValueError(f"P must be a positive definite ({n + 1}, {n + 1}) matrix")
    eig = np.linalg.eigvalsh(0.5 * (P + P.T))
    if eig[0] <= 0:
        raise ValueError(f"P must be a positive definite ({n + 1}, {n + 1}) matrix")
    alpha = np.sqrt(eig[-1] / eig[0])
    s = np.linalg.norm(e0 / v0 ** weights(n, mu))                  # ||D_r^{-1}(v(0)) e(0)||
    b = beta(s, alpha, L[0], mu, gamma1, gamma2, corrected=corrected)
    logT = np.log(settling_time(v0, mu, gamma1)) + mu * b           # (17)
    if log:
        return float(logT)
    return float(np.exp(logT)) if logT < 709.0 else np.inf


def homogeneous_norm(e, v, mu):
    r"""The r-homogeneous norm of Section VI, ``|v| + sum_i |e_i|^{1/r_i}``.

    Parameters
    ----------
    e : (n+1,) or (N, n+1) array_like
        ``(w, x - x_hat)``, time-major.
    v : float or (N,) array_like
    mu : float

    Returns
    -------
    float or (N,) ndarray

    Examples
    --------
    >>> float(homogeneous_norm([0.0, 1.0, 0.0, 0.0], 2.0, 0.2))
    3.0
    """
    e = np.asarray(e, dtype=float)
    r = weights(e.shape[-1] - 1, mu)
    return np.abs(np.asarray(v, dtype=float)) + np.sum(np.abs(e) ** (1.0 / r), axis=-1)


def gain_margin(w, v, gamma2):
    """``v - gamma2 |w|`` (>= 0 on (9) once v(0) > gamma2|w(0)|; decision 5).

    Examples
    --------
    >>> float(gain_margin(0.5, 1.0, 1.0))
    0.5
    """
    return np.asarray(v, dtype=float) - gamma2 * np.abs(np.asarray(w, dtype=float))


def iss_exponent(n, mu):
    r"""Exponent p of the ultimate bound ``max_i |e_i| <~ C a^p`` for small disturbances.

    By Proposition 5's proof, (19) is (r, r_d)-homogeneous of degree -mu with
    ``r_i = 1 - (i-1) mu`` and ``r_{d,i} = 1 - i mu``, i = 1..n+1; the
    asymptotic gain of such a system is linear between the homogeneous norms
    (the dilation maps solutions to solutions and keeps sup norms), so
    ``limsup ||xi||_r <= C ||d||_{r_d}`` with ``||d||_{r_d} = max_i
    |d_i|^{1/r_{d,i}}``. A disturbance whose every component has size a < 1
    has ``||d||_{r_d} ~ a^{1/r_{d,1}}`` as a -> 0, so
    ``|e_i| <~ (C a^{1/r_{d,1}})^{r_i}``, largest for the smallest weight
    ``r_{n+1} = 1 - n mu``: ``p = r_{n+1} / r_{d,1} = (1 - n mu)/(1 - mu)``.
    An upper bound's exponent: a realised error may fall faster as a -> 0.

    Examples
    --------
    >>> round(iss_exponent(3, 0.2), 12)          # Section VI: 0.4 / 0.8
    0.5

    References
    ----------
    Nekhoroshikh et al., CDC 2022, Theorem 2, (19), Proposition 5.
    """
    mu = check_mu(mu, int(n), strict=False)
    return (1.0 - n * mu) / (1.0 - mu)
