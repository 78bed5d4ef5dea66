"""The engine's cached kernels compiled before the test processes start.

numba keeps what compiling a kernel took in the process that compiled it (70-100
MB for each run kernel, for the life of the process), while a process that
loads the same kernel from numba's disk cache takes a few MB. So when the suite
runs on several pytest-xdist workers, ``conftest.py`` first runs this module in
two throwaway processes (``python warm_kernels.py 0`` and ``... 1``, in
parallel), which compile the run kernels whose signature is fixed (the maps
passed by address) into the disk cache, or find them there: every worker then
loads them, and each kernel is compiled once per machine rather than once per
worker. A kernel already in the cache costs the process about a second.

Kernels specialised on a system's maps (``specialize=True``, the SDE flow's)
are compiled by the tests that run those systems, as before.
"""
from __future__ import annotations

import sys

#: the run kernels (``_cache.compile_kernels`` arguments) of each warming
#: process, split so the two take about as long (COMPILE_SECONDS)
PARTS = (({"batch": True}, {"batch": False, "watch": True}),
         ({"batch": False, "delays": True}, {"batch": False, "method": "DOP853"}))


def warm(part):
    """Compile (or load) the kernels of ``PARTS[part]`` into numba's disk cache."""
    from hybridsim.compiled import _load_kernel
    k = _load_kernel()
    for kw in PARTS[part]:
        k.compile_kernels(**kw)


if __name__ == "__main__":
    warm(int(sys.argv[1]))
