"""The compiled path's batch kernel: :func:`run_rows`, a batch's rows run by a
run kernel called by its code address (imported only when numba is
installed; see :mod:`._kernel`'s notes).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._steps import _put
from ._types import _NJK, _NJL, CACHE, _claim, _claim_within, _one_at


@njit(cache=CACHE, **_NJL)
def _reduce_row(i, T, J, X, XD, grid, by_j, XF, TF, JF, XG, OK):
    """Row ``i``'s end (``XF[i]``, ``TF[i]``, ``JF[i]``) and its state at each
    point of ``grid`` (``XG[i, g]`` for the first ``XG.shape[2]`` components,
    ``OK[i, g]`` where the run has one), from the run's samples ``T, J, X, XD``,
    as :class:`hybridsim.estimate.Stats` reads them off an arc: ``by_j`` 0, an
    ordinary time grid (non-decreasing): the last sample at or before the
    time, itself at its own time (after the jumps there, as
    ``arc.interpolate(..., at_jump="end")``), else the cubic Hermite of its
    step's ends where both derivatives are finite, else the chord
    (:func:`hybridsim._arc_access.between_samples`, the same operations);
    ``by_j`` 1, jump counts: the first sample after the grid's jump count."""
    m = T.shape[0]
    for q in range(X.shape[1]):
        XF[i, q] = X[m - 1, q]
    TF[i] = T[m - 1]
    JF[i] = J[m - 1]
    nk = XG.shape[2]
    k = 0
    for g in range(grid.shape[0]):
        tg = grid[g]
        if by_j != 0:
            if g > 0 and tg < grid[g - 1]:      # (a j grid need not be sorted)
                k = 0
            while k < m and J[k] < tg:
                k += 1
            have = k < m and J[k] == tg
            OK[i, g] = have
            for q in range(nk):
                XG[i, g, q] = X[k, q] if have else np.nan
            continue
        have = T[0] <= tg and tg <= T[m - 1]
        OK[i, g] = have
        if not have:
            for q in range(nk):
                XG[i, g, q] = np.nan
            continue
        while k + 1 < m and T[k + 1] <= tg:
            k += 1
        if T[k] == tg:
            for q in range(nk):
                XG[i, g, q] = X[k, q]
            continue
        ta, tb = T[k], T[k + 1]
        h = tb - ta
        s = (tg - ta) / (tb - ta)
        herm = True
        for q in range(nk):
            herm = herm and math.isfinite(XD[k, q]) and math.isfinite(XD[k + 1, q])
        s2 = s * s
        u = 1 - s
        for q in range(nk):
            x0 = X[k, q]
            x1 = X[k + 1, q]
            if herm:
                XG[i, g, q] = (x0 + s2 * (3 - 2 * s) * (x1 - x0)
                               + s * (u * u) * h * XD[k, q] + s2 * (s - 1) * h * XD[k + 1, q])
            else:
                XG[i, g, q] = u * x0 + s * x1


@njit(cache=CACHE, nogil=True, **_NJK)
def run_rows(one, maps, X0, P, fopt, iopt, atol, rngp, poll, stop, next_row, chunk,
             TT, JJ, XX, XXD, fill, AT, NS, CA, DE, INFO, ST, grid, by_j, XF, TF, JF, XG, OK):
    """Runs of a batch, taken ``chunk`` rows at a time from the shared counter
    ``next_row`` until none is left, each run's samples written one after
    another into the batch's compact pool (``TT``, ``JJ``, ``XX``, ``XXD``):
    at rows ``AT[i]:AT[i] + NS[i]``, claimed from the shared ``fill`` counter
    when the run ends. A run that does not fit in the pool keeps only its
    counts (``AT[i] = -1``) and is re-run by the caller.

    Reduced (``XG`` of one row or more): no pool; each run keeps only its end
    and its states on ``grid`` (:func:`_reduce_row`: ``XF``, ``TF``, ``JF``,
    ``XG``, ``OK``), its samples dropped when it ends.

    ``P``: the parameters, one row for every run or one row per run.

    Released from the GIL: the caller runs it in as many threads as it wants
    cores (dynamic scheduling: a thread slowed by other work on the machine
    takes fewer chunks), all on one pool. ``one``: the address of the run
    kernel (:func:`jit_address`: ``run_one`` for the maps at ``maps``, or a
    system's specialised kernel), called, not compiled in: this kernel is
    compiled once, small, and serves every system. The pool needs no
    compaction afterwards: every arc is a view of its rows."""
    N = X0.shape[0]
    per_row = P.shape[0] > 1
    size = TT.shape[0]
    reduced = XG.shape[0] > 0
    while True:
        i0 = _claim(next_row, chunk)
        if i0 >= N:
            break
        for i in range(i0, min(i0 + chunk, N)):
            p = P[i] if per_row else P[0]
            T, J, X, XD, cause, detail, info, stats = _one_at(one)(
                maps, np.ascontiguousarray(X0[i]), p, fopt, iopt, atol, rngp, poll, stop)
            m = T.shape[0]
            NS[i] = m
            CA[i] = cause
            DE[i] = detail
            _put(INFO, i, info)
            for q in range(stats.shape[0]):     # (not _put: a second version for int64)
                ST[i, q] = stats[q]
            if reduced:
                _reduce_row(i, T, J, X, XD, grid, by_j, XF, TF, JF, XG, OK)
                continue
            o = _claim_within(fill, m, size)
            AT[i] = o
            if o >= 0:
                for r in range(m):
                    TT[o + r] = T[r]
                    JJ[o + r] = J[r]
                    for q in range(X.shape[1]):
                        XX[o + r, q] = X[r, q]
                        XXD[o + r, q] = XD[r, q]
    return 0
