"""Peers benchmark: 1,000 bouncing balls, every row's jump times read, hybridsim
compiled against diffrax's ``jit(vmap)``, measured side by side in one run.

The ball: x = (h, v), h' = v, v' = -g, v+ = -e v at h = 0 while falling
(g = 9.81, e = 0.8), dropped from rest at 1,000 heights in [0.5, 2], 10
bounces each, rtol 1e-10 and atol 1e-12 on both sides.

* hybridsim: ``hs.simulate_many(BouncingBall(g, e), x0s, backend="compiled")``
  (the library's ball, its maps compiled as written; threads: numba's count),
  then every row's jump times read from the batch's ``jump_times`` array: what
  a study does with the batch, timed as one. Twice: with the engine's generic
  kernel (the default), and with a kernel specialised on the ball's maps
  (``hybridsim.compiled.lower(ball, specialize=True)`` first; compiled once,
  cached on disk).
* diffrax: ``jax.jit(jax.vmap(one))`` where ``one(h0)`` is a ``fori_loop`` (a
  while loop) over the bounces, each a ``diffeqsolve`` (Dopri5, a
  PIDController at the same tolerances, an ``Event`` on the height while
  falling, Newton root finding) from the last impact, the velocity reversed
  and scaled after it (``bench_compiled.diffrax_peer``, written from diffrax's
  documentation). Its compilation is excluded: a warm-up call first, then
  the timed calls. JAX on the CPU, float64. Skipped with a printed reason
  where diffrax is not installed (``pip install diffrax``).

Both are timed in interleaved rounds (each contender once per round, medians),
in wall time and in CPU time of this process (the CPU time does not move
when other work shares the machine; hybridsim's kernels run in numba's
thread count, diffrax's in one). Both answers are checked against the exact
impact times. Run: ``python benchmarks/bench_peers_batch.py [--n 1000]
[--jumps 10] [--rounds 15] [--quick]``.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import warnings

import numpy as np

import hybridsim as hs
from hybridsim.compiled import lower
from hybridsim.library import BouncingBall, bouncing_ball_jump_times

G, E = 9.81, 0.8
RTOL, ATOL = 1e-10, 1e-12


def interleaved(fns, rounds):
    """Medians over ``rounds`` rounds of every function of ``fns`` (a dict) once
    each, in turn: ``{name: (wall s, CPU s)}``."""
    wall = {k: [] for k in fns}
    cpu = {k: [] for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            c, t = time.process_time(), time.perf_counter()
            fn()
            wall[k].append(time.perf_counter() - t)
            cpu[k].append(time.process_time() - c)
    return {k: (float(np.median(wall[k])), float(np.median(cpu[k]))) for k in fns}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="balls (default 1000)")
    ap.add_argument("--jumps", type=int, default=10, help="bounces each (default 10)")
    ap.add_argument("--rounds", type=int, default=15, help="interleaved rounds (default 15)")
    ap.add_argument("--quick", action="store_true", help="7 rounds")
    args = ap.parse_args(argv)
    if args.quick:
        args.rounds = 7
    try:
        import numba
    except ImportError as e:
        print(f"skipped: the compiled path needs numba ({e}); pip install numba")
        return
    N, K = args.n, args.jumps
    h0 = np.random.default_rng(0).uniform(0.5, 2.0, N)
    x0s = np.column_stack([h0, np.zeros(N)])
    exact = bouncing_ball_jump_times(h0, K, G, E)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.1f}, Python {platform.python_version()}, numpy "
          f"{np.__version__}, numba {numba.__version__} ({numba.get_num_threads()} threads)")
    print(f"{N:,} balls x {K} bounces, rtol {RTOL:g}, atol {ATOL:g}")
    ball = BouncingBall(G, E)
    kw = dict(t_max=1e9, j_max=K, rtol=RTOL, atol=ATOL, backend="compiled")

    reads = []

    def ours():
        b = hs.simulate_many(ball, x0s, **kw)
        t = time.perf_counter()
        out = b.jump_times
        reads.append(time.perf_counter() - t)
        return out

    # the same ball with its maps compiled into a kernel of its own (a user's choice:
    # lower(system, specialize=True) once, then simulate_many as before)
    ball_s = BouncingBall(G, E)
    t = time.perf_counter()
    lower(ball_s, specialize=True)
    jt = ours()                         # maps compiled (or loaded from the disk cache)
    jts = hs.simulate_many(ball_s, x0s, **kw).jump_times
    print(f"hybridsim: first calls {time.perf_counter() - t:.2f} s (maps and the specialised "
          f"kernel compiled or loaded), jump times within {np.max(np.abs(jt - exact)):.1e} "
          f"of the exact ones (specialised: {np.max(np.abs(jts - exact)):.1e})")
    fns = {"ours": ours, "call": lambda: hs.simulate_many(ball, x0s, **kw),
           "spec": lambda: hs.simulate_many(ball_s, x0s, **kw).jump_times}
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path.insert(0, here)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from bench_compiled import diffrax_peer
    build, why = diffrax_peer()
    if build is None:
        print(f"diffrax peer skipped: {why}")
    else:
        import diffrax
        import jax
        t = time.perf_counter()
        dball = build(K, RTOL, ATOL, True)
        djt = dball(h0)                  # the warm-up call: jit compiles here
        print(f"diffrax {diffrax.__version__}, jax {jax.__version__} (CPU, float64): warm-up "
              f"call (compiles) {time.perf_counter() - t:.2f} s, excluded; jump times within "
              f"{np.max(np.abs(djt - exact)):.1e}")
        fns["diffrax"] = lambda: dball(h0)
    med = interleaved(fns, args.rounds)
    (w, c), (wc, _) = med["ours"], med["call"]
    wr = float(np.median(reads[1:]))
    print(f"hybridsim simulate_many + every row's jump times: {w * 1e3:.2f} ms wall, "
          f"{c * 1e3:.2f} ms CPU (the call {wc * 1e3:.2f} ms; reading the jump times "
          f"{wr * 1e3:.3f} ms wall, {wr / wc:.3f}x the call)")
    from bench_compiled import kernel_share
    split = np.array([kernel_share(lower(ball), x0s, **{k: v for k, v in kw.items()
                                                        if k != "backend"})
                      for _ in range(args.rounds)])
    tot, ker = np.median(split, axis=0)
    print(f"  of which the batch kernel {ker * 1e3:.2f} ms wall, the Python side (options, "
          f"pools, {N:,} arcs made on first access) {(tot - ker) * 1e3:.2f} ms (a "
          f"simulate_many_compiled call, medians of {args.rounds})")
    ws, cs = med["spec"]
    print(f"  the same, specialize=True: {ws * 1e3:.2f} ms wall, {cs * 1e3:.2f} ms CPU")
    if build is not None:
        dw, dc = med["diffrax"]
        print(f"diffrax jit(vmap): {dw * 1e3:.2f} ms wall, {dc * 1e3:.2f} ms CPU")
        print(f"RESULT {N:,} balls x {K} bounces with every row's jump times read / diffrax "
              f"jit(vmap): {w / dw:.2f}x wall, {c / dc:.2f}x CPU; specialize=True "
              f"{ws / dw:.2f}x wall, {cs / dc:.2f}x CPU (medians of {args.rounds} "
              f"interleaved rounds)")


if __name__ == "__main__":
    main()
