"""Vectorized batch integrator: many trajectories of one hybrid system at once.

:func:`simulate_vectorized` integrates a batch of initial states of a system
whose maps are written over batches (``system.vectorized = True``) together in
numpy: an embedded Dormand-Prince 5(4) pair (scipy's RK45 coefficients) with a
per-trajectory step size, error control and dense output, per-trajectory event
location on the dense output (bisection of the set indicators, safeguarded
Illinois-type regula falsi on the guards, both to 4 eps), per-trajectory jumps,
and the same priority, limits and termination causes as
:func:`hybridsim.simulate`.

Each trajectory follows the rules ``simulate(..., method="RK45")`` follows
(the same initial-step rule, step-size controller and first step after an
event) and brackets its events to the same 4 eps. The arithmetic is batched,
so rounding differs: the step sizes can drift apart (sample times by up to
~1e-7 at rtol 1e-10 in the tests, and a row's steps can depend on the other
rows of its batch), and the results agree with a loop of
:func:`hybridsim.simulate` to the integrator's tolerance, not to rounding;
jumps of timer-like guards land on the same times to rounding. The event
search is an Illinois-type regula falsi (Anderson-Bjorck weights) on the
guards.
"""
from __future__ import annotations

import inspect
import itertools
import math
import numbers

import numpy as np
from scipy.integrate import RK45

from ._progress import make_bar
from .arc import HybridArc, Termination
from .events import _maximize, _near_peak
from .options import check_count, check_options, check_real
from .rules import (
    FAILURES,
    MapError,
    Priority,
    SimulationError,
    is_short_flow,
    is_sticking,
    jumps_now,
    needs_coin,
    sticking_message,
    t_max_slack,
    time_scale,
    zeno_message,
)
from .system import HybridSystem, as_map, guard_rows

__all__ = ["simulate_vectorized"]

_EPS = np.finfo(float).eps
# scipy's RK45 tableau, error weights and dense-output matrix
_A, _B, _C, _E, _P = RK45.A, RK45.B, RK45.C, RK45.E, RK45.P
_NS = RK45.n_stages
_ERR_EXP = -1.0 / (RK45.error_estimator_order + 1)
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = 0.9, 0.2, 10.0
_STALL = 4          # bisect when a bracket has not halved in this many probes
_TOO_SMALL = "Required step size is less than spacing between numbers."
# options of simulate() that make no sense for a batch integrated in numpy
_UNSUPPORTED = {"inputs": None, "prehistory": None, "dense": False}


def _rms(a):
    """Row-wise RMS norm of a (k, n) array (scipy's ``norm`` per row)."""
    return np.sqrt(np.einsum("ij,ij->i", a, a) / a.shape[1])


class _SampleLog:
    """Growable sample store shared by the trajectories of a batch.

    One flat buffer of (row, t, j, x) with doubling capacity: each append
    stores one sample for each of a set of trajectories with one slice
    assignment (amortised O(1) per sample, no quadratic copying, and no
    per-sample Python work however many rows append). :meth:`split` gathers
    each trajectory's samples (in time order: a stable sort by row) into its
    own arrays, so the arcs do not keep the log alive.
    """

    def __init__(self, N, n, cap=1024):
        self.size = 0
        self.rows = np.empty(cap, dtype=np.int64)
        self.t = np.empty(cap)
        self.j = np.empty(cap, dtype=np.int64)
        self.x = np.empty((cap, n))
        self.count = np.zeros(N, dtype=np.int64)

    def _grow(self, need):
        cap = max(2 * len(self.t), need)
        k = self.size
        for name in ("rows", "t", "j", "x"):
            old = getattr(self, name)
            new = np.empty((cap,) + old.shape[1:], dtype=old.dtype)
            new[:k] = old[:k]
            setattr(self, name, new)

    def append(self, rows, t, j, x):
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
        self.size = b
        self.count[rows] += 1

    def split(self):
        """Per-trajectory ``(t, j, x)`` arrays, in row order; frees the log."""
        k = self.size
        if len(self.count) == 1:             # one trajectory: shrink in place, no copy
            self.t.resize(k, refcheck=False)
            self.j.resize(k, refcheck=False)
            self.x.resize((k, self.x.shape[1]), refcheck=False)
            out = [(self.t, self.j, self.x)]
            self.rows = self.t = self.j = self.x = None
            return out
        order = np.argsort(self.rows[:k], kind="stable")
        bounds = np.concatenate(([0], np.cumsum(self.count)))
        out = []
        for a, b in itertools.pairwise(bounds):
            idx = order[a:b]
            out.append((self.t[idx], self.j[idx], self.x[idx]))
        self.rows = self.t = self.j = self.x = None
        return out


class _VMaps:
    """The system's maps called over batches, with shape checks.

    A call that raises (or returns a wrong shape) during the run is retried row
    by row; the rows that still fail are recorded in ``run.bad`` (they end
    with ``MAP_ERROR``) and get a harmless placeholder value. With
    ``strict=True`` (the checks at x0) errors propagate at once.
    """

    def __init__(self, system, n):
        self.n = n
        self.f = as_map(system.flow_map, "flow_map")
        self.g = as_map(system.jump_map, "jump_map")
        self.hD = as_map(system.jump_guard, "jump_guard") if system.jump_guard is not None else None
        self.hC = as_map(system.flow_guard, "flow_guard") if system.flow_guard is not None else None
        self.D_from_guard = not system._overrides("jump_set") and self.hD is not None
        self.C_from_guard = not system._overrides("flow_set") and self.hC is not None
        self.D = None if self.D_from_guard else as_map(system.jump_set, "jump_set")
        self.C = None if self.C_from_guard else as_map(system.flow_set, "flow_set")
        self.has_D = system.has_jumps
        self.has_C = system.has_flow_boundary
        self.run = None

    # ---------------------------------------------------------------- checks
    def _check(self, kind, name, val, k):
        if kind == "state":
            arr = np.asarray(val, dtype=float)
            if arr.shape != (k, self.n):
                raise MapError(f"{name} must return an array of shape ({k}, {self.n}) "
                               f"(vectorized system: one row per trajectory), got shape "
                               f"{arr.shape}")
            return arr
        if kind == "set":
            arr = np.asarray(val)
            if arr.shape != (k,):
                raise MapError(f"{name} must return a boolean array of shape ({k},) "
                               f"(vectorized system: one entry per trajectory), got shape "
                               f"{arr.shape}")
            return arr.astype(bool)
        arr = np.asarray(val, dtype=float)   # guard: (k,) or (k, m)
        if arr.ndim == 2 and arr.shape[0] == k and arr.shape[1] >= 1:
            return guard_rows(arr)
        if arr.shape != (k,):
            raise MapError(f"{name} must return an array of shape ({k},) or ({k}, m) "
                           f"(vectorized system: one row per trajectory), got shape "
                           f"{arr.shape}")
        return arr

    def _call(self, kind, name, fn, rows, x, t, j, strict=False):
        k = len(rows)
        if k == 0:
            return (np.empty((0, self.n)) if kind == "state"
                    else np.empty(0, dtype=bool if kind == "set" else float))
        try:
            return self._check(kind, name, fn(x, t, j, None), k)
        except (KeyboardInterrupt, SystemExit):
            raise
        except MapError:
            if strict:
                raise
        except Exception as e:
            if strict:          # at x0, as simulate: a MapError naming the map
                raise MapError(f"{name} raised {type(e).__name__}: {e} (at the initial "
                               f"states, t={t[0]:.10g})", name, float(t[0]), int(j[0])) from e
        if kind == "state":
            out = np.zeros((k, self.n))
        else:
            out = np.zeros(k, dtype=bool if kind == "set" else float)
        run = self.run
        for i in range(k):
            try:
                out[i] = self._check(kind, name, fn(x[i:i + 1], t[i:i + 1], j[i:i + 1], None),
                                     1)[0]
            except (KeyboardInterrupt, SystemExit):
                raise
            except Exception as e:  # noqa: BLE001
                r = rows[i]
                if not run.bad[r]:
                    run.bad[r] = True
                    run.bad_exc[r] = e
        return out

    # ------------------------------------------------------------ the maps
    def flow(self, rows, x, t, j, strict=False):
        return self._call("state", "flow_map", self.f, rows, x, t, j, strict)

    def jump(self, rows, x, t, j, strict=False):
        return self._call("state", "jump_map", self.g, rows, x, t, j, strict)

    def guard_D(self, rows, x, t, j, strict=False):
        return self._call("guard", "jump_guard", self.hD, rows, x, t, j, strict)

    def guard_C(self, rows, x, t, j, strict=False):
        return self._call("guard", "flow_guard", self.hC, rows, x, t, j, strict)

    def in_D(self, rows, x, t, j, strict=False):
        if not self.has_D:
            return np.zeros(len(rows), dtype=bool)
        if self.D_from_guard:
            return self.guard_D(rows, x, t, j, strict) >= 0.0
        return self._call("set", "jump_set", self.D, rows, x, t, j, strict)

    def in_C(self, rows, x, t, j, strict=False):
        if not self.has_C:
            return np.ones(len(rows), dtype=bool)
        if self.C_from_guard:
            return self.guard_C(rows, x, t, j, strict) >= 0.0
        return self._call("set", "flow_set", self.C, rows, x, t, j, strict)


def _is_rk45(method):
    return (isinstance(method, str) and method == "RK45") or method is RK45


def takes_options(kwargs):
    """Whether :func:`simulate_vectorized` implements these options of ``simulate``.

    It is Dormand-Prince 5(4) (``method="RK45"``, the default) without dense
    output, inputs, a prehistory or ``t_eval``; :func:`hybridsim.simulate_many`
    runs a vectorized system's rows through ``simulate`` otherwise.
    """
    if not _is_rk45(kwargs.get("method", "RK45")):
        return False
    known = inspect.signature(simulate_vectorized).parameters
    for name, val in kwargs.items():
        if name in _UNSUPPORTED:
            default = _UNSUPPORTED[name]
            if (val is not None) if default is None else bool(val):
                return False
        elif name not in known:
            return False
    return True


def _check_options(system, x0s, t_max, j_max, priority, method, rtol, atol, max_step,
                   first_step, zeno_jumps, zeno_time, t0, j0, max_norm, extra):
    if not isinstance(system, HybridSystem):
        raise TypeError(f"system must be a hybridsim.HybridSystem, got {type(system).__name__}")
    if not system.vectorized:
        raise ValueError("system: simulate_vectorized needs a system with vectorized = True "
                         "(maps written over (N, n) batches); use hybridsim.simulate_many")
    for name, val in extra.items():
        if name not in _UNSUPPORTED:
            raise TypeError(f"simulate_vectorized() got an unexpected keyword argument {name!r}")
        if (val is not None) if _UNSUPPORTED[name] is None else bool(val):
            raise ValueError(f"{name}={val!r} is not supported in vectorized mode; use "
                             "simulate_many with an executor, or a non-vectorized system")
    if int(system.input_dim or 0) > 0:
        raise ValueError(f"system: input_dim={system.input_dim}; inputs are not supported in "
                         "vectorized mode (close the loop with hs.connect first)")
    if system.needs_history or getattr(system, "delays", ()):
        raise ValueError("system: maps reading the run's history (needs_history, delays) "
                         "are not supported in vectorized mode")
    n = system.state_dim
    if n is None or isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"{type(system).__name__}.state_dim must be a positive int, got {n!r}")
    n = int(n)
    try:
        X = np.array(x0s, dtype=float)
    except (TypeError, ValueError) as e:
        raise TypeError(f"x0s must be an array of shape (N, {n}) of floats, got "
                        f"{type(x0s).__name__}") from e
    if X.ndim != 2 or X.shape[1] != n or X.shape[0] < 1:
        raise ValueError(f"x0s must have shape (N, {n}) with N >= 1 (one row per "
                         f"trajectory), got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        bad = np.flatnonzero(~np.isfinite(X).all(axis=1))
        raise ValueError(f"x0s must be finite; rows {bad[:10].tolist()} are not")
    (t0, t_max, j_max, prio, rtol, atol, max_step, first_step, max_norm,
     zeno_time) = check_options(system, n, t0, t_max, j_max, priority, rtol, atol, max_step,
                                first_step, max_norm, zeno_time)
    if isinstance(j0, bool) or not isinstance(j0, numbers.Integral):
        raise TypeError(f"j0 must be an int, got {j0!r}")
    if not _is_rk45(method):
        raise ValueError(f"method={method!r} is not supported in vectorized mode: the batch "
                         "integrator is Dormand-Prince 5(4) ('RK45'); use simulate_many with "
                         "an executor for other methods")
    if isinstance(zeno_jumps, bool) or not isinstance(zeno_jumps, numbers.Integral) \
            or zeno_jumps < 1:
        raise ValueError(f"zeno_jumps must be a positive int, got {zeno_jumps!r}")
    return (n, X, t0, t_max, j_max, prio, rtol, atol, max_step,
            first_step, int(zeno_jumps), zeno_time, int(j0), max_norm)


def simulate_vectorized(system, x0s, t_max, j_max=math.inf, *, priority="jumps",
                        rtol=1e-6, atol=1e-9, max_step=math.inf, first_step=None,
                        zeno_jumps=50, zeno_time=1e-12, zeno_rtol=1e-7, progress=False,
                        method="RK45", t0=0.0, j0=0, max_norm=math.inf, seed=None,
                        throw=False, refine=1, max_steps=1_000_000, **unsupported):
    r"""Simulate a vectorized hybrid system from many initial states at once.

    The whole batch is integrated together in numpy by an embedded
    Dormand-Prince 5(4) pair with scipy's RK45 coefficients, each trajectory
    with its own step size (scipy's step-size rule), error control, dense
    output, event location and jumps. Only the trajectories still running are
    evaluated. Semantics and termination causes are those of
    :func:`hybridsim.simulate`.

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
    method : {"RK45"}
        The only method of the batch integrator (others raise ``ValueError``).
    t0, j0 : float, int
        Initial hybrid time of every trajectory.
    max_norm : float
        A trajectory whose state norm exceeds it stops with ``BLOWUP``.
    seed : int or numpy Generator, optional
        Seed of ``priority="random"``.
    refine : int
        Samples stored per step, as in :func:`hybridsim.simulate`:
        ``refine - 1`` dense-output points inside each step.
    throw : bool
        Raise :class:`hybridsim.SimulationError` for the first trajectory
        that stops on a failure (``.arc`` is its arc, ``.arcs`` all of them).
    **unsupported
        ``inputs``, ``prehistory`` (must be None) and ``dense`` (must be
        False) are accepted for compatibility with
        :func:`hybridsim.simulate_many`; anything else raises ``TypeError``.

    Returns
    -------
    list of HybridArc
        One arc per row of ``x0s``, in order, each with samples at every
        accepted step end and at every event (``t`` (M,), ``j`` (M,),
        ``x`` (M, n)).

    Raises
    ------
    MapError
        A map raises or returns a wrong shape at the initial states (chained
        from the map's exception).
    ValueError, TypeError
        Bad arguments (each message names the argument).

    Notes
    -----
    A user map that raises during the run is retried row by row; only the
    rows that still fail stop, with cause ``MAP_ERROR`` (an error at the
    initial states is raised, as in :func:`hybridsim.simulate`;
    :func:`hybridsim.simulate_many` isolates such rows instead).

    Ctrl-C (KeyboardInterrupt) ends every trajectory still running with
    ``CANCELED``, keeping its samples so far and the finished trajectories.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> timer = hs.HybridSystem.from_functions(
    ...     f=lambda x: np.ones_like(x), g=lambda x: np.zeros_like(x),
    ...     jump_guard=lambda x: x[:, 0] - 1.0, flow_guard=lambda x: 1.0 - x[:, 0],
    ...     state_dim=1, vectorized=True)
    >>> arcs = simulate_vectorized(timer, [[0.0], [0.5]], t_max=2.2)
    >>> [np.round(a.jump_times, 12).tolist() for a in arcs]
    [[1.0, 2.0], [0.5, 1.5]]
    """
    (n, X, t0, t_max, j_max, prio, rtol, atol, max_step, first_step, zeno_jumps, zeno_time,
     j0, max_norm) = _check_options(system, x0s, t_max, j_max, priority, method, rtol, atol,
                                    max_step, first_step, zeno_jumps, zeno_time, t0, j0,
                                    max_norm, unsupported)
    if isinstance(refine, bool) or not isinstance(refine, numbers.Integral) or refine < 1:
        raise ValueError(f"refine must be an int >= 1, got {refine!r}")
    zeno_rtol = check_real("zeno_rtol", zeno_rtol, nonneg=True)
    max_steps = check_count("max_steps", max_steps, minimum=1, allow_inf=True)
    run = _BatchRun(system, X, n, t0, j0, t_max, j_max, prio, rtol, atol, max_step,
                    first_step, zeno_jumps, zeno_time, max_norm, np.random.default_rng(seed),
                    zeno_rtol=zeno_rtol, max_steps=max_steps)
    run.refine = int(refine)
    run.pbar = make_bar(progress, total=len(X), desc="simulate_vectorized", unit="run")
    try:
        run.run()
    except KeyboardInterrupt:       # Ctrl-C: every trajectory still running is canceled
        run.cancel()
    finally:
        if run.pbar is not None:
            run.pbar.close()
    arcs = []
    for i, (t, j, x) in enumerate(run.log.split()):
        arcs.append(HybridArc(t, j, x, run.cause[i], run.message[i], run.exception[i],
                              components=system.components, system=system))
    if throw:
        for i, arc in enumerate(arcs):
            if arc.termination in FAILURES:
                err = SimulationError(f"trajectory {i}: {arc.message}", arc)
                err.arcs = arcs
                raise err from arc.exception
    return arcs


class _BatchRun:
    """State of a batch run: one entry per trajectory in every array."""

    def __init__(self, system, X, n, t0, j0, t_max, j_max, prio, rtol, atol, max_step,
                 first_step, zeno_jumps, zeno_time, max_norm, rng, zeno_rtol=1e-7,
                 max_steps=math.inf):
        N = len(X)
        self.N, self.n = N, n
        self.maps = _VMaps(system, n)
        self.maps.run = self
        self.t_max, self.j_max, self.prio = t_max, j_max, prio
        self.rtol, self.atol, self.max_step = rtol, atol, max_step
        self.zeno_jumps, self.zeno_time, self.max_norm = zeno_jumps, zeno_time, max_norm
        self.zeno_rtol, self.max_steps = zeno_rtol, max_steps
        self.rng = rng
        self.refine = 1
        self.pbar = None
        # per-trajectory state
        self.t = np.full(N, t0)
        self.j = np.full(N, j0, dtype=np.int64)
        self.x = X.copy()
        self.fx = np.zeros((N, n))                  # f at (t, x): first stage (FSAL)
        self.h = np.full(N, np.nan if first_step is None else first_step)  # step hint
        self.rejected = np.zeros(N, dtype=bool)     # last attempt was rejected
        self.nonfinite = np.zeros(N, dtype=bool)    # its stages were not finite
        self.inD_prev = np.zeros(N, dtype=bool)
        self.force = np.zeros(N, dtype=bool)        # an event asks for a jump
        self.short = np.zeros(N, dtype=np.int64)    # consecutive short flows (Zeno)
        self.flows3 = np.full((N, 3), np.inf)        # the last three flow lengths
        self.steps = np.zeros(N, dtype=np.int64)     # accepted steps (max_steps)
        self.t0 = t0
        self.t_last = np.full(N, t0)
        self.t_flow0 = np.full(N, t0)               # start of the current flow
        self.jumps = np.zeros(N, dtype=np.int64)
        self.decide = np.ones(N, dtype=bool)        # at a decision point (jump/flow/stop)
        self.done = np.zeros(N, dtype=bool)
        self.bad = np.zeros(N, dtype=bool)          # a map failed on this row
        self.bad_exc = [None] * N
        self.cause = [None] * N
        self.message = [None] * N
        self.exception = [None] * N
        self.log = _SampleLog(N, n)
        m = self.maps
        self.watch_D = m.has_D and prio != Priority.FLOWS
        phi_ok = ((not self.watch_D or m.hD is not None) and (not m.has_C or m.hC is not None))
        self.use_phi = phi_ok and (m.hD is not None or m.hC is not None)

    # ------------------------------------------------------------ helpers
    def _stop(self, rows, cause, details=None):
        """End trajectories ``rows`` with ``cause``; ``details(i) -> str`` per row."""
        for i, r in enumerate(rows):
            if self.done[r]:
                continue
            self.done[r] = True
            self.cause[r] = cause
            d = details(i) if details is not None else None
            self.message[r] = cause.message if d is None else f"{cause.message}: {d}"
        if self.pbar is not None and len(rows):
            self.pbar.update(len(rows))

    def cancel(self):
        """End every trajectory still running with ``CANCELED`` (after Ctrl-C)."""
        rows = np.flatnonzero(~self.done)
        t, j = self.t, self.j
        self._stop(rows, Termination.CANCELED, lambda i: f"at t={t[rows[i]]:.10g}, "
                                                         f"j={j[rows[i]]}")

    def _reap(self, rows):
        """Stop the rows on which a map failed; return the mask of the others."""
        bad = self.bad[rows]
        if not bad.any():
            return None
        for r in rows[bad]:
            if not self.done[r]:
                e = self.bad_exc[r]
                self._stop([r], Termination.MAP_ERROR, lambda i, e=e: f"{type(e).__name__}: {e}")
                self.exception[r] = e
        return ~bad

    # ------------------------------------------------------------ main loop
    def run(self):
        N = self.N
        rows = np.arange(N)
        self.log.append(rows, self.t, self.j, self.x)
        self._validate()
        while True:
            rows = np.flatnonzero(self.decide & ~self.done)
            if rows.size:
                self._decide(rows)
            rows = np.flatnonzero(~self.decide & ~self.done)
            if rows.size:
                self._step(rows)
            elif not (self.decide & ~self.done).any():
                break

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
        if inC.any():
            r = rows[inC]
            m.flow(r, x[r], t[r], j[r], strict=True)
        if inD.any():
            r = rows[inD]
            m.jump(r, x[r], t[r], j[r], strict=True)

    # ------------------------------------------------------------ decisions
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
            coin = np.zeros(len(rows), dtype=bool)
            ask = needs_coin(inC, inD, self.prio, force)
            if ask.any():
                coin[ask] = self.rng.random(int(ask.sum())) < 0.5
            jump = jumps_now(inC, inD, self.prio, coin, force)
            # -- rows that stay: stop outside C, stop at t_max, or start a flow
            stay = ~jump
            if stay.any():
                sr, sx, st, sj, sD = rows[stay], x[stay], t[stay], j[stay], inD[stay]
                out = ~inC[stay]
                if out.any():
                    orow = sr[out]
                    first = self.log.count[orow] == 1
                    ox, ot, oj = sx[out], st[out], sj[out]
                    stick = np.array([not f and is_sticking(
                        self.flows3[r][np.isfinite(self.flows3[r])], tt - self.t_last[r],
                        int(self.jumps[r]), time_scale(self.t0, tt, self.t_max))
                        for r, f, tt in zip(orow, first, ot)], dtype=bool)
                    for r, tt, jj, xx in zip(orow[stick], ot[stick], oj[stick], ox[stick]):
                        fl = self.flows3[r]
                        self._stop([r], Termination.ZENO,
                                   lambda i, tt=tt, jj=jj, xx=xx, fl=fl:
                                   sticking_message(tt, jj, xx, fl[np.isfinite(fl)]))
                    for cause, sel in ((Termination.NOT_IN_SETS, first),
                                       (Termination.LEFT_SETS, ~first & ~stick)):
                        if sel.any():
                            xs, ts, js = ox[sel], ot[sel], oj[sel]
                            self._stop(orow[sel], cause,
                                       lambda i, xs=xs, ts=ts, js=js:
                                       f"x={xs[i]} at (t={ts[i]}, j={js[i]})")
                at_end = ~out & (st >= self.t_max)
                if at_end.any():
                    self._stop(sr[at_end], Termination.T_MAX)
                go = ~out & ~at_end
                if go.any():
                    self._start_flow(sr[go], sD[go])
            # -- rows that jump
            if not jump.any():
                return
            rows, x, t, j = rows[jump], x[jump], t[jump], j[jump]
            full = self.jumps[rows] >= self.j_max
            if full.any():
                self._stop(rows[full], Termination.J_MAX)
                keep = ~full
                rows, x, t, j = rows[keep], x[keep], t[keep], j[keep]
            if not rows.size:
                return
            xn = m.jump(rows, x, t, j)
            fin = np.isfinite(xn).all(axis=1)
            if not fin.all():
                for r, v in zip(rows[~fin], xn[~fin]):
                    if not self.bad[r]:
                        self.bad[r] = True
                        self.bad_exc[r] = MapError(f"jump_map returned non-finite values {v}")
            ok = self._reap(rows)
            if ok is not None:
                rows, xn, t, j = rows[ok], xn[ok], t[ok], j[ok]
            # Zeno: consecutive jumps after flows too short to resolve
            flow = t - self.t_last[rows]
            tiny = is_short_flow(flow, t, time_scale(self.t0, t, self.t_max), self.zeno_time,
                                 self.zeno_rtol)
            self.short[rows] = np.where(tiny, self.short[rows] + 1, 0)
            self.flows3[rows] = np.column_stack([self.flows3[rows][:, 1:], flow])
            self.t_last[rows] = t
            j = j + 1
            self.j[rows] = j
            self.jumps[rows] += 1
            self.x[rows] = xn
            self.log.append(rows, t, j, xn)
            full = self.jumps[rows] >= self.j_max
            if full.any():
                self._stop(rows[full], Termination.J_MAX)
            zeno = ~full & (self.short[rows] >= self.zeno_jumps)
            if zeno.any():
                zr, zt, zs = rows[zeno], t[zeno], self.short[rows[zeno]]
                self._stop(zr, Termination.ZENO,
                           lambda i, zs=zs, zt=zt: zeno_message(zs[i], zt[i]))
            rows = rows[~full & ~zeno]

    def _start_flow(self, rows, inD):
        """Begin a flow at the current state of ``rows`` (a new solver in simulate)."""
        m = self.maps
        x, t, j = self.x[rows], self.t[rows], self.j[rows]
        f0 = m.flow(rows, x, t, j)
        ok = self._reap(rows)
        if ok is not None:
            rows, x, t, j, f0, inD = rows[ok], x[ok], t[ok], j[ok], f0[ok], inD[ok]
        span = self.t_max - t
        h = np.minimum(np.minimum(self.h[rows], span), self.max_step)
        need = ~(h > 0)                      # no hint (NaN) or a degenerate one
        if need.any():
            h[need] = self._initial_step(rows[need], x[need], t[need], j[need], f0[need],
                                         span[need])
            ok = self._reap(rows)
            if ok is not None:
                rows, f0, inD, h = rows[ok], f0[ok], inD[ok], h[ok]
        self.fx[rows] = f0
        self.h[rows] = h
        self.rejected[rows] = False
        self.inD_prev[rows] = inD
        self.t_flow0[rows] = self.t[rows]
        self.decide[rows] = False

    def _initial_step(self, rows, y0, t0, j, f0, span):
        """scipy's ``select_initial_step`` (order 4), row by row in one go."""
        rtol, atol = self.rtol, self.atol
        scale = atol + np.abs(y0) * rtol
        d0 = _rms(y0 / scale)
        d1 = _rms(f0 / scale)
        with np.errstate(divide="ignore", invalid="ignore"):
            h0 = np.where((d0 < 1e-5) | (d1 < 1e-5), 1e-6, 0.01 * d0 / d1)
        h0 = np.minimum(h0, span)
        y1 = y0 + h0[:, None] * f0
        f1 = self.maps.flow(rows, y1, t0 + h0, j)
        d2 = _rms((f1 - f0) / scale) / h0
        with np.errstate(divide="ignore"):
            h1 = np.where((d1 <= 1e-15) & (d2 <= 1e-15), np.maximum(1e-6, h0 * 1e-3),
                          (0.01 / np.maximum(d1, d2)) ** (1.0 / 5.0))
        return np.minimum(np.minimum(np.minimum(100 * h0, h1), span), self.max_step)

    # ------------------------------------------------------------ flows
    def _step(self, rows):
        """One step attempt of every flowing trajectory (rejected ones retry next time)."""
        m = self.maps
        t, y, j, f = self.t[rows], self.x[rows], self.j[rows], self.fx[rows]
        rej = self.rejected[rows]
        h_abs = self.h[rows]
        min_step = 10 * np.abs(np.nextafter(t, np.inf) - t)
        h_abs = np.where(rej, h_abs, np.clip(h_abs, min_step, self.max_step))
        small = rej & (h_abs < min_step)
        if small.any():
            sr, st, ss = rows[small], t[small], self.short[rows[small]]
            nf = self.nonfinite[sr]        # a non-finite flow map: NON_FINITE, as in simulate
            if nf.any():
                nt, nj = st[nf], j[small][nf]
                self._stop(sr[nf], Termination.NON_FINITE,
                           lambda i: f"flow_map returned non-finite values near "
                                     f"t={nt[i]:.10g} (j={nj[i]})")
            zeno = (ss > 0) & ~nf
            if zeno.any():
                zt = st[zeno]
                self._stop(sr[zeno], Termination.ZENO,
                           lambda i: f"flows too short to resolve near t={zt[i]}")
            fail = ~zeno & ~nf
            if fail.any():
                ft, fj = st[fail], j[small][fail]
                self._stop(sr[fail], Termination.SOLVER_FAILED,
                           lambda i: f"{_TOO_SMALL} at t={ft[i]:.10g} (j={fj[i]})")
            keep = ~small
            rows, t, y, j, f, rej, h_abs = (rows[keep], t[keep], y[keep], j[keep], f[keep],
                                           rej[keep], h_abs[keep])
            if not rows.size:
                return
        t_new = np.minimum(t + h_abs, self.t_max)
        h = t_new - t
        h_abs = np.abs(h)
        # Dormand-Prince stages (scipy's rk_step, one row per trajectory)
        k = len(rows)
        K = np.empty((_NS + 1, k, self.n))
        K[0] = f
        hc = h[:, None]
        # overflow/NaN end as a rejected step or NON_FINITE, as in simulate
        with np.errstate(invalid="ignore", over="ignore"):
            for s in range(1, _NS):
                dy = np.tensordot(_A[s, :s], K[:s], axes=(0, 0)) * hc
                K[s] = m.flow(rows, y + dy, t + _C[s] * h, j)
            y_new = y + hc * np.tensordot(_B, K[:_NS], axes=(0, 0))
            K[_NS] = m.flow(rows, y_new, t + h, j)
            scale = self.atol + np.maximum(np.abs(y), np.abs(y_new)) * self.rtol
            err = np.tensordot(_E, K, axes=(0, 0)) * hc
            err_norm = _rms(err / scale)
        ok = self._reap(rows)
        if ok is not None:
            rows, t, y, j, rej, h, h_abs, t_new, y_new, err_norm = (
                rows[ok], t[ok], y[ok], j[ok], rej[ok], h[ok], h_abs[ok], t_new[ok],
                y_new[ok], err_norm[ok])
            K = K[:, ok]
            if not rows.size:
                return
        acc = err_norm < 1
        self.nonfinite[rows] = ~np.isfinite(K).all(axis=(0, 2))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            factor = _SAFETY * err_norm ** _ERR_EXP
        grow = np.where(err_norm == 0, _MAX_FACTOR, np.minimum(_MAX_FACTOR, factor))
        grow = np.where(rej, np.minimum(1.0, grow), grow)
        shrink = np.maximum(_MIN_FACTOR, factor)   # NaN error: NaN factor -> shrink (max)
        shrink = np.where(np.isnan(factor), _MIN_FACTOR, shrink)
        self.h[rows] = h_abs * np.where(acc, grow, shrink)
        self.rejected[rows] = ~acc
        if not acc.any():
            return
        if not acc.all():
            rows, t, y, j, h, t_new, y_new = (rows[acc], t[acc], y[acc], j[acc], h[acc],
                                              t_new[acc], y_new[acc])
            K = K[:, acc]
        self.rejected[rows] = False
        self._accepted(rows, t, y, j, h, t_new, y_new, K)

    def _accepted(self, rows, a, ya, j, h, b, yb, K):
        """Samples, events and limits after the accepted steps a -> b of ``rows``."""
        m = self.maps
        fin = np.isfinite(yb).all(axis=1)
        if not fin.all():
            nr, na, nb, nj = rows[~fin], a[~fin], b[~fin], j[~fin]
            self._stop(nr, Termination.NON_FINITE,
                       lambda i: f"after the step from t={na[i]:.10g} to t={nb[i]:.10g} "
                                 f"(j={nj[i]})")
            rows, a, ya, j, h, b, yb = (rows[fin], a[fin], ya[fin], j[fin], h[fin], b[fin],
                                        yb[fin])
            K = K[:, fin]
            if not rows.size:
                return
        event = ~m.in_C(rows, yb, b, j) if m.has_C else np.zeros(len(rows), dtype=bool)
        if self.watch_D:
            inDb = m.in_D(rows, yb, b, j)
            event |= inDb & ~self.inD_prev[rows]
        else:
            inDb = None
        ok = self._reap(rows)
        if ok is not None:
            rows, a, ya, j, h, b, yb, event = (rows[ok], a[ok], ya[ok], j[ok], h[ok], b[ok],
                                               yb[ok], event[ok])
            inDb = inDb[ok] if inDb is not None else None
            K = K[:, ok]
            if not rows.size:
                return
        if event.any():
            e = event
            Q = np.einsum("skn,sp->knp", K[:, e], _P)
            self._event(rows[e], a[e], b[e], ya[e], h[e], Q, j[e])
        calm = ~event
        if not calm.any():
            return
        # the inside of the other steps: D entered and left (or C left and
        # re-entered) within one step; and an entry into D within round-off
        # after t_max, which is taken at t_max
        watch = np.zeros(len(rows), dtype=bool)
        if m.has_C:
            watch[:] = True
        if self.watch_D:
            watch |= ~self.inD_prev[rows]
        watch &= calm
        if watch.any():
            w = np.flatnonzero(watch)
            Qw = np.einsum("skn,sp->knp", K[:, w], _P)
            lo_b, hi_b, found = self._interior(rows[w], a[w], b[w], ya[w], h[w], Qw, j[w])
            late = ~found & (b[w] >= self.t_max)
            if self.watch_D and late.any():
                wl = np.flatnonzero(late)
                rl = rows[w][wl]
                tb = b[w][wl] + t_max_slack(self.t_max) * (8.0 + self.jumps[rl]) / 8.0
                ys = self._dense(a[w][wl], h[w][wl], ya[w][wl], Qw[wl], tb)
                pred = self._pred(rl, ys, tb, j[w][wl], ~self.inD_prev[rl])
                pred &= ~self.inD_prev[rl]
                found_late = np.zeros(len(w), dtype=bool)
                found_late[wl[pred]] = True
                lo_b[found_late] = b[w][found_late]
                hi_b[found_late] = tb[pred]
            else:
                found_late = np.zeros(len(w), dtype=bool)
            for sel, clamp in ((found, None), (found_late, self.t_max)):
                if sel.any():
                    ww = w[sel]
                    self._event(rows[ww], a[ww], hi_b[sel], ya[ww], h[ww], Qw[sel], j[ww],
                                lo0=lo_b[sel], clamp=clamp)
                    calm[ww] = False
            if not calm.any():
                return
        self.steps[rows] += 1
        over = calm & (self.steps[rows] >= self.max_steps)
        if over.any():
            orow, ot = rows[over], b[over]
            ms = self.max_steps
            self.log.append(orow, ot, j[over], yb[over])
            self._stop(orow, Termination.MAX_STEPS,
                       lambda i: f"{ms} solver steps (max_steps) at t={ot[i]:.10g}")
            calm &= ~over
            if not calm.any():
                return
        rows, b, yb, j = rows[calm], b[calm], yb[calm], j[calm]
        if self.refine > 1:
            Qc = np.einsum("skn,sp->knp", K[:, calm], _P)
            self._refine(rows, a[calm], b, ya[calm], h[calm], Qc, j)
        self.t[rows] = b
        self.x[rows] = yb
        self.fx[rows] = K[_NS][calm]
        if inDb is not None:
            self.inD_prev[rows] = inDb[calm]
        self.log.append(rows, b, j, yb)
        if self.max_norm < math.inf:
            nrm = np.linalg.norm(yb, axis=1)
            big = nrm > self.max_norm
            if big.any():
                br, bn, bt = rows[big], nrm[big], b[big]
                mn = self.max_norm
                self._stop(br, Termination.BLOWUP,
                           lambda i: f"|x| = {bn[i]:.3g} > {mn:.3g} at t={bt[i]}")
        end = b >= self.t_max
        if end.any():
            er = rows[end]
            self.decide[er] = True           # jumps at t_max are still taken
            self.h[er] = np.nan

    # ------------------------------------------------------------ events
    def _refine(self, rows, a, b, ya, h, Q, j):
        """Store ``refine - 1`` dense-output samples strictly inside each (a, b)."""
        R = self.refine
        for k in range(1, R):
            s = a + (b - a) * (k / R)
            self.log.append(rows, s, j, self._dense(a, h, ya, Q, s))

    def _dense(self, a, h, ya, Q, s):
        """RK45 dense output (scipy's RkDenseOutput) of each row at its time s."""
        xx = (s - a) / h
        p = np.stack([xx, xx * xx, xx ** 3, xx ** 4], axis=1)
        return ya + h[:, None] * np.einsum("knp,kp->kn", Q, p)

    def _pred(self, rows, y, s, j, wd):
        """The event has happened: x left C, or entered D (rows with ``wd``)."""
        m = self.maps
        ev = np.zeros(len(rows), dtype=bool)
        if m.has_C:
            ev |= ~m.in_C(rows, y, s, j)
        if self.watch_D and wd.any():
            ev |= wd & m.in_D(rows, y, s, j)
        return ev

    def _phi(self, rows, y, s, j, wd):
        """Continuous version of :meth:`_pred` (>= 0 where the event has happened)."""
        m = self.maps
        v = np.full(len(rows), -np.inf)
        if self.watch_D and m.hD is not None and wd.any():
            v = np.where(wd, m.guard_D(rows, y, s, j), -np.inf)
        if m.has_C and m.hC is not None:
            v = np.maximum(v, -m.guard_C(rows, y, s, j))
        return v

    def _locate(self, rows, a, b, ya, h, Q, j, wd, lo0=None):
        """Bracket the first event in (a, b] of each row on its dense output.

        The batch version of :func:`hybridsim.events.locate_event`: the
        predicate (set indicators) decides each probe's side, so ``hi`` is
        always an event point and ``lo`` is not (or ``lo = a``); brackets end
        4 eps max(1, |t|) wide. Where the guards bracket a sign change, the
        probe is an Illinois-type regula falsi step (Anderson-Bjorck weights,
        kept off the ends); a bracket that has not halved in the last
        ``_STALL`` probes gets a bisection, and so does a step that starts on
        the guard's zero (a flow just after a jump), so a flow re-entering D
        within one step is never lost.

        Returns
        -------
        lo, hi : ndarray, shape (k,)
        ylo, yhi : ndarray, shape (k, n)
        """
        k = len(rows)
        tol = 4.0 * _EPS * np.maximum(1.0, np.maximum(np.abs(a), np.abs(b)))
        lo, hi = (a if lo0 is None else lo0).copy(), b.copy()
        ylo = self._dense(a, h, ya, Q, lo)
        yhi = self._dense(a, h, ya, Q, hi)
        out = [lo.copy(), hi.copy(), ylo.copy(), yhi.copy()]
        use_phi = self.use_phi
        if use_phi:
            flo = self._phi(rows, ylo, lo, j, wd)
            fhi = self._phi(rows, yhi, hi, j, wd)
        else:
            flo = fhi = np.zeros(k)
        side = np.zeros(k, dtype=np.int8)
        hist = np.full((k, _STALL), np.inf)  # bracket widths of the last probes
        pos = np.arange(k)                   # where each working row goes in ``out``
        for it in range(200):
            fin = (hi - lo <= tol) | self.bad[rows]
            if fin.any():
                p = pos[fin]
                out[0][p], out[1][p], out[2][p], out[3][p] = lo[fin], hi[fin], ylo[fin], yhi[fin]
                w = ~fin
                if not w.any():
                    break
                (pos, rows, a, h, ya, Q, j, wd, tol, lo, hi, ylo, yhi, flo, fhi, side,
                 hist) = (v[w] for v in (pos, rows, a, h, ya, Q, j, wd, tol, lo, hi, ylo,
                                         yhi, flo, fhi, side, hist))
            width = hi - lo
            m = 0.5 * (lo + hi)
            if use_phi:
                ill = (flo < 0.0) & (0.0 <= fhi) & (fhi - flo > 0) & \
                    ~(width > 0.5 * hist[:, it % _STALL])
                if ill.any():
                    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                        r = hi - fhi * width / (fhi - flo)
                    g = np.maximum(tol, 1e-3 * width)
                    r = np.minimum(np.maximum(r, lo + 0.5 * g), hi - 0.5 * g)
                    ill &= (lo < r) & (r < hi)
                    m = np.where(ill, r, m)
            ym = self._dense(a, h, ya, Q, m)
            hit = self._pred(rows, ym, m, j, wd)
            if use_phi:
                fm = self._phi(rows, ym, m, j, wd)
                with np.errstate(divide="ignore", invalid="ignore"):
                    # Anderson-Bjorck: scale the end that stays twice
                    kl = np.where(hit & (side == 1), 1.0 - fm / fhi, 1.0)
                    kh = np.where(~hit & (side == -1), 1.0 - fm / flo, 1.0)
                flo = flo * np.where(kl > 0, kl, 0.5)
                fhi = fhi * np.where(kh > 0, kh, 0.5)
                fhi = np.where(hit, fm, fhi)
                flo = np.where(hit, flo, fm)
                side = np.where(hit, 1, -1).astype(np.int8)
            hi = np.where(hit, m, hi)
            lo = np.where(hit, lo, m)
            hit2 = hit[:, None]
            yhi = np.where(hit2, ym, yhi)
            ylo = np.where(hit2, ylo, ym)
            hist[:, it % _STALL] = hi - lo
        else:
            out[0][pos], out[1][pos], out[2][pos], out[3][pos] = lo, hi, ylo, yhi
        return out

    def _interior(self, rows, a, b, ya, h, Q, j):
        """The batch version of :func:`hybridsim.events.find_interior_event`.

        Three interior samples of each step's dense output, the indicators
        tested there; with guards, every sampled local maximum of the guard
        whose peak could reach 0 refined by a golden-section search (row by
        row: such peaks are rare). Returns (lo, hi, found): a bracket with the
        event set entered at hi, where found.
        """
        k = len(rows)
        wd = ~self.inD_prev[rows]
        lo_b, hi_b = a.copy(), b.copy()
        found = np.zeros(k, dtype=bool)
        prev = a.copy()
        pts, vals = [a], []
        if self.use_phi:
            vals.append(self._phi(rows, self._dense(a, h, ya, Q, a), a, j, wd))
        for q in (1, 2, 3):
            s = a + (b - a) * (q / 4.0)
            ys = self._dense(a, h, ya, Q, s)
            hit = ~found & self._pred(rows, ys, s, j, wd)
            lo_b[hit], hi_b[hit] = prev[hit], s[hit]
            found |= hit
            prev = s
            pts.append(s)
            if self.use_phi:
                vals.append(self._phi(rows, ys, s, j, wd))
        self._reap(rows)
        if not self.use_phi or found.all():
            return lo_b, hi_b, found
        pts.append(b)
        vals.append(self._phi(rows, self._dense(a, h, ya, Q, b), b, j, wd))
        V, T = np.array(vals), np.array(pts)           # (5, k)
        for q in (1, 2, 3):
            lo_nb = np.minimum(V[q - 1], V[q + 1])
            cand = (~found & np.isfinite(V).all(axis=0) & (V[q] >= V[q - 1])
                    & (V[q] >= V[q + 1]) & _near_peak(V[q], lo_nb))
            for i in np.flatnonzero(cand):
                ri = rows[i:i + 1]
                wi, ji = wd[i:i + 1], j[i:i + 1]

                def sol(s, i=i):
                    return self._dense(a[i:i + 1], h[i:i + 1], ya[i:i + 1], Q[i:i + 1],
                                       np.array([s]))[0]

                def F(s, y, ri=ri, ji=ji, wi=wi):
                    return float(self._phi(ri, y[None, :], np.array([s]), ji, wi)[0])

                def pred(s, y, ri=ri, ji=ji, wi=wi):
                    return bool(self._pred(ri, y[None, :], np.array([s]), ji, wi)[0])
                sq = _maximize(F, T[q - 1, i], T[q + 1, i], V[q - 1, i], V[q + 1, i], pred, sol)
                if sq is not None:
                    found[i] = True
                    lo_b[i], hi_b[i] = T[q - 1, i], sq
        return lo_b, hi_b, found

    def _event(self, rows, a, b, ya, h, Q, j, lo0=None, clamp=None):
        """Locate the first event in (lo0, b] (default (a, b]) of the steps from a of
        ``rows`` and decide what happens there; ``clamp``: record event times no
        later than it (an event within round-off after t_max is taken at t_max)."""
        m = self.maps
        # a flow that started in D (random priority flowing on) watches only C
        wd = ~self.inD_prev[rows]
        lo, hi, ylo, yhi = self._locate(rows, a, b, ya, h, Q, j, wd, lo0)
        ok = self._reap(rows)
        if ok is not None:
            rows, a, ya, h, Q, lo, hi, ylo, yhi, j = (rows[ok], a[ok], ya[ok], h[ok], Q[ok],
                                                      lo[ok], hi[ok], ylo[ok], yhi[ok], j[ok])
            if not rows.size:
                return
        # next flow's first step (as simulate): at most 10x the length of this
        # flow; the controller's proposal after an overshooting step can be
        # huge where the flow is integrated exactly, and long steps cancel digits
        self.h[rows] = np.minimum(self.h[rows], _MAX_FACTOR * (hi - self.t_flow0[rows]))
        k = len(rows)
        kind = np.zeros(k, dtype=np.int8)    # 0 undecided, 1 jump at hi, 2 jump at lo,
        #                                      3 continue at hi, 4 leave C at lo
        if self.watch_D:
            dhi = m.in_D(rows, yhi, hi, j)
            kind[dhi] = 1
            if self.prio == Priority.RANDOM and dhi.any():
                idx = np.flatnonzero(dhi)
                cin = m.in_C(rows[idx], yhi[idx], hi[idx], j[idx])
                coin = self.rng.random(len(idx)) >= 0.5
                kind[idx[cin & coin]] = 3
        und = np.flatnonzero(kind == 0)
        if und.size and m.has_D:
            dlo = m.in_D(rows[und], ylo[und], lo[und], j[und])
            kind[und[dlo]] = 2
            und = und[~dlo]
            if und.size:
                dhi2 = m.in_D(rows[und], yhi[und], hi[und], j[und])
                kind[und[dhi2]] = 1
        kind[kind == 0] = 4
        ok = self._reap(rows)
        if ok is not None:
            rows, a, ya, h, Q, lo, hi, ylo, yhi, j, kind = (
                rows[ok], a[ok], ya[ok], h[ok], Q[ok], lo[ok], hi[ok], ylo[ok], yhi[ok],
                j[ok], kind[ok])
        at_hi = (kind == 1) | (kind == 3)
        at_lo = (kind == 2) | (kind == 4)
        ts = np.where(at_hi, hi, lo)
        if clamp is not None:
            ts = np.minimum(ts, clamp)
        xs = np.where(at_hi[:, None], yhi, ylo)
        sample = ts > a
        if self.refine > 1:
            self._refine(rows[sample], a[sample], ts[sample], ya[sample], h[sample],
                         Q[sample], j[sample])
        self.log.append(rows[sample], ts[sample], j[sample], xs[sample])
        self.t[rows] = ts
        self.x[rows] = xs
        jump = (kind == 1) | (kind == 2)
        if jump.any():
            self.force[rows[jump]] = True
            self.decide[rows[jump]] = True
        cont = kind == 3
        done = cont & (ts >= self.t_max)     # flowing on at t_max: the run ends there
        if done.any():
            self._stop(rows[done], Termination.T_MAX)
            cont &= ~done
        if cont.any():                       # random priority chose to flow on in C ∩ D
            self._start_flow(rows[cont], np.ones(int(cont.sum()), dtype=bool))
        left = at_lo & ~jump
        if left.any():
            lr, lt, lj, lx = rows[left], lo[left], j[left], ylo[left]
            self._stop(lr, Termination.LEFT_SETS,
                       lambda i: f"the flow left C at t={lt[i]} (j={lj[i]}), x={lx[i]}, "
                                 "outside D")
