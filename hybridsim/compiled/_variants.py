"""The compiled path's run kernels: the run core (:func:`._kernel._run_core`)
compiled, once per setting of its constants (imported only when numba is
installed).

Two kernels are compiled and cached: :data:`run_one` (one run) and
:func:`._batch.run_rows` (a batch's rows, in GIL-free Python threads), which
calls a run kernel by its code address instead of compiling it in (numba links and
re-optimises a callee's code into every caller: the batch kernel used to
cost as much to compile as the engine). A flow map that reads the past
(delays) runs in a third, :data:`run_one_delays`, compiled when such a
system first runs: the same run core with the record of the steps, which
:data:`run_one` leaves out (a quarter of its compile time); ``method="DOP853"``
in a fourth; ``method="RK4"`` (the classic Runge-Kutta method at the fixed
step ``max_step``) in :data:`run_one_rk4` and, with delays,
:data:`run_one_rk4_delays`. Each is the one run core with its constants
``_DELAYS``, ``_DOP`` and ``_RK4`` set (:func:`_variant`), and a system's
watched functions in another (:data:`run_one_watch`, ``_WATCH``,
:mod:`._watch`). numba caches each by the run core's file (:mod:`._kernel`),
under its own name; each is compiled only when a run first asks for it.
"""
from __future__ import annotations

from numba import njit

from ._kernel import DOP853_GLOBALS, RK4_GLOBALS, _run_core
from ._types import _NJI, _NJK, CACHE

#: one run of the maps at the addresses ``maps`` (f, g, hD, hC, D, C: their cfunc
#: wrappers, :func:`map_addresses`): compiled once, cached on disk. The core
#: itself, not a wrapper calling it: a wrapper's library is optimized and
#: code-generated again with the whole core linked in (about 2.6 s of the
#: first compile)
run_one = njit(cache=CACHE, **_NJK)(_run_core)

#: one run specialised on a system's own map dispatchers (maps compiled in, passed
#: as a tuple): the module :func:`spec_module` generates calls it under
#: ``run_one``'s signature (never cached itself: its signature names the system)
run_one_spec = njit(**_NJI)(_run_core)


def _variant(fn, suffix, **consts):
    """``fn`` (the run core) as a function of its own whose constants
    ``consts`` (``_DELAYS``, ``_DOP``, ``_RK4``) are set: the same code, its module's
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
run_one_delays = njit(cache=CACHE, **_NJK)(_variant(_run_core, "_delays", _DELAYS=True))

#: :data:`run_one_spec` with delays
run_one_spec_delays = njit(**_NJI)(_variant(_run_core, "_delays", _DELAYS=True))

#: :data:`run_one` stepping with scipy's DOP853 (``method="DOP853"``): compiled
#: (and cached) when a run first asks for it. Not with delays (refused by name)
run_one_dop853 = njit(cache=CACHE, **_NJK)(_variant(_run_core, "_dop853", **DOP853_GLOBALS))

#: :data:`run_one_spec` stepping with DOP853
run_one_spec_dop853 = njit(**_NJI)(_variant(_run_core, "_dop853", **DOP853_GLOBALS))

#: :data:`run_one` stepping with the classic RK4 at the fixed step ``max_step``
#: (``method="RK4"``, :class:`hybridsim._rk.RK4`): compiled (and cached) when a run
#: first asks for it
run_one_rk4 = njit(cache=CACHE, **_NJK)(_variant(_run_core, "_rk4", **RK4_GLOBALS))

#: :data:`run_one_rk4` for a flow map that reads the past (RK4's continuous
#: extension has the record of the past's form, RK45's)
run_one_rk4_delays = njit(cache=CACHE, **_NJK)(
    _variant(_run_core, "_rk4_delays", _DELAYS=True, **RK4_GLOBALS))

#: :data:`run_one_spec` stepping with RK4, without and with delays
run_one_spec_rk4 = njit(**_NJI)(_variant(_run_core, "_rk4", **RK4_GLOBALS))
run_one_spec_rk4_delays = njit(**_NJI)(
    _variant(_run_core, "_rk4_delays", _DELAYS=True, **RK4_GLOBALS))

#: :data:`run_one` recording the crossings of watched functions (:mod:`._watch`):
#: compiled (and cached) when a watching system first runs
run_one_watch = njit(cache=CACHE, **_NJK)(_variant(_run_core, "_watch", _WATCH=True))
