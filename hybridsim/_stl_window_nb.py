"""The sliding-window sup of :func:`hybridsim._stl_eval._window_sup`, compiled.

:func:`window_core` is :func:`hybridsim._stl_eval._window_core` (the
window's value at the output's breakpoints, its limits from both sides, the
kinks inside the open pieces) with the same formulas in the same order, so
the robustness is the same to the bit; one pass over the breakpoints in
place of numpy's array passes, the searches as pointers moving forward (the
breakpoints are sorted) and the breakpoints merged from their sorted parts
in place of a sort: on the chasing cars' arcs (4,000 samples) about three
times faster. :func:`window_sup` is the rest of ``_window_sup`` after the
core, compiled with it (the same results, to the bit). Imported only where numba is installed, by
:func:`hybridsim._stl_eval._window_sup` for signals of
:data:`MIN_INSTANTS` and more; compiled on first use, kept in numba's disk
cache where the engine's kernels are.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .compiled._types import CACHE

#: signals of fewer instants than this are left to numpy (its overhead is small there)
MIN_INSTANTS = 256
_EPS = float(np.finfo(float).eps)
_NINF = -math.inf
_njit = numba.njit(cache=CACHE, nogil=True, error_model="numpy")


@_njit
def mx(a, b):                       # np.maximum: NaN wins
    if a != a or b != b:
        return math.nan
    return a if a > b else b


@_njit
def lerp(y0, y1, w):                # _stl_eval._lerp
    out = y0 + w * (y1 - y0)
    if not math.isfinite(out):
        if not (math.isfinite(y0) and math.isfinite(y1)):
            out = y0 if w < 0.5 else y1
    return out


@_njit
def tol(x):
    return 4.0 * _EPS * max(1.0, abs(x))


@_njit
def piece(P, R, L, u, du, M, p, x):
    if M == 1:
        return P[0]
    p = min(max(p, 0), M - 2)
    return lerp(R[p], L[p + 1], (x - u[p]) / du[p])


@_njit
def left(u, M, key, i):             # np.searchsorted(u, key, "left"), from i up
    while i < M and u[i] < key:
        i += 1
    return i


@_njit
def right(u, M, key, i):            # np.searchsorted(u, key, "right"), from i up
    while i < M and u[i] <= key:
        i += 1
    return i


@_njit
def locate(u, M, x, first, ptr):
    """_stl_eval's locate, its search from ``ptr`` (keys nondecreasing);
    returns (index, at an instant, the search's position)."""
    tx = tol(x)
    top = max(M - 2, 0)
    if first:
        pos = left(u, M, x - tx, ptr)
        i = min(pos, M - 1)
        ui = u[i]
        if abs(ui - x) <= tx:
            return i, True, pos
        k = i if ui < x else i - 1
    else:
        pos = right(u, M, x + tx, ptr)
        i = max(pos - 1, 0)
        ui = u[i]
        if abs(ui - x) <= tx:
            return i, True, pos
        k = i - 1 if ui > x else i
    return min(max(k, 0), top), False, pos


@_njit
def query(tab, M, i0, i1):          # _RangeMax.query
    n = i1 - i0 + 1
    if n <= 0:
        return _NINF
    lev = 0
    while (2 << lev) <= n:
        lev += 1
    w = max(M, 1)
    a = tab[lev, min(i0, w - 1)]
    b = tab[lev, max(i1 - (1 << lev) + 1, 0)]
    return mx(a, b)


@_njit
def breakpoints(x, y, z, lo, hi):
    """np.unique of lo, hi and the sorted x, y, z within [lo, hi]."""
    out = np.empty(2 + len(x) + len(y) + len(z))
    i = j = k = 0
    n = 0
    first = True
    last = 0.0
    lo_done = hi_done = False
    while True:
        c = math.inf
        src = -1
        if i < len(x) and x[i] < c:
            c, src = x[i], 0
        if j < len(y) and y[j] < c:
            c, src = y[j], 1
        if k < len(z) and z[k] < c:
            c, src = z[k], 2
        if not lo_done and lo <= c:
            c, src = lo, 3
        elif not hi_done and hi <= c:
            c, src = hi, 4
        if src < 0:
            break
        if src == 0:
            i += 1
        elif src == 1:
            j += 1
        elif src == 2:
            k += 1
        elif src == 3:
            lo_done = True
        else:
            hi_done = True
        if c < lo or c > hi:
            continue
        if first or c != last:
            out[n] = c
            n += 1
            first, last = False, c
    return out[:n].copy()


@_njit
def window_core(t, j, v, l, r, a, b, lo, hi, jump_times):
    n = len(t)
    cnt = 1
    for i in range(1, n):
        if t[i] != t[i - 1]:
            cnt += 1
    M = cnt
    fi = np.empty(M, np.int64)
    fi[0] = 0
    k = 1
    for i in range(1, n):
        if t[i] != t[i - 1]:
            fi[k] = i
            k += 1
    la = np.empty(M, np.int64)
    for k in range(M - 1):
        la[k] = fi[k + 1] - 1
    la[M - 1] = n - 1
    u = np.empty(M)
    P = np.empty(M)
    for k in range(M):
        u[k] = t[fi[k]]
        m = v[fi[k]]
        for i in range(fi[k] + 1, la[k] + 1):
            m = mx(m, v[i])
        P[k] = m
    L = np.full(M, _NINF)
    R = np.full(M, _NINF)
    for k in range(M - 1):
        if j[fi[k + 1]] == j[la[k]]:
            L[k + 1] = l[fi[k + 1]]
            R[k] = r[la[k]]
    Q = np.empty(M)
    for k in range(M):
        Q[k] = mx(P[k], mx(L[k], R[k]))
    E = u[M - 1]
    du = np.empty(max(M - 1, 0))
    for k in range(M - 1):
        du[k] = u[k + 1] - u[k]
    rows = 1
    while (1 << rows) <= M:
        rows += 1
    rows = max(1, rows)
    tab = np.empty((rows, max(M, 1)))
    tab[0, :M] = Q
    s = 1
    for lev in range(1, rows):
        for i in range(M - s):
            tab[lev, i] = mx(tab[lev - 1, i], tab[lev - 1, i + s])
        for i in range(max(M - s, 0), M):
            tab[lev, i] = _NINF
        s *= 2
    # the output's breakpoints
    if hi <= lo:
        taus = np.array([lo])
    else:
        taus = breakpoints(u - a, jump_times, u - b if math.isfinite(b) else u[:0],
                           lo, hi)
    K1 = len(taus)
    val = np.empty(K1)
    rest = np.empty(K1)
    ia = np.empty(K1, np.int64)
    ea = np.empty(K1, np.bool_)
    Etol = E + tol(E)
    pa = pb = 0
    for k in range(K1):
        tau = taus[k]
        alpha = tau + a
        beta = min(tau + b, E)
        i_a, e_a, pa = locate(u, M, alpha, True, pa)
        i_b, e_b, pb = locate(u, M, beta, False, pb)
        deg = (e_a and e_b and i_a == i_b) or alpha >= beta
        Pa = P[i_a] if e_a else piece(P, R, L, u, du, M, i_a, alpha)
        rs = R[i_a] if (e_a and not deg) else _NINF
        Pb = P[i_b] if e_b else piece(P, R, L, u, du, M, i_b, beta)
        if deg:
            Pb = _NINF
        rs = mx(rs, Pb)
        rs = mx(rs, L[i_b] if (e_b and not deg) else _NINF)
        rs = mx(rs, query(tab, M, i_a + 1, i_b - 1 if e_b else i_b))
        if alpha > Etol:
            Pa = _NINF
            rs = _NINF
        val[k] = mx(Pa, rs)
        rest[k] = rs
        ia[k] = i_a
        ea[k] = e_a
    vl = val.copy()
    vr = val.copy()
    K = K1 - 1
    nk = 0
    kink_t = np.empty(3 * max(K, 0))
    kink_v = np.empty(3 * max(K, 0))
    if K > 0 and M > 1:
        Y = np.empty((3, K))
        S = np.zeros((3, K))
        Cn = np.empty(K)
        gone = np.empty(K, np.bool_)
        sp = sq = 0
        for k in range(K):
            t0, t1 = taus[k], taus[k + 1]
            mid = 0.5 * (t0 + t1)
            sp = right(u, M, mid + a, sp)
            p = min(max(sp - 1, 0), M - 2)
            S[0, k] = (L[p + 1] - R[p]) / du[p]
            Y[0, k] = piece(P, R, L, u, du, M, p, t0 + a)
            bm = mid + b
            at_end = bm >= E
            sq = right(u, M, min(bm, E), sq)
            q = min(max(sq - 1, 0), M - 2)
            if at_end:
                S[1, k] = 0.0
                # Python's max, as the numpy code: NaN only where P is
                Y[1, k] = L[M - 1] if L[M - 1] > P[M - 1] else P[M - 1]
            else:
                S[1, k] = (L[q + 1] - R[q]) / du[q]
                Y[1, k] = piece(P, R, L, u, du, M, q, min(t0 + b, E))
            C = query(tab, M, p + 1, M - 2 if at_end else q)
            Y[2, k] = C
            Cn[k] = _NINF if C != C else C
            gone[k] = mid + a > E
            for side in range(2):
                x = t0 if side == 0 else t1
                out = _NINF
                for g in range(2):
                    y0, sl = Y[g, k], S[g, k]
                    yy = y0 if sl == 0 else y0 + sl * (x - t0)
                    out = mx(out, _NINF if yy != yy else yy)
                out = mx(out, Cn[k])
                if gone[k]:
                    out = _NINF
                if side == 0:
                    vr[k] = out
                else:
                    vl[k + 1] = out
        for g0, g1 in ((0, 1), (0, 2), (1, 2)):
            for k in range(K):
                t0, t1 = taus[k], taus[k + 1]
                ds = S[g0, k] - S[g1, k]
                if ds == 0 or gone[k]:
                    continue
                tk = t0 - (Y[g0, k] - Y[g1, k]) / ds
                if not (math.isfinite(tk) and tk > t0 and tk < t1):
                    continue
                kv = _NINF
                for g in range(3):
                    sl = S[g, k]
                    yy = Y[g, k] + (0.0 if sl == 0 else sl * (tk - t0))
                    kv = mx(kv, _NINF if yy != yy else yy)
                kink_t[nk] = tk
                kink_v[nk] = kv
                nk += 1
    return (taus, val, vl, vr, rest, ea, ia, kink_t[:nk].copy(), kink_v[:nk].copy(),
            fi, la)


@_njit
def stable_order(x):
    """``np.argsort(x, kind="stable")`` for an ``x`` made of a few sorted runs
    (the breakpoints, then each kind of kink): the runs merged pairwise, the
    left one first on ties, in linear time a merge."""
    n = len(x)
    order = np.arange(n)
    starts = [0]
    for i in range(1, n):
        if x[i] < x[i - 1]:
            starts.append(i)
    starts.append(n)
    buf = np.empty(n, np.int64)
    while len(starts) > 2:
        nxt = [0]
        for q in range(0, len(starts) - 1, 2):
            a0 = starts[q]
            if q + 2 >= len(starts):
                nxt.append(starts[q + 1])
                continue
            a1, a2 = starts[q + 1], starts[q + 2]
            i, k, w = a0, a1, a0
            while i < a1 and k < a2:
                if x[order[k]] < x[order[i]]:
                    buf[w] = order[k]
                    k += 1
                else:
                    buf[w] = order[i]
                    i += 1
                w += 1
            while i < a1:
                buf[w] = order[i]
                i += 1
                w += 1
            while k < a2:
                buf[w] = order[k]
                k += 1
                w += 1
            order[a0:a2] = buf[a0:a2]
            nxt.append(a2)
        starts = nxt
    return order


@_njit
def window_sup(t, j, v, l, r, a, b, lo, hi, jump_times, at, aj, run_end):
    """:func:`hybridsim._stl_eval._window_sup` after its core, compiled: the
    window's breakpoints and kinks merged in time order (a stable sort, as
    numpy's), spread over every instant of the arc (``at``, ``aj``,
    ``run_end``: the evaluation's :meth:`_Context.domain`), and a window
    starting at an evaluation instant read from that instant's j on. Returns
    the output signal's ``(T, J, v, l, r)``, the numpy code's to the bit."""
    taus, val, vl, vr, rest, ea, ia, kink_t, kink_v, fi, la = window_core(
        t, j, v, l, r, a, b, lo, hi, jump_times)
    K1, nk = len(taus), len(kink_t)
    nt = K1 + nk
    times = np.empty(nt)
    times[:K1] = taus
    times[K1:] = kink_t
    order = stable_order(times)
    tt = times[order]
    V = np.empty(nt)
    Lv = np.empty(nt)
    Rv = np.empty(nt)
    Re = np.empty(nt)
    own = np.zeros(nt, np.bool_)
    Ia = np.zeros(nt, np.int64)
    for q in range(nt):
        o = order[q]
        if o < K1:
            V[q], Lv[q], Rv[q], Re[q] = val[o], vl[o], vr[o], rest[o]
            own[q] = ea[o] and a == 0.0
            Ia[q] = ia[o]
        else:
            kv = kink_v[o - K1]
            V[q] = Lv[q] = Rv[q] = Re[q] = kv
    # the arc's instants at each time (its first sample there, its last)
    N = len(at)
    jlo = np.empty(nt, np.int64)
    cnt = np.empty(nt, np.int64)
    ptr = 0
    n = 0
    for q in range(nt):
        x = tt[q]
        while ptr < N and at[ptr] < x:
            ptr += 1
        i0 = min(ptr, N - 1)
        i1 = run_end[i0] if at[i0] == x else ptr - 1
        i1 = max(i1, 0)
        lo_j, hi_j = aj[i0], aj[i1]
        lo_j = min(lo_j, hi_j)
        jlo[q] = lo_j
        cnt[q] = hi_j - lo_j + 1
        n += cnt[q]
    T = np.empty(n)
    J = np.empty(n, np.int64)
    Vd = np.empty(n)
    Lo = np.empty(n)
    Ro = np.empty(n)
    w = 0
    for q in range(nt):
        c_q = cnt[q]
        for e in range(c_q):
            fst, lst = e == 0, e == c_q - 1
            T[w] = tt[q]
            J[w] = jlo[q] + e
            vd = V[q]
            if own[q] and not (fst and lst):
                # the max of v over the signal's instants of its time from J[w] on
                g = Ia[q]
                c = min(max(fi[g] + (J[w] - j[fi[g]]), fi[g]), la[g])
                vs = v[c]
                for i in range(c + 1, la[g] + 1):
                    vs = mx(vs, v[i])
                vd = mx(Re[q], vs)
            Vd[w] = vd
            Lo[w] = Lv[q] if fst else vd
            Ro[w] = Rv[q] if lst else vd
            w += 1
    return T, J, Vd, Lo, Ro
