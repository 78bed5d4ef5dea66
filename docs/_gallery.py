"""Helpers of the sphinx-gallery configuration (``conf.py``), in a module so
that the configuration names them by string and stays picklable.

The engine's examples save their figures into the folder given as their first
argument and close them (``python examples/timer.py DIR``), so matplotlib's
scraper finds no open figure. Here each executed example gets a folder of its
own as ``sys.argv[1]``, and :func:`png_scraper` moves the PNGs written there
into the gallery page after each code block.
"""
from __future__ import annotations

import shutil
from pathlib import Path

GALLERY_OUT = Path(__file__).resolve().parent / "_build" / "gallery_figures"


def _folder(src_file) -> Path:
    return GALLERY_OUT / Path(src_file).stem


def reset_argv(gallery_conf, script_vars):
    """``sys.argv[1:]`` of an executed example: its own, emptied, output folder."""
    folder = _folder(script_vars["src_file"])
    shutil.rmtree(folder, ignore_errors=True)
    return [str(folder)]


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
