"""The invariants of a :class:`hybridsim.HybridArc`: the checks of
:meth:`~hybridsim.HybridArc.validate` (vectorized, O(N)) and what
:meth:`~hybridsim.HybridArc.save` and :meth:`~hybridsim.HybridArc.load`
refuse besides (arcs no run of the engine makes). A base class of
:class:`hybridsim.HybridArc` holds the method.
"""
from __future__ import annotations

import numpy as np

from .rules import Termination


def _check_made(arc, where, empty_ok=False):
    """Refuse an arc no run of the engine makes (after :meth:`HybridArc.validate`)."""
    if arc.x.shape[1] == 0:
        raise ValueError(f"{where}: the state has dimension 0 (x of shape {arc.x.shape}); "
                         f"a hybrid system's state has at least one component")
    if len(arc.j) and int(arc.j.min()) < 0:
        k = int(np.argmax(arc.j < 0))
        raise ValueError(f"{where}: sample {k} has the negative jump count j = {arc.j[k]}")
    if not len(arc.t) and arc.termination is not None and not empty_ok:
        raise ValueError(f"{where}: no samples, yet the run ended {arc.termination.name}: a "
                         f"run has at least its initial sample (an empty window is "
                         f"saved without a termination cause)")


class _ArcChecks:
    """The invariants of an arc (a base of :class:`HybridArc`)."""

    def _validate(self, t_max, j_max, where):
        """:meth:`HybridArc.validate`."""
        from .options import check_count, check_real
        if t_max is not None:
            t_max = check_real("t_max", t_max, allow_inf=True)
        if j_max is not None:
            j_max = check_count("j_max", j_max, allow_inf=True)
        t, j, x, xdot = self.t, self.j, self.x, self.xdot
        shapes = (getattr(t, "shape", None), getattr(j, "shape", None),
                  getattr(x, "shape", None), getattr(xdot, "shape", None))
        if not (isinstance(t, np.ndarray) and isinstance(j, np.ndarray)
                and isinstance(x, np.ndarray) and t.ndim == 1 and j.shape == t.shape
                and x.ndim == 2 and len(x) == len(t)
                and (xdot is None or (isinstance(xdot, np.ndarray)
                                      and xdot.shape == x.shape))):
            raise ValueError(f"{where}: expected t (N,), j (N,), x (N, n) and xdot None or "
                             f"(N, n) arrays; got shapes t {shapes[0]}, j {shapes[1]}, "
                             f"x {shapes[2]}, xdot {shapes[3]}")
        if j.dtype.kind not in "iu" or t.dtype.kind not in "iuf" or x.dtype.kind not in "iuf":
            raise ValueError(f"{where}: expected t and x of floats and j of ints; got "
                             f"dtypes t {t.dtype}, j {j.dtype}, x {x.dtype}")
        n = len(t)
        if n == 0:
            return self

        def at(k):
            return f"sample {k} (t={float(t[k])!r}, j={int(j[k])})"

        # one mask per check over the samples; the first sample any breaks is named
        dt, dj = np.diff(t), np.diff(j)
        bad_x = ~np.all(np.isfinite(x), axis=1)
        if self.termination is Termination.NON_FINITE:
            bad_x[-1] = False                 # the state that stopped the run
        first = np.inf, None
        checks = (
            (~np.isfinite(t), 0,
             lambda k: f"t[{k}] = {t[k]} is not finite at {at(k)}"),
            (dt < 0, 1,
             lambda k: f"t goes backwards at sample {k} (t[{k - 1}] = {t[k - 1]}, "
                       f"t[{k}] = {t[k]}; j = {j[k]})"),
            ((dj != 0) & (dj != 1), 1,
             lambda k: f"j must increase by 0 or 1 between samples; j[{k - 1}] = "
                       f"{j[k - 1]}, j[{k}] = {j[k]} at {at(k)}"),
            ((dj == 1) & (dt != 0), 1,
             lambda k: f"the jump at sample {k} (j {j[k - 1]} -> {j[k]}) changes t "
                       f"({t[k - 1]} -> {t[k]}); a jump keeps t"),
            ((dj == 0) & (dt == 0), 1,
             lambda k: f"{at(k)} repeats the sample before it (same t and j): a "
                       f"duplicate sample"),
            (bad_x, 0,
             lambda k: f"x[{k}] (t = {t[k]}, j = {j[k]}) is not finite: {x[k]}"),
        )
        for mask, shift, msg in checks:
            hit = np.flatnonzero(mask)
            if hit.size and hit[0] + shift < first[0]:
                first = int(hit[0]) + shift, msg
        if first[1] is not None:
            raise ValueError(f"{where}: {first[1](first[0])}")
        # where the run's limits are known: no sample beyond, the cause's sample at them
        term = self.termination
        if t_max is not None:
            over = np.flatnonzero(t > t_max)
            if over.size:
                raise ValueError(f"{where}: {at(int(over[0]))} lies after t_max = {t_max}")
            if term is Termination.T_MAX and t[-1] != t_max:
                raise ValueError(f"{where}: the run ended T_MAX but its last {at(n - 1)} "
                                 f"is not at t_max = {t_max}")
        if j_max is not None:
            count = j - j[0]
            over = np.flatnonzero(count > j_max)
            if over.size:
                raise ValueError(f"{where}: {at(int(over[0]))} is after jump "
                                 f"{int(count[over[0]])}, beyond j_max = {j_max}")
            if term is Termination.J_MAX and count[-1] != j_max:
                raise ValueError(f"{where}: the run ended J_MAX but its last {at(n - 1)} "
                                 f"is after {int(count[-1])} jumps, not j_max = {j_max}")
        return self
