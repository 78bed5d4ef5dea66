"""The one progress-bar factory of the engine (``simulate`` and the batches).

``progress=None`` everywhere in hybridsim means *automatic*: a bar at an
interactive terminal and in a Jupyter notebook (an IPython kernel), none
otherwise (under pytest, in CI, when stderr is redirected to a file).
``True`` and ``False`` force it on or off. The bars are tqdm's: a widget
in a notebook with ipywidgets, text elsewhere. A notebook without ipywidgets
gets one line of text: the bar of the outermost run only (a run inside a
batch or a study adds none), drawn after half a second (a short run leaves
nothing behind) and erased when it ends unless it is meant to stay.
"""
from __future__ import annotations

import functools
import importlib.util
import os
import sys
import weakref

__all__ = ["in_notebook", "make_bar", "progress_enabled"]


def in_notebook() -> bool:
    """True inside a Jupyter (IPython kernel) session.

    The test of ``tqdm.autonotebook``: IPython is imported and its running
    shell is an ``IPKernelApp`` (Jupyter, JupyterLab, VS Code notebooks,
    Colab). A terminal IPython session is not a notebook.

    Returns
    -------
    bool

    Examples
    --------
    >>> in_notebook()        # doctests run outside a notebook
    False
    """
    ipy = sys.modules.get("IPython")
    if ipy is None:
        return False
    try:
        shell = ipy.get_ipython()
        return shell is not None and "IPKernelApp" in getattr(shell, "config", {})
    except Exception:  # noqa: BLE001 - a broken IPython means: not a notebook
        return False


def _widgets_available() -> bool:
    """ipywidgets is installed (tqdm's notebook bar needs it)."""
    return importlib.util.find_spec("ipywidgets") is not None


#: The one-line text bar open in a notebook without ipywidgets (at most one; a
#: bar nobody holds any more is collected, and closed, by tqdm).
_ONE_LINE: weakref.WeakSet = weakref.WeakSet()


@functools.cache
def _one_line_class():
    from tqdm.std import tqdm as text_tqdm

    class OneLineBar(text_tqdm):
        """tqdm's text bar, which frees the notebook's one line when closed."""

        def close(self):
            try:
                super().close()
            finally:
                _ONE_LINE.discard(self)

    return OneLineBar


def _one_line_bar(kw):
    """The text bar of a notebook without widgets: one line at position 0, or
    None when a bar already draws it (a run inside a batch or a study)."""
    if any(not b.disable for b in _ONE_LINE):
        return None
    bar = _one_line_class()(**{"delay": 0.5, "mininterval": 0.5, **kw, "position": 0})
    _ONE_LINE.add(bar)
    return bar


def _stderr_is_terminal() -> bool:
    try:
        return bool(sys.stderr is not None and sys.stderr.isatty())
    except (AttributeError, ValueError):      # no isatty, or a closed stream
        return False


def progress_enabled(progress) -> bool:
    """Resolve a ``progress`` argument to on or off.

    Parameters
    ----------
    progress : bool or None
        ``True``/``False`` force the bar on/off. ``None`` (automatic): on at
        an interactive terminal (stderr is a tty) and in a Jupyter notebook,
        off otherwise, and always off when the environment variable ``CI``
        is set to a non-empty value other than ``0``/``false``.

    Returns
    -------
    bool

    Raises
    ------
    TypeError
        ``progress`` is not a bool or None.

    Examples
    --------
    >>> progress_enabled(True), progress_enabled(False)
    (True, False)
    >>> progress_enabled(None)       # doctests: stderr is not a terminal
    False
    """
    if progress is None:
        ci = os.environ.get("CI", "").strip().lower()
        if ci and ci not in ("0", "false", "no"):
            return False
        return _stderr_is_terminal() or in_notebook()
    if isinstance(progress, bool):
        return progress
    try:                                        # numpy bools
        import numpy as np
        if isinstance(progress, np.bool_):
            return bool(progress)
    except ImportError:  # pragma: no cover
        pass
    raise TypeError(f"progress must be True, False or None (automatic: at a terminal and "
                    f"in a notebook), got {type(progress).__name__} {progress!r}")


def make_bar(progress, *, total, desc, unit="it", postfix=None, bar_format=None,
             leave=False, file=None, **tqdm_kwargs):
    """A tqdm progress bar, or None when progress is off.

    Parameters
    ----------
    progress : bool or None
        On, off, or automatic (None): see :func:`progress_enabled`.
    total : float, int or None
        The bar's full length (a float is fine: a bar over time counts
        ``t - t0``); None for a counter without a known end.
    desc : str
        Label at the bar's left (``"simulate"``, ``"simulate_many"``).
    unit : str
        What one step of the bar counts (``"run"``, ``"t"``, ``"jump"``).
    postfix : str or dict, optional
        Initial text after the bar, e.g. ``"j=0"``; update it during the run
        with ``bar.set_postfix_str("j=3", refresh=False)``. A single run
        shows t on the bar and j in the postfix.
    bar_format : str, optional
        tqdm's format string, e.g.
        ``"{l_bar}{bar}| t={n:.4g}/{total:.4g}{postfix} [{elapsed}]"``
        (tqdm puts ``", "`` before a non-empty postfix itself).
    leave : bool
        Keep the finished bar on screen (default: erase it).
    file : file-like, optional
        Where to draw (default: stderr, or the notebook's widget). With a
        file given the text bar is used, also in a notebook. In a notebook
        without ipywidgets, the bar is one line of text on stderr, shown
        after half a second (``delay``); a bar asked for while that line is
        in use is None.
    **tqdm_kwargs
        Any other keyword of :class:`tqdm.tqdm` (``mininterval``...).

    Returns
    -------
    tqdm.tqdm or None
        Close it when done (``bar.close()``, or use it as a context manager).

    Raises
    ------
    TypeError
        ``progress`` is not a bool or None, or ``desc``/``unit`` not strings.

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> bar = make_bar(True, total=2.0, desc="simulate", unit="t", postfix="j=0",
    ...                bar_format="{desc}: t={n:.3g}/{total:.3g}{postfix}", file=out)
    >>> _ = bar.update(0.5); bar.set_postfix_str("j=1")
    >>> print(bar)
    simulate: t=0.5/2, j=1
    >>> bar.close()
    >>> make_bar(False, total=10, desc="runs") is None
    True
    """
    if not progress_enabled(progress):
        return None
    if not isinstance(desc, str):
        raise TypeError(f"desc must be a str, got {type(desc).__name__}")
    if not isinstance(unit, str):
        raise TypeError(f"unit must be a str, got {type(unit).__name__}")
    kw = dict(total=total, desc=desc, unit=unit, leave=leave, **tqdm_kwargs)
    if bar_format is not None:
        kw["bar_format"] = bar_format
    if postfix is not None:            # shown from the bar's first line on
        kw["postfix"] = dict(postfix) if isinstance(postfix, dict) else str(postfix)
    if file is not None:
        from tqdm.std import tqdm as text_tqdm
        bar = text_tqdm(file=file, **kw)
    elif in_notebook() and _widgets_available():
        try:
            from tqdm.notebook import tqdm as widget_tqdm
            bar = widget_tqdm(**kw)
        except ImportError:          # an ipywidgets tqdm cannot use: one line of text
            bar = _one_line_bar(kw)
    elif in_notebook():
        bar = _one_line_bar(kw)
    else:
        from tqdm.std import tqdm as text_tqdm
        bar = text_tqdm(**kw)
    return bar
