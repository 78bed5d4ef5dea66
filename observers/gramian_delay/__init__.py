r"""Fixed-time Gramian observers with a single delay (Mazenc & Malisoff, paper 004).

The paper builds reduced-order observers for systems affine in the
unmeasured state, written in the coordinates (2)::

    xi1' = A1 xi1 + F1(xi2, t) + eps1,   xi2' = A2 xi1 - k xi2 + F2(xi2, t) + eps2,
    Y = xi2 + delta2,

with a dynamic extension (7) and an estimate (13) that reads the extension
at ``t - tau`` only. With continuous measurements the estimate is exact for
``t >= tau`` (Theorem 1); with sampled measurements a variable omega is
reset to each sample (39) and the error decays exponentially when
``T_bar mu < 1`` (40) (Theorem 2).

The package follows the calling pattern of :mod:`observers`, one role per
file, each importing only the ones before it. ``design.py`` holds the paper's
formulas and design computations (numpy and scipy only): the coordinates (2),
lambda (4), the Gramian S (5) with N, R, H (6), the constants of Theorems 1
and 2 and the sampling instants (36). ``systems.py`` holds every hybrid
system: the plant (1) (and the DC motor (65) as one), the observer (7) with
its estimate (13) in the two realisations of psi_2 (decision 8), and the
sampled observer (39). ``example.py`` holds the paper's example, Section V's
DC motor with its data, and how a run is made (``simulate``) and read
(``errors``). ``monte_carlo.py`` restates Fig. 1's sampled observer under
random sampling gaps as an estimate with a Clopper–Pearson interval.
``figures.py`` computes and draws Figs. 1 and 2, our study of the sampling
period and that estimate (``FIGURES``; Fig. 3 is not reproduced, decision
9). ``every_gap.py`` checks Theorem 2's conclusion (42) on an example where
its hypothesis (40) holds, over every gap sequence of a prefix and by a
search over free gaps beside random sampling. ``claims.py`` lists the
paper's checkable statements (``CLAIMS``).

:data:`PAPER`, :data:`ERRATA` and :data:`DECISIONS` (numbered; "decision 3"
in a docstring is ``DECISIONS[2]``) are defined here; each decision is tested
in ``tests/papers/gramian_delay/test_gramian_delay.py``.

Examples
--------
>>> import numpy as np
>>> from observers import gramian_delay as gd
>>> ex = gd.dc_motor(k=100.0, tau=0.1, disturbed=False)      # Section V, (65)-(67)
>>> obs = ex.continuous_observer()                           # (7)
>>> arc = gd.simulate(obs, ex.chi0, None, t_max=0.3)         # with the plant (65)
>>> e = gd.errors(arc, obs).e                                # xi_1 - xi_e, (13)
>>> bool(np.abs(e[arc.t >= 0.1]).max() < 1e-8)              # Theorem 1: exact after tau
True

References
----------
.. [1] F. Mazenc, M. Malisoff, "New finite-time and fast converging
   observers with a single delay", IEEE Control Systems Letters 6 (2022)
   1561-1566, hal-03430682.
.. [2] C. Van Loan, "Computing integrals involving the matrix exponential",
   IEEE Trans. Automat. Control 23(3) (1978) 395-404.
"""
from __future__ import annotations

# every file's names are importable from here, as before; __all__ (below) is the
# public surface
from .claims import *
from .claims import CLAIMS
from .design import *
from .design import gramian_design
from .example import *
from .example import dc_motor, errors, simulate
from .falsification import *
from .falsification import PROBLEMS
from .figures import *
from .figures import FIGURES, NOT_REPRODUCED, reproduce
from .monte_carlo import *
from .systems import *
from .systems import GramianObserver, Plant, SampledGramianObserver

#: The paper.
PAPER = {
    "id": "004",
    "title": "New finite-time and fast converging observers with a single delay",
    "authors": "Frédéric Mazenc and Michael Malisoff",
    "venue": "IEEE Control Systems Letters 6 (2022) 1561-1566",
}

#: What the paper gets wrong or leaves out, found while reproducing it.
ERRATA = [
    "(39) and (45): the flow of the estimate of xi_2 is printed 'A2 xi_hat2 - k xi_hat2'; A2 is "
    "q x (n-q), so this cannot be evaluated when q != n - q, and it contradicts (7) and the "
    "error system (18). It must read 'A2 xi_hat1' (decision 1, claim 004-eq39-A2-typo).",
    "Theorem 2, (40): on the paper's own example (k = 100, tau = 0.1, T_bar = 0.1) the "
    "constants (38), (41) give T_bar mu ~ 4e19, so (40) fails by ~20 orders of magnitude and "
    "the theorem guarantees nothing for the simulated Fig. 1 (right); (40) would need "
    "T_bar < 2.5e-21 s (claims 004-eq40-*).",
    "Section V and (7): psi_2 flows with -(A1^T + 2kI), unstable when 2k < -min Re eig(A1) "
    "(k < 98.6 on the DC motor; k = 75 of Fig. 2 gives +47.2/s). The paper does not say so; "
    "integrated literally, the run of Fig. 2 at k = 75 blows up at t ~ 0.57 s. The reset "
    "realisation (decision 8) keeps Theorem 1's exactness over any horizon.",
]

#: Decisions taken where the paper is ambiguous (numbered as cited in the docstrings).
DECISIONS = [
    "1. Typo in (39) and (45): the xi_hat2 flow is A2 xi_hat1 - k xi_hat2 + F2(omega, t), as in "
    "(7) (the printed A2 xi_hat2 cannot be evaluated when q != n - q).",
    "2. Which xi_2 enters xi_e in (39): (13) uses the unmeasured xi_2(t). The implementable "
    "observer uses omega(t) (estimate='omega', the default); the literal reading "
    "(estimate='xi2') needs xi_2(t) as an extra input and is kept as an oracle. With omega the "
    "proof of Theorem 2 goes through with q1 + |R| in place of q1 (xi_e(omega) = xi_e(xi2) - "
    "R (xi2 - omega)); theorem2_constants reports both.",
    "3. The history before tau: (13) reads psi_i(t - tau), undefined for t - tau < t0. psi_i is "
    "continued backwards by its free response, i.e. the windows behind (52)-(53) are "
    "truncated to [t0, t]; the estimate before t0 + tau is then not exact (nor claimed) and "
    "never depends on psi_i(t0).",
    "4. Continuous-case estimate under noise: (13) uses xi_2(t); the implementable estimate "
    "uses Y(t) = xi_2(t) + delta_2(t) and so differs by R delta_2(t). estimate() takes "
    "whichever signal is passed; the bound (15) is for the literal (13).",
    "5. Sampling bounds: (36) asks T_min < T_bar strictly, yet Section V uses "
    "T_bar = T_min = 0.1 (periodic sampling). T_min = T_bar is allowed.",
    "6. Accuracy of S: S is badly conditioned on the DC motor (cond(S) ~ 1.4e5 at k = 100, "
    "5.9e6 at k = 75). S and N come from one augmented matrix exponential each (Van Loan) and "
    "are checked against adaptive quadrature.",
    "7. Section V's control and disturbances come from the paper's ref. [6], which we do not "
    "have: u(t) = 2 sin 2t, chi(0) = (0.5, -1, 0.2), delta_1(t) = (0, 0.5 sin 5t, 0.5 cos 3t), "
    "delta_2(t) = 1e-3 sin 20t are our choices, named in every caption.",
    "8. Realisation of psi_2 (realisation='reset'): (13) uses psi_2 only through the window "
    "integral I_2(t) = psi_2(t) - e^{-(A1^T+2kI)tau} psi_2(t - tau) (53). A timer resets every "
    "tau: p (flowing as psi_2) is reset to 0, phi = e^{-(A1^T+2kI) rho} p(t_r^-) carries the "
    "last window, and I_2 = p + phi - e^{-(A1^T+2kI)tau} p(t - tau). Equal to the literal (7) "
    "in exact arithmetic, bounded whatever k: Theorem 1's exactness then holds at k = 75 over "
    "the whole horizon (the literal realisation blows up at t ~ 0.57 s). The literal one stays "
    "the default.",
    "9. Fig. 3 (the observers of the paper's ref. [10], 'Theorems 1 and 2 of [10]' with "
    "L = [-1, 3]^T, nu = 0.1, g = 20) is not reproduced: the paper does not state those "
    "observers (only their three parameters), and [10] (Mazenc, Malisoff & Jiang, SCL 150 "
    "(2021) 104892) is not among the papers given. Implementing a guess would not be a "
    "reproduction.",
    "10. The falsification populations (falsification.simulate_population) run on the "
    "engine: the package's model (dc_motor, its observers, example.population; Theorem 1's "
    "per-row disturbances in the plant's state, PiecewiseDisturbed) as one batch of "
    "hs.simulate_many with method='RK4', the classic Runge-Kutta method at the fixed step "
    "h = 2e-3 (a divisor of tau, of every sampling period and of every disturbance piece). "
    "The compiled path has no RK4 (refused by name), so backend='auto' runs the numpy "
    "batch. Tests hold the runs to the package's adaptive runs (2e-3 after tau).",
]

# the public surface: the contract's names and the paper's observer and design; the
# rest are imported from their files (observers.gramian_delay.design, .systems...)
__all__ = ["PAPER", "ERRATA", "DECISIONS", "simulate", "errors", "FIGURES", "NOT_REPRODUCED",
           "reproduce", "CLAIMS", "PROBLEMS", "gramian_design", "GramianObserver",
           "SampledGramianObserver", "Plant", "dc_motor"]
