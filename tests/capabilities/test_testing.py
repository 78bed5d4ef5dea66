"""hybridsim.testing: settling times and exactness/bound assertions."""
import numpy as np
import pytest

import hybridsim as hs
from hybridsim import testing as hst
from hybridsim.rules import event_tolerance


@pytest.fixture(scope="module")
def arc():
    # x' = -x until t = 1, then a jump to 0 (a "finite-time observer error")
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([-x[0], 1.0]), jump_map=lambda x: np.array([0.0, x[1]]),
        jump_guard=lambda x: x[1] - 1.0, flow_guard=lambda x: 1.0 - x[1],
        jump_set=lambda x: x[1] >= 1.0 and x[0] != 0.0, state_dim=2)
    return hs.simulate(sysm, [1.0, 0.0], t_max=2.0, refine=4)


def test_settling_time(arc):
    t, j = hst.settling_time(arc, lambda x: x[0], threshold=1e-10)
    assert abs(t - 1.0) < 1e-12 and j == 0
    assert hst.settling_time(arc, arc.x[:, 0] * 0, 1e-10) == (0.0, 0)
    assert hst.settling_time(arc, np.ones(len(arc)), 0.5) == (float("inf"), None)


def test_assert_exact_after(arc):
    hst.assert_exact_after(arc, lambda x: x[0], t=1.0, j=1, atol=0.0)
    with pytest.raises(AssertionError, match=r"first violation at \(t=0\.5.*j=0\)"):
        hst.assert_exact_after(arc, lambda x: x[0], t=0.5, atol=1e-3)
    with pytest.raises(AssertionError, match="no sample"):
        hst.assert_exact_after(arc, lambda x: x[0], t=5.0)


def test_assert_bounded(arc):
    hst.assert_bounded(arc, lambda x: x[0], lambda t, j: np.exp(-t), rtol=1e-6)
    hst.assert_bounded(arc, arc.x[:, :1], 1.0)
    with pytest.raises(AssertionError, match=r"bound violated: first at \(t="):
        hst.assert_bounded(arc, lambda x: x[0], lambda t, j: 0.5 * np.exp(-t))
    with pytest.raises(ValueError, match="one value per sample"):
        hst.assert_bounded(arc, np.ones(3), 1.0)


# -- hybrid time compared to the engine's tolerance (issue 23) -----------------

DELTA = 0.8


@pytest.fixture(scope="module")
def timer_arc():
    # a timer started at 0.8 with period 1.6 jumps after δ = 0.8; the engine
    # stores the jump one rounding step early, at 0.7999999999999998
    arc = hs.simulate(hs.library.Timer(1.6), [0.8], t_max=1.2, refine=4)
    return arc


def test_timer_jump_lands_before_delta(timer_arc):
    # the premise of the tests below (if the engine's rounding changes, the
    # arc below still covers the case)
    (tj,) = timer_arc.jump_times
    assert tj <= DELTA and abs(tj - DELTA) <= event_tolerance(DELTA, DELTA)


def _first_after_jump(arc):
    return int(np.flatnonzero(arc.j == 1)[0])


def test_exact_after_checks_sample_one_rounding_step_before_delta(timer_arc):
    arc = timer_arc
    k = _first_after_jump(arc)
    signal = np.zeros(len(arc))
    hst.assert_exact_after(arc, signal, t=DELTA, j=1, atol=0.0)
    signal[k] = 1.0             # only the first sample after the jump is wrong
    with pytest.raises(AssertionError, match=r"first violation at \(t=0\.8, j=1\).*1 of "):
        hst.assert_exact_after(arc, signal, t=DELTA, j=1, atol=1e-8)
    # the stored arc, whatever the engine's rounding: a jump at δ - 2 ulp
    tj = 0.7999999999999998
    built = hs.HybridArc([0.0, tj, tj, 1.0], [0, 0, 1, 1], [[1.0], [0.5], [1.0], [0.0]], None)
    with pytest.raises(AssertionError, match=r"first violation at \(t=0\.8, j=1\)"):
        hst.assert_exact_after(built, built.x, t=DELTA, j=1)
    # without j, the sample before the jump is at δ too (t >= δ takes both)
    with pytest.raises(AssertionError, match=r"first violation at \(t=0\.8, j=0\).*2 of 3"):
        hst.assert_exact_after(built, built.x, t=DELTA)
    # the end of a closed range likewise: a sample 2 ulp past hi is at hi
    late = hs.HybridArc([0.0, 0.8000000000000002, 1.0], [0, 0, 0], [[0.0], [1.0], [0.0]], None)
    with pytest.raises(AssertionError, match=r"first violation at \(t=0\.8, j=0\)"):
        hst.assert_exact_after(late, late.x, t=(0.0, DELTA))


def test_bounded_checks_sample_one_rounding_step_before_delta(timer_arc):
    arc = timer_arc
    k = _first_after_jump(arc)
    signal = np.zeros(len(arc))
    signal[k] = 1.0
    with pytest.raises(AssertionError, match=r"bound violated: first at \(t=0\.8, j=1\)"):
        hst.assert_bounded(arc, signal, 0.5, t=DELTA)
    hst.assert_bounded(arc, signal, 0.5, t=(DELTA + 1e-9, None))


def test_sample_1e9_before_delta_is_excluded():
    # 1e-9 is far more than the engine's tolerance (4 ulp): not "at δ"
    t1 = DELTA - 1e-9
    arc = hs.HybridArc([0.0, t1, t1, 1.0], [0, 0, 1, 1], [[1.0], [0.5], [1.0], [0.0]], None)
    with pytest.raises(AssertionError, match="no sample"):
        hst.assert_exact_after(arc, arc.x, t=(DELTA, DELTA))
    hst.assert_exact_after(arc, arc.x, t=DELTA, j=1, atol=0.0)
    hst.assert_exact_after(arc, arc.x, t=DELTA, atol=0.0)
    hst.assert_bounded(arc, arc.x, 0.0, t=DELTA)
    # and a sample 1e-9 past the end of a range is outside it
    arc2 = hs.HybridArc([0.0, DELTA + 1e-9], [0, 0], [[0.0], [1.0]], None)
    hst.assert_exact_after(arc2, arc2.x, t=(0.0, DELTA), atol=0.0)


def test_tolerance_is_the_engines():
    # exactly event_tolerance(t, t) is in, the next float beyond is out
    tol = event_tolerance(DELTA, DELTA)
    inside = DELTA - tol
    outside = np.nextafter(inside, -np.inf)
    for t_s, expect_checked in ((inside, True), (outside, False)):
        arc = hs.HybridArc([0.0, t_s, 1.0], [0, 0, 0], [[0.0], [1.0], [0.0]], None)
        if expect_checked:
            with pytest.raises(AssertionError, match="first violation"):
                hst.assert_exact_after(arc, arc.x, t=DELTA)
        else:
            hst.assert_exact_after(arc, arc.x, t=DELTA)


def test_open_range_ends_and_bad_ranges(arc):
    hst.assert_exact_after(arc, lambda x: x[0], t=(1.0, None), j=1, atol=0.0)
    with pytest.raises(AssertionError, match="first violation"):
        hst.assert_exact_after(arc, lambda x: x[0], t=(None, 1.0), atol=0.0)
    with pytest.raises(TypeError, match="closed range"):
        hst.assert_exact_after(arc, lambda x: x[0], t=(0.0, 1.0, 2.0))


def test_margins_select_time_as_the_asserts(timer_arc):
    # the margins take the samples the asserts take: the first sample after
    # the jump stored at δ - 2 ulp is "at δ"
    arc = timer_arc
    k = _first_after_jump(arc)
    signal = np.zeros(len(arc))
    signal[k] = 1.0
    m = hst.margin_exact_after(arc, signal, t=DELTA, j=1, atol=1e-8)
    assert not m.holds and m.where == (float(arc.t[k]), 1)
    m = hst.margin_bounded(arc, signal, 0.5, t=DELTA)
    assert float(m) == -0.5 and m.where[1] == 1
    t1 = DELTA - 1e-9
    far = hs.HybridArc([0.0, t1, t1, 1.0], [0, 0, 1, 1], [[1.0], [0.5], [1.0], [0.0]], None)
    assert hst.margin_exact_after(far, far.x, t=DELTA, atol=0.0).holds


def test_margin_settles_by_counts_a_late_rounding_step_as_on_time():
    # the error is reset to 0 by a jump meant for δ that is stored 2 ulp late
    tj = 0.8000000000000002
    arc = hs.HybridArc([0.0, tj, tj, 1.0], [0, 0, 1, 1], [[1.0], [0.5], [0.0], [0.0]], None)
    m = hst.margin_settles_by(arc, arc.x, by=DELTA)
    assert m.holds and float(m) == 0.0 and m.where == (tj, 0)
    # 1e-9 late is late
    late = hs.HybridArc([0.0, DELTA + 1e-9, DELTA + 1e-9, 1.0], [0, 0, 1, 1],
                        [[1.0], [0.5], [0.0], [0.0]], None)
    m = hst.margin_settles_by(late, late.x, by=DELTA)
    assert not m.holds and float(m) == pytest.approx(-1e-9, rel=1e-6)
    # early is a positive margin, unchanged
    assert float(hst.margin_settles_by(arc, arc.x, by=0.9)) == pytest.approx(0.9 - tj)
