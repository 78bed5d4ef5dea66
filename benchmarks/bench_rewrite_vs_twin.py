"""The observers' maps as written (the source rewrite) against their deleted compiled twins.

The distributed observer's node, Li-Sanfelice's H_c, the bounded-noise
generator and Li-Sanfelice's family of designs (``RotatingFamily``, the
falsification's model) have no hand-written ``compiled_component()`` left: their
rewritten maps are timed against the deleted twins' figures (``DELETED``,
ns a call inside a numba loop, each measured in one run beside the
rewritten maps on a shared two-core machine: H_c's beside 32, 1302 and 19
ns; the node's and the generator's beside 319, 52 and 110 ns at a load of
3.9): compare the ratio, not the ns, across machines. The family is timed
as a falsification runs it, a compiled ``simulate_many`` of 400 random
designs and noises to t = 4 per noise kind, against the deleted twin's
batches (``DELETED_BATCH``, ms, the best of 3, measured alternating with the
rewritten maps in one sitting on two shared cores, 8 December 2026: the
rewritten 13.3-13.8, 74.5-74.8 and 34.0-34.6 ms).

Run: python benchmarks/bench_rewrite_vs_twin.py [calls]
"""
import math
import sys
import time

import numba
import numpy as np

from hybridsim.compiled import _from_source
from observers import li_sanfelice as ls
from observers.distributed import example_observer
from observers.li_sanfelice.systems import BoundedNoiseGenerator


@numba.njit
def _calls(f, x, u, p, n):
    s = 0.0
    for i in range(n):
        s += f(x, u, 1e-3 * i, 0, p)[0]
    return s


@numba.njit
def _output_calls(f, x, p, n):
    s = 0.0
    for i in range(n):
        s += f(x, 1e-3 * i, 0, p)[0]
    return s


def _jit(f):
    return f if hasattr(f, "py_func") else numba.njit(f)


def _ns(f, x, u, p, n):
    """ns per call of ``f`` (u None: an output of (x, t, j, p))."""
    f = _jit(f)
    loop = (lambda k: _output_calls(f, x, p, k)) if u is None else \
        (lambda k: _calls(f, x, u, p, k))
    loop(10)
    t0 = time.perf_counter()
    loop(n)
    return (time.perf_counter() - t0) / n * 1e9


#: (model, map) -> ns a call of the deleted twin, when it was deleted
DELETED = {("Li-Sanfelice H_c", "flow"): 56.0, ("Li-Sanfelice H_c", "jump"): 1110.0,
           ("Li-Sanfelice H_c", "output"): 47.0,
           ("distributed node", "flow"): 305.0, ("distributed node", "output"): 123.0,
           ("bounded noise", "output"): 126.0}


#: noise kind -> ms of the deleted twin's 400-row batch of RotatingFamily
DELETED_BATCH = {"none": 15.1, "pwc": 85.6, "sin": 38.9}


def family_batches(rows=400):
    """Each noise kind of Li-Sanfelice's RotatingFamily: a compiled batch of
    ``rows`` random designs and noises to t = 4 (the best of 3), ms."""
    import hybridsim as hs
    from observers.li_sanfelice import falsification as F
    print(f"{'RotatingFamily':<18} {'noise':<7} {'rewritten ms':>12} {'twin ms':>8} {'ratio':>6}")
    for kind in ("none", "pwc", "sin"):
        s = F.RotatingFamily(kind, eps=0.2, pieces=8, terms=2)
        rng = np.random.default_rng(0)
        X = []
        for _ in range(rows):
            noise = (np.r_[rng.uniform(-1, 1, 4), rng.uniform(0, 2, 4), rng.uniform(0, 6, 4)]
                     if kind == "sin" else rng.uniform(-1, 1, s.noise_size))
            X.append(s.state(rng.normal(size=2), rng.normal(size=2), F.VB_PARAMS, noise))
        X = np.array(X)
        hs.simulate_many(s, X[:2], 4.0, backend="compiled", warn=False, progress=False)
        best = math.inf
        for _ in range(3):
            t0 = time.perf_counter()
            hs.simulate_many(s, X, 4.0, backend="compiled", warn=False, progress=False)
            best = min(best, time.perf_counter() - t0)
        b = DELETED_BATCH[kind]
        print(f"{'':<18} {kind:<7} {best * 1e3:>12.1f} {b:>7.1f}* {best * 1e3 / b:>6.2f}")


def main(n=200_000):
    rng = np.random.default_rng(0)
    hc = ls.ConstantNoiseObserver(ls.example_VB())
    cases = [("distributed node", example_observer().nodes[1]), ("Li-Sanfelice H_c", hc),
             ("bounded noise", BoundedNoiseGenerator(2, 3))]
    print(f"{'model':<18} {'map':<7} {'rewritten ns':>12} {'twin ns':>8} {'ratio':>6} "
          f"{'max |diff|':>10}")
    for name, system in cases:
        maps, output, p, _ = _from_source.component_maps(system)
        form = getattr(type(system), "compiled_component", None)
        twin = system.compiled_component() if form is not None else None
        x = rng.standard_normal(system.state_dim)
        if system is hc:
            x[-1] = 0.0                         # before its jump
        u = rng.standard_normal(system.input_dim)
        rows = [(role, fn, None if twin is None else _jit(twin.maps[role]), u)
                for role, fn in maps.items()
                if role in ("flow", "jump") and (role in twin.maps if twin is not None
                                                 else (name, role) in DELETED)]
        if output is not None:
            rows.append(("output", output, None if twin is None else _jit(twin.output), None))
        for role, mine, theirs, uu in rows:
            args = (x, 0.1, 0) if uu is None else (x, uu, 0.1, 0)
            a = _ns(mine, x, uu, p, n)
            if theirs is None:                  # the deleted twin's figure
                b = DELETED[(name, role)]
                print(f"{name:<18} {role:<7} {a:>12.0f} {b:>7.0f}* {a / b:>6.2f} {'-':>10}")
                continue
            diff = np.abs(mine(*args, p) - theirs(*args, twin.params)).max()
            b = _ns(theirs, x, uu, twin.params, n)
            print(f"{name:<18} {role:<7} {a:>12.0f} {b:>8.0f} {a / b:>6.2f} {diff:>10.1e}")
    family_batches()
    print("* the deleted twin's figure (DELETED, DELETED_BATCH)")

if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200_000)
