"""Watched functions: what recording crossings costs, against the same run without.

A pendulum x'' = -sin x (rtol 1e-8) watched for its velocity's zeros (the
turning points) and its angle's, on the Python path, on the vectorized
one (100 rows) and on the compiled one (the same definition, rewritten;
one run and ``simulate_many`` of the 100 rows); and scipy's ``solve_ivp``
with the same two functions as non-terminal events, for reference. Prints
wall times, the ratios with/without watches and compiled/Python (measured
in the same run; the compiled kernels compiled before timing), and the
largest difference of the turning points between hybridsim and solve_ivp
and between the compiled and Python paths.

Run: ``python benchmarks/bench_watch.py [--t-max 200] [--rows 100]``
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import solve_ivp

import hybridsim as hs

RTOL, ATOL = 1e-8, 1e-10


def swing(x):
    dx = np.empty_like(x)
    dx[..., 0] = x[..., 1]
    dx[..., 1] = -np.sin(x[..., 0])
    return dx


def turn_and_angle(x):
    w = np.empty_like(x)
    w[..., 0] = x[..., 1]
    w[..., 1] = x[..., 0]
    return w


def pendulum(watch):
    return hs.HybridSystem.from_functions(
        flow_map=swing, state_dim=2, watch=turn_and_angle if watch else None,
        vectorized=True)


def best(fn, repeat=3):
    out, dt = None, np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        dt = min(dt, time.perf_counter() - t)
    return out, dt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-max", type=float, default=200.0)
    ap.add_argument("--rows", type=int, default=100)
    a = ap.parse_args()
    x0 = [1.0, 0.0]
    plain, t0 = best(lambda: hs.simulate(pendulum(False), x0, a.t_max, rtol=RTOL, atol=ATOL))
    watched, t1 = best(lambda: hs.simulate(pendulum(True), x0, a.t_max, rtol=RTOL, atol=ATOL))
    assert np.array_equal(plain.x, watched.x)
    print(f"python path, one run to t={a.t_max:g}: {plain.stats['steps']} steps, "
          f"{len(watched.crossings)} crossings; {t0 * 1e3:.1f} ms without watches, "
          f"{t1 * 1e3:.1f} ms with: ratio {t1 / t0:.2f}")
    X = np.column_stack([np.linspace(0.5, 1.5, a.rows), np.zeros(a.rows)])
    _, v0 = best(lambda: hs.simulate_vectorized(pendulum(False), X, a.t_max, rtol=RTOL,
                                                atol=ATOL), 1)
    arcs, v1 = best(lambda: hs.simulate_vectorized(pendulum(True), X, a.t_max, rtol=RTOL,
                                                   atol=ATOL), 1)
    print(f"vectorized path, {a.rows} rows: {v0:.2f} s without watches, {v1:.2f} s with: "
          f"ratio {v1 / v0:.2f} ({sum(len(c.crossings) for c in arcs)} crossings)")
    kw = dict(rtol=RTOL, atol=ATOL, backend="compiled")
    sw, sp = pendulum(True), pendulum(False)
    hs.simulate(sw, x0, 1.0, **kw)           # the kernels compiled (or loaded) first
    hs.simulate(sp, x0, 1.0, **kw)
    cplain, c0 = best(lambda: hs.simulate(sp, x0, a.t_max, **kw), 5)
    cw, c1 = best(lambda: hs.simulate(sw, x0, a.t_max, **kw), 5)
    assert np.array_equal(cplain.x, cw.x) and len(cw.crossings) == len(watched.crossings)
    dt = np.max(np.abs(cw.crossings.t - watched.crossings.t))
    print(f"compiled path, one run: {c0 * 1e3:.2f} ms without watches, {c1 * 1e3:.2f} ms "
          f"with: ratio {c1 / c0:.2f}; against the Python path with watches: "
          f"{t1 / c1:.0f}x faster; crossings' largest difference {dt:.1e}")
    _, m0 = best(lambda: hs.simulate_many(sp, X, a.t_max, **kw), 1)
    many, m1 = best(lambda: hs.simulate_many(sw, X, a.t_max, **kw), 1)
    print(f"compiled simulate_many, {a.rows} rows: {m0:.3f} s without watches (parallel), "
          f"{m1:.3f} s with (rows in turn): ratio {m1 / m0:.2f}; against the vectorized "
          f"path with watches: {v1 / m1:.0f}x faster "
          f"({sum(len(c.crossings) for c in many)} crossings)")

    def turn(t, y):
        return y[1]

    def angle(t, y):
        return y[0]
    ref, s = best(lambda: solve_ivp(lambda t, y: [y[1], -np.sin(y[0])], (0, a.t_max), x0,
                                    rtol=RTOL, atol=ATOL, events=[turn, angle]))
    ours = watched.crossings.select(which=0).t
    theirs = ref.t_events[0][ref.t_events[0] > 0.0]      # solve_ivp also reports x0's zero
    k = min(len(ours), len(theirs))
    print(f"solve_ivp with the two events: {s * 1e3:.1f} ms; turning points "
          f"{len(ours)} here, {len(theirs)} there (after t=0), largest difference "
          f"{np.max(np.abs(ours[:k] - theirs[:k])):.2e} (each to its own solver's error)")


if __name__ == "__main__":
    main()
