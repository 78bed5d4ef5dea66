"""Event location (hybridsim.events): the bracket it returns and what it costs.

``locate_event`` must return a bracket (lo, hi] of at most 4 ulp of the
event time with the indicator false at lo and true at hi, whatever the
guard's shape along the step; these tests check that on polynomials with
known roots, including the case every jump of a bouncing ball creates (the
flow starts on the guard's zero), and count the interpolant evaluations it
spends, which is what makes the Python path's events cheap.
"""
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import hybridsim as hs
from hybridsim.events import _root_off_zero, locate_event
from hybridsim.rules import event_tolerance


def counted(fn):
    """fn with a call counter (``.calls``)."""
    def call(s):
        call.calls += 1
        return fn(s)
    call.calls = 0
    return call


def check_bracket(lo, hi, root, a, b):
    assert a <= lo < hi <= b
    assert hi - lo <= event_tolerance(lo, hi)
    # the root lies in the bracket up to the guard's own rounding near it
    assert lo - 4 * event_tolerance(lo, hi) <= root <= hi + 4 * event_tolerance(lo, hi)


@settings(max_examples=200, deadline=None)
@given(a=st.floats(-50.0, 50.0), w=st.floats(1e-3, 10.0), frac=st.floats(0.01, 0.99),
       curv=st.floats(-3.0, 3.0), cubic=st.floats(-1.0, 1.0))
def test_bracket_of_a_crossing_from_below(a, w, frac, curv, cubic):
    # a guard g(s) = (s - r)(1 + curv u + cubic u^2), u = (s - a)/w: increasing
    # through its only root r in (a, b) when the bracket factor stays positive
    b = a + w
    r = a + frac * w

    def factor(s):
        u = (s - a) / w
        return 1.0 + 0.3 * curv * u + 0.3 * cubic * u * u

    # the premise: one root in (a, b) (the factor can vanish at u = 0.86 when
    # curv = -3, cubic = -1: a second crossing, found first, rightly)
    assume(min(factor(a + w * u) for u in np.linspace(0.0, 1.0, 101)) > 0.05)
    sol = counted(lambda s: np.array([(s - r) * factor(s)]))
    lo, hi, ylo, yhi = locate_event(sol, a, b, lambda s, y: y[0] >= 0.0, lambda s, y: y[0])
    check_bracket(lo, hi, r, a, b)
    assert yhi[0] >= 0.0 > ylo[0]
    # superlinear: a handful of evaluations, not a bisection's ~50
    assert sol.calls <= 16, sol.calls


@settings(max_examples=200, deadline=None)
@given(a=st.floats(0.0, 20.0), w=st.floats(1e-2, 10.0), frac=st.floats(0.02, 0.95),
       c=st.floats(0.1, 100.0))
def test_bracket_of_a_flow_that_starts_on_the_guard_zero(a, w, frac, c):
    # the ball's case: the guard is 0 at the step's start (just after a jump),
    # negative inside, back to 0 at r: a parabola c (s - a)(s - r)
    b = a + w
    r = a + frac * w
    sol = counted(lambda s: np.array([c * (s - a) * (s - r)]))
    lo, hi, _, _ = locate_event(sol, a, b, lambda s, y: s > a and y[0] >= 0.0,
                                lambda s, y: y[0])
    check_bracket(lo, hi, r, a, b)
    # ends, probe, the quadratic model's estimate, the secant, the closing point(s)
    assert sol.calls <= 8, sol.calls


def test_linear_guard_takes_two_evaluations_after_the_ends():
    # a timer's guard along a step: the regula falsi lands on the root, one
    # more evaluation closes the bracket from the other side
    sol = counted(lambda s: np.array([s - 11.0]))
    lo, hi, _, _ = locate_event(sol, 10.0, 20.0, lambda s, y: y[0] >= 0.0, lambda s, y: y[0])
    assert lo < 11.0 <= hi and hi - lo <= event_tolerance(lo, hi)
    assert sol.calls <= 4, sol.calls


def test_known_end_states_are_not_evaluated_again():
    sol = counted(lambda s: np.array([s - 11.0]))
    ya, yb = np.array([-1.0]), np.array([9.0])
    lo, hi, _, _ = locate_event(sol, 10.0, 20.0, lambda s, y: y[0] >= 0.0, lambda s, y: y[0],
                                ya=ya, yb=yb)
    assert lo < 11.0 <= hi and sol.calls <= 2, sol.calls


@pytest.mark.parametrize("frac", [0.05, 0.3, 0.7, 0.95])
@pytest.mark.parametrize("c", [0.5, 9.81])
def test_quadratic_model_lands_within_the_probe_of_the_root(frac, c):
    # g(tau) = c tau (tau - r): the probe's secant slope at d stands for the
    # slope at 0, so the model's root is off by at most about d, with the slope
    # there to match
    w = 2.0
    r = frac * w
    d = 1e-6 * w
    g = lambda tau: c * tau * (tau - r)   # noqa: E731
    tau, slope = _root_off_zero(g(0.0), g(d), g(w), d, w)
    assert abs(tau - r) <= 2 * d
    assert abs(slope - c * r) <= 2 * c * d


def test_quadratic_model_declines_without_a_root():
    # a guard still rising at the end of the step (fw < 0): no estimate
    assert _root_off_zero(0.0, -1e-9, -1.0, 1e-9, 1.0) is None


class CountingBall(hs.library.BouncingBall):
    """A ball that counts its guard evaluations."""

    def __init__(self):
        super().__init__()
        self.guard_calls = 0

    def jump_guard(self, x):
        self.guard_calls += 1
        return -x[0]

    def flow_guard(self, x):
        return x[0]


def test_a_ball_event_costs_a_handful_of_guard_evaluations():
    # 30 bounces at rtol 1e-8: every flow starts on the guard's zero; the
    # jump times stay at the closed form's accuracy
    ball = CountingBall()
    arc = hs.simulate(ball, [1.0, 0.0], t_max=10.0, j_max=30, rtol=1e-8, atol=1e-10)
    exact = hs.library.bouncing_ball_jump_times(1.0, 30)
    assert np.max(np.abs(arc.jump_times - exact)) < 1e-12
    per_event = ball.guard_calls / arc.stats["events"]
    assert per_event <= 12, per_event          # was ~26 before the quadratic model
    assert math.isfinite(per_event)


def test_interior_search_finds_a_peak_between_the_last_sample_and_the_step_end():
    # issue 22: the guard rises through the last quarter of the step, peaks
    # above 0 just before b and falls at b; the next step starts falling, so
    # only this step's search can find it (DOP853 at rtol 1e-10 missed it)
    from hybridsim.events import find_interior_event
    apex = 0.96

    def sol(s):
        return np.array([1e-4 - (s - apex) ** 2])
    hit = find_interior_event(sol, 0.0, 1.0, lambda s, y: y[0] >= 0.0, lambda s, y: y[0])
    assert hit is not None
    lo, hi = hit
    assert sol(hi)[0] >= 0.0 and lo < hi <= 1.0
