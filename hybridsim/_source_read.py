"""The user's maps as source, read: :class:`SourceRefusal` (a map that cannot
be rewritten, naming its method and line), the function's own node in its
file (a lambda as one, cached per code object) and :class:`Fn`, one
function's node, globals, closure and bound object. Used by
:mod:`hybridsim._source`, which re-exports the names other modules import
from it.
"""
from __future__ import annotations

import ast
import copy
import hashlib
import linecache
import types


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
