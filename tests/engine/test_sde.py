"""SDE flows (hybridsim._sde): schemes, events exact in law, refusals.

Known answers:
- standard Brownian motion and the barrier 1 on [0, 1]: P(hit) = 2 (1 - Phi(1)) = 0.31731
  (reflection principle); the hitting time's law P(tau <= s) = 2 (1 - Phi(1/sqrt(s)));
  end-of-step detection sees only the grid's maximum, P ~ 2 (1 - Phi(1 + 0.5826 sqrt(dt)))
  (Broadie-Glasserman-Kou's continuity correction): 0.236 at dt = 0.1.
- geometric Brownian motion dX = mu X dt + s X dW: X(1) = X0 exp((mu - s^2/2) + s W(1)).
Proportions are checked at 3 binomial standard errors (the stated tolerance of the issue).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

import hybridsim as hs
from hybridsim.brownian import BrownianPath

P_HIT = 2 * norm.sf(1.0)


def barrier(guard=True):
    # without a guard: an indicator no guard is derived from (a call, bool(...)), so the
    # crossing is seen only at the steps' ends
    kw = (dict(jump_guard=lambda x: x[0] - 1.0) if guard
          else dict(jump_set=lambda x: bool(x[0] >= 1.0)))
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([0.0]), jump_map=lambda x: x,
        diffusion=lambda x: np.array([1.0]),
        state_dim=1, **kw)


def hits(system, dt, runs, seed0=0):
    times = []
    for r in range(runs):
        a = hs.simulate(system, [0.0], t_max=1.0, j_max=1, method="EM", max_step=dt,
                        seed=seed0 + r)
        times.append(a.jump_times[0] if a.jump_count else math.inf)
    return np.array(times)


@pytest.mark.slow
def test_barrier_probability_with_the_bridge_correction_and_the_bias_without():
    # 2000 paths at dt = 0.1: se 0.0104
    N, dt = 2000, 0.1
    tau = hits(barrier(), dt, N)
    p = np.mean(tau <= 1.0)
    se = math.sqrt(P_HIT * (1 - P_HIT) / N)
    assert abs(p - P_HIT) <= 3 * se, (p, se)
    # the crossing time is drawn inside the step: P(tau <= 0.35) = 2 (1 - Phi(1/sqrt(.35)))
    q = 2 * norm.sf(1 / math.sqrt(0.35))
    assert abs(np.mean(tau <= 0.35) - q) <= 3 * math.sqrt(q * (1 - q) / N)
    # end-of-step detection (no guard): the grid's maximum only, biased low
    p_end = np.mean(hits(barrier(guard=False), dt, N) <= 1.0)
    assert p_end < P_HIT - 5 * se
    approx = 2 * norm.sf(1 + 0.5826 * math.sqrt(dt))           # 0.236
    assert abs(p_end - approx) <= 3 * se + 0.01                 # + the correction's error


@pytest.mark.slow
@pytest.mark.parametrize("dt, N", [(0.1, 20000), (0.01, 20000), (0.001, 2000)])
def test_barrier_probability_slow(dt, N):
    p = np.mean(hits(barrier(), dt, N, seed0=10**6) <= 1.0)
    assert abs(p - P_HIT) <= 3 * math.sqrt(P_HIT * (1 - P_HIT) / N), p


def gbm(mu=0.5, s=0.8):
    return hs.HybridSystem.from_functions(flow_map=lambda x: mu * x, diffusion=lambda x: s * x,
                                          state_dim=1)


def strong_error(method, h, runs=100, mu=0.5, s=0.8):
    err = []
    for r in range(runs):
        w = BrownianPath(7, r, block=1.0)
        a = hs.simulate(gbm(mu, s), [1.0], t_max=1.0, method=method, max_step=h, seed=w)
        exact = math.exp(mu - s * s / 2 + s * w(1.0)[0])
        err.append(abs(a.xf[0] - exact))
    return float(np.mean(err))


@pytest.mark.slow
def test_strong_orders_on_the_same_paths():
    # one path per run whatever the step (a BrownianPath as the seed): EM's error falls
    # by about 2^(1/2) per halving, Milstein's by about 2; over 4 halvings (16x smaller h):
    # EM by 4 (order 1/2), Milstein by 16 (order 1); accepted: > 2.5 and > 9
    e1, e2 = strong_error("EM", 2**-4), strong_error("EM", 2**-8)
    m1, m2 = strong_error("Milstein", 2**-4), strong_error("Milstein", 2**-8)
    assert e1 / e2 > 2.5 and m1 / m2 > 9, (e1, e2, m1, m2)
    assert m2 < e2


def ou_error(method, h, runs=40):
    ou = hs.HybridSystem.from_functions(flow_map=lambda x: -x, diffusion=lambda x: np.array([0.5]),
                                        state_dim=1)
    err = []
    for r in range(runs):
        w = BrownianPath(3, r, block=1.0)
        ref = hs.simulate(ou, [1.0], t_max=1.0, method="SRA1", max_step=2**-9, seed=w).xf[0]
        a = hs.simulate(ou, [1.0], t_max=1.0, method=method, max_step=h, seed=w)
        err.append(abs(a.xf[0] - ref))
    return float(np.mean(err))


@pytest.mark.slow
def test_sra1_is_strong_order_1_5_on_additive_noise():
    # Ornstein-Uhlenbeck dX = -X dt + 0.5 dW against SRA1 at h = 2^-9 on the same path:
    # SRA1's error falls by 2^1.5 = 2.8 per halving (8 over two), EM's (order 1 for additive
    # noise) by 2 (4 over two); accepted: SRA1 > 5.5, and below EM's at the same step
    s1, s2 = ou_error("SRA1", 2**-3), ou_error("SRA1", 2**-5)
    em = ou_error("EM", 2**-5)
    assert s1 / s2 > 5.5 and s2 < em / 3, (s1, s2, em)


def test_same_seed_same_run_and_the_arc_records_the_path():
    a = hs.simulate(barrier(), [0.0], t_max=1.0, j_max=1, method="EM", max_step=0.1, seed=4)
    b = hs.simulate(barrier(), [0.0], t_max=1.0, j_max=1, method="EM", max_step=0.1, seed=4)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.t, b.t)
    st = a.stats
    w = BrownianPath(st["noise_seed"], st["noise_run"], 1, t0=st["noise_t0"],
                     block=st["noise_block"], depth=st["noise_depth"])
    c = hs.simulate(barrier(), [0.0], t_max=1.0, j_max=1, method="EM", max_step=0.1, seed=w)
    np.testing.assert_array_equal(c.x, a.x)
    # EM on dx = dW is the path itself at the grid's times, up to the event
    k = a.t <= (a.jump_times[0] if a.jump_count else 1.0)
    grid = np.isclose(a.t * 10, np.round(a.t * 10)) & k & (a.j == 0)
    np.testing.assert_allclose(a.x[grid, 0], w(a.t[grid])[:, 0], atol=1e-12)


def test_general_noise_and_flow_guard():
    # 2-D Brownian motion driven by 3 noises: sigma (2, 3), variance of x_i(1) = |row_i|^2;
    # a flow guard stops the run where x leaves the disc of radius 2
    S = np.array([[1.0, 0.5, 0.0], [0.0, 0.3, 0.4]])
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: np.zeros(2), diffusion=lambda x: S,
                                          noise_dim=3, state_dim=2)
    xs = np.array([hs.simulate(sysm, [0.0, 0.0], t_max=1.0, method="EM", max_step=0.25,
                               seed=r).xf for r in range(1500)])
    v = xs.var(axis=0) / (S ** 2).sum(axis=1)
    assert np.all(np.abs(v - 1) < 4.5 * math.sqrt(2 / 1500)), v
    disc = hs.HybridSystem.from_functions(flow_map=lambda x: np.zeros(2), diffusion=lambda x: S,
                                          noise_dim=3, state_dim=2,
                                          flow_guard=lambda x: 0.5 - x @ x)
    a = hs.simulate(disc, [0.0, 0.0], t_max=50.0, method="EM", max_step=0.05, seed=1,
                    warn=False)
    assert a.termination is hs.Termination.LEFT_SETS
    assert a.xf @ a.xf == pytest.approx(0.5, abs=1e-12)     # on the boundary


def test_refusals_and_bad_input():
    b = barrier()
    with pytest.raises(ValueError, match="declares diffusion.*method must be one of"):
        hs.simulate(b, [0.0], t_max=1.0, max_step=0.1)
    with pytest.raises(ValueError, match="max_step"):
        hs.simulate(b, [0.0], t_max=1.0, method="EM")
    with pytest.raises(ValueError, match="t_eval"):
        hs.simulate(b, [0.0], t_max=1.0, method="EM", max_step=0.1, t_eval=[0.5])
    vb = hs.HybridSystem.from_functions(
        flow_map=lambda x: 0 * x, diffusion=lambda x: 1 + 0 * x, jump_guard=lambda x: x[..., 0] - 1,
        jump_map=lambda x: x, state_dim=1, vectorized=True)
    with pytest.raises(ValueError, match="the vectorized path does not step"):
        hs.simulate_vectorized(vb, [[0.0]], t_max=1.0)
    arcs = hs.simulate_many(vb, [[0.0], [0.0]], t_max=1.0, j_max=1, method="EM",
                            max_step=0.1)           # simulate_many runs it row by row
    assert [a.stats["sde_method"] for a in arcs] == ["EM", "EM"]
    assert arcs[0].stats["noise_seed"] != arcs[1].stats["noise_seed"]     # fresh entropy
    with pytest.raises(ValueError, match="every row .* would draw the same"):
        hs.simulate_many(vb, [[0.0], [0.0]], t_max=1.0, method="EM", max_step=0.1, seed=3)
    bad = hs.HybridSystem.from_functions(flow_map=lambda x: np.zeros(1), state_dim=1,
                                         diffusion=lambda x: np.ones(2))
    with pytest.raises(hs.MapError, match=r"diffusion must return an array of shape \(1,\)"):
        hs.simulate(bad, [0.0], t_max=1.0, method="EM", max_step=0.1)
    raises = hs.HybridSystem.from_functions(flow_map=lambda x: np.zeros(1), state_dim=1,
                                            diffusion=lambda x: 1 / 0)
    with pytest.raises(hs.MapError, match="diffusion raised ZeroDivisionError"):
        hs.simulate(raises, [0.0], t_max=1.0, method="EM", max_step=0.1)
    gen = hs.HybridSystem.from_functions(flow_map=lambda x: np.zeros(1), state_dim=1, noise_dim=2,
                                         diffusion=lambda x: np.ones((1, 2)))
    with pytest.raises(ValueError, match="Milstein' takes diagonal noise"):
        hs.simulate(gen, [0.0], t_max=1.0, method="Milstein", max_step=0.1)
    with pytest.raises(hs.MapError, match="SRA1' takes additive noise"):
        hs.simulate(gbm(), [1.0], t_max=1.0, method="SRA1", max_step=0.1)
    with pytest.raises(ValueError, match=r"systems\['p'\] declares diffusion: an "
                                         r"interconnection does not carry"):
        hs.Interconnection({"p": gbm(), "q": gbm()})
