"""Read access to the past of a run: values at t - tau, integrals over windows."""
from __future__ import annotations

from bisect import bisect_right

import numpy as np

__all__ = ["History", "HistoryError"]

# 5-point Gauss-Legendre: exact for polynomials of degree 9 (the dense output
# of RK45 is quartic, of DOP853 degree 7).
_GL_X, _GL_W = np.polynomial.legendre.leggauss(5)


class HistoryError(ValueError):
    """A value of the past was asked for where the run has none yet."""


class History:
    """The past of a run, exact to the integrator's dense output.

    A map reads it through ``self.history`` during :func:`hybridsim.simulate`.
    Calling it at a time s returns the state x(s):

    * s < t0: the prehistory (constant x0 unless ``simulate(prehistory=...)``);
    * at a jump time, the post-jump value (where the later flow started),
      also across several jumps at one time;
    * elsewhere, the dense output of the solver step that covers s.

    The solver step must not reach past the delay: a system that reads
    ``history(t - tau)`` sets ``max_step = tau`` (the engine caps the step).
    """

    def __init__(self, t0, x0, j0, prehistory=None, ufun=None, output=None):
        self._ufun = ufun
        self._h = output
        self.t0 = float(t0)
        self._x0 = np.array(x0, dtype=float)
        self._pre = prehistory
        self._starts: list[float] = []
        self._ends: list[float] = []
        self._js: list[int] = []
        self._sols: list = []
        self._cur_t = self.t0
        self._cur_x = self._x0.copy()
        self._cur_j = int(j0)

    # -- written by the engine -------------------------------------------
    def _add(self, ta, tb, j, sol):
        if tb > ta:
            self._starts.append(ta)
            self._ends.append(tb)
            self._js.append(j)
            self._sols.append(sol)

    def _restart(self, t, x, j):
        self._cur_t, self._cur_x, self._cur_j = t, x, j

    @property
    def segments(self):
        """List of ``(t_start, t_end, j, dense_output)`` recorded so far."""
        return list(zip(self._starts, self._ends, self._js, self._sols))

    # -- read by maps ------------------------------------------------------
    def _locate(self, s):
        k = bisect_right(self._starts, s) - 1
        if k >= 0 and s <= self._ends[k]:
            # prefer the later flow when s is a jump time shared by two segments
            return k
        return None

    def __call__(self, s):
        """The state x(s) (see the class docstring)."""
        s = float(s)
        if s < self.t0:
            if self._pre is None:
                return self._x0.copy()
            return np.asarray(self._pre(s), dtype=float)
        tol = 1e-12 * max(1.0, abs(s))
        if s >= self._cur_t and (not self._starts or self._starts[-1] < self._cur_t):
            # no step of the current flow is recorded yet: its start (post-jump value)
            if s <= self._cur_t + tol:
                return self._cur_x.copy()
            raise HistoryError(
                f"history: x({s}) lies in the solver step under way (the flow "
                f"started at t={self._cur_t}); cap the step with max_step <= the "
                f"smallest delay")
        k = self._locate(s)
        if k is None:
            if self._ends and self._ends[-1] < s <= self._ends[-1] + tol:
                k = len(self._ends) - 1
            elif self._ends and s > self._ends[-1]:
                raise HistoryError(
                    f"history: x({s}) lies in the solver step under way (recorded up to "
                    f"t={self._ends[-1]}); cap the step with max_step <= the smallest delay")
            else:
                raise HistoryError(f"history: no recorded value at s={s}")
        return np.asarray(self._sols[k](s), dtype=float)

    state = __call__

    def input(self, s):
        """The input u(s) of a standalone system (``simulate(inputs=...)``)."""
        return None if self._ufun is None else self._ufun(float(s))

    def output(self, s):
        """The output y(s) of the system."""
        return self._h(self(s), float(s), self.jump_count(s), self.input(s))

    def jump_count(self, s):
        """The j of the sample at time s (the later one at a jump time)."""
        if s < self.t0:
            if hasattr(self._pre, "jump_count"):     # a past continued (explore's branches)
                return self._pre.jump_count(s)
            return self._cur_j if not self._js else self._js[0]
        if s >= self._cur_t:
            return self._cur_j
        k = self._locate(s)
        return self._js[k] if k is not None else self._cur_j

    def integral(self, fn, a, b):
        """Integral of ``fn(x(s), s)`` over [a, b].

        Gauss-Legendre (5 nodes) on each recorded dense segment: exact to the
        dense output for polynomial integrands of low degree. The prehistory
        part (s < t0) uses 5-node Gauss-Legendre on [a, min(b, t0)], or the
        past's own integral where the prehistory is a recorded run's
        :class:`History` (:func:`hybridsim.explore`'s branches).
        """
        a, b = float(a), float(b)
        if b < a:
            return -self.integral(fn, b, a)
        total = 0.0
        pieces = []
        if a < self.t0:
            if hasattr(self._pre, "integral"):       # a past continued: its own pieces
                total = self._pre.integral(fn, a, min(b, self.t0))
            else:
                pieces.append((a, min(b, self.t0), None))
        lo = max(a, self.t0)
        if b > lo:
            k = max(bisect_right(self._starts, lo) - 1, 0)
            while k < len(self._starts) and self._starts[k] < b:
                pa, pb = max(self._starts[k], lo), min(self._ends[k], b)
                if pb > pa:
                    pieces.append((pa, pb, self._sols[k]))
                k += 1
            covered = self._ends[-1] if self._ends else self.t0
            if b > covered + 1e-12 * max(1.0, abs(b)):
                raise HistoryError(f"history.integral: [{a}, {b}] reaches past the "
                                   f"recorded run (up to t={covered})")
        for pa, pb, sol in pieces:
            s = 0.5 * (pb - pa) * _GL_X + 0.5 * (pa + pb)
            if sol is None:
                xs = [self(si) for si in s]
            else:
                X = np.asarray(sol(s))          # (n, 5)
                xs = list(X.T)
            vals = [np.asarray(fn(x, si), dtype=float) for x, si in zip(xs, s)]
            total = total + 0.5 * (pb - pa) * sum(w * v for w, v in zip(_GL_W, vals))
        return total


class ComponentHistory:
    """A component's view of its interconnection's history."""

    def __init__(self, parent: History, sl: slice, owner, name):
        self._parent = parent
        self._sl = sl
        self._owner = owner      # the Interconnection
        self._name = name

    def __call__(self, s):
        return self._parent(s)[self._sl]

    state = __call__

    def jump_count(self, s):
        return self._parent.jump_count(s)

    def input(self, s):
        """The component's input u(s), through the interconnection's wiring."""
        x = self._parent(s)
        return self._owner._input_of(self._name, x, float(s), self._parent.jump_count(s))

    def output(self, s):
        x = self._parent(s)
        return self._owner.outputs(x, float(s), self._parent.jump_count(s))[self._name]

    def integral(self, fn, a, b):
        sl = self._sl
        return self._parent.integral(lambda x, s: fn(x[sl], s), a, b)
