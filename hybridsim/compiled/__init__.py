"""The compiled path: hybrid systems whose maps numba can compile, run entirely
in machine code.

A :class:`CompiledSystem` is built from plain functions of ``(x, t, j, p)``
written with numpy on scalars and 1-D arrays (``p`` is the system's float
parameter array). It is an ordinary :class:`hybridsim.HybridSystem` too, so
``hs.simulate(system, ...)`` runs the same maps on the Python path and gives
a reference. :func:`simulate_compiled` runs one solution compiled and
:func:`simulate_many_compiled` runs a batch compiled and in parallel over the
machine's cores (numba ``prange``); both return the same
:class:`hybridsim.HybridArc` as the Python path.

What is compiled, and what is cached
------------------------------------
The engine (Dormand-Prince 5(4) stepping with scipy RK45's step-size
controller and dense output, event location, the decision loop) is compiled
once per machine and kept in numba's on-disk cache (``__pycache__`` beside
this package, or ``NUMBA_CACHE_DIR``): a new process loads it in a fraction
of a second. The user's maps reach it as numba first-class functions of a
fixed signature; they are compiled per system, when the system is first run
(about 0.1-0.3 s per map), and are not cached across processes (they are
often lambdas or closures). The rules (:mod:`hybridsim.rules`) are compiled
into the engine from their one source; a change of them invalidates the cache.

numba is an optional dependency: ``pip install 'hybridsim[fast]'``. Importing
this module does not need it; running compiled does.

Semantics are those of :func:`hybridsim.simulate` with ``method="RK45"``
(same priorities, event location to 4 ulp, jumps at t_max within
:func:`hybridsim.rules.t_max_slack`, termination causes) except for what
a compiled map cannot do: raise an exception (``MAP_ERROR`` only for jump
maps returning non-finite or mis-shaped values), take an input ``u``, or read
``self.history``. The Python path's stiffness warning is not issued.
"""
from __future__ import annotations

import math
import time
import warnings

import numpy as np

from ..arc import HybridArc
from ..rules import (
    FAILURES,
    MapError,
    SimulationWarning,
    Termination,
    sticking_message,
    zeno_message,
)
from ..system import HybridSystem

__all__ = ["CompiledSystem", "simulate_compiled", "simulate_many_compiled", "CompileError",
           "available", "compile_kernels"]

_KIND_TEXT = {"vec": "an array of state_dim floats", "scalar": "a float"}


_INSTALL = "pip install 'hybridsim[fast]'"
_ROLES = (("flow", "vec"), ("jump", "vec"), ("jump_guard", "scalar"),
          ("flow_guard", "scalar"), ("jump_set", "bool"), ("flow_set", "bool"))


class CompileError(TypeError):
    """A map of a :class:`CompiledSystem` could not be compiled by numba.

    ``map_name`` names the map; ``__cause__`` is numba's error. The Python
    path, ``hs.simulate(system, ...)``, runs the same system uncompiled.
    """

    def __init__(self, message, map_name=None):
        super().__init__(message)
        self.map_name = map_name


def available() -> bool:
    """Whether numba is installed (the compiled path can run).

    Examples
    --------
    >>> import hybridsim.compiled as hc
    >>> isinstance(hc.available(), bool)
    True
    """
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


_K = None
#: cause codes of the kernels (``_kernel.CAUSES``), as Termination members
_CAUSES = tuple(Termination[name] for name in (
    "T_MAX", "J_MAX", "NOT_IN_SETS", "LEFT_SETS", "NON_FINITE", "BLOWUP", "SOLVER_FAILED",
    "MAP_ERROR", "ZENO", "MAX_STEPS"))


def _load_kernel():
    global _K
    if _K is not None:
        return _K
    try:
        from . import _kernel as k
    except ImportError as e:
        if "numba" not in str(e).lower():
            raise
        raise ImportError(f"the compiled path needs numba: {_INSTALL} (or pip install "
                          f"numba). Without it, run the same system on the Python path "
                          f"with hs.simulate / hs.simulate_many.") from e
    assert tuple(c.name for c in _CAUSES) == k.CAUSES
    _K = k
    return k


def compile_kernels():
    """Compile the engine's kernels now (or load them from numba's disk cache).

    Returns the seconds it took. Called by the first compiled run anyway.
    """
    t = time.perf_counter()
    _load_kernel().compile_kernels(batch=True)
    return time.perf_counter() - t


def _summarise(err):
    """numba's error, shortened to the lines that say what failed."""
    lines = [ln.rstrip() for ln in str(err).splitlines() if ln.strip()]
    keep = []
    for ln in lines:
        s = ln.strip()
        if s.startswith(("During:", "File \"", "<source", "^", "Failed in nopython",
                         "- Resolution failure", "Rewrite", "This error may have")):
            continue
        keep.append(s)
        if len(keep) >= 4:
            break
    return " | ".join(keep) if keep else type(err).__name__


class _PyMap:
    """A user map ``fn(x, t, j, p)`` seen by the Python path as ``(x, t, j)``."""

    __slots__ = ("fn", "system")

    def __init__(self, fn, system):
        self.fn, self.system = fn, system

    def __call__(self, x, t, j):
        return self.fn(x, t, j, self.system.params)

    def __getstate__(self):
        return (self.fn, self.system)

    def __setstate__(self, s):
        self.fn, self.system = s


class CompiledSystem(HybridSystem):
    r"""A hybrid system written for the compiled path (and usable on the Python path).

    Each map is a plain function ``fn(x, t, j, p)``: ``x`` the state (a
    float64 array of shape (n,)), ``t`` a float, ``j`` an int, ``p`` the
    parameter array :attr:`params` (float64, 1-D). Write it with numpy on
    scalars and small arrays, as numba compiles it in nopython mode: no
    Python objects, no exceptions, no closures over mutable state.

    Parameters
    ----------
    flow : callable
        ``f(x, t, j, p)``: the flow map, a 1-D array of n floats (or a tuple).
    jump : callable, optional
        ``g(x, t, j, p)``: the jump map, receives the pre-jump j.
    jump_guard, flow_guard : callable, optional
        Continuous guards, a float (or a 1-D array: the set is where its
        minimum is >= 0): D = {jump_guard >= 0}, C = {flow_guard >= 0} near
        the events. Events are then located by root-finding on them.
    jump_set, flow_set : callable, optional
        Set indicators returning a bool. Where given, they decide membership
        and the guards only locate crossings; where absent, the set is
        derived from its guard (C defaults to everything, D to empty).
    state_dim : int
        n.
    params : array_like, optional
        Float parameters passed to every map as ``p`` (changing
        ``system.params`` later is seen by the next run; nothing recompiles).
    max_step : float, optional
        A cap on the solver step (as :attr:`HybridSystem.max_step`).
    specialize : bool
        False (default): the maps reach the engine as first-class functions;
        the engine is the one compiled kernel cached on disk, so a new system
        costs only its maps' compilation (about 1 s, see the module notes).
        True: the engine is compiled anew for this system with its maps
        inlined, 2-3x faster per run but about 10-20 s of compilation at the
        first run in each process (not cached across processes): for long
        Monte Carlo studies.
    name : str, optional
        For ``repr``.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> from hybridsim.compiled import CompiledSystem
    >>> ball = CompiledSystem(
    ...     flow=lambda x, t, j, p: np.array([x[1], -p[0]]),
    ...     jump=lambda x, t, j, p: np.array([0.0, -p[1] * x[1]]),
    ...     jump_guard=lambda x, t, j, p: -x[0], flow_guard=lambda x, t, j, p: x[0],
    ...     jump_set=lambda x, t, j, p: x[0] <= 0.0 and x[1] <= 0.0,
    ...     state_dim=2, params=[9.81, 0.8])
    >>> arc = hs.simulate(ball, [1.0, 0.0], t_max=2.0, j_max=3)   # the Python path
    >>> arc.jump_count
    3
    """

    def __init__(self, flow=None, jump=None, *, jump_guard=None, flow_guard=None,
                 jump_set=None, flow_set=None, state_dim, params=(), max_step=None,
                 specialize=False, name=None):
        HybridSystem.__init__(self)
        if isinstance(state_dim, bool) or not isinstance(state_dim, (int, np.integer)) \
                or state_dim < 1:
            raise ValueError(f"state_dim must be a positive int, got {state_dim!r}")
        self.state_dim = int(state_dim)
        self.params = params
        self.max_step = max_step
        if not isinstance(specialize, (bool, np.bool_)):
            raise TypeError(f"specialize must be True or False, got {specialize!r}")
        self.specialize = bool(specialize)
        self._name = name
        self.maps = {}
        for role, fn in (("flow", flow), ("jump", jump), ("jump_guard", jump_guard),
                         ("flow_guard", flow_guard), ("jump_set", jump_set),
                         ("flow_set", flow_set)):
            if fn is None:
                continue
            if not callable(fn):
                raise TypeError(f"{role} must be callable fn(x, t, j, p), got "
                                f"{type(fn).__name__}")
            self.maps[role] = fn
        if flow is None:
            raise TypeError("flow is required: a function flow(x, t, j, p) -> array of "
                            "state_dim floats")
        # the Python path sees the same maps through HybridSystem's attributes
        attrs = {"flow": "flow_map", "jump": "jump_map", "jump_guard": "jump_guard",
                 "flow_guard": "flow_guard", "jump_set": "jump_set", "flow_set": "flow_set"}
        for role, fn in self.maps.items():
            setattr(self, attrs[role], _PyMap(fn, self))
        self._nb = None

    @property
    def params(self):
        """The parameter array ``p`` passed to every map (float64, 1-D)."""
        return self._params

    @params.setter
    def params(self, value):
        try:
            p = np.array(value, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError) as e:
            raise TypeError(f"params must be an array of floats, got "
                            f"{type(value).__name__}") from e
        self._params = np.ascontiguousarray(p)

    def __getstate__(self):
        state = HybridSystem.__getstate__(self)
        state["_nb"] = None           # compiled functions are rebuilt after unpickling
        return state

    def compile(self):
        """Compile the maps (once per system; later calls return at once).

        Returns
        -------
        float
            Seconds spent compiling (0 when already compiled).

        Raises
        ------
        ImportError
            numba is not installed (``pip install 'hybridsim[fast]'``).
        CompileError
            A map numba cannot compile; the message names it and summarises
            numba's error. ``hs.simulate(system, ...)`` runs it uncompiled.
        """
        if self._nb is not None:
            return 0.0
        k = _load_kernel()
        t = time.perf_counter()
        import numba
        from numba.core.errors import NumbaExperimentalFeatureWarning
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumbaExperimentalFeatureWarning)
            out = self._compile_maps(k, numba)
        if not self.specialize:     # first-class function values for the cached kernels
            out = {role: k.handle(d, kind) for (role, d), kind in
                   zip(out.items(), (self._kinds[r] for r in out))}
            absent = {"vec": k.handle(k.absent_vec, "vec"),
                      "scalar": k.handle(k.absent_scalar, "scalar"),
                      "false": k.handle(k.absent_false, "bool"),
                      "true": k.handle(k.absent_true, "bool")}
        else:
            absent = {"vec": k.absent_vec, "scalar": k.absent_scalar,
                      "false": k.absent_false, "true": k.absent_true}
        self._nb = {
            "f": out["flow"], "g": out.get("jump", absent["vec"]),
            "hD": out.get("jump_guard", absent["scalar"]),
            "hC": out.get("flow_guard", absent["scalar"]),
            "D": out.get("jump_set", absent["false"]), "C": out.get("flow_set", absent["true"]),
            "has_C": "flow_set" in out, "has_D": "jump_set" in out,
            "has_hC": "flow_guard" in out, "has_hD": "jump_guard" in out,
        }
        return time.perf_counter() - t

    def _compile_maps(self, k, numba):
        out = {}
        self._kinds = {}
        for role, kind in _ROLES:
            fn = self.maps.get(role)
            if fn is None:
                continue
            try:
                out[role] = k.wrap_map(fn, kind)
                self._kinds[role] = kind
            except (numba.core.errors.NumbaError, TypeError, ValueError, NotImplementedError,
                    AttributeError, KeyError) as e:
                raise CompileError(
                    f"CompiledSystem: numba could not compile the map {role!r} "
                    f"({getattr(fn, '__qualname__', repr(fn))}): {_summarise(e)}. Write it "
                    f"as a numpy function of (x, t, j, p) returning "
                    f"{_KIND_TEXT.get(kind, 'a bool')}, "
                    f"or run this system on the Python path with hs.simulate(system, ...) "
                    f"(the fallback, same maps, no compiling)", role) from e
        # sets derived from their guards where no indicator is given
        for role, guard in (("jump_set", "jump_guard"), ("flow_set", "flow_guard")):
            if role not in out and guard in out:
                out[role] = k.wrap_map(self.maps[guard], "guard_set")
                self._kinds[role] = "guard_set"
        return out

    def __repr__(self):
        name = self._name or "CompiledSystem"
        return f"<{name}: state_dim={self.state_dim}, maps={sorted(self.maps)}>"


# ---------------------------------------------------------------- running
_UNSUPPORTED = ("inputs", "prehistory", "dense", "t_eval", "progress")
_I64_MAX = np.iinfo(np.int64).max
_DUMMY_RNG = None


def _check_system(system):
    if not isinstance(system, CompiledSystem):
        raise TypeError(f"system must be a hybridsim.compiled.CompiledSystem (maps of "
                        f"(x, t, j, p) numba can compile), got {type(system).__name__}; "
                        f"run other systems with hs.simulate (the Python path)")


def _options(system, x0_shape_n, t_max, j_max, t0, j0, priority, rtol, atol, max_step,
             first_step, max_steps, max_samples, zeno_jumps, zeno_time, zeno_rtol, max_norm,
             refine, method, extra):
    """Validate like :func:`hybridsim.simulate` and pack the kernel's option arrays."""
    from ..options import check_count as _check_count
    from ..options import check_options
    from ..options import check_real as _check_real
    for name in extra:
        if name == "progress" and not extra[name]:     # no bar: accepted (simulate_many sends it)
            continue
        if name in _UNSUPPORTED:
            raise TypeError(f"{name}= is not supported by the compiled path; use "
                            f"hs.simulate (the Python path) for it")
        raise TypeError(f"unexpected keyword argument {name!r}")
    if method not in ("RK45", None):
        raise ValueError(f"method: the compiled path integrates with RK45 (Dormand-Prince "
                         f"5(4)) only, got {method!r}; use hs.simulate for other methods")
    n = x0_shape_n
    (t0, t_max, j_max, prio, rtol, atol, max_step, first_step, max_norm,
     zeno_time) = check_options(system, n, t0, t_max, j_max, priority, rtol, atol, max_step,
                                first_step, max_norm, zeno_time)
    j0 = _check_count("j0", j0)
    refine = _check_count("refine", refine, minimum=1)
    max_steps = _check_count("max_steps", max_steps, minimum=1, allow_inf=True)
    max_samples = _check_count("max_samples", max_samples, minimum=2, allow_inf=True)
    if refine > max_samples:
        raise ValueError(f"refine must be <= max_samples = {max_samples}, got {refine}")
    zeno_jumps = _check_count("zeno_jumps", zeno_jumps, minimum=1)
    zeno_rtol = _check_real("zeno_rtol", zeno_rtol, nonneg=True)
    fopt = np.array([t0, t_max, j_max, rtol, max_step,
                     np.nan if first_step is None else first_step, max_norm, zeno_time,
                     zeno_rtol], dtype=np.float64)
    nb = system._nb
    iopt = np.array([j0, int(prio), _I64_MAX if max_steps == math.inf else max_steps,
                     _I64_MAX if max_samples == math.inf else max_samples, zeno_jumps, refine,
                     nb["has_C"], nb["has_D"], nb["has_hC"], nb["has_hD"], 64],
                    dtype=np.int64)
    atol_a = np.array(np.broadcast_to(np.asarray(atol, dtype=np.float64), (n,)), order="C")
    return fopt, iopt, atol_a, prio, max_steps, max_samples


def _quiet(kernel):
    """Call ``kernel`` without numba's "first-class functions are experimental"
    warning (a specialised kernel compiles at its first call)."""
    def call(*args):
        from numba.core.errors import NumbaExperimentalFeatureWarning
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumbaExperimentalFeatureWarning)
            return kernel(*args)
    return call


def _kernels(k, system, batch):
    """(run_one, run_batch) for the system: the cached generic pair, or the
    pair specialised on its maps."""
    if system.specialize:
        return _quiet(k.run_one_spec), _quiet(k.run_batch_spec)
    k.compile_kernels(batch=batch)
    return k.run_one, k.run_batch


def _message(system, code, detail, info, x_last, stats, max_steps, max_samples, max_norm,
             zeno_jumps):
    """The Python path's message for a cause code (see ``hybridsim.solve``)."""
    cause = _CAUSES[code]
    if cause is Termination.T_MAX or cause is Termination.J_MAX:
        return cause, cause.value
    t, t2, v, j = info
    j = None if j != j else int(j)
    base = cause.message
    if cause in (Termination.T_MAX, Termination.J_MAX):
        return cause, base
    if cause is Termination.NOT_IN_SETS:
        return cause, f"{base}: x={x_last} at (t={t}, j={j})"
    if cause is Termination.LEFT_SETS:
        if detail == 1:
            return cause, (f"{base}: the flow left C at t={t:.10g} (j={j}), x={x_last}, "
                           f"outside D")
        return cause, f"{base}: x={x_last} at (t={t}, j={j})"
    if cause is Termination.ZENO:
        if detail == 0:
            return cause, f"{base}: {zeno_message(int(v), t)}"
        if detail == 1:
            return cause, f"{base}: {sticking_message(t, j, x_last, [t2, v])}"
        return cause, f"{base}: flows too short to resolve near t={t:.10g}"
    if cause is Termination.NON_FINITE:
        if detail == 0:
            return cause, f"{base}: after the step from t={t:.10g} to t={t2:.10g} (j={j})"
        return cause, f"{base}: flow map returned non-finite values near t={t:.10g} (j={j})"
    if cause is Termination.BLOWUP:
        return cause, f"{base}: |x| = {v:.3g} > {max_norm:.3g} at t={t:.10g} (j={j})"
    if cause is Termination.SOLVER_FAILED:
        return cause, (f"{base}: Required step size is less than spacing between numbers. "
                       f"at t={t:.10g} (j={j})")
    if cause is Termination.MAX_STEPS:
        if detail == 0:
            return cause, (f"{base}: {stats[0]} solver steps (max_steps={max_steps}) at "
                           f"t={t:.10g}")
        return cause, f"{base}: samples stored reached max_samples={max_samples} at t={t:.10g}"
    if cause is Termination.MAP_ERROR:
        if detail == 0:
            return cause, (f"jump map must return an array of shape "
                           f"({len(x_last)},), got shape ({int(v)},) (at t={t:.10g}, j={j})")
        if detail == 1:
            return cause, f"jump map returned non-finite values (at t={t:.10g}, j={j})"
        if detail == 2:
            return cause, (f"flow map must return an array of shape ({len(x_last)},) "
                           f"(at t={t:.10g}, j={j})")
        role = "flow" if detail == 3 else "jump"
        if "jump" not in system.maps and role == "jump":
            return cause, (f"the state is in the jump set at t={t}, j={j} but the system "
                           f"has no jump map")
        what = ("non-finite values" if int(v) == len(x_last)
                else f"an array of shape ({int(v)},)")
        return cause, (f"{role} map returned {what} "
                       f"at x0 (expected {len(x_last)} finite floats; at t={t}, j={j})")
    return cause, base


_STAT_NAMES = ("steps", "rejected", "nfev", "events", "flows")


def _arc(system, T, J, X, XD, code, detail, info, stats, lim):
    cause, msg = _message(system, code, detail, info, X[-1], stats, *lim)
    st = dict(zip(_STAT_NAMES, stats.tolist() if isinstance(stats, np.ndarray) else stats))
    st["njev"] = 0
    st["nlu"] = 0
    exc = None
    if cause is Termination.MAP_ERROR:
        exc = MapError(msg, "flow" if detail in (2, 3) else "jump", float(info[0]),
                       None if info[3] != info[3] else int(info[3]))
    # the kernels' own arrays: (N,) float64 t, int64 j, (N, n) float64 x and xdot
    arc = HybridArc._trusted(T, J, X, cause, msg, exc, system=system, xdot=XD, stats=st)
    if exc is not None and detail >= 3:     # bad values at x0: raised at once
        exc.arc = arc
        raise exc
    return arc


def _rng_for(prio, seed):
    from ..options import check_seed as _check_seed
    from ..rules import Priority
    global _DUMMY_RNG
    if prio == Priority.RANDOM:
        return _check_seed(seed)
    if seed is not None:
        _check_seed(seed)
    if _DUMMY_RNG is None:
        _DUMMY_RNG = np.random.default_rng(0)
    return _DUMMY_RNG


def _finish(arc, throw, warn, stacklevel=3):
    cause = arc.termination
    if cause is Termination.MAP_ERROR and throw:
        err = arc.exception
        err.arc = arc
        raise err
    if warn and (cause in FAILURES or cause is Termination.MAX_STEPS) \
            and cause is not Termination.MAP_ERROR:
        warnings.warn(f"{cause.name}: {arc.message} (last sample t={arc.t[-1]:.10g}, "
                      f"j={arc.j[-1]})", SimulationWarning, stacklevel=stacklevel)
    return arc


def simulate_compiled(system, x0, t_max, j_max=math.inf, *, t0=0.0, j0=0, priority="jumps",
                      rtol=1e-6, atol=1e-9, max_step=math.inf, first_step=None,
                      max_steps=1_000_000, max_samples=10_000_000, zeno_jumps=50,
                      zeno_time=1e-12, zeno_rtol=1e-7, max_norm=math.inf, seed=None,
                      refine=1, throw=True, warn=True, method="RK45", **unsupported):
    """Simulate a :class:`CompiledSystem` entirely in compiled code.

    The same run as ``hs.simulate(system, x0, t_max, j_max, method="RK45",
    ...)``: Dormand-Prince 5(4) steps with scipy RK45's error control and
    step-size controller, events located to 4 ulp on the step's dense output
    (the Python path's root finder on guards, bisection of the indicators,
    the interior search for excursions within one step), the same priorities, limits and
    termination causes, and the same :class:`hybridsim.HybridArc` (``t``,
    ``j``, ``x``, ``xdot``, ``stats``, ``termination``, ``message``).

    Parameters
    ----------
    system : CompiledSystem
    x0 : array_like, shape (n,)
    t_max, j_max, t0, j0, priority, rtol, atol, max_step, first_step, max_steps,
    max_samples, zeno_jumps, zeno_time, zeno_rtol, max_norm, seed, refine, throw, warn
        As in :func:`hybridsim.simulate` (``seed`` drives ``priority="random"``
        with the same numpy Generator stream, so coins agree with the Python
        path).
    method : {"RK45"}
        The only method compiled.

    Returns
    -------
    HybridArc

    Raises
    ------
    ImportError
        numba is missing (``pip install 'hybridsim[fast]'``).
    CompileError
        A map numba cannot compile (named); ``hs.simulate`` is the fallback.
    MapError
        A jump map returned a non-finite or mis-shaped value (``throw=True``);
        bad values at x0 are raised at once, as on the Python path.

    Examples
    --------
    >>> import numpy as np
    >>> from hybridsim.compiled import CompiledSystem, simulate_compiled
    >>> timer = CompiledSystem(flow=lambda x, t, j, p: np.ones(1),
    ...                        jump=lambda x, t, j, p: np.zeros(1),
    ...                        jump_guard=lambda x, t, j, p: x[0] - p[0],
    ...                        flow_guard=lambda x, t, j, p: p[0] - x[0],
    ...                        state_dim=1, params=[1.0])
    >>> arc = simulate_compiled(timer, [0.0], t_max=3.0)
    >>> np.round(arc.jump_times, 12)
    array([1., 2., 3.])
    """
    from ..options import check_bool as _check_bool
    from ..options import check_x0 as _check_x0
    k = _load_kernel()
    _check_system(system)
    n = system.state_dim
    x = np.ascontiguousarray(_check_x0(x0, n))
    throw = _check_bool("throw", throw)
    warn = _check_bool("warn", warn)
    system.compile()
    kern = _kernels(k, system, batch=False)
    fopt, iopt, atol_a, prio, ms, msa = _options(
        system, n, t_max, j_max, t0, j0, priority, rtol, atol, max_step, first_step,
        max_steps, max_samples, zeno_jumps, zeno_time, zeno_rtol, max_norm, refine, method,
        unsupported)
    rng = _rng_for(prio, seed)
    nb = system._nb
    T, J, X, XD, code, detail, info, stats = kern[0](
        nb["f"], nb["g"], nb["hD"], nb["hC"], nb["D"], nb["C"], x, system.params, fopt,
        iopt, atol_a, rng)
    arc = _arc(system, T, J, X, XD, code, detail, info, stats,
               (ms, msa, fopt[6], zeno_jumps))
    return _finish(arc, throw, warn)


def simulate_many_compiled(system, x0s, t_max, j_max=math.inf, *, parallel=True,
                           chunk_bytes=64 * 2**20, t0=0.0, j0=0, priority="jumps",
                           rtol=1e-6, atol=1e-9, max_step=math.inf, first_step=None,
                           max_steps=1_000_000, max_samples=10_000_000, zeno_jumps=50,
                           zeno_time=1e-12, zeno_rtol=1e-7, max_norm=math.inf, seed=None,
                           refine=1, throw=True, warn=True, method="RK45", **unsupported):
    """Simulate a :class:`CompiledSystem` from many initial states, compiled and in parallel.

    Each run is exactly :func:`simulate_compiled`'s (same steps, events and
    arc); runs are spread over the machine's cores with numba ``prange``
    (``numba.set_num_threads`` limits them). The batch is processed in chunks
    whose sample pool stays under ``chunk_bytes``; a run longer than its
    slot is re-run alone, so memory is the returned arcs plus one chunk.

    Parameters
    ----------
    system : CompiledSystem
    x0s : array_like, shape (N, n)
        One initial state per row.
    parallel : bool
        False runs the batch on one core.
    chunk_bytes : int
        Memory budget of one chunk's sample pool.
    t_max, j_max, **options
        As in :func:`simulate_compiled`. With ``priority="random"`` the runs
        go one after another, each with its own ``numpy.random.default_rng(seed)``
        (as ``hs.simulate_many`` passes ``seed`` to every run).

    Returns
    -------
    list of HybridArc
        One per row of ``x0s``, in order.

    Examples
    --------
    >>> import numpy as np
    >>> from hybridsim.compiled import CompiledSystem, simulate_many_compiled
    >>> timer = CompiledSystem(flow=lambda x, t, j, p: np.ones(1),
    ...                        jump=lambda x, t, j, p: np.zeros(1),
    ...                        jump_guard=lambda x, t, j, p: x[0] - p[0],
    ...                        state_dim=1, params=[1.0])
    >>> arcs = simulate_many_compiled(timer, [[0.0], [0.5]], t_max=2.0)
    >>> [a.jump_count for a in arcs]
    [2, 2]
    """
    from ..options import check_bool as _check_bool
    from ..options import check_count as _check_count
    from ..rules import Priority
    k = _load_kernel()
    _check_system(system)
    n = system.state_dim
    try:
        X0 = np.array(x0s, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise TypeError(f"x0s must be an (N, {n}) array of floats, got "
                        f"{type(x0s).__name__}") from e
    if X0.ndim != 2 or X0.shape[1] != n:
        raise ValueError(f"x0s must have shape (N, {n}), got {X0.shape}")
    if not np.all(np.isfinite(X0)):
        raise ValueError("x0s must be finite")
    X0 = np.ascontiguousarray(X0)
    parallel = _check_bool("parallel", parallel)
    throw = _check_bool("throw", throw)
    warn = _check_bool("warn", warn)
    chunk_bytes = _check_count("chunk_bytes", chunk_bytes, minimum=1)
    system.compile()
    kern = _kernels(k, system, batch=parallel)
    fopt, iopt, atol_a, prio, ms, msa = _options(
        system, n, t_max, j_max, t0, j0, priority, rtol, atol, max_step, first_step,
        max_steps, max_samples, zeno_jumps, zeno_time, zeno_rtol, max_norm, refine, method,
        unsupported)
    nb = system._nb
    p = system.params
    maps = (nb["f"], nb["g"], nb["hD"], nb["hC"], nb["D"], nb["C"])
    lim = (ms, msa, fopt[6], zeno_jumps)
    N = len(X0)
    arcs = []
    if prio == Priority.RANDOM or not parallel:
        for x in X0:
            rng = _rng_for(prio, seed)
            out = kern[0](*maps, x, p, fopt, iopt, atol_a, rng)
            arcs.append(_arc(system, *out, lim))
    else:
        rng = _rng_for(prio, seed)
        # a few runs alone first: their length sizes the pool's slots
        i = min(N, 4)
        longest = 2
        for x in X0[:i]:
            out = kern[0](*maps, x, p, fopt, iopt, atol_a, rng)
            longest = max(longest, len(out[0]))
            arcs.append(_arc(system, *out, lim))
        cap = 1 << math.ceil(math.log2(longest * 1.25 + 1))
        per = (2 + 2 * n) * 8
        while i < N:
            B = int(max(64, min(N - i, chunk_bytes // (cap * per))))
            B = min(B, N - i)
            TT, JJ, XX, XXD, NS, CA, DE, INFO, ST = kern[1](
                *maps, X0[i:i + B], p, fopt, iopt, atol_a, rng, cap)
            # every run's samples in one compact array per field (one copy of
            # the pool), each arc a view of its rows
            ns_l, ca_l, de_l, st_l = NS.tolist(), CA.tolist(), DE.tolist(), ST.tolist()
            m_all = np.minimum(NS[:B], cap)
            keep = np.arange(cap) < m_all[:, None]
            Tf, Jf, Xf, XDf = TT[keep], JJ[keep], XX[keep], XXD[keep]
            o = 0
            for r in range(B):
                m = ns_l[r]
                if m <= cap:
                    e = o + m
                    arcs.append(_arc(system, Tf[o:e], Jf[o:e], Xf[o:e], XDf[o:e], ca_l[r],
                                     de_l[r], INFO[r], st_l[r], lim))
                    o = e
                else:                  # longer than its slot: run it alone
                    out = kern[0](*maps, X0[i + r], p, fopt, iopt, atol_a, rng)
                    arcs.append(_arc(system, *out, lim))
                    o += cap
            # the next chunk's slots: room for the longest run seen, with margin
            longest = int(NS.max()) if B else cap
            cap = max(cap, 1 << math.ceil(math.log2(max(longest, 2) * 1.25)))
            del TT, JJ, XX, XXD
            i += B
    for arc in arcs:
        _finish(arc, throw, False)
    if warn:
        bad = [a for a in arcs if (a.termination in FAILURES or
                                   a.termination is Termination.MAX_STEPS)]
        if bad:
            warnings.warn(f"{len(bad)} of {N} runs ended on a failure, the first "
                          f"{bad[0].termination.name}: {bad[0].message}",
                          SimulationWarning, stacklevel=2)
    return arcs
