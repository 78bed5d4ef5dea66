r"""The hybrid systems of paper 001: the observer (23)/(27) and its plants.

:class:`ReducedOrderObserver`
    the reduced-order finite-time observer (23) (known disturbance) or
    (27) (unknown), exact for t >= tau (Theorem 1, (24)); its input is the
    measured output y (17) and any known signals w its maps need.
:func:`lti_observer`
    the Section II observer (15) for xdot = A x + delta(t), y = C x.
:class:`TimeVaryingPlant`
    the system (16) built from an observer's own data.
:class:`ChainedFormPlant`
    the closed-loop chained form (44) of Section IV.
:func:`chained_form_observer`
    the observer of Section IV-B for (45) (tau = 2 pi, L = -2 cos t), run
    with :class:`ChainedFormPlant`.
:func:`tracking_loop`
    the output-feedback loop (44) + (58): the plant, the observer, and the
    control (57) fed with the estimate (50).

Each observer carries a :class:`PlantModel` (``observer.plant_model``): the
plant it observes, what of the plant's output it measures, and where x_r
is in the plant's state, so that :func:`observers.time_varying.simulate`
and :func:`observers.time_varying.errors` need nothing else.

Examples
--------
>>> import numpy as np
>>> from observers.time_varying import lti_observer
>>> obs, rc = lti_observer([[0.0, 1.0], [-2.0, -3.0]], [[1.0, 0.0]], tau=0.5)
>>> obs.state_dim, obs.input_dim, obs.output_dim   # [J_A, J_H, s, q]; y; [P, G]
(4, 1, 2)
>>> obs.plant_model.description
'LinearPlant: xdot = A x + delta(t), y = C x (2)-(3)'
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import linalg

import hybridsim as hs

from .._common import matrix, scalar, vector
from .design import (
    TAU_EXAMPLE,
    _dims,
    _rcond,
    _tv_data,
    choose_L_tau,
    example_data,
    reduced_coordinates,
    v2_feedback,
)

__all__ = ["PlantModel", "ReducedOrderObserver", "TimeVaryingPlant", "lti_observer",
           "ChainedFormPlant", "chained_form_observer", "tracking_loop", "ChainedFormEstimates"]


@dataclass(frozen=True)
class PlantModel:
    """The plant an observer is run with, and how to read it.

    Attributes
    ----------
    make : callable () -> hybridsim.HybridSystem
        A fresh plant. Its input, if any, is the observer's known signal w
        (``observer.w_dim`` entries, e.g. v2 of Section IV).
    measure : callable (plant output) -> (p,) array
        The noise-free measured signal z of (17) from the plant's output.
    x_r : callable ((N, n_plant) states) -> (N, m) array
        The unmeasured part x_r of the plant's state, time-major.
    initial_state : callable (x0) -> plant state
        Checks the user's x0 and returns the plant's initial state.
    description : str
        One line: which plant, which equation.
    """

    make: Callable
    measure: Callable
    x_r: Callable
    initial_state: Callable
    description: str


class ReducedOrderObserver(hs.HybridSystem):
    r"""The reduced-order finite-time observer (23)/(27) as a hybrid system.

    State (time-major arcs: one row per sample) ``x = [J_A, J_H, s, q]``:

    * J_A (m): J_A' = A2(t) J_A + delta2(t, z, w);
    * J_H (m): J_H' = H(t) J_H + delta4(t, z, w), H = A2 + L A1, delta4 of (21);
    * s: a timer, s' = 1, from s = 0 at the start of the measurements;
    * q in {0, 1}: 0 while the window [t - tau, t] is not yet measured; a jump
      at s = tau sets q = 1 (D = {q = 0, s >= tau}, located by root-finding).

    with z = y - eps(t) when the disturbance ``eps`` is known (the exact
    estimate (23)) and z = y otherwise (the approximate observer (27)). The
    input is u = [y (p), w (w_dim)], w being known signals the maps delta1,
    delta2 need (e.g. the control v2 of Section IV).

    Output ``[P (m), G (m*p, row-major)]``, with the estimate

        xhat_r(t) = P(t) + G(t) y(t)     (:meth:`estimate`),

    where, for q = 1 (t >= t0 + tau)::

        Lambda P = Phi_A2(t, t-tau) J_A(t) - J_A(t-tau) + Phi_H(t, t-tau) J_H(t)
                   - J_H(t-tau) - L(t-tau) z(t-tau) [- Phi_H(t, t-tau) L(t) eps(t)],
        Lambda G = Phi_H(t, t-tau) L(t),

    which is (23) (the window integrals rewritten through the semigroup
    identity, see the module docstring) and equals x_r(t) exactly
    (Theorem 1). For q = 0 the estimate is undefined: P = ``xr_init``, G = 0.

    Parameters
    ----------
    tau : float > 0
        The delay of Assumption 1.
    A1, A2, L : callables t -> (p, m), (m, m), (m, p) matrices, or constant arrays
    Phi_A2, Phi_H : callable (t, t0) -> (m, m)
        Phi of (1) for A2 and H (closed forms, or :func:`fundamental_matrix`).
    delta1, delta2 : callable, optional
        delta1(t, z) -> (p,), delta2(t, z) -> (m,) when ``w_dim == 0``;
        delta1(t, z, w), delta2(t, z, w) otherwise. Default 0.
    Ldot : callable, optional
        Derivative of L (default: 0 for a constant L, 4th-order central
        difference for a callable L).
    eps : callable t -> (p,), optional
        Known measurement disturbance: gives the exact (23); None gives (27).
    p, m : int, optional
        Dimensions of y and x_r (inferred from array arguments).
    w_dim : int
        Dimension of the extra known input w.
    xr_init : (m,) array, optional
        The output before the window is filled (default 0).
    rcond_min : float
        Lambda(t) counts as singular (a ValueError, i.e. a MAP_ERROR
        termination of the run, naming t) below this reciprocal condition.
    check_Lambda : bool
        Check Assumption 1 at every flow-map call once the window is filled
        (default True; the output map always checks it).
    z_history : callable s -> (p,), optional
        Where to read y(t - tau). Default: the observer's own input history.
        An interconnection whose observer input depends on the observer's own
        output (a feedback loop) should read it from the plant instead, to
        avoid a chain of evaluations back to t0 (see :func:`tracking_loop`).

    References
    ----------
    [1] eqs. (1), (16)-(24), (27); Theorem 1; Remark 4.
    """

    needs_history = True

    def __init__(self, tau, A1, A2, L, Phi_A2, Phi_H, *, delta1=None, delta2=None, Ldot=None,
                 eps=None, p=None, m=None, w_dim=0, xr_init=None, rcond_min=1e-12, z_history=None,
                 check_Lambda=True):
        self.tau = scalar("tau", tau, positive=True)
        p, m = _dims(A1, A2, L, p, m)
        self.p, self.m = p, m
        if isinstance(w_dim, bool) or not isinstance(w_dim, (int, np.integer)) or w_dim < 0:
            raise ValueError(f"w_dim must be an int >= 0, got {w_dim!r}")
        self.w_dim = int(w_dim)
        for nm, f in (("Phi_A2", Phi_A2), ("Phi_H", Phi_H), ("delta1", delta1), ("delta2", delta2),
                      ("eps", eps), ("z_history", z_history)):
            if f is not None and not callable(f):
                raise TypeError(f"{nm} must be callable, got {type(f).__name__}")
        if Phi_A2 is None or Phi_H is None:
            raise TypeError("Phi_A2 and Phi_H must be callables (t, t0) -> (m, m); "
                            "use fundamental_matrix() for a numerical one")
        self.A1, self.A2, self.L, self.Ldot = _tv_data(A1, A2, L, Ldot, p, m)
        self.Phi_A2 = lambda t, s: np.atleast_2d(np.asarray(Phi_A2(t, s), dtype=float))
        self.Phi_H = lambda t, s: np.atleast_2d(np.asarray(Phi_H(t, s), dtype=float))
        # dimensions agree at construction, not as a matmul error inside a run: probe the data at
        # t = tau
        for nm, f, shape in (("A1", self.A1, (p, m)), ("A2", self.A2, (m, m)),
                             ("L", self.L, (m, p)),
                             ("Phi_A2", lambda t: self.Phi_A2(t, 0.0), (m, m)),
                             ("Phi_H", lambda t: self.Phi_H(t, 0.0), (m, m))):
            v = f(self.tau)
            if np.shape(v) != shape:
                raise ValueError(f"{nm} must be {shape[0]} x {shape[1]} "
                                 f"(p = {p} outputs, m = {m} estimated states), "
                                 f"got shape {np.shape(v)}")

        def wrap(f, k):
            if f is None:
                return lambda t, z, w: np.zeros(k)
            return f if self.w_dim else (lambda t, z, w: f(t, z))
        self.delta1 = wrap(delta1, p)
        self.delta2 = wrap(delta2, m)
        self.eps = eps
        xi = np.zeros(m) if xr_init is None else np.atleast_1d(np.asarray(xr_init, dtype=float))
        if xi.shape != (m,):
            raise ValueError(f"xr_init must have shape ({m},), got {xi.shape}")
        self.xr_init = xi
        self.rcond_min = float(rcond_min)
        self.check_Lambda = bool(check_Lambda)
        self.z_history = z_history
        self.state_dim = 2 * m + 2
        self.input_dim = p + self.w_dim
        self.output_dim = m + m * p
        self.max_step = self.tau
        #: the plant run with this observer by simulate() (default: (16) with its own data)
        self.plant_model = _plant16(self)

    # -- helpers --------------------------------------------------------------
    def initial_state(self, J_A=None, J_H=None):
        """x0 = [J_A, J_H, s = 0, q = 0]; J_A, J_H default 0 (their value does not matter)."""
        m = self.m
        JA = np.zeros(m) if J_A is None else np.asarray(J_A, float).reshape(m)
        JH = np.zeros(m) if J_H is None else np.asarray(J_H, float).reshape(m)
        return np.concatenate([JA, JH, [0.0, 0.0]])

    def _z(self, y, t):
        z = np.asarray(y, dtype=float).reshape(self.p)
        return z if self.eps is None else z - np.asarray(self.eps(t), dtype=float).reshape(self.p)

    def _split_u(self, u, t):
        u = np.atleast_1d(np.asarray(u, dtype=float))
        if u.shape != (self.input_dim,):
            raise ValueError(f"observer input must have shape ({self.input_dim},) = "
                             f"[y (p={self.p}), w (w_dim={self.w_dim})], got {u.shape}")
        return self._z(u[: self.p], t), u[self.p:]

    def H(self, t):
        """H(t) = A2(t) + L(t) A1(t) (Assumption 1)."""
        return self.A2(t) + self.L(t) @ self.A1(t)

    def Lambda(self, t):
        """Lambda(t) of (20)."""
        return self.Phi_A2(t, t - self.tau) - self.Phi_H(t, t - self.tau)

    # -- data (C, f, D, g) ------------------------------------------------------
    def _Lambda_checked(self, t):
        t0 = t - self.tau
        PA, PH = self.Phi_A2(t, t0), self.Phi_H(t, t0)
        Lam = PA - PH
        rc = _rcond(Lam)
        if not rc >= self.rcond_min:
            raise ValueError(f"Assumption 1 fails along the run: Lambda(t) (20) is singular at "
                             f"t={t:.6g} (rcond {rc:.3g} < {self.rcond_min:g})")
        return PA, PH, Lam

    def flow_map(self, x, t, j, u):
        m = self.m
        if self.check_Lambda and x[-1] >= 0.5:
            self._Lambda_checked(t)
        z, w = self._split_u(u, t)
        JA, JH = x[:m], x[m:2 * m]
        A2 = self.A2(t)
        Lt = self.L(t)
        H = A2 + Lt @ self.A1(t)
        d1 = np.asarray(self.delta1(t, z, w), float).reshape(self.p)
        d2 = np.asarray(self.delta2(t, z, w), float).reshape(m)
        D = self.Ldot(t) - H @ Lt
        d4 = -(D @ z + Lt @ d1 + d2)                           # (21)
        return np.concatenate([A2 @ JA + d2, H @ JH + d4, [1.0, 0.0]])

    def jump_guard(self, x, t, j, u):
        return np.array([x[-2] - self.tau, 0.5 - x[-1]])

    def jump_set(self, x, t, j, u):
        return bool(x[-1] < 0.5 and x[-2] >= self.tau * (1 - 1e-12))

    def jump_map(self, x, t, j, u):
        xn = np.array(x, dtype=float)
        xn[-1] = 1.0
        return xn

    def _z_past(self, s):
        if self.z_history is not None:
            return self._z(self.z_history(s), s)
        u = self.history.input(s)
        return self._z(np.atleast_1d(np.asarray(u, dtype=float))[: self.p], s)

    def output(self, x, t, j):
        m, p = self.m, self.p
        if x[-1] < 0.5:
            return np.concatenate([self.xr_init, np.zeros(m * p)])
        t0 = t - self.tau
        past = np.asarray(self.history(t0), dtype=float)
        PA, PH, Lam = self._Lambda_checked(t)
        Lt = self.L(t)
        r = (PA @ x[:m] - past[:m] + PH @ x[m:2 * m] - past[m:2 * m]
             - self.L(t0) @ self._z_past(t0))
        Gn = PH @ Lt
        if self.eps is not None:
            r = r - Gn @ np.asarray(self.eps(t), dtype=float).reshape(p)
        if m == 1:                                  # Lambda is a number: no LAPACK call
            return np.concatenate([r, Gn.ravel()]) / Lam[0, 0]
        P = np.linalg.solve(Lam, r)
        G = np.linalg.solve(Lam, Gn)
        return np.concatenate([P, G.ravel()])

    # -- reading the estimate ----------------------------------------------------
    def estimate(self, out, y):
        r"""xhat_r = P + G y from the observer's output ``out`` and the measurement y.

        Parameters
        ----------
        out : (m + m p,) or time-major (N, m + m p) array
            The observer's output (``arc.outputs(name)``).
        y : (p,) or (N, p) array
            The measured output at the same times.

        Returns
        -------
        (m,) or (N, m) array
        """
        out = np.asarray(out, dtype=float)
        y = np.asarray(y, dtype=float)
        m, p = self.m, self.p
        if out.shape[-1] != m + m * p:
            raise ValueError(f"out must have last dimension {m + m * p}, got shape {out.shape}")
        if y.shape[-1:] != (p,) or y.shape[:-1] != out.shape[:-1]:
            raise ValueError(f"y must have shape {out.shape[:-1] + (p,)}, got {y.shape}")
        P = out[..., :m]
        G = out[..., m:].reshape(out.shape[:-1] + (m, p))
        return P + np.einsum("...ij,...j->...i", G, y)


class TimeVaryingPlant(hs.HybridSystem):
    r"""The system (16) with the data of a :class:`ReducedOrderObserver`.

    State ``[z (p), x_r (m)]``,

        z'   = A1(t) x_r + delta1(t, z[, w]),
        x_r' = A2(t) x_r + delta2(t, z[, w]),      (16)

    input w (``observer.w_dim`` known signals, none when 0), output z (the
    noise-free measurement; :func:`observers.time_varying.simulate` adds
    eps of (17)).

    Parameters
    ----------
    observer : ReducedOrderObserver
        Whose A1, A2, delta1, delta2 define (16).

    Examples
    --------
    >>> import numpy as np
    >>> from observers.time_varying import ReducedOrderObserver, TimeVaryingPlant
    >>> obs = ReducedOrderObserver(1.0, [[1.0]], [[-1.0]], [[-2.0]],
    ...                            lambda t, s: np.exp(t - s) * np.eye(1),
    ...                            lambda t, s: np.exp(3 * (t - s)) * np.eye(1))
    >>> TimeVaryingPlant(obs).flow_map(np.array([1.0, 2.0]), 0.0, 0, None)
    array([ 2., -2.])
    """

    def __init__(self, observer):
        if not isinstance(observer, ReducedOrderObserver):
            raise TypeError("observer must be a ReducedOrderObserver, "
                            f"got {type(observer).__name__}")
        self.obs = observer
        self.p, self.m, self.w_dim = observer.p, observer.m, observer.w_dim
        self.state_dim = self.p + self.m
        self.input_dim = self.w_dim
        self.output_dim = self.p

    def flow_map(self, x, t, j, u):
        o, p = self.obs, self.p
        z, xr = x[:p], x[p:]
        w = np.zeros(0) if not self.w_dim else np.atleast_1d(np.asarray(u, dtype=float))
        d1 = np.asarray(o.delta1(t, z, w), dtype=float).reshape(p)
        d2 = np.asarray(o.delta2(t, z, w), dtype=float).reshape(self.m)
        return np.concatenate([o.A1(t) @ xr + d1, o.A2(t) @ xr + d2])

    def output(self, x, t, j):
        return np.array(x[: self.p], dtype=float)


def _plant16(observer):
    """The default :class:`PlantModel` of an observer: (16) with its own data."""
    p, n = observer.p, observer.p + observer.m
    return PlantModel(make=lambda: TimeVaryingPlant(observer), measure=lambda y: y,
                      x_r=lambda X: np.asarray(X)[:, p:],
                      initial_state=lambda x0: vector("x0", x0, n),
                      description="TimeVaryingPlant: (16) with the observer's A1, A2, delta1, "
                                  "delta2; x0 = [z(0), x_r(0)]")


def _expm_phi(Omega, tau):
    """Phi(t, s) = e^{-Omega (t - s)} of (1) for a constant Omega; the value at t - s = tau
    (what the observer's output reads at every sample) computed once."""
    at_tau = linalg.expm(-Omega * tau)

    def Phi(t, s):
        d = t - s
        if abs(d - tau) <= 4e-16 * max(abs(t), abs(s), tau):      # t - (t - tau), rounded
            return at_tau
        return linalg.expm(-Omega * d)
    return Phi


def lti_observer(A, C, *, tau=1.0, L=None, poles=None, delta=None, eps=None, N=None, xr_init=None):
    r"""The Section II observer (15) for xdot = A x + delta(t), y = C x (+ eps(t)).

    Parameters
    ----------
    A, C : arrays (n, n), (p, n)
    tau : float > 0
    L, poles : see :func:`choose_L_tau`
    delta : callable t -> (n,), optional
        The known input delta of (2).
    eps : callable t -> (p,), optional
        Known measurement disturbance (exact estimate); None: (27).
    N : (n-p, n) array, optional
        See :func:`reduced_coordinates`.
    xr_init : (n-p,) array, optional

    Returns
    -------
    observer : ReducedOrderObserver
        Input y (p), output [P, G] (see :meth:`ReducedOrderObserver.estimate`).
    coords : ReducedCoordinates
        x_r = coords.x_r(x); the full state is coords.x_from(y, xhat_r).

    References
    ----------
    [1] eqs. (2)-(15); Phi_Omega(t, s) = e^{-Omega (t - s)} for constant Omega.
    """
    rc = reduced_coordinates(A, C, N)
    A_lti = matrix("A", A, square=True)
    L, tau, _ = choose_L_tau(rc.A2, rc.A1, L=L, tau=tau, poles=poles)
    H = rc.A2 + L @ rc.A1
    obs = ReducedOrderObserver(
        tau, rc.A1, rc.A2, L, Phi_A2=_expm_phi(rc.A2, tau), Phi_H=_expm_phi(H, tau),
        delta1=rc.delta1(delta), delta2=rc.delta2(delta), eps=eps, xr_init=xr_init,
        # Lambda(t) = M_tau (6) is constant and choose_L_tau checked it invertible: no check of
        # Assumption 1 (two matrix exponentials) at every step of the flow
        check_Lambda=False)
    obs.plant_model = PlantModel(
        make=lambda: hs.LinearPlant(A_lti, C=rc.C, disturbance=delta),
        measure=lambda y: y, x_r=rc.x_r,
        initial_state=lambda x0: vector("x0", x0, A_lti.shape[0]),
        description="LinearPlant: xdot = A x + delta(t), y = C x (2)-(3)")
    return obs, rc


# ---------------------------------------------------------------------------
# Section IV on the engine
# ---------------------------------------------------------------------------
class ChainedFormPlant(hs.HybridSystem):
    r"""The closed-loop chained form (44) with input v2, as a hybrid system.

    State ``[xi4, xi3, xi2, x1, q]`` (x1 = xi1 - 2 sin t, eq. 42), input v2,
    output ``[xi4, xi3, x1]`` (xi4, xi3, xi1 are measured, xi2 is not).

    The flow is (44) with v1 of (43). x1' = -2 sign(x1) sqrt|x1| reaches 0 at
    t = sqrt|x1(0)| with zero slope and is not Lipschitz there; an integrator
    chatters around 0 and spoils the exactness that the observer relies on.
    We model the arrival as a jump: q = sign(x1) before arrival, D =
    {q != 0, q x1 <= eta}, g: x1 = 0, q = 0; with q = 0 the flow keeps
    x1 = 0 exactly, as the exact solution does. The jump comes sqrt(eta)
    before the true arrival, which changes xi3, xi4 by about eta |xi2|
    (the integral of 2 sqrt|x1| over that interval). eta must stay above the
    solver's atol: x1' = -2 sqrt(x1) has Jacobian -1/sqrt(x1), and below
    atol an explicit solver crawls (eta = 1e-12 with atol = 1e-12 takes
    6e4 steps to cross t in [0.5, 1]).

    Parameters
    ----------
    eta : float
        Arrival threshold (default 1e-10; use atol <= eta / 100).

    References
    ----------
    [1] eqs. (40)-(44).
    """

    state_dim = 5
    input_dim = 1
    output_dim = 3

    def __init__(self, eta=1e-10):
        if not (isinstance(eta, (int, float)) and 0 < eta < 1e-2):
            raise ValueError(f"eta must be a number in (0, 1e-2), got {eta!r}")
        self.eta = float(eta)

    @staticmethod
    def initial_state(xi4, xi3, xi2, x1):
        """x0 = [xi4, xi3, xi2, x1, sign(x1)]."""
        return np.array([xi4, xi3, xi2, x1, float(np.sign(x1))], dtype=float)

    @staticmethod
    def v1(t, x1):
        """The feedback (43) in the x1 coordinate: -2 sign(x1) sqrt|x1| + 2 cos t."""
        return -2 * np.sign(x1) * np.sqrt(abs(x1)) + 2 * np.cos(t)

    def flow_map(self, x, t, j, u):
        _xi4, xi3, xi2, x1, q = x
        v2 = float(np.asarray(u).ravel()[0])
        dx1 = -2 * np.sign(x1) * np.sqrt(abs(x1)) if q != 0 else 0.0
        v1 = dx1 + 2 * np.cos(t)
        return np.array([xi3 * v1, xi2 * v1, v2, dx1, 0.0])

    def jump_guard(self, x, t, j, u):
        return self.eta - x[4] * x[3] if x[4] != 0 else -1.0

    def jump_set(self, x, t, j, u):
        return bool(x[4] != 0 and x[4] * x[3] <= self.eta)

    def jump_map(self, x, t, j, u):
        xn = np.array(x, dtype=float)
        xn[3] = 0.0
        xn[4] = 0.0
        return xn

    def output(self, x, t, j):
        return np.array([x[0], x[1], x[3]])


def chained_form_observer(xr_init=0.0, z_history=None):
    r"""The observer of Section IV-B for (45): tau = 2 pi, L = -2 cos t, Lambda = 1 - e^{4 pi}.

    Input [xi3, v2] (w = v2, delta2 = v2, delta1 = 0), closed forms (48) for
    Phi_H and Phi_A2 = 1 (:func:`~observers.time_varying.example_data`); its
    plant model is :class:`ChainedFormPlant` (x0 = (xi4, xi3, xi2, x1)).

    Parameters
    ----------
    xr_init : float
        The estimate before the window is filled (t < 2 pi).
    z_history : callable s -> (1,), optional
        Where to read xi3(t - 2 pi) (see :class:`ReducedOrderObserver`).

    Returns
    -------
    ReducedOrderObserver

    Examples
    --------
    >>> obs = chained_form_observer()
    >>> round(float(obs.Lambda(1.0)[0, 0]), 2), obs.plant_model.description.split(":")[0]
    (-286750.31, 'ChainedFormPlant')

    References
    ----------
    [1] eqs. (45)-(50).
    """
    ex = example_data()
    obs = ReducedOrderObserver(ex["tau"], ex["A1"], ex["A2"], ex["L"], ex["Phi_A2"], ex["Phi_H"],
                               Ldot=ex["Ldot"], delta2=lambda t, z, w: w, p=1, m=1, w_dim=1,
                               xr_init=[xr_init], z_history=z_history)
    obs.plant_model = PlantModel(
        make=ChainedFormPlant, measure=lambda y: np.asarray(y)[1:2],
        x_r=lambda X: np.asarray(X)[:, 2:3],
        initial_state=lambda x0: ChainedFormPlant.initial_state(*vector("x0", x0, 4)),
        description="ChainedFormPlant: (44) with input v2; x0 = (xi4, xi3, xi2, x1)")
    return obs


def tracking_loop(xr_init=0.0, feedback="estimate"):
    r"""The output-feedback tracking loop (44) + (58) as an interconnection.

    Components ``"plant"`` (:class:`ChainedFormPlant`) and ``"observer"``
    (:func:`chained_form_observer`). The plant's input is

        v2(t) = (57) with xi2 replaced by xhat2(t) = P(t) + G(t) xi3(t),

    which is (58): v2(t) depends on the past of v2 only through the
    observer's states, so there is no algebraic loop (a distributed-delay
    equation, see :mod:`observers.time_varying.example`). Before 2 pi
    (window not filled) xhat2 = ``xr_init``. The observer reads
    xi3(t - 2 pi) from the plant's history.

    Parameters
    ----------
    xr_init : float
        Estimate used before t = 2 pi.
    feedback : {"estimate", "state"}
        "state" feeds back the true xi2 (the state feedback (57)), for
        comparison.

    Returns
    -------
    loop : hybridsim.Interconnection
    v2 : callable (t, y) -> float
        The control, from the interconnection's outputs dict y.

    Examples
    --------
    >>> loop, v2 = tracking_loop()
    >>> sorted(loop.systems), loop.state_dim            # plant (5) and observer (4)
    (['observer', 'plant'], 9)

    References
    ----------
    [1] eqs. (51)-(59).
    """
    if feedback not in ("estimate", "state"):
        raise ValueError(f"feedback must be 'estimate' or 'state', got {feedback!r}")
    plant = ChainedFormPlant()
    obs = chained_form_observer(xr_init, z_history=lambda s: np.array([plant.history(s)[1]]))
    if feedback == "state":
        plant.output_dim = 4
        plant.output = lambda x, t, j: np.array([x[0], x[1], x[3], x[2]])

    def v2(t, y):
        yp = y["plant"]
        if feedback == "state":
            xi2h = yp[3]
        else:
            out = y["observer"]                     # [P, G]: xhat2 = P + G xi3 (m = p = 1)
            xi2h = out[0] + out[1] * yp[1]
        return float(v2_feedback(t, xi2h, yp[1], yp[0]))

    loop = hs.Interconnection({"plant": plant, "observer": obs},
                              inputs={"plant": lambda t, y: np.array([v2(t, y)]),
                                      "observer": lambda t, y: np.array([y["plant"][1], v2(t, y)])})
    return loop, v2


# ---------------------------------------------------------------------------
# populations: the example's estimate over many runs at once (falsification)
# ---------------------------------------------------------------------------
class ChainedFormEstimates(hs.HybridSystem):
    r"""The chained form (44) in open loop and the estimate (50)/(27) on a grid, vectorized.

    A population run for :mod:`observers.time_varying.falsification`: every
    uncertain quantity (the initial state, the input v2, the measurement
    noise eps of (17)) lives in the state, the maps are written over batches
    (``vectorized = True``; a single state ``x[..., k]`` works as well), and
    no map reads the run's history, so :func:`hybridsim.simulate_many`
    integrates a whole population in numpy.

    The window integrals of (49)/(50) are separable: with
    g(m) = e^{2 (m - 2 pi) + sin 2m}, Phi_H(m, s) = e^{M(m, t)} = g(m) / g(s)
    (48), so each integral over [s, t] = [t - 2 pi, t] is K(t) - K(s) of a
    running integral K. The state carries V = int_0 v2, K_v = int_0 g v2,
    K_y = int_0 g (4 cos^3 - sin) y (y = xi3 + eps, the measurement (17)),
    and at the latch times s_k = t_k - 2 pi a jump copies (y, V, K_v, K_y)
    into slot k; at t_k a jump evaluates::

        xhat2(t_k) = [2 cos t_k (-e^{4 pi} y(t_k) + y(s_k)) + (V(t_k) - V(s_k))
                      - (K_v(t_k) - K_v(s_k)) / g(s_k)
                      + 2 (K_y(t_k) - K_y(s_k)) / g(s_k)] / (1 - e^{4 pi}),

    which is (49) (with eps = 0, (50)) or the approximate observer (27)
    (with eps), and stores ``e = xhat2(t_k) - xi2(t_k)`` (the state's ``e``,
    held until the next evaluation). The grid is t_k = t_start + k h,
    k = 0..points-1, with t_start = max{2 pi, sqrt|x1(0)|} (``start=
    "printed"``, the range of (50) as printed) or 2 pi + sqrt|x1(0)|
    (``"corrected"``, the range this project finds, ERRATA).

    x1 follows its closed form sqrt|x1(t)| = max(sqrt|x1(0)| - t, 0)
    (Section IV-A), so v1 (43) = -2 sign(x1(0)) max(sqrt|x1(0)| - t, 0) +
    2 cos t needs no arrival jump (:class:`ChainedFormPlant` models it as a
    jump instead).

    State (time-major rows): ``[xi4, xi3, xi2, r0, V, K_v, K_y, c, e,
    latches (5 points), v2 coefficients (3 v2_terms), noise coefficients]``
    with r0 = sign(x1(0)) sqrt|x1(0)| and c the number of events so far
    (2 points in all: points latches, then points evaluations).

    Parameters
    ----------
    start : {"printed", "corrected"}
        Where the grid starts (see above).
    points : int
        Evaluation times per run.
    spacing : float
        h > 0, between evaluation times.
    v2_terms : int
        v2(t) = (v2_bound / v2_terms) sum_i a_i sin(2 pi f_i t + phi_i)
        (the parametrisation of :class:`hybridsim.falsification.Sinusoids`),
        so |v2| <= v2_bound as Section IV-A requires.
    v2_bound : float
    noise : {None, "sinusoids", "pieces"}
        eps of (17): none (the exact (50)), a :class:`Sinusoids` signal
        (``noise_terms`` terms) or a :class:`PiecewiseConstant` one
        (``noise_terms`` pieces of width ``noise_width``), |eps| <=
        ``noise_bound``.
    noise_terms : int
    noise_bound : float
    noise_width : float
        Piece width (``noise="pieces"``).

    Examples
    --------
    >>> import numpy as np
    >>> import hybridsim as hs
    >>> sys = ChainedFormEstimates("corrected", points=3, spacing=0.2)
    >>> x0 = sys.initial_state([1.0, -1.0, 0.5, 0.25], v2=[1.0, 0.3, 0.0])
    >>> arcs = hs.simulate_many(sys, [x0], sys.t_max(0.5), rtol=1e-10, atol=1e-12,
    ...                         progress=False)
    >>> bool(np.abs(sys.evaluated_errors(arcs[0])).max() < 1e-8)   # (50) from 2 pi + 0.5
    True

    References
    ----------
    [1] eqs. (17), (27), (43)-(50).
    """

    vectorized = True
    E4 = float(np.exp(4 * np.pi))

    def __init__(self, start="corrected", *, points=8, spacing=0.15, v2_terms=1, v2_bound=1.0,
                 noise=None, noise_terms=1, noise_bound=0.0, noise_width=1.0):
        if start not in ("printed", "corrected"):
            raise ValueError(f"start must be 'printed' or 'corrected', got {start!r}")
        if noise not in (None, "sinusoids", "pieces"):
            raise ValueError(f"noise must be None, 'sinusoids' or 'pieces', got {noise!r}")
        for nm, v in (("points", points), ("v2_terms", v2_terms), ("noise_terms", noise_terms)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"{nm} must be an int >= 1, got {v!r}")
        self.start = start
        self.points, self.v2_terms = int(points), int(v2_terms)
        self.spacing = scalar("spacing", spacing, positive=True)
        self.v2_bound = scalar("v2_bound", v2_bound, nonneg=True)
        self.noise = noise
        self.noise_terms = int(noise_terms)
        self.noise_bound = scalar("noise_bound", noise_bound, nonneg=True)
        self.noise_width = scalar("noise_width", noise_width, positive=True)
        self._latch = 9
        self._v2 = self._latch + 5 * self.points
        self._eps = self._v2 + 3 * self.v2_terms
        n_eps = {None: 0, "sinusoids": 3 * self.noise_terms, "pieces": self.noise_terms}[noise]
        self.state_dim = self._eps + n_eps

    # -- data ------------------------------------------------------------------
    def initial_state(self, x0, v2=(), noise=()):
        """One row of the state: x0 = (xi4, xi3, xi2, x1) at t = 0, the
        coefficients of v2 (a (terms), f (terms, Hz), phi (terms), the order
        of :class:`~hybridsim.falsification.Sinusoids`) and of the noise
        (Sinusoids' coefficients, or the pieces' values)."""
        xi4, xi3, xi2, x1 = vector("x0", x0, 4)
        v2 = np.asarray(v2, dtype=float).ravel()
        noise = np.asarray(noise, dtype=float).ravel()
        nv, ne = self._eps - self._v2, self.state_dim - self._eps
        if v2.size != nv or noise.size != ne:
            raise ValueError(f"v2 must have {nv} coefficients and noise {ne}, "
                             f"got {v2.size} and {noise.size}")
        head = [xi4, xi3, xi2, np.sign(x1) * np.sqrt(abs(x1)), 0.0, 0.0, 0.0, 0.0, 0.0]
        return np.concatenate([head, np.zeros(5 * self.points), v2, noise])

    def t_start(self, s0):
        """First evaluation time for sqrt|x1(0)| = s0."""
        s0 = np.asarray(s0, dtype=float)
        return np.maximum(TAU_EXAMPLE, s0) if self.start == "printed" else TAU_EXAMPLE + s0

    def t_max(self, s0_max):
        """A horizon just past the last evaluation time of every run with sqrt|x1(0)| <= s0_max."""
        return float(self.t_start(s0_max)) + (self.points - 1) * self.spacing + 1e-3

    def v2(self, x, t):
        """v2(t) of each row (|v2| <= v2_bound)."""
        k = self.v2_terms
        c = x[..., self._v2:self._eps]
        a, f, ph = c[..., :k], c[..., k:2 * k], c[..., 2 * k:]
        tt = np.asarray(t, dtype=float)[..., None]
        return self.v2_bound / k * np.sum(a * np.sin(2 * np.pi * f * tt + ph), axis=-1)

    def eps(self, x, t):
        """The measurement noise eps(t) of (17) of each row (|eps| <= noise_bound)."""
        t = np.asarray(t, dtype=float)
        if self.noise is None:
            return np.zeros(np.broadcast_shapes(x.shape[:-1], t.shape))
        c = x[..., self._eps:]
        k = self.noise_terms
        if self.noise == "sinusoids":
            a, f, ph = c[..., :k], c[..., k:2 * k], c[..., 2 * k:]
            return self.noise_bound / k * np.sum(
                a * np.sin(2 * np.pi * f * t[..., None] + ph), axis=-1)
        i = np.clip(np.floor(t / self.noise_width), 0, k - 1).astype(int)
        i = np.broadcast_to(i, x.shape[:-1])
        return np.take_along_axis(c, i[..., None], axis=-1)[..., 0]

    @staticmethod
    def _g(m):
        return np.exp(2 * (m - TAU_EXAMPLE) + np.sin(2 * m))

    def _next(self, x):
        c = x[..., 7]
        s0 = np.abs(x[..., 3])
        t0 = self.t_start(s0)
        k = np.where(c < self.points, c, c - self.points)
        return np.where(c < self.points, t0 - TAU_EXAMPLE, t0) + k * self.spacing

    # -- (C, f, D, g) ----------------------------------------------------------
    def flow_map(self, x, t):
        t = np.broadcast_to(np.asarray(t, dtype=float), x.shape[:-1])
        xi3, xi2, r0 = x[..., 1], x[..., 2], x[..., 3]
        v1 = -2 * np.sign(r0) * np.maximum(np.abs(r0) - t, 0.0) + 2 * np.cos(t)
        v2 = self.v2(x, t)
        y = xi3 + self.eps(x, t)
        g = self._g(t)
        dx = np.zeros_like(x)
        dx[..., 0] = xi3 * v1
        dx[..., 1] = xi2 * v1
        dx[..., 2] = v2
        dx[..., 4] = v2
        dx[..., 5] = g * v2
        dx[..., 6] = g * (4 * np.cos(t) ** 3 - np.sin(t)) * y
        return dx

    def jump_guard(self, x, t):
        t = np.broadcast_to(np.asarray(t, dtype=float), x.shape[:-1])
        return np.where(x[..., 7] < 2 * self.points, t - self._next(x), -1.0)

    def jump_set(self, x, t):
        return self.jump_guard(x, t) >= 0

    def jump_map(self, x, t):
        X = np.atleast_2d(np.asarray(x, dtype=float))
        T = np.broadcast_to(np.asarray(t, dtype=float), X.shape[:-1])
        XN = X.copy()
        c = X[:, 7].astype(int)
        now = np.stack([X[:, 1] + self.eps(X, T), X[:, 4], X[:, 5], X[:, 6]], axis=-1)
        latch = c < self.points
        r = np.flatnonzero(latch)                    # store (s, y, V, K_v, K_y) at s_k
        cols = self._latch + 5 * c[r, None] + np.arange(5)
        XN[r[:, None], cols] = np.column_stack([T[r], now[r]])
        r = np.flatnonzero(~latch)                   # evaluate (49)/(27) at t_k
        k = c[r] - self.points
        s, ys, Vs, Kvs, Kys = X[r[:, None], self._latch + 5 * k[:, None] + np.arange(5)].T
        gs, tr, nw = self._g(s), T[r], now[r]
        ph = self._g(tr) / gs                        # Phi_H(t, s) (48), e^{4 pi} when t - s = 2 pi
        xh = ((nw[:, 1] - Vs) - (nw[:, 2] - Kvs) / gs + 2 * (nw[:, 3] - Kys) / gs
              - 2 * np.cos(tr) * ph * nw[:, 0] + 2 * np.cos(s) * ys) / (1 - ph)
        XN[r, 8] = xh - X[r, 2]
        XN[:, 7] = c + 1
        return XN.reshape(np.shape(x))

    # -- reading a run ---------------------------------------------------------
    def evaluated_errors(self, arc):
        """The errors xhat2(t_k) - xi2(t_k) of a run, one per evaluation done, in order."""
        idx = self.evaluation_samples(arc)
        return arc.x[idx, 8]

    def evaluation_samples(self, arc):
        """Indices of the samples right after each evaluation jump (``e`` set there)."""
        c = arc.x[:, 7]
        first = np.flatnonzero((c > self.points) & np.r_[True, np.diff(c) > 0])
        return first

