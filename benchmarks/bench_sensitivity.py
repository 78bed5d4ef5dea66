"""Sensitivities through jumps (issue 26): accuracy and cost, against baselines.

1. The 30-bounce ball (h0 = 1, e = 0.8), theta = (h0, v0, e): d t_k / d h0,
   d t_k / d e (k = 1..30) and d x(T) / d e (T a quarter into the 31st
   flight) against their closed forms (from ``bouncing_ball_jump_times``'
   formula), at rtol 1e-6, 1e-8, 1e-10. Columns: ``simulate_sensitivity``
   with central-difference Jacobians, the same with the ball's Jacobians
   given, and two baselines of the same run: a plain ``hs.simulate`` (the
   cost of the state alone) and central differences of whole runs (6 runs,
   step 1e-6 relative: the usual way to get the same numbers).
2. Covariance through jumps: x0 ~ N((1, 0), diag(0.005^2, 0.01^2)) to a
   quarter into the flight after the 5th bounce: the linearised S P0 S^T
   (one sensitivity run) against a Monte Carlo of 1,000 runs (one vectorized
   ``simulate_many`` batch of ``BouncingBall(vectorized=True)``), with their difference in
   units of the Monte Carlo's standard error.
3. ``hs.falsify(..., refine="gradient")`` (L-BFGS-B on the margin's gradient
   from the sensitivities) against the compass search (``refine=True``), the
   same seed and budget (150 runs), on a smooth margin with its minimum
   1e-3 inside the box: x' = a, reset to b at x = 1, margin
   (t_2 - 1.5)^2 + (b - 0.2)^2 + 1e-3 over a in [0.5, 2], b in [0, 0.5].

4. The compiled path (issue 42): an indicator-only bouncing ball (its sets
   written as comparisons, no guard: the guards are derived), theta = (h0,
   v0, e): d t_k / d h0 and d t_k / d e for 10 bounces against the closed
   form at rtol 1e-6, 1e-8, 1e-10 on the Python and compiled paths, then
   1,000 runs (h0 spread over [0.5, 1.5], each ``simulate_sensitivity`` of
   a factory, as a user's loop is) on each path, the ratio measured in the
   same run (the compiled maps compiled before the clock starts).

Times are the best of ``--repeat`` (5; 3 with ``--quick``).

Run: ``python benchmarks/bench_sensitivity.py [--quick]``
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import hybridsim as hs
from hybridsim.library import BouncingBall, bouncing_ball_jump_times

G, E, H0, K = 9.81, 0.8, 1.0, 30


class BallJ(BouncingBall):
    """The ball with its Jacobians written out."""

    def flow_jacobian(self, x):
        return np.array([[0.0, 1.0], [0.0, 0.0]])

    def jump_jacobian(self, x):
        return np.array([[0.0, 0.0], [0.0, -self.e]])

    def jump_guard_gradient(self, x):
        return np.array([-1.0, 0.0])


def best(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def closed_forms():
    k = np.arange(1, K + 2)
    t1 = np.sqrt(2 * H0 / G)
    tk = bouncing_ball_jump_times(H0, K + 1, G, E)
    dt_dh0 = tk / (2 * H0)
    dt_de = t1 * 2 * ((1 - k * E ** (k - 1)) * (1 - E) + (E - E ** k)) / (1 - E) ** 2
    T = tk[K - 1] + 0.25 * (tk[K] - tk[K - 1])
    s, v, dv = T - tk[K - 1], E ** K * G * t1, K * E ** (K - 1) * G * t1
    dx_de = np.array([dv * s + (G * s - v) * dt_de[K - 1], dv + G * dt_de[K - 1]])
    return T, dt_dh0[:K], dt_de[:K], dx_de


def rel(a, b):
    """Largest relative difference (the exact zero d t_1 / d e compared absolutely)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1.0 * (b == 0))))


def ball_rows(repeat):
    T, dt_dh0, dt_de, dx_de = closed_forms()
    print("1. 30-bounce ball, theta = (h0, v0, e): largest relative error against the "
          "closed forms, best time of", repeat)
    print(f"{'rtol':>6} | {'what':34} | {'time':>8} | {'vs simulate':>11} | "
          f"{'dt/dh0':>8} | {'dt/de':>8} | {'dx(T)/de':>8}")
    out = []
    for rtol in (1e-6, 1e-8, 1e-10):
        opts = dict(t_max=T, j_max=K + 1, rtol=rtol)
        t_sim, _ = best(lambda opts=opts: hs.simulate(BouncingBall(G, E), [H0, 0.0], **opts),
                        repeat)

        def sens(cls, opts=opts):
            return hs.simulate_sensitivity(lambda p: cls(G, p[0]), [H0, 0.0], params=[E],
                                           **opts)

        def fd_runs(opts=opts):
            # central differences of whole runs, step 1e-6 relative
            th = np.array([H0, 0.0, E])
            cols = []
            for k in range(3):
                h = 1e-6 * max(1.0, abs(th[k]))
                vals = []
                for sgn in (1, -1):
                    q = th.copy()
                    q[k] += sgn * h
                    arc = hs.simulate(BouncingBall(G, q[2]), q[:2], **opts)
                    vals.append(np.concatenate([arc.jump_times, arc.xf]))
                cols.append((vals[0] - vals[1]) / (2 * h))
            return np.array(cols).T
        for name, fn in (("simulate_sensitivity (FD Jacobians)", lambda: sens(BouncingBall)),
                         ("simulate_sensitivity (Jacobians given)", lambda: sens(BallJ))):
            t, sarc = best(fn, repeat)
            e = (rel(sarc.dtj_dx0[:, 0], dt_dh0), rel(sarc.dtj_dp[:, 0], dt_de),
                 rel(sarc.dx_dp[-1, :, 0], dx_de))
            print(f"{rtol:6.0e} | {name[:34]:34} | {t * 1e3:6.2f}ms | {t / t_sim:10.1f}x | "
                  f"{e[0]:8.1e} | {e[1]:8.1e} | {e[2]:8.1e}")
            out.append((rtol, name, t, t_sim, e))
        t_fd, D = best(fd_runs, repeat)
        e = (rel(D[:K, 0], dt_dh0), rel(D[:K, 2], dt_de), rel(D[K:, 2], dx_de))
        print(f"{rtol:6.0e} | {'baseline: FD of 6 whole runs':34} | {t_fd * 1e3:6.2f}ms | "
              f"{t_fd / t_sim:10.1f}x | {e[0]:8.1e} | {e[1]:8.1e} | {e[2]:8.1e}")
        print(f"{rtol:6.0e} | {'baseline: hs.simulate (state only)':34} | "
              f"{t_sim * 1e3:6.2f}ms | {1.0:10.1f}x |")
        out.append((rtol, "fd", t_fd, t_sim, e))
    worst = max(max(r[4]) for r in out if r[1] != "fd")
    fd_worst = max(max(r[4]) for r in out if r[1] == "fd")
    t_s = [r[2] / r[3] for r in out if r[1].endswith("(FD Jacobians)")]
    t_f = [r[2] / r[3] for r in out if r[1] == "fd"]
    print(f"RESULT 30-bounce ball sensitivities: worst relative error {worst:.1e} at rtol "
          f"1e-6..1e-10 (target 1e-9); central differences of whole runs {fd_worst:.1e}; "
          f"cost {min(t_s):.1f}-{max(t_s):.1f}x a plain simulate (FD of runs "
          f"{min(t_f):.1f}-{max(t_f):.1f}x)")


def covariance_row(repeat, N=1000):
    P0 = np.diag([0.005 ** 2, 0.01 ** 2])
    tk = bouncing_ball_jump_times(H0, 6)
    T = tk[4] + 0.25 * (tk[5] - tk[4])

    def linear():
        sarc = hs.simulate_sensitivity(BouncingBall(), [H0, 0.0], t_max=T)
        return sarc.covariance(P0, T)

    rng = np.random.default_rng(26)
    x0s = rng.multivariate_normal([H0, 0.0], P0, size=N)

    def monte_carlo():
        arcs = hs.simulate_many(BouncingBall(vectorized=True), x0s, t_max=T, progress=False)
        return np.cov(np.array([a.xf for a in arcs]).T)

    t_lin, P = best(linear, repeat)
    t_mc, Pmc = best(monte_carlo, max(1, repeat // 2))
    se = np.sqrt((np.outer(np.diag(Pmc), np.diag(Pmc)) + Pmc ** 2) / (N - 1))
    z = float(np.max(np.abs(P - Pmc) / se))
    print(f"\n2. covariance through 5 jumps: linearised S P0 S^T {t_lin * 1e3:.2f} ms; "
          f"Monte Carlo of {N} runs (vectorized simulate_many) {t_mc * 1e3:.1f} ms; "
          f"ratio {t_lin / t_mc:.3f}x")
    print(f"   largest difference {z:.2f} Monte Carlo standard errors\n   linear {P.ravel()}"
          f"\n   Monte Carlo {Pmc.ravel()}")
    print(f"RESULT covariance through jumps: linearised {t_lin * 1e3:.2f} ms vs Monte Carlo "
          f"of {N} runs {t_mc * 1e3:.1f} ms ({t_lin / t_mc:.3f}x), agree within "
          f"{z:.2f} standard errors")


def _rate_reset(p):
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([p[0]]), jump_map=lambda x: np.array([p[1]]),
        jump_guard=lambda x: x[0] - 1.0, state_dim=1)


def _valley(arc):
    b = arc.x[arc.is_jump_end][0, 0]
    return (arc.jump_times[1] - 1.5) ** 2 + (b - 0.2) ** 2 + 1e-3


def falsify_row(repeat):
    from hybridsim.falsification import Interval, Space, falsify

    def run(pt):
        return hs.simulate(_rate_reset(pt.z), [0.0], t_max=5.0, j_max=2)
    calls = [0]

    def sens(pt):
        calls[0] += 1
        return hs.simulate_sensitivity(_rate_reset, [0.0], t_max=5.0, j_max=2, params=pt.z,
                                       wrt="params")
    run.sensitivity = sens
    space = Space(a=Interval(0.5, 2.0), b=Interval(0.0, 0.5))
    print("\n3. falsify refinement, budget 150, seed 1: margin above its minimum 1e-3")
    res = {}
    for refine in (True, "gradient"):
        calls[0] = 0
        t, r = best(lambda refine=refine: falsify(run, space, _valley, budget=150, seed=1,
                                                  refine=refine, stop=False, progress=False),
                    repeat)
        name = "gradient (L-BFGS-B)" if refine == "gradient" else "compass (default)"
        res[refine] = r.margin - 1e-3
        print(f"   {name:20s} {r.margin - 1e-3:9.2e} at {r.point}, {t * 1e3:6.1f} ms, "
              f"{calls[0] // repeat} sensitivity runs")
    print(f"RESULT falsify refine='gradient': margin {res['gradient']:.1e} above the "
          f"minimum vs compass search {res[True]:.1e} (same 150 runs, seed)")


class IndicatorBall(hs.HybridSystem):
    """The ball given by its sets only (no guard written)."""

    state_dim = 2

    def __init__(self, e=E):
        self.e = e

    def flow_map(self, x):
        return np.array([x[1], -G])

    def jump_map(self, x):
        return np.array([0.0, -self.e * x[1]])

    def flow_set(self, x):
        return x[0] >= 0

    def jump_set(self, x):
        return x[0] <= 0 and x[1] <= 0


def _indicator_ball(p):
    return IndicatorBall(p[0])


def compiled_rows(runs):
    from hybridsim.compiled import available
    if not available():
        print("\n4. compiled path: numba is not installed; skipped")
        return
    K10 = 10
    k = np.arange(1, K10 + 1)
    t1 = np.sqrt(2 * H0 / G)
    tk = bouncing_ball_jump_times(H0, K10, G, E)
    dt_dh0 = tk / (2 * H0)
    dt_de = t1 * 2 * ((1 - k * E ** (k - 1)) * (1 - E) + (E - E ** k)) / (1 - E) ** 2
    opts = dict(t_max=tk[-1] + 0.1, j_max=K10, params=[E])
    print("\n4. indicator-only ball (guards derived), 10 bounces: largest relative error "
          "against the closed form")
    t0 = time.perf_counter()
    hs.simulate_sensitivity(_indicator_ball, [H0, 0.0], backend="compiled", **opts)
    print(f"   first compiled call (maps compiled in this process): "
          f"{time.perf_counter() - t0:.1f} s")
    worst = 0.0
    for rtol in (1e-6, 1e-8, 1e-10):
        for backend in ("python", "compiled"):
            sarc = hs.simulate_sensitivity(_indicator_ball, [H0, 0.0], rtol=rtol,
                                           backend=backend, **opts)
            e = (rel(sarc.dtj_dx0[:, 0], dt_dh0), rel(sarc.dtj_dp[:, 0], dt_de))
            worst = max(worst, *e)
            print(f"   rtol {rtol:6.0e} {backend:9s} dt/dh0 {e[0]:8.1e}  dt/de {e[1]:8.1e}")
    h0s = np.linspace(0.5, 1.5, runs)
    opts["t_max"] = 10.0
    times, dts = {}, {}
    for backend in ("python", "compiled"):
        t0 = time.perf_counter()
        dts[backend] = [hs.simulate_sensitivity(_indicator_ball, [h, 0.0], backend=backend,
                                                **opts).dtj_dtheta for h in h0s]
        times[backend] = time.perf_counter() - t0
    agree = max(float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300 + (b == 0))))
                for a, b in zip(dts["python"], dts["compiled"]))
    ratio = times["python"] / times["compiled"]
    print(f"   {runs} runs: Python {times['python']:.2f} s "
          f"({times['python'] / runs * 1e3:.2f} ms/run), compiled {times['compiled']:.2f} s "
          f"({times['compiled'] / runs * 1e3:.2f} ms/run); paths agree to {agree:.1e} "
          f"relative")
    print(f"RESULT compiled sensitivities: closed form to {worst:.1e} relative on both paths "
          f"at rtol 1e-6..1e-10 (target 1e-9); {runs} runs {ratio:.1f}x faster compiled than "
          f"Python (target 10x)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 repeats instead of 5")
    ap.add_argument("--repeat", type=int, default=None)
    ap.add_argument("--only-compiled", action="store_true",
                    help="only part 4 (the compiled path)")
    a = ap.parse_args(argv)
    repeat = a.repeat or (3 if a.quick else 5)
    if not a.only_compiled:
        ball_rows(repeat)
        covariance_row(repeat)
        falsify_row(repeat)
    compiled_rows(200 if a.quick else 1000)


if __name__ == "__main__":
    main()
