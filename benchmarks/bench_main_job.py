"""The main job's time: ``python -m observers reproduce``, whole and per part.

Usage::

    python benchmarks/bench_main_job.py [--against REF] [--rounds 1] [--quick]

Runs the main job in a fresh process into a temporary folder and prints
each part's time (figures + claims, from its ``part.json``), the whole
run's wall time beside the issue-23 target of 90 s on two cores, and its
CPU time (user + system of the child process, what ``/usr/bin/time``
reports; the issue-42 figure is a ratio of these). With
``--against REF`` (a git revision, e.g. ``HEAD~5``) the same job at REF is
checked out into a temporary git worktree and timed in the same run,
alternating A B A B over ``--rounds``; the closing line is the ratio of
medians. ``--quick`` runs the engine and li_sanfelice parts only.

Each run starts a new interpreter, so imports and the first use of every
code path are counted, as a user sees them; numba's kernel cache is warm
(the compiled path is not used by the main job).
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import resource
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
TARGET = 90.0


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_job(root: pathlib.Path, names: list[str]) -> tuple[float, float, dict]:
    """Wall and CPU time of one main job at ``root`` and each part's seconds."""
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(root))
    with tempfile.TemporaryDirectory() as out:
        t0, c0 = time.perf_counter(), _child_cpu()
        proc = subprocess.run([sys.executable, "-m", "observers", "reproduce", *names,
                               "--out", out], cwd=root, env=env, capture_output=True,
                              text=True, timeout=1800)
        wall, cpu = time.perf_counter() - t0, _child_cpu() - c0
        if proc.returncode:
            print(proc.stdout[-2000:], proc.stderr[-2000:], sep="\n")
            raise SystemExit(f"the main job at {root} failed (exit {proc.returncode})")
        parts = {}
        for path in sorted(pathlib.Path(out).glob("*/part.json")):
            p = json.loads(path.read_text())
            parts[p["name"]] = (p["seconds"], p.get("claims_seconds") or 0.0)
    return wall, cpu, parts


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", help="a git revision to time in the same run")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    names = ["engine", "li_sanfelice"] if args.quick else []
    roots = {"now": ROOT}
    tmp = None
    if args.against:
        tmp = tempfile.mkdtemp(prefix="hybridsim-base-")
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", tmp,
                        args.against], check=True, capture_output=True)
        roots[args.against] = pathlib.Path(tmp)
    walls = {k: [] for k in roots}
    cpus = {k: [] for k in roots}
    last = {}
    try:
        for _ in range(args.rounds):
            for key, root in roots.items():
                wall, cpu, parts = run_job(root, names)
                walls[key].append(wall)
                cpus[key].append(cpu)
                last[key] = parts
    finally:
        if tmp:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", tmp],
                           capture_output=True)
    print(f"{'part':16s} " + " ".join(f"{k:>22s}" for k in roots))
    every = sorted({n for parts in last.values() for n in parts})
    for name in every:
        cells = []
        for key in roots:
            f, c = last[key].get(name, (float("nan"), 0.0))
            cells.append(f"{f:8.1f} + {c:5.1f} s")
        print(f"{name:16s} " + " ".join(f"{c:>22s}" for c in cells))
    med = {k: statistics.median(v) for k, v in walls.items()}
    cpu = {k: statistics.median(v) for k, v in cpus.items()}
    for key in roots:
        print(f"{'whole job':16s} {key}: median {med[key]:.1f} s wall, {cpu[key]:.1f} s CPU "
              f"over {len(walls[key])} run(s) ({', '.join(f'{w:.1f}' for w in walls[key])} s "
              f"wall; {', '.join(f'{c:.1f}' for c in cpus[key])} s CPU)")
    line = f"main job {med['now']:.1f} s, {med['now'] / TARGET:.2f}x the 90 s target"
    if args.against:
        line += (f"; {med['now'] / med[args.against]:.2f}x the time and "
                 f"{cpu['now'] / cpu[args.against]:.2f}x the CPU at {args.against}")
    print("RESULT", line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
