"""The compiled engine's first call: CPU seconds to compile, from an empty cache,
beside diffrax's first call (jit of a bouncing ball with an event) measured in
the same run.

Each figure is a fresh process (its CPU time, user + system, of all its
threads) with a numba cache folder of its own:

* the run kernel: a 30-bounce ball, the engine's kernels not yet compiled
  (the maps compiled too; the import apart);
* the batch kernel: then a 1,000-ball batch in the same process;
* a new user model: a plain :class:`hybridsim.HybridSystem` subclass run
  with ``backend="compiled"`` (its maps rewritten and compiled), in a copy
  of the cache that holds the engine's kernels only;
* a new ``specialize=True`` system: its own run kernel compiled, in another
  such copy;
* diffrax: the ball's 30 jump times jitted and run once (Dopri5, an Event;
  ``bench_compiled.diffrax_peer``), skipped with a printed reason where
  diffrax is not installed.

The issue's targets: the engine's kernels in <= 10 s of CPU and <= 2.5x
diffrax's first call, a new user model's maps in <= 2 s, a new specialised
system in <= 10 s.

Run: ``python benchmarks/bench_first_call.py``
"""
from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
import tempfile

import numpy as np

import hybridsim as hs

HERE = os.path.dirname(os.path.abspath(__file__))

CHILD = r"""
import sys, time, warnings
warnings.simplefilter("ignore")
sys.path.insert(0, {here!r})
c = time.process_time()
import numpy as np
import hybridsim as hs
from hybridsim.compiled import simulate_compiled, simulate_many_compiled
import bench_compiled as b
import bench_first_call as fc
out = {{"import": time.process_time() - c}}
what = {what!r}
if what in ("user", "spec"):        # the engine's kernels: loaded from the cache
    simulate_compiled(b.make_ball(), [1.0, 0.0], t_max=1.0, j_max=1)
c = time.process_time()
if what == "engine":
    arc = simulate_compiled(b.make_ball(), [1.0, 0.0], t_max=1e9, j_max=30, rtol=1e-8,
                            atol=1e-10)
    out["engine"] = time.process_time() - c
    h0 = np.linspace(0.5, 2.0, 1000)
    c = time.process_time()
    simulate_many_compiled(b.make_ball(), np.column_stack([h0, 0 * h0]), t_max=1e9, j_max=10,
                           rtol=1e-10, atol=1e-12)
    out["batch"] = time.process_time() - c
elif what == "user":
    arc = hs.simulate(fc.Ball(), [1.0, 0.0], t_max=1e9, j_max=30, rtol=1e-8, atol=1e-10,
                      backend="compiled")
    out["user"] = time.process_time() - c
elif what == "spec":
    arc = simulate_compiled(b.make_ball(True), [1.0, 0.0], t_max=1e9, j_max=30, rtol=1e-8,
                            atol=1e-10)
    out["spec"] = time.process_time() - c
print("OUT", out, repr(float(arc.jump_times[-1])))
"""

DIFFRAX = r"""
import sys, time, warnings
warnings.simplefilter("ignore")
sys.path.insert(0, {here!r})
c = time.process_time()
import bench_compiled as b
build, why = b.diffrax_peer()
if build is None:
    print("SKIP", why)
    raise SystemExit(0)
imp = time.process_time() - c
c = time.process_time()
jt = build(30, 1e-8, 1e-10, False)(1.0)
print("OUT", {{"import": imp, "diffrax": time.process_time() - c}}, repr(float(jt[-1])))
"""


class Ball(hs.HybridSystem):
    """A bouncing ball written as a plain model (no compiled form)."""

    state_dim = 2

    def __init__(self, gravity=9.81, restitution=0.8):
        self.gravity, self.restitution = gravity, restitution

    def flow_map(self, x, t, j):
        return np.array([x[1], -self.gravity])

    def jump_map(self, x, t, j):
        return np.array([0.0, -self.restitution * x[1]])

    def flow_set(self, x, t, j):
        return x[0] >= 0.0

    def jump_set(self, x, t, j):
        return x[0] <= 0.0 and x[1] <= 0.0


def child(template, what, cache):
    """A fresh process running ``template``: (its printed figures, its CPU s)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache,
               PYTHONPATH=os.pathsep.join(p for p in (os.path.dirname(HERE),
                                                      os.environ.get("PYTHONPATH")) if p))
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([sys.executable, "-c", template.format(here=HERE, what=what)],
                         capture_output=True, text=True, timeout=1800, env=env)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    line = [ln for ln in out.stdout.splitlines() if ln.startswith(("OUT", "SKIP"))][-1]
    if line.startswith("SKIP"):
        return None, line[5:], cpu
    figs, last = line[4:].rsplit(" ", 1)
    import ast
    return ast.literal_eval(figs), float(last), cpu


def main():
    with tempfile.TemporaryDirectory() as root:
        base = os.path.join(root, "engine")
        os.mkdir(base)
        eng, jt, cpu = child(CHILD, "engine", base)
        rows = {"engine": (eng["engine"], cpu), "batch": (eng["batch"], None)}
        for what in ("user", "spec"):
            d = os.path.join(root, what)
            shutil.copytree(base, d)
            figs, jt2, cpu2 = child(CHILD, what, d)
            assert jt2 == jt, (what, jt2, jt)
            rows[what] = (figs[what], cpu2)
        dfx, dfx_jt, dfx_cpu = child(DIFFRAX, "", os.path.join(root, "engine"))
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; CPU seconds "
          f"(user + system, all threads) of the call, its process's in brackets")
    names = {"engine": "run kernel compiled (empty cache), 30-bounce ball",
             "batch": "then the batch kernel, a 1,000-ball batch",
             "user": "a new user model (source rewrite), kernels cached",
             "spec": "a new specialize=True system, kernels cached"}
    targets = {"engine": 10.0, "batch": None, "user": 2.0, "spec": 10.0}
    for k, (s, whole) in rows.items():
        tgt = f"target <= {targets[k]:.0f} s" if targets[k] else ""
        br = f"({whole:5.1f} s)" if whole is not None else " " * 9
        print(f"{names[k]:<54} {s:6.2f} s {br}  {tgt}")
    if dfx is None:
        print(f"diffrax first call: skipped ({dfx_jt})")
        return
    ratio = rows["engine"][0] / dfx["diffrax"]
    print(f"{'diffrax first call (jit + run), 30 jump times':<54} {dfx['diffrax']:6.2f} s "
          f"({dfx_cpu:5.1f} s)  last jump time differs by {abs(dfx_jt - jt):.1e}")
    print(f"RESULT first call, empty cache: {rows['engine'][0]:.1f} s of CPU, "
          f"{ratio:.2f}x diffrax's first call (target <= 2.5x)")


if __name__ == "__main__":
    main()
