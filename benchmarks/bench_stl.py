"""STL robustness against simulation: what judging a population costs beside running it.

For ARCH-COMP requirements (:mod:`hybridsim.arch`) on both input instances,
one population of ``--rows`` points drawn uniformly from the instance's
space (seed 1) is simulated as the searches run it (the requirement's
:func:`hybridsim.arch.spaces.problem` run: one compiled ``simulate_many``
batch where numba is installed) and then judged: the requirement's
robustness (:mod:`hybridsim.stl`, dense time) on every arc, with
``refine=1`` (the searches' judge: samples, crossings, window ends) and
``refine=4`` (the validator's: extrema between samples too). The baseline
is the simulation of the same population in the same run: the table prints
milliseconds per run of each and the ratio robustness / simulation (below
1: judging is cheaper than simulating). Every time is the best of
``--repeat`` passes; the models' maps are compiled before any clock starts.

Then, with ``--trials N`` (default 0: skipped), seconds per trial of the
runner (:func:`hybridsim.arch.runner.run`, CMA-ES, both instances) for
``--trial-reqs`` (default AT1, AT2, CC1): the median over the trials of
each requirement and instance, the runs each took and the share of the
trial's time spent judging (robustness of the same arcs again, timed
apart).

Run: ``python benchmarks/bench_stl.py [--rows 200] [--repeat 3]
[--only AT1,CC4] [--trials 3]`` (``--quick``: 60 rows, one pass, four
requirements).
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from hybridsim.arch.requirements import REQUIREMENTS
from hybridsim.arch.spaces import model, problem
from hybridsim.compiled import available
from hybridsim.falsification import falsify

DEFAULT = ("AT1", "AT2", "AT51", "AT6a", "AT6abc", "CC1", "CC2", "CC3", "CC4", "CC5", "CCx")
QUICK = ("AT1", "AT6a", "CC1", "CC4")


def _best(fn, repeat):
    out, dt = None, np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        dt = min(dt, time.perf_counter() - t)
    return out, dt


def _prepare(name, inst):
    run, sp, claim, _ = problem(name, inst)
    m = model(REQUIREMENTS[name].system, inst)
    if available() and m._nb is None:
        m.compile()
    return run, sp, claim


def population(name, inst, rows, repeat):
    """(ms per run: simulation, robustness refine=1, refine=4; mean samples per arc)."""
    run, sp, _ = _prepare(name, inst)
    req = REQUIREMENTS[name]
    points = [sp.point(z) for z in sp.sample(rows, seed=1)]
    run(points[:2])                                     # warm: the first batch's setup
    arcs, t_sim = _best(lambda: run(points), repeat)
    _, t1 = _best(lambda: [float(req(a, refine=1)) for a in arcs], repeat)
    _, t4 = _best(lambda: [float(req(a, refine=4)) for a in arcs], repeat)
    samples = float(np.mean([len(a.t) for a in arcs]))
    return 1e3 * t_sim / rows, 1e3 * t1 / rows, 1e3 * t4 / rows, samples


def trials(name, inst, n):
    """Median seconds per runner trial, median runs, and the share spent judging."""
    run, sp, claim = _prepare(name, inst)
    judged = []

    def timed_claim(arc):
        t = time.perf_counter()
        m = claim(arc)
        judged[-1] += time.perf_counter() - t
        return m

    secs, runs, shares = [], [], []
    for seed in range(n):
        judged.append(0.0)
        t = time.perf_counter()
        res = falsify(run, sp, timed_claim, budget=1500, seed=seed, method="cmaes",
                      progress=False)
        dt = time.perf_counter() - t
        secs.append(dt)
        runs.append(res.evaluations)
        shares.append(judged[-1] / dt if dt > 0 else 0.0)
    return statistics.median(secs), statistics.median(runs), statistics.median(shares)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", default=None, help="comma-separated requirements")
    ap.add_argument("--trials", type=int, default=0, help="runner trials per requirement")
    ap.add_argument("--trial-reqs", default="AT1,AT2,CC1")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    names = a.only.split(",") if a.only else list(QUICK if a.quick else DEFAULT)
    rows, repeat = (60, 1) if a.quick else (a.rows, a.repeat)
    bad = [n for n in names + a.trial_reqs.split(",") if n not in REQUIREMENTS]
    if bad:
        ap.error(f"unknown requirements {bad}; have {', '.join(REQUIREMENTS)}")
    print(f"population of {rows} runs per requirement and instance, best of {repeat}; "
          f"compiled: {available()}")
    print(f"{'requirement':<12}{'inst':>5}{'samples':>9}{'sim ms':>9}{'stl1 ms':>9}"
          f"{'stl4 ms':>9}{'stl1/sim':>10}{'stl4/sim':>10}")
    ratios = []
    for name in names:
        for inst in (1, 2):
            sim, s1, s4, ns = population(name, inst, rows, repeat)
            ratios.append(s1 / sim)
            print(f"{name:<12}{inst:>5}{ns:>9.0f}{sim:>9.3f}{s1:>9.3f}{s4:>9.3f}"
                  f"{s1 / sim:>10.2f}{s4 / sim:>10.2f}")
    print(f"RESULT STL robustness (refine=1) / simulation of the same population: median "
          f"{statistics.median(ratios):.2f} over {len(ratios)} requirement-instances "
          f"(max {max(ratios):.2f})")
    if a.trials > 0:
        print(f"runner trials (CMA-ES, budget 1500), median of {a.trials}:")
        for name in a.trial_reqs.split(","):
            for inst in (1, 2):
                s, r, share = trials(name, inst, a.trials)
                print(f"RESULT {name} instance {inst}: {s:.3f} s per trial, {r:g} runs, "
                      f"{100 * share:.0f}% of it judging")


if __name__ == "__main__":
    main()
