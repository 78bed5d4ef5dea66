"""Standard hybrid systems with known solutions, for demos, tests and benchmarks."""
from __future__ import annotations

import numpy as np

from .system import HybridSystem

__all__ = ["BouncingBall", "BouncingBallBatch", "Timer", "bouncing_ball_jump_times", "AIMD",
           "Telegraph", "DriftedBrownian", "RandomRestitutionBall"]


def _check_ball(gravity, restitution):
    if not (np.isfinite(gravity) and gravity > 0):
        raise ValueError(f"gravity must be a positive finite float, got {gravity!r}")
    if not (0 <= restitution < 1):
        raise ValueError(f"restitution must lie in [0, 1), got {restitution!r}")
    return float(gravity), float(restitution)


class BouncingBall(HybridSystem):
    r"""A ball bouncing on the floor: x = (height, velocity).

    .. math:: \dot x = (x_2, -g) \text{ on } C = \{x_1 \ge 0\}, \qquad
              x^+ = (0, -e x_2) \text{ on } D = \{x_1 \le 0, x_2 \le 0\}.

    With guards (h = -x_1 for D, c = x_1 for C) the impacts are located by
    root-finding. Its exact impact times are
    :func:`bouncing_ball_jump_times`; from rest it is Zeno.

    The maps are written once, on the last axis (``x[..., k]``): one state
    (the Python path), a batch of states (N, 2) (``vectorized=True``: the
    vectorized path) and the compiled path (the maps rewritten as functions
    of (x, t, j, p), g and e read into p) all run these methods.

    Examples
    --------
    >>> import numpy as np
    >>> ball = BouncingBall(vectorized=True)
    >>> ball.flow_map(np.array([1.0, 0.5]))
    array([ 0.5 , -9.81])
    >>> ball.jump_set(np.array([[0.0, -1.0], [1.0, -1.0]]))
    array([ True, False])
    """

    state_dim = 2

    def __init__(self, gravity=9.81, restitution=0.8, vectorized=False):
        self.g, self.e = _check_ball(gravity, restitution)
        if not isinstance(vectorized, (bool, np.bool_)):
            raise TypeError(f"vectorized must be a bool, got {vectorized!r}")
        if vectorized:
            self.vectorized = True

    def flow_map(self, x):
        dx = np.empty_like(x)
        dx[..., 0] = x[..., 1]
        dx[..., 1] = -self.g
        return dx

    def jump_map(self, x):
        xn = np.empty_like(x)
        xn[..., 0] = 0.0
        xn[..., 1] = -self.e * x[..., 1]
        return xn

    def flow_set(self, x):
        return x[..., 0] >= 0

    def jump_set(self, x):
        return (x[..., 0] <= 0) & (x[..., 1] <= 0)

    def jump_guard(self, x):
        return -x[..., 0]

    def flow_guard(self, x):
        return x[..., 0]


class BouncingBallBatch(BouncingBall):
    """Deprecated: ``BouncingBall(gravity, restitution, vectorized=True)``
    (the same maps; this name is kept for old scripts).

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore", DeprecationWarning)
    ...     BouncingBallBatch().vectorized
    True
    """

    vectorized = True

    def __init__(self, gravity=9.81, restitution=0.8):
        import warnings
        warnings.warn("BouncingBallBatch is deprecated: use BouncingBall(gravity, restitution, "
                      "vectorized=True)", DeprecationWarning, stacklevel=2)
        super().__init__(gravity, restitution)


def bouncing_ball_jump_times(h0, k, gravity=9.81, restitution=0.8):
    """Exact impact times of balls dropped from rest at heights ``h0``.

    First impact t1 = sqrt(2 h0 / g); after impact i the ball leaves at
    e^i g t1 and flies 2 e^i t1, so
    t_k = t1 (1 + 2 e (1 - e^(k-1)) / (1 - e)).

    Returns
    -------
    ndarray, shape ``np.shape(h0) + (k,)``
    """
    g, e = _check_ball(gravity, restitution)
    h0 = np.asarray(h0, dtype=float)
    if np.any(~np.isfinite(h0)) or np.any(h0 <= 0):
        raise ValueError("h0 must be positive and finite")
    t1 = np.sqrt(2 * h0 / g)
    i = np.arange(1, int(k) + 1)
    return t1[..., None] * (1 + 2 * e * (1 - e ** (i - 1)) / (1 - e))


class Timer(HybridSystem):
    """A timer of period T: x' = 1 on C = {x <= T}, x+ = 0 on D = {x >= T}.

    Its jumps fall on the multiples of T (from x0 = 0).
    """

    state_dim = 1

    def __init__(self, period=1.0):
        if not (np.isfinite(period) and period > 0):
            raise ValueError(f"period must be a positive finite float, got {period!r}")
        self.period = float(period)

    def flow_map(self, x):
        return np.array([1.0])

    def jump_map(self, x):
        return np.array([0.0])

    def jump_guard(self, x):
        return x[0] - self.period

    def flow_guard(self, x):
        return self.period - x[0]


# ------------------------------------------------------------------ stochastic
def _positive(name, v):
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite float, got {v!r}")
    return float(v)


class AIMD(HybridSystem):
    """Additive increase, multiplicative decrease (TCP's window): x' = 1, x -> x/2
    at the rate x (``constant_rate=False``) or at the rate 1.

    Stationary moments, from the generator equation E[k X^(k-1) + r(X) (2^-k - 1)
    X^k] = 0: for r(x) = x, E[X^(k+1)] = k E[X^(k-1)] / (1 - 2^-k) (E[X^2] = 2,
    E[X^4] = 48/7); for r = 1, E[X^k] = k E[X^(k-1)] / (1 - 2^-k) (E[X] = 2,
    E[X^2] = 16/3).
    """

    state_dim = 1

    def __init__(self, constant_rate=False):
        self.constant_rate = bool(constant_rate)

    def flow_map(self, x):
        return np.array([1.0])

    def jump_map(self, x):
        return x / 2

    def jump_rate(self, x):
        return 1.0 if self.constant_rate else x[0]


class Telegraph(HybridSystem):
    """The telegraph process: x = (position, direction), x_1' = v x_2, the
    direction flips (x_2 -> -x_2) at the rate lam.

    From x_1(0) = 0: E[x_1(t)^2] = v^2 (2 lam t - 1 + exp(-2 lam t)) / (2 lam^2).
    """

    state_dim = 2

    def __init__(self, rate=1.0, speed=1.0):
        self.lam, self.v = _positive("rate", rate), _positive("speed", speed)

    def flow_map(self, x):
        return np.array([self.v * x[1], 0.0])

    def jump_map(self, x):
        return np.array([x[0], -x[1]])

    def jump_rate(self, x):
        return self.lam


class DriftedBrownian(HybridSystem):
    """Brownian motion with drift: dx = mu dt + sigma dW, and a jump (x+ = x) on
    reaching the barrier b (``jump_guard = x - b``; run it with ``j_max=1`` and an
    SDE method). From 0 with mu > 0 the hitting time is inverse Gaussian: mean
    b/mu, variance b sigma^2/mu^3.
    """

    state_dim = 1

    def __init__(self, drift=1.0, sigma=1.0, barrier=1.0):
        if not np.isfinite(drift):
            raise ValueError(f"drift must be finite, got {drift!r}")
        self.mu, self.sigma = float(drift), _positive("sigma", sigma)
        self.b = float(barrier)

    def flow_map(self, x):
        return np.array([self.mu])

    def diffusion(self, x):
        return np.array([self.sigma])

    def jump_map(self, x):
        return x.copy()

    def jump_guard(self, x):
        return x[0] - self.b


class RandomRestitutionBall(BouncingBall):
    """:class:`BouncingBall` whose restitution at each impact is drawn from
    U(lo, hi), i.i.d. (a random jump map). Dropped from h0 at rest, the k-th
    impact is at t1 + (2 v1/g) sum_{i<k} prod_{l<=i} e_l (t1 = sqrt(2 h0/g),
    v1 = g t1), of mean t1 + (2 v1/g) sum_{i=1}^{k-1} m^i with m = (lo + hi)/2,
    and the Zeno time has mean t1 + (2 v1/g) m/(1 - m).
    """

    def __init__(self, gravity=9.81, lo=0.3, hi=0.7):
        if not 0 <= lo <= hi < 1:
            raise ValueError(f"need 0 <= lo <= hi < 1, got lo={lo!r}, hi={hi!r}")
        super().__init__(gravity, 0.5 * (lo + hi))
        self.lo, self.hi = float(lo), float(hi)

    def jump_law(self, x, rng):
        return np.array([0.0, -rng.uniform(self.lo, self.hi) * x[1]])
