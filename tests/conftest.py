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
"""
from __future__ import annotations

import pathlib

import pytest
from paths import HAS_NUMBA, NO_NUMBA, PATHS

ROOT = pathlib.Path(__file__).resolve().parent.parent


def pytest_configure(config):
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


@pytest.fixture(scope="session")
def repo() -> pathlib.Path:
    """The repository's root folder."""
    return ROOT
