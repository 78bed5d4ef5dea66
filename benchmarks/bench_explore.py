"""Explore benchmark: 4,096 leaves of a tree that doubles at every jump.

The doubling tree (issue 42): (x, tau) with x' = 0, tau' = 1; every 0.1 s
(tau = 0.1) the set-valued jump map offers x+ in {2x, 2x + 1} (tau+ = 0).
Twelve jumps give 2^12 = 4,096 solutions, ending at x = 0, 1, ..., 4095
(merging off). The model is a plain class (its maps as a user writes them).

Rows, in one run:

* ``explore, compiled``: ``hs.explore(backend="auto")``: its levels run as
  compiled batches (the model's maps compiled from its source; the first
  call's compile is timed apart, as a warm-up);
* ``explore, python``: ``backend="python"``, each branch its own run of
  ``hs.simulate`` (what explore did before);
* the baseline: a loop of ``hs.simulate`` over every choice sequence (each
  sequence a system whose single-valued jump map follows it: 4,096 runs of
  12 jumps).

Each explore row includes building the leaves (``tree.leaves``: 4,096 arcs
from x0). Prints the wall times, the ratios to the baseline, whether the two
trees are the same (nodes, ends, merges) and the largest difference of
their samples, the leaves' agreement with the baseline's end states, and the
tree's memory per leaf (tracemalloc) at two depths.

Run: ``python benchmarks/bench_explore.py [--jumps 12] [--quick]``
(``--quick``: 10 jumps, 1,024 leaves).
"""
from __future__ import annotations

import argparse
import itertools
import os
import platform
import time
import tracemalloc

import numpy as np

import hybridsim as hs

PERIOD = 0.1


class Doubling(hs.HybridSystem):
    """x+ in {2x, 2x + 1} every PERIOD seconds (a timer tau)."""

    state_dim = 2

    def flow_map(self, x):
        return np.array([0.0, 1.0])

    def jump_map_values(self, x):
        return [np.array([2.0 * x[0], 0.0]), np.array([2.0 * x[0] + 1.0, 0.0])]

    def flow_set(self, x):
        return x[1] <= PERIOD

    def jump_set(self, x):
        return x[1] >= PERIOD


class Following(Doubling):
    """The same data, the jump map following one choice sequence."""

    jump_map_values = None

    def __init__(self, seq):
        self.seq = iter(seq)

    def jump_map(self, x):
        return np.array([2.0 * x[0] + next(self.seq), 0.0])


def timed_explore(J, backend):
    t = time.perf_counter()
    tree = hs.explore(Doubling(), [0.0, 0.0], J * PERIOD + 0.05, J, merge_tol=None,
                      max_seconds=900.0, backend=backend)
    leaves = tree.leaves
    return time.perf_counter() - t, tree, leaves


def same_trees(a, b):
    shape = [(n.parent, n.end, n.merged_into, n.children) for n in a.nodes] == \
        [(n.parent, n.end, n.merged_into, n.children) for n in b.nodes]
    dx = 0.0
    for u, v in zip(a.leaves, b.leaves, strict=True):
        if u.x.shape != v.x.shape:
            return shape, float("inf")
        dx = max(dx, float(np.max(np.abs(u.x - v.x))), float(np.max(np.abs(u.t - v.t))))
    return shape and a.merges == b.merges, dx


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--jumps", type=int, default=12)
    ap.add_argument("--quick", action="store_true", help="10 jumps: 1,024 leaves")
    args = ap.parse_args()
    J = 10 if args.quick else args.jumps
    t_max = J * PERIOD + 0.05
    print(f"{platform.python_version()} on {platform.machine()}, {os.cpu_count()} cores, "
          f"{J} jumps, {2 ** J} leaves")

    t = time.perf_counter()
    hs.explore(Doubling(), [0.0, 0.0], 3 * PERIOD + 0.05, 3, backend="compiled")
    print(f"warm-up (the model's maps compiled, or loaded from the disk cache): "
          f"{time.perf_counter() - t:.2f} s")

    t_c, tree_c, leaves_c = timed_explore(J, "auto")
    t_p, tree_p, _ = timed_explore(J, "python")

    t = time.perf_counter()
    ends = [hs.simulate(Following(seq), [0.0, 0.0], t_max, J).xf
            for seq in itertools.product((0.0, 1.0), repeat=J)]
    t_loop = time.perf_counter() - t

    same, dx = same_trees(tree_c, tree_p)
    a = np.array(sorted(tuple(x) for x in (arc.xf for arc in leaves_c)))
    b = np.array(sorted(tuple(x) for x in ends))
    err = float(np.max(np.abs(a - b))) if a.shape == b.shape else float("nan")
    print(f"explore, compiled: {t_c:8.3f} s  ({len(leaves_c)} leaves, "
          f"{len(tree_c.nodes)} branches)")
    print(f"explore, python:   {t_p:8.3f} s")
    print(f"loop of simulate:  {t_loop:8.3f} s  ({len(ends)} runs)  [baseline]")
    print(f"explore compiled / loop: {t_c / t_loop:7.3f}   (issue 42's figure: <= 0.05)")
    print(f"explore python / loop:   {t_p / t_loop:7.3f}")
    print(f"explore compiled / explore python: {t_c / t_p:7.3f}")
    print(f"the two trees the same: {same}; largest difference of their samples: {dx:.1e}")
    print(f"largest difference of the end states from the loop's: {err:.1e}")
    print(f"RESULT explore, doubling tree of {len(leaves_c):,} leaves: compiled batches "
          f"{t_c:.2f} s vs a loop of simulate over every choice sequence {t_loop:.1f} s | "
          f"{t_c / t_loop:.3f}x (branch by branch: {t_p:.2f} s, {t_p / t_loop:.3f}x); "
          f"same tree: {same}, samples within {dx:.0e}")

    for depth in (J - 2, J):
        tracemalloc.start()
        tr = hs.explore(Doubling(), [0.0, 0.0], depth * PERIOD + 0.05, depth,
                        merge_tol=None, max_seconds=900.0)
        _ = tr.leaves
        cur, _peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"memory at {len(tr):5d} leaves: {cur / 2 ** 20:7.2f} MiB "
              f"({cur / len(tr) / 1024:6.2f} KiB per leaf)")


if __name__ == "__main__":
    main()
