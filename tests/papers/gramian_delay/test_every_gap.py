"""Tests of observers.gramian_delay.every_gap: (42) on an example where (40) holds."""
import dataclasses
import itertools

import numpy as np
import pytest
import scipy.integrate

import hybridsim as hs
from observers.gramian_delay import every_gap as eg
from observers.gramian_delay.design import theorem2_constants
from observers.gramian_delay.example import errors, explore_samples, simulate

T4 = 4.0        # a short horizon: (42) is judged from 3 tau + T_bar = 3.1 s


def test_example_constants_by_hand():
    """K1 = K2 = 0 (F1 = F2 = 0), and mu of (41) from (38) by plain quadrature.

    A1 = -1, A2 = 1, k = 0.5, tau = 1: A1 + kI = -0.5, lambda(s) = -2 (1 - e^{-s/2}),
    H = -2, A1^T + 2kI = 0, so q1 = varsigma_4 = |S^-1| |H| ((1 - e^{-k tau}) / k + tau)
    (+ |R| with omega in (13)) and mu = q1 + k.
    """
    form, d = eg._form_design()
    assert all(np.all(L == 0.0) for L in form._linear)              # F1 = F2 = 0
    lam = lambda s: -2.0 * (1.0 - np.exp(-0.5 * s))  # noqa: E731
    S = scipy.integrate.quad(lambda s: lam(s) ** 2, -1.0, 0.0, epsabs=0, epsrel=1e-13)[0]
    Nn = scipy.integrate.quad(lam, -1.0, 0.0, epsabs=0, epsrel=1e-13)[0]
    vs4 = 2.0 / S * ((1.0 - np.exp(-0.5)) / 0.5 + 1.0)
    for est, q1 in (("xi2", vs4), ("omega", vs4 + abs(Nn / S))):
        c = eg.constants(est)
        mu = q1 + 0.5
        assert c.mu == pytest.approx(mu, rel=1e-9)
        assert c.T_bar_max == pytest.approx(1.0 / mu, rel=1e-9)
        assert c.holds and c.T_bar == eg.T_BAR < c.T_bar_max
        assert c.rate == pytest.approx(np.log(eg.T_BAR * mu) / 1.1, rel=1e-9)
        assert c.a1 == pytest.approx(q1 * np.exp(-c.rate), rel=1e-9)       # Remark 4
    assert eg.constants("xi2").T_bar_max == pytest.approx(0.1292, abs=1e-4)
    assert eg.constants("omega").T_bar_max == pytest.approx(0.1118, abs=1e-4)


def test_the_companion_form_has_lipschitz_terms():
    """M = [[0, 1], [-1, -1]], N = [1 0] has the same A1, A2 but F1(y) = -y, F2(y) = k y
    (the module docstring): K1 = 1, K2 = k, and (40) then asks T_bar < 0.027."""
    from observers.gramian_delay.design import gramian_design, observer_form
    form = observer_form([[0.0, 1.0], [-1.0, -1.0]], [[1.0, 0.0]], None, P=[[0.0, 1.0]], k=0.5)
    assert form.A1.tolist() == [[-1.0]] and form.A2.tolist() == [[1.0]]
    assert [L.tolist() for L in form._linear] == [[[-1.0]], [[0.5]]]
    d = gramian_design(form.A1, form.A2, 0.5, 1.0)
    assert theorem2_constants(d, 1.0, 0.5, 0.1, estimate="xi2").T_bar_max == pytest.approx(
        0.0275, abs=1e-4)
    assert not theorem2_constants(d, 1.0, 0.5, eg.T_BAR, estimate="xi2").holds


def test_sequence_run_rows_sample_at_their_own_instants():
    """One population, three sequences: each row's jumps are its own instants, and a
    row agrees with a direct run of the same sequence (LSODA, the Python path)."""
    rng = np.random.default_rng(1)
    seqs = [np.full(90, eg.T_LOW), np.full(45, eg.T_BAR), rng.uniform(eg.T_LOW, eg.T_BAR, 90)]
    chi0s = np.array([eg.CHI0, [1.0, 0.0], [0.0, 1.0]])
    arcs, obs = eg.sequence_run("xi2", seqs, chi0s, t_max=T4)
    for g, a in zip(seqs, arcs):
        ts = np.concatenate([[0.0], np.cumsum(g)])
        np.testing.assert_allclose(a.jump_times, ts[ts <= T4], atol=1e-12)
    g, chi0 = seqs[2], chi0s[2]
    direct = eg.observer("xi2", instants=np.concatenate([[0.0], np.cumsum(g)]))
    ref = simulate(direct, chi0, None, t_max=T4)
    e_pop, e_ref = errors(arcs[2], obs), errors(ref, direct)
    for s in (1.0, 2.0, 3.2, 3.9):
        # plant and observer states; the last entry is the sample counter kappa
        np.testing.assert_allclose(arcs[2].at(s)[:-1], ref.at(s)[:-1], atol=1e-7)
    # the errors of (13) at the samples' instants, stored by both runs
    a, b = (E.norm()[arc.is_jump_end] for E, arc in ((e_pop, arcs[2]), (e_ref, ref)))
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=3e-7)     # the states agree to ~1e-7
    with pytest.raises(ValueError, match="do not cover t_max"):
        eg.sequence_run("xi2", [np.full(3, eg.T_BAR)], chi0s[:1], t_max=T4)


def _brute_margin(arc, obs, c, floor):
    """(42)'s margin in decades by a double loop over the samples t and r."""
    E = errors(arc, obs)
    t, e = arc.t, E.norm()
    w = np.abs(E["w_tilde"]).max(axis=1)
    tau, width = obs.design.tau, 2 * obs.design.tau + c.T_bar
    worst = np.inf
    for i in np.flatnonzero((t >= tau + width) & (e > floor)):
        B = min(c.a1 * w[(t >= t[r] - width) & (t <= t[r])].max() * np.exp(c.rate * (t[i] - t[r]))
                for r in np.flatnonzero((t >= width) & (t <= t[i] - tau)))
        worst = min(worst, np.log10(B / e[i]))
    return worst


@pytest.mark.parametrize("est", ["xi2", "omega"])
def test_margin42_against_a_double_loop_and_catches_a_violation(est):
    g = np.random.default_rng(2).uniform(eg.T_LOW, eg.T_BAR, 90)
    arcs, obs = eg.sequence_run(est, [g], eg.CHI0[None, :], t_max=T4)
    c = eg.constants(est)
    m = eg.margin42(arcs[0], obs, c)
    assert float(m) == pytest.approx(_brute_margin(arcs[0], obs, c, eg.FLOOR), abs=1e-12)
    assert m > 3 and 3.1 <= m.where[0] <= T4             # (42) holds, with decades to spare
    low = dataclasses.replace(c, a1=c.a1 * 10.0 ** (-float(m) - 1))    # a bound 10x too low
    bad = eg.margin42(arcs[0], obs, low)
    assert float(bad) == pytest.approx(-1.0, abs=1e-9) and not bad.holds
    over = theorem2_constants(obs.design, 0.0, 0.0, 2 * c.T_bar_max, estimate=est)
    with pytest.raises(ValueError, match=r"\(40\) fails"):
        eg.margin42(arcs[0], obs, over)


def test_explored_prefixes_are_every_sequence_and_match_a_direct_run():
    """explore_samples on 4 samples: the 2^3 sequences of {T_low, T_bar}, each leaf the
    run of its own sequence."""
    obs = eg.observer("xi2", gaps=(eg.T_LOW, eg.T_BAR))
    tree = explore_samples(obs, eg.CHI0, samples=4, dwell_grid=(), t_max=T4)
    assert tree.complete and len(tree) == 8
    got = sorted(tuple(np.round(np.diff(a.jump_times), 12)) for a in tree)
    assert got == sorted(itertools.product((eg.T_LOW, eg.T_BAR), repeat=3))
    leaf = max(tree, key=lambda a: a.t[-1])
    ref = simulate(eg.observer("xi2", instants=leaf.jump_times), eg.CHI0, None,
                   t_max=leaf.t[-1], j_max=4)
    assert ref.termination in (hs.Termination.J_MAX, hs.Termination.T_MAX)
    np.testing.assert_allclose(ref.x[-1], leaf.x[-1], atol=1e-8)


@pytest.mark.slow
@pytest.mark.parametrize("est", ["xi2", "omega"])
def test_claims_figures(est):
    """The claims' data (and the omega reading's): 32 solutions, margins >= 0, the search
    beside its baseline."""
    td = eg.tree_data(est)
    assert td["count"] == 2 ** (eg.PREFIX - 1) and len(td["margins"]) == td["count"]
    assert td["margin"] == min(td["margins"]) > 0
    sd = eg.search_data(est)
    for r in sd.values():
        assert r.evaluations == eg.BUDGET and r.margin > 0 and not r.findings
    assert "random sampling" in sd["random"].found_by
