"""
Bouncing ball: sensitivity to restitution across bounces
========================================================

How does each impact time, and the ball's state, move with the restitution
coefficient e? ``hs.simulate_sensitivity`` integrates the variational
equation with the flow and applies the saltation matrix at each impact, so
the derivatives come out of one run, next to the closed form

    t_k = t_1 (1 + 2 (e - e^k) / (1 - e)),   t_1 = sqrt(2 h0 / g),

whose derivative in e the script prints beside the engine's. The system is
the library's ``BouncingBall``; its parameter e is declared by a factory,
``make(p) = BouncingBall(restitution=p[0])``.

Figures: d t_k / d e against the bounce k (engine markers on the closed
form's line; the impacts move later and later as e grows, and the
derivative levels off where the bounces accumulate); d height / d e against
t (it jumps at every impact, where the saltation matrix acts).

Run it with::

    python examples/ball_sensitivity.py [output_folder]

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
from hybridsim.library import BouncingBall

G, E, H0, BOUNCES = 9.81, 0.8, 1.0, 15


def make(p):
    return BouncingBall(G, restitution=p[0])


def closed_form_dt_de(k_max):
    """d t_k / d e for k = 1..k_max, the derivative of the formula above."""
    k = np.arange(1, k_max + 1)
    t1 = np.sqrt(2 * H0 / G)
    return t1 * 2 * ((1 - k * E ** (k - 1)) * (1 - E) + (E - E ** k)) / (1 - E) ** 2


# %%
# One run gives the state, its derivatives in (h0, v0, e) and the impact
# times' derivatives.


def run():
    return hs.simulate_sensitivity(make, [H0, 0.0], t_max=4.5, j_max=BOUNCES,
                                   params=[E], rtol=1e-8)


# %%
# Draw both panels: the impact times' derivatives against bounce number,
# and the height's derivative through flows and jumps.


def draw(sarc):
    k = np.arange(1, sarc.arc.jump_count + 1)
    fig, (ax_t, ax_x) = plt.subplots(2, 1, figsize=(7, 6))
    ax_t.plot(k, closed_form_dt_de(len(k)), "-", color="0.6", label="closed form")
    ax_t.plot(k, sarc.dtj_dp[:, 0], "o", label="engine (saltation)")
    ax_t.set_xlabel("bounce $k$")
    ax_t.set_ylabel(r"$\partial t_k / \partial e$ (s per unit restitution)")
    ax_t.legend()
    # the height's sensitivity as arcs: one line per flow, jumps dotted
    sens = hs.HybridArc(sarc.t, sarc.j, sarc.dx_dp[:, :, 0], sarc.termination)
    hs.plot_flows(sens, ax=ax_x, labels=[r"$\partial h / \partial e$",
                                         r"$\partial v / \partial e$"], legend=True)
    ax_x.set_xlabel("$t$ (s)")
    ax_x.set_ylabel("sensitivity to $e$")
    fig.tight_layout()
    return fig


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sarc = run()
    exact = closed_form_dt_de(sarc.arc.jump_count)
    for k in (1, 2, 5, BOUNCES):
        print(f"bounce {k:2d}: t = {sarc.jump_times[k - 1]:.6f} s, dt/de = "
              f"{sarc.dtj_dp[k - 1, 0]:.12f} (closed form {exact[k - 1]:.12f})")
    rel = np.abs(sarc.dtj_dp[1:, 0] / exact[1:] - 1).max()
    print(f"largest relative difference from the closed form: {rel:.1e}")
    fig = draw(sarc)
    fig.savefig(out / "ball_sensitivity.png", dpi=100)
    print(f"figure written to {out}")
    return sarc, fig


if __name__ == "__main__":
    # the folder given, else $HYBRIDSIM_FIGURES, else the working folder
    OUT = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HYBRIDSIM_FIGURES", ".")
    _, fig = main(OUT)
    plt.close(fig)
