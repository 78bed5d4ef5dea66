"""Reduction memory benchmark: a streaming reduction over many runs in bounded memory.

``hybridsim.estimate.accumulate`` reduces seeded runs of a cheap compiled
system, chunk by chunk, into one :class:`hybridsim.estimate.Stats`: the mean,
variance, min/max, exceedance counts and histogram quantiles of the state on
an ordinary time grid, each chunk's arcs dropped once reduced. The system is
the library's timer (period 1, x' = 1, x -> 0 at 1) from x0 ~ U(0, 1) to
t = 3, compiled (``backend="compiled"``); its exact law at every t is U(0, 1)
(mean 1/2, variance 1/12), checked at the end.

Printed: the peak resident memory of the process (``resource.getrusage``,
``ru_maxrss``) and the wall time after each checkpoint (10^3, 10^4, ... runs up
to ``--runs``), so that the memory's flatness in the number of runs shows.
Run: ``python benchmarks/bench_reduction_memory.py [--runs 10000000] [--batch
10000] [--quick]`` (``--quick``: 10^5 runs). Here (2 cores, idle at the start, the numba
cache warm) 10^7 runs took 247 s of wall at 370 MB peak: 358 MB after start-up
(numpy, scipy, numba and the kernels loaded), 370 MB from 10^4 runs on, flat to
10^7 (about 40,000 runs/s throughout).
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import resource
import time

import numpy as np

from hybridsim.estimate import Stats, accumulate
from hybridsim.falsification import batch_run
from hybridsim.library import Timer


def peak_mb():
    """The process's peak resident memory so far, MB (``ru_maxrss`` is in kB on Linux)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=float, default=None, help="runs in all (default 1e7)")
    ap.add_argument("--batch", type=int, default=10_000,
                    help="runs simulated and reduced at once (default 10,000)")
    ap.add_argument("--quick", action="store_true", help="10^5 runs (unless --runs is given)")
    args = ap.parse_args(argv)
    runs = int(1e5 if args.quick and args.runs is None else args.runs or 1e7)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.1f}, Python {platform.python_version()}, numpy "
          f"{np.__version__}")
    grid = np.linspace(0.0, 3.0, 31)
    stats = Stats(t=grid, signal=0, thresholds=[0.5, 0.9], bins=(0.0, 1.0, 50))
    run = batch_run(Timer(1.0), lambda rng: [rng.uniform()], 3.0, backend="compiled")
    accumulate(run, stats.empty_like(), 100, seed=1, batch=100)     # compile or load
    print(f"after start-up (import, compile or load): peak RSS {peak_mb():.0f} MB")
    print(f"{'runs':>12} {'wall s':>9} {'runs/s':>9} {'peak RSS MB':>12}")
    done, t0 = 0, time.perf_counter()
    peaks = []
    marks = [10 ** k for k in range(3, 1 + int(math.log10(runs)))] + [runs]
    for mark in sorted(set(m for m in marks if m <= runs)):
        # the next runs, a study of their own seed (independent of the others'), merged in
        accumulate(run, stats, mark - done, seed=np.random.SeedSequence(1, spawn_key=(mark,)),
                   batch=args.batch)
        done = mark
        w = time.perf_counter() - t0
        peaks.append(peak_mb())
        print(f"{done:>12,} {w:>9.1f} {done / w:>9.0f} {peaks[-1]:>12.0f}", flush=True)
    m, v = stats.mean[:, 0], stats.variance[:, 0]
    se = stats.std_error[:, 0]
    z = np.max(np.abs(m - 0.5) / se)
    print(f"mean on the grid within {z:.1f} standard errors of 1/2; variance "
          f"{v.min():.5f}..{v.max():.5f} (exact 1/12 = {1 / 12:.5f}); median "
          f"{np.median(stats.quantile(0.5)[:, 0]):.3f}; P(x > 0.9) "
          f"{stats.exceedance()[:, 0, 1].mean():.4f} (exact 0.1)")
    grow = f"{peaks[-1] - peaks[-2]:+.0f} MB since the checkpoint before" if len(peaks) > 1 else ""
    print(f"RESULT {done:,} runs of a streaming reduction: peak RSS {peak_mb():.0f} MB "
          f"({grow}), {time.perf_counter() - t0:.0f} s wall")


if __name__ == "__main__":
    main()
