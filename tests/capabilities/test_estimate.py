"""hybridsim.estimate: Monte Carlo answers with confidence.

Every check has a known answer: Bernoulli runs of a stated p, the timer
whose period is uniform (P(jump by t=1) = 1/2), sums of Gaussians, and the
Brownian maximum P(sup_[0,1] W >= b) = 2 (1 - Phi(b)) (reflection
principle) for splitting.
"""
from __future__ import annotations

import concurrent.futures
import math
import pickle

import numpy as np
import pytest
from scipy.stats import norm

import hybridsim as hs
from hybridsim.arc import HybridArc
from hybridsim.estimate import (
    Stats,
    accumulate,
    clopper_pearson,
    estimate,
    hybrid_segments,
    run_generator,
    splitting,
    time_moments,
)
from hybridsim.falsification import batch_run
from hybridsim.library import Timer
from hybridsim.rules import Termination


def bernoulli(p):
    return lambda rng: rng.random() < p


# ------------------------------------------------------------------ Clopper-Pearson
def test_clopper_pearson_closed_forms():
    # k = 0: hi = 1 - (alpha/2)^(1/n); k = n: lo = (alpha/2)^(1/n)
    n, a = 20, 0.05
    assert clopper_pearson(0, n, 0.95) == (0.0, pytest.approx(1 - (a / 2) ** (1 / n)))
    lo, hi = clopper_pearson(n, n, 0.95)
    assert hi == 1.0 and lo == pytest.approx((a / 2) ** (1 / n))
    # a textbook value: 5 of 10 at 95%: [0.187086, 0.812914]
    lo, hi = clopper_pearson(5, 10)
    assert (lo, hi) == (pytest.approx(0.187086, abs=1e-6), pytest.approx(0.812914, abs=1e-6))


def test_clopper_pearson_covers_at_least_nominal():
    # exact coverage for n = 30, p = 0.1: sum of binomial pmf over k whose interval holds p
    from scipy.stats import binom
    n, p = 30, 0.1
    cover = sum(binom.pmf(k, n, p) for k in range(n + 1)
                if clopper_pearson(k, n, 0.9)[0] <= p <= clopper_pearson(k, n, 0.9)[1])
    assert cover >= 0.9


# ------------------------------------------------------------------ estimate
def test_estimate_reaches_half_width_and_covers():
    res = estimate(bernoulli(0.3), event=lambda e: e, half_width=0.02, seed=3)
    assert res.reached and res.half_width <= 0.02
    assert res.lo <= 0.3 <= res.hi
    assert res.k == round(res.p * res.n) and res.stopping == "union"
    assert "runs" in str(res)


def test_estimate_is_reproducible_whatever_the_batches():
    # run i always gets run_generator(seed, i): batch sizes do not change the answer
    a = estimate(bernoulli(0.3), event=bool, half_width=0.05, seed=11, batch=100,
                 max_runs=800)
    b = estimate(bernoulli(0.3), event=bool, half_width=0.05, seed=11, batch=800,
                 max_runs=800)
    draws = [run_generator(11, i).random() < 0.3 for i in range(a.n)]
    assert a.k == sum(draws)
    if a.n == b.n:
        assert a.k == b.k
    c = estimate(bernoulli(0.3), event=bool, half_width=0.05, seed=11, batch=100,
                 max_runs=800)
    assert c == a


def test_union_stopping_is_wider_than_plain():
    u = estimate(bernoulli(0.5), event=bool, half_width=0.001, seed=0, batch=100,
                 max_runs=400)
    p = estimate(bernoulli(0.5), event=bool, half_width=0.001, seed=0, batch=100,
                 max_runs=400, stopping="plain")
    assert (u.n, u.k) == (p.n, p.k) and not u.reached
    assert u.lo < p.lo and u.hi > p.hi
    # the plain interval is the fixed-n Clopper-Pearson interval at the final n
    assert (p.lo, p.hi) == clopper_pearson(p.k, p.n, 0.95)
    # union at look 3: level 1 - 0.05/12
    assert (u.lo, u.hi) == clopper_pearson(u.k, u.n, 1 - 0.05 / 12)


@pytest.mark.slow
def test_union_stopping_covers_under_optional_stopping():
    # 100 studies of p = 0.05 stopping at half-width 0.03: the union intervals cover in
    # at least 95% of them (conservative: observed coverage near 1); binomial slack 3 sd
    hits = 0
    for s in range(100):
        r = estimate(bernoulli(0.05), event=bool, half_width=0.03, seed=s, batch=50)
        hits += r.lo <= 0.05 <= r.hi
    assert hits >= 100 * 0.95 - 3 * math.sqrt(100 * 0.95 * 0.05)


@pytest.mark.slow
def test_estimate_through_simulate_many_with_a_claim():
    # P(the timer's period < 1) = 1/2 with the period uniform in [0.5, 1.5]: a claim whose
    # margin is the first jump time minus 1, run as one simulate_many a batch
    class T(hs.HybridSystem):              # state (tau, period)
        state_dim = 2

        def flow_map(self, x):
            return np.array([1.0, 0.0])

        def jump_map(self, x):
            return np.array([0.0, x[1]])

        def flow_set(self, x):
            return x[0] <= x[1]

        def jump_set(self, x):
            return x[0] >= x[1]

    run = batch_run(T(), lambda rng: [0.0, rng.uniform(0.5, 1.5)], 1.5, 1, backend="python")
    res = estimate(run, claim=lambda arc: (arc.jump_times[0] if arc.jump_count else 2.0) - 1,
                   half_width=0.08, seed=5, batch=64)
    assert res.lo <= 0.5 <= res.hi and res.reached
    single = estimate(lambda rng: hs.simulate(T(), [0.0, rng.uniform(0.5, 1.5)], t_max=1.5,
                                              j_max=1),
                      claim=lambda arc: (arc.jump_times[0] if arc.jump_count else 2.0) - 1,
                      half_width=0.08, seed=5, batch=64)
    assert (single.k, single.n) == (res.k, res.n)


def test_estimate_failed_runs():
    bad = HybridArc([0.0], [0], [[0.0]], Termination.MAP_ERROR, "f raised")
    with pytest.raises(RuntimeError, match="run 0 ended with MAP_ERROR"):
        estimate(lambda rng: bad, event=lambda a: False, half_width=0.1, batch=5)
    r = estimate(lambda rng: bad, event=lambda a: False, half_width=0.3, batch=5,
                 failures="event", seed=0)
    assert r.k == r.n == r.failed


@pytest.mark.parametrize("kw, err, match", [
    (dict(), TypeError, "exactly one of event"),
    (dict(event=bool, claim=float), TypeError, "exactly one of event"),
    (dict(event=bool, half_width=0), ValueError, "half_width"),
    (dict(event=bool, confidence=1.0), ValueError, "confidence"),
    (dict(event=bool, batch=0), ValueError, "batch"),
    (dict(event=bool, stopping="naive"), ValueError, "stopping"),
    (dict(event=bool, seed=-1), TypeError, "seed"),
    (dict(event=lambda u: 1.0), TypeError, "event must return True or False"),
    (dict(claim=lambda u: math.nan), ValueError, "claim returned NaN"),
    (dict(claim=lambda u: "x"), TypeError, "claim must return a real number"),
])
def test_estimate_bad_input(kw, err, match):
    with pytest.raises(err, match=match):
        estimate(lambda rng: rng.random(), **kw)


# ------------------------------------------------------------------ streaming statistics
def const_arc(rng):
    """A run whose state is a N(0, 1) constant c and a ramp c t on [0, 1]."""
    c = rng.normal()
    return HybridArc([0.0, 1.0], [0, 0], [[c, 0.0], [c, c]], None)


def test_stats_match_numpy_and_merge_equals_whole():
    grid = [0.0, 0.5, 1.0]
    s = accumulate(const_arc, Stats(t=grid, thresholds=[0.0, 1.0], bins=(-4, 4, 80)),
                   3000, seed=2, batch=700)
    cs = np.array([run_generator(2, i).normal() for i in range(3000)])
    vals = np.stack([np.column_stack([cs, cs * t]) for t in grid], axis=1)   # (runs, 3, 2)
    np.testing.assert_allclose(s.mean, vals.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(s.variance[1:], vals.var(axis=0, ddof=1)[1:], rtol=1e-10)
    np.testing.assert_array_equal(s.exceed, (vals[..., None] > [0.0, 1.0]).sum(axis=0))
    np.testing.assert_array_equal(s.min, vals.min(axis=0))
    # quantiles from the histogram: within one bin width (0.1) of numpy's
    q = s.quantile([0.1, 0.5, 0.9])
    assert np.all(np.abs(q[:, :, 0] - np.quantile(cs, [0.1, 0.5, 0.9])[:, None]) <= 0.1)
    # two halves merged (Chan's update) give the whole to round-off
    a = accumulate(const_arc, Stats(t=grid, thresholds=[0.0, 1.0], bins=(-4, 4, 80)),
                   3000, seed=2, batch=3000)
    np.testing.assert_allclose(a.mean, s.mean, atol=1e-13)
    np.testing.assert_allclose(a._m2, s._m2, rtol=1e-11)
    np.testing.assert_array_equal(a.hist, s.hist)


@pytest.mark.slow
def test_stats_state_size_is_independent_of_runs():
    # bounded memory by design: the pickled state after 10 and after 5000 runs is the same size
    small = accumulate(const_arc, Stats(t=np.linspace(0, 1, 11), thresholds=[0.5],
                                        bins=(-3, 3, 60)), 10, seed=0)
    big = accumulate(const_arc, Stats(t=np.linspace(0, 1, 11), thresholds=[0.5],
                                      bins=(-3, 3, 60)), 5000, seed=0)
    def nbytes(s):
        return sum(v.nbytes for v in vars(s).values() if isinstance(v, np.ndarray))
    assert nbytes(small) == nbytes(big)
    # the pickles differ only in the run counter's encoding (a few bytes)
    assert abs(len(pickle.dumps(small)) - len(pickle.dumps(big))) <= 8
    assert big.runs == 5000 and small.runs == 10


def test_stats_merge_across_processes_equals_serial():
    grid = np.linspace(0, 1, 5)
    serial = accumulate(const_arc, Stats(t=grid, bins=(-4, 4, 40)), 400, seed=9)
    with concurrent.futures.ThreadPoolExecutor(2) as ex:
        spread = accumulate(const_arc, Stats(t=grid, bins=(-4, 4, 40)), 400, seed=9,
                            executor=ex, chunks=3)
    np.testing.assert_allclose(spread.mean, serial.mean, atol=1e-13)
    np.testing.assert_allclose(spread.variance, serial.variance, rtol=1e-11)
    np.testing.assert_array_equal(spread.hist, serial.hist)
    back = pickle.loads(pickle.dumps(spread))
    np.testing.assert_array_equal(back.mean, spread.mean)
    assert back.merge(serial).runs == 800


def test_stats_on_jump_counts_and_runs_that_end_early():
    # timers of period 1 from tau = 0 and 0.5 to t = 2: two jumps each, the state right after
    # a jump is 0, and no run has a third jump; a run of t_max 1.2 has no value at t = 1.5
    arcs = hs.simulate_many(Timer(1.0), [[0.0], [0.5]], t_max=2.0)
    sj = Stats(j=[0, 1, 2, 3], signal=lambda x: x[..., 0])
    sj.update(arcs)
    np.testing.assert_array_equal(sj.count, [2, 2, 2, 0])
    np.testing.assert_allclose(sj.mean[:3, 0], [0.25, 0.0, 0.0], atol=1e-12)
    assert np.isnan(sj.mean[3, 0])
    st = Stats(t=[1.0, 1.5], signal=0)
    st.update(hs.simulate_many(Timer(1.0), [[0.0]], t_max=1.2))
    np.testing.assert_array_equal(st.count, [1, 0])
    assert np.isnan(st.mean[1, 0]) and np.isnan(st.variance[1, 0])


def _ball():
    from hybridsim.library import BouncingBall
    h0 = np.linspace(0.5, 2.0, 9)
    return (BouncingBall(), np.column_stack([h0, 0 * h0]), 1.7,
            lambda x: x[..., 0] * x[..., 1] + 1.0)


@pytest.mark.parametrize("case", [
    pytest.param(lambda: (Timer(1.0), np.r_[np.linspace(0, 0.9, 8), np.nan][:, None], 2.5, 0),
                 id="timer"),
    pytest.param(_ball, id="ball", marks=pytest.mark.slow)])
def test_stats_of_a_compiled_batch_read_off_its_pools_equal_the_arcs(case):
    # the compiled batch's rows are read off its pools together; a failed row (NaN x0), a
    # grid time at a jump, between samples and past the end; timers, and balls whose
    # signal reads both components (Hermite between samples)
    pytest.importorskip("numba")
    system, x0s, t_max, signal = case()
    batch = hs.simulate_many(system, x0s, t_max, backend="compiled", warn=False)
    for grid in (dict(t=np.r_[np.linspace(0, t_max + 0.3, 23), 1.0]),
                 dict(j=[0, 1, 2, 3, 7])):
        grid = {k: np.sort(v) for k, v in grid.items()}
        fast, slow = (Stats(signal=signal, thresholds=[0.5], bins=(-3, 3, 30), **grid)
                      for _ in range(2))
        fast.update(batch)
        slow.update(list(batch))              # a plain list: arc by arc
        for k in ("count", "_mean", "_m2", "min", "max", "exceed", "hist"):
            np.testing.assert_array_equal(getattr(fast, k), getattr(slow, k), err_msg=k)
        assert fast.runs == slow.runs == len(x0s)
        assert fast.count.max() == np.isfinite(x0s).all(axis=1).sum()  # a NaN row: none
    with pytest.raises(ValueError, match="signal"):
        Stats(t=[0.5], signal=lambda x: x[:1]).update(batch)


# ------------------------------------------------------------------ time moments of one run
def sawtooth(rate, top):
    """x' = rate from 0 up to top (rate > 0) or from top down to 0 (rate < 0), then reset:
    the time average of x^k is top^k / (k + 1)."""
    up = rate > 0
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([rate]), jump_map=lambda x: np.array([0.0 if up else top]),
        jump_guard=(lambda x: x[0] - top) if up else (lambda x: -x[0]),
        flow_guard=(lambda x: top - x[0]) if up else (lambda x: x[0]), state_dim=1)


@pytest.mark.parametrize("rate, top, x0", [(1.0, 1.0, 0.0), (2.0, 1.5, 0.0), (-3.0, 3.0, 3.0)])
def test_time_moments_exact_on_constant_rate_flows(rate, top, x0):
    # 40 periods, windows of two periods each: every window's average is the period's
    period = top / abs(rate)
    arc = hs.simulate(sawtooth(rate, top), [x0], t_max=40 * period, rtol=1e-10, atol=1e-12)
    out = time_moments(arc, [0, 1, 2, 4], batches=20)
    for k, (m, se) in zip([0, 1, 2, 4], out):
        assert m == pytest.approx(top ** k / (k + 1), rel=1e-9)
        assert se <= 1e-9 * top ** k
    # t_burn drops the transient: from halfway, the sawtooth is joined at the first jump
    arc = hs.simulate(sawtooth(rate, top), [0.5 * top], t_max=40.5 * period, rtol=1e-10,
                      atol=1e-12)
    (m2, _), = time_moments(arc, [2], t_burn=arc.jump_times[0], batches=4)
    assert m2 == pytest.approx(top ** 2 / 3, rel=1e-9)


def test_time_moments_batch_means_error_covers_a_stationary_moment():
    # AIMD at rate 1 (x' = 1, x -> x/2 at rate 1): E[X] = 2, within 3 batch-means errors,
    # which shrink like 1/sqrt(T)
    from hybridsim.library import AIMD
    short = hs.simulate(AIMD(constant_rate=True), [1.0], t_max=1000.0, seed=4)
    long = hs.simulate(AIMD(constant_rate=True), [1.0], t_max=4000.0, seed=4)
    (m, se), = time_moments(long, [1], t_burn=20.0)
    (_, se_short), = time_moments(short, [1], t_burn=20.0)
    assert abs(m - 2.0) <= 3 * se
    assert 1.2 < se_short / se < 3.5          # sqrt(4) = 2, up to the errors' own noise


@pytest.mark.parametrize("kw, match", [
    (dict(powers=[1.5]), "powers must be non-negative ints"),
    (dict(powers=[-1]), "powers must be non-negative ints"),
    (dict(powers=[1], batches=1), "batches must be an int >= 2"),
    (dict(powers=[1], component=1), "component must be an int in"),
    (dict(powers=[1], t_burn=5.0), "no flow after t_burn"),
    (dict(powers=[1], batches=400), "windows hold no flow"),
])
def test_time_moments_bad_input(kw, match):
    arc = hs.simulate(Timer(1.0), [0.0], t_max=3.0)
    with pytest.raises(ValueError, match=match):
        time_moments(arc, **kw)


def test_stats_bad_input():
    with pytest.raises(TypeError, match="exactly one of t="):
        Stats()
    with pytest.raises(ValueError, match="non-decreasing"):
        Stats(t=[1.0, 0.0])
    with pytest.raises(ValueError, match="bins"):
        Stats(t=[0.0], bins=(1, 0, 5))
    with pytest.raises(ValueError, match="differ in grid"):
        Stats(t=[0.0]).merge(Stats(t=[1.0]))
    with pytest.raises(ValueError, match="needs bins"):
        accumulate(const_arc, Stats(t=[0.0]), 3, seed=0).quantile(0.5)


# ------------------------------------------------------------------ splitting
def brownian_chain(step):
    """Brownian motion on [0, 1] as a Markov chain of states (t, W_t, M), M the maximum of
    W over the step that ended at t, drawn exactly from the Brownian bridge between the two
    grid values: the chain's max of M is the continuous path's supremum in law."""
    def simulate(s, rng):
        t0, w0 = s[0], s[1]
        m = round((1.0 - t0) / step)
        if m <= 0:
            return np.asarray(s, dtype=float)[None]
        t = t0 + step * np.arange(m + 1)
        t[-1] = 1.0
        h = np.diff(t)
        dw = rng.standard_normal(m) * np.sqrt(h)
        w = w0 + np.concatenate([[0.0], np.cumsum(dw)])
        mx = 0.5 * (w[:-1] + w[1:] + np.sqrt(dw ** 2 - 2 * h * np.log(rng.random(m))))
        return np.column_stack([t, w, np.concatenate([[s[2]], mx])])
    return simulate


def committor_score(b):
    """A score whose level sets are the committor's, P(hit b by 1 | t, w) = 2 Phi((w - b) /
    sqrt(1 - t)): b - (b - w)/sqrt(1 - t), and b once the path's maximum reached b."""
    def score(p):
        with np.errstate(divide="ignore"):
            z = b - (b - p[:, 1]) / np.sqrt(np.maximum(1.0 - p[:, 0], 0.0))
        return np.where(p[:, 2] >= b, b, np.minimum(z, np.nextafter(b, -np.inf)))
    return score


def test_splitting_brownian_maximum_level_3():
    # P(sup W >= 3) = 2 (1 - Phi(3)) = 0.0026998; 10 replicates of 100 particles: the
    # replicates' standard error (about 7% here) must cover the truth at 3 se, and the
    # estimate is within 25% (loose: a fast check; the slow test reaches 10% at level 6)
    p = 2 * norm.sf(3)
    r = splitting(brownian_chain(0.02), committor_score(3.0), [0.0, 0.0, 0.0], 3.0, n=100,
                  replicates=10, seed=1)
    assert abs(r.p - p) <= 3 * r.std_error
    assert abs(r.p - p) <= 0.25 * p
    assert r.segments < 10**4 and r.relative_error < 0.15


@pytest.mark.slow
def test_splitting_brownian_maximum_level_6():
    # P(sup W >= 6) = 1.973e-9 (crude Monte Carlo: ~5e10 runs for 10%): to 10% with at most
    # 10^6 path segments
    p = 2 * norm.sf(6)
    r = splitting(brownian_chain(0.02), committor_score(6.0), [0.0, 0.0, 0.0], 6.0, n=2000,
                  replicates=4, seed=1)
    assert r.segments <= 10**6
    assert abs(r.p - p) <= 0.10 * p, (r.p, r.std_error)


def test_splitting_on_engine_runs():
    # the barrier 2 on [0, 1] as the engine's jump guard on an SDE flow (the Brownian-bridge
    # correction locates crossings between steps): score W, and the target once the run
    # jumped; P = 2 (1 - Phi(2)) = 0.0455, six replicates of 30 particles at 3 se
    from hybridsim.library import DriftedBrownian
    sim = hybrid_segments(DriftedBrownian(0.0, 1.0, 2.0), 1.0, j_max=1, method="EM",
                          max_step=0.05)
    r = splitting(sim, lambda p: np.where(p[:, 1] >= 1, 2.0, np.minimum(p[:, 2], 1.999999)),
                  [0.0, 0.0, 0.0], 2.0, n=30, replicates=6, seed=4)
    p = 2 * norm.sf(2.0)
    assert abs(r.p - p) <= 3 * r.std_error, (r.p, r.std_error, p)


def test_splitting_bad_input():
    sim = brownian_chain(0.1)
    with pytest.raises(ValueError, match="k must be less than n"):
        splitting(sim, committor_score(1.0), [0, 0, 0], 1.0, n=5, k=5)
    with pytest.raises(ValueError, match="target"):
        splitting(sim, committor_score(1.0), [0, 0, 0], math.inf)
    with pytest.raises(RuntimeError, match="max_segments"):
        splitting(sim, lambda p: p[:, 1], [0, 0, 0], 50.0, n=10, max_segments=50, seed=0)
