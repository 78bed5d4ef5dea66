"""Root test configuration, shared by ``tests/`` and the doctests that
``--doctest-modules`` collects from ``hybridsim/`` and ``observers/``.

One BLAS thread (the matrices here are tiny; threads only spin on a shared
2-core machine), a non-interactive matplotlib, and ``np`` / ``hs`` in every
doctest's namespace, as the docstrings' Examples assume
(``import numpy as np``, ``import hybridsim as hs``). Doctests print numpy
scalars as numpy 1.x did (``True``, ``64.0``, not ``np.True_``,
``np.float64(64.0)``), so Examples read as plain numbers; the tests in
``tests/`` keep numpy's default printing.
"""
import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
# every arc an integration path returns is validated (HybridArc.validate: the
# invariants of a hybrid time domain), so no test's run hides a corrupt arc
os.environ.setdefault("HYBRIDSIM_CHECK_ARCS", "1")

# numpy after the thread settings, which it reads at import
import numpy as np
import pytest


def pytest_xdist_auto_num_workers(config):
    """``-n auto``: one worker per core, at most 4 (each holds its own
    compiled kernels, about 1 GB with the papers' packages loaded)."""
    return max(1, min(os.cpu_count() or 1, 4))


def pytest_collection_modifyitems(config, items):
    """The compiled path's doctests compile numba kernels (tens of seconds on a
    fresh machine): slow, like tests/integration/test_compiled.py."""
    for item in items:
        if "hybridsim/compiled" in str(item.fspath).replace("\\", "/"):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(autouse=True)
def _close_figures():
    """Every figure a test or Example left open closed after it (pyplot keeps
    them, and their canvases, for the life of the process)."""
    yield
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        plt.close("all")


@pytest.fixture(autouse=True)
def _doctest_setup(request):
    from _pytest.doctest import DoctestItem

    if not isinstance(request.node, DoctestItem):
        yield
        return
    import hybridsim as hs

    namespace = request.getfixturevalue("doctest_namespace")
    namespace["np"] = np
    namespace["hs"] = hs
    with np.printoptions(legacy="1.25"):
        yield
