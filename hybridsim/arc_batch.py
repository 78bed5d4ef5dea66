"""A batch's runs as arrays: :class:`ArcBatch`, what :func:`hybridsim.simulate_many` returns.

A Monte Carlo study reads a few numbers of every run (where it ended, why,
when it jumped), not every sample of every arc. An :class:`ArcBatch` is the
list of the batch's arcs, as before, with those numbers as arrays computed
at once on first access: the compiled path's arcs are views of one compact
pool of samples, made on first access, and the batch reads the pool itself
(a few numpy operations for the whole batch, no arc touched).
"""
from __future__ import annotations

import numpy as np

from .arc import HybridArc

__all__ = ["ArcBatch"]


class ArcBatch(list):
    """The arcs of a batch (a ``list`` of :class:`HybridArc`, one per row, in
    order) and their fields as arrays.

    Indexing, iteration, ``len``, slicing (a slice is an ``ArcBatch``),
    ``==``, pickling and every other list behaviour are the list's. The
    fields are computed together on the first access to one of them and
    kept until the list changes: from the batch's pools of samples where the
    arcs are still views of one (the compiled path's arcs that ended at
    ``t_max`` or ``j_max``; a batch as the compiled path returns it reads
    them without visiting those arcs at all), from the arcs otherwise.
    :meth:`hybridsim.estimate.Stats.update` reads such a batch's rows off the
    pools too.

    Parameters
    ----------
    arcs : iterable of HybridArc
        The runs, in order; none may be empty (no samples).
    state_dim : int, optional
        The state's dimension n, which shapes :attr:`final_states` of an
        empty batch as (0, n) (default: read off the first arc, 0 for none).

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> from hybridsim.library import Timer
    >>> batch = hs.simulate_many(Timer(1.0), [[0.0], [0.5]], t_max=2.2)
    >>> len(batch), batch[1].jump_count                    # a list of arcs, as before
    (2, 2)
    >>> batch.jump_counts, batch.final_states[:, 0].round(6)
    (array([2, 2]), array([0.2, 0.7]))
    >>> batch.jump_times.round(6)                           # padded with NaN
    array([[1. , 2. ],
           [0.5, 1.5]])
    >>> batch.jump_times_flat.round(6), batch.jump_offsets  # ragged: row i is flat[o[i]:o[i+1]]
    (array([1. , 2. , 0.5, 1.5]), array([0, 2, 4]))
    >>> [c.name for c in batch.causes], batch.success
    (['T_MAX', 'T_MAX'], array([ True,  True]))
    """

    def __init__(self, arcs=(), state_dim: int | None = None):
        super().__init__(arcs)
        self._state_dim = None if state_dim is None else int(state_dim)
        self._fields = None
        self._runs = None

    @classmethod
    def _of_pools(cls, arcs, state_dim, runs):
        """A batch whose rows ``runs`` (a list of ``(pool, rows, starts, ends,
        termination)``: row ``rows[k]``'s samples are rows ``starts[k]:ends[k]``
        of ``pool = (t, j, x, xdot)``, its cause ``termination``) are the
        engine's own record of them: the fields read the pools for those rows
        without visiting their arcs (kept until the list changes)."""
        out = cls(arcs, state_dim)
        out._runs = runs
        return out

    # ------------------------------------------------------------------ the list
    def __getitem__(self, key):
        if isinstance(key, slice):
            return ArcBatch(super().__getitem__(key), self._state_dim)
        return super().__getitem__(key)

    def __getstate__(self):
        return {"_state_dim": self._state_dim}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._fields = None
        self._runs = None

    def _changed(self):
        self.__dict__["_fields"] = None
        self.__dict__["_runs"] = None

    # ------------------------------------------------------------------ the fields
    @property
    def final_states(self) -> np.ndarray:
        """The last state of each run, shape (N, n).

        Raises
        ------
        ValueError
            The rows' states have different dimensions (a sweep over systems
            of several sizes).
        """
        f = self._computed()
        if f["xf"] is None:
            raise ValueError(f"final_states: the batch's states have different dimensions "
                             f"{sorted(f['dims'])}; read each arc's xf")
        return f["xf"]

    @property
    def final_times(self) -> np.ndarray:
        """The last time t of each run, shape (N,)."""
        return self._computed()["tf"]

    @property
    def final_jumps(self) -> np.ndarray:
        """The last jump count j of each run, shape (N,) int64."""
        return self._computed()["jf"]

    @property
    def jump_counts(self) -> np.ndarray:
        """The number of jumps of each run (each arc's ``jump_count``), shape (N,) int64."""
        return self._computed()["count"]

    @property
    def causes(self) -> np.ndarray:
        """Why each run stopped: its :class:`hybridsim.Termination`, shape (N,) object
        (``batch.causes == hs.Termination.T_MAX`` compares every row)."""
        return self._computed()["causes"]

    @property
    def success(self) -> np.ndarray:
        """True where the run stopped at t_max or j_max (each arc's ``success``), shape (N,)."""
        return self._computed()["success"]

    @property
    def jump_offsets(self) -> np.ndarray:
        """Row i's jump times are ``jump_times_flat[o[i]:o[i + 1]]``, shape (N + 1,) int64."""
        return self._computed()["offsets"]

    @property
    def jump_times_flat(self) -> np.ndarray:
        """Every row's jump times (each arc's ``jump_times``) one after the other, in row
        order (ragged, with :attr:`jump_offsets`), shape (total jumps,)."""
        return self._computed()["flat"]

    @property
    def jump_times(self) -> np.ndarray:
        """Every row's jump times, shape (N, K) with K the most jumps of a row; row i's
        first ``jump_counts[i]`` entries are its jump times, the rest NaN."""
        f = self._computed()
        if f["padded"] is None:
            offsets, flat = f["offsets"], f["flat"]
            counts = np.diff(offsets)
            N = len(counts)
            out = np.full((N, int(counts.max()) if N else 0), np.nan)
            rows = np.repeat(np.arange(N), counts)
            out[rows, np.arange(len(flat)) - offsets[:-1][rows]] = flat
            f["padded"] = out
        return f["padded"]

    def _computed(self):
        f = self._fields
        if f is None:
            self._fields = f = _fields(self, self._state_dim, self.__dict__.get("_runs"))
        return f


def _mutating(name):
    base = getattr(list, name)

    def method(self, *args, **kwargs):
        out = base(self, *args, **kwargs)
        self._changed()
        return out
    method.__name__ = name
    method.__doc__ = base.__doc__
    return method


for _name in ("__setitem__", "__delitem__", "__iadd__", "__imul__", "append", "extend",
              "insert", "pop", "remove", "clear", "sort", "reverse"):
    setattr(ArcBatch, _name, _mutating(_name))
del _name


def _fields(arcs, state_dim, runs=None):
    """Every field of :class:`ArcBatch` for ``arcs``: read from the pools of the
    rows the engine recorded (``runs``, see :meth:`ArcBatch._of_pools`) and of
    the arcs that are still views of one (:meth:`HybridArc._pooled`), from the
    arcs otherwise."""
    N = len(arcs)
    causes = np.empty(N, dtype=object)
    if runs is not None:
        return _fields_of_runs(arcs, state_dim, runs, causes)
    groups = {}            # id(pool record) -> (record, rows, rows in the pool)
    others = []
    for i, arc in enumerate(arcs):
        if not isinstance(arc, HybridArc):
            raise TypeError(f"ArcBatch: row {i} is a {type(arc).__name__}, not a HybridArc")
        d = arc.__dict__
        causes[i] = arc.termination
        rec, r = d.get("_pool"), d.get("_row")
        if rec is not None and r is not None:
            g = groups.get(id(rec))
            if g is None:
                groups[id(rec)] = g = (rec, [], [])
            g[1].append(i)
            g[2].append(r)
        else:
            others.append(i)
    pooled = []            # (pool, rows, starts, ends)
    for (pool, starts, ends, _), rows, rs in groups.values():
        rs = np.array(rs, np.int64)
        pooled.append((pool, np.array(rows, np.int64), np.asarray(starts, np.int64)[rs],
                       np.asarray(ends, np.int64)[rs]))
    return _assemble(arcs, state_dim, pooled, others, causes)


def _fields_of_runs(arcs, state_dim, runs, causes):
    """:func:`_fields` from the engine's record ``runs``; the other rows' arcs read."""
    N = len(arcs)
    mine = np.zeros(N, bool)
    success = np.zeros(N, bool)
    pooled = []
    for pool, rows, starts, ends, term in runs:
        rows = np.asarray(rows, np.int64)
        mine[rows] = True
        causes[rows] = term
        success[rows] = term.success
        pooled.append((pool, rows, np.asarray(starts, np.int64), np.asarray(ends, np.int64)))
    others = np.flatnonzero(~mine).tolist()
    for i in others:
        arc = arcs[i]
        if not isinstance(arc, HybridArc):
            raise TypeError(f"ArcBatch: row {i} is a {type(arc).__name__}, not a HybridArc")
        c = causes[i] = arc.termination
        success[i] = c is not None and c.success
    return _assemble(arcs, state_dim, pooled, others, causes, success)


def _assemble(arcs, state_dim, pooled, others, causes, success=None):
    """The fields: rows ``pooled`` (``(pool, rows, starts, ends)``) read off their
    pools at once, rows ``others`` off their arcs; ``causes`` filled (and
    ``success``, or None: read off ``causes``)."""
    N = len(arcs)
    dims = {pool[2].shape[1] for pool, _, _, _ in pooled}
    dims |= {arcs[i].x.shape[1] for i in others}
    if len(dims) > 1:
        n = None
    else:
        n = next(iter(dims)) if dims else state_dim or 0
    xf = None if n is None else np.empty((N, n))
    tf = np.empty(N)
    jf, j0, counts = (np.empty(N, np.int64) for _ in range(3))
    pieces = []            # (rows, counts, the jump times in row order)
    for pool, rows, S, E in pooled:
        T, J, X = pool[0], pool[1], pool[2]
        last = E - 1
        if xf is not None:
            xf[rows] = X[last]
        tf[rows], jf[rows], j0[rows] = T[last], J[last], J[S]
        # the samples after a jump: j one more than the sample before, inside the run
        after = np.flatnonzero(J[1:] > J[:-1]) + 1
        lo, hi = np.searchsorted(after, S, "right"), np.searchsorted(after, E, "left")
        cnt = hi - lo
        counts[rows] = cnt
        within = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        pieces.append((rows, cnt, T[after[np.repeat(lo, cnt) + within]]))
    for i in others:
        arc = arcs[i]
        if len(arc.t) == 0:
            raise ValueError(f"ArcBatch: row {i}'s arc is empty (no samples)")
        if xf is not None:
            xf[i] = arc.x[-1]
        tf[i], jf[i], j0[i] = arc.t[-1], arc.j[-1], arc.j[0]
        jt = arc.jump_times
        counts[i] = len(jt)
        pieces.append((np.array([i]), np.array([len(jt)]), jt))
    offsets = np.zeros(N + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    flat = np.empty(int(offsets[-1]))
    for rows, cnt, values in pieces:
        within = np.arange(len(values)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        flat[np.repeat(offsets[rows], cnt) + within] = values
    if success is None:
        success = np.array([c is not None and c.success for c in causes], dtype=bool)
    return {"xf": xf, "dims": dims, "tf": tf, "jf": jf,
            "count": jf - j0, "causes": causes, "success": success, "offsets": offsets,
            "flat": flat, "padded": None}
