r"""Plots of hybrid arcs in hybrid time (t, j).

Five functions share one set of keywords:

========================  ======================================================
:func:`plot_flows`        components (or ``fn`` of the state) against time t
:func:`plot_jumps`        the same against the jump counter j
:func:`plot_hybrid`       one component in 3-D over the hybrid time domain (t, j)
:func:`plot_phase`        one component against another
:func:`plot_time_domain`  the hybrid time domain itself: j against t
:func:`plot_solutions`    every leaf of :func:`hybridsim.explore` on one Axes
========================  ======================================================

Every function returns its Axes (``subplots=True``: an array of Axes), accepts
``ax=``, and never calls ``plt.show()``.

**Flows** are drawn smooth whatever the solver's step size: each interval
between stored samples is filled with points of the arc's own interpolant,
:meth:`HybridArc.at` (the solver's dense output when the run kept it, else
cubic Hermite with the flow derivative ``arc.xdot``, exact for polynomial
flows of degree <= 3). The stored samples, jump instants included, are drawn
exactly. **Jumps** are thin dotted segments from the pre-jump to the post-jump
value, in the colour of their flow, with a filled circle at the pre-jump
point and an open circle at the post-jump point: a dashed reference curve
drawn by the user stays distinguishable from them.

**Style** comes from matplotlib itself: line widths, marker sizes and the
colour cycle are read from ``rcParams`` at call time, so
``with plt.style.context("seaborn-v0_8-paper"):`` or ``plt.rc("lines",
linewidth=2)`` apply; ``flow_kw``, ``jump_kw``, ``start_kw`` and ``end_kw``
override the flows, jump segments and pre-/post-jump markers of one call.

**Artists.** For each plotted component one call adds at most four
``Line2D`` artists, told apart by their ``gid``: ``"flows"`` (all flow
intervals, separated by NaN), ``"jumps"`` (all jump segments, NaN-separated),
``"jump_starts"`` and ``"jump_ends"`` (the markers). Only the flows carry a
legend label.

Examples
--------
>>> import hybridsim as hs
>>> from hybridsim.library import BouncingBall
>>> arc = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=2.0)
>>> axs = hs.plot_flows(arc, subplots=True, labels=["height (m)", "velocity (m/s)"])
>>> [a.get_ylabel() for a in axs], axs[-1].get_xlabel()
(['height (m)', 'velocity (m/s)'], '$t$')
"""
from __future__ import annotations

import numpy as np

from ._plot_sample import (
    _axes,
    _axes_array,
    _check_arc,
    _check_bool,
    _check_component,
    _check_kw,
    _check_labels,
    _check_smooth,
    _check_yscale,
    _component_names,
    _eval_fn,
    _sample,
)

__all__ = ["plot_flows", "plot_jumps", "plot_hybrid", "plot_phase", "plot_time_domain",
           "plot_solutions"]

T_LABEL, J_LABEL = "$t$", "$j$"


# --------------------------------------------------------------------------
# drawing
# --------------------------------------------------------------------------
def _styles(flow_kw, jump_kw, start_kw, end_kw, line_kw, where):
    from matplotlib.cbook import normalize_kwargs
    from matplotlib.lines import Line2D

    def norm(kw, name):
        # matplotlib's aliases (ls, lw, c, ms...) to their full names; unknown
        # properties named here, not by matplotlib at the first draw
        kw = normalize_kwargs(kw, Line2D)
        bad = [k for k in kw if k not in ("label", "labels")
               and not callable(getattr(Line2D, f"set_{k}", None))]
        if bad:
            raise TypeError(f"{where}: {name} has {', '.join(map(repr, bad))}, which "
                            f"{'is not a' if len(bad) == 1 else 'are not'} matplotlib Line2D "
                            f"propert{'y' if len(bad) == 1 else 'ies'} (e.g. color, "
                            f"linewidth, linestyle, marker, markersize, alpha)")
        return kw
    flow_kw = norm(_check_kw("flow_kw", flow_kw, where), "flow_kw")
    jump_kw = norm(_check_kw("jump_kw", jump_kw, where), "jump_kw")
    start_kw = norm(_check_kw("start_kw", start_kw, where), "start_kw")
    end_kw = norm(_check_kw("end_kw", end_kw, where), "end_kw")
    line_kw.update(norm({k: line_kw.pop(k) for k in list(line_kw)}, "**line_kw"))
    for bad in ("label", "labels"):
        if bad in line_kw:
            raise TypeError(f"{where}: use labels=[...] to name the plotted components, "
                            f"not {bad}=")
    common = {k: line_kw.pop(k) for k in ("color", "zorder", "alpha") if k in line_kw}
    return ({**common, **line_kw, **flow_kw}, {**common, **jump_kw},
            {**common, **start_kw}, {**common, **end_kw})


def _draw(ax, flow_xyz, jump_pre, jump_post, label, styles, jumps, markers):
    """Draw one component: flows, jump segments, pre-/post-jump markers.

    flow_xyz: tuple of (M,) coordinate arrays; jump_pre/jump_post: tuples
    of (J,) coordinates of the visible jumps' ends.
    """
    import matplotlib as mpl
    flow_st, jump_st, start_st, end_st = styles
    lw = mpl.rcParams["lines.linewidth"]
    ms = mpl.rcParams["lines.markersize"]
    # round caps: flow intervals meeting at a jump that does not move the
    # value join without the notch of projecting caps
    (line,) = ax.plot(*flow_xyz, **{"linestyle": "-", "solid_capstyle": "round", **flow_st},
                      label=label, gid="flows")
    color = line.get_color()
    lines = [line]
    if jumps and len(jump_pre[0]):
        # a jump that leaves the drawn coordinates unchanged (to 1e-9 of their
        # range) has no segment, only markers: a dotted line of length 0
        # would still leave a dot
        moves = np.zeros(len(jump_pre[0]), bool)
        for f, a, b in zip(flow_xyz, jump_pre, jump_post):
            span = np.concatenate([np.ravel(f), a, b]).astype(float)
            span = span[np.isfinite(span)]
            tol = 1e-9 * (span.max() - span.min()) if span.size else 0.0
            moves |= np.abs(a - b) > tol
        nan = np.full(int(moves.sum()), np.nan)
        seg = [np.column_stack([a[moves], b[moves], nan]).ravel()
               for a, b in zip(jump_pre, jump_post)]
        jst = {"color": color, "linestyle": ":", "linewidth": 0.8 * lw, **jump_st}
        lines += ax.plot(*seg, **jst, label="_jumps", gid="jumps")
        if markers:
            c = start_st.get("color", jst["color"])
            sst = {"marker": "o", "markersize": 0.5 * ms, "color": c,
                   "markerfacecolor": c, "markeredgecolor": c, **start_st,
                   "linestyle": "none"}
            lines += ax.plot(*jump_pre, **sst, label="_jump_starts", gid="jump_starts")
            c = end_st.get("color", jst["color"])
            est = {"marker": "o", "markersize": 0.5 * ms, "color": c,
                   "markerfacecolor": "none", "markeredgecolor": c,
                   "markeredgewidth": 0.8 * lw, **end_st, "linestyle": "none"}
            lines += ax.plot(*jump_post, **est, label="_jump_ends", gid="jump_ends")
    return lines


def _finish(ax, xlabel, ylabel, legend, yscale):
    ax.set_xlabel(xlabel)
    if ylabel is not None:
        ax.set_ylabel(ylabel)
    if yscale is not None:
        ax.set_yscale(yscale)
    if legend:
        handles, _ = ax.get_legend_handles_labels()
        if handles:
            ax.legend()


def _line_plot(arc, idx, *, where, axis, ax, labels, subplots, fn, filter, jumps,
               markers, smooth, flow_kw, jump_kw, start_kw, end_kw, legend, xlabel,
               ylabel, yscale, line_kw):
    """plot_flows and plot_jumps: values against t (axis "t") or j (axis "j")."""
    _check_arc(arc, where)
    subplots = _check_bool("subplots", subplots, where)
    jumps = _check_bool("jumps", jumps, where)
    markers = _check_bool("markers", markers, where)
    legend = _check_bool("legend", legend, where)
    smooth = _check_smooth(smooth, where)
    yscale = _check_yscale(yscale, where)
    if not subplots and ax is not None:
        _axes(ax, where)                          # check before the work
    styles = _styles(flow_kw, jump_kw, start_kw, end_kw, line_kw, where)
    s = _sample(arc, idx, fn, smooth, filter, where)
    names = s.names if labels is None else _check_labels(labels, s.k, where)
    coord = s.t if axis == "t" else np.where(np.isnan(s.t), np.nan, s.j.astype(float))
    xl = (T_LABEL if axis == "t" else J_LABEL) if xlabel is None else xlabel
    pre = s.sample_pos[s.pre[s.shown]]
    post = s.sample_pos[s.post[s.shown]]
    if axis == "t":
        jx_pre, jx_post = coord[pre], coord[post]
    else:
        jx_pre, jx_post = arc.j[s.pre[s.shown]].astype(float), arc.j[s.post[s.shown]].astype(
            float)
    if subplots:
        axs = _axes_array(ax, s.k, where)
        if ylabel is not None and not isinstance(ylabel, str):
            ylabel = _check_labels(ylabel, s.k, where)
        for c, a in enumerate(axs):
            v = s.v[:, c]
            _draw(a, (coord, v), (jx_pre, v[pre]), (jx_post, v[post]), names[c], styles,
                  jumps, markers)
            yl = names[c] if ylabel is None else ylabel if isinstance(ylabel, str) \
                else ylabel[c]
            _finish(a, xl if c == len(axs) - 1 and _at_bottom(a) else "", yl, legend, yscale)
            if axis == "j":
                _integer_ticks(a.xaxis)
        return axs
    ax = _axes(ax, where)
    for c in range(s.k):
        v = s.v[:, c]
        _draw(ax, (coord, v), (jx_pre, v[pre]), (jx_post, v[post]), names[c], styles, jumps,
              markers)
    if ylabel is None:
        ylabel = ", ".join(names)
    elif not isinstance(ylabel, str):
        raise TypeError(f"{where}: ylabel must be a str, got {type(ylabel).__name__}")
    _finish(ax, xl, ylabel, legend, yscale)
    if axis == "j":
        _integer_ticks(ax.xaxis)
    return ax


def _at_bottom(ax):
    """False for an Axes with another subplot of its grid below it."""
    spec = ax.get_subplotspec() if hasattr(ax, "get_subplotspec") else None
    return spec is None or spec.is_last_row()


def _integer_ticks(axis):
    from matplotlib.ticker import MaxNLocator
    axis.set_major_locator(MaxNLocator(integer=True))


_COMMON_DOC = """
    ax : matplotlib Axes, optional
        Where to draw (default: a new figure). With ``subplots=True``, a
        sequence of one Axes per plotted component.
    labels : list of str, optional
        One name per plotted component, used in the legend and the y label
        (default: ``$x_1$, $x_2$...``, 1-based, or the parts' names of an
        interconnection; ``$y$`` / ``$y_k$`` or the function's name for ``fn``).
    subplots : bool, default False
        One subplot per component, sharing the horizontal axis (x label on
        the last Axes only, and only when no subplot of its grid lies below
        it); an array of Axes is returned.
    fn : callable, optional
        Plot ``fn(x)``, ``fn(x, t)`` or ``fn(x, t, j)`` (a float or a 1-D
        array) instead of the state, evaluated at every plotted point (an
        error norm, an energy...). ``idx`` then selects among its outputs.
    filter : callable or bool array, optional
        ``filter(x, t, j)`` -> bool, or a mask of shape (N,) over the stored
        samples: points where it is False are hidden (flows are cut there),
        and a jump is drawn only when both its ends are shown.
    jumps : bool, default True
        Draw the jump segments (and their markers). A jump that does not
        change the plotted value gets its markers but no segment.
    markers : bool, default True
        Mark each jump's start (filled circle) and end (open circle).
    smooth : bool or int, default True
        Points of the arc's interpolant inserted between stored samples:
        True picks up to 20 per step (fewer on arcs of many samples, none
        past 50,000), an int that many, False none (a polyline through the
        samples).
    flow_kw, jump_kw, start_kw, end_kw : dict, optional
        ``Line2D`` properties of the flows, the jump segments, the pre-jump
        and the post-jump markers (default jump style: dotted, 0.8 x the
        rcParams line width, the flow's colour; markers half the rcParams
        marker size).
    legend : bool, default True
        Add a legend (also for a single component).
    xlabel, ylabel : str, optional
        Axis labels (default ``$t$`` / ``$j$`` and the components' names;
        with ``subplots=True`` ylabel may be a list, one per Axes).
    yscale : str, optional
        ``"log"``, ``"symlog"``... for the value axis.
    **line_kw
        Further ``Line2D`` properties of the flows; ``color``, ``alpha`` and
        ``zorder`` apply to the jumps and markers too.
"""


def plot_flows(arc, idx=None, *, ax=None, labels=None, subplots=False, fn=None,
               filter=None, jumps=True, markers=True, smooth=True, flow_kw=None,
               jump_kw=None, start_kw=None, end_kw=None, legend=True, xlabel=None,
               ylabel=None, yscale=None, **line_kw):
    r"""Selected components (or a function of the state) against ordinary time t.

    Flows are solid and smooth (see the module notes); each jump is a thin
    dotted vertical segment from the pre-jump value (filled circle) to the
    post-jump value (open circle), at the exact jump time.

    Parameters
    ----------
    arc : HybridArc
        The solution to draw (from :func:`hybridsim.simulate`).
    idx : int, list of int, callable or float array, optional
        State components to plot (default all, negative counts from the end),
        ``fn(x, t, j)`` (as ``fn=``), or values already computed at the
        samples, shape (N,) or (N, k) (drawn through the samples only).
    %s
    Returns
    -------
    matplotlib.axes.Axes, or ndarray of Axes with ``subplots=True``
        The Axes drawn on.

    Raises
    ------
    TypeError, ValueError
        For an argument of the wrong type or value, naming it.

    Examples
    --------
    >>> import hybridsim as hs
    >>> from hybridsim.library import BouncingBall
    >>> arc = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=2.0)
    >>> ax = hs.plot_flows(arc, 1, labels=["velocity (m/s)"])
    >>> ax.get_xlabel(), ax.get_ylabel(), ax.get_legend().get_texts()[0].get_text()
    ('$t$', 'velocity (m/s)', 'velocity (m/s)')
    >>> [ln.get_gid() for ln in ax.lines]
    ['flows', 'jumps', 'jump_starts', 'jump_ends']
    >>> ax = hs.plot_flows(arc, fn=lambda x: 9.81 * x[0] + x[1] ** 2 / 2, yscale="log",
    ...                    labels=["energy (J/kg)"])
    """
    return _line_plot(arc, idx, where="plot_flows", axis="t", ax=ax, labels=labels,
                      subplots=subplots, fn=fn, filter=filter, jumps=jumps, markers=markers,
                      smooth=smooth, flow_kw=flow_kw, jump_kw=jump_kw, start_kw=start_kw,
                      end_kw=end_kw, legend=legend, xlabel=xlabel, ylabel=ylabel,
                      yscale=yscale, line_kw=line_kw)


def plot_jumps(arc, idx=None, *, ax=None, labels=None, subplots=False, fn=None,
               filter=None, jumps=True, markers=True, smooth=True, flow_kw=None,
               jump_kw=None, start_kw=None, end_kw=None, legend=True, xlabel=None,
               ylabel=None, yscale=None, **line_kw):
    r"""Selected components (or a function of the state) against the jump counter j.

    The values taken during the flow of jump count j form a solid vertical
    line at j (the range the component sweeps, extremes inside a step
    included); each jump is a dotted segment from (j, pre-jump value) to
    (j + 1, post-jump value), with the jump markers.

    Parameters
    ----------
    arc : HybridArc
        The solution to draw.
    idx : int, list of int, callable or float array, optional
        As in :func:`plot_flows`.
    %s
    Returns
    -------
    matplotlib.axes.Axes, or ndarray of Axes with ``subplots=True``
        The Axes drawn on.

    Examples
    --------
    >>> import hybridsim as hs
    >>> from hybridsim.library import BouncingBall
    >>> arc = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=2.0)
    >>> ax = hs.plot_jumps(arc, 1)
    >>> ax.get_xlabel(), ax.get_ylabel()
    ('$j$', '$x_2$')
    """
    return _line_plot(arc, idx, where="plot_jumps", axis="j", ax=ax, labels=labels,
                      subplots=subplots, fn=fn, filter=filter, jumps=jumps, markers=markers,
                      smooth=smooth, flow_kw=flow_kw, jump_kw=jump_kw, start_kw=start_kw,
                      end_kw=end_kw, legend=legend, xlabel=xlabel, ylabel=ylabel,
                      yscale=yscale, line_kw=line_kw)


plot_flows.__doc__ = plot_flows.__doc__ % (_COMMON_DOC.strip("\n").lstrip() + "\n")
plot_jumps.__doc__ = plot_jumps.__doc__ % (_COMMON_DOC.strip("\n").lstrip() + "\n")


def _single_label(labels, default, where):
    if labels is None:
        return default
    return _check_labels(labels, 1, where)[0]


def plot_hybrid(arc, idx=0, *, ax=None, labels=None, fn=None, filter=None, jumps=True,
                markers=True, smooth=True, flow_kw=None, jump_kw=None, start_kw=None,
                end_kw=None, legend=False, xlabel=None, ylabel=None, zlabel=None,
                **line_kw):
    r"""One component (or a scalar function of the state) in 3-D over (t, j).

    Flows run along t at constant j; each jump is a dotted segment from
    (t, j, pre-jump value) to (t, j + 1, post-jump value), with the jump
    markers.

    Parameters
    ----------
    arc : HybridArc
        The solution to draw.
    idx : int or callable, default 0
        The state component, or ``fn(x, t, j)`` returning a scalar.
    ax : 3-D matplotlib Axes, optional
        ``fig.add_subplot(projection="3d")``; default a new figure's.
    labels : str or list of one str, optional
        The component's name (z label and legend entry).
    fn, filter, jumps, markers, smooth, flow_kw, jump_kw, start_kw, end_kw : optional
        As in :func:`plot_flows`.
    legend : bool, default False
        Add a legend (the z label already names the component).
    xlabel, ylabel, zlabel : str, optional
        Default ``$t$``, ``$j$`` and the component's name.
    **line_kw
        Further ``Line2D`` properties of the flows.

    Returns
    -------
    mpl_toolkits.mplot3d.Axes3D
        The 3-D Axes drawn on.

    Examples
    --------
    >>> import hybridsim as hs
    >>> from hybridsim.library import Timer
    >>> arc = hs.simulate(Timer(1.0), [0.0], t_max=2.5)
    >>> ax = hs.plot_hybrid(arc, labels=[r"$\tau$"])
    >>> ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()
    ('$t$', '$j$', '$\\tau$')
    """
    where = "plot_hybrid"
    _check_arc(arc, where)
    for name, v in (("jumps", jumps), ("markers", markers), ("legend", legend)):
        _check_bool(name, v, where)
    smooth = _check_smooth(smooth, where)
    ax = _axes(ax, where, projection="3d")
    styles = _styles(flow_kw, jump_kw, start_kw, end_kw, line_kw, where)
    s = _sample(arc, idx, fn, smooth, filter, where)
    if s.k != 1:
        raise ValueError("plot_hybrid: idx must select one component")
    name = _single_label(labels, s.names[0], where)
    jf = np.where(np.isnan(s.t), np.nan, s.j.astype(float))
    v = s.v[:, 0]
    pre = s.sample_pos[s.pre[s.shown]]
    post = s.sample_pos[s.post[s.shown]]
    _draw(ax, (s.t, jf, v), (s.t[pre], jf[pre], v[pre]), (s.t[post], jf[post], v[post]),
          name, styles, jumps, markers)
    ax.set_zlabel(name if zlabel is None else zlabel)
    _finish(ax, T_LABEL if xlabel is None else xlabel, J_LABEL if ylabel is None else ylabel,
            legend, None)
    _integer_ticks(ax.yaxis)
    return ax


def plot_phase(arc, i=0, k=1, *, ax=None, labels=None, fn=None, filter=None, jumps=True,
               markers=True, smooth=True, flow_kw=None, jump_kw=None, start_kw=None,
               end_kw=None, label=None, legend=None, xlabel=None, ylabel=None,
               xscale=None, yscale=None, **line_kw):
    r"""Component k against component i: the arc in the phase plane.

    Flows are solid and smooth, jumps dotted segments from the pre-jump
    point (filled circle) to the post-jump point (open circle).

    Parameters
    ----------
    arc : HybridArc
        The solution to draw.
    i, k : int, default 0 and 1
        The components on the horizontal and vertical axes (of the state, or
        of ``fn``'s output); they must differ.
    ax : matplotlib Axes, optional
        Where to draw (default: a new figure).
    labels : list of two str, optional
        Names of components i and k: the axis labels (default ``$x_{i+1}$``,
        ``$x_{k+1}$`` or the parts' names of an interconnection).
    fn : callable, optional
        ``fn(x, t, j)`` returning a 1-D array whose components i and k are
        plotted (e.g. an error in two coordinates).
    filter, jumps, markers, smooth, flow_kw, jump_kw, start_kw, end_kw : optional
        As in :func:`plot_flows`.
    label : str, optional
        The curve's legend entry.
    legend : bool, optional
        Add a legend; default: when ``label`` is given.
    xlabel, ylabel : str, optional
        Override the axis labels.
    xscale, yscale : str, optional
        Axis scales (``"log"``...).
    **line_kw
        Further ``Line2D`` properties of the flows.

    Returns
    -------
    matplotlib.axes.Axes
        The Axes drawn on.

    Examples
    --------
    >>> import hybridsim as hs
    >>> from hybridsim.library import BouncingBall
    >>> arc = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=2.0)
    >>> ax = hs.plot_phase(arc, 0, 1, labels=["height (m)", "velocity (m/s)"])
    >>> ax.get_xlabel(), ax.get_ylabel()
    ('height (m)', 'velocity (m/s)')
    """
    where = "plot_phase"
    _check_arc(arc, where)
    for name, v in (("jumps", jumps), ("markers", markers)):
        _check_bool(name, v, where)
    if legend is None:
        legend = label is not None
    _check_bool("legend", legend, where)
    if label is not None and not isinstance(label, str):
        raise TypeError(f"{where}: label must be a str, got {type(label).__name__}")
    smooth = _check_smooth(smooth, where)
    xscale, yscale = _check_yscale(xscale, where), _check_yscale(yscale, where)
    if ax is not None:
        _axes(ax, where)
    if fn is None:
        n = arc.state_dim
        i, k = _check_component(where, i, n), _check_component(where, k, n)
        if i == k:
            raise ValueError(f"{where}: i and k must be two different components, got "
                             f"i = k = {i} (plot_flows draws one component against t)")
        s = _sample(arc, [i, k], None, smooth, filter, where)
    else:
        if callable(fn):
            from .system import as_map
            try:
                as_map(fn, "fn")
            except TypeError as e:
                raise TypeError(f"{where}: {e}") from None
        s = _sample(arc, None, fn, smooth, filter, where)
        for name, c in (("i", i), ("k", k)):
            if isinstance(c, (bool, np.bool_)) or not isinstance(c, (int, np.integer)):
                raise TypeError(f"{where}: {name} must be an int index into fn's output, got "
                                f"{c!r}")
            if not -s.k <= c < s.k:
                raise ValueError(f"{where}: {name}={c} selects an output of fn, which returns "
                                 f"{s.k} value{'s' if s.k != 1 else ''} per sample: fn must "
                                 f"return at least two (plot_phase draws output k against "
                                 f"output i)" if s.k < 2 else
                                 f"{where}: {name}={c} is out of range for fn's {s.k} outputs")
        i, k = int(i) % s.k, int(k) % s.k
        if i == k:
            raise ValueError(f"{where}: i and k must be two different outputs of fn, got "
                             f"i = k = {i}")
        s.v, s.names = s.v[:, [i, k]], [s.names[i], s.names[k]]
    names = s.names if labels is None else _check_labels(
        labels, 2, where, "axis (components i and k)")
    ax = _axes(ax, where)
    styles = _styles(flow_kw, jump_kw, start_kw, end_kw, line_kw, where)
    a, b = s.v[:, 0], s.v[:, 1]
    pre = s.sample_pos[s.pre[s.shown]]
    post = s.sample_pos[s.post[s.shown]]
    _draw(ax, (a, b), (a[pre], b[pre]), (a[post], b[post]),
          "_nolegend_" if label is None else label, styles, jumps, markers)
    if xscale is not None:
        ax.set_xscale(xscale)
    _finish(ax, names[0] if xlabel is None else xlabel, names[1] if ylabel is None else ylabel,
            legend, yscale)
    return ax


def plot_time_domain(arc, *, ax=None, labels=None, filter=None, jumps=True, markers=True,
                     flow_kw=None, jump_kw=None, start_kw=None, end_kw=None, legend=None,
                     xlabel=None, ylabel=None, **line_kw):
    r"""The hybrid time domain: each interval [t_j, t_{j+1}] x {j}, j against t.

    Flow intervals are solid horizontal segments at height j; each jump is a
    dotted vertical segment from (t, j) to (t, j + 1) with the jump markers.
    A jump count whose interval has no length shows as its markers only.

    Parameters
    ----------
    arc : HybridArc
        The solution whose domain is drawn.
    ax : matplotlib Axes, optional
        Where to draw (default: a new figure).
    labels : str or list of one str, optional
        Legend entry of the domain (e.g. when several arcs share the Axes).
    filter : callable or bool array, optional
        As in :func:`plot_flows`: hides the parts of the domain where it is
        False.
    jumps, markers, flow_kw, jump_kw, start_kw, end_kw : optional
        As in :func:`plot_flows` (default: 1.5 x the rcParams line width).
    legend : bool, optional
        Add a legend; default: when ``labels`` is given.
    xlabel, ylabel : str, optional
        Default ``$t$`` and ``$j$``.
    **line_kw
        Further ``Line2D`` properties of the flow intervals.

    Returns
    -------
    matplotlib.axes.Axes
        The Axes drawn on.

    Examples
    --------
    >>> import hybridsim as hs
    >>> from hybridsim.library import Timer
    >>> arc = hs.simulate(Timer(1.0), [0.0], t_max=2.5)
    >>> ax = hs.plot_time_domain(arc)
    >>> ax.get_xlabel(), ax.get_ylabel(), ax.lines[0].get_gid()
    ('$t$', '$j$', 'flows')
    """
    import matplotlib as mpl
    where = "plot_time_domain"
    _check_arc(arc, where)
    for name, v in (("jumps", jumps), ("markers", markers)):
        _check_bool(name, v, where)
    name = _single_label(labels, "_nolegend_", where)
    if legend is None:
        legend = labels is not None
    _check_bool("legend", legend, where)
    ax = _axes(ax, where)
    flow_kw = {"linewidth": 1.5 * mpl.rcParams["lines.linewidth"],
               **_check_kw("flow_kw", flow_kw, where)}
    styles = _styles(flow_kw, jump_kw, start_kw, end_kw, line_kw, where)
    s = _sample(arc, None, None, 0 if not callable(filter) else True, filter, where,
                values=False)
    jf = np.where(s.keep & ~np.isnan(s.t), s.j.astype(float), np.nan)
    pre = s.sample_pos[s.pre[s.shown]]
    post = s.sample_pos[s.post[s.shown]]
    _draw(ax, (s.t, jf), (s.t[pre], jf[pre]), (s.t[post], jf[post]), name, styles, jumps,
          markers)
    _finish(ax, T_LABEL if xlabel is None else xlabel, J_LABEL if ylabel is None else ylabel,
            legend, None)
    _integer_ticks(ax.yaxis)
    return ax


def plot_solutions(tree, idx=0, *, view="flows", fn=None, ax=None, label=None, color=None,
                   alpha=0.6, branch_kw=None, ylabel=None, **line_kw):
    r"""Every solution of an exploration on one Axes, its branch points marked.

    Each leaf of ``tree`` is drawn by :func:`plot_flows` (``view="flows"``:
    component ``idx``, or output ``idx`` of ``fn``, against t),
    :func:`plot_jumps` (``"jumps"``: against j) or :func:`plot_time_domain`
    (``"domain"``: the hybrid time domain), all in one colour; the branch
    points (where the tree splits) are drawn once, on the curves, as black
    diamonds (``Line2D`` with gid ``"branch_points"``, labelled "branch
    points").

    Parameters
    ----------
    tree : SolutionTree or iterable of HybridArc
        From :func:`hybridsim.explore` (branch points drawn), or any arcs.
    idx : int
        The state component, or with ``fn`` the output of ``fn`` (views
        "flows" and "jumps").
    view : {"flows", "jumps", "domain"}
    fn : callable, optional
        Views "flows" and "jumps": plot ``fn(x)``, ``fn(x, t)`` or
        ``fn(x, t, j)`` (a float or a 1-D array, as in :func:`plot_flows`)
        instead of the state; the branch points are drawn at ``fn`` of their
        state. Refused with ``view="domain"``.
    ax : matplotlib Axes, optional
        Where to draw (default: a new figure).
    label : str, optional
        Legend entry of the solutions (default: "N solutions").
    color : color, optional
        Of every leaf (default ``"C0"``, the first colour of the cycle).
    alpha : float
        Of the leaves' lines (overlapping leaves show darker).
    branch_kw : dict, optional
        ``Line2D`` properties of the branch points' markers.
    ylabel : str, optional
        The value axis' label (default: the component's name, ``$x_1$``...,
        or ``fn``'s; ``$j$`` for the domain).
    **line_kw
        Passed to the per-leaf plot function (``flow_kw``, ``smooth``,
        ``filter``, ``Line2D`` properties...).

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    TypeError, ValueError
        For an argument of the wrong type or value, naming it.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> timer = hs.HybridSystem.from_functions(
    ...     flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
    ...     flow_set=lambda x: x[0] <= 2.0, jump_set=lambda x: x[0] >= 1.0, state_dim=1)
    >>> tree = hs.explore(timer, [0.0], t_max=5.0, j_max=2, merge_tol=None)
    >>> ax = hs.plot_solutions(tree)
    >>> ax.get_legend().get_texts()[0].get_text(), ax.get_ylabel()
    ('4 solutions', '$x_1$')
    >>> bp = [ln for ln in ax.lines if ln.get_gid() == "branch_points"][0]
    >>> bp.get_xdata(), bp.get_ydata()
    (array([1., 2., 3.]), array([1., 1., 1.]))
    >>> ax = hs.plot_solutions(tree, fn=lambda x: x[0] ** 2, ylabel="tau squared")
    >>> ax.get_ylabel()
    'tau squared'
    """
    where = "plot_solutions"
    views = {"flows": plot_flows, "jumps": plot_jumps, "domain": plot_time_domain}
    if view not in views:
        raise ValueError(f"{where}: view must be one of {sorted(views)}, got {view!r}")
    leaves = list(tree)
    if not leaves:
        raise ValueError(f"{where}: tree has no solution to draw")
    for a in leaves:
        _check_arc(a, where)
    branch_kw = _check_kw("branch_kw", branch_kw, where)
    if label is not None and not isinstance(label, str):
        raise TypeError(f"{where}: label must be a str, got {type(label).__name__}")
    if ylabel is not None and not isinstance(ylabel, str):
        raise TypeError(f"{where}: ylabel must be a str, got {type(ylabel).__name__}")
    if fn is not None and view == "domain":
        raise TypeError(f"{where}: fn= applies to the views 'flows' and 'jumps', not "
                        f"'domain' (which draws j against t)")
    if fn is not None and not callable(fn):
        raise TypeError(f"{where}: fn must be a callable fn(x), fn(x, t) or fn(x, t, j), "
                        f"got {type(fn).__name__}")
    if view != "domain" and not (isinstance(idx, (int, np.integer)) and not isinstance(
            idx, bool)):
        raise TypeError(f"{where}: idx must be an int (one component, or one output of fn), "
                        f"got {type(idx).__name__}")
    ax = _axes(ax, where)
    if color is None:
        color = "C0"
    label = f"{len(leaves)} solutions" if label is None else label
    # the branch points, on the plotted curves: (x coordinate, value)
    bp = list(getattr(tree, "branch_points", []))
    if view == "domain":
        bx = np.array([p[0] for p in bp], dtype=float)
        by = np.array([p[1] for p in bp], dtype=float)
    else:
        bx = np.array([p[0] if view == "flows" else p[1] for p in bp], dtype=float)
        if fn is None:
            i = _check_component("idx", idx, leaves[0].state_dim)
            by = np.array([p[2][i] for p in bp], dtype=float)
            default_y = _component_names(leaves[0])[i]
        else:
            from .system import as_map
            f = as_map(fn, "fn")
            a0 = leaves[0]
            X = np.array([a0.x[0], *[p[2] for p in bp]], dtype=float)
            T = np.array([a0.t[0], *[p[0] for p in bp]], dtype=float)
            J = np.array([a0.j[0], *[p[1] for p in bp]], dtype=np.int64)
            V, names = _eval_fn(f, X, T, J, np.ones(len(X), bool), fn, where)
            i = _check_component("idx", idx, V.shape[1])
            by, default_y = V[1:, i], names[i]
        if ylabel is None:
            ylabel = default_y
    for k, a in enumerate(leaves):
        kw = dict(ax=ax, color=color, alpha=alpha, legend=False, **line_kw)
        name = [label if k == 0 else "_nolegend_"]
        if view == "domain":
            views[view](a, labels=name, ylabel=ylabel, **kw)
        else:
            if fn is not None:
                kw["fn"] = fn
            views[view](a, idx, labels=name, ylabel=ylabel, **kw)
    if bp:
        st = {"marker": "D", "color": "k", "markersize": 5, "linestyle": "none",
              "zorder": 3, **branch_kw}
        ax.plot(bx, by, label="branch points", gid="branch_points", **st)
    ax.legend()
    return ax
