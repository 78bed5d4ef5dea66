"""The options of a run, parsed once per entry point: one module for every path.

:func:`hybridsim.simulate` (the Python path), the vectorized batch integrator
(:mod:`hybridsim.batch_vectorized`) and the compiled path
(:mod:`hybridsim.compiled`) validate their arguments here, so the same bad
input gets the same exception class and the same message on every path. Each
path declares what it supports (:data:`SUPPORTS`) and refuses the rest with
:func:`refuse`, naming the option and the path that has it.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, OdeSolver, Radau
from scipy.integrate._ivp.rk import RungeKutta

from ._rk import LEAN, RK4
from .rules import _SHOW, PRIORITIES, MapError, Priority

__all__ = ["RunOptions", "parse_run", "refuse", "SUPPORTS", "METHODS", "METHODS_ON",
           "method_on", "reads_past", "check_x0",
           "check_real", "check_count", "check_bool", "check_map_value", "check_options",
           "check_seed", "check_t_eval", "resolve_method", "check_dwell"]

METHODS = {"RK23": RK23, "RK45": RK45, "DOP853": DOP853, "Radau": Radau,
           "BDF": BDF, "LSODA": LSODA, "RK4": RK4}
#: the fixed-step methods: their step is ``max_step`` (:func:`hybridsim._rk.fixed_step`)
FIXED_STEP = ("RK4",)

#: what each path implements beyond the options every path shares (the
#: options of :class:`RunOptions`); anything else given there is refused by
#: :func:`refuse`
SUPPORTS = {
    "python": frozenset({"method", "inputs", "prehistory", "dense", "t_eval", "progress",
                         "dwell"}),
    "vectorized": frozenset({"progress", "method"}),
    "compiled": frozenset({"method"}),
}
#: the methods a path implements where it takes ``method`` (every one on the
#: Python path); the others are refused by name
METHODS_ON = {"vectorized": ("RK45", "DOP853", "RK4"),
              "compiled": ("RK45", "DOP853", "RK4")}
#: where to go for an option a path refuses
_WHERE = {"inputs": "hs.simulate, or close the loop with hs.connect first",
          "prehistory": "hs.simulate (the Python path)",
          "dense": "hs.simulate (the Python path)",
          "t_eval": "hs.simulate (the Python path)",
          "progress": "hs.simulate or hs.simulate_many",
          "dwell": "hs.simulate (the Python path) or hs.explore",
          "jump_map_values": "hs.simulate (the Python path) or hs.explore"}


def refuse(path, name, value):
    """Raise the one error for an option a path does not implement.

    Parameters
    ----------
    path : {"python", "vectorized", "compiled"}
    name : str
        The option's name.
    value : object
        What the caller gave.

    Raises
    ------
    ValueError
        Naming the option, the value, the path and where the option is supported.

    Examples
    --------
    >>> refuse("compiled", "dense", True)
    Traceback (most recent call last):
    ...
    ValueError: dense=True is not supported on the compiled path; use hs.simulate (the Python path)
    """
    raise ValueError(f"{name}={value!r} is not supported on the {path} path; use "
                     f"{_WHERE.get(name, 'hs.simulate (the Python path)')}")


def _has_bool(x0):
    """Whether x0 is, or holds, a bool (numpy would read True as 1.0)."""
    if isinstance(x0, (bool, np.bool_)):
        return True
    if isinstance(x0, np.ndarray):
        return x0.dtype == np.bool_ or (x0.dtype == object
                                        and any(_has_bool(v) for v in x0.ravel()))
    if isinstance(x0, (list, tuple)):
        return any(_has_bool(v) for v in x0)
    return False


def check_x0(x0, n):
    """x0 as a float array of shape (n,): real, finite, no bools.

    Examples
    --------
    >>> check_x0([1, 2.5], 2)
    array([1. , 2.5])
    >>> check_x0([True, 0.0], 2)
    Traceback (most recent call last):
    ...
    TypeError: x0 must be an array of 2 real numbers, got booleans in [True, 0.0] ...
    """
    if np.iscomplexobj(x0):
        raise TypeError(f"x0 must be real, got complex values {x0!r}")
    if _has_bool(x0):
        raise TypeError(f"x0 must be an array of {n} real numbers, got booleans in {x0!r} "
                        f"(numpy would read True as 1.0): give floats, e.g. "
                        f"np.asarray(x0, dtype=float)")
    try:
        x = np.array(x0, dtype=float)
    except (TypeError, ValueError) as e:
        raise TypeError(f"x0 must be an array of {n} floats, got {type(x0).__name__}") from e
    if x.ndim == 0 and n == 1:
        x = x.reshape(1)
    if x.shape != (n,):
        raise ValueError(f"x0 must have shape ({n},) (the system's state_dim), got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"x0 must be finite, got {x}")
    return x


def check_real(name, v, *, allow_inf=False, positive=False, nonneg=False):
    if type(v) is not float and (isinstance(v, bool) or not isinstance(v, numbers.Real)):
        raise TypeError(f"{name} must be a real number, got {type(v).__name__} {v!r}")
    v = float(v)
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise ValueError(f"{name} must be finite, got {v}")
    if positive and not v > 0:
        raise ValueError(f"{name} must be > 0, got {v}")
    if nonneg and v < 0:
        raise ValueError(f"{name} must be >= 0, got {v}")
    return v


def check_count(name, v, *, minimum=0, allow_inf=False):
    """An int >= minimum (or inf where allowed): bools, floats like 2.7 and None refused."""
    if allow_inf and isinstance(v, float) and math.isinf(v) and v > 0:
        return math.inf
    if type(v) is not int and (isinstance(v, bool) or not isinstance(v, numbers.Integral)):
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        else:
            desc = "a non-negative int" if minimum == 0 else f"an int >= {minimum}"
            raise TypeError(f"{name} must be {desc}{' (or inf)' if allow_inf else ''}, "
                            f"got {type(v).__name__} {v!r}")
    if v < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {v}")
    return int(v)


def check_bool(name, v, *, allow_none=False):
    if v is None and allow_none:
        return None
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    raise TypeError(f"{name} must be True or False{' or None' if allow_none else ''}, "
                    f"got {v!r}")


def check_map_value(name, val, n, t=None, j=None):
    """Check a flow/jump map's value: real, finite, shape (n,). Returns a float array."""
    if type(val) is np.ndarray and val.shape == (n,) and val.dtype.kind == "f" \
            and math.isfinite(val.sum()):
        return val
    where = "" if t is None else f" (at t={t:.10g}, j={j})"
    if np.iscomplexobj(val):
        raise MapError(f"{name} returned complex values {val!r}{where}: the state is real",
                       name, t, j)
    try:
        arr = np.asarray(val, dtype=float)
    except (TypeError, ValueError) as e:
        raise MapError(f"{name} must return an array of {n} floats, got "
                       f"{type(val).__name__}{where}", name, t, j) from e
    if arr.shape != (n,):
        raise MapError(f"{name} must return an array of shape ({n},), got shape "
                       f"{arr.shape}{where}", name, t, j)
    if not np.all(np.isfinite(arr)):
        raise MapError(f"{name} returned non-finite values {arr}{where}", name, t, j)
    return arr



def resolve_method(method):
    if isinstance(method, str):
        if method not in METHODS:
            raise ValueError(f"method must be one of {sorted(METHODS)} or an OdeSolver "
                             f"subclass, got {method!r}")
        return METHODS[method]
    if isinstance(method, type) and issubclass(method, OdeSolver):
        if method is OdeSolver or method is RungeKutta or \
                getattr(method, "_step_impl", None) is OdeSolver._step_impl:
            raise TypeError(f"method must be a concrete OdeSolver subclass (one that "
                            f"implements _step_impl), got the abstract {method.__name__}")
        return method
    raise TypeError(f"method must be a string or an OdeSolver subclass, got {method!r}")


def check_options(system, n, t0, t_max, j_max, priority, rtol, atol, max_step,
                  first_step, max_norm, zeno_time):
    """Validate the options shared by :func:`simulate` and the batch integrator.

    Returns them normalised: ``(t0, t_max, j_max, prio, rtol, atol, max_step,
    first_step, max_norm, zeno_time)`` with ``prio`` a :class:`Priority` and
    ``max_step`` capped by ``system.max_step``.
    """
    t0 = check_real("t0", t0)
    t_max = check_real("t_max", t_max, allow_inf=True)
    if t_max < t0:
        raise ValueError(f"t_max must be >= t0 = {t0}, got {t_max}")
    j_max = check_count("j_max", j_max, allow_inf=True)
    if priority not in PRIORITIES:
        raise ValueError(f"priority must be one of {PRIORITIES}, got {priority!r}")
    prio = Priority(PRIORITIES.index(priority))
    rtol = check_real("rtol", rtol, positive=True)
    if np.ndim(atol) == 0:
        atol = check_real("atol", atol, positive=True)
    else:
        try:
            atol = np.asarray(atol, dtype=float)
        except (TypeError, ValueError) as e:
            raise TypeError(f"atol must be a positive float or an array of shape ({n},), "
                            f"got {atol!r}") from e
        if atol.shape != (n,) or not np.all(np.isfinite(atol)) or not np.all(atol > 0):
            raise ValueError(f"atol must be a positive float or an array of shape "
                             f"({n},) of positive finite floats, got {atol!r}")
    max_step = check_real("max_step", max_step, allow_inf=True, positive=True)
    if system.max_step is not None:
        max_step = min(max_step, check_real("system.max_step", system.max_step, positive=True))
    if first_step is not None:
        first_step = check_real("first_step", first_step, positive=True)
    max_norm = check_real("max_norm", max_norm, allow_inf=True, positive=True)
    zeno_time = check_real("zeno_time", zeno_time, nonneg=True)
    return (t0, t_max, j_max, prio, rtol, atol, max_step, first_step, max_norm, zeno_time)


def check_seed(seed, build=True):
    """The run's random generator from ``seed`` (checked); None where not ``build``
    (only the random priority draws, and a generator costs ~20 us to make)."""
    if seed is None or isinstance(seed, np.random.Generator):
        return np.random.default_rng(seed) if build else None
    if isinstance(seed, bool) or not isinstance(seed, (numbers.Integral, np.random.SeedSequence)):
        raise TypeError(f"seed must be None, a non-negative int or a numpy Generator, "
                        f"got {type(seed).__name__} {seed!r}")
    if isinstance(seed, numbers.Integral) and seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    return np.random.default_rng(seed) if build else None


def check_delays(system):
    """``system.delays`` as a tuple of positive finite floats (every path's rule).

    Examples
    --------
    >>> class S:
    ...     delays = (0.5, 1)
    >>> check_delays(S())
    (0.5, 1.0)
    """
    delays = tuple(float(d) for d in (getattr(system, "delays", None) or ()))
    if any(not (math.isfinite(d) and d > 0) for d in delays):
        raise ValueError(f"system.delays must be positive finite floats, got {system.delays!r}")
    return delays


def check_dwell(dwell, prio):
    """The dwell law in C ∩ D as a callable ``rng -> float >= 0`` (or None).

    ``dwell`` is a scipy.stats frozen distribution (anything with
    ``rvs(random_state=...)``) or a callable ``dwell(rng) -> float``; only
    with ``priority="random"``. Each drawn value is checked (a real number
    >= 0, ``inf`` allowed: flow on).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy import stats
    >>> law = check_dwell(stats.uniform(0.0, 2.0), Priority.RANDOM)
    >>> 0.0 <= law(np.random.default_rng(1)) <= 2.0
    True
    >>> check_dwell(0.5, Priority.RANDOM)
    Traceback (most recent call last):
    ...
    TypeError: dwell must be a scipy.stats frozen distribution or a callable ...
    """
    if dwell is None:
        return None
    if hasattr(dwell, "rvs"):
        def draw(rng, _d=dwell):
            return _d.rvs(random_state=rng)
    elif callable(dwell):
        draw = dwell
    else:
        raise TypeError(f"dwell must be a scipy.stats frozen distribution or a callable "
                        f"rng -> float, got {type(dwell).__name__} {dwell!r}")
    if prio != Priority.RANDOM:
        raise ValueError(f"dwell is the law of the time spent in C ∩ D under "
                         f"priority='random'; got priority={PRIORITIES[int(prio)]!r}")

    def law(rng):
        # a failure is the user's, as a map's: MAP_ERROR (raised under throw=True)
        try:
            v = draw(rng)
        except Exception as e:
            raise MapError(f"dwell raised {type(e).__name__}: {e}", "dwell") from e
        try:
            f = float(np.asarray(v, dtype=float).reshape(()))
        except (TypeError, ValueError) as e:
            raise MapError(f"dwell must draw a real number >= 0 (or inf), got "
                           f"{type(v).__name__} {v!r}", "dwell") from e
        if not f >= 0.0:
            raise MapError(f"dwell must draw a real number >= 0 (or inf), got {f!r}", "dwell")
        return f
    return law


def check_t_eval(t_eval, t0, t_max):
    if t_eval is None:
        return None
    try:
        te = np.asarray(t_eval, dtype=float)
    except (TypeError, ValueError) as e:
        raise TypeError(f"t_eval must be a 1-D array of times, got {type(t_eval).__name__}") from e
    if te.ndim != 1:
        raise ValueError(f"t_eval must be 1-D, got shape {te.shape}")
    if not np.all(np.isfinite(te)):
        raise ValueError("t_eval must be finite")
    if np.any(np.diff(te) <= 0):
        raise ValueError("t_eval must be strictly increasing (sorted, no repeated "
                         "times: both samples of a jump at a t_eval time are stored anyway)")
    if te.size and (te[0] < t0 or te[-1] > t_max):
        raise ValueError(f"t_eval must lie in [t0, t_max] = [{t0}, {t_max}], got "
                         f"[{te[0]}, {te[-1]}]")
    return te


def _is_default(name, value):
    """Whether an option has its do-nothing value (accepted by every path)."""
    if name == "method":
        return value is None or value == "RK45" or value is RK45
    if name in ("dense", "progress"):
        return value is None or value is False
    return value is None


def check_unsupported(path, given):
    """Refuse the options of ``given`` (a dict) that ``path`` does not implement
    and that are set to something other than their do-nothing value."""
    for name, value in given.items():
        if name not in SUPPORTS[path] and not _is_default(name, value):
            refuse(path, name, value)
        if name == "method" and path in METHODS_ON:
            method_on(path, value)


def reads_past(system):
    """Whether ``system``'s flow reads its past (``needs_history`` or ``delays``)."""
    return bool(getattr(system, "needs_history", False) or getattr(system, "delays", ()))


def method_on(path, method, system=None):
    """The name of ``method`` (a name or scipy's class) among the methods
    ``path`` implements (:data:`METHODS_ON`); refused by name otherwise.

    Parameters
    ----------
    path : {"vectorized", "compiled"}
        The integration path (the Python path takes every method).
    method : str, scipy ``OdeSolver`` subclass or None
        None means the default, "RK45".
    system : HybridSystem, optional
        The system to run: one that reads its past (:func:`reads_past`) is
        stepped with RK45 or RK4 only on these paths (their record of the
        past is RK45's dense output, whose form RK4's takes).

    Returns
    -------
    str
        "RK45", "DOP853" or "RK4".

    Raises
    ------
    ValueError
        An unknown ``path``; a method the path does not implement (naming
        the ones it has), or an unknown name (:func:`resolve_method`'s
        message); a method other than RK45 (or RK4) for a system reading its
        past.
    TypeError
        ``method`` neither a string nor an ``OdeSolver`` subclass.

    Examples
    --------
    >>> from scipy.integrate import DOP853
    >>> method_on("compiled", DOP853)
    'DOP853'
    >>> method_on("vectorized", "DOP853")
    'DOP853'
    >>> method_on("compiled", "RK4")
    'RK4'
    >>> method_on("compiled", "Radau")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: method='Radau' is not supported on the compiled path; use hs.simulate ...
    """
    names = METHODS_ON.get(path) if isinstance(path, str) else None
    if names is None:
        raise ValueError(f"path must be one of {sorted(METHODS_ON)}, got {path!r}")
    if method is None or (type(method) is str and method == "RK45"):
        return "RK45"
    cls = resolve_method(method)
    for name in names:
        if cls is METHODS[name] or cls is LEAN.get(METHODS[name]):
            # RK4's continuous extension has the record of the past's form (RK45's)
            if name not in ("RK45", "RK4") and system is not None and reads_past(system):
                raise ValueError(f"method={method!r} for a system that reads its past "
                                 f"(delays) is not supported on the {path} path; use "
                                 f"hs.simulate (the Python path)")
            return name
    others = " and ".join(repr(m) for m in names)
    raise ValueError(f"method={method!r} is not supported on the {path} path; use "
                     f"hs.simulate (the Python path) for methods other than {others}")


@dataclass(frozen=True)
class RunOptions:
    """The options every path shares, validated and normalised."""

    t0: float
    t_max: float
    j_max: float
    j0: int
    prio: Priority
    rtol: float
    atol: object
    max_step: float
    first_step: float | None
    max_norm: float
    zeno_jumps: int
    zeno_time: float
    zeno_rtol: float
    refine: int
    max_steps: float
    max_samples: float
    throw: bool
    warn: bool


def parse_run(system, n, *, t0=0.0, j0=0, t_max, j_max=math.inf, priority="jumps",
              rtol=1e-6, atol=1e-9, max_step=math.inf, first_step=None, max_norm=math.inf,
              zeno_jumps=50, zeno_time=1e-12, zeno_rtol=1e-7, refine=1,
              max_steps=1_000_000, max_samples=10_000_000, throw=True, warn=True,
              python=False):
    """Validate the options every path shares; one message per bad input.

    ``python``: the caller is the Python path; the others refuse a system
    with a set-valued jump map (``jump_map_values``) by name.

    Returns
    -------
    RunOptions

    Examples
    --------
    >>> import hybridsim as hs
    >>> sysm = hs.library.Timer()
    >>> parse_run(sysm, 1, t_max=2.0).prio.name
    'JUMPS'
    >>> parse_run(sysm, 1, t_max=2.0, zeno_jumps=0)
    Traceback (most recent call last):
    ...
    ValueError: zeno_jumps must be >= 1, got 0
    """
    (t0, t_max, j_max, prio, rtol, atol, max_step, first_step, max_norm,
     zeno_time) = check_options(system, n, t0, t_max, j_max, priority, rtol, atol, max_step,
                                first_step, max_norm, zeno_time)
    if not python and (getattr(system, "jump_rate", None) is not None
                       or getattr(system, "jump_law", None) is not None):
        raise ValueError(f"{type(system).__name__} declares jump_rate or jump_law (random "
                         f"jumps), which the vectorized path does not draw (the Python path "
                         f"runs both, the compiled path jump_rate); use hs.simulate or "
                         f"hs.simulate_many with backend='python' (or 'compiled' for a "
                         f"jump_rate) and a non-vectorized system")
    if not python and getattr(system, "diffusion", None) is not None:
        raise ValueError(f"{type(system).__name__} declares diffusion (an SDE flow), which "
                         f"the vectorized path does not step (the Python and compiled paths "
                         f"do); use hs.simulate or hs.simulate_many with backend='python' or "
                         f"'compiled' and a non-vectorized system")
    if not python and getattr(system, "jump_map_values", None) is not None:
        raise ValueError(f"{type(system).__name__} declares jump_map_values (a set-valued "
                         f"jump map), which only the Python path supports; use "
                         f"{_WHERE['jump_map_values']}")
    j0 = check_count("j0", j0)
    refine = check_count("refine", refine, minimum=1)
    max_steps = check_count("max_steps", max_steps, minimum=1, allow_inf=True)
    max_samples = check_count("max_samples", max_samples, minimum=2, allow_inf=True)
    if refine > max_samples:
        raise ValueError(f"refine must be <= max_samples = {max_samples}, got {refine}")
    zeno_jumps = check_count("zeno_jumps", zeno_jumps, minimum=1)
    zeno_rtol = check_real("zeno_rtol", zeno_rtol, nonneg=True)
    throw = check_bool("throw", throw)
    warn = check_bool("warn", warn)
    return RunOptions(t0, t_max, j_max, j0, prio, rtol, atol, max_step, first_step, max_norm,
                      zeno_jumps, zeno_time, zeno_rtol, refine, max_steps, max_samples,
                      throw, warn)


# ------------------------------------------------------------------ batches
def check_chunks(chunks):
    if chunks is None:
        return None
    if isinstance(chunks, bool) or not isinstance(chunks, numbers.Integral):
        raise TypeError(f"chunks must be a positive int or None (default: 4 per worker), "
                        f"got {type(chunks).__name__} {chunks!r}")
    if chunks < 1:
        raise ValueError(f"chunks must be a positive int or None (default: 4 per worker), "
                         f"got {chunks}")
    return int(chunks)


def check_executor(executor):
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise TypeError(f"executor must be a concurrent.futures.Executor (an object with a "
                        f".submit method, e.g. ProcessPoolExecutor()) or None, got "
                        f"{type(executor).__name__} {executor!r}")


def check_x0s(x0s, n):
    """x0s as an (N, n) float array, with messages naming x0s."""
    try:
        if np.iscomplexobj(x0s):
            raise TypeError("x0s must be real, got complex values")
        X = np.array(x0s, dtype=float)
    except (TypeError, ValueError) as e:
        if "x0s must be real" in str(e):
            raise
        detail = ""
        if isinstance(x0s, (list, tuple)):
            shapes = []
            for i, r in enumerate(x0s):
                try:
                    s = np.shape(r)
                except ValueError:
                    s = "ragged"
                if s != (n,):
                    shapes.append(f"row {i} has shape {s}")
            if not shapes:
                shapes = ["its rows do not form an array of floats"]
            if shapes:
                detail = ": " + ", ".join(shapes[:_SHOW]) + \
                    (f" and {len(shapes) - _SHOW} more" if len(shapes) > _SHOW else "")
        raise ValueError(f"x0s must be a rectangular array of shape (N, {n}) of floats (one "
                         f"initial state per row){detail or f'; got {type(x0s).__name__}'}") \
            from e
    if X.ndim != 2 or X.shape[1] != n:
        raise ValueError(f"x0s must have shape (N, {n}), got {X.shape}")
    return X


def check_params(params):
    if isinstance(params, (str, bytes)) or not isinstance(params, Iterable):
        raise TypeError(f"params must be an iterable of parameter values (a list, a range, "
                        f"an array...), got {type(params).__name__} {params!r}")
    return list(params)


def check_delay_times(delays):
    """``delays`` as a tuple of distinct positive finite floats (the one check of
    :class:`hybridsim.compiled.Component` and :class:`hybridsim.compiled.CompiledSystem`; errors
    name the argument)."""
    try:
        d = tuple(float(v) for v in (delays or ()))
    except (TypeError, ValueError):
        raise TypeError(f"delays must be a sequence of positive floats, got "
                        f"{delays!r}") from None
    if not all(math.isfinite(v) and v > 0.0 for v in d):
        raise ValueError(f"delays must be positive finite floats, got {d}")
    if len(set(d)) != len(d):
        raise ValueError(f"delays must be distinct, got {d}")
    return d
