"""Linear matrix inequalities of the dynamic-gain (000) and distributed (003) designs.

Two layers:

* **Generic helpers** (used by both papers): :func:`solve_sdp` solves a cvxpy
  problem with Clarabel and raises :class:`LMISolverError` unless the solver
  reports ``optimal``; :func:`lmi_margin` / :func:`verify_lmi` /
  :func:`verify_lmis` check a *solved* LMI numerically with eigenvalues and raise
  :class:`LMIVerificationError` when it does not hold.  Solver status alone is not
  trusted: with no solver named cvxpy sends SDPs to SCS, whose default accuracy can
  report "optimal" for a point that violates the LMI.

* **LMI (10)** of Nekhoroshikh et al. (paper 000): :func:`solve_lmi10` returns
  ``L = P^{-1} Y`` for given ``n, mu, gamma1``; :func:`check_gain_lmi10` decides
  whether a *given* gain ``L`` (e.g. the paper's printed one) satisfies (10) for some
  ``P``; :func:`lmi10_residuals` evaluates the three left-hand sides for a pair
  ``(P, Y)``.

cvxpy and clarabel form the optional ``lmi`` extra; they are imported lazily so
that ``import observers.lmi`` works without them (only the solvers need them).

Relation strings used throughout: ``"<= 0"`` (negative semidefinite),
``"< 0"`` (negative definite), ``">= 0"`` (positive semidefinite), ``"> 0"``
(positive definite).

Examples
--------
>>> import numpy as np
>>> from observers.lmi import verify_lmi
>>> verify_lmi(np.diag([1.0, 2.0]), "> 0", name="P")     # returns the margin
1.0
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "LMIError",
    "LMISolverError",
    "LMIVerificationError",
    "require_cvxpy",
    "solve_sdp",
    "lmi_margin",
    "verify_lmi",
    "verify_lmis",
    "lmi10_matrices",
    "lmi10_residuals",
    "LMI10Result",
    "solve_lmi10",
    "check_gain_lmi10",
    "PAPER_L",
]

#: The gain printed in Section VI of paper 000 for n = 3, mu = 0.2, gamma1 = 1.
PAPER_L = -np.array([6.98, 28.60, 44.46, 23.04])

_RELATIONS = ("<= 0", "< 0", ">= 0", "> 0")


class LMIError(RuntimeError):
    """Base class of the LMI failures of this module."""


class LMISolverError(LMIError):
    """The SDP solver did not return an optimal (feasible) point."""


class LMIVerificationError(LMIError):
    """A solved LMI does not hold when checked with eigenvalues."""


# ---------------------------------------------------------------------------
# generic helpers
# ---------------------------------------------------------------------------
def require_cvxpy():
    """Import and return :mod:`cvxpy`, with a clear message when it is missing.

    Raises
    ------
    ImportError
        If cvxpy (optional extra ``lmi``) is not installed.
    """
    try:
        import cvxpy as cp
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "the LMI solvers need cvxpy and clarabel (optional extra 'lmi'): "
            "pip install cvxpy clarabel") from exc
    return cp


def solve_sdp(objective, constraints, *, solver="CLARABEL", verbose=False,
              **solver_options):
    """Solve a cvxpy problem with Clarabel and insist on an optimal status.

    Parameters
    ----------
    objective : cvxpy.Minimize, cvxpy.Maximize or None
        None means a feasibility problem (``Minimize(0)``).
    constraints : list of cvxpy constraints
        Write strict LMIs with an explicit margin (``P >> eps * I``); solvers only
        see non-strict ones.
    solver : str, default "CLARABEL"
        Any cvxpy solver name; Clarabel is the default because SCS' default
        accuracy can report "optimal" for a point violating the LMI.
    verbose : bool
    **solver_options
        Passed to ``Problem.solve``.

    Returns
    -------
    cvxpy.Problem
        The solved problem (``problem.value``, variables' ``.value``).

    Raises
    ------
    LMISolverError
        If the status is not ``optimal`` (infeasible, unbounded, inaccurate...).
        The solution must still be checked with :func:`verify_lmi`.
    """
    cp = require_cvxpy()
    if objective is None:
        objective = cp.Minimize(0)
    if not isinstance(constraints, (list, tuple)) or not constraints:
        raise TypeError("constraints must be a non-empty list of cvxpy constraints, "
                        f"got {type(constraints).__name__}")
    problem = cp.Problem(objective, list(constraints))
    try:
        problem.solve(solver=solver, verbose=verbose, **solver_options)
    except cp.error.SolverError as exc:
        raise LMISolverError(f"solver {solver} failed: {exc}") from exc
    if problem.status != cp.OPTIMAL:
        raise LMISolverError(f"solver {solver} returned status {problem.status!r} "
                             "(expected 'optimal')")
    return problem


def _as_square(M, name):
    M = np.asarray(M, dtype=float)
    if M.ndim != 2 or M.shape[0] != M.shape[1]:
        raise ValueError(f"{name} must be a square matrix, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ValueError(f"{name} must be finite, got non-finite entries")
    return M


def lmi_margin(M, relation, *, name="M", sym_rtol=1e-7):
    """Signed eigenvalue margin of the LMI ``M <relation> 0``.

    Parameters
    ----------
    M : (k, k) array_like
        Left-hand side; must be symmetric up to ``sym_rtol * max(1, ||M||)``
        (it is symmetrised before the eigenvalues are taken).
    relation : {"<= 0", "< 0", ">= 0", "> 0"}
    name : str
        Used in error messages.
    sym_rtol : float

    Returns
    -------
    float
        ``-lambda_max(M)`` for ``"<= 0"``/``"< 0"``, ``lambda_min(M)`` for
        ``">= 0"``/``"> 0"``: the LMI holds (non-strictly) iff the margin is >= 0.

    Raises
    ------
    ValueError
        Non-square, non-finite or non-symmetric ``M``, or an unknown relation.
    """
    M = _as_square(M, name)
    if relation not in _RELATIONS:
        raise ValueError(f"relation must be one of {_RELATIONS}, got {relation!r}")
    scale = max(1.0, float(np.linalg.norm(M, 2)))
    asym = float(np.max(np.abs(M - M.T))) if M.size else 0.0
    if asym > sym_rtol * scale:
        raise ValueError(f"{name} must be symmetric, got max |M - M^T| = {asym:.3g}")
    eig = np.linalg.eigvalsh(0.5 * (M + M.T))
    return float(-eig[-1]) if relation.startswith("<") else float(eig[0])


def verify_lmi(M, relation, *, name="M", rtol=1e-8, strict_rtol=1e-8):
    """Check numerically that ``M <relation> 0`` holds and return its margin.

    Tolerances are relative to ``scale = max(1, ||M||_2)`` because the eigenvalues
    of a matrix computed in floating point (and an interior-point solution) are only
    good to a small multiple of ``eps * ||M||``:

    * non-strict (``"<= 0"``, ``">= 0"``): pass when ``margin >= -rtol * scale``;
    * strict (``"< 0"``, ``"> 0"``): pass when ``margin > strict_rtol * scale``.

    Parameters
    ----------
    M : (k, k) array_like
    relation : {"<= 0", "< 0", ">= 0", "> 0"}
    name : str
        The LMI's name in the error message (e.g. ``"(10)"``).
    rtol, strict_rtol : float

    Returns
    -------
    float
        The margin of :func:`lmi_margin`.

    Raises
    ------
    LMIVerificationError
        If the LMI fails; the message names it, its worst eigenvalue and the tolerance.
    ValueError
        Bad ``M`` or ``relation`` (see :func:`lmi_margin`).
    """
    margin = lmi_margin(M, relation, name=name)
    scale = max(1.0, float(np.linalg.norm(np.asarray(M, float), 2)))
    strict = relation in ("< 0", "> 0")
    need = strict_rtol * scale if strict else -rtol * scale
    ok = margin > need if strict else margin >= need
    if not ok:
        which = "lambda_max" if relation.startswith("<") else "lambda_min"
        value = -margin if relation.startswith("<") else margin
        raise LMIVerificationError(
            f"LMI {name} {relation} fails: {which} = {value:.6g} "
            f"(tolerance {abs(need):.3g}, margin {margin:.3g})")
    return margin


def verify_lmis(lmis, **kwargs):
    """Verify several LMIs, raising on the first that fails.

    Parameters
    ----------
    lmis : iterable of (name, M, relation)
    **kwargs
        ``rtol`` / ``strict_rtol`` for :func:`verify_lmi`.

    Returns
    -------
    dict
        name -> margin.
    """
    return {name: verify_lmi(M, rel, name=name, **kwargs) for name, M, rel in lmis}


# ---------------------------------------------------------------------------
# LMI (10) of paper 000
# ---------------------------------------------------------------------------
def _check_design_params(n, mu, gamma1, *, strict_mu=True):
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise TypeError(f"n must be an int, got {type(n).__name__}")
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    mu = float(mu)
    gamma1 = float(gamma1)
    hi = 1.0 / (n + 1)
    if not (np.isfinite(mu) and 0.0 < mu and (mu < hi if strict_mu else mu <= hi)):
        interval = f"(0, {hi:g})" if strict_mu else f"(0, {hi:g}]"
        raise ValueError(f"mu must lie in {interval} for n = {n}, got {mu}")
    if not (np.isfinite(gamma1) and gamma1 > 0):
        raise ValueError(f"gamma1 must be > 0, got {gamma1}")
    return int(n), mu, gamma1


def lmi10_matrices(n, mu):
    """The matrices A, C, H of (9)-(10) for the extended error e = (w, x - x_hat).

    Parameters
    ----------
    n : int
        Order of the chain of integrators (1).
    mu : float

    Returns
    -------
    A : (n+1, n+1) ndarray
        Shift matrix ``[[0, I_n], [0, 0]]``.
    C : (1, n+1) ndarray
        ``[1, 0, ..., 0]``.
    H : (n+1, n+1) ndarray
        ``diag{1 - (i-1) mu}_{i=1}^{n+1}`` (the weights r_i).

    References
    ----------
    Nekhoroshikh et al., CDC 2022, eqs. (9), (10).
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an int >= 1, got {n!r}")
    A = np.eye(n + 1, k=1)
    C = np.zeros((1, n + 1))
    C[0, 0] = 1.0
    H = np.diag(1.0 - np.arange(n + 1) * float(mu))
    return A, C, H


def lmi10_residuals(P, Y, mu, gamma1):
    """Left-hand sides of LMIs (10) for a pair (P, Y).

    Returns
    -------
    dict
        ``"(10)"``: ``PA + YC + A'P + C'Y' + gamma1 (PH + HP) + P`` (must be ⪯ 0),
        ``"P"``: ``P`` (must be ≻ 0), ``"PH+HP"`` (must be ⪰ 0).
    """
    P = _as_square(P, "P")
    k = P.shape[0]
    Y = np.asarray(Y, dtype=float).reshape(-1, 1)
    if Y.shape[0] != k:
        raise ValueError(f"Y must have {k} entries (P is {k}x{k}), got {Y.shape[0]}")
    A, C, H = lmi10_matrices(k - 1, mu)
    S = P @ H + H @ P
    lhs = P @ A + Y @ C + A.T @ P + C.T @ Y.T + gamma1 * S + P
    return {"(10)": 0.5 * (lhs + lhs.T), "P": P, "PH+HP": S}


def _verify10(P, Y, mu, gamma1, rtol):
    R = lmi10_residuals(P, Y, mu, gamma1)
    return verify_lmis([("(10)", R["(10)"], "<= 0"), ("P", R["P"], "> 0"),
                        ("PH+HP", R["PH+HP"], ">= 0")], rtol=rtol)


@dataclass
class LMI10Result:
    """A verified solution of LMIs (10).

    Attributes
    ----------
    L : (n+1,) ndarray
        Observer gains ``col{L_i}_{i=0}^n = P^{-1} Y``.
    P : (n+1, n+1) ndarray
    Y : (n+1,) ndarray
    alpha : float
        ``sqrt(lambda_max(P) / lambda_min(P))`` of Proposition 4.
    objective : str
    margins : dict
        Eigenvalue margins of ``"(10)"``, ``"P"``, ``"PH+HP"`` (all >= -tol).
    """

    L: np.ndarray
    P: np.ndarray
    Y: np.ndarray
    alpha: float
    objective: str
    margins: dict = field(default_factory=dict)


def solve_lmi10(n, mu, gamma1, *, objective="alpha", gain_bound=None,
                solver="CLARABEL", rtol=1e-7, allow_mu_boundary=False):
    """Solve LMIs (10) and return the verified gain ``L = P^{-1} Y``.

    (10) is homogeneous in (P, Y), so P is normalised by ``P ⪰ I``.  The LMIs do not
    determine L and the paper states no objective; the choices here are

    * ``"alpha"`` (default): minimise kappa subject to ``I ⪯ P ⪯ kappa I``, i.e. the
      condition number ``alpha**2`` of P that enters the settling-time bound (17);
    * ``"gain"``: minimise ``||Y||_2`` subject to ``P ⪰ I`` (small injection gains);
    * ``"feasibility"``: any feasible point (whatever Clarabel returns).

    ``gain_bound`` (optional) adds ``||Y||_2 <= gain_bound`` to any objective.

    Parameters
    ----------
    n : int
        Order of the plant (1); the LMI has size n+1.
    mu : float
        Theorem 3 requires the open interval ``0 < mu < 1/(n+1)`` and so does this
        function by default.  ``mu = 1/(n+1)`` (allowed in Section IV, iISS case of
        Proposition 5) is accepted with ``allow_mu_boundary=True``: H stays positive
        definite there and (10) is well posed, but the last injection ``z^{-1} w``
        becomes discontinuous at w = 0 when z = gamma2|w|.
    gamma1 : float
        > 0.
    objective : {"alpha", "gain", "feasibility"}
    gain_bound : float, optional
    solver : str
        cvxpy solver name (default Clarabel).
    rtol : float
        Relative tolerance of the eigenvalue verification (:func:`verify_lmi`).
    allow_mu_boundary : bool, default False
        Accept ``mu = 1/(n+1)``.

    Returns
    -------
    LMI10Result

    Raises
    ------
    ValueError, TypeError
        Bad n, mu, gamma1, objective.
    LMISolverError
        Solver status not optimal.
    LMIVerificationError
        The returned point violates (10) when checked with eigenvalues.

    References
    ----------
    Nekhoroshikh, Efimov, Polyakov, Perruquetti, Furtat, "On simple design of a
    robust finite-time observer", CDC 2022, Theorem 3, LMIs (10).
    """
    n, mu, gamma1 = _check_design_params(n, mu, gamma1, strict_mu=not allow_mu_boundary)
    if objective not in ("alpha", "gain", "feasibility"):
        raise ValueError("objective must be 'alpha', 'gain' or 'feasibility', "
                         f"got {objective!r}")
    cp = require_cvxpy()
    A, C, H = lmi10_matrices(n, mu)
    k = n + 1
    P = cp.Variable((k, k), symmetric=True)
    Y = cp.Variable((k, 1))
    I = np.eye(k)
    lhs = P @ A + Y @ C + A.T @ P + C.T @ Y.T + gamma1 * (P @ H + H @ P) + P
    cons = [0.5 * (lhs + lhs.T) << 0, P >> I, P @ H + H @ P >> 0]
    if gain_bound is not None:
        if not (np.isfinite(gain_bound) and gain_bound > 0):
            raise ValueError(f"gain_bound must be > 0, got {gain_bound}")
        cons.append(cp.norm(Y, 2) <= gain_bound)
    if objective == "alpha":
        kappa = cp.Variable()
        cons.append(P << kappa * I)
        obj = cp.Minimize(kappa)
    elif objective == "gain":
        obj = cp.Minimize(cp.norm(Y, 2))
    else:
        obj = None
    solve_sdp(obj, cons, solver=solver)
    Pv = 0.5 * (P.value + P.value.T)
    Yv = np.asarray(Y.value, float).ravel()
    margins = _verify10(Pv, Yv, mu, gamma1, rtol)
    L = np.linalg.solve(Pv, Yv)
    eig = np.linalg.eigvalsh(Pv)
    return LMI10Result(L=L, P=Pv, Y=Yv, alpha=float(np.sqrt(eig[-1] / eig[0])),
                       objective=objective, margins=margins)


def check_gain_lmi10(L, mu, gamma1, *, solver="CLARABEL", rtol=1e-7):
    """Decide whether a given gain L satisfies (10) for some P, and how robustly.

    With ``Y = P L`` the LMIs (10) become linear in P alone.  Maximise the decay
    rate ``sigma`` such that ``P(A + LC) + (A + LC)'P + gamma1(PH + HP) ⪯ -sigma P``,
    ``P ⪰ I``, ``PH + HP ⪰ 0`` (bisection on sigma, one SDP each); L satisfies (10)
    iff ``sigma* >= 1``.  This avoids any equality test with printed numbers, which
    are rounded and not unique.

    Parameters
    ----------
    L : (n+1,) array_like
        Gains ``col{L_i}_{i=0}^n``.
    mu, gamma1 : float

    Returns
    -------
    dict
        ``feasible`` (bool: sigma* >= 1, verified by eigenvalues at sigma = 1 when
        True), ``sigma`` (largest verified sigma found, to 1e-4), ``P`` (when
        feasible: the P of smallest condition number satisfying (10) with Y = P L;
        otherwise the one at the largest sigma found), ``alpha`` (its
        ``sqrt(lambda_max/lambda_min)``, the alpha of Proposition 4).
    """
    L = np.asarray(L, dtype=float).ravel()
    if L.size < 2 or not np.all(np.isfinite(L)):
        raise ValueError(f"L must be a finite vector of length n+1 >= 2, got {L!r}")
    n = L.size - 1
    n, mu, gamma1 = _check_design_params(n, mu, gamma1, strict_mu=False)
    # the figures, the claims, the settling bounds and falsification ask for the same
    # gain: its bisection (~20 SDPs) runs once per process; P is copied per caller
    out = _gain_lmi10(tuple(L.tolist()), n, mu, gamma1, solver, float(rtol))
    return {**out, "P": None if out["P"] is None else out["P"].copy()}


@functools.lru_cache(maxsize=32)
def _gain_lmi10(L, n, mu, gamma1, solver, rtol):
    """:func:`check_gain_lmi10`'s bisection for a checked gain ``L`` (a tuple), cached."""
    L = np.array(L)
    cp = require_cvxpy()
    A, C, H = lmi10_matrices(n, mu)
    Acl = A + L[:, None] @ C
    k = n + 1
    I = np.eye(k)

    def attempt(sigma):
        P = cp.Variable((k, k), symmetric=True)
        lhs = P @ Acl + Acl.T @ P + gamma1 * (P @ H + H @ P) + sigma * P
        kappa = cp.Variable()
        cons = [0.5 * (lhs + lhs.T) << 0, P >> I, P @ H + H @ P >> 0, P << kappa * I]
        try:
            with warnings.catch_warnings():   # bisection probes infeasible sigmas on purpose
                warnings.simplefilter("ignore")
                solve_sdp(cp.Minimize(kappa), cons, solver=solver)
        except LMISolverError:
            return None
        Pv = 0.5 * (P.value + P.value.T)
        M = Pv @ Acl + Acl.T @ Pv + gamma1 * (Pv @ H + H @ Pv) + sigma * Pv
        try:
            verify_lmis([("(10)", 0.5 * (M + M.T), "<= 0"), ("P", Pv, "> 0"),
                         ("PH+HP", Pv @ H + H @ Pv, ">= 0")], rtol=rtol)
        except LMIVerificationError:
            return None
        return Pv

    # upper bound: the Lyapunov inequality needs sigma < -2 max Re eig(Acl + gamma1 H)
    hi = max(0.0, -2.0 * float(np.max(np.linalg.eigvals(Acl + gamma1 * H).real)))
    lo, best = 0.0, attempt(0.0)
    if best is None:
        return {"feasible": False, "sigma": -np.inf, "P": None, "alpha": np.nan}
    P1 = attempt(1.0) if hi > 1.0 else None
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        Pm = attempt(mid)
        if Pm is None:
            hi = mid
        else:
            lo, best = mid, Pm
    feasible = P1 is not None
    if feasible:
        best = P1           # the least-conditioned P of (10) itself (sigma = 1)
    eig = np.linalg.eigvalsh(best)
    return {"feasible": feasible, "sigma": lo, "P": best,
            "alpha": float(np.sqrt(eig[-1] / eig[0]))}
