"""
Bouncing ball
=============

Define a hybrid system, simulate it, and plot it in hybrid time. The ball
has height x[0] and velocity x[1]. It flows by free fall while above the
floor (C = {x0 >= 0}) and bounces (x1+ = -e x1) when it reaches the floor
moving down (D = {x0 <= 0, x1 <= 0}). The jump times have a closed form::

    t_1 = v0 / g,   t_{k+1} = t_k + 2 e^k v0 / g,   v0 = sqrt(2 g h0),

which the script prints next to the simulated ones.

Figures: height and velocity against t, one subplot each (``plot_flows``
with ``subplots=True``: the velocity's jumps are the dotted segments from a
filled circle, before the bounce, to an open circle, after it); velocity
against the jump counter j (``plot_jumps``); height over the hybrid time
domain in 3-D (``plot_hybrid``). The flows are drawn through the arc's
interpolant between samples, so the parabolas are smooth although RK45
crosses a whole flight in one or two steps.

Run it with::

    python examples/bouncing_ball.py [output_folder]

The figures go to ``output_folder``, else to the folder named by the
environment variable ``HYBRIDSIM_FIGURES``, else to the working folder.

``readme_figure(path)`` draws README's figure (docs/bouncing_ball.png).
"""
import os
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import hybridsim as hs

G, E, H0 = 9.81, 0.8, 1.0
LABELS = ["height (m)", "velocity (m/s)"]
T_LABEL = "$t$ (s)"


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


def readme_figure(path):
    """README's figure: README's ten-line run, height and velocity against t."""
    arc = hs.simulate(BouncingBall(), x0=[1.0, 0.0], t_max=5.0, j_max=20)
    axs = hs.plot_flows(arc, subplots=True, labels=LABELS, xlabel=T_LABEL, legend=False)
    axs[0].set_title("bouncing ball: a bounce is a jump of the velocity")
    fig = axs[0].figure
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    arc = hs.simulate(BouncingBall(), [H0, 0.0], t_max=10.0, j_max=20, rtol=1e-10, atol=1e-12)
    exact = analytic_jump_times(arc.jump_count)
    print(arc)
    print(" k   simulated t_k        analytic t_k         error")
    for k, (ts, te) in enumerate(zip(arc.jump_times, exact), 1):
        print(f"{k:2d}   {ts:.15f}   {te:.15f}   {ts - te:+.1e}")

    axs = hs.plot_flows(arc, subplots=True, labels=LABELS, xlabel=T_LABEL, legend=False)
    axs[0].set_title(f"bouncing ball, $h_0$ = {H0} m, restitution {E}: flows")
    axs[0].figure.tight_layout()
    axs[0].figure.savefig(out / "bouncing_ball_flows.png", dpi=100)

    ax = hs.plot_jumps(arc, 1, labels=LABELS[1:], legend=False)
    ax.set_title("velocity against the jump counter $j$")
    ax.figure.savefig(out / "bouncing_ball_jumps.png", dpi=100)

    ax = hs.plot_hybrid(arc, 0, labels=LABELS[:1], xlabel=T_LABEL)
    ax.set_title("height over the hybrid time domain")
    ax.figure.savefig(out / "bouncing_ball_hybrid.png", dpi=100)
    plt.close("all")
    print(f"figures written to {out}")
    return arc


if __name__ == "__main__":
    # the folder given, else $HYBRIDSIM_FIGURES, else the working folder
    OUT = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HYBRIDSIM_FIGURES", ".")
    main(OUT)
