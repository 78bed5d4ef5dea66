"""Run every benchmark script in this folder and print their figures.

Usage: ``python benchmarks/run_all.py [--quick]``

Each ``bench_*.py`` is run in its own process (with one BLAS thread) and
prints its own table, each figure beside its baseline measured in the same
run. Lines starting with ``RESULT`` are gathered into one closing table.
``--quick`` is passed on to scripts that accept it (smaller sizes).
"""
from __future__ import annotations

import os
import pathlib
import platform
import subprocess
import sys
import time


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    here = pathlib.Path(__file__).resolve().parent
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MPLBACKEND="Agg")
    results, status = [], []
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, {platform.platform()}")
    for script in sorted(here.glob("bench_*.py")):
        print(f"\n=== {script.name} ===", flush=True)
        t0 = time.perf_counter()
        # --quick only to the scripts that take it
        args = [a for a in argv if a != "--quick" or "--quick" in script.read_text()]
        proc = subprocess.run([sys.executable, str(script), *args], env=env,
                              capture_output=True, text=True, timeout=1800)
        dt = time.perf_counter() - t0
        print(proc.stdout, end="")
        if proc.returncode:
            print(proc.stderr[-3000:], end="")
        status.append((script.name, proc.returncode, dt))
        results += [f"{script.name}: {ln[len('RESULT'):].strip(' :')}"
                    for ln in proc.stdout.splitlines() if ln.startswith("RESULT")]
    print("\n=== summary ===")
    for name, rc, dt in status:
        print(f"{name:28s} {'ok' if rc == 0 else f'FAILED ({rc})':12s} {dt:7.1f} s")
    for r in results:
        print(r)
    return 0 if all(rc == 0 for _, rc, _ in status) else 1


if __name__ == "__main__":
    raise SystemExit(main())
