"""Compiled path benchmark: hybridsim.compiled against a hand-written numba loop
and the Python path, measured side by side in one run.

Workloads (rtol 1e-8, atol 1e-10 unless said):

* 30-bounce ball, one run (guards, exact impact times known);
* timer of period 1, 10,000 jumps;
* 1,000 balls x 10 jumps, batch (rtol 1e-10, atol 1e-12 as bench_batch.py);
* 100,000 balls x 10 jumps, batch (fits and finishes; peak memory printed).

Each is run by ``simulate_compiled`` / ``simulate_many_compiled`` (generic
kernel, cached on disk; and ``specialize=True``, maps inlined), by a
hand-written numba loop (Dormand-Prince 5(4) with scipy's step-size
controller, Illinois root-finding on the guard along the dense output, the
ball's physics written in; the "floor" of a compiled engine), and by the
Python path (``hs.simulate`` / ``hs.simulate_many``). First-call times
(fresh processes: import, compile or cache load, first run) are measured in
subprocesses.

Run: ``python benchmarks/bench_compiled.py [--quick] [--skip-big]``
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import resource
import subprocess
import sys
import time
import warnings

import numpy as np

warnings.simplefilter("ignore")

import numba  # noqa: E402
from numba import njit, prange  # noqa: E402
from scipy.integrate._ivp.rk import RK45  # noqa: E402

import hybridsim as hs  # noqa: E402
from hybridsim.compiled import CompiledSystem, simulate_compiled, simulate_many_compiled  # noqa: E402
from hybridsim.library import BouncingBall, BouncingBallBatch, Timer, bouncing_ball_jump_times  # noqa: E402

G, E = 9.81, 0.8
_A, _B, _C, _E, _P = (np.ascontiguousarray(v, dtype=np.float64)
                      for v in (RK45.A, RK45.B, RK45.C, RK45.E, RK45.P))


# ------------------------------------------------------------------ the hand-written floor
@njit(cache=True)
def _rhs(kind, y, g):
    out = np.empty(2)
    if kind == 0:                   # ball
        out[0] = y[1]
        out[1] = -g
    else:                           # timer
        out[0] = 1.0
        out[1] = 0.0
    return out


@njit(cache=True)
def _dense0(yold0, hq, x):
    """First component of the dense output at s = (t - told)/h."""
    return yold0 + (hq[0] * x + hq[1] * x * x + hq[2] * x * x * x + hq[3] * x * x * x * x)


@njit(cache=True)
def hand_written(kind, y0, t_max, n_jumps, rtol, atol, g, e, period, out):
    """DOPRI5 + Illinois on the guard, jump, restart: jump times into ``out``.

    kind 0: ball (guard -x0 crossing upward: the ball reaches the floor),
    kind 1: timer (guard x0 - period). Returns the number of jumps.
    """
    t = 0.0
    y = y0.copy()
    K = np.empty((7, 2))
    h = 1e-3
    f = _rhs(kind, y, g)
    jumps = 0
    eps = 2.220446049250313e-16
    while jumps < n_jumps and t < t_max:
        # one accepted step
        while True:
            if t + h > t_max:
                h = t_max - t
            K[0] = f
            for s in range(1, 6):
                yi = y.copy()
                for m in range(s):
                    yi += h * _A[s, m] * K[m]
                K[s] = _rhs(kind, yi, g)
            yn = y.copy()
            for m in range(6):
                yn += h * _B[m] * K[m]
            fn = _rhs(kind, yn, g)
            K[6] = fn
            err = 0.0
            for i in range(2):
                ei = 0.0
                for m in range(7):
                    ei += K[m, i] * _E[m]
                sc = atol + max(abs(y[i]), abs(yn[i])) * rtol
                err += (ei * h / sc) ** 2
            err = math.sqrt(err / 2.0)
            if err < 1.0:
                fac = 10.0 if err == 0.0 else min(10.0, 0.9 * err ** -0.2)
                break
            h *= max(0.2, 0.9 * err ** -0.2)
        # the guard at the step's end
        if kind == 0:
            gb = -yn[0]
        else:
            gb = yn[0] - period
        if gb >= 0.0:
            hq = np.empty(4)
            hq1 = np.empty(4)
            for k in range(4):
                a0 = 0.0
                a1 = 0.0
                for m in range(7):
                    a0 += K[m, 0] * _P[m, k]
                    a1 += K[m, 1] * _P[m, k]
                hq[k] = h * a0
                hq1[k] = h * a1
            # Illinois on s in [0, 1]: guard(s) = sign * x0(s) - offset
            sg = -1.0 if kind == 0 else 1.0
            off = 0.0 if kind == 0 else period
            lo, hi = 0.0, 1.0
            flo = sg * y[0] - off
            fhi = gb
            side = 0
            while (hi - lo) * h > 4.0 * eps * max(1.0, abs(t + h)):
                m = hi - fhi * (hi - lo) / (fhi - flo)
                if not (lo < m < hi):
                    m = 0.5 * (lo + hi)
                fm = sg * _dense0(y[0], hq, m) - off
                if fm >= 0.0:
                    hi, fhi = m, fm
                    if side == 1:
                        flo *= 0.5
                    side = 1
                else:
                    lo, flo = m, fm
                    if side == -1:
                        fhi *= 0.5
                    side = -1
            te = t + hi * h
            v = _dense0(y[1], hq1, hi)
            out[jumps] = te
            jumps += 1
            t = te
            if kind == 0:
                y[0] = 0.0
                y[1] = -e * v
            else:
                y[0] = 0.0
                y[1] = 0.0
            f = _rhs(kind, y, g)
            h = min(h * fac, 10.0 * h * hi) if hi > 0 else h
        else:
            t += h
            y = yn
            f = fn
            h *= fac
    return jumps


@njit(cache=True, parallel=True)
def hand_written_batch(h0s, n_jumps, rtol, atol, g, e):
    N = h0s.shape[0]
    out = np.full((N, n_jumps), np.nan)
    for i in prange(N):
        y0 = np.array([h0s[i], 0.0])
        hand_written(0, y0, 1e9, n_jumps, rtol, atol, g, e, 1.0, out[i])
    return out


# ------------------------------------------------------------------ the systems
def ball_f(x, t, j, p):
    return np.array([x[1], -p[0]])


def ball_g(x, t, j, p):
    return np.array([0.0, -p[1] * x[1]])


def ball_hD(x, t, j, p):
    return -x[0]


def ball_hC(x, t, j, p):
    return x[0]


def ball_D(x, t, j, p):
    return x[0] <= 0.0 and x[1] <= 0.0


def timer_f(x, t, j, p):
    return np.ones(1)


def timer_g(x, t, j, p):
    return np.zeros(1)


def timer_hD(x, t, j, p):
    return x[0] - p[0]


def timer_hC(x, t, j, p):
    return p[0] - x[0]


def make_ball(specialize=False):
    return CompiledSystem(ball_f, ball_g, jump_guard=ball_hD, flow_guard=ball_hC, jump_set=ball_D,
                          state_dim=2, params=[G, E], specialize=specialize)


def make_timer(specialize=False):
    return CompiledSystem(timer_f, timer_g, jump_guard=timer_hD, flow_guard=timer_hC,
                          state_dim=1, params=[1.0], specialize=specialize)


# ------------------------------------------------------------------ timing
def best(fn, repeat=5, number=1):
    """Best of ``repeat`` timings of ``number`` calls, seconds per call."""
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(number):
            fn()
        ts.append((time.perf_counter() - t) / number)
    return min(ts)


FIRST_CALL = r"""
import time, warnings, numpy as np
warnings.simplefilter("ignore")
t0 = time.perf_counter()
import sys; sys.path.insert(0, {here!r})
import bench_compiled as b
from hybridsim.compiled import simulate_compiled, simulate_many_compiled
t1 = time.perf_counter()
s = b.make_ball()
if {batch}:
    h0 = np.linspace(0.5, 2.0, 1000)
    simulate_many_compiled(s, np.column_stack([h0, 0 * h0]), t_max=1e9, j_max=10,
                           rtol=1e-10, atol=1e-12)
else:
    simulate_compiled(s, [1.0, 0.0], t_max=1e9, j_max=30, rtol=1e-8, atol=1e-10)
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def first_call(batch):
    here = os.path.dirname(os.path.abspath(__file__))
    out = subprocess.run([sys.executable, "-c", FIRST_CALL.format(here=here, batch=batch)],
                         capture_output=True, text=True, timeout=1200)
    if out.returncode:
        return math.nan, math.nan
    imp, run = map(float, out.stdout.split()[-2:])
    return imp, run


def row(name, ours, floor, python, note=""):
    def fmt(v):
        if v is None or v != v:
            return "—"
        return f"{v * 1e3:9.3f} ms" if v < 1 else f"{v:9.2f} s "
    r1 = f"{ours / floor:6.2f}x" if floor else "—"
    r2 = f"{python / ours:7.1f}x" if python else "—"
    print(f"{name:<44} {fmt(ours)} {fmt(floor)} {fmt(python)}  {r1:>8} {r2:>9}  {note}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats, smaller Python runs")
    ap.add_argument("--skip-big", action="store_true", help="skip the 100,000-ball batch")
    ap.add_argument("--skip-first-call", action="store_true")
    args = ap.parse_args(argv)
    rep = 3 if args.quick else 7
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
          f"numba threads {numba.get_num_threads()}")
    if not args.skip_first_call:
        imp, run = first_call(False)
        print(f"first call, fresh process, single ball: import {imp:.2f} s, maps compiled + "
              f"kernel loaded + run {run:.2f} s")
        imp, run = first_call(True)
        print(f"first call, fresh process, 1,000-ball batch: import {imp:.2f} s, maps compiled"
              f" + kernels loaded + run {run:.2f} s")
    ball, ball_s, timer, timer_s = make_ball(), make_ball(True), make_timer(), make_timer(True)
    t = time.perf_counter()
    simulate_compiled(ball_s, [1.0, 0.0], t_max=1.0, j_max=1)
    print(f"specialize=True: compiling the ball's own kernel took "
          f"{time.perf_counter() - t:.1f} s (once per process)")
    # warm everything
    simulate_compiled(ball, [1.0, 0.0], t_max=1.0, j_max=1)
    simulate_compiled(timer, [0.0], t_max=2.0)
    simulate_compiled(timer_s, [0.0], t_max=2.0)
    out = np.empty(10_000)
    hand_written(0, np.array([1.0, 0.0]), 1e9, 30, 1e-8, 1e-10, G, E, 1.0, out)
    print()
    print(f"{'workload':<44} {'compiled':>12} {'hand numba':>12} {'Python path':>12}  "
          f"{'vs hand':>8} {'speed-up':>9}")

    # 30-bounce ball
    kw = dict(rtol=1e-8, atol=1e-10)
    exact = bouncing_ball_jump_times(1.0, 30, G, E)[0] if np.ndim(
        bouncing_ball_jump_times(1.0, 30, G, E)) > 1 else bouncing_ball_jump_times(1.0, 30, G, E)
    arc = simulate_compiled(ball, [1.0, 0.0], t_max=1e9, j_max=30, **kw)
    err = np.max(np.abs(arc.jump_times - exact))
    t_ours = best(lambda: simulate_compiled(ball, [1.0, 0.0], t_max=1e9, j_max=30, **kw),
                  rep, 20)
    t_spec = best(lambda: simulate_compiled(ball_s, [1.0, 0.0], t_max=1e9, j_max=30, **kw),
                  rep, 20)
    y0 = np.array([1.0, 0.0])
    t_hw = best(lambda: hand_written(0, y0, 1e9, 30, 1e-8, 1e-10, G, E, 1.0, out), rep, 20)
    hand_written(0, y0, 1e9, 30, 1e-8, 1e-10, G, E, 1.0, out)
    err_hw = np.max(np.abs(out[:30] - exact))
    t_py = best(lambda: hs.simulate(BouncingBall(G, E), [1.0, 0.0], t_max=1e9, j_max=30,
                                    **kw), 3 if not args.quick else 1)
    row("30-bounce ball (generic kernel)", t_ours, t_hw, t_py,
        f"jump times within {err:.1e} (hand-written {err_hw:.1e})")
    row("30-bounce ball (specialize=True)", t_spec, t_hw, t_py)

    # timer, 10,000 jumps
    nj = 10_000
    t_ours = best(lambda: simulate_compiled(timer, [0.0], t_max=math.inf, j_max=nj), rep)
    t_spec = best(lambda: simulate_compiled(timer_s, [0.0], t_max=math.inf, j_max=nj), rep)
    y0 = np.array([0.0, 0.0])
    t_hw = best(lambda: hand_written(1, y0, 1e9, nj, 1e-6, 1e-9, G, E, 1.0, out), rep)
    # (the hand-written loop's timer: the same DOPRI5 and Illinois, state padded to 2)
    arc = simulate_compiled(timer, [0.0], t_max=math.inf, j_max=nj)
    terr = np.max(np.abs(arc.jump_times - np.arange(1, nj + 1)))
    npy = 1000 if args.quick else nj
    t_py = best(lambda: hs.simulate(Timer(1.0), [0.0], t_max=math.inf, j_max=npy), 1) \
        * nj / npy
    row("timer, 10,000 jumps (generic)", t_ours, t_hw, t_py,
        f"{t_ours / nj * 1e6:.1f} us/jump; jump times within {terr:.1e}"
        + ("" if npy == nj else f"; Python path from {npy} jumps, scaled"))
    row("timer, 10,000 jumps (specialize=True)", t_spec, t_hw, t_py,
        f"{t_spec / nj * 1e6:.1f} us/jump")

    # 1,000 balls x 10 jumps
    rng = np.random.default_rng(0)
    N, K = 1000, 10
    h0 = rng.uniform(0.5, 2.0, N)
    x0s = np.column_stack([h0, np.zeros(N)])
    kwb = dict(rtol=1e-10, atol=1e-12)
    exact = bouncing_ball_jump_times(h0, K, G, E)
    arcs = simulate_many_compiled(ball, x0s, t_max=1e9, j_max=K, **kwb)
    jt = np.array([a.jump_times for a in arcs])
    errb = np.max(np.abs(jt - exact))
    simulate_many_compiled(ball_s, x0s[:8], t_max=1e9, j_max=K, **kwb)
    # ~20-ms runs on two cores shared with other work: seven tries even with
    # --quick, so that one busy moment does not decide the figure
    t_ours = best(lambda: simulate_many_compiled(ball, x0s, t_max=1e9, j_max=K, **kwb), 7)
    t_spec = best(lambda: simulate_many_compiled(ball_s, x0s, t_max=1e9, j_max=K, **kwb), 7)
    t_ser = best(lambda: simulate_many_compiled(ball, x0s, t_max=1e9, j_max=K, parallel=False,
                                                **kwb), max(1, rep // 2))
    hand_written_batch(h0[:4], K, 1e-10, 1e-12, G, E)
    t_hw = best(lambda: hand_written_batch(h0, K, 1e-10, 1e-12, G, E), 7)
    t_py = best(lambda: hs.simulate_many(BouncingBallBatch(G, E), x0s, t_max=1e9, j_max=K,
                                         **kwb), 3 if not args.quick else 1)
    row("1,000 balls x 10 jumps (generic, parallel)", t_ours, t_hw, t_py,
        f"jump times within {errb:.1e}; serial {t_ser * 1e3:.1f} ms")
    row("1,000 balls x 10 jumps (specialize=True)", t_spec, t_hw, t_py,
        "Python path: vectorized hs.simulate_many")

    if not args.skip_big:
        N = 100_000
        h0 = np.random.default_rng(1).uniform(0.5, 2.0, N)
        x0s = np.column_stack([h0, np.zeros(N)])
        rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        t = time.perf_counter()
        arcs = simulate_many_compiled(ball, x0s, t_max=1e9, j_max=K, **kwb)
        t_big = time.perf_counter() - t
        rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        held = sum(a.t.nbytes + a.j.nbytes + a.x.nbytes + a.xdot.nbytes for a in arcs) / 2**20
        n_ok = sum(a.jump_count == K for a in arcs)
        del arcs
        t_hw = best(lambda: hand_written_batch(h0, K, 1e-10, 1e-12, G, E), 1)
        row("100,000 balls x 10 jumps (generic)", t_big, t_hw, None,
            f"{n_ok} of {N} with 10 jumps; samples held {held:.0f} MB, peak RSS "
            f"{rss1:.0f} MB (before {rss0:.0f} MB)")
    print("\nvs hand: compiled time / hand-written numba loop time (same run); speed-up: "
          "Python path time / compiled time.")


if __name__ == "__main__":
    main()
