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
from ._estimate_stats import Stats

__all__ = ["estimate", "Estimate", "clopper_pearson", "run_generator", "Stats", "accumulate",
           "splitting", "SplittingResult", "hybrid_segments", "time_moments"]

# documented here, under the name users import it by
Stats.__module__ = __name__

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
