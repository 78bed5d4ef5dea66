"""Jumps at a rate and random jump maps (hybridsim._random_jumps), against known answers.

- AIMD x' = 1, x -> x/2 at rate r(x): the stationary generator equation
  E[k X^(k-1) + r(X) (2^-k - 1) X^k] = 0 gives, for r(x) = x,
  E[X^(k+1)] = k E[X^(k-1)] / (1 - 2^-k): E[X^2] = 2, E[X^4] = 3 * 2 / (7/8) = 48/7;
  for r = 1, E[X^k] = k E[X^(k-1)] / (1 - 2^-k): E[X] = 2, E[X^2] = 16/3.
- the telegraph process x' = v s, s -> -s at rate lam, x(0) = 0:
  E[X(t)^2] = v^2 (2 lam t - 1 + exp(-2 lam t)) / (2 lam^2).
- Brownian motion with drift mu > 0 and diffusion s from 0 to the barrier b: the hitting
  time is inverse Gaussian, mean b/mu, variance b s^2/mu^3.
- a ball dropped from h0 with i.i.d. restitutions of mean m: E[t_inf] = t1 + (2 v1/g) m/(1-m),
  t1 = sqrt(2 h0/g), v1 = g t1.
Each check is at 3 standard errors (of the sample, or of batch means for a time average).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import hybridsim as hs
from hybridsim._random_jumps import threshold
from hybridsim.estimate import Stats, accumulate, time_moments
from hybridsim.library import AIMD, DriftedBrownian, RandomRestitutionBall, Telegraph


def aimd(rate):
    return hs.HybridSystem.from_functions(flow_map=lambda x: np.array([1.0]),
                                          jump_map=lambda x: x / 2,
                                          jump_rate=rate, state_dim=1)


def test_aimd_stationary_moments():
    arc = hs.simulate(AIMD(), [1.0], t_max=4000.0, seed=1)
    (m2, s2), (m4, s4) = time_moments(arc, [2, 4], t_burn=20.0)
    assert abs(m2 - 2.0) <= 3 * s2, (m2, s2)
    assert abs(m4 - 48 / 7) <= 3 * s4, (m4, s4)
    # the thresholds drawn are recorded, one per rate-driven jump and the first
    th = arc.stats["thresholds"]
    assert len(th) == arc.jump_count + 1
    assert th[:3] == [threshold(arc.stats["jump_seed"], k) for k in range(3)]


@pytest.mark.slow
def test_constant_rate_aimd_moments():
    arc = hs.simulate(AIMD(constant_rate=True), [1.0], t_max=8000.0, seed=2)
    (m1, s1), (m2, s2) = time_moments(arc, [1, 2], t_burn=20.0)
    assert abs(m1 - 2.0) <= 3 * s1 and abs(m2 - 16 / 3) <= 3 * s2, (m1, s1, m2, s2)


def test_rate_jumps_are_located_exactly_and_replay():
    # rate 1 from x0 = 1: the first jump is at the first threshold E_0 (x' = 1: Lambda = t)
    arc = hs.simulate(aimd(lambda x: 1.0), [1.0], t_max=50.0, seed=7)
    e0 = threshold(arc.stats["jump_seed"], 0)
    assert arc.jump_times[0] == pytest.approx(e0, abs=1e-12)
    again = hs.simulate(aimd(lambda x: 1.0), [1.0], t_max=50.0, seed=arc.stats["jump_seed"])
    np.testing.assert_array_equal(again.x, arc.x)
    assert arc.state_dim == 1 and arc.system is not None


@pytest.mark.slow
def test_telegraph_second_moment():
    lam, v, t = 1.0, 1.0, 1.0
    exact = v * v * (2 * lam * t - 1 + math.exp(-2 * lam * t)) / (2 * lam * lam)
    sysm = Telegraph(lam, v)
    s = accumulate(lambda rng: hs.simulate(sysm, [0.0, 1.0], t_max=t, seed=rng),
                   Stats(t=[t], signal=lambda x: x[..., 0] ** 2), 1000, seed=3)
    assert abs(s.mean[0, 0] - exact) <= 3 * s.std_error[0, 0], (s.mean, s.std_error, exact)


@pytest.mark.slow
def test_brownian_hitting_time_with_drift():
    mu, sig, b = 1.0, 1.0, 2.0
    bm = DriftedBrownian(mu, sig, b)
    tau = np.array([hs.simulate(bm, [0.0], t_max=60.0, j_max=1, method="EM", max_step=0.1,
                                seed=r).jump_times[0] for r in range(1000)])
    n = len(tau)
    mean, var = b / mu, b * sig ** 2 / mu ** 3
    # the inverse Gaussian's 4th central moment 15 m^7/l^3 + 3 m^6/l^2, l = b^2/s^2
    lam_ig = b * b / sig ** 2
    mu4 = 15 * mean ** 7 / lam_ig ** 3 + 3 * mean ** 6 / lam_ig ** 2
    assert abs(tau.mean() - mean) <= 3 * math.sqrt(var / n)
    assert abs(tau.var(ddof=1) - var) <= 3 * math.sqrt((mu4 - var ** 2) / n)


@pytest.mark.slow
def test_ball_with_random_restitution():
    g, h0, lo, hi = 9.81, 1.0, 0.3, 0.7
    m = 0.5 * (lo + hi)
    ball = RandomRestitutionBall(g, lo, hi)
    t1 = math.sqrt(2 * h0 / g)
    t_inf = t1 + 2 * g * t1 / g * m / (1 - m)
    # the J-th jump comes at t1 + (2 v1/g) sum_{k<J} prod_{i<=k} e_i: its mean is t1 +
    # (2 v1/g) sum_{k=1}^{J-1} m^k (-> t_inf; 8 jumps: within 0.01 of it)
    J = 8
    exact = t1 + 2 * t1 * sum(m ** k for k in range(1, J))
    assert abs(exact - t_inf) < 0.01
    tj = np.array([hs.simulate(ball, [h0, 0.0], t_max=10.0, j_max=J, seed=r).jump_times[-1]
                   for r in range(1000)])
    se = tj.std(ddof=1) / math.sqrt(len(tj))
    assert abs(tj.mean() - exact) <= 3 * se, (tj.mean(), se, exact)


@pytest.mark.parametrize("rate, match", [
    (lambda x: -1.0, r"jump_rate returned -1.0 .*a rate must be a finite number >= 0"),
    (lambda x: math.nan, r"jump_rate returned nan"),
    (lambda x: "fast", "jump_rate must return a number"),
])
def test_bad_rates(rate, match):
    with pytest.raises(hs.MapError, match=match):
        hs.simulate(aimd(rate), [1.0], t_max=1.0, seed=0)


def test_bad_laws_and_refusals():
    nan_law = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_guard=lambda x: x[0] - 1, state_dim=1,
        jump_law=lambda x, rng: np.array([math.nan]))
    with pytest.raises(hs.MapError, match="jump_law returned non-finite values"):
        hs.simulate(nan_law, [0.0], t_max=2.0, seed=0)
    shape = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_guard=lambda x: x[0] - 1, state_dim=1,
        jump_law=lambda x, rng: np.zeros(3))
    with pytest.raises(hs.MapError, match=r"jump_law must return an array of shape \(1,\)"):
        hs.simulate(shape, [0.0], t_max=2.0, seed=0)
    # a failed run in a batch: its arc carries the cause naming the map
    arcs = hs.simulate_many(aimd(lambda x: -x[0]), [[1.0]], t_max=1.0, warn=False)
    assert arcs[0].termination is hs.Termination.MAP_ERROR
    assert "jump_rate" in str(arcs[0].exception)


def test_rate_on_an_sde_flow_is_located_on_the_clock():
    # an SDE flow with a rate-1 clock: Lambda = t exactly (no noise on the clock), so the
    # first jump is at the first threshold to round-off, whatever the Brownian path does
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([0.0]), jump_map=lambda x: np.zeros(1), jump_rate=lambda x: 1.0,
        diffusion=lambda x: np.array([1.0]), state_dim=1)
    arc = hs.simulate(sysm, [0.0], t_max=20.0, j_max=3, method="EM", max_step=0.1, seed=5)
    key = arc.stats["jump_seed"]
    assert arc.stats["noise_seed"] == key
    assert arc.jump_times[0] == pytest.approx(threshold(key, 0), abs=1e-12)
    assert arc.jump_times[1] - arc.jump_times[0] == pytest.approx(threshold(key, 1), abs=1e-12)
    assert np.all(arc.x[arc.is_jump_end, 0] == 0.0)
