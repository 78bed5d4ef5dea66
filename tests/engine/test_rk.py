"""The engine's Runge-Kutta steppers (hybridsim._rk) are scipy's, bit for bit.

They replace only scipy's per-step Python overheads, so every accepted step,
rejection, failure and dense output must equal scipy's exactly (tolerance
zero: the same floating-point operations in the same order), on random
systems, both directions, with and without max_step, and on a flow that
fails. An end-to-end check: a smooth simulate run samples exactly
solve_ivp's steps.
"""

import math

import numpy as np
import pytest
from scipy.integrate import DOP853, RK23, RK45, solve_ivp

import hybridsim as hs
from hybridsim._rk import LEAN


def _pair(Base, fun, y0, t_bound, **kw):
    return Base(fun, 0.0, y0, t_bound, **kw), LEAN[Base](fun, 0.0, y0, t_bound, **kw)


def _same_state(a, b):
    return (a.t == b.t and a.status == b.status and a.h_abs == b.h_abs
            and np.array_equal(a.y, b.y) and np.array_equal(a.f, b.f)
            and np.array_equal(a.K, b.K))


@pytest.mark.parametrize("Base", [RK45, RK23, DOP853])
@pytest.mark.parametrize("seed", range(12))
def test_lean_steps_equal_scipy_bit_for_bit(Base, seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 7))
    A = rng.normal(size=(n, n))
    c = rng.normal(size=n)

    def fun(t, x):
        return A @ x + np.sin(3 * t) * c + 0.1 * np.tanh(x) ** 2

    y0 = rng.normal(size=n)
    direction = -1.0 if seed % 3 == 0 else 1.0
    kw = dict(rtol=10 ** -rng.uniform(3, 10), atol=10 ** -rng.uniform(6, 12))
    if seed % 4 == 1:
        kw["max_step"] = 0.05
    a, b = _pair(Base, fun, y0, direction * rng.uniform(0.5, 4.0), **kw)
    steps = 0
    while a.status == "running":
        a.step()
        b.step()
        steps += 1
        assert _same_state(a, b), f"step {steps}: scipy t={a.t}, lean t={b.t}"
        ts = np.linspace(a.t_old, a.t, 5)
        np.testing.assert_array_equal(a.dense_output()(ts), b.dense_output()(ts))
    assert b.status == "finished" and steps >= 2


@pytest.mark.parametrize("Base", [RK45, RK23, DOP853])
def test_lean_step_rejects_and_fails_as_scipy_does(Base):
    # a finite-time escape: rejections, then a step below the minimum
    def escape(t, x):
        return x ** 2

    a, b = _pair(Base, escape, np.array([1.0]), 2.0, rtol=1e-8, atol=1e-10)
    msgs = []
    while a.status == "running":
        msgs.append((a.step(), b.step()))
        assert _same_state(a, b)
    assert a.status == b.status == "failed" and msgs[-1][0] == msgs[-1][1]
    assert math.isclose(a.t, 1.0, rel_tol=1e-6)


def test_simulate_samples_exactly_solve_ivps_steps():
    A = np.array([[0.0, 1.0], [-4.0, -0.3]])
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: A @ x, state_dim=2)
    arc = hs.simulate(sysm, [1.0, 0.0], t_max=5.0, rtol=1e-9, atol=1e-12)
    ref = solve_ivp(lambda t, x: A @ x, (0.0, 5.0), [1.0, 0.0], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(arc.t, ref.t)
    np.testing.assert_array_equal(arc.x, ref.y.T)


def test_simulate_with_dop853_samples_exactly_solve_ivps_steps():
    A = np.array([[0.0, 1.0], [-4.0, -0.3]])
    sysm = hs.HybridSystem.from_functions(flow_map=lambda x: A @ x, state_dim=2)
    arc = hs.simulate(sysm, [1.0, 0.0], t_max=5.0, rtol=1e-10, atol=1e-12, method="DOP853")
    ref = solve_ivp(lambda t, x: A @ x, (0.0, 5.0), [1.0, 0.0], method="DOP853", rtol=1e-10,
                    atol=1e-12)
    np.testing.assert_array_equal(arc.t, ref.t)
    np.testing.assert_array_equal(arc.x, ref.y.T)
