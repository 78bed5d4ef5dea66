"""
Reduced-order finite-time observer for time-varying systems (Mazenc, Ahmed & Malisoff, CDC 2018)
================================================================================================

Section II: an LTI plant xdot = A x + delta(t), y = C x, observed by (15)
(exact from t = tau on). Section IV: the chained form (44) under the output
feedback (58), whose xi2 comes from (50). The observer is a hybrid system
(states J_A, J_H, a timer and a window-filled flag) whose output [P, G] gives
xhat_r = P + G y; ``tv.simulate(observer, x0, ...)`` runs it with its plant
and ``tv.errors(arc, observer)`` reads xhat_r - x_r off the arc.

Run: ``python examples/time_varying_example.py``
"""
import numpy as np

import hybridsim as hs
from observers import time_varying as tv

# --- Section II: design (4)-(6) and the observer (15) -------------------------
A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, -2.0, -1.5]])
C = np.array([[1.0, 0.0, 0.0]])


def delta(t):
    """The known input delta(t) of (2)."""
    return np.array([0.0, 0.0, np.sin(t)])


obs, rc = tv.lti_observer(A, C, tau=0.5, delta=delta)        # L placed, M_tau (6) checked
print("A1 =", rc.A1, " A2 =\n", rc.A2, "\nL =", obs.L(0).ravel(), " rcond(M_tau) =",
      1 / np.linalg.cond(tv.M_tau(rc.A2, rc.A1, obs.L(0), 0.5)))
arc = tv.simulate(obs, [1.0, -1.0, 0.5], t_max=2.0)        # plant (2)-(3) from lti_observer
x = arc["plant"].x
err = np.linalg.norm(tv.errors(arc, obs), axis=1)
# t >= tau after the observer's jump at tau (j >= 1): the sample before the jump still holds xr_init
print("max |xhat_r - x_r| before tau:", err[arc.j == 0].max(), " after:", err[arc.j >= 1].max())
xhat = rc.x_from(arc.outputs("plant")[-1], tv.estimates(arc, obs)[-1])
print("full state estimate at t = 2:", xhat, " true:", x[-1])

# --- Section IV: tracking with the observer in the loop ------------------------
ex = tv.example_data()
print("Lambda =", tv.Lambda(ex["Phi_A2"], ex["Phi_H"], 1.0, ex["tau"]).item(), "= 1 - e^{4 pi}")
loop, v2 = tv.tracking_loop()
arc = hs.simulate(loop, tv.tracking_initial_state(loop, xi4=1.0, xi3=-1.0, xi2=0.5, x1=0.5),
                  t_max=20.0, rtol=1e-10, atol=1e-12, dense=True)
S = tv.loop_signals(arc, loop, v2)
T0 = 2 * np.pi + np.sqrt(0.5)
print("jumps (x1 reaches 0, window filled):", arc.jump_times)
err2 = np.abs(S["xhat2"] - S["xi"][:, 1])
print("max |xhat2 - xi2| for t >= 2 pi + 1/sqrt2:", err2[S["t"] >= T0].max())
print("|zeta| at t = 0, 20:", np.linalg.norm(S["zeta"][0]), np.linalg.norm(S["zeta"][-1]))
print("(58) residual at t = 10:", tv.residual_58(arc, loop, v2, 10.0))
