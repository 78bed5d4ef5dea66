"""What the vectorized numpy path is for: the cases the compiled path cannot run.

Two models, each written once on the last axis (``x[..., k]``, so one
definition serves one state and a batch of states), 1,000 rows each:

* **a drag ball whose maps numba cannot compile**: a bouncing ball with a
  quadratic drag whose coefficient follows a table through
  ``scipy.interpolate.PchipInterpolator`` (a Python object numba cannot
  type) and a restitution given by ``scipy.special.expit`` (a ufunc numba
  does not know). ``hs.compiled.lowerable`` names the method, line and
  object; ``backend="auto"`` runs the rows as one vectorized batch.
  Baseline: the loop of ``hs.simulate`` over the rows (the Python path,
  what remains without the vectorized path).
* **the plain bouncing ball, which compiles**: the vectorized batch against
  the compiled batch (numba, two threads) and the Python loop, so the
  price of running without numba is visible beside the gain over the loop.

Each figure is the best of interleaved rounds (a shared machine's
preemptions only add time); the jump times of every path are compared with
the loop's.

Run: ``python benchmarks/bench_vectorized_path.py [--quick]``
"""
from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.special import expit

import hybridsim as hs
from hybridsim.library import BouncingBall

TOL = dict(rtol=1e-8, atol=1e-10)


class TableDragBall(hs.HybridSystem):
    """A ball with quadratic drag c(|v|) |v| v, c read from a table, and an
    impact restitution e(|v|) = 0.5 + 0.4 expit(2 - |v|) (slow impacts
    bounce more)."""
    state_dim = 2
    vectorized = True

    def __init__(self):
        speeds = np.array([0.0, 1.0, 2.0, 4.0, 8.0])
        self.drag = PchipInterpolator(speeds, [0.02, 0.025, 0.03, 0.04, 0.05])

    def flow_map(self, x):
        v = x[..., 1]
        dx = np.empty_like(x)
        dx[..., 0] = v
        dx[..., 1] = -9.81 - self.drag(np.abs(v)) * np.abs(v) * v
        return dx

    def jump_map(self, x):
        v = x[..., 1]
        dx = np.zeros_like(x)
        dx[..., 1] = -(0.5 + 0.4 * expit(2.0 - np.abs(v))) * v
        return dx

    def jump_guard(self, x):
        return -x[..., 0]

    def flow_guard(self, x):
        return x[..., 0]

    def jump_set(self, x):
        return (x[..., 0] <= 0) & (x[..., 1] <= 0)

    def flow_set(self, x):
        return x[..., 0] >= 0


def _rounds(fns, rounds):
    """Best seconds per call of each of ``fns`` over interleaved rounds."""
    times = {k: [] for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            t = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t)
    return {k: min(v) for k, v in times.items()}


def _jumps(arcs):
    return np.array([a.jump_times for a in arcs])


def _loop(system, x0s, **kw):
    return [hs.simulate(system, x0, backend="python", **kw) for x0 in x0s]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    rows = 300 if args.quick else 1000
    rounds = 3 if args.quick else 5
    x0s = np.column_stack([np.linspace(0.5, 2.0, rows), np.zeros(rows)])
    kw = dict(t_max=np.inf, j_max=10, **TOL)

    drag = TableDragBall()
    reason = hs.compiled.lowerable(drag)
    batch = hs.simulate_many(drag, x0s, backend="auto", **kw)
    loop = _loop(drag, x0s, **kw)
    err = np.max(np.abs(_jumps(batch) - _jumps(loop)))
    print(f"drag ball with a scipy table: the compiled path "
          f"{'refuses it: ' + reason.reason if not reason else 'runs it'}")
    print(f"backend='auto' runs it as one vectorized batch; its jump times equal the "
          f"loop's within {err:.1e} s")
    warnings.simplefilter("ignore")
    t_drag = _rounds({"vectorized": lambda: hs.simulate_many(drag, x0s, backend="auto", **kw),
                      "loop": lambda: _loop(drag, x0s, **kw)}, rounds)

    ball = BouncingBall(vectorized=True)         # the library's ball, one last-axis form
    fns = {"vectorized": lambda: hs.simulate_many(ball, x0s, backend="python", **kw),
           "loop": lambda: _loop(ball, x0s, **kw)}
    try:
        import numba  # noqa: F401
        comp = hs.simulate_many(ball, x0s, backend="compiled", **kw)
        fns["compiled"] = lambda: hs.simulate_many(ball, x0s, backend="compiled", **kw)
        cerr = np.max(np.abs(_jumps(comp) - _jumps(_loop(ball, x0s, **kw))))
        print(f"plain ball compiled vs loop: jump times within {cerr:.1e} s")
    except ImportError:
        print("numba is not installed: the compiled column is left out")
    t_ball = _rounds(fns, rounds)

    print(f"{rows:,} rows x 10 jumps, rtol 1e-8, best of {rounds} interleaved rounds")
    print(f"{'model':<32}{'loop':>10}{'vectorized':>12}{'compiled':>10}{'loop/vec':>10}")
    for name, r in (("drag ball, scipy table", t_drag), ("plain ball", t_ball)):
        c = f"{r['compiled']:.3f} s" if "compiled" in r else "refused"
        print(f"{name:<32}{r['loop']:>8.3f} s{r['vectorized']:>10.3f} s{c:>10}"
              f"{r['loop'] / r['vectorized']:>9.1f}x")
    print(f"RESULT vectorized batch where numba cannot compile the maps (drag ball, scipy "
          f"table, {rows:,} rows): {t_drag['vectorized']:.3f} s against the Python loop's "
          f"{t_drag['loop']:.3f} s ({t_drag['loop'] / t_drag['vectorized']:.1f}x)")
    if "compiled" in t_ball:
        print(f"RESULT plain ball, {rows:,} rows: compiled {t_ball['compiled']:.3f} s, "
              f"vectorized {t_ball['vectorized']:.3f} s "
              f"({t_ball['vectorized'] / t_ball['compiled']:.1f}x the compiled), Python loop "
              f"{t_ball['loop']:.3f} s ({t_ball['loop'] / t_ball['vectorized']:.1f}x the "
              f"vectorized)")


if __name__ == "__main__":
    main()
