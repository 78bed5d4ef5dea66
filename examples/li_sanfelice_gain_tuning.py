"""
A paper observer's gain tuned by gradient: Li & Sanfelice's H_n under noise
===========================================================================

The finite-time hybrid observer H_n of Li & Sanfelice ((10)-(12), paper 002)
on the plant of its Section V.B, with F_1 = -k I + J, F_2 = -(k + 3) I + J
(the design family of ``observers.li_sanfelice.falsification.family_design``;
L_i = (A - F_i) H^{-1}, delta = 0.5): two Luenberger copies that flow, and
one jump at tau = delta to K_1 x_hat_1 + K_2 x_hat_2, exact without noise
(Theorem 4.7). Under the measurement noise m(t) = 0.3 sin(20 t) (1, -1) a
larger gain k converges faster but passes more noise: which k minimises the
error integral J(k) = int_0^4 |x_bar - x|^2 dt?

Everything is the engine's: the plant is an ``hs.LinearPlant`` whose output
stacks y = H x + m and x, the observer is the package's ``NominalObserver``,
and a one-state component integrates |x_bar - x|^2 from its input, wired by
``hs.LinearInput`` (u = x - x_bar). One run of ``hs.simulate_sensitivity``
with k as a parameter gives dJ/dk through the flows and the jump (the gains
K_1, K_2 of (12) depend on k; the saltation update carries the jump);
scipy's L-BFGS-B uses it, and central differences of whole runs check it.

Figures: J(k) with the gradient drawn as tangents and the optimum marked;
the estimation error with the initial and the tuned gain; and the error's
sensitivity to the gain, d|x_bar - x|/dk, through the jump at t = delta.

Run it with::

    python examples/li_sanfelice_gain_tuning.py [output_folder]

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
from observers import li_sanfelice as ls
from observers.li_sanfelice.falsification import family_design

N = P = 2
DELTA, T_END, K0 = 0.5, 4.0, 3.0
X0, XHAT0 = np.array([0.3, 0.4]), np.array([1.0, -1.0])
GRID = [1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 13.0, 16.0, 20.0, 24.0]   # gains drawn
OPTS = dict(rtol=1e-8, atol=1e-10)


def noise(t):
    """m(t) = 0.3 sin(20 t) (1, -1), and zeros beside the stacked x."""
    return np.concatenate([0.3 * np.sin(20.0 * t) * np.array([1.0, -1.0]), np.zeros(N)])


class Cost(hs.HybridSystem):
    """J' = |u|^2 with u = x - x_bar (from the interconnection)."""

    state_dim, input_dim = 1, N

    def flow_map(self, x, t, j, u):
        return np.array([u @ u])


def make_system(p):
    """Plant, H_n with gain k = p[0], and the cost, as one interconnection."""
    design = family_design(p[0], p[0] + 3.0, 1.0, 1.0, DELTA)
    plant = hs.LinearPlant(design.A, C=np.vstack([design.H, np.eye(N)]), noise=noise)
    take_y = np.hstack([np.eye(P), np.zeros((P, N))])      # y = H x + m
    take_x = np.hstack([np.zeros((N, P)), np.eye(N)])      # x
    return hs.Interconnection(
        {"plant": plant, "observer": ls.NominalObserver(design), "cost": Cost()},
        inputs={"observer": hs.LinearInput({"plant": take_y}),
                "cost": hs.LinearInput({"plant": take_x, "observer": -np.eye(N)})})


def x0_of(k):
    obs = make_system([k]).systems["observer"]
    return np.concatenate([X0, obs.initial_state(XHAT0), [0.0]])


def cost_and_gradient(k):
    """J(k) and dJ/dk from one run (through the jump)."""
    sarc = hs.simulate_sensitivity(make_system, x0_of(k), t_max=T_END, params=[k],
                                   wrt="params", **OPTS)
    return sarc.x[-1, -1], sarc.dx_dp[-1, -1, 0], sarc


def cost(k):
    return hs.simulate(make_system([k]), x0_of(k), t_max=T_END, **OPTS).xf[-1]


def fd_gradient(k, h=1e-5):
    """The check: central differences of two whole runs (the initial state
    does not depend on k: x_hat_1 = x_hat_2 = XHAT0, tau = q = 0)."""
    return (cost(k + h) - cost(k - h)) / (2 * h)


# %%
# The gradient and its finite-difference check at the initial gain, then
# L-BFGS-B on k in [1, 24] with the gradient from the sensitivities.


def tune():
    return minimize(lambda k: cost_and_gradient(k[0])[:2], [K0], jac=True,
                    method="L-BFGS-B", bounds=[(1.0, 24.0)])


def error_norm(arc):
    e = arc["observer"].outputs() - arc["plant"].x
    return np.linalg.norm(e, axis=1)


def draw(k_star, grid=GRID):
    fig, (ax_j, ax_e, ax_s) = plt.subplots(3, 1, figsize=(7, 9))
    ax_j.plot(grid, [cost(k) for k in grid], "-", color="0.5", label="$J(k)$")
    for k in (2.0, 16.0):
        J, dJ, _ = cost_and_gradient(k)
        w = 1.5
        ax_j.plot([k - w, k + w], [J - w * dJ, J + w * dJ], "-", color="C1",
                  label="gradient (sensitivity)" if k == 2.0 else None)
    ax_j.plot([k_star], [cost(k_star)], "o", color="C3", label=f"tuned $k$ = {k_star:.2f}")
    ax_j.set_xlabel("gain $k$ ($F_1 = -kI + J$, $F_2 = -(k+3)I + J$)")
    ax_j.set_ylabel(r"$J = \int_0^4 |\bar x - x|^2\,dt$")
    ax_j.legend()
    for k, color in ((K0, "C0"), (k_star, "C3")):
        arc = hs.simulate(make_system([k]), x0_of(k), t_max=T_END, **OPTS)
        e = error_norm(arc)
        for jj in (0, 1):
            sel = arc.j == jj
            ax_e.plot(arc.t[sel], e[sel], "-", color=color,
                      label=f"$k$ = {k:.2f}" if jj == 0 else None)
        tj = arc.jump_times[0]
        ax_e.plot([tj, tj], [e[arc.j == 0][-1], e[arc.j == 1][0]], ":", color=color)
    ax_e.axvline(DELTA, color="0.7", lw=0.8)
    ax_e.set_yscale("log")
    ax_e.set_xlabel("$t$ (s)")
    ax_e.set_ylabel(r"$|\bar x - x|$ (jump at $t = \delta$)")
    ax_e.legend()
    _, _, sarc = cost_and_gradient(k_star)
    arc, obs = sarc.arc, make_system([k_star]).systems["observer"]
    d = obs.design
    # d xbar/dk = a1 dxh1/dk + a2 dxh2/dk (x does not depend on k)
    sl1, sl2 = (slice(N + s.start, N + s.stop) for s in (obs.slices["xh1"], obs.slices["xh2"]))
    dxbar = d.a1 * sarc.dx_dp[:, sl1, 0] + d.a2 * sarc.dx_dp[:, sl2, 0]
    for i, color in ((0, "C0"), (1, "C1")):
        for jj in (0, 1):
            sel = arc.j == jj
            ax_s.plot(arc.t[sel], dxbar[sel, i], "-", color=color,
                      label=rf"$\partial \bar x_{i + 1}/\partial k$" if jj == 0 else None)
        k1 = np.flatnonzero(arc.j == 1)[0]
        ax_s.plot([arc.t[k1]] * 2, [dxbar[k1 - 1, i], dxbar[k1, i]], ":", color=color)
    ax_s.set_xlabel("$t$ (s)")
    ax_s.set_ylabel(f"sensitivity to $k$ at $k$ = {k_star:.2f}")
    ax_s.legend()
    fig.tight_layout()
    return fig


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    J0, g0, _ = cost_and_gradient(K0)
    print(f"k = {K0}: J = {J0:.6f}, dJ/dk = {g0:.9f} (sensitivity), "
          f"{fd_gradient(K0):.9f} (central differences of runs)")
    res = tune()
    k_star = float(res.x[0])
    J1, g1, _ = cost_and_gradient(k_star)
    print(f"tuned: k = {k_star:.6f}, J = {J1:.6f} ({res.nit} iterations, {res.nfev} runs), "
          f"dJ/dk = {g1:.2e} (sensitivity), {fd_gradient(k_star):.2e} (differences)")
    fig = draw(k_star)
    fig.savefig(out / "li_sanfelice_gain_tuning.png", dpi=100)
    print(f"figure written to {out}")
    return {"k0": K0, "J0": J0, "g0": g0, "k_star": k_star, "J_star": J1, "g_star": g1}, fig


if __name__ == "__main__":
    # the folder given, else $HYBRIDSIM_FIGURES, else the working folder
    OUT = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HYBRIDSIM_FIGURES", ".")
    _, fig = main(OUT)
    plt.close(fig)
