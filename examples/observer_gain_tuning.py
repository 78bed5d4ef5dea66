"""
Tuning an observer's gain by gradient, through jumps
====================================================

A sampled-data observer of a damped oscillator: the plant x' = A x is
measured (y = x_1) every TS seconds, a timer tau says when; between samples
the estimate runs open-loop, x_hat' = A x_hat, and at each sample it jumps,
x_hat+ = x_hat + k L0 (y - x_hat_1). Which gain k minimises the error
integral J(k) = int_0^T |x - x_hat|^2 dt?

J is a state of the hybrid system (c' = |x - x_hat|^2), so one run of
``hs.simulate_sensitivity`` with the gain as a parameter gives dJ/dk,
through the flows and every jump (the saltation matrix: the reset changes
x_hat, and with it the error's flow after the jump). scipy's L-BFGS-B uses
that gradient; beside it, central differences of whole runs check it.

Figures: J(k) on a grid of gains with the gradient drawn as tangents at a
few of them and the optimum marked; the estimation error |x - x_hat| with
the initial and the tuned gain.

Run it with::

    python examples/observer_gain_tuning.py [output_folder]

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
from scipy.optimize import minimize

import hybridsim as hs

A = np.array([[0.0, 1.0], [-1.0, -0.1]])
L0 = np.array([1.0, 0.5])
TS, T_END, K0 = 0.5, 10.0, 0.2
GRID = np.linspace(0.05, 1.5, 15)                  # gains drawn in the figure
X0 = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0])     # plant (1, 0), estimate 0, tau, J


def make_observer(p):
    """Plant, observer, sampling timer and the cost integral; gain k = p[0].

    State (x1, x2, xh1, xh2, tau, J)."""
    k = p[0]

    def flow(z):
        e = z[:2] - z[2:4]
        return np.concatenate([A @ z[:2], A @ z[2:4], [1.0, e @ e]])

    def jump(z):
        out = z.copy()
        out[2:4] += k * L0 * (z[0] - z[2])
        out[4] = 0.0
        return out

    return hs.HybridSystem.from_functions(
        flow_map=flow, jump_map=jump, jump_guard=lambda z: z[4] - TS, state_dim=6,
        name="sampled-data observer")


def cost_and_gradient(k):
    """J(k) and dJ/dk from one run (the gradient through every jump)."""
    sarc = hs.simulate_sensitivity(make_observer, X0, t_max=T_END, params=[k],
                                   wrt="params", rtol=1e-10, atol=1e-12)
    return sarc.x[-1, 5], sarc.dx_dp[-1, 5, 0]


def cost(k):
    return hs.simulate(make_observer([k]), X0, t_max=T_END, rtol=1e-10,
                       atol=1e-12).xf[5]


def fd_gradient(k, h=1e-5):
    """The check: central differences of two whole runs."""
    return (cost(k + h) - cost(k - h)) / (2 * h)


# %%
# The gradient and its finite-difference check at the initial gain, then
# L-BFGS-B on k in [0, 1.5] with the gradient from the sensitivities.


def tune():
    res = minimize(lambda k: cost_and_gradient(k[0]), [K0], jac=True, method="L-BFGS-B",
                   bounds=[(0.0, 1.5)])
    return res


def draw(k_star, grid=GRID):
    fig, (ax_j, ax_e) = plt.subplots(2, 1, figsize=(7, 6))
    ax_j.plot(grid, [cost(k) for k in grid], "-", color="0.5", label="$J(k)$")
    for k in (0.2, 0.6, 1.2):
        J, dJ = cost_and_gradient(k)
        ax_j.plot([k - 0.1, k + 0.1], [J - 0.1 * dJ, J + 0.1 * dJ], "-", color="C1",
                  label="gradient (sensitivity)" if k == 0.2 else None)
    ax_j.plot([k_star], [cost(k_star)], "o", color="C3", label="tuned gain")
    ax_j.set_xlabel("gain $k$")
    ax_j.set_ylabel(r"$J = \int_0^T |x - \hat x|^2 dt$")
    ax_j.legend()
    for k, lab in ((K0, f"initial k = {K0:g}"), (k_star, f"tuned k = {k_star:.3f}")):
        arc = hs.simulate(make_observer([k]), X0, t_max=T_END, rtol=1e-10, atol=1e-12)
        hs.plot_flows(arc, ax=ax_e, fn=lambda z: np.linalg.norm(z[:2] - z[2:4]),
                      labels=[lab], yscale="log", legend=False)
    ax_e.set_xlabel("$t$ (s)")
    ax_e.set_ylabel(r"$|x - \hat x|$")
    ax_e.legend([ln for ln in ax_e.lines if not ln.get_label().startswith("_")][:2],
                [f"initial k = {K0:g}", f"tuned k = {k_star:.3f}"])
    fig.tight_layout()
    return fig


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    J0, g0 = cost_and_gradient(K0)
    print(f"k = {K0}: J = {J0:.6f}, dJ/dk = {g0:.9f} (sensitivity), "
          f"{fd_gradient(K0):.9f} (central differences of runs)")
    res = tune()
    k_star = float(res.x[0])
    J1, g1 = cost_and_gradient(k_star)
    print(f"tuned: k = {k_star:.6f}, J = {J1:.6f} ({res.nit} iterations, {res.nfev} runs), "
          f"dJ/dk = {g1:.2e} (sensitivity), {fd_gradient(k_star):.2e} (differences)")
    fig = draw(k_star)
    fig.savefig(out / "observer_gain_tuning.png", dpi=100)
    print(f"figure written to {out}")
    return {"k0": K0, "J0": J0, "g0": g0, "k_star": k_star, "J_star": J1, "g_star": g1}, fig


if __name__ == "__main__":
    # the folder given, else $HYBRIDSIM_FIGURES, else the working folder
    OUT = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HYBRIDSIM_FIGURES", ".")
    _, fig = main(OUT)
    plt.close(fig)
