"""Tests of the vectorized batch integrator (hybridsim.batch_vectorized) and of
simulate_many over executors."""
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import hybridsim as hs
from hybridsim import Termination
from hybridsim.batch_vectorized import simulate_vectorized
from hybridsim.library import BouncingBall, BouncingBallBatch, bouncing_ball_jump_times

G, E = 9.81, 0.8


# ---------------------------------------------------------------- systems
VBall = BouncingBallBatch          # balls over a batch (rows), picklable
Ball = BouncingBall                # the same ball, one state at a time


def ball_jump_times(h0, k, e=E):
    return bouncing_ball_jump_times(h0, k, G, e)


def vtimer(**kw):
    """x' = 1 on C = {x <= 1}, x+ = 0 on D = {x >= 1}, with guards."""
    return hs.HybridSystem.from_functions(
        f=lambda x: np.ones_like(x), g=lambda x: np.zeros_like(x),
        jump_guard=lambda x: x[:, 0] - 1.0, flow_guard=lambda x: 1.0 - x[:, 0],
        state_dim=1, vectorized=True, **kw)


def timer():
    return hs.HybridSystem.from_functions(
        f=lambda x: np.array([1.0]), g=lambda x: np.array([0.0]),
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
        f=f, g=lambda x: np.stack([x[:, 0], -0.5 * x[:, 1]], axis=1),
        D=lambda x: (x[:, 0] >= 1.5) & (x[:, 1] > 0),
        jump_guard=lambda x: np.stack([x[:, 0] - 1.5, x[:, 1]], axis=1),
        state_dim=2, vectorized=True)
    scalar = hs.HybridSystem.from_functions(
        f=lambda x: f(x[None])[0], g=lambda x: np.array([x[0], -0.5 * x[1]]),
        D=lambda x: x[0] >= 1.5 and x[1] > 0,
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
        f=lambda x, t, j: np.ones_like(x) * (1 + j)[:, None],
        g=lambda x, t, j: np.zeros_like(x),
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
        f=lambda x: np.ones_like(x), g=lambda x: np.zeros_like(x),
        C=lambda x: x[:, 0] <= 2.0, D=lambda x: x[:, 0] >= 1.0,
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
        f=lambda x: np.ones_like(x), C=lambda x: x[:, 0] <= 1.0, state_dim=1, vectorized=True)
    arcs = simulate_vectorized(leave, [[0.0], [0.5], [2.0]], t_max=7.0)
    assert arcs[0].termination is Termination.LEFT_SETS
    assert abs(arcs[0].tf - 1.0) <= 8 * np.finfo(float).eps
    assert abs(arcs[1].tf - 0.5) <= 8 * np.finfo(float).eps
    assert "left C" in arcs[0].message
    assert arcs[2].termination is Termination.NOT_IN_SETS and len(arcs[2]) == 1


def test_zeno():
    zeno = hs.HybridSystem.from_functions(
        f=lambda x: -np.ones_like(x), g=lambda x: np.zeros_like(x),
        C=lambda x: x[:, 0] >= 0, D=lambda x: x[:, 0] <= 0, state_dim=1, vectorized=True)
    arcs = simulate_vectorized(zeno, [[1.0], [0.0]], t_max=5.0, zeno_jumps=20)
    for arc, t in zip(arcs, [1.0, 0.0]):
        assert arc.termination is Termination.ZENO
        assert abs(arc.tf - t) < 1e-12
        assert "consecutive jumps" in arc.message
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
    grow = hs.HybridSystem.from_functions(f=lambda x: x, state_dim=1, vectorized=True)
    arcs = simulate_vectorized(grow, [[1.0], [-2.0]], t_max=30.0, max_norm=1e3)
    assert all(a.termination is Termination.BLOWUP for a in arcs)
    arcs = simulate_vectorized(vtimer(), [[0.0]], t_max=3.5, t0=1.0, j0=4)
    assert arcs[0].t[0] == 1.0 and arcs[0].j[0] == 4
    np.testing.assert_allclose(arcs[0].jump_times, [2.0, 3.0], atol=1e-12)


def test_non_finite_solver_failure_and_bad_jump_values():
    def vec(**kw):
        return hs.HybridSystem.from_functions(state_dim=1, vectorized=True, **kw)
    # an overflowing step is accepted (scale inf) and ends NON_FINITE
    over = vec(f=lambda x: np.full_like(x, 1e308))
    arcs = simulate_vectorized(over, [[1.7e308], [0.0]], t_max=10.0, first_step=1.0)
    assert [a.termination for a in arcs] == [Termination.NON_FINITE] * 2
    assert arcs[1].tf == 1.0 and np.isfinite(arcs[1].x).all()
    # a NaN flow is rejected down to the smallest step: NON_FINITE naming flow_map;
    # a finite escape likewise, but with finite stages: SOLVER_FAILED
    nan = vec(f=lambda x: np.where(x < 1, 1.0, np.nan))
    escape = vec(f=lambda x: x ** 2)
    for sysv, cause in ((nan, Termination.NON_FINITE), (escape, Termination.SOLVER_FAILED)):
        arc, = simulate_vectorized(sysv, [[0.0 if sysv is nan else 1.0]], t_max=3.0)
        assert arc.termination is cause
        assert abs(arc.tf - 1.0) < 1e-5
        if sysv is nan:
            assert "flow_map returned non-finite values near t=1 (j=0)" in arc.message
    # a jump map returning inf: MAP_ERROR naming it, the run kept so far
    bad = vec(f=lambda x: np.ones_like(x), g=lambda x: np.full_like(x, np.inf),
              D=lambda x: x[:, 0] >= 1.0)
    arc, = simulate_vectorized(bad, [[0.0]], t_max=3.0)
    assert arc.termination is Termination.MAP_ERROR
    assert "jump_map returned non-finite values" in arc.message
    assert abs(arc.tf - 1.0) < 1e-12
    # the same causes and samples as simulate
    refs = {
        "over": hs.HybridSystem.from_functions(f=lambda x: np.array([1e308]), state_dim=1),
        "nan": hs.HybridSystem.from_functions(f=lambda x: np.where(x < 1, 1.0, np.nan),
                                              state_dim=1),
        "escape": hs.HybridSystem.from_functions(f=lambda x: x ** 2, state_dim=1),
        "bad": hs.HybridSystem.from_functions(f=lambda x: np.ones(1),
                                              g=lambda x: np.full(1, np.inf),
                                              D=lambda x: x[0] >= 1.0, state_dim=1)}
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
        f=f, g=lambda x: np.zeros_like(x), jump_guard=lambda x: x[:, 0] - 1.0,
        flow_guard=lambda x: 1.0 - x[:, 0], state_dim=1, vectorized=True)
    arcs = simulate_vectorized(sysv, [[0.0], [0.7], [0.8]], t_max=0.55, max_step=0.01)
    assert arcs[0].termination is Termination.MAP_ERROR
    assert isinstance(arcs[0].exception, RuntimeError) and "boom" in arcs[0].message
    assert [a.termination for a in arcs[1:]] == [Termination.T_MAX] * 2
    with pytest.raises(hs.SimulationError, match="trajectory 0: .*boom"):
        simulate_vectorized(sysv, [[0.0], [0.7]], t_max=0.55, max_step=0.01, throw=True)


def test_simulate_many_dispatches_to_vectorized():
    x0s = np.array([[1.0, 0.0], [1.5, 0.0]])
    a = hs.simulate_many(VBall(), x0s, t_max=3.0, j_max=4)
    b = simulate_vectorized(VBall(), x0s, t_max=3.0, j_max=4)
    for p, q in zip(a, b):
        np.testing.assert_array_equal(p.t, q.t)
        np.testing.assert_array_equal(p.x, q.x)


# ---------------------------------------------------------------- bad input
def test_bad_x0s():
    with pytest.raises(ValueError, match=r"x0s must have shape \(N, 2\).*got shape \(2,\)"):
        simulate_vectorized(VBall(), [1.0, 0.0], t_max=1.0)
    with pytest.raises(ValueError, match=r"x0s must have shape \(N, 2\).*got shape \(1, 3\)"):
        simulate_vectorized(VBall(), [[1.0, 0.0, 0.0]], t_max=1.0)
    with pytest.raises(ValueError, match="x0s must be finite; rows \\[1\\]"):
        simulate_vectorized(VBall(), [[1.0, 0.0], [np.nan, 0.0]], t_max=1.0)
    with pytest.raises(ValueError, match=r"x0s must have shape \(N, 2\)"):
        hs.simulate_many(VBall(), [[1.0]], t_max=1.0)


def test_bad_options():
    x0s = [[1.0, 0.0]]
    with pytest.raises(TypeError, match="unexpected keyword argument 'rtoll'"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, rtoll=1e-3)
    with pytest.raises(ValueError, match="method='Radau' is not supported in vectorized"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, method="Radau")
    with pytest.raises(ValueError, match="priority must be one of"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, priority="both")
    with pytest.raises(ValueError, match="inputs=.* is not supported in vectorized mode"):
        simulate_vectorized(VBall(), x0s, t_max=1.0, inputs=lambda t: 0.0)
    with pytest.raises(ValueError, match="refine must be an int >= 1, got 0"):
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
        base = dict(f=lambda x: np.ones_like(x), g=lambda x: np.zeros_like(x),
                    C=lambda x: x[:, 0] <= 1.0, D=lambda x: x[:, 0] >= 1.0)
        base.update(kw)
        return hs.HybridSystem.from_functions(state_dim=1, vectorized=True, **base)

    with pytest.raises(hs.MapError, match=r"flow_map must return an array of shape \(2, 1\)"
                                          r".*got shape \(1,\)"):
        simulate_vectorized(make(f=lambda x: np.ones(1)), x0s, t_max=1.0)
    with pytest.raises(hs.MapError, match=r"jump_map must return an array of shape \(1, 1\)"
                                          r".*got shape \(\)"):
        simulate_vectorized(make(g=lambda x: 0.0), [[1.0]], t_max=1.0)
    with pytest.raises(hs.MapError, match=r"flow_set must return a boolean array of shape "
                                          r"\(2,\).*got shape \(\)"):
        simulate_vectorized(make(C=lambda x: True), x0s, t_max=1.0)
    with pytest.raises(hs.MapError, match=r"jump_set must return a boolean array of shape "
                                          r"\(2,\).*got shape \(2, 1\)"):
        simulate_vectorized(make(D=lambda x: x >= 1.0), x0s, t_max=1.0)
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
        f=lambda x: np.ones_like(x), g=lambda x: np.zeros_like(x),
        jump_guard=lambda x: x[:, 0] - 1.0, flow_guard=lambda x: 1.0 - x[:, 0],
        state_dim=1, vectorized=True)
    quiet = simulate_vectorized(timer, [[0.0], [0.5]], t_max=2.2)
    assert capsys.readouterr().err == ""
    arcs = hs.simulate_many(timer, [[0.0], [0.5]], t_max=2.2, progress=True)
    assert "simulate_vectorized" in capsys.readouterr().err
    for a, b in zip(arcs, quiet, strict=True):      # the bar changes nothing
        np.testing.assert_array_equal(a.t, b.t)
    with pytest.raises(TypeError, match="progress must be True, False or None"):
        simulate_vectorized(timer, [[0.0]], t_max=1.0, progress="on")
