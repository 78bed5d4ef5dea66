"""One run, side by side: hybridsim.simulate vs a hand-written solve_ivp loop.

A 30-bounce ball (h0 = 1, g = 9.81, restitution 0.8) at rtol 1e-8, atol
1e-10, measured in one process on one machine (best of ``--repeats``):

* ``hybridsim.simulate`` with continuous guards (root-finding event location),
* ``hybridsim.simulate`` with set indicators only (bisection),
* ``scipy.integrate.solve_ivp`` restarted after each terminal event.

Each line gives the wall time, its ratio to the solve_ivp loop, and the
largest error of the 30 jump times against the closed form
t_1 = v0/g, t_{k+1} = t_k + 2 e^k v0/g.

Then a timer of period 1 (1,000 jumps, default tolerances): the cost per
jump of ``simulate`` beside a ``solve_ivp`` restart loop, and a 10-s run of
a smooth linear system (no jumps) beside a bare scipy ``RK45.step()`` loop
and a bare loop of the engine's own RK45 stepper (``hybridsim._rk``: scipy's
steps bit for bit, without scipy's per-step overheads), which separates the
engine's bookkeeping from its stepping. Each figure is printed beside the
target of issue 13 (ball <= 0.35x the loop, timer <= 60 us per jump, smooth
overhead <= 5% over the bare scipy loop).

Then a profile of ``simulate``'s run loop (cProfile) on the ball and on a
10-s run of a smooth linear system (no jumps): the top entries by own time,
and how the time splits between scipy's ``step()`` (which includes the
right-hand-side evaluations) and the engine's own work (solver set-up, set
and guard tests, sample storage, event location). cProfile inflates every
Python call, so the smooth system's split is also measured without the
profiler: ``simulate`` against a bare ``RK45.step()`` loop over the same
interval with the same tolerances.

    python benchmarks/bench_simulate.py [--repeats 5] [--top 15]
"""
import argparse
import cProfile
import math
import os
import platform
import pstats
import time

import numpy as np
import scipy
from scipy.integrate import RK45, solve_ivp

import hybridsim as hs
from hybridsim._rk import LEAN

G, E, H0, JUMPS = 9.81, 0.8, 1.0, 30
RTOL, ATOL = 1e-8, 1e-10
T_MAX = 10.0                      # the 30th bounce is at t = 4.058


# ----------------------------------------------------------------- systems
def f_ball(x):
    return np.array([x[1], -G])


def g_ball(x):
    return np.array([0.0, -E * x[1]])


BALL_GUARDS = hs.HybridSystem.from_functions(
    flow_map=f_ball, jump_map=g_ball, state_dim=2, name="ball (guards)",
    jump_guard=lambda x: np.array([-x[0], -x[1]]),    # D = {x0 <= 0, x1 <= 0}
    flow_guard=lambda x: x[0])                        # C = {x0 >= 0}

BALL_SETS = hs.HybridSystem.from_functions(
    flow_map=f_ball, jump_map=g_ball, state_dim=2, name="ball (set indicators)",
    flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0)

# smooth linear system: two lightly damped oscillators, xdot = A x
A_LIN = np.array([[0.0, 1.0, 0.0, 0.0],
                  [-4.0, -0.1, 0.5, 0.0],
                  [0.0, 0.0, 0.0, 1.0],
                  [0.3, 0.0, -9.0, -0.2]])
X0_LIN = np.array([1.0, 0.0, -0.5, 0.2])
LINEAR = hs.HybridSystem.from_functions(flow_map=lambda x: A_LIN @ x, state_dim=4, name="linear")


def analytic_jump_times(n):
    v0 = np.sqrt(2 * G * H0)
    return v0 / G + np.concatenate(([0.0], np.cumsum(2 * v0 / G * E ** np.arange(1, n))))


# ---------------------------------------------------------------- the runs
def run_hybridsim(system, method="RK45"):
    arc = hs.simulate(system, [H0, 0.0], t_max=T_MAX, j_max=JUMPS, rtol=RTOL, atol=ATOL,
                      method=method, progress=False)
    assert arc.jump_count == JUMPS, arc
    return arc.jump_times


def run_solve_ivp():
    """The restart loop a user writes by hand: terminal event, jump, restart."""
    def rhs(t, x):
        return np.array([x[1], -G])

    def floor(t, x):
        return x[0]
    floor.terminal = True
    floor.direction = -1

    t, x, times = 0.0, np.array([H0, 0.0]), []
    while len(times) < JUMPS:
        sol = solve_ivp(rhs, (t, T_MAX), x, method="RK45", events=floor,
                        rtol=RTOL, atol=ATOL)
        if sol.status != 1:
            raise RuntimeError(f"solve_ivp stopped without an event: {sol.message}")
        t = float(sol.t_events[0][0])
        xe = sol.y_events[0][0]
        x = np.array([0.0, -E * xe[1]])
        times.append(t)
    return np.array(times)


def timer_system():
    return hs.library.Timer(1.0)


TIMER_JUMPS = 1000


def run_timer():
    arc = hs.simulate(timer_system(), [0.0], t_max=math.inf, j_max=TIMER_JUMPS, progress=False)
    assert arc.jump_count == TIMER_JUMPS, arc
    return arc.jump_times


def run_timer_solve_ivp():
    """The timer's restart loop by hand (default tolerances of simulate)."""
    def rhs(t, x):
        return np.ones(1)

    def wrap(t, x):
        return x[0] - 1.0
    wrap.terminal = True
    wrap.direction = 1

    t, x, times = 0.0, np.zeros(1), []
    while len(times) < TIMER_JUMPS:
        sol = solve_ivp(rhs, (t, t + 10.0), x, method="RK45", events=wrap, rtol=1e-6,
                        atol=1e-9)
        t = float(sol.t_events[0][0])
        x = np.zeros(1)
        times.append(t)
    return np.array(times)


def best_of(fns, repeats):
    """Best wall time of each callable over ``repeats`` rounds, interleaved
    (one call of each per round) so that a busy machine slows all alike."""
    best, out = [np.inf] * len(fns), [None] * len(fns)
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            out[i] = fn()
            best[i] = min(best[i], time.perf_counter() - t0)
    return best, out


def run_linear(method="RK45"):
    return hs.simulate(LINEAR, X0_LIN, t_max=10.0, rtol=RTOL, atol=ATOL, method=method,
                       progress=False)


# ------------------------------------------- where the time goes, unprofiled
PARTS = ("solver set-up", "step()", "dense_output()", "locate_event()")
_clock = dict.fromkeys(PARTS, 0.0)
_calls = dict.fromkeys(PARTS, 0)


def _timed(part, fn):
    def wrapper(*a, **k):
        t0 = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            _clock[part] += time.perf_counter() - t0
            _calls[part] += 1
    return wrapper


def split(label, run, repeats):
    """Wall time of ``run("RK45")`` split by part, without a profiler: the run
    with the smallest total of ``repeats``. RK45's methods and the engine's
    ``locate_event`` are clocked in place (a subclass would stop the engine
    from reusing its solver across flows). Everything not clocked is the
    engine's own work per step and per jump (set/guard tests outside event
    location, finiteness checks, sample storage, jumps, bookkeeping)."""
    import hybridsim.solve as solve_mod
    original = solve_mod.locate_event
    solve_mod.locate_event = _timed("locate_event()", original)
    patched = {"__init__": "solver set-up", "step": "step()", "dense_output": "dense_output()"}
    saved = {name: RK45.__dict__.get(name) for name in patched}
    for name, part in patched.items():
        setattr(RK45, name, _timed(part, getattr(RK45, name)))
    try:
        best = None
        for _ in range(repeats):
            for k in _clock:
                _clock[k], _calls[k] = 0.0, 0
            t0 = time.perf_counter()
            run("RK45")
            total = time.perf_counter() - t0
            if best is None or total < best[0]:
                best = (total, dict(_clock), dict(_calls))
    finally:
        solve_mod.locate_event = original
        for name, fn in saved.items():
            if fn is None:
                delattr(RK45, name)
            else:
                setattr(RK45, name, fn)
    total, parts, calls = best
    rest = total - sum(parts.values())
    print(f"\n{label}: {total * 1e3:.2f} ms (best of {repeats}, no profiler)")
    for name in PARTS + ("engine's own work",):
        v = parts.get(name, rest)
        per = f"{v / calls[name] * 1e6:8.1f} us per call ({calls[name]} calls)" \
            if calls.get(name) else ""
        print(f"  {name:20s}{v * 1e3:8.2f} ms  {v / total:6.1%}   {per}")


# -------------------------------------------------------------- profiling
SCIPY_STEP = ("scipy/integrate/_ivp/base.py", "step")


def _key_is(key, fileend, func):
    return key[0].replace("\\", "/").endswith(fileend) and key[2] == func


def _profile_once(call):
    prof = cProfile.Profile()
    prof.enable()
    call()
    prof.disable()
    stats = pstats.Stats(prof).stats   # {(file, line, func): (cc, nc, tottime, cumtime, callers)}
    # the front door, hybridsim.run.simulate
    total = next(v[3] for k, v in stats.items() if k[2] == "simulate"
                 and k[0].endswith(os.path.join("hybridsim", "run.py")))
    return total, prof, stats


def profile(label, call, top, repeats=3):
    """cProfile of one call (the quickest of ``repeats``: a busy machine adds noise)."""
    total, _prof, stats = min((_profile_once(call) for _ in range(repeats)), key=lambda r: r[0])
    step = sum(v[3] for k, v in stats.items() if _key_is(k, *SCIPY_STEP))
    nsteps = sum(v[1] for k, v in stats.items() if _key_is(k, *SCIPY_STEP))
    rhs = sum(v[3] for k, v in stats.items() if k[2] == "fun" and k[0].endswith("solve.py"))
    nrhs = sum(v[1] for k, v in stats.items() if k[2] == "fun" and k[0].endswith("solve.py"))

    def cum(fileend, func):
        return sum(v[3] for k, v in stats.items() if _key_is(k, fileend, func))
    parts = {
        "solver set-up (OdeSolver.__init__)": cum("_ivp/rk.py", "__init__"),
        "dense_output()": cum("_ivp/base.py", "dense_output"),
        "locate_event()": cum("hybridsim/events.py", "locate_event"),
        "_Buffer.append": cum("hybridsim/solve.py", "append"),
    }
    def ncalls(fileend, func):
        return sum(v[1] for k, v in stats.items() if _key_is(k, fileend, func))
    nev = ncalls("hybridsim/events.py", "locate_event")
    print(f"\n--- profile: {label}  ({nsteps} solver steps, {nrhs} RHS calls) ---")
    if nev:
        print(f"{nev} events; per event: {ncalls('hybridsim/events.py', 'call') / nev:.1f} dense "
              f"evaluations, {ncalls('hybridsim/solve.py', 'pred') / nev:.1f} indicator tests "
              f"(pred), {ncalls('hybridsim/solve.py', 'phi') / nev:.1f} guard evaluations (phi)")
    print(f"simulate: {total * 1e3:8.2f} ms under cProfile")
    print(f"  scipy step():              {step * 1e3:8.2f} ms  {step / total:6.1%}"
          f"   (of which RHS calls {rhs * 1e3:.2f} ms, {rhs / total:.1%})")
    print(f"  engine, everything else:   {(total - step) * 1e3:8.2f} ms  "
          f"{(total - step) / total:6.1%}")
    for name, v in parts.items():
        print(f"    {name:31s}{v * 1e3:8.2f} ms  {v / total:6.1%}")
    print(f"  top {top} by own time:\n  {'ncalls':>7s}{'own (ms)':>10s}{'cum (ms)':>10s}  function")
    rows = sorted(stats.items(), key=lambda kv: kv[1][2], reverse=True)[:top]
    for (file, line, func), (_cc, nc, tt, ct, _) in rows:
        where = f"{os.path.basename(file)}:{line}({func})" if line else func
        print(f"  {nc:7d}{tt * 1e3:10.3f}{ct * 1e3:10.3f}  {where}")


def bare_rk45(t_end, Method=RK45):
    """RK45 stepping alone from X0_LIN to t_end: no checks, no storage (scipy's
    class, or the engine's bit-for-bit copy of it without the per-step overheads)."""
    solver = Method(lambda t, x: A_LIN @ x, 0.0, X0_LIN, t_end, rtol=RTOL, atol=ATOL)
    n = 0
    while solver.status == "running":
        solver.step()
        n += 1
    return n


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--top", type=int, default=15)
    ap.add_argument("--quick", action="store_true",
                    help="3 repeats (benchmarks/run_all.py --quick)")
    args = ap.parse_args()
    if args.quick:
        args.repeats = min(args.repeats, 3)

    print(f"python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
          f"{platform.machine()} {platform.processor() or ''}".rstrip()
          + f", {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} "
            "(a busy machine makes every figure noisier)")
    print(f"30-bounce ball, h0 = {H0}, g = {G}, e = {E}, RK45 at rtol {RTOL:g}, atol {ATOL:g}; "
          f"best of {args.repeats}\n")
    exact = analytic_jump_times(JUMPS)
    runs = [("hybridsim.simulate, guards", lambda: run_hybridsim(BALL_GUARDS)),
            ("hybridsim.simulate, set indicators", lambda: run_hybridsim(BALL_SETS)),
            ("solve_ivp restart loop (baseline)", run_solve_ivp)]
    walls, outs = best_of([fn for _, fn in runs], args.repeats)
    results = [(name, w, o) for (name, _), w, o in zip(runs, walls, outs)]
    base = walls[-1]
    print(f"{'':36s}{'wall (ms)':>10s}{'/ baseline':>12s}{'max |t_k - exact|':>20s}")
    for name, wall, times in results:
        print(f"{name:36s}{wall * 1e3:10.2f}{wall / base:12.2f}"
              f"{np.max(np.abs(times - exact)):20.2e}")
    err_base = np.max(np.abs(results[-1][2] - exact))
    for name, wall, times in results[:-1]:
        target = " (target <= 0.35x)" if name.endswith("guards") else ""
        print(f"RESULT 30-bounce ball, {name.split(', ')[1]}: {wall * 1e3:.1f} ms "
              f"vs solve_ivp loop "
              f"{base * 1e3:.1f} ms = {wall / base:.2f}x{target}; max jump-time error "
              f"{np.max(np.abs(times - exact)):.1e} (solve_ivp {err_base:.1e})")

    # the timer: cost per jump
    (w_t, w_tivp), (tt, _tt_ivp) = best_of([run_timer, run_timer_solve_ivp], args.repeats)
    terr = np.max(np.abs(tt - np.arange(1, TIMER_JUMPS + 1)))
    print(f"\ntimer of period 1, {TIMER_JUMPS} jumps, rtol 1e-6, atol 1e-9; best of "
          f"{args.repeats}:")
    print(f"  hybridsim.simulate     {w_t / TIMER_JUMPS * 1e6:8.1f} us/jump   "
          f"(jump times within {terr:.1e} of k)")
    print(f"  solve_ivp restart loop {w_tivp / TIMER_JUMPS * 1e6:8.1f} us/jump")
    print(f"RESULT timer, {TIMER_JUMPS} jumps: {w_t / TIMER_JUMPS * 1e6:.1f} us/jump "
          f"(target <= 60) vs solve_ivp loop {w_tivp / TIMER_JUMPS * 1e6:.1f} us/jump = "
          f"{w_t / w_tivp:.2f}x")

    # the smooth linear system, unprofiled: engine vs bare stepping (about 12 ms
    # each: three times the repeats, so that a busy moment does not decide).
    # Two baselines: scipy's RK45 (what a user would write) and the engine's own
    # RK45 stepper alone (the same steps bit for bit, without scipy's per-step
    # overheads), so that the engine's bookkeeping is seen apart from its stepping
    reps = 3 * args.repeats
    (w_sim, w_bare, w_lean), (arc, nsteps, _n) = best_of(
        [run_linear, lambda: bare_rk45(10.0), lambda: bare_rk45(10.0, LEAN[RK45])], reps)
    print(f"\nsmooth linear system (n = 4), 10 s, {nsteps} RK45 steps; best of {reps}:")
    for name, w in (("hybridsim.simulate", w_sim), ("bare scipy RK45.step loop", w_bare),
                    ("bare loop, engine's stepper", w_lean)):
        print(f"  {name:28s} {w * 1e3:8.2f} ms   ({w / nsteps * 1e6:.1f} us/step)")
    print(f"  engine bookkeeping           {(w_sim - w_lean) / nsteps * 1e6:8.1f} us/step "
          f"({(w_sim - w_lean) / w_lean:.1%} over its own stepping); arc has {len(arc)} samples")
    print(f"RESULT smooth linear system, 10 s: simulate {w_sim * 1e3:.1f} ms vs bare scipy RK45 "
          f"steps {w_bare * 1e3:.1f} ms = {w_sim / w_bare:.3f}x, overhead "
          f"{(w_sim / w_bare - 1):+.1%} (target <= 5%); bookkeeping "
          f"{(w_sim - w_lean) / nsteps * 1e6:.1f} us/step = {(w_sim - w_lean) / w_lean:.1%} over "
          f"the engine's own stepper")

    print("\n=== where simulate's time goes (clocked parts; step() includes the RHS calls)")
    split("ball, guards", lambda m: run_hybridsim(BALL_GUARDS, m), args.repeats)
    split("ball, set indicators", lambda m: run_hybridsim(BALL_SETS, m), args.repeats)
    split("smooth linear system, 10 s", run_linear, args.repeats)
    split(f"timer, {TIMER_JUMPS} jumps", lambda m: run_timer(), args.repeats)

    print("\n=== cProfile of simulate (inflates every Python call; the shares above are "
          "the unbiased ones)")
    profile("ball, guards", lambda: run_hybridsim(BALL_GUARDS), args.top)
    profile("ball, set indicators", lambda: run_hybridsim(BALL_SETS), args.top)
    profile("smooth linear system, 10 s", run_linear, args.top)


if __name__ == "__main__":
    main()
