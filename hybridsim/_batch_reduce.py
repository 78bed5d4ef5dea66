"""``hs.simulate_many(..., stats=)``: a batch reduced into a
:class:`hybridsim.estimate.Stats` as its rows finish, no arc kept.

On the compiled path the batch kernel keeps of each row only its end and its
states on the Stats's grid (:func:`hybridsim.compiled._run.simulate_many_compiled`'s
``reduce``); elsewhere the rows' arcs are reduced a chunk at a time
(:meth:`Stats.update`), the same values. Rows that draw (a ``jump_rate``, a
``diffusion``, a ``jump_law``) are keyed ``row_keys(seed, N)[i]``
(:func:`hybridsim.compiled._stochastic.row_keys`'s rule, on every path), so the
same seed gives the same paths on every path, and row ``i`` replays alone as
``hs.simulate(system, x0s[i], ..., seed=key_i)``.
"""
from __future__ import annotations

import numbers
import warnings

import numpy as np

from .rules import CAUSES, FAILED, BatchWarning, Termination

#: rows held at once on the paths that make arcs
_ARC_CHUNK = 1000
#: the grid states a compiled chunk keeps at most (floats): rows per kernel call
_GRID_FLOATS = 1 << 23


def draws(system):
    return any(getattr(system, k, None) is not None
               for k in ("diffusion", "jump_rate", "jump_law"))


def check_stats(stats, system, X):
    """A Stats whose signal fits the system's state, or an error naming ``stats``."""
    # a Stats by what the reduction calls (hybridsim.estimate is above the front door)
    if not all(callable(getattr(stats, a, None)) for a in ("update", "add_states")) \
            or not hasattr(stats, "grid"):
        raise TypeError(f"stats must be a hybridsim.estimate.Stats, got {type(stats).__name__}")
    n = X.shape[1]
    sig = stats.signal
    if isinstance(sig, numbers.Integral) and not -n <= sig < n:
        raise ValueError(f"stats: its signal is component {sig}, but the system's state has "
                         f"{n} components")
    if stats._d is None:
        return
    width = n if sig is None else 1 if not callable(sig) else \
        stats._signal_of(np.array(X[:1], dtype=float), 1).shape[1]
    if width != stats._d:
        raise ValueError(f"stats: it holds a signal of width {stats._d}, but this system's "
                         f"{'state' if sig is None else 'signal'} has width {width}")


def reduce_into(system, X, t_max, j_max, stats, executor, chunks, throw, warn, options,
                front, attributes=None):
    """:func:`hybridsim.simulate_many` with ``stats``: returns ``stats``.
    ``front``: the front door's ``(simulate_many, _auto_backend, _run_row)``
    (:mod:`hybridsim.run`, which calls this: passed, not imported back);
    ``attributes``: the rows' (checked), as ``simulate_many``'s."""
    from ._batch_attributes import Attributes
    from .compiled._stochastic import row_keys
    simulate_many, _auto_backend, _run_row = front
    check_stats(stats, system, X)
    if throw:
        raise ValueError("throw: simulate_many(..., stats=) keeps no arcs to raise with; "
                         "leave throw=False (failed rows are named in one BatchWarning)")
    N, n = X.shape
    options = dict(options)
    keys = None
    if draws(system):
        keys = row_keys(options.pop("seed", None), N)
    backend = options.get("backend")
    if backend == "auto":
        backend = _auto_backend(system, options, executor)
    options.pop("backend", None)
    options.pop("progress", None)
    grid, by_j = stats.grid.astype(np.float64), stats.kind == "j"
    failed = []                                 # (row, cause name)
    rows = None
    compiled = backend == "compiled" and executor is None and \
        getattr(system, "diffusion", None) is None and getattr(system, "jump_law", None) is None
    if compiled and attributes is not None:
        from ._batch_attributes import row_params
        rows = row_params(system, attributes)
        compiled = rows is not None             # else: a row changes the compiled form
    if compiled:
        from .compiled._lower import lower, rebind
        from .compiled._run import simulate_many_compiled
        from .compiled._stochastic import simulate_many_rate
        cs, P = (lower(system), None) if rows is None else rows
        step = max(1, _GRID_FLOATS // max(1, len(grid) * n))
        for a in range(0, N, step):
            b = min(N, a + step)
            Pab = None if P is None else P[a:b]
            if keys is not None:
                out = simulate_many_rate(system, cs, X[a:b], t_max, j_max, options,
                                         keys=keys[a:b], reduce=(grid, by_j), params=Pab)
            else:
                out = simulate_many_compiled(cs, X[a:b], t_max, j_max, throw=False, warn=False,
                                             reduce=(grid, by_j, n), params=Pab, **options)
            have = out.cause >= 0
            if not have.all():
                have[list(out.arcs)] = False
            stats.add_states(out.grid_x[have], out.grid_ok[have])
            if out.arcs:
                rows = sorted(out.arcs)
                arcs = [rebind(out.arcs[i], system) for i in rows]
                stats.update(arcs)
                failed += [(a + i, arc.termination) for i, arc in zip(rows, arcs)
                           if arc.termination in FAILED or
                           arc.termination is Termination.CANCELED]
            bad = np.flatnonzero(have & np.isin(out.cause, _FAILED_CODES))
            failed += [(a + int(i), CAUSES[out.cause[i]]) for i in bad.tolist()]
            if any(c is Termination.CANCELED for _, c in failed):
                break
    else:
        if backend is not None:
            options["backend"] = backend
        for a in range(0, N, _ARC_CHUNK):
            b = min(N, a + _ARC_CHUNK)
            if keys is None:
                arcs = simulate_many(system, X[a:b], t_max, j_max, executor=executor,
                                     chunks=chunks, throw=False, warn=False,
                                     attributes=None if attributes is None else
                                     attributes[a:b], **options)
            else:
                # each row alone, keyed, a failure at x0 its own arc (as simulate_many's)
                kw = dict(options, t_max=t_max, j_max=j_max, throw=False, warn=False)
                setter = None if attributes is None else Attributes(system)
                try:
                    arcs = [_run_row(system, setter, None if setter is None else attributes[i],
                                     X[i], dict(kw, seed=int(keys[i])))[0]
                            for i in range(a, b)]
                finally:
                    if setter is not None:
                        setter.restore()
            stats.update(arcs)
            failed += [(a + i, arc.termination) for i, arc in enumerate(arcs)
                       if arc.termination in FAILED or arc.termination is Termination.CANCELED]
    if warn and failed:
        named = ", ".join(f"row {i}: {c.name}" for i, c in failed[:5])
        more = f"; and {len(failed) - 5} more" if len(failed) > 5 else ""
        warnings.warn(f"simulate_many: {len(failed)} of {N} rows failed or were canceled "
                      f"({named}{more}); their states up to their ends are in the statistics",
                      BatchWarning, stacklevel=3)
    return stats


_FAILED_CODES = np.array([CAUSES.index(c) for c in FAILED] +
                         [CAUSES.index(Termination.CANCELED)], np.int64)
