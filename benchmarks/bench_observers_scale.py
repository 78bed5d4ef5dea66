"""Observers at scale: a Monte Carlo of Li-Sanfelice's H_c and the cost of the
distributed observer against the number of nodes.

Usage: ``python benchmarks/bench_observers_scale.py [--quick]``

1. H_c (17)-(18) on a seeded random observable design with n = 4, p = 2,
   over 1,000 bounded random noise realisations (``--quick``: 100), through
   ``hybridsim.simulate_many`` (each realisation is the initial state of a
   noise generator inside the interconnection). Prints wall time, time per
   run, the peak memory of the batch (tracemalloc) and the error after the
   jump. Baseline in the same run: the same batch with H_n (no m̂ update).
   Also a Monte Carlo of the distributed observer (ring of 8 nodes, 30
   band-limited noise realisations through ``hybridsim.sweep``): wall time
   and peak memory.
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


def hc_monte_carlo(N, seed=0):
    design = ls.random_design(seed, 4, 2)
    rows = []
    for name, Obs in (("H_c", ls.ConstantNoiseObserver), ("H_n", ls.NominalObserver)):
        obs = Obs(design)
        gen = ls.BoundedNoiseGenerator(design.p, 3)
        S = gen.random_states(N, 0.1, w_max=5.0, seed=seed)
        rng = np.random.default_rng(seed + 1)
        sysm, x0s = ls.noise_batch(obs, rng.normal(size=4), np.zeros(4), S, gen)
        tracemalloc.start()
        t0 = time.perf_counter()
        arcs = hs.simulate_many(sysm, x0s, t_max=1.5 * design.delta, method="DOP853",
                                rtol=1e-10, atol=1e-12)
        wall = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        err = []
        for arc in arcs:
            k = np.flatnonzero(arc.j == 1)[0]
            err.append(np.linalg.norm(arc["observer"].x[k, :4] - arc["plant"].x[k]))
        rows.append((name, wall, peak, np.median(err), np.max(err), sum(len(a) for a in arcs)))
    print(f"H_c Monte Carlo: n = 4, p = 2, delta = {design.delta}, N = {N} noise realisations "
          "(|m| <= 0.1, sums of 3 sinusoids)")
    print(f"{'observer':8s} {'wall s':>8s} {'ms/run':>8s} {'peak MB':>8s} {'samples':>8s} "
          f"{'median|e+|':>11s} {'max|e+|':>9s}")
    for name, wall, peak, med, mx, ns in rows:
        print(f"{name:8s} {wall:8.2f} {1e3 * wall / N:8.2f} {peak / 2**20:8.1f} {ns:8d} "
              f"{med:11.3e} {mx:9.3e}")
    print(f"RESULT H_c Monte Carlo N={N}: {rows[0][1]:.1f} s, peak {rows[0][2] / 2**20:.1f} MB "
          f"(H_n baseline {rows[1][1]:.1f} s, ratio {rows[0][1] / rows[1][1]:.2f})")


def distributed_monte_carlo(R, N=8, t_sim=1.0):
    """R noise realisations of the N-node ring observer, via hs.sweep."""
    A, C, G = dist.random_system(N, seed=1, graph="ring")
    dsg = dist.design(A, C, G, warn=False)
    x0 = dist.initial_state(dsg, np.random.default_rng(0).normal(size=A.shape[0]))
    p = sum(np.atleast_2d(c).shape[0] for c in C.values())

    def make(seed):
        return dist.observer_network(dsg, noise=dist.band_limited_noise(1e-4, 0.1, t_sim, p, seed))

    tracemalloc.start()
    t0 = time.perf_counter()
    arcs = hs.sweep(make, range(R), x0, t_max=t_sim, rtol=1e-8, atol=1e-10)
    wall = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    final = [dist.transformed_errors(a, dsg)["norm"][-1] for a in arcs]
    print(f"\nDistributed observer Monte Carlo: ring of N = {N} nodes, {R} band-limited noise "
          f"realisations (power 1e-4), {t_sim} s each")
    print(f"  wall {wall:.2f} s ({1e3 * wall / R:.1f} ms/run), peak {peak / 2**20:.1f} MB, "
          f"final error median {np.median(final):.2e}, max {np.max(final):.2e}")
    print(f"RESULT distributed Monte Carlo R={R}, N={N}: {wall:.1f} s, peak {peak / 2**20:.1f} MB")


def distributed_scaling(sizes, t_sim=1.0):
    print(f"\nDistributed finite-time observer, {t_sim} simulated second(s), RK45 rtol 1e-8")
    print(f"{'graph':>8s} {'N':>4s} {'edges':>6s} {'steps':>6s} {'s/sim s':>8s} "
          f"{'ms/step':>8s} {'us/step/node':>13s} {'us/step/edge':>13s}")
    per_node = []
    for graph in ("ring", "random"):
        for N in sizes:
            A, C, G = dist.random_system(N, seed=1, graph=graph, p_edge=0.3)
            dsg = dist.design(A, C, G, warn=False)
            x0 = np.random.default_rng(0).normal(size=A.shape[0])
            t0 = time.perf_counter()
            arc = dist.simulate_network(dsg, x0, t_max=t_sim, rtol=1e-8, atol=1e-10)
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
    distributed_monte_carlo(4 if a.quick else 30)
    distributed_scaling([4, 8, 16] if a.quick else [4, 8, 16, 32])


if __name__ == "__main__":
    main()
