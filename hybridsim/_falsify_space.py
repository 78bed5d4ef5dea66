"""The uncertainty spaces of :mod:`hybridsim.falsification`: the bounded
entries (an interval, a box, piecewise-constant, control-point and sinusoid
signals, sampling gaps), a point of a space, and the space itself.
"""
from __future__ import annotations

import itertools
import math
import numbers
from collections.abc import Mapping

import numpy as np


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


def _coarse_grid(times, interpolation, k, t_end, dim, lo, hi):
    """``(E, lo, hi)`` of a signal on the grid ``times`` (its values point by
    point, ``dim`` components each) from the same kind of signal on ``k``
    points of [0, t_end]: the coarse signal's value at each of ``times``
    (held from the coarse piece's start, or linear between the coarse
    points), so each row of ``E`` is a convex combination and ``E @ c`` is in
    the box; the entry itself when ``k`` is not fewer points."""
    n = len(times)
    if k >= n:
        return np.eye(n * dim), lo, hi
    if interpolation == "linear":
        knots = np.linspace(0.0, t_end, k)
        T = np.stack([np.interp(times, knots, np.eye(k)[j]) for j in range(k)], axis=1)
    else:
        T = np.zeros((n, k))
        T[np.arange(n), np.minimum((np.asarray(times) * k / t_end).astype(int), k - 1)] = 1.0
    return np.kron(T, np.eye(dim)), lo[:k * dim], hi[:k * dim]


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

    def coarse(self, factor):
        """A coarser encoding of part of the entry's box: ``E`` (size, m) with
        ``E @ c`` in the box for every ``c`` in ``[lo, hi]`` (m,), the
        triple ``(E, lo, hi)``; by default the entry itself (``E`` the
        identity)."""
        lo, hi = self.bounds()
        return np.eye(self.size), lo, hi

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

    def coarse(self, factor):
        """The signals constant on ``ceil(pieces / factor)`` equal pieces
        (:func:`_coarse_grid`)."""
        k = math.ceil(self.pieces / factor)
        starts = self.t_end / self.pieces * np.arange(self.pieces)
        return _coarse_grid(starts, "previous", k, self.t_end, self.dim, *self.bounds())

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

    def coarse(self, factor):
        """The same kind of signal through fewer control points: for
        ``"linear"``, ``d + 1`` of the entry's own points, ``d`` the smallest
        divisor of ``points - 1`` at least ``(points - 1) / factor`` (every
        coarse signal is then one of the entry's, its kinks at the entry's
        times); ``ceil(points / factor)`` pieces for ``"previous"``
        (:func:`_coarse_grid`)."""
        linear = self.interpolation == "linear"
        if linear:
            n = self.points - 1
            k = 1 + min(d for d in range(math.ceil(n / factor), n + 1) if n % d == 0)
        else:
            k = math.ceil(self.points / factor)
        return _coarse_grid(self.times, self.interpolation, k, self.t_end, self.dim,
                            *self.bounds())

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

    def coarse(self, factor):
        """The space's signals (:class:`PiecewiseConstant`, :class:`ControlPoints`)
        on grids ``factor`` times coarser, its other entries as they are:
        ``(E, lo, hi)``, ``E`` (dim, m) block-diagonal, ``E @ c`` in the box for
        every ``c`` in ``[lo, hi]`` (m,); ``m == dim`` when no entry has a
        coarser grid.

        Examples
        --------
        >>> s = Space(u=ControlPoints(0.0, 1.0, 10.0, points=8), k=Interval(1.0, 2.0))
        >>> E, lo, hi = s.coarse(4)
        >>> E.shape, (E @ [0.25, 0.75, 1.5])[[0, 1, 2, 7, 8]].tolist()
        ((9, 3), [0.25, 0.25, 0.25, 0.75, 1.5])
        """
        if not factor >= 1:
            raise ValueError(f"factor must be >= 1, got {factor!r}")
        parts = [e.coarse(factor) for e in self.entries.values()]
        m = sum(E.shape[1] for E, _, _ in parts)
        E, r, c = np.zeros((self.dim, m)), 0, 0
        for Ei, _, _ in parts:
            E[r:r + Ei.shape[0], c:c + Ei.shape[1]] = Ei
            r, c = r + Ei.shape[0], c + Ei.shape[1]
        return (E, np.concatenate([lo for _, lo, _ in parts]),
                np.concatenate([hi for _, _, hi in parts]))

    def sample(self, n, seed=None) -> np.ndarray:
        """``n`` coordinate vectors drawn uniformly from the box, shape (n, dim)."""
        rng = np.random.default_rng(seed)
        return self.lo + (self.hi - self.lo) * rng.random((_count("n", n), self.dim))

    def __repr__(self):
        return "Space(" + ", ".join(f"{n}={e!r}" for n, e in self.entries.items()) + ")"
