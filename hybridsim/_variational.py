r"""The variational system on the compiled path: one definition, compiled.

:func:`hybridsim.simulate_sensitivity` integrates the variational system of
a hybrid system (:class:`hybridsim.sensitivity.SensitivitySystem`: state
``(x, vec S, dt/dtheta, t_last, flag)``, flow ``(f, Df S + f_p, 0, 0, 0)``,
jump the saltation update). Here the same system is built as a
:class:`hybridsim.compiled.CompiledSystem` whose maps are functions of
``(y, t, j, p)`` calling the user's system's own compiled maps (the system
lowered by :func:`hybridsim.compiled.lower`: a plain model's maps rewritten
from source, with guards derived from its sets), so the engine's compiled
kernel runs it unchanged: the same events, rules and options, with the
variational equation and the saltation update

.. math::
    \frac{\partial t_j}{\partial\theta} = -\frac{\nabla h\, S^- + h_\theta}
        {\nabla h\, f^- + h_t}, \qquad
    S^+ = Dg\, S^- + g_\theta + (Dg\, f^- + g_t - f^+)\,
          \frac{\partial t_j}{\partial\theta}

computed inside the kernel's maps. Each map here is the compiled twin of
the Python one, line for line (``SensitivitySystem.flow_map``,
``jump_map``, ``_tangency`` and ``_at_zero``): the same central differences
(steps :math:`\delta_i` = ``fd_step`` :math:`\max(1, |x_i|)`), the same
tests for grazing, simultaneous guards and jumps without a guard's zero,
the same flag codes, so the two paths agree to rounding (and to the
solver's tolerance where rounding moves a step).

``p`` of the compiled system is ``[fd_step, graze_tol, n, m_x0, m_p, L,
d_1..d_np, P0, P1+, P1-, ..., Pnp+, Pnp-]``: the step, the tolerance, the
sizes (state, columns for x0 and for p, length of the system's ``p``), the
parameter steps
:math:`d_k = p_k^+ - p_k^-` and the lowered parameter vectors of the system
at the nominal parameters and at :math:`p \pm \delta_k e_k` (each built by
the factory, the derivatives in p their central differences, as on the
Python path). The compiled maps depend only on the user's compiled maps (the sizes
are read from ``p``): they are compiled once per process and system (6-8 s
of CPU measured on a shared two-core machine: they are closures over the user's maps, so
numba cannot keep them on disk); a new run, at any parameters and with
any ``wrt``, only reads ``p``.

Refused by name (:func:`refusal`): an interconnection (its jump at an event
is frozen to the components in their jump sets, which the compiled
variational system does not build), Jacobians given by the system
(``flow_jacobian``, ``jump_jacobian``, ``jump_guard_gradient``: used on the
Python path; the compiled maps difference the maps), a system that does not
lower, and a factory whose systems at :math:`p \pm \delta_k e_k` lower to
other maps than at p (a structure that depends on p).
"""
from __future__ import annotations

import inspect
import math
import types

import numpy as np

from . import _source
from .system import _DerivedGuard

__all__ = ["refusal", "auto", "compiled_variational", "JACOBIANS"]

#: the Jacobians a system may give (used on the Python path only)
JACOBIANS = ("flow_jacobian", "jump_jacobian", "jump_guard_gradient")

_ROLES = ("flow", "jump", "jump_guard", "flow_guard", "jump_set", "flow_set")


def refusal(ssys):
    """Why the variational system ``ssys`` cannot run compiled (a message), or None.

    Checks what can be checked without compiling (numba need not be
    installed); :func:`compiled_variational` raises the rest (a map numba
    refuses, a factory whose structure depends on p).

    Examples
    --------
    >>> import hybridsim as hs
    >>> from hybridsim.library import BouncingBall
    >>> from hybridsim.sensitivity import sensitivity_system
    >>> ic = hs.Interconnection({"ball": BouncingBall()})
    >>> print(refusal(sensitivity_system(ic)))       # doctest: +ELLIPSIS
    Interconnection is an interconnection: its jump at an event is frozen ...
    """
    from .compiled import lowerable
    base = ssys.base
    why = _kind_refusal(base)
    if why is not None or _known(base):
        return why
    ok = lowerable(base)
    if not ok:
        return ok.reason
    return None


def _kind_refusal(base):
    """Why a system of this kind has no compiled variational system, or None."""
    from .compose import Interconnection
    name = type(base).__name__
    if isinstance(base, Interconnection):
        return (f"{name} is an interconnection: its jump at an event is frozen to the "
                f"components in their jump sets, which only the Python path's variational "
                f"system builds")
    given = [a for a in JACOBIANS if getattr(base, a, None) is not None]
    if given:
        return (f"{name} gives {', '.join(given)}, used on the Python path only (the "
                f"compiled variational system differences the maps centrally); drop "
                f"{'it' if len(given) == 1 else 'them'} or use backend='python'")
    return None


_WARNED = set()


def auto(ssys, codes):
    """``backend="auto"``'s choice: the compiled form of ``ssys``, or None (the
    Python path). A plain model whose maps cannot run compiled warns once per
    class and reason, as :func:`hybridsim.simulate` does
    (:class:`~hybridsim.compiled.FallbackWarning`), and so does a factory
    whose maps depend on p; an interconnection or a system giving its
    Jacobians takes the Python path silently (:func:`refusal` says why)."""
    import warnings

    from .compiled import lowerable
    from .compiled._from_source import FallbackWarning, applies, auto_choice
    base = ssys.base
    if _kind_refusal(base) is not None:
        return None
    if not _known(base):
        if applies(base):
            if auto_choice(base, lowerable(base)) != "compiled":
                return None
        elif not lowerable(base):
            return None
    try:
        return compiled_variational(ssys, codes)
    except TypeError as e:
        key = (type(base), str(e))
        if key not in _WARNED:
            _WARNED.add(key)
            warnings.warn(f"backend='auto' runs the sensitivities of {type(base).__name__} "
                          f"on the Python path: {e}", FallbackWarning, stacklevel=4)
        return None


def _lowered(system):
    """``(maps, p)`` of ``system`` lowered: read through the plan of an earlier
    system of the same structure where there is one (:func:`_reread`), else
    by :func:`hybridsim.compiled.lower` (the structure then kept)."""
    from .compiled import CompiledSystem, lower
    from .compiled._from_source import applies
    plain = applies(system)
    key = _structure(system) if plain else None
    hit = _STRUCTURES.get(key) if key is not None else None
    if hit is not None:
        p = _reread(hit[0], hit[1].layout, system)
        if p is not None:
            return hit[1].maps, p
    cs = lower(system)
    if key is not None and isinstance(cs, CompiledSystem) and getattr(cs, "layout", None) \
            is not None:
        if len(_STRUCTURES) > 64:
            _STRUCTURES.clear()
        _STRUCTURES[key] = (system, cs)
    return cs.maps, cs.params


#: a plain model's structure -> (the first system of it lowered, its compiled form)
_STRUCTURES = {}


def _known(system):
    """Whether a plain model of ``system``'s structure was lowered before."""
    from .compiled._from_source import applies
    return applies(system) and _STRUCTURES.get(_structure(system)) is not None


def _unwrap(fn):
    if isinstance(fn, types.MethodType):
        return fn.__func__, fn.__self__
    return (fn, None) if isinstance(fn, types.FunctionType) else (None, None)


def _given(system, attr):
    """The map ``attr`` as the system gives it: None for a guard derived from
    its set (that set's code decides the guard), or one not given."""
    if attr in ("jump_guard", "flow_guard") and attr not in vars(system) and isinstance(
            inspect.getattr_static(type(system), attr, None), _DerivedGuard):
        return None
    return getattr(system, attr, None)


def _structure(system):
    """What a plain model's plan depends on besides the values it reads (the
    class, the code of its maps and what the lowering checks), or None."""
    parts = [type(system), system.needs_history, system.delays, system.input_dim]
    for attr, _ in _source.ROLES:
        fn = _given(system, attr)
        if fn is None:
            parts.append(None)
            continue
        func, obj = _unwrap(fn)
        if func is None:
            return None
        parts.append((func.__code__, id(func.__globals__), obj is system,
                      None if obj is None else type(obj)))
    return tuple(parts)


def _reread(s0, layout, s1):
    """``p`` of ``s1`` read through the plan ``layout`` made for ``s0``, a system
    of the same structure (:func:`_structure`): each slot read from the object
    of ``s1`` that corresponds to the one of ``s0`` it was read from (the
    system, its maps' closure cells and defaults). None where a slot has no
    counterpart or changed kind or shape, or where something the plan
    followed without reading it (a function in a cell, on the instance)
    differs: then ``s1`` is lowered itself."""
    corr = {}
    for attr, _ in _source.ROLES:
        f0, f1 = _given(s0, attr), _given(s1, attr)
        if f0 is None:
            continue
        u0, u1 = _unwrap(f0)[0], _unwrap(f1)[0]
        if u0.__code__ is not u1.__code__:
            return None
        corr[("default", id(u0))] = u1
        for c0, c1 in zip(u0.__closure__ or (), u1.__closure__ or ()):
            corr[("cell", id(c0))] = c1
    slots = {}
    for key, i in layout._index.items():
        slots[key] = i
    for k, c1 in corr.items():                    # cells read without a slot: the same
        if k[0] == "cell" and k not in slots:
            c0 = next(c for c in _cells(s0) if id(c) == k[1])
            try:
                if c0.cell_contents is not c1.cell_contents:
                    return None
            except ValueError:
                return None
    own0, own1 = s0.__dict__, s1.__dict__         # callables on the instance: the same
    for name in set(own0) | set(own1):
        v0, v1 = own0.get(name), own1.get(name)
        if (_callable(v0) or _callable(v1)) and name not in _ROLE_ATTRS and v0 is not v1:
            return None
    readers = [None] * len(layout.slots)
    for key, i in slots.items():
        if key[0] == "self" and key[1] == id(s0):
            readers[i] = (lambda a: lambda: getattr(s1, a))(key[2])
        elif key[0] == "cell" and key in corr:
            readers[i] = (lambda c: lambda: c.cell_contents)(corr[key])
        elif key[0] == "global":
            readers[i] = layout.readers[i]
        elif key[0] == "default" and ("default", key[1]) in corr:
            readers[i] = _default(corr[("default", key[1])], key[2])
        else:
            return None
    checks = {}                                   # None-tests the rewrite folded
    for key, (_, is_none) in layout.checks.items():
        if key[0] != "none" or key[1] != id(s0):
            return None
        checks[key] = ((lambda a: lambda: getattr(s1, a))(key[2]), is_none)
    if layout.parts or layout.folded:             # parts followed, constants folded: s1's own
        return None
    lay = object.__new__(type(layout))
    lay.slots, lay.readers, lay.size = layout.slots, readers, layout.size
    lay.checks, lay.parts, lay.folded = checks, {}, {}
    return lay.read()


_ROLE_ATTRS = {attr for attr, _ in _source.ROLES}


def _callable(v):
    return callable(v) and not isinstance(v, type)


def _cells(system):
    for attr, _ in _source.ROLES:
        fn = _given(system, attr)
        if fn is not None:
            yield from (_unwrap(fn)[0].__closure__ or ())


def _default(func, name):
    code = func.__code__
    names = code.co_varnames[:code.co_argcount]

    def read():
        d = func.__defaults__
        return d[names.index(name) - (len(names) - len(d))]
    return read


def _same_map(a, b):
    """Whether two compiled maps are the same function (the same object, or
    functions of the same code over the same closure cells' values)."""
    if a is b:
        return True
    a, b = getattr(a, "py_func", a), getattr(b, "py_func", b)
    ca, cb = getattr(a, "__code__", None), getattr(b, "__code__", None)
    if ca is None or ca is not cb or a.__globals__ is not b.__globals__:
        return False
    cla, clb = a.__closure__ or (), b.__closure__ or ()
    return len(cla) == len(clb) and all(x.cell_contents is y.cell_contents
                                        for x, y in zip(cla, clb))


def compiled_variational(ssys, codes):
    """The :class:`~hybridsim.compiled.CompiledSystem` of the variational system
    ``ssys`` (a :class:`hybridsim.sensitivity.SensitivitySystem`), its ``p``
    read now (module notes).

    ``codes``: the flag codes (grazing, no guard, simultaneous, no flow).

    Raises
    ------
    TypeError
        The system cannot run compiled (:func:`refusal`'s reasons, numba's
        refusal of a map, a factory whose maps depend on p).
    ImportError
        numba is not installed.
    """
    why = refusal(ssys)
    if why is not None:
        raise TypeError(f"backend='compiled': the sensitivities of {type(ssys.base).__name__} "
                        f"cannot run compiled: {why}")
    cmaps, p0 = _lowered(ssys.base)
    maps = {r: cmaps[r] for r in _ROLES if r in cmaps}
    blocks = [np.asarray(p0, dtype=float)]
    L = blocks[0].size
    steps = []
    for k, (a, b, d) in enumerate(ssys._pm_sys):
        for s in (a, b):
            cm, cp = _lowered(s)
            if set(cm) != set(maps) or not all(_same_map(cm[r], maps[r])
                                               for r in maps) or cp.size != L:
                raise TypeError(
                    f"backend='compiled': the sensitivities of {type(ssys.base).__name__} "
                    f"cannot run compiled: make_system(p) at params[{k}] "
                    f"{'+' if s is a else '-'} {d / 2:.3g} lowers to other compiled maps "
                    f"than at p (its structure depends on p); use backend='python'")
            blocks.append(np.asarray(cp, dtype=float))
        steps.append(d)
    key = (tuple((r, id(maps[r])) for r in sorted(maps)), tuple(codes))
    proto = _PROTOS.get(key)
    if proto is None:
        from .compiled import CompiledSystem
        from .compiled._system import _load_kernel, keywords
        _load_kernel()
        proto = CompiledSystem(**keywords(_build(maps, codes)), state_dim=ssys.state_dim,
                               name=f"sensitivities of {type(ssys.base).__name__} (compiled)")
        proto.compile()
        proto.__dict__["_keep"] = maps          # the ids of the key stay valid
        _PROTOS[key] = proto
    out = object.__new__(type(proto))
    out.__dict__.update(proto.__dict__)
    out.state_dim = ssys.state_dim
    out.params = np.concatenate([[ssys.fd_step, ssys.graze_tol, ssys.n, ssys.nx0, ssys.np_, L],
                                 steps, *blocks])
    out.max_step = ssys.max_step
    out.components = ssys.components
    for attr in ("flow_map", "jump_map", "jump_guard", "flow_guard", "jump_set", "flow_set"):
        mp = out.__dict__.get(attr)
        if mp is not None:
            out.__dict__[attr] = type(mp)(mp.fn, out)
    return out


#: structure -> the compiled prototype its runs copy
_PROTOS = {}
_OVERLOADED = []


def _as_1d(v):
    """A guard's value as a 1-D float array (compiled code only)."""
    raise NotImplementedError


def _overloads():
    if _OVERLOADED:
        return
    from numba import types
    from numba.extending import overload

    @overload(_as_1d)
    def _ov(v):
        if isinstance(v, (types.Float, types.Integer, types.Boolean)):
            return lambda v: np.full(1, float(v))
        if isinstance(v, types.Array) and v.ndim == 1:
            return lambda v: v.astype(np.float64)
        if isinstance(v, types.UniTuple):
            def impl(v):
                out = np.empty(len(v))
                for i in range(len(v)):
                    out[i] = v[i]
                return out
            return impl
        return None
    _OVERLOADED.append(True)


def _build(maps, codes):
    """The roles of the compiled variational system (plain functions of
    ``(y, t, j, p)`` calling the user's compiled maps ``maps``), written with
    loops on scalars (numba compiles them quickly)."""
    import numba

    from .compiled._types import as_bool, as_vec
    _overloads()
    nj = numba.njit(error_model="numpy")

    def jit(fn):
        return fn if isinstance(fn, numba.core.dispatcher.Dispatcher) else nj(fn)
    GRAZING, NO_GUARD, SIMULTANEOUS, NO_FLOW = (float(c) for c in codes)
    EPS = float(np.finfo(float).eps)
    INF = math.inf
    f_u = jit(maps["flow"])
    g_u = jit(maps["jump"]) if "jump" in maps else None
    h_u = jit(maps["jump_guard"]) if "jump_guard" in maps else None

    @nj
    def sizes(p):                       # n, columns of x0, of p, length of the system's p
        return int(p[2]), int(p[3]), int(p[4]), int(p[5])

    @nj
    def block(p, b):                    # b = 0: nominal; 1 + 2k: p_k +; 2 + 2k: p_k -
        L, o0 = int(p[5]), 6 + int(p[4])
        return p[o0 + b * L:o0 + (b + 1) * L]

    @nj
    def f(x, t, j, P):
        return as_vec(f_u(x, t, j, P))

    def jac_of(fn):
        # the map is the closure's, not an argument: a dispatcher passed as an
        # argument is a dynamic global, which numba's disk cache refuses
        @nj
        def jac(x, t, j, P, step, k):
            """(k, n) central differences in x of ``fn``, a map of k values
            (the flow or jump map, k = n; the guards) (``_fd_jac``)."""
            n = x.shape[0]
            J = np.empty((k, n))
            for i in range(n):
                d = step * max(1.0, abs(x[i]))
                xp, xm = x.copy(), x.copy()
                xp[i] += d
                xm[i] -= d
                a, b = fn(xp, t, j, P), fn(xm, t, j, P)
                den = xp[i] - xm[i]
                for r in range(k):
                    J[r, i] = (a[r] - b[r]) / den
            return J
        return jac

    jac_f = jac_of(f)
    out = {}

    def flow(y, t, j, p):
        n, nx0, npar, _ = sizes(p)
        m = nx0 + npar
        P0 = block(p, 0)
        x = y[:n].copy()
        N = y.shape[0]
        out = np.zeros(N)
        fx = f(x, t, j, P0)
        for r in range(n):
            out[r] = fx[r]
        if y[N - 1] == 0.0 and m > 0:
            J = jac_f(x, t, j, P0, p[0], n)
            for r in range(n):
                for c in range(m):
                    s = 0.0
                    for q in range(n):
                        s += J[r, q] * y[n + q * m + c]
                    out[n + r * m + c] = s
            for k in range(npar):
                a, b = f(x, t, j, block(p, 1 + 2 * k)), f(x, t, j, block(p, 2 + 2 * k))
                for r in range(n):
                    out[n + r * m + nx0 + k] += (a[r] - b[r]) / p[6 + k]
        return out
    out["flow"] = flow

    def subset(fn, role):               # a set or guard of the system, on x only
        u = jit(fn)
        if role in ("jump_set", "flow_set"):
            def w(y, t, j, p):
                return as_bool(u(y[:int(p[2])].copy(), t, j, block(p, 0)))
        else:
            def w(y, t, j, p):
                return u(y[:int(p[2])].copy(), t, j, block(p, 0))
        return w
    for role in ("jump_guard", "flow_guard", "jump_set", "flow_set"):
        if role in maps:
            out[role] = subset(maps[role], role)
    if g_u is None:
        return out

    @nj
    def g(x, t, j, P):
        return as_vec(g_u(x, t, j, P))

    if h_u is None:
        @nj
        def h(x, t, j, P):
            return np.zeros(0)
    else:
        @nj
        def h(x, t, j, P):
            return _as_1d(h_u(x, t, j, P))

    def d_dt_of(fn):
        @nj
        def d_dt(x, s, j, P, step):
            """Central difference in t of the map ``fn`` (the jump map, the
            guards) (``_fd_scalar``)."""
            d = step * max(1.0, abs(s))
            sp, sm = s + d, s - d
            return (fn(x, sp, j, P) - fn(x, sm, j, P)) / (sp - sm)
        return d_dt
    jac_g, jac_h, dt_g, dt_h = jac_of(g), jac_of(h), d_dt_of(g), d_dt_of(h)

    @nj
    def rate(z, s, j, P, d, i):         # dh/dt along the flow at (z, s)
        fz = f(z, s, j, P)
        return (h(z + d * fz, s + d, j, P)[i] - h(z - d * fz, s - d, j, P)[i]) / (2 * d)

    @nj
    def tangency(x, t, j, P, hdot, i, t_last, step):
        """``SensitivitySystem._tangency``."""
        fx = f(x, t, j, P)
        smin = INF
        for r in range(x.shape[0]):
            if abs(fx[r]) > 0:
                smin = min(smin, max(1.0, abs(x[r])) / abs(fx[r]))
        d = step * min(max(1.0, abs(t)), smin)
        hddot = (rate(x + d * fx, t + d, j, P, d, i)
                 - rate(x - d * fx, t - d, j, P, d, i)) / (2 * d)
        span = abs(hddot) * (t - t_last)
        if span == 0:
            return 0.0 if hdot == 0 else INF
        return 2 * abs(hdot) / span

    def jump(y, t, j, p):
        n, nx0, npar, _ = sizes(p)
        m = nx0 + npar
        iS, iD, iT = n, n + n * m, n + n * m + m
        P0, step = block(p, 0), p[0]
        x = y[:n].copy()
        N = y.shape[0]
        out = np.zeros(N)
        xp = g(x, t, j, P0)
        for r in range(n):
            out[r] = xp[r]
        t_last, flag = y[iT], y[N - 1]
        out[iT] = t
        if flag != 0.0 or m == 0:
            for q in range(iS, iD):
                out[q] = y[q]
            out[N - 1] = flag
            return out
        f_minus = f(x, t, j, P0)
        dt = y[iD:iT].copy()
        code = 0.0
        if h_u is None:
            code = NO_GUARD
        else:
            hv = h(x, t, j, P0)
            k = hv.shape[0]
            grad = jac_h(x, t, j, P0, step, k)
            ht = dt_h(x, t, j, P0, step)
            i, nzero, zero_i = 0, 0, False
            for c in range(k):
                if hv[c] < hv[i]:
                    i = c
            hdot_i = 0.0
            for c in range(k):
                hd, sc = ht[c], 0.0
                for q in range(n):
                    hd += grad[c, q] * f_minus[q]
                    sc += abs(grad[c, q]) * max(abs(x[q]), 1.0)
                z = abs(hv[c]) <= 1e-9 * max(1.0, abs(t)) * abs(hd) + 256 * EPS * sc
                nzero += z
                if c == i:
                    zero_i, hdot_i = z, hd
            flowed = t > t_last
            if flowed and zero_i:
                if nzero > 1:
                    code = SIMULTANEOUS
                elif tangency(x, t, j, P0, hdot_i, i, t_last, step) <= p[1]:
                    code = GRAZING
                else:
                    for c in range(m):
                        s = 0.0
                        for q in range(n):
                            s += grad[i, q] * y[iS + q * m + c]
                        dt[c] = s
                    for kk in range(npar):
                        a = h(x, t, j, block(p, 1 + 2 * kk))[i]
                        b = h(x, t, j, block(p, 2 + 2 * kk))[i]
                        dt[nx0 + kk] += (a - b) / p[6 + kk]
                    for c in range(m):
                        dt[c] = -dt[c] / hdot_i
            elif flowed:
                code = NO_GUARD
            elif zero_i:
                code = NO_FLOW
        if code != 0.0:
            for q in range(iS, iD):
                out[q] = y[q]
            out[N - 1] = code
            return out
        Dg = jac_g(x, t, j, P0, step, x.shape[0])
        gt = dt_g(x, t, j, P0, step)
        f_plus = f(xp, t, j + 1, P0)
        for r in range(n):
            v = gt[r] - f_plus[r]
            for q in range(n):
                v += Dg[r, q] * f_minus[q]
            for c in range(m):
                s = 0.0
                for q in range(n):
                    s += Dg[r, q] * y[iS + q * m + c]
                out[iS + r * m + c] = s + v * dt[c]
        for kk in range(npar):
            a = g(x, t, j, block(p, 1 + 2 * kk))
            b = g(x, t, j, block(p, 2 + 2 * kk))
            for r in range(n):
                out[iS + r * m + nx0 + kk] += (a[r] - b[r]) / p[6 + kk]
        for c in range(m):
            out[iD + c] = dt[c]
        return out
    out["jump"] = jump
    return out
