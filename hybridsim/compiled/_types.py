"""The compiled path's ground floor (imported only when numba is installed):
constants (the Runge-Kutta tables, cause and detail codes), the maps' numba
signatures and the calls of a map, the Ctrl-C poll and the random draw by
their C addresses, and the handles that pass them from Python.

Every function of :mod:`hybridsim.rules`, and the algorithms' steps of
:mod:`hybridsim.events` (:data:`hybridsim.events.COMPILED`) and the first-step
rule of :mod:`hybridsim._rk` (:data:`hybridsim._rk.COMPILED`), are made callable
from compiled code here as they are (``register_jitable``): not written again.
"""
from __future__ import annotations

import inspect
import math
import os
import warnings

import numba
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.core import errors as nb_errors
from numba.extending import intrinsic, overload, register_jitable, typeof_impl
from scipy.integrate._ivp import dop853_coefficients as _dop
from scipy.integrate._ivp.rk import DOP853, RK45

from .. import _rk, events, rules
from .._rk import MAX_FACTOR, MIN_FACTOR, SAFETY
from ._private import unsafe

# A parallel batch runs its rows in Python threads calling the GIL-free
# :func:`run_rows`: no numba threading layer is started for it. Where one is
# started all the same (numba.set_num_threads, the user's own prange), a
# fork-safe one (a process pool that forks after a parallel region dies under
# GNU OpenMP): TBB where installed, else numba's workqueue; the user's choice
# (NUMBA_THREADING_LAYER) is kept.
if os.environ.get("NUMBA_THREADING_LAYER") is None and numba.config.THREADING_LAYER == "default":
    numba.config.THREADING_LAYER_PRIORITY = ["tbb", "workqueue", "omp"]

# ------------------------------------------------------------------ the rules
# Every function of hybridsim.rules becomes callable from compiled code as it is
# (register_jitable compiles it where a kernel calls it; nothing is copied),
# without the C wrapper numba makes for each by default (only compiled code
# calls them: 24 wrappers of the first compile; also the overloads below)
_CALLEE = dict(no_cfunc_wrapper=True)
for _name, _fn in vars(rules).items():
    if inspect.isfunction(_fn) and _fn.__module__ == rules.__name__:
        register_jitable(**_CALLEE)(_fn)
# ... and so does each algorithm's step of hybridsim.events written for both paths
for _fn in events.COMPILED:
    register_jitable(**_CALLEE)(_fn)
# ... and the first-step rule and step-size controller of hybridsim._rk (the
# controller, read at every step, inlined into the run core)
for _fn in _rk.COMPILED:
    register_jitable(**_CALLEE, **({"inline": "always"} if _fn is _rk.step_factor else {}))(_fn)


# ------------------------------------------------------------------ constants
_EPS = float(np.finfo(float).eps)
_INVPHI = (math.sqrt(5.0) - 1.0) / 2.0
_A = np.ascontiguousarray(RK45.A, dtype=np.float64)
_B = np.ascontiguousarray(RK45.B, dtype=np.float64)
_Cc = np.ascontiguousarray(RK45.C, dtype=np.float64)
_E = np.ascontiguousarray(RK45.E, dtype=np.float64)
_P = np.ascontiguousarray(RK45.P, dtype=np.float64)
# scipy's step-size controller constants (hybridsim._rk takes them from scipy)
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = SAFETY, MIN_FACTOR, MAX_FACTOR
_ERR_EXP = -1.0 / (RK45.error_estimator_order + 1)
_ORDER = float(RK45.error_estimator_order)
# scipy's DOP853 (Dormand-Prince 8(5,3)): 12 stages, the 3 more of its dense output
_A8 = np.ascontiguousarray(DOP853.A, dtype=np.float64)
_B8 = np.ascontiguousarray(DOP853.B, dtype=np.float64)
_C8 = np.ascontiguousarray(DOP853.C, dtype=np.float64)
_E3 = np.ascontiguousarray(DOP853.E3, dtype=np.float64)
_E5 = np.ascontiguousarray(DOP853.E5, dtype=np.float64)
_A8X = np.ascontiguousarray(_dop.A, dtype=np.float64)     # the extra stages' rows too
_C8X = np.ascontiguousarray(_dop.C, dtype=np.float64)
_D8 = np.ascontiguousarray(DOP853.D, dtype=np.float64)
# the classic RK4 with a fixed step (hybridsim._rk.RK4): 4 stages, no error estimate,
# its continuous extension in RK45's dense-output form (hybridsim._rk.RK4_P4)
_A4 = np.ascontiguousarray(_rk.RK4_TABLEAU["A"], dtype=np.float64)
_B4 = np.ascontiguousarray(_rk.RK4_TABLEAU["B"], dtype=np.float64)
_C4 = np.ascontiguousarray(_rk.RK4_TABLEAU["C"], dtype=np.float64)
_P4 = np.ascontiguousarray(_rk.RK4_P4, dtype=np.float64)
_RK4_SNAP = float(_rk.RK4_SNAP)
_JUMPS, _FLOWS, _RANDOM = int(rules.Priority.JUMPS), int(rules.Priority.FLOWS), \
    int(rules.Priority.RANDOM)
_A_JUMP, _A_FLOW, _A_STOP = int(rules.Action.JUMP), int(rules.Action.FLOW), \
    int(rules.Action.STOP)

#: cause codes returned by the kernels: ``rules.CODES`` (names of
#: :class:`hybridsim.rules.Termination`, in ``rules.CAUSES``'s order)
CAUSES = tuple(c.name for c in rules.CAUSES)
_T = rules.Termination
T_MAX, J_MAX, NOT_IN_SETS, LEFT_SETS, NON_FINITE, BLOWUP, SOLVER_FAILED, MAP_ERROR, ZENO, \
    MAX_STEPS, CANCELED = (rules.CODES[c] for c in (
        _T.T_MAX, _T.J_MAX, _T.NOT_IN_SETS, _T.LEFT_SETS, _T.NON_FINITE, _T.BLOWUP,
        _T.SOLVER_FAILED, _T.MAP_ERROR, _T.ZENO, _T.MAX_STEPS, _T.CANCELED))
_GOES_ON = rules.NO_CAUSE
_OUTSIDE = -2                   # in neither set: decided by ``_Run._stop_outside``'s rules
#: MAP_ERROR details (which map, and where)
MAP_JUMP_SHAPE, MAP_JUMP_VALUE, MAP_FLOW_SHAPE, MAP_FLOW_X0, MAP_JUMP_X0, MAP_GUARD, \
    MAP_HISTORY = range(7)
#: the detail code of a J_MAX or ZENO end after a jump loop (``rules.is_jump_loop``;
#: ZENO's others: 0 the Zeno test, 1 sticking, 2 flows too short to resolve)
DETAIL_LOOP = 3
#: the detail codes of a J_MAX end after jumps at one instant not all from C
#: (``rules.is_jump_loop`` on their count) and after chattering
#: (``rules.chatter_step``'s count of tiny flows)
DETAIL_INSTANT = 4
DETAIL_CHATTER = 5

# flow outcomes
_O_TMAX, _O_JUMP, _O_FLOW_ON, _O_STOP, _O_BREAK = 0, 1, 2, 3, 4

# ------------------------------------------------------------------ the disk cache
def _probe():  # pragma: no cover - never called: its file locates numba's cache
    pass


def _engine_cache():
    """Whether the engine's kernels are kept in numba's disk cache: only where
    its folder (the one numba picks for this package's files) is private to
    the user (:func:`hybridsim.compiled._private.unsafe`): numba's index files
    are pickles, which run code when loaded. Elsewhere the kernels compile in
    memory, and a warning says why."""
    from numba.core.caching import FunctionCache
    try:
        path = FunctionCache(_probe)._cache_path
    except Exception:  # noqa: BLE001 - no cache folder numba can use (numba says so)
        return True
    why = unsafe(path)
    if why is None:
        return True
    warnings.warn(f"hybridsim.compiled: numba's cache folder {path} is not private ({why}): "
                  f"the engine's kernels are compiled in memory in each process, not read "
                  f"from or kept there. Point NUMBA_CACHE_DIR at a folder of your own",
                  RuntimeWarning, stacklevel=2)
    return False


#: whether the engine's kernels are cached on disk (``cache=`` of each)
CACHE = _engine_cache()


# ------------------------------------------------------------------ map signatures
_ARGS = (types.float64[::1], types.float64, types.int64, types.float64[::1])
VEC_SIG = types.float64[::1](*_ARGS)
SCAL_SIG = types.float64(*_ARGS)
BOOL_SIG = types.boolean(*_ARGS)
with warnings.catch_warnings():     # "first-class function type feature is experimental"
    warnings.simplefilter("ignore", nb_errors.NumbaExperimentalFeatureWarning)
    VEC_T, SCAL_T, BOOL_T = (types.FunctionType(s) for s in (VEC_SIG, SCAL_SIG, BOOL_SIG))


def as_vec(v):
    """A flow/jump map's value as a C-contiguous float64 array (compiled code only)."""
    raise NotImplementedError


def as_scalar(v):
    """A guard's value as a float: a scalar, or the minimum of a vector guard."""
    raise NotImplementedError


def as_bool(v):
    """A set indicator's value as a bool."""
    raise NotImplementedError


@overload(as_vec, jit_options=_CALLEE)
def _ov_as_vec(v):
    if isinstance(v, types.Array):
        if v.ndim != 1:
            raise nb_errors.TypingError(f"must return a 1-D array of shape (n,), got a "
                                        f"{v.ndim}-D array")
        if v.dtype == types.float64 and v.layout == "C":
            return lambda v: v
        if isinstance(v.dtype, (types.Float, types.Integer, types.Boolean)):
            return lambda v: np.ascontiguousarray(v).astype(np.float64)
    if isinstance(v, types.UniTuple) and isinstance(v.dtype, (types.Float, types.Integer)):
        def impl(v):
            out = np.empty(len(v))
            for i in range(len(v)):
                out[i] = v[i]
            return out
        return impl
    if isinstance(v, types.BaseTuple) and all(isinstance(e, (types.Float, types.Integer))
                                              for e in v.types):
        n = len(v.types)

        def impl_t(v):
            out = np.empty(n)
            k = 0
            for e in numba.literal_unroll(v):
                out[k] = e
                k += 1
            return out
        return impl_t
    raise nb_errors.TypingError(f"must return a 1-D float array (or a tuple of floats), "
                                f"got {v}")


@overload(as_scalar, jit_options=_CALLEE)
def _ov_as_scalar(v):
    if isinstance(v, (types.Float, types.Integer, types.Boolean)):
        return lambda v: float(v)
    if isinstance(v, types.Array) and v.ndim == 1:
        def impl(v):
            m = np.inf
            for i in range(v.shape[0]):      # NaN propagates as in Python's min()
                e = float(v[i])
                if e < m or e != e:
                    m = e
                    if e != e:
                        break
            return m
        return impl
    if isinstance(v, types.UniTuple) and isinstance(v.dtype, (types.Float, types.Integer)):
        def impl_t(v):
            m = np.inf
            for i in range(len(v)):
                e = float(v[i])
                if e < m:
                    m = e
            return m
        return impl_t
    raise nb_errors.TypingError(f"must return a float (or a 1-D array of floats: the set "
                                f"is where their minimum is >= 0), got {v}")


@overload(as_bool, jit_options=_CALLEE)
def _ov_as_bool(v):
    if isinstance(v, types.Boolean):
        return lambda v: bool(v)
    if isinstance(v, types.Integer):
        return lambda v: v != 0
    if isinstance(v, types.Array) and isinstance(v.dtype, types.Boolean) and v.ndim == 0:
        return lambda v: bool(v[()])
    raise nb_errors.TypingError(f"must return a bool (x in the set or not), got {v}")


class _RandomIds:
    """The ids numba gives the functions it compiles, drawn at random.

    numba names compiled code by module, name, argument types and an id
    (``FunctionIdentity._unique_ids``: a counter of the process, from 1). Two
    processes that compile two functions of one name (two systems' maps
    ``<lambda>``, a wrapper made by one factory) at the same count write the
    same symbol, and a process that loads both from the disk cache links one
    body for both: one system runs another's map (numba issue #10486). Random
    63-bit ids make that a chance of about 1e-19 per pair."""

    def __iter__(self):
        return self

    def __next__(self):
        import secrets
        return secrets.randbits(63)


def _random_function_ids():
    from numba.core.bytecode import FunctionIdentity
    if not isinstance(getattr(FunctionIdentity, "_unique_ids", None), _RandomIds):
        FunctionIdentity._unique_ids = _RandomIds()


_random_function_ids()


#: ``_nrt`` set, not inherited: a function numba compiles for a caller's call
#: inherits the caller's reference counting where it does not set its own (a
#: helper called first from one of the leaf helpers below would be compiled
#: without it, or fail to compile where it makes arrays)
_NJ = dict(error_model="numpy", _nrt=True)
#: the run kernels (:mod:`._variants`, :func:`._batch.run_rows`): called from
#: Python and by their code's address (``_cache.jit_address``), never through
#: a C wrapper: none is made
_NJK = dict(_NJ, no_cfunc_wrapper=True)
#: the kernels' internal functions: no CPython or C wrappers (never called from
#: Python, so none is compiled; no measurable change of the first compile)
_NJI = dict(_NJ, no_cpython_wrapper=True, no_cfunc_wrapper=True)
#: the leaf helpers (no array made, kept or returned; the event search, the
#: dense output, the error norm): compiled without numba's reference counting.
#: numba counts every array argument of every call on entry and exit, and the
#: counts of a helper with several exits are not pruned: these calls were a
#: tenth of a ball run's time (the maps they call keep theirs: :data:`_NJ`)
_NJL = dict(_NJI, _nrt=False)


def wrap_map(fn, kind, lazy=False):
    """Compile a user map ``fn(x, t, j, p)`` to a first-class function.

    ``kind``: ``"vec"`` (flow/jump map), ``"scalar"`` (guard), ``"bool"`` (set
    indicator), ``"guard_set"`` (the set {guard >= 0} of a guard). Raises
    numba's own errors (the caller names the map). ``lazy``: compiled only
    where a kernel that calls it compiles (a specialised kernel loaded from
    the disk cache never compiles it). Made in memory: the engine calls
    :func:`hybridsim.compiled._cache.wrap_map`, which takes the one cached on
    disk where it can.
    """
    jf = njit(**_NJ)(fn) if not isinstance(fn, numba.core.dispatcher.Dispatcher) else fn
    if kind == "vec":
        def w(x, t, j, p):
            return as_vec(jf(x, t, j, p))
        sig = VEC_SIG
    elif kind == "scalar":
        def w(x, t, j, p):
            return as_scalar(jf(x, t, j, p))
        sig = SCAL_SIG
    elif kind == "bool":
        def w(x, t, j, p):
            return as_bool(jf(x, t, j, p))
        sig = BOOL_SIG
    elif kind == "guard_set":
        def w(x, t, j, p):
            return as_scalar(jf(x, t, j, p)) >= 0.0
        sig = BOOL_SIG
    else:
        raise ValueError(kind)
    return njit(**_NJ)(w) if lazy else njit(sig, **_NJ)(w)


@njit(VEC_SIG, cache=CACHE, **_NJ)
def absent_vec(x, t, j, p):  # pragma: no cover - never called (flags say absent)
    return np.full(x.shape[0], np.nan)


@njit(SCAL_SIG, cache=CACHE, **_NJ)
def absent_scalar(x, t, j, p):  # pragma: no cover
    return np.nan


@njit(BOOL_SIG, cache=CACHE, **_NJ)
def absent_false(x, t, j, p):
    return False


@njit(BOOL_SIG, cache=CACHE, **_NJ)
def absent_true(x, t, j, p):
    return True


# ------------------------------------------------------------------ Ctrl-C
_CHECK_SIG = types.int32()
_OCC_SIG = types.intp()
_CLEAR_SIG = types.none()
# PyEval_SaveThread / PyEval_RestoreThread: the thread state as an address
_SAVE_SIG = types.intp()
_RESTORE_SIG = types.none(types.intp)
with warnings.catch_warnings():
    warnings.simplefilter("ignore", nb_errors.NumbaExperimentalFeatureWarning)
    CHECK_T, OCC_T, CLEAR_T, SAVE_T, RESTORE_T = (
        types.FunctionType(s) for s in (_CHECK_SIG, _OCC_SIG, _CLEAR_SIG, _SAVE_SIG,
                                        _RESTORE_SIG))
#: a run in the GIL's thread lets other threads run every this many polls
#: (``_let_threads_run``): a timer's thread can then send its SIGINT
YIELD_EVERY = 64


# ------------------------------------------------------------------ functions by address
# The generic kernels take the maps (and the Ctrl-C poll) as C addresses in an
# int64 array, made first-class function values inside compiled code: a
# first-class function argument costs ~3 us of Python work per call to unbox
# (numba asks the object for its address through Python, a pickle included),
# 30 us for the nine of a run, as much as a short run itself; a numpy
# Generator argument costs 5 us more (hence :func:`rng_pointers`).
def _from_address(fnty, jit=False):
    """An intrinsic: an int64 C address (of a function of ``fnty``'s signature,
    C calling convention: a numba cfunc wrapper, or a C API function) as a
    first-class function value of type ``fnty``; ``jit``: the address of
    numba's own compiled code instead (its calling convention: arrays and
    tuples pass as they are, no C wrapper between)."""
    @intrinsic
    def fn(typingctx, addr):
        if not isinstance(addr, types.Integer):
            return None

        def codegen(context, builder, sig, args):
            st = cgutils.create_struct_proxy(fnty)(context, builder)
            vp = context.get_value_type(types.voidptr)
            given, null = builder.inttoptr(args[0], vp), ir.Constant(vp, None)
            st.c_addr, st.jit_addr = (null, given) if jit else (given, null)
            st.py_addr = null
            return st._getvalue()
        return fnty(addr), codegen
    return fn


_vec_at, _scal_at, _bool_at = (_from_address(t) for t in (VEC_T, SCAL_T, BOOL_T))
_check_at, _occ_at, _clear_at = (_from_address(t) for t in (CHECK_T, OCC_T, CLEAR_T))
_save_at, _restore_at = (_from_address(t) for t in (SAVE_T, RESTORE_T))


@njit(cache=CACHE, **_NJL)
def _let_threads_run(poll):
    """Release the GIL and take it back (``poll[3]``, ``poll[4]``: the C API's
    ``PyEval_SaveThread`` and ``PyEval_RestoreThread``): a thread waiting for
    it (a timer about to send SIGINT) runs meanwhile; where none waits this
    is two uncontended locks."""
    _restore_at(poll[4])(_save_at(poll[3])())


@njit(inline="always", **_NJL)
def _canceled(poll, stop, polls):
    """``(canceled, polls)``: whether a run ends ``CANCELED`` here (``stop[0]``
    set, or where ``poll`` has the C API's addresses, a batch's worker threads
    passing zeros, a signal or exception pending: the KeyboardInterrupt is
    cleared), and the polls since other threads last ran (every
    :data:`YIELD_EVERY`-th lets them, :func:`_let_threads_run`)."""
    polling = poll[0] != 0
    if polling:
        polls += 1
        if polls >= YIELD_EVERY:
            polls = 0
            _let_threads_run(poll)
    if stop[0] != 0 or (polling and (_check_at(poll[0])() != 0 or _occ_at(poll[1])() != 0)):
        if polling:
            _clear_at(poll[2])()
        return True, polls
    return False, polls


def maps_of(maps):
    """The six maps (f, g, hD, hC, D, C) a run calls (compiled code only): made
    from their addresses where ``maps`` is an int64 array (the generic kernel,
    :func:`run_one`), or ``maps`` itself, a tuple of a system's dispatchers (a
    specialised kernel)."""
    raise NotImplementedError


@overload(maps_of, jit_options=dict(_NJI))
def _ov_maps_of(maps):
    if isinstance(maps, types.Array) and maps.dtype == types.int64:
        def by_address(maps):
            return (_vec_at(maps[0]), _vec_at(maps[1]), _scal_at(maps[2]), _scal_at(maps[3]),
                    _bool_at(maps[4]), _bool_at(maps[5]))
        return by_address
    if isinstance(maps, types.BaseTuple) and len(maps) == 6:
        return lambda maps: maps
    return None


@intrinsic
def _next_double(typingctx, fnaddr, state):
    """numpy's ``bitgen.next_double(state)`` by the addresses of its
    BitGenerator's ctypes interface: ``Generator.random()``'s draw."""
    if not (isinstance(fnaddr, types.Integer) and isinstance(state, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        i64 = ir.IntType(64)
        fty = ir.FunctionType(ir.DoubleType(), (i64,))
        fptr = builder.inttoptr(args[0], fty.as_pointer())
        return builder.call(fptr, (args[1],))
    return types.float64(types.int64, types.int64), codegen


@njit(cache=CACHE, **_NJL)
def _coin(rngp):
    """A fair coin from the run's numpy Generator (``rngp``: its BitGenerator's
    ``state_address`` and ``next_double`` address): ``rng.random() < 0.5``."""
    return _next_double(rngp[1], rngp[0]) < 0.5


# ------------------------------------------------------------------ helpers
@intrinsic
def _f64_ptr(typingctx, addr):
    """An integer address as a float64 pointer (for :func:`numba.carray`)."""
    if not isinstance(addr, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        return builder.inttoptr(args[0], ir.DoubleType().as_pointer())
    return types.CPointer(types.float64)(addr), codegen


@intrinsic
def _bare(typingctx, a):
    """A view of the C-contiguous array ``a`` without its owner (no meminfo):
    passing it to a helper or a map costs no atomic reference count on entry
    and exit (numba counts every array argument of every call; they were a
    fifth of a ball run's time). The caller keeps ``a`` alive while the view
    is in use, and the view never escapes the call it is passed to.

    "Alive" means ``a`` is read again after the call on some path: numba
    deletes a variable right after its last use, so a view of a temporary, or
    of a variable the call is the last reader of, would be read after its
    owner is freed (such calls pass the owned array itself)."""
    if not (isinstance(a, types.Array) and a.layout == "C"):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(a)(context, builder, value=args[0])
        ary.meminfo = cgutils.get_null_value(ary.meminfo.type)
        ary.parent = cgutils.get_null_value(ary.parent.type)
        return ary._getvalue()
    return a(a), codegen


@intrinsic
def _hold(typingctx, a):
    """One more reference to the owner of the array ``a`` (its meminfo), returned
    as an int64 address: the owner lives until :func:`_release` of that address,
    whatever becomes of ``a``. A run's sample buffers are held so, and used as
    :func:`_bare` views: a view reassigned where the buffers grow costs no atomic
    reference count at each branch of the run's loop."""
    if not (isinstance(a, types.Array) and a.layout == "C"):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(a)(context, builder, value=args[0])
        context.nrt.incref(builder, a, args[0])
        return builder.ptrtoint(ary.meminfo, ir.IntType(64))
    return types.int64(a), codegen


@intrinsic
def _release(typingctx, addr):
    """Drop the reference :func:`_hold` took (``addr``: its address)."""
    if not isinstance(addr, types.Integer):
        return None
    mip = types.MemInfoPointer(types.voidptr)

    def codegen(context, builder, sig, args):
        ptr = builder.inttoptr(args[0], context.get_value_type(mip))
        context.nrt.decref(builder, mip, ptr)
        return context.get_dummy_value()
    return types.none(addr), codegen


@intrinsic
def _adopt(typingctx, a, addr):
    """The :func:`_bare` view ``a`` of a held array (``addr``: :func:`_hold`'s) as
    an array owning a reference of its own (a run's buffers returned)."""
    if not (isinstance(a, types.Array) and a.layout == "C" and isinstance(addr, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(a)(context, builder, value=args[0])
        ary.meminfo = builder.inttoptr(args[1], ary.meminfo.type)
        out = ary._getvalue()
        context.nrt.incref(builder, a, out)
        return out
    return a(a, addr), codegen


class MapHandle(types.WrapperAddressProtocol):
    """A compiled map as a first-class function value (numba's wrapper address
    protocol): typed as its signature at once, so a kernel call from Python
    matches the compiled signature exactly (no per-call conversion)."""

    def __init__(self, disp, sig):
        from numba.experimental.function_type import _get_wrapper_address
        self.disp, self.sig = disp, sig
        self.addr = _get_wrapper_address(disp, sig)
        self.nbtype = types.FunctionType(sig)

    def __wrapper_address__(self):
        return self.addr

    def signature(self):
        return self.sig

    def __call__(self, *args):
        return self.disp(*args)


@typeof_impl.register(MapHandle)
def _typeof_handle(val, c):
    """The handle's type, built once (numba's generic rule rebuilds it per call)."""
    return val.nbtype


_SIGS = {"vec": VEC_SIG, "scalar": SCAL_SIG, "bool": BOOL_SIG, "guard_set": BOOL_SIG}


def _c_api_address(name):
    import ctypes
    return ctypes.cast(getattr(ctypes.pythonapi, name), ctypes.c_void_p).value


def _addresses(a):
    """An int64 array of addresses (writeable: numba types a read-only array
    apart, and the kernels are compiled for one signature)."""
    return np.array(a, dtype=np.int64)


#: what a run in the GIL's thread polls for Ctrl-C (addresses, see :func:`_run_core`):
#: the interpreter's own signal check (the SIGINT handler runs, raising
#: KeyboardInterrupt), whether an exception is set, and the call that clears it
#: (the run ends CANCELED); then the pair that lets other threads run
#: (:func:`_let_threads_run`)
POLL_GIL = _addresses([_c_api_address(n) for n in
                       ("PyErr_CheckSignals", "PyErr_Occurred", "PyErr_Clear",
                        "PyEval_SaveThread", "PyEval_RestoreThread")])
#: the same slots for runs on a parallel batch's worker threads: none (no GIL:
#: they read the batch's stop flag only, and call nothing at every step)
POLL_NONE = _addresses([0, 0, 0, 0, 0])


def map_addresses(handles):
    """The ``maps`` argument of :func:`run_one` / :func:`run_rows`: the
    addresses of six :class:`MapHandle` (f, g, hD, hC, D, C). The handles
    (which keep the compiled code alive) must outlive every call."""
    return _addresses([h.addr for h in handles])


def rng_pointers(rng):
    """The ``rngp`` argument of the kernels: a numpy Generator as the addresses
    (state, next_double) of its BitGenerator's ctypes interface. ``rng`` must
    outlive every call that uses them."""
    import ctypes
    ct = rng.bit_generator.ctypes
    return _addresses([ct.state_address, ctypes.cast(ct.next_double, ctypes.c_void_p).value])


def handle(disp, kind):
    """:class:`MapHandle` of a dispatcher compiled for the ``kind``'s signature."""
    return MapHandle(disp, _SIGS[kind])


# ------------------------------------------------------------------ run kernels by address
#: what :func:`run_one` returns, and its type as a first-class function value
ONE_RET = types.Tuple((types.float64[::1], types.int64[::1], types.float64[:, ::1],
                       types.float64[:, ::1], types.int64, types.int64, types.float64[::1],
                       types.int64[::1]))
_I64C, _F64C = types.int64[::1], types.float64[::1]
ONE_SIG = ONE_RET(_I64C, _F64C, _F64C, _F64C, _I64C, _F64C, _I64C, _I64C, _I64C)
with warnings.catch_warnings():
    warnings.simplefilter("ignore", nb_errors.NumbaExperimentalFeatureWarning)
    ONE_T = types.FunctionType(ONE_SIG)


#: a kernel of :data:`ONE_SIG` by the address of its compiled code
_one_at = _from_address(ONE_T, jit=True)


@intrinsic
def _claim(typingctx, counter, step):
    """``counter[0] += step`` atomically; returns the value before (the first row
    of the chunk the calling thread takes)."""
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64
            and isinstance(step, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        arr = context.make_array(sig.args[0])(context, builder, args[0])
        inc = context.cast(builder, args[1], sig.args[1], types.int64)
        return builder.atomic_rmw("add", arr.data, inc, "monotonic")
    return types.int64(counter, step), codegen


@intrinsic
def _claim_within(typingctx, counter, step, size):
    """``counter[0] += step`` atomically where the sum stays within ``size``;
    returns the value before, or -1 (the counter unchanged) where it would
    not: a compare-and-swap loop, so a claim that fails takes nothing."""
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64
            and isinstance(step, types.Integer) and isinstance(size, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        arr = context.make_array(sig.args[0])(context, builder, args[0])
        inc = context.cast(builder, args[1], sig.args[1], types.int64)
        top = context.cast(builder, args[2], sig.args[2], types.int64)
        i64 = ir.IntType(64)
        out = cgutils.alloca_once_value(builder, ir.Constant(i64, -1))
        loop = builder.append_basic_block("claim.loop")
        done = builder.append_basic_block("claim.done")
        builder.branch(loop)
        builder.position_at_end(loop)
        old = builder.load_atomic(arr.data, "monotonic", 8)
        new = builder.add(old, inc)
        with builder.if_then(builder.icmp_signed(">", new, top)):
            builder.branch(done)
        pair = builder.cmpxchg(arr.data, old, new, "monotonic", "monotonic")
        with builder.if_then(builder.extract_value(pair, 1)):
            builder.store(old, out)
            builder.branch(done)
        builder.branch(loop)
        builder.position_at_end(done)
        return builder.load(out)
    return types.int64(counter, step, size), codegen


def _signature_one():
    i64, f64 = types.int64[::1], types.float64[::1]
    # maps, x0, p, fopt, iopt, atol, rngp, poll, stop
    return (i64, f64, f64, f64, i64, f64, i64, i64, i64)


def _batch_signature(sig):
    """:func:`run_rows`'s: one, maps, X0, P (rows of p), fopt, iopt, atol, rngp, poll, stop,
    next_row, chunk, then the pool (TT, JJ, XX, XXD, fill, AT), the rows'
    records (NS, CA, DE, INFO, ST) and a reduced batch's (grid, by_j, XF, TF,
    JF, XG, OK)."""
    f1, f2, i2 = types.float64[::1], types.float64[:, ::1], types.int64[:, ::1]
    i1 = types.int64[::1]
    return ((types.int64,) + sig[:1] + (f2, f2) + sig[3:] + (i1, types.int64)
            + (f1, i1, f2, f2, i1, i1, i1, i1, i1, f2, i2)
            + (f1, types.int64, f2, f1, i1, types.float64[:, :, ::1], types.boolean[:, ::1]))
