"""The compiled path's steps: dense output, error norms, the first step, and
the sample store (imported only when numba is installed).

Ported from scipy's ``RungeKutta`` (``RkDenseOutput``, DOP853's dense
output), as :mod:`hybridsim._rk` takes them; the first step is
:mod:`hybridsim._rk`'s rule (``select_initial_step`` written as plain loops),
compiled from its source.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _rk
from ._types import (
    _A8X,
    _C8X,
    _D8,
    _E,
    _E3,
    _E5,
    _GOES_ON,
    _NJI,
    _NJL,
    CACHE,
    MAP_ERROR,
    NON_FINITE,
    _adopt,
    _bare,
    _hold,
    _release,
)


@njit(cache=CACHE, **_NJL)
def _dense_to(out, yold, hQ, told, h, s):
    """A step's dense output at s written into ``out`` (the event search's trial
    points: no array made per evaluation; :func:`_dense` makes one).

    ``hQ`` says which, by its columns: 4, RK45's (h K^T P); 7, DOP853's
    (scipy's ``Dop853DenseOutput``, its F transposed); 3, the cubic Hermite
    of the step's ends (``solve._Hermite``: the state at the end, h f at the
    start and h f at the end), DOP853's first interior search."""
    x = (s - told) / h
    m = hQ.shape[1]
    if m == 4:
        x2 = x * x
        x3 = x2 * x
        x4 = x3 * x
        for i in range(yold.shape[0]):
            out[i] = yold[i] + (hQ[i, 0] * x + hQ[i, 1] * x2 + hQ[i, 2] * x3 + hQ[i, 3] * x4)
    elif m == 7:
        x1 = 1.0 - x
        for i in range(yold.shape[0]):
            acc = 0.0
            for k in range(6, -1, -1):
                acc += hQ[i, k]
                acc *= x if k % 2 == 0 else x1
            out[i] = acc + yold[i]
    else:
        x2 = x * x
        c1 = x2 * (3.0 - 2.0 * x)
        c2 = x * (1.0 - x) ** 2
        c3 = x2 * (x - 1.0)
        for i in range(yold.shape[0]):
            out[i] = (yold[i] + c1 * (hQ[i, 0] - yold[i]) + c2 * hQ[i, 1]) + c3 * hQ[i, 2]


@njit(inline="always", **_NJL)
def _rk_dense(K, P, hs, hQ):
    """RK45's (RK4's) dense output of a step of ``hs``, its stages in K's rows,
    ``P`` its continuous extension: ``hQ = hs K^T P`` (scipy's
    ``RkDenseOutput``'s Q times h), written in place. Returns whether it is
    finite (a finite step's end, an overflowed interior)."""
    ok = True
    for i in range(hQ.shape[0]):
        for k in range(4):
            acc = 0.0
            for m in range(P.shape[0]):
                acc += K[m, i] * P[m, k]
            acc *= hs
            hQ[i, k] = acc
            ok = ok and math.isfinite(acc)
    return ok


@njit(cache=CACHE, **_NJI)
def _dense(yold, hQ, told, h, s):
    """RK45's dense output at s (as :func:`hybridsim.events.fast_dense`)."""
    out = np.empty(yold.shape[0])
    _dense_to(out, yold, hQ, told, h, s)
    return out


@njit(cache=CACHE, **_NJL)
def _copy_to(out, y):
    """``out[:] = y`` as a loop (a state into a scratch row of the run)."""
    for i in range(y.shape[0]):
        out[i] = y[i]


@njit(cache=CACHE, **_NJL)
def _dense_deriv_to(XD, r, hQ, told, h, s):
    """d/dt of the dense output at s (``solve._dense_derivative``, Q = hQ / h)
    written into row ``r`` of ``XD``."""
    x = (s - told) / h
    for i in range(hQ.shape[0]):
        XD[r, i] = (hQ[i, 0] / h + 2.0 * (hQ[i, 1] / h) * x + 3.0 * (hQ[i, 2] / h) * x * x
                    + 4.0 * (hQ[i, 3] / h) * x * x * x)


@njit(cache=CACHE, **_NJL)
def _norm(v):
    """The 2-norm of ``v`` (``np.sum(v * v)``'s order of sums: no array made)."""
    s = 0.0
    for i in range(v.shape[0]):
        s += v[i] * v[i]
    return math.sqrt(s)


@njit(inline="always", **_NJL)
def _error_norm(K, ya, yb, atol, rtol, hs):
    """RK45's error norm of the step from ``ya`` over ``hs`` to ``yb``, its
    stages in K's first 7 rows (scipy's ``norm(K.T @ E * h / scale)``,
    :meth:`hybridsim._rk._LeanStep._error_norm`). Written apart from the
    Python path's on purpose: that one keeps scipy's own array expressions,
    bit for bit scipy's steps (``tests/engine/test_rk.py``), which a loop's
    order of sums is not."""
    n = ya.shape[0]
    es = 0.0
    for i in range(n):
        acc = 0.0
        for m in range(7):
            acc += K[m, i] * _E[m]
        sc = atol[i] + max(abs(ya[i]), abs(yb[i])) * rtol
        e = acc * hs / sc
        es += e * e
    return math.sqrt(es) / math.sqrt(n)


@njit(inline="always", **_NJL)
def _error_norm_dop853(K, ya, yb, atol, rtol, hs):
    """DOP853's error norm (scipy's ``DOP853._estimate_error_norm``,
    :meth:`hybridsim._rk.DOP853._error_norm`), its stages in K's first 13 rows."""
    n = ya.shape[0]
    s5 = 0.0
    s3 = 0.0
    for i in range(n):
        a5 = 0.0
        a3 = 0.0
        for m in range(13):
            a5 += K[m, i] * _E5[m]
            a3 += K[m, i] * _E3[m]
        sc = atol[i] + max(abs(ya[i]), abs(yb[i])) * rtol
        e5 = a5 / sc
        e3 = a3 / sc
        s5 += e5 * e5
        s3 += e3 * e3
    n5 = math.sqrt(s5) ** 2
    n3 = math.sqrt(s3) ** 2
    if n5 == 0 and n3 == 0:
        return 0.0
    return abs(hs) * n5 / math.sqrt((n5 + 0.01 * n3) * n)


@njit(cache=CACHE, **_NJL)
def _all_finite(v):
    for i in range(v.size):
        if not np.isfinite(v.flat[i]):
            return False
    return True


@njit(cache=CACHE, **_NJL)
def _put(A, i, v):
    """``A[i] = v`` as a loop (numba's broadcasting setitem compiles its shape
    error's formatting, seconds of every first compile)."""
    for q in range(v.shape[0]):
        A[i, q] = v[q]


@njit(cache=CACHE, **_NJI)
def _grown(T, J, X, XD, ns, H):
    """The sample buffers, full at ``ns``, doubled (the first ``ns`` rows kept).

    The run's buffers are held arrays used as :func:`_bare` views (``H``: their
    holds' addresses, :func:`._types._hold`): the new ones are held in ``H``,
    the old ones released, and their views returned."""
    n = X.shape[1]
    old = H.copy()
    T2, J2, X2, XD2 = _held_buffers(2 * T.shape[0], n, H)
    for r in range(ns):
        T2[r] = T[r]
        J2[r] = J[r]
        for q in range(n):
            X2[r, q] = X[r, q]
            XD2[r, q] = XD[r, q]
    _released(old)
    return T2, J2, X2, XD2


@njit(cache=CACHE, **_NJI)
def _released(H):
    """Release the run's four held buffers (:func:`_grown`)."""
    for q in range(4):
        _release(H[q])


@njit(cache=CACHE, **_NJI)
def _held_buffers(cap, n, H):
    """A run's first sample buffers (``cap`` rows), held in ``H``, as views
    (:func:`_grown`)."""
    T = np.empty(cap)
    J = np.empty(cap, np.int64)
    X = np.empty((cap, n))
    XD = np.empty((cap, n))
    H[0] = _hold(T)
    H[1] = _hold(J)
    H[2] = _hold(X)
    H[3] = _hold(XD)
    return _bare(T), _bare(J), _bare(X), _bare(XD)


@njit(cache=CACHE, **_NJI)
def _owned_buffers(T, J, X, XD, ns, H):
    """The run's held buffers (views ``T, J, X, XD``, holds ``H``) at its end,
    released: their first ``ns`` rows as arrays owning their memory (the
    buffers themselves; ``ns`` < 0: copies of the first ``-ns`` rows)."""
    m = ns if ns >= 0 else -ns
    To = _adopt(T, H[0])[:m]
    Jo = _adopt(J, H[1])[:m]
    Xo = _adopt(X, H[2])[:m]
    XDo = _adopt(XD, H[3])[:m]
    if ns < 0:
        To, Jo, Xo, XDo = To.copy(), Jo.copy(), Xo.copy(), XDo.copy()
    _released(H)
    return To, Jo, Xo, XDo


@njit(cache=CACHE, **_NJL)
def _store(T, J, X, XD, ns, t, j, x):
    """Write the sample (t, j, x) at row ``ns`` (xdot NaN); the buffers have room.

    The run appends with ``if ns == T.shape[0]: T, J, X, XD = _grown(...)``
    then this on :func:`_bare` views: a helper returning the four buffers made
    eight atomic reference counts a sample."""
    T[ns] = t
    J[ns] = j
    for q in range(X.shape[1]):
        X[ns, q] = x[q]
        XD[ns, q] = np.nan


# the first-step rule and the step-size controller, written once in hybridsim._rk
# (the Python path calls them)
_initial_guess = _rk.initial_guess
_initial_step = _rk.initial_step
_step_factor = _rk.step_factor


@njit(cache=CACHE, **_NJI)
def _dop853_dense(f, K, ya, yb, a, hs, j, p, yi, hQ):
    """DOP853's dense output of the step from (a, ya) over hs to yb
    (scipy's ``DOP853._dense_output_impl``): its three extra stages into
    ``K[13:16]`` (``K[:13]``: the step's), F into ``hQ`` (n x 7, F
    transposed). Returns 0, 1 where the flow map gave the wrong length, 2
    where F is not finite (an overflow inside the step)."""
    n = ya.shape[0]
    for s in range(13, 16):
        for i in range(n):
            acc = 0.0
            for m in range(s):
                acc += K[m, i] * _A8X[s, m]
            yi[i] = ya[i] + acc * hs
        ks = f(yi, a + _C8X[s] * hs, j, p)
        if ks.shape[0] != n:
            return 1
        for q in range(n):
            K[s, q] = ks[q]
    ok = True
    for i in range(n):
        dy = yb[i] - ya[i]
        hQ[i, 0] = dy
        hQ[i, 1] = hs * K[0, i] - dy
        hQ[i, 2] = 2.0 * dy - hs * (K[12, i] + K[0, i])
        for k in range(4):
            acc = 0.0
            for m in range(16):
                acc += _D8[k, m] * K[m, i]
            hQ[i, 3 + k] = hs * acc
        for k in range(7):
            ok = ok and math.isfinite(hQ[i, k])
    return 0 if ok else 2


@njit(cache=CACHE, **_NJI)
def _dop853_step_dense(f, K, ya, yb, a, hs, j, p, yi, hQ, stats, info):
    """:func:`_dop853_dense` for the run core: its evaluations counted, and
    the run's (cause, detail) where it fails (``info`` filled)."""
    r = _dop853_dense(f, K, ya, yb, a, hs, j, p, yi, hQ)
    stats[2] += 3
    if r == 0:
        return _GOES_ON, 0
    info[0] = a
    info[3] = j
    if r == 1:
        return MAP_ERROR, 2
    info[1] = a + hs
    return NON_FINITE, 2


@njit(cache=CACHE, **_NJI)
def _refined(T, J, X, XD, ns, a, e, j, refine, ya, hQ, hs, deriv, H):
    """The ``refine - 1`` samples inside a step's part from ``a`` to ``e``
    (MATLAB's ``Refine``), from the step's dense output (``ya``, ``hQ``, its
    length ``hs``), stored from row ``ns`` of the buffers (grown as needed).
    Returns ``(T, J, X, XD, ns)`` after them. ``deriv``: their flow derivative
    from the dense output too (RK45; none for DOP853, as on the Python path);
    ``H``: the buffers' holds (:func:`_grown`)."""
    for r in range(1, refine):
        s = a + (e - a) * (r / refine)
        if ns == T.shape[0]:
            T, J, X, XD = _grown(T, J, X, XD, ns, H)
        _store(T, J, X, XD, ns, s, j, _dense(ya, hQ, a, hs, s))
        if deriv:
            _dense_deriv_to(XD, ns, hQ, a, hs, s)
        ns += 1
    return T, J, X, XD, ns


@njit(cache=CACHE, **_NJI)
def _room(T, J, X, XD, ns, a, b, j, refine, ya, hQ, hs, deriv, max_samples, H):
    """Before a flow's sample at ``b``: the step's refined samples inside (a, b)
    (:func:`_refined`, where ``refine`` > 1), then room for that sample.
    Returns ``(T, J, X, XD, ns, ok)``; ``ok`` False: the run has
    ``max_samples`` samples (``MAX_STEPS``), nothing more stored.

    The run calls it only where ``refine > 1`` or the buffers are full or the
    samples at their cap (a helper returning the four buffers at every sample
    would cost eight atomic reference counts a sample), then :func:`_store`."""
    if refine > 1 and b > a:
        if ns + refine - 1 > max_samples:
            return T, J, X, XD, ns, False
        T, J, X, XD, ns = _refined(T, J, X, XD, ns, a, b, j, refine, ya, hQ, hs, deriv, H)
    if ns >= max_samples:
        return T, J, X, XD, ns, False
    if ns == T.shape[0]:
        T, J, X, XD = _grown(T, J, X, XD, ns, H)
    return T, J, X, XD, ns, True
