"""The ARCH-COMP falsification runner and its validator.

``python -m hybridsim.arch --out DIR [--quick] [--trials 10] [--only AT1,CC1]
[--method cmaes] [--baseline random]`` attempts every requirement on both
instances, ``trials`` seeded searches each (:func:`hybridsim.falsify`, by
default CMA-ES over the instance's space, every population one compiled
batch where numba is installed) within the competition's budget of 1,500
simulations, and, with ``--baseline``, as many trials of a second method
(``random``: uniform sampling of the same space, the baseline), and writes

* ``DIR/trials.csv``: the competition's per-trial format (system, property,
  instance, method, seed, simulations, time, robustness, falsified, input),
  the input the search ended on in the competition's ``[t a b; ...]`` rows;
* ``DIR/summary.csv``: per requirement, instance and method, trials,
  falsified, mean_simulations and median_simulations (over the falsified
  trials, the competition's convention), median_seconds_per_trial (over
  all), and published_mean_simulations (:data:`PUBLISHED`).

``python -m hybridsim.arch validate DIR`` simulates every falsifying input of
``DIR/trials.csv`` again, on the Python path (:func:`hybridsim.simulate`),
and confirms that its robustness is negative.
"""
from __future__ import annotations

import argparse
import csv
import logging
import os
import statistics
import sys
import time

import numpy as np

from ..compiled import available
from ..falsification import falsify
from ..run import simulate
from .requirements import REQUIREMENTS
from .spaces import INSTANCES, MODELS, f16_state, input_matrix, model, parse_input, problem

__all__ = ["run", "validate", "main", "BUDGET", "QUICK", "PUBLISHED"]

_LOG = logging.getLogger("hybridsim.arch")
#: the competition's budget of simulations per trial
BUDGET = 1500
#: what ``--quick`` attempts (two trials each)
QUICK = ("AT1", "AT2", "AT54", "AT6a", "CC1", "CC2", "CC3")
#: the best published mean number of simulations to falsify (every tool reaching
#: 10/10, either instance; FalCAuN's 2023-2026 result files, as issue 43 quotes
#: them; F16: MoonLight 2024, 10/10 in 21.0), the figure each mean is held against
PUBLISHED = {"AT1": 448, "AT2": 128, "AT6a": 458, "AT6b": 600, "AT6c": 449,
             "AT6abc": 616, "CC1": 198, "CC2": 38, "CC3": 61, "CC4": 474, "F16": 21}
METHODS = ("cmaes", "de", "random")
TRIAL_COLUMNS = ("system", "property", "instance", "method", "seed", "simulations", "time",
                 "robustness", "falsified", "input")
SUMMARY_COLUMNS = ("requirement", "instance", "method", "trials", "falsified",
                   "mean_simulations", "median_simulations", "median_seconds_per_trial",
                   "published_mean_simulations")


def _names(only):
    if only is None:
        return list(REQUIREMENTS)
    names = [n.strip() for n in (only.split(",") if isinstance(only, str) else only)
             if n.strip()]
    bad = [n for n in names if n not in REQUIREMENTS]
    if bad or not names:
        raise ValueError(f"only: unknown requirements {bad or names}; have "
                         f"{', '.join(REQUIREMENTS)}")
    return names


def run(out, *, trials=10, only=None, instances=(1, 2), budget=BUDGET, quick=False,
        backend="auto", log=None, method="cmaes", baseline=None, specialize=True):
    """Run the benchmarks and write ``out/trials.csv`` and ``out/summary.csv``.

    Parameters
    ----------
    out : str or path
        The folder (created).
    trials : int
        Seeded searches per requirement and instance (seeds 0, 1, ...).
    only : str or list of str, optional
        Requirements to attempt (default every one; with ``quick``,
        :data:`QUICK`).
    instances : iterable of int
    budget : int
        Simulations per trial.
    quick : bool
        :data:`QUICK` only (``only`` still wins where given).
    backend : {"auto", "compiled", "python"}
        How each population runs (:func:`hybridsim.falsification.batch_run`);
        the models' maps are compiled before the first trial, so the trials'
        times are the searches'.
    log : callable, optional
        Where each trial's line goes (default the ``hybridsim.arch`` logger).
    method : {"cmaes", "de", "random"}
        The search (:func:`hybridsim.falsify`'s ``method``).
    baseline : {"random", "de", "cmaes"}, optional
        A second method run on the same trials' seeds, its rows beside the
        search's (``"random"``: the random-sampling baseline).
    specialize : bool
        Run the compiled populations on a kernel specialised on each model's
        maps (:class:`hybridsim.compiled.CompiledSystem`'s ``specialize``:
        compiled once per machine, 10-15 s each, cached on disk; then CC's
        simulations take about a fifth less CPU), before the first trial.

    Returns
    -------
    list of dict
        The summary rows.
    """
    names = _names(QUICK if quick and only is None else only)
    methods = [method] + ([baseline] if baseline is not None and baseline != method else [])
    bad = [m for m in methods if m not in METHODS]
    if bad:
        raise ValueError(f"method and baseline must be among {METHODS}, got {bad}")
    log = log or _LOG.info
    os.makedirs(out, exist_ok=True)
    rows, summary = [], []
    for name in names:
        req = REQUIREMENTS[name]
        for inst in instances:
            if (req.system, inst) not in INSTANCES:
                continue                # F16 has one instance
            run_, sp, claim, _ = problem(name, inst, backend=backend)
            m = model(req.system, inst)
            if backend != "python" and available():
                m.specialize = specialize
            if backend != "python" and available() and m._nb is None:
                log(f"compiling the {req.system} model's maps (instance {inst}): "
                    f"{m.compile():.1f} s")
            for meth in methods:
                summary.append(_trials(run_, sp, claim, req, inst, meth, trials, budget,
                                       rows, log))
            # written after each requirement and instance: a long run's tables so far
            _write(os.path.join(out, "trials.csv"), TRIAL_COLUMNS, rows)
            _write(os.path.join(out, "summary.csv"), SUMMARY_COLUMNS, summary)
    return summary


def _trials(run_, sp, claim, req, inst, method, trials, budget, rows, log):
    """``trials`` seeded searches of one requirement and instance by ``method``:
    their rows appended to ``rows``, the summary row returned."""
    sims, secs, done = [], [], 0
    for seed in range(trials):
        res = falsify(run_, sp, claim, budget=budget, seed=seed, method=method,
                      progress=False)
        hit = res.verdict == "counterexample"
        done += hit
        secs.append(res.seconds)
        if hit:
            sims.append(res.evaluations)
        rows.append({"system": req.system, "property": req.name, "instance": inst,
                     "method": method, "seed": seed, "simulations": res.evaluations,
                     "time": f"{res.seconds:.3f}", "robustness": repr(res.margin),
                     "falsified": "yes" if hit else "no",
                     "input": input_matrix(res.point)})
        log(f"{req.name} instance {inst} {method} seed {seed}: "
            f"{'falsified' if hit else 'not falsified'} after {res.evaluations} "
            f"simulations, robustness {res.margin:.4g}, {res.seconds:.1f} s")
    return {"requirement": req.name, "instance": inst, "method": method, "trials": trials,
            "falsified": done,
            "mean_simulations": f"{statistics.fmean(sims):.1f}" if sims else "",
            "median_simulations": f"{statistics.median(sims):g}" if sims else "",
            "median_seconds_per_trial": f"{statistics.median(secs):.2f}",
            "published_mean_simulations": PUBLISHED.get(req.name, "")}


def _write(path, columns, rows):
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=columns)
        w.writeheader()
        w.writerows(rows)


def robustness_of(name, times, values, interpolation, **simulate_kwargs):
    """Requirement ``name``'s robustness on its model driven by these inputs.

    ``times`` (k,) and ``values`` (k, 2): the control points (throttle,
    brake), held (``"previous"``) or linear between them; one run of the
    Python path, as long as the requirement's horizon.

    Examples
    --------
    >>> float(robustness_of("AT1", [0.0], [[100.0, 0.0]], "previous")) < 0
    True
    """
    req = REQUIREMENTS[name]
    if req.system == "F16":             # values: the initial (roll, pitch, yaw)
        m = model("F16", 1)
        x0 = f16_state(m, *np.asarray(values, dtype=float).ravel())
    else:
        m = MODELS[req.system](times=times, interpolation=interpolation)
        values = np.asarray(values, dtype=float)
        x0 = m.set_inputs(values[:, 0], values[:, 1]).initial_state()
    arc = simulate(m, x0, t_max=req.horizon, **simulate_kwargs)
    return req(arc)


def validate(folder, log=None):
    """Simulate every falsifying input of ``folder/trials.csv`` again.

    ``log``: where each input's line goes (default the ``hybridsim.arch`` logger).

    Returns
    -------
    list of dict
        One per falsified trial: property, instance, seed, the robustness
        recorded and the one found again, and ``ok`` (negative again).
    """
    log = log or _LOG.info
    path = os.path.join(folder, "trials.csv")
    if not os.path.exists(path):
        raise FileNotFoundError(f"validate: no trials.csv in {folder!r} (run "
                                f"python -m hybridsim.arch --out {folder} first)")
    out = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            if r["falsified"] != "yes":
                continue
            inst = int(r["instance"])
            interp = INSTANCES[(r["system"], inst)][2]
            if r["system"] == "F16":
                times, values = None, [float(v) for v in r["input"].strip("[] ").split()]
            else:
                times, values = parse_input(r["input"])
            rob = float(robustness_of(r["property"], times, values, interp))
            ok = rob < 0
            out.append({"property": r["property"], "instance": inst, "seed": r["seed"],
                        "recorded": float(r["robustness"]), "again": rob, "ok": ok})
            log(f"{r['property']} instance {inst} seed {r['seed']}: robustness "
                f"{float(r['robustness']):.6g} recorded, {rob:.6g} again: "
                f"{'ok' if ok else 'NOT FALSIFIED'}")
    return out


def main(argv=None):
    """The command line (``python -m hybridsim.arch``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "validate":
        p = argparse.ArgumentParser(prog="python -m hybridsim.arch validate",
                                    description="re-simulate every falsifying input")
        p.add_argument("folder")
        a = p.parse_args(argv[1:])
        res = validate(a.folder, log=print)
        bad = [r for r in res if not r["ok"]]
        print(f"{len(res) - len(bad)} of {len(res)} falsifying inputs confirmed")
        return 1 if bad else 0
    p = argparse.ArgumentParser(prog="python -m hybridsim.arch",
                                description="the ARCH-COMP falsification benchmarks AT and CC")
    p.add_argument("--out", required=True, help="folder for summary.csv and trials.csv")
    p.add_argument("--quick", action="store_true",
                   help=f"two trials of {', '.join(QUICK)}")
    p.add_argument("--trials", type=int, default=None, help="trials per requirement (10)")
    p.add_argument("--only", default=None, help="comma-separated requirements, e.g. AT1,CC1")
    p.add_argument("--budget", type=int, default=BUDGET, help="simulations per trial (1500)")
    p.add_argument("--method", default="cmaes", choices=METHODS,
                   help="the search (default cmaes)")
    p.add_argument("--baseline", default=None, choices=METHODS,
                   help="a second method in the same tables, e.g. random")
    p.add_argument("--generic", action="store_true",
                   help="the engine's generic kernel (no kernel specialised on each model, "
                        "compiled once per machine)")
    a = p.parse_args(argv)
    trials = a.trials if a.trials is not None else (2 if a.quick else 10)
    if trials < 1:
        p.error(f"--trials must be >= 1, got {trials}")
    t0 = time.perf_counter()
    summary = run(a.out, trials=trials, only=a.only, budget=a.budget, quick=a.quick,
                  log=print, method=a.method, baseline=a.baseline, specialize=not a.generic)
    width = max(len(c) for c in SUMMARY_COLUMNS)
    print(" | ".join(c.ljust(min(width, 12)) for c in SUMMARY_COLUMNS))
    for s in summary:
        print(" | ".join(str(s[c]).ljust(min(width, 12)) for c in SUMMARY_COLUMNS))
    print(f"wrote {os.path.join(a.out, 'summary.csv')} and trials.csv in "
          f"{time.perf_counter() - t0:.0f} s")
    return 0
