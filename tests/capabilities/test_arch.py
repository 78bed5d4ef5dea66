"""hybridsim.arch: the ARCH-COMP AT and CC benchmarks, their spaces and runner."""
import csv
import math
from importlib import resources

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.arch import REQUIREMENTS, AutomaticTransmission, ChasingCars, problem, space
from hybridsim.arch import models as M
from hybridsim.arch.runner import main, robustness_of, run, validate
from hybridsim.arch.spaces import input_matrix, parse_input
from hybridsim.falsification import ControlPoints, Space


def _published():
    text = resources.files("hybridsim.arch").joinpath("data/falcaun_validation.csv").read_text()
    rows = list(csv.DictReader(line for line in text.splitlines() if not line.startswith("#")))
    assert len(rows) == 59
    return rows


def _full_throttle(t_max):
    at = AutomaticTransmission()
    return at, hs.simulate(at.set_inputs(100.0, 0.0), at.initial_state(), t_max=t_max,
                           rtol=1e-8, atol=1e-8)


# ------------------------------------------------------------------------ AT

def test_at_full_throttle_matches_the_reference_model():
    # the competition's Simulink model (fixed-step ode5, h = 0.01 s), throttle 100 and
    # brake 0: top speed over [0, 20] 120.21327 mph, top engine speed over [0, 10]
    # 4768.2772 rpm (the issue asks for 1e-3 relative). That reference carries ode5's
    # own error: halving its step moves it by 1e-7 (speed) and 2.4e-6 (rpm) relative
    # (measured on the same equations), so 1e-5 is the tolerance we can hold it to;
    # our rtol 1e-8 adds less. Measured: 2.3e-7 and 7.8e-7.
    at, arc = _full_throttle(20.0)
    speed20 = float(arc.at(20.0)[at.SPEED])
    rpm10 = arc.x[arc.t <= 10.0, at.RPM].max()
    assert speed20 == pytest.approx(120.21327, rel=1e-5)
    assert rpm10 == pytest.approx(4768.2772, rel=1e-5)
    # the same through the requirements (dense-time robustness): 120 - 120.21327 and
    # 4750 - 4768.2772
    assert float(REQUIREMENTS["AT1"](arc)) == pytest.approx(120.0 - 120.21327, abs=2e-3)
    assert float(REQUIREMENTS["AT2"](arc)) == pytest.approx(4750.0 - 4768.2772, abs=5e-2)


def test_at_upshifts_two_samples_after_the_threshold_is_crossed():
    # Stateflow's schedule at throttle 100: upshift thresholds 40, 70, 100 mph. The
    # first 0.04 s sample at or after the crossing starts upshifting; WAIT = 2 samples
    # later the gear changes (still above the threshold)
    at, arc = _full_throttle(20.0)
    x, t = arc.x, arc.t
    starts = np.flatnonzero(arc.is_jump_start)
    watch = [k for k in starts if x[k, 3] == 0.0 and x[k + 1, 3] == 2.0]
    changes = [k for k in starts if x[k + 1, at.GEAR] != x[k, at.GEAR]]
    assert len(watch) == len(changes) == 3
    for k, c, up in zip(watch, changes, (40.0, 70.0, 100.0)):
        assert x[k, at.SPEED] == pytest.approx(up, abs=1e-9)      # located on the threshold
        first = math.ceil(t[k] / M.SAMPLE - 1e-9)
        assert t[c] == pytest.approx(M.SAMPLE * (first + M.WAIT), abs=1e-9)
        assert x[c + 1, at.GEAR] == x[c, at.GEAR] + 1
    assert arc.x[-1, at.GEAR] == 4.0


def test_at_kickdown_at_a_control_point_is_sampled_at_that_instant():
    # 45 % to 15 s (fourth gear at 71 mph), then 100 %: the downshift threshold of
    # fourth gear jumps to 80 mph at t = 15, itself a sample (15 / 0.04 = 375): that
    # sample reads the new throttle and starts downshifting; third gear at 15.08
    at = AutomaticTransmission(times=[0.0, 15.0])
    arc = hs.simulate(at.set_inputs([45.0, 100.0], 0.0), at.initial_state(), t_max=16.0)
    g = arc.x[:, at.GEAR]
    k = np.flatnonzero(np.diff(g) < 0)
    assert len(k) == 1 and g[k[0]] == 4.0 and g[k[0] + 1] == 3.0
    assert arc.t[k[0] + 1] == pytest.approx(15.0 + M.WAIT * M.SAMPLE, abs=1e-9)
    start = np.flatnonzero(arc.is_jump_start & np.isclose(arc.t, 15.0, atol=1e-12))
    assert arc.x[start[0] + 1, 3] == -1.0                     # downshifting from 15.0


def test_at5_gear_stability_on_shifts_at_their_instants():
    # full throttle: every gear is held for more than 2.5 s, AT51-AT54 hold (+0.5, the
    # equals(gear, i) convention). 50 % to 4.4 s, then 100 %: third gear from 4.16 s,
    # kicked down to second at 4.48 s (speed below 50 mph), AT53 alone fails, decided
    # at the instant the shift into third happens
    # (the gear is piecewise constant: refine=1, no extremum search inside steps)
    at = AutomaticTransmission()
    full = hs.simulate(at.set_inputs(100.0, 0.0), at.initial_state(), t_max=33.0)
    assert [float(REQUIREMENTS[f"AT5{i}"](full, 1)) for i in (1, 2, 3, 4)] == [0.5] * 4
    at = AutomaticTransmission(times=[0.0, 4.4])
    arc = hs.simulate(at.set_inputs([50.0, 100.0], 0.0), at.initial_state(), t_max=33.0)
    got = {i: REQUIREMENTS[f"AT5{i}"](arc, 1) for i in (1, 2, 3, 4)}
    assert [float(m) for m in got.values()] == [0.5, 0.5, -0.5, 0.5]
    # decided inside the premise's window before the shift into third at 4.16 s: the
    # consequent F[0.001,0.1] G[0,2.5] gear == 3 fails there (third is left at 4.48 s);
    # its deciding instant is one of the ties in [4.06, 4.16]
    assert 4.06 - 1e-9 <= got[3].where[0] <= 4.16 + 1e-9


def test_at_engine_holds_at_idle_and_the_brake_stops_the_vehicle():
    at = AutomaticTransmission()
    arc = hs.simulate(at.set_inputs(0.0, 325.0), at.initial_state(), t_max=10.0)
    # (the stop is located to the event tolerance: v within 1e-12 of 0 there)
    assert arc.x[:, at.RPM].min() >= M.NE_MIN - 1e-9 and arc.x[:, at.SPEED].min() > -1e-12
    end = arc.x[-1]
    assert end[6] == -1.0 and end[at.RPM] == M.NE_MIN         # held at 600 rpm
    assert end[7] == 1.0 and end[at.SPEED] == 0.0             # stopped: drive < 40 + brake
    # without the brake the idling engine's drive torque (3.23 Tout = 329 lb ft at 600
    # rpm, above the static road load 40) keeps the vehicle creeping
    arc = hs.simulate(at.set_inputs(0.0, 0.0), at.initial_state(), t_max=10.0)
    assert arc.x[-1, 7] == 0.0 and arc.x[-1, at.SPEED] > 1.0


def test_inputs_held_or_linear_between_control_points():
    for interp, mid in (("previous", 20.0), ("linear", 60.0)):
        at = AutomaticTransmission(times=[0.0, 10.0], interpolation=interp)
        at.set_inputs([20.0, 100.0], 0.0)
        assert M._input(5.0, at.params, 0) == pytest.approx(mid)
        assert M._input(12.0, at.params, 0) == 100.0            # held after the last
        thr, brk = at.inputs()
        assert thr.tolist() == [20.0, 100.0] and brk.tolist() == [0.0, 0.0]
    # each control point is an event: the run jumps there (the shift logic may take a
    # sample at the same instant), the engine and the vehicle keep their state
    arc = hs.simulate(at.set_inputs([0.0, 50.0], 0.0), at.initial_state(), t_max=12.0)
    k = np.flatnonzero(arc.is_jump_start & np.isclose(arc.t, 10.0, atol=1e-12))
    assert len(k) == 1 and arc.x[k[0] + 1, 8] == arc.x[k[0], 8] + 1
    assert np.array_equal(arc.x[k[0], :2], arc.x[k[0] + 1, :2])


@pytest.mark.parametrize("call, match", [
    (lambda: AutomaticTransmission(times=[1.0, 2.0]), "start at 0"),
    (lambda: AutomaticTransmission(times=[0.0, 0.0]), "strictly increasing"),
    (lambda: AutomaticTransmission(interpolation="cubic"), "'previous' or 'linear'"),
    (lambda: AutomaticTransmission().set_inputs(101.0, 0.0), r"throttle must lie in \[0, 100\]"),
    (lambda: AutomaticTransmission(times=[0, 5]).set_inputs([1.0, 2.0, 3.0], 0.0),
     "throttle must be a scalar or 2 control-point values"),
    (lambda: ChasingCars().input_params(0.0, 1.5), r"brake must lie in \[0, 1\]"),
])
def test_bad_model_arguments(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ------------------------------------------------------------------------ CC

def test_cc_followers_switch_on_their_thresholds():
    cc = ChasingCars(times=[0.0, 20.0])
    arc = hs.simulate(cc.set_inputs([1.0, 0.0], [0.0, 0.5]), cc.initial_state(), t_max=40.0)
    x = arc.x
    moves = {(1.0, 0.0): 15.0, (1.0, 2.0): 5.0, (0.0, 1.0): 10.0, (2.0, 0.0): 20.0}
    switches = 0
    for k in np.flatnonzero(arc.is_jump_start):
        for i in range(1, 5):
            before, after = x[k, 4 + 3 * (i - 1)], x[k + 1, 4 + 3 * (i - 1)]
            if before != after:
                switches += 1
                gap = x[k, cc.POSITIONS[i]] - x[k, cc.POSITIONS[i - 1]]
                assert gap == pytest.approx(moves[(before, after)], abs=1e-8)
    assert switches > 10
    assert np.all(np.diff(x[:, 0]) <= 0.0)                    # the leader runs toward -inf


def test_cc_a_step_across_a_control_point_reads_the_piece_it_started_on():
    """Instance 2's held inputs jump at every control point: the flow reads
    the piece the control-point events have reached, so no solver step
    straddles a jump of an input. At the default tolerances the cars'
    positions at 100 s are within 5e-4 of a run at rtol 1e-11 (8e-5 to 2e-4
    on these inputs; reading the inputs by time, the steps across a jump,
    cut down by rejections, missed by 1.7e-3 to 1.7e-2)."""
    cc = ChasingCars(times=np.arange(20) * 5.0, interpolation="previous")
    rng = np.random.default_rng(3)
    for _ in range(2):
        x0 = cc.set_inputs(rng.random(20), rng.random(20)).initial_state()
        end = hs.simulate(cc, x0, t_max=100.0).x[-1, list(cc.POSITIONS)]
        ref = hs.simulate(cc, x0, t_max=100.0, rtol=1e-11, atol=1e-13).x[-1, list(cc.POSITIONS)]
        np.testing.assert_allclose(end, ref, rtol=0, atol=5e-4)


@pytest.mark.parametrize("prop", ["AT1", "AT2", "CC1", "CC3"])
def test_falcaun_2024_falsifying_inputs_falsify_our_models(prop):
    # FalCAuN's ARCH-COMP 2024 validation file: one input per requirement
    row = next(r for r in _published() if r["year"] == "2024" and r["property"] == prop)
    times, values = parse_input(row["input"])
    assert float(robustness_of(prop, times, values, "previous")) < 0


@pytest.mark.slow
def test_every_published_falsifying_input():
    # 59 distinct inputs of FalCAuN's 2023 and 2024 validation files. All 2024 inputs
    # falsify our models but CC4's; of 2023's, AT1 and AT2 all do, the AT6 ones mostly
    # not. The AT6 ones judged on FalCAuN's 2-s samples satisfy the premise
    # G[0,30] RPM < 3000, while the engine speed peaks above 3000 at gear changes
    # between samples (reproduced by a fixed-step ode5 replica of the Simulink model:
    # 3009.5 rpm at 4.2 s for the first one).
    ok, bad = [], []
    for r in _published():
        times, values = parse_input(r["input"])
        rob = float(robustness_of(r["property"], times, values, "previous"))
        (ok if rob < 0 else bad).append((r["year"], r["property"], rob))
        if rob >= 0 and r["system"] == "AT":
            at = AutomaticTransmission(times=times)
            at.set_inputs(values[:, 0], values[:, 1])
            arc = hs.simulate(at, at.initial_state(), t_max=30.0)
            on_samples = [arc.at(2.0 * k)[at.RPM] for k in range(16)]
            assert max(on_samples) < 3000.0 < arc.x[:, at.RPM].max()
    assert {p for y, p, _ in bad if y == "2024"} == {"CC4"}
    assert {p for y, p, _ in ok if y == "2023"} >= {"AT1", "AT2", "CC1", "CC2"}
    assert len(ok) == 22 and len(bad) == 37


@pytest.mark.slow
def test_compiled_and_python_paths_agree():
    at = AutomaticTransmission(times=[0.0, 5.0, 10.0])
    x0 = at.set_inputs([100.0, 30.0, 80.0], [0.0, 50.0, 0.0]).initial_state()
    tol = {"rtol": 1e-10, "atol": 1e-10}    # the two paths' steps agree to their tolerance
    a = hs.simulate(at, x0, t_max=30.0, **tol)
    b = hs.simulate(at, x0, t_max=30.0, backend="compiled", **tol)
    np.testing.assert_allclose(a.jump_times, b.jump_times, atol=1e-8)
    np.testing.assert_allclose(a.xf, b.xf, rtol=1e-8)


# ------------------------------------------------------------ spaces, runner

def test_control_points_signal():
    s = ControlPoints([0.0, 0.0], [100.0, 325.0], 30.0, points=6)
    assert s.size == 12 and s.times.tolist() == [0.0, 5.0, 10.0, 15.0, 20.0, 25.0]
    lo, hi = s.bounds()
    assert lo.tolist() == [0.0] * 12 and hi.tolist() == [100.0, 325.0] * 6
    u = Space(u=s).point(np.arange(12.0))["u"]
    assert u(7.0).tolist() == [2.0, 3.0] and u(99.0).tolist() == [10.0, 11.0]
    assert u.values.shape == (6, 2) and u.interpolation == "previous"
    lin = ControlPoints(0.0, 1.0, 10.0, points=3, interpolation="linear")
    assert lin.value(np.array([0.0, 1.0, 0.0]))(2.5).tolist() == [0.5]


@pytest.mark.parametrize("args, match", [
    ((0.0, 1.0, 0.0, 3), "t_end must be > 0"),
    ((1.0, 0.0, 5.0, 3), "inverted bounds"),
    ((0.0, 1.0, 5.0, 0), "points must be a positive integer"),
    ((0.0, 1.0, 5.0, 1, "linear"), "needs points >= 2"),
    ((0.0, 1.0, 5.0, 2, "spline"), "'previous' or 'linear'"),
])
def test_control_points_bad_arguments(args, match):
    with pytest.raises(ValueError, match=match):
        ControlPoints(*args)


def test_instance_spaces_and_the_input_format():
    assert space("AT", 1).dim == 26 and space("AT", 2).dim == 12
    assert space("CC", 1).dim == 22 and space("CC", 2).dim == 40
    run_, sp, claim, t_max = problem("AT6a", 1, backend="python")
    assert t_max == 30.0 and run_.batch
    p = sp.point(sp.lo + 0.3 * (sp.hi - sp.lo))
    times, values = parse_input(input_matrix(p))
    np.testing.assert_array_equal(times, p["u"].times)
    np.testing.assert_array_equal(values, p["u"].values)
    with pytest.raises(ValueError, match="no instance 3"):
        space("AT", 3)
    with pytest.raises(ValueError, match="no requirement 'AT7'"):
        problem("AT7", 1)
    with pytest.raises(ValueError, match=r"input must read"):
        parse_input("[0 a b]")


@pytest.mark.slow
def test_runner_writes_the_tables_and_the_validator_confirms(tmp_path):
    # AT2 on instance 2 (a vertex of the box falsifies it within the first runs)
    lines = []
    summary = run(tmp_path, trials=2, only="AT2", instances=(2,), budget=40,
                  backend="python", log=lines.append, baseline="random")
    assert [(s["method"], s["requirement"], s["instance"], s["trials"])
            for s in summary] == [("cmaes", "AT2", 2, 2), ("random", "AT2", 2, 2)]
    assert summary[0]["falsified"] == 2 and summary[0]["published_mean_simulations"] == 128
    with open(tmp_path / "trials.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["system", "property", "instance", "method", "seed",
                             "simulations", "time", "robustness", "falsified", "input"]
    assert [r["method"] for r in rows] == ["cmaes"] * 2 + ["random"] * 2
    assert all(int(r["simulations"]) <= 40 for r in rows)
    assert all(float(r["robustness"]) < 0 for r in rows if r["falsified"] == "yes")
    with open(tmp_path / "summary.csv") as fh:
        assert next(csv.reader(fh)) == ["requirement", "instance", "method", "trials",
                                        "falsified", "mean_simulations",
                                        "median_simulations", "median_seconds_per_trial",
                                        "published_mean_simulations"]
    checked = validate(tmp_path, log=lines.append)
    hits = sum(r["falsified"] == "yes" for r in rows)
    assert len(checked) == hits >= 2 and all(c["ok"] and c["again"] < 0 for c in checked)
    assert main(["validate", str(tmp_path)]) == 0


def test_validator_confirms_or_refutes_each_falsifying_input(tmp_path):
    # a trials.csv by hand: full throttle falsifies AT2 (4768 rpm > 4750); idling
    # does not, though its row claims so
    with open(tmp_path / "trials.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["system", "property", "instance", "seed", "simulations", "time",
                    "robustness", "falsified", "input"])
        w.writerow(["AT", "AT2", 2, 0, 1, 0.1, -18.27, "yes", "[0.0 100.0 0.0]"])
        w.writerow(["AT", "AT2", 2, 1, 1, 0.1, -1.0, "yes", "[0.0 0.0 0.0; 5.0 10.0 0.0]"])
        w.writerow(["AT", "AT2", 2, 2, 1500, 9.0, 3.5, "no", "[0.0 0.0 0.0]"])
    res = validate(tmp_path, log=lambda s: None)
    assert [r["ok"] for r in res] == [True, False]
    assert res[0]["again"] == pytest.approx(4750.0 - 4768.2772, abs=0.05)
    assert res[1]["again"] > 0
    assert main(["validate", str(tmp_path)]) == 1


def test_runner_refuses_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match="unknown requirements"):
        run(tmp_path, only="AT9")
    with pytest.raises(ValueError, match="method and baseline"):
        run(tmp_path, only="AT1", baseline="bayes")
    with pytest.raises(SystemExit):
        main(["--out", str(tmp_path), "--trials", "0"])
    with pytest.raises(SystemExit):
        main(["--out", str(tmp_path), "--method", "bayes"])
    with pytest.raises(FileNotFoundError, match="no trials.csv"):
        validate(tmp_path)


@pytest.mark.parametrize("stop", [True, False])
def test_compiled_populations_pipelined_judge_the_same_runs(stop):
    """A compiled population run (``run.concurrent``) simulates the next pieces
    of a population in threads while the claim judges those run: the runs,
    their order and margins, the count and the worst point are those of the
    population run one chunk after another."""
    from hybridsim.compiled import available
    run_, sp, claim, _ = problem("AT6a", 2)
    assert run_.concurrent is available()
    if not available():
        pytest.skip("numba is not installed: populations run on the Python path")
    res = [hs.falsify(run_, sp, claim, budget=80, seed=1, method="cmaes", stop=stop,
                      progress=False)]
    run_.concurrent = False
    res.append(hs.falsify(run_, sp, claim, budget=80, seed=1, method="cmaes", stop=stop,
                          progress=False))
    a, b = res
    np.testing.assert_array_equal(a.history, b.history)
    assert a.evaluations == b.evaluations and a.found_by == b.found_by
    assert a.verdict == b.verdict and np.array_equal(a.point.z, b.point.z)
    assert a.verdict == "counterexample"                 # within 80 runs from seed 1
    assert (a.evaluations < 80) is stop and a.evaluations == len(a.history)
