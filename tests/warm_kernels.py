"""The engine's cached kernels compiled before the test processes start.

numba keeps what compiling a kernel took in the process that compiled it (70-100
MB for each run kernel, for the life of the process), while a process that
loads the same kernel from numba's disk cache takes a few MB. So when the suite
runs on several pytest-xdist workers, ``conftest.py`` first runs this module in
throwaway processes (``python warm_kernels.py 0``, ``... 1``, ``... 2``, in
parallel), which compile the kernels whose signature is fixed (the maps passed
by address: the run kernels, the batch kernel, the SDE flow's) into the disk
cache, or find them there: every worker then loads them, and each kernel is
compiled once per machine rather than once per worker. A kernel already in
the cache costs the process about a second.

The maps of a model are compiled by the tests that run it, into the same
cache. Where a model takes longer than a test's budget to compile, the tests
in :data:`COMPILING` are run once here (the ``"tests"`` of :data:`PARTS`),
their output discarded, so the workers load what they compiled.
"""
from __future__ import annotations

import sys

#: the run kernels (``_cache.compile_kernels`` arguments) of each warming
#: process, split so they take about as long (``_cache.COMPILE_SECONDS``);
#: ``"sde"``: the SDE flow's kernel, compiled by a run of one small SDE; RK4's
#: run kernel (the compiled RK4 tests) with it; ``"tests"``: the tests of
#: :data:`COMPILING`, after RK4's kernel for flows with delays (004's populations)
PARTS = (({"batch": True}, {"batch": False, "watch": True}),
         ({"batch": False, "delays": True}, {"batch": False, "method": "DOP853"}),
         ("sde", {"batch": False, "method": "RK4"}),
         ({"batch": False, "delays": True, "method": "RK4"}, "tests"))


#: tests (node ids under this folder) whose models take seconds to compile cold:
#: 004's populations (the lowered plant and observer's maps, about 5-15 s each)
COMPILING = (
    "papers/gramian_delay/test_gramian_delay_falsification.py::"
    "test_population_run_matches_the_package_run",
    "papers/gramian_delay/test_gramian_delay_falsification.py::test_gaps_are_in_the_class",
    "papers/gramian_delay/test_gramian_delay_falsification.py::"
    "test_theorem1_rows_carry_their_own_disturbances",
    "papers/gramian_delay/test_every_gap.py::test_sequence_run_rows_sample_at_their_own_instants",
    "integration/test_source_unroll.py::test_sums_binary_ufuncs_and_a_times_axes_are_straight_line",
)


def warm_tests():
    """Run the tests of :data:`COMPILING` once in this process (pytest without
    the project's options and workers): what their models compile is kept in
    numba's disk cache. Their outcome is the workers' to report."""
    import pathlib

    import pytest
    here = pathlib.Path(__file__).resolve().parent
    return pytest.main(["-q", "-p", "no:cacheprovider", "-o", "addopts=", "-W", "ignore",
                        *(str(here / n) for n in COMPILING)])


def warm(part):
    """Compile (or load) the kernels of ``PARTS[part]`` into numba's disk cache."""
    from hybridsim.compiled import _load_kernel
    k = _load_kernel()
    if k.cache_dir() is None:       # not cached (a refused folder): each worker compiles
        return
    for kw in PARTS[part]:
        if kw == "tests":
            warm_tests()
        elif kw == "sde":
            import numpy as np

            import hybridsim as hs
            from hybridsim.compiled import CompiledSystem
            ou = CompiledSystem(flow_map=lambda x, t, j, p: -x,
                                diffusion=lambda x, t, j, p: np.full(1, 0.5), state_dim=1)
            hs.simulate(ou, [1.0], t_max=0.1, method="EM", max_step=0.05, seed=0,
                        backend="compiled")
        else:
            k.compile_kernels(**kw)


if __name__ == "__main__":
    warm(int(sys.argv[1]))
