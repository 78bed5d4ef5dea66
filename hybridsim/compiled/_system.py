"""The compiled path's system: :class:`CompiledSystem` (maps of ``(x, t, j, p)``
numba can compile, usable on the Python path too), its compiling, and the
engine loaded where numba is installed (:func:`_load_kernel`).
"""
from __future__ import annotations

import os
import time
import warnings

import numpy as np

from ..options import check_delay_times
from ..system import HybridSystem, renamed_keywords

_KIND_TEXT = {"vec": "an array of state_dim floats", "scalar": "a float"}


_INSTALL = "pip install 'hybridsim[fast]'"
_ROLES = (("flow", "vec"), ("jump", "vec"), ("jump_guard", "scalar"),
          ("flow_guard", "scalar"), ("jump_set", "bool"), ("flow_set", "bool"))
#: the keyword (and HybridSystem method) of each role of ``maps``
KEYWORDS = {"flow": "flow_map", "jump": "jump_map", "jump_guard": "jump_guard",
            "flow_guard": "flow_guard", "jump_set": "jump_set", "flow_set": "flow_set",
            "watch": "watch", "diffusion": "diffusion", "jump_rate": "jump_rate"}
#: the deprecated keywords of CompiledSystem and Component, ``{old: new}``
RENAMES = {"flow": "flow_map", "jump": "jump_map"}


def keywords(maps):
    """Maps keyed by role (``maps``' keys) as the keywords of
    :class:`CompiledSystem` and :class:`Component`."""
    return {KEYWORDS[role]: fn for role, fn in maps.items()}


class CompileError(TypeError):
    """A map of a :class:`CompiledSystem` could not be compiled by numba.

    ``map_name`` names the map; ``__cause__`` is numba's error. The Python
    path, ``hs.simulate(system, ...)``, runs the same system uncompiled.
    """

    def __init__(self, message, map_name=None):
        super().__init__(message)
        self.map_name = map_name


_K = None


def _load_kernel():
    global _K
    if _K is not None:
        return _K
    try:
        from . import _cache as k
    except ImportError as e:
        if "numba" not in str(e).lower():
            raise
        raise ImportError(f"the compiled path needs numba: {_INSTALL} (or pip install "
                          f"numba). Without it, run the same system on the Python path "
                          f"with hs.simulate / hs.simulate_many.") from e
    _K = k
    return k


def _refuse(what, why):
    return TypeError(f"backend='compiled': {what} cannot run compiled: {why}. Run it on "
                     f"the Python path (backend='python'), or see hybridsim.compiled's "
                     f"notes on lowering")


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


def _writes_into(fn):
    """Whether a map is written ``fn(x, t, j, p, out)`` (five positional parameters
    without defaults)."""
    import inspect
    try:
        ps = inspect.signature(getattr(fn, "py_func", fn)).parameters.values()
    except (TypeError, ValueError):
        return False
    return sum(q.kind in (q.POSITIONAL_ONLY, q.POSITIONAL_OR_KEYWORD)
               and q.default is q.empty for q in ps) == 5


def _returning(fn, shape):
    """A map written into ``out`` (of ``shape``) as the array it writes: the
    compiled form (numba's, calling ``fn`` compiled) and the Python path's."""
    def py_returning(x, t, j, p):
        out = np.empty(shape)
        fn(x, t, j, p, out)
        return out
    try:
        import numba
    except ImportError:
        return py_returning, py_returning
    jf = fn if hasattr(fn, "py_func") else numba.njit(error_model="numpy")(fn)

    def returning(x, t, j, p):
        out = np.empty(shape)
        jf(x, t, j, p, out)
        return out
    return returning, py_returning


class _PyMap:
    """A user map ``fn(x, t, j, p)`` seen by the Python path as ``(x, t, j)``."""

    __slots__ = ("fn", "system")

    def __init__(self, fn, system):
        self.fn, self.system = fn, system

    def __call__(self, x, t, j):
        s = self.system
        return self.fn(x, t, j, s._p_nan if s.delays else s.params)


class _PyFlowPast(_PyMap):
    """The flow map of a :class:`CompiledSystem` with ``delays`` on the Python
    path: ``p`` is the parameters followed by x(t - tau_i) for each delay, read
    from the run's :class:`hybridsim.History` (the kernel's convention)."""

    __slots__ = ()

    def __call__(self, x, t, j):
        s = self.system
        past = [s.history(t - d) for d in s.delays]
        return self.fn(x, t, j, np.concatenate([s.params, *past]))

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
    flow_map : callable
        ``f(x, t, j, p)``: the flow map, a 1-D array of n floats (or a tuple);
        or ``f(x, t, j, p, out)`` writing its n values into ``out`` (a float64
        array of shape (n,)) and returning nothing: the SDE stepper's
        Euler–Maruyama loop then evaluates it without making an array (the
        other paths see it as the array it writes).
    jump_map : callable, optional
        ``g(x, t, j, p)``: the jump map, receives the pre-jump j; or
        ``g(x, t, j, p, out)`` writing into ``out``, as ``flow_map``.
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
        A cap on the solver step (as :attr:`HybridSystem.max_step`); with
        ``delays``, at most the smallest delay.
    delays : tuple of float, optional
        Delays tau_1, ..., tau_m > 0 read by the flow map (a delay equation
        x' = f(x(t), x(t - tau_1), ..., x(t - tau_m))): the flow map's ``p``
        is then ``params`` followed by the m past states, ``p[len(params) +
        i n : len(params) + (i + 1) n] = x(t - tau_i)``, read as
        :class:`hybridsim.History` reads the past (the RK45 dense output;
        the post-jump value at a jump time; x0 before t0). The other maps see
        NaN there (they must not read the past). Flows stop at the
        breakpoints t_k + tau_i of the jumps t_k, on every path. Reading the
        past, the compiled path takes no ``prehistory``.
    specialize : bool
        False (default): the maps reach the engine as first-class functions;
        the engine is the one compiled kernel cached on disk, so a new system
        costs only its maps' compilation (about 1 s, see the module notes).
        True: the engine is compiled for this system with its maps inlined,
        10-20% faster per run; about 15 s of CPU the first time on a machine
        (and after a change of the maps), kept on disk and loaded in a
        fraction of a second by later processes (maps reading objects other
        than constants, arrays, modules and functions are compiled in each
        process instead).
    watch : callable, optional
        ``w(x, t, j, p)``: functions watched along the flows, a float or a
        1-D array (rule 11 of :class:`hybridsim.HybridSystem`): their
        crossings of 0 are recorded in ``arc.crossings``, on the Python path
        and compiled (with RK45, without ``delays`` or ``specialize``): the
        compiled path then runs the engine's watching kernel, compiled
        (about 20 s of CPU, once per machine) when a watching system first
        runs; systems without watch never compile it.
    watch_direction : int or sequence of int
        -1, 0 (default) or 1 per watched function: falling, both, rising.
    diffusion : callable, optional
        ``s(x, t, j, p)``: an SDE flow's diffusion (dx = f dt + σ dW, as
        :attr:`hybridsim.HybridSystem.diffusion`): shape (n,) for diagonal
        noise, (n, noise_dim) for general noise; or ``s(x, t, j, p, out)``
        writing into ``out`` of that shape, as ``flow_map``. Runs on the
        Python path and compiled (:mod:`hybridsim.compiled._stochastic`).
    noise_dim : int, optional
        None (diagonal noise) or the dimension m of W (general noise).
    jump_rate : callable, optional
        ``r(x, t, j, p)``: a jump rate, a float >= 0 (as
        :attr:`hybridsim.HybridSystem.jump_rate`).
    name : str, optional
        For ``repr``.
    **deprecated
        The former names ``flow`` and ``jump`` of ``flow_map`` and
        ``jump_map``: accepted with a ``DeprecationWarning``.

    Attributes
    ----------
    maps : dict
        The maps given, by role: ``"flow"``, ``"jump"``, ``"jump_guard"``,
        ``"flow_guard"``, ``"jump_set"``, ``"flow_set"`` (``KEYWORDS`` gives
        each role's keyword).

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> from hybridsim.compiled import CompiledSystem
    >>> ball = CompiledSystem(
    ...     flow_map=lambda x, t, j, p: np.array([x[1], -p[0]]),
    ...     jump_map=lambda x, t, j, p: np.array([0.0, -p[1] * x[1]]),
    ...     jump_guard=lambda x, t, j, p: -x[0], flow_guard=lambda x, t, j, p: x[0],
    ...     jump_set=lambda x, t, j, p: x[0] <= 0.0 and x[1] <= 0.0,
    ...     state_dim=2, params=[9.81, 0.8])
    >>> arc = hs.simulate(ball, [1.0, 0.0], t_max=2.0, j_max=3)   # the Python path
    >>> arc.jump_count
    3

    A delay equation x' = -x(t - 1), past x = 1: the flow map reads x(t - 1)
    at ``p[len(params):]`` (method of steps: x(2) = -1/2).

    >>> lag = CompiledSystem(flow_map=lambda x, t, j, p: -p[0:1], state_dim=1,
    ...                      delays=(1.0,))
    >>> round(float(hs.simulate(lag, [1.0], t_max=2.0).x[-1, 0]), 9)
    -0.5
    """

    def __init__(self, flow_map=None, jump_map=None, *, jump_guard=None, flow_guard=None,
                 jump_set=None, flow_set=None, state_dim, params=(), max_step=None,
                 delays=(), specialize=False, name=None, watch=None, watch_direction=0,
                 diffusion=None, noise_dim=None, jump_rate=None, **deprecated):
        HybridSystem.__init__(self)
        if deprecated:
            given = renamed_keywords("CompiledSystem", deprecated, RENAMES,
                                     {"flow_map": flow_map, "jump_map": jump_map})
            flow_map, jump_map = given["flow_map"], given["jump_map"]
        if isinstance(state_dim, bool) or not isinstance(state_dim, (int, np.integer)) \
                or state_dim < 1:
            raise ValueError(f"state_dim must be a positive int, got {state_dim!r}")
        self.state_dim = int(state_dim)
        self.delays = check_delay_times(delays)
        self.needs_history = bool(self.delays)
        self.params = params
        if self.delays:     # a step must not reach past the smallest delay (hs.History)
            cap = min(self.delays)
            max_step = cap if max_step is None else min(float(max_step), cap)
        self.max_step = max_step
        self.specialize = specialize
        self._name = name
        self.maps = {}
        for role, fn in (("flow", flow_map), ("jump", jump_map), ("jump_guard", jump_guard),
                         ("flow_guard", flow_guard), ("jump_set", jump_set),
                         ("flow_set", flow_set), ("diffusion", diffusion),
                         ("jump_rate", jump_rate)):
            if fn is None:
                continue
            if not callable(fn):
                raise TypeError(f"{KEYWORDS[role]} must be callable fn(x, t, j, p), got "
                                f"{type(fn).__name__}")
            self.maps[role] = fn
        self.noise_dim = noise_dim
        #: the maps written into an argument, by role (``maps`` holds their arrays)
        self.maps_into = {}
        py_into = {}
        n = self.state_dim
        for role, shape in (("flow", (n,)), ("jump", (n,)), ("diffusion", (
                n,) if noise_dim is None else (n, noise_dim))):
            fn = self.maps.get(role)
            if fn is not None and _writes_into(fn):
                self.maps_into[role] = fn
                self.maps[role], py_into[role] = _returning(fn, shape)
        if flow_map is None:
            raise TypeError("flow_map is required: a function flow_map(x, t, j, p) -> array "
                            "of state_dim floats")
        # the Python path sees the same maps through HybridSystem's attributes
        for role, fn in self.maps.items():
            cls = _PyFlowPast if role == "flow" and self.delays else _PyMap
            setattr(self, KEYWORDS[role], cls(py_into.get(role, fn), self))
        if watch is not None:
            if not callable(watch):
                raise TypeError(f"watch must be callable fn(x, t, j, p), got "
                                f"{type(watch).__name__}")
            self.watch = _PyMap(watch, self)
            self.watch_direction = watch_direction
        elif not (isinstance(watch_direction, (int, np.integer)) and watch_direction == 0):
            raise TypeError("watch_direction without watch: give the watched functions as "
                            "watch=")
        self._nb = None

    @property
    def specialize(self):
        """Whether the system runs on a kernel of its own with its maps compiled
        in (True) or on the engine's kernel, its maps by address (False).
        Changing it drops what was compiled: the next run compiles (or loads)
        the other form."""
        return self._specialize

    @specialize.setter
    def specialize(self, value):
        if not isinstance(value, (bool, np.bool_)):
            raise TypeError(f"specialize must be True or False, got {value!r}")
        value = bool(value)
        if self.__dict__.get("_specialize", value) != value:
            self._nb = None
        self._specialize = value

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
        # what maps other than the flow map see as p: the past's place is NaN
        self._p_nan = np.concatenate([self._params, np.full(
            len(getattr(self, "delays", ())) * self.state_dim, np.nan)])

    def __getstate__(self):
        state = HybridSystem.__getstate__(self)
        state["_nb"] = None           # compiled functions are rebuilt after unpickling
        state.pop("_batch_lengths", None)       # a batch's sizing memo (of this process)
        return state

    def compile(self):
        """Compile the maps (once per system; later calls return at once), and
        with ``specialize=True`` the system's own kernel, or load it from the
        disk cache.

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
            if self.specialize:
                self._nb = self._compile_specialised(k, numba)
            else:
                # the cached kernels take the maps by address
                out = self._compile_maps(k, numba)
                out = {role: k.handle(d, self._kinds[role]) for role, d in out.items()}
                absent = {"vec": k.handle(k.absent_vec, "vec"),
                          "scalar": k.handle(k.absent_scalar, "scalar"),
                          "false": k.handle(k.absent_false, "bool"),
                          "true": k.handle(k.absent_true, "bool")}
                nb = self._flags(out, absent)
                six = tuple(nb[r] for r in ("f", "g", "hD", "hC", "D", "C"))
                if self.watch is not None:      # the seventh: the watched functions
                    nb["W"] = k.handle(self._compile_watch(k, numba), "vec")
                    six += (nb["W"],)
                nb["args"] = (k.map_addresses(six),)
                nb["one"] = None                # k.run_kernel(delays), once compiled
                self._nb = nb
        return time.perf_counter() - t

    @staticmethod
    def _flags(out, absent):
        """The six maps (absent ones filled in) and what the kernel reads of them.

        A set without its indicator is {guard >= 0}, read by the kernel from
        the guard itself (a NaN guard is then the Python path's MapError)."""
        return {
            "f": out["flow"], "g": out.get("jump", absent["vec"]),
            "hD": out.get("jump_guard", absent["scalar"]),
            "hC": out.get("flow_guard", absent["scalar"]),
            "D": out.get("jump_set", absent["false"]), "C": out.get("flow_set", absent["true"]),
            "has_C": "flow_set" in out or "flow_guard" in out,
            "has_D": "jump_set" in out or "jump_guard" in out,
            "has_hC": "flow_guard" in out, "has_hD": "jump_guard" in out,
            "C_from_guard": "flow_set" not in out and "flow_guard" in out,
            "D_from_guard": "jump_set" not in out and "jump_guard" in out,
            "memo": {},
        }

    def _compile_specialised(self, k, numba, method="RK45"):
        """The run kernel specialised on this system's maps: a generated module
        keyed by the maps' digest, cached on disk by numba (see
        ``_cache.spec_module``); a new process with the kernel in its cache
        compiles nothing. Maps whose digest cannot be taken (they read an object
        that is not a constant, array, module or function) compile in memory.
        ``method``: "RK45" (made by :meth:`compile`), "DOP853" or "RK4" (made
        when a run first asks for it)."""
        entries = tuple((role, kind, self.maps.get(role)) for role, kind in _ROLES)
        # a flow map written into an array: the steps call it so (``_kernel._INTO``)
        into = self.maps_into.get("flow") if not self.delays else None
        if into is not None:
            entries += (("flow_into", "into", into),)
            into = into if isinstance(into, numba.core.dispatcher.Dispatcher) else \
                numba.njit(error_model="numpy", _nrt=True)(into)
        try:
            delays = bool(self.delays)
            mod = k.spec_module(k.spec_key(entries, delays, method), delays, method,
                                into is not None)
        except k.Unkeyable:
            mod = None
        sig = k._signature_one()
        if mod is not None and mod.one.overloads:       # compiled in this process
            out = {role: None for role in self.maps}
            one = mod.one
        else:
            cached = mod is not None and k.spec_in_cache(mod)
            if cached:                   # loaded below: the maps are never compiled
                out = {role: k.wrap_map(fn, kind, lazy=True) for role, kind in _ROLES
                       if (fn := self.maps.get(role)) is not None}
            else:
                # in memory: the kernel cached with them must load with nothing else
                out = self._compile_maps(k, numba, in_memory=True)   # names a map refused
                _notice(os.path.dirname(mod.__file__) if mod is not None else None,
                        k.COMPILE_SECONDS[2],
                        what="a kernel specialised on this system's maps")
            absent = {"vec": k.absent_vec, "scalar": k.absent_scalar,
                      "false": k.absent_false, "true": k.absent_true}
            nb = self._flags(out, absent)
            f, g, hD, hC, D, C = (nb[r] for r in ("f", "g", "hD", "hC", "D", "C"))
            if mod is not None:
                mod.f, mod.g, mod.hD, mod.hC, mod.D, mod.C = f, g, hD, hC, D, C
                mod.fi = into
                one = mod.one
            else:
                run = {("DOP853", False): k.run_one_spec_dop853,
                       ("RK4", False): k.run_one_spec_rk4,
                       ("RK4", True): k.run_one_spec_rk4_delays,
                       ("RK45", True): k.run_one_spec_delays,
                       ("RK45", False): k.run_one_spec}[method, bool(self.delays)]

                def one_mem(maps, x0, p, fopt, iopt, atol, rngp, poll, stop):
                    return run((f, g, hD, hC, D, C), x0, p, fopt, iopt, atol, rngp, poll, stop)
                one = numba.njit(error_model="numpy")(one_mem)
            one.compile(sig)
            one.disable_compile()
        nb = self._flags(out, {"vec": None, "scalar": None, "false": None, "true": None})
        nb["one"] = one
        nb["one_addr"] = k.jit_address(one)
        nb["args"] = (_NO_MAPS,)
        return nb

    def _compile_maps(self, k, numba, in_memory=False):
        """The maps wrapped for the kernels (``k.wrap_map``: cached on disk;
        ``in_memory``: compiled here, for a kernel that numba caches with them)."""
        wrap = k._wrap_in_memory if in_memory else k.wrap_map
        out = {}
        self._kinds = {}
        for role, kind in _ROLES:
            fn = self.maps.get(role)
            if fn is None:
                continue
            try:
                out[role] = wrap(fn, kind)
                self._kinds[role] = kind
            except (numba.core.errors.NumbaError, TypeError, ValueError, NotImplementedError,
                    AttributeError, KeyError) as e:
                raise CompileError(
                    f"CompiledSystem: numba could not compile the map {KEYWORDS[role]!r} "
                    f"({getattr(fn, '__qualname__', repr(fn))}): {_summarise(e)}. Write it "
                    f"as a numpy function of (x, t, j, p) returning "
                    f"{_KIND_TEXT.get(kind, 'a bool')}, "
                    f"or run this system on the Python path with hs.simulate(system, ...) "
                    f"(the fallback, same maps, no compiling)", KEYWORDS[role]) from e
        return out

    def _compile_watch(self, k, numba):
        """The watched functions compiled to the kernel's vector signature (a
        float becomes one value; :func:`._watch.wrap_watch`)."""
        from ._watch import wrap_watch
        fn = self.watch.fn
        try:
            return wrap_watch(fn)
        except (numba.core.errors.NumbaError, TypeError, ValueError, NotImplementedError,
                AttributeError, KeyError) as e:
            raise CompileError(
                f"CompiledSystem: numba could not compile the map 'watch' "
                f"({getattr(fn, '__qualname__', repr(fn))}): {_summarise(e)}. Write it as a "
                f"numpy function of (x, t, j, p) returning a float or a 1-D array of floats, "
                f"or run this system on the Python path with hs.simulate(system, ...)",
                "watch") from e

    def __repr__(self):
        name = self._name or "CompiledSystem"
        return f"<{name}: state_dim={self.state_dim}, maps={sorted(self.maps)}>"


_NO_MAPS = np.zeros(6, np.int64)


def _notice(cache_dir, seconds, what="the engine's kernels"):
    """Say, once per kernel, that it is being compiled and kept (the first
    compiled call on a machine is otherwise silent for seconds).

    Written to stderr as one line, as pip or a compiler would: a notice, not a
    warning (nothing is wrong, and ``-W error`` must not turn it into a
    failure), and not only ``logging.info``, which nobody sees unless logging
    is configured. Where the application has configured logging (a handler on
    the ``hybridsim`` logger or the root), it goes there instead, at INFO.
    """
    import logging
    import sys
    where = (f"numba caches it in {cache_dir}" if cache_dir else
             "not cached: compiled again in each process")
    msg = (f"hybridsim.compiled: compiling {what}, once per machine (about {seconds:.0f} s "
           f"of CPU); {where}")
    log = logging.getLogger("hybridsim.compiled")
    if log.hasHandlers():
        log.info(msg)
        return
    try:
        sys.stderr.write(msg + " ...\n")
        sys.stderr.flush()
    except (AttributeError, OSError, ValueError):   # no stderr (pythonw, closed)
        pass
