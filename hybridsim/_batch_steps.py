"""The vectorized batch's steps (a base class of
:class:`hybridsim.batch_vectorized._BatchRun`): scipy's RK45 and DOP853
tableaux and controller constants, the first step of a flow, one step
attempt of every flowing row with its error control, what follows the
accepted steps (samples, the events inside a step, the limits), and the
steps' dense output (made, evaluated, refined into samples).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import DOP853, RK45
from scipy.integrate._ivp import dop853_coefficients as _dop

from ._rk import MAX_FACTOR, MIN_FACTOR, RK4_P4, RK4_SNAP, RK4_TABLEAU, SAFETY
from .arc import Termination
from .rules import t_max_slack

# scipy's RK45 tableau, error weights and dense-output matrix
_A, _B, _C, _E, _P = RK45.A, RK45.B, RK45.C, RK45.E, RK45.P
_NS = RK45.n_stages
#: the tableaux (A, B, C) and dense outputs P (Q = K^T P, four powers of s) of the
#: methods stepped here with one form of dense output: RK45's, and RK4's fixed step
#: (hybridsim._rk.RK4: its continuous extension of order 3, a column of zeros added)
_RK45 = {"A": _A, "B": _B, "C": _C, "P": _P}
_RK4 = dict(RK4_TABLEAU, P=RK4_P4)
_ERR_EXP = -1.0 / (RK45.error_estimator_order + 1)
#: scipy's DOP853 (``method="DOP853"``): its tableau (12 stages), error weights
#: and dense output (3 more stages, then D); the rules of simulate's DOP853
_DOP = {"A": DOP853.A, "B": DOP853.B, "C": DOP853.C, "E3": DOP853.E3, "E5": DOP853.E5,
        "D": DOP853.D, "AX": _dop.A, "CX": _dop.C, "ns": DOP853.n_stages,
        "exp": -1.0 / (DOP853.error_estimator_order + 1),
        "order": DOP853.error_estimator_order}
# scipy's step-size controller constants, as the other paths take them (hybridsim._rk)
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = SAFETY, MIN_FACTOR, MAX_FACTOR
_TOO_SMALL = "Required step size is less than spacing between numbers."
# stage weights of the dense output's derivative: d/ds of (s, s^2, s^3, s^4)
_DP = np.array([1.0, 2.0, 3.0, 4.0])


def _rms(a):
    """Row-wise RMS norm of a (k, n) array (scipy's ``norm`` per row)."""
    return np.sqrt(np.einsum("ij,ij->i", a, a) / a.shape[1])


class _RowSteps:
    """The steps' methods of :class:`hybridsim.batch_vectorized._BatchRun` (its base class)."""

    # ------------------------------------------------------------ the first step
    def _initial_step(self, rows, y0, t0, j, f0, span):
        """scipy's ``select_initial_step`` (the method's error order), row by row
        in one go. The batch form of the kernel's ``_steps._initial_guess`` and
        ``_initial_step`` (the Python path takes scipy's own): every row's norms
        and branch in one array expression, which a per-row scalar rule would
        turn into a Python loop over the rows."""
        if self.fixed:
            return np.full(len(rows), self.max_step)
        rtol, atol = self.rtol, self.atol
        scale = atol + np.abs(y0) * rtol
        d0 = _rms(y0 / scale)
        d1 = _rms(f0 / scale)
        with np.errstate(divide="ignore", invalid="ignore"):
            h0 = np.where((d0 < 1e-5) | (d1 < 1e-5), 1e-6, 0.01 * d0 / d1)
        h0 = np.minimum(h0, span)
        y1 = y0 + h0[:, None] * f0
        f1 = self.maps.flow(rows, y1, t0 + h0, j)
        d2 = _rms((f1 - f0) / scale) / h0
        order = self.dop["order"] if self.dop else 4
        with np.errstate(divide="ignore"):
            h1 = np.where((d1 <= 1e-15) & (d2 <= 1e-15), np.maximum(1e-6, h0 * 1e-3),
                          (0.01 / np.maximum(d1, d2)) ** (1.0 / (order + 1)))
        return np.minimum(np.minimum(np.minimum(100 * h0, h1), span), self.max_step)

    # ------------------------------------------------------------ flows
    def _step(self, rows):
        """One step attempt of every flowing trajectory (rejected ones retry next time;
        a fixed-step method's steps are all accepted)."""
        if self.fixed:
            return self._fixed_step(rows)
        t, y, j, f = self.t[rows], self.x[rows], self.j[rows], self.fx[rows]
        rej = self.rejected[rows]
        h_abs = self.h[rows]
        min_step = 10 * np.abs(np.nextafter(t, np.inf) - t)
        h_abs = np.where(rej, h_abs, np.clip(h_abs, min_step, self.max_step))
        small = rej & ~(h_abs >= min_step)     # a NaN step (non-finite flow) too
        if small.any():
            sr, st, ss, sj = rows[small], t[small], self.short[rows[small]], j[small]
            nf = self.nonfinite[sr]        # a non-finite flow map: NON_FINITE, as in simulate
            if nf.any():
                self._stop(sr[nf], Termination.NON_FINITE, "flow", t=st[nf], j=sj[nf])
            zeno = (ss > 0) & ~nf
            if zeno.any():
                self._stop(sr[zeno], Termination.ZENO, "short", t=st[zeno])
            fail = ~zeno & ~nf
            if fail.any():
                self._stop(sr[fail], Termination.SOLVER_FAILED, reason=_TOO_SMALL,
                           t=st[fail], j=sj[fail])
            keep = ~small
            rows, t, y, j, f, rej, h_abs = (rows[keep], t[keep], y[keep], j[keep], f[keep],
                                           rej[keep], h_abs[keep])
            if not rows.size:
                return
        t_new = np.minimum(t + h_abs, self._bound(rows, t))
        h = t_new - t
        h_abs = np.abs(h)
        self.attempts[rows] += 1
        dop = self.dop
        A, B, C = (dop["A"], dop["B"], dop["C"]) if dop else (_A, _B, _C)
        K = self._stages(rows, t, y, j, f, h, A, B, C)
        y_new = K[-1]
        K = K[:-1]
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            scale = self.atol + np.maximum(np.abs(y), np.abs(y_new)) * self.rtol
            if dop:
                # DOP853._estimate_error_norm, row by row
                e5 = np.sum((np.tensordot(dop["E5"], K, axes=(0, 0)) / scale) ** 2, axis=1)
                e3 = np.sum((np.tensordot(dop["E3"], K, axes=(0, 0)) / scale) ** 2, axis=1)
                err_norm = np.where((e5 == 0) & (e3 == 0), 0.0,
                                    h_abs * e5 / np.sqrt((e5 + 0.01 * e3) * self.n))
            else:
                err = np.tensordot(_E, K, axes=(0, 0)) * h[:, None]
                err_norm = _rms(err / scale)
        ok = self._reap(rows)
        if ok is not None:
            rows, t, y, j, rej, h, h_abs, t_new, y_new, err_norm = (
                rows[ok], t[ok], y[ok], j[ok], rej[ok], h[ok], h_abs[ok], t_new[ok],
                y_new[ok], err_norm[ok])
            K = K[:, ok]
            if not rows.size:
                return
        acc = err_norm < 1
        self.nonfinite[rows] = ~np.isfinite(K).all(axis=(0, 2))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            factor = _SAFETY * err_norm ** self.err_exp
        grow = np.where(err_norm == 0, _MAX_FACTOR, np.minimum(_MAX_FACTOR, factor))
        grow = np.where(rej, np.minimum(1.0, grow), grow)
        shrink = np.maximum(_MIN_FACTOR, factor)   # NaN error: NaN factor -> shrink (max)
        shrink = np.where(np.isnan(factor), _MIN_FACTOR, shrink)
        self.h[rows] = h_abs * np.where(acc, grow, shrink)
        self.rejected[rows] = ~acc
        if not acc.any():
            return
        if not acc.all():
            rows, t, y, j, h, t_new, y_new = (rows[acc], t[acc], y[acc], j[acc], h[acc],
                                              t_new[acc], y_new[acc])
            K = K[:, acc]
        self.rejected[rows] = False
        self._accepted(rows, t, y, j, h, t_new, y_new, K)

    def _stages(self, rows, t, y, j, f, h, A, B, C):
        """The stages of steps t -> t + h of ``rows`` (scipy's rk_step, one row per
        trajectory): (ns + 2, k, n), the ns stages, f at the end, then the end state."""
        m, ns = self.maps, self.ns
        self.nfev[rows] += ns
        K = np.empty((ns + 2, len(rows), self.n))
        K[0] = f
        hc = h[:, None]
        # overflow/NaN end as a rejected step or NON_FINITE, as in simulate
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            for s in range(1, ns):
                dy = np.tensordot(A[s, :s], K[:s], axes=(0, 0)) * hc
                K[s] = m.flow(rows, y + dy, t + C[s] * h, j)
            K[ns + 1] = y + hc * np.tensordot(B, K[:ns], axes=(0, 0))
            K[ns] = m.flow(rows, K[ns + 1], t + h, j)
        return K

    def _fixed_step(self, rows):
        """One step of ``max_step`` of every flowing row (RK4: no error control), each
        ending on its bound where it would stop within RK4_SNAP of a step before it."""
        t, y, j, f = self.t[rows], self.x[rows], self.j[rows], self.fx[rows]
        bound = self._bound(rows, t)
        t_new = t + self.max_step
        t_new = np.where(t_new > bound - RK4_SNAP * self.max_step, bound, t_new)
        h = t_new - t
        self.attempts[rows] += 1
        tab = self.tableau
        K = self._stages(rows, t, y, j, f, h, tab["A"], tab["B"], tab["C"])
        y_new, K = K[-1], K[:-1]
        ok = self._reap(rows)
        if ok is not None:
            rows, t, y, j, h, t_new, y_new = (rows[ok], t[ok], y[ok], j[ok], h[ok],
                                              t_new[ok], y_new[ok])
            K = K[:, ok]
            if not rows.size:
                return
        self.nonfinite[rows] = ~np.isfinite(K).all(axis=(0, 2))
        self.rejected[rows] = False
        self._accepted(rows, t, y, j, h, t_new, y_new, K)

    def _accepted(self, rows, a, ya, j, h, b, yb, K):
        """Samples, events and limits after the accepted steps a -> b of ``rows``."""
        m = self.maps
        self.steps[rows] += 1
        self.t_step[rows] = b
        fin = np.isfinite(yb).all(axis=1)
        if not fin.all():
            self._stop(rows[~fin], Termination.NON_FINITE, "step", t=a[~fin], t2=b[~fin],
                       j=j[~fin])
            rows, a, ya, j, h, b, yb = (rows[fin], a[fin], ya[fin], j[fin], h[fin], b[fin],
                                        yb[fin])
            K = K[:, fin]
            if not rows.size:
                return
        event = ~m.in_C(rows, yb, b, j) if m.has_C else np.zeros(len(rows), dtype=bool)
        if self.watch_D:
            inDb = m.in_D(rows, yb, b, j)
            event |= inDb & ~self.inD_prev[rows]
        else:
            inDb = None
        ok = self._reap(rows)
        if ok is not None:
            rows, a, ya, j, h, b, yb, event = (rows[ok], a[ok], ya[ok], j[ok], h[ok], b[ok],
                                               yb[ok], event[ok])
            inDb = inDb[ok] if inDb is not None else None
            K = K[:, ok]
            if not rows.size:
                return
        if event.any():
            e = event
            Q = self._dense_of(rows[e], a[e], ya[e], h[e], yb[e], K[:, e], j[e])
            self._event(rows[e], a[e], a[e], b[e], ya[e], h[e], Q, j[e], ylo=ya[e], yhi=yb[e])
        calm = ~event
        if not calm.any():
            return
        # the inside of the other steps: D entered and left (or C left and
        # re-entered) within one step; and an entry into D within round-off
        # after t_max, which is taken at t_max
        watch = np.zeros(len(rows), dtype=bool)
        if m.has_C:
            watch[:] = True
        if self.watch_D:
            watch |= ~self.inD_prev[rows]
        watch &= calm
        if watch.any():
            w = np.flatnonzero(watch)
            if self.dop:
                # simulate's rule for DOP853: the search on the cubic Hermite of
                # each step's ends, a hit confirmed on the dense output (made
                # only for the rows that need it: three evaluations more)
                Qh = np.stack([yb[w], h[w][:, None] * K[0][w], h[w][:, None] * K[self.ns][w]],
                              axis=2)
                lo_b, hi_b, found = self._interior(rows[w], a[w], b[w], ya[w], h[w], Qh, j[w])
                Qw = np.full((len(w), self.n, 7), np.nan)
                made = np.zeros(len(w), dtype=bool)

                def dense(sel):
                    sel = sel[~made[sel]]
                    if sel.size:
                        ws = w[sel]
                        Qw[sel] = self._dense_of(rows[ws], a[ws], ya[ws], h[ws], yb[ws],
                                                 K[:, ws], j[ws])
                        made[sel] = True
                fi = np.flatnonzero(found)
                if fi.size:
                    dense(fi)
                    wf = w[fi]
                    lo_b[fi], hi_b[fi], found[fi] = self._interior(
                        rows[wf], a[wf], b[wf], ya[wf], h[wf], Qw[fi], j[wf])
            else:
                Qw = np.einsum("skn,sp->knp", K[:, w], self.tableau["P"])
                lo_b, hi_b, found = self._interior(rows[w], a[w], b[w], ya[w], h[w], Qw,
                                                   j[w])
            late = ~found & (b[w] >= self.t_max) & ~self.bad[rows[w]]
            if self.dop:             # (simulate: only a flow watching D reads it)
                late &= ~self.inD_prev[rows[w]]
            found_late = np.zeros(len(w), dtype=bool)
            if self.watch_D and late.any():
                wl = np.flatnonzero(late)
                if self.dop:
                    dense(wl)
                rl = rows[w][wl]
                tb = b[w][wl] + t_max_slack(self.t_max, self.jumps[rl])
                ys = self._dense(a[w][wl], h[w][wl], ya[w][wl], Qw[wl], tb)
                self._finite(rl, ys)
                wdl = ~self.inD_prev[rl]
                pred = self._pred(rl, ys, tb, j[w][wl], wdl) & wdl & ~self.bad[rl]
                found_late[wl[pred]] = True
                lo_b[found_late] = b[w][found_late]
                hi_b[found_late] = tb[pred]
            for sel, clamp in ((found, None), (found_late, self.t_max)):
                if sel.any():
                    ww = w[sel]
                    # the step's end is where the solver is (simulate: ylo=solver.y)
                    ylo = yb[ww] if clamp is not None else None
                    self._event(rows[ww], a[ww], lo_b[sel], hi_b[sel], ya[ww], h[ww],
                                Qw[sel], j[ww], ylo=ylo, clamp=clamp)
                    calm[ww] = False
            bad = self.bad[rows]
            if bad.any():
                self._reap(rows)
                calm &= ~bad
            if not calm.any():
                return
        over = calm & (self.steps[rows] >= self.max_steps)
        if over.any():
            orow, ot = rows[over], b[over]
            self.log.append(orow, ot, j[over], yb[over], K[self.ns][over])
            self._stop(orow, Termination.MAX_STEPS, "steps", steps=self.max_steps,
                       max_steps=self.max_steps, t=ot)
            calm &= ~over
            if not calm.any():
                return
        rows, b, yb, j = rows[calm], b[calm], yb[calm], j[calm]
        fb = K[self.ns][calm]
        if self.hist is not None or self.refine > 1 or self.watching:
            # the steps' dense output
            Qc = self._dense_of(rows, a[calm], ya[calm], h[calm], yb, K[:, calm], j)
            if self.hist is not None:
                self.hist._add(rows, a[calm], b, j, h[calm], ya[calm], Qc)
            if self.refine > 1:
                self._refine(rows, a[calm], b, ya[calm], h[calm], Qc, j)
            if self.watching:
                self._watch_to(rows, a[calm], ya[calm], h[calm], Qc, b, yb, j)
                bad = self.bad[rows]
                if bad.any():           # watch failed on these rows: they end MAP_ERROR
                    self._reap(rows)
                    calm = calm.copy()
                    calm[np.flatnonzero(calm)[bad]] = False
                    rows, b, yb, j, fb = rows[~bad], b[~bad], yb[~bad], j[~bad], fb[~bad]
        self.t[rows] = b
        self.x[rows] = yb
        self.fx[rows] = fb
        if inDb is not None:
            self.inD_prev[rows] = inDb[calm]
        self.log.append(rows, b, j, yb, fb)
        if self.max_norm < math.inf:
            nrm = np.linalg.norm(yb, axis=1)
            big = nrm > self.max_norm
            if big.any():
                self._stop(rows[big], Termination.BLOWUP, norm=nrm[big],
                           max_norm=self.max_norm, t=b[big], j=j[big])
        end = b >= self.t_max
        if end.any():
            er = rows[end]
            self.decide[er] = True           # jumps at t_max are still taken
            self.h[er] = np.nan

    # ------------------------------------------------------------ dense output
    def _refine(self, rows, a, b, ya, h, Q, j):
        """Store ``refine - 1`` dense-output samples strictly inside each (a, b),
        with the dense output's derivative as their ``xdot`` (as simulate: RK45's;
        NaN for DOP853, whose dense output simulate does not differentiate)."""
        R = self.refine
        for k in range(1, R):
            s = a + (b - a) * (k / R)
            xx = (s - a) / h
            if Q.shape[2] == 4:
                p = np.stack([np.ones_like(xx), xx, xx * xx, xx ** 3], axis=1) * _DP
                xd = np.einsum("knp,kp->kn", Q, p)
            else:
                xd = None
            self.log.append(rows, s, j, self._dense(a, h, ya, Q, s), xd)

    def _dense_of(self, rows, a, ya, h, yb, K, j):
        """The dense output of the accepted steps a -> a + h of ``rows`` (``K``:
        their stages): RK45's (or RK4's) Q = K^T P, (k, n, 4); DOP853's F, (k, n, 7),
        scipy's ``DOP853._dense_output_impl`` (its three more stages
        evaluated here)."""
        if not self.dop:
            return np.einsum("skn,sp->knp", K, self.tableau["P"])
        d, ns, k = self.dop, self.ns, len(rows)
        hc = h[:, None]
        KX = np.empty((ns + 4, k, self.n))
        KX[:ns + 1] = K
        with np.errstate(invalid="ignore", over="ignore"):
            for s in range(ns + 1, ns + 4):
                dy = np.tensordot(d["AX"][s, :s], KX[:s], axes=(0, 0)) * hc
                KX[s] = self.maps.flow(rows, ya + dy, a + d["CX"][s] * h, j)
            self.nfev[rows] += 3
            dyb = yb - ya
            F = np.empty((k, self.n, 7))
            F[:, :, 0] = dyb
            F[:, :, 1] = hc * K[0] - dyb
            F[:, :, 2] = 2 * dyb - hc * (K[ns] + K[0])
            F[:, :, 3:] = hc[:, :, None] * np.einsum("ps,skn->knp", d["D"], KX)
        return F

    def _dense(self, a, h, ya, Q, s):
        """Each row's dense output at its time s, by the form of ``Q``: RK45's
        (scipy's RkDenseOutput, Q = K^T P), DOP853's (its Dop853DenseOutput, F)
        or the cubic Hermite of the step's ends (the end state, h f at both
        ends: ``solve._Hermite``). A row form because the arithmetic must
        differ: scipy's dense outputs and ``solve._Hermite`` evaluate one step;
        here each row has its own step, so the same polynomials run over the
        rows' coefficients at once."""
        xx = (s - a) / h
        with np.errstate(invalid="ignore", over="ignore"):
            if Q.shape[2] == 4:
                p = np.stack([xx, xx * xx, xx ** 3, xx ** 4], axis=1)
                return ya + h[:, None] * np.einsum("knp,kp->kn", Q, p)
            x = xx[:, None]
            if Q.shape[2] == 7:
                y = np.zeros_like(ya)
                for i in range(7):
                    y = (y + Q[:, :, 6 - i]) * (x if i % 2 == 0 else 1 - x)
                return y + ya
            x2 = x * x
            return (ya + x2 * (3.0 - 2.0 * x) * (Q[:, :, 0] - ya) + x * (1.0 - x) ** 2 * Q[:, :, 1]
                    + x2 * (x - 1.0) * Q[:, :, 2])
