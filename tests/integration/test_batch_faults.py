"""Batches under faults: failed rows, Ctrl-C, executors losing chunks, bad arguments.

What each fault gets (issue 16, "no silent failure"; issue 12, "Ctrl-C"):

* a map raising at a row's x0, a NaN row of x0s, ``make_system(p)`` or
  ``x0(p)`` raising: that row's arc is one sample at (t0, j0, x0) with cause
  ``MAP_ERROR`` / ``NON_FINITE`` and the error on ``arc.exception``; the
  other rows are kept; one ``BatchWarning`` names each failed row;
* a run failing mid-way (``MAP_ERROR``, ``NON_FINITE``): its arc so far;
* ``throw=True``: ``BatchError`` naming the first failed row;
* an executor losing a chunk: that chunk's rows fail, the others are kept;
* Ctrl-C (a map raising KeyboardInterrupt at the k-th run): finished runs
  kept, the k-th ends ``CANCELED`` with its arc so far, later rows get a
  one-sample ``CANCELED`` arc, one warning; serially, with an executor and
  in the vectorized path;
* bad arguments (``chunks``, ``executor``, ``params``, ragged ``x0s``, an
  unpicklable ``x0`` callable with a process pool): a clear error naming
  the argument.
"""
import warnings
from concurrent.futures import Future, ProcessPoolExecutor

import numpy as np
import pytest

import hybridsim as hs
from hybridsim import Termination
from hybridsim.batch import BatchError, BatchWarning
from hybridsim.batch_vectorized import simulate_vectorized


class Fragile(hs.HybridSystem):
    """x' = -x, x = (value, marker); marker' = 0 says what goes wrong.

    marker 1: flow_map raises at x0; marker 2: flow_map raises at t > 0.5;
    marker 3: KeyboardInterrupt at t > 0.5; marker 4: KeyboardInterrupt at x0;
    marker 5: flow_map returns NaN for t > 0.5.
    """

    state_dim = 2

    def flow_map(self, x, t):
        m = x[1]
        if m == 1:
            raise ZeroDivisionError("marker 1 at x0")
        if m == 2 and t > 0.5:
            raise RuntimeError("marker 2 mid-run")
        if m == 3 and t > 0.5:
            raise KeyboardInterrupt
        if m == 4:
            raise KeyboardInterrupt
        if m == 5 and t > 0.5:
            return np.array([np.nan, 0.0])
        return np.array([-x[0], 0.0])


def make_fragile(p):
    if p == "broken":
        raise LookupError("no such plant")
    return Fragile()


def x0_of(p):
    return [1.0, float(p) if p != "broken" else 0.0]


def run_quiet(fn, *args, **kw):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        out = fn(*args, **kw)
    return out, [x for x in w if issubclass(x.category, Warning)]


X0S = np.array([[1.0, 0.0], [2.0, 1.0], [np.nan, 0.0], [3.0, 2.0], [4.0, 5.0], [5.0, 0.0]])


def check_failed_rows(arcs, w):
    assert len(arcs) == 6
    assert [a.termination for a in arcs] == [
        Termination.T_MAX, Termination.MAP_ERROR, Termination.NON_FINITE,
        Termination.MAP_ERROR, Termination.NON_FINITE, Termination.T_MAX]
    # the good rows are exact
    for i in (0, 5):
        np.testing.assert_allclose(arcs[i].xf[0], X0S[i, 0] * np.exp(-1.0), rtol=1e-6)
    # failed at x0: one sample at (t0, j0, x0), the error kept
    for i in (1, 2):
        assert len(arcs[i]) == 1 and arcs[i].t[0] == 0.0 and arcs[i].j[0] == 0
        np.testing.assert_array_equal(arcs[i].x[0], X0S[i])
        assert isinstance(arcs[i].exception, Exception)
    assert isinstance(arcs[1].exception, hs.MapError)
    assert "flow_map raised ZeroDivisionError: marker 1 at x0" in arcs[1].message
    # failed mid-run: the arc so far
    assert 0 < arcs[3].tf <= 0.5 + 1e-9 and len(arcs[3]) > 1
    assert "marker 2 mid-run" in arcs[3].message
    assert 0 < arcs[4].tf < 0.6 and len(arcs[4]) > 1
    # one warning naming every failed row and its cause
    batch = [x for x in w if issubclass(x.category, BatchWarning)]
    assert len(batch) == 1 and len(w) == 1
    msg = str(batch[0].message)
    assert "4 of 6 runs failed" in msg
    for i, cause in ((1, "MAP_ERROR"), (2, "NON_FINITE"), (3, "MAP_ERROR"), (4, "NON_FINITE")):
        assert f"row {i}: {cause}" in msg
    assert "row 1: MAP_ERROR (flow_map raised ZeroDivisionError: marker 1 at x0" in msg


def test_simulate_many_keeps_going_serially():
    arcs, w = run_quiet(hs.simulate_many, Fragile(), X0S, t_max=1.0)
    check_failed_rows(arcs, w)
    assert isinstance(arcs[1].exception.__cause__, ZeroDivisionError)   # chained


def test_simulate_many_keeps_going_in_a_process_pool():
    with ProcessPoolExecutor(2) as ex:
        arcs, w = run_quiet(hs.simulate_many, Fragile(), X0S, t_max=1.0, executor=ex, chunks=3)
    check_failed_rows(arcs, w)


def test_throw_true_names_the_first_failed_row():
    with pytest.raises(BatchError, match=r"row 1 of the batch failed: MAP_ERROR") as info:
        hs.simulate_many(Fragile(), X0S, t_max=1.0, throw=True)
    assert info.value.row == 1 and info.value.arc.termination is Termination.MAP_ERROR
    assert info.value.arcs[0].termination is Termination.T_MAX
    assert isinstance(info.value, hs.SimulationError)
    with pytest.raises(BatchError, match="row 2 of the batch failed: NON_FINITE"):
        hs.simulate_many(Fragile(), X0S[[0, 0, 2]], t_max=1.0, throw=True)
    with pytest.raises(TypeError, match="throw must be True or False"):
        hs.simulate_many(Fragile(), X0S, t_max=1.0, throw="yes")


def test_warn_false_silences_the_summary():
    arcs, w = run_quiet(hs.simulate_many, Fragile(), X0S, t_max=1.0, warn=False)
    assert not w and arcs[2].termination is Termination.NON_FINITE


def test_sweep_rows_fail_on_their_own():
    params = [0.0, "broken", 1.0, 2.0]
    arcs, w = run_quiet(hs.sweep, make_fragile, params, x0_of, t_max=1.0)
    assert [a.termination for a in arcs] == [Termination.T_MAX, Termination.MAP_ERROR,
                                             Termination.MAP_ERROR, Termination.MAP_ERROR]
    assert isinstance(arcs[1].exception, LookupError)
    assert "make_system" in arcs[1].message or "p='broken'" in arcs[1].message
    assert len(arcs[2]) == 1 and len(arcs[3]) > 1
    (warning,) = w
    assert "row 1: MAP_ERROR (LookupError: no such plant)" in str(warning.message)
    # with a process pool and a (module-level) callable x0
    with ProcessPoolExecutor(2) as ex:
        arcs2, w2 = run_quiet(hs.sweep, make_fragile, params, x0_of, t_max=1.0, executor=ex)
    assert [a.termination for a in arcs2] == [a.termination for a in arcs]
    np.testing.assert_allclose(arcs2[0].xf, arcs[0].xf)
    assert len(w2) == 1


class LazyExecutor:
    """Runs a chunk when its result is asked for (so later chunks can be canceled)."""

    def __init__(self, fail_chunk=None):
        self.fail_chunk = fail_chunk
        self.calls = 0
        self.ran = 0

    def submit(self, fn, *args):
        k = self.calls
        self.calls += 1
        ex = self

        class Lazy(Future):
            def result(self, timeout=None):
                if not self.done():
                    ex.ran += 1
                    if k == ex.fail_chunk:
                        self.set_exception(OSError(f"worker {k} died"))
                    else:
                        self.set_result(fn(*args))
                return super().result(timeout)

        return Lazy()


def test_an_executor_losing_a_chunk_keeps_the_others():
    x0s = np.column_stack([np.arange(1.0, 7.0), np.zeros(6)])
    arcs, w = run_quiet(hs.simulate_many, Fragile(), x0s, t_max=1.0,
                        executor=LazyExecutor(fail_chunk=1), chunks=3)
    assert [a.termination.name for a in arcs] == ["T_MAX"] * 2 + ["MAP_ERROR"] * 2 + \
        ["T_MAX"] * 2
    assert isinstance(arcs[2].exception, OSError) and "worker 1 died" in arcs[2].message
    np.testing.assert_allclose(arcs[5].xf[0], 6 * np.exp(-1.0), rtol=1e-6)
    assert "row 2: MAP_ERROR" in str(w[0].message) and "row 3: MAP_ERROR" in str(w[0].message)


def test_an_executor_failing_everywhere_raises():
    with pytest.raises(OSError, match="worker 0 died"):
        hs.simulate_many(Fragile(), np.zeros((2, 2)), t_max=1.0,
                         executor=LazyExecutor(fail_chunk=0), chunks=1)


# ------------------------------------------------------------------ Ctrl-C
def check_canceled(arcs, w, k, n):
    assert len(arcs) == n
    for i in range(k):
        assert arcs[i].termination is Termination.T_MAX
    assert arcs[k].termination is Termination.CANCELED
    for i in range(k + 1, n):
        assert arcs[i].termination is Termination.CANCELED and len(arcs[i]) == 1
        assert arcs[i].t[0] == 0.0
    (warning,) = w
    assert issubclass(warning.category, BatchWarning)
    assert "interrupted (KeyboardInterrupt)" in str(warning.message)
    assert f"{k} of {n} runs finished" in str(warning.message)


@pytest.mark.parametrize("marker", [3.0, 4.0])
def test_ctrl_c_serially_keeps_finished_runs(marker):
    x0s = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, marker], [4.0, 0.0], [5.0, 0.0]])
    arcs, w = run_quiet(hs.simulate_many, Fragile(), x0s, t_max=1.0)
    check_canceled(arcs, w, 2, 5)
    if marker == 3.0:                  # interrupted mid-run: the arc so far
        assert 0 < arcs[2].tf <= 0.5 + 1e-9 and len(arcs[2]) > 1
    else:                              # at x0: one sample there
        assert len(arcs[2]) == 1
        np.testing.assert_array_equal(arcs[2].x0, x0s[2])
    np.testing.assert_array_equal(arcs[4].x0, x0s[4])


def test_ctrl_c_in_sweep():
    arcs, w = run_quiet(hs.sweep, make_fragile, [0, 0, 0, 3, 0], x0_of, t_max=1.0)
    check_canceled(arcs, w, 3, 5)


def test_ctrl_c_in_a_worker_stops_launching_chunks():
    x0s = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 3.0], [4.0, 0.0], [5.0, 0.0], [6.0, 0.0]])
    ex = LazyExecutor()
    arcs, w = run_quiet(hs.simulate_many, Fragile(), x0s, t_max=1.0, executor=ex, chunks=3)
    check_canceled(arcs, w, 2, 6)
    assert ex.ran == 2              # the third chunk was never run


class VecFragile(hs.HybridSystem):
    """Vectorized x' = -x; KeyboardInterrupt once t > 0.5; rows with x0 < 0 stop at once."""

    state_dim = 1
    vectorized = True

    def flow_map(self, x, t):
        if np.any(t > 0.5):
            raise KeyboardInterrupt
        return -x

    def flow_set(self, x):
        return x[:, 0] >= 0


def test_ctrl_c_in_the_vectorized_path():
    x0s = [[1.0], [-1.0], [2.0]]
    arcs, w = run_quiet(hs.simulate_many, VecFragile(), x0s, t_max=1.0)
    assert [a.termination.name for a in arcs] == ["CANCELED", "NOT_IN_SETS", "CANCELED"]
    assert 0.3 < arcs[0].tf <= 0.5 + 1e-9 and len(arcs[0]) > 1
    np.testing.assert_allclose(arcs[0].xf, np.exp(-arcs[0].tf), rtol=1e-5)
    assert "at t=" in arcs[0].message
    (warning,) = w
    assert "rows 0, 2 end with CANCELED" in str(warning.message)


# ------------------------------------------------------------------ vectorized rows
class VecBall(hs.HybridSystem):
    """Vectorized timer-like system; jump_map raises on rows with x0[1] == 1 at x0."""

    state_dim = 2
    vectorized = True

    def flow_map(self, x):
        if np.any(x[:, 1] == 1):
            raise ValueError("row with marker 1")
        return np.column_stack([np.ones(len(x)), np.zeros(len(x))])

    def jump_map(self, x):
        return np.column_stack([np.zeros(len(x)), x[:, 1]])

    def jump_guard(self, x):
        return x[:, 0] - 1.0

    def flow_guard(self, x):
        return 1.0 - x[:, 0]


def test_vectorized_path_isolates_failed_rows_at_x0():
    x0s = np.array([[0.0, 0.0], [0.2, 1.0], [np.nan, 0.0], [0.5, 0.0]])
    arcs, w = run_quiet(hs.simulate_many, VecBall(), x0s, t_max=2.2)
    assert [a.termination.name for a in arcs] == ["T_MAX", "MAP_ERROR", "NON_FINITE", "T_MAX"]
    ref = simulate_vectorized(VecBall(), x0s[[0, 3]], t_max=2.2)
    for got, exp in zip((arcs[0], arcs[3]), ref, strict=True):
        np.testing.assert_array_equal(got.t, exp.t)
        np.testing.assert_array_equal(got.x, exp.x)
    assert len(arcs[1]) == 1 and "row with marker 1" in arcs[1].message
    (warning,) = w
    assert "row 1: MAP_ERROR" in str(warning.message)
    assert "row 2: NON_FINITE" in str(warning.message)
    with pytest.raises(BatchError, match="row 1 of the batch failed"):
        hs.simulate_many(VecBall(), x0s, t_max=2.2, throw=True)


# ------------------------------------------------------------------ arguments
@pytest.mark.parametrize("kw, exc, match", [
    (dict(chunks=-1), ValueError, r"chunks must be a positive int or None .*got -1"),
    (dict(chunks=0), ValueError, r"chunks must be a positive int.*got 0"),
    (dict(chunks=2.5), TypeError, r"chunks must be a positive int or None.*float 2.5"),
    (dict(chunks=True), TypeError, r"chunks must be a positive int.*bool True"),
    (dict(executor="threads"), TypeError,
     r"executor must be a concurrent.futures.Executor \(an object with a \.submit.*'threads'"),
    (dict(progress="yes"), TypeError, r"progress must be True, False or None"),
])
def test_bad_batch_options(kw, exc, match):
    with pytest.raises(exc, match=match):
        hs.simulate_many(Fragile(), np.zeros((2, 2)), t_max=1.0, **kw)
    with pytest.raises(exc, match=match):
        hs.sweep(make_fragile, [0, 0], [0.0, 0.0], t_max=1.0, **kw)


def test_bad_sweep_params_and_x0():
    with pytest.raises(TypeError, match=r"params must be an iterable of parameter values.*int 5"):
        hs.sweep(make_fragile, 5, [0.0, 0.0], t_max=1.0)
    with pytest.raises(TypeError, match=r"params must be an iterable.*str 'abc'"):
        hs.sweep(make_fragile, "abc", [0.0, 0.0], t_max=1.0)
    assert hs.sweep(make_fragile, [], [0.0, 0.0], t_max=1.0) == []
    with ProcessPoolExecutor(1) as ex:
        with pytest.raises(TypeError, match=r"x0: a callable p -> x0 .* must pickle"):
            hs.sweep(make_fragile, [0, 1], lambda p: [1.0, 0.0], t_max=1.0, executor=ex)


def test_ragged_x0s_named():
    with pytest.raises(ValueError, match=r"x0s must be a rectangular array of shape \(N, 2\).*"
                                         r"row 1 has shape \(3,\)"):
        hs.simulate_many(Fragile(), [[1.0, 0.0], [1.0, 0.0, 2.0], [0.0, 0.0]], t_max=1.0)
    with pytest.raises(ValueError, match=r"x0s must have shape \(N, 2\), got \(2, 3\)"):
        hs.simulate_many(Fragile(), np.zeros((2, 3)), t_max=1.0)
    with pytest.raises(TypeError, match="x0s must be real"):
        hs.simulate_many(Fragile(), np.zeros((2, 2)) * 1j, t_max=1.0)
    assert hs.simulate_many(Fragile(), np.zeros((0, 2)), t_max=1.0) == []


def test_argument_errors_raise_at_once():
    """A bad simulate option is the same for every row: it raises, not a failed row."""
    with pytest.raises(ValueError, match="rtol") as info:
        hs.simulate_many(Fragile(), np.zeros((3, 2)), t_max=1.0, rtol=-1.0)
    assert "row 0 of the batch" in info.value.__notes__[0]
    with pytest.raises(ValueError, match=r"x0 must have shape \(2,\)") as info:
        hs.sweep(make_fragile, [0, 1], [1.0, 0.0, 0.0], t_max=1.0)
    assert "row 0 of the batch" in info.value.__notes__[0]


def test_ctrl_c_in_a_process_pool_worker_keeps_the_rest():
    x0s = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 3.0], [4.0, 0.0], [5.0, 0.0], [6.0, 0.0]])
    with ProcessPoolExecutor(2) as ex:
        arcs, w = run_quiet(hs.simulate_many, Fragile(), x0s, t_max=1.0, executor=ex, chunks=3)
    assert [a.termination.name for a in arcs[:4]] == ["T_MAX", "T_MAX", "CANCELED", "CANCELED"]
    assert len(arcs[2]) > 1 and len(arcs[3]) == 1          # so far / never started
    # the last chunk may have run before the interruption was seen: kept if so
    assert all(a.termination.name in ("T_MAX", "CANCELED") for a in arcs[4:])
    np.testing.assert_allclose(arcs[1].xf[0], 2 * np.exp(-1.0), rtol=1e-6)
    (warning,) = w
    assert "interrupted (KeyboardInterrupt)" in str(warning.message)
