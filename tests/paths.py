"""The three integration paths behind one interface, for tests that must hold on all.

A :class:`Linear` case (x' = A x, x+ = G x + c, D = {a.x - b >= 0}, and C =
{e.x - d >= 0} or everything) or a :class:`Ball` is one plain model (a
``HybridSystem`` subclass whose maps read the case's numbers from its
attributes, written on the last axis), and every path runs that model:

* ``"python"``: :func:`hybridsim.simulate`, one state at a time;
* ``"vectorized"``: :func:`hybridsim.simulate_vectorized`, the same maps
  called on (N, n) batches (one row; ``vectorized = True``);
* ``"compiled"``: :func:`hybridsim.compiled.simulate_compiled` on the
  model's own maps lowered from source (:func:`hybridsim.compiled.lower`:
  the numbers are slots of ``params``, compiled once per state dimension
  and kind of sets and reused by every case: new numbers recompile nothing).

``sets`` says how the sets are given: ``"guards"`` (continuous guards only:
the sets derived from them), ``"both"`` (indicators decide membership, the
guards locate crossings) or ``"indicators"`` (indicators only, no guard:
events found by bisection of the indicators).

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
        """The case's model on ``path`` (a ``CompiledSystem`` lowered from it
        for ``"compiled"``)."""
        sC = (self.sets_C or self.sets) if self.with_C else None
        model = _model(_LinearModel, self.sets, sC)(self, vectorized=path == "vectorized")
        return _on(path, model)

    def python(self):
        return self.build("python")


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


# ------------------------------------------------------------------ the models
def _on(path, model):
    if path == "compiled":
        from hybridsim.compiled import lower
        return lower(model)
    if path not in PATHS:
        raise ValueError(f"path must be one of {PATHS}, got {path!r}")
    return model


class _LinearModel(hs.HybridSystem):
    """x' = A x + k, x+ = G x + c; the guards a.x - b (D) and e.x - d (C)."""

    def __init__(self, case, vectorized=False):
        n = case.n
        self.state_dim = n
        self.A, self.G = np.asarray(case.A, float), np.asarray(case.G, float)
        self.c, self.a = np.asarray(case.c, float), np.asarray(case.a, float)
        self.b, self.d = float(case.b), float(case.d)
        self.e = np.zeros(n) if case.e is None else np.asarray(case.e, float)
        self.k = np.zeros(n) if case.k is None else np.asarray(case.k, float)
        self.vectorized = vectorized

    def flow_map(self, x):
        return x @ self.A.T + self.k

    def jump_map(self, x):
        return x @ self.G.T + self.c

    def hD(self, x):
        return x @ self.a - self.b

    def hC(self, x):
        return x @ self.e - self.d

    def D(self, x):
        return x @ self.a - self.b >= 0

    def C(self, x):
        return x @ self.e - self.d >= 0


class _BallModel(hs.HybridSystem):
    """x' = (v, -gravity), x+ = (keep h, -lam v); hD NaN below ``nan_below``."""

    state_dim = 2

    def __init__(self, case, vectorized=False):
        self.gravity, self.lam = float(case.gravity), float(case.lam)
        self.keep, self.nan_below = bool(case.keep), float(case.nan_below)
        self.vectorized = vectorized

    def flow_map(self, x):
        dx = np.empty_like(x)
        dx[..., 0] = x[..., 1]
        dx[..., 1] = -self.gravity
        return dx

    def jump_map(self, x):
        xn = np.empty_like(x)
        xn[..., 0] = x[..., 0] * self.keep
        xn[..., 1] = -self.lam * x[..., 1]
        return xn

    def hD(self, x):
        return np.where(x[..., 0] < self.nan_below, np.nan, -x[..., 0])

    def hC(self, x):
        return x[..., 0]

    def D(self, x):
        return (x[..., 0] <= 0.0) & (x[..., 1] <= 0.0)

    def C(self, x):
        return x[..., 0] >= 0.0


_MODELS = {}


def _model(base, sD, sC):
    """``base`` with D given as ``sD`` and C as ``sC`` (None: C is everything):
    its hD/hC as guards, D/C as indicators (no guard where ``"indicators"``:
    none is derived). A module-level class (picklable)."""
    key = (base, sD, sC)
    cls = _MODELS.get(key)
    if cls is None:
        if sD not in SETS or sC not in (None, *SETS):
            raise ValueError(f"sets must be one of {SETS}, got {sD!r}, {sC!r}")
        body = {"jump_guard": base.hD if sD in ("guards", "both") else None,
                "flow_guard": base.hC if sC in ("guards", "both") else None}
        if sD in ("both", "indicators"):
            body["jump_set"] = base.D
        if sC in ("both", "indicators"):
            body["flow_set"] = base.C
        name = f"{base.__name__}_{sD}_{sC}"
        body.update(__module__=__name__, __qualname__=name)
        cls = _MODELS[key] = globals()[name] = type(name, (base,), body)
    return cls


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

    def build(self, path):
        """The ball's model on ``path`` (lowered for ``"compiled"``)."""
        sC = self.sets
        model = _model(_BallModel, self.sets, sC)(self, vectorized=path == "vectorized")
        return _on(path, model)


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
