"""hybridsim.testing: settling times and exactness/bound assertions."""
import numpy as np
import pytest

import hybridsim as hs
from hybridsim import testing as hst


@pytest.fixture(scope="module")
def arc():
    # x' = -x until t = 1, then a jump to 0 (a "finite-time observer error")
    sysm = hs.HybridSystem.from_functions(
        f=lambda x: np.array([-x[0], 1.0]), g=lambda x: np.array([0.0, x[1]]),
        jump_guard=lambda x: x[1] - 1.0, flow_guard=lambda x: 1.0 - x[1],
        D=lambda x: x[1] >= 1.0 and x[0] != 0.0, state_dim=2)
    return hs.simulate(sysm, [1.0, 0.0], t_max=2.0, refine=4)


def test_settling_time(arc):
    t, j = hst.settling_time(arc, lambda x: x[0], threshold=1e-10)
    assert abs(t - 1.0) < 1e-12 and j == 0
    assert hst.settling_time(arc, arc.x[:, 0] * 0, 1e-10) == (0.0, 0)
    assert hst.settling_time(arc, np.ones(len(arc)), 0.5) == (float("inf"), None)


def test_assert_exact_after(arc):
    hst.assert_exact_after(arc, lambda x: x[0], t=1.0, j=1, atol=0.0)
    with pytest.raises(AssertionError, match=r"first violation at \(t=0\.5.*j=0\)"):
        hst.assert_exact_after(arc, lambda x: x[0], t=0.5, atol=1e-3)
    with pytest.raises(AssertionError, match="no sample"):
        hst.assert_exact_after(arc, lambda x: x[0], t=5.0)


def test_assert_bounded(arc):
    hst.assert_bounded(arc, lambda x: x[0], lambda t, j: np.exp(-t), rtol=1e-6)
    hst.assert_bounded(arc, arc.x[:, :1], 1.0)
    with pytest.raises(AssertionError, match=r"bound violated: first at \(t="):
        hst.assert_bounded(arc, lambda x: x[0], lambda t, j: 0.5 * np.exp(-t))
    with pytest.raises(ValueError, match="one value per sample"):
        hst.assert_bounded(arc, np.ones(3), 1.0)
