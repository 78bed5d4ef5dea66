"""
Fixed-time Gramian observer with one delay (Mazenc & Malisoff, LCSYS 2022)
==========================================================================

Builds the design of Section III for the DC motor (65)-(67), runs the
continuous observer (7) and the sampled observer (39) beside the plant on the
hybridsim engine, and prints the estimation error: exact (to the integrator)
from t = tau = 0.1 on for Theorem 1, decaying for the sampled observer.

Run: ``python examples/gramian_delay_example.py``
"""
import numpy as np

import hybridsim as hs
from observers import gramian_delay as gd


def main():
    # the motor (65) without disturbances, k = 100, tau = 0.1 (Section V)
    ex = gd.dc_motor(k=100.0, tau=0.1, disturbed=False)
    d = ex.design
    print(f"cond(S) = {d.cond_S:.3g}, R = {d.R.ravel()}")

    # Theorem 1: plant -> observer (7); xi_e (13) evaluated along the run
    obs = ex.continuous_observer()
    sys_c = hs.connect(ex.plant, obs, names=("plant", "obs"))
    arc = hs.simulate(sys_c, sys_c.stack(plant=ex.chi0, obs=obs.initial_state()),
                      t_max=0.5, method="DOP853", rtol=1e-11, atol=1e-12, dense=True)
    xi = ex.xi(arc["plant"].x)                     # (66)'s coordinates, time-major
    err = xi[:, :2] - obs.estimate(arc, arc.outputs("plant"), name="obs")
    print("Theorem 1: max |xi1 - xi_e| for t >= tau:",
          np.linalg.norm(err[arc.t >= 0.1], axis=1).max())

    # Theorem 2: samples at random instants 5-10 ms apart, omega in (13)
    ins = gd.sampling_instants(0.005, 0.01, 1.0, seed=1)
    obs_s = ex.sampled_observer(instants=ins)
    sys_s = hs.connect(ex.plant, obs_s, names=("plant", "obs"))
    arc_s = hs.simulate(sys_s, sys_s.stack(plant=ex.chi0, obs=obs_s.initial_state()),
                        t_max=1.0, j_max=10**6, method="LSODA", rtol=1e-9, atol=1e-11,
                        dense=True)
    xi_s = ex.xi(arc_s["plant"].x)
    err_s = np.linalg.norm(xi_s[:, :2] - obs_s.estimate(arc_s, name="obs"), axis=1)
    print(f"Theorem 2: {arc_s.jump_count} samples; |xi1 - xi_e| at t = 0.2, 0.5, 1:",
          [float(err_s[np.searchsorted(arc_s.t, s) - 1]) for s in (0.2, 0.5, 1.0)])
    c = gd.theorem2_constants(d, ex.K1, ex.K2, 0.01)
    print(f"Theorem 2's condition (40): T_bar mu = {c.T_bar_mu:.3g} (needs < 1)")


if __name__ == "__main__":
    main()
