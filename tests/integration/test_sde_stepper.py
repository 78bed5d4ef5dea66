"""The compiled SDE stepper's Euler–Maruyama loop on the grid (no event watched)
and maps written into an argument: the same arcs as the maps returning arrays and
as the Python path, and the steps the loop does not take (a map's bad value, a
blow-up) ended as the Python path ends them.

Tolerances: arcs of the same seed agree to 1e-12 (the same arithmetic; the
compiled forms of one map give the same bits).
"""
from __future__ import annotations

import numpy as np
import pytest

import hybridsim as hs
from hybridsim import Termination
from hybridsim.compiled import CompiledSystem

pytest.importorskip("numba")


def _same(a, b):
    assert a.termination is b.termination
    np.testing.assert_array_equal(a.j, b.j)
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)


def _ou_flow(x, t, j, p, out):
    out[0] = -p[0] * x[0]
    out[1] = x[0] - x[1]


def _ou_noise(x, t, j, p, out):
    out[0] = 0.5
    out[1] = 0.1 * (1.0 + x[0] * x[0])


def _mixed_noise(x, t, j, p, out):
    out[0, 0], out[0, 1], out[0, 2] = 1.0, 0.5, 0.0
    out[1, 0], out[1, 1], out[1, 2] = 0.0, 0.3, 0.4 * x[0]


def test_maps_written_into_out_give_the_arcs_of_the_maps_returning_arrays():
    kw = dict(t_max=2.0, method="EM", max_step=1e-3, seed=7)     # 2000 blocks: the window moves
    into = CompiledSystem(flow_map=_ou_flow, diffusion=_ou_noise, state_dim=2, params=[1.5])
    arrays = CompiledSystem(
        flow_map=lambda x, t, j, p: np.array([-p[0] * x[0], x[0] - x[1]]),
        diffusion=lambda x, t, j, p: np.array([0.5, 0.1 * (1.0 + x[0] * x[0])]),
        state_dim=2, params=[1.5])
    a = hs.simulate(into, [1.0, 0.0], backend="compiled", **kw)
    b = hs.simulate(arrays, [1.0, 0.0], backend="compiled", **kw)
    c = hs.simulate(into, [1.0, 0.0], **kw)                     # the Python path
    assert len(a.t) == 2001 and a.termination is Termination.T_MAX
    np.testing.assert_array_equal(a.x, b.x)
    _same(a, c)
    assert not np.array_equal(a.x[-1], a.x[0])


def test_general_noise_and_an_ode_flow_written_into_out():
    kw = dict(t_max=2.0, method="EM", max_step=1e-3, seed=7)
    # general noise: out of shape (n, noise_dim)
    g = CompiledSystem(flow_map=_ou_flow, diffusion=_mixed_noise, noise_dim=3, state_dim=2,
                       params=[1.0])
    _same(hs.simulate(g, [0.5, 0.5], backend="compiled", **kw), hs.simulate(g, [0.5, 0.5], **kw))
    # an ODE run (the other kernels see the array the map writes)
    ode = CompiledSystem(flow_map=_ou_flow, state_dim=2, params=[1.5])
    ref = CompiledSystem(flow_map=lambda x, t, j, p: np.array([-p[0] * x[0], x[0] - x[1]]),
                         state_dim=2, params=[1.5])
    np.testing.assert_array_equal(hs.simulate(ode, [1.0, 0.0], 1.0, backend="compiled").x,
                                  hs.simulate(ref, [1.0, 0.0], 1.0, backend="compiled").x)
    # a fifth parameter with a default is not an out: the map returns its value
    dflt = CompiledSystem(flow_map=lambda x, t, j, p, k=1.5: np.array([-k * x[0], x[0] - x[1]]),
                          state_dim=2)
    assert dflt.maps_into == {} and "flow" in ode.maps_into
    np.testing.assert_allclose(hs.simulate(dflt, [1.0, 0.0], 1.0).x[-1],
                               hs.simulate(ode, [1.0, 0.0], 1.0).x[-1], rtol=1e-12)


def test_an_event_located_after_the_window_moved():
    # Brownian motion with drift to the barrier 1, dt = 1e-3: hits after hundreds of
    # blocks; the bridge-corrected time needs the Lévy areas of the block it falls in
    bm = CompiledSystem(flow_map=lambda x, t, j, p: np.full(1, 0.3),
                        jump_map=lambda x, t, j, p: np.zeros(1),
                        diffusion=lambda x, t, j, p: np.full(1, 0.4),
                        jump_guard=lambda x, t, j, p: x[0] - 1.0, state_dim=1)
    kw = dict(t_max=8.0, j_max=3, method="EM", max_step=1e-3)
    for seed in (2, 5):
        a = hs.simulate(bm, [0.0], backend="compiled", seed=seed, **kw)
        _same(a, hs.simulate(bm, [0.0], seed=seed, **kw))
        assert a.jump_count >= 1 and a.jump_times[0] > 0.256


def test_the_steps_the_grid_loop_does_not_take_end_as_on_the_python_path():
    kw = dict(t_max=3.0, method="EM", max_step=1e-3, seed=3, throw=False, warn=False)
    grow = CompiledSystem(flow_map=lambda x, t, j, p: x.copy(),
                          diffusion=lambda x, t, j, p: np.full(1, 0.1), state_dim=1)
    a = hs.simulate(grow, [1.0], backend="compiled", max_norm=5.0, **kw)
    assert a.termination is Termination.BLOWUP
    _same(a, hs.simulate(grow, [1.0], max_norm=5.0, **kw))
    # a diffusion that turns NaN past x = 2: the Python path's samples, the map named
    # (the Python path ends NON_FINITE at the same time: the state it makes is NaN)
    nan = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1),
                         diffusion=lambda x, t, j, p: np.full(1, 0.1 if x[0] < 2.0 else np.nan),
                         state_dim=1)
    a = hs.simulate(nan, [0.0], backend="compiled", **kw)
    b = hs.simulate(nan, [0.0], **kw)
    assert a.termination is Termination.MAP_ERROR and "diffusion" in a.message
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
    assert 1.9 < a.t[-1] < 2.2
    # a diffusion of the wrong shape past x = 2: named
    bad = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1),
                         diffusion=lambda x, t, j, p: np.full(1 if x[0] < 2.0 else 2, 0.1),
                         state_dim=1)
    a = hs.simulate(bad, [0.0], backend="compiled", **kw)
    assert a.termination is Termination.MAP_ERROR
    assert "diffusion" in a.message and "shape" in a.message
    assert 1.9 < a.t[-1] < 2.2
