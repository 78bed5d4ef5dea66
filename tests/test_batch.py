"""simulate_many (looped) and sweep: one arc per initial state or parameter."""
import numpy as np
import pytest

import hybridsim as hs


class Decay(hs.HybridSystem):
    """x' = -a x (a picklable module-level system)."""

    state_dim = 1

    def __init__(self, a=1.0):
        self.a = a

    def flow_map(self, x):
        return -self.a * x


def make_decay(a):
    return Decay(a)


def test_simulate_many_one_arc_per_row():
    x0s = np.array([[1.0], [2.0], [-3.0]])
    arcs = hs.simulate_many(Decay(), x0s, t_max=1.0, rtol=1e-10, atol=1e-12)
    assert len(arcs) == 3
    for x0, arc in zip(x0s, arcs):
        np.testing.assert_allclose(arc.xf, x0 * np.exp(-1.0), rtol=1e-8)


def test_sweep_over_parameters():
    arcs = hs.sweep(make_decay, [0.5, 1.0, 2.0], [1.0], t_max=1.0, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose([a.xf[0] for a in arcs], np.exp(-np.array([0.5, 1.0, 2.0])),
                               rtol=1e-8)
    arcs = hs.sweep(make_decay, [1.0, 2.0], lambda a: [a], t_max=0.0)
    assert [a.x0[0] for a in arcs] == [1.0, 2.0]


def test_sweep_and_many_with_a_process_pool():
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(2) as ex:
        arcs = hs.sweep(make_decay, [0.5, 1.0, 2.0, 4.0], [1.0], t_max=1.0, executor=ex,
                        rtol=1e-10, atol=1e-12)
        many = hs.simulate_many(Decay(), np.ones((5, 1)), t_max=1.0, executor=ex)
    np.testing.assert_allclose([a.xf[0] for a in arcs], np.exp(-np.array([0.5, 1, 2, 4])),
                               rtol=1e-8)
    assert len(many) == 5


def test_bad_batch_input():
    with pytest.raises(ValueError, match=r"x0s must have shape \(N, 1\), got \(3,\)"):
        hs.simulate_many(Decay(), np.ones(3), t_max=1.0)
    with pytest.raises(TypeError, match="system must be a HybridSystem"):
        hs.simulate_many(object(), np.ones((3, 1)), t_max=1.0)
    with pytest.raises(TypeError, match="make_system must be a callable"):
        hs.sweep(3, [1], [1.0], t_max=1.0)
