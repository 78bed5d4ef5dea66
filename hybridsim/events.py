"""Locating where a flow enters D or leaves C within one solver step."""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate._ivp.lsoda import LsodaDenseOutput
from scipy.integrate._ivp.rk import RkDenseOutput

from .rules import event_tolerance

__all__ = ["locate_event", "event_tolerance", "find_interior_event", "secant_of", "peak_of",
           "bisection_of",
           "secant_trial", "secant_slope", "root_off_zero", "near_peak", "watch_crossings",
           "sign_changes", "crossing_sides", "starts_on_zero"]

_EPS = np.finfo(float).eps
_INVPHI = (math.sqrt(5.0) - 1.0) / 2.0


def fast_dense(sol):
    """A quicker scalar evaluator for scipy's explicit Runge-Kutta and LSODA dense outputs.

    ``RkDenseOutput.__call__`` spends most of its time validating and tiling
    its argument; event location calls it at scalar times only. LSODA's
    Nordsieck polynomial is evaluated as scipy does (the same operations, so
    the same values), without the argument's checks. Other dense outputs are
    returned unchanged.
    """
    if type(sol) is LsodaDenseOutput:
        tn, hn, p, yh = sol.t, sol.h, sol.p, sol.yh

        def nordsieck(t):
            return np.dot(yh, ((t - tn) / hn) ** p)
        return nordsieck
    if type(sol) is not RkDenseOutput:
        return sol
    t_old, h, y_old = float(sol.t_old), float(sol.h), sol.y_old    # Python floats: quicker
    hQ = h * sol.Q
    if hQ.shape[1] == 4:            # RK45: a quartic
        def call(t):
            s = (t - t_old) / h
            s2 = s * s
            return y_old + hQ @ np.array((s, s2, s2 * s, s2 * s2))
        return call
    k = np.arange(1, hQ.shape[1] + 1)

    def call(t):
        return y_old + hQ @ (((t - t_old) / h) ** k)
    return call


# ------------------------------------------------------------------ the algorithms' steps
# Plain functions of floats (and loops over a given function), written once: the
# Python path calls them, and the compiled path compiles them from this source
# (hybridsim.compiled._types registers each of COMPILED with numba, as it does
# hybridsim.rules).
def secant_trial(lo, hi, xl, fl, slope, d2, tol, seeded, s0):
    """The next trial point of the safeguarded secant search (:func:`secant_of`).

    The secant step from the last evaluation ``(xl, fl)`` with ``slope``,
    accepted where it falls inside the bracket ``[lo, hi]`` and is shorter
    than half the step before last ``d2``, else the bracket's midpoint; a
    model's estimate ``s0`` instead where ``seeded``. Kept a quarter of the
    tolerance ``tol`` inside the bracket.

    Examples
    --------
    >>> secant_trial(0.0, 1.0, 0.0, -1.0, 2.0, float("inf"), 1e-3, False, 0.0)
    0.5
    >>> secant_trial(0.0, 1.0, 0.0, -1.0, 2.0, 0.1, 1e-3, False, 0.0)     # too long: bisect
    0.5
    >>> secant_trial(0.0, 1.0, 0.0, -1.0, 2.0, 0.1, 1e-3, True, 1.0)      # a model's, inside
    0.99975
    """
    if seeded:
        s = s0
    else:
        s = xl - fl / slope if slope != 0.0 else math.nan
        if not (lo <= s and s <= hi and abs(s - xl) < 0.5 * d2):
            s = 0.5 * (lo + hi)
    q = 0.25 * tol
    if not s > lo + q:
        s = lo + q
    elif not s < hi - q:
        s = hi - q
    return s


def secant_slope(fs, fl, s, xl):
    """The secant's slope through the last two evaluations ``(xl, fl)`` and
    ``(s, fs)`` (NaN where they coincide).

    Examples
    --------
    >>> secant_slope(1.0, -1.0, 1.0, 0.0)
    2.0
    """
    return (fs - fl) / (s - xl) if s != xl else math.nan


def root_off_zero(f0, fd, fw, d, w):
    """Where a guard that starts on its zero comes back to it, from a quadratic model.

    The guard is ``f0`` (about 0) at the step's start, ``fd < 0`` a probe
    ``d`` into it and ``fw >= 0`` at its end ``w``: the quadratic with that
    value, the probe's secant slope and that end value has its second root
    at the returned offset: within about ``d`` of the true root where the
    guard is quadratic along the step (as an affine guard is on a ball's
    parabola), since the secant over ``[0, d]`` stands in for the slope at
    the start; the secant steps that follow polish it.
    Returns ``(offset, slope there)``, NaNs where the model has no root in
    (d, w).

    Examples
    --------
    >>> g = lambda tau: tau * (tau - 1.0)        # back to its zero at 1
    >>> tau, slope = root_off_zero(g(0.0), g(1e-3), g(2.0), 1e-3, 2.0)
    >>> round(tau, 2), round(slope, 2)
    (1.0, 1.0)
    >>> root_off_zero(0.0, -1e-9, -1.0, 1e-9, 1.0)       # still falling at the end: none
    (nan, nan)
    """
    m = (fd - f0) / d
    c = (fw - f0 - m * w) / (w * w)
    disc = m * m - 4.0 * c * f0
    if not (c > 0.0 and disc >= 0.0):
        return math.nan, math.nan
    r = math.sqrt(disc)
    tau = (r - m) / (2.0 * c)
    if d < tau and tau < w:
        return tau, r
    return math.nan, math.nan


def near_peak(v, lo_nb):
    """Could a smooth guard peak near a sample v (neighbours' minimum lo_nb) reach 0?

    For a parabola through equally spaced samples, the vertex exceeds the
    largest sample by at most a quarter of its drop to the lower neighbour;
    the factor 2 leaves an 8x margin for guards that are not parabolas.

    Examples
    --------
    >>> near_peak(-0.1, -0.5), near_peak(-0.5, -0.6)
    (True, False)
    """
    return v + 2.0 * (v - lo_nb) >= 0.0


def secant_of(F):
    """The safeguarded secant on ``F(E, s)``: a function shrinking a sign-change
    bracket of it to 4 ulp.

    Each trial (:func:`secant_trial`) is the secant step from the last
    evaluation (the slope through the last two, :func:`secant_slope`; at
    first the chord of the bracket, a regula falsi step), accepted where it
    falls inside the bracket and is shorter than half the step before last
    (Brent's test: secant steps converge superlinearly, so they shrink at
    least that fast near a simple root); otherwise the bracket is bisected.
    Trial points are kept a quarter tolerance inside the bracket, so that
    once the steps are shorter than that the bracket closes from the other
    side.

    Parameters
    ----------
    F : callable
        ``F(E, s) -> float``: the function along a step at time ``s``, ``E``
        what it reads besides ``s`` (a compiled function where the kernel
        compiles the result: it calls ``F`` by name, not through a value).

    Returns
    -------
    secant : callable
        ``secant(E, lo, hi, flo, fhi, seeded, s0, slope0) -> (lo, hi)``, from
        ``flo = F(E, lo) < 0 <= fhi = F(E, hi)`` to ``hi - lo <=
        event_tolerance(lo, hi)`` (at most 100 trials), F negative at lo and
        nonnegative at hi (or the end unmoved). Where ``seeded``, ``s0`` is a
        model's estimate of the root and ``slope0`` of the guard's slope
        there: the first trial, and the slope for the step after it.

    Examples
    --------
    >>> root2 = secant_of(lambda E, s: s * s - E)
    >>> lo, hi = root2(2.0, 0.0, 2.0, -2.0, 2.0, False, math.nan, math.nan)
    >>> bool(hi - lo <= event_tolerance(lo, hi) and lo < math.sqrt(2.0) <= hi)
    True
    """
    def secant(E, lo, hi, flo, fhi, seeded, s0, slope0):
        d1 = math.inf           # the last two step lengths
        d2 = math.inf
        if -flo < fhi:          # the last evaluation
            xl = lo
            fl = flo
        else:
            xl = hi
            fl = fhi
        slope = (fhi - flo) / (hi - lo)
        for _ in range(100):
            tol = event_tolerance(lo, hi)
            if hi - lo <= tol:
                break
            s = secant_trial(lo, hi, xl, fl, slope, d2, tol, seeded, s0)
            fs = F(E, s)
            if seeded:
                slope = slope0
                seeded = False
            else:
                slope = secant_slope(fs, fl, s, xl)
            d2 = d1
            d1 = abs(s - xl)
            xl = s
            fl = fs
            if fs >= 0.0:
                hi = s
            else:
                lo = s
        return lo, hi
    return secant


def bisection_of(P, Q):
    """The event bracket's bisections on the indicator, ``P(E, s)`` and
    ``Q(E, s)``: two functions narrowing a bracket on times only.

    Parameters
    ----------
    P : callable
        ``P(E, s) -> bool``: the event has happened at time ``s`` of the step
        (``E`` what it reads besides ``s``).
    Q : callable
        ``Q(E, s) -> (bool, float)``: ``P`` and the guard there, from one
        evaluation of the state.

    Returns
    -------
    to_sign_change : callable
        ``to_sign_change(E, lo, hi, flo, fhi, n) -> (lo, hi, flo, fhi)``:
        bisects by the indicator, the guard's values kept at the ends, until
        the guard changes sign in the bracket (``flo < 0 <= fhi``) or the
        bracket is 4 ulp (at most ``n`` halvings).
    bisect : callable
        ``bisect(E, lo, hi, n) -> (lo, hi)``: bisects by the indicator to 4
        ulp (at most ``n`` halvings).

    Examples
    --------
    >>> _, bisect = bisection_of(lambda E, s: s * s >= E, None)
    >>> lo, hi = bisect(2.0, 0.0, 2.0, 200)
    >>> bool(lo * lo < 2.0 <= hi * hi and hi - lo <= event_tolerance(lo, hi))
    True
    """
    def to_sign_change(E, lo, hi, flo, fhi, n):
        for _ in range(n):
            if (flo < 0.0 and 0.0 <= fhi) or hi - lo <= event_tolerance(lo, hi):
                break
            m = 0.5 * (lo + hi)
            inside, fm = Q(E, m)
            if inside:
                hi = m
                fhi = fm
            else:
                lo = m
                flo = fm
        return lo, hi, flo, fhi

    def bisect(E, lo, hi, n):
        for _ in range(n):
            if hi - lo <= event_tolerance(lo, hi):
                break
            m = 0.5 * (lo + hi)
            if P(E, m):
                hi = m
            else:
                lo = m
        return lo, hi
    return to_sign_change, bisect


#: the functions the compiled path compiles from this source (and :func:`secant_of`'s
#: secant, compiled once per function it is made for)
COMPILED = (secant_trial, secant_slope, root_off_zero, near_peak)


def _call(E, s):
    return E(s)


#: :func:`secant_of` on a Python function of s (``E``)
_secant_py = secant_of(_call)


def _secant(F, lo, hi, flo, fhi, ylo, yhi, ev, seed=None):
    """The safeguarded secant (:func:`secant_of`) on ``F(s, ev(s))`` from the
    bracket ``[lo, hi]`` with states ``ylo``, ``yhi``; ``seed = (s0, slope)``
    where given. Returns ``(lo, hi, x_lo, x_hi)``: each state the one
    evaluated at its time."""
    states = {lo: ylo, hi: yhi}

    def at(s):
        states[s] = ys = ev(s)
        return F(s, ys)
    s0, slope0 = seed if seed is not None else (math.nan, math.nan)
    lo, hi = _secant_py(at, lo, hi, flo, fhi, seed is not None, s0, slope0)
    return lo, hi, states[lo], states[hi]


def _in_py(E, s):
    pred, _, ev = E
    return bool(pred(s, ev(s)))


def _in_guard_py(E, s):
    pred, phi, ev = E
    y = ev(s)
    return bool(pred(s, y)), phi(s, y)


#: :func:`bisection_of` on Python functions (``E = (pred, phi, ev)``)
_to_sign_change_py, _bisect_py = bisection_of(_in_py, _in_guard_py)


def _root_off_zero(f0, fd, fw, d, w):
    """:func:`root_off_zero`, None where the model has no root in (d, w)."""
    tau, r = root_off_zero(f0, fd, fw, d, w)
    return (tau, r) if tau == tau else None


def locate_event(sol, a, b, pred, phi=None, max_iter=200, ya=None, yb=None):
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
        Where it brackets a sign change, safeguarded secant steps find its
        root (a handful of evaluations of the interpolant) and the
        indicator confirms the bracket.
    ya, yb : ndarray, optional
        The states at a and b where the caller has them (the solver's state
        at a step's ends): they are not evaluated again.

    Returns
    -------
    lo, hi, x_lo, x_hi
        ``hi - lo <= 4 eps max(1, |lo|, |hi|)`` (4 ulp of the event time),
        ``pred`` false at lo (or lo = a), true at hi.

    Notes
    -----
    A step that starts on the guard's zero (just after a jump) outside the
    event set takes its direction from one probe a short way into the step;
    the probe's slope and the guard at the step's end give a quadratic model
    whose second root is the root finder's first trial (within about the
    probe's length of the root on a ball's parabola). Where the probe cannot
    step off the zero, the bracket is bisected by the indicator until the
    guard changes sign inside it, so a flow that re-enters D within one
    step is never lost.

    Examples
    --------
    >>> import numpy as np
    >>> sol = lambda s: np.array([s * s])
    >>> lo, hi, _, _ = locate_event(sol, 0.0, 2.0, lambda s, y: y[0] >= 2.0,
    ...                             lambda s, y: y[0] - 2.0)
    >>> bool(abs(hi - np.sqrt(2.0)) < 1e-15)
    True
    """
    ev = fast_dense(sol)
    lo, hi = float(a), float(b)
    ylo = ev(lo) if ya is None else ya
    yhi = ev(hi) if yb is None else yb
    if phi is not None:
        flo, fhi = phi(lo, ylo), phi(hi, yhi)
        seed = None
        if not flo < 0.0 and fhi >= 0.0:
            # on the guard's zero at the start: one probe gives the direction,
            # and with the end value a first estimate of the root
            d = max(64.0 * event_tolerance(lo, hi), 1e-9 * (hi - lo))
            if lo + d < hi:
                yd = ev(lo + d)
                fd = phi(lo + d, yd)
                if fd < 0.0 and not pred(lo + d, yd):
                    seed = _root_off_zero(flo, fd, fhi, d, hi - lo)
                    if seed is not None:
                        seed = (lo + seed[0], seed[1])
                    lo, ylo, flo = lo + d, yd, fd
        # bisect by the indicator until the guard changes sign in the bracket
        lo_at, hi_at = lo, hi
        lo, hi, flo, fhi = _to_sign_change_py((pred, phi, ev), lo, hi, flo, fhi, max_iter)
        if lo != lo_at:
            ylo = ev(lo)
        if hi != hi_at:
            yhi = ev(hi)
        if flo < 0.0 <= fhi and hi - lo > event_tolerance(lo, hi):
            l2, h2, yl2, yh2 = _secant(phi, lo, hi, flo, fhi, ylo, yhi, ev, seed)
            # the indicator decides membership: keep the guard's bracket where it
            # agrees (below the root the guard is negative, so the indicator is
            # asked at lo only when it disagrees at hi)
            if pred(h2, yh2):
                hi, yhi = h2, yh2
                lo, ylo = l2, yl2
            elif not pred(l2, yl2):
                lo, ylo = l2, yl2
    # bisection of the indicator (also finishes any bracket the guard left)
    lo_at, hi_at = lo, hi
    lo, hi = _bisect_py((pred, phi, ev), lo, hi, max_iter)
    if lo != lo_at:
        ylo = ev(lo)
    if hi != hi_at:
        yhi = ev(hi)
    return lo, hi, np.asarray(ylo, dtype=float), np.asarray(yhi, dtype=float)


def _near_peak(v, lo_nb):
    """:func:`near_peak`, of floats or arrays (a batch's rows)."""
    with np.errstate(invalid="ignore"):       # -inf guards ("never"): nan, not a peak
        return near_peak(v, lo_nb)


def peak_of(F, P):
    """The golden-section search for a guard's peak, on ``F(E, s)`` and
    ``P(E, s)``: a function returning a point of a bracket in the event set.

    The search narrows ``[l, r]`` around the guard's largest value. It stops
    at the first point where the guard is nonnegative and the event set's
    indicator holds, or once the bracket's peak can no longer reach 0
    (:func:`near_peak` on the shrinking bracket), or at 4 ulp.

    Parameters
    ----------
    F : callable
        ``F(E, s) -> float``: the guard along a step at time ``s``, ``E``
        what it reads besides ``s``.
    P : callable
        ``P(E, s) -> bool``: the event set's indicator there (asked only
        where ``F`` is nonnegative).

    Returns
    -------
    peak : callable
        ``peak(E, l, r, fl, fr) -> float``, from the guard's values ``fl``,
        ``fr`` at the bracket's ends: a point where ``P`` holds, NaN where
        none is found (at most 100 trials).

    Examples
    --------
    >>> apex = peak_of(lambda E, s: E - (s - 1.0) ** 2, lambda E, s: E - (s - 1.0) ** 2 >= 0.0)
    >>> s = apex(1e-6, 0.0, 2.0, 1e-6 - 1.0, 1e-6 - 1.0)
    >>> bool(abs(s - 1.0) <= 1e-3)
    True
    """
    def peak(E, l, r, fl, fr):
        x1 = r - _INVPHI * (r - l)
        x2 = l + _INVPHI * (r - l)
        f1 = F(E, x1)
        f2 = F(E, x2)
        for _ in range(100):
            if f1 >= 0.0 and P(E, x1):
                return x1
            if f2 >= 0.0 and P(E, x2):
                return x2
            if r - l <= event_tolerance(l, r) or not near_peak(max(f1, f2), min(fl, fr)):
                return math.nan
            if f1 >= f2:
                r = x2
                fr = f2
                x2 = x1
                f2 = f1
                x1 = r - _INVPHI * (r - l)
                f1 = F(E, x1)
            else:
                l = x1
                fl = f1
                x1 = x2
                f1 = f2
                x2 = l + _INVPHI * (r - l)
                f2 = F(E, x2)
        return math.nan
    return peak


def _guard_py(E, s):
    phi, _, sol = E
    return float(phi(s, sol(s)))


def _member_py(E, s):
    _, pred, sol = E
    return bool(pred(s, sol(s)))


#: :func:`peak_of` on Python functions (``E = (phi, pred, sol)``)
_peak_py = peak_of(_guard_py, _member_py)


def _maximize(F, l, r, fl, fr, pred, sol):
    """:func:`peak_of`'s search on the guard ``F(s, y)`` and the indicator
    ``pred(s, y)`` of the dense output ``sol``: a point of [l, r] in the
    event set, None where none is found."""
    s = _peak_py((F, pred, sol), float(l), float(r), float(fl), float(fr))
    return None if s != s else s


def nonnegative(phi):
    """The indicator ``phi(s, y) >= 0`` of an event set that is a guard's
    {phi >= 0}, marked so that :func:`find_interior_event` evaluates ``phi``
    once per sample (a NaN guard raises in ``phi``).

    Examples
    --------
    >>> pred = nonnegative(lambda s, y: y[0] - 1.0)
    >>> pred(0.0, [2.0]), pred(0.0, [0.5])
    (True, False)
    """
    def pred(s, y):
        return phi(s, y) >= 0.0
    pred.guard = phi
    return pred


def find_interior_event(sol, a, b, pred, phi=None, samples=3):
    """Search the inside of a step whose ends are outside the event set.

    A flow can enter D (or leave C) and come back within one solver step:
    RK45 integrates a ball's parabola exactly, so one step may span its
    whole excursion above a guard. The step's dense output is sampled at
    ``samples`` interior points; the indicator is tested there, and, where a
    continuous guard ``phi`` is given, every local maximum of the guard
    among the samples (the step's start included where the guard rises
    there, and its end where the guard falls there) whose peak could reach 0
    is refined by a golden-section search.

    Parameters
    ----------
    sol : callable
        The step's dense output.
    a, b : float
        The step; ``pred`` is false at both ends.
    pred, phi : callable
        As in :func:`locate_event`.
    samples : int
        Interior sample count (3: with the two ends, five values, which
        determine the quartic that an affine guard is along an RK45 step).

    Returns
    -------
    (lo, hi) or None
        A bracket with ``pred`` false at lo and true at hi, to be passed to
        :func:`locate_event`; None when no event was found.

    Notes
    -----
    What a sample spacing can miss: with a guard, an excursion whose peak
    lies below ``v + 2 (v - v_nb)`` for every sampled local maximum v (with
    v_nb its lower neighbour), i.e. a guard that is far from parabolic
    between samples h/4 apart; without a guard (indicators only), an
    excursion into the set shorter than h/4 that falls between samples.

    Examples
    --------
    >>> import numpy as np
    >>> sol = lambda s: np.array([2.0 * s - s * s])    # apex 1 at s = 1
    >>> find_interior_event(sol, 0.0, 2.0, lambda s, y: y[0] >= 1.0 - 1e-9,
    ...                     lambda s, y: y[0] - (1.0 - 1e-9)) is not None
    True
    """
    sol = fast_dense(sol)
    a, b = float(a), float(b)
    h = b - a
    if not h > 0:
        return None
    ts = [a + h * (k / (samples + 1.0)) for k in range(1, samples + 1)]
    ys = [sol(s) for s in ts]
    prev = a
    if phi is not None and getattr(pred, "guard", None) is phi:
        inner = []                  # pred is phi >= 0: one evaluation per sample
        for s, y in zip(ts, ys):
            v = phi(s, y)
            if v >= 0.0:
                return prev, s
            inner.append(v)
            prev = s
    else:
        for s, y in zip(ts, ys):
            if pred(s, y):
                return prev, s
            prev = s
        if phi is None:
            return None
        inner = [phi(s, y) for s, y in zip(ts, ys)]
    pts = [a] + ts + [b]
    vals = [phi(a, sol(a))] + inner + [phi(b, sol(b))]
    if not all(math.isfinite(v) for v in vals):
        return None
    for k in range(1, samples + 1):
        v = vals[k]
        if v >= vals[k - 1] and v >= vals[k + 1] and _near_peak(v, min(vals[k - 1], vals[k + 1])):
            s = _maximize(phi, pts[k - 1], pts[k + 1], vals[k - 1], vals[k + 1], pred, sol)
            if s is not None:
                return pts[k - 1], s
    # a peak between a and the first sample: only where the guard rises at a
    if vals[0] >= vals[1] and _near_peak(vals[0], vals[1]):
        eps = 1e-3 * (ts[0] - a)
        if phi(a + eps, sol(a + eps)) > vals[0]:
            s = _maximize(phi, a, ts[0], vals[0], vals[1], pred, sol)
            if s is not None:
                return a, s
    # a peak between the last sample and b: only where the guard falls at b
    # (the next step starts falling, so its own search never looks back)
    if vals[-1] >= vals[-2] and _near_peak(vals[-1], vals[-2]):
        eps = 1e-3 * (b - ts[-1])
        if phi(b - eps, sol(b - eps)) > vals[-1]:
            s = _maximize(phi, ts[-1], b, vals[-2], vals[-1], pred, sol)
            if s is not None:
                return ts[-1], s
    return None


# ------------------------------------------------------------------ watched functions
#: interior points of a step at which the watched functions are also sampled
#: (with the ends: a crossing pair closer than a quarter step may be missed)
WATCH_SAMPLES = 3


def sign_changes(v0, v1, direction):
    """The crossings of 0 between two values of the watched functions.

    ``v0``, ``v1``: (m,) values at the two ends; ``direction``: (m,) of -1,
    0, 1 (scipy's ``event.direction``). A rising crossing goes from below 0
    to 0 or above, a falling one from above 0 to 0 or below. Returns
    ``(which, sign)``: the indices crossing and +1 / -1.

    Examples
    --------
    >>> import numpy as np
    >>> sign_changes(np.array([-1.0, 1.0, 0.0]), np.array([0.0, -1.0, 1.0]), np.zeros(3))
    (array([0, 1]), array([ 1, -1]))
    >>> sign_changes(np.array([-1.0, 1.0]), np.array([0.0, -1.0]), np.array([-1, -1]))
    (array([1]), array([-1]))
    """
    up, down = crossing_sides(v0, v1, direction)
    which = np.flatnonzero(up | down)
    return which, np.where(up[which], 1, -1)


def crossing_sides(v0, v1, direction):
    """Elementwise (rising, falling) crossings between values ``v0`` and ``v1``
    (any shape that broadcasts with ``direction``; NaN crosses nothing), as
    :func:`sign_changes` reads them."""
    return ((v0 < 0.0) & (v1 >= 0.0) & (direction >= 0),
            (v0 > 0.0) & (v1 <= 0.0) & (direction <= 0))


def starts_on_zero(floor, t, tol):
    """A crossing located at ``t`` is the zero its flow starts on (at ``floor``,
    a jump's instant or x0): within two event tolerances ``tol`` of it
    (floats or arrays). ``floor = -inf`` marks a flow that starts on no zero
    (restarted without a jump): none of its crossings is, whatever ``tol``
    (the tolerance of -inf's scale is inf).

    Examples
    --------
    >>> starts_on_zero(1.0, 1.0 + 4e-16, 8.9e-16), starts_on_zero(1.0, 1.1, 8.9e-16)
    (True, False)
    >>> starts_on_zero(-math.inf, 2.0, math.inf)
    False
    """
    return (floor > -math.inf) & (t - floor <= 2.0 * tol)


def watch_crossings(sol, a, b, ya, yb, wa, wb, W, direction, floor, samples=WATCH_SAMPLES):
    """The crossings of watched functions within one flow step (a, b].

    Parameters
    ----------
    sol : callable
        The step's dense output, ``sol(s) -> x(s)``.
    a, b, ya, yb : float, ndarray
        The step and its end states.
    wa, wb : ndarray, shape (m,)
        The watched functions' values at a and b.
    W : callable
        ``W(s, x) -> (m,)`` values of the watched functions.
    direction : ndarray of int, shape (m,)
        -1, 0 or 1 per function (:func:`sign_changes`).
    floor : float
        The flow's start: a crossing located within 8 ulp of it is the zero
        the flow starts on (after a jump, or at x0), not recorded.
    samples : int
        Interior points where the functions are sampled too.

    Returns
    -------
    list of (t, which, sign, x)
        In time order. Each is located to 4 ulp by :func:`secant_of` (the
        guards' safeguarded secant) on ``sol``, between the samples that
        bracket its sign change; ``t`` is the bracket's end on or past 0.
        The step is untouched (nothing is cut or re-integrated).

    Examples
    --------
    >>> import numpy as np
    >>> sol = lambda s: np.array([np.sin(s)])
    >>> W = lambda s, y: y
    >>> out = watch_crossings(sol, 3.0, 7.0, sol(3.0), sol(7.0), W(3.0, sol(3.0)),
    ...                       W(7.0, sol(7.0)), W, np.zeros(1, int), 0.0)
    >>> [(round(t, 12), k, d) for t, k, d, _ in out]
    [(3.14159265359, 0, -1), (6.28318530718, 0, 1)]
    """
    a, b = float(a), float(b)
    if not b > a:
        return []
    ev = fast_dense(sol)
    h = b - a
    pts, ys, vals = [a], [ya], [wa]
    for k in range(1, samples + 1):
        s = a + h * (k / (samples + 1.0))
        y = ev(s)
        pts.append(s)
        ys.append(y)
        vals.append(W(s, y))
    pts.append(b)
    ys.append(yb)
    vals.append(wb)
    V = np.array(vals)
    up, down = crossing_sides(V[:-1], V[1:], direction)
    if not (up.any() or down.any()):
        return []
    out = []
    for i in range(len(pts) - 1):
        which, signs = sign_changes(vals[i], vals[i + 1], direction)
        for k, sg in zip(which.tolist(), signs.tolist()):
            def F(s, y, k=k, sg=sg):
                return sg * float(W(s, y)[k])
            _, hi, _, yhi = _secant(F, pts[i], pts[i + 1], sg * float(vals[i][k]),
                                    sg * float(vals[i + 1][k]), ys[i], ys[i + 1], ev)
            if starts_on_zero(floor, hi, event_tolerance(floor, hi)):
                continue
            out.append((hi, k, sg, np.array(yhi, dtype=float)))
    out.sort(key=lambda c: (c[0], c[1]))
    return out
