"""Theorem-check helpers over hybrid time.

Each takes an arc and a signal along it, given either as an (N, ...) array of
values at the arc's samples or as a callable ``fn(x, t, j)``. The norm of a
vector-valued signal is its Euclidean norm (max-abs with ``norm="inf"``).
Failures name the first violating (t, j), the value and the bound.

Hybrid time is compared as the engine compares it. A jump time is located
only to :func:`hybridsim.rules.event_tolerance` (4 ulp of ``max(1, |t|)``),
so a jump meant for t = δ may be stored a rounding step before or after δ.
The helpers that select samples by time (``t=`` of :func:`assert_exact_after`,
:func:`assert_bounded` and the ``margin_*`` functions) therefore count a
sample whose time is within ``event_tolerance(t, t)`` of a requested time
``t`` as *at* ``t``: the sample after a jump stored at 0.7999999999999998 is
"at 0.8"; :func:`margin_settles_by` likewise counts a settling time within
that tolerance after ``by`` as at ``by``. The same tolerance is how the
solver decides that a stored sample stands for a ``t_eval`` time. Jump
counts j are integers and compared exactly.

Beside the asserts, each ``margin_*`` function returns by how much its
claim holds (a :class:`Margin`, >= 0) or fails (< 0), and where it was
decided.

**Every solution.** Each assert and ``margin_*`` function also takes, in
place of one arc, a :class:`hybridsim.SolutionTree` (from
:func:`hybridsim.explore`: its leaves and the prefixes of its merged
branches, so every sample of every solution explored) or any iterable of
arcs. The signal (and an array bound) must then be a callable. An assert
fails on the first violating solution, naming it and its branch choices;
a margin is the worst over the solutions, with ``.solution`` (its index)
and ``.choices``. A solution without samples in the requested range is
skipped (an error only when none has one); an incomplete tree (the
budget ended :func:`hybridsim.explore`) is refused, since the claim would
not be checked over every solution.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .rules import event_tolerance

__all__ = ["signal_norm", "settling_time", "assert_exact_after", "assert_bounded",
           "Margin", "margin_exact_after", "margin_bounded", "margin_settles_by",
           "margin_decays", "margin_in_set", "all_of", "any_of", "solutions_of"]


class _NoSampleAssertion(AssertionError):
    """An assert found no sample of the arc in the requested range."""


class _NoSampleValue(ValueError):
    """A margin found no sample of the arc in the requested range."""


def _is_arc(a):
    return hasattr(a, "t") and hasattr(a, "j") and hasattr(a, "x")


def solutions_of(arcs, leaves_only=False):
    """The arcs a check over many solutions runs on: a list of ``(label, arc)``.

    Parameters
    ----------
    arcs : SolutionTree or iterable of HybridArc
        A tree from :func:`hybridsim.explore` (its leaves, then the prefixes
        of its merged branches unless ``leaves_only``), or any arcs.
    leaves_only : bool
        Only a tree's leaves (for claims about how a solution ends).

    Returns
    -------
    list of (str, HybridArc)
        The label names the solution and its branch choices.

    Raises
    ------
    ValueError
        An incomplete tree (its budget ended the exploration), or no arc.

    Examples
    --------
    >>> import hybridsim as hs
    >>> a = hs.HybridArc([0.0, 1.0], [0, 0], [[1.0], [0.5]], None)
    >>> [label for label, _ in solutions_of([a, a])]
    ['solution 0 of 2', 'solution 1 of 2']
    """
    if getattr(arcs, "complete", True) is False:
        raise ValueError(f"the tree is incomplete ({arcs.end.name}: {arcs.message}); a "
                         f"check over every solution needs a complete exploration")
    if hasattr(arcs, "leaves") and hasattr(arcs, "merged"):
        items = list(arcs.leaves) + ([] if leaves_only else list(arcs.merged))
    else:
        try:
            items = list(arcs)
        except TypeError:
            raise TypeError(f"arc must be a HybridArc, a SolutionTree or an iterable of "
                            f"HybridArc, got {type(arcs).__name__}") from None
    if not items:
        raise ValueError("no solution to check: the iterable of arcs is empty")
    out = []
    for i, a in enumerate(items):
        if not _is_arc(a):
            raise TypeError(f"arc: item {i} is a {type(a).__name__}, not a HybridArc")
        label = f"solution {i} of {len(items)}"
        ch = getattr(a, "choices", None)
        if ch is not None:
            label += f" ({'; '.join(str(c) for c in ch) or 'no choice'})"
        if getattr(a, "merged_into", None) is not None:
            label += f", up to where it merges into branch {a.merged_into}"
        out.append((label, a))
    return out


def _no_arrays(where, **kw):
    for name, v in kw.items():
        if v is not None and not callable(v) and np.ndim(v) > 0:
            raise TypeError(f"{where}: {name} must be a callable fn(x, t, j) (or a constant) "
                            f"when checking several solutions, got an array")


def _every(kind, leaves_only=False):
    """Let an assert (``kind="assert"``) or a margin take many solutions."""
    def wrap(fn):
        @functools.wraps(fn)
        def many(arc, *args, **kw):
            if _is_arc(arc):
                return fn(arc, *args, **kw)
            if args and not callable(args[0]):
                _no_arrays(fn.__name__, signal=args[0])
            _no_arrays(fn.__name__, **{k: v for k, v in kw.items()
                                       if k in ("signal", "distance")})
            if len(args) > 1 and fn.__name__.endswith("bounded"):
                _no_arrays(fn.__name__, bound=args[1])
            if "bound" in kw:
                _no_arrays(fn.__name__, bound=kw["bound"])
            items = solutions_of(arc, leaves_only)
            worst, checked, empty = None, 0, None
            for i, (label, a) in enumerate(items):
                try:
                    m = fn(a, *args, **kw)
                except (_NoSampleAssertion, _NoSampleValue) as e:
                    empty = e           # this solution has no sample in the range
                    continue
                except AssertionError as e:
                    raise AssertionError(f"{label}: {e}") from e
                checked += 1
                if kind == "margin" and (worst is None or float(m) < float(worst[0])):
                    worst = (m, i, label, a)
            if not checked:
                err = AssertionError if kind == "assert" else ValueError
                raise err(f"{fn.__name__}: no solution of the {len(items)} has a sample in "
                          f"the requested range ({empty})")
            if kind == "margin":
                m, i, label, a = worst
                out = Margin(float(m), *(m.where or (None, None)), f"{m.what}, {label}")
                out.solution, out.choices = i, getattr(a, "choices", None)
                return out
            return None
        return many
    return wrap


def signal_norm(arc, signal, norm=2):
    """Norm of ``signal`` at every sample of ``arc``.

    Parameters
    ----------
    arc : HybridArc
        The solution whose samples the signal is given at.
    signal : array_like or callable
        Values at the arc's samples, shape ``(N, ...)`` with ``N = len(arc)``,
        or a callable ``fn(x, t, j)`` evaluated at each sample
        (:meth:`HybridArc.evaluate`).
    norm : {2, "inf"}, optional
        Euclidean norm (default) or max-abs norm of each sample's value.

    Returns
    -------
    ndarray
        Shape ``(N,)``: the norm at each sample.

    Raises
    ------
    ValueError
        When ``signal`` does not have one value per sample.

    Examples
    --------
    >>> import hybridsim as hs
    >>> arc = hs.HybridArc([0.0, 1.0, 1.0], [0, 0, 1],
    ...                    [[3.0, 4.0], [0.0, 1.0], [0.0, 0.0]], None)
    >>> signal_norm(arc, arc.x)
    array([5., 1., 0.])
    >>> signal_norm(arc, lambda x, t, j: x, norm="inf")
    array([4., 1., 0.])
    """
    if callable(signal):
        v = np.asarray(arc.evaluate(signal), dtype=float)
    else:
        v = np.asarray(signal, dtype=float)
    if v.shape[:1] != (len(arc.t),):
        raise ValueError(f"signal must have one value per sample: expected leading "
                         f"dimension {len(arc.t)}, got shape {v.shape}")
    v = v.reshape(len(arc.t), -1)
    if norm == "inf":
        return np.max(np.abs(v), axis=1)
    return np.linalg.norm(v, axis=1)


def _bounds(w, what):
    """``(lo, hi)`` of a scalar (``[w, inf)``) or a closed range (None: open end)."""
    if w is None:
        return -math.inf, math.inf
    if np.ndim(w) == 0:
        return float(w), math.inf
    try:
        lo, hi = w
    except (TypeError, ValueError):
        raise TypeError(f"{what} must be a number or a closed range (lo, hi), "
                        f"got {w!r}") from None
    return (-math.inf if lo is None else float(lo)), (math.inf if hi is None else float(hi))


def _widen(lo, hi):
    """[lo, hi] widened by the engine's time tolerance at each finite end."""
    if math.isfinite(lo):
        lo -= event_tolerance(lo, lo)
    if math.isfinite(hi):
        hi += event_tolerance(hi, hi)
    return lo, hi


def _mask(arc, t, j):
    """Samples with time in ``t`` (to the engine's tolerance) and jump count in ``j``."""
    m = np.ones(len(arc.t), dtype=bool)
    if t is not None:
        lo, hi = _widen(*_bounds(t, "t"))
        m &= (arc.t >= lo) & (arc.t <= hi)
    if j is not None:
        lo, hi = _bounds(j, "j")
        m &= (arc.j >= lo) & (arc.j <= hi)
    return m


def settling_time(arc, signal, threshold=1e-8, norm=2):
    """The last hybrid time (t, j) at which |signal| exceeds ``threshold``.

    Parameters
    ----------
    arc : HybridArc, SolutionTree or iterable of HybridArc
        The solution, or every solution (see the module notes).
    signal : array_like or callable
        As for :func:`signal_norm`.
    threshold : float, optional
        A sample is above the threshold when its norm is strictly greater.
    norm : {2, "inf"}, optional
        As for :func:`signal_norm`.

    Returns
    -------
    t : float
        Time of the last sample above the threshold; ``arc.t[0]`` if no
        sample is above it; ``inf`` if the final sample still is (not
        settled within the arc).
    j : int or None
        Its jump count; ``arc.j[0]`` if no sample is above the threshold;
        ``None`` if not settled.

    Raises
    ------
    ValueError
        When ``signal`` does not have one value per sample.

    Notes
    -----
    No time is compared here: the answer is a stored sample's (t, j). A
    finite-time observer whose error is reset to 0 by its jump at δ settles
    at that jump's pre-jump sample, i.e. at the stored jump time, which may
    differ from δ by the engine's event tolerance (see the module's notes).

    Examples
    --------
    >>> import hybridsim as hs
    >>> arc = hs.HybridArc([0.0, 0.5, 1.0, 1.0, 2.0], [0, 0, 0, 1, 1],
    ...                    [[1.0], [0.5], [0.25], [0.0], [0.0]], None)
    >>> settling_time(arc, arc.x, threshold=1e-10)
    (1.0, 0)
    >>> settling_time(arc, arc.x * 0.0)
    (0.0, 0)
    >>> settling_time(arc, arc.x + 1.0, threshold=0.5)
    (inf, None)
    """
    v = signal_norm(arc, signal, norm)
    above = np.flatnonzero(v > threshold)
    if above.size == 0:
        return float(arc.t[0]), int(arc.j[0])
    k = above[-1]
    if k == len(v) - 1:
        return float("inf"), None
    return float(arc.t[k]), int(arc.j[k])


@_every("assert")
def assert_exact_after(arc, signal, t=None, j=None, atol=1e-8, norm=2):
    """Assert |signal| <= ``atol`` at every sample from hybrid time (t, j) on.

    Parameters
    ----------
    arc : HybridArc, SolutionTree or iterable of HybridArc
        The solution, or every solution (see the module notes).
    signal : array_like or callable
        As for :func:`signal_norm`.
    t : float or (float, float), optional
        The samples checked have time ``t' >= t``, or ``lo <= t' <= hi``
        for a closed range ``(lo, hi)`` (``None`` for an open end). A sample
        within the engine's time tolerance of ``t`` (or of ``lo``, ``hi``),
        :func:`hybridsim.rules.event_tolerance` ``(t, t)`` = 4 ulp of
        ``max(1, |t|)``, counts as at that time and is checked. ``None``:
        any time.
    j : int or (int, int), optional
        The samples checked have jump count ``j' >= j``, or ``lo <= j' <= hi``
        (compared exactly). ``None``: any jump count.
    atol : float, optional
        The largest norm allowed.
    norm : {2, "inf"}, optional
        As for :func:`signal_norm`.

    Returns
    -------
    None

    Raises
    ------
    AssertionError
        When a checked sample's norm exceeds ``atol`` (or is NaN); the
        message names the first one's (t, j) and the number of violations.
        Also when no sample of the arc is in the requested range.
    ValueError
        When ``signal`` does not have one value per sample.

    Examples
    --------
    A finite-time observer's error, reset to 0 by a jump meant for t = 0.8
    that the engine stored one rounding step early:

    >>> import hybridsim as hs
    >>> t_jump = 0.7999999999999998
    >>> arc = hs.HybridArc([0.0, t_jump, t_jump, 1.0], [0, 0, 1, 1],
    ...                    [[1.0], [0.5], [0.0], [0.0]], None)
    >>> assert_exact_after(arc, arc.x, t=0.8, j=1, atol=0.0)
    >>> bad = arc.x.copy()
    >>> bad[2] = 1e-3           # the first sample after the jump, "at 0.8"
    >>> assert_exact_after(arc, bad, t=0.8, j=1)
    Traceback (most recent call last):
    ...
    AssertionError: signal not exact after (t=0.8, j=1): first violation at (t=0.8, j=1) ...
    """
    m = _mask(arc, t, j)
    if not m.any():
        raise _NoSampleAssertion(f"assert_exact_after: no sample with t >= {t} and j >= {j} "
                             f"(arc ends at t={arc.t[-1]}, j={arc.j[-1]})")
    v = signal_norm(arc, signal, norm)
    bad = np.flatnonzero(m & ~(_slack(v, atol) >= 0))
    if bad.size:
        k = bad[0]
        raise AssertionError(
            f"signal not exact after (t={t}, j={j}): first violation at "
            f"(t={arc.t[k]:.12g}, j={arc.j[k]}) with |signal|={v[k]:.3e} > atol={atol:.1e} "
            f"({bad.size} of {int(m.sum())} samples violate)")


@_every("assert")
def assert_bounded(arc, signal, bound, t=None, j=None, rtol=0.0, atol=0.0, norm=2):
    """Assert |signal(t, j)| <= bound(t, j) * (1 + rtol) + atol over a range.

    Parameters
    ----------
    arc : HybridArc, SolutionTree or iterable of HybridArc
        The solution, or every solution (see the module notes).
    signal : array_like or callable
        As for :func:`signal_norm`.
    bound : callable, array_like or float
        A callable ``(t, j) -> float`` (called once with the arrays
        ``arc.t, arc.j`` if it accepts them, else sample by sample), an
        array of one value per sample, or a constant.
    t : float or (float, float), optional
        The samples checked, as for :func:`assert_exact_after`: time
        ``>= t`` or in the closed range ``(lo, hi)``, a sample within the
        engine's time tolerance (:func:`hybridsim.rules.event_tolerance`)
        of an end counting as at it. ``None``: any time.
    j : int or (int, int), optional
        Jump counts ``>= j`` or in the closed range ``(lo, hi)``.
    rtol, atol : float, optional
        Relative and absolute slack on the bound.
    norm : {2, "inf"}, optional
        As for :func:`signal_norm`.

    Returns
    -------
    None

    Raises
    ------
    AssertionError
        When a checked sample's norm exceeds its bound (or is NaN); the
        message names the first one's (t, j), value and bound. Also when no
        sample of the arc is in the requested range.
    ValueError
        When ``signal`` does not have one value per sample.

    Examples
    --------
    >>> import numpy as np
    >>> import hybridsim as hs
    >>> arc = hs.HybridArc([0.0, 0.5, 1.0], [0, 0, 0], [[1.0], [0.6], [0.36]], None)
    >>> assert_bounded(arc, arc.x, lambda t, j: np.exp(-t))
    >>> assert_bounded(arc, arc.x, 0.5, t=(1.0, None))
    >>> assert_bounded(arc, arc.x, 0.5, t=0.5000000000000001)   # 1 ulp past 0.5: "at 0.5"
    Traceback (most recent call last):
    ...
    AssertionError: bound violated: first at (t=0.5, j=0) with |signal|=6.000000e-01 > ...
    """
    m = _mask(arc, t, j)
    if not m.any():
        raise _NoSampleAssertion(f"assert_bounded: no sample in the requested range "
                             f"(t={t}, j={j}; the arc has t in [{arc.t[0]}, {arc.t[-1]}], "
                             f"j in [{arc.j[0]}, {arc.j[-1]}])")
    v = signal_norm(arc, signal, norm)
    b = _bound_values(arc, bound, v.shape)
    lim = b * (1 + rtol) + atol
    bad = np.flatnonzero(m & ~(_slack(v, lim) >= 0))
    if bad.size:
        k = bad[0]
        raise AssertionError(
            f"bound violated: first at (t={arc.t[k]:.12g}, j={arc.j[k]}) with "
            f"|signal|={v[k]:.6e} > bound={b[k]:.6e} (rtol={rtol}, atol={atol}); "
            f"{bad.size} of {int(m.sum())} samples violate")


# ------------------------------------------------------------------ margins --

def _slack(v, lim):
    """lim - v, with NaN values (a broken signal) as -inf: never "holds"."""
    d = np.asarray(lim, dtype=float) - np.asarray(v, dtype=float)
    return np.where(np.isnan(d), -np.inf, d)


def _bound_values(arc, bound, shape):
    if callable(bound):
        try:
            return np.broadcast_to(np.asarray(bound(arc.t, arc.j), dtype=float), shape)
        except (TypeError, ValueError):
            return np.array([float(bound(tt, jj)) for tt, jj in zip(arc.t, arc.j)])
    return np.broadcast_to(np.asarray(bound, dtype=float), shape)


class Margin(float):
    """A signed margin: by how much a claim holds (>= 0) or is violated (< 0).

    A float (compare, add, ``min``, ``max`` it as one) that also says where
    it was decided: :attr:`where` is the hybrid time ``(t, j)`` of the
    deciding sample (None when no single sample decides), :attr:`what`
    which claim, and :attr:`series` (None where not kept) the margin at
    every sample it judged, ``(t, j, value)`` arrays: what a plot of the
    run against its claim draws (the margin is their minimum).

    Examples
    --------
    >>> m = Margin(-0.25, t=1.5, j=2, what="bounded")
    >>> float(m), m.where, m.holds
    (-0.25, (1.5, 2), False)
    """

    def __new__(cls, value, t=None, j=None, what="", series=None):
        self = super().__new__(cls, value)
        self.where = None if t is None else (float(t), None if j is None else int(j))
        self.what = what
        self.series = series
        return self

    @property
    def holds(self):
        """``margin >= 0``."""
        return float(self) >= 0

    def __repr__(self):
        at = "" if self.where is None else f" at (t={self.where[0]:.6g}, j={self.where[1]})"
        return f"Margin({float(self):.6g}{at}{', ' + self.what if self.what else ''})"


def _worst(arc, slack, m, what):
    if not m.any():
        raise _NoSampleValue(f"{what}: no sample of the arc in the requested range (the arc has "
                         f"t in [{arc.t[0]}, {arc.t[-1]}], j in [{arc.j[0]}, {arc.j[-1]}])")
    idx = np.flatnonzero(m)
    k = idx[int(np.argmin(slack[idx]))]
    return Margin(slack[k], arc.t[k], arc.j[k], what,
                  series=(arc.t[idx], arc.j[idx], np.asarray(slack, dtype=float)[idx]))


@_every("margin")
def margin_exact_after(arc, signal, t=None, j=None, atol=1e-8, norm=2):
    """The margin of "|signal| <= atol at every sample from (t, j) on".

    ``atol - max |signal|`` over the samples selected as in
    :func:`assert_exact_after` (the same time tolerance), with the deciding
    sample's (t, j); NaN counts as -inf.

    Parameters
    ----------
    arc, signal, t, j, atol, norm
        As for :func:`assert_exact_after`.

    Returns
    -------
    Margin

    Raises
    ------
    ValueError
        No sample in the range.

    Examples
    --------
    >>> import hybridsim as hs
    >>> arc = hs.HybridArc([0.0, 0.8, 0.8, 1.0], [0, 0, 1, 1], [[1.0], [0.5], [0.0], [2e-9]],
    ...                    None)
    >>> margin_exact_after(arc, arc.x, t=0.8, j=1, atol=1e-8)
    Margin(8e-09 at (t=1, j=1), exact after)
    """
    v = signal_norm(arc, signal, norm)
    return _worst(arc, _slack(v, atol), _mask(arc, t, j), "exact after")


@_every("margin")
def margin_bounded(arc, signal, bound, t=None, j=None, rtol=0.0, atol=0.0, norm=2):
    """The margin of "|signal(t, j)| <= bound(t, j) (1 + rtol) + atol over a range".

    ``min (bound (1 + rtol) + atol - |signal|)`` over the selected samples
    (as :func:`assert_bounded`), with the deciding sample's (t, j).

    Parameters
    ----------
    arc, signal, bound, t, j, rtol, atol, norm
        As for :func:`assert_bounded`.

    Returns
    -------
    Margin

    Examples
    --------
    >>> import numpy as np
    >>> import hybridsim as hs
    >>> arc = hs.HybridArc([0.0, 0.5, 1.0], [0, 0, 0], [[1.0], [0.7], [0.3]], None)
    >>> m = margin_bounded(arc, arc.x, lambda t, j: np.exp(-t))
    >>> round(float(m), 4), m.where
    (-0.0935, (0.5, 0))
    """
    v = signal_norm(arc, signal, norm)
    lim = _bound_values(arc, bound, v.shape) * (1 + rtol) + atol
    return _worst(arc, _slack(v, lim), _mask(arc, t, j), "bounded")


@_every("margin")
def margin_decays(arc, signal, c, rate, t=None, j=None, norm=2):
    """The margin of "|signal(t, j)| <= c e^(-rate (t - t0))" (t0 = ``arc.t[0]``).

    A :func:`margin_bounded` with that bound. For an exponential decay the
    absolute margin is small late in the arc whatever the decay; compare
    claims of different size with a relative margin of your own
    (``margin_bounded`` of ``|signal| / bound`` against 1).

    Parameters
    ----------
    arc, signal, t, j, norm
        As for :func:`assert_bounded` (``t``: the samples checked, to the
        engine's time tolerance).
    c : float
        The bound at ``arc.t[0]``.
    rate : float
        The exponential rate.

    Returns
    -------
    Margin

    Raises
    ------
    ValueError
        No sample in the range.

    Examples
    --------
    >>> import numpy as np
    >>> import hybridsim as hs
    >>> t = np.linspace(0, 2, 5)
    >>> arc = hs.HybridArc(t, np.zeros(5, int), np.exp(-t)[:, None], None)
    >>> margin_decays(arc, arc.x, c=1.0, rate=0.5).holds
    True
    >>> margin_decays(arc, arc.x, c=1.0, rate=2.0).holds
    False
    """
    t0 = float(arc.t[0])
    return margin_bounded(arc, signal, lambda tt, jj: c * np.exp(-rate * (np.asarray(tt) - t0)),
                          t=t, j=j, norm=norm)


@_every("margin", leaves_only=True)
def margin_settles_by(arc, signal, by, threshold=1e-8, norm=2):
    """The margin of "|signal| <= threshold from time ``by`` on": ``by`` minus
    the settling time (:func:`settling_time`).

    Positive: it settled that long before ``by``. Negative: that long after
    (the last sample above the threshold is the ``where``). -inf when the
    arc ends above the threshold (never settled).

    Parameters
    ----------
    arc, signal, threshold, norm
        As for :func:`settling_time`.
    by : float
        The time by which the signal must have settled. A settling time
        within the engine's time tolerance after ``by``
        (:func:`hybridsim.rules.event_tolerance` ``(by, by)``, 4 ulp of
        ``max(1, |by|)``) counts as at ``by``: margin 0, so a reset meant for
        t = ``by`` that the engine stored a rounding step late holds.

    Returns
    -------
    Margin

    Examples
    --------
    >>> import hybridsim as hs
    >>> arc = hs.HybridArc([0.0, 1.0, 2.0, 3.0], [0] * 4, [[1.0], [0.1], [0.0], [0.0]], None)
    >>> margin_settles_by(arc, arc.x, by=1.5)
    Margin(0.5 at (t=1, j=0), settles by)
    """
    ts, js = settling_time(arc, signal, threshold, norm)
    if math.isinf(ts):
        return Margin(-math.inf, arc.t[-1], arc.j[-1], "settles by")
    by = float(by)
    late = ts - by
    if 0 < late <= event_tolerance(by, by):
        late = 0.0                      # within the engine's time tolerance: at ``by``
    return Margin(-late, ts, js, "settles by")


@_every("margin")
def margin_in_set(arc, distance, t=None, j=None):
    """The margin of "the arc stays in a set", given its signed distance.

    ``distance(x, t, j)`` is positive inside the set, negative outside (a
    level function: ``r - |x|`` for a ball of radius r, ``min(x - lo, hi -
    x)`` for a box); the margin is its minimum over the selected samples.

    Parameters
    ----------
    arc : HybridArc, SolutionTree or iterable of HybridArc
        The solution, or every solution (see the module notes).
    distance : callable
        ``distance(x, t, j) -> float``, evaluated at each sample.
    t, j
        The samples checked, as for :func:`assert_exact_after` (``t`` to the
        engine's time tolerance).

    Returns
    -------
    Margin

    Raises
    ------
    ValueError
        No sample in the range.

    Examples
    --------
    >>> import numpy as np
    >>> import hybridsim as hs
    >>> arc = hs.HybridArc([0.0, 1.0], [0, 0], [[0.5, 0.0], [0.0, 1.2]], None)
    >>> margin_in_set(arc, lambda x, t, j: 1.0 - np.linalg.norm(x))
    Margin(-0.2 at (t=1, j=0), in set)
    """
    d = np.asarray(arc.evaluate(distance), dtype=float).reshape(len(arc.t))
    return _worst(arc, np.where(np.isnan(d), -np.inf, d), _mask(arc, t, j), "in set")


def all_of(*margins):
    """Conjunction: the smallest margin (all hold iff it is >= 0), where it was decided.

    Parameters
    ----------
    *margins : Margin or float
        At least one.

    Returns
    -------
    Margin or float
        The smallest of ``margins`` (itself, with its ``where``).

    Raises
    ------
    ValueError
        No margin given.

    Examples
    --------
    >>> all_of(Margin(0.3), Margin(-0.1, t=2.0, j=1)).where
    (2.0, 1)
    """
    if not margins:
        raise ValueError("all_of needs at least one margin")
    return min(margins, key=float)


def any_of(*margins):
    """Disjunction: the largest margin (one holds iff it is >= 0).

    Parameters
    ----------
    *margins : Margin or float
        At least one.

    Returns
    -------
    Margin or float
        The largest of ``margins``.

    Raises
    ------
    ValueError
        No margin given.

    Examples
    --------
    >>> float(any_of(Margin(0.3), Margin(-0.1)))
    0.3
    """
    if not margins:
        raise ValueError("any_of needs at least one margin")
    return max(margins, key=float)
