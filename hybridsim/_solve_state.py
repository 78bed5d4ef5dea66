"""The Python loop's records: how a flow ended (``_Outcome``), the run's
options (``_Options``), statistics (``_Stats``) and state between flows
(``_State``), the sample store (``_Buffer``, ``_SampleCap``), the progress
bar, and a step's dense output read between its ends (``_Hermite``,
``_dense_finite``, ``_dense_derivative``). Used by :mod:`hybridsim.solve`,
which re-exports the names other modules import from it.
"""
from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .options import RunOptions


class _Outcome(enum.Enum):
    """How a flow ended (returned by ``_Run._flow``)."""

    T_MAX = 0       # reached t_max (a jump there is still decided by the loop)
    BREAK = 1       # a delay breakpoint: flow on
    JUMP = 2        # an event that must jump
    FLOW_ON = 3     # random priority chose to flow on in C ∩ D
    STOP = 4        # the run ends; the cause is recorded


class _SampleCap(Exception):
    """Internal: the sample cap was reached."""


class _Buffer:
    """Sample store (t, j, x, xdot).

    Each sample is copied straight into a row of numpy arrays that double
    when full (capped at ``max_samples``): amortised O(1) appends, no
    quadratic copies, 16 + 16n bytes a sample, and no reference kept to the
    solver's arrays, so their memory is reused.
    """

    __slots__ = ("t", "j", "x", "xdot", "m", "dim", "cap", "room")

    def __init__(self, dim, cap=256, max_samples=math.inf):
        self.cap = max_samples
        self.dim = dim
        self.room = int(min(cap, max_samples))
        self.t = np.empty(self.room)
        self.j = np.empty(self.room, dtype=np.int64)
        self.x = np.empty((self.room, dim))
        self.xdot = np.empty((self.room, dim))
        self.m = 0

    @property
    def n(self):
        return self.m

    def _reserve(self, need):
        if need > self.cap:
            raise _SampleCap()
        m = self.m
        self.room = int(min(max(2 * self.room, need, 16), self.cap))
        for name in ("t", "j", "x", "xdot"):
            old = getattr(self, name)
            new = np.empty((self.room,) + old.shape[1:], dtype=old.dtype)
            new[:m] = old[:m]
            setattr(self, name, new)

    def append(self, t, j, x, xdot=None):
        m = self.m
        if m >= self.room:
            self._reserve(m + 1)
        self.t[m] = t
        self.j[m] = j
        self.x[m] = x
        self.xdot[m] = np.nan if xdot is None else xdot
        self.m = m + 1

    def last(self):
        """(t, j, x, xdot) of the last sample."""
        k = self.m - 1
        return float(self.t[k]), int(self.j[k]), self.x[k], self.xdot[k]

    def set_last_xdot(self, v):
        self.xdot[self.m - 1] = v

    def pop(self):
        self.m -= 1

    def extend(self, t, j, X, Xd=None):
        """Append many samples of one j at once."""
        m, k = self.m, len(t)
        if m + k > self.room:
            self._reserve(m + k)
        self.t[m:m + k] = t
        self.j[m:m + k] = j
        self.x[m:m + k] = X
        self.xdot[m:m + k] = np.nan if Xd is None else Xd
        self.m = m + k

    def arrays(self):
        """The samples, shrunk in place (no copy); the buffer is done after this."""
        k = self.m
        self.t.resize(k, refcheck=False)
        self.j.resize(k, refcheck=False)
        self.x.resize((k, self.dim), refcheck=False)
        self.xdot.resize((k, self.dim), refcheck=False)
        return self.t, self.j, self.x, self.xdot


@dataclass(frozen=True)
class _Options(RunOptions):
    """Everything that is fixed during a run: the options every path shares
    (:class:`hybridsim.options.RunOptions`) and the Python path's own."""

    n: int
    Method: type
    t_eval: np.ndarray | None
    keep: bool
    delays: tuple
    rng: np.random.Generator | None     # None unless the priority is random
    dwell: Callable | None = None       # the dwell law in C ∩ D (random priority)


@dataclass
class _Stats:
    """Run statistics, returned as ``arc.stats`` (a dict)."""

    steps: int = 0          # accepted solver steps
    attempts: int = 0       # step attempts, accepted or rejected (RK23, RK45)
    nfev: int = 0           # flow-map evaluations by the solver
    njev: int = 0           # Jacobian evaluations (implicit methods)
    nlu: int = 0            # LU decompositions (implicit methods)
    events: int = 0         # events located (jumps, exits from C)
    flows: int = 0          # flows started (solver restarts)

    def as_dict(self):
        d = dict(self.__dict__)
        a = d.pop("attempts")
        d["rejected"] = max(a - self.steps, 0) if a else None
        return d


@dataclass
class _State:
    """The run's mutable state between flows."""

    t: float
    j: int
    x: np.ndarray
    jumps: int = 0
    short: int = 0              # consecutive jumps after short flows (Zeno)
    zref: float = 0.0           # the shrinking streak's reference flow (rules.zeno_short)
    longest: float = 0.0        # the longest flow so far (rules.chatter_step)
    tiny: int = 0               # consecutive flows tiny against it (chattering)
    same: int = 0               # consecutive jumps at one instant, from C or not
    loop: int = 0               # consecutive jumps at one instant from C ∩ D (a loop)
    t_last_jump: float = 0.0
    flow_lengths: list = field(default_factory=list)   # the last few flows
    h_hint: float | None = None
    breaks: list = field(default_factory=list)          # delay breakpoints
    dwelling: bool = False      # in C ∩ D since an entry whose dwell time was drawn
    deadline: float = math.inf  # ... and the time it jumps at (entry + dwell)
    stiff_hits: int = 0         # Hairer's stiffness counter (DOPRI5's IASTI)
    calm: int = 0               # ... and its reset counter (NONSTI)
    warned_stiff: bool = False


def _progress_bar(progress, t0, t_max, j_max):
    """A bar over t (with j shown) or over jumps; None when progress is off."""
    from ._progress import make_bar
    if math.isfinite(t_max):
        return make_bar(progress, total=t_max - t0, desc="simulate", unit="t",
                        postfix="j=0",
                        bar_format="{l_bar}{bar}| t={n:.4g}/{total:.4g}{postfix} "
                                   "[{elapsed}<{remaining}]")
    return make_bar(progress, total=None if not math.isfinite(j_max) else j_max,
                    desc="simulate", unit="jump")


class _Hermite:
    """The cubic Hermite interpolant of a step from its ends' states and slopes."""

    __slots__ = ("a", "h", "ya", "yb", "ma", "mb")

    def __init__(self, a, ya, fa, b, yb, fb):
        self.a, self.h = a, b - a
        self.ya, self.yb = ya, yb
        self.ma, self.mb = self.h * fa, self.h * fb

    def __call__(self, t):
        s = (t - self.a) / self.h
        s2 = s * s
        return (self.ya + s2 * (3.0 - 2.0 * s) * (self.yb - self.ya)
                + s * (1.0 - s) ** 2 * self.ma + s2 * (s - 1.0) * self.mb)


def _dense_finite(sol):
    """Whether a step's dense output is finite (an overflow inside the step,
    between finite ends, leaves NaN or inf in its coefficients)."""
    Q = getattr(sol, "Q", None)
    if Q is not None:
        return bool(np.isfinite(Q).all())
    try:
        ts = np.linspace(sol.t_min, sol.t_max, 5)
        return bool(np.isfinite(np.asarray(sol(ts), dtype=float)).all())
    except Exception:  # noqa: BLE001 - an unknown dense output: take it as finite
        return True


def _dense_derivative(sol, ts):
    """d/dt of a Runge-Kutta dense output at times ts, shape (len(ts), n); None otherwise."""
    Q = getattr(sol, "Q", None)
    if Q is None or not hasattr(sol, "h") or not hasattr(sol, "t_old"):
        return None
    s = (np.asarray(ts) - sol.t_old) / sol.h
    k = np.arange(Q.shape[1])
    P = (k + 1) * s[:, None] ** k        # d/ds of s^(k+1), times 1/h cancels h in y
    return P @ Q.T
