"""The papers' theorems as falsification problems: ``python -m observers falsify``.

A :class:`Problem` is a quantified statement of a paper turned into a search:
its hypotheses as a :class:`hybridsim.falsification.Space` (initial states,
disturbances in their class, sampling gaps, delays), its conclusion as a
margin of the run (positive: holds; negative: violated), a run from a point
of the space, a budget, and what we expect the search to find: a
``"counterexample"`` (the statement as printed is wrong: an erratum this
project documents) or ``"none"`` (the corrected statement, or one the paper
gets right, survives the budget). Each paper package lists its problems in
``PROBLEMS`` (``observers/<name>/falsification.py``).

:func:`run_problem` searches (scipy differential evolution over whole
populations, :func:`hybridsim.falsify`) and runs the random-sampling
baseline with the same budget and seed, so each result says whether the
search beat chance. ``python -m observers falsify [NAME ...] [--out DIR]``
runs every problem, writes ``DIR/<name>/falsification.json`` and a figure of
each counterexample's worst run, and the report (``index.html``) shows them.

Examples
--------
>>> import hybridsim as hs
>>> from hybridsim.falsification import Space, Interval
>>> from hybridsim.library import Timer
>>> from observers.falsification import Problem, run_problem
>>> p = Problem(id="999-timer-by-1.1", paper="999", where="(1)",
...             statement="The timer's first reset comes by t = 1.1.",
...             space=Space(period=Interval(0.9, 1.2)),
...             run=lambda pt: hs.simulate(Timer(pt["period"]), [0.0], t_max=2, j_max=1),
...             margin=lambda arc: 1.1 - arc.jump_times[0], budget=100,
...             expect="counterexample", reason="periods above 1.1 are allowed")
>>> r = run_problem(p, seed=0)
>>> r.found, r.passed, round(r.margin, 3)
('counterexample', True, -0.1)
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

import hybridsim as hs
from hybridsim.falsification import Space

__all__ = ["EXPECT", "Problem", "ProblemResult", "run_problem", "validate_problems",
           "draw_worst"]

#: What a search is expected to find.
EXPECT = ("counterexample", "none")


@dataclasses.dataclass(frozen=True)
class Problem:
    """One statement of a paper as a search for a counterexample.

    Parameters
    ----------
    id : str
        Unique, no whitespace: ``"<paper>-<where>-<what>"`` (as claims).
    paper, where, statement : str
        The paper's id, where it states it, and the statement searched, as
        the margin checks it (printed or corrected: say which).
    space : hybridsim.falsification.Space
        The hypotheses: what may vary, each entry bounded as the paper says.
    run : callable
        ``run(point) -> HybridArc``, or a population run (``run.batch =
        True``, :func:`hybridsim.falsification.batch_run`).
    margin : callable
        ``margin(arc) -> float``: positive when the statement holds on the
        run, negative when it is violated.
    budget : int
        Runs allowed to the search (and to the random baseline).
    expect : {"counterexample", "none"}
    reason : str
        Why: the erratum that makes it fail, or why it must hold.
    seconds : float
        Wall-time budget of each search (default unlimited).
    """

    id: str
    paper: str
    where: str
    statement: str
    space: Space
    run: Callable
    margin: Callable
    budget: int
    expect: str
    reason: str
    seconds: float = math.inf

    def __post_init__(self):
        for name in ("id", "paper", "where", "statement", "reason"):
            v = getattr(self, name)
            if not isinstance(v, str) or not v.strip():
                raise ValueError(f"Problem {self.id!r}: {name} must be a non-empty string")
        if any(ch.isspace() for ch in self.id):
            raise ValueError(f"Problem {self.id!r}: id must contain no whitespace")
        if not isinstance(self.space, Space):
            raise TypeError(f"Problem {self.id!r}: space must be a "
                            f"hybridsim.falsification.Space, got {type(self.space).__name__}")
        if not callable(self.run) or not callable(self.margin):
            raise TypeError(f"Problem {self.id!r}: run and margin must be callable")
        if isinstance(self.budget, bool) or not isinstance(self.budget, int) or self.budget < 1:
            raise ValueError(f"Problem {self.id!r}: budget must be a positive int, "
                             f"got {self.budget!r}")
        if self.expect not in EXPECT:
            raise ValueError(f"Problem {self.id!r}: expect must be one of {EXPECT}, "
                             f"got {self.expect!r}")


@dataclasses.dataclass(frozen=True)
class ProblemResult:
    """A problem searched, and the random baseline beside it.

    Attributes
    ----------
    problem : Problem
    search, baseline : hybridsim.falsification.FalsificationResult
        Differential evolution, and random sampling with the same budget.
    found : {"counterexample", "none"}
        What the search found.
    passed : bool
        ``found == problem.expect``, and the search's worst margin is no
        better than the baseline's (or both found a counterexample).
    """

    problem: Problem
    search: object
    baseline: object
    found: str
    passed: bool

    @property
    def margin(self) -> float:
        return self.search.margin

    def row(self) -> dict:
        """A JSON-able record (the report's row)."""
        p, s, b = self.problem, self.search, self.baseline
        return {"id": p.id, "paper": p.paper, "where": p.where, "statement": p.statement,
                "space": repr(p.space), "budget": p.budget, "expect": p.expect,
                "reason": p.reason, "found": self.found, "passed": self.passed,
                "margin": s.margin, "where_tj": list(s.where) if s.where else None,
                "point": repr(s.point), "evaluations": s.evaluations, "seconds": s.seconds,
                "found_by": s.found_by, "baseline_found_by": b.found_by,
                "findings": [f"{f.cause}: {f.message}" for f in s.findings[:5]],
                "baseline_margin": b.margin, "baseline_evaluations": b.evaluations,
                "baseline_seconds": b.seconds}


def validate_problems(problems, *, paper=None):
    """A list of :class:`Problem` with unique ids (of ``paper`` when given)."""
    out, seen = [], set()
    for k, p in enumerate(problems):
        if not isinstance(p, Problem):
            raise TypeError(f"problems[{k}] must be an observers.falsification.Problem, "
                            f"got {type(p).__name__}")
        if p.id in seen:
            raise ValueError(f"duplicate problem id {p.id!r}")
        if paper is not None and p.paper != paper:
            raise ValueError(f"problems[{k}] ({p.id!r}) belongs to paper {p.paper!r}, "
                             f"not {paper!r}")
        seen.add(p.id)
        out.append(p)
    return out


def run_problem(problem: Problem, *, seed: int = 0, scale: float = 1.0,
                progress: bool | None = False) -> ProblemResult:
    """Search one problem, then sample it at random with the same budget.

    Parameters
    ----------
    problem : Problem
    seed : int
        Seeds both searches.
    scale : float
        Multiplies the budget (e.g. 0.1 for a quick look; the expected
        outcomes are pinned at 1).
    progress : bool, optional
        Progress bars.

    Returns
    -------
    ProblemResult
    """
    budget = max(1, round(problem.budget * scale))
    kw = dict(budget=budget, seed=seed, seconds=problem.seconds, progress=progress,
              stop=problem.expect == "counterexample")
    search = hs.falsify(problem.run, problem.space, problem.margin, **kw)
    baseline = hs.falsify(problem.run, problem.space, problem.margin, method="random", **kw)
    found = "counterexample" if search.verdict == "counterexample" else "none"
    as_bad = (search.margin <= baseline.margin or
              (search.margin < 0 and baseline.margin < 0))
    return ProblemResult(problem, search, baseline, found,
                         found == problem.expect and as_bad)


def _margin_series(result):
    """``(t, j, value, what)``: the claim's margin at each sample of the worst
    run, where the problem's margin keeps it
    (:attr:`hybridsim.testing.Margin.series`), and what it measures; else None."""
    arc = getattr(result.search, "arc", None)
    if arc is None:
        return None
    try:
        m = result.problem.margin(arc)
    except Exception:  # noqa: BLE001 - a figure never fails on a margin that cannot be redrawn
        return None
    series = getattr(m, "series", None)
    return None if series is None else (*series, getattr(m, "what", ""))


def _draw_series(ax, series, result):
    """The worst run itself: its margin at each sample, a line per flow (jumps
    as gaps), the deciding sample marked."""
    t, j, v = (np.asarray(a) for a in series[:3])
    what = series[3]
    finite = np.isfinite(v)
    for jj in np.unique(j):
        sel = (j == jj) & finite
        ax.plot(t[sel], v[sel], ".-", color="C0", lw=1.2, ms=2.5,
                label="margin at each sample of the worst run" if jj == j[0] else None)
    ax.axhline(0.0, color="0.4", lw=0.8)
    big = np.abs(v[finite])
    if big.size and big.max() > 1e3 * max(float(np.median(big)), 1e-12):
        ax.set_yscale("symlog", linthresh=1.0)      # margins spanning decades
    where = result.search.where
    if where is not None:
        k = np.flatnonzero((t == where[0]) & (j == where[1]))
        if k.size:
            ax.plot(t[k[0]], v[k[0]], "o", color="C3", ms=6,
                    label=f"deciding sample (t = {where[0]:.4g}, j = {where[1]})")
    ax.set_xlabel("t (s), jumps as gaps between the flows")
    ax.set_ylabel("margin (< 0: violated)")
    ax.set_title(f"the worst run: the claim's margin at each sample{': ' + what if what else ''}",
                 fontsize=10)
    ax.legend(loc="best", fontsize=8)


def draw_worst(result: ProblemResult):
    """A figure of a search: the worst margin so far against the number of runs
    (the search and the random baseline), and where in the space the worst
    run lies (each coordinate scaled to its bounds: 0 the lower, 1 the upper;
    a counterexample on a face or a vertex shows as 0s and 1s); below, where
    the problem's margin keeps it (:attr:`hybridsim.testing.Margin.series`),
    the worst run itself: the claim's margin at each of its samples.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure
    series = _margin_series(result)
    fig = Figure(figsize=(11, 7.5 if series is not None else 4))
    if series is None:
        ax_h, ax_z = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 2]})
    else:
        grid = fig.add_gridspec(2, 2, width_ratios=[3, 2], height_ratios=[1, 1])
        ax_h, ax_z = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1])
        _draw_series(fig.add_subplot(grid[1, :]), series, result)
    for res, label, style in ((result.search, "differential evolution", "o-"),
                              (result.baseline, "random sampling", "s--")):
        h = np.minimum.accumulate(res.history)
        ax_h.plot(np.arange(1, h.size + 1), h, style, ms=3, label=label)
    ax_h.axhline(0.0, color="0.4", lw=0.8)
    ax_h.set_xlabel("runs")
    ax_h.set_ylabel("worst margin so far (< 0: counterexample)")
    ax_h.set_title(f"{result.problem.id}: margin {result.margin:.3g}"
                   + ("" if result.search.where is None else
                      f" at (t, j) = ({result.search.where[0]:.4g}, {result.search.where[1]})"))
    ax_h.legend()
    space, z = result.problem.space, result.search.point.z
    width = np.where(space.hi > space.lo, space.hi - space.lo, 1.0)
    u = (z - space.lo) / width
    ax_z.plot(np.arange(z.size), u, "o", ms=4, color="C3")
    k = 0
    for name, entry in space.entries.items():
        ax_z.axvspan(k - 0.5, k + entry.size - 0.5, color="0.93" if len(ax_z.patches) % 2
                     else "0.85", zorder=0)
        ax_z.text(k + entry.size / 2 - 0.5, 1.08, name, ha="center", fontsize=8)
        k += entry.size
    ax_z.set_ylim(-0.1, 1.18)
    ax_z.set_xlim(-0.5, z.size - 0.5)
    ax_z.set_xlabel("coordinate of the space")
    ax_z.set_ylabel("worst point, scaled to its bounds")
    fig.tight_layout()
    return fig
