"""Finite-time distributed observer (paper 003) on seeded random networks.

For N = 3..8 nodes, directed rings and random strongly connected digraphs:
alpha from LMI (11), simulation of plant + network through hs.simulate,
settling time of max_i |x_hat^i - x| (transformed coordinates) below 1e-10,
final error, and the linear observer (3)'s final error for comparison.

Run: python benchmarks/bench_distributed.py [t_max]
"""
import sys
import time
import warnings

import numpy as np

import observers.distributed as dist
from observers.distributed.design import choose_alpha
from observers.distributed.example import _settling, random_system, stable_initial_state


def main(t_max=10.0):
    print(f"{'N':>2} {'graph':>6} {'n':>2} {'n_i':>18} {'alpha':>5} {'settle':>7} "
          f"{'final':>9} {'linear':>9} {'wall s':>6}")
    for N in range(3, 9):
        for graph in ("ring", "random"):
            seed = 100 * N + (graph == "random")
            A, C, G = random_system(N, seed, graph=graph)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                d0 = dist.design(A, C, G, nodelist=range(N))
                alpha, _ = choose_alpha(d0)
                d = dist.design(A, C, G, nodelist=range(N), alpha=alpha)
                dl = dist.design(A, C, G, nodelist=range(N), alpha=alpha, kind="linear")
            rng = np.random.default_rng(seed)
            x0 = stable_initial_state(A, rng.standard_normal(d.n))
            xh = rng.standard_normal((N, d.n))
            obs, lin = dist.DistributedObserver(d), dist.DistributedObserver(dl)
            t0 = time.perf_counter()
            arc = dist.simulate(obs, x0, xh, t_max=t_max)
            wall = time.perf_counter() - t0
            E = dist.errors(arc, obs)
            El = dist.errors(dist.simulate(lin, x0, xh, t_max=t_max), lin)
            ts = _settling(E.t, E["norm"], 1e-10)
            print(f"{N:>2} {graph:>6} {d.n:>2} {d.n_o!s:>18} {alpha:>5g} {ts:>7.3f} "
                  f"{E['norm'][-1]:>9.2e} {El['norm'][-1]:>9.2e} {wall:>6.1f}")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 10.0)
