"""Finite-time hybrid observers H_n, H_c and H_pc of Li and Sanfelice (paper 002).

The plant is the linear system (1)::

    xdot = A x,    y = H x + m,      x in R^n, y in R^p,

and the observers run two Luenberger-like copies x̂1, x̂2 with gains L1, L2
(F_i = A - L_i H Hurwitz) and, when the timer tau reaches delta, reset both to
``K1 x̂1 + K2 x̂2`` (nominal observer H_n, eqs. (10)-(12)), or to a combination
that also estimates a constant output bias m̂ (H_c, eqs. (17)-(18), one jump;
H_pc, Section IV-E, a jump every delta).

The package follows the layout of every paper package of :mod:`observers`
(and keeps the contract of :mod:`observers._common`). ``design.py`` holds the
paper's formulas and design computations, pure numpy/scipy: the gains K1, K2
of (12), the matrix T and H T - I of (18), the admissibility of delta
(Assumption 4.1 / Remark 4.4), Lemma 4.2, the errors (6) and (15) after the
jump, the bounds of Theorems 4.7, 4.10 and 4.11, the noise of Theorem 4.14
and seeded random designs for the tests. ``systems.py`` holds every
:class:`hybridsim.HybridSystem`: the observers H_n, H_c, H_pc, the
Luenberger observer (2) and a bounded noise source for batches.
``example.py`` holds the paper's example data (Sections III, V.A, V.B) and
how a run is made and read: ``simulate`` wires the engine's linear plant (1)
to an observer, ``errors`` reads the estimation errors off the arc,
``noise_batch`` sets up a Monte Carlo of noise realisations. ``monte_carlo.py``
restates the paper's noise studies as estimates with Clopper–Pearson
intervals (Theorem 4.10 and Fig. 2(b) under random bounded noise).
``figures.py`` computes the numbers of Figs. 1-3 and of those studies and
draws them (``FIGURES``, ``reproduce``), and ``claims.py`` lists every checkable statement of the
paper (``CLAIMS``) with the sweeps behind Theorems 4.9 and 4.11.

:data:`PAPER`, :data:`ERRATA` (what the paper gets wrong) and
:data:`DECISIONS` (numbered; "decision 5" in a docstring is ``DECISIONS[4]``)
are defined here; every decision is tested in ``tests/papers/li_sanfelice/test_li_sanfelice.py``.

Examples
--------
>>> import numpy as np
>>> from observers import li_sanfelice as ls
>>> d = ls.example_VB()                                    # design, Section V.B
>>> obs = ls.NominalObserver(d)                             # H_n (10)-(12)
>>> arc = ls.simulate(obs, [0.3, 0.4], [0.0, 0.0], t_max=2.0)   # with plant (1)
>>> E = ls.errors(arc, obs)
>>> bool(np.abs(E.e[arc.j == 1]).max() < 1e-8)             # exact after the jump (Thm 4.7)
True

References
----------
.. [1] Y. Li and R. G. Sanfelice, "A robust finite-time convergent hybrid
   observer for linear systems", IEEE CDC 2013.
"""
from __future__ import annotations

# every file's names are importable from here, as before; __all__ (below) is the
# public surface
from .claims import *
from .claims import CLAIMS
from .design import *
from .design import Design
from .example import *
from .example import errors, example_VB, simulate
from .falsification import *
from .falsification import PROBLEMS
from .figures import *
from .figures import FIGURES, NOT_REPRODUCED, reproduce
from .monte_carlo import *
from .systems import *
from .systems import ConstantNoiseObserver, NominalObserver, PiecewiseConstantNoiseObserver

#: The paper.
PAPER = {
    "id": "002",
    "title": "A robust finite-time convergent hybrid observer for linear systems",
    "authors": "Yuchun Li and Ricardo G. Sanfelice",
    "venue": "IEEE Conference on Decision and Control (CDC) 2013",
}

#: What the paper gets wrong, found while reproducing it.
ERRATA = [
    "Theorem 4.7: the constant sqrt(c2/c1) is short by a factor sqrt(3). The Lyapunov argument "
    "bounds |(e1, e2)|, and |z|_A <= |(e1, e2)| <= sqrt(3) |z|_A; errors that rotate apart "
    "(F1 = -I + J, F2 = -I - J, P_i = I/2) reach sqrt(3) times the printed bound at t = pi/2 "
    "(claim 002-thm4.7-constant, decision 9). This is the reading with P fixed (the "
    "constants of the P one solved for); read as printed, \"for some P\", the bound holds, "
    "another P trading the factor for a slower rate (problem 002-thm4.7-printed-some-P).",
    "Theorems 4.10-4.11: the hypothesis mu_bar(F2) < mu_(F1) makes sym((L2 - L1) H) positive "
    "definite, hence rank H = n: the bounds apply only when there are at least as many outputs "
    "as states (p >= n), which the theorems do not say (decision 8).",
]

#: Decisions taken where the paper is ambiguous (numbered as cited in the docstrings).
DECISIONS = [
    "1. The OCR'd jump map (9) ends with '1 - a'; it is '1 - q' as in (12), (18).",
    "2. The flow (11) writes L_i H x; with noise (14) the observer only knows y, so the flow "
    "implemented is F_i x̂_i + L_i y (identical when m = 0).",
    "3. Footnote 7 and the garbled definition of K1, K2 in Section IV-D are rebuilt from (12): "
    "K2 = (I - exp(F2 delta) exp(-F1 delta))^-1, K1 = I - K2; xi_i in R^{np} stacks p pieces of "
    "length n, the k-th piece is driven by the k-th column of L_i (L_tilde(L) = vec(L), column "
    "stacking), and sum_k I_k xi v_k^T is the n x p matrix whose k-th column is the k-th piece "
    "(Xi_matrix). Then T = K1 Xi1 + K2 Xi2 is n x p and H T - I is p x p, as (18) needs.",
    "4. Example V.B prints L1, L2 rounded to two decimals; they are 5 H^-1 and 8 H^-1 "
    "(F1 = A - 5I, F2 = A - 8I). example_VB uses the exact values by default (rounded=True "
    "gives the printed ones).",
    "5. Noise switches: m(t) = sum_k c_k chi_[d_{k-1}, d_k)(t) is right-continuous, as the paper "
    "defines it. The observer's input at hybrid time (t, j) is y(t, j) = H x(t, j) + m(t), so a "
    "jump exactly at a switch time sees the new noise value (the flow before it saw the old "
    "one): that jump is not exact (its error is T (H T - I)^-1 (c_new - c_old), "
    "switch_jump_error) and the next one is. PiecewiseConstantNoise takes side='left' for the "
    "other convention and snap so that a jump time located a few ulps off the switch is "
    "treated as on it.",
    "6. Theorem 4.14 asks delta < min(d_k - d_{k-1}) / 2 strictly; example V.B sits on the "
    "boundary (delta = 1, switches 2 apart). The claim tested is the theorem's: for each flow "
    "interval I_j a sub-interval of I_j U I_{j+1} with nonempty interior on which x̂_i = x, and "
    "exactness within 2 delta after each switch; not exactness after every jump.",
    "7. The estimate is x̄ = a1 x̂1 + a2 x̂2 with a1 + a2 = 1 (footnote 2, default 1/2 each). The "
    "KL bound (16) is stated for a1 = a2 = 1/2; for general weights the same proof gives the "
    "bound times |a1| + |a2| (= 1 when both lie in [0, 1]), which theorem_4_11_bound applies.",
    "8. The hypothesis mu_bar(F2) < mu_(F1) of Theorems 4.10-4.11 makes sym(F1 - F2) = "
    "sym((L2 - L1) H) positive definite, hence H of rank n: these bounds exist only for p >= n "
    "(checked, with an error saying so).",
    "9. Theorem 4.7 bounds |z|_A, the distance to {x = x̂1 = x̂2}; the Lyapunov argument bounds "
    "|(e1, e2)|, and |z|_A <= |(e1, e2)| <= sqrt(3) |z|_A, so the constant sqrt(c2/c1) must be "
    "multiplied by sqrt(3) in general (rotating errors reach it). theorem_4_7_bound includes "
    "that factor.",
    "10. Numerical thresholds: I - e^{F2 delta} e^{-F1 delta} counts as singular (K2 undefined) "
    "when its smallest singular value is below 1e-12 max(1, |e^{F2 delta} e^{-F1 delta}|); "
    "H T - I likewise relative to max(1, |H T|). H_c / H_pc warn (RuntimeWarning) when "
    "|(H T - I)^-1| exceeds 1e6, since m̂'s update multiplies every error by it.",
    "11. The observer (3) of Section I is H_n (no jump after the first one: K1 = I, K2 = 0 for "
    "x̂1 and K1 = 0, K2 = I for x̂2 are identities), so NominalObserver is also the observer of "
    "Section III's motivational example (no separate class), and the scalar observer (7)-(9) "
    "of Section III is ConstantNoiseObserver with n = p = 1.",
    "12. Theorem 4.9 gives no constant (only that some sigma* exists). Since H_n is linear in m, "
    "the distance between the noisy and the noise-free solution (same z_m(0,0), same hybrid time "
    "domain) is the response to the noise alone; the check uses C = sqrt(2) (gamma1(1) + gamma(1)) "
    "from Theorem 4.11's coefficients (each copy's difference is at most gamma sigma before the "
    "jump, (gamma1 + gamma) sigma after it), on example V.B and on seeded random designs with "
    "p = n and dissipative F_i, where those hypotheses hold (claims.closeness_random; for "
    "p < n only the linearity, distance / sigma one constant K, so sigma* = eps / K, is "
    "tested), and compares the two solutions on a grid of equal (t, j) through their dense "
    "output (claims.closeness_sweep).",
    "13. Theorem 4.11's (16) uses |m|_delta (sup over [0, delta]) and |m|_inf separately; the "
    "tight check computes |m|_delta as a grid maximum plus its Lipschitz margin (an upper bound "
    "tight to 4e-5 sigma), not |m|_inf, so the ratio |ē| / (16) is not diluted "
    "(claims.theorem_4_11_ratios).",
]

# the public surface: the contract's names and the paper's observer and design; the
# rest are imported from their files (observers.li_sanfelice.design, .systems...)
__all__ = ["PAPER", "ERRATA", "DECISIONS", "simulate", "errors", "FIGURES", "NOT_REPRODUCED",
           "reproduce", "CLAIMS", "PROBLEMS", "Design", "NominalObserver", "ConstantNoiseObserver",
           "PiecewiseConstantNoiseObserver", "example_VB"]
