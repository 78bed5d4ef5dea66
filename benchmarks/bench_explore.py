"""Explore benchmark: 4,096 leaves of a system that branches at every jump.

(tau, z): tau' = 1, z' = -z; at tau = 1 the jump map offers two successors,
z+ in {z + 1, z - 1} (tau+ = 0). Twelve jumps give 2^12 = 4,096 solutions
(no two meet: merging is off). ``hs.explore`` builds the tree; the baseline,
measured in the same run, is a loop of ``hs.simulate`` over every choice
sequence (each sequence a system whose jump map follows it: 4,096 runs of 12
jumps). Prints both wall times, their ratio, the leaves' agreement with the
baseline's end states, and the tree's memory per leaf (tracemalloc) at two
depths (linear in the leaves: the same per leaf).

Run: ``python benchmarks/bench_explore.py [--jumps 12] [--quick]``
"""
from __future__ import annotations

import argparse
import itertools
import platform
import time
import tracemalloc

import numpy as np

import hybridsim as hs


def brancher():
    return hs.HybridSystem.from_functions(
        f=lambda x: np.array([1.0, -x[1]]), C=lambda x: x[0] <= 1.0,
        D=lambda x: x[0] >= 1.0, jump_guard=lambda x: x[0] - 1.0,
        g_values=lambda x: [np.array([0.0, x[1] + 1.0]), np.array([0.0, x[1] - 1.0])],
        state_dim=2)


def follow(seq):
    """The same data with a single-valued jump map following ``seq``."""
    it = iter(seq)
    return hs.HybridSystem.from_functions(
        f=lambda x: np.array([1.0, -x[1]]), C=lambda x: x[0] <= 1.0,
        D=lambda x: x[0] >= 1.0, jump_guard=lambda x: x[0] - 1.0,
        g=lambda x: np.array([0.0, x[1] + next(it)]), state_dim=2)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--jumps", type=int, default=12)
    ap.add_argument("--quick", action="store_true", help="10 jumps: 1,024 leaves")
    args = ap.parse_args()
    J = 10 if args.quick else args.jumps
    t_max = J + 0.5
    print(f"{platform.python_version()} on {platform.machine()}, {J} jumps, "
          f"{2 ** J} leaves")

    t = time.perf_counter()
    tree = hs.explore(brancher(), [0.0, 0.0], t_max, J, merge_tol=None,
                      max_seconds=600.0)
    leaves = tree.leaves
    t_explore = time.perf_counter() - t

    t = time.perf_counter()
    ends = [hs.simulate(follow(seq), [0.0, 0.0], t_max, J).xf
            for seq in itertools.product((1.0, -1.0), repeat=J)]
    t_loop = time.perf_counter() - t

    a = np.array(sorted(tuple(x) for x in (arc.xf for arc in leaves)))
    b = np.array(sorted(tuple(x) for x in ends))
    err = float(np.max(np.abs(a - b))) if a.shape == b.shape else float("nan")
    print(f"explore:          {t_explore:8.3f} s  ({len(leaves)} leaves, "
          f"{len(tree.nodes)} branches)")
    print(f"loop of simulate: {t_loop:8.3f} s  ({len(ends)} runs)  [baseline]")
    print(f"explore / loop:   {t_explore / t_loop:8.3f}")
    print(f"largest difference of the end states: {err:.1e}")

    for depth in (J - 2, J):
        tracemalloc.start()
        tr = hs.explore(brancher(), [0.0, 0.0], depth + 0.5, depth, merge_tol=None,
                        max_seconds=600.0)
        _ = tr.leaves
        cur, _peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"memory at {len(tr):5d} leaves: {cur / 2 ** 20:7.2f} MiB "
              f"({cur / len(tr) / 1024:6.2f} KiB per leaf)")


if __name__ == "__main__":
    main()
