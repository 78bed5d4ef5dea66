"""Signal temporal logic over hybrid arcs (hybridsim.stl): hand-computed
robustness, RTAMT where both semantics apply, jumps at located event times,
properties against a brute-force evaluation on a fine grid, and use as a claim."""
import math
import types

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hybridsim as hs
from hybridsim import stl
from hybridsim.falsification import Interval, Space
from hybridsim.library import BouncingBall
from hybridsim.sensitivity import margin_gradient

G_ACC, E_REST = 9.81, 0.8
T1 = math.sqrt(2.0 / G_ACC)                 # first impact from h0 = 1 at rest
V_PLUS = E_REST * math.sqrt(2.0 * G_ACC)     # speed after it
h, v = stl.state(0, "h"), stl.state(1, "v")


@pytest.fixture(scope="module")
def ball():
    return hs.simulate(BouncingBall(), [1.0, 0.0], t_max=1.5)


def gear_box(t_shift):
    """(clock, gear): clock' = 1; at clock = t_shift the gear goes up, the clock to 0."""
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0, 0.0]), jump_map=lambda x: np.array([0.0, x[1] + 1.0]),
        jump_guard=lambda x: x[0] - t_shift, flow_guard=lambda x: t_shift - x[0],
        state_dim=2)


# ---------------------------------------------------------- hand-computed --
def test_ball_always_and_eventually_by_hand(ball):
    # the floor: the least height is 0, at an impact (rounding of the event: 1e-12)
    m = stl.G(h >= 0, 0, 1.5)(ball)
    assert abs(float(m)) < 1e-12 and m.where[0] in ball.jump_times
    # the start decides G(h <= 0.9): 0.9 - 1
    m = stl.G(h <= 0.9, 0, 1.5)(ball)
    assert float(m) == pytest.approx(-0.1, abs=1e-15) and m.where == (0.0, 0)
    # the apex after the first bounce lies between samples: e^2 = 0.64 at t1 (1 + e);
    # the arc's Hermite interpolant is exact on the parabola, the extremum located
    # to 1e-5 of a step (value error O(step^2 1e-10))
    m = stl.F(h >= 0.5, 0.5, 1.0)(ball)
    assert float(m) == pytest.approx(E_REST ** 2 - 0.5, abs=1e-9)
    assert m.where == (pytest.approx(T1 * (1 + E_REST), abs=1e-5), 1)
    # with refine=1 only the samples, crossings and window ends: below the apex
    assert float(stl.F(h >= 0.5, 0.5, 1.0)(ball, refine=1)) < float(m) - 1e-3
    # the speed right after the impact (the post-jump instant decides)
    m = stl.G(v <= 3, 0, 1.0)(ball)
    assert float(m) == pytest.approx(3 - V_PLUS, rel=1e-9)
    assert m.where == (pytest.approx(T1, abs=1e-12), 1)


def test_ball_window_ends_are_evaluation_instants(ball):
    # h(0.3) = 1 - g 0.3^2 / 2 exactly (the window end is evaluated on the interpolant)
    m = stl.G(h >= 0.0, 0.0, 0.3)(ball, t=0.0)
    assert float(m) == pytest.approx(1 - G_ACC * 0.09 / 2, abs=1e-12)
    m = stl.F(stl.G(h >= 0.1, 0, 0.2), 0, 1)(ball)    # decided at tau = 0: h(0.2) - 0.1
    assert float(m) == pytest.approx(1 - G_ACC * 0.04 / 2 - 0.1, abs=1e-12)


def test_ball_until_by_hand(ball):
    # v >= 1 first holds right after the impact; h >= 0.2 fails before it (h = 0 at
    # the impact): sup over t' of min(psi, inf phi) = inf over [0, t1] of h - 0.2 = -0.2
    assert float(stl.until(h >= 0.2, v >= 1, 0, 1)(ball)) == pytest.approx(-0.2, abs=1e-12)
    # with phi = h >= -0.1 it holds by 0.1 (the impact, psi = V_PLUS - 1 there)
    assert float(stl.U(h >= -0.1, v >= 1, 0, 1)(ball)) == pytest.approx(0.1, abs=1e-12)
    # psi is needed inside [a, b]: before the impact it never holds (v <= 0 < 1)
    assert float(stl.U(h >= -0.1, v >= 1, 0, 0.4)(ball)) == pytest.approx(-1.0, abs=1e-12)


def test_an_excursion_between_samples_is_found_by_the_probes():
    """|x| with x = t - 0.55 sampled at 0 and 1 only: |x| <= 0.1 holds on
    [0.45, 0.65], between the samples, where both give -0.35 and -0.45. The probes
    reveal the dip, whose minimum (the kink at 0.55) is located to 1e-5 of the
    step; then its crossings are found too. With refine=1 it is missed."""
    arc = hs.HybridArc([0.0, 1.0], [0, 0], [[-0.55], [0.45]], hs.Termination.T_MAX)
    phi = stl.F(abs(stl.state(0)) <= 0.1, 0, 1)
    m = phi(arc)
    assert float(m) == pytest.approx(0.1, abs=1e-5) and m.where[0] == pytest.approx(0.55, abs=1e-5)
    assert float(phi(arc, refine=1)) == pytest.approx(-0.35)
    # the instants of G over the window: the crossings at 0.45 and 0.65 are exact
    g = stl.G(abs(stl.state(0)) >= 0.1, 0, 1)(arc)
    assert float(g) == pytest.approx(-0.1, abs=1e-5)
    t, j, val = g.series
    assert np.min(val) == float(g)
    assert np.any(np.abs(t - 0.45) < 1e-12) and np.any(np.abs(t - 0.65) < 1e-12)


def test_boolean_connectives_by_hand(ball):
    p, q = h >= 0.5, v <= -1
    at0 = (0.5, -1.0)                                  # h - 0.5 and -1 - v at t = 0
    assert float((p & q)(ball)) == min(at0)
    assert float((p | q)(ball)) == max(at0)
    assert float((~p)(ball)) == -at0[0]
    assert float(stl.implies(p, q)(ball)) == max(-at0[0], at0[1])
    assert float((p >> q)(ball)) == float(stl.implies(p, q)(ball))


# ------------------------------------------------- jumps at located events --
@pytest.mark.parametrize("t_shift", [2.5, 0.05])
def test_a_mode_change_at_a_located_event_is_an_exact_instant(t_shift):
    arc = hs.simulate(gear_box(t_shift), [0.0, 1.0], t_max=2 * t_shift + 0.3)
    te = float(arc.jump_times[0])
    assert te == pytest.approx(t_shift, abs=1e-12)
    gear = stl.state(1, "gear")
    one, two = stl.equals(gear, 1), stl.equals(gear, 2)
    eps = 1e-9
    assert float(stl.G(one, 0, te - eps)(arc)) == 0.5
    m = stl.G(one, 0, te + eps)(arc)
    assert float(m) == -0.5 and m.where == (te, 1)          # decided at the event itself
    # a window closing on the jump time reads both of its values
    assert float(stl.G(one, 0, te)(arc)) == -0.5
    assert float(stl.F(two, 0, te)(arc)) == 0.5
    assert float(stl.F(two, 0, te - eps)(arc)) == -0.5
    # the competition's short windows: F[0.001, 0.1] sees the shift iff it lies inside
    f = stl.F(two, 0.001, 0.1)(arc, t=te - 0.05)
    assert float(f) == 0.5 and f.where == (te, 1)
    if te - 0.1 - eps >= 0:
        assert float(stl.F(two, 0.001, 0.1)(arc, t=te - 0.1 - eps)) == -0.5
    assert float(stl.F(two, 0.001, 0.1)(arc, t=te - 0.001 + eps)) == 0.5  # (te, 1) itself
    # the mode as the jump counter
    assert float(stl.G(stl.equals(stl.jumps(), 0), 0, te - eps)(arc)) == 0.5


def test_a_window_never_reaches_back_before_its_hybrid_instant():
    """At a shift's post-jump instant G[0, d] (gear == 2) reads the post-jump value
    only, so the ARCH-COMP AT5x pattern holds at every shift instead of failing at
    the single tau where the short window's end meets the shift."""
    arc = hs.simulate(gear_box(1.0), [0.0, 1.0], t_max=5.0)
    te = float(arc.jump_times[0])
    gear = stl.state(1, "gear")
    two = stl.equals(gear, 2)
    g = stl.G(two, 0, 0.5)
    assert float(g(arc, t=te, j=1)) == 0.5            # from the post-jump instant on
    assert float(g(arc, t=te, j=0)) == -0.5           # the pre-jump instant: gear 1
    assert float(g(arc, t=te)) == -0.5                # (the first j at t by default)
    at5x = stl.G((~two & stl.F(two, 0.001, 0.1)) >> stl.F(stl.G(two, 0, 0.5), 0.001, 0.1),
                 0, 2.5)
    assert float(at5x(arc)) == 0.5
    # gear 2 lasts 1 s: a G[0, 1.5] consequent fails, decided at a shift (a gear
    # other than 2 inside the window)
    at5x = stl.G((~two & stl.F(two, 0.001, 0.1)) >> stl.F(stl.G(two, 0, 1.5), 0.001, 0.1),
                 0, 2.5)
    m = at5x(arc)
    assert float(m) == -0.5
    assert np.min(np.abs(m.where[0] - arc.jump_times)) < 1e-12


def test_equals_convention():
    arc = hs.HybridArc([0.0, 1.0, 1.0, 2.0], [0, 0, 1, 1], [[1.0], [1.0], [4.0], [4.0]], None)
    gear = stl.state(0)
    # tol - |sig - value|: +0.5 where equal, -(d - 0.5) at distance d
    assert float(stl.G(stl.equals(gear, 1), 0, 2)(arc)) == -2.5
    assert float(stl.F(stl.equals(gear, 4), 0, 2)(arc)) == 0.5
    assert float(stl.F(stl.equals(gear, 4.25, tol=0.3), 0, 2)(arc)) == pytest.approx(0.05)
    assert str(stl.equals(gear, 4.25, tol=0.3)) == "|x[0] - 4.25| <= 0.3"


# ------------------------------------------------------------- RTAMT ------
def _rtamt():
    try:
        import rtamt
    except Exception as e:  # noqa: BLE001 - any import failure: skip with its reason
        pytest.skip(f"rtamt does not import: {type(e).__name__}: {e}")
    return rtamt


def _rtamt_discrete(spec_text, period, series, t):
    rtamt = _rtamt()
    spec = rtamt.StlDiscreteTimeSpecification()
    for name in series:
        spec.declare_var(name, "float")
    spec.set_sampling_period(round(period * 1000), "ms", 0.1)
    spec.spec = spec_text
    spec.parse()
    data = {"time": [float(s) for s in t]}
    data.update({k: [float(y) for y in val] for k, val in series.items()})
    return np.array([r[1] for r in spec.evaluate(data)])


SAMPLED = [  # (ours, RTAMT's text): formulas whose dense and discrete semantics agree
    (lambda x, y: stl.G(x >= 0.2, 0, 1), "always[0:1](x >= 0.2)"),
    (lambda x, y: stl.F(x <= -0.3, 0.5, 1.5), "eventually[0.5:1.5](x <= -0.3)"),
    (lambda x, y: stl.G(x >= 0.2, 0, 1) | stl.F(y > 0.1, 0, 0.5),
     "always[0:1](x >= 0.2) or eventually[0:0.5](y > 0.1)"),
    (lambda x, y: stl.implies(x > 0, stl.G(y < 0.9, 0.25, 0.75)),
     "(x > 0) implies always[0.25:0.75](y < 0.9)"),
    (lambda x, y: ~stl.F(x - y >= 0.5, 0, 1) & (y <= 0.8),
     "not(eventually[0:1](x - y >= 0.5)) and (y <= 0.8)"),
]


@pytest.mark.parametrize("k", range(len(SAMPLED)))
def test_agrees_with_rtamt_discrete_time_on_a_linear_sampled_signal(k):
    """On a uniform grid with linear interpolation between samples (an arc without
    xdot or dense output), windows whose ends are samples, and predicates of one
    signal each under a temporal operator, the dense and the discrete semantics give
    the same numbers: a linear piece's extremes are at its ends, and a crossing's
    value 0 is never an extreme over a window it lies in."""
    period = 0.25
    t = np.arange(0, 6.0 + 1e-12, period)
    rng = np.random.default_rng(k)
    X = np.column_stack((np.sin(1.3 * t) + 0.2 * rng.standard_normal(t.size),
                         np.cos(0.7 * t) + 0.2 * rng.standard_normal(t.size)))
    arc = hs.HybridArc(t, np.zeros(t.size, int), X, hs.Termination.T_MAX)
    ours_fn, text = SAMPLED[k]
    phi = ours_fn(stl.state(0), stl.state(1))
    ref = _rtamt_discrete(text, period, {"x": X[:, 0], "y": X[:, 1]}, t)
    n = round((t[-1] - phi.horizon) / period) + 1     # times with a full window
    ours = np.array([float(phi(arc, t=float(s))) for s in t[:n]])
    np.testing.assert_allclose(ours, ref[:n], rtol=0, atol=1e-12)


def test_differs_from_rtamt_where_a_crossing_lies_between_samples():
    """Two signals that hold together only between samples: dense time finds the
    instant (t = 0.5, robustness 0.1); discrete time sees the samples only (-0.9)."""
    t = np.array([0.0, 1.0, 2.0])
    X = np.column_stack((1.1 - 2 * t, 2 * t - 0.9))
    arc = hs.HybridArc(t, [0, 0, 0], X, hs.Termination.T_MAX)
    phi = stl.F((stl.state(0) >= 0) & (stl.state(1) >= 0), 0, 1)
    m = phi(arc)
    assert float(m) == pytest.approx(0.1, abs=1e-15) and m.where == (0.5, 0)
    ref = _rtamt_discrete("eventually[0:1]((x >= 0) and (y >= 0))", 1.0,
                          {"x": X[:, 0], "y": X[:, 1]}, t)
    assert ref[0] == pytest.approx(-0.9)


def test_the_crossing_instant_is_exact_on_the_dense_output():
    """x = 1 - t^2 (cubic Hermite from xdot: exact), samples at 0, 0.75, 1.5: the
    zero of x >= 0 at t = 1 is found to 4 ulp; no sampled monitor puts it there."""
    t = np.array([0.0, 0.75, 1.5])
    arc = hs.HybridArc(t, [0, 0, 0], (1 - t ** 2)[:, None], hs.Termination.T_MAX,
                       xdot=(-2 * t)[:, None])
    x = stl.state(0)
    for d in (1e-6, 1e-9):
        assert stl.G(x >= 0, 0, 1 - d)(arc) > 0
        m = stl.G(x >= 0, 0, 1 + d)(arc)
        assert float(m) == pytest.approx(-(2 * d + d * d), rel=1e-6) and m.where[0] == 1 + d
    # F[0,1.5] (x <= 0) & ...: the crossing is an instant (value 0) of the predicate
    m = stl.F(stl.G(x <= 0, 0, 0.5), 0, 1)(arc)
    assert abs(float(m)) < 1e-15 and m.where[0] == pytest.approx(1.0, abs=4e-16)


def test_jumps_agree_with_rtamt_dense_time_except_at_the_jump_instant():
    """RTAMT's dense time reads a sampled signal as piecewise constant, right-continuous:
    a mode signal changing at the arc's jump times. Windows that do not start at a jump
    agree; one that starts at a jump time differs: the hybrid time domain holds both
    the pre- and the post-jump value at that instant, RTAMT only the new one."""
    rtamt = _rtamt()
    arc = hs.simulate(gear_box(1.0), [0.0, 1.0], t_max=3.5)
    te = arc.jump_times
    samples = [[0.0, 1.0]] + [[float(s), float(g)] for s, g in zip(te, [2.0, 3.0, 4.0])]

    def dense(text):
        spec = rtamt.StlDenseTimeSpecification()
        spec.declare_var("gear", "float")
        spec.spec = text
        spec.parse()
        return spec.evaluate(["gear", samples])[0][1]

    gear = stl.state(1)
    for a, b in [(0, 0.9), (0, 1.0), (0, 2.5), (0.5, 1.5), (0.2, 0.7), (1.5, 3.2)]:
        for ours, text in [
                (stl.G(stl.equals(gear, 1), a, b), "always[{}:{}](abs(gear - 1) <= 0.5)"),
                (stl.F(stl.equals(gear, 3), a, b), "eventually[{}:{}](abs(gear - 3) <= 0.5)")]:
            assert float(ours(arc)) == pytest.approx(dense(text.format(a, b)), abs=1e-12)
    # a window starting at the jump at t = 1
    assert dense("always[1:1.5](abs(gear - 2) <= 0.5)") == pytest.approx(0.5)
    assert float(stl.G(stl.equals(gear, 2), 1.0, 1.5)(arc)) == -0.5


# --------------------------------------------------------------- properties --
@st.composite
def pl_arcs(draw):
    """Random piecewise-linear arcs (no xdot): samples on a 0.1 grid, values in [-1, 1],
    jumps at some of the sample times."""
    n = draw(st.integers(8, 30))
    times = np.round(np.arange(n) * 0.1, 10)
    jumps = draw(st.lists(st.integers(1, n - 2), max_size=4, unique=True))
    vals = draw(st.lists(st.floats(-1, 1), min_size=2 * (n + len(jumps)),
                         max_size=2 * (n + len(jumps))))
    T, J = [], []
    j = 0
    for k, s in enumerate(times):
        T.append(s)
        J.append(j)
        if k in jumps:
            j += 1
            T.append(s)
            J.append(j)
    X = np.array(vals[:2 * len(T)]).reshape(len(T), 2)
    return hs.HybridArc(T, J, X, hs.Termination.T_MAX)


WIN = st.sampled_from([(0.0, 0.0), (0.0, 0.3), (0.1, 0.5), (0.2, 0.2), (0.0, 1.0), (0.3, 0.7)])


@st.composite
def formulas(draw, depth=2):
    x = [stl.state(0), stl.state(1)]
    if depth == 0 or draw(st.booleans()):
        c = draw(st.sampled_from([-0.5, 0.0, 0.3]))
        i = draw(st.integers(0, 1))
        return x[i] >= c if draw(st.booleans()) else x[i] <= c
    kind = draw(st.sampled_from(["F", "G", "and", "or", "not", "U"]))
    if kind in ("F", "G"):
        a, b = draw(WIN)
        return (stl.F if kind == "F" else stl.G)(draw(formulas(depth - 1)), a, b)
    if kind == "not":
        return ~draw(formulas(depth - 1))
    if kind == "U":
        a, b = draw(WIN)
        return stl.until(draw(formulas(0)), draw(formulas(0)), a, b)
    p, q = draw(formulas(depth - 1)), draw(formulas(depth - 1))
    return p & q if kind == "and" else p | q


def brute(phi, arc, t, dt):
    """The robustness on a uniform grid of step dt (the arc's samples on it, both
    values at each jump time): min / max over the grid instants in each window."""
    tf = float(arc.t[-1])
    grid = np.round(np.arange(0, tf + dt / 2, dt), 12)
    T, J, X = arc.interpolate(grid, at_jump="both")
    memo = {}

    def rho(f):
        if id(f) in memo:
            return memo[id(f)]
        if isinstance(f, stl._Predicate):
            out = f._rho(T, J, X)
        elif isinstance(f, stl._Not):
            out = -rho(f.phi)
        elif isinstance(f, stl._Implies):
            out = np.maximum(-rho(f.phi), rho(f.psi))
        elif isinstance(f, stl._Binary):
            out = f.op(rho(f.phi), rho(f.psi))
        elif isinstance(f, stl._Window):
            r = rho(f.phi)
            red = np.max if f.sup else np.min
            # the instants in the window, none before (s, j) in hybrid time
            out = np.array([red(r[(T >= s + f.a - 1e-9) & (T <= min(s + f.b, tf) + 1e-9)
                                  & ~((T == s) & (J < jk))],
                                initial=-np.inf if f.sup else np.inf) for s, jk in zip(T, J)])
        else:                                           # until
            r1, r2 = rho(f.phi), rho(f.psi)
            out = np.empty(len(T))
            for k, s in enumerate(T):
                # every instant from (s, j) on, in hybrid time order
                seq = np.arange(k, len(T))
                seq = seq[T[seq] <= min(s + f.b, tf) + 1e-9]
                m = np.minimum.accumulate(r1[seq])
                ok = T[seq] >= s + f.a - 1e-9
                out[k] = np.max(np.minimum(r2[seq], m)[ok]) if ok.any() else -np.inf
        memo[id(f)] = out
        return out

    k = np.flatnonzero(np.isclose(T, t))[0]
    return float(rho(phi)[k])


@pytest.mark.slow
@settings(max_examples=60, deadline=None, derandomize=True)
@given(arc=pl_arcs(), phi=formulas(), a=st.sampled_from([0.0, 0.1, 0.3]))
def test_robustness_against_a_fine_grid(arc, phi, a):
    """Against the brute-force semantics on a grid of step 1e-3 (the arc's samples on
    it): the two differ by at most the signals' variation over a grid step, 20 (slope
    of a piece: 2 / 0.1) x 1e-3 per nested window end, 3 levels: 0.06; the sign agrees
    wherever the robustness is larger than that; the Boolean connectives are exact."""
    t = a
    if t + phi.horizon > arc.t[-1] + 1e-9:
        return
    ours = float(phi(arc, t=t))
    ref = brute(phi, arc, t, 1e-3)
    assert ours == pytest.approx(ref, abs=0.06)
    if abs(ours) > 0.06:
        assert np.sign(ours) == np.sign(ref)


@pytest.mark.slow
@settings(max_examples=60, deadline=None, derandomize=True)
@given(arc=pl_arcs(), p=formulas(1), q=formulas(1), w=WIN)
def test_duality_and_distribution(arc, p, q, w):
    a, b = w
    if b + max(p.horizon, q.horizon) > arc.t[-1]:
        return
    r = float
    assert r((~stl.F(p, a, b))(arc)) == r(stl.G(~p, a, b)(arc))
    assert r((~stl.G(p, a, b))(arc)) == r(stl.F(~p, a, b)(arc))
    # sup distributes over max, inf over min; a window splits at any inner point
    assert r(stl.F(p | q, a, b)(arc)) == pytest.approx(r((stl.F(p, a, b) | stl.F(q, a, b))(arc)),
                                                       abs=1e-12)
    assert r(stl.G(p & q, a, b)(arc)) == pytest.approx(r((stl.G(p, a, b) & stl.G(q, a, b))(arc)),
                                                       abs=1e-12)
    c = 0.5 * (a + b)
    assert r(stl.F(p, a, b)(arc)) == pytest.approx(r((stl.F(p, a, c) | stl.F(p, c, b))(arc)),
                                                   abs=1e-12)
    # the until at [0, b] against F: phi U psi <= F psi
    assert r(stl.U(p, q, a, b)(arc)) <= r(stl.F(q, a, b)(arc)) + 1e-12


def _window_reference(s, tau, j, a, b, E, ulps=4):
    """sup of the signal ``s`` (a ``_stl_eval._Sig``) over [tau + a, min(tau + b, E)],
    read at the hybrid instant (tau, j), from the definition: every instant in the
    window (its value, and its limits from inside the window), the pieces' values
    at the window's ends, and with a = 0 none of the instants before (tau, j); an
    instant within the engine's tolerance (``ulps`` = 4 ulp) of an end is at that end."""
    alpha, beta = tau + a, min(tau + b, E)
    tol = [ulps * np.finfo(float).eps * max(1.0, abs(x)) for x in (alpha, beta)]
    if alpha > E + ulps * np.finfo(float).eps * max(1.0, abs(E)):
        return -np.inf
    t, jj, v, l, r = s.t, s.j, s.v, s.l, s.r
    n = len(t)
    best = -np.inf
    at_end = [False, False]
    for k in range(n):
        first, last = abs(t[k] - alpha) <= tol[0], abs(t[k] - beta) <= tol[1]
        at_end = [at_end[0] or first, at_end[1] or last]
        if not (first or last or alpha < t[k] < beta):
            continue
        if a == 0 and first and jj[k] < j:
            continue
        best = max(best, v[k])
        if not first and k > 0 and jj[k - 1] == jj[k]:
            best = max(best, l[k])
        if not last and k + 1 < n and jj[k + 1] == jj[k]:
            best = max(best, r[k])
    for x, hit in zip((alpha, beta), at_end):   # an end inside a piece
        k = np.flatnonzero((t[:-1] < x) & (t[1:] > x) & (jj[:-1] == jj[1:]))
        if k.size and not hit:
            k = int(k[0])
            best = max(best, r[k] + (x - t[k]) / (t[k + 1] - t[k]) * (l[k + 1] - r[k]))
    return best


@pytest.mark.parametrize("seed", range(6))
def test_window_sup_against_its_definition_on_random_signals_with_jumps(seed):
    """The sliding sup (``_stl_eval._window_sup``, every F / G window) against
    :func:`_window_reference` at each instant of its result, its limits from the left
    and right against the reference just beside it: piecewise-linear signals with
    jumps, ties, flat stretches and limits apart from the values, on a grid of 1/8
    (the window ends exact), windows nested twice (the inner result's kinks off the
    grid). A window end found a little more than 4 ulp from an instant was read on
    the piece past the instant (the rounded search bound crossed it)."""
    from hybridsim import _stl_eval as ev
    rng = np.random.default_rng(seed)
    for _ in range(8):
        n = int(rng.integers(3, 40))
        dt = rng.choice([0.0, 0.125, 0.25, 0.5, 1.0], size=n - 1, p=[0.2, 0.3, 0.2, 0.2, 0.1])
        t = np.concatenate(([0.0], np.cumsum(dt)))
        t[-1] = max(t[-1], 0.5)
        j = np.concatenate(([0], np.cumsum(dt == 0)))
        v = rng.integers(-2, 3, n) * 0.5 if rng.random() < 0.5 else rng.normal(size=n)
        arc = hs.HybridArc(t, j, np.column_stack((v, v)), None)
        ctx = ev._Context(arc, False, 1)
        E = float(t[-1])
        # limits apart from the value at some instants (as a window's result has them)
        lim = [np.where(rng.random(n) < 0.3, v + rng.integers(-2, 3, n) * 0.5, v)
               for _ in range(2)]
        sig = ev._Sig(ctx.t, ctx.j, v.astype(float), *lim)
        for _ in range(4):
            a = float(rng.choice([0.0, 0.0, 0.25, 0.5]))
            b = float(rng.choice([a, a + 0.25, a + 0.5, a + 1.0, a + 2.0]))
            lo = float(rng.choice([0.0, 0.125, 0.25]))
            hi = float(rng.choice([lo, E]))
            for inner in (sig, sig.neg(), ev._window_sup(ctx, sig, 0.0, 0.375, 0.0, E)):
                out = ev._window_sup(ctx, inner, a, b, lo, hi)
                for k in range(len(out.t)):
                    tau, jk = float(out.t[k]), int(out.j[k])
                    # an instant a few ulp from an instant (a kink beside a breakpoint)
                    # may read the window's end as at the instant or as just beside it
                    ref = [_window_reference(inner, tau, jk, a, b, E, ulps) for ulps in (4, 0)]
                    assert any(out.v[k] == x or abs(out.v[k] - x) <= 1e-12 for x in ref), \
                        (a, b, lo, hi, tau, jk, out.v[k], ref)
                    for side, near in ((-1, k - 1), (1, k + 1)):
                        if not (0 <= near < len(out.t)) or out.j[near] != jk \
                                or abs(out.t[near] - tau) < 1e-6:
                            continue
                        d = 1e-7 * abs(float(out.t[near]) - tau)
                        got = out.l[k] if side < 0 else out.r[k]
                        assert got == pytest.approx(
                            _window_reference(inner, tau + side * d, jk, a, b, E),
                            abs=1e-5), (side, a, b, lo, hi, tau, jk)


def test_sorted_keys_are_searched_as_numpy_searches():
    """``_stl_eval._search`` (one stable merge for long sorted keys) against
    np.searchsorted, both sides, with ties, repeated keys and unsorted keys."""
    from hybridsim import _stl_eval as ev
    rng = np.random.default_rng(3)
    for n, m in ((1, 600), (50, 2000), (3000, 4000), (2000, 700)):
        a = np.sort(rng.integers(0, 400, n) * 0.25)
        x = np.sort(np.concatenate((rng.integers(-4, 404, m - m // 3) * 0.25,
                                    rng.choice(a, m // 3))))
        for keys in (x, x[::-1], np.concatenate((x, [np.nan])), x[:10]):
            for side in ("left", "right"):
                assert np.array_equal(ev._search(a, keys, side),
                                      np.searchsorted(a, keys, side=side))


def test_an_until_with_a_degenerate_window_does_not_depend_on_its_range():
    """phi U[a,a] psi is min(G[0,a] phi, psi at t + a): read over the range [lo, hi]
    its value at t must not look at psi past t + a (it looked to hi + a, so that
    F[0.3,0.7] p read -0.833 where F[0.3,0.5] p | F[0.5,0.7] p and the grid read -1)."""
    x0, x1 = stl.state(0), stl.state(1)
    arc = hs.HybridArc([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.6, 0.7, 0.8, 0.9],
                       [0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1],
                       [[-1.0, 1.0], [-0.5, 0.0], [-1.0, -0.5], [-0.5, 0.0], [1.0, 1.0],
                        [-0.5, 0.0], [0.5, 0.0], [0.0, -1.0], [1.0, -1.0], [0.5, 0.5],
                        [1.0, 0.5]], hs.Termination.T_MAX)
    p = stl.until(x1 <= -0.5, x0 <= -0.5, 0.2, 0.2)
    whole = stl.F(p, 0.3, 0.7)(arc)
    assert float(whole) == pytest.approx(-1.0, abs=1e-12) and whole.where == (0.8, 1)
    split = stl.F(p, 0.3, 0.5) | stl.F(p, 0.5, 0.7)
    assert float(split(arc)) == pytest.approx(-1.0, abs=1e-12)
    assert brute(stl.F(p, 0.3, 0.7), arc, 0.0, 1e-3) == pytest.approx(-1.0, abs=1e-12)
    # pointwise, p at t is min(x0 <= -0.5 at t + 0.2, x1 <= -0.5 on [t, t + 0.2])
    assert float(p(arc, t=0.45)) == pytest.approx(-1.0, abs=1e-12)
    assert float(p(arc, t=0.3)) == pytest.approx(-1.5, abs=1e-12)


# ----------------------------------------------------------- as a claim ---
def test_a_formula_is_a_claim_for_falsify():
    space = Space(e=Interval(0.5, 0.9))

    def run(p):
        return hs.simulate(BouncingBall(restitution=p["e"]), [1.0, 0.0], t_max=1.0)

    claim = stl.G(v <= 3, 0, 1)              # fails for e > 3 / sqrt(2 g) = 0.677
    res = hs.falsify(run, space, claim, budget=40, seed=0, progress=False)
    assert res.verdict == "counterexample" and res.margin < 0
    assert res.where == (pytest.approx(T1, abs=1e-12), 1)
    assert res.margin == pytest.approx(3 - res.point["e"] * math.sqrt(2 * G_ACC), rel=1e-9)


def test_over_every_solution_of_an_exploration():
    counter = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0, 0.0]), flow_set=lambda x: x[0] <= 1.0,
        jump_set=lambda x: x[0] >= 1.0,
        jump_map_values=lambda x: [np.array([0.0, x[1] + c]) for c in (1.0, 2.0)], state_dim=2)
    tree = hs.explore(counter, [0.0, 0.0], t_max=3.5, j_max=4)
    m = stl.G(stl.state(1) <= 5, 0, 3.5)(tree)
    assert float(m) == -1.0 and m.where == (pytest.approx(3.0), 3)   # z = 6 after 2 + 2 + 2
    assert "solution" in m.what and m.solution is not None


def test_margin_gradient_through_the_jump():
    sarc = hs.simulate_sensitivity(BouncingBall(), [1.0, 0.0], t_max=1.0)
    g = margin_gradient(sarc, stl.G(v <= 3, 0, 1))
    # 3 - e sqrt(2 g h0 + v0^2): d/dh0 = -e g / sqrt(2 g h0), d/dv0 = 0 at v0 = 0
    assert g[0] == pytest.approx(-E_REST * G_ACC / math.sqrt(2 * G_ACC), rel=1e-5)
    assert abs(g[1]) < 1e-5


# ------------------------------------------------------------ the API -----
def test_text_and_horizon():
    x = stl.state(0)
    phi = stl.G((x > 1) >> stl.F(stl.state(2, "gear") < 3, 0.001, 0.1), 0, 10)
    assert str(phi) == "G[0,10]((x[0] > 1) -> F[0.001,0.1](gear < 3))"
    assert phi.horizon == pytest.approx(10.1)
    assert str(stl.until(x < 1, ~(x > 2), 0, 5)) == "((x[0] < 1) U[0,5] ~(x[0] > 2))"
    assert str(stl.F(abs(x - 1) / 2 <= stl.time())) == "F((|(x[0] - 1)| / 2) <= t)"
    assert stl.G(x > 0).horizon == math.inf and (x > 0).horizon == 0


def test_signal_functions_vectorised_or_row_by_row(ball):
    def norm(x):                   # written for one state: fails the probe rows on (m, n)
        return float(np.linalg.norm(x))

    def norm_v(x):
        return np.linalg.norm(x, axis=-1)

    a = stl.F(stl.signal(norm) >= 3.0, 0, 1)(ball)
    b = stl.F(stl.output(norm_v, "n") >= 3.0, 0, 1)(ball)
    assert float(a) == pytest.approx(float(b), abs=1e-12)
    assert float(a) == pytest.approx(math.sqrt(2 * G_ACC) - 3.0, rel=1e-9)   # |v| before the impact
    # t and j reach the function too
    m = stl.G(stl.signal(lambda x, t, j: t + j) <= 1.0, 0, 1.0)(ball)
    assert float(m) == pytest.approx(-1.0, abs=1e-12)       # (t, j) = (1, 1) at the end


def test_formulas_pickle(ball):
    """Claims travel to worker processes (distributed falsification): a formula
    pickles whenever its user functions do."""
    import pickle
    phi = stl.G((h > 0.5) >> stl.F(stl.signal(np.linalg.norm, "n") >= 3, 0, 0.5), 0, 1)
    back = pickle.loads(pickle.dumps(phi))
    assert str(back) == str(phi) and float(back(ball)) == float(phi(ball))


def test_strict_horizon_and_cut_windows():
    arc = hs.simulate(gear_box(1.0), [0.0, 1.0], t_max=1.5)
    x = stl.state(0)
    with pytest.raises(ValueError, match="reads the arc up to t = 3.*ends at t = 1.5"):
        stl.G(x >= 0, 0, 3)(arc)
    assert float(stl.G(x <= 0.9, 0, 3)(arc, strict=False)) == pytest.approx(-0.1)
    assert float(stl.F(x >= 0, 2, 3)(arc, strict=False)) == -math.inf
    assert float(stl.G(x >= 0, 2, 3)(arc, strict=False)) == math.inf
    # unbounded windows read to the end of the arc
    assert float(stl.F(stl.equals(stl.state(1), 2))(arc)) == 0.5


def test_bad_input_is_named():
    x = stl.state(0)
    arc = hs.HybridArc([0.0, 1.0], [0, 0], [[0.0], [1.0]], None)
    with pytest.raises(ValueError, match="always: a must be finite and >= 0"):
        stl.G(x > 0, -1, 1)
    with pytest.raises(ValueError, match="eventually: b must be >= a"):
        stl.F(x > 0, 2, 1)
    with pytest.raises(ValueError, match="until: a must be"):
        stl.U(x > 0, x < 1, math.inf, math.inf)
    with pytest.raises(TypeError, match="until: b must be a real number"):
        stl.U(x > 0, x < 1, 0, "1")
    with pytest.raises(ValueError, match="a must be a number, got NaN"):
        stl.G(x > 0, math.nan, 1)
    with pytest.raises(TypeError, match="phi must be a stl formula, got the signal x"):
        stl.G(x, 0, 1)
    with pytest.raises(TypeError, match="implies: psi must be a stl formula"):
        stl.implies(x > 0, 3)
    with pytest.raises(TypeError, match="right operand of & must be a stl formula"):
        (x > 0) & 1
    with pytest.raises(TypeError, match="i must be an int"):
        stl.state(1.0)
    with pytest.raises(TypeError, match="fn must be a callable"):
        stl.signal(3)
    with pytest.raises(TypeError, match="right side of < must be a number or a stl.Signal"):
        _ = x < "a"
    with pytest.raises(TypeError, match="no truth value"):
        _ = 0 < x < 1
    with pytest.raises(TypeError, match="no truth value"):
        bool(x)
    with pytest.raises(ValueError, match="equals: tol must be finite and >= 0"):
        stl.equals(x, 1, tol=-1)
    with pytest.raises(TypeError, match="arc: item 0 is a str"):
        (x > 0)(["no arc"])
    with pytest.raises(TypeError, match="robustness: arc must be a HybridArc"):
        (x > 0)(3.0)
    with pytest.raises(ValueError, match=r"t = 2.0 is outside the arc's time range \[0.0, 1.0\]"):
        (x > 0)(arc, t=2.0)
    with pytest.raises(ValueError, match="refine must be an int >= 1"):
        (x > 0)(arc, refine=0)
    with pytest.raises(ValueError, match="not in the arc's hybrid time domain"):
        (x > 0)(arc, j=3)
    with pytest.raises(IndexError, match=r"stl.state\(4\): the arc's state has 1"):
        (stl.state(4) > 0)(arc)
    with pytest.raises(ValueError, match="the arc is empty"):
        (x > 0)(hs.HybridArc(np.zeros(0), np.zeros(0, int), np.zeros((0, 1)), None))


@pytest.mark.parametrize("name", ["CC4", "CC5", "AT52", "AT6abc"])
def test_the_compiled_window_gives_the_numpy_robustness_to_the_bit(name, monkeypatch):
    """Where numba is installed, windows over long signals are computed by
    ``_stl_window_nb.window_core``: on runs of the ARCH-COMP models (thousands
    of samples, jumps, nested windows, a window from 0 at jump instants) the
    robustness and the instant deciding it are those of the numpy code, to the
    bit, at refine 1 and 4."""
    from hybridsim import _stl_eval
    from hybridsim.arch import REQUIREMENTS, problem
    fast = _stl_eval._compiled_core()
    if fast is None:
        pytest.skip("numba is not installed: the numpy code is the only one")
    req = REQUIREMENTS[name]
    run, sp, _, _ = problem(name, 1)
    rng = np.random.default_rng(5)
    Z = sp.lo + (sp.hi - sp.lo) * rng.random((6, sp.dim))
    Z[:2] = np.where(rng.random((2, sp.dim)) < 0.5, sp.lo, sp.hi)
    arcs = run([sp.point(z) for z in Z])
    assert max(len(a.t) for a in arcs) >= fast.MIN_INSTANTS
    got = {}
    for least in (0, 10 ** 12):             # every window compiled, none
        monkeypatch.setattr(fast, "MIN_INSTANTS", least)
        got[least] = [(float(m), m.where) for refine in (1, 4) for a in arcs
                      for m in [req(a, refine=refine)]]
    assert got[0] == got[10 ** 12]


def test_the_compiled_window_on_infinite_and_flat_values():
    """The compiled window with -inf values (NaN predicates), a constant
    signal and a jump at a window's end: numpy's results."""
    from hybridsim import _stl_eval
    fast = _stl_eval._compiled_core()
    if fast is None:
        pytest.skip("numba is not installed: the numpy code is the only one")
    t = np.concatenate((np.linspace(0.0, 1.0, 200), [1.0], np.linspace(1.0, 3.0, 300)[1:]))
    j = np.concatenate((np.zeros(200, np.int64), np.ones(300, np.int64)))
    for v in (np.sin(7 * t), np.where(t > 2.5, -np.inf, np.cos(3 * t)), np.full(len(t), 2.0)):
        for a, b, lo, hi in ((0.0, 0.5, 0.0, 2.0), (0.1, 0.1, 0.0, 2.5), (0.0, np.inf, 0.0, 3.0),
                             (0.5, 1.0, 0.2, 0.2)):
            args = (t, j, v, v, v, a, b, lo, hi, np.array([1.0]))
            for x, y in zip(fast.window_core(*args), _stl_eval._window_core(*args)):
                np.testing.assert_array_equal(x, y)


class _FakeWindow:
    """A stand-in for the compiled window: ``overloads`` compiled in this
    process, ``index`` the disk cache's entries."""

    MIN_INSTANTS = 256

    def __init__(self, overloads, index):
        cache_file = types.SimpleNamespace(_load_index=lambda: index)
        self.window_sup = types.SimpleNamespace(
            overloads=overloads,
            _cache=types.SimpleNamespace(_cache_file=cache_file, _cache_path="/cache/here"))


@pytest.mark.parametrize("overloads, index, said", [
    ({}, {}, True),                       # neither compiled here nor cached: say so
    ({}, {"key": "entry"}, False),        # in the disk cache: loads in about a second
    ({"sig": "code"}, {}, False),         # compiled in this process already
])
def test_the_compiled_windows_first_compile_is_announced_once(overloads, index, said,
                                                              monkeypatch, capsys):
    """A first STL robustness over a long signal compiles the window (about 10 s
    of CPU): one line on stderr says so, once per process, naming numba's
    cache folder; nothing where the window is compiled or cached already."""
    import logging

    from hybridsim import _stl_eval
    monkeypatch.setattr(_stl_eval, "_COMPILED_SAID", [])
    monkeypatch.setattr(logging.getLogger("hybridsim.compiled"), "hasHandlers", lambda: False)
    fake = _FakeWindow(overloads, index)
    _stl_eval._say_compiling(fake)
    _stl_eval._say_compiling(fake)
    err = capsys.readouterr().err
    if said:
        assert err.count("\n") == 1
        assert "compiling the STL window" in err and "256 instants" in err
        assert "/cache/here" in err and "about 10 s" in err
    else:
        assert err == ""


def test_the_compiled_windows_merge_is_numpys_stable_sort():
    """``_stl_window_nb.stable_order`` (the window's breakpoints and kinks, a
    few sorted runs, merged) is ``np.argsort(kind="stable")``, ties included,
    on random runs of repeated values and on unsorted data."""
    from hybridsim import _stl_eval
    fast = _stl_eval._compiled_core()
    if fast is None:
        pytest.skip("numba is not installed: the numpy code is the only one")
    rng = np.random.default_rng(11)
    for _ in range(200):
        runs = [np.sort(rng.integers(0, 12, rng.integers(0, 25))).astype(float)
                for _ in range(rng.integers(1, 6))]
        x = np.concatenate(runs)
        np.testing.assert_array_equal(fast.stable_order(x), np.argsort(x, kind="stable"))
    x = rng.random(300)
    np.testing.assert_array_equal(fast.stable_order(x), np.argsort(x, kind="stable"))
