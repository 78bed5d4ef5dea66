"""Stochastic systems on the compiled path: SDE flows (a ``diffusion``), single
runs and batches, the same path per seed as the Python path.

A :class:`~hybridsim.compiled.CompiledSystem` with ``diffusion=`` (or a plain
model whose ``diffusion`` the source rewrite lowers) runs in
:func:`._sde_flow.sde_run`, compiled once per system with its maps inlined.
The run's Brownian path is ``BrownianPath(noise_key(seed), 0, m, t0=t0,
block=max_step)``, the Python path's (:mod:`hybridsim._sde`), drawn by
:mod:`._draws` bit for bit: the same seed gives the same arc on both paths
to round-off, and ``arc.stats`` records the path (``noise_seed``...) as the
Python path does, so ``hs.simulate(system, x0, seed=arc.stats["noise_seed"],
...)`` replays a compiled row.

A batch (:func:`simulate_many_sde`) runs its rows in GIL-free threads, row
``i`` keyed by ``seeds[i]`` (drawn from fresh entropy when not given).
"""
from __future__ import annotations

import concurrent.futures
import math
import os

import numpy as np

from .._sde import SDE_METHODS, noise_key
from ..arc import HybridArc, _describe
from ..arc_batch import ArcBatch
from ..options import parse_run
from ..rules import CAUSES, MapError, Termination, finish, finish_batch, message
from ._system import CompiledSystem, _load_kernel

__all__ = ["simulate_sde_compiled", "simulate_many_sde"]


def _sde_kernel():
    """:mod:`._sde_flow`, its cached kernel keyed (once) by the engine's digest of
    the rules and compiled modules and by :mod:`._draws`' text (numba's own
    key sees only ``_sde_flow.py``)."""
    from . import _sde_flow
    if not getattr(_sde_flow, "_hs_keyed", False):
        import hashlib

        from . import _cache, _draws
        h = hashlib.sha256(_cache._rules_digest().encode())
        with open(_draws.__file__, "rb") as fh:
            h.update(fh.read())
        for disp in (_sde_flow.sde_run, _sde_flow._em_grid):
            cache = getattr(disp, "_cache", None)
            if hasattr(cache, "_index_key"):
                cache._index_key = _cache._keyed(cache._index_key, h.hexdigest())
        _sde_flow._hs_keyed = True
    return _sde_flow


def _dispatchers(system):
    """``(maps, flags)``: the addresses of the system's six maps and its
    diffusion (the cached kernel's ``maps``), and the sets' flags (made once)."""
    hit = system.__dict__.get("_sde_maps")
    if hit is not None and hit[0] is system.maps.get("diffusion"):
        return hit[1]
    k = _load_kernel()
    system.compile()
    import numba
    d = system._nb
    if system.specialize:           # its maps are compiled into its own kernel: by address too
        out = {role: k.handle(f, system._kinds[role])
               for role, f in system._compile_maps(k, numba).items()}
        absent = {"vec": k.handle(k.absent_vec, "vec"),
                  "scalar": k.handle(k.absent_scalar, "scalar"),
                  "false": k.handle(k.absent_false, "bool"),
                  "true": k.handle(k.absent_true, "bool")}
        d = system._flags(out, absent)
    sig = system.maps["diffusion"]
    if system.noise_dim is not None:            # (n, m): flattened, row-major
        jf = sig if hasattr(sig, "py_func") else numba.njit(error_model="numpy")(sig)

        def flat(x, t, j, p):
            return np.ascontiguousarray(jf(x, t, j, p)).ravel()
        fn = flat
    else:
        fn = sig
    try:
        hs = k.handle(k.wrap_map(fn, "vec"), "vec")
    except (numba.core.errors.NumbaError, TypeError, ValueError) as e:
        from ._system import CompileError, _summarise
        raise CompileError(f"CompiledSystem: numba could not compile the map 'diffusion': "
                           f"{_summarise(e)}. Write it as a numpy function of (x, t, j, p) "
                           f"returning an array, or run this system on the Python path",
                           "diffusion") from e
    handles = [d[r] for r in ("f", "g", "hD", "hC", "D", "C")] + [hs]
    into = _into_forms(system, handles[0], hs)
    handles += into
    flags = (d["has_C"], d["has_D"], d["has_hC"], d["has_hD"], d["C_from_guard"],
             d["D_from_guard"])
    K = _sde_kernel()
    maps = np.concatenate([k.map_addresses(handles[:7]),
                           np.array([K.jit_address(fn) for fn in into] + [K.grid_address()],
                                    np.int64)])
    out = (maps, flags, handles)
    system.__dict__["_sde_maps"] = (sig, out)
    return out


def _into_forms(system, hf, hs):
    """The flow map and the diffusion written into an argument (the SDE
    stepper's Euler–Maruyama loop): a map declared so as it is, an
    array-returning one through its compiled form (``hf``, ``hs``: their
    handles, kept with the system)."""
    import numba

    from ._system import CompileError, _summarise
    K = _sde_kernel()
    into = getattr(system, "maps_into", {})
    n, nd = system.state_dim, system.noise_dim
    out = []
    for role, h, shape in (("flow", hf, (n,)), ("diffusion", hs, (n,) if nd is None else (n, nd))):
        try:
            fn = K.into_form(into[role], shape) if role in into else K.into_form(h.addr)
        except (numba.core.errors.NumbaError, TypeError, ValueError) as e:
            raise CompileError(f"CompiledSystem: numba could not compile the map "
                               f"{'flow_map' if role == 'flow' else role!r} written into its "
                               f"out argument: {_summarise(e)}", role) from e
        out.append(fn)
    return out


def _no_watch(system, what):
    """Watched functions are recorded by the compiled kernel's watching variant
    only: with a diffusion or a jump rate they are refused by name."""
    if getattr(system, "watch", None) is not None:
        raise TypeError(f"backend='compiled': {type(system).__name__} declares watch (functions "
                        f"watched without a jump) and {what}: the compiled path records "
                        f"watched crossings on ODE flows without a jump rate only; use "
                        f"backend='python'")


def _check(system, method, step, x0):
    """The Python path's checks of an SDE flow (:class:`hybridsim._sde.SDEFlow`),
    and the diffusion's shape at x0 (a MapError naming it)."""
    name = type(system).__name__
    _no_watch(system, "a diffusion")
    if method not in SDE_METHODS:
        raise ValueError(f"method: {name} declares diffusion (an SDE flow); method must be one "
                         f"of {list(SDE_METHODS)}, got {method!r}")
    if not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0):
        raise ValueError(f"max_step: an SDE flow steps with the fixed step max_step; it must "
                         f"be a positive finite float, got {step!r}")
    nd = system.noise_dim
    if nd is not None and (isinstance(nd, bool) or not isinstance(nd, (int, np.integer))
                           or nd < 1):
        raise ValueError(f"{name}.noise_dim must be None (diagonal noise) or a positive int "
                         f"(general noise), got {nd!r}")
    n = system.state_dim
    m = n if nd is None else int(nd)
    if method == "Milstein" and nd is not None:
        raise ValueError(f"method='Milstein' takes diagonal noise (noise_dim=None); {name} has "
                         f"noise_dim={nd}: use 'EM', or 'SRA1' for additive noise")
    shape = (n,) if nd is None else (n, m)
    v = np.asarray(system.diffusion(np.array(x0, dtype=float), 0.0, 0), dtype=float)
    if v.shape != shape:
        what = "diagonal noise (noise_dim=None): shape (n,)" if nd is None else \
            f"noise_dim={m}: shape (n, noise_dim)"
        raise MapError(f"diffusion must return an array of shape {shape} ({what}), got shape "
                       f"{v.shape} (at t=0, j=0)", "diffusion", 0.0, 0)
    return m


def _pack(system, ro, method, step, flags):
    K = _sde_kernel()
    fopt = np.empty(K.F_SIZE)
    fopt[K.F_T0], fopt[K.F_T_MAX], fopt[K.F_J_MAX] = ro.t0, ro.t_max, ro.j_max
    fopt[K.F_H], fopt[K.F_MAX_NORM] = step, ro.max_norm
    fopt[K.F_ZENO_TIME], fopt[K.F_ZENO_RTOL] = ro.zeno_time, ro.zeno_rtol
    big = np.iinfo(np.int64).max
    iopt = np.zeros(K.I_SIZE, np.int64)
    iopt[K.I_J0], iopt[K.I_PRIO] = ro.j0, int(ro.prio)
    iopt[K.I_MAX_STEPS] = big if ro.max_steps == math.inf else ro.max_steps
    iopt[K.I_MAX_SAMPLES] = big if ro.max_samples == math.inf else ro.max_samples
    iopt[K.I_ZENO_JUMPS] = ro.zeno_jumps
    (iopt[K.I_HAS_C], iopt[K.I_HAS_D], iopt[K.I_HAS_HC], iopt[K.I_HAS_HD],
     iopt[K.I_C_FROM_GUARD], iopt[K.I_D_FROM_GUARD]) = flags
    iopt[K.I_METHOD] = SDE_METHODS.index(method)
    iopt[K.I_DEPTH] = 24
    iopt[K.I_DIAG] = system.noise_dim is None
    return fopt, iopt


def _prepare(system, x0, t_max, j_max, method, max_step, kw):
    if not isinstance(system, CompiledSystem) or system.maps.get("diffusion") is None:
        raise TypeError(f"the compiled SDE stepper takes a CompiledSystem with a diffusion, "
                        f"got {type(system).__name__}")
    if system.maps.get("jump_rate") is not None:
        raise ValueError(f"backend='compiled': {system!r} declares jump_rate and a diffusion; "
                         f"the compiled SDE stepper does not draw rate-driven jumps yet: use "
                         f"backend='python'")
    if system.delays:
        raise ValueError(f"{system!r} declares diffusion and reads its past (delays): SDE "
                         f"flows do not read the past yet")
    n = system.state_dim
    ro = parse_run(system, n, t_max=t_max, j_max=j_max, max_step=max_step, python=True, **kw)
    step = ro.max_step
    m = _check(system, method, step, np.zeros(n) if x0 is None else x0)
    maps, flags, _ = _dispatchers(system)
    fopt, iopt = _pack(system, ro, method, step, flags)
    return ro, step, m, maps, fopt, iopt


_DIFFUSION_TEXT = {20: "diffusion depends on the state, but method='SRA1' takes additive noise "
                       "(σ a function of t and j only); use 'EM' or 'Milstein'",
                   21: "diffusion returned non-finite values",
                   22: "diffusion returned an array of the wrong shape"}


def _arc(system, k, out, ro, seed_key, method, step):
    from ._arcs import _message
    T, J, X, code, detail, info, st = out
    stats = {"steps": int(st[0]), "nfev": 0, "njev": 0, "nlu": 0, "events": int(st[1]),
             "flows": int(st[2]), "rejected": None, "noise_seed": seed_key, "noise_run": 0,
             "noise_block": step, "noise_t0": ro.t0, "noise_depth": 24, "sde_method": method,
             "sde_step": step}
    if CAUSES[code] is Termination.MAP_ERROR and detail in _DIFFUSION_TEXT:
        t, j = float(info[0]), int(info[3])
        text = f"{_DIFFUSION_TEXT[detail]} (at t={t:.10g}, j={j})"
        cause, msg, exc = Termination.MAP_ERROR, message(Termination.MAP_ERROR, error=text), \
            MapError(text, "diffusion", t, j)
    else:
        cause, msg, exc = _message(system, k, code, detail, info, T, J, X, st, ro)
    desc = system.__dict__.get("_sde_description")
    if desc is None:
        system.__dict__["_sde_description"] = desc = _describe(system)
    arc = HybridArc._trusted(T, J, X, cause, msg, exc, system=system,
                             xdot=np.full(X.shape, np.nan), stats=stats, description=desc)
    if exc is not None:
        exc.arc = arc
    return arc


def sde_options(opts):
    """The options of :func:`hybridsim.simulate` an SDE flow takes compiled (the
    Python path's: the tolerances and ``first_step`` are not read; ``refine``
    must be 1)."""
    out = {}
    for name, v in opts.items():
        if name in ("rtol", "atol", "first_step", "seed" if v is None else ""):
            continue
        if name == "refine":
            if v != 1:
                raise ValueError("refine: SDE flows do not take refine yet")
            continue
        out[name] = v
    return out


_OPTS = ("t0", "j0", "priority", "max_norm", "zeno_jumps", "zeno_time", "zeno_rtol",
         "max_steps", "max_samples")


def simulate_sde_compiled(system, x0, t_max, j_max=math.inf, *, method="RK45",
                          max_step=math.inf, seed=None, throw=True, warn=True, **kw):
    """One run of an SDE flow, compiled: the run :func:`hybridsim.simulate`
    makes on the Python path with the same ``seed`` (an int, a Generator or
    None), to round-off.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> from hybridsim.compiled import CompiledSystem
    >>> bm = CompiledSystem(flow_map=lambda x, t, j, p: np.zeros(1),
    ...                     diffusion=lambda x, t, j, p: np.ones(1), state_dim=1)
    >>> a = simulate_sde_compiled(bm, [0.0], 1.0, max_step=0.1, seed=3, method="EM")
    >>> b = hs.simulate(bm, [0.0], 1.0, max_step=0.1, seed=3, method="EM")
    >>> bool(abs(a.x[-1, 0] - b.x[-1, 0]) < 1e-12)
    True
    """
    from ..options import check_x0
    unknown = set(kw) - set(_OPTS)
    if unknown:
        raise TypeError(f"simulate_sde_compiled() got an unexpected keyword argument "
                        f"{sorted(unknown)[0]!r}")
    k = _load_kernel()
    x = np.ascontiguousarray(check_x0(x0, system.state_dim))
    ro, step, m, maps, fopt, iopt = _prepare(system, x, t_max, j_max, method, max_step, kw)
    from ._draws import path_keys
    from ._run import _rng_for
    key = noise_key(seed)
    rng, rngp = _rng_for(k, ro.prio, key if seed is not None else None)
    out = _sde_kernel().sde_run(maps, x, system.params, fopt, iopt, path_keys(key, 0, m), rngp)
    del rng
    arc = _arc(system, k, out, ro, key, method, step)
    if arc.termination is Termination.MAP_ERROR and len(arc.t) == 1:
        raise arc.exception
    return finish(arc, throw, warn)


def _threads(rows):
    try:
        import numba
        cores = numba.config.NUMBA_NUM_THREADS
    except (ImportError, AttributeError):
        cores = os.cpu_count() or 1
    return max(1, min(cores, rows // 8 or 1))


def simulate_many_sde(system, X0, t_max, j_max=math.inf, *, method="RK45", max_step=math.inf,
                      seeds=None, throw=False, warn=True, threads=None, params=None, **kw):
    """Rows of an SDE flow, compiled, in GIL-free threads; row ``i`` is
    :func:`simulate_sde_compiled` from ``X0[i]`` with ``seed=seeds[i]``
    (fresh entropy per row when ``seeds`` is None; each arc records its key
    in ``stats["noise_seed"]``), its ``p`` the row ``params[i]`` where given
    (:func:`simulate_many_compiled`'s). Returns an :class:`hybridsim.ArcBatch`.

    Examples
    --------
    >>> import numpy as np
    >>> from hybridsim.compiled import CompiledSystem
    >>> bm = CompiledSystem(flow_map=lambda x, t, j, p: np.zeros(1),
    ...                     diffusion=lambda x, t, j, p: np.ones(1), state_dim=1)
    >>> b = simulate_many_sde(bm, np.zeros((4, 1)), 1.0, max_step=0.1, seeds=[1, 2, 3, 1],
    ...                       method="EM")
    >>> bool(b[0].x[-1, 0] == b[3].x[-1, 0]), len(b)
    (True, 4)
    """
    unknown = set(kw) - set(_OPTS)
    if unknown:
        raise TypeError(f"simulate_many_sde() got an unexpected keyword argument "
                        f"{sorted(unknown)[0]!r}")
    from ..options import check_x0s
    k = _load_kernel()
    n = system.state_dim
    X = np.ascontiguousarray(check_x0s(X0, n))
    N = len(X)
    ro, step, m, maps, fopt, iopt = _prepare(system, X[0] if N else None, t_max, j_max, method,
                                             max_step, kw)
    if seeds is None:                   # 63 bits of fresh entropy per row
        keys = (np.random.SeedSequence().generate_state(N, np.uint64) >> np.uint64(1)).tolist()
    else:
        if len(seeds) != N:
            raise ValueError(f"seeds: one per row, {N} rows, got {len(seeds)}")
        keys = [noise_key(s) for s in seeds]
    from ._draws import path_keys_many
    from ._run import _rng_for, _row, _row_params
    P = _row_params(system, params, N)
    KEYS = path_keys_many(np.array(keys, dtype=np.uint64), m)
    if ro.prio == _RANDOM_PRIO:
        raise ValueError("priority='random': a batch of SDE rows draws no coins yet; run the "
                         "rows with simulate_sde_compiled (one seed each)")
    rng, rngp = _rng_for(k, ro.prio, None)
    run = _sde_kernel().sde_run
    out = [None] * N
    if N:                               # compiled here, once, before the threads start
        out[0] = run(maps, X[0], _row(P, 0), fopt, iopt, KEYS[0], rngp)

    def part(rows):
        for i in rows:
            out[i] = run(maps, X[i], _row(P, i), fopt, iopt, KEYS[i], rngp)
    nt = threads or _threads(N)
    rest = list(range(1, N))
    if nt > 1 and rest:
        with concurrent.futures.ThreadPoolExecutor(nt) as ex:
            list(ex.map(part, [rest[i::nt] for i in range(nt)]))
    else:
        part(rest)
    del rng
    arcs = ArcBatch([_arc(system, k, o, ro, key, method, step) for o, key in zip(out, keys)], n)
    return finish_batch("simulate_many", arcs, throw, warn)


from ..rules import Priority as _P  # noqa: E402

_RANDOM_PRIO = _P.RANDOM


# ------------------------------------------------------------------ jumps at a rate
def _augmented(cs):
    """The :class:`CompiledSystem` of ``cs`` (declaring ``jump_rate``) with the
    clock of :mod:`hybridsim._random_jumps` appended (Λ, E and the key's
    halves, :data:`~hybridsim._random_jumps.CLOCK`): its maps are the Python
    path's ``_Augmented``'s, compiled (made once per system)."""
    hit = cs.__dict__.get("_rate_system")
    if hit is not None and hit[0] is cs.maps.get("jump_rate"):
        if hit[1].params is not cs.params:      # the system's params as they are now
            hit[1].params = cs.params
        return hit[1]
    import numba

    from .._random_jumps import CLOCK
    from ._draws import threshold_at
    k = _load_kernel()
    n, mp = cs.state_dim, cs.maps
    if "jump" not in mp:
        raise ValueError(f"backend='compiled': {cs!r} declares jump_rate but no jump_map")
    jit = numba.njit(error_model="numpy")
    fv = k.wrap_map(mp["flow"], "vec", lazy=True)
    gv = k.wrap_map(mp["jump"], "vec", lazy=True)
    rate = k.wrap_map(mp["jump_rate"], "scalar", lazy=True)
    m = n + CLOCK

    # (the user's maps read x[:n], a view: C-contiguous, as the Python path's). The
    # flow map is written into ``out`` (a specialised kernel's steps call it so: no
    # array made besides the user map's; elsewhere it is seen as the array it writes)
    if "flow" in cs.maps_into:              # the user's flow map written into out[:n] too
        fu = cs.maps_into["flow"]
        fu = fu if hasattr(fu, "py_func") else jit(fu)

        def flow_map(x, t, j, p, out):
            xs = x[:n]
            fu(xs, t, j, p, out[:n])
            r = rate(xs, t, j, p)
            out[n] = r if (r >= 0.0 and math.isfinite(r)) else np.nan
            for q in range(n + 1, m):
                out[q] = 0.0
    else:
        def flow_map(x, t, j, p, out):
            xs = x[:n]
            fx = fv(xs, t, j, p)
            r = rate(xs, t, j, p)
            if fx.shape[0] != n:
                for q in range(m):
                    out[q] = np.nan
                return
            for q in range(n):
                out[q] = fx[q]
            out[n] = r if (r >= 0.0 and math.isfinite(r)) else np.nan
            for q in range(n + 1, m):
                out[q] = 0.0

    def clock_jump(x, j, out):
        """The clock's part of the jump (after the state's, in ``out[:n]``)."""
        for q in range(n, m):
            out[q] = x[q]
        if x[n] >= x[n + 1]:                 # the rate's jump: a new clock
            out[n] = 0.0
            out[n + 1] = threshold_at(x[n + 2], x[n + 3], j + 1)
    clock_jump = jit(clock_jump)
    if "jump" in cs.maps_into:              # the user's jump map written into out[:n]
        gu = cs.maps_into["jump"]
        gu = gu if hasattr(gu, "py_func") else jit(gu)

        def jump_map(x, t, j, p):
            out = np.empty(m)
            gu(x[:n], t, j, p, out[:n])
            clock_jump(x, j, out)
            return out
    else:
        def jump_map(x, t, j, p):
            xn = gv(x[:n], t, j, p)
            out = np.empty(m)
            if xn.shape[0] != n:
                out[:] = np.nan
                return out
            for q in range(n):
                out[q] = xn[q]
            clock_jump(x, j, out)
            return out
    maps = {"flow_map": jit(flow_map), "jump_map": jit(jump_map)}
    if "jump_set" in mp:                     # an indicator: the union, located by bisection
        dv = k.wrap_map(mp["jump_set"], "bool", lazy=True)

        def jump_set(x, t, j, p):
            return x[n] >= x[n + 1] or dv(x[:n], t, j, p)
        maps["jump_set"] = jit(jump_set)
    elif "jump_guard" in mp:
        hv = k.wrap_map(mp["jump_guard"], "scalar", lazy=True)

        def jump_guard(x, t, j, p):
            return max(hv(x[:n], t, j, p), x[n] - x[n + 1])
        maps["jump_guard"] = jit(jump_guard)
    else:
        def clock_guard(x, t, j, p):
            return x[n] - x[n + 1]
        maps["jump_guard"] = jit(clock_guard)
    if "flow_set" in mp or "flow_guard" in mp:
        if "flow_set" in mp:
            cv = k.wrap_map(mp["flow_set"], "bool", lazy=True)
        else:
            cg = k.wrap_map(mp["flow_guard"], "scalar", lazy=True)

            def cv(x, t, j, p):                  # C = {flow_guard >= 0}, as the Python path's
                return cg(x, t, j, p) >= 0.0
            cv = jit(cv)

        def flow_set(x, t, j, p):
            return cv(x[:n], t, j, p)
        maps["flow_set"] = jit(flow_set)
        if "flow_guard" in mp:
            cg2 = k.wrap_map(mp["flow_guard"], "scalar", lazy=True)

            def flow_guard(x, t, j, p):
                return cg2(x[:n], t, j, p)
            maps["flow_guard"] = jit(flow_guard)
    if "diffusion" in mp:
        nd = cs.noise_dim
        sj = mp["diffusion"]
        sj = sj if hasattr(sj, "py_func") else jit(sj)
        if nd is None:
            def diffusion(x, t, j, p):
                out = np.zeros(m)
                out[:n] = sj(x[:n], t, j, p)
                return out
        else:
            def diffusion(x, t, j, p):
                out = np.zeros((m, nd))
                out[:n] = sj(x[:n], t, j, p)
                return out
        maps["diffusion"] = jit(diffusion)
    aug = CompiledSystem(**maps, state_dim=m, params=cs.params, noise_dim=cs.noise_dim,
                         specialize=cs.specialize, name=f"{cs!r} (with its rate's clock)")
    aug.max_step = cs.max_step
    cs.__dict__["_rate_system"] = (mp["jump_rate"], aug)
    return aug


def _rate_error(system, arc, n):
    """A run that failed where the rate is negative or NaN: the Python path's
    MapError naming ``jump_rate``."""
    if arc.termination not in (Termination.MAP_ERROR, Termination.NON_FINITE) or \
            not np.isfinite(arc.x[-1, :n]).all():    # (a state not finite: not the rate's)
        return arc
    from .._random_jumps import _named
    rate = _named(system.jump_rate, "jump_rate")
    t, j = float(arc.t[-1]), int(arc.j[-1])
    try:
        r = float(rate(arc.x[-1, :n], t, j, None))
    except (TypeError, ValueError):
        return arc
    if r >= 0 and math.isfinite(r):
        return arc
    text = (f"jump_rate returned {r} (at t={t:.10g}, j={j}): a rate must be a finite number "
            f">= 0")
    exc = MapError(text, "jump_rate", t, j)
    out = HybridArc(arc.t, arc.j, arc.x, Termination.MAP_ERROR,
                    message(Termination.MAP_ERROR, error=text), exc, system=arc.system,
                    xdot=arc.xdot, stats=arc.stats)
    exc.arc = out
    return out


def simulate_rate_compiled(system, cs, x0, t_max, j_max, opts, seed):
    """``hs.simulate(system, ..., backend="compiled")`` of a system with a
    ``jump_rate`` (``cs`` its compiled form): the Python path's run with the
    clock appended (the same key, the same thresholds, the same arc to
    round-off), on the compiled kernel (an ODE flow) or the SDE stepper."""
    from .._random_jumps import clock, run_key, strip
    from ..options import check_x0
    _no_watch(system, "a jump_rate")
    if getattr(system, "jump_law", None) is not None:
        raise ValueError(f"backend='compiled': {type(system).__name__} declares jump_law (a "
                         f"random jump map), whose draws (a numpy Generator) the compiled "
                         f"path does not make yet; use backend='python'")
    key = run_key(seed)
    opts = {k: v for k, v in opts.items() if k not in ("t_max", "j_max", "backend")}
    n = cs.state_dim
    aug = _augmented(cs)
    x = np.concatenate([check_x0(x0, n), clock(key, opts.get("j0", 0))])
    throw, warn = opts.pop("throw", True), opts.pop("warn", True)
    try:
        return _rate_run(system, cs, aug, x, t_max, j_max, opts, key, n, throw, warn)
    except MapError as e:               # at x0: raised at once, named as the Python path does
        arc = getattr(e, "arc", None)
        if arc is None:
            raise
        out = _rate_error(system, strip(arc, system, key, n, True), n)
        if out.exception is not e and out.termination is Termination.MAP_ERROR:
            raise out.exception from None
        raise


def _rate_run(system, cs, aug, x, t_max, j_max, opts, key, n, throw, warn):
    from .._random_jumps import strip
    from ._run import simulate_compiled
    if "diffusion" in cs.maps:
        arc = simulate_sde_compiled(aug, x, t_max, j_max, throw=False, warn=False,
                                    seed=key, **sde_options(opts))
    else:
        arc = simulate_compiled(aug, x, t_max, j_max, throw=False, warn=False,
                                seed=key if opts.get("priority") == "random" else None,
                                **{k: v for k, v in opts.items() if k != "seed"})
    out = _rate_error(system, strip(arc, system, key, n, True), n)
    if out.termination is Termination.MAP_ERROR and len(out.t) == 1:
        raise out.exception
    return finish(out, throw, warn)


def row_keys(seed, N):
    """The run keys (ints < 2**63, as uint64) of a batch's ``N`` rows: from
    fresh entropy (``seed`` None), ``SeedSequence(seed)`` (an int or a
    SeedSequence: row i's key the same whatever N) or a Generator's draws."""
    if isinstance(seed, np.random.Generator):
        return seed.integers(0, 2**63, size=N, dtype=np.uint64)
    if seed is not None and not isinstance(seed, np.random.SeedSequence):
        from .._random_jumps import run_key
        seed = run_key(seed)            # (its checks: a non-negative int)
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return ss.generate_state(N, np.uint64) >> np.uint64(1)


def simulate_many_rate(system, cs, X0, t_max, j_max, opts, keys=None, reduce=None,
                       params=None):
    """``hs.simulate_many(..., backend="compiled")`` of a system with a
    ``jump_rate``: row ``i`` keyed ``keys[i]`` (:func:`row_keys`; fresh
    entropy when None), recorded in its ``stats["jump_seed"]``:
    ``hs.simulate(system, x0, seed=that)`` replays it on any path; the rows
    in the compiled batch kernel. ``reduce``: ``(grid, by_j)``, the rows'
    ends and states of the system's own components on the grid
    (:class:`._run.RowEnds`), no arcs. ``params``: row ``i``'s ``p``
    (:func:`simulate_many_compiled`'s)."""
    from .._random_jumps import strip
    from ..options import check_x0s
    from ._draws import clocks_many
    from ._run import simulate_many_compiled
    _no_watch(system, "a jump_rate")
    if getattr(system, "jump_law", None) is not None or "diffusion" in cs.maps:
        raise ValueError(f"backend='compiled': {type(system).__name__} declares jump_rate with "
                         f"a jump_law or a diffusion, which a compiled batch does not run "
                         f"yet; use backend='python'")
    n = cs.state_dim
    X = check_x0s(X0, n)
    N = len(X)
    keys = row_keys(None, N) if keys is None else np.asarray(keys, dtype=np.uint64)
    if keys.shape != (N,):
        raise ValueError(f"keys: one per row, {N} rows, got shape {keys.shape}")
    j0 = opts.get("j0", 0)
    XA = np.empty((N, n + 4))
    XA[:, :n] = X
    clocks_many(keys, XA, int(j0))
    aug = _augmented(cs)
    if reduce is not None:
        grid, by_j = reduce
        out = simulate_many_compiled(aug, XA, t_max, j_max, throw=False, warn=False,
                                     reduce=(grid, by_j, n), params=params, **opts)
        out.x = out.x[:, :n]
        for i, a in out.arcs.items():
            out.arcs[i] = _rate_error(system, strip(a, system, int(keys[i]), n, True), n)
        return out
    out = simulate_many_compiled(aug, XA, t_max, j_max, throw=False, warn=False,
                                 params=params, **opts)
    return ArcBatch([_rate_error(system, strip(a, system, key, n, True), n)
                     for a, key in zip(out, keys.tolist())], n)
