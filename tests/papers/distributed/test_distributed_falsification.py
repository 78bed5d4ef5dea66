"""observers.distributed.falsification: paper 003's statements as searches.

Tolerances: the population runs integrate RK45 at rtol 1e-8, atol 1e-10
(settling statements: the 1e-8 crossing agrees with the claim's rtol 1e-10,
atol 1e-14 run to ~3e-3 s, and settling_time reads a stored sample, spaced
< 0.01 s there) and rtol 1e-5, atol 1e-8 (noise: the late error agrees with an
rtol 1e-6 run to ~1e-3 on a level of 2.7). The printed-sign errors grow
like e^(λ t) with λ = printed_sign_growth_rate(); their log-slope is checked
to 1 % (the power term of (9) and the decaying modes bend it by less). The
delayed runs (Python path, history) integrate at rtol 1e-6, atol 1e-9: the
late error agrees with an rtol 1e-8 run to 2e-3 of the level.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import hybridsim as hs
from observers import distributed as dist
from observers.distributed import falsification as F
from observers.distributed.claims import SETTLE_REFERENCE
from observers.distributed.example import EXAMPLE_V0, example_observer, stable_initial_state
from observers.distributed.systems import PopulationErrorSystem, error_system, split_errors
from observers.falsification import run_problem, validate_problems

PROBS = {p.id: p for p in F.PROBLEMS}


def test_problems_are_valid_and_exported():
    assert validate_problems(F.PROBLEMS, paper="003") == F.PROBLEMS
    assert list(PROBS) == ["003-thm1-settle-box", "003-rem2-noise-band-limited",
                           "003-rem2-delay-bounded", "003-rem2-delay-finite-time",
                           "003-sec2-laplacian-printed"]
    assert [p.expect for p in F.PROBLEMS] == ["none", "counterexample", "none",
                                              "counterexample", "counterexample"]
    # the delayed runs are Python-path runs one by one (~0.1-0.5 s): 200 of them; the
    # noise statement is refuted among the first runs, its random baseline runs 200
    short = ("003-rem2-delay-bounded", "003-rem2-noise-band-limited")
    assert all(p.budget >= 2000 for p in F.PROBLEMS if p.id not in short)
    assert all(PROBS[k].budget == 200 for k in short)
    assert dist.PROBLEMS is F.PROBLEMS and F.__all__ == ["PROBLEMS"]


def test_population_error_system_is_the_error_system():
    """Without noise, rows of the batch flow are ErrorSystem's flow (6)-(9)."""
    obs = example_observer()
    pes = PopulationErrorSystem(obs.design)
    E = np.random.default_rng(0).standard_normal((6, 24))
    got = pes.flow_map(E, np.zeros(6))
    want = np.array([obs.error_system().flow_map(e) for e in E])
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13)


def test_noisy_population_run_matches_the_plant_observer_network():
    """The noise enters as in (7) with y^i = C^i x + m_i: the population run of
    the error system equals the errors of the plant-observer network (plant
    (1) and nodes (7)-(8) over hs.network) with the same noise, to the
    integrators' tolerance (rtol 1e-9 both; errors of size ~1, agreement
    1e-6)."""
    obs = example_observer()
    space = PROBS["003-rem2-noise-band-limited"].space
    z = space.sample(1, seed=4)[0]
    point = space.point(z)
    pes = PopulationErrorSystem(obs.design, terms=3, bound=F.NOISE_BOUND)
    x0 = stable_initial_state(obs.design.A, EXAMPLE_V0)
    E0 = F.example_initial_error()
    arc = hs.simulate_many(pes, np.concatenate([E0, point.z])[None, :], 1.0, j_max=0,
                           rtol=1e-9, atol=1e-12, warn=False)[0]
    m = point["noise"]
    np.testing.assert_allclose(pes.noise(arc.x[-1], 1.0), m(1.0), rtol=1e-12, atol=1e-14)
    net = dist.simulate(obs, x0, t_max=1.0, noise=m, rtol=1e-9, atol=1e-12)
    e_net = dist.errors(net, obs).e[-1]
    assert abs(net.t[-1] - arc.t[-1]) < 1e-12
    np.testing.assert_allclose(arc.x[-1, :24], e_net, atol=1e-6)


def test_box_centre_is_the_pinned_settling_time():
    """At the box's centre (the example) the margin is the slack: the claim's
    crossing 6.6555 s read at a stored sample (within 0.02 s)."""
    p = PROBS["003-thm1-settle-box"]
    arc = p.run([p.space.point(F.example_initial_error())])[0]
    m = p.margin(arc)
    assert abs(float(m) - F.SETTLE_SLACK) < 0.02
    assert abs(m.where[0] - SETTLE_REFERENCE) < 0.02


def test_printed_sign_is_refuted_with_the_predicted_growth():
    """003-sec2-laplacian-printed: the search refutes (9) as printed from its
    first population; the worst run grows at the rate of the printed linear
    part's unstable eigenvalue (~19 /s), and the same initial error settles
    with the sign we use (decision 1)."""
    p = PROBS["003-sec2-laplacian-printed"]
    r = run_problem(p, seed=0)
    assert r.found == "counterexample" and r.passed
    lam = F.printed_sign_growth_rate()
    assert 15 < lam < 25
    arc = r.search.arc
    T = SETTLE_REFERENCE + F.SETTLE_SLACK
    v = np.max(np.abs(arc.x[:, :24]), axis=1)
    late = arc.t >= T - 2.0
    slope = np.polyfit(arc.t[late], np.log(v[late]), 1)[0]
    assert abs(slope - lam) < 0.01 * lam
    # the margin in decades: 8 + log10 max|E| after T, E ~ c e^(λ t), |c| ~ |E(0)| ~ 1
    predicted = -(8 + lam * (T + 0.5) / math.log(10))
    assert abs(r.margin - predicted) < 3.0
    assert r.search.where[0] == pytest.approx(T + 0.5, abs=1e-9)
    # the point is in the box, and with L = D - A it is no counterexample
    box = p.space.entries["E0"]
    z = r.search.point["E0"]
    assert np.all(z >= box.lo) and np.all(z <= box.hi)
    ok = PROBS["003-thm1-settle-box"]
    assert float(ok.margin(ok.run([ok.space.point(z)])[0])) > 0


@pytest.mark.slow
def test_thm1_box_survives_the_full_budget():
    """2,000 initial errors: all settle below 1e-8 before 6.6555 + 1.5 s; the
    search's worst slack is no better than random sampling's."""
    r = run_problem(PROBS["003-thm1-settle-box"], seed=0)
    assert r.found == "none" and r.passed
    assert r.search.evaluations == 2000 and r.baseline.evaluations == 2000
    assert 0 < r.search.margin <= r.baseline.margin
    assert r.search.margin < F.SETTLE_SLACK          # some point settles later than the example


@pytest.mark.slow
def test_noise_statement_is_refuted_by_a_constant_bias_inside_its_space():
    """The constant noise 1.193 (-, -, +, -) (a = sign, f = 0, phase pi/2: a point of
    the space as given) gives max|E| = 3.044 over [5, 10] s against the level 2.718;
    the search, seeded with the class's constant +-bound members, finds a bias at
    least as bad among its first runs, and random sampling of the same budget does
    not do better."""
    p = PROBS["003-rem2-noise-band-limited"]
    sign = np.array([-1.0, -1.0, 1.0, -1.0])
    a = np.repeat(sign, F._NOISE_TERMS)
    z = np.concatenate([a, np.zeros_like(a), np.full_like(a, np.pi / 2)])
    pt = p.space.point(z)
    assert np.allclose(pt["noise"](3.7), F.NOISE_BOUND * sign)
    m = float(p.margin(p.run([pt, pt, pt])[0]))
    assert m == pytest.approx(F.NOISE_LEVEL - 3.044, abs=2e-3)
    r = run_problem(p, seed=0)
    assert r.found == "counterexample" == p.expect and r.passed
    assert r.search.margin < -0.3 and r.search.evaluations <= 16
    assert r.search.found_by.startswith("a seeded extreme member")


# ------------------------------------------------------------------ delays --
def test_delayed_flow_is_the_nodes_flow_with_late_estimates():
    """DelayedErrorSystem's flow is, node by node, (7)-(8) with the
    in-neighbours' estimates x^j(t - tau_i) + T^j e^j(t - tau_i) received
    late, minus the plant's flow, in each node's coordinates (2); the last
    six entries are the plant (1). Checked against the nodes' own maps
    (systems._NodeData.rhs) at random states and random pasts."""
    from observers.distributed.systems import _NodeData
    dsg = example_observer().design
    taus = [0.01, 0.1, 0.1, 0.03]
    sysd = F.DelayedErrorSystem(dsg, taus)
    assert sysd.delays == (0.01, 0.03, 0.1) and sysd.max_step == 0.01 and sysd.needs_history
    rng = np.random.default_rng(1)
    t = 0.7
    z = rng.standard_normal(30)
    past = {tau: rng.standard_normal(30) for tau in sysd.delays}
    sysd.history = lambda s: past[min(past, key=lambda tau: abs(t - tau - s))]
    got = sysd.flow_map(z, t)
    E, x = z[:24], z[24:]
    e_o, e_u = split_errors(dsg, E)
    want_o, want_u = [], []
    for k, d in enumerate(dsg.decomp):
        node = _NodeData(dsg, k)
        zk = np.concatenate([e_o[k], e_u[k]]) + d.T.T @ x           # x~^i in node coords
        h = past[taus[k]]
        po, pu = split_errors(dsg, h[:24])
        nb = [dsg.nodelist.index(v) for v in node.neighbours]
        xhat_nb = [h[24:] + dsg.decomp[q].T @ np.concatenate([po[q], pu[q]]) for q in nb]
        de = node.rhs(zk, dsg.C[k] @ x, np.array(xhat_nb)) - d.T.T @ dsg.A @ x
        want_o.append(de[:d.n_o])
        want_u.append(de[d.n_o:])
    want = np.concatenate(want_o + want_u + [dsg.A @ x])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_delayed_system_tends_to_the_error_system():
    """As tau -> 0 the delayed errors tend to (9)'s, at first order: at
    t = 1 s they differ from ErrorSystem's run by ~4 tau (errors of size
    ~1.75), halving with tau."""
    dsg = example_observer().design
    ref = hs.simulate(error_system(dsg), F.example_initial_error(), 1.0, rtol=1e-10,
                      atol=1e-12)
    diffs = []
    for tau in (2e-3, 1e-3):
        arc = F.delayed_run(tau, t_max=1.0, rtol=1e-10, atol=1e-12)
        diffs.append(np.max(np.abs(arc.x[-1, :24] - ref.x[-1])))
        assert diffs[-1] < 5 * tau
    assert diffs[0] / diffs[1] == pytest.approx(2.0, rel=0.05)


def test_the_delayed_system_is_refused_by_name_where_it_cannot_run():
    """Its maps take one state (not batches): simulate_vectorized refuses it by name,
    simulate_many runs its rows one by one, and the compiled path refuses it naming
    the map, its line and the attribute numba cannot type (the groups of rows per
    delay, a list)."""
    sysd = F.DelayedErrorSystem(example_observer().design, 0.05)
    z0 = np.zeros((2, 30))
    with pytest.raises(ValueError, match="vectorized = True"):
        hs.simulate_vectorized(sysd, z0, 1.0)
    with pytest.raises(TypeError, match=r"DelayedErrorSystem\.flow_map \(.*falsification\.py:\d+\)"
                       r": it reads self\.\w+, a \w+ .*numba cannot type it"):
        hs.simulate_many(sysd, z0, 1.0, backend="compiled")
    with pytest.raises(ValueError, match="taus"):
        F.DelayedErrorSystem(example_observer().design, [0.1, 0.0, 0.1, 0.1])
    with pytest.raises(ValueError, match="taus"):
        F.DelayedErrorSystem(example_observer().design, [0.1, 0.1])


def test_delay_level_is_the_recorded_reference():
    """DELAY_REFERENCE is the late error at every tau_i = DELAY_MAX (one run),
    and the problem's tolerances read it to 2e-3 of the level."""
    ref = F.delay_level_reference()
    assert ref == pytest.approx(F.DELAY_REFERENCE, rel=1e-3)
    fine = F.delayed_run(F.DELAY_MAX, rtol=1e-8, atol=1e-10)
    late = fine.t >= SETTLE_REFERENCE + F.SETTLE_SLACK
    assert abs(np.max(np.abs(fine.x[late, :24])) - ref) < 2e-3 * F.DELAY_LEVEL
    p = PROBS["003-rem2-delay-bounded"]
    m = p.margin(F.delayed_run(F.DELAY_MAX))
    assert float(m) == pytest.approx(F.DELAY_LEVEL - ref, rel=1e-9)


@pytest.mark.slow
def test_delays_break_the_finite_time_at_the_first_run():
    """003-rem2-delay-finite-time: the first run is a counterexample (the
    errors follow the plant's decay, 1e-5-1e-3 at T, not 1e-8)."""
    r = run_problem(PROBS["003-rem2-delay-finite-time"], seed=0)
    assert r.found == "counterexample" and r.passed
    assert r.search.evaluations == 1 and r.baseline.evaluations == 1
    assert r.margin < -2.5                      # decades above 1e-8
    assert r.search.arc is not None and r.search.arc.t[-1] == pytest.approx(10.0)


@pytest.mark.slow
def test_delay_bounded_holds_on_a_small_budget():
    """A fiftieth of the budget (4 runs each for the search and the
    baseline, ~3 s): no counterexample; the worst margin is positive."""
    r = run_problem(PROBS["003-rem2-delay-bounded"], seed=0, scale=0.02)
    assert r.found == "none" and r.passed
    assert r.search.evaluations == 4
    assert 0 < r.search.margin <= r.baseline.margin


@pytest.mark.slow
def test_delay_bounded_full_budget():
    """200 delay vectors: none breaks the level; the search reaches the worst
    corner (every tau_i = DELAY_MAX: margin DELAY_LEVEL - DELAY_REFERENCE)."""
    r = run_problem(PROBS["003-rem2-delay-bounded"], seed=0)
    assert r.found == "none" and r.passed
    assert r.search.evaluations == 200
    assert 0 < r.search.margin <= r.baseline.margin
    assert r.search.margin == pytest.approx(F.DELAY_LEVEL - F.DELAY_REFERENCE, rel=0.02)
