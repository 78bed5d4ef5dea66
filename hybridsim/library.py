"""Standard hybrid systems with known solutions, for demos, tests and benchmarks."""
from __future__ import annotations

import numpy as np

from .system import HybridSystem

__all__ = ["BouncingBall", "BouncingBallBatch", "Timer", "bouncing_ball_jump_times"]


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
    """

    state_dim = 2

    def __init__(self, gravity=9.81, restitution=0.8):
        self.g, self.e = _check_ball(gravity, restitution)

    def flow_map(self, x):
        return np.array([x[1], -self.g])

    def jump_map(self, x):
        return np.array([0.0, -self.e * x[1]])

    def flow_set(self, x):
        return x[0] >= 0

    def jump_set(self, x):
        return x[0] <= 0 and x[1] <= 0

    def jump_guard(self, x):
        return -x[0]

    def flow_guard(self, x):
        return x[0]


class BouncingBallBatch(BouncingBall):
    """:class:`BouncingBall` written over batches (``vectorized = True``):
    x has shape (N, 2), one ball per row."""

    vectorized = True

    def flow_map(self, x):
        return np.stack([x[:, 1], np.full(len(x), -self.g)], axis=1)

    def jump_map(self, x):
        return np.stack([np.zeros(len(x)), -self.e * x[:, 1]], axis=1)

    def flow_set(self, x):
        return x[:, 0] >= 0

    def jump_set(self, x):
        return (x[:, 0] <= 0) & (x[:, 1] <= 0)

    def jump_guard(self, x):
        return -x[:, 0]

    def flow_guard(self, x):
        return x[:, 0]


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
