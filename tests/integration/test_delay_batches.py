"""Delays in batches: a population of delayed systems, each row with its own delay,
integrated as one vectorized batch, and a falsification search over the delay.

x' = -k x(t - tau) from the constant past 1 is asymptotically stable exactly when
k tau < pi / 2 (the characteristic equation s + k e^{-s tau} = 0 has its rightmost
roots on the imaginary axis at k tau = pi / 2). The delay is a state component,
constant, read by the flow map for its own row (``self.history`` returns the rows'
states at their own times ``t - tau``), so a population of delays is one batch.
"""
import math

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.falsification import Interval, Space, batch_run
from hybridsim.testing import margin_bounded

K = 1.5
TAU_CRIT = math.pi / (2 * K)            # 1.047: the delay margin of x' = -K x(t - tau)


class DelayedFeedback(hs.HybridSystem):
    """x0' = -k x0(t - x1), x1' = 0: the delay per row in the state."""

    state_dim, needs_history, vectorized = 2, True, True

    def __init__(self, k, tau_min):
        self.k = k
        self.max_step = tau_min         # no step reaches past the smallest delay

    def flow_map(self, x, t, j, u):
        x = np.asarray(x, dtype=float)
        out = np.zeros_like(x)
        out[..., 0] = -self.k * self.history(t - x[..., 1])[..., 0]
        return out


def _run(lo):
    return batch_run(DelayedFeedback(K, lo), lambda p: [1.0, p["tau"]], t_max=12.0,
                     rtol=1e-8, atol=1e-10)


def _settles(arc):
    """|x(t)| <= 1 from t = 8 on: violated where the loop lost its delay margin."""
    return margin_bounded(arc, lambda x, t, j: x[0], 1.0, t=(8.0, np.inf))


def test_each_row_reads_its_own_delay_as_the_python_path_does():
    """Four delays in one batch: each row equals its own Python-path run (1e-6 at
    rtol 1e-8; the kink at t = tau has no declared breakpoint here, the step-size
    control resolves it), and before the first kink x = 1 - K t exactly."""
    taus = [0.3, 0.8, 1.0, 1.2]
    arcs = _run(0.3)([{"tau": v} for v in taus])
    for tau, b in zip(taus, arcs):
        a = hs.simulate(DelayedFeedback(K, 0.3), [1.0, tau], 12.0, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(b.x[-1], a.x[-1], atol=1e-6)
        early = b.t <= tau
        np.testing.assert_allclose(b.x[early, 0], 1.0 - K * b.t[early], atol=1e-9)


@pytest.mark.slow
def test_falsify_finds_the_delay_margin_and_nothing_below_it():
    """Over tau in [0.2, 1.3] the search finds a counterexample past the delay margin
    pi / (2 K) = 1.047 (each population one batch); over [0.2, 0.9] (k tau <= 1.35 <
    pi / 2, decaying well before t = 8) none within 60 runs, and the random baseline
    of the same budget is no worse than the search."""
    found = hs.falsify(_run(0.2), Space(tau=Interval(0.2, 1.3)), _settles, budget=60,
                       seed=0, progress=False)
    assert found.verdict == "counterexample" and found.margin < 0
    assert found.point["tau"] > TAU_CRIT
    safe = hs.falsify(_run(0.2), Space(tau=Interval(0.2, 0.9)), _settles, budget=60, seed=0,
                      progress=False)
    rnd = hs.falsify(_run(0.2), Space(tau=Interval(0.2, 0.9)), _settles, budget=60, seed=0,
                     method="random", progress=False)
    assert safe.verdict == "none found" and safe.margin > 0
    assert safe.margin <= rnd.margin + 1e-12


def test_delays_are_refused_by_name_on_the_compiled_path():
    pytest.importorskip("numba")
    with pytest.raises(TypeError, match="reads its history"):
        hs.simulate_many(DelayedFeedback(K, 0.2), [[1.0, 0.5]], t_max=1.0,
                         backend="compiled")
