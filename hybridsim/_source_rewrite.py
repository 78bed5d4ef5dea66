"""The ast rewrite of one function's body for a plan of the maps as
functions of ``(x, t, j, p)`` (:class:`_Rewrite`, its helpers, and
:func:`_past_call`, a read of ``self.history``); the notes are in
:mod:`hybridsim._source`, whose planner drives it and re-exports the names
other modules import from it.
"""
from __future__ import annotations

import ast
import builtins
import copy
import inspect
import types

import numpy as np

from ._source_guards import _GUARD_NAMES, _call
from ._source_last_axis import _ellipsis_then, _LastAxis
from ._source_read import Fn, SourceRefusal
from ._source_slots import P, _slot_expr, _slot_item

_RESERVED = "_hs_"


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

def _is_int(v):
    """Whether ``v`` is an int (not a bool): a constant of the rewrite (a size,
    an index), as a bool or a str is."""
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def _located(st, like):
    """``st`` and every node under it at ``like``'s line (generated statements)."""
    for n in ast.walk(st):
        if "lineno" in n._attributes:
            ast.copy_location(n, like)
    return st


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


class Read:
    """Reads ``attr`` (and its item ``item``) of ``obj``, a part of the system at
    ``path`` (attribute names from the system; None: not known). :meth:`on`
    reads the same from another system of the same class (a plan made once
    serves every instance)."""

    def __init__(self, obj, attr, path, item=_MISSING, then=None):
        self.obj, self.attr, self.path, self.item, self.then = obj, attr, path, item, then

    def __call__(self):
        v = getattr(self.obj, self.attr)
        v = v if self.item is _MISSING else v[self.item]
        return v if self.then is None else self.then(v)

    def on(self, system):
        """The same read on ``system`` (AttributeError where its part is missing)."""
        o = system
        for a in self.path:
            o = getattr(o, a)
        return Read(o, self.attr, self.path, self.item, self.then)


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


# ------------------------------------------------------------------ one state: 1-D arrays
#: calls that give a new array of the shape of their first argument (or of the shape given)
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


class _Rewrite(_LastAxis, ast.NodeTransformer):
    """One function's body, rewritten for the plan (module notes)."""

    def __init__(self, planner, fn):
        self.pl, self.fn = planner, fn
        self.vectors, self.fresh = set(), set()     # one-state arrays (a map's x, u, dx)
        self._tmp = -1                              # generated names _hs_o0, _hs_v0_0, ...
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
            self.pl.layout.same(("part", id(obj), a), self._reader(obj, a), v)
            self.pl.prefix.setdefault(id(v), f"{self.pl.prefix.get(id(obj), '')}{a}.")
            path = self.pl.paths.get(id(obj))
            self.pl.paths.setdefault(id(v), None if path is None else path + (a,))
            obj = v
        return obj, node.attr

    def _reader(self, obj, attr, item=_MISSING):
        """The :class:`Read` of ``obj.attr`` (``[item]``); a part not reached from the
        system (no path) makes the plan the system's own (``pl.reusable``)."""
        path = self.pl.paths.get(id(obj))
        if path is None:
            self.pl.reusable = False
        return Read(obj, attr, path or (), item)

    def _name(self, obj, attr):
        """A slot's name: its path from the system (``design.F1``)."""
        return self.pl.prefix.get(id(obj), "") + attr

    def visit_Subscript(self, node):
        """``self.slices["xh1"]`` (a dict of the system read by a constant key):
        its value, a slice of ints written as a constant slice, a number or
        array read as a slot of ``p``; a row's gather (:meth:`_gather`)."""
        hit = self._gather(node)
        if hit is not None:
            return hit
        for axes in (1, 2):
            if isinstance(node.ctx, ast.Load) and not self._one_state(node.value) \
                    and _ellipsis_then(node.slice, *(None,) * axes):
                # e[..., None] of a row's number (to broadcast against its vectors):
                # on one state the number itself (an array's: numpy's new axes)
                return _call(f"_hs_newaxis{axes}", [self.visit(node.value)], node)
        v = node.value
        hit = self._owner(v) if isinstance(node.ctx, ast.Load) else None
        key = node.slice
        table = getattr(hit[0], hit[1], None) if hit is not None else None
        if not (isinstance(table, dict) and isinstance(key, ast.Constant)
                and isinstance(key.value, str) and key.value in table):
            node = self.generic_visit(node)
            node.slice = _as_slice(node.slice)
            return _slot_item(node)
        obj, attr = hit
        k = key.value
        e = table[k]

        reader = self._reader(obj, attr, k)
        name = f"{self._name(obj, attr)}[{k!r}]"
        if isinstance(e, slice) and all(b is None or isinstance(b, int)
                                        for b in (e.start, e.stop, e.step)):
            self.pl.layout.fold(("item", id(obj), attr, k), reader, e)
            return ast.copy_location(_call("slice", [ast.Constant(b) for b in
                                                     (e.start, e.stop, e.step)], node), node)
        if isinstance(e, (bool, str)) or _is_int(e):
            self.pl.layout.fold(("item", id(obj), attr, k), reader, e)
            return ast.copy_location(ast.Constant(int(e) if _is_int(e) else e), node)
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
        into = self._products_into(node)
        if into is not None:
            return into
        node = self.generic_visit(node)
        return self._setitem(node, node.targets, node.value) or node

    def _products_into(self, node):
        """``out[a:b] = M @ v + N @ w - ...``, ``r = ...`` or ``out[a:b] += ...``, every
        term a product with a matrix read from ``p``, as sums written in place:
        the first into the target, the others added to (subtracted from) it, no
        array per term (``out`` a new one-state array, ``r`` a name; neither
        read on the right). Of one-state vectors (``x[a:b]``, ``u``) the
        products are loops in the map itself (:meth:`_loops`). None where the
        statement is not of that form."""
        aug = isinstance(node, ast.AugAssign)
        if aug and not isinstance(node.op, (ast.Add, ast.Sub)):
            return None
        targets = [node.target] if aug else node.targets
        if len(targets) != 1:
            return None
        t = targets[0]
        if isinstance(t, ast.Name) and (not aug or t.id in self.vectors):
            base = t.id
        elif isinstance(t, ast.Subscript) and isinstance(t.value, ast.Name) \
                and t.value.id in self.fresh and isinstance(t.slice, ast.Slice):
            base = t.value.id
        else:
            return None
        terms, e = [], node.value
        while isinstance(e, ast.BinOp) and isinstance(e.op, (ast.Add, ast.Sub)):
            terms.append((e.op, e.right))
            e = e.left
        terms.append((node.op if aug else ast.Add(), e))
        terms.reverse()
        if aug and len(terms) > 1:      # y += a + b: (y + a) + b would round otherwise
            return None
        if any(isinstance(n, ast.Name) and n.id == base for n in ast.walk(node.value)):
            return None
        if not all(isinstance(v, ast.BinOp) and isinstance(v.op, ast.MatMult)
                   for _, v in terms):
            return None
        hits = [self._product(v) for _, v in terms]
        if any(h is None for h in hits):
            return None
        loops = all(self._one_state(vec) for _, vec, _ in hits)
        if not loops and (aug or len(terms) < 2):
            return None                 # as it is (y += M @ v: _hs_pmv_add)

        def where():
            if isinstance(t, ast.Name):
                return ast.Name(id=base, ctx=ast.Load())
            return ast.Subscript(value=ast.Name(id=base, ctx=ast.Load()),
                                 slice=self.visit(copy.deepcopy(t.slice)), ctx=ast.Load())
        if loops:
            return self._loops(node, t, where, terms, hits, aug)
        out = []
        for i, ((op, v), (slot, vec, side)) in enumerate(zip(terms, hits)):
            if i == 0 and isinstance(t, ast.Name):
                st = ast.Assign(targets=[t], value=self._pmv(slot, vec, side, v))
            else:
                call = self._pmv(slot, vec, side, v, where())
                mode = "_set" if i == 0 else "_sub" if isinstance(op, ast.Sub) else "_add"
                call.func.id = call.func.id[:-len("_add")] + mode
                st = ast.Expr(value=call)
            out.append(ast.fix_missing_locations(ast.copy_location(st, node)))
        return out

    def _one_state(self, v):
        """Whether ``v`` is a one-state vector: a 1-D name (``u``) or its slice (``x[a:b]``)."""
        if isinstance(v, ast.Subscript) and isinstance(v.slice, ast.Slice):
            v = v.value
        return isinstance(v, ast.Name) and v.id in self.vectors

    def _loops(self, node, t, where, terms, hits, aug):
        """The products of :meth:`_products_into` as loops over ``p`` in the map:
        each row's sum in index order (the sums of ``matvec``), set, added or
        subtracted into the target (views bound once, their lengths checked)."""
        k = self._tmp = self._tmp + 1
        o = f"_hs_o{k}"
        rows = hits[0][0][2][0]
        if isinstance(t, ast.Name) and not aug:
            first = ast.Assign(targets=[ast.Name(id=t.id, ctx=ast.Store())],
                               value=ast.parse(f"_hs_m_numpy.empty({rows})", mode="eval").body)
            out = [first, ast.Assign(targets=[ast.Name(id=o, ctx=ast.Store())],
                                     value=ast.Name(id=t.id, ctx=ast.Load()))]
        else:
            out = [ast.Assign(targets=[ast.Name(id=o, ctx=ast.Store())], value=where())]
        checks = [f"{o}.shape[0] != {rows}"]
        text = []
        for i, ((op, _), (slot, vec, _)) in enumerate(zip(terms, hits)):
            _, _, (r, c), off, _ = slot
            v = f"_hs_v{k}_{i}"
            out.append(ast.Assign(targets=[ast.Name(id=v, ctx=ast.Store())],
                                  value=self.visit(vec)))
            checks += [f"{v}.shape[0] != {c}"] + ([f"{r} != {rows}"] if r != rows else [])
            put = "=" if i == 0 and not aug else "-=" if isinstance(op, ast.Sub) else "+="
            text.append(f"for _hs_i in range({r}):\n"
                        f"    _hs_s = 0.0\n"
                        f"    for _hs_k in range({c}):\n"
                        f"        _hs_s += {P}[{off} + _hs_i * {c} + _hs_k] * {v}[_hs_k]\n"
                        f"    {o}[_hs_i] {put} _hs_s\n")
        out += ast.parse(f"if {' or '.join(checks)}:\n"
                         f"    raise ValueError('matmul: the shapes do not match')\n"
                         + "".join(text)).body
        return [_located(st, node) for st in out]

    def visit_AugAssign(self, node):
        self._check_store(node.target)
        into = self._products_into(node)
        if into is not None:
            return into
        v = node.value
        if isinstance(node.op, ast.Add) and isinstance(node.target, ast.Name) and \
                isinstance(v, ast.BinOp) and isinstance(v.op, ast.MatMult):
            hit = self._product(v)
            if hit is not None:                 # y += M @ v: accumulated in y
                target = ast.Name(id=node.target.id, ctx=ast.Load())
                call = self._pmv(*hit, v, target)
                return ast.copy_location(ast.Expr(value=call), node)
        node = self.generic_visit(node)
        if isinstance(node.target, ast.Subscript):     # a[i:j] += v: a[i:j] = a[i:j] + v
            read = copy.deepcopy(node.target)
            read.ctx = ast.Load()
            value = ast.copy_location(ast.BinOp(left=read, op=node.op, right=node.value),
                                      node)
            return self._setitem(node, [node.target], value) or node
        return node

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
                self.pl.layout.require(("none", id(obj), attr), self._reader(obj, attr),
                                       v is None)
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
                                  self._reader(obj, attr))

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
        head = [ast.Name(id=P, ctx=ast.Load()), ast.Constant(off), ast.Constant(r),
                ast.Constant(c)]
        pieces = None if extra else self._concatenated(v)
        if pieces is not None:          # M @ np.concatenate((a, b)): read from the pieces
            return _call(side + "_cat", head + [pieces[0], pieces[1]], like)
        return _call(side + ("_add" if extra else ""), head + [self.visit(v), *extra], like)

    def _concatenated(self, v):
        """``(pieces, axis)`` of ``np.concatenate((a, b, ...), axis=-1)`` (visited;
        axis -1 where not given), or None."""
        if not (isinstance(v, ast.Call) and isinstance(v.func, ast.Attribute)
                and v.func.attr == "concatenate" and len(v.args) == 1
                and isinstance(v.args[0], (ast.Tuple, ast.List))
                and getattr(self._module_of(v.func.value), "__name__", "") == "numpy"):
            return None
        axis = ast.Constant(-1)
        for k in v.keywords:
            if k.arg != "axis" or not isinstance(k.value, (ast.Constant, ast.UnaryOp)):
                return None
            axis = self.visit(k.value)
        return (ast.Tuple(elts=[self.visit(e) for e in v.args[0].elts], ctx=ast.Load()),
                axis)

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
        if isinstance(v, (bool, np.bool_, str)) or _is_int(v):   # a flag, a choice, a size
            self.pl.layout.fold(("self", id(obj), attr), self._reader(obj, attr), v)
            c = v if isinstance(v, str) else int(v) if _is_int(v) else bool(v)
            return ast.copy_location(ast.Constant(c), node)
        if isinstance(v, slice) and all(b is None or _is_int(b)
                                        for b in (v.start, v.stop, v.step)):
            self.pl.layout.fold(("self", id(obj), attr), self._reader(obj, attr), v)
            return ast.copy_location(_call("slice", [ast.Constant(None if b is None else int(b))
                                                     for b in (v.start, v.stop, v.step)],
                                           node), node)
        if _kind(v) is None:
            raise fn.refuse(node, f"it reads {name}, a {type(v).__name__} (not a number "
                                  f"or an array of numbers): numba cannot type it")
        slot = self.pl.layout.add(("self", id(obj), attr), self._name(obj, attr), v,
                                  self._reader(obj, attr))
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
        if _is_int(v) and key[0] in ("global", "cell"):      # a size or an index
            self.pl.layout.fold(key, reader, v)
            return ast.copy_location(ast.Constant(int(v)), node)
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
        if isinstance(f, ast.Attribute) and f.attr in ("swapaxes", "reshape") and args \
                and not kws and self._module_of(f.value) is None:
            # v.swapaxes(a, b) as np.swapaxes (numba has no method); v.reshape(shape) of
            # any layout (numba reshapes C-contiguous arrays only; numpy copies the others)
            v = self.visit(f.value)
            if f.attr == "swapaxes":
                return _call("_hs_m_numpy.swapaxes", [v, *args], node)
            shape = args[0] if len(args) == 1 else ast.Tuple(elts=args, ctx=ast.Load())
            return _call("_hs_reshape", [v, shape], node)
        if isinstance(f, ast.Attribute) and f.attr == "where" and len(args) == 3 \
                and not kws and getattr(self._module_of(f.value), "__name__", "") == "numpy":
            return _call("_hs_where", args, node)      # of numbers: a if c else b
        if isinstance(f, ast.Attribute):
            hit = self._of_numbers(f, node, args, kws)
            if hit is not None:
                return hit
        target = self._super_method(f)
        hit = None if target is not None else self._owner(f)
        if hit is not None:
            target = self._self_method(f, hit[0])
        elif isinstance(f, ast.Name) and f.id not in self.locals:
            v = self._lookup(f.id)[0]
            if isinstance(v, types.FunctionType) and self.pl.dispatcher(v) is None:
                target = _fn_of_plain(v, fn, f)
        if target is not None:
            # the caller's one-state arrays passed by position are one state in the callee
            vecs = tuple(i for i, a in enumerate(node.args) if self._one_state(a)
                         and not isinstance(a, ast.Subscript))
            target = self.pl.follow(target, vectors=vecs)
        if target is None:
            return ast.copy_location(ast.Call(func=self.visit(f), args=args, keywords=kws),
                                     node)
        return ast.copy_location(ast.Call(func=ast.Name(id=target, ctx=ast.Load()),
                                          args=[ast.Name(id=P, ctx=ast.Load()), *args],
                                          keywords=kws), node)

    def _super_method(self, f):
        """``super().name`` in a method: the name of the method that follows the
        method's own class in its object's method resolution order, followed
        (bound to the same object), or None where ``f`` is not such a call."""
        fn = self.fn
        v = f.value if isinstance(f, ast.Attribute) else None
        if not (isinstance(v, ast.Call) and isinstance(v.func, ast.Name)
                and v.func.id == "super" and "super" not in self.locals
                and self._lookup("super")[1] == ("builtin", "super")):
            return None
        if v.args or v.keywords or fn.obj is None:
            raise fn.refuse(f, "super() is followed without arguments, in a method only")
        mro = type(fn.obj).__mro__
        own = [k for k, c in enumerate(mro) if c.__dict__.get(fn.func.__name__) is fn.func]
        found = next((c.__dict__[f.attr] for c in mro[own[0] + 1:] if f.attr in c.__dict__),
                     None) if own else None
        if not isinstance(found, types.FunctionType):
            raise fn.refuse(f, f"super().{f.attr} is not a plain method of a base class")
        return Fn(found, fn.obj, found.__qualname__)

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
            return Fn(func, None, f"{type(obj).__name__}.{f.attr}")
        if isinstance(bound, types.MethodType) and isinstance(bound.__func__,
                                                               types.FunctionType):
            if bound.__self__ is not obj:               # a method of another object, stored
                if static is _MISSING or isinstance(static, types.FunctionType) or \
                        not _is_part(bound.__self__):
                    raise fn.refuse(f, f"{_dotted(f)} is bound to another object")
                self.pl.reusable = False                  # that object: this system's own
                return Fn(bound.__func__, bound.__self__, bound.__func__.__qualname__)
            return Fn(bound.__func__, obj, f"{type(obj).__name__}.{f.attr}")
        if isinstance(bound, types.FunctionType):      # a function stored on the instance
            self.pl.reusable = False
            return Fn(bound, None, f"{type(obj).__name__}.{f.attr}")
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
                         Read(system, "delays", (), then=lambda d: np.asarray(tuple(d),
                                                                              dtype=float)))
    pl.reads_past = rw.reads_past = True
    n = int(system.state_dim)
    return _call("_hs_past", [ast.Name(id=P, ctx=ast.Load()), rw.visit(arg.right),
                              ast.Constant(slot[3]), ast.Constant(len(delays)),
                              ast.Constant(n)], node)


def _fn_of_plain(v, caller, node):
    try:
        return Fn(v, None, v.__qualname__)
    except SourceRefusal as e:
        raise caller.refuse(node, f"it calls {v.__qualname__}, which cannot be followed: "
                                  f"{e.why}") from None
