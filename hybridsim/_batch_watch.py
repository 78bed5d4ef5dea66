"""The vectorized batch's watched functions (a base class of
:class:`hybridsim.batch_vectorized._BatchRun`): their values where the rows'
flows start, and their crossings on each step, all rows at once.
"""
from __future__ import annotations

import numpy as np

from ._batch_events import _tol
from .events import WATCH_SAMPLES, crossing_sides, starts_on_zero
from .system import watch_directions


class _RowWatch:
    """:meth:`_watch_start` and :meth:`_watch_to` of the batch's rows (they read
    the run's ``maps``, ``w_*`` fields, ``cross``, ``bad``, ``_dense`` and
    ``_secant``)."""

    def _watch_start(self, rows):
        """Flows start at the rows' current states: the watched functions there."""
        t, x, j = self.t[rows], self.x[rows], self.j[rows]
        v = self.maps.watch(rows, x, t, j)
        if self.w_v is None:
            m = v.shape[1]
            self.w_dir = watch_directions(self.w_direction, m)
            self.w_v = np.full((self.N, m), np.nan)
        self.w_v[rows] = v
        self.w_floor[rows] = np.where(t == self.t_last[rows], t, -np.inf)

    def _watch_to(self, rows, a, ya, h, Q, b, yb, j):
        """The crossings of the watched functions on the steps from (a, ya) to
        (b, yb) of ``rows`` (their dense outputs ``Q``): the batch version of
        :func:`hybridsim.events.watch_crossings` (the values at the ends and
        at its interior points, every sign change bracketed to 4 ulp by this
        path's :meth:`_secant`, all rows' crossings at once)."""
        m = self.maps
        va = self.w_v[rows]
        vb = m.watch(rows, yb, b, j)
        pts, ys, vals = [a], [ya], [va]
        for q in range(1, WATCH_SAMPLES + 1):
            s = a + (b - a) * (q / (WATCH_SAMPLES + 1.0))
            y = self._dense(a, h, ya, Q, s)
            pts.append(s)
            ys.append(y)
            vals.append(m.watch(rows, y, s, j))
        pts.append(b)
        ys.append(yb)
        vals.append(vb)
        self.w_v[rows] = vb
        d = self.w_dir
        it, ik, isg, lo, hi, flo, fhi, ylo, yhi = ([] for _ in range(9))
        for q in range(len(pts) - 1):
            up, down = crossing_sides(vals[q], vals[q + 1], d)
            i, k = np.nonzero(up | down)
            if not i.size:
                continue
            sg = np.where(up[i, k], 1.0, -1.0)
            it.append(i)
            ik.append(k)
            isg.append(sg)
            lo.append(pts[q][i])
            hi.append(pts[q + 1][i])
            flo.append(sg * vals[q][i, k])
            fhi.append(sg * vals[q + 1][i, k])
            ylo.append(ys[q][i])
            yhi.append(ys[q + 1][i])
        if not it:
            return
        it, ik, isg, lo, hi, flo, fhi = (np.concatenate(v) for v in (it, ik, isg, lo, hi,
                                                                     flo, fhi))
        ylo, yhi = np.concatenate(ylo), np.concatenate(yhi)
        keep = ~self.bad[rows[it]] & (b[it] > a[it])
        it, ik, isg, lo, hi, flo, fhi, ylo, yhi = (v[keep] for v in (it, ik, isg, lo, hi, flo,
                                                                     fhi, ylo, yhi))
        if not it.size:
            return
        ri = rows[it]

        def ev(ii, s):
            r = it[ii]
            return self._dense(a[r], h[r], ya[r], Q[r], s)

        def phi(ii, s, y):
            v = m.watch(ri[ii], y, s, j[it[ii]])
            return isg[ii] * v[np.arange(len(ii)), ik[ii]]
        nan = np.full(len(it), np.nan)
        _, tc, _, xc = self._secant(ri, np.arange(len(it)), lo, hi, flo, fhi, ylo, yhi, nan,
                                    nan, ev, phi)
        floor = self.w_floor[ri]
        ok = ~starts_on_zero(floor, tc, _tol(floor, tc)) & ~self.bad[ri]
        for q in np.lexsort((ik, tc, ri))[ok[np.lexsort((ik, tc, ri))]].tolist():
            self.cross[int(ri[q])].append((float(tc[q]), int(j[it[q]]), int(ik[q]),
                                           int(isg[q]), xc[q].copy()))
