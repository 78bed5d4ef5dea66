"""The compiled path's kernels: what is cached where, the specialised kernel's
disk cache and key, and the threaded batch (issue 27).

Fast tests check the specialised kernel's key (no compiling) and where an
installed, read-only copy keeps its cache; slow ones compile in fresh
processes with an empty numba cache.
"""
import enum
import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest

numba = pytest.importorskip("numba", reason="the compiled path needs numba "
                                            "(pip install 'hybridsim[fast]')")

from hybridsim.compiled import _cache as k  # noqa: E402

ROLES = ("flow", "jump", "jump_guard", "flow_guard", "jump_set", "flow_set")
KINDS = ("vec", "vec", "scalar", "scalar", "bool", "bool")


def _entries(*fns):
    fns = fns + (None,) * (6 - len(fns))
    return tuple(zip(ROLES, KINDS, fns))


def _flow_with(c):
    def f(x, t, j, p):
        return np.array([x[1], -c])
    return f


SCALE = np.array([1.0, 2.0])


def _flow_scaled(x, t, j, p):
    return SCALE * x


# ------------------------------------------------------------------ the specialised kernel's key
def test_spec_key_same_maps_same_key():
    assert k.spec_key(_entries(_flow_with(9.81))) == k.spec_key(_entries(_flow_with(9.81)))


def test_spec_key_changes_with_a_closure_constant_a_global_array_or_a_role():
    base = k.spec_key(_entries(_flow_with(9.81)))
    assert k.spec_key(_entries(_flow_with(9.8))) != base          # closure cell
    assert k.spec_key(_entries(_flow_with(9.81), _flow_with(1.0))) != base   # another map
    scaled = k.spec_key(_entries(_flow_scaled))
    SCALE[1] = 3.0                                                 # a global array read
    try:
        assert k.spec_key(_entries(_flow_scaled)) != scaled
    finally:
        SCALE[1] = 2.0
    assert k.spec_key(_entries(_flow_scaled)) == scaled


def test_spec_key_follows_jitted_helpers():
    """Maps calling numba-jitted helpers (as lowered systems do) are keyed on
    the helpers' code and constants too."""
    def helper_for(c):
        return numba.njit(lambda v: v * c)

    def flow_for(h):
        def f(x, t, j, p):
            return h(x)
        return f
    assert k.spec_key(_entries(flow_for(helper_for(2.0)))) != \
        k.spec_key(_entries(flow_for(helper_for(3.0))))


def test_spec_key_refuses_an_object_it_cannot_key():
    class Opaque:
        pass
    obj = Opaque()

    def f(x, t, j, p):
        return obj.v * x
    with pytest.raises(k.Unkeyable, match="Opaque"):
        k.spec_key(_entries(f))


def test_generated_module_is_written_once_and_reused(tmp_path, monkeypatch):
    """The first folder that can hold it: one that cannot (here a file is in
    the way) is passed over."""
    (tmp_path / "blocked").write_text("")
    monkeypatch.setattr(k, "_spec_dirs",
                        lambda: [str(tmp_path / "blocked" / "sub"), str(tmp_path / "rw")])
    key = "0" * 32
    try:
        mod = k.spec_module(key)
        assert mod is not None and os.path.dirname(mod.__file__) == str(tmp_path / "rw")
        assert k.spec_module(key) is mod
        assert hasattr(mod, "one") and mod.f is None
        assert len(list((tmp_path / "rw").glob("*.py"))) == 1
    finally:
        sys.modules.pop("hybridsim_spec_" + key, None)


def test_modules_of_another_engine_are_removed_once_a_week_old(tmp_path):
    """Writing a new generated module removes, in its folder, the modules this
    engine would not write (another engine's core) once older than a week,
    with their numba cache and bytecode; this engine's modules, and another
    engine's younger than a week (a checkout switched back soon), stay."""
    import time
    d = tmp_path / "specialized"
    (d / "__pycache__").mkdir(parents=True)
    old = time.time() - k.STALE_AGE - 60

    def module(key, text, mtime):
        path = d / f"hybridsim_spec_{key}.py"
        path.write_text(text)
        for ext in (".one-16.py311.nbi", ".one-16.py311.1.nbc", ".cpython-311.pyc"):
            (d / "__pycache__" / f"hybridsim_spec_{key}{ext}").write_text("x")
        os.utime(path, (mtime, mtime))
    stale, young, ours = "a" * 32, "b" * 32, "c" * 32
    module(stale, k._spec_source(stale).replace("_store(", "_push("), old)
    module(young, k._spec_source(young) + "\n# another engine\n", time.time())
    module(ours, k._spec_source(ours), old)
    (d / "unrelated.py").write_text("")
    assert k.remove_stale(str(d)) == [stale]
    left = sorted(p.name for p in d.rglob("*") if p.is_file())
    assert not [n for n in left if stale in n]
    assert sum(young in n for n in left) == 4 and sum(ours in n for n in left) == 4
    assert "unrelated.py" in left
    assert k.remove_stale(str(d)) == []                  # nothing more to remove
    assert k.remove_stale(str(d), age=0.0) == [young]    # age=0: every other engine's
    # a wrapper's and a lowered system's module: by age alone
    for kind, key, mtime in (("wrap", "d" * 32, old), ("lowered", "e" * 32, old),
                             ("wrap", "f" * 32, time.time())):
        path = d / f"hybridsim_{kind}_{key}.py"
        path.write_text('"""generated"""\n')
        os.utime(path, (mtime, mtime))
    assert sorted(k.remove_stale(str(d))) == ["d" * 32, "e" * 32]
    assert (d / f"hybridsim_wrap_{'f' * 32}.py").exists()


def test_writing_a_new_module_cleans_its_folder(tmp_path, monkeypatch):
    """spec_module calls the cleaning when it writes a module (not when it
    reuses one)."""
    import time
    d = tmp_path / "rw"
    d.mkdir()
    stale = "d" * 32
    path = d / f"hybridsim_spec_{stale}.py"
    path.write_text("an older engine's module")
    old = time.time() - k.STALE_AGE - 60
    os.utime(path, (old, old))
    monkeypatch.setattr(k, "_spec_dirs", lambda: [str(d)])
    key = "1" * 32
    try:
        assert k.spec_module(key) is not None
        assert not path.exists() and (d / f"hybridsim_spec_{key}.py").exists()
    finally:
        sys.modules.pop("hybridsim_spec_" + key, None)


def test_a_flow_map_with_delays_has_its_own_key_and_module_text():
    """The past's code is in the specialised kernel only where the flow map
    reads it: another key, a module that says so, and the cleaning keeps
    this engine's modules of both kinds."""
    base = _entries(_flow_with(9.81))
    assert k.spec_key(base, True) != k.spec_key(base)
    assert k.spec_key(base, False) == k.spec_key(base)
    key = "e" * 32
    plain, past = k._spec_source(key), k._spec_source(key, True)
    assert "_DELAYS = True" in past and "_DELAYS = True" not in plain
    assert past.replace("_DELAYS = True     # the flow map reads the past\n\n\n", "") == plain


def test_the_run_core_reads_the_past_only_in_its_kernel_with_delays():
    """run_one and run_one_delays are one source; the constant ``_DELAYS``
    they are compiled with decides whether the past's code is there (numba
    prunes the branches on it)."""
    assert k.run_kernel(False) is k.run_one and k.run_kernel(True) is k.run_one_delays
    assert k.run_one.py_func.__code__ is k.run_one_delays.py_func.__code__
    assert k.run_one.py_func.__globals__["_DELAYS"] is False
    assert k.run_one_delays.py_func.__globals__["_DELAYS"] is True
    assert k.run_one_spec_delays.py_func.__globals__["_DELAYS"] is True
    assert k.run_one_delays.py_func.__qualname__ == "_run_core_delays"   # cached apart


def test_dop853_has_its_own_kernel_key_and_module_text():
    """DOP853's run core is the same source with ``_DOP`` set (numba prunes
    RK45's branches): its own cached kernel, its own key and module text for
    a specialised system, kept by the cleaning; never with delays."""
    assert k.run_kernel(method="DOP853") is k.run_one_dop853
    assert k.run_one_dop853.py_func.__code__ is k.run_one.py_func.__code__
    assert k.run_one.py_func.__globals__["_DOP"] is False
    assert k.run_one_dop853.py_func.__globals__["_DOP"] is True
    assert k.run_one_spec_dop853.py_func.__globals__["_DOP"] is True
    assert k.run_one_dop853.py_func.__qualname__ == "_run_core_dop853"     # cached apart
    base = _entries(_flow_with(9.81))
    assert k.spec_key(base, method="DOP853") not in (k.spec_key(base), k.spec_key(base, True))
    key = "d" * 32
    dop = k._spec_source(key, method="DOP853")
    assert "DOP853_GLOBALS" in dop and "DOP853_GLOBALS" not in k._spec_source(key)
    with pytest.raises(ValueError, match="delays with RK45 or RK4 only"):
        k.run_kernel(True, "DOP853")


def test_rk4_has_its_own_kernels_from_the_same_source():
    """RK4's run cores are the same source with ``_RK4`` set, cached apart,
    without and with delays."""
    assert k.run_kernel(method="RK4") is k.run_one_rk4
    assert k.run_kernel(True, "RK4") is k.run_one_rk4_delays
    for v in (k.run_one_rk4, k.run_one_rk4_delays):
        assert v.py_func.__code__ is k.run_one.py_func.__code__
        assert v.py_func.__globals__["_RK4"] is True
    assert k.run_one.py_func.__globals__["_RK4"] is False
    assert k.run_one_rk4.py_func.__qualname__ == "_run_core_rk4"


def test_compile_kernels_names_a_bad_delays_argument():
    from hybridsim.compiled import compile_kernels
    for bad in ("yes", 1, None):
        with pytest.raises(TypeError, match="delays must be True or False"):
            compile_kernels(delays=bad)


def test_the_kernels_compile_at_their_own_optimisation_level_and_restore_numbas():
    """The engine's kernels compile at ``KERNEL_OPT`` (LLVM level 1: faster to
    compile, as fast to run, the same bits); numba's level is restored
    afterwards, also after a failed compile, and a lower level the user set
    (``NUMBA_OPT=0``) is kept."""
    cfg = numba.core.config
    before = cfg.OPT
    seen = []

    class Fake:                     # a dispatcher: what level does it compile at?
        def compile(self, sig):
            seen.append(int(cfg.OPT))

        def disable_compile(self):
            seen.append("no other signature")
    k._compile_or_rebuild(Fake(), None)
    assert seen == [min(int(before), k.KERNEL_OPT), "no other signature"]
    assert k.KERNEL_OPT == 1 and cfg.OPT is before
    with pytest.raises(RuntimeError, match="failed"):
        with k.kernel_opt():
            raise RuntimeError("a failed compile")
    assert cfg.OPT is before
    cfg.OPT = cfg._OptLevel(0)
    try:
        with k.kernel_opt():
            assert int(cfg.OPT) == 0
    finally:
        cfg.OPT = before


def test_every_run_kernel_is_keyed_on_the_engines_source():
    """Each cached run kernel (the run core's variants, :mod:`._variants`, whose
    function lives in :mod:`._kernel`) and the batch kernel is one of the
    engine's dispatchers: its cache key carries the digest of every engine
    file, and the digest reads the file that defines the kernels."""
    from hybridsim.compiled import _kernel, _variants
    mine = {id(d) for d in k._dispatchers()}
    kernels = [k.run_kernel(), k.run_kernel(delays=True), k.run_kernel(method="DOP853"),
               k.run_kernel(watch=True), k.run_rows]
    for disp in kernels:
        assert id(disp) in mine, disp
        if disp._cache.__class__.__name__ != "NullCache":
            assert disp._cache._hs_keyed
    assert all(getattr(_variants, n) is d for n, d in
               zip(("run_one", "run_one_delays", "run_one_dop853", "run_one_watch"), kernels))
    assert {_kernel, _variants} <= set(k._ENGINE)


def test_a_run_kernel_compiled_at_other_llvm_settings_has_another_key():
    """The run kernels' cache key names LLVM's settings they compile at: a
    kernel compiled under ``NUMBA_OPT=0`` or other vectorisation switches is
    never loaded as the engine's level-1 kernel; the key is the same inside
    :func:`kernel_opt` and out (``_in_cache`` asks outside it)."""
    cfg = numba.core.config
    disp = k.run_kernel()
    if disp._cache.__class__.__name__ == "NullCache":
        pytest.skip("the kernels are not cached on disk here")
    sig = k._signature_one()

    def key():
        return disp._cache._index_key(sig, disp.targetctx.codegen())
    before, loop = cfg.OPT, cfg.LOOP_VECTORIZE
    base = key()
    with k.kernel_opt():
        assert key() == base
    try:
        cfg.OPT = cfg._OptLevel(0)
        assert key() != base
        cfg.OPT = before
        cfg.LOOP_VECTORIZE = not loop
        assert key() != base
    finally:
        cfg.OPT, cfg.LOOP_VECTORIZE = before, loop
    assert key() == base
    # a helper's key does not change (a specialised kernel at numba's level links it)
    hkey = k._steps._store._cache._index_key
    h = hkey(sig, disp.targetctx.codegen())
    cfg.OPT = cfg._OptLevel(0)
    try:
        assert hkey(sig, disp.targetctx.codegen()) == h
    finally:
        cfg.OPT = before


@pytest.mark.slow
def test_systems_with_and_without_delays_take_their_own_kernel():
    from hybridsim.compiled import CompiledSystem, simulate_compiled
    plain = CompiledSystem(flow_map=lambda x, t, j, p: -x, state_dim=1)
    lag = CompiledSystem(flow_map=lambda x, t, j, p: -p[0:1], state_dim=1, delays=(1.0,))
    a = simulate_compiled(plain, [1.0], t_max=1.0)
    b = simulate_compiled(lag, [1.0], t_max=2.0, rtol=1e-10, atol=1e-12)
    assert plain._nb["one"] is k.run_one and lag._nb["one"] is k.run_one_delays
    assert a.x[-1, 0] == pytest.approx(np.exp(-1.0), rel=1e-5)
    # the method of steps: x = 1 - t on [0, 1], then 1 - t + (t - 1)^2 / 2: x(2) = -1/2
    assert b.x[-1, 0] == pytest.approx(-0.5, abs=1e-9)


# ------------------------------------------------------------------ an installed copy
def test_read_only_installed_copy_caches_in_the_user_cache_dir(tmp_path):
    """A copy of the package in a folder it cannot write (as site-packages may
    be) keeps numba's cache, and the specialised kernels, in the user's cache
    folder: the same policy as the checkout, one more compile per machine.
    (Where the test runs as a user who writes anywhere, root, the folder's
    refusal is simulated in the child: numba's in-tree locator fails there.)"""
    import hybridsim
    site = tmp_path / "site"
    src = os.path.dirname(hybridsim.__file__)
    shutil.copytree(src, site / "hybridsim",
                    ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    home = tmp_path / "home"
    env = {key: v for key, v in os.environ.items() if key != "NUMBA_CACHE_DIR"}
    env.update(HOME=str(home), XDG_CACHE_HOME=str(home / ".cache"), PYTHONPATH=str(site))
    code = textwrap.dedent(f"""
        from numba.core import caching
        site = {str(site)!r}
        ensure = caching.InTreeCacheLocator.ensure_cache_path

        def refuse(self):          # the read-only folder, as a non-root user sees it
            if self._cache_path.startswith(site):
                raise PermissionError(self._cache_path)
            return ensure(self)
        caching.InTreeCacheLocator.ensure_cache_path = refuse
        import hybridsim
        from hybridsim.compiled import _cache as k
        print(hybridsim.__file__)
        print(k.cache_dir())
        print(k._spec_dirs()[0])
    """)
    out = subprocess.run([sys.executable, "-W", "ignore", "-c", code], capture_output=True,
                         text=True, timeout=300, env=env, cwd=str(tmp_path))
    assert out.returncode == 0, out.stderr
    where, cache, spec = out.stdout.split()[-3:]
    assert where.startswith(str(site))
    assert cache.startswith(str(home / ".cache")), cache
    assert spec.startswith(cache)
    assert not any(p.name == "__pycache__" and any(p.glob("*.nbi"))
                   for p in (site / "hybridsim").rglob("__pycache__"))


# ------------------------------------------------------------------ compiled in fresh processes
FACTORY = textwrap.dedent("""
    def make(c):
        def flow(x, t, j, p, out):
            for q in range(x.shape[0]):
                out[q] = c * x[q]
        return flow
""")
TWO_WRAPPERS = textwrap.dedent("""
    import sys, numpy as np
    sys.path.insert(0, sys.argv[1])
    from factory import make
    from hybridsim.compiled import CompiledSystem, _cache as k
    x, p = np.array([1.0, 10.0]), np.zeros(0)
    for c in sys.argv[2:]:
        cs = CompiledSystem(flow_map=make(float(c)), state_dim=2)
        print(k.wrap_map(cs.maps["flow"], "vec")(x, 0.0, 0, p)[1])
""")


@pytest.mark.slow
def test_same_named_maps_compiled_by_two_processes_keep_their_own_code(tmp_path):
    """Two maps of one name (one factory's closures, written into ``out``: the
    engine wraps each in a function of one name), each compiled by its own
    process into the disk cache at the same point of that process, then both
    loaded by a third: each runs its own code. numba names compiled code by its
    function's name and an id; with ids counted from 1 in every process, both
    wrappers named the same symbol and the third process linked one body for
    both (``_types._RandomIds``)."""
    (tmp_path / "factory.py").write_text(FACTORY)

    cache = tmp_path / "cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))

    def child(*cs):
        out = subprocess.run([sys.executable, "-W", "ignore", "-c", TWO_WRAPPERS,
                              str(tmp_path), *cs], capture_output=True, text=True,
                             timeout=300, env=env, cwd=str(tmp_path))
        assert out.returncode == 0, out.stderr
        return [float(v) for v in out.stdout.split()]
    # two processes of the same history (each from an empty cache in one folder),
    # then both caches in that folder
    assert child("2") == [20.0]
    cache.rename(tmp_path / "a")
    assert child("3") == [30.0]
    shutil.copytree(tmp_path / "a", cache, dirs_exist_ok=True)
    assert child("2", "3") == [20.0, 30.0]          # both loaded from the disk cache


SPEC_RUN = textwrap.dedent("""
    import sys, time, numpy as np
    from hybridsim.compiled import CompiledSystem, simulate_compiled, simulate_many_compiled
    c = 9.81
    ball = CompiledSystem(lambda x, t, j, p: np.array([x[1], -c]),
                          lambda x, t, j, p: np.array([0.0, -p[0] * x[1]]),
                          jump_guard=lambda x, t, j, p: -x[0],
                          flow_guard=lambda x, t, j, p: x[0],
                          jump_set=lambda x, t, j, p: x[0] <= 0.0 and x[1] <= 0.0,
                          state_dim=2, params=[0.8], specialize=True)
    t = time.perf_counter()
    arc = simulate_compiled(ball, [1.0, 0.0], t_max=1e9, j_max=30, rtol=1e-8, atol=1e-10)
    first = time.perf_counter() - t
    arcs = simulate_many_compiled(ball, [[1.0, 0.0], [2.0, 0.0]] * 20, t_max=1e9, j_max=5,
                                  rtol=1e-8, atol=1e-10)
    np.save(sys.argv[1], np.concatenate([arc.t, arc.x.ravel(), arcs[-1].t]))
    print(first)
""")


@pytest.mark.slow
def test_specialised_kernel_is_cached_on_disk(tmp_path):
    """specialize=True compiles once per machine (with a notice) and a new
    process loads it: no notice, no compiling, the same samples to the bit."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    runs = []
    for i in range(2):
        out = subprocess.run([sys.executable, "-W", "ignore", "-c", SPEC_RUN,
                              str(tmp_path / f"r{i}.npy")], capture_output=True, text=True,
                             timeout=900, env=env)
        assert out.returncode == 0, out.stderr
        runs.append(out)
    assert "specialised on this system's maps" in runs[0].stderr
    assert "compiling" not in runs[1].stderr
    # loading is a fraction of a second; compiling takes >10 s (2 s: a loaded machine)
    assert float(runs[1].stdout.split()[-1]) < 2.0
    np.testing.assert_array_equal(np.load(tmp_path / "r0.npy"), np.load(tmp_path / "r1.npy"))
    gen = list((tmp_path / "cache").rglob("hybridsim_spec_*.py"))
    assert len(gen) == 1


BALL_RUN = textwrap.dedent("""
    import sys, numpy as np, hybridsim as hs
    from hybridsim.library import BouncingBall
    a = hs.simulate(BouncingBall(), x0=[1.0, 0.0], t_max=3.0, j_max=10, backend="compiled")
    print("ended", a.termination.name, file=sys.stderr)
    np.save(sys.argv[1], a.jump_times)
""")


@pytest.mark.skipif(not hasattr(os, "kill") or sys.platform == "win32",
                    reason="SIGINT sent to the process itself: POSIX")
def test_a_ctrl_c_a_callback_discards_during_a_kernel_compile_still_interrupts():
    """A SIGINT whose KeyboardInterrupt is discarded where it is raised (a
    callback of llvmlite during the compile swallows it) still ends the
    compile with KeyboardInterrupt, once the compile has returned: the kernel
    is whole, and disabled for further specialisation as after any compile."""
    import signal

    events = []

    class Dispatcher:                       # compiles by running a swallowing callback
        def compile(self, sig):
            try:
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(1000):       # the handler runs at a bytecode boundary
                    pass
            except KeyboardInterrupt:       # the callback's C caller discards it
                events.append("discarded")
            events.append("compiled")

        def disable_compile(self):
            events.append("disabled")

    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            k._compile_or_rebuild(Dispatcher(), ())
    finally:
        signal.signal(signal.SIGINT, old)
    assert events == ["discarded", "compiled", "disabled"]


@pytest.mark.slow
def test_a_compile_interrupted_by_ctrl_c_leaves_no_broken_kernel(tmp_path):
    """One SIGINT while the engine's kernels compile from an empty cache ends
    that process with KeyboardInterrupt (or, where it reaches the process only
    once the run has started, ends the run CANCELED with the arc so far, as
    any Ctrl-C of a run); the next process on the same cache
    compiles (or loads what was written whole) and runs: the ball's jump
    times equal the Python path's to the event tolerance."""
    import signal
    import time

    import hybridsim as hs
    from hybridsim.library import BouncingBall
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    # SIGINT as in a terminal's process: a job a non-interactive shell starts in the
    # background (CI's, here) inherits SIGINT ignored, and Python then installs no
    # handler of its own, so the signal would end nothing
    first = subprocess.Popen([sys.executable, "-W", "ignore", "-c", BALL_RUN,
                              str(tmp_path / "r0.npy")], stderr=subprocess.PIPE, text=True,
                             env=env,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    line = first.stderr.readline()         # the notice: the kernels are compiling now
    assert "compiling the engine's kernels" in line, line
    time.sleep(2.0)
    first.send_signal(signal.SIGINT)
    err = first.stderr.read()
    first.wait(timeout=600)
    second = subprocess.run([sys.executable, "-W", "ignore", "-c", BALL_RUN,
                             str(tmp_path / "r1.npy")], capture_output=True, text=True,
                            timeout=900, env=env)
    assert second.returncode == 0, second.stderr[-2000:]
    ref = hs.simulate(BouncingBall(), x0=[1.0, 0.0], t_max=3.0, j_max=10).jump_times
    np.testing.assert_allclose(np.load(tmp_path / "r1.npy"), ref, rtol=0, atol=1e-12)
    # the interrupt ends the process, also where it lands in a ctypes callback of
    # llvmlite that discards it (the engine's latch raises it once the compile has
    # returned), or, where it reaches the run, ends the run CANCELED
    if "ended CANCELED" in err:
        assert first.returncode == 0, err[-2000:]
        return
    assert "KeyboardInterrupt" in err, (first.returncode, err[-2000:])
    assert first.returncode != 0 and not (tmp_path / "r0.npy").exists()


def _assert_same(spec, gen, a, b, h0, kw):
    """A specialised kernel's run ``a`` and batch from the heights ``h0`` are
    the generic kernel's (``b``) to the bit."""
    from hybridsim.compiled import simulate_many_compiled
    for f in ("t", "j", "x", "xdot"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert a.termination is b.termination and a.stats == b.stats
    x0s = np.column_stack([h0, np.zeros_like(h0)])
    for u, v in zip(simulate_many_compiled(spec, x0s, **kw),
                    simulate_many_compiled(gen, x0s, **kw)):
        np.testing.assert_array_equal(u.x, v.x)
        np.testing.assert_array_equal(u.t, v.t)


@pytest.mark.slow
def test_maps_the_digest_cannot_key_specialise_in_memory():
    """specialize=True with a map reading an object the key cannot digest: the
    kernel is compiled in memory (no generated module), its maps inlined, and
    its runs and batches equal the generic kernel's to the bit."""
    from hybridsim.compiled import CompiledSystem, simulate_compiled

    class Gravity(enum.Enum):           # numba types it; spec_key cannot digest it
        EARTH = 9.81

    def ball(specialize):
        return CompiledSystem(lambda x, t, j, p: np.array([x[1], -Gravity.EARTH.value]),
                              lambda x, t, j, p: np.array([0.0, -p[0] * x[1]]),
                              jump_guard=lambda x, t, j, p: -x[0],
                              flow_guard=lambda x, t, j, p: x[0],
                              state_dim=2, params=[0.8], specialize=specialize)
    spec, gen = ball(True), ball(False)
    kw = dict(t_max=1e9, j_max=20, rtol=1e-8, atol=1e-10)
    a, b = simulate_compiled(spec, [1.0, 0.0], **kw), simulate_compiled(gen, [1.0, 0.0], **kw)
    assert spec._nb["one"] is not k.run_one
    # compiled in memory: no generated module
    assert not spec._nb["one"].py_func.__module__.startswith("hybridsim_spec_")
    _assert_same(spec, gen, a, b, np.linspace(0.5, 2.0, 40), kw)


@pytest.mark.slow
def test_batch_threads_give_the_same_arcs():
    """One thread or several (rows claimed dynamically), the same arcs."""
    from hybridsim.compiled import CompiledSystem, simulate_many_compiled
    timer = CompiledSystem(lambda x, t, j, p: np.ones(1), lambda x, t, j, p: np.zeros(1),
                           jump_guard=lambda x, t, j, p: x[0] - p[0], state_dim=1,
                           params=[1.0])
    x0s = np.random.default_rng(5).uniform(0.0, 0.9, (500, 1))
    nt = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        one = simulate_many_compiled(timer, x0s, t_max=7.3)
    finally:
        numba.set_num_threads(nt)
    many = simulate_many_compiled(timer, x0s, t_max=7.3)
    serial = simulate_many_compiled(timer, x0s, t_max=7.3, parallel=False)
    for a, b, c in zip(one, many, serial):
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.t, c.t)
        assert a.stats == b.stats == c.stats
        assert a.termination is b.termination


@pytest.mark.slow
def test_a_specialised_dop853_kernel_equals_the_generic_one():
    """specialize=True with method="DOP853": the system's DOP853 kernel is made
    when a run first asks for it (its RK45 one by compile()), and its runs
    and batches equal run_one_dop853's to the bit."""
    from hybridsim.compiled import CompiledSystem, simulate_compiled

    def osc(specialize):
        return CompiledSystem(flow_map=lambda x, t, j, p: np.array([x[1], -p[0] * x[0]]),
                              jump_map=lambda x, t, j, p: np.array([x[0], -0.5 * x[1]]),
                              jump_guard=lambda x, t, j, p: -x[0],
                              jump_set=lambda x, t, j, p: x[0] <= 0.0 and x[1] < 0.0,
                              state_dim=2, params=[4.0], specialize=specialize)
    spec, gen = osc(True), osc(False)
    kw = dict(t_max=6.0, rtol=1e-11, atol=1e-13, method="DOP853")
    a, b = simulate_compiled(spec, [1.0, 0.0], **kw), simulate_compiled(gen, [1.0, 0.0], **kw)
    assert gen._nb["one_DOP853"] is k.run_one_dop853
    assert spec._nb["one_DOP853"].py_func.__globals__["_DOP"] is True
    assert spec._nb["one"].py_func.__globals__["_DOP"] is False
    assert a.jump_count >= 2
    _assert_same(spec, gen, a, b, np.linspace(0.5, 1.5, 24), kw)


@pytest.mark.slow
def test_a_specialised_kernel_with_delays_equals_the_generic_one():
    """specialize=True on a flow map that reads the past: its generated module
    keeps the past's code (``_DELAYS``), and its runs equal run_one_delays's
    to the bit."""
    from hybridsim.compiled import CompiledSystem, simulate_compiled

    def lag(specialize):
        # a timer whose rate reads its own value 0.4 ago (p[2:4] after the params)
        return CompiledSystem(flow_map=lambda x, t, j, p: np.array([1.0 + p[1] * p[2], x[0]]),
                              jump_map=lambda x, t, j, p: np.array([0.0, x[1]]),
                              jump_guard=lambda x, t, j, p: x[0] - p[0],
                              state_dim=2, params=[0.7, 0.5], delays=(0.4,),
                              specialize=specialize)
    spec, gen = lag(True), lag(False)
    kw = dict(t_max=3.0, rtol=1e-9, atol=1e-12)
    a, b = simulate_compiled(spec, [0.0, 0.0], **kw), simulate_compiled(gen, [0.0, 0.0], **kw)
    assert gen._nb["one"] is k.run_one_delays
    assert spec._nb["one"].py_func.__globals__["_DELAYS"] is True
    assert a.jump_count >= 2
    for f in ("t", "j", "x", "xdot"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert a.termination is b.termination and a.stats == b.stats


def test_the_warming_stamp_reads_the_source_not_the_generated_modules():
    """A warming group's stamp (``tests/warm_kernels._stamp``) is named by the
    source of hybridsim and observers: a module generated into a package's
    ``__pycache__`` (where numba's cache of an installed copy keeps the
    generated maps) leaves it as it is, so a second suite skips the groups."""
    import pathlib
    import uuid

    import hybridsim
    here = pathlib.Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(here))
    try:
        import warm_kernels
    finally:
        sys.path.remove(str(here))
    before = warm_kernels._stamp("events", "/nowhere")
    gen = pathlib.Path(hybridsim.__file__).parent / "compiled" / "__pycache__"
    gen.mkdir(exist_ok=True)
    planted = gen / f"hybridsim_wrap_test_{uuid.uuid4().hex}.py"
    planted.write_text("x = 1\n")
    try:
        assert warm_kernels._stamp("events", "/nowhere") == before
    finally:
        planted.unlink()
