"""Guards derived from set indicators (:func:`derived_guard`,
:func:`guard_refusal`; the rules are in :mod:`hybridsim._source`'s notes).
Used by :mod:`hybridsim._source`, which re-exports the names other modules
import from it.
"""
from __future__ import annotations

import ast
import copy
import math
import types
import weakref

import numpy as np

from ._source_read import SourceRefusal, _fn_of


# ------------------------------------------------------------------ guards from sets
class _NoGuard(Exception):
    def __init__(self, node, why):
        super().__init__(why)
        self.node, self.why = node, why


def _call(name, args, like):
    return ast.copy_location(ast.Call(func=ast.Name(id=name, ctx=ast.Load()), args=args,
                                      keywords=[]), like)


def _sub(a, b, like):
    return ast.copy_location(ast.BinOp(left=a, op=ast.Sub(), right=b), like)


def _guard_expr(e):
    """The guard expression of a boolean expression ``e`` (module notes)."""
    if isinstance(e, ast.Compare):
        terms, left = [], e.left
        for op, right in zip(e.ops, e.comparators):
            if isinstance(op, (ast.Gt, ast.GtE)):
                terms.append(_sub(copy.deepcopy(left), copy.deepcopy(right), e))
            elif isinstance(op, (ast.Lt, ast.LtE)):
                terms.append(_sub(copy.deepcopy(right), copy.deepcopy(left), e))
            else:
                raise _NoGuard(e, f"the comparison {type(op).__name__} "
                                  f"({ast.unparse(e)}) has no signed distance")
            left = right
        return terms[0] if len(terms) == 1 else _call("_hs_min", terms, e)
    if isinstance(e, ast.BoolOp):
        name = "_hs_min" if isinstance(e.op, ast.And) else "_hs_max"
        return _call(name, [_guard_expr(v) for v in e.values], e)
    if isinstance(e, ast.BinOp) and isinstance(e.op, (ast.BitAnd, ast.BitOr)):
        name = "_hs_minimum" if isinstance(e.op, ast.BitAnd) else "_hs_maximum"
        return _call(name, [_guard_expr(e.left), _guard_expr(e.right)], e)
    if isinstance(e, ast.UnaryOp) and isinstance(e.op, (ast.Not, ast.Invert)):
        return ast.copy_location(ast.UnaryOp(op=ast.USub(), operand=_guard_expr(e.operand)), e)
    if isinstance(e, ast.IfExp):
        return ast.copy_location(ast.IfExp(test=e.test, body=_guard_expr(e.body),
                                           orelse=_guard_expr(e.orelse)), e)
    if isinstance(e, ast.Constant) and isinstance(e.value, bool):
        return ast.copy_location(ast.Constant(math.inf if e.value else -math.inf), e)
    raise _NoGuard(e, f"{ast.unparse(e)!r} is not a comparison, and, or, not or if/else "
                      f"of comparisons")


class _OwnReturns(ast.NodeTransformer):
    """Rewrites a function's own ``return`` statements (``visit_Return``);
    nested functions and lambdas keep theirs."""

    def visit_FunctionDef(self, node):
        return node

    visit_Lambda = visit_FunctionDef


class _Returns(_OwnReturns):
    def visit_Return(self, node):
        if node.value is None:
            raise _NoGuard(node, "a bare return")
        return ast.copy_location(ast.Return(value=_guard_expr(node.value)), node)


#: the helpers a derived guard's expression calls (bound in its closure)
_GUARD_CELLS = {"_hs_min": min, "_hs_max": max, "_hs_minimum": np.minimum,
                "_hs_maximum": np.maximum}

#: code object -> (guard node, None) or (None, (line, why)): the rewrite of a set's source
_DERIVED = {}


def _guard_node(fn):
    key = fn.func.__code__
    hit = _DERIVED.get(key)
    if hit is None:
        node = copy.deepcopy(fn.node)
        try:
            node.body = [_Returns().visit(s) for s in node.body]
            if not any(isinstance(n, ast.Return) for s in node.body for n in ast.walk(s)):
                raise _NoGuard(node, "it returns nothing")
            hit = (node, None)
        except _NoGuard as e:
            hit = (None, (fn.at(e.node), e.why))
        if len(_DERIVED) > 1024:
            _DERIVED.clear()
        _DERIVED[key] = hit
    return hit


def _as_function(fn, node, name):
    """A Python function of ``node`` in ``fn``'s globals and closure (plus the
    guard helpers), its line numbers the source's."""
    node = copy.deepcopy(node)
    node.name = name
    node.decorator_list = []
    free = sorted(set(fn.cells) | set(_GUARD_CELLS))
    outer = ast.FunctionDef(
        name="_hs_outer", args=ast.arguments(posonlyargs=[], args=[], kwonlyargs=[],
                                             kw_defaults=[], defaults=[]),
        body=[ast.Assign(targets=[ast.Name(id=v, ctx=ast.Store())],
                         value=ast.Constant(None)) for v in free]
        + [node, ast.Return(ast.Name(id=name, ctx=ast.Load()))],
        decorator_list=[], returns=None, type_comment=None)
    ast.copy_location(outer, node)
    mod = ast.fix_missing_locations(ast.Module(body=[outer], type_ignores=[]))
    code = compile(mod, fn.file, "exec")
    outer_code = next(c for c in code.co_consts if isinstance(c, types.CodeType))
    inner = next(c for c in outer_code.co_consts if isinstance(c, types.CodeType))
    cells = dict(fn.cells)
    for k, v in _GUARD_CELLS.items():
        cells.setdefault(k, types.CellType(v))
    f = types.FunctionType(inner, fn.globals, name, fn.func.__defaults__,
                           tuple(cells[v] for v in inner.co_freevars))
    f.__qualname__ = fn.qualname
    return f


#: the guard helpers in generated (numba) code
_GUARD_NAMES = {"_hs_min": "min", "_hs_max": "max", "_hs_minimum": "_hs_m_numpy.minimum",
                "_hs_maximum": "_hs_m_numpy.maximum"}

_SETS = {"jump_guard": "jump_set", "flow_guard": "flow_set"}
#: id(system) -> (weakref, {guard name: (set function, guard)})
_GUARDS = {}


def _set_fn(system, set_name):
    fn = getattr(system, set_name)
    return getattr(fn, "__func__", fn)


def derived_guard(system, name):
    """The guard ``name`` (``"jump_guard"`` or ``"flow_guard"``) derived from
    ``system``'s set indicator, or None (no set given, or one that cannot be
    turned into a guard: :func:`guard_refusal`). Cached per system and set.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> ball = hs.HybridSystem.from_functions(
    ...     f=lambda x: np.array([x[1], -9.81]), D=lambda x: x[0] <= 0 and x[1] <= 0,
    ...     state_dim=2)
    >>> ball.jump_guard(np.array([0.5, -1.0]))      # min(-x0, -x1)
    -0.5
    """
    set_name = _SETS[name]
    if not system._overrides(set_name):
        return None
    key = _set_fn(system, set_name)
    entry = _GUARDS.get(id(system))
    if entry is None or entry[0]() is not system:
        i, guards = id(system), _GUARDS
        try:
            ref = weakref.ref(system, lambda _r: guards.pop(i, None))
        except TypeError:
            ref = None
        entry = (ref, {})
        if ref is not None:
            _GUARDS[id(system)] = entry
    hit = entry[1].get(name)
    if hit is not None and hit[0] is key:
        return hit[1]
    guard = _derive(system, set_name, name)
    entry[1][name] = (key, guard)
    return guard


def _derive(system, set_name, name):
    try:
        fn = _fn_of(getattr(system, set_name), f"{type(system).__name__}.{set_name}")
    except SourceRefusal:
        return None
    node, _ = _guard_node(fn)
    if node is None:
        return None
    f = _as_function(fn, node, name)
    f.__hs_fn__ = types.SimpleNamespace(node=node, qualname=f"{fn.qualname} (its guard)")
    return types.MethodType(f, fn.obj) if fn.obj is not None else f


def guard_refusal(system, name):
    """Why no guard ``name`` is derived from ``system``'s set: ``"file:line:
    reason"``, or None where one is (or where no set is given)."""
    set_name = _SETS[name]
    if not system._overrides(set_name):
        return None
    try:
        fn = _fn_of(getattr(system, set_name), f"{type(system).__name__}.{set_name}")
    except SourceRefusal as e:
        return str(e)
    node, why = _guard_node(fn)
    return None if node is not None else f"{fn.qualname} ({why[0]}): {why[1]}"
