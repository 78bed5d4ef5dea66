"""A parameter slot of a rewritten map as an expression (:func:`_slot_expr`),
and a slot's array read at constant indices as one number in place
(:func:`_slot_item`); the notes are in :mod:`hybridsim._source`.
"""
from __future__ import annotations

import ast

P = "_hs_p"          # the parameter array of generated functions


def _slot_expr(slot, like):
    _, kind, shape, off, size = slot
    pv = ast.Name(id=P, ctx=ast.Load())
    if not shape and kind != "farray" and kind != "iarray":
        e = ast.Subscript(value=pv, slice=ast.Constant(off), ctx=ast.Load())
        if kind == "int":
            e = ast.Call(func=ast.Name(id="int", ctx=ast.Load()), args=[e], keywords=[])
        elif kind == "bool":
            e = ast.Compare(left=e, ops=[ast.NotEq()], comparators=[ast.Constant(0.0)])
    else:
        if not shape:
            e = ast.Subscript(value=pv, slice=ast.Constant(off), ctx=ast.Load())
        else:
            e = ast.parse(f"{P}[{off}:{off + size}]", mode="eval").body
            if len(shape) > 1:
                e = ast.parse(f"{P}[{off}:{off + size}].reshape({tuple(shape)!r})",
                              mode="eval").body
            if kind == "iarray":
                e = ast.Call(func=ast.Attribute(value=e, attr="astype", ctx=ast.Load()),
                             args=[ast.Name(id="_hs_m_numpy.int64", ctx=ast.Load())],
                             keywords=[])
    return ast.fix_missing_locations(ast.copy_location(e, like))


def _slot_item(node):
    """``p[a:b].reshape(shape)[i, j]`` (an array's slot read at constant
    indices) as ``p[a + flat index]``, a number read in place; else ``node``."""
    if not isinstance(node.ctx, ast.Load):
        return node
    idx = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
    if not all(isinstance(i, ast.Constant) and type(i.value) is int for i in idx):
        return node
    v, shape = node.value, None
    if isinstance(v, ast.Call) and isinstance(v.func, ast.Attribute) \
            and v.func.attr == "reshape" and len(v.args) == 1 and not v.keywords \
            and isinstance(v.args[0], ast.Tuple) \
            and all(isinstance(n, ast.Constant) and type(n.value) is int
                    for n in v.args[0].elts):
        v, shape = v.func.value, tuple(n.value for n in v.args[0].elts)
    if not (isinstance(v, ast.Subscript) and isinstance(v.value, ast.Name)
            and v.value.id == P and isinstance(v.slice, ast.Slice)
            and v.slice.step is None and all(isinstance(b, ast.Constant)
                                             and type(b.value) is int
                                             for b in (v.slice.lower, v.slice.upper))):
        return node
    a, b = v.slice.lower.value, v.slice.upper.value
    shape = shape if shape is not None else (b - a,)
    if len(shape) != len(idx) or not all(0 <= i.value < n for i, n in zip(idx, shape)):
        return node
    flat = 0
    for i, n in zip(idx, shape):
        flat = flat * n + i.value
    return ast.copy_location(ast.Subscript(value=ast.Name(id=P, ctx=ast.Load()),
                                           slice=ast.Constant(a + flat), ctx=ast.Load()), node)
