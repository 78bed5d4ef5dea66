"""The private machinery of a :class:`hybridsim.HybridArc`'s access to its
states: the interpolation behind :meth:`~hybridsim.HybridArc.at` and
:meth:`~hybridsim.HybridArc.interpolate` (stored sample, dense output, cubic
Hermite, linear) and the windows of hybrid time behind
:meth:`~hybridsim.HybridArc.restrict` and :meth:`~hybridsim.HybridArc.select`,
the map of :meth:`~hybridsim.HybridArc.transform`, and the dense outputs of
slices and maps of the state. A base class of :class:`hybridsim.HybridArc`;
it holds no data of its own.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from ._arc_records import ArcValues
from .rules import Termination

_AT_JUMP = ("start", "end", "mean", "nan", "both")



def between_samples(t, x, xdot, k0, tq):
    """The states at times ``tq`` strictly inside the steps ``[t[k0], t[k0 + 1]]``
    of samples ``(t, x, xdot)``: the cubic Hermite of the step's ends where both
    derivatives are finite (``xdot`` given), else linear. Written from x0, so a
    constant component stays exact."""
    x0, x1 = x[k0], x[k0 + 1]
    h = (t[k0 + 1] - t[k0])[:, None]
    s = ((tq - t[k0]) / (t[k0 + 1] - t[k0]))[:, None]
    val = (1 - s) * x0 + s * x1
    if xdot is not None:
        m0, m1 = xdot[k0], xdot[k0 + 1]
        herm = np.all(np.isfinite(m0), axis=1) & np.all(np.isfinite(m1), axis=1)
        if herm.any():
            s2 = s * s
            hv = (x0 + s2 * (3 - 2 * s) * (x1 - x0)
                  + s * (1 - s) ** 2 * h * m0 + s2 * (s - 1) * h * m1)
            val[herm] = hv[herm]
    return val

class _ArcAccess:
    """Interpolation, windows of hybrid time and maps of the state (a base of
    :class:`HybridArc`)."""

    def _dense_index(self):
        """``{j: (starts, ends, sols)}`` of the dense segments, built once."""
        idx = self._cache.get("dense")
        if idx is None:
            by_j = {}
            for a, b, jj, sol in self._segments or ():
                by_j.setdefault(int(jj), ([], [], []))
                by_j[int(jj)][0].append(a)
                by_j[int(jj)][1].append(b)
                by_j[int(jj)][2].append(sol)
            idx = {k: (np.asarray(s, float), np.asarray(e, float), f)
                   for k, (s, e, f) in by_j.items()}
            self._cache["dense"] = idx
        return idx

    def _call_dense(self, sol, ts):
        """Values of one dense output at times ``ts`` (m,), as (m, n)."""
        n = self.state_dim
        if len(ts) > 1:
            try:
                y = np.asarray(sol(ts), dtype=float)
                if y.shape == (n, len(ts)):
                    return y.T
            except Exception:  # noqa: BLE001 - a callable of scalars only: one call per time
                pass
        return np.array([np.asarray(sol(s), dtype=float).reshape(n) for s in ts])

    def _interp(self, t, j, where, deriv=False):
        """State (and d/dt where known) at the points (t[i], j[i]), 1-D arrays.

        Best available: the stored sample at its own time; the dense output;
        cubic Hermite where both neighbours have a finite xdot; else linear.
        Every point is located at once (the samples are sorted in hybrid
        time); only the flows with a dense output are visited one by one.
        """
        m, n = len(t), self.state_dim
        out = np.empty((m, n))
        dout = np.full((m, n), np.nan) if deriv else None
        if m == 0:
            return out, dout
        self._nonempty(where)
        a = np.searchsorted(self.j, j, side="left")
        b = np.searchsorted(self.j, j, side="right")
        have = a < b
        first, last = np.minimum(a, len(self.t) - 1), np.maximum(b - 1, 0)
        bad = ~have | (t < self.t[first]) | (t > self.t[last])
        if bad.any():
            jj = int(np.min(j[bad]))                # the first j in order that fails
            if not have[bad & (j == jj)].any():
                raise ValueError(f"{where}: the arc has no sample with j={jj} "
                                 f"(j runs from {self.j[0]} to {self.j[-1]})")
            i = int(np.flatnonzero(bad & (j == jj))[0])
            raise ValueError(
                f"{where}: (t={t[i]}, j={jj}) is not in the hybrid time "
                f"domain (for j={jj}, t lies in [{self.t[first[i]]}, {self.t[last[i]]}])")
        # the last sample of the flow at or before t (t is nondecreasing on the arc)
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, a, b - 1)
        exact = self.t[k] == t
        out[exact] = self.x[k[exact]]
        if deriv and self.xdot is not None:
            dout[exact] = self.xdot[k[exact]]
        rest = np.flatnonzero(~exact)
        if rest.size == 0:
            return out, dout
        k0 = k[rest]                    # t strictly between samples k0 and k0 + 1
        tr = t[rest]
        val = between_samples(self.t, self.x, self.xdot, k0, tr)
        if deriv and self.xdot is not None:
            x0, x1 = self.x[k0], self.x[k0 + 1]
            h = (self.t[k0 + 1] - self.t[k0])[:, None]
            s = ((tr - self.t[k0]) / (self.t[k0 + 1] - self.t[k0]))[:, None]
            m0, m1 = self.xdot[k0], self.xdot[k0 + 1]
            herm = np.all(np.isfinite(m0), axis=1) & np.all(np.isfinite(m1), axis=1)
            if herm.any():
                s2 = s * s
                hd = ((6 * s2 - 6 * s) * (x0 - x1) / h
                      + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1)
                dout[rest[herm]] = hd[herm]
        if self._segments:
            dense = self._dense_index()
            jr = j[rest]
            for jj in np.unique(jr):
                if int(jj) not in dense:
                    continue
                starts, ends, sols = dense[int(jj)]
                on = np.flatnonzero(jr == jj)
                q = np.searchsorted(starts, tr[on], side="right") - 1
                cov = (q >= 0) & (tr[on] <= ends[np.maximum(q, 0)])
                for sq in np.unique(q[cov]):
                    pick = on[cov & (q == sq)]
                    val[pick] = self._call_dense(sols[sq], tr[pick])
        out[rest] = val
        return out, dout

    def _hybrid_times(self, t, j, where):
        """Validate (t, j) of :meth:`at` into flat arrays; j=None: after jumps."""
        try:
            tt = np.asarray(t, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(f"{where}: t must be a float or an array of floats, "
                            f"got {type(t).__name__}") from None
        flat = tt.ravel()
        if not np.all(np.isfinite(flat)):
            raise ValueError(f"{where}: t must be finite, got {flat[~np.isfinite(flat)][0]}")
        self._nonempty(where)
        if j is None:
            k = np.searchsorted(self.t, flat, side="right") - 1
            out = (k < 0) | (flat > self.t[-1])
            if out.any():
                raise ValueError(f"{where}: t={flat[out][0]} is outside the arc's time "
                                 f"range [{self.t[0]}, {self.t[-1]}]")
            jf = self.j[k]
        else:
            jarr = np.asarray(j)
            if jarr.dtype.kind not in "iuf" or (jarr.dtype.kind == "f" and not np.all(
                    np.mod(jarr, 1) == 0)):
                raise TypeError(f"{where}: j must be an int or an array of ints, got {j!r}")
            try:
                jf = np.broadcast_to(jarr.astype(np.int64), tt.shape).ravel()
            except ValueError:
                raise ValueError(f"{where}: j must be a scalar or have the shape of t "
                                 f"{tt.shape}, got shape {jarr.shape}") from None
        return tt, flat, jf

    def _at_scalar(self, t, j):
        """:meth:`at` for one float t and an int j or None (the fast path)."""
        T = self.t
        if not math.isfinite(t):
            raise ValueError(f"at: t must be finite, got {t}")
        self._nonempty("at")
        if j is None:
            k = int(np.searchsorted(T, t, side="right")) - 1
            if k < 0 or t > T[-1]:
                raise ValueError(f"at: t={t} is outside the arc's time range "
                                 f"[{T[0]}, {T[-1]}]")
            j = int(self.j[k])
        else:
            j = int(j)
        a = int(np.searchsorted(self.j, j, side="left"))
        b = int(np.searchsorted(self.j, j, side="right"))
        if a == b:
            raise ValueError(f"at: the arc has no sample with j={j} "
                             f"(j runs from {self.j[0]} to {self.j[-1]})")
        if t < T[a] or t > T[b - 1]:
            raise ValueError(f"at: (t={t}, j={j}) is not in the hybrid time domain "
                             f"(for j={j}, t lies in [{T[a]}, {T[b - 1]}])")
        k = a + int(np.searchsorted(T[a:b], t, side="right")) - 1
        if T[k] == t:
            return self.x[k].copy()
        if self._segments:
            seg = self._dense_index().get(j)
            if seg is not None:
                q = int(np.searchsorted(seg[0], t, side="right")) - 1
                if q >= 0 and t <= seg[1][q]:
                    return np.asarray(seg[2][q](t), dtype=float).reshape(self.state_dim)
        h = T[k + 1] - T[k]
        w = (t - T[k]) / h
        x0, x1 = self.x[k], self.x[k + 1]
        if self.xdot is not None:
            m0, m1 = self.xdot[k], self.xdot[k + 1]
            if np.isfinite(m0).all() and np.isfinite(m1).all():
                w2 = w * w
                return ((1 + 2 * w) * (1 - w) ** 2 * x0 + w * (1 - w) ** 2 * h * m0
                        + w2 * (3 - 2 * w) * x1 + w2 * (w - 1) * h * m1)
        return (1 - w) * x0 + w * x1

    def _interpolate(self, t_grid, at_jump):
        """:meth:`HybridArc.interpolate`."""
        if at_jump not in _AT_JUMP:
            raise ValueError(f"interpolate: at_jump must be one of {_AT_JUMP}, "
                             f"got {at_jump!r}")
        try:
            tg = np.asarray(t_grid, dtype=float)
        except (TypeError, ValueError):
            raise TypeError("interpolate: t_grid must be a 1-D array of floats, got "
                            f"{type(t_grid).__name__}") from None
        if tg.ndim == 0:
            tg = tg.reshape(1)
        if tg.ndim != 1:
            raise ValueError(f"interpolate: t_grid must be 1-D, got shape {tg.shape}")
        if not np.all(np.isfinite(tg)):
            raise ValueError("interpolate: t_grid must be finite, got "
                             f"{tg[~np.isfinite(tg)][0]}")
        if np.any(np.diff(tg) < 0):
            k = int(np.flatnonzero(np.diff(tg) < 0)[0])
            raise ValueError(f"interpolate: t_grid must be sorted (non-decreasing); "
                             f"t_grid[{k + 1}] = {tg[k + 1]} < t_grid[{k}] = {tg[k]}")
        self._nonempty("interpolate")
        if tg.size and (tg[0] < self.t[0] or tg[-1] > self.t[-1]):
            v = tg[0] if tg[0] < self.t[0] else tg[-1]
            raise ValueError(f"interpolate: t_grid value {v} is outside the arc's time "
                             f"range [{self.t[0]}, {self.t[-1]}]")
        j_start = self.j[np.searchsorted(self.t, tg, side="left")]
        j_end = self.j[np.searchsorted(self.t, tg, side="right") - 1]
        if at_jump == "both":
            rep = 1 + (j_start != j_end)
            t_out = np.repeat(tg, rep)
            j_out = np.repeat(j_end, rep)
            first = np.cumsum(rep) - rep
            j_out[first] = j_start
            x, _ = self._interp(t_out, j_out, "interpolate")
            return ArcValues(t_out, j_out, x)
        if at_jump == "start":
            x, _ = self._interp(tg, j_start, "interpolate")
            return ArcValues(tg, j_start, x)
        x, _ = self._interp(tg, j_end, "interpolate")
        jumps = j_start != j_end
        if jumps.any():
            if at_jump == "nan":
                x[jumps] = np.nan
            elif at_jump == "mean":
                xs, _ = self._interp(tg[jumps], j_start[jumps], "interpolate")
                x[jumps] = 0.5 * (x[jumps] + xs)
        return ArcValues(tg, j_end, x)

    def _subset(self, mask):
        mask = np.asarray(mask, dtype=bool)
        return self._like(self.t[mask], self.j[mask], self.x[mask],
                          xdot=None if self.xdot is None else self.xdot[mask])

    @staticmethod
    def _window(w, what, where, integer):
        """``(lo, hi)`` from a pair (None: unbounded) or, for j, one int."""
        if w is None:
            return -math.inf, math.inf
        if integer and isinstance(w, (numbers.Integral, np.integer)) \
                and not isinstance(w, bool):
            return int(w), int(w)
        if isinstance(w, (str, bytes)) or np.ndim(w) != 1 or len(w) != 2:
            kind = "an int or a pair (lo, hi) of ints" if integer else \
                "a pair (a, b) of times (a closed interval)"
            hint = "" if integer else (
                f"; for the state at one time use arc.at({w!r})"
                if isinstance(w, numbers.Real) else "")
            raise TypeError(f"{where}: {what} must be {kind}, got {w!r}{hint}")
        lo, hi = w
        out = []
        for v, inf in ((lo, -math.inf), (hi, math.inf)):
            if v is None:
                out.append(inf)
                continue
            if not isinstance(v, (numbers.Real, np.integer, np.floating)) \
                    or isinstance(v, bool) or math.isnan(v):
                raise TypeError(f"{where}: {what} bounds must be numbers or None, "
                                f"got {w!r}")
            if integer and v != math.floor(v) and math.isfinite(v):
                raise TypeError(f"{where}: {what} bounds must be ints, got {w!r}")
            out.append(float(v))
        if out[0] > out[1]:
            raise ValueError(f"{where}: {what} = {w!r} is empty (lower bound above "
                             f"upper bound)")
        return out[0], out[1]

    def _restrict(self, t, j, where):
        a, b = self._window(t, "t", where, integer=False)
        lo, hi = self._window(j, "j", where, integer=True)
        mask = (self.t >= a) & (self.t <= b) & (self.j >= lo) & (self.j <= hi)
        extra_t = []
        if len(self.t):
            for s in sorted({a, b}):
                if not (self.t[0] < s < self.t[-1]):
                    continue
                k = int(np.searchsorted(self.t, s, side="right")) - 1
                if self.t[k] != s and lo <= self.j[k] <= hi:
                    extra_t.append(s)  # strictly inside the flow of sample k
        if not extra_t:
            return self._subset(mask)
        et = np.array(extra_t)
        ej = self.j[np.searchsorted(self.t, et, side="right") - 1]
        ex, ed = self._interp(et, ej, where, deriv=self.xdot is not None)
        idx = np.flatnonzero(mask)
        T = np.concatenate((self.t[idx], et))
        J = np.concatenate((self.j[idx], ej))
        X = np.concatenate((self.x[idx], ex))
        order = np.lexsort((J, T))
        XD = None if self.xdot is None else np.concatenate((self.xdot[idx], ed))[order]
        return self._like(T[order], J[order], X[order], xdot=XD)

    def _transform(self, fn):
        """:meth:`HybridArc.transform`."""
        from .system import as_map
        f = as_map(fn, "transform: fn")

        def row(x, t, j, k=None):
            y = np.asarray(f(x, t, j, None))
            place = (f"(t={float(t)!r}, j={int(j)})" if k is None
                     else f"sample {k} (t={float(t)!r}, j={int(j)})")
            if np.iscomplexobj(y):
                raise ValueError(f"transform: fn returned complex values at t={t}, j={j}")
            if y.ndim > 1:
                raise ValueError(f"transform: fn must return a scalar or a 1-D array, "
                                 f"got shape {y.shape} at t={t}, j={j}")
            try:
                y = np.atleast_1d(y).astype(float)
            except (TypeError, ValueError):
                raise ValueError(f"transform: fn must return numbers, got {y!r} at "
                                 f"{place}") from None
            # NaN/inf only where validate allows them: a NON_FINITE run's last sample
            if not np.isfinite(y).all() and not (k is not None and k == last
                                                  and not np.isfinite(x).all()):
                raise ValueError(f"transform: fn returned non-finite values {y} at {place}; "
                                 f"a transformed arc holds finite states only")
            return y

        last = len(self.t) - 1 if self.termination is Termination.NON_FINITE else None
        rows = [row(x, t, j, k) for k, (x, t, j) in enumerate(zip(self.x, self.t, self.j))]
        if rows and len({r.shape for r in rows}) > 1:
            raise ValueError("transform: fn must return arrays of one length, got "
                             f"lengths {sorted({len(r) for r in rows})}")
        X = np.array(rows, dtype=float) if rows else np.zeros((0, 0))
        segs = None if not self._segments else [
            (a, b, jj, _Mapped(sol, row, jj)) for (a, b, jj, sol) in self._segments]
        arc = self._like(self.t, self.j, X, keep=False, segments=segs)
        arc.system_description = None
        return arc


class _Sliced:
    """A dense output restricted to a slice of the state."""

    __slots__ = ("sol", "sl")

    def __init__(self, sol, sl):
        self.sol, self.sl = sol, sl

    def __call__(self, t):
        return np.asarray(self.sol(t))[self.sl]


class _Mapped:
    """A dense output mapped through ``fn(x, t, j)`` (see :meth:`HybridArc.transform`)."""

    __slots__ = ("sol", "fn", "j")

    def __init__(self, sol, fn, j):
        self.sol, self.fn, self.j = sol, fn, j

    def __call__(self, t):
        if np.ndim(t) == 0:
            return self.fn(np.asarray(self.sol(t), dtype=float), float(t), self.j)
        t = np.asarray(t, dtype=float)
        return np.stack([self.fn(np.asarray(self.sol(s), dtype=float), float(s), self.j)
                         for s in t], axis=1)
