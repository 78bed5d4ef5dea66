"""The engine's first compile taken apart, and the LLVM levers on it measured
(issue 42 item 6).

Each figure is a fresh process with an empty numba cache compiling the run
kernel for the 30-bounce ball of ``bench_compiled`` (the maps' compile and
the import apart), CPU seconds of the call:

* where it goes: numba's front end and LLVM (per-function passes, module
  passes, machine code), the run core's own compile against its ~100 helpers'
  (each helper is compiled, optimised and code-generated on its own, then
  linked into the core and optimised again), and how many C wrappers numba
  made;
* the levers, in interleaved rounds beside the engine as it is (``base``):
  the kernel at LLVM level 0 (``opt0``); the helpers' own LLVM work at level
  0 or 1 and the core at the engine's level (``helpers0``, ``helpers1``).
  Each row also gives the ball's run time after the compile (best of 7 x 200
  runs) and its last state's bits, which must not move.

Measured (two shared cores at load 1.5, one round, 8 December 2026): the
engine's first compile 14.7 s of CPU, LLVM 5.1 s of it (34 %: function
passes 1.1 s, module passes 1.7 s, machine code 2.3 s), the run core's own
7.2 s and its helpers' 7.5 s; numba's own pipeline times of the core put
7.3 s in type inference (which compiles the helpers it meets) and 3.8 s in
lowering. The levers: the kernel at LLVM level 0 17.9 s (more code for the
machine-code pass) and the ball's run 230 us against 58 us; the helpers at
level 0 20.1 s (148 us), at level 1 15.6 s (57 us): none is a lever. What
is left is numba's front end on one 790-line function.

Run: ``python benchmarks/bench_compile_levers.py [rounds]``
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))

CHILD = r"""
import collections, sys, time, timeit, warnings
warnings.simplefilter("ignore")
sys.path.insert(0, {here!r})
from numba.core import codegen as cg, compiler, config, lowering
import bench_compiled as b
from hybridsim.compiled import simulate_compiled, _cache
exp = {exp!r}
llvm = collections.Counter()
def timed(owner, name, tag):
    orig = getattr(owner, name)
    def w(self, *a, **k):
        c = time.process_time()
        try:
            return orig(self, *a, **k)
        finally:
            llvm[tag] += time.process_time() - c
    setattr(owner, name, w)
timed(cg.JITCodeLibrary, "_optimize_functions", "function passes")
timed(cg.JITCodeLibrary, "_optimize_final_module", "module passes")
timed(cg.JITCodeLibrary, "_finalize_specific", "machine code")
wrappers = collections.Counter()
orig_cw = lowering.BaseLower.create_cfunc_wrapper
def cw(self, *a, **k):
    wrappers["C"] += 1
    return orig_cw(self, *a, **k)
lowering.BaseLower.create_cfunc_wrapper = cw
own, stack = collections.Counter(), []
orig_ce = compiler.compile_extra
def ce(*a, **k):
    name = getattr(a[2], "__qualname__", "?")
    c = time.process_time()
    stack.append(0.0)
    try:
        return orig_ce(*a, **k)
    finally:
        dt = time.process_time() - c
        own["core" if "_run_core" in name else "helpers"] += dt - stack.pop()
        if stack:
            stack[-1] += dt
compiler.compile_extra = ce
if exp == "opt0":
    _cache.kernel_opt.__wrapped__.__defaults__ = (0,)
elif exp.startswith("helpers"):
    lvl = int(exp[-1])
    def at_helper_level(fn):
        def w(self, *a, **k):
            old = config.OPT
            if "_run_core" not in self.name and int(old) > lvl:
                config.OPT = config._OptLevel(lvl)
            try:
                return fn(self, *a, **k)
            finally:
                config.OPT = old
        return w
    cg.JITCodeLibrary.finalize = at_helper_level(cg.JITCodeLibrary.finalize)
    cg.JITCodeLibrary.add_llvm_module = at_helper_level(cg.JITCodeLibrary.add_llvm_module)
ball = b.make_ball()
ball.compile()
own.clear(); llvm.clear(); wrappers.clear()
c = time.process_time()
arc = simulate_compiled(ball, [1.0, 0.0], t_max=1e9, j_max=30, rtol=1e-8, atol=1e-10)
cpu = time.process_time() - c
run = lambda: simulate_compiled(ball, [1.0, 0.0], t_max=1e9, j_max=30, rtol=1e-8, atol=1e-10)
for _ in range(50):
    run()
us = min(timeit.repeat(run, number=200, repeat=7)) / 200 * 1e6
print("OUT", dict(cpu=cpu, us=us, bits=float(arc.x[-1][1]).hex(), llvm=dict(llvm),
                  own=dict(own), wrappers=wrappers["C"]))
"""


def child(exp):
    """One fresh process, empty cache: its printed figures."""
    import ast
    with tempfile.TemporaryDirectory() as d:
        env = dict(os.environ, NUMBA_CACHE_DIR=d,
                   PYTHONPATH=os.pathsep.join(p for p in (os.path.dirname(HERE),
                                                          os.environ.get("PYTHONPATH")) if p))
        out = subprocess.run([sys.executable, "-c", CHILD.format(here=HERE, exp=exp)],
                             capture_output=True, text=True, timeout=1800, env=env)
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("OUT")][-1]
    return ast.literal_eval(line[4:])


def main():
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 2
    exps = ("base", "opt0", "helpers0", "helpers1")
    rows = {e: [] for e in exps}
    for _ in range(rounds):
        for e in exps:
            rows[e].append(child(e))
    b = rows["base"][0]
    total = b["cpu"]
    llvm = sum(b["llvm"].values())
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"the engine's first compile (base, first round): {total:.2f} s of CPU; "
          f"{b['wrappers']} C wrappers made")
    print(f"  LLVM {llvm:.2f} s ({llvm / total:.0%}): " +
          ", ".join(f"{k} {v:.2f} s" for k, v in b["llvm"].items()))
    print(f"  the run core's own compile {b['own'].get('core', 0):.2f} s, "
          f"its helpers' {b['own'].get('helpers', 0):.2f} s (each with its LLVM)")
    print(f"{'lever':<10} {'compile, median':>16} {'ball run, median':>17}  bits")
    for e in exps:
        cpu = statistics.median(r["cpu"] for r in rows[e])
        us = statistics.median(r["us"] for r in rows[e])
        bits = {r["bits"] for r in rows[e]}
        same = "same" if bits == {b["bits"]} else f"DIFFER {bits}"
        print(f"{e:<10} {cpu:14.2f} s {us:14.1f} us  {same}")


if __name__ == "__main__":
    main()
