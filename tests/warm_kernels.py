"""The engine's cached kernels compiled before the test processes start.

numba keeps what compiling a kernel took in the process that compiled it (70-100
MB for each run kernel, for the life of the process), while a process that
loads the same kernel from numba's disk cache takes a few MB. So when the suite
runs on several pytest-xdist workers, ``conftest.py`` first runs this module in
throwaway processes, one per job of :data:`JOBS` (``python warm_kernels.py
base``, ...), as many at once as the machine has cores (:func:`run_jobs`),
which compile the kernels whose signature is fixed (the maps passed by
address: the run kernels, the batch kernel, the SDE flow's) into the disk
cache, or find them there: every worker then loads them, and each kernel is
compiled once per machine rather than once per worker. A kernel already in
the cache costs the process about a second.

The maps of a model are compiled by the tests that run it, into the same
cache. Where models take long to compile or keep much of a process, the tests
of :data:`COMPILING` are run once here (the ``("tests", name)`` of
:data:`JOBS`; their compiled cases), their output discarded, so the workers
load what they compiled: on two cores, from an empty cache, this keeps each
worker under the suite's 600 MB, its time about the same (what the workers
no longer compile, the warming processes do).
"""
from __future__ import annotations

import sys

#: the warming jobs, each one throwaway process: ``name: (steps, after)``, the
#: steps run in order (``_cache.compile_kernels`` arguments; ``"sde"``: the SDE
#: flow's kernel, compiled by a run of one small SDE; ``"stl"``: the compiled
#: STL window, :mod:`hybridsim._stl_window_nb`, about 10 s; ``("tests", name)``:
#: the tests of ``COMPILING[name]``), started once every job of ``after`` has
#: ended, so they load those kernels rather than compile them again. The run
#: kernels share their compiled helpers through the disk cache: the first
#: kernel compiled pays for them (about 8 s), so ``base`` runs first, beside
#: ``sde``. Of the jobs ready to start, the first in this order starts
#: (:func:`run_jobs`): the longer chains first. CPU seconds from an empty
#: cache, measured alone: base 17, sde 20, delays 18, watch 13, 004 29,
#: paths 23, stochastic 19, events 12, stl 10, 002 9
JOBS = {
    "base": (({"batch": True},), ()),
    "sde": (("sde", {"batch": False, "method": "RK4"}), ()),
    "delays": (({"batch": False, "delays": True},
                {"batch": False, "delays": True, "method": "RK4"}), ("base",)),
    "watch": (({"batch": False, "watch": True}, {"batch": False, "method": "DOP853"}),
              ("base",)),
    "004": ((("tests", "004"),), ("base", "delays")),
    "paths": ((("tests", "paths"),), ("base", "delays", "watch", "sde")),
    "stochastic": ((("tests", "stochastic"),), ("base", "sde")),
    "events": ((("tests", "events"),), ("base", "watch")),
    "stl": (("stl",), ()),
    "002": ((("tests", "002"),), ("base",)),
}
assert all(set(after) <= set(JOBS) for _, after in JOBS.values())


#: tests (node ids, or files, under this folder) whose models take the most to
#: compile cold, in seconds or in memory (each map 1-2 MB and more of a process
#: for its life, a specialised kernel 70 MB: 330 MB of one process for the
#: first four groups' files): each group run once by a warming process, only
#: their cases on the compiled path (:func:`_CompiledOnly`)
COMPILING = {
    # 004's populations (the lowered plant and observer's maps, about 5-15 s each)
    "004": (
        "papers/gramian_delay/test_gramian_delay_falsification.py::"
        "test_population_run_matches_the_package_run",
        "papers/gramian_delay/test_gramian_delay_falsification.py::test_gaps_are_in_the_class",
        "papers/gramian_delay/test_gramian_delay_falsification.py::"
        "test_theorem1_rows_carry_their_own_disturbances",
        "papers/gramian_delay/test_every_gap.py::"
        "test_sequence_run_rows_sample_at_their_own_instants",
        "integration/test_source_unroll.py::"
        "test_sums_binary_ufuncs_and_a_times_axes_are_straight_line"),
    "events": ("integration/test_watch.py", "integration/test_compiled_smoke.py",
               # the AT model's maps; the dynamic gain's falsified population (2-3 s each)
               "capabilities/test_arch.py::test_compiled_populations_pipelined_judge_the_same_runs",
               "papers/dynamic_gain/test_dynamic_gain_falsification.py::"
               "test_printed_decay_is_falsified_at_the_predicted_rate"),
    "paths": ("integration/test_paths.py", "integration/test_one_definition.py",
              "integration/test_last_axis.py"),
    "stochastic": ("integration/test_sde_stepper.py", "integration/test_stochastic_paths.py",
                   "capabilities/test_explore.py", "integration/test_batch_reduce.py",
                   "integration/test_batch_attributes.py"),
    # Li-Sanfelice's family of designs, rewritten from source (2-3 s each noise kind)
    "002": ("papers/li_sanfelice/test_li_sanfelice_falsification.py::"
            "test_the_family_is_one_definition_on_every_path",),
}


class _CompiledOnly:
    """pytest plugin: of the tests that take ``path``, only their compiled case."""

    @staticmethod
    def pytest_collection_modifyitems(config, items):
        keep = [i for i in items
                if getattr(i, "callspec", None) is None
                or i.callspec.params.get("path", "compiled") == "compiled"]
        config.hook.pytest_deselected(items=[i for i in items if i not in keep])
        items[:] = keep


def _stamp(name, folder):
    """The file that says ``COMPILING[name]`` ran here on this source: named by
    the digest of the group's test files and of every module of hybridsim and
    observers (their source, not the modules generated into ``__pycache__``),
    in numba's cache folder ``folder``."""
    import hashlib
    import pathlib
    here = pathlib.Path(__file__).resolve().parent
    import hybridsim
    import observers
    h = hashlib.sha256(name.encode())
    files = [here / n.split("::")[0] for n in COMPILING[name]]
    for pkg in (hybridsim, observers):
        # (not the generated modules numba's cache keeps inside an installed copy)
        files += sorted(f for f in pathlib.Path(pkg.__file__).parent.rglob("*.py")
                        if "__pycache__" not in f.parts)
    for f in files:
        h.update(str(f.name).encode() + f.read_bytes())
    return pathlib.Path(folder) / f"warmed_{name}_{h.hexdigest()[:24]}"


def warm_tests(name, folder):
    """Run the tests of ``COMPILING[name]`` once in this process (pytest without
    the project's options and workers): what their models compile is kept in
    numba's disk cache. Their outcome is the workers' to report. Once they
    passed on this source (:func:`_stamp`), later suites skip them."""
    import pathlib

    import pytest
    stamp = _stamp(name, folder)
    if stamp.exists():
        return 0
    here = pathlib.Path(__file__).resolve().parent
    code = pytest.main(["-q", "-p", "no:cacheprovider", "-o", "addopts=", "-m", "not slow",
                        "-W", "ignore", *(str(here / n) for n in COMPILING[name])],
                       plugins=[_CompiledOnly()])
    if code == 0:
        stamp.touch()
    return code


def warm(name):
    """Compile (or load) the kernels of ``JOBS[name]`` into numba's disk cache,
    and run its tests."""
    from hybridsim.compiled import _load_kernel
    k = _load_kernel()
    if k.cache_dir() is None:       # not cached (a refused folder): each worker compiles
        return
    for kw in JOBS[name][0]:
        if isinstance(kw, tuple):
            warm_tests(kw[1], k.cache_dir())
        elif kw == "sde":
            import numpy as np

            import hybridsim as hs
            from hybridsim.compiled import CompiledSystem
            ou = CompiledSystem(flow_map=lambda x, t, j, p: -x,
                                diffusion=lambda x, t, j, p: np.full(1, 0.5), state_dim=1)
            hs.simulate(ou, [1.0], t_max=0.1, method="EM", max_step=0.05, seed=0,
                        backend="compiled")
        elif kw == "stl":
            import numpy as np

            from hybridsim import _stl_window_nb
            t = np.linspace(0.0, 1.0, _stl_window_nb.MIN_INSTANTS)
            z = np.zeros(len(t), np.int64)
            _stl_window_nb.window_sup(t, z, t, t, t, 0.0, 0.5, 0.0, 0.5, np.zeros(0), t, z,
                                      np.arange(len(t)))
        else:
            k.compile_kernels(**kw)


def run_jobs(env, slots, timeout=900.0):
    """Run every job of :data:`JOBS`, each in a process of its own (this file),
    at most ``slots`` at once, a job once those it comes after have ended.

    ``env``: the processes' environment. A job still running after
    ``timeout`` seconds is killed (a failure here is the first compiled
    test's to report). Returns ``{name: seconds}`` of wall time per job."""
    import subprocess
    import time
    waiting, running, done, took = list(JOBS), {}, set(), {}
    while waiting or running:
        for name in [n for n in waiting if set(JOBS[n][1]) <= done]:
            if len(running) >= max(1, slots):
                break
            waiting.remove(name)
            running[name] = (subprocess.Popen([sys.executable, __file__, name], env=env,
                                              stdout=subprocess.DEVNULL,
                                              stderr=subprocess.DEVNULL), time.monotonic())
        time.sleep(0.05)
        for name, (proc, start) in list(running.items()):
            if proc.poll() is None and time.monotonic() - start > timeout:
                proc.kill()
                proc.wait()
            if proc.poll() is not None:
                del running[name]
                done.add(name)
                took[name] = time.monotonic() - start
    return took


if __name__ == "__main__":
    warm(sys.argv[1])
