"""
Reduced-order finite-time observer for time-varying systems (Mazenc, Ahmed & Malisoff, CDC 2018)
================================================================================================

Section II: an LTI plant xdot = A x + delta(t), y = C x, observed by (15)
(exact from t = tau on). Section IV: the chained form (44) under the output
feedback (58), whose xi2 comes from (50). The observer is a hybrid system
(states J_A, J_H, a timer and a window-filled flag) whose output [P, G] gives
xhat_r = P + G y; ``tv.simulate(observer, x0, ...)`` runs it with its plant
and ``tv.errors(arc, observer).e`` reads xhat_r - x_r off the arc.

The paper's main result, plotted below: the estimate is *exact* once the
window [t - tau, t] is measured (Theorem 1), and inside the loop (58) once
the window lies where x1 = 0 (t >= 2 pi + 1/sqrt 2 for x1(0) = 0.5).

Run: ``python examples/time_varying_example.py``
"""
import matplotlib.pyplot as plt
import numpy as np

import hybridsim as hs
from observers import time_varying as tv
from observers.time_varying.design import Lambda, M_tau, example_data, example_gain_sup, residual_58
from observers.time_varying.example import (
    estimates,
    loop_functions,
    loop_signals,
    tracking_initial_state,
)

# --- Section II: design (4)-(6) and the observer (15) -------------------------
A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, -2.0, -1.5]])
C = np.array([[1.0, 0.0, 0.0]])


def delta(t):
    """The known input delta(t) of (2)."""
    return np.array([0.0, 0.0, np.sin(t)])


obs, rc = tv.lti_observer(A, C, tau=0.5, delta=delta)        # L placed, M_tau (6) checked
print("A1 =", rc.A1, " A2 =\n", rc.A2, "\nL =", obs.L(0).ravel(), " rcond(M_tau) =",
      1 / np.linalg.cond(M_tau(rc.A2, rc.A1, obs.L(0), 0.5)))
arc = tv.simulate(obs, [1.0, -1.0, 0.5], t_max=2.0)        # plant (2)-(3) from lti_observer
E = tv.errors(arc, obs)                                    # an Errors: xhat_r - x_r under "e"
err = E.norm()
# t >= tau after the observer's jump at tau (j >= 1): the sample before the jump still holds xr_init
print("max |xhat_r - x_r| before tau:", err[arc.j == 0].max(), " after:", err[arc.j >= 1].max())
xhat = rc.x_from(arc.outputs("plant")[-1], estimates(arc, obs)[-1])
print("full state estimate at t = 2:", xhat, " true:", arc["plant"].x[-1])

# --- Section IV: tracking with the observer in the loop ------------------------
ex = example_data()
print("Lambda =", Lambda(ex["Phi_A2"], ex["Phi_H"], 1.0, ex["tau"]).item(), "= 1 - e^{4 pi}")
gain = example_gain_sup(2 ** 14)
print(f"l_a of (28) on the example: in [{gain.lower:.5f}, {gain.upper:.5f}] (certified)")
loop, v2 = tv.tracking_loop()
arc_l = hs.simulate(loop, tracking_initial_state(loop, xi4=1.0, xi3=-1.0, xi2=0.5, x1=0.5),
                    t_max=14.0, rtol=1e-10, atol=1e-12, dense=True)
S = loop_signals(arc_l, loop, v2)
T0 = 2 * np.pi + np.sqrt(0.5)
print("jumps (x1 reaches 0, window filled):", arc_l.jump_times)
err2 = np.abs(S["xhat2"] - S["xi"][:, 1])
print("max |xhat2 - xi2| for t >= 2 pi + 1/sqrt2:", err2[S["t"] >= T0].max())
print("|zeta| at t = 0, 14:", np.linalg.norm(S["zeta"][0]), np.linalg.norm(S["zeta"][-1]))
print("(58) residual at t = 10:",
      residual_58(10.0, *loop_functions(arc_l, loop, v2), points=arc_l.jump_times))

# %%
# The estimation errors in hybrid time: flows solid, each jump a dotted
# segment from a filled circle (before) to an open one (after). The floor
# 1e-16 stands for "exactly 0" on the log scale (the integrator leaves
# ~1e-12 to 1e-10). Before the window is filled the estimate is held at 0.
fig, axs = plt.subplots(2, 1, figsize=(7, 7))
hs.plot_flows(arc, np.maximum(err, 1e-16), ax=axs[0], labels=[r"$|\hat x_r - x_r|$, (15)"],
              yscale="log", legend=False)
axs[0].axvline(0.5, color="gray", lw=0.6, ls=":", label=r"$t = \tau = 0.5$")
axs[0].set_ylabel(r"estimation error $|\hat x_r - x_r|$")
axs[0].set_title(r"Section II, LTI plant: exact from $t = \tau$ on (14)-(15)")
hs.plot_flows(arc_l, np.maximum(err2, 1e-16), ax=axs[1],
              labels=[r"$|\hat\xi_2 - \xi_2|$, (50) in the loop (58)"], yscale="log",
              legend=False)
hs.plot_flows(arc_l, np.linalg.norm(S["zeta"], axis=1), ax=axs[1], labels=[r"$|\zeta|$ (52)"],
              yscale="log", legend=False)
axs[1].axvspan(2 * np.pi, T0, color="0.88", zorder=0, lw=0,
               label=r"$[2\pi, 2\pi + 1/\sqrt{2})$: (50) not yet exact")
axs[1].set_ylabel("error, norm")
axs[1].set_xlabel(r"time $t$")
axs[1].set_title(r"Section IV, the tracking loop: window filled at $2\pi$, exact from "
                 r"$2\pi + 1/\sqrt{2}$")
for ax in axs:
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
fig.tight_layout()
plt.show()
