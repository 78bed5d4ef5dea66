"""Observers at scale: a Monte Carlo of Li-Sanfelice's H_c and the cost of the
distributed observer against the number of nodes.

Usage: ``python benchmarks/bench_observers_scale.py [--quick]``

1. H_c (17)-(18) on a seeded random observable design with n = 4, p = 2,
   over 1,000 bounded random noise realisations (``--quick``: 100), through
   ``hybridsim.simulate_many`` (each realisation is the initial state of a
   noise generator inside the interconnection; every component is
   vectorized, so the batch is one numpy integration). Baseline in the same
   run: the per-run path (DOP853, a loop of ``simulate``) on the first 50
   rows, with the errors after the jump compared row by row; H_n likewise;
   and the same batch vectorized with ``method="DOP853"``.
   Also a Monte Carlo of the distributed observer (ring of 8 nodes, 30
   band-limited noise realisations): ``noise_batch``
   through ``simulate_many`` against ``hybridsim.sweep`` over per-seed
   networks. Times are untraced; peak memory comes from a separate run
   under tracemalloc (which slows Python about 4x).
2. The distributed finite-time observer (7)-(8) over directed rings of
   N = 4, 8, 16, 32 nodes (``--quick``: up to 16) and random strongly
   connected digraphs: wall time per simulated second and per accepted
   step, against the number of edges (the consensus terms are one per edge).
"""
import argparse
import time
import tracemalloc

import numpy as np

import hybridsim as hs
from observers import distributed as dist
from observers import li_sanfelice as ls
from observers.distributed.example import band_limited_noise, random_system
from observers.distributed.example import noise_batch as dist_noise_batch
from observers.distributed.systems import initial_state, observer_network
from observers.li_sanfelice.design import random_design
from observers.li_sanfelice.example import noise_batch as ls_noise_batch
from observers.li_sanfelice.systems import BoundedNoiseGenerator


def _traced(fn, *args, **kw):
    """(result, peak MB) of fn(...) under tracemalloc (timed apart: tracing slows Python)."""
    tracemalloc.start()
    try:
        out = fn(*args, **kw)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return out, peak / 2**20


def _timed(fn, *args, **kw):
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t0


def hc_monte_carlo(N, seed=0, n_slow=50):
    """H_c and H_n over N noise realisations: the vectorized batch (one numpy integration of
    all rows, RK45) against the per-run path (DOP853, rtol 1e-10, on the first n_slow rows,
    the path the study used before), same seeds; errors after the jump compared row by row."""
    design = random_design(seed, 4, 2)
    rows = []
    for name, Obs in (("H_c", ls.ConstantNoiseObserver), ("H_n", ls.NominalObserver)):
        obs = Obs(design)
        gen = BoundedNoiseGenerator(design.p, 3)
        S = gen.random_states(N, 0.1, w_max=5.0, seed=seed)
        rng = np.random.default_rng(seed + 1)
        sysm, x0s = ls_noise_batch(obs, rng.normal(size=4), np.zeros(4), S, gen)
        kw = dict(t_max=1.5 * design.delta, rtol=1e-10, atol=1e-12)

        def err(arcs):
            out = []
            for arc in arcs:
                k = np.flatnonzero(arc.j == 1)[0]
                out.append(np.linalg.norm(arc["observer"].x[k, :4] - arc["plant"].x[k]))
            return np.array(out)

        fast, wall = _timed(hs.simulate_many, sysm, x0s, **kw)
        _, peak = _traced(hs.simulate_many, sysm, x0s[:min(N, 100)], **kw)
        fast8, wall8 = _timed(hs.simulate_many, sysm, x0s, method="DOP853", **kw)
        slow, wall_slow = _timed(_per_run, sysm, x0s[:n_slow], method="DOP853", **kw)
        e_fast, e_slow, e8 = err(fast), err(slow), err(fast8)
        dev = np.max(np.abs(e_fast[:n_slow] - e_slow) / e_slow)
        dev8 = np.max(np.abs(e8[:n_slow] - e_slow) / e_slow)
        rows.append((name, wall, 1e3 * wall_slow / n_slow, peak, np.median(e_fast),
                     np.max(e_fast), np.median(e_slow), dev, wall8, dev8))
    print(f"H_c Monte Carlo: n = 4, p = 2, delta = {design.delta}, N = {N} noise realisations "
          "(|m| <= 0.1, sums of 3 sinusoids); vectorized batch (RK45, rtol 1e-10) vs the "
          f"per-run path (DOP853, rtol 1e-10) on the first {n_slow} rows, same seeds")
    print(f"{'observer':8s} {'batch s':>8s} {'ms/run':>7s} {'per-run ms':>10s} {'speed-up':>8s} "
          f"{'peak MB':>8s} {'median|e+|':>11s} {'max|e+|':>9s} {'med of ' + str(n_slow):>11s} "
          f"{'max rel dev':>11s} {'DOP853 s':>8s} {'its dev':>8s}")
    for name, wall, ms_slow, peak, med, mx, med_slow, dev, wall8, dev8 in rows:
        ms = 1e3 * wall / N
        print(f"{name:8s} {wall:8.2f} {ms:7.2f} {ms_slow:10.2f} {ms_slow / ms:7.1f}x "
              f"{peak:8.1f} {med:11.3e} {mx:9.3e} {med_slow:11.3e} {dev:11.1e} {wall8:8.2f} "
              f"{dev8:8.1e}")
    print("DOP853 s: the same batch vectorized with method='DOP853'; its dev: against the "
          "per-run DOP853 runs")
    name, wall, ms_slow, peak, med, mx, med_slow, dev, wall8, dev8 = rows[0]
    print(f"RESULT H_c Monte Carlo N={N}: {wall:.2f} s vectorized ({1e3 * wall / N:.2f} ms/run; "
          f"per-run DOP853 path {ms_slow:.1f} ms/run, {ms_slow * N / 1e3:.1f} s for N, "
          f"{ms_slow / (1e3 * wall / N):.1f}x), |e+| equal to {dev:.0e} relative; vectorized "
          f"with DOP853 {wall8:.2f} s ({wall / wall8:.1f}x RK45's), equal to the per-run "
          f"DOP853 runs to {dev8:.0e} relative")


def _per_run(system, x0s, **kw):
    """A loop of ``hs.simulate``: the per-run path, one row at a time."""
    return [hs.simulate(system, x, **kw) for x in x0s]


def distributed_monte_carlo(R, N=8, t_sim=1.0):
    """R noise realisations of the N-node ring observer: noise_batch through simulate_many
    (vectorized) against hs.sweep over per-seed networks with a callable noise (the per-run
    path), same seeds; final errors compared row by row."""
    A, C, G = random_system(N, seed=1, graph="ring")
    dsg = dist.design(A, C, G, warn=False)
    x0 = np.random.default_rng(0).normal(size=A.shape[0])
    p = sum(np.atleast_2d(c).shape[0] for c in C.values())
    kw = dict(t_max=t_sim, rtol=1e-8, atol=1e-10)
    sysm, X = dist_noise_batch(dist.DistributedObserver(dsg), x0, power=1e-4, seeds=range(R),
                               t_max=t_sim)

    def make(seed):
        return observer_network(dsg, noise=band_limited_noise(1e-4, 0.1, t_sim, p, seed))

    fast, wall = _timed(hs.simulate_many, sysm, X, **kw)
    _, peak = _traced(hs.simulate_many, sysm, X, **kw)
    slow, wall_slow = _timed(hs.sweep, make, range(R), initial_state(dsg, x0), **kw)
    obs = dist.DistributedObserver(dsg)
    f_fast = np.array([dist.errors(a, obs)["norm"][-1] for a in fast])
    f_slow = np.array([dist.errors(a, obs)["norm"][-1] for a in slow])
    dev = np.max(np.abs(f_fast - f_slow) / f_slow)
    print(f"\nDistributed observer Monte Carlo: ring of N = {N} nodes, {R} band-limited noise "
          f"realisations (power 1e-4), {t_sim} s each, RK45 rtol 1e-8")
    print(f"  vectorized noise_batch: {wall:.2f} s ({1e3 * wall / R:.1f} ms/run), peak "
          f"{peak:.1f} MB; per-run sweep: {wall_slow:.2f} s ({1e3 * wall_slow / R:.1f} ms/run)")
    print(f"  final error median {np.median(f_fast):.4e} (per-run {np.median(f_slow):.4e}), "
          f"max {np.max(f_fast):.4e} (per-run {np.max(f_slow):.4e}); rows equal to "
          f"{dev:.1e} relative")
    print(f"RESULT distributed Monte Carlo R={R}, N={N}: {wall:.2f} s vectorized vs "
          f"{wall_slow:.1f} s per-run ({wall_slow / wall:.1f}x), final errors equal to "
          f"{dev:.0e} relative")


def distributed_scaling(sizes, t_sim=1.0):
    print(f"\nDistributed finite-time observer, {t_sim} simulated second(s), RK45 rtol 1e-8")
    print(f"{'graph':>8s} {'N':>4s} {'edges':>6s} {'steps':>6s} {'s/sim s':>8s} "
          f"{'ms/step':>8s} {'us/step/node':>13s} {'us/step/edge':>13s}")
    per_node = []
    for graph in ("ring", "random"):
        for N in sizes:
            A, C, G = random_system(N, seed=1, graph=graph, p_edge=0.3)
            dsg = dist.design(A, C, G, warn=False)
            x0 = np.random.default_rng(0).normal(size=A.shape[0])
            t0 = time.perf_counter()
            arc = dist.simulate(dist.DistributedObserver(dsg), x0, t_max=t_sim, rtol=1e-8,
                                atol=1e-10)
            wall = time.perf_counter() - t0
            steps = len(arc) - 1
            E = G.number_of_edges()
            per_edge = 1e6 * wall / steps / E
            per_node.append(1e6 * wall / steps / N)
            print(f"{graph:>8s} {N:4d} {E:6d} {steps:6d} {wall / t_sim:8.3f} "
                  f"{1e3 * wall / steps:8.2f} {per_node[-1]:13.1f} {per_edge:13.1f}")
    print(f"RESULT distributed: cost per step grows with the number of nodes "
          f"({min(per_node):.0f}-{max(per_node):.0f} us per node per step), "
          f"never faster than the number of edges")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    hc_monte_carlo(100 if a.quick else 1000)
    distributed_monte_carlo(30)           # the study's size, quick or not
    distributed_scaling([4, 8, 16] if a.quick else [4, 8, 16, 32])


if __name__ == "__main__":
    main()
