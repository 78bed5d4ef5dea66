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
  run: changing ``ball.e`` changes the next run; an array's entry at
  constant indices, ``self.M[0, 1]``, is its one slot), ``self.helper(...)``
  and calls of plain functions are followed (rewritten the same way; an
  argument that is the caller's one state is one state there too, so
  ``x[..., k]`` reads ``x[k]``), modules are imported by name. Parts of
  the system are read through: ``self.design.F1``, ``d = self.design``
  then ``d.F1``, ``self.data.flow(...)`` (a method of a part, followed);
  another object in its place rewrites the maps. A bool,
  int or str attribute (or int global) is a constant of the rewrite (a size,
  an index; ``self.mode == "pwc"`` decides
  its branch, the other is dropped), and ``self.slices["x"]`` (a dict read by
  a constant key) its value (a slice as ``a:b``); a change rewrites the maps.
  ``self.a is None`` (``is not None``) is known when
  the maps are rewritten: the test becomes a constant and the branch not
  taken is dropped (the plan is made again where it changes). A product
  ``a @ b`` compiles as loops summing in index order (``_hs_matmul``), and
  one with a matrix the map reads from ``self`` (``self.M @ v``, ``v @
  self.M.T``, ``y += v @ self.M.T``) reads it in place from ``p``
  (:func:`hybridsim.compiled.matvec`; ``self.M @ X`` of a matrix X is M X).
  On one state (the compiled path), ``x[..., k]`` of the map's state or
  input (and of the arrays made from them) is ``x[k]``; a sum of such
  products of one-state vectors assigned to a slice of a new array
  (``dx[..., :n] = x[..., :n] @ self.F.T + u @ self.L.T``) is loops in the
  map writing into it (the same sums, no array a term), one of
  ``np.concatenate((a, b))`` reads the pieces; ``np.where`` of numbers is
  an if/else, ``v.swapaxes``, and ``v.reshape`` of any layout, numpy's.
  numpy's constructors, as a map written along the last axis calls them,
  follow their operands: ``np.stack([...], axis=-1)`` of numbers is a 1-D
  array, ``np.full(e.shape, c)`` (``zeros``, ``ones``, ``empty``, the
  ``np.shape(e)`` form) and ``np.full_like(e, c)`` (the ``_like`` forms)
  of a number ``e`` are numbers, ``np.clip`` and ``.astype`` of numbers
  ``min(max(a, lo), hi)`` and the converted number; of arrays, numpy's
  calls. A plan made once serves every instance of its class (:meth:`Layout.on`).
  A flow, jump or output map whose arrays all have shapes known when it is
  rewritten is then written as straight-line code of numbers, the same
  operations in the same order (:mod:`hybridsim._source_unroll`).
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
import copy
import functools
import inspect
import types

import numpy as np

from ._source_guards import _call, _OwnReturns, derived_guard, guard_refusal
from ._source_read import SourceRefusal, _fn_of
from ._source_rewrite import (
    _MISSING,
    P,
    Read,
    _inline_parts,
    _kind,
    _Rewrite,
    _slot_expr,
)
from ._source_shapes import one_state
from ._source_unroll import unroll

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


class Layout:
    """The named slots of ``p``: ``slots`` a list of ``(name, kind, shape,
    offset, size)``, ``size`` their total. :meth:`read` reads every value
    again (a system's attributes, a closure's numbers, module globals)."""

    def __init__(self):
        self.slots, self.readers, self.size, self._index = [], [], 0, {}
        self.checks = {}            # key -> (reader, whether the value was None)
        self.parts = {}             # key -> (reader, the part of the system followed)
        self.folded = {}            # key -> (reader, the bool, int or str written as a constant)
        self.owner = None           # id of the system the keys' own reads are of

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
        """Record that the rewrite wrote ``reader()`` (a bool, an int or a str) as the
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

    def on(self, system):
        """This layout read from ``system``, another instance of the class it was
        made for (every :class:`Read` of the system's parts read from its parts),
        or None where a part is missing or of another class."""
        def on(rd):
            return rd.on(system) if isinstance(rd, Read) else rd

        def key(k):               # the system's own reads keyed on the new instance
            return (k[0], id(system), *k[2:]) if k[1] == self.owner else k
        new = Layout()
        new.owner = id(system)
        new.slots, new.size = list(self.slots), self.size
        new._index = {key(k): i for k, i in self._index.items()}
        try:
            new.readers = [on(rd) for rd in self.readers]
            new.checks = {key(k): (on(rd), v) for k, (rd, v) in self.checks.items()}
            new.folded = {key(k): (on(rd), v) for k, (rd, v) in self.folded.items()}
            for k, (rd, obj) in self.parts.items():
                rd = on(rd)
                part = rd()
                if type(part) is not type(obj):
                    return None
                new.parts[key(k)] = (rd, part)
        except Exception:  # noqa: BLE001 - a part missing on this instance: its own plan
            return None
        return new


def _default_reader(func, params, name):
    """Reads the current default of parameter ``name`` of ``func``."""
    i = params.index(name)

    def read():
        d = func.__defaults__
        return d[i - (len(params) - len(d))]
    return read


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
        # id(part of the system) -> its attribute path from the system; whether the
        # plan serves every instance of the class (each read a path from the system)
        self.paths, self.reusable = {}, True

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

    def follow(self, fn, role=None, form=None, vectors=()):
        """The generated name of ``fn`` rewritten (once per function, object and
        the positions of its arguments that are one state, ``vectors``)."""
        key = (id(fn.func), id(fn.obj), vectors)
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
        if role is not None:            # one state on the compiled path: x (and u) are 1-D
            state = [own[0]] + ([own[3]] if self.inputs and role != "output" and k >= 4
                                else [])
            body.vectors, body.fresh = one_state(node, state)
        elif vectors:                   # a helper given the caller's one-state arrays
            body.vectors, body.fresh = one_state(node, [args[i] for i in vectors
                                                        if i < len(args)])
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


#: (class, what else a plan depends on) -> the last plan made for an instance of it
_BY_CLASS = {}


def _class_key(system, component):
    """What a plan depends on besides the values its layout reads (the class,
    sizes, delays, which maps are given), or None where the system holds
    functions of its own (its plan is its own)."""
    d = getattr(system, "__dict__", None)
    if d is None or any(isinstance(v, (types.FunctionType, types.MethodType,
                                       functools.partial)) for v in d.values()):
        return None
    try:
        given = tuple(getattr(system, a, None) is None for a in
                      ("jump_guard", "flow_guard", "diffusion", "jump_rate", "watch"))
        return (type(system), bool(component), int(system.state_dim), system.input_dim,
                bool(system.needs_history), tuple(system.delays or ()), given)
    except Exception:  # noqa: BLE001 - unhashable or missing: no shared plan
        return None


def plan(system, component=False):
    """The :class:`Plan` of ``system``'s maps as functions of ``(x, t, j, p)``
    (``component``: of ``(x, u, t, j, p)``, and its output of ``(x, t, j,
    p)``, for a part of an interconnection); a :class:`SourceRefusal` naming
    the method and line otherwise.

    Another instance of a class planned before takes that plan, its layout
    read from its own parts (:meth:`Layout.on`), where every value keeps its
    kind and shape and every constant of the rewrite its value (else its own
    plan is made): a batch of new systems rewrites nothing."""
    key = _class_key(system, component)
    hit = _BY_CLASS.get(key) if key is not None else None
    if hit is not None:
        layout = hit.layout.on(system)
        if layout is not None and layout.read() is not None:
            out = Plan(hit.source, hit.roles, layout, hit.dispatchers, hit.lines,
                       hit.qualnames)
            out.reads_past = hit.reads_past
            return out
    out = _plan(system, component)
    if key is not None and out.reusable:
        if len(_BY_CLASS) > 256:
            _BY_CLASS.clear()
        _BY_CLASS[key] = out
    return out


def _plan(system, component):
    pl = _Planner()
    pl.inputs = bool(component)
    pl.system = system
    pl.layout.owner = id(system)
    pl.paths[id(system)] = ()
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
    _unrolled(pl, roles, system)
    out = _assemble(pl, roles, f"the maps of {cls}, rewritten as functions of (x, t, j, p)")
    out.reads_past = pl.reads_past         # its flow reads x(t - tau_i): delays on the kernel
    out.reusable = pl.reusable
    return out


#: the roles written as straight-line code where every array's shape is known
_UNROLLED = ("flow", "jump", "output")


def _unrolled(pl, roles, system):
    """The maps of ``roles`` among the planner's functions replaced by their
    straight-line form (:func:`hybridsim._source_unroll.unroll`) where they
    have one: x of length ``state_dim``, a component's u of ``input_dim``.

    A plain model's flow and jump maps (not a component's, the flow not
    reading the past, called by no other generated function) are written into
    an argument, ``f(x, t, j, p, out)``: the compiled steps call the flow into
    their own rows, a rate system's clock-augmented jump map the jump into its
    own array (:attr:`hybridsim.compiled.CompiledSystem.maps_into`), no array
    made a call."""
    names = {name: role for role, name in roles.items() if role in _UNROLLED}
    functions = {name: node for name, node, _ in pl.functions}
    called = {n.id for name, node, _ in pl.functions for n in ast.walk(node)
              if isinstance(n, ast.Name) and n.id in functions and n.id != name}
    for k, (name, node, fn) in enumerate(pl.functions):
        role = names.get(name)
        if role is None:
            continue
        args = [a.arg for a in node.args.args]
        shapes = {args[0]: int(system.state_dim)}
        if pl.inputs and role != "output" and system.input_dim:
            shapes[args[1]] = int(system.input_dim)
        into = role in ("flow", "jump") and not pl.inputs and name not in called and not (
            role == "flow" and pl.reads_past)
        new = unroll(node, functions, shapes, into=into)
        if new is not None:
            pl.functions[k] = (name, new, fn)


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
