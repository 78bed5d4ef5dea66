"""The streaming statistics of :mod:`hybridsim.estimate`: :class:`Stats`
(moments, threshold probabilities and histograms of a signal on a grid, over
runs), its bins, and the state between two samples of an arc.
"""
from __future__ import annotations

import numbers
from collections.abc import Sequence

import numpy as np

from ._arc_access import between_samples
from .arc_batch import ArcBatch


# ------------------------------------------------------------------ streaming statistics
def _bins(bins):
    if bins is None:
        return None
    if isinstance(bins, tuple) and len(bins) == 3 and isinstance(bins[2], numbers.Integral):
        lo, hi, m = bins
        if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo and m >= 1):
            raise ValueError(f"bins=(lo, hi, count) needs finite lo < hi and count >= 1, "
                             f"got {bins!r}")
        return np.linspace(float(lo), float(hi), int(m) + 1)
    edges = np.asarray(bins, dtype=float)
    if edges.ndim != 1 or len(edges) < 2 or not np.all(np.isfinite(edges)) \
            or np.any(np.diff(edges) <= 0):
        raise ValueError("bins must be (lo, hi, count) or a 1-D increasing finite array of "
                         "at least 2 edges")
    return edges


class Stats:
    """Streaming statistics of a signal on a grid, over runs: O(1) memory in runs.

    Each run is reduced at the grid points as it is added and then dropped:
    the state is a fixed set of arrays of shape (grid, signal) (plus
    (grid, signal, thresholds) and (grid, signal, bins + 2)), whatever the
    number of runs. Two accumulators of the same layout combine with
    :meth:`merge` (Chan et al.'s pairwise update for mean and variance;
    counts and histograms add), so runs spread over threads, processes or
    dask workers reduce each in its own :class:`Stats` and merge; a
    :class:`Stats` pickles (with a picklable ``signal``).

    Parameters
    ----------
    t : array_like, optional
        An ordinary time grid: the signal at each time (after any jumps at
        it, ``arc.interpolate(..., at_jump="end")``). A run that ends before
        a grid time contributes nothing there (see :attr:`count`).
    j : array_like of int, optional
        A grid of jump counts (hybrid time): the signal right after the
        ``j``-th jump (``j = 0``: at the start), where the run has one.
        Exactly one of ``t`` and ``j``.
    signal : callable or int or None
        ``signal(x) -> value(s)`` applied to the states (rows (m, n) at
        once: write it with ``x[..., k]``), or a state component's index;
        None: the whole state.
    thresholds : sequence of float
        Exceedance counts: how many runs had ``value > threshold`` at each
        grid point.
    bins : (lo, hi, count) or array of edges, optional
        Fixed histogram bins for quantiles (with one underflow and one
        overflow bin): a quantile is exact to within the width of the bin it
        falls in, and is -inf/+inf when it falls below lo/above hi.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> decay = hs.HybridSystem.from_functions(flow_map=lambda x: -x, state_dim=1)
    >>> s = Stats(t=[0.0, 1.0], signal=0, thresholds=[1.0], bins=(0, 4, 40))
    >>> s.update(hs.simulate_many(decay, [[1.0], [2.0], [3.0]], t_max=1.0, rtol=1e-10))
    >>> s.mean[:, 0].round(4), s.exceed[:, 0, 0]      # 3/e > 1
    (array([2.    , 0.7358]), array([2, 1]))
    >>> s.quantile(0.5)[:, 0].round(2)                 # to within the bins' width 0.1
    array([2.05, 0.75])
    """

    def __init__(self, *, t=None, j=None, signal=None, thresholds: Sequence[float] = (),
                 bins=None):
        if (t is None) == (j is None):
            raise TypeError("Stats: pass exactly one of t= (an ordinary time grid) and j= "
                            "(a grid of jump counts)")
        if t is not None:
            g = np.asarray(t, dtype=float).reshape(-1)
            if not np.all(np.isfinite(g)) or np.any(np.diff(g) < 0):
                raise ValueError("Stats: t must be a finite non-decreasing grid")
            self.kind = "t"
        else:
            g = np.asarray(j).reshape(-1)
            if not np.issubdtype(g.dtype, np.integer) or np.any(g < 0):
                raise ValueError("Stats: j must be a grid of non-negative ints")
            self.kind = "j"
        if not len(g):
            raise ValueError("Stats: the grid is empty")
        if signal is not None and not callable(signal) and not (
                isinstance(signal, numbers.Integral) and not isinstance(signal, bool)):
            raise TypeError(f"Stats: signal must be callable (x -> value), a component index "
                            f"or None, got {type(signal).__name__}")
        self.grid, self.signal = g, signal
        self.thresholds = np.asarray(thresholds, dtype=float).reshape(-1)
        self.edges = _bins(bins)
        self.runs = 0
        self._d = None             # signal width, known at the first run

    # state arrays are made at the first value (the signal's width unknown before)
    def _alloc(self, d):
        m = len(self.grid)
        self._d = d
        self.count = np.zeros(m, dtype=np.int64)
        self._mean = np.zeros((m, d))
        self._m2 = np.zeros((m, d))
        self.min = np.full((m, d), np.inf)
        self.max = np.full((m, d), -np.inf)
        self.exceed = np.zeros((m, d, len(self.thresholds)), dtype=np.int64)
        self.hist = None if self.edges is None else \
            np.zeros((m, d, len(self.edges) + 1), dtype=np.int64)

    @property
    def mean(self):
        """The mean at each grid point, shape (grid, d) (NaN where no run has a value)."""
        return np.where(self.count[:, None] > 0, self._mean, np.nan)

    @property
    def variance(self):
        """The unbiased sample variance at each grid point (NaN below 2 runs)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.count[:, None] > 1,
                            self._m2 / np.maximum(self.count[:, None] - 1, 1), np.nan)

    @property
    def std_error(self):
        """The standard error of :attr:`mean`."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.sqrt(self.variance / self.count[:, None])

    def _values(self, arc):
        """(m, d) values at the grid (NaN rows where the arc has none)."""
        if self.kind == "t":
            ok = (self.grid >= arc.t[0]) & (self.grid <= arc.t[-1])
            x = np.full((len(self.grid), arc.state_dim), np.nan)
            if ok.any():
                x[ok] = arc.interpolate(self.grid[ok], at_jump="end").x
        else:
            first = np.searchsorted(arc.j, self.grid, side="left")
            ok = first < len(arc.j)
            ok[ok] &= arc.j[first[ok]] == self.grid[ok]
            x = np.full((len(self.grid), arc.state_dim), np.nan)
            x[ok] = arc.x[first[ok]]
        v = np.where(ok[:, None], self._signal_of(x, len(self.grid)), np.nan)
        return v.reshape(len(self.grid), -1)

    def add_values(self, values):
        """Add runs given as values at the grid: shape (runs, grid, d), NaN where missing."""
        V = np.asarray(values, dtype=float)
        if V.ndim == 2:
            V = V[:, :, None]
        if V.ndim != 3 or V.shape[1] != len(self.grid):
            raise ValueError(f"Stats.add_values: values must have shape (runs, "
                             f"{len(self.grid)}, d), got {V.shape}")
        if self._d is None:
            self._alloc(V.shape[2])
        elif V.shape[2] != self._d:
            raise ValueError(f"Stats: the signal has width {self._d}, got {V.shape[2]}")
        have = ~np.isnan(V[:, :, 0])
        nb = have.sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            mb = np.where(nb[:, None] > 0, np.nansum(V, axis=0) / np.maximum(nb, 1)[:, None],
                          0.0)
            m2b = np.nansum((V - mb) ** 2, axis=0)
        self._combine(nb, mb, m2b)
        if nb.any():
            self.min = np.fmin(self.min, np.nanmin(np.where(have[..., None], V, np.inf),
                                                   axis=0))
            self.max = np.fmax(self.max, np.nanmax(np.where(have[..., None], V, -np.inf),
                                                   axis=0))
        if len(self.thresholds):
            self.exceed += (V[..., None] > self.thresholds).sum(axis=0)
        if self.hist is not None:
            idx = np.searchsorted(self.edges, V, side="right")     # 0: under, len: over
            m, d = V.shape[1:]
            flat = (np.arange(m)[:, None] * d + np.arange(d)) * (len(self.edges) + 1)
            ok = have[..., None] & np.ones(d, dtype=bool)
            np.add.at(self.hist.reshape(-1), (flat[None] + idx)[ok], 1)
        self.runs += len(V)

    def add_states(self, x, ok=None):
        """Add runs given as their states at the grid (the signal applied as to
        an arc's): ``x`` of shape (runs, grid, n), ``ok`` (runs, grid) True
        where the run has a state (default: where ``x`` is not NaN)."""
        X = np.asarray(x, dtype=float)
        if X.ndim != 3 or X.shape[1] != len(self.grid):
            raise ValueError(f"Stats.add_states: x must have shape (runs, {len(self.grid)}, n), "
                             f"got {X.shape}")
        R, m, n = X.shape
        if R == 0:
            return
        ok = ~np.isnan(X).all(axis=2) if ok is None else np.asarray(ok, dtype=bool)
        if ok.shape != (R, m):
            raise ValueError(f"Stats.add_states: ok must have shape {(R, m)}, got {ok.shape}")
        with np.errstate(invalid="ignore"):
            V = self._signal_of(X.reshape(R * m, n), R * m).reshape(R, m, -1)
        self.add_values(np.where(ok[..., None], V, np.nan))

    def _combine(self, nb, mb, m2b):
        na = self.count
        n = na + nb
        with np.errstate(invalid="ignore", divide="ignore"):
            delta = mb - self._mean
            w = np.where(n > 0, nb / np.maximum(n, 1), 0.0)[:, None]
            self._mean = self._mean + delta * w
            self._m2 = self._m2 + m2b + delta ** 2 * (na * w[:, 0])[:, None]
        self.count = n

    def add(self, arc):
        """Add one run's arc (reduced at the grid, not kept)."""
        self.add_values(self._values(arc)[None])

    def update(self, arcs):
        """Add many runs' arcs (a batch of :func:`hybridsim.simulate_many`'s compiled
        path is read off its pools of samples at once, its arcs not made)."""
        runs = getattr(arcs, "_runs", None) if isinstance(arcs, ArcBatch) else None
        if runs is None:
            vals = [self._values(a) for a in arcs]
            if vals:
                self.add_values(np.stack(vals))
            return
        if len(arcs):
            self.add_values(self._batch_values(arcs, runs))

    def _batch_values(self, arcs, runs):
        """:meth:`_values` of every row of the batch ``arcs``, shape (N, m, d): the rows
        of the engine's record ``runs`` (:meth:`hybridsim.ArcBatch._of_pools`) read
        off their pools together (the same values as from their arcs), the others
        from their arcs."""
        N, m = len(arcs), len(self.grid)
        xs, oks, rows_all = [], [], []
        for pool, rows, S, E, _ in runs:
            T, J, X, XD = pool
            S, E = np.asarray(S, np.int64), np.asarray(E, np.int64)
            x = np.full((len(rows), m, X.shape[1]), np.nan)
            ok = np.zeros((len(rows), m), bool)
            for q, g in enumerate(self.grid):
                if self.kind == "t":
                    # k: the run's last sample with t <= g (its samples are in order)
                    c = np.concatenate([[0], np.cumsum(T <= g)])
                    k = S + (c[E] - c[S]) - 1
                    ok[:, q] = have = (T[S] <= g) & (g <= T[E - 1])
                    k, r = k[have], np.flatnonzero(have)
                    x[r, q] = _between(T, X, XD, k, g)
                else:
                    # the run's first sample with j >= g, where j == g
                    c = np.concatenate([[0], np.cumsum(J < g)])
                    first = S + (c[E] - c[S])
                    have = first < E
                    have[have] &= J[first[have]] == g
                    ok[:, q] = have
                    x[have, q] = X[first[have]]
            xs.append(x)
            oks.append(ok)
            rows_all.append(np.asarray(rows, np.int64))
        n = xs[0].shape[2] if xs else arcs[0].state_dim
        X_all = np.full((N, m, n), np.nan)
        ok_all = np.zeros((N, m), bool)
        mine = np.zeros(N, bool)
        for rows, x, ok in zip(rows_all, xs, oks):
            X_all[rows], ok_all[rows], mine[rows] = x, ok, True
        V = self._signal_of(X_all.reshape(N * m, n), N * m).reshape(N, m, -1)
        V = np.where(ok_all[..., None], V, np.nan)
        others = np.flatnonzero(~mine)
        if len(others):
            W = np.stack([self._values(arcs[i]) for i in others.tolist()])
            if W.shape[2] != V.shape[2]:
                raise ValueError(f"Stats: the signal has width {V.shape[2]} on some rows, "
                                 f"{W.shape[2]} on others")
            V[others] = W
        return V

    def _signal_of(self, x, rows):
        """The signal of the states ``x`` (rows, n), shape (rows, d)."""
        if self.signal is None:
            return x
        if callable(self.signal):
            v = np.asarray(self.signal(x), dtype=float)
            if v.ndim == 1:
                v = v[:, None]
            if v.shape[0] != rows:
                raise ValueError(f"Stats: signal(x) on {rows} rows must return {rows} rows "
                                 f"(write it with x[..., k]), got shape {v.shape}")
            return v
        return x[:, [self.signal]]

    def _same_layout(self, other):
        if not isinstance(other, Stats):
            raise TypeError(f"Stats.merge: expected a Stats, got {type(other).__name__}")
        same = (self.kind == other.kind and np.array_equal(self.grid, other.grid)
                and np.array_equal(self.thresholds, other.thresholds)
                and ((self.edges is None and other.edges is None)
                     or (self.edges is not None and other.edges is not None
                         and np.array_equal(self.edges, other.edges))))
        if not same:
            raise ValueError("Stats.merge: the two accumulators differ in grid, thresholds "
                             "or bins")

    def merge(self, other: Stats) -> Stats:
        """Add another accumulator's runs to this one (in place); returns self."""
        self._same_layout(other)
        if other._d is None:
            return self
        if self._d is None:
            self._alloc(other._d)
        elif other._d != self._d:
            raise ValueError(f"Stats.merge: signal widths differ ({self._d}, {other._d})")
        self._combine(other.count, other._mean, other._m2)
        self.min = np.fmin(self.min, other.min)
        self.max = np.fmax(self.max, other.max)
        self.exceed += other.exceed
        if self.hist is not None:
            self.hist += other.hist
        self.runs += other.runs
        return self

    def exceedance(self):
        """The fraction of runs with value > each threshold: (grid, d, thresholds)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.exceed / self.count[:, None, None]

    def quantile(self, q):
        """Quantiles from the histogram: shape (grid, d) (or (len(q), grid, d)).

        Linear within a bin; exact to within that bin's width. -inf/+inf when
        the quantile lies in the underflow/overflow bin; NaN where no run has
        a value.
        """
        if self.hist is None:
            raise ValueError("Stats.quantile needs bins= (the histogram) at construction")
        qs = np.atleast_1d(np.asarray(q, dtype=float))
        if np.any((qs < 0) | (qs > 1)):
            raise ValueError(f"quantile: q must be in [0, 1], got {q!r}")
        cum = np.cumsum(self.hist, axis=-1)              # (m, d, B + 2 - 1)
        total = cum[..., -1:]
        out = np.empty((len(qs),) + cum.shape[:2])
        e = self.edges
        for a, qq in enumerate(qs):
            target = qq * total
            b = np.minimum((cum < np.maximum(target, 1e-300)).sum(axis=-1),
                           cum.shape[-1] - 1)             # the bin holding the quantile
            prev = np.where(b > 0, np.take_along_axis(cum, np.maximum(b - 1, 0)[..., None],
                                                      -1)[..., 0], 0)
            inbin = np.take_along_axis(self.hist, b[..., None], -1)[..., 0]
            with np.errstate(invalid="ignore", divide="ignore"):
                frac = np.clip((target[..., 0] - prev) / inbin, 0, 1)
            inner = (b >= 1) & (b <= len(e) - 1)
            lo = e[np.clip(b - 1, 0, len(e) - 2)]
            width = np.diff(e)[np.clip(b - 1, 0, len(e) - 2)]
            v = np.where(inner, lo + frac * width, np.where(b == 0, -np.inf, np.inf))
            out[a] = np.where(total[..., 0] > 0, v, np.nan)
        return out[0] if np.ndim(q) == 0 else out

    def empty_like(self) -> Stats:
        """A new accumulator with this one's grid, signal, thresholds and bins, no runs."""
        out = Stats.__new__(Stats)
        out.kind, out.grid, out.signal = self.kind, self.grid, self.signal
        out.thresholds, out.edges = self.thresholds, self.edges
        out.runs, out._d = 0, None
        return out

    def __repr__(self):
        return f"Stats({self.kind} grid of {len(self.grid)}, {self.runs} runs)"


def _between(T, X, XD, k, g):
    """The state at time ``g`` from samples ``k`` (``T[k] <= g``, and ``g < T[k + 1]``
    at the same j where ``T[k] < g``), as :meth:`hybridsim.HybridArc.interpolate`
    makes it from an arc without dense output: the sample itself at its own
    time, cubic Hermite where both neighbours' xdot are finite, else linear."""
    out = X[k].copy()
    rest = np.flatnonzero(T[k] != g)
    if rest.size == 0:
        return out
    out[rest] = between_samples(T, X, XD, k[rest], g[rest] if np.ndim(g) else g)
    return out
