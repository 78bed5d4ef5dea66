"""A rewritten map whose arrays all have shapes known when it is rewritten,
written as straight-line code of numbers (:func:`unroll`).

On the compiled path a map's state and input have known lengths, the
parameters' slots known shapes, and the ints the rewrite folded (sizes,
indices) are constants: every array a map such as ``F @ Xi(xi).swapaxes(-1,
-2).reshape(n * p) + Lt`` makes has a shape known before it runs. Such a
map is evaluated here once, symbolically: each array is a grid of numbers
(a constant, an element of ``x``, ``u`` or ``p``, or a temporary), views
(slices, ``.T``, ``swapaxes``, ``reshape``, ``np.asarray``) reindex that
grid, elementwise operations broadcast as numpy does, and a product
``a @ b`` is each element's sum in index order (the sums of
``_hs_matmul``); loops over constant tuples and ``range`` are unrolled, an
``if`` whose test is known is its branch, helper functions the map calls
are inlined, and the map writes only the numbers it returns. Each operation
gives one temporary per element: the same operations, in the same order,
as the array code, so the numbers are the same, without an array per
intermediate result (a call of the rewritten H_c flow of Li-Sanfelice: 18
arrays made and copied).

A map with anything else (a test decided at run time, a call that is not
one of those, a write into its state, more than :data:`BUDGET` operations)
is kept as the rewrite wrote it.
"""
from __future__ import annotations

import ast
import copy
import itertools
import math

import numpy as np

from ._source_rewrite import P

#: at most this many statements in an unrolled map (else it keeps its loops)
BUDGET = 3000

_NP = "_hs_m_numpy"
_UFUNCS = frozenset(("sin", "cos", "tan", "exp", "log", "sqrt", "tanh", "sinh", "cosh",
                     "arctan", "arcsin", "arccos", "abs", "fabs", "expm1", "log1p",
                     "atan", "asin", "acos"))
#: numpy's functions of two numbers, elementwise with broadcasting
_BINARY = frozenset(("copysign", "minimum", "maximum", "fmin", "fmax", "arctan2", "hypot",
                     "floor_divide", "power", "fmod"))
_OPS = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
        ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b,
        ast.FloorDiv: lambda a, b: a // b, ast.Mod: lambda a, b: a % b,
        ast.Pow: lambda a, b: a ** b}
_CMP = {ast.Eq: lambda a, b: a == b, ast.NotEq: lambda a, b: a != b,
        ast.Lt: lambda a, b: a < b, ast.LtE: lambda a, b: a <= b,
        ast.Gt: lambda a, b: a > b, ast.GtE: lambda a, b: a >= b,
        ast.Is: lambda a, b: a is b, ast.IsNot: lambda a, b: a is not b,
        ast.In: lambda a, b: a in b, ast.NotIn: lambda a, b: a not in b}


class _Bail(Exception):
    """A construct this evaluation does not take: the map keeps its rewrite."""


class Dyn:
    """A number known when the map runs: an atom (a name, ``x[k]``, ``p[k]``)."""

    __slots__ = ("e",)

    def __init__(self, e):
        self.e = e


class Arr:
    """An array of a known ``shape``: ``read(index)`` its element (a Dyn or a
    number), ``write(index, value)`` (None: it cannot be written)."""

    def __init__(self, shape, read, write=None):
        self.shape, self.read, self.write = tuple(int(s) for s in shape), read, write

    def cells(self):
        return itertools.product(*(range(s) for s in self.shape))


class _Fresh(Arr):
    """A new array (``np.zeros``, ``np.empty``, ...): its elements as written."""

    def __init__(self, shape, fill):
        shape = tuple(int(s) for s in shape)
        self.data = {i: fill(i) for i in itertools.product(*(range(s) for s in shape))}
        super().__init__(shape, self.data.__getitem__, self.data.__setitem__)


class _Fn:
    """A function the map calls: ``name`` (a generated helper, a numpy function)."""

    def __init__(self, name, bound=None):
        self.name, self.bound = name, bound


def _leaf(name, shape):
    return Arr(shape, lambda i: Dyn(ast.Subscript(value=ast.Name(id=name, ctx=ast.Load()),
                                                  slice=ast.Constant(int(i[0])), ctx=ast.Load())))


def _view(a, shape, f):
    w = None if a.write is None else (lambda i, v: a.write(f(i), v))
    return Arr(shape, lambda i: a.read(f(i)), w)


def _reshape(a, shape):
    if isinstance(shape, int):
        shape = (shape,)
    shape = list(shape)
    size = math.prod(a.shape)
    if shape.count(-1) == 1:
        k = shape.index(-1)
        shape[k] = size // max(1, math.prod(s for s in shape if s != -1))
    if math.prod(shape) != size or any(not isinstance(s, int) or s < 0 for s in shape):
        raise _Bail("reshape")
    old = a.shape
    return _view(a, shape, lambda i: tuple(np.unravel_index(
        np.ravel_multi_index(i, shape) if shape else 0, old)) if old else ())


def _transpose(a, axes):
    inv = [axes.index(k) for k in range(len(axes))]
    return _view(a, [a.shape[k] for k in axes], lambda i: tuple(i[inv[k]]
                                                                for k in range(len(axes))))


def _swap(a, p, q):
    axes = list(range(len(a.shape)))
    axes[p], axes[q] = axes[q], axes[p]
    return _transpose(a, axes)


def _index(a, key):
    """``a[key]`` of static ints, slices, ``...`` and None: a view or an element."""
    key = list(key) if isinstance(key, tuple) else [key]
    if any(k is Ellipsis for k in key):
        e = key.index(Ellipsis)
        fill = len(a.shape) - sum(1 for k in key if k is not None and k is not Ellipsis)
        key[e:e + 1] = [slice(None)] * fill
    key += [slice(None)] * (len(a.shape) - sum(1 for k in key if k is not None))
    shape, parts, dim = [], [], 0
    for k in key:
        if k is None:
            shape.append(1)
            parts.append(("new",))
            continue
        if dim >= len(a.shape):
            raise _Bail("too many indices")
        n = a.shape[dim]
        if isinstance(k, bool) or not isinstance(k, (int, slice)):
            raise _Bail("index")
        if isinstance(k, int):
            if not -n <= k < n:
                raise _Bail("index out of range")
            parts.append(("int", k % n))
        else:
            r = range(*k.indices(n))
            shape.append(len(r))
            parts.append(("slice", r))
        dim += 1

    def f(i):
        out, q = [], 0
        for p in parts:
            if p[0] == "int":
                out.append(p[1])
            elif p[0] == "slice":
                out.append(p[1][i[q]])
                q += 1
            else:
                q += 1
        return tuple(out)
    v = _view(a, shape, f)
    return v.read(()) if not shape else v


def _num(v):
    return isinstance(v, (int, float, bool, np.integer, np.floating)) and not isinstance(
        v, np.ndarray)


#: the helpers of :meth:`_Unroll.of_numbers`, and their argument counts
_OF_NUMBERS = {"_hs_stack": 2, "_hs_full": 2, "_hs_full_like": 2, "_hs_clip": 3,
               "_hs_astype": 2, "_hs_newaxis1": 1, "_hs_newaxis2": 1}


class _Unroll:
    def __init__(self, functions):
        self.functions = functions          # generated name -> FunctionDef
        self.out = []
        self.k = 0
        self.depth = 0
        self.like = None

    # -- emitted code
    def atom(self, v):
        if isinstance(v, Dyn):
            return copy.deepcopy(v.e)
        if isinstance(v, (bool, np.bool_)):
            return ast.Constant(bool(v))
        if isinstance(v, (int, np.integer, float, np.floating)):
            c = int(v) if isinstance(v, (int, np.integer)) else float(v)
            if isinstance(c, float) and not math.isfinite(c):
                raise _Bail("a non-finite constant")
            if c >= 0 and not (isinstance(c, float) and math.copysign(1.0, c) < 0):
                return ast.Constant(c)
            return ast.UnaryOp(op=ast.USub(), operand=ast.Constant(-c))
        raise _Bail(f"not a number: {type(v).__name__}")

    def emit(self, e):
        self.k += 1
        if len(self.out) > BUDGET:
            raise _Bail("too long")
        name = f"_hs_e{self.k}"
        self.out.append(ast.copy_location(ast.Assign(
            targets=[ast.Name(id=name, ctx=ast.Store())], value=e), self.like))
        return Dyn(ast.Name(id=name, ctx=ast.Load()))

    # -- numbers and arrays
    def scalar_op(self, op, a, b):
        if _num(a) and _num(b):
            return _OPS[type(op)](a, b)
        return self.emit(ast.BinOp(left=self.atom(a), op=copy.deepcopy(op),
                                   right=self.atom(b)))

    def binop(self, op, a, b):
        if isinstance(op, ast.MatMult):
            return self.matmul(a, b)
        if not isinstance(a, Arr) and not isinstance(b, Arr):
            if type(op) not in _OPS or not (_num(a) or isinstance(a, Dyn)) or \
                    not (_num(b) or isinstance(b, Dyn)):
                raise _Bail("an operation")
            return self.scalar_op(op, a, b)
        if type(op) not in _OPS:
            raise _Bail("an operation")
        sa = a.shape if isinstance(a, Arr) else ()
        sb = b.shape if isinstance(b, Arr) else ()
        try:
            shape = np.broadcast_shapes(sa, sb)
        except ValueError:
            raise _Bail("shapes") from None
        res = _Fresh(shape, lambda i: 0.0)
        for i in res.cells():
            res.data[i] = self.scalar_op(op, self._at(a, i), self._at(b, i))
        return res

    @staticmethod
    def _at(a, i):
        if not isinstance(a, Arr):
            return a
        off = len(i) - len(a.shape)
        return a.read(tuple(0 if s == 1 else i[off + k] for k, s in enumerate(a.shape)))

    def unary(self, op, a):
        if isinstance(op, ast.UAdd):
            return a
        if not isinstance(op, ast.USub):
            if isinstance(op, ast.Not) and isinstance(a, (bool, int)):
                return not a
            raise _Bail("a unary operation")
        if isinstance(a, Arr):
            res = _Fresh(a.shape, lambda i: 0.0)
            for i in res.cells():
                res.data[i] = self.unary(op, a.read(i))
            return res
        if _num(a):
            return -a
        if isinstance(a, Dyn):
            return self.emit(ast.UnaryOp(op=ast.USub(), operand=self.atom(a)))
        raise _Bail("a unary operation")

    def dot(self, terms):
        """``sum a_k b_k`` in index order (0.0 + the first product is that product)."""
        e = None
        for a, b in terms:
            if _num(a) and _num(b):
                t = ast.Constant(float(a * b))
            else:
                t = ast.BinOp(left=self.atom(a), op=ast.Mult(), right=self.atom(b))
            e = t if e is None else ast.BinOp(left=e, op=ast.Add(), right=t)
        return 0.0 if e is None else self.emit(e)

    def matmul(self, a, b):
        if not (isinstance(a, Arr) and isinstance(b, Arr)) or \
                len(a.shape) not in (1, 2) or len(b.shape) not in (1, 2):
            raise _Bail("a product")
        q = a.shape[-1]
        if b.shape[0] != q:
            raise _Bail("a product of shapes that do not match")
        if len(a.shape) == 1 and len(b.shape) == 1:
            return self.dot((a.read((k,)), b.read((k,))) for k in range(q))
        if len(b.shape) == 1:
            res = _Fresh((a.shape[0],), lambda i: 0.0)
            for (i,) in res.cells():
                res.data[(i,)] = self.dot((a.read((i, k)), b.read((k,))) for k in range(q))
            return res
        if len(a.shape) == 1:
            res = _Fresh((b.shape[1],), lambda i: 0.0)
            for (i,) in res.cells():
                res.data[(i,)] = self.dot((a.read((k,)), b.read((k, i))) for k in range(q))
            return res
        res = _Fresh((a.shape[0], b.shape[1]), lambda i: 0.0)
        for i, m in res.cells():
            res.data[(i, m)] = self.dot((a.read((i, k)), b.read((k, m))) for k in range(q))
        return res

    def store(self, target, value, env):
        """``target = value`` (a name, a tuple of names, an element or a slice)."""
        if isinstance(target, ast.Name):
            env[target.id] = value
        elif isinstance(target, (ast.Tuple, ast.List)):
            if not isinstance(value, tuple) or len(value) != len(target.elts):
                raise _Bail("an unpacking")
            for t, v in zip(target.elts, value):
                self.store(t, v, env)
        elif isinstance(target, ast.Subscript):
            base = self.expr(target.value, env)
            if not isinstance(base, Arr) or base.write is None:
                raise _Bail("a write into an array the map does not own")
            self._put(base, self.expr(target.slice, env), value)
        else:
            raise _Bail("a target")

    def _put(self, base, key, value):
        into = _index(base, key)
        if not isinstance(into, Arr):                 # one element
            if isinstance(value, Arr):
                if value.shape not in ((), (1,)):
                    raise _Bail("an element set to an array")
                value = value.read((0,) * len(value.shape))
            self._element(base, key, value)
            return
        if isinstance(value, Arr):
            try:
                np.broadcast_shapes(value.shape, into.shape)
            except ValueError:
                raise _Bail("shapes") from None
            if len(value.shape) > len(into.shape):
                raise _Bail("shapes")
            vals = [(i, self._at(value, i)) for i in into.cells()]   # read before writing
        else:
            vals = [(i, value) for i in into.cells()]
        for i, v in vals:
            if not (_num(v) or isinstance(v, Dyn)):
                raise _Bail("an element that is not a number")
            into.write(i, v)

    def _element(self, base, key, value):
        if not (_num(value) or isinstance(value, Dyn)):
            raise _Bail("an element that is not a number")
        key = list(key) if isinstance(key, tuple) else [key]
        if Ellipsis in key:                           # v[..., k] of one element
            e = key.index(Ellipsis)
            key[e:e + 1] = [0] * (len(base.shape) - len(key) + 1)
        if len(key) != len(base.shape) or not all(isinstance(k, int) for k in key):
            raise _Bail("an element's index")
        idx = tuple(k % s for k, s in zip(key, base.shape))
        base.write(idx, value)

    # -- expressions
    def expr(self, e, env):
        m = getattr(self, "e_" + type(e).__name__, None)
        if m is None:
            raise _Bail(type(e).__name__)
        return m(e, env)

    def e_Constant(self, e, env):
        if isinstance(e.value, (int, float, bool, str, type(None))) or e.value is Ellipsis:
            return e.value
        raise _Bail("a constant")

    def e_Name(self, e, env):
        if e.id in env:
            return env[e.id]
        if e.id in ("range", "slice", "len", "int", "float", "abs", "min", "max"):
            return _Fn(e.id)
        if e.id.startswith("_hs_"):
            return _Fn(e.id)
        raise _Bail(f"the name {e.id}")

    def e_Tuple(self, e, env):
        return tuple(self.expr(v, env) for v in e.elts)

    e_List = e_Tuple

    def e_Slice(self, e, env):
        parts = [None if v is None else self.expr(v, env) for v in (e.lower, e.upper, e.step)]
        if any(p is not None and (isinstance(p, bool) or not isinstance(p, int))
               for p in parts):
            raise _Bail("a slice")
        return slice(*parts)

    def e_Attribute(self, e, env):
        v = self.expr(e.value, env)
        if isinstance(v, _Fn):
            return _Fn(f"{v.name}.{e.attr}")
        if isinstance(v, Arr):
            if e.attr == "T":
                return _transpose(v, list(range(len(v.shape)))[::-1])
            if e.attr == "shape":
                return v.shape
            if e.attr == "ndim":
                return len(v.shape)
            if e.attr == "size":
                return math.prod(v.shape)
            if e.attr in ("reshape", "copy", "swapaxes", "transpose", "ravel", "flatten"):
                return _Fn("." + e.attr, v)
        raise _Bail(f"the attribute {e.attr}")

    def e_Subscript(self, e, env):
        v = self.expr(e.value, env)
        key = self.expr(e.slice, env)
        if isinstance(v, Arr):
            return _index(v, key)
        if (isinstance(v, Dyn) or _num(v)) and all(
                k is None or k is Ellipsis for k in (key if isinstance(key, tuple) else (key,))):
            ks = key if isinstance(key, tuple) else (key,)   # a number's v[..., None]
            return Arr((1,) * sum(k is None for k in ks), lambda i: v)
        if isinstance(v, (tuple, str)):
            try:
                return v[key]
            except (TypeError, IndexError):
                raise _Bail("an index") from None
        raise _Bail("a subscript")

    def e_BinOp(self, e, env):
        a, b = self.expr(e.left, env), self.expr(e.right, env)
        if isinstance(a, tuple) and isinstance(b, tuple) and isinstance(e.op, ast.Add):
            return a + b
        if isinstance(a, (tuple, str)) or isinstance(b, (tuple, str)):
            raise _Bail("an operation of a tuple")
        return self.binop(e.op, a, b)

    def e_UnaryOp(self, e, env):
        return self.unary(e.op, self.expr(e.operand, env))

    def e_Compare(self, e, env):
        vals = [self.expr(v, env) for v in [e.left, *e.comparators]]
        if any(isinstance(v, (Arr, Dyn, _Fn)) for v in vals):
            raise _Bail("a test decided when the map runs")
        return all(_CMP[type(op)](a, b) for op, a, b in zip(e.ops, vals, vals[1:]))

    def e_BoolOp(self, e, env):
        is_and = isinstance(e.op, ast.And)
        v = None
        for x in e.values:
            v = self.expr(x, env)
            if isinstance(v, (Arr, Dyn, _Fn)):
                raise _Bail("a test decided when the map runs")
            if bool(v) != is_and:
                return v
        return v

    def e_IfExp(self, e, env):
        t = self.expr(e.test, env)
        if isinstance(t, (Arr, Dyn, _Fn)):
            raise _Bail("a test decided when the map runs")
        return self.expr(e.body if t else e.orelse, env)

    def e_Call(self, e, env):
        f = self.expr(e.func, env)
        if not isinstance(f, _Fn):
            raise _Bail("a call")
        args = [self.expr(a, env) for a in e.args]
        kw = {k.arg: self.expr(k.value, env) for k in e.keywords}
        if None in kw:
            raise _Bail("**keywords")
        return self.call(f, args, kw)

    def call(self, f, args, kw):
        name = f.name
        if f.bound is not None:                        # a method of an array
            return self.method(f.bound, name[1:], args, kw)
        if name in self.functions:
            return self.inline(self.functions[name], args, kw)
        short = name.rsplit(".", 1)[-1]
        mod = name.rsplit(".", 1)[0] if "." in name else ""
        if mod in (_NP, "_hs_m_math"):
            return self.numpy(short, args, kw, mod == "_hs_m_math")
        if kw:
            raise _Bail(f"keywords of {name}")
        return self.builtin(name, args)

    def builtin(self, name, args):
        if name == "range" and all(isinstance(a, int) for a in args):
            return tuple(range(*args))
        if name == "slice" and len(args) in (1, 2, 3) and all(
                a is None or (isinstance(a, int) and not isinstance(a, bool)) for a in args):
            return slice(*args)
        if name == "len" and len(args) == 1:
            a = args[0]
            if isinstance(a, Arr) and a.shape:
                return a.shape[0]
            if isinstance(a, tuple):
                return len(a)
        if name in ("int", "float") and len(args) == 1:
            a = args[0]
            if _num(a):
                return int(a) if name == "int" else float(a)
            if isinstance(a, Dyn):
                return self.emit(ast.Call(func=ast.Name(id=name, ctx=ast.Load()),
                                          args=[self.atom(a)], keywords=[]))
        if name == "abs" and len(args) == 1:
            return self.elementwise("abs", args[0], ast.Name(id="abs", ctx=ast.Load()))
        if name in ("min", "max") and len(args) >= 2 and all(_num(a) for a in args):
            return (min if name == "min" else max)(args)
        if name in ("_hs_scalar",) and len(args) == 1:
            a = args[0]
            return a.read(()) if isinstance(a, Arr) and not a.shape else a
        if name == "_hs_matmul" and len(args) == 2:
            return self.matmul(*args)
        if name == "_hs_reshape" and len(args) == 2:
            return self.method(args[0], "reshape", [args[1]], {})
        if name.startswith(("_hs_pmv", "_hs_mpv")):
            return self.product(name, args)
        if name in _OF_NUMBERS:
            return self.of_numbers(name, args)
        if name == "_hs_setitem" and len(args) == 3:   # a[i:j] = v (the rewrite's)
            base, key, value = args
            if not isinstance(base, Arr) or base.write is None:
                raise _Bail("a write into an array the map does not own")
            self._put(base, key, value)
            return None
        raise _Bail(f"a call of {name}")

    def of_numbers(self, name, args):
        """The helpers of a map written along the last axis
        (``_Rewrite._of_numbers``): of numbers (and of arrays of known shape
        for ``_hs_stack``, ``_hs_full``, ``_hs_full_like``), as the compiled
        helper computes them."""
        def number(v):
            return _num(v) or isinstance(v, Dyn)
        if len(args) != _OF_NUMBERS[name]:
            raise _Bail(f"a call of {name}")
        if name == "_hs_stack":
            items = args[0]          # of numbers, whatever the axis
            if not (isinstance(items, tuple) and all(number(v) for v in items)):
                raise _Bail("a stack of arrays")
            res = _Fresh((len(items),), lambda i: 0.0)
            for k, v in enumerate(items):
                res.data[(k,)] = float(v) if _num(v) else v
            return res
        e, v = args[0], args[-1]
        if name.startswith("_hs_newaxis"):     # e[..., None]: a number is itself
            if isinstance(e, Arr):
                return _index(e, (Ellipsis,) + (None,) * int(name[-1]))
            if number(e):
                return e
        if name in ("_hs_full", "_hs_full_like") and isinstance(e, Arr) and number(v):
            return _Fresh(e.shape, lambda i: float(v) if _num(v) else v)
        if name == "_hs_full" and number(e) and number(v):
            return v
        if name == "_hs_clip" and all(_num(a) for a in args):
            return min(max(args[0], args[1]), args[2])
        if name == "_hs_astype" and number(e) and isinstance(v, _Fn) and v.bound is None:
            # the helper's call, typed by its operand when the map compiles
            return self.emit(ast.Call(func=ast.Name(id=name, ctx=ast.Load()),
                                      args=[self.atom(e), ast.parse(v.name, mode="eval").body],
                                      keywords=[]))
        if name in ("_hs_clip", "_hs_full_like") and all(number(a) for a in args):
            return self.emit(ast.Call(func=ast.Name(id=name, ctx=ast.Load()),
                                      args=[self.atom(a) for a in args], keywords=[]))
        raise _Bail(f"{name} of these operands")

    def product(self, name, args):
        side, mode = name[:7], name[7:]
        if len(args) < 5 or not all(isinstance(a, int) for a in args[1:4]):
            raise _Bail("a product")
        p, off, r, c = args[:4]
        M = _reshape(_index(p, slice(off, off + r * c)), (r, c))
        v = args[4]
        if mode.startswith("_cat"):
            pieces, axis = args[4], args[5]
            v = self.concatenate(pieces, axis)
            mode = mode[4:]
        prod = self.matmul(M, v) if side == "_hs_mpv" else self.matmul(
            v, _transpose(M, [1, 0]))
        if mode == "":
            return prod
        y = args[-1]
        if not isinstance(y, Arr) or y.write is None:
            raise _Bail("a product into an array the map does not own")
        op = {"_add": ast.Add(), "_sub": ast.Sub(), "_set": None}.get(mode, False)
        if op is False:
            raise _Bail(f"a call of {name}")
        self._put(y, Ellipsis, prod if op is None else self.binop(op, y, prod))
        return None

    def concatenate(self, pieces, axis=0):
        if not isinstance(pieces, tuple) or not pieces or \
                not all(isinstance(a, Arr) and len(a.shape) == 1 for a in pieces) \
                or axis not in (0, -1):
            raise _Bail("a concatenation")
        where = [(k, q) for k, a in enumerate(pieces) for q in range(a.shape[0])]
        return Arr((len(where),), lambda i: pieces[where[i[0]][0]].read((where[i[0]][1],)))

    def elementwise(self, fname, a, func):
        if isinstance(a, Arr):
            res = _Fresh(a.shape, lambda i: 0.0)
            for i in res.cells():
                res.data[i] = self.elementwise(fname, a.read(i), func)
            return res
        if isinstance(a, Dyn) or _num(a):
            return self.emit(ast.Call(func=copy.deepcopy(func), args=[self.atom(a)],
                                      keywords=[]))
        raise _Bail(f"{fname} of something else")

    def binary(self, name, a, b):
        """numpy's ``name(a, b)``, elementwise with numpy's broadcasting."""
        func = ast.Attribute(value=ast.Name(id=_NP, ctx=ast.Load()), attr=name,
                             ctx=ast.Load())
        for v in (a, b):
            if not (isinstance(v, (Arr, Dyn)) or _num(v)):
                raise _Bail(f"numpy.{name} of something else")
        if not isinstance(a, Arr) and not isinstance(b, Arr):
            return self.emit(ast.Call(func=func, args=[self.atom(a), self.atom(b)],
                                      keywords=[]))
        try:
            shape = np.broadcast_shapes(a.shape if isinstance(a, Arr) else (),
                                        b.shape if isinstance(b, Arr) else ())
        except ValueError:
            raise _Bail("shapes") from None
        res = _Fresh(shape, lambda i: 0.0)
        for i in res.cells():
            res.data[i] = self.binary(name, self._at(a, i), self._at(b, i))
        return res

    def sum(self, a, axis):
        """``np.sum(a, axis=axis)`` of fewer than 8 numbers a sum: numpy's order
        there (from the first, in index order; it sums 8 or more pairwise)."""
        if not isinstance(a, Arr):
            raise _Bail("a sum of something else")
        nd = len(a.shape)
        if axis is None:
            a, axis, nd = _reshape(a, (-1,)), 0, 1
        if isinstance(axis, bool) or not isinstance(axis, int) or not -nd <= axis < nd:
            raise _Bail("a sum's axis")
        axis %= nd
        n = a.shape[axis]
        if n >= 8 or n == 0:
            raise _Bail("a pairwise sum")
        shape = a.shape[:axis] + a.shape[axis + 1:]
        res = _Fresh(shape, lambda i: 0.0)
        for i in res.cells():
            acc = a.read(i[:axis] + (0,) + i[axis:])
            for k in range(1, n):
                acc = self.scalar_op(ast.Add(), acc, a.read(i[:axis] + (k,) + i[axis:]))
            res.data[i] = acc
        return res if shape else res.data[()]

    def method(self, a, name, args, kw):
        if kw:
            raise _Bail("keywords of a method")
        if name == "reshape":
            shape = args[0] if len(args) == 1 else tuple(args)
            return _reshape(a, shape)
        if name in ("ravel", "flatten") and not args:
            return _reshape(a, (-1,))
        if name == "copy" and not args:
            return self.fresh_copy(a)
        if name == "swapaxes" and len(args) == 2:
            n = len(a.shape)
            return _swap(a, args[0] % n, args[1] % n)
        if name == "transpose" and not args:
            return _transpose(a, list(range(len(a.shape)))[::-1])
        raise _Bail(f"the method {name}")

    def fresh_copy(self, a):
        res = _Fresh(a.shape, lambda i: 0.0)
        for i in res.cells():
            res.data[i] = a.read(i)
        return res

    def numpy(self, name, args, kw, is_math):
        if name == "sum" and not is_math and len(args) == 1 and set(kw) <= {"axis"}:
            return self.sum(args[0], kw.get("axis"))
        dt = kw.pop("dtype", _Fn(f"{_NP}.float64"))
        if kw or not (isinstance(dt, _Fn) and dt.name == f"{_NP}.float64"):
            raise _Bail(f"keywords of {name}")
        if name in _UFUNCS and len(args) == 1:
            mod = "_hs_m_math" if is_math else _NP
            return self.elementwise(name, args[0], ast.Attribute(
                value=ast.Name(id=mod, ctx=ast.Load()), attr=name, ctx=ast.Load()))
        if is_math:
            raise _Bail(f"math.{name}")
        if name in _BINARY and len(args) == 2:
            return self.binary(name, *args)
        if name in ("asarray", "ascontiguousarray", "asfarray") and len(args) == 1:
            a = args[0]
            if isinstance(a, Arr) or isinstance(a, Dyn) or _num(a):
                return a
        if name in ("zeros", "empty", "ones") and len(args) == 1:
            shape = args[0]
            shape = (shape,) if isinstance(shape, int) else shape
            if isinstance(shape, tuple) and all(isinstance(s, int) for s in shape):
                v = 1.0 if name == "ones" else 0.0
                return _Fresh(shape, lambda i: v)
        if name in ("zeros_like", "empty_like", "ones_like") and len(args) == 1 and \
                isinstance(args[0], Arr):
            v = 1.0 if name == "ones_like" else 0.0
            return _Fresh(args[0].shape, lambda i: v)
        if name == "eye" and len(args) == 1 and isinstance(args[0], int):
            return _Fresh((args[0], args[0]), lambda i: 1.0 if i[0] == i[1] else 0.0)
        if name == "shape" and len(args) == 1 and isinstance(args[0], Arr):
            return args[0].shape
        if name == "swapaxes" and len(args) == 3 and isinstance(args[0], Arr):
            return self.method(args[0], "swapaxes", args[1:], {})
        if name == "transpose" and len(args) == 1 and isinstance(args[0], Arr):
            return self.method(args[0], "transpose", [], {})
        if name == "reshape" and len(args) == 2 and isinstance(args[0], Arr):
            return self.method(args[0], "reshape", [args[1]], {})
        if name == "copy" and len(args) == 1 and isinstance(args[0], Arr):
            return self.fresh_copy(args[0])
        if name == "array" and len(args) == 1:
            a = args[0]
            if isinstance(a, Arr):
                return self.fresh_copy(a)
            if isinstance(a, tuple) and all(_num(v) or isinstance(v, Dyn) for v in a):
                res = _Fresh((len(a),), lambda i: 0.0)
                for k, v in enumerate(a):
                    res.data[(k,)] = v
                return res
        if name == "concatenate" and len(args) == 1:
            return self.fresh_copy(self.concatenate(args[0]))
        if name in ("dot", "matmul") and len(args) == 2:
            return self.matmul(*args)
        raise _Bail(f"numpy.{name}")

    # -- statements
    def inline(self, node, args, kw):
        if kw or self.depth > 8:
            raise _Bail("a call")
        params = [a.arg for a in node.args.args]
        if len(args) > len(params) or node.args.vararg or node.args.kwonlyargs:
            raise _Bail("a call")
        defaults = node.args.defaults
        env = dict(zip(params, args))
        for name, d in zip(params[len(params) - len(defaults):], defaults):
            if name not in env:
                env[name] = self.expr(d, {})
        if len(env) != len(params):
            raise _Bail("a call")
        self.depth += 1
        try:
            done, value = self.block(node.body, env)
        finally:
            self.depth -= 1
        return value if done else None

    def block(self, body, env):
        """Run the statements: ``(True, value)`` where one returned."""
        for st in body:
            self.like = st
            if isinstance(st, ast.Expr):
                if not isinstance(st.value, ast.Constant):
                    self.expr(st.value, env)
            elif isinstance(st, ast.Assign):
                v = self.expr(st.value, env)
                for t in st.targets:
                    self.store(t, v, env)
            elif isinstance(st, ast.AugAssign):
                self.augment(st, env)
            elif isinstance(st, ast.If):
                t = self.expr(st.test, env)
                if isinstance(t, (Arr, Dyn, _Fn)):
                    raise _Bail("a test decided when the map runs")
                done, v = self.block(st.body if t else st.orelse, env)
                if done:
                    return done, v
            elif isinstance(st, ast.For):
                if st.orelse or any(isinstance(n, (ast.Break, ast.Continue))
                                    for n in ast.walk(st)):
                    raise _Bail("a loop with break or continue")
                seq = self.expr(st.iter, env)
                if not isinstance(seq, tuple):
                    raise _Bail("a loop over an array")
                for v in seq:
                    self.store(st.target, v, env)
                    done, r = self.block(st.body, env)
                    if done:
                        return done, r
            elif isinstance(st, ast.Return):
                return True, None if st.value is None else self.expr(st.value, env)
            elif isinstance(st, ast.Pass):
                pass
            else:
                raise _Bail(type(st).__name__)
        return False, None

    def augment(self, st, env):
        t = st.target
        if isinstance(t, ast.Name):
            cur = self.expr(t, env)
            v = self.binop(st.op, cur, self.expr(st.value, env))
            if isinstance(cur, Arr):                    # in place
                if cur.write is None:
                    raise _Bail("a write into an array the map does not own")
                self._put(cur, Ellipsis, v)
            else:
                env[t.id] = v
        elif isinstance(t, ast.Subscript):
            base = self.expr(t.value, env)
            key = self.expr(t.slice, env)
            if not isinstance(base, Arr) or base.write is None:
                raise _Bail("a write into an array the map does not own")
            cur = _index(base, key)
            v = self.binop(st.op, cur, self.expr(st.value, env))
            self._put(base, key, v)
        else:
            raise _Bail("a target")


def unroll(node, functions, shapes, into=False):
    """``node`` (a generated map's FunctionDef; ``functions`` the generated
    functions it may call, by name; ``shapes`` the lengths of its one-state
    arguments, by name) as straight-line code of numbers, or None where it
    takes something :class:`_Unroll` does not (the module's notes).

    ``into``: where the map returns an array, written into one more
    argument, ``out`` last (``f(x, t, j, p, out)``, no array made a call:
    :attr:`hybridsim.compiled.CompiledSystem.maps_into`); a map returning a
    number is returned as it is."""
    u = _Unroll(functions)
    env = {}
    for a in node.args.args:
        if a.arg == P:
            env[P] = _leaf(P, (1 << 40,))
        elif a.arg in shapes:
            env[a.arg] = _leaf(a.arg, (shapes[a.arg],))
        else:
            env[a.arg] = Dyn(ast.Name(id=a.arg, ctx=ast.Load()))
    try:
        done, value = u.block(node.body, env)
        if not done:
            raise _Bail("no return")
        u.like = node.body[-1]
        if isinstance(value, Arr):
            if not value.shape:
                ret = u.atom(value.read(()))
                into = False
            else:
                r = "_hs_r"
                if not into:
                    u.out.append(ast.Assign(targets=[ast.Name(id=r, ctx=ast.Store())],
                                            value=ast.parse(f"{_NP}.empty({value.shape!r})",
                                                            mode="eval").body))
                for i in value.cells():
                    u.out.append(ast.Assign(targets=[ast.Subscript(
                        value=ast.Name(id=r, ctx=ast.Load()),
                        slice=ast.Constant(int(i[0])) if len(i) == 1 else ast.Tuple(
                            elts=[ast.Constant(int(k)) for k in i], ctx=ast.Load()),
                        ctx=ast.Store())], value=u.atom(value.read(i))))
                ret = None if into else ast.Name(id=r, ctx=ast.Load())
        elif isinstance(value, Dyn) or _num(value):
            ret = u.atom(value)
            into = False
        else:
            raise _Bail("it returns something else than a number or an array")
        if len(u.out) > BUDGET:
            raise _Bail("too long")
    except (_Bail, RecursionError, ZeroDivisionError, OverflowError):
        return None
    new = copy.copy(node)
    last = node.body[-1]
    body = u.out + [ast.Return(value=ret)]
    if into:
        new.args = copy.copy(node.args)
        new.args.args = [*node.args.args, ast.arg(arg="_hs_r")]
    for st in body:
        if not hasattr(st, "lineno"):
            ast.copy_location(st, last)
        for n in ast.walk(st):
            if "lineno" in n._attributes and not hasattr(n, "lineno"):
                ast.copy_location(n, st)
    new.body = body
    return ast.fix_missing_locations(new)
