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

from observers import gramian_delay as gd


def main():
    # the motor (65) without disturbances, k = 100, tau = 0.1 (Section V)
    ex = gd.dc_motor(k=100.0, tau=0.1, disturbed=False)
    d = ex.design
    print(f"cond(S) = {d.cond_S:.3g}, R = {d.R.ravel()}")

    # Theorem 1: plant -> observer (7); xi_e (13) evaluated along the run
    obs = ex.continuous_observer()
    arc = gd.simulate(obs, ex.chi0, None, t_max=0.5)
    err = np.linalg.norm(gd.errors(arc, obs), axis=1)
    print("Theorem 1: max |xi1 - xi_e| for t >= tau:", err[arc.t >= 0.1].max())

    # k = 75: psi_2 of (7) is unstable; the reset realisation keeps (13) exact
    ex75 = gd.dc_motor(k=75.0, tau=0.1, disturbed=False)
    obs75 = ex75.continuous_observer(realisation="reset")
    arc75 = gd.simulate(obs75, ex75.chi0, None, t_max=1.0)
    err75 = np.linalg.norm(gd.errors(arc75, obs75), axis=1)
    print(f"k = 75, reset realisation: {arc75.jump_count} resets, max |xi1 - xi_e| for "
          f"t >= tau: {err75[arc75.t >= 0.1].max():.2e}")

    # Theorem 2: samples at random instants 5-10 ms apart, omega in (13)
    ins = gd.sampling_instants(0.005, 0.01, 1.0, seed=1)
    obs_s = ex.sampled_observer(instants=ins)
    arc_s = gd.simulate(obs_s, ex.chi0, None, t_max=1.0)
    err_s = np.linalg.norm(gd.errors(arc_s, obs_s), axis=1)
    print(f"Theorem 2: {arc_s.jump_count} samples; |xi1 - xi_e| at t = 0.2, 0.5, 1:",
          [float(err_s[np.searchsorted(arc_s.t, s) - 1]) for s in (0.2, 0.5, 1.0)])
    c = gd.theorem2_constants(d, ex.K1, ex.K2, 0.01)
    print(f"Theorem 2's condition (40): T_bar mu = {c.T_bar_mu:.3g} (needs < 1)")


if __name__ == "__main__":
    main()
