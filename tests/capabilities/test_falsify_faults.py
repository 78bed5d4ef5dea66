"""falsify, explore and simulate_sensitivity under faults: Ctrl-C, failing
claims and runs, a dying pool worker, time and memory budgets.

Ctrl-C is one SIGINT raised from inside a run or a claim after a counted
number of calls (never a timer), with this module's own SIGINT handler
installed (the default one, raising KeyboardInterrupt, whatever the runner
set) and a wall-time guard; the wall clock decides no verdict (the
``seconds`` tests run on a fake clock).
"""
from __future__ import annotations

import concurrent.futures
import faulthandler
import math
import os
import signal
import sys
import threading
import time
import tracemalloc
import types

import numpy as np
import pytest
from paths import one_sigint_inside_the_run
from test_falsify import BallE

import hybridsim as hs
from hybridsim import falsification
from hybridsim.falsification import Interval, Space, batch_run, falsify
from hybridsim.library import BouncingBall, Timer

SPACE = Space(period=Interval(0.9, 1.2))


def _holds(arc):                          # a claim true on every run: margin 1
    return 1.0


@pytest.fixture
def sigint():
    """The default SIGINT handler (KeyboardInterrupt) for the test, restored
    after; the process dumps its stacks and exits if the test hangs."""
    before = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    faulthandler.dump_traceback_later(300, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
        signal.signal(signal.SIGINT, before)


class CtrlCAt:
    """A counter that raises one SIGINT at its ``at``-th call."""

    def __init__(self, at):
        self.at, self.calls = at, 0

    def __call__(self):
        self.calls += 1
        if self.calls == self.at:
            signal.raise_signal(signal.SIGINT)


class SignalTimer(hs.HybridSystem):
    """The library's timer, whose flow map raises SIGINT when ``hit`` says so."""

    state_dim = 1

    def __init__(self, period, hit):
        self.period, self.hit = period, hit

    def flow_map(self, x):
        self.hit()
        return np.ones(1)

    def jump_map(self, x):
        return np.zeros(1)

    def jump_set(self, x):
        return x[0] >= self.period

    def jump_guard(self, x):
        return x[0] - self.period


# ------------------------------------------------------------------------ Ctrl-C
@pytest.mark.parametrize("stop", [True, False])
@pytest.mark.parametrize("at", [1, 5])
def test_ctrl_c_inside_a_run_ends_the_search_without_a_finding(sigint, stop, at):
    """The SIGINT lands in the 7th run's flow map (its first call, as the run
    starts, or its 5th, in the run's loop): that run ends CANCELED (or raises
    SimulationError from KeyboardInterrupt), which is not a failed run: the
    search ends with the 6 runs before it, no finding, no counterexample
    (the claim holds everywhere)."""
    runs = [0]
    hit = CtrlCAt(at)

    def run(p):
        runs[0] += 1
        return hs.simulate(SignalTimer(p["period"], hit if runs[0] == 7 else lambda: None),
                           [0.0], t_max=2.0, j_max=1, warn=False)
    res = falsify(run, SPACE, _holds, budget=50, seed=0, stop=stop, method="random",
                  popsize=10, progress=False)
    assert hit.calls >= at and runs[0] == 7
    assert res.interrupted and res.stopped == "interrupted"
    assert res.verdict == "none found" and res.margin == 1.0 and not res.findings
    assert res.evaluations == 6 and res.history.tolist() == [1.0] * 6
    assert "stopped: interrupted" in repr(res)


class KillFromAThread:
    """At its ``at``-th call, asks a helper thread to send one SIGINT to this
    process (os.kill) and waits for it (at most 120 s): the signal arrives
    from another thread at a point the test chooses, not after a delay."""

    def __init__(self, at):
        self.at, self.calls = at, 0

    def __call__(self):
        self.calls += 1
        if self.calls != self.at:
            return
        threading.Thread(target=os.kill, args=(os.getpid(), signal.SIGINT)).start()
        for _ in range(12000):             # KeyboardInterrupt ends this wait
            time.sleep(0.01)
        raise AssertionError("SIGINT from the helper thread never arrived")


def test_ctrl_c_from_another_thread_ends_the_search(sigint):
    runs = [0]
    hit = KillFromAThread(3)

    def run(p):
        runs[0] += 1
        return hs.simulate(SignalTimer(p["period"], hit if runs[0] == 4 else lambda: None),
                           [0.0], t_max=2.0, j_max=1, warn=False)
    res = falsify(run, SPACE, _holds, budget=50, seed=0, stop=False, method="random",
                  popsize=10, progress=False)
    assert res.interrupted and res.evaluations == 3 and not res.findings
    assert res.verdict == "none found"


def test_ctrl_c_in_the_claim_keeps_the_counterexample_found_before(sigint):
    """Ctrl-C in the claim of the 5th run: the search ends; a real
    counterexample among the first 4 runs is still the verdict."""
    hit = CtrlCAt(5)

    def claim(arc):
        hit()
        return 1.1 - arc.jump_times[0]         # broken for periods above 1.1

    def run(p):
        return hs.simulate(Timer(p["period"]), [0.0], t_max=2.0, j_max=1)
    res = falsify(run, SPACE, claim, budget=50, seed=3, stop=False, method="random",
                  popsize=10, progress=False)
    assert res.interrupted and res.evaluations == 4
    assert res.verdict == ("counterexample" if min(res.history) < 0 else "none found")
    assert res.margin == min(res.history)


class SignalBall(BallE):
    """test_falsify's ball (its restitution a third state, vectorized) whose flow
    map calls ``hit`` (a population run in one numpy batch)."""

    hit = staticmethod(lambda: None)

    def flow_map(self, x):
        self.hit()
        return super().flow_map(x)


BALL = Space(h0=Interval(0.9, 1.1), e=Interval(0.7, 0.85))


def _x0(p):
    return [p["h0"], 0.0, p["e"]]


@pytest.mark.parametrize("stop", [True, False])
def test_ctrl_c_inside_a_population_run_keeps_the_populations_before(sigint, stop):
    """simulate_many (the numpy batch) ends its rows CANCELED on Ctrl-C; the
    search keeps the runs judged before and ends interrupted."""
    system = SignalBall()
    seen = [0]
    hit = CtrlCAt(3)
    many = batch_run(system, _x0, t_max=3.0, j_max=1, backend="python")

    def run(points):                    # the third population is interrupted
        system.hit = hit if seen[0] >= 16 else (lambda: None)
        seen[0] += len(points)
        return many(points)
    run.batch = True
    res = falsify(run, BALL, _holds, budget=200, seed=0, method="random", popsize=8,
                  stop=stop, progress=False)
    assert hit.calls >= 3 and res.interrupted and not res.findings
    assert res.verdict == "none found"
    assert res.evaluations == 16 and np.all(res.history == 1.0)


@pytest.mark.parametrize("at", [1, 3])
def test_ctrl_c_during_explore_ends_it_interrupted(sigint, monkeypatch, at):
    """The SIGINT lands in the 4th branch's run (as it starts, or inside):
    that branch ends CANCELED (its arc so far), the others stay pending, and
    the tree says why."""
    branches = [0]
    hit = CtrlCAt(at)

    class Chooser(hs.HybridSystem):     # C ∩ D = [1, 2]: a choice at every entry
        state_dim = 1

        def flow_map(self, x):
            if branches[0] == 4:
                hit()
            return np.ones(1)

        def jump_map(self, x):
            return np.zeros(1)

        def flow_set(self, x):
            return x[0] <= 2.0

        def jump_set(self, x):
            return x[0] >= 1.0

    from hybridsim.explore import _Explorer
    run_branch = _Explorer._simulate

    def counted(self, *a, **k):
        branches[0] += 1
        return run_branch(self, *a, **k)
    monkeypatch.setattr(_Explorer, "_simulate", counted)
    with pytest.warns(hs.SimulationWarning, match="INTERRUPTED"):
        tree = hs.explore(Chooser(), [0.0], t_max=10.0, j_max=3, dwell_grid=[0.5])
    assert hit.calls >= at and branches[0] == 4
    assert tree.end is hs.ExploreEnd.INTERRUPTED and not tree.complete
    canceled = [n for n in tree.nodes if n.arc is not None
                and n.arc.termination is hs.Termination.CANCELED]
    assert len(canceled) == 1 and tree.pending > 0


@pytest.mark.parametrize("at", [1, 30])
def test_ctrl_c_during_sensitivities_returns_the_arc_so_far(sigint, at):
    """simulate_sensitivity: one SIGINT in the first flow evaluation (the
    run's check of its maps at x0) or the 30th ends the run CANCELED with the
    sensitivities so far (finite), and says so (it raised SimulationError at x0)."""
    hit = CtrlCAt(at)

    class Ball(BouncingBall):
        def flow_map(self, x):
            hit()
            return super().flow_map(x)
    sarc = hs.simulate_sensitivity(Ball(), [1.0, 0.0], t_max=10.0)
    assert sarc.termination is hs.Termination.CANCELED and "interrupted" in sarc.arc.message
    assert f"t={sarc.t[-1]:.10g}, j={sarc.arc.j[-1]}" in sarc.arc.message
    assert np.all(np.isfinite(sarc.S)) and sarc.t[-1] < 10.0
    np.testing.assert_array_equal(sarc.S[0], np.eye(2))
    if at == 1:                            # x0 alone
        assert sarc.t.tolist() == [0.0]


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(),
                    reason="Python runs signal handlers in the main thread")
def test_one_sigint_inside_a_sensitivity_run_ends_it_canceled():
    """One SIGINT from a helper thread once the run is under way
    (paths.one_sigint_inside_the_run, no clock) on a timer with no horizon:
    CANCELED, the arc and sensitivities so far (every jump 1 s earlier per
    unit of x0), the message naming its last sample."""
    timer = hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        jump_guard=lambda x: x[0] - 0.01, state_dim=1)
    with one_sigint_inside_the_run() as sig:
        sarc = hs.simulate_sensitivity(timer, [0.0], t_max=math.inf, max_samples=1_000_000,
                                       max_steps=math.inf, zeno_jumps=10 ** 9)
    assert sig.sent, "no run was seen under way"
    assert sarc.termination is hs.Termination.CANCELED, sarc.arc.message
    sarc.arc.validate()
    assert f"t={sarc.t[-1]:.10g}" in sarc.arc.message
    assert np.all(np.isfinite(sarc.S))
    if sarc.arc.jump_count:
        np.testing.assert_allclose(sarc.dtj_dx0[:, 0], -1.0, rtol=0, atol=1e-6)


# --------------------------------------------------------------- failing user code
def _run_timer(p):
    return hs.simulate(Timer(p["period"]), [0.0], t_max=2.0, j_max=1)


def _fragile(arc):
    """Holds where the period is below 1.1, raises above it."""
    if arc.jump_times[0] > 1.1:
        raise ZeroDivisionError("no margin above 1.1")
    return 1.0


def test_a_claim_that_raises_is_a_finding_naming_claim_point_and_exception():
    res = falsify(_run_timer, SPACE, _fragile, budget=40, seed=0, stop=False,
                  method="random", progress=False)
    assert res.stopped == "budget" and res.evaluations == 40
    assert res.findings and {f.cause for f in res.findings} == {"CLAIM_RAISED"}
    f = res.findings[0]
    assert f.point["period"] > 1.1 and isinstance(f.exception, ZeroDivisionError)
    assert "claim _fragile raised ZeroDivisionError: no margin above 1.1" in f.message
    assert "test_falsify_faults.py" in f.message and f.exception.__traceback__ is None
    assert res.verdict == "counterexample" and res.margin == -math.inf
    assert res.arc is not None and res.arc.jump_times[0] > 1.1   # the arc it raised on
    # the history holds every run: the findings' -inf and the others' 1.0
    assert np.sum(res.history == -math.inf) == len(res.findings)


def test_on_error_stop_ends_the_search_with_the_results_so_far():
    res = falsify(_run_timer, SPACE, _fragile, budget=40, seed=0, stop=False,
                  method="random", on_error="stop", progress=False)
    assert res.stopped == "error" and not res.findings
    assert res.error.cause == "CLAIM_RAISED" and res.error.point["period"] > 1.1
    assert res.verdict == "none found" and np.all(res.history == 1.0)
    assert res.evaluations == len(res.history) < 40


def test_on_error_raise_names_the_point():
    with pytest.raises(ZeroDivisionError, match="no margin above 1.1") as ei:
        falsify(_run_timer, SPACE, _fragile, budget=40, seed=0, stop=False,
                method="random", on_error="raise", progress=False)
    assert any("period=" in n for n in ei.value.__notes__)
    with pytest.raises(ValueError, match="on_error must be"):
        falsify(_run_timer, SPACE, _fragile, on_error="ignore")


def test_a_run_that_returns_no_arc_is_a_finding():
    def run(p):
        return None if p["period"] > 1.1 else _run_timer(p)
    res = falsify(run, SPACE, lambda arc: 1.1 - arc.jump_times[0] + 1.0, budget=30,
                  seed=0, stop=False, method="random", progress=False)
    causes = {f.cause for f in res.findings}
    assert causes == {"NOT_AN_ARC"} and res.arc is None
    assert all(f.point["period"] > 1.1 for f in res.findings)
    assert "returned NoneType, not a HybridArc" in res.findings[0].message


def test_a_population_run_that_raises_fails_its_chunk_only():
    """The second population's run raises: its points are findings; the
    first population's margins are kept."""
    pops = [0]
    many = batch_run(SignalBall(), _x0, t_max=3.0, j_max=1, backend="python")

    def run(points):
        pops[0] += 1
        if pops[0] == 2:
            raise RuntimeError("the cluster is gone")
        return many(points)
    run.batch = True
    res = falsify(run, BALL, _holds, budget=24, seed=0, method="random", popsize=8,
                  stop=False, progress=False)
    assert res.evaluations == 24 and res.stopped == "budget"
    assert np.all(res.history[:8] == 1.0) and np.all(res.history[8:16] == -math.inf)
    assert len(res.findings) == 8 and all("the cluster is gone" in f.message
                                          for f in res.findings)


class DyingBall(SignalBall):
    """test_falsify's ball with a fourth state, a mark: the run of a marked
    point kills the process that runs it (a pool worker dying mid-chunk)."""

    state_dim = 4
    vectorized = False

    def flow_map(self, x):
        if x[3] == 1.0:
            os._exit(3)
        return np.append(super().flow_map(x[:3]), 0.0)

    def jump_map(self, x):
        return np.append(super().jump_map(x[:3]), x[3])


@pytest.mark.skipif(sys.platform == "win32", reason="fork start method")
def test_a_dead_pool_worker_loses_only_its_chunk():
    """The 9th point of the search (in the second population) kills the pool's
    worker: that population's points are WORKER_DIED findings, the first
    population's margins are kept, and the search goes on to its budget on a
    fresh pool (the user's pool stays broken, left to its owner)."""
    marks = iter(range(10 ** 6))

    def x0_of(p):
        return [p["h0"], 0.0, p["e"], 1.0 if next(marks) == 8 else 0.0]
    with concurrent.futures.ProcessPoolExecutor(1) as ex:
        run = batch_run(DyingBall(), x0_of, t_max=3.0, j_max=1, backend="python",
                        executor=ex, chunks=1)
        res = falsify(run, BALL, _holds, budget=24, seed=0, method="random", popsize=6,
                      stop=False, progress=False)
        with pytest.raises(concurrent.futures.BrokenExecutor):
            ex.submit(int).result()
    assert res.stopped == "budget" and res.evaluations == 24 and res.error is None
    assert np.all(res.history[:6] == 1.0) and np.all(res.history[6:12] == -math.inf)
    assert np.all(res.history[12:] == 1.0)
    assert len(res.findings) == 6 and {f.cause for f in res.findings} == {"WORKER_DIED"}
    assert all("BrokenProcessPool" in f.message and "chunk of 6 points" in f.message
               for f in res.findings)
    assert res.verdict == "counterexample" and res.point == res.findings[0].point


@pytest.mark.skipif(sys.platform == "win32", reason="fork start method")
def test_a_dead_worker_of_a_run_that_cannot_renew_its_pool_ends_the_search():
    """A population run of the user's own, with no ``renew``: the chunk is
    lost and, the pool being broken for good, the search ends there with the
    populations before it."""
    pops = [0]
    with concurrent.futures.ProcessPoolExecutor(1) as ex:
        good = batch_run(SignalBall(), _x0, t_max=3.0, j_max=1, backend="python")
        dying = batch_run(DyingBall(), lambda p: [*_x0(p), 1.0], t_max=3.0, j_max=1,
                          backend="python", executor=ex, chunks=1)

        def run(points):
            pops[0] += 1
            return (good if pops[0] == 1 else dying)(points)
        run.batch = True
        res = falsify(run, BALL, _holds, budget=40, seed=0, method="random", popsize=6,
                      stop=False, progress=False)
    assert res.stopped == "error" and res.evaluations == 12
    assert np.all(res.history[:6] == 1.0) and np.all(res.history[6:] == -math.inf)
    assert res.error.cause == "WORKER_DIED" and "could not be renewed" in res.error.message
    assert isinstance(res.error.exception, concurrent.futures.BrokenExecutor)
    assert len(res.findings) == 6 and res.verdict == "counterexample"


# ---------------------------------------------------------------- budgets and space
class FakeClock:
    def __init__(self):
        self.now = 0.0

    def perf_counter(self):
        return self.now


def test_seconds_is_honoured_within_one_run(monkeypatch):
    """Each run takes 1 s of a fake clock: seconds=10 stops after the 10th
    run, not at the end of a population of 100."""
    clock = FakeClock()
    monkeypatch.setattr(falsification, "time", types.SimpleNamespace(
        perf_counter=clock.perf_counter))

    def run(p):
        clock.now += 1.0
        return _run_timer(p)
    res = falsify(run, SPACE, _holds, budget=1000, seconds=10.0, seed=0, stop=False,
                  method="random", popsize=100, progress=False)
    assert res.evaluations == 10 and res.stopped == "seconds"


@pytest.mark.parametrize("stop", [True, False])
def test_seconds_is_honoured_within_one_chunk_of_a_population(monkeypatch, stop):
    """A population run of k points takes k s of a fake clock: chunks of 1, 2,
    4 runs, then the 3 that fit, reach seconds=10 exactly."""
    clock = FakeClock()
    monkeypatch.setattr(falsification, "time", types.SimpleNamespace(
        perf_counter=clock.perf_counter))
    many = batch_run(SignalBall(), _x0, t_max=3.0, j_max=1, backend="python")

    def run(points):
        clock.now += len(points)
        return many(points)
    run.batch = True
    res = falsify(run, BALL, _holds, budget=1000, seconds=10.0, seed=0, stop=stop,
                  method="random", popsize=100, progress=False)
    assert res.evaluations == 10 and res.stopped == "seconds"


@pytest.mark.parametrize("method", ["de", "random"])
def test_a_huge_budget_allocates_only_what_runs(method):
    """budget=10**12 used to ask for 7.3 TiB of history up front; the search
    stops (on_error="stop") after 40 runs having used a few MB."""
    calls = [0]

    def claim(arc):
        calls[0] += 1
        if calls[0] > 40:
            raise RuntimeError("enough")
        return 1.0
    tracemalloc.start()
    try:
        res = falsify(_run_timer, SPACE, claim, budget=10 ** 12, seconds=1e9, seed=0,
                      method=method, stop=False, on_error="stop", progress=False)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert res.evaluations == 40 and res.stopped == "error"
    assert peak < 50e6


@pytest.mark.parametrize("method", ["de", "random"])
def test_zero_width_intervals_are_fixed_coordinates(method):
    """A space of one point is one run (the compass search has no coordinate
    to move: it used to take numpy's argmin of an empty population)."""
    res = falsify(_run_timer, Space(period=Interval(1.15, 1.15)),
                  lambda arc: 1.2 - arc.jump_times[0], budget=50, seed=0, method=method,
                  stop=False, progress=False)
    assert res.evaluations == 1 and res.point["period"] == 1.15
    assert res.verdict == "none found" and res.margin == pytest.approx(0.05)
    assert res.stopped == "converged"
    mixed = falsify(_run_timer, Space(period=Interval(0.9, 1.2), k=Interval(0.5, 0.5)),
                    lambda arc: 1.1 - arc.jump_times[0], budget=60, seed=0, method=method,
                    stop=False, progress=False)
    assert mixed.point["k"] == 0.5 and mixed.verdict == "counterexample"
    if method == "de":                     # a vertex of the box, tried first
        assert mixed.margin == pytest.approx(-0.1, abs=1e-6)
