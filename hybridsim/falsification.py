"""Search for counterexamples: uncertainty spaces and :func:`falsify`.

A theorem about a hybrid system is quantified: for every initial state in a
set, every disturbance below a bound, every sampling sequence with gaps in
[a, b], every delay in [τ1, τ2]. A test that runs the example and a few
seeded cases samples that set; :func:`falsify` searches it for the least
robust run. What may vary is declared as a :class:`Space` of named,
bounded entries (:class:`Interval`, :class:`Box`, :class:`PiecewiseConstant`
and :class:`Sinusoids` signals, :class:`Gaps`); the claim is a function of
the arc that returns a signed margin (positive: it holds, by how much;
negative: violated; see :mod:`hybridsim.testing`'s ``margin_*``
functions); a run maps one point of the space to an arc, or a whole
population of points to their arcs in one batch
(:func:`hybridsim.simulate_many` on a vectorized system, :func:`batch_run`).

The search is scipy's differential evolution over the space's box, which
evaluates each population at once (``vectorized=True``), then a local
compass-search refinement of the worst point within the remaining budget
(each of its iterations one population too);
``method="cmaes"`` is CMA-ES (numpy) over the same box after the same
seeded first population, with restarts;
``method="random"`` is the random-sampling baseline of the same budget.
Only each run's margin is kept, and the arc of the worst run so far (the one
the result returns; simulated again only if that run raised), so a search of
10^6 runs holds 10^6 floats and one arc, not 10^6 arcs.

Examples
--------
A timer whose period is uncertain in [0.9, 1.2], against the claim "the
first jump comes by t = 1.1":

>>> import hybridsim as hs
>>> from hybridsim.library import Timer
>>> from hybridsim.falsification import Space, Interval, falsify
>>> space = Space(period=Interval(0.9, 1.2))
>>> def run(p):
...     return hs.simulate(Timer(p["period"]), [0.0], t_max=2.0, j_max=1)
>>> def by_1_1(arc):                       # margin: 1.1 - (first jump time)
...     return 1.1 - arc.jump_times[0]
>>> res = falsify(run, space, by_1_1, budget=200, seed=0, progress=False)
>>> res.verdict, round(res.margin, 3), round(res.point["period"], 3)
('counterexample', -0.1, 1.2)
"""
from __future__ import annotations

import concurrent.futures
import dataclasses
import itertools
import math
import numbers
import os
import time
import traceback
import weakref
from collections.abc import Callable, Iterable, Mapping

import numpy as np

from ._falsify_search import _cmaes, _de, _refine, _refine_gradient
from ._falsify_space import (
    Box,
    ControlPoints,
    Gaps,
    Interval,
    PiecewiseConstant,
    Point,
    Sinusoids,
    Space,
)
from .arc import HybridArc
from .rules import Termination

__all__ = ["Interval", "Box", "PiecewiseConstant", "ControlPoints", "Sinusoids", "Gaps", "Space",
           "Point", "Finding", "FalsificationResult", "falsify", "batch_run"]

# documented here, under the name users import them by
Interval.__module__ = Box.__module__ = PiecewiseConstant.__module__ = __name__
ControlPoints.__module__ = Sinusoids.__module__ = Gaps.__module__ = __name__
Point.__module__ = Space.__module__ = __name__


@dataclasses.dataclass(frozen=True)
class Finding:
    """A run that failed inside the search: its point and why (counted as a
    counterexample, margin -inf).

    ``cause`` is the run's termination cause (``"BLOWUP"``, ``"MAP_ERROR"``...,
    any not in ``allow``), ``"RAISED"`` (the run raised), ``"WORKER_DIED"``
    (a worker of a population run's executor died: its chunk was lost, not
    run), ``"NOT_AN_ARC"`` (the run returned something else) or
    ``"CLAIM_RAISED"`` (the claim
    raised on the run's arc); ``message`` says why (the run's message, or
    the exception's type, text and where it was raised); ``exception`` is
    the exception that was raised (without its traceback, so that findings
    hold no arcs), or None for a termination cause (the worst run's arc
    keeps its own, ``result.arc.exception``).
    """

    point: Point
    cause: str
    message: str
    exception: BaseException | None = None


@dataclasses.dataclass(frozen=True)
class FalsificationResult:
    """What :func:`falsify` found.

    Attributes
    ----------
    verdict : {"counterexample", "none found"}
        ``"counterexample"`` when some run's margin was negative (or a run
        failed, see ``findings``).
    margin : float
        The worst (smallest) margin found.
    point : Point
        The point of the space that gave it.
    arc : HybridArc or None
        That run, as it was judged (plot it with the hybrid plots); None
        when it failed without an arc (a run that raised, simulated again
        to no avail).
    where : tuple or None
        The hybrid time (t, j) the claim's margin names, when it names one.
    history : ndarray
        Every evaluation's margin, in order (``np.minimum.accumulate`` gives
        the best-so-far curve).
    evaluations : int
    seconds : float
    findings : list of Finding
    method : str
    seed : int or None
    stopped : str
        Why the search ended: ``"counterexample"`` (the first, with
        ``stop=True``), ``"budget"``, ``"seconds"``, ``"converged"`` (the
        search had nothing left to try: a space of one point, DE collapsed
        without new points), ``"interrupted"`` (Ctrl-C: the results are
        those of the runs finished before it) or ``"error"`` (a failure with
        ``on_error="stop"``, or an executor that broke: see ``error``).
    error : Finding or None
        With ``stopped == "error"``: the failure that ended the search (its
        point, cause, message and exception); not counted in ``findings``
        when ``on_error="stop"``.
    found_by : str
        How the worst run was found, and which run it was: ``"a seeded
        vertex of the box, run 3 of 40"``, ``"differential evolution, run
        812 of 2000"``, ``"the compass search from the worst point, ..."``,
        ``"random sampling, ..."`` (empty when nothing ran).
    """

    verdict: str
    margin: float
    point: Point
    arc: object
    where: tuple | None
    history: np.ndarray
    evaluations: int
    seconds: float
    findings: list
    method: str
    seed: int | None
    stopped: str = "budget"
    error: Finding | None = None
    found_by: str = ""

    @property
    def interrupted(self) -> bool:
        """True when Ctrl-C (KeyboardInterrupt) ended the search."""
        return self.stopped == "interrupted"

    def __repr__(self):
        end = "" if self.stopped in ("budget", "counterexample", "converged") \
            else f", stopped: {self.stopped}"
        return (f"FalsificationResult({self.verdict}: margin {self.margin:.4g} at {self.point}"
                f"{'' if self.where is None else f', (t, j) = {self.where}'}; "
                f"{self.evaluations} evaluations in {self.seconds:.2f} s, {self.method}{end})")


def batch_run(system, x0_of, t_max, j_max=np.inf, *, attributes_of=None, **simulate_kwargs):
    """A population run: all points of a population in one :func:`hybridsim.simulate_many`.

    Parameters
    ----------
    system : HybridSystem
        Any model: a plain class (its maps as written) runs compiled where
        they compile (``backend="auto"``), a ``vectorized`` one otherwise as
        one numpy batch.
    x0_of : callable
        ``x0_of(point) -> initial state`` (the point's parameters written
        into the state, or the same state for every point).
    attributes_of : callable, optional
        ``attributes_of(point) -> dict`` of the system's attributes (numbers
        or arrays its maps read, such as ``{"e": point["e"]}``) for that
        point: the parameters stay where the model keeps them
        (:func:`hybridsim.simulate_many`'s ``attributes``: on the compiled
        path one parallel batch with a ``p`` per row, nothing compiled
        again; on the others the rows one after another with their
        attributes set, restored after; over an executor each row on a copy).
        A :class:`~hybridsim.compiled.CompiledSystem`'s are its ``params``
        (``{"params": p}``: taken as they are, nothing set). A plain
        model's attributes are set on ``system`` in turn while its next
        pieces' parameters are read (under a lock, restored at once), while
        :func:`falsify` judges earlier ones: a claim judges the arc it is
        given, not the system's attributes.
    t_max, j_max, **simulate_kwargs
        As in :func:`hybridsim.simulate_many`; ``backend`` defaults to
        ``"auto"``: the compiled path where the system runs there (numba
        installed, a system with a compiled form or a plain model whose maps
        compile), else the numpy batch or the Python path.
        ``executor=`` (and ``chunks=``) spreads each population over an
        executor: a ``concurrent.futures`` pool, or a dask cluster's
        ``client.get_executor()`` for several machines.

    Returns
    -------
    callable
        ``run(points) -> list of HybridArc``, with ``run.batch = True`` so
        :func:`falsify` passes it whole populations, and ``run.renew()``,
        which :func:`falsify` calls when a worker of the executor died: a
        process pool, broken for good, is replaced by a fresh one of the same
        settings (shut down with the run; the user's own pool is left to its
        owner), so the search loses only the chunk the worker was running;
        ``run.concurrent`` is True where the populations run on the compiled
        path in this process (a compiled system, no ``executor``): the
        kernel releases the GIL, and :func:`falsify`
        simulates the next pieces of a population in threads while it
        judges the pieces run (the same runs, judged in the same order).

    Examples
    --------
    >>> import hybridsim as hs
    >>> from hybridsim.library import Timer
    >>> run = batch_run(Timer(1.0), lambda p: [0.0], 2.0, 1, backend="python",
    ...                 attributes_of=lambda p: {"period": p["period"]})
    >>> [round(float(a.jump_times[0]), 6) for a in run([{"period": 0.5}, {"period": 1.5}])]
    [0.5, 1.5]
    """
    from .run import simulate_many

    simulate_kwargs.setdefault("backend", "auto")
    if attributes_of is not None and not callable(attributes_of):
        raise TypeError(f"attributes_of must be a callable point -> dict of the system's "
                        f"attributes, got {type(attributes_of).__name__}")
    pools = _Pools(simulate_kwargs)

    def run(points):
        x0s = np.array([np.asarray(x0_of(p), dtype=float) for p in points])
        rows = None
        if attributes_of is not None:
            rows = [attributes_of(p) for p in points]
            for v in rows:
                if not isinstance(v, Mapping):
                    raise TypeError(f"attributes_of must return a dict of the system's "
                                    f"attributes, got {type(v).__name__}")
        return simulate_many(system, x0s, t_max, j_max, warn=False, attributes=rows,
                             **simulate_kwargs)
    run.batch = True
    run.renew = pools.renew
    # compiled populations simulate without the GIL: falsify runs the next
    # pieces of a population in threads while it judges those run
    run.concurrent = (simulate_kwargs.get("executor") is None
                      and _gil_free(system, simulate_kwargs))
    weakref.finalize(run, pools.close)
    return run


def _gil_free(system, kwargs):
    """Whether :func:`hybridsim.simulate_many` runs ``system``'s batches on the
    compiled path (a kernel that releases the GIL): a compiled system whose
    options that path runs, numba installed."""
    from .compiled import CompiledSystem
    from .run import _auto_backend
    return (kwargs.get("backend") in ("auto", "compiled") and isinstance(system, CompiledSystem)
            and _auto_backend(system, kwargs, None) == "compiled")


class _Pools:
    """The executor of a :func:`batch_run`, renewed when a process pool breaks."""

    def __init__(self, kwargs):
        self.kwargs, self.owned = kwargs, None

    def renew(self):
        """A fresh process pool in place of a broken one; False when the
        executor is not a process pool (a dask cluster recovers by itself)."""
        ex = self.kwargs.get("executor")
        if not isinstance(ex, concurrent.futures.ProcessPoolExecutor):
            return False
        fresh = concurrent.futures.ProcessPoolExecutor(
            ex._max_workers, mp_context=ex._mp_context, initializer=ex._initializer,
            initargs=ex._initargs, max_tasks_per_child=ex._max_tasks_per_child)
        self.close()
        self.kwargs["executor"] = self.owned = fresh
        return True

    def close(self):
        if self.owned is not None:
            self.owned.shutdown(wait=False, cancel_futures=True)
            self.owned = None


def _where(exc):
    """``file:line in function`` of the frame that raised ``exc``, or ""."""
    tb = traceback.extract_tb(exc.__traceback__) if exc.__traceback__ else None
    if not tb:
        return ""
    f = tb[-1]
    return f" (at {f.filename.rsplit('/', 1)[-1]}:{f.lineno} in {f.name})"


def _name(fn):
    return getattr(fn, "__qualname__", None) or getattr(fn, "__name__", None) or repr(fn)


class _Evaluator:
    """Runs points, reduces each arc to its margin, keeps the history and the worst.

    The history is a float array grown as runs finish (8 bytes a run, never
    the whole budget at once); arcs are dropped as soon as their margin is
    known, but for the worst so far. With ``stop``, single runs are judged
    one by one, and a population run is split: the first population into
    batches of 1, 2, 4, ... runs (a claim that almost every run breaks is
    refuted by the first), later ones into quarters; so a counterexample
    ends the search without simulating the rest of its population. With a
    finite ``seconds``, a population run is split further so that each
    chunk is expected to end before the deadline (at most twice the last
    chunk, at the rate measured so far): the search stops within one chunk
    of runs of it. Points are built from the coordinates one chunk at a
    time, as the chunk runs; for a run with ``concurrent = True`` (and no
    ``seconds``) the population's points are built at once and its pieces
    simulate ahead in threads (:meth:`_pipelined`).

    A run ending ``CANCELED`` (Ctrl-C inside the engine) is not judged: the
    search stops there (``interrupted``), as it does on a KeyboardInterrupt
    anywhere else.
    """

    def __init__(self, run, space, claim, budget, seconds, allow, progress, stop,
                 on_error="finding"):
        self.run, self.space, self.claim = run, space, claim
        self.batch = bool(getattr(run, "batch", False))
        # a population run that releases the GIL: pipelined (:meth:`_pipelined`)
        self.concurrent = self.batch and getattr(run, "concurrent", False) is True
        self._pool, self._warm = None, False
        self.budget, self.deadline = budget, time.perf_counter() + seconds
        self.timed = math.isfinite(seconds)
        self.allow = allow
        self.on_error = on_error
        self._hist, self.n, self.findings = np.empty(min(budget, 1024)), 0, []
        self.best, self.best_z, self.best_where = math.inf, None, None
        self.best_arc = None                # the worst run's arc (None: it raised)
        self.stop_at_counterexample = stop
        self.error = None                   # a bad claim: raised after the optimizer
        self.failure = None                 # the Finding that stopped the search
        self.interrupted = False
        self._rate, self._last = None, 0    # seconds a run, size of the last chunk
        self.stages = []                    # (first run, what ran from there), in order
        from tqdm.auto import tqdm
        self.bar = tqdm(total=budget, unit="run", disable=None if progress is None
                        else not progress, leave=False)

    @property
    def history(self):
        return self._hist[:self.n]

    @property
    def found(self):
        return self.stop_at_counterexample and self.best < 0

    @property
    def done(self):
        return (self.n >= self.budget or self.interrupted or self.failure is not None
                or self.error is not None or self.found
                or time.perf_counter() >= self.deadline)

    def _fail(self, p, cause, exc, message):
        """A run or claim that failed at p: a finding, the end of the search,
        or the exception raised, as ``on_error`` says; the margin, or None."""
        if self.on_error == "raise":
            exc.add_note(f"(falsify: {message.split(': ', 1)[0]}, at {p!r})")
            raise exc
        if self.on_error == "stop":
            self.failure = Finding(p, cause, message, exc)
            return None
        self.findings.append(Finding(p, cause, message, exc.with_traceback(None)))
        return -math.inf

    def _margin(self, arc, point):
        """(margin, where) of one arc, or None when the search must stop."""
        if not isinstance(arc, HybridArc):
            exc = TypeError(f"run must return a HybridArc, got {type(arc).__name__}: "
                            f"{str(arc)[:80]}")
            return self._fail(point, "NOT_AN_ARC", exc, f"run {_name(self.run)} "
                              f"returned {type(arc).__name__}, not a HybridArc"), None
        cause = arc.termination
        if cause is Termination.CANCELED:   # Ctrl-C inside the engine: not a finding
            self.interrupted = True
            return None, None
        if isinstance(cause, Termination) and cause.name not in self.allow:
            self.findings.append(Finding(point, cause.name, arc.message or ""))
            return -math.inf, None
        try:
            m = self.claim(arc)
        except Exception as exc:  # noqa: BLE001 - the claim failed on this run
            return self._fail(point, "CLAIM_RAISED", exc,
                              f"claim {_name(self.claim)} raised {type(exc).__name__}: "
                              f"{exc}{_where(exc)}"), None
        where = None
        if hasattr(m, "where"):
            where = m.where
        try:
            value = float(m)
        except (TypeError, ValueError):
            self.error = TypeError(f"claim must return a real number (a margin), got "
                                   f"{type(m).__name__} at {point!r}")
            return None, None
        if math.isnan(value):
            self.error = ValueError(f"claim returned NaN at {point!r}: a margin must be a "
                                    f"number (positive: holds, negative: violated)")
            return None, None
        return value, where

    def _record(self, p, arc, message=None, cause="RAISED"):
        """Judge one run (an arc, or the exception its run raised, ``message``
        and ``cause`` saying so): its margin, or None when the search must stop."""
        if isinstance(arc, BaseException) and isinstance(arc.__cause__, KeyboardInterrupt):
            self.interrupted = True         # Ctrl-C as the run started (the engine's
            return None                     # SimulationError from KeyboardInterrupt)
        if isinstance(arc, BaseException):
            message = message or f"{type(arc).__name__}: {arc}{_where(arc)}"
            value, where = self._fail(p, cause, arc, message), None
        else:
            value, where = self._margin(arc, p)
        if value is None:
            return None
        if self.n == len(self._hist):       # grown as runs finish, never past the budget
            grown = np.empty(min(self.budget, 2 * len(self._hist)))
            grown[:self.n] = self._hist
            self._hist = grown
        self._hist[self.n] = value
        self.n += 1
        self.bar.update(1)
        if value < self.best:
            self.best, self.best_z, self.best_where = value, p.z, where
            self.best_arc = arc if isinstance(arc, HybridArc) else None
        return value

    def _bounds(self, size):
        """The planned chunks of a population of ``size`` rows."""
        if not self.stop_at_counterexample:
            return [0, size]
        if self.n == 0:                      # the first population: 1, 2, 4, ... runs
            return [0] + [min(2 ** k, size) for k in range(math.ceil(math.log2(size)) + 1)]
        step = max(8, math.ceil(size / 4))   # later ones: in quarters
        return [*range(0, size, step), size]

    def _fit(self, want):
        """Rows of the next chunk: ``want``, fewer if the deadline comes first."""
        if not self.timed:
            return want
        if self._rate is None:
            return 1                        # the first chunk measures the rate
        left = self.deadline - time.perf_counter()
        fit = int(left / self._rate) if self._rate > 0 else want
        return max(1, min(want, 2 * self._last, fit))

    def _run_batch(self, chunk):
        """The arcs of one chunk of points, or the exception its run raised."""
        start = time.perf_counter()
        try:
            arcs = list(self.run(chunk))
        except Exception as exc:  # noqa: BLE001 - a failed population run: its points
            return exc
        if len(arcs) != len(chunk):
            raise ValueError(f"a batch run must return one arc per point: got "
                             f"{len(arcs)} for {len(chunk)}")
        self._rate = (time.perf_counter() - start) / len(chunk)
        self._last = len(chunk)
        return arcs

    @staticmethod
    def _lost(exc, size):
        """(message, cause) of the points of a population run's chunk that raised."""
        if isinstance(exc, concurrent.futures.BrokenExecutor):
            return (f"a worker of the population run's executor died ({type(exc).__name__}: "
                    f"{exc}) on the chunk of {size} points this one was in: not run",
                    "WORKER_DIED")
        return (f"the population run raised {type(exc).__name__}: {exc}{_where(exc)} on "
                f"the chunk of {size} points this one was in", "RAISED")

    def _renew(self, p, exc):
        """After a dead worker: a fresh executor from the run (``run.renew()``),
        or the end of the search (False) when it has none."""
        renew = getattr(self.run, "renew", None)
        try:
            if callable(renew) and renew():
                return True
        except Exception as e:  # noqa: BLE001 - no fresh pool: the search ends below
            exc = e
        self.failure = Finding(p, "WORKER_DIED", f"the population run's executor broke "
                               f"and could not be renewed: {type(exc).__name__}: {exc}",
                               exc.with_traceback(None))
        return False

    def _judge(self, chunk, arcs, a, out):
        """Record the runs of one chunk (its arcs, or the exception its run
        raised), their margins written to ``out[a:]``; False when the search
        must stop at once."""
        broken = None                       # the BrokenExecutor of a dead worker
        if isinstance(arcs, BaseException):
            exc = arcs
            if isinstance(exc, concurrent.futures.BrokenExecutor):
                broken = exc
            for k, p in enumerate(chunk):
                value = self._record(p, exc, *self._lost(exc, len(chunk)))
                if value is None:
                    return False
                out[a + k] = value
        else:
            for k, (p, arc) in enumerate(zip(chunk, arcs)):
                if getattr(arc, "termination", None) is Termination.CANCELED:
                    self.interrupted = True     # the finished rows still count
                    continue
                exc = getattr(arc, "exception", None)
                if isinstance(exc, concurrent.futures.BrokenExecutor):
                    broken = exc            # a row the dead worker lost
                    value = self._record(p, exc, *self._lost(exc, len(chunk)))
                else:
                    value = self._record(p, arc)
                if value is None:
                    return False
                out[a + k] = value
        return broken is None or self._renew(chunk[0], broken)

    def _pipelined(self, rows, out):
        """The batch path of a run that simulates without the GIL (``run.concurrent``):
        the population in pieces of a quarter of a chunk (at least 2 rows),
        simulated in threads (one per core) ahead of the judging, which
        goes through the same chunks in the same order: the same runs are
        judged and counted as one by one, the claim of one piece computed
        while the next pieces simulate. After a chunk that ends the search,
        the pieces not started are cancelled and those under way awaited
        (their runs are not judged)."""
        point = self.space._point
        if self._pool is None:
            self._pool = concurrent.futures.ThreadPoolExecutor(
                max(2, os.cpu_count() or 1), thread_name_prefix="hybridsim-falsify")
        plan = []                           # (chunk's end, piece's start, its points)
        for a, b in itertools.pairwise(self._bounds(len(rows))):
            step = max(2, math.ceil((b - a) / 4))
            plan += [(b, s, [point(z) for z in rows[s:min(b, s + step)]])
                     for s in range(a, b, step)]
        # the first piece alone: the model is compiled (once) before threads share it
        futures = [self._pool.submit(self._run_batch, plan[0][2])]
        if self._warm:
            futures += [self._pool.submit(self._run_batch, ch) for _, _, ch in plan[1:]]
        try:
            for k, (end, s, chunk) in enumerate(plan):
                arcs = futures[k].result()
                if k == 0 and not self._warm:
                    self._warm = True
                    futures += [self._pool.submit(self._run_batch, ch) for _, _, ch in plan[1:]]
                if not self._judge(chunk, arcs, s, out) or (
                        self.done and (k + 1 == len(plan) or plan[k + 1][0] != end)):
                    break
        finally:
            for f in futures:
                f.cancel()
            concurrent.futures.wait(futures)

    def close(self):
        """Shut the threads of :meth:`_pipelined` down (after the search)."""
        self.bar.close()
        if self._pool is not None:
            self._pool.shutdown(wait=True)

    def __call__(self, Z):
        """Margins of the rows of Z (n, dim); +inf for rows not run (past the
        budget, the deadline, or after a counterexample when stopping at the
        first)."""
        Z = np.atleast_2d(Z)
        out = np.full(len(Z), np.inf)
        room = 0 if self.done else max(0, self.budget - self.n)
        rows = Z[:room]
        if not len(rows):
            return out
        # the optimizers' rows are finite and of the space's width; clipped once
        # here, and each made a Point only when its chunk runs (a counterexample
        # in the first chunk builds one Point, not a population of them)
        rows = np.clip(rows, self.space.lo, self.space.hi)
        point = self.space._point
        if self.batch and self.concurrent and not self.timed:
            self._pipelined(rows, out)
        elif self.batch:
            for a, b in itertools.pairwise(self._bounds(len(rows))):
                while a < b and not self.done:
                    c = a + self._fit(b - a)
                    chunk = [point(z) for z in rows[a:c]]
                    if not self._judge(chunk, self._run_batch(chunk), a, out):
                        return out
                    a = c
                if self.done:
                    break
        else:
            for k, z in enumerate(rows):
                p = point(z)
                try:
                    arc = self.run(p)
                except Exception as exc:  # noqa: BLE001 - a failed run is a finding
                    arc = exc
                value = self._record(p, arc)
                if value is None:
                    return out
                out[k] = value
                if self.done:
                    break
        return out


def falsify(run: Callable, space: Space, claim: Callable[..., float], *,
            budget: int = 1000, seconds: float = math.inf, seed: int | None = None,
            method: str = "de", popsize: int | None = None, refine: bool | str = True,
            allow: Iterable[str] = ("T_MAX", "J_MAX"), stop: bool = True,
            on_error: str = "finding", progress: bool | None = None) -> FalsificationResult:
    """Search ``space`` for a run on which ``claim``'s margin is negative.

    Parameters
    ----------
    run : callable
        ``run(point) -> HybridArc`` for one point of ``space``
        (:class:`Point`: the entries' values by name); or, when it has an
        attribute ``batch = True`` (:func:`batch_run`), ``run(points) ->
        list of HybridArc`` for a whole population at once.
    space : Space
        What may vary.
    claim : callable
        ``claim(arc) -> margin``: a real number, positive when the claim
        holds on the arc, negative when violated (the ``margin_*`` functions
        of :mod:`hybridsim.testing` return one, with the (t, j) that decided
        it as ``.where``).
    budget : int
        At most this many runs (>= 1).
    seconds : float
        At most this long: checked after every run, and a population run is
        split into chunks expected to end before the deadline, so the search
        overshoots it by at most one chunk of runs.
    seed : int, optional
        The search is reproducible with it.
    method : {"de", "cmaes", "random"}
        ``"de"``: differential evolution (scipy, ``vectorized=True``: each
        generation is one population evaluated at once, deferred updating;
        the first population is run first in this order: the entries'
        extreme members that are not vertices of the box (up to an eighth
        of it: :meth:`Sinusoids.extremes`, the constant signals at ±bound,
        lie on the face f = 0), vertices of the box (a quarter), points on
        its faces and edges (an eighth: each coordinate at a bound with
        probability 1/2), then a Latin hypercube; worst cases under bounded
        uncertainty often lie on the boundary), then a compass search from
        the worst point with what is left of the budget (``refine``: a
        fifth of it is kept for this; each of its iterations, a step along
        every coordinate both ways, and while that does best, every
        coordinate to each of its bounds, is one population too).
        ``FalsificationResult.found_by`` says which of these found the
        worst run. When DE converges before the budget is
        spent (its population collapsed on one point), it restarts with a
        new seed on what is left, so a search that finds nothing has used
        its budget. The first population is run before scipy's solver is
        set up, so a claim its first runs refute costs no solver.
        When a population's margins are all equal (a flat margin: no
        ranking to follow), DE has converged and restarts on fresh designs,
        and the compass search stops.
        ``"cmaes"``: CMA-ES (numpy; Hansen's (mu/mu_w, lambda) strategy with
        his default parameters) over the box scaled to [0, 1], after the
        same seeded first design (``max(2 lambda, 2 dim)`` points) whose
        best point is its first mean, step 0.3; candidates are clipped
        into the box for their runs (a worst case on a face is reached
        exactly), and the distribution is updated from them as drawn, its
        mean at most one of its standard deviations past a face in each
        coordinate (most of its samples then land on a face the margin
        favours: on CC4 of :mod:`hybridsim.arch`, instance 1, 10/10 within
        1,500 runs where clipped updates found 8/10). Where the
        space has signals (:class:`PiecewiseConstant`, :class:`ControlPoints`)
        the runs go coarse to fine: first with the signals on grids 4 and 2
        times coarser (:meth:`Space.coarse`, a subset of the box where a
        signal held at a bound over a long stretch is one coordinate at its
        bound; a third of the first design is drawn there), then on the
        space itself, each from the best point so far with the last run's
        step and the shape of its distribution (its covariance mapped onto
        the finer grid). A coarse run ends at its share (``budget / (2
        grids)``) or at its grid's own optimum, and hands on the best point
        snapped to the box's bounds (two runs: a bang-bang input the coarse
        grid approached); the space's own run ends at ``budget / grids``.
        It restarts through
        the same chain of grids, with the population doubled each cycle
        (IPOP), from the best of a fresh design on the coarsest grid (a
        space without signals: from a uniformly drawn mean), each finer
        grid from the restart's own best point, when a run converges,
        stalls, meets a margin flat over three populations (each widening
        its step first), or spends its share; ``refine`` does not apply. On the
        ARCH-COMP benchmarks (:mod:`hybridsim.arch`) it needs fewer runs than
        DE to the first counterexample.
        ``"random"``: uniform sampling of the box in populations, the
        baseline to compare with.
    popsize : int, optional
        Population size (default ``max(15, 5 * space.dim)`` for DE, at least
        5; ``4 + floor(3 ln n)`` for CMA-ES, n the free coordinates; 100 for
        random), capped by the budget.
    refine : bool or "gradient"
        Refine the worst point locally by compass search (``"de"`` only).
        ``"gradient"``: by projected gradient descent instead, where ``run``
        has an attribute ``sensitivity``, a callable ``point ->``
        :class:`hybridsim.sensitivity.SensitivityArc` whose parameters are
        the space's coordinates (``hs.simulate_sensitivity(make, x0, ...,
        params=point.z, wrt="params")``); the margin's gradient comes from
        :func:`hybridsim.sensitivity.margin_gradient`, one run a step. Where
        a sensitivity is not defined (a grazing jump...) it falls back to
        the compass search.
    allow : iterable of str
        Termination causes that are ordinary ends of a run; any other cause
        (a blow-up, a map error, a run that raised) is a finding: recorded
        in ``findings`` with its point and counted as margin -inf.
        ``CANCELED`` is neither: a run Ctrl-C cut short ends the search.
    stop : bool
        Stop at the first counterexample (default); False searches the whole
        budget for the worst one.
    on_error : {"finding", "stop", "raise"}
        What a failure of the user's code at a point does: a run that raises
        (or a population run that raises: each of its chunk's points), a run
        that returns something other than a :class:`hybridsim.HybridArc`, a
        claim that raises on a run's arc. ``"finding"`` (default, as for a
        run ending on a failure cause): recorded in ``findings`` with its
        point, cause (``"RAISED"``, ``"NOT_AN_ARC"``, ``"CLAIM_RAISED"``)
        and the exception (type, text, where; the claim or run named), and
        counted as margin -inf. ``"stop"``: the search ends there with the
        results so far (``stopped == "error"``, the failure in ``error``).
        ``"raise"``: the exception propagates at once, a note naming the
        point. A worker of a population run's executor that dies
        (:class:`concurrent.futures.BrokenExecutor`: a process-pool worker
        killed, out of memory...) loses its chunk's points (cause
        ``"WORKER_DIED"``, not re-run: a point that kills its worker would
        kill the next one too); the search goes on with the history and the
        worst point so far, on a fresh pool from ``run.renew()``
        (:func:`batch_run`'s runs have one), or ends there
        (``stopped == "error"``) when the run cannot renew its executor.
    progress : bool, optional
        A progress bar over the runs (default: when stderr is a terminal).

    Returns
    -------
    FalsificationResult
        ``stopped`` says why the search ended. Ctrl-C (KeyboardInterrupt,
        inside a run or between runs) ends it with the results of the runs
        finished before: ``stopped == "interrupted"``, ``interrupted`` True;
        the run it cut short (``CANCELED``) is neither judged nor a finding.

    Raises
    ------
    TypeError, ValueError
        A bad argument (named), or a claim that does not return a real number
        (or returns NaN), raised after the search with the point named.

    Notes
    -----
    CMA-ES follows N. Hansen, "The CMA Evolution Strategy: A Tutorial"
    (arXiv:1604.00772), with IPOP restarts (Auger and Hansen, CEC 2005).
    Differential evolution is scipy's (:func:`scipy.optimize.differential_evolution`):
    derivative-free, global, and it evaluates whole generations at once,
    which is what the batch paths make cheap; PSY-TaLiRo and S-TaLiRo
    default to similar population or annealing searches run one simulation
    at a time.
    """
    if not isinstance(space, Space):
        raise TypeError(f"space must be a hybridsim.falsification.Space, "
                        f"got {type(space).__name__}")
    if not callable(run):
        raise TypeError(f"run must be callable (point -> arc), got {type(run).__name__}")
    if not callable(claim):
        raise TypeError(f"claim must be callable (arc -> margin), got {type(claim).__name__}")
    if isinstance(budget, bool) or not isinstance(budget, (numbers.Integral, np.integer)) \
            or budget < 1:
        raise ValueError(f"budget must be a positive number of runs, got {budget!r}")
    seconds = float(seconds)
    if not seconds > 0:
        raise ValueError(f"seconds must be > 0, got {seconds}")
    if method not in ("de", "cmaes", "random"):
        raise ValueError(f"method must be 'de', 'cmaes' or 'random', got {method!r}")
    if not (refine is True or refine is False or refine == "gradient"):
        raise ValueError(f"refine must be True, False or 'gradient', got {refine!r}")
    if refine == "gradient" and not callable(getattr(run, "sensitivity", None)):
        raise ValueError("refine='gradient' needs run.sensitivity: a callable point -> "
                         "SensitivityArc whose parameters are the space's coordinates "
                         "(hs.simulate_sensitivity(make, x0, ..., params=point.z, "
                         "wrt='params'))")
    if on_error not in ("finding", "stop", "raise"):
        raise ValueError(f"on_error must be 'finding', 'stop' or 'raise', got {on_error!r}")
    allow = frozenset(allow)
    unknown = allow - {c.name for c in Termination}
    if unknown:
        raise ValueError(f"allow names unknown termination causes {sorted(unknown)}")
    budget = int(budget)
    if popsize is not None and (isinstance(popsize, bool) or not isinstance(
            popsize, (numbers.Integral, np.integer)) or popsize < 1):
        raise ValueError(f"popsize must be a positive integer or None, got {popsize!r}")
    if popsize is None and method != "cmaes":
        popsize = max(15, 5 * space.dim) if method == "de" else 100
    if popsize is not None:
        popsize = max(1, min(int(popsize), budget))
    t0 = time.perf_counter()
    ev = _Evaluator(run, space, claim, budget, seconds, allow, progress, stop, on_error)
    fixed = not np.any(space.hi > space.lo)          # a space of one point: one run
    try:
        if fixed:
            ev.stages.append((0, "the space's one point"))
            ev(space.lo[None, :])
        elif method == "random":
            ev.stages.append((0, "random sampling"))
            rng = np.random.default_rng(seed)
            while not ev.done:
                n = min(popsize, budget - ev.n)
                ev(space.lo + (space.hi - space.lo) * rng.random((n, space.dim)))
        elif method == "cmaes":
            _cmaes(ev, space, popsize, seed)
        else:
            seeds = np.random.SeedSequence(seed)
            round_seed, rounds = seed, 0
            while not ev.done:              # restarts while DE converges early
                before = ev.n
                left = budget - before
                _de(ev, space, popsize, round_seed, left - (left // 5 if refine else 0),
                    rnd=rounds)
                rounds += 1
                # a round whose margins all tied has no worst point to refine
                flat = ev.n > before and np.ptp(ev.history[before:]) == 0
                if refine and not ev.done and ev.best_z is not None and not flat:
                    if refine == "gradient":
                        _refine_gradient(ev, space, run.sensitivity)
                    else:
                        _refine(ev, space)
                if ev.n == before:
                    break
                round_seed = int(seeds.spawn(1)[0].generate_state(1)[0])
    except KeyboardInterrupt:               # Ctrl-C between runs, or in the claim
        ev.interrupted = True
    finally:
        ev.close()
    if ev.error is not None:
        raise ev.error
    point = space.point(ev.best_z if ev.best_z is not None else (space.lo + space.hi) / 2)
    arc = ev.best_arc                       # kept as it was judged: no second run
    if arc is None and ev.n and not ev.interrupted and ev.failure is None:
        try:
            arc = run([point])[0] if ev.batch else run(point)
        except (Exception, KeyboardInterrupt):  # noqa: BLE001 - the finding records it
            arc = None
        if not isinstance(arc, HybridArc):
            arc = None
    found = ev.best < 0
    found_by = ""
    if ev.n:
        k = int(np.argmin(ev.history))
        what = [label for first_run, label in ev.stages if first_run <= k]
        found_by = f"{what[-1] if what else method}, run {k + 1} of {ev.n}"
    if ev.interrupted:
        stopped = "interrupted"
    elif ev.failure is not None:
        stopped = "error"
    elif ev.found:
        stopped = "counterexample"
    elif ev.n >= budget:
        stopped = "budget"
    elif time.perf_counter() >= ev.deadline:
        stopped = "seconds"
    else:
        stopped = "converged"
    return FalsificationResult(
        verdict="counterexample" if found else "none found", margin=float(ev.best),
        point=point, arc=arc, where=ev.best_where, history=ev.history.copy(),
        evaluations=ev.n, seconds=time.perf_counter() - t0,
        findings=list(ev.findings), method=method, seed=seed, stopped=stopped,
        error=ev.failure, found_by=found_by)
