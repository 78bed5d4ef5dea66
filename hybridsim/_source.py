"""The user's maps as source: read, checked and rewritten with :mod:`ast`.

Two transformations share this module's reading of a map's source (the
function's own node in its file, so every message names the file and line):

* **Guards from sets** (:func:`derived_guard`). A set indicator built from
  comparisons with ``and``, ``or``, ``not``, ``&``, ``|``, ``~`` and
  ``if``/``else`` expressions gives a signed guard: ``a >= b`` and ``a > b``
  give ``a - b``, ``a <= b`` and ``a < b`` give ``b - a``, a chain the
  smallest of its links, ``and`` (``&``) the smallest, ``or`` (``|``) the
  largest, ``not`` (``~``) the negation, ``A if c else B`` the guard of the
  branch taken. Boundary convention: ``{guard >= 0}`` is the set with its
  boundary; the guard is positive only inside the set and negative only
  outside it, and zero on the boundary, where the set's own indicator
  decides (the engine's rule 6: the indicator decides membership, the guard
  locates the crossing). A set of anything else (``==``, a call, a bool
  variable) has no derived guard (:func:`guard_refusal` says why) and runs
  as today, by bisection of its indicator.
* **Maps of (x, t, j, p)** (:func:`plan`). The maps of a plain
  :class:`hybridsim.HybridSystem` (methods, or the functions of
  :meth:`~hybridsim.HybridSystem.from_functions`) rewritten as functions of
  ``(x, t, j, p)`` that numba compiles: every number and array a map reads
  from ``self``, from a closure, from a default argument or from a module
  global becomes a slot of ``p`` (:class:`Layout`, read again before every
  run: changing ``ball.e`` changes the next run), ``self.helper(...)`` and
  calls of plain functions are followed (rewritten the same way), modules
  are imported by name. Parts of the system are read through: ``self.design.F1``,
  ``d = self.design`` then ``d.F1``, ``self.data.flow(...)`` (a method of a
  part, followed); another object in its place rewrites the maps. A bool or
  str attribute is a constant of the rewrite (``self.mode == "pwc"`` decides
  its branch, the other is dropped), and ``self.slices["x"]`` (a dict read by
  a constant key) its value (a slice as ``a:b``); a change rewrites the maps.
  ``self.a is None`` (``is not None``) is known when
  the maps are rewritten: the test becomes a constant and the branch not
  taken is dropped (the plan is made again where it changes). A product
  ``a @ b`` compiles as loops summing in index order (``_hs_matmul``), and
  one with a matrix the map reads from ``self`` (``self.M @ v``, ``v @
  self.M.T``, ``y += v @ self.M.T``) reads it in place from ``p``
  (:func:`hybridsim.compiled.matvec`; ``self.M @ X`` of a matrix X is M X).
  For a part of an interconnection (``plan(system, component=True)``) the
  maps take ``(x, u, t, j, p)``
  and its output ``(x, t, j, p)``. What cannot be rewritten is refused by a
  :class:`SourceRefusal` naming the method and its line: ``self`` passed or
  written, global state, random draws, an object numba cannot type.

A flow map reading its past as ``self.history(t - tau)`` (the lags declared
in ``self.delays``) reads it from the past the compiled kernel writes after
the parameters (:func:`_past_call`); ``plan(...).reads_past`` says so.

Reading source (rather than tracing calls) keeps every branch of a map,
whatever state a trial call would take, and sees every read of ``self``.
Nothing here needs numba (:mod:`hybridsim.compiled._from_source` compiles
the plan).
"""
from __future__ import annotations

import ast
import builtins
import copy
import hashlib
import inspect
import linecache
import math
import types
import weakref

import numpy as np

_LEADING = ("t", "j", "u")


def _arity(fn) -> int:
    """How many of ``(x, t, j, u)`` ``fn`` takes (4 for ``*args``).

    Read from the *required* positional parameters, so a defaulted parameter
    (``lambda x, k=2.0: -k * x``, a common way to capture a loop variable)
    never receives t. A defaulted parameter still counts when it is named as
    the engine's argument at its position (``def f(self, x, t, j, u=None)``).
    Builtins and numpy ufuncs (no signature, or ``out=`` defaulted) take x.
    """
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):  # builtins, numpy ufuncs
        return 1
    if isinstance(fn, np.ufunc):
        return 1
    n = 0
    for p in sig.parameters.values():
        if p.kind == p.VAR_POSITIONAL:
            return 4
        if p.kind not in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD):
            break
        if p.default is not p.empty and not (1 <= n <= 3 and p.name == _LEADING[n - 1]):
            break
        n += 1
    return n


__all__ = ["SourceRefusal", "derived_guard", "guard_refusal", "plan", "Layout"]

P = "_hs_p"          # the parameter array of generated functions
_RESERVED = "_hs_"


class SourceRefusal(TypeError):
    """A map that cannot be rewritten: ``method`` (its qualified name),
    ``line`` (file:line) and ``why``."""

    def __init__(self, method, line, why):
        super().__init__(f"{method} ({line}): {why}")
        self.method, self.line, self.why = method, line, why


# ------------------------------------------------------------------ reading source
_TREES = {}


def _tree(file, func):
    lines = linecache.getlines(file, func.__globals__)
    if not lines:
        return None
    text = "".join(lines)
    key = (file, hashlib.sha1(text.encode()).hexdigest())
    t = _TREES.get(key)
    if t is None:
        try:
            t = ast.parse(text, file)
        except SyntaxError:
            return None
        if len(_TREES) > 64:
            _TREES.clear()
        _TREES[key] = t
    return t


def _names_in(node, args):
    out = set()
    for n in ast.walk(node):
        if isinstance(n, ast.Name) and n.id not in args:
            out.add(n.id)
        elif isinstance(n, ast.Attribute):
            out.add(n.attr)
    return out


def _consts(code):
    return tuple(repr(c) for c in code.co_consts if not isinstance(c, types.CodeType))


def _same_code(lam, code):
    """Whether the lambda node compiles to ``code`` (its constants, and its
    bytecode where it has no closure)."""
    try:
        mod = compile(ast.fix_missing_locations(ast.Expression(body=copy.deepcopy(lam))),
                      code.co_filename, "eval")
    except (SyntaxError, ValueError):
        return False
    mine = next((c for c in mod.co_consts if isinstance(c, types.CodeType)), None)
    if mine is None or _consts(mine) != _consts(code):
        return False
    return bool(code.co_freevars) or mine.co_code == code.co_code


#: code object -> its FunctionDef (a copy is handed out): a file's tree is walked once
#: per function, not once per system
_NODES = {}


def _node_of(func, qualname):
    """The FunctionDef of ``func`` in its file (a lambda as one)."""
    code = func.__code__
    hit = _NODES.get(code)
    if hit is not None and hit[0] == _file_key(code.co_filename, func):
        return copy.deepcopy(hit[1])
    node = _find_node(func, qualname)
    if len(_NODES) > 4096:
        _NODES.clear()
    _NODES[code] = (_file_key(code.co_filename, func), node)
    return copy.deepcopy(node)


def _file_key(file, func):
    lines = linecache.getlines(file, func.__globals__)
    return (len(lines), hash(tuple(lines))) if lines else None


def _find_node(func, qualname):
    code = func.__code__
    tree = _tree(code.co_filename, func)
    where = f"{code.co_filename}:{code.co_firstlineno}"
    if tree is None:
        raise SourceRefusal(qualname, where, "its source is not available (defined "
                            "interactively or by exec); define it in a file")
    cands = []
    for n in ast.walk(tree):
        if code.co_name == "<lambda>" and isinstance(n, ast.Lambda) \
                and n.lineno == code.co_firstlineno:
            cands.append(n)
        elif isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.name == code.co_name:
            first = n.decorator_list[0].lineno if n.decorator_list else n.lineno
            if first == code.co_firstlineno:
                cands.append(n)
    if len(cands) > 1 and code.co_name == "<lambda>":
        args = set(code.co_varnames[:code.co_argcount])
        want = set(code.co_names) | set(code.co_freevars)
        cands = [c for c in cands if {a.arg for a in c.args.args} == args
                 and _names_in(c.body, args) == want] or cands
        if len(cands) > 1:
            cands = [c for c in cands if _same_code(c, code)] or cands
        if len({ast.dump(c) for c in cands}) > 1:
            raise SourceRefusal(qualname, where, "several lambdas on one line: its source "
                                "cannot be told apart; put it on a line of its own")
    if not cands:
        raise SourceRefusal(qualname, where, "its source was not found in its file")
    n = cands[0]
    if isinstance(n, ast.AsyncFunctionDef):
        raise SourceRefusal(qualname, where, "an async function")
    if isinstance(n, ast.Lambda):
        fd = ast.FunctionDef(name="_lambda", args=n.args, body=[ast.Return(n.body)],
                             decorator_list=[], returns=None, type_comment=None)
        ast.copy_location(fd, n)
        ast.copy_location(fd.body[0], n.body)
        n = fd
    return copy.deepcopy(n)


class Fn:
    """One function's source and context: its node, globals, closure cells,
    the object bound to its first parameter (``obj``, a method's self)."""

    def __init__(self, func, obj, qualname, node=None):
        self.func, self.obj, self.qualname = func, obj, qualname
        code = func.__code__
        self.file = code.co_filename
        self.globals = func.__globals__
        self.cells = dict(zip(code.co_freevars, func.__closure__ or ()))
        self.node = node if node is not None else _node_of(func, qualname)
        a = self.node.args
        if a.vararg or a.kwarg or a.kwonlyargs:
            raise SourceRefusal(qualname, self.at(self.node),
                                "takes *args, **kwargs or keyword-only arguments")
        self.params = [p.arg for p in a.posonlyargs + a.args]
        self.self_name = self.params[0] if obj is not None and self.params else None
        defaults = func.__defaults__ or ()
        self.defaults = dict(zip(self.params[len(self.params) - len(defaults):], defaults))

    def at(self, node):
        return f"{self.file}:{getattr(node, 'lineno', self.node.lineno)}"

    def refuse(self, node, why):
        return SourceRefusal(self.qualname, self.at(node), why)


def _unwrap(fn, qualname):
    """``(function, bound object)`` of a map (a function, lambda or bound method)."""
    if isinstance(fn, types.MethodType):
        return fn.__func__, fn.__self__
    if isinstance(fn, types.FunctionType):
        return fn, None
    raise SourceRefusal(qualname, "?", f"it is a {type(fn).__name__}, not a function or "
                        f"method (its source cannot be read)")


def _fn_of(fn, qualname):
    func, obj = _unwrap(fn, qualname)
    hit = getattr(func, "__hs_fn__", None)      # a derived guard: its source is its node
    if hit is not None:
        return Fn(func, obj, hit.qualname, copy.deepcopy(hit.node))
    return Fn(func, obj, qualname)


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


# ------------------------------------------------------------------ maps of (x, t, j, p)
_NUMBA_MODULES = ("numpy", "math", "cmath")
_RANDOM_MODULES = ("random", "numpy.random", "secrets")


def _kind(v):
    """``(kind, shape)`` of a value a map may read as a parameter, or None."""
    if isinstance(v, (bool, np.bool_)):
        return ("bool", ())
    if isinstance(v, (int, np.integer)):
        return ("int", ())
    if isinstance(v, (float, np.floating)):
        return ("float", ())
    if isinstance(v, np.ndarray):
        if v.dtype.kind in "f":
            return ("farray", v.shape)
        if v.dtype.kind in "iub":
            return ("iarray", v.shape)
        return None
    if isinstance(v, (list, tuple)) and v and all(
            isinstance(e, (int, float, np.integer, np.floating)) and not isinstance(e, bool)
            for e in v):
        return ("farray", (len(v),))
    return None


class Layout:
    """The named slots of ``p``: ``slots`` a list of ``(name, kind, shape,
    offset, size)``, ``size`` their total. :meth:`read` reads every value
    again (a system's attributes, a closure's numbers, module globals)."""

    def __init__(self):
        self.slots, self.readers, self.size, self._index = [], [], 0, {}
        self.checks = {}            # key -> (reader, whether the value was None)
        self.parts = {}             # key -> (reader, the part of the system followed)
        self.folded = {}            # key -> (reader, the bool or str written as a constant)

    def require(self, key, reader, is_none):
        """Record that the rewrite folded ``reader() is None`` to ``is_none``
        (a branch taken): :meth:`read` asks for a rewrite where it changes."""
        self.checks.setdefault(key, (reader, is_none))

    def same(self, key, reader, obj):
        """Record that the rewrite followed ``reader()``, the part ``obj`` of the
        system (``self.design``): :meth:`read` asks for a rewrite where it is
        another object."""
        self.parts.setdefault(key, (reader, obj))

    def fold(self, key, reader, value):
        """Record that the rewrite wrote ``reader()`` (a bool or a str) as the
        constant ``value``: :meth:`read` asks for a rewrite where it changes."""
        self.folded.setdefault(key, (reader, value))

    def _unchanged(self):
        try:
            return all(rd() is obj for rd, obj in self.parts.values()) and all(
                type(rd()) is type(v) and rd() == v for rd, v in self.folded.values())
        except Exception:  # noqa: BLE001 - an attribute deleted since: rewrite
            return False

    def add(self, key, name, value, reader):
        hit = self._index.get(key)
        if hit is not None:
            return self.slots[hit]
        kind, shape = _kind(value)
        size = int(np.prod(shape)) if shape else 1
        slot = (name, kind, shape, self.size, size)
        self._index[key] = len(self.slots)
        self.slots.append(slot)
        self.readers.append(reader)
        self.size += size
        return slot

    def read(self):
        """``p`` now, or None where a value changed kind or shape (the maps must
        be rewritten)."""
        for rd, is_none in self.checks.values():
            try:
                if (rd() is None) != is_none:
                    return None
            except Exception:  # noqa: BLE001 - an attribute deleted since: rewrite
                return None
        if (self.parts or self.folded) and not self._unchanged():
            return None
        p = np.empty(self.size)
        for (_, kind, shape, off, size), rd in zip(self.slots, self.readers):
            try:
                v = rd()
            except Exception:  # noqa: BLE001 - an attribute deleted since: rewrite
                return None
            k = _kind(v)
            if k is None or k != (kind, shape):
                return None
            if size == 1 and not shape:
                p[off] = float(v)
            else:
                p[off:off + size] = np.asarray(v, dtype=np.float64).reshape(-1)
        return p

    def names(self):
        """``{name: (offset, shape)}`` (for reading ``p`` by name)."""
        return {s[0]: (s[3], s[2]) for s in self.slots}


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


def _locals(node):
    out = {a.arg for a in node.args.posonlyargs + node.args.args}
    for n in ast.walk(node):
        if isinstance(n, ast.Name) and isinstance(n.ctx, (ast.Store, ast.Del)):
            out.add(n.id)
        elif isinstance(n, ast.arg):
            out.add(n.arg)
    return out


class _Unresolved:
    pass


_MISSING = _Unresolved()


_DTYPES = {"float": "float64", "int": "int64", "bool": "bool_", "complex": "complex128"}


def _known(t):
    """The truth of a test the rewrite folded (constants, not, and, or), or None."""
    if isinstance(t, ast.Constant) and isinstance(t.value, bool):
        return t.value
    if isinstance(t, ast.UnaryOp) and isinstance(t.op, ast.Not):
        v = _known(t.operand)
        return None if v is None else not v
    if isinstance(t, ast.BoolOp):
        vs = [_known(v) for v in t.values]
        stop = isinstance(t.op, ast.Or)             # or: a True decides; and: a False
        if stop in vs:
            return stop
        return None if None in vs else not stop
    return None


def _is_part(v, tables=False):
    """Whether ``v`` is a part of a system the rewrite reads through (an
    instance of a Python class: not a number, array, string, module, function
    or container; ``tables``: or a dict of str keys, read by constant keys)."""
    if tables and isinstance(v, dict) and all(isinstance(k, str) for k in v):
        return True
    return (v is not _MISSING and v is not None and hasattr(v, "__dict__")
            and not isinstance(v, (type, types.ModuleType, types.FunctionType,
                                   types.MethodType, np.ndarray, np.generic))
            and _kind(v) is None)


def _as_slice(e):
    """An index with ``slice(a, b, c)`` of constants written ``a:b:c``."""
    if isinstance(e, ast.Tuple):
        e.elts = [_as_slice(v) for v in e.elts]
        return e
    if isinstance(e, ast.Call) and isinstance(e.func, ast.Name) and e.func.id == "slice" \
            and len(e.args) == 3 and not e.keywords \
            and all(isinstance(a, ast.Constant) for a in e.args):
        return ast.copy_location(ast.Slice(*(None if a.value is None else a
                                             for a in e.args)), e)
    return e


def _dotted(node):
    return ast.unparse(node)


def _chain_value(fn, e):
    """The value of ``self.a.b`` (an attribute chain from ``self``), or _MISSING."""
    chain = []
    while isinstance(e, ast.Attribute):
        chain.append(e.attr)
        e = e.value
    if not (chain and isinstance(e, ast.Name) and e.id == fn.self_name):
        return _MISSING
    v = fn.obj
    for a in reversed(chain):
        v = getattr(v, a, _MISSING)
        if v is _MISSING:
            break
    return v


class _Alias(ast.NodeTransformer):
    def __init__(self, names):
        self.names = names

    def visit_Name(self, node):
        e = self.names.get(node.id)
        if e is None or not isinstance(node.ctx, ast.Load):
            return node
        return ast.fix_missing_locations(ast.copy_location(copy.deepcopy(e), node))


def _inline_parts(fn, node):
    """``d = self.design`` (a name given once, at the top of the body, a part
    of the system) read as ``self.design`` wherever ``d`` is read: numba
    cannot hold the part, the rewrite reads through it."""
    if fn.self_name is None:
        return
    stores = {}
    for n in ast.walk(node):
        if isinstance(n, ast.Name) and isinstance(n.ctx, (ast.Store, ast.Del)):
            stores[n.id] = stores.get(n.id, 0) + 1
    names, body = {}, []
    for st in node.body:
        if isinstance(st, ast.Assign) and len(st.targets) == 1:
            t, v = st.targets[0], st.value
            pairs = (list(zip(t.elts, v.elts)) if isinstance(t, ast.Tuple)
                     and isinstance(v, ast.Tuple) and len(t.elts) == len(v.elts)
                     else [(t, v)])
            keep = []
            for a, b in pairs:
                if isinstance(a, ast.Name) and stores.get(a.id) == 1 \
                        and _is_part(_chain_value(fn, b), tables=True):
                    names[a.id] = _Alias(names).visit(copy.deepcopy(b))
                else:
                    keep.append((a, b))
            if not keep:
                continue
            if len(keep) < len(pairs):
                st = ast.copy_location(ast.Assign(
                    targets=[ast.copy_location(ast.Tuple(elts=[a for a, _ in keep],
                                                         ctx=ast.Store()), t)],
                    value=ast.copy_location(ast.Tuple(elts=[b for _, b in keep],
                                                      ctx=ast.Load()), v)), st)
        body.append(st)
    if names:
        node.body = [_Alias(names).visit(st) for st in body]


_COMPARE = {ast.Eq: lambda a, b: a == b, ast.NotEq: lambda a, b: a != b,
            ast.In: lambda a, b: a in b, ast.NotIn: lambda a, b: a not in b}


def _folded_compare(node):
    """A comparison of constants (``"pwc" == "pwc"``, after a str attribute was
    written as its value) as its truth; anything else as it is."""
    if not isinstance(node, ast.Compare):
        return node
    vals = [node.left, *node.comparators]
    consts = []
    for v in vals:
        if isinstance(v, ast.Constant) and isinstance(v.value, (str, bool, int, float)):
            consts.append(v.value)
        elif isinstance(v, (ast.Tuple, ast.List)) and all(
                isinstance(e, ast.Constant) for e in v.elts):
            consts.append(tuple(e.value for e in v.elts))
        else:
            return node
    if not any(isinstance(c, str) for c in consts):
        return node
    for op, a, b in zip(node.ops, consts, consts[1:]):
        f = _COMPARE.get(type(op))
        if f is None:
            return node
        if not f(a, b):
            return ast.copy_location(ast.Constant(False), node)
    return ast.copy_location(ast.Constant(True), node)


class _Rewrite(ast.NodeTransformer):
    """One function's body, rewritten for the plan (module notes)."""

    def __init__(self, planner, fn):
        self.pl, self.fn = planner, fn
        self.locals = _locals(fn.node)
        for v in self.locals:
            if v.startswith(_RESERVED):
                raise fn.refuse(fn.node, f"the name {v!r} is reserved for hybridsim")

    # -- what a name is
    def _lookup(self, name):
        fn = self.fn
        if name in fn.cells:
            cell = fn.cells[name]
            try:
                return cell.cell_contents, ("cell", id(cell)), lambda c=cell: c.cell_contents
            except ValueError:
                return _MISSING, None, None
        if name in fn.globals:
            g = fn.globals
            return g[name], ("global", id(g), name), lambda g=g, n=name: g[n]
        if hasattr(builtins, name):
            return getattr(builtins, name), ("builtin", name), None
        return _MISSING, None, None

    def _module_of(self, node):
        """The module an attribute chain ``a.b.c`` starting at a module names, or None."""
        if isinstance(node, ast.Name) and node.id not in self.locals:
            v = self._lookup(node.id)[0]
            return v if isinstance(v, types.ModuleType) else None
        if isinstance(node, ast.Attribute):
            m = self._module_of(node.value)
            v = getattr(m, node.attr, None) if m is not None else None
            return v if isinstance(v, types.ModuleType) else None
        return None

    def _check_random(self, node):
        m = self._module_of(node)
        if m is not None and m.__name__ in _RANDOM_MODULES:
            raise self.fn.refuse(node, f"it draws random numbers ({ast.unparse(node)}): the "
                                       f"draws would differ between the paths; put the "
                                       f"noise in the state or the parameters")
        base = node
        while isinstance(base, ast.Attribute):
            base = base.value
            mm = self._module_of(base)
            if mm is not None and mm.__name__ in _RANDOM_MODULES:
                raise self.fn.refuse(node, f"it draws random numbers ({ast.unparse(node)}): "
                                           f"the draws would differ between the paths; put "
                                           f"the noise in the state or the parameters")

    # -- parts of self: self.design.F1, self.data.flow(...)
    def _owner(self, node):
        """``(object, attr)`` of ``self.attr`` or of ``self.a.b.attr`` read through
        parts of the system (plain objects it holds, each recorded so that
        another object there rewrites the maps), or None."""
        fn = self.fn
        if fn.self_name is None or not isinstance(node, ast.Attribute):
            return None
        chain, base = [], node.value
        while isinstance(base, ast.Attribute):
            chain.append(base.attr)
            base = base.value
        if not (isinstance(base, ast.Name) and base.id == fn.self_name):
            return None
        obj = fn.obj
        for a in reversed(chain):
            v = getattr(obj, a, _MISSING)
            if not _is_part(v):
                return None
            self.pl.layout.same(("part", id(obj), a), lambda o=obj, n=a: getattr(o, n), v)
            self.pl.prefix.setdefault(id(v), f"{self.pl.prefix.get(id(obj), '')}{a}.")
            obj = v
        return obj, node.attr

    def _name(self, obj, attr):
        """A slot's name: its path from the system (``design.F1``)."""
        return self.pl.prefix.get(id(obj), "") + attr

    def visit_Subscript(self, node):
        """``self.slices["xh1"]`` (a dict of the system read by a constant key):
        its value, a slice of ints written as a constant slice, a number or
        array read as a slot of ``p``."""
        v = node.value
        hit = self._owner(v) if isinstance(node.ctx, ast.Load) else None
        key = node.slice
        table = getattr(hit[0], hit[1], None) if hit is not None else None
        if not (isinstance(table, dict) and isinstance(key, ast.Constant)
                and isinstance(key.value, str) and key.value in table):
            node = self.generic_visit(node)
            node.slice = _as_slice(node.slice)
            return node
        obj, attr = hit
        k = key.value
        e = table[k]

        def reader(o=obj, a=attr, k=k):
            return getattr(o, a)[k]
        name = f"{self._name(obj, attr)}[{k!r}]"
        if isinstance(e, slice) and all(b is None or isinstance(b, int)
                                        for b in (e.start, e.stop, e.step)):
            self.pl.layout.fold(("item", id(obj), attr, k), reader, e)
            return ast.copy_location(_call("slice", [ast.Constant(b) for b in
                                                     (e.start, e.stop, e.step)], node), node)
        if isinstance(e, (bool, str)):
            self.pl.layout.fold(("item", id(obj), attr, k), reader, e)
            return ast.copy_location(ast.Constant(e), node)
        if _kind(e) is None:
            raise self.fn.refuse(node, f"it reads {name}, a {type(e).__name__}: numba "
                                       f"cannot type it")
        return _slot_expr(self.pl.layout.add(("item", id(obj), attr, k), name, e, reader), node)

    # -- statements that are refused
    def visit_Global(self, node):
        raise self.fn.refuse(node, f"it declares global {', '.join(node.names)}: a map with "
                                   f"global state would differ between the paths")

    def visit_Nonlocal(self, node):
        raise self.fn.refuse(node, f"it declares nonlocal {', '.join(node.names)}: a map "
                                   f"with state of its own would differ between the paths")

    def _check_store(self, target):
        base = target
        while isinstance(base, (ast.Subscript, ast.Attribute)):
            if isinstance(base, ast.Attribute) and isinstance(base.value, ast.Name) \
                    and base.value.id == self.fn.self_name:
                raise self.fn.refuse(target, f"it writes {ast.unparse(target)}: a map that "
                                             f"changes the system's state would differ "
                                             f"between the paths")
            base = base.value
        if isinstance(base, ast.Name) and base.id not in self.locals \
                and target is not base:
            raise self.fn.refuse(target, f"it writes into {base.id!r}, which is not its own "
                                         f"(global or closure state)")

    def visit_Assign(self, node):
        for t in node.targets:
            for e in (t.elts if isinstance(t, (ast.Tuple, ast.List)) else [t]):
                self._check_store(e)
        return self.generic_visit(node)

    def visit_AugAssign(self, node):
        self._check_store(node.target)
        v = node.value
        if isinstance(node.op, ast.Add) and isinstance(node.target, ast.Name) and \
                isinstance(v, ast.BinOp) and isinstance(v.op, ast.MatMult):
            hit = self._product(v)
            if hit is not None:                 # y += M @ v: accumulated in y
                target = ast.Name(id=node.target.id, ctx=ast.Load())
                call = self._pmv(*hit, v, target)
                return ast.copy_location(ast.Expr(value=call), node)
        return self.generic_visit(node)

    def visit_AnnAssign(self, node):
        self._check_store(node.target)
        return self.generic_visit(node)

    # -- structure: `self.a is None` is known when the maps are rewritten
    def visit_Compare(self, node):
        fn = self.fn
        if len(node.ops) == 1 and isinstance(node.ops[0], (ast.Is, ast.IsNot)):
            a, b = node.left, node.comparators[0]
            if isinstance(a, ast.Constant) and a.value is None:
                a, b = b, a
            hit = self._owner(a) if isinstance(b, ast.Constant) and b.value is None else None
            if hit is not None:
                obj, attr = hit
                try:
                    v = getattr(obj, attr)
                except AttributeError:
                    raise fn.refuse(a, f"{_dotted(a)} does not exist") from None
                self.pl.layout.require(("none", id(obj), attr),
                                       lambda o=obj, n=attr: getattr(o, n), v is None)
                known = (v is None) == isinstance(node.ops[0], ast.Is)
                return ast.copy_location(ast.Constant(known), node)
        node = self.generic_visit(node)
        return _folded_compare(node)

    def _test(self, test):
        """The visited test and its value where the rewrite knows it (else None)."""
        t = self.visit(test)
        return t, _known(t)

    def stmts(self, body):
        """The statements of ``body`` visited (a pruned ``if`` gives its branch's;
        what follows a return is never run, and never read)."""
        out = []
        for st in body:
            v = self.visit(st)
            out.extend(v if isinstance(v, list) else [v])
            if out and isinstance(out[-1], (ast.Return, ast.Raise)):
                break
        return out

    def visit_If(self, node):
        test, known = self._test(node.test)
        if known is None:
            node.test = test
            node.body = self.stmts(node.body) or [ast.copy_location(ast.Pass(), node)]
            node.orelse = self.stmts(node.orelse)
            return node
        taken = node.body if known else node.orelse      # the other branch is never read
        return self.stmts(taken) or [ast.copy_location(ast.Pass(), node)]

    def visit_IfExp(self, node):
        test, known = self._test(node.test)
        if known is None:
            node.test = test
            node.body, node.orelse = self.visit(node.body), self.visit(node.orelse)
            return node
        return self.visit(node.body if known else node.orelse)

    def _matrix_slot(self, e):
        """The slot of ``self.M`` (a 2-D array of floats), or None."""
        hit = self._owner(e)
        if hit is None:
            return None
        obj, attr = hit
        v = getattr(obj, attr, None)
        if not (isinstance(v, np.ndarray) and v.ndim == 2 and v.dtype.kind == "f"):
            return None
        self.visit(e)                           # its slot (and checks)
        return self.pl.layout.add(("self", id(obj), attr), self._name(obj, attr), v,
                                  lambda o=obj, a=attr: getattr(o, a))

    def _product(self, node):
        """A product with a matrix of ``self`` as ``(slot, v, side)``: ``v @
        self.M.T`` (side ``"_hs_pmv"``: Mᵀ on the right) or ``self.M @ v``
        (``"_hs_mpv"``: M on the left; the same for a vector v), or None."""
        left, right = node.left, node.right
        if isinstance(right, ast.Attribute) and right.attr == "T":
            slot = self._matrix_slot(right.value)
            if slot is not None:
                return slot, left, "_hs_pmv"
        slot = self._matrix_slot(left)
        if slot is not None:
            return slot, right, "_hs_mpv"
        return None

    def _pmv(self, slot, v, side, like, *extra):
        _, _, (r, c), off, _ = slot
        args = [ast.Name(id=P, ctx=ast.Load()), ast.Constant(off), ast.Constant(r),
                ast.Constant(c), self.visit(v), *extra]
        return _call(side + ("_add" if extra else ""), args, like)

    def visit_BinOp(self, node):
        if isinstance(node.op, ast.MatMult):     # small products as loops, in index order
            hit = self._product(node)
            if hit is not None:                 # a matrix of p read in place
                return self._pmv(*hit, node)
            return _call("_hs_matmul", [self.visit(node.left), self.visit(node.right)], node)
        return self.generic_visit(node)

    # -- reads
    def visit_Attribute(self, node):
        hit = self._owner(node) if isinstance(node.ctx, ast.Load) else None
        if hit is not None:
            return self._self_attr(node, *hit)
        self._check_random(node)
        m = self._module_of(node)
        if m is not None:
            return self._module_name(m, node)
        return self.generic_visit(node)

    def _self_attr(self, node, obj, attr):
        fn, name = self.fn, _dotted(node)
        static = inspect.getattr_static(obj, attr, _MISSING)
        if isinstance(static, (types.FunctionType, staticmethod, classmethod)) or \
                inspect.ismethod(getattr(obj, attr, None)):
            raise fn.refuse(node, f"it reads the method {name} without calling it")
        if attr in ("history",):
            raise fn.refuse(node, "it uses self.history other than to call it at t - tau "
                                  "(a delay of self.delays): self.history(t - tau)")
        try:
            v = getattr(obj, attr)
        except AttributeError:
            raise fn.refuse(node, f"{name} does not exist") from None
        if isinstance(v, (bool, np.bool_, str)):        # a flag or a choice: a constant
            self.pl.layout.fold(("self", id(obj), attr), lambda o=obj, a=attr: getattr(o, a),
                                v)
            return ast.copy_location(ast.Constant(v if isinstance(v, str) else bool(v)), node)
        if _kind(v) is None:
            raise fn.refuse(node, f"it reads {name}, a {type(v).__name__} (not a number "
                                  f"or an array of numbers): numba cannot type it")
        slot = self.pl.layout.add(("self", id(obj), attr), self._name(obj, attr), v,
                                  lambda o=obj, a=attr: getattr(o, a))
        return _slot_expr(slot, node)

    def _module_name(self, m, node):
        top = m.__name__.split(".")[0]
        if top not in _NUMBA_MODULES:
            raise self.fn.refuse(node, f"it uses the module {m.__name__}, which numba cannot "
                                       f"compile")
        return ast.copy_location(ast.Name(id=self.pl.module(m), ctx=ast.Load()), node)

    def visit_Name(self, node):
        fn = self.fn
        if node.id in self.locals:
            if node.id == fn.self_name:
                raise fn.refuse(node, f"it uses {fn.self_name} other than to read its "
                                      f"numbers and arrays or call its methods")
            return node
        if node.id in _GUARD_NAMES and node.id in fn.cells:
            return ast.copy_location(ast.parse(_GUARD_NAMES[node.id], mode="eval").body, node)
        v, key, reader = self._lookup(node.id)
        if v is _MISSING:
            raise fn.refuse(node, f"{node.id!r} is not defined")
        if isinstance(v, types.ModuleType):
            if v.__name__ in _RANDOM_MODULES:
                raise fn.refuse(node, f"it uses the module {v.__name__}: random draws would "
                                      f"differ between the paths")
            return self._module_name(v, node)
        if key[0] == "builtin" and not isinstance(v, (bool, int, float)):
            return node
        if _kind(v) is not None:
            slot = self.pl.layout.add(key, node.id, v, reader)
            return _slot_expr(slot, node)
        if v is None:
            raise fn.refuse(node, f"it reads {node.id!r}, which is None")
        dispatcher = self.pl.dispatcher(v)
        if dispatcher is not None:
            return ast.copy_location(ast.Name(id=dispatcher, ctx=ast.Load()), node)
        if isinstance(v, types.FunctionType):
            raise fn.refuse(node, f"it passes the function {node.id!r} as a value (only "
                                  f"calls of functions are followed)")
        raise fn.refuse(node, f"it reads {node.id!r}, a {type(v).__name__}: numba cannot "
                              f"type it")

    def visit_Call(self, node):
        fn = self.fn
        f = node.func
        past = _past_call(self, node)           # self.history(t - tau): the run's past
        if past is not None:
            return past
        self._check_random(f)
        args = [self.visit(a) for a in node.args]
        kws = [ast.keyword(arg=k.arg, value=self._dtype(k.value) if k.arg == "dtype"
                           else self.visit(k.value)) for k in node.keywords]
        target = None
        hit = self._owner(f)
        if hit is not None:
            target = self._self_method(f, hit[0])
        elif isinstance(f, ast.Name) and f.id not in self.locals:
            v = self._lookup(f.id)[0]
            if isinstance(v, types.FunctionType) and self.pl.dispatcher(v) is None:
                target = self.pl.follow(_fn_of_plain(v, fn, f))
        if target is None:
            return ast.copy_location(ast.Call(func=self.visit(f), args=args, keywords=kws),
                                     node)
        return ast.copy_location(ast.Call(func=ast.Name(id=target, ctx=ast.Load()),
                                          args=[ast.Name(id=P, ctx=ast.Load()), *args],
                                          keywords=kws), node)

    def _dtype(self, v):
        """``dtype=float`` (a builtin type numba does not take as a dtype) as numpy's."""
        if isinstance(v, ast.Name) and v.id in _DTYPES and v.id not in self.locals \
                and self._lookup(v.id)[1] == ("builtin", v.id):
            return ast.copy_location(ast.parse(f"_hs_m_numpy.{_DTYPES[v.id]}",
                                               mode="eval").body, v)
        return self.visit(v)

    def _self_method(self, f, obj):
        fn = self.fn
        static = inspect.getattr_static(obj, f.attr, _MISSING)
        if isinstance(static, classmethod):
            raise fn.refuse(f, f"it calls the classmethod {_dotted(f)}")
        bound = getattr(obj, f.attr, None)
        if isinstance(static, staticmethod):
            func = static.__func__
            if not isinstance(func, types.FunctionType):
                raise fn.refuse(f, f"{_dotted(f)} is not a Python function")
            return self.pl.follow(Fn(func, None, f"{type(obj).__name__}.{f.attr}"))
        if isinstance(bound, types.MethodType) and isinstance(bound.__func__,
                                                               types.FunctionType):
            if bound.__self__ is not obj:
                raise fn.refuse(f, f"{_dotted(f)} is bound to another object")
            return self.pl.follow(Fn(bound.__func__, obj, f"{type(obj).__name__}.{f.attr}"))
        if isinstance(bound, types.FunctionType):      # a function stored on the instance
            return self.pl.follow(Fn(bound, None, f"{type(obj).__name__}.{f.attr}"))
        raise fn.refuse(f, f"it calls {_dotted(f)}, a {type(bound).__name__} that cannot "
                           f"be followed")


# ------------------------------------------------------------------ the past: self.history
def _past_call(rw, node):
    """``self.history(t - tau)`` in a flow map as a read of the past the compiled
    path hands the flow after its parameters (``_hs_past``), or None where
    ``node`` is not a call of ``self.history``.

    The delays are the system's (``self.delays``, a slot of ``p``: other
    delays share the compiled maps); the lag ``tau`` is matched to one of them
    when the map runs. Refused by name: a read outside the flow map (the other
    maps see no past on the compiled path), a system without delays, an
    argument not of the form ``t - tau``.
    """
    fn, pl = rw.fn, rw.pl
    f = node.func
    if not (isinstance(f, ast.Attribute) and f.attr == "history" and fn.self_name is not None
            and isinstance(f.value, ast.Name) and f.value.id == fn.self_name):
        return None
    system = pl.system
    if fn.obj is not system:
        raise fn.refuse(node, "it reads the history of another object than the system")
    if pl.root != "flow":
        raise fn.refuse(node, "it reads self.history outside the flow map (on the compiled "
                              "path only the flow map reads the past)")
    delays = tuple(float(d) for d in (getattr(system, "delays", None) or ()))
    if not delays:
        raise fn.refuse(node, "it reads self.history(...) but the system declares no delays "
                              "(self.delays = (tau, ...), the lags it reads)")
    arg = node.args[0] if len(node.args) == 1 and not node.keywords else None
    if not (isinstance(arg, ast.BinOp) and isinstance(arg.op, ast.Sub)
            and isinstance(arg.left, ast.Name) and arg.left.id in fn.params):
        raise fn.refuse(node, "self.history is read at t - tau only (t the map's time, tau "
                              "one of self.delays)")
    slot = pl.layout.add(("delays", id(system)), "delays", np.asarray(delays, dtype=float),
                         lambda s=system: np.asarray(tuple(s.delays), dtype=float))
    pl.reads_past = rw.reads_past = True
    n = int(system.state_dim)
    return _call("_hs_past", [ast.Name(id=P, ctx=ast.Load()), rw.visit(arg.right),
                              ast.Constant(slot[3]), ast.Constant(len(delays)),
                              ast.Constant(n)], node)


def _default_reader(func, params, name):
    """Reads the current default of parameter ``name`` of ``func``."""
    i = params.index(name)

    def read():
        d = func.__defaults__
        return d[i - (len(params) - len(d))]
    return read


def _fn_of_plain(v, caller, node):
    try:
        return Fn(v, None, v.__qualname__)
    except SourceRefusal as e:
        raise caller.refuse(node, f"it calls {v.__qualname__}, which cannot be followed: "
                                  f"{e.why}") from None


#: roles whose value is one number: their returns pass through ``_hs_scalar``
#: (bound by the compiler), which makes a 0-d array (``np.where`` of scalars,
#: ``x[..., k]`` on a single state under numba) the number it holds
_SCALAR_ROLES = ("jump_guard", "flow_guard", "jump_set", "flow_set", "jump_rate")


class _Scalar(_OwnReturns):
    def visit_Return(self, node):
        if node.value is None:
            return node
        return ast.copy_location(ast.Return(value=ast.copy_location(
            _call("_hs_scalar", [node.value], node.value), node.value)), node)


class _Planner:
    def __init__(self):
        self.layout = Layout()
        self.functions = []          # (generated name, FunctionDef, Fn)
        self._names = {}             # id(func), id(obj) -> generated name
        self.modules = {"numpy": "_hs_m_numpy"}     # module name -> generated name
        self.dispatchers = {}        # id -> (generated name, dispatcher)
        self.inputs = False          # a component's maps: (x, u, t, j, p)
        self.prefix = {}             # id(part of the system) -> its path ("design.")
        self.lines = {}
        # the past (self.history): the system, the role being followed, the
        # generated functions that read it, the rewrites under way
        self.system, self.root, self.reads_past = None, None, False
        self.past_fns, self.stack = set(), []

    def module(self, m):
        name = self.modules.get(m.__name__)
        if name is None:
            name = self.modules[m.__name__] = "_hs_m_" + m.__name__.replace(".", "_")
        return name

    def dispatcher(self, v):
        py = getattr(v, "py_func", None)
        if py is None or not hasattr(v, "overloads"):
            return None
        hit = self.dispatchers.get(id(v))
        if hit is None:
            hit = self.dispatchers[id(v)] = (f"_hs_d{len(self.dispatchers)}_{py.__name__}", v)
        return hit[0]

    def follow(self, fn, role=None, form=None):
        key = (id(fn.func), id(fn.obj))
        name = self._names.get(key)
        if name is not None:
            return self._past_from(name, fn)
        name = f"_hs_{role}" if role else f"_hs_f{len(self._names)}_{fn.func.__name__}"
        self._names[key] = name
        node = copy.deepcopy(fn.node)
        args = [a.arg for a in node.args.posonlyargs + node.args.args]
        if fn.self_name is not None:
            args = args[1:]
        pre = []
        if role is not None:            # the engine's (x, t, j, p)
            k = form
            if len(args) < k:
                raise fn.refuse(node, f"it takes {len(args)} arguments, expected {k}")
            for extra in args[k:]:
                # a defaulted parameter past the engine's: its value is a parameter
                value = fn.defaults.get(extra, _MISSING)
                if _kind(value) is None:
                    raise fn.refuse(node, f"its default {extra}={value!r} is not a "
                                          f"number or an array")
                slot = self.layout.add(("default", id(fn.func), extra), extra, value,
                                       _default_reader(fn.func, fn.params, extra))
                pre.append(ast.Assign(targets=[ast.Name(id=extra, ctx=ast.Store())],
                                      value=_slot_expr(slot, node)))
            own = args[:k]
            sig = [own[i] if i < len(own) else f"_hs_{'xtj'[i]}" for i in range(3)] + [P]
            if self.inputs and role != "output":        # a component's (x, u, t, j, p)
                sig.insert(1, own[3] if k >= 4 else "_hs_u")
            elif k >= 4:                # u: no input on this path
                pre.append(ast.Assign(targets=[ast.Name(id=own[3], ctx=ast.Store())],
                                      value=ast.Constant(None)))
            new_args = [ast.arg(arg=a) for a in sig]
            defaults = []
        else:
            for d in node.args.defaults:
                if not isinstance(d, ast.Constant):
                    raise fn.refuse(d, "a default argument that is not a constant")
            new_args = [ast.arg(arg=P)] + [ast.arg(arg=a) for a in args]
            defaults = node.args.defaults
        _inline_parts(fn, node)
        body = _Rewrite(self, fn)
        body.reads_past = False
        self.stack.append(body)
        try:
            node.body = body.stmts(node.body)
        finally:
            self.stack.pop()
        if body.reads_past:
            self.past_fns.add(name)
            self._past_from(name, fn)
        if role in _SCALAR_ROLES:
            node.body = [_Scalar().visit(s) for s in node.body]
        node.body = pre + node.body
        node.args = ast.arguments(posonlyargs=[], args=new_args, kwonlyargs=[],
                                  kw_defaults=[], defaults=defaults)
        node.name = name
        node.decorator_list = []
        node.returns = None
        for a in ast.walk(node):
            if isinstance(a, ast.arg):
                a.annotation = None
        ast.fix_missing_locations(node)
        self.functions.append((name, node, fn))
        return name


    def _past_from(self, name, fn):
        """``name``, a function already followed: one that reads the past marks
        its caller, and is refused outside the flow map."""
        if name in self.past_fns:
            if self.root != "flow":
                raise fn.refuse(fn.node, "it reads self.history and is called outside the "
                                         "flow map (on the compiled path only the flow map "
                                         "reads the past)")
            if self.stack:
                self.stack[-1].reads_past = True
        return name


class Plan:
    """The rewritten maps: ``source`` (a module's text), ``roles`` (engine role
    -> generated function name), ``layout``, ``dispatchers`` (names to bind
    before compiling), ``lines`` (generated line -> original ``(method,
    file:line)``)."""

    def __init__(self, source, roles, layout, dispatchers, lines, qualnames):
        self.source, self.roles, self.layout = source, roles, layout
        self.dispatchers, self.lines, self.qualnames = dispatchers, lines, qualnames

    def where(self, line):
        return self.lines.get(line)


#: HybridSystem attribute -> CompiledSystem role
ROLES = (("flow_map", "flow"), ("jump_map", "jump"), ("jump_guard", "jump_guard"),
         ("flow_guard", "flow_guard"), ("jump_set", "jump_set"), ("flow_set", "flow_set"))
#: the noise's maps (a single system's, not a component's): attribute -> role
NOISE_ROLES = (("diffusion", "diffusion"), ("jump_rate", "jump_rate"))


def plan(system, component=False):
    """The :class:`Plan` of ``system``'s maps as functions of ``(x, t, j, p)``
    (``component``: of ``(x, u, t, j, p)``, and its output of ``(x, t, j,
    p)``, for a part of an interconnection); a :class:`SourceRefusal` naming
    the method and line otherwise."""
    pl = _Planner()
    pl.inputs = bool(component)
    pl.system = system
    roles = {}
    cls = type(system).__name__
    todo = ROLES + ((("output", "output"),) if component and system._overrides("output")
                    else NOISE_ROLES if not component else ()) + (
        (("watch", "watch"),) if not component and system.watch is not None else ())
    for attr, role in todo:
        if attr in ("jump_guard", "flow_guard") or role in ("diffusion", "jump_rate"):
            fn = getattr(system, attr)
            if fn is None:
                continue
        elif attr in ("flow_map", "jump_map", "output", "watch"):
            if not system._overrides(attr):
                continue
            fn = getattr(system, attr)
        else:
            if not system._overrides(attr):
                continue
            fn = getattr(system, attr)
        f = _fn_of(fn, f"{cls}.{attr}")
        form = max(1, min(_arity(fn), 3 if role == "output" else 4))
        pl.root = role
        roles[role] = pl.follow(f, role=role, form=form)
    if "flow" not in roles:
        raise SourceRefusal(f"{cls}.flow_map", "-", "the system defines no flow_map")
    out = _assemble(pl, roles, f"the maps of {cls}, rewritten as functions of (x, t, j, p)")
    out.reads_past = pl.reads_past         # its flow reads x(t - tau_i): delays on the kernel
    return out


def _assemble(pl, roles, title):
    """The :class:`Plan` of the planner's functions: one module's text."""
    lines = [f"# hybridsim: {title}"]
    lines += [f"import {m} as {n}" for m, n in sorted(pl.modules.items())]
    lines.append("")
    where = {}
    qual = {}
    for name, node, fn in pl.functions:
        text = ast.unparse(node)
        start = len(lines) + 1
        # generated line -> the source line (the trees have one shape: walk them together)
        gen = ast.parse(text).body[0]
        for g, o in zip(ast.walk(gen), ast.walk(node)):
            if hasattr(g, "lineno") and hasattr(o, "lineno"):
                where.setdefault(start + g.lineno - 1, (fn.qualname, f"{fn.file}:{o.lineno}"))
        qual[name] = fn.qualname
        lines += text.splitlines()
        lines.append("")
    src = "\n".join(lines) + "\n"
    return Plan(src, roles, pl.layout, {n: d for n, d in pl.dispatchers.values()}, where, qual)


# ------------------------------------------------------------------ one plain function
def plan_function(fn):
    """The :class:`Plan` of one plain function ``fn(*args)`` (a module's
    function or a closure) rewritten as ``f(p, *args)`` (role ``"function"``),
    the numbers and arrays it reads slots of ``p``; a :class:`SourceRefusal`
    naming its line otherwise. For a compiled form that calls a user's
    function (:func:`hybridsim.compiled._from_source.compiled_function`)."""
    pl = _Planner()
    f = _fn_of(fn, getattr(fn, "__qualname__", type(fn).__name__))
    if f.obj is not None:
        raise f.refuse(f.node, "it is a bound method (a plain function is rewritten here)")
    out = _assemble(pl, {"function": pl.follow(f)},
                    f"{f.qualname}, rewritten as a function of (p, ...)")
    out.reads_past = False
    return out
