"""hybridsim.plot: the artists drawn, not pixels.

On bouncing-ball arcs: Axes returned and ``ax=`` honoured, plt.show never
called; per component one flow line, one NaN-separated line of jump
segments and two marker lines (told apart by gid), their styles and
colours; axis labels, 1-based names and legend entries; ``subplots=True``
(number of Axes, shared t, x label at the bottom only); ``filter=`` hiding
points; ``fn=`` values and log scales; defaults from rcParams; flows
between samples on the closed-form parabola to 1e-6; bad arguments
rejected with a message naming them.

Agg backend throughout: nothing is displayed.
"""
import doctest

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.axes import Axes

import hybridsim as hs
import hybridsim.plot
from hybridsim.library import BouncingBall, bouncing_ball_jump_times

G, E, H0 = 9.81, 0.8, 1.0
N_JUMPS = 4
GIDS = ["flows", "jumps", "jump_starts", "jump_ends"]


@pytest.fixture(scope="module")
def arc():
    """The ball at default simulate settings (no refine, no dense output)."""
    a = hs.simulate(BouncingBall(G, E), [H0, 0.0], t_max=10.0, j_max=N_JUMPS)
    assert a.jump_count == N_JUMPS and a.xdot is not None
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


def gid(ax, name):
    return [ln for ln in ax.lines if ln.get_gid() == name]


def one(ax, name):
    (line,) = gid(ax, name)
    return line


def segments(line):
    """The NaN-separated pieces of a line's data, as a list of (x, y)."""
    x, y = line.get_xdata(), line.get_ydata()
    gap = np.isnan(x) | np.isnan(y)
    cut = np.flatnonzero(gap)
    pieces = zip(np.split(x, cut), np.split(y, cut), np.split(gap, cut))
    return [(a[~g], b[~g]) for a, b, g in pieces if (~g).any()]


def true_height(t):
    """Closed-form height of the ball (h0 = 1, from rest) at times t."""
    tk = np.concatenate(([0.0], bouncing_ball_jump_times(H0, 20, G, E)))
    k = np.searchsorted(tk, t, side="right") - 1
    v0 = np.where(k == 0, 0.0, np.sqrt(2 * G * H0) * E ** k)
    h0 = np.where(k == 0, H0, 0.0)
    s = t - tk[k]
    return h0 + v0 * s - G / 2 * s ** 2


PLOTS_2D = [hs.plot_flows, hs.plot_jumps, hs.plot_phase, hs.plot_time_domain]
ALL_PLOTS = PLOTS_2D + [hs.plot_hybrid]
ids = lambda f: f.__name__          # noqa: E731


def test_module_examples_run():
    res = doctest.testmod(hybridsim.plot, optionflags=doctest.ELLIPSIS)
    assert res.attempted >= 10 and res.failed == 0


# ------------------------------------------------------------- Axes and ax=
@pytest.mark.parametrize("plot", ALL_PLOTS, ids=ids)
def test_returns_an_axes_on_a_new_figure(plot, arc):
    before = set(plt.get_fignums())
    ax = plot(arc)
    assert isinstance(ax, Axes)
    assert set(plt.get_fignums()) - before == {ax.figure.number}
    assert [ln.get_gid() for ln in ax.lines][:4] == GIDS
    ax.figure.canvas.draw()                      # and it renders


@pytest.mark.parametrize("plot", PLOTS_2D, ids=ids)
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
    assert (ax3.get_xlabel(), ax3.get_ylabel(), ax3.get_zlabel()) == ("$t$", "$j$", "$x_1$")


# ------------------------------------------------- labels, names, legends
def test_default_axis_labels_are_latex_and_one_based(arc):
    ax = hs.plot_flows(arc)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$t$", "$x_1$, $x_2$")
    ax = hs.plot_jumps(arc, 1)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$j$", "$x_2$")
    ax = hs.plot_phase(arc, 0, 1)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$x_1$", "$x_2$")
    ax = hs.plot_phase(arc, 1, 0)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$x_2$", "$x_1$")
    ax = hs.plot_time_domain(arc)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$t$", "$j$")


def legend_texts(ax):
    leg = ax.get_legend()
    return None if leg is None else [t.get_text() for t in leg.get_texts()]


def test_legend_one_entry_per_component_even_a_single_one(arc):
    assert legend_texts(hs.plot_flows(arc, 0)) == ["$x_1$"]
    assert legend_texts(hs.plot_flows(arc)) == ["$x_1$", "$x_2$"]
    assert legend_texts(hs.plot_jumps(arc, [1, 0])) == ["$x_2$", "$x_1$"]
    # the legend's handles are the flow lines, not jumps or markers
    ax = hs.plot_flows(arc)
    handles, _ = ax.get_legend_handles_labels()
    assert [h.get_gid() for h in handles] == ["flows", "flows"]
    assert hs.plot_flows(arc, 0, legend=False).get_legend() is None


@pytest.mark.parametrize("plot", [hs.plot_flows, hs.plot_jumps], ids=ids)
def test_labels_name_the_components(plot, arc):
    ax = plot(arc, labels=["height (m)", "velocity (m/s)"])
    assert legend_texts(ax) == ["height (m)", "velocity (m/s)"]
    assert ax.get_ylabel() == "height (m), velocity (m/s)"
    ax = plot(arc, 1, labels="velocity (m/s)", ylabel="$v$ (m/s)", xlabel="time (s)")
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("time (s)", "$v$ (m/s)")
    assert legend_texts(ax) == ["velocity (m/s)"]


def test_labels_on_phase_hybrid_and_time_domain(arc):
    # issue 12: these raised inside matplotlib (Line2D.set() got 'labels')
    ax = hs.plot_phase(arc, 0, 1, labels=["height (m)", "velocity (m/s)"])
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("height (m)", "velocity (m/s)")
    assert ax.get_legend() is None                       # one curve: no legend by default
    ax = hs.plot_phase(arc, label="ball")
    assert legend_texts(ax) == ["ball"]
    ax = hs.plot_hybrid(arc, 0, labels=["height (m)"])
    assert ax.get_zlabel() == "height (m)"
    ax = hs.plot_time_domain(arc, labels=["ball"])
    assert legend_texts(ax) == ["ball"]
    with pytest.raises(ValueError, match="labels must have one entry per axis"):
        hs.plot_phase(arc, labels=["only one"])


def test_names_of_an_interconnection_parts():
    a = hs.HybridArc([0.0, 1.0], [0, 0], [[0, 1, 2], [1, 2, 3]], None,
                     components={"plant": slice(0, 2), "observer": slice(2, 3)})
    ax = hs.plot_flows(a)
    assert legend_texts(ax) == ["plant$_1$", "plant$_2$", "observer"]
    ax = hs.plot_phase(a, 0, 2)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("plant$_1$", "observer")


def test_names_past_nine_are_braced():
    a = hs.HybridArc([0.0, 1.0], [0, 0], np.zeros((2, 11)), None)
    assert legend_texts(hs.plot_flows(a, [0, 10])) == ["$x_1$", "$x_{11}$"]


# ------------------------------------------------------- flows and jumps
def test_artists_per_component_and_their_styles(arc):
    ax = hs.plot_flows(arc)
    assert [ln.get_gid() for ln in ax.lines] == GIDS * 2
    lw = matplotlib.rcParams["lines.linewidth"]
    for c in range(2):
        flow, jump, start, end = ax.lines[4 * c:4 * c + 4]
        assert flow.get_linestyle() == "-" and flow.get_marker() in ("None", None, "")
        # jumps: thin, dotted, so a user's dashed "--" reference stays distinct
        assert jump.get_linestyle() == ":" and jump.get_linestyle() != "--"
        assert jump.get_linewidth() < flow.get_linewidth() == lw
        # pre-jump filled, post-jump open circles, no connecting line
        assert start.get_marker() == end.get_marker() == "o"
        assert start.get_linestyle() == end.get_linestyle() == "None"
        assert start.get_markerfacecolor() == start.get_color()
        assert end.get_markerfacecolor() == "none"
        # one colour per component
        assert len({flow.get_color(), jump.get_color(), start.get_color(),
                    end.get_markeredgecolor()}) == 1
    assert ax.lines[0].get_color() != ax.lines[4].get_color()


def test_jump_segments_are_exact_and_vertical(arc):
    ax = hs.plot_flows(arc)
    k = arc.jump_index
    # the height does not jump (0 -> 0): markers but no segment, not even a dot
    assert len(ax.lines[1].get_xdata()) == 0
    np.testing.assert_array_equal(ax.lines[2].get_xdata(), arc.jump_times)
    for c in range(1, 2):
        jump = ax.lines[4 * c + 1]
        x = jump.get_xdata().reshape(-1, 3)
        y = jump.get_ydata().reshape(-1, 3)
        assert len(x) == arc.jump_count
        np.testing.assert_array_equal(x[:, 0], arc.t[k - 1])
        np.testing.assert_array_equal(x[:, 1], arc.t[k])     # a jump takes no ordinary time
        assert np.isnan(x[:, 2]).all() and np.isnan(y[:, 2]).all()
        np.testing.assert_array_equal(y[:, 0], arc.x[k - 1, c])
        np.testing.assert_array_equal(y[:, 1], arc.x[k, c])
        start, end = ax.lines[4 * c + 2], ax.lines[4 * c + 3]
        np.testing.assert_array_equal(start.get_ydata(), arc.x[k - 1, c])
        np.testing.assert_array_equal(end.get_xdata(), arc.t[k])
        np.testing.assert_array_equal(end.get_ydata(), arc.x[k, c])


def test_flows_pass_through_every_stored_sample(arc):
    flow = one(hs.plot_flows(arc, 1), "flows")
    t, v = flow.get_xdata(), flow.get_ydata()
    pieces = segments(flow)
    assert len(pieces) == arc.jump_count + 1                 # one piece per flow interval
    assert np.isnan(t).sum() == arc.jump_count
    for (pt, pv), (a, b, j) in zip(pieces, arc.flow_intervals):
        assert pt[0] == a and pt[-1] == b and np.all(np.diff(pt) > 0)
    # the stored samples, in order, are among the plotted points, exactly
    live = ~np.isnan(t)
    pos = np.flatnonzero(np.isin(t, arc.t) & live)
    np.testing.assert_array_equal(t[pos], arc.t)
    np.testing.assert_array_equal(v[pos], arc.x[:, 1])


def test_flows_are_smooth_between_samples(arc):
    """Default simulate settings (RK45 takes about two steps per flight):
    the plotted height between samples is the parabola to 1e-6."""
    flow = one(hs.plot_flows(arc, 0), "flows")
    t, h = flow.get_xdata(), flow.get_ydata()
    live = ~np.isnan(t)
    between = live & ~np.isin(t, arc.t)
    assert between.sum() >= 10 * (len(arc.t) - 1 - arc.jump_count)   # points inside steps
    np.testing.assert_allclose(h[live], true_height(t[live]), rtol=0, atol=1e-6)
    # the samples alone would not do: the polyline is far from the parabola
    coarse = one(hs.plot_flows(arc, 0, smooth=False), "flows")
    assert np.isin(coarse.get_xdata()[~np.isnan(coarse.get_xdata())], arc.t).all()
    mid = 0.5 * (arc.t[1:] + arc.t[:-1])
    same = np.diff(arc.j) == 0
    poly = np.interp(mid[same], arc.t, arc.x[:, 0])
    assert np.max(np.abs(poly - true_height(mid[same]))) > 1e-2


def test_flows_smooth_from_a_dense_output_too():
    a = hs.simulate(BouncingBall(G, E), [H0, 0.0], t_max=3.0, j_max=3, dense=True)
    flow = one(hs.plot_flows(a, 0, smooth=8), "flows")
    t, h = flow.get_xdata(), flow.get_ydata()
    live = ~np.isnan(t)
    assert (live & ~np.isin(t, a.t)).sum() == 8 * (len(a.t) - 1 - a.jump_count)
    np.testing.assert_allclose(h[live], true_height(t[live]), rtol=0, atol=1e-6)


def test_no_jump_artists_without_jumps(arc, flow_only):
    ax = hs.plot_flows(arc, 1, jumps=False)
    assert [ln.get_gid() for ln in ax.lines] == ["flows"]
    ax = hs.plot_flows(arc, 1, markers=False)
    assert [ln.get_gid() for ln in ax.lines] == ["flows", "jumps"]
    for plot in ALL_PLOTS:
        ax = plot(flow_only)
        assert {ln.get_gid() for ln in ax.lines} == {"flows"}, plot.__name__


# ---------------------------------------------------------------- styles
def test_flow_and_jump_styles_set_separately(arc):
    ax = hs.plot_flows(arc, 1, flow_kw={"color": "k", "linewidth": 2.5},
                       jump_kw={"color": "r", "linestyle": "-."},
                       start_kw={"marker": "s"}, end_kw={"markersize": 9})
    flow, jump, start, end = ax.lines
    assert (flow.get_color(), flow.get_linewidth()) == ("k", 2.5)
    assert (jump.get_color(), jump.get_linestyle()) == ("r", "-.")
    assert start.get_marker() == "s" and start.get_color() == "r"
    assert end.get_markersize() == 9 and end.get_markeredgecolor() == "r"


def test_color_keyword_colours_everything(arc):
    ax = hs.plot_flows(arc, color="m", alpha=0.5)
    assert {ln.get_color() for ln in ax.lines} == {"m"}
    assert {ln.get_alpha() for ln in ax.lines} == {0.5}


def test_defaults_follow_rcparams_and_style_contexts(arc):
    with matplotlib.rc_context({"lines.linewidth": 3.0, "lines.markersize": 10.0,
                                "axes.prop_cycle": matplotlib.cycler(color=["#123456"])}):
        flow, jump, start, _ = hs.plot_flows(arc, 0).lines
    assert flow.get_linewidth() == 3.0 and jump.get_linewidth() == pytest.approx(2.4)
    assert start.get_markersize() == pytest.approx(5.0)
    assert flow.get_color() == "#123456"
    with plt.style.context("grayscale"):
        ax = hs.plot_flows(arc, 0)
    assert ax.lines[0].get_color() != "C0"


def test_a_users_dashed_reference_stays_distinct_from_jumps(arc):
    fig, ax = plt.subplots()
    ax.plot(arc.t, 0 * arc.t, "--", label="floor")
    hs.plot_flows(arc, 0, ax=ax)
    styles = {ln.get_gid(): ln.get_linestyle() for ln in ax.lines}
    assert styles[None] == "--" and styles["jumps"] == ":"
    assert legend_texts(ax) == ["floor", "$x_1$"]


# -------------------------------------------------------------- subplots
def test_subplots_one_axes_per_component_shared_t(arc):
    axs = hs.plot_flows(arc, subplots=True, labels=["height (m)", "velocity (m/s)"])
    assert isinstance(axs, np.ndarray) and axs.shape == (2,)
    assert len(axs[0].figure.axes) == 2
    assert axs[0].get_shared_x_axes().joined(axs[0], axs[1])
    assert [a.get_xlabel() for a in axs] == ["", "$t$"]       # t only at the bottom
    assert [a.get_ylabel() for a in axs] == ["height (m)", "velocity (m/s)"]
    assert [legend_texts(a) for a in axs] == [["height (m)"], ["velocity (m/s)"]]
    assert [[ln.get_gid() for ln in a.lines] for a in axs] == [GIDS, GIDS]
    np.testing.assert_array_equal(one(axs[1], "jump_ends").get_ydata(),
                                  arc.x[arc.jump_index, 1])


def test_subplots_on_given_axes_and_on_j(arc):
    fig, axs = plt.subplots(2, 1, sharex=True)
    out = hs.plot_jumps(arc, subplots=True, ax=axs, ylabel=["$h$", "$v$"])
    assert list(out) == list(axs)
    assert [a.get_xlabel() for a in out] == ["", "$j$"]
    # Axes above other subplots of their grid get no x label
    fig, axs3 = plt.subplots(3, 1, sharex=True)
    hs.plot_flows(arc, subplots=True, ax=axs3[:2])
    assert [a.get_xlabel() for a in axs3] == ["", "", ""]
    assert [a.get_ylabel() for a in out] == ["$h$", "$v$"]
    one_ax = hs.plot_flows(arc, 0, subplots=True)
    assert one_ax.shape == (1,) and one_ax[0].get_xlabel() == "$t$"
    with pytest.raises(ValueError, match=r"one Axes per plotted component \(2\), got 1"):
        hs.plot_flows(arc, subplots=True, ax=[axs[0]])
    with pytest.raises(TypeError, match="sequence of 2 matplotlib Axes"):
        hs.plot_flows(arc, subplots=True, ax="foo")


# ---------------------------------------------------------------- filter=
def test_filter_predicate_hides_points_and_their_jumps(arc):
    falling = lambda x: x[1] <= 0        # noqa: E731
    ax = hs.plot_flows(arc, 1, filter=falling)
    v = one(ax, "flows").get_ydata()
    shown = v[~np.isnan(v)]
    assert shown.size > 20 and shown.max() <= 0           # inserted points filtered too
    # every jump ends rising (v+ > 0): none is drawn
    assert not gid(ax, "jumps")
    everything = one(hs.plot_flows(arc, 1), "flows").get_ydata()
    assert np.count_nonzero(~np.isnan(everything)) > shown.size


def test_filter_per_mode_with_t_and_j(arc):
    ax = hs.plot_flows(arc, 0, filter=lambda x, t, j: j % 2 == 0)
    pieces = segments(one(ax, "flows"))
    even = [(a, b) for a, b, j in arc.flow_intervals if j % 2 == 0]
    assert len(pieces) == len(even)
    for (pt, ph), (a, b) in zip(pieces, even):           # only the flows of even j
        assert (pt[0], pt[-1]) == (a, b)
    assert not gid(ax, "jumps")                           # each jump changes the parity


def test_filter_as_a_mask_of_the_samples(arc):
    ax = hs.plot_flows(arc, 1, filter=arc.j >= 2)
    flow, jump = one(ax, "flows"), one(ax, "jumps")
    t = flow.get_xdata()[~np.isnan(flow.get_ydata())]
    assert t.min() == arc.jump_times[1]                   # the flow of j = 2 onwards
    np.testing.assert_array_equal(jump.get_xdata()[::3], arc.jump_times[2:])
    with pytest.raises(TypeError, match=r"filter must be a callable .* bool array of shape"):
        hs.plot_flows(arc, filter=(arc.j >= 2)[:-1])


def test_filter_on_phase_and_time_domain(arc):
    ax = hs.plot_phase(arc, filter=lambda x: x[1] <= 0)
    assert np.nanmax(one(ax, "flows").get_ydata()) <= 0
    ax = hs.plot_time_domain(arc, filter=arc.j >= 1)
    j = one(ax, "flows").get_ydata()
    assert np.nanmin(j) == 1


# -------------------------------------------------------- fn= and scales
def energy(x):
    return G * x[0] + 0.5 * x[1] ** 2


def test_fn_values_and_log_scale(arc):
    ax = hs.plot_flows(arc, fn=energy, yscale="log")
    assert ax.get_yscale() == "log"
    assert legend_texts(ax) == ["energy"] and ax.get_ylabel() == "energy"
    flow, jump = one(ax, "flows"), one(ax, "jumps")
    # the energy is constant along each flow (inserted points included)
    for (pt, pv), (a, b, j) in zip(segments(flow), arc.flow_intervals):
        np.testing.assert_allclose(pv, pv[0], rtol=1e-9)
        np.testing.assert_allclose(pv[0], G * H0 * E ** (2 * j), rtol=1e-6)
    y = jump.get_ydata().reshape(-1, 3)
    assert len(y) == arc.jump_count
    np.testing.assert_allclose(y[:, 1], E ** 2 * y[:, 0], rtol=1e-6)
    # same values as the function applied to the plotted states
    h = one(hs.plot_flows(arc, 0), "flows").get_ydata()
    v = one(hs.plot_flows(arc, 1), "flows").get_ydata()
    np.testing.assert_allclose(flow.get_ydata(), G * h + 0.5 * v ** 2, rtol=1e-12)


def test_fn_with_vector_output_and_idx_selecting_it(arc):
    fn = lambda x, t, j: np.array([x[0], -x[1], t])     # noqa: E731
    ax = hs.plot_flows(arc, fn=fn)
    assert legend_texts(ax) == ["$y_1$", "$y_2$", "$y_3$"]
    ax = hs.plot_flows(arc, 1, fn=fn, labels=["$-v$"])
    np.testing.assert_array_equal(one(ax, "jump_ends").get_ydata(), -arc.x[arc.jump_index, 1])
    # a lambda of one output: "$y$"; the legacy callable idx still works
    assert legend_texts(hs.plot_flows(arc, lambda x: x[0])) == ["$y$"]
    ax = hs.plot_phase(arc, 0, 2, fn=fn)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$y_1$", "$y_3$")
    h = one(hs.plot_flows(arc, 0), "flows")
    np.testing.assert_array_equal(one(ax, "flows").get_xdata(), h.get_ydata())
    np.testing.assert_array_equal(one(ax, "flows").get_ydata(), h.get_xdata())   # t


def test_fn_rejects_bad_outputs(arc):
    with pytest.raises(ValueError, match="fn must return a float or a 1-D array"):
        hs.plot_flows(arc, fn=lambda x: np.eye(2))
    with pytest.raises(TypeError, match="fn must be a callable"):
        hs.plot_flows(arc, fn=3)


def test_plot_flows_takes_precomputed_values(arc):
    # a derived signal (here the energy) given as values at the samples
    e = G * arc.x[:, 0] + 0.5 * arc.x[:, 1] ** 2
    ax = hs.plot_flows(arc, e, labels=["energy"], color="r")
    assert all(ln.get_color() == "r" for ln in ax.get_lines())
    y = one(ax, "flows").get_ydata()
    np.testing.assert_allclose(y[~np.isnan(y)], e)          # through the samples only
    with pytest.raises(ValueError, match=r"idx: an array of values must have shape"):
        hs.plot_flows(arc, e[:-1])


# ----------------------------------------------------- the other four plots
def test_plot_jumps_vertical_flows_and_slanted_jumps(arc):
    ax = hs.plot_jumps(arc, 0)
    flow, jump = one(ax, "flows"), one(ax, "jumps")     # (j, 0) -> (j + 1, 0): not zero length
    for (pj, ph), (a, b, j) in zip(segments(flow), arc.flow_intervals):
        assert set(pj) == {j}                                 # a flow stays at its j
    # the vertical line reaches each apex although it lies inside a step
    apex = H0 * E ** (2 * np.arange(1, N_JUMPS))
    tops = [ph.max() for _, ph in segments(flow)][1:-1]
    np.testing.assert_allclose(tops, apex, rtol=5e-3)
    x = jump.get_xdata().reshape(-1, 3)
    np.testing.assert_array_equal(x[:, 0], np.arange(N_JUMPS))
    np.testing.assert_array_equal(x[:, 1], np.arange(1, N_JUMPS + 1))
    np.testing.assert_array_equal(jump.get_ydata().reshape(-1, 3)[:, 1], arc.x[arc.jump_index, 0])


def test_plot_hybrid_jumps_in_t_j_x(arc):
    ax = hs.plot_hybrid(arc, idx=1)
    t, j, x = one(ax, "jumps").get_data_3d()
    t, j, x = (a.reshape(-1, 3) for a in (t, j, x))
    k = arc.jump_index
    np.testing.assert_array_equal(t[:, :2], np.column_stack([arc.t[k]] * 2))
    np.testing.assert_array_equal(j[:, :2], np.column_stack([arc.j[k] - 1, arc.j[k]]))
    np.testing.assert_array_equal(x[:, :2], np.column_stack([arc.x[k - 1, 1], arc.x[k, 1]]))
    ft, fj, fx = one(ax, "flows").get_data_3d()
    live = ~np.isnan(ft)
    np.testing.assert_allclose(fx[live], arc.at(ft[live], fj[live].astype(int))[:, 1])


def test_plot_phase_jumps_and_flows(arc):
    ax = hs.plot_phase(arc, 0, 1)
    k = arc.jump_index
    jump = one(ax, "jumps")
    np.testing.assert_array_equal(jump.get_xdata().reshape(-1, 3)[:, :2],
                                  np.column_stack([arc.x[k - 1, 0], arc.x[k, 0]]))
    np.testing.assert_array_equal(jump.get_ydata().reshape(-1, 3)[:, :2],
                                  np.column_stack([arc.x[k - 1, 1], arc.x[k, 1]]))
    # flows: on the parabola g h + v^2 / 2 = g h0 e^(2j) of each flight
    pieces = segments(one(ax, "flows"))
    assert len(pieces) == arc.jump_count + 1 and sum(len(h) for h, _ in pieces) > 100
    for (h, v), (_, _, j) in zip(pieces, arc.flow_intervals):
        np.testing.assert_allclose(G * h + 0.5 * v ** 2, G * H0 * E ** (2 * j), rtol=1e-6)
    ax2 = hs.plot_phase(arc, 1, 0)
    np.testing.assert_array_equal(one(ax2, "jumps").get_xdata(), jump.get_ydata())


def test_plot_time_domain_intervals_and_jumps(arc):
    ax = hs.plot_time_domain(arc)
    flow, jump = one(ax, "flows"), one(ax, "jumps")
    pieces = segments(flow)
    assert len(pieces) == arc.jump_count + 1
    for (pt, pj), (a, b, j) in zip(pieces, arc.flow_intervals):
        assert (pt[0], pt[-1]) == (a, b) and set(pj) == {j}
    assert flow.get_linewidth() > jump.get_linewidth()
    x = jump.get_xdata().reshape(-1, 3)
    y = jump.get_ydata().reshape(-1, 3)
    np.testing.assert_array_equal(x[:, 0], arc.jump_times)
    np.testing.assert_array_equal(x[:, 1], arc.jump_times)
    np.testing.assert_array_equal(y[:, 1] - y[:, 0], 1)


# --------------------------------------------------------------- bad input
@pytest.mark.parametrize("plot", ALL_PLOTS, ids=ids)
def test_arc_must_be_a_hybrid_arc(plot):
    with pytest.raises(TypeError, match=rf"{plot.__name__}: arc must be a HybridArc.*NoneType"):
        plot(None)


@pytest.mark.parametrize("plot", ALL_PLOTS, ids=ids)
def test_empty_arc_is_refused(plot):
    empty = hs.HybridArc(np.zeros(0), np.zeros(0, int), np.zeros((0, 2)), None)
    with pytest.raises(ValueError, match="arc is empty"):
        plot(empty)


@pytest.mark.parametrize("plot", ALL_PLOTS, ids=ids)
def test_ax_must_be_an_axes(plot, arc):
    with pytest.raises(TypeError, match=rf"{plot.__name__}: ax must be a matplotlib Axes, "
                                        r"got str"):
        plot(arc, ax="foo")


def test_plot_hybrid_needs_a_3d_axes(arc):
    _, ax = plt.subplots()
    with pytest.raises(ValueError, match="ax must be a 3-D Axes"):
        hs.plot_hybrid(arc, ax=ax)


@pytest.mark.parametrize("plot", [hs.plot_flows, hs.plot_jumps, hs.plot_hybrid], ids=ids)
@pytest.mark.parametrize("idx", [2, -3, 10])
def test_bad_idx_raises(plot, idx, arc):
    with pytest.raises(ValueError, match=rf"idx: component {idx} out of range for a state "
                                         r"of dimension 2"):
        plot(arc, idx)


@pytest.mark.parametrize("plot", [hs.plot_flows, hs.plot_jumps], ids=ids)
def test_bad_idx_in_a_list_raises(plot, arc):
    with pytest.raises(ValueError, match=r"idx: component 5 out of range"):
        plot(arc, [0, 5])


def test_negative_idx_counts_from_the_end(arc):
    ax = hs.plot_flows(arc, -1)
    np.testing.assert_array_equal(one(ax, "jump_ends").get_ydata(), arc.x[arc.jump_index, 1])
    assert legend_texts(ax) == ["$x_2$"]


def test_plot_hybrid_needs_one_component(arc):
    with pytest.raises(ValueError, match="plot_hybrid: idx must select one component"):
        hs.plot_hybrid(arc, idx=[0, 1])


@pytest.mark.parametrize("i, k, bad", [(0, 2, 2), (-3, 1, -3)])
def test_plot_phase_bad_component_raises(arc, i, k, bad):
    with pytest.raises(ValueError, match=rf"plot_phase: component {bad} out of range"):
        hs.plot_phase(arc, i, k)


@pytest.mark.parametrize("i, k", [(0, 0), (1, -1)])
def test_plot_phase_same_component_twice_raises(arc, i, k):
    with pytest.raises(ValueError, match="i and k must be two different components"):
        hs.plot_phase(arc, i, k)


@pytest.mark.parametrize("idx", [1.5, True, "a"])
def test_non_integer_idx_raises(idx, arc):
    with pytest.raises((ValueError, TypeError), match="idx"):
        hs.plot_flows(arc, idx)


def test_empty_idx_raises(arc):
    with pytest.raises(ValueError, match="idx"):
        hs.plot_flows(arc, [])


def test_labels_of_the_wrong_length_raise(arc):
    with pytest.raises(ValueError, match="labels must have one entry per plotted component"):
        hs.plot_flows(arc, [0, 1], labels=["height"])
    with pytest.raises(TypeError, match="labels must be strings"):
        hs.plot_flows(arc, 0, labels=[3])


@pytest.mark.parametrize("kw, exc, match", [
    ({"smooth": -1}, TypeError, "smooth must be True, False or a non-negative int"),
    ({"smooth": 2.5}, TypeError, "smooth must be"),
    ({"flow_kw": "red"}, TypeError, "flow_kw must be a dict"),
    ({"jump_kw": 1}, TypeError, "jump_kw must be a dict"),
    ({"yscale": "logarithmic"}, ValueError, "yscale must be one of"),
    ({"subplots": "yes"}, TypeError, "subplots must be True or False"),
    ({"markers": None}, TypeError, "markers must be True or False"),
    ({"label": "ball"}, TypeError, r"use labels=\[...\]"),
    ({"filter": lambda x: "maybe"}, TypeError, "filter must return one bool"),
    ({"filter": 3}, TypeError, "filter must be a callable"),
])
def test_bad_keywords_raise_naming_them(arc, kw, exc, match):
    with pytest.raises(exc, match=match):
        hs.plot_flows(arc, **kw)


def test_matplotlib_aliases_are_accepted():
    # ls/lw/c are matplotlib's short names: the plot's own defaults must not clash
    arc = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=1.5, j_max=2)
    ax = hs.plot_flows(arc, 0, ls="--", lw=3, c="k")
    (flow,) = [ln for ln in ax.lines if ln.get_gid() == "flows"]
    assert flow.get_linestyle() == "--" and flow.get_linewidth() == 3
    assert flow.get_color() == "k"
    plt.close(ax.figure)
