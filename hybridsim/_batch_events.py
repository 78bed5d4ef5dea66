"""The vectorized batch's events (a base class of
:class:`hybridsim.batch_vectorized._BatchRun`): the event indicators over
rows, the location of each row's first event on its step's dense output
(:func:`hybridsim.events.locate_event` run over the rows), the search
inside a step, and the decision at the located event.
"""
from __future__ import annotations

import math

import numpy as np

from ._batch_steps import _MAX_FACTOR
from .arc import Termination
from .events import _maximize, _near_peak
from .rules import Action, Priority, event_tolerance, needs_coin

# rules.event_tolerance(a, b) = unit * max(1, |a|, |b|); the unit read from the rule
_TOL_UNIT = event_tolerance(1.0, 1.0)
_MAX_ITER = 200     # bisection steps of locate_event
_SECANT_ITER = 100  # secant steps of events.secant_of


def _tol(lo, hi):
    """:func:`hybridsim.rules.event_tolerance` over arrays (bit for bit the same).

    Belongs in rules.py: ``event_tolerance`` takes Python floats only.
    """
    return _TOL_UNIT * np.maximum(1.0, np.maximum(np.abs(lo), np.abs(hi)))


def _root_off_zero(f0, fd, fw, d, w):
    """:func:`hybridsim.events.root_off_zero` over arrays: ``(offset, slope)``,
    NaN where the quadratic model has no root in (d, w).

    A row form because the arithmetic must differ: the plain function branches
    per value (numba compiles it for the kernel, and has no ``errstate``); here
    the same formulas run over all rows at once, masked."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        m = (fd - f0) / d
        c = (fw - f0 - m * w) / (w * w)
        disc = m * m - 4.0 * c * f0
        ok = (c > 0.0) & (disc >= 0.0)
        r = np.sqrt(np.where(ok, disc, 0.0))
        tau = (r - m) / (2.0 * c)
    ok &= (d < tau) & (tau < w)
    return np.where(ok, tau, np.nan), np.where(ok, r, np.nan)


class _RowEvents:
    """The events' methods of :class:`hybridsim.batch_vectorized._BatchRun` (its base class)."""

    # ------------------------------------------------------------ event location
    def _pred(self, rows, y, s, j, wd):
        """The event has happened: x left C, or entered D (rows with ``wd``)."""
        m = self.maps
        self._finite(rows, y)
        ev = np.zeros(len(rows), dtype=bool)
        if m.has_C:
            ev |= ~m.in_C(rows, y, s, j)
        if self.watch_D and wd.any():
            ev |= wd & m.in_D(rows, y, s, j)
        return ev

    def _pred_phi(self, rows, y, s, j, wd):
        """:meth:`_pred` and :meth:`_phi` at once: from one evaluation of each guard
        where the sets are the guards' (``shared``), else each on its own."""
        if not self.shared:
            return self._pred(rows, y, s, j, wd), self._phi(rows, y, s, j, wd)
        m = self.maps
        self._finite(rows, y)
        ev = np.zeros(len(rows), dtype=bool)
        v = np.full(len(rows), -np.inf)
        if self.watch_D and wd.any():
            gD = m.guard_D(rows, y, s, j)
            ev |= wd & (gD >= 0.0)
            v = np.where(wd, gD, -np.inf)
        if m.has_C:
            gC = m.guard_C(rows, y, s, j)
            ev |= ~(gC >= 0.0)
            v = np.maximum(v, -gC)
        return ev, v

    def _phi(self, rows, y, s, j, wd):
        """Continuous version of :meth:`_pred` (>= 0 where the event has happened)."""
        m = self.maps
        self._finite(rows, y)               # a non-finite probe is NON_FINITE, not a guard's NaN
        v = np.full(len(rows), -np.inf)
        if self.watch_D and m.hD is not None and wd.any():
            v = np.where(wd, m.guard_D(rows, y, s, j), -np.inf)
        if m.has_C and m.hC is not None:
            v = np.maximum(v, -m.guard_C(rows, y, s, j))
        return v

    def _locate(self, rows, a, h, ya, Q, j, wd, lo, hi, ylo=None, yhi=None):
        """Bracket the first event in (lo, hi] of each row on its dense output.

        :func:`hybridsim.events.locate_event` run over the rows: the same
        phases, tests and tolerance (:func:`hybridsim.rules.event_tolerance`)
        for each row, so each row's bracket is the one ``locate_event``
        returns on the same dense output, to rounding of the batched
        interpolant. With a guard: a start on the guard's zero is probed and
        seeded by the quadratic model (``events._root_off_zero``); the
        indicator bisects until the guard changes sign; safeguarded secant
        steps (``events.secant_of``: Brent's test, else bisection) shrink the
        guard's bracket, which the indicator confirms; a final bisection of
        the indicator closes any bracket left. ``ylo``, ``yhi``: the states
        at lo and hi where the caller has them (the step's ends).

        Returns
        -------
        lo, hi : ndarray, shape (k,)
        ylo, yhi : ndarray, shape (k, n)
        """
        k = len(rows)
        lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
        ylo = self._dense(a, h, ya, Q, lo) if ylo is None else np.array(ylo)
        yhi = self._dense(a, h, ya, Q, hi) if yhi is None else np.array(yhi)
        bad = self.bad

        def ev(i, s):
            return self._dense(a[i], h[i], ya[i], Q[i], s)

        def pred(i, s, y):
            return self._pred(rows[i], y, s, j[i], wd[i])

        def phi(i, s, y):
            return self._phi(rows[i], y, s, j[i], wd[i])

        def bisect(cond):
            # locate_event's bisection of the indicator while cond(lo, hi) holds
            for _ in range(_MAX_ITER):
                i = np.flatnonzero(cond() & (hi - lo > _tol(lo, hi)) & ~bad[rows])
                if not i.size:
                    break
                s = 0.5 * (lo[i] + hi[i])
                ys = ev(i, s)
                hit = pred(i, s, ys)
                if use_phi:
                    fs = phi(i, s, ys)
                    fhi[i[hit]], flo[i[~hit]] = fs[hit], fs[~hit]
                hi[i[hit]], yhi[i[hit]] = s[hit], ys[hit]
                lo[i[~hit]], ylo[i[~hit]] = s[~hit], ys[~hit]

        use_phi = self.use_phi
        if use_phi:
            every = np.arange(k)
            flo, fhi = phi(every, lo, ylo), phi(every, hi, yhi)
            seed_s, seed_m = np.full(k, np.nan), np.full(k, np.nan)
            # on the guard's zero at the start: one probe gives the direction,
            # and with the end value a first estimate of the root
            i = np.flatnonzero(~(flo < 0.0) & (fhi >= 0.0) & ~bad[rows])
            if i.size:
                d = np.maximum(64.0 * _tol(lo[i], hi[i]), 1e-9 * (hi[i] - lo[i]))
                ok = lo[i] + d < hi[i]
                i, d = i[ok], d[ok]
            if i.size:
                sd = lo[i] + d
                yd = ev(i, sd)
                fd = phi(i, sd, yd)
                neg = fd < 0.0
                off = np.zeros(len(i), dtype=bool)
                if neg.any():
                    off[neg] = ~pred(i[neg], sd[neg], yd[neg])
                i, d, sd, yd, fd = i[off], d[off], sd[off], yd[off], fd[off]
                if i.size:
                    tau, slope = _root_off_zero(flo[i], fd, fhi[i], d, hi[i] - lo[i])
                    seed_s[i], seed_m[i] = lo[i] + tau, slope
                    lo[i], ylo[i], flo[i] = sd, yd, fd
            # bisect by the indicator until the guard changes sign in the bracket
            bisect(lambda: ~((flo < 0.0) & (0.0 <= fhi)))
            i = np.flatnonzero((flo < 0.0) & (0.0 <= fhi) & (hi - lo > _tol(lo, hi))
                               & ~bad[rows])
            if i.size:
                l2, h2, yl2, yh2 = self._secant(rows, i, lo[i], hi[i], flo[i], fhi[i],
                                                ylo[i], yhi[i], seed_s[i], seed_m[i], ev, phi)
                # the indicator decides membership: keep the guard's bracket where
                # it agrees (the indicator is asked at lo only where it disagrees at hi)
                agree = pred(i, h2, yh2)
                ia = i[agree]
                hi[ia], yhi[ia], lo[ia], ylo[ia] = h2[agree], yh2[agree], l2[agree], yl2[agree]
                rest = ~agree
                if rest.any():
                    out = ~pred(i[rest], l2[rest], yl2[rest])
                    ib = i[rest][out]
                    lo[ib], ylo[ib] = l2[rest][out], yl2[rest][out]
        # bisection of the indicator (also finishes any bracket the guard left)
        bisect(lambda: True)
        return lo, hi, ylo, yhi

    # a row form: events.secant_of's loop calls F at one point; here one masked step of all rows
    def _secant(self, rows, idx, lo, hi, flo, fhi, ylo, yhi, seed_s, seed_m, ev, phi):
        """:func:`hybridsim.events.secant_of`'s secant over the rows ``idx`` of a
        :meth:`_locate` (or the watched functions' crossings): each row's
        trial is its secant step from its last evaluation, accepted inside
        the bracket and shorter than half its step before last (Brent's
        test), else the midpoint; a seed (not NaN) is the first trial and
        gives the slope after it; trials are kept a quarter tolerance inside
        the bracket. Every active row takes its trial in one masked step, the
        maps called once per iteration for all of them (the plain
        ``events.secant_trial``/``secant_slope`` branch per value).
        Returns ``(lo, hi, x_lo, x_hi)``."""
        n = len(idx)
        d1, d2 = np.full(n, np.inf), np.full(n, np.inf)
        first = -flo < fhi
        xl, fl = np.where(first, lo, hi), np.where(first, flo, fhi)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            slope = (fhi - flo) / (hi - lo)
        has_seed = ~np.isnan(seed_s)
        bad = self.bad
        for _ in range(_SECANT_ITER):
            tol = _tol(lo, hi)
            act = np.flatnonzero((hi - lo > tol) & ~bad[rows[idx]])
            if not act.size:
                break
            L, H, X, FL, tl = lo[act], hi[act], xl[act], fl[act], tol[act]
            sd = has_seed[act]
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                sl = slope[act]
                s = np.where(sl != 0.0, X - FL / sl, np.nan)
            ok = (L <= s) & (s <= H) & (np.abs(s - X) < 0.5 * d2[act])
            s = np.where(ok, s, 0.5 * (L + H))
            s = np.where(sd, seed_s[act], s)
            q = 0.25 * tl
            s = np.where(~(s > L + q), L + q, np.where(~(s < H - q), H - q, s))
            ii = idx[act]
            ys = ev(ii, s)
            fs = phi(ii, s, ys)
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                ns = np.where(s != X, (fs - FL) / (s - X), np.nan)
            slope[act] = np.where(sd, seed_m[act], ns)
            has_seed[act] = False
            d2[act] = d1[act]
            d1[act] = np.abs(s - X)
            xl[act], fl[act] = s, fs
            up = fs >= 0.0
            au, ad = act[up], act[~up]
            hi[au], yhi[au], fhi[au] = s[up], ys[up], fs[up]
            lo[ad], ylo[ad], flo[ad] = s[~up], ys[~up], fs[~up]
        return lo, hi, ylo, yhi

    def _interior(self, rows, a, b, ya, h, Q, j):
        """The batch version of :func:`hybridsim.events.find_interior_event`.

        Three interior samples of each step's dense output, the indicators
        tested there; with guards, every sampled local maximum of the guard
        (the step's start included where the guard rises there, and its end
        where it falls there; the probe deciding that over the rows at once)
        whose peak could reach 0 refined by a golden-section search (row by
        row: such peaks are rare). Returns (lo, hi, found): a bracket with the
        event set entered at hi, where found.
        """
        k = len(rows)
        wd = ~self.inD_prev[rows]
        lo_b, hi_b = a.copy(), b.copy()
        found = np.zeros(k, dtype=bool)
        prev = a.copy()
        pts, vals = [a], []
        if self.use_phi:
            vals.append(self._phi(rows, self._dense(a, h, ya, Q, a), a, j, wd))
        for q in (1, 2, 3):
            s = a + (b - a) * (q / 4.0)
            ys = self._dense(a, h, ya, Q, s)
            if self.use_phi:
                ev, v = self._pred_phi(rows, ys, s, j, wd)
                vals.append(v)
            else:
                ev = self._pred(rows, ys, s, j, wd)
            hit = ~found & ev
            lo_b[hit], hi_b[hit] = prev[hit], s[hit]
            found |= hit
            prev = s
            pts.append(s)
        found &= ~self.bad[rows]
        if not self.use_phi or found.all():
            return lo_b, hi_b, found
        pts.append(b)
        vals.append(self._phi(rows, self._dense(a, h, ya, Q, b), b, j, wd))
        V, T = np.array(vals), np.array(pts)           # (5, k)
        fin = np.isfinite(V).all(axis=0)

        def refine(i, l, r, fl, fr):
            # events._maximize on row i's dense output (row by row: peaks are rare)
            ri, wi, ji = rows[i:i + 1], wd[i:i + 1], j[i:i + 1]

            def sol(s):
                return self._dense(a[i:i + 1], h[i:i + 1], ya[i:i + 1], Q[i:i + 1],
                                   np.array([s]))[0]

            def F(s, y):
                return float(self._phi(ri, y[None, :], np.array([s]), ji, wi)[0])

            def pred(s, y):
                return bool(self._pred(ri, y[None, :], np.array([s]), ji, wi)[0])
            sq = _maximize(F, l, r, fl, fr, pred, sol)
            if sq is not None and not self.bad[rows[i]]:
                found[i] = True
                lo_b[i], hi_b[i] = l, sq

        for q in (1, 2, 3):
            lo_nb = np.minimum(V[q - 1], V[q + 1])
            cand = (~found & fin & (V[q] >= V[q - 1]) & (V[q] >= V[q + 1])
                    & _near_peak(V[q], lo_nb) & ~self.bad[rows])
            for i in np.flatnonzero(cand):
                refine(i, T[q - 1, i], T[q + 1, i], V[q - 1, i], V[q + 1, i])
        # a peak between a and the first sample (only where the guard rises at
        # a), then between the last sample and b (only where it falls at b: the
        # next step starts falling, so its own search never looks back)
        for e, nb, sign in ((0, 1, 1.0), (4, 3, -1.0)):
            cand = (~found & fin & (V[e] >= V[nb]) & _near_peak(V[e], V[nb])
                    & ~self.bad[rows])
            if not cand.any():
                continue
            c = np.flatnonzero(cand)
            # one probe a thousandth of the way in, over the rows at once
            s = T[e, c] + sign * (1e-3 * np.abs(T[nb, c] - T[e, c]))
            ys = self._dense(a[c], h[c], ya[c], Q[c], s)
            rise = (self._phi(rows[c], ys, s, j[c], wd[c]) > V[e, c]) & ~self.bad[rows[c]]
            l, r = (0, 1) if e == 0 else (3, 4)
            for i in c[rise]:
                refine(i, T[l, i], T[r, i], V[l, i], V[r, i])
        return lo_b, hi_b, found

    # ------------------------------------------------------------ at an event
    def _event(self, rows, a, lo, hi, ya, h, Q, j, ylo=None, yhi=None, clamp=None):
        """Locate the first event in (lo, hi] of the steps from a of ``rows`` and
        decide there (:func:`hybridsim.rules.event_outcome`); ``clamp``: record
        event times no later than it (an event within round-off after t_max is
        taken at t_max)."""
        m = self.maps
        self.events[rows] += 1
        # a flow that started in D (random priority flowing on) watches only C
        wd = ~self.inD_prev[rows]
        lo, hi, ylo, yhi = self._locate(rows, a, h, ya, Q, j, wd, lo, hi, ylo, yhi)
        ok = self._reap(rows)
        if ok is not None:
            rows, a, ya, h, Q, lo, hi, ylo, yhi, j, wd = (
                rows[ok], a[ok], ya[ok], h[ok], Q[ok], lo[ok], hi[ok], ylo[ok], yhi[ok],
                j[ok], wd[ok])
            if not rows.size:
                return
        # next flow's first step (as simulate): at most 10x the length of this
        # flow; the controller's proposal after an overshooting step can be
        # huge where the flow is integrated exactly, and long steps cancel digits
        self.h[rows] = np.minimum(self.h[rows], _MAX_FACTOR * (hi - self.t_flow0[rows]))
        k = len(rows)
        false = np.zeros(k, dtype=bool)
        watching = wd if self.watch_D else false
        d_hi = m.in_D(rows, yhi, hi, j) if m.has_D else false
        entry = watching & d_hi
        c_hi = false.copy()                  # C at hi matters only for the coin
        if self.prio == Priority.RANDOM and entry.any():
            c_hi[entry] = m.in_C(rows[entry], yhi[entry], hi[entry], j[entry])
        coin = np.ones(k, dtype=bool)
        ask = needs_coin(c_hi, entry, self.prio)
        if ask.any():
            coin[ask] = self.rng.random(int(ask.sum())) < 0.5
        d_lo = false.copy()
        if m.has_D and not entry.all():
            e = ~entry
            d_lo[e] = m.in_D(rows[e], ylo[e], lo[e], j[e])
        ok = self._reap(rows)
        code = (watching.astype(np.intp) << 4) | (d_hi << 3) | (c_hi << 2) | (d_lo << 1) | coin
        action, at_hi = self.ev_action[code], self.ev_side[code] == 1
        if ok is not None:
            rows, a, ya, h, Q, lo, hi, ylo, yhi, j, action, at_hi = (
                rows[ok], a[ok], ya[ok], h[ok], Q[ok], lo[ok], hi[ok], ylo[ok], yhi[ok],
                j[ok], action[ok], at_hi[ok])
        ts = np.where(at_hi, hi, lo)
        if clamp is not None:
            ts = np.minimum(ts, clamp)
        xs = np.where(at_hi[:, None], yhi, ylo)
        sample = ts > a
        if self.watching and sample.any():
            sr = np.flatnonzero(sample)
            self._watch_to(rows[sr], a[sr], ya[sr], h[sr], Q[sr], ts[sr], xs[sr], j[sr])
            ok = self._reap(rows)
            if ok is not None:
                rows, a, ya, h, Q, lo, hi, ylo, yhi, j, action, at_hi, ts, xs, sample = (
                    rows[ok], a[ok], ya[ok], h[ok], Q[ok], lo[ok], hi[ok], ylo[ok], yhi[ok],
                    j[ok], action[ok], at_hi[ok], ts[ok], xs[ok], sample[ok])
                if not rows.size:
                    return
        if sample.any():
            if self.hist is not None:       # the step up to the event
                self.hist._add(rows[sample], a[sample], ts[sample], j[sample], h[sample],
                               ya[sample], Q[sample])
            if self.refine > 1:
                self._refine(rows[sample], a[sample], ts[sample], ya[sample], h[sample],
                             Q[sample], j[sample])
            self.log.append(rows[sample], ts[sample], j[sample], xs[sample],
                            m.flow_soft(xs[sample], ts[sample], j[sample], rows[sample]))
        self.t[rows] = ts
        self.x[rows] = xs
        if self.max_norm < math.inf and sample.any():   # the event's sample, as a step's end
            nrm = np.linalg.norm(xs, axis=1)
            big = sample & (nrm > self.max_norm)
            if big.any():
                self._stop(rows[big], Termination.BLOWUP, norm=nrm[big],
                           max_norm=self.max_norm, t=ts[big], j=j[big])
                keep = ~big
                rows, ts, xs, j, action, at_hi, lo, ylo, yhi = (
                    rows[keep], ts[keep], xs[keep], j[keep], action[keep], at_hi[keep],
                    lo[keep], ylo[keep], yhi[keep])
        jump = action == Action.JUMP
        if jump.any():
            self.force[rows[jump]] = True
            self.decide[rows[jump]] = True
            # jumping from hi: the bracket, for rules.post_jump_probe after the jump
            self.pend[rows[jump]] = at_hi[jump]
            jh = jump & at_hi
            if jh.any():
                rh = rows[jh]
                self.pend_lo[rh], self.pend_xlo[rh], self.pend_xhi[rh] = lo[jh], ylo[jh], yhi[jh]
        cont = action == Action.FLOW
        done = cont & (ts >= self.t_max)     # flowing on at t_max: the run ends there
        if done.any():
            self._stop(rows[done], Termination.T_MAX)
            cont &= ~done
        if cont.any():                       # random priority chose to flow on in C ∩ D
            self._start_flow(rows[cont], np.ones(int(cont.sum()), dtype=bool))
        left = action == Action.STOP
        if left.any():
            self._stop_outside(rows[left], xs[left], ts[left], j[left], "left")
