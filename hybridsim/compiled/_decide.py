"""The decision loop's compiled steps that both run kernels take (imported only
when numba is installed): the ODE run core (:mod:`._kernel`) and the SDE
stepper (:mod:`._sde_flow`).

The jump-or-flow decision at a point, the bookkeeping of a jump and the
cause it may end the run with (``_Run._jump``), and the cause of a run that
stops outside C ∪ D (``_Run._stop_outside``), each with the rules of
:mod:`hybridsim.rules` as they are.
"""
from __future__ import annotations

from numba import njit

from .. import rules
from ._types import (
    _GOES_ON,
    _NJI,
    _NJL,
    CACHE,
    DETAIL_CHATTER,
    DETAIL_INSTANT,
    DETAIL_LOOP,
    J_MAX,
    LEFT_SETS,
    NOT_IN_SETS,
    ZENO,
    _coin,
)


@njit(cache=CACHE, **_NJL)
def decide_at(in_C, in_D, prio, rngp):
    """:func:`hybridsim.rules.decide` at a point in C (``in_C``) and D (``in_D``),
    its coin (``priority="random"`` in C ∩ D) drawn from the run's Generator
    (``rngp``, :func:`._types.rng_pointers`) only where it is read."""
    coin = False
    if rules.needs_coin(in_C, in_D, prio, False):
        coin = _coin(rngp)
    return rules.decide(in_C, in_D, prio, coin, False)


@njit(cache=CACHE, **_NJL)
def jump_books(flows_last, n_fl, t, t_last_jump, jumps, from_C, zref, short, longest, tiny,
               same, loop, zeno_time, zeno_rtol):
    """The record of a jump at ``t`` (``_Run._jump``): the last (up to) 4 flow
    lengths in ``flows_last`` (oldest first, ``n_fl`` of them), the Zeno streak
    (:func:`hybridsim.rules.zeno_short`), the chattering count
    (:func:`hybridsim.rules.chatter_step`) and the jumps at one instant
    (``same``; ``loop``: those from C).

    Returns ``(n_fl, zref, short, longest, longest_before, tiny, same, loop,
    flow)``."""
    flow = t - t_last_jump
    if n_fl == 4:
        flows_last[0] = flows_last[1]
        flows_last[1] = flows_last[2]
        flows_last[2] = flows_last[3]
        flows_last[3] = flow
    else:
        flows_last[n_fl] = flow
        n_fl += 1
    is_short, zref = rules.zeno_short(flows_last, n_fl, t, zref, zeno_time, zeno_rtol)
    short = short + 1 if is_short else 0
    longest_before = longest
    longest, tiny = rules.chatter_step(flow, longest, tiny)
    instant = flow == 0.0 and jumps > 0
    same = same + 1 if instant else 0
    loop = loop + 1 if (from_C and instant) else 0
    return n_fl, zref, short, longest, longest_before, tiny, same, loop, flow


@njit(cache=CACHE, **_NJL)
def jump_cause(jumps, short, j_max, zeno_jumps, loop, same, tiny, t, longest_before, flow, info):
    """The cause a run ends with after its ``jumps``-th jump at ``t``
    (:func:`hybridsim.rules.after_jump`; ``_GOES_ON``: none) and its detail code,
    the message's values written into ``info`` (t, longest, count, _, flow)."""
    c = rules.after_jump(jumps, short, j_max, zeno_jumps)
    detail = 0
    if c != _GOES_ON:
        info[0] = t
        info[2] = short
        if rules.is_jump_loop(loop, zeno_jumps):
            # the jumps of the loop and the one that started it, all at t
            detail = DETAIL_LOOP
            info[2] = loop + 1
        elif c == J_MAX and rules.is_jump_loop(same, zeno_jumps):
            detail = DETAIL_INSTANT      # jumps at t, not all from C
            info[2] = same + 1
        elif c == J_MAX and rules.is_jump_loop(tiny, zeno_jumps):
            detail = DETAIL_CHATTER
            info[1] = longest_before
            info[2] = tiny
            info[4] = flow
    return c, detail


@njit(cache=CACHE, **_NJI)
def stop_outside(ns, t0, t, t_max, j, flows_last, n_fl, t_last_jump, jumps, info, detail):
    """``_Run._stop_outside``: the cause of a run that stopped outside C ∪ D at
    ``(t, j)`` after ``ns`` samples (x0 outside both sets, sticking to the
    sets' boundary, or leaving C ∪ D) and its detail code (``detail``, the
    stop's own, is kept when the run left the sets: 1 says the flow left C
    outside D); ``info`` gets t, j and, when sticking, the last three flows."""
    if ns == 1:
        cause = NOT_IN_SETS
        detail = 0
    else:
        scale = rules.time_scale(t0, t, t_max)
        if rules.is_sticking(flows_last[:n_fl], t - t_last_jump, jumps, scale):
            cause = ZENO
            detail = 1
            info[1] = flows_last[n_fl - 3]
            info[4] = flows_last[n_fl - 2]
            info[5] = flows_last[n_fl - 1]
        else:
            cause = LEFT_SETS
    info[0] = t
    info[3] = j
    return cause, detail
