"""Paper 003: finite-time distributed observer for LTI systems over a directed graph.

Silm, Efimov, Michiels, Ushirobira and Richard, "A simple finite-time
distributed observer design for linear time-invariant systems", Systems &
Control Letters 141 (2020) 104707.

The plant is ``xdot = A x``, ``y^i = C^i x`` (1); node ``i`` of a networkx
``DiGraph`` measures ``y^i`` and receives the full estimates of its
in-neighbours (edge ``j -> i``: node ``i`` receives from node ``j``).

The package's files, each with one role (imports run downward):
``design.py`` holds the paper's formulas and design computations (the graph
matrices of Section 2, the decomposition (2), the canonical form of Section
3.1, Proposition 2's bound, :func:`design` returning a
:class:`DistributedDesign`, Proposition 1 and LMI (10)-(11)); ``systems.py``
every hybrid system (the nodes (7)-(8) / (4)-(5), the plant-observer network
over ``hs.network``, the error system (6)-(9), the noise generator) and
:class:`DistributedObserver`, the observer the contract's ``simulate`` and
``errors`` take; ``example.py`` Section 4's example, random networks and how a
run is made and read (:func:`simulate`, :func:`errors`, :func:`simulate_errors`,
:func:`settling_time`); ``figures.py`` Figs. 2-3 as data and drawings
(:data:`FIGURES`, :func:`reproduce`); ``claims.py`` the :data:`CLAIMS`.

1. **Design**: ``design(A, C, G, nodelist, kind=, poles=, nu=, alpha=, beta=)``.
2. **Observer**: ``DistributedObserver(dsg)``: one node per node of ``G``,
   each receiving its measurement and its in-neighbours' estimates.
3. **Run**: ``simulate(observer, x0, xhat0=None, *, t_max, noise=None,
   seed=None, ...)``; components ``"plant"`` and one per node. Addition:
   :func:`simulate_errors` runs the error system (6)-(9) itself.
4. **Errors**: ``errors(arc, observer)``: an :class:`observers._common.Errors`
   with the stacked errors ``(E_o, E_u)`` of (6) under ``"e"``.

Decisions where the paper is ambiguous (each one is tested)
-----------------------------------------------------------
1. **Laplacian sign.** The text writes ``𝓛 = 𝒜 − 𝒟``, but the error system
   (6) obtained from (5), Proposition 1 and the Appendix ("𝓛 has a unique
   zero eigenvalue ... all the other eigenvalues are strictly larger") all
   need ``𝓛 = 𝒟 − 𝒜``: then ``Σ_j a_ij (e^i − e^j) = [(𝓛 ⊗ I) E]_i`` and
   ``−α T_uᵀ(𝓛⊗I)T_u`` is the (Hurwitz) consensus term.  We use
   ``𝓛 = 𝒟 − 𝒜`` (rows sum to zero, non-negative spectrum).
2. **Dimensions in (9) and the proof of Theorem 1.** ``T_uᵀ 𝒜 T_o`` is read
   as ``T_uᵀ (𝒜 ⊗ I_n) T_o``; ``x̃_j`` in (8) is the estimate ``x̃^j``.
3. **The power in (7).** ``[1 (C_o x̃_o − y)]^γ`` is the scalar output error
   copied into an ``n_i``-vector and raised element-wise to
   ``γ_k = 1 + k ν_i`` (k = 1..n_i) with its sign kept.
4. **Orientation of the canonical form.** ``𝓘`` is the upper shift
   (ones on the super-diagonal) and ``Θ^{-1} A_o Θ = 𝓘 − p e_1ᵀ`` with
   ``C_o Θ = e_1ᵀ`` and ``p`` the coefficients of ``det(sI − A_o) =
   s^{n_i} + p_1 s^{n_i−1} + ... + p_{n_i}``; the error of (7) in
   Θ-coordinates is then ``ε̇_k = ε_{k+1} − L_k ⌈ε_1⌋^{γ_k}``, and
   ``L_o^i`` holds the coefficients of the monic Hurwitz polynomial
   ``s^{n_i} + L_1 s^{n_i−1} + ... + L_{n_i}`` (Prop. 2).  With ``ν_i = 0``,
   (7) is the Luenberger observer (4) with gain ``Θ (L − p)``.
5. **Vector outputs.** Section 3.1 defers to its ref. [15] for ``m_i > 1``.
   The linear observer (3)-(5) accepts vector outputs (gain by pole
   placement).  For the finite-time observer we follow the paper's own
   Conclusion: each entry of a vector output is given to an imaginary node;
   :func:`split_vector_outputs` builds that graph (the imaginary nodes of one
   physical node form a complete digraph and inherit its in- and out-edges),
   and :func:`design` raises for ``m_i > 1`` when ``kind="finite-time"``.
6. **Proposition 2 norm.** ``‖P diag(L_o^i)‖`` is the spectral norm; ``P``
   is scaled so that ``λ_min(P) = 1`` (the smallest ``P ⪰ I``, which
   maximises ``η`` for a given ``Q``).
7. **Rank tolerance.** The rank of the observability matrix counts the
   singular values above ``rtol * σ_max`` (default ``rtol = 1e-9``).
8. **Proposition 2 is only sufficient.** For the example, ``η`` gives
   ``ν_min ≈ −4.4e-3`` (``n_i = 2``) and ``≈ −3.3e-9`` (``n_i = 5``): the
   paper's ``ν = −0.1`` is outside it; the simulations converge anyway.
9. **Fig. 1 is missing:** :func:`example_system` uses the ring
   ``1 -> 2 -> 3 -> 4 -> 1``.

Simulation
----------
All runs go through ``hs.simulate`` (RK45, ``rtol = 1e-10``, ``atol =
1e-13`` for the network). The example's plant is unstable;
:func:`stable_initial_state` starts it in its stable subspace so that ``|x|``
(and the rounding of ``x̃ − x``) stays small: the error dynamics do not
depend on ``x``. The error system (:func:`simulate_errors`) has no plant at
all, so Theorem 1's settling time is measured there to 1e-8 and below.

Examples
--------
>>> from observers.distributed import (DistributedObserver, design, errors, example_system,
...                                    simulate)
>>> from observers.distributed.design import lmi11
>>> A, C, G = example_system()
>>> dsg = design(A, C, G, nodelist=[1, 2, 3, 4], nu=-0.1, alpha=10.0, beta=0.7)
>>> dsg.n_o, bool(lmi11(dsg).feasible)
([2, 2, 5, 5], True)
>>> obs = DistributedObserver(dsg)
>>> arc = simulate(obs, [0.0] * 6, [0.1] * 6, t_max=0.05)
>>> errors(arc, obs).e.shape == (arc.t.size, 24)
True

References
----------
.. [1] H. Silm et al., Systems & Control Letters 141 (2020) 104707,
       eqs. (1)-(11), Propositions 1-2, Lemma 1, Theorem 1, Remarks 1-2.
"""
# every file's names are importable from here, as before; __all__ (below) is the
# public surface. ``design`` is the function: the module is observers.distributed.design
from .claims import *
from .claims import CLAIMS
from .design import *
from .design import DistributedDesign, design
from .example import *
from .example import errors, example_system, simulate
from .falsification import *
from .falsification import PROBLEMS
from .figures import *
from .figures import FIGURES, NOT_REPRODUCED, reproduce
from .systems import *
from .systems import DistributedObserver

PAPER = {
    "id": "003",
    "title": "A simple finite-time distributed observer design for linear time-invariant "
             "systems",
    "authors": "H. Silm, D. Efimov, W. Michiels, R. Ushirobira, J.-P. Richard",
    "venue": "Systems & Control Letters 141 (2020) 104707",
}

ERRATA = [
    "Sec. 2: the Laplacian is written L = A - D; the error system (6) derived from (5), "
    "Proposition 1 and the Appendix (unique zero eigenvalue, all others larger) need "
    "L = D - A (rows summing to zero, non-negative spectrum); on the example's ring the "
    "text's A - D has nonzero eigenvalues with real parts -1, -2, -1 (claim "
    "003-sec2-laplacian); we use D - A and test that (6) then equals the stacked "
    "observer (3).",
    "Prop. 2 / Sec. 4: the example's nu_i = -0.1 lies outside Proposition 2's sufficient "
    "range (nu_min = -4.4e-3 for n_i = 2, -3.3e-9 for n_i = 5); the observer converges in "
    "finite time anyway (the bound is conservative, not wrong).",
]

DECISIONS = [
    "L = D - A with in-degrees, a_ij = 1 for an edge j -> i (the text's A - D has the wrong "
    "sign).",
    "(9) and the proof of Theorem 1: T_u^T A T_o is read as T_u^T (A kron I_n) T_o; x_j in "
    "(8) is the estimate of node j.",
    "(7): [1 (C_o x_o - y)]^gamma is the scalar output error copied into an n_i-vector and "
    "raised element-wise to gamma_k = 1 + k nu_i with its sign kept.",
    "Canonical form: upper-shift integrator chain, C_o Theta = e_1^T, L_o^i the coefficients "
    "of the monic Hurwitz polynomial (all poles -3 at nu = 0, Sec. 4).",
    "Vector outputs: the finite-time observer (7) needs scalar outputs; each entry goes to "
    "an imaginary node (the paper's Conclusion, split_vector_outputs).",
    "Prop. 2: ||P diag(L)|| is the spectral norm, P scaled to lambda_min(P) = 1.",
    "Rank tolerance of the observability matrices: singular values above 1e-9 sigma_max.",
    "Fig. 1 (the graph) is missing from the text: the directed ring 1 -> 2 -> 3 -> 4 -> 1.",
    "The example gives no initial state: x(0) is the projection of (1, -1, 0.5, 0, 1, -0.5) "
    "on A's stable subspace, x_hat^i(0) = 0.",
    "Theorem 1's settling time is measured on the error system (6)-(9) itself "
    "(simulate_errors), where no plant leaves a rounding floor, and checked against the "
    "same equations integrated by scipy's solve_ivp.",
]

# the public surface: the contract's names and the paper's observer and design; the
# rest are imported from their files (observers.distributed.design, .systems...)
__all__ = ["PAPER", "ERRATA", "DECISIONS", "simulate", "errors", "FIGURES", "NOT_REPRODUCED",
           "reproduce", "CLAIMS", "PROBLEMS", "design", "DistributedDesign", "DistributedObserver",
           "example_system"]
