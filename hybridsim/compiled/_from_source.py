"""Plain hybrid systems on the compiled path: their own maps, rewritten and compiled.

A :class:`hybridsim.HybridSystem` subclass (or a
:meth:`~hybridsim.HybridSystem.from_functions` system) with no compiled
form of its own runs compiled as written: :func:`hybridsim._source.plan`
rewrites its maps as functions of ``(x, t, j, p)`` (the numbers and arrays
they read are slots of ``p``; helpers are followed), and this module
compiles them into a :class:`~hybridsim.compiled.CompiledSystem`.

Before every run ``p`` is read again from the system (its attributes, its
closures' numbers, module globals): changing ``ball.e`` between runs
changes the next run, and a value that changes kind or shape (a float
becoming an array) rewrites the maps. The compiled maps depend only on the
rewritten source: systems whose source is the same (every instance of a
class) share them.

The rewritten source is a module of its own, named by the digest of its
text (and of numba's and Python's versions), kept on disk beside the
engine's specialised kernels and compiled with numba's ``cache=True``: a
new process loads the compiled maps instead of compiling them. The file is
created exclusively (written to a private temporary file, then linked to
its name, never replaced), and its text is read back and compared with the
text generated in this process before it is executed; a file that differs
is never run (the module is then compiled in memory).
"""
from __future__ import annotations

import functools
import hashlib
import re
import sys
import types
import warnings

import numpy as np

from .. import _source
from ..system import HybridSystem

__all__ = ["FallbackWarning", "applies", "refusal", "lower_source", "auto_choice",
           "compiled_function"]


class FallbackWarning(UserWarning):
    """``backend="auto"`` ran a system on the Python path because its maps
    cannot run compiled (the message says which method and line, and why)."""


_PLAIN = {}


def applies(system):
    """Whether ``system`` is a plain model: a single system with no compiled form."""
    t = type(system)
    hit = _PLAIN.get(t)
    if hit is None:
        from ..compose import Interconnection
        from ._system import CompiledSystem
        hit = _PLAIN[t] = (issubclass(t, HybridSystem)
                           and not issubclass(t, (CompiledSystem, Interconnection))
                           and getattr(t, "compiled_component", None) is None)
    return hit and "compiled_component" not in system.__dict__


def _plan(system, component=False):
    """The system's plan (cached on the system while its maps are the same);
    ``component``: its maps of ``(x, u, t, j, p)`` as a part of an
    interconnection."""
    key = _identity(system)
    slot = "_source_component" if component else "_source_plan"
    hit = system.__dict__.get(slot)
    if hit is not None and hit[0] == key:
        return hit[1]
    try:
        pl = _source.plan(system, component=component)
    except _source.SourceRefusal as e:
        pl = e
    system.__dict__[slot] = (key, pl)
    return pl


def _identity(system):
    """What a plan depends on besides its slots' values: the class, the maps
    given on the instance and what the lowering's checks read (a class whose
    methods are replaced after its first compiled run keeps its first plan)."""
    g = system.__dict__.get
    return (type(system), system.needs_history, system.delays, system.input_dim,
            id(g("flow_map")), id(g("jump_map")), id(g("jump_guard")), id(g("flow_guard")),
            id(g("jump_set")), id(g("flow_set")), id(g("watch")), id(g("diffusion")),
            id(g("jump_rate")))


def cached(system):
    """The system's compiled form when nothing it depends on changed since it
    was made (its ``p`` read again now), else None: the fast path of every
    run after the first."""
    d = system.__dict__
    hit, sp = d.get("_lowered"), d.get("_source_plan")
    if hit is None or sp is None or hit.__dict__.get("_source_plan_of") is not sp[1] \
            or sp[0] != _identity(system):
        return None
    p = sp[1].layout.read()
    if p is None:
        return None
    if p.size and not np.array_equal(hit.params, p):
        hit.params = p
    hit.max_step = _max_step(system, hit.delays)
    if hit.watch is not None:
        hit.watch_direction = system.watch_direction
    return hit


def _delays(system, plan):
    """The delays the compiled flow reads: the system's (its rewritten flow map
    reads ``self.history(t - tau)`` at them)."""
    from ..options import check_delay_times
    if getattr(plan, "reads_past", False) or tuple(system.delays or ()):
        return check_delay_times(system.delays)
    return ()


def _max_step(system, delays):
    """The system's ``max_step``, no larger than its smallest delay (as
    :class:`~hybridsim.compiled.CompiledSystem` caps it)."""
    if not delays:
        return system.max_step
    cap = min(delays)
    return cap if system.max_step is None else min(float(system.max_step), cap)


def refusal(system):
    """Why ``system``'s maps cannot be rewritten (a :class:`SourceRefusal`), or None."""
    pl = _plan(system)
    return pl if isinstance(pl, _source.SourceRefusal) else None


_CANNOT = "has no compiled form and its maps cannot be rewritten for numba"


def _text(system, e):
    return f"{type(system).__name__} {_CANNOT}: {e}"


# ------------------------------------------------------------------ the module
_MODULES = {}


@functools.cache
def _helpers_text():
    """The source of the helpers generated maps call (numba's cache of a map
    holds them inlined: a changed helper must name a new module)."""
    import inspect
    try:
        return "".join(inspect.getsource(f) for f in (_scalar_fn, _helpers, _into,
                                                       _matvec_cat))
    except OSError:                 # no source shipped: the bytecode
        return repr([getattr(f, "__wrapped__", f).__code__.co_code
                     for f in (_scalar_fn, _helpers, _into, _matvec_cat)])


def _digest(plan):
    import numba
    h = hashlib.sha256()
    for part in (plan.source, numba.__version__, sys.version, _helpers_text()):
        h.update(part.encode())
        h.update(b"\0")
    for name, d in sorted(plan.dispatchers.items()):
        code = d.py_func.__code__
        h.update(name.encode() + code.co_code + repr(code.co_consts).encode())
    return h.hexdigest()[:32]


def _module(plan):
    """``(module, digest)``: the plan's functions compiled (numba dispatchers).

    The text is the generated module ``hybridsim_src_<digest>`` of
    :func:`hybridsim.compiled._cache._generated_module` (its file written once
    in a private folder and read back before it runs), so numba caches the
    functions by its path; made in memory, and not cached, where no folder is
    private and writable."""
    from ._cache import _generated_module
    from ._system import _load_kernel
    _load_kernel()                  # numba, or the ImportError saying how to install it
    import numba
    digest = _digest(plan)
    mod = _MODULES.get(digest)
    if mod is not None:
        return mod, digest
    name = f"hybridsim_src_{digest}"
    src = plan.source
    mod = _generated_module(name, src, execute=False)
    cached = mod is not None
    if not cached:
        mod = types.ModuleType(name)
        mod.__file__ = f"<hybridsim {name}>"
    if "__hs_bound__" not in mod.__dict__:
        try:
            # the text generated here (compared with the file's), compiled under its name
            exec(compile(src, mod.__file__, "exec"), mod.__dict__)
        except BaseException:
            sys.modules.pop(name, None)
            raise
        mod.__dict__.update(plan.dispatchers)
        mod.__dict__.update(_scalar_fn())
        mod.__dict__["_hs_past"] = _helpers()["past"]
        for fname in plan.qualnames:
            mod.__dict__[fname] = numba.njit(cache=cached,
                                             error_model="numpy")(mod.__dict__[fname])
        mod.__hs_bound__ = True
    _MODULES[digest] = mod
    return mod, digest


def _numba():
    try:
        import numba
    except ImportError as e:
        raise ImportError("the compiled path needs numba: pip install 'hybridsim[fast]'; "
                          "run the system on the Python path (backend='python') "
                          "without it") from e
    return numba


@functools.cache
def _helpers():
    numba = _numba()
    nj = numba.njit(error_model="numpy")

    @nj
    def matvec(p, off, rows, cols, v):
        """``M @ v`` with M (rows, cols) stored row-major in ``p`` from ``off``."""
        out = np.zeros(rows)
        for i in range(rows):
            s = 0.0
            b = off + i * cols
            for k in range(cols):
                s += p[b + k] * v[k]
            out[i] = s
        return out

    @nj
    def matvec_add(p, off, rows, cols, v, out):
        """``out += M @ v`` (M as in :func:`matvec`)."""
        for i in range(rows):
            s = 0.0
            b = off + i * cols
            for k in range(cols):
                s += p[b + k] * v[k]
            out[i] += s

    @nj
    def matvec_into(p, off, rows, cols, v, out, mode):
        """``out = M @ v`` (``mode`` 0), ``out += M @ v`` (1) or ``out -= M @ v``
        (-1), in place (M as in :func:`matvec`; each row's sum as matvec's)."""
        if out.shape[0] != rows or v.shape[0] != cols:
            raise ValueError("matmul: the shapes do not match")
        for i in range(rows):
            s = 0.0
            b = off + i * cols
            for k in range(cols):
                s += p[b + k] * v[k]
            if mode == 0:
                out[i] = s
            elif mode > 0:
                out[i] += s
            else:
                out[i] -= s

    @nj
    def put(out, a, b, v):
        """``out[a:b] = v`` as a loop (numba's slice assignment compiles the
        formatting of its shape error: seconds of the first compile)."""
        if v.shape[0] != b - a:
            raise ValueError("a component's map returned an array of another length")
        for q in range(b - a):
            out[a + q] = v[q]

    @nj
    def add_into(u, v):
        """``u += v`` as a loop (see ``put``)."""
        if v.shape[0] != u.shape[0]:
            raise ValueError("a component's output has another length than the input it feeds")
        for q in range(u.shape[0]):
            u[q] += v[q]

    @nj
    def past(p, lag, off, nd, n):
        """``self.history(t - lag)`` in a rewritten flow map: the state at the delay
        ``p[off + i]`` equal to ``lag``, from the past the engine writes after the
        parameters (``CompiledSystem(delays=)``), as a new array."""
        b = p.shape[0] - nd * n
        for i in range(nd):
            d = p[off + i]
            if abs(lag - d) <= 1e-12 * max(1.0, abs(d)):
                return p[b + i * n:b + (i + 1) * n].copy()
        raise ValueError("self.history(t - tau) is read at a tau that is not one of the "
                         "system's delays (self.delays)")

    return {"matvec": matvec, "matvec_add": matvec_add, "matvec_into": matvec_into,
            "put": put, "add_into": add_into, "past": past}


_SCALAR = []


def _scalar_fn():
    """The helpers of generated maps by name: ``_hs_scalar``, a guard's or a set's
    value as a number (a 0-d array's element, anything else as it is),
    ``_hs_matmul``, ``a @ b`` of vectors and matrices as loops summing in
    index order (no BLAS call per product of a small matrix; the sums of
    :func:`hybridsim.compiled.matvec`), and the products with a matrix read
    in place from ``p``: ``_hs_pmv`` (``v @ M.T``), ``_hs_mpv`` (``M @ v``)
    and their ``_add`` forms (``y += ...``); and the calls of a map written
    along the last axis (``_Rewrite._of_numbers``, ``_Rewrite._gather``),
    typed by their operands: ``_hs_stack``, ``_hs_full``, ``_hs_full_like``,
    ``_hs_clip``, ``_hs_astype``, ``_hs_take``, ``_hs_take_row``,
    ``_hs_newaxis1``/``2`` (of numbers, numbers; of arrays, numpy's calls);
    ``_hs_setitem``, a slice assignment (``_LastAxis._setitem``), of vectors
    a loop."""
    if not _SCALAR:
        from numba.core import types as nt
        from numba.extending import overload, register_jitable

        def _hs_scalar(v):
            return v

        @overload(_hs_scalar)
        def _typed(v):
            if isinstance(v, nt.Array) and v.ndim == 0:
                return lambda v: v[()]
            return lambda v: v

        def _hs_matmul(a, b):
            return a @ b

        @overload(_hs_matmul)
        def _typed_matmul(a, b):
            if not (isinstance(a, nt.Array) and isinstance(b, nt.Array)) \
                    or a.ndim not in (1, 2) or b.ndim not in (1, 2):
                return lambda a, b: a @ b
            if a.ndim == 1 and b.ndim == 1:
                def dot(a, b):
                    if a.shape[0] != b.shape[0]:
                        raise ValueError("matmul: the shapes do not match")
                    s = 0.0
                    for k in range(a.shape[0]):
                        s += a[k] * b[k]
                    return s
                return dot
            if a.ndim == 2 and b.ndim == 1:
                def mv(a, b):
                    r, c = a.shape
                    if c != b.shape[0]:
                        raise ValueError("matmul: the shapes do not match")
                    out = np.empty(r)
                    for i in range(r):
                        s = 0.0
                        for k in range(c):
                            s += a[i, k] * b[k]
                        out[i] = s
                    return out
                return mv
            if a.ndim == 1 and b.ndim == 2:
                def vm(a, b):
                    r, c = b.shape
                    if a.shape[0] != r:
                        raise ValueError("matmul: the shapes do not match")
                    out = np.empty(c)
                    for i in range(c):
                        s = 0.0
                        for k in range(r):
                            s += a[k] * b[k, i]
                        out[i] = s
                    return out
                return vm

            def mm(a, b):
                r, q = a.shape
                c = b.shape[1]
                if b.shape[0] != q:
                    raise ValueError("matmul: the shapes do not match")
                out = np.empty((r, c))
                for i in range(r):
                    for m in range(c):
                        s = 0.0
                        for k in range(q):
                            s += a[i, k] * b[k, m]
                        out[i, m] = s
                return out
            return mm

        # M @ v with M (r, c) row-major in p from off: hybridsim.compiled.matvec
        # (v a vector), else the product of the matrix
        # (the helpers and their loops inlined in the map: a call of a compiled
        # function passing arrays costs more than a small product)
        h = {k: _numba().njit(inline="always", error_model="numpy")(f.py_func)
             for k, f in _helpers().items()}
        matvec, matvec_add = h["matvec"], h["matvec_add"]

        def _hs_pmv(p, off, r, c, v):
            return v @ p[off:off + r * c].reshape((r, c)).T

        @overload(_hs_pmv)
        def _typed_pmv(p, off, r, c, v):
            if isinstance(v, nt.Array) and v.ndim == 1:
                return lambda p, off, r, c, v: matvec(p, off, r, c, v)
            return lambda p, off, r, c, v: _hs_matmul(v, p[off:off + r * c].reshape((r, c)).T)

        def _hs_pmv_add(p, off, r, c, v, y):
            y += v @ p[off:off + r * c].reshape((r, c)).T

        @overload(_hs_pmv_add)
        def _typed_pmv_add(p, off, r, c, v, y):
            if isinstance(v, nt.Array) and v.ndim == 1 and isinstance(y, nt.Array) \
                    and y.ndim == 1:
                return lambda p, off, r, c, v, y: matvec_add(p, off, r, c, v, y)

            def add(p, off, r, c, v, y):
                y += _hs_matmul(v, p[off:off + r * c].reshape((r, c)).T)
            return add

        # M @ v with M on the left: the same as _hs_pmv for a vector v, M V for a matrix
        def _hs_mpv(p, off, r, c, v):
            return p[off:off + r * c].reshape((r, c)) @ v

        @overload(_hs_mpv)
        def _typed_mpv(p, off, r, c, v):
            if isinstance(v, nt.Array) and v.ndim == 1:
                return lambda p, off, r, c, v: matvec(p, off, r, c, v)
            return lambda p, off, r, c, v: _hs_matmul(p[off:off + r * c].reshape((r, c)), v)

        def _hs_mpv_add(p, off, r, c, v, y):
            y += p[off:off + r * c].reshape((r, c)) @ v

        @overload(_hs_mpv_add)
        def _typed_mpv_add(p, off, r, c, v, y):
            if isinstance(v, nt.Array) and v.ndim == 1 and isinstance(y, nt.Array) \
                    and y.ndim == 1:
                return lambda p, off, r, c, v, y: matvec_add(p, off, r, c, v, y)

            def add(p, off, r, c, v, y):
                y += _hs_matmul(p[off:off + r * c].reshape((r, c)), v)
            return add
        # a sum of products written in place (``out[a:b] = M @ v + N @ w``): the first
        # term set, the others added or subtracted, each row's sum as matvec's
        into = h["matvec_into"]
        fns = {}
        for side, left in (("_hs_pmv", False), ("_hs_mpv", True)):
            for mode, sign in (("_set", 0), ("_sub", -1)):
                fns[side + mode] = _into(overload, nt, into, _hs_matmul, left, sign)

        # M @ np.concatenate(pieces): of 1-D pieces, matvec's sums read from the pieces
        # (no concatenated array); else the product of the concatenation
        def _hs_pmv_cat(p, off, r, c, pieces, axis):
            return _hs_pmv(p, off, r, c, np.concatenate(pieces, axis=axis))

        def _hs_mpv_cat(p, off, r, c, pieces, axis):
            return _hs_mpv(p, off, r, c, np.concatenate(pieces, axis=axis))

        def _cat_typed(product):
            def typed(p, off, r, c, pieces, axis):
                if isinstance(pieces, nt.UniTuple) and isinstance(pieces.dtype, nt.Array) \
                        and pieces.dtype.ndim == 1:
                    return _matvec_cat
                return lambda p, off, r, c, pieces, axis: product(
                    p, off, r, c, np.concatenate(pieces, axis=axis))
            return typed
        overload(_hs_pmv_cat)(_cat_typed(_hs_pmv))
        overload(_hs_mpv_cat)(_cat_typed(_hs_mpv))

        def _hs_reshape(v, shape):
            return v.reshape(shape)

        @overload(_hs_reshape)
        def _typed_reshape(v, shape):
            if isinstance(v, nt.Array) and v.layout != "C":
                return lambda v, shape: np.ascontiguousarray(v).reshape(shape)
            return lambda v, shape: v.reshape(shape)

        def _hs_where(c, a, b):
            return np.where(c, a, b)

        @overload(_hs_where)
        def _typed_where(c, a, b):
            if not any(isinstance(v, nt.Array) for v in (c, a, b)):
                return lambda c, a, b: a if c else b
            return lambda c, a, b: np.where(c, a, b)
        # a map written along the last axis, on one state (``_Rewrite._of_numbers``):
        # of numbers, numbers (a 1-D array of a stack); of arrays, numpy's call
        from numba import literal_unroll

        def _numbers(*vs):
            return not any(isinstance(v, nt.Array) for v in vs)

        def _hs_stack(items, axis):
            return np.stack(items, axis)

        @overload(_hs_stack)
        def _typed_stack(items, axis):
            if isinstance(items, nt.BaseTuple) and _numbers(*items):
                n = len(items)

                def stack(items, axis):
                    out = np.empty(n)
                    i = 0
                    for v in literal_unroll(items):
                        out[i] = v
                        i += 1
                    return out
                return stack
            return lambda items, axis: np.stack(items, axis)

        def _hs_full(e, v):
            return np.full(np.shape(e), v)

        @overload(_hs_full)
        def _typed_full(e, v):
            if _numbers(e):
                return lambda e, v: v
            return lambda e, v: np.full(e.shape, v)

        def _hs_full_like(e, v):
            return np.full_like(e, v)

        @overload(_hs_full_like)
        def _typed_full_like(e, v):
            if isinstance(e, nt.Boolean):
                return lambda e, v: bool(v)
            if isinstance(e, nt.Integer):
                return lambda e, v: int(v)
            if _numbers(e):
                return lambda e, v: float(v)
            return lambda e, v: np.full_like(e, v)

        def _hs_clip(a, lo, hi):
            return np.clip(a, lo, hi)

        @overload(_hs_clip)
        def _typed_clip(a, lo, hi):
            if _numbers(a, lo, hi):
                return lambda a, lo, hi: min(max(a, lo), hi)
            return lambda a, lo, hi: np.clip(a, lo, hi)

        def _hs_astype(v, dtype):
            return v.astype(dtype)

        @overload(_hs_astype)
        def _typed_astype(v, dtype):
            if _numbers(v):
                return lambda v, dtype: dtype(v)
            return lambda v, dtype: v.astype(dtype)
        def _hs_take(a, i):
            return np.take_along_axis(a, np.expand_dims(i, -1), -1)[..., 0]

        @overload(_hs_take)
        def _typed_take(a, i):
            if isinstance(a, nt.Array) and a.ndim == 1 and isinstance(i, nt.Integer):
                return lambda a, i: a[i]
            return lambda a, i: np.take_along_axis(a, np.expand_dims(i, -1), -1)[..., 0]
        def _hs_take_row(a, i):
            return np.take_along_axis(a, np.expand_dims(np.expand_dims(i, -1), -1),
                                      -2)[..., 0, :]

        @overload(_hs_take_row)
        def _typed_take_row(a, i):
            if isinstance(a, nt.Array) and a.ndim == 2 and isinstance(i, nt.Integer):
                return lambda a, i: a[i]
            return lambda a, i: np.take_along_axis(
                a, np.expand_dims(np.expand_dims(i, -1), -1), -2)[..., 0, :]

        def _hs_newaxis1(e):
            return e[..., None]

        def _hs_newaxis2(e):
            return e[..., None, None]

        def _typed_newaxis(axes):
            def typed(e):
                if _numbers(e):             # a number broadcasts as e[..., None] does
                    return lambda e: e
                if isinstance(e, nt.Array) and e.ndim == 0:
                    return lambda e: e[()]
                if axes == 1:
                    return lambda e: np.expand_dims(e, -1)
                return lambda e: np.expand_dims(np.expand_dims(e, -1), -1)
            return typed
        overload(_hs_newaxis1)(_typed_newaxis(1))
        overload(_hs_newaxis2)(_typed_newaxis(2))

        @register_jitable
        def _put_slice(a, start, step, n, v):
            """``a[start::step][:n] = v`` of vectors as numpy assigns it: ``v`` of
            length n or 1 (broadcast), as if read whole before the writes where
            it overlaps ``a`` (contiguous: memmove's order; else a copy)."""
            m = v.shape[0]
            if m != n and m != 1:
                raise ValueError("cannot assign slice from input of different size")
            if m == 1:
                x = v[0]
                for i in range(n):
                    a[start + i * step] = x
                return
            isz = a.itemsize
            pa, pv, sa, sv = a.ctypes.data, v.ctypes.data, a.strides[0], v.strides[0]
            if step == 1 and sa == isz and sv == v.itemsize:
                if pa + start * isz <= pv:
                    for i in range(n):
                        a[start + i] = v[i]
                else:
                    for i in range(n - 1, -1, -1):
                        a[start + i] = v[i]
                return
            la, lv = (a.shape[0] - 1) * sa, (m - 1) * sv
            if (pv + min(0, lv) < pa + max(0, la) + isz
                    and pa + min(0, la) < pv + max(0, lv) + v.itemsize):
                w = v.copy()
                for i in range(n):
                    a[start + i * step] = w[i]
            else:
                for i in range(n):
                    a[start + i * step] = v[i]

        def _hs_setitem(a, index, v):
            a[index] = v

        @overload(_hs_setitem)
        def _typed_setitem(a, index, v):
            if isinstance(a, nt.Array) and a.ndim == 1 and isinstance(v, nt.Array) \
                    and v.ndim == 1:
                if isinstance(index, nt.SliceType):
                    def put(a, index, v):
                        start, stop, step = index.indices(a.shape[0])
                        _put_slice(a, start, step, len(range(start, stop, step)), v)
                    return put
                if isinstance(index, nt.BaseTuple) and len(index) == 2 \
                        and isinstance(index[0], nt.EllipsisType) \
                        and isinstance(index[1], nt.SliceType):
                    def put_last(a, index, v):
                        start, stop, step = index[1].indices(a.shape[0])
                        _put_slice(a, start, step, len(range(start, stop, step)), v)
                    return put_last

            def setitem(a, index, v):
                a[index] = v
            return setitem
        fns.update(_hs_stack=_hs_stack, _hs_full=_hs_full, _hs_full_like=_hs_full_like,
                   _hs_clip=_hs_clip, _hs_astype=_hs_astype, _hs_take=_hs_take,
                   _hs_take_row=_hs_take_row, _hs_newaxis1=_hs_newaxis1,
                   _hs_newaxis2=_hs_newaxis2, _hs_setitem=_hs_setitem)
        _SCALAR.append({"_hs_scalar": _hs_scalar, "_hs_matmul": _hs_matmul,
                        "_hs_pmv": _hs_pmv, "_hs_pmv_add": _hs_pmv_add,
                        "_hs_mpv": _hs_mpv, "_hs_mpv_add": _hs_mpv_add,
                        "_hs_where": _hs_where, "_hs_reshape": _hs_reshape,
                        "_hs_pmv_cat": _hs_pmv_cat, "_hs_mpv_cat": _hs_mpv_cat, **fns})
    return _SCALAR[0]


def _matvec_cat(p, off, r, c, pieces, axis):
    """``M @ np.concatenate(pieces)`` of 1-D pieces, M (r, c) row-major in ``p``
    from ``off``: each row's sum over the pieces in order (matvec's sums)."""
    n = 0
    for a in pieces:
        n += a.shape[0]
    if n != c:
        raise ValueError("matmul: the shapes do not match")
    out = np.empty(r)
    for i in range(r):
        s = 0.0
        b = off + i * c
        for a in pieces:
            for q in range(a.shape[0]):
                s += p[b] * a[q]
                b += 1
        out[i] = s
    return out


def _into(overload, nt, into, matmul, left, sign):
    """``f(p, off, r, c, v, out)``: ``out = M @ v`` (``left``; else ``v @ M.T``)
    in place (``sign`` 0) or ``out -= ...`` (-1), M (r, c) row-major in ``p``
    from ``off``; of a vector v and a 1-D out, the loops of matvec."""
    def f(p, off, r, c, v, out):
        pass

    @overload(f)
    def typed(p, off, r, c, v, out):
        if isinstance(v, nt.Array) and v.ndim == 1 and isinstance(out, nt.Array) \
                and out.ndim == 1:
            return lambda p, off, r, c, v, out: into(p, off, r, c, v, out, sign)

        def product(p, off, r, c, v):
            M = p[off:off + r * c].reshape((r, c))
            return matmul(M, v) if left else matmul(v, M.T)
        if sign == 0:
            def put(p, off, r, c, v, out):
                out[:] = product(p, off, r, c, v)
            return put

        def sub(p, off, r, c, v, out):
            out -= product(p, off, r, c, v)
        return sub
    return f


def component_maps(system):
    """A plain component's maps as functions of ``(x, u, t, j, p)`` (its
    output of ``(x, t, j, p)``), compiled, and ``p`` read now:
    ``(maps, output or None, params)`` for a :class:`~hybridsim.compiled.Component`.

    Raises
    ------
    TypeError
        The maps cannot be rewritten (naming the method and line).
    """
    from ._system import _refuse
    pl = _plan(system, component=True)
    p = None if isinstance(pl, _source.SourceRefusal) else pl.layout.read()
    if p is None and not isinstance(pl, _source.SourceRefusal):
        system.__dict__.pop("_source_component", None)      # a value changed kind
        pl = _plan(system, component=True)
        p = None if isinstance(pl, _source.SourceRefusal) else pl.layout.read()
    if isinstance(pl, _source.SourceRefusal):
        err = _refuse(type(system).__name__, _text(system, pl))
        err.method, err.line, err.why = pl.method, pl.line, pl.why
        raise err
    mod, _ = _module(pl)
    maps = {role: getattr(mod, name) for role, name in pl.roles.items() if role != "output"}
    out = pl.roles.get("output")
    return maps, (None if out is None else getattr(mod, out)), p, _delays(system, pl)


def compiled_function(fn):
    """A plain function ``fn(*args)`` compiled from its source as ``f(p, *args)``
    (its numbers and arrays read into ``p`` now): ``(f, p)``, ``f`` a numba
    dispatcher shared by every function of the same rewritten source.

    Raises
    ------
    TypeError
        Its source cannot be rewritten (a :class:`~hybridsim._source.SourceRefusal`
        naming the line).
    """
    pl = _source.plan_function(fn)
    p = pl.layout.read()
    mod, _ = _module(pl)
    return getattr(mod, pl.roles["function"]), p


def component_refusal(system):
    """Why a plain component's maps cannot be rewritten (a :class:`SourceRefusal`), or None."""
    pl = _plan(system, component=True)
    return pl if isinstance(pl, _source.SourceRefusal) else None


# ------------------------------------------------------------------ lowering
#: (digest, specialize) -> the compiled prototype its systems copy
_PROTOS = {}

_LINE = re.compile(r'hybridsim_src_[0-9a-f]+\.py"?, line (\d+)')


def _compile_error(system, plan, e):
    """numba's failure, named by the user's method and line."""
    from ._system import KEYWORDS, CompileError, _summarise
    cause = e.__cause__ if e.__cause__ is not None else e
    where = None
    for m in _LINE.finditer(str(cause)):
        where = plan.where(int(m.group(1)))
        if where is not None:
            break
    role = getattr(e, "map_name", None)       # a keyword: flow_map, jump_map...
    at = (f"{where[0]} ({where[1]})" if where is not None else plan.qualnames.get(
        plan.roles.get({k: r for r, k in KEYWORDS.items()}.get(role, ""), ""), role))
    err = CompileError(f"backend='compiled': {type(system).__name__} cannot run compiled: "
                       f"numba could not compile {at}: {_summarise(cause)}. Run it on the "
                       f"Python path (backend='python')", role)
    err.where = where
    return err


def lower_source(system, specialize=None):
    """The :class:`~hybridsim.compiled.CompiledSystem` of a plain model
    (module notes), its ``params`` read from the system now; cached on the
    system as :func:`~hybridsim.compiled.lower` caches.

    Raises
    ------
    TypeError
        The maps cannot be rewritten (the message names the method and line).
    CompileError
        numba cannot compile a rewritten map (named by method and line).
    """
    hit = cached(system)
    if hit is not None and (specialize is None or hit.specialize == bool(specialize)):
        return hit
    from ._system import CompiledSystem, _refuse, keywords
    pl = _plan(system)
    if isinstance(pl, _source.SourceRefusal):
        err = _refuse(type(system).__name__, _text(system, pl))
        err.method, err.line, err.why = pl.method, pl.line, pl.why
        raise err
    p = pl.layout.read()
    if p is None:                   # a value changed kind or shape: rewrite
        system.__dict__.pop("_source_plan", None)
        pl = _plan(system)
        if isinstance(pl, _source.SourceRefusal):
            return lower_source(system, specialize)
        p = pl.layout.read()
    prev = system.__dict__.get("_lowered")
    if prev is not None and prev.__dict__.get("_source_plan_of") is pl and (
            specialize is None or prev.specialize == bool(specialize)):
        if not np.array_equal(prev.params, p):
            prev.params = p
        prev.max_step = _max_step(system, prev.delays)
        if prev.watch is not None:
            prev.watch_direction = system.watch_direction
        return prev
    spec = bool(specialize) if specialize is not None else False
    mod, digest = _module(pl)
    past = _delays(system, pl)
    proto = _PROTOS.get((digest, spec))
    if proto is None:
        maps = {role: getattr(mod, name) for role, name in pl.roles.items()}
        proto = CompiledSystem(**keywords(maps), state_dim=int(system.state_dim), params=p,
                               specialize=spec, name=f"{type(system).__name__} (compiled)",
                               delays=past)
        try:
            proto.compile()
        except TypeError as e:          # CompileError: named by the user's method and line
            raise _compile_error(system, pl, e) from e
        _PROTOS[(digest, spec)] = proto
    cs = object.__new__(CompiledSystem)
    cs.__dict__.update(proto.__dict__)
    cs.params = p
    cs.delays, cs.needs_history = past, bool(past)
    cs.max_step = _max_step(system, past)
    cs.noise_dim = getattr(system, "noise_dim", None)
    if cs.watch is not None:
        cs.watch_direction = system.watch_direction
    for attr in ("flow_map", "jump_map", "jump_guard", "flow_guard", "jump_set", "flow_set",
                 "watch", "diffusion", "jump_rate"):
        m = cs.__dict__.get(attr)
        if m is not None:
            cs.__dict__[attr] = type(m)(m.fn, cs)
    cs.__dict__["_source_plan_of"] = pl
    cs.layout = pl.layout
    system.__dict__["_lowered"] = cs
    return cs


_WARNED = set()


def auto_choice(system, ok):
    """``backend="auto"``'s choice for a system :func:`~hybridsim.compiled.lowerable`
    judged (``ok``): a plain model is lowered and compiled here, and where its
    maps cannot be (rewritten, or compiled by numba), one :class:`FallbackWarning`
    per class and reason says why and the Python path runs it (other reasons,
    such as reading the history, are ``lowerable(system).reason``)."""
    if not applies(system):
        return "compiled" if ok else "python"
    why = None if ok else getattr(ok, "reason", None)
    if ok:
        try:
            lower_source(system)
        except TypeError as e:
            why = str(e)
    if why is None:
        return "compiled"
    if (_CANNOT not in why and "numba could not compile" not in why) or system.vectorized:
        # history, inputs...; or a vectorized system, whose batches integrate
        # together in numpy: lowerable(system).reason says why
        return "python"
    return _fall_back(system, why, 6)


def _fall_back(system, why, stacklevel):
    """One :class:`FallbackWarning` per class and reason (``stacklevel`` from here
    to the user's call of simulate); "python"."""
    key = (type(system), why)
    if key not in _WARNED:
        _WARNED.add(key)
        warnings.warn(f"backend='auto' runs {type(system).__name__} on the Python path: "
                      f"{why}", FallbackWarning, stacklevel=stacklevel)
    return "python"
