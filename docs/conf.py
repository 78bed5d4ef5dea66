"""Sphinx configuration of the hybridsim documentation.

Build (from the repository root; warnings are errors)::

    python -m pip install ".[docs]"
    python -m sphinx -W --keep-going -b html docs docs/_build/html

The API reference is generated from the docstrings (numpydoc format), the
gallery from ``examples/`` by sphinx-gallery (which runs the fast scripts and
shows the slow ones without running them: see ``NOT_RUN``), the
papers page from the paper packages (``_papers.py``); the benchmarks page,
``benchmarks.rst``, is written by ``benchmarks/run_all.py`` from one run and
committed. MathJax is bundled into the HTML (sphinx-mathjax-offline), so
the math renders with no network. Every build ends by checking that each internal link of the HTML
resolves, file and #anchor (``_linkcheck.py``; a broken one is a warning).
"""
from __future__ import annotations

import os
import re
import sys
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))           # the checkout, also when it is not installed
sys.path.insert(0, str(DOCS))           # _gallery.py

import hybridsim  # noqa: E402  (after sys.path)
import hybridsim._version  # noqa: E402

# -- project -----------------------------------------------------------------

project = "hybridsim"
author = "the hybridsim authors"
copyright = f"2026, {author}"
release = hybridsim._version.__version__
version = ".".join(release.split(".")[:2])

# -- general -----------------------------------------------------------------

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    # MathJax 3 copied into _static/mathjax: math renders with no network
    # (sphinx.ext.mathjax alone loads it from a CDN when the page is read)
    "sphinx-mathjax-offline",
    "sphinx.ext.viewcode",
    # the user guide's figures: its examples run when the page is built
    "matplotlib.sphinxext.plot_directive",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]
# intersphinx is off: the build machine has no network. To link numpy/scipy
# names, add "sphinx.ext.intersphinx" to extensions and
#   intersphinx_mapping = {"python": ("https://docs.python.org/3", None),
#                          "numpy": ("https://numpy.org/doc/stable", None),
#                          "scipy": ("https://docs.scipy.org/doc/scipy", None)}
if os.environ.get("HYBRIDSIM_DOCS_INTERSPHINX"):
    extensions.append("sphinx.ext.intersphinx")
    intersphinx_mapping = {
        "python": ("https://docs.python.org/3", None),
        "numpy": ("https://numpy.org/doc/stable", None),
        "scipy": ("https://docs.scipy.org/doc/scipy", None),
        "matplotlib": ("https://matplotlib.org/stable", None),
        "networkx": ("https://networkx.org/documentation/stable", None),
    }

# primes stay primes: v' is a derivative, not a closing quote
smartquotes = False
templates_path = []
exclude_patterns = ["_build", "_generated", "**.ipynb_checkpoints", "auto_examples/*.ipynb",
                    "auto_examples/*.py", "auto_examples/*.zip", "auto_examples/*.json",
                    "auto_examples/*.md5", "auto_examples/*.pickle"]
nitpicky = False
default_role = "py:obj"
# Temporary: numpydoc turns each "References" section into citations, and the
# observers' module docstrings list references they do not cite in the text
# ("Citation [R...-1] is not referenced"). Remove once they cite them ([1]_).
suppress_warnings = ["ref.citation"]

# -- autodoc / autosummary / numpydoc ----------------------------------------

autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "member-order": "bysource"}
autodoc_typehints = "none"              # numpydoc's Parameters sections carry the types
numpydoc_show_class_members = False     # autosummary's class pages list the members
numpydoc_class_members_toctree = False
numpydoc_attributes_as_param_list = False

# -- sphinx-gallery ----------------------------------------------------------

# Examples that take more than ~20 s on a 2-core machine are rendered (code and
# text) but not run; their output is what `python examples/<name>.py` prints,
# and their thumbnail is sphinx-gallery's placeholder. None at present: every
# example runs in a few seconds (measured with `time python examples/<name>.py`,
# MPLBACKEND=Agg, on 2 cores: the papers' examples 1.4 to 4.2 s, the longest
# falsify_overshoot.py 5.1 s) and draws its figure.
NOT_RUN: tuple[str, ...] = ()


def _run_pattern(not_run) -> str:
    """sphinx-gallery's ``filename_pattern``: every ``.py`` but those of ``not_run``."""
    if not not_run:
        return r"\.py$"
    return r"^(?!.*(" + "|".join(re.escape(n) for n in not_run) + r")$).*\.py$"


sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": _run_pattern(NOT_RUN),
    "ignore_pattern": r"__init__\.py",
    # the engine's examples write PNGs to sys.argv[1]: see _gallery.py
    "reset_argv": "_gallery.reset_argv",
    # figures drawn with pyplot appear where the script shows them (plt.show),
    # not empty after the block that made them: see _gallery.py
    "image_scrapers": ("_gallery.mpl_scraper", "_gallery.png_scraper"),
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_memory": False,
    "abort_on_example_error": False,
    "only_warn_on_example_error": False,
}

# -- the guide's figures (matplotlib's plot directive) ------------------------

plot_include_source = True
plot_html_show_source_link = False
plot_html_show_formats = False
plot_formats = [("png", 100)]
plot_rcparams = {"figure.figsize": (7.0, 4.0)}
plot_apply_rcparams = True

# -- HTML --------------------------------------------------------------------

html_theme = "pydata_sphinx_theme"
html_title = f"hybridsim {release}"
html_static_path = []
html_theme_options = {"show_toc_level": 2, "navigation_with_keys": False}
html_show_sourcelink = False


# -- docstrings: plain-text math ----------------------------------------------

# The docstrings write math as plain text, to be read by help() as well as
# here: |x| is a norm, not a reST substitution. Outside inline literals, roles,
# literal blocks, doctests, tables and line blocks, "|" is escaped before
# docutils reads it.
_INLINE = re.compile(r"(``.+?``|:[\w:.-]+:`[^`]*`|`[^`]*`_{0,2})")


def _escape_bars(line: str) -> str:
    parts = _INLINE.split(line)
    for i in range(0, len(parts), 2):           # even parts are outside literals/roles
        parts[i] = re.sub(r"(?<!\\)\|", r"\\|", parts[i])
    return "".join(parts)


def _escape_plain_bars(lines, skip_directives=False):
    """Escape, in place, the "|" of the plain-text lines of reST ``lines``.

    ``skip_directives``: the content of every directive is left alone (a
    gallery page's code and output blocks), not only that of literal blocks.
    """
    literal_indent = None       # indentation of the line that opened a literal block
    for k, line in enumerate(lines):
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if literal_indent is not None:
            if not stripped or indent > literal_indent:
                continue
            literal_indent = None
        if stripped.startswith((">>>", "... ", "| ", "+-", "+=", ".. ")) or stripped == "|":
            if stripped.startswith(".. ") and (stripped.rstrip().endswith("::") or (
                    skip_directives and re.match(r"\.\. [\w:-]+::", stripped))):
                literal_indent = indent
            continue
        if "|" in line:
            lines[k] = _escape_bars(line)
        if stripped.rstrip().endswith("::"):
            literal_indent = indent


def _plain_text_math(app, what, name, obj, options, lines):
    _escape_plain_bars(lines)


def _gallery_plain_text_math(app, docname, source):
    """The gallery's text blocks (the examples' comments) follow the
    docstrings' convention too: ``|e|`` is a norm, not a substitution."""
    if docname.startswith("auto_examples/") and "|" in source[0]:
        lines = source[0].split("\n")
        _escape_plain_bars(lines, skip_directives=True)
        source[0] = "\n".join(lines)


def _skip_foreign(app, what, name, obj, skip, options):
    """The reference documents this project's objects only: a name a module
    re-exports from elsewhere (``observers.li_sanfelice.expm`` is scipy's)
    is skipped."""
    module = getattr(obj, "__module__", None)
    if what == "module" and isinstance(module, str) and callable(obj) \
            and not module.startswith(("hybridsim", "observers")):
        return True
    return None


# -- known warnings of docstrings (temporary) ----------------------------------

# Warnings that come from docstrings in modules this configuration cannot fix,
# each matched by (where, message). Each entry is temporary: remove it when
# the docstring is fixed (the build fails again if it comes back).
KNOWN_WARNINGS: list[tuple[str, str]] = []   # none: every docstring builds clean


class _KnownWarnings:
    def __init__(self):
        self.patterns = [(re.compile(w), re.compile(m)) for w, m in KNOWN_WARNINGS]

    def filter(self, record) -> bool:
        where = str(getattr(record, "location", "") or "")
        message = record.getMessage()
        return not any(w.search(where) and m.search(message) for w, m in self.patterns)


def _install_known_warnings(app):
    import logging

    for handler in logging.getLogger("sphinx").handlers:
        if type(handler).__name__ == "WarningStreamHandler":
            handler.filters.insert(0, _KnownWarnings())


# -- generated pages ---------------------------------------------------------

def _write_generated(app):
    """docs/_generated/: the papers page (:mod:`_papers`: the packages'
    PAPER, ERRATA, DECISIONS, NOT_REPRODUCED and claims, read from the code
    without evaluating the claims). A file is
    rewritten only when its text changed, so that an unchanged page is not
    rebuilt."""
    import _papers
    from sphinx.util import logging

    try:
        papers = _papers.papers_rst()
    except Exception as exc:  # noqa: BLE001 - any failure of a package is reported, the build goes on
        logging.getLogger(__name__).warning(
            "docs/papers.rst: reading the paper packages failed: %s: %s",
            type(exc).__name__, exc)
        papers = (f"The paper packages could not be read when this page was built "
                  f"(``{type(exc).__name__}``).\n")
    gen = DOCS / "_generated"
    gen.mkdir(exist_ok=True)
    for name, text in (("papers.rst", papers),):
        target = gen / name
        if not target.exists() or target.read_text(encoding="utf-8") != text:
            target.write_text(text, encoding="utf-8")


def _check_api_coverage(app):
    """Every name in ``hybridsim.__all__`` is on the API page (a warning,
    hence an error under -W, names the missing ones)."""
    from sphinx.util import logging

    page = (DOCS / "api" / "hybridsim.rst").read_text(encoding="utf-8")
    listed = set(re.findall(r"^\s{3,}~?(?:hybridsim\.)?(\w+)\s*$", page, flags=re.M))
    missing = [n for n in hybridsim.__all__ if n not in listed]
    if missing:
        logging.getLogger(__name__).warning(
            "docs/api/hybridsim.rst does not list these names of hybridsim.__all__: %s",
            ", ".join(missing))


def _anchored(objects, name):
    """``name`` is documented with an anchor of its own (autodoc's ``:canonical:``
    names are registered as aliases of the documented name, without one)."""
    entry = objects.get(name)
    return entry is not None and not getattr(entry, "aliased", False)


def _fix_viewcode_backlinks(app, env):
    """Point each highlighted source page's [docs] links at anchors that exist.

    sphinx.ext.viewcode keeps one reference prefix per source module (the
    module name under which it first met one of the module's objects), and
    for each object the last page that documented it. An object of
    ``hybridsim.rules`` is documented twice: as ``hybridsim.SimulationError``
    (re-exported, on its own page) and as ``hybridsim.rules.SimulationError``
    (on the module's page). The source page then linked the module's page
    with the other prefix, ``hybridsim.rules.html#hybridsim.SimulationError``:
    anchors that do not exist. Here each module gets the prefix under which
    most of its linked objects are documented (its own name first on a tie),
    each object the page that documents it under that prefix, and an object
    documented only under another prefix (or only as another name's
    canonical alias) no [docs] link: one prefix per module is all viewcode
    can write.
    """
    modules = getattr(env, "_viewcode_modules", {})
    objects = env.get_domain("py").objects
    for modname, entry in list(modules.items()):
        if not entry:
            continue
        code, tags, used, refname = entry
        if not used:
            continue
        prefixes = list(dict.fromkeys(p for p in (modname, refname) if p))
        best = max(prefixes, key=lambda p: sum(_anchored(objects, f"{p}.{n}") for n in used))
        linked = {name: objects[f"{best}.{name}"].docname
                  for name in used if _anchored(objects, f"{best}.{name}")}
        modules[modname] = (code, tags, linked, best)


def _check_links(app, exception):
    """Every internal link (file and #anchor) of the built HTML resolves
    (:mod:`_linkcheck`); each broken one is a warning, an error under -W."""
    if exception is not None or app.builder.format != "html":
        return
    import _linkcheck
    from sphinx.util import logging

    n, problems = _linkcheck.check_links(app.outdir)
    log = logging.getLogger(__name__)
    for line in problems[:25]:
        log.warning("broken internal link: %s", line)
    if len(problems) > 25:
        log.warning("... and %d more broken internal links", len(problems) - 25)
    print(f"hybridsim docs: {n} internal links checked, {len(problems)} broken")


_t0 = time.perf_counter()


def _report_time(app, exception):
    if exception is None:
        print(f"hybridsim docs built in {time.perf_counter() - _t0:.1f} s")


def _declare_parallel_safe(app):
    """sphinx-mathjax-offline (0.0.2) declares nothing, so that ``-j N`` would
    warn (an error under -W); it only copies files after the build."""
    ext = app.extensions.get("sphinx-mathjax-offline")
    if ext is not None:
        ext.parallel_read_safe = ext.parallel_write_safe = True


def setup(app):
    _declare_parallel_safe(app)
    app.connect("builder-inited", _install_known_warnings)
    app.connect("autodoc-process-docstring", _plain_text_math)
    app.connect("source-read", _gallery_plain_text_math)
    app.connect("autodoc-skip-member", _skip_foreign)
    app.connect("builder-inited", _write_generated)
    app.connect("builder-inited", _check_api_coverage)
    app.connect("env-updated", _fix_viewcode_backlinks)
    # after sphinx-mathjax-offline (build-finished, priority 500) has copied MathJax
    app.connect("build-finished", _check_links, priority=900)
    app.connect("build-finished", _report_time, priority=950)
