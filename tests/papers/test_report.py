"""The main job's report (observers.report, observers.reproduce): a synthetic
output folder (matplotlib PNGs, captions, claims) made into index.html, its
structure read back with html.parser, and the page opened in headless
Chromium to check that every image loads and every table renders.

Fake paper packages stand in for the real ones (put in ``sys.modules`` under
the real names for one test), so no paper's simulation runs here.
"""
import html
import html.parser
import json
import pathlib
import re
import shutil
import subprocess
import sys
import types

import pytest

from observers import reproduce as rp
from observers.claims import Claim, read_csv, run_claims
from observers.report import Part, load_parts, paper_metadata, write_report

EVIL = '<script>alert("x")</script> & a<b'


def _png(path, label):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0, 1, 2], [0, 1, 0], label=label)
    ax.legend()
    fig.savefig(path, dpi=60)
    plt.close(fig)
    return path


def _claims(paper):
    def c(cid, **kw):
        base = dict(id=f"{paper}-{cid}", paper=paper, where="(1)", statement=f"claim {cid}",
                    paper_value=1.0, compute=lambda: 1.0, tol=1e-3, tol_why="3 decimals")
        base.update(kw)
        return Claim(**base)
    return [c("ok"),
            c("erratum", where="(39)", paper_value=2.0, expected="differs",
              reason=f"erratum: (39) has a factor 2 {EVIL}", reference=1.0),
            c("none-printed", paper_value=None, reference=0.0, compute=lambda: 1e-12, tol=1e-10,
              statement=f"the error vanishes {EVIL}"),
            c("broken", compute=lambda: 1.5),
            c("raises", compute=lambda: 1 / 0)]


@pytest.fixture
def outdir(tmp_path):
    """A folder as the main job leaves it: three parts, one with everything, one
    with nothing but a figure, one failed."""
    out = tmp_path / "results"
    (out / "li_sanfelice").mkdir(parents=True)
    figs = []
    for k in range(2):
        png = _png(out / "li_sanfelice" / f"fig{k + 1}.png", f"curve {k}")
        png.with_suffix(".txt").write_text(f"Figure {k + 1}: caption {EVIL}\n")
        figs.append(f"li_sanfelice/fig{k + 1}.png")
    rows = [r.row() for r in run_claims(_claims("002"))]
    Part(name="li_sanfelice", figures=figs, seconds=12.5, claims=rows, claims_seconds=0.25,
         paper={"id": "002", "title": f"A robust observer {EVIL}", "authors": "Li & Sanfelice",
                "venue": "Automatica"},
         errata=[f"(39): A2 xi2 must read A2 xi1 {EVIL}"], decisions=["delta = 1 (Sec. V.A)"],
         log=f"[li_sanfelice] done {EVIL}\n").save(out)
    (out / "gramian_delay").mkdir()
    _png(out / "gramian_delay" / "only.png", "x")        # its caption is missing on purpose
    meta = paper_metadata(types.ModuleType("observers.gramian_delay"))
    Part(name="gramian_delay", figures=["gramian_delay/only.png"], seconds=3.0,
         problems=meta["problems"], claims_note="observers.gramian_delay defines no CLAIMS yet",
         **{k: meta[k] for k in ("paper", "errata", "decisions")}).save(out)
    Part(name="time_varying", status="failed", error=f"Traceback ...\nValueError: {EVIL}",
         paper={"id": "001", "title": "Reduced order", "authors": "M", "venue": "CDC"},
         errata=[], decisions=[], claims=[]).save(out)
    return out


class _Page(html.parser.HTMLParser):
    """Images, links, tables (head cells, body rows of cells with their classes), sections."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.imgs, self.links, self.tables, self.tags = [], [], [], []
        self.section = None
        self._cell = None
        self._where = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        if tag == "section":
            self.section = a.get("id")
        elif tag == "img":
            self.imgs.append(a)
        elif tag == "a":
            self.links.append(a.get("href"))
        elif tag == "table":
            self.tables.append({"class": a.get("class"), "section": self.section, "head": [],
                                "rows": [], "foot": []})
        elif tag in ("thead", "tbody", "tfoot"):
            self._where = tag
        elif tag == "tr" and self.tables:
            t = self.tables[-1]
            {"thead": t["head"], "tbody": t["rows"], "tfoot": t["foot"]}[self._where].append([])
        elif tag in ("td", "th"):
            self._cell = {"tag": tag, "class": a.get("class", ""), "text": ""}

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            t = self.tables[-1]
            target = {"thead": t["head"], "tbody": t["rows"], "tfoot": t["foot"]}[self._where]
            target[-1].append(self._cell)
            self._cell = None
        elif tag == "section":
            self.section = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell["text"] += data


def _parse(page):
    p = _Page()
    p.feed(page.read_text(encoding="utf-8"))
    p.close()
    return p


def test_page_structure(outdir):
    page = write_report(outdir, command="python -m observers reproduce --out results")
    assert page == outdir / "index.html"
    text = page.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    assert "<script" not in text and EVIL not in text          # no script; all text escaped
    assert html.escape(EVIL) in text
    p = _parse(page)
    # every image is a PNG inside the folder, by relative path
    assert len(p.imgs) == 3
    for img in p.imgs:
        src = img["src"]
        assert not src.startswith(("/", "file:", "http")), src
        f = outdir / src
        assert f.is_file() and f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert img.get("alt")
    # every table: a header row, body rows as wide as the header
    assert p.tables
    for t in p.tables:
        if t["class"] == "env":
            continue
        assert len(t["head"]) == 1 and t["head"][0], t["class"]
        width = len(t["head"][0])
        assert t["rows"] and all(len(r) == width for r in t["rows"] + t["foot"]), t["class"]
    # the summary: one row per part, in page order, with its counts
    summary = next(t for t in p.tables if t["class"] == "summary")
    head = [c["text"] for c in summary["head"][0]]
    col = {name: head.index(name) for name in head}
    body = {r[0]["text"]: [c["text"] for c in r] for r in summary["rows"]}
    assert list(body) == ["li_sanfelice", "gramian_delay", "time_varying"]
    ls = body["li_sanfelice"]
    assert (ls[col["figures"]], ls[col["claims"]], ls[col["reproduced"]],
            ls[col["differs"]]) == ("2", "5", "2", "2")
    assert ls[col["not as expected"]] == "✗ 2" and ls[col["errata"]] == "1"
    assert body["gramian_delay"][col["claims"]] == "—"
    assert body["time_varying"][col["status"]] == "FAILED"
    total = [c["text"] for c in summary["foot"][0]]
    assert total[col["figures"]] == "3" and total[col["claims"]] == "5"
    # the claims table matches the claims, row by row
    claims = [t for t in p.tables if t["class"] == "claims"]
    assert [t["section"] for t in claims] == ["li_sanfelice"]
    rows = read_csv(outdir / "claims.csv")
    head = [c["text"] for c in claims[0]["head"][0]]
    assert len(claims[0]["rows"]) == len(rows) == 5
    for cells, row in zip(claims[0]["rows"], rows, strict=True):
        got = dict(zip(head, cells, strict=True))
        assert got["claim"]["text"] == row["id"]
        assert got["where"]["text"] == row["where"]
        assert got["statement"]["text"] == row["statement"]
        verdict = got["verdict"]
        assert verdict["text"] == row["verdict"]                       # in words ...
        assert f"v-{row['verdict']}" in verdict["class"].split()       # ... and in colour
        assert got["check"]["text"] == ("✓ as expected" if row["passed"]
                                        else "✗ NOT as expected")
    # each claim names the function computing it, linked to its source file and line
    page_links = [h for h in p.links if h and "#L" in h]
    assert len(page_links) == 5
    for cells, link in zip(claims[0]["rows"], page_links, strict=True):
        got = dict(zip(head, cells, strict=True))["computed by"]
        assert got["class"] == "code"
        assert got["text"].startswith(f"{_claims.__module__}:_claims.<locals>.")
        target, line = link.split("#L")
        assert (outdir / target).resolve() == pathlib.Path(__file__).resolve()
        assert f"test_report.py, line {line}" in got["text"]
        assert "compute=" in pathlib.Path(__file__).read_text().splitlines()[int(line) - 1] \
            or "def c(" in pathlib.Path(__file__).read_text().splitlines()[int(line) - 1]
    # the statements wrap in a column of readable width; a wide table scrolls
    assert re.search(r"td\.statement \{[^}]*min-width: 18em;[^}]*white-space: normal", text)
    assert '<div class="wide"><table class="claims">' in text
    paper_cells = [dict(zip(head, c, strict=True))["paper's value"]["text"]
                   for c in claims[0]["rows"]]
    assert paper_cells[2].startswith("none printed") and "reference 0" in paper_cells[2]
    assert "claims.csv" in p.links
    # missing names and the failure are said on the page
    assert "observers.gramian_delay defines no PAPER" in text
    assert "The package defines no <code>ERRATA</code>" in text
    assert "only.png has no caption" not in text        # problems come from run_part ...
    assert "no caption (.txt missing)" in text          # ... the page flags it itself
    assert "This part failed." in text and html.escape(f"ValueError: {EVIL}") in text


def test_claims_csv_gathers_every_part(outdir):
    write_report(outdir)
    rows = read_csv(outdir / "claims.csv")
    assert [r["id"] for r in rows] == [f"002-{k}" for k in
                                       ("ok", "erratum", "none-printed", "broken", "raises")]
    assert [r["passed"] for r in rows] == [True, True, True, False, False]


def test_load_parts_orders_and_survives_a_damaged_record(outdir):
    (outdir / "engine").mkdir()
    (outdir / "engine" / "part.json").write_text("{not json")
    (outdir / "zzz").mkdir()
    Part(name="zzz").save(outdir)
    names = [p.name for p in load_parts(outdir)]
    assert names == ["engine", "li_sanfelice", "gramian_delay", "time_varying", "zzz"]
    engine = load_parts(outdir)[0]
    assert engine.status == "failed" and "not a readable part record" in engine.error
    page = write_report(outdir)
    assert "not a readable part record" in page.read_text()


def test_bad_arguments_are_named(tmp_path):
    with pytest.raises(NotADirectoryError, match="outdir must be an existing folder"):
        write_report(tmp_path / "nope")
    with pytest.raises(TypeError, match=r"parts\[0\] must be an observers.report.Part, got dict"):
        write_report(tmp_path, [{"name": "x"}])
    with pytest.raises(ValueError, match="status must be 'ok' or 'failed'"):
        Part(name="x", status="done")
    with pytest.raises(ValueError, match="name must be a non-empty folder name"):
        Part(name="a/b")
    with pytest.raises(ValueError, match="name must be one of"):
        rp.run_part("nope", tmp_path)


@pytest.mark.parametrize("cmd, names", [("reproduce", rp.PAPERS),
                                         ("falsify", rp.PAPER_MODULES)])
def test_command_line_help_lists_each_name_once_and_no_empty_choice(cmd, names, capsys):
    with pytest.raises(SystemExit) as exit_:
        rp.main([cmd, "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert "[]" not in out and ",}" not in out and "{" not in out
    listed = " ".join(out.split())               # argparse wraps the help text
    assert f"{', '.join(names)} (default: all)" in listed
    with pytest.raises(SystemExit) as exit_:
        rp.main([cmd, "nope"])
    assert exit_.value.code == 2
    assert "invalid choice: 'nope' (choose from " in capsys.readouterr().err


# ------------------------------------------------ the runner, on fake papers --

def _fake(name, *, reproduce, paper=True, claims=True):
    mod = types.ModuleType(f"observers.{name}")
    pid = rp.PAPER_MODULES[name]
    if paper:
        mod.PAPER = {"id": pid, "title": f"Paper {pid}", "authors": "A. B", "venue": "V"}
        mod.ERRATA = ["(1): sign"]
        mod.DECISIONS = []
    if claims:
        mod.CLAIMS = [Claim(id=f"{pid}-a", paper=pid, where="(1)", statement="s",
                            paper_value=1.0, compute=lambda: 1.0, tol=0.0, tol_why="exact")]
    mod.reproduce = reproduce
    return mod


def _good(outdir):
    png = _png(pathlib.Path(outdir) / "f.png", "f")
    png.with_suffix(".txt").write_text("caption\n")
    print("made f.png")
    return [png]


def _nocaption(outdir):
    return [_png(pathlib.Path(outdir) / "g.png", "g")]


def _raises(outdir):
    raise RuntimeError("figure code broke")


def test_main_runs_parts_records_them_and_reports(tmp_path, monkeypatch, capsys):
    fakes = {"li_sanfelice": _fake("li_sanfelice", reproduce=_good),
             "gramian_delay": _fake("gramian_delay", reproduce=_raises),
             "time_varying": _fake("time_varying", reproduce=_nocaption, paper=False,
                                   claims=False),
             "dynamic_gain": _fake("dynamic_gain", reproduce=lambda d: str(d))}
    for name, mod in fakes.items():
        monkeypatch.setitem(sys.modules, f"observers.{name}", mod)
    out = tmp_path / "out"
    rc = rp.main(["reproduce", *fakes, "--out", str(out)])
    assert rc == 1                                   # two parts failed, the others ran
    captured = capsys.readouterr()
    assert "failed: gramian_delay, dynamic_gain" in captured.err
    assert f"report: {(out / 'index.html').resolve()}" in captured.out
    parts = {p.name: p for p in load_parts(out)}
    assert list(parts) == ["li_sanfelice", "gramian_delay", "time_varying", "dynamic_gain"]
    good = parts["li_sanfelice"]
    assert (good.status, good.figures, good.problems) == ("ok", ["li_sanfelice/f.png"], [])
    assert good.paper["title"] == "Paper 002" and good.errata == ["(1): sign"]
    assert [r["verdict"] for r in good.claims] == ["reproduced"] and good.claims[0]["passed"]
    assert "made f.png" in good.log and good.seconds > 0
    bad = parts["gramian_delay"]
    assert bad.status == "failed" and "RuntimeError: figure code broke" in bad.error
    assert bad.claims[0]["passed"]                   # claims still evaluated
    bare = parts["time_varying"]
    assert bare.status == "ok" and bare.claims is None
    assert bare.problems == [
        "observers.time_varying defines no PAPER (title, authors and venue unknown)",
        "observers.time_varying defines no ERRATA (shown as none)",
        "observers.time_varying defines no DECISIONS (shown as none)",
        "g.png has no caption (g.txt missing)",
        "observers.time_varying defines no CLAIMS (no claims table)"]
    wrong = parts["dynamic_gain"]
    assert "must return a list of pathlib.Path (the PNGs written), got str" in wrong.error
    text = (out / "index.html").read_text()
    assert "figure code broke" in text and "g.png has no caption" in text
    assert [r["id"] for r in read_csv(out / "claims.csv")] == ["002-a", "004-a", "000-a"]
    # one part again: the others stay on the page; --no-claims leaves the table out
    assert rp.main(["reproduce", "li_sanfelice", "--out", str(out), "--no-claims"]) == 0
    parts = {p.name: p for p in load_parts(out)}
    assert len(parts) == 4 and parts["li_sanfelice"].claims is None
    assert parts["li_sanfelice"].claims_note == "claims not evaluated (--no-claims)"
    assert rp.main(["report", "--out", str(out)]) == 0
    assert rp.main(["report", "--out", str(tmp_path / "none")]) == 2


def test_a_claim_off_its_expected_verdict_fails_the_job(tmp_path, monkeypatch, capsys):
    mod = _fake("distributed", reproduce=_good)
    mod.CLAIMS = [Claim(id="003-a", paper="003", where="(1)", statement="s", paper_value=2.0,
                        compute=lambda: 1.0, tol=0.0, tol_why="exact")]
    monkeypatch.setitem(sys.modules, "observers.distributed", mod)
    assert rp.main(["reproduce", "distributed", "--out", str(tmp_path)]) == 1
    assert "claims not as expected: 003-a" in capsys.readouterr().err
    mod.CLAIMS = [mod.CLAIMS[0], mod.CLAIMS[0]]               # an invalid registry
    assert rp.main(["reproduce", "distributed", "--out", str(tmp_path)]) == 1
    part = load_parts(tmp_path)[0]
    assert part.status == "failed" and "duplicate claim id '003-a'" in part.claims_note


# ------------------------------------------------------- in a real browser --

CHROMIUM = next((p for p in (shutil.which("chromium"), shutil.which("chromium-browser"),
                             shutil.which("google-chrome")) if p), None)

_CHECK = """<script>
window.addEventListener("load", () => {
  const imgs = Array.from(document.images).map(i => ({
    src: i.getAttribute("src"), complete: i.complete, w: i.naturalWidth, h: i.naturalHeight}));
  const tables = Array.from(document.querySelectorAll("table")).map(t => ({
    cls: t.className, height: t.offsetHeight, width: t.offsetWidth,
    rows: t.tBodies.length ? t.tBodies[0].rows.length : 0,
    cols: t.tHead ? t.tHead.rows[0].cells.length : 0}));
  const pre = document.createElement("pre");
  pre.id = "render-check";
  pre.textContent = JSON.stringify({imgs, tables, width: document.body.scrollWidth});
  document.body.appendChild(pre);
});
</script>"""


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on PATH (Debian: apt-get install "
                                              "chromium): the page is not opened in a browser")
def test_page_renders_in_headless_chromium(outdir, tmp_path):
    page = write_report(outdir)
    # a copy of the page, beside it (same relative image paths), with a probe script
    probe = outdir / "render-check.html"
    probe.write_text(page.read_text(encoding="utf-8").replace("</body>", _CHECK + "</body>"),
                     encoding="utf-8")
    cmd = [CHROMIUM, "--headless=new", "--disable-gpu", "--no-sandbox",
           "--no-first-run", "--disable-extensions", f"--user-data-dir={tmp_path / 'profile'}",
           "--run-all-compositor-stages-before-draw", "--virtual-time-budget=5000",
           "--window-size=1200,3000", "--dump-dom", probe.as_uri()]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=90)
    m = re.search(r'<pre id="render-check">(.*?)</pre>', res.stdout, re.S)
    assert m, f"the probe did not run (exit {res.returncode}): {res.stderr[-2000:]}"
    state = json.loads(html.unescape(m.group(1)))
    assert len(state["imgs"]) == 3
    for img in state["imgs"]:
        assert img["complete"] and img["w"] > 0 and img["h"] > 0, img     # loaded and decoded
    # the PNGs are 180 x 120 (3 x 2 in at 60 dpi): the browser decoded the real files
    assert {(i["w"], i["h"]) for i in state["imgs"]} == {(180, 120)}
    expected_rows = {"summary": 3, "claims": 5, "env": None}
    assert sorted(t["cls"] for t in state["tables"]) == ["claims", "env", "summary"]
    for t in state["tables"]:
        assert t["height"] > 20 and t["width"] > 100, t                     # laid out, visible
        if expected_rows[t["cls"]] is not None:
            assert t["rows"] == expected_rows[t["cls"]], t
            assert t["cols"] >= 10, t
    assert state["width"] <= 1200, "the page overflows the window horizontally"


def test_report_lists_figures_not_reproduced_and_reads_yes_no_and_bounds(tmp_path):
    c = [Claim(id="004-blowup", paper="004", where="Sec. 5", statement="the run blows up",
               paper_value=None, reference=1.0, compute=lambda: True, tol=0.0,
               tol_why="a yes/no claim"),
         Claim(id="004-settle", paper="004", where="Fig. 1", statement="not later than 8 s",
               paper_value=8.0, compute=lambda: 7.5, tol=0.0, tol_why="a bound",
               relation="<=")]
    rows = [r.row() for r in run_claims(c)]
    Part(name="gramian_delay", claims=rows, not_reproduced={"Fig. 3": f"needs [10] {EVIL}"},
         paper={"id": "004", "title": "T", "authors": "A", "venue": "V"}).save(tmp_path)
    text = write_report(tmp_path).read_text()
    assert "Not reproduced:" in text and "<strong>Fig. 3</strong>: needs [10] &lt;script" in text
    page = _Page()
    page.feed(text)
    table = next(t for t in page.tables if t["section"] == "gramian_delay")
    head = [c["text"] for c in table["head"][0]]
    col = {name: head.index(name) for name in head}
    yes, bound = ([c["text"] for c in row] for row in table["rows"])
    assert yes[col["our value"]] == "yes" and yes[col["paper's value"]].startswith("yes")
    assert bound[col["paper's value"]] == "≤ 8" and bound[col["verdict"]] == "reproduced"


# ------------------------------------------------------------ falsification --

def _timer_problem(pid, level, expect):
    import hybridsim as hs
    from hybridsim.falsification import Interval, Space
    from hybridsim.library import Timer
    from observers.falsification import Problem
    return Problem(id=pid, paper="002", where="(9)", statement=f"first reset by {level}",
                   space=Space(period=Interval(0.9, 1.2)),
                   run=lambda p: hs.simulate(Timer(p["period"]), [0.0], t_max=2.0, j_max=1),
                   margin=lambda arc: level - arc.jump_times[0], budget=60, expect=expect,
                   reason=f"periods reach 1.2 {EVIL}")


@pytest.mark.slow
def test_falsify_command_records_problems_and_the_report_shows_them(tmp_path, monkeypatch,
                                                                    capsys):
    mod = _fake("li_sanfelice", reproduce=_good)
    mod.PROBLEMS = [_timer_problem("002-printed", 1.1, "counterexample"),
                    _timer_problem("002-corrected", 1.25, "none")]
    monkeypatch.setitem(sys.modules, "observers.li_sanfelice", mod)
    assert rp.main(["reproduce", "li_sanfelice", "--out", str(tmp_path)]) == 0
    assert rp.main(["falsify", "li_sanfelice", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "as expected" in out and "002-printed" in out
    rows = json.loads((tmp_path / "li_sanfelice" / "falsification.json").read_text())
    assert [(r["id"], r["found"], r["passed"]) for r in rows] == [
        ("002-printed", "counterexample", True), ("002-corrected", "none", True)]
    assert rows[0]["margin"] < 0 and rows[1]["margin"] >= 0.05 - 1e-9
    png = tmp_path / rows[0]["figure"]
    assert png.is_file() and png.with_suffix(".txt").is_file() and rows[1]["figure"] is None
    text = (tmp_path / "index.html").read_text()
    assert "Falsification: searches for counterexamples" in text
    assert "periods reach 1.2 &lt;script" in text and rows[0]["figure"] in text
    page = _Page()
    page.feed(text)
    table = next(t for t in page.tables if t["class"] == "falsification")
    assert len(table["rows"]) == 2
    # a problem off its expected outcome fails the command
    mod.PROBLEMS = [_timer_problem("002-wrong", 1.1, "none")]
    assert rp.main(["falsify", "li_sanfelice", "--out", str(tmp_path)]) == 1
    assert "problems not as expected: 002-wrong" in capsys.readouterr().err
    assert rp.main(["falsify", "--out", str(tmp_path), "--scale", "0"]) == 2
