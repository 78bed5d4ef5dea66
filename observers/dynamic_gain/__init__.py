r"""Robust finite-time observer with a dynamic gain (paper 000) and its relatives.

Nekhoroshikh, Efimov, Polyakov, Perruquetti, Furtat, "On simple design of a
robust finite-time observer", CDC 2022 (hal-03778054).

Plant: the perturbed chain of integrators (1),
``x_i' = x_{i+1} + b_i u + d_{x,i}``, ``x_n' = b_n u + d_{x,n}``, ``y = x_1 + d_y``.

Observer (6)-(8), state ``(w, x_hat_1..x_hat_n, v, q)`` (``q`` is the settled
flag of decision 1)::

    w'       = y - x_hat_1 + z^{-rbar_0} L_0 w                          (6)
    x_hat_i' = x_hat_{i+1} + b_i u - z^{-rbar_i} L_i w   (x_hat_{n+1} := 0)
    v'       = gamma2 |w'| - gamma1 ceil(v - gamma2 |w|)^{1 - mu}        (8)
    z        = max{v, gamma2 |w|}                                        (7)

with ``rbar_i = (i+1) mu``.  Variants from the same code (``z_mode``):

* ``"max"`` and gamma2 > 0: the proposed observer;
* ``"max"`` and gamma2 = 0: the prescribed-time observer of Holloway-Krstic, z = v,
  settling time exactly ``T = v(0)^mu / (mu gamma1)`` (18);
* ``"abs"``: the homogeneous observer of Perruquetti et al., z = |w|; the filter (8)
  is kept with gamma2 = 0 as in Section VI (it does not act on the estimate);
* ``"max"``, gamma1 = gamma2 = 0: z = v(0) constant, the Luenberger (v(0) = 1) or
  high-gain (small v(0)) observer of Remark 1.

Files
-----
``design.py`` holds the paper's formulas and design computations in plain
numpy/scipy: the settling time (18), bound (17) with beta, Remark 1's gain,
the closed-form error via (13)-(16), the r-homogeneous norm, the argument
checks (the LMIs (10) are in :mod:`observers.lmi`). ``systems.py`` holds
every hybrid system: the observer (6)-(8) and its variants, the plant (1) of
Section VI (single runs and a vectorized batch under scaled disturbances),
and the Euler scheme of ref. [8] as a hybrid system with a jump per step.
``example.py`` holds Section VI's data and how a run is made and read
(:func:`simulate`, :func:`errors`, the measured settling times).
``figures.py`` computes each figure's numbers, then draws them (``FIGURES``,
``reproduce``): Figs. 1(a)-(b), 2(a)-(b), Euler vs Radau, and Proposition
5's ISS check over amplitudes and seeds. ``claims.py`` lists the paper's
checkable statements (``CLAIMS``), reading the figures' cached runs.

Settling time and 1e-6 crossing
-------------------------------
The *settling time* (Proposition 4, (17)-(18)) is when v, and with it e, reaches
0: :func:`gain_settling_time` (5.00 s for gamma2 = 0, 7.81 s for gamma2 = 1 in
Section VI's example). The *1e-6 crossing* is the last time max|e_i| > 1e-6,
located on the run's interpolant: :func:`settle_time` (4.79 s and 7.28 s).

Examples
--------
>>> from observers.dynamic_gain import EXAMPLE, prescribed_time_observer, simulate, errors
>>> from observers.dynamic_gain.example import gain_settling_time
>>> obs = prescribed_time_observer(EXAMPLE["L"], EXAMPLE["mu"], EXAMPLE["gamma1"],
...                                b=EXAMPLE["b"])
>>> arc = simulate(obs, EXAMPLE["x0"], [0.0, 0.0, 0.0], t_max=5.2)
>>> round(gain_settling_time(arc, obs), 4)             # T = v(0)^mu/(mu gamma1) of (18)
5.0
>>> bool(abs(errors(arc, obs).e[arc.t >= 5.0]).max() < 1e-7)
True

References
----------
.. [1] A. N. Nekhoroshikh et al., CDC 2022: observer (6)-(8), error system (9),
   LMIs (10), Theorem 3, Proposition 4 (17)-(18), Proposition 5, Section VI.
.. [8] D. Efimov, A. Polyakov, A. Aleksandrov, "Discretization of homogeneous
   systems using Euler method with a state-dependent step", Automatica 109, 2019.
"""
from __future__ import annotations

# every file's names are importable from here, as before; __all__ (below) is the
# public surface
from .claims import *
from .claims import CLAIMS
from .design import *
from .example import *
from .example import EXAMPLE, errors, simulate
from .falsification import *
from .falsification import PROBLEMS
from .figures import *
from .figures import FIGURES, NOT_REPRODUCED, reproduce
from .systems import *
from .systems import (
    DynamicGainObserver,
    homogeneous_observer,
    prescribed_time_observer,
    proposed_observer,
)

PAPER = {
    "id": "000",
    "title": "On simple design of a robust finite-time observer",
    "authors": "A. N. Nekhoroshikh, D. Efimov, A. Polyakov, W. Perruquetti, I. B. Furtat",
    "venue": "61st IEEE Conference on Decision and Control (CDC), Cancún, 2022 "
             "(hal-03778054)",
}

ERRATA = [
    "Section VI: the settling time of the prescribed-time observer is printed as "
    "T = v(0)/(mu gamma1); (18) and the gain dynamics v' = -gamma1 v^{1-mu} "
    "(Remark 1) give T = v(0)^mu/(mu gamma1). They agree only for v(0) = 1 (the "
    "example, T = 5); for v(0) = 2 the run settles at 2^0.2/0.2 = 5.74, not 10.",
    "Proof of Theorem 3 / Proposition 4, bound (17): dV/dtau <= -V with "
    "V = eps' P eps gives ||eps(tau)|| <= alpha ||eps(0)|| e^{-tau/2}, not e^{-tau}; "
    "integrating e^{-tau/2} doubles beta: beta(s) = 2 alpha gamma2 (1+|L0|) s + "
    "4 gamma1/(1-mu) (alpha gamma2 s)^{1-mu}. settling_time_bound uses the corrected "
    "beta by default (corrected=False gives the printed one).",
    "Proof of Theorem 3: 'zeta = gamma2|w| - v is negative for all t >= T0' holds only "
    "as 'non-positive': from v(0) just above gamma2|w(0)| with |w| growing, zeta "
    "reaches 0 and v slides on v = gamma2|w| (tested); (7) still gives z = v, so the "
    "proof stands.",
]

DECISIONS = [
    "1. At and after the settling time z -> 0 and z^{-rbar_i} w is 0 * inf, and the "
    "right-hand side is not Lipschitz. The gain uses max{z, z_min} (z_min = 1e-12), and "
    "a logic variable q jumps 0 -> 1 (v -> 0) when v reaches z_min (exact event location "
    "on the guard z_min - v); with q = 1 the filter (8) is stopped and "
    "z = max{gamma2|w|, z_min}. For gamma2 = 0 the switch occurs at "
    "T - z_min^mu/(mu gamma1) (0.02 s before T = 5 in the example), where the error is "
    "already ~1e-11. The run thus ends normally (T_MAX).",
    "2. Settling time (18) vs Section VI: (18)'s v(0)^mu/(mu gamma1) is used (erratum).",
    "3. Bound (17): settling_time_bound returns the corrected bound by default "
    "(erratum); the example's corrected bound exceeds the float range (log=True gives "
    "its logarithm, 713.5).",
    "4. mu interval: the observer accepts Section IV's 0 < mu <= 1/(n+1); the statements "
    "that need Theorem 3 (settling_time_bound, the LMI by default) require the open "
    "interval. At mu = 1/(n+1) (10) is still solvable (allow_mu_boundary=True) and the "
    "prescribed-time observer still settles exactly at (18) (tested).",
    "5. 'zeta < 0 obviously' is read as zeta <= 0 (erratum); gain_margin measures "
    "v - gamma2|w|.",
    "6. Noise: Section VI draws uniform omega in (-1, 1) at each Euler step; here omega "
    "is drawn every 0.01 s (the paper's base step), seeded, and linearly interpolated "
    "(uniform_noise), a continuous signal an adaptive solver can integrate.",
    "7. Integrator: Radau (rtol 1e-8, atol 1e-10) without noise, RK45 (rtol 1e-6, atol "
    "1e-10) with noise, through hs.simulate instead of the paper's Euler with "
    "state-dependent step [8]. With noise the kinks of the interpolated omega every 0.01 s "
    "cap every step, so the explicit method is ~4x cheaper than Radau and agrees with it to "
    "~1e-4 on the claims (max|e| over [6, 10]: 0.30660 vs 0.30667; escape at 4.9661 vs "
    "4.9656 s). The scheme of [8] is a hybrid system (ConsistentEuler: the state held over "
    "each step, a jump per step), run by hs.simulate (simulate(..., euler_dt0=1e-2)) and "
    "compared in euler_vs_radau.png.",
    "8. Settling time vs 1e-6 crossing: the settling time of Proposition 4 is measured "
    "as the time v reaches 0 (gain_settling_time: the switch v = z_min plus "
    "z_min^mu/(mu gamma1)); the last time max|e_i| > 1e-6 (settle_time, located by brentq "
    "on the run's interpolant between the last sample above and the next) is reported "
    "separately. For gamma2 = 1: 7.81 s and 7.28 s.",
    "9. Proposition 5 is checked over a seeded Monte Carlo (prop5_iss.png, claim "
    "000-prop5-iss-montecarlo): Section VI's disturbance pattern scaled to amplitudes "
    "0.01-0.3, noise seeds 0-3, the ultimate bound read as max|e_i| over t in [6, 10]; "
    "all runs in one vectorized batch (NoisyExamplePlant, hs.simulate_many, RK45 rtol 1e-4: "
    "the bounds agree with rtol 1e-6 to 0.3%).",
]

# the public surface: the contract's names and the paper's observer and design; the
# rest are imported from their files (observers.dynamic_gain.design, .systems...)
__all__ = ["PAPER", "ERRATA", "DECISIONS", "simulate", "errors", "FIGURES", "NOT_REPRODUCED",
           "reproduce", "CLAIMS", "PROBLEMS", "DynamicGainObserver", "proposed_observer",
           "prescribed_time_observer", "homogeneous_observer", "EXAMPLE"]
