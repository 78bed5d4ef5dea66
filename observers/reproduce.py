"""Regenerate every paper's results and figures: ``python -m observers reproduce``.

Usage
-----
``python -m observers reproduce [NAME ...] [--out DIR]``

NAME is one of ``engine`` (bouncing ball and timer demos of the engine),
``li_sanfelice``, ``gramian_delay``, ``time_varying``, ``dynamic_gain``,
``distributed``; default all. Each module's ``reproduce(outdir)`` writes its
PNG figures, each with a ``.txt`` caption beside it, into ``DIR/NAME/``.
A paper whose reproduction fails is reported and the others still run; the
exit status is 1 if any failed.
"""
from __future__ import annotations

import argparse
import importlib
import pathlib
import sys
import time
import traceback

PAPERS = ["engine", "li_sanfelice", "gramian_delay", "time_varying", "dynamic_gain",
          "distributed"]


def _engine_demo(outdir):
    """Bouncing ball and timer: the engine's own demo figures."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import hybridsim as hs
    from hybridsim.library import BouncingBall, Timer, bouncing_ball_jump_times

    outdir = pathlib.Path(outdir)
    arc = hs.simulate(BouncingBall(9.81, 0.8), [1.0, 0.0], t_max=5.0, j_max=30, rtol=1e-10,
                      atol=1e-12, refine=12)
    fig, axs = plt.subplots(1, 3, figsize=(14, 4))
    hs.plot_flows(arc, 0, ax=axs[0]).set_title("height against t")
    hs.plot_jumps(arc, 0, ax=axs[1]).set_title("height against j")
    hs.plot_time_domain(arc, ax=axs[2]).set_title("hybrid time domain")
    fig.tight_layout()
    paths = [outdir / "bouncing_ball.png"]
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)
    paths[-1].with_suffix(".txt").write_text(
        "Bouncing ball (h0 = 1 m, g = 9.81, restitution 0.8), 30 jumps, rtol 1e-10: "
        "height against t (jumps dashed), against j, and the hybrid time domain.\n")
    ex = bouncing_ball_jump_times(1.0, 30)
    print(f"  bouncing ball: 30 jumps, largest jump-time error "
          f"{np.max(np.abs(arc.jump_times - ex)):.2e}")
    arc = hs.simulate(Timer(1.0), [0.0], t_max=5.5, refine=4)
    ax = hs.plot_hybrid(arc, 0)
    ax.set_title("timer, period 1, in hybrid time (t, j, x)")
    paths.append(outdir / "timer_hybrid.png")
    ax.figure.savefig(paths[-1], dpi=120)
    plt.close(ax.figure)
    paths[-1].with_suffix(".txt").write_text(
        "A timer with period 1 (flow 1, reset to 0 at x = 1) over t in [0, 5.5], drawn in "
        "hybrid time (t, j, x).\n")
    print(f"  timer: jump times {arc.jump_times} (exact multiples of 1 up to "
          f"{np.max(np.abs(arc.jump_times - np.arange(1, 6))):.1e})")
    return paths


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m observers",
                                description="Reproduce the papers' results and figures.")
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("reproduce", help="regenerate figures and results")
    r.add_argument("names", nargs="*", choices=PAPERS + [[]], default=[],
                   help="which to run (default: all)")
    r.add_argument("--out", default="results", help="output folder (default: results)")
    args = p.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    names = args.names or PAPERS
    out = pathlib.Path(args.out)
    failed = []
    for name in names:
        d = out / name
        d.mkdir(parents=True, exist_ok=True)
        print(f"[{name}] -> {d}")
        t0 = time.perf_counter()
        try:
            if name == "engine":
                paths = _engine_demo(d)
            else:
                mod = importlib.import_module(f"observers.{name}")
                paths = mod.reproduce(d)
            print(f"[{name}] {len(paths)} figure(s) in {time.perf_counter() - t0:.1f} s")
        except Exception:  # noqa: BLE001 - report and go on with the other papers
            traceback.print_exc()
            failed.append(name)
            print(f"[{name}] FAILED")
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    print(f"all results in {out.resolve()}")
    return 0
