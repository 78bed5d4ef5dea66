"""Guards derived from set indicators (hybridsim._source.derived_guard).

A set built from comparisons, and/or/not (&, |, ~) and if/else gets a signed
guard: positive only inside the set, negative only outside it, zero on its
boundary (where the indicator decides). The engine then locates events by
root finding and searches each step's interior with the guard's peaks, and
sensitivities are defined, for systems that give indicators alone.
"""
from __future__ import annotations

import copy
import math
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hybridsim as hs
from hybridsim._source import derived_guard, guard_refusal
from hybridsim.library import bouncing_ball_jump_times

G, E = 9.81, 0.8


class ReadmeBall(hs.HybridSystem):
    """README's ten-line bouncing ball, indicators only."""
    state_dim = 2

    def flow_map(self, x):  return np.array([x[1], -9.81])
    def jump_map(self, x):  return np.array([0.0, -0.8 * x[1]])
    def flow_set(self, x):  return x[0] >= 0
    def jump_set(self, x):  return x[0] <= 0 and x[1] <= 0


class HandBall(ReadmeBall):
    """The same ball with the guards written by hand."""

    def jump_guard(self, x):
        return -x[0]

    def flow_guard(self, x):
        return x[0]


# ------------------------------------------------------------ agreement with the set
SETS = [
    lambda x: x[0] >= 0,
    lambda x: x[0] <= 0 and x[1] <= 0,
    lambda x: 0.0 <= x[0] <= 1.0,
    lambda x: not (x[0] > 1.0) or x[1] < -x[0],
    lambda x: (x[0] >= 0.5 if x[1] > 0 else x[0] <= -0.5) and not x[1] >= 3.0,
    lambda x: (x[0] >= x[1]) & ~(x[1] > 2.0) | (x[0] < -1.0),
]


def _signs_agree(S, h, x):
    """The boundary convention: h > 0 only in the set, h < 0 only outside it."""
    inside, v = bool(S(x)), float(h(x))
    return (inside or v <= 0.0) and (not inside or v >= 0.0)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(-5.0, 5.0, allow_nan=False, width=64), min_size=2, max_size=2),
       st.sampled_from(range(len(SETS))))
def test_a_derived_guard_agrees_with_its_set_on_random_states(x, k):
    system = hs.HybridSystem.from_functions(flow_map=lambda x: -x, jump_set=SETS[k],
                                            flow_set=SETS[k], state_dim=2)
    x = np.array(x)
    for h, S in ((system.jump_guard, SETS[k]), (system.flow_guard, SETS[k])):
        assert h is not None
        assert _signs_agree(S, h, x), (k, x, h(x))
        # a non-strict comparison is exact: {h >= 0} is the set itself there
    if k in (0, 1, 2):
        assert bool(SETS[k](x)) == (system.jump_guard(x) >= 0.0)


@settings(max_examples=100, deadline=None)
@given(st.floats(-3.0, 3.0, allow_nan=False), st.floats(-3.0, 3.0, allow_nan=False))
def test_the_guard_is_zero_exactly_where_a_comparison_is_an_equality(a, b):
    system = hs.HybridSystem.from_functions(flow_map=lambda x: -x, jump_set=lambda x: x[0] >= x[1],
                                            state_dim=2)
    v = system.jump_guard(np.array([a, b]))
    assert (v == 0.0) == (a == b) and (v > 0.0) == (a > b)


def test_a_vectorized_set_gets_a_vectorized_guard():
    system = hs.HybridSystem.from_functions(
        flow_map=lambda x: -x, jump_set=lambda x: (x[..., 0] >= 0) & (x[..., 1] <= 1), state_dim=2,
        vectorized=True)
    X = np.array([[1.0, 0.0], [-1.0, 0.0], [1.0, 3.0]])
    np.testing.assert_array_equal(system.jump_guard(X), [1.0, -1.0, -2.0])


def test_sets_that_cannot_be_guards_are_named_and_keep_the_indicator():
    def odd_j(x, t, j):
        return j % 2 == 1

    def all_positive(x):
        return np.all(x >= 0)
    for D, words in ((odd_j, "Eq"), (all_positive, "is not a comparison")):
        system = hs.HybridSystem.from_functions(flow_map=lambda x: -x, jump_set=D, state_dim=1)
        assert system.jump_guard is None
        why = guard_refusal(system, "jump_guard")
        assert words in why and f"test_derived_guards.py:{D.__code__.co_firstlineno + 1}" in why
        assert system._compile().hD is None          # today's behaviour: bisection
    assert guard_refusal(ReadmeBall(), "jump_guard") is None


def test_a_given_guard_or_none_replaces_the_derived_one():
    class Opt(ReadmeBall):
        jump_guard = None
    assert Opt().jump_guard is None and Opt().flow_guard is not None
    assert HandBall().jump_guard(np.array([0.5, -1.0])) == -0.5
    # a set replaced on the instance gets its own guard
    s = hs.HybridSystem.from_functions(flow_map=lambda x: -x, jump_set=lambda x: x[0] >= 1.0,
                                       state_dim=1)
    assert s.jump_guard(np.array([3.0])) == 2.0
    s.jump_set = lambda x: x[0] >= 2.0
    assert s.jump_guard(np.array([3.0])) == 1.0
    assert derived_guard(s, "flow_guard") is None       # C is everything: no set, no guard


def test_systems_with_derived_guards_pickle_and_copy():
    ball = ReadmeBall()
    assert ball.jump_guard is not None
    back = pickle.loads(pickle.dumps(ball))
    assert back.jump_guard(np.array([0.5, -1.0])) == -0.5
    assert copy.deepcopy(ball).flow_guard(np.array([0.25, 0.0])) == 0.25


# ------------------------------------------------------------ the engine uses them
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_event_times_equal_the_hand_guarded_ball_to_4_ulp(rtol):
    kw = dict(x0=[1.0, 0.0], t_max=10.0, j_max=15, rtol=rtol, atol=rtol * 1e-3)
    derived, hand = hs.simulate(ReadmeBall(), **kw), hs.simulate(HandBall(), **kw)
    assert derived.jump_count == hand.jump_count == 15
    d, h = derived.jump_times, hand.jump_times
    assert np.all(np.abs(d - h) <= 4 * np.spacing(h)), d - h
    # and both are the closed form to the integrator's accuracy (RK45 is exact on
    # parabolas: what is left is the events' location, a few ulp per bounce)
    np.testing.assert_allclose(d, bouncing_ball_jump_times(1.0, 15, G, E), rtol=1e-12)


def _apex(guard):
    kw = {"jump_guard": lambda x: x[0] - 1.0} if guard else {"jump_set": lambda x: x[0] >= 1.0}
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[1], -1.0]), jump_map=lambda x: np.array([x[0], -abs(x[1])]),
        state_dim=2, **kw)


@pytest.mark.parametrize("method", ["RK45", "DOP853"])
@pytest.mark.parametrize("rtol", [1e-3, 1e-6, 1e-10])
def test_the_apex_1e6_above_the_guard_is_found_with_indicators_only(method, rtol):
    # README: "with guards, an apex 1e-6 above the guard is found" (tests/engine/test_faults.py);
    # here the system gives D = {x >= 1} alone and its guard x - 1 is derived
    for d in (0.3, 1e-3, 1e-6):
        v0 = math.sqrt(2.0 * (1.0 + d))
        arcs = [hs.simulate(_apex(g), [0.0, v0], t_max=1.5 * v0, j_max=1, method=method,
                            rtol=rtol, atol=rtol * 1e-3) for g in (False, True)]
        assert [a.jump_count for a in arcs] == [1, 1], (method, rtol, d)
        # the same event as with the hand-written guard, to 4 ulp
        a, b = arcs[0].jump_times[0], arcs[1].jump_times[0]
        assert abs(a - b) <= 4 * np.spacing(b)


@pytest.mark.parametrize("rtol", [1e-6, 1e-8, 1e-10])
def test_sensitivities_of_an_indicator_only_ball(rtol):
    """d t_k / d h0 = t_k / (2 h0) (t_k is proportional to sqrt(h0)) for 10
    bounces, to 1e-9 relative: RK45 integrates the parabolas exactly, so what
    is left is event location and the central differences on affine maps
    (see tests/capabilities/test_sensitivity.py's closed forms)."""
    h0, k = 1.0, 10
    tk = bouncing_ball_jump_times(h0, k + 1, G, E)
    sarc = hs.simulate_sensitivity(ReadmeBall(), [h0, 0.0], t_max=0.5 * (tk[k - 1] + tk[k]),
                                   j_max=k, rtol=rtol)
    assert sarc.arc.jump_count == k
    np.testing.assert_allclose(sarc.jump_times, tk[:k], rtol=1e-12)
    np.testing.assert_allclose(sarc.dtj_dx0[:, 0], tk[:k] / (2 * h0), rtol=1e-9)


def test_sensitivities_still_refuse_a_set_without_a_guard():
    system = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        jump_set=lambda x: bool(np.all(x >= 1.0)), state_dim=1)
    from hybridsim.sensitivity import SensitivityError
    with pytest.raises(SensitivityError, match="without a guard|no jump_guard"):
        hs.simulate_sensitivity(system, [0.0], t_max=1.5)
