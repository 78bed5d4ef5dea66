"""The compiled path's batch kernel: :func:`run_rows`, a batch's rows run by a
run kernel called by its code address (imported only when numba is
installed; see :mod:`._kernel`'s notes).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ._steps import _put
from ._types import _NJ, CACHE, _claim, _claim_within, _one_at


@njit(cache=CACHE, nogil=True, **_NJ)
def run_rows(one, maps, X0, p, fopt, iopt, atol, rngp, poll, stop, next_row, chunk,
             TT, JJ, XX, XXD, fill, AT, NS, CA, DE, INFO, ST):
    """Runs of a batch, taken ``chunk`` rows at a time from the shared counter
    ``next_row`` until none is left, each run's samples written one after
    another into the batch's compact pool (``TT``, ``JJ``, ``XX``, ``XXD``):
    at rows ``AT[i]:AT[i] + NS[i]``, claimed from the shared ``fill`` counter
    when the run ends. A run that does not fit in the pool keeps only its
    counts (``AT[i] = -1``) and is re-run by the caller.

    Released from the GIL: the caller runs it in as many threads as it wants
    cores (dynamic scheduling: a thread slowed by other work on the machine
    takes fewer chunks), all on one pool. ``one``: the address of the run
    kernel (:func:`jit_address`: ``run_one`` for the maps at ``maps``, or a
    system's specialised kernel), called, not compiled in: this kernel is
    compiled once, small, and serves every system. The pool needs no
    compaction afterwards: every arc is a view of its rows."""
    N = X0.shape[0]
    size = TT.shape[0]
    while True:
        i0 = _claim(next_row, chunk)
        if i0 >= N:
            break
        for i in range(i0, min(i0 + chunk, N)):
            T, J, X, XD, cause, detail, info, stats = _one_at(one)(
                maps, np.ascontiguousarray(X0[i]), p, fopt, iopt, atol, rngp, poll, stop)
            m = T.shape[0]
            NS[i] = m
            CA[i] = cause
            DE[i] = detail
            _put(INFO, i, info)
            for q in range(stats.shape[0]):     # (not _put: a second version for int64)
                ST[i, q] = stats[q]
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
