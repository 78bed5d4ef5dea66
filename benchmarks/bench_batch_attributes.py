"""Rows of their own parameters: ``hs.simulate_many(..., attributes=)`` on the
compiled path (one parallel batch, a ``p`` per row) against the same rows run one
after another with their attributes set (what ``batch_run(attributes_of=)`` did
before: ``hs.sweep`` of compiled single runs), in the same run.

Rows: a restitution sweep of the README's bouncing ball (a plain model, its maps
rewritten from source), and the chasing cars of ARCH-COMP (a CompiledSystem
whose input signal is its ``params``) against the same population with the
inputs carried in the state as constant components (the model before: here a
copy of its 22 values appended to the state, read by nobody, so only their cost
is measured). Times are the best of 3; the machine's cores are shared.
Measured (2 idle cores, 7 December 2026): the ball's 2,000 rows 57 ms as one
batch against 139 ms one by one (2.5x); CC's 256 signals 0.63 s against 1.24 s
with the inputs carried in the state (2.0x).

Run: ``python benchmarks/bench_batch_attributes.py [--rows N]``
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import hybridsim as hs
from hybridsim.library import BouncingBall


def best(fn, repeat=3):
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return min(out)


def bench_ball(rows):
    ball = BouncingBall()
    es = np.linspace(0.5, 0.95, rows)
    attrs = [{"e": float(e)} for e in es]
    X = np.tile([1.0, 0.0], (rows, 1))
    hs.simulate_many(ball, X[:4], 5.0, 20, attributes=attrs[:4], backend="compiled")

    def one_by_one():
        def make(e):
            ball.e = e
            return ball
        try:
            hs.sweep(make, es.tolist(), [1.0, 0.0], 5.0, 20, backend="compiled")
        finally:
            ball.e = 0.8
    batch = best(lambda: hs.simulate_many(ball, X, 5.0, 20, attributes=attrs,
                                          backend="compiled"))
    loop = best(one_by_one)
    a = hs.simulate_many(ball, X, 5.0, 20, attributes=attrs, backend="compiled")
    b = [hs.simulate(BouncingBall(restitution=float(e)), [1.0, 0.0], 5.0, 20,
                     backend="compiled") for e in es[:20]]
    same = all(np.array_equal(u.x, v.x) for u, v in zip(a, b))
    print(f"ball, {rows} restitutions: one batch {batch * 1e3:.1f} ms, rows one by one "
          f"{loop * 1e3:.1f} ms: {loop / batch:.1f}x (the first 20 rows equal single runs "
          f"to the bit: {same})")


def bench_cars(rows):
    from hybridsim.arch.spaces import model, space
    cc = model("CC", 1)
    sp = space("CC", 1)
    rng = np.random.default_rng(0)
    pts = [sp.point(sp.lo + (sp.hi - sp.lo) * rng.random(sp.dim)) for _ in range(rows)]
    P = [{"params": cc.input_params(p["u"].values[:, 0], p["u"].values[:, 1])} for p in pts]
    x0 = cc.initial_state()
    X = np.tile(x0, (rows, 1))
    hs.simulate_many(cc, X[:4], 100.0, attributes=P[:4], backend="compiled")
    # the inputs as constant components of the state, read by nobody: their cost only
    from numba import njit

    from hybridsim.arch import models as M
    from hybridsim.compiled import CompiledSystem
    n, k = len(x0), 2 * cc.times.size
    f, g, h, d = (njit(error_model="numpy")(fn) for fn in
                  (M.cc_flow, M.cc_jump, M.cc_guard, M.cc_jump_set))

    def flow(x, t, j, p, out):
        out[n:] = 0.0
        f(x[:n], t, j, p, out[:n])

    def jump(x, t, j, p):
        y = x.copy()
        y[:n] = g(x[:n], t, j, p)
        return y

    def guard(x, t, j, p):
        return h(x[:n], t, j, p)

    def jset(x, t, j, p):
        return d(x[:n], t, j, p)
    wide = CompiledSystem(flow_map=flow, jump_map=jump, jump_guard=guard, jump_set=jset,
                          state_dim=n + k, params=cc.params)
    XW = np.hstack([X, np.array([d["params"][-k:] for d in P])])
    hs.simulate_many(wide, XW[:4], 100.0, attributes=P[:4], backend="compiled")
    narrow = best(lambda: hs.simulate_many(cc, X, 100.0, attributes=P, backend="compiled"))
    widet = best(lambda: hs.simulate_many(wide, XW, 100.0, attributes=P, backend="compiled"))
    print(f"chasing cars, {rows} input signals to 100 s: inputs in params {narrow:.2f} s, "
          f"carried in the state too {widet:.2f} s: {widet / narrow:.2f}x")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rows", type=int, default=2000)
    a = ap.parse_args()
    bench_ball(a.rows)
    bench_cars(min(a.rows, 256))
