"""hybridsim.sensitivity: forward sensitivities through flows and jumps.

Checked against closed forms (the bouncing ball's impact times and states,
derived here from ``bouncing_ball_jump_times``' formula), against central
finite differences of whole runs (random linear flows with affine jumps and
guards), against a Monte Carlo of 1,000 runs (covariance through jumps), and
on every case where a derivative does not exist.
"""
from __future__ import annotations

import random
import runpy
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import hybridsim as hs
from hybridsim.compiled import available
from hybridsim.library import BouncingBall, bouncing_ball_jump_times
from hybridsim.sensitivity import (
    SensitivityError,
    SensitivityWarning,
    sensitivity_system,
    simulate_sensitivity,
)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
G, E, H0, K = 9.81, 0.8, 1.0, 30


def ball(p):
    return BouncingBall(G, p[0])


def ball_closed_forms(k_max):
    """t_k, dt_k/dh0, dt_k/de for k = 1..k_max, from
    t_k = t1 (1 + 2 (e - e^k) / (1 - e)), t1 = sqrt(2 h0 / g)."""
    k = np.arange(1, k_max + 1)
    t1 = np.sqrt(2 * H0 / G)
    tk = bouncing_ball_jump_times(H0, k_max, G, E)
    assert np.allclose(tk, t1 * (1 + 2 * (E - E ** k) / (1 - E)), rtol=1e-15)
    dt_dh0 = tk / (2 * H0)                              # t_k is proportional to sqrt(h0)
    dt_de = t1 * 2 * ((1 - k * E ** (k - 1)) * (1 - E) + (E - E ** k)) / (1 - E) ** 2
    return tk, dt_dh0, dt_de


def ball_state_de(T, k):
    """d x(T) / de for T in (t_k, t_{k+1}): after impact k the ball leaves at
    v_k = e^k g t1, so x = (v_k s - g s^2 / 2, v_k - g s), s = T - t_k."""
    tk, _, dt_de = ball_closed_forms(k)
    t1 = np.sqrt(2 * H0 / G)
    s = T - tk[k - 1]
    v, dv = E ** k * G * t1, k * E ** (k - 1) * G * t1
    return np.array([dv * s + (G * s - v) * dt_de[k - 1], dv + G * dt_de[k - 1]])


# ----------------------------------------------------------------------- closed forms
@pytest.mark.parametrize("rtol", [1e-6, 1e-7, 1e-8, 1e-9, 1e-10])
def test_ball_30_bounces_closed_forms(rtol):
    # 1e-9 relative: the target. RK45 integrates the parabolas (and
    # the sensitivities, linear in t) exactly, so what is left is event
    # location (jump times within ~2e-13) and the finite-difference Jacobians
    # (~eps^(2/3) on these affine maps); the state after 30 bounces is itself
    # only ~2e-10 relative (its speed e^30 v0 carries the jump times' error),
    # which bounds dx(T)/de. T is a quarter into the 31st flight, away from
    # the apex, where dx1/de (a difference of two terms) is ill-conditioned.
    tk, dt_dh0, dt_de = ball_closed_forms(K + 1)
    T = tk[K - 1] + 0.25 * (tk[K] - tk[K - 1])
    sarc = simulate_sensitivity(ball, [H0, 0.0], t_max=T, j_max=K + 1, params=[E],
                                rtol=rtol)
    assert sarc.arc.jump_count == K and sarc.t[-1] == T
    np.testing.assert_allclose(sarc.jump_times, tk[:K], rtol=1e-12)
    np.testing.assert_allclose(sarc.dtj_dx0[:, 0], dt_dh0[:K], rtol=1e-9)
    assert sarc.dtj_dp[0, 0] == pytest.approx(0.0, abs=1e-12)   # t1 does not depend on e
    np.testing.assert_allclose(sarc.dtj_dp[1:, 0], dt_de[1:K], rtol=1e-9)
    np.testing.assert_allclose(sarc.dx_dp[-1, :, 0], ball_state_de(T, K), rtol=1e-9)


def test_error_follows_the_tolerance_on_a_non_polynomial_flow():
    # x' = -p x, reset to 1 when x falls to 1/2 (guard 1/2 - x): RK45 is not
    # exact here, so the sensitivities' error must follow rtol. Closed form:
    # t_k = (ln(2 x0) + (k - 1) ln 2) / p, so dt_k/dp = -t_k / p and
    # dt_k/dx0 = 1 / (p x0). Bound: 100 rtol (relative), a margin over RK45's
    # global error of a few rtol on these smooth flows.
    def make(p):
        return hs.HybridSystem.from_functions(
            flow_map=lambda x: -p[0] * x, jump_map=lambda x: np.array([1.0]),
            jump_guard=lambda x: 0.5 - x[0], state_dim=1)
    p, x0 = 1.3, 0.9
    errors = []
    for rtol in (1e-6, 1e-8, 1e-10):
        sarc = simulate_sensitivity(make, [x0], t_max=5.0, params=[p], rtol=rtol,
                                    atol=rtol * 1e-3)
        k = np.arange(1, sarc.arc.jump_count + 1)
        tk = (np.log(2 * x0) + (k - 1) * np.log(2)) / p
        np.testing.assert_allclose(sarc.jump_times, tk, rtol=100 * rtol)
        e_p = np.max(np.abs(sarc.dtj_dp[:, 0] / (-tk / p) - 1))
        e_x = np.max(np.abs(sarc.dtj_dx0[:, 0] * p * x0 - 1))
        assert max(e_p, e_x) <= 100 * rtol, (rtol, e_p, e_x)
        errors.append(max(e_p, e_x))
    assert errors[2] < errors[1] < errors[0]


def test_user_jacobians_are_used_and_agree():
    # the maps are affine: the given Jacobians and central differences agree
    # to rounding (eps / fd_step ~ 4e-11 relative, amplified over 10 bounces)
    calls = []

    class Ball(BouncingBall):
        def flow_jacobian(self, x):
            calls.append("f")
            return np.array([[0.0, 1.0], [0.0, 0.0]])

        def jump_jacobian(self, x):
            calls.append("g")
            return np.array([[0.0, 0.0], [0.0, -self.e]])

        def jump_guard_gradient(self, x):
            return np.array([-1.0, 0.0])

    a = simulate_sensitivity(Ball(), [H0, 0.0], t_max=3.0, j_max=10)
    b = simulate_sensitivity(BouncingBall(), [H0, 0.0], t_max=3.0, j_max=10)
    assert {"f", "g"} <= set(calls)
    np.testing.assert_allclose(a.dtj_dtheta, b.dtj_dtheta, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.S[-1], b.S[-1], rtol=1e-9, atol=1e-12)


def test_user_jacobian_of_wrong_shape_is_named():
    class Ball(BouncingBall):
        def flow_jacobian(self, x):
            return np.zeros(3)

    with pytest.raises(hs.MapError, match=r"flow_jacobian must return .* shape \(2, 2\)"):
        simulate_sensitivity(Ball(), [H0, 0.0], t_max=1.0)


def test_interpolation_between_samples_matches_a_stored_sample():
    # S is linear in t on the ball's flows: Hermite interpolation through the
    # augmented flow is exact, and so is the dense output (rounding: 1e-12)
    t_star = 0.9 * bouncing_ball_jump_times(H0, 2)[1]
    ref = simulate_sensitivity(ball, [H0, 0.0], t_max=2.0, params=[E], t_eval=[t_star])
    k = int(np.flatnonzero(ref.t == t_star)[0])
    for dense in (False, True):
        sarc = simulate_sensitivity(ball, [H0, 0.0], t_max=2.0, params=[E], dense=dense)
        assert t_star not in sarc.t
        x, S = sarc.at(t_star)
        np.testing.assert_allclose(x, ref.x[k], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(S, ref.S[k], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(sarc.S_at([t_star, t_star])[1], ref.S[k], rtol=1e-12,
                                   atol=1e-12)


def test_jump_inside_D_at_t0_and_a_timer():
    timer = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        jump_guard=lambda x: x[0] - 1.0, state_dim=1)
    # x0 = 1.5 is strictly inside D: the jump at t0 happens whatever x0 near it,
    # then x(t) = t - t0 does not depend on x0; exact arithmetic (affine maps)
    sarc = simulate_sensitivity(timer, [1.5], t_max=0.5)
    assert sarc.arc.jump_count == 1 and sarc.dtj_dx0[0, 0] == 0.0
    assert sarc.S[-1, 0, 0] == pytest.approx(0.0, abs=1e-12)
    # from 0.25: t_j = j - 0.25 + ..., so dt_j/dx0 = -1 and dx(t)/dx0 = 1
    sarc = simulate_sensitivity(timer, [0.25], t_max=2.5)
    np.testing.assert_allclose(sarc.dtj_dx0[:, 0], -1.0, rtol=1e-9)
    np.testing.assert_allclose(sarc.dx_dx0[:, 0, 0], 1.0, rtol=1e-9)


def test_parameter_in_guard_and_time_dependent_jump():
    # x' = 1 from x0, jump where the guard x - p crosses 0, x+ = x + t: the
    # jump is at t1 = p - x0 to x+ = 2p - x0, so x(T) = T + p for T > t1
    # (dx/dp = 1, dx/dx0 = 0; dt1/dp = 1, dt1/dx0 = -1). D = [p, p + 0.5)
    # keeps x+ out of D.
    def make(p):
        return hs.HybridSystem.from_functions(
            flow_map=lambda x: np.array([1.0]), jump_map=lambda x, t: np.array([x[0] + t]),
            jump_guard=lambda x: x[0] - p[0],
            jump_set=lambda x: p[0] <= x[0] < p[0] + 0.5, state_dim=1)
    sarc = simulate_sensitivity(make, [0.0], t_max=1.5, params=[1.0])
    assert sarc.arc.jump_count == 1
    assert sarc.x[-1, 0] == pytest.approx(2.5, rel=1e-12)
    # tolerance: central differences of affine maps, rounding ~1e-10
    np.testing.assert_allclose(sarc.dtj_dtheta[0], [-1.0, 1.0], rtol=1e-9)
    np.testing.assert_allclose(sarc.S[-1, 0], [0.0, 1.0], atol=1e-9)


# ----------------------------------------------------------------------- random cases
def _linear_case(data):
    n = data.draw(st.integers(2, 3), label="n")
    u = st.floats(-1.0, 1.0)
    A = np.array(data.draw(st.lists(u, min_size=n * n, max_size=n * n), label="A")).reshape(n, n)
    A[0] *= 0.2                       # x[0] is a clock-like coordinate, drift 1
    Gm = 0.8 * np.array(data.draw(st.lists(u, min_size=n * n, max_size=n * n),
                                  label="G")).reshape(n, n)
    Gm[0] = 0.0                       # the jump resets x[0] to 0: off the guard
    c = 0.2 * np.array(data.draw(st.lists(u, min_size=n - 1, max_size=n - 1), label="c"))
    d = np.array(data.draw(st.lists(u, min_size=n, max_size=n), label="d"))
    d[0] = 0.0
    x0 = 0.5 * np.array(data.draw(st.lists(u, min_size=n, max_size=n), label="x0"))
    x0[0] = 0.0
    b = np.zeros(n)
    b[0] = 1.0

    def make(p):
        # f = p0 A x + b, g = G x + d + p1 e_1, guard x0 - 1 + c . x[1:]
        return hs.HybridSystem.from_functions(
            flow_map=lambda x: p[0] * (A @ x) + b,
            jump_map=lambda x: Gm @ x + d + p[1] * np.eye(n)[1],
            jump_guard=lambda x: x[0] - 1.0 + c @ x[1:], state_dim=n)
    return make, x0, np.array([1.0, 0.1])


OPTS = dict(t_max=2.5, j_max=5, rtol=1e-12, atol=1e-12, method="DOP853")


def _run(make, x0, p):
    arc = hs.simulate(make(p), x0, **OPTS)
    return arc, np.concatenate([arc.xf, arc.jump_times])


@pytest.mark.slow
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_random_affine_systems_match_finite_differences(data):
    make, x0, p = _linear_case(data)
    try:
        sarc = simulate_sensitivity(make, x0, params=p, **OPTS)
    except SensitivityError:
        assume(False)                 # a grazing draw: covered by its own test
    arc0 = sarc.arc
    # regular runs only: no jump near t_max (a perturbation would add or drop it)
    assume(arc0.jump_count >= 1 and arc0.termination is hs.Termination.T_MAX)
    assume(OPTS["t_max"] - arc0.jump_times[-1] > 0.05)
    assume(np.all(np.diff(np.concatenate([[0.0], arc0.jump_times])) > 0.05))
    theta = np.concatenate([x0, p])
    n = len(x0)
    sens = np.concatenate([sarc.S[-1], sarc.dtj_dtheta], axis=0)     # (n + J, m)

    h = 1e-4
    runs = {}
    for k in range(len(theta)):
        for step in (h, -h, 2 * h, -2 * h):
            th = theta.copy()
            th[k] += step
            runs[k, step] = _run(make, th[:n], th[n:])
    # the same hybrid time domain for every perturbed run (else no derivative)
    assume(all(arc.jump_count == arc0.jump_count for arc, _ in runs.values()))

    def D(k, h):
        return (runs[k, h][1] - runs[k, -h][1]) / (2 * h)

    for k in range(len(theta)):
        d1, d2 = D(k, h), D(k, 2 * h)
        # the central difference's truncation error is ~ (d2 - d1) / 3
        # (Richardson); 3 |d2 - d1| is that with a safety factor of 9. The
        # runs' own error (rtol = atol = 1e-12) over h = 1e-4 adds ~1e-8:
        # 1e-7 (1 + |d1|) covers it tenfold.
        tol = 3 * np.abs(d2 - d1) + 1e-7 * (1 + np.abs(d1))
        assert np.all(np.abs(sens[:, k] - d1) <= tol), (k, sens[:, k], d1, tol)


# ----------------------------------------------------------------------- covariance
def test_covariance_through_jumps_matches_monte_carlo():
    # x0 ~ N((1, 0), P0) propagated a quarter into the flight after the 5th
    # bounce (not its apex, where the height is stationary in the timing and
    # the quadratic term would dominate the variance):
    # S P0 S^T against the sample covariance of 1,000 seeded runs (one
    # vectorized batch). Sample covariance standard error (Gaussian):
    # sqrt((P_ii P_jj + P_ij^2) / (N - 1)); 4 of them. Linearisation bias is
    # O(sigma / h0) ~ 0.5%, well inside the ~4.5% Monte Carlo error.
    N = 1000
    P0 = np.diag([0.005 ** 2, 0.01 ** 2])
    tk = bouncing_ball_jump_times(H0, 6)
    T = tk[4] + 0.25 * (tk[5] - tk[4])
    sarc = simulate_sensitivity(BouncingBall(), [H0, 0.0], t_max=T)
    assert sarc.arc.j[-1] == 5
    P = sarc.covariance(P0, T)
    rng = np.random.default_rng(26)
    x0s = rng.multivariate_normal([H0, 0.0], P0, size=N)
    arcs = hs.simulate_many(BouncingBall(vectorized=True), x0s, t_max=T)
    xT = np.array([a.xf for a in arcs])
    assert all(a.j[-1] == 5 for a in arcs)
    Pmc = np.cov(xT.T)
    se = np.sqrt((np.outer(np.diag(Pmc), np.diag(Pmc)) + Pmc ** 2) / (N - 1))
    assert np.all(np.abs(P - Pmc) <= 4 * se), (P, Pmc, se)


def test_covariance_checks_its_input():
    sarc = simulate_sensitivity(BouncingBall(), [H0, 0.0], t_max=1.0)
    with pytest.raises(ValueError, match=r"P0 must be a finite symmetric \(2, 2\)"):
        sarc.covariance(np.eye(3), 1.0)


# ----------------------------------------------------------------------- undefined
def test_grazing_jump_is_named():
    # the guard h = x2 - (x1 - 1)^2 along x1' = 1 from x2 = EPS^2: the flow
    # crosses it at t = 1 - EPS, EPS = 1e-7 of the flow's duration before the
    # tangency (h' = 2 EPS, h'' = -2): grazing; t_j = 1 - x1(0) - sqrt(x2(0))
    eps = 1e-7
    sys_ = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0, 0.0]), jump_map=lambda x: np.array([x[0], -1.0]),
        jump_guard=lambda x: x[1] - (x[0] - 1.0) ** 2, state_dim=2)
    x0 = [0.0, eps ** 2]
    with pytest.raises(SensitivityError, match=r"t=0\.9999999\d* \(j=0 -> 1\).*grazing") as ei:
        simulate_sensitivity(sys_, x0, t_max=1.5)
    assert ei.value.j == 1 and ei.value.t == pytest.approx(1.0 - eps, abs=1e-12)
    with pytest.warns(SensitivityWarning, match="grazing"):
        sarc = simulate_sensitivity(sys_, x0, t_max=1.5, undefined="warn")
    assert np.isnan(sarc.S[-1]).all() and np.isnan(sarc.dtj_dtheta).all()
    assert not np.isnan(sarc.S[0]).any() and np.isfinite(sarc.x).all()
    assert np.isnan(sarc.S_at(1.2)).all() and not np.isnan(sarc.S_at(0.5)).any()
    # with the tolerance below 2 EPS it is a (badly conditioned) number:
    # dt_j/dx2(0) = -1 / (2 EPS); 1e-6: the event time's rounding over EPS
    sarc = simulate_sensitivity(sys_, x0, t_max=1.5, graze_tol=1e-8)
    assert sarc.dtj_dx0[0, 1] == pytest.approx(-0.5 / eps, rel=1e-6)
    assert sarc.dtj_dx0[0, 0] == pytest.approx(-1.0, rel=1e-9)


def test_a_slow_transversal_crossing_is_not_grazing():
    # h = x2 along x2' = 1e-9: the rate is small against |f| (1, the other
    # component) but never changes sign: dt_j/dx2(0) = -1e9 exactly
    sys_ = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0, 1e-9]), jump_map=lambda x: np.array([x[0], -1.0]),
        jump_guard=lambda x: x[1], state_dim=2)
    sarc = simulate_sensitivity(sys_, [0.0, -1e-9], t_max=1.5)
    assert sarc.dtj_dx0[0, 1] == pytest.approx(-1e9, rel=1e-6)


def test_a_zeno_ball_is_zeno_not_grazing():
    """Restitution 0.5: the impact speeds fall to 1e-15 (each below 1e-6 of
    |f|, which holds gravity: the old test called bounce 20 grazing). The
    guard's rate changes sign mid-flow at every bounce (the apex), so no
    jump is grazing: the run ends ZENO with its warning, the jump times'
    sensitivities those of the closed form t_k = t_1 (1 + 2e + ... + 2e^(k-1)),
    d t_k / d h0 = t_k / (2 h0), to 1e-6 over the first 20 bounces."""
    with pytest.warns(SensitivityWarning, match=r"Zeno accumulation.*j=\d+"):
        sarc = simulate_sensitivity(BouncingBall(restitution=0.5), [1.0, 0.0], t_max=10.0,
                                    j_max=200)
    assert sarc.termination is hs.Termination.ZENO and sarc.undefined is None
    tk = sarc.jump_times[:20]
    np.testing.assert_allclose(sarc.dtj_dx0[:20, 0], tk / 2.0, rtol=1e-6)


def test_indicator_without_guard_is_named():
    # a set no guard is derived from (a call: hybridsim._source); the same ball's
    # D written as comparisons gets one (tests/engine/test_derived_guards.py)
    b = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[1], -G]), jump_map=lambda x: np.array([0.0, -E * x[1]]),
        flow_set=lambda x: x[0] >= 0, jump_set=lambda x: bool(x[0] <= 0 and x[1] <= 0), state_dim=2)
    with pytest.raises(SensitivityError, match=r"\(j=0 -> 1\).*no jump_guard") as ei:
        simulate_sensitivity(b, [H0, 0.0], t_max=1.0)
    assert ei.value.t == pytest.approx(np.sqrt(2 * H0 / G), rel=1e-9)


def test_simultaneous_guards_are_named():
    corner = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0, 1.0]), jump_map=lambda x: np.zeros(2),
        jump_guard=lambda x: np.array([x[0] - 1.0, x[1] - 1.0]), state_dim=2)
    with pytest.raises(SensitivityError, match=r"simultaneous guards: components \[0, 1\]"):
        simulate_sensitivity(corner, [0.0, 0.0], t_max=1.5)
    # apart, the later crossing (x[0] at t = 1) decides: dt/dx0 = (-1, 0)
    sarc = simulate_sensitivity(corner, [0.0, 0.5], t_max=1.2)
    np.testing.assert_allclose(sarc.dtj_dx0[0], [-1.0, 0.0], atol=1e-9)


def test_jump_from_the_guards_zero_without_flow_is_named():
    timer = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        jump_guard=lambda x: x[0] - 1.0, state_dim=1)
    with pytest.raises(SensitivityError, match=r"t=0 \(j=0 -> 1\).*without a flow"):
        simulate_sensitivity(timer, [1.0], t_max=0.5)


def test_zeno_accumulation_warns_with_the_last_jump():
    # graze_tol=0: only the Zeno warning is under test (the default
    # tolerance: test_a_zeno_ball_is_zeno_not_grazing)
    with pytest.warns(SensitivityWarning, match=r"Zeno accumulation.*j=\d+"):
        sarc = simulate_sensitivity(BouncingBall(), [H0, 0.0], t_max=10.0, graze_tol=0.0)
    assert sarc.termination is hs.Termination.ZENO
    _, dt_dh0, _ = ball_closed_forms(20)
    np.testing.assert_allclose(sarc.dtj_dx0[:20, 0], dt_dh0, rtol=1e-9)


# ----------------------------------------------------------------------- bad input
def test_paths_that_cannot_run_it_refuse_by_name():
    with pytest.raises(ValueError, match="backend must be 'python', 'compiled' or 'auto'"):
        simulate_sensitivity(BouncingBall(), [H0, 0.0], t_max=1.0, backend="vectorized")
    with pytest.raises(ValueError, match="vectorized system's batches do not carry"):
        simulate_sensitivity(BouncingBall(vectorized=True), [H0, 0.0], t_max=1.0)
    # Jacobians given are used on the Python path only: compiled refuses, auto
    # runs the Python path (nothing is compiled to decide either)
    with pytest.raises(TypeError, match="BallJ gives flow_jacobian.*backend='python'"):
        simulate_sensitivity(BallJ(), [H0, 0.0], t_max=1.0, backend="compiled")
    a = simulate_sensitivity(BallJ(), [H0, 0.0], t_max=1.0, backend="auto")
    b = simulate_sensitivity(BallJ(), [H0, 0.0], t_max=1.0)
    np.testing.assert_array_equal(a.S, b.S)
    if available():          # auto: a map that cannot run compiled says why, once
        from hybridsim.compiled import FallbackWarning

        class Drawn(IndicatorBall):
            def flow_map(self, x):
                return np.array([x[1], -G + 0.0 * random.random()])
        with pytest.warns(FallbackWarning, match=r"Drawn\.flow_map .*random"):
            a = simulate_sensitivity(Drawn(), [H0, 0.0], t_max=1.0, backend="auto")
        np.testing.assert_array_equal(
            a.S, simulate_sensitivity(Drawn(), [H0, 0.0], t_max=1.0).S)
    ic = hs.Interconnection({"ball": BouncingBall()})
    with pytest.raises(TypeError, match="Interconnection is an interconnection: its jump"):
        simulate_sensitivity(ic, [H0, 0.0], t_max=1.0, backend="compiled")


class BallJ(BouncingBall):
    """The library's ball with its Jacobians written out."""

    def flow_jacobian(self, x):
        return np.array([[0.0, 1.0], [0.0, 0.0]])

    def jump_jacobian(self, x):
        return np.array([[0.0, 0.0], [0.0, -self.e]])

    def jump_guard_gradient(self, x):
        return np.array([-1.0, 0.0])


# ----------------------------------------------------------------------- compiled path
class IndicatorBall(hs.HybridSystem):
    """The ball given by its sets only: no guard written (derived from the sets)."""

    state_dim = 2

    def __init__(self, e=E):
        self.e = e

    def flow_map(self, x):
        return np.array([x[1], -G])

    def jump_map(self, x):
        return np.array([0.0, -self.e * x[1]])

    def flow_set(self, x):
        return x[0] >= 0

    def jump_set(self, x):
        return x[0] <= 0 and x[1] <= 0


def _indicator_ball(p):
    return IndicatorBall(p[0])


COMPILED = pytest.param("compiled", marks=[
    pytest.mark.slow,    # the variational maps compile once per process (~8 s of CPU)
    pytest.mark.skipif(not available(), reason="needs numba")])


@pytest.mark.parametrize("backend", ["python", COMPILED])
@pytest.mark.parametrize("rtol", [1e-6, 1e-8, 1e-10])
def test_indicator_only_ball_10_bounces_closed_form(rtol, backend):
    # issue 42's figure: no guard given, the guards derived from the sets;
    # d t_k / d h0 and d t_k / d e for 10 bounces equal the closed form to
    # 1e-9 relative at every rtol (RK45 is exact on the parabolas; what is
    # left is event location and the central differences, ~1e-11)
    assert IndicatorBall().jump_guard is not None
    tk, dt_dh0, dt_de = ball_closed_forms(10)
    sarc = simulate_sensitivity(_indicator_ball, [H0, 0.0], t_max=tk[-1] + 0.1, j_max=10,
                                params=[E], rtol=rtol, backend=backend)
    assert sarc.arc.jump_count == 10 and sarc.undefined is None
    np.testing.assert_allclose(sarc.jump_times, tk, rtol=1e-12)
    np.testing.assert_allclose(sarc.dtj_dx0[:, 0], dt_dh0, rtol=1e-9)
    assert sarc.dtj_dp[0, 0] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(sarc.dtj_dp[1:, 0], dt_de[1:], rtol=1e-9)


@pytest.mark.slow
@pytest.mark.skipif(not available(), reason="needs numba")
def test_compiled_path_equals_the_python_path():
    """The same variational system on both paths: the same samples (the same
    solver steps) and sensitivities to rounding, 1e-9 relative to the
    largest entry (central differences over rounding-level differences of
    the states); the flags of undefined jumps alike."""
    def same(a, b):
        assert a.arc.jump_count == b.arc.jump_count and a.t.shape == b.t.shape
        np.testing.assert_allclose(a.t, b.t, rtol=1e-12, atol=1e-12)
        for u, v in ((a.S, b.S), (a.dtj_dtheta, b.dtj_dtheta)):
            scale = max(1.0, float(np.nanmax(np.abs(v))))
            np.testing.assert_allclose(u, v, rtol=1e-9, atol=1e-9 * scale)
    kw = dict(t_max=9.0, j_max=30, params=[E])
    same(simulate_sensitivity(ball, [H0, 0.0], backend="compiled", **kw),
         simulate_sensitivity(ball, [H0, 0.0], **kw))
    # a parameter in the guard, a time-dependent jump, an explicit D

    def make(p):
        return hs.HybridSystem.from_functions(
            flow_map=lambda x: np.array([1.0]), jump_map=lambda x, t: np.array([x[0] + t]),
            jump_guard=lambda x: x[0] - p[0],
            jump_set=lambda x: p[0] <= x[0] < p[0] + 0.5, state_dim=1)
    a = simulate_sensitivity(make, [0.0], t_max=1.5, params=[1.0], backend="compiled")
    same(a, simulate_sensitivity(make, [0.0], t_max=1.5, params=[1.0]))
    np.testing.assert_allclose(a.dtj_dtheta[0], [-1.0, 1.0], rtol=1e-9)
    # auto takes the compiled path here, and the same numbers
    same(simulate_sensitivity(make, [0.0], t_max=1.5, params=[1.0], backend="auto"), a)
    # an undefined jump is named the same way on both paths
    corner = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0, 1.0]), jump_map=lambda x: np.zeros(2),
        jump_guard=lambda x: np.array([x[0] - 1.0, x[1] - 1.0]), state_dim=2)
    for backend in ("python", "compiled"):
        with pytest.raises(SensitivityError, match=r"simultaneous guards: components \[0, 1\]"):
            simulate_sensitivity(corner, [0.0, 0.0], t_max=1.5, backend=backend)


@pytest.mark.slow
@pytest.mark.skipif(not available(), reason="needs numba")
def test_a_factorys_systems_are_read_through_one_plan():
    # the systems make_system(p) builds share their first one's plan: each
    # one's p read through it equals that system lowered on its own
    from hybridsim import _variational
    from hybridsim.compiled import lower
    _variational._lowered(IndicatorBall(0.7))
    for e in (0.3, 0.9):
        maps, p = _variational._lowered(IndicatorBall(e))
        own = lower(IndicatorBall(e))
        np.testing.assert_array_equal(p, own.params)
        assert maps is _variational._STRUCTURES[_variational._structure(IndicatorBall())][1].maps
    # a system with a helper function on the instance is lowered itself
    b = IndicatorBall(0.5)
    b.helper = lambda v: v
    s0 = IndicatorBall(0.7)
    assert _variational._reread(s0, lower(s0).layout, b) is None
    assert _variational._reread(s0, lower(s0).layout, IndicatorBall(0.5)) is not None


@pytest.mark.parametrize("kwargs, exc, match", [
    (dict(params=[E]), TypeError, "factory make_system"),
    (dict(wrt="params"), ValueError, "no params were given"),
    (dict(wrt="y"), ValueError, "wrt must be"),
    (dict(undefined="ignore"), ValueError, "undefined must be"),
    (dict(fd_step=2.0), ValueError, "fd_step must be"),
    (dict(graze_tol=-1.0), ValueError, "graze_tol must be"),
    (dict(sens_atol=0.0), ValueError, "sens_atol must be"),
    (dict(inputs=lambda t: 0.0), ValueError, "inputs/prehistory"),
])
def test_bad_arguments_are_named(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        simulate_sensitivity(BouncingBall(), [H0, 0.0], t_max=1.0, **kwargs)


def test_bad_x0_params_and_factory_domain():
    with pytest.raises(ValueError, match=r"x0 must be a finite array of shape \(2,\)"):
        simulate_sensitivity(BouncingBall(), [H0], t_max=1.0)
    with pytest.raises(ValueError, match="params must be a non-empty 1-D array"):
        simulate_sensitivity(ball, [H0, 0.0], t_max=1.0, params=[np.nan])
    # e = 0 is on the edge of BouncingBall's domain [0, 1): the step leaves it
    with pytest.raises(ValueError, match=r"params\[0\].*finite-difference step"):
        simulate_sensitivity(ball, [H0, 0.0], t_max=1.0, params=[0.0])
    sarc = simulate_sensitivity(BouncingBall(), [H0, 0.0], t_max=1.0)
    with pytest.raises(ValueError, match="no sensitivities with respect to params"):
        sarc.dx_dp  # noqa: B018


def test_sensitivity_system_runs_through_simulate():
    ssys = sensitivity_system(ball, params=[E], wrt="params")
    assert ssys.state_dim == 2 + 2 + 1 + 2
    arc = hs.simulate(ssys, ssys.initial_state(np.array([H0, 0.0])), t_max=2.0, j_max=2)
    _, _, dt_de = ball_closed_forms(2)
    np.testing.assert_allclose(arc["dt"].x[-1, 0], dt_de[1], rtol=1e-9)


# ----------------------------------------------------------------------- example
def test_ball_sensitivity_example(tmp_path):
    import matplotlib.pyplot as plt

    mod = runpy.run_path(str(EXAMPLES / "ball_sensitivity.py"), run_name="example")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sarc, fig = mod["main"](tmp_path)
    assert (tmp_path / "ball_sensitivity.png").is_file()
    ax_t, ax_x = fig.axes[:2]
    _, _, dt_de = ball_closed_forms(sarc.arc.jump_count)
    labels = [ln.get_label() for ln in ax_t.lines]
    assert "engine (saltation)" in labels and "closed form" in labels
    eng = ax_t.lines[labels.index("engine (saltation)")]
    np.testing.assert_allclose(eng.get_ydata(), dt_de, rtol=1e-9, atol=1e-12)
    assert "restitution" in ax_t.get_ylabel() and ax_x.get_xlabel() == "$t$ (s)"
    plt.close(fig)


@pytest.mark.slow
def test_observer_gain_tuning_example(tmp_path):
    import matplotlib.pyplot as plt

    mod = runpy.run_path(str(EXAMPLES / "observer_gain_tuning.py"), run_name="example")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r, fig = mod["main"](tmp_path)
    assert (tmp_path / "observer_gain_tuning.png").is_file()
    # the gradient against central differences of runs (step 1e-5): their
    # truncation ~h^2 |J'''| ~ 1e-9 and the runs' error (rtol 1e-10, atol
    # 1e-12) over h ~ 1e-6 absolute on |dJ/dk| ~ 7: 1e-6 relative covers both
    assert r["g0"] == pytest.approx(mod["fd_gradient"](r["k0"]), rel=1e-6)
    # tuned: J dropped, the gradient vanished, no gain of the grid does better
    assert r["J_star"] < 0.6 * r["J0"] and abs(r["g_star"]) < 1e-3 * abs(r["g0"])
    ax_j, ax_e = fig.axes[:2]
    labels = [ln.get_label() for ln in ax_j.lines]
    assert {"$J(k)$", "gradient (sensitivity)", "tuned gain"} <= set(labels)
    grid_line = ax_j.lines[labels.index("$J(k)$")]
    assert np.min(grid_line.get_ydata()) >= r["J_star"] - 1e-9
    assert ax_e.get_yscale() == "log"
    assert [t.get_text() for t in ax_e.get_legend().get_texts()] == [
        f"initial k = {r['k0']:g}", f"tuned k = {r['k_star']:.3f}"]
    plt.close(fig)


# ----------------------------------------------------------------------- falsify
def _rate_reset(p):
    """x' = a from 0, reset to b at x = 1: t_2 = (2 - b) / a (p = (a, b))."""
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([p[0]]), jump_map=lambda x: np.array([p[1]]),
        jump_guard=lambda x: x[0] - 1.0, state_dim=1)


def _valley(arc):
    # smallest (1e-3) at t_2 = 1.5 and b = 0.2, i.e. (a, b) = (1.2, 0.2): inside the box
    b = arc.x[arc.is_jump_end][0, 0]
    return (arc.jump_times[1] - 1.5) ** 2 + (b - 0.2) ** 2 + 1e-3


def test_falsify_refines_by_gradient():
    from hybridsim.falsification import Interval, Space, falsify

    def run(pt):
        return hs.simulate(_rate_reset(pt.z), [0.0], t_max=5.0, j_max=2)

    calls = []

    def sens(pt):
        calls.append(pt.z)
        return simulate_sensitivity(_rate_reset, [0.0], t_max=5.0, j_max=2, params=pt.z,
                                    wrt="params")
    run.sensitivity = sens
    space = Space(a=Interval(0.5, 2.0), b=Interval(0.0, 0.5))
    grad = falsify(run, space, _valley, budget=150, seed=1, refine="gradient", stop=False)
    compass = falsify(run, space, _valley, budget=150, seed=1, refine=True, stop=False)
    assert calls and grad.evaluations <= 150
    # L-BFGS-B on an exact gradient lands on the minimiser of this smooth
    # valley: the margin to 1e-12 (rounding of t_2), the point to 1e-6
    assert grad.margin == pytest.approx(1e-3, abs=1e-12)
    np.testing.assert_allclose(grad.point.z, [1.2, 0.2], atol=1e-6)
    assert grad.margin <= compass.margin
    assert grad.verdict == "none found"


def test_falsify_gradient_falls_back_and_checks_its_input():
    from hybridsim.falsification import Interval, Space, falsify

    def no_guard(p):         # the jump set alone: no gradient (SensitivityError)
        # (bool(...): a set no guard is derived from, hybridsim._source)
        return hs.HybridSystem.from_functions(
            flow_map=lambda x: np.array([p[0]]), jump_map=lambda x: np.array([p[1]]),
            jump_set=lambda x: bool(x[0] >= 1.0), state_dim=1)

    def run(pt):
        return hs.simulate(_rate_reset(pt.z), [0.0], t_max=5.0, j_max=2)

    calls = []

    def sens(pt):
        calls.append(1)
        return simulate_sensitivity(no_guard, [0.0], t_max=5.0, j_max=2, params=pt.z,
                                    wrt="params")
    space = Space(a=Interval(0.5, 2.0), b=Interval(0.0, 0.5))
    with pytest.raises(ValueError, match="refine='gradient' needs run.sensitivity"):
        falsify(run, space, _valley, budget=20, refine="gradient")
    with pytest.raises(ValueError, match="refine must be True, False or 'gradient'"):
        falsify(run, space, _valley, budget=20, refine="newton")
    run.sensitivity = sens
    res = falsify(run, space, _valley, budget=60, seed=1, refine="gradient", stop=False)
    # one sensitivity run raised; the compass search used the rest of the budget
    assert len(calls) == 1 and res.evaluations == 60 and res.margin > 1e-3


def _ls_example():
    return runpy.run_path(str(EXAMPLES / "li_sanfelice_gain_tuning.py"), run_name="example")


@pytest.mark.slow
def test_a_paper_observer_in_an_interconnection_matches_differences():
    """Li & Sanfelice's H_n wired to its plant and a cost integrator
    (examples/li_sanfelice_gain_tuning.py): dJ/dk, with the gains (12) and so
    the jump map depending on k, equals central differences of whole runs;
    and so does dJ/d(delta), where the guard moves with the parameter. The
    jump's derivatives keep the components that jump at the event (a
    perturbation of tau or delta must not take H_n out of its D: with the
    interconnection's jump map differenced across that edge dJ/d(delta) was
    10% off). Tolerance: runs at rtol 1e-8 differenced with h = 1e-5 (error
    ~1e-8 / 1e-5 relative to |J| ~ 0.3, below 1e-3 of |dJ|), plus the
    truncation h^2 |J'''|."""
    mod = _ls_example()
    J, dJ, _ = mod["cost_and_gradient"](3.0)
    assert dJ == pytest.approx(mod["fd_gradient"](3.0), rel=1e-5)
    make, x0_of, opts = mod["make_system"], mod["x0_of"], mod["OPTS"]

    def system(p):                      # (k, delta) -> the same interconnection
        from observers import li_sanfelice as ls
        from observers.li_sanfelice.falsification import family_design
        ic = make([p[0]])
        obs = ls.NominalObserver(family_design(p[0], p[0] + 3.0, 1.0, 1.0, p[1]))
        return hs.Interconnection({"plant": ic.systems["plant"], "observer": obs,
                                   "cost": ic.systems["cost"]}, inputs=ic.inputs)
    p0 = np.array([3.0, 0.5])
    sarc = hs.simulate_sensitivity(system, x0_of(3.0), t_max=mod["T_END"], params=p0,
                                   wrt="params", **opts)
    np.testing.assert_allclose(sarc.dtj_dp[0], [0.0, 1.0], atol=1e-12)   # t_1 = delta
    h = 1e-5

    def J_at(p):
        return hs.simulate(system(p), x0_of(3.0), t_max=mod["T_END"], **opts).xf[-1]
    fd = (J_at(p0 + [0, h]) - J_at(p0 - [0, h])) / (2 * h)
    assert sarc.dx_dp[-1, -1, 1] == pytest.approx(fd, rel=1e-4)


@pytest.mark.slow
def test_example_li_sanfelice_gain_tuning(tmp_path):
    """The paper observer's gain tuned by L-BFGS-B on the sensitivity: J falls,
    the gradient vanishes at the optimum (checked by differences), and the
    figure draws J(k), the errors and the sensitivity through the jump."""
    import matplotlib.pyplot as plt
    mod = _ls_example()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r, fig = mod["main"](tmp_path)
    assert (tmp_path / "li_sanfelice_gain_tuning.png").is_file()
    assert r["g0"] == pytest.approx(mod["fd_gradient"](r["k0"]), rel=1e-5)
    assert r["J_star"] < 0.7 * r["J0"] and abs(r["g_star"]) < 1e-3 * abs(r["g0"])
    ax_j, ax_e, ax_s = fig.axes[:3]
    labels = [ln.get_label() for ln in ax_j.lines]
    assert "$J(k)$" in labels and "gradient (sensitivity)" in labels
    assert any(lb.startswith("tuned") for lb in labels)
    assert ax_e.get_yscale() == "log" and "jump" in ax_e.get_ylabel()
    assert {ln.get_label() for ln in ax_s.lines} >= {r"$\partial \bar x_1/\partial k$",
                                                      r"$\partial \bar x_2/\partial k$"}
    plt.close(fig)
