"""Tests of the observers' batch (vectorized) paths against their single-state paths.

Li & Sanfelice's H_n, H_c, H_pc and ``BoundedNoiseGenerator``, the distributed
observer's nodes and ``BandLimitedNoise`` take a batch of states (N, r) as
well as one state (r,); ``noise_batch`` wires them into an
``hs.Interconnection`` that ``hs.simulate_many`` integrates all rows at once.

Tolerances.

* Maps, batch against single state: the same formulas with the products
  taken in another order (``x @ A.T`` against ``A @ x``), so they agree to
  rounding: 1e-12 relative to the row's size (measured <= 3e-15, H_c's
  jump, which solves with H T - I, |(H T - I)^-1| ~ 150 on the random
  design, included).
  Sets and guards are the same comparisons and subtractions: exact.
* The distributed nodes' powers ``|C_o x_o - y|^γ`` (γ down to 0.5) and
  ``|s|^β`` are not Lipschitz at 0: on rows where the output error or the
  consensus term is 0 the ~1e-16 rounding of the two orders becomes ~1e-8
  (times the gains). Those rows get the bound :func:`_power_rounding_tol`.
* Integrations, batch integrator against a loop of ``hs.simulate`` (both
  RK45): a step's error estimate (~rtol |x|) is a difference of O(|x|)
  quantities, so the maps' ~1e-16 rounding changes it by ~1e-6 relative at
  rtol = 1e-10 and the step sizes by ~1e-7: the sample times drift apart (<= 3e-7 measured on
  H_c) although both runs are the same to rounding at equal times. The
  states are therefore compared at the same times (the jump at t = δ, t_max)
  and, elsewhere, after a first-order shift ``x + f(x) Δt`` to the other
  run's sample time (measured <= 5e-13 relative; tolerance 1e-10).
  With the distributed network's band-limited noise (a kink every ts) the
  runs' step sequences part (different sample counts) and they agree only
  to the integrator's error (NORM_RTOL, VECTOR_RTOL below).
"""
import functools

import numpy as np
import pytest

import hybridsim as hs
from observers import distributed as dist
from observers import li_sanfelice as ls
from observers.distributed.example import band_limited_noise, random_system
from observers.distributed.example import noise_batch as dist_noise_batch
from observers.distributed.systems import (
    BandLimitedNoise,
    _NodeData,
    initial_state,
    observer_network,
)
from observers.li_sanfelice.design import random_design
from observers.li_sanfelice.example import noise_batch as ls_noise_batch
from observers.li_sanfelice.systems import BoundedNoiseGenerator

EPS = np.finfo(float).eps
MAP_RTOL = 1e-12
OBSERVERS = [ls.NominalObserver, ls.ConstantNoiseObserver, ls.PiecewiseConstantNoiseObserver]


@functools.cache
def _ls_design(name):
    return random_design(0, 4, 2) if name == "random" else ls.example_VB()


def _assert_rows(batch, single, what, rtol=MAP_RTOL):
    """Batch result against the stacked single-state results, to rtol of the largest entry."""
    batch, single = np.asarray(batch, dtype=float), np.asarray(single, dtype=float)
    assert batch.shape == single.shape, what
    scale = max(1.0, float(np.abs(single).max()))
    np.testing.assert_allclose(batch, single, rtol=rtol, atol=rtol * scale, err_msg=what)


def _observer_rows(obs, N, rng, *, offset=0, width=None):
    """N random states of ``obs`` (inside a wider row of ``width`` at ``offset``):
    tau below, at and above delta, q = 0 and 1, so some rows are in D and some not."""
    width = obs.state_dim if width is None else width
    d = obs.design
    X = rng.normal(size=(N, width))
    X[:, offset + obs._tau] = d.delta + np.resize([-0.5, 0.0, 0.25, -1e-3, 1e-9], N)
    if obs._has_q:
        X[:, offset + obs._q] = np.resize([0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0], N)
    return X


# ---------------------------------------------------------------------------
# Li & Sanfelice: maps over batches
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("design_name", ["random", "VB"])
@pytest.mark.parametrize("cls", OBSERVERS)
def test_ls_observer_batch_maps_equal_single_maps(cls, design_name):
    """Each map of H_n, H_c, H_pc on a batch (N, r) equals the single-state map row by row.

    States are random with tau below, at and above δ and q = 0 or 1; the
    flow and jump maps agree to 1e-12 relative (rounding only), the sets,
    the guard and the output exactly (same comparisons and arithmetic).
    """
    d = _ls_design(design_name)
    obs = cls(d)
    assert obs.vectorized
    rng = np.random.default_rng(7)
    N = 9
    X = _observer_rows(obs, N, rng)
    T = rng.uniform(0.0, 3.0, N)
    J = rng.integers(0, 3, N)
    U = rng.normal(size=(N, d.p))
    for name in ("flow_map", "jump_map"):
        f = getattr(obs, name)
        _assert_rows(f(X, T, J, U), [f(X[i], T[i], J[i], U[i]) for i in range(N)], name)
    inD = obs.jump_set(X, T, J, U)
    assert inD.dtype == bool and inD.shape == (N,)
    np.testing.assert_array_equal(inD, [obs.jump_set(X[i], T[i], J[i], U[i]) for i in range(N)])
    assert inD.any() and not inD.all()           # the batch mixes rows in and out of D
    np.testing.assert_array_equal(obs.jump_guard(X, T, J, U),
                                  [obs.jump_guard(X[i], T[i], J[i], U[i]) for i in range(N)])
    np.testing.assert_array_equal(obs.output(X, T, J),
                                  [obs.output(X[i], T[i], J[i]) for i in range(N)])
    # the guard is >= 0 exactly on D
    np.testing.assert_array_equal(obs.jump_guard(X, T, J, U) >= 0, inD)


def test_bounded_noise_generator_batch_output_equals_single():
    """BoundedNoiseGenerator's output over a batch (each row its own t) equals the rows' outputs.

    sin of the same arguments summed over K terms: 1e-12 relative (rounding).
    """
    gen = BoundedNoiseGenerator(3, K=4)
    assert gen.vectorized
    N = 8
    W = gen.random_states(N, 0.3, seed=11)
    T = np.r_[0.0, np.random.default_rng(1).uniform(0.0, 10.0, N - 1)]
    J = np.zeros(N, dtype=int)
    B = gen.output(W, T, J)
    assert B.shape == (N, 3)
    _assert_rows(B, [gen.output(W[i], T[i], 0) for i in range(N)], "output")
    _assert_rows(B, [gen.callable(W[i])(T[i]) for i in range(N)], "callable")
    np.testing.assert_array_equal(gen.flow_map(W, T, J, None), np.zeros_like(W))
    # a bound the realisations respect (random_states scales them to m_max)
    assert np.all(np.abs(B) <= 0.3 + 1e-12)


@pytest.mark.parametrize("design_name", ["random", "VB"])
@pytest.mark.parametrize("cls", OBSERVERS)
def test_ls_interconnection_batch_maps_and_partial_jumps(cls, design_name):
    """noise_batch's interconnection noise -> (plant, observer) over a batch equals it row by row.

    Rows in and out of the observer's D are mixed: the batch jump map moves
    only the rows in D (to the single-state jump, 1e-12 relative) and leaves
    the others exactly as they were; flow map, sets and guard as in the
    observer test above.
    """
    d = _ls_design(design_name)
    obs = cls(d)
    gen = BoundedNoiseGenerator(d.p, K=2)
    S = gen.random_states(10, 0.3, seed=3)
    sysm, x0s = ls_noise_batch(obs, np.ones(d.n), np.zeros(d.n), S, gen)
    assert sysm.vectorized
    rng = np.random.default_rng(5)
    N = len(x0s)
    off = sysm.components["observer"].start
    X = _observer_rows(obs, N, rng, offset=off, width=sysm.state_dim)
    X[:, sysm.components["noise"]] = S                     # realisations of bounded noise
    T = rng.uniform(0.0, 2.0, N)
    J = rng.integers(0, 2, N)
    _assert_rows(sysm.flow_map(X, T, J), [sysm.flow_map(X[i], T[i], J[i]) for i in range(N)],
                 "flow_map")
    inD = sysm.jump_set(X, T, J)
    np.testing.assert_array_equal(inD, [sysm.jump_set(X[i], T[i], J[i]) for i in range(N)])
    assert inD.any() and not inD.all()
    np.testing.assert_array_equal(sysm.flow_set(X, T, J),
                                  [sysm.flow_set(X[i], T[i], J[i]) for i in range(N)])
    np.testing.assert_array_equal(sysm.jump_guard(X, T, J),
                                  [sysm.jump_guard(X[i], T[i], J[i]) for i in range(N)])
    G = sysm.jump_map(X, T, J)
    np.testing.assert_array_equal(G[~inD], X[~inD])        # rows not in D keep their state
    rows = np.flatnonzero(inD)
    _assert_rows(G[rows], [sysm.jump_map(X[i], T[i], J[i]) for i in rows], "jump_map")
    # the observer's input is y = H x + m over the batch too
    y = sysm.outputs(X, T, J)
    _assert_rows(y["noise"], [gen.output(X[i, sysm.components["noise"]], T[i], J[i])
                              for i in range(N)], "noise output")


# ---------------------------------------------------------------------------
# Li & Sanfelice: simulate_many on an H_c batch
# ---------------------------------------------------------------------------
HC_KW = dict(rtol=1e-10, atol=1e-12)


@functools.cache
def _hc_runs(design_name):
    """An H_c noise batch of 6 realisations: the batch integrator, a loop of
    simulate (RK45) and single DOP853 runs, all to t_max = 1.5 δ."""
    d = _ls_design(design_name)
    obs = ls.ConstantNoiseObserver(d)
    gen = BoundedNoiseGenerator(d.p, K=2)
    S = gen.random_states(6, 0.3, seed=4)
    x0 = np.random.default_rng(2).normal(size=d.n)
    sysm, x0s = ls_noise_batch(obs, x0, np.zeros(d.n), S, gen)
    t_max = 1.5 * d.delta
    arcs = hs.simulate_many(sysm, x0s, t_max=t_max, **HC_KW)
    loop = [hs.simulate(sysm, x, t_max=t_max, **HC_KW) for x in x0s]
    dop = [hs.simulate(sysm, x, t_max=t_max, method="DOP853", **HC_KW) for x in x0s]
    return d, obs, sysm, x0s, arcs, loop, dop


@pytest.mark.slow
@pytest.mark.parametrize("design_name", ["random", "VB"])
def test_hc_simulate_many_equals_simulate_loop(design_name):
    """simulate_many's batch integrator on H_c equals a loop of simulate (RK45) row by row.

    Same number of samples and jump at the same index; jump times within
    1e-12 (both locate tau = δ, linear in t: measured 4e-16); states equal at
    the common times (the pre- and post-jump samples, t_max) and, elsewhere,
    after shifting one run's sample by ``f(x) Δt`` to the other's time
    (module docstring): 1e-10 relative, measured <= 5e-13 (the pre-jump
    rounding times the reset's |T| |(H T - I)^-1|). The sample times
    themselves drift by <= 3e-7 (the step sizes' sensitivity to rounding),
    bounded here by 1e-5 t_max.
    """
    d, obs, sysm, x0s, arcs, loop, _ = _hc_runs(design_name)
    t_max = 1.5 * d.delta
    for a, b in zip(arcs, loop):
        assert a.termination == b.termination == hs.Termination.T_MAX
        assert len(a.t) == len(b.t)
        np.testing.assert_array_equal(a.j, b.j)
        np.testing.assert_array_equal(a.jump_index, b.jump_index)
        np.testing.assert_allclose(a.jump_times, b.jump_times, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.jump_times, [d.delta], rtol=0, atol=1e-12)
        assert np.abs(a.t - b.t).max() <= 1e-5 * t_max
        scale = max(1.0, float(np.abs(b.x).max()))
        k = b.jump_index[0]
        for i in (k - 1, k, -1):                         # pre-jump, post-jump, t_max
            np.testing.assert_allclose(a.x[i], b.x[i], rtol=0, atol=1e-10 * scale)
        shifted = b.x + sysm.flow_map(b.x, b.t, b.j) * (a.t - b.t)[:, None]
        np.testing.assert_allclose(a.x, shifted, rtol=0, atol=1e-10 * scale)


@pytest.mark.slow
@pytest.mark.parametrize("design_name", ["random", "VB"])
def test_hc_batch_error_after_jump_agrees_with_dop853(design_name):
    """H_c's error and m̂ after the jump: batch (RK45) against single DOP853 runs.

    Each integrator's pre-jump state is within a few rtol |x| of the exact
    one; the reset (18) multiplies such errors by up to |(H T - I)^-1|
    (``HT_inv_norm``: 145 on the random design, 25 on V.B) into m̂ and x̂.
    Tolerance 10 rtol HT_inv_norm max|x| (x the plant's and observer's
    states): measured |Δe|, |Δm̂| <= 2.6e-8 on the random design (tolerance
    >= 3.5e-7) and <= 1.7e-9 on V.B (tolerance >= 2.5e-8).
    """
    d, obs, sysm, x0s, arcs, _, dop = _hc_runs(design_name)
    for a, c in zip(arcs, dop):
        Ea, Ec = ls.errors(a, obs), ls.errors(c, obs)
        scale = max(1.0, float(np.abs(np.c_[Ec["x"], c.component("observer").x]).max()))
        tol = 10 * HC_KW["rtol"] * d.HT_inv_norm * scale
        ka, kc = a.jump_index[0], c.jump_index[0]
        assert a.t[ka] == pytest.approx(d.delta, abs=1e-12) and c.t[kc] == pytest.approx(
            d.delta, abs=1e-12)
        for key in ("e", "mhat"):
            np.testing.assert_allclose(Ea[key][ka], Ec[key][kc], rtol=0, atol=tol, err_msg=key)
            np.testing.assert_allclose(Ea[key][-1], Ec[key][-1], rtol=0, atol=tol, err_msg=key)
        # m̂ is constant after the jump (m̂' = 0) in both
        np.testing.assert_array_equal(Ea["mhat"][ka:], np.broadcast_to(Ea["mhat"][ka],
                                                                      Ea["mhat"][ka:].shape))


def test_simulate_many_dop853_on_vectorized_system_is_one_batch(monkeypatch):
    """A vectorized system with method="DOP853" runs as one batch of the batch
    integrator (no run of simulate), equal to single DOP853 runs: the jump at
    δ to 1e-12 (tau linear in t), and the states at the pre- and post-jump
    samples and at t_max to 1e-10 max|x| (rtol 1e-10; measured 2e-12
    relative on the error after the jump, bench_observers_scale.py). The
    sample times themselves drift by the step sizes' sensitivity to
    rounding (DOP853's error estimate at rtol 1e-10: measured 2.8e-6)."""
    d, obs, sysm, x0s, arcs, _, dop = _hc_runs("VB")
    assert sysm.vectorized
    import hybridsim.run
    calls = []
    real = hybridsim.run.simulate
    monkeypatch.setattr(hybridsim.run, "simulate",
                        lambda *a, **k: calls.append(1) or real(*a, **k))
    hs.simulate_many(sysm, x0s[:1], t_max=1.5 * d.delta, dense=True, **HC_KW)
    assert calls == [1]                 # (an option the batch lacks: a run of simulate)
    many = hs.simulate_many(sysm, x0s, t_max=1.5 * d.delta, method="DOP853", **HC_KW)
    assert calls == [1]
    for a, c in zip(many, dop):
        assert a.termination == c.termination == hs.Termination.T_MAX
        np.testing.assert_allclose(a.jump_times, [d.delta], rtol=0, atol=1e-12)
        scale = max(1.0, float(np.abs(c.x).max()))
        ka, kc = a.jump_index[0], c.jump_index[0]
        for i, k in ((ka - 1, kc - 1), (ka, kc), (-1, -1)):
            np.testing.assert_allclose(a.x[i], c.x[k], rtol=0, atol=1e-10 * scale)


# ---------------------------------------------------------------------------
# distributed: BandLimitedNoise, node right-hand sides, noise_batch
# ---------------------------------------------------------------------------
def test_band_limited_noise_generator_equals_callable():
    """BandLimitedNoise's output is band_limited_noise's interpolation for the same seed.

    The same samples (the realisation) and numpy.interp's formula
    ``slope (t - t_k) + w_k``: equal to 1e-15 relative (measured: bitwise),
    at 0, on the grid points and next to them, between them and beyond
    t_max (the last sample holds). Over a batch, w (N, state_dim) and t
    (N,), each row is its own realisation at its own t.
    """
    ts, t_max, dim, power = 0.1, 1.0, 3, 0.2
    gen = BandLimitedNoise(ts, t_max, dim)
    assert gen.vectorized and gen.output_dim == dim
    assert gen.state_dim == gen.grid.size * dim and gen.grid[-1] >= t_max
    grid = gen.grid
    tt = np.r_[0.0, grid, np.nextafter(grid, -1)[1:], np.nextafter(grid, 2),
               np.linspace(0.0, 1.7, 53), t_max, 1.15, 5.0, 100.0]
    seeds = [0, 5]
    for seed in seeds:
        w = gen.realisation(power, seed)
        m = band_limited_noise(power, ts, t_max, dim, seed)
        for t in tt:
            np.testing.assert_allclose(gen.output(w, t, 0), m(t), rtol=1e-15, atol=0,
                                       err_msg=f"t={t}")
        np.testing.assert_array_equal(gen.output(w, 50.0, 0), w.reshape(-1, dim)[-1])
    # a batch: each row its realisation at its own t
    N = len(tt)
    W = np.array([gen.realisation(power, s) for s in range(N)])
    B = gen.output(W, tt, np.zeros(N, dtype=int))
    assert B.shape == (N, dim)
    ref = np.array([band_limited_noise(power, ts, t_max, dim, s)(t)
                    for s, t in zip(range(N), tt)])
    np.testing.assert_allclose(B, ref, rtol=1e-15, atol=0)
    np.testing.assert_allclose(B, [gen.output(W[i], tt[i], 0) for i in range(N)], rtol=1e-15,
                               atol=0)
    np.testing.assert_array_equal(gen.flow_map(W, tt, 0, None), np.zeros_like(W))
    # the realisation's samples have variance power / ts
    big = BandLimitedNoise(ts, 400.0, 2).realisation(power, 1)
    assert np.var(big) == pytest.approx(power / ts, rel=0.1)


@functools.cache
def _dist_design(name, kind="finite-time"):
    if name == "example":
        A, C, G = dist.example_system()
        return dist.design(A, C, G, nodelist=[1, 2, 3, 4], kind=kind)
    if name == "ring":
        A, C, G = random_system(5, 3, graph="ring")
    else:                                                  # several in-neighbours per node
        A, C, G = random_system(6, 1, graph="random")
    return dist.design(A, C, G, kind=kind, warn=False)


def _power_rounding_tol(nd, M):
    """Bound on |rhs (batch) - rhs (row)| on a row where C_o x_o = y and the estimates agree.

    Both orders round C_o x_o - y and s (true value 0) by at most
    ``d = 4 (n + |𝒩| + 1) eps M`` (M bounds the terms summed); for 0 < γ <= 1,
    | |a|^γ sgn a - |b|^γ sgn b | <= 2^(1-γ) |a - b|^γ, times the gains
    |Θ diag(L)| (γ_k of (7)), 1 (β of (8)) and α.
    """
    d = 4 * (nd.n + len(nd.neighbours) + 1) * EPS * M
    tol = MAP_RTOL * M
    if nd.finite_time and nd.n_o:
        tol += np.abs(nd.Lt_o).sum(axis=1).max() * max(2 ** (1 - g) * d ** g for g in nd.gamma)
    if nd.n_u:
        tol += nd.alpha * d + (2 ** (1 - nd.beta) * d ** nd.beta if nd.finite_time else 0.0)
    return tol


@pytest.mark.parametrize("kind", ["finite-time", "linear"])
@pytest.mark.parametrize("name", ["example", "ring", "random"])
def test_node_rhs_batch_equals_rhs(name, kind):
    """_NodeData.rhs over a batch equals rhs row by row, for (7)-(8) and (4)-(5).

    Random rows: 1e-12 relative (rounding). Rows at zero output error and
    consensus term (every estimate agreeing), where the powers of (7)-(8)
    are not Lipschitz: :func:`_power_rounding_tol` (measured up to 1e-7 on
    the example's node 3, γ_5 = 0.5 and gains ~400).
    """
    dsg = _dist_design(name, kind)
    rng = np.random.default_rng(3)
    N = 7
    for k in range(dsg.N):
        nd = _NodeData(dsg, k)
        nb = len(nd.neighbours)
        z = rng.normal(size=(N, nd.n_o + nd.n_u))
        y = rng.normal(size=(N, nd.m))
        xnb = rng.normal(size=(N, nb, dsg.n))
        B = nd.rhs(z, y, xnb)
        assert B.shape == z.shape
        _assert_rows(B, [nd.rhs(z[i], y[i], xnb[i]) for i in range(N)], f"node {nd.node}")
        # rows at agreement: y = C_o x_o, every neighbour's estimate x̃ = T z
        y0 = z[:, :nd.n_o] @ nd.C_o[:1].T if nd.n_o else y
        x_agree = z @ nd.T.T
        xnb0 = np.repeat(x_agree[:, None, :], nb, axis=1)
        B0 = nd.rhs(z, y0, xnb0)
        S0 = np.array([nd.rhs(z[i], y0[i], xnb0[i]) for i in range(N)])
        M = max(1.0, float(np.abs(np.c_[z, y0, x_agree]).max())) * nd.n
        np.testing.assert_allclose(B0, S0, rtol=0, atol=_power_rounding_tol(nd, M),
                                   err_msg=f"node {nd.node} at agreement")


@pytest.mark.parametrize("name", ["example", "random"])
def test_network_with_generator_batch_flow_equals_single(name):
    """observer_network(dsg, noise=BandLimitedNoise) over a batch equals it row by row.

    The plant, the generator and every node take their slices of the rows
    (and the nodes the noisy outputs and neighbours' estimates): 1e-12
    relative on random states at random t in and beyond the noise's horizon.
    """
    dsg = _dist_design(name)
    p = sum(Ci.shape[0] for Ci in dsg.C)
    gen = BandLimitedNoise(0.1, 0.5, p)
    net = observer_network(dsg, noise=gen)
    assert net.vectorized and list(net.systems)[:2] == ["plant", "noise"]
    rng = np.random.default_rng(9)
    N = 6
    X = rng.normal(size=(N, net.state_dim))
    X[:, net.components["noise"]] = [gen.realisation(1e-2, s) for s in range(N)]
    T = np.r_[0.0, 0.5, rng.uniform(0.0, 0.8, N - 2)]
    J = np.zeros(N, dtype=int)
    _assert_rows(net.flow_map(X, T, J), [net.flow_map(X[i], T[i], 0) for i in range(N)],
                 "flow_map")
    np.testing.assert_array_equal(net.flow_map(X, T, J)[:, net.components["noise"]], 0.0)


DIST_KW = dict(rtol=1e-8, atol=1e-10)
DObs = dist.DistributedObserver          # the observer of a distributed design
DIST_POWER, DIST_T_MAX, DIST_SEEDS = 1e-3, 0.3, (0, 1, 2)


@functools.cache
def _dist_runs(name):
    """noise_batch's 3 realisations through simulate_many, a loop of simulate
    on the same system, and dist.simulate with the callable noise."""
    dsg = _dist_design(name)
    x0 = np.random.default_rng(1).normal(size=dsg.n)
    sysm, X = dist_noise_batch(DObs(dsg), x0, power=DIST_POWER, seeds=DIST_SEEDS, t_max=DIST_T_MAX)
    arcs = hs.simulate_many(sysm, X, t_max=DIST_T_MAX, **DIST_KW)
    loop = [hs.simulate(sysm, x, t_max=DIST_T_MAX, **DIST_KW) for x in X]
    refs = [dist.simulate(DObs(dsg), x0, noise=DIST_POWER, seed=s, t_max=DIST_T_MAX, **DIST_KW)
            for s in DIST_SEEDS]
    return dsg, x0, sysm, X, arcs, loop, refs


@pytest.mark.parametrize("name", ["example", "ring"])
def test_noise_batch_rows_are_the_realisations(name):
    """noise_batch's row r is initial_state(x0) with seed r's samples as the generator's state,
    which stays constant along the run (flow 0), so the noise the nodes see is
    band_limited_noise(power, ts, t_max, Σ m_i, seed) exactly."""
    dsg, x0, sysm, X, arcs, _, refs = _dist_runs(name)
    assert sysm.vectorized and X.shape == (len(DIST_SEEDS), sysm.state_dim)
    gen = sysm.systems["noise"]
    z0 = initial_state(dsg, x0)
    keep = np.delete(np.arange(sysm.state_dim), np.arange(sysm.state_dim)[
        sysm.components["noise"]])
    for row, s, arc in zip(X, DIST_SEEDS, arcs):
        np.testing.assert_array_equal(row[keep], z0)
        np.testing.assert_array_equal(row[sysm.components["noise"]],
                                      gen.realisation(DIST_POWER, s))
        assert arc.termination == hs.Termination.T_MAX and arc.tf == DIST_T_MAX
        W = arc["noise"].x
        np.testing.assert_array_equal(W, np.broadcast_to(W[0], W.shape))
        m = band_limited_noise(DIST_POWER, 0.1, DIST_T_MAX, gen.output_dim, s)
        np.testing.assert_allclose(gen.output(W, arc.t, arc.j), [m(t) for t in arc.t],
                                   rtol=1e-15, atol=0)
    # errors() leaves the generator's columns out
    assert dist.errors(arcs[0], DObs(dsg))["e"].shape == (len(arcs[0].t), dsg.N * dsg.n)
    assert dist.errors(refs[0], DObs(dsg))["e"].shape[1] == dsg.N * dsg.n


# Two RK45 runs of the noisy network whose step sequences differ (any two of
# the batch, the loop of simulate and dist.simulate: 81 to 89 samples for the
# same row) differ by the integrator's global error, not by rounding: the error
# control is local and the noise's slope jumps every ts. Measured at t_max =
# 0.3, rtol = 1e-8 on the example and on 5- and 6-node rings (3 to 10 seeds):
# the final error norms within 5.4e-7 relative, the final error vectors and
# states within 1.3e-6 of their largest entry, for every pair (at rtol =
# 1e-10: 3e-9 and 3e-8, so the spread scales with rtol). Tolerances ~10x:
NORM_RTOL = 5e-6      # final error norm, relative (~7e-6 was seen at t_max = 1, 8-node ring)
VECTOR_RTOL = 1e-5    # final error vector and state, relative to their largest entry


def _assert_final_errors_agree(a, b, dsg):
    obs = DObs(dsg)
    Ea, Eb = dist.errors(a, obs), dist.errors(b, obs)
    assert Ea["norm"][-1] == pytest.approx(Eb["norm"][-1], rel=NORM_RTOL)
    scale = float(np.abs(Eb["e"][-1]).max())
    np.testing.assert_allclose(Ea["e"][-1], Eb["e"][-1], rtol=0, atol=VECTOR_RTOL * scale)


@pytest.mark.parametrize("name", ["example", "ring"])
def test_noise_batch_final_errors_equal_simulate(name):
    """Final errors of the batch equal dist.simulate's (callable noise) with the same seeds.

    Both integrate the same flow to rtol = 1e-8; the batch's RMS error norm
    also counts the generator's constant states (most of the columns), so
    its steps differ and the results agree to the integrator's error
    (NORM_RTOL, VECTOR_RTOL above).
    """
    dsg, _, _, _, arcs, _, refs = _dist_runs(name)
    for a, r in zip(arcs, refs):
        assert a.tf == r.tf == DIST_T_MAX
        _assert_final_errors_agree(a, r, dsg)


@pytest.mark.parametrize("name", ["example", "ring"])
def test_noise_batch_simulate_many_equals_simulate_loop(name):
    """The batch integrator against a loop of simulate (RK45) on the same vectorized system.

    Same system and method, but the maps' and the integrators' rounding
    shift the step sizes (module docstring), the step sequences then part
    and the runs agree to the integrator's error, as against dist.simulate:
    not to ~1e-10 (measured up to 1.3e-6 relative in the final state).
    """
    dsg, _, _, _, arcs, loop, _ = _dist_runs(name)
    for a, b in zip(arcs, loop):
        assert a.termination == b.termination == hs.Termination.T_MAX
        _assert_final_errors_agree(a, b, dsg)
        scale = float(np.abs(b.xf).max())
        np.testing.assert_allclose(a.xf, b.xf, rtol=0, atol=VECTOR_RTOL * scale)


# ---------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------
def test_band_limited_noise_and_noise_batch_bad_input():
    """BandLimitedNoise, noise_batch and observer_network reject bad arguments by name."""
    for ts in (0.0, -0.1, np.inf, np.nan):
        with pytest.raises(ValueError, match="ts must be a positive finite float"):
            BandLimitedNoise(ts, 1.0, 2)
    for dim in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="dim must be a positive int"):
            BandLimitedNoise(0.1, 1.0, dim)
    with pytest.raises(ValueError, match="t_max must be a finite float >= 0"):
        BandLimitedNoise(0.1, -1.0, 2)
    gen = BandLimitedNoise(0.1, 1.0, 2)
    for power in (-1e-3, np.nan, np.inf):
        with pytest.raises(ValueError, match="power must be a finite float >= 0"):
            gen.realisation(power, 0)
    dsg = _dist_design("example")
    with pytest.raises(ValueError, match="seeds must name at least one realisation"):
        dist_noise_batch(DObs(dsg), np.zeros(6), power=1e-3, seeds=[], t_max=0.3)
    with pytest.raises(ValueError, match="power must be >= 0"):
        dist_noise_batch(DObs(dsg), np.zeros(6), power=-1e-3, seeds=[0], t_max=0.3)
    with pytest.raises(ValueError, match="ts must be a positive"):
        dist_noise_batch(DObs(dsg), np.zeros(6), power=1e-3, seeds=[0], t_max=0.3, noise_ts=0.0)
    for wrong in (BandLimitedNoise(0.1, 1.0, 3), BoundedNoiseGenerator(2)):
        with pytest.raises(ValueError, match=r"noise: the generator's output_dim must be .* = 4, "
                                             rf"got {wrong.output_dim}"):
            observer_network(dsg, noise=wrong)


def test_band_limited_noise_generator_before_the_grid_and_scalar_t_over_a_batch():
    """Before t = 0 the generator holds the first sample, as numpy.interp (and so the
    callable) does; a batch of realisations at one scalar t gives each row its value
    (what ``Interconnection.outputs(X)`` asks, t defaulting to 0.0)."""
    gen = BandLimitedNoise(0.1, 1.0, 2)
    W = np.array([gen.realisation(0.2, s) for s in range(3)])
    for s, w in enumerate(W):
        f = band_limited_noise(0.2, 0.1, 1.0, 2, seed=s)
        for t in (-1.0, -1e-300, 0.0):
            np.testing.assert_array_equal(gen.output(w, t, 0), f(t))
    Y = gen.output(W, 0.35, 0)
    assert Y.shape == (3, 2)
    for s, w in enumerate(W):
        np.testing.assert_array_equal(Y[s], gen.output(w, 0.35, 0))
    A, C, G = dist.example_system()
    sysm, X = dist_noise_batch(DObs(dist.design(A, C, G)), [1.0] * 6, power=1e-4, seeds=[0, 1],
                               t_max=0.5)
    assert sysm.outputs(X)["noise"].shape == (2, 4)
