"""Many runs: initial conditions, noise realisations, parameter sweeps.

A batch keeps going when one of its runs fails. A row whose map raises at its
initial state, whose initial state is not finite, or whose run ends on a
failure (``MAP_ERROR``, ``NON_FINITE``, ``BLOWUP``, ``SOLVER_FAILED``,
``MAX_STEPS``) gets an arc of its own carrying the cause; the other rows'
results are kept, and one :class:`BatchWarning` names the failed rows. With
``throw=True`` the first failed row raises :class:`BatchError` instead.

Ctrl-C (KeyboardInterrupt) during a batch stops launching runs: every finished
run is kept, the run under way ends with ``Termination.CANCELED`` (and the arc
so far), runs never started get a one-sample ``CANCELED`` arc at their initial
state, and the list of N arcs is returned with one warning.
"""
from __future__ import annotations

import concurrent.futures
import itertools
import numbers
import operator
import warnings
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ._progress import make_bar
from .arc import HybridArc
from .options import method_on
from .rules import FAILURES, MapError, SimulationError, SimulationWarning, Termination
from .system import HybridSystem

# hybridsim.solve is imported where a row runs (``_run_row``), so that the
# integration paths (batch_vectorized, compiled) can import finish_batch from
# here without importing solve.py

__all__ = ["BatchError", "BatchWarning", "simulate_many", "sweep", "finish_batch"]

#: causes that make a row "failed" in a batch (named in the summary warning)
FAILED = frozenset(FAILURES | {Termination.MAX_STEPS})
_SHOW = 5               # failed rows named one by one in the summary
#: seconds a batch waits, after Ctrl-C, for executor chunks under way to come back
GRACE = 2.0


class BatchWarning(SimulationWarning):
    """Some runs of a batch failed or were canceled; the message names the rows.

    Each failed row's arc carries its cause (``arc.termination``,
    ``arc.message``, ``arc.exception``).
    """


class BatchError(SimulationError):
    """A run of a batch failed and the batch was called with ``throw=True``.

    Attributes
    ----------
    row : int
        Index of the failed row (its place in ``x0s`` or ``params``).
    arc : HybridArc
        That row's arc (its cause in ``arc.termination``/``arc.exception``).
    arcs : list of HybridArc or None
        The batch's arcs so far, in row order (None for rows not run).
    """

    def __init__(self, message, row=None, arc=None, arcs=None):
        super().__init__(message, arc)
        self.row, self.arcs = row, arcs


# ------------------------------------------------------------------ arguments
def _check_chunks(chunks):
    if chunks is None:
        return None
    if isinstance(chunks, bool) or not isinstance(chunks, numbers.Integral):
        raise TypeError(f"chunks must be a positive int or None (default: 4 per worker), "
                        f"got {type(chunks).__name__} {chunks!r}")
    if chunks < 1:
        raise ValueError(f"chunks must be a positive int or None (default: 4 per worker), "
                         f"got {chunks}")
    return int(chunks)


def _check_executor(executor):
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise TypeError(f"executor must be a concurrent.futures.Executor (an object with a "
                        f".submit method, e.g. ProcessPoolExecutor()) or None, got "
                        f"{type(executor).__name__} {executor!r}")


def _check_bool(name, v):
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    raise TypeError(f"{name} must be True or False, got {type(v).__name__} {v!r}")


def _as_rows(x0s, n):
    """x0s as an (N, n) float array, with messages naming x0s."""
    try:
        if np.iscomplexobj(x0s):
            raise TypeError("x0s must be real, got complex values")
        X = np.array(x0s, dtype=float)
    except (TypeError, ValueError) as e:
        if "x0s must be real" in str(e):
            raise
        detail = ""
        if isinstance(x0s, (list, tuple)):
            shapes = []
            for i, r in enumerate(x0s):
                try:
                    s = np.shape(r)
                except ValueError:
                    s = "ragged"
                if s != (n,):
                    shapes.append(f"row {i} has shape {s}")
            if not shapes:
                shapes = ["its rows do not form an array of floats"]
            if shapes:
                detail = ": " + ", ".join(shapes[:_SHOW]) + \
                    (f" and {len(shapes) - _SHOW} more" if len(shapes) > _SHOW else "")
        raise ValueError(f"x0s must be a rectangular array of shape (N, {n}) of floats (one "
                         f"initial state per row){detail or f'; got {type(x0s).__name__}'}") \
            from e
    if X.ndim != 2 or X.shape[1] != n:
        raise ValueError(f"x0s must have shape (N, {n}), got {X.shape}")
    return X


def _check_params(params):
    if isinstance(params, (str, bytes)) or not isinstance(params, Iterable):
        raise TypeError(f"params must be an iterable of parameter values (a list, a range, "
                        f"an array...), got {type(params).__name__} {params!r}")
    return list(params)


# ------------------------------------------------------------------ one row
def _one_sample(x0, kwargs, cause, detail, exc=None, system=None):
    """A one-sample arc at (t0, j0, x0) ending with ``cause`` (x0 None: unknown)."""
    try:
        x = np.empty((1, 0)) if x0 is None else np.array(x0, dtype=float).reshape(1, -1)
    except (TypeError, ValueError):
        x = np.empty((1, 0))
    return HybridArc([float(kwargs.get("t0", 0.0))], [int(kwargs.get("j0", 0))], x, cause,
                     f"{cause.message}: {detail}", exc,
                     components=getattr(system, "components", None), system=system)


def _nonfinite(x0):
    try:
        x = np.asarray(x0, dtype=float)
    except (TypeError, ValueError):
        return False
    return not np.all(np.isfinite(x))


def _run_row(system, make_system, p, x0, kwargs):
    """One run of a batch: ``(arc, stop)``; stop is True when it was interrupted.

    Failures of the user's code at x0 (``make_system(p)``, ``x0(p)``, a map
    raising at x0) and non-finite x0 become one-sample arcs with their cause.
    Argument errors raised by :func:`simulate` (the same for every row)
    propagate.
    """
    from .solve import simulate
    try:
        if make_system is not None:
            try:
                system = make_system(p)
                if callable(x0):
                    x0 = x0(p)
            except (KeyboardInterrupt, SystemExit):
                raise
            except Exception as e:  # noqa: BLE001 - the user's code: a failed row
                return _one_sample(x0 if not callable(x0) else None, kwargs,
                                   Termination.MAP_ERROR,
                                   f"building the run for p={p!r} raised "
                                   f"{type(e).__name__}: {e}", e), False
        if _nonfinite(x0):
            return _one_sample(x0, kwargs, Termination.NON_FINITE,
                               f"the initial state is not finite: {np.asarray(x0)}",
                               ValueError(f"x0 must be finite, got {np.asarray(x0)}"),
                               system), False
        arc = simulate(system, x0, **kwargs)
    except KeyboardInterrupt:
        return _one_sample(x0 if not callable(x0) else None, kwargs, Termination.CANCELED,
                           "interrupted at the initial state", None, system), True
    except SimulationError as e:          # a map failed at x0 (MapError), or the engine
        if isinstance(e.__cause__, KeyboardInterrupt):
            return _one_sample(x0, kwargs, Termination.CANCELED,
                               "interrupted at the initial state", None, system), True
        cause = Termination.MAP_ERROR if isinstance(e, MapError) else Termination.SOLVER_FAILED
        return _one_sample(x0, kwargs, cause, str(e), e, system), False
    return arc, arc.termination is Termination.CANCELED


def _never_started(x0, kwargs, system=None):
    return _one_sample(None if callable(x0) else x0, kwargs, Termination.CANCELED,
                       "never started (the batch was interrupted)", None, system)


def _run_chunk(system, make_system, items, kwargs):
    """Rows ``items`` = [(p, x0)] of a batch, in a worker; stops on Ctrl-C."""
    out = []
    for k, (p, x0) in enumerate(items):
        arc, stop = _run_row(system, make_system, p, x0, kwargs)
        out.append(arc)
        if stop:
            out.extend(_never_started(x, kwargs, system) for _, x in items[k + 1:])
            break
    return out


# ------------------------------------------------------------------ the loop
class _Batch:
    """Runs rows serially or over an executor; keeps every finished arc."""

    def __init__(self, system, make_system, items, kwargs, throw, bar):
        self.system, self.make_system = system, make_system
        self.items, self.kwargs, self.throw, self.bar = items, kwargs, throw, bar
        self.out = [None] * len(items)
        self.interrupted = False

    def _store(self, i, arc):
        self.out[i] = arc
        if self.bar is not None:
            self.bar.update(1)
        if arc.termination is Termination.CANCELED:
            self.interrupted = True
        if self.throw and arc.termination in FAILED:
            raise BatchError(f"row {i} of the batch failed: {arc.termination.name}: "
                             f"{arc.message}", i, arc, self.out) from arc.exception

    def fill(self, todo):
        """Rows of ``todo`` still without an arc: canceled (never started)."""
        for i in todo:
            if self.out[i] is None:
                _, x0 = self.items[i]
                self.out[i] = _never_started(x0, self.kwargs,
                                             self.system if self.make_system is None else None)

    def serial(self, todo):
        try:
            for i in todo:
                p, x0 = self.items[i]
                try:
                    arc, stop = _run_row(self.system, self.make_system, p, x0, self.kwargs)
                except (TypeError, ValueError) as e:     # an argument error: raise at once
                    e.add_note(f"(raised by simulate in row {i} of the batch)")
                    raise
                self._store(i, arc)
                if stop:
                    break
        except KeyboardInterrupt:
            self.interrupted = True
        self.fill(todo)

    def spread(self, executor, todo, chunks):
        workers = getattr(executor, "_max_workers", None) or 2
        k = min(len(todo), chunks or 4 * workers)
        bounds = np.linspace(0, len(todo), k + 1).astype(int)
        parts = [todo[a:b] for a, b in itertools.pairwise(bounds) if b > a]
        futs = []
        try:
            for part in parts:
                futs.append((part, executor.submit(
                    _run_chunk, self.system, self.make_system,
                    [self.items[i] for i in part], self.kwargs)))
            errors = []
            for part, fut in futs:
                if self.interrupted:
                    break
                try:
                    res = fut.result()
                except KeyboardInterrupt:
                    raise
                except Exception as e:  # noqa: BLE001 - the executor lost this chunk
                    errors.append(e)
                    for i in part:
                        self._store(i, _one_sample(
                            self.items[i][1], self.kwargs, Termination.MAP_ERROR,
                            f"the executor failed on this row's chunk: "
                            f"{type(e).__name__}: {e}", e,
                            self.system if self.make_system is None else None))
                    continue
                for i, arc in zip(part, res, strict=True):
                    self._store(i, arc)
            if errors and len(errors) == len(futs):
                raise errors[0]          # nothing ran (e.g. the system does not pickle)
        except KeyboardInterrupt:
            self.interrupted = True
        except BaseException:
            for _, fut in futs:
                fut.cancel()
            raise
        if self.interrupted:
            self._drain(futs)
        self.fill(todo)

    def _drain(self, futs):
        """After Ctrl-C: cancel chunks not started, keep those that finish soon.

        Workers at the same terminal get the Ctrl-C too and return their
        chunk (the run under way CANCELED) at once; chunks that do not come
        back within ``GRACE`` seconds (queued in a worker, or on a remote
        cluster) are abandoned: their rows end CANCELED at x0.
        """
        pending = [(part, fut) for part, fut in futs if not fut.cancel()
                   and self.out[part[0]] is None]
        if not pending:
            return
        try:
            done, _ = concurrent.futures.wait([f for _, f in pending], timeout=GRACE)
        except KeyboardInterrupt:            # a second Ctrl-C: stop waiting
            done = {f for _, f in pending if f.done()}
        for part, fut in pending:
            if fut not in done:
                fut.cancel()
                continue
            try:
                res = fut.result()
            except Exception:  # noqa: BLE001 - a broken pool after Ctrl-C
                continue
            for i, arc in zip(part, res, strict=True):
                if self.out[i] is None:
                    self.out[i] = arc


_TERMINATION = operator.attrgetter("termination")


def _summary(what, arcs, offset=0):
    """One warning text for the failed and canceled rows, or None."""
    # by identity (an Enum member hashes in Python code: 0.3 µs a row)
    bad, stop = {id(c) for c in FAILED}, id(Termination.CANCELED)
    terms = list(map(id, map(_TERMINATION, arcs)))
    if bad.isdisjoint(terms) and stop not in terms:     # the common case: one pass
        return None
    failed = [(i, arcs[i]) for i, c in enumerate(terms) if c in bad]
    canceled = [i for i, c in enumerate(terms) if c == stop]
    parts = []
    if failed:
        named = []
        for i, a in failed[:_SHOW]:
            msg = a.message or a.termination.message
            if isinstance(a.exception, SimulationError):      # names the map already
                msg = str(a.exception)
            elif a.exception is not None:
                msg = f"{type(a.exception).__name__}: {a.exception}"
            msg = " ".join(str(msg).split())
            if len(msg) > 160:
                msg = msg[:157] + "..."
            named.append(f"row {i}: {a.termination.name} ({msg})")
        more = f"; and {len(failed) - _SHOW} more" if len(failed) > _SHOW else ""
        parts.append(f"{len(failed)} of {len(arcs)} runs failed: " + "; ".join(named) + more
                     + ". Each failed row's arc carries its cause (arc.termination, "
                       "arc.message, arc.exception); pass throw=True to raise at the first "
                       "failure instead")
    if canceled:
        rows = canceled if len(canceled) <= 2 * _SHOW else \
            [*canceled[:_SHOW], "...", *canceled[-1:]]
        finished = len(arcs) - len(canceled)
        parts.append(f"interrupted (KeyboardInterrupt): {finished} of {len(arcs)} runs finished, "
                     f"rows {', '.join(map(str, rows))} end with CANCELED (the arc so far, or "
                     f"one sample at x0 for rows never started)")
    if not parts:
        return None
    return f"{what}: " + ". ".join(parts) + "."


# ------------------------------------------------------------------ public
def simulate_many(system: HybridSystem, x0s: ArrayLike, t_max: float,
                  j_max: float = np.inf, *, executor: concurrent.futures.Executor | None = None,
                  chunks: int | None = None, progress: bool | None = None,
                  throw: bool = False, warn: bool = True, **kwargs) -> list[HybridArc]:
    """Simulate one system from many initial states.

    Parameters
    ----------
    system : HybridSystem
        With ``vectorized = True`` (maps written over (N, n) batches), no
        executor and options the batch integrator implements (``method=
        "RK45"``, the default, or ``"DOP853"`` where the system does not read
        its past; no ``dense``, ``inputs``, ``prehistory`` or ``t_eval``),
        the whole batch is integrated together in numpy
        (:func:`hybridsim.batch_vectorized.simulate_vectorized`), each
        trajectory with its own steps, events and jumps. Otherwise the runs
        are looped over (or spread over ``executor``) with
        :func:`hybridsim.simulate`, which passes the maps single states (so
        write a vectorized system's maps with ``x[..., k]`` to allow both).
    x0s : array_like, shape (N, n)
        One initial state per row (a rectangular array: ragged lists are
        refused with the rows at fault named).
    t_max, j_max : float, int
        As in :func:`hybridsim.simulate`.
    executor : concurrent.futures.Executor, optional
        Any object with ``.submit`` (``ProcessPoolExecutor``, a
        ``dask.distributed`` client's ``get_executor()``...). The batch is
        split into ``chunks`` and the system is pickled to each.
    chunks : int, optional
        Number of pieces the batch is split into for the executor (a
        positive int; default: 4 per worker, at most N).
    progress : bool or None
        A progress bar over runs (None: at a terminal and in a notebook;
        see :func:`hybridsim._progress.progress_enabled`). Each run's own
        bar is switched off.
    throw : bool
        False (default): a failed row (a map raising at its x0, a non-finite
        x0, a run ending with ``MAP_ERROR``, ``NON_FINITE``, ``BLOWUP``,
        ``SOLVER_FAILED`` or ``MAX_STEPS``) gets its own arc with the cause,
        the batch goes on and one :class:`BatchWarning` names the failed
        rows. True: raise :class:`BatchError` at the first failed row,
        naming it.
    warn : bool
        Issue the summary warning (default True). Single runs never warn on
        their own inside a batch.
    **kwargs
        Passed to :func:`hybridsim.simulate` (``priority``, ``rtol``...).
        Argument errors (the same for every row) raise at once.
        ``backend="compiled"`` (no executor) runs the batch compiled and
        in parallel over the cores (:func:`hybridsim.compiled.simulate_many_compiled`):
        a :class:`hybridsim.compiled.CompiledSystem`, or a system lowered to
        one (:func:`hybridsim.compiled.lower`: a ``LinearPlant``, systems
        with a compiled form, interconnections of them wired by
        :class:`hybridsim.LinearInput`; others are refused by name).
        ``backend="auto"`` runs compiled where numba is installed, the
        system lowers and the options are the compiled path's (RK45 or
        DOP853; no ``dense``, ``inputs``, ``prehistory``, ``t_eval``,
        executor), and as
        ``"python"`` otherwise; a structure's maps compile once per process
        (seconds), so it pays for batches of hundreds of runs and more.

    Returns
    -------
    list of HybridArc
        One arc per row of ``x0s``, in order. A row that failed before
        flowing has a one-sample arc at (t0, j0, x0) with cause
        ``MAP_ERROR`` or ``NON_FINITE`` and the error in ``arc.exception``.
        After Ctrl-C the list is still complete: finished runs are kept, the
        run under way and the runs never started end with ``CANCELED``. With
        an executor, chunks not started are canceled and the batch waits
        ``hybridsim.batch.GRACE`` (2) seconds for chunks under way (workers
        at the same terminal get the Ctrl-C too and return at once); rows of
        chunks that do not come back end ``CANCELED`` at x0.

    Raises
    ------
    BatchError
        ``throw=True`` and a row failed (``.row``, ``.arc``, ``.arcs``).
    TypeError, ValueError
        Bad arguments (``x0s``, ``chunks``, ``executor``...), each named.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> decay = hs.HybridSystem.from_functions(f=lambda x: -x, state_dim=1)
    >>> arcs = hs.simulate_many(decay, [[1.0], [2.0]], t_max=1.0, rtol=1e-10, atol=1e-12)
    >>> [round(float(a.xf[0]), 6) for a in arcs]
    [0.367879, 0.735759]
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     arcs = hs.simulate_many(decay, [[1.0], [np.nan]], t_max=1.0)
    >>> [a.termination.name for a in arcs], len(w)
    (['T_MAX', 'NON_FINITE'], 1)
    """
    if not isinstance(system, HybridSystem):
        raise TypeError(f"system must be a HybridSystem, got {type(system).__name__}")
    _check_executor(executor)
    chunks = _check_chunks(chunks)
    throw = _check_bool("throw", throw)
    warn = _check_bool("warn", warn)
    n = int(system.state_dim)
    X = _as_rows(x0s, n)
    N = len(X)
    if N == 0:
        return []
    if kwargs.get("seed") is not None and any(
            getattr(system, k, None) is not None for k in ("diffusion", "jump_rate", "jump_law")):
        raise ValueError(f"seed: simulate_many passes one seed to every row, so every row of "
                         f"{type(system).__name__} (it draws noise: diffusion, jump_rate or "
                         f"jump_law) would draw the same; run seeded rows with "
                         f"hybridsim.estimate.accumulate or estimate (a generator per run), or "
                         f"hs.sweep over seeds")
    kwargs = dict(kwargs, t_max=t_max, j_max=j_max, progress=False)
    if kwargs.get("backend") == "auto":
        kwargs["backend"] = _auto_backend(system, kwargs, executor)
    if kwargs.get("backend") == "python":
        del kwargs["backend"]               # the default: the batch integrator may take it
    if kwargs.get("backend", "python") == "compiled" and executor is None:
        from .compiled import simulate_many_compiled
        from .compiled._lower import lower, rebind
        kw = {k: v for k, v in kwargs.items() if k not in ("backend", "progress")}
        out = simulate_many_compiled(lower(system), X, throw=False, warn=False, **kw)
        out = [rebind(a, system) for a in out]
        return finish_batch("simulate_many", out, throw, warn)
    if system.vectorized and executor is None and _batch_takes(system, kwargs):
        out = _many_vectorized(system, X, kwargs, progress)
        return finish_batch("simulate_many", out, throw, warn)
    else:
        kwargs.update(throw=False, warn=False)
        items = [(None, x0) for x0 in X]
        bar = make_bar(progress, total=N, desc="simulate_many", unit="run", leave=True)
        out = _execute(_Batch(system, None, items, kwargs, throw, bar), executor, chunks, bar)
    return _warned("simulate_many", out, warn)


#: options the compiled path runs (beyond those every path shares) at these values
#: only (its methods: :data:`hybridsim.options.METHODS_ON`)
_COMPILED_ONLY_AT = {"inputs": (None,), "prehistory": (None,),
                     "dense": (False,), "t_eval": (None,), "dwell": (None,)}


def _auto_backend(system, kwargs, executor):
    """``backend="auto"``: "compiled" where numba is installed, the system runs
    compiled (:func:`hybridsim.compiled.lowerable`) and the options are the
    compiled path's; "python" otherwise (which integrates a vectorized
    system's batch together)."""
    import importlib.util

    from .compiled import lowerable
    if executor is not None or importlib.util.find_spec("numba") is None \
            or any(getattr(system, k, None) is not None         # Python path only
                   for k in ("diffusion", "jump_rate", "jump_law")):
        return "python"
    if any(kwargs.get(k, v[0]) not in v for k, v in _COMPILED_ONLY_AT.items()):
        return "python"
    try:
        method_on("compiled", kwargs.get("method"), system)
    except (TypeError, ValueError):
        return "python"
    return "compiled" if lowerable(system) else "python"


def _raise_first_failure(out):
    """``throw=True`` on a batch that ran in one piece: the first failed row raises."""
    for i, arc in enumerate(out):
        if arc.termination in FAILED:
            raise BatchError(f"row {i} of the batch failed: {arc.termination.name}: "
                             f"{arc.message}", i, arc, out) from arc.exception


def finish_batch(name, arcs, throw, warn, stacklevel=3):
    """The batch policy, applied once a batch has run: the same on every path.

    Every row has run and every failed row keeps its arc and cause (one of
    :data:`FAILED`). ``throw=True`` raises :class:`BatchError` (``.row``,
    ``.arc``, ``.arcs``) for the first failed row; otherwise ``warn=True``
    issues one :class:`BatchWarning` naming the failed (and canceled) rows.
    Used by :func:`simulate_many`, :func:`hybridsim.simulate_vectorized` and
    the compiled batch; this module imports no integration path at import
    time, so each can import this function.

    Parameters
    ----------
    name : str
        The entry point named in the warning (``"simulate_many"``...).
    arcs : list of HybridArc
        One per row, in order.
    throw, warn : bool
    stacklevel : int
        Of the warning: 3 points at the caller of the function that calls
        ``finish_batch``.

    Returns
    -------
    list of HybridArc
        ``arcs``.
    """
    if throw:
        _raise_first_failure(arcs)
    return _warned(name, arcs, warn, stacklevel + 1)


def _execute(batch, executor, chunks, bar):
    """Run every row of ``batch`` here or on ``executor``; the arcs, in order."""
    rows = list(range(len(batch.out)))
    try:
        if executor is None:
            batch.serial(rows)
        else:
            batch.spread(executor, rows, chunks)
    finally:
        if bar is not None:
            bar.close()
    return batch.out


def _warned(name, out, warn, stacklevel=3):
    """One BatchWarning summarising the failed rows (if any and if asked)."""
    if warn:
        msg = _summary(name, out)
        if msg:
            warnings.warn(msg, BatchWarning, stacklevel=stacklevel)
    return out


def _batch_takes(system, kwargs):
    from .batch_vectorized import takes_options
    return takes_options(kwargs, system)


def _many_vectorized(system, X, kwargs, progress):
    """The vectorized path, row failures at x0 isolated (see simulate_many)."""
    from .batch_vectorized import simulate_vectorized
    kwargs = dict(kwargs, progress=progress, throw=False, warn=False)
    N = len(X)
    out = [None] * N
    try:
        _vectorized_rows(simulate_vectorized, system, X, kwargs, out)
    except KeyboardInterrupt:       # during a probe: keep what is known
        pass
    for i in range(N):
        if out[i] is None:
            out[i] = _never_started(X[i], kwargs, system)
    return out


def _vectorized_rows(simulate_vectorized, system, X, kwargs, out):
    good = []
    N = len(X)
    for i in range(N):
        if _nonfinite(X[i]):
            out[i] = _one_sample(X[i], kwargs, Termination.NON_FINITE,
                                 f"the initial state is not finite: {X[i]}",
                                 ValueError(f"x0s row {i} must be finite, got {X[i]}"), system)
        else:
            good.append(i)
    while good:
        try:
            arcs = simulate_vectorized(system, X[good], **kwargs)
        except MapError as err:
            # which rows fail at x0? probe each alone (no flow: t_max = t0, j_max = 0)
            probe = dict(kwargs, t_max=kwargs.get("t0", 0.0), j_max=0, progress=False)
            bad = []
            for i in good:
                try:
                    simulate_vectorized(system, X[i:i + 1], **probe)
                except MapError as e:
                    bad.append(i)
                    out[i] = _one_sample(X[i], kwargs, Termination.MAP_ERROR, str(e), e, system)
            if not bad:
                raise err          # only the whole batch fails: the maps are not vectorized
            good = [i for i in good if out[i] is None]
            continue
        for i, arc in zip(good, arcs, strict=True):
            out[i] = arc
        break


def sweep(make_system: Callable[[Any], HybridSystem], params: Iterable, x0: ArrayLike | Callable,
          t_max: float, j_max: float = np.inf, *,
          executor: concurrent.futures.Executor | None = None, chunks: int | None = None,
          progress: bool | None = None, throw: bool = False, warn: bool = True,
          **kwargs) -> list[HybridArc]:
    """Simulate ``make_system(p)`` from x0 for every parameter value p.

    Noise realisations go through the same door: let ``p`` be a seed and
    ``make_system`` build the plant with that realisation.

    Parameters
    ----------
    make_system : callable
        ``p -> HybridSystem`` (picklable when an executor is used).
    params : iterable
        Parameter values (a list, range, array...; not a string).
    x0 : array_like, shape (n,), or callable ``p -> x0``
        The initial state, or a function of p giving it (with an executor
        it is called in the worker, so it must pickle: a module-level
        function, not a lambda).
    t_max, j_max : float, int
        As in :func:`hybridsim.simulate`.
    executor, chunks, progress, throw, warn
        As in :func:`simulate_many`. A failure of ``make_system(p)`` or
        ``x0(p)`` is a failed row (cause ``MAP_ERROR``) like a map raising.
    **kwargs
        Passed to :func:`hybridsim.simulate`.

    Returns
    -------
    list of HybridArc
        One per parameter value, in order (see :func:`simulate_many` for
        failed and canceled rows).

    Raises
    ------
    BatchError
        ``throw=True`` and a row failed.
    TypeError, ValueError
        Bad arguments, each named.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> make = lambda a: hs.HybridSystem.from_functions(f=lambda x: -a * x, state_dim=1)
    >>> arcs = hs.sweep(make, [1.0, 2.0], [1.0], t_max=1.0, rtol=1e-10, atol=1e-12)
    >>> [round(float(a.xf[0]), 6) for a in arcs]
    [0.367879, 0.135335]
    """
    if not callable(make_system):
        raise TypeError(f"make_system must be a callable p -> HybridSystem, got "
                        f"{type(make_system).__name__}")
    params = _check_params(params)
    _check_executor(executor)
    chunks = _check_chunks(chunks)
    throw = _check_bool("throw", throw)
    warn = _check_bool("warn", warn)
    kwargs = dict(kwargs, t_max=t_max, j_max=j_max, progress=False, throw=False, warn=False)
    N = len(params)
    if N == 0:
        return []
    if executor is not None and callable(x0):
        import pickle
        try:
            pickle.dumps(x0)
        except Exception as e:
            raise TypeError(f"x0: a callable p -> x0 is sent to the executor's workers and "
                            f"must pickle (a module-level function, not a lambda or a local "
                            f"function); {type(e).__name__}: {e}. Or pass an array") from e
    items = [(p, x0) for p in params]
    bar = make_bar(progress, total=N, desc="sweep", unit="run", leave=True)
    out = _execute(_Batch(None, make_system, items, kwargs, throw, bar), executor, chunks, bar)
    return _warned("sweep", out, warn)
