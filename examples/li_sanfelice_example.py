"""
Finite-time hybrid observers of Li & Sanfelice
==============================================

Plant (1): xdot = A x, y = H x + m (Section V.B: a harmonic oscillator seen
through two mixed outputs). The observers H_n, H_c and H_pc are hybrid systems
whose input is y; ``simulate`` wires the engine's ``LinearPlant``
(with output noise) to the observer with ``hs.connect`` and runs
``hs.simulate``.

Run: ``python examples/li_sanfelice_example.py``
"""
import numpy as np

from observers import li_sanfelice as ls

A = np.array([[0.0, 1.0], [-1.0, 0.0]])
H = np.array([[1.0, 2.0], [2.0, 1.0]])
L1, L2 = 5 * np.linalg.inv(H), 8 * np.linalg.inv(H)      # F1 = A - 5I, F2 = A - 8I

# design checks: Assumption 4.1 / Remark 4.4, Lemma 4.2, K1, K2, H T - I
print("first zero of det(I - e^{F2 t} e^{-F1 t}) up to t=20:", ls.admissible_delta(A, H, L1, L2))
print("Lemma 4.2 condition:", ls.lemma_4_2_condition(A, H, L1, L2))
d = ls.Design(A=A, H=H, L1=L1, L2=L2, delta=1.0)
print("K2 =\n", d.K2, "\ncond(HT - I) =", round(d.HT_cond, 3),
      " |(HT - I)^-1| =", round(d.HT_inv_norm, 3))

# H_n without noise: exact after its one jump (Theorem 4.7)
obs = ls.NominalObserver(d)
arc = ls.simulate(obs, x0=[0.3, 0.4], xhat0=[0.0, 0.0], t_max=2.0)
E = ls.errors(arc, obs)
print("H_n, m = 0: jump at t =", arc.jump_times,
      " max |e| after it:", np.abs(E["ebar"][arc.j == 1]).max())

# H_n under a bias: the error after the jump is (15) = T m, within Theorem 4.10's bound
m = np.array([0.3, 0.2])
arc = ls.simulate(obs, [0.3, 0.4], [0.0, 0.0], noise=m, t_max=2.0)
E = ls.errors(arc, obs)
print("H_n, m = (0.3, 0.2): e(delta,1) =", E["e1"][arc.j == 1][0],
      " (15):", ls.error_after_jump(d, m),
      " Thm 4.10 bound:", round(ls.theorem_4_10_bound(d, np.linalg.norm(m)), 4))

# H_c compensates the bias after one jump (Theorem 4.13) and estimates it
obs_c = ls.ConstantNoiseObserver(d)
arc = ls.simulate(obs_c, [0.3, 0.4], [0.0, 0.0], noise=m, t_max=3.0)
E = ls.errors(arc, obs_c)
print("H_c: max |e| after the jump:", np.abs(E["ebar"][arc.j == 1]).max(), " m̂ =", E["mhat"][-1])

# H_pc tracks a piecewise-constant noise, exact within 2 delta of each switch (Theorem 4.14)
noise = ls.PiecewiseConstantNoise([2.5, 4.5], [[0.3, 0.2], [0.4, 0.4], [0.2, 0.3]])
obs_pc = ls.PiecewiseConstantNoiseObserver(d)
arc = ls.simulate(obs_pc, [0.3, 0.4], [0.0, 0.0], noise=noise, t_max=8.0)
E = ls.errors(arc, obs_pc)
for t in (2.0, 3.5, 4.2, 5.5, 7.0):
    k = np.searchsorted(arc.t, t)
    print(f"H_pc at t={arc.t[k]:.2f}: |ē| = {np.linalg.norm(E['ebar'][k]):.2e}, "
          f"m̂ = {E['mhat'][k]}, m = {noise(t)}")
