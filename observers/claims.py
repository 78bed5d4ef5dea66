"""The claims registry: every quantitative statement of a paper, with its number.

A :class:`Claim` is one checkable statement of a paper: where it is (an
equation, figure, theorem or section), what it says, the value the paper
prints (or None when it prints none), a zero-argument ``compute`` that
returns our value, and the tolerance under which the two count as the same,
with the reason for that tolerance. Each paper package lists its claims in
``CLAIMS``; the tests pin every one (``tests/papers/test_claims.py``) and the main
job writes them all to ``claims.csv`` and ``index.html``.

Semantics
---------
*Verdict.* A claim with a printed value is ``"reproduced"`` when
``|ours - paper_value| <= tol``, else ``"differs"``. A one-sided claim
("settles not later than 8 s", "the error stays below the bound") says so
with ``relation="<="`` (reproduced when ``ours <= paper_value + tol``) or
``">="`` (when ``ours >= paper_value - tol``). A claim with no printed
value (``paper_value=None``, e.g. "the error is exactly zero after T") is
judged against its ``reference``, the value derived independently of this
package (0 for an exactness claim, a closed form, a recomputation): it is
``"reproduced"`` when ``|ours - reference| <= tol``. When ``compute`` raises
or returns something that is not a finite real number the verdict is
``"error"``.

*Passed.* ``passed`` is what the tests assert: the verdict equals the
claim's ``expected`` verdict and, where a ``reference`` is given,
``|ours - reference| <= ref_tol`` (``ref_tol`` defaults to ``tol``). So a
claim expected to differ from the paper (an erratum) is pinned twice: it
must still differ from the printed value, and it must equal the corrected
value that the documented ``reason`` derives.

Examples
--------
>>> from observers.claims import Claim, evaluate
>>> c = Claim(id="999-eq1-root", paper="999", where="(1)",
...           statement="The positive root of x^2 = 2 is 1.414.",
...           paper_value=1.414, compute=lambda: 2 ** 0.5,
...           tol=5e-4, tol_why="the paper prints 4 significant digits")
>>> r = evaluate(c)
>>> r.verdict, r.passed
('reproduced', True)
>>> wrong = Claim(id="999-eq2-typo", paper="999", where="(2)",
...               statement="x^2 = 2 has the positive root 1.5.",
...               paper_value=1.5, compute=lambda: 2 ** 0.5, tol=5e-4,
...               tol_why="the paper prints 2 significant digits; ours is exact",
...               expected="differs", reason="erratum: (2) drops a digit",
...               reference=1.41421356, ref_tol=1e-8)
>>> r = evaluate(wrong)
>>> r.verdict, r.passed
('differs', True)
"""
from __future__ import annotations

import csv
import dataclasses
import functools
import importlib
import inspect
import math
import numbers
import pathlib
import time
import traceback
from collections.abc import Callable, Iterable, Mapping

import numpy as np

__all__ = [
    "CSV_FIELDS",
    "PAPER_MODULES",
    "RELATIONS",
    "VERDICTS",
    "Claim",
    "ClaimResult",
    "code_location",
    "collect_claims",
    "evaluate",
    "read_csv",
    "run_claims",
    "validate_registry",
    "write_csv",
]

#: The verdicts a claim can be expected to reach.
VERDICTS = ("reproduced", "differs")

#: How a claim's value is compared with its target: equal within ``tol``, or a
#: one-sided bound.
RELATIONS = ("==", "<=", ">=")

#: The paper packages of :mod:`observers`, by module name, with their paper ids.
PAPER_MODULES = {"li_sanfelice": "002", "gramian_delay": "004", "time_varying": "001",
                 "dynamic_gain": "000", "distributed": "003"}

#: Columns of ``claims.csv``, in order (``package``: the paper's module, e.g. 000 is
#: ``dynamic_gain``; ``relation``: "==", or "<=" / ">=" for a one-sided bound).
CSV_FIELDS = ("id", "paper", "package", "where", "statement", "relation", "paper_value",
              "our_value", "reference", "tol", "tol_why", "verdict", "expected", "passed", "reason",
              "seconds", "error")


def _text(name, value, *, required=True, cid=""):
    who = f"Claim {cid!r}: " if cid else "Claim: "
    if not isinstance(value, str):
        raise TypeError(f"{who}{name} must be a str, got {type(value).__name__}")
    if required and not value.strip():
        raise ValueError(f"{who}{name} must be a non-empty string")
    return value


def _real(name, value, *, cid, optional=False, nonneg=False):
    who = f"Claim {cid!r}: "
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        kind = "a real number or None" if optional else "a real number"
        raise TypeError(f"{who}{name} must be {kind}, got {type(value).__name__}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{who}{name} must be finite, got {value}")
    if nonneg and value < 0:
        raise ValueError(f"{who}{name} must be >= 0, got {value}")
    return value


@dataclasses.dataclass(frozen=True)
class Claim:
    """One quantitative statement of a paper, with how to check it.

    Parameters
    ----------
    id : str
        Unique across all papers, no whitespace; by convention
        ``"<paper>-<where>-<what>"``, e.g. ``"002-thm4.7-const"``.
    paper : str
        The paper's id, e.g. ``"002"`` (as in the package's ``PAPER["id"]``).
    where : str
        Where the paper states it: ``"Thm 4.7"``, ``"(39)"``, ``"Fig. 2"``,
        ``"Sec. V.A"``.
    statement : str
        One sentence: what the paper claims.
    paper_value : float or None
        The value the paper prints (or that its formula gives on its own
        data); None when it prints none, and then ``reference`` is required.
    compute : callable
        ``compute() -> float``: our value, computed by this package.
    tol : float
        Absolute tolerance (>= 0) for the verdict.
    tol_why : str
        Why this tolerance: e.g. ``"the paper prints 3 significant digits"``,
        ``"integrator rtol 1e-10 x cond(S) = 1e3"``.
    expected : {"reproduced", "differs"}
        The verdict the claim must reach; default ``"reproduced"``.
    reason : str
        Required when ``expected == "differs"``: the documented reason (an
        erratum, a decision), naming the equation.
    reference : float, optional
        The value derived independently of this package that ours must
        equal within ``ref_tol``; required when ``paper_value`` is None,
        recommended for ``"differs"`` claims (the corrected value).
    ref_tol : float, optional
        Tolerance of the reference pin; default ``tol``. Tighter than ``tol``
        when the paper rounds but the reference is exact.
    slow : bool
        True when ``compute`` takes more than a few seconds: the default
        test suite then skips it (``pytest -m slow`` runs it).
    relation : {"==", "<=", ">="}
        ``"=="`` (default): the paper's value, within ``tol``. ``"<="``: the
        paper states an upper bound, met when ``ours <= paper_value + tol``;
        ``">="``: a lower bound. The reference pin stays two-sided.

    Raises
    ------
    TypeError, ValueError
        A field of the wrong type or value, naming the claim and the field.

    Examples
    --------
    >>> Claim(id="999-x", paper="999", where="(1)", statement="x is 1.",
    ...       paper_value=1.0, compute=lambda: 1.0, tol=-1, tol_why="exact")
    Traceback (most recent call last):
    ...
    ValueError: Claim '999-x': tol must be >= 0, got -1.0
    """

    id: str
    paper: str
    where: str
    statement: str
    paper_value: float | None
    compute: Callable[[], float]
    tol: float
    tol_why: str
    expected: str = "reproduced"
    reason: str = ""
    reference: float | None = None
    ref_tol: float | None = None
    slow: bool = False
    relation: str = "=="

    def __post_init__(self):
        _text("id", self.id)
        cid = self.id
        if any(ch.isspace() for ch in cid):
            raise ValueError(f"Claim {cid!r}: id must contain no whitespace")
        for name in ("paper", "where", "statement", "tol_why"):
            _text(name, getattr(self, name), cid=cid)
        _text("reason", self.reason, required=False, cid=cid)
        set_ = object.__setattr__
        set_(self, "paper_value", _real("paper_value", self.paper_value, cid=cid, optional=True))
        set_(self, "reference", _real("reference", self.reference, cid=cid, optional=True))
        set_(self, "tol", _real("tol", self.tol, cid=cid, nonneg=True))
        set_(self, "ref_tol", _real("ref_tol", self.ref_tol, cid=cid, optional=True, nonneg=True))
        if not callable(self.compute):
            raise TypeError(f"Claim {cid!r}: compute must be a zero-argument callable "
                            f"returning a float, got {type(self.compute).__name__}")
        if self.expected not in VERDICTS:
            raise ValueError(f"Claim {cid!r}: expected must be one of {VERDICTS}, "
                             f"got {self.expected!r}")
        if self.expected == "differs" and not self.reason.strip():
            raise ValueError(f"Claim {cid!r}: expected='differs' needs a reason (the erratum "
                             "or decision that explains the difference, naming the equation)")
        if self.paper_value is None:
            if self.reference is None:
                raise ValueError(f"Claim {cid!r}: paper_value is None (none printed), so a "
                                 "reference is required: the independently derived value "
                                 "our result must match")
            if self.expected == "differs":
                raise ValueError(f"Claim {cid!r}: with no printed value the claim is judged "
                                 "against its reference, so expected='differs' cannot pass; "
                                 "give the value the paper's statement implies as "
                                 "paper_value")
        if self.relation not in RELATIONS:
            raise ValueError(f"Claim {cid!r}: relation must be one of {RELATIONS}, "
                             f"got {self.relation!r}")
        if not isinstance(self.slow, bool):
            raise TypeError(f"Claim {cid!r}: slow must be a bool, got "
                            f"{type(self.slow).__name__}")

    @property
    def target(self) -> float:
        """The value the verdict compares with: ``paper_value``, else ``reference``."""
        return self.paper_value if self.paper_value is not None else self.reference

    def holds(self, value: float) -> bool:
        """Whether ``value`` meets the target under :attr:`relation` and ``tol``."""
        if self.relation == "<=":
            return value <= self.target + self.tol
        if self.relation == ">=":
            return value >= self.target - self.tol
        return abs(value - self.target) <= self.tol

    @property
    def reference_tol(self) -> float:
        """The tolerance of the reference pin (``ref_tol``, else ``tol``)."""
        return self.tol if self.ref_tol is None else self.ref_tol


@dataclasses.dataclass(frozen=True)
class ClaimResult:
    """The outcome of :func:`evaluate` on one claim.

    Attributes
    ----------
    claim : Claim
    value : float
        Our value (nan when ``compute`` failed).
    verdict : {"reproduced", "differs", "error"}
    passed : bool
        The verdict equals ``claim.expected`` and the reference pin holds.
    seconds : float
        Wall time of ``compute``.
    error : str
        Empty, or why the claim could not be evaluated / did not pass.
    boolean : bool
        ``compute`` returned a bool (a yes/no claim: 1.0 is "yes").
    """

    claim: Claim
    value: float
    verdict: str
    passed: bool
    seconds: float
    error: str = ""
    boolean: bool = False

    def shown(self) -> str:
        """Our value as the terminal and the report show it ("yes"/"no" for a
        yes/no claim)."""
        if self.boolean:
            return "yes" if self.value == 1.0 else "no"
        return f"{self.value:.6g}"

    def line(self) -> str:
        """One readable terminal line: whether it is as expected, the verdict
        against the paper, and the values."""
        c = self.claim
        if c.paper_value is not None:
            rel = "" if c.relation == "==" else c.relation + " "
            against = f"paper {rel}{c.paper_value:.6g}"
        else:
            against = f"reference {c.reference:.6g}"
        if self.boolean:
            against = f"paper: {'yes' if c.target == 1.0 else 'no'}"
        if not self.passed:
            status = "NOT AS EXPECTED"
        elif self.verdict == "differs":
            status = "differs, as documented"
        else:
            status = "reproduced"
        text = f"  {status:<22} {c.id:<30} ours {self.shown()}, {against}"
        return text + (f"  {self.error}" if self.error else "")

    def row(self) -> dict:
        """The claim and its outcome as a ``claims.csv`` row (keys :data:`CSV_FIELDS`, and
        ``boolean`` and ``code`` (:func:`code_location` of ``compute``), which the report
        reads and the CSV leaves out)."""
        c = self.claim
        package = {pid: m for m, pid in PAPER_MODULES.items()}.get(c.paper, "")
        return {"id": c.id, "paper": c.paper, "package": package, "where": c.where,
                "statement": c.statement,
                "relation": c.relation, "paper_value": c.paper_value, "our_value": self.value,
                "reference": c.reference, "tol": c.tol, "tol_why": c.tol_why,
                "verdict": self.verdict, "expected": c.expected, "passed": self.passed,
                "reason": c.reason, "seconds": self.seconds, "error": self.error,
                "boolean": self.boolean, "code": code_location(c.compute)}


def code_location(fn) -> dict:
    """Where a claim's value is computed: the function ``fn`` stands for.

    Parameters
    ----------
    fn : callable
        A claim's ``compute`` (a function, a lambda, a closure or a
        :class:`functools.partial` of one).

    Returns
    -------
    dict
        ``function``: ``"module:qualified name"`` (a lambda is
        ``module:<lambda>``, its line says which); ``file``: the source
        file's absolute path, or None; ``line``: the line it starts on, or
        None.

    Examples
    --------
    >>> loc = code_location(code_location)
    >>> loc["function"], pathlib.Path(loc["file"]).name
    ('observers.claims:code_location', 'claims.py')
    """
    f = fn
    while isinstance(f, functools.partial):
        f = f.func
    f = inspect.unwrap(f)
    module = getattr(f, "__module__", None) or "?"
    name = getattr(f, "__qualname__", None) or getattr(f, "__name__", None) or \
        type(f).__qualname__
    try:
        file = inspect.getsourcefile(f)
        line = inspect.getsourcelines(f)[1]
    except (TypeError, OSError):        # a builtin, or code without a source file
        file, line = None, None
    return {"function": f"{module}:{name}",
            "file": None if file is None else str(pathlib.Path(file).resolve()),
            "line": line}


def evaluate(claim: Claim) -> ClaimResult:
    """Compute one claim and judge it (see the module's Semantics).

    Parameters
    ----------
    claim : Claim

    Returns
    -------
    ClaimResult
        ``compute`` raising, or returning anything but a finite real number
        (bools count as 1.0 / 0.0), gives verdict ``"error"``, ``passed``
        False and the reason in ``error``; nothing is raised.

    Examples
    --------
    >>> c = Claim(id="999-zero", paper="999", where="Thm 1",
    ...           statement="The error is zero after T.", paper_value=None,
    ...           compute=lambda: 3e-13, reference=0.0, tol=1e-10,
    ...           tol_why="integrator rtol 1e-12 x state size 1e2")
    >>> evaluate(c).verdict
    'reproduced'
    """
    if not isinstance(claim, Claim):
        raise TypeError(f"claim must be an observers.claims.Claim, got {type(claim).__name__}")
    t0 = time.perf_counter()
    try:
        raw = claim.compute()
    except Exception as exc:  # noqa: BLE001 - a failing claim is reported, not raised
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return ClaimResult(claim, math.nan, "error", False, time.perf_counter() - t0,
                           f"compute() raised {tb}")
    seconds = time.perf_counter() - t0
    boolean = isinstance(raw, (bool, np.bool_))
    try:
        value = float(raw)
    except (TypeError, ValueError):
        return ClaimResult(claim, math.nan, "error", False, seconds,
                           f"compute() must return a real number, got {type(raw).__name__}")
    if not math.isfinite(value):
        return ClaimResult(claim, value, "error", False, seconds,
                           f"compute() returned a non-finite value {value}")
    verdict = "reproduced" if claim.holds(value) else "differs"
    problems = []
    if verdict != claim.expected:
        which = "paper" if claim.paper_value is not None else "reference"
        how = (f"|ours - {which}| = {abs(value - claim.target):.3g}"
               if claim.relation == "==" else
               f"ours {value:.6g} {claim.relation} {which} {claim.target:.6g}")
        problems.append(f"verdict {verdict!r} but expected {claim.expected!r} "
                        f"({how}, tol {claim.tol:g})")
    if claim.reference is not None and abs(value - claim.reference) > claim.reference_tol:
        problems.append(f"|ours - reference| = {abs(value - claim.reference):.3g} > "
                        f"{claim.reference_tol:g} (reference {claim.reference!r})")
    return ClaimResult(claim, value, verdict, not problems, seconds, "; ".join(problems),
                       boolean)


def validate_registry(claims: Iterable[Claim], *, paper: str | None = None) -> list[Claim]:
    """Check a list of claims as a registry: all :class:`Claim`, ids unique.

    Parameters
    ----------
    claims : iterable of Claim
    paper : str, optional
        When given, every claim's ``paper`` must equal it.

    Returns
    -------
    list of Claim

    Raises
    ------
    TypeError
        An entry is not a Claim (its position is named).
    ValueError
        Two claims share an id, or a claim belongs to another paper.

    Examples
    --------
    >>> c = Claim(id="999-a", paper="999", where="(1)", statement="a is 1.",
    ...           paper_value=1.0, compute=lambda: 1.0, tol=0.0, tol_why="exact")
    >>> validate_registry([c, c])
    Traceback (most recent call last):
    ...
    ValueError: duplicate claim id '999-a' (entries 0 and 1)
    """
    if isinstance(claims, (str, bytes, Mapping)) or not isinstance(claims, Iterable):
        raise TypeError(f"claims must be a list of Claim, got {type(claims).__name__}")
    out, seen = [], {}
    for k, c in enumerate(claims):
        if not isinstance(c, Claim):
            raise TypeError(f"claims[{k}] must be an observers.claims.Claim, "
                            f"got {type(c).__name__}")
        if c.id in seen:
            raise ValueError(f"duplicate claim id {c.id!r} (entries {seen[c.id]} and {k})")
        if paper is not None and c.paper != paper:
            raise ValueError(f"claims[{k}] ({c.id!r}) belongs to paper {c.paper!r}, "
                             f"not {paper!r}")
        seen[c.id] = k
        out.append(c)
    return out


def run_claims(claims: Iterable[Claim], *, slow: bool = True,
               echo: Callable[[str], None] | None = None) -> list[ClaimResult]:
    """Evaluate a registry, in order.

    Parameters
    ----------
    claims : iterable of Claim
        Validated first (:func:`validate_registry`).
    slow : bool
        Include claims marked ``slow`` (default True).
    echo : callable, optional
        Called with one line per claim (:meth:`ClaimResult.line`), e.g. ``print``.

    Returns
    -------
    list of ClaimResult

    Examples
    --------
    >>> c = Claim(id="999-a", paper="999", where="(1)", statement="a is 1.",
    ...           paper_value=1.0, compute=lambda: 1.0, tol=0.0, tol_why="exact")
    >>> [r.verdict for r in run_claims([c])]
    ['reproduced']
    """
    results = []
    for c in validate_registry(claims):
        if c.slow and not slow:
            continue
        r = evaluate(c)
        results.append(r)
        if echo is not None:
            echo(r.line())
    return results


def _csv_cell(v):
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return str(v)


def write_csv(results: Iterable[ClaimResult | Mapping], path) -> pathlib.Path:
    """Write claims and their outcomes to a CSV file, columns :data:`CSV_FIELDS`.

    Parameters
    ----------
    results : iterable of ClaimResult or mapping
        Results, or rows as from :meth:`ClaimResult.row`.
    path : str or pathlib.Path
        The file to write (its folder must exist).

    Returns
    -------
    pathlib.Path

    Notes
    -----
    UTF-8 with a header row. No printed value is an empty ``paper_value``;
    floats are written in full precision (``repr``); ``passed`` is
    ``true``/``false``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> c = Claim(id="999-a", paper="999", where="(1)", statement="a is 1.",
    ...           paper_value=1.0, compute=lambda: 1.0, tol=0.0, tol_why="exact")
    >>> p = write_csv(run_claims([c]), pathlib.Path(tempfile.mkdtemp()) / "claims.csv")
    >>> read_csv(p)[0]["verdict"]
    'reproduced'
    """
    path = pathlib.Path(path)
    rows = []
    for k, r in enumerate(results):
        if isinstance(r, ClaimResult):
            rows.append(r.row())
        elif isinstance(r, Mapping):
            missing = [f for f in CSV_FIELDS if f not in r]
            if missing:
                raise ValueError(f"results[{k}] lacks the column(s) {missing}")
            rows.append(r)
        else:
            raise TypeError(f"results[{k}] must be a ClaimResult or a row mapping, "
                            f"got {type(r).__name__}")
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_FIELDS)
        for row in rows:
            w.writerow([_csv_cell(row[f]) for f in CSV_FIELDS])
    return path


def read_csv(path) -> list[dict]:
    """Read a ``claims.csv`` back as rows: numbers as float (None when empty),
    ``passed`` as bool."""
    out = []
    with pathlib.Path(path).open(newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            for f in ("paper_value", "our_value", "reference", "tol", "seconds"):
                row[f] = float(row[f]) if row[f] != "" else None
            row["passed"] = row["passed"] == "true"
            out.append(row)
    return out


def collect_claims(names: Iterable[str] | None = None) -> dict[str, list[Claim] | None]:
    """The ``CLAIMS`` registry of each paper package, by module name.

    Parameters
    ----------
    names : iterable of str, optional
        Module names under :mod:`observers`; default :data:`PAPER_MODULES`.

    Returns
    -------
    dict
        ``{name: list of Claim}``, or ``{name: None}`` for a package that
        defines no ``CLAIMS`` yet. Each list is validated (each claim's
        ``paper`` must equal the package's ``PAPER["id"]`` when it has one),
        and ids are checked unique across all of them.

    Examples
    --------
    >>> sorted(collect_claims())
    ['distributed', 'dynamic_gain', 'gramian_delay', 'li_sanfelice', 'time_varying']
    """
    names = list(PAPER_MODULES if names is None else names)
    out, owner = {}, {}
    for name in names:
        mod = importlib.import_module(f"observers.{name}")
        claims = getattr(mod, "CLAIMS", None)
        if claims is None:
            out[name] = None
            continue
        paper = getattr(mod, "PAPER", None)
        paper = paper.get("id") if isinstance(paper, Mapping) else None
        try:
            claims = validate_registry(claims, paper=paper)
        except (TypeError, ValueError) as exc:
            raise type(exc)(f"observers.{name}.CLAIMS: {exc}") from exc
        for c in claims:
            if c.id in owner:
                raise ValueError(f"duplicate claim id {c.id!r} in observers.{owner[c.id]} "
                                 f"and observers.{name}")
            owner[c.id] = name
        out[name] = claims
    return out
