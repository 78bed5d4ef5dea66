"""Delay equations in batches: the vectorized path against a loop of ``simulate``.

A sampled loop with a delayed feedback, x0' = -a x0(t - tau) + b sin t with
a reset x0+ = c x0 every s time units (a timer x1), over a batch of initial
states: ``hs.simulate_many`` integrates the rows together in numpy, each
row reading its own past (``self.history`` over the batch's rows, delay
breakpoints per row), against the same rows run one by one through
``hs.simulate`` (the Python path) in the same process. Both RK45, rtol
1e-8, atol 1e-10; the figures are medians of interleaved rounds, and the
two paths' end states are compared.

A second study runs a paper's observer the same way: Mazenc & Malisoff's
sampled observer (39) with the DC motor (65), samples every 0.01 s, a
batch of initial states (``gramian_delay.population``) against a loop of
``gramian_delay.simulate`` (both RK45, rtol 1e-8, to t = 0.3 s).

Run: ``python benchmarks/bench_delays.py [--quick]``.
"""
import argparse
import statistics
import time

import numpy as np

import hybridsim as hs
from observers.gramian_delay.example import population


class Lag(hs.HybridSystem):
    """x0' = -a x0(t - tau) + b sin t, x1' = 1; x0+ = c x0, x1+ = 0 when x1 >= s."""

    state_dim, needs_history, vectorized = 2, True, True

    def __init__(self, a=1.2, b=0.5, c=0.6, tau=0.4, s=0.7):
        self.a, self.b, self.c, self.tau, self.s = a, b, c, tau, s
        self.delays, self.max_step = (tau,), tau

    def flow_map(self, x, t, j, u):
        out = np.zeros_like(np.asarray(x, dtype=float))
        out[..., 0] = -self.a * self.history(t - self.tau)[..., 0] + self.b * np.sin(t)
        out[..., 1] = 1.0
        return out

    def jump_guard(self, x, t, j, u):
        return x[..., 1] - self.s

    def jump_map(self, x, t, j, u):
        y = np.array(x, dtype=float)
        y[..., 0] = self.c * x[..., 0]
        y[..., 1] = 0.0
        return y


def _interleaved(batch, loop, rounds):
    """``((median s, result), (median s, result))`` of the two, run in turn."""
    times, out = ([], []), [None, None]
    for _ in range(rounds):
        for k, fn in enumerate((batch, loop)):
            t0 = time.perf_counter()
            out[k] = fn()
            times[k].append(time.perf_counter() - t0)
    return tuple((statistics.median(times[k]), out[k]) for k in (0, 1))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller batches")
    args = ap.parse_args(argv)
    N, rounds = (200, 2) if args.quick else (500, 2)
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-1, 1, N), rng.uniform(0, 0.7, N)])
    system = Lag()
    kw = dict(t_max=5.0, rtol=1e-8, atol=1e-10)
    (v, batch), (lp, loop) = _interleaved(
        lambda: hs.simulate_many(system, X, **kw),
        lambda: [hs.simulate(system, x0, **kw) for x0 in X], rounds)
    diff = max(float(np.abs(a.x[-1] - b.x[-1]).max()) for a, b in zip(batch, loop))
    jumps = sum(len(a.jump_times) for a in batch)
    print(f"delay batch, {N} rows x 5 s ({jumps} jumps in all), RK45 rtol 1e-8")
    print(f"  vectorized simulate_many: {v:8.3f} s")
    print(f"  loop of simulate:         {lp:8.3f} s")
    print(f"  ratio: {v / lp:.2f}x the loop's time ({lp / v:.1f}x faster); "
          f"end states equal to {diff:.1e}")
    print(f"RESULT delay batch of {N} rows: vectorized {v:.3f} s vs loop {lp:.3f} s "
          f"({lp / v:.1f}x faster), end states equal to {diff:.1e}")
    gramian(args.quick)


def gramian(quick):
    from observers import gramian_delay as gd
    P, rounds = (20, 1) if quick else (100, 2)
    ex = gd.dc_motor(100.0, 0.1)
    obs = ex.sampled_observer(period=0.01)
    X = ex.chi0 + np.random.default_rng(1).uniform(-0.3, 0.3, (P, 3))
    system, rows = population(obs, X)
    kw = dict(t_max=0.3, rtol=1e-8, atol=1e-10)
    (v, batch), (lp, loop) = _interleaved(
        lambda: hs.simulate_many(system, rows, **kw),
        lambda: [gd.simulate(obs, x0, method="RK45", dense=False, **kw) for x0 in X], rounds)
    diff = max(float(np.abs(gd.errors(a, obs).e[-1] - gd.errors(b, obs).e[-1]).max())
               for a, b in zip(batch, loop))
    print(f"\nMazenc-Malisoff (39), DC motor, {P} initial states x 0.3 s, samples every 0.01 s")
    print(f"  vectorized simulate_many: {v:8.3f} s")
    print(f"  loop of gd.simulate:      {lp:8.3f} s")
    print(f"  ratio: {v / lp:.2f}x the loop's time ({lp / v:.1f}x faster); "
          f"final errors of (13) equal to {diff:.1e}")
    print(f"RESULT (39) population of {P}: vectorized {v:.3f} s vs loop {lp:.3f} s "
          f"({lp / v:.1f}x faster), errors equal to {diff:.1e}")


if __name__ == "__main__":
    main()
