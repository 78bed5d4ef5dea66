"""The compiled path's runners: :func:`simulate_compiled` (one run) and
:func:`simulate_many_compiled` (a batch on worker threads taking rows from a
shared counter) and the options packed for the kernels; the arcs and messages
made of the kernels' results are in :mod:`._arcs`.
"""
from __future__ import annotations

import gc
import math
import threading
import warnings
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import OdeSolver

from .._rk import fixed_step
from ..arc import HybridArc, _one_sample
from ..arc_batch import ArcBatch
from ..options import FIXED_STEP, check_unsupported, check_x0, method_on, parse_run
from ..rules import (
    MapError,
    Priority,
    Termination,
    finish,
    finish_batch,
)
from . import _layout as lay
from ._arcs import _arc, _at_x0, _plain, _stats_of
from ._pool import _cut, _interruptible, _threads, _untouched
from ._raised import _CatchRaised, _raised_arc, _unraisable  # noqa: F401
from ._system import CompiledSystem, _load_kernel, _notice

__all__ = ["simulate_compiled", "simulate_many_compiled"]

_I64_MAX = np.iinfo(np.int64).max
_RANDOM = Priority.RANDOM
#: the Generator of runs that draw no coins, and its addresses (built once)
_DUMMY_RNG = None
#: the stop flag of single runs (never set: they poll the interpreter's signal check)
_NO_STOP = np.zeros(1, np.int64)
#: the rows a batch's thread takes at a time from the shared counter
_CHUNK = 4
#: a batch of at most this many rows of short runs (at most :data:`_SHORT` samples,
#: as the system's last batch, or its first rows, ran) run from the main thread
#: runs them one after another in it, each a run of the single-run kernel (Ctrl-C
#: read at every step): handing rows to a worker thread and back costs about
#: 150 us a batch, such a run 10-50 us (a falsification's first rows, explore's
#: first levels). Off the main thread a one-thread batch runs in the calling
#: thread, the GIL released (``_pool._interruptible``)
_ALONE = 15
#: the samples of a short run (:data:`_ALONE`)
_SHORT = 64
#: runs of more samples than this (about 0.3 ms and more each) take a thread per
#: row from two rows on, shorter ones a thread per 8 rows (``_pool._threads``)
_LONG = 256


def _x0(x0, n):
    """:func:`hybridsim.options.check_x0` (same errors), a list or tuple of n
    finite floats or a float64 array of shape (n,) taken without numpy's
    per-call costs (the kernel copies x0, never writes it)."""
    t = type(x0)
    if t is list or t is tuple:
        if len(x0) == n and all(type(v) is float for v in x0) and all(map(math.isfinite, x0)):
            return np.array(x0)
    elif t is np.ndarray and x0.dtype == np.float64 and x0.shape == (n,) and \
            x0.flags.c_contiguous and all(map(math.isfinite, x0.tolist())):
        return x0
    return np.ascontiguousarray(check_x0(x0, n))


def _refuse_noise(system, runner):
    """The kernel steps ODE flows without a jump rate; a diffusion or a jump rate
    runs through the front door (``hs.simulate`` / ``hs.simulate_many`` with
    ``backend="compiled"``), which adds the clock or takes the SDE stepper
    (:mod:`hybridsim.compiled._stochastic`)."""
    noisy = sorted(system.maps.keys() & {"diffusion", "jump_rate"}) \
        if isinstance(system, CompiledSystem) else []
    if noisy:
        raise TypeError(f"{runner}: {system!r} declares {' and '.join(noisy)}: run it with "
                        f"hs.simulate or hs.simulate_many(..., backend='compiled'), which "
                        f"step SDE flows and jump rates on the compiled path")


def _check_system(system):
    if not isinstance(system, CompiledSystem):
        raise TypeError(f"system must be a hybridsim.compiled.CompiledSystem (maps of "
                        f"(x, t, j, p) numba can compile), got {type(system).__name__}; "
                        f"run other systems with hs.simulate (the Python path)")
    if system.watch is not None and (system.delays or system.specialize):
        raise TypeError(f"backend='compiled': {system!r} declares watch (functions watched "
                        f"along the flows) with {'delays' if system.delays else 'specialize'}"
                        f", which the compiled kernel does not combine; run it with "
                        f"hs.simulate(system, ...) (the Python path)")


#: the options a path may refuse (:data:`hybridsim.options.SUPPORTS`); others are unknown
_REFUSABLE = ("inputs", "prehistory", "dense", "t_eval", "progress", "dwell")


#: the options of both compiled entry points, in the order :func:`_options` takes them
_OPTION_NAMES = ("t0", "j0", "t_max", "j_max", "priority", "rtol", "atol", "max_step",
                 "first_step", "max_norm", "zeno_jumps", "zeno_time", "zeno_rtol", "refine",
                 "max_steps", "max_samples", "throw", "warn")


def _options(system, n, caller, method, extra, vals):
    """Validate like :func:`hybridsim.simulate` (:func:`hybridsim.options.parse_run`:
    the same exception and message for the same bad input) and pack the
    kernel's option arrays. ``vals``: the values of :data:`_OPTION_NAMES`, in
    order. Returns ``(ro, fopt, iopt, atol)`` (the kernels only read the
    arrays: a repeated call returns the same ones)."""
    # the same options again (a loop of runs): parsed once per system (a
    # positional key: packing keywords into a dict was a tenth of a short run)
    memo = system._nb["memo"]
    key = None
    if not extra:
        try:
            # what the packed arrays read of the system: its max_step and delays
            # (systems lowered from one structure share this memo, not their delays);
            # the types too: 1, 1.0 and True are equal keys, not equal options
            key = (caller, method, n, system.max_step, system.delays, vals)
            hit = memo.get(key)
        except TypeError:       # an array atol: parsed every time
            key = hit = None
        types = (type(system.max_step), *map(type, vals))
        if hit is not None and hit[0] == types:
            return hit[1]
    out = _parse_options(system, n, caller, method, extra, dict(zip(_OPTION_NAMES, vals)))
    if key is not None:
        if len(memo) >= 64:
            memo.clear()
        memo[key] = (types, out)
    return out


def _parse_options(system, n, caller, method, extra, shared):
    """:func:`_options` without its memo."""
    for name in extra:
        if name not in _REFUSABLE:
            raise TypeError(f"{caller}() got an unexpected keyword argument {name!r}")
    check_unsupported("compiled", dict(extra, method=method))
    name = method_on("compiled", method, system)
    ro = parse_run(system, n, **shared)
    if name in FIXED_STEP:
        fixed_step(name, ro.max_step)
    # the delays (the flow map's past, CompiledSystem(delays=)) after the options
    fopt = np.empty(lay.F_DELAYS + len(system.delays))
    fopt[lay.F_T0] = ro.t0
    fopt[lay.F_T_MAX] = ro.t_max
    fopt[lay.F_J_MAX] = ro.j_max
    fopt[lay.F_RTOL] = ro.rtol
    fopt[lay.F_MAX_STEP] = ro.max_step
    fopt[lay.F_FIRST_STEP] = np.nan if ro.first_step is None else ro.first_step
    fopt[lay.F_MAX_NORM] = ro.max_norm
    fopt[lay.F_ZENO_TIME] = ro.zeno_time
    fopt[lay.F_ZENO_RTOL] = ro.zeno_rtol
    fopt[lay.F_DELAYS:] = system.delays
    nb = system._nb
    iopt = np.empty(lay.I_SIZE, np.int64)
    iopt[lay.I_J0] = ro.j0
    iopt[lay.I_PRIO] = int(ro.prio)
    iopt[lay.I_MAX_STEPS] = _I64_MAX if ro.max_steps == math.inf else ro.max_steps
    iopt[lay.I_MAX_SAMPLES] = _I64_MAX if ro.max_samples == math.inf else ro.max_samples
    iopt[lay.I_ZENO_JUMPS] = ro.zeno_jumps
    iopt[lay.I_REFINE] = ro.refine
    iopt[lay.I_HAS_C] = nb["has_C"]
    iopt[lay.I_HAS_D] = nb["has_D"]
    iopt[lay.I_HAS_HC] = nb["has_hC"]
    iopt[lay.I_HAS_HD] = nb["has_hD"]
    iopt[lay.I_CAP] = 64
    iopt[lay.I_D_FROM_GUARD] = nb["D_from_guard"]
    iopt[lay.I_C_FROM_GUARD] = nb["C_from_guard"]
    iopt[lay.I_N_DELAYS] = len(system.delays)
    # 1 in the batch kernel's rows: the run returns its buffers uncopied
    # (run_rows copies them into its pool)
    iopt[lay.I_ROW] = 0
    if isinstance(ro.atol, float):
        atol_a = np.full(n, ro.atol)
    else:
        atol_a = np.array(np.broadcast_to(np.asarray(ro.atol, dtype=np.float64), (n,)),
                          order="C")
    return ro, fopt, iopt, atol_a


def _kernels(k, system, batch, method="RK45"):
    """``(run, address)``: the system's run kernel for ``method`` ("RK45",
    "DOP853" or "RK4"; the cached generic one, maps passed by address, or its
    specialised one) and that kernel's code address for
    :func:`_batch.run_rows` (compiled when ``batch``)."""
    nb = system._nb
    # (one structure lowered with other delays shares ``nb``: with delays or not)
    delays = bool(system.delays)
    watch = system.watch is not None
    if watch and method != "RK45":
        raise TypeError(f"backend='compiled': {system!r} declares watch (functions watched "
                        f"along the flows), which the compiled kernel records with RK45 "
                        f"only, not {method}; run it with hs.simulate(system, ...)")
    tag = "" if method == "RK45" else "_" + method
    one = nb.get("one" + tag)
    if one is None and system.specialize:
        # DOP853's or RK4's specialised kernel: made when a run first asks for it
        import numba
        from numba.core.errors import NumbaExperimentalFeatureWarning
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumbaExperimentalFeatureWarning)
            sub = system._compile_specialised(k, numba, method)
        nb["one" + tag], nb["one_addr" + tag] = one, _ = sub["one"], sub["one_addr"]
    if one is None:
        k.compile_kernels(batch=batch, notice=_notice, delays=delays, method=method,
                          watch=watch)
        nb["one" + tag] = one = k.run_kernel(delays, method, watch)
        nb["one_addr" + tag] = k.one_address(delays, method, watch)
    elif batch:
        k.compile_kernels(batch=True, notice=_notice,
                          one=one is k.run_kernel(delays, method, watch), delays=delays,
                          method=method, watch=watch)
    return one, nb["one_addr" + tag]


def _rng_for(k, prio, seed):
    """``(rng, rngp)``: the run's numpy Generator and its addresses for the
    kernel (:func:`_types.rng_pointers`; the caller keeps ``rng`` alive)."""
    global _DUMMY_RNG
    if prio == _RANDOM or seed is not None:
        from ..options import check_seed as _check_seed
        rng = _check_seed(seed)
        if prio == _RANDOM:
            return rng, k.rng_pointers(rng)
    if _DUMMY_RNG is None:
        rng = np.random.default_rng(0)
        _DUMMY_RNG = rng, k.rng_pointers(rng)
    return _DUMMY_RNG


def simulate_compiled(system: CompiledSystem, x0: ArrayLike, t_max: float,
                      j_max: float = math.inf, *, t0: float = 0.0, j0: int = 0,
                      priority: str = "jumps", rtol: float = 1e-6,
                      atol: float | ArrayLike = 1e-9, max_step: float = math.inf,
                      first_step: float | None = None, max_steps: float = 1_000_000,
                      max_samples: float = 10_000_000, zeno_jumps: int = 50,
                      zeno_time: float = 1e-12, zeno_rtol: float = 1e-7,
                      max_norm: float = math.inf,
                      seed: int | np.random.Generator | None = None, refine: int = 1,
                      throw: bool = True, warn: bool = True,
                      method: str | type[OdeSolver] = "RK45",
                      **unsupported: Any) -> HybridArc:
    """Simulate a :class:`CompiledSystem` entirely in compiled code.

    The same run as ``hs.simulate(system, x0, t_max, j_max, method=method,
    ...)``: Dormand-Prince 5(4) steps with scipy RK45's error control and
    step-size controller (or scipy DOP853's 8(5,3), or the classic RK4 at the
    fixed step ``max_step``), events located to 4 ulp
    on the step's dense output
    (the Python path's root finder on guards, bisection of the indicators,
    the interior search for excursions within one step), the same priorities, limits and
    termination causes, and the same :class:`hybridsim.HybridArc` (``t``,
    ``j``, ``x``, ``xdot``, ``stats``, ``termination``, ``message``).

    Parameters
    ----------
    system : CompiledSystem
    x0 : array_like, shape (n,)
    t_max, j_max, t0, j0, priority, rtol, atol, max_step, first_step, max_steps,
    max_samples, zeno_jumps, zeno_time, zeno_rtol, max_norm, seed, refine, throw, warn
        As in :func:`hybridsim.simulate` (``seed`` drives ``priority="random"``
        with the same numpy Generator stream, so coins agree with the Python
        path).
    method : {"RK45", "DOP853", "RK4"} or scipy's class
        The Runge-Kutta pair (scipy's steps, error norm, step-size controller
        and dense output). DOP853, for tight tolerances (rtol 1e-8 and
        below), takes several times fewer steps; as on the Python path, its
        interior event search runs on the cubic Hermite of each step's ends
        and confirms a hit on the dense output (three more evaluations of
        the flow map), and its refined samples carry no derivative (NaN).
        Not with ``delays``. "RK4": the Python path's
        :class:`hybridsim._rk.RK4`, the classic Runge-Kutta method at the
        fixed step ``max_step`` (finite; no error control, ``rtol`` and
        ``atol`` not read), its continuous extension of order 3 for events,
        refined samples and the past (``delays``). Each of the two has its
        own kernel, compiled (about 15 s, once per machine) when a run first
        asks for it; other methods are refused by name.

    Returns
    -------
    HybridArc
        Ctrl-C during the run ends it with ``CANCELED`` and the arc so far.

    Raises
    ------
    ImportError
        numba is missing (``pip install 'hybridsim[fast]'``).
    CompileError
        A map numba cannot compile (named); ``hs.simulate`` is the fallback.
    MapError
        A jump map returned a non-finite or mis-shaped value, or a guard that
        defines a set returned NaN (``throw=True``; the policy of
        :func:`hybridsim.rules.finish`); bad values at x0 are raised at once,
        as on the Python path. ``.arc`` ends with ``MAP_ERROR``.

    Examples
    --------
    >>> import numpy as np
    >>> from hybridsim.compiled import CompiledSystem, simulate_compiled
    >>> timer = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1),
    ...                        jump_map=lambda x, t, j, p: np.zeros(1),
    ...                        jump_guard=lambda x, t, j, p: x[0] - p[0],
    ...                        flow_guard=lambda x, t, j, p: p[0] - x[0],
    ...                        state_dim=1, params=[1.0])
    >>> arc = simulate_compiled(timer, [0.0], t_max=3.0)
    >>> np.round(arc.jump_times, 12)
    array([1., 2., 3.])

    DOP853, for tight tolerances (its kernel compiles on first use):

    >>> arc = simulate_compiled(timer, [0.0], t_max=3.0, method="DOP853", rtol=1e-12)
    >>> np.round(arc.jump_times, 12)
    array([1., 2., 3.])
    """
    _refuse_noise(system, "simulate_compiled")
    k = _load_kernel()
    _check_system(system)
    n = system.state_dim
    x = _x0(x0, n)
    system.compile()
    ro, fopt, iopt, atol_a = _options(
        system, n, "simulate_compiled", method, unsupported,
        (t0, j0, t_max, j_max, priority, rtol, atol, max_step, first_step, max_norm,
         zeno_jumps, zeno_time, zeno_rtol, refine, max_steps, max_samples, throw, warn))
    one, _ = _kernels(k, system, False, method_on("compiled", method))
    if system.watch is not None:
        from ._watch import watch_options
        fopt = watch_options(system, x, ro.t0, ro.j0, fopt)
    rng, rngp = _rng_for(k, ro.prio, seed)
    stop = np.zeros(1, np.int64)
    with _CatchRaised(stop) as caught:
        T, J, X, XD, code, detail, info, stats = one(
            *system._nb["args"], x, system.params, fopt, iopt, atol_a, rngp, k.POLL_GIL, stop)
    del rng
    arc = _arc(system, k, T, J, X, XD, code, detail, info, stats, ro)
    if caught.raised is not None:
        at_x0 = _at_x0(k, arc, detail)
        arc, exc = _raised_arc(system, arc, caught.raised)
        exc.arc = arc
        if at_x0:                    # at x0: raised at once, as on the Python path
            raise exc
        return finish(arc, ro.throw, ro.warn)
    if _plain(k, code, detail):             # rules.finish: nothing to raise or warn
        return arc
    if _at_x0(k, arc, detail):
        raise arc.exception
    return finish(arc, ro.throw, ro.warn)


def simulate_many_compiled(system: CompiledSystem, x0s: ArrayLike, t_max: float,
                           j_max: float = math.inf, *, parallel: bool = True,
                           chunk_bytes: int = 64 * 2**20, t0: float = 0.0, j0: int = 0,
                           priority: str = "jumps", rtol: float = 1e-6,
                           atol: float | ArrayLike = 1e-9, max_step: float = math.inf,
                           first_step: float | None = None, max_steps: float = 1_000_000,
                           max_samples: float = 10_000_000, zeno_jumps: int = 50,
                           zeno_time: float = 1e-12, zeno_rtol: float = 1e-7,
                           max_norm: float = math.inf,
                           seed: int | np.random.Generator | None = None, refine: int = 1,
                           throw: bool = False, warn: bool = True,
                           method: str | type[OdeSolver] = "RK45", reduce: tuple | None = None,
                           params: ArrayLike | None = None,
                           **unsupported: Any) -> ArcBatch:
    """Simulate a :class:`CompiledSystem` from many initial states, compiled and in parallel.

    Each run is exactly :func:`simulate_compiled`'s (same steps, events and
    arc); runs are spread over threads, one per core (``NUMBA_NUM_THREADS`` or
    ``numba.set_num_threads`` limits them), each taking the next few rows
    from a shared counter as it finishes: a thread slowed by other work on
    the machine takes fewer rows, so threads help under load too. The
    threads are Python threads running a GIL-free kernel (no numba threading
    layer: a fork-based process pool afterwards is safe, and several threads
    may run batches at once). The batch is processed in chunks
    whose sample pool stays under ``chunk_bytes``, sized by four runs spread
    over the batch (or, when the same system runs again with the same
    options and parameters, by the last batch's, every row in parallel);
    each run's samples go into the pool when it ends, and
    the runs that find no room run again, in parallel, in a later round
    sized for the longest run seen. Memory is the returned arcs plus one
    chunk's pool.

    A batch keeps going when one of its runs fails, as
    :func:`hybridsim.simulate_many`: a row whose initial state is not finite
    (cause ``NON_FINITE``), whose map fails at its x0 (``MAP_ERROR``) or whose
    run ends on a failure gets its own arc carrying the cause, and one
    :class:`hybridsim.BatchWarning` names the failed rows. Ctrl-C stops the
    batch: finished runs are kept, runs under way end ``CANCELED`` with the arc
    so far, runs never started get a one-sample ``CANCELED`` arc.

    Parameters
    ----------
    system : CompiledSystem
    x0s : array_like, shape (N, n)
        One initial state per row.
    parallel : bool
        False runs the batch on one core.
    chunk_bytes : int
        Memory budget of one chunk's sample pool.
    throw : bool
        False (default, as :func:`hybridsim.simulate_many`): failed rows keep
        their arcs. True: after the whole batch ran, the first failed row
        raises :class:`hybridsim.BatchError` (``.row``, ``.arc``, ``.arcs``).
    t_max, j_max, **options
        As in :func:`simulate_compiled`. With ``priority="random"`` the runs
        go one after another, each with its own ``numpy.random.default_rng(seed)``
        (as ``hs.simulate_many`` passes ``seed`` to every run).
    reduce : (grid, by_j, components), optional
        Keep of each row only its end and its states on ``grid`` (a float
        array: times, non-decreasing, ``by_j`` False; or jump counts, ``by_j``
        True), their first ``components`` components: no arcs are made
        (``hs.simulate_many(..., stats=)`` reduces them into a
        :class:`hybridsim.estimate.Stats`).
    params : array_like, shape (N, len(system.params)), optional
        Row ``i`` runs with ``params[i]`` as its ``p`` (default: every row
        with ``system.params``): a parameter sweep or a population of
        designs in one parallel batch (``hs.simulate_many(...,
        attributes=)`` builds it for any system). The arcs' ``system`` is
        ``system`` itself, its ``params`` as they are.

    Returns
    -------
    hybridsim.ArcBatch or RowEnds
        ``RowEnds`` with ``reduce``.
    hybridsim.ArcBatch
        A list of one arc per row of ``x0s``, in order. The arcs of runs
        ending at ``t_max`` or ``j_max`` take their samples and stats from the
        batch's compact pool on first access (views of it, as every row's
        arrays are); the batch's array fields (final states, jump counts and
        times...) are read off that pool without making them.

    Examples
    --------
    >>> import numpy as np
    >>> from hybridsim.compiled import CompiledSystem, simulate_many_compiled
    >>> timer = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1),
    ...                        jump_map=lambda x, t, j, p: np.zeros(1),
    ...                        jump_guard=lambda x, t, j, p: x[0] - p[0],
    ...                        state_dim=1, params=[1.0])
    >>> arcs = simulate_many_compiled(timer, [[0.0], [0.5]], t_max=2.0)
    >>> [a.jump_count for a in arcs]
    [2, 2]
    """
    _refuse_noise(system, "simulate_many_compiled")
    from ..options import check_bool as _check_bool
    from ..options import check_count as _check_count
    k = _load_kernel()
    _check_system(system)
    n = system.state_dim
    try:
        X0 = np.array(x0s, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise TypeError(f"x0s must be an (N, {n}) array of floats, got "
                        f"{type(x0s).__name__}") from e
    if X0.ndim != 2 or X0.shape[1] != n:
        raise ValueError(f"x0s must have shape (N, {n}), got {X0.shape}")
    X0 = np.ascontiguousarray(X0)
    parallel = _check_bool("parallel", parallel)
    chunk_bytes = _check_count("chunk_bytes", chunk_bytes, minimum=1)
    system.compile()
    ro, fopt, iopt, atol_a = _options(
        system, n, "simulate_many_compiled", method, unsupported,
        (t0, j0, t_max, j_max, priority, rtol, atol, max_step, first_step, max_norm,
         zeno_jumps, zeno_time, zeno_rtol, refine, max_steps, max_samples, throw, warn))
    mname = method_on("compiled", method)
    run, one_addr = _kernels(k, system, parallel, mname)
    P = _row_params(system, params, len(X0))
    maps = system._nb["args"]
    N = len(X0)
    arcs = [None] * N
    where = {"t0": ro.t0, "j0": ro.j0}
    good = np.isfinite(X0).all(axis=1)
    for i in np.flatnonzero(~good).tolist():        # as hs.simulate_many: the row's own arc
        arcs[i] = _one_sample(X0[i], where, Termination.NON_FINITE,
                              f"the initial state is not finite: {X0[i]}",
                              ValueError(f"x0 must be finite, got {X0[i]}"), system)
    rows = np.flatnonzero(good)
    canceled = k.CANCELED
    # watching: the rows one after another (their crossings come back with each run)
    watching = system.watch is not None
    if watching:
        from ._watch import watch_options

    def one(i, rng):
        stop = np.zeros(1, np.int64)
        fo = fopt
        if watching:
            try:
                fo = watch_options(system, X0[i], ro.t0, ro.j0, fopt, _row(P, i))
            except MapError as e:       # at x0: the row's own arc
                arcs[i] = _one_sample(X0[i], where, Termination.MAP_ERROR, str(e), e, system)
                return False, 1
        with _CatchRaised(stop) as caught:
            T, J, X, XD, code, detail, info, stats = run(
                *maps, X0[i], _row(P, i), fo, iopt, atol_a, rng[1], k.POLL_GIL, stop)
        arcs[i] = _arc(system, k, T, J, X, XD, code, detail, info, stats, ro)
        if caught.raised is not None:
            arcs[i] = _raised_arc(system, arcs[i], caught.raised)[0]
            arcs[i].exception.arc = arcs[i]
            return False, len(T)
        return code == canceled, len(T)

    if reduce is not None:
        reduce = _check_reduce(reduce, n)
    if reduce is not None and ro.prio != Priority.RANDOM and not watching:
        return _reduced(k, system, X0, rows, arcs, one, one_addr, maps, P, fopt, iopt_rows_of(
            iopt), atol_a, _rng_for(k, ro.prio, seed), parallel, reduce, mname, where)
    stopped = False
    runs = []               # the pooled rows' record, for the batch's fields (ArcBatch)
    # no cyclic garbage collection while the arcs are built (a 100,000-row batch
    # makes 300,000 objects and triggered 400 collections, 6% of its time)
    gc_on = gc.isenabled()
    gc.disable()
    try:
        if ro.prio == Priority.RANDOM or not parallel or watching:
            for i in rows.tolist():
                stopped, _ = one(i, _rng_for(k, ro.prio, seed))
                if stopped:
                    break
        else:
            rng = _rng_for(k, ro.prio, seed)
            # a few runs alone first, spread over the batch (a sweep's first
            # rows may be its shortest runs): their length sizes the pools. A
            # batch of the same system, options and parameters again (a Monte
            # Carlo's or a falsification's next batch) takes the last one's
            # length and runs every row in parallel
            sizes = system.__dict__.setdefault("_batch_lengths", {})
            skey = _sizes_key(mname, fopt, iopt, atol_a, P)
            longest = sizes.get(skey, 0)
            if not longest:
                pick = np.unique(np.linspace(0, len(rows) - 1, min(4, len(rows))).round()
                                 .astype(np.int64)) if len(rows) else np.zeros(0, np.int64)
                first = rows[pick].tolist()
                rows = np.delete(rows, pick)
                longest = 2
                for i in first:
                    stopped, m = one(i, rng)
                    longest = max(longest, m)
                    if stopped:
                        break
                if not stopped:
                    if len(sizes) >= 16:
                        sizes.clear()
                    sizes[skey] = longest
            cap = 1 << math.ceil(math.log2(longest * 1.25 + 1))
            seen = longest                       # the longest run of this batch, so far
            if len(rows) <= _ALONE and longest <= _SHORT and \
                    threading.current_thread() is threading.main_thread():
                for i in rows.tolist():          # a few short runs: here, one by one
                    stopped, m = one(i, rng)
                    seen = max(seen, m)
                    if stopped:
                        break
                rows = rows[:0]
            heavy = longest > _LONG
            per = (2 + 2 * n) * 8
            c = 0
            stop = np.zeros(1, np.int64)
            iopt_rows = iopt.copy()
            iopt_rows[lay.I_ROW] = 1
            # the arcs of runs ending at t_max or j_max (most rows): built here,
            # their message the cause's own (as _arc would)
            plain = {c: (t, t.message) for c, t in ((k.T_MAX, Termination.T_MAX),
                                                     (k.J_MAX, Termination.J_MAX))}
            named = (k.DETAIL_LOOP, k.DETAIL_INSTANT, k.DETAIL_CHATTER)
            retry = []              # runs that found no room: the next round's rows
            while not stopped:
                if c >= len(rows):
                    if not retry:
                        break
                    rows, retry, c = np.array(retry, np.int64), [], 0
                B = int(max(64, min(len(rows) - c, chunk_bytes // (cap * per))))
                B = min(B, len(rows) - c)
                idx = rows[c:c + B]
                # the chunk's compact pool: room for B runs of cap samples, each
                # run's rows claimed when it ends (pages never written are never
                # made; the pool is cut to what was written afterwards)
                size = B * cap
                iopt_rows[lay.I_CAP] = cap         # each run's first buffers: no doubling
                TT, JJ = _untouched((size,)), _untouched((size,), np.int64)
                XX, XXD = _untouched((size, n)), _untouched((size, n))
                fill = np.zeros(1, np.int64)
                AT = np.full(B, -1, np.int64)         # -1: not in the pool (not run, no room)
                NS, CA, DE = (np.zeros(B, np.int64) for _ in range(3))
                INFO, ST = np.empty((B, 6)), np.zeros((B, 6), np.int64)
                with _CatchRaised(None) as caught:
                    stopped = _interruptible(
                        k.run_rows, (one_addr, *maps, X0[idx] if B < N else X0,
                                     P[idx] if len(P) > 1 and B < N else P, fopt,
                                     iopt_rows, atol_a, rng[1], k.POLL_NONE, stop,
                                     np.zeros(1, np.int64), _CHUNK, TT, JJ, XX, XXD, fill, AT,
                                     NS, CA, DE, INFO, ST, *_no_grid(n)),
                        stop, _threads(parallel, B, heavy))
                if caught.raised is not None and not stopped:
                    # a map raised in some row: the chunk's rows run again one by
                    # one, each run's own exception caught (the others' arcs are
                    # the same: these runs draw no coins)
                    for i in idx.tolist():
                        stopped, _ = one(i, rng)
                        if stopped:
                            break
                    c += B
                    continue
                used = int(fill[0])
                pool = tuple(_cut(a, used) for a in (TT, JJ, XX, XXD))
                fits = AT >= 0
                starts = np.where(fits, AT, 0)
                ends = starts + np.where(fits, NS, 0)
                easy = fits & (NS > 0) & ~np.isin(DE, named)
                done = np.zeros(B, bool)
                for code, (term, msg) in plain.items():
                    sel = np.flatnonzero(easy & (CA == code))
                    if len(sel):
                        made = HybridArc._pooled(
                            pool, starts[sel].tolist(), ends[sel].tolist(), term, msg,
                            system, _stats_of(ST, sel))
                        for i, arc in zip(idx[sel].tolist(), made):
                            arcs[i] = arc
                        done[sel] = True
                        runs.append((pool, idx[sel], starts[sel], ends[sel], term))
                Tf, Jf, Xf, XDf = pool
                for r in np.flatnonzero(~done).tolist():
                    i = int(idx[r])
                    o, e = int(starts[r]), int(ends[r])
                    if fits[r]:
                        ca = int(CA[r])
                        if not (stopped and ca == canceled and NS[r] == 1 and
                                not ST[r].any()):
                            arcs[i] = _arc(system, k, Tf[o:e], Jf[o:e], Xf[o:e], XDf[o:e],
                                           ca, int(DE[r]), INFO[r], ST[r].tolist(), ro)
                    elif not stopped:
                        # no room left in the pool: run again in a later round,
                        # in parallel, with room for the longest run seen (so
                        # a batch whose first rows are its shortest runs does
                        # not run the others one by one)
                        retry.append(i)
                # the next chunk's room: the longest run seen, with margin
                longest = int(NS.max()) if B else cap
                seen = max(seen, longest)
                cap = max(cap, 1 << math.ceil(math.log2(max(longest, 2) * 1.25)))
                del TT, JJ, XX, XXD, pool
                c += B
            # the next batch's pools sized for the longest run seen (a batch
            # whose first runs were short would have every later run run twice)
            if not stopped and seen > sizes.get(skey, 0):
                if len(sizes) >= 16 and skey not in sizes:
                    sizes.clear()
                sizes[skey] = seen
    except KeyboardInterrupt:           # between two kernels: the runs so far are kept
        stopped = True
    finally:
        if gc_on:
            gc.enable()
    if stopped:
        for i in range(N):
            if arcs[i] is None:
                arcs[i] = _one_sample(X0[i], where, Termination.CANCELED,
                                      "never started (the batch was interrupted)", None,
                                      system)
    if reduce is not None:                  # rows one by one: every row has its arc
        return RowEnds.of_arcs(arcs, n, len(reduce[0]), reduce[2])
    return finish_batch("simulate_many_compiled", ArcBatch._of_pools(arcs, n, runs), ro.throw,
                        ro.warn)


def _row_params(system, params, N):
    """``simulate_many_compiled``'s ``params``, checked: a C-contiguous (N, m)
    array of finite floats (m: ``system.params``' length), or ``system.params``
    as its one row."""
    if params is None:
        return np.ascontiguousarray(system.params, dtype=np.float64).reshape(1, -1)
    m = system.params.size
    try:
        P = np.array(params, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise TypeError(f"params must be an (N, {m}) array of floats (one row of p per row "
                        f"of x0s), got {type(params).__name__}") from e
    if P.shape != (N, m):
        raise ValueError(f"params must have shape (N, len(system.params)) = ({N}, {m}), one "
                         f"row of p per row of x0s, got {P.shape}")
    if not np.isfinite(P).all():
        bad = np.flatnonzero(~np.isfinite(P).all(axis=1))
        raise ValueError(f"params must be finite, rows {bad[:5].tolist()} are not")
    return np.ascontiguousarray(P) if N else P.reshape(1, m)


def _row(P, i):
    """Row ``i``'s p: its own row of ``P``, or the one row every row shares."""
    return P[i] if len(P) > 1 else P[0]


def _sizes_key(mname, fopt, iopt, atol_a, P):
    """The key of a batch's run lengths (``system._batch_lengths``): the method,
    the options and the parameters (rows of their own: their shape only, as a
    population of designs changes them batch by batch)."""
    pk = P.tobytes() if len(P) == 1 else ("rows", P.shape)
    return (mname, fopt.tobytes(), iopt.tobytes(), atol_a.tobytes(), pk)


def _no_grid(n):
    """:func:`_batch.run_rows`' reduction arguments of a batch that keeps its arcs."""
    return (np.zeros(0), 0, np.zeros((0, n)), np.zeros(0), np.zeros(0, np.int64),
            np.zeros((0, 0, 0)), np.zeros((0, 0), bool))


class RowEnds:
    """What a reduced batch keeps of each row (``simulate_many_compiled(...,
    reduce=)``): its end (``x`` (N, n), ``t``, ``j``, ``cause``: the cause
    codes of :data:`hybridsim.rules.CAUSES`) and its states on the grid
    (``grid_x`` (N, G, components), NaN where ``grid_ok`` (N, G) is False: the
    run has no state there). ``arcs``: ``{row: arc}`` of the rows that have
    an arc instead (a non-finite x0, a map that raised, never started),
    whose other fields are unset (NaN, cause -1)."""

    def __init__(self, N, n, G, nk):
        self.x = np.full((N, n), np.nan)
        self.t = np.full(N, np.nan)
        self.j = np.full(N, -1, np.int64)
        self.cause = np.full(N, -1, np.int64)
        self.grid_x = np.full((N, G, nk), np.nan)
        self.grid_ok = np.zeros((N, G), bool)
        self.arcs = {}

    @classmethod
    def of_arcs(cls, arcs, n, G, nk):
        out = cls(len(arcs), n, G, nk)
        out.arcs = dict(enumerate(arcs))
        return out

    def __len__(self):
        return len(self.t)


def iopt_rows_of(iopt):
    """The options of a batch's rows (:func:`_batch.run_rows`: each run's
    buffers returned uncopied)."""
    out = iopt.copy()
    out[lay.I_ROW] = 1
    return out


def _check_reduce(reduce, n):
    """``simulate_many_compiled``'s ``reduce``, checked: ``(grid, by_j,
    components)`` with ``grid`` a 1-D array of finite non-decreasing numbers
    (whole non-negative jump counts with ``by_j``) and ``1 <= components <= n``."""
    from ..options import check_bool, check_count
    if not isinstance(reduce, (tuple, list)) or len(reduce) != 3:
        raise TypeError("reduce must be a tuple (grid, by_j, components), got "
                        f"{type(reduce).__name__}"
                        + (f" of length {len(reduce)}" if isinstance(reduce, (tuple, list))
                           else ""))
    grid, by_j, nk = reduce
    by_j = check_bool("reduce's by_j", by_j)
    try:
        grid = np.asarray(grid, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise TypeError("reduce's grid must be a 1-D array of numbers, got "
                        f"{type(grid).__name__}") from e
    if grid.ndim != 1 or not np.isfinite(grid).all() or (np.diff(grid) < 0).any():
        raise ValueError("reduce's grid must be a 1-D array of finite non-decreasing "
                         f"{'jump counts' if by_j else 'times'}, got shape {grid.shape}")
    if by_j and ((grid < 0).any() or (grid != np.round(grid)).any()):
        raise ValueError("reduce's grid must hold whole non-negative jump counts with "
                         "by_j=True")
    nk = check_count("reduce's components", nk, minimum=1)
    if nk > n:
        raise ValueError(f"reduce's components must be at most the state's dimension {n}, "
                         f"got {nk}")
    return grid, by_j, nk


def _reduced(k, system, X0, rows, arcs, one, one_addr, maps, P, fopt, iopt_rows, atol_a, rng,
             parallel, reduce, mname, where):
    """:func:`simulate_many_compiled` with ``reduce``: the good ``rows`` in one
    call of :func:`_batch.run_rows` keeping each row's end and grid states
    (:class:`RowEnds`), the others' arcs (``arcs``, made by the caller) kept."""
    grid, by_j, nk = reduce
    grid = np.ascontiguousarray(grid, dtype=np.float64)
    N, n = X0.shape
    out = RowEnds(N, n, len(grid), nk)
    out.arcs = {i: a for i, a in enumerate(arcs) if a is not None}
    B = len(rows)
    if B == 0:
        return out
    sizes = system.__dict__.setdefault("_batch_lengths", {})
    iopt = iopt_rows.copy()
    iopt[lay.I_ROW] = 0
    skey = _sizes_key(mname, fopt, iopt, atol_a, P)
    iopt_rows[lay.I_CAP] = 1 << math.ceil(math.log2(max(sizes.get(skey, 48), 2) * 1.25 + 1))
    XS = X0 if B == N else np.ascontiguousarray(X0[rows])
    PS = P if B == N or len(P) == 1 else np.ascontiguousarray(P[rows])
    empty_f, empty_i = np.zeros(0), np.zeros(0, np.int64)
    NS, CA, DE = (np.zeros(B, np.int64) for _ in range(3))
    INFO, ST = np.empty((B, 6)), np.zeros((B, 6), np.int64)
    XF, TF, JF = np.full((B, n), np.nan), np.full(B, np.nan), np.full(B, -1, np.int64)
    XG, OK = np.full((B, len(grid), nk), np.nan), np.zeros((B, len(grid)), bool)
    stop = np.zeros(1, np.int64)
    with _CatchRaised(None) as caught:
        stopped = _interruptible(
            k.run_rows, (one_addr, *maps, XS, PS, fopt, iopt_rows, atol_a, rng[1], k.POLL_NONE,
                         stop, np.zeros(1, np.int64), _CHUNK, empty_f, empty_i,
                         np.zeros((0, n)), np.zeros((0, n)), np.zeros(1, np.int64),
                         np.zeros(B, np.int64), NS, CA, DE, INFO, ST, grid, int(bool(by_j)),
                         XF, TF, JF, XG, OK),
            stop, _threads(parallel, B, sizes.get(skey, 0) > _LONG))
    ran = NS > 0
    longest = int(NS.max())
    if longest > sizes.get(skey, 0) and not stopped:   # the next batch's first buffers
        if len(sizes) >= 16:
            sizes.clear()
        sizes[skey] = longest
    out.x[rows], out.t[rows], out.j[rows] = XF, TF, JF
    out.cause[rows] = np.where(ran, CA, -1)
    out.grid_x[rows], out.grid_ok[rows] = XG, OK
    if caught.raised is not None and not stopped:
        # a map raised in some row: each row's own exception, from its arc
        # (the others' ends are the same again: these runs draw no coins)
        for i in rows.tolist():
            if one(i, rng)[0]:
                break
            out.arcs[i] = arcs[i]
            out.cause[i] = -1
    for r in np.flatnonzero(~ran).tolist():          # never started (Ctrl-C)
        i = int(rows[r])
        out.arcs[i] = _one_sample(X0[i], where, Termination.CANCELED,
                                  "never started (the batch was interrupted)", None, system)
    return out
