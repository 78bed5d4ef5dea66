"""Lowering: ordinary hybrid systems onto the compiled path.

``simulate(system, ..., backend="compiled")`` runs a
:class:`~hybridsim.compiled.CompiledSystem` as it is; any other system is
*lowered* to one first, from the compiled forms of its parts:

* a system with a ``compiled_component()`` method (a
  :class:`Component`: its maps written for numba as functions of
  ``(x, u, t, j, p)``, its output of ``(x, t, j, p)``), as the observers
  of the papers that run compiled have; a :class:`hybridsim.LinearPlant`
  and a plain part have theirs rewritten from their own maps;
* a :class:`~hybridsim.compiled.CompiledSystem` (maps of ``(x, t, j, p)``);
* an :class:`hybridsim.Interconnection` (a cascade from :func:`hybridsim.connect`,
  a network from :func:`hybridsim.network`) of such parts whose inputs are
  :class:`hybridsim.LinearInput` wirings: the stacked maps are generated as
  Python source that calls each part's compiled maps on its slice of the
  state, with the interconnection's rules (C where every part is in its C;
  D where some part is in its D; at a jump every part in its D jumps, from
  the pre-jump outputs; the jump guard the largest of the parts', the flow
  guard the smallest).

Everything numeric (the parts' parameters, the wiring matrices) goes in the
lowered system's parameter array, so the generated maps depend only on the
structure (the parts' map functions and dimensions): a second system of the
same structure reuses the compiled maps of the first (in the process).

A part whose flow map reads its own past state x(t - tau) (a delay equation:
the Gramian observer (39) of Mazenc-Malisoff) declares its delays in its
:class:`Component` (``delays=``): its flow map then receives its parameters
followed by its own state at t - tau_i for each of them, and the lowered
system reads its past through :class:`~hybridsim.compiled.CompiledSystem`'s
``delays`` (the sorted union of the parts'; see there for the rules of the
past). A plain part reading ``self.history(t - tau)`` in its flow map, its
lags declared in ``self.delays``, has those reads rewritten into the same
reads of its past (:mod:`hybridsim.compiled._from_source`).

A plain model (a single system with no compiled form: README's
``BouncingBall`` class, a ``from_functions`` system) is lowered from its
own maps, rewritten from their source as functions of ``(x, t, j, p)``
(:mod:`hybridsim.compiled._from_source`; its ``p`` is read again before
every run). As a part of an interconnection (and a
:class:`hybridsim.LinearPlant` always) its maps are rewritten the same way
as functions of ``(x, u, t, j, p)``, its output of ``(x, t, j, p)``: its
:class:`Component` (:func:`source_component`).

What cannot be lowered is refused by name: a part without a compiled form,
an input given as a Python callable, a part reading its history without
declaring the delays it reads, a plain model's map that cannot be rewritten
(the method and its line).
"""
from __future__ import annotations

import functools
import math
import types

import numpy as np

from ..compose import Interconnection, LinearInput, LinearPlant
from ..options import check_delay_times
from ..system import HybridSystem, renamed_keywords
from . import _from_source
from ._from_source import _helpers, _numba
from ._system import KEYWORDS, RENAMES, CompiledSystem, _load_kernel, _refuse, keywords

__all__ = ["Component", "Lowerable", "lower", "lowerable", "matvec", "rebind", "rebind_all"]

_ROLES = ("flow", "jump", "jump_guard", "flow_guard", "jump_set", "flow_set")


class Component:
    r"""The compiled form of a hybrid system with an input: what
    ``system.compiled_component()`` returns.

    Each map is a function ``fn(x, u, t, j, p)`` numba can compile in
    nopython mode (``x`` the part's state, ``u`` its input: a float64 array,
    empty when ``input_dim`` is 0, ``p`` :attr:`params`); ``output(x, t, j,
    p)`` is its output (default: the state). The sets follow
    :class:`~hybridsim.compiled.CompiledSystem`: an indicator decides
    membership where given, else the set is ``{guard >= 0}``.

    Parameters
    ----------
    state_dim, input_dim : int
    flow_map : callable, optional
        Absent: the state is constant (x' = 0), as in a noise generator
        whose state is its realisation.
    jump_map, jump_guard, flow_guard, jump_set, flow_set, output : callable, optional
    output_dim : int, optional
        Required with ``output``.
    params : array_like
        Floats passed as ``p`` (put matrices here, flattened: the compiled
        maps then serve every system of the same dimensions).
    delays : tuple of float, optional
        The delays tau_1, ..., tau_m (positive, distinct) at which the flow
        map reads the component's own past state. Its ``p`` is then
        ``params`` followed by x(t - tau_i) for each i: ``p[len(params) +
        i*n : len(params) + (i+1)*n]`` (n = ``state_dim``), with the rules of
        :class:`hybridsim.History` (constant x0 before t0, the post-jump
        value at a jump time), the convention of
        :class:`~hybridsim.compiled.CompiledSystem`'s ``delays``. The other
        maps receive ``params`` alone: they must not read the past.
    **deprecated
        The former names ``flow`` and ``jump`` of ``flow_map`` and
        ``jump_map``: accepted with a ``DeprecationWarning``.

    Attributes
    ----------
    maps : dict
        The maps given, by role (``"flow"``, ``"jump"``, ``"jump_guard"``...,
        as :attr:`CompiledSystem.maps`).

    Examples
    --------
    >>> import numpy as np
    >>> from hybridsim.compiled import Component
    >>> def flow(x, u, t, j, p):                 # x' = -p0 x + u
    ...     return -p[0] * x + u
    >>> c = Component(state_dim=1, input_dim=1, flow_map=flow, params=[2.0])
    >>> c.maps["flow"](np.ones(1), np.zeros(1), 0.0, 0, c.params)
    array([-2.])
    """

    __slots__ = ("state_dim", "input_dim", "output_dim", "maps", "output", "params",
                 "delays")

    def __init__(self, *, state_dim, flow_map=None, input_dim=0, jump_map=None,
                 jump_guard=None, flow_guard=None, jump_set=None, flow_set=None, output=None,
                 output_dim=None, params=(), delays=(), **deprecated):
        if deprecated:
            given = renamed_keywords("Component", deprecated, RENAMES,
                                     {"flow_map": flow_map, "jump_map": jump_map})
            flow_map, jump_map = given["flow_map"], given["jump_map"]
        for name, v in (("state_dim", state_dim), ("input_dim", input_dim)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ValueError(f"{name} must be an int >= 0, got {v!r}")
        if state_dim < 1:
            raise ValueError(f"state_dim must be a positive int, got {state_dim!r}")
        self.state_dim, self.input_dim = int(state_dim), int(input_dim)
        self.maps = {}
        for role, fn in zip(_ROLES, (flow_map, jump_map, jump_guard, flow_guard, jump_set,
                                     flow_set)):
            if fn is None:
                continue
            if not callable(fn):
                raise TypeError(f"{KEYWORDS[role]} must be callable fn(x, u, t, j, p), got "
                                f"{type(fn).__name__}")
            self.maps[role] = fn
        if output is not None and not callable(output):
            raise TypeError(f"output must be callable fn(x, t, j, p), got {type(output).__name__}")
        if output is not None and output_dim is None:
            raise ValueError("output_dim is required with output")
        self.output = output
        self.output_dim = int(state_dim if output is None else output_dim)
        try:
            p = np.array(params, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError) as e:
            raise TypeError(f"params must be an array of floats, got "
                            f"{type(params).__name__}") from e
        if not np.all(np.isfinite(p)):
            raise ValueError(f"params must be finite, got {p[~np.isfinite(p)][:3]} among them")
        self.params = np.ascontiguousarray(p)
        self.delays = check_delay_times(delays)
        if self.delays and "flow" not in self.maps:
            raise ValueError("delays are read by the flow map: a component with delays "
                             "needs flow_map")

    @property
    def has_D(self):
        return "jump_set" in self.maps or "jump_guard" in self.maps

    @property
    def has_C(self):
        return "flow_set" in self.maps or "flow_guard" in self.maps


# ------------------------------------------------------------------ compiled helpers
def matvec(p, off, rows, cols, v):
    """``M @ v`` with M (rows, cols) stored row-major in the flat array ``p``
    from index ``off``: the matrix product of compiled maps that read their
    matrices from their parameters (compiled code; in Python, a plain loop).

    Examples
    --------
    >>> import numpy as np
    >>> from hybridsim.compiled import matvec
    >>> matvec(np.array([9.0, 1.0, 2.0, 3.0, 4.0]), 1, 2, 2, np.array([1.0, 1.0]))
    array([3., 7.])
    """
    M = np.asarray(p[off:off + rows * cols]).reshape(rows, cols)
    return M @ np.asarray(v, dtype=float)


def compiled_matvec():
    """The numba-compiled :func:`matvec` (for maps of compiled components)."""
    return _helpers()["matvec"]


_JITTED = {}


def _jit(fn):
    """``fn`` as a numba dispatcher (one per function object in the process).

    Plain Python functions ``fn`` closes over (helpers defined beside it in a
    factory) are compiled with it: the function is rebuilt with their
    dispatchers in its closure. Helpers at module level must be numba
    functions already."""
    numba = _numba()
    if isinstance(fn, numba.core.dispatcher.Dispatcher):
        return fn
    key = id(fn)
    hit = _JITTED.get(key)
    if hit is not None and hit[0] is fn:
        return hit[1]
    target = fn
    cells = getattr(fn, "__closure__", None) or ()
    if any(isinstance(c.cell_contents, types.FunctionType) for c in cells
           if _filled(c)):
        new = tuple(types.CellType(_jit(c.cell_contents))
                    if _filled(c) and isinstance(c.cell_contents, types.FunctionType)
                    else c for c in cells)
        target = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__,
                                    fn.__defaults__, new)
    d = numba.njit(error_model="numpy")(target)
    _JITTED[key] = (fn, d)
    return d


def _filled(cell):
    try:
        _ = cell.cell_contents
    except ValueError:          # an empty cell
        return False
    return True


# ------------------------------------------------------------------ the parts
class _Part:
    """One part of a lowered system: its component, slices, wiring."""

    def __init__(self, name, comp, xs, ps):
        self.name, self.comp, self.xs, self.ps = name, comp, xs, ps
        self.terms = []          # [(source index, None | (off, rows, cols))]
        self.past = ()           # where each of the part's delays is in the system's


def _refusal(system, what, wired=None):
    """Why ``system`` cannot be lowered, as the TypeError to raise, or None.

    Every check that needs no compiling (numba need not be installed): the one
    list :func:`lower` raises from and :func:`lowerable` reads. ``wired``: for
    a component of an interconnection, ``(its name, its input's wiring)``."""
    if isinstance(system, CompiledSystem):
        return None
    form = _compiled_form(system, wired is not None)
    source = getattr(form, "func", None) is source_component    # its own maps, rewritten
    # a plain model's self.history(t - tau) is rewritten, at the delays it declares
    plain = source or (form is None and wired is None and _from_source.applies(system))
    if _reads_history(system) and (form is None or source) and not (
            plain and tuple(system.delays or ())):
        return _refuse(what, f"it reads its history (x(t - tau)) and {type(system).__name__} "
                             f"has no compiled form declaring the delays it reads "
                             f"(self.delays for its flow map's self.history(t - tau), or a "
                             f"compiled_component() returning a Component(delays=...))")
    if getattr(system, "set_valued", False):
        return _refuse(what, "its jump map is set-valued (jump_map_values): a run takes one "
                             "successor; hs.explore follows every one (its levels run as "
                             "compiled batches)")
    if system._compile().h_u:
        return _refuse(what, "its output reads its input (direct feedthrough, "
                             "output(x, t, j, u)); a compiled output is a function of "
                             "(x, t, j, p)")
    if isinstance(system, LinearPlant) and not system.vectorized:
        return _plant_refusal(system, what)
    why = getattr(system, "compiled_refusal", None)
    why = why() if callable(why) else None
    if why:                 # the system's own reason (a callable of t it cannot compile)
        return _refuse(what, why)
    if form is None:
        if wired is None and _from_source.applies(system):
            # a plain model: its own maps, rewritten (hybridsim.compiled._from_source)
            if int(system.input_dim or 0):
                return _refuse(what, _from_source._text(
                    system, f"it has an input (input_dim={system.input_dim}); connect it "
                            f"in an Interconnection with a LinearInput"))
            why = _from_source.refusal(system)
            return None if why is None else _refuse(what, _from_source._text(system, why))
        return _refuse(what, f"{type(system).__name__} has no compiled form (a "
                             f"compiled_component() method returning a "
                             f"hybridsim.compiled.Component)")
    if source:
        why = _from_source.component_refusal(system)
        if why is not None:
            return _refuse(what, _from_source._text(system, why))
    if int(system.input_dim or 0):
        if wired is None:
            return _refuse(what, f"it has an input (input_dim={system.input_dim}); connect "
                                 f"it in an Interconnection with a LinearInput")
        name, wiring = wired
        if not isinstance(wiring, LinearInput):
            return _refuse(f"the input of component {name!r}",
                           f"it is a Python callable ({type(wiring).__name__}); wire it with "
                           f"hybridsim.LinearInput ({{source: matrix}}), which every path runs")
    return None


def _compiled_form(system, wired=False):
    """The system's ``compiled_component`` (a callable returning its
    :class:`Component`), or None. A :class:`hybridsim.LinearPlant` (and a
    plain model that is a part of an interconnection, ``wired``) has its own maps
    rewritten from source (:func:`source_component`)."""
    form = getattr(system, "compiled_component", None)
    if form is None and (isinstance(system, LinearPlant) or (
            wired and _from_source.applies(system))):
        form = functools.partial(source_component, system)
    return form


def source_component(system):
    """The :class:`Component` of a plain system (a :class:`hybridsim.LinearPlant`,
    or a plain part of an interconnection): its own maps rewritten as
    functions of ``(x, u, t, j, p)`` (:mod:`hybridsim.compiled._from_source`),
    the numbers they read in ``p``."""
    if isinstance(system, LinearPlant) and not system.vectorized:
        raise _plant_refusal(system, "LinearPlant")
    maps, output, p, delays = _from_source.component_maps(system)
    n, m = int(system.state_dim), int(system.input_dim or 0)
    q = None
    if output is not None:
        from .._compose_network import _output_dim
        q = _output_dim(system)
    return Component(state_dim=n, input_dim=m, output=output, output_dim=q, params=p,
                     delays=delays, **keywords(maps))


def _reads_history(system):
    return bool(system.needs_history or tuple(system.delays or ()))


def _plant_refusal(plant, what):
    which = [nm for nm in ("u", "noise", "disturbance") if getattr(plant, nm) is not None]
    return _refuse(what, f"its {', '.join(which)} is a Python callable of t; put the "
                         f"signal in a component's state (a generator with a compiled "
                         f"form) and wire it in")


def _component_of(system, what, wired=None):
    """The :class:`Component` of a non-interconnection system, or a refusal."""
    refusal = _refusal(system, what, wired)
    if refusal is not None:
        raise refusal
    if isinstance(system, CompiledSystem):
        return _from_compiled_system(system)
    comp = _compiled_form(system, wired is not None)()
    if not isinstance(comp, Component):
        raise TypeError(f"{what}: compiled_component() must return a "
                        f"hybridsim.compiled.Component, got {type(comp).__name__}")
    n, m = int(system.state_dim), int(system.input_dim or 0)
    if comp.state_dim != n or comp.input_dim != m:
        raise ValueError(f"{what}: compiled_component() has state_dim={comp.state_dim}, "
                         f"input_dim={comp.input_dim}; the system has {n}, {m}")
    if _reads_history(system) and not comp.delays:
        raise _refuse(what, "it reads its history (x(t - tau)) but its compiled form "
                            "declares no delays (Component(delays=...))")
    return comp


@functools.cache
def _adapter(fn):
    """A map of ``(x, t, j, p)`` as one of ``(x, u, t, j, p)``."""
    f = _jit(fn)

    def a(x, u, t, j, p):
        return f(x, t, j, p)
    a._adapted = True
    return a


def _from_compiled_system(cs):
    # a CompiledSystem's flow reads its past as a Component's does: params, then x(t - tau_i)
    return Component(state_dim=cs.state_dim, params=cs.params,
                     delays=tuple(getattr(cs, "delays", None) or ()),
                     **keywords({r: _adapter(fn) for r, fn in cs.maps.items()}))


# ------------------------------------------------------------------ code generation
def _reads_input(fn):
    """Whether a map ``fn(x, u, t, j, p)`` reads its ``u`` (its second argument):
    maps that do not are called without computing the input (guards and sets
    of an observer usually read its own state only)."""
    import dis
    fn = getattr(fn, "py_func", fn)
    code = getattr(fn, "__code__", None)
    if code is None or code.co_argcount < 2:
        return True
    name = code.co_varnames[1]
    if name in code.co_cellvars:
        return True
    for ins in dis.get_instructions(code):
        if ins.opname.startswith(("LOAD_FAST", "DELETE_FAST", "STORE_FAST")):
            v = ins.argval
            if v == name or (isinstance(v, tuple) and name in v):
                return True
    return False


def _generate(parts, n, npar=0):
    """Python source of the stacked maps of ``parts`` and the roles present.

    ``npar``: the length of the system's parameters, after which the flow map
    reads the past state x(t - tau_i), n floats per delay of the system."""
    lines = []
    P = range(len(parts))

    def flow_params(k):
        """Statements building part k's flow parameters: its own, then its slice
        of x(t - tau_i) for each of its delays (:class:`Component`)."""
        part = parts[k]
        a, b, nk = part.ps.start, part.ps.stop, part.comp.state_dim
        st = [f"    p{k} = np.empty({b - a + nk * len(part.past)})",
              f"    put(p{k}, 0, {b - a}, p[{a}:{b}])"]
        for i, g in enumerate(part.past):
            src = npar + g * n + part.xs.start
            dst = b - a + i * nk
            st.append(f"    put(p{k}, {dst}, {dst + nk}, p[{src}:{src + nk}])")
        return st

    def needed(ks, roles):
        """Statements computing the inputs of parts ``ks`` whose maps ``roles``
        read them (and the outputs those inputs read)."""
        ks = [k for k in ks if parts[k].terms and any(
            _reads_input(parts[k].comp.maps[r]) for r in roles if r in parts[k].comp.maps)]
        outs = sorted({s for k in ks for s, _ in parts[k].terms})
        st = [f"    y{s} = {_out_expr(parts[s], s)}" for s in outs]
        # the inputs that are sums: slices of one zeroed array (an array an
        # input was a fifth of the ring of 8's flow map)
        summed = [k for k in ks if not (len(parts[k].terms) == 1
                                        and parts[k].terms[0][1] is None)]
        if summed:
            st.append(f"    U = np.zeros({sum(parts[k].comp.input_dim for k in summed)})")
        at = 0
        for k in ks:
            terms = parts[k].terms
            if k not in summed:
                st.append(f"    u{k} = y{terms[0][0]}")      # its source's output itself
                continue
            m = parts[k].comp.input_dim
            st.append(f"    u{k} = U[{at}:{at + m}]")
            at += m
            for s, mat in terms:
                if mat is None:
                    st.append(f"    add_into(u{k}, y{s})")
                elif mat[0] == "sel":               # a selection matrix: copies, no products
                    st += [f"    u{k}[{i}] += y{s}[{c}]" for i, c in mat[2]]
                else:
                    st.append(f"    matvec_add(p, {mat[0]}, {mat[1]}, {mat[2]}, y{s}, u{k})")
        return st

    def head(name, ks, roles):
        st = [f"def {name}(x, t, j, p):"]
        st += [f"    x{k} = x[{parts[k].xs.start}:{parts[k].xs.stop}]" for k in P]
        for k in P:
            if name == "flow" and parts[k].past:
                st += flow_params(k)
            else:
                st.append(f"    p{k} = p[{parts[k].ps.start}:{parts[k].ps.stop}]")
        st += needed(ks, roles)
        return st

    def u(k, role=None):
        c = parts[k].comp
        if not parts[k].terms or (role is not None and role in c.maps
                                  and not _reads_input(c.maps[role])):
            return "NOU"
        return f"u{k}"

    def in_set(k, which):
        c = parts[k].comp
        ind, guard = ("jump_set", "jump_guard") if which == "D" else ("flow_set", "flow_guard")
        if ind in c.maps:
            return f"as_bool({ind}{k}(x{k}, {u(k, ind)}, t, j, p{k}))"
        return f"as_scalar({guard}{k}(x{k}, {u(k, guard)}, t, j, p{k})) >= 0.0"

    roles = {"flow"}

    def guard(role, ks, start, op):
        """The stacked guard of parts ``ks``, where each of them has one."""
        if not all(role in parts[k].comp.maps for k in ks):
            return
        roles.add(role)
        lines.extend(head(role, ks, (role,)))
        lines.append(f"    h = {start}")
        lines.extend(f"    h = {op}(h, as_scalar({role}{k}(x{k}, {u(k, role)}, t, j, p{k})))"
                     for k in ks)
        lines.extend(["    return h", ""])

    lines += head("flow", list(P), ("flow",))
    lines.append(f"    out = np.empty({n})")
    for k in P:
        sl = parts[k].xs
        if "flow" not in parts[k].comp.maps:
            lines.append(f"    out[{sl.start}:{sl.stop}] = 0.0")
            continue
        lines.append(f"    put(out, {sl.start}, {sl.stop}, "
                     f"as_vec(flow{k}(x{k}, {u(k, 'flow')}, t, j, p{k})))")
    lines += ["    return out", ""]
    D = [k for k in P if parts[k].comp.has_D]
    C = [k for k in P if parts[k].comp.has_C]
    if D:
        roles |= {"jump", "jump_set"}
        lines += head("jump", D, ("jump", "jump_set", "jump_guard"))
        lines.append("    out = x.copy()")
        for k in D:
            sl = parts[k].xs
            lines.append(f"    if {in_set(k, 'D')}:")
            lines.append(f"        put(out, {sl.start}, {sl.stop}, "
                         f"as_vec(jump{k}(x{k}, {u(k, 'jump')}, t, j, p{k})))")
        lines += ["    return out", ""]
        lines += head("jump_set", D, ("jump_set", "jump_guard"))
        lines += ["    return " + " or ".join(f"({in_set(k, 'D')})" for k in D), ""]
        guard("jump_guard", D, "-np.inf", "max")       # D is a union: the largest guard
    if C:
        roles.add("flow_set")
        lines += head("flow_set", C, ("flow_set", "flow_guard"))
        lines += ["    return " + " and ".join(f"({in_set(k, 'C')})" for k in C), ""]
        guard("flow_guard", C, "np.inf", "min")        # C an intersection: the smallest
    return "\n".join(lines), roles


def _out_expr(part, k):
    if part.comp.output is None:
        return f"x{k}.copy()"
    return f"as_vec(output{k}(x{k}, t, j, p{k}))"


def _structure(parts):
    """The key of the generated maps: what they call and the dimensions."""
    return tuple((tuple(sorted((r, id(f)) for r, f in p.comp.maps.items())),
                  id(p.comp.output), p.xs.start, p.xs.stop, p.ps.start, p.ps.stop,
                  tuple(p.terms), p.past) for p in parts)


_LOWERED = {}


def _lowered_namespace(k, src, ns, name):
    """The generated maps ``src`` run with the names ``ns``: in a generated module
    named by the digest of the text and of every part's maps
    (:func:`~hybridsim.compiled._cache.keyed_module`), so the engine's
    wrappers of the lowered maps are cached on disk with them (a module with a
    file: numba's cache imports it when it loads); in memory where a part's map
    cannot be keyed or no folder is private."""
    mod = k.keyed_module("lowered", src, ns, lambda: ns)
    if mod is None:
        exec(compile(src, f"<lowered {name}>", "exec"), ns)
        return ns
    return mod.__dict__


def _build(parts, n, pvec, name, specialize, delays=()):
    """The lowered :class:`CompiledSystem` (maps shared by structure; ``delays``
    the system's, the sorted union of its parts')."""
    key = (_structure(parts), n, len(pvec), specialize, len(delays))
    proto = _LOWERED.get(key)
    if proto is None:
        k = _load_kernel()
        src, roles = _generate(parts, n, len(pvec))
        ns = {"np": np, "math": math, "as_vec": k.as_vec, "as_scalar": k.as_scalar,
              "as_bool": k.as_bool, "matvec": compiled_matvec(),
              "matvec_add": _helpers()["matvec_add"], "put": _helpers()["put"],
              "add_into": _helpers()["add_into"],
              "NOU": np.zeros(0)}
        for i, p in enumerate(parts):
            for r, f in p.comp.maps.items():
                ns[f"{r}{i}"] = _jit(f)
            if p.comp.output is not None:
                ns[f"output{i}"] = _jit(p.comp.output)
        ns = _lowered_namespace(k, src, ns, name)
        maps = {r: ns[r] for r in roles}
        past = {"delays": delays} if delays else {}
        proto = CompiledSystem(**keywords(maps), state_dim=n, params=pvec,
                               name=f"lowered {name}",
                               specialize=specialize, **past)
        proto._source = src
        proto.compile()
        _LOWERED[key] = proto
    # a new system of the same structure: the prototype's compiled maps, its own
    # parameters (copy.copy would drop the compiled maps, see __getstate__)
    cs = object.__new__(CompiledSystem)
    cs.__dict__.update(proto.__dict__)
    cs.params = pvec
    if delays:                  # the same structure reads its past at this system's delays
        cs.delays = delays
        cs.max_step = min(delays)       # the prototype's is its own delays' (lower caps it)
    for attr in ("flow_map", "jump_map", "jump_guard", "flow_guard", "jump_set", "flow_set"):
        m = cs.__dict__.get(attr)
        if m is not None:
            cs.__dict__[attr] = type(m)(m.fn, cs)
    return cs


def _is_selection(M):
    """Every entry 0 or 1, at most one 1 a row: ``M @ y`` only copies entries."""
    return bool(np.all((M == 0.0) | (M == 1.0)) and np.all(M.sum(axis=1) <= 1.0))


def _parts_of(system):
    """The :class:`_Part` list and the parameter vector of a system."""
    if isinstance(system, Interconnection):
        names = list(system.systems)
        comps = [_component_of(s, f"component {nm!r} ({type(s).__name__})",
                               (nm, system.inputs.get(nm)))
                 for nm, s in system.systems.items()]
    else:
        names = [None]
        comps = [_component_of(system, f"{type(system).__name__}")]
    parts, pv, xo, po = [], [], 0, 0
    for nm, c in zip(names, comps):
        parts.append(_Part(nm, c, slice(xo, xo + c.state_dim), slice(po, po + c.params.size)))
        pv.append(c.params)
        xo += c.state_dim
        po += c.params.size
    if isinstance(system, Interconnection):
        index = {nm: i for i, nm in enumerate(names)}
        for i, nm in enumerate(names):
            c = comps[i]
            if c.input_dim == 0:
                continue
            w = system.inputs[nm]            # a LinearInput (_refusal)
            m = w.input_dim({s: comps[index[s]].output_dim for s in w.terms})
            if m != c.input_dim:
                raise ValueError(f"component {nm!r}: its LinearInput gives an input of "
                                 f"dimension {m}, its input_dim is {c.input_dim}")
            for s, M in w.terms.items():
                if M is None:
                    parts[i].terms.append((index[s], None))
                elif _is_selection(M):
                    pairs = tuple((int(r), int(c)) for r, c in zip(*np.nonzero(M)))
                    parts[i].terms.append((index[s], ("sel", M.shape, pairs)))
                else:
                    parts[i].terms.append((index[s], (po, M.shape[0], M.shape[1])))
                    pv.append(np.ascontiguousarray(M, dtype=np.float64).reshape(-1))
                    po += M.size
    n = xo
    pvec = np.concatenate(pv) if pv else np.zeros(0)
    delays = tuple(sorted({d for c in comps for d in c.delays}))
    for part in parts:
        part.past = tuple(delays.index(d) for d in part.comp.delays)
    return parts, n, pvec, delays


def lower(system, *, specialize=None):
    """The :class:`~hybridsim.compiled.CompiledSystem` that runs ``system`` compiled.

    A :class:`~hybridsim.compiled.CompiledSystem` is returned as it is; a
    system with a compiled form, or an interconnection of such systems wired
    by :class:`hybridsim.LinearInput`, is lowered (module notes); a plain
    model is lowered from its own maps, rewritten from source (its numbers
    and arrays read into ``p`` at each call). The result
    is cached on the system (``simulate(system, backend="compiled")`` then
    runs it), and dropped when the system is pickled.

    Parameters
    ----------
    system : HybridSystem
    specialize : bool, optional
        False (the default when lowering): the maps reach the engine's cached
        kernel by address; they compile in each process (2-8 s for the
        papers' observers). True: a kernel with the maps compiled in, cached
        on disk by the structure's digest (about 15 s once per machine and
        structure, then well under a second in a new process, and 10-20%
        faster per run): for Monte Carlo studies run again and again. None
        keeps what the system was lowered with.

    Returns
    -------
    CompiledSystem
        Its state is the system's (an interconnection's stacked state); its
        ``delays`` the sorted union of the parts' (:class:`Component`).

    Raises
    ------
    TypeError
        A part without a compiled form, an input that is a Python callable,
        a part reading its history whose compiled form declares no delays,
        or a plain model's map that cannot be rewritten (a Python object
        numba cannot type, global state, random draws): the message names
        it (for a map, its method and line). numba's own refusal of a
        rewritten map is a :class:`~hybridsim.compiled.CompileError` naming
        the method and line.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> from hybridsim.compiled import lower
    >>> plant = hs.LinearPlant([[0.0, 1.0], [-1.0, 0.0]], C=[[1.0, 0.0]])
    >>> lower(plant).state_dim
    2
    """
    if "_source_plan" in getattr(system, "__dict__", ()) and (
            specialize is None or isinstance(specialize, bool)):
        hit = _from_source.cached(system)       # a plain model run before: nothing changed
        if hit is not None and (specialize is None or hit.specialize == specialize):
            return hit
    if isinstance(system, CompiledSystem):
        return system
    if not isinstance(system, HybridSystem):
        raise TypeError(f"system must be a hybridsim.HybridSystem, got {type(system).__name__}")
    if specialize is not None and not isinstance(specialize, (bool, np.bool_)):
        raise TypeError(f"specialize must be True, False or None, got {specialize!r}")
    if _compiled_form(system) is None and _from_source.applies(system):   # a plain model
        why = _refusal(system, type(system).__name__)
        if why is not None:
            raise why
        return _from_source.lower_source(system, specialize)
    # the parts' parameters are read again at every call (their attributes may have
    # changed since the last run); the maps are built again only where the
    # structure changed
    parts, n, pvec, delays = _parts_of(system)
    key = (_structure(parts), n, len(pvec), delays)
    cached = system.__dict__.get("_lowered")
    if cached is not None and (specialize is None or cached.specialize == bool(specialize)) \
            and cached.__dict__.get("_lowered_key") == key:
        if not np.array_equal(cached.params, pvec):
            cached.params = pvec
        return cached
    if specialize is None and cached is not None:
        specialize = cached.specialize
    _check_shapes(parts, pvec)
    try:
        cs = _build(parts, n, pvec, type(system).__name__, bool(specialize), delays)
    except TypeError as e:          # numba's refusal of a rewritten part: its method and line
        err = _source_error(system, e)
        if err is None:
            raise
        raise err from e
    if system.max_step is not None:      # with delays, at most the smallest (CompiledSystem)
        cs.max_step = min([float(system.max_step), *delays])
    cs.__dict__["_lowered_key"] = key
    system.__dict__["_lowered"] = cs
    return cs


def _source_error(system, e):
    """The CompileError naming a part's own method and line, where numba's
    refusal ``e`` lies in a part rewritten from source; else None."""
    subs = system.systems.values() if isinstance(system, Interconnection) else (system,)
    for s in subs:
        hit = s.__dict__.get("_source_component")
        if hit is not None and not isinstance(hit[1], _from_source._source.SourceRefusal):
            cause = e.__cause__ if e.__cause__ is not None else e
            if f"hybridsim_src_{_from_source._digest(hit[1])}" not in str(cause):
                continue            # another part's module
            err = _from_source._compile_error(s, hit[1], e)
            if err.where is not None:
                return err
    return None


def _check_shapes(parts, pvec):
    """Call each part's maps once in Python at x = 0 and check their shapes, so a
    wrong size is named here rather than corrupting memory in compiled code."""
    for part in parts:
        c, what = part.comp, (f"component {part.name!r}" if part.name is not None
                              else "the system")
        x = np.zeros(c.state_dim)
        u = np.zeros(c.input_dim)
        p = pvec[part.ps]
        for role, want in (("flow", c.state_dim), ("jump", c.state_dim)):
            if role not in c.maps:
                continue
            fn = c.maps.get(role)
            if fn is None or getattr(fn, "_adapted", False):
                continue
            pr = p                  # the flow reads the past after its params: x0 = 0 here
            if role == "flow" and c.delays:
                pr = np.concatenate([p, np.zeros(c.state_dim * len(c.delays))])
            v = _probe(getattr(fn, "py_func", fn), x, u, pr)
            if v is not None and np.shape(v) != (want,):
                raise ValueError(f"{what}: its compiled {role} map returns shape "
                                 f"{np.shape(v)}, expected ({want},)")
        if c.output is not None:
            v = _probe(getattr(c.output, "py_func", c.output), x, None, p)
            if v is not None and np.shape(v) != (c.output_dim,):
                raise ValueError(f"{what}: its compiled output returns shape {np.shape(v)}, "
                                 f"expected ({c.output_dim},)")


def _probe(fn, x, u, p):
    try:
        with np.errstate(all="ignore"):
            return fn(x, 0.0, 0, p) if u is None else fn(x, u, 0.0, 0, p)
    except Exception:  # noqa: BLE001 - numba-only code may not run in Python: skip the probe
        return None


def rebind(arc, system):
    """Give an arc of a lowered system back to ``system`` (its components, its
    description); an arc of ``system`` itself is returned as it is."""
    if arc.system is system:
        return arc
    from ..arc import _describe
    arc.system = system
    arc.system_description = _describe(system)
    arc.components = system.components
    if arc.exception is not None and getattr(arc.exception, "arc", None) is not None:
        arc.exception.arc = arc
    return arc


def rebind_all(arcs, system):
    """:func:`rebind` every arc of ``arcs`` (a list, changed in place and returned)
    to ``system``: the description read once for all."""
    from ..arc import _describe
    desc, comps = _describe(system), system.components
    for arc in arcs:
        if arc.system is system:
            continue
        d = arc.__dict__
        d["system"], d["system_description"], d["components"] = system, desc, comps
        exc = d.get("exception")
        if exc is not None and getattr(exc, "arc", None) is not None:
            exc.arc = arc
    return arcs


class Lowerable:
    """:func:`lowerable`'s answer: true where the system runs compiled; else
    false, with ``reason`` (the message :func:`lower` raises)."""

    __slots__ = ("reason",)

    def __init__(self, reason=None):
        self.reason = reason

    def __bool__(self):
        return self.reason is None

    def __repr__(self):
        return "Lowerable(True)" if self.reason is None else \
            f"Lowerable(False, reason={self.reason!r})"


def lowerable(system):
    """Whether :func:`lower` accepts ``system``: the same checks (no refusal),
    without compiling anything (numba need not be installed). (Not built
    either: a part reading its history whose compiled form, once built,
    declares no delays passes here and is refused by :func:`lower`; a plain
    model whose rewritten maps numba refuses passes here and is refused by
    :func:`lower` with numba's reason.)

    Returns
    -------
    Lowerable
        True or false; where false, ``.reason`` says why (for a plain model,
        the method and line that cannot be rewritten).

    Examples
    --------
    >>> import hybridsim as hs
    >>> from hybridsim.compiled import lowerable
    >>> noisy = hs.LinearPlant([[-1.0]], noise=lambda t: [0.0])   # a callable of t
    >>> bool(lowerable(hs.LinearPlant([[-1.0]]))), bool(lowerable(noisy))
    (True, False)
    >>> print(lowerable(noisy).reason)
    backend='compiled': LinearPlant cannot run compiled: its noise is a Python callable of t; ...
    """
    if "_source_plan" in getattr(system, "__dict__", ()) and \
            _from_source.cached(system) is not None:         # a plain model run before
        return Lowerable()
    if not isinstance(system, HybridSystem):
        raise TypeError(f"system must be a hybridsim.HybridSystem, got {type(system).__name__}")
    if isinstance(system, CompiledSystem) or (
            "_lowered" in system.__dict__ and "_source_plan" not in system.__dict__):
        return Lowerable()
    if isinstance(system, Interconnection):
        for nm, sub in system.systems.items():
            why = _refusal(sub, f"component {nm!r} ({type(sub).__name__})",
                           (nm, system.inputs.get(nm)))
            if why is not None:
                return Lowerable(str(why))
        return Lowerable()
    why = _refusal(system, type(system).__name__)
    return Lowerable(None if why is None else str(why))


def auto_choice(system, ok):
    """``backend="auto"``'s choice (:func:`hybridsim.compiled._from_source.auto_choice`);
    an interconnection :func:`lowerable` accepts is lowered here, so that numba's
    refusal of a part rewritten from source falls back with one warning naming
    the part's method and line."""
    if ok and isinstance(system, Interconnection):
        try:
            lower(system)
        except TypeError as e:
            return _from_source._fall_back(system, str(e), 5)
        return "compiled"
    return _from_source.auto_choice(system, ok)
