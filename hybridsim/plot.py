"""Plots in hybrid time. Every function returns its Axes, accepts ``ax=`` and
never calls ``plt.show()``."""
from __future__ import annotations

import numpy as np

__all__ = ["plot_flows", "plot_jumps", "plot_hybrid", "plot_phase", "plot_time_domain"]


def _axes(ax, projection=None):
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt
    fig = plt.figure()
    return fig.add_subplot(111, projection=projection)


def _values(arc, idx):
    """(N, k) values to plot and their labels; idx: None, int, list, callable,
    or a float array of values at the samples, shape (N,) or (N, k)."""
    if isinstance(idx, np.ndarray) and idx.dtype.kind == "f":
        if idx.shape[:1] != (len(arc.t),) or idx.ndim > 2:
            raise ValueError(f"idx: an array of values must have shape ({len(arc.t)},) or "
                             f"({len(arc.t)}, k), one row per sample; got {idx.shape}")
        v = idx.reshape(len(arc.t), -1)
        return v, [f"y{k}" for k in range(v.shape[1])]
    if callable(idx):
        v = np.asarray(arc.evaluate(idx), dtype=float)
        v = v.reshape(len(arc.t), -1)
        return v, [f"y{k}" for k in range(v.shape[1])]
    if idx is None:
        idx = list(range(arc.state_dim))
    idx = [idx] if np.ndim(idx) == 0 else list(idx)
    if not idx:
        raise ValueError("idx must select at least one component, got an empty list")
    for i in idx:
        _check_component("idx", i, arc.state_dim)
    return arc.x[:, idx], [f"x{i}" for i in idx]


def _check_component(name, i, n):
    if isinstance(i, (bool, np.bool_)) or not isinstance(i, (int, np.integer)):
        raise TypeError(f"{name} must be an int component index (or a list of them, or a "
                        f"callable), got {i!r}")
    if not (-n <= i < n):
        raise ValueError(f"{name}: component {i} out of range for a state of dimension {n}")


def _check_labels(labels, k):
    labels = list(labels)
    if len(labels) != k:
        raise ValueError(f"labels must have one entry per plotted component ({k}), "
                         f"got {len(labels)}")
    return labels


def _segments(arc):
    """Index ranges [a, b) of each interval of flow."""
    cut = np.concatenate(([0], arc.jump_index, [len(arc.t)]))
    return list(zip(cut[:-1], cut[1:]))


def plot_flows(arc, idx=None, *, ax=None, labels=None, jumps=True, **line_kw):
    """Each selected component against ordinary time t.

    Flows are solid lines; each jump is a dashed segment from the pre-jump to
    the post-jump value.

    Parameters
    ----------
    arc : HybridArc
    idx : int, list of int, callable or float array, optional
        State components to plot (default all), ``fn(x, t, j)`` giving the
        values to plot (an error, an output...), or those values already
        computed at the samples, shape (N,) or (N, k).
    ax : matplotlib Axes, optional
    labels : list of str, optional
    jumps : bool
        Draw the dashed jump segments.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax)
    v, default = _values(arc, idx)
    labels = default if labels is None else _check_labels(labels, v.shape[1])
    color0 = line_kw.pop("color", None)
    for k in range(v.shape[1]):
        color = color0
        for s, (a, b) in enumerate(_segments(arc)):
            (line,) = ax.plot(arc.t[a:b], v[a:b, k], color=color,
                              label=labels[k] if s == 0 else None, **line_kw)
            color = line.get_color()
        if jumps:
            for i in arc.jump_index:
                ax.plot([arc.t[i - 1], arc.t[i]], [v[i - 1, k], v[i, k]], ls="--",
                        color=color, lw=0.8)
    ax.set_xlabel("t")
    if v.shape[1] > 1 or labels != default:
        ax.legend()
    return ax


def plot_jumps(arc, idx=None, *, ax=None, labels=None, **line_kw):
    """Each selected component against the jump counter j.

    Values during a flow interval are drawn at its j (vertical marks); jumps
    are dashed segments from (j, pre-jump value) to (j + 1, post-jump value).
    """
    ax = _axes(ax)
    v, default = _values(arc, idx)
    labels = default if labels is None else _check_labels(labels, v.shape[1])
    for k in range(v.shape[1]):
        (line,) = ax.plot(arc.j, v[:, k], ".", label=labels[k], **line_kw)
        for i in arc.jump_index:
            ax.plot([arc.j[i - 1], arc.j[i]], [v[i - 1, k], v[i, k]], ls="--",
                    color=line.get_color(), lw=0.8)
    ax.set_xlabel("j")
    if v.shape[1] > 1:
        ax.legend()
    return ax


def plot_hybrid(arc, idx=0, *, ax=None, **line_kw):
    """One component in 3-D over the hybrid time domain: (t, j, x).

    ``idx`` is a state index or ``fn(x, t, j)`` returning a scalar.
    """
    import mpl_toolkits.mplot3d  # noqa: F401 - registers the 3d projection
    ax = _axes(ax, projection="3d")
    v, labels = _values(arc, idx)
    if v.shape[1] != 1:
        raise ValueError("plot_hybrid: idx must select one component")
    color = None
    for a, b in _segments(arc):
        (line,) = ax.plot(arc.t[a:b], arc.j[a:b], v[a:b, 0], color=color, **line_kw)
        color = line.get_color()
    for i in arc.jump_index:
        ax.plot([arc.t[i - 1]] * 2, [arc.j[i - 1], arc.j[i]], [v[i - 1, 0], v[i, 0]],
                ls="--", color=color, lw=0.8)
    ax.set_xlabel("t")
    ax.set_ylabel("j")
    ax.set_zlabel(labels[0])
    return ax


def plot_phase(arc, i=0, k=1, *, ax=None, **line_kw):
    """Component k against component i, flows solid and jumps dashed."""
    ax = _axes(ax)
    for c in (i, k):
        _check_component("plot_phase", c, arc.state_dim)
    color = None
    for a, b in _segments(arc):
        (line,) = ax.plot(arc.x[a:b, i], arc.x[a:b, k], color=color, **line_kw)
        color = line.get_color()
    for m in arc.jump_index:
        ax.plot(arc.x[m - 1:m + 1, i], arc.x[m - 1:m + 1, k], ls="--", color=color, lw=0.8)
    ax.set_xlabel(f"x{i}")
    ax.set_ylabel(f"x{k}")
    return ax


def plot_time_domain(arc, *, ax=None, **line_kw):
    """The hybrid time domain: each interval [t_j, t_{j+1}] x {j}."""
    ax = _axes(ax)
    for a, b, j in arc.flow_intervals:
        ax.plot([a, b], [j, j], "-", color=line_kw.get("color", "C0"), lw=2)
        ax.plot([a], [j], "o", color=line_kw.get("color", "C0"), ms=3)
    ax.set_xlabel("t")
    ax.set_ylabel("j")
    return ax
