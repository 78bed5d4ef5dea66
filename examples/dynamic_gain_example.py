"""
Robust finite-time observer with a dynamic gain (Nekhoroshikh et al., CDC 2022)
===============================================================================

Tune the observer with LMI (10), run it on the example of Section VI (chain of
three integrators, u = Kx + cos 10t) through hybridsim, and print the settling
times: exact at T of (18) for the prescribed-time observer (gamma2 = 0), within
bound (17) for the proposed one, and how each behaves under noise. The figure
shows the r-homogeneous norm of the error state of each run (Fig. 1(a) and
2(a) of the paper, with our L).

Run: ``python examples/dynamic_gain_example.py`` (a few seconds).
"""
import matplotlib.pyplot as plt
import numpy as np

import hybridsim as hs
from observers.dynamic_gain import (
    EXAMPLE,
    errors,
    prescribed_time_observer,
    proposed_observer,
    simulate,
)
from observers.dynamic_gain.design import settling_time
from observers.dynamic_gain.example import example_norm, gain_settling_time, settle_time
from observers.lmi import check_gain_lmi10, solve_lmi10

mu, gamma1 = EXAMPLE["mu"], EXAMPLE["gamma1"]

# %%
# 1. Gains from LMI (10): L = P^{-1} Y (Clarabel, verified by eigenvalues).
res = solve_lmi10(3, mu, gamma1, objective="alpha")
print("our L    =", np.round(res.L, 2), f"(alpha = {res.alpha:.2f})")
paper = check_gain_lmi10(EXAMPLE["L"], mu, gamma1)
print("paper's L satisfies (10):", paper["feasible"], f"(decay margin {paper['sigma']:.2f} >= 1)")

observers = {"proposed": proposed_observer(res.L, mu, gamma1, 1.0, b=EXAMPLE["b"]),
             "prescribed-time": prescribed_time_observer(res.L, mu, gamma1, b=EXAMPLE["b"])}
colors = {"proposed": "k", "prescribed-time": "r"}
fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)

# %%
# 2. Without disturbances: the proposed observer (gamma2 = 1) and its prescribed-time
#    counterpart (gamma2 = 0) both settle; gamma2 = 0 exactly at T of (18).
for name, obs in observers.items():
    arc = simulate(obs, EXAMPLE["x0"], None, t_max=9.0)   # hs.connect(plant, obs) + hs.simulate
    e = errors(arc, obs).e                                  # (w, x - x_hat)
    print(f"{name:16s}: {arc.termination.name}, settling time (v = 0) "
          f"{gain_settling_time(arc, obs):.3f}, error below 1e-6 from t = "
          f"{settle_time(arc, obs):.3f}, final max|e| = {np.abs(e[-1]).max():.1e}")
    norm = example_norm(obs)
    hs.plot_flows(arc, fn=lambda x, norm=norm: max(norm(x), 1e-16), ax=axes[0], labels=[name],
                  yscale="log", color=colors[name], legend=False)
print("exact settling time (18) for gamma2 = 0:", settling_time(1.0, mu, gamma1))

# %%
# 3. Under noise, gamma2 = 0 escapes in finite time (an expected BLOWUP, so no
#    warning) while gamma2 = 1 stays bounded (Proposition 5).
for name, obs in observers.items():
    arc = simulate(obs, EXAMPLE["x0"], None, noise=True, seed=1, t_max=6.0, warn=False)
    print(f"{name:16s} with noise: {arc.termination.name} at t = {arc.tf:.3f}")
    norm = example_norm(obs)
    hs.plot_flows(arc, fn=norm, ax=axes[1], labels=[name], yscale="log",
                  color=colors[name], legend=False)

for ax, title in zip(axes, ["without disturbances", "with Section VI's disturbances"]):
    ax.axvline(5.0, color="0.6", lw=0.8, ls=":", label="$T$ of (18)")
    ax.set_title(title)
    ax.set_xlabel("$t$ (s)")
    ax.legend(fontsize=8, loc="lower left")
axes[0].set_ylabel(r"$\|\xi(t)\|_r = |v| + \sum_i |e_i|^{1/r_i}$")
axes[1].set_ylabel("")
fig.tight_layout()
plt.show()
