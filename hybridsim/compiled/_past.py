"""The compiled path's past, for flow maps with delays (imported only when
numba is installed).

A run with delays (``CompiledSystem(delays=)``) keeps every recorded step's
dense output, as :class:`hybridsim.History` does, and reads x(t - tau) from it.
"""
from __future__ import annotations

import numpy as np
from numba import njit, types

from ._types import (
    _NJI,
    CACHE,
    MAP_ERROR,
    MAP_HISTORY,
)

# ------------------------------------------------------------------ the past (delays)
# A run with delays (CompiledSystem(delays=)) keeps every recorded step's dense
# output, as hybridsim.History does: one row a step, (start, end, h, the step's
# start state (n), its h K^T P (n x 4, row-major)), in chunks of _CH rows kept in
# a typed List HL (appended to, never reassigned: an array reassigned in the run's
# loop costs every run about 10%, delays or not); HM = (count, the last jump's time, and where
# the past was first missing: the time read, the recorded end, the flow map's t).
# The flow map's p holds x(t - tau_i) after the parameters while it runs, NaN
# otherwise.
_CH = 256                           # rows of a chunk of the step record
_CHUNK_T = types.float64[:, ::1]


@njit(cache=CACHE, **_NJI)
def _span(HL, k):
    """The step record's row k: its (start, end). One function for both entries
    (an entry index passed as a constant compiled one version per constant)."""
    R = HL[k // _CH]
    i = k % _CH
    return R[i, 0], R[i, 1]


@njit(cache=CACHE, **_NJI)
def _past(p, pb, dl, s, HL, HM, cur_x, x0, t0):
    """Write x(s - tau_i) for every delay into ``p[pb:]`` (``hybridsim.History``'s
    rules). False, the tail NaN and HM[2:5] set (the first time), where a value
    is not recorded yet (the solver step under way)."""
    n = x0.shape[0]
    hn = int(HM[0])
    cur_t = HM[1]
    for i in range(dl.shape[0]):
        r = s - dl[i]
        o = pb + i * n
        if r < t0:                          # the prehistory: constant x0
            for q in range(n):
                p[o + q] = x0[q]
            continue
        tol = 1e-12 * max(1.0, abs(r))
        if r >= cur_t and (hn == 0 or _span(HL, hn - 1)[0] < cur_t):
            if r <= cur_t + tol:            # the current flow's start: post-jump value
                for q in range(n):
                    p[o + q] = cur_x[q]
                continue
            if HM[2] != HM[2]:
                HM[2] = r
                HM[3] = cur_t
                HM[4] = s
            p[pb:] = np.nan
            return False
        lo = 0
        hi = hn
        while lo < hi:                      # bisect_right on the starts
            mid = (lo + hi) // 2
            if r < _span(HL, mid)[0]:
                hi = mid
            else:
                lo = mid + 1
        k = lo - 1
        if not (k >= 0 and r <= _span(HL, k)[1]):
            if hn > 0 and _span(HL, hn - 1)[1] < r <= _span(HL, hn - 1)[1] + tol:
                k = hn - 1
            else:
                if HM[2] != HM[2]:
                    HM[2] = r
                    HM[3] = _span(HL, hn - 1)[1] if hn > 0 else cur_t
                    HM[4] = s
                p[pb:] = np.nan
                return False
        R = HL[k // _CH]
        kk = k % _CH
        x = (r - R[kk, 0]) / R[kk, 2]
        x2 = x * x
        x3 = x2 * x
        x4 = x3 * x
        for q in range(n):
            c = 3 + n + 4 * q
            p[o + q] = R[kk, 3 + q] + (R[kk, c] * x + R[kk, c + 1] * x2 + R[kk, c + 2] * x3
                                       + R[kk, c + 3] * x4)
    return True


@njit(cache=CACHE, **_NJI)
def _fd(f, y, s, j, p, pb, dl, HL, HM, cur_x, x0, t0):
    """The flow map at (y, s), with the past in ``p[pb:]`` where there are delays
    (NaN again afterwards); a value of NaN where the past is missing (HM[2])."""
    if dl.shape[0] == 0:
        return f(y, s, j, p)
    if not _past(p, pb, dl, s, HL, HM, cur_x, x0, t0):
        return np.full(y.shape[0], np.nan)
    v = f(y, s, j, p)
    p[pb:] = np.nan
    return v


@njit(cache=CACHE, **_NJI)
def _past_missing(info, HM, j):
    """The run's end where the past was missing: MAP_ERROR, with ``info`` = (the
    flow map's t, the time read, the recorded end, j) for the message."""
    info[0] = HM[4]
    info[1] = HM[2]
    info[2] = HM[3]
    info[3] = j
    return MAP_ERROR, MAP_HISTORY


@njit(cache=CACHE, **_NJI)
def _record(HL, HM, a, b, h, ya, hQ):
    """Record the step from a (dense output ya, hQ over h) up to b (a new chunk
    where the last is full)."""
    if not b > a:
        return
    hn = int(HM[0])
    n = ya.shape[0]
    if hn // _CH == len(HL):
        HL.append(np.empty((_CH, 3 + 5 * n)))
    R = HL[hn // _CH]
    k = hn % _CH
    R[k, 0] = a
    R[k, 1] = b
    R[k, 2] = h
    for q in range(n):
        R[k, 3 + q] = ya[q]
        for c in range(4):
            R[k, 3 + n + 4 * q + c] = hQ[q, c]
    HM[0] = hn + 1


@njit(cache=CACHE, **_NJI)
def _add_breaks(BL, t, dl):
    """Insert t + tau_i into the sorted breakpoints BL (a typed List)."""
    for i in range(dl.shape[0]):
        v = t + dl[i]
        k = len(BL)
        while k > 0 and BL[k - 1] > v:
            k -= 1
        BL.insert(k, v)
