"""History: delayed values and window integrals, exact to the dense output."""
import numpy as np
import pytest

import hybridsim as hs


class DDE(hs.HybridSystem):
    """x'(t) = -x(t - 1), x = 1 on [-1, 0]."""

    state_dim = 1
    max_step = 1.0
    needs_history = True
    delays = (1.0,)

    def flow_map(self, x, t):
        return -self.history(t - 1.0)


def dde_exact(t):
    """Method of steps on [0, 3]: piecewise polynomial."""
    if t <= 1:
        return 1 - t
    if t <= 2:
        return 1 - t + (t - 1) ** 2 / 2
    return 1 - t + (t - 1) ** 2 / 2 - (t - 2) ** 3 / 6


def test_dde_against_method_of_steps():
    arc = hs.simulate(DDE(), [1.0], t_max=3.0, rtol=1e-10, atol=1e-12, dense=True)
    ts = np.linspace(0, 3, 301)
    err = max(abs(arc.at(t)[0] - dde_exact(t)) for t in ts)
    # delays = (1.0,) makes the engine stop the flow at the breaking points
    # t = 1, 2 where the solution's derivatives jump: no step straddles a
    # kink, so the error is that of the integrator (rtol 1e-10).
    assert err < 1e-9


def test_prehistory_function_is_used():
    sysm = DDE()
    # x = 1 + s on [-1, 0): x'(t) = -(t) on [0, 1] -> x(1) = 1 - 1/2
    arc = hs.simulate(sysm, [1.0], t_max=1.0, prehistory=lambda s: np.array([1.0 + s]),
                      rtol=1e-10, atol=1e-12)
    assert abs(arc.xf[0] - 0.5) < 1e-9


class DelayedTimer(hs.HybridSystem):
    """tau: timer of period 1; s' = tau(t - 0.5) (the delayed value crosses jumps)."""

    state_dim = 2
    max_step = 0.5
    needs_history = True
    delays = (0.5,)

    def flow_map(self, x, t):
        return np.array([1.0, self.history(t - 0.5)[0]])

    def jump_map(self, x):
        return np.array([0.0, x[1]])

    def jump_guard(self, x):
        return x[0] - 1.0

    def flow_guard(self, x):
        return 1.0 - x[0]


def test_delay_across_jumps():
    sysm = DelayedTimer()
    arc = hs.simulate(sysm, [0.0, 0.0], t_max=3.0, rtol=1e-10, atol=1e-12)
    # s(3) = 0 + 1/2 + 1/2 + 1/8 (the delayed timer is a sawtooth)
    assert abs(arc.xf[1] - 1.125) < 1e-9
    h = sysm.history
    tj = arc.jump_times[0]
    assert abs(tj - 1.0) < 1e-12
    assert h(tj)[0] == 0.0                       # post-jump value at a jump time
    assert abs(h(0.999)[0] - 0.999) < 1e-12      # before it: the flow
    assert h(-0.3)[0] == 0.0                     # constant prehistory x0
    assert h.jump_count(1.5) == 1
    # integral of tau over [0.5, 2.5] = 1/2 * 2 - ... exactly 1.0
    assert abs(h.integral(lambda x, s: x[0], 0.5, 2.5) - 1.0) < 1e-12


def test_history_beyond_the_current_step_is_an_error():
    class Bad(hs.HybridSystem):
        state_dim = 1
        needs_history = True

        def flow_map(self, x, t):
            return -self.history(t - 0.01)
    with pytest.raises(hs.MapError, match="flow_map raised HistoryError.*max_step") as info:
        hs.simulate(Bad(), [1.0], t_max=2.0)
    assert isinstance(info.value.__cause__, hs.HistoryError)
    arc = hs.simulate(Bad(), [1.0], t_max=2.0, throw=False)
    assert arc.termination is hs.Termination.MAP_ERROR
    assert isinstance(arc.exception.__cause__, hs.HistoryError)
    assert "max_step" in arc.message
    # with the step capped it runs
    arc = hs.simulate(Bad(), [1.0], t_max=2.0, max_step=0.01)
    assert arc.success


def test_history_output_and_input_of_a_component():
    class Delay(hs.HybridSystem):
        """z' = u(t - 0.5): integrates the plant's delayed output."""

        state_dim = 1
        input_dim = 1
        max_step = 0.5
        needs_history = True

        def flow_map(self, z, t, j, u):
            return np.atleast_1d(self.history.input(t - 0.5))

    plant = hs.HybridSystem.from_functions(flow_map=lambda x: np.array([1.0]), state_dim=1)
    sysm = hs.connect(plant, Delay())
    arc = hs.simulate(sysm, [0.0, 0.0], t_max=2.0, rtol=1e-10, atol=1e-12, dense=True)
    # y(s) = s for s >= 0, constant x0 = 0 before: z(2) = (2 - 0.5)^2 / 2
    assert abs(arc["observer"].xf[0] - 1.125) < 1e-9
    obs = sysm.systems["observer"]
    assert abs(obs.history.output(1.0)[0] - arc["observer"].at(1.0)[0]) < 1e-6


@pytest.mark.parametrize("method", ["RK45", "DOP853", "Radau", "LSODA"])
def test_history_covers_the_flow_up_to_the_jump_time(method):
    # a delayed read landing between the located bracket's ends (a few ulp
    # before the jump) must find the flow that led to the jump
    class S(hs.HybridSystem):
        state_dim = 2
        max_step = 0.1
        needs_history = True

        def flow_map(self, x, t):
            return np.array([1.0, -self.history(t - 0.1)[1] if t >= 0.1 else -x[1]])

        def jump_guard(self, x, t):
            return x[0] - 0.1

        def jump_map(self, x, t):
            return np.array([0.0, x[1]])

    arc = hs.simulate(S(), [0.1, 1.0], t_max=1.0, j_max=100, rtol=1e-8, method=method)
    assert arc.termination is hs.Termination.T_MAX, arc.message


def test_batch_history_reads_and_integrates_each_rows_past():
    """BatchHistory with hand-made steps: row 0 has x(s) = s^2 on [0, 1], row 1
    x(s) = 1 + s on [0, 0.5] and 3 s on [0.5, 1] (a jump at 0.5); before t0 = 0
    each row's x0. Values, jump counts and Gauss-Legendre integrals (exact for
    these polynomials), vector-valued integrands, reversed bounds, and a window
    past the recorded run (HistoryError)."""
    from hybridsim import BatchHistory, HistoryError
    X0 = np.array([[0.0], [1.0]])
    h = BatchHistory(0.0, X0, 0)
    q2 = np.zeros((1, 1, 4))
    q2[0, 0, 1] = 1.0                          # x = ya + h (s')^2, s' = (s - a) / h
    h._add(np.array([0]), np.array([0.0]), np.array([1.0]), np.array([0]), np.array([1.0]),
           np.array([[0.0]]), q2)
    q1 = np.zeros((1, 1, 4))
    q1[0, 0, 0] = 1.0                          # x = ya + h s'
    h._add(np.array([1]), np.array([0.0]), np.array([0.5]), np.array([0]), np.array([0.5]),
           np.array([[1.0]]), q1)
    h._add(np.array([1]), np.array([0.5]), np.array([1.0]), np.array([1]), np.array([0.5]),
           np.array([[1.5]]), q1 * 3.0)
    h._restart(np.array([1]), np.array([0.5]), np.array([[1.5]]), np.array([1]))
    h.rows = np.array([0, 1])
    np.testing.assert_allclose(h(np.array([0.5, 0.25])), [[0.25], [1.25]])
    np.testing.assert_allclose(h(-1.0), X0)                       # the constant past
    np.testing.assert_allclose(h(np.array([0.75, 0.75])), [[0.5625], [2.25]])
    assert h.jump_count(np.array([0.25, 0.75])).tolist() == [0, 1]
    # int_{-1}^{1} x: row 0: 0 + 1/3; row 1: 1 (past) + [s + s^2/2]_0^0.5 + [3 s^2/2]_0.5^1
    want = np.array([1 / 3, 1.0 + 0.625 + 1.125])
    np.testing.assert_allclose(h.integral(lambda x, s: x[:, 0], -1.0, 1.0), want, rtol=1e-14)
    np.testing.assert_allclose(h.integral(lambda x, s: x[:, 0], 1.0, -1.0), -want, rtol=1e-14)
    two = h.integral(lambda x, s: np.column_stack([x[:, 0], s]), np.array([0.0, 0.5]), 1.0)
    np.testing.assert_allclose(two, [[1 / 3, 0.5], [1.125, 0.375]], rtol=1e-14)
    with pytest.raises(HistoryError, match="reaches past the recorded run"):
        h.integral(lambda x, s: x[:, 0], 0.0, 1.5)
