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
"""

import math

import numpy as np
from scipy.integrate import DOP853 as _ScipyDOP853
from scipy.integrate import RK23 as _ScipyRK23
from scipy.integrate import RK45 as _ScipyRK45
from scipy.integrate._ivp.rk import MAX_FACTOR, MIN_FACTOR, SAFETY

_dot, _maximum, _abs = np.dot, np.maximum, np.abs


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
            if error_norm < 1:
                if error_norm == 0:
                    factor = MAX_FACTOR
                else:
                    factor = min(MAX_FACTOR, SAFETY * error_norm ** expo)
                if rejected:
                    factor = min(1, factor)
                h_abs *= factor
                break
            h_abs *= max(MIN_FACTOR, SAFETY * error_norm ** expo)
            rejected = True
        self.h_previous = h
        self.y_old = y
        self.t = t_new
        self.y = y_new
        self.h_abs = h_abs
        self.f = f_new
        return True, None


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


#: scipy's class -> the engine's stepper for it
LEAN = {_ScipyRK45: RK45, _ScipyRK23: RK23, _ScipyDOP853: DOP853}
