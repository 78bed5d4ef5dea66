"""Regenerate every paper's results and figures: ``python -m observers reproduce``.

Usage
-----
``python -m observers reproduce [NAME ...] [--out DIR] [--no-claims] [--verbose]``

NAME is one of ``engine`` (bouncing ball and timer demos of the engine),
``li_sanfelice``, ``gramian_delay``, ``time_varying``, ``dynamic_gain``,
``distributed``; default all. For each part:

1. its figures are written into ``DIR/NAME/``: each :class:`Figure` of the
   package's ``FIGURES`` (the contract of :mod:`observers._common`; a
   package without them is run through its ``reproduce(outdir)``, which
   returns the PNGs' paths), each PNG with a ``.txt`` caption beside it;
2. its ``CLAIMS`` are evaluated (:mod:`observers.claims`), unless
   ``--no-claims``; the claims read the figures' cached runs, so nothing
   is computed twice;
3. what it produced is recorded in ``DIR/NAME/part.json``
   (:class:`observers.report.Part`), with its ``PAPER``, ``ERRATA``,
   ``DECISIONS`` and ``NOT_REPRODUCED``;
4. its falsification problems expected to find a counterexample (the
   errata, searched from the statements as printed) are searched, unless
   ``--no-falsify``; ``python -m observers falsify`` runs them all, those
   expected to survive their budgets included.

The terminal shows one progress bar over every figure and claim (when it
is a terminal), one line per part, and what needs attention: a warning
logged, a claim not as expected, a failure. What the parts log
(:mod:`logging`, logger ``observers``) and one line per claim go to the
part's record and the report (``--verbose`` prints them too).

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
import logging
import os
import pathlib
import sys
import time
import traceback

from ._common import Figure, reproduce_figures
from .claims import PAPER_MODULES, evaluate, validate_registry
from .report import Part, paper_metadata, write_report

log = logging.getLogger(__name__)

__all__ = ["ENGINE_FIGURES", "PAPERS", "main", "run_part"]

PAPERS = ["engine", *PAPER_MODULES]



def _runs(n):
    """``n`` runs, in words: "1 run", "16 runs"."""
    return f"{n} run" if n == 1 else f"{n} runs"

def _ball_data():
    """The bouncing ball's run and its jump-time error against the closed form."""
    import numpy as np

    import hybridsim as hs
    from hybridsim.library import BouncingBall, bouncing_ball_jump_times
    h0, g, e, n_jumps = 1.0, 9.81, 0.8, 30
    arc = hs.simulate(BouncingBall(g, e), [h0, 0.0], t_max=5.0, j_max=n_jumps, rtol=1e-10,
                      atol=1e-12)
    err = float(np.max(np.abs(arc.jump_times - bouncing_ball_jump_times(h0, arc.jump_count,
                                                                         g, e))))
    log.info("bouncing ball: %d jumps, largest jump-time error %.2e", arc.jump_count, err)
    return {"arc": arc, "h0": h0, "g": g, "e": e, "err": err}


def _ball_draw(d):
    from matplotlib.figure import Figure

    import hybridsim as hs
    arc = d["arc"]
    fig = Figure(figsize=(12, 5))
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
    fig.suptitle(f"bouncing ball, $h_0$ = {d['h0']:g} m, $g$ = {d['g']} m/s$^2$, restitution "
                 f"{d['e']}, {arc.jump_count} jumps")
    fig.tight_layout()
    return fig


def _ball_caption(d):
    return (f"Bouncing ball (h0 = {d['h0']:g} m, g = {d['g']} m/s^2, restitution {d['e']}; "
            f"values chosen for the demo), {d['arc'].jump_count} jumps, RK45 at rtol 1e-10. "
            "Left: height and velocity against t, flows drawn from the arc's interpolant "
            "between samples; each bounce is a jump of the velocity, dotted from the pre-jump "
            "value (filled circle) to the post-jump value (open circle). Right: the hybrid "
            "time domain, [t_j, t_{j+1}] x {j} for each j. Largest jump-time error against the "
            f"closed form: {d['err']:.1e} s.")


def _timer_data():
    import numpy as np

    import hybridsim as hs
    from hybridsim.library import Timer
    arc = hs.simulate(Timer(1.0), [0.0], t_max=5.5)
    log.info("timer: jump times %s (exact multiples of 1 up to %.1e)", arc.jump_times,
             np.max(np.abs(arc.jump_times - np.arange(1, 6))))
    return arc


def _timer_draw(arc):
    from matplotlib.figure import Figure

    import hybridsim as hs
    fig = Figure()
    ax = fig.add_subplot(projection="3d")
    hs.plot_hybrid(arc, 0, labels=[r"timer $\tau$"], ax=ax)
    ax.set_title("timer, period 1, in hybrid time $(t, j, \\tau)$")
    return fig


#: The engine's demo figures (the ``engine`` part of the main job).
ENGINE_FIGURES = [
    Figure("bouncing_ball", "bouncing ball", _ball_data, _ball_draw, _ball_caption),
    Figure("timer_hybrid", "timer in hybrid time", _timer_data, _timer_draw,
           lambda arc: "A timer with period 1 (flow 1, reset to 0 at tau = 1) over t in "
           "[0, 5.5], drawn in hybrid time (t, j, tau): flows along t at constant j, each reset "
           "a dotted jump from (t, j, 1) (filled circle) to (t, j + 1, 0) (open circle)."),
]


def _engine_demo(outdir):
    """Bouncing ball and timer: the engine's own demo figures (:data:`ENGINE_FIGURES`).

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
    >>> import tempfile
    >>> [p.name for p in _engine_demo(tempfile.mkdtemp())]
    ['bouncing_ball.png', 'timer_hybrid.png']
    """
    return reproduce_figures(ENGINE_FIGURES, outdir)


class _Tee(io.TextIOBase):
    """Write to a console stream and keep a copy (a part's log for the report)."""

    def __init__(self, stream):
        self.stream, self.copy = stream, io.StringIO()

    def write(self, s):
        self.copy.write(s)
        return self.stream.write(s)

    def flush(self):
        self.stream.flush()


class _PartLog(logging.Handler):
    """Keeps a part's log records (for the report) and shows warnings at once.

    INFO and DEBUG records go to the part's log only (the report shows them);
    WARNING and above are also written to the terminal, above the progress
    bar, so nothing unexpected is silent.
    """

    def __init__(self, copy, echo):
        super().__init__(logging.DEBUG)
        self.copy, self.echo = copy, echo
        self.setFormatter(logging.Formatter("%(message)s"))

    def emit(self, record):
        try:
            text = self.format(record)
            if record.levelno >= logging.WARNING:
                text = f"{record.levelname}: {text}"
                self.echo(text)
            self.copy.write(text + "\n")
        except Exception:  # noqa: BLE001 - logging must never break the job
            self.handleError(record)


class _Progress:
    """One progress bar over the figures and claims of every part (tqdm, to stderr;
    tqdm turns itself off when stderr is not a terminal)."""

    def __init__(self, total, enabled=None):
        from tqdm.auto import tqdm
        self.bar = tqdm(total=total, unit="step", disable=None if enabled is None else not enabled,
                        leave=False, dynamic_ncols=True,
                        bar_format="{desc:<40.40} {percentage:3.0f}%|{bar}| "
                                   "{n_fmt}/{total_fmt} [{elapsed}<{remaining}]")

    def step(self, what):
        self.bar.set_description_str(what, refresh=False)
        self.bar.update(1)

    def write(self, line):
        self.bar.write(line, file=sys.stdout)

    def close(self):
        self.bar.close()


def _steps(name):
    """How many progress steps a part has (figures + claims); 1 when unknown."""
    if name == "engine":
        return len(ENGINE_FIGURES)
    try:
        mod = importlib.import_module(f"observers.{name}")
    except Exception:  # noqa: BLE001 - the part itself reports the failure
        return 1
    return len(getattr(mod, "FIGURES", ()) or ()) + len(getattr(mod, "CLAIMS", ()) or ())


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


def run_part(name: str, out, *, claims: bool = True, progress=None,
             echo=None) -> Part:
    """Run one part of the main job into ``out/<name>/`` and record it.

    Parameters
    ----------
    name : str
        ``"engine"`` or a paper package's name (:data:`PAPERS`).
    out : str or pathlib.Path
        The main job's output folder (created if needed).
    claims : bool
        Evaluate the package's ``CLAIMS`` (default True).
    progress : callable, optional
        Called with a short description after each figure and each claim
        (the main job's progress bar).
    echo : callable, optional
        Called with each line meant for the terminal: the part's summary,
        claims not as expected, warnings. Default: print to stdout.

    Returns
    -------
    observers.report.Part
        Also saved as ``out/<name>/part.json``; its ``log`` holds what the
        part logged (:mod:`logging`, logger ``observers``) and printed, and
        one line per claim. Nothing is raised for a failing part: ``status``
        is ``"failed"`` and ``error`` holds the traceback.

    Raises
    ------
    ValueError
        ``name`` is not one of :data:`PAPERS`.

    Examples
    --------
    >>> import tempfile
    >>> part = run_part("engine", tempfile.mkdtemp(), echo=lambda line: None)
    >>> part.status, part.figures
    ('ok', ['engine/bouncing_ball.png', 'engine/timer_hybrid.png'])
    """
    if name not in PAPERS:
        raise ValueError(f"name must be one of {PAPERS}, got {name!r}")
    echo = print if echo is None else echo
    step = progress or (lambda what: None)
    out = pathlib.Path(out)
    d = out / name
    d.mkdir(parents=True, exist_ok=True)
    part = Part(name=name)
    tee = _Tee(sys.stdout)
    err = _Tee(sys.stderr)
    err.copy = tee.copy                    # one log, warnings where they happened
    handler = _PartLog(tee.copy, echo)
    logger = logging.getLogger("observers")
    level, logger_level = logging.getLogger().level, logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    logging.captureWarnings(True)
    pywarn = logging.getLogger("py.warnings")
    pywarn.addHandler(handler)
    with contextlib.redirect_stdout(tee), contextlib.redirect_stderr(err):
        mod = None
        t0 = time.perf_counter()
        try:
            if name == "engine":
                who = "observers.reproduce._engine_demo"
                paths = reproduce_figures(ENGINE_FIGURES, d,
                                          progress=lambda f: step(f"{name}: {f}"))
            else:
                mod = importlib.import_module(f"observers.{name}")
                who = f"observers.{name}.reproduce"
                figures = getattr(mod, "FIGURES", None)
                if isinstance(figures, (list, tuple)) and figures and all(
                        isinstance(f, Figure) for f in figures):
                    paths = reproduce_figures(figures, d,
                                              progress=lambda f: step(f"{name}: {f}"))
                else:
                    paths = mod.reproduce(d)
            part.figures, part.problems = _figure_paths(paths, d, out, who)
            tee.copy.write(f"[{name}] {len(part.figures)} figure(s) in "
                           f"{time.perf_counter() - t0:.1f} s\n")
        except Exception:  # noqa: BLE001 - report and go on with the other parts
            part.status, part.error = "failed", traceback.format_exc()
            tee.copy.write(part.error)
            echo(f"[{name}] FAILED while making its figures:\n{part.error.rstrip()}")
        part.seconds = time.perf_counter() - t0
        if mod is not None:
            meta = paper_metadata(mod)
            part.paper, part.errata, part.decisions = (meta["paper"], meta["errata"],
                                                       meta["decisions"])
            nr = getattr(mod, "NOT_REPRODUCED", None)
            part.not_reproduced = dict(nr) if isinstance(nr, dict) else {}
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
                    results = []
                    for c in registry:
                        r = evaluate(c)
                        results.append(r)
                        tee.copy.write(r.line() + "\n")
                        if not r.passed:
                            echo(f"[{name}]{r.line()}")
                        step(f"{name}: {c.id}")
                    part.claims = [r.row() for r in results]
                except (TypeError, ValueError) as exc:
                    part.claims_note = f"observers.{name}.CLAIMS is invalid: {exc}"
                    part.status = "failed"
                    part.error += f"observers.{name}.CLAIMS is invalid: {exc}\n"
                    echo(f"[{name}] {part.claims_note}")
                part.claims_seconds = time.perf_counter() - t1
        elif name != "engine":
            part.claims_note = f"observers.{name} could not be imported"
    logger.removeHandler(handler)
    pywarn.removeHandler(handler)
    logger.setLevel(logger_level)
    logging.getLogger().setLevel(level)
    logging.captureWarnings(False)
    part.log = tee.copy.getvalue()
    part.save(out)
    echo(_summary_line(part))
    return part


def _summary_line(part: Part) -> str:
    """The part's one terminal line: figures, claims by outcome, time."""
    what = [f"{len(part.figures)} figure(s)"]
    if part.claims is not None:
        c = part.counts
        what.append(f"{c['total']} claim(s): {c['reproduced']} reproduced, {c['differs']} "
                    "differ as documented" if not c["failed"] else
                    f"{c['total']} claim(s), {c['failed']} NOT as expected")
    elif part.claims_note and part.name != "engine":
        what.append(part.claims_note)
    status = "ok" if part.status == "ok" else "FAILED"
    return (f"{status:<6} {part.name:<14} " + "; ".join(what)
            + f"  ({part.seconds + part.claims_seconds:.1f} s)")


def run_falsification(name: str, out, *, scale: float = 1.0, seed: int = 0,
                      expect: str | None = None, echo=None) -> list[dict]:
    """Search every problem of a paper package's ``PROBLEMS`` and record them.

    Each :class:`observers.falsification.Problem` is searched and sampled at
    random with the same budget (:func:`observers.falsification.run_problem`);
    the rows go to ``out/<name>/falsification.json`` (read by the report),
    and each counterexample's worst run is drawn as
    ``out/<name>/falsify_<id>.png`` with a caption.

    Parameters
    ----------
    name : str
        A paper package's name.
    out : str or pathlib.Path
        The output folder (the main job's).
    scale : float
        Multiplies every budget (the expected outcomes hold at 1).
    seed : int
        Seeds every search.
    expect : {"counterexample", "none"}, optional
        Only the problems expecting this outcome (the main job searches the
        statements expected to fail, which stop at their first
        counterexample; ``python -m observers falsify`` runs all).
    echo : callable, optional
        Gets one line per problem (default ``print``).

    Returns
    -------
    list of dict
        One row per problem (:meth:`observers.falsification.ProblemResult.row`),
        with ``figure`` (relative path or None) and ``error`` (a traceback
        when the search itself failed).
    """
    import json

    from ._common import save_figure
    from .falsification import draw_worst, run_problem, validate_problems
    echo = print if echo is None else echo
    mod = importlib.import_module(f"observers.{name}")
    d = pathlib.Path(out) / name
    d.mkdir(parents=True, exist_ok=True)
    rows = []
    for prob in validate_problems(getattr(mod, "PROBLEMS", []) or []):
        if expect is not None and prob.expect != expect:
            continue
        try:
            res = run_problem(prob, seed=seed, scale=scale)
        except Exception:  # noqa: BLE001 - one broken problem does not stop the others
            rows.append({"id": prob.id, "where": prob.where, "statement": prob.statement,
                         "expect": prob.expect, "passed": False, "error":
                         traceback.format_exc(), "figure": None})
            echo(f"  ERROR  {prob.id}")
            continue
        row = res.row()
        row["figure"], row["error"] = None, ""
        if res.found == "counterexample" and res.search.arc is not None:
            fig = draw_worst(res)
            png = save_figure(fig, d, f"falsify_{prob.id}", (
                f"{prob.id} ({prob.where}): {prob.statement} Counterexample found by "
                f"{res.search.found_by} (the search ran {_runs(res.search.evaluations)}): "
                f"margin {res.margin:.4g} at {res.search.point}; random sampling of the "
                f"same budget: margin {res.baseline.margin:.4g} after "
                f"{_runs(res.baseline.evaluations)}. Left: the worst margin so far "
                "against the number of runs, for the search (circles) and random sampling "
                "of the same budget (squares); below 0 the statement is violated. Right: "
                "where the worst run lies in the space, each coordinate scaled to its bounds "
                "(0 the lower, 1 the upper), entries named above."))
            row["figure"] = png.relative_to(pathlib.Path(out)).as_posix()
        rows.append(row)
        mark = "as expected" if res.passed else "NOT AS EXPECTED"
        echo(f"  {mark:<16} {prob.id:<34} {res.found}: margin {res.margin:.4g} "
             f"(random: {res.baseline.margin:.4g}), {_runs(res.search.evaluations)}, "
             f"{res.search.seconds:.1f} s")
    (d / "falsification.json").write_text(json.dumps(rows, indent=1, default=str),
                                         encoding="utf-8")
    return rows


def _one_of(names):
    """An argparse ``type`` accepting one of ``names`` (argparse's ``choices``
    with ``nargs="*"`` would list an empty choice in ``--help``)."""
    names = list(names)

    def check(value):
        if value not in names:
            raise argparse.ArgumentTypeError(
                f"invalid choice: {value!r} (choose from {', '.join(names)})")
        return value

    check.__name__ = "name"
    return check


def main(argv=None):
    """The command line: ``reproduce [NAME ...] [--out DIR] [--no-claims]``, ``falsify``,
    ``report``."""
    p = argparse.ArgumentParser(prog="python -m observers",
                                description="Reproduce the papers' results and figures.")
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("reproduce", help="regenerate figures, claims and the report")
    r.add_argument("names", nargs="*", type=_one_of(PAPERS), default=[], metavar="NAME",
                   help=f"which parts to run: {', '.join(PAPERS)} (default: all)")
    r.add_argument("--out", default="results", help="output folder (default: results)")
    r.add_argument("--no-claims", action="store_true",
                   help="do not evaluate the papers' claims")
    r.add_argument("--verbose", "-v", action="store_true",
                   help="also print every part's log and every claim's line")
    r.add_argument("--no-falsify", action="store_true",
                   help="do not search the statements expected to fail (the papers' "
                        "errata, found by falsification)")
    fal = sub.add_parser("falsify", help="search the papers' theorems for counterexamples "
                                         "(each package's PROBLEMS) and add them to the report")
    fal.add_argument("names", nargs="*", type=_one_of(PAPER_MODULES), default=[],
                     metavar="NAME",
                     help=f"which papers: {', '.join(PAPER_MODULES)} (default: all)")
    fal.add_argument("--out", default="results", help="output folder (default: results)")
    fal.add_argument("--scale", type=float, default=1.0,
                     help="multiply every budget (default 1: the pinned outcomes)")
    fal.add_argument("--seed", type=int, default=0, help="seed of every search (default 0)")
    rep = sub.add_parser("report", help="rewrite index.html and claims.csv from the parts "
                                        "recorded in the output folder")
    rep.add_argument("--out", default="results", help="output folder (default: results)")
    args = p.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")                   # the command line draws into files only
    out = pathlib.Path(args.out)
    command = "python -m observers " + " ".join(sys.argv[1:] if argv is None else argv)
    if args.cmd == "report":
        if not out.is_dir():
            print(f"--out {str(out)!r} is not a folder", file=sys.stderr)
            return 2
        page = write_report(out, command=command)
        print(f"report: {page.resolve()}")
        return 0
    if args.cmd == "falsify":
        if not args.scale > 0:
            print(f"--scale must be > 0, got {args.scale}", file=sys.stderr)
            return 2
        off = []
        for name in dict.fromkeys(args.names or PAPER_MODULES):
            print(f"[{name}] falsification problems")
            rows = run_falsification(name, out, scale=args.scale, seed=args.seed)
            off += [r["id"] for r in rows if not r["passed"]]
        if not any((out / n / "part.json").is_file() for n in PAPERS):
            print("(no parts recorded in this folder yet: run `reproduce` into it for the "
                  "full report)")
        page = write_report(out, command=command)
        print(f"report: {page.resolve()}")
        if off:
            print(f"problems not as expected: {', '.join(off)}", file=sys.stderr)
            return 1
        return 0
    names = list(dict.fromkeys(args.names or PAPERS))
    t0 = time.perf_counter()
    bar = _Progress(sum(_steps(n) for n in names))
    failed, off = [], []
    try:
        for name in names:
            part = run_part(name, out, claims=not args.no_claims, progress=bar.step,
                            echo=bar.write)
            if args.verbose and part.log.strip():
                bar.write(part.log.rstrip())
            if part.status != "ok":
                failed.append(name)
            off += [row["id"] for row in part.claims or [] if not row["passed"]]
            if name in PAPER_MODULES and part.status == "ok" and not args.no_falsify:
                t1 = time.perf_counter()
                rows = run_falsification(name, out, expect="counterexample",
                                         echo=bar.write if args.verbose else lambda line: None)
                bad = [r["id"] for r in rows if not r["passed"]]
                off += bad
                if rows:
                    bar.write(f"{'ok' if not bad else 'FAILED':<6} {name:<14} {len(rows)} "
                              f"erratum search(es): {len(rows) - len(bad)} found as expected"
                              f"  ({time.perf_counter() - t1:.1f} s)")
    finally:
        bar.close()
    page = write_report(out, command=command)
    print(f"claims: {(out / 'claims.csv').resolve()}")
    print(f"report: {page.resolve()}  (open it first)")
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    if off:
        print(f"claims not as expected: {', '.join(off)}", file=sys.stderr)
    if failed or off:
        return 1
    print(f"all results in {out.resolve()} ({time.perf_counter() - t0:.0f} s)")
    return 0
