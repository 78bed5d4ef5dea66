"""The compiled path's numba kernels (imported only when numba is installed).

Everything here runs in nopython mode. The user's maps reach the kernels as
numba *first-class functions* of fixed signatures (:data:`VEC_SIG`,
:data:`SCAL_SIG`, :data:`BOOL_SIG`), so the kernels are compiled once and
cached on disk (``cache=True``) for every system; only the small wrappers of
each system's own maps are compiled per system (see :func:`wrap_map`). From
Python they are passed by address (an int64 array, :func:`map_addresses`),
as are the Ctrl-C poll and the numpy Generator: numba's unboxing of a
first-class function or Generator argument costs microseconds per call.

Two kernels are compiled and cached: :func:`run_one` (one run) and
:func:`run_rows` (a batch's rows, in GIL-free Python threads), which calls a
run kernel by its code address instead of compiling it in (numba links and
re-optimises a callee's code into every caller: the batch kernel used to
cost as much to compile as the engine). A flow map that reads the past
(delays) runs in a third, :func:`run_one_delays`, compiled when such a
system first runs: the same run core with the record of the steps, which
:func:`run_one` leaves out (a quarter of its compile time). A system with
``specialize=True`` gets its own run kernel in a generated module
(:func:`spec_module`), cached on disk like these, and batches run it
through the same :func:`run_rows`.

The rules (priorities, the jump-or-flow decision, event tolerances, the
t_max slack, short flows, the time scale) are :mod:`hybridsim.rules`'s own
functions, made callable from compiled code by ``register_jitable``; they are
not written again here. The algorithms ported from the Python path are:

* scipy's RK45 step (Dormand-Prince 5(4), ``select_initial_step``,
  ``RungeKutta._step_impl``'s step-size controller, ``RkDenseOutput``);
* :func:`hybridsim.events.locate_event` (where a flow starts on the guard's
  zero, a probe and a quadratic model's first estimate; indicator bisection
  until the guard changes sign; safeguarded secant steps on the guard to a
  bracket of 4 ulp confirmed by the indicator) and
  :func:`hybridsim.events.find_interior_event` (three interior samples and a
  golden-section search on guard peaks);
* the decision loop of :func:`hybridsim.simulate` (``_Run.run``, ``_flow``,
  ``_event``, ``_event_past_t_max``, ``_jump``, ``_stop_outside``).
"""
from __future__ import annotations

import contextlib
import hashlib
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
from numba.typed import List
from scipy.integrate._ivp import dop853_coefficients as _dop
from scipy.integrate._ivp.rk import DOP853, RK45

from .. import rules

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
# (register_jitable compiles it where a kernel calls it; nothing is copied).
for _name, _fn in vars(rules).items():
    if inspect.isfunction(_fn) and _fn.__module__ == rules.__name__:
        register_jitable(_fn)


def _rules_digest():
    """A hash of the rules' source: part of the kernels' cache key, so that a
    change of :mod:`hybridsim.rules` recompiles them (numba's own cache key only
    sees this file)."""
    src = inspect.getsource(rules)
    return hashlib.sha256(src.encode()).hexdigest()


# ------------------------------------------------------------------ constants
_EPS = float(np.finfo(float).eps)
_INVPHI = (math.sqrt(5.0) - 1.0) / 2.0
_A = np.ascontiguousarray(RK45.A, dtype=np.float64)
_B = np.ascontiguousarray(RK45.B, dtype=np.float64)
_Cc = np.ascontiguousarray(RK45.C, dtype=np.float64)
_E = np.ascontiguousarray(RK45.E, dtype=np.float64)
_P = np.ascontiguousarray(RK45.P, dtype=np.float64)
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = 0.9, 0.2, 10.0
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
#: a constant of the run core: its method is DOP853 (False: RK45). True in
#: :data:`run_one_dop853` (:func:`_variant`), whose steps, error norm and dense
#: output are DOP853's; numba prunes the other method's branches from each
_DOP = False
#: the run core's globals in its DOP853 variant
DOP853_GLOBALS = {"_DOP": True}
#: a constant of the run core: whether its flow map reads the past (delays).
#: False in :data:`run_one` (numba prunes every branch on it: no code for the
#: past, a smaller kernel to compile), True in :data:`run_one_delays`
_DELAYS = False
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

# flow outcomes
_O_TMAX, _O_JUMP, _O_FLOW_ON, _O_STOP, _O_BREAK = 0, 1, 2, 3, 4

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


@overload(as_vec)
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


@overload(as_scalar)
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


@overload(as_bool)
def _ov_as_bool(v):
    if isinstance(v, types.Boolean):
        return lambda v: bool(v)
    if isinstance(v, types.Integer):
        return lambda v: v != 0
    if isinstance(v, types.Array) and isinstance(v.dtype, types.Boolean) and v.ndim == 0:
        return lambda v: bool(v[()])
    raise nb_errors.TypingError(f"must return a bool (x in the set or not), got {v}")


#: ``_nrt`` set, not inherited: a function numba compiles for a caller's call
#: inherits the caller's reference counting where it does not set its own (a
#: helper called first from one of the leaf helpers below would be compiled
#: without it, or fail to compile where it makes arrays)
_NJ = dict(error_model="numpy", _nrt=True)
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
    the disk cache never compiles it).
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


@njit(VEC_SIG, cache=True, **_NJ)
def absent_vec(x, t, j, p):  # pragma: no cover - never called (flags say absent)
    return np.full(x.shape[0], np.nan)


@njit(SCAL_SIG, cache=True, **_NJ)
def absent_scalar(x, t, j, p):  # pragma: no cover
    return np.nan


@njit(BOOL_SIG, cache=True, **_NJ)
def absent_false(x, t, j, p):
    return False


@njit(BOOL_SIG, cache=True, **_NJ)
def absent_true(x, t, j, p):
    return True


# ------------------------------------------------------------------ Ctrl-C
_CHECK_SIG = types.int32()
_OCC_SIG = types.intp()
_CLEAR_SIG = types.none()
with warnings.catch_warnings():
    warnings.simplefilter("ignore", nb_errors.NumbaExperimentalFeatureWarning)
    CHECK_T, OCC_T, CLEAR_T = (types.FunctionType(s) for s in (_CHECK_SIG, _OCC_SIG,
                                                               _CLEAR_SIG))


# ------------------------------------------------------------------ functions by address
# The generic kernels take the maps (and the Ctrl-C poll) as C addresses in an
# int64 array, made first-class function values inside compiled code: a
# first-class function argument costs ~3 us of Python work per call to unbox
# (numba asks the object for its address through Python, a pickle included),
# 30 us for the nine of a run, as much as a short run itself; a numpy
# Generator argument costs 5 us more (hence :func:`rng_pointers`).
def _from_address(fnty):
    """An intrinsic: an int64 C address (of a function of ``fnty``'s signature,
    C calling convention: a numba cfunc wrapper, or a C API function) as a
    first-class function value of type ``fnty``."""
    @intrinsic
    def fn(typingctx, addr):
        if not isinstance(addr, types.Integer):
            return None

        def codegen(context, builder, sig, args):
            st = cgutils.create_struct_proxy(fnty)(context, builder)
            vp = context.get_value_type(types.voidptr)
            st.c_addr = builder.inttoptr(args[0], vp)
            st.py_addr = ir.Constant(vp, None)
            st.jit_addr = ir.Constant(vp, None)       # called through c_addr
            return st._getvalue()
        return fnty(addr), codegen
    return fn


_vec_at, _scal_at, _bool_at = (_from_address(t) for t in (VEC_T, SCAL_T, BOOL_T))
_check_at, _occ_at, _clear_at = (_from_address(t) for t in (CHECK_T, OCC_T, CLEAR_T))


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


@njit(cache=True, **_NJL)
def _coin(rngp):
    """A fair coin from the run's numpy Generator (``rngp``: its BitGenerator's
    ``state_address`` and ``next_double`` address): ``rng.random() < 0.5``."""
    return _next_double(rngp[1], rngp[0]) < 0.5


# ------------------------------------------------------------------ helpers
@njit(cache=True, **_NJL)
def _dense_to(out, yold, hQ, told, h, s):
    """A step's dense output at s written into ``out`` (the event search's trial
    points: no array made per evaluation; :func:`_dense` makes one).

    ``hQ`` says which, by its columns: 4, RK45's (h K^T P); 7, DOP853's
    (scipy's ``Dop853DenseOutput``, its F transposed); 3, the cubic Hermite
    of the step's ends (``solve._Hermite``: the state at the end, h f at the
    start and h f at the end), DOP853's first interior search."""
    x = (s - told) / h
    m = hQ.shape[1]
    if m == 4:
        x2 = x * x
        x3 = x2 * x
        x4 = x3 * x
        for i in range(yold.shape[0]):
            out[i] = yold[i] + (hQ[i, 0] * x + hQ[i, 1] * x2 + hQ[i, 2] * x3 + hQ[i, 3] * x4)
    elif m == 7:
        x1 = 1.0 - x
        for i in range(yold.shape[0]):
            acc = 0.0
            for k in range(6, -1, -1):
                acc += hQ[i, k]
                acc *= x if k % 2 == 0 else x1
            out[i] = acc + yold[i]
    else:
        x2 = x * x
        c1 = x2 * (3.0 - 2.0 * x)
        c2 = x * (1.0 - x) ** 2
        c3 = x2 * (x - 1.0)
        for i in range(yold.shape[0]):
            out[i] = (yold[i] + c1 * (hQ[i, 0] - yold[i]) + c2 * hQ[i, 1]) + c3 * hQ[i, 2]


@njit(cache=True, **_NJI)
def _dense(yold, hQ, told, h, s):
    """RK45's dense output at s (as :func:`hybridsim.events.fast_dense`)."""
    out = np.empty(yold.shape[0])
    _dense_to(out, yold, hQ, told, h, s)
    return out


@njit(cache=True, **_NJL)
def _copy_to(out, y):
    """``out[:] = y`` as a loop (a state into a scratch row of the run)."""
    for i in range(y.shape[0]):
        out[i] = y[i]


@njit(cache=True, **_NJL)
def _dense_deriv_to(XD, r, hQ, told, h, s):
    """d/dt of the dense output at s (``solve._dense_derivative``, Q = hQ / h)
    written into row ``r`` of ``XD``."""
    x = (s - told) / h
    for i in range(hQ.shape[0]):
        XD[r, i] = (hQ[i, 0] / h + 2.0 * (hQ[i, 1] / h) * x + 3.0 * (hQ[i, 2] / h) * x * x
                    + 4.0 * (hQ[i, 3] / h) * x * x * x)


@njit(cache=True, **_NJL)
def _norm(v):
    """The 2-norm of ``v`` (``np.sum(v * v)``'s order of sums: no array made)."""
    s = 0.0
    for i in range(v.shape[0]):
        s += v[i] * v[i]
    return math.sqrt(s)


@njit(cache=True, **_NJL)
def _all_finite(v):
    for i in range(v.size):
        if not np.isfinite(v.flat[i]):
            return False
    return True


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


@njit(cache=True, **_NJL)
def _fault(ev_addr, which, s, j):
    """Record the first NaN guard of the run in the kernel's ``ev`` (at
    ``ev_addr``; ``ev[0]``: 1 jump_guard, 2 flow_guard, then s and j)."""
    ev = _f64_ptr(ev_addr)
    if ev[0] == 0.0:
        ev[0] = which
        ev[1] = s
        ev[2] = j


# _inD, _inC, _pred: plain calls (numba's IR inlining of them, at ~30 call sites,
# cost ~10 s of the engine's first compile for no measurable speed: LLVM inlines)
@njit(cache=True, **_NJL)
def _inD(M, y, s, j, p):
    """x in D: the indicator, or {jump_guard >= 0} where D is derived from its guard
    (a NaN guard is the map's contract breach: recorded at ``M[8]``, as the Python
    path's ``MapError``).

    ``M`` = (f, g, hD, hC, D, C, D from its guard, C from its guard, the
    address of the kernel's fault record): scalars only. An array in ``M``
    (passed to every helper of the event search) cost 10% of a run."""
    if M[6]:
        v = M[2](y, s, j, p)
        if v != v:
            _fault(M[8], 1.0, s, j)
            return False
        return v >= 0.0
    return M[4](y, s, j, p)


@njit(cache=True, **_NJL)
def _inC(M, y, s, j, p):
    """x in C: the indicator, or {flow_guard >= 0} (see :func:`_inD`)."""
    if M[7]:
        v = M[3](y, s, j, p)
        if v != v:
            _fault(M[8], 2.0, s, j)
            return True
        return v >= 0.0
    return M[5](y, s, j, p)


@njit(cache=True, **_NJL)
def _pred(M, s, y, j, p, has_C, d_active):
    """The event has happened at (s, y): left C, or (watched) entered D."""
    if has_C and not _inC(M, y, s, j, p):
        return True
    if d_active and _inD(M, y, s, j, p):
        return True
    return False


@njit(cache=True, **_NJL)
def _phi(M, s, y, j, p, useD, useC):
    """The continuous event function (>= 0 once the event has happened): every
    given guard of the flow (``_Run._phi``). A NaN guard is recorded as the
    Python path's ``MapError`` naming it (see :func:`_fault`)."""
    v = -np.inf
    if useD:
        v = M[2](y, s, j, p)
    if useC:
        w = -M[3](y, s, j, p)
        if w > v:
            v = w
        elif w != w:
            v = w
    if v != v:                       # either guard NaN (kept by the max above)
        _phi_nan(M, s, y, j, p, useD)
    return v


@njit(cache=True, **_NJL)
def _phi_nan(M, s, y, j, p, useD):
    """Record which guard returned NaN in :func:`_phi` (the jump guard first, as
    ``_Run._phi`` names it): off the event search's fast path."""
    if useD:
        v = M[2](y, s, j, p)
        if v != v:
            _fault(M[8], 1.0, s, j)
            return
    _fault(M[8], 2.0, s, j)


@njit(cache=True, **_NJL)
def _secant(M, yold, hQ, told, h, j, p, useD, useC, lo, hi, flo, fhi, seeded, s0, slope0,
            wk):
    """``events._secant``: secant steps from the last evaluation, accepted inside
    the bracket when shorter than half the step before last, else bisection;
    ``seeded``: ``s0`` is the first trial, ``slope0`` the guard's slope there.
    Returns the bracket (lo, hi); ``wk`` holds the trial points' states."""
    d1 = np.inf
    d2 = np.inf
    if -flo < fhi:
        xl = lo
        fl = flo
    else:
        xl = hi
        fl = fhi
    slope = (fhi - flo) / (hi - lo)
    for _ in range(100):
        tol = rules.event_tolerance(lo, hi)
        if hi - lo <= tol:
            break
        if seeded:
            s = s0
        else:
            s = xl - fl / slope if slope != 0.0 else np.nan
            if not (lo <= s and s <= hi and abs(s - xl) < 0.5 * d2):
                s = 0.5 * (lo + hi)
        q = 0.25 * tol
        if not s > lo + q:
            s = lo + q
        elif not s < hi - q:
            s = hi - q
        _dense_to(wk, yold, hQ, told, h, s)
        fs = _phi(M, s, wk, j, p, useD, useC)
        if seeded:
            slope = slope0
            seeded = False
        else:
            slope = (fs - fl) / (s - xl) if s != xl else np.nan
        d2 = d1
        d1 = abs(s - xl)
        xl = s
        fl = fs
        if fs >= 0.0:
            hi = s
            fhi = fs
        else:
            lo = s
            flo = fs
    return lo, hi


@njit(cache=True, **_NJL)
def _root_off_zero(f0, fd, fw, d, w):
    """``events._root_off_zero``: (offset, slope), NaNs where the model has no root."""
    m = (fd - f0) / d
    c = (fw - f0 - m * w) / (w * w)
    disc = m * m - 4.0 * c * f0
    if not (c > 0.0 and disc >= 0.0):
        return np.nan, np.nan
    r = math.sqrt(disc)
    tau = (r - m) / (2.0 * c)
    if d < tau and tau < w:
        return tau, r
    return np.nan, np.nan


@njit(cache=True, **_NJL)
def _locate(M, yold, hQ, told, h, j, p, has_C, d_active, phi_on, useD, useC, a, b,
            yb, yb_known, wk, ylo, yhi):
    """:func:`hybridsim.events.locate_event` on the step's dense output (``yb``:
    the state at b where ``yb_known``; the state at the step's start is exact).
    Returns the bracket (lo, hi); the states of its ends are written into
    ``ylo`` and ``yhi`` (the run's scratch rows: no array made an event).

    The bracket is narrowed on times, trial points evaluated in ``wk``;
    ``ylo`` holds the state at ``ylo_at`` (and ``yhi`` at ``yhi_at``), made
    again at the bracket's end times when it is done: the same values as
    the states kept along the way."""
    lo, hi = a, b
    if a == told:
        _copy_to(ylo, yold)
    else:
        _dense_to(ylo, yold, hQ, told, h, lo)
    if yb_known:
        _copy_to(yhi, yb)
    else:
        _dense_to(yhi, yold, hQ, told, h, hi)
    ylo_at = lo
    yhi_at = hi
    if phi_on:
        flo = _phi(M, lo, ylo, j, p, useD, useC)
        fhi = _phi(M, hi, yhi, j, p, useD, useC)
        seeded = False
        s0 = np.nan
        slope0 = np.nan
        if not flo < 0.0 and fhi >= 0.0:
            # on the guard's zero at the start: one probe gives the direction,
            # and with the end value a first estimate of the root
            d = max(64.0 * rules.event_tolerance(lo, hi), 1e-9 * (hi - lo))
            if lo + d < hi:
                _dense_to(wk, yold, hQ, told, h, lo + d)
                fd = _phi(M, lo + d, wk, j, p, useD, useC)
                if fd < 0.0 and not _pred(M, lo + d, wk, j, p, has_C, d_active):
                    tau, slope0 = _root_off_zero(flo, fd, fhi, d, hi - lo)
                    if tau == tau:
                        seeded = True
                        s0 = lo + tau
                    lo = lo + d
                    _copy_to(ylo, wk)
                    ylo_at = lo
                    flo = fd
        for _ in range(200):
            if (flo < 0.0 and 0.0 <= fhi) or hi - lo <= rules.event_tolerance(lo, hi):
                break
            m = 0.5 * (lo + hi)
            _dense_to(wk, yold, hQ, told, h, m)
            if _pred(M, m, wk, j, p, has_C, d_active):
                hi = m
                fhi = _phi(M, m, wk, j, p, useD, useC)
            else:
                lo = m
                flo = _phi(M, m, wk, j, p, useD, useC)
        if (flo < 0.0 and 0.0 <= fhi) and hi - lo > rules.event_tolerance(lo, hi):
            l2, h2 = _secant(M, yold, hQ, told, h, j, p, useD, useC, lo, hi, flo, fhi,
                             seeded, s0, slope0, wk)
            # the indicator decides membership: keep the guard's bracket where it
            # agrees (the state at h2, then at l2, in wk where not kept already)
            if h2 == yhi_at:
                in_h2 = _pred(M, h2, yhi, j, p, has_C, d_active)
            else:
                _dense_to(wk, yold, hQ, told, h, h2)
                in_h2 = _pred(M, h2, wk, j, p, has_C, d_active)
                if in_h2:
                    _copy_to(yhi, wk)
            if in_h2:
                hi = h2
                yhi_at = hi
                lo = l2
                if l2 != ylo_at:
                    _dense_to(ylo, yold, hQ, told, h, l2)
                ylo_at = lo
            elif l2 == ylo_at:
                if not _pred(M, l2, ylo, j, p, has_C, d_active):
                    lo = l2
            else:
                _dense_to(wk, yold, hQ, told, h, l2)
                if not _pred(M, l2, wk, j, p, has_C, d_active):
                    lo = l2
                    _copy_to(ylo, wk)
                    ylo_at = lo
    for _ in range(200):
        if hi - lo <= rules.event_tolerance(lo, hi):
            break
        m = 0.5 * (lo + hi)
        _dense_to(wk, yold, hQ, told, h, m)
        if _pred(M, m, wk, j, p, has_C, d_active):
            hi = m
        else:
            lo = m
    if lo != ylo_at:
        _dense_to(ylo, yold, hQ, told, h, lo)
    if hi != yhi_at:
        _dense_to(yhi, yold, hQ, told, h, hi)
    return lo, hi


@njit(cache=True, **_NJL)
def _near_peak(v, lo_nb):
    return v + 2.0 * (v - lo_nb) >= 0.0


@njit(cache=True, **_NJI)
def _maximize(M, yold, hQ, told, h, j, p, has_C, d_active, useD, useC, l, r, fl, fr):
    """Golden-section search (``events._maximize``); returns NaN when nothing found."""
    x1 = r - _INVPHI * (r - l)
    x2 = l + _INVPHI * (r - l)
    y1 = _dense(yold, hQ, told, h, x1)
    y2 = _dense(yold, hQ, told, h, x2)
    f1 = _phi(M, x1, _bare(y1), j, p, useD, useC)
    f2 = _phi(M, x2, _bare(y2), j, p, useD, useC)
    for _ in range(100):
        if f1 >= 0.0 and _pred(M, x1, _bare(y1), j, p, has_C, d_active):
            return x1
        if f2 >= 0.0 and _pred(M, x2, _bare(y2), j, p, has_C, d_active):
            return x2
        if r - l <= rules.event_tolerance(l, r) or not _near_peak(max(f1, f2), min(fl, fr)):
            return np.nan
        if f1 >= f2:
            r = x2
            fr = f2
            x2 = x1
            y2 = y1
            f2 = f1
            x1 = r - _INVPHI * (r - l)
            y1 = _dense(yold, hQ, told, h, x1)
            f1 = _phi(M, x1, _bare(y1), j, p, useD, useC)
        else:
            l = x1
            fl = f1
            x1 = x2
            y1 = y2
            f1 = f2
            x2 = l + _INVPHI * (r - l)
            y2 = _dense(yold, hQ, told, h, x2)
            f2 = _phi(M, x2, _bare(y2), j, p, useD, useC)
    return np.nan


@njit(cache=True, **_NJL)
def _interior(M, yold, hQ, told, h, j, p, has_C, d_active, phi_on, useD, useC, a, b, WS):
    """:func:`hybridsim.events.find_interior_event` with 3 samples: (found, lo, hi).

    ``WS``: the run's (4, n) buffer, the samples' states in its first three
    rows (read again for the guard values), other points in the last: no
    array made a step."""
    hh = b - a
    if not hh > 0:
        return False, a, b
    y1, y2, y3, wk = WS[0], WS[1], WS[2], WS[3]
    s1 = a + hh * 0.25
    s2 = a + hh * 0.5
    s3 = a + hh * 0.75
    _dense_to(y1, yold, hQ, told, h, s1)
    if _pred(M, s1, y1, j, p, has_C, d_active):
        return True, a, s1
    _dense_to(y2, yold, hQ, told, h, s2)
    if _pred(M, s2, y2, j, p, has_C, d_active):
        return True, s1, s2
    _dense_to(y3, yold, hQ, told, h, s3)
    if _pred(M, s3, y3, j, p, has_C, d_active):
        return True, s2, s3
    if not phi_on:
        return False, a, b
    _dense_to(wk, yold, hQ, told, h, a)
    v0 = _phi(M, a, wk, j, p, useD, useC)
    v1 = _phi(M, s1, y1, j, p, useD, useC)
    v2 = _phi(M, s2, y2, j, p, useD, useC)
    v3 = _phi(M, s3, y3, j, p, useD, useC)
    _dense_to(wk, yold, hQ, told, h, b)
    v4 = _phi(M, b, wk, j, p, useD, useC)
    if not (np.isfinite(v0) and np.isfinite(v1) and np.isfinite(v2) and np.isfinite(v3)
            and np.isfinite(v4)):
        return False, a, b
    # a peak at a sample between its neighbours (the samples' order: s1, s2, s3)
    for k in range(1, 4):
        if k == 1:
            left, v, right, vl, vr = a, v1, s2, v0, v2
        elif k == 2:
            left, v, right, vl, vr = s1, v2, s3, v1, v3
        else:
            left, v, right, vl, vr = s2, v3, b, v2, v4
        if v >= vl and v >= vr and _near_peak(v, min(vl, vr)):
            s = _maximize(M, yold, hQ, told, h, j, p, has_C, d_active, useD, useC,
                          left, right, vl, vr)
            if s == s:
                return True, left, s
    if v0 >= v1 and _near_peak(v0, v1):
        eps = 1e-3 * (s1 - a)
        _dense_to(wk, yold, hQ, told, h, a + eps)
        if _phi(M, a + eps, wk, j, p, useD, useC) > v0:
            s = _maximize(M, yold, hQ, told, h, j, p, has_C, d_active, useD, useC,
                          a, s1, v0, v1)
            if s == s:
                return True, a, s
    # a peak between the last sample and b: only where the guard falls at b (the
    # next step starts falling, so its own search never looks back)
    if v4 >= v3 and _near_peak(v4, v3):
        eps = 1e-3 * (b - s3)
        _dense_to(wk, yold, hQ, told, h, b - eps)
        if _phi(M, b - eps, wk, j, p, useD, useC) > v4:
            s = _maximize(M, yold, hQ, told, h, j, p, has_C, d_active, useD, useC,
                          s3, b, v3, v4)
            if s == s:
                return True, s3, s
    return False, a, b


@njit(cache=True, **_NJL)
def _put(A, i, v):
    """``A[i] = v`` as a loop (numba's broadcasting setitem compiles its shape
    error's formatting, seconds of every first compile)."""
    for q in range(v.shape[0]):
        A[i, q] = v[q]


@njit(cache=True, **_NJI)
def _grown(T, J, X, XD, ns):
    """The sample buffers, full at ``ns``, doubled (the first ``ns`` rows kept)."""
    cap2 = 2 * T.shape[0]
    n = X.shape[1]
    T2 = np.empty(cap2)
    J2 = np.empty(cap2, np.int64)
    X2 = np.empty((cap2, n))
    XD2 = np.empty((cap2, n))
    for r in range(ns):
        T2[r] = T[r]
        J2[r] = J[r]
        for q in range(n):
            X2[r, q] = X[r, q]
            XD2[r, q] = XD[r, q]
    return T2, J2, X2, XD2


@njit(cache=True, **_NJL)
def _store(T, J, X, XD, ns, t, j, x):
    """Write the sample (t, j, x) at row ``ns`` (xdot NaN); the buffers have room.

    The run appends with ``if ns == T.shape[0]: T, J, X, XD = _grown(...)``
    then this on :func:`_bare` views: a helper returning the four buffers made
    eight atomic reference counts a sample."""
    T[ns] = t
    J[ns] = j
    for q in range(X.shape[1]):
        X[ns, q] = x[q]
        XD[ns, q] = np.nan


# ------------------------------------------------------------------ the past (delays)
# A run with delays (CompiledSystem(delays=)) keeps every recorded step's dense
# output, as hybridsim.History does: one row a step, (start, end, h, the step's
# start state (n), its h K^T P (n x 4, row-major)), in chunks of _CH rows kept in
# a typed List HL (appended to, never reassigned: an array reassigned in the run's
# loop costs every run about 10%, delays or not); HM = (count, the last jump's time, and where
# the past was first missing: the time read, the recorded end, the flow map's t).
# The flow map's p holds x(t - tau_i) after the parameters while it runs, NaN
# otherwise.
_CH = 256                           # rows of a chunk of the step record
_CHUNK_T = types.float64[:, ::1]


@njit(cache=True, **_NJI)
def _span(HL, k):
    """The step record's row k: its (start, end). One function for both entries
    (an entry index passed as a constant compiled one version per constant)."""
    R = HL[k // _CH]
    i = k % _CH
    return R[i, 0], R[i, 1]


@njit(cache=True, **_NJI)
def _past(p, pb, dl, s, HL, HM, cur_x, x0, t0):
    """Write x(s - tau_i) for every delay into ``p[pb:]`` (``hybridsim.History``'s
    rules). False, the tail NaN and HM[2:5] set (the first time), where a value
    is not recorded yet (the solver step under way)."""
    n = x0.shape[0]
    hn = int(HM[0])
    cur_t = HM[1]
    for i in range(dl.shape[0]):
        r = s - dl[i]
        o = pb + i * n
        if r < t0:                          # the prehistory: constant x0
            for q in range(n):
                p[o + q] = x0[q]
            continue
        tol = 1e-12 * max(1.0, abs(r))
        if r >= cur_t and (hn == 0 or _span(HL, hn - 1)[0] < cur_t):
            if r <= cur_t + tol:            # the current flow's start: post-jump value
                for q in range(n):
                    p[o + q] = cur_x[q]
                continue
            if HM[2] != HM[2]:
                HM[2] = r
                HM[3] = cur_t
                HM[4] = s
            p[pb:] = np.nan
            return False
        lo = 0
        hi = hn
        while lo < hi:                      # bisect_right on the starts
            mid = (lo + hi) // 2
            if r < _span(HL, mid)[0]:
                hi = mid
            else:
                lo = mid + 1
        k = lo - 1
        if not (k >= 0 and r <= _span(HL, k)[1]):
            if hn > 0 and _span(HL, hn - 1)[1] < r <= _span(HL, hn - 1)[1] + tol:
                k = hn - 1
            else:
                if HM[2] != HM[2]:
                    HM[2] = r
                    HM[3] = _span(HL, hn - 1)[1] if hn > 0 else cur_t
                    HM[4] = s
                p[pb:] = np.nan
                return False
        R = HL[k // _CH]
        kk = k % _CH
        x = (r - R[kk, 0]) / R[kk, 2]
        x2 = x * x
        x3 = x2 * x
        x4 = x3 * x
        for q in range(n):
            c = 3 + n + 4 * q
            p[o + q] = R[kk, 3 + q] + (R[kk, c] * x + R[kk, c + 1] * x2 + R[kk, c + 2] * x3
                                       + R[kk, c + 3] * x4)
    return True


@njit(cache=True, **_NJI)
def _fd(f, y, s, j, p, pb, dl, HL, HM, cur_x, x0, t0):
    """The flow map at (y, s), with the past in ``p[pb:]`` where there are delays
    (NaN again afterwards); a value of NaN where the past is missing (HM[2])."""
    if dl.shape[0] == 0:
        return f(y, s, j, p)
    if not _past(p, pb, dl, s, HL, HM, cur_x, x0, t0):
        return np.full(y.shape[0], np.nan)
    v = f(y, s, j, p)
    p[pb:] = np.nan
    return v


@njit(cache=True, **_NJI)
def _past_missing(info, HM, j):
    """The run's end where the past was missing: MAP_ERROR, with ``info`` = (the
    flow map's t, the time read, the recorded end, j) for the message."""
    info[0] = HM[4]
    info[1] = HM[2]
    info[2] = HM[3]
    info[3] = j
    return MAP_ERROR, MAP_HISTORY


@njit(cache=True, **_NJI)
def _record(HL, HM, a, b, h, ya, hQ):
    """Record the step from a (dense output ya, hQ over h) up to b (a new chunk
    where the last is full)."""
    if not b > a:
        return
    hn = int(HM[0])
    n = ya.shape[0]
    if hn // _CH == len(HL):
        HL.append(np.empty((_CH, 3 + 5 * n)))
    R = HL[hn // _CH]
    k = hn % _CH
    R[k, 0] = a
    R[k, 1] = b
    R[k, 2] = h
    for q in range(n):
        R[k, 3 + q] = ya[q]
        for c in range(4):
            R[k, 3 + n + 4 * q + c] = hQ[q, c]
    HM[0] = hn + 1


@njit(cache=True, **_NJI)
def _add_breaks(BL, t, dl):
    """Insert t + tau_i into the sorted breakpoints BL (a typed List)."""
    for i in range(dl.shape[0]):
        v = t + dl[i]
        k = len(BL)
        while k > 0 and BL[k - 1] > v:
            k -= 1
        BL.insert(k, v)


@njit(cache=True, **_NJL)
def _scaled_rms(v, w, scale, diff):
    """The RMS norm of ``v / scale``, or of ``(v - w) / scale`` where ``diff``
    (a loop: no array made)."""
    s = 0.0
    for i in range(v.shape[0]):
        e = ((v[i] - w[i]) if diff else v[i]) / scale[i]
        s += e * e
    return math.sqrt(s) / math.sqrt(v.shape[0])


@njit(cache=True, **_NJL)
def _initial_guess(t0, y0, t_bound, f0, rtol, atol, y1, scale):
    """scipy's ``select_initial_step`` (direction +1, order 4), its first part:
    ``(h0, d1)`` (h0 0.0 where the interval is empty), with the Euler point
    ``y1`` and the error ``scale`` written in place. The caller evaluates the
    flow map at (t0 + h0, y1) and ends with :func:`_initial_step` (the flow
    map with delays is another function: this one never calls it)."""
    interval = abs(t_bound - t0)
    if interval == 0.0:
        return 0.0, 0.0
    n = y0.shape[0]
    for i in range(n):
        scale[i] = atol[i] + abs(y0[i]) * rtol
    d0 = _scaled_rms(y0, y0, scale, False)
    d1 = _scaled_rms(f0, f0, scale, False)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, interval)
    for i in range(n):
        y1[i] = y0[i] + h0 * f0[i]
    return h0, d1


@njit(cache=True, **_NJL)
def _initial_step(t0, t_bound, max_step, f0, f1, h0, d1, scale, order):
    """``select_initial_step``'s end, from :func:`_initial_guess`'s ``h0``,
    ``d1`` and ``scale`` and the flow map's value ``f1`` at its Euler point
    (``order``: the method's error estimator's); -1.0 where ``f1`` has the
    wrong length."""
    if f1.shape[0] != f0.shape[0]:
        return -1.0
    d2 = _scaled_rms(f1, f0, scale, True) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1.0))
    return min(100.0 * h0, h1, abs(t_bound - t0), max_step)


@njit(cache=True, **_NJI)
def _event(M, yold, hQ, told, h, j, p, has_C, has_D, d_active, phi_on, useD, useC,
           a, lo, hi, clamp, h_abs, flow_t0, prio, rngp, yb, yb_known, wk, ylo, yhi):
    """``_Run._event``: locate, then decide. Returns (kind, te, xe, lo, ylo, h_hint,
    from_hi): ``from_hi``, a jump from the bracket's hi (``xe`` the state there),
    whose bracket the post-jump tolerance reads (``rules.post_jump_probe``).
    ``xe`` and ``ylo`` are the scratch rows ``ylo``/``yhi`` the bracket's end
    states are written into (:func:`_locate`): read before the next event."""
    lo, hi = _locate(M, yold, hQ, told, h, j, p, has_C, d_active, phi_on, useD, useC, lo, hi,
                     yb, yb_known, wk, ylo, yhi)
    if hi <= flow_t0:
        hint = np.nan
    else:
        hint = min(h_abs, 10.0 * (hi - flow_t0))
    te_hi = hi if not clamp == clamp else min(hi, clamp)
    # ``rules.event_outcome``: the maps are read only where the rule needs them
    in_D_hi = has_D and _inD(M, _bare(yhi), hi, j, p)
    in_C_hi = True
    in_D_lo = False
    coin = True
    if d_active and in_D_hi:
        in_C_hi = (not has_C) or _inC(M, _bare(yhi), hi, j, p)
        if rules.needs_coin(in_C_hi, True, prio):
            coin = _coin(rngp)
    elif has_D:
        in_D_lo = _inD(M, _bare(ylo), lo, j, p)
    action, side = rules.event_outcome(d_active, in_D_hi, in_C_hi, in_D_lo, prio, coin)
    if action == _A_FLOW:
        return _O_FLOW_ON, te_hi, yhi, lo, ylo, hint, False
    if action == _A_STOP:
        return _O_STOP, lo, ylo, lo, ylo, hint, False
    if side == 1:
        return _O_JUMP, te_hi, yhi, lo, ylo, hint, True
    return _O_JUMP, lo, ylo, lo, ylo, hint, False


@njit(cache=True, **_NJI)
def _near_C(M, x, j, p, lo, yold, hQ, told, h, x_hi):
    """``_Run._near_C``: a post-jump state in neither C nor D is within the located
    event's tolerance of C (``rules.post_jump_probe``; off the run's main loop).

    The bracket's x_lo is rebuilt here, not kept per jump: the event step's
    dense output (``yold``, ``hQ``, ``told``, ``h``: untouched between the
    event and this test) at ``lo``, as :func:`_locate` made it (``yold``
    itself where ``lo`` is the step's start)."""
    x_lo = yold.copy() if lo == told else _dense(yold, hQ, told, h, lo)
    tp, xp = rules.post_jump_probe(x, lo, x_lo, x_hi)
    return _inC(M, xp, tp, j, p)


@njit(cache=True, **_NJI)
def _dop853_dense(f, K, ya, yb, a, hs, j, p, yi, hQ):
    """DOP853's dense output of the step from (a, ya) over hs to yb
    (scipy's ``DOP853._dense_output_impl``): its three extra stages into
    ``K[13:16]`` (``K[:13]``: the step's), F into ``hQ`` (n x 7, F
    transposed). Returns 0, 1 where the flow map gave the wrong length, 2
    where F is not finite (an overflow inside the step)."""
    n = ya.shape[0]
    for s in range(13, 16):
        for i in range(n):
            acc = 0.0
            for m in range(s):
                acc += K[m, i] * _A8X[s, m]
            yi[i] = ya[i] + acc * hs
        ks = f(yi, a + _C8X[s] * hs, j, p)
        if ks.shape[0] != n:
            return 1
        for q in range(n):
            K[s, q] = ks[q]
    ok = True
    for i in range(n):
        dy = yb[i] - ya[i]
        hQ[i, 0] = dy
        hQ[i, 1] = hs * K[0, i] - dy
        hQ[i, 2] = 2.0 * dy - hs * (K[12, i] + K[0, i])
        for k in range(4):
            acc = 0.0
            for m in range(16):
                acc += _D8[k, m] * K[m, i]
            hQ[i, 3 + k] = hs * acc
        for k in range(7):
            ok = ok and math.isfinite(hQ[i, k])
    return 0 if ok else 2


@njit(cache=True, **_NJI)
def _dop853_step_dense(f, K, ya, yb, a, hs, j, p, yi, hQ, stats, info):
    """:func:`_dop853_dense` for the run core: its evaluations counted, and
    the run's (cause, detail) where it fails (``info`` filled)."""
    r = _dop853_dense(f, K, ya, yb, a, hs, j, p, yi, hQ)
    stats[2] += 3
    if r == 0:
        return _GOES_ON, 0
    info[0] = a
    info[3] = j
    if r == 1:
        return MAP_ERROR, 2
    info[1] = a + hs
    return NON_FINITE, 2


def _run_core(maps, x0, p_in, fopt, iopt, atol, rngp, poll, stop):
    """One run, entirely compiled.

    ``maps``: the maps f, g, hD, hC, D, C by their addresses (an int64 array of
    their cfunc wrappers, :func:`map_addresses`), or a tuple of a system's own
    dispatchers (a specialised kernel; :func:`maps_of`).

    Returns ``(T, J, X, XD, cause, detail, info, stats)``: the samples
    (trimmed), the cause code (:data:`CAUSES`), a detail code saying which
    message variant, ``info`` (floats for the message: t, t2, value, j) and
    ``stats`` (steps, rejected, nfev, events, flows, jumps).

    ``rngp``: the run's numpy Generator by its addresses (:func:`rng_pointers`).
    ``poll``: the addresses of (check, occurred, clear): ``PyErr_CheckSignals``,
    ``PyErr_Occurred`` and ``PyErr_Clear`` for a run in the thread that holds
    the GIL (Ctrl-C is read at every step and jump: the run ends ``CANCELED``),
    zeros inside a parallel batch (nothing is called), whose runs read ``stop[0]``
    instead.
    """
    f, g, hD, hC, D, C = maps_of(maps)
    # the first NaN guard (which, s, j): written by ``_fault`` through its address
    ev = np.zeros(3)
    M = (f, g, hD, hC, D, C, iopt[11] != 0, iopt[12] != 0, ev.ctypes.data)
    # polled only where given (a batch's worker threads pass zeros: stop[0] only)
    polling = poll[0] != 0
    check = _check_at(poll[0])
    occurred = _occ_at(poll[1])
    clear = _clear_at(poll[2])
    t0 = fopt[0]
    t_max = fopt[1]
    j_max = fopt[2]
    rtol = fopt[3]
    max_step = fopt[4]
    first_step = fopt[5]
    max_norm = fopt[6]
    zeno_time = fopt[7]
    zeno_rtol = fopt[8]
    nd = iopt[13]                    # delays read by the flow map (fopt[9:])
    j0 = iopt[0]
    prio = iopt[1]
    max_steps = iopt[2]
    max_samples = iopt[3]
    zeno_jumps = iopt[4]
    refine = iopt[5]
    has_C = iopt[6] != 0
    has_D = iopt[7] != 0
    has_hC = iopt[8] != 0
    has_hD = iopt[9] != 0
    cap = iopt[10]
    # iopt[14]: a batch's run, whose samples are copied by the caller
    watch_D = has_D and prio != _FLOWS
    # every given guard goes into the event function (the indicators decide membership)
    useC = has_C and has_hC

    n = x0.shape[0]
    # with delays: the run's own p, the past's place after the parameters (NaN
    # but while the flow map runs), and the record of the steps (``_past``)
    # (``_DELAYS``: a constant of the kernel, False in :data:`run_one`, whose
    # code has none of this; :data:`run_one_delays` is the kernel with it)
    pb = p_in.shape[0]
    if _DELAYS:
        dl = fopt[9:9 + nd].copy()
        p = np.empty(pb + nd * n)
        for q in range(pb):
            p[q] = p_in[q]
        p[pb:] = np.nan
        HL = List.empty_list(_CHUNK_T)
        HM = np.zeros(5)
        HM[1] = t0
        HM[2] = np.nan
        cur_x = x0.copy()
        BL = List.empty_list(types.float64)     # delay breakpoints t_k + tau_i, sorted
        ibr = 0                                 # the first not yet passed
        _add_breaks(BL, t0, dl)
    else:
        p = _bare(p_in)              # the caller's: alive for the whole run
    T = np.empty(cap)
    J = np.empty(cap, np.int64)
    X = np.empty((cap, n))
    XD = np.empty((cap, n))
    stats = np.zeros(6, np.int64)
    info = np.full(6, np.nan)
    cause = -1
    detail = 0
    # the run's scratch, one owned array read again before the run returns (alive
    # throughout), its parts views without reference counts (:func:`_bare`)
    # the method (``_DOP``, a constant: the other's code is pruned): its
    # stages (the first the flow at the step's start), the rows of K (DOP853's
    # dense output adds three) and the dense output's columns
    NST = 12 if _DOP else 6
    NK = 16 if _DOP else 7
    NQ = 7 if _DOP else 4
    SA = _A8 if _DOP else _A
    SB = _B8 if _DOP else _B
    SC = _C8 if _DOP else _Cc
    ERRX = -1.0 / 8.0 if _DOP else _ERR_EXP
    work = np.zeros((NK + NQ + 10) * n)
    K = _bare(work[:NK * n]).reshape((NK, n))
    Ks = _bare(work[:(NST + 1) * n])         # the step's stages (scipy's solver.K)
    o = NK * n
    hQ = _bare(work[o:o + NQ * n]).reshape((n, NQ))
    o += NQ * n
    yi = _bare(work[o:o + n])        # a stage's state: read by f, never kept
    # the event search's states: the interior search's three samples, and a
    # trial point (``wk``, its last row); read by guards, never kept
    WS = _bare(work[o + n:o + 5 * n]).reshape((4, n))
    wk = WS[3]
    # the steps' new states, in turn: a step writes the row its start is not in
    # (``ya`` in row ``ya_row``, -1: not in these rows); copied where a flow ends
    YY = _bare(work[o + 5 * n:o + 7 * n]).reshape((2, n))
    # DOP853's first interior search: the cubic Hermite of the step's ends
    hH = _bare(work[o + 7 * n:o + 10 * n]).reshape((n, 3))

    t = t0
    j = j0
    x = x0.copy()
    jumps = 0
    short = 0
    t_last_jump = t0
    flows_last = np.zeros(4)        # the last (up to) 4 flow lengths, oldest first
    n_flows_last = 0
    h_hint = first_step              # NaN: none
    # counters as int64 from the start: a constant argument (Literal[int]) compiles
    # a helper again for it, even where type inference only tries it on the way
    ns = np.int64(0)                 # (the buffers start with room: iopt[10] rows)
    _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, t, j, _bare(x))
    ns = np.int64(1)
    # at x0: the maps' values are checked (the Python path raises at once)
    in_D0 = has_D and _inD(M, _bare(x), t, j, p)
    if ev[0] != 0.0:
        info[0] = ev[1]
        info[2] = ev[0]
        info[3] = ev[2]
        return (T[:1].copy(), J[:1].copy(), X[:1].copy(), XD[:1].copy(), MAP_ERROR,
                MAP_GUARD, info, stats)
    if (not has_C) or _inC(M, _bare(x), t, j, p):
        if _DELAYS:
            v0 = _fd(f, x, t, j, p, pb, dl, HL, HM, cur_x, x0, t0)
        else:
            v0 = f(x, t, j, p)
        if v0.shape[0] != n or not _all_finite(v0):
            info[0] = t
            info[2] = v0.shape[0]
            info[3] = j
            return (T[:1].copy(), J[:1].copy(), X[:1].copy(), XD[:1].copy(), MAP_ERROR,
                    MAP_FLOW_X0, info, stats)
    if in_D0:
        v0 = g(x, t, j, p)
        if v0.shape[0] != n or not _all_finite(v0):
            info[0] = t
            info[2] = v0.shape[0]
            info[3] = j
            return (T[:1].copy(), J[:1].copy(), X[:1].copy(), XD[:1].copy(), MAP_ERROR,
                    MAP_JUMP_X0, info, stats)
    forced = False
    flow_on = False
    in_D = False
    in_C = True
    loop = 0                         # consecutive jumps at one instant from C and D
    # the bracket's lo of the located event the last flow ends with, a jump from
    # its hi (``pend``), and of the jump just taken (``post``): rules.post_jump_probe.
    # Scalars only per jump (copying x_lo, x_hi at every jump cost ~10% of a
    # timer's run): ``_near_C`` rebuilds x_lo from the event step (a, ya, hQ,
    # hs), and x_hi is the pre-jump sample X[ns - 2]
    pend = False
    post = False
    post_lo = t0
    a = t0
    ya = x
    hs = 1.0
    done = False
    while not done:
        if stop[0] != 0 or (polling and (check() != 0 or occurred() != 0)):
            if polling:
                clear()              # the KeyboardInterrupt: the run ends CANCELED
            cause = CANCELED
            break
        if flow_on:
            in_D = True
        else:
            if forced:
                # the located event is in D: jump (``_Run._loop``, no set read again)
                forced = False
                from_C = True
                action = _A_JUMP
                post = pend
                pend = False
            else:
                in_D = has_D and _inD(M, _bare(x), t, j, p)
                in_C = (not has_C) or _inC(M, _bare(x), t, j, p)
                if ev[0] != 0.0:
                    cause = MAP_ERROR
                    detail = MAP_GUARD
                    break
                coin = False
                if rules.needs_coin(in_C, in_D, prio, False):
                    coin = _coin(rngp)
                action = rules.decide(in_C, in_D, prio, coin, False)
                if action == _A_STOP and post and _near_C(M, x, j, p, post_lo, ya, hQ, a,
                                                          hs, X[ns - 2]):
                    # within the located event's own error of C: in C
                    in_C = True
                    action = _A_FLOW
                if ev[0] != 0.0:
                    cause = MAP_ERROR
                    detail = MAP_GUARD
                    break
                post = False
                from_C = in_C
            if action == _A_JUMP:
                if jumps >= j_max:
                    cause = J_MAX
                    break
                xn = g(x, t, j, p)
                if xn.shape[0] != n or not _all_finite(xn):
                    cause = MAP_ERROR
                    detail = MAP_JUMP_SHAPE if xn.shape[0] != n else MAP_JUMP_VALUE
                    info[0] = t
                    info[2] = xn.shape[0]
                    info[3] = j
                    break
                # ---- the jump (``_Run._jump``)
                flow = t - t_last_jump
                if n_flows_last == 4:
                    flows_last[0] = flows_last[1]
                    flows_last[1] = flows_last[2]
                    flows_last[2] = flows_last[3]
                    flows_last[3] = flow
                else:
                    flows_last[n_flows_last] = flow
                    n_flows_last += 1
                if rules.is_short_flow(flow, t, rules.time_scale(t0, t, t_max), zeno_time,
                                       zeno_rtol):
                    short += 1
                else:
                    short = 0
                if from_C and flow == 0.0 and jumps > 0:
                    loop += 1
                else:
                    loop = 0
                t_last_jump = t
                j += 1
                jumps += 1
                x = xn.copy()
                if _DELAYS:                  # ``History._restart``, the new breakpoints
                    for q in range(n):
                        cur_x[q] = x[q]
                    HM[1] = t
                    _add_breaks(BL, t, dl)
                if ns >= max_samples:
                    cause = MAX_STEPS
                    detail = 1
                    info[0] = t
                    break
                if ns == T.shape[0]:
                    T, J, X, XD = _grown(T, J, X, XD, ns)
                _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, t, j, _bare(x))
                ns += 1
                c = rules.after_jump(jumps, short, j_max, zeno_jumps)
                if c != _GOES_ON:
                    cause = c
                    info[0] = t
                    info[2] = short
                    if rules.is_jump_loop(loop, zeno_jumps):
                        # the jumps of the loop and the one that started it, all at t
                        detail = DETAIL_LOOP
                        info[2] = loop + 1
                    break
                continue
            if action == _A_STOP:
                cause = _OUTSIDE     # decided below (_stop_outside)
                break
        if t >= t_max:
            cause = T_MAX
            break
        flow_on = False
        # ---------------------------------------------------------- a flow
        t_bound = t_max
        if _DELAYS:                          # ``_Run._bound``: the next breakpoint
            tol = 4.0 * _EPS * max(1.0, abs(t))
            while ibr < len(BL) and BL[ibr] <= t + tol:
                ibr += 1
            if ibr < len(BL) and BL[ibr] < t_max:
                t_bound = BL[ibr]
        flow_t0 = t
        hh0 = h_hint
        if hh0 == hh0:
            hh0 = min(hh0, t_bound - t, max_step)
            if not hh0 > 0:
                hh0 = np.nan
        if _DELAYS:
            fa = _fd(f, x, t, j, p, pb, dl, HL, HM, cur_x, x0, t0)
        else:
            fa = f(x, t, j, p)
        stats[2] += 1
        if fa.shape[0] != n:
            cause = MAP_ERROR
            detail = 2
            info[0] = t
            info[2] = fa.shape[0]
            info[3] = j
            break
        if hh0 == hh0:
            h_abs = hh0
        else:
            # scipy's select_initial_step: the Euler point in yi, the scale in WS[0]
            h0, d1 = _initial_guess(t, x, t_bound, fa, rtol, atol, yi, WS[0])
            h_abs = 0.0
            if abs(t_bound - t) != 0.0:
                if _DELAYS:
                    f1 = _fd(f, yi, t + h0, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                else:
                    f1 = f(yi, t + h0, j, p)
                h_abs = _initial_step(t, t_bound, max_step, fa, f1, h0, d1, WS[0],
                                      7.0 if _DOP else _ORDER)
            stats[2] += 1
            if h_abs < 0.0:
                cause = MAP_ERROR
                detail = 2
                info[0] = t
                info[3] = j
                break
        if _DELAYS and HM[2] == HM[2]:       # the past is missing (a delay under a step)
            cause, detail = _past_missing(info, HM, j)
            break
        stats[4] += 1
        for q in range(n):
            XD[ns - 1, q] = fa[q]
        a = t
        ya = x
        ya_row = -1
        yb_row = -1
        d_active = watch_D and not in_D
        tried = False
        outcome = _O_STOP
        while True:
            if stats[0] >= max_steps:
                cause = MAX_STEPS
                detail = 0
                info[0] = a
                t, x = a, ya
                outcome = _O_STOP
                break
            if stop[0] != 0 or (polling and (check() != 0 or occurred() != 0)):
                if polling:
                    clear()
                cause = CANCELED
                t, x = a, ya
                break
            # ---- scipy's RungeKutta._step_impl
            min_step = 10.0 * abs(np.nextafter(a, np.inf) - a)
            if h_abs > max_step:
                ha = max_step
            elif h_abs < min_step:
                ha = min_step
            else:
                ha = h_abs
            accepted = False
            rejected = False
            failed = False
            attempts = 0
            b = a
            hs = 0.0
            yb = ya
            fb = fa
            bad_len = False
            while not accepted:
                if ha < min_step:
                    failed = True
                    break
                hs = ha
                b = a + hs
                if b - t_bound > 0:
                    b = t_bound
                hs = b - a
                ha = abs(hs)
                attempts += 1
                tried = True
                for q in range(n):
                    K[0, q] = fa[q]
                for s in range(1, NST):
                    for i in range(n):
                        acc = 0.0
                        for m in range(s):
                            acc += K[m, i] * SA[s, m]
                        yi[i] = ya[i] + acc * hs
                    if _DELAYS:
                        ks = _fd(f, yi, a + SC[s] * hs, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                    else:
                        ks = f(yi, a + SC[s] * hs, j, p)
                    if ks.shape[0] != n:
                        bad_len = True
                        break
                    for q in range(n):
                        K[s, q] = ks[q]
                if bad_len:
                    break
                ynew_row = 1 if ya_row == 0 else 0
                ynew = YY[ynew_row]
                for i in range(n):
                    acc = 0.0
                    for m in range(NST):
                        acc += K[m, i] * SB[m]
                    ynew[i] = ya[i] + hs * acc
                if _DELAYS:
                    fnew = _fd(f, ynew, b, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                else:
                    fnew = f(ynew, b, j, p)
                stats[2] += NST
                if _DELAYS and HM[2] == HM[2]:
                    break
                if fnew.shape[0] != n:
                    bad_len = True
                    break
                for q in range(n):
                    K[NST, q] = fnew[q]
                if _DOP:
                    # ``DOP853._estimate_error_norm``
                    s5 = 0.0
                    s3 = 0.0
                    for i in range(n):
                        a5 = 0.0
                        a3 = 0.0
                        for m in range(13):
                            a5 += K[m, i] * _E5[m]
                            a3 += K[m, i] * _E3[m]
                        sc = atol[i] + max(abs(ya[i]), abs(ynew[i])) * rtol
                        e5 = a5 / sc
                        e3 = a3 / sc
                        s5 += e5 * e5
                        s3 += e3 * e3
                    n5 = math.sqrt(s5) ** 2
                    n3 = math.sqrt(s3) ** 2
                    if n5 == 0 and n3 == 0:
                        err = 0.0
                    else:
                        err = abs(hs) * n5 / math.sqrt((n5 + 0.01 * n3) * n)
                else:
                    es = 0.0
                    for i in range(n):
                        acc = 0.0
                        for m in range(7):
                            acc += K[m, i] * _E[m]
                        sc = atol[i] + max(abs(ya[i]), abs(ynew[i])) * rtol
                        e = acc * hs / sc
                        es += e * e
                    err = math.sqrt(es) / math.sqrt(n)
                if err < 1:
                    if err == 0:
                        factor = _MAX_FACTOR
                    else:
                        fc = _SAFETY * err ** ERRX
                        factor = fc if fc < _MAX_FACTOR else _MAX_FACTOR
                    if rejected:
                        factor = factor if factor < 1.0 else 1.0
                    ha *= factor
                    accepted = True
                    yb = ynew
                    yb_row = ynew_row
                    fb = fnew
                else:
                    fc = _SAFETY * err ** ERRX
                    ha *= fc if fc > _MIN_FACTOR else _MIN_FACTOR
                    rejected = True
            if attempts > 1:
                stats[1] += attempts - 1
            if _DELAYS and HM[2] == HM[2]:
                cause, detail = _past_missing(info, HM, j)
                t, x = a, ya
                break
            if bad_len:
                cause = MAP_ERROR
                detail = 2
                info[0] = a
                info[3] = j
                t, x = a, ya
                break
            if failed:
                # ``_Run._solver_failed``
                bad = tried and not _all_finite(Ks)
                if not bad:
                    if _DELAYS:
                        fy = _fd(f, ya, a, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                    else:
                        fy = f(ya, a, j, p)
                    bad = fy.shape[0] != n or not _all_finite(fy)
                if bad:
                    cause = NON_FINITE
                    detail = 1
                elif short > 0:
                    cause = ZENO
                    detail = 2
                else:
                    cause = SOLVER_FAILED
                info[0] = a
                info[3] = j
                t, x = a, ya
                break
            h_abs = ha
            stats[0] += 1
            if not _all_finite(yb):
                cause = NON_FINITE
                detail = 0
                info[0] = a
                info[1] = b
                info[3] = j
                t, x = a, ya
                break
            # dense output of the step: hQ = h K^T P (RK45); DOP853's costs three
            # evaluations more, made where it may be read (below)
            dense_ok = True
            if not _DOP:
                for i in range(n):
                    for k in range(4):
                        acc = 0.0
                        for m in range(7):
                            acc += K[m, i] * _P[m, k]
                        acc *= hs
                        hQ[i, k] = acc
                        dense_ok = dense_ok and math.isfinite(acc)
            if not dense_ok:
                # the dense output overflowed (a finite end, a non-finite interior)
                cause = NON_FINITE
                detail = 2
                info[0] = a
                info[1] = b
                info[3] = j
                t, x = a, ya
                break
            event = has_C and not _inC(M, _bare(yb), b, j, p)
            if d_active:
                event = event or _inD(M, _bare(yb), b, j, p)
            hit = False
            elo = a
            ehi = b
            phi_on = (d_active and has_hD) or useC
            if event:
                hit = True
            elif has_C or d_active:
                if _DOP:
                    # ``_Run._flow``: the search on the cubic Hermite of the step's
                    # ends first, a hit confirmed on the dense output (below)
                    for i in range(n):
                        hH[i, 0] = yb[i]
                        hH[i, 1] = hs * fa[i]
                        hH[i, 2] = hs * fb[i]
                    hit, elo, ehi = _interior(M, _bare(ya), hH, a, hs, j, p, has_C, d_active,
                                              phi_on, d_active and has_hD, useC, a, b, WS)
                else:
                    hit, elo, ehi = _interior(M, _bare(ya), hQ, a, hs, j, p, has_C, d_active,
                                              phi_on, d_active and has_hD, useC, a, b, WS)
            if _DOP and ev[0] == 0.0 and (hit or refine > 1 or (
                    b - t_bound >= 0 and not t_bound < t_max and watch_D)):
                # DOP853's dense output, made where it may be read: an event, a hit
                # to confirm, refined samples, an entry into D after t_max (below)
                cause, detail = _dop853_step_dense(f, K, ya, yb, a, hs, j, p, yi, hQ,
                                                   stats, info)
                if cause != _GOES_ON:
                    t, x = a, ya
                    break
                if hit and not event:
                    hit, elo, ehi = _interior(M, _bare(ya), hQ, a, hs, j, p, has_C, d_active,
                                              phi_on, d_active and has_hD, useC, a, b, WS)
            clamp = np.nan
            past = False
            if not hit and watch_D and not d_active:
                d_active = not _inD(M, _bare(yb), b, j, p)
            if ev[0] != 0.0:
                cause = MAP_ERROR
                detail = MAP_GUARD
                t, x = a, ya
                break
            if not hit:
                if _DELAYS:                  # ``History._add``
                    _record(HL, HM, a, b, hs, ya, hQ)
                ns_step = ns             # this step's samples start here
                if refine > 1 and b > a:
                    if ns + refine - 1 > max_samples:
                        cause = MAX_STEPS
                        detail = 1
                        info[0] = t
                        break
                    for r in range(1, refine):
                        s = a + (b - a) * (r / refine)
                        if ns == T.shape[0]:
                            T, J, X, XD = _grown(T, J, X, XD, ns)
                        _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, s, j,
                               _dense(ya, hQ, a, hs, s))
                        if not _DOP:         # (the Python path's: none for DOP853)
                            _dense_deriv_to(_bare(XD), ns, hQ, a, hs, s)
                        ns += 1
                if ns >= max_samples:
                    cause = MAX_STEPS
                    detail = 1
                    info[0] = t
                    break
                if ns == T.shape[0]:
                    T, J, X, XD = _grown(T, J, X, XD, ns)
                _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, b, j, _bare(yb))
                for q in range(n):
                    XD[ns, q] = fb[q]
                ns += 1
                if max_norm < np.inf:
                    nb = _norm(yb)
                    if nb > max_norm:
                        cause = BLOWUP
                        info[0] = b
                        info[2] = nb
                        info[3] = j
                        t, x = b, yb
                        break
                if b - t_bound >= 0:          # the solver finished
                    if t_bound < t_max:       # a delay breakpoint: flow on, a new flow
                        h_hint = h_abs
                        t, x = b, yb.copy()
                        outcome = _O_BREAK
                        break
                    h_hint = np.nan
                    if d_active:
                        # ``_event_past_t_max``: an entry into D within round-off
                        tb = b + rules.t_max_slack(b, jumps)
                        if _pred(M, tb, _dense(ya, hQ, a, hs, tb), j, p, has_C, d_active):
                            # the step's samples are stored again by the
                            # event's commit (up to te = b): drop them here
                            ns = ns_step
                            past = True
                            hit = True
                            elo = b
                            ehi = tb
                            clamp = b
                        if ev[0] != 0.0:
                            cause = MAP_ERROR
                            detail = MAP_GUARD
                            t, x = b, yb
                            break
                    if not past:
                        t, x = b, yb.copy()
                        outcome = _O_TMAX
                        break
                if not hit:
                    a = b
                    ya = yb
                    ya_row = yb_row
                    fa = fb
                    continue
            # ---- an event in (elo, ehi] of the step from a (``_Run._event``)
            da = True if past else d_active
            phi_on = (da and has_hD) or useC
            stats[3] += 1
            # the bracket's end states in WS's first two rows (free: the interior
            # search's samples are read no more); ``xe`` is one of them
            kind, te, xe, lo, _ylo, hint, from_hi = _event(
                M, _bare(ya), hQ, a, hs, j, p, has_C, has_D, da, phi_on, da and has_hD, useC,
                a, elo, ehi, clamp, h_abs, flow_t0, prio, rngp, yb, ehi == b and not past, wk,
                WS[0], WS[1])
            h_hint = hint
            if ev[0] != 0.0:
                cause = MAP_ERROR
                detail = MAP_GUARD
                t, x = a, ya
                break
            # ``_commit``
            if _DELAYS and not past and te > a:
                _record(HL, HM, a, te, hs, ya, hQ)
            if te > a:
                if refine > 1:
                    if ns + refine - 1 > max_samples:
                        cause = MAX_STEPS
                        detail = 1
                        info[0] = t
                        break
                    for r in range(1, refine):
                        s = a + (te - a) * (r / refine)
                        if ns == T.shape[0]:
                            T, J, X, XD = _grown(T, J, X, XD, ns)
                        _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, s, j,
                               _dense(ya, hQ, a, hs, s))
                        if not _DOP:         # (the Python path's: none for DOP853)
                            _dense_deriv_to(_bare(XD), ns, hQ, a, hs, s)
                        ns += 1
                if ns >= max_samples:
                    cause = MAX_STEPS
                    detail = 1
                    info[0] = t
                    break
                if ns == T.shape[0]:
                    T, J, X, XD = _grown(T, J, X, XD, ns)
                _store(_bare(T), _bare(J), _bare(X), _bare(XD), ns, te, j, _bare(xe))
                if _DELAYS:
                    fe = _fd(f, xe, te, j, p, pb, dl, HL, HM, cur_x, x0, t0)
                else:
                    fe = f(xe, te, j, p)
                if fe.shape[0] == n:
                    for q in range(n):
                        XD[ns, q] = fe[q]
                ns += 1
                if max_norm < np.inf:        # the event's sample, as a step's end
                    nb = _norm(xe)
                    if nb > max_norm:
                        cause = BLOWUP
                        info[0] = te
                        info[2] = nb
                        info[3] = j
                        t, x = te, xe.copy()
                        break
            # a jump reads xe (its scratch row) at once and makes its own state; a
            # run that flows on from xe, or ends there, keeps a copy
            t, x = te, (xe if kind == _O_JUMP else xe.copy())
            outcome = kind
            if from_hi:
                pend = True
                post_lo = lo
            if kind == _O_STOP:
                cause = _OUTSIDE
                detail = 1
                info[0] = lo
                info[3] = j
            break
        if cause != _GOES_ON:
            break
        if outcome == _O_JUMP:
            forced = True
        elif outcome == _O_FLOW_ON:
            flow_on = True
    if cause == _OUTSIDE:
        # ``_Run._stop_outside``: x0 outside both sets, sticking, or leaving C u D
        if ns == 1:
            cause = NOT_IN_SETS
            detail = 0
        else:
            scale = rules.time_scale(t0, t, t_max)
            if rules.is_sticking(flows_last[:n_flows_last], t - t_last_jump, jumps, scale):
                cause = ZENO
                detail = 1
                info[1] = flows_last[n_flows_last - 3]
                info[4] = flows_last[n_flows_last - 2]
                info[5] = flows_last[n_flows_last - 1]
            else:
                cause = LEFT_SETS
        info[0] = t
        info[3] = j
    if cause == MAP_ERROR and detail == MAP_GUARD:
        info[0] = ev[1]
        info[2] = ev[0]
        info[3] = ev[2]
    if cause != MAP_ERROR and XD[ns - 1, 0] != XD[ns - 1, 0]:
        if _DELAYS:
            fl = _fd(f, np.ascontiguousarray(X[ns - 1]), T[ns - 1], J[ns - 1], p, pb, dl, HL, HM,
                     cur_x, x0, t0)
        else:
            fl = f(np.ascontiguousarray(X[ns - 1]), T[ns - 1], J[ns - 1], p)
        if fl.shape[0] == n:
            _put(XD, ns - 1, fl)
    stats[5] = jumps
    if work[0] != work[0]:           # (keeps the scratch's owner alive to here)
        stats[5] = jumps
    if iopt[14] != 0:
        # a batch's run (:func:`run_rows` copies it into the pool at once): the
        # buffers themselves, cut to the samples (no copy, four arrays fewer)
        return T[:ns], J[:ns], X[:ns], XD[:ns], cause, detail, info, stats
    return (T[:ns].copy(), J[:ns].copy(), X[:ns].copy(), XD[:ns].copy(), cause, detail,
            info, stats)


#: one run of the maps at the addresses ``maps`` (f, g, hD, hC, D, C: their cfunc
#: wrappers, :func:`map_addresses`): compiled once, cached on disk. The core
#: itself, not a wrapper calling it: a wrapper's library is optimized and
#: code-generated again with the whole core linked in (about 2.6 s of the
#: first compile)
run_one = njit(cache=True, **_NJ)(_run_core)

#: one run specialised on a system's own map dispatchers (maps compiled in, passed
#: as a tuple): the module :func:`spec_module` generates calls it under
#: ``run_one``'s signature (never cached itself: its signature names the system)
run_one_spec = njit(**_NJI)(_run_core)


def _variant(fn, suffix, **consts):
    """``fn`` (the run core) as a function of its own whose constants
    ``consts`` (``_DELAYS``, ``_DOP``) are set: the same code, its module's
    globals but those (numba reads a global as a constant of the compiled
    code, and caches this function apart from ``fn``, under its own name)."""
    import types as pytypes
    glb = dict(fn.__globals__)
    glb.update(consts)
    out = pytypes.FunctionType(fn.__code__, glb, fn.__name__ + suffix, fn.__defaults__,
                               fn.__closure__)
    out.__qualname__ = fn.__qualname__ + suffix
    out.__module__ = fn.__module__
    out.__doc__ = fn.__doc__
    return out


#: :data:`run_one` for a flow map that reads the past (``CompiledSystem(delays=)``):
#: the run core with the record of the steps and the delay breakpoints,
#: compiled (and cached) only when a system with delays first runs
run_one_delays = njit(cache=True, **_NJ)(_variant(_run_core, "_delays", _DELAYS=True))

#: :data:`run_one_spec` with delays
run_one_spec_delays = njit(**_NJI)(_variant(_run_core, "_delays", _DELAYS=True))

#: :data:`run_one` stepping with scipy's DOP853 (``method="DOP853"``): compiled
#: (and cached) when a run first asks for it. Not with delays (refused by name)
run_one_dop853 = njit(cache=True, **_NJ)(_variant(_run_core, "_dop853", **DOP853_GLOBALS))

#: :data:`run_one_spec` stepping with DOP853
run_one_spec_dop853 = njit(**_NJI)(_variant(_run_core, "_dop853", **DOP853_GLOBALS))

#: what :func:`run_one` returns, and its type as a first-class function value
ONE_RET = types.Tuple((types.float64[::1], types.int64[::1], types.float64[:, ::1],
                       types.float64[:, ::1], types.int64, types.int64, types.float64[::1],
                       types.int64[::1]))
_I64C, _F64C = types.int64[::1], types.float64[::1]
ONE_SIG = ONE_RET(_I64C, _F64C, _F64C, _F64C, _I64C, _F64C, _I64C, _I64C, _I64C)
with warnings.catch_warnings():
    warnings.simplefilter("ignore", nb_errors.NumbaExperimentalFeatureWarning)
    ONE_T = types.FunctionType(ONE_SIG)


@intrinsic
def _one_at(typingctx, addr):
    """A kernel of :data:`ONE_SIG` by the address of its compiled code (numba's
    own calling convention, ``jit_addr``: arrays and tuples pass as they are)."""
    if not isinstance(addr, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        st = cgutils.create_struct_proxy(ONE_T)(context, builder)
        vp = context.get_value_type(types.voidptr)
        st.jit_addr = builder.inttoptr(args[0], vp)
        st.c_addr = ir.Constant(vp, None)
        st.py_addr = ir.Constant(vp, None)
        return st._getvalue()
    return ONE_T(addr), codegen


def jit_address(disp):
    """The address of ``disp``'s code compiled for :data:`ONE_SIG`'s arguments
    (the ``one`` argument of :func:`run_rows`; ``disp`` must outlive its use)."""
    cres = disp.overloads[_signature_one()]
    if cres.signature.return_type != ONE_RET:
        raise TypeError(f"a run kernel must return {ONE_RET}, got "
                        f"{cres.signature.return_type}")
    return cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)


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


@njit(cache=True, nogil=True, **_NJ)
def run_rows(one, maps, X0, p, fopt, iopt, atol, rngp, poll, stop, next_row, chunk,
             TT, JJ, XX, XXD, fill, AT, NS, CA, DE, INFO, ST):
    """Runs of a batch, taken ``chunk`` rows at a time from the shared counter
    ``next_row`` until none is left, each run's samples written one after
    another into the batch's compact pool (``TT``, ``JJ``, ``XX``, ``XXD``):
    at rows ``AT[i]:AT[i] + NS[i]``, claimed from the shared ``fill`` counter
    when the run ends. A run that does not fit in the pool keeps only its
    counts (``AT[i] = -1``) and is re-run by the caller.

    Released from the GIL: the caller runs it in as many threads as it wants
    cores (dynamic scheduling: a thread slowed by other work on the machine
    takes fewer chunks), all on one pool. ``one``: the address of the run
    kernel (:func:`jit_address`: ``run_one`` for the maps at ``maps``, or a
    system's specialised kernel), called, not compiled in: this kernel is
    compiled once, small, and serves every system. The pool needs no
    compaction afterwards: every arc is a view of its rows."""
    N = X0.shape[0]
    size = TT.shape[0]
    while True:
        i0 = _claim(next_row, chunk)
        if i0 >= N:
            break
        for i in range(i0, min(i0 + chunk, N)):
            T, J, X, XD, cause, detail, info, stats = _one_at(one)(
                maps, np.ascontiguousarray(X0[i]), p, fopt, iopt, atol, rngp, poll, stop)
            m = T.shape[0]
            NS[i] = m
            CA[i] = cause
            DE[i] = detail
            _put(INFO, i, info)
            for q in range(stats.shape[0]):     # (not _put: a second version for int64)
                ST[i, q] = stats[q]
            o = _claim_within(fill, m, size)
            AT[i] = o
            if o >= 0:
                for r in range(m):
                    TT[o + r] = T[r]
                    JJ[o + r] = J[r]
                    for q in range(X.shape[1]):
                        XX[o + r, q] = X[r, q]
                        XXD[o + r, q] = XD[r, q]
    return 0


def _signature_one():
    i64, f64 = types.int64[::1], types.float64[::1]
    # maps, x0, p, fopt, iopt, atol, rngp, poll, stop
    return (i64, f64, f64, f64, i64, f64, i64, i64, i64)


def _key_with_rules():
    """Add the rules' digest to the cache key of every cached dispatcher here."""
    digest = _rules_digest()
    for obj in list(globals().values()):
        cache = getattr(obj, "_cache", None)
        if isinstance(obj, numba.core.dispatcher.Dispatcher) and \
                hasattr(cache, "_index_key") and not getattr(cache, "_hs_keyed", False):
            orig = cache._index_key
            cache._index_key = _keyed(orig, digest)
            cache._hs_keyed = True


def _keyed(orig, digest):
    """A cache index key with the rules' digest appended."""
    return lambda sig, codegen: orig(sig, codegen) + (digest,)


def _unless_specialised(fn):
    """A cache save/load that skips specialised signatures (see below)."""
    return lambda sig, arg: None if _has_dispatcher(sig) else fn(sig, arg)


def _has_dispatcher(sig):
    """A signature with a Dispatcher type (a specialised kernel's): never cached,
    since its index entry would name the user's module."""
    stack = list(sig.args if hasattr(sig, "args") else sig)
    while stack:
        ty = stack.pop()
        if isinstance(ty, types.Dispatcher):
            return True
        if isinstance(ty, types.BaseTuple):
            stack.extend(ty.types)
    return False


def _skip_specialised():
    for obj in list(globals().values()):
        cache = getattr(obj, "_cache", None)
        if isinstance(obj, numba.core.dispatcher.Dispatcher) and \
                hasattr(cache, "save_overload") and not getattr(cache, "_hs_skip", False):
            save, load = cache.save_overload, cache.load_overload
            cache.save_overload = _unless_specialised(save)
            cache.load_overload = _unless_specialised(load)
            cache._hs_skip = True


try:                      # numba's private cache API: without it, the key is numba's own
    _key_with_rules()
    _skip_specialised()
except Exception:  # noqa: BLE001 - a numba version without these internals
    pass


_READY = set()


def _batch_signature(sig):
    """:func:`run_rows`'s: one, maps, X0, p, fopt, iopt, atol, rngp, poll, stop,
    next_row, chunk, then the pool (TT, JJ, XX, XXD, fill, AT) and the rows'
    records (NS, CA, DE, INFO, ST)."""
    f1, f2, i2 = types.float64[::1], types.float64[:, ::1], types.int64[:, ::1]
    i1 = types.int64[::1]
    return ((types.int64,) + sig[:1] + (f2,) + sig[2:] + (i1, types.int64)
            + (f1, i1, f2, f2, i1, i1, i1, i1, i1, f2, i2))


def cache_dir():
    """Where numba keeps this module's compiled kernels (None: not cached)."""
    try:
        return run_one._cache._cache_path
    except AttributeError:
        return None


# ------------------------------------------------------------------ specialised kernels
# numba's ``cache=True`` cannot keep a kernel that closes over dispatchers made
# at run time. A specialised kernel is therefore a generated module file, one
# per system and engine (its name is a digest of the maps' code, constants,
# closures and globals, and of the engine's source), whose ``one`` reads the
# maps as module globals set before it compiles: numba caches it like any
# function of a file, and a new process loads it without compiling the maps.
_SPEC_HEAD = """\"\"\"hybridsim.compiled: a run kernel specialised on one system's maps.

Generated by hybridsim.compiled._kernel.spec_module (key {key}); safe to delete.
\"\"\"
import numba

from hybridsim.compiled import _kernel as _k

# the run core's globals: the engine's helpers and constants
globals().update((k, v) for k, v in vars(_k).items() if not k.startswith("__"))

f = g = hD = hC = D = C = None     # the system's compiled maps, set before one compiles
_f, _g, _hD, _hC, _D, _C = (_k.map_value(globals(), r) for r in ("f", "g", "hD", "hC", "D", "C"))


"""

#: the line of the run core that takes its maps, and its specialised kernel's
_MAPS_LINE = "    f, g, hD, hC, D, C = maps_of(maps)\n"
_SPEC_MAPS_LINE = "    f, g, hD, hC, D, C = _f(), _g(), _hD(), _hC(), _D(), _C()\n"


def _spec_source(key, delays=False, method="RK45"):
    """A specialised kernel's module: the run core itself (its source, the maps
    read from the module's globals), so that numba optimizes and generates its
    code once (a wrapper calling :data:`run_one_spec` took about 2.4 s more);
    with the code for the past where ``delays`` (see :data:`run_one_delays`),
    DOP853's steps where ``method`` is ``"DOP853"`` (``key`` then names them
    too, :func:`spec_key`)."""
    import inspect
    core = inspect.getsource(_run_core)
    head = "def _run_core(maps, "
    if not core.startswith(head) or core.count(_MAPS_LINE) != 1:
        raise RuntimeError("hybridsim.compiled: the run core's source is not as expected")
    core = "def one(maps, " + core[len(head):].replace(_MAPS_LINE, _SPEC_MAPS_LINE)
    head = _SPEC_HEAD.format(key=key)
    if delays:
        head += "_DELAYS = True     # the flow map reads the past\n\n\n"
    if method == "DOP853":
        head += "globals().update(_k.DOP853_GLOBALS)     # DOP853's steps\n\n\n"
    return (head + core
            + '\n\none = numba.njit(cache=True, error_model="numpy")(one)\n')


def map_value(glb, name):
    """An intrinsic: the dispatcher ``glb[name]`` as a value of its type, without
    its address in the code (numba's constant for a dispatcher is its address,
    a "dynamic global" that keeps the kernel out of the disk cache; the value
    is never read: calls through a dispatcher's type are resolved statically)."""
    @intrinsic
    def value(typingctx):
        ty = typingctx.resolve_value_type(glb[name])

        def codegen(context, builder, sig, args):
            return context.get_dummy_value()
        return ty(), codegen
    return value


class Unkeyable(TypeError):
    """A map reads a value the specialised kernel's digest cannot key on."""


def _digest_value(v, h, seen, depth=0):
    """Feed ``v`` (a constant, array, module, function or dispatcher a map reads)
    into the hash ``h``; raise :class:`Unkeyable` for anything else."""
    if depth > 50:
        raise Unkeyable("too deeply nested")
    if v is None or isinstance(v, (bool, int, float, complex, str, bytes, np.generic)):
        h.update(f"{type(v).__name__}:{v!r};".encode())
    elif isinstance(v, np.ndarray):
        h.update(f"nd:{v.dtype.str}:{v.shape};".encode())
        h.update(np.ascontiguousarray(v).tobytes())
    elif isinstance(v, (tuple, list)):
        h.update(f"{type(v).__name__}:{len(v)}(".encode())
        for e in v:
            _digest_value(e, h, seen, depth + 1)
        h.update(b")")
    elif inspect.ismodule(v):
        h.update(f"module:{v.__name__};".encode())
    elif isinstance(v, numba.core.dispatcher.Dispatcher):
        h.update(f"dispatcher:{sorted(v.targetoptions.items())!r};".encode())
        _digest_value(v.py_func, h, seen, depth + 1)
    elif inspect.isfunction(v):
        if id(v) in seen:
            h.update(b"<seen>")
            return
        seen.add(id(v))
        h.update(f"fn:{v.__module__}.{v.__qualname__};".encode())
        _digest_code(v.__code__, v.__globals__, h, seen, depth)
        for c in v.__closure__ or ():
            _digest_value(c.cell_contents, h, seen, depth + 1)
        _digest_value(v.__defaults__, h, seen, depth + 1)
    elif isinstance(v, (np.ufunc, types.Type)) or inspect.isbuiltin(v) or \
            (isinstance(v, type) and v.__module__ in ("builtins", "numpy", "math")):
        h.update(f"named:{getattr(v, '__module__', '')}.{getattr(v, '__name__', v)!s};"
                 .encode())
    else:
        raise Unkeyable(f"a map reads a {type(v).__name__}")


def _digest_code(code, glb, h, seen, depth):
    h.update(code.co_code)
    h.update(repr(code.co_names).encode())
    for c in code.co_consts:
        if inspect.iscode(c):
            _digest_code(c, glb, h, seen, depth + 1)
        else:
            _digest_value(c, h, seen, depth + 1)
    for name in code.co_names:
        if name in glb:
            h.update(f"global:{name}=".encode())
            _digest_value(glb[name], h, seen, depth + 1)


def _engine_digest():
    """The engine's own key: this file, the rules, numba's and Python's versions."""
    import sys
    h = hashlib.sha256()
    with open(__file__, "rb") as fh:
        h.update(fh.read())
    h.update(_rules_digest().encode())
    h.update(f"{numba.__version__};{sys.version};{np.__version__}".encode())
    return h.hexdigest()


_ENGINE_DIGEST = []


def spec_key(maps, delays=False, method="RK45"):
    """The digest naming a system's specialised kernel: ``maps`` is a tuple of
    (role, kind, function or None) for f, g, hD, hC, D, C; ``delays``: whether
    its flow map reads the past; ``method``: "RK45" or "DOP853". Raises
    :class:`Unkeyable` for a map reading a value that cannot be keyed."""
    if not _ENGINE_DIGEST:
        _ENGINE_DIGEST.append(_engine_digest())
    h = hashlib.sha256(_ENGINE_DIGEST[0].encode())
    if delays:
        h.update(b"delays;")
    if method != "RK45":
        h.update(f"{method};".encode())
    seen = set()
    for role, kind, fn in maps:
        h.update(f"{role}:{kind}:".encode())
        _digest_value(fn, h, seen)
    return h.hexdigest()[:32]


def _spec_dirs():
    """Where generated kernels may go, the first writable one: beside numba's
    cache of this module, then the user's cache directory."""
    out = []
    d = cache_dir()
    if d:
        out.append(os.path.join(d, "specialized"))
    from numba.misc.appdirs import AppDirs
    out.append(os.path.join(AppDirs(appname="hybridsim", appauthor=False).user_cache_dir,
                            "specialized"))
    return out


def spec_module(key, delays=False, method="RK45"):
    """The generated module of ``key`` (written once; None where no folder is
    writable: the caller then compiles in memory); ``delays`` and ``method``
    as :func:`_spec_source`'s, the ones ``key`` was made with."""
    import importlib.util
    import sys
    name = f"hybridsim_spec_{key}"
    if name in sys.modules:
        return sys.modules[name]
    src = _spec_source(key, delays, method)
    for d in _spec_dirs():
        path = os.path.join(d, name + ".py")
        try:
            os.makedirs(d, exist_ok=True)
            if not os.access(d, os.W_OK):
                continue
            if not os.path.exists(path):
                tmp = f"{path}.{os.getpid()}.tmp"
                with open(tmp, "w") as fh:
                    fh.write(src)
                os.replace(tmp, path)       # atomic: processes may race here
                remove_stale(d)             # (a new module: the engine may have changed)
            with open(path) as fh:
                if fh.read() != src:
                    continue
        except OSError:
            continue
        spec = importlib.util.spec_from_file_location(name, path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        sys.modules[name] = mod
        return mod
    return None


#: a generated module another engine wrote is removed once it is this old (seconds):
#: a checkout switched back to that engine within the week still finds it
STALE_AGE = 7 * 24 * 3600.0


def remove_stale(d, age=None):
    """Remove the generated modules in the folder ``d`` that this engine would
    not write, with their numba cache and bytecode, once older than ``age``
    seconds (default :data:`STALE_AGE`). Returns the keys removed.

    A module is this engine's when its text is exactly what
    :func:`_spec_source` makes for its key: a module of another engine (an
    older checkout, another installed version sharing the user cache folder)
    can never be loaded by this one, and nothing else removes it. Its age is
    its file's (written once: numba's index records that time). Files that
    vanish meanwhile (another process cleaning) are passed over.

    Examples
    --------
    >>> import tempfile
    >>> remove_stale(tempfile.mkdtemp())
    []
    """
    import glob
    import time
    age = STALE_AGE if age is None else age
    now = time.time()
    removed = []
    for path in glob.glob(os.path.join(d, "hybridsim_spec_*.py")):
        name = os.path.basename(path)[:-3]
        key = name[len("hybridsim_spec_"):]
        try:
            if now - os.path.getmtime(path) < age:
                continue
            with open(path) as fh:
                if fh.read() in (_spec_source(key), _spec_source(key, True),
                                 _spec_source(key, method="DOP853")):
                    continue
            os.remove(path)
        except (OSError, ValueError):
            continue
        for cached in glob.glob(os.path.join(d, "__pycache__", glob.escape(name) + ".*")):
            try:
                os.remove(cached)
            except OSError:
                pass
        removed.append(key)
    return sorted(removed)


def spec_in_cache(mod):
    """Whether the generated module's kernel is in numba's disk cache."""
    return _in_cache(mod.one, _signature_one())


def _in_cache(disp, sig):
    """Whether numba's disk cache holds ``disp`` compiled for ``sig`` (numba's
    private cache API; where it is missing, the answer is no)."""
    try:
        cache = disp._cache
        key = cache._index_key(sig, disp.targetctx.codegen())
        return key in cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 - another numba: say it compiles
        return False


def _tag(delays, method):
    if method == "DOP853":
        if delays:
            raise ValueError("the compiled path steps a flow map with delays with RK45 only")
        return "one_dop853"
    return "one_delays" if delays else "one"


def run_kernel(delays=False, method="RK45"):
    """The cached run kernel of systems whose maps are passed by address:
    :data:`run_one`, :data:`run_one_delays` for a flow map that reads the
    past, :data:`run_one_dop853` for ``method="DOP853"``."""
    return {"one": run_one, "one_delays": run_one_delays,
            "one_dop853": run_one_dop853}[_tag(delays, method)]


def compile_kernels(batch=True, notice=None, one=True, delays=False, method="RK45"):
    """Compile (or load from numba's on-disk cache) the kernels for the
    first-class map signatures: the run kernel (:func:`run_kernel` of
    ``delays`` and ``method``; unless not ``one``: a specialised system's
    batch needs only ``run_rows``), and ``run_rows`` when ``batch``.

    ``notice(cache_dir, seconds)`` is called once per run kernel and process
    before it is compiled (not in the disk cache; ``seconds``: about how
    long, the batch kernel's included where it is compiled with it). The
    batch kernel alone (about a second) is compiled without one."""
    tag = _tag(delays, method)
    want_one = one and tag not in _READY
    want_batch = batch and "batch" not in _READY
    if not (want_one or want_batch):
        return          # every call of simulate_compiled asks: answer cheaply
    import warnings
    sig = _signature_one()
    run = run_kernel(delays, method)
    if notice is not None and want_one and ("noticed", tag) not in _READY \
            and not _in_cache(run, sig):
        _READY.add(("noticed", tag))
        seconds = COMPILE_SECONDS[{"one": 0, "one_delays": 3, "one_dop853": 4}[tag]]
        if want_batch and not _in_cache(run_rows, _batch_signature(sig)):
            seconds += COMPILE_SECONDS[1]
        notice(cache_dir(), seconds,
               what={"one": "the engine's kernels",
                     "one_delays": "the engine's kernels for flow maps with delays",
                     "one_dop853": "the engine's DOP853 kernel"}[tag])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", nb_errors.NumbaExperimentalFeatureWarning)
        # compiled for the first-class map signatures only: a call with a
        # system's map dispatchers converts them instead of specialising
        if want_one:
            _compile_or_rebuild(run, sig)
            _ONE_ADDR[tag] = jit_address(run)
            _READY.add(tag)
        if want_batch:
            _compile_or_rebuild(run_rows, _batch_signature(sig))
            _READY.add("batch")


#: CPU seconds to compile run_one, run_rows, a specialised run kernel,
#: run_one_delays and run_one_dop853 with an empty cache (measured on the
#: project's machine, issue 27; the notice quotes them)
COMPILE_SECONDS = (15, 1, 15, 20, 15)
#: the run kernels' code addresses (:func:`jit_address`), once compiled
_ONE_ADDR = {}


def one_address(delays=False, method="RK45"):
    """:func:`run_kernel`'s code address (the ``one`` of :func:`run_rows`)."""
    compile_kernels(batch=False, delays=delays, method=method)
    return _ONE_ADDR[_tag(delays, method)]


#: LLVM's optimisation level for the engine's cached kernels (``run_one``,
#: ``run_one_delays``, ``run_rows``): numba's default is 3 (``NUMBA_OPT``; a
#: lower level set there is kept). At 1 they compiled 1.2-2.8 s faster (of
#: 12-17 s) and ran as fast or faster (the generic 30-bounce ball 1.72-1.78x
#: the hand-written loop against 1.80-1.85x at 3, three alternating
#: processes), to the same bits: the run core is one large function of
#: branches and short loops over the state, where level 3's inlining and
#: unrolling cost compile time and instruction cache. A specialised kernel
#: keeps numba's level: with the maps inlined it ran 20% slower at 1.
KERNEL_OPT = 1


@contextlib.contextmanager
def kernel_opt(level=KERNEL_OPT):
    """numba's optimisation level lowered to ``level`` while a kernel
    compiles (numba reads ``config.OPT`` for each library's LLVM passes; the
    target machine's own level is unchanged)."""
    cfg = numba.core.config
    old = cfg.OPT
    if int(old) > level:
        cfg.OPT = cfg._OptLevel(level)
    try:
        yield
    finally:
        cfg.OPT = old


def _compile_or_rebuild(disp, sig):
    """``disp.compile(sig)`` at :data:`KERNEL_OPT`, then no other
    specialisation. A disk cache that cannot be read (written by another
    numba, or damaged) is bypassed: the kernels are compiled in memory for
    this process."""
    with kernel_opt():
        try:
            disp.compile(sig)
        except Exception:  # noqa: BLE001 - an unreadable cache index
            from numba.core.caching import NullCache
            for obj in list(globals().values()):
                if isinstance(obj, numba.core.dispatcher.Dispatcher) and \
                        obj._cache is not None:
                    obj._cache = NullCache()
            disp.compile(sig)
    disp.disable_compile()



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
#: (the run ends CANCELED)
POLL_GIL = _addresses([_c_api_address(n) for n in
                       ("PyErr_CheckSignals", "PyErr_Occurred", "PyErr_Clear")])
#: the same slots for runs on a parallel batch's worker threads: none (no GIL:
#: they read the batch's stop flag only, and call nothing at every step)
POLL_NONE = _addresses([0, 0, 0])


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
