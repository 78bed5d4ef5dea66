"""Run every benchmark script in this folder, print their figures, write the docs page.

Usage::

    python benchmarks/run_all.py [--quick] [--page docs/benchmarks.rst] [--only NAME ...]

Each ``bench_*.py`` is run in its own process (with one BLAS thread) and
prints its own table, each figure beside its baseline measured in the same
run. Lines starting with ``RESULT`` are gathered into one closing table.
``--quick`` is passed on to scripts that accept it (smaller sizes).

``--page PATH`` writes that table as the documentation's benchmarks page
(reStructuredText, :func:`page`): the run's date, the machine named once
(processor, cores, load, Python and the libraries' versions), each
script's status and time, and its ``RESULT`` lines, so that the page holds
the figures of one run and nothing else. ``--only`` runs the named scripts
alone (``bench_sensitivity`` or ``bench_sensitivity.py``); a page written
from such a run says which scripts it covers.
"""
from __future__ import annotations

import argparse
import datetime
import importlib.metadata
import os
import pathlib
import platform
import subprocess
import sys
import time

#: The libraries whose versions the page names (those installed).
LIBRARIES = ("numpy", "scipy", "numba", "matplotlib", "jax", "diffrax", "psy-taliro")


def _cpu_model() -> str:
    """The processor's name (Linux: /proc/cpuinfo), else the platform's word for it."""
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict:
    """What the figures were measured on: processor, cores, system, Python, libraries."""
    libs = {}
    for name in LIBRARIES:
        try:
            libs[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return {"processor": f"{_cpu_model()} ({platform.machine()})",
            "cores": os.cpu_count(), "system": platform.platform(),
            "python": platform.python_version(), "libraries": libs}


def _load() -> str:
    try:
        return " / ".join(f"{v:.2f}" for v in os.getloadavg())
    except (AttributeError, OSError):        # not on this system
        return "unknown"


def _split(result: str) -> tuple[str, str]:
    """``"what: figures"`` into its two parts (at the first ": ")."""
    what, sep, figures = result.partition(": ")
    return (what, figures) if sep else ("", result)


def _cell(text: str) -> str:
    r"""Text as a reST table cell: backslashes, ``|``, ``*`` and backquotes taken literally."""
    out = text.replace("\\", "\\\\")
    for ch in "|*`_":
        out = out.replace(ch, "\\" + ch)
    return out or "—"


def page(results, status, *, when, host, argv, load=("unknown", "unknown")) -> str:
    """The benchmarks page (reStructuredText) of one run.

    Parameters
    ----------
    results : list of (str, str)
        ``(script, RESULT line without its prefix)`` in the order printed.
    status : list of (str, int, float)
        ``(script, exit status, seconds)`` of every script run.
    when : datetime.datetime
        When the run started (written in UTC, to the minute).
    host : dict
        :func:`machine`.
    argv : list of str
        The run's arguments (``--quick``...), shown in the command.
    load : (str, str)
        The load averages (1, 5, 15 min) at the run's start and end.

    Returns
    -------
    str

    Examples
    --------
    >>> import datetime
    >>> text = page([("bench_x.py", "a ball: 1.0 ms vs 2.0 ms")], [("bench_x.py", 0, 1.5)],
    ...             when=datetime.datetime(2026, 1, 2, 3, 4, tzinfo=datetime.timezone.utc),
    ...             host={"processor": "cpu", "cores": 2, "system": "Linux", "python": "3.11",
    ...                   "libraries": {"numpy": "2.0"}}, argv=["--quick"])
    >>> "2026-01-02 03:04 UTC" in text, "     - 1.0 ms vs 2.0 ms" in text
    (True, True)
    """
    stamp = when.astimezone(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    cmd = " ".join(["python benchmarks/run_all.py", *argv])
    libs = ", ".join(f"{k} {v}" for k, v in host["libraries"].items())
    ok = sum(rc == 0 for _, rc, _ in status)
    lines = [
        "Benchmarks", "==========", "",
        ".. This page is written by benchmarks/run_all.py --page; do not edit it by hand.", "",
        f"The figures of one run of ``{cmd}``, started on {stamp}, on one machine: "
        f"{host['processor']}, {host['cores']} cores, {host['system']}, Python "
        f"{host['python']}, {libs}. Load average (1, 5, 15 min) at the start "
        f"{load[0]}, at the end {load[1]}: absolute times vary with the machine and its "
        f"load, ratios within a run less so.", "",
        "Each script prints a table of its own, every figure beside a baseline measured in "
        "the same run; below are its headline lines (``RESULT``). Run "
        "``python benchmarks/<script> --help`` for a script's options, and "
        "``pip install \".[bench]\"`` for the peers it compares with (diffrax, "
        "PSY-TaLiRo: rows without them are measured without them).", "",
        f"{ok} of {len(status)} scripts ran to completion. To measure again and rewrite "
        "this page: ``python benchmarks/run_all.py --quick --page docs/benchmarks.rst``.", "",
    ]
    if results:
        lines += [".. list-table::", "   :header-rows: 1", "   :widths: 20 30 50", "",
                  "   * - script", "     - what", "     - figures"]
        for script, result in results:
            what, figures = _split(result)
            lines += [f"   * - ``{script}``", f"     - {_cell(what)}",
                      f"     - {_cell(figures)}"]
    else:
        lines.append("No script printed a ``RESULT`` line.")
    lines += ["", "Scripts", "-------", "", ".. list-table::", "   :header-rows: 1", "",
              "   * - script", "     - status", "     - time (s)"]
    for script, rc, dt in status:
        lines += [f"   * - ``{script}``", f"     - {'ok' if rc == 0 else f'failed ({rc})'}",
                  f"     - {dt:.1f}"]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="pass --quick to the scripts that take it (smaller sizes)")
    ap.add_argument("--page", type=pathlib.Path, default=None,
                    help="write the documentation's benchmarks page here "
                         "(docs/benchmarks.rst)")
    ap.add_argument("--only", nargs="+", default=None, metavar="NAME",
                    help="run these scripts only (bench_x or bench_x.py)")
    args = ap.parse_args(sys.argv[1:] if argv is None else argv)
    here = pathlib.Path(__file__).resolve().parent
    scripts = sorted(here.glob("bench_*.py"))
    if args.only:
        wanted = {n if n.endswith(".py") else f"{n}.py" for n in args.only}
        unknown = sorted(wanted - {s.name for s in scripts})
        if unknown:
            ap.error(f"--only: no such script {', '.join(unknown)} (choose from "
                     f"{', '.join(s.name for s in scripts)})")
        scripts = [s for s in scripts if s.name in wanted]
    # this checkout's packages, installed or not
    path = os.pathsep.join(p for p in (str(here.parent), os.environ.get("PYTHONPATH")) if p)
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MPLBACKEND="Agg",
               PYTHONPATH=path)
    when, load0 = datetime.datetime.now(datetime.UTC), _load()
    host = machine()
    results, status = [], []
    print(f"machine: {host['processor']}, {host['cores']} cores, Python {host['python']}, "
          f"{host['system']}")
    for script in scripts:
        print(f"\n=== {script.name} ===", flush=True)
        t0 = time.perf_counter()
        # --quick only to the scripts that take it
        extra = ["--quick"] if args.quick and "--quick" in script.read_text() else []
        proc = subprocess.run([sys.executable, str(script), *extra], env=env,
                              capture_output=True, text=True, timeout=1800)
        dt = time.perf_counter() - t0
        print(proc.stdout, end="")
        if proc.returncode:
            print(proc.stderr[-3000:], end="")
        status.append((script.name, proc.returncode, dt))
        results += [(script.name, ln[len("RESULT"):].strip(" :"))
                    for ln in proc.stdout.splitlines() if ln.startswith("RESULT")]
    print("\n=== summary ===")
    for name, rc, dt in status:
        print(f"{name:28s} {'ok' if rc == 0 else f'FAILED ({rc})':12s} {dt:7.1f} s")
    for name, r in results:
        print(f"{name}: {r}")
    if args.page is not None:
        shown = (["--quick"] if args.quick else []) + (
            ["--only", *[s.name for s in scripts]] if args.only else [])
        args.page.write_text(page(results, status, when=when, host=host, argv=shown,
                                  load=(load0, _load())), encoding="utf-8")
        print(f"page written: {args.page}")
    return 0 if all(rc == 0 for _, rc, _ in status) else 1


if __name__ == "__main__":
    raise SystemExit(main())
