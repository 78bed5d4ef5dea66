"""observers.distributed.falsification: paper 003's statements as searches.

Tolerances: the population runs integrate RK45 at rtol 1e-8, atol 1e-10
(settling statements: the 1e-8 crossing agrees with the claim's rtol 1e-10,
atol 1e-14 run to ~3e-3 s, and settling_time reads a stored sample, spaced
< 0.01 s there) and rtol 1e-5, atol 1e-8 (noise: the late error agrees with an
rtol 1e-6 run to ~1e-3 on a level of 2.7). The printed-sign errors grow
like e^(λ t) with λ = printed_sign_growth_rate(); their log-slope is checked
to 1 % (the power term of (9) and the decaying modes bend it by less).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import hybridsim as hs
from observers import distributed as dist
from observers.distributed import falsification as F
from observers.distributed.claims import SETTLE_REFERENCE
from observers.falsification import run_problem, validate_problems

PROBS = {p.id: p for p in F.PROBLEMS}


def test_problems_are_valid_and_exported():
    assert validate_problems(F.PROBLEMS, paper="003") == F.PROBLEMS
    assert list(PROBS) == ["003-thm1-settle-box", "003-rem2-noise-band-limited",
                           "003-sec2-laplacian-printed"]
    assert [p.expect for p in F.PROBLEMS] == ["none", "none", "counterexample"]
    assert all(p.budget >= 2000 for p in F.PROBLEMS)
    assert dist.PROBLEMS is F.PROBLEMS and F.__all__ == ["PROBLEMS"]


def test_population_error_system_is_the_error_system():
    """Without noise, rows of the batch flow are ErrorSystem's flow (6)-(9)."""
    obs = dist.example_observer()
    pes = dist.PopulationErrorSystem(obs.design)
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
    obs = dist.example_observer()
    space = PROBS["003-rem2-noise-band-limited"].space
    z = space.sample(1, seed=4)[0]
    point = space.point(z)
    pes = dist.PopulationErrorSystem(obs.design, terms=3, bound=F.NOISE_BOUND)
    x0 = dist.stable_initial_state(obs.design.A, dist.EXAMPLE_V0)
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
def test_noise_statement_full_budget():
    r = run_problem(PROBS["003-rem2-noise-band-limited"], seed=0)
    assert r.found == PROBS["003-rem2-noise-band-limited"].expect and r.passed
    assert r.search.evaluations == 2000
