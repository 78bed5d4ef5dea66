"""README.md says what the code does: its commands, its pointers, its length.

The numbers the documentation quotes from the papers' reproductions (each
package's section of ``docs/observers.rst``) are tied here to the claims
that produce them, so a claim that moves fails a test until the text
follows: the pinned values (a claim's printed or reference value) in the
default suite, our measured values (which need the runs) in the slow one.
"""
from __future__ import annotations

import pathlib
import re

import pytest

from observers.claims import PAPER_MODULES, collect_claims, evaluate

ROOT = pathlib.Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()
OBSERVERS = (ROOT / "docs" / "observers.rst").read_text()


@pytest.fixture(scope="module")
def claims():
    return {c.id: c for reg in collect_claims().values() for c in reg}


def _row(module):
    """A paper package's section of docs/observers.rst, its whitespace collapsed."""
    m = re.search(rf"^``{module}``\n-+\n(.*?)(?=^\.\. _observers-|\Z)", OBSERVERS,
                  flags=re.S | re.M)
    assert m, f"docs/observers.rst has no section for {module}"
    return " ".join(m.group(1).split())


def test_readme_is_one_page():
    """A newcomer's first page: at most 200 lines, its times filled in, the
    question "which path do I use" answered in a table."""
    assert len(README.splitlines()) <= 200, len(README.splitlines())
    for placeholder in ("WALL_TESTS", "CPU_TESTS", "WALL_MAIN", "CPU_MAIN", "DOCS_BUILD_TIME"):
        assert placeholder not in README
    table = README.split("## Which path when", 1)[1].split("\n## ", 1)[0]
    for path in ("Python", "vectorized", "compiled"):
        assert re.search(rf"^\| \*\*{path}", table, flags=re.M), path


def test_exactly_two_setup_commands():
    block = README.split("## Set-up: the two commands", 1)[1].split("```bash", 1)[1]
    block = block.split("```", 1)[0]
    commands = [ln for ln in block.splitlines() if ln.strip() and not ln.startswith("#")]
    assert commands == [
        'python -m pip install ".[lmi]" && python -m observers reproduce --out results',
        'python -m pip install ".[lmi,test]" && python -m pytest -q']


def test_ten_line_example_runs_as_printed():
    """README's example block, run as printed (Agg backend): the ball's first
    bounces at the closed-form times, to the engine's event accuracy."""
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hybridsim.library import bouncing_ball_jump_times

    block = README.split("## Ten lines: define, simulate, plot", 1)[1]
    code = block.split("```python\n", 1)[1].split("```", 1)[0]
    assert len(code.strip().splitlines()) <= 14
    ns = {}
    exec(compile(code, "README.md", "exec"), ns)
    plt.close("all")
    arc = ns["arc"]
    assert arc.jump_count == 20 and arc.termination.name == "J_MAX"
    # default rtol 1e-6, but RK45 integrates the parabola exactly: 1e-9 on t_k
    np.testing.assert_allclose(arc.jump_times, bouncing_ball_jump_times(1.0, 20), rtol=0,
                               atol=1e-9)
    assert [a.get_ylabel() for a in ns["axs"]] == ["height (m)", "velocity (m/s)"]


def test_points_only_inside_the_repository():
    assert "../" not in README and "/work/" not in README
    targets = re.findall(r"`((?:hybridsim|observers|tests|benchmarks|examples|docs)/"
                         r"[\w./-]+\.(?:py|rst|md|png))`", README)
    targets += re.findall(r"\]\(((?:docs|examples|benchmarks)/[\w./-]+)\)", README)
    assert targets
    for target in targets:
        assert (ROOT / target).exists(), target


def test_paper_ids_explained():
    for module, pid in PAPER_MODULES.items():
        assert re.search(rf"{pid} [^()]*\(`{module}`\)", README.replace("\n", " ")), module


def test_claim_counts(claims):
    for module, pid in PAPER_MODULES.items():
        for n in re.findall(r"(\d+) claims", _row(module)):
            assert int(n) == sum(c.paper == pid for c in claims.values()), module


#: README text, the claim, which pinned field, and how README writes it.
PINNED = [
    ("li_sanfelice", "002-VA-K2-delta1", "paper_value", "δ = 1 is {:.4f}"),
    ("li_sanfelice", "002-VA-eq15-delta1", "paper_value", "per unit of m {:.4f}"),
    ("gramian_delay", "004-eq5-condS-k100", "reference",
     lambda v: f"cond(S) = {v / 1e5:.3f}e5"),
    ("gramian_delay", "004-fig2-k75-literal-horizon", "reference", "stops at {:.2f} s"),
    ("time_varying", "001-eq28-la-example", "reference", "certified supremum {:.4f}"),
    ("distributed", "003-thm1-settle", "reference", "settles to 1e-8 at {:.7f} s"),
]

#: README text tied to our measured value (the claim is evaluated).
MEASURED = [
    ("dynamic_gain", "000-fig1a-settling-gamma2-1", "settles at {:.2f} s"),
    ("dynamic_gain", "000-fig1a-1e-6-crossing-gamma2-1", "exceeds 1e-6 at {:.2f} s"),
    ("dynamic_gain", "000-fig2-blowup-gamma2-0", "``BLOWUP`` at t = {:.2f}"),
]

#: Round-off figures, which differ between machines (BLAS, CPU): the page states
#: a bound, and the claim's measured value must stay below it.
ROUND_OFF = [
    ("dynamic_gain", "000-fig1a-T-gamma2-0", lambda v: abs(v - 5.0),
     "reproduced to within 1e-5 s", 1e-5),
    ("dynamic_gain", "000-fig1a-exact-after-T", abs, "error after T below 1e-11", 1e-11),
    ("gramian_delay", "004-thm1-exact-k75", abs,
     "exact to round-off (below 1e-9) over the whole horizon", 1e-9),
]


def sci(v, digits=1):
    """As README writes it: 2.2e-6, not 2.2e-06."""
    m, e = f"{v:.{digits}e}".split("e")
    return f"{m}e{int(e)}"


def _text(fmt, v):
    return fmt(v) if callable(fmt) else fmt.format(v)


@pytest.mark.parametrize("module, cid, field, fmt", PINNED, ids=[p[1] for p in PINNED])
def test_pinned_numbers(claims, module, cid, field, fmt):
    assert _text(fmt, getattr(claims[cid], field)) in _row(module)


@pytest.mark.slow
@pytest.mark.parametrize("module, cid, fmt", MEASURED, ids=[m[1] for m in MEASURED])
def test_measured_numbers(claims, module, cid, fmt):
    r = evaluate(claims[cid])
    assert r.passed, r.error
    assert _text(fmt, r.value) in _row(module)


@pytest.mark.slow
@pytest.mark.parametrize("module, cid, err, text, bound", ROUND_OFF,
                         ids=[m[1] for m in ROUND_OFF])
def test_round_off_stays_below_the_stated_bound(claims, module, cid, err, text, bound):
    r = evaluate(claims[cid])
    assert r.passed, r.error
    assert text in _row(module)
    assert err(r.value) < bound, (cid, r.value)
