"""The robustness computation of :mod:`hybridsim.stl` (its Semantics
section): the piecewise-linear signals on a hybrid time domain (``_Sig``),
their exact pointwise min and max, the sup over sliding windows, the
untimed until, one evaluation's context, and the dense-time evaluation of
a predicate (its instants: samples, extrema, crossings), of a window
``F``/``G`` and of until, as the bases of those formulas' nodes.
"""
from __future__ import annotations

import math

import numpy as np

from ._arc_access import between_samples
from .rules import event_tolerance
from .testing import Margin, _every

_INF = math.inf
_EPS = np.finfo(float).eps


def _num(v):
    """A number as the formula's text prints it."""
    v = float(v)
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if v == int(v) and abs(v) < 1e15:
        return str(int(v))
    return format(v, ".15g")


def _tol(x):
    """The engine's event tolerance at x (4 ulp of max(1, |x|)), elementwise."""
    return 4.0 * _EPS * np.maximum(1.0, np.abs(x))


def _clip(x, lo, hi):
    """np.clip(x, lo, hi) (hi where lo > hi), without its per-call overhead."""
    return np.minimum(np.maximum(x, lo), hi)


def _search(a, x, side):
    """np.searchsorted(a, x, side) for a sorted ``a``: where x is long and
    sorted too, by one stable merge of both (numpy's binary search starts
    each key afresh), else numpy's."""
    nx = len(x)
    if nx < 512 or not np.all(x[1:] >= x[:-1]):
        return np.searchsorted(a, x, side=side)
    if side == "left":                  # a key before the equal entries of a
        order = np.argsort(np.concatenate((x, a)), kind="stable")
        pos = np.flatnonzero(order < nx)
    else:
        order = np.argsort(np.concatenate((a, x)), kind="stable")
        pos = np.flatnonzero(order >= len(a))
    pos -= np.arange(nx)
    return pos


def _lerp(y0, y1, w):
    """y0 + w (y1 - y0), the nearer end where an end is not finite."""
    with np.errstate(invalid="ignore"):
        out = y0 + w * (y1 - y0)
    bad = ~np.isfinite(out)
    if np.any(bad):
        y0, y1, w = np.broadcast_arrays(np.asarray(y0, float), np.asarray(y1, float),
                                        np.asarray(w, float))
        fin = np.isfinite(y0) & np.isfinite(y1)
        out = np.where(fin, out, np.where(w < 0.5, y0, y1))
    return out


# ----------------------------------------------------------- signal values --

class _Sig:
    """A robustness signal on a hybrid time domain.

    Instants (t, j) sorted in hybrid time; ``v`` the value at each, ``l``
    and ``r`` its limits from the left and the right within the flow
    (between two instants of the same j the signal is linear from ``r[k]``
    to ``l[k + 1]``).
    """

    __slots__ = ("t", "j", "v", "l", "r")

    def __init__(self, t, j, v, l=None, r=None):
        self.t, self.j, self.v = t, j, v
        self.l = v if l is None else l
        self.r = v if r is None else r

    def neg(self):
        return _Sig(self.t, self.j, -self.v, -self.l, -self.r)

    def succ(self):
        """Mask: the instant has a later instant of the same flow."""
        s = np.zeros(len(self.t), dtype=bool)
        s[:-1] = self.j[1:] == self.j[:-1]
        return s

    def pred(self):
        p = np.zeros(len(self.t), dtype=bool)
        p[1:] = self.j[1:] == self.j[:-1]
        return p


def _sorted_points(T, J, *arrays):
    order = np.lexsort((J, T))
    return (T[order], J[order]) + tuple(a[order] for a in arrays)


def _merge(s1, s2):
    """Both signals on the union of their instants: T, J, (v, l, r) of each."""
    n1 = len(s1.t)
    T = np.concatenate((s1.t, s2.t))
    J = np.concatenate((s1.j, s2.j))
    order = np.lexsort((J, T))
    Ts, Js = T[order], J[order]
    new = np.ones(len(Ts), dtype=bool)
    new[1:] = (Ts[1:] != Ts[:-1]) | (Js[1:] != Js[:-1])
    uid = np.cumsum(new) - 1
    Tu, Ju = Ts[new], Js[new]
    out = [Tu, Ju]
    for s, mine, shift in ((s1, order < n1, 0), (s2, order >= n1, n1)):
        idx = np.full(len(Tu), -1)
        idx[uid[mine]] = order[mine] - shift
        out.append(_values_at(s, Tu, idx))
    return out


def _values_at(s, T, idx):
    """(v, l, r) of ``s`` at instants T (sorted), ``idx`` its own instants' indices or -1."""
    have = idx >= 0
    v, l, r = np.empty(len(T)), np.empty(len(T)), np.empty(len(T))
    v[have], l[have], r[have] = s.v[idx[have]], s.l[idx[have]], s.r[idx[have]]
    miss = np.flatnonzero(~have)
    if miss.size:
        prev = np.maximum.accumulate(np.where(have, idx, -1))[miss]
        n = len(s.t)
        k0 = _clip(prev, 0, max(n - 2, 0))
        k1 = np.minimum(k0 + 1, n - 1)
        h = s.t[k1] - s.t[k0]
        with np.errstate(invalid="ignore", divide="ignore"):
            w = np.where(h > 0, (T[miss] - s.t[k0]) / np.where(h > 0, h, 1.0), 0.0)
        w = _clip(w, 0.0, 1.0)
        val = _lerp(s.r[k0], s.l[k1], w)
        v[miss] = l[miss] = r[miss] = val
    return v, l, r


def _combine(s1, s2, op):
    """The pointwise ``op`` (np.minimum or np.maximum) of two signals, exactly."""
    T, J, (v1, l1, r1), (v2, l2, r2) = _merge(s1, s2)
    same = J[1:] == J[:-1]
    d0 = r1[:-1] - r2[:-1]
    d1 = l1[1:] - l2[1:]
    with np.errstate(invalid="ignore"):
        cross = same & np.isfinite(d0) & np.isfinite(d1) & (d0 * d1 < 0)
    k = np.flatnonzero(cross)
    v, l, r = op(v1, v2), op(l1, l2), op(r1, r2)
    if k.size:
        w = d0[k] / (d0[k] - d1[k])
        tc = T[k] + w * (T[k + 1] - T[k])
        inside = (tc > T[k]) & (tc < T[k + 1])      # a crossing at an instant is one already
        k, w, tc = k[inside], w[inside], tc[inside]
        vc = _lerp(r1[k], l1[k + 1], w)
        T, J, v, l, r = _sorted_points(np.concatenate((T, tc)), np.concatenate((J, J[k])),
                                       np.concatenate((v, vc)), np.concatenate((l, vc)),
                                       np.concatenate((r, vc)))
    return _Sig(T, J, v, l, r)


class _RangeMax:
    """Maxima of q over index ranges [i0, i1] (a sparse table, O(n log n)): row
    L of ``table`` holds the maxima of q over [i, i + 2^L - 1] (-inf past the end)."""

    def __init__(self, q):
        q = np.asarray(q, float)
        n = len(q)
        rows = max(1, int(n).bit_length())
        self.table = tab = np.empty((rows, max(n, 1)))
        tab[0, :n] = q
        k = 1
        for L in range(1, rows):
            np.maximum(tab[L - 1, :n - k], tab[L - 1, k:n], out=tab[L, :n - k])
            tab[L, n - k:] = -_INF
            k *= 2

    def query(self, i0, i1):
        """max of q over [i0, i1] elementwise (-inf where i1 < i0); indices with
        -1 <= i1 and i0 <= len(q)."""
        i0, i1 = np.asarray(i0, np.int64), np.asarray(i1, np.int64)
        n = i1 - i0 + 1
        ok = n > 0
        # floor(log2(n)), exactly (frexp: n = f 2^e with 0.5 <= f < 1); 0 where empty
        lev = np.frexp(np.maximum(n, 1).astype(float))[1] - 1
        w = self.table.shape[1]
        flat = self.table.ravel()
        base = lev * w
        out = np.maximum(flat[base + np.minimum(i0, w - 1)],
                         flat[base + np.maximum(i1 - (np.int64(1) << lev) + 1, 0)])
        return np.where(ok, out, -_INF)


# --------------------------------------------------------- evaluation state --

class _Context:
    """One evaluation: the arc, its domain, the options, the computed signals."""

    def __init__(self, arc, strict, refine):
        self.arc = arc
        self.t, self.j, self.x = (np.asarray(arc.t, float), np.asarray(arc.j, np.int64),
                                  np.asarray(arc.x, float))
        self.xdot = None if arc.xdot is None else np.asarray(arc.xdot, float)
        self.strict, self.refine = strict, refine
        self.t0, self.tf = float(self.t[0]), float(self.t[-1])
        self.jump_times = np.unique(self.t[1:][np.diff(self.j) > 0])
        # the index of the last sample at each sample's time
        ends = np.flatnonzero(np.append(self.t[1:] != self.t[:-1], True))
        self.run_end = np.repeat(ends, np.diff(np.append(-1, ends)))
        # keyed by id(node): every node memoised is kept alive with its value, so a
        # node made during the evaluation (until's rewriting) cannot hand its id on
        self.memo = {}

    def domain(self, times):
        """Every instant (t, j) of the arc at the given times (sorted): T, J and
        masks of each time's first and last instant."""
        times = np.asarray(times, float)
        N = len(self.t)
        i = _search(self.t, times, "left")
        i0 = np.minimum(i, N - 1)
        # the last sample at each time (side="right" - 1), from the first one
        i1 = np.maximum(np.where(self.t[i0] == times, self.run_end[i0], i - 1), 0)
        jlo, jhi = self.j[i0], self.j[i1]
        jlo = np.minimum(jlo, jhi)
        cnt = jhi - jlo + 1
        start = np.cumsum(cnt) - cnt
        n = int(start[-1] + cnt[-1]) if len(cnt) else 0
        if n == len(times):                     # one instant at each time
            one = np.ones(n, dtype=bool)
            return times, jlo, one, one.copy(), np.arange(n)
        src = np.repeat(np.arange(len(times)), cnt)
        T = times[src]
        J = np.arange(n) + (jlo - start)[src]
        first = np.zeros(n, dtype=bool)
        first[start] = True
        last = np.zeros(n, dtype=bool)
        last[start + cnt - 1] = True
        return T, J, first, last, src

    def states(self, T, J):
        """The arc's interpolant at the instants (T, J) (:meth:`HybridArc.at`)."""
        if len(T) == 0:
            return np.zeros((0, self.x.shape[1]))
        interp = getattr(self.arc, "_interp", None)
        if interp is None:
            return np.asarray(self.arc.at(T, j=J), dtype=float).reshape(len(T), -1)
        # the instants are the evaluation's own (finite, in the domain): read
        # without at()'s checks of the user's arguments
        return interp(np.asarray(T, float), np.asarray(J, np.int64), "robustness")[0]

    def steps(self, T, J):
        """The arc's step k (samples k and k + 1 of flow J) holding each time T
        of a piece between two instants of flow J; None where the arc has a
        dense output (its states are then read through :meth:`states`)."""
        if getattr(self.arc, "_segments", None):
            return None
        a = np.searchsorted(self.j, J, side="left")
        b = np.searchsorted(self.j, J, side="right")
        return _clip(np.searchsorted(self.t, T, side="right") - 1, a, b - 2)

    def inside(self, k, T, J):
        """The interpolant at times T in the steps ``k`` (:meth:`steps`) of flow J,
        as :meth:`states` reads it (the samples at theirs, else
        :func:`hybridsim._arc_access.between_samples`), without locating the
        steps again: what the root and extremum searches evaluate."""
        if k is None:
            return self.states(T, J)
        out = between_samples(self.t, self.x, self.xdot, k, T)
        for kk in (k, k + 1):
            e = self.t[kk] == T
            if e.any():
                out[e] = self.x[kk[e]]
        return out


def _value(sig, tau, j):
    """The value of a signal at the instant (tau, j)."""
    k = np.flatnonzero((sig.t == tau) & (sig.j == j))
    if k.size:
        return float(sig.v[k[0]])
    m = np.flatnonzero((sig.j == j) & (sig.t < tau))
    if not m.size:
        return float(sig.v[int(np.argmin(np.abs(sig.t - tau)))])
    k0 = int(m[-1])
    if k0 + 1 < len(sig.t) and sig.j[k0 + 1] == j:
        w = (tau - sig.t[k0]) / (sig.t[k0 + 1] - sig.t[k0])
        return float(_lerp(sig.r[k0], sig.l[k0 + 1], min(max(w, 0.0), 1.0)))
    return float(sig.v[k0])


def _window_core(t, j, v, l, r, a, b, lo, hi, jump_times):
    """The window's value at the output's breakpoints over [lo, hi] (the times
    ``taus``), its limits from the right and the left (``vr``, ``vl``), the
    part read past the window's start (``rest``), where the start falls
    (``ia``, at an instant: ``ea``), the kinks inside the open pieces, and the
    first and last index of each time of the signal (``fi``, ``la``).
    :mod:`hybridsim._stl_window_nb` is the same, compiled."""
    n = len(t)
    first = np.empty(n, dtype=bool)
    first[0] = True
    np.not_equal(t[1:], t[:-1], out=first[1:])
    fi = np.flatnonzero(first)
    M = len(fi)
    la = np.empty(M, dtype=fi.dtype)
    la[:-1] = fi[1:] - 1
    la[-1] = n - 1
    u = t[fi]
    P = v if M == n else np.maximum.reduceat(v, fi)
    # L (R): the limit from the left (right) at each time, where the flow goes on
    conn = j[fi[1:]] == j[la[:-1]]
    L = np.full(M, -_INF)
    L[1:] = np.where(conn, l[fi[1:]], -_INF)
    R = np.full(M, -_INF)
    R[:-1] = np.where(conn, r[la[:-1]], -_INF)
    Q = np.maximum(P, np.maximum(L, R))
    E = u[-1]
    rm = _RangeMax(Q)
    du = np.diff(u)

    def piece(p, x):
        if M == 1:
            return np.full(np.shape(x), P[0])
        p = _clip(p, 0, M - 2)
        return _lerp(R[p], L[p + 1], (x - u[p]) / du[p])

    def locate(x, first):
        """The instant within the engine's tolerance of x (the first such for a
        window's start, the last for its end), else the piece x lies in."""
        tx = _tol(x)
        # x - tx and x + tx are rounded: an instant found just outside the
        # tolerance is on the other side of x than the search assumed
        if first:
            i = np.minimum(_search(u, x - tx, "left"), M - 1)
            ui = u[i]
            hit = np.abs(ui - x) <= tx
            return np.where(hit, i, _clip(np.where(ui < x, i, i - 1), 0, max(M - 2, 0))), hit
        i = np.maximum(_search(u, x + tx, "right") - 1, 0)
        ui = u[i]
        hit = np.abs(ui - x) <= tx
        return np.where(hit, i, _clip(np.where(ui > x, i - 1, i), 0, max(M - 2, 0))), hit

    # the output's breakpoints
    if hi <= lo:
        taus = np.array([lo])
    else:
        cand = [np.array([lo, hi]), u - a, jump_times]
        if math.isfinite(b):
            cand.append(u - b)
        c = np.concatenate(cand)
        taus = np.unique(c[(c >= lo) & (c <= hi)])
    alpha = taus + a
    beta = np.minimum(taus + b, E)
    empty = alpha > E + _tol(E)
    ia, ea = locate(alpha, True)
    ib, eb = locate(beta, False)
    deg = ea & eb & (ia == ib) | (alpha >= beta)
    # the window's start (its instants, or the piece it falls in), and the rest
    Pa = P[ia]
    k = np.flatnonzero(~ea)
    if k.size:
        Pa[k] = piece(ia[k], alpha[k])
    rest = np.where(ea & ~deg, R[ia], -_INF)
    Pb = P[ib]
    k = np.flatnonzero(~eb)
    if k.size:
        Pb[k] = piece(ib[k], beta[k])
    Pb[deg] = -_INF
    rest = np.maximum(rest, Pb)
    rest = np.maximum(rest, np.where(eb & ~deg, L[ib], -_INF))
    rest = np.maximum(rest, rm.query(ia + 1, np.where(eb, ib - 1, ib)))
    Pa[empty] = rest[empty] = -_INF
    val = np.maximum(Pa, rest)
    # the open intervals between breakpoints: max of two lines and a constant
    K = len(taus) - 1
    vl, vr = val.copy(), val.copy()
    kink_t = np.zeros(0)
    kink_v = np.zeros(0)
    if K > 0 and M > 1:
        t0, t1 = taus[:-1], taus[1:]
        mid = 0.5 * (t0 + t1)
        p = _clip(_search(u, mid + a, "right") - 1, 0, M - 2)
        sA = (L[p + 1] - R[p]) / du[p]
        A0 = piece(p, t0 + a)
        bm = mid + b
        at_end = bm >= E
        q = _clip(_search(u, np.minimum(bm, E), "right") - 1, 0, M - 2)
        sB = np.where(at_end, 0.0, (L[q + 1] - R[q]) / du[q])
        B0 = np.where(at_end, max(P[-1], L[-1]), piece(q, np.minimum(t0 + b, E)))
        C = rm.query(p + 1, np.where(at_end, M - 2, q))
        gone = mid + a > E
        lines = [(A0, sA), (B0, sB), (C, np.zeros(K))]
        Cn = np.where(np.isnan(C), -_INF, C)

        def at(x):
            out = np.full(K, -_INF)
            for y0, sl in lines[:2]:
                with np.errstate(invalid="ignore"):
                    yy = np.where(sl == 0, y0, y0 + sl * (x - t0))
                out = np.maximum(out, np.where(np.isnan(yy), -_INF, yy))
            out = np.maximum(out, Cn)           # the constant
            out[gone] = -_INF
            return out

        vr[:-1] = at(t0)
        vl[1:] = at(t1)
        ks, ts = [], []
        for (y0, s0), (y1, s1) in ((lines[0], lines[1]), (lines[0], lines[2]),
                                   (lines[1], lines[2])):
            ds = s0 - s1
            with np.errstate(invalid="ignore", divide="ignore"):
                tk = t0 - (y0 - y1) / ds
            ok = (ds != 0) & np.isfinite(tk) & (tk > t0) & (tk < t1) & ~gone
            ks.append(np.flatnonzero(ok))
            ts.append(tk[ok])
        kk = np.concatenate(ks)
        if kk.size:
            kink_t = np.concatenate(ts)
            kink_v = np.full(kk.size, -_INF)
            for y0, sl in lines:
                with np.errstate(invalid="ignore"):
                    yy = y0[kk] + np.where(sl[kk] == 0, 0.0, sl[kk] * (kink_t - t0[kk]))
                kink_v = np.maximum(kink_v, np.where(np.isnan(yy), -_INF, yy))
    return taus, val, vl, vr, rest, ea, ia, kink_t, kink_v, fi, la


_COMPILED = []


def _compiled_core():
    """:mod:`hybridsim._stl_window_nb` where numba is installed, else None."""
    if not _COMPILED:
        try:
            from . import _stl_window_nb
        except ImportError:
            _stl_window_nb = None
        _COMPILED.append(_stl_window_nb)
    return _COMPILED[0]


#: CPU seconds the compiled window takes to compile with an empty cache (the notice's)
WINDOW_COMPILE_SECONDS = 10


def _say_compiling(fast):
    """Say, once per process, that the compiled window is about to be compiled
    (:func:`hybridsim.compiled._system._notice`: one line on stderr, or the
    ``hybridsim.compiled`` logger where logging is configured), where it is
    neither compiled in this process nor in numba's disk cache; a first STL
    robustness on a long signal is otherwise silent for seconds."""
    if _COMPILED_SAID or fast.window_sup.overloads:
        return
    _COMPILED_SAID.append(True)
    from .compiled._system import _notice
    try:        # numba's private cache API (any entry: the window has one signature)
        cache = fast.window_sup._cache
        if cache._cache_file._load_index():
            return
        where = cache._cache_path
    except Exception:  # noqa: BLE001 - another numba, or not cached: say it compiles
        where = None
    _notice(where, WINDOW_COMPILE_SECONDS,
            what="the STL window (hybridsim._stl_window_nb, for signals of "
                 f"{fast.MIN_INSTANTS} instants and more)")


_COMPILED_SAID = []


def _window_sup(ctx, s, a, b, lo, hi):
    """sup of ``s`` over [tau + a, tau + b] (cut at the end of s), for tau in [lo, hi]."""
    v = s.v
    fast = _compiled_core()
    arr = np.ascontiguousarray
    args = (arr(s.t, float), arr(s.j, np.int64), arr(v, float), arr(s.l, float),
            arr(s.r, float), float(a), float(b), float(lo), float(hi),
            arr(ctx.jump_times, float))
    if fast is not None and len(s.t) >= fast.MIN_INSTANTS:
        _say_compiling(fast)
        return _Sig(*fast.window_sup(*args, arr(ctx.t), arr(ctx.j), arr(ctx.run_end)))
    taus, val, vl, vr, rest, ea, ia, kink_t, kink_v, fi, la = _window_core(*args)
    nk = len(kink_t)
    times = np.concatenate((taus, kink_t))
    V = np.concatenate((val, kink_v))
    Lv = np.concatenate((vl, kink_v))
    Rv = np.concatenate((vr, kink_v))
    Re = np.concatenate((rest, kink_v))
    own = np.concatenate((ea & (a == 0.0), np.zeros(nk, dtype=bool)))
    Ia = np.concatenate((ia, np.zeros(nk, dtype=np.int64)))
    order = np.argsort(times, kind="stable")
    times, V, Lv, Rv, Re, own, Ia = (z[order] for z in (times, V, Lv, Rv, Re, own, Ia))
    T, J, fst, lst, src = ctx.domain(times)
    Vd = V[src]
    # a window starting at the evaluation instant (tau, j) itself reads the
    # instants of tau from j on, not those before it in hybrid time
    sp = own[src] & ~(fst & lst)
    k = np.flatnonzero(sp)
    if k.size:
        g = Ia[src[k]]
        c = _clip(fi[g] + (J[k] - s.j[fi[g]]), fi[g], la[g])
        # the max of v over the instants of its time from c on
        vs, end = v[c], la[g]
        off = 1
        while True:
            m = np.flatnonzero(c + off <= end)
            if not m.size:
                break
            vs[m] = np.maximum(vs[m], v[c[m] + off])
            off += 1
        Vd[k] = np.maximum(Re[src[k]], vs)
    return _Sig(T, J, Vd, np.where(fst, Lv[src], Vd), np.where(lst, Rv[src], Vd))


def _restrict(ctx, s, lo, hi):
    """``s`` on [lo, hi] (instants added at the ends where they fall inside a piece)."""
    T, J, *_ = ctx.domain(np.array([lo, hi]) if hi > lo else np.array([lo]))
    Tm, Jm, (v, l, r), _ = _merge(s, _Sig(T, J, np.zeros(len(T))))
    m = (Tm >= lo) & (Tm <= hi)
    return _Sig(Tm[m], Jm[m], v[m], l[m], r[m])


def _untimed_until(sp, sq):
    """phi U psi (untimed, to the end of the signals) at the instants of both.

    At the union of the instants and the crossings of phi and psi, both and
    m = min(phi, psi) are linear on every open piece, where
    U(T_k+) = max(min(max(m(T_k+), m(T_k+1 -)), phi(T_k+)),
    min(phi(T_k+), phi(T_k+1 -), U(T_k+1))) and at each instant
    U(T_k) = max(m(T_k), min(phi(T_k), U(T_k+))): each a map
    x -> max(a, min(b, x)), a family closed under composition
    ((a1, b1) after (a2, b2) is (max(a1, min(b1, a2)), min(b1, b2))), so the
    backward recursion is a suffix scan, O(n log n) in numpy.
    """
    mn = _combine(sp, sq, np.minimum)           # every instant of both, and their crossings
    T, J = mn.t, mn.j
    _, _, (pv, pl, pr), _ = _merge(sp, mn)
    n = len(T)
    succ = np.zeros(n, dtype=bool)
    succ[:-1] = J[1:] == J[:-1]
    A = np.full(2 * n, -_INF)
    B = np.full(2 * n, _INF)
    A[0::2], B[0::2] = mn.v, pv                 # the instant T_k
    k = np.flatnonzero(succ)                    # the open piece after it
    A[2 * k + 1] = np.minimum(np.maximum(mn.r[k], mn.l[k + 1]), pr[k])
    B[2 * k + 1] = np.minimum(pr[k], pl[k + 1])
    s = 1
    while s < 2 * n:
        a2 = np.concatenate((A[s:], np.full(s, -_INF)))
        b2 = np.concatenate((B[s:], np.full(s, _INF)))
        A, B = np.maximum(A, np.minimum(B, a2)), np.minimum(B, b2)
        s *= 2
    U = A[0::2]
    right = np.where(succ, A[1::2], U)
    left = np.empty(n)
    left[0] = U[0]
    # U(T_k -) from the piece before: max(m(T_k -), min(phi(T_k -), U(T_k)))
    left[1:] = np.where(succ[:-1], np.maximum(mn.l[1:], np.minimum(pl[1:], U[1:])), U[1:])
    return _Sig(T, J, U, left, right)


# ------------------------------------------------------ evaluation of nodes --

class _PredicateEval:
    """A predicate's robustness at its instants (a base of ``stl._Predicate``)."""

    def _compute(self, ctx, lo, hi, probes):
        lo, hi = max(lo, ctx.t0), min(hi, ctx.tf)
        if hi <= lo:                            # one time: its instants' values
            T, J, *_ = ctx.domain(np.array([lo]))
            return _Sig(T, J, self._at(ctx, T, J))
        base = self._intrinsic(ctx)
        # the instants within the engine's tolerance of the range count as in it
        a = int(np.searchsorted(base.t, lo - _tol(lo), side="left"))
        b = int(np.searchsorted(base.t, hi + _tol(hi), side="right"))
        T, J, v = base.t[a:b], base.j[a:b], base.v[a:b]
        e = np.array([lo, hi])
        if len(probes):
            p = np.asarray(sorted(probes), float)
            e = np.concatenate((e, p[(p > lo) & (p < hi)]))
        e = np.unique(e)
        if len(T):                              # not an instant already (T is sorted)
            k = np.minimum(np.searchsorted(T, e), len(T) - 1)
            e = e[T[k] != e]
        if e.size:
            Te, Je, *_ = ctx.domain(e)
            T, J, v = _sorted_points(np.concatenate((T, Te)), np.concatenate((J, Je)),
                                     np.concatenate((v, self._at(ctx, Te, Je))))
            T, J, v = self._crossings(ctx, T, J, v)
        return _Sig(T, J, v)

    def _intrinsic(self, ctx):
        """The predicate at its instants over the whole arc (computed once per
        evaluation): the samples, the extrema inside the steps, the crossings."""
        key = ("instants", id(self))
        hit = ctx.memo.get(key)
        got = None if hit is None or hit[0] is not self else hit[1]
        if got is None:
            T, J = ctx.t, ctx.j
            v = self._rho(T, J, ctx.x)
            if ctx.refine > 1 and len(T) > 1:
                dv = self._slopes(ctx)
                if dv is not False:
                    T, J, v = self._extrema(ctx, T, J, v, dv)
            got = self._crossings(ctx, T, J, v)
            ctx.memo[key] = (self, got)
        return _Sig(*got)

    def _crossings(self, ctx, T, J, v):
        """Add the zeros of rho inside the steps where it changes sign (value 0)."""
        with np.errstate(invalid="ignore"):
            k = np.flatnonzero((J[1:] == J[:-1]) & (v[:-1] * v[1:] < 0)
                               & np.isfinite(v[:-1]) & np.isfinite(v[1:]))
        if k.size:
            tc = self._roots(ctx, T[k], T[k + 1], v[k], v[k + 1], J[k])
            inside = (tc > T[k]) & (tc < T[k + 1])  # else within 4 ulp of an instant
            k, tc = k[inside], tc[inside]
            T, J, v = _sorted_points(np.concatenate((T, tc)), np.concatenate((J, J[k])),
                                     np.concatenate((v, np.zeros(len(tc)))))
        return T, J, v

    def _rho(self, T, J, X):
        v = np.asarray(self.rho._values(T, J, X), dtype=float).reshape(len(T))
        return np.where(np.isnan(v), -_INF, v)

    def _at(self, ctx, T, J):
        return self._rho(T, J, ctx.states(T, J))

    def _inside(self, ctx, k, T, J):
        """rho at times T in the arc's steps k (:meth:`_Context.steps`)."""
        return self._rho(T, J, ctx.inside(k, T, J))

    def _slopes(self, ctx):
        """d rho / dt at the arc's samples by the chain rule from ``xdot`` (NaN
        where xdot is); None where unknown (a user function, or no xdot);
        False when rho is affine in (x, t) on an arc interpolated linearly (it
        has no extremum inside a step)."""
        arc = ctx.arc
        if arc.xdot is None:
            linear = not getattr(arc, "_segments", None)
            return False if linear and self.rho._affine() is not None else None
        XD = np.asarray(arc.xdot, dtype=float)
        with np.errstate(invalid="ignore"):
            d = self.rho._dt(ctx.t, ctx.j, ctx.x, XD)
        return None if d is None else np.asarray(d, dtype=float).reshape(len(ctx.t))

    def _extrema(self, ctx, T, J, v, dv=None):
        """Probe ``refine - 1`` interpolant values inside every step and add each
        local extremum they reveal, located by parabolic interpolation. With
        the slopes ``dv`` at the instants known, only the steps where the
        slope changes sign (or is unknown at an end) are probed."""
        k = np.flatnonzero(J[1:] == J[:-1])
        if dv is not None and k.size:
            with np.errstate(invalid="ignore"):
                k = k[~(dv[k] * dv[k + 1] > 0)]
        if not k.size:
            return T, J, v
        m = ctx.refine - 1
        w = np.arange(1, m + 1) / (m + 1)
        h = T[k + 1] - T[k]
        S = T[k][:, None] + w[None, :] * h[:, None]                 # (steps, m)
        Js = np.repeat(J[k], m)
        st = ctx.steps(T[k], J[k])
        Vs = self._inside(ctx, None if st is None else np.repeat(st, m), S.ravel(),
                          Js).reshape(len(k), m)
        tt = np.hstack((T[k][:, None], S, T[k + 1][:, None]))         # (steps, m + 2)
        vv = np.hstack((v[k][:, None], Vs, v[k + 1][:, None]))
        with np.errstate(invalid="ignore"):
            d = np.diff(vv, axis=1)
            peak = (d[:, :-1] > 0) & (d[:, 1:] < 0)
            dip = (d[:, :-1] < 0) & (d[:, 1:] > 0)
        # the extrema become instants (the probes only reveal them: an excursion
        # of the sign between samples shows in its extremum, and so its crossings)
        ext_t, ext_j, ext_v = [], [], []
        r, c = np.nonzero(peak | dip)
        if r.size:
            sgn = np.where(peak[r, c], -1.0, 1.0)          # minimise sgn * rho
            jj = J[k][r]
            x, fx = self._minimum(ctx, tt[r, c], tt[r, c + 1], tt[r, c + 2], sgn * vv[r, c],
                                  sgn * vv[r, c + 1], sgn * vv[r, c + 2], sgn, jj, h[r],
                                  None if st is None else st[r])
            ext_t.append(x)
            ext_j.append(jj)
            ext_v.append(sgn * fx)
        return _sorted_points(np.concatenate([T] + ext_t), np.concatenate([J] + ext_j),
                              np.concatenate([v] + ext_v))

    def _minimum(self, ctx, lo, mid, hi, flo, fmid, fhi, sgn, J, h, steps):
        """Minima of ``sgn * rho`` in brackets (lo, mid, hi) with fmid below both
        ends: successive parabolic interpolation, golden-section where a
        vertex falls outside, until a step or the bracket is below 1e-5 or
        1e-6 of the arc's step. ``steps``: the arc's step of each bracket
        (:meth:`_Context.steps`)."""
        g = 0.5 * (3.0 - math.sqrt(5.0))
        live = np.ones(len(lo), dtype=bool)
        for _ in range(60):
            live &= (hi - lo) > 1e-6 * h + _tol(hi)
            if not live.any():
                break
            i = np.flatnonzero(live)
            a, m, b, fa, fm, fb = lo[i], mid[i], hi[i], flo[i], fmid[i], fhi[i]
            p = (m - a) ** 2 * (fm - fb) - (m - b) ** 2 * (fm - fa)
            q = (m - a) * (fm - fb) - (m - b) * (fm - fa)
            with np.errstate(invalid="ignore", divide="ignore"):
                x = m - 0.5 * p / q
            gold = np.where(b - m > m - a, m + g * (b - m), m - g * (m - a))
            usable = np.isfinite(x) & (x > a) & (x < b)
            # converged: a parabolic step this short moves the value by O(step^2)
            conv = usable & (np.abs(x - m) <= 1e-5 * h[i])
            if conv.any():
                live[i[conv]] = False
                keep = ~conv
                i, a, m, b, fa, fm, fb = (y[keep] for y in (i, a, m, b, fa, fm, fb))
                x, gold, usable = x[keep], gold[keep], usable[keep]
                if not i.size:
                    break
            x = np.where(usable, x, gold)
            fx = sgn[i] * self._inside(ctx, None if steps is None else steps[i], x, J[i])
            better = fx < fm
            left = x < m
            # the new bracket around the best point so far
            lo[i] = np.where(better, np.where(left, a, m), np.where(left, x, a))
            flo[i] = np.where(better, np.where(left, fa, fm), np.where(left, fx, fa))
            hi[i] = np.where(better, np.where(left, m, b), np.where(left, b, x))
            fhi[i] = np.where(better, np.where(left, fm, fb), np.where(left, fb, fx))
            mid[i] = np.where(better, x, m)
            fmid[i] = np.where(better, fx, fm)
        return mid, fmid

    def _roots(self, ctx, a, b, fa, fb, J):
        """Where rho changes sign in (a, b) on the interpolant, to 4 ulp: the
        engine's safeguarded secant (``events.secant_of``), vectorised: a secant
        step from the last evaluation where it falls inside the bracket and is
        shorter than half the step before last, else bisection; trials a
        quarter tolerance inside the bracket so that it closes from both sides.
        Returns each bracket's end past the crossing."""
        sg = np.sign(fb)                         # F = sg * rho: F(lo) < 0 < F(hi)
        steps = ctx.steps(a, J)                  # each bracket lies in one step of the arc
        lo, hi, flo, fhi = a.copy(), b.copy(), sg * fa, sg * fb
        first = -flo < fhi
        xl, fl = np.where(first, lo, hi), np.where(first, flo, fhi)
        slope = (fhi - flo) / (hi - lo)
        d1 = np.full(len(a), _INF)
        d2 = d1.copy()
        live = np.ones(len(a), dtype=bool)
        for _ in range(200):
            tol = _tol(hi)
            live &= (hi - lo) > tol
            if not live.any():
                break
            i = np.flatnonzero(live)
            with np.errstate(invalid="ignore", divide="ignore"):
                s = xl[i] - fl[i] / slope[i]
            ok = (lo[i] <= s) & (s <= hi[i]) & (np.abs(s - xl[i]) < 0.5 * d2[i])
            s = np.where(ok, s, 0.5 * (lo[i] + hi[i]))
            q = 0.25 * tol[i]
            s = _clip(s, lo[i] + q, hi[i] - q)
            fs = sg[i] * self._inside(ctx, None if steps is None else steps[i], s, J[i])
            fs = np.where(np.isnan(fs), 0.0, fs)
            with np.errstate(invalid="ignore", divide="ignore"):
                slope[i] = (fs - fl[i]) / (s - xl[i])
            d2[i], d1[i] = d1[i], np.abs(s - xl[i])
            xl[i], fl[i] = s, fs
            up = fs >= 0
            hi[i] = np.where(up, s, hi[i])
            lo[i] = np.where(up & (fs != 0), lo[i], s)     # an exact zero: found
        return hi


class _WindowEval:
    """``F[a,b]`` / ``G[a,b]`` of a formula, computed (a base of ``stl._Window``)."""

    def _range(self, ctx, lo, hi):
        return max(lo + self.a, ctx.t0), min(hi + self.b, ctx.tf)

    def _compute(self, ctx, lo, hi, probes):
        clo, chi = self._range(ctx, lo, hi)
        if clo > ctx.tf:                        # (strict=False) every window is empty
            T, J, *_ = ctx.domain(np.array([lo, hi]) if hi > lo else np.array([lo]))
            return _Sig(T, J, np.full(len(T), -_INF if self.sup else _INF))
        cp = sorted({p + d for p in probes for d in (self.a, self.b) if math.isfinite(p + d)})
        s = self.phi._sig(ctx, clo, chi, cp[:256])
        if self.sup:
            return _window_sup(ctx, s, self.a, self.b, lo, hi)
        return _window_sup(ctx, s.neg(), self.a, self.b, lo, hi).neg()

    def _window_points(self, ctx, lo, hi, tau):
        clo, chi = self._range(ctx, lo, hi)
        s = self.phi._sig(ctx, clo, chi, ())
        top = min(tau + self.b, chi)
        m = (s.t >= tau + self.a - _tol(tau + self.a)) & (s.t <= top + _tol(top))
        return s, m, clo, chi

    def _decide(self, ctx, lo, hi, tau, j, target):
        if lo + self.a > ctx.tf:
            return tau, j
        s, m, clo, chi = self._window_points(ctx, lo, hi, tau)
        if self.a == 0:                         # not before (tau, j) in hybrid time
            m &= ~((np.abs(s.t - tau) <= _tol(tau)) & (s.j < j))
        k = np.flatnonzero(m)
        if not k.size:
            return tau, j
        cand = np.stack((s.v[k], s.l[k], s.r[k]))
        err = np.min(np.abs(cand - target), axis=0)
        best = k[int(np.argmin(err))]
        return self.phi._decide(ctx, clo, chi, float(s.t[best]), int(s.j[best]), target)


class _UntilEval:
    """``phi U[a,b] psi``, computed (a base of ``stl._Until``)."""

    def _ranges(self, ctx, lo, hi):
        end = min(hi + self.b, ctx.tf)
        return (lo, end), (min(lo + self.a, end), end)

    def _compute(self, ctx, lo, hi, probes):
        a, b = self.a, self.b
        (plo, phi_), (qlo, qhi) = self._ranges(ctx, lo, hi)
        if lo + a > ctx.tf:
            T, J, *_ = ctx.domain(np.array([lo, hi]) if hi > lo else np.array([lo]))
            return _Sig(T, J, np.full(len(T), -_INF))
        cp = sorted({p + d for p in probes for d in (0.0, a, b) if math.isfinite(p + d)})
        sp = self.phi._sig(ctx, plo, phi_, cp[:256])
        sq = self.psi._sig(ctx, qlo, qhi, cp[:256])
        # untimed phi U psi on [qlo, qhi], at the instants of both
        sp_q = _restrict(ctx, sp, qlo, qhi)
        w = _untimed_until(sp_q, sq)
        if math.isfinite(b):
            # F[0, b - a] psi bounds the witness to the window (for b = a, psi itself:
            # the untimed until alone would read to the end of the range, qhi)
            w = _combine(w, _window_sup(ctx, sq, 0.0, b - a, qlo, min(hi + a, qhi)), np.minimum)
        out = _window_sup(ctx, w, a, a, lo, hi)
        if a > 0:
            g = _window_sup(ctx, sp.neg(), 0.0, a, lo, hi).neg()
            out = _combine(out, g, np.minimum)
        return out

    def _decide(self, ctx, lo, hi, tau, j, target):
        (plo, phi_), (qlo, qhi) = self._ranges(ctx, lo, hi)
        best = None
        for f, (flo, fhi) in ((self.phi, (plo, phi_)), (self.psi, (qlo, qhi))):
            s = f._sig(ctx, flo, fhi, ())
            m = (s.t >= tau - _tol(tau)) & (s.t <= min(tau + self.b, fhi) + _tol(fhi))
            k = np.flatnonzero(m)
            if not k.size:
                continue
            err = np.abs(s.v[k] - target)
            i = int(np.argmin(err))
            if best is None or err[i] < best[0]:
                best = (err[i], f, flo, fhi, float(s.t[k[i]]), int(s.j[k[i]]))
        if best is None:
            return tau, j
        _, f, flo, fhi, tb, jb = best
        return f._decide(ctx, flo, fhi, tb, jb, target)


# --------------------------------------------------------------- evaluation --

@_every("margin")
def _robustness(arc, formula, t, j, strict, refine):
    if len(arc.t) == 0:
        raise ValueError("robustness: the arc is empty (no samples)")
    if getattr(arc, "merged_into", None) is not None:
        strict = False                  # a merged branch's prefix ends where it merges
    ctx = _Context(arc, strict, refine)
    tol = event_tolerance(ctx.tf, ctx.tf)
    if not (ctx.t0 - tol <= t <= ctx.tf + tol):
        raise ValueError(f"robustness: t = {t!r} is outside the arc's time range "
                         f"[{ctx.t0}, {ctx.tf}]")
    t = min(max(t, ctx.t0), ctx.tf)
    h = formula.horizon
    if strict and math.isfinite(h) and t + h > ctx.tf + event_tolerance(t + h, ctx.tf):
        raise ValueError(f"robustness: {formula} reads the arc up to t = {_num(t + h)} "
                         f"(t = {_num(t)} plus its horizon {_num(h)}), but the arc ends at "
                         f"t = {ctx.tf!r}; simulate longer, or pass strict=False to cut the "
                         f"windows at the arc's end")
    _, J, *_ = ctx.domain(np.array([t]))
    if j is None:
        j = int(J[0])
    elif int(j) not in set(J.tolist()):
        raise ValueError(f"robustness: (t={t!r}, j={j}) is not in the arc's hybrid time "
                         f"domain (at t the arc has j in {sorted(set(J.tolist()))})")
    s = formula._sig(ctx, t, t, (t,))
    k = np.flatnonzero(s.j == j)
    value = float(s.v[k[0]]) if k.size else float(s.v[0])
    wt, wj = formula._decide(ctx, t, t, t, int(j), value)
    series = None
    if isinstance(formula, _WindowEval) and not formula.sup and not (t + formula.a > ctx.tf):
        c, m, _, _ = formula._window_points(ctx, t, t, t)
        series = (c.t[m], c.j[m], c.v[m])
    return Margin(value, wt, wj, str(formula), series=series)
