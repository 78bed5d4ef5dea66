"""The compiled path (hybridsim.compiled) against the Python path and closed forms.

Every system is compiled once per module (fixtures); compilation dominates
this file's time. Each comparison runs the *same* CompiledSystem on both
paths (``hs.simulate`` uses the plain Python maps, ``simulate_compiled`` the
numba-compiled ones) and, where there is one, checks the closed form.
"""
import doctest
import math
import os
import pickle
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest

numba = pytest.importorskip("numba", reason="the compiled path needs numba "
                                            "(pip install 'hybridsim[fast]')")

# compiling the engine takes tens of seconds on a fresh machine: CI runs these
pytestmark = pytest.mark.slow

import hybridsim as hs  # noqa: E402
import hybridsim.compiled as hc  # noqa: E402
from hybridsim.compiled import (  # noqa: E402
    CompiledSystem,
    CompileError,
    simulate_compiled,
    simulate_many_compiled,
)
from hybridsim.library import BouncingBall, Timer, bouncing_ball_jump_times  # noqa: E402

T = hs.Termination
TIGHT = dict(rtol=1e-8, atol=1e-10)
DOP853 = pytest.importorskip("scipy.integrate").DOP853


# ------------------------------------------------------------------ the systems' maps
def pend_f(x, t, j, p):          # a damped pendulum
    return np.array([x[1], -np.sin(x[0]) - p[0] * x[1]])


def pend_g(x, t, j, p):          # a kick back when it swings through the bottom
    return np.array([1e-9, 0.9 * abs(x[1])])


def pend_hD(x, t, j, p):
    return -x[0]


def ball_f(x, t, j, p):
    return np.array([x[1], -p[0]])


def ball_g(x, t, j, p):
    return np.array([0.0, -p[1] * x[1]])


def ball_hD(x, t, j, p):
    return -x[0]


def ball_hC(x, t, j, p):
    return x[0]


def ball_D(x, t, j, p):
    return x[0] <= 0.0 and x[1] <= 0.0


def ball_C(x, t, j, p):
    return x[0] >= 0.0


def one(x, t, j, p):
    return np.ones(1)


def zero(x, t, j, p):
    return np.zeros(1)


def timer_hD(x, t, j, p):
    return x[0] - p[0]


def timer_hC(x, t, j, p):
    return p[0] - x[0]


# thermostat with hysteresis: x = (z, q); p = (z_out, z_heat, z_min, z_max)
def thermo_f(x, t, j, p):
    return np.array([-x[0] + p[0] + p[1] * x[1], 0.0])


def thermo_g(x, t, j, p):
    return np.array([x[0], 1.0 - x[1]])


def thermo_hD(x, t, j, p):
    return x[0] - p[3] if x[1] > 0.5 else p[2] - x[0]


def thermo_hC(x, t, j, p):
    return p[3] - x[0] if x[1] > 0.5 else x[0] - p[2]


# sample-and-hold: z = (x1, x2, u, tau), xdot = A x + B u (double integrator),
# u+ = K x every p[0] seconds, K = (p[1], p[2])
def sah_f(z, t, j, p):
    return np.array([z[1], z[2], 0.0, 1.0])


def sah_g(z, t, j, p):
    return np.array([z[0], z[1], p[1] * z[0] + p[2] * z[1], 0.0])


def sah_hD(z, t, j, p):
    return z[3] - p[0]


def sah_hC(z, t, j, p):
    return p[0] - z[3]


# apex: x'' = -1, D = {x >= 1}; the jump resets the height to 0
def apex_f(x, t, j, p):
    return np.array([x[1], -1.0])


def apex_g(x, t, j, p):
    return np.array([0.0, p[0]])          # back to 0 with the launch speed


def apex_hD(x, t, j, p):
    return x[0] - 1.0


def apex_D(x, t, j, p):
    return x[0] >= 1.0


# leaving C u D: x' = 1 on C = {x <= 1}, D = {x <= -1}
def leave_hC(x, t, j, p):
    return 1.0 - x[0]


def leave_D(x, t, j, p):
    return x[0] <= -1.0


def grow_f(x, t, j, p):
    return x.copy()


def nan_f(x, t, j, p):
    return np.array([x[0] if t < 0.5 else np.nan])


# ------------------------------------------------------------------ fixtures
def _compiled(system):
    system.compile()
    return system


@pytest.fixture(scope="module")
def ball():
    return _compiled(CompiledSystem(ball_f, ball_g, jump_guard=ball_hD, flow_guard=ball_hC,
                                    jump_set=ball_D, flow_set=ball_C, state_dim=2,
                                    params=[9.81, 0.8]))


@pytest.fixture(scope="module")
def ball_sets():
    """The ball with set indicators only (events by bisection)."""
    return _compiled(CompiledSystem(ball_f, ball_g, jump_set=ball_D, flow_set=ball_C,
                                    state_dim=2, params=[9.81, 0.8]))


@pytest.fixture(scope="module")
def timer():
    return _compiled(CompiledSystem(one, zero, jump_guard=timer_hD, flow_guard=timer_hC,
                                    state_dim=1, params=[1.0]))


@pytest.fixture(scope="module")
def thermostat():
    return _compiled(CompiledSystem(thermo_f, thermo_g, jump_guard=thermo_hD,
                                    flow_guard=thermo_hC, state_dim=2,
                                    params=[60.0, 30.0, 70.0, 80.0]))


@pytest.fixture(scope="module")
def sample_hold():
    return _compiled(CompiledSystem(sah_f, sah_g, jump_guard=sah_hD, flow_guard=sah_hC,
                                    state_dim=4, params=[0.2, -1.0, -1.5]))


@pytest.fixture(scope="module")
def apex():
    return _compiled(CompiledSystem(apex_f, apex_g, jump_guard=apex_hD, jump_set=apex_D,
                                    state_dim=2, params=[math.sqrt(2.0 * (1.0 + 1e-6))]))


@pytest.fixture(scope="module")
def leave():
    return _compiled(CompiledSystem(one, zero, flow_guard=leave_hC, jump_set=leave_D,
                                    state_dim=1))


def both(system, x0, **kw):
    """The same run on the compiled and the Python path."""
    return simulate_compiled(system, x0, **kw), hs.simulate(system, x0, **kw)


def _jump_states(arc):
    """(pre-jump, post-jump) states of every jump."""
    k = np.flatnonzero(arc.j[1:] != arc.j[:-1])
    return arc.x[k], arc.x[k + 1]


def assert_agree(a, b, tol=1e-9, jt_tol=1e-12):
    """Same cause, same jumps (times within ``jt_tol`` relative to the horizon),
    same states at every jump and at the end within ``tol``.

    Sample grids may differ: a step's error estimate sums stages that nearly
    cancel, so the last bits (and with them the step sizes) depend on the
    summation order (numpy's dot versus a loop). Where the flow is integrated
    exactly (ball, timer) the grids agree anyway.
    """
    assert a.termination is b.termination, (a.message, b.message)
    assert a.jump_count == b.jump_count, (a.jump_count, b.jump_count)
    scale = max(1.0, float(np.max(np.abs(b.t))))
    np.testing.assert_allclose(a.jump_times, b.jump_times, rtol=0, atol=jt_tol * scale)
    for u, v in zip(_jump_states(a), _jump_states(b)):
        np.testing.assert_allclose(u, v, rtol=tol, atol=tol)
    np.testing.assert_allclose(a.t[-1], b.t[-1], rtol=0, atol=max(jt_tol, tol) * scale)
    np.testing.assert_allclose(a.xf, b.xf, rtol=tol, atol=tol)


def assert_same_grid(a, b, tol=1e-12):
    np.testing.assert_array_equal(a.j, b.j)
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=tol * max(1.0, abs(b.t[-1])))
    np.testing.assert_allclose(a.x, b.x, rtol=tol, atol=tol)
    np.testing.assert_allclose(a.xdot, b.xdot, rtol=1e-9, atol=1e-9)


# ------------------------------------------------------------------ agreement
def test_ball_agrees_with_python_path_and_closed_form(ball):
    a, b = both(ball, [1.0, 0.0], t_max=20.0, j_max=30, **TIGHT)
    ref = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=20.0, j_max=30, **TIGHT)
    assert_agree(a, b)
    assert_agree(a, ref)
    assert_same_grid(a, b)           # RK45 integrates the parabola exactly: same steps
    exact = bouncing_ball_jump_times(1.0, 30)
    assert np.max(np.abs(a.jump_times - exact)) < 1e-12
    assert a.termination is T.J_MAX
    assert a.stats["events"] == a.stats["flows"] == 30
    assert a.stats["steps"] > 30 and a.stats["nfev"] >= 6 * a.stats["steps"]
    # the plain end's words and the system's description (kept per system)
    assert a.message == T.J_MAX.message and a.exception is None
    c = simulate_compiled(ball, [1.0, 0.0], t_max=0.5, **TIGHT)
    assert c.termination is T.T_MAX and c.message == T.T_MAX.message
    assert a.system_description == c.system_description == "hybridsim.compiled.CompiledSystem"


def test_specialised_kernel_same_results(ball):
    spec = CompiledSystem(ball_f, ball_g, jump_guard=ball_hD, flow_guard=ball_hC,
                          jump_set=ball_D, flow_set=ball_C, state_dim=2, params=[9.81, 0.8],
                          specialize=True)
    a = simulate_compiled(spec, [1.0, 0.0], t_max=20.0, j_max=30, **TIGHT)
    b = simulate_compiled(ball, [1.0, 0.0], t_max=20.0, j_max=30, **TIGHT)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.x, b.x)
    assert a.stats == b.stats and a.termination is b.termination


def _ball_f_into(x, t, j, p, out):
    out[0] = x[1]
    out[1] = -p[0]


@pytest.mark.slow           # a specialised kernel: about 15 s of CPU once per machine
def test_specialised_kernel_flow_written_into_the_rows(ball):
    # a flow map written into out: the specialised kernel's steps call it into the
    # run's rows (no array per evaluation), the same arc as the generic kernel's
    spec = CompiledSystem(_ball_f_into, ball_g, jump_guard=ball_hD, flow_guard=ball_hC,
                          jump_set=ball_D, flow_set=ball_C, state_dim=2, params=[9.81, 0.8],
                          specialize=True)
    assert "flow" in spec.maps_into
    a = simulate_compiled(spec, [1.0, 0.0], t_max=20.0, j_max=30, refine=3, **TIGHT)
    b = simulate_compiled(ball, [1.0, 0.0], t_max=20.0, j_max=30, refine=3, **TIGHT)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.xdot, b.xdot)
    assert a.stats == b.stats and a.termination is b.termination
    assert spec._nb["one"].py_func.__globals__["_INTO"] is True     # the form the steps call


def test_ball_set_indicators_only_bisection(ball_sets):
    a, b = both(ball_sets, [1.0, 0.0], t_max=20.0, j_max=15, **TIGHT)
    assert_agree(a, b)
    assert np.max(np.abs(a.jump_times - bouncing_ball_jump_times(1.0, 15))) < 1e-12


def test_ball_refine_samples_and_xdot(ball):
    a, b = both(ball, [2.0, 0.0], t_max=3.0, j_max=5, refine=4, **TIGHT)
    assert_agree(a, b)
    assert_same_grid(a, b)
    flows = a.j[1:] == a.j[:-1]
    # the parabola: xdot is (v, -g) at every sample
    np.testing.assert_allclose(a.xdot[:, 0], a.x[:, 1], atol=1e-9)
    np.testing.assert_allclose(a.xdot[:, 1], -9.81, atol=1e-9)
    assert flows.sum() > 5 * 3


@pytest.mark.parametrize("period", [0.1, 0.25, 1.0, 1.0 / 3.0])
def test_timer_jump_at_t_max(timer, period):
    timer.params = [period]
    try:
        k = 12
        a, b = both(timer, [0.0], t_max=k * period)
        ref = hs.simulate(Timer(period), [0.0], t_max=k * period)
    finally:
        timer.params = [1.0]
    assert_agree(a, b)
    assert_agree(a, ref)
    assert_same_grid(a, b)
    assert a.jump_count == k                     # the jump at t_max is taken
    np.testing.assert_allclose(a.jump_times, period * np.arange(1, k + 1), rtol=0,
                               atol=1e-12)
    assert a.termination is T.T_MAX


def test_timer_many_jumps_j_max(timer):
    a, b = both(timer, [0.0], t_max=math.inf, j_max=500)
    assert_agree(a, b)
    assert a.termination is T.J_MAX and a.jump_count == 500
    np.testing.assert_allclose(a.jump_times, np.arange(1, 501), rtol=0, atol=1e-10)


def test_thermostat_hysteresis(thermostat):
    a, b = both(thermostat, [75.0, 1.0], t_max=6.0, **TIGHT)
    assert_agree(a, b, tol=1e-7, jt_tol=1e-8)
    first = np.log((60.0 + 30.0 - 75.0) / (60.0 + 30.0 - 80.0))
    exact = first + np.log(2.0) * np.arange(a.jump_count)
    np.testing.assert_allclose(a.jump_times, exact, atol=1e-8)
    assert np.array_equal(a.x[a.j == 3, 1], np.zeros(np.sum(a.j == 3)))


def test_sample_and_hold(sample_hold):
    a, b = both(sample_hold, [1.0, 0.0, 0.0, 0.2], t_max=4.0, **TIGHT)
    assert_agree(a, b, tol=1e-8)       # tau integrates exactly: jump times to 1e-12
    assert a.jump_count == 21                    # t = 0, 0.2, ..., 4.0
    np.testing.assert_allclose(a.jump_times, 0.2 * np.arange(21), atol=1e-12)


def test_zeno_ball(ball):
    a, b = both(ball, [1.0, 0.0], t_max=10.0)
    assert a.termination is T.ZENO and b.termination is T.ZENO
    assert_agree(a, b, jt_tol=1e-10)
    assert a.jump_times[-1] < 9.0 * math.sqrt(2 / 9.81)      # before the Zeno time


def test_left_sets(leave):
    a, b = both(leave, [0.0], t_max=5.0)
    assert a.termination is T.LEFT_SETS and b.termination is T.LEFT_SETS
    assert_agree(a, b)
    assert abs(a.t[-1] - 1.0) < 1e-14
    assert "left C" in a.message


def test_apex_entered_and_left_within_one_step(apex):
    """x'' = -1 up to an apex 1e-6 above D = {x >= 1}: RK45 steps over the excursion
    whole; the interior search finds it, on both paths."""
    v0 = apex.params[0]
    a, b = both(apex, [0.0, v0], t_max=3.0 * v0, j_max=2)
    assert_agree(a, b)
    assert a.jump_count == 2
    t1 = v0 - math.sqrt(v0 * v0 - 2.0)
    np.testing.assert_allclose(a.jump_times, [t1, 2 * t1], atol=1e-9)


def test_random_priority_same_coins_as_python_path():
    """Timer with overlapping C and D: random priority draws the same coins
    from numpy's Generator on both paths."""
    sysr = _compiled(CompiledSystem(one, zero, flow_guard=timer_hC,
                                    jump_guard=lambda x, t, j, p: x[0] - 0.5,
                                    state_dim=1, params=[1.0]))
    # t_max off the event grid: an event exactly at t_max is decided by round-off
    # (a few ulp either side), and with random priority that decides a coin
    for seed in (0, 1, 7):
        a, b = both(sysr, [0.0], t_max=4.8, priority="random", seed=seed)
        assert_agree(a, b)
    a, b = both(sysr, [0.0], t_max=5.0, priority="flows")
    assert_agree(a, b)
    np.testing.assert_allclose(a.jump_times[:4], [1, 2, 3, 4], atol=1e-12)


def test_failure_causes(ball):
    grow = _compiled(CompiledSystem(grow_f, state_dim=1))
    with pytest.warns(hs.SimulationWarning):
        a, b = both(grow, [1.0], t_max=50.0, max_norm=1e6)
    assert a.termination is T.BLOWUP
    assert_agree(a, b, tol=1e-5, jt_tol=1e-6)         # exp(t) at rtol 1e-6
    np.testing.assert_allclose(a.xf, np.exp(a.t[-1]), rtol=1e-4)
    with pytest.warns(hs.SimulationWarning):
        a, b = both(grow, [1.0], t_max=50.0, max_steps=7)
    assert a.termination is T.MAX_STEPS and len(a.t) == len(b.t) == 8
    assert_agree(a, b, tol=1e-5, jt_tol=1e-6)
    nan = _compiled(CompiledSystem(nan_f, state_dim=1))
    with pytest.warns(hs.SimulationWarning):
        a, b = both(nan, [1.0], t_max=1.0)
    assert a.termination is T.NON_FINITE and b.termination is T.NON_FINITE
    a, b = both(ball, [-1.0, 1.0], t_max=1.0)
    assert a.termination is T.NOT_IN_SETS and len(a.t) == 1
    assert_agree(a, b)


def test_jump_map_non_finite_is_map_error():
    bad = _compiled(CompiledSystem(one, lambda x, t, j, p: np.array([np.nan]),
                                   jump_guard=timer_hD, state_dim=1, params=[1.0]))
    with pytest.raises(hs.MapError) as e:
        simulate_compiled(bad, [0.0], t_max=3.0)
    assert e.value.arc is not None and e.value.arc.t[-1] == pytest.approx(1.0)
    arc = simulate_compiled(bad, [0.0], t_max=3.0, throw=False)
    assert arc.termination is T.MAP_ERROR and "jump_map" in arc.message
    ref = hs.simulate(bad, [0.0], t_max=3.0, throw=False)
    assert arc.message == ref.message and arc.exception.map_name == ref.exception.map_name


# ------------------------------------------------------------------ batches
def test_batch_equals_single_runs_and_python_path(ball):
    rng = np.random.default_rng(3)
    h0 = rng.uniform(0.5, 2.0, 300)
    x0s = np.column_stack([h0, np.zeros_like(h0)])
    # a tiny chunk budget: many chunks, and runs without room in their chunk's
    # pool run again in a later round
    arcs = simulate_many_compiled(ball, x0s, t_max=20.0, j_max=10, chunk_bytes=4096,
                                  **TIGHT)
    assert len(arcs) == 300
    jt = np.array([a.jump_times for a in arcs])
    np.testing.assert_allclose(jt, bouncing_ball_jump_times(h0, 10), rtol=0, atol=2e-12)
    for i in (0, 5, 150, 299):
        single = simulate_compiled(ball, x0s[i], t_max=20.0, j_max=10, **TIGHT)
        np.testing.assert_array_equal(arcs[i].t, single.t)
        np.testing.assert_array_equal(arcs[i].x, single.x)
        assert arcs[i].stats == single.stats
        assert_agree(arcs[i], hs.simulate(ball, x0s[i], t_max=20.0, j_max=10, **TIGHT))
    serial = simulate_many_compiled(ball, x0s[:20], t_max=20.0, j_max=10, parallel=False,
                                    **TIGHT)
    for a, b in zip(serial, arcs[:20]):
        np.testing.assert_array_equal(a.t, b.t)


def test_a_dop853_batch_equals_its_single_runs_and_the_python_paths():
    """method="DOP853": a damped pendulum's batch (guards, jumps, a flow that is
    no polynomial: the error estimate is not round-off) gives each row its
    single run to the bit, and the Python path's DOP853 run to round-off
    (steps of rtol 1e-10: jump times to 1e-9). The pool-size memo keeps the
    methods apart: an RK45 batch of the same rows sizes again."""
    pend = _compiled(CompiledSystem(pend_f, pend_g, jump_guard=pend_hD, state_dim=2,
                                    params=[0.3]))
    x0s = np.column_stack([np.linspace(0.5, 1.4, 40), np.zeros(40)])
    kw = dict(t_max=12.0, j_max=6, rtol=1e-10, atol=1e-12)
    arcs = simulate_many_compiled(pend, x0s, method="DOP853", **kw)
    for i in (0, 17, 39):
        single = simulate_compiled(pend, x0s[i], method=DOP853, **kw)
        np.testing.assert_array_equal(arcs[i].t, single.t)
        np.testing.assert_array_equal(arcs[i].x, single.x)
        assert arcs[i].stats == single.stats
        ref = hs.simulate(pend, x0s[i], method="DOP853", **kw)
        assert arcs[i].termination is ref.termination and arcs[i].jump_count == ref.jump_count
        np.testing.assert_allclose(arcs[i].jump_times, ref.jump_times, rtol=0, atol=1e-9)
        np.testing.assert_allclose(arcs[i].xf, ref.xf, rtol=1e-8, atol=1e-9)
        # far fewer steps than RK45 at this tolerance
        rk = simulate_compiled(pend, x0s[i], **kw)
        assert arcs[i].stats["steps"] < rk.stats["steps"] / 2
    sizes = pend.__dict__["_batch_lengths"]
    assert {k[0] for k in sizes} == {"DOP853"}
    simulate_many_compiled(pend, x0s, **kw)
    assert {k[0] for k in sizes} == {"DOP853", "RK45"}


def _timer_batch(monkeypatch):
    """A timer whose period is in its state, 70 rows: rows 40, 50 and 60 jump
    2,000 times, the others twice; its pools sized by a batch of two short
    rows. Returns the timer, the rows' x0 and the list the batch kernel's
    rounds are counted in."""
    timer = CompiledSystem(flow_map=lambda x, t, j, p: np.array([1.0, 0.0]),
                           jump_map=lambda x, t, j, p: np.array([0.0, x[1]]),
                           jump_guard=lambda x, t, j, p: x[0] - x[1], state_dim=2)
    period = np.full(70, 1.0)
    period[[40, 50, 60]] = 1e-3
    x0s = np.column_stack([np.zeros(70), period])
    simulate_many_compiled(timer, x0s[:2], t_max=2.5)
    calls = []
    real = hc._run._interruptible
    monkeypatch.setattr(hc._run, "_interruptible", lambda *a, **k: calls.append(1) or real(*a, **k))
    return timer, x0s, calls


def test_batch_runs_without_room_in_the_pool_run_again_in_parallel(monkeypatch):
    # a timer whose period is in its state: the rows that size the pool (the
    # warm-up batch's, whose length the batch reuses) jump twice, rows 40, 50
    # and 60 2,000 times, far more samples than the pool holds; those rows run
    # again in a second round of the batch kernel, and every arc is its single
    # run's, bit for bit
    timer, x0s, calls = _timer_batch(monkeypatch)
    arcs = simulate_many_compiled(timer, x0s, t_max=2.5)
    assert len(calls) == 2                      # the batch, then the rows without room
    assert [arcs[i].jump_count for i in (0, 23, 46, 69)] == [2] * 4
    assert all(arcs[i].jump_count > 2000 for i in (40, 50, 60))
    for i in (0, 39, 40, 41, 50, 60, 69):
        single = simulate_compiled(timer, x0s[i], t_max=2.5)
        np.testing.assert_array_equal(arcs[i].t, single.t)
        np.testing.assert_array_equal(arcs[i].j, single.j)
        np.testing.assert_array_equal(arcs[i].x, single.x)
        assert arcs[i].stats == single.stats and arcs[i].termination is single.termination


def test_the_next_batch_sizes_its_pools_for_the_longest_run_seen(monkeypatch):
    # the timer of the test above: sized by two short rows, a batch whose rows
    # 40, 50, 60 jump 2,000 times runs them again for want of room; the same
    # batch again has room for them at once (one round of the batch kernel)
    timer, x0s, calls = _timer_batch(monkeypatch)
    first = simulate_many_compiled(timer, x0s, t_max=2.5)
    assert len(calls) == 2
    (sizes,) = [timer.__dict__["_batch_lengths"]]
    assert max(sizes.values()) == max(len(a.t) for a in first)
    again = simulate_many_compiled(timer, x0s, t_max=2.5)
    assert len(calls) == 3                      # no second round
    for i in (0, 40, 69):
        np.testing.assert_array_equal(first[i].t, again[i].t)
        np.testing.assert_array_equal(first[i].x, again[i].x)


def test_a_batch_again_reuses_the_pools_size_and_runs_every_row_in_parallel(monkeypatch):
    """The first batch sizes its pools by four runs alone (single-run arcs);
    the same system, options and parameters again take that size and run all
    rows in the batch kernel; other options or parameters size again. The arcs
    are the same to the bit either way."""
    def make(e):
        return _compiled(CompiledSystem(ball_f, ball_g, jump_guard=ball_hD, flow_guard=ball_hC,
                                        jump_set=ball_D, flow_set=ball_C, state_dim=2,
                                        params=[9.81, e]))
    ball = make(0.8)
    h0 = np.random.default_rng(4).uniform(0.5, 2.0, 64)
    x0s = np.column_stack([h0, np.zeros_like(h0)])
    alone = []
    real = hc._run._arc
    monkeypatch.setattr(hc._run, "_arc", lambda *a, **k: alone.append(1) or real(*a, **k))
    sized = [simulate_many_compiled(ball, x0s, t_max=20.0, j_max=5, **TIGHT)]
    assert len(alone) == 4
    sized.append(simulate_many_compiled(ball, x0s[::-1], t_max=20.0, j_max=5, **TIGHT))
    assert len(alone) == 4                          # no run alone: the size reused
    for a, b in zip(sized[0], sized[1][::-1]):
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.xdot, b.xdot)
        assert a.stats == b.stats and a.termination is b.termination
    simulate_many_compiled(ball, x0s, t_max=20.0, j_max=6, **TIGHT)
    assert len(alone) == 8                          # other options: sized again
    ball.params = [9.81, 0.5]       # the same system, other parameters
    simulate_many_compiled(ball, x0s, t_max=20.0, j_max=5, **TIGHT)
    assert len(alone) == 12                         # other parameters: sized again
    assert "_batch_lengths" not in pickle.loads(pickle.dumps(ball)).__dict__


def mixed_f(x, t, j, p):
    return np.array([1.0, x[1]])


def mixed_g(x, t, j, p):
    return np.array([0.0, x[1]])


def mixed_hD(x, t, j, p):
    return x[0] - 1.0


def test_batch_members_ending_differently_agree_with_single_runs():
    """One parallel batch whose rows end T_MAX, J_MAX, BLOWUP and NON_FINITE (a
    timer z and a growing r = r0 e^t): each row's arc is the single run's, to
    the bit (the batch's worker threads read private copies of the options and
    poll nothing but the stop flag), and the Python path's."""
    mixed = _compiled(CompiledSystem(mixed_f, mixed_g, jump_guard=mixed_hD, state_dim=2))
    base = np.array([[0.0, 0.0],       # jumps at 1, 2; flows on to t_max
                     [0.9, 0.0],       # jumps at 0.1, 1.1, 2.1: the third is j_max
                     [0.0, 1e5],       # jumps at 1, 2; r > 1e6 at t = ln 10: BLOWUP
                     [0.2, 1.0],       # jumps at 0.8, 1.8; T_MAX
                     [np.nan, 0.0]])   # its own NON_FINITE arc
    x0s = np.tile(base, (13, 1))
    kw = dict(t_max=2.5, j_max=3, max_norm=1e6)
    with pytest.warns(hs.BatchWarning):
        arcs = simulate_many_compiled(mixed, x0s, **kw)
    want = [T.T_MAX, T.J_MAX, T.BLOWUP, T.T_MAX, T.NON_FINITE]
    assert [a.termination for a in arcs] == want * 13
    for i, arc in enumerate(arcs):
        if i % 5 == 4:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", hs.SimulationWarning)
            single = simulate_compiled(mixed, x0s[i], **kw)
            ref = hs.simulate(mixed, x0s[i], **kw)
        np.testing.assert_array_equal(arc.t, single.t)
        np.testing.assert_array_equal(arc.x, single.x)
        np.testing.assert_array_equal(arc.xdot, single.xdot)
        assert arc.termination is single.termination and arc.stats == single.stats
        assert_agree(arc, ref, tol=1e-5, jt_tol=1e-9)


def test_batch_bad_arguments(ball):
    with pytest.raises(ValueError, match="x0s"):
        simulate_many_compiled(ball, np.zeros((3, 3)), t_max=1.0)
    with pytest.raises(ValueError, match="t_max"):
        simulate_many_compiled(ball, np.zeros((3, 2)), t_max=-1.0)


# ------------------------------------------------------------------ errors and form
def test_bad_arguments_name_themselves(ball):
    with pytest.raises(ValueError, match="x0"):
        simulate_compiled(ball, [1.0, 2.0, 3.0], t_max=1.0)
    with pytest.raises(ValueError, match="priority"):
        simulate_compiled(ball, [1.0, 0.0], t_max=1.0, priority="often")
    with pytest.raises(ValueError, match="method"):
        simulate_compiled(ball, [1.0, 0.0], t_max=1.0, method="Radau")
    with pytest.raises(ValueError, match="inputs=.*not supported on the compiled path"):
        simulate_compiled(ball, [1.0, 0.0], t_max=1.0, inputs=lambda t: 0.0)
    with pytest.raises(TypeError, match="unexpected keyword argument 'tmax'"):
        simulate_compiled(ball, [1.0, 0.0], t_max=1.0, tmax=2.0)
    with pytest.raises(TypeError, match="CompiledSystem"):
        simulate_compiled(BouncingBall(), [1.0, 0.0], t_max=1.0)
    with pytest.raises(TypeError, match="flow"):
        CompiledSystem(jump_map=zero, state_dim=1)


def test_options_parsed_once_still_refuse_an_equal_value_of_another_type(ball):
    """Repeated options are parsed once per system (a memo keyed by their
    values); 1 and 1.0 equal True as keys, not as options: after a run with
    throw=True (and t_max=1.0), throw=1 and t_max=True get the errors a first
    call gets, and a run with equal options of another type is parsed anew."""
    simulate_compiled(ball, [1.0, 0.0], t_max=1.0, throw=True)
    for bad in (1, 1.0):
        with pytest.raises(TypeError, match="throw must be True or False"):
            simulate_compiled(ball, [1.0, 0.0], t_max=1.0, throw=bad)
    simulate_compiled(ball, [1.0, 0.0], t_max=1, j_max=3)
    with pytest.raises(TypeError, match="t_max must be a real number, got bool"):
        simulate_compiled(ball, [1.0, 0.0], t_max=True, j_max=3)
    a = simulate_compiled(ball, [1.0, 0.0], t_max=2.0, j_max=3)
    b = simulate_compiled(ball, [1.0, 0.0], t_max=2, j_max=3.0)
    np.testing.assert_array_equal(a.t, b.t)


def test_uncompilable_map_names_itself_and_the_fallback():
    class Opaque:
        pass
    thing = Opaque()

    def flow(x, t, j, p):
        return np.array([len(thing.__dict__) + 0.0])    # a Python object: not compilable

    sysobj = CompiledSystem(flow, state_dim=1)
    with pytest.raises(CompileError) as e:
        simulate_compiled(sysobj, [0.0], t_max=1.0)
    msg = str(e.value)
    assert "'flow_map'" in msg and "hs.simulate" in msg and e.value.map_name == "flow_map"
    assert isinstance(e.value.__cause__, numba.core.errors.NumbaError)
    arc = hs.simulate(sysobj, [0.0], t_max=1.0)      # the Python path runs it
    assert arc.termination is T.T_MAX
    with pytest.raises(CompileError, match="'jump_guard'.*a float"):
        CompiledSystem(one, zero, jump_guard=lambda x, t, j, p: "high",
                       state_dim=1).compile()


def test_maps_may_return_tuples_and_vector_guards():
    sysobj = _compiled(CompiledSystem(
        lambda x, t, j, p: (1.0, 2.0), lambda x, t, j, p: (0.0, 0.0),
        jump_guard=lambda x, t, j, p: np.array([x[0] - 1.0, x[1] - 2.0]),
        state_dim=2))
    a, b = both(sysobj, [0.0, 0.0], t_max=2.5)
    assert_agree(a, b)
    np.testing.assert_allclose(a.jump_times, [1.0, 2.0], atol=1e-12)


def test_pickle_round_trip(ball):
    again = pickle.loads(pickle.dumps(ball))
    assert again._nb is None
    a = simulate_compiled(again, [1.0, 0.0], t_max=2.0, j_max=3)
    b = simulate_compiled(ball, [1.0, 0.0], t_max=2.0, j_max=3)
    np.testing.assert_array_equal(a.x, b.x)


def test_runs_free_every_array_they_make():
    """The leaf helpers of the event search run without numba's reference
    counting (``_kernel._NJL``), the maps and the rest of the kernel with it:
    numba's allocation statistics (on in a fresh process) balance after runs
    through every part of the search (events on guards and on indicators,
    a guard that makes arrays, an excursion within one step found by the
    interior search, refined samples, random priority, a batch), and a second
    round of the same runs allocates exactly what the first did."""
    code = """
import gc, sys, numpy as np
from numba.core.runtime import rtsys
from hybridsim.compiled import CompiledSystem, simulate_compiled, simulate_many_compiled
f = lambda x, t, j, p: np.array([x[1], -p[0]])
g = lambda x, t, j, p: np.array([0.0, -p[1] * x[1]])
hD = lambda x, t, j, p: np.min(np.array([-x[0], 1.0]))     # makes an array
hC = lambda x, t, j, p: x[0]
D = lambda x, t, j, p: x[0] <= 0.0 and x[1] <= 0.0
ball = CompiledSystem(f, g, jump_guard=hD, flow_guard=hC, jump_set=D, state_dim=2,
                      params=[9.81, 0.8])
ball_sets = CompiledSystem(f, g, flow_set=lambda x, t, j, p: x[0] >= 0.0, jump_set=D,
                           state_dim=2, params=[9.81, 0.8])
apex = CompiledSystem(lambda x, t, j, p: np.array([x[1], -1.0]),
                      lambda x, t, j, p: np.array([0.0, p[0]]),
                      jump_guard=lambda x, t, j, p: x[0] - 1.0,
                      jump_set=lambda x, t, j, p: x[0] >= 1.0, state_dim=2,
                      params=[np.sqrt(2.0 + 2e-6)])
X0 = np.column_stack([np.linspace(0.5, 2.0, 40), np.zeros(40)])
def runs():
    out = [simulate_compiled(ball, [1.0, 0.0], t_max=20.0, j_max=30, rtol=1e-8),
           simulate_compiled(ball, [1.0, 0.0], t_max=5.0, j_max=8, refine=4),
           simulate_compiled(ball, [1.0, 0.0], t_max=5.0, j_max=8, priority="random",
                             seed=1),
           simulate_compiled(ball_sets, [1.0, 0.0], t_max=5.0, j_max=8),
           simulate_compiled(apex, [0.0, apex.params[0]], t_max=3.0 * apex.params[0],
                             j_max=2),
           simulate_compiled(ball, [1.0, 0.0], t_max=5.0, j_max=8, method="DOP853"),
           *simulate_many_compiled(ball, X0, t_max=5.0, j_max=10)]
    assert out[4].jump_count == 2 and out[0].jump_count == 30
    return [len(a.t) for a in out]
runs()                                   # compiled (or loaded), maps included
del_stats = []
for _ in range(2):
    gc.collect()
    a = rtsys.get_allocation_stats()
    n = runs()
    gc.collect()
    b = rtsys.get_allocation_stats()
    del_stats.append((b.alloc - a.alloc, b.free - a.free, b.mi_alloc - a.mi_alloc,
                      b.mi_free - a.mi_free))
print(del_stats)
"""
    env = dict(os.environ, NUMBA_NRT_STATS="1")
    out = subprocess.run([sys.executable, "-W", "ignore", "-c", code], capture_output=True,
                         text=True, timeout=600, env=env)
    assert out.returncode == 0, out.stderr[-3000:]
    (a1, f1, m1, mf1), (a2, f2, m2, mf2) = eval(out.stdout.strip().splitlines()[-1])
    assert a1 > 0 and a1 == f1 and m1 == mf1, out.stdout
    assert (a2, f2, m2, mf2) == (a1, f1, m1, mf1), out.stdout


def test_without_numba_import_error_names_the_extra():
    code = ("import sys; sys.modules['numba'] = None\n"
            "import numpy as np, hybridsim as hs\n"
            "from hybridsim.compiled import CompiledSystem, simulate_compiled, available\n"
            "s = CompiledSystem(lambda x, t, j, p: np.ones(1), state_dim=1)\n"
            "assert not available()\n"
            "assert hs.simulate(s, [0.0], t_max=1.0).termination.name == 'T_MAX'\n"
            "try:\n"
            "    simulate_compiled(s, [0.0], t_max=1.0)\n"
            "except ImportError as e:\n"
            "    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert "pip install 'hybridsim[fast]'" in out.stdout
    assert "hs.simulate" in out.stdout


def test_doctests():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for mod in (hc, hc._run):       # (CompiledSystem is hc's: its __module__)
            res = doctest.testmod(mod, optionflags=doctest.NORMALIZE_WHITESPACE)
            assert res.failed == 0 and res.attempted > 0, mod.__name__


# ------------------------------------------------------------------ one source of rules
def test_same_bad_input_same_error_as_the_python_path(ball):
    """Validation is ``hybridsim.options.parse_run``'s on both paths."""
    bad = [dict(t_max=-1.0), dict(t_max=1.0, rtol=0.0), dict(t_max=1.0, zeno_jumps=0),
           dict(t_max=1.0, refine=2.5), dict(t_max=1.0, j_max=True),
           dict(t_max=1.0, priority="often"), dict(t_max=1.0, throw=1),
           dict(t_max=1.0, max_samples=1)]
    for kw in bad:
        errs = []
        for run in (simulate_compiled, hs.simulate):
            with pytest.raises(Exception) as e:
                run(ball, [1.0, 0.0], **kw)
            errs.append(e.value)
        assert type(errs[0]) is type(errs[1]) and str(errs[0]) == str(errs[1]), kw


def test_cause_codes_and_rules_come_from_rules():
    from hybridsim import rules
    from hybridsim.compiled import _types as k
    assert k.CAUSES == tuple(c.name for c in rules.CAUSES)
    for name in k.CAUSES:
        assert getattr(k, name) == rules.CODES[T[name]]
    assert not hasattr(k, "_is_sticking_local") and not hasattr(hc, "_CAUSES")
    assert not hasattr(hc, "_finish")


@pytest.mark.parametrize("kw, cause", [
    (dict(t_max=50.0, max_norm=1e6), T.BLOWUP),
    (dict(t_max=50.0, max_steps=7), T.MAX_STEPS),
    (dict(t_max=50.0, max_samples=5), T.MAX_STEPS),
])
def test_messages_are_the_python_paths(kw, cause):
    grow = _compiled(CompiledSystem(grow_f, state_dim=1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a, b = both(grow, [1.0], **kw)
    assert a.termination is b.termination is cause
    if "max_norm" not in kw:              # |x| at the step differs in the last digits
        # the same words and numbers; the step ends agree to 1e-8 relative, not to every
        # printed digit: x' = x's error estimate cancels (sum of E_i = 0 over stages
        # that are nearly equal), so its rounding (numba may fuse multiply-adds where
        # numpy does not) moves each step size by ~1e-9 (seen: t = 1.528471786 vs 787)
        num = r"[-+]?\d+\.?\d*(?:e[-+]?\d+)?"
        assert re.sub(num, "#", a.message) == re.sub(num, "#", b.message)
        np.testing.assert_allclose([float(v) for v in re.findall(num, a.message)],
                                   [float(v) for v in re.findall(num, b.message)], rtol=1e-8)


def test_messages_zeno_left_sets_not_in_sets(ball, leave):
    a, b = both(ball, [1.0, 0.0], t_max=10.0)
    assert a.termination is T.ZENO and a.message.split(" near t=")[0] == \
        b.message.split(" near t=")[0]
    a, b = both(leave, [0.0], t_max=5.0)
    assert a.message == b.message
    a, b = both(ball, [-1.0, 1.0], t_max=1.0)
    assert a.message == b.message


def test_map_error_at_x0_carries_a_map_error_arc():
    bad = _compiled(CompiledSystem(lambda x, t, j, p: np.array([np.nan]), state_dim=1))
    with pytest.raises(hs.MapError, match="flow_map returned non-finite") as e:
        simulate_compiled(bad, [0.0], t_max=1.0, throw=False)
    assert e.value.arc.termination is T.MAP_ERROR and e.value.map_name == "flow_map"
    with pytest.raises(hs.MapError) as ref:
        hs.simulate(bad, [0.0], t_max=1.0)
    assert str(e.value) == str(ref.value)


# ------------------------------------------------------------------ Ctrl-C, fork
# One SIGINT, raised once the batch has been under way for 0.1 s (no clock before
# it: paths.one_sigint_inside_the_run); max_samples bounds the memory of a run the
# signal would not reach (each row ends MAX_SAMPLES then, and the test fails).


def test_ctrl_c_during_a_parallel_batch_keeps_the_finished_rows(timer):
    from paths import one_sigint_inside_the_run
    timer.params = [1e-3]
    try:
        simulate_many_compiled(timer, np.zeros((8, 1)), t_max=0.1)     # compiled first
        X = np.zeros((40, 1))
        with one_sigint_inside_the_run(settle=0.1) as sig, \
                pytest.warns(hs.BatchWarning, match="interrupted"):
            arcs = simulate_many_compiled(timer, X, t_max=math.inf, j_max=10**9,
                                          max_samples=2 * 10**6, max_steps=10**9)
    finally:
        timer.params = [1.0]
    assert sig.sent, "no batch was seen under way"
    assert len(arcs) == 40
    assert all(a.termination is T.CANCELED for a in arcs), {a.termination for a in arcs}
    assert any(a.jump_count > 0 for a in arcs)


def test_ctrl_c_during_a_serial_batch(timer):
    from paths import one_sigint_inside_the_run
    timer.params = [1e-3]
    try:
        with one_sigint_inside_the_run(settle=0.1) as sig, \
                pytest.warns(hs.BatchWarning, match="interrupted"):
            arcs = simulate_many_compiled(timer, np.zeros((3, 1)), t_max=math.inf,
                                          j_max=10**9, parallel=False,
                                          max_samples=2 * 10**6, max_steps=10**9)
    finally:
        timer.params = [1.0]
    assert sig.sent, "no batch was seen under way"
    assert arcs[0].termination is T.CANCELED and arcs[0].jump_count > 0
    assert arcs[1].termination is T.CANCELED and len(arcs[1].t) == 1
    assert "never started" in arcs[2].message


def test_fork_after_a_parallel_batch(ball):
    """A fork-based process pool after a parallel batch (GNU OpenMP would abort
    the child; the batch's threads are Python threads, no numba threading layer)."""
    code = (
        "import multiprocessing as mp, numpy as np\n"
        "from hybridsim.compiled import CompiledSystem, simulate_many_compiled\n"
        "s = CompiledSystem(lambda x, t, j, p: np.ones(1), lambda x, t, j, p: np.zeros(1),\n"
        "                   jump_guard=lambda x, t, j, p: x[0] - 1.0, state_dim=1)\n"
        "simulate_many_compiled(s, np.zeros((200, 1)), t_max=3.0)\n"
        "from numba.np.ufunc import parallel as P; print('layer started', P._is_initialized)\n"
        "def work(i):\n"
        "    return len(simulate_many_compiled(s, np.zeros((50, 1)), t_max=3.0))\n"
        "with mp.get_context('fork').Pool(2) as pool:\n"
        "    print(pool.map(work, range(2)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert "[50, 50]" in out.stdout
    assert "layer started False" in out.stdout


# ------------------------------------------------------------------ first compile
def test_first_compile_says_so_once(tmp_path):
    """A fresh cache: one notice naming the cache (a batch after the first
    run compiles the small batch kernel without another; the first system
    with delays, its own kernel with its own); the next process: none."""
    import os
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    code = ("import numpy as np\n"
            "from hybridsim.compiled import CompiledSystem, simulate_compiled, "
            "simulate_many_compiled\n"
            "s = CompiledSystem(lambda x, t, j, p: np.ones(1), state_dim=1)\n"
            "simulate_compiled(s, [0.0], t_max=1.0)\n"
            "simulate_compiled(s, [0.0], t_max=1.0)\n"
            "simulate_many_compiled(s, np.zeros((20, 1)), t_max=1.0)\n"
            "lag = CompiledSystem(lambda x, t, j, p: -p[0:1], state_dim=1, delays=(0.5,))\n"
            "simulate_compiled(lag, [1.0], t_max=1.0)\n")
    runs = [subprocess.run([sys.executable, "-W", "ignore", "-c", code], capture_output=True,
                           text=True, timeout=600, env=env) for _ in range(2)]
    for r in runs:
        assert r.returncode == 0, r.stderr
    assert runs[0].stderr.count("compiling the engine's kernels,") == 1
    # the kernel for flow maps that read the past: its own notice, when first needed
    assert runs[0].stderr.count("compiling the engine's kernels for flow maps with delays") == 1
    assert str(tmp_path) in runs[0].stderr
    assert "compiling" not in runs[1].stderr


# ------------------------------------------------------------------ a map that raises
def raises_above(x, t, j, p):
    """A flow map numba compiles with its ``raise``: above p[0] it raises."""
    if x[0] > p[0]:
        raise ValueError("x above its range")
    return np.array([1.0])


def clock_jump_set_raises(x, t, j, p):
    if x[0] > p[0]:
        raise KeyError("no set there")
    return x[0] >= 5.0


@pytest.mark.parametrize("role", ["flow", "jump_set"])
def test_a_map_that_raises_is_map_error_with_its_exception(role):
    """A compiled map's ``raise`` ends the run ``MAP_ERROR`` naming the map, its
    exception class and text, the run so far kept; a raising set indicator no
    longer lets the run go on with the value numba's wrapper leaves."""
    kw = {"flow_map": raises_above} if role == "flow" else {
        "flow_map": lambda x, t, j, p: np.array([1.0]), "jump_set": clock_jump_set_raises,
        "jump_map": lambda x, t, j, p: np.zeros(1)}
    sysm = CompiledSystem(state_dim=1, params=[0.5], **kw)
    name, exc, text = (("flow_map", "ValueError", "x above its range") if role == "flow"
                       else ("jump_set", "KeyError", "'no set there'"))
    arc = simulate_compiled(sysm, [0.0], t_max=2.0, max_step=0.1, throw=False)
    assert arc.termination is T.MAP_ERROR
    assert f"{name} raised {exc}: {text}" in arc.message and "non-finite" not in arc.message
    assert arc.exception.map_name == name and type(arc.exception.__cause__).__name__ == exc
    # the run so far: its samples up to where the map raised (x = t <= 0.5 + one step)
    assert len(arc.t) > 3 and arc.t[-1] <= 0.6 + 1e-12 and arc.t[-2] <= 0.5 + 1e-12
    np.testing.assert_allclose(arc.x[:, 0], arc.t, rtol=0, atol=1e-12)
    with pytest.raises(hs.MapError, match=f"{name} raised {exc}"):
        simulate_compiled(sysm, [0.0], t_max=2.0, max_step=0.1)
    # a batch: the row whose map raises says so, the others run to t_max
    arcs = simulate_many_compiled(sysm, [[0.45], [-30.0]] * 8, t_max=2.0, max_step=0.1,
                                  warn=False)
    for a in arcs[0::2]:
        assert a.termination is T.MAP_ERROR and f"{name} raised {exc}" in a.message
    for a in arcs[1::2]:
        assert a.termination is T.T_MAX and a.exception is None
    assert sys.unraisablehook is not hc._run._unraisable     # put back after each run


def test_a_map_that_raises_at_x0_raises_at_once():
    """As on the Python path: a flow map that raises at x0 is bad input, raised
    whatever ``throw`` says, with the exception's text and a one-sample arc."""
    sysm = CompiledSystem(state_dim=1, params=[-1.0], flow_map=raises_above)
    with pytest.raises(hs.MapError, match="flow_map raised ValueError: x above its range") as e:
        simulate_compiled(sysm, [0.0], t_max=1.0, throw=False)
    assert e.value.arc.termination is T.MAP_ERROR and len(e.value.arc.t) == 1
