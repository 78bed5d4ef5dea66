"""The compiled path's smoke set: part of the default test command (not slow).

A few systems through ``hybridsim.compiled`` against the Python path and
closed forms: the docs' example (the ball, run as docs/compiled.rst prints it), a timer
with a jump at t_max, NaN guards and overflow, a batch with bad rows, Ctrl-C,
and the arcs' stats and xdot. On a fresh numba cache the engine's kernels
compile first (under a minute on two cores); afterwards the set takes seconds.
The full comparison is tests/integration/test_compiled.py (marked slow).
"""
import math
import re
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest

numba = pytest.importorskip("numba", reason="the compiled path needs numba "
                                            "(pip install 'hybridsim[fast]')")

import hybridsim as hs  # noqa: E402
from hybridsim.compiled import CompiledSystem, simulate_compiled, simulate_many_compiled  # noqa: E402
from hybridsim.library import bouncing_ball_jump_times  # noqa: E402

T = hs.Termination
PAGE = Path(__file__).resolve().parents[2] / "docs" / "compiled.rst"


def readme_example():
    """The first python block of the compiled path's docs page."""
    import textwrap

    text = PAGE.read_text(encoding="utf-8")
    block = re.search(r"^\.\. code-block:: python\n\n((?:   .*\n|\n)+)", text, re.M)
    return textwrap.dedent(block.group(1))


# ------------------------------------------------------------------ maps
def one(x, t, j, p):
    return np.ones(1)


def zero(x, t, j, p):
    return np.zeros(1)


def half(x, t, j, p):
    return x[0] - 0.5


def nan_near_jump(x, t, j, p):
    """A jump guard that breaks its contract (NaN) as the timer nears its jump."""
    return np.nan if x[0] > 0.9 else x[0] - 1.0


def ball_f(x, t, j, p):
    return np.array([x[1], -9.81])


def ball_f_bad_high(x, t, j, p):
    """The ball's flow map, non-finite above 5 m (fails at such an x0)."""
    if x[0] > 5.0:
        return np.array([np.nan, np.nan])
    return np.array([x[1], -9.81])


def ball_g(x, t, j, p):
    return np.array([0.0, -0.8 * x[1]])


def ball_hD(x, t, j, p):
    return -x[0]


def ball_hC(x, t, j, p):
    return x[0]


def ball_D(x, t, j, p):
    return x[0] <= 0.0 and x[1] <= 0.0


@pytest.fixture(scope="module")
def readme():
    """The compiled page's example, run as printed: its namespace after the run."""
    ns = {}
    exec(compile(readme_example(), str(PAGE), "exec"), ns)
    return ns


@pytest.fixture(scope="module")
def timer():
    return CompiledSystem(one, zero, jump_guard=half, state_dim=1)


@pytest.fixture(scope="module")
def ball_bad():
    return CompiledSystem(ball_f_bad_high, ball_g, jump_guard=ball_hD, flow_guard=ball_hC,
                          jump_set=ball_D, state_dim=2)


# ------------------------------------------------------------------ the page's example
@pytest.mark.slow
def test_readme_example_runs_and_bounces_right(readme):
    arc, arcs, x0s = readme["arc"], readme["arcs"], readme["x0s"]
    assert arc.termination is T.J_MAX and arc.jump_count == 30
    np.testing.assert_allclose(arc.jump_times, bouncing_ball_jump_times(1.0, 30), rtol=0,
                               atol=1e-9)
    assert len(arcs) == len(x0s)
    jt = np.array([a.jump_times for a in arcs])
    np.testing.assert_allclose(jt, bouncing_ball_jump_times(x0s[:, 0], 10), rtol=0, atol=1e-9)


def test_arcs_carry_stats_and_xdot_as_the_python_path(readme):
    ball = readme["ball"]
    a = simulate_compiled(ball, [1.0, 0.0], t_max=2.0, j_max=3)
    b = hs.simulate(ball, [1.0, 0.0], t_max=2.0, j_max=3)
    assert list(a.stats) == list(b.stats)
    assert a.stats["steps"] > 0 and a.stats["events"] == 3 and a.stats["flows"] == 3
    assert a.xdot is not None and a.xdot.shape == a.x.shape
    np.testing.assert_allclose(a.xdot[:, 0], a.x[:, 1], atol=1e-9)
    np.testing.assert_allclose(a.xdot[:, 1], -9.81, atol=1e-9)


def test_batch_arcs_made_on_first_access_are_whole_arcs(readme, monkeypatch):
    """A batch's plain rows (T_MAX, J_MAX) are pooled arcs: their samples and
    stats are sliced from the batch's pool on first access (the suite validates
    every arc at once, HYBRIDSIM_CHECK_ARCS: here they stay pooled until read).
    Read, copied, deep-copied or pickled before any access, each is the single
    run's arc to the bit."""
    import copy
    import pickle

    import hybridsim.arc as arc_mod
    monkeypatch.setattr(arc_mod, "CHECK_ARCS", False)
    ball = readme["ball"]
    x0s = np.column_stack([np.linspace(0.5, 2.0, 40), np.zeros(40)])
    kw = dict(t_max=20.0, j_max=4, rtol=1e-10, atol=1e-12)
    arcs = simulate_many_compiled(ball, x0s, **kw)
    rows = [i for i, a in enumerate(arcs) if "_pool" in a.__dict__]
    assert len(rows) >= 30            # every row but the few run alone first
    r = rows[:5]
    read = [arcs[r[0]], copy.copy(arcs[r[1]]), copy.deepcopy(arcs[r[2]]),
            pickle.loads(pickle.dumps(arcs[r[3]]))]
    assert all("_pool" not in arcs[i].__dict__ for i in r[1:4])   # copy, pickle: unpooled
    for i, a in zip(r, read):
        single = simulate_compiled(ball, x0s[i], **kw)
        for f in ("t", "j", "x", "xdot"):
            np.testing.assert_array_equal(getattr(a, f), getattr(single, f))
        assert a.stats == single.stats and a.termination is single.termination
        assert a.message == single.message and a.jump_count == 4
        # the same fields as an arc made whole (HybridArc._trusted), none missing
        assert set(vars(a)) - {"_cache"} == set(vars(single)) - {"_cache"}
        a.validate(where="a pooled arc")
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = arcs[r[4]].nope
    assert "_pool" in arcs[r[4]].__dict__       # a missing name does not unpool


@pytest.mark.slow
def test_a_large_batchs_pool_is_mapped_memory_and_its_arcs_are_the_single_runs(readme):
    """A pool of 4 MiB or more is on fresh pages without numpy's huge-page
    advice (``_untouched``: an anonymous private map; the pages the batch never
    writes are never made): its arcs are views of the map, writable as any
    arc's arrays, and each is its single run to the bit. A smaller pool is a
    numpy array, cut in place."""
    import mmap

    import hybridsim.compiled as hc
    ball = readme["ball"]
    h0 = np.random.default_rng(5).uniform(0.5, 2.0, 20_000)
    x0s = np.column_stack([h0, np.zeros_like(h0)])
    kw = dict(t_max=20.0, j_max=2, rtol=1e-8, atol=1e-10)
    arcs = simulate_many_compiled(ball, x0s, **kw)
    base = arcs[100].x
    while isinstance(base, np.ndarray):
        base = base.base
    assert isinstance(base, memoryview) and isinstance(base.obj, mmap.mmap)
    for i in (3, 100, 9_999, 19_998):
        single = simulate_compiled(ball, x0s[i], **kw)
        for f in ("t", "j", "x", "xdot"):
            np.testing.assert_array_equal(getattr(arcs[i], f), getattr(single, f))
            assert getattr(arcs[i], f).flags.writeable
    small = hc._run._untouched((10, 2))
    assert small.flags.owndata and hc._run._cut(small, 4).shape == (4, 2)
    big = hc._run._untouched((1 << 20, 2))
    assert not big.flags.owndata and big.flags.writeable and big.dtype == np.float64
    cut = hc._run._cut(big, 5)
    assert cut.shape == (5, 2) and np.shares_memory(cut, big)


# ------------------------------------------------------------------ a timer
@pytest.mark.slow
def test_timer_jump_at_t_max_refined_samples_stored_once(timer):
    a = simulate_compiled(timer, [0.0], t_max=1.0, refine=2)
    b = hs.simulate(timer, [0.0], t_max=1.0, refine=2)
    assert a.termination is b.termination is T.T_MAX
    np.testing.assert_allclose(a.jump_times, [0.5, 1.0], rtol=0, atol=1e-12)
    assert np.all(np.diff(a.t) >= 0)
    pairs = list(zip(a.t.tolist(), a.j.tolist()))
    assert len(pairs) == len(set(pairs)), pairs
    assert a.t.shape == b.t.shape, (a.t, b.t)
    np.testing.assert_array_equal(a.j, b.j)
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)


# ------------------------------------------------------------------ non-finite values
@pytest.mark.slow
def test_nan_guard_is_the_python_paths_failure_not_out_of_the_set():
    bad = CompiledSystem(one, zero, jump_guard=nan_near_jump, state_dim=1)
    a = simulate_compiled(bad, [0.0], t_max=3.0, throw=False)
    b = hs.simulate(bad, [0.0], t_max=3.0, throw=False)
    assert a.termination in (T.NON_FINITE, T.MAP_ERROR)
    assert a.termination is b.termination, (a.message, b.message)
    assert "jump_guard" in a.message and a.t[-1] < 1.0 and a.jump_count == 0
    assert a.t[-1] == pytest.approx(b.t[-1], abs=1e-12)
    if a.termination is T.MAP_ERROR:
        assert a.exception.map_name == "jump_guard"
        with pytest.raises(hs.MapError, match="jump_guard") as e:
            simulate_compiled(bad, [0.0], t_max=3.0)
        assert e.value.arc.termination is T.MAP_ERROR


def test_overflow_is_non_finite_not_outside_the_sets(readme):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = simulate_compiled(readme["ball"], [1e308, 1e308], t_max=3.0, throw=False)
        b = hs.simulate(readme["ball"], [1e308, 1e308], t_max=3.0, throw=False)
    assert a.termination in (T.NON_FINITE, T.MAP_ERROR), a.message
    assert b.termination in (T.NON_FINITE, T.MAP_ERROR), b.message
    assert a.termination is not T.NOT_IN_SETS


@pytest.mark.slow
def test_map_error_at_x0_raises_with_a_map_error_arc(ball_bad):
    with pytest.raises(hs.MapError, match="flow_map") as e:
        simulate_compiled(ball_bad, [6.0, 0.0], t_max=1.0, throw=False)
    assert e.value.arc is not None and e.value.arc.termination is T.MAP_ERROR
    assert len(e.value.arc.t) == 1


# ------------------------------------------------------------------ a batch with bad rows
def test_batch_keeps_good_rows_like_the_python_path(ball_bad):
    X = np.array([[1.0, 0.0], [np.nan, 0.0], [2.0, 0.0], [6.0, 0.0], [1.5, 0.0]])
    kw = dict(t_max=10.0, j_max=4)
    with pytest.warns(hs.BatchWarning, match=r"row 1.*row 3") as rec:
        a = hs.simulate_many(ball_bad, X, backend="compiled", **kw)
    assert len([w for w in rec if issubclass(w.category, hs.BatchWarning)]) == 1
    with pytest.warns(hs.BatchWarning):
        b = hs.simulate_many(ball_bad, X, **kw)
    assert [x.termination for x in a] == [x.termination for x in b] == [
        T.J_MAX, T.NON_FINITE, T.J_MAX, T.MAP_ERROR, T.J_MAX]
    assert a[3].message == b[3].message
    for i in (0, 2, 4):
        np.testing.assert_allclose(a[i].jump_times, b[i].jump_times, rtol=0, atol=1e-12)
    with pytest.raises(hs.BatchError) as e:
        simulate_many_compiled(ball_bad, X, throw=True, **kw)
    assert e.value.row == 1 and len(e.value.arcs) == 5
    assert all(arc is not None for arc in e.value.arcs)
    assert e.value.arcs[4].termination is T.J_MAX          # the rows after it ran too


# ------------------------------------------------------------------ Ctrl-C
@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(),
                    reason="Python runs signal handlers in the main thread")
def test_ctrl_c_ends_a_run_canceled_with_the_arc_so_far(timer):
    """One SIGINT, raised once the kernel is under way (paths.one_sigint_inside_the_run:
    no clock, the test's own handler): CANCELED, the arc so far, its message."""
    from paths import one_sigint_inside_the_run
    simulate_compiled(timer, [0.0], t_max=10.0)               # compiled before the signal
    with one_sigint_inside_the_run() as sig:
        a = simulate_compiled(timer, [0.0], t_max=math.inf, j_max=10**8, max_samples=10**9,
                              max_steps=10**9)
    assert sig.sent, "no run was seen under way"
    assert a.termination is T.CANCELED, a.message
    assert a.jump_count > 0 and a.t[-1] < 5e7
    assert a.message == hs.rules.message(T.CANCELED, t=a.t[-1], j=a.j[-1])


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(),
                    reason="Python runs signal handlers in the main thread")
def test_one_sigint_from_a_timer_thread_ends_a_single_run(timer):
    """One SIGINT, raised once by a timer thread of the same process (issue 45):
    a single run lets other threads run every ``YIELD_EVERY`` polls, so the
    timer's thread gets to raise it and the run ends CANCELED with the arc so
    far. (Without that the timer's thread waits for the GIL until the run has
    ended, here at its Zeno end after millions of jumps, and the signal
    lands after it.) The test's own handler; no wall-clock bound asserted."""
    import signal
    simulate_compiled(timer, [0.0], t_max=10.0)               # compiled before the clock
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    alarm = threading.Timer(0.3, signal.raise_signal, (signal.SIGINT,))
    try:
        alarm.start()
        a = simulate_compiled(timer, [0.0], t_max=math.inf, j_max=10**8, max_samples=10**9,
                              max_steps=10**9)
        alarm.join(timeout=60)
    except KeyboardInterrupt:
        pytest.fail("the SIGINT was not honoured by the run (it arrived after it)")
    finally:
        alarm.cancel()
        signal.signal(signal.SIGINT, old)
    assert a.termination is T.CANCELED
    assert a.jump_count > 0 and a.t[-1] < 5e6          # before the run's Zeno end
    assert a.message == hs.rules.message(T.CANCELED, t=a.t[-1], j=a.j[-1])


# ------------------------------------------------------------------ jump loops
@pytest.mark.slow
@pytest.mark.parametrize("kw", [dict(j_max=30), dict(j_max=math.inf, zeno_jumps=12)])
def test_a_jump_loop_is_named_in_the_python_paths_words(kw):
    """Guards only: the ball at the floor stays in D = {-h >= 0} after each jump;
    J_MAX (or ZENO) ends the run and the message names the loop, word for word
    the Python path's (rules.is_jump_loop, rules.message kind "loop")."""
    ball = CompiledSystem(ball_f, ball_g, jump_guard=ball_hD, flow_guard=ball_hC, state_dim=2)
    a = simulate_compiled(ball, [1.0, 0.0], t_max=10.0, **kw)
    b = hs.simulate(ball, [1.0, 0.0], t_max=10.0, **kw)
    assert a.termination is b.termination and a.jump_count == b.jump_count
    assert "jump loop" in a.message
    assert a.message.split(" at t=")[0] == b.message.split(" at t=")[0]
    assert float(re.search(r"at t=([0-9.e+-]+)", a.message).group(1)) == \
        pytest.approx(float(re.search(r"at t=([0-9.e+-]+)", b.message).group(1)), abs=1e-12)
