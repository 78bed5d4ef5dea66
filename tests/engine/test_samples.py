"""Every sample an arc holds is stored once (issue 22, defects 1 and 2).

The README's semantics: samples at the solver's steps (``refine - 1`` more
inside each), or at the ``t_eval`` times, plus the initial and final samples
and both samples of every jump, each stored once: hybrid time (t, j) never
repeats and never runs backwards, whatever ends the run (t_max, a jump at
t_max, an event, a failure mid-step, max_samples, Ctrl-C).
"""
import itertools
import math
import warnings

import numpy as np
import pytest

import hybridsim as hs
from hybridsim import Termination


def assert_stored_once(arc):
    """(t, j) strictly increasing in the lexicographic order of hybrid time."""
    t, j = np.asarray(arc.t), np.asarray(arc.j)
    dt, dj = np.diff(t), np.diff(j)
    assert np.all(dj >= 0), f"j runs backwards: {j}"
    assert np.all(dt >= 0), f"t runs backwards: {t}"
    # equal times only across a jump (j + 1), and a jump keeps t
    assert np.all((dt > 0) | (dj == 1)), f"a sample stored twice: t={t}, j={j}"
    assert np.all((dj == 0) | (dt == 0)), f"a jump changed t: t={t}, j={j}"


def timer(kind, period=0.5):
    """x' = 1, D = {x >= period}, g(x) = 0; as a set indicator or as a guard."""
    kw = (dict(jump_set=lambda x: x[0] >= period) if kind == "set"
          else dict(jump_guard=lambda x: x[0] - period))
    return hs.HybridSystem.from_functions(flow_map=lambda x: np.array([1.0]),
                                          jump_map=lambda x: np.array([0.0]), state_dim=1, **kw)


def decay():
    return hs.HybridSystem.from_functions(flow_map=lambda x: -x, state_dim=1)


# ------------------------------------------------- refine, a jump at t_max
@pytest.mark.parametrize("kind", ["set", "guard"])
@pytest.mark.parametrize("refine", [1, 2, 3, 4, 7])
def test_refine_with_a_jump_at_t_max_stores_each_sample_once(kind, refine):
    arc = hs.simulate(timer(kind), [0.0], t_max=1.0, refine=refine)
    assert_stored_once(arc)
    assert arc.termination is Termination.T_MAX and arc.jump_count == 2
    np.testing.assert_allclose(arc.jump_times, [0.5, 1.0], atol=1e-12)
    # the last flow, [0.5, 1], is one solver step: its refine - 1 inner points once
    last = (arc.j == 1)
    np.testing.assert_allclose(arc.t[last], np.linspace(0.5, 1.0, refine + 1), atol=1e-12)
    assert (arc.t[-1], arc.j[-1]) == (1.0, 2) and arc.x[-1, 0] == 0.0


def test_refine_2_gives_the_issues_samples():
    arc = hs.simulate(timer("set"), [0.0], t_max=1.0, refine=2)
    tail = slice(-5, None)
    np.testing.assert_allclose(arc.t[tail], [0.5, 0.5, 0.75, 1.0, 1.0], atol=1e-12)
    assert arc.j[tail].tolist() == [0, 1, 1, 1, 2]


@pytest.mark.parametrize("period", [0.1, 0.25, 1.0 / 3.0])
@pytest.mark.parametrize("opts", [dict(refine=3), dict(dense=True),
                                  dict(t_eval=np.linspace(0.0, 2.0, 9))])
def test_jumps_landing_on_t_max_up_to_round_off_store_each_sample_once(period, opts):
    arc = hs.simulate(timer("guard", period), [0.0], t_max=2.0, **opts)
    assert_stored_once(arc)
    assert arc.jump_count == round(2.0 / period)
    assert arc.j[-1] == arc.jump_count and abs(arc.t[-1] - 2.0) < 1e-12


def test_dense_records_each_flow_once_when_a_jump_lands_on_t_max():
    arc = hs.simulate(timer("set"), [0.0], t_max=1.0, dense=True)
    segs = [(a, b, j) for a, b, j, _ in arc._segments]
    assert len(segs) == len(set(segs))
    # consecutive segments of one flow meet end to start, never overlap
    for (a0, b0, j0), (a1, b1, j1) in itertools.pairwise(segs):
        assert (j1 == j0 and a1 == b0) or (j1 == j0 + 1 and a1 >= b0)
    assert abs(arc.at(0.75, 1)[0] - 0.25) < 1e-12


# ----------------------------------------------------------------- t_eval
def test_t_eval_ending_at_t_max_gives_the_final_sample_once():
    arc = hs.simulate(decay(), [1.0], t_max=1.0, t_eval=[0.0, 0.5, 1.0])
    assert arc.t.tolist() == [0.0, 0.5, 1.0]
    np.testing.assert_allclose(arc.x[:, 0], np.exp(-arc.t), rtol=1e-5)


@pytest.mark.parametrize("kind", ["set", "guard"])
def test_t_eval_at_a_jump_time_gives_the_two_jump_samples_only(kind):
    arc = hs.simulate(timer(kind), [0.0], t_max=0.8, t_eval=[0.5])
    assert arc.j.tolist() == [0, 0, 1, 1]
    np.testing.assert_allclose(arc.t, [0.0, 0.5, 0.5, 0.8], atol=1e-12)
    np.testing.assert_allclose(arc.x[:, 0], [0.0, 0.5, 0.0, 0.3], atol=1e-12)


@pytest.mark.parametrize("kind", ["set", "guard"])
def test_t_eval_with_a_jump_at_t_max(kind):
    arc = hs.simulate(timer(kind), [0.0], t_max=1.0, t_eval=[0.25, 0.5, 0.75, 1.0])
    assert_stored_once(arc)
    np.testing.assert_allclose(arc.t, [0, 0.25, 0.5, 0.5, 0.75, 1.0, 1.0], atol=1e-12)
    assert arc.j.tolist() == [0, 0, 0, 1, 1, 1, 2]


def test_t_eval_run_ending_mid_flow_keeps_its_final_sample():
    # the run ends between t_eval times (BLOWUP, MAX_STEPS): the state it stopped
    # at is the final sample, stored once
    quad = hs.HybridSystem.from_functions(flow_map=lambda x: x ** 2, state_dim=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hs.SimulationWarning)
        arc = hs.simulate(quad, [1.0], t_max=2.0, max_norm=1e3, t_eval=[0.0, 0.5])
        assert arc.termination is Termination.BLOWUP
        assert_stored_once(arc)
        assert arc.t[:2].tolist() == [0.0, 0.5] and len(arc) == 3 and abs(arc.x[-1, 0]) > 1e3
        arc = hs.simulate(decay(), [1.0], t_max=1.0, max_step=1e-3, max_steps=100,
                          t_eval=[0.0, 0.05, 0.5])
    assert arc.termination is Termination.MAX_STEPS
    assert_stored_once(arc)
    assert arc.t[:2].tolist() == [0.0, 0.05] and abs(arc.t[-1] - 0.1) < 1e-9


def test_t_eval_across_delay_breakpoints_and_random_priority():
    class Delayed(hs.HybridSystem):
        state_dim = 1
        delays = (0.3,)

        def flow_map(self, x):
            return np.array([1.0])

        def jump_map(self, x):
            return np.array([0.0])

        def jump_set(self, x):
            return x[0] >= 0.5

    grid = np.linspace(0.0, 2.0, 21)        # holds the breakpoints 0.3, 0.8, ... and jumps
    arc = hs.simulate(Delayed(), [0.0], t_max=2.0, t_eval=grid)
    assert_stored_once(arc)
    assert arc.jump_count == 4
    arc = hs.simulate(timer("guard"), [0.0], t_max=2.0, t_eval=grid, priority="random",
                      seed=3)
    assert_stored_once(arc)


# --------------------------------------------- ends mid-step, caps, Ctrl-C
def test_max_samples_reached_inside_a_step_stores_each_sample_once():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hs.SimulationWarning)
        for cap in (7, 20, 21, 22, 40):
            arc = hs.simulate(timer("set"), [0.0], t_max=3.0, refine=4, max_samples=cap)
            assert arc.termination is Termination.MAX_STEPS and len(arc) <= cap
            assert_stored_once(arc)
            assert f"at t={arc.t[-1]:.10g}" in arc.message


@pytest.mark.parametrize("opts", [dict(), dict(refine=3), dict(t_eval=np.linspace(0, 1, 101))])
def test_ctrl_c_inside_a_step_stores_each_sample_once_and_says_where(opts):
    def f(x, t):
        if t > 0.5:
            raise KeyboardInterrupt
        return np.array([1.0])
    sysm = hs.HybridSystem.from_functions(flow_map=f, jump_map=lambda x: np.array([0.0]),
                                          jump_set=lambda x: x[0] >= 0.2, state_dim=1)
    arc = hs.simulate(sysm, [0.0], t_max=1.0, max_step=0.01, **opts)
    assert arc.termination is Termination.CANCELED
    assert_stored_once(arc)
    # the message names where the run stopped: its last sample, not the flow's start
    assert arc.message.endswith(f"stopped at t={arc.t[-1]:.10g}, j={arc.j[-1]}")
    assert arc.t[-1] > 0.45


def test_events_leaving_the_sets_mid_step_store_each_sample_once():
    # the flow leaves C outside D inside a refined step: the exit sample once
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: np.array([1.0]),
                                          flow_set=lambda x: x[0] <= 0.7, state_dim=1)
    for opts in (dict(refine=5), dict(t_eval=[0.0, 0.7, 0.9]), dict(dense=True)):
        arc = hs.simulate(sysm, [0.0], t_max=1.0, **opts)
        assert arc.termination is Termination.LEFT_SETS
        assert_stored_once(arc)
        assert abs(arc.t[-1] - 0.7) < 1e-12


@pytest.mark.parametrize("t_max", [1.0, 2.0, 10.0])
def test_timer_jumps_at_t_max_with_refine_and_t_eval(t_max):
    for kind in ("set", "guard"):
        for opts in (dict(refine=2), dict(refine=5), dict(t_eval=np.linspace(0, t_max, 7))):
            arc = hs.simulate(timer(kind, 1.0 / 3.0), [0.0], t_max=t_max, **opts)
            assert_stored_once(arc)
            assert arc.jump_count == round(3 * t_max)
            assert math.isclose(arc.t[-1], t_max, abs_tol=1e-12)
