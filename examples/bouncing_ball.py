"""Bouncing ball: define a hybrid system, simulate it, plot it in hybrid time.

The ball has height x[0] and velocity x[1]. It flows by free fall while above
the floor (C = {x0 >= 0}) and bounces (x1+ = -e x1) when it reaches the floor
moving down (D = {x0 <= 0, x1 <= 0}). The jump times have a closed form,

    t_1 = v0 / g,   t_{k+1} = t_k + 2 e^k v0 / g,   v0 = sqrt(2 g h0),

which the script prints next to the simulated ones. Figures: plot_flows (x
against t, jumps dashed), plot_jumps (x against j) and plot_hybrid (height over
the hybrid time domain, 3-D).

    python examples/bouncing_ball.py [output_folder]
"""
import sys
import tempfile
from pathlib import Path

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import hybridsim as hs

G, E, H0 = 9.81, 0.8, 1.0


class BouncingBall(hs.HybridSystem):
    state_dim = 2

    def flow_map(self, x, t, j):
        return np.array([x[1], -G])

    def jump_map(self, x, t, j):
        return np.array([0.0, -E * x[1]])

    def flow_set(self, x, t, j):
        return x[0] >= 0

    def jump_set(self, x, t, j):
        return x[0] <= 0 and x[1] <= 0


def analytic_jump_times(n, h0=H0):
    v0 = np.sqrt(2 * G * h0)
    return v0 / G + np.concatenate(([0.0], np.cumsum(2 * v0 / G * E ** np.arange(1, n))))


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    # The flow is a parabola: RK45 crosses a whole flight in one or two
    # steps, so refine=20 stores 19 dense-output points inside each step for
    # smooth plots (event location does not depend on it).
    arc = hs.simulate(BouncingBall(), [H0, 0.0], t_max=10.0, j_max=20,
                      rtol=1e-10, atol=1e-12, refine=20)
    exact = analytic_jump_times(arc.jump_count)
    print(arc)
    print(" k   simulated t_k        analytic t_k         error")
    for k, (ts, te) in enumerate(zip(arc.jump_times, exact), 1):
        print(f"{k:2d}   {ts:.15f}   {te:.15f}   {ts - te:+.1e}")
    for name, plot, kw in (("flows", hs.plot_flows, {}), ("jumps", hs.plot_jumps, {}),
                           ("hybrid", hs.plot_hybrid, {"idx": 0})):
        ax = plot(arc, **kw)
        ax.set_title(f"bouncing ball: plot_{name}")
        ax.figure.savefig(out / f"bouncing_ball_{name}.png", dpi=100)
        plt.close(ax.figure)
    print(f"figures written to {out}")
    return arc


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="hybridsim_"))
