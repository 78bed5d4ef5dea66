"""
Every solution of a thermostat whose thresholds overlap
=======================================================

A thermostat as a hybrid *inclusion*: the heater may switch on anywhere in
a band of low temperatures and off anywhere in a band of high ones, rather
than at one threshold. The state is x = (z, q), room temperature z and
heater mode q in {0, 1}::

    zdot = -z + z_out + z_heat * q,
    C = {q = 0, z >= z_on_min} U {q = 1, z <= z_off_max},
    D = {q = 0, z <= z_on_max} U {q = 1, z >= z_off_min},   q+ = 1 - q.

In C ∩ D (z in [z_on_min, z_on_max] with the heater off, or in
[z_off_min, z_off_max] with it on) a solution may switch or keep going;
at the band's far end it must switch. :func:`hybridsim.explore` follows
them all: switch on entering the band, after each dwell of a grid, or at
its end. Every solution stays in [z_on_min, z_off_max] once it is there,
the claim checked over every leaf by :mod:`hybridsim.testing`.

Figure: all solutions' temperatures on one set of axes, the branch points
(where the tree splits) marked.

Run it with::

    python examples/explore_thermostat.py [output_folder]

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

import hybridsim as hs
from hybridsim import testing

Z_OUT, Z_HEAT = 60.0, 30.0
Z_ON = (70.0, 71.0)         # the heater may switch on in this band (must at 70)
Z_OFF = (79.0, 80.0)        # and off in this one (must at 80)
Z_LOW, Z_HIGH = Z_ON[0], Z_OFF[1]
T_IN = 0.7                  # from z0 = 65 the heater has brought z into the band


class OverlappingThermostat(hs.HybridSystem):
    state_dim = 2

    def flow_map(self, x):
        return np.array([-x[0] + Z_OUT + Z_HEAT * x[1], 0.0])

    def jump_map(self, x):
        return np.array([x[0], 1.0 - x[1]])

    def flow_set(self, x):
        return bool(x[0] <= Z_OFF[1]) if x[1] > 0.5 else bool(x[0] >= Z_ON[0])

    def jump_set(self, x):
        return bool(x[0] >= Z_OFF[0]) if x[1] > 0.5 else bool(x[0] <= Z_ON[1])

    # continuous guards: exact event location at the bands' edges
    def jump_guard(self, x):
        return x[0] - Z_OFF[0] if x[1] > 0.5 else Z_ON[1] - x[0]

    def flow_guard(self, x):
        return Z_OFF[1] - x[0] if x[1] > 0.5 else x[0] - Z_ON[0]


def explore_all(t_max=2.5, j_max=4):
    """Every solution from z = 65 with the heater on, switching after dwells
    of 0 (at once), 0.05, or at the band's end."""
    return hs.explore(OverlappingThermostat(), [65.0, 1.0], t_max=t_max, j_max=j_max,
                      dwell_grid=[0.05], rtol=1e-10, atol=1e-12, merge_tol=1e-7)


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tree = explore_all()
    print(f"{tree}: {len(tree)} solutions, {len(tree.branch_points)} branch points, "
          f"{tree.merges} merged, in {tree.seconds:.2f} s")
    # the claim, over every solution: the temperature stays in the band once in it
    testing.assert_bounded(tree, lambda x, t, j: abs(x[0] - (Z_LOW + Z_HIGH) / 2),
                           (Z_HIGH - Z_LOW) / 2, atol=1e-6, t=T_IN)
    print("every solution stays in [z_on_min, z_off_max] after t = 0.7")

    fig, ax = plt.subplots(figsize=(7, 4))
    for band, c in ((Z_ON, "C0"), (Z_OFF, "C3")):
        ax.axhspan(*band, color=c, alpha=0.12, lw=0)
    hs.plot_solutions(tree, 0, ax=ax, alpha=0.5)
    ax.set_ylabel("temperature $z$")
    ax.set_title("every solution of the thermostat with overlapping switching bands")
    fig.tight_layout()
    fig.savefig(out / "explore_thermostat.png", dpi=100)
    plt.close("all")
    print(f"figures written to {out}")
    return tree


if __name__ == "__main__":
    # the folder given, else $HYBRIDSIM_FIGURES, else the working folder
    OUT = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HYBRIDSIM_FIGURES", ".")
    TREE = main(OUT)
