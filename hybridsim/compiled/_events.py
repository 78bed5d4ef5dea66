"""The compiled path's event location (imported only when numba is installed).

The port of :func:`hybridsim.events.locate_event` (a flow starting on the
guard's zero, a probe and a quadratic model's first estimate; then, each
compiled from its one source in :mod:`hybridsim.events`: indicator
bisection until the guard changes sign and to 4 ulp, :func:`bisection_of
<hybridsim.events.bisection_of>`; the safeguarded secant on the guard,
:func:`secant_of <hybridsim.events.secant_of>`, its bracket confirmed by the
indicator) and :func:`hybridsim.events.find_interior_event` (three interior
samples and the golden-section search on guard peaks, :func:`peak_of
<hybridsim.events.peak_of>`).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .. import events, rules
from ._steps import (
    _copy_to,
    _dense,
    _dense_to,
)
from ._types import (
    _A_FLOW,
    _A_STOP,
    _NJI,
    _NJL,
    _O_FLOW_ON,
    _O_JUMP,
    _O_STOP,
    CACHE,
    _coin,
    _f64_ptr,
)


@njit(cache=CACHE, **_NJL)
def _fault(ev_addr, which, s, j):
    """Record the first NaN guard of the run in the kernel's ``ev`` (at
    ``ev_addr``; ``ev[0]``: 1 jump_guard, 2 flow_guard, then s and j)."""
    ev = _f64_ptr(ev_addr)
    if ev[0] == 0.0:
        ev[0] = which
        ev[1] = s
        ev[2] = j


# _inD, _inC, _pred: plain calls (numba's IR inlining of them, at ~30 call sites,
# cost ~10 s of the engine's first compile for no measurable speed: LLVM inlines)
@njit(cache=CACHE, **_NJL)
def _inD(M, y, s, j, p):
    """x in D: the indicator, or {jump_guard >= 0} where D is derived from its guard
    (a NaN guard is the map's contract breach: recorded at ``M[8]``, as the Python
    path's ``MapError``).

    ``M`` = (f, g, hD, hC, D, C, D from its guard, C from its guard, the
    address of the kernel's fault record): scalars only. An array in ``M``
    (passed to every helper of the event search) cost 10% of a run."""
    if M[6]:
        v = M[2](y, s, j, p)
        if v != v:
            _fault(M[8], 1.0, s, j)
            return False
        return v >= 0.0
    return M[4](y, s, j, p)


@njit(cache=CACHE, **_NJL)
def _inC(M, y, s, j, p):
    """x in C: the indicator, or {flow_guard >= 0} (see :func:`_inD`)."""
    if M[7]:
        v = M[3](y, s, j, p)
        if v != v:
            _fault(M[8], 2.0, s, j)
            return True
        return v >= 0.0
    return M[5](y, s, j, p)


@njit(cache=CACHE, **_NJL)
def _pred(M, s, y, j, p, has_C, d_active):
    """The event has happened at (s, y): left C, or (watched) entered D."""
    if has_C and not _inC(M, y, s, j, p):
        return True
    if d_active and _inD(M, y, s, j, p):
        return True
    return False


@njit(cache=CACHE, **_NJL)
def _phi(M, s, y, j, p, useD, useC):
    """The continuous event function (>= 0 once the event has happened): every
    given guard of the flow (``_Run._phi``). A NaN guard is recorded as the
    Python path's ``MapError`` naming it (see :func:`_fault`)."""
    v = -np.inf
    if useD:
        v = M[2](y, s, j, p)
    if useC:
        w = -M[3](y, s, j, p)
        if w > v:
            v = w
        elif w != w:
            v = w
    if v != v:                       # either guard NaN (kept by the max above)
        _phi_nan(M, s, y, j, p, useD)
    return v


@njit(cache=CACHE, **_NJL)
def _phi_nan(M, s, y, j, p, useD):
    """Record which guard returned NaN in :func:`_phi` (the jump guard first, as
    ``_Run._phi`` names it): off the event search's fast path."""
    if useD:
        v = M[2](y, s, j, p)
        if v != v:
            _fault(M[8], 1.0, s, j)
            return
    _fault(M[8], 2.0, s, j)


# inlined into the secant (one call site): its tuple passed per trial cost 2% of a ball run
@njit(inline="always", **_NJL)
def _phi_at(E, s):
    """:func:`_phi` at time s of a step's dense output, for :func:`_secant`:
    ``E = (M, yold, hQ, told, h, j, p, useD, useC, wk)``, the state written into ``wk``."""
    M, yold, hQ, told, h, j, p, useD, useC, wk = E
    _dense_to(wk, yold, hQ, told, h, s)
    return _phi(M, s, wk, j, p, useD, useC)


#: the guards' secant (compiled into its callers, which numba caches)
_secant = njit(**_NJL)(events.secant_of(_phi_at))


# the bisections' and the peak search's evaluators, inlined into them:
# ``E = (M, yold, hQ, told, h, j, p, has_C, d_active, useD, useC, wk)``, the
# state written into ``wk``
@njit(inline="always", **_NJL)
def _guard_at(E, s):
    M, yold, hQ, told, h, j, p, _, _, useD, useC, wk = E
    _dense_to(wk, yold, hQ, told, h, s)
    return _phi(M, s, wk, j, p, useD, useC)


@njit(inline="always", **_NJL)
def _member_at(E, s):
    M, yold, hQ, told, h, j, p, has_C, d_active, _, _, wk = E
    _dense_to(wk, yold, hQ, told, h, s)
    return _pred(M, s, wk, j, p, has_C, d_active)


@njit(inline="always", **_NJL)
def _member_guard_at(E, s):
    M, yold, hQ, told, h, j, p, has_C, d_active, useD, useC, wk = E
    _dense_to(wk, yold, hQ, told, h, s)
    inside = _pred(M, s, wk, j, p, has_C, d_active)
    return inside, _phi(M, s, wk, j, p, useD, useC)


#: the guard peak's golden-section search and the bracket's bisections (compiled
#: into their callers, which numba caches)
_peak = njit(**_NJL)(events.peak_of(_guard_at, _member_at))
_to_sign_change, _bisect = (njit(**_NJL)(f) for f in
                            events.bisection_of(_member_at, _member_guard_at))


@njit(cache=CACHE, **_NJL)
def _locate(M, yold, hQ, told, h, j, p, has_C, d_active, phi_on, useD, useC, a, b,
            yb, yb_known, wk, ylo, yhi):
    """:func:`hybridsim.events.locate_event` on the step's dense output (``yb``:
    the state at b where ``yb_known``; the state at the step's start is exact).
    Returns the bracket (lo, hi); the states of its ends are written into
    ``ylo`` and ``yhi`` (the run's scratch rows: no array made an event).

    The bracket is narrowed on times, trial points evaluated in ``wk``;
    ``ylo`` holds the state at ``ylo_at`` (and ``yhi`` at ``yhi_at``), made
    again at the bracket's end times when it is done: the same values as
    the states kept along the way."""
    lo, hi = a, b
    if a == told:
        _copy_to(ylo, yold)
    else:
        _dense_to(ylo, yold, hQ, told, h, lo)
    if yb_known:
        _copy_to(yhi, yb)
    else:
        _dense_to(yhi, yold, hQ, told, h, hi)
    ylo_at = lo
    yhi_at = hi
    E = (M, yold, hQ, told, h, j, p, has_C, d_active, useD, useC, wk)
    if phi_on:
        flo = _phi(M, lo, ylo, j, p, useD, useC)
        fhi = _phi(M, hi, yhi, j, p, useD, useC)
        seeded = False
        s0 = np.nan
        slope0 = np.nan
        if not flo < 0.0 and fhi >= 0.0:
            # on the guard's zero at the start: one probe gives the direction,
            # and with the end value a first estimate of the root
            d = max(64.0 * rules.event_tolerance(lo, hi), 1e-9 * (hi - lo))
            if lo + d < hi:
                _dense_to(wk, yold, hQ, told, h, lo + d)
                fd = _phi(M, lo + d, wk, j, p, useD, useC)
                if fd < 0.0 and not _pred(M, lo + d, wk, j, p, has_C, d_active):
                    tau, slope0 = events.root_off_zero(flo, fd, fhi, d, hi - lo)
                    if tau == tau:
                        seeded = True
                        s0 = lo + tau
                    lo = lo + d
                    _copy_to(ylo, wk)
                    ylo_at = lo
                    flo = fd
        # bisect by the indicator until the guard changes sign in the bracket
        lo, hi, flo, fhi = _to_sign_change(E, lo, hi, flo, fhi, 200)
        if (flo < 0.0 and 0.0 <= fhi) and hi - lo > rules.event_tolerance(lo, hi):
            l2, h2 = _secant((M, yold, hQ, told, h, j, p, useD, useC, wk), lo, hi, flo, fhi,
                             seeded, s0, slope0)
            # the indicator decides membership: keep the guard's bracket where it
            # agrees (the state at h2, then at l2, in wk where not kept already)
            if h2 == yhi_at:
                in_h2 = _pred(M, h2, yhi, j, p, has_C, d_active)
            else:
                _dense_to(wk, yold, hQ, told, h, h2)
                in_h2 = _pred(M, h2, wk, j, p, has_C, d_active)
                if in_h2:
                    _copy_to(yhi, wk)
            if in_h2:
                hi = h2
                yhi_at = hi
                lo = l2
                if l2 != ylo_at:
                    _dense_to(ylo, yold, hQ, told, h, l2)
                ylo_at = lo
            elif l2 == ylo_at:
                if not _pred(M, l2, ylo, j, p, has_C, d_active):
                    lo = l2
            else:
                _dense_to(wk, yold, hQ, told, h, l2)
                if not _pred(M, l2, wk, j, p, has_C, d_active):
                    lo = l2
                    _copy_to(ylo, wk)
                    ylo_at = lo
    # bisection of the indicator (also finishes any bracket the guard left)
    lo, hi = _bisect(E, lo, hi, 200)
    if lo != ylo_at:
        _dense_to(ylo, yold, hQ, told, h, lo)
    if hi != yhi_at:
        _dense_to(yhi, yold, hQ, told, h, hi)
    return lo, hi


@njit(cache=CACHE, **_NJL)
def _interior(M, yold, hQ, told, h, j, p, has_C, d_active, phi_on, useD, useC, a, b, WS):
    """:func:`hybridsim.events.find_interior_event` with 3 samples: (found, lo, hi).

    ``WS``: the run's (4, n) buffer, the samples' states in its first three
    rows (read again for the guard values), other points in the last: no
    array made a step."""
    hh = b - a
    if not hh > 0:
        return False, a, b
    y1, y2, y3, wk = WS[0], WS[1], WS[2], WS[3]
    s1 = a + hh * 0.25
    s2 = a + hh * 0.5
    s3 = a + hh * 0.75
    _dense_to(y1, yold, hQ, told, h, s1)
    if _pred(M, s1, y1, j, p, has_C, d_active):
        return True, a, s1
    _dense_to(y2, yold, hQ, told, h, s2)
    if _pred(M, s2, y2, j, p, has_C, d_active):
        return True, s1, s2
    _dense_to(y3, yold, hQ, told, h, s3)
    if _pred(M, s3, y3, j, p, has_C, d_active):
        return True, s2, s3
    if not phi_on:
        return False, a, b
    _dense_to(wk, yold, hQ, told, h, a)
    v0 = _phi(M, a, wk, j, p, useD, useC)
    v1 = _phi(M, s1, y1, j, p, useD, useC)
    v2 = _phi(M, s2, y2, j, p, useD, useC)
    v3 = _phi(M, s3, y3, j, p, useD, useC)
    _dense_to(wk, yold, hQ, told, h, b)
    v4 = _phi(M, b, wk, j, p, useD, useC)
    if not (np.isfinite(v0) and np.isfinite(v1) and np.isfinite(v2) and np.isfinite(v3)
            and np.isfinite(v4)):
        return False, a, b
    E = (M, yold, hQ, told, h, j, p, has_C, d_active, useD, useC, wk)
    # a peak at a sample between its neighbours (the samples' order: s1, s2, s3)
    for k in range(1, 4):
        if k == 1:
            left, v, right, vl, vr = a, v1, s2, v0, v2
        elif k == 2:
            left, v, right, vl, vr = s1, v2, s3, v1, v3
        else:
            left, v, right, vl, vr = s2, v3, b, v2, v4
        if v >= vl and v >= vr and events.near_peak(v, min(vl, vr)):
            s = _peak(E, left, right, vl, vr)
            if s == s:
                return True, left, s
    if v0 >= v1 and events.near_peak(v0, v1):
        eps = 1e-3 * (s1 - a)
        _dense_to(wk, yold, hQ, told, h, a + eps)
        if _phi(M, a + eps, wk, j, p, useD, useC) > v0:
            s = _peak(E, a, s1, v0, v1)
            if s == s:
                return True, a, s
    # a peak between the last sample and b: only where the guard falls at b (the
    # next step starts falling, so its own search never looks back)
    if v4 >= v3 and events.near_peak(v4, v3):
        eps = 1e-3 * (b - s3)
        _dense_to(wk, yold, hQ, told, h, b - eps)
        if _phi(M, b - eps, wk, j, p, useD, useC) > v4:
            s = _peak(E, s3, b, v3, v4)
            if s == s:
                return True, s3, s
    return False, a, b


@njit(cache=CACHE, **_NJL)
def _event(M, yold, hQ, told, h, j, p, has_C, has_D, d_active, phi_on, useD, useC,
           a, lo, hi, clamp, h_abs, flow_t0, prio, rngp, yb, yb_known, wk, WS):
    """``_Run._event``: locate, then decide. Returns (kind, te, at_hi, lo, h_hint,
    from_hi): the event's state ``xe`` is the bracket's hi state (``WS[1]``) where
    ``at_hi``, else its lo state (``WS[0]``), the rows the bracket's end states
    are written into (:func:`_locate`; read before the next event); ``from_hi``,
    a jump from the bracket's hi, whose bracket the post-jump tolerance reads
    (``rules.post_jump_probe``). Scalars only returned: no reference counts."""
    ylo, yhi = WS[0], WS[1]
    lo, hi = _locate(M, yold, hQ, told, h, j, p, has_C, d_active, phi_on, useD, useC, lo, hi,
                     yb, yb_known, wk, ylo, yhi)
    if hi <= flow_t0:
        hint = np.nan
    else:
        hint = min(h_abs, 10.0 * (hi - flow_t0))
    te_hi = hi if not clamp == clamp else min(hi, clamp)
    # ``rules.event_outcome``: the maps are read only where the rule needs them
    in_D_hi = has_D and _inD(M, yhi, hi, j, p)
    in_C_hi = True
    in_D_lo = False
    coin = True
    if d_active and in_D_hi:
        in_C_hi = (not has_C) or _inC(M, yhi, hi, j, p)
        if rules.needs_coin(in_C_hi, True, prio):
            coin = _coin(rngp)
    elif has_D:
        in_D_lo = _inD(M, ylo, lo, j, p)
    action, side = rules.event_outcome(d_active, in_D_hi, in_C_hi, in_D_lo, prio, coin)
    if action == _A_FLOW:
        return _O_FLOW_ON, te_hi, True, lo, hint, False
    if action == _A_STOP:
        return _O_STOP, lo, False, lo, hint, False
    if side == 1:
        return _O_JUMP, te_hi, True, lo, hint, True
    return _O_JUMP, lo, False, lo, hint, False


@njit(cache=CACHE, **_NJI)
def _near_C(M, x, j, p, lo, yold, hQ, told, h, x_hi):
    """``_Run._near_C``: a post-jump state in neither C nor D is within the located
    event's tolerance of C (``rules.post_jump_probe``; off the run's main loop).

    The bracket's x_lo is rebuilt here, not kept per jump: the event step's
    dense output (``yold``, ``hQ``, ``told``, ``h``: untouched between the
    event and this test) at ``lo``, as :func:`_locate` made it (``yold``
    itself where ``lo`` is the step's start)."""
    x_lo = yold.copy() if lo == told else _dense(yold, hQ, told, h, lo)
    tp, xp = rules.post_jump_probe(x, lo, x_lo, x_hi)
    return _inC(M, xp, tp, j, p)
