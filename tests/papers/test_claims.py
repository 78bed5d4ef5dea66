"""The claims registry (observers.claims): its semantics on synthetic claims,
and every paper package's ``CLAIMS`` pinned, one test per claim.

The per-claim test collects the registries when this file is collected: a
paper package that adds a claim gets it pinned with no change here. Claims
marked ``slow`` carry ``pytest.mark.slow`` (deselected by ``-m 'not slow'``).
"""
import dataclasses
import importlib
import inspect
import math
import sys
import time
import types

import numpy as np
import pytest

from observers.claims import (
    CSV_FIELDS,
    PAPER_MODULES,
    Claim,
    ClaimResult,
    collect_claims,
    evaluate,
    read_csv,
    run_claims,
    validate_registry,
    write_csv,
)


def make(**kw):
    base = dict(id="999-eq1-x", paper="999", where="(1)", statement="x equals 1.",
                paper_value=1.0, compute=lambda: 1.0, tol=1e-3,
                tol_why="the paper prints 3 decimals")
    base.update(kw)
    return Claim(**base)


# ------------------------------------------------------------------ verdicts --

@pytest.mark.parametrize("ours, verdict", [
    (1.0, "reproduced"), (1.0 + 0.9e-3, "reproduced"), (1.0 - 0.9e-3, "reproduced"),
    (1.0 + 1.1e-3, "differs"), (0.5, "differs"), (-1.0, "differs"),
])
def test_verdict_is_the_distance_to_the_printed_value(ours, verdict):
    r = evaluate(make(compute=lambda: ours))
    assert r.verdict == verdict
    assert r.value == ours
    assert r.passed is (verdict == "reproduced")       # expected defaults to "reproduced"
    assert (r.error == "") is r.passed


def test_tolerance_is_inclusive_and_zero_tolerance_needs_equality():
    assert evaluate(make(compute=lambda: 1.5, tol=0.5)).verdict == "reproduced"
    assert evaluate(make(compute=lambda: 1.0, tol=0.0)).verdict == "reproduced"
    assert evaluate(make(compute=lambda: math.nextafter(1.0, 2), tol=0.0)).verdict == "differs"


def test_a_failed_claim_says_why():
    r = evaluate(make(compute=lambda: 1.2))
    assert not r.passed
    assert "verdict 'differs' but expected 'reproduced'" in r.error
    assert "0.2" in r.error and "tol 0.001" in r.error


def test_expected_difference_is_pinned_to_its_reference():
    erratum = dict(paper_value=2.0, expected="differs", reason="erratum in (1): factor 2",
                   reference=1.0, ref_tol=1e-12, tol=1e-3)
    r = evaluate(make(compute=lambda: 1.0, **erratum))
    assert (r.verdict, r.passed) == ("differs", True)
    # still differs from the paper, but no longer the corrected value: not passed
    r = evaluate(make(compute=lambda: 1.0 + 1e-9, **erratum))
    assert (r.verdict, r.passed) == ("differs", False)
    assert "reference" in r.error and "1e-09" in r.error
    # the erratum disappeared (ours equals the paper): not passed, the verdict moved
    r = evaluate(make(compute=lambda: 2.0, **erratum))
    assert (r.verdict, r.passed) == ("reproduced", False)


def test_ref_tol_defaults_to_tol():
    c = make(reference=1.0)
    assert c.reference_tol == c.tol == 1e-3
    assert evaluate(make(compute=lambda: 1.0005, reference=1.0)).passed
    assert not evaluate(make(compute=lambda: 1.0005, reference=1.0, ref_tol=1e-6)).passed


def test_no_printed_value_is_judged_against_the_reference():
    c = make(paper_value=None, reference=0.0, tol=1e-10, compute=lambda: 3e-11)
    assert c.target == 0.0
    r = evaluate(c)
    assert (r.verdict, r.passed) == ("reproduced", True)
    r = evaluate(make(paper_value=None, reference=0.0, tol=1e-10, compute=lambda: 1e-6))
    assert (r.verdict, r.passed) == ("differs", False)
    assert "|ours - reference|" in r.error


@pytest.mark.parametrize("compute, message", [
    (lambda: 1 / 0, "compute() raised ZeroDivisionError"),
    (lambda: float("nan"), "non-finite"),
    (lambda: math.inf, "non-finite"),
    (lambda: "1.0x", "must return a real number, got str"),
    (lambda: [1.0, 2.0], "must return a real number, got list"),
    (lambda: None, "must return a real number, got NoneType"),
])
def test_a_claim_that_cannot_be_computed_is_an_error_not_an_exception(compute, message):
    r = evaluate(make(compute=compute))
    assert r.verdict == "error"
    assert r.passed is False
    assert message in r.error
    assert r.seconds >= 0


def test_numpy_scalars_and_bools_are_values():
    np = pytest.importorskip("numpy")
    assert evaluate(make(compute=lambda: np.float32(1.0))).value == 1.0
    assert evaluate(make(compute=lambda: np.array(1.0))).verdict == "reproduced"
    assert evaluate(make(compute=lambda: True)).value == 1.0


def test_seconds_are_the_time_of_compute():
    def slow():
        time.sleep(0.05)
        return 1.0
    r = evaluate(make(compute=slow))
    assert 0.05 <= r.seconds < 2.0


def test_evaluate_rejects_what_is_not_a_claim():
    with pytest.raises(TypeError, match=r"claim must be an observers\.claims\.Claim, got dict"):
        evaluate({"id": "x"})


# ---------------------------------------------------------------- validation --

@pytest.mark.parametrize("kw, exc, message", [
    (dict(tol=-1e-3), ValueError, "'999-eq1-x': tol must be >= 0, got -0.001"),
    (dict(tol=math.nan), ValueError, "tol must be finite"),
    (dict(tol="0.1"), TypeError, "tol must be a real number, got str"),
    (dict(ref_tol=-1.0), ValueError, "ref_tol must be >= 0"),
    (dict(expected="differs"), ValueError, "expected='differs' needs a reason"),
    (dict(expected="differs", reason="   "), ValueError, "needs a reason"),
    (dict(expected="same"), ValueError, "expected must be one of ('reproduced', 'differs')"),
    (dict(paper_value=None), ValueError, "paper_value is None (none printed), so a reference"),
    (dict(paper_value=None, reference=0.0, expected="differs", reason="r"), ValueError,
     "cannot pass"),
    (dict(paper_value=True), TypeError, "paper_value must be a real number or None, got bool"),
    (dict(paper_value=math.inf), ValueError, "paper_value must be finite"),
    (dict(reference="0"), TypeError, "reference must be a real number or None, got str"),
    (dict(compute=1.0), TypeError, "compute must be a zero-argument callable"),
    (dict(id=""), ValueError, "id must be a non-empty string"),
    (dict(id="002 thm"), ValueError, "id must contain no whitespace"),
    (dict(id=2), TypeError, "id must be a str, got int"),
    (dict(statement=""), ValueError, "'999-eq1-x': statement must be a non-empty string"),
    (dict(where=None), TypeError, "where must be a str, got NoneType"),
    (dict(tol_why=""), ValueError, "tol_why must be a non-empty string"),
    (dict(paper=""), ValueError, "paper must be a non-empty string"),
    (dict(reason=3), TypeError, "reason must be a str"),
    (dict(slow=1), TypeError, "slow must be a bool, got int"),
])
def test_bad_fields_are_named(kw, exc, message):
    with pytest.raises(exc) as info:
        make(**kw)
    assert message in str(info.value)


def test_claims_are_frozen_and_numbers_normalised():
    c = make(paper_value=2, tol=0, reference=2)
    assert isinstance(c.paper_value, float) and isinstance(c.tol, float)
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.tol = 1.0


def test_registry_rejects_duplicates_foreign_papers_and_non_claims():
    a, b = make(id="999-a"), make(id="999-b")
    assert validate_registry((a, b)) == [a, b]
    assert validate_registry([]) == []
    with pytest.raises(ValueError, match=r"duplicate claim id '999-a' \(entries 0 and 2\)"):
        validate_registry([a, b, make(id="999-a")])
    with pytest.raises(TypeError, match=r"claims\[1\] must be an observers.claims.Claim, got dict"):
        validate_registry([a, {"id": "999-c"}])
    with pytest.raises(ValueError, match=r"claims\[0\] \('999-a'\) belongs to paper '999', "
                                         r"not '002'"):
        validate_registry([a], paper="002")
    with pytest.raises(TypeError, match="claims must be a list of Claim, got str"):
        validate_registry("999-a")


def test_run_claims_in_order_skipping_slow_on_request():
    claims = [make(id="999-a"), make(id="999-b", slow=True), make(id="999-c", compute=lambda: 9)]
    lines = []
    results = run_claims(claims, echo=lines.append)
    assert [r.claim.id for r in results] == ["999-a", "999-b", "999-c"]
    assert [r.passed for r in results] == [True, True, False]
    assert len(lines) == 3 and lines[2].lstrip().startswith("NOT AS EXPECTED")
    assert [r.claim.id for r in run_claims(claims, slow=False)] == ["999-a", "999-c"]
    with pytest.raises(ValueError, match="duplicate claim id"):
        run_claims([claims[0], claims[0]])


# ----------------------------------------------------------------------- CSV --

def test_csv_round_trip_keeps_every_field(tmp_path):
    tricky = 'a "quoted", comma\nand a new line; λ ≤ 1 & <b>'
    claims = [make(id="999-a", compute=lambda: 1.0 + 1e-13),
              make(id="999-b", paper_value=None, reference=0.0, tol=1e-10, statement=tricky,
                   compute=lambda: 2.5e-12),
              make(id="999-c", paper_value=2.0, expected="differs", reason=tricky,
                   reference=1.0, compute=lambda: 1.0),
              make(id="999-d", compute=lambda: 1 / 0)]
    results = run_claims(claims)
    path = write_csv(results, tmp_path / "claims.csv")
    header = path.read_text(encoding="utf-8").splitlines()[0]
    assert header == ",".join(CSV_FIELDS)
    rows = read_csv(path)
    assert [r["id"] for r in rows] == ["999-a", "999-b", "999-c", "999-d"]
    for row, res in zip(rows, results, strict=True):
        want = res.row()
        for f in CSV_FIELDS:
            got, exp = row[f], want[f]
            if isinstance(exp, float) and math.isnan(exp):
                assert math.isnan(got)
            else:
                assert got == exp, (f, got, exp)       # floats in full precision
    assert rows[0]["our_value"] == 1.0 + 1e-13
    assert rows[1]["paper_value"] is None and rows[1]["statement"] == tricky
    assert rows[3]["verdict"] == "error" and "ZeroDivisionError" in rows[3]["error"]
    # rows (as recorded in part.json) write the same file
    again = write_csv([r.row() for r in results], tmp_path / "again.csv")
    assert again.read_bytes() == path.read_bytes()


def test_write_csv_rejects_incomplete_rows(tmp_path):
    with pytest.raises(ValueError, match=r"results\[0\] lacks the column\(s\) \['paper'"):
        write_csv([{"id": "x"}], tmp_path / "c.csv")
    with pytest.raises(TypeError, match=r"results\[0\] must be a ClaimResult or a row mapping"):
        write_csv([1.0], tmp_path / "c.csv")


# -------------------------------------------------------- collecting registries --

def _fake_paper(monkeypatch, name, paper_id, claims):
    mod = types.ModuleType(f"observers.{name}")
    mod.PAPER = {"id": paper_id, "title": "t", "authors": "a", "venue": "v"}
    mod.CLAIMS = claims
    monkeypatch.setitem(sys.modules, f"observers.{name}", mod)


def test_collect_claims_checks_ids_across_papers_and_paper_ids(monkeypatch):
    _fake_paper(monkeypatch, "_fake_a", "998", [make(id="998-x", paper="998")])
    _fake_paper(monkeypatch, "_fake_b", "999", [make(id="998-x", paper="999")])
    _fake_paper(monkeypatch, "_fake_c", "997", [make(id="997-x", paper="999")])
    _fake_paper(monkeypatch, "_fake_d", "996", None)
    got = collect_claims(["_fake_a", "_fake_d"])
    assert [c.id for c in got["_fake_a"]] == ["998-x"] and got["_fake_d"] is None
    with pytest.raises(ValueError, match=r"duplicate claim id '998-x' in observers\._fake_a and "
                                         r"observers\._fake_b"):
        collect_claims(["_fake_a", "_fake_b"])
    with pytest.raises(ValueError, match=r"observers._fake_c.CLAIMS: claims\[0\] \('997-x'\) "
                                         "belongs to paper '999', not '997'"):
        collect_claims(["_fake_c"])


# ------------------------------------------- the papers' registries, pinned --

def _registry():
    """The registries, or the error that stops one being read (reported by a failing
    test, not a collection error that would hide the tests above)."""
    try:
        return collect_claims(), None
    except Exception as exc:  # noqa: BLE001 - shown by test_paper_claim below
        return {}, f"{type(exc).__name__}: {exc}"


REGISTRY, REGISTRY_ERROR = _registry()
WITHOUT = sorted(name for name, claims in REGISTRY.items() if claims is None)


def _params():
    if REGISTRY_ERROR:
        return [pytest.param(REGISTRY_ERROR, id="registry-error")]
    params = [pytest.param(c, id=c.id, marks=[pytest.mark.slow] if c.slow else [])
              for claims in REGISTRY.values() for c in claims or []]
    if not params:
        params = [pytest.param("no paper package defines CLAIMS (" + ", ".join(WITHOUT) + ")",
                               id="no-claims")]
    return params


@pytest.mark.parametrize("claim", _params())
def test_paper_claim(claim):
    if isinstance(claim, str):
        pytest.fail(f"the papers' CLAIMS could not be collected: {claim}")
    r = evaluate(claim)
    assert r.passed, (f"{claim.id} ({claim.where}): {r.error}; ours {r.value!r}, paper "
                      f"{claim.paper_value!r}, reference {claim.reference!r}")
    assert r.verdict == claim.expected


@pytest.mark.parametrize("name", sorted(PAPER_MODULES))
def test_paper_package_contract(name):
    """PAPER, ERRATA, DECISIONS, CLAIMS and reproduce(outdir) as the main job reads them."""
    mod = importlib.import_module(f"observers.{name}")
    sig = inspect.signature(mod.reproduce)
    params = list(sig.parameters.values())
    assert params and params[0].kind in (params[0].POSITIONAL_ONLY,
                                         params[0].POSITIONAL_OR_KEYWORD), \
        f"observers.{name}.reproduce must take the output folder as its first argument"
    assert all(p.default is not p.empty or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
               for p in params[1:]), f"observers.{name}.reproduce(outdir) must need nothing else"
    defined = [k for k in ("PAPER", "ERRATA", "DECISIONS", "CLAIMS") if hasattr(mod, k)]
    assert defined == ["PAPER", "ERRATA", "DECISIONS", "CLAIMS"], \
        f"observers.{name} must define PAPER, ERRATA, DECISIONS and CLAIMS (has {defined})"
    if hasattr(mod, "PAPER"):
        paper = mod.PAPER
        assert isinstance(paper, dict), f"observers.{name}.PAPER must be a dict"
        for key in ("id", "title", "authors", "venue"):
            assert isinstance(paper.get(key), str) and paper[key].strip(), \
                f"observers.{name}.PAPER[{key!r}] must be a non-empty str"
        assert paper["id"] == PAPER_MODULES[name]
    for key in ("ERRATA", "DECISIONS"):
        if hasattr(mod, key):
            items = getattr(mod, key)
            assert isinstance(items, (list, tuple)), f"observers.{name}.{key} must be a list"
            assert all(isinstance(s, str) and s.strip() for s in items), \
                f"observers.{name}.{key} must hold non-empty strings"
    if getattr(mod, "CLAIMS", None) is not None:
        validate_registry(mod.CLAIMS, paper=PAPER_MODULES[name])
        assert all(isinstance(c, Claim) for c in mod.CLAIMS)


def test_claim_result_row_has_the_csv_columns():
    r = evaluate(make())
    assert isinstance(r, ClaimResult)
    assert tuple(r.row()) == (*CSV_FIELDS, "boolean", "code")
    code = r.row()["code"]                       # where the value is computed
    assert code["function"].endswith("<lambda>") and code["file"] and code["line"]


# ------------------------------------------------- one-sided claims, yes/no --

@pytest.mark.parametrize("relation, ours, verdict", [
    ("<=", 7.0, "reproduced"), ("<=", 8.0 + 0.9e-3, "reproduced"), ("<=", 8.1, "differs"),
    (">=", 9.0, "reproduced"), (">=", 8.0 - 0.9e-3, "reproduced"), (">=", 7.9, "differs"),
    ("==", 7.0, "differs")])
def test_one_sided_claims(relation, ours, verdict):
    """'Not later than 8 s' holds at 7 s: a bound is checked on its one side."""
    c = make(paper_value=8.0, compute=lambda: ours, relation=relation,
             expected=verdict, reason="" if verdict == "reproduced" else "erratum: (1)")
    r = evaluate(c)
    assert r.verdict == verdict and r.passed
    assert c.holds(ours) == (verdict == "reproduced")


def test_relation_is_checked():
    with pytest.raises(ValueError, match="relation must be one of"):
        make(relation="<")


def test_claim_lines_read_in_words():
    ok = evaluate(make(paper_value=8.0, compute=lambda: 7.0, relation="<="))
    assert ok.line().split()[:2] == ["reproduced", "999-eq1-x"]
    assert "ours 7, paper <= 8" in ok.line()
    yes = evaluate(make(paper_value=None, reference=1.0, tol=0.0,
                        compute=lambda: np.bool_(True)))
    assert yes.boolean and yes.shown() == "yes" and "paper: yes" in yes.line()
    assert yes.row()["boolean"] is True
    off = evaluate(make(compute=lambda: 2.0))
    assert off.line().lstrip().startswith("NOT AS EXPECTED") and "tol 0.001" in off.line()
    erratum = evaluate(make(compute=lambda: 2.0, expected="differs", reason="erratum: (1)"))
    assert erratum.line().lstrip().startswith("differs, as documented")
