"""Monte Carlo studies that answer with confidence.

Three tools, each keeping only what its answer needs (never the arcs):

- :func:`estimate`: the probability of an event (``event(arc) -> bool``) or
  of a claim's margin being negative (``claim(arc) -> margin``, the
  :mod:`hybridsim.testing` ``margin_*`` functions), with an exact
  Clopper–Pearson interval, run in batches until the interval's half-width
  reaches a requested value.
- :class:`Stats`: streaming statistics of a signal on an ordinary time grid
  or a grid of jump counts (count, mean and variance by Welford/Chan
  merging, min, max, exceedance counts, quantiles from fixed histogram
  bins), accumulated as runs finish, mergeable across threads and
  processes (:meth:`Stats.merge`, picklable); :func:`accumulate` drives it.
- :func:`splitting`: rare-event probabilities by adaptive multilevel
  splitting on a score (a claim's negated margin is one).
- :func:`time_moments`: time averages of a state's powers along one long
  (ergodic) run, with batch-means standard errors: a stationary moment
  from one arc.

Runs are seeded: run ``i`` of a study gets the ``i``-th child of
``numpy.random.SeedSequence(seed)`` as its generator, whatever the batch
sizes, so a study is reproducible from its seed and any run can be replayed
alone (:func:`run_generator`). A run is ``run(rng) -> arc``, or a batch run
``run(list of rng) -> list of arcs`` marked ``run.batch = True``
(:func:`hybridsim.falsification.batch_run` builds one over
:func:`hybridsim.simulate_many`: ``batch_run(system, lambda rng: x0, t_max)``).

Examples
--------
>>> import numpy as np
>>> from hybridsim.estimate import estimate
>>> res = estimate(lambda rng: rng.random(), event=lambda u: u < 0.25,
...                half_width=0.02, seed=1)
>>> res.lo <= 0.25 <= res.hi, res.half_width <= 0.02
(True, True)
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import numbers
from collections.abc import Callable, Sequence

import numpy as np

from ._estimate_runs import _ams, _in_open_unit, _outcome, _positive_int, _run_batch, _seed_sequence
from .arc_batch import ArcBatch

__all__ = ["estimate", "Estimate", "clopper_pearson", "run_generator", "Stats", "accumulate",
           "splitting", "SplittingResult", "hybrid_segments", "time_moments"]

_STOPPING = ("union", "plain")


def run_generator(seed, i: int) -> np.random.Generator:
    """The generator run ``i`` of a study seeded with ``seed`` receives.

    The ``i``-th child of ``SeedSequence(seed)``: replay one run of a study
    alone with ``run(run_generator(seed, i))``.

    Examples
    --------
    >>> import numpy as np
    >>> g = run_generator(7, 3)
    >>> float(g.random()) == float(np.random.default_rng(
    ...     np.random.SeedSequence(7).spawn(4)[3]).random())
    True
    """
    ss = _seed_sequence(seed)
    child = np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, int(i)),
                                   pool_size=ss.pool_size)
    return np.random.default_rng(child)


def _generators(ss, start, count):
    return [run_generator(ss, i) for i in range(start, start + count)]


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper–Pearson) interval for a binomial proportion.

    Parameters
    ----------
    k, n : int
        Successes and trials (0 <= k <= n, n >= 1).
    confidence : float
        In (0, 1).

    Returns
    -------
    (lo, hi) : floats
        ``P(p in [lo, hi]) >= confidence`` for every p (central: each tail
        at most (1 - confidence)/2).

    Examples
    --------
    >>> lo, hi = clopper_pearson(0, 10)
    >>> lo, round(hi, 4)
    (0.0, 0.3085)
    """
    from scipy.stats import beta
    a = 1.0 - confidence
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


@dataclasses.dataclass(frozen=True)
class Estimate:
    """The answer of :func:`estimate`.

    Attributes
    ----------
    p : float
        The fraction of runs with the event (k / n).
    lo, hi : float
        The confidence interval (see ``stopping``).
    k, n : int
        Runs with the event, runs in all.
    confidence : float
    stopping : str
        ``"union"``: the interval is valid under the sequential stopping
        (each look ``i`` at level ``1 - alpha/(i (i + 1))``); ``"plain"``:
        the Clopper–Pearson interval at the final n, as if n had been fixed.
    looks : int
        Times the interval was examined.
    reached : bool
        The requested half-width was reached (False: ``max_runs`` ran out).
    seed : int or None
        The study's entropy (``SeedSequence(seed).entropy``): replay with it.
    failed : int
        Runs that ended on a failure (counted per ``failures``).
    """

    p: float
    lo: float
    hi: float
    k: int
    n: int
    confidence: float
    stopping: str
    looks: int
    reached: bool
    seed: int | None
    failed: int = 0

    @property
    def half_width(self) -> float:
        """Half the interval's width."""
        return 0.5 * (self.hi - self.lo)

    def __str__(self):
        return (f"{self.p:.6g} in [{self.lo:.6g}, {self.hi:.6g}] "
                f"({100 * self.confidence:g}%, {self.k}/{self.n} runs)")


def estimate(run: Callable, *, event: Callable | None = None, claim: Callable | None = None,
             half_width: float = 0.01, confidence: float = 0.95, seed=None,
             batch: int = 1000, max_runs: int = 10**6, stopping: str = "union",
             failures: str = "raise") -> Estimate:
    """The probability of an event, with an exact confidence interval.

    Runs are made in batches (the first of ``batch`` runs, then each look
    doubles the total) until the interval's half-width is at most
    ``half_width`` or ``max_runs`` have run.

    Parameters
    ----------
    run : callable
        ``run(rng) -> arc`` (any object ``event``/``claim`` accept), or
        ``run(list of rng) -> list`` with ``run.batch = True`` (e.g.
        :func:`hybridsim.falsification.batch_run`, one
        :func:`hybridsim.simulate_many` a batch). Run ``i`` gets
        :func:`run_generator(seed, i) <run_generator>`.
    event : callable, optional
        ``event(arc) -> bool``: the event whose probability is wanted.
    claim : callable, optional
        ``claim(arc) -> margin``: the event is ``margin < 0``. Exactly one
        of ``event`` and ``claim``.
    half_width : float
        The target half-width of the interval, in (0, 1).
    confidence : float
        In (0, 1).
    seed : int, numpy.random.SeedSequence or None
        The study's seed (None: fresh entropy, returned in the result).
    batch : int
        Runs before the first look.
    max_runs : int
        Upper bound on the number of runs.
    stopping : {"union", "plain"}
        ``"union"`` (default): look ``i`` uses the Clopper–Pearson interval
        at level ``1 - alpha/(i (i + 1))`` (alpha = 1 - confidence); the
        levels' failure probabilities add up to alpha, so by the union bound
        every look's interval holds at once with probability >= confidence,
        and the returned interval is valid whatever the stopping rule (a
        confidence sequence; conservative). ``"plain"``: the interval at
        ``confidence`` at every look; its coverage is exact only for a
        number of runs fixed in advance, and stopping at the first narrow
        enough interval (data-dependent n) may cover slightly less.
    failures : {"raise", "event"}
        What a run ending on a failure (``MAP_ERROR``, ``NON_FINITE``,
        ``BLOWUP``, ``SOLVER_FAILED``, ``MAX_STEPS``) does: raise (default),
        or count as the event (conservative for a claim).

    Returns
    -------
    Estimate

    Examples
    --------
    The probability that a timer with period drawn uniformly in [0.5, 1.5]
    jumps before t = 1 (exactly 1/2):

    >>> import hybridsim as hs
    >>> from hybridsim.library import Timer
    >>> def run(rng):
    ...     return hs.simulate(Timer(rng.uniform(0.5, 1.5)), [0.0], t_max=1.0, j_max=1)
    >>> res = estimate(run, event=lambda arc: arc.jump_count > 0, half_width=0.15,
    ...                seed=0, batch=50)
    >>> res.lo < 0.5 < res.hi, res.n
    (True, 100)
    """
    if not callable(run):
        raise TypeError(f"run must be callable (rng -> arc), got {type(run).__name__}")
    if (event is None) == (claim is None):
        raise TypeError("estimate: pass exactly one of event= (arc -> bool) and "
                        "claim= (arc -> margin)")
    for name, fn in (("event", event), ("claim", claim)):
        if fn is not None and not callable(fn):
            raise TypeError(f"{name} must be callable, got {type(fn).__name__}")
    half_width = _in_open_unit("half_width", half_width)
    confidence = _in_open_unit("confidence", confidence)
    batch = _positive_int("batch", batch)
    max_runs = _positive_int("max_runs", max_runs)
    if stopping not in _STOPPING:
        raise ValueError(f"stopping must be one of {_STOPPING}, got {stopping!r}")
    if failures not in ("raise", "event"):
        raise ValueError(f"failures must be 'raise' or 'event', got {failures!r}")
    ss = _seed_sequence(seed)
    alpha = 1.0 - confidence
    k = n = failed = looks = 0
    target = min(batch, max_runs)
    while True:
        gens = _generators(ss, n, target - n)
        for i, value in enumerate(_run_batch(run, gens, n)):
            hit, bad = _outcome(value, event, claim, failures, f"run {n + i}")
            k += hit
            failed += bad
        n = target
        looks += 1
        level = 1.0 - alpha / (looks * (looks + 1)) if stopping == "union" else confidence
        lo, hi = clopper_pearson(k, n, level)
        reached = 0.5 * (hi - lo) <= half_width
        if reached or n >= max_runs:
            break
        target = min(2 * n, max_runs)
    return Estimate(k / n, lo, hi, k, n, confidence, stopping, looks, reached,
                    ss.entropy, failed)


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
    k0 = k[rest]
    t0, t1 = T[k0], T[k0 + 1]
    x0, x1 = X[k0], X[k0 + 1]
    h = (t1 - t0)[:, None]
    s = ((g - t0) / (t1 - t0))[:, None]
    val = (1 - s) * x0 + s * x1
    m0, m1 = XD[k0], XD[k0 + 1]
    herm = np.all(np.isfinite(m0), axis=1) & np.all(np.isfinite(m1), axis=1)
    if herm.any():
        s2 = s * s
        hv = (x0 + s2 * (3 - 2 * s) * (x1 - x0)
              + s * (1 - s) ** 2 * h * m0 + s2 * (s - 1) * h * m1)
        val[herm] = hv[herm]
    out[rest] = val
    return out


def _reduce_chunk(run, stats, ss, start, count, batch):
    """Runs start..start+count-1, reduced into a new accumulator of ``stats``'s layout."""
    out = stats.empty_like()
    done = 0
    while done < count:
        b = min(batch, count - done)
        out.update(_run_batch(run, _generators(ss, start + done, b), start + done))
        done += b
    return out


def accumulate(run: Callable, stats: Stats, runs: int, *, seed=None, batch: int = 1000,
               executor=None, chunks: int | None = None) -> Stats:
    """Reduce ``runs`` seeded runs into ``stats`` as they finish (arcs dropped).

    Parameters
    ----------
    run : callable
        As in :func:`estimate` (``run(rng) -> arc``, or a batch run).
    stats : Stats
        Updated in place and returned.
    runs : int
    seed : int, SeedSequence or None
        Run ``i`` gets :func:`run_generator(seed, i) <run_generator>`.
    batch : int
        Runs held at once (per worker): memory is O(batch) arcs plus the
        statistics, whatever ``runs``.
    executor : concurrent.futures.Executor, optional
        Each chunk of runs is reduced in a worker into its own
        :class:`Stats` and the chunks are merged here (``run`` and the
        signal must pickle).
    chunks : int, optional
        Pieces for the executor (default: 4 per worker).

    Returns
    -------
    Stats

    Examples
    --------
    >>> import numpy as np
    >>> from hybridsim.arc import HybridArc
    >>> def run(rng):                     # a random constant on [0, 1]
    ...     c = rng.normal()
    ...     return HybridArc([0.0, 1.0], [0, 0], [[c], [c]], None)
    >>> s = accumulate(run, Stats(t=[0.5]), 4000, seed=0)
    >>> bool(abs(s.mean[0, 0]) < 4 * s.std_error[0, 0]), s.runs
    (True, 4000)
    """
    if not isinstance(stats, Stats):
        raise TypeError(f"stats must be a Stats, got {type(stats).__name__}")
    runs = _positive_int("runs", runs)
    batch = _positive_int("batch", batch)
    ss = _seed_sequence(seed)
    if executor is None:
        stats.merge(_reduce_chunk(run, stats, ss, 0, runs, batch))
        return stats
    workers = getattr(executor, "_max_workers", None) or 2
    k = min(runs, chunks or 4 * workers)
    bounds = np.linspace(0, runs, k + 1).astype(int)
    futs = [executor.submit(_reduce_chunk, run, stats, ss, int(a), int(b - a), batch)
            for a, b in itertools.pairwise(bounds) if b > a]
    for f in futs:
        stats.merge(f.result())
    return stats


# ------------------------------------------------------------------ splitting
@dataclasses.dataclass(frozen=True)
class SplittingResult:
    """The answer of :func:`splitting`.

    Attributes
    ----------
    p : float
        The estimate (the mean over replicates).
    std_error : float
        The replicates' standard error (NaN for one replicate).
    estimates : ndarray
        Each replicate's estimate (each unbiased).
    segments : int
        Path segments simulated in all (calls of ``simulate``).
    levels : int
        Splitting iterations in all.
    """

    p: float
    std_error: float
    estimates: np.ndarray
    segments: int
    levels: int

    @property
    def relative_error(self) -> float:
        """``std_error / p``."""
        return self.std_error / self.p if self.p > 0 else math.nan


def splitting(simulate: Callable, score: Callable, x0, target: float, *, n: int = 1000,
              k: int = 1, replicates: int = 1, seed=None,
              max_segments: int = 10**6) -> SplittingResult:
    """The probability that a score reaches ``target``: adaptive multilevel splitting.

    Crude Monte Carlo needs about ``100 / p`` runs for a 10% relative error;
    splitting needs about ``n log(1/p) / k`` path segments, with a relative
    variance near ``log(1/p) / n`` when the score orders states as the
    probability of reaching the target from them does (the committor), and
    larger for a cruder score (still unbiased).

    Parameters
    ----------
    simulate : callable
        ``simulate(state, rng) -> path``: a path of the Markov process
        started at ``state`` (its first row) up to the end of the horizon,
        as an array (m, d) of states (time, if it matters, is a component).
        A segment restarts from any state of a path, so a state must hold
        all the process needs to go on.
    score : callable
        ``score(path) -> (m,)`` the score of each state; the event is that
        the path's maximal score reaches ``target`` (for a claim: the
        negated margin, target 0).
    x0 : array_like
        The initial state.
    target : float
    n : int
        Particles.
    k : int
        Particles killed (at least) per iteration, 1 <= k < n.
    replicates : int
        Independent splitting runs (their mean is returned; two or more
        give a standard error).
    seed : int, SeedSequence or None
        Replicate ``r`` uses :func:`run_generator(seed, r) <run_generator>`.
    max_segments : int
        Budget of path segments per replicate (a clear error past it).

    Returns
    -------
    SplittingResult

    Examples
    --------
    A random walk's probability of reaching 8 in 10 steps of +-1 (exactly
    11/1024 = 0.0107):

    >>> import numpy as np
    >>> def walk(s, rng):                  # state (step, position)
    ...     m = int(10 - s[0])
    ...     steps = rng.choice([-1.0, 1.0], m)
    ...     return np.column_stack([s[0] + np.arange(m + 1),
    ...                             s[1] + np.concatenate([[0.0], np.cumsum(steps)])])
    >>> res = splitting(walk, lambda p: p[:, 1], [0.0, 0.0], 8, n=200, replicates=4,
    ...                 seed=0)
    >>> bool(abs(res.p - 11 / 1024) < 4 * res.std_error)
    True
    """
    for name, fn in (("simulate", simulate), ("score", score)):
        if not callable(fn):
            raise TypeError(f"{name} must be callable, got {type(fn).__name__}")
    n = _positive_int("n", n)
    k = _positive_int("k", k)
    if k >= n:
        raise ValueError(f"k must be less than n ({n}), got {k}")
    replicates = _positive_int("replicates", replicates)
    max_segments = _positive_int("max_segments", max_segments)
    if not isinstance(target, numbers.Real) or not math.isfinite(target):
        raise ValueError(f"target must be a finite number, got {target!r}")
    ss = _seed_sequence(seed)
    x0 = np.asarray(x0, dtype=float)
    est, segs, its = [], 0, 0
    for r in range(replicates):
        p, s, i = _ams(simulate, score, x0, float(target), n, k, run_generator(ss, r),
                       max_segments)
        est.append(p)
        segs += s
        its += i
    est = np.array(est)
    se = float(est.std(ddof=1) / math.sqrt(len(est))) if len(est) > 1 else math.nan
    return SplittingResult(float(est.mean()), se, est, segs, its)


def hybrid_segments(system, t_max: float, j_max: float = math.inf, **simulate_kwargs):
    """:func:`splitting`'s ``simulate`` for a hybrid system: segments are runs of the engine.

    A state is the row ``(t, j, x_1, ..., x_n)``; a segment from it is
    ``hs.simulate(system, x, t0=t, j0=j, t_max=t_max, j_max=j_max, seed=rng,
    **simulate_kwargs)`` (its own noise from ``rng``: an SDE flow's Brownian
    path, thresholds, random jump maps), returned as the rows
    ``column_stack([arc.t, arc.j, arc.x])``. A score is then a function of
    those rows, e.g. a claim's per-sample margin negated; an event located
    by the engine (a barrier as a jump guard, with the Brownian-bridge
    correction on SDE flows) shows in the rows' j.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> bm = hs.library.DriftedBrownian(0.0, 1.0, 1.0)
    >>> sim = hybrid_segments(bm, 1.0, j_max=1, method="EM", max_step=0.25)
    >>> rows = sim(np.array([0.0, 0.0, 0.0]), np.random.default_rng(0))
    >>> rows.shape[1], rows[0].tolist()
    (3, [0.0, 0.0, 0.0])
    """
    from .run import simulate as run

    def simulate(state, rng):
        st = np.asarray(state, dtype=float)
        arc = run(system, st[2:], t0=float(st[0]), j0=int(st[1]), t_max=t_max, j_max=j_max,
                  seed=rng, **simulate_kwargs)
        return np.column_stack([arc.t, arc.j, arc.x])
    return simulate


def time_moments(arc, powers: Sequence[int], t_burn: float = 0.0, *, batches: int = 20,
                 component: int = 0) -> list[tuple[float, float]]:
    r"""Time averages of :math:`x_c^k` over :math:`[t_{burn}, t_f]` of one arc, with
    batch-means standard errors.

    The stationary moment :math:`E[X^k]` of an ergodic process is the limit
    of :math:`\frac{1}{T} \int_0^T x(t)^k \, dt`. The integral is taken on
    the arc's flows (pieces between consecutive samples of equal j whose
    start is at or after ``t_burn``), each piece along the straight line
    between its samples: exact wherever the component moves at a constant
    rate between samples (:math:`\dot x = 1` of TCP/AIMD, :math:`\pm v`
    of a telegraph process), the piecewise-linear interpolant's integral
    otherwise (keep the samples dense: ``max_step``). The pieces are put in
    ``batches`` equal windows of time by their start; the estimate is the
    mean of the window averages, its standard error their standard deviation
    over :math:`\sqrt{batches}` (batch means: valid when a window is much
    longer than the process's correlation time).

    Parameters
    ----------
    arc : HybridArc
        One long run.
    powers : sequence of int
        The non-negative integer powers k.
    t_burn : float
        Time discarded at the start (the transient).
    batches : int
        Number of windows, at least 2.
    component : int
        The state component c.

    Returns
    -------
    list of (mean, std_error)
        One pair of floats per power, in order.

    Raises
    ------
    ValueError
        A power that is not a non-negative int, ``batches < 2``, a component
        out of range, or a window without flow after ``t_burn``.

    Examples
    --------
    >>> import hybridsim as hs
    >>> arc = hs.HybridArc([0.0, 1.0, 1.0, 2.0], [0, 0, 1, 1], [[0.0], [1.0], [0.0], [1.0]],
    ...                    hs.Termination.T_MAX)             # x' = 1, reset to 0 at t = 1
    >>> [(m, round(se, 12)) for m, se in time_moments(arc, [1, 2], batches=2)]
    [(0.5, 0.0), (0.3333333333333333, 0.0)]
    """
    ks = []
    for k in powers:
        if isinstance(k, bool) or not isinstance(k, numbers.Integral) or k < 0:
            raise ValueError(f"powers must be non-negative ints, got {k!r}")
        ks.append(int(k))
    if isinstance(batches, bool) or not isinstance(batches, numbers.Integral) or batches < 2:
        raise ValueError(f"batches must be an int >= 2, got {batches!r}")
    n = arc.x.shape[1]
    if isinstance(component, bool) or not isinstance(component, numbers.Integral) \
            or not -n <= component < n:
        raise ValueError(f"component must be an int in [0, {n}) (the arc's state has {n} "
                         f"components), got {component!r}")
    t, j, x = arc.t, arc.j, arc.x[:, component]
    same = (j[1:] == j[:-1]) & (t[:-1] >= t_burn)
    a, b = x[:-1][same], x[1:][same]
    ta, dt = t[:-1][same], np.diff(t)[same]
    if len(ta) == 0 or t[-1] <= t_burn:
        raise ValueError(f"time_moments: the arc has no flow after t_burn={t_burn!r} "
                         f"(it ends at t={float(t[-1]) if len(t) else math.nan!r})")
    edges = np.linspace(t_burn, t[-1], batches + 1)
    which = np.clip(np.searchsorted(edges, ta, side="right") - 1, 0, batches - 1)
    dur = np.bincount(which, weights=dt, minlength=batches)
    if not np.all(dur > 0):
        raise ValueError(f"time_moments: {int(np.sum(dur <= 0))} of the {batches} windows "
                         f"hold no flow; take fewer batches or a longer run")
    out = []
    for k in ks:
        # the mean of (a + (b - a) s)^k over s in [0, 1]: sum of a^i b^(k-i), over k + 1
        mean_k = sum(a ** i * b ** (k - i) for i in range(k + 1)) / (k + 1)
        m = np.bincount(which, weights=dt * mean_k, minlength=batches) / dur
        out.append((float(m.mean()), float(m.std(ddof=1) / math.sqrt(batches))))
    return out
