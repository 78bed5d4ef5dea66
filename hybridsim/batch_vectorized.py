"""Vectorized batch integrator: many trajectories of one hybrid system at once.

:func:`simulate_vectorized` integrates a batch of initial states of a system
whose maps are written over batches (``system.vectorized = True``) together in
numpy: an embedded Dormand-Prince 5(4) pair (scipy's RK45 coefficients; or
scipy's DOP853, ``method="DOP853"``) with a per-trajectory step size, error
control and dense output, per-trajectory event
location on the dense output, per-trajectory jumps, and the same priority,
limits, termination causes and messages as :func:`hybridsim.simulate`.

Each trajectory follows the rules ``simulate(..., method="RK45")`` (or
``"DOP853"``) follows (the same initial-step rule, step-size controller and
first step after an event; for DOP853 the interior search on each step's
cubic Hermite, a hit confirmed on the dense output) and locates its events
with the same algorithm as
:func:`hybridsim.events.locate_event` (a start on the guard's zero probed and
modelled by a quadratic, bisection of the set indicators until the guard
changes sign, safeguarded secant steps under Brent's test, the indicators
confirming the bracket; to :func:`hybridsim.rules.event_tolerance`), run
over the rows in numpy. The arithmetic is batched, so rounding differs: the
step sizes can drift apart (sample times by up to ~1e-7 at rtol 1e-10 in the
tests, and a row's steps can depend on the other rows of its batch), and the
results agree with a loop of :func:`hybridsim.simulate` to the integrator's
tolerance, not to rounding; where the steps agree, jump times agree to
rounding.

The decisions are :mod:`hybridsim.rules`' own: :func:`~hybridsim.rules.jumps_now`
and :func:`~hybridsim.rules.needs_coin` at decision points, tables of
:func:`~hybridsim.rules.event_outcome` and :func:`~hybridsim.rules.after_jump`
(built once per run from the rules) at events and after jumps,
:func:`~hybridsim.rules.post_jump_probe` for a state after an event's jump
that is in neither set, :func:`~hybridsim.rules.is_jump_loop` on a per-row
count of jumps at one instant from C, and each row's message from
:func:`~hybridsim.rules.message`. Every given guard enters the event
function, beside the other set's indicator (as on the Python path).

The maps over rows are in :mod:`hybridsim._batch_maps`, the sample store in
:mod:`hybridsim._batch_samples`, the steps and their dense output in
:mod:`hybridsim._batch_steps`, event location and the decision at an event in
:mod:`hybridsim._batch_events` (the last two as the run's base classes).
"""
from __future__ import annotations

import bisect
import inspect
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import OdeSolver

from ._batch_events import _RowEvents
from ._batch_maps import _VMaps
from ._batch_samples import _SampleLog
from ._batch_steps import _DOP, _ERR_EXP, _NS, _RK4, _RK45, _RowSteps
from ._batch_watch import _RowWatch
from ._interrupt import SigintLatch
from ._progress import make_bar
from ._rk import fixed_step
from .arc import Crossings, HybridArc, Termination
from .arc_batch import ArcBatch
from .history import BatchHistory
from .options import (
    FIXED_STEP,
    check_bool,
    check_delays,
    check_seed,
    check_unsupported,
    check_x0s,
    method_on,
    parse_run,
    refuse,
    resolve_method,
)
from .rules import (
    CAUSES,
    CHATTER_RTOL,
    NO_CAUSE,
    MapError,
    Priority,
    after_jump,
    chatter_step,
    event_outcome,
    finish_batch,
    is_jump_loop,
    is_sticking,
    jumps_now,
    message,
    needs_coin,
    post_jump_probe,
    time_scale,
    zeno_short,
)
from .system import (
    HybridSystem,
    as_map,
    check_watch_direction,
    watch_directions,
)

__all__ = ["simulate_vectorized"]

_EPS = np.finfo(float).eps
# options of simulate() the batch integrator does not implement (refused by
# options.check_unsupported unless at their do-nothing value)
_UNSUPPORTED = ("inputs", "prehistory", "dense", "t_eval", "dwell")


def _outcome_table(prio):
    """:func:`hybridsim.rules.event_outcome` for every combination of its bool
    arguments (code = 16 watching_D + 8 in_D_hi + 4 in_C_hi + 2 in_D_lo + coin):
    the rule itself, evaluated once per run, looked up per event row."""
    action = np.empty(32, dtype=np.int8)
    side = np.empty(32, dtype=np.int8)
    for code in range(32):
        bits = [bool(code >> k & 1) for k in (4, 3, 2, 1, 0)]
        act, sd = event_outcome(bits[0], bits[1], bits[2], bits[3], prio, bits[4])
        action[code], side[code] = int(act), sd
    return action, side


def _after_jump_table():
    """:func:`hybridsim.rules.after_jump` by (jumps >= j_max, short >= zeno_jumps):
    the rule's order of causes (J_MAX before ZENO), looked up per jumping row."""
    return np.array([[after_jump(int(full), int(zeno), 1, 1) for zeno in (0, 1)]
                     for full in (0, 1)], dtype=np.int64)


class _NonFiniteStep(Exception):
    """Internal: a row's dense output became non-finite inside an accepted step."""


def takes_options(kwargs, system=None):
    """Whether :func:`simulate_vectorized` implements these options of ``simulate``.

    It is Dormand-Prince 5(4) (``method="RK45"``, the default) or DOP853
    (not for a ``system`` reading its past) without dense output, inputs, a
    prehistory or ``t_eval`` (the options
    :func:`hybridsim.options.check_unsupported` refuses on the vectorized
    path); :func:`hybridsim.simulate_many` runs a vectorized system's rows
    through ``simulate`` otherwise.
    """
    try:
        method_on("vectorized", kwargs.get("method"), system)
    except (TypeError, ValueError):
        return False
    known = inspect.signature(simulate_vectorized).parameters
    for name, val in kwargs.items():
        if name in _UNSUPPORTED:
            try:
                check_unsupported("vectorized", {name: val})
            except ValueError:
                return False
        elif name not in known:
            return False
    return True


def _parse(system, x0s, t_max, j_max, kw, method, progress, seed, extra):
    """Validate the arguments of :func:`simulate_vectorized`: the shared options
    through :func:`hybridsim.options.parse_run` (the messages of
    :func:`hybridsim.simulate`), the others refused by
    :func:`hybridsim.options.check_unsupported`."""
    if not isinstance(system, HybridSystem):
        raise TypeError(f"system must be a hybridsim.HybridSystem, got {type(system).__name__}")
    if not system.vectorized:
        raise ValueError("system: simulate_vectorized needs a system with vectorized = True "
                         "(maps written over (N, n) batches); use hybridsim.simulate_many")
    for name in extra:
        if name not in _UNSUPPORTED:
            raise TypeError(f"simulate_vectorized() got an unexpected keyword argument {name!r}")
    n = system.state_dim
    if n is None or isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"{type(system).__name__}.state_dim must be a positive int, got {n!r}")
    n = int(n)
    X = check_x0s(x0s, n)            # the messages of simulate_many
    if X.shape[0] < 1:
        raise ValueError(f"x0s must have shape (N, {n}) with N >= 1 (one row per "
                         f"trajectory), got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        bad = np.flatnonzero(~np.isfinite(X).all(axis=1))
        raise ValueError(f"x0s must be finite; rows {bad[:10].tolist()} are not "
                         f"(row {bad[0]}: {X[bad[0]]})")
    ro = parse_run(system, n, t_max=t_max, j_max=j_max, **kw)
    resolve_method(method)          # a bad method: simulate's message
    method = method_on("vectorized", method, system)
    if method in FIXED_STEP:
        fixed_step(method, ro.max_step)
    check_unsupported("vectorized", extra)
    if int(system.input_dim or 0) > 0:
        refuse("vectorized", "inputs", f"<input_dim={system.input_dim}>")
    check_delays(system)
    progress = check_bool("progress", progress, allow_none=True)
    rng = check_seed(seed, build=ro.prio == Priority.RANDOM)
    return n, X, ro, progress, rng, method


def simulate_vectorized(system: HybridSystem, x0s: ArrayLike, t_max: float,
                        j_max: float = math.inf, *, priority: str = "jumps",
                        rtol: float = 1e-6, atol: float | ArrayLike = 1e-9,
                        max_step: float = math.inf, first_step: float | None = None,
                        zeno_jumps: int = 50, zeno_time: float = 1e-12,
                        zeno_rtol: float = 1e-7, progress: bool | None = False,
                        method: str | type[OdeSolver] = "RK45", t0: float = 0.0, j0: int = 0,
                        max_norm: float = math.inf,
                        seed: int | np.random.Generator | None = None, throw: bool = False,
                        warn: bool = True, refine: int = 1, max_steps: float = 1_000_000,
                        max_samples: float = 10_000_000, **unsupported: Any) -> ArcBatch:
    r"""Simulate a vectorized hybrid system from many initial states at once.

    The whole batch is integrated together in numpy by an embedded
    Dormand-Prince 5(4) pair with scipy's RK45 coefficients (or DOP853's,
    ``method="DOP853"``), each trajectory
    with its own step size (scipy's step-size rule), error control, dense
    output, event location and jumps. Only the trajectories still running are
    evaluated. Semantics, termination causes and messages are those of
    :func:`hybridsim.simulate`; the arcs carry ``xdot`` and ``stats`` as
    its arcs do. Failed rows follow the batch policy of
    :func:`hybridsim.simulate_many` (:func:`hybridsim.rules.finish_batch`).

    Parameters
    ----------
    system : HybridSystem
        With ``vectorized = True``: ``flow_map``/``jump_map`` take ``x`` of
        shape (k, n), ``t`` (k,) and ``j`` (k,) int (any of the signatures
        ``(x)``, ``(x, t)``, ``(x, t, j)``, ``(x, t, j, u)``; ``u`` is None)
        and return (k, n) arrays; ``flow_set``/``jump_set`` return (k,) bools;
        ``jump_guard``/``flow_guard`` return (k,) or (k, m) floats (the set is
        where the minimum over the last axis is >= 0).
    x0s : array_like, shape (N, n)
        One initial state per row (time-major, as every state array here).
    t_max : float
        Flows stop at t_max (a sample there); may be ``inf``.
    j_max : int or inf, optional
        At most this many jumps per trajectory.
    priority : {"jumps", "flows", "random"}
        As in :func:`hybridsim.simulate`; ``"random"`` draws one fair coin per
        trajectory and decision from ``numpy.random.default_rng(seed)`` (the
        draws differ from those of a loop of ``simulate``).
    rtol, atol, max_step, first_step : float
        Tolerances and step bounds, as in :func:`hybridsim.simulate`
        (``atol`` may be an (n,) array; ``max_step`` is also capped by
        ``system.max_step``).
    zeno_jumps, zeno_time, zeno_rtol : int, float, float
        Zeno rule of :func:`hybridsim.simulate`, per trajectory.
    max_steps : int or inf
        Accepted steps per trajectory before it ends with ``MAX_STEPS``.
    progress : bool or None
        A tqdm bar over finished trajectories (None: at a terminal and in a
        notebook; see :func:`hybridsim._progress.progress_enabled`).
    method : {"RK45", "DOP853", "RK4"} or scipy's class
        The Runge-Kutta pair (scipy's coefficients, error norm, step-size
        controller and dense output; DOP853 takes several times fewer steps
        at tight tolerances, and its dense output, three more evaluations of
        the flow map, is made only for steps with an event or refined
        samples). DOP853 not for a system that reads its past. "RK4": the
        classic method with the fixed step ``max_step`` (finite), as
        ``simulate(method="RK4")`` (:class:`hybridsim._rk.RK4`). Other
        methods raise ``ValueError`` naming these.
    t0, j0 : float, int
        Initial hybrid time of every trajectory.
    max_norm : float
        A trajectory whose state norm exceeds it stops with ``BLOWUP``.
    seed : int or numpy Generator, optional
        Seed of ``priority="random"``.
    refine : int
        Samples stored per step, as in :func:`hybridsim.simulate`:
        ``refine - 1`` dense-output points inside each step.
    max_samples : int or inf
        Samples stored per trajectory; a trajectory that would store more
        ends with ``MAX_STEPS`` (as in :func:`hybridsim.simulate`).
    throw : bool
        False (the default here, unlike :func:`hybridsim.simulate`): every
        row runs and a failed row (``MAP_ERROR``, ``NON_FINITE``,
        ``BLOWUP``, ``SOLVER_FAILED``, ``MAX_STEPS``) keeps its arc and
        cause. True: once the batch has run, raise
        :class:`hybridsim.BatchError` for the first failed row (``.row``,
        ``.arc``, ``.arcs``).
    warn : bool
        Issue one :class:`hybridsim.BatchWarning` naming the failed rows
        (default True), as :func:`hybridsim.simulate_many` does.
    **unsupported
        ``inputs``, ``prehistory``, ``t_eval`` (must be None) and ``dense``
        (must be False) are accepted for compatibility with
        :func:`hybridsim.simulate_many` and refused otherwise
        (:func:`hybridsim.options.refuse`); anything else raises ``TypeError``.

    Returns
    -------
    hybridsim.ArcBatch
        A list of one arc per row of ``x0s``, in order (their fields as
        arrays: :class:`hybridsim.ArcBatch`), each with samples at every
        accepted step end and at every event (``t`` (M,), ``j`` (M,),
        ``x`` (M, n)), the flow map's value at each sample (``xdot``; NaN
        at a jump's sample that jumps again, where the state may be outside
        C) and the row's ``stats`` (the keys of :func:`hybridsim.simulate`'s).

    Raises
    ------
    MapError
        A map raises or returns a wrong shape at the initial states (chained
        from the map's exception).
    BatchError
        ``throw=True`` and a row failed.
    ValueError, TypeError
        Bad arguments (each message names the argument; the same class and
        message as :func:`hybridsim.simulate` for the options they share).

    Notes
    -----
    A user map that raises during the run is retried row by row; only the
    rows that still fail stop, with cause ``MAP_ERROR`` (an error at the
    initial states is raised, as in :func:`hybridsim.simulate`;
    :func:`hybridsim.simulate_many` isolates such rows instead). A
    non-finite state (a step's end or its dense output) ends the row with
    ``NON_FINITE``, a guard returning NaN with ``MAP_ERROR`` naming it.

    Ctrl-C (KeyboardInterrupt) ends every trajectory still running with
    ``CANCELED``, keeping its samples so far and the finished trajectories.

    A system that reads its past (``needs_history``, ``delays``) runs here
    too: its maps get ``self.history`` as a
    :class:`hybridsim.BatchHistory` of the rows they are called on
    (``history(s)`` returns the (k, n) states, s a float or one time per
    row; the past before t0 is the constant x0), and every row's flows stop
    at its delay breakpoints (t0 + tau, each jump time + tau), as in
    :func:`hybridsim.simulate`; ``history.integral(fn, a, b)`` integrates
    each row's window (``fn`` called on batches).
    Every accepted step's dense output is kept: memory grows with the
    steps, about 5 n floats a step per row.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> timer = hs.HybridSystem.from_functions(
    ...     flow_map=lambda x: np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
    ...     jump_guard=lambda x: x[:, 0] - 1.0, flow_guard=lambda x: 1.0 - x[:, 0],
    ...     state_dim=1, vectorized=True)
    >>> arcs = simulate_vectorized(timer, [[0.0], [0.5]], t_max=2.2)
    >>> [np.round(a.jump_times, 12).tolist() for a in arcs]
    [[1.0, 2.0], [0.5, 1.5]]
    >>> sorted(arcs[0].stats)
    ['events', 'flows', 'nfev', 'njev', 'nlu', 'rejected', 'steps']
    """
    n, X, ro, progress, rng, method = _parse(
        system, x0s, t_max, j_max, dict(
            t0=t0, j0=j0, priority=priority, rtol=rtol, atol=atol, max_step=max_step,
            first_step=first_step, max_norm=max_norm, zeno_jumps=zeno_jumps,
            zeno_time=zeno_time, zeno_rtol=zeno_rtol, refine=refine, max_steps=max_steps,
            max_samples=max_samples, throw=throw, warn=warn),
        method, progress, seed, unsupported)
    run = _BatchRun(system, X, n, ro, rng, method)
    run.pbar = make_bar(progress, total=len(X), desc="simulate_vectorized", unit="run")
    try:
        with SigintLatch() as run.latch:
            run.run()
    except KeyboardInterrupt:       # Ctrl-C: every trajectory still running is canceled
        run.cancel()
    except MapError as e:           # at x0: raised, with the failing row's arc (one sample)
        if e.arc is None:
            r = getattr(e, "row", None) or 0
            e.arc = HybridArc._trusted(
                np.array([ro.t0]), np.array([ro.j0], dtype=np.int64), X[r:r + 1].copy(),
                Termination.MAP_ERROR, message(Termination.MAP_ERROR, error=str(e)), e,
                components=system.components, system=system)
        raise
    finally:
        if run.pbar is not None:
            run.pbar.close()
    return finish_batch("simulate_vectorized", ArcBatch(run.arcs(system), n), ro.throw, ro.warn)


class _BatchRun(_RowSteps, _RowEvents, _RowWatch):
    """State of a batch run: one entry per trajectory in every array."""

    def __init__(self, system, X, n, ro, rng, method="RK45"):
        N = len(X)
        self.N, self.n = N, n
        self.latch = None            # simulate_vectorized's SigintLatch
        # the method: RK45's stages and exponent, DOP853's (``self.dop``) or RK4's
        # fixed step (``self.fixed``: its tableau, the dense output in RK45's form)
        self.dop = _DOP if method == "DOP853" else None
        self.fixed = method in FIXED_STEP
        self.tableau = _RK4 if self.fixed else _RK45
        self.ns = _DOP["ns"] if self.dop else 4 if self.fixed else _NS
        self.err_exp = _DOP["exp"] if self.dop else _ERR_EXP
        self.maps = _VMaps(system, n)
        self.maps.run = self
        self.t_max, self.j_max, self.prio = ro.t_max, ro.j_max, ro.prio
        self.rtol, self.atol, self.max_step = ro.rtol, ro.atol, ro.max_step
        self.zeno_jumps, self.zeno_time, self.max_norm = ro.zeno_jumps, ro.zeno_time, ro.max_norm
        self.zeno_rtol, self.max_steps = ro.zeno_rtol, ro.max_steps
        self.max_samples = ro.max_samples
        self.rng = rng
        self.refine = ro.refine
        self.pbar = None
        t0, j0 = ro.t0, ro.j0
        # per-trajectory state
        self.t = np.full(N, t0)
        self.j = np.full(N, j0, dtype=np.int64)
        self.x = X.copy()
        self.fx = np.zeros((N, n))                  # f at (t, x): first stage (FSAL)
        first_step = ro.first_step
        self.h = np.full(N, np.nan if first_step is None else first_step)  # step hint
        self.rejected = np.zeros(N, dtype=bool)     # last attempt was rejected
        self.nonfinite = np.zeros(N, dtype=bool)    # its stages were not finite
        self.inD_prev = np.zeros(N, dtype=bool)
        self.force = np.zeros(N, dtype=bool)        # an event asks for a jump
        self.short = np.zeros(N, dtype=np.int64)    # consecutive short flows (Zeno)
        self.zref = np.zeros(N)                     # shrinking streak's reference (Zeno)
        self.longest = np.zeros(N)                  # longest flow so far (chattering)
        self.tiny = np.zeros(N, dtype=np.int64)     # consecutive tiny flows against it
        # consecutive jumps at one instant, each from a state in C (rules.is_jump_loop)
        self.loop = np.zeros(N, dtype=np.int64)
        self.same = np.zeros(N, dtype=np.int64)     # ... from C or not
        # the bracket (lo, x_lo, x_hi) of a located event a row jumps from at hi
        # (pend), then the decision after that jump (post): rules.post_jump_probe
        self.pend = np.zeros(N, dtype=bool)
        self.post = np.zeros(N, dtype=bool)
        self.pend_lo = np.zeros(N)
        self.pend_xlo = np.zeros((N, n))
        self.pend_xhi = np.zeros((N, n))
        self.flows3 = np.full((N, 3), np.inf)        # the last three flow lengths
        self.t0 = t0
        self.t_last = np.full(N, t0)
        self.t_flow0 = np.full(N, t0)               # start of the current flow
        self.t_step = np.full(N, t0)                # end of the step being examined
        self.jumps = np.zeros(N, dtype=np.int64)
        self.decide = np.ones(N, dtype=bool)        # at a decision point (jump/flow/stop)
        self.done = np.zeros(N, dtype=bool)
        self.bad = np.zeros(N, dtype=bool)          # a map failed on this row
        self.bad_exc = [None] * N
        self.cause = [None] * N
        self.message = [None] * N
        self.exception = [None] * N
        self.keep = None                            # samples kept per row (max_samples)
        # statistics, the keys of simulate's arc.stats
        self.steps = np.zeros(N, dtype=np.int64)     # accepted steps
        self.attempts = np.zeros(N, dtype=np.int64)  # step attempts
        self.nfev = np.zeros(N, dtype=np.int64)
        self.events = np.zeros(N, dtype=np.int64)
        self.flows = np.zeros(N, dtype=np.int64)
        self.log = _SampleLog(N, n)
        m = self.maps
        self.watch_D = m.has_D and self.prio != Priority.FLOWS
        # every given guard goes into the event function, beside the other set's
        # indicator (which, with the guards' sets, decides membership: _pred)
        self.use_phi = ((self.watch_D and m.hD is not None)
                        or (m.has_C and m.hC is not None))
        self.ev_action, self.ev_side = _outcome_table(self.prio)
        self.after = _after_jump_table()
        # every watched set is its guard's: membership and guard value from one call
        self.shared = (self.use_phi and (not m.has_C or (m.C_from_guard and m.hC is not None))
                       and (not self.watch_D or (m.D_from_guard and m.hD is not None)))
        # the past, for maps that read it: segments per row, and the delay breakpoints
        # (t0 + d, each jump time + d) where every flow stops, as in simulate
        self.delays = check_delays(system)
        self.hist = None
        if system.needs_history or self.delays:
            self.hist = BatchHistory(t0, X, j0, output=as_map(system.output, "output"))
            system._bind_history(self.hist)
            m.hist = self.hist
        self.breaks = [sorted(t0 + d for d in self.delays) for _ in range(N)]
        self.bp = np.array([b[0] if b else np.inf for b in self.breaks])
        # watched functions: their values where each row's recorded flow ends
        # (``w_v``, at ``self.t``), the start of its flow after a jump or at x0
        # (``w_floor``), the direction filter, and the crossings found per row
        self.watching = m.W is not None
        self.w_v = None
        self.w_floor = np.full(N, -np.inf)
        self.w_dir = None
        self.w_direction = (None if system.watch is None
                            else check_watch_direction(system.watch_direction))
        self.cross = [[] for _ in range(N)] if self.watching else None

    # ------------------------------------------------------------ helpers
    def _stop(self, rows, cause, kind=None, **fields):
        """End trajectories ``rows`` with ``cause``; the message is
        :func:`hybridsim.rules.message` of ``kind`` with ``fields`` (arrays
        indexed like ``rows``, or one value for all)."""
        per = {k: v for k, v in fields.items() if isinstance(v, (np.ndarray, list))}
        same = {k: v for k, v in fields.items() if k not in per}
        plain = not fields and kind is None
        count = 0
        for i, r in enumerate(rows):
            if self.done[r]:
                continue
            self.done[r] = True
            count += 1
            self.cause[r] = cause
            if plain:
                self.message[r] = cause.message
            else:
                f = dict(same)
                for k, v in per.items():
                    f[k] = v[i]
                self.message[r] = message(cause, kind, **f)
        if self.pbar is not None and count:
            self.pbar.update(count)

    def cancel(self):
        """End every trajectory still running with ``CANCELED`` (after Ctrl-C)."""
        rows = np.flatnonzero(~self.done)
        log = self.log
        log.settle()                # the interrupt may have landed inside an append
        last = log.last[rows]       # where each row stopped: its last stored sample
        self._stop(rows, Termination.CANCELED, t=log.t[last], j=log.j[last])

    def _reap(self, rows):
        """Stop the rows on which a map failed (``MAP_ERROR``) or whose dense
        output became non-finite (``NON_FINITE``); return the mask of the others."""
        bad = self.bad[rows]
        if not bad.any():
            return None
        for r in rows[bad]:
            if not self.done[r]:
                e = self.bad_exc[r]
                if isinstance(e, _NonFiniteStep):
                    self._stop([r], Termination.NON_FINITE, "dense", t=self.t[r],
                               t2=self.t_step[r], j=self.j[r])
                else:
                    self._stop([r], Termination.MAP_ERROR, error=str(e))
                    self.exception[r] = e
        return ~bad

    def _finite(self, rows, y):
        """Mark the rows whose probed state is not finite (see :meth:`_reap`)."""
        fin = np.isfinite(y).all(axis=1)
        if not fin.all():
            for r in rows[~fin]:
                if not self.bad[r]:
                    self.bad[r] = True
                    self.bad_exc[r] = _NonFiniteStep()

    def arcs(self, system):
        """One :class:`HybridArc` per row, with ``xdot`` and ``stats``."""
        log = self.log
        # the last sample's xdot, where no flow started there (as simulate's arc())
        fill = np.flatnonzero(np.isnan(log.xd[log.last]).any(axis=1))
        if self.keep is not None:
            fill = fill[self.keep[fill] >= log.count[fill]]
        fill = np.array([r for r in fill if self.cause[r] is not Termination.MAP_ERROR],
                        dtype=np.int64)
        if fill.size:
            k = log.last[fill]
            log.xd[k] = self.maps.flow_soft(log.x[k], log.t[k], log.j[k], fill)
        rej = (self.attempts - self.steps).tolist()
        cols = [c.tolist() for c in (self.steps, self.nfev, self.events, self.flows,
                                     self.attempts)]
        comps = system.components
        out = []
        for i, (t, j, x, xd) in enumerate(log.split(self.keep)):
            stats = {"steps": cols[0][i], "nfev": cols[1][i], "njev": 0, "nlu": 0,
                     "events": cols[2][i], "flows": cols[3][i],
                     "rejected": max(rej[i], 0) if cols[4][i] else None}
            out.append(HybridArc._trusted(t, j, x, self.cause[i], self.message[i],
                                          self.exception[i], components=comps,
                                          system=system, xdot=xd, stats=stats))
            if self.watching:
                c = self.cross[i]
                out[-1].crossings = Crossings(
                    [e[0] for e in c], [e[1] for e in c], [e[2] for e in c],
                    [e[3] for e in c], np.array([e[4] for e in c]).reshape(len(c), self.n))
        return out

    # ------------------------------------------------------------ main loop
    def run(self):
        N = self.N
        rows = np.arange(N)
        self.log.append(rows, self.t, self.j, self.x)
        self._validate()
        cap = self.max_samples
        latch = self.latch
        while True:
            if latch is not None:
                latch.check()            # a Ctrl-C whose KeyboardInterrupt was lost
            rows = np.flatnonzero(self.decide & ~self.done)
            if rows.size:
                self._decide(rows)
            rows = np.flatnonzero(~self.decide & ~self.done)
            if rows.size:
                self._step(rows)
            elif not (self.decide & ~self.done).any():
                break
            if cap < math.inf:
                self._cap_samples(cap)

    def _cap_samples(self, cap):
        """Rows that stored more than ``max_samples``: MAX_STEPS, the samples cut."""
        over = np.flatnonzero((self.log.count > cap) & ~self.done)
        if not over.size:
            return
        if self.keep is None:
            self.keep = np.full(self.N, np.iinfo(np.int64).max, dtype=np.int64)
        self.keep[over] = cap
        self._stop(over, Termination.MAX_STEPS, "samples", samples=int(cap),
                   max_samples=int(cap), t=self.t[over])

    def _validate(self):
        """Check every map's shape at the initial states (errors raise at once)."""
        m = self.maps
        rows = np.arange(self.N)
        x, t, j = self.x, self.t, self.j
        inD = m.in_D(rows, x, t, j, strict=True)
        inC = m.in_C(rows, x, t, j, strict=True)
        if m.hD is not None:
            m.guard_D(rows, x, t, j, strict=True)
        if m.hC is not None:
            m.guard_C(rows, x, t, j, strict=True)
        if m.W is not None:          # the watched functions and their directions, at x0
            watch_directions(self.w_direction, m.watch(rows, x, t, j, strict=True).shape[1],
                             float(t[0]), int(j[0]))
        for name, call, inside in (("flow_map", m.flow, inC), ("jump_map", m.jump, inD)):
            if inside.any():
                r = rows[inside]
                v = call(r, x[r], t[r], j[r], strict=True)
                bad = ~np.isfinite(v).all(axis=1)
                if bad.any():        # as simulate at x0: a programming error, raised
                    k = int(np.flatnonzero(bad)[0])
                    err = MapError(f"{name} returned non-finite values {v[k]} (at "
                                   f"t={t[r[k]]:.10g}, j={j[r[k]]}; row {r[k]} of x0s)",
                                   name, float(t[r[k]]), int(j[r[k]]))
                    err.row = int(r[k])
                    raise err

    # ------------------------------------------------------------ decisions
    def _stop_outside(self, rows, x, t, j, kind=None):
        """In neither C nor D: x0 outside both, sticking, or leaving C ∪ D
        (simulate's ``_stop_outside``); ``kind``: LEFT_SETS' message kind."""
        first = self.log.count[rows] == 1
        stick = np.array([not f and is_sticking(
            self.flows3[r][np.isfinite(self.flows3[r])], tt - self.t_last[r],
            int(self.jumps[r]), time_scale(self.t0, tt, self.t_max))
            for r, f, tt in zip(rows, first, t)], dtype=bool)
        for r, tt, jj, xx in zip(rows[stick], t[stick], j[stick], x[stick]):
            fl = self.flows3[r]
            self._stop([r], Termination.ZENO, "sticking", t=[tt], j=[jj], x=[xx],
                       flows=[fl[np.isfinite(fl)]])
        if first.any():
            self._stop(rows[first], Termination.NOT_IN_SETS, x=x[first], t=t[first],
                       j=j[first])
        left = ~first & ~stick
        if left.any():
            self._stop(rows[left], Termination.LEFT_SETS, kind, x=x[left], t=t[left],
                       j=j[left])

    def _decide(self, rows):
        """Jump, stop or start flowing, at the current (t, j, x) of ``rows``.

        Loops while some rows jump (several jumps at one t are allowed).
        """
        m = self.maps
        while rows.size:
            x, t, j = self.x[rows], self.t[rows], self.j[rows]
            inD = m.in_D(rows, x, t, j)
            inC = m.in_C(rows, x, t, j)
            ok = self._reap(rows)
            if ok is not None:
                rows, x, t, j, inD, inC = rows[ok], x[ok], t[ok], j[ok], inD[ok], inC[ok]
            force = self.force[rows]
            self.force[rows] = False
            post = self.post[rows]          # the decision right after an event's jump
            self.post[rows] = False
            coin = np.zeros(len(rows), dtype=bool)
            ask = needs_coin(inC, inD, self.prio, force)
            if ask.any():
                coin[ask] = self.rng.random(int(ask.sum())) < 0.5
            jump = jumps_now(inC, inD, self.prio, coin, force)
            probe = post & ~jump & ~inC
            if probe.any():
                # in neither C nor D after the jump: within the located event's
                # own error of C counts as in C (rules.post_jump_probe)
                i = np.flatnonzero(probe)
                r = rows[i]
                tp, xp = post_jump_probe(x[i], self.pend_lo[r], self.pend_xlo[r],
                                         self.pend_xhi[r])
                near = m.in_C(r, xp, tp, j[i])
                inC[i[near]] = True
                ok = self._reap(rows)
                if ok is not None:
                    rows, x, t, j, inD, inC, force, jump = (
                        rows[ok], x[ok], t[ok], j[ok], inD[ok], inC[ok], force[ok], jump[ok])
            # -- rows that stay: stop outside C, stop at t_max, or start a flow
            stay = ~jump
            if stay.any():
                sr, sx, st, sj, sD = rows[stay], x[stay], t[stay], j[stay], inD[stay]
                out = ~inC[stay]
                if out.any():
                    self._stop_outside(sr[out], sx[out], st[out], sj[out])
                at_end = ~out & (st >= self.t_max)
                if at_end.any():
                    self._stop(sr[at_end], Termination.T_MAX)
                go = ~out & ~at_end
                if go.any():
                    self._start_flow(sr[go], sD[go])
            # -- rows that jump
            if not jump.any():
                return
            # from_C: flowing was possible (a forced jump is from an event in C)
            rows, x, t, j = rows[jump], x[jump], t[jump], j[jump]
            from_C, force = (force | inC)[jump], force[jump]
            full = self.jumps[rows] >= self.j_max
            if full.any():
                self._stop(rows[full], Termination.J_MAX)
                keep = ~full
                rows, x, t, j, from_C, force = (rows[keep], x[keep], t[keep], j[keep],
                                                from_C[keep], force[keep])
            if not rows.size:
                return
            if force.any():                  # the event's bracket, for the next decision
                fr = rows[force]
                self.post[fr] = self.pend[fr]
                self.pend[fr] = False
            xn = m.jump(rows, x, t, j)
            fin = np.isfinite(xn).all(axis=1)
            if not fin.all():
                for r, v, tt, jj in zip(rows[~fin], xn[~fin], t[~fin], j[~fin]):
                    m._fail(r, MapError(f"jump_map returned non-finite values {v} (at "
                                        f"t={tt:.10g}, j={jj})", "jump_map", float(tt),
                                        int(jj)))
            ok = self._reap(rows)
            if ok is not None:
                rows, xn, t, j, from_C = rows[ok], xn[ok], t[ok], j[ok], from_C[ok]
            # Zeno (rules.zeno_short) and chattering (rules.chatter_step), row by row
            flow = t - self.t_last[rows]
            longest = self.longest[rows]
            for i, r in enumerate(rows.tolist()):
                fl = [v for v in self.flows3[r].tolist() if v != math.inf] + [float(flow[i])]
                short, self.zref[r] = zeno_short(fl, len(fl), float(t[i]), float(self.zref[r]),
                                                 self.zeno_time, self.zeno_rtol)
                self.short[r] = self.short[r] + 1 if short else 0
                self.longest[r], self.tiny[r] = chatter_step(float(flow[i]), float(longest[i]),
                                                             int(self.tiny[r]))
            # a jump loop: consecutive jumps at one instant, each from a state in C
            self.loop[rows] = np.where(from_C & (flow == 0.0) & (self.jumps[rows] > 0),
                                       self.loop[rows] + 1, 0)
            self.same[rows] = np.where((flow == 0.0) & (self.jumps[rows] > 0),
                                       self.same[rows] + 1, 0)
            self.flows3[rows] = np.column_stack([self.flows3[rows][:, 1:], flow])
            self.t_last[rows] = t
            j = j + 1
            self.j[rows] = j
            self.jumps[rows] += 1
            self.x[rows] = xn
            self.log.append(rows, t, j, xn)
            if self.hist is not None:
                self.hist._restart(rows, t, xn, j)
            if self.delays:                 # the delayed jump: a kink at t + d
                for r, tt in zip(rows.tolist(), t.tolist()):
                    br = self.breaks[r]
                    for d in self.delays:
                        bisect.insort(br, tt + d)
                    self.bp[r] = br[0]
            # rules.after_jump: J_MAX before ZENO
            code = self.after[(self.jumps[rows] >= self.j_max).astype(np.intp),
                              (self.short[rows] >= self.zeno_jumps).astype(np.intp)]
            end = code != NO_CAUSE
            if end.any():
                loop = self.loop[rows]
                named = is_jump_loop(loop, self.zeno_jumps)
                for c in np.unique(code[end]):
                    sel = code == c
                    cause = CAUSES[c]
                    lp = sel & named
                    if lp.any():             # the loop's jumps and the one that began it
                        self._stop(rows[lp], cause, "loop", count=loop[lp] + 1, t=t[lp])
                    sel &= ~named
                    if not sel.any():
                        continue
                    if cause is Termination.ZENO:
                        self._stop(rows[sel], cause, "zeno", count=self.short[rows[sel]],
                                   t=t[sel])
                        continue
                    same = self.same[rows]
                    at = sel & is_jump_loop(same, self.zeno_jumps)
                    if at.any():
                        self._stop(rows[at], cause, "instant", count=same[at] + 1, t=t[at])
                    sel &= ~at
                    tiny = self.tiny[rows]
                    ch = sel & is_jump_loop(tiny, self.zeno_jumps)
                    if ch.any():
                        self._stop(rows[ch], cause, "chatter", count=tiny[ch],
                                   rtol=CHATTER_RTOL, longest=longest[ch], flow=flow[ch],
                                   t=t[ch])
                    if (sel & ~ch).any():
                        self._stop(rows[sel & ~ch], cause)
            rows = rows[~end]

    def _start_flow(self, rows, inD):
        """Begin a flow at the current state of ``rows`` (a new solver in simulate)."""
        m = self.maps
        x, t, j = self.x[rows], self.t[rows], self.j[rows]
        f0 = m.flow(rows, x, t, j)
        self.nfev[rows] += 1
        ok = self._reap(rows)
        if ok is not None:
            rows, x, t, j, f0, inD = rows[ok], x[ok], t[ok], j[ok], f0[ok], inD[ok]
        span = self._bound(rows, t) - t
        h = np.minimum(np.minimum(self.h[rows], span), self.max_step)
        need = ~(h > 0)                      # no hint (NaN) or a degenerate one
        if need.any():
            h[need] = self._initial_step(rows[need], x[need], t[need], j[need], f0[need],
                                         span[need])
            self.nfev[rows[need]] += 1
            ok = self._reap(rows)
            if ok is not None:
                rows, f0, inD, h = rows[ok], f0[ok], inD[ok], h[ok]
        self.fx[rows] = f0
        self.log.set_last_xdot(rows, f0)     # the flow's derivative at its first sample
        self.flows[rows] += 1
        self.h[rows] = h
        self.rejected[rows] = False
        self.inD_prev[rows] = inD
        self.t_flow0[rows] = self.t[rows]
        self.decide[rows] = False
        if self.watching:
            self._watch_start(rows)
            self._reap(rows)

    def _bound(self, rows, t):
        """End of the rows' integration: t_max, or the next delay breakpoint (the
        breakpoints at or before t, within round-off, are spent)."""
        if not self.delays:
            return self.t_max
        tol = 4 * _EPS * np.maximum(1.0, np.abs(t))
        stale = self.bp[rows] <= t + tol
        if stale.any():
            for r, tt, tl in zip(rows[stale].tolist(), t[stale].tolist(), tol[stale].tolist()):
                br = self.breaks[r]
                while br and br[0] <= tt + tl:
                    br.pop(0)
                self.bp[r] = br[0] if br else np.inf
        return np.minimum(self.t_max, self.bp[rows])
