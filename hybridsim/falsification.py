"""Search for counterexamples: uncertainty spaces and :func:`falsify`.

A theorem about a hybrid system is quantified: for every initial state in a
set, every disturbance below a bound, every sampling sequence with gaps in
[a, b], every delay in [τ1, τ2]. A test that runs the example and a few
seeded cases samples that set; :func:`falsify` searches it for the least
robust run. What may vary is declared as a :class:`Space` of named,
bounded entries (:class:`Interval`, :class:`Box`, :class:`PiecewiseConstant`
and :class:`Sinusoids` signals, :class:`Gaps`); the claim is a function of
the arc that returns a signed margin (positive: it holds, by how much;
negative: violated; see :mod:`hybridsim.testing`'s ``margin_*``
functions); a run maps one point of the space to an arc, or a whole
population of points to their arcs in one batch
(:func:`hybridsim.simulate_many` on a vectorized system, :func:`batch_run`).

The search is scipy's differential evolution over the space's box, which
evaluates each population at once (``vectorized=True``), then a local
compass-search refinement of the worst point within the remaining budget
(each of its iterations one population too);
``method="cmaes"`` is CMA-ES (numpy) over the same box after the same
seeded first population, with restarts;
``method="random"`` is the random-sampling baseline of the same budget.
Only each run's margin is kept, and the arc of the worst run so far (the one
the result returns; simulated again only if that run raised), so a search of
10^6 runs holds 10^6 floats and one arc, not 10^6 arcs.

Examples
--------
A timer whose period is uncertain in [0.9, 1.2], against the claim "the
first jump comes by t = 1.1":

>>> import hybridsim as hs
>>> from hybridsim.library import Timer
>>> from hybridsim.falsification import Space, Interval, falsify
>>> space = Space(period=Interval(0.9, 1.2))
>>> def run(p):
...     return hs.simulate(Timer(p["period"]), [0.0], t_max=2.0, j_max=1)
>>> def by_1_1(arc):                       # margin: 1.1 - (first jump time)
...     return 1.1 - arc.jump_times[0]
>>> res = falsify(run, space, by_1_1, budget=200, seed=0, progress=False)
>>> res.verdict, round(res.margin, 3), round(res.point["period"], 3)
('counterexample', -0.1, 1.2)
"""
from __future__ import annotations

import concurrent.futures
import dataclasses
import itertools
import math
import numbers
import time
import traceback
import weakref
from collections.abc import Callable, Iterable, Mapping

import numpy as np

from .arc import HybridArc
from .rules import Termination

__all__ = ["Interval", "Box", "PiecewiseConstant", "ControlPoints", "Sinusoids", "Gaps", "Space",
           "Point", "Finding", "FalsificationResult", "falsify", "batch_run"]


def _real(name, v):
    if isinstance(v, bool) or not isinstance(v, (numbers.Real, np.floating, np.integer)):
        raise TypeError(f"{name} must be a real number, got {type(v).__name__}")
    v = float(v)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    return v


def _signs(dim, cap=64):
    """The sign vectors of {-1, 1}^dim, (min(2^dim, cap), dim): all of them, or
    the first ``cap`` in binary order."""
    k = min(2 ** min(dim, 20), cap)
    return np.where((np.arange(k)[:, None] >> np.arange(dim)) & 1, 1.0, -1.0)


def _count(name, v):
    if isinstance(v, bool) or not isinstance(v, (numbers.Integral, np.integer)) or v < 1:
        raise ValueError(f"{name} must be a positive integer, got {v!r}")
    return int(v)


class _Entry:
    """One named, bounded coordinate block of a :class:`Space`."""

    size: int

    def bounds(self):                       # (lo, hi) arrays of length size
        raise NotImplementedError

    def value(self, z):                     # the user's value from its coordinates
        raise NotImplementedError

    def extremes(self):
        """Coordinates of the entry's extreme members that are not vertices of
        its box, shape (k, size) (none by default: an Interval's, a Box's and
        Gaps' extremes are the box's vertices)."""
        return np.zeros((0, self.size))

    def _check(self, lo, hi, what):
        lo, hi = np.atleast_1d(np.asarray(lo, float)), np.atleast_1d(np.asarray(hi, float))
        if lo.shape != hi.shape or lo.ndim != 1 or lo.size == 0:
            raise ValueError(f"{what}: lo and hi must be non-empty vectors of one length, "
                             f"got shapes {lo.shape} and {hi.shape}")
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ValueError(f"{what}: bounds must be finite")
        if np.any(lo > hi):
            k = int(np.argmax(lo > hi))
            raise ValueError(f"{what}: inverted bounds at index {k}: lo {lo[k]} > hi {hi[k]}")
        return lo, hi


class Interval(_Entry):
    """A scalar in [lo, hi] (a parameter, a delay, one initial coordinate).

    Examples
    --------
    >>> Interval(0.1, 0.3).value(np.array([0.2]))
    0.2
    """

    size = 1

    def __init__(self, lo, hi):
        self.lo, self.hi = _real("Interval lo", lo), _real("Interval hi", hi)
        self._check(self.lo, self.hi, "Interval")

    def bounds(self):
        return np.array([self.lo]), np.array([self.hi])

    def value(self, z):
        return float(z[0])

    def __repr__(self):
        return f"Interval({self.lo:g}, {self.hi:g})"


class Box(_Entry):
    """A vector in the box [lo, hi] (initial states, parameter vectors).

    Parameters
    ----------
    lo, hi : array_like, shape (n,)
        lo <= hi componentwise; an entry with lo == hi is held fixed.

    Examples
    --------
    >>> b = Box.around([1.0, 0.0], 0.1)
    >>> b.bounds()[0].tolist(), b.bounds()[1].tolist()
    ([0.9, -0.1], [1.1, 0.1])
    """

    def __init__(self, lo, hi):
        self.lo, self.hi = self._check(lo, hi, "Box")
        self.size = self.lo.size

    @classmethod
    def around(cls, nominal, radius):
        """The box ``nominal ± radius`` (radius a scalar or one per coordinate, >= 0)."""
        nominal = np.atleast_1d(np.asarray(nominal, float))
        r = np.broadcast_to(np.asarray(radius, float), nominal.shape)
        if np.any(r < 0) or not np.all(np.isfinite(r)):
            raise ValueError(f"Box.around: radius must be finite and >= 0, got {radius!r}")
        return cls(nominal - r, nominal + r)

    def bounds(self):
        return self.lo, self.hi

    def value(self, z):
        return np.array(z, dtype=float)

    def __repr__(self):
        return f"Box({self.lo.tolist()}, {self.hi.tolist()})"


class _Signal:
    """A bounded signal t -> R^dim from finitely many coordinates (callable)."""

    def __init__(self, fn, dim, bound):
        self._fn, self.dim, self.bound = fn, dim, bound

    def __call__(self, t):
        return self._fn(t)


class PiecewiseConstant(_Entry):
    """A signal |m(t)|_inf <= bound, constant on ``pieces`` equal intervals of [0, t_end].

    The coordinates are the values on each piece (``pieces * dim`` of them,
    each in [-bound, bound]); after ``t_end`` the last value is held. The
    point's value is a callable ``m(t) -> ndarray (dim,)``.

    Parameters
    ----------
    bound : float
        ε >= 0: the class is |m_i(t)| <= ε.
    t_end : float
        > 0, the horizon the pieces cover.
    pieces : int
        Number of pieces (the search's resolution in time).
    dim : int
        Components of m.

    Examples
    --------
    >>> s = PiecewiseConstant(0.5, 2.0, pieces=2)
    >>> m = s.value(np.array([0.5, -0.25]))
    >>> m(0.3).tolist(), m(1.5).tolist(), m(9.0).tolist()
    ([0.5], [-0.25], [-0.25])
    """

    def __init__(self, bound, t_end, pieces, dim=1):
        self.eps = _real("PiecewiseConstant bound", bound)
        if self.eps < 0:
            raise ValueError(f"PiecewiseConstant bound must be >= 0, got {bound}")
        self.t_end = _real("PiecewiseConstant t_end", t_end)
        if self.t_end <= 0:
            raise ValueError(f"PiecewiseConstant t_end must be > 0, got {t_end}")
        self.pieces = _count("PiecewiseConstant pieces", pieces)
        self.dim = _count("PiecewiseConstant dim", dim)
        self.size = self.pieces * self.dim

    def bounds(self):
        return np.full(self.size, -self.eps), np.full(self.size, self.eps)

    def extremes(self):
        """The constant signals m_i = ±bound (vertices of the box, listed so
        that they are tried first), one per sign vector (at most 64)."""
        return np.tile(self.eps * _signs(self.dim), self.pieces)

    def value(self, z):
        vals = np.array(z, dtype=float).reshape(self.pieces, self.dim)
        width = self.t_end / self.pieces

        def m(t):
            k = min(max(int(t // width), 0), self.pieces - 1)
            return vals[k].copy()
        return _Signal(m, self.dim, self.eps)

    def __repr__(self):
        return (f"PiecewiseConstant(bound={self.eps:g}, t_end={self.t_end:g}, "
                f"pieces={self.pieces}, dim={self.dim})")


class _ControlSignal(_Signal):
    """A signal from control points: ``times`` (k,), ``values`` (k, dim), and
    how it goes between them (``interpolation``)."""

    def __init__(self, fn, times, values, interpolation, bound):
        super().__init__(fn, values.shape[1], bound)
        self.times, self.values, self.interpolation = times, values, interpolation

    def __repr__(self):
        return (f"<{self.interpolation} signal through {len(self.times)} control points "
                f"on [0, {self.times[-1]:g}]>")


class ControlPoints(_Entry):
    """An input signal from control points, each component within its own range.

    The coordinates are the values at the control points (``points * dim``
    of them, point by point; component i in [lo_i, hi_i]). With
    ``interpolation="previous"`` the signal is piecewise constant on
    ``points`` equal pieces of [0, t_end] (each value from its piece's
    start); with ``"linear"`` it is piecewise linear through ``points``
    evenly spaced points from 0 to t_end. After the last point the last
    value is held. The point's value is a callable ``u(t) -> ndarray
    (dim,)`` with ``times`` (the control points' times), ``values``
    (points, dim) and ``interpolation``, so a system that takes its inputs
    as control points can be given them directly.

    Parameters
    ----------
    lo, hi : float or array_like, shape (dim,)
        The range of each component.
    t_end : float
        > 0: the horizon the points cover.
    points : int
        Number of control points (>= 2 for ``"linear"``).
    interpolation : {"previous", "linear"}

    Examples
    --------
    >>> s = ControlPoints([0.0, 0.0], [100.0, 325.0], 30.0, points=7, interpolation="linear")
    >>> s.size, s.bounds()[1][:2].tolist()
    (14, [100.0, 325.0])
    >>> u = s.value(np.tile([50.0, 0.0], 7) + np.repeat(np.arange(7.0), 2))
    >>> u.times.tolist()[:3], u(2.5).tolist()
    ([0.0, 5.0, 10.0], [50.5, 0.5])
    >>> steps = ControlPoints(0.0, 1.0, 10.0, points=2)
    >>> steps.value(np.array([0.2, 0.9]))(7.0).tolist()
    [0.9]
    """

    def __init__(self, lo, hi, t_end, points, interpolation="previous"):
        self.lo, self.hi = self._check(lo, hi, "ControlPoints")
        self.dim = self.lo.size
        self.t_end = _real("ControlPoints t_end", t_end)
        if self.t_end <= 0:
            raise ValueError(f"ControlPoints t_end must be > 0, got {t_end}")
        self.points = _count("ControlPoints points", points)
        if interpolation not in ("previous", "linear"):
            raise ValueError(f"ControlPoints interpolation must be 'previous' or 'linear', "
                             f"got {interpolation!r}")
        if interpolation == "linear" and self.points < 2:
            raise ValueError("ControlPoints: a linear signal needs points >= 2, got "
                             f"{self.points}")
        self.interpolation = interpolation
        self.times = (np.linspace(0.0, self.t_end, self.points) if interpolation == "linear"
                      else self.t_end / self.points * np.arange(self.points))
        self.size = self.points * self.dim

    def bounds(self):
        return np.tile(self.lo, self.points), np.tile(self.hi, self.points)

    def extremes(self):
        """The constant inputs at a bound of each component (vertices of the
        box, listed so that they are tried first), at most 64."""
        s = _signs(self.dim) > 0
        return np.tile(np.where(s, self.hi, self.lo), self.points)

    def value(self, z):
        vals = np.array(z, dtype=float).reshape(self.points, self.dim)
        times, linear = self.times, self.interpolation == "linear"

        def u(t):
            if linear:
                return np.array([np.interp(t, times, vals[:, i]) for i in range(self.dim)])
            k = int(np.searchsorted(times, t, side="right")) - 1
            return vals[max(k, 0)].copy()
        bound = float(max(np.max(np.abs(self.lo)), np.max(np.abs(self.hi))))
        return _ControlSignal(u, times.copy(), vals, self.interpolation, bound)

    def __repr__(self):
        return (f"ControlPoints({self.lo.tolist()}, {self.hi.tolist()}, t_end={self.t_end:g}, "
                f"points={self.points}, interpolation={self.interpolation!r})")


class Sinusoids(_Entry):
    """A signal |m(t)|_inf <= bound: a sum of ``terms`` sinusoids up to a bandwidth.

    m_i(t) = bound / terms * sum_k a_ik sin(2π f_ik t + φ_ik) with a in
    [-1, 1], f in [0, bandwidth] (Hz), φ in [0, 2π]: every point of the
    space is in the class (|m_i| <= bound), and the class's smooth members
    of bandwidth below ``bandwidth`` are approached as ``terms`` grows.

    Examples
    --------
    >>> s = Sinusoids(0.2, bandwidth=5.0, terms=2)
    >>> s.size
    6
    >>> m = s.value(np.array([1.0, 1.0, 0.0, 0.0, np.pi / 2, np.pi / 2]))
    >>> m(0.0).tolist()                        # both terms at their peak
    [0.2]
    """

    def __init__(self, bound, bandwidth, terms, dim=1):
        self.eps = _real("Sinusoids bound", bound)
        if self.eps < 0:
            raise ValueError(f"Sinusoids bound must be >= 0, got {bound}")
        self.bandwidth = _real("Sinusoids bandwidth", bandwidth)
        if self.bandwidth <= 0:
            raise ValueError(f"Sinusoids bandwidth must be > 0, got {bandwidth}")
        self.terms = _count("Sinusoids terms", terms)
        self.dim = _count("Sinusoids dim", dim)
        self.size = 3 * self.terms * self.dim

    def extremes(self):
        """The class's bang-bang members: m_i = ±bound at every t (a = ±1,
        f = 0, φ = π/2: on the face f = 0 of the box, not at a vertex, where
        sin φ = 0), one per sign vector (at most 64); then the same signs at
        full amplitude at the band edge (f = bandwidth, every term in phase)."""
        s = _signs(self.dim)
        a = np.repeat(s, self.terms, axis=1)             # (k, dim * terms), as value reads
        ph = np.full_like(a, np.pi / 2)
        const = np.hstack([a, np.zeros_like(a), ph])
        edge = np.hstack([a, np.full_like(a, self.bandwidth), ph])
        return np.vstack([const, edge])

    def bounds(self):
        k = self.terms * self.dim
        lo = np.concatenate([-np.ones(k), np.zeros(k), np.zeros(k)])
        hi = np.concatenate([np.ones(k), np.full(k, self.bandwidth), np.full(k, 2 * np.pi)])
        return lo, hi

    def value(self, z):
        a, f, ph = (np.array(z, dtype=float).reshape(3, self.dim, self.terms))
        scale = self.eps / self.terms

        def m(t):
            return scale * np.sum(a * np.sin(2 * np.pi * f * t + ph), axis=-1)
        return _Signal(m, self.dim, self.eps)

    def __repr__(self):
        return (f"Sinusoids(bound={self.eps:g}, bandwidth={self.bandwidth:g}, "
                f"terms={self.terms}, dim={self.dim})")


class Gaps(_Entry):
    """A sequence of ``count`` gaps, each in [lo, hi] (sampling or dwell times).

    The point's value is the array of gaps; ``Gaps.times(gaps, t0)`` gives
    the instants t0 + cumulative sums.

    Examples
    --------
    >>> g = Gaps(0.05, 0.1, count=3)
    >>> Gaps.times(g.value(np.array([0.1, 0.05, 0.1]))).round(2).tolist()
    [0.1, 0.15, 0.25]
    """

    def __init__(self, lo, hi, count):
        self.lo, self.hi = _real("Gaps lo", lo), _real("Gaps hi", hi)
        if self.lo <= 0:
            raise ValueError(f"Gaps lo must be > 0 (a gap of zero is not a gap), got {lo}")
        self._check(self.lo, self.hi, "Gaps")
        self.size = _count("Gaps count", count)

    def bounds(self):
        return np.full(self.size, self.lo), np.full(self.size, self.hi)

    def value(self, z):
        return np.array(z, dtype=float)

    @staticmethod
    def times(gaps, t0=0.0):
        """The instants ``t0 + cumsum(gaps)``."""
        return t0 + np.cumsum(gaps)

    def __repr__(self):
        return f"Gaps({self.lo:g}, {self.hi:g}, count={self.size})"


class Point(Mapping):
    """One point of a :class:`Space`: its entries' values by name, and ``z``,
    its coordinates in the space's box."""

    def __init__(self, values, z):
        self._values, self.z = dict(values), np.array(z, dtype=float)

    def __getitem__(self, name):
        return self._values[name]

    def __iter__(self):
        return iter(self._values)

    def __len__(self):
        return len(self._values)

    def __repr__(self):
        def show(v):
            if isinstance(v, np.ndarray):
                return np.array2string(v, precision=4, separator=", ")
            if isinstance(v, float):
                return f"{v:.6g}"
            return repr(v) if not isinstance(v, _Signal) else f"<signal, |m| <= {v.bound:g}>"
        return "Point(" + ", ".join(f"{k}={show(v)}" for k, v in self._values.items()) + ")"


class Space:
    """What may vary in a claim, each entry named and bounded.

    Parameters
    ----------
    **entries : Interval, Box, PiecewiseConstant, ControlPoints, Sinusoids or Gaps
        In order; the search runs over the product of their boxes.

    Raises
    ------
    ValueError
        No entries.
    TypeError
        An entry of another type (named).

    Examples
    --------
    >>> s = Space(x0=Box.around([1.0, 0.0], 0.1), k=Interval(1.0, 2.0))
    >>> s.dim, s.names
    (3, ('x0', 'k'))
    >>> p = s.point([1.05, 0.0, 1.5])
    >>> p["x0"].tolist(), p["k"]
    ([1.05, 0.0], 1.5)
    """

    def __init__(self, **entries):
        if not entries:
            raise ValueError("Space needs at least one entry (e.g. x0=Box(lo, hi))")
        for name, e in entries.items():
            if not isinstance(e, _Entry):
                raise TypeError(f"Space entry {name!r} must be an Interval, Box, "
                                f"PiecewiseConstant, ControlPoints, Sinusoids or Gaps, got "
                                f"{type(e).__name__}")
        self.entries = dict(entries)
        self.names = tuple(entries)
        lo, hi, self._slices, k = [], [], {}, 0
        for name, e in entries.items():
            a, b = e.bounds()
            lo.append(a)
            hi.append(b)
            self._slices[name] = slice(k, k + e.size)
            k += e.size
        self.lo, self.hi = np.concatenate(lo), np.concatenate(hi)
        self.dim = k

    def point(self, z) -> Point:
        """The point of coordinates ``z`` (clipped into the box)."""
        z = np.asarray(z, dtype=float)
        if z.shape != (self.dim,):
            raise ValueError(f"z must have shape ({self.dim},), got {z.shape}")
        if not np.all(np.isfinite(z)):
            raise ValueError(f"z must be finite, got {z}")
        return self._point(np.clip(z, self.lo, self.hi))

    def _point(self, z):
        """The point of coordinates ``z``, already checked and in the box."""
        return Point({n: e.value(z[self._slices[n]]) for n, e in self.entries.items()}, z)

    def extremes(self, n, rng) -> np.ndarray:
        """Up to ``n`` coordinate vectors made of the entries' extreme members
        (:meth:`Sinusoids.extremes`...), the entries without any at a random
        vertex of their box, shape (k, dim); empty when no entry has extremes.
        Every combination when there are at most ``n``, else ``n`` of them
        drawn at random (the first of each entry's list first)."""
        ext = {name: e.extremes() for name, e in self.entries.items()}
        lists = [len(x) for x in ext.values() if len(x)]
        if not lists or n < 1:
            return np.zeros((0, self.dim))
        total = math.prod(lists)
        if total <= n:
            combos = itertools.product(*[range(len(x)) for x in ext.values() if len(x)])
            picks = np.array(list(combos), dtype=np.int64)
        else:
            picks = np.column_stack([rng.integers(0, k, n) for k in lists])
            picks[0] = 0
        out = self.lo + (self.hi - self.lo) * rng.integers(0, 2, (len(picks), self.dim))
        c = 0
        for name, x in ext.items():
            if len(x):
                out[:, self._slices[name]] = x[picks[:, c]]
                c += 1
        return out

    def sample(self, n, seed=None) -> np.ndarray:
        """``n`` coordinate vectors drawn uniformly from the box, shape (n, dim)."""
        rng = np.random.default_rng(seed)
        return self.lo + (self.hi - self.lo) * rng.random((_count("n", n), self.dim))

    def __repr__(self):
        return "Space(" + ", ".join(f"{n}={e!r}" for n, e in self.entries.items()) + ")"


@dataclasses.dataclass(frozen=True)
class Finding:
    """A run that failed inside the search: its point and why (counted as a
    counterexample, margin -inf).

    ``cause`` is the run's termination cause (``"BLOWUP"``, ``"MAP_ERROR"``...,
    any not in ``allow``), ``"RAISED"`` (the run raised), ``"WORKER_DIED"``
    (a worker of a population run's executor died: its chunk was lost, not
    run), ``"NOT_AN_ARC"`` (the run returned something else) or
    ``"CLAIM_RAISED"`` (the claim
    raised on the run's arc); ``message`` says why (the run's message, or
    the exception's type, text and where it was raised); ``exception`` is
    the exception that was raised (without its traceback, so that findings
    hold no arcs), or None for a termination cause (the worst run's arc
    keeps its own, ``result.arc.exception``).
    """

    point: Point
    cause: str
    message: str
    exception: BaseException | None = None


@dataclasses.dataclass(frozen=True)
class FalsificationResult:
    """What :func:`falsify` found.

    Attributes
    ----------
    verdict : {"counterexample", "none found"}
        ``"counterexample"`` when some run's margin was negative (or a run
        failed, see ``findings``).
    margin : float
        The worst (smallest) margin found.
    point : Point
        The point of the space that gave it.
    arc : HybridArc or None
        That run, as it was judged (plot it with the hybrid plots); None
        when it failed without an arc (a run that raised, simulated again
        to no avail).
    where : tuple or None
        The hybrid time (t, j) the claim's margin names, when it names one.
    history : ndarray
        Every evaluation's margin, in order (``np.minimum.accumulate`` gives
        the best-so-far curve).
    evaluations : int
    seconds : float
    findings : list of Finding
    method : str
    seed : int or None
    stopped : str
        Why the search ended: ``"counterexample"`` (the first, with
        ``stop=True``), ``"budget"``, ``"seconds"``, ``"converged"`` (the
        search had nothing left to try: a space of one point, DE collapsed
        without new points), ``"interrupted"`` (Ctrl-C: the results are
        those of the runs finished before it) or ``"error"`` (a failure with
        ``on_error="stop"``, or an executor that broke: see ``error``).
    error : Finding or None
        With ``stopped == "error"``: the failure that ended the search (its
        point, cause, message and exception); not counted in ``findings``
        when ``on_error="stop"``.
    found_by : str
        How the worst run was found, and which run it was: ``"a seeded
        vertex of the box, run 3 of 40"``, ``"differential evolution, run
        812 of 2000"``, ``"the compass search from the worst point, ..."``,
        ``"random sampling, ..."`` (empty when nothing ran).
    """

    verdict: str
    margin: float
    point: Point
    arc: object
    where: tuple | None
    history: np.ndarray
    evaluations: int
    seconds: float
    findings: list
    method: str
    seed: int | None
    stopped: str = "budget"
    error: Finding | None = None
    found_by: str = ""

    @property
    def interrupted(self) -> bool:
        """True when Ctrl-C (KeyboardInterrupt) ended the search."""
        return self.stopped == "interrupted"

    def __repr__(self):
        end = "" if self.stopped in ("budget", "counterexample", "converged") \
            else f", stopped: {self.stopped}"
        return (f"FalsificationResult({self.verdict}: margin {self.margin:.4g} at {self.point}"
                f"{'' if self.where is None else f', (t, j) = {self.where}'}; "
                f"{self.evaluations} evaluations in {self.seconds:.2f} s, {self.method}{end})")


#: an attribute the system did not have before a population set it
_UNSET = object()


def batch_run(system, x0_of, t_max, j_max=np.inf, *, attributes_of=None, **simulate_kwargs):
    """A population run: all points of a population in one :func:`hybridsim.simulate_many`.

    Parameters
    ----------
    system : HybridSystem
        Any model: a plain class (its maps as written) runs compiled where
        they compile (``backend="auto"``), a ``vectorized`` one otherwise as
        one numpy batch.
    x0_of : callable
        ``x0_of(point) -> initial state`` (the point's parameters written
        into the state, or the same state for every point).
    attributes_of : callable, optional
        ``attributes_of(point) -> dict`` of the system's attributes (numbers
        or arrays its maps read, such as ``{"e": point["e"]}``) for that
        point: the parameters stay where the model keeps them. The
        population's rows then run one after another on ``system`` with
        those attributes set (restored after), through :func:`hybridsim.sweep`:
        compiled under ``backend="auto"`` where the model compiles (its maps
        read the attributes at each run, so nothing is compiled again); not
        with ``executor=``.
    t_max, j_max, **simulate_kwargs
        As in :func:`hybridsim.simulate_many`; ``backend`` defaults to
        ``"auto"``: the compiled path where the system runs there (numba
        installed, a system with a compiled form or a plain model whose maps
        compile), else the numpy batch or the Python path.
        ``executor=`` (and ``chunks=``) spreads each population over an
        executor: a ``concurrent.futures`` pool, or a dask cluster's
        ``client.get_executor()`` for several machines.

    Returns
    -------
    callable
        ``run(points) -> list of HybridArc``, with ``run.batch = True`` so
        :func:`falsify` passes it whole populations, and ``run.renew()``,
        which :func:`falsify` calls when a worker of the executor died: a
        process pool, broken for good, is replaced by a fresh one of the same
        settings (shut down with the run; the user's own pool is left to its
        owner), so the search loses only the chunk the worker was running.

    Examples
    --------
    >>> import hybridsim as hs
    >>> from hybridsim.library import Timer
    >>> run = batch_run(Timer(1.0), lambda p: [0.0], 2.0, 1, backend="python",
    ...                 attributes_of=lambda p: {"period": p["period"]})
    >>> [round(float(a.jump_times[0]), 6) for a in run([{"period": 0.5}, {"period": 1.5}])]
    [0.5, 1.5]
    """
    from .run import simulate_many, sweep

    simulate_kwargs.setdefault("backend", "auto")
    if attributes_of is not None and not callable(attributes_of):
        raise TypeError(f"attributes_of must be a callable point -> dict of the system's "
                        f"attributes, got {type(attributes_of).__name__}")
    if attributes_of is not None and simulate_kwargs.get("executor") is not None:
        raise ValueError("attributes_of: the rows set the attributes of this process's "
                         "system, one after another; without executor=, or put the "
                         "parameters in the state (x0_of)")
    pools = _Pools(simulate_kwargs)

    def run(points):
        if attributes_of is None:
            x0s = np.array([np.asarray(x0_of(p), dtype=float) for p in points])
            return simulate_many(system, x0s, t_max, j_max, warn=False, **simulate_kwargs)
        saved = {}                      # the attributes set, as they were

        def at(point):
            values = attributes_of(point)
            if not isinstance(values, Mapping):
                raise TypeError(f"attributes_of must return a dict of the system's "
                                f"attributes, got {type(values).__name__}")
            for name, v in values.items():
                saved.setdefault(name, vars(system).get(name, _UNSET))
                setattr(system, name, v)
            return system
        try:
            return sweep(at, points, x0_of, t_max, j_max, warn=False, **simulate_kwargs)
        finally:
            for name, v in saved.items():
                if v is _UNSET:
                    delattr(system, name)
                else:
                    setattr(system, name, v)
    run.batch = True
    run.renew = pools.renew
    weakref.finalize(run, pools.close)
    return run


class _Pools:
    """The executor of a :func:`batch_run`, renewed when a process pool breaks."""

    def __init__(self, kwargs):
        self.kwargs, self.owned = kwargs, None

    def renew(self):
        """A fresh process pool in place of a broken one; False when the
        executor is not a process pool (a dask cluster recovers by itself)."""
        ex = self.kwargs.get("executor")
        if not isinstance(ex, concurrent.futures.ProcessPoolExecutor):
            return False
        fresh = concurrent.futures.ProcessPoolExecutor(
            ex._max_workers, mp_context=ex._mp_context, initializer=ex._initializer,
            initargs=ex._initargs, max_tasks_per_child=ex._max_tasks_per_child)
        self.close()
        self.kwargs["executor"] = self.owned = fresh
        return True

    def close(self):
        if self.owned is not None:
            self.owned.shutdown(wait=False, cancel_futures=True)
            self.owned = None


def _where(exc):
    """``file:line in function`` of the frame that raised ``exc``, or ""."""
    tb = traceback.extract_tb(exc.__traceback__) if exc.__traceback__ else None
    if not tb:
        return ""
    f = tb[-1]
    return f" (at {f.filename.rsplit('/', 1)[-1]}:{f.lineno} in {f.name})"


def _name(fn):
    return getattr(fn, "__qualname__", None) or getattr(fn, "__name__", None) or repr(fn)


class _Evaluator:
    """Runs points, reduces each arc to its margin, keeps the history and the worst.

    The history is a float array grown as runs finish (8 bytes a run, never
    the whole budget at once); arcs are dropped as soon as their margin is
    known, but for the worst so far. With ``stop``, single runs are judged
    one by one, and a population run is split: the first population into
    batches of 1, 2, 4, ... runs (a claim that almost every run breaks is
    refuted by the first), later ones into quarters; so a counterexample
    ends the search without simulating the rest of its population. With a
    finite ``seconds``, a population run is split further so that each
    chunk is expected to end before the deadline (at most twice the last
    chunk, at the rate measured so far): the search stops within one chunk
    of runs of it. Points are built from the coordinates one chunk at a
    time, as the chunk runs.

    A run ending ``CANCELED`` (Ctrl-C inside the engine) is not judged: the
    search stops there (``interrupted``), as it does on a KeyboardInterrupt
    anywhere else.
    """

    def __init__(self, run, space, claim, budget, seconds, allow, progress, stop,
                 on_error="finding"):
        self.run, self.space, self.claim = run, space, claim
        self.batch = bool(getattr(run, "batch", False))
        self.budget, self.deadline = budget, time.perf_counter() + seconds
        self.timed = math.isfinite(seconds)
        self.allow = allow
        self.on_error = on_error
        self._hist, self.n, self.findings = np.empty(min(budget, 1024)), 0, []
        self.best, self.best_z, self.best_where = math.inf, None, None
        self.best_arc = None                # the worst run's arc (None: it raised)
        self.stop_at_counterexample = stop
        self.error = None                   # a bad claim: raised after the optimizer
        self.failure = None                 # the Finding that stopped the search
        self.interrupted = False
        self._rate, self._last = None, 0    # seconds a run, size of the last chunk
        self.stages = []                    # (first run, what ran from there), in order
        from tqdm.auto import tqdm
        self.bar = tqdm(total=budget, unit="run", disable=None if progress is None
                        else not progress, leave=False)

    @property
    def history(self):
        return self._hist[:self.n]

    @property
    def found(self):
        return self.stop_at_counterexample and self.best < 0

    @property
    def done(self):
        return (self.n >= self.budget or self.interrupted or self.failure is not None
                or self.error is not None or self.found
                or time.perf_counter() >= self.deadline)

    def _fail(self, p, cause, exc, message):
        """A run or claim that failed at p: a finding, the end of the search,
        or the exception raised, as ``on_error`` says; the margin, or None."""
        if self.on_error == "raise":
            exc.add_note(f"(falsify: {message.split(': ', 1)[0]}, at {p!r})")
            raise exc
        if self.on_error == "stop":
            self.failure = Finding(p, cause, message, exc)
            return None
        self.findings.append(Finding(p, cause, message, exc.with_traceback(None)))
        return -math.inf

    def _margin(self, arc, point):
        """(margin, where) of one arc, or None when the search must stop."""
        if not isinstance(arc, HybridArc):
            exc = TypeError(f"run must return a HybridArc, got {type(arc).__name__}: "
                            f"{str(arc)[:80]}")
            return self._fail(point, "NOT_AN_ARC", exc, f"run {_name(self.run)} "
                              f"returned {type(arc).__name__}, not a HybridArc"), None
        cause = arc.termination
        if cause is Termination.CANCELED:   # Ctrl-C inside the engine: not a finding
            self.interrupted = True
            return None, None
        if isinstance(cause, Termination) and cause.name not in self.allow:
            self.findings.append(Finding(point, cause.name, arc.message or ""))
            return -math.inf, None
        try:
            m = self.claim(arc)
        except Exception as exc:  # noqa: BLE001 - the claim failed on this run
            return self._fail(point, "CLAIM_RAISED", exc,
                              f"claim {_name(self.claim)} raised {type(exc).__name__}: "
                              f"{exc}{_where(exc)}"), None
        where = None
        if hasattr(m, "where"):
            where = m.where
        try:
            value = float(m)
        except (TypeError, ValueError):
            self.error = TypeError(f"claim must return a real number (a margin), got "
                                   f"{type(m).__name__} at {point!r}")
            return None, None
        if math.isnan(value):
            self.error = ValueError(f"claim returned NaN at {point!r}: a margin must be a "
                                    f"number (positive: holds, negative: violated)")
            return None, None
        return value, where

    def _record(self, p, arc, message=None, cause="RAISED"):
        """Judge one run (an arc, or the exception its run raised, ``message``
        and ``cause`` saying so): its margin, or None when the search must stop."""
        if isinstance(arc, BaseException) and isinstance(arc.__cause__, KeyboardInterrupt):
            self.interrupted = True         # Ctrl-C as the run started (the engine's
            return None                     # SimulationError from KeyboardInterrupt)
        if isinstance(arc, BaseException):
            message = message or f"{type(arc).__name__}: {arc}{_where(arc)}"
            value, where = self._fail(p, cause, arc, message), None
        else:
            value, where = self._margin(arc, p)
        if value is None:
            return None
        if self.n == len(self._hist):       # grown as runs finish, never past the budget
            grown = np.empty(min(self.budget, 2 * len(self._hist)))
            grown[:self.n] = self._hist
            self._hist = grown
        self._hist[self.n] = value
        self.n += 1
        self.bar.update(1)
        if value < self.best:
            self.best, self.best_z, self.best_where = value, p.z, where
            self.best_arc = arc if isinstance(arc, HybridArc) else None
        return value

    def _bounds(self, size):
        """The planned chunks of a population of ``size`` rows."""
        if not self.stop_at_counterexample:
            return [0, size]
        if self.n == 0:                      # the first population: 1, 2, 4, ... runs
            return [0] + [min(2 ** k, size) for k in range(math.ceil(math.log2(size)) + 1)]
        step = max(8, math.ceil(size / 4))   # later ones: in quarters
        return [*range(0, size, step), size]

    def _fit(self, want):
        """Rows of the next chunk: ``want``, fewer if the deadline comes first."""
        if not self.timed:
            return want
        if self._rate is None:
            return 1                        # the first chunk measures the rate
        left = self.deadline - time.perf_counter()
        fit = int(left / self._rate) if self._rate > 0 else want
        return max(1, min(want, 2 * self._last, fit))

    def _run_batch(self, chunk):
        """The arcs of one chunk of points, or the exception its run raised."""
        start = time.perf_counter()
        try:
            arcs = list(self.run(chunk))
        except Exception as exc:  # noqa: BLE001 - a failed population run: its points
            return exc
        if len(arcs) != len(chunk):
            raise ValueError(f"a batch run must return one arc per point: got "
                             f"{len(arcs)} for {len(chunk)}")
        self._rate = (time.perf_counter() - start) / len(chunk)
        self._last = len(chunk)
        return arcs

    @staticmethod
    def _lost(exc, size):
        """(message, cause) of the points of a population run's chunk that raised."""
        if isinstance(exc, concurrent.futures.BrokenExecutor):
            return (f"a worker of the population run's executor died ({type(exc).__name__}: "
                    f"{exc}) on the chunk of {size} points this one was in: not run",
                    "WORKER_DIED")
        return (f"the population run raised {type(exc).__name__}: {exc}{_where(exc)} on "
                f"the chunk of {size} points this one was in", "RAISED")

    def _renew(self, p, exc):
        """After a dead worker: a fresh executor from the run (``run.renew()``),
        or the end of the search (False) when it has none."""
        renew = getattr(self.run, "renew", None)
        try:
            if callable(renew) and renew():
                return True
        except Exception as e:  # noqa: BLE001 - no fresh pool: the search ends below
            exc = e
        self.failure = Finding(p, "WORKER_DIED", f"the population run's executor broke "
                               f"and could not be renewed: {type(exc).__name__}: {exc}",
                               exc.with_traceback(None))
        return False

    def __call__(self, Z):
        """Margins of the rows of Z (n, dim); +inf for rows not run (past the
        budget, the deadline, or after a counterexample when stopping at the
        first)."""
        Z = np.atleast_2d(Z)
        out = np.full(len(Z), np.inf)
        room = 0 if self.done else max(0, self.budget - self.n)
        rows = Z[:room]
        if not len(rows):
            return out
        # the optimizers' rows are finite and of the space's width; clipped once
        # here, and each made a Point only when its chunk runs (a counterexample
        # in the first chunk builds one Point, not a population of them)
        rows = np.clip(rows, self.space.lo, self.space.hi)
        point = self.space._point
        if self.batch:
            for a, b in itertools.pairwise(self._bounds(len(rows))):
                while a < b and not self.done:
                    c = a + self._fit(b - a)
                    chunk = [point(z) for z in rows[a:c]]
                    arcs = self._run_batch(chunk)
                    broken = None           # the BrokenExecutor of a dead worker
                    if isinstance(arcs, BaseException):
                        exc = arcs
                        if isinstance(exc, concurrent.futures.BrokenExecutor):
                            broken = exc
                        for k, p in enumerate(chunk):
                            value = self._record(p, exc, *self._lost(exc, len(chunk)))
                            if value is None:
                                return out
                            out[a + k] = value
                    else:
                        for k, (p, arc) in enumerate(zip(chunk, arcs)):
                            if getattr(arc, "termination", None) is Termination.CANCELED:
                                self.interrupted = True     # the finished rows still count
                                continue
                            exc = getattr(arc, "exception", None)
                            if isinstance(exc, concurrent.futures.BrokenExecutor):
                                broken = exc            # a row the dead worker lost
                                value = self._record(p, exc, *self._lost(exc, len(chunk)))
                            else:
                                value = self._record(p, arc)
                            if value is None:
                                return out
                            out[a + k] = value
                    if broken is not None and not self._renew(chunk[0], broken):
                        return out
                    a = c
                if self.done:
                    break
        else:
            for k, z in enumerate(rows):
                p = point(z)
                try:
                    arc = self.run(p)
                except Exception as exc:  # noqa: BLE001 - a failed run is a finding
                    arc = exc
                value = self._record(p, arc)
                if value is None:
                    return out
                out[k] = value
                if self.done:
                    break
        return out


def falsify(run: Callable, space: Space, claim: Callable[..., float], *,
            budget: int = 1000, seconds: float = math.inf, seed: int | None = None,
            method: str = "de", popsize: int | None = None, refine: bool | str = True,
            allow: Iterable[str] = ("T_MAX", "J_MAX"), stop: bool = True,
            on_error: str = "finding", progress: bool | None = None) -> FalsificationResult:
    """Search ``space`` for a run on which ``claim``'s margin is negative.

    Parameters
    ----------
    run : callable
        ``run(point) -> HybridArc`` for one point of ``space``
        (:class:`Point`: the entries' values by name); or, when it has an
        attribute ``batch = True`` (:func:`batch_run`), ``run(points) ->
        list of HybridArc`` for a whole population at once.
    space : Space
        What may vary.
    claim : callable
        ``claim(arc) -> margin``: a real number, positive when the claim
        holds on the arc, negative when violated (the ``margin_*`` functions
        of :mod:`hybridsim.testing` return one, with the (t, j) that decided
        it as ``.where``).
    budget : int
        At most this many runs (>= 1).
    seconds : float
        At most this long: checked after every run, and a population run is
        split into chunks expected to end before the deadline, so the search
        overshoots it by at most one chunk of runs.
    seed : int, optional
        The search is reproducible with it.
    method : {"de", "cmaes", "random"}
        ``"de"``: differential evolution (scipy, ``vectorized=True``: each
        generation is one population evaluated at once, deferred updating;
        the first population is run first in this order: the entries'
        extreme members that are not vertices of the box (up to an eighth
        of it: :meth:`Sinusoids.extremes`, the constant signals at ±bound,
        lie on the face f = 0), vertices of the box (a quarter), points on
        its faces and edges (an eighth: each coordinate at a bound with
        probability 1/2), then a Latin hypercube; worst cases under bounded
        uncertainty often lie on the boundary), then a compass search from
        the worst point with what is left of the budget (``refine``: a
        fifth of it is kept for this; each of its iterations, a step along
        every coordinate both ways, and while that does best, every
        coordinate to each of its bounds, is one population too).
        ``FalsificationResult.found_by`` says which of these found the
        worst run. When DE converges before the budget is
        spent (its population collapsed on one point), it restarts with a
        new seed on what is left, so a search that finds nothing has used
        its budget. The first population is run before scipy's solver is
        set up, so a claim its first runs refute costs no solver.
        When a population's margins are all equal (a flat margin: no
        ranking to follow), DE has converged and restarts on fresh designs,
        and the compass search stops.
        ``"cmaes"``: CMA-ES (numpy; Hansen's (mu/mu_w, lambda) strategy with
        his default parameters) over the box scaled to [0, 1], after the
        same seeded first design (``max(2 lambda, 2 dim)`` points) whose
        best point is its first mean, step 0.3; candidates are clipped
        into the box (a worst case on a face is reached exactly). It
        restarts with the population doubled (IPOP) from a uniformly drawn
        mean when it converges, stalls, or meets a margin flat over three
        populations (each widening its step first); ``refine`` does not
        apply. On the ARCH-COMP benchmarks (:mod:`hybridsim.arch`) it needs
        fewer runs than DE to the first counterexample.
        ``"random"``: uniform sampling of the box in populations, the
        baseline to compare with.
    popsize : int, optional
        Population size (default ``max(15, 5 * space.dim)`` for DE, at least
        5; ``4 + floor(3 ln n)`` for CMA-ES, n the free coordinates; 100 for
        random), capped by the budget.
    refine : bool or "gradient"
        Refine the worst point locally by compass search (``"de"`` only).
        ``"gradient"``: by projected gradient descent instead, where ``run``
        has an attribute ``sensitivity``, a callable ``point ->``
        :class:`hybridsim.sensitivity.SensitivityArc` whose parameters are
        the space's coordinates (``hs.simulate_sensitivity(make, x0, ...,
        params=point.z, wrt="params")``); the margin's gradient comes from
        :func:`hybridsim.sensitivity.margin_gradient`, one run a step. Where
        a sensitivity is not defined (a grazing jump...) it falls back to
        the compass search.
    allow : iterable of str
        Termination causes that are ordinary ends of a run; any other cause
        (a blow-up, a map error, a run that raised) is a finding: recorded
        in ``findings`` with its point and counted as margin -inf.
        ``CANCELED`` is neither: a run Ctrl-C cut short ends the search.
    stop : bool
        Stop at the first counterexample (default); False searches the whole
        budget for the worst one.
    on_error : {"finding", "stop", "raise"}
        What a failure of the user's code at a point does: a run that raises
        (or a population run that raises: each of its chunk's points), a run
        that returns something other than a :class:`hybridsim.HybridArc`, a
        claim that raises on a run's arc. ``"finding"`` (default, as for a
        run ending on a failure cause): recorded in ``findings`` with its
        point, cause (``"RAISED"``, ``"NOT_AN_ARC"``, ``"CLAIM_RAISED"``)
        and the exception (type, text, where; the claim or run named), and
        counted as margin -inf. ``"stop"``: the search ends there with the
        results so far (``stopped == "error"``, the failure in ``error``).
        ``"raise"``: the exception propagates at once, a note naming the
        point. A worker of a population run's executor that dies
        (:class:`concurrent.futures.BrokenExecutor`: a process-pool worker
        killed, out of memory...) loses its chunk's points (cause
        ``"WORKER_DIED"``, not re-run: a point that kills its worker would
        kill the next one too); the search goes on with the history and the
        worst point so far, on a fresh pool from ``run.renew()``
        (:func:`batch_run`'s runs have one), or ends there
        (``stopped == "error"``) when the run cannot renew its executor.
    progress : bool, optional
        A progress bar over the runs (default: when stderr is a terminal).

    Returns
    -------
    FalsificationResult
        ``stopped`` says why the search ended. Ctrl-C (KeyboardInterrupt,
        inside a run or between runs) ends it with the results of the runs
        finished before: ``stopped == "interrupted"``, ``interrupted`` True;
        the run it cut short (``CANCELED``) is neither judged nor a finding.

    Raises
    ------
    TypeError, ValueError
        A bad argument (named), or a claim that does not return a real number
        (or returns NaN), raised after the search with the point named.

    Notes
    -----
    CMA-ES follows N. Hansen, "The CMA Evolution Strategy: A Tutorial"
    (arXiv:1604.00772), with IPOP restarts (Auger and Hansen, CEC 2005).
    Differential evolution is scipy's (:func:`scipy.optimize.differential_evolution`):
    derivative-free, global, and it evaluates whole generations at once,
    which is what the batch paths make cheap; PSY-TaLiRo and S-TaLiRo
    default to similar population or annealing searches run one simulation
    at a time.
    """
    if not isinstance(space, Space):
        raise TypeError(f"space must be a hybridsim.falsification.Space, "
                        f"got {type(space).__name__}")
    if not callable(run):
        raise TypeError(f"run must be callable (point -> arc), got {type(run).__name__}")
    if not callable(claim):
        raise TypeError(f"claim must be callable (arc -> margin), got {type(claim).__name__}")
    if isinstance(budget, bool) or not isinstance(budget, (numbers.Integral, np.integer)) \
            or budget < 1:
        raise ValueError(f"budget must be a positive number of runs, got {budget!r}")
    seconds = float(seconds)
    if not seconds > 0:
        raise ValueError(f"seconds must be > 0, got {seconds}")
    if method not in ("de", "cmaes", "random"):
        raise ValueError(f"method must be 'de', 'cmaes' or 'random', got {method!r}")
    if not (refine is True or refine is False or refine == "gradient"):
        raise ValueError(f"refine must be True, False or 'gradient', got {refine!r}")
    if refine == "gradient" and not callable(getattr(run, "sensitivity", None)):
        raise ValueError("refine='gradient' needs run.sensitivity: a callable point -> "
                         "SensitivityArc whose parameters are the space's coordinates "
                         "(hs.simulate_sensitivity(make, x0, ..., params=point.z, "
                         "wrt='params'))")
    if on_error not in ("finding", "stop", "raise"):
        raise ValueError(f"on_error must be 'finding', 'stop' or 'raise', got {on_error!r}")
    allow = frozenset(allow)
    unknown = allow - {c.name for c in Termination}
    if unknown:
        raise ValueError(f"allow names unknown termination causes {sorted(unknown)}")
    budget = int(budget)
    if popsize is not None and (isinstance(popsize, bool) or not isinstance(
            popsize, (numbers.Integral, np.integer)) or popsize < 1):
        raise ValueError(f"popsize must be a positive integer or None, got {popsize!r}")
    if popsize is None and method != "cmaes":
        popsize = max(15, 5 * space.dim) if method == "de" else 100
    if popsize is not None:
        popsize = max(1, min(int(popsize), budget))
    t0 = time.perf_counter()
    ev = _Evaluator(run, space, claim, budget, seconds, allow, progress, stop, on_error)
    fixed = not np.any(space.hi > space.lo)          # a space of one point: one run
    try:
        if fixed:
            ev.stages.append((0, "the space's one point"))
            ev(space.lo[None, :])
        elif method == "random":
            ev.stages.append((0, "random sampling"))
            rng = np.random.default_rng(seed)
            while not ev.done:
                n = min(popsize, budget - ev.n)
                ev(space.lo + (space.hi - space.lo) * rng.random((n, space.dim)))
        elif method == "cmaes":
            _cmaes(ev, space, popsize, seed)
        else:
            seeds = np.random.SeedSequence(seed)
            round_seed, rounds = seed, 0
            while not ev.done:              # restarts while DE converges early
                before = ev.n
                left = budget - before
                _de(ev, space, popsize, round_seed, left - (left // 5 if refine else 0),
                    rnd=rounds)
                rounds += 1
                # a round whose margins all tied has no worst point to refine
                flat = ev.n > before and np.ptp(ev.history[before:]) == 0
                if refine and not ev.done and ev.best_z is not None and not flat:
                    if refine == "gradient":
                        _refine_gradient(ev, space, run.sensitivity)
                    else:
                        _refine(ev, space)
                if ev.n == before:
                    break
                round_seed = int(seeds.spawn(1)[0].generate_state(1)[0])
    except KeyboardInterrupt:               # Ctrl-C between runs, or in the claim
        ev.interrupted = True
    finally:
        ev.bar.close()
    if ev.error is not None:
        raise ev.error
    point = space.point(ev.best_z if ev.best_z is not None else (space.lo + space.hi) / 2)
    arc = ev.best_arc                       # kept as it was judged: no second run
    if arc is None and ev.n and not ev.interrupted and ev.failure is None:
        try:
            arc = run([point])[0] if ev.batch else run(point)
        except (Exception, KeyboardInterrupt):  # noqa: BLE001 - the finding records it
            arc = None
        if not isinstance(arc, HybridArc):
            arc = None
    found = ev.best < 0
    found_by = ""
    if ev.n:
        k = int(np.argmin(ev.history))
        what = [label for first_run, label in ev.stages if first_run <= k]
        found_by = f"{what[-1] if what else method}, run {k + 1} of {ev.n}"
    if ev.interrupted:
        stopped = "interrupted"
    elif ev.failure is not None:
        stopped = "error"
    elif ev.found:
        stopped = "counterexample"
    elif ev.n >= budget:
        stopped = "budget"
    elif time.perf_counter() >= ev.deadline:
        stopped = "seconds"
    else:
        stopped = "converged"
    return FalsificationResult(
        verdict="counterexample" if found else "none found", margin=float(ev.best),
        point=point, arc=arc, where=ev.best_where, history=ev.history.copy(),
        evaluations=ev.n, seconds=time.perf_counter() - t0,
        findings=list(ev.findings), method=method, seed=seed, stopped=stopped,
        error=ev.failure, found_by=found_by)


def _de(ev, space, popsize, seed, budget, rnd=0):
    from scipy.optimize import differential_evolution
    free = space.hi > space.lo
    if not np.any(free):                     # a single point
        ev(space.lo[None, :])
        return
    lo, hi = space.lo[free], space.hi[free]

    def full(Zf):                            # (k, n_free) -> (k, dim)
        Z = np.tile(space.lo, (Zf.shape[0], 1))
        Z[:, free] = Zf
        return Z

    npop = max(5, popsize)
    maxiter = max(0, (budget - npop) // npop)
    init = _seeded(ev, space, free, npop, np.random.default_rng(seed), extremes=rnd == 0)
    # the first population is run before scipy's solver is built (a claim the
    # first runs refute costs no solver setup); the solver's first call, on
    # this population, is answered from it
    first = [ev(full(init))]
    if ev.done:
        return
    ev.stages.append((ev.n, "differential evolution" + (f" (restart {rnd})" if rnd else "")))

    def f(Zt):                               # scipy passes (n_free, k)
        if first:
            return first.pop()
        return ev(full(np.asarray(Zt).T))

    differential_evolution(
        f, list(zip(lo, hi)), maxiter=maxiter, seed=seed, init=init,
        vectorized=True, updating="deferred", polish=False,
        tol=0.0, atol=0.0, callback=lambda *a, **k: ev.done)


def _cmaes(ev, space, popsize, seed):
    """CMA-ES (Hansen's (mu/mu_w, lambda) with his default parameters) over the
    free coordinates scaled to [0, 1], after a seeded first design
    (:func:`_seeded`, ``max(2 lambda, 2 n)`` points) whose best point is the
    first mean; restarts with the population doubled (IPOP) from a fresh
    uniform mean whenever a run converges, stalls or meets a flat margin."""
    free = space.hi > space.lo
    if not np.any(free):
        ev(space.lo[None, :])
        return
    lo, width = space.lo[free], (space.hi - space.lo)[free]
    n = int(free.sum())
    rng = np.random.default_rng(seed)

    def full(U):                             # (k, n_free) in [0, 1] -> (k, dim)
        Z = np.tile(space.lo, (U.shape[0], 1))
        Z[:, free] = lo + np.clip(U, 0.0, 1.0) * width
        return Z

    lam = popsize if popsize is not None else 4 + int(3 * math.log(n))
    lam = max(2, lam)
    init = (_seeded(ev, space, free, max(5, 2 * lam, 2 * n), rng) - lo) / width
    vals = ev(full(init))
    mean = init[int(np.argmin(vals))].copy()
    restart = 0
    while not ev.done:
        ev.stages.append((ev.n, f"CMA-ES, population {lam}"
                          + (f" (restart {restart})" if restart else "")))
        _cma_run(ev, full, mean, 0.3, lam, rng)
        restart += 1
        lam *= 2
        mean = rng.random(n)


def _cma_run(ev, full, mean, sigma, lam, rng):
    """One run of CMA-ES from ``mean`` with step ``sigma`` (unit box), until
    the budget, a counterexample, convergence (sigma below 1e-6 of the box),
    a stall (no better margin in 10 + 30 n / lambda generations) or a
    margin flat over three populations in a row. Candidates are clipped into
    the box and the update uses the clipped ones (a worst case on a face
    is reached exactly)."""
    n = mean.size
    mu = lam // 2
    w = math.log(mu + 0.5) - np.log(np.arange(1, mu + 1))
    w /= w.sum()
    mueff = 1.0 / np.sum(w ** 2)
    cc = (4 + mueff / n) / (n + 4 + 2 * mueff / n)
    cs = (mueff + 2) / (n + mueff + 5)
    c1 = 2 / ((n + 1.3) ** 2 + mueff)
    cmu = min(1 - c1, 2 * (mueff - 2 + 1 / mueff) / ((n + 2) ** 2 + mueff))
    damps = 1 + 2 * max(0.0, math.sqrt((mueff - 1) / (n + 1)) - 1) + cs
    chin = math.sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n * n))
    pc, ps = np.zeros(n), np.zeros(n)
    B, D, C = np.eye(n), np.ones(n), np.eye(n)
    best, since, flat, g = math.inf, 0, 0, 0
    patience = 10 + math.ceil(30 * n / lam)
    while not ev.done:
        X = np.clip(mean + sigma * (rng.standard_normal((lam, n)) * D) @ B.T, 0.0, 1.0)
        f = ev(full(X))
        if ev.done:
            return
        if np.ptp(f) == 0:                   # no ranking: widen, then start afresh
            flat += 1
            if flat >= 3:
                return
            sigma = min(1.0, sigma * math.exp(0.2 + cs / damps))
            continue
        flat, g = 0, g + 1
        if f.min() < best:
            best, since = float(f.min()), 0
        else:
            since += 1
        sel = np.argsort(f, kind="stable")[:mu]
        Y = (X[sel] - mean) / sigma
        yw = w @ Y
        mean = mean + sigma * yw
        ps = (1 - cs) * ps + math.sqrt(cs * (2 - cs) * mueff) * (B @ ((B.T @ yw) / D))
        hsig = (np.linalg.norm(ps) / math.sqrt(1 - (1 - cs) ** (2 * g)) / chin
                < 1.4 + 2 / (n + 1))
        pc = (1 - cc) * pc + hsig * math.sqrt(cc * (2 - cc) * mueff) * yw
        C = ((1 - c1 - cmu) * C + c1 * (np.outer(pc, pc) + (1 - hsig) * cc * (2 - cc) * C)
             + cmu * (Y.T * w) @ Y)
        sigma *= math.exp(cs / damps * (np.linalg.norm(ps) / chin - 1))
        sigma = min(sigma, 1.0)
        C = (C + C.T) / 2
        ev2, B = np.linalg.eigh(C)
        D = np.sqrt(np.maximum(ev2, 1e-20))
        if sigma * D.max() < 1e-6 or since > patience or D.max() > 1e7 * D.min():
            return


def _seeded(ev, space, free, npop, rng, extremes=True):
    """The first population of a search over the free coordinates, (npop,
    n_free), its stages recorded on ``ev``: the entries' extreme members
    (with ``extremes``; a restart has run them already), vertices of the box,
    points on its faces and edges, a Latin hypercube."""
    lo, hi = space.lo[free], space.hi[free]
    nfree = int(free.sum())
    # a Latin hypercube, a quarter of it replaced by vertices of the box: worst
    # cases under bounded uncertainty are often extreme (bang-bang noise). The
    # vertices come first (the first population runs in chunks of 1, 2, 4, ...
    # when the search stops at a counterexample) and are distinct where the
    # box has few of them
    u = (rng.permuted(np.tile(np.arange(npop), (nfree, 1)), axis=1).T
         + rng.random((npop, nfree))) / npop
    nv = min(npop // 4, 2 ** min(nfree, 20))
    if nfree <= 12:
        corners = rng.choice(2 ** nfree, nv, replace=False)
        u[:nv] = (corners[:, None] >> np.arange(nfree)) & 1
    else:
        u[:nv] = rng.integers(0, 2, (nv, nfree))
    # before the vertices, the entries' extreme members that are not vertices
    # (a Sinusoids' constant ±bound signals lie on its face f = 0, with
    # sin φ = 1); after them, points on faces and edges of the box: each
    # coordinate at one of its bounds with probability 1/2, else its Latin
    # hypercube value (a worst case with some parameters at their bounds and
    # the others inside)
    ext = space.extremes(npop // 8, rng) if extremes else np.zeros((0, space.dim))
    ue = (ext[:, free] - lo) / (hi - lo)
    ne = len(ue)
    nf = max(0, min(npop // 8, npop - ne - nv)) if nfree > 1 else 0
    faces = u[nv:nv + nf].copy()
    at = rng.random(faces.shape) < 0.5
    faces[at] = rng.integers(0, 2, int(at.sum()))
    u = np.vstack([ue, u[:nv], faces, u[nv + nf:]])[:npop]
    init = lo + u * (hi - lo)
    n0 = ev.n
    for k, label in ((0, "a seeded extreme member of an entry (its extremes())"),
                     (ne, "a seeded vertex of the box"),
                     (ne + nv, "a seeded point on a face or an edge of the box"),
                     (ne + nv + nf, "the first population's Latin hypercube")):
        ev.stages.append((n0 + k, label))
    return init


def _refine(ev, space):
    """A compass (pattern) search from the worst point: each iteration tries a
    step of +h and -h along every free coordinate as one population, moves to
    the best if it improves, else halves h; steps are clipped into the box, so
    a worst case on a face or a vertex is reached exactly. While moves to a
    bound do best, each iteration also tries every free coordinate at each of
    its bounds (the edges from the point to the faces of the box). It stops
    when h falls below 1e-6, or when every step gave the point's own margin
    (a flat margin: the search's budget goes to fresh designs instead)."""
    free = np.flatnonzero(space.hi > space.lo)
    if not free.size:                        # every coordinate fixed: nothing to move
        return
    width = space.hi - space.lo
    z, best = ev.best_z.copy(), ev.best
    ev.stages.append((ev.n, "the compass search from the worst point"))
    h = 0.1
    snap = True                              # also each coordinate to each bound
    rows = np.arange(free.size)
    while not ev.done and h > 1e-6:
        cand = np.repeat(z[None, :], (4 if snap else 2) * free.size, axis=0)
        cand[rows, free] += h * width[free]
        cand[free.size + rows, free] -= h * width[free]
        if snap:
            cand[2 * free.size + rows, free] = space.lo[free]
            cand[3 * free.size + rows, free] = space.hi[free]
        cand = np.clip(cand, space.lo, space.hi)
        moved = np.any(cand != z, axis=1)    # a coordinate at its bound already: no run
        cand = cand[moved]
        is_snap = (np.arange(len(moved)) >= 2 * free.size)[moved]
        vals = ev(cand) if len(cand) else np.zeros(0)
        if len(vals) and np.all(vals == best):
            return                           # flat at every step: shorter ones tell no more
        k = int(np.argmin(vals)) if len(vals) else -1
        if k >= 0 and vals[k] < best:
            z, best = cand[k], vals[k]
            snap = snap and bool(is_snap[k])  # snapping stops once a step does better
        else:
            snap = False
            h /= 2



class _NoGradient(Exception):
    """The gradient is not defined at a point (or the refinement must stop)."""


def _refine_gradient(ev, space, sensitivity):
    """L-BFGS-B (scipy) from the worst point, on the free coordinates scaled
    to [0, 1], with the margin's gradient from the sensitivities: one run of
    ``sensitivity`` per evaluation, within what is left of the budget. Where
    the gradient is not defined, the compass search takes over."""
    from scipy.optimize import minimize

    from .sensitivity import SensitivityArc, SensitivityError, margin_gradient
    free = np.flatnonzero(space.hi > space.lo)
    if not free.size:
        return
    lo, width = space.lo[free], (space.hi - space.lo)[free]
    z0 = ev.best_z.copy()

    def full(u):
        z = z0.copy()
        z[free] = np.clip(lo + u * width, space.lo[free], space.hi[free])
        return z

    def fun(u):
        if ev.done:
            raise _NoGradient
        p = space.point(full(u))
        try:
            sarc = sensitivity(p)
        except SensitivityError as exc:     # the state's arc is fine, its gradient not
            if exc.arc is not None:
                ev._record(p, exc.arc.arc)
            raise _NoGradient from exc
        except Exception as exc:            # a failed run is a finding
            ev._record(p, exc)
            raise _NoGradient from exc
        if not isinstance(sarc, SensitivityArc) or sarc.system.m != space.dim:
            raise TypeError(f"run.sensitivity must return a SensitivityArc with one "
                            f"parameter per coordinate of the space ({space.dim}), got "
                            f"{sarc!r}")
        value = ev._record(p, sarc.arc)
        if value is None or not math.isfinite(value) or ev.found:
            raise _NoGradient
        try:
            g = margin_gradient(sarc, ev.claim)[free] * width
        except Exception as exc:            # the claim on the perturbed arcs
            raise _NoGradient from exc
        if not np.all(np.isfinite(g)):
            raise _NoGradient
        return value, g

    u0 = np.clip((z0[free] - lo) / width, 0.0, 1.0)
    ev.stages.append((ev.n, "gradient descent from the worst point"))
    try:
        minimize(fun, u0, jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * free.size,
                 options={"maxfun": max(1, ev.budget - ev.n), "ftol": 0.0, "gtol": 0.0})
    except _NoGradient:
        if not ev.done:
            _refine(ev, space)
