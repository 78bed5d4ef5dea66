r"""The hybrid systems of paper 000: observer (6)-(8) and the plant (1) of Section VI.

=================================  =============================================
:class:`DynamicGainObserver`       observer (6)-(8) with z of (7), settled mode
:func:`proposed_observer`          gamma2 > 0, z = max{v, gamma2 |w|} (7)
:func:`prescribed_time_observer`   gamma2 = 0, z = v (Holloway-Krstic, ref. [10])
:func:`homogeneous_observer`       z = |w| (Perruquetti et al., ref. [17])
:func:`luenberger_observer`        gamma1 = gamma2 = 0, z = v(0) (Remark 1)
:func:`example_plant`              plant (1) of Section VI in closed loop
:func:`uniform_noise`              Section VI's omega in (-1, 1), seeded
:class:`NoisyExamplePlant`         plant (1) under scaled disturbances, batched
:class:`ConsistentEuler`           the Euler scheme of ref. [8] (jump per step)
:class:`AuxiliarySystem`           (13) with the clock (16): (9) in the time tau, batched
:class:`BoxDisturbedPlant`         plant (1) under piecewise-constant |d_i| <= a, batched
=================================  =============================================

Examples
--------
>>> from observers.dynamic_gain.systems import proposed_observer
>>> from observers.lmi import PAPER_L
>>> obs = proposed_observer(PAPER_L, 0.2, 1.0, 1.0, b=[[0.0], [0.0], [1.0]])
>>> obs.state_dim, obs.input_dim          # (w, x_hat_1..3, v, q); (y, u)
(6, 2)
"""
from __future__ import annotations

import numpy as np

import hybridsim as hs
from hybridsim.system import as_map
from observers._common import matrix, scalar, vector

from .design import check_gains, check_mu, rbar

__all__ = ["DynamicGainObserver", "proposed_observer", "prescribed_time_observer",
           "homogeneous_observer", "luenberger_observer", "uniform_noise", "example_plant",
           "NoisyExamplePlant", "ConsistentEuler", "AuxiliarySystem", "BoxDisturbedPlant"]


class DynamicGainObserver(hs.HybridSystem):
    r"""Observer (6)-(8) and its prescribed-time / homogeneous / Luenberger variants.

    State ``x = (w, x_hat_1, ..., x_hat_n, v, q)`` (length n+3); input
    ``u = (y, u_1, ..., u_m)`` (the measured output, then the known control);
    output: the whole state.  Flow set: everything; jump set
    ``{q = 0, v <= z_min}`` (decision 1 of :data:`observers.dynamic_gain.DECISIONS`)::

        w'       = y - x_hat_1 + z^{-rbar_0} L_0 w                       (6)
        x_hat_i' = x_hat_{i+1} + b_i u - z^{-rbar_i} L_i w               (6)
        z        = max{v, gamma2 |w|}                                    (7)
        v'       = gamma2 |w'| - gamma1 ceil(v - gamma2 |w|)^{1 - mu}    (8)

    Parameters
    ----------
    L : (n+1,) array_like
        Gains ``(L_0, ..., L_n)``, all < 0 (e.g. from :func:`observers.lmi.solve_lmi10`).
    mu : float
        ``0 < mu <= 1/(n+1)`` (Section IV).
    gamma1 : float
        >= 0 (0 only for Remark 1's constant gain).
    gamma2 : float, default 1
        >= 0.  0 gives the prescribed-time observer when ``z_mode="max"``.
    z_mode : {"max", "abs"}
        ``"max"``: z = max{v, gamma2|w|} (7); ``"abs"``: z = |w| (homogeneous).
    b : (n, m) array_like, optional
        Input matrix rows b_i of (1); None means no control input (m = 0).
    z_min : float, default 1e-12
        Floor of the gain z and the v at which the observer switches to the settled
        mode (decision 1).

    Raises
    ------
    TypeError, ValueError
        A parameter of the wrong type or value, naming it.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.lmi import PAPER_L
    >>> obs = DynamicGainObserver(PAPER_L, 0.2, 1.0, 1.0, b=np.eye(3)[:, -1:])
    >>> obs.initial_state().tolist()            # Section VI: w(0) = x_hat(0) = 0, v(0) = 1
    [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    >>> float(obs.z(w=0.5, v=0.1))              # (7): max{v, gamma2 |w|}
    0.5

    References
    ----------
    Nekhoroshikh et al., CDC 2022, eqs. (6), (7), (8), Remark 1, Section VI.
    """

    def __init__(self, L, mu, gamma1, gamma2=1.0, *, z_mode="max", b=None, z_min=1e-12):
        self.L = check_gains(L)
        n = self.n = self.L.size - 1
        self.mu = check_mu(mu, n, strict=False)
        self.gamma1 = scalar("gamma1", gamma1, nonneg=True)
        self.gamma2 = scalar("gamma2", gamma2, nonneg=True)
        if z_mode not in ("max", "abs"):
            raise ValueError(f"z_mode must be 'max' or 'abs', got {z_mode!r}")
        self.z_mode = z_mode
        if b is None:
            b = np.zeros((n, 0))
        shape = np.shape(b)
        if len(shape) not in (1, 2) or shape[0] != n:
            raise ValueError(f"b must be a finite ({n}, m) matrix, got shape {shape}")
        b = matrix("b", b, shape=(n, 1) if len(shape) == 1 else (n, None))
        self.b = b
        self.m = b.shape[1]
        self.z_min = scalar("z_min", z_min, positive=True)
        self.rbar = rbar(n, self.mu)
        self.state_dim = n + 3
        self.input_dim = 1 + self.m
        self.vectorized = True          # flow_map, jump_guard, jump_map take batches too

    # -- pieces -------------------------------------------------------------
    def z(self, w, v, q=0.0):
        """The dynamic gain z of (7) (|w| for the homogeneous observer), floored at z_min.

        Elementwise over arrays ``w``, ``v``, ``q`` of one shape.
        """
        if self.z_mode == "abs":
            z = np.abs(w)
        else:
            z = np.maximum(np.where(np.asarray(q) >= 0.5, 0.0, v), self.gamma2 * np.abs(w))  # (7)
        return np.maximum(z, self.z_min)

    def injection(self, w, v, q):
        """``z^{-rbar_i} w`` for i = 0..n (with the floor of decision 1), on a new last axis."""
        w = np.asarray(w, dtype=float)
        return self.z(w, v, q)[..., None] ** (-self.rbar) * w[..., None]

    def flow_map(self, x, t, j, u):
        """(6) and (8); v held at its limit 0 in the settled mode (q = 1).

        On the last axis: ``x`` (n+3,) or a batch (N, n+3) with ``u`` (1+m,)
        or (N, 1+m).
        """
        n, L = self.n, self.L
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        w, xh, v, q = x[..., 0], x[..., 1:n + 1], x[..., n + 1], x[..., n + 2]
        k = self.injection(w, v, q)
        dx = np.empty(x.shape)
        dw = u[..., 0] - xh[..., 0] + L[0] * k[..., 0]                          # (6), w
        dx[..., 0] = dw
        dx[..., 1:n] = xh[..., 1:]                                              # (6), x_hat
        dx[..., n] = 0.0
        if self.m:
            dx[..., 1:n + 1] += u[..., 1:] @ self.b.T
        dx[..., 1:n + 1] -= L[1:] * k[..., 1:]
        s = v - self.gamma2 * np.abs(w)                                         # (8)
        dv = self.gamma2 * np.abs(dw) - self.gamma1 * np.sign(s) * np.abs(s) ** (1 - self.mu)
        dx[..., n + 1] = np.where(q >= 0.5, 0.0, dv)
        dx[..., n + 2] = 0.0
        return dx

    def jump_guard(self, x, t, j, u):
        """Jump when v reaches z_min with q = 0 (decision 1); last axis of length 2."""
        n = self.n
        g = np.empty(np.shape(x)[:-1] + (2,))
        g[..., 0] = self.z_min - x[..., n + 1]
        g[..., 1] = 0.5 - x[..., n + 2]
        return g

    def jump_map(self, x, t, j, u):
        """Settle: v -> 0, q -> 1 (z stays continuous); row by row over a batch."""
        xp = np.array(x, dtype=float)
        xp[..., self.n + 1] = 0.0
        xp[..., self.n + 2] = 1.0
        return xp

    def initial_state(self, x_hat0=None, w0=0.0, v0=1.0):
        """``(w0, x_hat0, v0, q=0)``; Section VI uses w0 = 0, x_hat0 = 0, v0 = 1."""
        x_hat0 = np.zeros(self.n) if x_hat0 is None else vector("x_hat0", x_hat0, self.n)
        w0 = scalar("w0", w0)
        v0 = scalar("v0", v0)
        if not v0 > self.z_min:
            raise ValueError(f"v0 must be > z_min = {self.z_min:g}, got {v0}")
        return np.concatenate([[w0], x_hat0, [v0, 0.0]])


def proposed_observer(L, mu, gamma1, gamma2=1.0, **kw):
    """The proposed observer (6)-(8), z = max{v, gamma2|w|} (7), gamma2 > 0.

    Examples
    --------
    >>> from observers.lmi import PAPER_L
    >>> proposed_observer(PAPER_L, 0.2, 1.0, 0.0)
    Traceback (most recent call last):
    ...
    ValueError: gamma2 must be > 0, got 0.0
    """
    scalar("gamma2", gamma2, positive=True)   # gamma2 = 0 is the prescribed-time observer
    return DynamicGainObserver(L, mu, gamma1, gamma2, z_mode="max", **kw)


def prescribed_time_observer(L, mu, gamma1, **kw):
    """Prescribed-time counterpart (Holloway-Krstic): gamma2 = 0, z = v (Section VI).

    Settles exactly at T of (18).

    Examples
    --------
    >>> from observers.lmi import PAPER_L
    >>> prescribed_time_observer(PAPER_L, 0.2, 1.0).gamma2
    0.0
    """
    return DynamicGainObserver(L, mu, gamma1, 0.0, z_mode="max", **kw)


def homogeneous_observer(L, mu, gamma1, **kw):
    """Homogeneous observer (Perruquetti et al.): z = |w|, filter (8) with gamma2 = 0.

    Examples
    --------
    >>> from observers.lmi import PAPER_L
    >>> homogeneous_observer(PAPER_L, 0.2, 1.0).z_mode
    'abs'
    """
    return DynamicGainObserver(L, mu, gamma1, 0.0, z_mode="abs", **kw)


def luenberger_observer(L, mu, **kw):
    """Remark 1: gamma1 = gamma2 = 0, so z = v(0) constant (Luenberger for v(0) = 1,
    high-gain for small v(0)); the gains are ``v(0)^{-rbar_i} L_i``.

    Examples
    --------
    >>> from observers.lmi import PAPER_L
    >>> o = luenberger_observer(PAPER_L, 0.2)
    >>> o.gamma1, o.gamma2
    (0.0, 0.0)
    """
    return DynamicGainObserver(L, mu, 0.0, 0.0, z_mode="max", **kw)


# ---------------------------------------------------------------------------
# the plant (1) of Section VI
# ---------------------------------------------------------------------------
def uniform_noise(seed, t_max, dt=0.01, dim=1):
    """Seeded uniform noise in (-1, 1), drawn every ``dt`` and linearly interpolated.

    Section VI draws omega at each Euler step; decision 6 of
    :data:`observers.dynamic_gain.DECISIONS` explains the interpolation.

    Parameters
    ----------
    seed : int or numpy.random.Generator
    t_max, dt : float
        Horizon and spacing of the draws (> 0).
    dim : int
        Number of independent signals.

    Returns
    -------
    callable
        ``omega(t) -> (dim,) ndarray``.

    Examples
    --------
    >>> om = uniform_noise(3, 1.0, dim=2)
    >>> om(0.37).shape, bool(abs(om(0.37)).max() < 1)
    ((2,), True)
    """
    t_max = scalar("t_max", t_max, positive=True)
    dt = scalar("dt", dt, positive=True)
    rng = np.random.default_rng(seed)
    grid = np.arange(0.0, t_max + 2 * dt, dt)
    vals = rng.uniform(-1.0, 1.0, size=(grid.size, dim))

    last = grid.size - 2

    def omega(t):
        s = min(max(float(t), 0.0) / dt, float(last) + 1.0)
        k = min(int(s), last)
        f = s - k
        return (1.0 - f) * vals[k] + f * vals[k + 1]
    return omega


def example_plant(*, noise=False, seed=0, t_max=10.0, n=3, K=None):
    """Plant (1) of Section VI in closed loop, ``u = Kx + cos(10 t)``.

    A LinearPlant with ``x' = (A + bK) x + b cos(10t) + d_x(t)`` and output
    ``(y, u) = (x_1 + d_y(t), Kx + cos(10 t))``: exactly the observer's input.

    Parameters
    ----------
    noise : bool
        Add ``d_x = 0.1 [sin 2t, omega_x, 1 + cos t]``, ``d_y = 0.1 omega_y``
        (Section VI; omega from :func:`uniform_noise` with ``seed``).  For n != 3 the
        pattern is extended with omega_x in the middle components.
    seed : int or numpy.random.Generator
        Seed of the noise.
    t_max : float
        Horizon of the noise.
    n : int
        Order of the chain; b = e_n.
    K : (n,) array_like, optional
        Defaults to the coefficients making the closed loop ``(s+1)(s+2)...(s+n)``
        (K = -[6, 11, 6] for n = 3).

    Returns
    -------
    hybridsim.LinearPlant

    Examples
    --------
    >>> plant = example_plant()
    >>> plant.A.tolist()
    [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-6.0, -11.0, -6.0]]
    """
    if n < 2:
        raise ValueError(f"n must be >= 2 for the example plant, got {n}")
    if K is None:
        K = -np.poly(-np.arange(1.0, n + 1))[1:][::-1]
    K = np.asarray(K, dtype=float)
    if K.shape != (n,):
        raise ValueError(f"K must have shape ({n},), got {K.shape}")
    K = vector("K", K, n)
    A = np.eye(n, k=1)
    b = np.zeros(n)
    b[-1] = 1.0
    Ccl = np.vstack([np.eye(1, n), K[None, :]])
    if noise:
        om = uniform_noise(seed, t_max, dim=2)

        def dist(t):
            d = np.empty(n)
            d[0] = 0.1 * np.sin(2 * t)
            d[1:-1] = 0.1 * om(t)[0]
            d[-1] = 0.1 * (1.0 + np.cos(t)) + np.cos(10 * t)      # d_x,n + b_n cos 10t
            return d

        def meas(t):
            return np.array([0.1 * om(t)[1], np.cos(10 * t)])
    else:
        def dist(t):
            return b * np.cos(10 * t)

        def meas(t):
            return np.array([0.0, np.cos(10 * t)])
    return hs.LinearPlant(A + np.outer(b, K), C=Ccl, disturbance=dist, noise=meas)


class NoisyExamplePlant(hs.HybridSystem):
    r"""Plant (1) of Section VI under its disturbances, scaled, for a batch of runs.

    The closed loop of :func:`example_plant` (``u = Kx + cos 10t``, b = e_n)
    with Section VI's disturbances multiplied by an amplitude ``a / 0.1``:
    ``d_x = a [sin 2t, omega_x, 1 + cos t]``, ``d_y = a omega_y`` (a = 0.1 is
    Section VI). State ``(x_1..x_n, a, s)``: the amplitude a and the index s
    of the noise realisation (``seeds[s]``, drawn as :func:`uniform_noise`)
    are constant states, so that one vectorized batch
    (:func:`hybridsim.simulate_many`) runs every (amplitude, seed) pair at
    once. Output ``(y, u) = (x_1 + a omega_y, Kx + cos 10t)``, the observer's
    input. For a = 0.1 and ``seeds[s] = seed`` the run is that of
    ``example_plant(noise=True, seed=seed)``.

    Parameters
    ----------
    seeds : sequence of int
        One noise realisation per seed.
    t_max : float
        Horizon of the noise.
    n : int
        Order of the chain (>= 2).
    K : (n,) array_like, optional
        As in :func:`example_plant`.

    Examples
    --------
    >>> import numpy as np
    >>> plant = NoisyExamplePlant([0, 1], 1.0)
    >>> x = np.array([[1.0, 0.0, 0.0, 0.1, 0.0], [1.0, 0.0, 0.0, 0.0, 1.0]])
    >>> plant.output(x, np.zeros(2), np.zeros(2))[1].tolist()    # a = 0: y = x_1
    [1.0, -5.0]

    References
    ----------
    Nekhoroshikh et al., CDC 2022, (1), (19) and Section VI (Proposition 5).
    """

    vectorized = True

    def __init__(self, seeds, t_max, n=3, K=None, dt=0.01):
        ref = example_plant(n=n, K=K)
        self.n = n
        self.Acl = ref.A
        self.K = ref.C[1]
        self.seeds = [int(s) for s in seeds]
        if not self.seeds:
            raise ValueError("seeds must name at least one noise realisation")
        self.dt = scalar("dt", dt, positive=True)
        t_max = scalar("t_max", t_max, positive=True)
        grid = np.arange(0.0, t_max + 2 * self.dt, self.dt)
        # the draws of uniform_noise(seed, t_max, dt, dim=2), one table per seed
        self.table = np.stack([np.random.default_rng(s).uniform(-1.0, 1.0, size=(grid.size, 2))
                               for s in self.seeds])
        self.last = grid.size - 2
        self._memo = None
        self.state_dim = n + 2
        self.output_dim = 2

    def omega(self, s, t):
        """omega of realisation(s) ``s`` at time(s) ``t``: (N, 2) (as :func:`uniform_noise`).

        The last call is remembered: a flow evaluation asks for the output
        and the flow at the same (s, t).
        """
        t = np.asarray(t, dtype=float)
        s = np.asarray(s, dtype=float)
        memo = self._memo
        if memo is not None and memo[0].shape == t.shape and np.array_equal(memo[0], t) \
                and np.array_equal(memo[1], s):
            return memo[2]
        c = np.minimum(np.maximum(t, 0.0) / self.dt, float(self.last) + 1.0)
        k = np.minimum(c.astype(int), self.last)
        f = (c - k)[..., None]
        i = s.astype(int)
        om = (1.0 - f) * self.table[i, k] + f * self.table[i, k + 1]
        self._memo = (t.copy(), s.copy(), om)
        return om

    def flow_map(self, x, t, j, u):
        """``x' = (A + bK) x + b cos 10t + d_x(t)``; a and s constant (on the last axis)."""
        x = np.asarray(x, dtype=float)
        t = np.asarray(t, dtype=float)
        n = self.n
        a = x[..., n]
        om = self.omega(x[..., n + 1], t)
        dx = np.zeros(x.shape)
        dx[..., :n] = x[..., :n] @ self.Acl.T
        dx[..., 0] += a * np.sin(2 * t)
        dx[..., 1:n - 1] += (a * om[..., 0])[..., None]
        dx[..., n - 1] += a * (1.0 + np.cos(t)) + np.cos(10 * t)
        return dx

    def output(self, x, t, j):
        """``(y, u) = (x_1 + a omega_y, Kx + cos 10t)`` (on the last axis)."""
        x = np.asarray(x, dtype=float)
        t = np.asarray(t, dtype=float)
        n = self.n
        om = self.omega(x[..., n + 1], t)
        y = np.empty(x.shape[:-1] + (2,))
        y[..., 0] = x[..., 0] + x[..., n] * om[..., 1]
        y[..., 1] = x[..., :n] @ self.K + np.cos(10 * t)
        return y


class ConsistentEuler(hs.HybridSystem):
    r"""The explicit Euler scheme with state-dependent step of [8], as a hybrid system.

    Discretises the flow of ``system`` (an interconnection without input):
    the state is held constant over each step, a timer tau counts the step
    out, and at tau = h a jump takes the Euler step and draws the next step
    size::

        flow (tau < h):   x' = 0,  tau' = 1,  h' = 0
        jump (tau >= h):  x+ = x + h f(x, t - h),  tau+ = 0,
                          h+ = max{dt0 min{1, ||x+||}^mu, h_min}

    For a system r-homogeneous of degree ``-mu`` (the error system (9)) this
    step is the uniform step of the time-rescaled, degree-0 system, so the
    discretisation keeps finite-time convergence. ``h_min`` (default 1e-5)
    keeps the scheme from stalling once the error is at rounding level (the
    paper stops at N_max = 1e6 iterations instead). Jumps of ``system``
    itself (the observer's settled switch) are taken where the Euler step
    lands in its jump set, at the end of that step. State: ``system``'s,
    then ``(tau, h)``; components: ``system``'s and ``"scheme"``.

    Parameters
    ----------
    system : hybridsim.HybridSystem
        Without input (``input_dim`` 0), e.g. ``hs.connect(plant, observer)``.
    norm : callable
        ``norm(x) -> float`` on ``system``'s state (:func:`example_norm`).
    mu : float
    dt0, h_min : float
        Basic step (Section VI: 1e-2) and floor of the step.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> decay = hs.HybridSystem.from_functions(flow_map=lambda x: -x, state_dim=1)
    >>> euler = ConsistentEuler(decay, lambda x: abs(x[0]), 0.5, dt0=0.1)
    >>> arc = hs.simulate(euler, euler.initial_state([1.0]), t_max=0.25)
    >>> arc.jump_times.round(12).tolist(), round(float(arc.xf[0]), 12)    # 1 - 0.1, 0.9 - 0.09...
    ([0.1, 0.2], 0.81)

    References
    ----------
    [8] Efimov, Polyakov, Aleksandrov, Automatica 109, 2019; Section VI of [1].
    """

    def __init__(self, system, norm, mu, dt0=1e-2, h_min=1e-5):
        if not isinstance(system, hs.HybridSystem):
            raise TypeError(f"system must be a hybridsim.HybridSystem, got "
                            f"{type(system).__name__}")
        if int(system.input_dim or 0) > 0:
            raise ValueError("system must have no input (connect its input first)")
        if not callable(norm):
            raise TypeError(f"norm must be callable, got {type(norm).__name__}")
        self.system, self.norm = system, norm
        self.mu = scalar("mu", mu, positive=True)
        self.dt0 = scalar("dt0", dt0, positive=True)
        self.h_min = scalar("h_min", h_min, positive=True)
        n = self.n = int(system.state_dim)
        self.state_dim = n + 2
        self.components = {**(system.components or {}), "scheme": slice(n, n + 2)}
        # the system's maps as callables of (x, t, j, u), whatever their signature
        self._f = as_map(system.flow_map, "flow_map")
        self._g = as_map(system.jump_map, "jump_map")
        self._inD = as_map(system.jump_set, "jump_set") if system.has_jumps else None

    def step(self, x):
        """The step ``max{dt0 min{1, ||x||}^mu, h_min}`` of [8] from state x."""
        return max(self.dt0 * min(1.0, float(self.norm(x))) ** self.mu, self.h_min)

    def initial_state(self, x0):
        """``(x0, tau = 0, h = step(x0))``."""
        x0 = vector("x0", x0, self.n)
        return np.concatenate([x0, [0.0, self.step(x0)]])

    def flow_map(self, x, t, j, u):
        dx = np.zeros(self.state_dim)
        dx[self.n] = 1.0
        return dx

    def jump_guard(self, x, t, j, u):
        return x[self.n] - x[self.n + 1]

    def jump_set(self, x, t, j, u):
        n = self.n
        return bool(x[n] >= x[n + 1] or (self._inD is not None
                                          and self._inD(x[:n], t, j, None)))

    def jump_map(self, x, t, j, u):
        n = self.n
        y = x[:n]
        if self._inD is not None and self._inD(y, t, j, None):
            y = np.asarray(self._g(y, t, j, None), dtype=float)
            return np.concatenate([y, [x[n], self.step(y)]])
        h = x[n + 1]
        y = y + h * self._f(y, t - h, j, None)                  # the Euler step
        return np.concatenate([y, [0.0, self.step(y)]])


# ---------------------------------------------------------------------------
# population runs of the falsification problems (observers.dynamic_gain.falsification)
# ---------------------------------------------------------------------------
class AuxiliarySystem(hs.HybridSystem):
    r"""The auxiliary system (13) with the clock (16): system (9) in the time tau, batched.

    State ``(eps_1..eps_{n+1}, ln nu, psi)``, in the time tau of (16)::

        d eps/dtau   = (A + LC - (h(eps) - gamma1) H) eps                 (13)
        d ln nu/dtau = h(eps) - gamma1                                    (13)
        d psi/dtau   = nu^mu                                              (16)

    with ``h(eps) = gamma2 |CA eps + L_0 C eps| + gamma1 (1 + ceil(gamma2 |C eps|
    - 1)^{1-mu})``. For ``v(0) > gamma2 |w(0)|`` (so T_0 = 0) it is (9) under
    the coordinate change (14) ``e = D_r(nu) eps``, ``v = nu`` and the time
    change ``t = psi(tau)``: the proof of Theorem 3. The settling time of (9)
    is ``T = psi(inf)`` (proof of Proposition 4); once eps is negligible
    ``nu' = -gamma1 nu`` exactly, so ``T = psi(tau) + nu(tau)^mu/(mu gamma1)``
    (:meth:`settling_time`). Unlike (9), whose gains ``z^{-rbar_i}`` blow up
    at T, this system is smooth and exponentially stable: an explicit RK45
    resolves T to the solver's tolerance, the whole population in one batch.

    Parameters
    ----------
    L : (n+1,) array_like
    mu, gamma1, gamma2 : float

    Examples
    --------
    >>> import numpy as np
    >>> from observers.lmi import PAPER_L
    >>> aux = AuxiliarySystem(PAPER_L, 0.2, 1.0, 1.0)
    >>> x0 = aux.initial_state([0.0, 10.0, 0.0, -5.0], 1.0)
    >>> arc = hs.simulate(aux, x0, t_max=40.0, rtol=1e-9, atol=1e-12, progress=False)
    >>> round(aux.settling_time(arc.x[-1]), 3)      # the observer's run: 7.81 s
    7.81

    References
    ----------
    Nekhoroshikh et al., CDC 2022, (9), (13), (14), (16), proofs of Theorem 3 and
    Proposition 4.
    """

    vectorized = True

    def __init__(self, L, mu, gamma1, gamma2=1.0):
        from observers.lmi import lmi10_matrices
        self.L = check_gains(L)
        n = self.n = self.L.size - 1
        self.mu = check_mu(mu, n, strict=False)
        self.gamma1 = scalar("gamma1", gamma1, positive=True)
        self.gamma2 = scalar("gamma2", gamma2, nonneg=True)
        A, C, H = lmi10_matrices(n, self.mu)
        self.M = A + np.outer(self.L, C[0])                   # A + LC
        self.h_diag = np.diag(H).copy()
        self.state_dim = n + 3

    def h(self, eps):
        """``h(eps)`` of (13), rows of eps (N, n+1) or one eps."""
        eps = np.asarray(eps, dtype=float)
        c = eps[..., 0]
        g = self.gamma2 * np.abs(eps[..., 1] + self.L[0] * c)     # |CA eps + L_0 C eps|
        s = self.gamma2 * np.abs(c) - 1.0
        return g + self.gamma1 * (1.0 + np.sign(s) * np.abs(s) ** (1.0 - self.mu))

    def flow_map(self, x, t, j, u):
        n = self.n
        eps = x[..., :n + 1]
        h = self.h(eps)
        dx = np.empty(np.shape(x))
        dx[..., :n + 1] = (eps @ self.M.T
                           - ((h - self.gamma1)[..., None] * self.h_diag) * eps)  # (13)
        dx[..., n + 1] = h - self.gamma1
        dx[..., n + 2] = np.exp(self.mu * x[..., n + 1])                          # (16)
        return dx

    def initial_state(self, e0, v0):
        """``(D_r^{-1}(v0) e0, ln v0, 0)`` (14); needs ``v0 > gamma2 |w(0)|`` (T_0 = 0)."""
        e0 = vector("e0", e0, self.n + 1)
        v0 = scalar("v0", v0, positive=True)
        if not v0 > self.gamma2 * abs(e0[0]):
            raise ValueError(f"v0 must exceed gamma2 |w(0)| = {self.gamma2 * abs(e0[0]):g} "
                             f"(Proposition 4), got {v0}")
        r = 1.0 - np.arange(self.n + 1) * self.mu
        return np.concatenate([e0 / v0 ** r, [np.log(v0), 0.0]])

    def settling_time(self, x):
        """``T = psi + nu^mu / (mu gamma1)`` from a state (or rows) late in the run."""
        x = np.asarray(x, dtype=float)
        n = self.n
        return x[..., n + 2] + np.exp(self.mu * x[..., n + 1]) / (self.mu * self.gamma1)


class BoxDisturbedPlant(hs.HybridSystem):
    r"""Plant (1) of Section VI under a piecewise-constant disturbance ``|d_i| <= a``, batched.

    The closed loop of :func:`example_plant` (``u = Kx + cos 10t``, b = e_n)
    with ``d = (d_y, d_x1..d_xn)`` constant on each of ``pieces`` equal
    intervals of [0, t_end] (the last value held after), the values carried
    in the state so that one vectorized batch runs a whole population of
    disturbances: state ``(x_1..x_n, d_{piece 1}, ..., d_{piece P})`` (each
    ``d_piece`` of length n+1). ``x' = (A + bK) x + b cos 10t + d_x(t)``,
    output ``(y, u) = (x_1 + d_y(t), Kx + cos 10t)``. The error e of (19) is
    driven by exactly this d (d_0 = d_y enters w', d_i = d_{x,i} enters
    e_i'), the class of Proposition 5 with ``||d||_inf <= a``.

    Examples
    --------
    >>> import numpy as np
    >>> plant = BoxDisturbedPlant(pieces=2, t_end=2.0)
    >>> x = np.r_[1.0, 0.0, 0.0, [0.1, 0, 0, 0], [-0.1, 0, 0, 0]]
    >>> plant.output(x, 1.5, 0)[0].round(3).tolist()      # y = x_1 + d_y (2nd piece)
    0.9
    """

    vectorized = True

    def __init__(self, pieces, t_end, n=3, K=None):
        ref = example_plant(n=n, K=K)
        self.n = n
        self.Acl = ref.A
        self.K = ref.C[1]
        self.pieces = int(pieces)
        if self.pieces < 1:
            raise ValueError(f"pieces must be >= 1, got {pieces}")
        self.width = scalar("t_end", t_end, positive=True) / self.pieces
        self.state_dim = n + self.pieces * (n + 1)
        self.output_dim = 2

    def d(self, x, t):
        """The disturbance ``(d_y, d_x)`` at t, on the last axis: (n+1,) or rows (N, n+1)."""
        x = np.asarray(x, dtype=float)
        k = np.clip((np.asarray(t, dtype=float) // self.width).astype(int), 0, self.pieces - 1)
        n = self.n
        vals = x[..., n:].reshape(x.shape[:-1] + (self.pieces, n + 1))
        k = np.broadcast_to(k, x.shape[:-1])[..., None, None]
        return np.take_along_axis(vals, k, axis=-2)[..., 0, :]

    def flow_map(self, x, t, j, u):
        """``x' = (A + bK) x + b cos 10t + d_x(t)`` (on the last axis)."""
        x = np.asarray(x, dtype=float)
        n = self.n
        dx = np.zeros(x.shape)
        dx[..., :n] = x[..., :n] @ self.Acl.T + self.d(x, t)[..., 1:]
        dx[..., n - 1] += np.cos(10 * np.asarray(t, dtype=float))
        return dx

    def output(self, x, t, j):
        """``(y, u) = (x_1 + d_y(t), Kx + cos 10t)`` (on the last axis)."""
        x = np.asarray(x, dtype=float)
        y = np.empty(x.shape[:-1] + (2,))
        y[..., 0] = x[..., 0] + self.d(x, t)[..., 0]
        y[..., 1] = x[..., :self.n] @ self.K + np.cos(10 * np.asarray(t, dtype=float))
        return y
