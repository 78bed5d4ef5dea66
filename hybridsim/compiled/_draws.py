"""The compiled path's draws: :class:`hybridsim.BrownianPath` and the SDE
stepper's uniform stream, bit for bit (imported only when numba is installed).

The Python path's generator is plain integer arithmetic (SplitMix64's
finaliser of a key and a counter, Box–Muller normals), so the same seed gives
the same Brownian path here: the block sums (the increment and Lévy area of
each block) and the descent of the dyadic tree to a time inside a block are
:mod:`hybridsim.brownian`'s, in uint64 arithmetic. Values agree with the
Python path's to the last bit where ``math.log``/``cos``/``sin`` of the
platform agree with LLVM's (the same libm: they do on Linux x86_64).

A path's state in a kernel is ``(S, F, H, nb)``: per component, W and its
time integral at the block starts and each block's Lévy area, for a window
of the ``nb[0]`` blocks drawn so far starting at block ``nb[1]`` (drawn on
demand, :func:`blocks_to`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..brownian import mix64 as _py_mix64
from ._types import _NJ, _NJL

_U = np.uint64
_GOLD = _U(0x9E3779B97F4A7C15)
_TWO53 = 1.0 / (1 << 53)
_KB = _U(0x9FB21C651E98DF25)
_KI = _U(0xD6E8FEB86659FD93)
_KC = _U(0x2545F4914F6CDD1D)


@njit(**_NJ)
def mix64(z):
    """:func:`hybridsim.brownian.mix64` on a uint64."""
    z = z + _GOLD
    z = (z ^ (z >> _U(30))) * _U(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> _U(27))) * _U(0x94D049BB133111EB)
    return z ^ (z >> _U(31))


@njit(**_NJ)
def _u01(k):
    return (float(mix64(k) >> _U(11)) + 0.5) * _TWO53


@njit(**_NJ)
def normals3(key, out, count):
    """``hybridsim.brownian.normals(key, count)`` (count <= 4) into ``out``."""
    c = 0
    i = 0
    while i < count:
        u1 = _u01(key ^ (_U(2 * c + 1) * _GOLD))
        u2 = _u01(key ^ (_U(2 * c + 2) * _GOLD))
        r = math.sqrt(-2.0 * math.log(u1))
        out[i] = r * math.cos(2.0 * math.pi * u2)
        if i + 1 < count:
            out[i + 1] = r * math.sin(2.0 * math.pi * u2)
        i += 2
        c += 1


@njit(**_NJ)
def _node_key(ck, blk, level, index):
    return mix64(ck ^ mix64(_U(blk) * _KB + _U(level))
                 ^ mix64(_U(index) * _KI + _KC))


@njit(**_NJ)
def blocks_to(keys, S, F, H, nb, T, blk, z):
    """Draw the blocks of every component up to block ``blk`` (inclusive).

    The arrays hold a window of the blocks: column ``q`` is block ``nb[1] + q``
    (``nb[0]`` blocks drawn so far). Queries only move forward in time, so
    when the window is full the blocks before the last two drawn are dropped
    (the arrays doubled only where that is not room enough). ``z``: scratch
    of 4. Returns ``(S, F, H)``."""
    if nb[0] > blk:
        return S, F, H
    m = keys.shape[0]
    if blk + 2 - nb[1] > S.shape[1]:
        shift_window(S, F, H, nb)
    if blk + 2 - nb[1] > S.shape[1]:
        cap = max(2 * S.shape[1], blk + 2 - nb[1])
        S2 = np.zeros((m, cap))
        F2 = np.zeros((m, cap))
        H2 = np.zeros((m, cap))
        for c in range(m):
            for q in range(nb[0] + 1 - nb[1]):
                S2[c, q] = S[c, q]
                F2[c, q] = F[c, q]
            for q in range(nb[0] - nb[1]):
                H2[c, q] = H[c, q]
        S, F, H = S2, F2, H2
    while nb[0] <= blk:
        draw_block(keys, S, F, H, nb[0], nb[0] - nb[1], T, z)
        nb[0] += 1
    return S, F, H


@njit(**_NJL)
def shift_window(S, F, H, nb):
    """Drop the blocks before the last two drawn from the window (:func:`blocks_to`)."""
    drop = nb[0] - 2 - nb[1]
    if drop <= 0:
        return
    for c in range(S.shape[0]):
        for q in range(nb[0] + 1 - nb[1] - drop):
            S[c, q] = S[c, q + drop]
            F[c, q] = F[c, q + drop]
        for q in range(nb[0] - nb[1] - drop):
            H[c, q] = H[c, q + drop]
    nb[1] += drop


@njit(inline="always", **_NJL)
def draw_block(keys, S, F, H, k, q, T, z):
    """Block ``k`` of every component (its increment and Lévy area, W and ∫W
    at its end) into column ``q`` of the window (``q + 1`` for its end)."""
    rt, rt12 = math.sqrt(T), math.sqrt(T / 12.0)
    for c in range(keys.shape[0]):
        normals3(_node_key(keys[c], k, 0, 0), z, 2)
        dw, hh = rt * z[0], rt12 * z[1]
        s = S[c, q]
        H[c, q] = hh
        S[c, q + 1] = s + dw
        F[c, q + 1] = F[c, q] + T * (s + 0.5 * dw) + T * hh


@njit(**_NJ)
def descend(ck, S, F, H, c, blk, q, u, T, depth, z):
    """``(W, ∫W)`` of component ``c`` at position ``u`` in [0, 1) of block ``blk``
    (held in column ``q`` of the window, :func:`blocks_to`; ``BrownianPath._one``:
    the tree's exact conditional midpoints, the chord inside a finest cell).
    ``z``: scratch of 4."""
    lev = 0
    idx = 0
    wl, wr, hh, fl = S[c, q], S[c, q + 1], H[c, q], F[c, q]
    while True:
        sc = float(1 << lev)
        h = T / sc
        pos = u * sc - idx
        if pos == 0.0:
            return wl, fl
        if lev >= depth:
            x = pos * h
            return (wl + pos * (wr - wl),
                    fl + x * wl + 0.5 * x * pos * (wr - wl) + x * hh)
        normals3(_node_key(ck, blk, lev + 1, idx), z, 3)
        b = math.sqrt(h / 4) * z[0]
        hl = math.sqrt(h / 24) * z[1]
        hr = math.sqrt(h / 24) * z[2]
        r = hh - 0.5 * (b + hl + hr)
        b, hl, hr = b + 1.5 * r, hl + 0.25 * r, hr + 0.25 * r
        wm = 0.5 * (wl + wr) + b
        if pos < 0.5:
            idx, wr, hh = 2 * idx, wm, hl
        else:
            fl = fl + 0.5 * h * (0.5 * (wl + wm) + hl)
            idx, wl, hh = 2 * idx + 1, wm, hr
        lev += 1


@njit(**_NJ)
def stream_uniform(key, c):
    """The ``c``-th uniform (c >= 1) of ``hybridsim._sde._Stream(key)``."""
    return _u01(key ^ (_U(c) * _GOLD))


@njit(**_NJ)
def threshold_at(hi, lo, k):
    """``hybridsim._random_jumps.threshold(key, k)`` of the key whose halves are
    the floats ``hi``, ``lo`` (the rate's clock, :func:`hybridsim._random_jumps.clock`)."""
    key = (_U(int(hi)) << _U(32)) | _U(int(lo))
    z = mix64(mix64(key ^ _U(0x5DEECE66D)) ^ mix64(_U(k + 1)))
    return -math.log((float(z >> _U(11)) + 0.5) * _TWO53)


@njit(**_NJ)
def path_keys_many(seeds, dim):
    """:func:`path_keys` ``(seed, 0, dim)`` of each of ``seeds`` (uint64 < 2**63), one row each."""
    out = np.empty((seeds.shape[0], dim + 1), np.uint64)
    r0 = mix64(_U(0x632BE59BD9B4E019))
    for i in range(seeds.shape[0]):
        base = mix64(mix64(seeds[i]) ^ r0)
        for c in range(dim):
            out[i, c] = mix64(base ^ mix64(_U(c + 1)))
        out[i, dim] = mix64(out[i, 0])
    return out


def path_keys(seed, run, dim):
    """The per-component keys of ``BrownianPath(seed, run, dim)`` and the SDE
    stepper's stream key (``mix64`` of the first), as a uint64 array of
    ``dim + 1`` (computed in Python, as :class:`hybridsim.BrownianPath` does)."""
    from ..brownian import BrownianPath
    p = BrownianPath(seed, run, dim)
    ks = [c.key for c in p._comp]
    return np.array(ks + [_py_mix64(ks[0])], dtype=np.uint64)


@njit(**_NJ)
def clocks_many(keys, X, j0):
    """Each row's rate clock (:func:`hybridsim._random_jumps.clock` of ``keys[i]``,
    uint64 < 2**63, at ``j0``) written into the last four columns of ``X``."""
    n = X.shape[1] - 4
    for i in range(keys.shape[0]):
        hi = float(keys[i] >> _U(32))
        lo = float(keys[i] & _U(0xFFFFFFFF))
        X[i, n] = 0.0
        X[i, n + 1] = threshold_at(hi, lo, j0)
        X[i, n + 2] = hi
        X[i, n + 3] = lo
