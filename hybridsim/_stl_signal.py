"""The signals of :mod:`hybridsim.stl`: expressions evaluated along an arc.

Public names are re-exported by :mod:`hybridsim.stl`, where they are documented.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from ._stl_eval import _num
from .system import as_map

# ------------------------------------------------------------------ signals --

class Signal:
    """An expression evaluated along an arc (a scalar at every hybrid instant).

    Made by :func:`state`, :func:`signal`, :func:`output`, :func:`time`,
    :func:`jumps`, :func:`const`; combined with ``+ - * /`` (with numbers or
    signals), unary ``-`` and ``abs()``. Comparing it with ``<, <=, >, >=``
    gives a predicate (a :class:`Formula`); for equality use :func:`equals`.

    Examples
    --------
    >>> v = state(1, "v")
    >>> str(abs(2 * v - 1) <= 0.5)
    '|((2 * v) - 1)| <= 0.5'
    """

    _predicate = None    # ``stl._compare``, set by :mod:`hybridsim.stl`

    def _values(self, T, J, X):  # pragma: no cover - every subclass defines it
        raise NotImplementedError

    def _affine(self):
        """``({i: c_i}, c_t)`` where the signal is sum c_i x_i + c_t t + const
        (within a flow), else None."""
        return None

    def _dt(self, T, J, X, XD):
        """The time derivative along the flow at the samples, by the chain rule
        from ``XD`` (xdot), or None where unknown (a user function)."""
        return None

    def _bin(self, other, op, name, swap=False):
        o = _as_signal(other, f"the operand of {name}")
        a, b = (o, self) if swap else (self, o)
        return _Bin(a, b, op, name)

    def __add__(self, o):
        return self._bin(o, np.add, "+")

    def __radd__(self, o):
        return self._bin(o, np.add, "+", swap=True)

    def __sub__(self, o):
        return self._bin(o, np.subtract, "-")

    def __rsub__(self, o):
        return self._bin(o, np.subtract, "-", swap=True)

    def __mul__(self, o):
        return self._bin(o, np.multiply, "*")

    def __rmul__(self, o):
        return self._bin(o, np.multiply, "*", swap=True)

    def __truediv__(self, o):
        return self._bin(o, np.divide, "/")

    def __rtruediv__(self, o):
        return self._bin(o, np.divide, "/", swap=True)

    def __neg__(self):
        return _Unary(self, np.negative, "-{}")

    def __pos__(self):
        return self

    def __abs__(self):
        return _Unary(self, np.abs, "|{}|")

    def __lt__(self, o):
        return self._predicate(self, "<", o)

    def __le__(self, o):
        return self._predicate(self, "<=", o)

    def __gt__(self, o):
        return self._predicate(self, ">", o)

    def __ge__(self, o):
        return self._predicate(self, ">=", o)

    __hash__ = object.__hash__

    def __bool__(self):
        raise TypeError("a stl.Signal has no truth value: compare it (sig >= c) to make a "
                        "predicate, and combine predicates with &, |, ~")

    def __repr__(self):
        return f"stl.Signal({self})"


def _as_signal(v, what):
    if isinstance(v, Signal):
        return v
    if isinstance(v, (numbers.Real, np.integer, np.floating)) and not isinstance(v, bool):
        if math.isnan(float(v)):
            raise ValueError(f"{what} must not be NaN")
        return _Const(float(v))
    raise TypeError(f"{what} must be a number or a stl.Signal, got {type(v).__name__}")


class _Const(Signal):
    def __init__(self, c):
        self.c = float(c)

    def _affine(self):
        return {}, 0.0

    def _dt(self, T, J, X, XD):
        return np.zeros(len(T))

    def _values(self, T, J, X):
        return np.full(len(T), self.c)

    def __str__(self):
        return _num(self.c)


class _State(Signal):
    def __init__(self, i, name):
        self.i, self.name = i, name

    def _affine(self):
        return {self.i: 1.0}, 0.0

    def _dt(self, T, J, X, XD):
        return XD[:, self.i]

    def _values(self, T, J, X):
        if self.i >= X.shape[1] or self.i < -X.shape[1]:
            raise IndexError(f"stl.state({self.i}): the arc's state has {X.shape[1]} "
                             f"components")
        return X[:, self.i]

    def __str__(self):
        return self.name if self.name is not None else f"x[{self.i}]"


class _Time(Signal):
    def _values(self, T, J, X):
        return np.asarray(T, float)

    def _affine(self):
        return {}, 1.0

    def _dt(self, T, J, X, XD):
        return np.ones(len(T))

    def __str__(self):
        return "t"


class _Jumps(Signal):
    def _values(self, T, J, X):
        return np.asarray(J, float)

    def _affine(self):
        return {}, 0.0                          # constant within a flow

    def _dt(self, T, J, X, XD):
        return np.zeros(len(T))

    def __str__(self):
        return "j"


class _Fn(Signal):
    """A user function fn(x, t, j) -> float, tried over all samples at once."""

    def __init__(self, fn, name, what):
        self.f = as_map(fn, what)
        self.fn, self.what = fn, what
        self.name = name if name is not None else getattr(fn, "__name__", "signal")
        if self.name == "<lambda>":
            self.name = "signal"

    def __getstate__(self):                     # the wrapper is remade, not pickled
        return {k: v for k, v in self.__dict__.items() if k != "f"}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.f = as_map(self.fn, self.what)

    def _row(self, x, t, j):
        y = np.asarray(self.f(x, float(t), int(j), None), dtype=float)
        if y.size != 1:
            raise ValueError(f"{self.what}: fn must return a scalar, got shape {y.shape} "
                             f"at (t={float(t)!r}, j={int(j)})")
        return float(y.reshape(()))

    def _values(self, T, J, X):
        m = len(T)
        if m == 0:
            return np.zeros(0)
        if m > 1:
            try:
                with np.errstate(all="ignore"):
                    y = np.asarray(self.f(X, T, J, None), dtype=float)
            except Exception:  # noqa: BLE001 - a map of one state: row by row
                y = None
            if y is not None and y.shape == (m,):
                probe = sorted({0, m // 2, m - 1})
                ref = np.array([self._row(X[k], T[k], J[k]) for k in probe])
                got = y[probe]
                if np.all((got == ref) | (np.isnan(got) & np.isnan(ref))
                          | np.isclose(got, ref, rtol=1e-12, atol=0.0)):
                    return y
        return np.array([self._row(x, t, j) for x, t, j in zip(X, T, J)])

    def __str__(self):
        return self.name


class _Bin(Signal):
    def __init__(self, a, b, op, name):
        self.a, self.b, self.op, self.name = a, b, op, name

    def _values(self, T, J, X):
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.op(self.a._values(T, J, X), self.b._values(T, J, X))

    def __str__(self):
        return f"({self.a} {self.name} {self.b})"

    def _affine(self):
        fa, fb = self.a._affine(), self.b._affine()
        if fa is None or fb is None:
            return None
        if self.name in "+-":
            sg = 1.0 if self.name == "+" else -1.0
            c = dict(fa[0])
            for i, w in fb[0].items():
                c[i] = c.get(i, 0.0) + sg * w
            return c, fa[1] + sg * fb[1]
        # a product or quotient is affine when the factor is a constant
        if self.name == "*" and isinstance(self.a, _Const):
            return {i: self.a.c * w for i, w in fb[0].items()}, self.a.c * fb[1]
        if isinstance(self.b, _Const) and self.b.c != 0:
            k = self.b.c if self.name == "*" else 1.0 / self.b.c
            return {i: k * w for i, w in fa[0].items()}, k * fa[1]
        return None

    def _dt(self, T, J, X, XD):
        da, db = self.a._dt(T, J, X, XD), self.b._dt(T, J, X, XD)
        if da is None or db is None:
            return None
        if self.name == "+":
            return da + db
        if self.name == "-":
            return da - db
        a, b = self.a._values(T, J, X), self.b._values(T, J, X)
        with np.errstate(divide="ignore", invalid="ignore"):
            return da * b + a * db if self.name == "*" else (da * b - a * db) / (b * b)


class _Unary(Signal):
    def __init__(self, a, op, fmt):
        self.a, self.op, self.fmt = a, op, fmt

    def _values(self, T, J, X):
        return self.op(self.a._values(T, J, X))

    def _affine(self):
        f = self.a._affine() if self.op is np.negative else None
        return None if f is None else ({i: -w for i, w in f[0].items()}, -f[1])

    def _dt(self, T, J, X, XD):
        d = self.a._dt(T, J, X, XD)
        if d is None:
            return None
        if self.op is np.negative:
            return -d
        return np.sign(self.a._values(T, J, X)) * d      # |a|: a kink where a = 0

    def __str__(self):
        return self.fmt.format(self.a)


def _index(i):
    if isinstance(i, bool) or not isinstance(i, (numbers.Integral, np.integer)):
        raise TypeError(f"stl.state: i must be an int (a component of x), got "
                        f"{type(i).__name__}")
    return int(i)


def _name(name, where):
    if name is not None and not isinstance(name, str):
        raise TypeError(f"{where}: name must be a str or None, got {type(name).__name__}")
    return name


def state(i, name=None):
    """Component ``i`` of the state x, as a signal.

    Parameters
    ----------
    i : int
        The component (negative counts from the end).
    name : str, optional
        How the formula prints it (default ``x[i]``).

    Examples
    --------
    >>> str(state(0) >= 0), str(state(2, "gear") < 3)
    ('x[0] >= 0', 'gear < 3')
    """
    return _State(_index(i), _name(name, "stl.state"))


def signal(fn, name=None):
    """A signal ``fn(x, t, j)`` (or ``fn(x)``, ``fn(x, t)``) returning a scalar.

    It is first called once over all instants, with x of shape (m, n) and
    t, j of shape (m,) (the engine's convention for vectorized maps: write
    ``x[..., k]``); where that fails, returns another shape or disagrees
    with single calls at three probe rows, it is called row by row with
    x of shape (n,).

    Parameters
    ----------
    fn : callable
    name : str, optional
        How the formula prints it (default: the function's name).

    Examples
    --------
    >>> energy = signal(lambda x: 9.81 * x[..., 0] + x[..., 1] ** 2 / 2, "E")
    >>> str(energy <= 10)
    'E <= 10'
    """
    if isinstance(fn, Signal):
        return fn
    if not callable(fn):
        raise TypeError(f"stl.signal: fn must be a callable fn(x, t, j), got "
                        f"{type(fn).__name__}")
    return _Fn(fn, _name(name, "stl.signal"), "stl.signal: fn")


def output(fn, name=None):
    """An output ``fn(x, t, j)`` of the system as a signal (:func:`signal`).

    Examples
    --------
    >>> str(output(lambda x: x[..., 0] * 3.6, "kmh") > 100)
    'kmh > 100'
    """
    if isinstance(fn, Signal):
        return fn
    if not callable(fn):
        raise TypeError(f"stl.output: fn must be a callable fn(x, t, j), got "
                        f"{type(fn).__name__}")
    return _Fn(fn, _name(name, "stl.output"), "stl.output: fn")


def time():
    """Ordinary time t as a signal.

    Examples
    --------
    >>> str(time() <= 5)
    't <= 5'
    """
    return _Time()


def jumps():
    """The jump counter j as a signal (a discrete mode that counts jumps).

    Examples
    --------
    >>> str(equals(jumps(), 2))
    'j == 2'
    """
    return _Jumps()


def const(c):
    """A constant signal.

    Examples
    --------
    >>> str(const(2.5) + time())
    '(2.5 + t)'
    """
    return _as_signal(c, "stl.const: c")
