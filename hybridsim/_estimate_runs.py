"""How the studies of :mod:`hybridsim.estimate` run: the checks of their
arguments, the seed sequence of a study, one run's outcome (event, claim or
failure), a batch of runs, and one adaptive multilevel splitting run.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from .rules import FAILURES, Termination


def _positive_int(name, v, allow_inf=False):
    if allow_inf and v == math.inf:
        return math.inf
    if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 1:
        raise ValueError(f"{name} must be a positive int, got {v!r}")
    return int(v)


def _in_open_unit(name, v):
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not 0 < v < 1:
        raise ValueError(f"{name} must be a number in (0, 1), got {v!r}")
    return float(v)


def _seed_sequence(seed):
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if seed is None or (isinstance(seed, numbers.Integral) and not isinstance(seed, bool)
                        and seed >= 0):
        return np.random.SeedSequence(seed)
    raise TypeError(f"seed must be a non-negative int, a numpy SeedSequence or None, "
                    f"got {type(seed).__name__} {seed!r}")


def _outcome(value, event, claim, failures, where):
    """(hit, failed) for one run's result."""
    cause = getattr(value, "termination", None)
    if isinstance(cause, Termination) and cause in FAILURES | {Termination.MAX_STEPS}:
        if failures == "raise":
            raise RuntimeError(f"estimate: {where} ended with {cause.name} "
                               f"({getattr(value, 'message', '')}); pass failures='event' to "
                               f"count failed runs as the event")
        return True, True
    if claim is not None:
        m = claim(value)
        try:
            m = float(m)
        except (TypeError, ValueError):
            raise TypeError(f"estimate: claim must return a real number (a margin), got "
                            f"{type(m).__name__} for {where}") from None
        if math.isnan(m):
            raise ValueError(f"estimate: claim returned NaN for {where}: a margin must be a "
                             f"number (positive: holds, negative: violated)")
        return m < 0, False
    e = event(value)
    if not isinstance(e, (bool, np.bool_)):
        raise TypeError(f"estimate: event must return True or False, got "
                        f"{type(e).__name__} {e!r} for {where}")
    return bool(e), False


def _run_batch(run, gens, start):
    if getattr(run, "batch", False):
        out = run(gens)
        if not isinstance(out, list):         # (a batch, ArcBatch, is kept as it is)
            out = list(out)
        if len(out) != len(gens):
            raise ValueError(f"a batch run must return one result per generator: got "
                             f"{len(out)} for {len(gens)}")
        return out
    return [run(g) for g in gens]


def _ams(simulate, score, x0, target, n, k, rng, max_segments):
    """One adaptive multilevel splitting run: (estimate, segments, iterations).

    The generalized AMS of Bréhier, Gazeau, Goudenège, Lelièvre and Rousset
    (Ann. Appl. Probab. 2016), unbiased for any Markov chain and score: at
    each iteration the level is the k-th smallest maximal score, every
    particle at or below it is killed (ties included), and each is replaced
    by a copy of a surviving particle, cut at its first state scoring above
    the level and continued with fresh noise.
    """
    paths, scores = [], []
    for _ in range(n):
        p = np.asarray(simulate(x0, rng), dtype=float)
        paths.append(p)
        scores.append(np.asarray(score(p), dtype=float).reshape(-1))
    segs, its, log_w = n, 0, 0.0
    smax = np.array([s.max() for s in scores])
    while True:
        level = np.partition(smax, k - 1)[k - 1]
        if level >= target:
            break
        killed = np.flatnonzero(smax <= level)
        alive = np.flatnonzero(smax > level)
        if not len(alive):
            return 0.0, segs, its
        log_w += math.log1p(-len(killed) / n)
        for i in killed:
            src = alive[rng.integers(len(alive))]
            cut = int(np.flatnonzero(scores[src] > level)[0])
            tail = np.asarray(simulate(paths[src][cut], rng), dtype=float)
            paths[i] = np.concatenate([paths[src][:cut + 1], tail[1:]])
            scores[i] = np.concatenate([scores[src][:cut + 1],
                                        np.asarray(score(tail), dtype=float).reshape(-1)[1:]])
            smax[i] = scores[i].max()
            segs += 1
        its += 1
        if segs > max_segments:
            raise RuntimeError(f"splitting: more than max_segments={max_segments} path "
                               f"segments before the level reached {target} (level "
                               f"{level:.6g} after {its} iterations); raise n or max_segments, "
                               f"or use a score closer to the target")
    return math.exp(log_w) * float(np.mean(smax >= target)), segs, its
