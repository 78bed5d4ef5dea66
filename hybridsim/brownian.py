"""Reproducible Brownian paths, queryable at any time (a virtual Brownian tree).

A :class:`BrownianPath` is one Brownian motion W (of ``dim`` independent
components) per ``(seed, run)``, defined before it is queried: its value at
any time is a function of the key and the time only, so the same seed gives
the same path whatever the step sequence, under rejected steps, and in any
order of queries.

Construction: time from ``t0`` is cut into blocks of length ``block``. A
block's increment and its space-time Lévy area H (the mean of the path minus
its chord over the block, ``N(0, T/12)``, independent of the increment) are
drawn from a counter-based generator (SplitMix64 of the key, block, level,
index and component; Box–Muller normals). Each cell of the dyadic tree of a
block is refined by the exact conditional law of the midpoint value and of
the two halves' Lévy areas given the cell's increment and Lévy area (a
Gaussian conditioned on the linear identity ``H = (b + H_left + H_right)/2``,
b the midpoint's deviation from the chord), down to ``depth`` levels;
inside a finest cell (``block / 2**depth`` long) the path is the chord. A
time on the tree's grid (a dyadic point of a block) is reached exactly,
without interpolation. The tree carries the time integral of W too, so
``integral(s, t)`` (∫_s^t (W(u) - W(s)) du, what strong order 1.5 schemes
need) comes with the same descent.

The generator is plain integer arithmetic (no numpy state), so a compiled
kernel can reproduce it bit for bit later.

Examples
--------
>>> w = BrownianPath(seed=1, dim=2)
>>> a = w(0.3)
>>> bool((w(0.3) == a).all()), w(0.0).tolist()
(True, [0.0, 0.0])
>>> d = w.increment(0.25, 0.5)
>>> bool(abs(d - (w(0.5) - w(0.25))).max() < 1e-15)
True
"""
from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["BrownianPath", "mix64", "normals"]

_M = (1 << 64) - 1
_GOLD = 0x9E3779B97F4A7C15
_TWO53 = 1.0 / (1 << 53)


def mix64(z: int) -> int:
    """SplitMix64's finaliser of ``z`` (a 64-bit integer hash).

    Examples
    --------
    >>> mix64(0) != mix64(1), 0 <= mix64(12345) < 2**64
    (True, True)
    """
    z = (z + _GOLD) & _M
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _M
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _M
    return z ^ (z >> 31)


def normals(key: int, count: int) -> list[float]:
    """``count`` standard normals, a function of the 64-bit ``key`` alone.

    Box–Muller on uniforms in (0, 1) from SplitMix64 of ``key`` and a counter.

    Examples
    --------
    >>> normals(7, 3) == normals(7, 3), len(normals(7, 3))
    (True, 3)
    """
    out = []
    c = 0
    while len(out) < count:
        u1 = ((mix64(key ^ (2 * c + 1) * _GOLD & _M) >> 11) + 0.5) * _TWO53
        u2 = ((mix64(key ^ (2 * c + 2) * _GOLD & _M) >> 11) + 0.5) * _TWO53
        r = math.sqrt(-2.0 * math.log(u1))
        out.append(r * math.cos(2.0 * math.pi * u2))
        out.append(r * math.sin(2.0 * math.pi * u2))
        c += 1
    return out[:count]


def _key(seed, run):
    return mix64(mix64(seed & _M) ^ mix64((run * _GOLD + 0x632BE59BD9B4E019) & _M))


class _Component:
    """One component's tree: block sums, and the last descent (for reuse)."""

    __slots__ = ("key", "S", "F", "H", "path")

    def __init__(self, key):
        self.key = key
        self.S = [0.0]       # W at block starts
        self.F = [0.0]       # ∫ W from t0 to block starts
        self.H = []          # each block's Lévy area
        self.path = None     # the last descent: [(block, level, index, wl, wr, H, F_left)]


class BrownianPath:
    """One Brownian path of ``dim`` components per ``(seed, run)``, at any time >= t0.

    Parameters
    ----------
    seed : int
        A non-negative int (the study's seed).
    run : int
        The run's index: each (seed, run) is an independent path.
    dim : int
        Number of independent components.
    t0 : float
        W(t0) = 0; times before t0 are refused.
    block : float
        Length of the tree's blocks (the path is exact at the dyadic points
        ``t0 + block * k / 2**level``, level <= depth).
    depth : int
        Levels of the tree in a block (between 1 and 60): the finest cell is
        ``block / 2**depth`` long, and the path is its chord inside it.

    Examples
    --------
    The same value whatever the queries before it:

    >>> a = BrownianPath(3, run=5)
    >>> b = BrownianPath(3, run=5)
    >>> _ = [b(s) for s in (0.9, 0.1, 0.55)]
    >>> bool(a(0.37)[0] == b(0.37)[0])
    True
    """

    def __init__(self, seed: int = 0, run: int = 0, dim: int = 1, *, t0: float = 0.0,
                 block: float = 1.0, depth: int = 24):
        for name, v in (("seed", seed), ("run", run)):
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 0:
                raise ValueError(f"BrownianPath: {name} must be a non-negative int, got {v!r}")
        if isinstance(dim, bool) or not isinstance(dim, numbers.Integral) or dim < 1:
            raise ValueError(f"BrownianPath: dim must be a positive int, got {dim!r}")
        if not (isinstance(block, numbers.Real) and math.isfinite(block) and block > 0):
            raise ValueError(f"BrownianPath: block must be a positive finite float, "
                             f"got {block!r}")
        if not isinstance(t0, numbers.Real) or not math.isfinite(t0):
            raise ValueError(f"BrownianPath: t0 must be finite, got {t0!r}")
        if isinstance(depth, bool) or not isinstance(depth, numbers.Integral) \
                or not 1 <= depth <= 60:
            raise ValueError(f"BrownianPath: depth must be an int in [1, 60], got {depth!r}")
        self.seed, self.run, self.dim = int(seed), int(run), int(dim)
        self.t0, self.block, self.depth = float(t0), float(block), int(depth)
        base = _key(self.seed, self.run)
        self._comp = [_Component(mix64(base ^ mix64(c + 1))) for c in range(self.dim)]

    @classmethod
    def from_generator(cls, rng: np.random.Generator, dim: int = 1, **kw) -> BrownianPath:
        """A path keyed by 63 random bits drawn from ``rng`` (seeded runs of a study).

        Examples
        --------
        >>> import numpy as np
        >>> a = BrownianPath.from_generator(np.random.default_rng(4))
        >>> b = BrownianPath.from_generator(np.random.default_rng(4))
        >>> bool(a(0.5)[0] == b(0.5)[0])
        True
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy Generator, got {type(rng).__name__}")
        return cls(int(rng.integers(0, 2**63)), 0, dim, **kw)

    def __getstate__(self):
        return {k: getattr(self, k) for k in ("seed", "run", "dim", "t0", "block", "depth")}

    def __setstate__(self, s):
        self.__init__(s["seed"], s["run"], s["dim"], t0=s["t0"], block=s["block"],
                      depth=s["depth"])

    def __repr__(self):
        return f"BrownianPath(seed={self.seed}, run={self.run}, dim={self.dim})"

    # ------------------------------------------------------------------ the tree
    def _node_normals(self, comp, blk, level, index, count):
        k = mix64(comp.key ^ mix64((blk * 0x9FB21C651E98DF25 + level) & _M)
                  ^ mix64((index * 0xD6E8FEB86659FD93 + 0x2545F4914F6CDD1D) & _M))
        return normals(k, count)

    def _block_sums(self, comp, blk):
        T = self.block
        while len(comp.S) <= blk + 1:
            k = len(comp.S) - 1
            z0, z1 = self._node_normals(comp, k, 0, 0, 2)
            dw, H = math.sqrt(T) * z0, math.sqrt(T / 12.0) * z1
            s = comp.S[k]
            comp.H.append(H)
            comp.S.append(s + dw)
            comp.F.append(comp.F[k] + T * (s + 0.5 * dw) + T * H)
        return comp.S[blk], comp.S[blk + 1]

    def _root(self, comp, blk):
        wl, wr = self._block_sums(comp, blk)
        return (blk, 0, 0, wl, wr, comp.H[blk], comp.F[blk])

    def _one(self, comp, t):
        """(W(t), ∫_{t0}^t W) for one component."""
        T = self.block
        s = (t - self.t0) / T
        blk = math.floor(s)
        if blk < 0:
            raise ValueError(f"BrownianPath: t = {t} is before t0 = {self.t0}")
        u = s - blk                                  # position in the block, [0, 1)
        path = comp.path
        if path is None or path[0][0] != blk:
            path = [self._root(comp, blk)]
        else:
            # keep the ancestors whose cell still holds u
            k = 1
            while k < len(path):
                _, lev, idx = path[k][:3]
                if not idx <= u * (1 << lev) < idx + 1:
                    break
                k += 1
            path = path[:k]
        while True:
            _, lev, idx, wl, wr, H, Fl = path[-1]
            h = T / (1 << lev)
            pos = u * (1 << lev) - idx                 # in [0, 1) within the cell
            if pos == 0.0:
                comp.path = path
                return wl, Fl
            if lev >= self.depth:                      # the chord inside the finest cell
                comp.path = path
                x = pos * h
                # the integral: the chord's, plus the cell's Lévy area pro rata (continuous,
                # and the cell's exact integral at its end)
                return (wl + pos * (wr - wl),
                        Fl + x * wl + 0.5 * x * pos * (wr - wl) + x * H)
            zb, zl, zr = self._node_normals(comp, blk, lev + 1, idx, 3)
            b, HL, HR = math.sqrt(h / 4) * zb, math.sqrt(h / 24) * zl, math.sqrt(h / 24) * zr
            r = H - 0.5 * (b + HL + HR)               # condition on H = (b + HL + HR) / 2
            b, HL, HR = b + 1.5 * r, HL + 0.25 * r, HR + 0.25 * r
            wm = 0.5 * (wl + wr) + b
            if pos < 0.5:
                path.append((blk, lev + 1, 2 * idx, wl, wm, HL, Fl))
            else:
                Fm = Fl + 0.5 * h * (0.5 * (wl + wm) + HL)
                path.append((blk, lev + 1, 2 * idx + 1, wm, wr, HR, Fm))

    def _query(self, t):
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f"BrownianPath: t must be finite, got {t}")
        w = np.empty(self.dim)
        F = np.empty(self.dim)
        for c, comp in enumerate(self._comp):
            w[c], F[c] = self._one(comp, t)
        return w, F

    def at_block(self, k: int):
        """``(W, ∫_{t0} W)`` at the block end ``t0 + k * block`` (k >= 0), each (dim,).

        The same values as at that time, without the float division that
        places a time in its block (a stepper on the block grid uses it).
        """
        if k < 0:
            raise ValueError(f"BrownianPath: block index must be >= 0, got {k}")
        w = np.empty(self.dim)
        F = np.empty(self.dim)
        for c, comp in enumerate(self._comp):
            self._block_sums(comp, k)
            w[c], F[c] = comp.S[k], comp.F[k]
        return w, F

    # ------------------------------------------------------------------ public
    def __call__(self, t):
        """W(t): shape (dim,) for a scalar t, (len(t), dim) for an array."""
        if np.ndim(t) == 0:
            return self._query(t)[0]
        return np.array([self._query(s)[0] for s in np.asarray(t, dtype=float).reshape(-1)])

    def increment(self, s: float, t: float) -> np.ndarray:
        """W(t) - W(s), shape (dim,)."""
        return self._query(t)[0] - self._query(s)[0]

    def integral(self, s: float, t: float) -> np.ndarray:
        """∫_s^t (W(u) - W(s)) du, shape (dim,): the iterated integral I_(1,0).

        Examples
        --------
        >>> w = BrownianPath(0)
        >>> bool(abs(w.integral(0.5, 0.5)[0]) == 0.0)
        True
        """
        ws, Fs = self._query(s)
        _, Ft = self._query(t)
        return Ft - Fs - (t - s) * ws

    def increments(self, s: float, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(W(t) - W(s), ∫_s^t (W(u) - W(s)) du)`` in one pair of queries."""
        ws, Fs = self._query(s)
        wt, Ft = self._query(t)
        return wt - ws, Ft - Fs - (t - s) * ws
