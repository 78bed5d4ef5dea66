"""Hybrid arcs: solutions on hybrid time domains.

A :class:`HybridArc` holds the samples ``(t, j, x)`` of a solution, time-major,
with a jump stored as two samples at the same t with j and j + 1. Besides the
samples it offers interpolation inside the flows (:meth:`HybridArc.at`,
:meth:`HybridArc.interpolate`), windows of hybrid time
(:meth:`HybridArc.restrict`, :meth:`HybridArc.select`), maps of the state
(:meth:`HybridArc.transform`), pickling whatever the system holds, and a
versioned, validated ``.npz`` format (:meth:`HybridArc.save`,
:meth:`HybridArc.load`).
"""
from __future__ import annotations

import os
import pickle

import numpy as np

# the class's bases and records live in private modules; Choice and _Mapped are
# names of this module too (explore imports Choice, pickles of arcs name _Mapped)
from ._arc_access import _ArcAccess, _Mapped, _Sliced  # noqa: F401
from ._arc_checks import _ArcChecks
from ._arc_io import FORMAT_VERSION, MAX_FILE_BYTES, ArcFileError, _ArcFile
from ._arc_records import ArcValues, Choice, Crossings  # noqa: F401
from .rules import Termination  # one source of the causes

__all__ = ["HybridArc", "Termination", "ArcValues", "ArcFileError", "FORMAT_VERSION", "load",
           "MAX_FILE_BYTES", "Crossings"]

#: validate every arc an integration path returns (``HYBRIDSIM_CHECK_ARCS=1``;
#: the test suite sets it): a defect of the engine then fails at its run
CHECK_ARCS = os.environ.get("HYBRIDSIM_CHECK_ARCS", "") not in ("", "0")
#: the attributes a pooled arc makes on first access (``HybridArc._pooled``)
_POOLED = frozenset(("t", "j", "x", "xdot", "stats"))


def _describe(system):
    """A short description of a system, kept when the object cannot travel."""
    if system is None:
        return None
    cls = type(system)
    desc = f"{cls.__module__}.{cls.__qualname__}"
    comps = getattr(system, "components", None)
    if comps:
        desc += f" with components {list(comps)}"
    return desc


def _picklable(obj) -> bool:
    try:
        pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - any failure means: does not travel
        return False
    return True


def load(path, *, max_bytes: int = MAX_FILE_BYTES):
    """Load what :meth:`HybridArc.save` wrote: a :class:`HybridArc` (an
    explore leaf with its ``choices``). The file format holds arcs only.

    Parameters and errors as :meth:`HybridArc.load`.

    Examples
    --------
    >>> import os, tempfile, hybridsim as hs
    >>> tree = hs.explore(hs.HybridSystem.from_functions(
    ...     flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
    ...     flow_set=lambda x: x[0] <= 2.0, jump_set=lambda x: x[0] >= 1.0, state_dim=1),
    ...     [0.0], t_max=3.0, j_max=1)
    >>> path = tree.leaves[0].save(os.path.join(tempfile.mkdtemp(), "leaf"))
    >>> [str(c) for c in hs.load(path).choices]
    ['jump to successor 0 at (t=1, j=0)']
    """
    return HybridArc.load(path, max_bytes=max_bytes)


class HybridArc(_ArcAccess, _ArcChecks, _ArcFile):
    """A solution of a hybrid system on its hybrid time domain.

    Parameters
    ----------
    t, j, x : array_like, shapes (N,), (N,), (N, n)
        The samples (N may be 0: an empty arc).
    termination : Termination or None
        Why the run stopped.
    message, exception, components :
        See the attributes.
    segments : list of (t_a, t_b, j, dense), optional
        The solver's dense outputs: ``dense(s)`` is the state at s in
        [t_a, t_b] on the flow of jump count j (scipy's ``DenseOutput``
        convention: an array of m times gives an (n, m) array).
    system : HybridSystem, optional
        The system the arc solves (dropped, keeping its description, when
        the arc is pickled and the system does not pickle).
    xdot : array_like, shape (N, n), optional
        The flow map f at each sample (NaN rows where unknown, e.g. at
        samples that are not in C). Used for cubic Hermite interpolation.
    stats : dict, optional
        Statistics of the run (steps, function evaluations, events...),
        carried through :meth:`restrict`, :meth:`component` and files.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Ordinary time of each sample (non-decreasing).
    j : ndarray of int, shape (N,)
        Jump counter of each sample. A jump appears as two consecutive samples
        with the same t and j, j + 1.
    x : ndarray, shape (N, n)
        The state at each sample (time-major).
    xdot : ndarray, shape (N, n), or None
        The flow derivative at each sample where known.
    stats : dict or None
        Statistics of the run.
    termination : Termination
        Why the run stopped; ``termination.message`` explains it.
    message : str
        A sentence saying why the run stopped (with details where known).
    exception : BaseException or None
        The exception a user map raised (``termination is MAP_ERROR``).
    components : dict or None
        ``{name: slice}`` of an interconnection's parts (see :meth:`component`).
    system : HybridSystem or None
        The system, where the arc still holds it.
    system_description : str or None
        The system's class (and components), kept when the object is not.
    crossings : Crossings or None
        The crossings of the system's watched functions (``watch``, rule 11
        of :class:`hybridsim.HybridSystem`) along the run, or None where it
        watches nothing (and on arcs made from a run's: windows, components,
        transforms).

    Notes
    -----
    ``arc[name]`` is :meth:`component`; an arc is not iterable (``list(arc)``
    raises a ``TypeError`` that says where the samples are:
    ``zip(arc.t, arc.j, arc.x)`` iterates them). Pickling keeps the system
    and the dense outputs only when they pickle.

    Examples
    --------
    >>> import numpy as np
    >>> arc = HybridArc([0.0, 1.0, 1.0, 2.0], [0, 0, 1, 1],
    ...                 [[0.0], [1.0], [0.0], [1.0]], Termination.T_MAX)
    >>> arc.jump_times, arc.jump_count
    (array([1.]), 1)
    >>> arc.at(0.5), arc.at(1.0, j=0), arc.at(1.0)
    (array([0.5]), array([1.]), array([0.]))
    """

    #: the crossings of the system's watched functions (:class:`Crossings`), or
    #: None where the system watches nothing
    crossings = None

    def __init__(self, t, j, x, termination, message=None, exception=None,
                 components=None, segments=None, system=None, *, xdot=None,
                 stats=None):
        self.t = np.asarray(t, dtype=float)
        jj = np.asarray(j)
        self.j = jj.astype(np.int64)
        self.x = np.asarray(x, dtype=float)
        if self.t.ndim != 1 or self.j.ndim != 1 or self.x.ndim != 2 \
                or len(self.x) != len(self.t) or len(self.j) != len(self.t):
            raise ValueError(f"HybridArc: expected t (N,), j (N,), x (N, n); got shapes "
                             f"{self.t.shape}, {self.j.shape}, {self.x.shape}")
        if jj.dtype.kind == "f" and not np.array_equal(jj, self.j):
            raise ValueError("HybridArc: j must hold integers (jump counts), got "
                             f"non-integer values such as {jj[jj != self.j][0]!r}")
        if xdot is not None:
            xdot = np.asarray(xdot, dtype=float)
            if xdot.shape != self.x.shape:
                raise ValueError(f"HybridArc: xdot must have the shape of x, (N, n) = "
                                 f"{self.x.shape}; got {xdot.shape}")
        if stats is not None and not isinstance(stats, dict):
            raise TypeError(f"HybridArc: stats must be a dict or None, got "
                            f"{type(stats).__name__}")
        self.xdot = xdot
        self.stats = stats
        self.termination = termination
        self.message = message or (termination.message if termination else "")
        self.exception = exception
        self.components = components
        self.system = system
        self.system_description = _describe(system)
        self._segments = segments  # list of (t_a, t_b, j, dense) or None
        self._cache = {}

    @classmethod
    def _trusted(cls, t, j, x, termination, message=None, exception=None,
                 components=None, segments=None, system=None, xdot=None, stats=None,
                 description=None):
        """An arc from the engine's own output, without re-validating it.

        ``t`` (N,) float, ``j`` (N,) int64 and ``x``/``xdot`` (N, n) float
        arrays, as every integration path produces them; saves the checks of
        :meth:`__init__` (a large share of a short run in a batch of
        thousands). ``description``: ``_describe(system)``, where the caller
        keeps it.
        """
        arc = cls.__new__(cls)
        # one dict, set at once (faster than an attribute at a time: a short
        # compiled run's arc is made in about a microsecond)
        arc.__dict__ = {
            "t": t, "j": j, "x": x, "xdot": xdot, "stats": stats, "termination": termination,
            "message": message or (termination.message if termination else ""),
            "exception": exception, "components": components, "system": system,
            "system_description": description if description is not None else
            _describe(system), "_segments": segments, "_cache": {}}
        if CHECK_ARCS:
            arc.validate(where="the engine's arc")
        return arc

    @classmethod
    def _pooled(cls, pool, starts, ends, termination, message, system, stats_of):
        """Arcs of a batch's runs, run ``i``'s samples rows ``starts[i]:ends[i]``
        of the batch's compact pool ``pool = (t, j, x, xdot)`` and its stats
        ``stats_of(i)`` (a dict), made on first access: a batch of thousands
        of short runs otherwise spends most of its Python time slicing.
        ``termination`` and ``message``: one each, for every run. The arcs
        share one record of the pool (each holds its index): two objects an
        arc for the garbage collector to visit, not four.
        """
        like = {"termination": termination, "message": message, "exception": None,
                "components": None, "system": system, "system_description": _describe(system),
                "_segments": None, "_cache": None, "_pool": (pool, starts, ends, stats_of),
                "_row": 0}
        new, copy = cls.__new__, like.copy
        out = []
        for i in range(len(starts)):
            arc = new(cls)
            arc.__dict__ = d = copy()
            d["_cache"] = {}
            d["_row"] = i
            out.append(arc)
        if CHECK_ARCS:
            for arc in out:
                arc.validate(where="the engine's arc")
        return out

    def _unpool(self):
        """A pooled arc's samples and stats, set (see :meth:`_pooled`)."""
        d = self.__dict__
        pooled, i = d.get("_pool"), d.get("_row")
        # the fields are set before the keys are dropped: threads may race here
        if pooled is not None and i is not None:
            (t, j, x, xdot), starts, ends, stats_of = pooled
            a, b = starts[i], ends[i]
            self.t, self.j, self.x, self.xdot = t[a:b], j[a:b], x[a:b], xdot[a:b]
            self.stats = stats_of(i)
            d.pop("_pool", None)
            d.pop("_row", None)

    def __getattr__(self, name):
        # only for attributes not set: a pooled arc's samples and stats
        if name in _POOLED and "_pool" in self.__dict__:
            self._unpool()
            return self.__dict__[name]
        raise AttributeError(f"'{type(self).__name__}' object has no attribute {name!r}")

    def _like(self, t, j, x, *, xdot=None, segments=None, components=None,
              system=None, keep=True):
        """A new arc with other samples and this arc's run information."""
        arc = HybridArc(t, j, x, self.termination, self.message, self.exception,
                        self.components if keep else components,
                        self._segments if keep else segments,
                        self.system if keep else system, xdot=xdot,
                        stats=None if self.stats is None else dict(self.stats))
        if keep and self.system is None:
            arc.system_description = self.system_description
        return arc

    # ------------------------------------------------------------------ basics
    def __len__(self):
        return len(self.t)

    def __repr__(self):
        term = self.termination.name if self.termination else None
        if len(self.t) == 0:
            return f"<HybridArc: empty (0 samples), termination={term}>"
        return (f"<HybridArc: {len(self.t)} samples, t in [{self.t[0]:.6g}, "
                f"{self.t[-1]:.6g}], {self.jump_count} jumps, termination={term}>")

    def __iter__(self):
        raise TypeError(
            "a HybridArc is not iterable: its samples are arc.t (N,), arc.j (N,) and "
            "arc.x (N, n) (iterate rows with zip(arc.t, arc.j, arc.x)); arc[name] is "
            "a component of an interconnection (names: arc.components)")

    def __contains__(self, name):
        """True when ``name`` is a component of this interconnection's arc."""
        return bool(self.components) and name in self.components

    def __copy__(self):
        self._unpool()
        new = object.__new__(HybridArc)
        new.__dict__.update(self.__dict__)
        new._cache = {}
        return new

    def __deepcopy__(self, memo):
        import copy
        self._unpool()
        new = object.__new__(HybridArc)
        memo[id(self)] = new
        state = {k: v for k, v in self.__dict__.items() if k != "_cache"}
        new.__dict__.update(copy.deepcopy(state, memo))
        new._cache = {}
        return new

    def __getstate__(self):
        """Pickle state: the system and dense outputs only when they pickle."""
        self._unpool()
        state = self.__dict__.copy()
        state.pop("_cache", None)
        state.pop("_seg_starts", None)
        if state.get("system") is not None and not _picklable(state["system"]):
            state["system"] = None
        if state.get("_segments") and not _picklable(state["_segments"]):
            state["_segments"] = None
        exc = state.get("exception")
        if exc is not None and not _picklable(exc):
            state["exception"] = RuntimeError(f"{type(exc).__name__}: {exc}")
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.__dict__.setdefault("xdot", None)
        self.__dict__.setdefault("stats", None)
        self.__dict__.setdefault("system_description", None)
        self._cache = {}

    def _nonempty(self, what):
        if len(self.t) == 0:
            raise ValueError(f"{what}: the arc is empty (no samples)")

    @property
    def termination_cause(self):
        """Alias of :attr:`termination` (HyEQ toolbox name)."""
        return self.termination

    @property
    def success(self) -> bool:
        """True when the run stopped at t_max or j_max."""
        return bool(self.termination is not None and self.termination.success)

    @property
    def state_dim(self) -> int:
        """The length n of the state."""
        return self.x.shape[1]

    @property
    def x0(self):
        """The first sample of the state."""
        self._nonempty("x0")
        return self.x[0]

    @property
    def xf(self):
        """The last sample of the state."""
        self._nonempty("xf")
        return self.x[-1]

    @property
    def t0(self) -> float:
        """The first time."""
        self._nonempty("t0")
        return float(self.t[0])

    @property
    def tf(self) -> float:
        """The last time."""
        self._nonempty("tf")
        return float(self.t[-1])

    @property
    def jf(self) -> int:
        """The last jump count."""
        self._nonempty("jf")
        return int(self.j[-1])

    @property
    def jump_index(self):
        """Indices k of the post-jump samples (``j[k] == j[k-1] + 1``)."""
        return np.flatnonzero(np.diff(self.j) > 0) + 1

    @property
    def is_jump_start(self):
        """Boolean mask (N,): True at each pre-jump sample (the next one has j + 1).

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> arc.is_jump_start, arc.is_jump_end
        (array([False,  True, False, False]), array([False, False,  True, False]))
        """
        m = np.zeros(len(self.t), dtype=bool)
        m[self.jump_index - 1] = True
        return m

    @property
    def is_jump_end(self):
        """Boolean mask (N,): True at each post-jump sample (j one more than before)."""
        m = np.zeros(len(self.t), dtype=bool)
        m[self.jump_index] = True
        return m

    @property
    def jump_times(self):
        """Times t at which the jumps happened, shape (jump_count,)."""
        return self.t[self.jump_index]

    @property
    def jump_count(self) -> int:
        """The number of jumps, ``j[-1] - j[0]`` (0 for an empty arc)."""
        return int(self.j[-1] - self.j[0]) if len(self.j) else 0

    @property
    def flow_intervals(self):
        """List of ``(t_start, t_end, j)``: the interval [t_j, t_{j+1}] of each j."""
        if len(self.t) == 0:
            return []
        out = []
        starts = np.concatenate(([0], self.jump_index))
        ends = np.concatenate((self.jump_index - 1, [len(self.t) - 1]))
        for a, b in zip(starts, ends):
            out.append((float(self.t[a]), float(self.t[b]), int(self.j[a])))
        return out

    @property
    def flow_lengths(self):
        """Length t_{j+1} - t_j of each interval of flow, shape (jump_count + 1,)."""
        return np.array([b - a for a, b, _ in self.flow_intervals])

    def at(self, t, j=None):
        """The state at hybrid time (t, j), interpolated.

        Parameters
        ----------
        t : float or array_like of floats
            Ordinary time(s).
        j : int or array_like of int, optional
            Jump count(s): a scalar, or one per time (the shape of ``t``).
            ``None``: the last j at each t, i.e. the value after any jumps at t.

        Returns
        -------
        ndarray
            Shape (n,) for a scalar t, else ``np.shape(t) + (n,)``.

        Notes
        -----
        At a stored sample's time the stored sample is returned. Between
        samples the best available interpolant is used: the solver's dense
        output where the run kept it (``simulate(..., dense=True)``), else a
        cubic Hermite polynomial where both neighbouring samples have a finite
        :attr:`xdot` (exact for polynomial flows of degree <= 3, e.g. a
        falling ball), else linear interpolation.

        Raises
        ------
        ValueError
            When (t, j) is not in the hybrid time domain.

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> arc.at([0.25, 1.0, 1.5])[:, 0]
        array([0.25, 0.  , 0.5 ])
        >>> arc.at([1.0, 1.0], j=[0, 1])[:, 0]
        array([1., 0.])
        """
        if isinstance(t, (float, int, np.floating, np.integer)) and not isinstance(t, bool) \
                and (j is None or isinstance(j, (int, np.integer))):
            return self._at_scalar(float(t), j)
        tt, flat, jf = self._hybrid_times(t, j, "at")
        val, _ = self._interp(flat, jf, "at")
        return val.reshape(tt.shape + (self.state_dim,))

    __call__ = at

    def interpolate(self, t_grid, at_jump="end"):
        """The arc on a grid of ordinary time (HyEQ's ``interpolateToArray``).

        Parameters
        ----------
        t_grid : array_like, shape (m,)
            Non-decreasing finite times inside ``[arc.t0, arc.tf]``.
        at_jump : {"end", "start", "mean", "nan", "both"}
            The value at a time where the arc jumps: ``"end"`` after the
            jumps, ``"start"`` before them, ``"mean"`` the average of the two,
            ``"nan"`` NaN, ``"both"`` two rows (before, then after, with their
            j). Elsewhere all rules agree.

        Returns
        -------
        ArcValues
            ``(t, j, x)``: t (m,) the grid (with ``"both"`` each jump time
            twice), j (m,) the jump count used ("start": before the jumps;
            "end", "mean", "nan": after), x (m, n).

        Raises
        ------
        ValueError
            For a grid outside the arc's time range, unsorted or not finite,
            or an unknown ``at_jump``.

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> t, j, x = arc.interpolate([0.5, 1.0, 1.5], at_jump="mean")
        >>> x[:, 0], j
        (array([0.5, 0.5, 0.5]), array([0, 1, 1]))
        >>> arc.interpolate([1.0], at_jump="both").j
        array([0, 1])
        """
        return self._interpolate(t_grid, at_jump)

    def evaluate(self, fn):
        """Evaluate ``fn(x, t, j)`` (or ``fn(x)``, ``fn(x, t)``) at every sample.

        Returns an array of shape (N, ...) stacking the results.

        Raises
        ------
        ValueError
            fn's values have different shapes at different samples (naming
            the first sample whose shape differs from the first one's).

        Examples
        --------
        >>> arc = HybridArc([0, 1], [0, 0], [[1.0], [2.0]], None)
        >>> arc.evaluate(lambda x, t: x[0] + t)
        array([1., 3.])
        """
        from .system import as_map
        f = as_map(fn, "fn")
        vals = [np.asarray(f(x, t, j, None)) for x, t, j in zip(self.x, self.t, self.j)]
        if vals:
            s0 = vals[0].shape
            for k, v in enumerate(vals):
                if v.shape != s0:
                    raise ValueError(
                        f"evaluate: fn must return values of one shape at every sample; "
                        f"sample 0 (t={float(self.t[0])!r}, j={int(self.j[0])}) gave shape "
                        f"{s0}, sample {k} (t={float(self.t[k])!r}, j={int(self.j[k])}) shape "
                        f"{v.shape}")
        return np.array(vals)

    def transform(self, fn):
        """A new arc with the state replaced by ``fn(x, t, j)`` at each sample.

        Parameters
        ----------
        fn : callable
            ``fn(x)``, ``fn(x, t)`` or ``fn(x, t, j)`` returning a scalar or a
            1-D array of the same length at every sample.

        Returns
        -------
        HybridArc
            Same t, j, termination and stats; x of shape (N, m). Dense
            outputs are mapped through ``fn`` (so :meth:`at` stays exact);
            xdot, components and the system are dropped (they describe the
            original state).

        Raises
        ------
        ValueError
            When fn returns complex, non-numeric or non-finite values (naming
            the sample and its (t, j)), arrays of more than one dimension, or
            arrays of different lengths. Non-finite values pass only at the
            last sample of a ``NON_FINITE`` run where x itself is not finite
            (as :meth:`validate` allows); the mapped dense outputs refuse
            them too when evaluated.

        Examples
        --------
        >>> arc = HybridArc([0, 1], [0, 0], [[3.0, 4.0], [0.0, 1.0]], None)
        >>> arc.transform(lambda x: np.hypot(*x)).x[:, 0]
        array([5., 1.])
        """
        return self._transform(fn)

    # ------------------------------------------------------------ selection
    def restrict(self, t=None, j=None):
        """The arc on a window of hybrid time: t in [a, b] and j in [lo, hi].

        Parameters
        ----------
        t : (float, float), optional
            Closed interval [a, b] of ordinary time (``None`` for an open end).
        j : int or (int, int), optional
            One jump count, or a closed range of them.

        Returns
        -------
        HybridArc
            The stored samples in the window, plus samples interpolated (as by
            :meth:`at`) at a and b where they fall inside a flow between
            stored samples; empty (0 samples) when the window does not meet
            the hybrid time domain. Termination, components, system, dense
            outputs and stats are kept. Never raises for a valid window.

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> r = arc.restrict(t=(0.5, 1.5))
        >>> r.t, r.j, r.x[:, 0]
        (array([0.5, 1. , 1. , 1.5]), array([0, 0, 1, 1]), array([0.5, 1. , 0. , 0.5]))
        >>> len(arc.restrict(t=(0.2, 0.4), j=1))
        0
        """
        return self._restrict(t, j, "restrict")

    def select(self, t=None, j=None):
        """The arc on a window of hybrid time; like :meth:`restrict` but raises
        when the window does not meet the hybrid time domain.

        Parameters
        ----------
        t : (float, float), optional
            Closed interval [a, b] of ordinary time.
        j : int or (int, int), optional
            One jump count, or a closed range of them.

        Raises
        ------
        TypeError
            When ``t`` is not an (a, b) pair (``select(t=5)``).
        ValueError
            When no (t, j) of the arc's domain lies in the window.

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> arc.select(j=1).t
        array([1., 2.])
        """
        r = self._restrict(t, j, "select")
        if len(r) == 0:
            dom = ("the arc is empty" if len(self.t) == 0 else
                   f"the arc has t in [{self.t[0]}, {self.t[-1]}], j in "
                   f"[{self.j[0]}, {self.j[-1]}]")
            raise ValueError(f"select: no sample with t in {t} and j in {j}: the window "
                             f"does not meet the hybrid time domain ({dom})")
        return r

    # ---------------------------------------------------------- components
    def component(self, name):
        """The part of an interconnection's state named ``name``, as an arc.

        Examples
        --------
        >>> arc = HybridArc([0.0], [0], [[1.0, 2.0]], None,
        ...                 components={"a": slice(0, 1), "b": slice(1, 2)})
        >>> arc["b"].x
        array([[2.]])
        """
        if not self.components:
            raise KeyError("component: this arc is not the solution of an "
                           "interconnection (it has no named components)")
        if name not in self.components:
            raise KeyError(f"component: no component named {name!r}; "
                           f"have {list(self.components)}")
        sl = self.components[name]
        sub = self.system.systems[name] if self.system is not None and hasattr(
            self.system, "systems") else None
        segs = None if not self._segments else [
            (a, b, j, _Sliced(sol, sl)) for (a, b, j, sol) in self._segments]
        arc = self._like(self.t, self.j, self.x[:, sl], keep=False, segments=segs,
                         components=getattr(sub, "components", None), system=sub,
                         xdot=None if self.xdot is None else self.xdot[:, sl])
        if sub is None and self.system_description is not None:
            arc.system_description = f"component {name!r} of {self.system_description}"
        return arc

    def __getitem__(self, name):
        return self.component(name)

    def _dropped(self, what):
        if self.system_description is not None:
            return (f"{what}: this arc no longer holds its system ({self.system_description}):"
                    f" an arc loaded from a file, or pickled with a system that does not "
                    f"pickle (e.g. one holding a lambda), keeps only its description; "
                    f"evaluate arc.evaluate(system.output) with the system at hand, or "
                    f"write the system's maps as module-level functions or methods so "
                    f"that it pickles")
        return (f"{what}: the arc does not know its system (built without one); "
                f"evaluate arc.evaluate(system.output) instead")

    def outputs(self, name=None):
        """The output map evaluated along the arc, shape (N, q).

        ``name`` selects a component of an interconnection. Needs the system:
        an arc loaded from a file, or pickled with a system that does not
        pickle, raises a ``ValueError`` saying so.
        """
        if name is not None and self.system is not None and hasattr(self.system, "outputs"):
            # through the interconnection: feedthrough outputs see their inputs
            out = self.system.outputs
            return np.array([np.atleast_1d(np.asarray(out(x, t, j)[name], dtype=float))
                             for x, t, j in zip(self.x, self.t, self.j)])
        if self.system is None:
            raise ValueError(self._dropped("outputs"))
        arc = self.component(name) if name is not None else self
        if arc.system is None:
            raise ValueError(arc._dropped("outputs"))
        c = arc.system._compile()
        if c.h_u:
            raise ValueError("outputs: this system's output reads its input u, which the "
                             "arc does not know; evaluate it through its interconnection")
        return np.array([np.atleast_1d(np.asarray(c.h(x, t, j, None), dtype=float))
                         for x, t, j in zip(arc.x, arc.t, arc.j)])

    # ----------------------------------------------------------------- checks
    def validate(self, *, t_max=None, j_max=None, where="validate"):
        """Check the invariants of a hybrid arc; return self, or raise ValueError.

        Vectorized and O(N): cheap enough to run after every simulation.

        Parameters
        ----------
        t_max : float, optional
            The run's ``t_max``: no sample after it, and a run that ended
            ``T_MAX`` has its last sample at ``t_max``.
        j_max : int, optional
            The run's ``j_max``: at most that many jumps, and a run that
            ended ``J_MAX`` made exactly ``j_max``.
        where : str, optional
            Prefix of the error messages.

        Returns
        -------
        HybridArc
            ``self``, so that ``arc.validate()`` chains.

        Raises
        ------
        ValueError
            At the first sample k that breaks one of (message naming k and
            its (t, j)): shapes t (N,), j (N,) of ints, x (N, n), xdot
            (N, n); t finite and non-decreasing; j stepping by 0 or 1; a jump
            (j + 1) at the t of the sample before it; no duplicate sample
            (same t and j as the one before); x finite (except the last
            sample of a run that ended ``NON_FINITE``); the limits above.

        Examples
        --------
        >>> HybridArc([0, 1], [0, 0], [[0], [1]], Termination.T_MAX).validate(t_max=1).t
        array([0., 1.])
        >>> HybridArc([0, 1, 1], [0, 0, 0], [[0], [1], [1]], None).validate()
        ... # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        ValueError: validate: sample 2 (t=1.0, j=0) repeats the sample before it ...
        """
        return self._validate(t_max, j_max, where)

    def save(self, path):
        """Validate the arc and save it to an ``.npz`` file (format :data:`FORMAT_VERSION`).

        Parameters
        ----------
        path : str, path-like or binary file
            ``.npz`` is appended when missing (as :meth:`load` does).

        Returns
        -------
        pathlib.Path or the file object
            Where the arc was written.

        Raises
        ------
        ValueError
            When the arc is not valid (:meth:`validate`), or not one the
            engine makes (a state of dimension 0, a negative jump count);
            nothing is written.
        IsADirectoryError
            When ``path`` names a directory (``"results/"``, an existing
            directory, or one named ``path + ".npz"``).

        Notes
        -----
        Stores t, j, x, the termination and message, the components (any
        names of str, int, float or tuples of them), xdot and stats (as JSON)
        when present, the system's description, an explore leaf's
        ``choices``, and the :attr:`crossings` of watched functions. Not
        stored: the system, the dense outputs, the exception (its text is in
        the message); an empty arc (a window with no
        samples) is stored without its termination cause.

        Examples
        --------
        >>> import tempfile, os
        >>> arc = HybridArc([0, 1], [0, 0], [[0.0], [1.0]], Termination.T_MAX)
        >>> d = tempfile.mkdtemp()
        >>> arc.save(os.path.join(d, "run")).name
        'run.npz'
        >>> HybridArc.load(os.path.join(d, "run")).x[:, 0]
        array([0., 1.])
        """
        return self._save(path)

    @classmethod
    def load(cls, path, *, max_bytes: int = MAX_FILE_BYTES):
        """Load and validate an arc written by :meth:`save`.

        Parameters
        ----------
        path : str, path-like or binary file
            When ``path`` does not exist and ``path + ".npz"`` does, that file.
            It must be a regular file (or a symlink to one): a FIFO, a
            device (``/dev/zero``), a socket or a directory is refused before
            anything is read.
        max_bytes : int
            The most the file, and its arrays once decompressed, may hold
            (default :data:`MAX_FILE_BYTES`, 16 GiB).

        Returns
        -------
        HybridArc
            With ``system`` None (``system_description`` says what it was).

        Raises
        ------
        FileNotFoundError
            When neither ``path`` nor ``path.npz`` exists.
        ArcFileError
            (a ``ValueError``) naming the file and what is wrong, for every
            damaged, foreign or crafted file: truncated or corrupt, not an
            ``.npz`` archive, a damaged zip directory, missing or unexpected
            arrays (naming them and the format version found), an
            unsupported ``format_version`` (not an int among the versions
            this hybridsim reads), arrays of the wrong
            dtype or shape or declaring more data than they hold, object
            arrays (pickled data is never loaded), components/stats that are
            not JSON of the expected form, an unknown termination name,
            samples that break :meth:`validate`, and arcs no run of the
            engine makes (a state of dimension 0, a negative jump count, no
            samples with a termination cause); a path that is not a regular
            file, or more than ``max_bytes``.

        Examples
        --------
        See :meth:`save`.
        """
        return cls._load(path, max_bytes)

    def to_pandas(self, names=None):
        """A pandas DataFrame with columns t, j and one per state component.

        Requires the optional ``pandas`` extra.
        """
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover
            raise ImportError("to_pandas needs pandas: pip install 'hybridsim[pandas]'") from e
        n = self.state_dim
        if names is None:
            names = [f"x{i}" for i in range(n)]
            if self.components:
                names = [None] * n
                for cname, sl in self.components.items():
                    for k, i in enumerate(range(*sl.indices(n))):
                        names[i] = f"{cname}[{k}]"
        if len(names) != n:
            raise ValueError(f"to_pandas: names must have length {n}, got {len(names)}")
        df = pd.DataFrame(self.x, columns=list(names))
        df.insert(0, "j", self.j)
        df.insert(0, "t", self.t)
        return df


def _one_sample(x0, kwargs, cause, detail, exc=None, system=None):
    """A one-sample arc at (t0, j0, x0) ending with ``cause`` (x0 None: unknown)."""
    try:
        x = np.empty((1, 0)) if x0 is None else np.array(x0, dtype=float).reshape(1, -1)
    except (TypeError, ValueError):
        x = np.empty((1, 0))
    return HybridArc([float(kwargs.get("t0", 0.0))], [int(kwargs.get("j0", 0))], x, cause,
                     f"{cause.message}: {detail}", exc,
                     components=getattr(system, "components", None), system=system)
