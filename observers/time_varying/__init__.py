r"""Reduced-order finite-time observers for time-varying systems (paper 001).

Mazenc, Ahmed & Malisoff, *Reduced order finite time observers for
time-varying nonlinear systems*, CDC 2018. The observer returns the exact
value of the unmeasured part x_r of the state for every t >= tau, from the
output on the window [t - tau, t].

The package follows the layout of every paper package of :mod:`observers`
(and keeps the contract of :mod:`observers._common`). ``design.py`` holds the
paper's formulas and design computations, pure numpy/scipy: the coordinates
(4)-(5), M_tau (6) and the choice of L and tau, the literal estimates (15),
(23)/(27) and (49) by quadrature (references for the observer), Phi of (1)
(the paper's inverse convention), Lambda (20), Assumption 1, Remark 3
(25)-(26), the gain l(t) of (28), and the example's data (47)-(48), sigma
(54), zeta (52), the feedback (57), (58) evaluated literally and the
certified l_a of (28) on the example. ``systems.py`` holds every
:class:`hybridsim.HybridSystem`: the observer (23)/(27) as a hybrid system
(a timer and a window-filled flag; its output [P, G] gives xhat_r = P + G y),
the LTI observer (15), the plants (16) and (44), and the tracking loop
(44) + (58). ``example.py`` holds the example's initial data and how a run
is made and read: ``simulate(observer, x0, xhat0=None, *, t_max, noise=None,
seed=None, w=None, **simulate_kwargs)`` runs an observer with its plant,
``errors(arc, observer)`` returns the error xhat_r - x_r (an
:class:`observers._common.Errors`, under ``"e"``), ``loop_signals`` reads
a run of the loop. ``figures.py`` computes the numbers of Fig. 1 and of our
LTI figure and draws them (``FIGURES``, ``reproduce``), and ``claims.py``
lists every checkable statement of the paper (``CLAIMS``).

Examples
--------
>>> import numpy as np
>>> from observers import time_varying as tv
>>> obs, rc = tv.lti_observer([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, -2.0, -1.5]],
...                           [[1.0, 0.0, 0.0]], tau=0.5)
>>> arc = tv.simulate(obs, [1.0, -1.0, 0.5], t_max=1.5)
>>> bool(np.abs(tv.errors(arc, obs).e[arc.j >= 1]).max() < 1e-7)    # (14): x_r exact after tau
True

Conventions and decisions (a careful reading of the paper)
----------------------------------------------------------
See :data:`DECISIONS` and :data:`ERRATA`; each is tested in
``tests/papers/time_varying/test_time_varying.py`` and pinned in :data:`CLAIMS` where it has a
number.

References
----------
.. [1] F. Mazenc, S. Ahmed, M. Malisoff, "Reduced order finite time observers
   for time-varying nonlinear systems", 57th IEEE CDC, 2018, eqs. (1)-(59).
"""
# every file's names are importable from here, as before; __all__ (below) is the
# public surface
from .claims import *
from .claims import CLAIMS
from .design import *
from .example import *
from .example import errors, simulate
from .falsification import *
from .falsification import PROBLEMS
from .figures import *
from .figures import FIGURES, NOT_REPRODUCED, reproduce
from .systems import *
from .systems import (
    ReducedOrderObserver,
    TimeVaryingPlant,
    chained_form_observer,
    lti_observer,
    tracking_loop,
)

PAPER = {
    "id": "001",
    "title": "Reduced order finite time observers for time-varying nonlinear systems",
    "authors": "Frédéric Mazenc, Saeed Ahmed, Michael Malisoff",
    "venue": "57th IEEE Conference on Decision and Control (CDC 2018), Miami",
}

ERRATA = [
    "(50) is exact for t >= 2 pi + sqrt|x1(0)|, not for t >= max{2 pi, sqrt|x1(0)|} as printed: "
    "the model (45) holds only where x1 = 0 (t >= sqrt|x1(0)|) and (50) integrates it over the "
    "whole window [t - 2 pi, t]. With the paper's x1(0) = 0.5 (the closed loop of Fig. 1), once "
    "the observer's window fills at t = 2 pi the estimate (50) is off by 6.5e-6 (its largest "
    "error on [2 pi, 2 pi + 1/sqrt 2), at t = 2 pi; it decreases to 0 at 2 pi + 1/sqrt 2) and "
    "is exact (3e-10) after.",
    "Under the bounded feedback (57) the origin of (51) is uniformly globally asymptotically, not "
    "exponentially, stable: |v2| <= 1 gives |zeta3(t)| >= |zeta3(0)| - t, which no global "
    "exponential bound allows.",
    "\"Assumption 2\" in the proof of Theorem 1 is Assumption 1.",
    "Remark 3's condition |Phi_A2^{-1} Phi_H| <= varpi < 1 does not hold on the paper's own "
    "example (varpi = e^{4 pi}); the swapped condition |Phi_H^{-1} Phi_A2| < 1 "
    "(varpi = e^{-4 pi}) does, with the same argument.",
]

DECISIONS = [
    "Phi of (1) is the inverse fundamental matrix (dPhi/dt = -Phi Omega), as printed, everywhere: "
    "it gives Lambda = 1 - e^{4 pi} on the example, as the paper states.",
    "The window integrals of (23) are computed by two observer states J_A' = A2 J_A + delta2, "
    "J_H' = H J_H + delta4 and the semigroup identity Phi(m, t - tau) = Phi(t, t - tau) Phi(m, t): "
    "int = Phi(t, t - tau) J(t) - J(t - tau), with J(t - tau) read from the engine's history "
    "(O(1) per step instead of a quadrature over the window).",
    "The observer is a hybrid system with a timer s and a flag q; its one jump, at s = tau, marks "
    "the window as filled. Before tau the estimate is held at xr_init (default 0).",
    "(23) contains y(t) itself, and the engine forbids outputs that read their input: the observer "
    "outputs (P, G) with xhat_r = P + G y.",
    "(58) is built as the observer fed back through (57): v2(t) enters (58) only under an "
    "integral, so it is a distributed-delay equation, not an algebraic loop; the residual of "
    "(58) evaluated literally along a run is below 1e-8.",
    "x1's arrival at 0 (x1' = -2 sign(x1) sqrt|x1| is not Lipschitz there) is modelled as a jump "
    "of the plant to x1 = 0 when |x1| <= eta = 1e-10, so x1 is exactly 0 afterwards, as in the "
    "paper.",
    "l_a of (28) on the example (the paper asserts it exists, prints none) is sup_t l(t), "
    "certified: l has period pi, its maximum over a grid of spacing pi / 2^18 is a lower bound "
    "and |l'| <= |D| + 4 l + 2 (e^{4 pi} + 1) / (e^{4 pi} - 1) turns it into an upper bound "
    "(design.example_gain_sup): l_a in [4.09216, 4.09232].",
    "Not given by the paper and chosen by us: xi4(0) = 1, xi3(0) = -1, xi2(0) = 0.5 (the paper "
    "gives only x1(0) = 0.5), the horizon 60 of Fig. 1, and xr_init = 0.",
]

# the public surface: the contract's names and the paper's observer and design; the
# rest are imported from their files (observers.time_varying.design, .systems...)
__all__ = ["PAPER", "ERRATA", "DECISIONS", "simulate", "errors", "FIGURES", "NOT_REPRODUCED",
           "reproduce", "CLAIMS", "PROBLEMS", "ReducedOrderObserver", "TimeVaryingPlant",
           "lti_observer", "chained_form_observer", "tracking_loop"]
