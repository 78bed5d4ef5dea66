"""Helpers of the sphinx-gallery configuration (``conf.py``), in a module so
that the configuration names them by string and stays picklable.

The engine's examples save their figures into the folder given as their first
argument and close them (``python examples/timer.py DIR``), so matplotlib's
scraper finds no open figure. Here each executed example gets a folder of its
own as ``sys.argv[1]``, and :func:`png_scraper` moves the PNGs written there
into the gallery page after each code block.

The papers' examples draw with pyplot and end with ``plt.show()``, often
drawing one figure over several code blocks (axes made in the first block,
curves added in the next ones). sphinx-gallery's matplotlib scraper saves and
closes every open figure after each block, which would show the figure empty
and lose what is drawn later. :func:`mpl_scraper` shows a figure where the
script shows it: after the block that calls ``plt.show()``, or after the
example's last code block for a figure never shown.
"""
from __future__ import annotations

import functools
import shutil
from pathlib import Path

GALLERY_OUT = Path(__file__).resolve().parent / "_build" / "gallery_figures"


def _folder(src_file) -> Path:
    return GALLERY_OUT / Path(src_file).stem


def reset_argv(gallery_conf, script_vars):
    """``sys.argv[1:]`` of an executed example: its own, emptied, output folder.

    Called before each example runs, it also installs :func:`_show` as
    ``plt.show``."""
    import matplotlib.pyplot as plt

    plt.show = _show
    folder = _folder(script_vars["src_file"])
    shutil.rmtree(folder, ignore_errors=True)
    return [str(folder)]


_SHOWN = "_hybridsim_gallery_shown"


def _show(*args, **kwargs):
    """``plt.show`` in the gallery: marks the open figures as shown, so that
    :func:`mpl_scraper` puts them on the page after the current block."""
    from matplotlib._pylab_helpers import Gcf

    for manager in Gcf.get_all_fig_managers():
        setattr(manager.canvas.figure, _SHOWN, True)


@functools.cache
def _last_code_line(src_file: str) -> int:
    """Line number of the last code block of an example that has code."""
    from sphinx_gallery.py_source_parser import split_code_and_text_blocks

    _, blocks = split_code_and_text_blocks(src_file)
    last = 0
    for kind, content, lineno in blocks:
        code = [ln for ln in content.splitlines()
                if ln.strip() and not ln.lstrip().startswith("#")]
        if kind == "code" and code:
            last = lineno
    return last


def mpl_scraper(block, block_vars, gallery_conf):
    """sphinx-gallery's matplotlib scraper, for the figures shown so far.

    Figures not shown yet (no ``plt.show()`` since they were made) stay
    open for the next blocks to draw on, until the example's last code
    block, after which every open figure is put on the page.
    """
    from matplotlib._pylab_helpers import Gcf
    from sphinx_gallery.scrapers import matplotlib_scraper

    held = {}
    if block.lineno < _last_code_line(str(block_vars["src_file"])):
        for num, manager in list(Gcf.figs.items()):
            if not getattr(manager.canvas.figure, _SHOWN, False):
                held[num] = Gcf.figs.pop(num)
    try:
        return matplotlib_scraper(block, block_vars, gallery_conf)
    finally:
        Gcf.figs.update(held)


def png_scraper(block, block_vars, gallery_conf):
    """Move the PNG files the example wrote since the last block into the page."""
    from sphinx_gallery.scrapers import figure_rst

    folder = _folder(block_vars["src_file"])
    pngs = sorted(folder.glob("*.png")) if folder.is_dir() else []
    names = []
    for png in pngs:
        target = block_vars["image_path_iterator"].next()
        shutil.move(png, target)
        names.append(target)
    return figure_rst(names, gallery_conf["src_dir"])
