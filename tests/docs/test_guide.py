"""The user guide's examples (docs/guide/*.rst) run as shown: each page is a
doctest, in a fresh namespace, with the suite's doctest flags; the figures of
the plotting page are drawn on the Agg backend.

The compiled page compiles its maps with numba (seconds once per process), so
it runs with the slow checks, and only where numba is installed.
"""
import doctest
import importlib.util
from pathlib import Path

import pytest

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide"
ORDER = ["define", "simulate", "plot", "check", "batch", "fast", "explore", "falsify",
         "sensitivities"]
SLOW = {"fast"}


def test_guide_pages_in_order_and_linked():
    index = (GUIDE / "index.rst").read_text(encoding="utf-8")
    toc = index.split(":maxdepth: 1", 1)[1].split("\n\n", 2)[1].split()
    assert toc == ORDER
    assert sorted(p.stem for p in GUIDE.glob("*.rst")) == sorted([*ORDER, "index"])
    docs_index = (GUIDE.parent / "index.rst").read_text(encoding="utf-8")
    assert "guide/index" in docs_index


@pytest.mark.parametrize("page", [pytest.param(p, marks=pytest.mark.slow) if p in SLOW else p
                                  for p in ORDER])
def test_guide_page_runs_as_shown(page, monkeypatch, tmp_path):
    if page == "fast" and importlib.util.find_spec("numba") is None:
        pytest.skip("the compiled path needs numba (pip install '.[fast]')")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)                # anything a page writes stays here
    flags = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
    result = doctest.testfile(str(GUIDE / f"{page}.rst"), module_relative=False,
                              optionflags=flags, verbose=False, report=True)
    plt.close("all")
    assert result.attempted > 0, f"docs/guide/{page}.rst has no example"
    assert result.failed == 0, f"{result.failed} example(s) of docs/guide/{page}.rst failed"
