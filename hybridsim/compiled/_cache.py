"""The compiled path's compilation and caches, above the kernels (imported only
when numba is installed): which kernel a run takes, compiling it (or loading
it from numba's disk cache) at its optimisation level, the rules' digest in
its cache key, and the kernels specialised on a system's maps (generated
modules named by a digest of the maps and of the engine, kept on disk).

The runners (:mod:`._system`, :mod:`._run`) reach the engine through this
module (``hybridsim.compiled._load_kernel()``): the names of :data:`__all__`.
"""
from __future__ import annotations

import contextlib
import hashlib
import inspect
import os
import warnings

import numba
import numpy as np
from numba import types
from numba.core import errors as nb_errors
from numba.extending import intrinsic

from .. import _rk, events, rules
from . import (
    _batch,
    _decide,
    _events,
    _kernel,
    _layout,
    _past,
    _steps,
    _types,
    _variants,
    _watch,
)
from ._batch import run_rows
from ._kernel import _run_core
from ._private import private_folder
from ._types import (
    _NJ,
    _SIGS,
    CANCELED,
    CAUSES,
    DETAIL_CHATTER,
    DETAIL_INSTANT,
    DETAIL_LOOP,
    J_MAX,
    MAP_FLOW_X0,
    MAP_GUARD,
    MAP_HISTORY,
    MAP_JUMP_SHAPE,
    MAP_JUMP_VALUE,
    MAP_JUMP_X0,
    ONE_RET,
    POLL_GIL,
    POLL_NONE,
    T_MAX,
    _batch_signature,
    _signature_one,
    absent_false,
    absent_scalar,
    absent_true,
    absent_vec,
    as_bool,
    as_scalar,
    as_vec,
    handle,
    map_addresses,
    rng_pointers,
)
from ._types import wrap_map as _wrap_in_memory
from ._variants import (
    run_one,
    run_one_delays,
    run_one_dop853,
    run_one_rk4,
    run_one_rk4_delays,
    run_one_spec,
    run_one_spec_delays,
    run_one_spec_dop853,
    run_one_spec_rk4,
    run_one_spec_rk4_delays,
    run_one_watch,
)

#: what the runners (:mod:`._system`, :mod:`._run`, :mod:`._lower`) read of the engine
__all__ = [
    "CANCELED", "CAUSES", "DETAIL_CHATTER", "DETAIL_INSTANT", "DETAIL_LOOP", "J_MAX",
    "MAP_FLOW_X0", "MAP_GUARD", "MAP_HISTORY", "MAP_JUMP_SHAPE", "MAP_JUMP_VALUE",
    "MAP_JUMP_X0", "POLL_GIL", "POLL_NONE", "T_MAX",
    "absent_false", "absent_scalar", "absent_true", "absent_vec", "as_bool", "as_scalar",
    "as_vec", "handle", "map_addresses", "rng_pointers", "wrap_map", "jit_address",
    "run_one", "run_one_delays", "run_one_dop853", "run_one_rk4", "run_one_rk4_delays",
    "run_one_spec", "run_one_spec_delays", "run_one_spec_dop853", "run_one_spec_rk4",
    "run_one_spec_rk4_delays", "run_one_watch", "run_rows", "COMPILE_SECONDS", "Unkeyable",
    "compile_kernels", "one_address", "run_kernel", "spec_in_cache", "spec_key", "spec_module",
    "cache_dir", "remove_stale", "kernel_opt", "KERNEL_OPT", "STALE_AGE",
]

#: the modules of compiled code, in the order they import each other: their
#: dispatchers are the engine's cached kernels, their text part of its digest
_ENGINE = (_types, _steps, _events, _decide, _past, _watch, _kernel, _variants, _batch)


def _dispatchers():
    """Every numba dispatcher of the engine's modules."""
    for mod in _ENGINE:
        for obj in list(vars(mod).values()):
            if isinstance(obj, numba.core.dispatcher.Dispatcher):
                yield obj


def _rules_digest():
    """A hash of the source the kernels are compiled from: the rules, the
    algorithms' steps of :mod:`hybridsim.events` (:data:`hybridsim.events.COMPILED`), the
    first-step rule of :mod:`hybridsim._rk`, every
    module of :data:`_ENGINE` (with the option layout). Part of each kernel's
    cache key: numba's own key sees only the file of the function it caches,
    not the helpers, rules and constants of other files compiled into it."""
    h = hashlib.sha256(inspect.getsource(rules).encode())
    h.update(inspect.getsource(events).encode())
    h.update(inspect.getsource(_rk).encode())
    for mod in (*_ENGINE, _layout):
        with open(mod.__file__, "rb") as fh:
            h.update(fh.read())
    return h.hexdigest()


def _key_with_rules():
    """Add the rules' digest to the cache key of every cached dispatcher of the
    engine, and LLVM's settings (:func:`_llvm_settings`) to the run kernels'."""
    digest = _rules_digest()
    kernels = {id(d) for d in _KERNELS}
    for obj in _dispatchers():
        cache = getattr(obj, "_cache", None)
        if hasattr(cache, "_index_key") and not getattr(cache, "_hs_keyed", False):
            orig = cache._index_key
            cache._index_key = _keyed(orig, digest, id(obj) in kernels)
            cache._hs_keyed = True


def _keyed(orig, digest, llvm=False):
    """A cache index key with the rules' digest appended (``llvm``: and
    :func:`_llvm_settings`, read when the key is made)."""
    if llvm:
        return lambda sig, codegen: orig(sig, codegen) + (digest, _llvm_settings())
    return lambda sig, codegen: orig(sig, codegen) + (digest,)


def _llvm_settings():
    """LLVM's settings a run kernel is compiled with (:func:`_compile_or_rebuild`):
    its optimisation level (:data:`KERNEL_OPT`, or numba's where lower) and
    numba's vectorisation switches. The same inside :func:`kernel_opt` and out,
    so a kernel compiled under other settings (``NUMBA_OPT=0``) is never
    loaded as this one."""
    cfg = numba.core.config
    return (min(int(cfg.OPT), KERNEL_OPT), bool(cfg.LOOP_VECTORIZE),
            bool(cfg.SLP_VECTORIZE))


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
    for obj in _dispatchers():
        cache = getattr(obj, "_cache", None)
        if hasattr(cache, "save_overload") and not getattr(cache, "_hs_skip", False):
            save, load = cache.save_overload, cache.load_overload
            cache.save_overload = _unless_specialised(save)
            cache.load_overload = _unless_specialised(load)
            cache._hs_skip = True


#: the kernels compiled at the engine's LLVM settings (:func:`_compile_or_rebuild`)
_KERNELS = (run_one, run_one_delays, run_one_dop853, run_one_rk4, run_one_rk4_delays,
            run_one_watch, run_rows)

try:                      # numba's private cache API: without it, the key is numba's own
    _key_with_rules()
    _skip_specialised()
except Exception:  # noqa: BLE001 - a numba version without these internals
    pass


_READY = set()
#: whether the kernels are kept in numba's disk cache (a generated module's too)
CACHE = _types.CACHE


def cache_dir():
    """Where numba keeps this module's compiled kernels (None: not cached)."""
    try:
        return run_one._cache._cache_path
    except AttributeError:
        return None


def jit_address(disp):
    """The address of ``disp``'s code compiled for :data:`ONE_SIG`'s arguments
    (the ``one`` argument of :func:`run_rows`; ``disp`` must outlive its use)."""
    cres = disp.overloads[_signature_one()]
    if cres.signature.return_type != ONE_RET:
        raise TypeError(f"a run kernel must return {ONE_RET}, got "
                        f"{cres.signature.return_type}")
    return cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)


# ------------------------------------------------------------------ specialised kernels
# numba's ``cache=True`` cannot keep a kernel that closes over dispatchers made
# at run time. A specialised kernel is therefore a generated module file, one
# per system and engine (its name is a digest of the maps' code, constants,
# closures and globals, and of the engine's source), whose ``one`` reads the
# maps as module globals set before it compiles: numba caches it like any
# function of a file, and a new process loads it without compiling the maps.
_SPEC_HEAD = """\"\"\"hybridsim.compiled: a run kernel specialised on one system's maps.

Generated by hybridsim.compiled._cache.spec_module (key {key}); safe to delete.
\"\"\"
import numba

from hybridsim.compiled import _cache
from hybridsim.compiled import _kernel as _k

# the run core's globals: the engine's helpers and constants
globals().update((k, v) for k, v in vars(_k).items() if not k.startswith("__"))

f = g = hD = hC = D = C = fi = None   # the system's compiled maps, set before one compiles
_f, _g, _hD, _hC, _D, _C = (_cache.map_value(globals(), r)
                            for r in ("f", "g", "hD", "hC", "D", "C"))


"""

#: the line of the run core that takes its maps, and its specialised kernel's
_MAPS_LINE = "    f, g, hD, hC, D, C = maps_of(maps)\n"
_SPEC_MAPS_LINE = "    f, g, hD, hC, D, C = _f(), _g(), _hD(), _hC(), _D(), _C()\n"
#: the run core's line that takes the flow map written into an array (``_INTO``)
_INTO_LINE = "    fi = f\n"


def _spec_source(key, delays=False, method="RK45", into=False):
    """A specialised kernel's module: the run core itself (its source, the maps
    read from the module's globals), so that numba optimizes and generates its
    code once (a wrapper calling :data:`run_one_spec` took about 2.4 s more);
    with the code for the past where ``delays`` (see :data:`run_one_delays`),
    DOP853's or RK4's steps where ``method`` is ``"DOP853"`` or ``"RK4"`` (``key``
    then names them too, :func:`spec_key`); ``into``: the steps call the flow map
    written into an array, the module's ``fi`` (``_kernel._INTO``; not with
    ``delays``)."""
    import inspect
    core = inspect.getsource(_run_core)
    head = "def _run_core(maps, "
    if not core.startswith(head) or core.count(_MAPS_LINE) != 1 or \
            core.count(_INTO_LINE) != 1:
        raise RuntimeError("hybridsim.compiled: the run core's source is not as expected")
    core = "def one(maps, " + core[len(head):].replace(_MAPS_LINE, _SPEC_MAPS_LINE)
    head = _SPEC_HEAD.format(key=key)
    if into and not delays:
        head += ('_fi = _cache.map_value(globals(), "fi")\n'
                 '_INTO = True       # the flow map written into the run\'s rows\n\n\n')
        core = core.replace(_INTO_LINE, "    fi = _fi()\n")
    if delays:
        head += "_DELAYS = True     # the flow map reads the past\n\n\n"
    if method == "DOP853":
        head += "globals().update(_k.DOP853_GLOBALS)     # DOP853's steps\n\n\n"
    elif method == "RK4":
        head += "globals().update(_k.RK4_GLOBALS)     # RK4's fixed steps\n\n\n"
    return (head + core
            + '\n\none = numba.njit(cache=_cache.CACHE, error_model="numpy")(one)\n')


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
    if v is None or v is Ellipsis or isinstance(v, (bool, int, float, complex, str, bytes,
                                                    np.generic)):
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
        seen.add(("module", v.__module__))
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
    """The engine's own key: the kernels' source (:func:`_rules_digest`), this
    file's (which writes the generated modules), numba's and Python's versions."""
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
    its flow map reads the past; ``method``: "RK45", "DOP853" or "RK4". Raises
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
    """Where generated kernels may go, the first private one
    (:func:`hybridsim.compiled._private.private_folder`): beside numba's
    cache of this module, then the user's cache directory."""
    out = []
    d = cache_dir()
    if d:
        out.append(os.path.join(d, "specialized"))
    from numba.misc.appdirs import AppDirs
    out.append(os.path.join(AppDirs(appname="hybridsim", appauthor=False).user_cache_dir,
                            "specialized"))
    return out


def spec_module(key, delays=False, method="RK45", into=False):
    """The generated module of ``key`` (written once; None where no folder is
    private and writable: the caller then compiles in memory); ``delays``,
    ``method`` and ``into`` as :func:`_spec_source`'s, the ones ``key`` was made with."""
    return _generated_module(f"hybridsim_spec_{key}", _spec_source(key, delays, method, into))


#: the text of the module holding the engine's wrapper of one map
#: (:func:`wrapper_module`); ``{call}``: the map's value as its kind's type
_WRAP_SRC = ('"""hybridsim: the engine\'s wrapper of one map, {kind} (generated; named by '
             'the map\'s digest)."""\n\n\ndef w(x, t, j, p):\n    return {call}\n')
_WRAP_CALL = {"vec": "_hs_as_vec(_hs_fn(x, t, j, p))",
              "scalar": "_hs_as_scalar(_hs_fn(x, t, j, p))",
              "bool": "_hs_as_bool(_hs_fn(x, t, j, p))",
              "guard_set": "_hs_as_scalar(_hs_fn(x, t, j, p)) >= 0.0"}


def wrapper_module(fn, kind):
    """The generated module whose ``w(x, t, j, p)`` is the engine's wrapper of
    the map ``fn`` for ``kind`` (:func:`wrap_map`),
    named by the digest of ``fn`` (its code and every value it reads, as
    :func:`spec_key` keys a specialised kernel) and of the engine, so numba's
    disk cache keeps the compiled wrapper, the map's code inlined in it: a new
    process loads it instead of compiling the map (0.5 s and 1-2 MB a map).
    None where ``fn`` reads a value that cannot be keyed, calls a function of
    a module that is not a file's (numba's cache of the wrapper imports it),
    or no folder is private and writable (the caller compiles in memory)."""
    if not _ENGINE_DIGEST:
        _ENGINE_DIGEST.append(_engine_digest())

    def bind():
        f = fn if isinstance(fn, numba.core.dispatcher.Dispatcher) else numba.njit(**_NJ)(fn)
        return {"_hs_fn": f, "_hs_as_vec": as_vec, "_hs_as_scalar": as_scalar,
                "_hs_as_bool": as_bool}
    return keyed_module("wrap", _WRAP_SRC.format(kind=kind, call=_WRAP_CALL[kind]),
                        {"_hs_fn": fn}, bind, salt=_ENGINE_DIGEST[0], importable=True)


def keyed_module(kind, src, keyed, bind, salt="", importable=False):
    """The generated module ``hybridsim_<kind>_<digest>`` of the text ``src``
    run with the globals ``bind()`` (once per process), named by the digest of
    ``salt``, ``src`` and the values ``keyed`` (each function's code and every
    value it reads: :func:`_digest_value`), so numba's disk cache keeps what its
    functions compile to. None where a value cannot be keyed, where
    ``importable`` and a function it reads is of a module that is no file's
    (numba's cache imports it when it loads), or where no folder is private and
    writable (the caller then runs ``src`` in memory)."""
    import sys
    h = hashlib.sha256(salt.encode())
    h.update(src.encode())
    seen = set()
    try:
        for key in sorted(keyed):
            h.update(f"\0{key}=".encode())
            _digest_value(keyed[key], h, seen)
    except Unkeyable:
        return None
    if importable:
        for m in (e[1] for e in seen if isinstance(e, tuple)):
            if not os.path.isfile(getattr(sys.modules.get(m), "__file__", None) or ""):
                return None
    mod = _generated_module(f"hybridsim_{kind}_{h.hexdigest()[:32]}", src, execute=False)
    if mod is not None and "__hs_ran__" not in mod.__dict__:
        mod.__dict__.update(bind())
        try:
            exec(compile(mod.__hs_source__, mod.__file__, "exec"), mod.__dict__)
        except BaseException:
            sys.modules.pop(mod.__name__, None)
            raise
        mod.__hs_ran__ = True
    return mod


def wrap_map(fn, kind, lazy=False):
    """The engine's wrapper of the map ``fn`` for ``kind`` (see
    :func:`hybridsim.compiled._types.wrap_map`): the cached one of
    :func:`wrapper_module` where the map's digest can be taken (and not
    ``lazy``), else made in memory."""
    mod = None if lazy else wrapper_module(fn, kind)
    if mod is None:
        return _wrap_in_memory(fn, kind, lazy)
    if not isinstance(mod.w, numba.core.dispatcher.Dispatcher):
        mod.w = numba.njit(_SIGS[kind], cache=True, **_NJ)(mod.w)
    return mod.w


def _generated_module(name, src, execute=True):
    """The module ``name`` of the text ``src``, from its file in the first private
    folder of :func:`_spec_dirs` (written once, exclusively; its text read back
    and compared before it is run), or None. ``execute=False``: the module is
    made with its file and text (``__hs_source__``) but not run, so the caller
    binds its globals first."""
    import sys
    import tempfile
    import types as pytypes
    if name in sys.modules:
        return sys.modules[name]
    for d in _spec_dirs():
        path = os.path.join(d, name + ".py")
        # code is read from the folder and from numba's cache beside it: both
        # must be the user's own (no one else can plant or swap a file there)
        if private_folder(d) or private_folder(os.path.join(d, "__pycache__")):
            continue
        try:
            if not os.path.exists(path):
                # an unpredictable name, created exclusively (O_EXCL, no link
                # followed), then moved in place atomically: processes may race
                fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=d)
                try:
                    with os.fdopen(fd, "w") as fh:
                        fh.write(src)
                    os.replace(tmp, path)
                except BaseException:
                    with contextlib.suppress(OSError):
                        os.remove(tmp)
                    raise
                remove_stale(d)             # (a new module: the engine may have changed)
            with open(path) as fh:
                if fh.read() != src:
                    continue
        except OSError:
            continue
        # the checked text itself is run (never a bytecode file the import
        # system would pick beside it); numba caches ``one`` by this path
        mod = pytypes.ModuleType(name)
        mod.__file__ = path
        mod.__hs_source__ = src
        sys.modules[name] = mod
        if execute:
            try:
                exec(compile(src, path, "exec"), mod.__dict__)
            except BaseException:
                sys.modules.pop(name, None)
                raise
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
    vanish meanwhile (another process cleaning) are passed over. A map's
    wrapper, a lowered system's maps and a plain model's rewritten maps
    (``hybridsim_wrap_*``, ``hybridsim_lowered_*``, ``hybridsim_src_*``) are
    named by their maps' digest, which no text tells apart: they are removed by
    age alone (written again when next used).

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
    for path in [p for pat in ("spec", "wrap", "lowered", "src")
                 for p in glob.glob(os.path.join(d, f"hybridsim_{pat}_*.py"))]:
        name = os.path.basename(path)[:-3]
        key = name.split("_", 2)[2]
        try:
            if now - os.path.getmtime(path) < age:
                continue
            with open(path) as fh:      # a wrapper's key is its maps': only its age tells
                if name.startswith("hybridsim_spec_") and fh.read() in (
                        _spec_source(key), _spec_source(key, True),
                                 _spec_source(key, method="DOP853"),
                                 _spec_source(key, method="RK4"),
                                 _spec_source(key, True, "RK4")):
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


def _tag(delays, method, watch=False):
    if watch:
        if delays or method != "RK45":
            raise ValueError("the compiled path records watched functions with RK45 and "
                             "without delays only")
        return "one_watch"
    if method == "DOP853":
        if delays:
            raise ValueError("the compiled path steps a flow map with delays with RK45 or "
                             "RK4 only")
        return "one_dop853"
    if method == "RK4":
        return "one_rk4_delays" if delays else "one_rk4"
    return "one_delays" if delays else "one"


def run_kernel(delays=False, method="RK45", watch=False):
    """The cached run kernel of systems whose maps are passed by address:
    :data:`run_one`, :data:`run_one_delays` for a flow map that reads the
    past, :data:`run_one_dop853` for ``method="DOP853"``, :data:`run_one_rk4`
    (:data:`run_one_rk4_delays`) for ``method="RK4"``, :data:`run_one_watch`
    for a system that watches functions."""
    return {"one": run_one, "one_delays": run_one_delays, "one_dop853": run_one_dop853,
            "one_rk4": run_one_rk4, "one_rk4_delays": run_one_rk4_delays,
            "one_watch": run_one_watch}[_tag(delays, method, watch)]


def compile_kernels(batch=True, notice=None, one=True, delays=False, method="RK45",
                    watch=False):
    """Compile (or load from numba's on-disk cache) the kernels for the
    first-class map signatures: the run kernel (:func:`run_kernel` of
    ``delays`` and ``method``; unless not ``one``: a specialised system's
    batch needs only ``run_rows``), and ``run_rows`` when ``batch``.

    ``notice(cache_dir, seconds)`` is called once per run kernel and process
    before it is compiled (not in the disk cache; ``seconds``: about how
    long, the batch kernel's included where it is compiled with it). The
    batch kernel alone (about a second) is compiled without one."""
    tag = _tag(delays, method, watch)
    want_one = one and tag not in _READY
    want_batch = batch and "batch" not in _READY
    if not (want_one or want_batch):
        return          # every call of simulate_compiled asks: answer cheaply
    sig = _signature_one()
    run = run_kernel(delays, method, watch)
    if notice is not None and want_one and ("noticed", tag) not in _READY \
            and not _in_cache(run, sig):
        _READY.add(("noticed", tag))
        seconds = COMPILE_SECONDS[{"one": 0, "one_delays": 3, "one_dop853": 4,
                                   "one_watch": 5, "one_rk4": 6, "one_rk4_delays": 7}[tag]]
        if want_batch and not _in_cache(run_rows, _batch_signature(sig)):
            seconds += COMPILE_SECONDS[1]
        notice(cache_dir(), seconds,
               what={"one": "the engine's kernels",
                     "one_delays": "the engine's kernels for flow maps with delays",
                     "one_dop853": "the engine's DOP853 kernel",
                     "one_rk4": "the engine's RK4 kernel",
                     "one_rk4_delays": "the engine's RK4 kernel for flow maps with delays",
                     "one_watch": "the engine's kernel for watched functions"}[tag])
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
#: run_one_delays, run_one_dop853, run_one_watch, run_one_rk4 and
#: run_one_rk4_delays with an empty cache (measured on the project's machine,
#: issue 27; the notice quotes them)
COMPILE_SECONDS = (15, 1, 15, 20, 15, 20, 15, 20)
#: the run kernels' code addresses (:func:`jit_address`), once compiled
_ONE_ADDR = {}


def one_address(delays=False, method="RK45", watch=False):
    """:func:`run_kernel`'s code address (the ``one`` of :func:`run_rows`)."""
    compile_kernels(batch=False, delays=delays, method=method, watch=watch)
    return _ONE_ADDR[_tag(delays, method, watch)]


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
    this process. A Ctrl-C during the compile ends it with KeyboardInterrupt,
    also where it lands in a callback of llvmlite that discards it
    (:class:`hybridsim._interrupt.SigintLatch`: raised once the compile has
    returned, its kernel whole)."""
    from .._interrupt import SigintLatch
    with SigintLatch() as latch, kernel_opt():
        try:
            disp.compile(sig)
        except Exception:  # noqa: BLE001 - an unreadable cache index
            from numba.core.caching import NullCache
            for obj in _dispatchers():
                if obj._cache is not None:
                    obj._cache = NullCache()
            disp.compile(sig)
    disp.disable_compile()
    latch.check()
