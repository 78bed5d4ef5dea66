"""Work the engine skips: inputs a set or guard never reads, the second evaluation of a
guard-derived indicator, LinearInput's selection, LSODA's dense output without checks."""
import numpy as np
import pytest
from scipy.integrate import LSODA

import hybridsim as hs
from hybridsim.events import fast_dense, find_interior_event, nonnegative
from hybridsim.system import reads_input


class Sampler(hs.HybridSystem):
    """Holds its input u every `period` (a timer); its guard reads only the timer."""

    state_dim, input_dim = 2, 1

    def __init__(self, period):
        self.period = period

    def flow_map(self, x, t, j, u):
        return np.array([0.0, 1.0])

    def jump_guard(self, x, t, j, u):
        return x[1] - self.period

    def jump_map(self, x, t, j, u):
        return np.array([u[0], 0.0])


class ReadingSampler(Sampler):
    """The same, its guard reading u (with no effect on its value)."""

    def jump_guard(self, x, t, j, u):
        return x[1] - self.period + 0.0 * u[0]


def _loop(guard_reads_u, calls):
    plant = hs.LinearPlant(np.array([[0.0, 1.0], [-1.0, 0.0]]), C=np.array([[1.0, 0.0]]))
    wire = hs.LinearInput({"plant": None})

    def counted(t, y):
        calls.append(t)
        return wire(t, y)
    sampler = ReadingSampler(0.25) if guard_reads_u else Sampler(0.25)
    return hs.Interconnection({"plant": plant, "sampler": sampler},
                              inputs={"sampler": counted})


def test_reads_input_sees_the_fourth_parameter():
    assert not reads_input(lambda x, t, j, u: x[0])
    assert reads_input(lambda x, t, j, u: x[0] + u[0])
    assert reads_input(lambda x, t, j, u: [v for v in u])          # read inside a closure
    assert reads_input(lambda *a: a[0])                            # *args: cannot tell
    assert not reads_input(Sampler(1.0).jump_guard)
    assert reads_input(ReadingSampler(1.0).jump_guard)
    assert reads_input(Sampler(1.0).jump_map)

    class Call:
        def __call__(self, x, t, j, u):
            return x[0]
    assert reads_input(Call())                                     # not a function: assumed


def test_a_guard_that_ignores_u_is_run_without_computing_u():
    """Same arc; the input is computed only for the flows and jumps when the guard
    ignores it, and at every guard evaluation too when it reads it."""
    lean, full = [], []
    x0 = [1.0, 0.0, 0.0, 0.0]
    a = hs.simulate(_loop(False, lean), x0, t_max=2.0, rtol=1e-9, atol=1e-12)
    b = hs.simulate(_loop(True, full), x0, t_max=2.0, rtol=1e-9, atol=1e-12)
    assert a.jump_count == b.jump_count == 8
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.x, b.x)
    assert len(lean) < 0.7 * len(full)


def test_guard_derived_indicator_evaluates_the_guard_once_per_sample():
    """An excursion above the guard inside one step: the same bracket with the fused
    indicator, without the 3 evaluations of the indicator at the interior samples."""
    def sol(s):
        return np.array([2.0 * s - s * s])                         # apex 1 at s = 1
    seen = []

    def phi(s, y):
        seen.append(s)
        return y[0] - 1.5                                          # never reached
    plain = find_interior_event(sol, 0.0, 2.0, lambda s, y: phi(s, y) >= 0.0, phi)
    n_plain = len(seen)
    seen.clear()
    fused = find_interior_event(sol, 0.0, 2.0, nonnegative(phi), phi)
    assert plain is None and fused is None
    assert n_plain - len(seen) == 3                                # the interior samples

    def phi_hit(s, y):
        return y[0] - (1.0 - 1e-9)
    assert find_interior_event(sol, 0.0, 2.0, nonnegative(phi_hit), phi_hit) == \
        find_interior_event(sol, 0.0, 2.0, lambda s, y: phi_hit(s, y) >= 0.0, phi_hit)


def test_selection_wiring_equals_the_sum_of_products():
    rng = np.random.default_rng(3)
    S = np.zeros((5, 2))
    S[[0, 1], [1, 0]] = 1.0
    E = np.zeros((5, 3))
    E[[2, 3, 4], [0, 2, 1]] = 1.0
    w = hs.LinearInput({"a": S, "b": E})
    for y in ({"a": rng.standard_normal(2), "b": np.array([-0.0, 1.5, -2.0])},
              {"a": rng.standard_normal((4, 2)), "b": rng.standard_normal((4, 3))}):
        got = w(0.0, y)
        want = (y["a"] @ S.T + y["b"] @ E.T) if y["a"].ndim == 2 else S @ y["a"] + E @ y["b"]
        np.testing.assert_array_equal(got, want)
        assert np.array_equal(np.signbit(got), np.signbit(want))
    # a matrix that does not select keeps the products
    M = 0.5 * E
    w2 = hs.LinearInput({"a": S, "b": M})
    y = {"a": rng.standard_normal(2), "b": rng.standard_normal(3)}
    np.testing.assert_array_equal(w2(0.0, y), S @ y["a"] + M @ y["b"])


@pytest.mark.parametrize("t_end", [5.0, 40.0])
def test_lsoda_dense_output_evaluated_as_scipy_does(t_end):
    s = LSODA(lambda t, y: np.array([y[1], -np.sin(y[0]) - 0.1 * y[1] * t]), 0.0,
              np.array([1.0, 0.3]), t_end, rtol=1e-9, atol=1e-11)
    rng = np.random.default_rng(0)
    while s.status == "running":
        s.step()
        d = s.dense_output()
        f = fast_dense(d)
        for tt in np.r_[s.t_old, s.t, s.t_old + (s.t - s.t_old) * rng.random(3)]:
            np.testing.assert_array_equal(f(float(tt)), d(tt))
