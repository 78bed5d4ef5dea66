"""The small records of an arc: :class:`ArcValues` (what
:meth:`HybridArc.interpolate` returns), :class:`Choice` (a choice an explore
leaf took) and :class:`Crossings` (the crossings of a system's watched
functions). Re-exported by :mod:`hybridsim.arc`.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class ArcValues(NamedTuple):
    """Values of an arc on a grid of ordinary time, from :meth:`HybridArc.interpolate`.

    Unpack it as ``t, j, x = arc.interpolate(grid)``.

    Attributes
    ----------
    t : ndarray, shape (m,)
        The times (the grid; with ``at_jump="both"`` a jump time appears twice).
    j : ndarray of int, shape (m,)
        The jump count of each row.
    x : ndarray, shape (m, n)
        The state at (t, j).
    """

    t: np.ndarray
    j: np.ndarray
    x: np.ndarray


class Choice(NamedTuple):
    """A choice taken at a branch point (t, j, x).

    ``kind``: ``"jump"`` (to successor ``value`` of the jump map, 0 for a
    single-valued one; None where j_max allows no more jumps: the solution
    ends there, as :func:`hybridsim.simulate`'s), ``"flow"`` (flow on through C ∩ D) or ``"dwell"``
    (jump after ``value`` time units in C ∩ D).
    """

    t: float
    j: int
    x: np.ndarray
    kind: str
    value: float | int | None

    def __str__(self):
        at = f"(t={self.t:.10g}, j={self.j})"
        if self.kind == "jump" and self.value is None:
            return f"jump, with no jump left (j_max), at {at}"
        if self.kind == "jump":
            return f"jump to successor {self.value} at {at}"
        if self.kind == "flow":
            return f"flow on at {at}"
        return f"dwell {self.value:.10g} in C ∩ D from {at}"


class Crossings:
    """The crossings of a system's watched functions along a run's flows.

    A system's ``watch`` (rule 11 of :class:`hybridsim.HybridSystem`)
    returns m values; each time one of them crosses 0 during a flow the run
    records it here, in hybrid-time order, without a jump and without
    changing the solution.

    Attributes
    ----------
    t : ndarray, shape (K,)
        The crossing times, each located to 4 ulp on the step's dense
        output: the first time, within that bracket, at which the function
        has crossed (on or past 0).
    j : ndarray of int, shape (K,)
        The jump count of the flow it happened on.
    which : ndarray of int, shape (K,)
        The index of the function (0 for a scalar ``watch``).
    direction : ndarray of int, shape (K,)
        1 rising (from below 0 to 0 or above), -1 falling.
    x : ndarray, shape (K, n)
        The state at ``(t, j)``.

    Examples
    --------
    >>> c = Crossings([0.5, 1.5], [0, 0], [0, 0], [1, -1], [[0.0], [0.0]])
    >>> len(c), c.select(direction=-1).t
    (2, array([1.5]))
    """

    _FIELDS = ("t", "j", "which", "direction", "x")

    def __init__(self, t, j, which, direction, x):
        self.t = np.asarray(t, dtype=float).reshape(-1)
        self.j = np.asarray(j, dtype=np.int64).reshape(-1)
        self.which = np.asarray(which, dtype=np.int64).reshape(-1)
        self.direction = np.asarray(direction, dtype=np.int64).reshape(-1)
        k = len(self.t)
        x = np.asarray(x, dtype=float)
        self.x = x.reshape(k, -1) if k else x.reshape(0, x.shape[-1] if x.ndim == 2 else 0)
        if not (len(self.j) == len(self.which) == len(self.direction) == len(self.x) == k):
            raise ValueError(f"Crossings: t, j, which, direction and x must have one row "
                             f"per crossing; got lengths {k}, {len(self.j)}, "
                             f"{len(self.which)}, {len(self.direction)}, {len(self.x)}")
        if not np.isin(self.direction, (-1, 1)).all():
            raise ValueError("Crossings: direction must be 1 (rising) or -1 (falling)")

    def __len__(self):
        return len(self.t)

    def __repr__(self):
        return f"<Crossings: {len(self)} crossings>"

    def __eq__(self, other):
        if not isinstance(other, Crossings):
            return NotImplemented
        return all(np.array_equal(getattr(self, k), getattr(other, k))
                   for k in self._FIELDS)

    __hash__ = None

    def select(self, which=None, direction=None):
        """The crossings of function ``which`` and/or of one ``direction`` (1 or -1)."""
        keep = np.ones(len(self), bool)
        if which is not None:
            keep &= self.which == which
        if direction is not None:
            if direction not in (-1, 1):
                raise ValueError(f"direction must be 1 (rising) or -1 (falling), got "
                                 f"{direction!r}")
            keep &= self.direction == direction
        return Crossings(self.t[keep], self.j[keep], self.which[keep], self.direction[keep],
                         self.x[keep])
