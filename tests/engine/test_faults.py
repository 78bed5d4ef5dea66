"""The engine under bad inputs and faults (issue 16): no missed jump, no
silent failure, no runaway, the right cause.

What this file tries, and what each gets (183 runs in 71 tests):

* 105 apex runs (7 heights from 0.3 down to 1e-6 above the guard x 3
  tolerances x 5 methods) of a flow entering and leaving D inside one solver
  step: each makes its jump, at the closed-form time; 1 more under flows
  priority (leaving C and coming back), and 6 with set indicators only under
  both priorities.
* 24 timers whose jumps land on t_max up to round-off (periods 0.1, 0.25, 1,
  1/3; t_max 1, 2, 10; guards and indicators): every jump taken.
* 23 bad arguments (j0, seed, atol, dense, throw, warn, progress, method,
  refine, max_steps, zeno_rtol, t_eval, a complex x0): a TypeError or
  ValueError naming the argument.
* 11 maps: a defaulted parameter and a ufunc get the right result; complex,
  wrong-shape, NaN and string values from maps, sets and guards, at x0 and
  mid-run, and a jump map raising at its first jump: a MapError naming the
  map, t and j, chained from the original, with the arc so far.
* 10 failures and runaways (NaN flow, blow-up with warn=False, max_steps,
  t_max = inf, max_samples, chattering with a 1e-9 hysteresis, a stiff and a
  non-stiff flow, a ball sticking to a moving floor, Ctrl-C): the right cause,
  the arc so far, one warning where the computation failed.
* t_eval: samples at the given times, both samples of a jump at a jump time.

Batches under faults are in tests/integration/test_batch_faults.py; random systems in
tests/integration/test_fuzz.py.
"""
import math
import warnings

import numpy as np
import pytest
from scipy.integrate import OdeSolver

import hybridsim as hs
from hybridsim import Termination


# ------------------------------------------------------------- missed jumps
def apex_system(guard=True, priority_flows=False):
    """x'' = -1 with D = {x >= 1}; the jump reverses the velocity downwards."""
    kw = {}
    if guard:
        kw["jump_guard"] = lambda x: x[0] - 1.0
        if priority_flows:
            kw["flow_guard"] = lambda x: 1.0 - x[0]
    else:
        kw["jump_set"] = lambda x: x[0] >= 1.0
        if priority_flows:
            kw["flow_set"] = lambda x: x[0] <= 1.0
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[1], -1.0]), jump_map=lambda x: np.array([x[0], -abs(x[1])]),
        state_dim=2, **kw)


def first_crossing(v0):
    return v0 - math.sqrt(v0 * v0 - 2.0)


@pytest.mark.parametrize("method", ["RK45", "RK23", "DOP853", "Radau", "LSODA"])
@pytest.mark.parametrize("rtol", [1e-3, 1e-6, 1e-10])
def test_jump_set_entered_and_left_within_one_step_is_found(method, rtol):
    # RK45 integrates the parabola exactly, so one step spans the excursion
    # above the guard; the apex is 0.3 down to 1e-6 above it
    for d in (0.3, 0.1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
        v0 = math.sqrt(2.0 * (1.0 + d))
        arc = hs.simulate(apex_system(), [0.0, v0], t_max=1.5 * v0, j_max=1,
                          method=method, rtol=rtol, atol=rtol * 1e-3)
        assert arc.jump_count == 1, (method, rtol, d)
        # the jump time to the integrator's accuracy (exact for RK45 and DOP853)
        tol = 1e-6 if rtol < 1e-3 else 1e-4
        assert abs(arc.jump_times[0] - first_crossing(v0)) < tol * max(1.0, 1e-3 / d), d


def test_flows_priority_finds_an_exit_from_C_and_back_within_one_step():
    v0 = math.sqrt(2.0 * (1.0 + 1e-5))
    arc = hs.simulate(apex_system(priority_flows=True), [0.0, v0], t_max=1.5 * v0,
                      j_max=1, priority="flows")
    assert arc.jump_count == 1
    assert abs(arc.jump_times[0] - first_crossing(v0)) < 1e-9


@pytest.mark.parametrize("priority", ["jumps", "flows"])
def test_set_indicators_alone_find_an_excursion_longer_than_a_quarter_step(priority):
    # the case: in D for 30% of the flight (apex 0.1 above the guard)
    v0 = math.sqrt(2.2)
    for rtol in (1e-3, 1e-6, 1e-10):
        arc = hs.simulate(apex_system(guard=False, priority_flows=priority == "flows"),
                          [0.0, v0], t_max=1.5 * v0, j_max=1, rtol=rtol, priority=priority)
        assert arc.jump_count == 1
        assert abs(arc.jump_times[0] - first_crossing(v0)) < 1e-12


# --------------------------------------------------------- jumps at t_max
@pytest.mark.parametrize("period", [0.1, 0.25, 1.0, 1.0 / 3.0])
@pytest.mark.parametrize("t_max", [1.0, 2.0, 10.0])
@pytest.mark.parametrize("guard", [True, False])
def test_jump_at_t_max_is_taken_despite_round_off(period, t_max, guard):
    if guard:
        kw = dict(jump_guard=lambda x: x[0] - period, flow_guard=lambda x: period - x[0])
    else:
        kw = dict(jump_set=lambda x: x[0] >= period, flow_set=lambda x: x[0] <= period)
    timer = hs.HybridSystem.from_functions(flow_map=lambda x: np.ones(1),
                                           jump_map=lambda x: np.zeros(1),
                                           state_dim=1, **kw)
    arc = hs.simulate(timer, [0.0], t_max=t_max)
    assert arc.jump_count == round(t_max / period)
    assert arc.tf == t_max and arc.termination is Termination.T_MAX
    # the last jump is at t_max (to round-off) and the last sample after it
    assert abs(arc.jump_times[-1] - t_max) <= 1e-12 and abs(arc.x[-1, 0]) <= 1e-12


@pytest.mark.parametrize("method", ["RK45", "DOP853", "Radau", "BDF", "LSODA"])
@pytest.mark.parametrize("ulps", [1, 2, 8])
def test_jump_a_few_ulp_before_t_max_ends_at_t_max(method, ulps):
    # the jump lands a few ulp before t_max: the flow left is within round-off
    # of nothing (LSODA refuses such a step); the run still ends at t_max, T_MAX
    t_max = 1.0
    tj = t_max - ulps * np.spacing(t_max)
    # x = (clock, mode): one jump, at t = tj, sets the mode to 1
    clock = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0, 0.0]), jump_map=lambda x: np.array([x[0], 1.0]),
        jump_guard=lambda x, t: np.array([t - tj, 0.5 - x[1]]), state_dim=2)
    arc = hs.simulate(clock, [0.0, 0.0], t_max=t_max, method=method)
    assert arc.termination is Termination.T_MAX, arc.message
    assert arc.jump_count == 1 and abs(arc.jump_times[0] - tj) <= 4 * np.spacing(t_max)
    assert arc.tf == t_max and arc.j[-1] == 1
    # the flow after the jump (a few 1e-16 long) moves the clock to t_max
    np.testing.assert_allclose(arc.x[-1], [t_max, 1.0], rtol=0, atol=1e-12)
    assert np.isfinite(arc.xdot[-1]).all()


# ----------------------------------------------------------- bad arguments
def decay():
    return hs.HybridSystem.from_functions(flow_map=lambda x: -x, state_dim=1)


@pytest.mark.parametrize("kw, err, match", [
    (dict(j0=2.7), TypeError, "j0 must be a non-negative int, got float 2.7"),
    (dict(j0=-5), ValueError, "j0 must be >= 0"),
    (dict(j0=None), TypeError, "j0 must be a non-negative int, got NoneType"),
    (dict(j0=True), TypeError, "j0 must be a non-negative int"),
    (dict(seed="abc"), TypeError, "seed must be None, a non-negative int or a numpy Generator"),
    (dict(seed=-1), ValueError, "seed must be >= 0"),
    (dict(atol=[np.inf]), ValueError, "atol must be a positive float or an array"),
    (dict(atol=[np.nan]), ValueError, "atol must be a positive float or an array"),
    (dict(atol=["a"]), TypeError, "atol must be a positive float"),
    (dict(dense="no"), TypeError, "dense must be True or False"),
    (dict(throw=1), TypeError, "throw must be True or False"),
    (dict(warn="yes"), TypeError, "warn must be True or False"),
    (dict(progress="auto"), TypeError, "progress must be True or False or None"),
    (dict(method=OdeSolver), TypeError, "concrete OdeSolver subclass"),
    (dict(refine=2.5), TypeError, "refine must be an int >= 1"),
    (dict(refine=11, max_samples=10), ValueError, "refine must be <= max_samples"),
    (dict(max_steps=0), ValueError, "max_steps must be >= 1"),
    (dict(max_steps="many"), TypeError, "max_steps must be an int >= 1"),
    (dict(zeno_rtol=-1.0), ValueError, "zeno_rtol must be >= 0"),
    (dict(t_eval=[0.5, 0.2]), ValueError, "t_eval must be strictly increasing"),
    (dict(t_eval=[0.5, 2.0]), ValueError, r"t_eval must lie in \[t0, t_max\]"),
    (dict(t_eval=[0.1], refine=3), ValueError, "t_eval and refine > 1 cannot be combined"),
])
def test_bad_arguments_name_the_argument(kw, err, match):
    with pytest.raises(err, match=match):
        hs.simulate(decay(), [1.0], t_max=1.0, **kw)


def test_complex_x0_is_refused():
    with pytest.raises(TypeError, match="x0 must be real"):
        hs.simulate(decay(), [1.0 + 1j], t_max=1.0)


# -------------------------------------------------------------- broken maps
def test_defaulted_parameter_never_receives_t():
    # capturing a value with a default is common Python: k must stay 2
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x, k=2.0: -k * x, state_dim=1)
    arc = hs.simulate(sysm, [1.0], t_max=1.0, rtol=1e-10, atol=1e-12)
    assert abs(arc.xf[0] - math.exp(-2.0)) < 1e-9


def test_ufunc_as_flow_map_takes_x_only():
    arc = hs.simulate(hs.HybridSystem.from_functions(flow_map=np.negative, state_dim=1), [1.0],
                      t_max=1.0, rtol=1e-10, atol=1e-12)
    assert abs(arc.xf[0] - math.exp(-1.0)) < 1e-9


def test_defaulted_engine_arguments_still_count():
    class S(hs.HybridSystem):
        state_dim = 1

        def flow_map(self, x, t, j=0, u=None):     # t required, j/u defaulted by name
            return np.array([t])
    arc = hs.simulate(S(), [0.0], t_max=1.0, rtol=1e-10)
    assert abs(arc.xf[0] - 0.5) < 1e-9


@pytest.mark.parametrize("maps, match", [
    (dict(flow_map=lambda x: np.array([1j])),
     r"flow_map returned complex values .* \(at t=0, j=0\)"),
    (dict(flow_map=lambda x: -x, jump_set=lambda x: "False", jump_map=lambda x: x),
     "jump_set must return a bool .* got str 'False'"),
    (dict(flow_map=lambda x: -x, jump_set=lambda x: float("nan"), jump_map=lambda x: x),
     "jump_set must return a bool .* got float nan"),
    (dict(flow_map=lambda x: -x, jump_set=lambda x: np.array([True, False]), jump_map=lambda x: x),
     "jump_set must return a bool"),
    (dict(flow_map=lambda x: -x, jump_guard=lambda x: np.nan, jump_map=lambda x: x),
     "jump_guard returned NaN"),
])
def test_contract_breaches_at_x0_raise_naming_the_map(maps, match):
    with pytest.raises(hs.MapError, match=match):
        hs.simulate(hs.HybridSystem.from_functions(state_dim=1, **maps), [1.0], t_max=1.0)


def test_flow_map_of_wrong_shape_mid_run_names_flow_map():
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x, t: np.zeros(2) if t > 0.5 else -x, state_dim=1)
    with pytest.raises(hs.MapError, match=r"flow_map must return an array of shape \(1,\), "
                                          r"got shape \(2,\) \(at t=0\.5"):
        hs.simulate(sysm, [1.0], t_max=1.0)


def test_complex_flow_mid_run_is_a_map_error_not_a_cast():
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x, t: np.array([1j]) if t > 0.5 else -x, state_dim=1)
    arc = hs.simulate(sysm, [1.0], t_max=1.0, throw=False)
    assert arc.termination is Termination.MAP_ERROR and "complex" in arc.message
    assert arc.tf <= 0.5 + 1e-12


def test_jump_map_raising_at_first_jump_raises_with_the_arc():
    def g(x):
        raise ZeroDivisionError("bad reset")
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: np.ones(1), jump_map=g,
                                          jump_guard=lambda x: x[0] - 1.0, state_dim=1)
    with pytest.raises(hs.MapError, match=r"jump_map raised ZeroDivisionError: bad reset "
                                          r"\(at t=1, j=0\)") as info:
        hs.simulate(sysm, [0.0], t_max=3.0)
    err = info.value
    assert (err.map_name, err.j) == ("jump_map", 0) and abs(err.t - 1.0) < 1e-12
    assert isinstance(err.__cause__, ZeroDivisionError)
    assert abs(err.arc.tf - 1.0) < 1e-12 and err.arc.termination is Termination.MAP_ERROR


# ------------------------------------------------- failures and runaways
def test_nan_from_the_flow_map_mid_run_is_non_finite_with_one_warning():
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x, t: np.array([np.nan]) if t > 0.5 else -x, state_dim=1)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        arc = hs.simulate(sysm, [1.0], t_max=1.0)
    assert arc.termination is Termination.NON_FINITE
    assert "flow_map returned non-finite values" in arc.message
    assert len([x for x in w if issubclass(x.category, hs.SimulationWarning)]) == 1
    assert np.isfinite(arc.x).all() and arc.tf <= 0.5


def test_warn_false_is_silent_but_keeps_the_cause():
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: x ** 2, state_dim=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        arc = hs.simulate(sysm, [1.0], t_max=2.0, max_norm=1e3, warn=False)
    assert arc.termination is Termination.BLOWUP


def test_max_steps_ends_the_run_with_its_own_cause():
    with pytest.warns(hs.SimulationWarning, match="MAX_STEPS"):
        arc = hs.simulate(decay(), [1.0], t_max=1.0, max_step=1e-6, max_steps=500)
    assert arc.termination is Termination.MAX_STEPS
    assert len(arc.t) == 501 and abs(arc.tf - 5e-4) < 1e-9


def test_t_max_inf_without_jumps_is_bounded_by_max_steps():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hs.SimulationWarning)
        arc = hs.simulate(decay(), [1.0], t_max=math.inf, max_steps=2000)
    assert arc.termination is Termination.MAX_STEPS and len(arc.t) == 2001


def test_max_samples_caps_refine():
    with pytest.warns(hs.SimulationWarning, match="MAX_STEPS"):
        arc = hs.simulate(decay(), [1.0], t_max=1.0, refine=1000, max_samples=5000)
    assert arc.termination is Termination.MAX_STEPS and len(arc.t) <= 5000


def test_chattering_with_a_tiny_hysteresis_is_named_at_j_max():
    """A jump every 2e-9 s after a first flow of 0.5 s. Its flows do not shrink,
    so it is no Zeno accumulation (issue 45: Zeno is decided by the run's own
    flows, not by the horizon, which called a 1 kHz timer Zeno); it runs to
    j_max, which names the chattering in its message and one warning."""
    eps = 1e-9
    chat = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0 if x[1] > 0 else -1.0, 0.0]),
        jump_map=lambda x: np.array([x[0], -x[1]]),
        jump_set=lambda x: (x[1] > 0 and x[0] >= eps) or (x[1] < 0 and x[0] <= -eps), state_dim=2)
    with pytest.warns(hs.SimulationWarning, match="chattering"):
        arc = hs.simulate(chat, [-0.5, 1.0], t_max=1.0, j_max=50)
    assert arc.termination is Termination.J_MAX and "chattering" in arc.message
    assert arc.jump_count == 50 and arc.tf < 0.5 + 1e-6


def test_stiff_flow_under_rk45_warns_naming_implicit_methods():
    stiff = hs.HybridSystem.from_functions(flow_map=lambda x, t: -1e6 * (x - np.cos(t)),
                                           state_dim=1)
    with pytest.warns(hs.SimulationWarning, match="looks stiff.*Radau"):
        hs.simulate(stiff, [0.0], t_max=0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        arc = hs.simulate(stiff, [0.0], t_max=0.01, method="Radau")
    assert arc.success


def test_non_stiff_flow_gives_no_stiffness_warning():
    osc = hs.HybridSystem.from_functions(flow_map=lambda x: np.array([x[1], -x[0]]), state_dim=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert hs.simulate(osc, [1.0, 0.0], t_max=50.0).success


def test_ball_sticking_to_a_moving_floor_is_not_left_sets():
    A, w = 0.1, 2 * np.pi

    def floor(t):
        return A * np.sin(w * t)

    def dfloor(t):
        return A * w * np.cos(w * t)
    ball = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[1], -9.81]),
        jump_map=lambda x, t: np.array([floor(t), dfloor(t) - 0.5 * (x[1] - dfloor(t))]),
        flow_set=lambda x, t: x[0] >= floor(t),
        jump_set=lambda x, t: x[0] <= floor(t) and x[1] <= dfloor(t), state_dim=2)
    arc = hs.simulate(ball, [1.0, 0.0], t_max=10.0, j_max=10_000)
    assert arc.termination is Termination.ZENO
    assert "sticks to the boundary of C" in arc.message


def test_ctrl_c_ends_the_run_with_canceled_and_keeps_the_arc():
    def f(x, t):
        if t > 0.5:
            raise KeyboardInterrupt
        return -x
    arc = hs.simulate(hs.HybridSystem.from_functions(flow_map=f, state_dim=1), [1.0], t_max=1.0,
                      max_step=0.01)
    assert arc.termination is Termination.CANCELED
    assert 0.48 < arc.tf <= 0.5 and np.all(np.diff(arc.t) >= 0)


# ----------------------------------------------------------------- t_eval
def test_t_eval_places_samples_and_keeps_both_samples_of_each_jump():
    timer = hs.library.Timer(1.0)
    grid = np.linspace(0.0, 3.5, 15)            # steps of 0.25: holds the jump times
    arc = hs.simulate(timer, [0.0], t_max=3.5, t_eval=grid)
    assert arc.jump_count == 3
    # every grid time is a sample, with the timer's value t - floor(t)
    for s in grid:
        k = np.flatnonzero(np.abs(arc.t - s) < 1e-12)
        assert k.size >= 1
        assert np.allclose(arc.x[k[-1], 0], s - math.floor(s + 1e-12), atol=1e-9)
    # and nothing but the grid, the jumps and the ends
    extra = set(np.round(arc.t, 9)) - set(np.round(grid, 9))
    assert extra <= {1.0, 2.0, 3.0}
    # at a jump time both samples are there: j and j + 1
    at1 = np.flatnonzero(np.abs(arc.t - 1.0) < 1e-12)
    assert set(arc.j[at1]) == {0, 1}


def test_flow_map_reusing_its_output_array_gives_right_samples_and_derivatives():
    # a map that returns one array, overwritten on every call: the samples and
    # xdot must be copies taken when stored, not views of the user's buffer
    out = np.empty(1)

    def f(x):
        out[0] = -x[0]
        return out

    arc = hs.simulate(hs.HybridSystem.from_functions(flow_map=f, state_dim=1), [1.0], t_max=2.0,
                      rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(arc.x[:, 0], np.exp(-arc.t), rtol=1e-8)
    np.testing.assert_allclose(arc.xdot[:, 0], -arc.x[:, 0], rtol=1e-12)


@pytest.mark.parametrize("cap", [2, 17, 256, 257, 600])
def test_max_samples_is_an_exact_cap_on_stored_samples(cap):
    # the sample store grows past its first block (256 rows) and stops exactly at the cap
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hs.SimulationWarning)
        arc = hs.simulate(decay(), [1.0], t_max=1e4, max_samples=cap, max_step=0.01)
    assert arc.termination is Termination.MAX_STEPS and "max_samples" in arc.message
    assert len(arc.t) == cap and arc.x.shape == (cap, 1) and arc.xdot.shape == (cap, 1)
    np.testing.assert_allclose(arc.x[:, 0], np.exp(-arc.t), rtol=1e-5)
    assert np.all(np.diff(arc.t) > 0)


# ------------------------------------------------------- issue 22 (faults)
def _free_ball(**sets):
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[1], -9.81]), jump_map=lambda x: np.array([0.0, -0.8 * x[1]]),
        state_dim=2, **sets)


@pytest.mark.parametrize("ball", [
    hs.library.BouncingBall(),
    _free_ball(flow_guard=lambda x: x[0], jump_guard=lambda x: np.array([-x[0], -x[1]])),
    _free_ball(flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0),
    _free_ball(flow_set=lambda x: x[0] >= 0, jump_guard=lambda x: -x[0])])
def test_overflow_inside_the_first_step_is_non_finite_not_a_set_exit(ball):
    # the step's ends are finite, its dense output is NaN: not "x0 outside C"
    with warnings.catch_warnings(record=True) as w, np.errstate(over="ignore",
                                                                 invalid="ignore"):
        warnings.simplefilter("always")
        arc = hs.simulate(ball, [1e308, 1e308], t_max=1.0)
    assert arc.termination is Termination.NON_FINITE, arc.message
    assert "non-finite" in arc.message
    assert len([x for x in w if issubclass(x.category, hs.SimulationWarning)]) == 1
    assert np.isfinite(arc.x).all() and arc.t.tolist() == [0.0]


def test_nan_guard_beside_an_indicator_is_a_map_error_naming_the_guard():
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        jump_set=lambda x: x[0] >= 1.0,
        jump_guard=lambda x: x[0] - 1.0 if x[0] < 0.5 else math.nan, state_dim=1)
    arc = hs.simulate(sysm, [0.0], t_max=2.0, throw=False)
    assert arc.termination is Termination.MAP_ERROR and "jump_guard returned NaN" in arc.message


@pytest.mark.parametrize("flow_side", ["C", "flow_guard"])
def test_a_jump_guard_is_used_beside_an_indicator_for_C(flow_side):
    # the apex is 1e-6 above the guard's zero: the in-step search needs the guard
    v0 = math.sqrt(2.0 * 9.81 * (1.0 + 1e-6))
    kw = {"flow_set": lambda x: x[0] >= -1e-9} if flow_side == "C" else \
        {"flow_guard": lambda x: x[0] + 1e-9}
    flight = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[1], -9.81]), jump_map=lambda x: np.array([x[0], -abs(x[1])]),
        jump_guard=lambda x: x[0] - 1.0, state_dim=2, **kw)
    arc = hs.simulate(flight, [0.0, v0], t_max=2.0 * v0 / 9.81, j_max=1)
    assert arc.jump_count == 1
    t_hit = (v0 - math.sqrt(v0 * v0 - 2.0 * 9.81)) / 9.81
    assert abs(arc.jump_times[0] - t_hit) < 1e-6


def _floor_ball(kind, restitution=0.8, jump_map=None):
    """A ball on a floor y_f(t) = 0.1 sin(2t), written the natural way: the jump
    map keeps the located position and reflects the relative velocity."""
    def yf(t):
        return 0.1 * math.sin(2.0 * t)

    def dyf(t):
        return 0.2 * math.cos(2.0 * t)

    def g(x, t):
        return np.array([x[0], dyf(t) - restitution * (x[1] - dyf(t))])
    kw = dict(jump_set=lambda x, t: x[0] - yf(t) <= 0 and x[1] - dyf(t) <= 0)
    if kind in ("guard", "both"):
        kw["flow_guard"] = lambda x, t: x[0] - yf(t)
    if kind in ("indicator", "both"):
        kw["flow_set"] = lambda x, t: x[0] - yf(t) >= 0
    return hs.HybridSystem.from_functions(flow_map=lambda x: np.array([x[1], -9.81]),
                                          jump_map=jump_map or g, state_dim=2, **kw)


@pytest.mark.parametrize("kind", ["guard", "indicator", "both"])
@pytest.mark.parametrize("restitution", [0.8, 0.3])
def test_ball_on_a_moving_floor_keeping_the_located_position_bounces_on(kind, restitution):
    arc = hs.simulate(_floor_ball(kind, restitution), [1.0, 0.0], t_max=3.0, j_max=6)
    assert arc.termination is Termination.J_MAX, arc.message
    # the post-jump states are within the event's location error of the floor
    after = arc.x[1:][np.diff(arc.j) == 1]
    floor = 0.1 * np.sin(2.0 * arc.jump_times)
    assert np.all(np.abs(after[:, 0] - floor) < 1e-13)


def test_a_post_jump_state_genuinely_outside_C_is_still_left_sets():
    arc = hs.simulate(_floor_ball("both", jump_map=lambda x, t: np.array([x[0] - 1e-9, 5.0])),
                      [1.0, 0.0], t_max=3.0)
    assert arc.termination is Termination.LEFT_SETS and arc.jump_count == 1


def test_jump_loop_of_a_guard_alone_says_what_is_wrong():
    # D = {-h >= 0} by the guard alone: after the impact (h = 0, rising) the
    # state is still in D, and the jumps priority jumps again, at one instant
    ball = _free_ball(flow_guard=lambda x: x[0], jump_guard=lambda x: -x[0])
    arc = hs.simulate(ball, [1.0, 0.0], t_max=2.0, j_max=30)
    assert arc.termination is Termination.J_MAX
    t1 = math.sqrt(2.0 / 9.81)
    assert "jump loop: the last 30 jumps were all at t=0.451523" in arc.message
    assert "check jump_set" in arc.message.lower() and abs(arc.jump_times[-1] - t1) < 1e-9
    arc = hs.simulate(ball, [1.0, 0.0], t_max=2.0)
    assert arc.termination is Termination.ZENO and "jump loop" in arc.message
    # ordinary runs keep their plain messages
    arc = hs.simulate(hs.library.BouncingBall(), [1.0, 0.0], t_max=10.0, j_max=5)
    assert arc.message == Termination.J_MAX.message


@pytest.mark.parametrize("j_max, cause", [(30, Termination.J_MAX), (100, Termination.ZENO)])
def test_purely_discrete_systems_are_not_jump_loops(j_max, cause):
    count = hs.HybridSystem.from_functions(jump_map=lambda x: x + 1.0, jump_set=lambda x: True,
                                           flow_set=lambda x: False, state_dim=1)
    arc = hs.simulate(count, [0.0], t_max=1.0, j_max=j_max)
    assert arc.termination is cause and "loop" not in arc.message
    assert arc.jump_count == min(j_max, 50) and arc.xf[0] == arc.jump_count


def test_map_error_at_x0_carries_an_arc_ending_with_map_error():
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: -x, jump_map=lambda x: 1 / 0,
                                          jump_set=lambda x: True, state_dim=1)
    with pytest.raises(hs.MapError) as info:
        hs.simulate(sysm, [1.0], t_max=1.0)
    arc = info.value.arc
    assert arc.termination is Termination.MAP_ERROR and "ZeroDivisionError" in arc.message
    assert len(arc) == 1


def test_stiffness_warning_points_at_the_caller():
    stiff = hs.HybridSystem.from_functions(flow_map=lambda x, t: -1e6 * (x - np.cos(t)),
                                           state_dim=1)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        hs.simulate(stiff, [0.0], t_max=0.01)
    hits = [x for x in w if "looks stiff" in str(x.message)]
    assert len(hits) == 1 and hits[0].filename == __file__


def test_end_of_run_warning_points_at_the_caller():
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        hs.simulate(decay(), [1.0], t_max=1.0, max_step=1e-6, max_steps=50)
    hits = [x for x in w if issubclass(x.category, hs.SimulationWarning)]
    assert len(hits) == 1 and hits[0].filename == __file__
