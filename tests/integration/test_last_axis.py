"""A model written along the last axis (one ``x[..., k]`` per component, numpy's
array constructors) is one definition for every path.

The vectorized path calls its maps on (N, n) batches; the Python path on one
state, where ``x[..., 0]`` is a 0-d array; the compiled path on the maps
rewritten from source, where ``x[..., 0]`` is ``x[0]``, a number. There
``np.stack(..., axis=-1)``, ``np.full(e.shape, c)``, ``np.zeros(np.shape(e))``,
``np.ones_like(e)``, ``np.full_like(e, c)``, ``np.clip`` and ``.astype`` of
numbers are numbers (a 1-D array for the stack), and numpy's calls where the
operands are arrays (``hybridsim._source_rewrite._Rewrite._of_numbers``).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from paths import _on, run

import hybridsim as hs

G = 9.81
FLOORS = (0.0, -0.3, -0.5, -0.6)
E_MAX = 0.9


class Stairs(hs.HybridSystem):
    """A ball bouncing down a staircase: after its k-th bounce it falls to floor
    ``floors[min(k, 3)]``; its restitution, the third state, is clipped to
    [0, 0.9] at each bounce. Written along the last axis as a vectorized model
    is, with numpy's constructors of arrays."""

    state_dim = 3               # height, velocity, restitution
    vectorized = True
    g = G
    floors = np.array(FLOORS)

    def flow_map(self, x):
        h = x[..., 0]
        return np.stack([x[..., 1], np.full(h.shape, -self.g), np.zeros(np.shape(h))],
                        axis=-1)

    def _floor(self, j):
        k = np.clip(j, 0, self.floors.shape[0] - 1).astype(np.int64)
        return self.floors[k]

    def jump_map(self, x, t, j):
        e = np.clip(x[..., 2], 0.0, E_MAX)
        keep = np.full_like(e, 1.0)
        return np.stack([keep * x[..., 0], -e * x[..., 1], np.ones_like(e) * x[..., 2]],
                        axis=-1)

    def flow_set(self, x, t, j):
        return x[..., 0] >= self._floor(j)

    def jump_set(self, x, t, j):
        return (x[..., 0] <= self._floor(j)) & (x[..., 1] <= 0.0)


class _Case:
    """A model as a case of :func:`paths.run` (its form on each path)."""

    def __init__(self, model):
        self.model = model

    def build(self, path):
        return _on(path, self.model)


def stairs_jump_times(h0, e, n):
    """The bounces' times in closed form: from height h and velocity v the ball
    falls to floor f in (v + sqrt(v^2 + 2 g (h - f))) / g, and leaves it at
    -min(e, 0.9) times its impact velocity."""
    t, h, v, out = 0.0, h0, 0.0, []
    for k in range(n):
        f = FLOORS[min(k, len(FLOORS) - 1)]
        s = (v + math.sqrt(v * v + 2.0 * G * (h - f))) / G
        t += s
        h, v = f, -min(max(e, 0.0), E_MAX) * (v - G * s)
        out.append(t)
    return np.array(out)


@pytest.mark.parametrize("e", [0.6, 0.95])
def test_a_model_on_the_last_axis_is_one_definition_for_every_path(path, e):
    """The staircase ball's bounce times equal the closed form on every path, to
    1e-10 s: each flow is a parabola, which RK45 integrates exactly, and the
    events are located to 4 ulp (the tolerance leaves room for the round-off
    that 8 bounces accumulate). The restitution above 0.9 is clipped."""
    arc = run(path, _Case(Stairs()), [1.0, 0.0, e], t_max=10.0, j_max=8, rtol=1e-10,
              atol=1e-12)
    assert arc.jump_count == 8
    np.testing.assert_allclose(arc.jump_times, stairs_jump_times(1.0, e, 8), rtol=0,
                               atol=1e-10)
    np.testing.assert_allclose(arc.x[arc.j == 8][0, 0], FLOORS[-1], atol=1e-12)


def test_the_rewritten_maps_are_straight_line_where_their_shapes_are_known():
    """On the compiled path the flow and jump maps' stacks of numbers are
    straight-line code writing into the kernel's row (no array made, no
    helper call left but the typed ones of numbers)."""
    from hybridsim import _source
    fns = {part.split("(")[0]: part for part in _source.plan(Stairs()).source.split("\ndef ")}
    flow, jump = fns["_hs_flow"], fns["_hs_jump"]
    assert "_hs_stack" not in flow and "_hs_full" not in flow and "_hs_r[1] = " in flow
    assert "_hs_stack" not in jump and "_hs_r[2] = " in jump
    assert "_hs_clip(x[2], 0.0, _hs_p[" in jump          # E_MAX, a global read per run


def _on_numbers_and_arrays(x, v):
    """numpy's constructors on a number ``x[0]`` and on an array ``v``."""
    a = np.stack([x[..., 0], np.full(x[..., 0].shape, 2.0)], axis=-1)
    b = np.stack([v, 2.0 * v], axis=-1)                    # of arrays: (len(v), 2)
    c = np.clip(v, -0.5, 0.5) + np.zeros(v.shape) + np.zeros_like(v[1:] * 0.0).sum()
    d = np.clip(x[..., 0] * 10.0, -1.0, 1.0) + np.ones_like(x[..., 1])
    k = np.clip(x[..., 0] * 10.0, 0.0, 3.0).astype(np.int64)
    m = (x[..., 1] * 10.0).astype(int) + v.astype(float).sum()     # builtin dtypes
    return a.sum() + b[:, 1].sum() + c.sum() + d + float(k) + np.full_like(v, 3.0).sum() + m


def test_the_helpers_give_numpys_values_on_numbers_and_on_arrays():
    """The typed helpers of the rewrite: of numbers the numbers numpy's 0-d
    results hold, of arrays numpy's own calls; the compiled function's value
    equals numpy's to the bit on random operands."""
    pytest.importorskip("numba")
    from hybridsim.compiled._from_source import compiled_function
    f, p = compiled_function(_on_numbers_and_arrays)
    rng = np.random.default_rng(3)
    for _ in range(20):
        x, v = rng.normal(size=3), rng.normal(size=4)
        assert f(p, x, v) == _on_numbers_and_arrays(x, v)


def _slice_writes(x, v):
    """Slice assignments as numpy does them: steps, a negative step, ``...``
    then a slice, a vector of one broadcast, a number, overlapping source and
    target, ``+=`` into a slice, and a number into a 2-D array (numba's own)."""
    out = np.zeros(9)
    out[0:3] = x
    out[..., 3:5] = v[1:3] * 2.0
    out[5::2] = v[:2]
    out[8:5:-1] += x[::-1]
    out[1:4] = out[0:3]                                     # overlaps: read first
    out[0:3] = out[1:4]                                     # (the other way)
    out[0:6:2] = out[1:4]                                   # (a step: a copy first)
    out[6:8] = v[3:4]                                       # length 1: broadcast
    out[..., :1] = 7.0
    m = np.zeros((2, 3))
    m[1, 0:2] = x[2]
    return np.concatenate((out, m[1]))


def test_slice_assignment_gives_numpys_values():
    """A map's ``a[i:j] = v`` and ``a[..., i:j] = v`` compile as loops
    (``_hs_setitem``: numba's slice assignment compiles the formatting of its
    shape-mismatch message, about 1.7 s of a process's first such map): the
    same values as numpy to the bit, and a ValueError where the lengths differ,
    as numpy's."""
    pytest.importorskip("numba")
    from hybridsim import _source
    from hybridsim.compiled._from_source import compiled_function
    assert _source.plan_function(_slice_writes).source.count("_hs_setitem(") == 9
    f, p = compiled_function(_slice_writes)
    rng = np.random.default_rng(4)
    for _ in range(10):
        x, v = rng.normal(size=3), rng.normal(size=4)
        np.testing.assert_array_equal(f(p, x, v), _slice_writes(x, v))
    with pytest.raises(ValueError):
        _slice_writes(np.ones(2), np.ones(4))
    with pytest.raises(ValueError, match="different size"):
        f(p, np.ones(2), np.ones(4))


class Steps(hs.HybridSystem):
    """x' = m(t), the input piecewise constant on four pieces of [0, 1], its
    values in the state (x, m_0, ..., m_3): each row reads its own piece
    (``np.take_along_axis``: t is one time per row on the vectorized path).
    No jumps: the sets are written as a batch map writes them."""

    state_dim = 5
    vectorized = True
    width = 0.25

    def flow_map(self, x, t):
        k = np.clip(np.floor_divide(t, self.width), 0, 3).astype(np.int64)
        d = np.zeros(x.shape)
        d[..., 0] = np.take_along_axis(x, (1 + k)[..., None], axis=-1)[..., 0]
        return d

    def flow_set(self, x, t):
        return np.ones(x.shape[:-1], bool)

    def jump_set(self, x, t):
        return np.zeros(x.shape[:-1], bool)


def test_each_row_reads_its_own_piece_on_every_path(path):
    """x(1) is the input's integral, a quarter of the sum of its values, on
    every path to 5e-8: at rtol 1e-10 a step that straddles a piece's end is
    cut until its error estimate is met, but that estimate of a step across
    a jump of the integrand is not its error (6e-9 in all here)."""
    m = np.array([1.0, -2.0, 0.5, 3.0])
    arc = run(path, _Case(Steps()), np.r_[0.0, m], t_max=1.0, max_step=0.05, rtol=1e-10,
              atol=1e-12)
    assert arc.jump_count == 0
    np.testing.assert_allclose(arc.x[-1, 0], 0.25 * m.sum(), rtol=0, atol=5e-8)
    np.testing.assert_array_equal(arc.x[-1, 1:], m)



class Turns(hs.HybridSystem):
    """(x0, x1) turning at unit rate, x2' the piece of t of the values in the
    state (x3.., x6): written with a helper method given the state
    (``self._turn(x, 0)``), the entries of a matrix attribute at constant
    indices (``self.M[0, 1]``) and each row's piece broadcast to its batch
    shape (``np.broadcast_to(..., x.shape[:-1])``)."""

    state_dim = 7
    vectorized = True
    M = np.array([[0.0, 1.0], [-1.0, 0.0]])
    width = 0.25

    def _turn(self, x, k):
        return (self.M[0, 0] * x[..., k] + self.M[0, 1] * x[..., k + 1],
                self.M[1, 0] * x[..., k] + self.M[1, 1] * x[..., k + 1])

    def _piece(self, x, t):
        k = np.clip(np.floor(t / self.width), 0, 3).astype(np.int64)
        i = np.broadcast_to(3 + k, x.shape[:-1])
        return np.take_along_axis(x, i[..., None], axis=-1)[..., 0]

    def flow_map(self, x, t):
        d = np.zeros_like(x)
        d[..., 0], d[..., 1] = self._turn(x, 0)
        d[..., 2] = self._piece(x, t)
        return d

    def jump_set(self, x):
        return np.zeros(x.shape[:-1], bool)


def test_a_helper_given_the_state_reads_it_as_one_state_on_every_path(path):
    """(x0, x1)(t) = R(t) (x0, x1)(0) (R the rotation e^{Mt}) and x2(1) the
    values' integral, on every path (1e-9 at rtol 1e-11; 5e-8 for the pieces,
    as above). On the compiled path the helper reads ``x[..., k]`` of the
    caller's state as ``x[k]`` (a number, no 0-d array), ``self.M[0, 1]`` as
    one slot of ``p`` and the broadcast piece as a number."""
    m = np.array([1.0, -2.0, 0.5, 3.0])
    arc = run(path, _Case(Turns()), np.r_[0.6, -0.8, 0.0, m], t_max=1.0, max_step=0.05,
              rtol=1e-11, atol=1e-13)
    c, s = math.cos(1.0), math.sin(1.0)
    np.testing.assert_allclose(arc.x[-1, :2], [c * 0.6 + s * -0.8, -s * 0.6 + c * -0.8],
                               rtol=0, atol=1e-9)
    np.testing.assert_allclose(arc.x[-1, 2], 0.25 * m.sum(), rtol=0, atol=5e-8)
    if path == "compiled":
        from hybridsim import _source
        src = _source.plan(Turns()).source
        turn = next(f for f in src.split("\ndef ") if "_turn(" in f.split("\n")[0])
        assert "x[k]" in turn and "x[..., k]" not in turn and "reshape" not in turn
        piece = next(f for f in src.split("\ndef ") if "_piece(" in f.split("\n")[0])
        assert "_hs_scalar(" in piece and "broadcast_to" not in piece


GRID = np.linspace(0.0, 1.0, 11)


def _interpolated(x, t):
    """A row's samples (G, 2) joined by straight lines at t, numpy.interp's
    formula, as observers.distributed.BandLimitedNoise writes it along the last
    axis: each row's own segment (``np.take_along_axis`` along axis -2), its
    numbers broadcast against its vectors (``e[..., None]``)."""
    grid, G = GRID, GRID.size
    S = np.asarray(x, dtype=float)
    S = S.reshape(S.shape[:-1] + (G, 2))
    t = np.broadcast_to(np.asarray(t, dtype=float), S.shape[:-2])
    k = np.clip(np.searchsorted(grid, t, side="right") - 1, 0, G - 2)
    lo = np.take_along_axis(S, k[..., None, None], axis=-2)[..., 0, :]
    hi = np.take_along_axis(S, k[..., None, None] + 1, axis=-2)[..., 0, :]
    y = (hi - lo) / (grid[k + 1] - grid[k])[..., None] * (t - grid[k])[..., None] + lo
    y = np.where((t >= grid[-1])[..., None], S[..., -1, :], y)
    return np.where((t < grid[0])[..., None], S[..., 0, :], y)


def test_each_rows_segment_and_its_numbers_broadcast_give_numpys_values():
    """The rewrite of a row's gather along axis -2 (``S[k]`` on one state) and
    of ``e[..., None]`` of a number (the number): the compiled function gives
    numpy's values to the bit, inside the grid, on its points and outside it;
    and numpy's own batch of rows agrees with it row by row."""
    pytest.importorskip("numba")
    from hybridsim.compiled._from_source import compiled_function
    f, p = compiled_function(_interpolated)
    rng = np.random.default_rng(8)
    X = rng.normal(size=(40, 2 * GRID.size))
    T = np.concatenate([rng.uniform(-0.2, 1.2, 34), [0.0, 0.3, 1.0, -0.1, 1.5, 0.5]])
    batch = _interpolated(X, T)
    for x, t, row in zip(X, T, batch):
        np.testing.assert_array_equal(f(p, x, t), _interpolated(x, t))
        np.testing.assert_array_equal(f(p, x, t), row)
