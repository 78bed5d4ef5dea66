"""
Every solution of a sampled-data loop with jittery sampling
===========================================================

A sample-and-hold controller whose samples come at irregular times: any gap
between 0.1 and 0.3 time units is possible. The plant x' = x + u is
unstable; the controller holds u = -2 x from the last sample. The state is
(x, u, s), s the time since the last sample::

    x' = x + u,  u' = 0,  s' = 1,          C = {s <= 0.3},
    x+ = x,      u+ = -2 x,  s+ = 0,       D = {s >= 0.1}.

C ∩ D (s in [0.1, 0.3]) is where a sample may come or not: the system is a
hybrid *inclusion*, and a claim about the loop ("every sampling pattern
with gaps in [0.1, 0.3] contracts") is a claim about all its solutions.

* :func:`hybridsim.simulate` with a dwell law (``dwell=``, uniform on
  [0, 0.2] after the entry at s = 0.1) gives one random solution, with the
  same gap distribution at every solver step size;
* :func:`hybridsim.explore` gives every solution for gaps from the grid
  {0.1, 0.2, 0.3}, as a tree, and :mod:`hybridsim.testing` checks the
  contraction on each one. The 3^5 = 243 gap sequences of five samples end
  at 21 distinct points (the loop is linear and time-invariant, so the
  order of the gaps does not change where a solution ends): the tree merges
  them and explores each future once.

Between samples x grows by e^g - 2 (e^g - 1) = 2 - e^g over a gap g, so
|x| shrinks by at least the factor 2 - e^0.1 = 0.895 per sample with gaps
of at most 0.3 (where 2 - e^0.3 = 0.650). The worst solution samples every
0.1: |x(t, j)| <= (2 - e^0.1)^j.

Figure: left, every solution's x against t (branch points marked), with
one random solution of the dwell law; right, every solution's x against
the jump count j under the bound (2 - e^0.1)^j.

Run it with::

    python examples/explore_jittery_sampling.py [output_folder]

The figures go to ``output_folder``, else to the folder named by the
environment variable ``HYBRIDSIM_FIGURES``, else to the working folder.
"""
import os
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy import stats

import hybridsim as hs
from hybridsim import testing

GAP_MIN, GAP_MAX = 0.1, 0.3
RATE = 2.0 - np.exp(GAP_MIN)        # the worst contraction per sample


class JitterySampleAndHold(hs.HybridSystem):
    """x' = x + u with u = -2 x held from the last sample, gaps in [0.1, 0.3]."""

    state_dim = 3

    def flow_map(self, x):
        return np.array([x[0] + x[1], 0.0, 1.0])

    def jump_map(self, x):
        return np.array([x[0], -2.0 * x[0], 0.0])

    # continuous guards: C = {s <= 0.3}, D = {s >= 0.1}, located exactly
    def flow_guard(self, x):
        return GAP_MAX - x[2]

    def jump_guard(self, x):
        return x[2] - GAP_MIN


X0 = [1.0, -2.0, 0.0]       # a sample has just been taken at t = 0


def explore_all(j_max=5):
    """Every solution for gaps from {0.1, 0.2, 0.3} over j_max samples."""
    return hs.explore(JitterySampleAndHold(), X0, t_max=2.0, j_max=j_max,
                      dwell_grid=[GAP_MAX - GAP_MIN - 0.1], rtol=1e-10, atol=1e-12)


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tree = explore_all()
    print(f"{tree}: {len(tree)} solutions, {len(tree.branch_points)} branch points, "
          f"{tree.merges} merged, in {tree.seconds:.2f} s")
    # the claim, over every solution: |x(t, j)| <= (2 - e^0.1)^j
    testing.assert_bounded(tree, lambda x, t, j: x[0], lambda t, j: RATE ** j, rtol=1e-6)
    print(f"every solution: |x(t, j)| <= {RATE:.4f}^j")

    # one random solution: the gap after the entry into C ∩ D uniform on [0, 0.2]
    law = stats.uniform(0.0, GAP_MAX - GAP_MIN)
    rnd = hs.simulate(JitterySampleAndHold(), X0, t_max=2.0, j_max=5, priority="random",
                      dwell=law, seed=3, rtol=1e-10, atol=1e-12)
    print("one random solution's gaps:", np.round(np.diff(rnd.jump_times), 3))

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
    hs.plot_solutions(tree, 0, ax=ax, alpha=0.35)
    hs.plot_flows(rnd, 0, ax=ax, color="C3", labels=["a random solution (dwell law)"])
    ax.set(ylabel="$x$", title="every solution, gaps in {0.1, 0.2, 0.3}")
    ax.legend(loc="upper right", fontsize="small")
    hs.plot_solutions(tree, 0, view="jumps", ax=bx, alpha=0.35)
    js = np.arange(6)
    bx.plot(js, RATE ** js, "k--", label=r"bound $(2 - e^{0.1})^j$ (a sample every 0.1)")
    bx.set(ylabel="$x$ (positive on every solution)", ylim=(0, 1.05),
           title="contraction per sample, every solution")
    bx.legend(loc="lower left", fontsize="small")
    fig.tight_layout()
    fig.savefig(out / "explore_jittery_sampling.png", dpi=100)
    plt.close("all")
    print(f"figures written to {out}")
    return tree, rnd


if __name__ == "__main__":
    # the folder given, else $HYBRIDSIM_FIGURES, else the working folder
    OUT = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HYBRIDSIM_FIGURES", ".")
    TREE, RANDOM = main(OUT)
