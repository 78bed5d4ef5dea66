"""Locating where a flow enters D or leaves C within one solver step."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["locate_event", "event_tolerance"]

_EPS = np.finfo(float).eps


def event_tolerance(a, b):
    """Width to which an event time is bracketed: 4 ulp of the time scale."""
    return 4.0 * _EPS * max(1.0, abs(a), abs(b))


def locate_event(sol, a, b, pred, phi=None, max_iter=200):
    """Bracket the first time in (a, b] at which ``pred`` becomes true.

    Parameters
    ----------
    sol : callable
        The step's dense output, ``sol(s) -> x(s)``.
    a, b : float
        The step; ``pred`` is false at a (or a is on the boundary) and true at b.
    pred : callable
        ``pred(s, x) -> bool``: the event has happened at (s, x). It decides
        membership, so the returned ``hi`` always satisfies it.
    phi : callable, optional
        A continuous guard, ``phi(s, x) >= 0`` where the event has happened.
        Where it brackets a sign change, a safeguarded Illinois (regula falsi)
        step replaces bisection: a few evaluations instead of ~50.

    Returns
    -------
    lo, hi, x_lo, x_hi
        ``hi - lo <= 4 eps max(1, |t|)``, ``pred`` false at lo (or lo = a),
        true at hi.

    Notes
    -----
    A step that starts on the boundary of D (a guard exactly 0 just after a
    jump) is handled: the bracket is refined by the indicator until the guard
    changes sign inside it, so a flow that re-enters D within one step is
    never lost.
    """
    tol = event_tolerance(a, b)
    lo, hi = float(a), float(b)
    ylo, yhi = sol(lo), sol(hi)
    if phi is not None:
        flo, fhi = phi(lo, ylo), phi(hi, yhi)
    side = 0
    last_width = hi - lo
    bisect_next = False
    for _ in range(max_iter):
        width = hi - lo
        if width <= tol:
            break
        m = 0.5 * (lo + hi)
        if phi is not None and not bisect_next and flo < 0.0 <= fhi and fhi - flo > 0:
            r = hi - fhi * (hi - lo) / (fhi - flo)
            if lo < r < hi:
                # keep the probe off the ends so the bracket always shrinks
                g = max(tol, 1e-3 * width)
                m = min(max(r, lo + 0.5 * g), hi - 0.5 * g)
                if not lo < m < hi:
                    m = 0.5 * (lo + hi)
        ym = sol(m)
        if pred(m, ym):
            hi, yhi = m, ym
            if phi is not None:
                fhi = phi(m, ym)
                if side == 1:
                    flo *= 0.5       # Illinois: the other end has stayed twice
                side = 1
        else:
            lo, ylo = m, ym
            if phi is not None:
                flo = phi(m, ym)
                if side == -1:
                    fhi *= 0.5
                side = -1
        # safeguard: an interpolation step that removed less than half the
        # bracket is followed by a bisection
        new_width = hi - lo
        bisect_next = new_width > 0.5 * last_width
        last_width = new_width
        if math.isnan(new_width):  # pragma: no cover - defensive
            break
    return lo, hi, np.asarray(ylo, dtype=float), np.asarray(yhi, dtype=float)
