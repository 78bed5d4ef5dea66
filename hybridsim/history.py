"""Read access to the past of a run: values at t - tau, integrals over windows."""
from __future__ import annotations

from bisect import bisect_right

import numpy as np

from .rules import MapError

__all__ = ["History", "HistoryError", "BatchHistory"]

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
            h = self._holder(s)
            if s >= h.t0:
                return h(s)
            if h._pre is None:
                return h._x0.copy()
            return h._prehistory(s)
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

    def _prehistory(self, s):
        """The user's ``prehistory(s)``, checked: a :class:`hybridsim.MapError`
        naming ``prehistory`` where it raises or returns anything but a finite
        real array of the state's shape."""
        n = self._x0.shape[0]
        where = f"(at s={s:.10g}, read by the maps through history before t0={self.t0:.10g})"
        try:
            v = self._pre(s)
        except MapError:
            raise
        except Exception as e:
            raise MapError(f"prehistory raised {type(e).__name__}: {e} {where}",
                           "prehistory", s) from e
        if np.iscomplexobj(v):
            raise MapError(f"prehistory returned complex values {v!r} {where}: the state "
                           f"is real", "prehistory", s)
        try:
            arr = np.asarray(v, dtype=float)
        except (TypeError, ValueError) as e:
            raise MapError(f"prehistory must return an array of {n} floats, got "
                           f"{type(v).__name__} {where}", "prehistory", s) from e
        if arr.shape != (n,):
            raise MapError(f"prehistory must return an array of shape ({n},) (the state's), "
                           f"got shape {arr.shape} {where}", "prehistory", s)
        if not np.all(np.isfinite(arr)):
            raise MapError(f"prehistory returned non-finite values {arr} {where}",
                           "prehistory", s)
        return arr

    def _holder(self, s):
        """The run of a chain of pasts (explore's branches) that recorded s, or the
        first whose plain prehistory holds it; walked without recursion."""
        h = self
        while s < h.t0 and isinstance(h._pre, History):
            h = h._pre
        return h

    def input(self, s):
        """The input u(s) of a standalone system (``simulate(inputs=...)``)."""
        return None if self._ufun is None else self._ufun(float(s))

    def output(self, s):
        """The output y(s) of the system."""
        return self._h(self(s), float(s), self.jump_count(s), self.input(s))

    def jump_count(self, s):
        """The j of the sample at time s (the later one at a jump time)."""
        if s < self.t0:
            h = self._holder(s)
            if s >= h.t0:
                return h.jump_count(s)
            return h._cur_j if not h._js else h._js[0]
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
        if a < self.t0:
            # the part before t0 from the chain of pasts (explore), walked without recursion
            h, hi = self, min(b, self.t0)
            while isinstance(h._pre, History) and a < h.t0:
                h = h._pre
                lo = max(a, h.t0)
                if hi > lo:
                    total = total + h._own_integral(fn, lo, hi)
                hi = min(hi, h.t0)
            if a < hi:
                total = total + h._own_integral(fn, a, hi, before=True)
        return total + self._own_integral(fn, max(a, self.t0), b)

    def _own_integral(self, fn, a, b, before=False):
        """The integral over [a, b] within this run (``before``: a <= b <= t0, by
        its prehistory)."""
        pieces = []
        if before:
            pieces.append((a, b, None))
        lo = a
        if b > lo and not before:
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
        total = 0.0
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
        return self._parent(s)[..., self._sl]     # (n,) or, on a batch, (k, n) rows

    state = __call__

    def jump_count(self, s):
        return self._parent.jump_count(s)

    @staticmethod
    def _when(s, x):
        """s as the wiring takes it: a float, or (k,) times for a batch's rows."""
        if np.ndim(x) == 2:
            return np.broadcast_to(np.asarray(s, dtype=float), (len(x),)).copy()
        return float(s)

    def input(self, s):
        """The component's input u(s), through the interconnection's wiring."""
        x = self._parent(s)
        return self._owner._input_of(self._name, x, self._when(s, x),
                                     self._parent.jump_count(s))

    def output(self, s):
        x = self._parent(s)
        return self._owner.outputs(x, self._when(s, x), self._parent.jump_count(s))[self._name]

    def integral(self, fn, a, b):
        sl = self._sl
        return self._parent.integral(lambda x, s: fn(x[..., sl], s), a, b)


class BatchHistory:
    """The past of every trajectory of a vectorized batch run (``simulate_many``).

    A vectorized map reads it through ``self.history`` as on the Python path;
    a call covers the rows the engine is evaluating (x of shape (k, n)):
    ``history(s)`` with s a float or a (k,) array returns the (k, n) states
    x(s), by the rules of :class:`History` (constant prehistory x0 before
    t0, the post-jump value at a jump time, else the RK45 dense output of the
    step that covers s). ``jump_count(s)`` returns (k,) ints;
    ``integral(fn, a, b)`` each row's integral over its window.

    Examples
    --------
    x' = -x(t - 1) from constant pasts 1 and 2, one batch: x = x0 (1 - t) on [0, 1].

    >>> import numpy as np, hybridsim as hs
    >>> class Lag(hs.HybridSystem):
    ...     state_dim, vectorized, needs_history, delays, max_step = 1, True, True, (1.0,), 1.0
    ...     def flow_map(self, x, t, j, u):
    ...         return -self.history(t - 1.0)          # (k, 1): the rows being evaluated
    >>> arcs = hs.simulate_many(Lag(), [[1.0], [2.0]], t_max=1.0, rtol=1e-10, atol=1e-12)
    >>> [round(float(a.x[-1, 0]), 9) for a in arcs]
    [0.0, 0.0]
    """

    def __init__(self, t0, X, j0, output=None):
        N, n = X.shape
        self.n, self.t0 = n, float(t0)
        self._x0 = np.array(X, dtype=float)
        self._h = output
        self.rows = np.arange(N)                 # the rows of the call under way
        cap = 8
        self._cnt = np.zeros(N, dtype=np.int64)
        self._a = np.full((N, cap), np.inf)      # segment starts (inf: unused)
        self._b = np.zeros((N, cap))
        self._dt = np.ones((N, cap))             # the step's h (the dense output's scale)
        self._js = np.zeros((N, cap), dtype=np.int64)
        self._ya = np.zeros((N, cap, n))
        self._q = np.zeros((N, cap, n, 4))
        self._cur_t = np.full(N, self.t0)
        self._cur_x = self._x0.copy()
        self._cur_j = np.full(N, int(j0), dtype=np.int64)

    # -- written by the engine -------------------------------------------
    def _add(self, rows, a, b, j, h, ya, Q):
        """Steps a -> b of ``rows`` (dense output ``ya + h Q [s, s^2, s^3, s^4]``)."""
        keep = b > a
        if not keep.all():
            rows, a, b, j, h, ya, Q = (rows[keep], a[keep], b[keep], j[keep], h[keep],
                                       ya[keep], Q[keep])
        if not rows.size:
            return
        c = self._cnt[rows]
        cap = self._a.shape[1]
        if c.max() >= cap:
            grow = max(cap, int(c.max()) + 1 - cap)
            N = len(self._cnt)
            self._a = np.concatenate([self._a, np.full((N, grow), np.inf)], axis=1)
            for name in ("_b", "_dt", "_js", "_ya", "_q"):
                arr = getattr(self, name)
                pad = np.zeros((N, grow) + arr.shape[2:], dtype=arr.dtype)
                setattr(self, name, np.concatenate([arr, pad], axis=1))
        self._a[rows, c], self._b[rows, c], self._dt[rows, c] = a, b, h
        self._js[rows, c], self._ya[rows, c], self._q[rows, c] = j, ya, Q
        self._cnt[rows] += 1

    def _restart(self, rows, t, x, j):
        self._cur_t[rows], self._cur_x[rows], self._cur_j[rows] = t, x, j

    # -- read by maps ------------------------------------------------------
    def _times(self, s):
        k = len(self.rows)
        s = np.asarray(s, dtype=float)
        if s.ndim == 0 or s.shape == (1,):
            return np.full(k, float(s.reshape(-1)[0]))
        if s.shape != (k,):
            raise ValueError(f"history: s must be a float or one time per row ({k},), "
                             f"got shape {s.shape}")
        return s

    def _segments(self, s):
        """(rows, segment index) for times s >= t0 outside the current flow's start."""
        rows = self.rows
        cap = self._a.shape[1]
        if len(rows) * cap <= 1 << 16:           # few: count the starts <= s (one pass)
            a = self._a[rows]
            used = np.arange(cap) < self._cnt[rows][:, None]
            return np.count_nonzero((a <= s[:, None]) & used, axis=1) - 1
        lo = np.zeros(len(rows), dtype=np.int64)
        hi = self._cnt[rows].copy()
        while True:                              # bisect_right over each row's starts
            act = lo < hi
            if not act.any():
                break
            mid = (lo + hi) // 2
            go = self._a[rows, np.minimum(mid, self._a.shape[1] - 1)] <= s
            lo = np.where(act & go, mid + 1, lo)
            hi = np.where(act & ~go, mid, hi)
        return lo - 1

    def __call__(self, s):
        """The rows' states x(s), shape (k, n) (see the class docstring)."""
        s = self._times(s)
        rows = self.rows
        out = np.empty((len(rows), self.n))
        pre = s < self.t0
        out[pre] = self._x0[rows[pre]]
        if pre.all():
            return out
        tol = 1e-12 * np.maximum(1.0, np.abs(s))
        cnt = self._cnt[rows]
        last = np.where(cnt > 0, self._a[rows, np.maximum(cnt - 1, 0)], -np.inf)
        cur_t = self._cur_t[rows]
        # no step of the current flow recorded yet: its start (the post-jump value)
        fresh = ~pre & (s >= cur_t) & ~(last >= cur_t)
        if fresh.any():
            late = fresh & (s > cur_t + tol)
            if late.any():
                i = int(np.flatnonzero(late)[0])
                raise HistoryError(
                    f"history: x({s[i]}) lies in the solver step under way (the flow "
                    f"started at t={cur_t[i]}); cap the step with max_step <= the "
                    f"smallest delay")
            out[fresh] = self._cur_x[rows[fresh]]
        look = ~pre & ~fresh
        if not look.any():
            return out
        k = self._segments(s)
        ok = look & (k >= 0)
        kk = np.maximum(k, 0)
        b = self._b[rows, kk]
        inside = ok & (s <= b + tol)
        if not (inside == look).all():
            i = int(np.flatnonzero(look & ~inside)[0])
            if cnt[i] and s[i] > self._b[rows[i], cnt[i] - 1]:
                raise HistoryError(
                    f"history: x({s[i]}) lies in the solver step under way (recorded up to "
                    f"t={self._b[rows[i], cnt[i] - 1]}); cap the step with max_step <= "
                    f"the smallest delay")
            raise HistoryError(f"history: no recorded value at s={s[i]}")
        r, kk, ss = rows[look], kk[look], np.minimum(s[look], b[look])
        h = self._dt[r, kk]
        xx = (ss - self._a[r, kk]) / h
        p = np.stack([xx, xx * xx, xx ** 3, xx ** 4], axis=1)
        out[look] = self._ya[r, kk] + h[:, None] * np.einsum("knp,kp->kn", self._q[r, kk], p)
        return out

    state = __call__

    def jump_count(self, s):
        """The rows' j at time s, shape (k,) (the later one at a jump time)."""
        s = self._times(s)
        rows = self.rows
        out = self._cur_j[rows].copy()
        look = (s >= self.t0) & (s < self._cur_t[rows])
        if look.any():
            k = np.maximum(self._segments(s), 0)
            out[look] = self._js[rows[look], k[look]]
        first = (s < self.t0) & (self._cnt[rows] > 0)
        out[first] = self._js[rows[first], 0]
        return out

    def input(self, s):
        """None: a vectorized system has no input."""
        return None

    def output(self, s):
        """The rows' outputs y(s)."""
        s = self._times(s)
        return self._h(self(s), s, self.jump_count(s), None)

    def integral(self, fn, a, b):
        """Each row's integral of ``fn(x(s), s)`` over its [a, b].

        As :meth:`History.integral`: 5-node Gauss-Legendre on each recorded
        step of the window (exact to the dense output for polynomial
        integrands of low degree), and on the part before t0 (the constant
        x0). ``a`` and ``b`` are floats or one per row; ``fn`` is called on
        batches, ``x`` of shape (m, n) and ``s`` of shape (m,), and returns
        (m,) or (m, d). Returns (k,) or (k, d).
        """
        a, b = self._times(a), self._times(b)
        rows = self.rows
        flip = b < a
        lo, hi = np.where(flip, b, a), np.where(flip, a, b)
        total = None

        def add(sel, pa, pb, X, S):
            """GL over [pa, pb] of the rows ``sel`` from states X (r, 5, n) at S (r, 5)."""
            nonlocal total
            r = len(pa)
            v = np.asarray(fn(X.reshape(r * 5, self.n), S.reshape(r * 5)), dtype=float)
            v = v.reshape((r, 5) + v.shape[1:])
            part = 0.5 * (pb - pa).reshape((r,) + (1,) * (v.ndim - 2)) * np.tensordot(
                _GL_W, v.swapaxes(0, 1), axes=(0, 0))
            if total is None:
                total = np.zeros((len(rows),) + part.shape[1:])
            total[sel] += part

        def nodes(pa, pb):
            return 0.5 * (pb - pa)[:, None] * _GL_X + 0.5 * (pa + pb)[:, None]

        pre = lo < self.t0                          # the constant past x0
        if pre.any():
            i = np.flatnonzero(pre)
            pa, pb = lo[i], np.minimum(hi[i], self.t0)
            S = nodes(pa, pb)
            X = np.broadcast_to(self._x0[rows[i]][:, None, :], (len(i), 5, self.n))
            add(i, pa, pb, X, S)
        start = np.maximum(lo, self.t0)
        covered = np.where(self._cnt[rows] > 0,
                           self._b[rows, np.maximum(self._cnt[rows] - 1, 0)], self.t0)
        late = hi > covered + 1e-12 * np.maximum(1.0, np.abs(hi))
        if late.any():
            i = int(np.flatnonzero(late)[0])
            raise HistoryError(f"history.integral: [{lo[i]}, {hi[i]}] reaches past the "
                               f"recorded run (up to t={covered[i]})")
        k = np.maximum(self._segments(start), 0)
        act = (hi > start) & (self._cnt[rows] > 0)
        while act.any():                            # one step of each row's window a pass
            i = np.flatnonzero(act)
            r, kk = rows[i], k[i]
            pa = np.maximum(self._a[r, kk], start[i])
            pb = np.minimum(self._b[r, kk], hi[i])
            use = pb > pa
            if use.any():
                iu, ru, ku = i[use], r[use], kk[use]
                S = nodes(pa[use], pb[use])
                h = self._dt[ru, ku]
                xx = (S - self._a[ru, ku][:, None]) / h[:, None]
                P = np.stack([xx, xx * xx, xx ** 3, xx ** 4], axis=-1)       # (r, 5, 4)
                X = self._ya[ru, ku][:, None, :] + h[:, None, None] * np.einsum(
                    "rnp,rsp->rsn", self._q[ru, ku], P)
                add(iu, pa[use], pb[use], X, S)
            k[i] += 1
            act[i] = (k[i] < self._cnt[r]) & (self._a[r, np.minimum(k[i], self._a.shape[1] - 1)]
                                              < hi[i])
        if total is None:
            total = np.zeros(len(rows))
        return np.where(flip.reshape((-1,) + (1,) * (total.ndim - 1)), -total, total)
