"""Stochastic systems on every path: the compiled path runs SDE flows (and jumps at
a rate) with the Python path's draws, so the same seed gives the same arc; the
vectorized path refuses them by name.

Tolerances: arcs of the same seed agree to 1e-12 (the same arithmetic; only
the order of a few sums may differ); proportions and means are checked at 3
standard errors (the issue's tolerance).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

import hybridsim as hs
from hybridsim.library import AIMD, DriftedBrownian, Telegraph

P_HIT = 2 * norm.sf(1.0)          # standard BM, barrier 1 on [0, 1]


def barrier(vectorized=False):
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: 0.0 * x, jump_map=lambda x: x, diffusion=lambda x: 1.0 + 0.0 * x,
        jump_guard=lambda x: x[..., 0] - 1.0, state_dim=1, vectorized=vectorized)


def _run(path, system, x0, **kw):
    if path == "vectorized":
        return hs.simulate_vectorized(system, np.atleast_2d(x0), **kw)[0]
    return hs.simulate(system, x0, backend=path, **kw)


def _same(a, b):
    assert a.termination is b.termination
    np.testing.assert_array_equal(a.j, b.j)
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)


@pytest.mark.parametrize("method", ["EM", "Milstein", "SRA1"])
def test_same_seed_same_arc_on_every_path(path, method):
    # the bridge-corrected barrier event, drawn inside a step, on the same Brownian path
    kw = dict(t_max=1.0, j_max=1, method=method, max_step=0.1)
    if path == "vectorized":
        with pytest.raises(ValueError, match="declares diffusion"):
            _run(path, barrier(vectorized=True), [0.0], seed=4, **kw)
        return
    for seed in (1, 4):
        ref = hs.simulate(barrier(), [0.0], seed=seed, **kw)
        a = _run(path, barrier(), [0.0], seed=seed, **kw)
        _same(a, ref)
        assert a.stats == ref.stats            # the path recorded: noise_seed, block...


def test_general_noise_flow_guard_and_a_state_dependent_diffusion(path):
    S = np.array([[1.0, 0.5, 0.0], [0.0, 0.3, 0.4]])
    disc = hs.HybridSystem.from_functions(flow_map=lambda x: 0.0 * x, diffusion=lambda x: S,
                                          noise_dim=3, state_dim=2,
                                          flow_guard=lambda x: 0.5 - x @ x,
                                          vectorized=path == "vectorized")
    gbm = hs.HybridSystem.from_functions(flow_map=lambda x: 0.5 * x,
                                         diffusion=lambda x: 0.8 * x, state_dim=1)
    kw = dict(t_max=50.0, method="EM", max_step=0.05, seed=1, warn=False)
    if path == "vectorized":
        with pytest.raises(ValueError, match="declares diffusion"):
            _run(path, disc, [0.0, 0.0], **kw)
        return
    a = _run(path, disc, [0.0, 0.0], **kw)
    _same(a, hs.simulate(disc, [0.0, 0.0], **kw))
    assert a.termination is hs.Termination.LEFT_SETS
    for method in ("EM", "Milstein"):
        kw = dict(t_max=1.0, method=method, max_step=0.01, seed=7)
        _same(_run(path, gbm, [1.0], **kw), hs.simulate(gbm, [1.0], **kw))


@pytest.mark.paths(only=("python", "compiled"))
def test_batch_rows_replay_and_refusals(path):
    s = DriftedBrownian(1.0, 1.0, 2.0)
    B = hs.simulate_many(s, np.zeros((6, 1)), 20.0, 1, method="EM", max_step=0.01,
                         backend=path)
    seeds = [a.stats["noise_seed"] for a in B]
    assert len(set(seeds)) == 6                           # fresh entropy per row
    for a in (B[0], B[5]):                                # each row replays on the Python path
        _same(a, hs.simulate(s, [0.0], 20.0, 1, method="EM", max_step=0.01,
                             seed=a.stats["noise_seed"]))
    bad = hs.HybridSystem.from_functions(flow_map=lambda x: np.zeros(1), state_dim=1,
                                         diffusion=lambda x: np.ones(2))
    with pytest.raises(hs.MapError, match=r"diffusion must return an array of shape \(1,\)"):
        _run(path, bad, [0.0], t_max=1.0, method="EM", max_step=0.1)
    gbm = hs.HybridSystem.from_functions(flow_map=lambda x: 0.5 * x,
                                         diffusion=lambda x: 0.8 * x, state_dim=1)
    with pytest.raises(hs.MapError, match="SRA1' takes additive noise"):
        _run(path, gbm, [1.0], t_max=1.0, method="SRA1", max_step=0.1)


@pytest.mark.slow
def test_compiled_barrier_probability_and_hitting_time_law():
    # 20,000 compiled paths at dt = 0.01: P(hit) within 3 binomial standard errors (0.0099)
    N = 20_000
    B = hs.simulate_many(barrier(), np.zeros((N, 1)), 1.0, 1, method="EM", max_step=0.01,
                         backend="compiled")
    p = np.mean(B.jump_counts > 0)
    se = math.sqrt(P_HIT * (1 - P_HIT) / N)
    assert abs(p - P_HIT) <= 3 * se, (p, se)


def aimd(rate, vectorized=False):
    return hs.HybridSystem.from_functions(flow_map=lambda x: 1.0 + 0.0 * x,
                                          jump_map=lambda x: x / 2, jump_rate=rate,
                                          state_dim=1, vectorized=vectorized)


# compiled: 5.5 s of CPU (each system's rate kernel compiled) and 80 MB kept by
# the worker; test_compiled_system_keywords runs compiled rate jumps in the default suite
@pytest.mark.paths(compiled_slow=True)
def test_rate_jumps_same_seed_same_arc_on_every_path(path):
    # the clock (its thresholds drawn from the run's key) is the Python path's on every
    # path: the same jumps, to round-off of the located times
    if path == "vectorized":
        with pytest.raises(ValueError, match="declares jump_rate"):
            hs.simulate_vectorized(aimd(lambda x: x[..., 0], vectorized=True), [[1.0]],
                                   t_max=10.0)
        return
    for sysm, x0 in ((AIMD(), [1.0]), (Telegraph(2.0, 0.5), [0.0, 1.0])):
        ref = hs.simulate(sysm, x0, 30.0, seed=3)
        a = hs.simulate(sysm, x0, 30.0, seed=3, backend=path)
        _same(a, ref)
        assert a.stats["thresholds"] == ref.stats["thresholds"]
        assert a.stats["jump_seed"] == ref.stats["jump_seed"]
    # a rate on an SDE flow: the clock located on its chord, the same Brownian path
    sde = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([0.0]), jump_map=lambda x: np.zeros(1),
        jump_rate=lambda x: 1.0, diffusion=lambda x: np.array([1.0]), state_dim=1)
    kw = dict(t_max=20.0, j_max=3, method="EM", max_step=0.1, seed=5)
    _same(hs.simulate(sde, [0.0], backend=path, **kw), hs.simulate(sde, [0.0], **kw))


# compiled: 2.8 s of CPU and 30 MB (as above)
@pytest.mark.paths(only=("python", "compiled"), compiled_slow=True)
def test_rate_batches_replay_and_bad_rates(path):
    B = hs.simulate_many(AIMD(), np.ones((5, 1)), 20.0, backend=path)
    keys = [a.stats["jump_seed"] for a in B]
    assert len(set(keys)) == 5
    _same(B[4], hs.simulate(AIMD(), [1.0], 20.0, seed=keys[4]))
    with pytest.raises(hs.MapError, match=r"jump_rate returned -1.0 .*finite number >= 0"):
        hs.simulate(aimd(lambda x: -1.0), [1.0], t_max=1.0, seed=0, backend=path)
    law = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_guard=lambda x: x[0] - 1, state_dim=1,
        jump_law=lambda x, rng: x * rng.uniform())
    if path == "compiled":
        with pytest.raises(ValueError, match="declares jump_law"):
            hs.simulate(law, [0.0], t_max=2.0, seed=0, backend=path)


@pytest.mark.paths(only=("python", "compiled"), compiled_slow=True)   # 2.8 s of CPU compiled
def test_compiled_system_keywords(path):
    # CompiledSystem(diffusion=, jump_rate=): the one vocabulary, the same runs on both paths
    from hybridsim.compiled import CompiledSystem
    ou = CompiledSystem(flow_map=lambda x, t, j, p: -p[0] * x,
                        diffusion=lambda x, t, j, p: np.full(1, p[1]), state_dim=1,
                        params=[1.0, 0.5])
    kw = dict(t_max=2.0, method="SRA1", max_step=0.05, seed=9)
    _same(hs.simulate(ou, [1.0], backend=path, **kw), hs.simulate(ou, [1.0], **kw))
    tcp = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1),
                         jump_map=lambda x, t, j, p: x / 2,
                         jump_rate=lambda x, t, j, p: x[0], state_dim=1)
    a = hs.simulate(tcp, [1.0], 20.0, seed=2, backend=path)
    _same(a, hs.simulate(tcp, [1.0], 20.0, seed=2))
    B = hs.simulate_many(tcp, np.ones((3, 1)), 5.0, backend=path)
    assert len({b.stats["jump_seed"] for b in B}) == 3
    # the kernel's own runners step ODE flows: noise is refused there by name, pointing
    # at the front door that runs it compiled
    from hybridsim.compiled import simulate_compiled, simulate_many_compiled
    with pytest.raises(TypeError, match=r"simulate_compiled: .*declares diffusion.*hs\.simulate"):
        simulate_compiled(ou, [1.0], 2.0)
    with pytest.raises(TypeError, match=r"simulate_many_compiled: .*declares jump_rate"):
        simulate_many_compiled(tcp, np.ones((2, 1)), 2.0)
