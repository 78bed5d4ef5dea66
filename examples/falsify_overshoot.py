"""
Falsifying an overshoot claim under bounded noise
=================================================

A thermostat (see the thermostat example) whose switching decisions read a
noisy temperature y = z + m(t), with the measurement noise bounded,
|m(t)| <= ε = 1. Its designer claims the room stays within half a degree of
the band [z_min, z_max] = [70, 80]. Is that true for every noise in the
class?

``hs.falsify`` searches the noise class for the worst run: the noise is a
:class:`~hybridsim.falsification.PiecewiseConstant` signal (20 values on
[0, 4], each in [-ε, ε]), the claim a margin (positive: the temperature stays
in the widened band; :func:`hybridsim.testing.margin_in_set`), and the search
is differential evolution over the 20 values, beside random sampling with
the same budget of runs. The heater switches when y crosses a threshold, so
a noise of -ε at an upward crossing lets z reach z_max + ε: the claim with
half a degree fails, and the claim with ε = 1 degree holds, tightly: its
worst margin is 0 to the runs' accuracy, reached by noise at -ε or +ε when
the temperature crosses a threshold.

Run it with::

    python examples/falsify_overshoot.py
"""
import matplotlib.pyplot as plt
import numpy as np

import hybridsim as hs
from hybridsim.falsification import PiecewiseConstant, Space
from hybridsim.testing import margin_in_set

Z_OUT, Z_HEAT, Z_MIN, Z_MAX, EPS = 60.0, 30.0, 70.0, 80.0, 1.0


class NoisyThermostat(hs.HybridSystem):
    """x = (z, q); the thresholds are compared with y = z + m(t)."""

    state_dim = 2

    def __init__(self, m):
        self.m = m

    def flow_map(self, x, t):
        return np.array([-x[0] + Z_OUT + Z_HEAT * x[1], 0.0])

    def jump_map(self, x, t):
        return np.array([x[0], 1.0 - x[1]])

    def jump_guard(self, x, t):          # past the active threshold, as measured
        y = x[0] + self.m(t)[0]
        return y - Z_MAX if x[1] > 0.5 else Z_MIN - y

    def flow_guard(self, x, t):
        y = x[0] + self.m(t)[0]
        return Z_MAX - y if x[1] > 0.5 else y - Z_MIN


space = Space(m=PiecewiseConstant(EPS, t_end=4.0, pieces=20))


def run(point):
    return hs.simulate(NoisyThermostat(point["m"]), [75.0, 1.0], t_max=4.0,
                       max_step=0.05, rtol=1e-8, atol=1e-10)


TOL = 1e-6     # the runs' accuracy: rtol 1e-8 of temperatures near 80


def within(delta):
    """The claim "z stays in [z_min - delta, z_max + delta]" as a margin, with
    the integrator's accuracy as slack (the corrected claim is tight)."""
    def margin(arc):
        return margin_in_set(arc, lambda x, t, j: min(x[0] - (Z_MIN - delta),
                                                      (Z_MAX + delta) - x[0]) + TOL)
    return margin


claimed = hs.falsify(run, space, within(0.5), budget=150, seed=1, stop=False)
baseline = hs.falsify(run, space, within(0.5), budget=150, seed=1, stop=False,
                      method="random")
corrected = hs.falsify(run, space, within(EPS), budget=150, seed=1, stop=False)
print("claim: within 0.5 degree ->", claimed)
print("random sampling, same budget: worst margin", f"{baseline.margin:.3f}")
print("claim: within eps = 1 degree ->", corrected)

fig, (ax_h, ax_z) = plt.subplots(1, 2, figsize=(11, 4))
for res, label, style in ((claimed, "differential evolution", "-"),
                          (baseline, "random sampling", "--")):
    ax_h.plot(np.minimum.accumulate(res.history), style, label=label)
ax_h.axhline(0.0, color="0.4", lw=0.8)
ax_h.set_xlabel("runs")
ax_h.set_ylabel("worst margin so far (degrees)")
ax_h.set_title("search for a run leaving the band ± 0.5")
ax_h.legend()
hs.plot_flows(claimed.arc, 0, ax=ax_z, labels=["room temperature $z$"], xlabel="$t$")
for level in (Z_MIN, Z_MAX):
    ax_z.axhline(level, color="0.5", lw=0.8)
for level in (Z_MIN - 0.5, Z_MAX + 0.5):
    ax_z.axhline(level, color="C3", ls="--", lw=0.8)
ax_z.set_ylabel("temperature (degrees)")
ax_z.set_title(f"worst run: margin {claimed.margin:.2f} at t = {claimed.where[0]:.2f}")
fig.tight_layout()
plt.show()
