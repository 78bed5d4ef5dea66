"""The vectorized batch's sample store (``_SampleLog``): one growable buffer
shared by the rows of a batch, split into each trajectory's arrays at the
end. Used by :mod:`hybridsim.batch_vectorized`.
"""
from __future__ import annotations

import itertools

import numpy as np


class _SampleLog:
    """Growable sample store shared by the trajectories of a batch.

    One flat buffer of (row, t, j, x, xdot) with doubling capacity: each
    append stores one sample for each of a set of trajectories with one slice
    assignment (amortised O(1) per sample, no quadratic copying, and no
    per-sample Python work however many rows append). ``last[r]`` is where
    row r's last sample is (its xdot is set when a flow starts there, as
    :func:`hybridsim.simulate` does). :meth:`split` gathers each
    trajectory's samples (in time order: a stable sort by row) into its own
    arrays, so the arcs do not keep the log alive.
    """

    def __init__(self, N, n, cap=1024):
        self.size = 0
        self.rows = np.empty(cap, dtype=np.int64)
        self.t = np.empty(cap)
        self.j = np.empty(cap, dtype=np.int64)
        self.x = np.empty((cap, n))
        self.xd = np.empty((cap, n))
        self.count = np.zeros(N, dtype=np.int64)
        self.last = np.zeros(N, dtype=np.int64)

    def _grow(self, need):
        cap = max(2 * len(self.t), need)
        k = self.size
        for name in ("rows", "t", "j", "x", "xd"):
            old = getattr(self, name)
            new = np.empty((cap,) + old.shape[1:], dtype=old.dtype)
            new[:k] = old[:k]
            setattr(self, name, new)

    def append(self, rows, t, j, x, xd=None):
        """One sample for each of ``rows`` (distinct); ``xd`` None: NaN."""
        k = len(rows)
        if k == 0:
            return
        a = self.size
        b = a + k
        if b > len(self.t):
            self._grow(b)
        self.rows[a:b] = rows
        self.t[a:b] = t
        self.j[a:b] = j
        self.x[a:b] = x
        self.xd[a:b] = np.nan if xd is None else xd
        self.size = b
        self.count[rows] += 1
        self.last[rows] = np.arange(a, b)

    def settle(self):
        """``count`` and ``last`` recomputed from the stored rows: after an
        interrupt, which may land inside :meth:`append` (between its slice
        assignments), so that every row's arc and its message name the same
        last sample. A sample counts once ``size`` covers it."""
        k, N = self.size, len(self.count)
        r = self.rows[:k]
        self.count = np.bincount(r, minlength=N).astype(np.int64)
        last = np.zeros(N, dtype=np.int64)
        np.maximum.at(last, r, np.arange(k, dtype=np.int64))
        self.last = last

    def set_last_xdot(self, rows, v):
        self.xd[self.last[rows]] = v

    def split(self, keep=None):
        """Per-trajectory ``(t, j, x, xdot)`` arrays, in row order; frees the log.

        ``keep``: at most this many samples of each row (None: all)."""
        k = self.size
        if len(self.count) == 1 and keep is None:    # one trajectory: shrink in place
            for name in ("t", "j"):
                getattr(self, name).resize(k, refcheck=False)
            for name in ("x", "xd"):
                getattr(self, name).resize((k, self.x.shape[1]), refcheck=False)
            out = [(self.t, self.j, self.x, self.xd)]
            self.rows = self.t = self.j = self.x = self.xd = None
            return out
        order = np.argsort(self.rows[:k], kind="stable")
        bounds = np.concatenate(([0], np.cumsum(self.count)))
        out = []
        for r, (a, b) in enumerate(itertools.pairwise(bounds)):
            if keep is not None and b - a > keep[r]:
                b = a + keep[r]
            idx = order[a:b]
            out.append((self.t[idx], self.j[idx], self.x[idx], self.xd[idx]))
        self.rows = self.t = self.j = self.x = self.xd = None
        return out
