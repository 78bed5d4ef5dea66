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
    """Bouncing ball and timer: the engine's own demo figures.

    ``bouncing_ball.png``: the ball's height and velocity against t (one
    subplot each, shared t; a bounce is the velocity's jump, dotted from a
    filled circle to an open one) beside its hybrid time domain.
    ``timer_hybrid.png``: a timer in 3-D over (t, j). Each with a ``.txt``
    caption.

    Parameters
    ----------
    outdir : str or pathlib.Path
        Existing folder for the figures.

    Returns
    -------
    list of pathlib.Path
        The PNG files written.

    Examples
    --------
    >>> import contextlib, io, tempfile
    >>> with contextlib.redirect_stdout(io.StringIO()):      # it prints its numbers
    ...     paths = _engine_demo(tempfile.mkdtemp())
    >>> [p.name for p in paths]
    ['bouncing_ball.png', 'timer_hybrid.png']
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import hybridsim as hs
    from hybridsim.library import BouncingBall, Timer, bouncing_ball_jump_times

    outdir = pathlib.Path(outdir)
    h0, g, e, n_jumps = 1.0, 9.81, 0.8, 30
    arc = hs.simulate(BouncingBall(g, e), [h0, 0.0], t_max=5.0, j_max=n_jumps, rtol=1e-10,
                      atol=1e-12)
    fig = plt.figure(figsize=(12, 5))
    grid = fig.add_gridspec(2, 2, width_ratios=[3, 2])
    ax_h = fig.add_subplot(grid[0, 0])
    ax_v = fig.add_subplot(grid[1, 0], sharex=ax_h)
    ax_h.tick_params(labelbottom=False)
    hs.plot_flows(arc, subplots=True, ax=[ax_h, ax_v], labels=["height (m)", "velocity (m/s)"],
                  xlabel="$t$ (s)", legend=False)
    ax_h.set_title("height and velocity against $t$")
    ax_d = fig.add_subplot(grid[:, 1])
    hs.plot_time_domain(arc, ax=ax_d, xlabel="$t$ (s)")
    ax_d.set_title("hybrid time domain")
    fig.suptitle(f"bouncing ball, $h_0$ = {h0:g} m, $g$ = {g} m/s$^2$, restitution {e}, "
                 f"{arc.jump_count} jumps")
    fig.tight_layout()
    paths = [outdir / "bouncing_ball.png"]
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)
    ex = bouncing_ball_jump_times(h0, arc.jump_count, g, e)
    err = np.max(np.abs(arc.jump_times - ex))
    paths[-1].with_suffix(".txt").write_text(
        f"Bouncing ball (h0 = {h0:g} m, g = {g} m/s^2, restitution {e}; values chosen for the "
        f"demo), {arc.jump_count} jumps, RK45 at rtol 1e-10. Left: height and velocity against "
        "t, flows drawn from the arc's interpolant between samples; each bounce is a jump of "
        "the velocity, dotted from the pre-jump value (filled circle) to the post-jump value "
        "(open circle). Right: the hybrid time domain, [t_j, t_{j+1}] x {j} for each j. "
        f"Largest jump-time error against the closed form: {err:.1e} s.\n")
    print(f"  bouncing ball: {arc.jump_count} jumps, largest jump-time error {err:.2e}")
    arc = hs.simulate(Timer(1.0), [0.0], t_max=5.5)
    ax = hs.plot_hybrid(arc, 0, labels=[r"timer $\tau$"])
    ax.set_title("timer, period 1, in hybrid time $(t, j, \\tau)$")
    paths.append(outdir / "timer_hybrid.png")
    ax.figure.savefig(paths[-1], dpi=120)
    plt.close(ax.figure)
    paths[-1].with_suffix(".txt").write_text(
        "A timer with period 1 (flow 1, reset to 0 at tau = 1) over t in [0, 5.5], drawn in "
        "hybrid time (t, j, tau): flows along t at constant j, each reset a dotted jump from "
        "(t, j, 1) (filled circle) to (t, j + 1, 0) (open circle).\n")
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
