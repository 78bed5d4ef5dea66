"""
Sample-and-hold control loop
============================

A continuous plant under a sampled feedback, as one hybrid system. The plant
xdot = A x + B u (a double integrator) is driven by a zero-order hold: every
T seconds the controller samples u = K x and holds it until the next sample.
With state (x, u, tau), the timer tau being an ordinary state component::

    flow (tau <= T):  xdot = A x + B u,  udot = 0,  taudot = 1
    jump (tau >= T):  x+ = x,  u+ = K x,  tau+ = 0.

Starting with tau = T samples at t = 0 (priority="jumps"). Between samples
the loop is linear, so the state at the samples follows the exact ZOH
discretisation x_{k+1} = (e^{AT} + int_0^T e^{As} ds B K) x_k; the script
prints its spectral radius (< 1: the loop converges) and compares the
simulated samples with it.

Figures: position, velocity and the held input against t, one subplot each
on a shared t axis (the plant's state does not jump, so its jump markers are
switched off; the input's jumps are the controller's updates); and the phase
plane of the plant, where the flows bend at each update.

Run it with::

    python examples/sample_and_hold.py [output_folder]

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
from scipy.linalg import expm

import hybridsim as hs

A = np.array([[0.0, 1.0], [0.0, 0.0]])
B = np.array([[0.0], [1.0]])
K = np.array([[-1.0, -1.5]])
T = 0.2
N, M = A.shape[0], B.shape[1]


class SampleAndHold(hs.HybridSystem):
    state_dim = N + M + 1          # (x, u, tau)

    def flow_map(self, z, t, j):
        x, u = z[:N], z[N:N + M]
        return np.concatenate((A @ x + B @ u, np.zeros(M), [1.0]))

    def jump_map(self, z, t, j):
        x = z[:N]
        return np.concatenate((x, K @ x, [0.0]))

    def jump_guard(self, z, t, j):
        return z[-1] - T

    def flow_guard(self, z, t, j):
        return T - z[-1]


def zoh_closed_loop():
    """Sample-to-sample matrix of the loop: x_{k+1} = Phi x_k."""
    E = expm(np.block([[A, B], [np.zeros((M, N + M))]]) * T)
    return E[:N, :N] + E[:N, N:] @ K


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    x0 = np.array([1.0, 0.0])
    arc = hs.simulate(SampleAndHold(), np.concatenate((x0, np.zeros(M), [T])),
                      t_max=15.0, rtol=1e-10, atol=1e-12)
    phi = zoh_closed_loop()
    samples = arc.x[arc.jump_index, :N]                  # x at each sampling instant
    expected = np.array([np.linalg.matrix_power(phi, k) @ x0 for k in range(len(samples))])
    print(f"{arc}\nspectral radius of the sampled loop: {max(abs(np.linalg.eigvals(phi))):.4f}")
    print(f"samples vs ZOH discretisation: largest error {np.max(abs(samples - expected)):.1e}")
    print(f"|x(0)| = {np.linalg.norm(x0):.3g}, |x({arc.tf:g})| = {np.linalg.norm(arc.xf[:N]):.2e}")
    fig, axs = plt.subplots(3, 1, sharex=True, figsize=(7, 6))
    hs.plot_flows(arc, [0, 1], subplots=True, ax=axs[:2], markers=False, legend=False,
                  labels=["position $x_1$", "velocity $x_2$"])
    hs.plot_flows(arc, N, ax=axs[2], labels=["input $u$ (held)"], legend=False,
                  color="C1", xlabel="$t$")
    axs[0].set_title(f"sample-and-hold loop, T = {T}, u = K x at each sample")
    fig.tight_layout()
    fig.savefig(out / "sample_and_hold_flows.png", dpi=100)
    ax = hs.plot_phase(arc, 0, 1, labels=["position $x_1$", "velocity $x_2$"], markers=False)
    ax.plot(*samples.T, "o", color="C1", mfc="none", ms=6, label="samples (u updated)")
    ax.plot(*expected.T, "x", color="k", ms=4, label="ZOH discretisation")
    ax.legend()
    ax.set_title("sample-and-hold loop: phase plane")
    ax.figure.savefig(out / "sample_and_hold_phase.png", dpi=100)
    plt.close("all")
    print(f"figures written to {out}")
    return arc


if __name__ == "__main__":
    # the folder given, else $HYBRIDSIM_FIGURES, else the working folder
    OUT = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HYBRIDSIM_FIGURES", ".")
    main(OUT)
