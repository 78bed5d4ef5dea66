"""The vectorized batch's maps: the system's maps called over batches of rows,
their values checked, a failing call retried row by row and its rows
recorded (``_VMaps``), and a value check's :class:`hybridsim.MapError` given
its row's t and j (``_located``). Used by :mod:`hybridsim.batch_vectorized`.
"""
from __future__ import annotations

import numpy as np

from .rules import MapError
from .system import as_map, guard_rows


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
