"""Theorem-check helpers over hybrid time.

Each takes an arc and a signal along it, given either as an (N, ...) array of
values at the arc's samples or as a callable ``fn(x, t, j)``. The norm of a
vector-valued signal is its Euclidean norm (max-abs with ``norm="inf"``).
Failures name the first violating (t, j), the value and the bound.
"""
from __future__ import annotations

import numpy as np

__all__ = ["signal_norm", "settling_time", "assert_exact_after", "assert_bounded"]


def signal_norm(arc, signal, norm=2):
    """Norm of ``signal`` at every sample of ``arc``, shape (N,)."""
    if callable(signal):
        v = np.asarray(arc.evaluate(signal), dtype=float)
    else:
        v = np.asarray(signal, dtype=float)
    if v.shape[:1] != (len(arc.t),):
        raise ValueError(f"signal must have one value per sample: expected leading "
                         f"dimension {len(arc.t)}, got shape {v.shape}")
    v = v.reshape(len(arc.t), -1)
    if norm == "inf":
        return np.max(np.abs(v), axis=1)
    return np.linalg.norm(v, axis=1)


def _mask(arc, t, j):
    m = np.ones(len(arc.t), dtype=bool)
    if t is not None:
        lo, hi = (t, np.inf) if np.ndim(t) == 0 else t
        m &= (arc.t >= lo) & (arc.t <= hi)
    if j is not None:
        lo, hi = (j, np.inf) if np.ndim(j) == 0 else j
        m &= (arc.j >= lo) & (arc.j <= hi)
    return m


def settling_time(arc, signal, threshold=1e-8, norm=2):
    """The last hybrid time (t, j) at which |signal| exceeds ``threshold``.

    Returns ``(t, j)`` of the last sample above the threshold, or
    ``(arc.t[0], arc.j[0])`` if it never is; ``(inf, None)`` if the final
    sample is still above it (not settled within the arc).
    """
    v = signal_norm(arc, signal, norm)
    above = np.flatnonzero(v > threshold)
    if above.size == 0:
        return float(arc.t[0]), int(arc.j[0])
    k = above[-1]
    if k == len(v) - 1:
        return float("inf"), None
    return float(arc.t[k]), int(arc.j[k])


def assert_exact_after(arc, signal, t=None, j=None, atol=1e-8, norm=2):
    """Assert |signal| <= atol at every sample with t' >= t and j' >= j.

    ``t`` and ``j`` may also be closed ranges ``(lo, hi)``.
    """
    m = _mask(arc, t, j)
    if not m.any():
        raise AssertionError(f"assert_exact_after: no sample with t >= {t} and j >= {j} "
                             f"(arc ends at t={arc.t[-1]}, j={arc.j[-1]})")
    v = signal_norm(arc, signal, norm)
    bad = np.flatnonzero(m & ~(v <= atol))
    if bad.size:
        k = bad[0]
        raise AssertionError(
            f"signal not exact after (t={t}, j={j}): first violation at "
            f"(t={arc.t[k]:.12g}, j={arc.j[k]}) with |signal|={v[k]:.3e} > atol={atol:.1e} "
            f"({bad.size} of {int(m.sum())} samples violate)")


def assert_bounded(arc, signal, bound, t=None, j=None, rtol=0.0, atol=0.0, norm=2):
    """Assert |signal(t, j)| <= bound(t, j) * (1 + rtol) + atol over a range.

    ``bound`` is a callable ``(t, j) -> float`` (vectorised over arrays is
    fine), an array of one value per sample, or a constant.
    """
    m = _mask(arc, t, j)
    if not m.any():
        raise AssertionError("assert_bounded: no sample in the requested range")
    v = signal_norm(arc, signal, norm)
    if callable(bound):
        try:
            b = np.broadcast_to(np.asarray(bound(arc.t, arc.j), dtype=float), v.shape)
        except (TypeError, ValueError):
            b = np.array([float(bound(tt, jj)) for tt, jj in zip(arc.t, arc.j)])
    else:
        b = np.broadcast_to(np.asarray(bound, dtype=float), v.shape)
    lim = b * (1 + rtol) + atol
    bad = np.flatnonzero(m & ~(v <= lim))
    if bad.size:
        k = bad[0]
        raise AssertionError(
            f"bound violated: first at (t={arc.t[k]:.12g}, j={arc.j[k]}) with "
            f"|signal|={v[k]:.6e} > bound={b[k]:.6e} (rtol={rtol}, atol={atol}); "
            f"{bad.size} of {int(m.sum())} samples violate")
