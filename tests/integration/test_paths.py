"""Every integration path under the same tests (issue 22).

The Python loop, the vectorized numpy batch and the compiled kernel keep
three loops; these tests hold them to one set of rules. Each test takes the
``path`` parameter (see ``tests/paths.py``): random hybrid systems keep the
invariants of a hybrid arc on every path, with ``refine``, jumps at t_max,
both priorities, C ∩ D, guards and set indicators; the paths agree with each
other sample for sample where they accept the same options; the same bad
input gets the same exception and message everywhere; options a path does
not implement are refused by name.

Tolerances: events are bracketed to 4 ulp of t (``rules.event_tolerance``),
so a state at an event is off its guard by at most |guard rate| * 4 ulp,
below 1e-9 for these flows (states of order 10, rates of order 100); runs at
rtol 1e-9 agree between paths to 1e-7 where their steps are the same
arithmetic in another order.
"""
import math
import threading

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from paths import (
    SETS,
    Ball,
    Linear,
    one_sigint_inside_the_run,
    random_linear,
    run,
    timer,
)

import hybridsim as hs
from hybridsim import Termination

T = Termination
TOL_EVENT = 1e-8
FUZZ = settings(max_examples=25, deadline=None,
                suppress_health_check=[HealthCheck.too_slow,
                                       HealthCheck.function_scoped_fixture])
OPTS = dict(rtol=1e-9, atol=1e-11, max_norm=1e6, max_steps=20_000, warn=False)


def assert_invariants(arc, case, priority, t_max, j_max):
    """What every arc of a Linear case satisfies, whichever path computed it."""
    arc.validate()
    t, j, x = arc.t, arc.j, arc.x
    assert np.all(np.diff(t) >= 0), "time runs backwards"
    dj = np.diff(j)
    assert np.all((dj == 0) | (dj == 1))
    jumps = np.flatnonzero(dj == 1)
    assert np.all(t[jumps] == t[jumps + 1])
    same = (np.diff(t) == 0) & (dj == 0)
    assert not same.any(), f"sample stored twice at t={t[1:][same][:3]}"
    assert arc.jump_count == len(jumps) <= j_max
    for k in jumps:                      # pre-jump samples are in D
        assert case.hD(x[k]) >= -TOL_EVENT, (k, t[k], case.hD(x[k]))
    if case.with_C:                      # samples the run flows from are in C
        for k in np.flatnonzero((dj == 0) & (np.diff(t) > 0)):
            assert case.hC(x[k]) >= -TOL_EVENT, (k, t[k], case.hC(x[k]))
    cause = arc.termination
    assert cause is not None
    if cause is T.T_MAX:
        assert t[-1] == t_max
    elif cause is T.J_MAX:
        assert arc.jump_count == j_max
    elif cause in (T.LEFT_SETS, T.NOT_IN_SETS):
        assert case.with_C and case.hC(x[-1]) <= TOL_EVENT and case.hD(x[-1]) < TOL_EVENT
    elif cause is T.BLOWUP:
        assert np.linalg.norm(x[-1]) > 1e6
    else:
        assert cause in (T.ZENO, T.MAX_STEPS), cause
    # one arc contract: every path fills xdot and stats
    assert arc.xdot is not None and arc.xdot.shape == x.shape
    assert arc.stats is not None and {"steps", "nfev", "events", "flows"} <= set(arc.stats)


@pytest.mark.slow
@FUZZ
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 3), with_C=st.booleans(),
       sets=st.sampled_from(SETS), priority=st.sampled_from(["jumps", "flows"]),
       refine=st.sampled_from([1, 2, 4]), t_max=st.floats(2.0, 6.0),
       j_max=st.integers(6, 20))
def test_random_systems_keep_the_invariants_on_every_path(path, seed, n, with_C, sets,
                                                          priority, refine, t_max, j_max):
    case, x0 = random_linear(seed, n, with_C, sets)
    arc = run(path, case, x0, t_max=t_max, j_max=j_max, priority=priority, refine=refine,
              **OPTS)
    assert_invariants(arc, case, priority, t_max, j_max)


@pytest.mark.slow
@pytest.mark.paths(only=("vectorized", "compiled"))
@FUZZ
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 3), with_C=st.booleans(),
       sets=st.sampled_from(["guards", "both"]), priority=st.sampled_from(["jumps", "flows"]),
       refine=st.sampled_from([1, 3]))
def test_every_path_gives_the_python_paths_samples(path, seed, n, with_C, sets, priority,
                                                   refine):
    """The same run, the same solution: jump times to 1e-7, states along every
    flow to 1e-6 relative (rtol 1e-9 per step, over a few hundred steps)."""
    case, x0 = random_linear(seed, n, with_C, sets)
    kw = dict(t_max=3.0, j_max=8, priority=priority, refine=refine, **OPTS)
    ref = run("python", case, x0, **kw)
    arc = run(path, case, x0, **kw)
    assert arc.termination is ref.termination, (arc.message, ref.message)
    assert arc.jump_count == ref.jump_count
    np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-7)
    np.testing.assert_allclose(arc.xf, ref.xf, rtol=1e-6, atol=1e-7)
    # the same solution between the jumps: each path's arc read at the Python
    # path's samples inside its flows (the step sequences may part by round-off
    # in the error norm, so samples are compared through arc.at, not one by one)
    for t, j in zip(ref.t, ref.j):
        inside = [a.t[a.j == j] for a in (arc, ref)]
        if all(len(s) for s in inside) and \
                max(s[0] for s in inside) + 1e-6 < t < min(s[-1] for s in inside) - 1e-6:
            np.testing.assert_allclose(arc.at(t, j), ref.at(t, j), rtol=1e-6, atol=1e-7)


@pytest.mark.paths(compiled_slow=True, only=("vectorized", "compiled"))
@FUZZ
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 3), with_C=st.booleans(),
       sets=st.sampled_from(SETS), priority=st.sampled_from(["jumps", "flows"]),
       refine=st.sampled_from([1, 3]), t_max=st.floats(2.0, 6.0), j_max=st.integers(6, 20))
def test_dop853_gives_the_python_paths_samples(path, seed, n, with_C, sets, priority, refine,
                                               t_max, j_max):
    """method="DOP853" on the vectorized and compiled paths: the arc keeps the
    invariants and is the Python path's DOP853 run (scipy's steps, its dense
    output, the interior search on the step's cubic Hermite confirmed on the
    dense output): jump times to 1e-7, states to 1e-6 relative, as RK45's
    above."""
    case, x0 = random_linear(seed, n, with_C, sets)
    kw = dict(t_max=t_max, j_max=j_max, priority=priority, refine=refine, method="DOP853",
              **OPTS)
    arc = run(path, case, x0, **kw)
    assert_invariants(arc, case, priority, t_max, j_max)
    ref = run("python", case, x0, **kw)
    assert arc.termination is ref.termination, (arc.message, ref.message)
    assert arc.jump_count == ref.jump_count
    np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-7)
    np.testing.assert_allclose(arc.xf, ref.xf, rtol=1e-6, atol=1e-7)
    assert abs(arc.stats["steps"] - ref.stats["steps"]) <= 2 + ref.stats["steps"] // 20


def test_methods_run_where_implemented_and_are_refused_by_name_elsewhere(path):
    """DOP853 by name or as scipy's class: stepped on every path (the timer's
    jumps exact); a method the vectorized or compiled path lacks is refused
    naming the ones it has."""
    from scipy.integrate import DOP853
    for method in ("DOP853", DOP853):
        arc = run(path, timer(), [0.0], t_max=1.0, method=method)
        np.testing.assert_allclose(arc.jump_times, [0.5, 1.0], atol=1e-12)
    if path != "python":
        with pytest.raises(ValueError, match=rf"method='RK23' is not supported on the {path} "
                                             r"path; .* other than 'RK45' and 'DOP853'"):
            run(path, timer(), [0.0], t_max=1.0, method="RK23")
        with pytest.raises(ValueError, match="method must be one of"):
            run(path, timer(), [0.0], t_max=1.0, method="dop853")
    else:
        from hybridsim.options import method_on
        with pytest.raises(ValueError, match="path must be one of"):
            method_on(path, "DOP853")           # every method there: no list to check


@pytest.mark.parametrize("sets", SETS)
@pytest.mark.parametrize("refine", [1, 2, 4])
@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_a_jump_at_t_max_stores_every_sample_once(path, sets, refine, method):
    """The timer x' = 1, D = {x >= 0.5}, g = 0 to t_max = 1: jumps at 0.5 and 1.0,
    samples refine - 1 per step, none twice, time never running backwards."""
    case = timer(0.5, sets)
    arc = run(path, case, [0.0], t_max=1.0, refine=refine, warn=False, method=method)
    assert_invariants(arc, case, "jumps", 1.0, math.inf)
    np.testing.assert_allclose(arc.jump_times, [0.5, 1.0], atol=1e-12)
    assert arc.t[-1] == 1.0 and arc.j[-1] == 2
    ref = run("python", case, [0.0], t_max=1.0, refine=refine, warn=False, method=method)
    np.testing.assert_allclose(arc.t, ref.t, atol=1e-12)
    np.testing.assert_array_equal(arc.j, ref.j)
    # refined samples carry the dense output's derivative (RK45), none for DOP853
    np.testing.assert_array_equal(np.isnan(arc.xdot), np.isnan(ref.xdot))


@pytest.mark.parametrize("bad, error, match", [
    (dict(refine=True), TypeError, "refine must be an int >= 1"),
    (dict(refine=0), ValueError, "refine must be >= 1"),
    (dict(zeno_jumps=0), ValueError, "zeno_jumps must be >= 1"),
    (dict(rtol=-1.0), ValueError, "rtol must be > 0"),
    (dict(priority="sometimes"), ValueError, "priority must be one of"),
    (dict(t_max=-1.0), ValueError, "t_max must be >= t0"),
    (dict(max_steps=0), ValueError, "max_steps must be >= 1"),
    (dict(throw="yes"), TypeError, "throw must be True or False"),
    (dict(warn=1), TypeError, "warn must be True or False"),
])
def test_the_same_bad_input_gets_the_same_error_on_every_path(path, bad, error, match):
    kw = dict(t_max=1.0)
    kw.update(bad)
    with pytest.raises(error, match=match):
        run(path, timer(), [0.0], **kw)


@pytest.mark.paths(only=("vectorized", "compiled"))
@pytest.mark.parametrize("option, value", [
    ("dense", True), ("t_eval", [0.0, 0.5]), ("prehistory", lambda s: np.zeros(1)),
    ("method", "Radau"),
])
def test_options_a_path_does_not_implement_are_refused_by_name(path, option, value):
    with pytest.raises(ValueError, match=rf"{option}=.* is not supported on the {path} path"):
        run(path, timer(), [0.0], t_max=1.0, **{option: value})


@pytest.mark.parametrize("method", ["RK45", "DOP853"])
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
def test_overflow_is_non_finite_on_every_path(path, method):
    """A ball (x' = (v, -9.81), C = {h >= 0}, D = {-h >= 0}) from (1e308, 1e308):
    the flow at x0 is finite, the state overflows inside the first step. That is
    NON_FINITE with a warning, never a set exit at x0, with either method."""
    case = Linear(np.array([[0.0, 1.0], [0.0, 0.0]]), np.zeros((2, 2)), np.zeros(2),
                  np.array([-1.0, 0.0]), 0.0, np.array([1.0, 0.0]), 0.0,
                  k=np.array([0.0, -9.81]))
    with pytest.warns(hs.SimulationWarning, match="NON_FINITE"):
        arc = run(path, case, [1e308, 1e308], t_max=1.0, throw=False, method=method)
    assert arc.termination is T.NON_FINITE, (arc.termination, arc.message)
    arc.validate()


def test_a_map_error_at_x0_carries_an_arc_with_its_cause(path):
    case = timer()
    case.k = np.array([np.nan])          # the flow map returns NaN at x0
    with pytest.raises(hs.MapError) as info:
        run(path, case, [0.0], t_max=1.0)
    assert info.value.arc is not None
    assert info.value.arc.termination is T.MAP_ERROR


def test_failures_warn_the_same_way_on_every_path(path):
    case, x0 = random_linear(5, 2, False)
    with pytest.warns(hs.SimulationWarning, match="MAX_STEPS"):
        arc = run(path, case, x0, t_max=5.0, max_steps=3)
    assert arc.termination is T.MAX_STEPS


@pytest.mark.parametrize("sets", ["both", "indicators"])
def test_max_norm_is_checked_at_an_event_sample(path, sets):
    """The ball from 1 m hits the floor at |v| = sqrt(2 g) = 4.43 m/s: with
    max_norm 4 the run ends BLOWUP at the impact's pre-jump sample (it used to
    jump on, ending J_MAX, on every path: a step ending on an event skipped the
    norm check); with max_norm 5 it bounces."""
    impact = np.sqrt(2 / 9.81)
    arc = run(path, Ball(sets=sets), [1.0, 0.0], t_max=2.0, j_max=3, rtol=1e-10, atol=1e-12,
              max_norm=4.0, warn=False)
    assert arc.termination is T.BLOWUP and arc.jump_count == 0
    assert arc.t[-1] == pytest.approx(impact, abs=1e-9)
    assert np.linalg.norm(arc.x[-1]) == pytest.approx(np.sqrt(2 * 9.81), rel=1e-8)
    arc.validate()
    arc = run(path, Ball(sets=sets), [1.0, 0.0], t_max=2.0, j_max=3, rtol=1e-10, atol=1e-12,
              max_norm=5.0, warn=False)
    assert arc.termination is T.J_MAX


@pytest.mark.parametrize("sets", ["both", "indicators"])
@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_the_ball_bounces_at_its_closed_form_times_on_every_path(path, sets, method):
    from hybridsim.library import bouncing_ball_jump_times
    arc = run(path, Ball(sets=sets), [1.0, 0.0], t_max=10.0, j_max=12, rtol=1e-10,
              atol=1e-12, method=method)
    assert arc.termination is T.J_MAX
    np.testing.assert_allclose(arc.jump_times, bouncing_ball_jump_times(1.0, 12, 9.81, 0.8),
                               rtol=0, atol=1e-9)
    arc.validate()


@pytest.mark.parametrize("sets", ["both", "indicators"])
def test_a_jump_map_that_keeps_the_located_position_runs_on(path, sets):
    """x+ = (h, -0.8 v): the located height is a few ulp below the floor, the
    post-jump state (rising) outside C and D at full precision. Within the
    event's own location error of C, it counts as in C (rules.post_jump_probe)
    on every path: the ball bounces on, never LEFT_SETS."""
    arc = run(path, Ball(sets=sets, keep=True), [1.0, 0.0], t_max=10.0, j_max=12,
              rtol=1e-10, atol=1e-12)
    assert arc.termination is T.J_MAX, arc.message
    assert arc.jump_count == 12
    assert np.all(np.abs(arc.x[:, 0]) < 2.0) and arc.x[arc.is_jump_end, 0].min() > -1e-12


def test_a_jump_loop_is_named_on_every_path(path):
    """Guards only: D = {-h >= 0} still holds after the impact (height 0,
    rising), so the ball jumps again and again at one instant. The run ends
    by the limits as always (J_MAX here), and the message says what is wrong."""
    arc = run(path, Ball(sets="guards"), [1.0, 0.0], t_max=10.0, j_max=30)
    assert arc.termination is T.J_MAX
    assert "jump loop" in arc.message and "jump_set" in arc.message, arc.message
    assert np.ptp(arc.jump_times) == 0.0


def test_a_nan_guard_is_a_map_error_naming_the_guard(path):
    with pytest.raises(hs.MapError, match="jump_guard") as info:
        run(path, Ball(sets="both", nan_below=0.5), [1.0, 0.0], t_max=2.0, j_max=3)
    assert info.value.arc.termination is T.MAP_ERROR
    info.value.arc.validate()
    assert info.value.arc.t[-1] < 0.33           # it fell from 1 to 0.5 in 0.319 s


def test_a_given_jump_guard_is_used_beside_a_flow_set_indicator(path):
    """A flight whose apex is 1e-6 above the jump guard h - 1: with C an
    indicator (h >= -1e-9) and D given by its guard, the jump is found
    inside the step (the guard's maximum is refined) on every path."""
    v0 = math.sqrt(2 * 9.81 * (1 + 1e-6))
    case = Linear(np.array([[0.0, 1.0], [0.0, 0.0]]), np.diag([0.0, 1.0]), np.zeros(2),
                  np.array([1.0, 0.0]), 1.0, np.array([1.0, 0.0]), -1e-9, sets="guards",
                  sets_C="indicators", k=np.array([0.0, -9.81]))
    arc = run(path, case, [0.0, v0], t_max=0.6, j_max=1)
    assert arc.jump_count == 1, arc.message
    t1 = (v0 - math.sqrt(v0**2 - 2 * 9.81)) / 9.81     # h(t1) = 1, 0.45 ms before the apex
    np.testing.assert_allclose(arc.jump_times, [t1], rtol=0, atol=1e-9)


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(),
                    reason="Python runs signal handlers in the main thread")
def test_ctrl_c_ends_the_run_with_canceled_and_the_arc_so_far(path):
    """One SIGINT, raised once the run is under way (paths.one_sigint_inside_the_run:
    a helper thread watching the main thread's frames, no clock): CANCELED, the
    arc so far (valid), the message naming its last sample. The sample cap only
    ends a run that the signal did not reach."""
    case = timer(1e-2)           # runs until interrupted: no horizon
    run(path, case, [0.0], t_max=0.05)     # compiled first: the signal must hit the run
    # the cap: a run the signal missed fails in about a minute instead of running
    # on (the kernel's 5e6 samples take seconds; the loops' 2e5 some tens)
    cap = 5_000_000 if path == "compiled" else 200_000
    with one_sigint_inside_the_run() as sig:
        arc = run(path, case, [0.0], t_max=math.inf, max_samples=cap,
                  max_steps=math.inf, zeno_jumps=10**9, warn=False)
    assert sig.sent, "no run was seen under way"
    assert arc.termination is T.CANCELED, arc.message
    arc.validate()
    assert f"t={arc.t[-1]:.10g}" in arc.message and f"j={arc.j[-1]}" in arc.message
    # the arc so far is the timer's: a jump every 1e-2 (each located to the event
    # tolerance; their sum drifts by round-off over tens of thousands of jumps)
    assert arc.jump_count >= 1 and arc.jump_times[0] == pytest.approx(1e-2, abs=1e-12)
    np.testing.assert_allclose(np.diff(arc.jump_times), 1e-2, rtol=0, atol=1e-9)


@pytest.mark.paths(only=("python", "vectorized"))
@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(),
                    reason="Python runs signal handlers in the main thread")
def test_a_ctrl_c_whose_exception_is_lost_still_ends_the_run(path):
    """A SIGINT whose KeyboardInterrupt lands in code that discards it (here a
    flow map that swallows it, as a __del__ or a C probe does): the loop's latch
    raises it again, and the run ends CANCELED instead of running on to its cap."""
    import signal
    calls = [0]

    def flow(x):
        calls[0] += 1
        if calls[0] == 50:
            try:
                signal.raise_signal(signal.SIGINT)
                for _ in range(10):          # bytecodes: the handler runs here
                    pass
            except KeyboardInterrupt:
                pass                         # lost, as CPython loses it in a __del__
        return np.ones_like(x)

    vec = path == "vectorized"
    sysm = hs.HybridSystem.from_functions(
        flow_map=flow, jump_map=lambda x: np.zeros_like(x),
        jump_guard=(lambda x: x[:, 0] - 1e-2) if vec else (lambda x: x[0] - 1e-2),
        state_dim=1, vectorized=vec)
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        if vec:
            arc = hs.simulate_vectorized(sysm, [[0.0]], t_max=math.inf, max_samples=20_000,
                                         max_steps=math.inf, zeno_jumps=10**9, warn=False)[0]
        else:
            arc = hs.simulate(sysm, [0.0], t_max=math.inf, max_samples=20_000,
                              max_steps=math.inf, zeno_jumps=10**9, warn=False)
    finally:
        signal.signal(signal.SIGINT, old)
    assert calls[0] >= 50
    assert arc.termination is T.CANCELED, arc.message
    arc.validate()


# ------------------------------------------------------------------ issue 25
def test_a_dwell_law_runs_on_the_python_path_and_is_refused_by_name_elsewhere(path):
    """dwell (the time in C ∩ D under priority="random") is the Python path's:
    there a dwell of 0 is priority "jumps"; the other paths refuse it by
    name through options.refuse, with the same message shape."""
    case = timer(0.5, sets="both")
    if path == "python":
        a = run(path, case, [0.0], t_max=2.0, priority="random", dwell=lambda rng: 0.0)
        b = run(path, case, [0.0], t_max=2.0, priority="jumps")
        np.testing.assert_allclose(a.jump_times, b.jump_times, rtol=0, atol=TOL_EVENT)
        return
    with pytest.raises(ValueError, match=rf"dwell=.* is not supported on the {path} path; "
                                         r"use hs.simulate \(the Python path\) or hs.explore"):
        run(path, case, [0.0], t_max=2.0, priority="random", dwell=lambda rng: 0.0)
    if path == "compiled":
        with pytest.raises(ValueError, match=r"dwell=.* is not supported on the compiled path"):
            hs.simulate(case.build("python"), [0.0], t_max=2.0, priority="random",
                        dwell=lambda rng: 0.0, backend="compiled")


def test_a_set_valued_jump_map_is_the_python_paths(path):
    """A system declaring jump_map_values: the Python path jumps to the first
    successor; the others refuse the system naming jump_map_values."""
    import copy
    successors = lambda x: [np.zeros(1), np.full(1, 0.25)]  # noqa: E731
    if path == "python":
        system = hs.HybridSystem.from_functions(
            flow_map=lambda x: np.ones(1), jump_guard=lambda x: x[0] - 0.5,
            jump_map_values=successors,
            state_dim=1)
        arc = hs.simulate(system, [0.0], t_max=1.0)
        np.testing.assert_allclose(arc.jump_times, [0.5, 1.0], rtol=0, atol=TOL_EVENT)
        return
    system = copy.copy(timer(0.5, sets="both").build(path))
    system.jump_map_values = successors
    with pytest.raises(ValueError, match="declares jump_map_values .* only the Python path"):
        if path == "vectorized":
            hs.simulate_vectorized(system, np.zeros((1, 1)), t_max=1.0)
        else:
            from hybridsim.compiled import simulate_compiled
            simulate_compiled(system, [0.0], t_max=1.0)


# ---------------------------------------------------------------- delays (the past)
class _Lag(hs.HybridSystem):
    """x0' = -a x0(t - tau) + b sin t, x1' = 1 (a timer), a reset x0+ = c x0, x1+ = 0
    at x1 >= s (D by a guard): maps written with ``[..., k]`` serve one state and a
    batch, so one class runs on the Python and the vectorized paths."""

    state_dim, needs_history, vectorized = 2, True, True

    def __init__(self, a=1.0, b=0.0, c=1.0, tau=1.0, s=1e9, max_step="tau"):
        self.a, self.b, self.c, self.tau, self.s = a, b, c, tau, s
        self.delays = (tau,)
        self.max_step = tau if max_step == "tau" else max_step

    def flow_map(self, x, t, j, u):
        out = np.zeros_like(np.asarray(x, dtype=float))
        out[..., 0] = -self.a * self.history(t - self.tau)[..., 0] + self.b * np.sin(t)
        out[..., 1] = 1.0
        return out

    def jump_guard(self, x, t, j, u):
        return x[..., 1] - self.s

    def jump_map(self, x, t, j, u):
        y = np.array(x, dtype=float)
        y[..., 0] = self.c * x[..., 0]
        y[..., 1] = 0.0
        return y


def _lag_flow(x, t, j, p):            # p: a, b, c, tau, s, then x(t - tau) (2)
    return np.array([-p[0] * p[5] + p[1] * np.sin(t), 1.0])


def _lag_guard(x, t, j, p):
    return x[1] - p[4]


def _lag_jump(x, t, j, p):
    return np.array([p[2] * x[0], 0.0])


def _compiled_lag(system):
    """``_Lag`` as a CompiledSystem: the flow map reads x(t - tau) from ``p``."""
    from hybridsim.compiled import CompiledSystem
    s = system
    cs = CompiledSystem(flow_map=_lag_flow, jump_map=_lag_jump, jump_guard=_lag_guard, state_dim=2,
                        params=[s.a, s.b, s.c, s.tau, s.s], delays=(s.tau,))
    cs.max_step = s.max_step        # None: uncapped (the constructor caps it at tau)
    return cs


def _run_lag(path, system, x0, **kw):
    if path == "python":
        return hs.simulate(system, x0, **kw)
    if path == "vectorized":
        return hs.simulate_many(system, np.atleast_2d(x0), **kw)[0]
    return hs.simulate(_compiled_lag(system), x0, backend="compiled", **kw)


def test_a_delay_equation_runs_on_every_path(path):
    """x' = -x(t - 1) from the constant past 1: x = 1 - t on [0, 1] and
    1 - t + (t - 1)^2 / 2 on [1, 2] (method of steps), to the integrator's
    rtol 1e-10 (1e-9 absolute). The compiled path runs its CompiledSystem twin
    (the past in the flow map's ``p``)."""
    kw = dict(t_max=2.0, rtol=1e-10, atol=1e-12)
    arc = _run_lag(path, _Lag(), [1.0, 0.0], **kw)
    t = arc.t
    exact = np.where(t <= 1.0, 1.0 - t, 1.0 - t + (t - 1.0) ** 2 / 2)
    np.testing.assert_allclose(arc.x[:, 0], exact, atol=1e-9)
    assert arc.termination is T.T_MAX and np.any(np.isclose(t, 1.0, atol=1e-15))


def test_dop853_with_delays_is_the_python_paths_and_refused_by_name_elsewhere(path):
    """A delay equation with method="DOP853": the Python path steps it (its
    history reads DOP853's dense output) to the method of steps' solution,
    also for the CompiledSystem twin under backend="auto" and for the
    vectorized system through simulate_many (which fall back to it); the
    vectorized and compiled paths refuse it by name."""
    kw = dict(t_max=2.0, rtol=1e-10, atol=1e-12, method="DOP853")
    if path == "python":
        for arc in (_run_lag(path, _Lag(), [1.0, 0.0], **kw),
                    hs.simulate(_compiled_lag(_Lag()), [1.0, 0.0], backend="auto", **kw)):
            t = arc.t
            exact = np.where(t <= 1.0, 1.0 - t, 1.0 - t + (t - 1.0) ** 2 / 2)
            np.testing.assert_allclose(arc.x[:, 0], exact, atol=1e-9)
        return
    if path == "vectorized":
        with pytest.raises(ValueError, match=r"method='DOP853' for a system that reads its past "
                                             r"\(delays\) is not supported on the vectorized"):
            hs.simulate_vectorized(_Lag(), np.array([[1.0, 0.0]]), **kw)
        arc = hs.simulate_many(_Lag(), np.array([[1.0, 0.0]]), **kw)[0]   # per run
        t = arc.t
        exact = np.where(t <= 1.0, 1.0 - t, 1.0 - t + (t - 1.0) ** 2 / 2)
        np.testing.assert_allclose(arc.x[:, 0], exact, atol=1e-9)
        return
    with pytest.raises(ValueError, match=r"method='DOP853' for a system that reads its past "
                                         r"\(delays\) is not supported on the compiled"):
        _run_lag(path, _Lag(), [1.0, 0.0], **kw)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_delay_systems_with_jumps_agree_on_the_python_and_vectorized_paths(seed):
    """Seeded random delays, gains, resets and forcing: a batch of 6 rows on the
    vectorized path gives each row's Python-path solution (jump times to 1e-9,
    states to 1e-7 at rtol 1e-10: the two paths read the past from the same RK45
    dense output, but round-off moves their step sequences apart)."""
    rng = np.random.default_rng(seed)
    sys_ = _Lag(a=rng.uniform(0.5, 2.0), b=rng.uniform(-1, 1), c=rng.uniform(-0.9, 0.9),
                tau=rng.uniform(0.2, 0.6), s=rng.uniform(0.3, 0.8))
    X = np.column_stack([rng.uniform(-1, 1, 6), rng.uniform(0.0, 0.3, 6)])
    kw = dict(t_max=3.0, j_max=8, rtol=1e-10, atol=1e-12)
    arcs = hs.simulate_many(sys_, X, **kw)
    for x0, b in zip(X, arcs):
        a = hs.simulate(sys_, x0, **kw)
        assert a.termination is b.termination
        np.testing.assert_allclose(b.jump_times, a.jump_times, atol=1e-9)
        np.testing.assert_allclose(b.x[-1], a.x[-1], atol=1e-7)
        # the past is read at the located jump times too: x0 after each reset
        np.testing.assert_allclose(b.x[b.j > 0][:1], a.x[a.j > 0][:1], atol=1e-7)


@pytest.mark.paths(compiled_slow=True, only=("compiled",))
@pytest.mark.parametrize("seed", range(4))
def test_delay_systems_with_jumps_agree_on_the_python_and_compiled_paths(path, seed):
    """The seeded systems above as CompiledSystem twins: compiled single runs and
    a compiled batch give the Python path's solution (jump times to 1e-9, states
    to 1e-7 at rtol 1e-10, as above); the twin's own maps on the Python path
    give the compiled run's jump times to 1e-12 and end states to 1e-7
    (measured 2.4e-9 on one machine, 1.9e-8 on another: the kernel's
    arithmetic differs from numpy's in round-off, e.g. fused multiply-adds, and
    at rtol 1e-10 the error estimate turns that into other step sizes from the
    third step on, so the end states agree to the runs' accuracy over the
    horizon, the bound of the comparison with the Python path above)."""
    rng = np.random.default_rng(seed)
    sys_ = _Lag(a=rng.uniform(0.5, 2.0), b=rng.uniform(-1, 1), c=rng.uniform(-0.9, 0.9),
                tau=rng.uniform(0.2, 0.6), s=rng.uniform(0.3, 0.8))
    twin = _compiled_lag(sys_)
    X = np.column_stack([rng.uniform(-1, 1, 4), rng.uniform(0.0, 0.3, 4)])
    kw = dict(t_max=3.0, j_max=8, rtol=1e-10, atol=1e-12)
    batch = hs.simulate_many(twin, X, backend="compiled", **kw)
    for x0, b in zip(X, batch):
        a = hs.simulate(sys_, x0, **kw)
        c = hs.simulate(twin, x0, backend="compiled", **kw)
        p = hs.simulate(twin, x0, backend="python", **kw)
        assert a.termination is c.termination is b.termination
        np.testing.assert_allclose(c.jump_times, a.jump_times, atol=1e-9)
        np.testing.assert_allclose(c.x[-1], a.x[-1], atol=1e-7)
        np.testing.assert_array_equal(b.t, c.t)
        np.testing.assert_array_equal(b.x, c.x)
        np.testing.assert_allclose(p.jump_times, c.jump_times, rtol=0, atol=1e-12)
        np.testing.assert_allclose(p.x[-1], c.x[-1], rtol=0, atol=1e-7)
        # breakpoints t_k + tau of the jumps (and t0 + tau) are samples
        for tb in [kw.get("t0", 0.0) + sys_.tau, *(c.jump_times + sys_.tau)]:
            if tb < c.t[-1]:
                assert np.min(np.abs(c.t - tb)) < 1e-12


@pytest.mark.paths(only=("python", "compiled"))
def test_maps_other_than_the_flow_map_see_no_past(path):
    """A CompiledSystem with delays whose jump guard reads the past's place in
    ``p``: NaN there on both paths that run it (a CompiledSystem has no batch
    form), so the run ends MAP_ERROR naming the guard (never a stale value)."""
    from hybridsim.compiled import CompiledSystem
    twin = CompiledSystem(flow_map=_lag_flow, jump_map=_lag_jump,
                          jump_guard=lambda x, t, j, p: x[1] - p[4] + 0.0 * p[5],
                          state_dim=2, params=[1.0, 0.0, 0.5, 0.5, 0.3], delays=(0.5,))
    with pytest.raises(hs.MapError, match="jump_guard returned NaN") as info:
        hs.simulate(twin, [1.0, 0.0], t_max=1.0,
                    backend="compiled" if path == "compiled" else "python")
    assert info.value.arc.termination is T.MAP_ERROR


def test_compiled_system_delays_are_checked_and_cap_the_step():
    from hybridsim.compiled import CompiledSystem
    for bad in [(-1.0,), (float("nan"),), (0.0,)]:
        with pytest.raises(ValueError, match="delays must be positive finite floats"):
            CompiledSystem(flow_map=_lag_flow, state_dim=2, delays=bad)
    with pytest.raises(TypeError, match="delays must be a sequence"):
        CompiledSystem(flow_map=_lag_flow, state_dim=2, delays="a")
    cs = CompiledSystem(flow_map=_lag_flow, state_dim=2, delays=(0.5, 0.2), max_step=1.0)
    assert cs.max_step == 0.2 and cs.needs_history and cs.delays == (0.5, 0.2)


def test_a_past_inside_the_step_under_way_is_a_map_error_on_every_path(path):
    """Delay 0.1 with no cap on the step: the flow map reads a time inside the
    step being taken; every path ends with MAP_ERROR and the same message."""
    arc = _run_lag(path, _Lag(tau=0.1, max_step=None), [1.0, 0.0], t_max=1.0, throw=False,
                   warn=False)
    assert arc.termination is T.MAP_ERROR
    assert "lies in the solver step under way" in arc.message
    assert "cap the step with max_step" in arc.message
    if path == "compiled":          # the same first missing value, time and words
        ref = _run_lag("python", _Lag(tau=0.1, max_step=None), [1.0, 0.0], t_max=1.0,
                       throw=False, warn=False)
        assert arc.message == ref.message


def test_an_interconnection_reads_its_components_past_on_the_vectorized_path():
    """A plant x' = -x feeding a component that reads its own past: z' = y - z(t - 0.5).
    The components' history views slice the batch's rows (ComponentHistory on (k, n))."""
    plant = hs.LinearPlant(np.array([[-1.0]]), C=np.eye(1))
    assert plant.vectorized

    class Echo(hs.HybridSystem):
        state_dim, input_dim, needs_history, vectorized = 1, 1, True, True
        delays, max_step = (0.5,), 0.5

        def flow_map(self, z, t, j, u):
            return u - self.history(t - 0.5)

    sys_ = hs.connect(plant, Echo(), names=("plant", "echo"))
    assert sys_.vectorized and sys_.needs_history        # one batch, not rows through simulate
    X = np.array([[1.0, 0.0], [2.0, 1.0], [-1.0, 0.5]])
    kw = dict(t_max=2.0, rtol=1e-10, atol=1e-12)
    arcs = hs.simulate_many(sys_, X, **kw)
    for x0, b in zip(X, arcs):
        a = hs.simulate(sys_, x0, **kw)
        np.testing.assert_allclose(b.x[-1], a.x[-1], atol=1e-8)


def test_a_guard_that_is_never_reached_runs_quietly_on_every_path(path):
    """D = {x >= inf}: the guard is -inf everywhere ("never"); no event, no
    RuntimeWarning (the vectorized path's peak test once subtracted -inf from -inf)."""
    import warnings
    case = Linear(np.array([[-1.0]]), np.eye(1), np.zeros(1), np.array([1.0]), np.inf)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        arc = run(path, case, [1.0], t_max=1.0)
    assert arc.termination is T.T_MAX and len(arc.jump_times) == 0
    np.testing.assert_allclose(arc.x[-1, 0], np.exp(-1.0), rtol=1e-5)


class _Window(_Lag):
    """x0' = 1 - int_{t-1.5}^{t-0.5} x0(s) cos s ds (an integral of the past), the
    timer's reset every s scaling x0 by c; ``fn`` written with ``[..., 0]`` serves
    one state (Python path) and a batch (vectorized)."""

    def __init__(self, **kw):
        super().__init__(tau=0.5, **kw)
        self.delays = (0.5, 1.5)

    def flow_map(self, x, t, j, u):
        w = self.history.integral(lambda x, s: x[..., 0] * np.cos(s), t - 1.5, t - 0.5)
        out = np.zeros_like(np.asarray(x, dtype=float))
        out[..., 0] = 1.0 - w
        out[..., 1] = 1.0
        return out


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(2))
def test_an_integral_of_the_past_agrees_on_the_python_and_vectorized_paths(seed):
    """Each row's window integral on the vectorized path (Gauss-Legendre on its own
    steps and on the constant past) gives the Python path's solution, to 1e-9 at
    rtol 1e-10 (measured 1e-11)."""
    rng = np.random.default_rng(seed)
    sys_ = _Window(c=rng.uniform(-0.9, 0.9), s=rng.uniform(0.2, 0.5))
    X = np.column_stack([rng.uniform(-1, 1, 4), rng.uniform(0.0, 0.2, 4)])
    kw = dict(t_max=3.0, j_max=50, rtol=1e-10, atol=1e-12)
    for x0, b in zip(X, hs.simulate_many(sys_, X, **kw)):
        a = hs.simulate(sys_, x0, **kw)
        np.testing.assert_allclose(b.jump_times, a.jump_times, atol=1e-9)
        np.testing.assert_allclose(b.x[-1], a.x[-1], atol=1e-9)


def test_a_component_reads_its_past_input_on_the_vectorized_path():
    """A component integrating its own input from tau ago (z' = u(t - 0.3)), fed by a
    plant x' = -x: its ComponentHistory's input(s) over a batch's rows (the wiring
    evaluated on the rows' past states) gives the Python path's solution."""
    plant = hs.LinearPlant(np.array([[-1.0]]), C=np.eye(1))

    class Delayed(hs.HybridSystem):
        state_dim, input_dim, needs_history, vectorized = 1, 1, True, True
        delays, max_step = (0.3,), 0.3

        def flow_map(self, z, t, j, u):
            return np.asarray(self.history.input(t - 0.3), dtype=float).reshape(np.shape(z))

    sys_ = hs.connect(plant, Delayed(), names=("plant", "lag"))
    assert sys_.vectorized
    X = np.array([[1.0, 0.0], [-2.0, 0.5]])
    kw = dict(t_max=1.5, rtol=1e-10, atol=1e-12)
    for x0, b in zip(X, hs.simulate_many(sys_, X, **kw)):
        a = hs.simulate(sys_, x0, **kw)
        np.testing.assert_allclose(b.x[-1], a.x[-1], atol=1e-9)
        # z(1.5) = z0 + 0.3 x0 + int_0^1.2 x0 e^{-s} ds (the past before 0 is x0)
        np.testing.assert_allclose(b.x[-1, 1], x0[1] + x0[0] * (0.3 + 1 - np.exp(-1.2)),
                                   atol=1e-8)


@pytest.mark.paths(only=("python", "vectorized"))
@pytest.mark.parametrize("delays", [(-1.0,), (float("nan"),), (0.0,)])
def test_bad_delays_get_the_same_error_on_every_path(path, delays):
    sys_ = _Lag()
    sys_.delays = delays
    with pytest.raises(ValueError, match="system.delays must be positive finite floats"):
        _run_lag(path, sys_, [1.0, 0.0], t_max=1.0)


@pytest.mark.parametrize("seed", [3, 11])
def test_rk4_takes_fixed_steps_on_every_path(path, seed):
    """method="RK4": steps of max_step (shortened only at events and t_max), the
    same steps on every path, and the RK45 solution to RK4's error (h^4)."""
    case, x0 = random_linear(seed, 2, False)
    h, t_max = 2e-3, 3.0
    kw = dict(t_max=t_max, j_max=8, method="RK4", max_step=h, warn=False)
    arc = run(path, case, x0, **kw)
    ref = run("python", case, x0, **OPTS | dict(t_max=t_max, j_max=8))
    assert arc.termination is ref.termination and arc.jump_count == ref.jump_count
    np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-9)
    np.testing.assert_allclose(arc.xf, ref.xf, rtol=1e-8, atol=1e-9)
    steps = np.diff(arc.t)[np.diff(arc.j) == 0]
    full = np.isclose(steps, h, rtol=1e-9, atol=0)
    assert full.sum() >= len(steps) - 2 * (arc.jump_count + 1)    # short: before an event
    assert np.all(steps <= h * (1 + 1e-9))
    py = run("python", case, x0, **kw)
    np.testing.assert_allclose(arc.t, py.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(arc.x, py.x, rtol=1e-10, atol=1e-12)


class _Lagged(hs.HybridSystem):
    """x'(t) = -x(t - 1), x = 1 on [-1, 0]: on the last axis (a batch reads its rows' past)."""

    state_dim = 1
    needs_history = True
    delays = (1.0,)
    vectorized = True

    def flow_map(self, x, t):
        return -self.history(t - 1.0)


def _lagged_exact(t):
    """The method of steps on [0, 4]: a quartic by pieces."""
    return (1 - t + np.maximum(t - 1, 0) ** 2 / 2 - np.maximum(t - 2, 0) ** 3 / 6
            + np.maximum(t - 3, 0) ** 4 / 24)


@pytest.mark.paths(only=("python", "vectorized"))
def test_rk4_reads_the_past_through_its_continuous_extension(path):
    """A delay equation with RK4 at h = tau / 10: the flow stops on the breakpoints
    (t = 1, 2, 3 on the grid), and the solution, a polynomial of degree <= 4 on
    each piece, is exact to round-off (RK4 integrates it exactly and its
    continuous extension of order 3 returns the past exactly at the stages)."""
    kw = dict(t_max=4.0, method="RK4", max_step=0.1)
    if path == "python":
        arc = hs.simulate(_Lagged(), [1.0], **kw)
    else:
        arc = hs.simulate_vectorized(_Lagged(), [[1.0], [1.0]], **kw)[1]
    assert arc.stats["steps"] == 40
    np.testing.assert_allclose(arc.x[:, 0], _lagged_exact(arc.t), rtol=0, atol=1e-13)


@pytest.mark.paths(only=("compiled",))
def test_rk4_compiled_arc_is_the_python_paths_to_round_off(path):
    """method="RK4" on the compiled kernel takes the Python path's steps: a
    bouncing ball at h = 1e-3 gives the same samples, times and jumps, and its
    states to round-off (the kernel sums the same stages in the same order)."""
    from hybridsim.library import BouncingBall
    kw = dict(t_max=3.0, j_max=10, method="RK4", max_step=1e-3)
    py = hs.simulate(BouncingBall(), [1.0, 0.0], backend="python", **kw)
    arc = hs.simulate(BouncingBall(), [1.0, 0.0], backend=path, **kw)
    assert arc.termination is py.termination and arc.jump_count == py.jump_count
    np.testing.assert_array_equal(arc.j, py.j)
    np.testing.assert_allclose(arc.t, py.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(arc.x, py.x, rtol=0, atol=1e-12)
