"""Falsification benchmark: ``hs.falsify`` side by side with PSY-TaLiRo.

Claims with known answers (each has a counterexample), searched with the same
budget of runs and the same seeds by

* ``hs.falsify`` (differential evolution, ``method="de"``), its populations
  run as one :func:`hybridsim.falsification.batch_run` batch per chunk
  (``simulate_many``, ``backend="auto"``): compiled where numba is installed
  (each claim's model is written once, a plain class along the last axis,
  and its maps are compiled from their source; the batch runs on the cores
  in machine code), else the vectorized numpy batch of the same model;
  stopping at the first counterexample ("falsify batch");
* the same with the vectorized numpy batch ("falsify vectorized", what
  "falsify batch" was before the compiled forms) and with one
  ``hs.simulate`` per run on the Python path ("falsify 1-by-1"), to
  separate the search, the batching and the compiling;
* PSY-TaLiRo (``psy-taliro`` 3.2, ``staliro.staliro``) with ``DualAnnealing``
  (its best optimizer for these cases) and ``UniformRandom`` (the floor),
  both with ``min_cost=0`` (stop at the first negative robustness), driving
  ``hs.simulate`` one run at a time as its model (the Python path, the
  default: "PSY-TaLiRo DA", "UR"; the target is measured against these).
  Its inputs are the space's coordinates as static inputs (the same box,
  the same map from coordinates to runs), its specification returns the
  claim's margin of the run (the same signed margin: the robustness of
  ``always(claim)``); the model hands the arc itself to the specification
  in a one-entry ``Trace``, so PSY-TaLiRo pays no trace conversion (its
  most favourable setting);
* for information, PSY-TaLiRo driving the compiled system one run at a time
  (``hs.simulate(..., backend="compiled")``: "PSY-TaLiRo DA/c", "UR/c"):
  what is left of the advantage when both use the compiled simulator. On a
  claim found in 1-6 runs it is the search's (fewer runs: the box's
  vertices first) and the overheads'; there is no batch to share.

The compiled maps are compiled once per machine (a few seconds per claim,
kept in numba's disk cache; the engine itself is cached too), by the
agreement check that runs before any clock starts; the line of each claim
prints it. All clocks, ours and
PSY-TaLiRo's, start warm.

The claims:

a. ball: the apex after the first bounce, e^2 h0, stays <= 0.7 for
   h0 in [0.9, 1.1], e in [0.7, 0.85]; false only near the corner
   (1.1, 0.85) (sup 0.795).
b. thermostat: the noisy thermostat of ``examples/falsify_overshoot.py``
   stays within 0.5 degree of [70, 80] under measurement noise of 20
   piecewise-constant values in [-1, 1]; false (the sup overshoot is 1).
c. linear: x' = A x + m(t), A = [[0, 1], [-1, -0.2]], |m_i| <= 1 constant on
   10 pieces of [0, 5] (20 coordinates), claim |x(5)| <= 0.6 S where S is
   the exact sup of |x(5)| over the class (attained at bang-bang noise):
   the violating set is ~1.5e-5 of the 20-cube (Monte Carlo), around the
   bang-bang corners.
d. resonance: x'' + 2 zeta w0 x' + w0^2 x = sin(2 pi f t), w0 = 2 pi,
   f in [0.5, 2] Hz, zeta in [0.05, 0.2], claim max |x| on [0, 10]
   <= 0.8 / (2 zeta_min w0^2); false only near f = 1 Hz, small zeta (an
   interior counterexample, not at a vertex of the box).

Per claim and tool: success rate over the seeds (a counterexample within the
budget), median wall time and median runs simulated by the first
counterexample (over the successful seeds; the clock starts when the tool
is called and stops when the first negative margin has been computed: for
a batch, the whole chunk that held it has been simulated), and the tool's
time / falsify batch's time. Then the memory of a large search: ``hs.falsify(...,
method="random", budget=100_000)`` on a batch_run population of vectorized
balls under ``tracemalloc``.

Run: ``python benchmarks/bench_falsify.py [--quick] [--seeds N] [--no-memory]``
(``--quick``: 3 seeds, smaller budgets, no vectorized or one-by-one falsify
rows, a 10^4-run memory search; about 30 s on an idle machine.)
"""
from __future__ import annotations

import argparse
import gc
import math
import os
import platform
import statistics
import time
import tracemalloc
import warnings
from importlib.metadata import version

import numpy as np
from scipy.linalg import expm

import hybridsim as hs
import hybridsim.compiled as hc
from hybridsim.falsification import Interval, PiecewiseConstant, Space, batch_run
from hybridsim.library import BouncingBall

try:
    import staliro
    from staliro.optimizers import DualAnnealing, UniformRandom
    HAVE_STALIRO = True
except ImportError:                                    # pragma: no cover
    HAVE_STALIRO = False

G = 9.81
RTOL, ATOL = 1e-8, 1e-10
#: the population runs of ``hs.falsify``: compiled (numba installed) or vectorized
COMPILED = hc.available()


class Case:
    """One claim: its space and margin, its model written once along the last
    axis (``model``, the noise's values in its state: ``x0_of(point)``), and
    the ways to run a point: ``many`` (a :func:`batch_run` population under
    ``backend="auto"``: the model's maps compiled from their source where
    numba is installed, else the vectorized batch), ``vec`` (the vectorized
    population), ``one_compiled`` (``hs.simulate(..., backend="compiled")``
    of the model, one run) and ``one`` (``hs.simulate`` on the Python path,
    what PSY-TaLiRo drives: the claim's system as a user of PSY-TaLiRo
    writes it, one state at a time with the noise a function of t, so that
    the peer is measured on its most favourable model)."""

    def __init__(self, space, claim, one, model, x0_of, run_kw, known):
        self.space, self.claim, self.one, self.known = space, claim, one, known
        self.model = model
        self.vec = batch_run(model, x0_of, backend="python", **run_kw)
        self.many = batch_run(model, x0_of, **run_kw)

        def one_compiled(p):
            return hs.simulate(model, x0_of(p), backend="compiled", **run_kw)
        self.one_compiled = one_compiled


# ------------------------------------------------------------------ (a) ball
class BallE(hs.HybridSystem):
    """The bouncing ball with its restitution as a third, constant state."""

    state_dim = 3
    vectorized = True

    def flow_map(self, x):
        return np.stack([x[..., 1], np.full(x[..., 0].shape, -G),
                         np.zeros(x[..., 0].shape)], axis=-1)

    def jump_map(self, x):
        return np.stack([np.zeros(x[..., 0].shape), -x[..., 2] * x[..., 1], x[..., 2]],
                        axis=-1)

    def flow_set(self, x):
        return x[..., 0] >= 0

    def jump_set(self, x):
        return (x[..., 0] <= 0) & (x[..., 1] <= 0)

    def jump_guard(self, x):
        return -x[..., 0]

    def flow_guard(self, x):
        return x[..., 0]


def ball_claim(arc):
    """0.7 - (apex after the first bounce), from the post-jump state."""
    k = int(np.flatnonzero(arc.j == 1)[0])
    h, v = arc.x[k, 0], arc.x[k, 1]
    return 0.7 - (h + v * v / (2 * G))


def ball_case():
    space = Space(h0=Interval(0.9, 1.1), e=Interval(0.7, 0.85))

    def one(p):
        return hs.simulate(BouncingBall(restitution=p["e"]), [p["h0"], 0.0], t_max=3.0,
                           j_max=1, rtol=RTOL, atol=ATOL)
    return Case(space, ball_claim, one, BallE(), lambda p: [p["h0"], 0.0, p["e"]],
                dict(t_max=3.0, j_max=1, rtol=RTOL, atol=ATOL),
                "sup apex 0.85^2 * 1.1 = 0.795 > 0.7")


# ------------------------------------------------------------ (b) thermostat
Z_OUT, Z_HEAT, Z_MIN, Z_MAX, EPS = 60.0, 30.0, 70.0, 80.0, 1.0
T_TH, P_TH = 4.0, 20


class NoisyThermostat(hs.HybridSystem):
    """examples/falsify_overshoot.py: x = (z, q), thresholds read y = z + m(t)."""

    state_dim = 2

    def __init__(self, m):
        self.m = m

    def flow_map(self, x, t):
        return np.array([-x[0] + Z_OUT + Z_HEAT * x[1], 0.0])

    def jump_map(self, x, t):
        return np.array([x[0], 1.0 - x[1]])

    def jump_guard(self, x, t):
        y = x[0] + self.m(t)[0]
        return y - Z_MAX if x[1] > 0.5 else Z_MIN - y

    def flow_guard(self, x, t):
        y = x[0] + self.m(t)[0]
        return Z_MAX - y if x[1] > 0.5 else y - Z_MIN


def _piece(x, t, first, pieces, width, dim=1, comp=0):
    """Value of the piecewise-constant noise stored in the state (columns
    first.. first + pieces*dim, piece-major) at time t, component comp: each
    row's own column (t is one time per row on the vectorized path)."""
    k = np.clip(np.floor_divide(t, width), 0, pieces - 1).astype(np.int64)
    return np.take_along_axis(x, (first + k * dim + comp)[..., None], axis=-1)[..., 0]


class NoisyThermostatV(hs.HybridSystem):
    """The same thermostat, vectorized: x = (z, q, m_1..m_20)."""

    state_dim = 2 + P_TH
    vectorized = True

    def flow_map(self, x, t):
        d = np.zeros(x.shape)
        d[..., 0] = -x[..., 0] + Z_OUT + Z_HEAT * x[..., 1]
        return d

    def jump_map(self, x, t):
        y = x.copy()
        y[..., 1] = 1.0 - x[..., 1]
        return y

    def _y(self, x, t):
        return x[..., 0] + _piece(x, t, 2, P_TH, T_TH / P_TH)

    def jump_guard(self, x, t):
        y = self._y(x, t)
        return np.where(x[..., 1] > 0.5, y - Z_MAX, Z_MIN - y)

    def flow_guard(self, x, t):
        y = self._y(x, t)
        return np.where(x[..., 1] > 0.5, Z_MAX - y, y - Z_MIN)


def thermostat_claim(arc):
    """Within 0.5 degree of [70, 80] (the example's margin, its 1e-6 slack)."""
    z = arc.x[:, 0]
    return float(min(np.min(z - (Z_MIN - 0.5)), np.min((Z_MAX + 0.5) - z))) + 1e-6


def thermostat_case():
    space = Space(m=PiecewiseConstant(EPS, t_end=T_TH, pieces=P_TH))

    def one(p):
        return hs.simulate(NoisyThermostat(p["m"]), [75.0, 1.0], t_max=T_TH, max_step=0.05,
                           rtol=RTOL, atol=ATOL)
    return Case(space, thermostat_claim, one, NoisyThermostatV(),
                lambda p: np.r_[75.0, 1.0, p.z],
                dict(t_max=T_TH, max_step=0.05, rtol=RTOL, atol=ATOL),
                "sup overshoot eps = 1 > 0.5")


# ----------------------------------------------------------------- (c) linear
A_LIN = np.array([[0.0, 1.0], [-1.0, -0.2]])
T_LIN, P_LIN, D_LIN = 5.0, 10, 2
#: level / sup: uniform sampling of the box violates it with probability ~1.5e-5
#: (Monte Carlo, 2e6 points: 7.6e-4 at 0.5, 1.2e-4 at 0.55, 5e-7 at 0.65)
LIN_FRACTION = 0.6


def linear_sup():
    """Exact sup of |x(T)| over |m_i| <= 1 piecewise constant, x(0) = 0:
    x(T) = sum_k G_k m_k with G_k = A^-1 (e^{A(T-t_k)} - e^{A(T-t_k+1)}), so
    sup |x(T)| = max over unit u of sum_k |G_k^T u|_1 (at bang-bang m)."""
    w = T_LIN / P_LIN
    Ainv = np.linalg.inv(A_LIN)
    Gs = [Ainv @ (expm(A_LIN * (T_LIN - k * w)) - expm(A_LIN * (T_LIN - (k + 1) * w)))
          for k in range(P_LIN)]
    th = np.linspace(0, np.pi, 200_001)
    U = np.stack([np.cos(th), np.sin(th)])
    return float(np.max(sum(np.abs(Gk.T @ U).sum(axis=0) for Gk in Gs)))


class Linear(hs.HybridSystem):
    state_dim = 2

    def __init__(self, m):
        self.m = m

    def flow_map(self, x, t):
        return A_LIN @ x + self.m(t)


class LinearV(hs.HybridSystem):
    """x' = A x + m(t), vectorized: state (x1, x2, m values piece-major)."""

    state_dim = 2 + P_LIN * D_LIN
    vectorized = True

    def flow_map(self, x, t):
        d = np.zeros(x.shape)
        w = T_LIN / P_LIN
        d[..., 0] = x[..., 1] + _piece(x, t, 2, P_LIN, w, D_LIN, 0)
        d[..., 1] = -x[..., 0] - 0.2 * x[..., 1] + _piece(x, t, 2, P_LIN, w, D_LIN, 1)
        return d

    def flow_set(self, x, t):
        return np.ones(x.shape[:-1], bool)

    def jump_set(self, x, t):
        return np.zeros(x.shape[:-1], bool)


def linear_case():
    sup = linear_sup()
    level = LIN_FRACTION * sup
    space = Space(m=PiecewiseConstant(1.0, t_end=T_LIN, pieces=P_LIN, dim=D_LIN))

    def claim(arc):
        return level - float(np.hypot(arc.x[-1, 0], arc.x[-1, 1]))

    step = T_LIN / P_LIN / 4

    def one(p):
        return hs.simulate(Linear(p["m"]), [0.0, 0.0], t_max=T_LIN, max_step=step,
                           rtol=RTOL, atol=ATOL)
    return Case(space, claim, one, LinearV(), lambda p: np.r_[0.0, 0.0, p.z],
                dict(t_max=T_LIN, max_step=step, rtol=RTOL, atol=ATOL),
                f"sup |x(5)| = {sup:.4f} > level {level:.4f}")


# -------------------------------------------------------------- (d) resonance
W0, T_RES, ZMIN = 2 * np.pi, 10.0, 0.05
RES_LEVEL = 0.8 / (2 * ZMIN * W0 ** 2)


class Oscillator(hs.HybridSystem):
    state_dim = 2

    def __init__(self, f, zeta):
        self.f, self.zeta = f, zeta

    def flow_map(self, x, t):
        return np.array([x[1], math.sin(2 * math.pi * self.f * t)
                         - 2 * self.zeta * W0 * x[1] - W0 ** 2 * x[0]])


class OscillatorV(hs.HybridSystem):
    """The same, vectorized: state (x, v, f, zeta)."""

    state_dim = 4
    vectorized = True

    def flow_map(self, x, t):
        d = np.zeros(x.shape)
        d[..., 0] = x[..., 1]
        d[..., 1] = (np.sin(2 * np.pi * x[..., 2] * t) - 2 * x[..., 3] * W0 * x[..., 1]
                     - W0 ** 2 * x[..., 0])
        return d

    def flow_set(self, x, t):
        return np.ones(x.shape[:-1], bool)

    def jump_set(self, x, t):
        return np.zeros(x.shape[:-1], bool)


def resonance_claim(arc):
    return RES_LEVEL - float(np.max(np.abs(arc.x[:, 0])))


def resonance_case():
    space = Space(f=Interval(0.5, 2.0), zeta=Interval(ZMIN, 0.2))

    def one(p):
        return hs.simulate(Oscillator(p["f"], p["zeta"]), [0.0, 0.0], t_max=T_RES,
                           max_step=0.02, rtol=RTOL, atol=ATOL)
    steady = 1 / (2 * ZMIN * W0 ** 2) * (1 - math.exp(-ZMIN * W0 * T_RES))
    return Case(space, resonance_claim, one, OscillatorV(),
                lambda p: [0.0, 0.0, p["f"], p["zeta"]],
                dict(t_max=T_RES, max_step=0.02, rtol=RTOL, atol=ATOL),
                f"amplitude at f = 1, zeta = 0.05 >= {steady:.4f} > level {RES_LEVEL:.4f}")


CASES = {"ball": ball_case, "thermostat": thermostat_case, "linear": linear_case,
         "resonance": resonance_case}
BUDGET = {"ball": 300, "thermostat": 300, "linear": 500, "resonance": 300}
QUICK_BUDGET = {"ball": 100, "thermostat": 60, "linear": 60, "resonance": 60}


# ------------------------------------------------------------------- clocking
class Clock:
    """Counts margins and notes when the first negative one was computed."""

    def __init__(self, claim):
        self.claim = claim
        self.start()

    def start(self):
        self.n, self.sim, self.first_n, self.first_t = 0, 0, None, None
        self.t0 = time.perf_counter()

    def __call__(self, arc):
        m = self.claim(arc)
        self.n += 1
        if m < 0 and self.first_n is None:
            # runs simulated by then (a whole population on the batch path)
            self.first_n, self.first_t = self.sim, time.perf_counter() - self.t0
        return m

    def counted(self, run):
        """``run`` (single or batch) counting the runs it simulates."""
        if getattr(run, "batch", False):
            def wrapped(points):
                arcs = run(points)
                self.sim += len(arcs)
                return arcs
            wrapped.batch = True
        else:
            def wrapped(point):
                self.sim += 1
                return run(point)
        return wrapped


#: the tools compared: (label, searcher, which run of the Case it drives)
TOOLS = {"falsify batch": ("falsify", "many"),
         "falsify vectorized": ("falsify", "vec"),
         "falsify 1-by-1": ("falsify", "one"),
         "PSY-TaLiRo DA": ("DA", "one"),
         "PSY-TaLiRo UR": ("UR", "one"),
         "PSY-TaLiRo DA/c": ("DA", "one_compiled"),
         "PSY-TaLiRo UR/c": ("UR", "one_compiled")}


def run_tool(case, tool, seed, budget):
    how, which = TOOLS[tool]
    run = getattr(case, which)
    if how == "falsify":
        return run_falsify(case, run, seed, budget)
    return run_staliro(case, run, seed, budget, how)


def run_falsify(case, run, seed, budget):
    clock = Clock(case.claim)
    clock.start()
    res = hs.falsify(clock.counted(run), case.space, clock, budget=budget, seed=seed,
                     method="de", stop=True, progress=False)
    total = time.perf_counter() - clock.t0
    return dict(found=res.verdict == "counterexample" and clock.first_n is not None,
                t=clock.first_t, n=clock.first_n, total=total, evals=res.evaluations)


def run_staliro(case, one, seed, budget, optimizer):
    space = case.space
    clock = Clock(case.claim)
    one = clock.counted(one)
    names = [f"z{i}" for i in range(space.dim)]

    @staliro.model
    def model(inputs):
        z = np.array([inputs.static[k] for k in names])
        return staliro.Trace({0.0: one(space.point(z))})       # the arc, as is

    @staliro.specification
    def spec(trace):
        (arc,) = trace.states
        return clock(arc)

    opts = staliro.TestOptions(static_inputs={k: (lo, hi) for k, lo, hi in
                                              zip(names, space.lo, space.hi)},
                               iterations=budget, runs=1, seed=seed + 1)
    opt = DualAnnealing(min_cost=0.0) if optimizer == "DA" else UniformRandom(min_cost=0.0)
    clock.start()
    staliro.staliro(model, spec, opt, opts)
    total = time.perf_counter() - clock.t0
    return dict(found=clock.first_n is not None, t=clock.first_t, n=clock.first_n,
                total=total, evals=clock.n)


def check_agreement(case, n=4, seed=123):
    """Largest |margin(single Python run) - margin(other run)| on a few random
    points, over the batch, vectorized and single compiled runs; and the
    seconds of the first batch call (the compiled maps' compiling, once per
    process, before any clock starts)."""
    claim = case.claim
    pts = [case.space.point(z) for z in case.space.sample(n, seed=seed)]
    t = time.perf_counter()
    b = np.array([claim(arc) for arc in case.many(pts)])
    first = time.perf_counter() - t
    a = np.array([claim(case.one(p)) for p in pts])
    v = np.array([claim(arc) for arc in case.vec(pts)])
    c = np.array([claim(case.one_compiled(p)) for p in pts]) if COMPILED else a
    return float(max(np.max(np.abs(a - b)), np.max(np.abs(a - v)),
                     np.max(np.abs(a - c)))), first


def verdict(name, per, nseeds, psy, how, target=True):
    """The RESULT line: falsify batch against the better of the ``psy`` tools
    (more successes, then the shorter median time to the first)."""
    fb = per["falsify batch"]
    succ_fb = sum(r["found"] for r in fb)
    ref_t = [r["t"] for r in fb if r["found"]]
    best = max(psy, key=lambda k: (sum(r["found"] for r in per[k]),
                                   -statistics.median([r["t"] for r in per[k] if r["found"]]
                                                      or [math.inf])))
    sb = [r["t"] for r in per[best] if r["found"]]
    succ_best = max(sum(r["found"] for r in per[k]) for k in psy)
    if sb and ref_t:
        ratio = f"{statistics.median(sb) / statistics.median(ref_t):.1f}x"
    elif ref_t:
        ratio = "inf (PSY-TaLiRo found none)"
    else:
        ratio = "n/a (falsify found none)"
    faster = bool((not sb and ref_t) or (sb and ref_t and
                                         statistics.median(sb) >= 5 * statistics.median(ref_t)))
    met = "meets" if succ_fb >= succ_best and faster else "MISSES"
    what = "the target" if target else "5x (not the target: information)"
    return (f"RESULT {name}: success falsify {succ_fb}/{nseeds} vs PSY-TaLiRo {how}, best "
            f"({best}) {succ_best}/{nseeds}; median time to first counterexample "
            f"PSY-TaLiRo/falsify = {ratio} ({met} {what}: success >= and >= 5x)")


def med(xs, fmt):
    xs = [x for x in xs if x is not None]
    return format(statistics.median(xs), fmt) if xs else "-"


# --------------------------------------------------------------------- memory
def memory(runs):
    """Peak traced memory of random searches on a batch_run population of
    vectorized balls (stop=False: the whole budget); ``runs``: a list of
    (budget, popsize)."""
    space = Space(h0=Interval(0.9, 1.1), e=Interval(0.7, 0.85))
    many = batch_run(BallE(), lambda p: [p["h0"], 0.0, p["e"]], t_max=3.0, j_max=1,
                     rtol=RTOL, atol=ATOL)
    hs.falsify(many, space, ball_claim, budget=2000, seed=1, method="random", popsize=1000,
               stop=False, progress=False)         # warm-up: lazy imports and caches
    out = []
    for budget, pop in runs:
        gc.collect()
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        t = time.perf_counter()
        res = hs.falsify(many, space, lambda arc: ball_claim(arc) + 1.0, budget=budget,
                         seed=0, method="random", popsize=pop, stop=False, progress=False)
        dt = time.perf_counter() - t
        held, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        out.append(dict(budget=budget, pop=pop, peak=(peak - base) / 2**20,
                        held=(held - base) / 2**20, s=dt, evals=res.evaluations))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 seeds, smaller budgets")
    ap.add_argument("--seeds", type=int, default=None, help="seeds 0..N-1 (default 10)")
    ap.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    ap.add_argument("--no-memory", action="store_true")
    args = ap.parse_args(argv)
    nseeds = args.seeds or (3 if args.quick else 10)
    budgets = QUICK_BUDGET if args.quick else BUDGET
    warnings.simplefilter("ignore")
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, numpy {np.__version__}")
    if HAVE_STALIRO:
        print(f"psy-taliro {version('psy-taliro')}: baselines DualAnnealing and UniformRandom "
              f"(min_cost=0), one hs.simulate per run (the Python path; '/c': "
              f"backend='compiled')")
    else:
        print("psy-taliro is not installed (pip install psy-taliro): running hs.falsify alone")
    print("populations of hs.falsify: " + (f"compiled (numba {version('numba')})" if COMPILED
                                           else "vectorized (numba is not installed)"))
    tools = ["falsify batch"] + ([] if args.quick or not COMPILED else ["falsify vectorized"])
    tools += [] if args.quick else ["falsify 1-by-1"]
    if HAVE_STALIRO:
        tools += ["PSY-TaLiRo DA", "PSY-TaLiRo UR"]
        if COMPILED:
            tools += ["PSY-TaLiRo DA/c", "PSY-TaLiRo UR/c"]
    seeds = list(range(nseeds))
    rows, results = [], []
    for name in args.cases:
        case = CASES[name]()
        budget = budgets[name]
        agree, first = check_agreement(case)
        print(f"\n[{name}] dim {case.space.dim}, budget {budget}, seeds 0..{nseeds - 1}; "
              f"known: {case.known}; |margin 1-by-1 - others| <= {agree:.1e}; first batch "
              f"call (compiling the maps, outside the clocks) {first:.2f} s", flush=True)
        per = {}
        for tool in tools:
            out = [run_tool(case, tool, s, budget) for s in seeds]
            per[tool] = out
            ok = [r for r in out if r["found"]]
            print(f"  {tool:18s} found {len(ok)}/{nseeds}  runs to first "
                  f"{[r['n'] for r in out]}  total {sum(r['total'] for r in out):6.1f} s",
                  flush=True)
        ref_t = [r["t"] for r in per["falsify batch"] if r["found"]]
        for tool in tools:
            ok = [r for r in per[tool] if r["found"]]
            ts = [r["t"] for r in ok]
            ratio = "-"
            if tool != "falsify batch" and ts and ref_t:
                ratio = f"{statistics.median(ts) / statistics.median(ref_t):.1f}x"
            rows.append((name, tool, f"{len(ok)}/{nseeds}", med(ts, ".4f"),
                         med([r["n"] for r in ok], ".0f"), ratio))
        if HAVE_STALIRO:
            results.append(verdict(name, per, nseeds, ("PSY-TaLiRo DA", "PSY-TaLiRo UR"),
                                   "driving hs.simulate (the Python path)"))
            if COMPILED:
                results.append(verdict(name, per, nseeds,
                                       ("PSY-TaLiRo DA/c", "PSY-TaLiRo UR/c"),
                                       "driving hs.simulate(backend='compiled')", target=False))
        else:
            results.append(f"RESULT {name}: falsify success "
                           f"{sum(r['found'] for r in per['falsify batch'])}/{nseeds}, "
                           f"median time to first {med(ref_t, '.4f')} s")

    print("\nclaim       tool                success  median s to 1st  median runs  "
          "time / falsify batch")
    for name, tool, succ, t, n, ratio in rows:
        print(f"{name:11s} {tool:19s} {succ:>7s}  {t:>15s}  {n:>11s}  {ratio:>8s}")
    for r in results:
        print(r)

    if not args.no_memory:
        big = 10_000 if args.quick else 100_000
        print("\nmemory: hs.falsify(method='random', stop=False) on a batch_run population "
              "of vectorized balls, under tracemalloc", flush=True)
        mem = memory([(big // 10, 1000), (big, 1000)] + ([] if args.quick else [(big, 100)]))
        for m in mem:
            print(f"  budget {m['budget']:7d}, popsize {m['pop']:5d}: peak {m['peak']:7.2f} MB, "
                  f"held after {m['held']:6.2f} MB, {m['s']:.1f} s (traced)")
        a, b = mem[0], mem[1]
        slope = (b["peak"] - a["peak"]) / (b["budget"] - a["budget"])      # MB a run
        at = b["peak"] + slope * (10**6 - b["budget"])
        print(f"  -> {slope * 2**20:.0f} B of peak a run (the margins: a preallocated "
              f"array of 8 B a run, copied once into the result); 10^6 runs at popsize "
              f"1000: ~{at:.0f} MB "
              f"(extrapolated{'; rough at --quick sizes' if args.quick else ''}); the rest is "
              f"one population's arcs, set by popsize")
        print(f"RESULT memory: falsify random, {big} runs, popsize 1000: peak "
              f"{b['peak']:.1f} MB; {slope * 2**20:.0f} B a run -> 10^6 runs ~{at:.0f} MB")


if __name__ == "__main__":
    main()
