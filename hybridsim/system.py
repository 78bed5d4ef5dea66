"""Hybrid systems H = (C, f, D, g): the data the engine simulates."""
from __future__ import annotations

import dis
import inspect
import warnings

import numpy as np

from ._source import _arity
from .rules import MapError

__all__ = ["HybridSystem", "as_map", "MapError"]


def guard_min(v) -> float:
    """The minimum of a guard's value: a scalar, or the components of an array.

    Fast for Python and numpy scalars and small arrays (this runs at every
    evaluation during event location). Returns a Python float (arithmetic on
    it is several times quicker than on numpy's scalars).
    """
    if v.__class__ is float:
        return v
    if isinstance(v, float):        # numpy.float64
        return float(v)
    if isinstance(v, np.ndarray):
        return float(min(v.tolist())) if v.ndim else float(v)
    if isinstance(v, (list, tuple)):
        return float(min(v))
    return float(v)


def guard_rows(v) -> np.ndarray:
    """A batch guard's value per row: (N,) as it is, (N, m) its minimum over the columns."""
    v = np.asarray(v, dtype=float)
    return v.min(axis=1) if v.ndim == 2 else v




def renamed_keywords(where: str, old: dict, renames: dict, given: dict) -> dict:
    """The maps given under their deprecated keyword names, under the new ones.

    Parameters
    ----------
    where : str
        The callable's name, for the messages (``"HybridSystem.from_functions"``).
    old : dict
        The keywords received under names outside the signature.
    renames : dict
        ``{old name: new name}``.
    given : dict
        The new names' values as received (None: not given).

    Returns
    -------
    dict
        ``given`` updated with the values received under the old names, each
        with a ``DeprecationWarning`` naming the new name; a TypeError for a
        name that is neither, or a map given under both names.
    """
    for name, value in old.items():
        new = renames.get(name)
        if new is None:
            raise TypeError(f"{where}() got an unexpected keyword argument {name!r}")
        if given.get(new) is not None:
            raise TypeError(f"{where}: {name}= is the deprecated name of {new}=; give one")
        warnings.warn(f"{where}: the keyword {name}= is deprecated, use {new}=",
                      DeprecationWarning, stacklevel=3)
        given[new] = value
    return given


#: from_functions' deprecated keywords, ``{old: new}`` (the methods' names)
_FROM_FUNCTIONS_RENAMES = {"f": "flow_map", "g": "jump_map", "C": "flow_set",
                           "D": "jump_set", "g_values": "jump_map_values"}


def _where(t, j):
    try:
        return f"t={float(t):.10g}, j={int(j)}"
    except (TypeError, ValueError):     # arrays (vectorized maps)
        return "the batch"


def _map_error(name, e, t, j):
    return MapError(f"{name} raised {type(e).__name__}: {e} (at {_where(t, j)})", name, t, j)


def _named(fn, name):
    """A user map of any signature as a callable of ``(x, t, j, u)``, one frame
    above the user's function, whose failures name the map, t and j."""
    k = _check_map(fn, name)
    if k <= 1:
        def call(x, t, j, u):
            try:
                return fn(x)
            except MapError:
                raise
            except Exception as e:
                raise _map_error(name, e, t, j) from e
    elif k == 2:
        def call(x, t, j, u):
            try:
                return fn(x, t)
            except MapError:
                raise
            except Exception as e:
                raise _map_error(name, e, t, j) from e
    elif k == 3:
        def call(x, t, j, u):
            try:
                return fn(x, t, j)
            except MapError:
                raise
            except Exception as e:
                raise _map_error(name, e, t, j) from e
    else:
        def call(x, t, j, u):
            try:
                return fn(x, t, j, u)
            except MapError:
                raise
            except Exception as e:
                raise _map_error(name, e, t, j) from e
    return call


_F64 = np.float64


def _guard_value(name, v, t, j, batch=False):
    """A guard's value checked: a real number or a 1-D array of them.

    Complex values are refused even with a zero imaginary part (as a flow
    map's, :func:`hybridsim.options.check_map_value`): a guard is real, and
    taking its real part would hide a mistake.
    """
    if isinstance(v, np.ndarray):
        kind = v.dtype.kind
        if kind == "f" and v.ndim <= 1 + batch:
            return v
        if kind in "iub" and v.ndim <= 1 + batch:
            return v.astype(float)
    elif isinstance(v, float):
        return v
    if np.iscomplexobj(v):
        raise MapError(f"{name} returned complex values {v!r} (at {_where(t, j)}): a guard "
                       f"is real", name, t, j)
    try:
        arr = np.asarray(v, dtype=float)
    except (TypeError, ValueError) as e:
        raise MapError(f"{name} must return a real number or a 1-D array of them, got "
                       f"{type(v).__name__} {v!r} (at {_where(t, j)})", name, t, j) from e
    if arr.ndim > 1 + batch or arr.size == 0:
        raise MapError(f"{name} must return a real number or a non-empty 1-D array of them, "
                       f"got shape {arr.shape} (at {_where(t, j)})", name, t, j)
    return arr if arr.ndim else float(arr)


def _named_guard(fn, name):
    """:func:`_named` for a guard, its value checked by :func:`_guard_value`
    (one frame above the user's function, as :func:`_named`)."""
    k = _check_map(fn, name)

    def guard(x, t, j, u):
        try:
            v = fn(x) if k <= 1 else fn(x, t) if k == 2 else fn(x, t, j) if k == 3 \
                else fn(x, t, j, u)
        except MapError:
            raise
        except Exception as e:
            raise _map_error(name, e, t, j) from e
        c = v.__class__
        if c is float or c is _F64:
            return v
        # a vectorized system's batch of states (N, n) gets a guard row per state
        return _guard_value(name, v, t, j, batch=getattr(x, "ndim", 1) == 2)
    return guard


def _named_watch(fn, name="watch"):
    """:func:`_named` for the watched functions: a 1-D float array of their
    values (a scalar is one function), finite; a :class:`MapError` naming
    ``watch`` otherwise. Called and checked as a guard is
    (:func:`_named_guard`)."""
    values = _named_guard(fn, name)

    def watch(x, t, j, u):
        v = values(x, t, j, u)
        w = np.array((v,)) if v.__class__ is float or v.__class__ is _F64 \
            else np.asarray(v, dtype=float).reshape(-1)
        if not np.isfinite(w).all():
            raise MapError(f"{name} returned non-finite values {w} (at {_where(t, j)})",
                           name, t, j)
        return w
    return watch


def check_watch_direction(direction):
    """A system's ``watch_direction`` checked: -1, 0 or 1 (scipy's
    ``event.direction``: 1 keeps rising crossings only, -1 falling ones, 0
    both), or a 1-D sequence of them; a ValueError naming it otherwise."""
    try:
        d = np.array(direction)
    except (TypeError, ValueError):
        d = np.array(None)
    ok = d.dtype.kind in "iuf" and d.ndim <= 1 and d.size >= 1
    if ok:
        ok = bool(np.isin(d, (-1, 0, 1)).all())
    if not ok:
        raise ValueError(f"watch_direction must be -1, 0 or 1 (falling, both, rising), or "
                         f"a sequence of them, one per watched function; got {direction!r}")
    return d.astype(np.int64)


def watch_directions(direction, m, t=None, j=None):
    """:func:`check_watch_direction` for m watched functions: an (m,) int array; a
    :class:`MapError` naming ``watch`` where one value per function does not match."""
    d = check_watch_direction(direction)
    if d.ndim == 1 and d.size != m:
        raise MapError(f"watch returned {m} values but watch_direction gives {d.size} "
                       f"directions (one per watched function, or one for all)"
                       + ("" if t is None else f" (at {_where(t, j)})"), "watch", t, j)
    return np.broadcast_to(d, (m,)).copy()


def _as_bool(name, v, t, j):
    """A set indicator's value as a bool; anything else is a contract breach."""
    if v is True or v is False:
        return v
    if isinstance(v, (np.bool_, np.ndarray)) and getattr(v, "dtype", None) == np.bool_ \
            and np.size(v) == 1:
        return bool(v)
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v in (0, 1):
        return bool(v)
    raise MapError(f"{name} must return a bool (x in the set or not), got "
                   f"{type(v).__name__} {v!r} (at {_where(t, j)})", name, t, j)


def _from_guard(h, name):
    """The set {min_i h_i >= 0} of a guard; a NaN guard is a contract breach."""
    def call(x, t, j, u):
        v = guard_min(h(x, t, j, u))
        if v != v:
            raise MapError(f"{name} returned NaN (at {_where(t, j)})", name, t, j)
        return v >= 0.0
    return call


_NP_BOOL = np.bool_


def _indicator(m, name):
    def call(x, t, j, u):
        v = m(x, t, j, u)
        if v is True or v is False:
            return v
        if v.__class__ is _NP_BOOL:          # x[0] >= 0 on an array
            return bool(v)
        return _as_bool(name, v, t, j)
    return call


def _check_map(fn, name):
    """The number of ``(x, t, j, u)`` a user map takes; TypeError where it is
    not a callable of one of the four signatures."""
    if not callable(fn):
        raise TypeError(f"{name} must be callable, got {type(fn).__name__}")
    k = _arity(fn)
    if k > 4:
        raise TypeError(f"{name} must take (x), (x, t), (x, t, j) or (x, t, j, u); "
                        f"got a callable with {k} positional arguments")
    return k


#: names whose call can read a function's locals without naming them
_READS_LOCALS = frozenset(("locals", "vars", "eval", "exec"))
_LOADS = frozenset(("LOAD_FAST", "LOAD_FAST_CHECK", "LOAD_FAST_AND_CLEAR", "LOAD_CLOSURE",
                    "LOAD_DEREF", "DELETE_FAST", "STORE_FAST"))


def reads_input(fn) -> bool:
    """Whether a map ``fn`` of ``(x, t, j, u)`` can read its input u.

    False only where that is certain: ``fn`` takes fewer than four of the
    engine's arguments, or it is a Python function (or bound method) whose
    code never loads its fourth parameter (no closure over it, no
    ``locals()``, ``vars()``, ``eval``, ``exec``). Anything else (callable
    objects, builtins, ``*args``) counts as reading it. An interconnection
    then skips computing a component's input for its sets and guards.

    Examples
    --------
    >>> reads_input(lambda x, t, j, u: x[0] - 1.0), reads_input(lambda x, t, j, u: u[0])
    (False, True)
    >>> reads_input(lambda x, t: t - 1.0)
    False
    """
    if fn is None:
        return False
    try:
        k = _arity(fn)
    except (TypeError, ValueError):
        return True
    if k < 4:
        return False
    func, skip = fn, 0
    if inspect.ismethod(fn):
        func, skip = fn.__func__, 1
    code = getattr(func, "__code__", None)
    if code is None or not inspect.isfunction(func) or code.co_flags & inspect.CO_VARARGS:
        return True
    pos = code.co_varnames[:code.co_argcount]
    if len(pos) < skip + 4:
        return True
    name = pos[skip + 3]
    if name in code.co_cellvars or _READS_LOCALS & set(code.co_names):
        return True
    return any(ins.opname in _LOADS and ins.argval == name
               for ins in dis.get_instructions(code))


def as_map(fn, name: str):
    """Wrap a user map written as ``fn(x)``, ``fn(x, t)``, ``fn(x, t, j)`` or
    ``fn(x, t, j, u)`` into a callable of ``(x, t, j, u)``.

    Parameters
    ----------
    fn : callable
        The user's map or set indicator.
    name : str
        Its role (``"flow_map"``...), used in error messages.
    """
    if fn is None:
        return None
    k = _check_map(fn, name)
    if k <= 1:
        return lambda x, t, j, u: fn(x)
    if k == 2:
        return lambda x, t, j, u: fn(x, t)
    if k == 3:
        return lambda x, t, j, u: fn(x, t, j)
    return fn


class _DerivedGuard:
    """``jump_guard`` / ``flow_guard`` where a system gives none: the signed
    guard derived from its set indicator (:func:`hybridsim._source.derived_guard`),
    or None. An instance attribute, a method or ``jump_guard = None`` in a
    subclass replaces it."""

    def __init__(self, name):
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            return None
        from ._source import derived_guard
        return derived_guard(obj, self.name)


class HybridSystem:
    r"""A hybrid system with data (C, f, D, g), an optional input u and output y.

    .. math::  \dot x = f(x, t, j, u),\ x \in C; \qquad x^+ = g(x, t, j, u),\ x \in D.

    Subclass it and override what you need, or build one from plain functions
    with :meth:`from_functions`. The contract, as numbered rules:

    1. ``state_dim`` (int) is the length n of the state. ``input_dim`` is the
       length of the input u (0: no input; the maps then receive ``u=None``).
    2. ``flow_map(x, t, j, u)`` returns an (n,) array: the flow f. Default: no
       flow map (a system that must flow raises).
    3. ``jump_map(x, t, j, u)`` returns an (n,) array: the jump g. It receives
       the pre-jump j; the sample after the jump has j + 1 at the same t.
    4. ``flow_set`` and ``jump_set`` return a bool: x in C, x in D. Defaults:
       C is the whole space, D is empty (a purely continuous system).
    5. Any map or set may be written with the signature ``(x)``, ``(x, t)``,
       ``(x, t, j)`` or ``(x, t, j, u)``.
    6. Optional continuous guards give exact event location by root-finding:
       ``jump_guard(x, t, j, u)`` (scalar or 1-D) with D = {min_i h_i >= 0}
       near the events, ``flow_guard`` with C = {min_i c_i >= 0}. Where the set
       indicator is not overridden it is derived from its guard. Where both
       are given, the indicator decides membership and the guard locates the
       crossing. Where no guard is given and the set is built from
       comparisons, ``and``, ``or``, ``not`` and ``if``/``else``, its guard is
       derived from its source (``a >= b`` gives ``a - b``, ``and`` the
       minimum, ``or`` the maximum, ``not`` the negation; zero on the
       boundary, where the indicator decides); ``jump_guard = None`` in a
       subclass keeps the indicator alone.
    7. ``output(x, t, j)`` is the output y (default: x). Written
       ``output(x, t, j, u)`` it may read the input (direct feedthrough): an
       interconnection then evaluates outputs in dependency order and raises
       on an algebraic loop.
    8. ``vectorized = True`` declares maps written over batches: x of shape
       (N, n), t and j of shape (N,), returning (N, n) arrays and (N,)
       booleans; :func:`hybridsim.simulate_many` then integrates a batch
       together (RK45; with other options it runs the rows through
       :func:`hybridsim.simulate`, which passes single states, so maps
       written with ``x[..., k]`` serve both). An interconnection whose
       components are all vectorized is vectorized.
    9. ``max_step`` (float or None) caps the solver step; set it to the
       smallest delay when the maps read ``self.history``, and set
       ``needs_history = True`` so the engine records the dense output.
       During a run ``self.history`` is a :class:`hybridsim.History` view of
       the run's past. ``delays`` (tuple of floats) lists the delays the
       maps use: the engine then stops each flow at t0 + tau and at every
       jump time + tau, where the delayed value is discontinuous, so no
       solver step straddles a kink of the right-hand side.
    10. A set-valued jump map (a hybrid inclusion x+ ∈ G(x)) is declared by
        defining ``jump_map_values(x, t, j, u)`` instead of ``jump_map``: it
        returns the successors, a non-empty sequence of (n,) arrays (or a
        (k, n) array). :func:`hybridsim.simulate` takes the first successor
        (one drawn with the seed under ``priority="random"``);
        :func:`hybridsim.explore` follows every one. Its ``jump_map`` is then
        the first successor. Python path only.

    11. ``watch(x, t, j, u)`` (any signature of rule 5) returns a float or a
        1-D array of m floats: functions watched along the flows, whose
        zeros are recorded without a jump (scipy's non-terminal events).
        Each crossing is located to 4 ulp on the step's dense output, with
        the guards' root finder, and stored in ``arc.crossings`` (time,
        jump count, which function, direction, state). The solution is the
        same as without them: no step is cut. ``watch_direction`` (-1, 0 or
        1, or one per function) keeps falling crossings, both, or rising
        ones; a rising crossing goes from below 0 to 0 or above. Sign
        changes at jumps are not crossings, nor is a zero a flow starts on.

    State arrays are time-major everywhere: a run's samples are (N, n).
    """

    state_dim: int = None
    input_dim: int = 0
    output_dim: int | None = None
    vectorized: bool = False
    max_step: float | None = None
    needs_history: bool = False
    delays: tuple = ()
    jump_guard = _DerivedGuard("jump_guard")
    flow_guard = _DerivedGuard("flow_guard")
    #: a set-valued jump map ``(x, t, j, u) -> successors`` (rule 10), or None
    jump_map_values = None
    #: names of the components of an interconnection: ``{name: slice}``
    components: dict | None = None
    #: an SDE flow's diffusion ``(x, t, j) -> σ`` (dx = f dt + σ dW; see
    #: :mod:`hybridsim._sde`), or None (an ODE flow)
    diffusion = None
    #: None: diagonal noise (σ of shape (n,)); an int m: general noise (σ (n, m))
    noise_dim: int | None = None
    #: a jump rate ``(x, t, j) -> float >= 0``: jumps also when its integral
    #: reaches an Exp(1) threshold (see :mod:`hybridsim._random_jumps`), or None
    jump_rate = None
    #: a random jump map ``(x, rng) -> x+`` (or ``(x, t, rng)``, ``(x, t, j, rng)``),
    #: drawn with a generator seeded per run and jump; replaces jump_map; or None
    jump_law = None
    #: functions watched along the flows (rule 11) ``(x, t, j, u) -> (m,)``, or None
    watch = None
    #: which crossings of ``watch`` are kept: -1 falling, 0 both, 1 rising (or one each)
    watch_direction = 0

    def flow_map(self, x, t, j, u):
        raise NotImplementedError(f"{type(self).__name__} defines no flow_map, "
                                  "but the state is in its flow set")

    def jump_map(self, x, t, j, u):
        if self.jump_map_values is not None:
            return successors(self._compile().G(x, t, j, u), self.state_dim, t, j)[0]
        raise NotImplementedError(f"{type(self).__name__} defines no jump_map, "
                                  "but the state is in its jump set")

    def flow_set(self, x, t, j, u):
        return True

    def jump_set(self, x, t, j, u):
        return False

    def output(self, x, t, j):
        return x

    # ------------------------------------------------------------------
    history = None

    def __getstate__(self):
        # compiled maps and the run's history hold closures: rebuilt on demand
        state = self.__dict__.copy()
        state.pop("_compiled_maps", None)
        state.pop("history", None)
        state.pop("_lowered", None)         # the compiled path's generated maps
        state.pop("_source_plan", None)     # its rewrite of the maps (hybridsim._source)
        state.pop("_source_component", None)    # the same, as a part of an interconnection
        return state

    def _bind_history(self, history):
        """Give this system (and its components) read access to a run's past."""
        self.history = history

    @property
    def has_jumps(self) -> bool:
        """False when D is empty by construction (no jump set, no guard)."""
        return (self._overrides("jump_set") or self.jump_guard is not None)

    @property
    def set_valued(self) -> bool:
        """True when the system declares a set-valued jump map (rule 10)."""
        return self.jump_map_values is not None

    @property
    def has_flow_boundary(self) -> bool:
        """False when C is the whole space by construction."""
        return (self._overrides("flow_set") or self.flow_guard is not None)

    def _overrides(self, name: str) -> bool:
        if name in vars(self):
            return True
        return getattr(type(self), name) is not getattr(HybridSystem, name)

    def _compile(self):
        """Uniform ``(x, t, j, u)`` callables: f, g, C, D, hD, hC, h (cached)."""
        c = self.__dict__.get("_compiled_maps")
        if c is not None:
            return c
        n = self.state_dim
        if n is None or isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"{type(self).__name__}.state_dim must be a positive int, got {n!r}")
        def named(fn, name):
            return None if fn is None else _named(fn, name)

        hD = None if self.jump_guard is None else _named_guard(self.jump_guard, "jump_guard")
        hC = None if self.flow_guard is None else _named_guard(self.flow_guard, "flow_guard")
        if self._overrides("jump_set") or hD is None:
            D = _indicator(named(self.jump_set, "jump_set"), "jump_set")
        else:
            D = _from_guard(hD, "jump_guard")
        if self._overrides("flow_set") or hC is None:
            C = _indicator(named(self.flow_set, "flow_set"), "flow_set")
        else:
            C = _from_guard(hC, "flow_guard")
        G = None
        if self.jump_map_values is not None:
            if self._overrides("jump_map"):
                raise TypeError(f"{type(self).__name__} defines both jump_map and "
                                "jump_map_values: define one (jump_map_values for a "
                                "set-valued jump map)")
            G = named(self.jump_map_values, "jump_map_values")

            def g_first(x, t, j, u):
                return successors(G(x, t, j, u), n, t, j)[0]
            g = g_first
        else:
            g = named(self.jump_map, "jump_map")
        # D is {its guard >= 0}: derived here, or an override declaring so
        # (Interconnection: every component's D derived from its guard)
        D_guard = hD is not None and (not self._overrides("jump_set")
                                      or bool(getattr(self, "_jump_set_of_guard", False)))
        hD_u = hD is not None and reads_input(self.jump_guard)
        hC_u = hC is not None and reads_input(self.flow_guard)
        c = _Compiled(
            f=named(self.flow_map, "flow_map"), g=g, G=G,
            C=C, D=D, hD=hD, hC=hC, h=named(self.output, "output"),
            has_D=self.has_jumps, has_C=self.has_flow_boundary,
            h_u=_arity(self.output) >= 4,
            hD_u=hD_u, hC_u=hC_u, D_guard=D_guard,
            D_u=reads_input(self.jump_set) if self._overrides("jump_set") or hD is None
            else hD_u,
            C_u=reads_input(self.flow_set) if self._overrides("flow_set") or hC is None
            else hC_u,
            f_raw=self.flow_map, f_arity=_arity(self.flow_map),
            W=None if self.watch is None else _named_watch(self.watch),
            W_dir=None if self.watch is None else check_watch_direction(self.watch_direction))
        self.__dict__["_compiled_maps"] = c
        return c

    # ------------------------------------------------------------------
    @classmethod
    def from_functions(cls, flow_map=None, jump_map=None, flow_set=None, jump_set=None, *,
                       state_dim, jump_guard=None, flow_guard=None, output=None,
                       input_dim=0, output_dim=None, vectorized=False,
                       max_step=None, needs_history=False, name=None, jump_map_values=None,
                       diffusion=None, noise_dim=None, jump_rate=None, jump_law=None,
                       watch=None, watch_direction=0, **deprecated):
        """Build a hybrid system from plain functions.

        The keywords are the names of the methods they stand for (a subclass
        defines ``flow_map``, ``jump_map``, ``flow_set``, ``jump_set``...).

        Parameters
        ----------
        flow_map, jump_map : callable, optional
            The flow map f and the jump map g, each ``(x)``, ``(x, t)``,
            ``(x, t, j)`` or ``(x, t, j, u)`` returning an (n,) array.
        flow_set, jump_set : callable, optional
            The indicators of C and D, returning bool. Defaults: C everything,
            D empty (or derived from the guards).
        state_dim : int
            The state dimension n.
        jump_guard, flow_guard : callable, optional
            Continuous guards (see the class docstring, rule 6).
        output : callable, optional
            Output map ``(x, t, j)``; default the state.
        jump_map_values : callable, optional
            A set-valued jump map (rule 10 of the class): returns the
            successors, a sequence of (n,) arrays. Not with ``jump_map``.
        diffusion : callable, optional
            An SDE flow's diffusion σ(x, t, j): dx = f dt + σ dW in C (run
            with ``method="EM"``, ``"Milstein"`` or ``"SRA1"`` and a fixed
            step ``max_step``; see :mod:`hybridsim._sde`).
        noise_dim : int, optional
            None: diagonal noise, σ of shape (n,); m: σ of shape (n, m).
        jump_rate : callable, optional
            A jump rate (x, t, j) -> float >= 0: the state also jumps when
            the rate's integral reaches an Exp(1) threshold.
        jump_law : callable, optional
            A random jump map (x, rng) -> x+ (or (x, t, rng), (x, t, j,
            rng)), drawn with a generator seeded per run and jump.
        watch : callable, optional
            Functions watched along the flows (rule 11): a float or a 1-D
            array; their crossings of 0 are recorded in ``arc.crossings``
            without a jump.
        watch_direction : int or sequence of int
            -1, 0 (default) or 1: keep falling crossings, both, or rising
            ones (one value for all the functions, or one each).
        **deprecated
            The former names ``f``, ``g``, ``C``, ``D`` and ``g_values`` of
            ``flow_map``, ``jump_map``, ``flow_set``, ``jump_set`` and
            ``jump_map_values``: accepted with a ``DeprecationWarning``.

        Examples
        --------
        >>> import numpy as np, hybridsim as hs
        >>> ball = hs.HybridSystem.from_functions(
        ...     flow_map=lambda x: np.array([x[1], -9.81]),
        ...     jump_map=lambda x: np.array([0.0, -0.8 * x[1]]),
        ...     flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0,
        ...     state_dim=2)
        >>> arc = hs.simulate(ball, [1.0, 0.0], t_max=3.0, j_max=5)
        >>> arc.jump_count
        5

        A jump map with two successors (:func:`hybridsim.explore` follows both):

        >>> coin = hs.HybridSystem.from_functions(
        ...     flow_map=lambda x: np.array([1.0]), jump_set=lambda x: x[0] >= 1.0,
        ...     flow_set=lambda x: x[0] <= 1.0,
        ...     jump_map_values=lambda x: [np.array([0.0]), np.array([0.5])], state_dim=1)
        >>> hs.simulate(coin, [0.0], t_max=3.0, j_max=1).xf    # the first successor
        array([0.])

        The ball's apexes, watched (its velocity falling through 0):

        >>> ball = hs.HybridSystem.from_functions(
        ...     flow_map=lambda x: np.array([x[1], -9.81]),
        ...     jump_map=lambda x: np.array([0.0, -0.8 * x[1]]),
        ...     flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0,
        ...     watch=lambda x: x[1], watch_direction=-1, state_dim=2)
        >>> arc = hs.simulate(ball, [0.0, 9.81], t_max=3.0, j_max=5)
        >>> arc.crossings.t[:2]                 # v0 / g, then 2 + 0.8 v0 / g
        array([1. , 2.8])
        """
        if deprecated:
            given = renamed_keywords(
                "HybridSystem.from_functions", deprecated, _FROM_FUNCTIONS_RENAMES,
                {"flow_map": flow_map, "jump_map": jump_map, "flow_set": flow_set,
                 "jump_set": jump_set, "jump_map_values": jump_map_values})
            flow_map, jump_map, flow_set, jump_set, jump_map_values = (
                given[k] for k in ("flow_map", "jump_map", "flow_set", "jump_set",
                                   "jump_map_values"))
        if jump_map is not None and jump_map_values is not None:
            raise TypeError("jump_map and jump_map_values: give one (jump_map_values for a "
                            "set-valued jump map)")
        sysobj = cls.__new__(cls)
        HybridSystem.__init__(sysobj)
        sysobj.state_dim = state_dim
        sysobj.input_dim = input_dim
        sysobj.output_dim = output_dim
        sysobj.vectorized = vectorized
        sysobj.max_step = max_step
        sysobj.needs_history = needs_history
        sysobj._name = name
        sysobj.noise_dim = noise_dim
        for attr, fn in (("flow_map", flow_map), ("jump_map", jump_map),
                         ("flow_set", flow_set), ("jump_set", jump_set),
                         ("output", output), ("jump_map_values", jump_map_values),
                         ("diffusion", diffusion), ("jump_rate", jump_rate),
                         ("jump_law", jump_law)):
            if fn is not None:
                if not callable(fn):
                    raise TypeError(f"{attr} must be callable, got {type(fn).__name__}")
                setattr(sysobj, attr, fn)
        if watch is not None or not (isinstance(watch_direction, (int, np.integer))
                                     and watch_direction == 0):
            if watch is None:
                raise TypeError("watch_direction without watch: give the watched "
                                "functions as watch=")
            sysobj.watch_direction = watch_direction
        for attr, fn in (("jump_guard", jump_guard), ("flow_guard", flow_guard),
                         ("watch", watch)):
            if fn is not None:
                if not callable(fn):
                    raise TypeError(f"{attr} must be callable, got {type(fn).__name__}")
                setattr(sysobj, attr, fn)
        return sysobj

    def __repr__(self):
        name = getattr(self, "_name", None) or type(self).__name__
        return f"<{name}: state_dim={self.state_dim}, input_dim={self.input_dim}>"


def check_nested_set_valued(system, where=""):
    """Refuse an interconnection with a component that declares a set-valued
    jump map: its jump would silently take the first successor."""
    for name, sub in (getattr(system, "systems", None) or {}).items():
        if not isinstance(sub, HybridSystem):
            continue
        if sub.jump_map_values is not None:
            raise ValueError(f"system: component {where + str(name)!r} declares "
                             f"jump_map_values (a set-valued jump map), which an "
                             f"interconnection does not support: the interconnection "
                             f"would take its first successor only. Write the "
                             f"interconnected system's own jump_map_values")
        check_nested_set_valued(sub, f"{where}{name}.")


def successors(vals, n, t=None, j=None):
    """A set-valued jump map's value as a (k, n) float array, k >= 1, finite;
    a :class:`MapError` naming ``jump_map_values`` otherwise."""
    where = "" if t is None else f" (at {_where(t, j)})"
    if isinstance(vals, np.ndarray) and vals.ndim == 1:
        raise MapError(f"jump_map_values must return a sequence of successors (a list of "
                       f"({n},) arrays or a (k, {n}) array), got a 1-D array{where}",
                       "jump_map_values", t, j)
    try:
        arr = np.asarray(vals, dtype=float)
    except (TypeError, ValueError) as e:
        raise MapError(f"jump_map_values must return a sequence of ({n},) arrays, got "
                       f"{type(vals).__name__}{where}", "jump_map_values", t, j) from e
    if arr.ndim != 2 or arr.shape[1] != n or arr.shape[0] < 1:
        raise MapError(f"jump_map_values must return k >= 1 successors of shape ({n},) "
                       f"(a (k, {n}) array), got shape {arr.shape}{where}",
                       "jump_map_values", t, j)
    if not np.all(np.isfinite(arr)):
        raise MapError(f"jump_map_values returned non-finite successors {arr}{where}",
                       "jump_map_values", t, j)
    return arr


class _Compiled:
    __slots__ = ("f", "g", "G", "C", "D", "hD", "hC", "h", "has_D", "has_C", "h_u",
                 "hD_u", "hC_u", "D_u", "C_u", "D_guard", "f_raw", "f_arity", "W", "W_dir")

    def __init__(self, **kw):
        for k, v in kw.items():
            setattr(self, k, v)
