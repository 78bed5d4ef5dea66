"""
Timer and its hybrid time domain
================================

The simplest hybrid system: a timer with period 1. The state tau flows at
unit rate on C = [0, 1] and resets to 0 on D = {tau >= 1}. Given as
continuous guards (D = {tau - 1 >= 0}, C = {1 - tau >= 0}), the jumps are
located by root-finding and fall on the integers to within a few ulp.

Figure: the sawtooth tau against t (``plot_flows``; each reset is a jump,
dotted from a filled circle at tau = 1 to an open circle at tau = 0) above
the hybrid time domain E = [0, 1] x {0} U [1, 2] x {1} U ...
(``plot_time_domain``), on a shared t axis.

Run it with::

    python examples/timer.py [output_folder]

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

PERIOD = 1.0

timer = hs.HybridSystem.from_functions(
    flow_map=lambda x: np.array([1.0]),
    jump_map=lambda x: np.array([0.0]),
    jump_guard=lambda x: x[0] - PERIOD,
    flow_guard=lambda x: PERIOD - x[0],
    state_dim=1, name="timer")


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    arc = hs.simulate(timer, [0.0], t_max=5.5)
    exact = PERIOD * np.arange(1, arc.jump_count + 1)
    print(f"{arc}\njump times {arc.jump_times}\n"
          f"largest error against k * PERIOD: {np.max(np.abs(arc.jump_times - exact)):.1e}")
    print("flow intervals (t_j, t_{j+1}, j):", [(round(a, 12), round(b, 12), j)
                                                for a, b, j in arc.flow_intervals])
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    hs.plot_flows(arc, ax=ax1, labels=[r"timer $\tau$"], xlabel="", legend=False)
    hs.plot_time_domain(arc, ax=ax2)
    ax1.set_title("timer: state (top) and hybrid time domain (bottom)")
    fig.tight_layout()
    fig.savefig(out / "timer_time_domain.png", dpi=100)
    plt.close(fig)
    print(f"figures written to {out}")
    return arc


if __name__ == "__main__":
    # the folder given, else $HYBRIDSIM_FIGURES, else the working folder
    OUT = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HYBRIDSIM_FIGURES", ".")
    main(OUT)
