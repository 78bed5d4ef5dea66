"""Tests of observers.lmi: generic LMI helpers and LMI (10) of paper 000.

cvxpy is imported by the tests that solve (not at collection: it is about
130 MB of every test process's memory, and most processes solve no LMI).
"""

import importlib.util

import numpy as np
import pytest

from observers import lmi
from observers.lmi import (
    PAPER_L,
    LMISolverError,
    LMIVerificationError,
    check_gain_lmi10,
    lmi10_matrices,
    lmi10_residuals,
    lmi_margin,
    solve_lmi10,
    solve_sdp,
    verify_lmi,
    verify_lmis,
)

pytestmark = pytest.mark.skipif(importlib.util.find_spec("cvxpy") is None,
                                reason="the LMI solvers need cvxpy (optional extra 'lmi')")


# ---------------------------------------------------------------- generic helpers
def test_margin_signs_match_eigenvalues():
    M = np.diag([-3.0, -1.0])
    assert lmi_margin(M, "<= 0") == pytest.approx(1.0)
    assert lmi_margin(M, ">= 0") == pytest.approx(-3.0)


def test_verify_lmi_accepts_and_rejects():
    assert verify_lmi(np.eye(2), "> 0") == pytest.approx(1.0)
    assert verify_lmi(np.zeros((2, 2)), ">= 0") == 0.0          # non-strict: boundary ok
    with pytest.raises(LMIVerificationError, match=r"LMI P > 0 fails: lambda_min = 0"):
        verify_lmi(np.zeros((2, 2)), "> 0", name="P")            # strict: boundary not ok
    with pytest.raises(LMIVerificationError, match=r"LMI \(10\) <= 0 fails: lambda_max = 0.5"):
        verify_lmi(np.diag([-1.0, 0.5]), "<= 0", name="(10)")


def test_verify_lmis_returns_margins_and_names_failure():
    m = verify_lmis([("a", -np.eye(2), "< 0"), ("b", np.eye(3), ">= 0")])
    assert m == {"a": pytest.approx(1.0), "b": pytest.approx(1.0)}
    with pytest.raises(LMIVerificationError, match="LMI b"):
        verify_lmis([("a", -np.eye(2), "< 0"), ("b", -np.eye(3), ">= 0")])


def test_bad_matrix_inputs():
    with pytest.raises(ValueError, match=r"M must be a square matrix, got shape \(2, 3\)"):
        lmi_margin(np.zeros((2, 3)), "<= 0")
    with pytest.raises(ValueError, match="must be symmetric"):
        lmi_margin(np.array([[0.0, 1.0], [0.0, 0.0]]), "<= 0")
    with pytest.raises(ValueError, match="must be finite"):
        lmi_margin(np.array([[np.nan]]), "<= 0")
    with pytest.raises(ValueError, match="relation must be one of"):
        lmi_margin(np.eye(2), "<<")


def test_solve_sdp_raises_on_infeasible():
    import cvxpy as cp

    x = cp.Variable()
    with pytest.raises(LMISolverError, match="infeasible"):
        solve_sdp(cp.Minimize(x), [x >= 1, x <= 0])
    with pytest.raises(TypeError, match="constraints must be a non-empty list"):
        solve_sdp(None, [])


# ---------------------------------------------------------------- LMI (10)
def test_lmi10_matrices_shapes():
    A, C, H = lmi10_matrices(3, 0.2)
    assert A.shape == (4, 4) and C.shape == (1, 4)
    assert np.allclose(np.diag(H), [1.0, 0.8, 0.6, 0.4])


@pytest.mark.parametrize("objective", ["alpha", "gain", "feasibility"])
def test_solve_lmi10_example_is_verified(objective):
    """The returned (P, Y) satisfies (10) by eigenvalues (tolerance 1e-7 relative:
    interior-point solutions sit on the boundary of (10) up to ~1e-8)."""
    r = solve_lmi10(3, 0.2, 1.0, objective=objective)
    R = lmi10_residuals(r.P, r.Y, 0.2, 1.0)
    scale = np.linalg.norm(R["(10)"], 2)
    assert np.linalg.eigvalsh(R["(10)"]).max() <= 1e-7 * max(1, scale)
    assert np.linalg.eigvalsh(r.P).min() > 0
    assert np.linalg.eigvalsh(R["PH+HP"]).min() >= -1e-7
    assert np.allclose(r.P @ r.L, r.Y)
    assert np.all(r.L < 0)            # the paper requires L_i < 0
    # (10) implies M = A + LC + gamma1 H has spectral abscissa <= -1/2
    A, C, H = lmi10_matrices(3, 0.2)
    assert np.linalg.eigvals(A + np.outer(r.L, C[0]) + H).real.max() <= -0.5 + 1e-6


def test_alpha_objective_minimises_condition_number():
    ra = solve_lmi10(3, 0.2, 1.0, objective="alpha")
    rf = solve_lmi10(3, 0.2, 1.0, objective="feasibility")
    assert ra.alpha <= rf.alpha + 1e-6


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_solve_lmi10_random_cases(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 6))
    mu = float(rng.uniform(0.05, 0.95)) / (n + 1)
    gamma1 = float(rng.uniform(0.3, 3.0))
    r = solve_lmi10(n, mu, gamma1)
    assert r.L.shape == (n + 1,)
    assert r.margins["(10)"] >= -1e-7 * max(1, np.linalg.norm(r.P, 2))
    # the gain found is accepted by the independent checker
    assert check_gain_lmi10(r.L, mu, gamma1)["feasible"]


def test_paper_gain_satisfies_lmi10():
    """The printed L = -[6.98, 28.60, 44.46, 23.04] satisfies (10) (mu=0.2,
    gamma1=1) for some P, with decay-rate margin sigma* > 1 (the LMI needs 1)."""
    out = check_gain_lmi10(PAPER_L, 0.2, 1.0)
    assert out["feasible"]
    assert out["sigma"] > 1.2
    M = lmi10_residuals(out["P"], out["P"] @ PAPER_L, 0.2, 1.0)["(10)"]
    assert np.linalg.eigvalsh(M).max() <= 1e-7 * np.linalg.norm(M, 2)


def test_a_gain_is_checked_once_and_each_caller_owns_its_P():
    """The second call with the same gain solves nothing (the bisection is cached) and
    returns the same numbers; changing one caller's P leaves the next caller's intact."""
    first = check_gain_lmi10(PAPER_L, 0.2, 1.0)
    hits = lmi._gain_lmi10.cache_info().hits
    P0 = first["P"].copy()
    first["P"][:] = 0.0
    again = check_gain_lmi10(list(PAPER_L), 0.2, 1.0)
    assert lmi._gain_lmi10.cache_info().hits == hits + 1
    np.testing.assert_array_equal(again["P"], P0)
    assert (again["sigma"], again["alpha"]) == (first["sigma"], first["alpha"])


def test_bad_gain_is_rejected():
    # positive gains: A + LC is not Hurwitz, (10) is infeasible for every P
    out = check_gain_lmi10(-PAPER_L, 0.2, 1.0)
    assert not out["feasible"]


def test_lmi10_bad_parameters():
    with pytest.raises(ValueError, match=r"mu must lie in \(0, 0.25\) for n = 3, got 0.25"):
        solve_lmi10(3, 0.25, 1.0)               # Theorem 3: open interval
    with pytest.raises(ValueError, match="gamma1 must be > 0, got -1"):
        solve_lmi10(3, 0.2, -1.0)
    with pytest.raises(TypeError, match="n must be an int, got float"):
        solve_lmi10(3.0, 0.2, 1.0)
    with pytest.raises(ValueError, match="objective must be"):
        solve_lmi10(3, 0.2, 1.0, objective="trace")
    with pytest.raises(ValueError, match="Y must have 4 entries"):
        lmi10_residuals(np.eye(4), np.ones(3), 0.2, 1.0)
    with pytest.raises(ValueError, match="L must be a finite vector"):
        check_gain_lmi10([1.0], 0.2, 1.0)


def test_verification_catches_a_violating_point(monkeypatch):
    """A solver that returns 'optimal' for a bad point is caught by the eigenvalue check."""
    real = lmi.solve_sdp

    def lying(objective, constraints, **kw):
        prob = real(objective, constraints, **kw)
        for v in prob.variables():
            if v.shape == (4, 1):
                v.value = np.full((4, 1), 50.0)    # gains of the wrong sign
        return prob

    monkeypatch.setattr(lmi, "solve_sdp", lying)
    with pytest.raises(LMIVerificationError, match=r"LMI \(10\) <= 0 fails"):
        solve_lmi10(3, 0.2, 1.0, objective="feasibility")


def test_more_bad_parameters():
    with pytest.raises(ValueError, match="n must be >= 1, got 0"):
        solve_lmi10(0, 0.2, 1.0)
    with pytest.raises(ValueError, match="gain_bound must be > 0, got -1"):
        solve_lmi10(3, 0.2, 1.0, gain_bound=-1.0)
    with pytest.raises(ValueError, match="n must be an int >= 1, got 0"):
        lmi10_matrices(0, 0.2)


def test_gain_bound_is_respected():
    """min ||Y|| over (10) with P >= I is ~424 (objective 'gain'): a bound of 500 is
    met, a bound of 300 is infeasible and raises."""
    rmin = solve_lmi10(3, 0.2, 1.0, objective="gain")
    assert 300 < np.linalg.norm(rmin.Y) < 500
    r = solve_lmi10(3, 0.2, 1.0, objective="feasibility", gain_bound=500.0)
    assert np.linalg.norm(r.Y) <= 500.0 * (1 + 1e-6)
    with pytest.raises(LMISolverError, match="infeasible"):
        solve_lmi10(3, 0.2, 1.0, gain_bound=300.0)
