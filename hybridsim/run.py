"""The front door: :func:`simulate`, :func:`simulate_many`, :func:`sweep`, and
the one choice of path (``backend=``).

Below it are the paths, none of which imports this module: the Python loop
(:mod:`hybridsim.solve`), the vectorized batch (:mod:`hybridsim.batch_vectorized`)
and the compiled kernels (:mod:`hybridsim.compiled`). The rules they share
(causes, messages, the raise/warn policy of a run and of a batch) are
:mod:`hybridsim.rules`'s, their input checks :mod:`hybridsim.options`'.

A batch keeps going when one of its runs fails. A row whose map raises at its
initial state, whose initial state is not finite, or whose run ends on a
failure (``MAP_ERROR``, ``NON_FINITE``, ``BLOWUP``, ``SOLVER_FAILED``,
``MAX_STEPS``) gets an arc of its own carrying the cause; the other rows'
results are kept, and one :class:`hybridsim.BatchWarning` names the failed
rows. With ``throw=True`` the first failed row raises
:class:`hybridsim.BatchError` instead.

Ctrl-C (KeyboardInterrupt) during a batch stops launching runs: every finished
run is kept, the run under way ends with ``Termination.CANCELED`` (and the arc
so far), runs never started get a one-sample ``CANCELED`` arc at their initial
state, and the list of N arcs is returned with one warning.
"""
from __future__ import annotations

import concurrent.futures
import importlib.util
import itertools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import OdeSolver

from . import compiled
from ._batch_attributes import Attributes, check_attributes, row_params
from ._progress import make_bar
from ._random_jumps import is_random, simulate_random
from ._rk import RK4, fixed_step
from ._sde import is_stochastic
from ._sde import prepare as prepare_sde
from .arc import HybridArc, _one_sample
from .arc_batch import ArcBatch
from .batch_vectorized import simulate_vectorized, takes_options
from .compiled._lower import lower, rebind, rebind_all
from .history import History
from .options import (
    RunOptions,
    check_bool,
    check_chunks,
    check_delays,
    check_dwell,
    check_executor,
    check_params,
    check_seed,
    check_t_eval,
    check_unsupported,
    check_x0,
    check_x0s,
    method_on,
    parse_run,
    resolve_method,
)
from .rules import (
    FAILED,
    BatchError,
    MapError,
    Priority,
    SimulationError,
    Termination,
    _warned,
    finish,
    finish_batch,
)
from .solve import _Options, _progress_bar, _Run
from .system import HybridSystem, check_nested_set_valued

__all__ = ["simulate", "simulate_many", "sweep"]

#: seconds a batch waits, after Ctrl-C, for executor chunks under way to come back
GRACE = 2.0


# ------------------------------------------------------------------ one run
def simulate(system: HybridSystem, x0: ArrayLike, t_max: float, j_max: float = math.inf, *,
             t0: float = 0.0, j0: int = 0, priority: str = "jumps",
             method: str | type[OdeSolver] = "RK45", rtol: float = 1e-6,
             atol: float | ArrayLike = 1e-9, max_step: float = math.inf,
             first_step: float | None = None, inputs: Callable | None = None,
             prehistory: Callable | None = None, max_norm: float = math.inf,
             seed: int | np.random.Generator | None = None, progress: bool | None = None,
             throw: bool = True, warn: bool = True, dense: bool = False, refine: int = 1,
             t_eval: ArrayLike | None = None, max_steps: float = 1_000_000,
             max_samples: float = 10_000_000, zeno_jumps: int = 50,
             zeno_time: float = 1e-12, zeno_rtol: float = 1e-7,
             backend: str = "python", dwell: Any = None) -> HybridArc:
    r"""Simulate a hybrid system from x0 until t_max or j_max.

    Flows by :math:`\dot x = f(x)` with a scipy ODE solver while x is in C,
    jumps by :math:`x^+ = g(x)` when x is in D (as the priority decides).
    Events are located on each step's dense output to 4 ulp of the event
    time: safeguarded secant steps on the guards where the system has them
    (a flow that starts on a guard's zero takes its first estimate from a
    probe's slope), else bisection of the set indicators. Each step's interior is searched too
    (the guard sampled and its maxima refined), so a jump set entered and
    left within one solver step is not missed.

    Parameters
    ----------
    system : HybridSystem
        The data (C, f, D, g).
    x0 : array_like, shape (n,)
        Initial state.
    t_max : float
        Flows stop at t_max; a run that flows up to t_max ends with a sample
        there. Jumps at t = t_max are still taken, including events that land
        on t_max only up to round-off (:func:`hybridsim.rules.t_max_slack`).
        May be ``inf``.
    j_max : int or inf, optional
        At most this many jumps; the run stops at the sample after the last.
    t0, j0 : float, int, optional
        Initial hybrid time (j0 a non-negative int).
    priority : {"jumps", "flows", "random"}
        What happens in C ∩ D. ``"jumps"``: jump as soon as x is in D.
        ``"flows"``: jump only when x is in D and flowing is impossible (x not
        in C, or on the edge of C where the flow leaves C at once).
        ``"random"``: a fair coin (seeded by ``seed``) at each such point,
        or the ``dwell`` law. A set-valued jump map (``jump_map_values``)
        jumps to its first successor, under ``"random"`` to one drawn
        uniformly with the seed.
    method : str or OdeSolver subclass
        "RK45" (default), "RK23", "DOP853", "Radau", "BDF", "LSODA" or a
        concrete subclass of :class:`scipy.integrate.OdeSolver`. The three
        explicit Runge-Kutta methods take scipy's steps bit for bit, through
        ``hybridsim._rk``'s copies without scipy's per-step overheads.
        "RK4": the classic Runge-Kutta method with the fixed step
        ``max_step`` (finite; no error control, ``rtol`` and ``atol`` not
        read; :class:`hybridsim._rk.RK4`), on the Python and vectorized
        paths.
    rtol, atol, max_step, first_step : float
        Passed to the solver. ``max_step`` is also capped by
        ``system.max_step``.
    inputs : callable, optional
        ``u(t)`` for a system with ``input_dim > 0`` simulated on its own.
    prehistory : callable, optional
        ``x(s)`` for s < t0, read by maps through ``self.history``
        (default: constant x0).
    max_norm : float
        Stop with cause ``BLOWUP`` when the state's norm exceeds it.
    seed : int or numpy Generator, optional
        Seed of ``priority="random"``.
    progress : bool or None
        Show a progress bar (tqdm) with t and j. None: at a terminal and in
        a notebook.
    throw : bool
        True (default): when a user map raises or breaks its contract (wrong
        shape, complex or non-finite value), raise :class:`MapError` (a
        :class:`SimulationError`) naming the map, t and j, chained from the
        original exception, with the arc so far on ``.arc``. False: return the
        arc with cause ``MAP_ERROR`` (``arc.exception`` holds the error).
    warn : bool
        Issue one :class:`SimulationWarning` when the run ends on a numerical
        failure (``NON_FINITE``, ``BLOWUP``, ``SOLVER_FAILED``) or on
        ``MAX_STEPS``, and when an explicit method's steps signal stiffness.
        The arc is returned either way.
    refine : int
        Samples stored per solver step (as MATLAB's ``Refine``): ``refine - 1``
        points of the step's dense output are added inside each step.
    t_eval : array_like, optional
        Store samples at these times (from the dense output) instead of at
        the solver's steps; the initial and final samples and both samples
        of every jump are kept. Not with ``refine > 1``.
    dense : bool
        Keep every step's dense output, so ``arc.at(t, j)`` is exact to the
        integrator and the history is available after the run. Without it
        ``arc.at`` interpolates by cubic Hermite with the flow derivative
        stored at each sample (``arc.xdot``).
    max_steps, max_samples : int or inf
        Safety limits: the run ends with cause ``MAX_STEPS`` after this many
        accepted solver steps, or this many stored samples.
    zeno_jumps, zeno_time, zeno_rtol : int, float, float
        The run stops with cause ``ZENO`` after ``zeno_jumps`` consecutive
        jumps each preceded by a short flow: at most
        ``zeno_time * max(1, |t|)`` or ``zeno_rtol`` times the run's time
        scale (``t_max - t0``, or the time elapsed when t_max is inf).

    dwell : scipy.stats frozen distribution or callable, optional
        With ``priority="random"``: the time spent in C ∩ D before jumping,
        drawn once at each entry into C ∩ D (``dist.rvs(random_state=rng)``,
        or ``dwell(rng) -> float``, with the run's seeded generator) instead
        of the fair coin. 0 jumps at once, ``inf`` flows on. The jump is
        placed at entry + dwell exactly (the flow is stopped there, as at
        any event), so the law does not depend on the step size. A flow
        that leaves D first does not jump (the next entry draws again); one
        that leaves C while in D jumps there (the dwell is cut short).
        Python path only.
    backend : {"python", "compiled", "auto"}
        ``"compiled"`` runs a :class:`hybridsim.compiled.CompiledSystem`
        entirely in compiled code (numba: ``pip install 'hybridsim[fast]'``)
        through :func:`hybridsim.compiled.simulate_compiled`: the same
        Dormand-Prince steps (RK45, or DOP853), events, rules and arc.
        Other systems are lowered to one (:func:`hybridsim.compiled.lower`:
        a ``LinearPlant``, systems with a compiled form, interconnections of
        them wired by :class:`hybridsim.LinearInput`), or refused by name.
        Options it does not support (inputs, prehistory, dense, t_eval,
        other methods) raise. ``"auto"``: compiled where numba is installed, the system
        lowers and the options allow it; the Python path otherwise.

    Returns
    -------
    HybridArc
        The solution; ``arc.termination`` says why it stopped and
        ``arc.stats`` counts steps, evaluations and events.

    Raises
    ------
    MapError
        A user map raised or broke its contract (``throw=True``).
    TypeError, ValueError
        Bad arguments, each naming the argument.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> timer = hs.HybridSystem.from_functions(
    ...     flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
    ...     jump_guard=lambda x: x[0] - 1.0, flow_guard=lambda x: 1.0 - x[0],
    ...     state_dim=1)
    >>> arc = hs.simulate(timer, [0.0], t_max=3.0)
    >>> np.round(arc.jump_times, 12)         # the jump at t_max is taken
    array([1., 2., 3.])
    """
    if not isinstance(system, HybridSystem):
        raise TypeError(f"system must be a hybridsim.HybridSystem, got {type(system).__name__}")
    if is_random(system):      # jump_rate / jump_law: run with the clock's state added
        kw = {k: v for k, v in locals().items() if k not in ("system", "x0")}
        if kw["backend"] == "compiled":      # the clock appended, on the compiled path
            from .compiled._stochastic import simulate_rate_compiled
            check_unsupported("compiled", {k: kw.pop(k) for k in (
                "inputs", "prehistory", "dense", "t_eval", "progress", "dwell")})
            return rebind(simulate_rate_compiled(system, lower(system), x0, t_max, j_max,
                                                 kw, kw.pop("seed")), system)
        kw["backend"] = "python"
        return simulate_random(simulate, system, x0, kw)
    if backend == "auto" and (dwell is not None or system.set_valued):
        backend = "python"          # the compiled path has neither
    if backend == "auto":
        backend = _auto_backend(system, dict(method=method, inputs=inputs,
                                             prehistory=prehistory, dense=dense,
                                             t_eval=t_eval), None)
    if backend == "compiled":
        return _compiled_run(system, x0, t_max, j_max, dict(
            t0=t0, j0=j0, priority=priority, method=method, rtol=rtol, atol=atol,
            max_step=max_step, first_step=first_step, max_norm=max_norm, seed=seed,
            throw=throw, warn=warn, refine=refine, max_steps=max_steps,
            max_samples=max_samples, zeno_jumps=zeno_jumps, zeno_time=zeno_time,
            zeno_rtol=zeno_rtol), dict(inputs=inputs, prehistory=prehistory, dense=dense,
                                       t_eval=t_eval, progress=progress, dwell=dwell))
    if backend != "python":
        raise ValueError(f"backend must be 'python', 'compiled' or 'auto', got {backend!r}")
    check_nested_set_valued(system)
    maps = system._compile()
    n = int(system.state_dim)
    x = check_x0(x0, n)
    ro = parse_run(system, n, t0=t0, j0=j0, t_max=t_max, j_max=j_max, priority=priority,
                   rtol=rtol, atol=atol, max_step=max_step, first_step=first_step,
                   max_norm=max_norm, zeno_jumps=zeno_jumps, zeno_time=zeno_time,
                   zeno_rtol=zeno_rtol, refine=refine, max_steps=max_steps,
                   max_samples=max_samples, throw=throw, warn=warn, python=True)
    t0, t_max, j_max, j0, prio = ro.t0, ro.t_max, ro.j_max, ro.j0, ro.prio
    rtol, atol, max_step, first_step, max_norm = (ro.rtol, ro.atol, ro.max_step,
                                                  ro.first_step, ro.max_norm)
    zeno_jumps, zeno_time, zeno_rtol = ro.zeno_jumps, ro.zeno_time, ro.zeno_rtol
    refine, max_steps, max_samples, throw, warn = (ro.refine, ro.max_steps, ro.max_samples,
                                                   ro.throw, ro.warn)
    sde = None
    if is_stochastic(system) and maps.W is not None:
        raise ValueError(f"{type(system).__name__} declares watch (functions watched along "
                         f"the flows) and a diffusion: crossings of an SDE path are not "
                         f"located (its flow has no dense output); watch an ODE flow")
    if is_stochastic(system):            # an SDE flow: stepped by hybridsim._sde
        sde = prepare_sde(system, method, max_step, seed, n, t0, maps, inputs=inputs,
                          prehistory=prehistory, dense=dense, t_eval=t_eval, refine=refine,
                          dwell=dwell)
        method, seed = "RK45", sde.rng_seed(seed)
    Method = resolve_method(method)
    if Method is RK4:
        fixed_step("RK4", max_step)
    if int(system.input_dim or 0) > 0 and inputs is None:
        raise ValueError(f"inputs: the system has input_dim={system.input_dim}; pass "
                         "inputs=callable(t) -> u, or connect it with hs.connect")
    if inputs is not None and not callable(inputs):
        raise TypeError(f"inputs must be a callable u(t), got {type(inputs).__name__}")
    if prehistory is not None and not callable(prehistory):
        raise TypeError(f"prehistory must be a callable x(s), got {type(prehistory).__name__}")
    dense = check_bool("dense", dense)
    progress = check_bool("progress", progress, allow_none=True)
    t_eval = check_t_eval(t_eval, t0, t_max)
    if t_eval is not None and refine > 1:
        raise ValueError("t_eval and refine > 1 cannot be combined: choose one way of "
                         "placing samples")
    rng = check_seed(seed, build=prio == Priority.RANDOM)
    dwell = check_dwell(dwell, prio)
    delays = check_delays(system)

    keep = dense or system.needs_history
    history = History(t0, x, j0, prehistory, inputs, maps.h)
    system._bind_history(history)
    opts = _Options(**{f.name: getattr(ro, f.name) for f in fields(RunOptions)}, n=n,
                    Method=Method, t_eval=t_eval, keep=keep, delays=delays, rng=rng,
                    dwell=dwell)
    run = _Run(system, maps, opts, inputs, history)
    run.sde = sde
    run.pbar = _progress_bar(progress, t0, t_max, j_max)
    try:
        run.run(t0, j0, x)
    except MapError as e:
        # at x0 (a map's contract checked before the loop): bad input, raised at
        # once whatever throw says; its arc is x0 alone, ended by MAP_ERROR
        run._stop(Termination.MAP_ERROR, exc=e, error=str(e))
        e.arc = run.arc()
        raise
    except BaseException as e:
        raise SimulationError(f"internal error of the engine or solver: "
                              f"{type(e).__name__}: {e}", run.arc()) from e
    finally:
        if run.pbar is not None:
            run.pbar.close()
    # finish -> simulate -> the caller
    return finish(run.arc(), throw, warn, stacklevel=3)


def _compiled_run(system, x0, t_max, j_max, opts, python_only):
    """``simulate(..., backend="compiled")``: the compiled path, or a clear refusal."""
    check_unsupported("compiled", python_only)
    cs = lower(system)        # the system itself, or its lowered form (named refusals)
    if is_stochastic(system):             # an SDE flow: the compiled SDE stepper
        from .compiled._stochastic import sde_options, simulate_sde_compiled
        return rebind(simulate_sde_compiled(cs, x0, t_max, j_max, **sde_options(opts)),
                      system)
    try:
        return rebind(compiled.simulate_compiled(cs, x0, t_max, j_max, **opts), system)
    except MapError as e:
        if getattr(e, "arc", None) is not None:
            rebind(e.arc, system)
        raise


# ------------------------------------------------------------------ batches
def simulate_many(system: HybridSystem, x0s: ArrayLike, t_max: float,
                  j_max: float = np.inf, *, executor: concurrent.futures.Executor | None = None,
                  chunks: int | None = None, progress: bool | None = None,
                  throw: bool = False, warn: bool = True, stats: Any = None,
                  attributes: Sequence[Mapping[str, Any]] | None = None,
                  **options: Any) -> ArcBatch:
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
    stats : hybridsim.estimate.Stats, optional
        Reduce the rows into ``stats`` (updated in place and returned) as
        they finish, keeping no arc: on the compiled path the batch kernel
        keeps of each row only its end and its states on the Stats's grid
        (the values :meth:`Stats.update` reads off the row's arc); on the
        other paths the arcs are reduced a thousand rows at a time. A
        system that draws (``jump_rate``, ``diffusion``, ``jump_law``) takes
        ``seed`` here: row ``i`` is keyed by the ``i``-th word of
        ``numpy.random.SeedSequence(seed).generate_state(N, uint64)`` shifted
        right by one (``seed=key`` replays it alone in :func:`simulate`),
        the same rows on every path. ``throw`` must be False; failed rows
        are named in one :class:`BatchWarning`.
    attributes : sequence of dict, optional
        One dict per row: row ``i`` runs with these attributes of ``system``
        set (``setattr``; a parameter sweep or a population of designs,
        e.g. ``[{"e": 0.8}, {"e": 0.9}]``; a
        :class:`~hybridsim.compiled.CompiledSystem`'s are its ``params``:
        ``[{"params": p0}, ...]``), the system's attributes as they were
        afterwards. On the compiled path each row's ``p`` is read with its
        attributes set and the rows run as one parallel batch
        (:func:`hybridsim.compiled.simulate_many_compiled`'s ``params``); on
        the other paths (and where a row changes the compiled form, an
        attribute of another shape) the rows run one after another, each with
        its attributes. The arcs' ``system`` is ``system`` with its
        attributes restored (``arc.outputs()`` reads them as they are then:
        set a row's again to evaluate an output that reads them); with an
        executor (whose workers may share the system) each row runs on a
        copy with its attributes, its arc's ``system``.
    **options
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
    ArcBatch or Stats
        ``stats`` when given. Otherwise a list of one arc per row of
        ``x0s``, in order, with the runs' final states, causes, jump counts
        and jump times as arrays (:class:`hybridsim.ArcBatch`: ``batch.jump_times`` reads every
        row's at once, far faster than from the arcs). A row that failed before
        flowing has a one-sample arc at (t0, j0, x0) with cause
        ``MAP_ERROR`` or ``NON_FINITE`` and the error in ``arc.exception``.
        After Ctrl-C the list is still complete: finished runs are kept, the
        run under way and the runs never started end with ``CANCELED``. With
        an executor, chunks not started are canceled and the batch waits
        ``hybridsim.run.GRACE`` (2) seconds for chunks under way (workers
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
    >>> decay = hs.HybridSystem.from_functions(flow_map=lambda x: -x, state_dim=1)
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
    check_executor(executor)
    chunks = check_chunks(chunks)
    throw = check_bool("throw", throw)
    warn = check_bool("warn", warn)
    n = int(system.state_dim)
    X = check_x0s(x0s, n)
    N = len(X)
    if attributes is not None:
        attributes = check_attributes(attributes, N)
    if stats is not None:
        from ._batch_reduce import reduce_into
        options = dict(options, progress=False)
        return reduce_into(system, X, t_max, j_max, stats, executor, chunks, throw, warn,
                           options, (simulate_many, _auto_backend, _run_row), attributes)
    if N == 0:
        return ArcBatch((), n)
    if options.get("seed") is not None and any(
            getattr(system, k, None) is not None for k in ("diffusion", "jump_rate", "jump_law")):
        raise ValueError(f"seed: simulate_many passes one seed to every row, so every row of "
                         f"{type(system).__name__} (it draws noise: diffusion, jump_rate or "
                         f"jump_law) would draw the same; run seeded rows with "
                         f"hybridsim.estimate.accumulate or estimate (a generator per run), or "
                         f"hs.sweep over seeds")
    options = dict(options, t_max=t_max, j_max=j_max, progress=False)
    if options.get("backend") == "auto":
        options["backend"] = _auto_backend(system, options, executor)
    if options.get("backend") == "python":
        del options["backend"]               # the default: the batch integrator may take it
    rows = None if attributes is None else \
        (row_params(system, attributes) if options.get("backend") == "compiled" and
         executor is None else None)
    if options.get("backend", "python") == "compiled" and executor is None and \
            (attributes is None or rows is not None):
        kw = {k: v for k, v in options.items() if k not in ("backend", "progress")}
        cs, P = (lower(system), None) if rows is None else rows
        if is_random(system):             # jumps at a rate: each row its own clock
            from .compiled._stochastic import simulate_many_rate
            out = simulate_many_rate(system, cs, X, t_max, j_max,
                                     {k: v for k, v in kw.items() if k not in ("t_max", "j_max")},
                                     params=P)
            out = ArcBatch([rebind(a, system) for a in out], n)
            return finish_batch("simulate_many", out, throw, warn)
        if is_stochastic(system):         # an SDE flow: each row its own Brownian path
            from .compiled._stochastic import sde_options, simulate_many_sde
            out = simulate_many_sde(cs, X, throw=False, warn=False, params=P,
                                    **sde_options(kw))
            out = ArcBatch([rebind(a, system) for a in out], n)
            return finish_batch("simulate_many", out, throw, warn)
        out = compiled.simulate_many_compiled(cs, X, throw=False, warn=False, params=P, **kw)
        return finish_batch("simulate_many", rebind_all(out, system), throw, warn)
    if system.vectorized and executor is None and attributes is None and \
            _batch_takes(system, options):
        out = ArcBatch(_many_vectorized(system, X, options, progress), n)
        return finish_batch("simulate_many", out, throw, warn)
    options.update(throw=False, warn=False)
    bar = make_bar(progress, total=N, desc="simulate_many", unit="run", leave=True)
    if attributes is None:
        items = [(None, x0) for x0 in X]
        out = _execute(_Batch(system, None, items, options, throw, bar), executor, chunks, bar)
    else:                                 # the rows one by one, each with its attributes
        setter = Attributes(system, copies=executor is not None)
        try:
            out = _execute(_Batch(None, setter, list(zip(attributes, X)), options, throw, bar),
                           executor, chunks, bar)
        finally:
            setter.restore()
    return _warned("simulate_many", ArcBatch(out, n), warn)


#: options the compiled path runs (beyond those every path shares) at these values
#: only (its methods: :data:`hybridsim.options.METHODS_ON`)
_COMPILED_ONLY_AT = {"inputs": (None,), "prehistory": (None,),
                     "dense": (False,), "t_eval": (None,), "dwell": (None,)}


def _auto_backend(system, kwargs, executor):
    """``backend="auto"``: "compiled" where numba is installed, the system runs
    compiled (:func:`hybridsim.compiled.lowerable`) and the options are the
    compiled path's; "python" otherwise (which integrates a vectorized
    system's batch together)."""
    if executor is not None or importlib.util.find_spec("numba") is None \
            or any(getattr(system, k, None) is not None         # Python path only
                   for k in ("diffusion", "jump_rate", "jump_law")):
        return "python"
    if getattr(system, "watch", None) is not None and (
            getattr(system, "delays", ()) or kwargs.get("method") not in (None, "RK45")):
        return "python"         # watched with RK45 and without delays only, compiled
    if any(kwargs.get(k, v[0]) not in v for k, v in _COMPILED_ONLY_AT.items()):
        return "python"
    try:
        method_on("compiled", kwargs.get("method"), system)
    except (TypeError, ValueError):
        return "python"
    from .compiled._lower import auto_choice
    # a plain model: compiled, or one warning saying why not
    return auto_choice(system, compiled.lowerable(system))


def _batch_takes(system, kwargs):
    return takes_options(kwargs, system)


def _many_vectorized(system, X, kwargs, progress):
    """The vectorized path, row failures at x0 isolated (see simulate_many)."""
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
          **options: Any) -> ArcBatch:
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
    **options
        Passed to :func:`hybridsim.simulate`.

    Returns
    -------
    ArcBatch
        A list of one arc per parameter value, in order, with their fields
        as arrays (see :func:`simulate_many` for failed and canceled rows).

    Raises
    ------
    BatchError
        ``throw=True`` and a row failed.
    TypeError, ValueError
        Bad arguments, each named.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> make = lambda a: hs.HybridSystem.from_functions(flow_map=lambda x: -a * x, state_dim=1)
    >>> arcs = hs.sweep(make, [1.0, 2.0], [1.0], t_max=1.0, rtol=1e-10, atol=1e-12)
    >>> [round(float(a.xf[0]), 6) for a in arcs]
    [0.367879, 0.135335]
    """
    if not callable(make_system):
        raise TypeError(f"make_system must be a callable p -> HybridSystem, got "
                        f"{type(make_system).__name__}")
    params = check_params(params)
    check_executor(executor)
    chunks = check_chunks(chunks)
    throw = check_bool("throw", throw)
    warn = check_bool("warn", warn)
    options = dict(options, t_max=t_max, j_max=j_max, progress=False, throw=False, warn=False)
    N = len(params)
    if N == 0:
        return ArcBatch()
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
    out = _execute(_Batch(None, make_system, items, options, throw, bar), executor, chunks, bar)
    return _warned("sweep", ArcBatch(out), warn)


# ------------------------------------------------------------------ the rows of a loop
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
