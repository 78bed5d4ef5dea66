"""The checks of an interconnection's component values: each component's flow
and jump values, outputs, guards, set indicators and inputs, over one state or
a batch of rows, with a :class:`hybridsim.MapError` naming the component
(``_state_value``, ``_rows_value``, ``_output_value``, ``_guard_rows``,
``_set_rows``, ``_input_value``, ``_in_component``) and a vectorized
component's flow or jump set (``_rows_set``). Used by
:mod:`hybridsim.compose`.
"""
from __future__ import annotations

import numpy as np

from .options import check_map_value
from .rules import MapError
from .system import as_map, guard_rows

# -- the components' values -----------------------------------------------------
# Each component's map values are checked before they are placed in its slice of
# the stacked state (numpy would otherwise stretch a scalar or a (1,) value over
# the slice, or fail with a broadcast error naming no component). The happy path
# costs a few attribute tests and one dot product per component and call.
_ND = np.ndarray


def _at(t, j, r=0):
    """(t, j) of row r of a batch (scalars as they are), as a float and an int."""
    try:
        tt = float(t if np.ndim(t) == 0 else np.ravel(t)[r])
        jj = int(j if np.ndim(j) == 0 else np.ravel(j)[r])
    except (TypeError, ValueError, IndexError):
        return None, None
    return tt, jj


def _state_value(nm, kind, v, n, t, j):
    """The slow path of a component's flow/jump value at one state: a float (n,)
    array, or a MapError naming the component (the standalone checks, reworded)."""
    try:
        return check_map_value(kind, v, n, *_at(t, j))
    except MapError as e:
        raise MapError(f"component {nm!r}: {e}", f"{nm}.{kind}", *_at(t, j)) from e


def _rows_value(nm, kind, v, k, n, t, j):
    """A component's flow/jump value over a batch of k rows: a float (k, n) array
    of finite reals, or a MapError naming the component (at the first bad row)."""
    name = f"{nm}.{kind}"
    what = f"component {nm!r}: {kind}"
    def at(r):
        tt, jj = _at(t, j, r)
        row = f": row {r} of the batch" if k > 1 else ""
        return tt, jj, ("" if tt is None else f" (at t={tt:.10g}, j={jj}{row})")

    tt, jj, where = at(0)
    if np.iscomplexobj(v):
        raise MapError(f"{what} returned complex values{where}: the state is real",
                       name, tt, jj)
    try:
        arr = np.asarray(v, dtype=float)
    except (TypeError, ValueError) as e:
        raise MapError(f"{what} must return an array of shape ({k}, {n}) (vectorized: one "
                       f"row per trajectory), got {type(v).__name__}{where}",
                       name, tt, jj) from e
    if arr.shape != (k, n):
        raise MapError(f"{what} must return an array of shape ({k}, {n}) (vectorized: one "
                       f"row per trajectory), got shape {arr.shape}{where}", name, tt, jj)
    fin = np.isfinite(arr).all(axis=1)
    if not fin.all():
        r = int(np.flatnonzero(~fin)[0])
        tt, jj, where = at(r)
        raise MapError(f"{what} returned non-finite values {arr[r]}{where}", name, tt, jj)
    return arr


def _bad_signal(nm, kind, v, accepted, t, j):
    """Raise the MapError for a component's output, guard or set value that is not
    real or has none of the ``accepted`` shapes (a description)."""
    name = f"{nm}.{kind}"
    tt, jj = _at(t, j)
    where = "" if tt is None else f" (at t={tt:.10g}, j={jj})"
    if np.iscomplexobj(v):
        raise MapError(f"component {nm!r}: {kind} returned complex values{where}: it must "
                       "be real", name, tt, jj)
    try:
        arr = np.asarray(v)
    except ValueError:              # ragged
        arr = np.asarray(v, dtype=object)
    if arr.dtype.kind not in "biuf":
        raise MapError(f"component {nm!r}: {kind} must return real numbers, got "
                       f"{type(v).__name__} of dtype {arr.dtype}{where}", name, tt, jj)
    raise MapError(f"component {nm!r}: {kind} must return {accepted}, got shape "
                   f"{arr.shape}{where}", name, tt, jj)


def _real_shape(v):
    """The shape of a real value (None where it is complex or not numeric)."""
    if np.iscomplexobj(v):
        return None
    try:
        arr = np.asarray(v)
    except ValueError:
        return None
    return arr.shape if arr.dtype.kind in "biuf" else None


def _output_value(nm, y, p, k, t, j):
    """A component's output: shape (p,) (or (k, p) over a batch of k rows), the last
    axis optional when p == 1; any 1-D (batch: (k,) or (k, m)) where ``output_dim``
    is not declared (p is None). Returns y, or raises a MapError naming it."""
    if y.__class__ is _ND and y.dtype.kind == "f":
        sh = y.shape
        if (sh == (k, p) if p is not None else len(sh) in (1, 2) and sh[0] == k) \
                if k is not None else (p is None and len(sh) <= 1):
            return y
    sh = _real_shape(y)
    if k is None:
        if p is None:
            ok, acc = sh is not None and len(sh) <= 1, "a scalar or a 1-D array"
        else:
            ok = sh == (p,) or (p == 1 and sh == ())
            acc = f"an array of shape ({p},)" + (" or a scalar" if p == 1 else "") + \
                f" (output_dim={p})"
    elif p is None:
        ok = sh is not None and len(sh) in (1, 2) and sh[0] == k
        acc = f"an array of shape ({k},) or ({k}, p) (vectorized: one row per trajectory)"
    else:
        ok = sh == (k, p) or (p == 1 and sh == (k,))
        acc = f"an array of shape ({k}, {p})" + (f" or ({k},)" if p == 1 else "") + \
            f" (output_dim={p}; vectorized: one row per trajectory)"
    if not ok:
        _bad_signal(nm, "output", y, acc, t, j)
    return y


def _guard_rows(nm, kind, v, k, t, j):
    """A component's guard over a batch of k rows, (k,) or (k, m): its (k,) minima."""
    if v.__class__ is _ND and v.dtype.kind == "f":
        sh = v.shape
        if sh == (k,):
            return v
        if len(sh) == 2 and sh[0] == k and sh[1] >= 1:
            return v.min(axis=1)
    sh = _real_shape(v)
    if sh == (k,) or (sh is not None and len(sh) == 2 and sh[0] == k and sh[1] >= 1):
        return guard_rows(v)
    _bad_signal(nm, kind, v, f"an array of shape ({k},) or ({k}, m) (vectorized: one row "
                             "per trajectory)", t, j)


def _set_rows(nm, kind, v, k, t, j):
    """A component's set indicator over a batch of k rows: a (k,) bool array."""
    if v.__class__ is _ND and v.shape == (k,):
        return v if v.dtype.kind == "b" else v.astype(bool)
    if _real_shape(v) == (k,):
        return np.asarray(v, dtype=bool)
    _bad_signal(nm, kind, v, f"a boolean array of shape ({k},) (vectorized: one entry per "
                             "trajectory)", t, j)


def _in_component(nm, e):
    """A component's MapError (raised inside its own maps) named by the component:
    ``component 'a': jump_guard ...``, ``map_name="a.jump_guard"``."""
    name = e.map_name or "map"
    if (isinstance(name, str) and (name.startswith(f"{nm}.") or name.startswith("inputs[")))\
            or str(e).startswith("component "):
        return e
    err = MapError(f"component {nm!r}: {e}", f"{nm}.{name}", e.t, e.j)
    err.__cause__ = e
    return err


def _input_value(nm, u, m, k, t, j):
    """A component's input from its ``inputs`` entry: shape (m,) (a batch of k
    rows: (k, m)), or a scalar ((k,) over a batch) where m == 1; real and
    finite. Returns u as it is, or raises a MapError naming ``inputs[nm]``."""
    name = f"inputs[{nm!r}]"
    sh = _real_shape(u)
    ok = (sh == (m,) or (m == 1 and sh == ())) if k is None else \
        (sh == (k, m) or (m == 1 and sh == (k,)))
    tt, jj = _at(t, j)
    where = "" if tt is None else f" (at t={tt:.10g}, j={jj})"
    if not ok:
        if np.iscomplexobj(u):
            raise MapError(f"{name} returned complex values{where}: component {nm!r} takes a "
                           f"real input", name, tt, jj)
        want = f"({m},)" + (" or a scalar" if m == 1 else "") if k is None else \
            f"({k}, {m})" + (f" or ({k},)" if m == 1 else "") + " (one row per trajectory)"
        got = f"shape {sh}" if sh is not None else f"{type(u).__name__} {u!r}"
        raise MapError(f"{name} must return the input of component {nm!r}, an array of shape "
                       f"{want} (its input_dim={m}), got {got}{where}", name, tt, jj)
    if not np.all(np.isfinite(u)):
        raise MapError(f"{name} returned non-finite values {u}{where}", name, tt, jj)
    return u


def _rows_set(nm, system, kind):
    """A vectorized component's flow or jump set over a batch, as an (N,) bool array
    (its indicator's or guard's value checked, the messages naming the component)."""
    guard = system.flow_guard if kind == "flow" else system.jump_guard
    if system._overrides(f"{kind}_set") or guard is None:
        test = as_map(getattr(system, f"{kind}_set"), f"{kind}_set")
        return lambda x, t, j, u: _set_rows(nm, f"{kind}_set", test(x, t, j, u), len(x), t, j)
    h = as_map(guard, f"{kind}_guard")
    return lambda x, t, j, u: _guard_rows(nm, f"{kind}_guard", h(x, t, j, u), len(x),
                                          t, j) >= 0.0
