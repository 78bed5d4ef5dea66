"""Jumps at a rate, and random jump maps (the Python path).

A system may declare

- ``jump_rate(x, t, j)`` (any map signature): besides its jump set, the
  state jumps when the rate integrated along the flow since the last
  rate-driven jump reaches a threshold E ~ Exp(1) (a jump at the rate, as a
  Poisson clock whose intensity is the rate). The integral Λ and the
  threshold E are two extra state components flowing as Λ' = rate, E' = 0
  (with two more holding the run's key, its high and low 32 bits, so that a
  batch's rows each draw their own thresholds on every path: :func:`clock`);
  the crossing Λ = E is the guard ``Λ - E`` added to the jump set, located
  like any guard (to 4 ulp of the time, exact for ODE flows; on an SDE flow
  the guard process has no noise and the crossing is the chord's). At a
  rate-driven jump Λ is reset and a new threshold drawn; at a jump of the
  jump set both are kept (by the threshold's memorylessness either is exact
  in law).
- ``jump_law(x, rng)`` (or ``(x, t, rng)``, ``(x, t, j, rng)``): a random
  jump map x+ ~ G(x, ω), drawn with a numpy Generator seeded by the run's
  key and the jump's index (it replaces ``jump_map``; every jump draws).

Draws are counter-based: threshold k is -log(U_k) with U_k a function of
the run's key and k, and jump j's generator is ``default_rng([key, j])``,
so a run replays from its key whatever else changes. The run's key comes
from :func:`hybridsim.simulate`'s ``seed`` (an int; a Generator gives 63
random bits; None: fresh entropy); the arc records it
(``arc.stats["jump_seed"]``) with the thresholds drawn
(``arc.stats["thresholds"]``). :func:`simulate_random` runs the system with
the two components added and returns the arc of the system's own state.
"""
from __future__ import annotations

import math

import numpy as np

from .brownian import mix64
from .options import check_map_value
from .rules import MapError
from .system import HybridSystem, _arity, _named, guard_min

__all__ = ["is_random", "simulate_random", "threshold", "clock", "strip"]

_TWO53 = 1.0 / (1 << 53)


def is_random(system) -> bool:
    """True when ``system`` declares ``jump_rate`` or ``jump_law``."""
    return getattr(system, "jump_rate", None) is not None or \
        getattr(system, "jump_law", None) is not None


def threshold(key: int, k: int) -> float:
    """The k-th Exp(1) threshold of the run keyed ``key``: -log(U_k).

    Examples
    --------
    >>> threshold(3, 0) == threshold(3, 0), threshold(3, 0) > 0
    (True, True)
    """
    u = ((mix64(mix64(key ^ 0x5DEECE66D) ^ mix64(k + 1)) >> 11) + 0.5) * _TWO53
    return -math.log(u)


def _law(fn):
    if not callable(fn):
        raise TypeError(f"jump_law must be callable (x, rng) -> x+, got {type(fn).__name__}")
    k = _arity(fn)
    if k not in (2, 3, 4):
        raise TypeError(f"jump_law must take (x, rng), (x, t, rng) or (x, t, j, rng); got a "
                        f"callable with {k} positional arguments")

    def call(x, t, j, rng):
        try:
            return fn(x, rng) if k == 2 else fn(x, t, rng) if k == 3 else fn(x, t, j, rng)
        except MapError:
            raise
        except Exception as e:
            raise MapError(f"jump_law raised {type(e).__name__}: {e} (at t={t:.10g}, j={j})",
                           "jump_law", t, j) from e
    return call


class _Augmented(HybridSystem):
    """``base`` with (Λ, E) appended (when it has a rate) and its random jump map."""

    def __init__(self, base, key):
        n = int(base.state_dim)
        maps = base._compile()
        self.base, self.key, self.n = base, key, n
        rate = None if base.jump_rate is None else _named(base.jump_rate, "jump_rate")
        law = None if getattr(base, "jump_law", None) is None else _law(base.jump_law)
        self.has_rate = rate is not None
        m = n + CLOCK if self.has_rate else n
        self.state_dim = m
        self.input_dim = base.input_dim
        self.output_dim = base.output_dim
        self.max_step = base.max_step
        self.components = base.components
        self._name = f"{type(base).__name__} (random jumps)"
        f, g, C, D, hD, hC = maps.f, maps.g, maps.C, maps.D, maps.hD, maps.hC

        def flow_map(x, t, j, u):
            fx = np.asarray(f(x[:n], t, j, u), dtype=float)
            if not self.has_rate:
                return fx
            r = rate(x[:n], t, j, u)
            try:
                r = float(r)
            except (TypeError, ValueError):
                raise MapError(f"jump_rate must return a number, got {type(r).__name__} "
                               f"(at t={t:.10g}, j={j})", "jump_rate", t, j) from None
            if not (r >= 0 and math.isfinite(r)):
                raise MapError(f"jump_rate returned {r} (at t={t:.10g}, j={j}): a rate must "
                               f"be a finite number >= 0", "jump_rate", t, j)
            out = np.zeros(m)
            out[:n] = fx
            out[n] = r
            return out
        self.flow_map = flow_map

        def jump_map(x, t, j, u):
            xs = x[:n]
            if law is not None:
                rng = np.random.default_rng([key, int(j)])
                xn = check_map_value("jump_law", law(xs, t, j, rng), n, t, j)
            else:
                xn = np.asarray(g(xs, t, j, u), dtype=float)
            if not self.has_rate:
                return xn
            out = np.empty(m)
            out[:n] = xn
            out[n:] = x[n:]
            if x[n] >= x[n + 1]:                 # the rate's jump: a new clock
                out[n], out[n + 1] = 0.0, threshold(key, int(j) + 1)
            return out
        self.jump_map = jump_map

        if base.has_flow_boundary:
            self.flow_set = lambda x, t, j, u: C(x[:n], t, j, u)
            if hC is not None:
                self.flow_guard = lambda x, t, j, u: hC(x[:n], t, j, u)
        user_D = base.has_jumps
        if self.has_rate:
            if hD is not None and not base._overrides("jump_set"):
                self.jump_guard = lambda x, t, j, u: max(guard_min(hD(x[:n], t, j, u)),
                                                         x[n] - x[n + 1])
            elif user_D:        # an indicator: the union, located by bisection
                self.jump_set = lambda x, t, j, u: bool(x[n] >= x[n + 1]) or \
                    D(x[:n], t, j, u)
            else:
                self.jump_guard = lambda x, t, j, u: x[n] - x[n + 1]
        elif user_D:
            self.jump_set = lambda x, t, j, u: D(x[:n], t, j, u)
            if hD is not None:
                self.jump_guard = lambda x, t, j, u: hD(x[:n], t, j, u)
        out_map = maps.h
        self.output = lambda x, t, j: out_map(x[:n], t, j, None)
        if maps.W is not None:         # the watched functions, of the user's state
            W = maps.W
            self.watch = lambda x, t, j, u: W(x[:n], t, j, u)
            self.watch_direction = base.watch_direction
        if getattr(base, "diffusion", None) is not None:
            sig = _named(base.diffusion, "diffusion")
            self.noise_dim = base.noise_dim

            def diffusion(x, t, j, u):
                s = np.asarray(sig(x[:n], t, j, u), dtype=float)
                if not self.has_rate or s.shape not in ((n,), (n, s.shape[-1])):
                    return s                 # its shape checked (and named) by the stepper
                return np.concatenate([s, np.zeros((CLOCK,) + s.shape[1:])])
            self.diffusion = diffusion


#: the clock's components appended to the state: Λ, E and the key's two halves
CLOCK = 4


def clock(key, j0=0):
    """The clock's initial components ``[Λ, E, key >> 32, key & 0xFFFFFFFF]``
    (exact floats) of the run keyed ``key``.

    Examples
    --------
    >>> c = clock(2**40 + 5)
    >>> c[0], int(c[2]) << 32 | int(c[3])
    (0.0, 1099511627781)
    """
    return [0.0, threshold(key, int(j0)), float(key >> 32), float(key & 0xFFFFFFFF)]


def run_key(seed):
    """The run's key (an int < 2**63) from ``seed``."""
    from ._sde import noise_key
    if (seed is not None and not isinstance(seed, (int, np.integer, np.random.Generator,
                                                  np.random.SeedSequence))) \
            or isinstance(seed, bool):
        raise TypeError(f"seed must be None, a non-negative int or a numpy Generator, got "
                        f"{type(seed).__name__} {seed!r}")
    if isinstance(seed, (int, np.integer)) and seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    return noise_key(seed)


def simulate_random(simulate, system, x0, kwargs):
    """Run ``system`` (declaring ``jump_rate``/``jump_law``) through ``simulate``.

    The thresholds' components are added to the state for the run and taken
    off its arc; ``arc.stats`` records ``jump_seed`` and ``thresholds``.
    """
    key = run_key(kwargs.pop("seed", None))
    aug = _Augmented(system, key)
    n = aug.n
    x = np.asarray(x0, dtype=float).reshape(-1)
    if x.shape != (n,):
        raise ValueError(f"x0 must have shape ({n},), got {np.shape(x0)}")
    if aug.has_rate:
        x = np.concatenate([x, clock(key, kwargs.get("j0", 0))])
    arc = simulate(aug, x, seed=key, **kwargs)
    return strip(arc, system, key, n, aug.has_rate)


def strip(arc, system, key, n, has_rate):
    """The arc of ``system``'s own state (the first ``n`` components) of a run
    with the clock appended; ``stats`` records ``jump_seed`` and ``thresholds``."""
    from .arc import Crossings, HybridArc
    stats = dict(arc.stats or {})
    stats["jump_seed"] = key
    if has_rate:
        E = arc.x[:, n + 1]
        stats["thresholds"] = E[np.r_[True, E[1:] != E[:-1]]].tolist()
    xdot = None if arc.xdot is None else arc.xdot[:, :n]
    out = HybridArc(arc.t, arc.j, arc.x[:, :n], arc.termination, arc.message, arc.exception,
                    components=system.components, system=system, xdot=xdot, stats=stats)
    c = arc.crossings
    if c is not None:
        out.crossings = Crossings(c.t, c.j, c.which, c.direction, c.x[:, :n])
    return out
