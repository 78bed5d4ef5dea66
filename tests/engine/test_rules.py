"""One source of the engine's rules (issue 15): the decision, the Zeno test and
the t_max slack of :mod:`hybridsim.rules`, and single runs against batches.

The vectorized batch integrator and :func:`hybridsim.simulate` take their
semantics from :mod:`hybridsim.rules`; these tests check that the two paths
agree on random balls, timers and thermostats (hypothesis), on the issue-16
edge cases (a jump set entered and left within one step, jumps at t_max), and
that the rules' scalar and array forms agree everywhere.
"""
import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hybridsim as hs
from hybridsim import rules
from hybridsim.library import BouncingBall

FAST = settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ------------------------------------------------------------ the rules alone
def test_decision_scalar_and_array_forms_agree_everywhere():
    combos = list(itertools.product([False, True], repeat=4))
    for prio in rules.Priority:
        C, D, coin, forced = (np.array(v) for v in zip(*combos))
        mask = rules.jumps_now(C, D, prio, coin, forced)
        ask = rules.needs_coin(C, D, prio, forced)
        for k, (c, d, co, f) in enumerate(combos):
            action = rules.decide(c, d, prio, co, f)
            assert (action == rules.Action.JUMP) == bool(mask[k])
            assert bool(ask[k]) == (prio == rules.Priority.RANDOM and c and d and not f)
            if action != rules.Action.JUMP:
                assert action == (rules.Action.FLOW if c else rules.Action.STOP)


def test_decision_table():
    P, A = rules.Priority, rules.Action
    # in C ∩ D: the priority decides; outside C: jump if in D, else stop
    assert rules.decide(True, True, P.JUMPS, False) == A.JUMP
    assert rules.decide(True, True, P.FLOWS, False) == A.FLOW
    assert rules.decide(True, True, P.FLOWS, False, forced=True) == A.JUMP
    assert rules.decide(True, True, P.RANDOM, True) == A.JUMP
    assert rules.decide(True, True, P.RANDOM, False) == A.FLOW
    assert rules.decide(False, True, P.FLOWS, False) == A.JUMP
    assert rules.decide(False, False, P.JUMPS, False) == A.STOP
    assert rules.decide(True, False, P.JUMPS, True) == A.FLOW


def test_t_max_slack_grows_with_jumps():
    eps = np.finfo(float).eps
    assert rules.t_max_slack(1.0) == 64 * eps
    assert rules.t_max_slack(10.0, 100) == 4 * eps * 10 * 216


def test_failure_flags():
    T = hs.Termination
    assert {c for c in T if c.failure} == {T.MAP_ERROR, T.NON_FINITE, T.SOLVER_FAILED,
                                           T.BLOWUP}
    assert {c for c in T if c.success} == {T.T_MAX, T.J_MAX}


# ------------------------------------------------- single runs against batches
def vtimer(period):
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), jump_map=lambda x: np.zeros_like(x),
        jump_guard=lambda x: x[:, 0] - period, flow_guard=lambda x: period - x[:, 0],
        state_dim=1, vectorized=True)


def stimer(period):
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones(1), jump_map=lambda x: np.zeros(1),
        jump_guard=lambda x: x[0] - period, flow_guard=lambda x: period - x[0], state_dim=1)


def thermostat(vectorized, lo, hi, a):
    """Heating (q = 1) towards 30 until T >= hi, cooling towards 0 until T <= lo."""
    if vectorized:
        return hs.HybridSystem.from_functions(
            flow_map=lambda x: np.stack([-a * x[:, 0] + a * 30 * x[:, 1], 0 * x[:, 1]], axis=1),
            jump_map=lambda x: np.stack([x[:, 0], 1 - x[:, 1]], axis=1),
            jump_guard=lambda x: np.where(x[:, 1] > 0.5, x[:, 0] - hi, lo - x[:, 0]),
            state_dim=2, vectorized=True)
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([-a * x[0] + a * 30 * x[1], 0.0]),
        jump_map=lambda x: np.array([x[0], 1 - x[1]]),
        jump_guard=lambda x: x[0] - hi if x[1] > 0.5 else lo - x[0], state_dim=2)


def assert_same(single, batch, tol):
    assert single.termination is batch.termination
    assert single.jump_count == batch.jump_count
    np.testing.assert_allclose(batch.jump_times, single.jump_times, rtol=0, atol=tol)
    np.testing.assert_allclose(batch.xf, single.xf, rtol=1e-9, atol=tol)


@FAST
@given(h0=st.lists(st.floats(0.1, 10.0), min_size=1, max_size=4),
       e=st.floats(0.3, 0.9), g=st.floats(2.0, 20.0))
def test_single_runs_and_batches_agree_on_balls(h0, e, g):
    x0s = np.column_stack([h0, np.zeros(len(h0))])
    batch = hs.simulate_vectorized(BouncingBall(g, e, vectorized=True), x0s, t_max=math.inf,
                                   j_max=8, rtol=1e-10, atol=1e-12)
    for x0, arc in zip(x0s, batch):
        single = hs.simulate(BouncingBall(g, e), x0, t_max=math.inf, j_max=8, rtol=1e-10,
                             atol=1e-12)
        assert_same(single, arc, 1e-12)


@FAST
@given(period=st.floats(0.01, 5.0), x0=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=4),
       n=st.integers(1, 12))
def test_single_runs_and_batches_agree_on_timers(period, x0, n):
    x0s = np.array(x0)[:, None] * period
    t_max = n * period                   # jumps of the x0 = 0 rows land on t_max
    batch = hs.simulate_vectorized(vtimer(period), x0s, t_max=t_max)
    for x, arc in zip(x0s, batch):
        single = hs.simulate(stimer(period), x, t_max=t_max)
        assert_same(single, arc, 1e-12 * max(1.0, t_max))


@pytest.mark.slow
@FAST
@given(lo=st.floats(15.0, 19.0), gap=st.floats(0.5, 5.0), a=st.floats(0.1, 2.0),
       T0=st.lists(st.floats(16.0, 25.0), min_size=1, max_size=3))
def test_single_runs_and_batches_agree_on_thermostats(lo, gap, a, T0):
    hi = lo + gap
    x0s = np.column_stack([np.clip(T0, lo, hi), np.ones(len(T0))])
    batch = hs.simulate_vectorized(thermostat(True, lo, hi, a), x0s, t_max=6.0, rtol=1e-9,
                                   atol=1e-11)
    for x0, arc in zip(x0s, batch):
        single = hs.simulate(thermostat(False, lo, hi, a), x0, t_max=6.0, rtol=1e-9,
                             atol=1e-11)
        assert_same(single, arc, 1e-9)


@pytest.mark.parametrize("d", [0.3, 1e-3, 1e-6])
def test_batches_find_a_jump_set_entered_and_left_within_one_step(d):
    sysv = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.stack([x[:, 1], -np.ones(len(x))], axis=1),
        jump_map=lambda x: np.stack([x[:, 0], -np.abs(x[:, 1])], axis=1),
        jump_guard=lambda x: x[:, 0] - 1.0, state_dim=2, vectorized=True)
    v0 = math.sqrt(2.0 * (1.0 + d))
    arc, = hs.simulate_vectorized(sysv, [[0.0, v0]], t_max=1.5 * v0, j_max=1)
    assert arc.jump_count == 1
    assert abs(arc.jump_times[0] - (v0 - math.sqrt(v0 * v0 - 2.0))) < 1e-9


@pytest.mark.parametrize("period", [0.1, 0.25, 1.0, 1.0 / 3.0])
def test_batches_take_the_jump_at_t_max(period):
    arcs = hs.simulate_vectorized(vtimer(period), [[0.0], [0.0]], t_max=1.0)
    for arc in arcs:
        assert arc.jump_count == round(1.0 / period) and arc.tf == 1.0


def test_post_jump_probe_undoes_the_flow_over_the_event_bracket():
    import numpy as np

    from hybridsim.rules import post_jump_probe
    x_lo, x_hi = np.array([3e-16, -2.0]), np.array([-6e-16, -2.0])
    x_plus = np.array([-6e-16, 1.6])            # position kept, velocity reflected
    t, x = post_jump_probe(x_plus, 0.25, x_lo, x_hi)
    assert t == 0.25 and abs(x[0] - 3e-16) < 1e-30 and x[1] == 1.6
    # far outside C stays outside
    t, x = post_jump_probe(np.array([-1e-9, 1.6]), 0.25, x_lo, x_hi)
    assert x[0] < 0


def test_jump_loop_threshold_and_messages():
    from hybridsim.rules import DETAILS, LOOP_JUMPS, Termination, is_jump_loop, message
    assert not is_jump_loop(LOOP_JUMPS - 1, 50) and is_jump_loop(LOOP_JUMPS, 50)
    assert is_jump_loop(3, 3) and not is_jump_loop(2, 3)
    for cause in (Termination.J_MAX, Termination.ZENO):
        assert (cause, "loop") in DETAILS
        text = message(cause, "loop", count=30, t=0.4515)
        assert text.startswith(cause.message) and "last 30 jumps were all at t=0.4515" in text
        assert "D = {guard >= 0}" in text
    assert "dense output" in message(Termination.NON_FINITE, "dense", t=0.0, t2=1.0, j=0)
