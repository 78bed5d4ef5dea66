"""The papers' observers on the compiled path: two Monte Carlo studies, compiled
against the vectorized numpy batch measured in the same run.

1. Li-Sanfelice's H_c (17)-(18) on the seeded random design of
   ``bench_observers_scale.py`` (n = 4, p = 2), 1,000 bounded sinusoidal
   noise realisations (``--quick`` too), RK45 rtol 1e-10, atol 1e-12, to
   1.5 delta (one jump each); compiled with DOP853 too (``method="DOP853"``,
   the method for so tight a tolerance: about 20 steps a run against RK45's
   140), against the same vectorized RK45 batch.
2. The distributed finite-time observer (7)-(8) over a directed ring of 8
   nodes, 30 band-limited noise realisations, RK45 rtol 1e-8, atol 1e-10,
   to t = 1 s.
3. Mazenc-Malisoff's sampled observer (39) (literal realisation, omega in
   (13)) with the DC motor (65), samples every 0.01 s, 20 initial states of
   the motor (``gramian_delay.population``, as in ``bench_delays.py``), RK45
   rtol 1e-8, atol 1e-10, to t = 0.3 s: a delay equation, its flow reading
   psi(t - tau) (the compiled path's ``delays``).

Each study is one interconnection (noise generator -> plant -> observer)
whose batch of realisations is a batch of initial states: the vectorized
path integrates all rows together in numpy (``hs.simulate_many``), the
compiled path lowers the interconnection (``hybridsim.compiled.lower``) and
runs the rows in parallel compiled code (``backend="compiled"``). Timings
are warm (the lowered maps compiled once before, reported apart), over
interleaved rounds (vectorized, compiled, vectorized, ...), medians; the
results of the two paths are compared row by row.

Run: ``python benchmarks/bench_observers_compiled.py [--rounds 5]
[--only hc,ring,gramian]``
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

import hybridsim as hs
from observers import distributed as dist
from observers import li_sanfelice as ls
from observers.distributed.example import noise_batch as dist_noise_batch
from observers.distributed.example import random_system
from observers.gramian_delay.example import population
from observers.li_sanfelice.design import random_design
from observers.li_sanfelice.example import noise_batch as ls_noise_batch
from observers.li_sanfelice.systems import BoundedNoiseGenerator


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def hc_study(N):
    design = random_design(0, 4, 2)
    obs = ls.ConstantNoiseObserver(design)
    gen = BoundedNoiseGenerator(design.p, 3)
    S = gen.random_states(N, 0.1, w_max=5.0, seed=0)
    rng = np.random.default_rng(1)
    sysm, x0s = ls_noise_batch(obs, rng.normal(size=4), np.zeros(4), S, gen)
    kw = dict(t_max=1.5 * design.delta, rtol=1e-10, atol=1e-12)

    def result(arcs):
        return np.array([ls.errors(a, obs).e[np.flatnonzero(a.j == 1)[0]] for a in arcs])
    return f"H_c Monte Carlo, {N} noise realisations", sysm, x0s, kw, result


def ring_study(R, N=8, t_sim=1.0):
    A, C, G = random_system(N, seed=1, graph="ring")
    dsg = dist.design(A, C, G, warn=False)
    x0 = np.random.default_rng(0).normal(size=A.shape[0])
    obs = dist.DistributedObserver(dsg)
    sysm, X = dist_noise_batch(obs, x0, power=1e-4, seeds=range(R), t_max=t_sim)
    kw = dict(t_max=t_sim, rtol=1e-8, atol=1e-10)

    def result(arcs):
        return np.array([dist.errors(a, obs)["norm"][-1] for a in arcs])
    return f"distributed ring of {N}, {R} noise realisations", sysm, X, kw, result


def gramian_study(P=20):
    from observers import gramian_delay as gd
    ex = gd.dc_motor(100.0, 0.1)
    obs = ex.sampled_observer(period=0.01)
    X = ex.chi0 + np.random.default_rng(1).uniform(-0.3, 0.3, (P, 3))
    sysm, rows = population(obs, X)
    kw = dict(t_max=0.3, rtol=1e-8, atol=1e-10)

    def result(arcs):            # xi_1 - xi_e of (13) at the end of each run
        return np.array([gd.errors(a, obs).e[-1] for a in arcs])
    return f"Mazenc-Malisoff (39) with the DC motor, {P} initial states", sysm, rows, kw, result


def compare(study, rounds, methods=()):
    """The study's batch, vectorized against compiled (RK45), and compiled with
    each of ``methods`` too (timed in the same rounds)."""
    name, sysm, x0s, kw, result = study
    from hybridsim.compiled import lower
    _, compile_s = _timed(lambda: lower(sysm).compile())
    hs.simulate_many(sysm, x0s[:2], backend="compiled", **kw)          # warm
    for m in methods:       # its kernel compiled (once per machine) or loaded
        hs.simulate_many(sysm, x0s[:2], backend="compiled", method=m, **kw)
    tv, tc = [], []
    tm = {m: [] for m in methods}
    out = {}
    for _ in range(rounds):
        vec, t = _timed(lambda: hs.simulate_many(sysm, x0s, **kw))
        tv.append(t)
        cc, t = _timed(lambda: hs.simulate_many(sysm, x0s, backend="compiled", **kw))
        tc.append(t)
        for m in methods:
            out[m], t = _timed(lambda m=m: hs.simulate_many(sysm, x0s, backend="compiled",
                                                            method=m, **kw))
            tm[m].append(t)
    rv, rc = result(vec), result(cc)
    dev = float(np.max(np.abs(rc - rv)))
    mv, mc = statistics.median(tv), statistics.median(tc)
    # specialised: the maps compiled into the kernel, cached on disk by structure
    _, spec_s = _timed(lambda: lower(sysm, specialize=True).compile())
    hs.simulate_many(sysm, x0s[:2], backend="compiled", **kw)
    ts = [_timed(lambda: hs.simulate_many(sysm, x0s, backend="compiled", **kw))[1]
          for _ in range(rounds)]
    ms = statistics.median(ts)
    print(f"{name}: vectorized {mv:.3f} s (min {min(tv):.3f}), compiled {mc:.3f} s "
          f"(min {min(tc):.3f}); {mv / mc:.1f}x; compiling the lowered maps once: "
          f"{compile_s:.1f} s; results differ by at most {dev:.1e}; specialised "
          f"{ms:.3f} s (its kernel compiled or loaded from disk in {spec_s:.1f} s)")
    print(f"RESULT {name}: compiled {mc:.3f} s ({ms:.3f} s specialised) vs vectorized "
          f"{mv:.3f} s ({mv / min(mc, ms):.1f}x), max deviation {dev:.0e}")
    for m in methods:
        mm = statistics.median(tm[m])
        dm = float(np.max(np.abs(result(out[m]) - rv)))
        print(f"{name}, compiled with {m}: {mm:.3f} s (min {min(tm[m]):.3f}); "
              f"{mv / mm:.1f}x the vectorized RK45 batch, {mc / mm:.1f}x the compiled RK45 "
              f"one; results differ from the vectorized ones by at most {dm:.1e}")
        print(f"RESULT {name}, {m}: compiled {mm:.3f} s vs vectorized RK45 {mv:.3f} s "
              f"({mv / mm:.1f}x), max deviation {dm:.0e}")
    return mc


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="accepted for run_all.py; the sizes are the same")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--only", default="hc,ring,gramian",
                    help="the studies to run, comma-separated (default: all three)")
    a = ap.parse_args(argv)
    only = set(a.only.split(","))
    import numba
    print(f"{os.cpu_count()} cores, numba {numba.__version__}, {numba.get_num_threads()} "
          f"threads; medians of {a.rounds} interleaved rounds")
    if "hc" in only:
        # issue 27's size in both modes (the vectorized batch: about 2 s a round)
        compare(hc_study(1000), a.rounds, methods=("DOP853",))
    if "ring" in only:
        compare(ring_study(30), a.rounds)
    if "gramian" in only:
        compare(gramian_study(20), a.rounds)


if __name__ == "__main__":
    main()
