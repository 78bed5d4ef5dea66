r"""Reduced-order finite-time observers for time-varying systems (paper 001).

Mazenc, Ahmed & Malisoff, *Reduced order finite time observers for
time-varying nonlinear systems*, CDC 2018. The observer returns the exact
value of the unmeasured part x_r of the state for every t >= tau, from the
output on the window [t - tau, t].

Layout (the calling pattern of :mod:`observers`)
------------------------------------------------
* ``design.py``: Sections II-III: (4)-(6), (15), Phi of (1), Lambda (20),
  Assumption 1, Remark 3 (25)-(26), (21)-(23), (27), l(t) of (28).
* ``systems.py``: :class:`ReducedOrderObserver` (the observer as a hybrid
  system), :func:`lti_observer` (15), :class:`TimeVaryingPlant` (16),
  :class:`ChainedFormPlant` (44).
* ``example.py``: Section IV: (47)-(50), (52), (57), the loop (58)-(59);
  :func:`simulate`, :func:`estimates`, :func:`errors`.
* ``figures.py``: :func:`reproduce` (Fig. 1 and the LTI figure).
* ``claims.py``: ``CLAIMS``.

1. Design: :func:`reduced_coordinates`, :func:`choose_L_tau` (LTI) or the
   data A1, A2, L, Phi_A2, Phi_H of (16) and Assumption 1
   (:func:`check_assumption1`).
2. Observer: :class:`ReducedOrderObserver` (or :func:`lti_observer`,
   :func:`chained_form_observer`).
3. Run: ``simulate(observer, x0, xhat0=None, *, t_max, noise=None,
   seed=None, w=None, **simulate_kwargs)``.
4. Errors: ``errors(arc, observer)``, xhat_r - x_r, shape (N, m).

Examples
--------
>>> import numpy as np
>>> from observers import time_varying as tv
>>> obs, rc = tv.lti_observer([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, -2.0, -1.5]],
...                           [[1.0, 0.0, 0.0]], tau=0.5)
>>> arc = tv.simulate(obs, [1.0, -1.0, 0.5], t_max=1.5)
>>> bool(np.abs(tv.errors(arc, obs)[arc.j >= 1]).max() < 1e-7)    # (14): x_r exact after tau
True

Conventions and decisions (a careful reading of the paper)
----------------------------------------------------------
See :data:`DECISIONS` and :data:`ERRATA`; each is tested in
``tests/test_time_varying.py`` and pinned in :data:`CLAIMS` where it has a
number.

References
----------
.. [1] F. Mazenc, S. Ahmed, M. Malisoff, "Reduced order finite time observers
   for time-varying nonlinear systems", 57th IEEE CDC, 2018, eqs. (1)-(59).
"""
from .claims import CLAIMS
from .design import (
    D_of,
    FundamentalMatrix,
    Lambda,
    M_tau,
    ReducedCoordinates,
    Remark3Result,
    check_assumption1,
    choose_L_tau,
    delta3,
    delta4,
    estimate_15,
    estimate_23,
    fundamental_matrix,
    is_observable,
    noise_gain,
    phi_scalar,
    reduced_coordinates,
    remark3,
)
from .example import (
    TAU_EXAMPLE,
    bounded_noise,
    chained_form_observer,
    error_norm,
    errors,
    estimate_49,
    estimates,
    example_data,
    loop_signals,
    residual_58,
    sigma,
    simulate,
    tracking_initial_state,
    tracking_loop,
    v2_feedback,
    zeta_of,
)
from .figures import reproduce
from .systems import (
    ChainedFormPlant,
    PlantModel,
    ReducedOrderObserver,
    TimeVaryingPlant,
    lti_observer,
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
    "whole window [t - 2 pi, t]. With the paper's x1(0) = 0.5 the estimate is off by up to 2.1 on "
    "[2 pi, 2 pi + 1/sqrt 2) and exact (3e-10) after.",
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
    "Not given by the paper and chosen by us: xi4(0) = 1, xi3(0) = -1, xi2(0) = 0.5 (the paper "
    "gives only x1(0) = 0.5), the horizon 60 of Fig. 1, and xr_init = 0.",
]

__all__ = [
    "PAPER", "ERRATA", "DECISIONS", "CLAIMS",
    # design (Sections II-III)
    "ReducedCoordinates", "reduced_coordinates", "is_observable", "M_tau", "choose_L_tau",
    "estimate_15", "FundamentalMatrix", "fundamental_matrix", "phi_scalar", "Lambda",
    "check_assumption1", "Remark3Result", "remark3", "D_of", "delta3", "delta4", "estimate_23",
    "noise_gain",
    # systems
    "PlantModel", "ReducedOrderObserver", "TimeVaryingPlant", "lti_observer", "ChainedFormPlant",
    # the example and runs
    "TAU_EXAMPLE", "example_data", "estimate_49", "sigma", "zeta_of", "v2_feedback",
    "chained_form_observer", "tracking_loop", "tracking_initial_state", "loop_signals",
    "residual_58", "simulate", "estimates", "errors", "error_norm", "bounded_noise",
    # figures
    "reproduce",
]
