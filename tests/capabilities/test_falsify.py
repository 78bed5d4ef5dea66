"""hybridsim.falsification: uncertainty spaces and the counterexample search.

The systems here have closed forms, so every search's answer is known: the
ball's first apex after a bounce is e^2 h0 (restitution e, drop height h0),
the timer's first jump is at its period.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.falsification import (
    Box,
    FalsificationResult,
    Gaps,
    Interval,
    PiecewiseConstant,
    Sinusoids,
    Space,
    batch_run,
    falsify,
)
from hybridsim.library import BouncingBall


class BallE(hs.HybridSystem):
    """The bouncing ball with its restitution as a third, constant state
    (so a population of restitutions is one vectorized batch)."""

    state_dim = 3
    vectorized = True
    g = 9.81

    def flow_map(self, x):
        return np.stack([x[..., 1], np.full(x[..., 0].shape, -self.g),
                         np.zeros(x[..., 0].shape)], axis=-1)

    def jump_map(self, x):
        return np.stack([np.zeros(x[..., 0].shape), -x[..., 2] * x[..., 1], x[..., 2]],
                        axis=-1)

    def flow_set(self, x):
        return x[..., 0] >= 0

    def jump_set(self, x):
        return (x[..., 0] <= 0) & (x[..., 1] <= 0)

    def jump_guard(self, x):
        return -x[..., 0]

    def flow_guard(self, x):
        return x[..., 0]


BALL = Space(h0=Interval(0.9, 1.1), e=Interval(0.7, 0.85))
TOL = 1e-6          # rtol 1e-9 runs: an apex is exact to ~1e-9 of h0


def apex_after_first_bounce(arc):
    """Height of the apex after the first bounce (v = 0 on j = 1), by the
    flow's closed form from the post-jump state."""
    k = int(np.flatnonzero(arc.j == 1)[0])
    h, v = arc.x[k, 0], arc.x[k, 1]
    return h + v * v / (2 * 9.81)


def below(level):
    def claim(arc):
        return level - apex_after_first_bounce(arc)
    return claim


def run_one(p):
    return hs.simulate(BouncingBall(restitution=p["e"]), [p["h0"], 0.0], t_max=3.0, j_max=1,
                       rtol=1e-9, atol=1e-12)


def test_finds_the_corner_counterexample():
    """Apex e^2 h0 <= 0.7 fails only near the corner (1.1, 0.85): 0.795."""
    res = falsify(run_one, BALL, below(0.7), budget=300, seed=1, progress=False)
    assert isinstance(res, FalsificationResult)
    assert res.verdict == "counterexample" and res.margin < 0
    assert res.point["e"] ** 2 * res.point["h0"] > 0.7
    assert res.arc is not None and res.arc.jump_count == 1
    assert res.evaluations <= 300 and len(res.history) == res.evaluations
    assert res.history.min() == res.margin


def test_worst_margin_at_least_as_bad_as_random_and_at_the_sup():
    """With no counterexample (level 0.8 > 0.795), the search's worst margin
    reaches the true infimum 0.8 - 0.85^2 * 1.1 within the integrator's
    tolerance, and is no better than random sampling of the same budget."""
    exact = 0.8 - 0.85 ** 2 * 1.1
    de = falsify(run_one, BALL, below(0.8), budget=250, seed=3, stop=False, progress=False)
    rnd = falsify(run_one, BALL, below(0.8), budget=250, seed=3, method="random",
                  stop=False, progress=False)
    assert de.verdict == rnd.verdict == "none found"
    assert de.margin <= rnd.margin
    assert abs(de.margin - exact) < 1e-4          # NM converges to the corner
    assert de.margin >= exact - TOL               # and no run beats the closed form


def _point_arc(p):
    """An arc whose state is the point's coordinates (a claim on the space itself)."""
    return hs.HybridArc([0.0, 1.0], [0, 0], np.tile(p.z, (2, 1)), hs.Termination.T_MAX)


def test_a_worst_case_on_a_face_with_an_inner_coordinate_is_found():
    """Violated only where z0 = z1 = z2 = 0 (to 1e-3: a face, flat elsewhere) and z3
    is near 0.5 (inside): no vertex is a counterexample, random sampling almost
    never comes close (each of z0, z1, z2 below 1e-3: 1e-9), and steps of the
    compass search see a plateau; moving coordinates to their bounds reaches the
    face, stepping the inner one the counterexample, for every seed."""
    space = Space(z=Box(np.zeros(6), np.ones(6)))

    def claim(arc):
        z = arc.x[0]
        return -0.01 + sum(0.0 if z[i] <= 1e-3 else 0.2 for i in range(3)) \
            + 0.1 * abs(z[3] - 0.5)

    for seed in range(6):
        res = falsify(_point_arc, space, claim, budget=400, seed=seed, progress=False)
        assert res.verdict == "counterexample", seed
        assert np.all(res.point["z"][:3] <= 1e-3)
        assert res.found_by.startswith(("a seeded point on a face", "the compass search",
                                        "differential evolution"))
    rnd = falsify(_point_arc, space, claim, budget=400, seed=0, method="random",
                  progress=False)
    assert rnd.verdict == "none found" and rnd.found_by.startswith("random sampling, run ")


def test_the_constant_bang_bang_member_of_a_sinusoid_class_is_seeded():
    """A Sinusoids class's constant ±bound members (f = 0, phase pi/2: a face of
    its box, not a vertex, where sin(phase) = 0) are among the first runs."""
    s = Sinusoids(0.5, bandwidth=5.0, terms=3, dim=2)
    ext = s.extremes()
    assert ext.shape == (2 * 4, s.size)
    consts = [s.value(z)(1.7).tolist() for z in ext[:4]]
    assert sorted(consts) == [[-0.5, -0.5], [-0.5, 0.5], [0.5, -0.5], [0.5, 0.5]]
    space = Space(m=s)

    def claim(arc):                          # violated where m0 - m1 nears 1: (0.5, -0.5)
        m = space.point(arc.x[0])["m"]
        return 0.9 - max(m(t)[0] - m(t)[1] for t in np.linspace(0.0, 2.0, 9))

    res = falsify(_point_arc, space, claim, budget=200, seed=0, progress=False)
    assert res.verdict == "counterexample" and res.evaluations <= 4
    assert res.found_by.startswith("a seeded extreme member of an entry")


def test_populations_in_one_batch_agree_with_single_runs():
    calls = []

    def x0_of(p):
        return [p["h0"], 0.0, p["e"]]
    run = batch_run(BallE(), x0_of, t_max=3.0, j_max=1, rtol=1e-9, atol=1e-12)

    def counted(points):
        calls.append(len(points))
        return run(points)
    counted.batch = True
    res = falsify(counted, BALL, below(0.8), budget=120, seed=0, stop=False, refine=False,
                  popsize=30, progress=False)
    # the worst run's arc is kept as judged: no run beyond the budget
    assert len(calls) >= 2 and max(calls) == 30 and sum(calls) == res.evaluations
    assert below(0.8)(res.arc) == res.margin
    one = falsify(run_one, BALL, below(0.8), budget=120, seed=0, stop=False, refine=False,
                  popsize=30, progress=False)
    # same seed, same candidates: margins equal to the integrators' accuracy
    assert np.allclose(res.history, one.history, atol=1e-6)


def test_reproducible_with_a_seed():
    a = falsify(run_one, BALL, below(0.7), budget=60, seed=7, stop=False, progress=False)
    b = falsify(run_one, BALL, below(0.7), budget=60, seed=7, stop=False, progress=False)
    assert np.array_equal(a.history, b.history)


def test_failed_runs_are_findings_not_silence():
    """A run that raises, or ends in a blow-up, is recorded with its point and
    cause and counts as a counterexample; the search goes on."""
    space = Space(a=Interval(0.0, 1.5))

    class Growth(hs.HybridSystem):
        state_dim = 1

        def __init__(self, a):
            self.a = a

        def flow_map(self, x):
            return self.a * x

    def run(p):                   # |x(2)| = e^(2a) > 5 for a > 0.80: BLOWUP
        if p["a"] > 1.4:
            raise RuntimeError("model broke")
        return hs.simulate(Growth(p["a"]), [1.0], t_max=2.0, max_norm=5.0, max_step=0.1,
                           warn=False)
    res = falsify(run, space, lambda arc: 1.0, budget=80, seed=0, stop=False,
                  method="random", progress=False)
    causes = {f.cause for f in res.findings}
    assert causes == {"RAISED", "BLOWUP"}
    assert res.verdict == "counterexample" and res.margin == -math.inf
    assert res.evaluations == 80
    raised = next(f for f in res.findings if f.cause == "RAISED")
    assert raised.point["a"] > 1.4 and "model broke" in raised.message
    blown = [f.point["a"] for f in res.findings if f.cause == "BLOWUP"]
    assert min(blown) > math.log(5.0) / 2


def test_seconds_budget_and_stop_at_first():
    res = falsify(run_one, BALL, below(0.0), budget=10_000, seconds=0.5, seed=0,
                  progress=False)
    assert res.verdict == "counterexample" and res.evaluations < 10_000


@pytest.mark.parametrize("make, match", [
    (lambda: Interval(1.0, 0.0), "inverted bounds"),
    (lambda: Box([0.0, 1.0], [1.0, 0.5]), "inverted bounds at index 1"),
    (lambda: Box([], []), "non-empty"),
    (lambda: Space(), "at least one entry"),
    (lambda: Gaps(0.0, 0.1, 3), "Gaps lo must be > 0"),
    (lambda: PiecewiseConstant(-1.0, 1.0, 4), "bound must be >= 0"),
    (lambda: Sinusoids(0.1, 0.0, 2), "bandwidth must be > 0"),
    (lambda: falsify(run_one, BALL, below(0.7), budget=0), "budget must be a positive"),
    (lambda: falsify(run_one, BALL, below(0.7), method="annealing"), "method must be"),
    (lambda: falsify(run_one, BALL, below(0.7), allow=["T_MAX", "DONE"]), "unknown"),
    (lambda: falsify(run_one, BALL, below(0.7), popsize=0), "popsize must be a positive"),
    (lambda: BALL.point([np.nan, 0.8]), "z must be finite"),
    (lambda: BALL.point([1.0]), r"z must have shape \(2,\)"),
])
def test_bad_input_is_named(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_bad_types_are_named():
    with pytest.raises(TypeError, match="Space entry 'x' must be"):
        Space(x=(0.0, 1.0))
    with pytest.raises(TypeError, match="space must be"):
        falsify(run_one, {"e": (0, 1)}, below(0.7))
    with pytest.raises(TypeError, match="claim must return a real number"):
        falsify(run_one, BALL, lambda arc: "fine", budget=5, progress=False)
    with pytest.raises(ValueError, match="claim returned NaN"):
        falsify(run_one, BALL, lambda arc: float("nan"), budget=5, progress=False)


def test_signal_classes_hold_their_bound():
    rng = np.random.default_rng(0)
    for entry in (PiecewiseConstant(0.3, 2.0, pieces=8, dim=2),
                  Sinusoids(0.3, bandwidth=4.0, terms=3, dim=2)):
        space = Space(m=entry)
        for z in space.sample(20, seed=rng):
            m = space.point(z)["m"]
            vals = np.array([m(t) for t in np.linspace(0, 3, 301)])
            assert vals.shape == (301, 2) and np.max(np.abs(vals)) <= 0.3 + 1e-12
    g = Space(gaps=Gaps(0.05, 0.1, 4)).point([0.05, 0.1, 0.07, 0.2])["gaps"]
    assert np.allclose(g, [0.05, 0.1, 0.07, 0.1])                # clipped into [a, b]
    assert np.allclose(Gaps.times(g, 1.0), [1.05, 1.15, 1.22, 1.32])


@pytest.mark.slow
def test_noise_counterexample_through_a_signal_entry():
    """A first-order filter x' = -x + m(t), |m| <= 0.5: |x(2)| <= 0.4 holds
    for constant noise of size below 0.4 / (1 - e^-2) ~ 0.46 only, so the
    worst piecewise-constant noise (m = ±0.5 throughout) breaks it."""
    space = Space(m=PiecewiseConstant(0.5, 2.0, pieces=4))

    class Filter(hs.HybridSystem):
        state_dim = 1

        def __init__(self, m):
            self.m = m

        def flow_map(self, x, t):
            return -x + self.m(t)

    def run(p):
        return hs.simulate(Filter(p["m"]), [0.0], t_max=2.0, rtol=1e-9, atol=1e-12,
                           max_step=0.05)
    res = falsify(run, space, lambda arc: 0.4 - abs(arc.x[-1, 0]), budget=400, seed=2,
                  stop=False, progress=False)
    exact = 0.4 - 0.5 * (1 - math.exp(-2.0))
    assert res.verdict == "counterexample"
    assert abs(res.margin - exact) < 1e-3 and res.margin >= exact - 1e-6


def _x0_ball(p):
    return [p["h0"], 0.0, p["e"]]


@pytest.mark.parametrize("kind", ["process-pool", "dask"])
def test_populations_spread_over_an_executor(kind):
    """A population run with an executor (a process pool; a dask cluster's
    executor) finds what the one-process batch finds: same seed, same
    candidates, margins equal to the integrator's accuracy (1e-6: rtol 1e-9
    runs of the per-row path against the numpy batch)."""
    import concurrent.futures
    kw = dict(budget=60, seed=2, stop=False, refine=False, popsize=20, progress=False)
    local = falsify(batch_run(BallE(), _x0_ball, t_max=3.0, j_max=1, rtol=1e-9, atol=1e-12),
                    BALL, below(0.8), **kw)
    if kind == "process-pool":
        with concurrent.futures.ProcessPoolExecutor(2) as ex:
            spread = falsify(batch_run(BallE(), _x0_ball, t_max=3.0, j_max=1, rtol=1e-9,
                                       atol=1e-12, executor=ex, chunks=2),
                             BALL, below(0.8), **kw)
    else:
        distributed = pytest.importorskip("dask.distributed",
                                          reason="dask is an optional extra (dask)")
        with distributed.Client(processes=False, n_workers=1, threads_per_worker=2,
                                dashboard_address=None) as client:
            spread = falsify(batch_run(BallE(), _x0_ball, t_max=3.0, j_max=1, rtol=1e-9,
                                       atol=1e-12, executor=client.get_executor(), chunks=2),
                             BALL, below(0.8), **kw)
    assert spread.evaluations == local.evaluations
    np.testing.assert_allclose(spread.history, local.history, rtol=0, atol=1e-6)
