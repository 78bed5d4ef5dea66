"""Which names of a map hold one state on the compiled path (:func:`one_state`):
its x and u, and the locals only ever assigned a one-state array of them,
whose ``v[..., k]`` the rewrite reads as ``v[k]``. The notes are in
:mod:`hybridsim._source`.
"""
from __future__ import annotations

import ast

_FRESH_OF = ("zeros_like", "empty_like", "ones_like", "array", "copy")
_FRESH_SHAPED = ("zeros", "empty", "ones")


def _vector_expr(e, vecs, fresh=False):
    """Whether ``e`` is a one-state array (1-D) given the 1-D names ``vecs``:
    such a name, ``np.asarray(v, ...)``, ``np.zeros(v.shape)`` (``np.shape(v)``,
    ``empty``, ``ones``), ``np.zeros_like(v)``, ``np.array(v)``, ``v.copy()``;
    ``fresh``: only those that are a new array (not ``v`` or ``np.asarray(v)``)."""
    if isinstance(e, ast.Name):
        return not fresh and e.id in vecs
    if not (isinstance(e, ast.Call) and isinstance(e.func, ast.Attribute)):
        return False
    f, args = e.func, e.args
    if f.attr == "copy" and not args and not e.keywords:
        return _vector_expr(f.value, vecs)
    if not (isinstance(f.value, ast.Name) and args):
        return False
    a = args[0]
    if f.attr in _FRESH_SHAPED:
        if isinstance(a, ast.Attribute) and a.attr == "shape":
            return _vector_expr(a.value, vecs)
        return (isinstance(a, ast.Call) and isinstance(a.func, ast.Attribute)
                and a.func.attr == "shape" and len(a.args) == 1
                and _vector_expr(a.args[0], vecs))
    if f.attr in _FRESH_OF or (f.attr in ("asarray", "ascontiguousarray") and not fresh):
        if f.attr == "array" and any(k.arg == "copy" for k in e.keywords):
            return False
        return _vector_expr(a, vecs)
    return False


def _stores(node):
    """``{name: [value or None]}``: what each name of ``node`` is assigned (None:
    a store that is not ``name = value`` or ``name op= value``)."""
    direct = {}
    for n in ast.walk(node):
        if isinstance(n, ast.Assign):
            for t in n.targets:
                if isinstance(t, ast.Name):
                    direct[id(t)] = n.value
        elif isinstance(n, ast.AugAssign) and isinstance(n.target, ast.Name):
            direct[id(n.target)] = n.target           # v op= w keeps v's shape
    out = {}
    for n in ast.walk(node):
        if isinstance(n, ast.Name) and isinstance(n.ctx, (ast.Store, ast.Del)):
            out.setdefault(n.id, []).append(direct.get(id(n)))
    return out


def vector_names(node, names):
    """The names of ``node`` that hold one state (1-D) on the compiled path:
    ``names`` (its x and u) and the locals only ever assigned a one-state
    array of them (:func:`_vector_expr`); and those of them only ever
    assigned a new array (their writes alias nothing the map reads)."""
    stores = _stores(node)
    vecs = set(names) | {k for k, vs in stores.items() if vs and None not in vs}
    while True:
        keep = {v for v in vecs if all(e is not None and _vector_expr(e, vecs)
                                       for e in stores.get(v, ()))}
        if keep == vecs:
            break
        vecs = keep
    fresh = {v for v in vecs if v not in names and stores.get(v) and all(
        (isinstance(e, ast.Name) and e.id == v) or _vector_expr(e, vecs, fresh=True)
        for e in stores[v])}
    return vecs, fresh


class _OneState(ast.NodeTransformer):
    """``v[..., k]`` of a one-state array ``v`` read as ``v[k]`` (a number where k
    is one: no 0-d array)."""

    def __init__(self, vecs):
        self.vecs = vecs

    def visit_Subscript(self, node):
        node = self.generic_visit(node)
        sl = node.slice
        if isinstance(node.value, ast.Name) and node.value.id in self.vecs \
                and isinstance(sl, ast.Tuple) and len(sl.elts) == 2 \
                and isinstance(sl.elts[0], ast.Constant) and sl.elts[0].value is Ellipsis:
            k = sl.elts[1]
            if not (isinstance(k, ast.Constant) and k.value in (None, Ellipsis)):
                node.slice = k
        return node


def one_state(node, names):
    """``node`` (a map's FunctionDef on the compiled path, its state and input
    ``names``) with ``v[..., k]`` read as ``v[k]`` for its one-state arrays;
    their names and the fresh ones among them (:func:`vector_names`)."""
    vecs, fresh = vector_names(node, names)
    node.body = [_OneState(vecs).visit(st) for st in node.body]
    return vecs, fresh
