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
"""
from __future__ import annotations

import bisect
import inspect
import itertools
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import DOP853, RK45, OdeSolver
from scipy.integrate._ivp import dop853_coefficients as _dop

from ._progress import make_bar
from ._rk import MAX_FACTOR, MIN_FACTOR, SAFETY
from .arc import Crossings, HybridArc, Termination
from .arc_batch import ArcBatch
from .events import WATCH_SAMPLES, _maximize, _near_peak, crossing_sides, starts_on_zero
from .history import BatchHistory
from .options import (
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
    Action,
    MapError,
    Priority,
    after_jump,
    chatter_step,
    event_outcome,
    event_tolerance,
    finish_batch,
    is_jump_loop,
    is_sticking,
    jumps_now,
    message,
    needs_coin,
    post_jump_probe,
    t_max_slack,
    time_scale,
    zeno_short,
)
from .system import (
    HybridSystem,
    as_map,
    check_watch_direction,
    guard_rows,
    watch_directions,
)

__all__ = ["simulate_vectorized"]

_EPS = np.finfo(float).eps
# scipy's RK45 tableau, error weights and dense-output matrix
_A, _B, _C, _E, _P = RK45.A, RK45.B, RK45.C, RK45.E, RK45.P
_NS = RK45.n_stages
_ERR_EXP = -1.0 / (RK45.error_estimator_order + 1)
#: scipy's DOP853 (``method="DOP853"``): its tableau (12 stages), error weights
#: and dense output (3 more stages, then D); the rules of simulate's DOP853
_DOP = {"A": DOP853.A, "B": DOP853.B, "C": DOP853.C, "E3": DOP853.E3, "E5": DOP853.E5,
        "D": DOP853.D, "AX": _dop.A, "CX": _dop.C, "ns": DOP853.n_stages,
        "exp": -1.0 / (DOP853.error_estimator_order + 1),
        "order": DOP853.error_estimator_order}
# scipy's step-size controller constants, as the other paths take them (hybridsim._rk)
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = SAFETY, MIN_FACTOR, MAX_FACTOR
_TOO_SMALL = "Required step size is less than spacing between numbers."
# options of simulate() the batch integrator does not implement (refused by
# options.check_unsupported unless at their do-nothing value)
_UNSUPPORTED = ("inputs", "prehistory", "dense", "t_eval", "dwell")
# rules.event_tolerance(a, b) = unit * max(1, |a|, |b|); the unit read from the rule
_TOL_UNIT = event_tolerance(1.0, 1.0)
_MAX_ITER = 200     # bisection steps of locate_event
_SECANT_ITER = 100  # secant steps of events._secant
# stage weights of the dense output's derivative: d/ds of (s, s^2, s^3, s^4)
_DP = np.array([1.0, 2.0, 3.0, 4.0])


def _tol(lo, hi):
    """:func:`hybridsim.rules.event_tolerance` over arrays (bit for bit the same).

    Belongs in rules.py: ``event_tolerance`` takes Python floats only.
    """
    return _TOL_UNIT * np.maximum(1.0, np.maximum(np.abs(lo), np.abs(hi)))


def _root_off_zero(f0, fd, fw, d, w):
    """:func:`hybridsim.events._root_off_zero` over arrays: ``(offset, slope)``,
    NaN where the quadratic model has no root in (d, w)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        m = (fd - f0) / d
        c = (fw - f0 - m * w) / (w * w)
        disc = m * m - 4.0 * c * f0
        ok = (c > 0.0) & (disc >= 0.0)
        r = np.sqrt(np.where(ok, disc, 0.0))
        tau = (r - m) / (2.0 * c)
    ok &= (d < tau) & (tau < w)
    return np.where(ok, tau, np.nan), np.where(ok, r, np.nan)


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


def _rms(a):
    """Row-wise RMS norm of a (k, n) array (scipy's ``norm`` per row)."""
    return np.sqrt(np.einsum("ij,ij->i", a, a) / a.shape[1])


class _NonFiniteStep(Exception):
    """Internal: a row's dense output became non-finite inside an accepted step."""


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


class _VMaps:
    """The system's maps called over batches, with shape checks.

    A call that raises (or returns a wrong shape) during the run is retried row
    by row; the rows that still fail are recorded in ``run.bad`` (they end
    with ``MAP_ERROR``, the error a :class:`MapError` naming the map, t and
    j, chained from the map's exception, as in :func:`hybridsim.simulate`)
    and get a harmless placeholder value. A guard returning NaN is a
    contract breach of that row (``MAP_ERROR`` naming the guard). With
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
        # watched functions (rule 11): (N, n) -> (N,) or (N, m); m fixed by the first call
        self.W = as_map(system.watch, "watch") if system.watch is not None else None
        self.m_watch = None
        self.run = None
        self.hist = None            # a BatchHistory where the maps read their past

    # ---------------------------------------------------------------- checks
    def _check(self, kind, name, val, k):
        if np.iscomplexobj(val):
            raise MapError(f"{name} returned complex values: "
                           f"{'a guard' if kind == 'guard' else 'the state'} is real", name)
        if kind == "state":
            arr = np.asarray(val, dtype=float)
            if arr.shape != (k, self.n):
                raise MapError(f"{name} must return an array of shape ({k}, {self.n}) "
                               f"(vectorized system: one row per trajectory), got shape "
                               f"{arr.shape}", name)
            return arr
        if kind == "set":
            arr = np.asarray(val)
            if arr.shape != (k,):
                raise MapError(f"{name} must return a boolean array of shape ({k},) "
                               f"(vectorized system: one entry per trajectory), got shape "
                               f"{arr.shape}", name)
            return arr.astype(bool)
        arr = np.asarray(val, dtype=float)   # guard: (k,) or (k, m)
        if arr.ndim == 2 and arr.shape[0] == k and arr.shape[1] >= 1:
            return guard_rows(arr)
        if arr.shape != (k,):
            raise MapError(f"{name} must return an array of shape ({k},) or ({k}, m) "
                           f"(vectorized system: one row per trajectory), got shape "
                           f"{arr.shape}", name)
        return arr

    def _fail(self, r, err):
        run = self.run
        if not run.bad[r]:
            run.bad[r] = True
            run.bad_exc[r] = err

    def _nan_guard(self, name, rows, out, t, j, strict):
        """A guard's NaN rows: MapError naming it (as simulate's sets from guards)."""
        nan = np.isnan(out)
        if not nan.any():
            return out
        for i in np.flatnonzero(nan):
            err = MapError(f"{name} returned NaN (at t={float(t[i]):.10g}, j={int(j[i])})",
                           name, float(t[i]), int(j[i]))
            if strict:
                raise err
            self._fail(rows[i], err)
        return np.where(nan, -1.0, out)

    def _call(self, kind, name, fn, rows, x, t, j, strict=False):
        k = len(rows)
        if k == 0:
            return (np.empty((0, self.n)) if kind == "state"
                    else np.empty(0, dtype=bool if kind == "set" else float))
        hist = self.hist
        if hist is not None:        # the rows whose past self.history reads
            hist.rows = rows
        try:
            out = self._check(kind, name, fn(x, t, j, None), k)
        except (KeyboardInterrupt, SystemExit):
            raise
        except MapError as e:
            if strict:
                raise _located(e, t[0], j[0]) from e.__cause__
        except Exception as e:
            if strict:          # at x0, as simulate: a MapError naming the map
                raise MapError(f"{name} raised {type(e).__name__}: {e} (at the initial "
                               f"states, t={t[0]:.10g})", name, float(t[0]), int(j[0])) from e
        else:
            return out if kind != "guard" else self._nan_guard(name, rows, out, t, j, strict)
        if kind == "state":
            out = np.zeros((k, self.n))
        else:
            out = np.zeros(k, dtype=bool if kind == "set" else float)
        for i in range(k):
            if hist is not None:
                hist.rows = rows[i:i + 1]
            try:
                out[i] = self._check(kind, name, fn(x[i:i + 1], t[i:i + 1], j[i:i + 1], None),
                                     1)[0]
            except (KeyboardInterrupt, SystemExit):
                raise
            except Exception as e:  # noqa: BLE001
                if not isinstance(e, MapError):
                    err = MapError(f"{name} raised {type(e).__name__}: {e} (at "
                                   f"t={float(t[i]):.10g}, j={int(j[i])})", name,
                                   float(t[i]), int(j[i]))
                    err.__cause__ = e
                    e = err
                self._fail(rows[i], _located(e, t[i], j[i]))
        return out if kind != "guard" else self._nan_guard(name, rows, out, t, j, strict)

    def _watch_rows(self, v, k, t, j):
        """A batch's watched values as (k, m) floats, checked."""
        if np.iscomplexobj(v):
            raise MapError("watch returned complex values: a watched function is real",
                           "watch")
        arr = np.asarray(v, dtype=float)
        if arr.shape == (k,):
            arr = arr[:, None]
        m = self.m_watch
        if arr.ndim != 2 or arr.shape[0] != k or arr.shape[1] < 1 or (
                m is not None and arr.shape[1] != m):
            raise MapError(f"watch must return an array of shape ({k},) or ({k}, "
                           f"{m or 'm'}) (vectorized system: one row per trajectory), got "
                           f"shape {arr.shape}", "watch")
        if not np.isfinite(arr).all():
            i = int(np.flatnonzero(~np.isfinite(arr).all(axis=1))[0])
            raise MapError(f"watch returned non-finite values {arr[i]} (at "
                           f"t={float(t[i]):.10g}, j={int(j[i])})", "watch",
                           float(t[i]), int(j[i]))
        self.m_watch = arr.shape[1]
        return arr

    def watch(self, rows, x, t, j, strict=False):
        """The watched functions of ``rows``, (k, m); a row on which they fail is
        recorded (``MAP_ERROR`` naming ``watch``) and gets NaN."""
        k = len(rows)
        try:
            return self._watch_rows(self.W(x, t, j, None), k, t, j)
        except (KeyboardInterrupt, SystemExit):
            raise
        except Exception as e:
            if strict:
                if isinstance(e, MapError):
                    raise _located(e, t[0], j[0]) from e.__cause__
                raise MapError(f"watch raised {type(e).__name__}: {e} (at the initial "
                               f"states, t={t[0]:.10g})", "watch", float(t[0]),
                               int(j[0])) from e
        rows_v = [None] * k
        for i in range(k):
            try:
                rows_v[i] = self._watch_rows(self.W(x[i:i + 1], t[i:i + 1], j[i:i + 1], None),
                                             1, t[i:i + 1], j[i:i + 1])[0]
            except (KeyboardInterrupt, SystemExit):
                raise
            except Exception as e:  # noqa: BLE001
                if not isinstance(e, MapError):
                    err = MapError(f"watch raised {type(e).__name__}: {e} (at "
                                   f"t={float(t[i]):.10g}, j={int(j[i])})", "watch",
                                   float(t[i]), int(j[i]))
                    err.__cause__ = e
                    e = err
                self._fail(rows[i], _located(e, t[i], j[i]))
        out = np.full((k, self.m_watch or 1), np.nan)
        for i, v in enumerate(rows_v):
            if v is not None:
                out[i] = v
        return out

    # ------------------------------------------------------------ the maps
    def flow(self, rows, x, t, j, strict=False):
        return self._call("state", "flow_map", self.f, rows, x, t, j, strict)

    def flow_soft(self, x, t, j, rows=None):
        """The flow map's value where it is defined, NaN where it raises or is
        not a row of floats (samples' ``xdot``: outside C the flow map may be
        undefined); nothing is recorded. ``rows``: whose past the maps read."""
        k = len(x)
        out = np.full((k, self.n), np.nan)
        if k == 0:
            return out
        hist = self.hist
        if hist is not None:
            hist.rows = rows
        with np.errstate(all="ignore"):
            try:
                v = np.asarray(self.f(x, t, j, None), dtype=float)
                if v.shape == (k, self.n):
                    return v
            except (KeyboardInterrupt, SystemExit):
                raise
            except Exception:  # noqa: BLE001 - row by row below
                pass
            for i in range(k):
                if hist is not None:
                    hist.rows = rows[i:i + 1]
                try:
                    v = np.asarray(self.f(x[i:i + 1], t[i:i + 1], j[i:i + 1], None), dtype=float)
                except (KeyboardInterrupt, SystemExit):
                    raise
                except Exception:  # noqa: BLE001 - undefined there: NaN
                    continue
                if v.shape == (1, self.n):
                    out[i] = v[0]
        return out

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


def _located(e, t, j):
    """A :class:`MapError` of a batch's value check, with the row's t and j
    where it has none yet."""
    if e.t is not None:
        return e
    err = MapError(f"{e} (at t={float(t):.10g}, j={int(j)})", e.map_name, float(t), int(j))
    err.__cause__ = e.__cause__
    return err


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
    method : {"RK45", "DOP853"} or scipy's class
        The Runge-Kutta pair (scipy's coefficients, error norm, step-size
        controller and dense output; DOP853 takes several times fewer steps
        at tight tolerances, and its dense output, three more evaluations of
        the flow map, is made only for steps with an event or refined
        samples). DOP853 not for a system that reads its past; other methods
        raise ``ValueError`` naming these two.
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


class _BatchRun:
    """State of a batch run: one entry per trajectory in every array."""

    def __init__(self, system, X, n, ro, rng, method="RK45"):
        N = len(X)
        self.N, self.n = N, n
        # the method: RK45's stages and exponent, or DOP853's (``self.dop``)
        self.dop = _DOP if method == "DOP853" else None
        self.ns = _DOP["ns"] if self.dop else _NS
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

    # ------------------------------------------------------------ watched functions
    def _watch_start(self, rows):
        """Flows start at the rows' current states: the watched functions there."""
        t, x, j = self.t[rows], self.x[rows], self.j[rows]
        v = self.maps.watch(rows, x, t, j)
        if self.w_v is None:
            m = v.shape[1]
            self.w_dir = watch_directions(self.w_direction, m)
            self.w_v = np.full((self.N, m), np.nan)
        self.w_v[rows] = v
        self.w_floor[rows] = np.where(t == self.t_last[rows], t, -np.inf)

    def _watch_to(self, rows, a, ya, h, Q, b, yb, j):
        """The crossings of the watched functions on the steps from (a, ya) to
        (b, yb) of ``rows`` (their dense outputs ``Q``): the batch version of
        :func:`hybridsim.events.watch_crossings` (the values at the ends and
        at its interior points, every sign change bracketed to 4 ulp by this
        path's :meth:`_secant`, all rows' crossings at once)."""
        m = self.maps
        va = self.w_v[rows]
        vb = m.watch(rows, yb, b, j)
        pts, ys, vals = [a], [ya], [va]
        for q in range(1, WATCH_SAMPLES + 1):
            s = a + (b - a) * (q / (WATCH_SAMPLES + 1.0))
            y = self._dense(a, h, ya, Q, s)
            pts.append(s)
            ys.append(y)
            vals.append(m.watch(rows, y, s, j))
        pts.append(b)
        ys.append(yb)
        vals.append(vb)
        self.w_v[rows] = vb
        d = self.w_dir
        it, ik, isg, lo, hi, flo, fhi, ylo, yhi = ([] for _ in range(9))
        for q in range(len(pts) - 1):
            up, down = crossing_sides(vals[q], vals[q + 1], d)
            i, k = np.nonzero(up | down)
            if not i.size:
                continue
            sg = np.where(up[i, k], 1.0, -1.0)
            it.append(i)
            ik.append(k)
            isg.append(sg)
            lo.append(pts[q][i])
            hi.append(pts[q + 1][i])
            flo.append(sg * vals[q][i, k])
            fhi.append(sg * vals[q + 1][i, k])
            ylo.append(ys[q][i])
            yhi.append(ys[q + 1][i])
        if not it:
            return
        it, ik, isg, lo, hi, flo, fhi = (np.concatenate(v) for v in (it, ik, isg, lo, hi,
                                                                     flo, fhi))
        ylo, yhi = np.concatenate(ylo), np.concatenate(yhi)
        keep = ~self.bad[rows[it]] & (b[it] > a[it])
        it, ik, isg, lo, hi, flo, fhi, ylo, yhi = (v[keep] for v in (it, ik, isg, lo, hi, flo,
                                                                     fhi, ylo, yhi))
        if not it.size:
            return
        ri = rows[it]

        def ev(ii, s):
            r = it[ii]
            return self._dense(a[r], h[r], ya[r], Q[r], s)

        def phi(ii, s, y):
            v = m.watch(ri[ii], y, s, j[it[ii]])
            return isg[ii] * v[np.arange(len(ii)), ik[ii]]
        nan = np.full(len(it), np.nan)
        _, tc, _, xc = self._secant(ri, np.arange(len(it)), lo, hi, flo, fhi, ylo, yhi, nan,
                                    nan, ev, phi)
        floor = self.w_floor[ri]
        ok = ~starts_on_zero(floor, tc, _tol(floor, tc)) & ~self.bad[ri]
        for q in np.lexsort((ik, tc, ri))[ok[np.lexsort((ik, tc, ri))]].tolist():
            self.cross[int(ri[q])].append((float(tc[q]), int(j[it[q]]), int(ik[q]),
                                           int(isg[q]), xc[q].copy()))

    # ------------------------------------------------------------ main loop
    def run(self):
        N = self.N
        rows = np.arange(N)
        self.log.append(rows, self.t, self.j, self.x)
        self._validate()
        cap = self.max_samples
        while True:
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

    def _initial_step(self, rows, y0, t0, j, f0, span):
        """scipy's ``select_initial_step`` (the method's error order), row by row
        in one go. The batch form of the kernel's ``_steps._initial_guess`` and
        ``_initial_step`` (the Python path takes scipy's own): every row's norms
        and branch in one array expression, which a per-row scalar rule would
        turn into a Python loop over the rows."""
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
        order = self.dop["order"] if self.dop else 4
        with np.errstate(divide="ignore"):
            h1 = np.where((d1 <= 1e-15) & (d2 <= 1e-15), np.maximum(1e-6, h0 * 1e-3),
                          (0.01 / np.maximum(d1, d2)) ** (1.0 / (order + 1)))
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
        small = rej & ~(h_abs >= min_step)     # a NaN step (non-finite flow) too
        if small.any():
            sr, st, ss, sj = rows[small], t[small], self.short[rows[small]], j[small]
            nf = self.nonfinite[sr]        # a non-finite flow map: NON_FINITE, as in simulate
            if nf.any():
                self._stop(sr[nf], Termination.NON_FINITE, "flow", t=st[nf], j=sj[nf])
            zeno = (ss > 0) & ~nf
            if zeno.any():
                self._stop(sr[zeno], Termination.ZENO, "short", t=st[zeno])
            fail = ~zeno & ~nf
            if fail.any():
                self._stop(sr[fail], Termination.SOLVER_FAILED, reason=_TOO_SMALL,
                           t=st[fail], j=sj[fail])
            keep = ~small
            rows, t, y, j, f, rej, h_abs = (rows[keep], t[keep], y[keep], j[keep], f[keep],
                                           rej[keep], h_abs[keep])
            if not rows.size:
                return
        t_new = np.minimum(t + h_abs, self._bound(rows, t))
        h = t_new - t
        h_abs = np.abs(h)
        self.attempts[rows] += 1
        ns, dop = self.ns, self.dop
        A, B, C = (dop["A"], dop["B"], dop["C"]) if dop else (_A, _B, _C)
        self.nfev[rows] += ns
        # Dormand-Prince stages (scipy's rk_step, one row per trajectory)
        k = len(rows)
        K = np.empty((ns + 1, k, self.n))
        K[0] = f
        hc = h[:, None]
        # overflow/NaN end as a rejected step or NON_FINITE, as in simulate
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            for s in range(1, ns):
                dy = np.tensordot(A[s, :s], K[:s], axes=(0, 0)) * hc
                K[s] = m.flow(rows, y + dy, t + C[s] * h, j)
            y_new = y + hc * np.tensordot(B, K[:ns], axes=(0, 0))
            K[ns] = m.flow(rows, y_new, t + h, j)
            scale = self.atol + np.maximum(np.abs(y), np.abs(y_new)) * self.rtol
            if dop:
                # DOP853._estimate_error_norm, row by row
                e5 = np.sum((np.tensordot(dop["E5"], K, axes=(0, 0)) / scale) ** 2, axis=1)
                e3 = np.sum((np.tensordot(dop["E3"], K, axes=(0, 0)) / scale) ** 2, axis=1)
                err_norm = np.where((e5 == 0) & (e3 == 0), 0.0,
                                    h_abs * e5 / np.sqrt((e5 + 0.01 * e3) * self.n))
            else:
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
            factor = _SAFETY * err_norm ** self.err_exp
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
        self.steps[rows] += 1
        self.t_step[rows] = b
        fin = np.isfinite(yb).all(axis=1)
        if not fin.all():
            self._stop(rows[~fin], Termination.NON_FINITE, "step", t=a[~fin], t2=b[~fin],
                       j=j[~fin])
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
            Q = self._dense_of(rows[e], a[e], ya[e], h[e], yb[e], K[:, e], j[e])
            self._event(rows[e], a[e], a[e], b[e], ya[e], h[e], Q, j[e], ylo=ya[e], yhi=yb[e])
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
            if self.dop:
                # simulate's rule for DOP853: the search on the cubic Hermite of
                # each step's ends, a hit confirmed on the dense output (made
                # only for the rows that need it: three evaluations more)
                Qh = np.stack([yb[w], h[w][:, None] * K[0][w], h[w][:, None] * K[self.ns][w]],
                              axis=2)
                lo_b, hi_b, found = self._interior(rows[w], a[w], b[w], ya[w], h[w], Qh, j[w])
                Qw = np.full((len(w), self.n, 7), np.nan)
                made = np.zeros(len(w), dtype=bool)

                def dense(sel):
                    sel = sel[~made[sel]]
                    if sel.size:
                        ws = w[sel]
                        Qw[sel] = self._dense_of(rows[ws], a[ws], ya[ws], h[ws], yb[ws],
                                                 K[:, ws], j[ws])
                        made[sel] = True
                fi = np.flatnonzero(found)
                if fi.size:
                    dense(fi)
                    wf = w[fi]
                    lo_b[fi], hi_b[fi], found[fi] = self._interior(
                        rows[wf], a[wf], b[wf], ya[wf], h[wf], Qw[fi], j[wf])
            else:
                Qw = np.einsum("skn,sp->knp", K[:, w], _P)
                lo_b, hi_b, found = self._interior(rows[w], a[w], b[w], ya[w], h[w], Qw,
                                                   j[w])
            late = ~found & (b[w] >= self.t_max) & ~self.bad[rows[w]]
            if self.dop:             # (simulate: only a flow watching D reads it)
                late &= ~self.inD_prev[rows[w]]
            found_late = np.zeros(len(w), dtype=bool)
            if self.watch_D and late.any():
                wl = np.flatnonzero(late)
                if self.dop:
                    dense(wl)
                rl = rows[w][wl]
                tb = b[w][wl] + t_max_slack(self.t_max, self.jumps[rl])
                ys = self._dense(a[w][wl], h[w][wl], ya[w][wl], Qw[wl], tb)
                self._finite(rl, ys)
                wdl = ~self.inD_prev[rl]
                pred = self._pred(rl, ys, tb, j[w][wl], wdl) & wdl & ~self.bad[rl]
                found_late[wl[pred]] = True
                lo_b[found_late] = b[w][found_late]
                hi_b[found_late] = tb[pred]
            for sel, clamp in ((found, None), (found_late, self.t_max)):
                if sel.any():
                    ww = w[sel]
                    # the step's end is where the solver is (simulate: ylo=solver.y)
                    ylo = yb[ww] if clamp is not None else None
                    self._event(rows[ww], a[ww], lo_b[sel], hi_b[sel], ya[ww], h[ww],
                                Qw[sel], j[ww], ylo=ylo, clamp=clamp)
                    calm[ww] = False
            bad = self.bad[rows]
            if bad.any():
                self._reap(rows)
                calm &= ~bad
            if not calm.any():
                return
        over = calm & (self.steps[rows] >= self.max_steps)
        if over.any():
            orow, ot = rows[over], b[over]
            self.log.append(orow, ot, j[over], yb[over], K[self.ns][over])
            self._stop(orow, Termination.MAX_STEPS, "steps", steps=self.max_steps,
                       max_steps=self.max_steps, t=ot)
            calm &= ~over
            if not calm.any():
                return
        rows, b, yb, j = rows[calm], b[calm], yb[calm], j[calm]
        fb = K[self.ns][calm]
        if self.hist is not None or self.refine > 1 or self.watching:
            # the steps' dense output
            Qc = self._dense_of(rows, a[calm], ya[calm], h[calm], yb, K[:, calm], j)
            if self.hist is not None:
                self.hist._add(rows, a[calm], b, j, h[calm], ya[calm], Qc)
            if self.refine > 1:
                self._refine(rows, a[calm], b, ya[calm], h[calm], Qc, j)
            if self.watching:
                self._watch_to(rows, a[calm], ya[calm], h[calm], Qc, b, yb, j)
                bad = self.bad[rows]
                if bad.any():           # watch failed on these rows: they end MAP_ERROR
                    self._reap(rows)
                    calm = calm.copy()
                    calm[np.flatnonzero(calm)[bad]] = False
                    rows, b, yb, j, fb = rows[~bad], b[~bad], yb[~bad], j[~bad], fb[~bad]
        self.t[rows] = b
        self.x[rows] = yb
        self.fx[rows] = fb
        if inDb is not None:
            self.inD_prev[rows] = inDb[calm]
        self.log.append(rows, b, j, yb, fb)
        if self.max_norm < math.inf:
            nrm = np.linalg.norm(yb, axis=1)
            big = nrm > self.max_norm
            if big.any():
                self._stop(rows[big], Termination.BLOWUP, norm=nrm[big],
                           max_norm=self.max_norm, t=b[big], j=j[big])
        end = b >= self.t_max
        if end.any():
            er = rows[end]
            self.decide[er] = True           # jumps at t_max are still taken
            self.h[er] = np.nan

    # ------------------------------------------------------------ events
    def _refine(self, rows, a, b, ya, h, Q, j):
        """Store ``refine - 1`` dense-output samples strictly inside each (a, b),
        with the dense output's derivative as their ``xdot`` (as simulate: RK45's;
        NaN for DOP853, whose dense output simulate does not differentiate)."""
        R = self.refine
        for k in range(1, R):
            s = a + (b - a) * (k / R)
            xx = (s - a) / h
            if Q.shape[2] == 4:
                p = np.stack([np.ones_like(xx), xx, xx * xx, xx ** 3], axis=1) * _DP
                xd = np.einsum("knp,kp->kn", Q, p)
            else:
                xd = None
            self.log.append(rows, s, j, self._dense(a, h, ya, Q, s), xd)

    def _dense_of(self, rows, a, ya, h, yb, K, j):
        """The dense output of the accepted steps a -> a + h of ``rows`` (``K``:
        their stages): RK45's Q = K^T P, (k, n, 4); DOP853's F, (k, n, 7),
        scipy's ``DOP853._dense_output_impl`` (its three more stages
        evaluated here)."""
        if not self.dop:
            return np.einsum("skn,sp->knp", K, _P)
        d, ns, k = self.dop, self.ns, len(rows)
        hc = h[:, None]
        KX = np.empty((ns + 4, k, self.n))
        KX[:ns + 1] = K
        with np.errstate(invalid="ignore", over="ignore"):
            for s in range(ns + 1, ns + 4):
                dy = np.tensordot(d["AX"][s, :s], KX[:s], axes=(0, 0)) * hc
                KX[s] = self.maps.flow(rows, ya + dy, a + d["CX"][s] * h, j)
            self.nfev[rows] += 3
            dyb = yb - ya
            F = np.empty((k, self.n, 7))
            F[:, :, 0] = dyb
            F[:, :, 1] = hc * K[0] - dyb
            F[:, :, 2] = 2 * dyb - hc * (K[ns] + K[0])
            F[:, :, 3:] = hc[:, :, None] * np.einsum("ps,skn->knp", d["D"], KX)
        return F

    def _dense(self, a, h, ya, Q, s):
        """Each row's dense output at its time s, by the form of ``Q``: RK45's
        (scipy's RkDenseOutput, Q = K^T P), DOP853's (its Dop853DenseOutput, F)
        or the cubic Hermite of the step's ends (the end state, h f at both
        ends: ``solve._Hermite``)."""
        xx = (s - a) / h
        with np.errstate(invalid="ignore", over="ignore"):
            if Q.shape[2] == 4:
                p = np.stack([xx, xx * xx, xx ** 3, xx ** 4], axis=1)
                return ya + h[:, None] * np.einsum("knp,kp->kn", Q, p)
            x = xx[:, None]
            if Q.shape[2] == 7:
                y = np.zeros_like(ya)
                for i in range(7):
                    y = (y + Q[:, :, 6 - i]) * (x if i % 2 == 0 else 1 - x)
                return y + ya
            x2 = x * x
            return (ya + x2 * (3.0 - 2.0 * x) * (Q[:, :, 0] - ya) + x * (1.0 - x) ** 2 * Q[:, :, 1]
                    + x2 * (x - 1.0) * Q[:, :, 2])

    def _pred(self, rows, y, s, j, wd):
        """The event has happened: x left C, or entered D (rows with ``wd``)."""
        m = self.maps
        self._finite(rows, y)
        ev = np.zeros(len(rows), dtype=bool)
        if m.has_C:
            ev |= ~m.in_C(rows, y, s, j)
        if self.watch_D and wd.any():
            ev |= wd & m.in_D(rows, y, s, j)
        return ev

    def _pred_phi(self, rows, y, s, j, wd):
        """:meth:`_pred` and :meth:`_phi` at once: from one evaluation of each guard
        where the sets are the guards' (``shared``), else each on its own."""
        if not self.shared:
            return self._pred(rows, y, s, j, wd), self._phi(rows, y, s, j, wd)
        m = self.maps
        self._finite(rows, y)
        ev = np.zeros(len(rows), dtype=bool)
        v = np.full(len(rows), -np.inf)
        if self.watch_D and wd.any():
            gD = m.guard_D(rows, y, s, j)
            ev |= wd & (gD >= 0.0)
            v = np.where(wd, gD, -np.inf)
        if m.has_C:
            gC = m.guard_C(rows, y, s, j)
            ev |= ~(gC >= 0.0)
            v = np.maximum(v, -gC)
        return ev, v

    def _phi(self, rows, y, s, j, wd):
        """Continuous version of :meth:`_pred` (>= 0 where the event has happened)."""
        m = self.maps
        self._finite(rows, y)               # a non-finite probe is NON_FINITE, not a guard's NaN
        v = np.full(len(rows), -np.inf)
        if self.watch_D and m.hD is not None and wd.any():
            v = np.where(wd, m.guard_D(rows, y, s, j), -np.inf)
        if m.has_C and m.hC is not None:
            v = np.maximum(v, -m.guard_C(rows, y, s, j))
        return v

    def _locate(self, rows, a, h, ya, Q, j, wd, lo, hi, ylo=None, yhi=None):
        """Bracket the first event in (lo, hi] of each row on its dense output.

        :func:`hybridsim.events.locate_event` run over the rows: the same
        phases, tests and tolerance (:func:`hybridsim.rules.event_tolerance`)
        for each row, so each row's bracket is the one ``locate_event``
        returns on the same dense output, to rounding of the batched
        interpolant. With a guard: a start on the guard's zero is probed and
        seeded by the quadratic model (``events._root_off_zero``); the
        indicator bisects until the guard changes sign; safeguarded secant
        steps (``events._secant``: Brent's test, else bisection) shrink the
        guard's bracket, which the indicator confirms; a final bisection of
        the indicator closes any bracket left. ``ylo``, ``yhi``: the states
        at lo and hi where the caller has them (the step's ends).

        Returns
        -------
        lo, hi : ndarray, shape (k,)
        ylo, yhi : ndarray, shape (k, n)
        """
        k = len(rows)
        lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
        ylo = self._dense(a, h, ya, Q, lo) if ylo is None else np.array(ylo)
        yhi = self._dense(a, h, ya, Q, hi) if yhi is None else np.array(yhi)
        bad = self.bad

        def ev(i, s):
            return self._dense(a[i], h[i], ya[i], Q[i], s)

        def pred(i, s, y):
            return self._pred(rows[i], y, s, j[i], wd[i])

        def phi(i, s, y):
            return self._phi(rows[i], y, s, j[i], wd[i])

        def bisect(cond):
            # locate_event's bisection of the indicator while cond(lo, hi) holds
            for _ in range(_MAX_ITER):
                i = np.flatnonzero(cond() & (hi - lo > _tol(lo, hi)) & ~bad[rows])
                if not i.size:
                    break
                s = 0.5 * (lo[i] + hi[i])
                ys = ev(i, s)
                hit = pred(i, s, ys)
                if use_phi:
                    fs = phi(i, s, ys)
                    fhi[i[hit]], flo[i[~hit]] = fs[hit], fs[~hit]
                hi[i[hit]], yhi[i[hit]] = s[hit], ys[hit]
                lo[i[~hit]], ylo[i[~hit]] = s[~hit], ys[~hit]

        use_phi = self.use_phi
        if use_phi:
            every = np.arange(k)
            flo, fhi = phi(every, lo, ylo), phi(every, hi, yhi)
            seed_s, seed_m = np.full(k, np.nan), np.full(k, np.nan)
            # on the guard's zero at the start: one probe gives the direction,
            # and with the end value a first estimate of the root
            i = np.flatnonzero(~(flo < 0.0) & (fhi >= 0.0) & ~bad[rows])
            if i.size:
                d = np.maximum(64.0 * _tol(lo[i], hi[i]), 1e-9 * (hi[i] - lo[i]))
                ok = lo[i] + d < hi[i]
                i, d = i[ok], d[ok]
            if i.size:
                sd = lo[i] + d
                yd = ev(i, sd)
                fd = phi(i, sd, yd)
                neg = fd < 0.0
                off = np.zeros(len(i), dtype=bool)
                if neg.any():
                    off[neg] = ~pred(i[neg], sd[neg], yd[neg])
                i, d, sd, yd, fd = i[off], d[off], sd[off], yd[off], fd[off]
                if i.size:
                    tau, slope = _root_off_zero(flo[i], fd, fhi[i], d, hi[i] - lo[i])
                    seed_s[i], seed_m[i] = lo[i] + tau, slope
                    lo[i], ylo[i], flo[i] = sd, yd, fd
            # bisect by the indicator until the guard changes sign in the bracket
            bisect(lambda: ~((flo < 0.0) & (0.0 <= fhi)))
            i = np.flatnonzero((flo < 0.0) & (0.0 <= fhi) & (hi - lo > _tol(lo, hi))
                               & ~bad[rows])
            if i.size:
                l2, h2, yl2, yh2 = self._secant(rows, i, lo[i], hi[i], flo[i], fhi[i],
                                                ylo[i], yhi[i], seed_s[i], seed_m[i], ev, phi)
                # the indicator decides membership: keep the guard's bracket where
                # it agrees (the indicator is asked at lo only where it disagrees at hi)
                agree = pred(i, h2, yh2)
                ia = i[agree]
                hi[ia], yhi[ia], lo[ia], ylo[ia] = h2[agree], yh2[agree], l2[agree], yl2[agree]
                rest = ~agree
                if rest.any():
                    out = ~pred(i[rest], l2[rest], yl2[rest])
                    ib = i[rest][out]
                    lo[ib], ylo[ib] = l2[rest][out], yl2[rest][out]
        # bisection of the indicator (also finishes any bracket the guard left)
        bisect(lambda: True)
        return lo, hi, ylo, yhi

    def _secant(self, rows, idx, lo, hi, flo, fhi, ylo, yhi, seed_s, seed_m, ev, phi):
        """:func:`hybridsim.events._secant` over the rows ``idx`` of a
        :meth:`_locate`: each row's trial is its secant step from its last
        evaluation, accepted inside the bracket and shorter than half its
        step before last (Brent's test), else the midpoint; a seed (not NaN)
        is the first trial and gives the slope after it; trials are kept a
        quarter tolerance inside the bracket."""
        n = len(idx)
        d1, d2 = np.full(n, np.inf), np.full(n, np.inf)
        first = -flo < fhi
        xl, fl = np.where(first, lo, hi), np.where(first, flo, fhi)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            slope = (fhi - flo) / (hi - lo)
        has_seed = ~np.isnan(seed_s)
        bad = self.bad
        for _ in range(_SECANT_ITER):
            tol = _tol(lo, hi)
            act = np.flatnonzero((hi - lo > tol) & ~bad[rows[idx]])
            if not act.size:
                break
            L, H, X, FL, tl = lo[act], hi[act], xl[act], fl[act], tol[act]
            sd = has_seed[act]
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                sl = slope[act]
                s = np.where(sl != 0.0, X - FL / sl, np.nan)
            ok = (L <= s) & (s <= H) & (np.abs(s - X) < 0.5 * d2[act])
            s = np.where(ok, s, 0.5 * (L + H))
            s = np.where(sd, seed_s[act], s)
            q = 0.25 * tl
            s = np.where(~(s > L + q), L + q, np.where(~(s < H - q), H - q, s))
            ii = idx[act]
            ys = ev(ii, s)
            fs = phi(ii, s, ys)
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                ns = np.where(s != X, (fs - FL) / (s - X), np.nan)
            slope[act] = np.where(sd, seed_m[act], ns)
            has_seed[act] = False
            d2[act] = d1[act]
            d1[act] = np.abs(s - X)
            xl[act], fl[act] = s, fs
            up = fs >= 0.0
            au, ad = act[up], act[~up]
            hi[au], yhi[au], fhi[au] = s[up], ys[up], fs[up]
            lo[ad], ylo[ad], flo[ad] = s[~up], ys[~up], fs[~up]
        return lo, hi, ylo, yhi

    def _interior(self, rows, a, b, ya, h, Q, j):
        """The batch version of :func:`hybridsim.events.find_interior_event`.

        Three interior samples of each step's dense output, the indicators
        tested there; with guards, every sampled local maximum of the guard
        (the step's start included where the guard rises there, and its end
        where it falls there; the probe deciding that over the rows at once)
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
            if self.use_phi:
                ev, v = self._pred_phi(rows, ys, s, j, wd)
                vals.append(v)
            else:
                ev = self._pred(rows, ys, s, j, wd)
            hit = ~found & ev
            lo_b[hit], hi_b[hit] = prev[hit], s[hit]
            found |= hit
            prev = s
            pts.append(s)
        found &= ~self.bad[rows]
        if not self.use_phi or found.all():
            return lo_b, hi_b, found
        pts.append(b)
        vals.append(self._phi(rows, self._dense(a, h, ya, Q, b), b, j, wd))
        V, T = np.array(vals), np.array(pts)           # (5, k)
        fin = np.isfinite(V).all(axis=0)

        def refine(i, l, r, fl, fr):
            # events._maximize on row i's dense output (row by row: peaks are rare)
            ri, wi, ji = rows[i:i + 1], wd[i:i + 1], j[i:i + 1]

            def sol(s):
                return self._dense(a[i:i + 1], h[i:i + 1], ya[i:i + 1], Q[i:i + 1],
                                   np.array([s]))[0]

            def F(s, y):
                return float(self._phi(ri, y[None, :], np.array([s]), ji, wi)[0])

            def pred(s, y):
                return bool(self._pred(ri, y[None, :], np.array([s]), ji, wi)[0])
            sq = _maximize(F, l, r, fl, fr, pred, sol)
            if sq is not None and not self.bad[rows[i]]:
                found[i] = True
                lo_b[i], hi_b[i] = l, sq

        for q in (1, 2, 3):
            lo_nb = np.minimum(V[q - 1], V[q + 1])
            cand = (~found & fin & (V[q] >= V[q - 1]) & (V[q] >= V[q + 1])
                    & _near_peak(V[q], lo_nb) & ~self.bad[rows])
            for i in np.flatnonzero(cand):
                refine(i, T[q - 1, i], T[q + 1, i], V[q - 1, i], V[q + 1, i])
        # a peak between a and the first sample (only where the guard rises at
        # a), then between the last sample and b (only where it falls at b: the
        # next step starts falling, so its own search never looks back)
        for e, nb, sign in ((0, 1, 1.0), (4, 3, -1.0)):
            cand = (~found & fin & (V[e] >= V[nb]) & _near_peak(V[e], V[nb])
                    & ~self.bad[rows])
            if not cand.any():
                continue
            c = np.flatnonzero(cand)
            # one probe a thousandth of the way in, over the rows at once
            s = T[e, c] + sign * (1e-3 * np.abs(T[nb, c] - T[e, c]))
            ys = self._dense(a[c], h[c], ya[c], Q[c], s)
            rise = (self._phi(rows[c], ys, s, j[c], wd[c]) > V[e, c]) & ~self.bad[rows[c]]
            l, r = (0, 1) if e == 0 else (3, 4)
            for i in c[rise]:
                refine(i, T[l, i], T[r, i], V[l, i], V[r, i])
        return lo_b, hi_b, found

    def _event(self, rows, a, lo, hi, ya, h, Q, j, ylo=None, yhi=None, clamp=None):
        """Locate the first event in (lo, hi] of the steps from a of ``rows`` and
        decide there (:func:`hybridsim.rules.event_outcome`); ``clamp``: record
        event times no later than it (an event within round-off after t_max is
        taken at t_max)."""
        m = self.maps
        self.events[rows] += 1
        # a flow that started in D (random priority flowing on) watches only C
        wd = ~self.inD_prev[rows]
        lo, hi, ylo, yhi = self._locate(rows, a, h, ya, Q, j, wd, lo, hi, ylo, yhi)
        ok = self._reap(rows)
        if ok is not None:
            rows, a, ya, h, Q, lo, hi, ylo, yhi, j, wd = (
                rows[ok], a[ok], ya[ok], h[ok], Q[ok], lo[ok], hi[ok], ylo[ok], yhi[ok],
                j[ok], wd[ok])
            if not rows.size:
                return
        # next flow's first step (as simulate): at most 10x the length of this
        # flow; the controller's proposal after an overshooting step can be
        # huge where the flow is integrated exactly, and long steps cancel digits
        self.h[rows] = np.minimum(self.h[rows], _MAX_FACTOR * (hi - self.t_flow0[rows]))
        k = len(rows)
        false = np.zeros(k, dtype=bool)
        watching = wd if self.watch_D else false
        d_hi = m.in_D(rows, yhi, hi, j) if m.has_D else false
        entry = watching & d_hi
        c_hi = false.copy()                  # C at hi matters only for the coin
        if self.prio == Priority.RANDOM and entry.any():
            c_hi[entry] = m.in_C(rows[entry], yhi[entry], hi[entry], j[entry])
        coin = np.ones(k, dtype=bool)
        ask = needs_coin(c_hi, entry, self.prio)
        if ask.any():
            coin[ask] = self.rng.random(int(ask.sum())) < 0.5
        d_lo = false.copy()
        if m.has_D and not entry.all():
            e = ~entry
            d_lo[e] = m.in_D(rows[e], ylo[e], lo[e], j[e])
        ok = self._reap(rows)
        code = (watching.astype(np.intp) << 4) | (d_hi << 3) | (c_hi << 2) | (d_lo << 1) | coin
        action, at_hi = self.ev_action[code], self.ev_side[code] == 1
        if ok is not None:
            rows, a, ya, h, Q, lo, hi, ylo, yhi, j, action, at_hi = (
                rows[ok], a[ok], ya[ok], h[ok], Q[ok], lo[ok], hi[ok], ylo[ok], yhi[ok],
                j[ok], action[ok], at_hi[ok])
        ts = np.where(at_hi, hi, lo)
        if clamp is not None:
            ts = np.minimum(ts, clamp)
        xs = np.where(at_hi[:, None], yhi, ylo)
        sample = ts > a
        if self.watching and sample.any():
            sr = np.flatnonzero(sample)
            self._watch_to(rows[sr], a[sr], ya[sr], h[sr], Q[sr], ts[sr], xs[sr], j[sr])
            ok = self._reap(rows)
            if ok is not None:
                rows, a, ya, h, Q, lo, hi, ylo, yhi, j, action, at_hi, ts, xs, sample = (
                    rows[ok], a[ok], ya[ok], h[ok], Q[ok], lo[ok], hi[ok], ylo[ok], yhi[ok],
                    j[ok], action[ok], at_hi[ok], ts[ok], xs[ok], sample[ok])
                if not rows.size:
                    return
        if sample.any():
            if self.hist is not None:       # the step up to the event
                self.hist._add(rows[sample], a[sample], ts[sample], j[sample], h[sample],
                               ya[sample], Q[sample])
            if self.refine > 1:
                self._refine(rows[sample], a[sample], ts[sample], ya[sample], h[sample],
                             Q[sample], j[sample])
            self.log.append(rows[sample], ts[sample], j[sample], xs[sample],
                            m.flow_soft(xs[sample], ts[sample], j[sample], rows[sample]))
        self.t[rows] = ts
        self.x[rows] = xs
        if self.max_norm < math.inf and sample.any():   # the event's sample, as a step's end
            nrm = np.linalg.norm(xs, axis=1)
            big = sample & (nrm > self.max_norm)
            if big.any():
                self._stop(rows[big], Termination.BLOWUP, norm=nrm[big],
                           max_norm=self.max_norm, t=ts[big], j=j[big])
                keep = ~big
                rows, ts, xs, j, action, at_hi, lo, ylo, yhi = (
                    rows[keep], ts[keep], xs[keep], j[keep], action[keep], at_hi[keep],
                    lo[keep], ylo[keep], yhi[keep])
        jump = action == Action.JUMP
        if jump.any():
            self.force[rows[jump]] = True
            self.decide[rows[jump]] = True
            # jumping from hi: the bracket, for rules.post_jump_probe after the jump
            self.pend[rows[jump]] = at_hi[jump]
            jh = jump & at_hi
            if jh.any():
                rh = rows[jh]
                self.pend_lo[rh], self.pend_xlo[rh], self.pend_xhi[rh] = lo[jh], ylo[jh], yhi[jh]
        cont = action == Action.FLOW
        done = cont & (ts >= self.t_max)     # flowing on at t_max: the run ends there
        if done.any():
            self._stop(rows[done], Termination.T_MAX)
            cont &= ~done
        if cont.any():                       # random priority chose to flow on in C ∩ D
            self._start_flow(rows[cont], np.ones(int(cont.sum()), dtype=bool))
        left = action == Action.STOP
        if left.any():
            self._stop_outside(rows[left], xs[left], ts[left], j[left], "left")
