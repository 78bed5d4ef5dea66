"""What the five paper packages share: the observer contract, input checks, figures.

* **The contract** every paper package keeps (:data:`CONTRACT`,
  :func:`contract_problems`, checked for all five by
  ``tests/papers/test_contract.py``): ``simulate(observer, x0, xhat0=None, *, t_max,
  noise=None, seed=None, **simulate_kwargs)`` returns the interconnection's
  :class:`hybridsim.HybridArc`; ``errors(arc, observer)`` returns an
  :class:`Errors`; ``FIGURES`` lists each figure as a :class:`Figure` (its
  numbers computed by one function, drawn by another); ``reproduce(outdir)``
  writes them through :func:`reproduce_figures`; ``NOT_REPRODUCED`` names the
  paper's figures left out, with the reason; ``PAPER``, ``ERRATA``,
  ``DECISIONS``, ``CLAIMS``; ``PROBLEMS``, the paper's quantified statements
  as searches for counterexamples (:mod:`observers.falsification`).
* **Input checks** (matrices, vectors, scalars, observability), so that a bad
  argument gets the same kind of message whichever observer it was given to.
* **Figures**: :func:`save_figure` writes a PNG with its caption.

Library code does not print and does not choose a matplotlib backend: what a
figure or a run has to say goes to :func:`logging.getLogger` of its module
(the main job shows and records it).

Examples
--------
>>> from observers._common import matrix, observable
>>> A = matrix("A", [[0.0, 1.0], [0.0, 0.0]], square=True)
>>> C = matrix("C", [1.0, 0.0], shape=(1, 2))
>>> observable(A, C, what="the example")
"""
from __future__ import annotations

import collections.abc
import dataclasses
import inspect
import logging
import numbers
import pathlib
from collections.abc import Callable

import numpy as np

__all__ = ["matrix", "vector", "scalar", "observable", "unobservable_mode",
           "save_figure", "write_caption", "Errors", "Figure", "reproduce_figures",
           "CONTRACT", "contract_problems"]

log = logging.getLogger(__name__)


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


class Errors(collections.abc.Mapping):
    """The estimation error of an observer run, at the arc's samples.

    What every paper's ``errors(arc, observer)`` returns: a read-only mapping
    from names to arrays with one row per sample of the arc, the main error
    under ``"e"`` (shape ``(N, k)``), the paper's other error signals under
    their own names (``"xbar"``, ``"mhat"``, ...), and the samples' hybrid
    times as :attr:`t` and :attr:`j`.

    Parameters
    ----------
    t, j : array_like, shape (N,)
        The samples' hybrid times (``arc.t``, ``arc.j``).
    e : array_like, shape (N, k) or (N,)
        The main estimation error (a 1-D error is stored as one column).
    **signals : array_like
        Further named signals, each with N rows.

    Raises
    ------
    ValueError
        ``t`` and ``j`` differ in length, or a signal does not have N rows.

    Examples
    --------
    >>> import numpy as np
    >>> E = Errors([0.0, 1.0], [0, 0], e=[[1.0, 0.0], [0.0, 0.0]])
    >>> E.e.shape, list(E), E.norm().tolist()
    ((2, 2), ['e'], [1.0, 0.0])
    """

    def __init__(self, t, j, e, **signals):
        self.t = np.asarray(t, dtype=float)
        self.j = np.asarray(j, dtype=int)
        if self.t.ndim != 1 or self.j.shape != self.t.shape:
            raise ValueError(f"t and j must be 1-D of one length, got shapes {self.t.shape} "
                             f"and {self.j.shape}")
        n = self.t.size
        e = np.asarray(e, dtype=float)
        if e.ndim == 1:
            e = e[:, None]
        self._signals = {"e": e}
        for name, v in signals.items():
            self._signals[name] = np.asarray(v)
        for name, v in self._signals.items():
            if v.ndim < 1 or v.shape[0] != n:
                raise ValueError(f"error signal {name!r} must have {n} rows (one per sample), "
                                 f"got shape {v.shape}")

    @property
    def e(self):
        """The main estimation error, shape (N, k)."""
        return self._signals["e"]

    def norm(self, name="e"):
        """The Euclidean norm of a signal at each sample, shape (N,)."""
        v = self._signals[name]
        return np.linalg.norm(v.reshape(v.shape[0], -1), axis=1)

    def __getitem__(self, name):
        return self._signals[name]

    def __iter__(self):
        return iter(self._signals)

    def __len__(self):
        return len(self._signals)

    def __repr__(self):
        shapes = ", ".join(f"{k}: {v.shape}" for k, v in self._signals.items())
        return f"Errors({self.t.size} samples; {shapes})"


@dataclasses.dataclass(frozen=True)
class Figure:
    """One figure of a paper: its numbers computed by one function, drawn by another.

    Parameters
    ----------
    name : str
        The file's stem: the figure is written as ``<name>.png`` with its
        caption in ``<name>.txt``.
    title : str
        What it is in the paper (``"Fig. 1(a)"``) or, for a figure of ours,
        a short title.
    data : callable
        ``data()`` computes the figure's numbers and returns them (any
        object; the paper packages return frozen dataclasses). Cache it
        (``functools.cache``) when the claims read the same numbers, so the
        main job computes each run once.
    draw : callable
        ``draw(data)`` returns a :class:`matplotlib.figure.Figure`; it computes
        nothing the data does not hold.
    caption : callable
        ``caption(data)`` returns the caption's text.
    dpi : int
        Resolution of the PNG.
    """

    name: str
    title: str
    data: Callable
    draw: Callable
    caption: Callable
    dpi: int = 120

    def render(self, outdir):
        """Compute, draw and save this figure into ``outdir``; return the PNG's path."""
        data = self.data()
        fig = self.draw(data)
        return save_figure(fig, outdir, self.name, self.caption(data), dpi=self.dpi)


def reproduce_figures(figures, outdir, *, progress=None):
    """Write every :class:`Figure` of ``figures`` into ``outdir``.

    Parameters
    ----------
    figures : sequence of Figure
    outdir : str or pathlib.Path
        An existing folder.
    progress : callable, optional
        Called with each figure's name once it is written (the main job's
        progress bar).

    Returns
    -------
    list of pathlib.Path
        The PNGs written, each with a ``.txt`` caption beside it.
    """
    outdir = pathlib.Path(outdir)
    if not outdir.is_dir():
        raise ValueError(f"outdir must be an existing folder, got {str(outdir)!r}")
    paths = []
    for fig in figures:
        paths.append(fig.render(outdir))
        log.debug("wrote %s", paths[-1])
        if progress is not None:
            progress(fig.name)
    return paths


#: The names every paper package exports, and what each is.
CONTRACT = {
    "PAPER": "dict: the paper's id, title, authors, venue",
    "ERRATA": "list of str: what the paper gets wrong",
    "DECISIONS": "list of str: the reproduction's numbered decisions",
    "CLAIMS": "list of observers.claims.Claim",
    "FIGURES": "list of observers._common.Figure",
    "NOT_REPRODUCED": "dict: the paper's figure (e.g. 'Fig. 3') -> why it is not reproduced",
    "reproduce": "reproduce(outdir) -> list of pathlib.Path (the PNGs)",
    "simulate": "simulate(observer, x0, xhat0=None, *, t_max, noise=None, seed=None, "
                "**simulate_kwargs) -> hybridsim.HybridArc",
    "errors": "errors(arc, observer) -> observers._common.Errors",
    "PROBLEMS": "list of observers.falsification.Problem: the paper's quantified statements "
                "as searches for counterexamples",
}

# Where each contract name is defined in a package.
_HOME = {"FIGURES": "figures", "NOT_REPRODUCED": "figures", "reproduce": "figures",
         "simulate": "example", "errors": "example", "CLAIMS": "claims",
         "PROBLEMS": "falsification"}


def _signature_problems(name, fn, positional, keyword_only, var_keyword):
    sig = inspect.signature(fn)
    params = list(sig.parameters.values())
    problems = []
    pos = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    got = [p.name for p in pos[:len(positional)]]
    if got != [p for p, _ in positional]:
        problems.append(f"{name}: positional parameters must start {[p for p, _ in positional]},"
                        f" got {got}")
    for p, (want, default) in zip(pos, positional):
        if default is not inspect.Parameter.empty and p.default is not default:
            problems.append(f"{name}: {want} must default to {default!r}")
    for p in pos[len(positional):]:
        if p.default is inspect.Parameter.empty:
            problems.append(f"{name}: extra positional parameter {p.name!r} has no default")
    kw = {p.name: p for p in params if p.kind is p.KEYWORD_ONLY}
    for want, default in keyword_only:
        if want not in kw:
            problems.append(f"{name}: keyword-only parameter {want!r} missing")
        elif default is not inspect.Parameter.empty and kw[want].default is not default:
            problems.append(f"{name}: {want} must default to {default!r}")
    required = {want for want, _ in keyword_only}
    for p in kw.values():
        if p.name not in required and p.default is inspect.Parameter.empty:
            problems.append(f"{name}: extra keyword {p.name!r} has no default")
    if var_keyword and not any(p.kind is p.VAR_KEYWORD for p in params):
        problems.append(f"{name}: must take **simulate_kwargs (passed to hybridsim.simulate)")
    return problems


#: the most names a paper package's ``__all__`` lists: the contract's ten and
#: the paper's observer and design (the rest are imported from their files)
PUBLIC_MAX = 15

#: submodules a paper package may add to the six of the layout
#: (``monte_carlo``: its noise and gap studies as estimates with confidence)
OPTIONAL_SUBMODULES = ("monte_carlo",)


def contract_problems(package):
    """What a paper package does not keep of :data:`CONTRACT` (empty: it keeps all).

    Checks that every contract name is exported (in ``__all__``) and defined
    in its file (``simulate``/``errors`` in ``example.py``, ``FIGURES``,
    ``NOT_REPRODUCED`` and ``reproduce`` in ``figures.py``, ``CLAIMS`` in
    ``claims.py``, ``PROBLEMS`` in ``falsification.py``; a package may add
    the submodules of :data:`OPTIONAL_SUBMODULES`), the signatures of
    ``simulate``, ``errors`` and ``reproduce``, the types of the registries;
    that the package's ``__all__`` is its small public surface (at most
    :data:`PUBLIC_MAX` names: the contract's and the paper's observer and
    design, each one a file's export, the observer a class of
    ``systems.py``), every other name
    being imported from its file (whose ``__all__`` lists it); that no
    object is exported under two names (no aliases); and that every
    :class:`hybridsim.HybridSystem` the files export is defined in
    ``systems.py``.

    Parameters
    ----------
    package : module
        A paper package, e.g. ``observers.li_sanfelice``.

    Returns
    -------
    list of str
    """
    import importlib

    import hybridsim as hs
    E = inspect.Parameter.empty
    name = package.__name__
    problems = []
    exported = list(getattr(package, "__all__", []))
    if len(set(exported)) != len(exported):
        problems.append(f"{name}.__all__ lists a name twice")
    for key in CONTRACT:
        if key not in exported:
            problems.append(f"{name}.__all__ lacks {key!r}")
        elif not hasattr(package, key):
            problems.append(f"{name} exports {key!r} but does not define it")
    subs = {}
    for sub in ("design", "systems", "example", "figures", "claims", "falsification"):
        try:
            subs[sub] = importlib.import_module(f"{name}.{sub}")
        except ImportError as exc:
            problems.append(f"{name}.{sub} cannot be imported: {exc}")
    for sub in OPTIONAL_SUBMODULES:
        try:
            subs[sub] = importlib.import_module(f"{name}.{sub}")
        except ModuleNotFoundError:
            pass
    home = {key: package for key in ("PAPER", "ERRATA", "DECISIONS")}
    for sub, mod in subs.items():
        if not hasattr(mod, "__all__"):
            problems.append(f"{name}.{sub} has no __all__")
            continue
        for key in mod.__all__:
            if key in home:
                problems.append(f"{name}.{sub} exports {key!r}, as {home[key].__name__} does")
            home[key] = mod
    if len(exported) > PUBLIC_MAX:
        problems.append(f"{name}.__all__ has {len(exported)} names: at most {PUBLIC_MAX} (the "
                        f"contract's and the paper's observer and design; the rest are "
                        f"imported from their files)")
    for key in exported:
        if key not in home:
            problems.append(f"{name}.__all__ lists {key!r}, which no file of the package "
                            f"exports")
        elif home[key] is not package and getattr(package, key, None) is not getattr(
                home[key], key, None):
            problems.append(f"{name}.{key} is not {home[key].__name__}.{key}")
    systems = f"{name}.systems"
    if "systems" in subs and not any(inspect.isclass(getattr(package, key, None))
                                     and getattr(package, key).__module__ == systems
                                     for key in exported):
        problems.append(f"{name}.__all__ names no observer (a class of systems.py)")
    for key, sub in _HOME.items():
        mod = subs.get(sub)
        if mod is not None and key not in getattr(mod, "__all__", ()):
            problems.append(f"{key} must be defined in {name}.{sub}")
    seen = {}
    for key, mod in home.items():
        obj = getattr(mod, key, None)
        if callable(obj) or inspect.isclass(obj):
            if id(obj) in seen:
                problems.append(f"{mod.__name__}.{key} is an alias of {seen[id(obj)]}")
            seen.setdefault(id(obj), f"{mod.__name__}.{key}")
        if (inspect.isclass(obj) and issubclass(obj, hs.HybridSystem)
                and obj.__module__ != systems):
            problems.append(f"{mod.__name__}.{key} is a HybridSystem defined in "
                            f"{obj.__module__}, not in systems.py")
    if callable(getattr(package, "simulate", None)):
        problems += _signature_problems(
            f"{name}.simulate", package.simulate, [("observer", E), ("x0", E), ("xhat0", None)],
            [("t_max", E), ("noise", None), ("seed", None)], var_keyword=True)
    if callable(getattr(package, "errors", None)):
        problems += _signature_problems(f"{name}.errors", package.errors,
                                        [("arc", E), ("observer", E)], [], False)
    if callable(getattr(package, "reproduce", None)):
        problems += _signature_problems(f"{name}.reproduce", package.reproduce,
                                        [("outdir", E)], [], False)
    figures = getattr(package, "FIGURES", None)
    if figures is not None:
        if not isinstance(figures, (list, tuple)) or not all(isinstance(f, Figure)
                                                             for f in figures):
            problems.append(f"{name}.FIGURES must be a list of observers._common.Figure")
        elif len({f.name for f in figures}) != len(figures):
            problems.append(f"{name}.FIGURES has two figures of one name")
    nr = getattr(package, "NOT_REPRODUCED", None)
    if nr is not None and not (isinstance(nr, dict) and all(
            isinstance(k, str) and isinstance(v, str) and v.strip() for k, v in nr.items())):
        problems.append(f"{name}.NOT_REPRODUCED must map figure names to non-empty reasons")
    return problems
