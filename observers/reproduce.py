"""Regenerate every paper's results and figures: ``python -m observers reproduce``.

Usage
-----
``python -m observers reproduce [NAME ...] [--out DIR] [--no-claims]``

NAME is one of ``engine`` (bouncing ball and timer demos of the engine),
``li_sanfelice``, ``gramian_delay``, ``time_varying``, ``dynamic_gain``,
``distributed``; default all. For each part:

1. its ``reproduce(outdir)`` writes the figures into ``DIR/NAME/``. Every
   paper package's ``reproduce`` takes one positional argument, the existing
   output folder (a ``str`` or ``pathlib.Path``), and returns the list of
   ``pathlib.Path`` of the PNGs it wrote, each with a ``.txt`` caption
   beside it (extra keyword arguments, all with defaults, are the paper's
   business; the main job never passes them);
2. its ``CLAIMS`` are evaluated (:mod:`observers.claims`), unless
   ``--no-claims``;
3. what it produced is recorded in ``DIR/NAME/part.json``
   (:class:`observers.report.Part`), with its ``PAPER``, ``ERRATA`` and
   ``DECISIONS``.

Then ``DIR/claims.csv`` (every claim of every part recorded in DIR) and
``DIR/index.html`` (the report: open it first) are written.

A part that fails is reported and the others still run. The exit status is 1
if a part run now failed (its import, ``reproduce``, its return value, or
its ``CLAIMS`` registry) or one of its claims did not reach its expected
verdict.

``python -m observers report [--out DIR]`` rewrites ``index.html`` and
``claims.csv`` from the parts already recorded in DIR, without running them.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import os
import pathlib
import sys
import time
import traceback

from .claims import PAPER_MODULES, run_claims, validate_registry
from .report import Part, paper_metadata, write_report

__all__ = ["PAPERS", "main", "run_part"]

PAPERS = ["engine", *PAPER_MODULES]


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


class _Tee(io.TextIOBase):
    """Write to a console stream and keep a copy (a part's log for the report)."""

    def __init__(self, stream):
        self.stream, self.copy = stream, io.StringIO()

    def write(self, s):
        self.copy.write(s)
        return self.stream.write(s)

    def flush(self):
        self.stream.flush()


def _figure_paths(paths, outdir: pathlib.Path, root: pathlib.Path, who: str):
    """Check what ``reproduce(outdir)`` returned; the PNGs relative to ``root``
    and the problems (missing captions)."""
    if isinstance(paths, (str, bytes, os.PathLike)) or not isinstance(paths, (list, tuple)):
        raise TypeError(f"{who}(outdir) must return a list of pathlib.Path (the PNGs written),"
                        f" got {type(paths).__name__}")
    rel, problems = [], []
    for k, p in enumerate(paths):
        if not isinstance(p, (str, os.PathLike)):
            raise TypeError(f"{who}(outdir) returned a {type(p).__name__} at position {k}; "
                            "expected the path of a PNG")
        p = pathlib.Path(p)
        if not p.is_absolute():
            p = (p if p.exists() else outdir / p)
        if p.suffix.lower() != ".png" or not p.is_file():
            raise ValueError(f"{who}(outdir) returned {str(p)!r} at position {k}, which is "
                             "not an existing .png file")
        try:
            rel.append(p.resolve().relative_to(root.resolve()).as_posix())
        except ValueError:
            raise ValueError(f"{who}(outdir) returned {str(p)!r}, outside the output folder "
                             f"{str(outdir)!r}") from None
        if not p.with_suffix(".txt").is_file():
            problems.append(f"{p.name} has no caption ({p.with_suffix('.txt').name} missing)")
    return rel, problems


def run_part(name: str, out, *, claims: bool = True) -> Part:
    """Run one part of the main job into ``out/<name>/`` and record it.

    Parameters
    ----------
    name : str
        ``"engine"`` or a paper package's name (:data:`PAPERS`).
    out : str or pathlib.Path
        The main job's output folder (created if needed).
    claims : bool
        Evaluate the package's ``CLAIMS`` (default True).

    Returns
    -------
    observers.report.Part
        Also saved as ``out/<name>/part.json``. Nothing is raised for a
        failing part: ``status`` is ``"failed"`` and ``error`` holds the
        traceback.

    Raises
    ------
    ValueError
        ``name`` is not one of :data:`PAPERS`.

    Examples
    --------
    >>> import contextlib, io, tempfile
    >>> with contextlib.redirect_stdout(io.StringIO()):
    ...     part = run_part("engine", tempfile.mkdtemp())
    >>> part.status, part.figures
    ('ok', ['engine/bouncing_ball.png', 'engine/timer_hybrid.png'])
    """
    if name not in PAPERS:
        raise ValueError(f"name must be one of {PAPERS}, got {name!r}")
    out = pathlib.Path(out)
    d = out / name
    d.mkdir(parents=True, exist_ok=True)
    part = Part(name=name)
    tee = _Tee(sys.stdout)
    err = _Tee(sys.stderr)
    err.copy = tee.copy                    # one log, warnings where they happened
    with contextlib.redirect_stdout(tee), contextlib.redirect_stderr(err):
        print(f"[{name}] -> {d}")
        mod = None
        t0 = time.perf_counter()
        try:
            if name == "engine":
                who, paths = "observers.reproduce._engine_demo", _engine_demo(d)
            else:
                mod = importlib.import_module(f"observers.{name}")
                who, paths = f"observers.{name}.reproduce", mod.reproduce(d)
            part.figures, part.problems = _figure_paths(paths, d, out, who)
            print(f"[{name}] {len(part.figures)} figure(s) in "
                  f"{time.perf_counter() - t0:.1f} s")
        except Exception:  # noqa: BLE001 - report and go on with the other parts
            part.status, part.error = "failed", traceback.format_exc()
            print(part.error, end="")
            print(f"[{name}] FAILED")
        part.seconds = time.perf_counter() - t0
        if mod is not None:
            meta = paper_metadata(mod)
            part.paper, part.errata, part.decisions = (meta["paper"], meta["errata"],
                                                       meta["decisions"])
            part.problems = meta["problems"] + part.problems
            registry = getattr(mod, "CLAIMS", None)
            if registry is None:
                part.claims_note = f"observers.{name} defines no CLAIMS yet"
                part.problems.append(f"observers.{name} defines no CLAIMS (no claims table)")
            elif not claims:
                part.claims_note = "claims not evaluated (--no-claims)"
            else:
                t1 = time.perf_counter()
                try:
                    paper_id = (part.paper or {}).get("id")
                    registry = validate_registry(registry, paper=paper_id)
                    print(f"[{name}] {len(registry)} claim(s)")
                    part.claims = [r.row() for r in run_claims(registry, echo=print)]
                    bad = [r["id"] for r in part.claims if not r["passed"]]
                    print(f"[{name}] claims: {len(part.claims) - len(bad)} of "
                          f"{len(part.claims)} as expected"
                          + (f"; NOT as expected: {', '.join(bad)}" if bad else ""))
                except (TypeError, ValueError) as exc:
                    part.claims_note = f"observers.{name}.CLAIMS is invalid: {exc}"
                    part.status = "failed"
                    part.error += f"observers.{name}.CLAIMS is invalid: {exc}\n"
                    print(f"[{name}] {part.claims_note}")
                part.claims_seconds = time.perf_counter() - t1
        elif name != "engine":
            part.claims_note = f"observers.{name} could not be imported"
    part.log = tee.copy.getvalue()
    part.save(out)
    return part


def main(argv=None):
    """The command line: ``reproduce [NAME ...] [--out DIR] [--no-claims]``, ``report``."""
    p = argparse.ArgumentParser(prog="python -m observers",
                                description="Reproduce the papers' results and figures.")
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("reproduce", help="regenerate figures, claims and the report")
    r.add_argument("names", nargs="*", choices=[*PAPERS, []], default=[],
                   help="which to run (default: all)")
    r.add_argument("--out", default="results", help="output folder (default: results)")
    r.add_argument("--no-claims", action="store_true",
                   help="do not evaluate the papers' claims")
    rep = sub.add_parser("report", help="rewrite index.html and claims.csv from the parts "
                                        "recorded in the output folder")
    rep.add_argument("--out", default="results", help="output folder (default: results)")
    args = p.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    out = pathlib.Path(args.out)
    command = "python -m observers " + " ".join(sys.argv[1:] if argv is None else argv)
    if args.cmd == "report":
        if not out.is_dir():
            print(f"--out {str(out)!r} is not a folder", file=sys.stderr)
            return 2
        page = write_report(out, command=command)
        print(f"report: {page.resolve()}")
        return 0
    names = list(dict.fromkeys(args.names or PAPERS))
    failed, off = [], []
    for name in names:
        part = run_part(name, out, claims=not args.no_claims)
        if part.status != "ok":
            failed.append(name)
        off += [row["id"] for row in part.claims or [] if not row["passed"]]
    page = write_report(out, command=command)
    print(f"claims: {(out / 'claims.csv').resolve()}")
    print(f"report: {page.resolve()}  (open it first)")
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    if off:
        print(f"claims not as expected: {', '.join(off)}", file=sys.stderr)
    if failed or off:
        return 1
    print(f"all results in {out.resolve()}")
    return 0
