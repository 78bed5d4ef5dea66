"""SDE flows on the Python path: dx = f dt + σ dW in C, with events exact in law.

A system declares ``diffusion(x, t, j)`` (any of the map signatures) and
``noise_dim``: None for diagonal noise (σ of shape (n,), one Brownian
component per state component, ``dx_i = f_i dt + σ_i dW_i``), an int m for
general noise (σ of shape (n, m), ``dx = f dt + σ dW`` with W in R^m).

Methods (fixed step ``max_step``, on the grid ``t0 + k * max_step``; a flow
that starts between grid points, after a jump, first steps to the next one):

- ``"EM"``: Euler–Maruyama, strong order 1/2 (1 with additive noise);
- ``"Milstein"``: diagonal noise whose σ_i depends on x_i only (the usual
  diagonal Milstein), derivative-free (Kloeden–Platen's Runge–Kutta form),
  strong order 1;
- ``"SRA1"``: Rößler's (2010) stochastic Runge–Kutta for additive noise
  (σ a function of t and j only; checked at the first step), strong order
  1.5, from the increment and the iterated integral
  I_(1,0) = ∫ (W(s) - W(t)) ds of the run's Brownian path.

The Brownian path is one :class:`hybridsim.BrownianPath` per run:
``seed`` an int (a Generator gives 63 random bits; None: fresh entropy)
keys a path whose blocks are one step long (the grid's times are then block
ends, each reached at once); ``seed`` a ``BrownianPath`` is used as it is
(the same path for several step sizes: steps that divide its block land on
its dyadic grid). The path is recorded in ``arc.stats`` (``noise_seed``,
``noise_block``...) so a run can be replayed; the same path gives the same
values at any step sequence (events, t_max, rejected steps).

Events. Where a set has a guard (``jump_guard``, ``flow_guard``), a step
from a to b whose ends are both outside the set is an event with the
probability that a Brownian bridge of the guard process crossed between
them, ``exp(-2 y_a y_b / (s^2 (b - a)))``, the guard process approximated by
its linearisation (s^2 = |σ^T ∇y|^2 at a, ∇y by central differences); the
crossing time is then drawn from that bridge conditioned on crossing
(bisection, each midpoint drawn from the bridge's law given a crossing, down
to ``2**-40`` of the step), and the state there is the step's chord
corrected along σσ^T ∇y so that the linearised guard is zero, then moved
along that direction onto the guard (Newton). Exact in law
for Brownian motion and a linear guard; end-of-step detection would miss the
excursions between steps (biased by O(√h)). Sets given by indicators only
are checked at step ends. Uniforms for these draws come from a
counter-based stream keyed by the path and the step, so a run replays.

The stepping functions (:func:`em_step`, :func:`milstein_step`,
:func:`sra1_step`, :func:`crossing_probability`,
:func:`bridge_first_passage`) are plain arithmetic for a compiled path to
take later.
"""
from __future__ import annotations

import math
import numbers
import struct

import numpy as np

from .brownian import BrownianPath, mix64
from .rules import MapError, Termination

__all__ = ["SDE_METHODS", "is_stochastic", "SDEFlow", "em_step", "milstein_step", "sra1_step",
           "crossing_probability", "bridge_first_passage"]

SDE_METHODS = ("EM", "Milstein", "SRA1")
_M = (1 << 64) - 1
_TWO53 = 1.0 / (1 << 53)


def is_stochastic(system) -> bool:
    """True when ``system`` declares a diffusion (an SDE flow)."""
    return getattr(system, "diffusion", None) is not None


# ------------------------------------------------------------------ the schemes
def em_step(x, f, s, dw, h, diagonal):
    """Euler–Maruyama: ``x + f h + σ dW``."""
    return x + f * h + (s * dw if diagonal else s @ dw)


def milstein_step(x, f, s, s_hat, dw, h):
    """Diagonal Milstein, derivative-free: ``s_hat`` is σ at ``x + f h + σ √h``."""
    return x + f * h + s * dw + (s_hat - s) * (dw * dw - h) / (2.0 * math.sqrt(h))


def sra1_step(x, t, h, f_of, s_t, s_th, dw, i10, diagonal):
    """Rößler's SRA1 (additive noise, strong order 1.5).

    ``f_of(t, x)`` the drift; ``s_t``, ``s_th`` σ at t and t + h; ``dw`` the
    increment and ``i10`` = ∫_t^{t+h} (W(s) - W(t)) ds.
    """
    def mul(s, v):
        return s * v if diagonal else s @ v
    f1 = f_of(t, x)
    h2 = x + 0.75 * h * f1 + 1.5 * mul(s_th, i10 / h)
    f2 = f_of(t + 0.75 * h, h2)
    return x + h * (f1 / 3.0 + 2.0 * f2 / 3.0) + mul(s_th, dw - i10 / h) + mul(s_t, i10 / h)


def crossing_probability(ya, yb, s2, dt):
    """P(a Brownian bridge from ya < 0 to yb < 0, variance rate s2, over dt, reaches 0).

    Examples
    --------
    >>> round(crossing_probability(-0.1, -0.2, 1.0, 0.1), 6)      # exp(-0.4)
    0.67032
    """
    if ya >= 0 or yb >= 0:
        return 1.0
    if not s2 > 0:
        return 0.0
    return math.exp(-2.0 * ya * yb / (s2 * dt))


class _Stream:
    """Counter-based uniforms and normals keyed by a 64-bit key."""

    __slots__ = ("key", "c")

    def __init__(self, key):
        self.key, self.c = key, 0

    def uniform(self):
        self.c += 1
        return ((mix64(self.key ^ (self.c * 0x9E3779B97F4A7C15 & _M)) >> 11) + 0.5) * _TWO53

    def normal(self):
        u1, u2 = self.uniform(), self.uniform()
        return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


def bridge_first_passage(ya, yb, s2, dt, stream, levels=40):
    """The first time in (0, dt] a Brownian bridge from ya < 0 to yb reaches 0, given it does.

    Bisection: each midpoint is drawn from the bridge's law given a crossing
    in the interval (by rejection, accepting with the probability of a
    crossing given the midpoint), then the half holding the first crossing
    is chosen with its conditional probability. Returns the right end of the
    final interval (``dt * 2**-levels`` long).
    """
    lo, length, yl, yr = 0.0, float(dt), float(ya), float(yb)
    for _ in range(levels):
        half = 0.5 * length
        mean, sd = 0.5 * (yl + yr), math.sqrt(s2 * length / 4.0)
        for _tries in range(10**7):
            m = mean + sd * stream.normal()
            pl = 1.0 if m >= 0 else math.exp(-2.0 * yl * m / (s2 * half))
            pr = 1.0 if (m >= 0 or yr >= 0) else math.exp(-2.0 * m * yr / (s2 * half))
            pe = pl + (1.0 - pl) * pr
            if stream.uniform() < pe:
                break
        if stream.uniform() * pe < pl:
            yr, length = m, half
        else:
            lo, yl, length = lo + half, m, half
    return lo + length


def _bits(t):
    return struct.unpack("<Q", struct.pack("<d", float(t)))[0]


# ------------------------------------------------------------------ the flow
def noise_key(seed):
    """The run's Brownian-path key (an int < 2**63) from ``simulate``'s ``seed``."""
    if seed is None:
        return int(np.random.SeedSequence().generate_state(1, np.uint64)[0] >> np.uint64(1))
    if isinstance(seed, np.random.Generator):
        return int(seed.integers(0, 2**63))
    if isinstance(seed, np.random.SeedSequence):
        return int(seed.generate_state(1, np.uint64)[0] >> np.uint64(1))
    return int(seed)


def prepare(system, method, step, seed, n, t0, maps, **others):
    """The run's :class:`SDEFlow`, or a clear error for an option SDE flows do not take.

    ``others``: the options of :func:`hybridsim.simulate` SDE flows refuse
    unless at their defaults (``inputs``, ``prehistory``, ``dense``,
    ``t_eval``, ``refine``, ``dwell``), named in the error.
    """
    defaults = {"inputs": None, "prehistory": None, "dense": False, "t_eval": None,
                "refine": 1, "dwell": None}
    for name, v in others.items():
        if v is not defaults[name] and v != defaults[name]:
            raise ValueError(f"{name}: {type(system).__name__} declares diffusion (an SDE "
                             f"flow), and SDE flows do not take {name} yet")
    if getattr(system, "delays", ()) or getattr(system, "needs_history", False):
        raise ValueError(f"{type(system).__name__} declares diffusion and reads its past "
                         f"(delays, needs_history): SDE flows do not read the past yet")
    if int(getattr(system, "input_dim", 0) or 0) > 0:
        raise ValueError(f"{type(system).__name__} declares diffusion and inputs "
                         f"(input_dim > 0): SDE flows do not take inputs yet")
    return SDEFlow(system, method, step, seed, n, t0, maps)


class SDEFlow:
    """The SDE stepping of one run, called by ``_Run._flow`` in place of a solver."""

    def __init__(self, system, method, step, seed, n, t0, maps):
        from .system import _named
        if method not in SDE_METHODS:
            raise ValueError(f"method: {type(system).__name__} declares diffusion (an SDE "
                             f"flow); method must be one of {list(SDE_METHODS)}, got "
                             f"{method!r}")
        if not (isinstance(step, numbers.Real) and math.isfinite(step) and step > 0):
            raise ValueError(f"max_step: an SDE flow steps with the fixed step max_step; it "
                             f"must be a positive finite float, got {step!r}")
        nd = getattr(system, "noise_dim", None)
        if nd is not None and (isinstance(nd, bool) or not isinstance(nd, numbers.Integral)
                               or nd < 1):
            raise ValueError(f"{type(system).__name__}.noise_dim must be None (diagonal noise) "
                             f"or a positive int (general noise), got {nd!r}")
        self.diagonal = nd is None
        self.m = n if nd is None else int(nd)
        if method == "Milstein" and not self.diagonal:
            raise ValueError(f"method='Milstein' takes diagonal noise (noise_dim=None); "
                             f"{type(system).__name__} has noise_dim={nd}: use 'EM', or "
                             f"'SRA1' for additive noise")
        self.method, self.h, self.n, self.t0 = method, float(step), n, float(t0)
        self.sigma = _named(system.diffusion, "diffusion")
        if isinstance(seed, BrownianPath):
            if seed.dim != self.m:
                raise ValueError(f"seed: a BrownianPath of dim {seed.dim} for noise of "
                                 f"dimension {self.m}")
            # a path whose blocks are this run's steps: stepped on its block grid (bit for
            # bit the run an int seed gives)
            self.path = seed
            self.own_grid = seed.block == self.h and seed.t0 == self.t0
        else:
            self.own_grid = True
            # blocks of one step: the grid's times are block ends, reached at once
            self.path = BrownianPath(noise_key(seed), 0, self.m, t0=self.t0, block=self.h)
        self.key = mix64(self.path._comp[0].key)
        self.maps = maps
        self.additive_checked = False
        self.events = 0

    def record(self):
        """What the arc records so the run can be replayed: the Brownian path's
        key and layout (``BrownianPath(seed, run, dim, t0=, block=, depth=)``),
        the method and the step."""
        p = self.path
        return {"noise_seed": p.seed, "noise_run": p.run, "noise_block": p.block,
                "noise_t0": p.t0, "noise_depth": p.depth, "sde_method": self.method,
                "sde_step": self.h}

    def rng_seed(self, seed):
        """The seed the run's other draws (random priority) take."""
        return self.path.seed if isinstance(seed, BrownianPath) else seed

    def _s(self, x, t, j, u):
        v = self.sigma(x, t, j, u)
        shape = (self.n,) if self.diagonal else (self.n, self.m)
        try:
            arr = np.asarray(v, dtype=float)
        except (TypeError, ValueError) as e:
            raise MapError(f"diffusion must return an array of floats, got "
                           f"{type(v).__name__} (at t={t:.10g}, j={j})", "diffusion", t, j) \
                from e
        if arr.shape != shape:
            what = "diagonal noise (noise_dim=None): shape (n,)" if self.diagonal else \
                f"noise_dim={self.m}: shape (n, noise_dim)"
            raise MapError(f"diffusion must return an array of shape {shape} ({what}), got "
                           f"shape {arr.shape} (at t={t:.10g}, j={j})", "diffusion", t, j)
        return arr

    # the guard process y (an entry when y reaches 0 from below) and its noise
    def _grad(self, y, x, t, j, u):
        g = np.empty(self.n)
        for i in range(self.n):
            e = 1e-6 * max(1.0, abs(x[i]))
            xp, xm = x.copy(), x.copy()
            xp[i] += e
            xm[i] -= e
            g[i] = (y(xp, t, j, u) - y(xm, t, j, u)) / (2 * e)
        return g

    def _noise(self, s, grad):
        """(s^2, σσ^T ∇y) of the guard process."""
        if self.diagonal:
            v = s * s * grad
        else:
            v = s @ (s.T @ grad)
        return float(grad @ v), v

    def _w(self, t, k):
        """(W, ∫W) at t, the grid's k-th time when k is not None."""
        if k is not None and self.own_grid:
            return self.path.at_block(k)
        return self.path._query(t)

    def _step(self, run, a, x, h, j, u, f, ka, kb):
        s = self._s(x, a, j, u)
        b = a + h
        wa, Fa = self._w(a, ka)
        wb, Fb = self._w(b, kb)
        dw = wb - wa
        if self.method == "SRA1":
            i10 = Fb - Fa - h * wa
            s_b = self._s(x, b, j, run._u(b))
            if not self.additive_checked:
                x_probe = x + 1.0 + np.abs(x)
                if not np.array_equal(self._s(x_probe, a, j, u), s):
                    raise MapError("diffusion depends on the state, but method='SRA1' takes "
                                   "additive noise (σ a function of t and j only); use 'EM' "
                                   "or 'Milstein'", "diffusion", a, j)
                self.additive_checked = True

            def f_of(tt, xx):
                return run.maps.f(xx, tt, j, run._u(tt))
            return sra1_step(x, a, h, f_of, s, s_b, dw, i10, self.diagonal), s
        if self.method == "Milstein":
            s_hat = self._s(x + f * h + s * math.sqrt(h), a, j, u)
            return milstein_step(x, f, s, s_hat, dw, h), s
        return em_step(x, f, s, dw, h, self.diagonal), s

    def _crossing(self, y, a, xa, b, xb, s, j, u, stream):
        """The event time and state in (a, b] of the guard process y, or None."""
        ya, yb = y(xa, a, j, u), y(xb, b, j, u)
        if not (math.isfinite(ya) and math.isfinite(yb)):
            return None
        if yb < 0:
            grad = self._grad(y, xa, a, j, u)
            s2, v = self._noise(s, grad)
            if stream.uniform() >= crossing_probability(ya, yb, s2, b - a):
                return None
        else:
            grad = self._grad(y, xa, a, j, u)
            s2, v = self._noise(s, grad)
            if ya >= 0:
                return b, xb
            if not s2 > 0:        # a guard without noise (a rate's clock): the chord's zero
                th = ya / (ya - yb)
                return a + th * (b - a), xa + th * (xb - xa)
        tau = bridge_first_passage(ya, yb, s2, b - a, stream)
        th = tau / (b - a)
        te = min(a + tau, b)
        y_lin = ya + (yb - ya) * th
        xe = xa + (xb - xa) * th - v * (y_lin / s2)
        # onto the guard along the noise's direction v (Newton on y(xe + c v) = 0)
        d = 1e-7 * max(1.0, float(np.abs(xe).max())) / max(float(np.abs(v).max()), 1e-300)
        for _ in range(8):
            ye = y(xe, te, j, u)
            if not math.isfinite(ye) or abs(ye) <= 1e-14 * max(1.0, abs(ya)):
                break
            slope = (y(xe + d * v, te, j, u) - y(xe - d * v, te, j, u)) / (2 * d)
            if not (math.isfinite(slope) and slope != 0):
                break
            xe = xe - v * (ye / slope)
        return te, xe

    def flow(self, run, st, in_D_start):
        """Step from (st.t, st.x) until an event, t_max or a failure (an _Outcome)."""
        from .rules import Action, Priority, event_outcome, needs_coin
        from .solve import _Outcome
        from .system import guard_min
        o, maps, stats, buf = run.o, run.maps, run.stats, run.buf
        C, D = maps.C, maps.D
        has_C, watch_D = maps.has_C, run.watch_D
        t, j, x = st.t, st.j, np.array(st.x, dtype=float)
        hD, hC = maps.hD, maps.hC
        yD = None if hD is None else (lambda xx, tt, jj, uu: guard_min(hD(xx, tt, jj, uu)))
        yC = None if hC is None else (lambda xx, tt, jj, uu: -guard_min(hC(xx, tt, jj, uu)))
        d_active = watch_D and not in_D_start
        stats.flows += 1
        k = 0
        cap = o.max_steps - stats.steps
        H = self.h
        a = t
        ka = 0 if t == self.t0 else None      # the grid index of a, where a is on the grid
        try:
            while True:
                if a >= o.t_max:
                    st.t, st.x = a, x
                    return _Outcome.T_MAX
                if k >= cap:
                    run._stop(Termination.MAX_STEPS, "steps", steps=stats.steps + k,
                              max_steps=o.max_steps, t=a)
                    st.t, st.x = a, x
                    return _Outcome.STOP
                if ka is None:              # off the grid (a flow's start): to the next
                    kb = math.floor((a - self.t0) / H) + 1
                    if self.t0 + kb * H - a <= 1e-12 * max(1.0, abs(a)):
                        ka, kb = kb, kb + 1     # on it, to round-off
                        a = self.t0 + ka * H
                else:
                    kb = ka + 1
                b = self.t0 + kb * H
                if b > o.t_max:
                    b, kb = o.t_max, None
                u = run._u(a)
                f = maps.f(x, a, j, u)
                f = np.asarray(f, dtype=float)
                xb, s = self._step(run, a, x, b - a, j, u, f, ka, kb)
                k += 1
                if not np.all(np.isfinite(xb)):
                    run._stop(Termination.NON_FINITE, "step", t=a, t2=b, j=j)
                    st.t, st.x = a, x
                    return _Outcome.STOP
                stream = _Stream(mix64(self.key ^ _bits(a)) ^ mix64(_bits(b) ^ j))
                hit, kind = None, None
                if d_active:
                    if yD is not None:
                        hit = self._crossing(yD, a, x, b, xb, s, j, u, stream)
                    elif D(xb, b, j, run._u(b)):
                        hit = (b, xb)
                    kind = "D" if hit is not None else None
                if has_C:
                    if yC is not None:
                        hc = self._crossing(yC, a, x, b, xb, s, j, u, stream)
                    else:
                        hc = None if C(xb, b, j, run._u(b)) else (b, xb)
                    if hc is not None and (hit is None or hc[0] < hit[0]):
                        hit, kind = hc, "C"
                if hit is not None:
                    te, xe = hit
                    self.events += 1
                    stats.events += 1
                    buf.append(te, j, xe)
                    st.t, st.x = te, xe
                    ue = run._u(te)
                    in_D = maps.has_D and (kind == "D" or D(xe, te, j, ue))
                    in_C = kind != "C" and ((not has_C) or C(xe, te, j, ue))
                    coin = True
                    if kind == "D" and o.prio == Priority.RANDOM and needs_coin(in_C, True,
                                                                               o.prio):
                        coin = run._coin(st, te)
                    action, _ = event_outcome(kind == "D", in_D, in_C, False, o.prio, coin)
                    if action == Action.JUMP:
                        return _Outcome.JUMP
                    if action == Action.STOP:
                        run._stop_outside(st)
                        return _Outcome.STOP
                    return _Outcome.FLOW_ON
                buf.append(b, j, xb)
                if o.max_norm < math.inf:
                    nb = float(np.linalg.norm(xb))
                    if nb > o.max_norm:
                        run._stop(Termination.BLOWUP, norm=nb, max_norm=o.max_norm, t=b, j=j)
                        st.t, st.x = b, xb
                        return _Outcome.STOP
                if watch_D and not d_active:
                    d_active = not D(xb, b, j, run._u(b))
                a, x, ka = b, xb, kb
        finally:
            stats.steps += k

