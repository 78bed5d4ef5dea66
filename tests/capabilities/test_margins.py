"""Signed margins of claims (hybridsim.testing.margin_*): the asserts' verdicts
in numbers, with the (t, j) that decides them."""
from __future__ import annotations

import math

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.testing import (
    Margin,
    all_of,
    any_of,
    assert_bounded,
    assert_exact_after,
    margin_bounded,
    margin_decays,
    margin_exact_after,
    margin_in_set,
    margin_settles_by,
)


def random_arc(rng, n=40):
    t = np.sort(rng.uniform(0, 2, n))
    j = np.cumsum(rng.random(n) < 0.1)
    x = rng.normal(scale=0.5, size=(n, 2))
    return hs.HybridArc(t, j, x, None)


@pytest.mark.parametrize("seed", range(30))
def test_margin_sign_is_the_asserts_verdict(seed):
    """On random arcs, margin >= 0 exactly when the boolean assert passes, and
    the margin is the slack at its deciding sample."""
    rng = np.random.default_rng(seed)
    arc = random_arc(rng)
    atol, level = rng.uniform(0.3, 1.5), rng.uniform(0.3, 1.5)
    m = margin_exact_after(arc, arc.x, t=0.5, atol=atol)
    try:
        assert_exact_after(arc, arc.x, t=0.5, atol=atol)
        passed = True
    except AssertionError:
        passed = False
    assert m.holds == passed
    k = np.flatnonzero((arc.t == m.where[0]) & (arc.j == m.where[1]))
    assert np.isclose(float(m), atol - np.linalg.norm(arc.x[k], axis=1).max())
    b = margin_bounded(arc, arc.x, lambda tt, jj: level * np.exp(-0.3 * tt), j=(1, None))
    try:
        assert_bounded(arc, arc.x, lambda tt, jj: level * np.exp(-0.3 * tt), j=(1, None))
        passed = True
    except AssertionError:
        passed = False
    assert b.holds == passed and b.where[1] >= 1


def test_nan_is_never_a_pass():
    arc = hs.HybridArc([0.0, 1.0], [0, 0], [[0.0], [np.nan]], None)
    assert margin_exact_after(arc, arc.x) == -math.inf
    assert margin_bounded(arc, arc.x, 10.0).where == (1.0, 0)


def test_settles_by_and_never_settled():
    t = np.linspace(0, 3, 7)
    arc = hs.HybridArc(t, np.zeros(7, int), np.exp(-4 * t)[:, None], None)
    m = margin_settles_by(arc, arc.x, by=2.0, threshold=1e-3)
    assert m.where[0] == 1.5 and float(m) == 0.5              # last above 1e-3: t = 1.5
    assert margin_settles_by(arc, arc.x, by=1.0, threshold=1e-3) == -0.5
    assert margin_settles_by(arc, arc.x, by=9.0, threshold=1e-9) == -math.inf


def test_decay_and_set_and_logic():
    t = np.linspace(0, 2, 21)
    arc = hs.HybridArc(t, np.zeros(21, int), np.c_[np.exp(-t), np.zeros(21)], None)
    assert margin_decays(arc, arc.x, c=1.0, rate=1.0) == 0.0     # exactly on the bound
    assert not margin_decays(arc, arc.x, c=0.9, rate=1.0).holds
    inside = margin_in_set(arc, lambda x, tt, jj: 1.0 - np.linalg.norm(x))
    assert float(inside) == 0.0 and inside.where == (0.0, 0)
    a, b = Margin(0.2, 1.0, 0, "a"), Margin(-0.3, 2.0, 1, "b")
    assert all_of(a, b) is b and any_of(a, b) is a
    assert Margin(1.0) + 1 == 2.0 and max(a, b) == 0.2
    with pytest.raises(ValueError, match="at least one"):
        all_of()
    with pytest.raises(ValueError, match="no sample of the arc in the requested range"):
        margin_exact_after(arc, arc.x, j=3)


def test_falsify_reports_where_the_margin_was_decided():
    from hybridsim.falsification import Interval, Space
    from hybridsim.library import Timer

    def run(p):
        return hs.simulate(Timer(p["period"]), [0.0], t_max=3.0)

    def reset_by_period_1(arc):        # tau stays below 1.05 at every sample
        return margin_bounded(arc, arc.x, 1.05)
    res = hs.falsify(run, Space(period=Interval(0.8, 1.2)), reset_by_period_1, budget=50,
                     seed=0, progress=False)
    assert res.verdict == "counterexample" and res.where is not None
    assert res.where[0] == pytest.approx(res.point["period"], rel=1e-9)
