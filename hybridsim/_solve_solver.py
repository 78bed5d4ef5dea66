"""The solver side of the Python loop (a base class of
:class:`hybridsim.solve._Run`): the solver's right-hand side built from the
flow map and its contract checked, the check for a flow map returning a shared
array, the solver started or reset in place, its counters added to the run's
statistics, its failures (a failed step, a non-finite dense output), and
Hairer's stiffness test for RK45.
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy.integrate import DOP853, RK23, RK45

from ._rk import LEAN, first_step
from ._solve_state import _Outcome
from .options import check_map_value
from .rules import MapError, SimulationWarning, Termination

# Hairer's stiffness test for RK45 (Dormand-Prince): rows giving (y7 - y6) / h
# and k7 - k6 from the seven stages K
_STIFF_W = np.zeros((2, RK45.n_stages + 1))
_STIFF_W[0, :RK45.n_stages] = RK45.B
_STIFF_W[0, :RK45.n_stages - 1] -= RK45.A[RK45.n_stages - 1]
_STIFF_W[1, -2:] = (-1.0, 1.0)


class _RunSolver:
    """The solver's methods of :class:`hybridsim.solve._Run` (its base class)."""

    def _fun(self):
        """The solver's right-hand side: the user's flow map called directly
        (one Python frame), its failures named and its value's contract checked.

        It reads the flow's j from ``self.jcell``, so one solver object serves
        every flow of the run, and counts its calls in ``self.calls`` (the
        explicit Runge-Kutta solvers call it without scipy's two wrappers).
        """
        maps, ufun, n, jcell, calls = self.maps, self.ufun, self.o.n, self.jcell, self.calls
        fn, k = maps.f_raw, maps.f_arity
        shape = (n,)
        nd, f64 = np.ndarray, np.dtype(float)

        def fail(e, s):
            if isinstance(e, MapError):
                raise e
            raise MapError(f"flow_map raised {type(e).__name__}: {e} (at t={s:.10g}, "
                           f"j={jcell[0]})", "flow_map", s, jcell[0]) from e

        def checked(v, s):
            if isinstance(v, np.ndarray) and v.shape == shape and v.dtype.kind in "iub":
                return v.astype(float)
            return check_map_value("flow_map", v, n, s, jcell[0])

        if k <= 1 and ufun is None:
            def fun(s, y):
                calls[0] += 1
                try:
                    v = fn(y)
                except Exception as e:  # noqa: BLE001 - named and re-raised
                    fail(e, s)
                if v.__class__ is nd and v.dtype is f64 and v.shape == shape:
                    return v
                return checked(v, s)
        elif k == 2 and ufun is None:
            def fun(s, y):
                calls[0] += 1
                try:
                    v = fn(y, s)
                except Exception as e:  # noqa: BLE001
                    fail(e, s)
                if v.__class__ is nd and v.dtype is f64 and v.shape == shape:
                    return v
                return checked(v, s)
        else:
            f = maps.f

            def fun(s, y):
                calls[0] += 1
                v = f(y, s, jcell[0], ufun(s) if ufun is not None else None)
                if v.__class__ is nd and v.dtype is f64 and v.shape == shape:
                    return v
                return checked(v, s)
        return fun

    def _check_shared_output(self, t, j, x):
        """A flow map that returns one array, overwritten on every call (a
        preallocated ``out``), would leave the solver's stored derivative
        stale: two calls at the first flow's start tell, and its values are
        then copied as they come."""
        self.out_checked = True
        u = self._u(t)
        v = self.maps.f(x, t, j, u)
        if isinstance(v, np.ndarray) and self.maps.f(x, t, j, u) is v:
            raw = self.fun

            def fun(s, y):
                return raw(s, y).copy()
            self.fun = fun

    def _start_solver(self, t, x, t_bound, h):
        """The solver for a flow from (t, x): the run's Runge-Kutta solver reset
        in place where it can be (its set-up is a third of a short flow's
        cost), else a new one."""
        s = self.solver
        if s is not None and h is not None and self.reuse:
            # the solver never writes into its y: the run's own float state serves
            s.t, s.t_bound = t, t_bound
            s.y = x if type(x) is np.ndarray and x.dtype == np.float64 else np.array(x, float)
            s.status, s.t_old, s.y_old, s.h_previous = "running", None, None, None
            s.h_abs = h
            s.f = s.fun(t, s.y)
            self.restarts += 1
            return s
        self._count(self.solver)
        # RK45 and RK23 step without scipy's per-step overheads (bit for bit the same)
        Method = LEAN.get(self.o.Method, self.o.Method) if self.reuse else self.o.Method
        # an adaptive Runge-Kutta flow's first step: the rule the kernel compiles
        # (hybridsim._rk), in place of scipy's (the same rule, its norms summed in
        # another order)
        own = h is None and issubclass(Method, (RK23, RK45, DOP853)) and t_bound != t
        s = Method(self.fun, t, x, t_bound, rtol=self.o.rtol, atol=self.o.atol,
                   max_step=self.o.max_step, first_step=abs(t_bound - t) if own else h)
        if self.reuse:
            # self.fun already returns float arrays of shape (n,): scipy's two
            # wrappers (asarray, call count) are bypassed; self.calls counts
            s.fun = self.fun
            self.calls0 = self.calls[0]
        if own:
            s.h_abs = first_step(s.fun, t, s.y, t_bound, s.max_step, s.f,
                                 s.error_estimator_order, s.rtol, s.atol)
        self.solver = s
        return s

    def _count(self, solver):
        """Add a retired solver's evaluation counters to the run's statistics."""
        if solver is not None:
            st = self.stats
            nfev = solver.nfev
            if solver.fun is self.fun:
                nfev += self.calls[0] - self.calls0
            st.nfev += nfev
            ns = getattr(solver, "n_stages", None)
            if isinstance(solver, (RK23, RK45)):
                # each attempt costs n_stages evaluations, each (re)start one
                st.attempts += (nfev - 1 - self.restarts) // ns
                self.restarts = 0
            st.njev += getattr(solver, "njev", 0)
            st.nlu += getattr(solver, "nlu", 0)

    def _solver_failed(self, st, solver, msg, a, ya, j):
        """A failed step: a non-finite flow map is NON_FINITE; short flows ZENO."""
        K = getattr(solver, "K", None)
        bad = K is not None and not np.isfinite(K).all()
        if not bad:
            try:
                bad = not np.isfinite(self.maps.f(ya, a, j, self._u(a))).all()
            except MapError:
                bad = True
        if bad:
            self._stop(Termination.NON_FINITE, "flow", t=a, j=j)
        elif st.short > 0:
            self._stop(Termination.ZENO, "short", t=a)
        else:
            self._stop(Termination.SOLVER_FAILED, reason=msg, t=a, j=j)
        return self._end(st, a, ya, _Outcome.STOP)

    def _non_finite(self, st, a, ya, b, j):
        """The step from a to b overflowed inside (its dense output is not
        finite although its ends may be): NON_FINITE, the run ends at a."""
        self._stop(Termination.NON_FINITE, "dense", t=a, t2=b, j=j)
        return self._end(st, a, ya, _Outcome.STOP)

    def _check_stiff(self, st, solver, steps):
        """Hairer's stiffness test for Dormand-Prince: h·ρ > 3.25 on 15 steps.

        ρ = |k7 - k6| / |y7 - y6| estimates the Jacobian's dominant eigenvalue
        from the two stages at t + h (Hairer & Wanner, Solving ODEs II, IV.2).
        """
        if st.warned_stiff:
            return
        # rows of W @ K: (y7 - y6) / h = (b - a6) . K and k7 - k6, in one product
        dy, dk = _STIFF_W @ solver.K
        den = float(dy @ dy)
        if den > 0 and float(dk @ dk) > 3.25 * 3.25 * den:
            st.stiff_hits += 1
            st.calm = 0
        else:
            st.calm += 1
            if st.calm >= 6:         # as Hairer's DOPRI5: six calm steps reset the count
                st.stiff_hits = 0
        if st.stiff_hits >= 15 and steps >= 500:     # a short run is not worth a warning
            st.warned_stiff = True
            warnings.warn(f"the flow looks stiff near t={solver.t:.6g} (j={st.j}): "
                          f"{self.o.Method.__name__}'s step size is limited by stability, "
                          f"not accuracy. Use method='Radau', 'BDF' or 'LSODA'",
                          SimulationWarning, stacklevel=6)  # _flow, _loop, run, simulate
