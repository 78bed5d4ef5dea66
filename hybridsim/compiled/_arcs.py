"""The compiled path's arcs and messages: a kernel's result (its cause and
detail codes, the numbers it reports in ``info``, its samples and counters)
as a :class:`~hybridsim.arc.HybridArc` and its termination message, in the
Python path's words (:data:`hybridsim.rules.DETAILS`).
"""
from __future__ import annotations

import numpy as np

from ..arc import HybridArc, _describe
from ..rules import CAUSES, CHATTER_RTOL, DETAILS, MapError, Termination, message

#: the Python path's stats keys, in its order
_STAT_KEYS = ("steps", "nfev", "njev", "nlu", "events", "flows", "rejected")
_SOLVER_REASON = "Required step size is less than spacing between numbers."   # scipy's words


def _map_error(system, k, detail, info, x, t, j):
    """``(text, map_name)`` of a map's contract breach, in the Python path's words:
    the map is evaluated again in Python at the point the kernel reports and
    its value checked by :func:`hybridsim.options.check_map_value`."""
    from ..options import check_map_value
    n = system.state_dim
    if detail == k.MAP_GUARD:
        name = "jump_guard" if info[2] == 1.0 else "flow_guard"
        return f"{name} returned NaN (at t={t:.10g}, j={j})", name
    from ._watch import MAP_WATCH
    if detail == MAP_WATCH:
        return f"watch returned non-finite values (at t={t:.10g}, j={j})", "watch"
    if detail == k.MAP_HISTORY:         # the Python path's HistoryError, in its words
        return (f"flow_map raised HistoryError: history: x({info[1]}) lies in the solver step "
                f"under way (recorded up to t={info[2]}); cap the step with max_step <= the "
                f"smallest delay (at t={t:.10g}, j={j})"), "flow_map"
    jumpish = detail in (k.MAP_JUMP_SHAPE, k.MAP_JUMP_VALUE, k.MAP_JUMP_X0)
    name = "jump_map" if jumpish else "flow_map"
    role = "jump" if jumpish else "flow"
    if role not in system.maps:
        return (f"the state is in the jump set at t={t:.10g}, j={j} but the system has no "
                f"jump map"), name
    try:
        p = system._p_nan if system.delays else system.params     # the past: unread here
        check_map_value(name, system.maps[role](np.array(x), t, j, p), n, t, j)
    except MapError as e:
        return str(e), name
    except Exception as e:  # noqa: BLE001 - the map raised in Python: say so
        return f"{name} raised {type(e).__name__}: {e} (at t={t:.10g}, j={j})", name
    m = int(info[2]) if info[2] == info[2] else n
    if m != n:
        return f"{name} must return an array of shape ({n},), got shape ({m},) " \
               f"(at t={t:.10g}, j={j})", name
    return f"{name} returned non-finite values (at t={t:.10g}, j={j})", name


#: ``_message``'s result for the plain ends (t_max, j_max): by cause code
_PLAIN_END = {CAUSES.index(c): (c, c.message, None) for c in (Termination.T_MAX,
                                                              Termination.J_MAX)}


def _plain(k, code, detail):
    """Whether a kernel's end is a plain t_max or j_max (its message the
    cause's sentence alone: no jump loop, jumps at one instant or chattering)."""
    return code == k.T_MAX or (code == k.J_MAX and detail not in (
        k.DETAIL_LOOP, k.DETAIL_INSTANT, k.DETAIL_CHATTER))


def _message(system, k, code, detail, info, T, J, X, stats, ro):
    """``(cause, message, exception)`` of a kernel's result: the words of
    :data:`hybridsim.rules.DETAILS` (:func:`hybridsim.rules.message`)."""
    if _plain(k, code, detail):
        return _PLAIN_END[code]
    cause = CAUSES[code]
    if (cause is Termination.J_MAX or cause is Termination.ZENO) and detail == k.DETAIL_LOOP:
        # a jump loop (rules.is_jump_loop): its jumps, all at one instant
        return cause, message(cause, "loop", count=int(info[2]), t=float(info[0])), None
    if cause is Termination.J_MAX and detail == k.DETAIL_INSTANT:
        return cause, message(cause, "instant", count=int(info[2]), t=float(info[0])), None
    if cause is Termination.J_MAX and detail == k.DETAIL_CHATTER:
        # rules.chatter_step's count, the longest flow before the last one, the last
        return cause, message(cause, "chatter", count=int(info[2]), rtol=CHATTER_RTOL,
                              longest=float(info[1]), flow=float(info[4]),
                              t=float(info[0])), None
    if cause is Termination.T_MAX or cause is Termination.J_MAX:
        return cause, cause.message, None
    t = float(info[0]) if info[0] == info[0] else float(T[-1])
    j = int(info[3]) if info[3] == info[3] else int(J[-1])
    x = X[-1]
    if cause is Termination.MAP_ERROR:
        text, name = _map_error(system, k, detail, info, X[-1], t, j)
        return cause, message(cause, error=text), MapError(text, name, t, j)
    if cause is Termination.CANCELED:
        return cause, message(cause, t=float(T[-1]), j=int(J[-1])), None
    if cause is Termination.ZENO:
        if detail == 0:
            return cause, message(cause, "zeno", count=int(info[2]), t=t), None
        if detail == 1:
            return cause, message(cause, "sticking", t=t, j=j, x=x,
                                  flows=[info[1], info[4], info[5]]), None
        return cause, message(cause, "short", t=t), None
    kind, fields = None, {"t": t, "j": j, "x": x}
    if cause is Termination.LEFT_SETS and detail == 1:
        kind = "left"
    elif cause is Termination.NON_FINITE:
        kind = ("step", "flow", "dense")[detail]
        if (cause, kind) not in DETAILS:
            kind = "step"
        fields["t2"] = float(info[1])
    elif cause is Termination.BLOWUP:
        fields.update(norm=float(info[2]), max_norm=ro.max_norm)
    elif cause is Termination.SOLVER_FAILED:
        fields["reason"] = _SOLVER_REASON
    elif cause is Termination.MAX_STEPS:
        kind = "steps" if detail == 0 else "samples"
        if detail != 0:             # the sample cap: where the last sample was stored
            fields["t"] = float(T[-1])
        fields.update(steps=int(stats[0]), max_steps=ro.max_steps, samples=len(T),
                      max_samples=ro.max_samples)
    return cause, message(cause, kind, **fields), None


def _stats(s):
    """An arc's ``stats`` from the kernel's (steps, rejected, nfev, events, flows, jumps)."""
    return {"steps": s[0], "nfev": s[2], "njev": 0, "nlu": 0, "events": s[3], "flows": s[4],
            "rejected": s[1]}


def _stats_of(ST, rows):
    """``i -> _stats(ST[rows[i]])`` (a pooled arc's, made on first access)."""
    return lambda i: _stats(ST[rows[i]].tolist())


def _arc(system, k, T, J, X, XD, code, detail, info, stats, ro):
    """The run's :class:`HybridArc`; a map's breach at x0 is raised at once (as
    on the Python path), with ``.arc`` (cause ``MAP_ERROR``) set."""
    cause, msg, exc = _message(system, k, code, detail, info, T, J, X, stats, ro)
    st = _stats(stats.tolist() if isinstance(stats, np.ndarray) else stats)
    # the kernels' own arrays: (N,) float64 t, int64 j, (N, n) float64 x and xdot
    desc = system._nb.get("description")
    if desc is None:
        system._nb["description"] = desc = _describe(system)
    arc = HybridArc._trusted(T, J, X, cause, msg, exc, system=system, xdot=XD, stats=st,
                             description=desc)
    if system.watch is not None:
        from ._watch import crossings_of
        arc.crossings = crossings_of(info, system.state_dim)
    if exc is not None:
        exc.arc = arc
    return arc


def _at_x0(k, arc, detail):
    """A map's breach at x0: raised at once by a single run (as on the Python path)."""
    return arc.termination is Termination.MAP_ERROR and (
        detail in (k.MAP_FLOW_X0, k.MAP_JUMP_X0) or (detail == k.MAP_GUARD and len(arc.t) == 1))
