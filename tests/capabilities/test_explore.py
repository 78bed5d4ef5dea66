"""Every solution of a hybrid inclusion: set-valued jumps, dwell laws in C ∩ D,
hs.explore's tree, checks over every leaf, and its plot.

The systems here flow at constant speed (x' = 1, z' = const): every solver
step integrates them exactly, so the only errors are the event locations
(4 ulp, :func:`hybridsim.rules.event_tolerance`) and their sums over a
handful of jumps; the tolerances below (1e-9) are far above that and far
below the smallest difference between two distinct solutions (0.25).
"""
import itertools
import math
import runpy
import sys
import weakref
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest
from scipy import stats

import hybridsim as hs
from hybridsim import testing as ht

TOL = 1e-9      # see the module docstring
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "explore_thermostat.py"


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def window_timer(T1=1.0, T2=2.0):
    """x' = 1; may reset to 0 anywhere in [T1, T2], must at T2."""
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        flow_set=lambda x: x[0] <= T2, jump_set=lambda x: x[0] >= T1, state_dim=1)


def counter(offsets, period=1.0, rate=0.0):
    """(tau, z): tau' = 1, z' = rate; at tau = period z+ in {z + c : c in offsets}."""
    offs = [float(c) for c in offsets]
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0, rate]), flow_set=lambda x: x[0] <= period,
        jump_set=lambda x: x[0] >= period,
        jump_map_values=lambda x: [np.array([0.0, x[1] + c]) for c in offs], state_dim=2)


# ---------------------------------------------------------------- the data
def test_set_valued_jump_map_simulate_takes_the_first_or_a_seeded_draw():
    sys_ = counter([1.0, 2.0])
    arc = hs.simulate(sys_, [0.0, 0.0], t_max=10.0, j_max=5)
    np.testing.assert_array_equal(arc.x[arc.jump_index, 1], [1, 2, 3, 4, 5])
    a = hs.simulate(sys_, [0.0, 0.0], t_max=10.0, j_max=40, priority="random", seed=3)
    b = hs.simulate(sys_, [0.0, 0.0], t_max=10.0, j_max=40, priority="random", seed=3)
    steps = np.diff(np.concatenate([[0.0], a.x[a.jump_index, 1]]))
    np.testing.assert_array_equal(a.x, b.x)                 # reproducible
    assert set(steps) == {1.0, 2.0}                          # both successors drawn
    assert sys_.set_valued and sys_.jump_map([1.0, 4.0], 0.0, 0, None)[1] == 5.0


def test_set_valued_jump_map_contract():
    bad = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_set=lambda x: x[0] >= 1.0,
        flow_set=lambda x: x[0] <= 1.0,
        jump_map_values=lambda x: [], state_dim=1)
    with pytest.raises(hs.MapError, match=r"jump_map_values must return k >= 1 successors"):
        hs.simulate(bad, [0.0], t_max=3.0)
    with pytest.raises(TypeError, match="jump_map and jump_map_values"):
        hs.HybridSystem.from_functions(jump_map=lambda x: x, jump_map_values=lambda x: [x],
                                       state_dim=1)

    class Both(hs.HybridSystem):
        state_dim = 1

        def jump_map(self, x):
            return x

        def jump_map_values(self, x):
            return [x]
    with pytest.raises(TypeError, match="both jump_map and jump_map_values"):
        hs.simulate(Both(), [0.0], t_max=1.0)


def test_a_set_valued_component_of_an_interconnection_is_refused_by_name():
    both = hs.Interconnection({"counter": counter([1.0, 2.0]), "timer": window_timer()})
    with pytest.raises(ValueError, match="component 'counter' declares jump_map_values"):
        hs.simulate(both, [0.0, 0.0, 0.0], t_max=1.0)
    with pytest.raises(ValueError, match="component 'counter' declares jump_map_values"):
        hs.explore(both, [0.0, 0.0, 0.0], t_max=1.0, j_max=1)


@pytest.mark.parametrize("dwell, priority", [(0.0, "jumps"), (math.inf, "flows")])
def test_a_constant_dwell_is_a_priority(dwell, priority):
    """dwell 0 in C ∩ D is priority "jumps", dwell inf is "flows"."""
    sys_ = window_timer()
    a = hs.simulate(sys_, [0.0], t_max=7.0, priority="random", dwell=lambda rng: dwell)
    b = hs.simulate(sys_, [0.0], t_max=7.0, priority=priority)
    np.testing.assert_allclose(a.jump_times, b.jump_times, rtol=0, atol=TOL)
    assert a.jump_count == (7 if dwell == 0 else 3)


@pytest.mark.slow
def test_dwell_law_passes_kolmogorov_smirnov_at_three_step_sizes():
    """The time spent in C ∩ D = [1, 10] before each reset is the declared law,
    Exp(mean 0.5) (P(> 9) = e^-18: never cut by leaving C), whatever max_step:
    the dwell is drawn once on entry and the jump placed at entry + dwell.
    KS at the 1% level on 300 seeded draws; the draws are the same numbers
    (to TOL) at the three step sizes."""
    law = stats.expon(scale=0.5)
    sys_ = window_timer(1.0, 10.0)
    samples = []
    for max_step in (math.inf, 0.05, 0.007):
        arc = hs.simulate(sys_, [0.0], t_max=math.inf, j_max=300, priority="random",
                          dwell=law, seed=11, max_step=max_step)
        d = np.diff(np.concatenate([[0.0], arc.jump_times])) - 1.0
        assert len(d) == 300
        assert stats.kstest(d, law.cdf).pvalue > 0.01
        samples.append(d)
    np.testing.assert_allclose(samples[1], samples[0], rtol=0, atol=TOL)
    np.testing.assert_allclose(samples[2], samples[0], rtol=0, atol=TOL)


def test_dwell_that_outlasts_C_jumps_where_C_ends_and_one_that_outlasts_D_flows_on():
    t2 = hs.simulate(window_timer(1.0, 2.0), [0.0], t_max=2.5, j_max=1, priority="random",
                     dwell=lambda rng: 5.0)
    assert abs(t2.jump_times[0] - 2.0) <= TOL                # cut short at the end of C
    # D = [1, 1.5] inside C = [0, 3]: a dwell of 5 leaves D and never jumps
    sys_ = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        flow_set=lambda x: x[0] <= 3.0, jump_set=lambda x: 1.0 <= x[0] <= 1.5, state_dim=1)
    arc = hs.simulate(sys_, [0.0], t_max=2.8, priority="random", dwell=lambda rng: 5.0)
    assert arc.jump_count == 0 and arc.termination is hs.Termination.T_MAX


def test_dwell_bad_input_is_named():
    sys_ = window_timer()
    with pytest.raises(ValueError, match="dwell .* priority='random'; got priority='jumps'"):
        hs.simulate(sys_, [0.0], t_max=3.0, dwell=lambda rng: 1.0)
    with pytest.raises(TypeError, match="dwell must be a scipy.stats frozen distribution"):
        hs.simulate(sys_, [0.0], t_max=3.0, priority="random", dwell=0.5)
    with pytest.raises(hs.MapError, match=r"dwell must draw a real number >= 0.*-1"):
        hs.simulate(sys_, [0.0], t_max=3.0, priority="random", dwell=lambda rng: -1.0)
    arc = hs.simulate(sys_, [0.0], t_max=3.0, priority="random", throw=False,
                      dwell=lambda rng: 1 / 0)
    assert arc.termination is hs.Termination.MAP_ERROR and "dwell raised" in arc.message


# ---------------------------------------------------------------- known answers
@pytest.mark.parametrize("J", [1, 2, 3])
def test_timer_window_leaf_count_in_closed_form(J):
    """Window [1, 2] inside C, dwell grid {0.25, 0.5, 0.75}: each reset happens
    at one of m + 2 = 5 ages (jump now, each dwell, at 2 where it must), so J
    resets give 5^J solutions; their reset times are sums of J ages in
    1 + {0, 1/4, ..., 1}, so merged they end at 4J + 1 distinct times."""
    sys_, grid = window_timer(), [0.25, 0.5, 0.75]
    tree = hs.explore(sys_, [0.0], t_max=math.inf, j_max=J, dwell_grid=grid, merge_tol=None)
    assert tree.complete and len(tree) == 5 ** J
    ages = {1.0, 1.25, 1.5, 1.75, 2.0}
    seen = set()
    for arc in tree:
        assert arc.termination is hs.Termination.J_MAX and arc.jump_count == J
        gaps = np.diff(np.concatenate([[0.0], arc.jump_times]))
        assert all(min(abs(g - a) for a in ages) <= TOL for g in gaps)
        seen.add(tuple(np.round(gaps, 6)))
    assert len(seen) == 5 ** J                               # every sequence, once
    merged = hs.explore(sys_, [0.0], t_max=math.inf, j_max=J, dwell_grid=grid)
    assert len(merged) == 4 * J + 1
    ends = sorted(float(a.jump_times[-1]) for a in merged)
    np.testing.assert_allclose(ends, J + 0.25 * np.arange(4 * J + 1), rtol=0, atol=TOL)


@pytest.mark.parametrize("k, J", [(2, 3), (3, 2), (2, 5)])
def test_k_successors_give_k_to_the_J_leaves_and_merge_by_their_sums(k, J):
    """z+ in {z + 1, ..., z + k} at every tau = 1: k^J solutions; the (t, j, z)
    reached after J jumps is (J, J, J + s) with s one of the J(k - 1) + 1
    sums of J numbers in {0, ..., k - 1}: that many merged leaves."""
    sys_ = counter(range(1, k + 1))
    tree = hs.explore(sys_, [0.0, 0.0], t_max=50.0, j_max=J, merge_tol=None)
    assert len(tree) == k ** J and not tree.branch_points == []
    z = sorted(float(a.xf[1]) for a in tree)
    merged = hs.explore(sys_, [0.0, 0.0], t_max=50.0, j_max=J)
    assert len(merged) == J * (k - 1) + 1
    np.testing.assert_allclose(sorted(float(a.xf[1]) for a in merged),
                               J + np.arange(J * (k - 1) + 1), rtol=0, atol=TOL)
    assert sorted(set(z)) == sorted(float(a.xf[1]) for a in merged)
    # every merged branch's prefix is kept for the checks; a "flow on" branch
    # whose flow leaves C at once (tau = 1, located on the guard derived from
    # C) is its sibling's and counts in merges without a prefix of its own
    flow_on = [n for n in merged.nodes if n.end == "merged" and n.merged_into == n.parent]
    assert all(n.choice.kind == "flow" for n in flow_on)
    assert len(merged.merged) == merged.merges - len(flow_on)


@pytest.mark.parametrize("J", [1, 2])
def test_solutions_of_a_merged_tree_are_the_unmerged_trees_leaves(J):
    """Merged, the window timer's tree has 4J + 1 leaves but still 5^J solutions:
    each merged branch continued by the solutions of the branch it met, each whole
    (from x0, through its own prefix, to a leaf's end) and the unmerged tree's leaf
    with its gaps: the same jump times and states."""
    sys_, grid = window_timer(), [0.25, 0.5, 0.75]
    full = hs.explore(sys_, [0.0], t_max=math.inf, j_max=J, dwell_grid=grid, merge_tol=None)
    merged = hs.explore(sys_, [0.0], t_max=math.inf, j_max=J, dwell_grid=grid)
    sols = merged.solutions()
    assert len(merged) == 4 * J + 1 and len(sols) == len(full) == 5 ** J

    def key(arc):
        return tuple(np.round(np.diff(np.concatenate([[0.0], arc.jump_times])), 6))
    by_gaps = {key(a): a for a in full}
    assert sorted(by_gaps) == sorted(key(a) for a in sols)
    for arc in sols:
        ref = by_gaps[key(arc)]
        assert arc.termination is hs.Termination.J_MAX and arc.jump_count == J
        assert arc.t[0] == 0.0 and np.all(np.diff(arc.t) >= 0)
        np.testing.assert_allclose(arc.xf, ref.xf, atol=TOL)
        np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=TOL)
        for jj in range(J):                  # each flow's end, as the unmerged leaf's
            np.testing.assert_allclose(arc.x[arc.j == jj][-1], ref.x[ref.j == jj][-1], atol=TOL)


def test_coinciding_successors_merge():
    """G(z) = {z + 1, z + 1, z + 2}: 3^J branches, J + 1 distinct ends."""
    sys_ = counter([1.0, 1.0, 2.0])
    assert len(hs.explore(sys_, [0.0, 0.0], t_max=50.0, j_max=3, merge_tol=None)) == 27
    assert len(hs.explore(sys_, [0.0, 0.0], t_max=50.0, j_max=3)) == 4


def test_one_dimensional_overlaps_enumerated_by_hand():
    """x' = 1 from 0; C = [0, 5] U [10, inf), D = [1, 2] U [3, 4] U [5, 6],
    g = 10 (then it flows, outside D, to t_max = 8). By hand, a solution jumps
    once: on entering [1, 2] (t = 1), on entering [3, 4] (t = 3), or at 5
    where C ends inside D; with the dwell grid {0.5} also at 1.5 and 3.5.
    It ends at x = 10 + (8 - t_jump). A flow that leaves D (at 2, at 4) does
    not jump there, and at 5 "flow on" is impossible (C ends)."""
    sys_ = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([10.0]),
        flow_set=lambda x: x[0] <= 5.0 or x[0] >= 10.0,
        jump_set=lambda x: 1 <= x[0] <= 2 or 3 <= x[0] <= 4 or 5 <= x[0] <= 6, state_dim=1)
    for grid, jumps in (((), [1.0, 3.0, 5.0]), ((0.5,), [1.0, 1.5, 3.0, 3.5, 5.0])):
        tree = hs.explore(sys_, [0.0], t_max=8.0, j_max=5, dwell_grid=grid, merge_tol=None)
        got = sorted(float(a.jump_times[0]) for a in tree)
        np.testing.assert_allclose(got, jumps, rtol=0, atol=TOL)
        for a in tree:
            assert a.termination is hs.Termination.T_MAX and a.jump_count == 1
            assert abs(a.xf[0] - (18.0 - a.jump_times[0])) <= TOL
        # branch points: the entries at 1 and 3 (at 5 only "jump" is possible)
        np.testing.assert_allclose(sorted(p[0] for p in tree.branch_points), [1.0, 3.0],
                                   rtol=0, atol=TOL)


# ---------------------------------------------------------------- every choice sequence
def _replay(system, x0, t_max, j_max, grid, k):
    """Every solution simulate finds under a deterministic choice sequence:
    each run replays a script (a dwell at each entry into C ∩ D: 0, a grid
    value or inf; a successor index at each jump), its unscripted choices
    taken as the first option, and the alternatives to each are run in turn."""
    dwells = [0.0, *grid, math.inf]
    out, todo = [], [[]]
    while todo:
        prefix = todo.pop()
        taken = []

        def next_choice(options, prefix=prefix, taken=taken):
            i = prefix[len(taken)] if len(taken) < len(prefix) else 0
            taken.append((i, len(options)))
            return options[i]

        class Scripted(hs.HybridSystem):
            state_dim = system.state_dim
            flow_map = staticmethod(system.flow_map)
            flow_set = staticmethod(system.flow_set)
            jump_set = staticmethod(system.jump_set)

            def jump_map(self, x, t, j, u):
                vals = system.jump_map_values(x)
                return np.asarray(vals[next_choice(list(range(len(vals))))])
        arc = hs.simulate(Scripted(), x0, t_max, j_max, priority="random",
                          dwell=lambda rng: next_choice(dwells))
        out.append(arc)
        for pos in range(len(prefix), len(taken)):
            for alt in range(1, taken[pos][1]):
                todo.append([c for c, _ in taken[:pos]] + [alt])
    return out


def _signature(arc):
    k = arc.jump_index
    return np.concatenate([arc.jump_times, arc.x[k].ravel(), [arc.tf], arc.xf])


def _same_sets(a, b):
    sa, sb = [_signature(x) for x in a], [_signature(x) for x in b]

    def covered(xs, ys):
        return all(any(len(x) == len(y) and np.max(np.abs(x - y)) <= TOL for y in ys)
                   for x in xs)
    return covered(sa, sb) and covered(sb, sa)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(6))
def test_leaves_are_the_solutions_of_every_choice_sequence(seed):
    """Seeded random cases: a window [T1, T2] in C for tau, a drift on z, k in
    {1, 2, 3} successors, a dwell grid strictly inside the window, j_max 2-3
    and a horizon cutting some branches. The tree (unmerged) has each
    solution once, and the same solutions (to TOL) as simulate's runs."""
    rng = np.random.default_rng(seed)
    T1 = float(rng.uniform(0.5, 1.0))
    T2 = T1 + float(rng.uniform(0.4, 1.0))
    k = int(rng.integers(1, 4))
    offs = [float(c) for c in rng.uniform(-1.0, 1.0, size=k)]
    rate = float(rng.uniform(-0.5, 0.5))
    grid = sorted(float(g) for g in rng.uniform(0.1, 0.9, size=int(rng.integers(0, 3)))
                  * (T2 - T1))
    j_max = int(rng.integers(2, 4))
    t_max = float(rng.uniform(1.5, 3.5)) * T2

    def G(x):
        return [np.array([0.0, x[1] + c]) for c in offs]
    system = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0, rate]), flow_set=lambda x: x[0] <= T2,
        jump_set=lambda x: x[0] >= T1, jump_map_values=G, state_dim=2)
    tree = hs.explore(system, [0.0, 0.0], t_max, j_max, dwell_grid=grid, merge_tol=None)
    runs = _replay(system, np.array([0.0, 0.0]), t_max, j_max, grid, k)
    assert tree.complete and _same_sets(tree.leaves, runs)
    sigs = [_signature(a) for a in tree]
    for i in range(len(sigs)):              # no solution twice
        for m in range(i):
            assert len(sigs[i]) != len(sigs[m]) or np.max(np.abs(sigs[i] - sigs[m])) > TOL


# ---------------------------------------------------------------- the tree
def test_j_max_zero_stops_where_a_jump_would_be_taken():
    """simulate(j_max=0) ends at the first jump it would take (J_MAX, no jump);
    at an entry into C ∩ D it may also flow on. So explore: the window timer
    from 0 with t_max 2.5 ends at t = 1 (jump now), 1.5 (dwell) or 2 (flow on,
    where C ends); no leaf has a jump."""
    tree = hs.explore(window_timer(), [0.0], t_max=2.5, j_max=0, dwell_grid=[0.5])
    ends = sorted(float(a.tf) for a in tree)
    np.testing.assert_allclose(ends, [1.0, 1.5, 2.0], rtol=0, atol=TOL)
    for a in tree:
        assert a.termination is hs.Termination.J_MAX and a.jump_count == 0
        a.validate()
    sims = {round(float(hs.simulate(window_timer(), [0.0], 2.5, 0, priority=p).tf), 9)
            for p in ("jumps", "flows")}
    assert sims == {1.0, 2.0}


def test_inputs_reach_every_branch():
    """u(t) = t read by the jump map (x+ = u / 4): a reset at time s lands on
    s / 4 on every branch (the successors are computed with the input too)."""
    sys_ = hs.HybridSystem.from_functions(
        flow_map=lambda x, t, j, u: np.array([1.0]),
        jump_map=lambda x, t, j, u: np.array([u[0] / 4]),
        flow_set=lambda x: x[0] <= 2.0, jump_set=lambda x: x[0] >= 1.0, state_dim=1, input_dim=1)
    tree = hs.explore(sys_, [0.0], t_max=2.5, j_max=1, dwell_grid=[0.5],
                      inputs=lambda t: np.array([t]))
    assert sorted(round(float(a.jump_times[0]), 9) for a in tree) == [1.0, 1.5, 2.0]
    for a in tree:
        assert abs(a.x[a.jump_index[0], 0] - a.jump_times[0] / 4) <= TOL


def test_tree_structure_and_choices():
    tree = hs.explore(window_timer(), [0.0], t_max=10.0, j_max=2, dwell_grid=[0.5],
                      merge_tol=None)
    root = tree.nodes[0]
    assert root.parent is None and root.choice is None and root.end == "branch"
    kinds = [tree.nodes[c].choice.kind for c in root.children]
    assert kinds == ["jump", "flow", "dwell"]
    for leaf in tree.leaf_nodes:
        path = tree.path(leaf.index)
        assert path[0] is root and path[-1] is leaf
        for a, b in itertools.pairwise(path):
            assert b.parent == a.index and b.index in a.children
    # a leaf's arc: from x0, its choices those of its path, valid samples
    arc = tree.leaves[-1]
    assert arc.t[0] == 0.0 and len(arc.choices) >= 2
    arc.validate()
    assert str(arc.choices[0]).startswith(("jump to successor 0", "flow on", "dwell 0.5"))


def test_budgets_end_the_exploration_with_a_cause():
    sys_ = counter([1.0, 2.0])
    with pytest.warns(hs.SimulationWarning, match="MAX_BRANCHES"):
        tree = hs.explore(sys_, [0.0, 0.0], t_max=50.0, j_max=10, max_branches=7,
                          merge_tol=None)
    assert tree.end is hs.ExploreEnd.MAX_BRANCHES and not tree.complete
    assert tree.pending > 0 and "max_branches" in tree.message
    with pytest.warns(hs.SimulationWarning, match="MAX_SECONDS"):
        tree = hs.explore(sys_, [0.0, 0.0], t_max=50.0, j_max=10, max_seconds=1e-9)
    assert tree.end is hs.ExploreEnd.MAX_SECONDS
    with pytest.raises(ValueError, match="incomplete"):
        ht.assert_bounded(tree, lambda x, t, j: x[1], 100.0)


def test_explore_bad_input_is_named():
    sys_ = window_timer()
    with pytest.raises(TypeError, match="priority=: explore follows every choice"):
        hs.explore(sys_, [0.0], 3.0, 2, priority="jumps")
    with pytest.raises(ValueError, match="dwell_grid must be a sequence of positive"):
        hs.explore(sys_, [0.0], 3.0, 2, dwell_grid=[0.5, -1.0])
    with pytest.raises(ValueError, match="merge_tol must be >= 0"):
        hs.explore(sys_, [0.0], 3.0, 2, merge_tol=-1.0)
    with pytest.raises(TypeError, match="system must be a hybridsim.HybridSystem"):
        hs.explore(object(), [0.0], 3.0, 2)
    delayed = hs.HybridSystem.from_functions(flow_map=lambda x: -x, state_dim=1,
                                             needs_history=True)
    with pytest.raises(ValueError, match="merge_tol must be None .* reads its history"):
        hs.explore(delayed, [1.0], 1.0, 1, merge_tol=1e-9)


def test_a_failing_map_names_the_branch():
    def g(x, t):
        if t > 1.5:
            raise RuntimeError("broken reset")
        return np.array([0.0])
    sys_ = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=g, flow_set=lambda x: x[0] <= 2.0,
        jump_set=lambda x: x[0] >= 1.0, state_dim=1)
    with pytest.raises(hs.MapError, match=r"broken reset.*on the branch: flow on at"):
        hs.explore(sys_, [0.0], 5.0, 1)
    tree = hs.explore(sys_, [0.0], 5.0, 1, throw=False)
    causes = sorted(a.termination.name for a in tree)
    assert causes == ["J_MAX", "MAP_ERROR"]


# ---------------------------------------------------------------- checks over every leaf
def test_testing_helpers_report_the_first_violating_leaf_with_its_choices():
    tree = hs.explore(window_timer(), [0.0], t_max=6.0, j_max=2, dwell_grid=[0.5])
    ht.assert_bounded(tree, lambda x, t, j: x[0], 2.0, atol=TOL)      # x <= T2 always
    with pytest.raises(AssertionError, match=r"solution \d+ of \d+ \(.*(flow on|dwell 0.5)"):
        ht.assert_bounded(tree, lambda x, t, j: x[0], 1.6)
    m = ht.margin_bounded(tree, lambda x, t, j: x[0], 1.6)
    assert float(m) == pytest.approx(-0.4, abs=TOL) and not m.holds
    assert any(c.kind == "flow" for c in m.choices) and "solution" in m.what
    # an iterable of arcs serves too; signals must be callables there
    ht.assert_bounded(list(tree), lambda x, t, j: x[0], 2.0, atol=TOL)
    with pytest.raises(TypeError, match="signal must be a callable"):
        ht.assert_bounded(list(tree), tree.leaves[0].x, 2.0)


def test_checks_cover_the_prefixes_of_merged_branches():
    """Merged, the timer's solutions that first reset at 1.5 (after a dwell of
    0.5) all meet others later (at (3, 2, 0), (2.5, 2, 0)...): no leaf resets
    at 1.5, but the merged branches' prefixes do, and they are checked."""
    tree = hs.explore(window_timer(), [0.0], t_max=10.0, j_max=2, dwell_grid=[0.5])
    assert not any(abs(a.jump_times[0] - 1.5) <= TOL for a in tree)

    def mark(x, t, j):          # 1 on the sample just after a reset at 1.5
        return 1.0 if (j == 1 and abs(t - 1.5) <= TOL) else 0.0
    ht.assert_bounded(list(tree), mark, 0.5)                 # the leaves alone miss it
    with pytest.raises(AssertionError, match=r"dwell 0.5 .*merges into branch"):
        ht.assert_bounded(tree, mark, 0.5)


def test_a_check_with_no_sample_in_range_on_any_solution_is_an_error():
    tree = hs.explore(window_timer(), [0.0], t_max=3.0, j_max=1)
    with pytest.raises(AssertionError, match="no solution of the .* has a sample"):
        ht.assert_bounded(tree, lambda x, t, j: x[0], 2.0, t=(50.0, 60.0))
    with pytest.raises(ValueError, match="no solution of the .* has a sample"):
        ht.margin_bounded(tree, lambda x, t, j: x[0], 2.0, j=7)


def test_jittery_sampling_every_gap_sequence_contracts():
    """The guide's example (docs/guide/explore.rst): x' = x + u, u = -2 x held
    between samples whose gaps h are 0.1, 0.2 or 0.3. Between samples x(s) = (2 - e^s) x_k, so every
    solution satisfies |x(t, j)| <= (2 - e^0.1)^j |x0| (the worst contraction
    per sample). 3^5 gap sequences; the state after j samples is the product
    of the factors (order-free), so merged the tree ends at the C(7, 2) = 21
    multisets of five gaps."""
    jittery = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[0] + x[1], 0.0, 1.0]),
        jump_map=lambda x: np.array([x[0], -2.0 * x[0], 0.0]),
        flow_set=lambda x: x[2] <= 0.3, jump_set=lambda x: x[2] >= 0.1, state_dim=3)
    tree = hs.explore(jittery, [1.0, -2.0, 0.0], t_max=2.0, j_max=5, dwell_grid=[0.1])
    assert len(tree) == 21 and tree.complete
    # rtol 1e-6: the solver's (rtol 1e-6) error on x, relative to the bound
    ht.assert_bounded(tree, lambda x, t, j: x[0], lambda t, j: (2 - np.exp(0.1)) ** j,
                      rtol=1e-6)
    with pytest.raises(AssertionError, match="bound violated"):
        ht.assert_bounded(tree, lambda x, t, j: x[0], lambda t, j: (2 - np.exp(0.2)) ** j)
    assert len(hs.explore(jittery, [1.0, -2.0, 0.0], t_max=2.0, j_max=5, dwell_grid=[0.1],
                          merge_tol=None)) == 3 ** 5


# ---------------------------------------------------------------- plot
@pytest.mark.parametrize("view", ["flows", "jumps", "domain"])
def test_plot_solutions_draws_every_leaf_and_marks_branch_points(view):
    tree = hs.explore(window_timer(), [0.0], t_max=5.0, j_max=2, dwell_grid=[0.5],
                      merge_tol=None)
    ax = hs.plot_solutions(tree, view=view)
    flows = [ln for ln in ax.lines if ln.get_gid() == "flows"]
    assert len(flows) == len(tree) == 9
    assert len({ln.get_color() for ln in flows}) == 1
    (bp,) = [ln for ln in ax.lines if ln.get_gid() == "branch_points"]
    assert len(bp.get_xdata()) == len(tree.branch_points) and bp.get_marker() == "D"
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert texts == ["9 solutions", "branch points"]
    assert ax.get_xlabel() == ("$j$" if view == "jumps" else "$t$")
    if view == "domain":
        np.testing.assert_array_equal(np.asarray(bp.get_ydata()),
                                      [p[1] for p in tree.branch_points])
    with pytest.raises(ValueError, match="view must be one of"):
        hs.plot_solutions(tree, view="phase")


def _on_a_curve(ax, x, y):
    """Whether (x, y) is a point of one of the Axes' flow lines (to 1e-12)."""
    for ln in ax.lines:
        if ln.get_gid() == "flows":
            xs, ys = np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float)
            if np.any((np.abs(xs - x) <= 1e-12) & (np.abs(ys - y) <= 1e-12)):
                return True
    return False


@pytest.mark.parametrize("view", ["flows", "jumps"])
@pytest.mark.parametrize("fn", [None, "square"])
def test_plot_solutions_labels_and_puts_branch_points_on_the_curves(view, fn):
    tree = hs.explore(window_timer(), [0.0], t_max=5.0, j_max=2, dwell_grid=[0.5],
                      merge_tol=None)

    def square(x):
        return x[0] ** 2

    ax = hs.plot_solutions(tree, view=view, fn=square if fn else None)
    # the value axis names what is drawn, never matplotlib's "_nolegend_"
    assert ax.get_ylabel() == ("square" if fn else "$x_1$")
    (bp,) = [ln for ln in ax.lines if ln.get_gid() == "branch_points"]
    xs, ys = np.asarray(bp.get_xdata(), float), np.asarray(bp.get_ydata(), float)
    assert len(xs) == len(tree.branch_points) > 0
    for (t, j, x), bx, by in zip(tree.branch_points, xs, ys):
        assert bx == (t if view == "flows" else j)
        assert by == (x[0] ** 2 if fn else x[0])
        assert _on_a_curve(ax, bx, by), (bx, by)
    # the flow lines themselves are fn's values where fn is given
    flows = [ln for ln in ax.lines if ln.get_gid() == "flows"]
    if fn and view == "flows":
        leaf = next(iter(tree))
        y = np.asarray(flows[0].get_ydata(), float)
        assert np.nanmax(y) == pytest.approx(np.max(leaf.x[:, 0] ** 2), abs=1e-12)
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert texts == ["9 solutions", "branch points"]
    ax = hs.plot_solutions(tree, view=view, ylabel="timer")
    assert ax.get_ylabel() == "timer"


def test_plot_solutions_refuses_what_it_cannot_draw():
    tree = hs.explore(window_timer(), [0.0], t_max=3.0, j_max=1, merge_tol=None)
    with pytest.raises(TypeError, match="fn= applies to the views"):
        hs.plot_solutions(tree, view="domain", fn=lambda x: x[0])
    with pytest.raises(TypeError, match="fn must be a callable"):
        hs.plot_solutions(tree, fn=3.0)
    with pytest.raises(TypeError, match="idx must be an int"):
        hs.plot_solutions(tree, idx=[0])
    with pytest.raises(ValueError, match="idx"):
        hs.plot_solutions(tree, idx=1, fn=lambda x: x[0])
    with pytest.raises(TypeError, match="ylabel must be a str"):
        hs.plot_solutions(tree, ylabel=1)


# ---------------------------------------------------------------- the example
def test_explore_thermostat_example(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", [str(EXAMPLE), str(tmp_path)])
    ns = runpy.run_path(str(EXAMPLE), run_name="__main__")
    tree = ns["TREE"]
    assert tree.complete and len(tree) > 1
    assert (tmp_path / "explore_thermostat.png").stat().st_size > 5000
    lo, hi = ns["Z_LOW"], ns["Z_HIGH"]
    # every solution stays in the band once inside it (the claim of the example)
    ht.assert_bounded(tree, lambda x, t, j: abs(x[0] - (lo + hi) / 2), (hi - lo) / 2,
                      atol=1e-6, t=ns["T_IN"])
    assert "solutions" in capsys.readouterr().out


@pytest.mark.slow
def test_explore_jittery_sampling_example(tmp_path, monkeypatch, capsys):
    """The gallery's jittery sampling: 3^5 gap sequences merged at their distinct ends
    (the loop is linear and time-invariant: the gaps' order does not change the end),
    the contraction on every solution, a random run of the dwell law, and the figure's
    artists: the leaves, the branch points, the random run and the bound."""
    script = EXAMPLE.parent / "explore_jittery_sampling.py"
    monkeypatch.setattr(sys, "argv", [str(script), str(tmp_path)])
    monkeypatch.setattr(plt, "close", lambda *a: None)        # keep the figure to read it
    ns = runpy.run_path(str(script), run_name="__main__")
    tree, rnd = ns["TREE"], ns["RANDOM"]
    assert tree.complete and len(tree) == 21
    ends = {tuple(np.round(np.diff(np.r_[0.0, a.jump_times]), 6)) for a in tree}
    assert all(set(g) <= {0.1, 0.2, 0.3} for g in ends)
    ht.assert_bounded(tree, lambda x, t, j: x[0], lambda t, j: ns["RATE"] ** j, rtol=1e-6)
    gaps = np.diff(np.r_[0.0, rnd.jump_times])
    assert np.all((gaps >= 0.1 - 1e-9) & (gaps <= 0.3 + 1e-9)) and np.ptp(gaps) > 0.01
    assert (tmp_path / "explore_jittery_sampling.png").stat().st_size > 5000
    fig = plt.gcf()
    ax, bx = fig.axes
    labels = [ln.get_label() for ln in ax.get_lines()]
    assert "21 solutions" in labels and "a random solution (dwell law)" in labels
    assert any(ln.get_gid() == "branch_points" for ln in bx.get_lines())
    bound = [ln for ln in bx.get_lines() if ln.get_label().startswith("bound")]
    assert len(bound) == 1 and bound[0].get_linestyle() == "--"
    np.testing.assert_allclose(bound[0].get_ydata(), ns["RATE"] ** np.arange(6))
    assert ax.get_xlabel() == "$t$" and bx.get_xlabel() == "$j$"
    assert "every solution" in capsys.readouterr().out
    plt.close("all")


# ---------------------------------------------------------------- systems with a past
class _DelayedSampler(hs.HybridSystem):
    """x' = -a x(t - tau) + b, a sample (x+ = c x) at a gap in [lo, hi] after the last
    (a timer s); ``instants``: jump at those times instead (the deterministic replay)."""

    state_dim, needs_history = 2, True

    def __init__(self, a, b, c, tau, lo, hi, instants=None):
        self.a, self.b, self.c, self.tau = a, b, c, tau
        self.lo, self.hi, self.instants = lo, hi, instants
        self.delays, self.max_step = (tau,), tau

    def flow_map(self, x, t, j, u):
        return np.array([-self.a * self.history(t - self.tau)[0] + self.b, 1.0])

    def flow_guard(self, x, t, j, u):
        if self.instants is not None:
            return 1.0
        return self.hi - x[1]

    def jump_guard(self, x, t, j, u):
        if self.instants is not None:
            return t - self.instants[j] if j < len(self.instants) else -1.0
        return x[1] - self.lo

    def jump_map(self, x, t, j, u):
        return np.array([self.c * x[0], 0.0])


@pytest.mark.parametrize("seed", range(3))
def test_a_system_with_delays_branches_with_its_past(seed):
    """Seeded random delay systems with jittery samples: every leaf equals the
    run of simulate that samples at the leaf's jump times (its past read
    across the branch points the same way), to the integrators' 1e-8."""
    rng = np.random.default_rng(seed)
    a, b, c = rng.uniform(0.5, 2.0), rng.uniform(-1, 1), rng.uniform(-0.9, 0.9)
    tau = float(rng.uniform(0.15, 0.4))
    lo = float(rng.uniform(0.1, 0.2))
    hi = lo + float(rng.uniform(0.1, 0.2))
    grid = [0.5 * (hi - lo)]
    system = _DelayedSampler(a, b, c, tau, lo, hi)
    opts = dict(rtol=1e-11, atol=1e-13)
    tree = hs.explore(system, [1.0, 0.0], t_max=5.0, j_max=3, dwell_grid=grid, **opts)
    assert tree.complete and len(tree) == 3 ** 3
    # never merged across solutions (equal states, different pasts)
    assert all(n.merged_into in (None, n.parent) for n in tree.nodes)
    pre = lambda s: np.array([1.0, 0.0])                            # noqa: E731
    for leaf in tree.leaves[::4]:
        replay = _DelayedSampler(a, b, c, tau, lo, hi, instants=leaf.jump_times)
        arc = hs.simulate(replay, [1.0, 0.0], 5.0, 3, prehistory=pre, **opts)
        np.testing.assert_allclose(arc.jump_times, leaf.jump_times, atol=1e-9)
        np.testing.assert_allclose(arc.x[-1, 0], leaf.x[-1, 0], atol=1e-8)
        # the leaf keeps its runs' dense output: x(s) read between samples
        s = 0.5 * (leaf.jump_times[0] + leaf.jump_times[1])
        np.testing.assert_allclose(leaf.at(s)[0], arc.at(s)[0], atol=1e-8)


def test_a_past_is_continued_not_restarted():
    """x' = -x(t - 1) from a constant past 1: the tree's one branch point sits at
    t = 0.5, before the delay; the branch that flows on must read x(s) for s
    in [0.5, 1.5] from its parent's run, not from a constant prehistory."""
    system = _DelayedSampler(1.0, 0.0, 1.0, 1.0, 0.5, 3.0)
    tree = hs.explore(system, [1.0, 0.0], t_max=2.0, j_max=1, rtol=1e-11, atol=1e-13)
    flows = [a for a in tree if a.choices[0].kind == "flow"]
    assert len(flows) == 1
    # exact solution of x' = -x(t - 1), x = 1 before 0: 1 - t on [0, 1],
    # 1 - t + (t - 1)^2 / 2 on [1, 2] (the jump x+ = x changes nothing)
    t = 2.0
    np.testing.assert_allclose(flows[0].x[-1, 0], 1 - t + (t - 1) ** 2 / 2, atol=1e-9)


@pytest.mark.slow
def test_a_past_read_across_a_thousand_branch_points():
    """A forced reset every 0.01 (each jump a new branch of the tree) and a delay of
    11: x(t - 11) is read back through ~1,100 parents' pasts, a chain deeper than
    Python's recursion limit, and is the exact x(s) = 1 + s for the flow x' = 1
    with x(s) = 1 + s before 0 (the resets only touch the timer)."""
    class Deep(hs.HybridSystem):
        state_dim, needs_history, delays, max_step = 3, True, (11.0,), 11.0

        def flow_map(self, x, t, j, u):
            return np.array([1.0, 1.0, self.history(t - 11.0)[0]])

        def flow_guard(self, x, t, j, u):
            return 0.01 - x[1]

        def jump_guard(self, x, t, j, u):
            return x[1] - 0.01

        def jump_map(self, x, t, j, u):
            return np.array([x[0], 0.0, x[2]])

    t_end = 11.05
    tree = hs.explore(Deep(), [1.0, 0.0, 0.0], t_max=t_end, j_max=2000, atol=1e-12,
                      rtol=1e-12, prehistory=lambda s: np.array([1.0 + s, 0.0, 0.0]))
    (leaf,) = tree.leaves
    assert len(leaf.jump_times) > 1000
    # x2' = x0(t - 11) = t - 10, x2(0) = 0: x2(t) = t^2 / 2 - 10 t
    np.testing.assert_allclose(leaf.x[-1, 2], t_end ** 2 / 2 - 10 * t_end, atol=1e-8)


@pytest.mark.slow
def test_an_integral_of_the_past_is_read_across_branch_points():
    """x0' = 1 - int_{t-1.5}^{t-0.5} x0(s) cos s ds with a prehistory sin s and a forced
    reset of a timer every 0.1: the window reaches back over up to 15 branch points
    and into the root's prehistory; the tree's one solution is simulate's, to 1e-7
    (rtol 1e-10; Gauss-Legendre on differently cut pieces)."""
    class Window(hs.HybridSystem):
        state_dim, needs_history, delays, max_step = 2, True, (0.5, 1.5), 0.5

        def flow_map(self, x, t, j, u):
            w = self.history.integral(lambda x, s: x[0] * np.cos(s), t - 1.5, t - 0.5)
            return np.array([1.0 - w, 1.0])

        def flow_guard(self, x, t, j, u):
            return 0.1 - x[1]

        def jump_guard(self, x, t, j, u):
            return x[1] - 0.1

        def jump_map(self, x, t, j, u):
            return np.array([x[0], 0.0])

    kw = dict(rtol=1e-10, atol=1e-12, prehistory=lambda s: np.array([np.sin(s), 0.0]))
    tree = hs.explore(Window(), [0.0, 0.0], t_max=2.5, j_max=100, **kw)
    arc = hs.simulate(Window(), [0.0, 0.0], 2.5, 100, **kw)
    (leaf,) = tree.leaves
    np.testing.assert_allclose(leaf.jump_times, arc.jump_times, atol=1e-9)
    np.testing.assert_allclose(leaf.x[-1], arc.x[-1], atol=1e-7)


# ---------------------------------------------------------------- levels as compiled batches
class Doubling(hs.HybridSystem):
    """The benchmark's tree (issue 42): x+ in {2x, 2x + 1} every ``period``."""

    state_dim = 2

    def __init__(self, period=0.1):
        self.period = period

    def flow_map(self, x):
        return np.array([0.0, 1.0])

    def jump_map_values(self, x):
        return [np.array([2.0 * x[0], 0.0]), np.array([2.0 * x[0] + 1.0, 0.0])]

    def flow_set(self, x):
        return x[1] <= self.period

    def jump_set(self, x):
        return x[1] >= self.period


class Window(hs.HybridSystem):
    """(tau, z): tau' = 1, z' = rate; may reset in [T1, T2], must at T2, z+ in
    {z + c : c in offs} (a choice at every entry into C ∩ D); ``fail_after``:
    the jump map raises after that time."""

    state_dim = 2

    def __init__(self, T1=1.0, T2=2.0, rate=0.5, offs=(1.0, -0.5), fail_after=np.inf):
        self.T1, self.T2, self.rate, self.offs = T1, T2, rate, offs
        self.fail_after = fail_after

    def flow_map(self, x):
        return np.array([1.0, self.rate])

    def jump_map_values(self, x, t):
        if t > self.fail_after:
            raise RuntimeError("broken reset")
        return [np.array([0.0, x[1] + c]) for c in self.offs]

    def flow_set(self, x):
        return x[0] <= self.T2

    def jump_set(self, x):
        return x[0] >= self.T1


def _shape(tree):
    return [(n.parent, None if n.choice is None else (n.choice.kind, n.choice.value), n.end,
             n.merged_into, n.children) for n in tree.nodes]


@pytest.fixture
def batches(monkeypatch):
    """Counts the compiled batches explore runs and the branches it runs alone."""
    pytest.importorskip("numba")
    import hybridsim.compiled as hc
    from hybridsim.explore import _Explorer
    seen = {"batches": 0, "rows": 0, "alone": 0}
    batch, alone = hc.simulate_many_compiled, _Explorer._simulate

    def counted_batch(cs, X, *a, **k):
        seen["batches"] += 1
        seen["rows"] += len(X)
        return batch(cs, X, *a, **k)

    def counted_alone(self, *a, **k):
        seen["alone"] += 1
        return alone(self, *a, **k)
    monkeypatch.setattr(hc, "simulate_many_compiled", counted_batch)
    monkeypatch.setattr(_Explorer, "_simulate", counted_alone)
    # no class has run batched yet (auto's choice from the first level)
    monkeypatch.setattr(sys.modules["hybridsim.explore"], "_BATCHED", weakref.WeakSet())
    return seen


@pytest.mark.parametrize("case", ["doubling", "window", "window merged"])
def test_levels_run_as_compiled_batches_give_the_tree_of_single_runs(case, batches):
    """backend="compiled" runs each level's branches as compiled batches
    restarted at their branch points: the same nodes, ends, merges and
    choices as backend="python" (every branch its own run of simulate), and
    the same leaves to round-off. On the doubling tree every branch runs in
    a batch; on the window, the dwells and the "flow on" branches that flow
    run alone (with their dwell law), the others in batches."""
    if case == "doubling":
        system, x0, kw = Doubling(), [0.0, 0.0], dict(t_max=0.65, j_max=6, merge_tol=None)
    else:
        system, x0 = Window(), [0.0, 0.0]
        kw = dict(t_max=5.0, j_max=3, dwell_grid=[0.5],
                  merge_tol=None if case == "window" else 1e-9)
    python = hs.explore(system, x0, backend="python", **kw)
    assert batches["batches"] == 0
    alone = batches["alone"]
    compiled = hs.explore(system, x0, backend="compiled", **kw)
    assert batches["batches"] >= kw["j_max"] and batches["rows"] > 0
    assert _shape(compiled) == _shape(python) and compiled.merges == python.merges
    assert compiled.complete and len(compiled) == len(python)
    if case == "doubling":
        # every branch that runs (the last jump's leaves do not: j_max) in a batch
        assert batches["alone"] == alone and batches["rows"] == alone == 63
        assert sorted(a.xf[0] for a in compiled) == list(range(64))
    else:
        assert 0 < batches["alone"] - alone < alone
    for a, b in zip(compiled, python, strict=True):
        assert a.termination is b.termination and list(map(str, a.choices)) == \
            list(map(str, b.choices))
        np.testing.assert_array_equal(a.j, b.j)
        np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
        a.validate()


def test_auto_batches_levels_from_batch_level_branches(batches, monkeypatch):
    """backend="auto" (the default) runs a small tree branch by branch, and
    compiled batches from the first level of BATCH_LEVEL branches on; once a
    system of the class has run batched, every level of its trees."""
    from hybridsim import explore as _  # noqa: F401
    ex = sys.modules["hybridsim.explore"]
    small = hs.explore(Doubling(), [0.0, 0.0], t_max=0.45, j_max=4, merge_tol=None)
    assert batches["batches"] == 0 and batches["alone"] == 1 + 2 + 4 + 8
    monkeypatch.setattr(ex, "BATCH_LEVEL", 4)
    tree = hs.explore(Doubling(), [0.0, 0.0], t_max=0.45, j_max=4, merge_tol=None)
    # the levels of 1 and 2 branches alone, those of 4 and 8 batched (the 16
    # leaves after the last jump do not run)
    assert batches["alone"] == 15 + 3 and batches["batches"] == 2
    assert _shape(tree) == _shape(small)
    monkeypatch.setattr(ex, "BATCH_LEVEL", 512)
    again = hs.explore(Doubling(), [0.0, 0.0], t_max=0.45, j_max=4, merge_tol=None)
    assert batches["alone"] == 18 and batches["batches"] == 2 + 4
    assert _shape(again) == _shape(small)
    for a, b in zip(again, small, strict=True):
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)


def test_compiled_explore_refusals_name_the_reason():
    pytest.importorskip("numba")
    with pytest.raises(ValueError, match="backend must be one of 'auto', 'compiled', 'python'"):
        hs.explore(Doubling(), [0.0, 0.0], 1.0, 2, backend="fast")
    with pytest.raises(ValueError, match=r"backend='compiled'.*inputs= runs on the Python"):
        hs.explore(Doubling(), [0.0, 0.0], 1.0, 2, backend="compiled",
                   inputs=lambda t: np.zeros(1))
    with pytest.raises(ValueError, match=r"backend='compiled'.*reads its history"):
        hs.explore(_DelayedSampler(1.0, 0.0, 1.0, 0.2, 0.1, 0.3), [1.0, 0.0], 1.0, 2,
                   backend="compiled")
    with pytest.raises(ValueError, match=r"backend='compiled'.*LSODA"):
        hs.explore(Doubling(), [0.0, 0.0], 1.0, 2, backend="compiled", method="LSODA")


def test_a_map_failing_on_a_batched_branch_names_the_branch(batches):
    """The jump map raising on a branch run in a batch: the same MapError
    naming the branch as branch by branch; throw=False, the same leaves."""
    system = Window(fail_after=2.2)
    kw = dict(t_max=5.0, j_max=3, dwell_grid=[0.5])
    messages = []
    for backend in ("python", "compiled"):
        with pytest.raises(hs.MapError, match=r"broken reset.*on the branch: ") as e:
            hs.explore(system, [0.0, 0.0], backend=backend, **kw)
        messages.append(str(e.value))
    assert messages[0] == messages[1] and batches["batches"] > 0
    trees = [hs.explore(system, [0.0, 0.0], backend=b, throw=False, **kw)
             for b in ("python", "compiled")]
    assert _shape(trees[0]) == _shape(trees[1])
    assert sorted(a.termination.name for a in trees[0]) == \
        sorted(a.termination.name for a in trees[1])
    assert "MAP_ERROR" in {a.termination.name for a in trees[1]}


def test_ctrl_c_in_a_batch_ends_the_exploration_interrupted(batches, monkeypatch):
    """A batch that Ctrl-C stopped (simulate_many_compiled's rows: those done,
    the first under way CANCELED with its samples, the rest never started):
    the branches before it are kept, it is the one CANCELED leaf, the others
    are pending, and the tree says why."""
    import hybridsim.compiled as hc
    counted = hc.simulate_many_compiled

    def stopped(cs, X, *a, **k):
        arcs = counted(cs, X, *a, **k)
        if batches["batches"] == 4:         # the level of 8 branches: Ctrl-C at row 3
            arcs[3].termination = hs.Termination.CANCELED
            for i in range(4, len(arcs)):
                arcs[i] = hs.HybridArc(np.array([k["t0"]]), np.array([k["j0"]]),
                                       X[i:i + 1], termination=hs.Termination.CANCELED)
        return arcs
    monkeypatch.setattr(hc, "simulate_many_compiled", stopped)
    with pytest.warns(hs.SimulationWarning, match="INTERRUPTED"):
        tree = hs.explore(Doubling(), [0.0, 0.0], t_max=0.65, j_max=6, merge_tol=None,
                          backend="compiled")
    assert tree.end is hs.ExploreEnd.INTERRUPTED and not tree.complete
    canceled = [n for n in tree.nodes if n.arc is not None
                and n.arc.termination is hs.Termination.CANCELED]
    assert len(canceled) == 1 and len(canceled[0].arc.t) > 1
    level = [n for n in tree.nodes if n.start[1] == 3]
    assert len(level) == 8 and [n.end for n in level[:3]] == ["forced"] * 3
    assert level[3] is canceled[0] and all(n.end == "pending" for n in level[4:])
    assert tree.pending == 4 + 6              # the rest of its level, the children of 3


# ---------------------------------------------------------------- falsification populations
class Ball(hs.HybridSystem):
    """A plain model (its maps as written), its restitution an attribute."""

    state_dim = 2

    def __init__(self, e=0.8):
        self.e = e

    def flow_map(self, x):
        return np.array([x[1], -9.81])

    def jump_map(self, x):
        return np.array([0.0, -self.e * x[1]])

    def flow_set(self, x):
        return x[0] >= 0.0

    def jump_set(self, x):
        return x[0] <= 0.0 and x[1] <= 0.0


def _third_bounce_by(limit):
    def claim(arc):
        return limit - arc.jump_times[2]
    return claim


@pytest.fixture
def paths(monkeypatch):
    """Counts the rows each path ran: compiled batches, compiled single runs and
    the Python loop (hybridsim.solve's runs)."""
    pytest.importorskip("numba")
    import hybridsim.compiled as hc
    from hybridsim import solve
    seen = {"batch": 0, "single": 0, "python": 0}
    batch, single, loop = hc.simulate_many_compiled, hc.simulate_compiled, solve._Run.run

    def counted_batch(cs, X, *a, **k):
        seen["batch"] += len(X)
        return batch(cs, X, *a, **k)

    def counted_single(*a, **k):
        seen["single"] += 1
        return single(*a, **k)

    def counted_loop(self, *a, **k):
        seen["python"] += 1
        return loop(self, *a, **k)
    monkeypatch.setattr(hc, "simulate_many_compiled", counted_batch)
    monkeypatch.setattr(hc, "simulate_compiled", counted_single)
    monkeypatch.setattr(solve._Run, "run", counted_loop)
    return seen


def test_a_falsification_population_of_a_plain_model_runs_compiled(paths):
    """falsify over a plain model's population (batch_run, backend "auto" by
    default): every row runs in the compiled batches, none on the Python
    loop, and the counterexample is the closed form's (the highest drop)."""
    from hybridsim.falsification import Interval, Space, batch_run, falsify
    from hybridsim.library import bouncing_ball_jump_times
    run = batch_run(Ball(), lambda p: [p["h0"], 0.0], t_max=6.0, j_max=3)
    res = falsify(run, Space(h0=Interval(0.5, 2.0)), _third_bounce_by(2.0), budget=40,
                  seed=0, progress=False, stop=False)
    assert paths["batch"] == res.evaluations == 40 and paths["python"] == 0
    assert res.point["h0"] == pytest.approx(2.0, abs=1e-6)
    exact = 2.0 - bouncing_ball_jump_times(2.0, 3)[2]
    assert res.margin == pytest.approx(exact, abs=1e-6) and res.verdict == "counterexample"


def test_a_population_over_a_plain_models_attributes_runs_compiled(paths):
    """The uncertain number is the model's attribute (attributes_of): the
    population runs in compiled batches, a p per row read with the point's e
    (nothing compiled again), none on the Python loop; e is restored after;
    the margins are the closed form's, and the Python path's to round-off."""
    from hybridsim.falsification import Interval, Space, batch_run, falsify
    from hybridsim.library import bouncing_ball_jump_times
    ball = Ball(0.8)
    kw = dict(t_max=6.0, j_max=3, attributes_of=lambda p: {"e": p["e"]})
    space, claim = Space(e=Interval(0.5, 0.9)), _third_bounce_by(2.0)
    res = falsify(batch_run(ball, lambda p: [1.0, 0.0], **kw), space, claim, budget=30,
                  seed=0, progress=False, stop=False)
    assert paths["batch"] == res.evaluations == 30 and paths["python"] == 0
    assert paths["single"] == 0 and ball.e == 0.8
    exact = 2.0 - bouncing_ball_jump_times(1.0, 3, restitution=res.point["e"])[2]
    assert res.margin == pytest.approx(exact, abs=1e-6)
    py = falsify(batch_run(ball, lambda p: [1.0, 0.0], backend="python", **kw), space, claim,
                 budget=30, seed=0, progress=False, stop=False)
    assert paths["python"] == 30 and paths["single"] == 0
    assert py.margin == pytest.approx(res.margin, abs=1e-9)
    with pytest.raises(TypeError, match="attributes_of must return a dict of the system's "
                                        "attributes, got float"):
        batch_run(ball, lambda p: [1.0, 0.0], attributes_of=lambda p: 0.5,
                  t_max=1.0)([{"e": 0.5}])
