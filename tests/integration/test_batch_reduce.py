"""``hs.simulate_many(..., stats=)``: a batch reduced into a Stats, no arc kept.

The compiled batch kernel keeps of each row only its end and its states on the
Stats's grid; the other paths reduce the rows' arcs. Both must give the Stats
that :meth:`Stats.update` gives on the rows' arcs (the reference: each row run
alone with ``hs.simulate``, keyed by the documented rule for rows that draw).

Tolerances: the compiled and Python paths run the same arithmetic up to the
order of a few sums, so means and variances agree to 1e-12 (measured: 1e-15 for
AIMD, 8e-14 for the bouncing ball); counts, exceedances and histograms exactly.
"""
from __future__ import annotations

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.estimate import Stats
from hybridsim.library import AIMD, BouncingBall


def _aimd_stats():
    return Stats(t=np.linspace(0.0, 20.0, 9), signal=0, thresholds=[1.0, 2.5],
                 bins=(0.0, 5.0, 20))


def _keys(seed, N):
    # simulate_many's documented rule: row i's key, the i-th word of the seed sequence's
    # state shifted right by one
    return np.random.SeedSequence(seed).generate_state(N, np.uint64) >> np.uint64(1)


def _same_stats(a, b, tol=1e-12):
    np.testing.assert_array_equal(a.count, b.count)
    np.testing.assert_allclose(a.mean, b.mean, rtol=0, atol=tol)
    np.testing.assert_allclose(a.variance, b.variance, rtol=0, atol=tol)
    np.testing.assert_array_equal(a.exceed, b.exceed)
    if a.hist is not None:
        np.testing.assert_array_equal(a.hist, b.hist)


@pytest.mark.paths(only=("python", "compiled"))
def test_rate_rows_reduced_equal_the_rows_arcs(path):
    # AIMD: the reduced batch is the Stats of the rows' own arcs, each row keyed by the
    # rule, on every path; the stats object is updated in place and returned
    N, seed = 60, 5
    st = _aimd_stats()
    out = hs.simulate_many(AIMD(), np.ones((N, 1)), 20.0, stats=st, seed=seed, backend=path)
    assert out is st and st.runs == N
    ref = _aimd_stats()
    ref.update([hs.simulate(AIMD(), [1.0], 20.0, seed=int(k)) for k in _keys(seed, N)])
    _same_stats(st, ref)
    assert st.count[-1] == N          # every row reaches t_max = 20, the grid's end


@pytest.mark.paths(only=("python", "compiled"))
def test_rate_rows_seeds_reproduce(path):
    # the same seed: the same statistics; another seed: others; row i's key does not
    # depend on the batch's size (the first 20 rows of 60 are a batch of 20)
    X = np.ones((60, 1))
    a = hs.simulate_many(AIMD(), X, 20.0, stats=_aimd_stats(), seed=7, backend=path)
    b = hs.simulate_many(AIMD(), X, 20.0, stats=_aimd_stats(), seed=7, backend=path)
    c = hs.simulate_many(AIMD(), X, 20.0, stats=_aimd_stats(), seed=8, backend=path)
    _same_stats(a, b, tol=0)
    assert not np.allclose(a.mean[1:], c.mean[1:])
    head = hs.simulate_many(AIMD(), X[:20], 20.0, stats=_aimd_stats(), seed=7, backend=path)
    ref = _aimd_stats()
    ref.update([hs.simulate(AIMD(), [1.0], 20.0, seed=int(k)) for k in _keys(7, 60)[:20]])
    _same_stats(head, ref)


def test_compiled_reduction_equals_the_python_and_vectorized_paths():
    # a system that draws nothing, on a time grid and on a grid of jump counts: the
    # compiled kernel's reduction (its grid states off the samples it drops) is the
    # Python path's and the vectorized path's Stats of the arcs
    X = np.column_stack([np.linspace(1.0, 3.0, 40), np.linspace(-1.0, 1.0, 40)])
    for make in (lambda: Stats(t=np.linspace(0.0, 3.0, 7), thresholds=[0.5]),
                 lambda: Stats(j=[0, 1, 2, 5], signal=1)):
        py = hs.simulate_many(BouncingBall(), X, 3.0, stats=make(), backend="python")
        co = hs.simulate_many(BouncingBall(), X, 3.0, stats=make(), backend="compiled")
        ve = hs.simulate_many(BouncingBall(vectorized=True), X, 3.0, stats=make())
        ref = make()
        ref.update(hs.simulate_many(BouncingBall(), X, 3.0))
        for s in (py, co, ve):
            _same_stats(s, ref, tol=1e-12)
        assert py.count[0] == len(X)


def test_reduction_bad_input_names_the_argument():
    X = np.ones((4, 1))
    with pytest.raises(TypeError, match=r"^stats must be a hybridsim\.estimate\.Stats"):
        hs.simulate_many(AIMD(), X, 1.0, stats=[1.0], seed=1)
    with pytest.raises(ValueError, match=r"^stats: its signal is component 3.*1 components"):
        hs.simulate_many(AIMD(), X, 1.0, stats=Stats(t=[0.0], signal=3), seed=1)
    wide = Stats(t=[0.0, 1.0])
    wide.add_values(np.zeros((1, 2, 2)))
    with pytest.raises(ValueError, match=r"^stats: it holds a signal of width 2"):
        hs.simulate_many(AIMD(), X, 1.0, stats=wide, seed=1)
    with pytest.raises(ValueError, match=r"^throw: simulate_many\(\.\.\., stats=\)"):
        hs.simulate_many(AIMD(), X, 1.0, stats=Stats(t=[0.0]), seed=1, throw=True)
    with pytest.raises(ValueError, match=r"seed must be >= 0"):
        hs.simulate_many(AIMD(), X, 1.0, stats=Stats(t=[0.0]), seed=-1, backend="compiled")


def test_compiled_reduce_bad_input_names_the_argument():
    pytest.importorskip("numba")
    from hybridsim.compiled import lower, simulate_many_compiled
    ball = lower(BouncingBall())
    X = np.array([[1.0, 0.0], [2.0, 0.0]])
    for bad, err, msg in (
            ([0.0, 1.0], TypeError, r"^reduce must be a tuple \(grid, by_j, components\), "
                                    r"got list of length 2"),
            ((np.ones((2, 2)), False, 1), ValueError, r"^reduce's grid must be a 1-D .*times"),
            (([1.0, 0.5], False, 1), ValueError, r"non-decreasing times"),
            (([0, 1.5], True, 1), ValueError, r"whole non-negative jump counts"),
            (([0.0], "no", 1), TypeError, r"^reduce's by_j must be True or False"),
            (([0.0], False, 0), ValueError, r"^reduce's components must be >= 1"),
            (([0.0], False, 3), ValueError, r"at most the state's dimension 2, got 3")):
        with pytest.raises(err, match=msg):
            simulate_many_compiled(ball, X, 1.0, reduce=bad)
    out = simulate_many_compiled(ball, X, 1.0, reduce=([0.0, 0.5], False, 1))
    np.testing.assert_array_equal(out.grid_x[:, 0, 0], X[:, 0])
    assert out.grid_ok.all() and out.grid_x.shape == (2, 2, 1)


@pytest.mark.paths(only=("python", "compiled"))
def test_reduction_failed_rows_are_named_and_counted(path):
    # a row whose x0 is not finite: named in one BatchWarning; the others are reduced
    X = np.ones((5, 1))
    X[2, 0] = np.nan
    st = Stats(t=[0.0, 5.0], signal=0)
    with pytest.warns(hs.BatchWarning, match=r"1 of 5 rows failed.*row 2: NON_FINITE"):
        hs.simulate_many(AIMD(), X, 5.0, stats=st, seed=3, backend=path)
    assert st.count.tolist() == [4, 4]


def test_rate_system_keeps_specialize():
    # the clock-augmented system of a rate system lowered with specialize=True is
    # specialised too (its kernel has the maps compiled in), and not otherwise
    from hybridsim.compiled import CompiledSystem
    from hybridsim.compiled._stochastic import _augmented
    for spec in (False, True):
        cs = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1),
                            jump_map=lambda x, t, j, p: x / 2,
                            jump_rate=lambda x, t, j, p: x[0], state_dim=1, specialize=spec)
        aug = _augmented(cs)
        assert aug.specialize is spec and aug.state_dim == 5


@pytest.mark.slow       # the specialised kernel: about 15 s of CPU once per machine
def test_specialised_rate_rows_reduce_as_the_python_path():
    from hybridsim.compiled import lower
    s = AIMD()
    lower(s, specialize=True)
    st = hs.simulate_many(s, np.ones((30, 1)), 20.0, stats=_aimd_stats(), seed=4,
                          backend="compiled")
    ref = _aimd_stats()
    ref.update([hs.simulate(AIMD(), [1.0], 20.0, seed=int(k)) for k in _keys(4, 30)])
    _same_stats(st, ref)
