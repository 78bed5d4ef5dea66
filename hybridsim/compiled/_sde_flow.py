"""SDE flows on the compiled path: one run, entirely compiled (imported only
when numba is installed).

The port of :class:`hybridsim._sde.SDEFlow` (Euler–Maruyama, diagonal
Milstein, Rößler's SRA1 on the fixed grid ``t0 + k * max_step``; events by
the Brownian-bridge correction on the guards, their time drawn from the
bridge) and of the decision loop of :func:`hybridsim.simulate` around it
(``_Run._loop``, ``_jump``, ``_stop_outside``), with the rules of
:mod:`hybridsim.rules` as they are. The Brownian path and the stream of
uniforms are :mod:`._draws`' (the Python path's, bit for bit), so a run and
its Python twin with the same seed agree to round-off.

:func:`sde_run` takes the system's maps by address (one kernel, cached on
disk, for every system). Where no event is watched, Euler–Maruyama on the
grid runs in :func:`_em_grid`: the flow map and the diffusion written into
arrays of the run (:func:`into_form`; a map declared ``(x, t, j, p, out)``
as it is), x updated in place, nothing allocated or reference-counted per
step; it hands any step it does not take (the last to ``t_max``, a map's
bad value, a blow-up, full buffers) back to the loop here, which takes it
as before. The grid loop is a cached kernel of its own, called by its
code's address (:func:`grid_address`). The plain run kernel
(:mod:`._kernel`) is not touched.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
from numba import njit, types
from numba.core import errors as nb_errors

from .. import rules
from ._decide import decide_at, jump_books, jump_cause, stop_outside
from ._draws import blocks_to, descend, draw_block, mix64, shift_window, stream_uniform
from ._types import (
    _A_JUMP,
    _A_STOP,
    _ARGS,
    _FLOWS,
    _GOES_ON,
    _NJ,
    _NJL,
    _O_FLOW_ON,
    _O_JUMP,
    _O_STOP,
    _O_TMAX,
    _OUTSIDE,
    _RANDOM,
    BLOWUP,
    CACHE,
    J_MAX,
    MAP_ERROR,
    MAP_FLOW_X0,
    MAP_JUMP_SHAPE,
    MAP_JUMP_VALUE,
    MAP_JUMP_X0,
    MAX_STEPS,
    NON_FINITE,
    T_MAX,
    _coin,
    _from_address,
    _vec_at,
    maps_of,
)

#: fopt's slots
F_T0, F_T_MAX, F_J_MAX, F_H, F_MAX_NORM, F_ZENO_TIME, F_ZENO_RTOL, F_SIZE = range(8)
#: iopt's slots
(I_J0, I_PRIO, I_MAX_STEPS, I_MAX_SAMPLES, I_ZENO_JUMPS, I_HAS_C, I_HAS_D, I_HAS_HC,
 I_HAS_HD, I_C_FROM_GUARD, I_D_FROM_GUARD, I_METHOD, I_DEPTH, I_DIAG, I_SIZE) = range(15)
#: methods' codes (``hybridsim._sde.SDE_METHODS``' order)
EM, MILSTEIN, SRA1 = 0, 1, 2
#: MAP_ERROR details of the diffusion (beyond :mod:`._types`')
MAP_NOT_ADDITIVE = 20
MAP_DIFFUSION_VALUE = 21
MAP_DIFFUSION_SHAPE = 22

_U = np.uint64
#: a map writing its value into its last argument: ``fn(x, t, j, p, out)``
INTO_SIG = types.none(*_ARGS, types.float64[::1])
with warnings.catch_warnings():
    warnings.simplefilter("ignore", nb_errors.NumbaExperimentalFeatureWarning)
    INTO_T = types.FunctionType(INTO_SIG)


#: a map of :data:`INTO_SIG` by its address
_into_at = _from_address(INTO_T, jit=True)


def jit_address(disp, sig=INTO_SIG):
    """The address of ``disp``'s code compiled for ``sig`` (``disp`` must
    outlive its use)."""
    cres = disp.overloads[sig.args]
    return cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)


def into_form(fn, shape=None):
    """A map as one writing into a flat ``out`` of :data:`INTO_SIG` (compiled):
    ``fn`` the address (an int) of a compiled map returning an array
    (:data:`._types.VEC_SIG`; a value of the wrong size writes NaN, and the
    stepper then takes the step that reports it), or an ``(x, t, j, p, out)``
    map, ``shape`` its ``out``'s, (n,) or (n, m)."""
    if shape is None:
        addr = int(fn)

        def w(x, t, j, p, out):
            v = _vec_at(addr)(x, t, j, p)
            n = out.shape[0]
            ok = v.shape[0] == n
            for i in range(n):
                out[i] = v[i] if ok else np.nan
        return njit(INTO_SIG, **_NJ)(w)
    jf = fn if hasattr(fn, "py_func") else njit(**_NJ)(fn)
    if len(shape) == 1:
        try:                            # as it is, where it returns nothing
            jf.compile(INTO_SIG)
            return jf
        except nb_errors.TypingError:
            pass

        def w(x, t, j, p, out):
            jf(x, t, j, p, out)
    else:
        n, m = shape

        def w(x, t, j, p, out):
            jf(x, t, j, p, out.reshape((n, m)))
    return njit(INTO_SIG, **_NJ)(w)


@njit(**_NJ)
def _mul(s, v, diag, n):
    """σ v: diagonal noise (σ of n values) elementwise, general noise (σ an
    (n, m) matrix, row-major) a product."""
    out = np.zeros(n)
    if diag:
        for i in range(n):
            out[i] = s[i] * v[i]
        return out
    m = v.shape[0]
    for i in range(n):
        acc = 0.0
        for k in range(m):
            acc += s[i * m + k] * v[k]
        out[i] = acc
    return out


@njit(**_NJ)
def _noise_dir(s, grad, diag, n, m):
    """σσ^T ∇y (the guard process's noise direction)."""
    if diag:
        return s * s * grad
    w = np.zeros(m)
    for k in range(m):
        for i in range(n):
            w[k] += s[i * m + k] * grad[i]
    return _mul(s, w, False, n)


@njit(**_NJ)
def _finite(s):
    for i in range(s.shape[0]):
        if not math.isfinite(s[i]):
            return False
    return True


@njit(**_NJ)
def _same(a, b):
    if a.shape[0] != b.shape[0]:
        return False
    for i in range(a.shape[0]):
        if a[i] != b[i]:
            return False
    return True


@njit(**_NJ)
def _y(h, neg, x, t, j, p):
    v = h(x, t, j, p)
    return -v if neg else v


@njit(**_NJ)
def _inset(ind, h, from_guard, x, t, j, p):
    if from_guard:
        return h(x, t, j, p) >= 0.0
    return ind(x, t, j, p)


@njit(**_NJ)
def _uni(key, ctr):
    ctr[0] += 1
    return stream_uniform(key, ctr[0])


@njit(**_NJ)
def _normal(key, ctr):
    u1 = _uni(key, ctr)
    u2 = _uni(key, ctr)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@njit(**_NJ)
def crossing_probability(ya, yb, s2, dt):
    """:func:`hybridsim._sde.crossing_probability`."""
    if ya >= 0 or yb >= 0:
        return 1.0
    if not s2 > 0:
        return 0.0
    return math.exp(-2.0 * ya * yb / (s2 * dt))


@njit(**_NJ)
def bridge_first_passage(ya, yb, s2, dt, key, ctr):
    """:func:`hybridsim._sde.bridge_first_passage` (40 levels)."""
    lo, length, yl, yr = 0.0, dt, ya, yb
    for _ in range(40):
        half = 0.5 * length
        mean, sd = 0.5 * (yl + yr), math.sqrt(s2 * length / 4.0)
        m = mean
        pl = 1.0
        pe = 1.0
        for _tries in range(10**7):
            m = mean + sd * _normal(key, ctr)
            pl = 1.0 if m >= 0 else math.exp(-2.0 * yl * m / (s2 * half))
            pr = 1.0 if (m >= 0 or yr >= 0) else math.exp(-2.0 * m * yr / (s2 * half))
            pe = pl + (1.0 - pl) * pr
            if _uni(key, ctr) < pe:
                break
        if _uni(key, ctr) * pe < pl:
            yr, length = m, half
        else:
            lo, yl, length = lo + half, m, half
    return lo + length


@njit(**_NJ)
def _crossing(h, neg, sig_a, diag, m, a, xa, b, xb, j, p, key, ctr):
    """``SDEFlow._crossing``: ``(hit, te, xe)`` of the guard process ±h in (a, b]."""
    n = xa.shape[0]
    ya, yb = _y(h, neg, xa, a, j, p), _y(h, neg, xb, b, j, p)
    if not (math.isfinite(ya) and math.isfinite(yb)):
        return False, b, xb
    grad = np.empty(n)
    for i in range(n):
        e = 1e-6 * max(1.0, abs(xa[i]))
        xp = xa.copy()
        xm = xa.copy()
        xp[i] += e
        xm[i] -= e
        grad[i] = (_y(h, neg, xp, a, j, p) - _y(h, neg, xm, a, j, p)) / (2 * e)
    v = _noise_dir(sig_a, grad, diag, n, m)
    s2 = 0.0
    for i in range(n):
        s2 += grad[i] * v[i]
    if yb < 0:
        if _uni(key, ctr) >= crossing_probability(ya, yb, s2, b - a):
            return False, b, xb
    else:
        if ya >= 0:
            return True, b, xb
        if not s2 > 0:
            th = ya / (ya - yb)
            return True, a + th * (b - a), xa + th * (xb - xa)
    tau = bridge_first_passage(ya, yb, s2, b - a, key, ctr)
    th = tau / (b - a)
    te = min(a + tau, b)
    y_lin = ya + (yb - ya) * th
    xe = xa + (xb - xa) * th - v * (y_lin / s2)
    d = 1e-7 * max(1.0, np.abs(xe).max()) / max(np.abs(v).max(), 1e-300)
    for _ in range(8):
        ye = _y(h, neg, xe, te, j, p)
        if not math.isfinite(ye) or abs(ye) <= 1e-14 * max(1.0, abs(ya)):
            break
        slope = (_y(h, neg, xe + d * v, te, j, p) - _y(h, neg, xe - d * v, te, j, p)) / (2 * d)
        if not (math.isfinite(slope) and slope != 0):
            break
        xe = xe - v * (ye / slope)
    return True, te, xe


@njit(**_NJ)
def _w(keys, S, F, H, base, c, t, t0, T, depth, z):
    """(W, ∫W) of component c at t (``BrownianPath._query``; its block drawn,
    in the window from block ``base``)."""
    s = (t - t0) / T
    blk = int(math.floor(s))  # noqa: RUF046 - an int under numba too
    return descend(keys[c], S, F, H, c, blk, blk - base, s - blk, T, depth, z)


@njit(**_NJ)
def _w_all(keys, S, F, H, base, t, k, t0, T, depth, m, w, Fo, z):
    """(W, ∫W) at t into ``w``, ``Fo`` (block end ``k`` where k >= 0)."""
    if k >= 0:
        for c in range(m):
            w[c] = S[c, k - base]
            Fo[c] = F[c, k - base]
        return
    for c in range(m):
        w[c], Fo[c] = _w(keys, S, F, H, base, c, t, t0, T, depth, z)


@njit(**_NJ)
def _grown(T, J, X, ns):
    """The sample buffers, twice as long (their first ``ns`` rows kept)."""
    T2 = np.empty(2 * ns)
    J2 = np.empty(2 * ns, np.int64)
    X2 = np.empty((2 * ns, X.shape[1]))
    T2[:ns] = T[:ns]
    J2[:ns] = J[:ns]
    X2[:ns] = X[:ns]
    return T2, J2, X2


@njit(inline="always", **_NJ)
def _put(T, J, X, ns, t, j, x):
    T[ns] = t
    J[ns] = j
    for q in range(x.shape[0]):
        X[ns, q] = x[q]


_V = types.float64[::1]
_M = types.float64[:, ::1]
_I = types.int64
_D = types.float64
#: :func:`_em_grid`'s signature
EM_SIG = types.Tuple((_D, _I, _I, _I))(
    INTO_T, INTO_T, _V, _I, _V, _D, _I, _D, _D, _D, types.boolean, _D, _I, _I,
    types.uint64[::1], _M, _M, _M, types.int64[::1], _V, _V, _V, _V, _V, types.int64[::1],
    _M, _I)
with warnings.catch_warnings():
    warnings.simplefilter("ignore", nb_errors.NumbaExperimentalFeatureWarning)
    EM_T = types.FunctionType(EM_SIG)
#: :func:`_em_grid` by its address
_em_at = _from_address(EM_T, jit=True)


# Compiled on its own (cached) and called by its code's address from
# :func:`sde_run` (``maps[9]``, :func:`grid_address`): linked into sde_run's
# module, LLVM compiles the loop with its counters spilled to the stack.
@njit(cache=CACHE, **_NJL)
def _em_grid(fi, si, x, j, p, a, ka, t0, t_max, H, diag, max_norm, steps, max_steps,
             keys, S, F, H_, nb, z, xn, fa, s, T, J, X, ns):
    """Euler–Maruyama steps on the grid ``t0 + k H`` from ``a = t0 + ka H``,
    where no event is watched, the maps written into ``fa`` and ``s``
    (:func:`into_form`): ``x`` updated in place (``xn``: scratch of n), the
    samples stored; nothing allocated, no reference counted.
    Stops before a step it does not take as the loop of :func:`sde_run` does
    (the last step to ``t_max``, a block the window has no room for, the sample
    buffers full, a map's value of the wrong shape, a non-finite or too large
    x(b), ``max_steps``): that loop takes it. Returns ``(a, ka, steps, ns)``."""
    n = x.shape[0]
    m = keys.shape[0]
    cols = S.shape[1]
    cap = T.shape[0]
    while steps < max_steps and ns < cap:
        kb = ka + 1
        b = t0 + kb * H
        if b >= t_max:
            break
        if nb[0] <= kb:
            if kb + 2 - nb[1] > cols:
                shift_window(S, F, H_, nb)
                if kb + 2 - nb[1] > cols:
                    break
            draw_block(keys, S, F, H_, nb[0], nb[0] - nb[1], H, z)
            nb[0] += 1
        base = nb[1]
        hh = b - a
        fi(x, a, j, p, fa)
        si(x, a, j, p, s)
        if diag:
            for i in range(n):
                xn[i] = x[i] + fa[i] * hh + s[i] * (S[i, kb - base] - S[i, ka - base])
        else:
            for i in range(n):
                acc = 0.0
                for c in range(m):
                    acc += s[i * m + c] * (S[c, kb - base] - S[c, ka - base])
                xn[i] = x[i] + fa[i] * hh + acc
        nrm = 0.0
        for i in range(n):
            nrm += xn[i] * xn[i]
        if not (math.isfinite(nrm) and (max_norm == np.inf or math.sqrt(nrm) <= max_norm)):
            break
        for i in range(n):
            x[i] = xn[i]
        steps += 1
        _put(T, J, X, ns, b, j, x)
        ns += 1
        a, ka = b, kb
    return a, ka, steps, ns


@njit(nogil=True, cache=CACHE, **_NJ)
def sde_run(maps, x0, p, fopt, iopt, keys, rngp):
    """One run of an SDE flow. ``maps``: the addresses of f, g, hD, hC, D, C
    and the diffusion (flattened row-major for general noise), as the run
    kernel's (:func:`._types.map_addresses`), then f and the diffusion written
    into an argument (:func:`into_form`, the same values), then :func:`_em_grid`'s
    (:func:`grid_address`). ``keys``: the
    Brownian path's per-component keys and the stream key last (:func:`._draws.path_keys`). Returns
    ``(T, J, X, cause, detail, info, stats)``, the codes of :mod:`._types`
    (stats: steps, events, flows, jumps)."""
    f, g, hD, hC, D, C = maps_of(maps[:6])
    sig = _vec_at(maps[6])
    t0, t_max, j_max, H = fopt[F_T0], fopt[F_T_MAX], fopt[F_J_MAX], fopt[F_H]
    max_norm, zeno_time, zeno_rtol = fopt[F_MAX_NORM], fopt[F_ZENO_TIME], fopt[F_ZENO_RTOL]
    prio = iopt[I_PRIO]
    max_steps, max_samples, zeno_jumps = iopt[I_MAX_STEPS], iopt[I_MAX_SAMPLES], \
        iopt[I_ZENO_JUMPS]
    has_C, has_D = iopt[I_HAS_C] != 0, iopt[I_HAS_D] != 0
    has_hC, has_hD = iopt[I_HAS_HC] != 0, iopt[I_HAS_HD] != 0
    C_g, D_g = iopt[I_C_FROM_GUARD] != 0, iopt[I_D_FROM_GUARD] != 0
    method, depth = iopt[I_METHOD], iopt[I_DEPTH]
    n = x0.shape[0]
    m = keys.shape[0] - 1
    diag = iopt[I_DIAG] != 0
    ns_sig = n if diag else n * m
    skey = keys[m]
    ckeys = keys[:m]
    watch_D = has_D and prio != _FLOWS
    SB, FB, HB = np.zeros((m, 64)), np.zeros((m, 64)), np.zeros((m, 64))
    nb = np.zeros(2, np.int64)
    z4 = np.empty(4)
    xbuf = np.empty((2, n))             # EM's x(b), alternately (x is the other row)
    xrow = -1
    xn4, fa4, s4 = np.empty(n), np.empty(n), np.empty(ns_sig)
    fi, si = _into_at(maps[7]), _into_at(maps[8])
    grid = _em_at(maps[9])
    grid_em = method == EM and not has_C and not watch_D     # no event watched: _em_grid
    wa, Fa, wb, Fb, dw = np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    bits = np.empty(2)
    ubits = bits.view(np.uint64)
    ctr = np.zeros(1, np.int64)
    cap = 64                            # the grid's samples (and 64 more), up to 2^20
    if t_max < np.inf:
        cap = min(max(cap, math.ceil((t_max - t0) / H) + 65), 1 << 20)
    T = np.empty(cap)
    J = np.empty(cap, np.int64)
    X = np.empty((cap, n))
    info = np.full(6, np.nan)
    stats = np.zeros(4, np.int64)
    t, j, x = t0, iopt[I_J0], x0.copy()
    _put(T, J, X, 0, t, j, x)
    ns = 1
    in_D = has_D and _inset(D, hD, D_g, x, t, j, p)
    in_C = (not has_C) or _inset(C, hC, C_g, x, t, j, p)
    if in_C:
        v0 = f(x, t, j, p)
        if v0.shape[0] != n or not _finite(v0):
            info[0], info[2], info[3] = t, v0.shape[0], j
            return T[:1].copy(), J[:1].copy(), X[:1].copy(), MAP_ERROR, MAP_FLOW_X0, info, stats
    if in_D:
        v0 = g(x, t, j, p)
        if v0.shape[0] != n or not _finite(v0):
            info[0], info[2], info[3] = t, v0.shape[0], j
            return T[:1].copy(), J[:1].copy(), X[:1].copy(), MAP_ERROR, MAP_JUMP_X0, info, stats
    cause = _GOES_ON
    detail = 0
    forced = False
    flow_on = False
    jumps = 0
    short = 0
    zref = 0.0
    t_last_jump = t0
    flows_last = np.zeros(4)
    n_fl = 0
    loop = 0
    same = 0
    longest = 0.0
    tiny = 0
    steps = 0
    additive_checked = False
    while True:
        from_C = True
        if flow_on:
            in_D = True
            action = -1
        elif forced:
            forced = False
            action = _A_JUMP
        else:
            in_D = has_D and _inset(D, hD, D_g, x, t, j, p)
            in_C = (not has_C) or _inset(C, hC, C_g, x, t, j, p)
            action = decide_at(in_C, in_D, prio, rngp)
            from_C = in_C
            if action == _A_STOP:
                cause = _OUTSIDE
                break
        if action == _A_JUMP:
            if jumps >= j_max:
                cause = J_MAX
                break
            xn = g(x, t, j, p)
            if xn.shape[0] != n or not _finite(xn):
                cause = MAP_ERROR
                detail = MAP_JUMP_SHAPE if xn.shape[0] != n else MAP_JUMP_VALUE
                info[0], info[2], info[3] = t, xn.shape[0], j
                break
            n_fl, zref, short, longest, longest_before, tiny, same, loop, flow = \
                jump_books(flows_last, n_fl, t, t_last_jump, jumps, from_C, zref, short, longest,
                           tiny, same, loop, zeno_time, zeno_rtol)
            t_last_jump = t
            j += 1
            jumps += 1
            x = xn.copy()
            if ns >= max_samples:
                cause = MAX_STEPS
                detail = 1
                info[0] = t
                break
            if ns == T.shape[0]:
                T, J, X = _grown(T, J, X, ns)
            _put(T, J, X, ns, t, j, x)
            ns += 1
            cause, detail = jump_cause(jumps, short, j_max, zeno_jumps, loop, same, tiny, t,
                                       longest_before, flow, info)
            if cause != _GOES_ON:
                break
            continue
        if t >= t_max:
            cause = T_MAX
            break
        # ------------------------------------------------ a flow (SDEFlow.flow)
        d_active = watch_D and not in_D
        flow_on = False
        stats[2] += 1
        a = t
        ka = 0 if t == t0 else -1
        outcome = -1
        while True:
            if grid_em and ka >= 0:
                a, ka, steps, ns = grid(fi, si, x, j, p, a, ka, t0, t_max, H, diag,
                                        max_norm, steps, max_steps, ckeys, SB, FB, HB, nb,
                                        z4, xn4, fa4, s4, T, J, X, ns)
            if a >= t_max:
                t = a
                outcome = _O_TMAX
                break
            if steps >= max_steps:
                cause = MAX_STEPS
                info[0] = a
                t = a
                break
            if ka < 0:
                kb = int(math.floor((a - t0) / H)) + 1  # noqa: RUF046
                if t0 + kb * H - a <= 1e-12 * max(1.0, abs(a)):
                    ka, kb = kb, kb + 1
                    a = t0 + ka * H
            else:
                kb = ka + 1
            b = t0 + kb * H
            if b > t_max:
                b, kb = t_max, -1
            fa = f(x, a, j, p)
            hh = b - a
            s = sig(x, a, j, p)
            if s.shape[0] != ns_sig or not _finite(s):
                cause = MAP_ERROR
                detail = MAP_DIFFUSION_VALUE if s.shape[0] == ns_sig else MAP_DIFFUSION_SHAPE
                info[0], info[3] = a, j
                t = a
                break
            need = kb if kb >= 0 else int(math.floor((b - t0) / H))  # noqa: RUF046
            if nb[0] <= need:                # the blocks up to b's drawn
                SB, FB, HB = blocks_to(ckeys, SB, FB, HB, nb, H, need, z4)
            _w_all(ckeys, SB, FB, HB, nb[1], a, ka, t0, H, depth, m, wa, Fa, z4)
            _w_all(ckeys, SB, FB, HB, nb[1], b, kb, t0, H, depth, m, wb, Fb, z4)
            for c in range(m):
                dw[c] = wb[c] - wa[c]
            if method == SRA1:
                i10 = Fb - Fa - hh * wa
                s_b = sig(x, b, j, p)
                if not additive_checked:
                    xq = x + 1.0 + np.abs(x)
                    if not _same(sig(xq, a, j, p), s):
                        cause = MAP_ERROR
                        detail = MAP_NOT_ADDITIVE
                        info[0], info[3] = a, j
                        t = a
                        break
                    additive_checked = True
                f1 = f(x, a, j, p)
                h2 = x + 0.75 * hh * f1 + 1.5 * _mul(s_b, i10 / hh, diag, n)
                f2 = f(h2, a + 0.75 * hh, j, p)
                xb = x + hh * (f1 / 3.0 + 2.0 * f2 / 3.0) + _mul(s_b, dw - i10 / hh, diag, n) + \
                    _mul(s, i10 / hh, diag, n)
            elif method == MILSTEIN:
                rh = math.sqrt(hh)
                s_hat = sig(x + fa * hh + _mul(s, np.full(n, rh), diag, n), a, j, p)
                xb = x + fa * hh + _mul(s, dw, diag, n) + (s_hat - s) * (dw * dw - hh) / (2.0 * rh)
            else:
                q = 1 if xrow == 0 else 0
                xb = xbuf[q]
                xrow = q
                if diag:
                    for i in range(n):
                        xb[i] = x[i] + fa[i] * hh + s[i] * dw[i]
                else:
                    for i in range(n):
                        acc = 0.0
                        for c in range(m):
                            acc += s[i * m + c] * dw[c]
                        xb[i] = x[i] + fa[i] * hh + acc
            steps += 1
            if not _finite(xb):
                cause = NON_FINITE
                info[0], info[1], info[3] = a, b, j
                t = a
                break
            key = _U(0)
            if d_active or has_C:
                bits[0] = a
                bits[1] = b
                key = mix64(skey ^ ubits[0]) ^ mix64(ubits[1] ^ _U(j))
                ctr[0] = 0
            hit = False
            kind_D = False
            te, xe = b, xb
            if d_active:
                if has_hD:
                    hit, te, xe = _crossing(hD, False, s, diag, m, a, x, b, xb, j, p, key, ctr)
                elif D(xb, b, j, p):
                    hit, te, xe = True, b, xb
                kind_D = hit
            if has_C:
                if has_hC:
                    hc, tc, xc = _crossing(hC, True, s, diag, m, a, x, b, xb, j, p, key, ctr)
                else:
                    hc, tc, xc = not C(xb, b, j, p), b, xb
                if hc and ((not hit) or tc < te):
                    hit, te, xe, kind_D = True, tc, xc, False
            if hit:
                stats[1] += 1
                if ns >= max_samples:
                    cause = MAX_STEPS
                    detail = 1
                    info[0] = a
                    t = a
                    break
                if ns == T.shape[0]:
                    T, J, X = _grown(T, J, X, ns)
                _put(T, J, X, ns, te, j, xe)
                ns += 1
                t, x = te, xe
                in_De = has_D and (kind_D or _inset(D, hD, D_g, xe, te, j, p))
                in_Ce = kind_D and ((not has_C) or _inset(C, hC, C_g, xe, te, j, p))
                coin = False
                if kind_D and prio == _RANDOM and rules.needs_coin(in_Ce, True, prio, False):
                    coin = _coin(rngp)
                act, _side = rules.event_outcome(kind_D, in_De, in_Ce, False, prio, coin)
                in_C = in_Ce
                if act == _A_JUMP:
                    outcome = _O_JUMP
                elif act == _A_STOP:
                    outcome = _O_STOP
                else:
                    outcome = _O_FLOW_ON
                break
            if ns >= max_samples:
                cause = MAX_STEPS
                detail = 1
                info[0] = a
                t = a
                break
            if ns == T.shape[0]:
                T, J, X = _grown(T, J, X, ns)
            _put(T, J, X, ns, b, j, xb)
            ns += 1
            if max_norm < np.inf:
                nrm = math.sqrt((xb * xb).sum())
                if nrm > max_norm:
                    cause = BLOWUP
                    info[0], info[2], info[3] = b, nrm, j
                    t, x = b, xb
                    break
            if watch_D and not d_active:
                d_active = not _inset(D, hD, D_g, xb, b, j, p)
            a, x, ka = b, xb, kb
        stats[0] = steps
        if cause != _GOES_ON:
            break
        if outcome == _O_TMAX:
            cause = T_MAX
            break
        if outcome == _O_JUMP:
            forced = True
        elif outcome == _O_FLOW_ON:
            flow_on = True
        elif outcome == _O_STOP:
            cause = _OUTSIDE
            break
    if cause == _OUTSIDE:
        cause, detail = stop_outside(ns, t0, t, t_max, j, flows_last, n_fl, t_last_jump, jumps,
                                     info, detail)
    stats[0] = steps
    stats[3] = jumps
    if ns + 64 >= T.shape[0]:           # the grid (nearly) filled the buffers: views
        return T[:ns], J[:ns], X[:ns], cause, detail, info, stats
    return T[:ns].copy(), J[:ns].copy(), X[:ns].copy(), cause, detail, info, stats


def grid_address():
    """The address of :func:`_em_grid`'s code (``maps[9]`` of :func:`sde_run`),
    compiled (or loaded from the cache, keyed by
    :func:`hybridsim.compiled._stochastic._sde_kernel`) on first use."""
    if EM_SIG.args not in _em_grid.overloads:
        _em_grid.compile(EM_SIG)
    return jit_address(_em_grid, EM_SIG)
