"""Property tests (hypothesis) of the engine on systems with closed-form solutions."""
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

import hybridsim as hs
from hybridsim.library import BouncingBall, Timer, bouncing_ball_jump_times

FAST = settings(max_examples=40, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])


@FAST
@given(h0=st.floats(0.05, 20.0), e=st.floats(0.2, 0.9), g=st.floats(1.0, 30.0))
def test_ball_impacts_match_closed_form(h0, e, g):
    # 15 events, each bracketed to 4 ulp on an exactly integrated parabola
    exact = bouncing_ball_jump_times(h0, 15, g, e)
    arc = hs.simulate(BouncingBall(g, e), [h0, 0.0], t_max=np.inf, j_max=15,
                      rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(arc.jump_times, exact, rtol=1e-11, atol=1e-12)
    assert arc.x[:, 0].min() >= -1e-12


@FAST
@given(period=st.floats(1e-3, 50.0), n=st.integers(1, 30))
def test_timer_jumps_on_multiples(period, n):
    arc = hs.simulate(Timer(period), [0.0], t_max=(n + 0.5) * period)
    np.testing.assert_allclose(arc.jump_times, period * np.arange(1, n + 1),
                               rtol=1e-12, atol=0)
    assert arc.termination is hs.Termination.T_MAX


@FAST
@given(seed=st.integers(0, 10**6))
def test_plant_observer_error_matches_expm(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 5))
    A = rng.normal(size=(n, n))
    C = rng.normal(size=(1, n))
    L = rng.normal(size=n)

    class Obs(hs.HybridSystem):
        state_dim, input_dim = n, 1

        def flow_map(self, xh, t, j, y):
            return A @ xh + L * (y[0] - C[0] @ xh)

    x0 = rng.normal(size=2 * n)
    T = 1.0
    arc = hs.simulate(hs.connect(hs.LinearPlant(A, C=C), Obs()), x0, t_max=T,
                      rtol=1e-10, atol=1e-12)
    e = arc["observer"].xf - arc["plant"].xf
    expected = expm((A - np.outer(L, C[0])) * T) @ (x0[n:] - x0[:n])
    scale = 1 + np.abs(expm(A * T)).max() * np.abs(x0).max() + np.abs(expected).max()
    np.testing.assert_allclose(e, expected, atol=1e-7 * scale)
