"""Watched functions on the compiled path (rule 11 of :class:`hybridsim.HybridSystem`):
their crossings located in the run kernel's watching variant (imported only
when numba is installed).

The algorithm is :func:`hybridsim.events.watch_crossings`'s: each step's dense
output is sampled at :data:`hybridsim.events.WATCH_SAMPLES` interior points,
each sign change between neighbouring samples (:func:`hybridsim.events.crossing_sides`)
is shrunk to 4 ulp by the guards' safeguarded secant
(:func:`hybridsim.events.secant_of`'s, compiled from its one source), and the
zero a flow starts on is dropped (:func:`hybridsim.events.starts_on_zero`).
Nothing of this is in the plain run kernel: only
:data:`hybridsim.compiled._kernel.run_one_watch` (the run core with its
constant ``_WATCH`` set), compiled when a watching system first runs, calls it.

The watching kernel takes the watched functions' address as the seventh
entry of ``maps`` and their directions after the delays in ``fopt``; it
returns the crossings in its ``info`` after the six message floats, one
record of ``4 + n`` floats each: ``t, j, which, direction, x``
(:func:`crossings_of`).
"""
from __future__ import annotations

import numba
import numpy as np
from numba import njit, types
from numba.extending import overload, register_jitable

from .. import events, rules
from ._steps import _dense_to
from ._types import _NJ, _NJI, _NJL, CACHE, MAP_ERROR, VEC_SIG, as_vec

for _fn in (events.crossing_sides, events.starts_on_zero):
    register_jitable(_fn)

#: the message floats of a kernel's ``info`` before the crossings' records
INFO_HEAD = 6
#: the MAP_ERROR detail of watched functions whose values are not finite, or
#: whose number changed (after :data:`hybridsim.compiled._types.MAP_HISTORY`)
MAP_WATCH = 7
_SAMPLES = events.WATCH_SAMPLES


def as_watch(v):
    """The watched functions' value as a float64 array (compiled code only): a
    number (or a 0-d array) is one value."""
    raise NotImplementedError


@overload(as_watch)
def _ov_as_watch(v):
    if isinstance(v, (types.Float, types.Integer, types.Boolean)):
        return lambda v: np.full(1, np.float64(v))
    if isinstance(v, types.Array) and v.ndim == 0:
        return lambda v: np.full(1, np.float64(v[()]))
    return lambda v: as_vec(v)


def wrap_watch(fn):
    """``fn(x, t, j, p)`` compiled to the kernel's vector signature."""
    jf = fn if isinstance(fn, numba.core.dispatcher.Dispatcher) else njit(**_NJ)(fn)

    def w(x, t, j, p):
        return as_watch(jf(x, t, j, p))
    return njit(VEC_SIG, **_NJ)(w)


# inlined into the secant, as compiled._events._phi_at
@njit(inline="always", **_NJI)
def _watched_at(E, s):
    """``sg * W(s, y(s))[k]`` at time s of a step's dense output, for
    :func:`_secant`: ``E = (W, k, sg, yold, hQ, told, h, j, p, wk)``, the state
    written into ``wk``."""
    W, k, sg, yold, hQ, told, h, j, p, wk = E
    _dense_to(wk, yold, hQ, told, h, s)
    return sg * W(wk, s, j, p)[k]


#: the guards' secant on the watched functions (compiled into :func:`watch_step`)
_secant = njit(**_NJI)(events.secant_of(_watched_at))


@njit(cache=CACHE, **_NJI)
def watch_values(W, x, t, j, p, m):
    """``(W(x, t, j, p), ok)``: ``ok`` false where its values are not ``m``
    finite floats."""
    v = W(x, t, j, p)
    if v.shape[0] != m:
        return v, False
    for q in range(m):
        if not np.isfinite(v[q]):
            return v, False
    return v, True


@njit(cache=CACHE, **_NJI)
def watch_step(W, dirs, yold, hQ, told, h, a, ya, wa, b, yb, j, p, floor, CR, nc, P, Y, V):
    """The crossings of the watched functions on the flow from ``(a, ya)``
    (values ``wa``) to ``(b, yb)`` along one step's dense output (``yold``,
    ``hQ``, ``told``, ``h``): :func:`hybridsim.events.watch_crossings`,
    appended to the records ``CR`` (rows ``nc:``, grown as needed; each step's
    in time order, then by function). ``P``, ``Y``, ``V``: the run's scratch
    for the samples' times, states and values (:func:`scratch`).

    Returns ``(CR, nc, wb, ok)``: ``wb`` the values at b; ``ok`` false where a
    value is not finite or their number changed (the run's MAP_ERROR)."""
    m = wa.shape[0]
    wb, ok = watch_values(W, yb, b, j, p, m)
    if not ok or not b > a:
        return CR, nc, wb, ok
    P[0] = a
    Y[0] = ya
    V[0] = wa
    hh = b - a
    for i in range(1, _SAMPLES + 1):
        s = a + hh * (i / (_SAMPLES + 1.0))
        _dense_to(Y[i], yold, hQ, told, h, s)
        v, ok = watch_values(W, Y[i], s, j, p, m)
        if not ok:
            return CR, nc, wb, False
        P[i] = s
        V[i] = v
    P[_SAMPLES + 1] = b
    Y[_SAMPLES + 1] = yb
    V[_SAMPLES + 1] = wb
    n0 = nc
    wk = Y[_SAMPLES + 2]
    for i in range(_SAMPLES + 1):
        for k in range(m):
            up, down = events.crossing_sides(V[i, k], V[i + 1, k], dirs[k])
            if not (up or down):
                continue
            sg = 1.0 if up else -1.0
            _, tc = _secant((W, k, sg, yold, hQ, told, h, j, p, wk), P[i], P[i + 1],
                            sg * V[i, k], sg * V[i + 1, k], False, np.nan, np.nan)
            if events.starts_on_zero(floor, tc, rules.event_tolerance(floor, tc)):
                continue
            if nc == CR.shape[0]:
                grown = np.empty((2 * CR.shape[0], CR.shape[1]))
                grown[:nc] = CR[:nc]
                CR = grown
            CR[nc, 0] = tc
            CR[nc, 1] = j
            CR[nc, 2] = k
            CR[nc, 3] = sg
            if tc == P[i + 1]:
                CR[nc, 4:] = Y[i + 1]
            else:
                _dense_to(wk, yold, hQ, told, h, tc)
                CR[nc, 4:] = wk
            nc += 1
    # the step's crossings by (t, which), as watch_crossings sorts them
    for r in range(n0 + 1, nc):
        q = r
        while q > n0 and (CR[q, 0] < CR[q - 1, 0] or (
                CR[q, 0] == CR[q - 1, 0] and CR[q, 2] < CR[q - 1, 2])):
            row = CR[q].copy()
            CR[q] = CR[q - 1]
            CR[q - 1] = row
            q -= 1
    return CR, nc, wb, True


@njit(cache=CACHE, **_NJI)
def scratch(n, m):
    """``(P, Y, V)``: a run's scratch for :func:`watch_step` (n states, m functions;
    the samples' times, states and values, and a trial point's state in ``Y``'s last row)."""
    return np.empty(_SAMPLES + 2), np.empty((_SAMPLES + 3, n)), np.empty((_SAMPLES + 2, m))


@njit(cache=CACHE, **_NJL)
def watch_fault(info, s, j):
    """A watched value that is not finite at (s, j): ``info`` written, the run's
    ``(cause, detail)`` returned (MAP_ERROR, :data:`MAP_WATCH`)."""
    info[0] = s
    info[3] = j
    return MAP_ERROR, MAP_WATCH


@njit(cache=CACHE, **_NJI)
def with_crossings(info, CR, nc):
    """``info`` followed by the records ``CR[:nc]``, flattened."""
    w = CR.shape[1]
    out = np.empty(info.shape[0] + nc * w)
    out[:info.shape[0]] = info
    for r in range(nc):
        out[info.shape[0] + r * w:info.shape[0] + (r + 1) * w] = CR[r]
    return out


def watch_options(system, x0, t0, j0, fopt, p=None):
    """The kernel's ``fopt`` followed by the watched functions' directions, one
    per value the system's watch returns at x0 (with ``p``, default the
    system's params); a value there that is not
    finite raises :class:`hybridsim.MapError` naming ``watch``, in the Python
    path's words."""
    from ..rules import MapError
    from ..system import watch_directions
    v = system._nb["W"].disp(x0, float(t0), int(j0), system.params if p is None else p)
    if not np.isfinite(v).all():
        raise MapError(f"watch returned non-finite values {v} (at the initial state, "
                       f"t={t0:.10g}, j={j0})", "watch", t0, j0)
    d = watch_directions(system.watch_direction, len(v), t0, j0)
    return np.concatenate([fopt, d.astype(np.float64)])


def crossings_of(info, n):
    """The :class:`hybridsim.arc.Crossings` of a watching kernel's ``info``."""
    from ..arc import Crossings
    rec = np.asarray(info[INFO_HEAD:], dtype=float).reshape(-1, 4 + n)
    return Crossings(rec[:, 0], rec[:, 1].astype(np.int64), rec[:, 2].astype(np.int64),
                     rec[:, 3].astype(np.int64), rec[:, 4:].copy())
