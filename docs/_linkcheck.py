"""Offline check of a built HTML tree: every internal link resolves.

An internal link is an ``href`` or ``src`` without a scheme (``http:``,
``mailto:``, ``data:`` ...): its file must exist in the tree and, for a link
to a page with a ``#fragment``, the page must have an element with that
``id`` (or an ``<a name>``). External links are not followed (the build has no
network). The theme's template fragments under ``_static/`` are not pages
and are not checked.

``conf.py`` runs it at the end of every HTML build (a broken link is a
warning, so an error under ``-W``); ``tests/docs/test_docs.py`` runs it on a fresh
build. By hand::

    python docs/_linkcheck.py docs/_build/html
"""
from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

__all__ = ["check_links"]


class _Page(HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.links: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(a["id"])
        if tag == "a" and a.get("name"):
            self.ids.add(a["name"])
        for key in ("href", "src"):
            if a.get(key):
                self.links.append(a[key])

    handle_startendtag = handle_starttag


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8", errors="replace"))
    page.close()
    return page


def check_links(outdir) -> tuple[int, list[str]]:
    """Check every internal link of the HTML pages under ``outdir``.

    Returns
    -------
    n : int
        The number of internal links checked.
    problems : list of str
        One line per broken link: ``page: link (why)``.
    """
    root = Path(outdir).resolve()
    pages = {p.resolve(): None for p in root.rglob("*.html")
             if p.relative_to(root).parts[0] != "_static"}
    for p in pages:
        pages[p] = _parse(p)
    n, problems = 0, []
    for path, page in pages.items():
        for link in page.links:
            u = urlsplit(link)
            if u.scheme or link.startswith("//"):
                continue            # external (http, mailto, data, javascript ...)
            n += 1
            target = path if not u.path else (path.parent / unquote(u.path)).resolve()
            where = f"{path.relative_to(root)}: {link}"
            if not target.exists():
                shown = target.relative_to(root) if target.is_relative_to(root) else target
                problems.append(f"{where} (no file {shown})")
                continue
            if u.fragment and target.suffix == ".html":
                doc = pages.get(target) or _parse(target)
                if unquote(u.fragment) not in doc.ids:
                    problems.append(f"{where} (no anchor #{unquote(u.fragment)} in "
                                    f"{target.relative_to(root)})")
    return n, problems


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python docs/_linkcheck.py BUILD_DIR", file=sys.stderr)
        return 2
    n, problems = check_links(argv[0])
    for line in problems:
        print(line)
    print(f"{n} internal links checked, {len(problems)} broken")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
