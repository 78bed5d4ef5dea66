r"""Forward sensitivities of hybrid arcs: derivatives through flows and jumps.

For a parameter vector :math:`\theta` (the initial state x0, declared
parameters p, or both) the sensitivity :math:`S(t, j) = \partial x(t, j) /
\partial\theta` obeys the variational equation along flows,

.. math:: \dot S = \frac{\partial f}{\partial x} S + \frac{\partial f}{\partial p},

and at a jump triggered by a guard h (D = {h >= 0} near the event, the
engine's convention) the saltation update (Kong et al., "Saltation matrices:
the essential tool for linearizing hybrid dynamical systems", Proc. IEEE
2024), here with parameter- and time-dependent maps,

.. math::
    \frac{\partial t_j}{\partial\theta} = -\frac{\nabla h\, S^- + h_\theta}
        {\nabla h\, f^- + h_t}, \qquad
    S^+ = Dg\, S^- + g_\theta + (Dg\, f^- + g_t - f^+)\,
          \frac{\partial t_j}{\partial\theta},

which for h, g independent of t and p is the familiar
:math:`S^+ = Dg S^- + (f^+ - Dg f^-)(\nabla h S^-)/(\nabla h f^-)`.

Design
------
* **The variational system is an ordinary hybrid system** run by the engine
  (:func:`sensitivity_system`): its state is (x, vec S, the last jump's
  :math:`\partial t_j/\partial\theta`, the last jump's time, a flag), its
  flow (f, the variational equation, 0, 0, 0), its jump (g, the saltation
  update). Events, the in-step search, priorities, t_max, Zeno, every
  termination cause and every option of :func:`hybridsim.simulate`
  (``rtol``, ``method``, ``refine``, ``t_eval``, ``dense``...) come from the
  engine unchanged. Its sets and guards read x only, so the sensitivities
  never create events; the same solver steps carry x and S, and the error
  control includes S (``sens_atol``, default the state's ``atol``; ``rtol``
  is shared), as CVODES's and diffrax's forward modes do.
* **Jump-time derivatives are state, not side effects**: the jump map
  writes :math:`\partial t_j/\partial\theta` into components with zero flow,
  so each is read at its post-jump sample; the jump map has no side effect
  (the engine may call it more than once).
* **Parameters come from a factory** ``make_system(p) -> HybridSystem``, the
  convention of :func:`hybridsim.sweep`: any system, from the library's
  ``BouncingBall(restitution=p[0])`` to an interconnection, exposes its
  parameters without a new attribute. Derivatives in p are central
  differences between ``make_system(p ± δ e_k)``, built once per run.
* **Jacobians** come from the system where it defines them:
  ``flow_jacobian(x, t, j, u)`` (n, n), ``jump_jacobian(x, t, j, u)`` (n, n),
  ``jump_guard_gradient(x, t, j, u)`` ((n,) or (m, n) for a vector guard),
  any of the four signatures. Otherwise central finite differences with the
  step :math:`\delta_i = \epsilon^{1/3}\max(1, |x_i|)` (``fd_step``,
  :math:`\epsilon^{1/3} \approx 6\cdot 10^{-6}`): truncation
  :math:`\delta^2 |f'''|/6` and rounding :math:`\epsilon |f| / \delta`, both
  about :math:`\epsilon^{2/3} \approx 4\cdot 10^{-11}` relative on maps
  varying on the scale of x; exact to rounding on affine maps. Not complex
  step: user maps build float arrays (``np.zeros(n)`` then item assignment
  drops an imaginary part with only a warning) and use comparisons, ``min``
  and ``abs``, so it would be silently wrong on ordinary maps.
* **Where the derivative does not exist, say so**: a grazing jump (the
  guard's rate along the flow, :math:`\dot h = \nabla h f^- + h_t`, is
  that of a tangency: :math:`2|\dot h| \le` ``graze_tol``
  :math:`|\ddot h| (t_j - t_{j-1})`, the rate changing sign within
  ``graze_tol`` of the flow's duration; see ``SensitivitySystem._tangency``),
  a jump without a guard or triggered by the jump set away from the
  guard's zero, simultaneous guards (two components of a vector guard at
  zero within 1e-9 max(1, |t|) of time along the flow), a jump from a
  guard's zero with no flow before it (x0 on the guard): a
  :class:`SensitivityError` (or, with ``undefined="warn"``, a
  :class:`SensitivityWarning` and NaN sensitivities from that jump on)
  naming the jump (t, j) and why. A Zeno accumulation warns, naming the
  last jump. A jump strictly inside D right after another jump (or at t0)
  happens at that instant whatever theta: S+ = Dg S- + ... with the
  previous jump's dt/dtheta, no new event. The active component of a
  vector guard is its minimum (D = {min_i h_i >= 0}); an interconnection's
  composite guard is a scalar (the max over its components), so two
  components jumping at once are not detected as simultaneous there.
* ``max_norm`` bounds the norm of the whole augmented state (x, S, ...).
* **Paths** (``backend``, as for :func:`hybridsim.simulate`): ``"python"``
  runs :class:`SensitivitySystem`; ``"compiled"`` runs the same variational
  system compiled (:mod:`hybridsim._variational`: its maps call the system's
  own compiled maps, the saltation update inside the kernel, Jacobians by
  the same central differences), the same results to rounding;
  ``"auto"`` takes the compiled path where it can and the Python path
  otherwise (an interconnection, Jacobians given by the system, a model
  that does not compile, options the compiled path does not take). A
  vectorized system is refused by name (give its single-state form).

Examples
--------
>>> from hybridsim.library import BouncingBall
>>> sarc = hs.simulate_sensitivity(lambda p: BouncingBall(restitution=p[0]),
...                                [1.0, 0.0], t_max=10, j_max=3, params=[0.8])
>>> sarc.theta_names
['x0[0]', 'x0[1]', 'p[0]']
>>> t1 = np.sqrt(2 / 9.81)                       # first impact from 1 m
>>> bool(np.isclose(sarc.dtj_dx0[0, 0], t1 / 2))   # d t_1 / d h0 = t_1 / (2 h0)
True
>>> bool(np.isclose(sarc.dtj_dp[1, 0], 2 * t1))     # t_2 = t_1 (1 + 2e)
True
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ._sensitivity_maps import (
    _EPS,
    _at_zero,
    _check_wrt,
    _fd_jac,
    _fd_scalar,
    _frozen_jump,
    _jumping,
    _user_jac,
)
from .arc import Termination
from .rules import SimulationError, SimulationWarning
from .run import simulate
from .system import HybridSystem

__all__ = ["simulate_sensitivity", "sensitivity_system", "margin_gradient", "SensitivityArc",
           "SensitivitySystem", "SensitivityError", "SensitivityWarning"]

FD_STEP = _EPS ** (1 / 3)

# reasons a jump's sensitivity is not defined (the flag component's codes)
_GRAZING, _NO_GUARD, _SIMULTANEOUS, _NO_FLOW = 1.0, 2.0, 3.0, 4.0
REASONS = {
    _GRAZING: "a grazing jump: the flow is tangent to the guard (its rate dh/dt = "
              "{rate:.3g} changes sign {ratio:.2e} times the flow's duration ({flow:.3g}) "
              "away, at most graze_tol = {tol:g}); the jump time is not differentiable "
              "there",
    _NO_GUARD: "the jump was not triggered at a guard's zero ({why}); the saltation "
               "matrix needs the guard h whose crossing times the jump",
    _SIMULTANEOUS: "simultaneous guards: components {comps} of the vector jump_guard "
                   "are at zero together; the jump's derivative depends on which "
                   "crosses first",
    _NO_FLOW: "the jump starts on the guard's zero without a flow before it (x0, or "
              "a jump map, on the guard): whether it jumps depends on the side of "
              "the guard a perturbation takes",
}
_CODES = (_GRAZING, _NO_GUARD, _SIMULTANEOUS, _NO_FLOW)


class SensitivityError(SimulationError, ValueError):
    """A sensitivity is not defined at a jump; ``.arc`` is the
    :class:`SensitivityArc` with NaN sensitivities from that jump on, and
    ``.t``, ``.j``, ``.reason`` say where and why."""

    def __init__(self, message, arc=None, t=None, j=None, reason=None):
        super().__init__(message, arc)
        self.t, self.j, self.reason = t, j, reason


class SensitivityWarning(SimulationWarning):
    """A sensitivity is not defined at a jump (``undefined="warn"``), or the
    jumps accumulate (Zeno)."""


# --------------------------------------------------------------------------- the system
class SensitivitySystem(HybridSystem):
    """The variational system of a hybrid system, itself a hybrid system.

    Built by :func:`sensitivity_system`; its state is
    ``(x, vec S, dt/dtheta of the last jump, time of the last jump, flag)``
    (``S`` row-major, (n, m)), named by ``components`` ``"x"``, ``"S"``,
    ``"dt"``, ``"t_last"``, ``"flag"``. Run it with :func:`hybridsim.simulate`
    from :meth:`initial_state`, or let :func:`simulate_sensitivity` do both.
    """

    def __init__(self, system, params, wrt, fd_step, graze_tol, make_system):
        self.base = system
        self.wrt = wrt
        self.fd_step = float(fd_step)
        self.graze_tol = float(graze_tol)
        n = self.n = int(system.state_dim)
        self.p = params
        self.nx0 = n if "x0" in wrt else 0
        self.np_ = 0 if params is None or "params" not in wrt else len(params)
        m = self.m = self.nx0 + self.np_
        self.state_dim = n + n * m + m + 2
        self.max_step = system.max_step
        # the systems at p ± δ e_k, built once: derivatives in p by central differences
        self._pm_sys = []          # (system at p + δ, at p - δ, 2δ); their maps: _pm
        for k in range(self.np_):
            d = self.fd_step * max(1.0, abs(params[k]))
            pp, pm = params.copy(), params.copy()
            pp[k] += d
            pm[k] -= d
            pair = []
            for q in (pp, pm):
                try:
                    s = make_system(q)
                except Exception as e:
                    raise ValueError(f"make_system(p) raised {type(e).__name__}: {e} at "
                                     f"params[{k}] = {q[k]!r} (the finite-difference step "
                                     f"for params[{k}] is {d:.3g}); keep p inside the "
                                     f"factory's domain by that much") from e
                if not isinstance(s, HybridSystem) or s.state_dim != n:
                    raise TypeError("make_system(p) must return a HybridSystem of the "
                                    f"same state_dim ({n}), got {s!r}")
                pair.append(s)
            self._pm_sys.append((pair[0], pair[1], pp[k] - pm[k]))
        self._Jf = _user_jac(system, "flow_jacobian", lambda s: s == (n, n), f"({n}, {n})")
        self._Jg = _user_jac(system, "jump_jacobian", lambda s: s == (n, n), f"({n}, {n})")
        self._Jh = _user_jac(system, "jump_guard_gradient",
                             lambda s: s == (n,) or (len(s) == 2 and s[1] == n),
                             f"({n},) or (m, {n})")
        self.components = {"x": slice(0, n), "S": slice(n, n + n * m),
                           "dt": slice(n + n * m, n + n * m + m),
                           "t_last": slice(n + n * m + m, n + n * m + m + 1),
                           "flag": slice(n + n * m + m + 1, n + n * m + m + 2)}
        # mirror the sets and guards of the system, on x only (its maps are made
        # on the Python path's first use: the compiled path needs none of them)
        if system.has_jumps:
            self.jump_set = lambda y, t, j: self._maps.D(y[:n], t, j, None)
        if system.has_flow_boundary:
            self.flow_set = lambda y, t, j: self._maps.C(y[:n], t, j, None)
        self._name = f"sensitivities of {type(system).__name__}"

    @property
    def _maps(self):
        """The system's maps (``HybridSystem._compile``)."""
        return self.base._compile()

    def _mirror(self, which):
        h = getattr(self._maps, which)
        if h is None:
            return None
        n = self.n
        return lambda y, t, j: h(y[:n], t, j, None)

    jump_guard = property(lambda self: self._mirror("hD"),
                          doc="The system's jump guard, on x (None where it has none).")
    flow_guard = property(lambda self: self._mirror("hC"),
                          doc="The system's flow guard, on x (None where it has none).")

    @property
    def _pm(self):
        """The maps of the systems at p ± δ e_k (made on the Python path's first use)."""
        pm = self.__dict__.get("_pm_maps")
        if pm is None:
            pm = self.__dict__["_pm_maps"] = [(a._compile(), b._compile(), d)
                                              for a, b, d in self._pm_sys]
        return pm

    def initial_state(self, x0, t0=0.0):
        """The augmented initial state: x0, S0 = [I | 0], no jump yet at t0."""
        n, m = self.n, self.m
        S0 = np.zeros((n, m))
        S0[:, :self.nx0] = np.eye(n)[:, :self.nx0]
        return np.concatenate([x0, S0.ravel(), np.zeros(m), [t0, 0.0]])

    # ---------------------------------------------------------------- derivatives
    def _f(self, x, t, j):
        return np.asarray(self._maps.f(x, t, j, None), dtype=float)

    def _dfdx(self, x, t, j):
        if self._Jf is not None:
            return self._Jf(x, t, j)
        return _fd_jac(lambda z: self._maps.f(z, t, j, None), x, self.fd_step)

    def _dp(self, which, x, t, j):
        """(k, np) derivative in p of map ``which`` ("f", "g", "hD") at x."""
        cols = [(np.atleast_1d(np.asarray(getattr(a, which)(x, t, j, None), dtype=float))
                 - np.atleast_1d(np.asarray(getattr(b, which)(x, t, j, None), dtype=float)))
                / d for a, b, d in self._pm]
        return np.stack(cols, axis=-1)

    def _tangency(self, x, t, j, hdot, i, t_last):
        """How near the jump at (x, t) is to a tangency of guard component i,
        in units of the flow that led to it: ``2 |h'| / (|h''| (t - t_last))``
        (h' = dh/dt, h'' = d^2h/dt^2 along the flow).

        Along the flow h(t + s) = h' s + h'' s^2 / 2 near the jump, whose rate
        changes sign (the tangency) at s = -h'/h'': the jump time is
        differentiable only for perturbations that move it by less than that.
        Measured against the flow's own duration, the test reads the guard
        along the flow alone (no component of f the guard does not see, no
        scale of x), and is the same at every bounce of a self-similar Zeno
        accumulation (1 for the ball: the apex halves each flow). h'' is a
        central difference of the rate along the flow (the rate itself a
        central difference of h along f), steps ``fd_step`` of the time in
        which the state moves by its own scale.
        """
        mp, f = self._maps, self._f(x, t, j)
        moving = np.abs(f) > 0
        scale = np.maximum(1.0, np.abs(x[moving])) / np.abs(f[moving])
        d = self.fd_step * min(max(1.0, abs(t)), float(np.min(scale)) if scale.size else np.inf)

        def rate(z, s):                     # dh/dt along the flow at (z, s)
            fz = self._f(z, s, j)
            hp = np.atleast_1d(np.asarray(mp.hD(z + d * fz, s + d, j, None), dtype=float))
            hm = np.atleast_1d(np.asarray(mp.hD(z - d * fz, s - d, j, None), dtype=float))
            return (hp[i] - hm[i]) / (2 * d)
        hddot = (rate(x + d * f, t + d) - rate(x - d * f, t - d)) / (2 * d)
        span = abs(hddot) * (t - t_last)
        if span == 0:
            return 0.0 if hdot == 0 else math.inf
        return 2 * abs(hdot) / span

    # ---------------------------------------------------------------- the maps
    def flow_map(self, y, t, j):
        n, m, c = self.n, self.m, self.components
        x = y[:n]
        out = np.zeros(self.state_dim)
        out[:n] = self._f(x, t, j)
        if y[-1] == 0.0 and m:       # once undefined, S is frozen (and masked)
            S = y[c["S"]].reshape(n, m)
            dS = self._dfdx(x, t, j) @ S
            if self.np_:
                dS[:, self.nx0:] += self._dp("f", x, t, j)
            out[c["S"]] = dS.ravel()
        return out

    def jump_map(self, y, t, j):
        n, m, c, mp, step = self.n, self.m, self.components, self._maps, self.fd_step
        x = np.array(y[:n], dtype=float)
        S = y[c["S"]].reshape(n, m)
        dt_prev = y[c["dt"]]
        t_last, flag = float(y[c["t_last"]][0]), float(y[-1])
        # the jump map as it acts at this event: an interconnection jumps the
        # components in their D here, and its derivatives keep that choice (a
        # perturbation must not take a component out of D, nor p move a guard)
        jumping = _jumping(self.base, x, t, j)
        g = _frozen_jump(self.base, mp, jumping)
        xp = np.asarray(g(x, t, j), dtype=float)
        out = np.zeros(self.state_dim)
        out[:n] = xp
        out[c["t_last"]] = t
        if flag != 0.0 or m == 0:
            out[c["S"]] = S.ravel()
            out[-1] = flag
            return out
        Dg = (self._Jg(x, t, j) if self._Jg is not None
              else _fd_jac(lambda z: g(z, t, j), x, step))
        g_t = _fd_scalar(lambda s: g(x, s, j), t, step)
        g_th = np.zeros((n, m))
        if self.np_:
            g_th[:, self.nx0:] = np.stack(
                [(np.asarray(_frozen_jump(a, a._compile(), jumping)(x, t, j), dtype=float)
                  - np.asarray(_frozen_jump(b, b._compile(), jumping)(x, t, j), dtype=float))
                 / d for a, b, d in self._pm_sys], axis=-1)
        f_minus = self._f(x, t, j)
        flowed = t > t_last
        dt, code = dt_prev, 0.0
        if mp.hD is None:
            code = _NO_GUARD
        else:
            hv = np.atleast_1d(np.asarray(mp.hD(x, t, j, None), dtype=float))
            grad = (np.atleast_2d(self._Jh(x, t, j)) if self._Jh is not None
                    else np.atleast_2d(_fd_jac(lambda z: mp.hD(z, t, j, None), x, step)))
            h_t = _fd_scalar(lambda s: mp.hD(x, s, j, None), t, step)
            hdot = grad @ f_minus + h_t
            zero = _at_zero(hv, hdot, grad, x, t)
            i = int(np.argmin(hv))
            if flowed and zero[i]:
                if np.count_nonzero(zero) > 1:
                    code = _SIMULTANEOUS
                elif self._tangency(x, t, j, hdot[i], i, t_last) <= self.graze_tol:
                    code = _GRAZING
                else:
                    num = grad[i] @ S
                    if self.np_:
                        num[self.nx0:] += self._dp("hD", x, t, j)[i]
                    dt = -num / hdot[i]
            elif flowed:
                code = _NO_GUARD      # the jump set fired away from the guard's zero
            elif zero[i]:
                code = _NO_FLOW
            # else: strictly inside D at the instant of the last jump (or t0):
            # the jump follows at once whatever theta, at the last jump's time
        if code:
            out[c["S"]] = S.ravel()
            out[-1] = code
            return out
        f_plus = self._f(xp, t, j + 1)
        Sp = Dg @ S + g_th + np.outer(Dg @ f_minus + g_t - f_plus, dt)
        out[c["S"]] = Sp.ravel()
        out[c["dt"]] = dt
        return out


def sensitivity_system(system, *, params: ArrayLike | None = None, wrt=None,
                       fd_step: float = FD_STEP, graze_tol: float = 1e-6):
    """The variational system of ``system`` as a hybrid system.

    Parameters
    ----------
    system : HybridSystem or callable
        The system; with ``params``, a factory ``make_system(p)`` returning it.
    params : array_like, optional
        The nominal parameters p (1-D, finite).
    wrt : {"x0", "params"} or tuple of them, optional
        The columns of S: ``("x0", "params")`` where params are given, else
        ``("x0",)``.
    fd_step : float
        Relative step of the central differences (default eps^(1/3)).
    graze_tol : float
        A jump is grazing when the guard's rate along the flow changes sign
        within ``graze_tol`` times the flow's duration of it:
        ``2 |h'| <= graze_tol * |h''| * (t_j - t_last)`` (h', h'' the first
        and second derivatives of the guard along the flow).

    Returns
    -------
    SensitivitySystem

    Examples
    --------
    >>> from hybridsim.library import BouncingBall
    >>> from hybridsim.sensitivity import sensitivity_system
    >>> ssys = sensitivity_system(BouncingBall())
    >>> ssys.state_dim, list(ssys.components)       # x, S (2x2), dt (2), t_last, flag
    (10, ['x', 'S', 'dt', 't_last', 'flag'])
    """
    if params is not None:
        if not callable(system) or isinstance(system, HybridSystem):
            raise TypeError("with params, system must be a factory make_system(p) -> "
                            f"HybridSystem (as for hs.sweep), got {type(system).__name__}")
        p = np.array(params, dtype=float)
        if p.ndim != 1 or p.size == 0 or not np.all(np.isfinite(p)):
            raise ValueError(f"params must be a non-empty 1-D array of finite floats, got "
                             f"{params!r}")
        make_system = system
        system = make_system(p.copy())
        if not isinstance(system, HybridSystem):
            raise TypeError(f"make_system(params) must return a HybridSystem, got "
                            f"{type(system).__name__}")
    else:
        p, make_system = None, None
        if not isinstance(system, HybridSystem):
            raise TypeError(f"system must be a hybridsim.HybridSystem (or, with params=, a "
                            f"factory make_system(p)), got {type(system).__name__}")
    wrt = _check_wrt(("x0", "params") if (wrt is None and p is not None) else
                     (("x0",) if wrt is None else wrt), p is not None)
    if not (isinstance(fd_step, (float, int)) and 0 < fd_step < 1):
        raise ValueError(f"fd_step must be a float in (0, 1), got {fd_step!r}")
    if not (isinstance(graze_tol, (float, int)) and 0 <= graze_tol < 1):
        raise ValueError(f"graze_tol must be a float in [0, 1), got {graze_tol!r}")
    if int(system.input_dim or 0) > 0:
        raise ValueError("system: sensitivities need a closed system (input_dim = 0); "
                         "close the loop with hs.connect")
    if system.needs_history or system.delays:
        raise ValueError("system: sensitivities of systems with delays (needs_history, "
                         "delays) are not supported")
    if system.vectorized:
        raise ValueError("system: a vectorized system's batches do not carry the "
                         "variational system; give the single-state (not vectorized) system")
    return SensitivitySystem(system, p, wrt, fd_step, graze_tol, make_system)


# --------------------------------------------------------------------------- the result
class SensitivityArc:
    """A hybrid arc with its sensitivities ``S = dx/dtheta`` and ``dt_j/dtheta``.

    Attributes
    ----------
    arc : HybridArc
        The state's arc (x only), as :func:`hybridsim.simulate` returns it.
    augmented : HybridArc
        The variational system's arc (its components ``"x"``, ``"S"``...).
    theta_names : list of str
        The columns of S: ``"x0[i]"`` then ``"p[k]"``.
    S : ndarray, shape (N, n, m)
        The sensitivity at every sample (NaN from an undefined jump on).
    dtj_dtheta : ndarray, shape (J, m)
        ``d t_j / d theta`` for every jump, in the order of ``jump_times``.
    undefined : tuple or None
        ``(t, j, reason)`` of the first jump where S is not defined.
    """

    def __init__(self, aug, ssys, undefined=None):
        n, m, c = ssys.n, ssys.m, ssys.components
        self.augmented = aug
        self.system = ssys
        self.nx0, self.np_ = ssys.nx0, ssys.np_
        self.theta_names = ([f"x0[{i}]" for i in range(ssys.nx0)]
                            + [f"p[{k}]" for k in range(ssys.np_)])
        arc = aug.component("x")
        arc.components, arc.system = ssys.base.components, ssys.base
        arc.system_description = aug.system_description
        self.arc = arc
        self.S = aug.x[:, c["S"]].reshape(-1, n, m).copy()
        end = aug.is_jump_end
        self.dtj_dtheta = aug.x[end][:, c["dt"]].copy()
        self.undefined = undefined
        if undefined is not None:
            bad = (aug.t > undefined[0]) | ((aug.t == undefined[0]) & (aug.j >= undefined[1]))
            self.S[bad] = np.nan
            self.dtj_dtheta[aug.j[end] >= undefined[1]] = np.nan
        self._bad = undefined

    # plain views
    t = property(lambda self: self.arc.t, doc="Ordinary time of each sample.")
    j = property(lambda self: self.arc.j, doc="Jump count of each sample.")
    x = property(lambda self: self.arc.x, doc="The state at each sample, (N, n).")
    jump_times = property(lambda self: self.arc.jump_times, doc="The jump times, (J,).")
    termination = property(lambda self: self.arc.termination, doc="Why the run stopped.")

    @property
    def dx_dx0(self):
        """``dx/dx0`` at every sample, (N, n, n) (needs ``"x0"`` in ``wrt``)."""
        self._need("x0")
        return self.S[:, :, :self.nx0]

    @property
    def dx_dp(self):
        """``dx/dp`` at every sample, (N, n, np) (needs ``"params"`` in ``wrt``)."""
        self._need("params")
        return self.S[:, :, self.nx0:]

    @property
    def dtj_dx0(self):
        """``d t_j / d x0`` for every jump, (J, n)."""
        self._need("x0")
        return self.dtj_dtheta[:, :self.nx0]

    @property
    def dtj_dp(self):
        """``d t_j / d p`` for every jump, (J, np)."""
        self._need("params")
        return self.dtj_dtheta[:, self.nx0:]

    def _need(self, w):
        if w not in self.system.wrt:
            raise ValueError(f"no sensitivities with respect to {w}: the run had "
                             f"wrt={self.system.wrt}")

    def at(self, t, j=None):
        """``(x, S)`` at hybrid time (t, j), interpolated like the state.

        Through the run's dense output where it kept one (``dense=True``),
        else cubic Hermite with the augmented flow at the samples (see
        :meth:`hybridsim.HybridArc.at`); t scalar or array, j as there.
        """
        n, m, c = self.system.n, self.system.m, self.system.components
        y = self.augmented.at(t, j)
        x, S = y[..., :n], y[..., c["S"]].reshape(y.shape[:-1] + (n, m))
        if self._bad is not None:
            tb, jb, _ = self._bad
            tt = np.broadcast_to(np.asarray(t, dtype=float), y.shape[:-1])
            jj = (np.broadcast_to(np.asarray(j), y.shape[:-1]) if j is not None
                  else self._last_j(tt))
            bad = (tt > tb) | ((tt == tb) & (jj >= jb))
            S = np.where(bad[..., None, None], np.nan, S)
        return x, S

    def _last_j(self, tt):
        k = np.searchsorted(self.t, tt, side="right") - 1
        return self.j[np.clip(k, 0, len(self.j) - 1)]

    def S_at(self, t, j=None):
        """The sensitivity ``dx/dtheta`` at (t, j), (n, m) (see :meth:`at`)."""
        return self.at(t, j)[1]

    def covariance(self, P0, t, j=None):
        """The linearised covariance of x(t, j): ``S P0 S^T``.

        ``P0`` is the covariance of theta (m, m): of x0, of p, or of both
        (x0 first), independent of the jumps (P+ = S P S^T through each).

        Examples
        --------
        >>> from hybridsim.library import BouncingBall
        >>> sarc = hs.simulate_sensitivity(BouncingBall(), [1.0, 0.0], t_max=1.0)
        >>> P = sarc.covariance(np.diag([1e-4, 1e-4]), 1.0)
        >>> P.shape, bool(np.allclose(P, P.T))
        ((2, 2), True)
        """
        m = self.system.m
        P0 = np.asarray(P0, dtype=float)
        if P0.shape != (m, m) or not np.all(np.isfinite(P0)) or not np.allclose(P0, P0.T):
            raise ValueError(f"P0 must be a finite symmetric ({m}, {m}) covariance of "
                             f"theta = {self.theta_names}, got shape {P0.shape}")
        S = self.S_at(t, j)
        return S @ P0 @ np.swapaxes(S, -1, -2)

    def __repr__(self):
        return (f"<SensitivityArc: {len(self.t)} samples, {self.arc.jump_count} jumps, "
                f"theta={self.theta_names}, {self.termination.name if self.termination else None}>")


# --------------------------------------------------------------------------- the run
def simulate_sensitivity(system: HybridSystem | Callable[..., HybridSystem], x0: ArrayLike,
                         t_max: float, j_max: float = math.inf, *,
                         params: ArrayLike | None = None,
                         wrt: str | tuple[str, ...] | None = None,
                         sens_atol: float | None = None, fd_step: float = FD_STEP,
                         graze_tol: float = 1e-6, undefined: str = "raise",
                         backend: str = "python", **options: Any) -> SensitivityArc:
    """Simulate a hybrid system with its forward sensitivities through jumps.

    Parameters
    ----------
    system : HybridSystem or callable
        The system, or with ``params`` a factory ``make_system(p) ->
        HybridSystem`` (as for :func:`hybridsim.sweep`). Optional Jacobians
        on the system: ``flow_jacobian``, ``jump_jacobian``,
        ``jump_guard_gradient`` (see the module's docstring); otherwise
        central differences.
    x0 : array_like, shape (n,)
        Initial state.
    t_max, j_max : float
        As in :func:`hybridsim.simulate`.
    params : array_like, optional
        Nominal parameters p passed to the factory.
    wrt : "x0", "params" or a tuple of both, optional
        The columns theta of S, x0's first (default: both where params are
        given, else x0).
    sens_atol : float, optional
        Absolute tolerance on the entries of S (default: ``atol``); ``rtol``
        applies to x and S alike.
    fd_step : float
        Relative step of the central differences (default eps^(1/3)).
    graze_tol : float
        A jump is grazing when the guard's rate along the flow changes sign
        within ``graze_tol`` times the flow's duration of it (``2 |h'| <=
        graze_tol * |h''| * (t_j - t_last)``); a Zeno accumulation is not
        grazing (the ball's ratio is 1 at every bounce): it ends ``ZENO``
        and warns.
    undefined : {"raise", "warn"}
        Where a jump's sensitivity is not defined: raise
        :class:`SensitivityError`, or warn (:class:`SensitivityWarning`)
        and return NaN sensitivities from that jump on. A Zeno accumulation
        always warns (the values up to the last jump are defined).
    backend : {"python", "compiled", "auto"}
        ``"compiled"`` runs the variational system compiled (the module's
        notes), refused by name where the system cannot (an interconnection,
        Jacobians given by the system, a model that does not lower);
        ``"auto"`` takes the compiled path where numba is installed, the
        system and the options allow it, else the Python path.
    **options
        Any option of :func:`hybridsim.simulate` (``rtol``, ``atol``,
        ``method``, ``priority``, ``dense``, ``refine``, ``t_eval``...).
        ``max_norm`` bounds the norm of the augmented state (x, S, ...).

    Returns
    -------
    SensitivityArc

    Raises
    ------
    SensitivityError
        A jump's sensitivity is not defined (``undefined="raise"``).

    Examples
    --------
    >>> timer = hs.HybridSystem.from_functions(
    ...     flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
    ...     jump_guard=lambda x: x[0] - 1.0, state_dim=1)
    >>> sarc = hs.simulate_sensitivity(timer, [0.25], t_max=2.0)
    >>> sarc.dtj_dx0[:, 0]                  # every jump comes 1 s earlier per unit of x0
    array([-1., -1.])
    >>> sarc.S_at(2.0)[0, 0]        # x(t) = t - t_j and t_j moves with x0: dx/dx0 = 1
    1.0
    """
    if backend not in ("python", "compiled", "auto"):
        raise ValueError(f"backend must be 'python', 'compiled' or 'auto', got {backend!r}")
    if undefined not in ("raise", "warn"):
        raise ValueError(f"undefined must be 'raise' or 'warn', got {undefined!r}")
    if "inputs" in options or "prehistory" in options:
        raise ValueError("inputs/prehistory: sensitivities need a closed system without "
                         "history; close the loop with hs.connect")
    ssys = sensitivity_system(system, params=params, wrt=wrt, fd_step=fd_step,
                              graze_tol=graze_tol)
    n, m = ssys.n, ssys.m
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (n,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 must be a finite array of shape ({n},), got {x0!r}")
    atol = options.pop("atol", 1e-9)
    atol_x = np.broadcast_to(np.asarray(atol, dtype=float), (n,)) if np.ndim(atol) <= 1 \
        and np.size(atol) in (1, n) else None
    if atol_x is None:
        raise ValueError(f"atol must be a float or an array of {n} floats, got {atol!r}")
    s_atol = float(np.min(atol_x)) if sens_atol is None else sens_atol
    if not (isinstance(s_atol, (float, int)) and s_atol > 0 and math.isfinite(s_atol)):
        raise ValueError(f"sens_atol must be a positive float, got {sens_atol!r}")
    atol_aug = np.concatenate([atol_x, np.full(n * m, float(s_atol)), np.ones(m + 2)])
    t0 = float(options.get("t0", 0.0))
    target = _on_path(ssys, backend, options)
    aug = simulate(target, ssys.initial_state(x0, t0), t_max, j_max, atol=atol_aug,
                   backend="python" if target is ssys else "compiled", **options)
    if target is not ssys:
        from .compiled._lower import rebind
        rebind(aug, ssys)
    # the first jump whose sensitivity is undefined
    flags = aug.x[:, -1]
    bad = None
    if np.any(flags != 0):
        k = int(np.argmax(flags != 0))
        tb, jb = float(aug.t[k]), int(aug.j[k])
        bad = (tb, jb, _explain(ssys, aug, k, flags[k]))
    sarc = SensitivityArc(aug, ssys, bad)
    if bad is not None:
        msg = (f"the sensitivity of the jump at t={bad[0]:.10g} (j={bad[1] - 1} -> {bad[1]}) "
               f"is not defined: {bad[2]}")
        if undefined == "raise":
            raise SensitivityError(msg + "; undefined='warn' returns NaN sensitivities from "
                                   "that jump on", sarc, bad[0], bad[1], bad[2])
        warnings.warn(msg + "; the sensitivities from that jump on are NaN",
                      SensitivityWarning, stacklevel=2)
    if aug.termination is Termination.ZENO and aug.jump_count:
        warnings.warn(f"Zeno accumulation: the run stopped with ZENO after the jump at "
                      f"t={aug.jump_times[-1]:.10g} (j={aug.j[-1]}); the sensitivities are "
                      "those of the jumps taken, and are not defined at the accumulation "
                      "point or beyond", SensitivityWarning, stacklevel=2)
    return sarc


def _on_path(ssys, backend, options):
    """What runs the variational system: ``ssys`` (the Python path) or its
    compiled form (``backend`` "compiled", or "auto" where it can)."""
    if backend == "python":
        return ssys
    from . import _variational
    from .compiled import available
    if backend == "auto":
        from .run import _COMPILED_ONLY_AT
        if not available() or any(options.get(k, v[0]) not in v
                                  for k, v in _COMPILED_ONLY_AT.items()) \
                or not _method_compiles(options.get("method", "RK45")):
            return ssys
        cs = _variational.auto(ssys, _CODES)
        return ssys if cs is None else cs
    return _variational.compiled_variational(ssys, _CODES)


def _method_compiles(method):
    from .options import method_on
    try:
        method_on("compiled", method)
    except (TypeError, ValueError):
        return False
    return True


def _explain(ssys, aug, k, code):
    """The reason for flag ``code`` raised at sample k (the post-jump sample)."""
    n, mp = ssys.n, ssys._maps
    x, t, j = aug.x[k - 1, :n], float(aug.t[k - 1]), int(aug.j[k - 1])
    if code == _GRAZING:
        f = np.asarray(mp.f(x, t, j, None), dtype=float)
        grad = np.atleast_2d(_fd_jac(lambda z: mp.hD(z, t, j, None), x, ssys.fd_step))
        h_t = _fd_scalar(lambda s: mp.hD(x, s, j, None), t, ssys.fd_step)
        i = int(np.argmin(np.atleast_1d(mp.hD(x, t, j, None))))
        hdot = float(grad[i] @ f + h_t[i])
        t_last = float(aug.x[k - 1, ssys.components["t_last"]][0])
        ratio = ssys._tangency(x, t, j, hdot, i, t_last)
        return REASONS[code].format(rate=hdot, ratio=ratio, flow=t - t_last,
                                    tol=ssys.graze_tol)
    if code == _NO_GUARD:
        why = ("the system has no jump_guard: a jump set given by an indicator alone"
               if mp.hD is None else "the jump set fired where the guard is not at zero")
        return REASONS[code].format(why=why)
    if code == _SIMULTANEOUS:
        hv = np.atleast_1d(np.asarray(mp.hD(x, t, j, None), dtype=float))
        grad = np.atleast_2d(_fd_jac(lambda z: mp.hD(z, t, j, None), x, ssys.fd_step))
        hdot = grad @ np.asarray(mp.f(x, t, j, None), dtype=float)
        comps = np.flatnonzero(_at_zero(hv, hdot, grad, x, t))
        return REASONS[code].format(comps=comps.tolist())
    return REASONS[code]


def margin_gradient(sarc: SensitivityArc, claim, *, rel_step: float = 1e-6) -> np.ndarray:
    """The gradient of a claim's margin in theta, through the linearised arc.

    ``claim(arc) -> margin`` (a :mod:`hybridsim.testing` margin, or any
    function of an arc's samples) is evaluated on the arcs x ± ε S_k, with
    each jump's two samples moved to t_j ± ε dt_j/dθ_k and their states
    to x ± ε (S + f dt_j/dθ_k) (the state at the moved event), and
    differenced centrally. For margins that are a min or max over samples of
    a smooth function of (t, x) this is the margin's derivative (Danskin:
    the deciding sample's), to the rounding of the difference,
    ``rel_step`` (1e-6) of the state's scale. It needs no new run. It is
    the derivative of the margin as the claim computes it from the samples:
    for a max over time, store samples densely (``refine``, ``t_eval``).

    Returns
    -------
    ndarray, shape (m,)
        d margin / d theta; NaN where the sensitivities are not defined.

    Examples
    --------
    >>> from hybridsim.library import BouncingBall
    >>> sarc = hs.simulate_sensitivity(BouncingBall(), [1.0, 0.0], t_max=1.0)
    >>> late = lambda arc: arc.jump_times[0] - 0.4      # "the first impact after 0.4 s"
    >>> g = margin_gradient(sarc, late)                 # d t_1 / d h0 = t_1 / (2 h0)
    >>> bool(np.isclose(g[0], np.sqrt(2 / 9.81) / 2, rtol=1e-6))
    True
    """
    if not isinstance(sarc, SensitivityArc):
        raise TypeError(f"sarc must be a SensitivityArc, got {type(sarc).__name__}")
    if not callable(claim):
        raise TypeError(f"claim must be callable (arc -> margin), got {type(claim).__name__}")
    if not (isinstance(rel_step, (float, int)) and 0 < rel_step < 1):
        raise ValueError(f"rel_step must be a float in (0, 1), got {rel_step!r}")
    arc, aug, ssys = sarc.arc, sarc.augmented, sarc.system
    n, m, c = ssys.n, ssys.m, ssys.components
    S = sarc.S
    if not np.all(np.isfinite(S)) or not np.all(np.isfinite(sarc.dtj_dtheta)):
        return np.full(m, np.nan)
    # the flow at each jump's samples, for the moved events
    starts = np.flatnonzero(aug.is_jump_start)
    jumps = np.concatenate([starts, starts + 1])
    dt = np.concatenate([sarc.dtj_dtheta, sarc.dtj_dtheta])       # (2J, m)
    fj = np.array([ssys._f(arc.x[i], float(arc.t[i]), int(arc.j[i])) for i in jumps]) \
        .reshape(len(jumps), n)
    xd = None if aug.xdot is None else aug.xdot[:, :n]
    Sd = None if aug.xdot is None else aug.xdot[:, c["S"]].reshape(-1, n, m)
    scale = max(1.0, float(np.max(np.abs(arc.x))))
    g = np.empty(m)
    for k in range(m):
        size = float(np.max(np.abs(S[:, :, k])))
        if size == 0 and not np.any(dt[:, k]):
            g[k] = 0.0
            continue
        eps = rel_step * scale / max(size, 1.0)
        vals = []
        for sgn in (1.0, -1.0):
            t = arc.t.copy()
            x = arc.x + sgn * eps * S[:, :, k]
            t[jumps] += sgn * eps * dt[:, k]
            x[jumps] += sgn * eps * fj * dt[:, k, None]
            xdot = None if xd is None else xd + sgn * eps * Sd[:, :, k]
            vals.append(float(claim(arc._like(t, arc.j, x, xdot=xdot, segments=None,
                                              components=arc.components,
                                              system=arc.system, keep=False))))
        g[k] = (vals[0] - vals[1]) / (2 * eps)
    return g
