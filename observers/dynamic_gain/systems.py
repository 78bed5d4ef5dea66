r"""The hybrid systems of paper 000: observer (6)-(8) and the plant (1) of Section VI.

=================================  =============================================
:class:`DynamicGainObserver`       observer (6)-(8) with z of (7), settled mode
:func:`proposed_observer`          gamma2 > 0, z = max{v, gamma2 |w|} (7)
:func:`prescribed_time_observer`   gamma2 = 0, z = v (Holloway-Krstic, ref. [10])
:func:`homogeneous_observer`       z = |w| (Perruquetti et al., ref. [17])
:func:`luenberger_observer`        gamma1 = gamma2 = 0, z = v(0) (Remark 1)
:func:`example_plant`              plant (1) of Section VI in closed loop
:func:`uniform_noise`              Section VI's omega in (-1, 1), seeded
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
from observers._common import matrix, scalar, vector

from .design import check_gains, check_mu, rbar

__all__ = ["DynamicGainObserver", "proposed_observer", "prescribed_time_observer",
           "homogeneous_observer", "luenberger_observer", "uniform_noise", "example_plant"]


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

    # -- pieces -------------------------------------------------------------
    def z(self, w, v, q=0.0):
        """The dynamic gain z of (7) (|w| for the homogeneous observer), floored at z_min."""
        if self.z_mode == "abs":
            z = abs(w)
        else:
            z = max(0.0 if q >= 0.5 else v, self.gamma2 * abs(w))     # (7)
        return max(z, self.z_min)

    def injection(self, w, v, q):
        """``z^{-rbar_i} w`` for i = 0..n (with the floor of decision 1)."""
        return self.z(w, v, q) ** (-self.rbar) * w

    def flow_map(self, x, t, j, u):
        """(6) and (8); v held at its limit 0 in the settled mode (q = 1)."""
        n, L = self.n, self.L
        w, xh, v, q = x[0], x[1:n + 1], x[n + 1], x[n + 2]
        y = u[0]
        k = self.injection(w, v, q)
        dx = np.empty(n + 3)
        dw = y - xh[0] + L[0] * k[0]                                    # (6), w
        dx[0] = dw
        dx[1:n] = xh[1:]                                                # (6), x_hat
        dx[n] = 0.0
        if self.m:
            dx[1:n + 1] += self.b @ np.asarray(u[1:], dtype=float)
        dx[1:n + 1] -= L[1:] * k[1:]
        if q >= 0.5:
            dx[n + 1] = 0.0
        else:
            s = v - self.gamma2 * abs(w)                                # (8)
            dx[n + 1] = self.gamma2 * abs(dw) - self.gamma1 * np.sign(s) * abs(s) ** (1 - self.mu)
        dx[n + 2] = 0.0
        return dx

    def jump_guard(self, x, t, j, u):
        """Jump when v reaches z_min with q = 0 (decision 1)."""
        n = self.n
        return np.array([self.z_min - x[n + 1], 0.5 - x[n + 2]])

    def jump_map(self, x, t, j, u):
        """Settle: v -> 0, q -> 1 (z stays continuous)."""
        xp = np.array(x, dtype=float)
        xp[self.n + 1] = 0.0
        xp[self.n + 2] = 1.0
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
