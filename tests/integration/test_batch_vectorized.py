"""Tests of the vectorized batch integrator (hybridsim.batch_vectorized) and of
simulate_many over executors."""
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import hybridsim as hs
from hybridsim import Termination
from hybridsim.batch_vectorized import simulate_vectorized
from hybridsim.library import BouncingBall, bouncing_ball_jump_times

G, E = 9.81, 0.8


# ---------------------------------------------------------------- systems
class VBall(BouncingBall):         # the same ball over a batch (rows), picklable
    vectorized = True


Ball = BouncingBall                # the same ball, one state at a time


def ball_jump_times(h0, k, e=E):
    return bouncing_ball_jump_times(h0, k, G, e)


def vtimer(**kw):
    """x' = 1 on C = {x <= 1}, x+ = 0 on D = {x >= 1}, with guards."""
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
        jump_guard=lambda x: x[:, 0] - 1.0, flow_guard=lambda x: 1.0 - x[:, 0],
        state_dim=1, vectorized=True, **kw)


def timer():
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        jump_guard=lambda x: x[0] - 1.0, flow_guard=lambda x: 1.0 - x[0], state_dim=1)


def check_domain(arc):
    """t non-decreasing; j steps by one, at a repeated t."""
    assert np.all(np.diff(arc.t) >= 0)
    dj = np.diff(arc.j)
    assert set(np.unique(dj)) <= {0, 1}
    assert np.all(np.diff(arc.t)[dj == 1] == 0)


# ---------------------------------------------------------------- accuracy
def test_thousand_balls_jump_times_exact():
    rng = np.random.default_rng(12345)
    h0 = rng.uniform(0.5, 2.0, 1000)
    x0s = np.column_stack([h0, np.zeros_like(h0)])
    arcs = hs.simulate_many(VBall(), x0s, t_max=np.inf, j_max=10, rtol=1e-10, atol=1e-12)
    assert len(arcs) == 1000
    assert all(a.termination is Termination.J_MAX for a in arcs)
    assert all(a.jump_count == 10 for a in arcs)           # no missed jump
    jt = np.array([a.jump_times for a in arcs])
    assert jt.shape == (1000, 10)
    np.testing.assert_allclose(jt, ball_jump_times(h0, 10), rtol=0, atol=1e-9)
    for a in arcs[:20]:
        check_domain(a)
        np.testing.assert_array_equal(a.x[a.jump_index, 0], 0.0)
        np.testing.assert_allclose(a.x[0], [a.x[0, 0], 0.0])


def test_agrees_with_simulate_loop():
    x0s = np.array([[0.7, 0.0], [1.3, 0.5], [2.0, -1.0]])
    kw = dict(t_max=np.inf, j_max=5, rtol=1e-10, atol=1e-12)
    arcs = simulate_vectorized(VBall(), x0s, **kw)
    for x0, arc in zip(x0s, arcs):
        ref = hs.simulate(Ball(), x0, **kw)
        assert arc.termination is ref.termination
        assert arc.jump_count == ref.jump_count == 5
        assert len(arc) == len(ref)                 # the same steps and events
        np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-12)
        np.testing.assert_allclose(arc.t, ref.t, rtol=0, atol=1e-12)
        np.testing.assert_allclose(arc.x, ref.x, rtol=0, atol=1e-10)
    # default tolerances, a t_max inside a flow, dense samples: the same steps
    kw = dict(t_max=2.0, refine=4)
    arcs = simulate_vectorized(VBall(), x0s, **kw)
    for x0, arc in zip(x0s, arcs):
        ref = hs.simulate(Ball(), x0, **kw)
        assert arc.termination is ref.termination is Termination.T_MAX
        assert arc.jump_count == ref.jump_count
        assert arc.tf == ref.tf == 2.0
        assert len(arc) == len(ref)
        np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-9)
        np.testing.assert_allclose(arc.x, ref.x, rtol=0, atol=1e-9)


def test_agrees_with_simulate_on_a_nonlinear_flow():
    """Van der Pol with resets: rejected steps, vector guards, both priorities."""
    mu = 3.0

    def f(x):
        return np.stack([x[:, 1], mu * (1 - x[:, 0] ** 2) * x[:, 1] - x[:, 0]], axis=1)

    vdp = hs.HybridSystem.from_functions(
        flow_map=f, jump_map=lambda x: np.stack([x[:, 0], -0.5 * x[:, 1]], axis=1),
        jump_set=lambda x: (x[:, 0] >= 1.5) & (x[:, 1] > 0),
        jump_guard=lambda x: np.stack([x[:, 0] - 1.5, x[:, 1]], axis=1),
        state_dim=2, vectorized=True)
    scalar = hs.HybridSystem.from_functions(
        flow_map=lambda x: f(x[None])[0], jump_map=lambda x: np.array([x[0], -0.5 * x[1]]),
        jump_set=lambda x: x[0] >= 1.5 and x[1] > 0,
        jump_guard=lambda x: np.array([x[0] - 1.5, x[1]]), state_dim=2)
    x0s = np.random.default_rng(3).uniform(-2, 2, (3, 2))
    for kw in (dict(t_max=10.0), dict(t_max=10.0, priority="flows")):
        arcs = simulate_vectorized(vdp, x0s, **kw)
        for x0, arc in zip(x0s, arcs):
            ref = hs.simulate(scalar, x0, **kw)
            assert arc.termination is ref.termination
            assert len(arc) == len(ref) and arc.jump_count == ref.jump_count
            # step sizes agree to rounding of the error estimate (relative ~1e-10)
            np.testing.assert_allclose(arc.t, ref.t, rtol=0, atol=1e-9)
            np.testing.assert_allclose(arc.x, ref.x, rtol=0, atol=1e-8)
            np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-12)
    assert sum(a.jump_count for a in simulate_vectorized(vdp, x0s, t_max=10.0)) > 0


def test_timer_jumps_at_exact_multiples():
    x0s = np.array([[0.0], [0.25], [1.0]])
    arcs = simulate_vectorized(vtimer(), x0s, t_max=10.5)
    starts = [0.0, 0.25, 1.0]
    for s, arc in zip(starts, arcs):
        expect = np.arange(1.0, 12.0) - s
        expect = expect[(expect >= 0) & (expect <= 10.5)]
        np.testing.assert_allclose(arc.jump_times, expect, rtol=0, atol=1e-12)
        assert arc.termination is Termination.T_MAX
        assert arc.t[-1] == 10.5 and arc.j[-1] == len(expect)
        check_domain(arc)
        ref = hs.simulate(timer(), [s], t_max=10.5)
        np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-12)


def test_maps_with_t_and_j_and_multi_guards():
    # x' = 1 + j, jump when x >= 1 (guard of two columns: the min decides)
    sysv = hs.HybridSystem.from_functions(
        flow_map=lambda x, t, j: np.ones_like(x) * (1 + j)[:, None],
        jump_map=lambda x, t, j: np.zeros_like(x),
        jump_guard=lambda x: np.column_stack([x[:, 0] - 1.0, np.full(len(x), 5.0)]),
        flow_guard=lambda x: 1.0 - x[:, 0], state_dim=1, vectorized=True)
    arc, = simulate_vectorized(sysv, [[0.0]], t_max=np.inf, j_max=3)
    np.testing.assert_allclose(arc.jump_times, [1.0, 1.5, 1.5 + 1 / 3], atol=1e-12)


def test_j_max_and_zero_jumps():
    arcs = simulate_vectorized(vtimer(), [[0.0], [1.0]], t_max=np.inf, j_max=0)
    assert [a.termination for a in arcs] == [Termination.J_MAX, Termination.J_MAX]
    assert len(arcs[1]) == 1 and arcs[0].jump_count == 0
    np.testing.assert_allclose(arcs[0].tf, 1.0, atol=1e-12)


# ---------------------------------------------------------------- semantics
def overlap():
    """C = {x <= 2}, D = {x >= 1}: C ∩ D = [1, 2]."""
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
        flow_set=lambda x: x[:, 0] <= 2.0, jump_set=lambda x: x[:, 0] >= 1.0,
        state_dim=1, vectorized=True)


def test_priority_flows_on_overlap():
    arcs = simulate_vectorized(overlap(), [[0.0], [1.5]], t_max=7.0, priority="flows")
    np.testing.assert_allclose(arcs[0].jump_times, [2.0, 4.0, 6.0], atol=1e-12)
    np.testing.assert_allclose(arcs[1].jump_times, [0.5, 2.5, 4.5, 6.5], atol=1e-12)
    arcs = simulate_vectorized(overlap(), [[0.0], [1.5]], t_max=3.5, priority="jumps")
    np.testing.assert_allclose(arcs[0].jump_times, [1.0, 2.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(arcs[1].jump_times, [0.0, 1.0, 2.0, 3.0], atol=1e-12)


def test_priority_random_is_seeded():
    kw = dict(t_max=10.0, priority="random", seed=7)
    a1 = simulate_vectorized(overlap(), np.zeros((8, 1)), **kw)
    a2 = simulate_vectorized(overlap(), np.zeros((8, 1)), **kw)
    for p, q in zip(a1, a2):
        np.testing.assert_array_equal(p.t, q.t)
        assert p.termination is Termination.T_MAX
        # a jump only from C ∩ D: from x in [1, 2]
        pre = p.x[p.jump_index - 1, 0]
        assert np.all((pre >= 1 - 1e-12) & (pre <= 2 + 1e-12))
    # the coin does something: not every trajectory jumps at x = 1
    assert any(np.any(p.x[p.jump_index - 1, 0] > 1.5) for p in a1)


def test_leaving_C_union_D():
    leave = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), flow_set=lambda x: x[:, 0] <= 1.0, state_dim=1,
        vectorized=True)
    arcs = simulate_vectorized(leave, [[0.0], [0.5], [2.0]], t_max=7.0)
    assert arcs[0].termination is Termination.LEFT_SETS
    assert abs(arcs[0].tf - 1.0) <= 8 * np.finfo(float).eps
    assert abs(arcs[1].tf - 0.5) <= 8 * np.finfo(float).eps
    assert "left C" in arcs[0].message
    assert arcs[2].termination is Termination.NOT_IN_SETS and len(arcs[2]) == 1


def test_zeno():
    zeno = hs.HybridSystem.from_functions(
        flow_map=lambda x: -np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
        flow_set=lambda x: x[:, 0] >= 0, jump_set=lambda x: x[:, 0] <= 0, state_dim=1,
        vectorized=True)
    ref = hs.HybridSystem.from_functions(
        flow_map=lambda x: -np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
        flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0, state_dim=1)
    arcs = simulate_vectorized(zeno, [[1.0], [0.0]], t_max=5.0, zeno_jumps=20)
    for arc, t in zip(arcs, [1.0, 0.0]):
        assert arc.termination is Termination.ZENO
        assert abs(arc.tf - t) < 1e-12
        # jumps at one instant from C ∩ D: a jump loop (rules.is_jump_loop), as simulate says
        assert "jump loop" in arc.message
        assert arc.message == hs.simulate(ref, [t], t_max=5.0, zeno_jumps=20,
                                          warn=False).message
    # a Zeno ball (accumulating bounces) stops near its Zeno time, as simulate does
    x0s = np.array([[1.0, 0.0]])
    arc, = simulate_vectorized(VBall(restitution=0.5), x0s, t_max=10.0)
    t_zeno = np.sqrt(2 / G) * (1 + 2 * 0.5 / (1 - 0.5))
    assert arc.termination is Termination.ZENO
    assert abs(arc.tf - t_zeno) < 1e-6


def test_reentry_into_D_within_one_step_after_a_jump():
    """C is everything: the only event is D's entry, and each flow starts on
    the guard's zero and comes back within one (large) step."""
    class NoC(VBall):
        flow_set = hs.HybridSystem.flow_set
        flow_guard = None
    h0 = np.array([1.0, 1.5])
    for e in (0.05, 0.3):
        arcs = simulate_vectorized(NoC(G, e), np.column_stack([h0, 0 * h0]), t_max=np.inf,
                                   j_max=6, rtol=1e-10, atol=1e-12)
        jt = np.array([a.jump_times for a in arcs])
        np.testing.assert_allclose(jt, ball_jump_times(h0, 6, e), rtol=0, atol=1e-9)


def test_max_norm_and_t0_j0():
    grow = hs.HybridSystem.from_functions(flow_map=lambda x: x, state_dim=1, vectorized=True)
    arcs = simulate_vectorized(grow, [[1.0], [-2.0]], t_max=30.0, max_norm=1e3)
    assert all(a.termination is Termination.BLOWUP for a in arcs)
    arcs = simulate_vectorized(vtimer(), [[0.0]], t_max=3.5, t0=1.0, j0=4)
    assert arcs[0].t[0] == 1.0 and arcs[0].j[0] == 4
    np.testing.assert_allclose(arcs[0].jump_times, [2.0, 3.0], atol=1e-12)


def test_non_finite_solver_failure_and_bad_jump_values():
    def vec(**kw):
        return hs.HybridSystem.from_functions(state_dim=1, vectorized=True, **kw)
    # an overflowing step is accepted (scale inf) and ends NON_FINITE
    over = vec(flow_map=lambda x: np.full_like(x, 1e308))
    arcs = simulate_vectorized(over, [[1.7e308], [0.0]], t_max=10.0, first_step=1.0)
    assert [a.termination for a in arcs] == [Termination.NON_FINITE] * 2
    assert arcs[1].tf == 1.0 and np.isfinite(arcs[1].x).all()
    # a NaN flow is rejected down to the smallest step: NON_FINITE naming flow_map;
    # a finite escape likewise, but with finite stages: SOLVER_FAILED
    nan = vec(flow_map=lambda x: np.where(x < 1, 1.0, np.nan))
    escape = vec(flow_map=lambda x: x ** 2)
    for sysv, cause in ((nan, Termination.NON_FINITE), (escape, Termination.SOLVER_FAILED)):
        arc, = simulate_vectorized(sysv, [[0.0 if sysv is nan else 1.0]], t_max=3.0)
        assert arc.termination is cause
        assert abs(arc.tf - 1.0) < 1e-5
        if sysv is nan:
            assert "flow_map returned non-finite values near t=1 (j=0)" in arc.message
    # a jump map returning inf: MAP_ERROR naming it, the run kept so far
    bad = vec(flow_map=lambda x: np.ones_like(x), jump_map=lambda x: np.full_like(x, np.inf),
              jump_set=lambda x: x[:, 0] >= 1.0)
    arc, = simulate_vectorized(bad, [[0.0]], t_max=3.0)
    assert arc.termination is Termination.MAP_ERROR
    assert "jump_map returned non-finite values" in arc.message
    assert abs(arc.tf - 1.0) < 1e-12
    # the same causes and samples as simulate
    refs = {
        "over": hs.HybridSystem.from_functions(flow_map=lambda x: np.array([1e308]), state_dim=1),
        "nan": hs.HybridSystem.from_functions(flow_map=lambda x: np.where(x < 1, 1.0, np.nan),
                                              state_dim=1),
        "escape": hs.HybridSystem.from_functions(flow_map=lambda x: x ** 2, state_dim=1),
        "bad": hs.HybridSystem.from_functions(flow_map=lambda x: np.ones(1),
                                              jump_map=lambda x: np.full(1, np.inf),
                                              jump_set=lambda x: x[0] >= 1.0, state_dim=1)}
    for name, sysv, x0, kw in (("over", over, 1.7e308, dict(t_max=10.0, first_step=1.0)),
                               ("nan", nan, 0.0, dict(t_max=3.0)),
                               ("escape", escape, 1.0, dict(t_max=3.0)),
                               ("bad", bad, 0.0, dict(t_max=3.0))):
        with np.errstate(over="ignore", invalid="ignore"):
            ref = hs.simulate(refs[name], [x0], throw=False, warn=False, **kw)
        got, = simulate_vectorized(sysv, [[x0]], **kw)
        assert got.termination is ref.termination, name
        assert len(got) == len(ref), name
        if name != "bad":        # the same sentence (times printed alike)
            assert got.message == ref.message, name


def test_map_error_stops_only_the_failing_row():
    def f(x):
        if np.any((x[:, 0] > 0.5) & (x[:, 0] < 0.6)):
            raise RuntimeError("boom")
        return np.ones_like(x)
    sysv = hs.HybridSystem.from_functions(
        flow_map=f, jump_map=lambda x: np.zeros_like(x), jump_guard=lambda x: x[:, 0] - 1.0,
        flow_guard=lambda x: 1.0 - x[:, 0], state_dim=1, vectorized=True)
    arcs = simulate_vectorized(sysv, [[0.0], [0.7], [0.8]], t_max=0.55, max_step=0.01)
    assert arcs[0].termination is Termination.MAP_ERROR
    assert isinstance(arcs[0].exception, RuntimeError) and "boom" in arcs[0].message
    assert [a.termination for a in arcs[1:]] == [Termination.T_MAX] * 2
    assert isinstance(arcs[0].exception, hs.MapError)           # naming the map, t and j
    assert "flow_map raised RuntimeError: boom (at t=" in arcs[0].message
    # throw=True: the batch policy (every row runs, then the first failed row raises)
    with pytest.raises(hs.BatchError, match="row 0 of the batch failed: MAP_ERROR: .*boom") \
            as info:
        simulate_vectorized(sysv, [[0.0], [0.7]], t_max=0.55, max_step=0.01, throw=True)
    assert info.value.row == 0 and len(info.value.arcs) == 2
    assert info.value.arcs[1].termination is Termination.T_MAX


def test_simulate_many_dispatches_to_vectorized():
    x0s = np.array([[1.0, 0.0], [1.5, 0.0]])
    a = hs.simulate_many(VBall(), x0s, t_max=3.0, j_max=4)
    b = simulate_vectorized(VBall(), x0s, t_max=3.0, j_max=4)
    for p, q in zip(a, b):
        np.testing.assert_array_equal(p.t, q.t)
        np.testing.assert_array_equal(p.x, q.x)


# ---------------------------------------------------------------- bad input
def test_bad_x0s():
    with pytest.raises(ValueError, match=r"x0s must have shape \(N, 2\), got \(2,\)"):
        simulate_vectorized(VBall(), [1.0, 0.0], t_max=1.0)
    with pytest.raises(ValueError, match=r"x0s must have shape \(N, 2\), got \(1, 3\)"):
        simulate_vectorized(VBall(), [[1.0, 0.0, 0.0]], t_max=1.0)
    with pytest.raises(ValueError, match="x0s must be finite; rows \\[1\\]"):
        simulate_vectorized(VBall(), [[1.0, 0.0], [np.nan, 0.0]], t_max=1.0)
    with pytest.raises(ValueError, match=r"x0s must have shape \(N, 2\)"):
        hs.simulate_many(VBall(), [[1.0]], t_max=1.0)


def test_bad_options():
    x0s = [[1.0, 0.0]]
    with pytest.raises(TypeError, match="unexpected keyword argument 'rtoll'"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, rtoll=1e-3)
    with pytest.raises(ValueError, match="method='Radau' is not supported on the vectorized "
                                         "path"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, method="Radau")
    with pytest.raises(ValueError, match="priority must be one of"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, priority="both")
    with pytest.raises(ValueError, match="inputs=.* is not supported on the vectorized path"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, inputs=lambda t: 0.0)
    with pytest.raises(ValueError, match="refine must be >= 1, got 0"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, refine=0)
    with pytest.raises(ValueError, match="rtol must be > 0"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, rtol=0.0)
    with pytest.raises(ValueError, match="t_max must be >= t0"):
        simulate_vectorized(VBall(), x0s, t_max=-1.0)
    with pytest.raises(ValueError, match="vectorized = True"):
        simulate_vectorized(Ball(), x0s, t_max=1.0)
    with pytest.raises(TypeError, match="system must be a hybridsim.HybridSystem"):
        simulate_vectorized(object(), x0s, t_max=1.0)


def test_maps_returning_wrong_shapes():
    x0s = [[0.0], [0.5]]

    def make(**kw):
        base = dict(flow_map=lambda x: np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
                    flow_set=lambda x: x[:, 0] <= 1.0, jump_set=lambda x: x[:, 0] >= 1.0)
        base.update(kw)
        return hs.HybridSystem.from_functions(state_dim=1, vectorized=True, **base)

    with pytest.raises(hs.MapError, match=r"flow_map must return an array of shape \(2, 1\)"
                                          r".*got shape \(1,\)"):
        simulate_vectorized(make(flow_map=lambda x: np.ones(1)), x0s, t_max=1.0)
    with pytest.raises(hs.MapError, match=r"jump_map must return an array of shape \(1, 1\)"
                                          r".*got shape \(\)"):
        simulate_vectorized(make(jump_map=lambda x: 0.0), [[1.0]], t_max=1.0)
    with pytest.raises(hs.MapError, match=r"flow_set must return a boolean array of shape "
                                          r"\(2,\).*got shape \(\)"):
        simulate_vectorized(make(flow_set=lambda x: True), x0s, t_max=1.0)
    with pytest.raises(hs.MapError, match=r"jump_set must return a boolean array of shape "
                                          r"\(2,\).*got shape \(2, 1\)"):
        simulate_vectorized(make(jump_set=lambda x: x >= 1.0), x0s, t_max=1.0)
    with pytest.raises(hs.MapError, match=r"jump_guard must return an array of shape \(2,\) "
                                          r"or \(2, m\)"):
        simulate_vectorized(make(jump_guard=lambda x: np.zeros(3)), x0s, t_max=1.0)


# ---------------------------------------------------------------- executors
def _same(arcs, refs):
    assert len(arcs) == len(refs)
    for a, r in zip(arcs, refs):
        assert a.termination is r.termination
        np.testing.assert_array_equal(a.t, r.t)
        np.testing.assert_array_equal(a.j, r.j)
        np.testing.assert_array_equal(a.x, r.x)


def test_simulate_many_process_pool():
    x0s = np.column_stack([np.linspace(0.5, 2.0, 6), np.zeros(6)])
    kw = dict(t_max=5.0, j_max=6, rtol=1e-8, atol=1e-10)
    refs = [hs.simulate(Ball(), x0, **kw) for x0 in x0s]
    with ProcessPoolExecutor(2) as ex:
        arcs = hs.simulate_many(Ball(), x0s, executor=ex, **kw)
    _same(arcs, refs)
    # a system simulated once (maps compiled, history bound) ships too
    sysobj = Ball()
    refs = [hs.simulate(sysobj, x0, **kw) for x0 in x0s]
    with ProcessPoolExecutor(2) as ex:
        arcs = hs.simulate_many(sysobj, x0s, executor=ex, **kw)
    _same(arcs, refs)


@pytest.mark.slow      # starts a dask LocalCluster (~8 s)
def test_simulate_many_dask_local_cluster():
    distributed = pytest.importorskip("dask.distributed")
    x0s = np.column_stack([np.linspace(0.5, 2.0, 4), np.zeros(4)])
    kw = dict(t_max=5.0, j_max=6)
    refs = [hs.simulate(Ball(), x0, **kw) for x0 in x0s]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        arcs = hs.simulate_many(Ball(), x0s, executor=client.get_executor(), **kw)
    _same(arcs, refs)


def test_progress_bar_over_trajectories(capsys):
    timer = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
        jump_guard=lambda x: x[:, 0] - 1.0, flow_guard=lambda x: 1.0 - x[:, 0],
        state_dim=1, vectorized=True)
    quiet = simulate_vectorized(timer, [[0.0], [0.5]], t_max=2.2)
    assert capsys.readouterr().err == ""
    arcs = hs.simulate_many(timer, [[0.0], [0.5]], t_max=2.2, progress=True)
    assert "simulate_vectorized" in capsys.readouterr().err
    for a, b in zip(arcs, quiet, strict=True):      # the bar changes nothing
        np.testing.assert_array_equal(a.t, b.t)
    with pytest.raises(TypeError, match="progress must be True or False or None"):
        simulate_vectorized(timer, [[0.0]], t_max=1.0, progress="on")


# ---------------------------------------------------------------- issue 22: one engine
def test_event_outcome_and_after_jump_come_from_the_rules():
    from hybridsim import rules
    from hybridsim.batch_vectorized import _after_jump_table, _outcome_table
    for prio in rules.Priority:
        action, side = _outcome_table(prio)
        for code in range(32):
            b = [bool(code >> k & 1) for k in (4, 3, 2, 1, 0)]
            assert (action[code], side[code]) == rules.event_outcome(*b[:4], prio, b[4])
    table = _after_jump_table()
    for jumps, short in ((3, 0), (5, 0), (5, 9), (2, 9), (2, 1)):
        full, zeno = jumps >= 5, short >= 9
        assert table[int(full), int(zeno)] == rules.after_jump(jumps, short, 5, 9)


def test_coin_drawn_only_where_the_rules_need_it():
    """A timer's events leave C as they enter D: no coin anywhere (the old
    code drew one per D entry)."""
    rng = np.random.default_rng(3)
    open_timer = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
        flow_set=lambda x: x[:, 0] < 1.0, jump_set=lambda x: x[:, 0] >= 1.0, state_dim=1,
        vectorized=True)
    arcs = simulate_vectorized(open_timer, np.zeros((5, 1)), t_max=4.5, priority="random",
                               seed=rng)
    assert all(a.jump_count == 4 for a in arcs)
    assert rng.random() == np.random.default_rng(3).random()      # untouched


def test_event_tolerance_over_arrays_is_the_rule():
    from hybridsim._batch_events import _tol
    from hybridsim.rules import event_tolerance
    v = np.r_[0.0, 1e-300, 0.5, 1.0, 1.5, -3.0, 1e6, 2.0 ** 52, np.random.default_rng(1)
              .uniform(-1e4, 1e4, 50)]
    for a in v[:12]:
        got = _tol(np.full(v.size, a), v)
        assert got.tolist() == [event_tolerance(a, b) for b in v]


def _count_locator(monkeypatch):
    """Count state probes of each path's event locator (pred and phi calls, per row)."""
    import hybridsim.batch_vectorized as bv
    import hybridsim.solve as solve
    counts = {"py": 0, "py_events": 0, "vec": 0, "vec_events": 0}
    orig = solve.locate_event

    def locate(sol, a, b, pred, phi=None, **kw):
        counts["py_events"] += 1

        def p(s, y):
            counts["py"] += 1
            return pred(s, y)
        return orig(sol, a, b, p, phi, **kw)
    monkeypatch.setattr(solve, "locate_event", locate)
    run_cls = bv._BatchRun
    orig_loc, orig_pred = run_cls._locate, run_cls._pred
    inside = [False]

    def vloc(self, rows, *args, **kw):
        counts["vec_events"] += len(rows)
        inside[0] = True
        try:
            return orig_loc(self, rows, *args, **kw)
        finally:
            inside[0] = False

    def vpred(self, rows, *args):
        if inside[0]:
            counts["vec"] += len(rows)
        return orig_pred(self, rows, *args)
    monkeypatch.setattr(run_cls, "_locate", vloc)
    monkeypatch.setattr(run_cls, "_pred", vpred)
    return counts


def test_one_event_locator_jump_times_and_evaluations(monkeypatch):
    counts = _count_locator(monkeypatch)
    x0s = np.array([[0.7, 0.0], [1.3, 0.5], [2.0, -1.0], [1.0, 3.0]])
    kw = dict(t_max=np.inf, j_max=8, rtol=1e-10, atol=1e-12)
    arcs = simulate_vectorized(VBall(), x0s, **kw)
    refs = [hs.simulate(Ball(), x0, **kw) for x0 in x0s]
    for arc, ref in zip(arcs, refs):
        assert arc.jump_count == ref.jump_count == 8
        np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-12)
    # the same algorithm: the same number of indicator probes per event (to a
    # probe or two where rounding of the batched interpolant moves a bisection)
    assert counts["vec_events"] == counts["py_events"] == 32
    assert abs(counts["vec"] - counts["py"]) <= 2 * counts["py_events"], counts
    assert counts["vec"] <= 20 * counts["vec_events"]       # a handful per event
    # a timer (guards, jumps at exact multiples)
    for k in counts:
        counts[k] = 0
    arcs = simulate_vectorized(vtimer(), [[0.0], [0.3], [0.9]], t_max=6.5)
    for s, arc in zip([0.0, 0.3, 0.9], arcs):
        ref = hs.simulate(timer(), [s], t_max=6.5)
        assert arc.jump_count == ref.jump_count
        np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-12)
    assert counts["vec_events"] == counts["py_events"]
    assert abs(counts["vec"] - counts["py"]) <= 2 * counts["py_events"], counts


BAD_OPTIONS = [dict(zeno_jumps=0), dict(zeno_jumps=2.5), dict(refine=True), dict(refine=0),
               dict(rtol=-1.0), dict(rtol="1"), dict(t_max=np.nan), dict(j_max=-1),
               dict(max_steps=0), dict(max_samples=1), dict(seed=-1), dict(seed="a"),
               dict(priority="both"), dict(method="foo"), dict(throw="yes"), dict(warn=1),
               dict(atol=[1.0, 2.0, 3.0]), dict(t0=2.0, t_max=1.0), dict(j0=-1),
               dict(max_norm=0.0), dict(first_step=-1.0), dict(zeno_rtol=-1.0)]


@pytest.mark.parametrize("bad", BAD_OPTIONS, ids=lambda d: ",".join(map(str, d.items())))
def test_bad_options_same_error_as_simulate(bad):
    kw = dict(t_max=1.0)
    kw.update(bad)
    with pytest.raises((TypeError, ValueError)) as ref:
        hs.simulate(Ball(), [1.0, 0.0], **kw)
    with pytest.raises((TypeError, ValueError)) as got:
        simulate_vectorized(VBall(), [[1.0, 0.0]], **kw)
    assert type(got.value) is type(ref.value)
    assert str(got.value) == str(ref.value)


def test_unsupported_options_refused_by_the_one_rule():
    for name, val in (("dense", True), ("t_eval", [0.5]), ("prehistory", lambda s: 0)):
        with pytest.raises(ValueError, match=f"{name}=.* is not supported on the vectorized "
                                             "path; use hs.simulate"):
            simulate_vectorized(VBall(), [[1.0, 0.0]], t_max=1.0, **{name: val})
    from hybridsim.batch_vectorized import takes_options
    assert takes_options(dict(rtol=1e-8, dense=False, t_eval=None, max_samples=100))
    assert not takes_options(dict(dense=True))
    assert not takes_options(dict(t_eval=[0.5]))
    assert not takes_options(dict(method="Radau"))
    assert takes_options(dict(method="DOP853"))
    assert not takes_options(dict(backend="python"))


def _fragile():
    """A timer whose flow map raises on rows that reach x > 1.5 (row-wise)."""
    def f(x):
        if np.any(x[:, 0] > 1.5):
            raise ZeroDivisionError("too far")
        return np.ones_like(x)
    return hs.HybridSystem.from_functions(flow_map=f, state_dim=1, vectorized=True)


def test_throw_and_warn_are_the_batch_policy():
    x0s = [[0.0], [1.0], [0.2], [1.2]]
    import warnings
    for run in (simulate_vectorized, hs.simulate_many):
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            arcs = run(_fragile(), x0s, t_max=1.0)
        assert [a.termination for a in arcs] == [Termination.T_MAX, Termination.MAP_ERROR,
                                                 Termination.T_MAX, Termination.MAP_ERROR]
        (warning,) = w
        assert issubclass(warning.category, hs.BatchWarning)
        assert warning.filename == __file__            # points at the caller
        assert "2 of 4 runs failed: row 1: MAP_ERROR" in str(warning.message)
        assert "row 3: MAP_ERROR" in str(warning.message)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            run(_fragile(), x0s, t_max=1.0, warn=False)
        with pytest.raises(hs.BatchError, match="row 1 of the batch failed: MAP_ERROR") as info:
            run(_fragile(), x0s, t_max=1.0, throw=True)
        assert info.value.row == 1 and info.value.arc is info.value.arcs[1]
        assert [a.termination for a in info.value.arcs] == [a.termination for a in arcs]


def test_arcs_have_xdot_and_stats_as_simulate():
    x0s = np.array([[1.0, 0.0], [1.7, 0.4]])
    kw = dict(t_max=3.0, j_max=5, rtol=1e-10, atol=1e-12)
    arcs = simulate_vectorized(VBall(), x0s, **kw)
    for x0, arc in zip(x0s, arcs):
        ref = hs.simulate(Ball(), x0, **kw)
        assert arc.xdot is not None and arc.xdot.shape == arc.x.shape
        assert len(arc) == len(ref)
        np.testing.assert_array_equal(np.isnan(arc.xdot), np.isnan(ref.xdot))
        np.testing.assert_allclose(arc.xdot, ref.xdot, rtol=0, atol=1e-9)
        assert set(arc.stats) == set(ref.stats)
        for key in ("steps", "rejected", "nfev", "njev", "nlu", "events", "flows"):
            assert arc.stats[key] == ref.stats[key], key
        # arc.at uses xdot (no fallback): the same values as simulate's arc
        mid = (np.diff(arc.j) == 0) & (np.diff(arc.t) > 0)
        ts = 0.5 * (arc.t[:-1] + arc.t[1:])[mid]          # inside flows, off the jumps
        np.testing.assert_allclose(arc.at(ts), ref.at(ts), rtol=0, atol=1e-8)
    # a post-jump state that jumps again has NaN xdot only where simulate has it
    arcs = simulate_vectorized(overlap(), [[1.5]], t_max=2.5)
    ref = hs.simulate(hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones(1), jump_map=lambda x: np.zeros(1),
        flow_set=lambda x: x[0] <= 2.0,
        jump_set=lambda x: x[0] >= 1.0, state_dim=1), [1.5], t_max=2.5)
    np.testing.assert_array_equal(np.isnan(arcs[0].xdot), np.isnan(ref.xdot))
    assert arcs[0].stats["flows"] == ref.stats["flows"]


def test_refine_with_a_jump_at_t_max_stores_each_sample_once():
    vt = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
        jump_guard=lambda x: x[:, 0] - 0.5, flow_guard=lambda x: 0.5 - x[:, 0],
        state_dim=1, vectorized=True)
    st = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones(1), jump_map=lambda x: np.zeros(1),
        jump_guard=lambda x: x[0] - 0.5,
        flow_guard=lambda x: 0.5 - x[0], state_dim=1)
    arcs = simulate_vectorized(vt, [[0.0], [0.25]], t_max=1.0, refine=2)
    for x0, arc in zip([0.0, 0.25], arcs):
        check_domain(arc)
        same = (np.diff(arc.t) == 0) & (np.diff(arc.j) == 0)
        assert not same.any()
        ref = hs.simulate(st, [x0], t_max=1.0, refine=2)
        assert arc.termination is ref.termination
        # simulate's samples, each once (it may store the last inner sample twice)
        once = np.r_[True, (np.diff(ref.t) != 0) | (np.diff(ref.j) != 0)]
        assert len(arc) == once.sum()
        np.testing.assert_array_equal(arc.j, ref.j[once])
        np.testing.assert_allclose(arc.t, ref.t[once], rtol=0, atol=1e-12)
        np.testing.assert_allclose(arc.x, ref.x[once], rtol=0, atol=1e-12)
    assert arcs[0].j[-1] == 2 and arcs[0].t[-1] == 1.0      # the jump at t_max is taken


def test_non_finite_state_or_guard_is_never_a_set_exit():
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        arc, = simulate_vectorized(VBall(), [[1e308, 1e308]], t_max=5.0)
    assert arc.termination is Termination.NON_FINITE
    assert np.isfinite(arc.x).all()
    # a guard returning NaN: MAP_ERROR naming it, as simulate's sets from guards

    class NanGuard(VBall):
        def jump_guard(self, x):
            return np.where(x[:, 0] < 0.5, np.nan, -x[:, 0])
    arcs = simulate_vectorized(NanGuard(), [[1.0, 0.0], [3.0, 5.0]], t_max=0.6, warn=False)
    assert arcs[0].termination is Termination.MAP_ERROR
    assert isinstance(arcs[0].exception, hs.MapError)
    assert arcs[0].exception.map_name == "jump_guard"
    assert "jump_guard returned NaN (at t=" in arcs[0].message
    assert arcs[1].termination is Termination.T_MAX


def test_messages_come_from_the_rules_table():
    from hybridsim.rules import message
    leave = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), flow_set=lambda x: x[:, 0] <= 1.0, state_dim=1,
        vectorized=True)
    a, b = simulate_vectorized(leave, [[0.0], [2.0]], t_max=7.0)
    assert a.message == message(Termination.LEFT_SETS, "left", t=a.tf, j=0, x=a.x[-1])
    assert b.message == message(Termination.NOT_IN_SETS, x=b.x[0], t=0.0, j=0)
    grow = hs.HybridSystem.from_functions(flow_map=lambda x: x, state_dim=1, vectorized=True)
    c, = simulate_vectorized(grow, [[1.0]], t_max=30.0, max_norm=1e3, warn=False)
    assert c.message == message(Termination.BLOWUP, norm=np.linalg.norm(c.x[-1]),
                                max_norm=1e3, t=c.tf, j=0)
    d, = simulate_vectorized(grow, [[1.0]], t_max=30.0, max_steps=3, warn=False)
    assert d.message == message(Termination.MAX_STEPS, "steps", steps=3, max_steps=3, t=d.tf)
    e, = simulate_vectorized(vtimer(), [[0.0]], t_max=30.0, max_samples=5, warn=False)
    assert e.termination is Termination.MAX_STEPS and len(e) == 5
    assert "samples stored (max_samples=5)" in e.message


# ------------------------------------------------ the Python path's rules (aed3bcf)
def _both_paths(make, x0s, **kw):
    """The vectorized arcs of ``x0s`` and simulate's arcs of the same system
    (``make(vectorized)`` builds it), each row under its own run."""
    arcs = simulate_vectorized(make(True), x0s, **kw)
    refs = [hs.simulate(make(False), x0, **kw) for x0 in np.asarray(x0s, float)]
    return arcs, refs


def _floor_ball(vectorized, kind, restitution=0.8, jump_map=None):
    """A ball on a floor y_f(t) = 0.1 sin(2t) whose jump map keeps the located
    position and reflects the relative velocity (tests/engine/test_faults.py's)."""
    def yf(t):
        return 0.1 * np.sin(2.0 * t)

    def dyf(t):
        return 0.2 * np.cos(2.0 * t)
    if vectorized:
        def g(x, t):
            return np.column_stack([x[:, 0], dyf(t) - restitution * (x[:, 1] - dyf(t))])
        kw = dict(jump_set=lambda x, t: (x[:, 0] - yf(t) <= 0) & (x[:, 1] - dyf(t) <= 0))
        if kind in ("guard", "both"):
            kw["flow_guard"] = lambda x, t: x[:, 0] - yf(t)
        if kind in ("indicator", "both"):
            kw["flow_set"] = lambda x, t: x[:, 0] - yf(t) >= 0

        def f(x):
            return np.column_stack([x[:, 1], np.full(len(x), -9.81)])
    else:
        def g(x, t):
            return np.array([x[0], dyf(t) - restitution * (x[1] - dyf(t))])
        kw = dict(jump_set=lambda x, t: x[0] - yf(t) <= 0 and x[1] - dyf(t) <= 0)
        if kind in ("guard", "both"):
            kw["flow_guard"] = lambda x, t: x[0] - yf(t)
        if kind in ("indicator", "both"):
            kw["flow_set"] = lambda x, t: x[0] - yf(t) >= 0

        def f(x):
            return np.array([x[1], -9.81])
    return hs.HybridSystem.from_functions(flow_map=f, jump_map=jump_map or g, state_dim=2,
                                          vectorized=vectorized, **kw)


@pytest.mark.parametrize("kind", ["guard", "indicator", "both"])
@pytest.mark.parametrize("restitution", [0.8, 0.3])
def test_post_jump_state_within_the_events_error_of_C_flows_on(kind, restitution):
    """rules.post_jump_probe: the post-jump state keeps the located height, a
    few ulp outside C; within the event's own location error it counts as in
    C, row by row, as on the Python path."""
    x0s = [[1.0, 0.0], [0.7, 0.5], [1.3, -1.0]]
    arcs, refs = _both_paths(lambda v: _floor_ball(v, kind, restitution), x0s,
                             t_max=3.0, j_max=6)
    for arc, ref in zip(arcs, refs):
        assert arc.termination is ref.termination, (arc.message, ref.message)
        assert arc.termination in (Termination.J_MAX, Termination.T_MAX)    # never LEFT_SETS
        np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-9)
        after = arc.x[1:][np.diff(arc.j) == 1]
        floor = 0.1 * np.sin(2.0 * arc.jump_times)
        assert np.all(np.abs(after[:, 0] - floor) < 1e-13)
        check_domain(arc)


def test_post_jump_state_genuinely_outside_C_still_leaves_the_sets():
    def bad(vectorized):
        if vectorized:
            return lambda x, t: np.column_stack([x[:, 0] - 1e-9, np.full(len(x), 5.0)])
        return lambda x, t: np.array([x[0] - 1e-9, 5.0])
    arcs, refs = _both_paths(lambda v: _floor_ball(v, "both", jump_map=bad(v)),
                             [[1.0, 0.0], [0.5, 0.0]], t_max=3.0)
    for arc, ref in zip(arcs, refs):
        assert arc.termination is ref.termination is Termination.LEFT_SETS
        assert arc.jump_count == ref.jump_count == 1
        assert arc.message == ref.message


def _free_ball(vectorized, **guards):
    """A ball landing at height 0 (tests/engine/test_faults.py's)."""
    if vectorized:
        f = lambda x: np.column_stack([x[:, 1], np.full(len(x), -9.81)])  # noqa: E731
        g = lambda x: np.column_stack([np.zeros(len(x)), -0.8 * x[:, 1]])  # noqa: E731
    else:
        f = lambda x: np.array([x[1], -9.81])                              # noqa: E731
        g = lambda x: np.array([0.0, -0.8 * x[1]])                         # noqa: E731
    return hs.HybridSystem.from_functions(flow_map=f, jump_map=g, state_dim=2,
                                          vectorized=vectorized,
                                          **guards)


@pytest.mark.parametrize("j_max, cause", [(30, Termination.J_MAX),
                                          (np.inf, Termination.ZENO)])
def test_a_jump_loop_is_named_as_on_the_python_path(j_max, cause):
    """D = {-h >= 0} by the guard alone: the state after the impact is in D
    again, the run jumps at one instant until J_MAX or ZENO, and the message
    (rules.is_jump_loop, kind "loop") is simulate's, word for word."""
    def make(v):
        col = (lambda x: x[:, 0]) if v else (lambda x: x[0])
        return _free_ball(v, flow_guard=col, jump_guard=lambda x: -col(x))
    arcs, refs = _both_paths(make, [[1.0, 0.0], [2.0, 0.0]], t_max=2.0, j_max=j_max,
                             warn=False)
    for arc, ref in zip(arcs, refs):
        assert arc.termination is ref.termination is cause
        assert "jump loop" in arc.message and arc.message == ref.message
        assert np.ptp(arc.jump_times) == 0.0
    if j_max == 30:
        assert "the last 30 jumps were all at t=0.451523" in arcs[0].message


def test_loops_only_where_the_jumps_are_from_C():
    """A purely discrete system (C empty) and an ordinary ball keep their plain
    messages; a loop row beside an ordinary row is named alone."""
    count = hs.HybridSystem.from_functions(jump_map=lambda x: x + 1.0,
                                           jump_set=lambda x: np.ones(len(x), bool),
                                           flow_set=lambda x: np.zeros(len(x), bool), state_dim=1,
                                           vectorized=True)
    for j_max, cause in ((30, Termination.J_MAX), (100, Termination.ZENO)):
        arc, = simulate_vectorized(count, [[0.0]], t_max=1.0, j_max=j_max, warn=False)
        assert arc.termination is cause and "loop" not in arc.message
        assert arc.jump_count == min(j_max, 50) and arc.xf[0] == arc.jump_count
    arcs = simulate_vectorized(VBall(), [[1.0, 0.0]], t_max=10.0, j_max=5)
    assert arcs[0].message == Termination.J_MAX.message
    # h >= 0 is D on the first row's side only: its jumps loop, the other's do not
    mixed = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.column_stack([x[:, 1], np.full(len(x), -9.81), np.zeros(len(x))]),
        jump_map=lambda x: np.column_stack([np.zeros(len(x)), -0.8 * x[:, 1], x[:, 2]]),
        flow_guard=lambda x: x[:, 0],
        jump_set=lambda x: (x[:, 0] <= 0) & ((x[:, 1] <= 0) | (x[:, 2] > 0)),
        state_dim=3, vectorized=True)
    a, b = simulate_vectorized(mixed, [[1.0, 0.0, 1.0], [1.0, 0.0, 0.0]], t_max=10.0,
                               j_max=12, warn=False)
    assert a.termination is Termination.J_MAX and "the last 12 jumps were all at" in a.message
    assert b.termination is Termination.J_MAX and b.message == Termination.J_MAX.message


@pytest.mark.parametrize("flow_side", ["C", "flow_guard"])
def test_a_jump_guard_is_used_beside_an_indicator_for_C(flow_side):
    """The apex is 1e-6 above the jump guard h - 1: only the guard's peak,
    refined inside the step, finds the jump, with C an indicator or a guard."""
    import math
    v0 = math.sqrt(2.0 * 9.81 * (1.0 + 1e-6))
    t_hit = (v0 - math.sqrt(v0 * v0 - 2.0 * 9.81)) / 9.81

    def make(v):
        col = (lambda x: x[:, 0]) if v else (lambda x: x[0])
        kw = ({"flow_set": lambda x: col(x) >= -1e-9} if flow_side == "C"
              else {"flow_guard": lambda x: col(x) + 1e-9})
        return _free_ball(v, jump_guard=lambda x: col(x) - 1.0, **kw)
    arcs, refs = _both_paths(make, [[0.0, v0], [0.0, v0]], t_max=2.0 * v0 / 9.81, j_max=1)
    for arc, ref in zip(arcs, refs):
        assert arc.jump_count == ref.jump_count == 1, arc.message
        np.testing.assert_allclose(arc.jump_times, [t_hit], rtol=0, atol=1e-9)


@pytest.mark.parametrize("apex", [0.04, 0.96])
def test_a_guard_peak_between_a_step_end_and_its_nearest_sample_is_found(apex):
    """x' = 1 in one step [0, 1] (first_step = max_step = 1); the jump guard
    1e-4 - (x - apex)^2 peaks above 0 between a step end and the nearest of the
    three interior samples, rising at the start (apex 0.04) or falling at the
    end (0.96): events.find_interior_event's end cases, on the vectorized path."""
    def make(v):
        col = (lambda x: x[:, 0]) if v else (lambda x: x[0])
        return hs.HybridSystem.from_functions(
            flow_map=lambda x: np.ones_like(x), jump_map=lambda x: x + 1.0,
            jump_guard=lambda x: 1e-4 - (col(x) - apex) ** 2, state_dim=1, vectorized=v)
    arcs, refs = _both_paths(make, [[0.0]], t_max=1.0, first_step=1.0, max_step=1.0)
    for arc, ref in zip(arcs, refs):
        assert arc.jump_count == ref.jump_count == 1, arc.message
        np.testing.assert_allclose(arc.jump_times, [apex - 0.01], rtol=0, atol=1e-12)
        np.testing.assert_allclose(arc.t, ref.t, rtol=0, atol=1e-12)


@pytest.mark.parametrize("period", [0.1, 0.25, 1.0 / 3.0])
@pytest.mark.parametrize("refine", [1, 3])
@pytest.mark.parametrize("kind", ["set", "guard"])
def test_jumps_landing_on_t_max_up_to_round_off_store_each_sample_once(period, refine, kind):
    """A jump found within t_max's slack replaces the t_max sample; the step's
    inner samples are stored once; simulate's samples, sample for sample."""
    def make(v):
        col = (lambda x: x[:, 0]) if v else (lambda x: x[0])
        kw = (dict(jump_set=lambda x: col(x) >= period) if kind == "set"
              else dict(jump_guard=lambda x: col(x) - period))
        return hs.HybridSystem.from_functions(flow_map=lambda x: np.ones_like(x),
                                              jump_map=lambda x: np.zeros_like(x), state_dim=1,
                                              vectorized=v, **kw)
    arcs, refs = _both_paths(make, [[0.0]], t_max=2.0, refine=refine)
    for arc, ref in zip(arcs, refs):
        check_domain(arc)
        assert np.all((np.diff(arc.t) > 0) | (np.diff(arc.j) == 1))
        assert arc.jump_count == ref.jump_count == round(2.0 / period)
        assert arc.j[-1] == arc.jump_count and abs(arc.t[-1] - 2.0) < 1e-12
        assert len(arc) == len(ref)
        np.testing.assert_allclose(arc.t, ref.t, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(arc.j, ref.j)


@pytest.mark.parametrize("x0", [[1e308, 1e308], [1e308, -1e308]])
def test_overflow_inside_a_step_is_non_finite_dense_as_on_the_python_path(x0):
    import warnings
    with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore"):
        warnings.simplefilter("ignore")
        arc, = simulate_vectorized(VBall(), [x0], t_max=1.0)
        ref = hs.simulate(Ball(), x0, t_max=1.0, throw=False)
    assert arc.termination is ref.termination is Termination.NON_FINITE
    assert arc.message == ref.message
    assert np.isfinite(arc.x).all() and arc.t.tolist() == ref.t.tolist()


def test_ctrl_c_names_each_rows_last_stored_sample():
    """A KeyboardInterrupt from a map mid-run: every row still running ends
    CANCELED, its message naming its last stored sample (rules.message)."""
    calls = {"n": 0}

    def f(x):
        calls["n"] += 1
        if calls["n"] == 40:
            raise KeyboardInterrupt
        return np.ones_like(x)
    sysm = hs.HybridSystem.from_functions(
        flow_map=f, jump_map=lambda x: np.zeros_like(x), jump_guard=lambda x: x[:, 0] - 0.1,
        state_dim=1, vectorized=True)
    arcs = simulate_vectorized(sysm, [[0.0], [0.05], [0.09]], t_max=100.0, refine=3,
                               warn=False)
    for arc in arcs:
        assert arc.termination is Termination.CANCELED
        arc.validate()
        assert arc.message == hs.rules.message(Termination.CANCELED, t=arc.t[-1],
                                               j=int(arc.j[-1]))
        assert arc.jump_count > 0
