"""The compiled path: hybrid systems whose maps numba can compile, run entirely
in machine code.

A :class:`CompiledSystem` is built from plain functions of ``(x, t, j, p)``
written with numpy on scalars and 1-D arrays (``p`` is the system's float
parameter array). It is an ordinary :class:`hybridsim.HybridSystem` too, so
``hs.simulate(system, ...)`` runs the same maps on the Python path and gives
a reference. :func:`simulate_compiled` runs one solution compiled and
:func:`simulate_many_compiled` runs a batch compiled and in parallel over the
machine's cores (threads taking rows from a shared counter); both return the
same :class:`hybridsim.HybridArc` as the Python path.

What is compiled, and what is cached
------------------------------------
The engine (Dormand-Prince 5(4) stepping with scipy RK45's step-size
controller and dense output, event location, the decision loop) is compiled
once per machine and kept in numba's on-disk cache (``__pycache__`` beside
this package; ``NUMBA_CACHE_DIR``; or, where the package's folder cannot be
written, as in a read-only site-packages, numba's user cache folder): a new
process loads it in a fraction of a second. Compiling it takes about 15 s of
CPU (the run kernel; the batch kernel, which calls it by address, about 0.5 s)
and is announced once on stderr. Flow maps that read the past
(``delays=``) run in a kernel of their own, compiled (about 20 s, announced
too) when the first such system runs, and so do runs with
``method="DOP853"`` (scipy's DOP853, for tight tolerances; about 15 s).
The user's maps reach it as numba first-class functions of a fixed
signature; they are compiled per system, when the system is first run
(about 0.1-0.3 s per map), and are not cached across processes (they are
often lambdas or closures). A system with
``specialize=True`` gets its own run kernel, its maps compiled in; it is kept
on disk too, in a module generated beside the engine's cache and named by a
digest of the maps' code, constants, closures and globals and of the engine
(see ``_cache.spec_module``): about 15 s of CPU once per machine and per
change of the maps, then loaded in a fraction of a second without compiling
the maps. The rules (:mod:`hybridsim.rules`) are compiled into the engine
from their one source; a change of them invalidates the cache.

The cache folders are code this process runs (numba's index files are
pickles), so they must be the user's own: the engine reads and keeps its
kernels only in a folder owned by the user (or root) and writable by no one
else, under folders no one else can swap it in (:mod:`._private`). A
``NUMBA_CACHE_DIR`` others can write to is refused with a warning (the kernels
then compile in memory in each process), and a specialised kernel's module
goes to the next private folder. A generated module is written under an
unpredictable name, created exclusively, and its checked text is what runs
(never a bytecode file beside it).

Ordinary systems run here too, lowered to a :class:`CompiledSystem` by
:func:`lower` (what ``backend="compiled"`` does): a
:class:`hybridsim.LinearPlant`, any system whose ``compiled_component()``
returns a :class:`Component` (maps of ``(x, u, t, j, p)``), and
interconnections of them wired by :class:`hybridsim.LinearInput` (module
:mod:`hybridsim.compiled._lower`). The papers' observers that have compiled
forms run so.

numba is an optional dependency: ``pip install 'hybridsim[fast]'``. Importing
this module does not need it; running compiled does.

Semantics are those of :func:`hybridsim.simulate` with ``method="RK45"``
or ``"DOP853"`` (same priorities, event location to 4 ulp, jumps at t_max within
:func:`hybridsim.rules.t_max_slack`, termination causes) except for what
a compiled map cannot do: raise an exception (``MAP_ERROR`` only for jump
maps returning non-finite or mis-shaped values), take an exogenous input
``u`` (inputs come from other components, through :func:`lower`), or read
``self.history`` (the past reaches a flow map through ``p`` instead:
``CompiledSystem(..., delays=)``). The Python path's stiffness warning is not
issued.
"""
from __future__ import annotations

import time

from ._from_source import FallbackWarning
from ._lower import Component, Lowerable, compiled_matvec, lower, lowerable, matvec
from ._run import simulate_compiled, simulate_many_compiled
from ._system import CompiledSystem, CompileError, _load_kernel, _notice

# the public classes under the name users import them by (pickles, descriptions)
CompiledSystem.__module__ = CompileError.__module__ = __name__
FallbackWarning.__module__ = Lowerable.__module__ = __name__

__all__ = ["CompiledSystem", "simulate_compiled", "simulate_many_compiled", "CompileError",
           "available", "compile_kernels", "Component", "lower", "lowerable", "matvec",
           "compiled_matvec", "Lowerable", "FallbackWarning"]


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


def compile_kernels(delays=False):
    """Compile the engine's kernels now (or load them from numba's disk cache).

    Parameters
    ----------
    delays : bool
        Also the run kernel of flow maps that read the past
        (``CompiledSystem(delays=)``): a kernel of its own, compiled on the
        first run of such a system otherwise.

    Returns
    -------
    float
        The seconds it took. Called by the first compiled run anyway.
    """
    from ..options import check_bool
    delays = check_bool("delays", delays)
    t = time.perf_counter()
    k = _load_kernel()
    k.compile_kernels(batch=True, notice=_notice)
    if delays:
        k.compile_kernels(batch=False, notice=_notice, delays=True)
    return time.perf_counter() - t
