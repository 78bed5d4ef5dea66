"""Memory benchmark: a timer system run for many jumps with ``hs.simulate``.

The timer x' = 1 on C = {x <= 1}, x+ = 0 on D = {x >= 1} (given by a
jump_guard and a flow_guard) is run to ``j_max`` jumps. Printed: wall time,
samples returned, bytes of the returned arrays (t, j, x), the peak memory
traced by ``tracemalloc`` during the run and the memory still held after it,
each as a ratio to the returned bytes (no quadratic copying: the ratios stay
flat as the run grows; the sample buffer doubles as it grows, so the peak is
about 2x the returned samples).

A pilot of 10^4 jumps estimates the cost of 10^6; if that exceeds
``--budget`` seconds (default 180), the wall-time run is 10^5 jumps and the
10^6 figures are extrapolated linearly (said so in the output).
``tracemalloc`` slows the run 4-6x, so the peak is traced on shorter runs
(``--traced``, default 10^4 and 2*10^4 jumps) and its ratio to the returned
bytes is extrapolated; the wall-time run reports its peak RSS growth instead.

Run: ``python benchmarks/bench_memory.py [--jumps N] [--budget S] [--traced N1 N2 ...]``
"""
from __future__ import annotations

import argparse
import gc
import platform
import resource
import time
import tracemalloc

import numpy as np

import hybridsim as hs


def timer_system():
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        jump_guard=lambda x: x[0] - 1.0, flow_guard=lambda x: 1.0 - x[0], state_dim=1)


def run(jumps):
    """One run of ``jumps`` jumps; returns (arc, wall seconds)."""
    sysobj = timer_system()
    t = time.perf_counter()
    arc = hs.simulate(sysobj, [0.0], t_max=np.inf, j_max=jumps, progress=False,
                      max_steps=np.inf, max_samples=np.inf)   # a deliberately long run
    dt = time.perf_counter() - t
    if arc.jump_count != jumps:
        raise RuntimeError(f"expected {jumps} jumps, got {arc.jump_count}: {arc.message}")
    return arc, dt


def returned_bytes(arc):
    return arc.t.nbytes + arc.j.nbytes + arc.x.nbytes


def traced(jumps):
    """Peak and held memory (tracemalloc) of one run, and its returned bytes."""
    gc.collect()
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    arc, dt = run(jumps)
    gc.collect()
    held, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return dict(jumps=jumps, samples=len(arc), bytes=returned_bytes(arc), peak=peak - base,
                held=held - base, wall=dt)


def mb(b):
    return f"{b / 2**20:9.2f} MB"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jumps", type=int, default=None,
                    help="jumps of the wall-time run (default: 10^6 if the pilot says it "
                         "fits in --budget, else 10^5)")
    ap.add_argument("--budget", type=float, default=180.0, help="seconds allowed for 10^6")
    ap.add_argument("--traced", type=int, nargs="*", default=[10**4, 2 * 10**4],
                    help="jump counts of the tracemalloc runs")
    args = ap.parse_args(argv)

    print(f"# timer system (jump_guard/flow_guard), hs.simulate, RK45 defaults; "
          f"{platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}")
    _pilot, t_pilot = run(10**4)
    est = t_pilot * 100
    jumps = args.jumps
    if jumps is None:
        jumps = 10**6 if est <= args.budget else 10**5
    print(f"pilot: 10^4 jumps in {t_pilot:.2f} s -> 10^6 jumps estimated at {est:.0f} s "
          f"(budget {args.budget:.0f} s): running {jumps:.0e} jumps")

    # wall-time run (no tracing): time, samples, bytes, peak RSS growth
    gc.collect()
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    arc, wall = run(jumps)
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    nbytes = returned_bytes(arc)
    samples = len(arc)
    del arc
    gc.collect()

    # traced runs: peak and held memory against the returned bytes
    rows = [traced(n) for n in args.traced]

    print()
    print(f"{'jumps':>9}  {'wall [s]':>9}  {'samples':>9}  {'returned':>12}  {'peak':>12}  "
          f"{'held after':>12}  {'peak/ret':>8}  {'held/ret':>8}")
    for r in rows:
        print(f"{r['jumps']:9d}  {r['wall']:9.2f}  {r['samples']:9d}  {mb(r['bytes'])}  "
              f"{mb(r['peak'])}  {mb(r['held'])}  {r['peak'] / r['bytes']:8.2f}  "
              f"{r['held'] / r['bytes']:8.2f}   (traced: wall inflated)")
    drss = max(rss1 - rss0, 0) * 1024      # ru_maxrss is in KiB on Linux
    print(f"{jumps:9d}  {wall:9.2f}  {samples:9d}  {mb(nbytes)}  "
          f"{'(untraced)':>12}  {'':>12}  {'':>8}  {'':>8}   peak RSS growth {mb(drss)}")
    big = max(rows, key=lambda r: r["jumps"])   # fixed overheads weigh least there
    ratio = big["peak"] / big["bytes"]
    per_jump = wall / jumps
    if jumps < 10**6:
        scale = 10**6 / jumps
        print(f"\n10^6 jumps, EXTRAPOLATED linearly from the {jumps:.0e}-jump run "
              f"(10^6 would take more than {args.budget:.0f} s here): "
              f"wall ~{per_jump * 1e6:.0f} s, samples ~{samples * scale:.0f}, "
              f"returned ~{mb(nbytes * scale).strip()}, peak ~{mb(ratio * nbytes * scale).strip()} "
              f"(peak/returned ratio {ratio:.2f} of the {big['jumps']}-jump traced run)")
    else:
        print(f"\n10^6 jumps measured: wall {wall:.1f} s, {samples} samples, "
              f"returned {mb(nbytes).strip()}, peak ~{mb(ratio * nbytes).strip()} "
              f"(peak/returned ratio {ratio:.2f} of the {big['jumps']}-jump traced run)")
    print(f"cost per jump: {per_jump * 1e6:.0f} us; samples per jump: {samples / jumps:.2f}")
    held = big["held"] / big["bytes"]
    print(f"held after the run: {held:.2f}x the returned bytes "
          f"({'within' if held <= 2 else 'MORE than'} 2x); "
          f"peak during the run: {ratio:.2f}x (the sample buffer's spare capacity: it doubles "
          f"as it grows); flat ratios across run lengths = no quadratic copying")


if __name__ == "__main__":
    main()
