"""What the five paper packages share: input checks and figure output.

One validation helper for every paper (matrices, vectors, scalars,
observability), so that a bad argument gets the same kind of message
whichever observer it was given to, and one way of writing a figure with
its caption.

Examples
--------
>>> from observers._common import matrix, observable
>>> A = matrix("A", [[0.0, 1.0], [0.0, 0.0]], square=True)
>>> C = matrix("C", [1.0, 0.0], shape=(1, 2))
>>> observable(A, C, what="the example")
"""
from __future__ import annotations

import numbers
import pathlib

import numpy as np

__all__ = ["matrix", "vector", "scalar", "observable", "unobservable_mode",
           "save_figure", "write_caption"]


def matrix(name, M, shape=None, *, square=False, what=""):
    """``M`` as a finite 2-D float array, its shape checked.

    Parameters
    ----------
    name : str
        The argument's name, used in messages.
    M : array_like
        A scalar is read as a 1 x 1 matrix; a 1-D array as a row when
        ``shape`` asks for one row, else as a column when it asks for one
        column.
    shape : tuple of (int or None), optional
        Expected shape; None entries are free.
    square : bool
        Require a square matrix.
    what : str
        Appended to shape messages (e.g. ``" (n x p)"``).

    Raises
    ------
    TypeError
        ``M`` is None, a string, a callable, or not numeric.
    ValueError
        Wrong shape or non-finite entries.
    """
    if M is None or isinstance(M, (str, bytes)) or callable(M):
        raise TypeError(f"{name} must be a real array, got {type(M).__name__}")
    if np.iscomplexobj(M):
        raise TypeError(f"{name} must be real, got complex entries")
    try:
        A = np.array(M, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a real array, got {type(M).__name__}") from exc
    if A.ndim == 0:
        A = A.reshape(1, 1)
    elif A.ndim == 1 and shape is not None:
        if shape[0] == 1:
            A = A[None, :]
        elif len(shape) > 1 and shape[1] == 1:
            A = A[:, None]
    if A.ndim != 2:
        raise ValueError(f"{name} must be 2-dimensional{what}, got shape {A.shape}")
    if square and A.shape[0] != A.shape[1]:
        raise ValueError(f"{name} must be square{what}, got shape {A.shape}")
    if shape is not None:
        want = tuple(A.shape[k] if s is None else s for k, s in enumerate(shape))
        if A.shape != want:
            shown = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
            raise ValueError(f"{name} must have shape {shown}{what}, got {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError(f"{name} must be finite, got non-finite entries")
    return A


def vector(name, v, dim=None):
    """``v`` as a finite 1-D float array of length ``dim`` (a scalar is length 1)."""
    if v is None or isinstance(v, (str, bytes)) or callable(v):
        raise TypeError(f"{name} must be a real vector, got {type(v).__name__}")
    try:
        a = np.array(v, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a real vector, got {type(v).__name__}") from exc
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1 or (dim is not None and a.shape != (dim,)):
        want = f"({dim},)" if dim is not None else "(n,)"
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {a}")
    return a


def scalar(name, v, *, positive=False, nonneg=False, lo=None, hi=None):
    """A finite real number, optionally > 0, >= 0 or within [lo, hi]."""
    if isinstance(v, bool) or not isinstance(v, (numbers.Real, np.floating, np.integer)):
        raise TypeError(f"{name} must be a real number, got {type(v).__name__}")
    v = float(v)
    if not np.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    if positive and not v > 0:
        raise ValueError(f"{name} must be > 0, got {v}")
    if nonneg and v < 0:
        raise ValueError(f"{name} must be >= 0, got {v}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise ValueError(f"{name} must lie in [{lo}, {hi}], got {v}")
    return v


def unobservable_mode(A, C, rtol=1e-9):
    """An eigenvalue of A that C does not see (PBH test), or None.

    rank [A - λI; C] < n for some eigenvalue λ of A. The rank is decided
    relative to the largest singular value of the stacked matrix.
    """
    A = np.asarray(A, dtype=float)
    C = np.asarray(C, dtype=float)
    n = A.shape[0]
    scale = max(1.0, np.linalg.norm(A, 2), np.linalg.norm(C, 2))
    for lam in np.linalg.eigvals(A):
        M = np.vstack([A - lam * np.eye(n), C.astype(complex)])
        s = np.linalg.svd(M, compute_uv=False)
        if s[-1] <= rtol * scale:
            return lam
    return None


def observable(A, C, *, what="the observer", rtol=1e-9):
    """Raise ValueError, naming the unseen mode, when (A, C) is not observable."""
    lam = unobservable_mode(A, C, rtol)
    if lam is not None:
        lam = complex(lam)
        shown = f"{lam.real:.6g}" if abs(lam.imag) < 1e-12 else f"{lam:.6g}"
        raise ValueError(f"(A, C) must be observable for {what}: the mode at eigenvalue "
                         f"{shown} is not seen by the output (PBH rank test)")


def write_caption(png, text):
    """Write ``text`` beside a figure as ``<name>.txt``."""
    png = pathlib.Path(png)
    png.with_suffix(".txt").write_text(text.strip() + "\n")


def save_figure(fig, outdir, name, caption, dpi=120):
    """Save a matplotlib figure as ``outdir/name.png`` with its caption; close it.

    Returns the PNG's path.
    """
    import matplotlib.pyplot as plt
    path = pathlib.Path(outdir) / f"{name}.png"
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    write_caption(path, caption)
    return path
