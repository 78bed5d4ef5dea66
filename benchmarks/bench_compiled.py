"""Compiled path benchmark: hybridsim.compiled against a hand-written numba loop,
diffrax (JAX) where installed, and the Python path, measured side by side in one run.

Workloads (rtol 1e-8, atol 1e-10 unless said):

* 30-bounce ball, one run (guards, exact impact times known);
* timer of period 1, 10,000 jumps;
* 1,000 balls x 10 jumps, batch (rtol 1e-10, atol 1e-12 as bench_batch.py), and the
  time of reading every row's jump times (from the arcs, and from the batch's
  ``jump_times`` array) against the integration's;
* 100,000 balls x 10 jumps, batch, each kernel's first call in the process
  (fits and finishes; peak memory printed), then a second call split into
  the batch kernel's time and the Python side's.

Each is run by ``simulate_compiled`` / ``simulate_many_compiled`` (generic
kernel, cached on disk; and ``specialize=True``, maps inlined, cached on disk
too), by a hand-written numba loop (Dormand-Prince 5(4) with scipy's step-size
controller, Illinois root-finding on the guard along the dense output, the
ball's physics written in; the "floor" of a compiled engine), by diffrax
(``jax.jit`` of its Dopri5 with a PID controller and an event, ``jax.vmap``
over the batch; skipped with a printed reason where diffrax is not
installed: ``pip install diffrax``) and by the Python path (``hs.simulate`` /
``hs.simulate_many``). The ball and the 1,000-ball batch are timed in
interleaved rounds (every contender once per round), medians reported, so
that a busy moment of a shared machine hits all alike. First calls (fresh
processes: import, compile or cache load, first run) are measured in
subprocesses, with the engine's kernels cached and with an empty cache
(``NUMBA_CACHE_DIR`` a new folder; CPU seconds of the child, user + sys).

Run: ``python benchmarks/bench_compiled.py [--quick] [--skip-big] [--skip-first-call]``
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
from hybridsim.library import BouncingBall, Timer, bouncing_ball_jump_times  # noqa: E402

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


def sweep_f(x, t, j, p):
    return np.array([1.0, 0.0])


def sweep_g(x, t, j, p):
    return np.array([0.0, x[1]])


def sweep_hD(x, t, j, p):
    return x[0] - x[1]


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


def interleaved(fns, rounds, number=1):
    """Medians over ``rounds`` rounds, each timing every function of ``fns`` (a
    dict) once (``number`` calls), in turn: seconds per call, by name."""
    ts = {k: [] for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            t = time.perf_counter()
            for _ in range(number):
                fn()
            ts[k].append((time.perf_counter() - t) / number)
    return {k: float(np.median(v)) for k, v in ts.items()}


def kernel_share(system, x0s, **kw):
    """``(total, kernel)`` seconds of one ``simulate_many_compiled`` call: the
    whole call, and the time its GIL-free batch kernel ran (the rest is the
    Python side: options, the sample pools, building one arc per row).
    ``kernel`` is NaN where the batch runs no kernel threads (or the private
    helper timed here is gone)."""
    import hybridsim.compiled._run as hc
    orig = getattr(hc, "_interruptible", None)
    spent = [0.0] if orig is not None else [math.nan]

    def timed(*a, **k):
        t = time.perf_counter()
        try:
            return orig(*a, **k)
        finally:
            spent[0] += time.perf_counter() - t
    if orig is not None:
        hc._interruptible = timed
    try:
        t = time.perf_counter()
        simulate_many_compiled(system, x0s, **kw)
        return time.perf_counter() - t, spent[0]
    finally:
        if orig is not None:
            hc._interruptible = orig


# ------------------------------------------------------------------ diffrax, the peer
def diffrax_peer():
    """``(make, None)``: ``make(K, rtol, atol)`` builds the ball's K jump times
    as a function of h0 for diffrax (Dopri5, PIDController, an Event on the
    height while falling, Newton root finding; JAX on the CPU, float64); or
    ``(None, reason)`` where it cannot run."""
    try:
        import jax
        jax.config.update("jax_enable_x64", True)
        jax.config.update("jax_platforms", "cpu")
        import diffrax
        import jax.numpy as jnp
        import optimistix as optx
    except Exception as e:  # noqa: BLE001 - any reason: printed, the peer skipped
        return None, f"diffrax not available ({type(e).__name__}: {e}); pip install diffrax"

    def make(K, rtol, atol):
        term = diffrax.ODETerm(lambda t, y, args: jnp.stack([y[1], -G * jnp.ones_like(y[0])]))
        solver = diffrax.Dopri5()
        ctrl = diffrax.PIDController(rtol=rtol, atol=atol)
        # falling and at the floor (positive before: no event at the bounce itself)
        event = diffrax.Event(lambda t, y, args, **kw: jnp.where(y[1] < 0, y[0], 1.0),
                              root_finder=optx.Newton(rtol=1e-13, atol=1e-14))

        def one(h0):
            def body(k, carry):
                t, y, out = carry
                sol = diffrax.diffeqsolve(term, solver, t, t + 10.0, None, y,
                                          stepsize_controller=ctrl, event=event,
                                          saveat=diffrax.SaveAt(t1=True), max_steps=256)
                te, ye = sol.ts[-1], sol.ys[-1]
                return te, jnp.stack([jnp.zeros_like(ye[0]), -E * ye[1]]), out.at[k].set(te)
            z = jnp.zeros_like(h0)
            _, _, out = jax.lax.fori_loop(0, K, body, (z, jnp.stack([h0, z]), jnp.zeros(K)))
            return out
        return one

    def build(K, rtol, atol, batch):
        f = make(K, rtol, atol)
        f = jax.jit(jax.vmap(f) if batch else f)
        return lambda h: np.asarray(f(jnp.asarray(h)).block_until_ready())
    return build, None


FIRST_CALL = r"""
import time, warnings, numpy as np
warnings.simplefilter("ignore")
t0 = time.perf_counter()
import sys; sys.path.insert(0, {here!r})
import bench_compiled as b
from hybridsim.compiled import simulate_compiled, simulate_many_compiled
t1 = time.perf_counter()
s = b.make_ball({spec})
h0 = np.linspace(0.5, 2.0, 1000)
simulate_compiled(s, [1.0, 0.0], t_max=1e9, j_max=30, rtol=1e-8, atol=1e-10)
t2 = time.perf_counter()
simulate_many_compiled(s, np.column_stack([h0, 0 * h0]), t_max=1e9, j_max=10,
                       rtol=1e-10, atol=1e-12)
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2)
"""


def first_call(spec=False, cache_dir=None):
    """A fresh process: (import s, first single run s, first batch s, the
    child's CPU s, its stderr); ``cache_dir``: numba's cache folder."""
    here = os.path.dirname(os.path.abspath(__file__))
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([sys.executable, "-c", FIRST_CALL.format(here=here, spec=spec)],
                         capture_output=True, text=True, timeout=1200, env=env)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    if out.returncode:
        return math.nan, math.nan, math.nan, cpu, out.stderr[-500:]
    imp, one, many = map(float, out.stdout.split()[-3:])
    return imp, one, many, cpu, out.stderr


def row(name, ours, floor, python, note=""):
    def fmt(v):
        if v is None or v != v:
            return "—"
        return f"{v * 1e3:9.3f} ms" if v < 1 else f"{v:9.2f} s "
    r1 = f"{ours / floor:6.2f}x" if floor else "—"
    r2 = f"{python / ours:7.1f}x" if python else "—"
    print(f"{name:<44} {fmt(ours)} {fmt(floor)} {fmt(python)}  {r1:>8} {r2:>9}  {note}")


def main(argv=None):
    import tempfile
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer rounds, smaller Python runs")
    ap.add_argument("--skip-big", action="store_true", help="skip the 100,000-ball batch")
    ap.add_argument("--skip-first-call", action="store_true",
                    help="skip the fresh-process measurements (the empty-cache one "
                         "compiles the kernels: about 20 s of CPU)")
    args = ap.parse_args(argv)
    rounds = 7 if args.quick else 15
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
          f"numba threads {numba.get_num_threads()}")
    build, why = diffrax_peer()
    if build is None:
        print(f"diffrax peer skipped: {why}")
    else:
        import diffrax
        import jax
        print(f"diffrax {diffrax.__version__}, jax {jax.__version__} (CPU, float64)")
    if not args.skip_first_call:
        with tempfile.TemporaryDirectory() as d:
            imp, one, many, cpu, err = first_call(False, d)
            print(f"first call, empty cache (kernels compiled): import {imp:.2f} s, single "
                  f"ball {one:.2f} s, then 1,000-ball batch {many:.2f} s; {cpu:.1f} s of CPU "
                  f"in all (target <= 20 s)")
            print(f"RESULT first compiled call, empty cache: {cpu:.1f} s of CPU (import, "
                  f"kernels compiled, ball, 1,000-ball batch)")
            print("  its notice: " + (" | ".join(ln for ln in err.splitlines()
                                                 if "hybridsim.compiled" in ln) or "none"))
            imp, one, many, cpu, err = first_call(False, d)
            print(f"first call, kernels cached: import {imp:.2f} s, single ball {one:.2f} s "
                  f"(maps compiled, kernel loaded), batch {many:.2f} s; {cpu:.1f} s of CPU")
            first_call(True, d)
            imp, one, many, cpu, err = first_call(True, d)
            print(f"first call, specialize=True, its kernel cached: single ball {one:.2f} s, "
                  f"batch {many:.2f} s; {cpu:.1f} s of CPU")
    ball, ball_s, timer, timer_s = make_ball(), make_ball(True), make_timer(), make_timer(True)
    t = time.perf_counter()
    simulate_compiled(ball_s, [1.0, 0.0], t_max=1.0, j_max=1)
    print(f"specialize=True in this process: its kernel compiled or loaded from the disk "
          f"cache in {time.perf_counter() - t:.2f} s")
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
    exact = bouncing_ball_jump_times(1.0, 30, G, E)
    arc = simulate_compiled(ball, [1.0, 0.0], t_max=1e9, j_max=30, **kw)
    err = np.max(np.abs(arc.jump_times - exact))
    y0 = np.array([1.0, 0.0])
    fns = {"ours": lambda: simulate_compiled(ball, [1.0, 0.0], t_max=1e9, j_max=30, **kw),
           "spec": lambda: simulate_compiled(ball_s, [1.0, 0.0], t_max=1e9, j_max=30, **kw),
           "hand": lambda: hand_written(0, y0, 1e9, 30, 1e-8, 1e-10, G, E, 1.0, out)}
    dfx_note = ""
    if build is not None:
        t = time.perf_counter()
        dball = build(30, 1e-8, 1e-10, False)
        jt = dball(1.0)
        dfx_first = time.perf_counter() - t
        fns["diffrax"] = lambda: dball(1.0)
        dfx_err = np.max(np.abs(jt - exact))
    med = interleaved(fns, rounds, 20)
    hand_written(0, y0, 1e9, 30, 1e-8, 1e-10, G, E, 1.0, out)
    err_hw = np.max(np.abs(out[:30] - exact))
    t_py = best(lambda: hs.simulate(BouncingBall(G, E), [1.0, 0.0], t_max=1e9, j_max=30,
                                    **kw), 3 if not args.quick else 1)
    if build is not None:
        dfx_note = (f"; diffrax {med['diffrax'] * 1e3:.3f} ms ({med['ours'] / med['diffrax']:.2f}x"
                    f" its time; its first call {dfx_first:.1f} s, within {dfx_err:.1e})")
    row("30-bounce ball (generic kernel)", med["ours"], med["hand"], t_py,
        f"jump times within {err:.1e} (hand-written {err_hw:.1e}){dfx_note}")
    row("30-bounce ball (specialize=True)", med["spec"], med["hand"], t_py)
    print(f"RESULT 30-bounce ball compiled: {med['ours'] * 1e3:.3f} ms, "
          f"{med['ours'] / med['hand']:.2f}x the hand-written numba loop "
          f"({med['spec'] / med['hand']:.2f}x specialised)"
          + (f", {med['ours'] / med['diffrax']:.2f}x diffrax's time" if build else ""))

    # timer, 10,000 jumps
    rep = 3 if args.quick else 7
    nj = 10_000
    y0 = np.array([0.0, 0.0])
    med = interleaved({
        "ours": lambda: simulate_compiled(timer, [0.0], t_max=math.inf, j_max=nj),
        "spec": lambda: simulate_compiled(timer_s, [0.0], t_max=math.inf, j_max=nj),
        "hand": lambda: hand_written(1, y0, 1e9, nj, 1e-6, 1e-9, G, E, 1.0, out)}, rep)
    # (the hand-written loop's timer: the same DOPRI5 and Illinois, state padded to 2)
    arc = simulate_compiled(timer, [0.0], t_max=math.inf, j_max=nj)
    terr = np.max(np.abs(arc.jump_times - np.arange(1, nj + 1)))
    npy = 1000 if args.quick else nj
    t_py = best(lambda: hs.simulate(Timer(1.0), [0.0], t_max=math.inf, j_max=npy), 1) \
        * nj / npy
    row("timer, 10,000 jumps (generic)", med["ours"], med["hand"], t_py,
        f"{med['ours'] / nj * 1e6:.1f} us/jump; jump times within {terr:.1e}"
        + ("" if npy == nj else f"; Python path from {npy} jumps, scaled"))
    row("timer, 10,000 jumps (specialize=True)", med["spec"], med["hand"], t_py,
        f"{med['spec'] / nj * 1e6:.1f} us/jump")

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
    hand_written_batch(h0[:4], K, 1e-10, 1e-12, G, E)
    nt = numba.get_num_threads()

    def one_thread(system):
        def run():
            numba.set_num_threads(1)
            try:
                simulate_many_compiled(system, x0s, t_max=1e9, j_max=K, **kwb)
            finally:
                numba.set_num_threads(nt)
        return run
    fns = {"ours": lambda: simulate_many_compiled(ball, x0s, t_max=1e9, j_max=K, **kwb),
           "spec": lambda: simulate_many_compiled(ball_s, x0s, t_max=1e9, j_max=K, **kwb),
           "ours1": one_thread(ball), "spec1": one_thread(ball_s),
           "hand": lambda: hand_written_batch(h0, K, 1e-10, 1e-12, G, E)}
    if build is not None:
        t = time.perf_counter()
        dbatch = build(K, 1e-10, 1e-12, True)
        jt = dbatch(h0)
        dfx_first = time.perf_counter() - t
        dfx_err = np.max(np.abs(jt - exact))
        fns["diffrax"] = lambda: dbatch(h0)
    med = interleaved(fns, rounds)
    vball = BouncingBall(G, E, vectorized=True)
    t_py = best(lambda: hs.simulate_many(vball, x0s, t_max=1e9, j_max=K, **kwb),
                3 if not args.quick else 1)
    row(f"1,000 balls x 10 jumps (generic, {nt} threads)", med["ours"], med["hand"], t_py,
        f"jump times within {errb:.1e}; one thread {med['ours1'] * 1e3:.1f} ms")
    row(f"1,000 balls x 10 jumps (specialize, {nt} thr.)", med["spec"], med["hand"], t_py,
        f"one thread {med['spec1'] * 1e3:.1f} ms; Python path: vectorized hs.simulate_many")
    if build is not None:
        best_ours = min(med["ours"], med["spec"], med["ours1"], med["spec1"])
        print(f"{'1,000 balls x 10 jumps, diffrax jit(vmap)':<44} {med['diffrax'] * 1e3:9.3f} ms"
              f"  first call {dfx_first:.1f} s, jump times within {dfx_err:.1e}; compiled "
              f"(best setting) / diffrax = {best_ours / med['diffrax']:.2f}x, generic "
              f"{med['ours'] / med['diffrax']:.2f}x (medians of {rounds} interleaved rounds)")
        print(f"RESULT 1,000 balls x 10 jumps compiled (best setting): {best_ours * 1e3:.1f} ms"
              f", {best_ours / med['diffrax']:.2f}x diffrax jit(vmap)'s time "
              f"({med['diffrax'] * 1e3:.1f} ms), {best_ours / med['hand']:.2f}x the hand-written"
              f" loop's")
    # every row's jump times, as a study reads them: from the 1,000 arcs (each made from
    # the pool and its jumps found) against the batch's arrays (read off the pool at once)
    integ, from_arcs, from_batch = [], [], []
    for _ in range(rounds):
        for read, out in (((lambda b: [a.jump_times for a in b]), from_arcs),
                          ((lambda b: b.jump_times), from_batch)):
            t = time.perf_counter()
            b = simulate_many_compiled(ball, x0s, t_max=1e9, j_max=K, **kwb)
            t1 = time.perf_counter()
            read(b)
            out.append(time.perf_counter() - t1)
            integ.append(t1 - t)
    ti, ta, tb = (float(np.median(v)) for v in (integ, from_arcs, from_batch))
    b = simulate_many_compiled(ball, x0s, t_max=1e9, j_max=K, **kwb)
    same = np.array_equal(b.jump_times, np.array([a.jump_times for a in b]))
    print(f"  1,000 balls, every row's jump times read: from the arcs {ta * 1e3:.2f} ms "
          f"({ta / ti:.2f}x the batch's {ti * 1e3:.1f} ms), from batch.jump_times "
          f"{tb * 1e3:.3f} ms ({tb / ti:.3f}x; {ta / tb:.0f}x faster; the same values: {same})")
    print(f"RESULT 1,000-ball batch, reading every row's jump times / integrating: before "
          f"(from the arcs) {ta / ti:.2f}x, after (batch.jump_times) {tb / ti:.3f}x "
          f"(medians of {rounds} rounds)"
          + (f"; batch + read / diffrax jit(vmap): {(ti + ta) / med['diffrax']:.2f}x before, "
             f"{(ti + tb) / med['diffrax']:.2f}x after" if build is not None else ""))
    for name, system in (("generic", ball), ("specialize=True", ball_s)):
        tk = np.array([kernel_share(system, x0s, t_max=1e9, j_max=K, **kwb)
                       for _ in range(rounds)])
        tot, ker = np.median(tk[:, 0]), np.median(tk[:, 1])
        print(f"  1,000 balls ({name}, {nt} threads): of {tot * 1e3:.1f} ms, the batch kernel "
              f"{ker * 1e3:.1f} ms, the Python side (options, pools, 1,000 arcs) "
              f"{(tot - ker) * 1e3:.1f} ms (medians of {rounds})")

    # a sweep whose runs grow along the batch: the pools are sized by four runs
    # spread over it, and runs without room run again in a parallel round
    sweep = CompiledSystem(sweep_f, sweep_g, jump_guard=sweep_hD, state_dim=2)
    per = np.geomspace(1.0, 0.01, 2000)
    up = np.column_stack([np.zeros_like(per), per])
    down = up[::-1].copy()
    simulate_many_compiled(sweep, up[:8], t_max=3.0)
    med = interleaved({"up": lambda: simulate_many_compiled(sweep, up, t_max=3.0),
                       "down": lambda: simulate_many_compiled(sweep, down, t_max=3.0)}, rounds)
    n_s = sum(len(a.t) for a in simulate_many_compiled(sweep, up, t_max=3.0))
    print(f"sweep of 2,000 timers, periods 1 -> 0.01 ({n_s:,} samples): shortest runs first "
          f"{med['up'] * 1e3:.1f} ms, longest first {med['down'] * 1e3:.1f} ms "
          f"({med['up'] / med['down']:.2f}x; medians of {rounds} interleaved rounds)")

    if not args.skip_big:
        N = 100_000
        h0 = np.random.default_rng(1).uniform(0.5, 2.0, N)
        x0s = np.column_stack([h0, np.zeros(N)])
        t_hw = best(lambda: hand_written_batch(h0, K, 1e-10, 1e-12, G, E), 1)
        note = ""
        if build is not None:
            dbatch(h0)      # recompiles for the new shape: timed again warm
            t = time.perf_counter()
            dbatch(h0)
            note = f"; diffrax {time.perf_counter() - t:.2f} s"
        # both kernels, each its first 100,000-row call in this process, then
        # a second call split into the kernel's share and the Python side's
        for name, system in (("generic", ball), ("specialize=True", ball_s)):
            rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            t = time.perf_counter()
            arcs = simulate_many_compiled(system, x0s, t_max=1e9, j_max=K, **kwb)
            t_big = time.perf_counter() - t
            rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            held = sum(a.t.nbytes + a.j.nbytes + a.x.nbytes + a.xdot.nbytes
                       for a in arcs) / 2**20
            n_ok = sum(a.jump_count == K for a in arcs)
            jt = np.array([a.jump_times for a in arcs])
            errbig = np.max(np.abs(jt - bouncing_ball_jump_times(h0, K, G, E)))
            del arcs, jt
            t_big2, k_big = kernel_share(system, x0s, t_max=1e9, j_max=K, **kwb)
            print(f"RESULT 100,000 balls x 10 jumps compiled ({name}): {t_big:.2f} s, "
                  f"{t_big / t_hw:.2f}x the hand-written loop's time")
            row(f"100,000 balls x 10 jumps ({name})", t_big, t_hw, None,
                f"{n_ok} of {N} with 10 jumps, within {errbig:.1e}; samples held "
                f"{held:.0f} MB, peak RSS {rss1:.0f} MB (before {rss0:.0f} MB){note}")
            print(f"  100,000 balls ({name}): of {t_big2:.2f} s (a second call), the batch "
                  f"kernel {k_big:.2f} s, the Python side (options, pools, 100,000 arcs) "
                  f"{t_big2 - k_big:.2f} s")
    print("\nvs hand: compiled time / hand-written numba loop time (same run); speed-up: "
          "Python path time / compiled time. Ball and batch rows: medians of interleaved "
          "rounds.")


if __name__ == "__main__":
    main()
