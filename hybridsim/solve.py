"""The Python path: the flow/jump loop with exact event location.

The rules (priority, causes, the jump-or-flow decision, Zeno and t_max
tolerances) come from :mod:`hybridsim.rules`; this module runs them with a
scipy ODE solver. The run's records (options, state, statistics, samples) are
in :mod:`hybridsim._solve_state`; the solver's set-up, counters, failures and
stiffness test in :mod:`hybridsim._solve_solver`.
"""
from __future__ import annotations

import bisect
import math

import numpy as np
from scipy.integrate import DOP853, RK23, RK45
from scipy.integrate._ivp.rk import RungeKutta

from ._interrupt import SigintLatch
from ._solve_solver import _RunSolver
from ._solve_state import (  # noqa: F401 - run.py imports _Options, _progress_bar here
    _Buffer,
    _dense_derivative,
    _dense_finite,
    _Hermite,
    _Options,
    _Outcome,
    _progress_bar,
    _SampleCap,
    _State,
    _Stats,
)
from .arc import Crossings, HybridArc
from .events import find_interior_event, locate_event, nonnegative, watch_crossings
from .options import check_map_value
from .rules import (
    CAUSES,
    CHATTER_RTOL,
    NO_CAUSE,
    Action,
    MapError,
    Priority,
    SimulationError,
    SimulationWarning,
    Termination,
    after_jump,
    chatter_step,
    decide,
    dwell_outcome,
    event_outcome,
    event_tolerance,
    is_jump_loop,
    is_sticking,
    message,
    needs_coin,
    post_jump_probe,
    t_max_slack,
    time_scale,
    zeno_short,
)
from .system import guard_min, successors, watch_directions

__all__ = ["MapError", "SimulationError", "SimulationWarning"]

_EXPLICIT = (RK23, RK45, DOP853)



class _Run(_RunSolver):
    """One run: the decision loop between flows, and the flows."""

    def __init__(self, system, maps, opts, ufun, history):
        self.system = system
        self.maps = maps
        self.o = opts
        self.ufun = ufun
        self.history = history
        self.latch = SigintLatch()     # run() opens it; unopened, check() does nothing
        self.buf = _Buffer(opts.n, max_samples=opts.max_samples)
        self.stats = _Stats()
        self.cause = None
        self.message = None
        self.exception = None
        self.pbar = None
        self.state = None
        self.t_eval_k = 0
        # events: watch D entries unless flows have priority
        self.watch_D = maps.has_D and opts.prio != Priority.FLOWS
        # (lo, x_lo, x_hi) of a located event the run jumps from at hi, for the
        # post-jump tolerance (rules.post_jump_probe)
        self.pending = None
        self.is_rk = issubclass(opts.Method, RungeKutta)
        # scipy's explicit Runge-Kutta solvers keep no state between steps but
        # (t, y, f, h): one object serves every flow
        self.reuse = opts.Method in (RK23, RK45, DOP853)
        self.restarts = 0       # in-place restarts of the current solver
        self.solver = None
        self.jcell = [0]
        self.calls = [0]        # evaluations of self.fun
        self.calls0 = None      # self.calls when the current solver took self.fun as its own
        self.fun = self._fun()
        self.out_checked = False    # has the flow map been checked for a shared output array?
        self.stiff_check = opts.Method is RK45
        self.sde = None         # an SDE flow's stepper (hybridsim._sde.SDEFlow)
        # watched functions (rule 11): their crossings, and their values where
        # the flow's recorded part ends (w_t, w_x, w_v); w_floor: the flow's start
        self.W = maps.W
        self.w_dir = None
        self.cross = []
        self.w_t = self.w_x = self.w_v = None
        self.w_floor = -math.inf

    # ------------------------------------------------------------------ helpers
    def arc(self):
        b = self.buf
        if b.n and self.cause is not Termination.MAP_ERROR:
            tl, jl, xl, dl = b.last()
            if np.isnan(dl).any():
                fd = self._fdot(tl, xl, int(jl))
                if fd is not None and np.shape(fd) == (self.o.n,) and not np.iscomplexobj(fd):
                    b.set_last_xdot(np.asarray(fd, dtype=float))
        t, j, X, Xd = b.arrays()
        self._count(self.solver)
        self.solver = None
        arc = HybridArc._trusted(t, j, X, self.cause, self.message, self.exception,
                                  components=self.system.components,
                                  segments=self.history.segments if self.o.keep else None,
                                  system=self.system, xdot=Xd,
                                  stats=self.stats.as_dict() if self.sde is None else
                                  {**self.stats.as_dict(), **self.sde.record()})
        if self.W is not None:
            c = self.cross
            arc.crossings = Crossings([e[0] for e in c], [e[1] for e in c],
                                      [e[2] for e in c], [e[3] for e in c],
                                      np.array([e[4] for e in c]).reshape(len(c), self.o.n))
        return arc

    # ------------------------------------------------------------------ watched functions
    def _watch_values(self, s, y, j):
        """The watched functions at (s, y, j): (m,) floats, m fixed for the run."""
        v = self.W(y, s, j, self._u(s))
        if self.w_dir is None:
            self.w_dir = watch_directions(self.maps.W_dir, len(v), s, j)
        elif len(v) != len(self.w_dir):
            raise MapError(f"watch must return the same number of values at every call: "
                           f"{len(self.w_dir)} before, {len(v)} at t={s:.10g}, j={j}",
                           "watch", s, j)
        return v

    def _watch_start(self, st):
        """A flow starts at the current state: the watched functions' values there;
        after a jump (or at x0) a zero there is where the flow starts, not a crossing."""
        t, j, x = st.t, st.j, st.x
        self.w_t, self.w_x, self.w_v = t, x, self._watch_values(t, x, j)
        self.w_floor = t if t == st.t_last_jump else -math.inf

    def _watch_to(self, sol, b, yb, j):
        """Record the crossings of the watched functions on the flow up to (b, yb),
        located on the step's dense output ``sol`` (the step itself is untouched)."""
        if not b > self.w_t:
            return
        wb = self._watch_values(b, yb, j)
        found = watch_crossings(sol, self.w_t, b, self.w_x, yb, self.w_v, wb,
                                lambda s, y: self._watch_values(s, y, j), self.w_dir,
                                self.w_floor)
        for tc, k, sg, xc in found:
            self.cross.append((tc, j, k, sg, xc))
        self.w_t, self.w_x, self.w_v = b, yb, wb

    def _stop(self, cause, kind=None, exc=None, **fields):
        """End the run with ``cause``; its message from :func:`hybridsim.rules.message`."""
        self.cause = cause
        self.message = message(cause, kind, **fields)
        self.exception = exc

    def _last(self):
        """(t, j) of the last stored sample."""
        b = self.buf
        return float(b.t[b.m - 1]), int(b.j[b.m - 1])

    def _u(self, s):
        return self.ufun(s) if self.ufun is not None else None

    # ------------------------------------------------------------------ the loop
    def run(self, t, j, x):
        """The run, then its final sample: every run ends with a sample at the
        state it stopped at (with ``t_eval`` the last step's end is not stored
        otherwise), each sample stored once."""
        with SigintLatch() as self.latch:
            self._loop(t, j, x)
        st, b = self.state, self.buf
        if self.cause is Termination.CANCELED or not b.m:
            return          # interrupted anywhere: the state may be ahead of the store
        tl, jl = self._last()
        if st.t > tl or (st.t == tl and st.j > jl):
            try:
                b.append(st.t, st.j, st.x)
            except _SampleCap:
                pass

    def _loop(self, t, j, x):
        o, maps = self.o, self.maps
        C, D, ufun = maps.C, maps.D, self.ufun
        g = self._g if maps.G is not None else maps.g
        has_C, has_D = maps.has_C, maps.has_D
        st = self.state = _State(t, j, x, t_last_jump=t, h_hint=o.first_step,
                                 breaks=sorted(t + d for d in o.delays))
        self.buf.append(t, j, x)
        if o.t_eval is not None:
            self._skip_t_eval(t)
        forced = False       # the last flow's event requires a jump
        flow_on = False      # random priority chose to flow on in C ∩ D
        post = None          # the event bracket the last jump was taken from
        # at x0: shapes and contracts, raised at once (a programming error);
        # Ctrl-C there ends the run CANCELED with x0, as anywhere in the loop
        try:
            u = self._u(t)
            in_D = has_D and D(x, t, j, u)
            in_C = (not has_C) or C(x, t, j, u)
            if in_C:
                check_map_value("flow_map", maps.f(x, t, j, u), o.n, t, j)
            if in_D and maps.G is None:
                check_map_value("jump_map", g(x, t, j, u), o.n, t, j)
            elif in_D:
                successors(maps.G(x, t, j, u), o.n, t, j)
            if self.W is not None:   # the watched functions and their directions
                self._watch_values(t, x, j)
        except KeyboardInterrupt:
            self._stop(Termination.CANCELED, t=t, j=j)
            return
        latch = self.latch
        try:
            while True:
                latch.check()            # a Ctrl-C whose KeyboardInterrupt was lost
                t, j, x = st.t, st.j, st.x
                if flow_on:          # random priority chose to flow on in C ∩ D
                    in_D = True
                elif forced:         # the located event is in D: jump
                    forced = False
                    if st.jumps >= o.j_max:
                        self._stop(Termination.J_MAX)
                        return
                    post, self.pending = self.pending, None
                    if self._jump(st, g(x, t, j, self._u(t)), True):
                        return
                    continue
                else:
                    u = ufun(t) if ufun is not None else None
                    in_D = has_D and D(x, t, j, u)
                    in_C = (not has_C) or C(x, t, j, u)
                    coin = self._coin(st, t) if needs_coin(in_C, in_D, o.prio, forced) \
                        else False
                    action = decide(in_C, in_D, o.prio, coin, forced)
                    forced = False
                    if action == Action.STOP and post is not None and self._near_C(post):
                        in_C, action = True, Action.FLOW    # within the event's tolerance of C
                    post = None
                    if action == Action.JUMP:
                        if st.jumps >= o.j_max:
                            self._stop(Termination.J_MAX)
                            return
                        if self._jump(st, g(x, t, j, u), in_C):
                            return
                        continue
                    if action == Action.STOP:
                        self._stop_outside(st)
                        return
                if t >= o.t_max:
                    self._stop(Termination.T_MAX)
                    return
                flow_on = False
                kind = self._flow(st, in_D)
                if kind is _Outcome.JUMP:
                    forced = True
                elif kind is _Outcome.FLOW_ON:
                    flow_on = True
                elif kind is _Outcome.STOP:
                    return
        except KeyboardInterrupt:
            tl, jl = self._last()        # where the run stopped: its last stored sample
            self._stop(Termination.CANCELED, t=tl, j=jl)
        except _SampleCap:
            self._stop(Termination.MAX_STEPS, "samples", samples=self.buf.n,
                       max_samples=o.max_samples, t=self._last()[0])
        except MapError as e:
            self._stop(Termination.MAP_ERROR, exc=e, error=str(e))

    def _g(self, x, t, j, u):
        """A set-valued jump map's successor: the first, or one drawn (random priority)."""
        vals = successors(self.maps.G(x, t, j, u), self.o.n, t, j)
        k = 0
        if self.o.prio == Priority.RANDOM and len(vals) > 1:
            k = int(self.o.rng.integers(len(vals)))
        return vals[k]

    def _coin(self, st, t):
        """The random priority's choice at a point of C ∩ D: True jumps.

        A fair coin; with a dwell law, the dwell drawn at the entry into
        C ∩ D (the run then jumps when it has elapsed)."""
        o = self.o
        if o.dwell is None:
            return o.rng.random() < 0.5
        # inside a dwell (a breakpoint, or its deadline) nothing is drawn
        tau = 0.0 if st.dwelling else o.dwell(o.rng)
        jump, st.dwelling, st.deadline = dwell_outcome(st.dwelling, t, st.deadline, tau)
        return jump

    def _near_C(self, post):
        """The post-jump state, in neither C nor D, is within the located
        event's tolerance of C (:func:`hybridsim.rules.post_jump_probe`)."""
        st = self.state
        tp, xp = post_jump_probe(st.x, *post)
        return self.maps.C(xp, tp, st.j, self._u(tp))

    def _jump(self, st, xn, from_C):
        """Apply x+ = g(x) at the current point; True when the run stops.

        ``from_C``: the state jumped from is in C too (flowing was possible):
        consecutive such jumps at one instant are a jump loop."""
        o = self.o
        t, j = st.t, st.j
        xn = check_map_value("jump_map", xn, o.n, t, j).copy()    # the user may reuse it
        flow = t - st.t_last_jump
        fl = st.flow_lengths = (st.flow_lengths + [flow])[-4:]
        short, st.zref = zeno_short(fl, len(fl), t, st.zref, o.zeno_time, o.zeno_rtol)
        st.short = st.short + 1 if short else 0
        longest = st.longest
        st.longest, st.tiny = chatter_step(flow, longest, st.tiny)
        st.same = st.same + 1 if (flow == 0.0 and st.jumps > 0) else 0
        st.loop = st.loop + 1 if (from_C and flow == 0.0 and st.jumps > 0) else 0
        st.t_last_jump = t
        st.dwelling, st.deadline = False, math.inf
        st.j = j + 1
        st.jumps += 1
        st.x = xn
        self.buf.append(t, st.j, xn)
        self.history._restart(t, xn, st.j)
        if o.delays:
            for d in o.delays:
                bisect.insort(st.breaks, t + d)
        if self.pbar is not None:
            if math.isfinite(o.t_max):
                self.pbar.set_postfix_str(f"j={st.j}", refresh=False)
            else:
                self.pbar.update(1)
        code = after_jump(st.jumps, st.short, o.j_max, o.zeno_jumps)
        if code == NO_CAUSE:
            return False
        cause = CAUSES[code]
        if is_jump_loop(st.loop, o.zeno_jumps):
            # the jumps of the loop and the one that started it, all at t
            self._stop(cause, "loop", count=st.loop + 1, t=t)
        elif cause is Termination.ZENO:
            self._stop(cause, "zeno", count=st.short, t=t)
        elif is_jump_loop(st.same, o.zeno_jumps):
            self._stop(cause, "instant", count=st.same + 1, t=t)
        elif is_jump_loop(st.tiny, o.zeno_jumps):
            self._stop(cause, "chatter", count=st.tiny, rtol=CHATTER_RTOL, longest=longest,
                       flow=flow, t=t)
        else:
            self._stop(cause)
        return True

    def _stop_outside(self, st):
        """In neither C nor D: x0 outside both, sticking, or leaving C ∪ D."""
        if self.buf.n == 1:
            self._stop(Termination.NOT_IN_SETS, x=st.x, t=st.t, j=st.j)
            return
        if is_sticking(st.flow_lengths, st.t - st.t_last_jump, st.jumps,
                       time_scale(self.o.t0, st.t, self.o.t_max)):
            self._stop(Termination.ZENO, "sticking", t=st.t, j=st.j, x=st.x,
                       flows=st.flow_lengths[-3:])
            return
        self._stop(Termination.LEFT_SETS, x=st.x, t=st.t, j=st.j)

    def _bound(self, st):
        """End of the flow's integration: t_max, or the next delay breakpoint."""
        br = st.breaks
        tol = 4 * np.finfo(float).eps * max(1.0, abs(st.t))
        while br and br[0] <= st.t + tol:
            br.pop(0)
        return min(br[0], self.o.t_max) if br else self.o.t_max

    # ------------------------------------------------------------------ a flow
    def _flow(self, st, in_D_start):
        """Integrate from (st.t, st.x) until an event, t_max or a failure."""
        if self.sde is not None:
            return self.sde.flow(self, st, in_D_start)
        o, maps, stats = self.o, self.maps, self.stats
        C, D = maps.C, maps.D
        has_C, watch_D = maps.has_C, self.watch_D
        buf, hist, keep, pbar = self.buf, self.history, o.keep, self.pbar
        t, j, x = st.t, st.j, st.x
        self.jcell[0] = j
        if not self.out_checked:
            self._check_shared_output(t, j, x)
        fun = self.fun
        t_bound = self._bound(st) if o.delays else o.t_max
        if st.dwelling:
            if st.deadline <= t:        # out of D when its dwell ended: it is over
                st.dwelling, st.deadline = False, math.inf
            elif st.deadline < t_bound:
                t_bound = st.deadline   # the dwell ends: stopped there, as at an event
        if t_bound == o.t_max < math.inf and t_bound - t <= t_max_slack(t_bound, st.jumps):
            return self._sliver(st, t_bound)
        h = st.h_hint
        if h is not None:
            h = min(h, t_bound - t, o.max_step)
            if not h > 0:
                h = None
        solver = self._start_solver(t, x, t_bound, h)
        stats.flows += 1
        W = self.W
        if W is not None:
            self._watch_start(st)
        # the flow's derivative at its first sample (the solver has it: FSAL)
        f0 = getattr(solver, "f", None)
        buf.set_last_xdot(f0 if f0 is not None else fun(t, x))
        a, ya = t, x
        d_active = watch_D and not in_D_start     # D entries count only from outside D
        # a dwell law locates the exit from D, so the next entry is an event
        exits_D = watch_D and not d_active and o.dwell is not None
        sets = has_C or watch_D
        inner = keep or o.refine > 1 or o.t_eval is not None
        stiff = self.stiff_check
        ufun = self.ufun
        pred = phi = None
        n_stages = getattr(solver, "n_stages", None) if self.is_rk else None
        max_norm, t_eval = o.max_norm, o.t_eval
        check_norm = max_norm < math.inf
        cap = o.max_steps - stats.steps      # steps left in this run
        hermite = o.Method is DOP853
        fa = solver.f if hermite else None
        k = 0
        step = solver.step
        append = buf.append
        try:
            while True:
                if k >= cap:
                    self._stop(Termination.MAX_STEPS, "steps", steps=stats.steps + k,
                               max_steps=o.max_steps, t=a)
                    return self._end(st, a, ya, _Outcome.STOP)
                msg = step()
                if solver.status == "failed":
                    return self._solver_failed(st, solver, msg, a, ya, j)
                k += 1
                b = solver.t
                yb = solver.y
                if not math.isfinite(yb.dot(yb)) and not np.isfinite(yb).all():
                    self._stop(Termination.NON_FINITE, "step", t=a, t2=b, j=j)
                    return self._end(st, a, ya, _Outcome.STOP)
                sol = None
                if sets:
                    try:
                        ub = ufun(b) if ufun is not None else None
                        if exits_D and not d_active:
                            out = self._leave_D(st, solver, a, ya, b, yb, j)
                            if out is not None:
                                return out
                        if (has_C and not C(yb, b, j, ub)) or (d_active and D(yb, b, j, ub)):
                            sol = solver.dense_output()
                            return self._event(st, sol, a, ya, a, b, j, solver, d_active,
                                               ya, yb)
                        if has_C or d_active:
                            if pred is None:
                                phi = self._phi(j, d_active)
                                pred = self._pred(j, d_active, phi)
                            if hermite:
                                # DOP853's dense output costs three more flow evaluations:
                                # search with the cubic Hermite of the step's ends (exact
                                # on parabolas), confirm a hit on the dense output
                                hit = find_interior_event(
                                    _Hermite(a, ya, fa, b, yb, solver.f), a, b, pred, phi)
                                if hit is not None:
                                    sol = solver.dense_output()
                                    hit = find_interior_event(sol, a, b, pred, phi)
                            else:
                                sol = solver.dense_output()
                                hit = find_interior_event(sol, a, b, pred, phi)
                            if hit is not None:
                                return self._event(st, sol, a, ya, hit[0], hit[1], j, solver,
                                                   d_active)
                    except MapError:
                        # a set or guard given the NaN of an overflowing dense output
                        # did not fail: the step did
                        if sol is None or _dense_finite(sol):
                            raise
                        return self._non_finite(st, a, ya, b, j)
                    if watch_D and not d_active:
                        d_active = not D(yb, b, j, ub)
                        pred = phi = None
                        if d_active:        # left D: a dwell in C ∩ D is over
                            st.dwelling, st.deadline = False, math.inf
                if stiff and (st.stiff_hits or k % 25 == 0):
                    self._check_stiff(st, solver, stats.steps + k)
                if W is not None:
                    if sol is None:
                        sol = solver.dense_output()
                    self._watch_to(sol, b, yb, j)
                fin = solver.status == "finished"
                if inner:
                    if sol is None:
                        sol = solver.dense_output()
                    if keep:
                        hist._add(a, b, j, sol)
                    # the end's own sample (t_max, a breakpoint) stands for t_eval times at b
                    self._inner_samples(sol, a, b, j, fin)
                if t_eval is None or fin:
                    append(b, j, yb, solver.f if n_stages else fun(b, yb))
                    if t_eval is not None:
                        self._skip_t_eval(b)
                if pbar is not None and math.isfinite(o.t_max):
                    pbar.update(b - a)
                if check_norm:
                    nb = float(np.linalg.norm(yb))
                    if nb > max_norm:
                        self._stop(Termination.BLOWUP, norm=nb, max_norm=max_norm, t=b, j=j)
                        return self._end(st, b, yb, _Outcome.STOP)
                if fin:
                    if b < o.t_max:          # a delay breakpoint: go on flowing
                        st.h_hint = getattr(solver, "h_abs", None)
                        return self._end(st, b, yb, _Outcome.BREAK)
                    st.h_hint = None
                    if d_active:
                        hit = self._event_past_t_max(st, solver, a, ya, b, j)
                        if hit is not None:
                            return hit
                    return self._end(st, b, yb, _Outcome.T_MAX)
                a, ya = b, yb
                if hermite:
                    fa = solver.f
        finally:
            stats.steps += k

    def _sliver(self, st, t_end):
        """A flow to t_max within round-off of zero length (a jump landed a few
        ulp before t_max): one Euler step, as no solver steps it reliably
        (LSODA refuses it); the run then ends with a sample at t_max."""
        o = self.o
        t, j, x = st.t, st.j, st.x
        f = check_map_value("flow_map", self.maps.f(x, t, j, self._u(t)), o.n, t, j)
        self.stats.flows += 1
        self.buf.set_last_xdot(f)
        xe = x + (t_end - t) * f
        if self.W is not None:
            self._watch_start(st)
            self._watch_to(lambda s: x + (s - t) * f, t_end, xe, j)
        self.buf.append(t_end, j, xe, f)
        if self.pbar is not None and math.isfinite(o.t_max):
            self.pbar.update(t_end - t)
        st.h_hint = None
        return self._end(st, t_end, xe, _Outcome.T_MAX)

    def _end(self, st, t, x, outcome):
        st.t, st.x = t, x
        return outcome

    def _pred(self, j, d_active, phi=None):
        """The event indicator of a flow: it left C, or (d_active) it entered D.

        With ``phi`` (:meth:`_phi`) where D is {jump_guard >= 0} and C is not
        watched, the indicator is ``phi >= 0`` (:func:`hybridsim.events.nonnegative`:
        the interior search evaluates the guard once per sample)."""
        maps, has_C, ufun = self.maps, self.maps.has_C, self.ufun
        C, D = maps.C, maps.D
        if phi is not None and d_active and not has_C and maps.D_guard:
            return nonnegative(phi)
        if ufun is None:            # the common case, without the input's call
            if has_C and d_active:
                def pred(s, y):
                    return (not C(y, s, j, None)) or D(y, s, j, None)
            elif has_C:
                def pred(s, y):
                    return not C(y, s, j, None)
            else:
                def pred(s, y):
                    return d_active and D(y, s, j, None)
            return pred

        def pred(s, y):
            u = ufun(s)
            return (has_C and not C(y, s, j, u)) or (d_active and D(y, s, j, u))
        return pred

    def _phi(self, j, d_active):
        """The continuous event function (>= 0 once the event has happened), if any.

        Every given guard is used: where one set has a guard and the other only
        an indicator, the guard's part locates its crossings and the indicator
        (in ``pred``, which decides membership) the other set's. A guard that
        returns NaN raises a :class:`MapError` naming it."""
        maps, ufun = self.maps, self.ufun
        hC, hD = maps.hC, maps.hD
        useD = d_active and hD is not None
        useC = maps.has_C and hC is not None
        if not (useD or useC):
            return None

        def nan(name, s):
            return MapError(f"{name} returned NaN (at t={s:.10g}, j={j})", name, s, j)
        if ufun is None:
            if useD and useC:
                def phi(s, y):
                    vd, vc = guard_min(hD(y, s, j, None)), guard_min(hC(y, s, j, None))
                    if vd != vd or vc != vc:
                        raise nan("jump_guard" if vd != vd else "flow_guard", s)
                    return max(vd, -vc)
            elif useD:
                def phi(s, y):
                    v = guard_min(hD(y, s, j, None))
                    if v != v:
                        raise nan("jump_guard", s)
                    return v
            else:
                def phi(s, y):
                    v = guard_min(hC(y, s, j, None))
                    if v != v:
                        raise nan("flow_guard", s)
                    return -v
            return phi

        def phi(s, y):
            u = ufun(s)
            v = -math.inf
            if useD:
                v = guard_min(hD(y, s, j, u))
                if v != v:
                    raise nan("jump_guard", s)
            if useC:
                c = guard_min(hC(y, s, j, u))
                if c != c:
                    raise nan("flow_guard", s)
                v = max(v, -c)
            return v
        return phi

    def _event(self, st, sol, a, ya, lo, hi, j, solver, d_active, ylo=None, yhi=None,
               clamp=None, start=None):
        """Locate the first event in (lo, hi] of the step from (a, ya); decide
        there (:func:`hybridsim.rules.event_outcome`).

        ``ylo``, ``yhi``: the states at lo and hi where the caller has them;
        ``clamp``: the latest time the event is recorded at; ``start``: the
        step is recorded (samples, history) up to here already."""
        o, maps = self.o, self.maps
        C, D, has_C, has_D = maps.C, maps.D, maps.has_C, maps.has_D
        self.stats.events += 1
        phi = self._phi(j, d_active)
        lo, hi, ylo, yhi = locate_event(sol, lo, hi, self._pred(j, d_active, phi), phi,
                                        ya=ylo, yb=yhi)
        if not (math.isfinite(ylo.dot(ylo)) and math.isfinite(yhi.dot(yhi))) \
                and not (np.isfinite(ylo).all() and np.isfinite(yhi).all()):
            # the NaN of an overflowing dense output read as "left C" or "in D"
            return self._non_finite(st, a, ya, solver.t, j)
        # next flow's first step: at most 10x the length of this flow (the
        # controller's proposal after an overshooting step can be huge where
        # the flow is integrated exactly, and long steps cancel digits)
        h = getattr(solver, "h_abs", None)
        st.h_hint = None if h is None or hi <= st.t else min(h, 10.0 * (hi - st.t))
        te_hi = hi if clamp is None else min(hi, clamp)
        if self.pbar is not None and math.isfinite(o.t_max):
            self.pbar.update(te_hi - a)
        uhi = self._u(hi)
        in_D_hi = has_D and D(yhi, hi, j, uhi)
        in_C_hi, coin = False, True
        if d_active and in_D_hi and o.prio == Priority.RANDOM:
            # C matters here only for the random priority's coin
            in_C_hi = (not has_C) or C(yhi, hi, j, uhi)
            if needs_coin(in_C_hi, True, o.prio):
                coin = self._coin(st, hi)
        # D at lo matters only where the flow leaves C
        in_D_lo = has_D and not (d_active and in_D_hi) and D(ylo, lo, j, self._u(lo))
        action, side = event_outcome(d_active, in_D_hi, in_C_hi, in_D_lo, o.prio, coin)
        if action == Action.STOP:
            out = self._commit(st, sol, a, j, lo, ylo, _Outcome.STOP, start)
            self._stop_outside(st)
            if self.cause is Termination.LEFT_SETS:
                self._stop(Termination.LEFT_SETS, "left", t=lo, j=j, x=ylo)
            return out
        if action == Action.JUMP:
            self.pending = (lo, ylo, yhi) if side else None
            return self._commit(st, sol, a, j, te_hi if side else lo, yhi if side else ylo,
                                _Outcome.JUMP, start)
        return self._commit(st, sol, a, j, te_hi, yhi, _Outcome.FLOW_ON, start)

    def _leave_D(self, st, solver, a, ya, b, yb, j):
        """With a dwell law, a flow in C ∩ D that leaves D within the step
        (a, b] stops where it leaves (still in C): the flow then goes on
        watching D, so a later entry within the same step is not missed.
        None where it stays in D, or leaves C first (the step's own event)."""
        maps, u = self.maps, self._u
        C, D, hD = maps.C, maps.D, maps.hD

        def out_D(s, y):
            return not D(y, s, j, u(s))
        phi = None if hD is None else (lambda s, y: -guard_min(hD(y, s, j, u(s))))
        sol = solver.dense_output()
        if not out_D(b, yb):
            hit = find_interior_event(sol, a, b, out_D, phi)
            if hit is None:
                return None
            _, hi, _, yhi = locate_event(sol, hit[0], hit[1], out_D, phi)
        else:
            _, hi, _, yhi = locate_event(sol, a, b, out_D, phi, ya=ya, yb=yb)
        if maps.has_C and not C(yhi, hi, j, u(hi)):
            return None
        self.stats.events += 1
        st.dwelling, st.deadline = False, math.inf
        h = getattr(solver, "h_abs", None)
        st.h_hint = None if h is None or hi <= st.t else min(h, 10.0 * (hi - st.t))
        return self._commit(st, sol, a, j, hi, yhi, _Outcome.BREAK)

    def _event_past_t_max(self, st, solver, a, ya, b, j):
        """An entry into D within round-off after t_max is taken at t_max."""
        pred = self._pred(j, True)
        sol = solver.dense_output()
        tb = b + t_max_slack(b, st.jumps)
        if not pred(tb, sol(tb)):
            return None
        # the step up to b is recorded: the event's sample replaces the t_max one
        if self._last() == (b, j):
            self.buf.pop()
        return self._event(st, sol, a, ya, b, tb, j, solver, True, ylo=solver.y, clamp=b,
                           start=b)

    def _commit(self, st, sol, a, j, te, xe, outcome, start=None):
        """Record the flow of the event step from ``start`` (default: a, the
        step's start) up to the event time te, and the event's sample."""
        o = self.o
        s = a if start is None else start
        if self.W is not None:
            self._watch_to(sol, te, xe, j)
        if o.keep and (start is None or te > s):
            self.history._add(s, te, j, sol)
        if te > s and (o.refine > 1 or o.t_eval is not None):
            self._inner_samples(sol, s, te, j, True)
        b = self.buf
        # stored once: a flow's start (or an ordinary step's end without t_eval)
        # at te is the event's sample already
        if te > b.t[b.m - 1] or j != b.j[b.m - 1]:
            b.append(te, j, xe, self._fdot(te, xe, j))
            if o.max_norm < math.inf:        # the event's sample is checked like a step's end
                nb = float(np.linalg.norm(xe))
                if nb > o.max_norm:
                    self._stop(Termination.BLOWUP, norm=nb, max_norm=o.max_norm, t=te, j=j)
                    return self._end(st, te, xe, _Outcome.STOP)
        if o.t_eval is not None:
            self._skip_t_eval(te)
        return self._end(st, te, xe, outcome)

    def _fdot(self, s, y, j):
        try:
            return self.maps.f(y, s, j, self._u(s))
        except Exception:  # noqa: BLE001 - outside C the flow map may be undefined
            return None

    def _inner_samples(self, sol, a, b, j, end=False):
        """refine - 1 dense-output samples inside (a, b), or the t_eval points
        not stored yet up to b; ``end``: b gets a sample of its own (an event,
        t_max, a breakpoint), which stands for the t_eval times within the
        event tolerance of b."""
        o = self.o
        if o.t_eval is not None:
            te = o.t_eval
            k0 = max(self.t_eval_k, int(np.searchsorted(te, a, side="right")))
            top = b - event_tolerance(b, b) if end else b
            k1 = int(np.searchsorted(te, top, side="right"))
            if k1 <= k0:
                return
            ts = te[k0:k1]
            self.t_eval_k = k1
        elif o.refine > 1 and b > a:
            ts = np.linspace(a, b, o.refine + 1)[1:-1]
        else:
            return
        X = np.asarray(sol(ts)).T.reshape(ts.size, o.n)
        self.buf.extend(ts, j, X, _dense_derivative(sol, ts))

    def _skip_t_eval(self, t):
        """A sample at t is stored (the initial one, an event's, a flow's end):
        it stands for the t_eval times within the event tolerance of t."""
        te = self.o.t_eval
        k = int(np.searchsorted(te, t + event_tolerance(t, t), side="right"))
        if k > self.t_eval_k:
            self.t_eval_k = k


