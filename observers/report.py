"""The main job's report: one static HTML page, ``index.html``, and ``claims.csv``.

``python -m observers reproduce --out results`` records each part it runs
(the engine demos and the five papers) as ``results/<name>/part.json`` (a
:class:`Part`) and then calls :func:`write_report`, which gathers every
part recorded in the folder and writes

* ``results/index.html``: one self-contained page (inline CSS, no script,
  images by relative path, so the folder can be copied or zipped as is): a
  summary table (papers, claims reproduced / differing / not as expected,
  figures, time), then per part its title, authors and venue, each figure
  with its caption (the ``.txt`` beside the PNG), the claims table with
  verdicts (in words and colour) and, for each claim, the function that
  computes it (``module:name``, linked to its source file and line), the
  errata found, the decisions taken, how long the figures and the claims
  took, and its console output;
* ``results/claims.csv``: every claim of every part
  (:data:`observers.claims.CSV_FIELDS`), linked from the page.

What a paper package does not define (``PAPER``, ``ERRATA``, ``DECISIONS``,
``CLAIMS``) is shown as missing on the page, never silently left out.

Examples
--------
>>> import pathlib, tempfile
>>> out = pathlib.Path(tempfile.mkdtemp())
>>> part = Part(name="demo", seconds=0.5, paper={"id": "999", "title": "A demo",
...             "authors": "A. Author", "venue": "Nowhere 2024"},
...             errata=["(3): the sign of the gain is wrong"], decisions=[])
>>> _ = part.save(out)
>>> page = write_report(out)
>>> page.name, (out / "claims.csv").exists()
('index.html', True)
"""
from __future__ import annotations

import dataclasses
import datetime
import html
import json
import os
import pathlib
import platform
import subprocess
import sys
import urllib.parse
from collections.abc import Iterable, Mapping

from .claims import CSV_FIELDS, PAPER_MODULES, write_csv

__all__ = [
    "PART_FILE",
    "PART_ORDER",
    "Part",
    "load_parts",
    "paper_metadata",
    "write_report",
]

#: Name of a part's record inside its folder.
PART_FILE = "part.json"

#: Order of the parts on the page (others follow alphabetically).
PART_ORDER = ["engine", *PAPER_MODULES]

_PAPER_KEYS = ("id", "title", "authors", "venue")


@dataclasses.dataclass
class Part:
    """What one part of the main job produced; saved as ``<out>/<name>/part.json``.

    Attributes
    ----------
    name : str
        ``"engine"`` or a paper package's module name.
    figures : list of str
        The PNGs, as paths relative to the output folder (posix).
    seconds : float
        Time of ``reproduce(outdir)`` (the figures).
    status : {"ok", "failed"}
    error : str
        The traceback when the part failed.
    paper : dict or None
        The package's ``PAPER`` (id, title, authors, venue); None when it
        defines none.
    errata, decisions : list of str or None
        The package's ``ERRATA`` and ``DECISIONS``; None when not defined.
    claims : list of dict or None
        One ``claims.csv`` row per claim evaluated
        (:meth:`observers.claims.ClaimResult.row`); None when not evaluated.
    claims_note : str
        Why ``claims`` is None (no ``CLAIMS``, ``--no-claims``), or a problem.
    claims_seconds : float
        Time of the claims' evaluation.
    problems : list of str
        Departures from the paper packages' contract (missing names or
        captions), shown on the page.
    not_reproduced : dict
        The package's ``NOT_REPRODUCED``: the paper's figures left out, each
        with the reason.
    log : str
        The part's console output.
    finished : str
        When the part finished (ISO 8601, local time).
    """

    name: str
    figures: list = dataclasses.field(default_factory=list)
    seconds: float = 0.0
    status: str = "ok"
    error: str = ""
    paper: dict | None = None
    errata: list | None = None
    decisions: list | None = None
    claims: list | None = None
    claims_note: str = ""
    claims_seconds: float = 0.0
    problems: list = dataclasses.field(default_factory=list)
    not_reproduced: dict = dataclasses.field(default_factory=dict)
    log: str = ""
    finished: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name or "/" in self.name:
            raise ValueError(f"Part: name must be a non-empty folder name, got {self.name!r}")
        if self.status not in ("ok", "failed"):
            raise ValueError(f"Part {self.name!r}: status must be 'ok' or 'failed', "
                             f"got {self.status!r}")
        if not self.finished:
            self.finished = datetime.datetime.now().isoformat(timespec="seconds")

    def save(self, outdir) -> pathlib.Path:
        """Write ``outdir/<name>/part.json`` (folder created) and return its path."""
        d = pathlib.Path(outdir) / self.name
        d.mkdir(parents=True, exist_ok=True)
        path = d / PART_FILE
        path.write_text(json.dumps(dataclasses.asdict(self), indent=1, default=_jsonable),
                        encoding="utf-8")
        return path

    @classmethod
    def load(cls, path) -> Part:
        """Read a ``part.json``; ValueError naming the file when it is not one."""
        path = pathlib.Path(path)
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            fields = {f.name for f in dataclasses.fields(cls)}
            return cls(**{k: v for k, v in data.items() if k in fields})
        except (OSError, ValueError, TypeError) as exc:
            raise ValueError(f"{path} is not a readable part record: {exc}") from exc

    @property
    def counts(self) -> dict:
        """Claims by outcome: ``reproduced``, ``differs``, ``error``, ``failed``
        (not as expected), ``total``."""
        rows = self.claims or []
        return {"total": len(rows),
                "reproduced": sum(r["verdict"] == "reproduced" for r in rows),
                "differs": sum(r["verdict"] == "differs" for r in rows),
                "error": sum(r["verdict"] == "error" for r in rows),
                "failed": sum(not r["passed"] for r in rows)}


def _jsonable(v):
    if isinstance(v, pathlib.PurePath):
        return v.as_posix()
    try:
        return float(v)
    except (TypeError, ValueError):
        return str(v)


def paper_metadata(module) -> dict:
    """A paper package's ``PAPER``, ``ERRATA``, ``DECISIONS`` and the problems found.

    Parameters
    ----------
    module : module
        A paper package (e.g. ``observers.li_sanfelice``).

    Returns
    -------
    dict
        ``paper`` (dict or None), ``errata``, ``decisions`` (list of str or
        None when the package does not define them) and ``problems`` (list
        of str: each missing or malformed name, said in words).

    Examples
    --------
    >>> import types
    >>> m = types.ModuleType("observers.fake")
    >>> m.PAPER = {"id": "999", "title": "T", "authors": "A", "venue": "V"}
    >>> for problem in paper_metadata(m)["problems"]:
    ...     print(problem)
    observers.fake defines no ERRATA (shown as none)
    observers.fake defines no DECISIONS (shown as none)
    """
    name = module.__name__
    problems = []
    paper = getattr(module, "PAPER", None)
    if paper is None:
        problems.append(f"{name} defines no PAPER (title, authors and venue unknown)")
    elif not isinstance(paper, Mapping):
        problems.append(f"{name}.PAPER must be a dict, got {type(paper).__name__}")
        paper = None
    else:
        paper = {str(k): (", ".join(map(str, v)) if isinstance(v, (list, tuple)) else str(v))
                 for k, v in paper.items()}
        missing = [k for k in _PAPER_KEYS if not paper.get(k)]
        if missing:
            problems.append(f"{name}.PAPER lacks {', '.join(missing)}")
    out = {"paper": paper, "problems": problems}
    for key in ("ERRATA", "DECISIONS"):
        items = getattr(module, key, None)
        if items is None:
            problems.append(f"{name} defines no {key} (shown as none)")
        elif isinstance(items, (str, bytes)) or not isinstance(items, Iterable):
            problems.append(f"{name}.{key} must be a list of str, got {type(items).__name__}")
            items = None
        else:
            items = [str(s) for s in items]
        out[key.lower()] = items
    return out


def load_parts(outdir) -> list[Part]:
    """Every part recorded under ``outdir`` (``*/part.json``), in page order.

    A record that cannot be read becomes a failed part saying so.
    """
    outdir = pathlib.Path(outdir)
    parts = []
    for path in sorted(outdir.glob(f"*/{PART_FILE}")):
        try:
            parts.append(Part.load(path))
        except ValueError as exc:
            parts.append(Part(name=path.parent.name, status="failed", error=str(exc)))
    rank = {n: k for k, n in enumerate(PART_ORDER)}
    return sorted(parts, key=lambda p: (rank.get(p.name, len(rank)), p.name))


# --------------------------------------------------------------------- HTML --

_CSS = """
body { font: 15px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif;
       color: #1b1b1b; background: #fff; margin: 0 auto; max-width: 1150px;
       padding: 1.2em 2em 4em; }
h1 { font-size: 1.7em; margin-bottom: .2em; }
h2 { font-size: 1.35em; border-bottom: 2px solid #d0d4da; padding-bottom: .2em; margin-top: 2.4em; }
h3 { font-size: 1.1em; margin-top: 1.6em; }
a { color: #0b57a4; }
.meta { color: #555; font-size: .92em; }
table { border-collapse: collapse; margin: .6em 0 1em; font-size: .9em; width: 100%; }
th, td { border: 1px solid #c9ced6; padding: .3em .5em; vertical-align: top; text-align: left; }
th { background: #eef1f5; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.why, td.reason { color: #444; font-size: .92em; }
.verdict { font-weight: 600; white-space: nowrap; }
.v-reproduced { background: #dff3e1; color: #155d22; }
.v-differs { background: #fff1cc; color: #6b4a00; }
.v-error { background: #fbdada; color: #8a1111; }
.problem { color: #8a1111; font-weight: 600; }
td.reason, td.why { overflow-wrap: anywhere; }
.wide { overflow-x: auto; }
table.claims { min-width: 70em; }
td.statement { min-width: 18em; max-width: 32em; white-space: normal; overflow-wrap: break-word;
               hyphens: auto; }
td.code { min-width: 10em; max-width: 16em; font-size: .88em; }
td.code code.fn { overflow-wrap: anywhere; }
.ok { color: #155d22; font-weight: 600; white-space: nowrap; }
.bad { background: #fbdada; color: #8a1111; font-weight: 700; white-space: nowrap; }
tr.notpassed td:first-child { border-left: 5px solid #c62828; }
.status-ok { color: #155d22; font-weight: 600; }
.status-failed { color: #fff; background: #c62828; padding: 0 .4em; font-weight: 700; }
.warn { background: #fff7e0; border-left: 5px solid #e0a800; padding: .4em .8em; margin: .6em 0; }
.fail { background: #fdecec; border-left: 5px solid #c62828; padding: .4em .8em; margin: .6em 0; }
figure { margin: 1.2em 0 2em; }
figure img { max-width: 100%; height: auto; border: 1px solid #e1e4e8; display: block; }
figcaption { font-size: .92em; color: #333; margin-top: .4em; max-width: 75em; }
figcaption .fname { font-family: ui-monospace, monospace; color: #666; }
pre { background: #f6f8fa; padding: .6em; overflow-x: auto; font-size: .85em;
      white-space: pre-wrap; }
nav ol { columns: 2; }
code { font-family: ui-monospace, monospace; font-size: .92em; }
@media print { body { max-width: none; } figure { break-inside: avoid; } }
"""


def _e(s) -> str:
    return html.escape("" if s is None else str(s), quote=True)


def _num(v, none="—") -> str:
    if v is None:
        return none
    v = float(v)
    if v != v:
        return "nan"
    return f"{v:.7g}"


def _secs(s) -> str:
    s = float(s or 0.0)
    return f"{s:.1f} s" if s < 600 else f"{s / 60:.1f} min"


def _href(path: str) -> str:
    return urllib.parse.quote(path, safe="/")


def _heading(part: Part) -> str:
    if part.name == "engine":
        return "Engine demos (hybridsim)"
    p = part.paper or {}
    ident = p.get("id") or PAPER_MODULES.get(part.name, "")
    title = p.get("title") or f"observers.{part.name} (no PAPER defined)"
    return f"{ident} — {title}" if ident else title


def _environment() -> list[tuple[str, str]]:
    env = [("Python", platform.python_version()), ("platform", platform.platform())]
    for mod in ("numpy", "scipy", "matplotlib", "hybridsim"):
        m = sys.modules.get(mod)
        if m is None:
            try:
                m = __import__(mod)
            except ImportError:
                continue
        env.append((mod, getattr(m, "__version__", "?")))
    try:
        root = pathlib.Path(__file__).resolve().parent.parent
        rev = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, timeout=5)
        if rev.returncode == 0 and rev.stdout.strip():
            env.append(("git commit", rev.stdout.strip()))
    except (OSError, subprocess.SubprocessError):
        pass
    env.append(("CPU cores", str(os.cpu_count())))
    return env


def _summary(parts: list[Part]) -> list[str]:
    h = ['<table class="summary">', "<thead><tr><th>part</th><th>paper</th><th>status</th>"
         "<th>figures</th><th>claims</th><th>reproduced</th><th>differs</th>"
         "<th>not as expected</th><th>errata</th><th>time (figures + claims)</th>"
         "</tr></thead>", "<tbody>"]
    tot = {"figures": 0, "total": 0, "reproduced": 0, "differs": 0, "failed": 0,
           "errata": 0, "seconds": 0.0}
    for p in parts:
        c = p.counts
        claims_cell = str(c["total"]) if p.claims is not None else "—"
        errata = "—" if p.errata is None else str(len(p.errata))
        if p.name == "engine":
            errata = ""
        failed = (f'<span class="bad">✗ {c["failed"]}</span>' if c["failed"]
                  else ('<span class="ok">0</span>' if p.claims is not None else "—"))
        status = ('<span class="status-ok">ok</span>' if p.status == "ok"
                  else '<span class="status-failed">FAILED</span>')
        secs = p.seconds + p.claims_seconds
        h.append(f'<tr><td><a href="#{_e(p.name)}"><code>{_e(p.name)}</code></a></td>'
                 f"<td>{_e(_heading(p))}</td><td>{status}</td>"
                 f'<td class="num">{len(p.figures)}</td><td class="num">{claims_cell}</td>'
                 f'<td class="num">{c["reproduced"] if p.claims is not None else "—"}</td>'
                 f'<td class="num">{c["differs"] if p.claims is not None else "—"}</td>'
                 f'<td class="num">{failed}</td><td class="num">{errata}</td>'
                 f'<td class="num">{_secs(p.seconds)}'
                 f'{" + " + _secs(p.claims_seconds) if p.claims is not None else ""}</td></tr>')
        tot["figures"] += len(p.figures)
        for k in ("total", "reproduced", "differs", "failed"):
            tot[k] += c[k]
        tot["errata"] += len(p.errata or [])
        tot["seconds"] += secs
    nfail = sum(p.status != "ok" for p in parts)
    h.append("</tbody><tfoot>")
    h.append(f"<tr><th>all</th><th>{len(parts)} part(s)</th>"
             f"<th>{'all ok' if not nfail else f'{nfail} failed'}</th>"
             f'<th class="num">{tot["figures"]}</th><th class="num">{tot["total"]}</th>'
             f'<th class="num">{tot["reproduced"]}</th><th class="num">{tot["differs"]}</th>'
             f'<th class="num">{tot["failed"]}</th><th class="num">{tot["errata"]}</th>'
             f'<th class="num">{_secs(tot["seconds"])}</th></tr>')
    h.append("</tfoot></table>")
    return h


def _code_cell(code, outdir: pathlib.Path) -> str:
    """The function computing a claim (``module:name``), linked to its source
    file by a path relative to the page (the folder's own copy of the page
    keeps working where the checkout is), with the line it starts on."""
    if not code:
        return '<span class="meta">not recorded</span>'
    name = f'<code class="fn">{_e(code.get("function", "?"))}</code>'
    file, line = code.get("file"), code.get("line")
    if not file:
        return name
    try:
        rel = pathlib.Path(os.path.relpath(file, outdir.resolve())).as_posix()
        href = _href(rel)
    except ValueError:                    # another drive: an absolute file URI
        href = pathlib.Path(file).as_uri()
    where = f"{pathlib.Path(file).name}" + (f", line {line}" if line else "")
    anchor = f"#L{line}" if line else ""
    return f'<a href="{_e(href + anchor)}">{name}</a><br><span class="meta">{_e(where)}</span>'


def _claims_table(rows: list[dict], outdir: pathlib.Path) -> list[str]:
    h = ['<div class="wide"><table class="claims">', "<thead><tr><th>claim</th><th>where</th>"
         "<th>statement</th><th>computed by</th><th>paper's value</th><th>our value</th>"
         "<th>tolerance</th><th>verdict</th>"
         "<th>expected</th><th>check</th><th>reason / note</th><th>time</th></tr></thead>",
         "<tbody>"]
    for r in rows:
        verdict = r["verdict"]
        rel = {"<=": "≤ ", ">=": "≥ "}.get(r.get("relation", "=="), "")
        paper_v = (rel + _num(r["paper_value"])) if r["paper_value"] is not None \
            else "none printed"
        ours = _num(r["our_value"])
        if r.get("boolean"):
            ours = "yes" if r["our_value"] == 1.0 else "no"
            target = r["paper_value"] if r["paper_value"] is not None else r.get("reference")
            paper_v = ("yes" if target == 1.0 else "no") + (
                "" if r["paper_value"] is not None else " (reference)")
        if r.get("reference") is not None and not r.get("boolean"):
            paper_v += f'<br><span class="meta">reference {_e(_num(r["reference"]))}</span>'
        check = ('<span class="ok">✓ as expected</span>' if r["passed"]
                 else '<span class="bad">✗ NOT as expected</span>')
        note = _e(r.get("reason", ""))
        if r.get("error"):
            note += (("<br>" if note else "") + f'<span class="problem">{_e(r["error"])}</span>')
        h.append(f'<tr class="{"passed" if r["passed"] else "notpassed"}">'
                 f'<td><code>{_e(r["id"])}</code></td><td>{_e(r["where"])}</td>'
                 f'<td class="statement">{_e(r["statement"])}</td>'
                 f'<td class="code">{_code_cell(r.get("code"), outdir)}</td>'
                 f'<td class="num">{paper_v}</td>'
                 f'<td class="num">{_e(ours)}</td>'
                 f'<td class="why"><span class="num">± {_e(_num(r["tol"]))}</span><br>'
                 f'{_e(r["tol_why"])}</td>'
                 f'<td class="verdict v-{_e(verdict)}">{_e(verdict)}</td>'
                 f'<td>{_e(r["expected"])}</td><td>{check}</td>'
                 f'<td class="reason">{note}</td>'
                 f'<td class="num">{_e(_secs(r["seconds"]))}</td></tr>')
    h.append("</tbody></table></div>")
    return h


def _falsification(outdir: pathlib.Path, part: Part) -> list[str]:
    """The part's falsification problems, if ``python -m observers falsify`` ran."""
    path = outdir / part.name / "falsification.json"
    if not path.is_file():
        return []
    try:
        rows = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        return [f'<p class="fail">{_e(path.name)} cannot be read: {_e(exc)}</p>']
    if not rows:
        return []
    h = ["<h3>Falsification: searches for counterexamples</h3>",
         '<p class="meta">Each statement searched over its hypotheses by differential '
         "evolution (whole populations per run), beside random sampling with the same "
         "budget; a margin below 0 is a counterexample. Expected: a counterexample for the "
         "statements as printed where the paper errs, none for the corrected ones. The main "
         "job searches the statements expected to fail; <code>python -m observers falsify"
         "</code> runs every problem.</p>",
         '<table class="falsification"><thead><tr><th>problem</th><th>where</th>'
         "<th>statement</th><th>space</th><th>budget</th><th>expected</th><th>found</th>"
         "<th>worst margin</th><th>random sampling</th><th>check</th></tr></thead><tbody>"]
    figures = []
    for r in rows:
        if r.get("error"):
            h.append(f'<tr class="notpassed"><td><code>{_e(r.get("id"))}</code></td>'
                     f'<td colspan="9"><pre>{_e(r["error"])}</pre></td></tr>')
            continue
        check = ('<span class="ok">✓ as expected</span>' if r.get("passed")
                 else '<span class="bad">✗ NOT as expected</span>')
        found = r.get("found", "")
        cls = "v-differs" if found == "counterexample" else "v-reproduced"
        h.append(f'<tr class="{"passed" if r.get("passed") else "notpassed"}">'
                 f'<td><code>{_e(r["id"])}</code></td><td>{_e(r["where"])}</td>'
                 f'<td class="statement">{_e(r["statement"])}<br><span class="meta">'
                 f'{_e(r.get("reason", ""))}</span></td>'
                 f'<td class="why"><code>{_e(r.get("space", ""))}</code></td>'
                 f'<td class="num">{_e(r.get("budget", ""))}</td><td>{_e(r["expect"])}</td>'
                 f'<td class="verdict {cls}">{_e(found)}</td>'
                 f'<td class="num">{_e(_num(r.get("margin")))}<br><span class="meta">'
                 f'{_e(r.get("evaluations", ""))} runs, {_e(_secs(r.get("seconds")))}'
                 f'{"; found by " + _e(r["found_by"]) if r.get("found_by") else ""}'
                 f'</span></td>'
                 f'<td class="num">{_e(_num(r.get("baseline_margin")))}<br>'
                 f'<span class="meta">{_e(r.get("baseline_evaluations", ""))} runs, '
                 f'{_e(_secs(r.get("baseline_seconds")))}</span></td>'
                 f"<td>{check}</td></tr>")
        if r.get("figure"):
            figures.append(r["figure"])
    h.append("</tbody></table>")
    for rel in figures:
        png = outdir / rel
        if not png.is_file():
            continue
        txt = png.with_suffix(".txt")
        cap = _e(txt.read_text(encoding="utf-8").strip()) if txt.is_file() else ""
        h.append(f'<figure><a href="{_href(rel)}"><img src="{_href(rel)}" '
                 f'alt="{_e("worst run of " + pathlib.PurePosixPath(rel).stem)}"></a>'
                 f"<figcaption>{cap}</figcaption></figure>")
    return h


def _items(title: str, items, what: str, engine: bool) -> list[str]:
    if engine:
        return []
    h = [f"<h3>{_e(title)}</h3>"]
    if items is None:
        h.append(f'<p class="warn">The package defines no <code>{_e(what)}</code>: '
                 "none listed here, which is not the same as none found.</p>")
    elif not items:
        h.append("<p>None.</p>")
    else:
        h.append("<ol>" + "".join(f"<li>{_e(s)}</li>" for s in items) + "</ol>")
    return h


def _section(part: Part, outdir: pathlib.Path) -> list[str]:
    engine = part.name == "engine"
    h = [f'<section id="{_e(part.name)}">', f"<h2>{_e(_heading(part))}</h2>"]
    p = part.paper or {}
    if p.get("authors"):
        h.append(f'<p class="authors">{_e(p["authors"])}</p>')
    if p.get("venue"):
        h.append(f'<p class="meta venue"><em>{_e(p["venue"])}</em></p>')
    for key in ("doi", "url"):
        link = p.get(key, "")
        if key == "doi" and link and not link.startswith("http"):
            link = "https://doi.org/" + link
        if link.startswith(("https://", "http://")):
            h.append(f'<p class="meta"><a href="{_e(link)}">{_e(link)}</a></p>')
    status = ('<span class="status-ok">ok</span>' if part.status == "ok"
              else '<span class="status-failed">FAILED</span>')
    if part.claims is not None:
        claims_t = f" · claims {_secs(part.claims_seconds)}"
    else:
        claims_t = "" if engine else " · no claims evaluated"
    module = "observers.reproduce" if engine else f"observers.{part.name}"
    h.append(f'<p class="meta">module <code>{_e(module)}</code>'
             f" · status {status} · figures {_secs(part.seconds)}{claims_t} · "
             f"run {_e(part.finished)}</p>")
    if part.status != "ok":
        h.append(f'<div class="fail"><strong>This part failed.</strong>'
                 f"<pre>{_e(part.error)}</pre></div>")
    if part.problems:
        h.append('<div class="warn"><strong>Missing from the package:</strong><ul>'
                 + "".join(f"<li>{_e(s)}</li>" for s in part.problems) + "</ul></div>")
    h.append(f"<h3>Figures ({len(part.figures)})</h3>")
    if not part.figures:
        h.append("<p>No figures.</p>")
    if part.not_reproduced:
        h.append('<div class="warn notreproduced"><strong>Not reproduced:</strong><ul>'
                 + "".join(f"<li><strong>{_e(k)}</strong>: {_e(v)}</li>"
                           for k, v in part.not_reproduced.items()) + "</ul></div>")
    for rel in part.figures:
        png = outdir / rel
        txt = png.with_suffix(".txt")
        if not png.is_file():
            h.append(f'<p class="fail">Figure <code>{_e(rel)}</code> is missing.</p>')
            continue
        if txt.is_file():
            cap = _e(txt.read_text(encoding="utf-8", errors="replace").strip())
        else:
            cap = '<span class="bad">no caption (.txt missing)</span>'
        alt = _e(f"figure {pathlib.PurePosixPath(rel).name} of {_heading(part)}")
        h.append(f'<figure><a href="{_href(rel)}"><img src="{_href(rel)}" alt="{alt}"></a>'
                 f'<figcaption><span class="fname">{_e(pathlib.PurePosixPath(rel).name)}'
                 f"</span> — {cap}</figcaption></figure>")
    if not engine or part.claims:
        h.append("<h3>Claims</h3>")
        if part.claims is None:
            note = part.claims_note or "not evaluated"
            h.append(f'<p class="warn">No claims table: {_e(note)}.</p>')
        elif not part.claims:
            h.append("<p>The registry is empty.</p>")
        else:
            c = part.counts
            h.append(f"<p>{c['reproduced']} reproduced, {c['differs']} differ"
                     f"{', ' + str(c['error']) + ' could not be evaluated' if c['error'] else ''}"
                     f"; {c['total'] - c['failed']} of {c['total']} as expected.</p>")
            h += _claims_table(part.claims, outdir)
    h += _falsification(outdir, part)
    h += _items("Errata found", part.errata, "ERRATA", engine)
    h += _items("Decisions taken where the paper is ambiguous", part.decisions, "DECISIONS",
                engine)
    if part.log.strip():
        n = part.log.count("\n") + (not part.log.endswith("\n"))
        h.append(f"<details><summary>console output ({n} lines)</summary>"
                 f"<pre>{_e(part.log)}</pre></details>")
    h.append("</section>")
    return h


def write_report(outdir, parts: list[Part] | None = None, *,
                 title: str = "hybridsim observers: reproduction report",
                 command: str | None = None) -> pathlib.Path:
    """Write ``outdir/index.html`` and ``outdir/claims.csv``.

    Parameters
    ----------
    outdir : str or pathlib.Path
        The main job's output folder (must exist).
    parts : list of Part, optional
        Default: every part recorded in ``outdir`` (:func:`load_parts`).
    title : str
        The page's title.
    command : str, optional
        The command that produced the results, shown on the page.

    Returns
    -------
    pathlib.Path
        The page.

    Raises
    ------
    NotADirectoryError
        ``outdir`` is not a folder.
    """
    outdir = pathlib.Path(outdir)
    if not outdir.is_dir():
        raise NotADirectoryError(f"outdir must be an existing folder, got {str(outdir)!r}")
    if parts is None:
        parts = load_parts(outdir)
    for k, p in enumerate(parts):
        if not isinstance(p, Part):
            raise TypeError(f"parts[{k}] must be an observers.report.Part, "
                            f"got {type(p).__name__}")
    rows = [r for p in parts for r in (p.claims or [])]
    csv_path = write_csv(rows, outdir / "claims.csv")
    now = datetime.datetime.now().isoformat(timespec="seconds")
    h = ["<!DOCTYPE html>", '<html lang="en">', "<head>", '<meta charset="utf-8">',
         '<meta name="viewport" content="width=device-width, initial-scale=1">',
         f"<title>{_e(title)}</title>", f"<style>{_CSS}</style>", "</head>", "<body>",
         f"<h1>{_e(title)}</h1>",
         f'<p class="meta">Written {_e(now)}'
         + (f" after <code>{_e(command)}</code>" if command else "") + ", from the "
         f"{len(parts)} part(s) recorded in this folder (each section says when it ran). "
         f'All claims with their values: <a href="{_href(csv_path.name)}">'
         f"{_e(csv_path.name)}</a> ({len(rows)} rows, columns "
         f"{_e(', '.join(CSV_FIELDS))}).</p>",
         "<h2>Summary</h2>"]
    h += _summary(parts)
    h.append(
        "<p class=\"meta\">How to read the claims: a claim is <strong>reproduced</strong> when "
        "our value is within its tolerance of the paper's printed value (or, where the paper "
        "prints none, of an independently derived reference), and <strong>differs</strong> "
        "otherwise; <strong>error</strong> means it could not be computed. <em>Check</em> says "
        "whether the verdict is the one expected: an expected difference comes with its "
        "documented reason (an erratum or decision), and is pinned to the corrected reference "
        "value. The tolerance column says why each tolerance was chosen.</p>")
    if parts:
        h.append("<nav><ol>" + "".join(f'<li><a href="#{_e(p.name)}">{_e(_heading(p))}</a>'
                                       "</li>" for p in parts) + "</ol></nav>")
    else:
        h.append('<p class="warn">No parts recorded in this folder.</p>')
    for p in parts:
        h += _section(p, outdir)
    env = "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in _environment())
    h += ["<h2>Environment</h2>", f'<table class="env"><tbody>{env}</tbody></table>',
          "</body>", "</html>", ""]
    page = outdir / "index.html"
    page.write_text("\n".join(h), encoding="utf-8")
    return page
