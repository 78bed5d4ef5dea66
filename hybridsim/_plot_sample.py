"""The data of :mod:`hybridsim.plot`: its argument checks, the default names
of an arc's components, and the arc resampled for drawing (stored samples
exactly, points of the arc's interpolant inside each step, NaN between flow
intervals, ``fn`` and the filter applied).
"""
from __future__ import annotations

import numbers

import numpy as np

#: Points inserted inside each interval between stored samples (smooth=True).
_POINTS_PER_STEP = 20
#: Cap on the plotted points per call (smooth=True): long arcs get fewer
#: inserted points per step, arcs of more samples than this none.
_MAX_POINTS = 50_000


# --------------------------------------------------------------------------
# argument checks
# --------------------------------------------------------------------------
def _check_arc(arc, where):
    from .arc import HybridArc
    if not isinstance(arc, HybridArc):
        raise TypeError(f"{where}: arc must be a HybridArc (the result of hs.simulate), "
                        f"got {type(arc).__name__}")
    if len(arc.t) == 0:
        raise ValueError(f"{where}: arc is empty (no samples): nothing to plot")


def _is_axes(ax, projection=None):
    from matplotlib.axes import Axes
    if not isinstance(ax, Axes):
        return False
    return projection is None or getattr(ax, "name", None) == projection


def _axes(ax, where, projection=None):
    """The Axes to draw on: ``ax`` checked, or a new figure's."""
    if ax is not None:
        if not _is_axes(ax):
            raise TypeError(f"{where}: ax must be a matplotlib Axes, got "
                            f"{type(ax).__name__}")
        if projection == "3d" and not _is_axes(ax, "3d"):
            raise ValueError(f"{where}: ax must be a 3-D Axes (fig.add_subplot(projection="
                             f"'3d')), got a {getattr(ax, 'name', '2-D')!r} Axes")
        return ax
    import matplotlib.pyplot as plt
    if projection == "3d":
        import mpl_toolkits.mplot3d  # noqa: F401 - registers the 3d projection
    fig = plt.figure()
    return fig.add_subplot(111, projection=projection)


def _axes_array(ax, k, where):
    """k Axes sharing t, one per component (``subplots=True``)."""
    if ax is None:
        import matplotlib.pyplot as plt
        w, h = plt.rcParams["figure.figsize"]
        _fig, axs = plt.subplots(k, 1, sharex=True, squeeze=False,
                                figsize=(w, h * max(1.0, 0.45 * k)))
        return axs[:, 0]
    axs = [ax] if _is_axes(ax) else ax
    try:
        axs = list(np.ravel(np.asarray(axs, dtype=object)))
    except TypeError:
        axs = None
    if axs is None or not all(_is_axes(a) for a in axs):
        raise TypeError(f"{where}: with subplots=True, ax must be a sequence of {k} "
                        f"matplotlib Axes (one per component), got {type(ax).__name__}")
    if len(axs) != k:
        raise ValueError(f"{where}: with subplots=True, ax must hold one Axes per plotted "
                         f"component ({k}), got {len(axs)}")
    return np.array(axs, dtype=object)


def _check_kw(name, kw, where):
    if kw is None:
        return {}
    if not isinstance(kw, dict):
        raise TypeError(f"{where}: {name} must be a dict of matplotlib Line2D properties "
                        f"or None, got {type(kw).__name__}")
    return dict(kw)


def _check_bool(name, v, where):
    if not isinstance(v, (bool, np.bool_)):
        raise TypeError(f"{where}: {name} must be True or False, got {v!r}")
    return bool(v)


def _check_smooth(smooth, where):
    if isinstance(smooth, (bool, np.bool_)):
        return bool(smooth)
    if isinstance(smooth, numbers.Integral) and smooth >= 0:
        return int(smooth)
    raise TypeError(f"{where}: smooth must be True, False or a non-negative int (points "
                    f"inserted in each step), got {smooth!r}")


def _check_yscale(yscale, where):
    if yscale is None:
        return None
    from matplotlib.scale import get_scale_names
    if not isinstance(yscale, str) or yscale not in get_scale_names():
        raise ValueError(f"{where}: yscale must be one of {get_scale_names()} or None, "
                         f"got {yscale!r}")
    return yscale


def _check_component(name, i, n):
    if isinstance(i, (bool, np.bool_)) or not isinstance(i, (int, np.integer)):
        raise TypeError(f"{name} must be an int component index (or a list of them, or a "
                        f"callable), got {i!r}")
    if not (-n <= i < n):
        raise ValueError(f"{name}: component {i} out of range for a state of dimension {n}")
    return int(i) % n


def _check_labels(labels, k, where, what="plotted component"):
    if isinstance(labels, str):
        labels = [labels]
    try:
        labels = list(labels)
    except TypeError:
        raise TypeError(f"{where}: labels must be a list of str (one per {what}), got "
                        f"{type(labels).__name__}") from None
    if len(labels) != k:
        raise ValueError(f"{where}: labels must have one entry per {what} ({k}), got "
                         f"{len(labels)}")
    for s in labels:
        if not isinstance(s, str):
            raise TypeError(f"{where}: labels must be strings, got {s!r}")
    return labels


# --------------------------------------------------------------------------
# names and values
# --------------------------------------------------------------------------
def _math_sub(base, k):
    """``base`` with subscript k: ``$x_1$``, ``$x_{12}$``."""
    sub = str(k) if k < 10 else "{" + str(k) + "}"
    return f"${base}_{sub}$"


def _component_names(arc):
    """Default names of the state components: LaTeX-friendly, 1-based.

    ``$x_1$, $x_2$, ...``; for an arc of an interconnection (``arc.components``),
    each part's name, subscripted 1-based when the part has several components.

    Examples
    --------
    >>> from hybridsim import HybridArc
    >>> _component_names(HybridArc([0.0], [0], [[1.0, 2.0]], None))
    ['$x_1$', '$x_2$']
    >>> _component_names(HybridArc([0.0], [0], [[1.0, 2.0, 3.0]], None,
    ...                           components={"plant": slice(0, 2), "obs": slice(2, 3)}))
    ['plant$_1$', 'plant$_2$', 'obs']
    """
    n = arc.state_dim
    names = [_math_sub("x", i + 1) for i in range(n)]
    comps = getattr(arc, "components", None)
    if comps:
        for name, sl in comps.items():
            idx = range(*sl.indices(n)) if isinstance(sl, slice) else []
            idx = list(idx)
            for m, i in enumerate(idx):
                names[i] = str(name) if len(idx) == 1 else f"{name}{_math_sub('', m + 1)}"
    return names


def _select(arc, idx, fn, where):
    """What to plot: ``(kind, payload, names)``.

    kind "state": payload the component indices; "fn": a callable of
    (x, t, j) and the output columns (or None: all); "values": an (N, k)
    array given at the samples.
    """
    n, N = arc.state_dim, len(arc.t)
    if fn is not None:
        if not callable(fn):
            raise TypeError(f"{where}: fn must be a callable fn(x), fn(x, t) or fn(x, t, j), "
                            f"got {type(fn).__name__}")
        if idx is not None and (callable(idx) or (isinstance(idx, np.ndarray)
                                and idx.dtype.kind == "f")):
            raise TypeError(f"{where}: give either fn= or values in idx, not both")
        return "fn", (fn, idx), None
    if isinstance(idx, np.ndarray) and idx.dtype.kind == "f":
        if idx.shape[:1] != (N,) or idx.ndim > 2:
            raise ValueError(f"idx: an array of values must have shape ({N},) or "
                             f"({N}, k), one row per sample; got {idx.shape}")
        v = idx.reshape(N, -1).astype(float)
        return "values", v, [_math_sub("y", k + 1) for k in range(v.shape[1])]
    if callable(idx):
        return "fn", (idx, None), None
    if idx is None:
        idx = list(range(n))
    idx = [idx] if np.ndim(idx) == 0 else list(np.ravel(idx)) if isinstance(
        idx, np.ndarray) else list(idx)
    if not idx:
        raise ValueError("idx must select at least one component, got an empty list")
    idx = [_check_component("idx", i, n) for i in idx]
    names = _component_names(arc)
    return "state", idx, [names[i] for i in idx]


def _fn_names(fn, k):
    name = getattr(fn, "__name__", "")
    if k == 1:
        return [name if name.isidentifier() else "$y$"]
    return [_math_sub("y", m + 1) for m in range(k)]


class _Sampled:
    """The arc resampled for drawing.

    Attributes
    ----------
    t, j : (M,) plotted times and jump counts; NaN in t separates flow
        intervals.
    v : (M, k) plotted values, NaN where hidden or at separators.
    sample_pos : (N,) position of each stored sample in the (M,) arrays.
    pre, post : (J,) sample indices before and after each jump.
    shown : (J,) bool, jumps left visible by the filter.
    names : default labels of the k columns.
    """


def _sample(arc, idx, fn, smooth, filt, where, values=True):
    """Resample the arc: stored samples exactly, points of the interpolant
    inside each step, NaN between flow intervals; apply fn and the filter."""
    from .system import as_map
    if values:
        kind, payload, names = _select(arc, idx, fn, where)
    else:
        kind, payload, names = "none", None, []
    t, j, x = arc.t, arc.j, arc.x
    N = len(t)
    # points inserted in each interval between samples
    if isinstance(smooth, bool):
        m = 0
        # a linear interpolant needs no inserted points, unless fn or the
        # filter bends it
        can_interp = arc.xdot is not None or bool(getattr(arc, "_segments", None)) \
            or kind == "fn" or callable(filt)
        if smooth and kind != "values" and can_interp:
            m = int(np.clip(_MAX_POINTS // max(N, 1) - 1, 0, _POINTS_PER_STEP))
    else:
        m = smooth if kind != "values" else 0
    same_j = np.zeros(N, bool)
    same_j[:-1] = j[1:] == j[:-1]
    fp = np.zeros(N, bool)
    fp[:-1] = same_j[:-1] & (t[1:] > t[:-1])
    jb = np.zeros(N, bool)
    jb[:-1] = ~same_j[:-1]
    cnt = 1 + m * fp + jb
    start = np.cumsum(cnt) - cnt
    M = int(cnt.sum())
    T = np.full(M, np.nan)
    J = np.zeros(M, np.int64)
    X = np.full((M, arc.state_dim), np.nan)
    T[start], J[start], X[start] = t, j, x
    sep = start[jb] + 1
    J[sep] = j[jb]
    inner = np.zeros(0, np.int64)
    if m and fp.any():
        ks = np.flatnonzero(fp)
        frac = np.arange(1, m + 1) / (m + 1)
        inner = (start[ks][:, None] + 1 + np.arange(m)).ravel()
        ti = (t[ks][:, None] + (t[ks + 1] - t[ks])[:, None] * frac).ravel()
        # interior points cannot round onto the next sample: keep them inside
        ti = np.minimum(ti, np.repeat(t[ks + 1], m))
        T[inner], J[inner] = ti, np.repeat(j[ks], m)
        X[inner] = _at(arc, ti, J[inner])
    live = ~np.isnan(T)                      # every non-separator point
    # values to plot
    if kind == "state":
        V = X[:, payload]
    elif kind == "values":
        V = np.full((M, payload.shape[1]), np.nan)
        V[start] = payload
    elif kind == "fn":
        f, cols = payload
        V, names = _eval_fn(as_map(f, "fn"), X, T, J, live, f, where)
        if cols is not None:
            cols = [cols] if np.ndim(cols) == 0 else list(cols)
            if not cols:
                raise ValueError("idx must select at least one output of fn, got an "
                                 "empty list")
            cols = [_check_component("idx", c, V.shape[1]) for c in cols]
            V, names = V[:, cols], [names[c] for c in cols]
    else:
        V = np.zeros((M, 0))
    V = np.array(V, dtype=float)
    # filter
    keep = np.ones(M, bool)
    if filt is not None:
        if callable(filt):
            p = as_map(filt, "filter")
            for q in np.flatnonzero(live):
                r = p(X[q], T[q], int(J[q]), None)
                rv = np.asarray(r)
                if rv.shape != () or rv.dtype.kind not in "biu":
                    raise TypeError(f"{where}: filter must return one bool, got "
                                    f"{r!r} at (t={T[q]}, j={J[q]})")
                keep[q] = bool(rv)
        else:
            mask = np.asarray(filt)
            if mask.dtype != bool or mask.shape != (N,):
                raise TypeError(f"{where}: filter must be a callable filter(x, t, j) "
                                f"returning a bool, or a bool array of shape ({N},) (one "
                                f"per sample); got {type(filt).__name__}"
                                + (f" of dtype {mask.dtype} and shape {mask.shape}"
                                   if isinstance(filt, np.ndarray) else ""))
            keep[start] = mask
            if inner.size:
                ks = np.flatnonzero(fp)
                keep[inner] = np.repeat(mask[ks] & mask[ks + 1], m)
        V[~keep] = np.nan
    s = _Sampled()
    s.t, s.j, s.v, s.keep, s.sample_pos = T, J, V, keep, start
    s.post = arc.jump_index
    s.pre = s.post - 1
    s.shown = keep[start[s.pre]] & keep[start[s.post]]
    s.names = names
    s.k = V.shape[1]
    return s


def _at(arc, t, j):
    """States (m, n) of the arc at times t (m,) with jump counts j (m,)."""
    return np.asarray(arc.at(t, j), dtype=float).reshape(len(t), arc.state_dim)


def _eval_fn(f, X, T, J, live, fn, where):
    rows = np.flatnonzero(live)
    out = None
    for q, xq, tq, jq in zip(rows.tolist(), X[rows], T[rows], J[rows].tolist()):
        try:
            r = f(xq, tq, jq, None)
            c = r.__class__
            if (c is float or c is np.float64) and out is not None and out.shape[1] == 1:
                out[q, 0] = r           # the common case: one float per point
                continue
            r = np.asarray(r, dtype=float)
        except (TypeError, ValueError) as e:
            if "could not convert" in str(e) or "float()" in str(e):
                raise TypeError(f"{where}: fn must return a float or a 1-D array of floats, "
                                f"got a non-numeric value at (t={T[q]}, j={J[q]})") from e
            raise
        if r.ndim > 1:
            raise ValueError(f"{where}: fn must return a float or a 1-D array of floats, "
                             f"got shape {r.shape} at (t={T[q]}, j={J[q]})")
        r = r.reshape(-1)
        if out is None:
            out = np.full((len(T), r.size), np.nan)
        elif r.size != out.shape[1]:
            raise ValueError(f"{where}: fn returned {r.size} values at (t={T[q]}, j={J[q]}) "
                             f"but {out.shape[1]} before")
        out[q] = r
    return out, _fn_names(fn, out.shape[1])
