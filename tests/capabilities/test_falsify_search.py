"""The searches of hybridsim.falsify on claims whose worst case is known.

The run here is an arc whose state is the point's coordinates, so a claim is
a function of the space itself: its minimum, and where it lies, are known
in closed form.
"""
from __future__ import annotations

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.falsification import Box, ControlPoints, Interval, Space, falsify


def _point_arc(p):
    return hs.HybridArc([0.0, 1.0], [0, 0], np.tile(p.z, (2, 1)), hs.Termination.T_MAX)


BOX = Space(z=Box(-np.ones(8), 2 * np.ones(8)))
CENTRE = np.linspace(-0.6, 1.4, 8)                     # inside the box, off its grid
SCALES = 10.0 ** np.linspace(0, 2, 8)                  # an ellipsoid, condition 100


def ellipsoid(arc):
    """sum s_i (z_i - c_i)^2 - 1e-4: its minimum -1e-4 at the centre c."""
    z = arc.x[0]
    return float(np.sum(SCALES * (z - CENTRE) ** 2)) - 1e-4


def test_cmaes_finds_the_minimum_of_an_ellipsoid_within_its_budget():
    """Negative only within about 1e-2 / sqrt(s_i) of the centre in each
    coordinate (a volume of 1e-17 of the box): CMA-ES reaches it within 1,500
    runs for every seed, random sampling of the same budget does not come
    near, and the search is reproducible with its seed."""
    for seed in range(3):
        res = falsify(_point_arc, BOX, ellipsoid, budget=1500, seed=seed, method="cmaes",
                      progress=False)
        assert res.verdict == "counterexample" and res.margin < 0, seed
        assert res.method == "cmaes" and res.found_by.startswith("CMA-ES, population")
        assert np.all(np.abs(res.point["z"] - CENTRE) < 1e-2 / np.sqrt(SCALES))
    rnd = falsify(_point_arc, BOX, ellipsoid, budget=1500, seed=0, method="random",
                  progress=False)
    assert rnd.verdict == "none found" and rnd.margin > 1.0
    again = falsify(_point_arc, BOX, ellipsoid, budget=1500, seed=0, method="cmaes",
                    progress=False)
    first = falsify(_point_arc, BOX, ellipsoid, budget=1500, seed=0, method="cmaes",
                    progress=False)
    assert np.array_equal(again.history, first.history)


def test_cmaes_converges_to_a_minimum_on_a_face():
    """The centre pushed outside the box in three coordinates: the minimum is
    its projection onto the box, on a face, reached exactly (candidates are
    clipped, and the mean moves past the face: with BLAS kernels of three
    processors, ``OPENBLAS_CORETYPE`` Zen, Haswell and SkylakeX; updated from
    the clipped samples, the mean stopped 1e-8 short of it with two of them)
    and to 1e-5 of the margin within the budget."""
    c = CENTRE.copy()
    c[[0, 3, 6]] = [-3.0, 4.0, 5.0]
    proj = np.clip(c, -1.0, 2.0)
    exact = float(np.sum(SCALES * (proj - c) ** 2))

    def claim(arc):
        return float(np.sum(SCALES * (arc.x[0] - c) ** 2))
    res = falsify(_point_arc, BOX, claim, budget=3000, seed=1, method="cmaes", stop=False,
                  progress=False)
    assert res.verdict == "none found" and res.evaluations == 3000
    assert exact <= res.margin < exact * (1 + 1e-5)
    assert np.array_equal(res.point["z"][[0, 3, 6]], proj[[0, 3, 6]])


def test_cmaes_moves_past_a_face_the_margin_favours():
    """Negative only within 1e-3 of a face of codimension 6 in 12 coordinates,
    the margin the largest of those 6 (a max, as temporal logic's robustness
    is): the distribution, updated from its samples as drawn, moves past the
    face, where most of them land on it. Every seed finds it within 600 runs
    (377-516 on seeds 0-7; updated from the clipped samples, one seed of 8
    found none in 3,000 runs and the others needed 667-2,481)."""
    space = Space(z=Box(np.zeros(12), np.ones(12)))

    def claim(arc):
        z = arc.x[0]
        return float(np.max(z[:6]) + np.sum((z[6:] - 0.4) ** 2) - 1e-3)
    for seed in range(4):
        res = falsify(_point_arc, space, claim, budget=1500, seed=seed, method="cmaes",
                      progress=False)
        assert res.verdict == "counterexample" and res.evaluations <= 600, seed
        z = res.point["z"]
        assert np.all(z[:6] < 1e-3) and np.all(np.abs(z[6:] - 0.4) < 0.04), seed


@pytest.mark.parametrize("method", ["cmaes", "de"])
def test_a_flat_margin_sends_the_budget_to_fresh_designs(method):
    """A margin equal everywhere but in a small region (1.5 % of the box in
    two of its six coordinates, none of it a vertex or a face): a search
    whose populations tie does not stall there, it draws new points; every
    seed finds the region within the budget, few runs at a point run before
    (a vertex of the box seeded again in a restart)."""
    space = Space(z=Box(np.zeros(6), np.ones(6)))
    seen = []

    def claim(arc):
        z = arc.x[0]
        seen.append(z.copy())
        return -1.0 if np.all(np.abs(z[:2] - [0.37, 0.61]) < 0.06) else 1.0
    for seed in range(5):
        seen.clear()
        res = falsify(_point_arc, space, claim, budget=800, seed=seed, method=method,
                      progress=False)
        assert res.verdict == "counterexample", seed
        assert len(seen) == res.evaluations
        assert len(np.unique(np.array(seen), axis=0)) >= 0.9 * len(seen)


@pytest.mark.parametrize("method", ["cmaes", "de"])
def test_a_margin_flat_everywhere_uses_the_whole_budget_spread_over_the_box(method):
    space = Space(z=Box(np.zeros(5), np.ones(5)))
    seen = []

    def claim(arc):
        seen.append(arc.x[0].copy())
        return 1.0
    res = falsify(_point_arc, space, claim, budget=600, seed=2, method=method, stop=False,
                  progress=False)
    assert res.verdict == "none found" and res.evaluations == 600
    assert res.stopped == "budget" and res.method == method
    z = np.array(seen)
    assert len(np.unique(z, axis=0)) >= 0.9 * len(z)        # fresh points, few repeats
    assert np.all(np.mean(z < 0.5, axis=0) > 0.2) and np.all(np.mean(z > 0.5, axis=0) > 0.2)


def test_cmaes_bad_popsize_and_a_fixed_space():
    with pytest.raises(ValueError, match="method must be 'de', 'cmaes' or 'random'"):
        falsify(_point_arc, BOX, ellipsoid, method="cma")
    fixed = Space(z=Box([0.5, 0.5], [0.5, 0.5]))
    res = falsify(_point_arc, fixed, lambda arc: 1.0, budget=50, method="cmaes",
                  progress=False)
    assert res.evaluations == 1 and res.stopped == "converged"


@pytest.mark.parametrize("interp, points, coarse", [("previous", 16, 4), ("linear", 17, 5)])
def test_a_coarse_grid_encodes_signals_of_the_space_itself(interp, points, coarse):
    """Space.coarse(4): a ControlPoints signal on a grid 4 times coarser, the
    other entries as they are; E @ c is in the box, and the space's signal at
    E @ c is the coarse signal at every time (for "linear" the coarse times
    are among the space's, 17 = 4 * 4 + 1 points)."""
    u = ControlPoints([0.0, -1.0], [1.0, 2.0], 16.0, points=points, interpolation=interp)
    space = Space(u=u, k=Interval(3.0, 4.0))
    E, lo, hi = space.coarse(4)
    assert E.shape == (space.dim, 2 * coarse + 1) and lo.size == hi.size == 2 * coarse + 1
    small = Space(u=ControlPoints([0.0, -1.0], [1.0, 2.0], 16.0, points=coarse,
                                  interpolation=interp), k=Interval(3.0, 4.0))
    rng = np.random.default_rng(0)
    for c in lo + (hi - lo) * rng.random((20, lo.size)):
        z = E @ c
        assert np.all(z >= space.lo - 1e-12) and np.all(z <= space.hi + 1e-12)
        fine, ref = space.point(z), small.point(c)
        assert fine["k"] == ref["k"] == c[-1]
        for t in np.linspace(0.0, 20.0, 161):
            np.testing.assert_allclose(fine["u"](t), ref["u"](t), atol=1e-12)
    E1, lo1, _ = Space(k=Interval(3.0, 4.0)).coarse(4)     # no signal: the space itself
    assert E1.tolist() == [[1.0]] and lo1.tolist() == [3.0]
    with pytest.raises(ValueError, match="factor must be >= 1"):
        space.coarse(0.5)


def test_cmaes_finds_a_signal_held_at_its_bounds_over_long_stretches():
    """A step the claim wants: component 0 at least 0.95 on the first 4 of 16
    pieces and at most 0.02 on the other 12, the other component free (a
    face of the box of codimension 16 in 32 coordinates, none of it a
    seeded extreme; the margin the worst of those 16 coordinates). On the
    grid 4 times coarser it is 4 coordinates at their bounds: every seed
    finds it within 200 runs (68-103 on seeds 0-5 with the BLAS kernels of
    three processors; one CMA-ES run over the whole box needs more than
    1,100, measured on seeds 0-5)."""
    space = Space(u=ControlPoints([0.0, 0.0], [1.0, 1.0], 16.0, points=16))

    def step(arc):
        v = arc.x[0].reshape(16, 2)
        return max(0.95 - float(v[:4, 0].min()), float(v[4:, 0].max()) - 0.02)
    for seed in range(4):
        res = falsify(_point_arc, space, step, budget=1500, seed=seed, method="cmaes",
                      progress=False)
        assert res.verdict == "counterexample" and res.evaluations <= 200, seed
        assert "grid 4 times coarser" in res.found_by
        v = res.point["u"].values
        assert np.all(v[:4, 0] >= 0.95) and np.all(v[4:, 0] <= 0.02)


def test_cmaes_finds_a_step_on_linear_control_points_off_the_coarse_knots():
    """The same step on 16 linear control points (15 intervals): no coarse
    grid of the entry's own points (every third, ``Space.coarse(4)``) holds
    it, its kinks between them; the worst point of that grid, snapped to the
    box's bounds, is the step: every seed finds it within 1,000 runs (one
    CMA-ES run over the whole box needs 1,163-1,423, seeds 0-5)."""
    space = Space(u=ControlPoints([0.0, 0.0], [1.0, 1.0], 16.0, points=16,
                                  interpolation="linear"))
    E, lo, _ = space.coarse(4)
    assert lo.size == 12 and np.allclose(E[::2, ::2].sum(axis=1), 1.0)

    def step(arc):
        v = arc.x[0].reshape(16, 2)
        return max(0.95 - float(v[:4, 0].min()), float(v[4:, 0].max()) - 0.02)
    for seed in range(3):
        res = falsify(_point_arc, space, step, budget=1500, seed=seed, method="cmaes",
                      progress=False)
        assert res.verdict == "counterexample" and res.evaluations <= 1000, seed
        v = res.point["u"].values
        assert np.all(v[:4, 0] >= 0.95) and np.all(v[4:, 0] <= 0.02)


def test_a_run_hands_its_distribution_on_to_the_finer_grid():
    """_carried: a covariance along one coordinate of the grid 4 times
    coarser (component 0 of the first of 4 pieces) is, on the space's own
    grid of 16 pieces, an axis along that component's first 4 pieces, the
    longest (1), every other direction a tenth of it; the handoff from the
    grid 4 times coarser to the grid 2 times coarser is the same axis on 2
    of its pieces."""
    from hybridsim._falsify_search import _carried
    space = Space(u=ControlPoints([0.0, 0.0], [1.0, 2.0], 16.0, points=16))
    grids = []
    for factor in (4, 2):
        E, lo, hi = space.coarse(factor)
        grids.append((factor, E, lo, hi - lo, hi > lo))
    own = (1, None, space.lo, space.hi - space.lo, space.hi > space.lo)
    cov = np.zeros((8, 8))
    cov[0, 0] = 0.04
    for fine, pieces in ((own, 4), (grids[1], 2)):
        C = _carried(cov, grids[0], fine)
        w, V = np.linalg.eigh(C)
        axis = np.zeros(len(C))
        axis[0:2 * pieces:2] = 1 / np.sqrt(pieces)
        np.testing.assert_allclose(w[-1], 1 + 0.01)
        np.testing.assert_allclose(w[:-1], 0.01)
        np.testing.assert_allclose(np.abs(V[:, -1]), axis, atol=1e-12)
    assert _carried(np.zeros((8, 8)), grids[0], own) is None
