"""hybridsim.library: the standard systems match their closed forms."""
import numpy as np
import pytest

import hybridsim as hs
from hybridsim.library import BouncingBall, Timer, bouncing_ball_jump_times


def test_ball_and_its_batch_version_match_the_closed_form():
    exact = bouncing_ball_jump_times(1.3, 12, 9.81, 0.7)
    arc = hs.simulate(BouncingBall(9.81, 0.7), [1.3, 0.0], t_max=np.inf, j_max=12,
                      rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(arc.jump_times, exact, atol=1e-12)
    arcs = hs.simulate_many(BouncingBall(9.81, 0.7, vectorized=True), [[1.3, 0.0], [0.5, 0.0]],
                            t_max=np.inf, j_max=12, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(arcs[0].jump_times, exact, atol=1e-12)
    np.testing.assert_allclose(arcs[1].jump_times, bouncing_ball_jump_times(0.5, 12, 9.81, 0.7),
                               atol=1e-12)


def test_timer_jumps_on_multiples():
    arc = hs.simulate(Timer(0.5), [0.0], t_max=2.2)
    np.testing.assert_allclose(arc.jump_times, [0.5, 1.0, 1.5, 2.0], atol=1e-13)


@pytest.mark.parametrize("call, match", [
    (lambda: BouncingBall(gravity=-1.0), "gravity must be a positive finite float"),
    (lambda: BouncingBall(restitution=1.0), r"restitution must lie in \[0, 1\)"),
    (lambda: Timer(0.0), "period must be a positive finite float"),
    (lambda: bouncing_ball_jump_times(-1.0, 3), "h0 must be positive and finite"),
])
def test_bad_parameters(call, match):
    with pytest.raises(ValueError, match=match):
        call()
