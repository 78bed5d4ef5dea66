"""scipy's explicit Runge-Kutta step, without its per-step Python overheads.

:class:`RK45`, :class:`RK23` and :class:`DOP853` here are scipy's classes
with one method replaced: ``_step_impl`` performs the same floating-point
operations in the same order as scipy's ``RungeKutta._step_impl``,
``rk_step`` and the classes' error norms, so every step, rejection and
dense output is bit for bit scipy's (``tests/engine/test_rk.py`` checks it against
the installed scipy on random systems). What it saves, about 15% of a step
of a small system: the views ``K[:s].T`` of the stage array made once per
solver rather than once per stage, the minimum step from ``math.nextafter``
rather than numpy scalars, and the error norm computed in place rather than
through two methods and ``numpy.linalg.norm``.

The engine uses them for ``method="RK45"``, ``"RK23"`` and ``"DOP853"``;
users keep passing scipy's names or classes.

The first step of a flow is scipy's rule (``select_initial_step``) written
here once as plain loops (:func:`initial_guess`, :func:`initial_step`): the
Python path calls them and the compiled kernel compiles the same source
(:data:`COMPILED`), so both paths start a flow with the same step, bit for
bit. The vectorized batch keeps its row form (every row's norms in one array
expression).

:class:`RK4` is the engine's own: the classic fourth-order Runge-Kutta
method with a fixed step (``max_step``) and no error control, for runs
whose step is chosen by the model (a divisor of its delays, sampling
periods and the pieces of its inputs); its tableau and continuous
extension (:data:`RK4_TABLEAU`, :data:`RK4_P4`) serve every path that steps it.
"""

import math

import numpy as np
from scipy.integrate import DOP853 as _ScipyDOP853
from scipy.integrate import RK23 as _ScipyRK23
from scipy.integrate import RK45 as _ScipyRK45
from scipy.integrate import OdeSolver
from scipy.integrate._ivp.rk import MAX_FACTOR, MIN_FACTOR, SAFETY, RungeKutta, rk_step

_dot, _maximum, _abs = np.dot, np.maximum, np.abs


def _advance(solver, h, y, t_new, y_new, h_abs, f_new):
    """A step's end: the solver at ``(t_new, y_new)`` (scipy's ``_step_impl``'s
    bookkeeping), returning its ``(True, None)``."""
    solver.h_previous = h
    solver.y_old = y
    solver.t = t_new
    solver.y = y_new
    solver.h_abs = h_abs
    solver.f = f_new
    return True, None


class _LeanStep:
    """``_step_impl`` of scipy's ``RungeKutta``, the same arithmetic."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # K is allocated once per solver and written in place: views made now stay valid
        K = self.K
        stages = [(s, K[:s].T, a[:s], c)
                  for s, (a, c) in enumerate(zip(self.A[1:], self.C[1:]), start=1)]
        self._kviews = (K, stages, K[:-1].T, K.T)

    def _step_impl(self):
        t, y = self.t, self.y
        rtol, atol, d = self.rtol, self.atol, self.direction
        K, stages, KbT, KT = self._kviews
        fun, B, expo = self.fun, self.B, self.error_exponent
        min_step = 10 * abs(math.nextafter(t, d * math.inf) - t)
        h_abs = self.h_abs
        if h_abs > self.max_step:
            h_abs = self.max_step
        elif h_abs < min_step:
            h_abs = min_step
        rejected = False
        while True:
            if h_abs < min_step:
                return False, self.TOO_SMALL_STEP
            t_new = t + h_abs * d
            if d * (t_new - self.t_bound) > 0:
                t_new = self.t_bound
            h = t_new - t
            h_abs = abs(h)
            # rk_step
            K[0] = self.f
            for s, KsT, a, c in stages:
                K[s] = fun(t + c * h, y + _dot(KsT, a) * h)
            y_new = y + h * _dot(KbT, B)
            f_new = fun(t + h, y_new)
            K[-1] = f_new
            scale = atol + _maximum(_abs(y), _abs(y_new)) * rtol
            error_norm = self._error_norm(KT, h, scale)
            h_abs *= step_factor(error_norm, rejected, expo)
            if error_norm < 1:
                break
            rejected = True
        return _advance(self, h, y, t_new, y_new, h_abs, f_new)


    def _error_norm(self, KT, h, scale):
        # scipy's norm(np.dot(K.T, E) * h / scale): RMS, np.linalg.norm's sqrt(x.x)
        e = _dot(KT, self.E) * h / scale
        return math.sqrt(e.dot(e)) / e.size ** 0.5


class RK45(_LeanStep, _ScipyRK45):
    """scipy's :class:`~scipy.integrate.RK45` with :class:`_LeanStep`'s step."""


class RK23(_LeanStep, _ScipyRK23):
    """scipy's :class:`~scipy.integrate.RK23` with :class:`_LeanStep`'s step."""


class DOP853(_LeanStep, _ScipyDOP853):
    """scipy's :class:`~scipy.integrate.DOP853` with :class:`_LeanStep`'s step."""

    def _error_norm(self, KT, h, scale):
        # scipy's DOP853._estimate_error_norm, the same operations
        err5 = _dot(KT, self.E5) / scale
        err3 = _dot(KT, self.E3) / scale
        err5_norm_2 = math.sqrt(err5.dot(err5)) ** 2
        err3_norm_2 = math.sqrt(err3.dot(err3)) ** 2
        if err5_norm_2 == 0 and err3_norm_2 == 0:
            return 0.0
        denom = err5_norm_2 + 0.01 * err3_norm_2
        return abs(h) * err5_norm_2 / math.sqrt(denom * len(scale))


def step_factor(err, rejected, exponent):
    """scipy's step-size controller (``RungeKutta._step_impl``): the factor of
    the next step after a step of error norm ``err`` (accepted where
    ``err < 1``; ``rejected``: the step was rejected before), the error
    estimator's ``exponent`` (-1 / (order + 1)); its constants scipy's.

    Examples
    --------
    >>> step_factor(0.0, False, -0.2) == MAX_FACTOR, step_factor(1e9, False, -0.2) == MIN_FACTOR
    (True, True)
    >>> step_factor(0.5, True, -0.2)        # after a rejection: not larger
    1.0
    """
    if err < 1:
        if err == 0:
            factor = MAX_FACTOR
        else:
            factor = SAFETY * err ** exponent
            factor = factor if factor < MAX_FACTOR else MAX_FACTOR
        if rejected:
            factor = factor if factor < 1.0 else 1.0
        return factor
    factor = SAFETY * err ** exponent
    return factor if factor > MIN_FACTOR else MIN_FACTOR


def scaled_rms(v, w, scale, diff):
    """The RMS norm of ``v / scale``, or of ``(v - w) / scale`` where ``diff``
    (scipy's ``norm``; a loop: no array made).

    Examples
    --------
    >>> import numpy as np
    >>> r = scaled_rms(np.array([3.0, 4.0]), np.zeros(2), np.ones(2), False)
    >>> bool(abs(r - 12.5 ** 0.5) < 1e-15)
    True
    """
    s = 0.0
    for i in range(v.shape[0]):
        e = ((v[i] - w[i]) if diff else v[i]) / scale[i]
        s += e * e
    return math.sqrt(s) / math.sqrt(v.shape[0])


def initial_guess(t0, y0, t_bound, f0, rtol, atol, y1, scale):
    """scipy's ``select_initial_step`` (direction +1), its first part.

    Parameters
    ----------
    t0, t_bound : float
        The flow's start and the end of its interval.
    y0, f0 : ndarray
        The state and the flow map's value there.
    rtol : float
    atol : ndarray
        The tolerances (``atol`` one per state).
    y1, scale : ndarray
        Written in place: the Euler point ``y0 + h0 f0`` and the error scale
        ``atol + |y0| rtol``.

    Returns
    -------
    h0, d1 : float
        The Euler step (0.0 where the interval is empty) and the RMS norm of
        ``f0 / scale``. The caller evaluates the flow map at ``(t0 + h0, y1)``
        and ends with :func:`initial_step`.

    Examples
    --------
    >>> import numpy as np
    >>> y1, scale = np.empty(1), np.empty(1)
    >>> h0, d1 = initial_guess(0.0, np.array([1.0]), 10.0, np.array([-1.0]), 1e-3,
    ...                        np.array([1e-6]), y1, scale)
    >>> h0 == 0.01, float(y1[0]) == 0.99
    (True, True)
    """
    interval = abs(t_bound - t0)
    if interval == 0.0:
        return 0.0, 0.0
    n = y0.shape[0]
    for i in range(n):
        scale[i] = atol[i] + abs(y0[i]) * rtol
    d0 = scaled_rms(y0, y0, scale, False)
    d1 = scaled_rms(f0, f0, scale, False)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, interval)
    for i in range(n):
        y1[i] = y0[i] + h0 * f0[i]
    return h0, d1


def initial_step(t0, t_bound, max_step, f0, f1, h0, d1, scale, order):
    """``select_initial_step``'s end: the first step from :func:`initial_guess`'s
    ``h0``, ``d1`` and ``scale`` and the flow map's value ``f1`` at its Euler
    point (``order``: the method's error estimator's, 4 for RK45, 7 for
    DOP853); -1.0 where ``f1`` has the wrong length.

    Examples
    --------
    >>> import numpy as np
    >>> y0, f0 = np.array([1.0]), np.array([-1.0])
    >>> y1, scale = np.empty(1), np.empty(1)
    >>> h0, d1 = initial_guess(0.0, y0, 10.0, f0, 1e-3, np.array([1e-6]), y1, scale)
    >>> h = initial_step(0.0, 10.0, np.inf, f0, -y1, h0, d1, scale, 4.0)
    >>> bool(0.0 < h <= 1.0)
    True
    """
    if f1.shape[0] != f0.shape[0]:
        return -1.0
    d2 = scaled_rms(f1, f0, scale, True) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1.0))
    return min(100.0 * h0, h1, abs(t_bound - t0), max_step)


def first_step(fun, t0, y0, t_bound, max_step, f0, order, rtol, atol):
    """The first step of a flow from ``(t0, y0)`` (:func:`initial_guess`, one
    evaluation of ``fun(t, y)`` at its Euler point, :func:`initial_step`):
    the Python path's call of the rule the kernel compiles; 0.0 where the
    interval is empty.

    Examples
    --------
    >>> import numpy as np
    >>> h = first_step(lambda t, y: -y, 0.0, np.array([1.0]), 10.0, np.inf,
    ...                np.array([-1.0]), 4, 1e-3, 1e-6)
    >>> bool(0.0 < h <= 1.0)
    True
    """
    n = y0.shape[0]
    y1, scale = np.empty(n), np.empty(n)
    h0, d1 = initial_guess(t0, y0, t_bound, f0, rtol, np.broadcast_to(atol, (n,)), y1, scale)
    if h0 == 0.0:
        return 0.0
    return initial_step(t0, t_bound, max_step, f0, np.asarray(fun(t0 + h0, y1)), h0, d1,
                        scale, float(order))


#: the functions the compiled kernel compiles from this source
COMPILED = (step_factor, scaled_rms, initial_guess, initial_step)


#: scipy's class -> the engine's stepper for it
LEAN = {_ScipyRK45: RK45, _ScipyRK23: RK23, _ScipyDOP853: DOP853}


#: The classic RK4 tableau (A, B, C) and its continuous extension of order 3,
#: in scipy's dense-output form: y(t + s h) = y + h K^T P [s, s^2, s^3], K the
#: four stages and f at the step's end (row of zeros). Its value at s = 1/2 is
#: y + h (5/24 k1 + (k2 + k3)/6 - k4/24).
RK4_TABLEAU = {
    "A": np.array([[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0],
                   [0.0, 0.0, 1.0, 0.0]]),
    "B": np.array([1.0, 2.0, 2.0, 1.0]) / 6.0,
    "C": np.array([0.0, 0.5, 0.5, 1.0]),
    "P": np.array([[1.0, -1.5, 2.0 / 3.0], [0.0, 1.0, -2.0 / 3.0], [0.0, 1.0, -2.0 / 3.0],
                   [0.0, -0.5, 2.0 / 3.0], [0.0, 0.0, 0.0]]),
}
#: RK4's continuous extension in RK45's dense-output form (y + h K^T P [s, s^2, s^3,
#: s^4], :data:`RK4_TABLEAU`'s P with a column of zeros): the form the vectorized
#: batch and the compiled kernel evaluate, search and record the past in
RK4_P4 = np.hstack([RK4_TABLEAU["P"], np.zeros((5, 1))])
#: A step that would end within this fraction of a step before its bound ends on it
#: (no sliver step after it: the bound is a delay breakpoint or t_max on the grid)
RK4_SNAP = 1e-9


def fixed_step(method, max_step):
    """Check the step of a fixed-step method: ``max_step``, finite (the step of ``"RK4"``).

    Parameters
    ----------
    method : str
        The method's name (for the message).
    max_step : float
        The run's ``max_step`` after the cap by ``system.max_step``.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        ``max_step`` infinite: a fixed-step method has no step to take.
    """
    if not math.isfinite(max_step):
        raise ValueError(f"method={method!r} takes fixed steps of max_step: give a finite "
                         f"max_step (or a system.max_step)")
    return float(max_step)


class RK4(RungeKutta):
    """The classic Runge-Kutta method of order 4 with the fixed step ``max_step``.

    A scipy :class:`~scipy.integrate.OdeSolver`: every step is ``max_step``
    (the last one before ``t_bound`` shortened to end there, or lengthened by
    at most :data:`RK4_SNAP` of a step to end there rather than leave a
    sliver), accepted without an error estimate (``rtol`` and ``atol`` are
    not read); the dense output is RK4's continuous extension of order 3
    (:data:`RK4_TABLEAU`). The step is the caller's choice: a divisor of the
    model's delays, sampling periods and input pieces keeps them on the grid.

    Examples
    --------
    >>> import numpy as np
    >>> s = RK4(lambda t, y: -y, 0.0, np.array([1.0]), 1.0, max_step=0.1)
    >>> while s.status == "running":
    ...     _ = s.step()
    >>> round(float(s.y[0]), 9), round(float(np.exp(-1.0)), 9)
    (0.367879774, 0.367879441)
    """

    A, B, C, P = (RK4_TABLEAU[k] for k in "ABCP")
    E = np.zeros(5)
    order = 4
    error_estimator_order = 3
    n_stages = 4

    def __init__(self, fun, t0, y0, t_bound, max_step=np.inf, rtol=1e-3, atol=1e-6,
                 vectorized=False, first_step=None, **extraneous):
        OdeSolver.__init__(self, fun, t0, y0, t_bound, vectorized, support_complex=True)
        self.max_step = fixed_step("RK4", max_step)
        self.rtol, self.atol = rtol, atol
        self.f = self.fun(self.t, self.y)
        self.h_abs = self.max_step
        self.K = np.empty((self.n_stages + 1, self.n), dtype=self.y.dtype)
        self.error_exponent = -1.0 / (self.error_estimator_order + 1)
        self.h_previous = None

    def _step_impl(self):
        t, y, d, h_abs = self.t, self.y, self.direction, self.max_step
        t_new = t + d * h_abs
        if d * (t_new - self.t_bound) > -RK4_SNAP * h_abs:
            t_new = self.t_bound
        h = t_new - t
        y_new, f_new = rk_step(self.fun, t, y, self.f, h, self.A, self.B, self.C, self.K)
        return _advance(self, h, y, t_new, y_new, h_abs, f_new)
