"""Stochastic systems on the compiled path (issue 44): speed against baselines of the
same run, and known answers within 3 standard errors.

Rows:

1. TCP/AIMD (x' = 1, x -> x/2 at rate x) to T = 100: a compiled ``simulate_many``
   batch of N paths beside the Python path on a few paths (time per path, and the
   ratio); the time 10^6 paths would take at the batch's rate (the issue's target:
   10 s on two cores); stationary E[X^2] = 2 and E[X^4] = 48/7 from each path's time
   average over [20, 100] (exact on each flow: x' = 1), standard errors over the paths.
   Then the same batch reduced (``simulate_many(..., stats=)``: no arcs), on the generic
   and the specialised kernel, with E[X(100)^2] and E[X(100)^4] over the paths.
2. Standard Brownian motion, barrier 1 on [0, 1], Euler-Maruyama with the Brownian-bridge
   correction, compiled: P(hit) = 2 (1 - Phi(1)) = 0.31731 at dt = 0.1 and 0.01, beside
   the Python path on fewer paths (the same arcs per seed; time per path and the ratio).
3. The compiled SDE stepper against a hand-written numba Euler-Maruyama loop on the same
   Brownian path (an Ornstein-Uhlenbeck process to T = 100, dt = 1e-3, no events; the loop
   draws each block's two normals as the path does, and keeps no samples): the best of 10
   of each, the stepper with its maps returning arrays and written into ``out``
   (``flow_map(x, t, j, p, out)``), and the difference of the final states. Measured
   (2 cores, 8 December 2026): the loop 3.4 ms; the stepper with maps returning arrays
   16.7-16.9 ms (4.9-5.0x: their two arrays a step), written into ``out`` 7.5-8.8 ms
   (2.2-2.6x: beyond the loop's work, two calls of the maps by address and the arc's
   100,001 samples a run). Before the grid loop was a kernel of its own (called by its
   address; linked into the stepper's module, LLVM spilled its counters to the stack):
   10.9-11.4 ms (3.2-3.3x) loaded from the disk cache, 7-8 ms only in a process that had
   just compiled it (2 December's 5.3-6.4 ms).

Run: ``python benchmarks/bench_stochastic_compiled.py [--quick] [--paths N]``
"""
from __future__ import annotations

import argparse
import math
import sys
import time
import warnings

import numpy as np
from scipy.stats import norm

import hybridsim as hs
from hybridsim.library import AIMD


def aimd_moments(batch, powers=(2, 4), t_burn=20.0):
    """Each path's time averages of x^k over [t_burn, t_f] (its flows cut at t_burn;
    x' = 1: the integral of x^k over a flow from xa to xb is (xb^(k+1) - xa^(k+1))/(k+1)),
    then their mean and standard error over the paths. The window starts at t_burn
    itself, not at the first jump after it (a window opened at a jump sees x just
    halved: biased low by about 1/T of the mean)."""
    out = np.empty((len(batch), len(powers)))
    for i, a in enumerate(batch):
        t, j, x = a.t, a.j, a.x[:, 0]
        keep = (j[1:] == j[:-1]) & (t[1:] > t_burn)
        ta = np.maximum(t[:-1][keep], t_burn)
        xa = x[:-1][keep] + (ta - t[:-1][keep])
        xb = x[1:][keep]
        length = (t[1:][keep] - ta).sum()
        for c, k in enumerate(powers):
            out[i, c] = ((xb ** (k + 1) - xa ** (k + 1)) / (k + 1)).sum() / length
    return out.mean(axis=0), out.std(axis=0, ddof=1) / math.sqrt(len(out))


def line(name, value, ours, se):
    ok = abs(ours - value) <= 3 * se
    print(f"  {name:44s} {value:10.6g} {ours:10.6g} {se:9.3g} {'ok' if ok else 'OFF':>4s}")
    return ok


def bench_aimd(n_paths, n_python):
    s = AIMD()
    hs.simulate_many(s, np.ones((8, 1)), 100.0, backend="compiled")      # compiled, loaded
    t0 = time.perf_counter()
    B = hs.simulate_many(s, np.ones((n_paths, 1)), 100.0, backend="compiled")
    tc = time.perf_counter() - t0
    t0 = time.perf_counter()
    for r in range(n_python):
        hs.simulate(s, [1.0], 100.0, seed=r)
    tp = time.perf_counter() - t0
    per_c, per_p = tc / n_paths, tp / n_python
    print(f"AIMD to T=100 ({B.jump_counts.mean():.0f} jumps a path): compiled {n_paths} paths "
          f"{tc:.2f} s ({per_c * 1e6:.0f} us/path); Python {n_python} paths {tp:.2f} s "
          f"({per_p * 1e6:.0f} us/path); ratio {per_p / per_c:.0f}x per path")
    print(f"  10^6 paths at this rate: {per_c * 1e6:.0f} s (target 10 s on two cores)")
    (m2, m4), (s2, s4) = aimd_moments(B)
    oks = [line("AIMD E[X^2]", 2.0, m2, s2), line("AIMD E[X^4]", 48 / 7, m4, s4)]
    return oks + bench_aimd_reduced(n_paths, tc)


def nrt_allocations(run):
    """numba's allocations (NRT meminfos) made by ``run()``: its statistics switched on
    for that call only (they cost an atomic count an allocation)."""
    from numba.core.runtime import _nrt_python, rtsys
    was = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        a0 = rtsys.get_allocation_stats().alloc
        run()
        return rtsys.get_allocation_stats().alloc - a0
    finally:
        if not was:
            _nrt_python.memsys_disable_stats()


def bench_aimd_reduced(n_paths, t_arcs):
    """Row 1 reduced: ``simulate_many(..., stats=)`` keeps no arc (the kernel keeps each
    row's state at t = 100 only), generic and with the system lowered ``specialize=True``
    (its kernel compiled with the maps in: about 15 s of CPU once per machine); CPU time
    (the machine is shared) beside the wall time, numba's allocations a path (counted on
    200 more paths), and the ensemble moments at t = 100 (stationary by then), standard
    errors over the paths.

    Measured (2 shared cores at load ~7, 20,000 paths, both versions in one sitting,
    4 December 2026), CPU a path: generic 314 -> 235 us (2,679 -> 1,271 allocations a
    path), specialised 211 -> 115 us (1,549 -> 144: the clock-augmented jump map's
    array a jump is what is left), 10^6 paths on two cores at that rate 105 -> 57 s,
    once the rewritten flow and jump maps were written into the run's own rows, the
    event's outcome and the sample buffers made free of reference counts. What is left
    (perf, gdb counts of the reference-count calls): about 11,000 reference-count calls
    a path on array variables reassigned in the run core's loop (views, no atomic
    count, still calls), the steps and the event search themselves."""
    from hybridsim.compiled import lower
    from hybridsim.estimate import Stats
    oks = []
    for label, spec in (("generic kernel", False), ("specialised kernel", True)):
        s = AIMD()
        lower(s, specialize=spec)

        def moments():
            return Stats(t=[100.0], signal=lambda x: np.stack([x[..., 0] ** 2, x[..., 0] ** 4],
                                                              axis=-1))
        hs.simulate_many(s, np.ones((8, 1)), 100.0, backend="compiled", stats=moments(),
                         seed=0)                                       # compiled, loaded
        c0, t0 = time.process_time(), time.perf_counter()
        st = hs.simulate_many(s, np.ones((n_paths, 1)), 100.0, backend="compiled",
                              stats=moments(), seed=1)
        cpu, wall = time.process_time() - c0, time.perf_counter() - t0
        allocs = nrt_allocations(lambda s=s: hs.simulate_many(
            s, np.ones((200, 1)), 100.0, backend="compiled", stats=moments(), seed=2)) / 200
        print(f"AIMD reduced (stats=, no arcs), {label}: {n_paths} paths {wall:.2f} s wall, "
              f"{cpu:.2f} s CPU ({cpu / n_paths * 1e6:.0f} us CPU/path, {allocs:.0f} numba "
              f"allocations/path; {t_arcs / wall:.2f}x the batch with arcs); 10^6 paths: "
              f"{cpu / n_paths * 1e6 / 2:.0f} s on two cores at this CPU rate (target 10 s)")
        (m2, m4), (s2, s4) = st.mean[0], st.std_error[0]
        oks += [line(f"AIMD E[X(100)^2], {label}", 2.0, m2, s2),
                line(f"AIMD E[X(100)^4], {label}", 48 / 7, m4, s4)]
    return oks


def barrier():
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([0.0]), jump_map=lambda x: x,
        diffusion=lambda x: np.array([1.0]), jump_guard=lambda x: x[0] - 1.0, state_dim=1)


def bench_barrier(n_paths, n_python):
    p_hit = 2 * norm.sf(1.0)
    oks = []
    b = barrier()
    hs.simulate_many(b, np.zeros((8, 1)), 1.0, 1, method="EM", max_step=0.1,
                     backend="compiled")
    for dt in (0.1, 0.01):
        t0 = time.perf_counter()
        B = hs.simulate_many(b, np.zeros((n_paths, 1)), 1.0, 1, method="EM", max_step=dt,
                             backend="compiled")
        tc = time.perf_counter() - t0
        t0 = time.perf_counter()
        for r in range(n_python):
            hs.simulate(b, [0.0], 1.0, 1, method="EM", max_step=dt, seed=r)
        tp = time.perf_counter() - t0
        p = float(np.mean(B.jump_counts > 0))
        se = math.sqrt(p_hit * (1 - p_hit) / n_paths)
        print(f"BM barrier, dt={dt}: compiled {n_paths} paths {tc:.2f} s "
              f"({tc / n_paths * 1e6:.0f} us/path); Python {n_python} paths {tp:.2f} s "
              f"({tp / n_python * 1e6:.0f} us/path); ratio "
              f"{(tp / n_python) / (tc / n_paths):.0f}x per path")
        oks.append(line(f"P(hit), bridge-corrected, dt={dt}", p_hit, p, se))
    return oks


def bench_stepper():
    from numba import njit

    from hybridsim.compiled import CompiledSystem
    from hybridsim.compiled._draws import _node_key, normals3, path_keys
    from hybridsim.compiled._stochastic import simulate_sde_compiled

    @njit
    def em_by_hand(x, h, steps, key):
        z = np.empty(4)
        rh = math.sqrt(h)
        w = 0.0
        for k in range(steps):
            normals3(_node_key(key, k, 0, 0), z, 2)     # block k's increment: sqrt(h) z0
            w_next = w + rh * z[0]
            x = x + (-x) * h + 0.5 * (w_next - w)
            w = w_next
        return x

    def ou_flow(x, t, j, p, out):
        out[0] = -x[0]

    def ou_noise(x, t, j, p, out):
        out[0] = 0.5
    forms = {"maps returning arrays": CompiledSystem(
                 flow_map=lambda x, t, j, p: -x, diffusion=lambda x, t, j, p: np.full(1, 0.5),
                 state_dim=1),
             "maps written into out": CompiledSystem(flow_map=ou_flow, diffusion=ou_noise,
                                                     state_dim=1)}
    h, T, seed = 1e-3, 100.0, 11
    steps = round(T / h)
    key = path_keys(seed, 0, 1)[0]
    em_by_hand(1.0, h, 10, key)
    for ou in forms.values():
        simulate_sde_compiled(ou, [1.0], 1.0, method="EM", max_step=h, seed=seed)
    best = {name: math.inf for name in ["hand", *forms]}
    for _ in range(10):                 # the best of 10 of each, interleaved
        t0 = time.perf_counter()
        xh = em_by_hand(1.0, h, steps, key)
        best["hand"] = min(best["hand"], time.perf_counter() - t0)
        for name, ou in forms.items():
            t0 = time.perf_counter()
            a = simulate_sde_compiled(ou, [1.0], T, method="EM", max_step=h, seed=seed)
            best[name] = min(best[name], time.perf_counter() - t0)
            assert abs(a.x[-1, 0] - xh) < 1e-12, name
    th = best["hand"]
    print(f"EM stepper, OU to T={T:g}, dt={h:g} ({steps} steps; best of 10): hand-written "
          f"numba loop {th * 1e3:.1f} ms; final states differ by {abs(a.x[-1, 0] - xh):.1e}")
    for name in forms:
        print(f"  compiled SDE stepper, {name}: {best[name] * 1e3:.1f} ms, ratio "
              f"{best[name] / th:.1f}x (target <= 2x)")
    into = best["maps written into out"]
    print(f"RESULT EM stepper (OU, {steps} steps, maps written into out): {into * 1e3:.1f} ms, "
          f"{into / th:.2f}x the hand-written numba loop's {th * 1e3:.1f} ms (target <= 2x)")


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--paths", type=int, default=None, help="AIMD paths (default 20000)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    n = args.paths or (2000 if args.quick else 20000)
    print(f"{'':46s} {'value':>10s} {'ours':>10s} {'std err':>9s}")
    oks = bench_aimd(n, 5 if args.quick else 20)
    oks += bench_barrier(20000 if args.quick else 100000, 100 if args.quick else 500)
    bench_stepper()
    print(f"RESULT {sum(oks)}/{len(oks)} known answers within 3 standard errors")
    return 0


if __name__ == "__main__":
    sys.exit(main())
