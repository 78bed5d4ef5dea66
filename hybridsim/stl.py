r"""Signal temporal logic over hybrid arcs, with quantitative robustness.

Signals are expressions evaluated along an arc: :func:`state` (a component
of x), :func:`signal` / :func:`output` (a user function ``fn(x, t, j)``),
:func:`time` and :func:`jumps` (the jump counter, for discrete modes),
combined with ``+ - * /``, unary ``-`` and ``abs()``. Comparing a signal
makes a predicate (``speed < 120``, ``rpm >= 3000``, ``equals(gear, 3)``);
formulas are built with :func:`always` (:data:`G`), :func:`eventually`
(:data:`F`), :func:`until` (:data:`U`), ``&``, ``|``, ``~``, :func:`implies`
(``>>``). ``phi.robustness(arc)`` (or ``phi(arc)``) is a
:class:`hybridsim.testing.Margin`, so a formula is directly a claim for
:func:`hybridsim.falsify`, works over the solutions of
:func:`hybridsim.explore` and with :func:`hybridsim.sensitivity.margin_gradient`.

Semantics
---------
**Hybrid time.** A signal is a function on the arc's hybrid time domain
E = ∪_j [t_j, t_{j+1}] × {j}: at a jump time both the pre- and the post-jump
values belong to it (two instants (t, j) and (t, j + 1) at the same t).
Time intervals [a, b] are in ordinary time t, and at an instant where the
arc has several j **all** of its values are read, but never one before the
current hybrid instant: ``F[a,b] phi`` at (t, j) is the sup of phi over the
(t', j') of E with t' in [t + a, t + b] and (t', j') not before (t, j) (which
matters only for a = 0: at a jump time, the window of the pre-jump instant
holds both values, that of the post-jump instant the post-jump one), ``G``
the inf. So ``G[0, 2.5] (gear == 2)`` holds right after a shift into gear 2
at the shift's post-jump instant, and ``F[0.001, 0.1] G[0, 2.5] (gear == 2)``
holds just before it; a window that reaches a jump time with t' > t reads
both values there. A formula is evaluated at hybrid time (t, j) (default: the
first j at t, so every value at t counts).

**Robustness** is the Donzé–Maler space robustness: ``sig >= c`` and
``sig > c`` have robustness sig - c, ``sig <= c`` and ``sig < c`` c - sig;
and / or are min / max, ``~`` is negation, ``implies(phi, psi)`` is
``~phi | psi``; ``F`` and ``G`` are sup and inf over their windows and
``phi U[a,b] psi`` at (t, j) is the sup over the instants (t', j') not before
(t, j) with t' in [t+a, t+b] of min(psi(t', j'), inf of phi over the
instants from (t, j) to (t', j') in hybrid time). ``equals(sig, value, tol=0.5)`` has
robustness tol - |sig - value|: on integer-valued signals (gears, modes,
:func:`jumps`) +0.5 where equal and -(d - 0.5) at distance d >= 1 (a
quantitative convention, not a ±1 indicator).

**Dense time.** Each predicate is evaluated at its instants on the arc's
interpolant (:meth:`hybridsim.HybridArc.at`: the solver's dense output where
the run kept one, else cubic Hermite from ``xdot``, else linear): the arc's
samples; the instants where the windows' ends fall (t + a, t + b,
propagated through nested operators); its local maxima and minima inside
the steps (``refine=4``, the default, probes the interpolant at 3 evenly
spaced points of a step and locates each extremum they reveal by parabolic
interpolation to 1e-5 of the step; on an arc with ``xdot``, a predicate
built from :func:`state`, :func:`time`, :func:`jumps` and constants (any
arithmetic and ``abs``) is probed only in the steps where its slope, by the
chain rule from ``xdot``, changes sign; one affine in x and t on a linearly
interpolated arc has no extremum inside a step); and the zeros of its
robustness, root-found by a safeguarded secant to 4 ulp of t.
Between its instants a predicate is taken linear (the piecewise-linear
semantics of Breach), and from there the temporal operators are computed
**exactly**: every breakpoint where a window's end meets an instant
(t - a, t - b), every kink of a max or min of linear pieces and the arc's
jump times are instants of the result, and a result can differ at a point
from its one-sided limits (a window closing on a jump time reads both of its
values). A window's end within the engine's event tolerance
(:func:`hybridsim.rules.event_tolerance`, 4 ulp of max(1, |t|)) of an
instant counts as at it, as in :mod:`hybridsim.testing`: a jump meant for
t = 1 and stored a rounding step early is in ``G[1, 2]``. Hence:

- the *sign* of every predicate is exact at its crossings, and a jump
  located by the engine is an exact instant: ``G[0, 2.5] (gear == 3)`` and
  ``F[0.001, 0.1]`` are decided at the event time, not on a grid;
- the *value* is exact for the piecewise-linear interpolation through the
  predicates' instants; against the arc's own interpolant it errs by at most
  the largest deviation of a predicate from its chord between two
  consecutive instants, which its extrema being instants keeps second
  order in the step (on an arc without dense output or ``xdot`` the
  interpolant is linear, and for affine predicates the result is exact);
- an excursion of a predicate between two of its probes that changes the
  sign of none of them (narrower than a quarter step, by default) is
  missed: use a larger ``refine`` or denser samples. ``refine=1`` reads the
  samples, the window ends and the crossings only.

Until is computed by the identity phi U[a,b] psi = G[0,a] phi ∧
F[a,a] ((phi U psi) ∧ F[0,b-a] psi), exact in the quantitative semantics
(for b = a too: F[0,0] psi keeps the untimed until from reading psi past
t + a, so a value does not depend on the range it is computed over);
the untimed phi U psi is exact at the instants of its operands (their
points, one-sided limits and mutual crossings) and taken linear between.

**Horizon.** ``phi.horizon`` is how far past t the formula reads (b plus
the operand's horizon; infinite for an unbounded window, which reads to the
end of the arc). With ``strict=True`` (default) an arc ending before
t + horizon (beyond the engine's time tolerance) raises ``ValueError``;
``strict=False`` cuts every window at the arc's end (a window that starts
after it is empty: ``F`` gives -inf, ``G`` +inf).

A NaN value of a signal counts as -inf for its predicate (never holds).

Where numba is installed, the windows over signals of 256 instants and more
are computed by a compiled pass (the numpy code's formulas in the same
order: the same robustness to the bit, about three times faster on arcs of
thousands of samples); it is compiled on first use and kept in numba's disk
cache.

Examples
--------
>>> import hybridsim as hs
>>> from hybridsim import stl
>>> from hybridsim.library import BouncingBall
>>> arc = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=1.0)
>>> h = stl.state(0, "h")
>>> phi = stl.G(h <= 1.0) & stl.F(h <= 0.0, 0.0, 0.5)
>>> str(phi)
'(G(h <= 1) & F[0,0.5](h <= 0))'
>>> m = phi(arc)
>>> m.holds, m.where[1]
(True, 0)
>>> round(float(stl.F(h >= 0.5, 0.2, 0.3)(arc)), 4)      # h(0.2) - 0.5 = 0.5 - g 0.2**2 / 2
0.3038
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from ._stl_eval import (
    _INF,
    _combine,
    _num,
    _PredicateEval,
    _robustness,
    _UntilEval,
    _value,
    _WindowEval,
)
from .testing import _is_arc

__all__ = ["Signal", "Formula", "state", "signal", "output", "time", "jumps", "const",
           "equals", "always", "eventually", "until", "implies", "G", "F", "U"]


from ._stl_signal import (  # noqa: F401  (re-exported)
    Signal,
    _as_signal,
    _Bin,
    _Const,
    _Fn,
    _index,
    _Jumps,
    _name,
    _State,
    _Time,
    _Unary,
    const,
    jumps,
    output,
    signal,
    state,
    time,
)

# documented where the user imports them
for _pub in (Signal, const, jumps, output, signal, state, time):
    _pub.__module__ = __name__
del _pub


def _real(v, what):
    if isinstance(v, bool) or not isinstance(v, (numbers.Real, np.integer, np.floating)):
        raise TypeError(f"{what} must be a real number, got {type(v).__name__}")
    v = float(v)
    if math.isnan(v):
        raise ValueError(f"{what} must be a number, got NaN")
    return v


def _interval(a, b, where):
    a = _real(a, f"{where}: a")
    b = _real(b, f"{where}: b")
    if not (0 <= a < _INF):
        raise ValueError(f"{where}: a must be finite and >= 0 (the window [a, b] starts "
                         f"a time units after t), got a = {a!r}")
    if b < a:
        raise ValueError(f"{where}: b must be >= a (the window [a, b]), got a = {a!r}, "
                         f"b = {b!r}")
    return a, b


def _as_formula(phi, what):
    if isinstance(phi, Formula):
        return phi
    if isinstance(phi, Signal):
        raise TypeError(f"{what} must be a stl formula, got the signal {phi}: compare it "
                        f"(sig >= c) to make a predicate")
    raise TypeError(f"{what} must be a stl formula (a predicate such as state(0) >= 0, or "
                    f"one built from them), got {type(phi).__name__}")


# ----------------------------------------------------------------- formulas --

class Formula:
    """A signal temporal logic formula over hybrid arcs.

    Build formulas from predicates (comparisons of :class:`Signal`) with
    ``&``, ``|``, ``~``, ``>>`` (implies), :func:`always`,
    :func:`eventually`, :func:`until`. ``str(phi)`` prints it in the usual
    STL syntax; ``phi(arc)`` is :meth:`robustness`.

    Attributes
    ----------
    horizon : float
        How far past t the formula reads the arc (``inf``: to its end).

    Examples
    --------
    >>> x = state(0)
    >>> phi = always((x > 1) >> eventually(x < 0.5, 0, 2), 0, 10)
    >>> str(phi), phi.horizon
    ('G[0,10]((x[0] > 1) -> F[0,2](x[0] < 0.5))', 12.0)
    """

    horizon: float = 0.0

    def __and__(self, other):
        return _And(self, _as_formula(other, "the right operand of &"))

    def __rand__(self, other):
        return _And(_as_formula(other, "the left operand of &"), self)

    def __or__(self, other):
        return _Or(self, _as_formula(other, "the right operand of |"))

    def __ror__(self, other):
        return _Or(_as_formula(other, "the left operand of |"), self)

    def __invert__(self):
        return _Not(self)

    def __rshift__(self, other):
        return _Implies(self, _as_formula(other, "the right operand of >>"))

    def __bool__(self):
        raise TypeError("a stl formula has no truth value: combine formulas with &, |, ~ "
                        "(not `and`, `or`, `not`, nor chained comparisons a < s < b); "
                        "evaluate one with phi.robustness(arc)")

    __hash__ = object.__hash__

    def __repr__(self):
        return f"stl.Formula({self})"

    def __call__(self, arc, t=0.0, **kw):
        return self.robustness(arc, t, **kw)

    def robustness(self, arc, t=0.0, *, j=None, strict=True, refine=4):
        """The robustness of the formula on ``arc`` at hybrid time (t, j).

        Parameters
        ----------
        arc : HybridArc, SolutionTree or iterable of HybridArc
            The solution, or every solution (the worst is returned, as by
            the :mod:`hybridsim.testing` margins; a merged branch's prefix,
            which ends where it merges, is read with ``strict=False``).
        t : float
            The time at which the formula is evaluated (in the arc's range).
        j : int, optional
            The jump count at t (default the first at t; matters only for a
            formula that is a predicate or a Boolean combination of them).
        strict : bool
            Raise when the arc ends before ``t + horizon`` (beyond the
            engine's time tolerance); False: cut windows at the arc's end.
        refine : int
            Evaluate every predicate at ``refine - 1`` evenly spaced
            interpolant points inside each step of the arc and at the local
            extrema they reveal (located by parabolic interpolation), so that
            its maxima and minima between samples are instants (default 4;
            1: the samples, crossings and window ends only).

        Returns
        -------
        Margin
            The robustness, with ``where`` the instant (t, j) of the
            predicate that decides it, ``what`` the formula's text, and for
            a formula ``G[a,b] phi`` the ``series`` of phi's robustness over
            the window (its minimum is the margin).

        Raises
        ------
        TypeError, ValueError
            A bad argument (named), an empty arc, t outside it, or an arc
            shorter than t + horizon with ``strict=True``.

        Examples
        --------
        >>> import hybridsim as hs
        >>> arc = hs.HybridArc([0.0, 1.0, 2.0], [0, 0, 0], [[0.0], [2.0], [0.0]], None)
        >>> m = always(state(0) <= 1.5, 0, 2).robustness(arc)
        >>> float(m), m.where
        (-0.5, (1.0, 0))
        """
        if not isinstance(strict, (bool, np.bool_)):
            raise TypeError(f"robustness: strict must be a bool, got {type(strict).__name__}")
        if isinstance(refine, bool) or not isinstance(refine, (numbers.Integral, np.integer)) \
                or refine < 1:
            raise ValueError(f"robustness: refine must be an int >= 1, got {refine!r}")
        t = _real(t, "robustness: t")
        if j is not None and (isinstance(j, bool)
                              or not isinstance(j, (numbers.Integral, np.integer))):
            raise TypeError(f"robustness: j must be an int or None, got {type(j).__name__}")
        if not _is_arc(arc) and not hasattr(arc, "__iter__"):
            raise TypeError(f"robustness: arc must be a HybridArc, a SolutionTree or an "
                            f"iterable of HybridArc, got {type(arc).__name__}")
        return _robustness(arc, self, t, j, bool(strict), int(refine))

    # the evaluation: a signal on [lo, hi] (cached per node and range)
    def _sig(self, ctx, lo, hi, probes):
        key = (id(self), lo, hi)
        hit = ctx.memo.get(key)
        if hit is None or hit[0] is not self:
            hit = ctx.memo[key] = (self, self._compute(ctx, lo, hi, probes))
        return hit[1]

    def _compute(self, ctx, lo, hi, probes):  # pragma: no cover - every subclass defines it
        raise NotImplementedError

    def _decide(self, ctx, lo, hi, tau, j, target):
        """The instant (t, j) of the predicate deciding the value at (tau, j)."""
        return tau, j


class _Predicate(_PredicateEval, Formula):
    """A predicate: robustness ``rho`` (a signal) >= 0, printed as ``text``."""

    def __init__(self, rho, text):
        self.rho, self.text = rho, text

    def __str__(self):
        return self.text


def _wrap(phi):
    """A formula's text as an operand: a predicate in parentheses."""
    return f"({phi})" if isinstance(phi, _Predicate) else str(phi)


def _compare(sig, op, other):
    rhs = _as_signal(other, f"the right side of {op}")
    text = f"{sig} {op} {rhs}"
    rho = rhs - sig if op in ("<", "<=") else sig - rhs
    return _Predicate(rho, text)


Signal._predicate = staticmethod(_compare)   # a comparison of signals makes a predicate


def equals(sig, value, tol=0.5):
    """The predicate ``sig == value``, with robustness ``tol - |sig - value|``.

    For integer-valued signals (gears, modes, :func:`jumps`) the default
    ``tol = 0.5`` gives +0.5 where equal and -(d - 0.5) at distance d >= 1:
    the sign decides equality, the size says how far the mode is from it.

    Parameters
    ----------
    sig : Signal or number
    value : Signal or number
    tol : float
        >= 0: how close counts as equal.

    Examples
    --------
    >>> import hybridsim as hs
    >>> arc = hs.HybridArc([0.0, 1.0, 1.0, 2.0], [0, 0, 1, 1],
    ...                    [[1.0], [1.0], [2.0], [2.0]], None)
    >>> gear = state(0, "gear")
    >>> float(always(equals(gear, 1), 0, 0.9)(arc)), float(always(equals(gear, 1), 0, 1)(arc))
    (0.5, -0.5)
    """
    s = _as_signal(sig, "equals: sig")
    v = _as_signal(value, "equals: value")
    tol = _real(tol, "equals: tol")
    if not (0 <= tol < _INF):
        raise ValueError(f"equals: tol must be finite and >= 0, got {tol!r}")
    text = f"{s} == {v}" if tol == 0.5 else f"|{s} - {v}| <= {_num(tol)}"
    return _Predicate(tol - abs(s - v), text)


class _Not(Formula):
    def __init__(self, phi):
        self.phi = phi
        self.horizon = phi.horizon

    def __str__(self):
        return f"~{_wrap(self.phi)}"

    def _compute(self, ctx, lo, hi, probes):
        return self.phi._sig(ctx, lo, hi, probes).neg()

    def _decide(self, ctx, lo, hi, tau, j, target):
        return self.phi._decide(ctx, lo, hi, tau, j, -target)


class _Binary(Formula):
    op_text = "?"
    op = staticmethod(np.minimum)

    def __init__(self, phi, psi):
        self.phi, self.psi = phi, psi
        self.horizon = max(phi.horizon, psi.horizon)

    def __str__(self):
        return f"({_wrap(self.phi)} {self.op_text} {_wrap(self.psi)})"

    def _parts(self, ctx, lo, hi, probes):
        return self.phi._sig(ctx, lo, hi, probes), self.psi._sig(ctx, lo, hi, probes)

    def _compute(self, ctx, lo, hi, probes):
        s1, s2 = self._parts(ctx, lo, hi, probes)
        return _combine(s1, s2, self.op)

    def _decide(self, ctx, lo, hi, tau, j, target):
        s1, s2 = self._parts(ctx, lo, hi, ())
        v1, v2 = _value(s1, tau, j), _value(s2, tau, j)
        imp = isinstance(self, _Implies)        # a tie: the consequent is the reason
        sgn = -1.0 if imp else 1.0
        d1, d2 = abs(sgn * v1 - target), abs(v2 - target)
        if d1 < d2 or (d1 == d2 and not imp):
            return self.phi._decide(ctx, lo, hi, tau, j, sgn * target)
        return self.psi._decide(ctx, lo, hi, tau, j, target)


class _And(_Binary):
    op_text = "&"
    op = staticmethod(np.minimum)


class _Or(_Binary):
    op_text = "|"
    op = staticmethod(np.maximum)


class _Implies(_Binary):
    op_text = "->"
    op = staticmethod(np.maximum)

    def _parts(self, ctx, lo, hi, probes):
        return self.phi._sig(ctx, lo, hi, probes).neg(), self.psi._sig(ctx, lo, hi, probes)


def implies(phi, psi):
    """``phi -> psi``, i.e. ``~phi | psi`` (also written ``phi >> psi``).

    Examples
    --------
    >>> x = state(0)
    >>> str(implies(x > 1, x > 0))
    '((x[0] > 1) -> (x[0] > 0))'
    """
    return _Implies(_as_formula(phi, "implies: phi"), _as_formula(psi, "implies: psi"))


class _Window(_WindowEval, Formula):
    """F[a,b] (sup) or G[a,b] (inf) of a formula."""

    def __init__(self, phi, a, b, sup):
        self.phi, self.a, self.b, self.sup = phi, a, b, sup
        self.horizon = b + phi.horizon

    def __str__(self):
        name = "F" if self.sup else "G"
        win = "" if self.a == 0 and math.isinf(self.b) else f"[{_num(self.a)},{_num(self.b)}]"
        inner = str(self.phi)
        return f"{name}{win}{inner}" if isinstance(self.phi, (_Binary, _Until)) \
            else f"{name}{win}({inner})"


def _check_formula_args(phi, a, b, where):
    phi = _as_formula(phi, f"{where}: phi")
    a, b = _interval(a, b, where)
    return phi, a, b


def always(phi, a=0.0, b=_INF):
    """``G[a,b] phi``: phi holds at every instant of [t + a, t + b] (inf over it).

    Parameters
    ----------
    phi : Formula
    a, b : float
        The window, 0 <= a <= b (b may be ``inf``: to the end of the arc).

    Examples
    --------
    >>> str(always(state(0) >= 0, 0, 2.5)), str(always(state(0) >= 0))
    ('G[0,2.5](x[0] >= 0)', 'G(x[0] >= 0)')
    """
    phi, a, b = _check_formula_args(phi, a, b, "always")
    return _Window(phi, a, b, sup=False)


def eventually(phi, a=0.0, b=_INF):
    """``F[a,b] phi``: phi holds at some instant of [t + a, t + b] (sup over it).

    Parameters
    ----------
    phi : Formula
    a, b : float
        The window, 0 <= a <= b (b may be ``inf``).

    Examples
    --------
    >>> str(eventually(state(0) < 1, 0.001, 0.1))
    'F[0.001,0.1](x[0] < 1)'
    """
    phi, a, b = _check_formula_args(phi, a, b, "eventually")
    return _Window(phi, a, b, sup=True)


class _Until(_UntilEval, Formula):
    def __init__(self, phi, psi, a, b):
        self.phi, self.psi, self.a, self.b = phi, psi, a, b
        self.horizon = b + max(phi.horizon, psi.horizon)

    def __str__(self):
        win = "" if self.a == 0 and math.isinf(self.b) else f"[{_num(self.a)},{_num(self.b)}]"
        return f"({_wrap(self.phi)} U{win} {_wrap(self.psi)})"


def until(phi, psi, a=0.0, b=_INF):
    """``phi U[a,b] psi``: psi holds at some t' in [t + a, t + b] and phi on [t, t'].

    Robustness: sup over t' in the window of min(psi(t'), inf over [t, t'] of
    phi) (every j at each instant).

    Parameters
    ----------
    phi, psi : Formula
    a, b : float
        The window, 0 <= a <= b (b may be ``inf``).

    Examples
    --------
    >>> x = state(0)
    >>> str(until(x < 1, x > 2, 0, 5))
    '((x[0] < 1) U[0,5] (x[0] > 2))'
    """
    phi = _as_formula(phi, "until: phi")
    psi = _as_formula(psi, "until: psi")
    a, b = _interval(a, b, "until")
    return _Until(phi, psi, a, b)


G = always
F = eventually
U = until
