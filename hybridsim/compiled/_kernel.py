"""The compiled path's run core (imported only when numba is installed).

Everything here runs in nopython mode. The user's maps reach the kernels as
numba *first-class functions* of fixed signatures (:mod:`._types`), so the
kernels are compiled once and cached on disk (``cache=True``) for every
system; only the small wrappers of each system's own maps are compiled per
system. From Python they are passed by address (an int64 array,
:func:`._types.map_addresses`), as are the Ctrl-C poll and the numpy
Generator: numba's unboxing of a first-class function or Generator argument
costs microseconds per call.

The run core is compiled as the engine's run kernels (:mod:`._variants`:
one per setting of its constants ``_DELAYS``, ``_DOP``, ``_RK4`` and ``_WATCH``,
below);
a system with ``specialize=True`` gets its own copy in a generated module
(:mod:`._cache`), whose globals are this module's.

The run core's options arrive in two arrays, ``fopt`` and ``iopt``, packed
and read by the names of :mod:`._layout`. The rules (priorities, the
jump-or-flow decision, event tolerances, the t_max slack, short flows, the
time scale) are :mod:`hybridsim.rules`'s own functions; the steps, events and
the past are :mod:`._steps`', :mod:`._events`' and :mod:`._past`'s. The run
core is the port of the decision loop of :func:`hybridsim.simulate`
(``_Run.run``, ``_flow``, ``_event``, ``_event_past_t_max``, ``_jump``,
``_stop_outside``).
"""
from __future__ import annotations

import numpy as np
from numba import types
from numba.typed import List

from .. import rules
from ._decide import decide_at, jump_books, jump_cause, stop_outside
from ._events import _event, _inC, _inD, _interior, _near_C, _pred
from ._layout import (
    F_DELAYS,
    F_FIRST_STEP,
    F_J_MAX,
    F_MAX_NORM,
    F_MAX_STEP,
    F_RTOL,
    F_T0,
    F_T_MAX,
    F_ZENO_RTOL,
    F_ZENO_TIME,
    I_C_FROM_GUARD,
    I_CAP,
    I_D_FROM_GUARD,
    I_HAS_C,
    I_HAS_D,
    I_HAS_HC,
    I_HAS_HD,
    I_J0,
    I_MAX_SAMPLES,
    I_MAX_STEPS,
    I_N_DELAYS,
    I_PRIO,
    I_REFINE,
    I_ROW,
    I_ZENO_JUMPS,
)
from ._past import _CHUNK_T, _add_breaks, _fd, _past_missing, _record
from ._steps import (
    _all_finite,
    _dense,
    _dop853_step_dense,
    _error_norm,
    _error_norm_dop853,
    _grown,
    _held_buffers,
    _initial_guess,
    _initial_step,
    _norm,
    _owned_buffers,
    _put,
    _rk_dense,
    _room,
    _step_factor,
    _store,
)
from ._types import (
    _A,
    _A4,
    _A8,
    _A_FLOW,
    _A_JUMP,
    _A_STOP,
    _B,
    _B4,
    _B8,
    _C4,
    _C8,
    _EPS,
    _ERR_EXP,
    _FLOWS,
    _GOES_ON,
    _O_BREAK,
    _O_FLOW_ON,
    _O_JUMP,
    _O_STOP,
    _O_TMAX,
    _ORDER,
    _OUTSIDE,
    _P,
    _P4,
    _RK4_SNAP,
    BLOWUP,
    CANCELED,
    J_MAX,
    MAP_ERROR,
    MAP_FLOW_X0,
    MAP_GUARD,
    MAP_JUMP_SHAPE,
    MAP_JUMP_VALUE,
    MAP_JUMP_X0,
    MAX_STEPS,
    NON_FINITE,
    SOLVER_FAILED,
    T_MAX,
    ZENO,
    _bare,
    _canceled,
    _Cc,
    _vec_at,
    maps_of,
)
from ._watch import scratch, watch_fault, watch_step, watch_values, with_crossings

#: a constant of the run core: its method is DOP853 (False: RK45). True in
#: :data:`._variants.run_one_dop853` (:func:`._variants._variant`), whose steps,
#: error norm and dense output are DOP853's; numba prunes the other method's
#: branches from each
_DOP = False
#: the run core's globals in its DOP853 variant
DOP853_GLOBALS = {"_DOP": True}
#: a constant of the run core: its method is the classic RK4 with the fixed step
#: ``max_step`` (:class:`hybridsim._rk.RK4`: no error control, the step ending on
#: its bound within ``RK4_SNAP`` of a step, the continuous extension of order 3 in
#: RK45's dense-output form). True in :data:`._variants.run_one_rk4` and
#: ``run_one_rk4_delays``; numba prunes the error control and the first-step rule
_RK4 = False
#: the run core's globals in its RK4 variants
RK4_GLOBALS = {"_RK4": True}
#: a constant of the run core: whether its flow map reads the past (delays).
#: False in :data:`._variants.run_one` (numba prunes every branch on it: no code
#: for the past, a smaller kernel to compile), True in ``run_one_delays``
_DELAYS = False
#: a constant of the run core: whether the system watches functions along its
#: flows (:mod:`._watch`). True only in ``run_one_watch``
_WATCH = False
#: a constant of the run core: its flow map is also given written into an array,
#: ``fi(x, t, j, p, out)`` (:attr:`CompiledSystem.maps_into`), and the steps call
#: that form into the run's scratch rows (the stages into K's rows): no array
#: made per evaluation. True only in a specialised kernel of such a system
#: without delays (``_cache.spec_module``); ``fi`` is ``f`` elsewhere
_INTO = False


def _run_core(maps, x0, p_in, fopt, iopt, atol, rngp, poll, stop):
    """One run, entirely compiled.

    ``maps``: the maps f, g, hD, hC, D, C by their addresses (an int64 array of
    their cfunc wrappers, :func:`map_addresses`), or a tuple of a system's own
    dispatchers (a specialised kernel; :func:`maps_of`).

    Returns ``(T, J, X, XD, cause, detail, info, stats)``: the samples
    (trimmed), the cause code (:data:`CAUSES`), a detail code saying which
    message variant, ``info`` (floats for the message: t, t2, value, j) and
    ``stats`` (steps, rejected, nfev, events, flows, jumps).

    ``rngp``: the run's numpy Generator by its addresses (:func:`rng_pointers`).
    ``poll``: the addresses of (check, occurred, clear): ``PyErr_CheckSignals``,
    ``PyErr_Occurred`` and ``PyErr_Clear`` for a run in the thread that holds
    the GIL (Ctrl-C is read at every step and jump: the run ends ``CANCELED``),
    zeros inside a parallel batch (nothing is called), whose runs read ``stop[0]``
    instead.
    """
    f, g, hD, hC, D, C = maps_of(maps)
    fi = f
    # the first NaN guard (which, s, j): written by ``_fault`` through its address
    ev = np.zeros(3)
    M = (f, g, hD, hC, D, C, iopt[I_D_FROM_GUARD] != 0, iopt[I_C_FROM_GUARD] != 0, ev.ctypes.data)
    polls = np.int64(0)              # Ctrl-C's polls since other threads last ran
    t0 = fopt[F_T0]
    t_max = fopt[F_T_MAX]
    j_max = fopt[F_J_MAX]
    rtol = fopt[F_RTOL]
    max_step = fopt[F_MAX_STEP]
    first_step = fopt[F_FIRST_STEP]
    max_norm = fopt[F_MAX_NORM]
    zeno_time = fopt[F_ZENO_TIME]
    zeno_rtol = fopt[F_ZENO_RTOL]
    nd = iopt[I_N_DELAYS]            # delays read by the flow map (fopt[F_DELAYS:])
    j0 = iopt[I_J0]
    prio = iopt[I_PRIO]
    max_steps = iopt[I_MAX_STEPS]
    max_samples = iopt[I_MAX_SAMPLES]
    zeno_jumps = iopt[I_ZENO_JUMPS]
    refine = iopt[I_REFINE]
    has_C = iopt[I_HAS_C] != 0
    has_D = iopt[I_HAS_D] != 0
    has_hC = iopt[I_HAS_HC] != 0
    has_hD = iopt[I_HAS_HD] != 0
    cap = iopt[I_CAP]
    # iopt[I_ROW]: a batch's run, whose samples are copied by the caller
    watch_D = has_D and prio != _FLOWS
    # every given guard goes into the event function (the indicators decide membership)
    useC = has_C and has_hC

    n = x0.shape[0]
    if _WATCH:      # the watched functions, their directions, and the crossings found
        W = _vec_at(maps[6])
        wdir = fopt[F_DELAYS + nd:]
        CR = np.empty((8, 4 + n))
        nc = 0
        WP, WY, WV = scratch(n, wdir.shape[0])
        wv = np.empty(0)
        wt = t0
        wfloor = t0
    # with delays: the run's own p, the past's place after the parameters (NaN
    # but while the flow map runs), and the record of the steps (``_past``)
    # (``_DELAYS``: a constant of the kernel, False in :data:`run_one`, whose
    # code has none of this; :data:`run_one_delays` is the kernel with it)
    pb = p_in.shape[0]
    if _DELAYS:
        dl = fopt[F_DELAYS:F_DELAYS + nd].copy()
        p = np.empty(pb + nd * n)
        for q in range(pb):
            p[q] = p_in[q]
        p[pb:] = np.nan
        HL = List.empty_list(_CHUNK_T)
        HM = np.zeros(5)
        HM[1] = t0
        HM[2] = np.nan
        cur_x = x0.copy()
        BL = List.empty_list(types.float64)     # delay breakpoints t_k + tau_i, sorted
        ibr = 0                                 # the first not yet passed
        _add_breaks(BL, t0, dl)
    else:
        p = _bare(p_in)              # the caller's: alive for the whole run
    # the sample buffers: held (their owners live until released at the run's end,
    # ``H`` their holds), used as views without reference counts (``_steps._grown``)
    H = np.empty(4, np.int64)
    T, J, X, XD = _held_buffers(cap, n, H)
    stats = np.zeros(6, np.int64)
    info = np.full(6, np.nan)
    cause = -1
    detail = 0
    # the run's scratch, one owned array read again before the run returns (alive
    # throughout), its parts views without reference counts (:func:`_bare`)
    # the method (``_DOP``, ``_RK4``: constants, the others' code is pruned): its
    # stages (the first the flow at the step's start), the rows of K (DOP853's
    # dense output adds three) and the dense output's columns (RK4's in RK45's form)
    NST = 12 if _DOP else (4 if _RK4 else 6)
    NK = 16 if _DOP else (5 if _RK4 else 7)
    NQ = 7 if _DOP else 4
    SA = _A8 if _DOP else (_A4 if _RK4 else _A)
    SB = _B8 if _DOP else (_B4 if _RK4 else _B)
    SC = _C8 if _DOP else (_C4 if _RK4 else _Cc)
    SP = _P4 if _RK4 else _P
    ERRX = -1.0 / 8.0 if _DOP else _ERR_EXP
    work = np.zeros((NK + NQ + 15) * n)
    K = _bare(work[:NK * n]).reshape((NK, n))
    Ks = _bare(work[:(NST + 1) * n])         # the step's stages (scipy's solver.K)
    o = NK * n
    hQ = _bare(work[o:o + NQ * n]).reshape((n, NQ))
    o += NQ * n
    yi = _bare(work[o:o + n])        # a stage's state: read by f, never kept
    # the event search's states: the interior search's three samples, and a
    # trial point (``wk``, its last row); read by guards, never kept
    WS = _bare(work[o + n:o + 5 * n]).reshape((4, n))
    wk = WS[3]
    # the steps' new states, in turn: a step writes the row its start is not in
    # (``ya`` in row ``ya_row``, -1: not in these rows); copied where a flow ends
    YY = _bare(work[o + 5 * n:o + 7 * n]).reshape((2, n))
    # DOP853's first interior search: the cubic Hermite of the step's ends
    hH = _bare(work[o + 7 * n:o + 10 * n]).reshape((n, 3))
    # ``_INTO``: the flow's values written by ``fi``: a step's end in the row of its
    # state's (YY's), the flow's start in row 1, any other in row 2
    FF = _bare(work[o + 10 * n:o + 13 * n]).reshape((3, n))
    # the state after a jump, in turn: a jump writes the row the state it jumps
    # from is not in (that state, or the last flow's start, ``ya``, the post-jump
    # test reads after it: ``_near_C``), no array made a jump
    XJ = _bare(work[o + 13 * n:o + 15 * n]).reshape((2, n))
    xj_row = np.int64(0)            # (x0 in row 0)

    t = t0
    j = j0
    x = XJ[0]
    for q in range(n):
        x[q] = x0[q]
    jumps = np.int64(0)
    short = np.int64(0)
    zref = 0.0                      # the Zeno streak's reference flow (rules.zeno_short)
    t_last_jump = t0
    flows_last = np.zeros(4)        # the last (up to) 4 flow lengths, oldest first
    n_flows_last = np.int64(0)
    h_hint = first_step              # NaN: none
    # counters as int64 from the start: a constant argument (Literal[int]) compiles
    # a helper again for it, even where type inference only tries it on the way
    ns = np.int64(0)                 # (the buffers start with room: iopt[I_CAP] rows)
    _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, t, j, _bare(x))
    ns = np.int64(1)
    # at x0: the maps' values are checked (the Python path raises at once)
    in_D0 = has_D and _inD(M, _bare(x), t, j, p)
    if ev[0] != 0.0:
        info[0] = ev[1]
        info[2] = ev[0]
        info[3] = ev[2]
        T, J, X, XD = _owned_buffers(T, J, X, XD, -ns, H)
        return T, J, X, XD, MAP_ERROR, MAP_GUARD, info, stats
    if (not has_C) or _inC(M, _bare(x), t, j, p):
        if _DELAYS:
            v0 = _fd(f, x, t, j, p, pb, dl, HL, HM, cur_x, x0, t0)
        else:
            v0 = f(x, t, j, p)
        if v0.shape[0] != n or not _all_finite(v0):
            info[0] = t
            info[2] = v0.shape[0]
            info[3] = j
            T, J, X, XD = _owned_buffers(T, J, X, XD, -ns, H)
            return T, J, X, XD, MAP_ERROR, MAP_FLOW_X0, info, stats
    if in_D0:
        v0 = g(x, t, j, p)
        if v0.shape[0] != n or not _all_finite(v0):
            info[0] = t
            info[2] = v0.shape[0]
            info[3] = j
            T, J, X, XD = _owned_buffers(T, J, X, XD, -ns, H)
            return T, J, X, XD, MAP_ERROR, MAP_JUMP_X0, info, stats
    forced = False
    flow_on = False
    in_D = False
    in_C = True
    loop = np.int64(0)               # consecutive jumps at one instant from C and D
    same = np.int64(0)               # consecutive jumps at one instant, from C or not
    longest = 0.0                    # the longest flow so far (rules.chatter_step)
    tiny = np.int64(0)               # consecutive flows tiny against it (chattering)
    # the bracket's lo of the located event the last flow ends with, a jump from
    # its hi (``pend``), and of the jump just taken (``post``): rules.post_jump_probe.
    # Scalars only per jump (copying x_lo, x_hi at every jump cost ~10% of a
    # timer's run): ``_near_C`` rebuilds x_lo from the event step (a, ya, hQ,
    # hs), and x_hi is the pre-jump sample X[ns - 2]
    pend = False
    post = False
    post_lo = t0
    a = t0
    ya = x
    hs = 1.0
    done = False
    while not done:
        canceled, polls = _canceled(poll, stop, polls)
        if canceled:
            cause = CANCELED
            break
        if flow_on:
            in_D = True
        else:
            if forced:
                # the located event is in D: jump (``_Run._loop``, no set read again)
                forced = False
                from_C = True
                action = _A_JUMP
                post = pend
                pend = False
            else:
                in_D = has_D and _inD(M, _bare(x), t, j, p)
                in_C = (not has_C) or _inC(M, _bare(x), t, j, p)
                if ev[0] != 0.0:
                    cause = MAP_ERROR
                    detail = MAP_GUARD
                    break
                action = decide_at(in_C, in_D, prio, rngp)
                if action == _A_STOP and post and _near_C(M, x, j, p, post_lo, ya, hQ, a,
                                                          hs, X[ns - 2]):
                    # within the located event's own error of C: in C
                    in_C = True
                    action = _A_FLOW
                if ev[0] != 0.0:
                    cause = MAP_ERROR
                    detail = MAP_GUARD
                    break
                post = False
                from_C = in_C
            if action == _A_JUMP:
                if jumps >= j_max:
                    cause = J_MAX
                    break
                xn = g(x, t, j, p)
                if xn.shape[0] != n or not _all_finite(xn):
                    cause = MAP_ERROR
                    detail = MAP_JUMP_SHAPE if xn.shape[0] != n else MAP_JUMP_VALUE
                    info[0] = t
                    info[2] = xn.shape[0]
                    info[3] = j
                    break
                # ---- the jump (``_Run._jump``)
                n_flows_last, zref, short, longest, longest_before, tiny, same, loop, flow = \
                    jump_books(flows_last, n_flows_last, t, t_last_jump, jumps, from_C, zref,
                               short, longest, tiny, same, loop, zeno_time, zeno_rtol)
                t_last_jump = t
                j += 1
                jumps += 1
                xj_row = 1 - xj_row
                x = XJ[xj_row]
                for q in range(n):
                    x[q] = xn[q]
                if _DELAYS:                  # ``History._restart``, the new breakpoints
                    for q in range(n):
                        cur_x[q] = x[q]
                    HM[1] = t
                    _add_breaks(BL, t, dl)
                if ns >= max_samples:
                    cause = MAX_STEPS
                    detail = 1
                    info[0] = t
                    break
                if ns == T.shape[0]:
                    T, J, X, XD = _grown(T, J, X, XD, ns, H)
                _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, t, j, _bare(x))
                ns += 1
                cause, detail = jump_cause(jumps, short, j_max, zeno_jumps, loop, same, tiny, t,
                                           longest_before, flow, info)
                if cause != _GOES_ON:
                    break
                continue
            if action == _A_STOP:
                cause = _OUTSIDE     # decided below (_stop_outside)
                break
        if t >= t_max:
            cause = T_MAX
            break
        flow_on = False
        # ---------------------------------------------------------- a flow
        t_bound = t_max
        if _DELAYS:                          # ``_Run._bound``: the next breakpoint
            tol = 4.0 * _EPS * max(1.0, abs(t))
            while ibr < len(BL) and BL[ibr] <= t + tol:
                ibr += 1
            if ibr < len(BL) and BL[ibr] < t_max:
                t_bound = BL[ibr]
        flow_t0 = t
        hh0 = h_hint
        if hh0 == hh0:
            hh0 = min(hh0, t_bound - t, max_step)
            if not hh0 > 0:
                hh0 = np.nan
        if _DELAYS:
            fa = _fd(f, x, t, j, p, pb, dl, HL, HM, cur_x, x0, t0)
        elif _INTO:
            fa = FF[1]
            fi(x, t, j, p, fa)
        else:
            fa = f(x, t, j, p)
        stats[2] += 1
        if fa.shape[0] != n:
            cause = MAP_ERROR
            detail = 2
            info[0] = t
            info[2] = fa.shape[0]
            info[3] = j
            break
        if _RK4:
            h_abs = max_step                 # RK4's fixed step: no hint, no first-step rule
        elif hh0 == hh0:
            h_abs = hh0
        else:
            # scipy's select_initial_step: the Euler point in yi, the scale in WS[0]
            h0, d1 = _initial_guess(t, x, t_bound, fa, rtol, atol, yi, WS[0])
            h_abs = 0.0
            if abs(t_bound - t) != 0.0:
                if _DELAYS:
                    f1 = _fd(f, yi, t + h0, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                elif _INTO:
                    f1 = FF[2]
                    fi(yi, t + h0, j, p, f1)
                else:
                    f1 = f(yi, t + h0, j, p)
                h_abs = _initial_step(t, t_bound, max_step, fa, f1, h0, d1, WS[0],
                                      7.0 if _DOP else _ORDER)
            stats[2] += 1
            if h_abs < 0.0:
                cause = MAP_ERROR
                detail = 2
                info[0] = t
                info[3] = j
                break
        if _DELAYS and HM[2] == HM[2]:       # the past is missing (a delay under a step)
            cause, detail = _past_missing(info, HM, j)
            break
        stats[4] += 1
        if _WATCH:       # ``_Run._watch_start``: a zero at a jump (or x0) is no crossing
            wv, wok = watch_values(W, x, t, j, p, wdir.shape[0])
            if not wok:
                cause, detail = watch_fault(info, t, j)
                break
            wt = t
            wfloor = t if t == t_last_jump else -np.inf
        for q in range(n):
            XD[ns - 1, q] = fa[q]
        a = t
        ya = x
        ya_row = -1
        yb_row = -1
        d_active = watch_D and not in_D
        tried = False
        outcome = _O_STOP
        while True:
            if stats[0] >= max_steps:
                cause = MAX_STEPS
                detail = 0
                info[0] = a
                t, x = a, ya
                outcome = _O_STOP
                break
            canceled, polls = _canceled(poll, stop, polls)
            if canceled:
                cause = CANCELED
                t, x = a, ya
                break
            # ---- scipy's RungeKutta._step_impl (RK4's: ``hybridsim._rk.RK4._step_impl``)
            min_step = 10.0 * abs(np.nextafter(a, np.inf) - a)
            if _RK4:
                ha = max_step
            elif h_abs > max_step:
                ha = max_step
            elif h_abs < min_step:
                ha = min_step
            else:
                ha = h_abs
            accepted = False
            rejected = False
            failed = False
            attempts = 0
            b = a
            hs = 0.0
            yb = ya
            fb = fa
            bad_len = False
            while not accepted:
                if not _RK4 and ha < min_step:
                    failed = True
                    break
                hs = ha
                b = a + hs
                if _RK4:
                    if b - t_bound > -_RK4_SNAP * hs:    # no sliver step before the bound
                        b = t_bound
                elif b - t_bound > 0:
                    b = t_bound
                hs = b - a
                ha = abs(hs)
                attempts += 1
                tried = True
                for q in range(n):
                    K[0, q] = fa[q]
                for s in range(1, NST):
                    for i in range(n):
                        acc = 0.0
                        for m in range(s):
                            acc += K[m, i] * SA[s, m]
                        yi[i] = ya[i] + acc * hs
                    if _INTO:                # into K's row s itself
                        fi(yi, a + SC[s] * hs, j, p, K[s])
                        continue
                    if _DELAYS:
                        ks = _fd(f, yi, a + SC[s] * hs, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                    else:
                        ks = f(yi, a + SC[s] * hs, j, p)
                    if ks.shape[0] != n:
                        bad_len = True
                        break
                    for q in range(n):
                        K[s, q] = ks[q]
                if bad_len:
                    break
                ynew_row = 1 if ya_row == 0 else 0
                ynew = YY[ynew_row]
                for i in range(n):
                    acc = 0.0
                    for m in range(NST):
                        acc += K[m, i] * SB[m]
                    ynew[i] = ya[i] + hs * acc
                if _DELAYS:
                    fnew = _fd(f, ynew, b, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                elif _INTO:
                    fnew = FF[ynew_row]
                    fi(ynew, b, j, p, fnew)
                else:
                    fnew = f(ynew, b, j, p)
                stats[2] += NST
                if _DELAYS and HM[2] == HM[2]:
                    break
                if fnew.shape[0] != n:
                    bad_len = True
                    break
                for q in range(n):
                    K[NST, q] = fnew[q]
                if _RK4:
                    # no error control: every step accepted, h_abs stays max_step
                    ha = max_step
                    accepted = True
                    yb = ynew
                    yb_row = ynew_row
                    fb = fnew
                    break
                if _DOP:
                    err = _error_norm_dop853(K, ya, ynew, atol, rtol, hs)
                else:
                    err = _error_norm(K, ya, ynew, atol, rtol, hs)
                ha *= _step_factor(err, rejected, ERRX)
                if err < 1:
                    accepted = True
                    yb = ynew
                    yb_row = ynew_row
                    fb = fnew
                else:
                    rejected = True
            if attempts > 1:
                stats[1] += attempts - 1
            if _DELAYS and HM[2] == HM[2]:
                cause, detail = _past_missing(info, HM, j)
                t, x = a, ya
                break
            if bad_len:
                cause = MAP_ERROR
                detail = 2
                info[0] = a
                info[3] = j
                t, x = a, ya
                break
            if failed:
                # ``_Run._solver_failed``
                bad = tried and not _all_finite(Ks)
                if not bad:
                    if _DELAYS:
                        fy = _fd(f, ya, a, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                    else:
                        fy = f(ya, a, j, p)
                    bad = fy.shape[0] != n or not _all_finite(fy)
                if bad:
                    cause = NON_FINITE
                    detail = 1
                elif short > 0:
                    cause = ZENO
                    detail = 2
                else:
                    cause = SOLVER_FAILED
                info[0] = a
                info[3] = j
                t, x = a, ya
                break
            h_abs = ha
            stats[0] += 1
            if not _all_finite(yb):
                cause = NON_FINITE
                detail = 0
                info[0] = a
                info[1] = b
                info[3] = j
                t, x = a, ya
                break
            # dense output of the step: hQ = h K^T P (RK45, RK4); DOP853's costs
            # three evaluations more, made where it may be read (below)
            if not _DOP and not _rk_dense(K, SP, hs, hQ):
                # the dense output overflowed (a finite end, a non-finite interior)
                cause = NON_FINITE
                detail = 2
                info[0] = a
                info[1] = b
                info[3] = j
                t, x = a, ya
                break
            event = has_C and not _inC(M, _bare(yb), b, j, p)
            if d_active:
                event = event or _inD(M, _bare(yb), b, j, p)
            hit = False
            elo = a
            ehi = b
            phi_on = (d_active and has_hD) or useC
            if event:
                hit = True
            elif has_C or d_active:
                if _DOP:
                    # ``_Run._flow``: the search on the cubic Hermite of the step's
                    # ends first, a hit confirmed on the dense output (below)
                    for i in range(n):
                        hH[i, 0] = yb[i]
                        hH[i, 1] = hs * fa[i]
                        hH[i, 2] = hs * fb[i]
                    hit, elo, ehi = _interior(M, _bare(ya), hH, a, hs, j, p, has_C, d_active,
                                              phi_on, d_active and has_hD, useC, a, b, WS)
                else:
                    hit, elo, ehi = _interior(M, _bare(ya), hQ, a, hs, j, p, has_C, d_active,
                                              phi_on, d_active and has_hD, useC, a, b, WS)
            if _DOP and ev[0] == 0.0 and (hit or refine > 1 or (
                    b - t_bound >= 0 and not t_bound < t_max and watch_D)):
                # DOP853's dense output, made where it may be read: an event, a hit
                # to confirm, refined samples, an entry into D after t_max (below)
                cause, detail = _dop853_step_dense(f, K, ya, yb, a, hs, j, p, yi, hQ,
                                                   stats, info)
                if cause != _GOES_ON:
                    t, x = a, ya
                    break
                if hit and not event:
                    hit, elo, ehi = _interior(M, _bare(ya), hQ, a, hs, j, p, has_C, d_active,
                                              phi_on, d_active and has_hD, useC, a, b, WS)
            clamp = np.nan
            past = False
            if not hit and watch_D and not d_active:
                d_active = not _inD(M, _bare(yb), b, j, p)
            if ev[0] != 0.0:
                cause = MAP_ERROR
                detail = MAP_GUARD
                t, x = a, ya
                break
            if not hit:
                if _WATCH:                   # ``_Run._watch_to``, before the step's samples
                    CR, nc, wv, wok = watch_step(W, wdir, ya, hQ, a, hs, wt, ya, wv, b, yb, j,
                                                 p, wfloor, CR, nc, WP, WY, WV)
                    wt = b
                    if not wok:
                        cause, detail = watch_fault(info, b, j)
                        t, x = a, ya
                        break
                if _DELAYS:                  # ``History._add``
                    _record(HL, HM, a, b, hs, ya, hQ)
                ns_step = ns             # this step's samples start here
                if refine > 1 or ns >= T.shape[0] or ns >= max_samples:
                    T, J, X, XD, ns, ok = _room(T, J, X, XD, ns, a, b, j, refine, ya, hQ, hs,
                                                not _DOP, max_samples, H)
                    if not ok:
                        cause = MAX_STEPS
                        detail = 1
                        info[0] = t
                        break
                _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, b, j, _bare(yb))
                for q in range(n):
                    XD[ns, q] = fb[q]
                ns += 1
                if max_norm < np.inf:
                    nb = _norm(yb)
                    if nb > max_norm:
                        cause = BLOWUP
                        info[0] = b
                        info[2] = nb
                        info[3] = j
                        t, x = b, yb
                        break
                if b - t_bound >= 0:          # the solver finished
                    if t_bound < t_max:       # a delay breakpoint: flow on, a new flow
                        h_hint = h_abs
                        t, x = b, yb.copy()
                        outcome = _O_BREAK
                        break
                    h_hint = np.nan
                    if d_active:
                        # ``_event_past_t_max``: an entry into D within round-off
                        tb = b + rules.t_max_slack(b, jumps)
                        if _pred(M, tb, _dense(ya, hQ, a, hs, tb), j, p, has_C, d_active):
                            # the step's samples are stored again by the
                            # event's commit (up to te = b): drop them here
                            ns = ns_step
                            past = True
                            hit = True
                            elo = b
                            ehi = tb
                            clamp = b
                        if ev[0] != 0.0:
                            cause = MAP_ERROR
                            detail = MAP_GUARD
                            t, x = b, yb
                            break
                    if not past:
                        t, x = b, yb.copy()
                        outcome = _O_TMAX
                        break
                if not hit:
                    a = b
                    ya = yb
                    ya_row = yb_row
                    fa = fb
                    continue
            # ---- an event in (elo, ehi] of the step from a (``_Run._event``)
            da = True if past else d_active
            phi_on = (da and has_hD) or useC
            stats[3] += 1
            # the bracket's end states in WS's first two rows (free: the interior
            # search's samples are read no more); ``xe`` is one of them
            kind, te, at_hi, lo, hint, from_hi = _event(
                M, _bare(ya), hQ, a, hs, j, p, has_C, has_D, da, phi_on, da and has_hD, useC,
                a, elo, ehi, clamp, h_abs, flow_t0, prio, rngp, yb, ehi == b and not past, wk,
                WS)
            xe = WS[1] if at_hi else WS[0]
            h_hint = hint
            if ev[0] != 0.0:
                cause = MAP_ERROR
                detail = MAP_GUARD
                t, x = a, ya
                break
            # ``_commit``
            if _DELAYS and not past and te > a:
                _record(HL, HM, a, te, hs, ya, hQ)
            if _WATCH and te > wt:          # ``_commit``: the flow up to the event
                CR, nc, wv, wok = watch_step(W, wdir, ya, hQ, a, hs, wt, ya if wt == a else yb,
                                             wv, te, xe, j, p, wfloor, CR, nc, WP, WY, WV)
                if not wok:
                    cause, detail = watch_fault(info, te, j)
                    t, x = a, ya
                    break
            if te > a:
                if refine > 1 or ns >= T.shape[0] or ns >= max_samples:
                    T, J, X, XD, ns, ok = _room(T, J, X, XD, ns, a, te, j, refine, ya, hQ, hs,
                                                not _DOP, max_samples, H)
                    if not ok:
                        cause = MAX_STEPS
                        detail = 1
                        info[0] = t
                        break
                _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, te, j, _bare(xe))
                if _DELAYS:
                    fe = _fd(f, xe, te, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                elif _INTO:
                    fe = FF[2]
                    fi(xe, te, j, p, fe)
                else:
                    fe = f(xe, te, j, p)
                if fe.shape[0] == n:
                    for q in range(n):
                        XD[ns, q] = fe[q]
                ns += 1
                if max_norm < np.inf:        # the event's sample, as a step's end
                    nb = _norm(xe)
                    if nb > max_norm:
                        cause = BLOWUP
                        info[0] = te
                        info[2] = nb
                        info[3] = j
                        t, x = te, xe.copy()
                        break
            # a jump reads xe (its scratch row) at once and makes its own state; a
            # run that flows on from xe, or ends there, keeps a copy
            t, x = te, (xe if kind == _O_JUMP else xe.copy())
            outcome = kind
            if from_hi:
                pend = True
                post_lo = lo
            if kind == _O_STOP:
                cause = _OUTSIDE
                detail = 1
                info[0] = lo
                info[3] = j
            break
        if cause != _GOES_ON:
            break
        if outcome == _O_JUMP:
            forced = True
        elif outcome == _O_FLOW_ON:
            flow_on = True
    if cause == _OUTSIDE:
        # ``_Run._stop_outside``: x0 outside both sets, sticking, or leaving C u D
        cause, detail = stop_outside(ns, t0, t, t_max, j, flows_last, n_flows_last,
                                     t_last_jump, jumps, info, detail)
    if cause == MAP_ERROR and detail == MAP_GUARD:
        info[0] = ev[1]
        info[2] = ev[0]
        info[3] = ev[2]
    if cause != MAP_ERROR and XD[ns - 1, 0] != XD[ns - 1, 0]:
        if _DELAYS:
            fl = _fd(f, np.ascontiguousarray(X[ns - 1]), T[ns - 1], J[ns - 1], p, pb, dl, HL, HM,
                     cur_x, x0, t0)
        else:
            fl = f(np.ascontiguousarray(X[ns - 1]), T[ns - 1], J[ns - 1], p)
        if fl.shape[0] == n:
            _put(XD, ns - 1, fl)
    stats[5] = jumps
    if _WATCH:
        info = with_crossings(info, CR, nc)
    if work[0] != work[0]:           # (keeps the scratch's owner alive to here)
        stats[5] = jumps
    # a batch's run (:func:`run_rows` copies it into the pool at once): the buffers
    # themselves, cut to the samples (no copy, four arrays fewer); else copies
    T, J, X, XD = _owned_buffers(T, J, X, XD, ns if iopt[I_ROW] != 0 else -ns, H)
    return T, J, X, XD, cause, detail, info, stats
