"""hybridsim.plot on a bouncing-ball arc: Axes returned, ax= honoured, jumps
dashed, plt.show never called, bad component indices rejected.

Agg backend throughout: nothing is displayed.
"""
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.axes import Axes

import hybridsim as hs
from hybridsim.library import BouncingBall

G, E = 9.81, 0.8
N_JUMPS = 4


@pytest.fixture(scope="module")
def arc():
    a = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=10.0, j_max=N_JUMPS, refine=4)
    assert a.jump_count == N_JUMPS
    return a


@pytest.fixture(scope="module")
def flow_only():
    """An arc with no jump: the ball before it first reaches the floor."""
    return hs.simulate(BouncingBall(), [1.0, 0.0], t_max=0.3)


@pytest.fixture(autouse=True)
def no_show(monkeypatch):
    def show(*args, **kwargs):
        raise AssertionError("a plot function called plt.show()")
    monkeypatch.setattr(plt, "show", show)
    yield
    plt.close("all")


def dashed(ax):
    return [ln for ln in ax.lines if ln.get_linestyle() == "--"]


def solid(ax):
    return [ln for ln in ax.lines if ln.get_linestyle() == "-"]


PLOTS_2D = [hs.plot_flows, hs.plot_jumps, hs.plot_phase, hs.plot_time_domain]
ALL_PLOTS = PLOTS_2D + [hs.plot_hybrid]


# ------------------------------------------------------------- Axes and ax=
@pytest.mark.parametrize("plot", ALL_PLOTS, ids=lambda f: f.__name__)
def test_returns_an_axes_on_a_new_figure(plot, arc):
    before = set(plt.get_fignums())
    ax = plot(arc)
    assert isinstance(ax, Axes)
    assert set(plt.get_fignums()) - before == {ax.figure.number}
    assert ax.lines                              # something was drawn
    ax.figure.canvas.draw()                      # and it renders


@pytest.mark.parametrize("plot", PLOTS_2D, ids=lambda f: f.__name__)
def test_draws_on_the_given_axes(plot, arc):
    fig, (ax0, ax1) = plt.subplots(1, 2)
    out = plot(arc, ax=ax1)
    assert out is ax1
    assert ax1.lines and not ax0.lines
    assert plt.get_fignums() == [fig.number]     # no new figure


def test_plot_hybrid_draws_on_the_given_3d_axes(arc):
    fig = plt.figure()
    ax3 = fig.add_subplot(111, projection="3d")
    assert hs.plot_hybrid(arc, ax=ax3) is ax3
    assert ax3.lines and plt.get_fignums() == [fig.number]
    assert (ax3.get_xlabel(), ax3.get_ylabel()) == ("t", "j")


def test_axis_labels(arc):
    assert hs.plot_flows(arc).get_xlabel() == "t"
    assert hs.plot_jumps(arc).get_xlabel() == "j"
    ax = hs.plot_phase(arc, 0, 1)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x0", "x1")
    ax = hs.plot_time_domain(arc)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("t", "j")


# ------------------------------------------------------- jumps are dashed
def test_plot_flows_flows_solid_jumps_dashed(arc):
    ax = hs.plot_flows(arc)
    n, J = arc.state_dim, arc.jump_count
    assert len(solid(ax)) == n * (J + 1)         # one solid line per flow interval
    jumps = dashed(ax)
    assert len(jumps) == n * J
    k = arc.jump_index
    for c in range(n):                           # jumps of component c, in order
        for line, i in zip(jumps[c * J:(c + 1) * J], k):
            np.testing.assert_array_equal(line.get_xdata(), [arc.t[i - 1], arc.t[i]])
            np.testing.assert_array_equal(line.get_ydata(), [arc.x[i - 1, c], arc.x[i, c]])
    # each component keeps one colour across its flows and jumps
    for c in range(n):
        colours = {ln.get_color() for ln in solid(ax)[c * (J + 1):(c + 1) * (J + 1)]}
        colours |= {ln.get_color() for ln in jumps[c * J:(c + 1) * J]}
        assert len(colours) == 1
    # the dashed jump segments are vertical: a jump takes no ordinary time
    assert all(ln.get_xdata()[0] == ln.get_xdata()[1] for ln in jumps)


def test_plot_flows_without_jumps(arc):
    ax = hs.plot_flows(arc, 1, jumps=False)
    assert not dashed(ax) and len(solid(ax)) == arc.jump_count + 1


def test_plot_flows_of_a_function_along_the_arc(arc):
    energy = lambda x: 0.5 * x[1] ** 2 + G * x[0]      # noqa: E731
    ax = hs.plot_flows(arc, energy)
    k = arc.jump_index
    for line, i in zip(dashed(ax), k):
        y0, y1 = line.get_ydata()
        assert y1 == pytest.approx(E ** 2 * y0, rel=1e-6)   # each bounce keeps e^2 of the energy


def test_plot_jumps_dashed_from_j_to_j_plus_1(arc):
    ax = hs.plot_jumps(arc, 0)
    jumps = dashed(ax)
    assert len(jumps) == arc.jump_count
    for line, i in zip(jumps, arc.jump_index):
        np.testing.assert_array_equal(line.get_xdata(), [arc.j[i] - 1, arc.j[i]])
        np.testing.assert_array_equal(line.get_ydata(), [arc.x[i - 1, 0], arc.x[i, 0]])
    dots = [ln for ln in ax.lines if ln.get_marker() == "."]
    assert len(dots) == 1 and len(dots[0].get_xdata()) == len(arc.t)


def test_plot_hybrid_dashed_jumps_in_t_j_x(arc):
    ax = hs.plot_hybrid(arc, idx=0)
    jumps = dashed(ax)
    assert len(jumps) == arc.jump_count
    assert len(solid(ax)) == arc.jump_count + 1
    for line, i in zip(jumps, arc.jump_index):
        t, j, x = line.get_data_3d()
        np.testing.assert_array_equal(t, [arc.t[i]] * 2)
        np.testing.assert_array_equal(j, [arc.j[i] - 1, arc.j[i]])
        np.testing.assert_array_equal(x, [arc.x[i - 1, 0], arc.x[i, 0]])


def test_plot_phase_dashed_jumps(arc):
    ax = hs.plot_phase(arc, 0, 1)
    jumps = dashed(ax)
    assert len(jumps) == arc.jump_count and len(solid(ax)) == arc.jump_count + 1
    for line, i in zip(jumps, arc.jump_index):
        np.testing.assert_array_equal(line.get_xdata(), arc.x[i - 1:i + 1, 0])
        np.testing.assert_array_equal(line.get_ydata(), arc.x[i - 1:i + 1, 1])
    # swapped components: same segments, transposed
    ax2 = hs.plot_phase(arc, 1, 0)
    np.testing.assert_array_equal(dashed(ax2)[0].get_xdata(), jumps[0].get_ydata())


def test_plot_time_domain_one_segment_per_j(arc):
    ax = hs.plot_time_domain(arc)
    segs = solid(ax)
    assert len(segs) == arc.jump_count + 1
    for line, (a, b, j) in zip(segs, arc.flow_intervals):
        np.testing.assert_array_equal(line.get_xdata(), [a, b])
        np.testing.assert_array_equal(line.get_ydata(), [j, j])
    # consecutive intervals meet at the jump times
    ends = [ln.get_xdata()[1] for ln in segs[:-1]]
    starts = [ln.get_xdata()[0] for ln in segs[1:]]
    np.testing.assert_array_equal(ends, arc.jump_times)
    np.testing.assert_array_equal(starts, arc.jump_times)


@pytest.mark.parametrize("plot", ALL_PLOTS, ids=lambda f: f.__name__)
def test_an_arc_without_jumps_has_no_dashed_line(plot, flow_only):
    assert flow_only.jump_count == 0
    ax = plot(flow_only)
    assert ax.lines and not dashed(ax)


# --------------------------------------------------------------- bad input
@pytest.mark.parametrize("plot", [hs.plot_flows, hs.plot_jumps, hs.plot_hybrid],
                         ids=lambda f: f.__name__)
@pytest.mark.parametrize("idx", [2, -3, 10])
def test_bad_idx_raises(plot, idx, arc):
    with pytest.raises(ValueError, match=rf"idx: component {idx} out of range for a state "
                                         r"of dimension 2"):
        plot(arc, idx)


@pytest.mark.parametrize("plot", [hs.plot_flows, hs.plot_jumps], ids=lambda f: f.__name__)
def test_bad_idx_in_a_list_raises(plot, arc):
    with pytest.raises(ValueError, match=r"idx: component 5 out of range"):
        plot(arc, [0, 5])


def test_negative_idx_counts_from_the_end(arc):
    ax = hs.plot_flows(arc, -1)
    np.testing.assert_array_equal(dashed(ax)[0].get_ydata(),
                                  arc.x[arc.jump_index[0] - 1:arc.jump_index[0] + 1, 1])


def test_plot_hybrid_needs_one_component(arc):
    with pytest.raises(ValueError, match="plot_hybrid: idx must select one component"):
        hs.plot_hybrid(arc, idx=[0, 1])


@pytest.mark.parametrize("i, k, bad", [(0, 2, 2), (-3, 1, -3)])
def test_plot_phase_bad_component_raises(arc, i, k, bad):
    with pytest.raises(ValueError, match=rf"plot_phase: component {bad} out of range"):
        hs.plot_phase(arc, i, k)


@pytest.mark.parametrize("idx", [1.5, True, "a"])
def test_non_integer_idx_raises_value_error(idx, arc):
    with pytest.raises((ValueError, TypeError), match="idx"):
        hs.plot_flows(arc, idx)


def test_empty_idx_raises(arc):
    with pytest.raises(ValueError, match="idx"):
        hs.plot_flows(arc, [])


def test_labels_of_the_wrong_length_raise(arc):
    with pytest.raises(ValueError, match="labels"):
        hs.plot_flows(arc, [0, 1], labels=["height"])


def test_plot_flows_takes_precomputed_values(arc):
    # a derived signal (here the energy) given as values at the samples
    energy = 9.81 * arc.x[:, 0] + 0.5 * arc.x[:, 1] ** 2
    ax = hs.plot_flows(arc, energy, labels=["energy"], color="r")
    assert all(ln.get_color() == "r" for ln in ax.get_lines())
    flows = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
    np.testing.assert_allclose(np.concatenate([ln.get_ydata() for ln in flows]), energy)
    with pytest.raises(ValueError, match=r"idx: an array of values must have shape"):
        hs.plot_flows(arc, energy[:-1])
