"""Seconds per ARCH-COMP trial, the populations pipelined against run chunk by chunk.

:func:`hybridsim.falsify` pipelines a compiled population run
(``batch_run``'s ``run.concurrent``): the pieces of each chunk simulate in
threads (the compiled kernel releases the GIL) while the claim judges the
pieces run. The baseline is the same trial run chunk after chunk
(``run.concurrent = False``), in the same process, the two interleaved
trial by trial: same requirement, instance and seed, so the same runs
(checked: the histories must be equal).

Per trial the table prints, for both: wall seconds, process CPU seconds
(every thread), and the main thread's CPU seconds (the search and the
robustness; the rest is the simulation in the worker threads). On a
machine whose two cores are free, a pipelined trial's wall time is at
least max(main thread, all CPU / 2); on a loaded machine the wall times
show the load (the 1-minute load average is printed beside them).

Run: ``python benchmarks/bench_falsify_pipeline.py [--only CC4,AT51,F16]
[--instances 1,2] [--seeds 0,1,2]`` (``--quick``: CC4 instance 1, seed 0).
"""
from __future__ import annotations

import argparse
import os
import statistics
import threading
import time

import numpy as np

from hybridsim.arch.requirements import REQUIREMENTS
from hybridsim.arch.spaces import INSTANCES, model, problem
from hybridsim.compiled import available
from hybridsim.falsification import falsify

DEFAULT = ("CC4", "CC5", "AT51", "AT6b", "F16")


def _trial(run, sp, claim, seed, budget):
    main = threading.get_ident()
    c0, w0, m0 = time.process_time(), time.perf_counter(), time.thread_time()
    res = falsify(run, sp, claim, budget=budget, seed=seed, method="cmaes", progress=False)
    assert threading.get_ident() == main
    return res, (time.perf_counter() - w0, time.process_time() - c0, time.thread_time() - m0)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--only", default=",".join(DEFAULT))
    p.add_argument("--instances", default="1,2")
    p.add_argument("--seeds", default="0,1,2")
    p.add_argument("--budget", type=int, default=1500)
    p.add_argument("--quick", action="store_true")
    a = p.parse_args(argv)
    if not available():
        print("numba is not installed: populations run on the Python path, nothing to pipeline")
        return 0
    names = ["CC4"] if a.quick else a.only.split(",")
    insts = [1] if a.quick else [int(i) for i in a.instances.split(",")]
    seeds = [0] if a.quick else [int(s) for s in a.seeds.split(",")]
    print(f"{'req':7} {'in':>2} {'seed':>4} {'runs':>5} | {'serial wall':>11} {'cpu':>6} | "
          f"{'pipelined wall':>14} {'cpu':>6} {'main':>6} | load")
    rows = []
    for name in names:
        system = REQUIREMENTS[name].system
        for inst in insts:
            if (system, inst) not in INSTANCES:
                continue
            run, sp, claim, _ = problem(name, inst)
            model(system, inst).compile()
            falsify(run, sp, claim, budget=20, seed=0, method="cmaes", progress=False)  # warm
            for seed in seeds:
                run.concurrent = False
                ser, ts = _trial(run, sp, claim, seed, a.budget)
                run.concurrent = True
                pip, tp = _trial(run, sp, claim, seed, a.budget)
                if not np.array_equal(ser.history, pip.history):
                    raise AssertionError(f"{name} instance {inst} seed {seed}: the pipelined "
                                         f"trial judged other runs")
                rows.append((name, inst, ts, tp))
                print(f"{name:7} {inst:>2} {seed:>4} {ser.evaluations:>5} | {ts[0]:>11.2f} "
                      f"{ts[1]:>6.2f} | {tp[0]:>14.2f} {tp[1]:>6.2f} {tp[2]:>6.2f} | "
                      f"{os.getloadavg()[0]:.1f}")
    print("\nmedians per requirement and instance (seconds per trial):")
    print(f"{'req':7} {'in':>2} | {'serial wall':>11} {'cpu':>6} | {'pipelined wall':>14} "
          f"{'cpu':>6} {'bound on 2 free cores':>22}")
    for key in dict.fromkeys((r[0], r[1]) for r in rows):
        sel = [r for r in rows if (r[0], r[1]) == key]
        med = [statistics.median(r[k][i] for r in sel) for k in (2, 3) for i in range(3)]
        bound = statistics.median(max(r[3][2], r[3][1] / 2) for r in sel)
        print(f"{key[0]:7} {key[1]:>2} | {med[0]:>11.2f} {med[1]:>6.2f} | {med[3]:>14.2f} "
              f"{med[4]:>6.2f} {bound:>22.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
