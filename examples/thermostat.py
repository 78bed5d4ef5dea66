"""
Thermostat with hysteresis
==========================

A continuous temperature and a discrete mode in one state. The state is
x = (z, q): room temperature z and heater mode q in {0, 1} (a logic
variable carried as an ordinary state component). The room follows::

    zdot = -z + z_out + z_heat * q,

the heater switches on when z falls to z_min and off when z rises to z_max::

    D = {q = 0, z <= z_min} U {q = 1, z >= z_max},   q+ = 1 - q,
    C = {q = 0, z >= z_min} U {q = 1, z <= z_max}.

C and D overlap on the thresholds; priority="jumps" switches the heater there
at once. Continuous guards (the signed distance to the active threshold) give
exact event location, so the switching times match the closed form: the first
switch at ln((z_out + z_heat - z0) / (z_out + z_heat - z_max)) and then every
ln 2 for the numbers below.

Figures: the temperature coloured by mode (two ``plot_flows`` calls with
``filter=`` keeping one mode each) above the mode itself, whose switches are
jumps, on a shared t axis; and the hybrid time domain.

Run it with::

    python examples/thermostat.py [output_folder]

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

import hybridsim as hs

Z_OUT, Z_HEAT, Z_MIN, Z_MAX = 60.0, 30.0, 70.0, 80.0


class Thermostat(hs.HybridSystem):
    state_dim = 2

    def flow_map(self, x, t, j):
        return np.array([-x[0] + Z_OUT + Z_HEAT * x[1], 0.0])

    def jump_map(self, x, t, j):
        return np.array([x[0], 1.0 - x[1]])

    def jump_guard(self, x, t, j):     # D = {guard >= 0}: past the active threshold
        return x[0] - Z_MAX if x[1] > 0.5 else Z_MIN - x[0]

    def flow_guard(self, x, t, j):     # C = {guard >= 0}: inside the band (or heading to it)
        return Z_MAX - x[0] if x[1] > 0.5 else x[0] - Z_MIN


def switch_times(z0, n):
    """Closed-form switching times from (z0 < z_max, heater on)."""
    first = np.log((Z_OUT + Z_HEAT - z0) / (Z_OUT + Z_HEAT - Z_MAX))
    return first + np.log(2.0) * np.arange(n)


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    z0 = 65.0
    arc = hs.simulate(Thermostat(), [z0, 1.0], t_max=8.0, priority="jumps",
                      rtol=1e-10, atol=1e-12)
    err = np.max(np.abs(arc.jump_times - switch_times(z0, arc.jump_count)))
    print(f"{arc}\nswitching times {np.round(arc.jump_times, 6)}\n"
          f"largest error against the closed form: {err:.1e}")

    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7, 5),
                                   gridspec_kw={"height_ratios": [2, 1]})
    for z in (Z_MIN, Z_MAX):
        ax1.axhline(z, color="gray", lw=0.8, ls="--")
    ax1.text(0.02, Z_MIN, "$z_{min}$", va="bottom", color="gray",
             transform=ax1.get_yaxis_transform())
    ax1.text(0.02, Z_MAX, "$z_{max}$", va="top", color="gray",
             transform=ax1.get_yaxis_transform())
    # one mode per call: z is continuous at a switch, so no jump is lost
    hs.plot_flows(arc, 0, ax=ax1, filter=lambda x: x[1] > 0.5, color="C3",
                  labels=["heater on"], ylabel="temperature $z$", xlabel="")
    hs.plot_flows(arc, 0, ax=ax1, filter=lambda x: x[1] < 0.5, color="C0",
                  labels=["heater off"], ylabel="temperature $z$", xlabel="")
    hs.plot_flows(arc, 1, ax=ax2, labels=["mode $q$"], legend=False, color="k")
    ax2.set_yticks([0, 1], ["off (0)", "on (1)"])
    ax1.set_title("thermostat: temperature (top) and heater mode (bottom)")
    fig.tight_layout()
    fig.savefig(out / "thermostat_flows.png", dpi=100)

    ax = hs.plot_time_domain(arc)
    ax.set_title("thermostat: hybrid time domain (a jump at each switch)")
    ax.figure.savefig(out / "thermostat_time_domain.png", dpi=100)
    plt.close("all")
    print(f"figures written to {out}")
    return arc


if __name__ == "__main__":
    # the folder given, else $HYBRIDSIM_FIGURES, else the working folder
    OUT = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("HYBRIDSIM_FIGURES", ".")
    main(OUT)
