"""The papers page of the documentation, generated from the code at build time.

``conf.py`` writes :func:`papers_rst` into ``docs/_generated/papers.rst``,
which ``docs/papers.rst`` includes: each paper package's ``PAPER``,
``ERRATA``, ``DECISIONS`` and ``NOT_REPRODUCED`` (where defined), and every
claim of :func:`observers.claims.collect_claims` with its place in the paper,
statement, paper value, tolerance and why, expected verdict and reason. The
claims' ``compute`` is never called (evaluating them takes minutes; the main
job does, into ``results/index.html``). Kept out of ``conf.py`` so that
``tests/docs/test_docs.py`` can check the text without a Sphinx build.
"""
from __future__ import annotations

import importlib
import re
from collections.abc import Mapping

#: Title underline characters of the generated sections (the including page's
#: title uses "=").
_H2, _H3 = "-", "~"


def escape(text) -> str:
    """Plain text as reStructuredText that shows it verbatim, on one line.

    Inline markup characters are backslash-escaped and so is the first
    character, so that "A. N. Author" or "(50) is ..." do not start an
    enumerated list.
    """
    text = " ".join(str(text).split())
    if not text:
        return "\\"
    text = re.sub(r"([\\`*_|\[\]<>])", r"\\\1", text)
    return text if text.startswith("\\") else "\\" + text


def _number(v) -> str:
    return "none printed" if v is None else format(float(v), ".10g")


def _heading(text: str, char: str, label: str | None = None) -> list[str]:
    """A section title, with an explicit target (a stable anchor) if given:
    docutils drops the leading digits of "000 errata" from its implicit id."""
    return ([f".. _{label}:", ""] if label else []) + [text, char * len(text), ""]


def _bullets(items) -> list[str]:
    return [f"* {escape(s)}" for s in items] + [""]


def _value(c) -> str:
    """The paper's value with the claim's relation, or its reference."""
    if c.paper_value is None:
        return f"none printed; reference {_number(c.reference)}"
    rel = {"==": "", "<=": "≤ ", ">=": "≥ "}[c.relation]
    out = f"{rel}{_number(c.paper_value)}"
    if c.reference is not None:
        out += f" (reference {_number(c.reference)}, to {_number(c.reference_tol)})"
    return out


def _claims_table(claims) -> list[str]:
    out = [".. list-table::", "   :header-rows: 1", "   :widths: 18 34 14 20 14",
           "   :class: claims-table", "",
           "   * - Claim (where)", "     - Statement", "     - Paper value",
           "     - Tolerance (why)", "     - Expected verdict (reason)"]
    for c in claims:
        out += [f"   * - ``{c.id}``", "",
                f"       {escape(c.where)}",
                f"     - {escape(c.statement)}",
                f"     - {escape(_value(c))}",
                f"     - {escape(_number(c.tol))}", "",
                f"       {escape(c.tol_why)}",
                f"     - **{c.expected}**" + (" (slow)" if c.slow else "")]
        if c.reason.strip():
            out += ["", f"       {escape(c.reason)}"]
    return out + [""]


def papers_rst() -> str:
    """The generated part of the papers page, as reStructuredText."""
    from observers.claims import PAPER_MODULES, collect_claims

    claims = collect_claims()
    order = sorted(PAPER_MODULES, key=lambda name: PAPER_MODULES[name])
    out = [".. list-table:: The five papers by id (a claim's id starts with it)",
           "   :header-rows: 1", "   :widths: 8 18 44 30", "",
           "   * - Id", "     - Package", "     - Paper", "     - Claims"]
    mods = {name: importlib.import_module(f"observers.{name}") for name in order}
    for name in order:
        paper = getattr(mods[name], "PAPER", None) or {}
        n = len(claims[name] or [])
        out += [f"   * - :ref:`{PAPER_MODULES[name]} <paper-{name}>`",
                f"     - :mod:`observers.{name}`",
                f"     - {escape(paper.get('title', name))}",
                f"     - {n} claim{'s' if n != 1 else ''}"]
    out.append("")
    for name in order:
        mod, pid = mods[name], PAPER_MODULES[name]
        paper = getattr(mod, "PAPER", None)
        paper = paper if isinstance(paper, Mapping) else {}
        out += _heading(f"{pid}: {escape(paper.get('title', name))}", _H2, f"paper-{name}")
        out += [f"{escape(paper.get('authors', ''))}. *{escape(paper.get('venue', ''))}*.",
                f"Package :mod:`observers.{name}`.", ""]
        errata = getattr(mod, "ERRATA", None)
        if errata:
            out += _heading(f"{pid} errata", _H3, f"paper-{name}-errata") + _bullets(errata)
        decisions = getattr(mod, "DECISIONS", None)
        if decisions:
            out += (_heading(f"{pid} decisions", _H3, f"paper-{name}-decisions")
                    + _bullets(decisions))
        missing = getattr(mod, "NOT_REPRODUCED", None)
        if missing is not None:
            out += _heading(f"{pid} figures not reproduced", _H3, f"paper-{name}-not-reproduced")
            if isinstance(missing, Mapping) and missing:
                out += _bullets(f"{fig}: {why}" for fig, why in missing.items())
            elif isinstance(missing, Mapping):
                out += ["None: every figure of the paper is reproduced.", ""]
            else:
                out += _bullets(missing)
        cl = claims[name]
        out += _heading(f"{pid} claims", _H3, f"paper-{name}-claims")
        if cl:
            out += _claims_table(cl)
        else:
            out += ["No claims registered yet.", ""]
    return "\n".join(out) + "\n"


if __name__ == "__main__":      # python docs/_papers.py: print the page
    print(papers_rst())
