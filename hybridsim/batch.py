"""Many runs: initial conditions, noise realisations, parameter sweeps."""
from __future__ import annotations

import sys

import numpy as np

from .solve import simulate
from .system import HybridSystem

__all__ = ["simulate_many", "sweep"]


def _chunks(n, k):
    bounds = np.linspace(0, n, k + 1).astype(int)
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def _run_chunk(system, x0s, kwargs):
    return [simulate(system, x0, **kwargs) for x0 in x0s]


def _run_sweep_chunk(make_system, params, x0, kwargs):
    return [simulate(make_system(p), x0, **kwargs) for p in params]


def _spread(executor, chunk_fn, items, args, chunks, bar):
    """Run ``chunk_fn(*args(chunk))`` on the executor for chunks of ``items``, in order."""
    workers = getattr(executor, "_max_workers", None) or 2
    parts = _chunks(len(items), chunks or min(len(items), 4 * workers))
    futs = [executor.submit(chunk_fn, *args(items[a:b])) for a, b in parts]
    out = []
    for fut in futs:
        res = fut.result()
        out.extend(res)
        if bar is not None:
            bar.update(len(res))
    return out


def _bar(progress, total, desc):
    if progress is None:
        progress = bool(getattr(sys.stderr, "isatty", lambda: False)())
    if not progress:
        return None
    from tqdm.auto import tqdm
    return tqdm(total=total, desc=desc, unit="run")


def simulate_many(system, x0s, t_max, j_max=np.inf, *, executor=None, chunks=None,
                  progress=None, **kwargs):
    """Simulate one system from many initial states.

    Parameters
    ----------
    system : HybridSystem
        With ``vectorized = True`` (maps written over (N, n) batches) and no
        executor, the whole batch is integrated together in numpy
        (:func:`hybridsim.batch_vectorized.simulate_vectorized`), each
        trajectory with its own steps, events and jumps. Otherwise the runs
        are looped over (or spread over ``executor``).
    x0s : array_like, shape (N, n)
        One initial state per row.
    t_max, j_max : float, int
        As in :func:`hybridsim.simulate`.
    executor : concurrent.futures.Executor, optional
        Any executor (``ProcessPoolExecutor``, a ``dask.distributed``
        client's ``get_executor()``...). The batch is split into ``chunks``
        (default: 4 per worker, at most N) and the system is pickled to each.
    progress : bool or None
        A progress bar over runs (default: only at a terminal). Each run's
        own bar is switched off.
    **kwargs
        Passed to :func:`hybridsim.simulate` (``priority``, ``rtol``...).

    Returns
    -------
    list of HybridArc
        One arc per row of ``x0s``, in order.
    """
    if not isinstance(system, HybridSystem):
        raise TypeError(f"system must be a HybridSystem, got {type(system).__name__}")
    x0s = np.asarray(x0s, dtype=float)
    n = int(system.state_dim)
    if x0s.ndim != 2 or x0s.shape[1] != n:
        raise ValueError(f"x0s must have shape (N, {n}), got {x0s.shape}")
    kwargs = dict(kwargs, t_max=t_max, j_max=j_max, progress=False)
    if system.vectorized and executor is None:
        from .batch_vectorized import simulate_vectorized
        return simulate_vectorized(system, x0s, **kwargs)
    N = len(x0s)
    bar = _bar(progress, N, "simulate_many")
    try:
        if executor is None:
            out = []
            for x0 in x0s:
                out.append(simulate(system, x0, **kwargs))
                if bar is not None:
                    bar.update(1)
            return out
        return _spread(executor, _run_chunk, x0s, lambda part: (system, part, kwargs),
                       chunks, bar)
    finally:
        if bar is not None:
            bar.close()


def sweep(make_system, params, x0, t_max, j_max=np.inf, *, executor=None, chunks=None,
          progress=None, **kwargs):
    """Simulate ``make_system(p)`` from x0 for every parameter value p.

    Noise realisations go through the same door: let ``p`` be a seed and
    ``make_system`` build the plant with that realisation.

    Parameters
    ----------
    make_system : callable
        ``p -> HybridSystem`` (picklable when an executor is used).
    params : iterable
        Parameter values.
    x0 : array_like, shape (n,), or callable ``p -> x0``
    executor : concurrent.futures.Executor, optional
        As in :func:`simulate_many`.

    Returns
    -------
    list of HybridArc
        One per parameter value, in order.
    """
    if not callable(make_system):
        raise TypeError("make_system must be a callable p -> HybridSystem")
    params = list(params)
    kwargs = dict(kwargs, t_max=t_max, j_max=j_max, progress=False)
    bar = _bar(progress, len(params), "sweep")
    try:
        if executor is None:
            out = []
            for p in params:
                out.append(simulate(make_system(p), x0(p) if callable(x0) else x0, **kwargs))
                if bar is not None:
                    bar.update(1)
            return out
        if callable(x0):
            raise TypeError("x0 must be an array when an executor is used")
        return _spread(executor, _run_sweep_chunk, params,
                       lambda part: (make_system, part, x0, kwargs), chunks, bar)
    finally:
        if bar is not None:
            bar.close()
