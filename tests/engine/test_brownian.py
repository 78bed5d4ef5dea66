"""hybridsim.brownian: one reproducible Brownian path per (seed, run), at any time.

Known answers: W(t) - W(s) ~ N(0, t - s); the bridge midpoint W((s+t)/2) - (W(s) +
W(t))/2 ~ N(0, (t - s)/4), independent of the increment; I = ∫_s^t (W - W(s)) has
variance (t - s)^3/3 and covariance (t - s)^2/2 with the increment. Moments are checked
over 3000 independent runs at 4.5 standard errors (a chi-square variance estimate's
relative sd is sqrt(2/N) = 2.6%).
"""
from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from hybridsim.brownian import BrownianPath, normals

N = 3000


def moments(h, s=0.3):
    d, m, integ = np.empty(N), np.empty(N), np.empty(N)
    for r in range(N):
        w = BrownianPath(11, r, block=1.0)
        d[r], integ[r] = (v[0] for v in w.increments(s, s + h))
        m[r] = w(s + h / 2)[0] - w(s)[0] - 0.5 * d[r]
    return d, m, integ


@pytest.mark.slow
@pytest.mark.parametrize("h", [0.125, 0.1])        # a dyadic step, and one that is not
def test_increments_bridge_and_integral_moments(h):
    d, m, integ = moments(h)
    tol = 4.5 * math.sqrt(2 / N)
    assert abs(d.mean()) < 4.5 * math.sqrt(h / N)
    assert d.var() / h == pytest.approx(1, abs=tol)
    assert m.var() / (h / 4) == pytest.approx(1, abs=tol)                 # the bridge
    assert abs(np.corrcoef(m, d)[0, 1]) < 4.5 / math.sqrt(N)              # independent
    assert integ.var() / (h ** 3 / 3) == pytest.approx(1, abs=tol)
    # corr(dW, I) = (h^2/2) / sqrt(h * h^3/3) = sqrt(3)/2
    assert np.corrcoef(d, integ)[0, 1] == pytest.approx(math.sqrt(3) / 2, abs=0.02)


def test_same_path_whatever_the_queries():
    ts = np.linspace(0.0, 3.0, 301)       # three blocks
    a = BrownianPath(5, 2, dim=2)(ts)
    b = BrownianPath(5, 2, dim=2)
    rng = np.random.default_rng(0)
    b(np.sort(rng.uniform(0, 3, 40)))     # another step sequence first ...
    b(rng.uniform(0, 3, 40))              # ... and rejected steps in any order
    np.testing.assert_array_equal(b(ts[::-1])[::-1], a)
    assert not np.array_equal(BrownianPath(5, 3, dim=2)(ts), a)       # another run
    assert not np.array_equal(a[:, 0], a[:, 1])                        # components differ
    c = pickle.loads(pickle.dumps(BrownianPath(5, 2, dim=2)))
    np.testing.assert_array_equal(c(ts), a)


def test_integral_is_additive_and_matches_quadrature():
    w = BrownianPath(8, block=1.0, depth=12)
    s, u, t = 0.2, 0.45, 0.9
    i_st = w.integral(s, t)
    # ∫_s^t (W - W(s)) = ∫_s^u (W - W(s)) + ∫_u^t (W - W(u)) + (t - u)(W(u) - W(s))
    split = w.integral(s, u) + w.integral(u, t) + (t - u) * w.increment(s, u)
    np.testing.assert_allclose(i_st, split, atol=1e-13)
    # the trapezoid rule on the finest cells (h_f = 2^-12) misses only their Lévy areas,
    # independent N(0, h_f/12) each weighted by h_f: sd sqrt((t - s) h_f / 12); 5 sd
    hf = 2.0 ** -12
    k0, k1 = round(s / hf), round(t / hf)
    grid = np.arange(k0, k1 + 1) * hf
    vals = w(grid)[:, 0] - w(grid[0])[0]
    trap = float(np.sum(0.5 * (vals[1:] + vals[:-1])) * hf)
    ref = w.integral(grid[0], grid[-1])[0]
    assert ref == pytest.approx(trap, abs=5 * math.sqrt((t - s) * hf / 12))
    # and the integral is continuous through a finest cell's end
    e = grid[5]
    assert abs(w.integral(s, e)[0] - w.integral(s, np.nextafter(e, 0))[0]) < 1e-12


def test_normals_are_standard():
    z = np.array([x for k in range(2000) for x in normals(k, 3)])
    assert abs(z.mean()) < 4.5 / math.sqrt(len(z))
    assert z.var() == pytest.approx(1, abs=4.5 * math.sqrt(2 / len(z)))


def test_from_generator_and_bad_input():
    a = BrownianPath.from_generator(np.random.default_rng(1), dim=3)
    assert a(0.7).shape == (3,)
    with pytest.raises(ValueError, match="before t0"):
        BrownianPath(0, t0=1.0)(0.5)
    with pytest.raises(ValueError, match="seed must be a non-negative int"):
        BrownianPath(-1)
    with pytest.raises(ValueError, match="dim"):
        BrownianPath(0, dim=0)
    with pytest.raises(ValueError, match="depth"):
        BrownianPath(0, depth=0)
    with pytest.raises(ValueError, match="finite"):
        BrownianPath(0)(math.nan)
    with pytest.raises(TypeError, match="Generator"):
        BrownianPath.from_generator(3)
