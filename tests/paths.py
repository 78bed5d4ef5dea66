"""The three integration paths behind one interface, for tests that must hold on all.

A :class:`Linear` case (x' = A x, x+ = G x + c, D = {a.x - b >= 0}, and C =
{e.x - d >= 0} or everything) is built on each path from the same numbers:

* ``"python"``: :func:`hybridsim.simulate` on a plain ``HybridSystem``;
* ``"vectorized"``: :func:`hybridsim.simulate_vectorized` on the same maps
  written over (N, n) batches (one row);
* ``"compiled"``: :func:`hybridsim.compiled.simulate_compiled` on a
  ``CompiledSystem`` whose maps read the case's numbers from ``params``
  (the maps are compiled once per state dimension and kind of sets, and
  reused by every case: new numbers recompile nothing).

``sets`` says how the sets are given: ``"guards"`` (continuous guards only:
the sets derived from them), ``"both"`` (indicators decide membership, the
guards locate crossings) or ``"indicators"`` (indicators only: events found
by bisection of the indicators).

``run(path, case, x0, **options)`` returns the arc; options a path does not
implement raise its refusal (see :mod:`hybridsim.options`). A test that takes
an argument ``path`` runs on every path (``conftest.py`` parametrizes it;
``@pytest.mark.paths(...)`` narrows it).
"""
from __future__ import annotations

import importlib.util
import signal
import threading
from dataclasses import dataclass

import numpy as np
import pytest

import hybridsim as hs

PATHS = ("python", "vectorized", "compiled")
HAS_NUMBA = importlib.util.find_spec("numba") is not None
NO_NUMBA = "the compiled path needs numba (pip install 'hybridsim[fast]')"
SETS = ("guards", "both", "indicators")


@dataclass
class Linear:
    """x' = A x + k; x+ = G x + c; D = {a.x >= b}; C = {e.x >= d} (or all of R^n)."""

    A: np.ndarray
    G: np.ndarray
    c: np.ndarray
    a: np.ndarray
    b: float
    e: np.ndarray | None = None
    d: float = 0.0
    sets: str = "guards"
    k: np.ndarray | None = None
    sets_C: str | None = None       # how C is given, where not as D (``sets``)

    @property
    def n(self):
        return len(self.a)

    @property
    def with_C(self):
        return self.e is not None

    def hD(self, x):
        return float(self.a @ x - self.b)

    def hC(self, x):
        return np.inf if self.e is None else float(self.e @ x - self.d)

    def build(self, path):
        return {"python": self.python, "vectorized": self.vectorized,
                "compiled": self.compiled}[path]()

    # -------------------------------------------------------------- the paths
    def python(self):
        A, G, c, a, b, e, d = self.A, self.G, self.c, self.a, self.b, self.e, self.d
        kw = {}
        sD, sC = self.sets, self.sets_C or self.sets
        if sD in ("guards", "both"):
            kw["jump_guard"] = lambda x: a @ x - b
        if sD in ("both", "indicators"):
            kw["D"] = lambda x: a @ x - b >= 0
        if e is not None and sC in ("guards", "both"):
            kw["flow_guard"] = lambda x: e @ x - d
        if e is not None and sC in ("both", "indicators"):
            kw["C"] = lambda x: e @ x - d >= 0
        k = np.zeros(self.n) if self.k is None else self.k
        return hs.HybridSystem.from_functions(f=lambda x: A @ x + k, g=lambda x: G @ x + c,
                                              state_dim=self.n, **kw)

    def vectorized(self):
        A, G, c, a, b, e, d = self.A, self.G, self.c, self.a, self.b, self.e, self.d
        kw = {}
        sD, sC = self.sets, self.sets_C or self.sets
        if sD in ("guards", "both"):
            kw["jump_guard"] = lambda X: X @ a - b
        if sD in ("both", "indicators"):
            kw["D"] = lambda X: X @ a - b >= 0
        if e is not None and sC in ("guards", "both"):
            kw["flow_guard"] = lambda X: X @ e - d
        if e is not None and sC in ("both", "indicators"):
            kw["C"] = lambda X: X @ e - d >= 0
        k = np.zeros(self.n) if self.k is None else self.k
        return hs.HybridSystem.from_functions(f=lambda X: X @ A.T + k, g=lambda X: X @ G.T + c,
                                              state_dim=self.n, vectorized=True, **kw)

    def params(self):
        n = self.n
        e = np.zeros(n) if self.e is None else self.e
        k = np.zeros(n) if self.k is None else self.k
        return np.concatenate([[n], self.A.ravel(), self.G.ravel(), self.c, self.a, [self.b],
                               e, [self.d], k]).astype(float)

    def compiled(self):
        key = (self.n, self.with_C, self.sets, self.sets_C or self.sets)
        system = _COMPILED.get(key)
        if system is None:
            system = _COMPILED[key] = _compiled_system(*key)
        system.params = self.params()
        return system


def run(path, case, x0, **options):
    """One run of ``case`` (a :class:`Linear` or a :class:`Ball`) from ``x0``
    on ``path``; the arc."""
    system = case.build(path)
    if path == "python":
        return hs.simulate(system, x0, **options)
    if path == "vectorized":
        # one row of a batch, under the single run's raise/warn policy (a batch
        # has its own: one BatchWarning, BatchError; tested in test_batch*)
        throw, warn = options.pop("throw", True), options.pop("warn", True)
        policy = {k: (False if isinstance(v, bool) else v)    # bad values: the path's error
                  for k, v in (("throw", throw), ("warn", warn))}
        arc = hs.simulate_vectorized(system, np.atleast_2d(np.asarray(x0, float)),
                                     **policy, **options)[0]
        return hs.rules.finish(arc, throw, warn)
    from hybridsim.compiled import simulate_compiled
    return simulate_compiled(system, x0, **options)


# ------------------------------------------------------------------ compiled maps
# the case's numbers are read from p: [n, A (n*n), G (n*n), c (n), a (n), b, e (n), d, k (n)]
_COMPILED = {}
_MAPS = None


def _maps():
    global _MAPS
    if _MAPS is not None:
        return _MAPS
    from numba import njit

    @njit(cache=False)
    def lin_f(x, t, j, p):
        n = x.shape[0]
        o = 3 + 2 * n * n + 3 * n
        out = np.zeros(n)
        for r in range(n):
            out[r] = p[o + r]
            for k in range(n):
                out[r] += p[1 + r * n + k] * x[k]
        return out

    @njit(cache=False)
    def lin_g(x, t, j, p):
        n = x.shape[0]
        o = 1 + n * n
        out = np.zeros(n)
        for r in range(n):
            out[r] = p[o + n * n + r]
            for k in range(n):
                out[r] += p[o + r * n + k] * x[k]
        return out

    @njit(cache=False)
    def lin_hD(x, t, j, p):
        n = x.shape[0]
        o = 1 + 2 * n * n + n
        s = -p[o + n]
        for k in range(n):
            s += p[o + k] * x[k]
        return s

    @njit(cache=False)
    def lin_hC(x, t, j, p):
        n = x.shape[0]
        o = 1 + 2 * n * n + 2 * n + 1
        s = -p[o + n]
        for k in range(n):
            s += p[o + k] * x[k]
        return s

    @njit(cache=False)
    def lin_D(x, t, j, p):
        return lin_hD(x, t, j, p) >= 0.0

    @njit(cache=False)
    def lin_C(x, t, j, p):
        return lin_hC(x, t, j, p) >= 0.0

    _MAPS = dict(flow=lin_f, jump=lin_g, jump_guard=lin_hD, flow_guard=lin_hC,
                 jump_set=lin_D, flow_set=lin_C)
    return _MAPS


def _compiled_system(n, with_C, sets, sets_C):
    from hybridsim.compiled import CompiledSystem
    m = _maps()
    kw = dict(flow=m["flow"], jump=m["jump"])
    if sets in ("guards", "both"):
        kw["jump_guard"] = m["jump_guard"]
    if sets in ("both", "indicators"):
        kw["jump_set"] = m["jump_set"]
    if with_C and sets_C in ("guards", "both"):
        kw["flow_guard"] = m["flow_guard"]
    if with_C and sets_C in ("both", "indicators"):
        kw["flow_set"] = m["flow_set"]
    return CompiledSystem(state_dim=n, params=np.zeros(3 + 2 * n * n + 4 * n), **kw)


# ------------------------------------------------------------------ random cases
def random_linear(seed, n, with_C, sets="guards"):
    """A random case whose flows come back to the guard (rotations for n >= 2,
    growth for n = 1) and whose jumps land outside D; x0 in C.

    Returns ``(case, x0)``.
    """
    rng = np.random.default_rng(seed)
    if n == 1:
        A = np.array([[rng.uniform(0.2, 1.5)]])
    else:
        S = rng.normal(size=(n, n))
        A = rng.uniform(1.0, 4.0) * (S - S.T) / 2 + rng.normal(scale=0.3, size=(n, n))
    a = rng.normal(size=n)
    a /= np.linalg.norm(a)
    b = float(rng.uniform(0.2, 1.5))
    G = rng.normal(scale=0.3, size=(n, n))
    c = rng.normal(size=n) * 2.5
    if a @ c > b - 0.3:
        c -= a * (a @ c - b + 0.3 + rng.uniform(0.0, 1.0))
    e, d = None, 0.0
    x0 = rng.normal(size=n) * 2.0
    if with_C:
        e = rng.normal(size=n)
        e /= np.linalg.norm(e)
        d = float(rng.uniform(-4.0, -1.0))
        if e @ x0 - d < 0:
            x0 = x0 + (d - e @ x0 + 0.1) * e
    return Linear(A, G, c, a, b, e, d, sets), x0


def timer(period=0.5, sets="guards"):
    """x' = 1, D = {x >= period}, g = 0: jumps at every multiple of period."""
    return Linear(np.zeros((1, 1)), np.zeros((1, 1)), np.zeros(1), np.ones(1), period,
                  sets=sets, k=np.ones(1))


# ------------------------------------------------------------------ balls
@dataclass
class Ball:
    """A bouncing ball x = (height, velocity), x' = (v, -gravity), written the
    ways users write it: ``sets`` ``"guards"`` (guards only: D = {-h >= 0},
    which the post-jump state at height 0 still satisfies), ``"both"`` (D =
    {h <= 0, v <= 0} as an indicator beside the guards) or ``"indicators"``.
    ``keep`` keeps the located height at the jump (x+ = (h, -lam v)), as a
    natural model of an impact does; else x+ = (0, -lam v). ``nan_below``:
    the jump guard returns NaN below that height (a broken guard)."""

    lam: float = 0.8
    gravity: float = 9.81
    sets: str = "both"
    keep: bool = False
    nan_below: float = -np.inf

    def params(self):
        return np.array([self.gravity, self.lam, float(self.keep), self.nan_below])

    def build(self, path):
        p = self.params()
        if path == "compiled":
            key = ("ball", self.sets)
            system = _COMPILED.get(key)
            if system is None:
                system = _COMPILED[key] = _ball_compiled(self.sets)
            system.params = p
            return system
        m = _ball_maps(vectorized=path == "vectorized")
        kw = {}
        if self.sets in ("guards", "both"):
            kw.update(jump_guard=lambda x: m["hD"](x, p), flow_guard=lambda x: m["hC"](x, p))
        if self.sets in ("both", "indicators"):
            kw.update(D=lambda x: m["D"](x, p), C=lambda x: m["C"](x, p))
        return hs.HybridSystem.from_functions(f=lambda x: m["f"](x, p),
                                              g=lambda x: m["g"](x, p), state_dim=2,
                                              vectorized=path == "vectorized", **kw)


def _ball_maps(vectorized):
    if vectorized:
        def f(X, p):
            return np.column_stack([X[:, 1], np.full(len(X), -p[0])])

        def g(X, p):
            return np.column_stack([X[:, 0] * p[2], -p[1] * X[:, 1]])

        def hD(X, p):
            return np.where(X[:, 0] < p[3], np.nan, -X[:, 0])

        def hC(X, p):
            return X[:, 0]

        def D(X, p):
            return (X[:, 0] <= 0.0) & (X[:, 1] <= 0.0)

        def C(X, p):
            return X[:, 0] >= 0.0
    else:
        def f(x, p):
            return np.array([x[1], -p[0]])

        def g(x, p):
            return np.array([x[0] * p[2], -p[1] * x[1]])

        def hD(x, p):
            return np.nan if x[0] < p[3] else -x[0]

        def hC(x, p):
            return x[0]

        def D(x, p):
            return x[0] <= 0.0 and x[1] <= 0.0

        def C(x, p):
            return x[0] >= 0.0
    return dict(f=f, g=g, hD=hD, hC=hC, D=D, C=C)


def _ball_compiled(sets):
    from hybridsim.compiled import CompiledSystem

    def f(x, t, j, p):
        return np.array([x[1], -p[0]])

    def g(x, t, j, p):
        return np.array([x[0] * p[2], -p[1] * x[1]])

    def hD(x, t, j, p):
        return np.nan if x[0] < p[3] else -x[0]

    def hC(x, t, j, p):
        return x[0]

    def D(x, t, j, p):
        return x[0] <= 0.0 and x[1] <= 0.0

    def C(x, t, j, p):
        return x[0] >= 0.0
    kw = {}
    if sets in ("guards", "both"):
        kw.update(jump_guard=hD, flow_guard=hC)
    if sets in ("both", "indicators"):
        kw.update(jump_set=D, flow_set=C)
    return CompiledSystem(f, g, state_dim=2, params=np.zeros(4), **kw)


# ------------------------------------------------------------------ Ctrl-C
#: (file, function) of the engine's run loops: a signal raised while the main
#: thread is in one of them lands inside a run
_LOOPS = {("solve.py", "_loop"), ("batch_vectorized.py", "run")}


def _in_run(frame):
    """Whether the main thread's ``frame`` is inside a run's loop: a Python
    loop's frame, a compiled batch's wait for its workers, or a compiled kernel
    (the innermost frame a runner's, at the same instruction twice: in the
    kernel, which lets threads run)."""
    f = frame
    while f is not None:
        if (f.f_code.co_filename.rsplit("/", 1)[-1], f.f_code.co_name) in _LOOPS:
            return True
        if f.f_code.co_filename.endswith("compiled/_run.py") and \
                f.f_code.co_name == "_interruptible":
            return True
        f = f.f_back
    return frame.f_code.co_filename.endswith("compiled/_run.py") and frame.f_code.co_name in (
        "simulate_compiled", "one")


class one_sigint_inside_the_run:
    """Context: ONE SIGINT, raised by a helper thread once the main thread is
    inside a run's loop (never on a clock), under the test's own SIGINT handler
    (``signal.default_int_handler``, whatever the runner installed, SIG_IGN
    included), restored after. ``sent`` says whether it was raised; the thread
    gives up after ``limit`` seconds of wall time without seeing a run."""

    def __init__(self, limit=120.0, settle=0.0):
        self.limit, self.settle, self.sent = limit, settle, False

    def _watch(self):
        import sys
        import time
        main = threading.main_thread().ident
        end = time.monotonic() + self.limit
        last, since = None, None
        while not self._stop.is_set() and time.monotonic() < end:
            frame = sys._current_frames().get(main)
            inside = False
            if frame is not None and _in_run(frame):
                here = (frame.f_code, frame.f_lasti)
                python = not frame.f_code.co_filename.endswith("compiled/_run.py")
                inside = python or here == last
                last = here
            if not inside:
                since = None
            elif since is None:
                since = time.monotonic()
            if inside and time.monotonic() - since >= self.settle:
                self.sent = True
                signal.raise_signal(signal.SIGINT)
                return
            self._stop.wait(0.01)

    def __enter__(self):
        self._old = signal.signal(signal.SIGINT, signal.default_int_handler)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(self.limit)
        signal.signal(signal.SIGINT, self._old)
        return False
