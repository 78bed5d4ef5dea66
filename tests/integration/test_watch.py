"""Watched functions (rule 11 of HybridSystem): crossings recorded without a jump.

Each system is written once over ``x[..., k]`` (so one set of maps serves a
single state and a vectorized batch) and run on each path of
``tests/conftest.py``'s ``path``: ``"python"`` (:func:`hybridsim.simulate`),
``"vectorized"`` (:func:`hybridsim.simulate_vectorized`, one row) and
``"compiled"`` (``backend="compiled"``: the maps rewritten from the same
definition, the engine's watching kernel). Crossing times are checked against closed forms to 4 ulp
(:func:`hybridsim.rules.event_tolerance`), which RK45 allows where it
integrates the flow exactly (a clock, a ball's parabola).
"""
import math

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.rules import event_tolerance

G, E = 1.0, 0.5          # dyadic gravity and restitution: the ball's times are exact


def ulp4(t):
    return event_tolerance(t, t)


def _fall(x):
    dx = np.empty_like(x)
    dx[..., 0] = x[..., 1]
    dx[..., 1] = -G
    return dx


def _bounce(x):
    xn = np.zeros_like(x)
    xn[..., 1] = -E * x[..., 1]
    return xn


def height_and_speed(x):
    """Two watched functions of the ball: its height above 0.3, its velocity."""
    w = np.empty_like(x)
    w[..., 0] = x[..., 0] - 0.3
    w[..., 1] = x[..., 1]
    return w


def ball(watch=None, direction=0, vectorized=False):
    """A ball on a floor, x = (height, velocity): x' = (v, -G), v+ = -E v on the floor."""
    return hs.HybridSystem.from_functions(
        flow_map=_fall, jump_map=_bounce,
        flow_set=lambda x: x[..., 0] >= 0.0,
        jump_set=lambda x: (x[..., 0] <= 0.0) & (x[..., 1] <= 0.0),
        jump_guard=lambda x: -x[..., 0], state_dim=2, watch=watch,
        watch_direction=direction, vectorized=vectorized)


def clock(watch, direction=0, vectorized=False):
    """x' = 1 (x = t from x0 = 0): its watched functions are functions of time."""
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), state_dim=1, watch=watch, watch_direction=direction,
        vectorized=vectorized)


def run(path, make, x0, t_max, **kw):
    """The arc of ``make(vectorized=...)`` from x0 on ``path``."""
    if path == "compiled":
        return hs.simulate(make(vectorized=False), x0, t_max, backend="compiled", **kw)
    if path == "python":
        return hs.simulate(make(vectorized=False), x0, t_max, **kw)
    return hs.simulate_vectorized(make(vectorized=True), [x0], t_max, **kw)[0]


def apexes(v0, bounces):
    """The ball's apex and bounce times from the floor with velocity v0 > 0
    (exact in floats: G and E are dyadic)."""
    top, hit, t, v = [], [], 0.0, v0
    for _ in range(bounces):
        top.append(t + v / G)
        t += 2.0 * v / G
        hit.append(t)
        v *= E
    return np.array(top), np.array(hit)


# ------------------------------------------------------------------ closed forms
def test_a_balls_apexes_to_4_ulp(path):
    """The velocity watched falling through 0: the apexes v0/G, then each bounce's
    time plus its rebound velocity over G; the bounces are the only jumps."""
    arc = run(path, lambda vectorized: ball(lambda x: x[..., 1], -1, vectorized),
              [0.0, 2.0], 7.9, j_max=8)
    c = arc.crossings
    want = apexes(2.0, 6)[0]            # 2, 5, 6.5, ..., 7.8125 (the next is after t_max)
    assert len(c) == len(want) and (c.direction == -1).all() and (c.which == 0).all()
    np.testing.assert_array_equal(c.j, np.arange(6))
    # the first apex to 4 ulp of v0/G; each later one to 4 ulp of its flow's own
    # closed form, the bounce's located time plus the rebound velocity over G
    # (the bounces' own 4 ulp add up along the arc: 1e-13 of the exact times)
    assert abs(c.t[0] - want[0]) <= ulp4(want[0])
    own = (arc.jump_times + arc.x[1:][np.diff(arc.j) == 1][:, 1] / G)[:5]
    assert np.all(np.abs(c.t[1:] - own) <= [ulp4(t) for t in own]), c.t[1:] - own
    np.testing.assert_allclose(c.t, want, rtol=0, atol=1e-13)
    # the state recorded is the arc's own at that time: on the flow, at its apex
    for tc, jc, xc in zip(c.t, c.j, c.x):
        np.testing.assert_allclose(xc, arc.at(tc, j=jc), rtol=0, atol=1e-12)
        assert abs(xc[1]) <= 8 * np.finfo(float).eps


def test_sine_zeros_to_4_ulp_in_both_directions(path):
    """sin(t) crosses 0 at k pi, falling at odd k and rising at even k; steps of
    at most 1 (so no two zeros share a quarter step)."""
    arc = run(path, lambda vectorized: clock(lambda x: np.sin(x[..., 0]), 0, vectorized),
              [0.0], 20.0, max_step=1.0)
    c = arc.crossings
    k = np.arange(1, 7)
    assert len(c) == 6 and (c.j == 0).all()
    assert np.all(np.abs(c.t - k * np.pi) <= [ulp4(t) for t in k * np.pi]), c.t - k * np.pi
    np.testing.assert_array_equal(c.direction, np.where(k % 2, -1, 1))


# ------------------------------------------------------------------ directions
@pytest.mark.parametrize("direction, k", [(1, [2, 4, 6]), (-1, [1, 3, 5]),
                                          ((1, -1), None)])
def test_direction_keeps_rising_falling_or_one_each(path, direction, k):
    """scipy's ``event.direction``: 1 keeps the rising crossings, -1 the falling;
    one per function for several. With (1, -1) on (sin t, cos t): sin's rising
    zeros 2 pi, 4 pi, 6 pi and cos's falling ones pi/2 + 2 pi i."""
    def sin(x):
        return np.sin(x[..., 0])

    def sin_cos(x):
        return np.concatenate((np.sin(x), np.cos(x)), axis=-1)
    w = sin_cos if isinstance(direction, tuple) else sin
    arc = run(path, lambda vectorized: clock(w, direction, vectorized), [0.0], 20.0,
              max_step=1.0)
    c = arc.crossings
    if k is not None:
        np.testing.assert_allclose(c.t, np.array(k) * np.pi, rtol=0, atol=1e-13)
        assert (c.direction == (1 if direction == 1 else -1)).all()
        return
    sin_up = np.arange(1, 4) * 2 * np.pi
    cos_down = np.pi / 2 + np.arange(0, 3) * 2 * np.pi
    np.testing.assert_allclose(c.select(which=0).t, sin_up, rtol=0, atol=1e-13)
    np.testing.assert_allclose(c.select(which=1).t, cos_down, rtol=0, atol=1e-13)
    assert (c.select(which=0).direction == 1).all() and (c.select(which=1).direction == -1).all()
    assert np.all(np.diff(c.t) > 0)              # in time order across the functions
    assert len(c.select(direction=1)) == 3


# ------------------------------------------------------------------ jumps
def test_a_zero_at_a_jump_is_recorded_once_before_it(path):
    """The height watched: it reaches 0 at each bounce, where the ball jumps. The
    falling crossing is recorded at the bounce (within the event's 4 ulp, on the
    flow before it: j of the pre-jump sample); the flow after it starts on that
    zero, which is no rising crossing."""
    arc = run(path, lambda vectorized: ball(lambda x: x[..., 0], 0, vectorized),
              [0.0, 2.0], 7.9, j_max=8)
    c = arc.crossings
    jt = arc.jump_times
    assert len(c) == len(jt) == 6 and (c.direction == -1).all()
    assert np.all(np.abs(c.t - jt) <= [2 * ulp4(t) for t in jt])
    np.testing.assert_array_equal(c.j, np.arange(6))
    np.testing.assert_allclose(jt, apexes(2.0, 6)[1], rtol=0, atol=1e-12)


class DelayedClock(hs.HybridSystem):
    """x' = 1 with a declared delay of 1: every path stops the flow at t0 + 1 (a
    delay breakpoint) and starts it again there, without a jump."""
    state_dim = 1
    delays = (1.0,)

    def flow_map(self, x):
        return np.ones_like(x)

    def watch(self, x):
        return np.concatenate((x - 0.5, x - 1.5), axis=-1)


def delayed_clock(vectorized=False):
    s = DelayedClock()
    s.vectorized = vectorized
    return s


def coin_clock(vectorized=False):
    """x' = 1 in C = {x <= 2}, x+ = 0 in D = {x >= 1}: under priority="random" a
    coin at t = 1 may flow on in C ∩ D (a flow restarted without a jump) until
    C ends at t = 2. Watched: x - 1.5, rising."""
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones_like(x), jump_map=lambda x: 0.0 * x,
        flow_set=lambda x: x[..., 0] <= 2.0, jump_set=lambda x: x[..., 0] >= 1.0,
        state_dim=1, watch=lambda x: x[..., 0] - 1.5, watch_direction=1,
        vectorized=vectorized)


@pytest.mark.parametrize("restart", ["delay breakpoint", "coin flows on"])
def test_a_flow_restarted_without_a_jump_keeps_its_crossings(path, restart):
    """A flow that starts again where no jump happened (a delay breakpoint; the
    random priority's coin flowing on in C ∩ D) starts on no zero: its
    crossings are recorded at their closed-form times (seed 0's coin flows on
    at t = 1, so the only jump is at t = 2)."""
    if restart == "delay breakpoint":
        if path == "compiled":
            with pytest.raises(TypeError, match=r"backend='compiled'.*(history|delays)"):
                run(path, delayed_clock, [0.0], 3.0)
            return
        arc = run(path, delayed_clock, [0.0], 3.0)
        want, which = [0.5, 1.5], [0, 1]
    else:
        arc = run(path, coin_clock, [0.0], 2.5, priority="random", seed=0)
        assert len(arc.jump_times) == 1 and abs(arc.jump_times[0] - 2.0) <= ulp4(2.0)
        want, which = [1.5], [0]
    c = arc.crossings
    assert len(c) == len(want) and (c.direction == 1).all() and (c.j == 0).all()
    np.testing.assert_array_equal(c.which, which)
    assert np.all(np.abs(c.t - want) <= [ulp4(t) for t in want]), c.t - want


def test_watching_changes_nothing_else(path):
    """The arc with watched functions is the arc without them, bit for bit:
    samples, derivatives and statistics (no step is cut)."""
    w = height_and_speed
    a = run(path, lambda vectorized: ball(w, 0, vectorized), [0.0, 2.0], 7.9, j_max=8)
    b = run(path, lambda vectorized: ball(None, 0, vectorized), [0.0, 2.0], 7.9, j_max=8)
    assert len(a.crossings) == 10 and b.crossings is None
    for k in ("t", "j", "x", "xdot"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    assert a.stats == b.stats and a.termination is b.termination


# ------------------------------------------------------------------ files
def test_crossings_survive_save_and_load(tmp_path):
    arc = hs.simulate(ball(height_and_speed), [0.0, 2.0], 7.9, j_max=8)
    back = hs.load(arc.save(tmp_path / "watched"))
    assert back.crossings == arc.crossings and len(back.crossings) == 10
    plain = hs.load(hs.simulate(ball(), [0.0, 2.0], 3.0).save(tmp_path / "plain"))
    assert plain.crossings is None


def test_a_file_with_part_of_the_crossings_is_refused(tmp_path):
    arc = hs.simulate(ball(lambda x: x[..., 1]), [0.0, 2.0], 3.0)
    p = arc.save(tmp_path / "a")
    with np.load(p) as z:
        d = {k: z[k] for k in z.files if k != "crossing_x"}
    np.savez(tmp_path / "b.npz", **d)
    with pytest.raises(hs.arc.ArcFileError, match=r"missing \['crossing_x'\]"):
        hs.load(tmp_path / "b.npz")
    d["crossing_x"] = np.zeros((len(arc.crossings), 3))
    np.savez(tmp_path / "c.npz", **d)
    with pytest.raises(hs.arc.ArcFileError, match=r"crossing_x of shape \(1, 2\)"):
        hs.load(tmp_path / "c.npz")


# ------------------------------------------------------------------ bad input
def test_bad_watch_arguments_are_named():
    with pytest.raises(TypeError, match="watch must be callable"):
        clock(3.0)
    with pytest.raises(TypeError, match="watch_direction without watch"):
        hs.HybridSystem.from_functions(flow_map=lambda x: x, state_dim=1, watch_direction=1)
    with pytest.raises(ValueError, match=r"watch_direction must be -1, 0 or 1.*got 2"):
        hs.simulate(clock(lambda x: x[0], direction=2), [0.0], 1.0)
    with pytest.raises(hs.MapError, match=r"watch returned 2 values but watch_direction "
                                          r"gives 3 directions"):
        hs.simulate(clock(lambda x: np.array([x[0], 1.0]), direction=(1, 0, 1)), [0.0], 1.0)


@pytest.mark.parametrize("w, match", [
    (lambda x: np.ones((2, 2)), r"watch must return a real number or a non-empty 1-D"),
    (lambda x: "high", r"watch must return a real number"),
    (lambda x: x[0] + 1j, r"watch returned complex values"),
    (lambda x: np.nan, r"watch returned non-finite values"),
    (lambda x: 1.0 / 0.0, r"watch raised ZeroDivisionError"),
])
def test_a_bad_watch_value_at_x0_raises_naming_watch(w, match):
    with pytest.raises(hs.MapError, match=match) as e:
        hs.simulate(clock(w), [0.0], 1.0)
    assert e.value.map_name == "watch"


def test_a_watch_failing_during_the_run_is_map_error_with_the_run_so_far(path):
    """NaN after t = 0.5, then a changing length: MAP_ERROR naming watch, the
    samples so far kept."""
    def w(x):
        return np.where(x[..., 0] > 0.5, np.nan, x[..., 0] - 0.25)
    arc = run(path, lambda vectorized: clock(w, 0, vectorized), [0.0], 2.0, max_step=0.1,
              throw=False, warn=False)
    assert arc.termination is hs.Termination.MAP_ERROR and "watch returned non-finite" in \
        arc.message
    assert arc.t[-1] <= 0.5 + 1e-12 and len(arc.t) > 3
    if path == "python":
        grow = clock(lambda x: np.zeros(1 + int(x[0] > 0.5)))
        arc = hs.simulate(grow, [0.0], 2.0, max_step=0.1, throw=False)
        assert "watch must return the same number of values" in arc.message


@pytest.mark.paths(only=("compiled",))
def test_a_changed_watch_direction_is_seen_by_the_next_compiled_run(path):
    """The direction is read at each run (a plain class's rewritten maps are kept)."""
    s = clock(lambda x: np.sin(x[..., 0]), 1)
    a = hs.simulate(s, [0.0], 7.0, max_step=1.0, backend="compiled")
    s.watch_direction = -1
    b = hs.simulate(s, [0.0], 7.0, max_step=1.0, backend="compiled")
    assert a.crossings.direction.tolist() == [1] and b.crossings.direction.tolist() == [-1]
    np.testing.assert_allclose([a.crossings.t[0], b.crossings.t[0]], [2 * np.pi, np.pi],
                               rtol=0, atol=1e-14)


def test_random_jumps_keep_the_watched_crossings():
    """A system with a jump rate runs with its clock added to the state: its
    watched functions still read the user's state, and the crossings keep it."""
    tick = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.ones(1), jump_map=lambda x: np.zeros(1), jump_rate=lambda x: 2.0,
        state_dim=1, watch=lambda x: x[0] - 0.25, watch_direction=1)
    arc = hs.simulate(tick, [0.0], 5.0, seed=3)
    c = arc.crossings
    assert len(c) >= 1 and c.x.shape == (len(c), 1)
    np.testing.assert_allclose(c.x[:, 0], 0.25, rtol=0, atol=1e-12)
    starts = np.r_[0.0, arc.jump_times]            # each flow from 0 crosses 0.25 once
    np.testing.assert_allclose(c.t, starts[c.j] + 0.25, rtol=0, atol=1e-12)
    # the compiled path runs jump rates, but not with watched functions: refused by
    # name, single runs and batches (never a run that drops the crossings)
    for run in (lambda: hs.simulate(tick, [0.0], 5.0, seed=3, backend="compiled"),
                lambda: hs.simulate_many(tick, [[0.0], [0.1]], 5.0, backend="compiled")):
        with pytest.raises(TypeError, match=r"declares watch .* and a jump_rate.*backend='python'"):
            run()


def test_watch_with_a_diffusion_is_refused_by_name():
    sde = hs.HybridSystem.from_functions(flow_map=lambda x: -x, diffusion=lambda x: 0.1 + 0 * x,
                                         state_dim=1, watch=lambda x: x[0], max_step=0.01)
    with pytest.raises(ValueError, match="declares watch.*and a diffusion"):
        hs.simulate(sde, [1.0], 0.1, method="EM", seed=1)


def test_a_compiled_systems_watch_runs_on_both_paths(path):
    """A CompiledSystem's watch (a function of (x, t, j, p)) gives the same
    crossings on the Python path and compiled; backend='auto' runs a plain
    class that watches."""
    from hybridsim.compiled import CompiledSystem, simulate_compiled
    cs = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1), state_dim=1,
                        watch=lambda x, t, j, p: math.sin(x[0]), watch_direction=1)
    arc = hs.simulate(cs, [0.0], 7.0, max_step=1.0)
    np.testing.assert_allclose(arc.crossings.t, [2 * np.pi], rtol=0, atol=1e-14)
    if path == "compiled":
        assert simulate_compiled(cs, [0.0], 7.0, max_step=1.0).crossings == arc.crossings
        with pytest.raises(TypeError, match="declares watch.*RK45 only"):
            simulate_compiled(cs, [0.0], 7.0, method="DOP853")
    if path != "vectorized":
        auto = hs.simulate(clock(lambda x: np.sin(x[0])), [0.0], 7.0, max_step=1.0,
                           backend="auto")
        assert len(auto.crossings) == 2


@pytest.mark.paths(only=("compiled",))
def test_compiled_crossings_equal_the_python_paths_in_a_batch(path, tmp_path):
    """simulate_many compiled: each row's crossings are its single compiled
    run's, and the Python path's: the same crossings, those of the first flow
    at the same times to 4 ulp, later ones to the bounces' own 4 ulp added up
    along the arc (the two paths locate each bounce to 4 ulp, not to the same
    bits), the same states; and they survive save and load."""
    w = height_and_speed
    X0 = [[0.0, 2.0], [0.5, 1.0], [1.0, -0.5]]
    many = hs.simulate_many(ball(w), X0, 6.0, j_max=8, backend="compiled")
    for x0, arc in zip(X0, many):
        assert arc.crossings == hs.simulate(ball(w), x0, 6.0, j_max=8,
                                            backend="compiled").crossings
        ref = hs.simulate(ball(w), x0, 6.0, j_max=8)
        c, r = arc.crossings, ref.crossings
        assert len(c) == len(r) > 0
        for k in ("j", "which", "direction"):
            np.testing.assert_array_equal(getattr(c, k), getattr(r, k))
        first = c.j == 0
        assert np.all(np.abs(c.t - r.t)[first] <= [ulp4(t) for t in r.t[first]])
        np.testing.assert_allclose(c.t, r.t, rtol=0, atol=1e-13)
        np.testing.assert_allclose(c.x, r.x, rtol=0, atol=1e-12)
    back = hs.load(many[0].save(tmp_path / "compiled"))
    assert back.crossings == many[0].crossings
