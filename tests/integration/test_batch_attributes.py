"""A batch whose rows set the system's attributes (``simulate_many(..., attributes=)``):
every path runs row i as a single run with its attributes set, the compiled path
as one parallel kernel call with a ``p`` per row; the system's attributes are as
they were afterwards; a part's attribute changed between runs of an
interconnection is seen by the next compiled run."""
from __future__ import annotations

import concurrent.futures

import numpy as np
import pytest
from paths import HAS_NUMBA, NO_NUMBA

import hybridsim as hs
from hybridsim.library import BouncingBall

needs_numba = pytest.mark.skipif(not HAS_NUMBA, reason=NO_NUMBA)
ES = np.linspace(0.5, 0.9, 9)


def _backend(path):
    return "compiled" if path == "compiled" else "python"


def test_rows_run_with_their_own_attributes(path):
    """Row i equals a single run of a ball with row i's restitution, on the
    same path, to the bit; the system's restitution is as it was."""
    ball = BouncingBall(vectorized=path == "vectorized")
    X = np.tile([1.0, 0.0], (len(ES), 1))
    rows = [{"e": float(e)} for e in ES]
    B = hs.simulate_many(ball, X, 3.0, 8, attributes=rows, backend=_backend(path))
    assert ball.e == 0.8 and "e" in vars(ball)
    for e, a in zip(ES, B):
        one = BouncingBall(restitution=float(e), vectorized=path == "vectorized")
        r = hs.simulate(one, [1.0, 0.0], 3.0, 8, backend=_backend(path))
        np.testing.assert_array_equal(a.x, r.x)
        np.testing.assert_array_equal(a.t, r.t)
    # the bounce heights fall by e^2 a bounce: the rows differ as their e
    h1 = np.array([a.x[a.j == 2][0, 1] ** 2 / (2 * 9.81) for a in B])
    np.testing.assert_allclose(h1, ES ** 4, rtol=1e-6)


@needs_numba
def test_compiled_rows_are_one_batch_with_a_p_per_row():
    """A CompiledSystem's rows set its ``params``: the batch kernel reads row
    i's p (simulate_many_compiled's ``params``), equal to single runs; bad
    ``params`` are refused naming the argument."""
    from hybridsim.compiled import CompiledSystem, simulate_compiled, simulate_many_compiled
    timer = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1),
                           jump_map=lambda x, t, j, p: np.zeros(1),
                           jump_guard=lambda x, t, j, p: x[0] - p[0], state_dim=1, params=[1.0])
    periods = np.array([0.3, 0.7, 1.1, 0.45])
    B = hs.simulate_many(timer, np.zeros((4, 1)), 2.0, attributes=[{"params": [T]}
                                                                   for T in periods])
    assert timer.params.tolist() == [1.0]
    for T, a in zip(periods, B):
        np.testing.assert_allclose(np.diff(np.r_[0.0, a.jump_times]), T, rtol=0, atol=1e-12)
        timer.params = [T]
        np.testing.assert_array_equal(a.x, simulate_compiled(timer, [0.0], 2.0).x)
    timer.params = [1.0]
    with pytest.raises(ValueError, match=r"params must have shape \(N, len\(system.params\)\)"):
        simulate_many_compiled(timer, np.zeros((4, 1)), 2.0, params=np.ones((3, 1)))
    with pytest.raises(ValueError, match="params must be finite"):
        simulate_many_compiled(timer, np.zeros((2, 1)), 2.0, params=[[1.0], [np.nan]])


@pytest.mark.parametrize("bad, match", [
    ({"e": 0.5}, "a sequence of dicts"),
    ([{"e": 0.5}], "one dict per row of x0s: 2 rows, got 1"),
    ([{"e": 0.5}, 0.7], r"attributes\[1\] must be a dict"),
    ([{"e": 0.5}, {3: 0.7}], "attribute names must be identifiers"),
])
def test_bad_attributes_are_named(bad, match):
    with pytest.raises((TypeError, ValueError), match=match):
        hs.simulate_many(BouncingBall(), [[1.0, 0.0], [2.0, 0.0]], 1.0, attributes=bad)


def test_rows_over_an_executor_run_on_copies():
    """Threads share the system: each row runs on a copy with its attributes
    (its arc's system), the system untouched."""
    ball = BouncingBall()
    X = np.tile([1.0, 0.0], (len(ES), 1))
    rows = [{"e": float(e)} for e in ES]
    with concurrent.futures.ThreadPoolExecutor(2) as ex:
        B = hs.simulate_many(ball, X, 3.0, 8, attributes=rows, executor=ex, chunks=3)
    ref = hs.simulate_many(ball, X, 3.0, 8, attributes=rows, backend="python")
    for a, r, e in zip(B, ref, ES):
        np.testing.assert_array_equal(a.x, r.x)
        assert a.system.e == e
    assert ball.e == 0.8


def test_reduced_rows_take_their_attributes(path):
    """``stats=`` with ``attributes``: the mean height after the first bounce over
    the rows is the mean of e^2 (the ball from rest at 1 m, its speed after the
    bounce e sqrt(2 g)): exact to the integrator's tolerance."""
    from hybridsim.estimate import Stats
    ball = BouncingBall(vectorized=path == "vectorized")
    X = np.tile([1.0, 0.0], (len(ES), 1))
    st = hs.simulate_many(ball, X, 10.0, 1, attributes=[{"e": float(e)} for e in ES],
                          backend=_backend(path), rtol=1e-10, atol=1e-12,
                          stats=Stats(j=[1], signal=lambda x: x[..., 1:2]))
    v = np.sqrt(2 * 9.81)
    np.testing.assert_allclose(st.mean[0, 0], np.mean(ES * v), rtol=1e-8)


class _Poisson(hs.HybridSystem):
    """x' = 1; x -> x/2 at the constant rate ``c``."""

    state_dim = 1

    def __init__(self, c):
        self.c = c

    def flow_map(self, x):
        return np.ones_like(x)

    def jump_map(self, x):
        return x / 2

    def jump_rate(self, x):
        return self.c + 0.0 * x[0]


@needs_numba
def test_a_rate_read_from_an_attribute_changes_with_it():
    """A rate read from an attribute changed between two compiled batches: the
    second batch jumps at the new rate (the rate's clock system reads the
    parameters again), and rows of their own rates in one batch."""
    s = _Poisson(1.0)
    N = 1000
    X = np.ones((N, 1))
    a = hs.simulate_many(s, X, 50.0, backend="compiled")
    s.c = 2.0
    b = hs.simulate_many(s, X, 50.0, backend="compiled")
    # Poisson counts over 50 s: mean 50 c, standard error sqrt(50 c / N); 5 of them
    assert abs(a.jump_counts.mean() - 50.0) < 5 * np.sqrt(50.0 / N)
    assert abs(b.jump_counts.mean() - 100.0) < 5 * np.sqrt(100.0 / N)
    rows = hs.simulate_many(s, X, 50.0, backend="compiled",
                            attributes=[{"c": 1.0 + (i % 2)} for i in range(N)])
    for r in (0, 1):
        m = rows.jump_counts[r::2].mean()
        assert abs(m - 50.0 * (1 + r)) < 5 * np.sqrt(50.0 * (1 + r) / (N / 2))
    assert s.c == 2.0


class _Decay(hs.HybridSystem):
    state_dim = 1

    def __init__(self, a):
        self.a = a

    def flow_map(self, x):
        return -self.a * x

    def jump_set(self, x):
        return False

    def jump_map(self, x):
        return x


@needs_numba
def test_a_parts_attribute_changed_between_runs_is_seen_compiled():
    """An interconnection lowered once: a part's attribute changed afterwards
    reaches the next compiled run (its parameters read again at each run,
    nothing recompiled), as on the Python path."""
    d = _Decay(1.0)
    ic = hs.Interconnection({"d": d, "b": BouncingBall()})
    ends = {}
    for be in ("compiled", "python"):
        for a in (1.0, 2.0):
            d.a = a
            ends[be, a] = hs.simulate(ic, [1.0, 1.0, 0.0], 1.0, backend=be,
                                      rtol=1e-10, atol=1e-12).xf[0]
    for a in (1.0, 2.0):
        np.testing.assert_allclose(ends["compiled", a], np.exp(-a), rtol=1e-8)
        np.testing.assert_allclose(ends["python", a], np.exp(-a), rtol=1e-8)


@needs_numba
def test_a_compiled_systems_specialize_is_checked_and_keeps_what_was_compiled():
    """``specialize`` set again to its value keeps the compiled maps (nothing
    compiles); a value that is not a bool is refused naming it, on the
    constructor and on the attribute."""
    from hybridsim.compiled import CompiledSystem
    timer = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1), state_dim=1)
    timer.compile()
    timer.specialize = False
    assert timer.compile() == 0.0
    with pytest.raises(TypeError, match="specialize must be True or False, got 'yes'"):
        timer.specialize = "yes"
    with pytest.raises(TypeError, match="specialize must be True or False, got 1"):
        CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1), state_dim=1, specialize=1)


class _Noisy(hs.HybridSystem):
    """dx = -x dt + s dW: the noise's scale an attribute."""

    state_dim = 1

    def __init__(self, s):
        self.s = s

    def flow_map(self, x):
        return -x

    def diffusion(self, x):
        return self.s + 0.0 * x


@pytest.mark.paths(only=("python", "compiled"))
def test_sde_rows_take_their_own_attributes(path):
    """SDE rows of their own noise scale: each row replays on the Python path
    from its recorded seed with its scale set (to 1e-12: the same arithmetic),
    and a scale of 0 gives the noiseless flow, e^-t, to the method's
    (Euler's, dt = 0.01) error."""
    s = _Noisy(1.0)
    scales = [0.0, 0.5, 2.0, 0.0]
    B = hs.simulate_many(s, np.ones((4, 1)), 1.0, method="EM", max_step=0.01, backend=path,
                         attributes=[{"s": c} for c in scales])
    assert s.s == 1.0
    for a, c in zip(B, scales):
        ref = hs.simulate(_Noisy(c), [1.0], 1.0, method="EM", max_step=0.01,
                          seed=a.stats["noise_seed"])
        np.testing.assert_allclose(a.x, ref.x, rtol=0, atol=1e-12)
    for a in (B[0], B[3]):
        assert abs(a.xf[0] - np.exp(-1.0)) < 0.01      # Euler: (1 - 0.01)^100 vs e^-1
