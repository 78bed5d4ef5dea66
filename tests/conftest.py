"""Fixtures shared by every test folder.

``path``: a test that takes an argument named ``path`` runs once on each
integration path (``"python"``, ``"vectorized"``, ``"compiled"``; the
compiled one skipped without numba). The marker ``@pytest.mark.paths(...)``
narrows it: ``only=("vectorized", "compiled")`` keeps those paths,
``compiled_slow=True`` moves the compiled case to the slow suite,
``xfail_compiled="reason"`` marks it a strict expected failure for that
reason (a known gap of the compiled path, named). The cases
the paths run are built by :mod:`paths` (this folder), one definition per
case.

``repo``: the repository's root folder (a :class:`pathlib.Path`), for tests
that read the README, the docs, the examples or the package's source.

Budget: every test of the default suite takes at most 2 s on an idle core
(longer ones are marked ``slow``). Wall times swing with the machine's load,
so the session also prints the tests that took the most CPU time of their
own process (setup, call and teardown, every thread; a process pool's
workers not counted), the figure the budget is checked by, whatever else
runs; ``HYBRIDSIM_TEST_CPU=file.json`` writes every test's figure. It
also prints each test process's peak resident memory (budget 600 MB per
pytest-xdist worker); ``HYBRIDSIM_TEST_RSS=file.json`` writes each
process's peak after every test phase, in order, to find what raises it.

The tests that solve LMIs (:data:`LMI_FILES`) run on one pytest-xdist
worker (:func:`pytest_xdist_make_scheduler`): importing cvxpy and its solvers costs a
process about 70 MB, paid once rather than by every worker. The summary
names the processes that imported cvxpy, and the first test outside the
group that did (a file to add to the group).

On several workers the engine's cached kernels are first compiled (or found)
in throwaway processes, one per job of :data:`warm_kernels.JOBS` (this
folder), as many at once as there are cores, the tests of
:data:`warm_kernels.COMPILING` among them: a worker
that loads a kernel from numba's disk cache keeps a few MB of it, one that
compiles it keeps 70-175 MB.
"""
from __future__ import annotations

import json
import os
import pathlib
import resource
import sys
import time

import pytest
from paths import HAS_NUMBA, NO_NUMBA, PATHS

ROOT = pathlib.Path(__file__).resolve().parent.parent


def _two_malloc_arenas():
    """glibc's malloc at most two arenas in this process (``M_ARENA_MAX``, as
    ``MALLOC_ARENA_MAX=2``): it gives each thread that allocates an arena of
    its own, up to 8 a core, and keeps what is freed in it, so the compiled
    batches' threads held about 40 MB of a test process each run."""
    import ctypes
    import ctypes.util
    name = ctypes.util.find_library("c")
    if sys.platform.startswith("linux") and name:
        try:
            ctypes.CDLL(name).mallopt(-8, 2)         # M_ARENA_MAX
        except (OSError, AttributeError):             # not glibc
            pass


def pytest_configure(config):
    _two_malloc_arenas()
    config.addinivalue_line(
        "markers", "paths(only=None, compiled_slow=False, xfail_compiled=None): the "
        "integration paths a test taking `path` runs on (default: all three)")


def pytest_generate_tests(metafunc):
    if "path" not in metafunc.fixturenames:
        return
    if any(m.name == "parametrize" and "path" in m.args[0].replace(" ", "").split(",")
           for m in metafunc.definition.iter_markers()):
        return                                         # the test names its own paths
    marker = metafunc.definition.get_closest_marker("paths")
    kw = marker.kwargs if marker is not None else {}
    unknown = set(kw) - {"only", "compiled_slow", "xfail_compiled"}
    if unknown:
        raise pytest.UsageError(f"@pytest.mark.paths: unknown argument(s) {sorted(unknown)}; "
                                "expected only=, compiled_slow=, xfail_compiled=")
    only = kw.get("only") or PATHS
    bad = set(only) - set(PATHS)
    if bad:
        raise pytest.UsageError(f"@pytest.mark.paths(only=...): {sorted(bad)} is not a path; "
                                f"expected some of {PATHS}")
    params = []
    for p in PATHS:
        if p not in only:
            continue
        marks = []
        if p == "compiled":
            marks.append(pytest.mark.skipif(not HAS_NUMBA, reason=NO_NUMBA))
            if kw.get("compiled_slow"):
                marks.append(pytest.mark.slow)
            if kw.get("xfail_compiled"):
                marks.append(pytest.mark.xfail(strict=True, reason=kw["xfail_compiled"]))
        params.append(pytest.param(p, id=p, marks=marks))
    metafunc.parametrize("path", params)


#: the files whose tests (or doctests) solve LMIs with cvxpy: one xdist group
LMI_FILES = ("tests/papers/test_lmi.py", "tests/papers/test_claims.py",
             "tests/papers/distributed/test_distributed.py",
             "tests/papers/dynamic_gain/test_dynamic_gain.py",
             "tests/papers/dynamic_gain/test_dynamic_gain_falsification.py",
             "observers/distributed/__init__.py")


def pytest_xdist_make_scheduler(config, log):
    """pytest-xdist's ``load`` scheduling, with the tests of :data:`LMI_FILES` one
    unit of work (pytest-xdist's own ``xdist_group`` marks name their group in
    the test's id, which pytest 9 no longer lets a plugin change)."""
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class LoadWithLMIGroup(LoadScopeScheduling):
        def _split_scope(self, nodeid):
            return "lmi" if nodeid.split("::", 1)[0] in LMI_FILES else nodeid
    return LoadWithLMIGroup(config, log)


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session):
    # in pytest-xdist's controller, before it starts the workers
    config = session.config
    if not HAS_NUMBA or hasattr(config, "workerinput") \
            or config.pluginmanager.getplugin("dsession") is None:
        return
    import warm_kernels

    import hybridsim
    # the hybridsim the workers import (this checkout's, or the installed one)
    where = str(pathlib.Path(hybridsim.__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (where, os.environ.get("PYTHONPATH")) if p)}
    for name in ("HYBRIDSIM_TEST_CPU", "HYBRIDSIM_TEST_RSS"):    # the workers' figures only
        env.pop(name, None)
    slots = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
        else os.cpu_count() or 1
    start = time.monotonic()
    _WARMED.update(warm_kernels.run_jobs(env, slots))
    _WARMED["all"] = time.monotonic() - start


@pytest.fixture(scope="session")
def repo() -> pathlib.Path:
    """The repository's root folder."""
    return ROOT


_CPU = {}
_WARMED = {}           # the warming jobs' wall seconds, and all of them's ("all")
_RSS = {}              # peak resident memory (MB) of each process that ran tests
_RSS_LOG = []
_CVXPY = {}            # worker -> (the first test after which cvxpy was loaded, grouped)
_CVXPY_SEEN = []       # in a test process: that test
CPU_BUDGET = 2.0       # seconds of CPU per default-suite test
RSS_BUDGET = 600       # MB of peak resident memory per test process
_PHASE_CPU = pytest.StashKey[float]()


def _timed(item):
    start = time.process_time()
    yield
    item.stash[_PHASE_CPU] = time.process_time() - start


pytest_runtest_setup = pytest.hookimpl(hookwrapper=True)(_timed)
pytest_runtest_call = pytest.hookimpl(hookwrapper=True)(_timed)
pytest_runtest_teardown = pytest.hookimpl(hookwrapper=True)(_timed)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()       # its own list: the item's would add up the phases
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024   # KB on Linux
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    report.user_properties = [*report.user_properties, ("cpu", item.stash.get(_PHASE_CPU, 0.0)),
                              ("rss", (worker, rss))]
    if "cvxpy" in sys.modules and not _CVXPY_SEEN:
        _CVXPY_SEEN.append(item.nodeid)         # the first test after which it is loaded
        report.user_properties.append(("cvxpy", (worker, item.nodeid,
                                                 item.nodeid.split("::", 1)[0] in LMI_FILES)))
    item.stash[_PHASE_CPU] = 0.0


def pytest_runtest_logreport(report):
    # in the process that reports (pytest-xdist's controller included)
    cpu = sum(v for k, v in report.user_properties if k == "cpu")
    _CPU[report.nodeid] = _CPU.get(report.nodeid, 0.0) + cpu
    for worker, nodeid, grouped in (v for k, v in report.user_properties if k == "cvxpy"):
        _CVXPY.setdefault(worker, (nodeid, grouped))
    for worker, rss in (v for k, v in report.user_properties if k == "rss"):
        _RSS[worker] = max(_RSS.get(worker, 0.0), rss)
        if os.environ.get("HYBRIDSIM_TEST_RSS"):
            _RSS_LOG.append((worker, report.nodeid, report.when, rss))


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    tr = terminalreporter
    if _WARMED:
        jobs = ", ".join(f"{n} {s:.1f}" for n, s in _WARMED.items() if n != "all")
        tr.write_line(f"warming processes (the engine's kernels compiled or found): "
                      f"{_WARMED['all']:.1f} s of wall before the tests ({jobs} s each)")
    if not _CPU:
        return
    worst = sorted(_CPU.items(), key=lambda kv: -kv[1])[:15]
    tr.section(f"most CPU time per test (budget {CPU_BUDGET:g} s outside the slow suite)")
    for nodeid, cpu in worst:
        tr.write_line(f"{cpu:7.2f}s cpu  {nodeid}")
    if _RSS:
        peaks = ", ".join(f"{w} {mb:.0f} MB" for w, mb in sorted(_RSS.items()))
        tr.write_line(f"peak memory per test process (budget {RSS_BUDGET} MB): {peaks}")
    if _CVXPY:
        tr.write_line("cvxpy imported by: " + ", ".join(sorted(_CVXPY)) + "".join(
            f"; outside the lmi group first by {n} (add its file to LMI_FILES)"
            for w, (n, grouped) in sorted(_CVXPY.items()) if not grouped))
    out = os.environ.get("HYBRIDSIM_TEST_CPU")
    if out:                                   # every test's figure, for the budget's review
        with open(out, "w", encoding="utf-8") as fh:
            json.dump(_CPU, fh, indent=0, sort_keys=True)
    out = os.environ.get("HYBRIDSIM_TEST_RSS")
    if out:                                   # each process's peak after each phase, in order
        with open(out, "w", encoding="utf-8") as fh:
            json.dump(_RSS_LOG, fh, indent=0)
