"""The pieces of :mod:`hybridsim.sensitivity`'s variational system: central
differences (a Jacobian, a derivative in a scalar), a user's Jacobian
checked as a map, the check of ``wrt``, the components of an
interconnection that jump, the jump map with them fixed, and the guards at
their zero.
"""
from __future__ import annotations

import numpy as np

from .rules import MapError
from .system import as_map

_EPS = np.finfo(float).eps


def _fd_jac(fun, x, step):
    """Central differences of ``fun`` (x -> (k,)) at x: the (k, n) Jacobian."""
    cols = []
    for i in range(len(x)):
        d = step * max(1.0, abs(x[i]))
        xp, xm = x.copy(), x.copy()
        xp[i] += d
        xm[i] -= d
        cols.append((np.atleast_1d(np.asarray(fun(xp), dtype=float))
                     - np.atleast_1d(np.asarray(fun(xm), dtype=float))) / (xp[i] - xm[i]))
    return np.stack(cols, axis=-1)


def _fd_scalar(fun, s, step):
    """Central difference of ``fun`` (s -> array) in the scalar s."""
    d = step * max(1.0, abs(s))
    sp, sm = s + d, s - d
    return (np.atleast_1d(np.asarray(fun(sp), dtype=float))
            - np.atleast_1d(np.asarray(fun(sm), dtype=float))) / (sp - sm)


def _user_jac(system, name, shape_ok, what):
    """A user-given Jacobian as a checked callable of (x, t, j), or None."""
    fn = getattr(system, name, None)
    if fn is None:
        return None
    call = as_map(fn, name)

    def jac(x, t, j):
        # a MapError naming this map (the engine's wrappers pass it on as it is)
        try:
            v = call(x, t, j, None)
        except Exception as e:
            raise MapError(f"{name} raised {type(e).__name__}: {e} (at t={t:.10g}, j={j})",
                           name, t, j) from e
        try:
            v = np.asarray(v, dtype=float) if not np.iscomplexobj(v) else None
        except (TypeError, ValueError):
            v = None
        if v is None or not shape_ok(v.shape) or not np.all(np.isfinite(v)):
            got = "complex or non-numeric values" if v is None else f"shape {v.shape}"
            raise MapError(f"{name} must return finite real values of shape {what}, got "
                           f"{got} (at t={t:.10g}, j={j})", name, t, j)
        return v
    return jac


def _check_wrt(wrt, has_params):
    if isinstance(wrt, str):
        wrt = (wrt,)
    try:
        wrt = tuple(wrt)
    except TypeError:
        raise TypeError(f"wrt must be 'x0', 'params' or a tuple of them, got {wrt!r}") \
            from None
    if not wrt or any(w not in ("x0", "params") for w in wrt) or len(set(wrt)) != len(wrt):
        raise ValueError(f"wrt must be 'x0', 'params' or both, each once; got {wrt!r}")
    if "params" in wrt and not has_params:
        raise ValueError("wrt includes 'params' but no params were given: pass params=p "
                         "and system as a factory make_system(p) -> HybridSystem")
    return wrt


def _jumping(system, x, t, j):
    """The components of an interconnection that jump at (x, t, j) (None for
    another system)."""
    from .compose import Interconnection, _Outputs
    if not isinstance(system, Interconnection):
        return None
    y = _Outputs(system, x, t, j)
    return tuple(nm for nm, inD in system._in(system._D, x, t, j, y) if inD)


def _frozen_jump(system, maps, jumping):
    """``g(z, t, j)``: the jump map with the jumping components fixed.

    For an interconnection, the components ``jumping`` jump (each from the
    pre-jump outputs) and the others keep their state, whatever z: the map
    the event applies, differentiable across the edges of the components'
    jump sets. For another system, its jump map."""
    if jumping is None:
        return lambda z, t, j: maps.g(z, t, j, None)
    from .compose import _Outputs

    def g(z, t, j):
        y = _Outputs(system, z, t, j)
        out = np.array(z, dtype=float)
        for nm in jumping:
            sl = system._slices[nm]
            out[sl] = system._g[nm](z[sl], t, j, system._u(nm, z, t, j, y))
        return out
    return g


def _at_zero(hv, hdot, grad, x, t):
    """Which guard components are at their zero: within 1e-9 max(1, |t|) of
    time along the flow, or a few hundred ulp of their own scale."""
    scale = np.abs(grad) @ np.maximum(np.abs(x), 1.0)
    return np.abs(hv) <= 1e-9 * max(1.0, abs(t)) * np.abs(hdot) + 256 * _EPS * scale
