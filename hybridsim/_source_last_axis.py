"""The rewrite's forms of a map written along the last axis (scipy's
``vectorized`` contract: ``x[..., k]``), on one state: the numpy calls whose
operands become numbers there (``_hs_stack``, ``_hs_full``, ...), a row's
gather (``_hs_take``, ``_hs_take_row``), and slice assignment as a loop
(``_hs_setitem``); :class:`_LastAxis` is a part of
:class:`hybridsim._source_rewrite._Rewrite`. The helpers they call are
compiled in :func:`hybridsim.compiled._from_source._scalar_fn`.
"""
from __future__ import annotations

import ast
import copy

from ._source_guards import _call

_DTYPES = {"float": "float64", "int": "int64", "bool": "bool_", "complex": "complex128"}


def _int_of(e):
    """The int a node writes as ``k`` or ``-k`` (a constant), or None."""
    if isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.USub):
        k = _int_of(e.operand)
        return None if k is None else -k
    if isinstance(e, ast.Constant) and type(e.value) is int:
        return e.value
    return None


def _ellipsis_then(sl, *values):
    """Whether the index ``sl`` is ``[..., *values]``: each value a constant
    (None, an int) or ``slice`` for a bare ``:``."""
    return isinstance(sl, ast.Tuple) and len(sl.elts) == 1 + len(values) \
        and isinstance(sl.elts[0], ast.Constant) and sl.elts[0].value is Ellipsis \
        and all((isinstance(e, ast.Slice) and e.lower is e.upper is e.step is None)
                if v is slice else (isinstance(e, ast.Constant) and e.value is v)
                for e, v in zip(sl.elts[1:], values))


def _slice_value(e):
    """The index ``e`` as an expression of a slice (``a:b:c`` as ``slice(a, b,
    c)``; a call of ``slice`` as it is), or None where it is not a slice."""
    if isinstance(e, ast.Slice):
        args = [ast.Constant(None) if v is None else v for v in (e.lower, e.upper, e.step)]
        return ast.copy_location(ast.Call(func=ast.Name(id="slice", ctx=ast.Load()),
                                          args=args, keywords=[]), e)
    if isinstance(e, ast.Call) and isinstance(e.func, ast.Name) and e.func.id == "slice":
        return e
    return None


class _LastAxis:
    """The last axis's forms of :class:`~hybridsim._source_rewrite._Rewrite`
    (it gives ``visit``, ``_module_of``, ``_one_state``, ``_lookup`` and
    ``locals``)."""

    def _setitem(self, node, targets, value):
        """``a[i:j] = v`` (a slice, or ``...`` and a slice; already visited) as
        ``_hs_setitem(a, slice(i, j, None), v)``, which numba compiles as a loop
        where ``a`` and ``v`` are vectors: numba's own slice assignment compiles
        the formatting of its shape-mismatch message, about 1.7 s of CPU in
        each process that compiles a first such map. None where the
        statement is not of that form."""
        if len(targets) != 1 or not isinstance(targets[0], ast.Subscript):
            return None
        t = targets[0]
        key = t.slice
        if isinstance(key, ast.Tuple) and len(key.elts) == 2 \
                and isinstance(key.elts[0], ast.Constant) and key.elts[0].value is Ellipsis:
            last = _slice_value(key.elts[1])
            index = None if last is None else ast.Tuple(elts=[key.elts[0], last],
                                                        ctx=ast.Load())
        else:
            index = _slice_value(key)
        if index is None:
            return None
        base = copy.deepcopy(t.value)
        base.ctx = ast.Load()
        call = _call("_hs_setitem", [base, index, value], node)
        return ast.fix_missing_locations(ast.copy_location(ast.Expr(value=call), node))

    def _of_numbers(self, f, node, args, kws):
        """On one state, the numpy calls of a map written along the last axis
        whose operands become numbers (``x[..., 0]`` is ``x[0]``), as helpers
        typed by their operands (numpy's call where they are arrays):
        ``np.stack(seq, axis=-1)`` (or ``axis=0``) of numbers a 1-D array
        (``_hs_stack``); ``np.zeros(e.shape)``, ``ones``, ``empty``,
        ``np.full(e.shape, c)`` and ``np.shape(e)`` forms, of a number ``e``,
        the number (``_hs_full``); ``np.zeros_like(e)``, ``ones_like``,
        ``empty_like``, ``full_like(e, c)`` the number as ``e``'s type
        (``_hs_full_like``); ``np.zeros(x.shape[:-1], dtype)`` and its kin
        (the batch's shape, of one state ``()``) the number converted;
        ``np.clip(a, lo, hi)`` of numbers ``min(max(a, lo), hi)``
        (``_hs_clip``); ``e.astype(dtype)`` of a number the number converted
        (``_hs_astype``); ``np.broadcast_to(e, x.shape[:-1])`` (the batch's
        shape, of one state ``()``) the number (``_hs_scalar``). A one-state
        vector ``e`` (the map's x, u, and arrays made from them) keeps numpy's call. None
        where ``node`` is none of these."""
        kw = {k.arg: k.value for k in kws}
        if f.attr == "astype" and self._module_of(f.value) is None:
            if len(args) != 1 or kws or self._one_state(f.value):
                return None
            return _call("_hs_astype", [self.visit(f.value), self._builtin_dtype(args[0])],
                         node)
        if getattr(self._module_of(f.value), "__name__", "") != "numpy":
            return None
        name = f.attr
        if name == "stack" and len(args) == 1 and isinstance(args[0], (ast.List, ast.Tuple)) \
                and set(kw) <= {"axis"} and not any(isinstance(v, ast.Starred)
                                                    for v in args[0].elts):
            a = _int_of(kw.get("axis", ast.Constant(value=0)))
            if a not in (0, -1):
                return None
            items = ast.Tuple(elts=list(args[0].elts), ctx=ast.Load())
            return _call("_hs_stack", [items, ast.Constant(value=a)], node)
        fills = {"zeros": 0.0, "ones": 1.0, "empty": 0.0}
        if name in (*fills, "full") and args and self._batch_shape(node.args[0]):
            # np.zeros(x.shape[:-1], bool): of one state, the batch's shape is ()
            rest = list(args[1:])
            if name == "full" and not rest:
                return None
            value = rest.pop(0) if name == "full" else ast.Constant(value=fills[name])
            if len(rest) > 1 or set(kw) - {"dtype"} or (rest and kw):
                return None
            dtype = self._builtin_dtype(rest[0]) if rest else kw.get("dtype")
            return value if dtype is None else _call("_hs_astype", [value, dtype], node)
        if ((name in fills and len(args) == 1) or (name == "full" and len(args) == 2)) \
                and not kws:
            e = self._shape_source(node.args[0], args[0])
            if e is None:
                return None
            v = args[1] if name == "full" else ast.Constant(value=fills[name])
            return _call("_hs_full", [e, v], node)
        likes = {"zeros_like": 0.0, "ones_like": 1.0, "empty_like": 0.0}
        if ((name in likes and len(args) == 1) or (name == "full_like" and len(args) == 2)) \
                and not kws and not self._one_state(node.args[0]):
            v = args[1] if name == "full_like" else ast.Constant(value=likes[name])
            return _call("_hs_full_like", [args[0], v], node)
        if name == "clip" and len(args) == 3 and not kws:
            return _call("_hs_clip", args, node)
        if name == "broadcast_to" and len(args) == 2 and not kws \
                and self._batch_shape(node.args[1]):
            # to the batch's shape: of one state (), the number itself
            return _call("_hs_scalar", [args[0]], node)
        return None

    def _gather(self, node):
        """``np.take_along_axis(a, i[..., None], axis=-1)[..., 0]``, each row's
        element at its own index as a map written along the last axis gathers
        it: ``_hs_take(a, i)``, on one state (a 1-D ``a``, a number ``i``)
        ``a[i]``; ``np.take_along_axis(S, i[..., None, None] + c,
        axis=-2)[..., 0, :]``, each row's row ``i + c`` of its (G, m) block:
        ``_hs_take_row(S, i + c)``, on one state ``S[i + c]``. None where
        ``node`` is not of these forms."""
        c = node.value
        if not (isinstance(node.ctx, ast.Load) and isinstance(c, ast.Call)
                and isinstance(c.func, ast.Attribute) and c.func.attr == "take_along_axis"
                and getattr(self._module_of(c.func.value), "__name__", "") == "numpy"):
            return None
        args, kw = list(c.args), {k.arg: k.value for k in c.keywords}
        if len(args) == 3 and not kw:
            axis = args.pop()
        elif len(args) == 2 and set(kw) == {"axis"}:
            axis = kw["axis"]
        else:
            return None
        if _int_of(axis) not in (-1, -2):
            return None
        rows = _int_of(axis) == -2             # a row of each (..., G, m) block
        want_idx, want_out = ((None, None), (0, slice)) if rows else ((None,), (0,))
        idx, shift = args[1], None
        if rows and isinstance(idx, ast.BinOp) and isinstance(idx.op, (ast.Add, ast.Sub)):
            idx, shift = idx.left, idx          # i[..., None, None] + c: the row i + c
        if not (isinstance(idx, ast.Subscript) and _ellipsis_then(idx.slice, *want_idx)
                and _ellipsis_then(node.slice, *want_out)):
            return None
        i = self.visit(idx.value)
        if shift is not None:
            i = ast.copy_location(ast.BinOp(left=i, op=shift.op, right=self.visit(shift.right)),
                                  shift)
        return _call("_hs_take_row" if rows else "_hs_take", [self.visit(args[0]), i], node)

    def _batch_shape(self, e):
        """Whether ``e`` is ``v.shape[:-1]`` of a one-state vector ``v`` (a batch
        map's shape of its rows: ``()`` on one state)."""
        if not (isinstance(e, ast.Subscript) and isinstance(e.slice, ast.Slice)
                and isinstance(e.value, ast.Attribute) and e.value.attr == "shape"
                and self._one_state(e.value.value)):
            return False
        sl = e.slice
        return sl.lower is None and sl.step is None and _int_of(sl.upper) == -1

    def _shape_source(self, orig, new):
        """``e`` (rewritten) of a shape argument ``e.shape`` or ``np.shape(e)``
        (``orig`` as read, ``new`` rewritten: numpy's name is ``_hs_m_numpy``
        there), where ``e`` is not a one-state vector; else None."""
        if isinstance(orig, ast.Attribute) and orig.attr == "shape":
            e, got = orig.value, (new.value if isinstance(new, ast.Attribute)
                                  and new.attr == "shape" else None)
        elif isinstance(orig, ast.Call) and isinstance(new, ast.Call) \
                and isinstance(new.func, ast.Attribute) and new.func.attr == "shape" \
                and isinstance(new.func.value, ast.Name) \
                and new.func.value.id == "_hs_m_numpy" and len(new.args) == 1 \
                and not new.keywords:        # np.shape(e) (numpy's name, rewritten)
            e, got = orig.args[0], new.args[0]
        else:
            return None
        return None if got is None or self._one_state(e) else got

    def _builtin_dtype(self, v):
        """A rewritten dtype argument: ``float`` (``int``, ``bool``, ``complex``),
        a builtin numba does not take as a dtype, as numpy's; else ``v``."""
        if isinstance(v, ast.Name) and v.id in _DTYPES and v.id not in self.locals \
                and self._lookup(v.id)[1] == ("builtin", v.id):
            return ast.copy_location(ast.parse(f"_hs_m_numpy.{_DTYPES[v.id]}",
                                               mode="eval").body, v)
        return v

    def _dtype(self, v):
        """``dtype=float`` (a builtin type numba does not take as a dtype) as numpy's."""
        hit = self._builtin_dtype(v)
        return hit if hit is not v else self.visit(v)
