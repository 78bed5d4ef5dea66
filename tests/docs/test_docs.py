"""The documentation: generated pages, internal links, math offline, gallery.

Cheap checks (default suite): the link checker on a small tree, the papers
page's text (every paper and claim, valid reST), the gallery configuration.
Slow checks (``pytest -m slow``; skipped when Sphinx and the docs extra are
not installed): one full build into a temporary folder, warning-free, whose
internal links all resolve; then, where Chromium is installed, the pages in
a real headless browser opened from ``file://`` with the network cut off:
the math is typeset by the bundled MathJax and the gallery's paper figures
load. ``HYBRIDSIM_DOCS_BUILD=DIR`` checks an existing build instead of
building.
"""
import ast
import importlib
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS))

import _linkcheck  # noqa: E402  (docs/ on sys.path)

PAPER_EXAMPLES = ("dynamic_gain_example", "time_varying_example", "li_sanfelice_example",
                  "distributed_example", "gramian_delay_example")
DOCS_EXTRA = ("sphinx", "numpydoc", "sphinx_gallery", "pydata_sphinx_theme",
              "sphinx-mathjax-offline")


# -- cheap -------------------------------------------------------------------

def test_linkcheck_finds_missing_files_and_anchors(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "_static").mkdir()
    (tmp_path / "a.html").write_text(
        '<a href="sub/b.html#here">ok</a> <a href="sub/b.html#gone">anchor</a> '
        '<a href="c.html">file</a> <a href="#top">self</a> <img src="sub/x.png"> '
        '<a href="https://example.org/#x">external</a> <a href="mailto:a@b">mail</a> '
        '<a href="data:image/png;base64,xx">data</a> <p id="top"></p>')
    (tmp_path / "sub" / "b.html").write_text(
        '<section id="here"></section><a name="old"></a><a href="../a.html#top">back</a>'
        '<a href="b.html#old">named</a><a href="sub%20dir.html">quoted</a>')
    (tmp_path / "sub" / "sub dir.html").write_text("<p></p>")
    (tmp_path / "_static" / "macros.html").write_text("<a href=\"{{ pathto('x') }}\">")
    n, problems = _linkcheck.check_links(tmp_path)
    assert n == 8
    assert sorted(problems) == [
        "a.html: c.html (no file c.html)",
        "a.html: sub/b.html#gone (no anchor #gone in sub/b.html)",
        "a.html: sub/x.png (no file sub/x.png)",
    ]


@pytest.fixture(scope="module")
def papers_text():
    import _papers

    return _papers.papers_rst()


def test_papers_page_lists_every_paper_and_claim(papers_text):
    import _papers

    from observers.claims import PAPER_MODULES, collect_claims

    for name, pid in PAPER_MODULES.items():
        mod = importlib.import_module(f"observers.{name}")
        assert f"`{pid} <paper-{name}>`" in papers_text
        assert f".. _paper-{name}-claims:" in papers_text
        for key in ("ERRATA", "DECISIONS"):
            for entry in getattr(mod, key, None) or []:
                assert _papers.escape(entry) in papers_text, (name, key, entry[:60])
        for fig, why in (getattr(mod, "NOT_REPRODUCED", None) or {}).items():
            assert _papers.escape(f"{fig}: {why}") in papers_text
    for name, claims in collect_claims().items():
        for c in claims or []:
            assert f"``{c.id}``" in papers_text
            assert _papers.escape(c.statement) in papers_text
            assert _papers.escape(c.tol_why) in papers_text
    # the paper ids in order, 000 first
    ids = re.findall(r"^(\d{3}): ", papers_text, flags=re.M)
    assert ids == sorted(PAPER_MODULES.values())


def test_papers_page_is_valid_rest(papers_text):
    """Parsed by docutils (Sphinx's roles stubbed): no warning or error, and
    plain text stays plain ("A. N. Author" is no list, "|e|" no substitution)."""
    docutils = pytest.importorskip("docutils")
    from docutils.core import publish_doctree
    from docutils.parsers.rst import roles

    def stub(name, rawtext, text, lineno, inliner, options=None, content=None):
        return [docutils.nodes.literal(rawtext, text)], []

    for role in ("ref", "mod", "func", "doc"):
        roles.register_local_role(role, stub)
    import _papers

    tricky = ["A. N. Author, I. B. Other", "(50) is exact", "|e| <= 1e-8 * x_", "`x` [1]_ *a",
              "1. The first", "- a dash", "\\n backslash"]
    text = papers_text + "\n" + "".join(f"{_papers.escape(s)}\n\n" for s in tricky)
    doctree = publish_doctree(text, settings_overrides={
        "report_level": 2, "halt_level": 5, "warning_stream": False})
    messages = [m.astext() for m in doctree.findall(docutils.nodes.system_message)]
    assert messages == []
    paragraphs = [p.astext() for p in doctree.findall(docutils.nodes.paragraph)]
    for s in tricky:
        assert s in paragraphs
    assert not list(doctree.findall(docutils.nodes.enumerated_list))


def _not_run():
    """conf.py's NOT_RUN (the examples shown but not run), without running conf.py."""
    tree = ast.parse((DOCS / "conf.py").read_text(encoding="utf-8"))
    for node in tree.body:
        target = getattr(node, "target", None) or (getattr(node, "targets", None) or [None])[0]
        if isinstance(target, ast.Name) and target.id == "NOT_RUN":
            return tuple(ast.literal_eval(node.value))
    raise AssertionError("docs/conf.py defines no NOT_RUN")


def test_gallery_configuration_names_existing_examples():
    for name in _not_run():
        assert (ROOT / "examples" / name).is_file(), name
    for name in PAPER_EXAMPLES:
        assert (ROOT / "examples" / f"{name}.py").is_file(), name
    text = (DOCS / "conf.py").read_text(encoding="utf-8")
    assert '"sphinx-mathjax-offline"' in text   # math needs no network when read


def test_benchmarks_page_is_one_dated_run_on_one_named_machine():
    """benchmarks/run_all.py --page writes the benchmarks page from one run:
    dated once, the machine named once, every RESULT line in the table,
    valid reST whatever the figures' characters."""
    docutils = pytest.importorskip("docutils")
    import datetime

    from docutils.core import publish_doctree

    spec = importlib.util.spec_from_file_location("run_all", ROOT / "benchmarks" / "run_all.py")
    run_all = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(run_all)
    host = run_all.machine()
    results = [("bench_a.py", "30-bounce ball: 2.8 ms vs *loop* 10.6 ms | 0.27x"),
               ("bench_a.py", "timer_jump: 50.7 us per jump (`fast`) \\ done"),
               ("bench_b.py", "no colon here")]
    status = [("bench_a.py", 0, 12.34), ("bench_b.py", 1, 0.5)]
    when = datetime.datetime(2026, 11, 29, 8, 35, tzinfo=datetime.UTC)
    text = run_all.page(results, status, when=when, host=host, argv=["--quick"],
                        load=("1.00 / 1.00 / 1.00", "2.00 / 1.50 / 1.20"))
    assert text.count("2026-11-29 08:35 UTC") == 1
    assert text.count(host["processor"]) == 1 and f"{host['cores']} cores" in text
    assert "python benchmarks/run_all.py --quick" in text and "1 of 2 scripts" in text
    doctree = publish_doctree(text, settings_overrides={
        "report_level": 2, "halt_level": 5, "warning_stream": False})
    assert [m.astext() for m in doctree.findall(docutils.nodes.system_message)] == []
    cells = [e.astext() for e in doctree.findall(docutils.nodes.entry)]
    assert "30-bounce ball" in cells and "2.8 ms vs *loop* 10.6 ms | 0.27x" in cells
    assert "50.7 us per jump (`fast`) \\ done" in cells and "no colon here" in cells
    assert "failed (1)" in cells
    # the committed page: dated, the machine named, the command that rewrites it
    committed = (DOCS / "benchmarks.rst").read_text(encoding="utf-8")
    assert re.search(r"on \d{4}-\d{2}-\d{2}", committed)
    assert "python benchmarks/run_all.py --quick --page docs/benchmarks.rst" in committed


# -- slow: a full build ------------------------------------------------------

def _missing_docs_extra():
    return [m for m in DOCS_EXTRA if importlib.util.find_spec(m) is None]


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    """The HTML documentation built once, as CI builds it: ``(folder, error)``,
    where ``error`` is the build's exit status and stderr when it failed.
    ``HYBRIDSIM_DOCS_BUILD=DIR`` names a finished build to check instead."""
    given = os.environ.get("HYBRIDSIM_DOCS_BUILD")
    if given:
        return Path(given).resolve(), None
    missing = _missing_docs_extra()
    if missing:
        pytest.skip(f"the docs extra is not installed (missing {', '.join(missing)}): "
                    f"pip install '.[docs]'")
    out = tmp_path_factory.mktemp("html")
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         str(DOCS), str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=900,
        env={**os.environ, "MPLBACKEND": "Agg"})
    error = None if proc.returncode == 0 else (
        f"docs build failed (exit {proc.returncode}) after "
        f"{time.perf_counter() - t0:.0f} s:\n{proc.stderr[-6000:]}")
    return out, error


@pytest.fixture(scope="module")
def built(build):
    """The built HTML folder, whether or not the build had warnings."""
    out, error = build
    if not (out / "index.html").is_file():
        pytest.fail(f"no HTML was built in {out}: {error}")
    return out


@pytest.mark.slow
def test_build_is_warning_free(build):
    out, error = build
    assert error is None, error


@pytest.mark.slow
def test_build_has_no_broken_internal_links(built):
    n, problems = _linkcheck.check_links(built)
    assert n > 1000, f"only {n} internal links: is {built} a full build?"
    assert problems == [], "\n".join(problems[:40])


def _run_examples():
    return [name for name in PAPER_EXAMPLES if f"{name}.py" not in _not_run()]


@pytest.mark.slow
def test_gallery_shows_a_figure_for_each_paper_that_runs(built, tmp_path):
    from sphinx_gallery.gen_rst import scale_image

    placeholder = tmp_path / "placeholder.png"
    import sphinx_gallery

    scale_image(str(Path(sphinx_gallery.__file__).parent / "_static" / "no_image.png"),
                str(placeholder), 400, 280)
    index = (built / "auto_examples" / "index.html").read_text(encoding="utf-8")
    for name in PAPER_EXAMPLES:
        assert f"sphx_glr_{name}_thumb.png" in index, f"{name} is not in the gallery"
    for name in _run_examples():
        page = (built / "auto_examples" / f"{name}.html").read_text(encoding="utf-8")
        figure = built / "_images" / f"sphx_glr_{name}_001.png"
        assert f"sphx_glr_{name}_001.png" in page and figure.is_file(), \
            f"the gallery page of {name} shows no figure"
        thumb = built / "_images" / f"sphx_glr_{name}_thumb.png"
        assert thumb.read_bytes() != placeholder.read_bytes(), \
            f"the gallery's thumbnail of {name} is the placeholder, not its figure"


# -- slow: in a real browser -------------------------------------------------

def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return None


def _dump_dom(url, budget_ms=15000):
    """The DOM of ``url`` after its scripts ran, in headless Chromium with
    every network request refused (no proxy reachable, no name resolved)."""
    exe = _chromium()
    if exe is None:
        pytest.skip("no Chromium installed (apt-get install chromium): the browser "
                    "checks need a real headless browser")
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
           "--disable-extensions", "--disable-background-networking",
           "--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>",
           "--host-resolver-rules=MAP * ~NOTFOUND",
           f"--virtual-time-budget={budget_ms}", "--dump-dom", url]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


@pytest.mark.slow
def test_math_renders_offline_in_chromium(built):
    html = (built / "index.html").read_text(encoding="utf-8")
    scripts = re.findall(r"<script[^>]*src=\"([^\"]*mathjax[^\"]*)\"", html, flags=re.I)
    assert scripts and not any(re.match(r"(https?:)?//", s) for s in scripts), \
        f"MathJax is not loaded from the build itself: {scripts}"
    assert "math notranslate" in html, "the index page has no math to render"
    dom = _dump_dom((built / "index.html").as_uri())
    rendered = len(re.findall(r"<mjx-container[^>]*jax=\"CHTML\"", dom))
    assert rendered >= 2, "MathJax did not typeset the math (raw LaTeX shown)"
    assert "<mjx-merror" not in dom, "MathJax reported a TeX error"


@pytest.mark.slow
def test_gallery_figures_load_in_chromium(built):
    """Each paper example's thumbnail and figure decode in the browser."""
    names = _run_examples()
    if not names:
        pytest.skip("no paper example runs in the gallery (all in NOT_RUN)")
    urls = [f"_images/sphx_glr_{n}_thumb.png" for n in names] + \
           [f"_images/sphx_glr_{n}_001.png" for n in names]
    probe = built / "_probe_images.html"
    probe.write_text(
        "<html><body><pre id='out'></pre><script>\n"
        f"const urls = {urls!r};\n"
        "const out = document.getElementById('out');\n"
        "for (const u of urls) { const im = new Image();\n"
        "  im.onload = () => { out.textContent += `ok ${u} ${im.naturalWidth}\\n`; };\n"
        "  im.onerror = () => { out.textContent += `broken ${u}\\n`; };\n"
        "  im.src = u; }\n"
        "</script></body></html>", encoding="utf-8")
    try:
        dom = _dump_dom(probe.as_uri(), budget_ms=5000)
    finally:
        probe.unlink()
    for u in urls:
        m = re.search(rf"ok {re.escape(u)} (\d+)", dom)
        assert m and int(m.group(1)) > 50, f"{u} does not load in Chromium"
