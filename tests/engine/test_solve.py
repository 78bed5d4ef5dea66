"""simulate(): event location, priorities, limits, termination, validation."""
import math

import numpy as np
import pytest

import hybridsim as hs
from hybridsim import Termination

G, E = 9.81, 0.8


class Ball(hs.HybridSystem):
    state_dim = 2

    def flow_map(self, x, t, j):
        return np.array([x[1], -G])

    def jump_map(self, x, t, j):
        return np.array([0.0, -E * x[1]])

    def flow_set(self, x, t, j):
        return x[0] >= 0

    def jump_set(self, x, t, j):
        return x[0] <= 0 and x[1] <= 0


class GuardBall(Ball):
    """The same ball with continuous guards (root-finding instead of bisection)."""

    def jump_guard(self, x):
        return np.array([-x[0], -x[1]])

    def flow_guard(self, x):
        return x[0]


def ball_jump_times(h0, k):
    """Analytic impact times of a ball dropped from h0 at rest."""
    v, t, out = math.sqrt(2 * G * h0), math.sqrt(2 * h0 / G), []
    for _ in range(k):
        out.append(t)
        v *= E
        t += 2 * v / G
    return np.array(out)


def zeno_time(h0):
    v0 = math.sqrt(2 * G * h0)
    return math.sqrt(2 * h0 / G) + 2 * v0 * E / (G * (1 - E))


def timer(period=1.0, guards=True):
    kw = dict(jump_guard=lambda x: x[0] - period, flow_guard=lambda x: period - x[0]) \
        if guards else dict(flow_set=lambda x: x[0] <= period, jump_set=lambda x: x[0] >= period)
    return hs.HybridSystem.from_functions(flow_map=lambda x: np.array([1.0]),
                                          jump_map=lambda x: np.array([0.0]), state_dim=1, **kw)


# --------------------------------------------------------------------- accuracy
@pytest.mark.parametrize("cls", [Ball, GuardBall])
@pytest.mark.parametrize("h0", [1.0, 0.37, 2.5])
def test_ball_jump_times_match_analytic(cls, h0):
    # RK45 integrates the parabola exactly up to rounding; 30 events each
    # located to 4 ulp accumulate far below the 1e-9 asked for.
    arc = hs.simulate(cls(), [h0, 0.0], t_max=20.0, j_max=30, rtol=1e-10, atol=1e-12)
    assert arc.termination is Termination.J_MAX
    assert arc.jump_count == 30
    np.testing.assert_allclose(arc.jump_times, ball_jump_times(h0, 30), rtol=0, atol=1e-9)
    # the ball never sinks below the floor: every sample has x >= -1e-12
    assert arc.x[:, 0].min() > -1e-12
    # each jump is two samples at the same t with j, j + 1
    k = arc.jump_index
    assert np.all(arc.t[k] == arc.t[k - 1]) and np.all(arc.j[k] == arc.j[k - 1] + 1)


def test_ball_energy_never_increases():
    arc = hs.simulate(Ball(), [1.0, 0.0], t_max=20.0, j_max=30, rtol=1e-10, atol=1e-12)
    energy = G * arc.x[:, 0] + 0.5 * arc.x[:, 1] ** 2
    # flows conserve energy (to the integrator), jumps dissipate it
    assert np.all(np.diff(energy) <= 1e-9)


@pytest.mark.parametrize("guards", [True, False])
def test_timer_jumps_on_exact_multiples(guards):
    arc = hs.simulate(timer(0.25, guards), [0.0], t_max=10.1)
    expected = 0.25 * np.arange(1, 41)
    # event brackets are 4 ulp wide; 40 restarts add at most 40 such errors
    np.testing.assert_allclose(arc.jump_times, expected, rtol=0, atol=1e-12)
    assert arc.termination is Termination.T_MAX and arc.tf == 10.1


def test_short_flow_after_jump_is_not_missed():
    # after each bounce the ball sits exactly on the guard's zero (x = 0);
    # a flight shorter than one solver step must still end in a jump
    arc = hs.simulate(GuardBall(), [1e-6, 0.0], t_max=1.0, j_max=40, max_step=10.0,
                      rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(arc.jump_times, ball_jump_times(1e-6, 40), atol=1e-12)


def test_all_scipy_methods_locate_the_same_jumps():
    ref = ball_jump_times(1.0, 5)
    for method in ["RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA"]:
        arc = hs.simulate(GuardBall(), [1.0, 0.0], t_max=10.0, j_max=5, method=method,
                          rtol=1e-9, atol=1e-11)
        # implicit/multistep methods are not exact on the parabola: the
        # tolerance follows rtol, not the event location
        np.testing.assert_allclose(arc.jump_times, ref, atol=1e-6, err_msg=method)


# -------------------------------------------------------------------- priority
def overlap_system():
    """C = {x <= 2}, D = {x >= 1}: C ∩ D = [1, 2]. Flow x' = 1, jump x+ = 0."""
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        flow_set=lambda x: x[0] <= 2.0, jump_set=lambda x: x[0] >= 1.0, state_dim=1)


def test_priority_jumps_jumps_on_entering_D():
    arc = hs.simulate(overlap_system(), [0.0], t_max=3.5, priority="jumps")
    np.testing.assert_allclose(arc.jump_times, [1.0, 2.0, 3.0], atol=1e-12)


def test_priority_flows_jumps_only_when_leaving_C():
    arc = hs.simulate(overlap_system(), [0.0], t_max=7.0, priority="flows")
    np.testing.assert_allclose(arc.jump_times, [2.0, 4.0, 6.0], atol=1e-12)
    assert arc.x.max() <= 2.0 + 1e-12


def test_priority_jumps_at_t0_and_flows_from_C_cap_D():
    arc = hs.simulate(overlap_system(), [1.5], t_max=1.0, priority="jumps")
    assert arc.jump_times[0] == 0.0 and arc.x[1, 0] == 0.0
    arc = hs.simulate(overlap_system(), [1.5], t_max=1.0, priority="flows")
    np.testing.assert_allclose(arc.jump_times, [0.5], atol=1e-12)


def test_priority_flows_jumps_on_edge_of_C_where_flow_leaves():
    # x0 = 2 is on the edge of C and the flow leaves C at once: it jumps
    arc = hs.simulate(overlap_system(), [2.0], t_max=0.5, priority="flows")
    assert arc.jump_count >= 1
    assert abs(arc.jump_times[0]) < 1e-12


def test_priority_random_is_seeded_and_mixes():
    runs = [hs.simulate(overlap_system(), [0.0], t_max=20.0, priority="random", seed=s)
            for s in (1, 1, 2)]
    np.testing.assert_array_equal(runs[0].jump_times, runs[1].jump_times)
    jt = np.concatenate([r.jump_times for r in runs])
    # jumps happen anywhere in C ∩ D = [1, 2] after a reset: between 1 and 2
    # time units after the previous one, and both extremes occur
    gaps = np.diff(np.concatenate([[0.0], runs[2].jump_times]))
    assert np.all(gaps >= 1.0 - 1e-9) and np.all(gaps <= 2.0 + 1e-9)
    assert len(jt) > 3


# ---------------------------------------------------------------- termination
def test_x0_in_neither_set_returns_one_sample():
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        flow_set=lambda x: x[0] <= 2.0, jump_set=lambda x: 1.0 <= x[0] <= 3.0, state_dim=1)
    arc = hs.simulate(sysm, [5.0], t_max=1.0)
    assert arc.termination is Termination.NOT_IN_SETS
    assert len(arc) == 1 and arc.xf[0] == 5.0
    assert not arc.success and "neither C nor D" in arc.message


def test_leaving_C_outside_D_stops_at_exit_time():
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), flow_set=lambda x: x[0] <= 1.0, state_dim=1)
    arc = hs.simulate(sysm, [0.0], t_max=5.0)
    assert arc.termination is Termination.LEFT_SETS
    assert abs(arc.tf - 1.0) < 1e-12 and arc.xf[0] <= 1.0


def test_t_max_ends_with_a_sample_at_t_max():
    arc = hs.simulate(Ball(), [1.0, 0.0], t_max=0.3, j_max=10)
    assert arc.tf == 0.3 and arc.termination is Termination.T_MAX and arc.success


def test_j_max_zero_and_limits():
    arc = hs.simulate(overlap_system(), [1.5], t_max=1.0, j_max=0)
    assert arc.termination is Termination.J_MAX and len(arc) == 1
    arc = hs.simulate(timer(), [0.0], t_max=100.0, j_max=3)
    assert arc.jump_count == 3 and arc.termination is Termination.J_MAX
    assert abs(arc.tf - 3.0) < 1e-12


def test_zeno_ball_stops_quickly_not_past_zeno_time():
    arc = hs.simulate(Ball(), [1.0, 0.0], t_max=100.0, j_max=10_000, rtol=1e-10, atol=1e-12)
    assert arc.termination is Termination.ZENO
    assert arc.jump_count < 10_000
    # the arc ends at the Zeno time, up to the accumulated event tolerance
    # (each located event is 4 ulp late and slightly rebounds: ~1e-10 total)
    assert arc.tf <= zeno_time(1.0) + 1e-9
    assert arc.tf >= zeno_time(1.0) - 1e-6


def test_instant_jump_loop_is_zeno():
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: np.zeros(1), jump_map=lambda x: x,
                                          jump_set=lambda x: True, state_dim=1)
    arc = hs.simulate(sysm, [1.0], t_max=1.0, j_max=10**6, zeno_jumps=20)
    assert arc.termination is Termination.ZENO and arc.jump_count == 20 and arc.tf == 0.0


def test_non_finite_state_stops_with_cause():
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x, t: np.array([np.nan if t > 0.5 else 1.0]), state_dim=1)
    with pytest.warns(hs.SimulationWarning, match=r"NON_FINITE.*flow_map returned non-finite"):
        arc = hs.simulate(sysm, [0.0], t_max=2.0, max_step=0.1)
    assert arc.termination is Termination.NON_FINITE     # not a solver failure
    assert arc.tf <= 0.6 and np.all(np.isfinite(arc.x))


def test_blowup_with_max_norm():
    # x' = x^2 from 1 escapes at t = 1
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: x ** 2, state_dim=1)
    with pytest.warns(hs.SimulationWarning, match=r"BLOWUP.*last sample t=0\.99"):
        arc = hs.simulate(sysm, [1.0], t_max=2.0, max_norm=1e6)
    assert arc.termination is Termination.BLOWUP
    assert arc.tf < 1.0 and "max_norm" in arc.message


def test_finite_escape_without_max_norm_ends_cleanly():
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: x ** 2, state_dim=1)
    with pytest.warns(hs.SimulationWarning, match="SOLVER_FAILED|NON_FINITE"):
        arc = hs.simulate(sysm, [1.0], t_max=2.0)
    assert arc.termination in (Termination.SOLVER_FAILED, Termination.NON_FINITE)
    assert arc.tf < 1.0 + 1e-6


def test_exception_in_user_map_keeps_the_arc():
    def f(x, t):
        if t > 1.0:
            raise RuntimeError("sensor failed")
        return np.array([1.0])
    sysm = hs.HybridSystem.from_functions(flow_map=f, state_dim=1)
    arc = hs.simulate(sysm, [0.0], t_max=5.0, max_step=0.1, throw=False)
    assert arc.termination is Termination.MAP_ERROR
    assert isinstance(arc.exception, hs.MapError) and "sensor failed" in arc.message
    assert isinstance(arc.exception.__cause__, RuntimeError)
    assert 0.9 < arc.tf <= 1.0 + 1e-12
    # by default the error is raised, naming the map, t and j, with the arc so far
    with pytest.raises(hs.MapError, match=r"flow_map raised RuntimeError: sensor failed "
                                          r"\(at t=1\.0\d*, j=0\)") as info:
        hs.simulate(sysm, [0.0], t_max=5.0, max_step=0.1)
    assert isinstance(info.value, hs.SimulationError)
    assert info.value.map_name == "flow_map" and info.value.j == 0
    assert isinstance(info.value.__cause__, RuntimeError)
    assert info.value.arc.tf > 0.9


def test_jump_map_wrong_shape_mid_run_is_map_error():
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.zeros(3),
        jump_guard=lambda x: x[0] - 1, flow_guard=lambda x: 1 - x[0], state_dim=1)
    arc = hs.simulate(sysm, [0.0], t_max=5.0, throw=False)
    assert arc.termination is Termination.MAP_ERROR
    assert isinstance(arc.exception, hs.MapError)
    assert "jump_map must return an array of shape (1,)" in arc.message


# ----------------------------------------------------------------- validation
def test_bad_x0():
    with pytest.raises(ValueError, match=r"x0 must have shape \(2,\).*got shape \(3,\)"):
        hs.simulate(Ball(), [1.0, 0.0, 0.0], t_max=1.0)
    with pytest.raises(ValueError, match="x0 must be finite"):
        hs.simulate(Ball(), [np.nan, 0.0], t_max=1.0)
    with pytest.raises(ValueError, match="x0 must be finite"):
        hs.simulate(Ball(), [np.inf, 0.0], t_max=1.0)


@pytest.mark.parametrize("kw, err, match", [
    (dict(t_max=-1.0), ValueError, "t_max must be >= t0"),
    (dict(t_max=np.nan), ValueError, "t_max must be finite"),
    (dict(t_max=1.0, j_max=-1), ValueError, "j_max must be >= 0"),
    (dict(t_max=1.0, j_max=2.5), TypeError, "j_max must be a non-negative int"),
    (dict(t_max=1.0, priority="sometimes"), ValueError, "priority must be one of"),
    (dict(t_max=1.0, method="Euler"), ValueError, "method must be one of"),
    (dict(t_max=1.0, method=3), TypeError, "method must be a string or an OdeSolver"),
    (dict(t_max=1.0, rtol=-1e-3), ValueError, "rtol must be > 0"),
    (dict(t_max=1.0, atol=[1e-3]), ValueError, "atol must be a positive float or an array"),
    (dict(t_max=1.0, max_step=0.0), ValueError, "max_step must be > 0"),
    (dict(t_max=1.0, refine=0), ValueError, "refine must be >= 1"),
    (dict(t_max="1"), TypeError, "t_max must be a real number"),
])
def test_bad_arguments(kw, err, match):
    with pytest.raises(err, match=match):
        hs.simulate(Ball(), [1.0, 0.0], **kw)


def test_unknown_keyword_is_a_type_error():
    with pytest.raises(TypeError):
        hs.simulate(Ball(), [1.0, 0.0], t_max=1.0, rtoll=1e-3)


def test_maps_returning_wrong_shape_or_nonfinite_at_x0():
    bad_f = hs.HybridSystem.from_functions(flow_map=lambda x: np.zeros(3), state_dim=2)
    with pytest.raises(ValueError, match=r"flow_map must return an array of shape \(2,\), "
                                         r"got shape \(3,\)"):
        hs.simulate(bad_f, [0.0, 0.0], t_max=1.0)
    nan_f = hs.HybridSystem.from_functions(flow_map=lambda x: np.array([np.nan, 0.0]), state_dim=2)
    with pytest.raises(ValueError, match="flow_map returned non-finite"):
        hs.simulate(nan_f, [0.0, 0.0], t_max=1.0)
    bad_g = hs.HybridSystem.from_functions(flow_map=lambda x: x, jump_map=lambda x: [1.0],
                                           jump_set=lambda x: True, state_dim=2)
    with pytest.raises(ValueError, match=r"jump_map must return an array of shape \(2,\)"):
        hs.simulate(bad_g, [0.0, 0.0], t_max=1.0)


def test_bad_system_definitions():
    with pytest.raises(TypeError, match="system must be a hybridsim.HybridSystem"):
        hs.simulate(lambda x: x, [0.0], t_max=1.0)
    with pytest.raises(TypeError, match="flow_map must be callable"):
        hs.HybridSystem.from_functions(flow_map=3, state_dim=1)

    class NoDim(hs.HybridSystem):
        pass
    with pytest.raises(ValueError, match="state_dim must be a positive int"):
        hs.simulate(NoDim(), [0.0], t_max=1.0)

    class FourArgs(hs.HybridSystem):
        state_dim = 1

        def flow_map(self, x, t, j, u, extra):
            return x
    with pytest.raises(TypeError, match=r"flow_map must take \(x\), \(x, t\)"):
        hs.simulate(FourArgs(), [0.0], t_max=1.0)


def test_input_system_needs_inputs():
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x, t, j, u: u, state_dim=1, input_dim=1)
    with pytest.raises(ValueError, match="inputs: the system has input_dim=1"):
        hs.simulate(sysm, [0.0], t_max=1.0)
    arc = hs.simulate(sysm, [0.0], t_max=2.0, inputs=lambda t: np.array([2 * t]),
                      rtol=1e-10, atol=1e-12)
    assert abs(arc.xf[0] - 4.0) < 1e-9


def test_maps_may_read_t_and_j():
    # x' = j between jumps; jumps every unit of time via a timer component
    sysm = hs.HybridSystem.from_functions(
        flow_map=lambda x, t, j: np.array([1.0, float(j)]),
        jump_map=lambda x, t, j: np.array([0.0, x[1]]),
        jump_guard=lambda x: x[0] - 1.0, flow_guard=lambda x: 1.0 - x[0], state_dim=2)
    arc = hs.simulate(sysm, [0.0, 0.0], t_max=3.0)
    # integral of j over [0, 3] with j = 0, 1, 2 on unit intervals
    assert abs(arc.xf[1] - 3.0) < 1e-9


def test_refine_adds_interior_samples_on_the_flow():
    a1 = hs.simulate(Ball(), [1.0, 0.0], t_max=2.0, j_max=3)
    a5 = hs.simulate(Ball(), [1.0, 0.0], t_max=2.0, j_max=3, refine=5)
    assert len(a5) > len(a1)
    exact = 1.0 - 0.5 * G * a5.select(j=0).t ** 2
    np.testing.assert_allclose(a5.select(j=0).x[:, 0], exact, atol=1e-9)


def test_progress_bar_runs(capsys, monkeypatch):
    """The bar follows the run (t on the bar, j after it; or jumps when t_max
    is infinite), reaches the run's end and is erased when the run ends."""
    from hybridsim import _progress
    bars, make = [], _progress.make_bar

    def recording(*args, **kwargs):
        bar = make(*args, mininterval=0, **kwargs)
        bars.append(bar)
        return bar

    monkeypatch.setattr(_progress, "make_bar", recording)
    arc = hs.simulate(timer(), [0.0], t_max=3.5, progress=True)
    assert arc.jump_count == 3
    (bar,) = bars
    assert bar.n == pytest.approx(3.5) and bar.total == pytest.approx(3.5)
    assert bar.postfix == "j=3" and bar.disable          # closed
    err = capsys.readouterr().err
    assert "simulate: " in err and "t=0/3.5, j=0" in err
    assert err.rstrip("\r").rsplit("\r", 1)[-1].strip() == ""        # erased at the end
    arc = hs.simulate(timer(), [0.0], t_max=np.inf, j_max=4, progress=True)
    assert arc.jump_count == 4
    assert bars[1].n == 4 and bars[1].total == 4 and bars[1].unit == "jump"
    assert "4/4" in capsys.readouterr().err


def test_random_priority_jumps_only_at_entry_or_exit_of_overlap():
    # after choosing to flow on in C ∩ D, the next event is the exit of C
    pre = []
    for seed in range(10):
        arc = hs.simulate(overlap_system(), [0.0], t_max=10.0, priority="random",
                          seed=seed, max_step=0.3)
        pre += arc.x[arc.jump_index - 1, 0].tolist()
    np.testing.assert_allclose(np.sort(np.unique(np.round(pre, 9))), [1.0, 2.0])


def test_jump_times_stay_exact_when_flows_are_integrated_exactly():
    # RK45 is exact on the parabola, so its step proposals explode; the
    # engine caps the first step after an event and keeps every digit
    arc = hs.simulate(GuardBall(), [1.0, 0.0], t_max=np.inf, j_max=10, rtol=1e-10,
                      atol=1e-12)
    np.testing.assert_allclose(arc.jump_times, ball_jump_times(1.0, 10), rtol=0, atol=1e-12)
