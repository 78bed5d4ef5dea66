"""simulate(): the flow/jump loop with exact event location."""
from __future__ import annotations

import bisect
import math
import numbers
import sys

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, OdeSolver, Radau

from .arc import HybridArc, Termination
from .events import locate_event
from .history import History
from .system import HybridSystem, guard_min

__all__ = ["simulate", "MapError", "SimulationError"]

METHODS = {"RK23": RK23, "RK45": RK45, "DOP853": DOP853, "Radau": Radau,
           "BDF": BDF, "LSODA": LSODA}
PRIORITIES = ("jumps", "flows", "random")
_JUMPS, _FLOWS, _RANDOM = 0, 1, 2


class MapError(ValueError):
    """A user map returned something the engine cannot use (wrong shape...)."""


class SimulationError(RuntimeError):
    """Raised by ``simulate(..., throw=True)`` when a run stops on a failure.

    ``.arc`` holds the solution computed up to the failure.
    """

    def __init__(self, message, arc):
        super().__init__(message)
        self.arc = arc


class _Buffer:
    """Growable (t, j, x) sample store: amortised O(1) appends, no quadratic copies."""

    __slots__ = ("t", "j", "x", "n")

    def __init__(self, dim, cap=256):
        self.t = np.empty(cap)
        self.j = np.empty(cap, dtype=np.int64)
        self.x = np.empty((cap, dim))
        self.n = 0

    def append(self, t, j, x):
        k = self.n
        if k == len(self.t):
            for name in ("t", "j", "x"):
                old = getattr(self, name)
                new = np.empty((2 * k,) + old.shape[1:], dtype=old.dtype)
                new[:k] = old
                setattr(self, name, new)
        self.t[k] = t
        self.j[k] = j
        self.x[k] = x
        self.n = k + 1

    def arrays(self):
        """The samples, shrunk in place (no copy); the buffer is done after this."""
        k = self.n
        self.t.resize(k, refcheck=False)
        self.j.resize(k, refcheck=False)
        self.x.resize((k, self.x.shape[1]), refcheck=False)
        return self.t, self.j, self.x


def _check_x0(x0, n):
    try:
        x = np.array(x0, dtype=float)
    except (TypeError, ValueError) as e:
        raise TypeError(f"x0 must be an array of {n} floats, got {type(x0).__name__}") from e
    if x.ndim == 0 and n == 1:
        x = x.reshape(1)
    if x.shape != (n,):
        raise ValueError(f"x0 must have shape ({n},) (the system's state_dim), got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"x0 must be finite, got {x}")
    return x


def _check_real(name, v, *, allow_inf=False, positive=False, nonneg=False):
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(v).__name__}")
    v = float(v)
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise ValueError(f"{name} must be finite, got {v}")
    if positive and not v > 0:
        raise ValueError(f"{name} must be > 0, got {v}")
    if nonneg and v < 0:
        raise ValueError(f"{name} must be >= 0, got {v}")
    return v


def _check_map_value(name, val, n):
    arr = np.asarray(val, dtype=float)
    if arr.shape != (n,):
        raise MapError(f"{name} must return an array of shape ({n},), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise MapError(f"{name} returned non-finite values {arr}")
    return arr


def _resolve_method(method):
    if isinstance(method, str):
        if method not in METHODS:
            raise ValueError(f"method must be one of {sorted(METHODS)} or an OdeSolver "
                             f"subclass, got {method!r}")
        return METHODS[method]
    if isinstance(method, type) and issubclass(method, OdeSolver):
        return method
    raise TypeError(f"method must be a string or an OdeSolver subclass, got {method!r}")


def _progress_bar(progress, t0, t_max, j_max):
    if progress is None:
        progress = bool(getattr(sys.stderr, "isatty", lambda: False)())
    if not progress:
        return None
    from tqdm.auto import tqdm
    if math.isfinite(t_max):
        return tqdm(total=t_max - t0, unit="t", desc="simulate", leave=False,
                    bar_format="{l_bar}{bar}| t={n:.4g}/{total:.4g} [{elapsed}<{remaining}]")
    return tqdm(total=None if not math.isfinite(j_max) else j_max, unit="jump",
                desc="simulate", leave=False)


def check_options(system, n, t0, t_max, j_max, priority, rtol, atol, max_step,
                  first_step, max_norm, zeno_time):
    """Validate the options shared by :func:`simulate` and the batch integrator.

    Returns them normalised: ``(t0, t_max, j_max, prio, rtol, atol, max_step,
    first_step, max_norm, zeno_time)`` with ``prio`` an index into PRIORITIES
    and ``max_step`` capped by ``system.max_step``.
    """
    t0 = _check_real("t0", t0)
    t_max = _check_real("t_max", t_max, allow_inf=True)
    if t_max < t0:
        raise ValueError(f"t_max must be >= t0 = {t0}, got {t_max}")
    if isinstance(j_max, bool) or not isinstance(j_max, numbers.Real) or (
            isinstance(j_max, float) and not (math.isinf(j_max) or j_max.is_integer())):
        raise TypeError(f"j_max must be a non-negative int (or inf), got {j_max!r}")
    if j_max < 0:
        raise ValueError(f"j_max must be >= 0, got {j_max}")
    if priority not in PRIORITIES:
        raise ValueError(f"priority must be one of {PRIORITIES}, got {priority!r}")
    prio = PRIORITIES.index(priority)
    rtol = _check_real("rtol", rtol, positive=True)
    if np.ndim(atol) == 0:
        atol = _check_real("atol", atol, positive=True)
    else:
        atol = np.asarray(atol, dtype=float)
        if atol.shape != (n,) or not np.all(atol > 0):
            raise ValueError(f"atol must be a positive float or an array of shape ({n},) "
                             f"of positive floats, got {atol!r}")
    max_step = _check_real("max_step", max_step, allow_inf=True, positive=True)
    if system.max_step is not None:
        max_step = min(max_step, _check_real("system.max_step", system.max_step, positive=True))
    if first_step is not None:
        first_step = _check_real("first_step", first_step, positive=True)
    max_norm = _check_real("max_norm", max_norm, allow_inf=True, positive=True)
    zeno_time = _check_real("zeno_time", zeno_time, nonneg=True)
    return (t0, t_max, j_max, prio, rtol, atol, max_step, first_step, max_norm, zeno_time)


def simulate(system, x0, t_max, j_max=math.inf, *, t0=0.0, j0=0, priority="jumps",
             method="RK45", rtol=1e-6, atol=1e-9, max_step=math.inf, first_step=None,
             inputs=None, prehistory=None, max_norm=math.inf, seed=None,
             progress=None, throw=False, dense=False, refine=1, zeno_jumps=50,
             zeno_time=1e-12):
    r"""Simulate a hybrid system from x0 until t_max or j_max.

    Flows by :math:`\dot x = f(x)` with a scipy ODE solver while x is in C,
    jumps by :math:`x^+ = g(x)` when x is in D (as the priority decides).
    Events are located on each step's dense output to near machine
    precision: by a safeguarded Illinois root search on the guards where the
    system has them, else by bisection of the set indicators.

    Parameters
    ----------
    system : HybridSystem
        The data (C, f, D, g).
    x0 : array_like, shape (n,)
        Initial state.
    t_max : float
        Flows stop at t_max; a run that flows up to t_max ends with a sample
        there (jumps at t = t_max are still taken). May be ``inf``.
    j_max : int or inf, optional
        At most this many jumps; the run stops at the sample after the last.
    t0, j0 : float, int, optional
        Initial hybrid time.
    priority : {"jumps", "flows", "random"}
        What happens in C ∩ D. ``"jumps"``: jump as soon as x is in D.
        ``"flows"``: jump only when x is in D and flowing is impossible (x not
        in C, or on the edge of C where the flow leaves C at once).
        ``"random"``: a fair coin (seeded by ``seed``) at each such point.
    method : str or OdeSolver subclass
        "RK45" (default), "RK23", "DOP853", "Radau", "BDF", "LSODA" or a
        subclass of :class:`scipy.integrate.OdeSolver`.
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
        Show a progress bar (tqdm). None: only at a terminal.
    throw : bool
        Raise :class:`SimulationError` (with ``.arc``) when the run stops on a
        failure (user-map exception, non-finite state, solver failure)
        instead of returning the arc with that cause.
    refine : int
        Samples stored per solver step (as MATLAB's ``Refine``): ``refine - 1``
        points of the step's dense output are added inside each step. Use
        4-10 for smooth plots; 1 (default) stores the step ends only.
    dense : bool
        Keep every step's dense output, so ``arc.at(t, j)`` is exact to the
        integrator and the history is available after the run.
    zeno_jumps, zeno_time : int, float
        The run stops with cause ``ZENO`` after ``zeno_jumps`` consecutive
        jumps each preceded by a flow shorter than
        ``zeno_time * max(1, |t|)``.

    Returns
    -------
    HybridArc
        The solution; ``arc.termination`` says why it stopped.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> timer = hs.HybridSystem.from_functions(
    ...     f=lambda x: np.array([1.0]), g=lambda x: np.array([0.0]),
    ...     jump_guard=lambda x: x[0] - 1.0, flow_guard=lambda x: 1.0 - x[0],
    ...     state_dim=1)
    >>> arc = hs.simulate(timer, [0.0], t_max=3.5)
    >>> np.round(arc.jump_times, 12)
    array([1., 2., 3.])
    """
    if not isinstance(system, HybridSystem):
        raise TypeError(f"system must be a hybridsim.HybridSystem, got {type(system).__name__}")
    maps = system._compile()
    n = int(system.state_dim)
    x = _check_x0(x0, n)
    (t0, t_max, j_max, prio, rtol, atol, max_step, first_step, max_norm,
     zeno_time) = check_options(system, n, t0, t_max, j_max, priority, rtol, atol, max_step,
                                first_step, max_norm, zeno_time)
    Method = _resolve_method(method)
    if int(system.input_dim or 0) > 0 and inputs is None:
        raise ValueError(f"inputs: the system has input_dim={system.input_dim}; pass "
                         "inputs=callable(t) -> u, or connect it with hs.connect")
    if inputs is not None and not callable(inputs):
        raise TypeError(f"inputs must be a callable u(t), got {type(inputs).__name__}")
    if prehistory is not None and not callable(prehistory):
        raise TypeError(f"prehistory must be a callable x(s), got {type(prehistory).__name__}")
    if isinstance(refine, bool) or not isinstance(refine, numbers.Integral) or refine < 1:
        raise ValueError(f"refine must be an int >= 1, got {refine!r}")
    if isinstance(zeno_jumps, bool) or not isinstance(zeno_jumps, numbers.Integral) \
            or zeno_jumps < 1:
        raise ValueError(f"zeno_jumps must be a positive int, got {zeno_jumps!r}")
    rng = np.random.default_rng(seed)

    delays = tuple(float(d) for d in (system.delays or ()))
    if any(not (math.isfinite(d) and d > 0) for d in delays):
        raise ValueError(f"system.delays must be positive finite floats, got {system.delays!r}")
    keep = dense or system.needs_history
    history = History(t0, x, j0, prehistory, inputs, maps.h)
    system._bind_history(history)

    run = _Run(system, maps, n, t_max, j_max, prio, Method, rtol, atol, max_step,
               first_step, inputs, max_norm, rng, keep, history, zeno_jumps, zeno_time,
               int(refine))
    run.delays = delays
    run.breaks = sorted(t0 + d for d in delays)
    run.pbar = _progress_bar(progress, t0, t_max, j_max)
    try:
        run.run(t0, int(j0), x)
    finally:
        if run.pbar is not None:
            run.pbar.close()
    t, j, X = run.buf.arrays()
    arc = HybridArc(t, j, X, run.cause, run.message, run.exception,
                    components=system.components, segments=history.segments if keep else None,
                    system=system)
    if throw and run.cause in (Termination.MAP_ERROR, Termination.NON_FINITE,
                               Termination.SOLVER_FAILED):
        err = SimulationError(arc.message, arc)
        raise err from run.exception
    return arc


class _Run:
    """State of one run (kept out of simulate() to keep the hot loop readable)."""

    def __init__(self, system, maps, n, t_max, j_max, prio, Method, rtol, atol,
                 max_step, first_step, ufun, max_norm, rng, keep, history,
                 zeno_jumps, zeno_time, refine):
        self.__dict__.update(locals())
        del self.__dict__["self"]
        self.buf = _Buffer(n)
        self.cause = None
        self.message = None
        self.exception = None
        self.h_hint = first_step
        self.pbar = None
        # events: watch D entries unless flows have priority
        self.watch_D = maps.has_D and prio != _FLOWS
        phi_ok = ((not self.watch_D or maps.hD is not None)
                  and (not maps.has_C or maps.hC is not None))
        self.use_phi = phi_ok and (maps.hD is not None or maps.hC is not None)

    def _stop(self, cause, message=None, exc=None):
        self.cause = cause
        self.message = cause.message if message is None else f"{cause.message}: {message}"
        self.exception = exc

    # ------------------------------------------------------------------
    def run(self, t, j, x):
        maps, ufun, prio = self.maps, self.ufun, self.prio
        C, D, g = maps.C, maps.D, maps.g
        has_C, has_D = maps.has_C, maps.has_D
        buf = self.buf
        buf.append(t, j, x)
        jumps = 0
        short = 0
        t_last = t
        first = True
        force_jump = False
        keep_flowing = False
        try:
            while True:
                if keep_flowing:     # random priority chose to flow on in C ∩ D
                    inD = True
                    if t >= self.t_max:
                        self._stop(Termination.T_MAX)
                        return
                else:
                    u = ufun(t) if ufun is not None else None
                    inD = has_D and bool(D(x, t, j, u))
                    inC = (not has_C) or bool(C(x, t, j, u))
                    if first:
                        self._validate(x, t, j, u, inC, inD)
                        first = False
                    if inD and (force_jump or not inC or prio == _JUMPS or
                                (prio == _RANDOM and self.rng.random() < 0.5)):
                        force_jump = False
                        if jumps >= self.j_max:
                            self._stop(Termination.J_MAX)
                            return
                        xn = _check_map_value("jump_map", g(x, t, j, u), self.n)
                        # Zeno: consecutive jumps after flows too short to resolve
                        tiny = (t - t_last) <= self.zeno_time * max(1.0, abs(t))
                        short = short + 1 if tiny else 0
                        t_last = t
                        j += 1
                        jumps += 1
                        x = xn
                        buf.append(t, j, x)
                        self.history._restart(t, x, j)
                        if self.delays:
                            self._add_breaks(t)
                        if self.pbar is not None and not math.isfinite(self.t_max):
                            self.pbar.update(1)
                        if jumps >= self.j_max:
                            self._stop(Termination.J_MAX)
                            return
                        if short >= self.zeno_jumps:
                            self._stop(Termination.ZENO, f"{short} consecutive jumps near t={t}")
                            return
                        continue
                    force_jump = False
                    if not inC:
                        cause = Termination.NOT_IN_SETS if buf.n == 1 else Termination.LEFT_SETS
                        self._stop(cause, f"x={x} at (t={t}, j={j})")
                        return
                    if t >= self.t_max:
                        self._stop(Termination.T_MAX)
                        return
                keep_flowing = False
                kind, t, x = self._flow(t, j, x, inD)
                if kind == "jump":
                    force_jump = True
                elif kind == "continue":
                    keep_flowing = True
                elif kind == "stop":
                    if self.cause is Termination.SOLVER_FAILED and short > 0:
                        self._stop(Termination.ZENO, f"flows too short to resolve near t={t}")
                    return
        except (KeyboardInterrupt, SystemExit):
            raise
        except Exception as e:  # noqa: BLE001 - any user-map failure ends the run with a cause
            if first:       # at x0: a programming error, raised at once
                raise
            self._stop(Termination.MAP_ERROR, f"{type(e).__name__}: {e}", e)

    def _add_breaks(self, t):
        for d in self.delays:
            bisect.insort(self.breaks, t + d)

    def _bound(self, t):
        """End of the flow's integration: t_max, or the next delay breakpoint."""
        br = self.breaks
        tol = 4 * np.finfo(float).eps * max(1.0, abs(t))
        while br and br[0] <= t + tol:
            br.pop(0)
        return min(br[0], self.t_max) if br else self.t_max

    def _validate(self, x, t, j, u, inC, inD):
        """Check the maps' shapes at x0 (a clear error before anything runs)."""
        if inC:
            _check_map_value("flow_map", self.maps.f(x, t, j, u), self.n)
        if inD:
            _check_map_value("jump_map", self.maps.g(x, t, j, u), self.n)

    # ------------------------------------------------------------------
    def _flow(self, t, j, x, inD_start):
        """Integrate from (t, x) until an event, t_max or a failure.

        Returns (kind, t, x) with kind "tmax" (reached t_max), "break" (a delay
        breakpoint: flow on), "jump" (jump from x), "continue" (random priority
        flows on in C ∩ D) or "stop" (the run ends; the cause is recorded).
        """
        maps, ufun = self.maps, self.ufun
        f, C, D = maps.f, maps.C, maps.D
        has_C, watch_D = maps.has_C, self.watch_D
        buf, hist, keep, pbar = self.buf, self.history, self.keep, self.pbar
        if ufun is None:
            def fun(s, y):
                return f(y, s, j, None)
        else:
            def fun(s, y):
                return f(y, s, j, ufun(s))
        t_bound = self._bound(t) if self.delays else self.t_max
        h = self.h_hint
        if h is not None:
            h = min(h, t_bound - t, self.max_step)
            if not h > 0:
                h = None
        solver = self.Method(fun, t, x, t_bound, rtol=self.rtol, atol=self.atol,
                             max_step=self.max_step, first_step=h)
        a, ya = t, x
        inD_prev = inD_start
        max_norm = self.max_norm
        refine = self.refine
        while True:
            msg = solver.step()
            if solver.status == "failed":
                self._stop(Termination.SOLVER_FAILED, f"{msg} at t={a}")
                return "stop", a, ya
            b = solver.t
            yb = solver.y
            if not np.isfinite(yb).all():
                self._stop(Termination.NON_FINITE, f"after the step from t={a} to t={b}")
                return "stop", a, ya
            ub = ufun(b) if ufun is not None else None
            d_active = watch_D and not inD_prev     # D entries count only from outside D
            event = has_C and not C(yb, b, j, ub)
            if watch_D:
                inDb = bool(D(yb, b, j, ub))
                event = event or (inDb and d_active)
                inD_prev = inDb
            if event:
                sol = solver.dense_output()
                return self._event(sol, a, b, j, solver, d_active, t)
            if keep or refine > 1:
                sol = solver.dense_output()
                if keep:
                    hist._add(a, b, j, sol)
                if refine > 1:
                    self._refine(sol, a, b, j)
            buf.append(b, j, yb)
            if pbar is not None and math.isfinite(self.t_max):
                pbar.update(b - a)
            if max_norm < math.inf and np.linalg.norm(yb) > max_norm:
                self._stop(Termination.BLOWUP, f"|x| = {np.linalg.norm(yb):.3g} > "
                                               f"{max_norm:.3g} at t={b}")
                return "stop", b, yb
            if solver.status == "finished":
                if b < self.t_max:          # a delay breakpoint: go on flowing
                    self.h_hint = getattr(solver, "h_abs", None)
                    return "break", b, yb
                self.h_hint = None
                return "tmax", b, yb
            a, ya = b, yb

    def _refine(self, sol, a, b, j):
        """Store refine - 1 dense-output samples strictly inside (a, b)."""
        if b > a:
            ts = np.linspace(a, b, self.refine + 1)[1:-1]
            X = np.asarray(sol(ts)).T
            for s, xs in zip(ts, X):
                self.buf.append(s, j, xs)

    def _event(self, sol, a, b, j, solver, watch_D, t_start):
        """Locate the first event in (a, b] and decide what happens there.

        ``watch_D``: entering D is an event (the step started outside D).
        """
        maps, ufun = self.maps, self.ufun
        C, D, hC, hD = maps.C, maps.D, maps.hC, maps.hD
        has_C, has_D = maps.has_C, maps.has_D

        def u_at(s):
            return ufun(s) if ufun is not None else None

        def pred(s, y):
            u = u_at(s)
            return (has_C and not C(y, s, j, u)) or (watch_D and bool(D(y, s, j, u)))

        phi = None
        if self.use_phi and (watch_D or hC is not None):
            def phi(s, y):
                u = u_at(s)
                v = -math.inf
                if watch_D and hD is not None:
                    v = guard_min(hD(y, s, j, u))
                if has_C and hC is not None:
                    v = max(v, -guard_min(hC(y, s, j, u)))
                return v

        lo, hi, ylo, yhi = locate_event(sol, a, b, pred, phi)
        # next flow's first step: at most 10x the length of this flow (the
        # controller's proposal after an overshooting step can be huge where
        # the flow is integrated exactly, and long steps cancel digits)
        h = getattr(solver, "h_abs", None)
        self.h_hint = None if h is None or hi <= t_start else min(h, 10.0 * (hi - t_start))
        if self.pbar is not None and math.isfinite(self.t_max):
            self.pbar.update(hi - a)
        uhi = u_at(hi)
        if watch_D and D(yhi, hi, j, uhi):
            kind = "jump"
            if self.prio == _RANDOM and (not has_C or C(yhi, hi, j, uhi)) \
                    and self.rng.random() >= 0.5:
                kind = "continue"
            return self._commit(sol, a, j, hi, yhi, kind)
        # the flow leaves C: jump from the last point in C if it is in D
        if has_D and D(ylo, lo, j, u_at(lo)):
            return self._commit(sol, a, j, lo, ylo, "jump")
        if has_D and D(yhi, hi, j, uhi):
            return self._commit(sol, a, j, hi, yhi, "jump")
        self._stop(Termination.LEFT_SETS, f"the flow left C at t={lo} (j={j}), "
                                          f"x={ylo}, outside D")
        return self._commit(sol, a, j, lo, ylo, "stop")

    def _commit(self, sol, a, j, te, xe, kind):
        """Record the flow of the event step up to the event time te."""
        if self.keep:
            self.history._add(a, te, j, sol)
        if te > a:
            if self.refine > 1:
                self._refine(sol, a, te, j)
            self.buf.append(te, j, xe)
        return kind, te, xe
