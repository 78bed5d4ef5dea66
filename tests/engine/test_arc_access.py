"""HybridArc access: vectorized ``at``, Hermite interpolation, ``interpolate``
with each ``at_jump`` rule, ``restrict``/``select`` windows, ``transform``,
jump masks, iteration, ``xdot``/``stats``; checked against closed forms."""
import doctest

import numpy as np
import pytest

import hybridsim as hs
import hybridsim.arc as arc_module
from hybridsim.library import BouncingBall, Timer

G = 9.81


def with_xdot(arc, f):
    """The arc with xdot = f(x) at every sample (as the engine will pass it)."""
    xd = np.array([f(x) for x in arc.x])
    return hs.HybridArc(arc.t, arc.j, arc.x, arc.termination, arc.message,
                        components=arc.components, system=arc.system, xdot=xd,
                        stats={"steps": 7})


@pytest.fixture(scope="module")
def ball():
    """A ball arc with few samples (refine=1) and xdot from f."""
    sysm = BouncingBall()
    a = hs.simulate(sysm, [1.0, 0.0], t_max=3.0, j_max=4, refine=1)
    return with_xdot(a, sysm.flow_map)


def parabola(arc, s, j):
    """Closed form through the first sample of flow j: x(s) = x_k + v_k τ - g τ²/2."""
    k = np.flatnonzero(arc.j == j)[0]
    tau = s - arc.t[k]
    h0, v0 = arc.x[k]
    return np.stack([h0 + v0 * tau - 0.5 * G * tau ** 2, v0 - G * tau], axis=-1)


@pytest.fixture(scope="module")
def timer():
    a = hs.simulate(Timer(1.0), [0.0], t_max=3.5, j_max=10)
    np.testing.assert_allclose(a.jump_times, [1.0, 2.0, 3.0], rtol=0, atol=1e-12)
    return a


# ---------------------------------------------------------------- at
def test_hermite_is_exact_for_the_parabola(ball):
    assert ball._segments is None and ball.xdot is not None
    for j in range(ball.jf + 1):
        blk = ball.t[ball.j == j]
        # midpoints between consecutive samples: the worst place for linear
        mids = 0.5 * (blk[1:] + blk[:-1])
        mids = mids[np.diff(blk) > 0]
        got = ball.at(mids, j)
        np.testing.assert_allclose(got, parabola(ball, mids, j), rtol=0, atol=1e-12)
    # without xdot the same arc interpolates linearly: visibly wrong on the parabola
    lin = hs.HybridArc(ball.t, ball.j, ball.x, ball.termination)
    s = 0.5 * (ball.t[3] + ball.t[4])
    assert abs(lin.at(s, 0)[0] - parabola(ball, s, 0)[0]) > 1e-4


def test_hermite_falls_back_to_linear_where_xdot_unknown(ball):
    xd = ball.xdot.copy()
    xd[3] = np.nan                       # unknown at sample 3: both its intervals linear
    a = hs.HybridArc(ball.t, ball.j, ball.x, None, xdot=xd)
    s = 0.5 * (ball.t[3] + ball.t[4])
    np.testing.assert_allclose(a.at(s, 0), 0.5 * (ball.x[3] + ball.x[4]), atol=1e-15)
    s = 0.5 * (ball.t[1] + ball.t[2])     # interval 1-2 still Hermite
    np.testing.assert_allclose(a.at(s, 0), parabola(ball, s, 0), atol=1e-12)


def test_at_vectorized_matches_scalar_and_closed_form():
    a = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=3.0, j_max=4, rtol=1e-10,
                    atol=1e-12, dense=True)
    t1 = a.jump_times[0]
    assert abs(t1 - np.sqrt(2 / G)) < 1e-12
    ts = np.linspace(0, t1, 37)
    got = a.at(ts, 0)
    assert got.shape == (37, 2)
    np.testing.assert_allclose(got[:, 0], 1 - 0.5 * G * ts ** 2, atol=1e-10)
    np.testing.assert_allclose(got[:, 1], -G * ts, atol=1e-9)
    grid = np.linspace(0, a.tf, 101)
    vec = a.at(grid)
    assert vec.shape == (101, 2)
    np.testing.assert_allclose(vec, np.array([a.at(s) for s in grid]), rtol=0, atol=1e-14)
    # 2-D t and an array of j of the same shape
    tt = grid[:100].reshape(10, 10)
    jj = np.vectorize(lambda s: a.j[np.searchsorted(a.t, s, side="right") - 1])(tt)
    np.testing.assert_allclose(a.at(tt, jj), vec[:100].reshape(10, 10, 2), rtol=0, atol=1e-14)
    # one call with both j at a jump time: pre- and post-jump velocities
    tj = a.jump_times[0]
    pre, post = a.at([tj, tj], [0, 1])
    assert pre[1] < 0 < post[1]
    np.testing.assert_allclose(post[1], -0.8 * pre[1], rtol=1e-12)


def test_at_errors_name_the_problem(ball):
    with pytest.raises(ValueError, match="outside the arc's time range"):
        ball.at(np.array([0.1, 99.0]))
    with pytest.raises(ValueError, match=r"not in the hybrid time domain \(for j=0"):
        ball.at(np.array([0.1, 2.0]), 0)
    with pytest.raises(ValueError, match="no sample with j=99"):
        ball.at([0.1], 99)
    with pytest.raises(ValueError, match="shape of t"):
        ball.at([0.1, 0.2, 0.3], [0, 0])
    with pytest.raises(TypeError, match="j must be an int"):
        ball.at([0.1], "0")
    with pytest.raises(ValueError, match="finite"):
        ball.at([np.nan])
    with pytest.raises(ValueError, match="finite"):
        ball.at(np.inf)
    empty = ball.restrict(t=(0.1, 0.2), j=3)
    with pytest.raises(ValueError, match="empty"):
        empty.at(0.1)


# --------------------------------------------------------- interpolate
def test_interpolate_each_rule_on_a_timer(timer):
    t1, t2, t3 = timer.jump_times                        # 1, 2, 3 to round-off
    grid = np.array([0.0, 0.5, t1, 1.5, t2, t3, 3.25, 3.5])
    base = np.array([0, 0, 1, 1, 2, 3, 3, 3])            # jumps before each time
    t, j, x = timer.interpolate(grid)                      # default "end"
    np.testing.assert_array_equal(t, grid)
    np.testing.assert_array_equal(j, base)
    exact_end = np.array([0, .5, 0, .5, 0, 0, .25, .5])
    exact_start = np.array([0, .5, 1, .5, 1, 1, .25, .5])
    np.testing.assert_allclose(x[:, 0], exact_end, atol=1e-12)
    s = timer.interpolate(grid, at_jump="start")
    np.testing.assert_array_equal(s.j, [0, 0, 0, 1, 1, 2, 3, 3])
    np.testing.assert_allclose(s.x[:, 0], exact_start, atol=1e-12)
    m = timer.interpolate(grid, at_jump="mean")
    np.testing.assert_allclose(m.x[:, 0], 0.5 * (exact_start + exact_end), atol=1e-12)
    np.testing.assert_array_equal(m.j, base)
    n = timer.interpolate(grid, at_jump="nan")
    jumps = np.array([0, 0, 1, 0, 1, 1, 0, 0], bool)
    np.testing.assert_array_equal(np.isnan(n.x[:, 0]), jumps)
    np.testing.assert_allclose(n.x[~jumps, 0], exact_end[~jumps], atol=1e-12)
    b = timer.interpolate(grid, at_jump="both")
    np.testing.assert_array_equal(b.t, [0, .5, t1, t1, 1.5, t2, t2, t3, t3, 3.25, 3.5])
    np.testing.assert_array_equal(b.j, [0, 0, 0, 1, 1, 1, 2, 2, 3, 3, 3])
    np.testing.assert_allclose(b.x[:, 0], [0, .5, 1, 0, .5, 1, 0, 1, 0, .25, .5],
                               atol=1e-12)
    # "both" gives a valid arc's samples: build one from them
    hs.HybridArc(b.t, b.j, b.x, None).validate()


def test_interpolate_several_jumps_at_one_time():
    a = hs.HybridArc([0, 1, 1, 1, 2], [0, 0, 1, 2, 2], [[0], [1], [5], [0], [1]], None)
    g = [0.5, 1.0, 1.5]
    assert a.interpolate(g, "start").x[1, 0] == 1 and a.interpolate(g, "end").x[1, 0] == 0
    assert a.interpolate(g, "mean").x[1, 0] == 0.5
    b = a.interpolate(g, "both")
    np.testing.assert_array_equal(b.j, [0, 0, 2, 2])
    np.testing.assert_array_equal(b.x[:, 0], [0.5, 1, 0, 0.5])


def test_interpolate_errors(timer):
    with pytest.raises(ValueError, match=r"outside the arc's time range \[0.0, 3.5\]"):
        timer.interpolate([0.0, 4.0])
    with pytest.raises(ValueError, match="outside"):
        timer.interpolate([-1.0, 1.0])
    with pytest.raises(ValueError, match=r"sorted.*t_grid\[2\] = 0.5 < t_grid\[1\] = 2.0"):
        timer.interpolate([1.0, 2.0, 0.5])
    with pytest.raises(ValueError, match="at_jump must be one of"):
        timer.interpolate([1.0], at_jump="after")
    with pytest.raises(ValueError, match="1-D"):
        timer.interpolate(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="finite"):
        timer.interpolate([np.nan])
    t, j, x = timer.interpolate([])
    assert t.shape == j.shape == (0,) and x.shape == (0, 1)


# ------------------------------------------------------ restrict/select
def test_restrict_window_without_samples_gets_interpolated_ends(ball):
    k = 3
    a, b = ball.t[k] + 0.25 * (ball.t[k + 1] - ball.t[k]), ball.t[k] + 0.75 * (
        ball.t[k + 1] - ball.t[k])
    assert not np.any((ball.t >= a) & (ball.t <= b))
    with_samples_none = ball.restrict(t=(a, b))
    np.testing.assert_array_equal(with_samples_none.t, [a, b])
    np.testing.assert_array_equal(with_samples_none.j, [0, 0])
    np.testing.assert_allclose(with_samples_none.x, parabola(ball, np.array([a, b]), 0),
                               atol=1e-12)
    # the end samples carry the derivative of the interpolant: exact here
    v = parabola(ball, np.array([a, b]), 0)[:, 1]
    np.testing.assert_allclose(with_samples_none.xdot, np.stack([v, [-G, -G]], 1),
                               atol=1e-11)
    assert with_samples_none.stats == {"steps": 7}
    # select behaves the same instead of raising
    np.testing.assert_array_equal(ball.select(t=(a, b)).x, with_samples_none.x)
    # a single time inside a flow: one sample
    one = ball.restrict(t=(a, a))
    assert len(one) == 1 and one.t[0] == a


def test_restrict_across_a_jump(ball):
    tj = ball.jump_times[0]
    a, b = tj - 0.05, tj + 0.05
    r = ball.restrict(t=(a, b))
    assert r.t[0] == a and r.t[-1] == b and r.jump_count == 1
    np.testing.assert_array_equal(r.jump_times, [tj])
    inside = (ball.t >= a) & (ball.t <= b)
    np.testing.assert_array_equal(r.t[1:-1], ball.t[inside])
    np.testing.assert_allclose(r.x[0], parabola(ball, a, 0), atol=1e-12)
    np.testing.assert_allclose(r.x[-1], parabola(ball, b, 1), atol=1e-12)
    r.validate()
    # at() on the restricted arc agrees with the original inside the window
    s = np.linspace(a, b, 9)
    np.testing.assert_allclose(r.at(s), ball.at(s), atol=1e-13)
    # the window of the jump time alone holds both samples of the jump
    at_jump = ball.restrict(t=(tj, tj))
    np.testing.assert_array_equal(at_jump.j, [0, 1])
    # restricted in j too: only the pre-jump side
    pre = ball.restrict(t=(a, b), j=0)
    assert set(pre.j) == {0} and pre.t[-1] == tj


def test_restrict_empty_and_select_errors(ball):
    assert len(ball.restrict(t=(50.0, 60.0))) == 0
    e = ball.restrict(t=(0.0, 0.1), j=(2, 3))          # window meets no (t, j) of it
    assert len(e) == 0 and e.x.shape == (0, 2) and e.jump_count == 0
    assert "empty" in repr(e) and e.flow_intervals == []
    with pytest.raises(ValueError, match="x0: the arc is empty"):
        _ = e.x0
    with pytest.raises(ValueError, match="does not meet the hybrid time domain"):
        ball.select(t=(50.0, 60.0))
    with pytest.raises(ValueError, match="no sample"):
        ball.select(j=99)
    with pytest.raises(TypeError, match=r"select: t must be a pair \(a, b\).*got 5.*arc.at\(5\)"):
        ball.select(t=5)
    with pytest.raises(TypeError, match=r"pair \(a, b\)"):
        ball.restrict(t=(1, 2, 3))
    with pytest.raises(ValueError, match="empty"):
        ball.restrict(t=(2.0, 1.0))
    with pytest.raises(TypeError, match="ints"):
        ball.restrict(j=(0.5, 2))
    # open ends
    r = ball.restrict(t=(None, 0.2))
    assert r.t[0] == 0.0 and r.t[-1] == 0.2
    np.testing.assert_array_equal(ball.restrict(j=(2, None)).t, ball.t[ball.j >= 2])


def test_select_by_j_keeps_stored_samples(ball):
    s = ball.select(j=1)
    np.testing.assert_array_equal(s.t, ball.t[ball.j == 1])
    np.testing.assert_array_equal(s.xdot, ball.xdot[ball.j == 1])


# ------------------------------------------------------------ transform
def test_transform_energy_is_constant_on_each_flow(ball):
    en = ball.transform(lambda x: G * x[0] + 0.5 * x[1] ** 2)
    assert en.x.shape == (len(ball), 1) and en.xdot is None and en.system is None
    np.testing.assert_array_equal(en.t, ball.t)
    np.testing.assert_array_equal(en.j, ball.j)
    for j in range(ball.jf + 1):
        e = en.x[en.j == j, 0]
        np.testing.assert_allclose(e, e[0], rtol=1e-12)
    # energy after each impact: e^2 times the energy before
    e0 = en.x[ball.is_jump_start, 0]
    e1 = en.x[ball.is_jump_end, 0]
    np.testing.assert_allclose(e1, 0.64 * e0, rtol=1e-12)
    # every signature
    tj = ball.transform(lambda x, t, j: [t, j, x[0]])
    np.testing.assert_array_equal(tj.x, np.stack([ball.t, ball.j, ball.x[:, 0]], 1))
    np.testing.assert_array_equal(ball.transform(lambda x, t: t).x[:, 0], ball.t)


def test_transform_keeps_dense_output():
    a = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=1.0, j_max=2, dense=True)
    h = a.transform(lambda x: x[0])
    s = np.linspace(0, 0.4, 11)
    np.testing.assert_allclose(h.at(s)[:, 0], 1 - 0.5 * G * s ** 2, atol=1e-9)
    np.testing.assert_allclose(h.at(0.3)[0], a.at(0.3)[0], atol=0)


def test_transform_errors(ball):
    with pytest.raises(ValueError, match="1-D"):
        ball.transform(lambda x: np.eye(2))
    with pytest.raises(ValueError, match="complex"):
        ball.transform(lambda x: x + 1j)
    with pytest.raises(ValueError, match="one length"):
        ball.transform(lambda x, t, j: np.zeros(j + 1))
    with pytest.raises(TypeError, match="callable"):
        ball.transform(3)


# ---------------------------------------------------------- masks, misc
def test_jump_masks(ball):
    s, e = ball.is_jump_start, ball.is_jump_end
    assert s.dtype == bool and s.shape == e.shape == (len(ball),)
    assert s.sum() == e.sum() == ball.jump_count
    np.testing.assert_array_equal(ball.t[s], ball.jump_times)
    np.testing.assert_array_equal(ball.t[e], ball.t[s])
    np.testing.assert_array_equal(ball.j[e], ball.j[s] + 1)
    assert np.all(ball.x[s, 0] <= 1e-12)
    assert np.all(ball.x[s, 1] < 0) and np.all(ball.x[e, 1] > 0)


def test_iteration_is_refused_with_directions(ball):
    with pytest.raises(TypeError, match=r"zip\(arc.t, arc.j, arc.x\)"):
        list(ball)
    assert "a" not in ball
    rows = list(zip(ball.t, ball.j, ball.x))
    assert len(rows) == len(ball)


def test_components_carry_xdot_and_stats():
    sysm = hs.Interconnection({"p": BouncingBall(), "q": Timer(0.5)})
    a = hs.simulate(sysm, [1.0, 0.0, 0.0], t_max=1.0, j_max=5)
    xd = np.array([sysm.flow_map(x, t, j) for x, t, j in zip(a.x, a.t, a.j)])
    a = hs.HybridArc(a.t, a.j, a.x, a.termination, components=a.components,
                     system=sysm, xdot=xd, stats={"nfev": 3})
    assert "p" in a and "z" not in a
    q = a["q"]
    np.testing.assert_array_equal(q.xdot, xd[:, 2:])
    assert q.stats == {"nfev": 3} and q.stats is not a.stats


def test_constructor_validates_xdot_and_stats():
    with pytest.raises(ValueError, match=r"xdot must have the shape of x, \(N, n\) = \(2, 1\)"):
        hs.HybridArc([0, 1], [0, 0], [[0], [1]], None, xdot=np.zeros((2, 2)))
    with pytest.raises(TypeError, match="stats must be a dict"):
        hs.HybridArc([0, 1], [0, 0], [[0], [1]], None, stats=[1])
    with pytest.raises(ValueError, match="j must hold integers"):
        hs.HybridArc([0, 1], [0, 0.5], [[0], [1]], None)


def test_validate_catches_broken_invariants():
    ok = dict(t=[0, 1, 1], j=[0, 0, 1], x=[[0], [1], [0]])
    hs.HybridArc(**ok, termination=None).validate()
    for t, j, msg in [([0, 2, 1], [0, 0, 0], "goes backwards"),
                      ([0, 1, 2], [0, 0, 1], "changes t"),
                      ([0, 1, 1], [0, 0, 2], "increase by 0 or 1"),
                      ([0, np.inf, 3], [0, 0, 0], "not finite")]:
        with pytest.raises(ValueError, match=msg):
            hs.HybridArc(t, j, ok["x"], None).validate()


def test_module_examples_run():
    res = doctest.testmod(arc_module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert res.attempted > 10 and res.failed == 0


def test_engine_xdot_gives_exact_interpolation_without_dense_output():
    a = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=3.0, j_max=4)
    assert a.xdot is not None, "the Python path records xdot at every sample"
    assert a._segments is None and a.xdot.shape == a.x.shape
    blk = a.t[a.j == 0]
    mids = 0.5 * (blk[1:] + blk[:-1])
    np.testing.assert_allclose(a.at(mids, 0)[:, 0], 1 - 0.5 * G * mids ** 2,
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.at(mids, 0)[:, 1], -G * mids, rtol=0, atol=1e-12)
    # and through restrict: the interpolated ends carry exact derivatives
    r = a.restrict(t=(mids[1], mids[-1]))
    np.testing.assert_allclose(r.xdot[[0, -1], 0], -G * mids[[1, -1]], atol=1e-12)
