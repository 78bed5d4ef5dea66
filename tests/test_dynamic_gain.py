"""Tests of observers.dynamic_gain (paper 000, Nekhoroshikh et al., CDC 2022).

Design computations first (no integrator), then theorem checks through hs.simulate.
"""

import numpy as np
import pytest

from observers import dynamic_gain as dg
from observers.dynamic_gain import (EXAMPLE, DynamicGainObserver, homogeneous_norm,
                                    prescribed_error, prescribed_v, settling_time,
                                    settling_time_bound, weights)
from observers.lmi import lmi10_matrices

L_PAPER = EXAMPLE["L"]
E0 = np.array([0.0, 10.0, 0.0, -5.0])          # (w(0), x(0) - x_hat(0)) of Section VI


@pytest.fixture(scope="module")
def P_paper():
    """Least-conditioned P of (10) for the paper's L (one SDP bisection per module)."""
    from observers.lmi import check_gain_lmi10
    return check_gain_lmi10(L_PAPER, 0.2, 1.0)["P"]


# ---------------------------------------------------------------- design computations
def test_settling_time_18_and_not_section_vi_formula():
    assert settling_time(1.0, 0.2, 1.0) == pytest.approx(5.0)
    # v(0) != 1: (18) gives v0^mu/(mu gamma1), Section VI's v0/(mu gamma1) would give 10
    T = settling_time(2.0, 0.2, 1.0)
    assert T == pytest.approx(2 ** 0.2 / 0.2)
    assert abs(T - 2.0 / 0.2) > 4
    # the closed-form gain of Remark 1 vanishes exactly at T and not before
    assert prescribed_v(T, 2.0, 0.2, 1.0) == 0.0
    assert prescribed_v(T * (1 - 1e-9), 2.0, 0.2, 1.0) > 0.0


def test_prescribed_error_solves_error_system():
    """The closed form e(t) = D_r(v) expm(M tau) D_r(v0)^-1 e0 satisfies (9) with
    gamma2 = 0: checked by central differences (step 1e-6, truncation ~1e-10)."""
    mu, g1, v0 = 0.2, 1.0, 1.7
    A, C, H = lmi10_matrices(3, mu)
    T = settling_time(v0, mu, g1)
    rbar = dg.rbar(3, mu)
    for t in [0.3, 1.1, 2.9, 0.9 * T]:
        h = 1e-6
        e = prescribed_error([t], E0, v0, L_PAPER, mu, g1)[0]
        de = (prescribed_error([t + h], E0, v0, L_PAPER, mu, g1)[0]
              - prescribed_error([t - h], E0, v0, L_PAPER, mu, g1)[0]) / (2 * h)
        v = prescribed_v(t, v0, mu, g1)
        rhs = A @ e + v ** (-rbar) * L_PAPER * e[0]
        assert np.allclose(de, rhs, rtol=1e-5, atol=1e-6)
    assert np.allclose(prescribed_error([0.0], E0, v0, L_PAPER, mu, g1)[0], E0)
    E = prescribed_error([T, T + 1.0], E0, v0, L_PAPER, mu, g1)
    assert np.all(E == 0.0)
    # not before T: invertible maps of e0 != 0
    Eb = prescribed_error(np.linspace(0, T * (1 - 1e-6), 50), E0, v0, L_PAPER, mu, g1)
    assert np.all(np.linalg.norm(Eb, axis=1) > 0)


def test_bound_17_limits_and_ordering(P_paper):
    """(17) -> (18) as gamma2 -> 0 (paper, end of Section IV); the corrected beta
    (decay e^{-tau/2}) gives a larger bound than the printed one."""
    T18 = settling_time(1.0, 0.2, 1.0)
    b0 = settling_time_bound(E0, 1.0, L_PAPER, 0.2, 1.0, 0.0, P=P_paper)
    assert b0 == pytest.approx(T18)
    prev = T18
    for g2 in [1e-6, 1e-3, 1e-1, 1.0]:
        lc = settling_time_bound(E0, 1.0, L_PAPER, 0.2, 1.0, g2, P=P_paper, log=True)
        lp = settling_time_bound(E0, 1.0, L_PAPER, 0.2, 1.0, g2, P=P_paper, corrected=False,
                                 log=True)
        assert lc >= lp >= np.log(prev) - 1e-12
        prev = np.exp(lp)
    # the example's bound is valid but enormous: > e^700 corrected, ~1.9e155 printed
    assert settling_time_bound(E0, 1.0, L_PAPER, 0.2, 1.0, 1.0, P=P_paper) == np.inf
    assert 1e150 < settling_time_bound(E0, 1.0, L_PAPER, 0.2, 1.0, 1.0, P=P_paper,
                                       corrected=False) < 1e160


def test_bound_17_bad_inputs():
    with pytest.raises(ValueError, match=r"v0 must exceed gamma2 \|w\(0\)\| = 2"):
        settling_time_bound(np.r_[2.0, 0, 0, 0], 1.0, L_PAPER, 0.2, 1.0, 1.0)
    with pytest.raises(ValueError, match=r"mu must lie in \(0, 0.25\) for n = 3, got 0.25"):
        settling_time_bound(E0, 1.0, L_PAPER, 0.25, 1.0, 1.0)      # Theorem 3: open
    with pytest.raises(ValueError, match=r"e0 must have shape \(4,\), got \(3,\)"):
        settling_time_bound(E0[:3], 1.0, L_PAPER, 0.2, 1.0, 1.0)
    with pytest.raises(ValueError, match="L does not satisfy LMIs"):
        settling_time_bound(E0, 1.0, -np.array([1.0, 1e-3, 1e-3, 1e-3]), 0.2, 1.0, 1.0)
    with pytest.raises(ValueError, match="strictly negative"):
        settling_time_bound(E0, 1.0, -L_PAPER, 0.2, 1.0, 1.0)
    with pytest.raises(ValueError, match="gamma1 must be > 0, got 0"):
        settling_time(1.0, 0.2, 0.0)
    with pytest.raises(ValueError, match=r"mu must lie in \(0, 1\)"):
        settling_time(1.0, 1.5, 1.0)


def test_homogeneous_norm_is_r_homogeneous_of_degree_one():
    rng = np.random.default_rng(0)
    e, v = rng.normal(size=4), 0.7
    r = weights(3, 0.2)
    for lam in [0.01, 0.5, 3.0]:
        assert homogeneous_norm(lam ** r * e, lam * v, 0.2) == pytest.approx(
            lam * homogeneous_norm(e, v, 0.2))
    # vectorised over time-major samples
    assert homogeneous_norm(np.vstack([e, e]), [v, v], 0.2).shape == (2,)


def _error_field(obs, e, v):
    """Vector field of (9) read off the observer's flow map with x = 0, u = 0
    (then y = 0 and e = (w, -x_hat))."""
    n = obs.n
    x = np.concatenate([[e[0]], -e[1:], [v, 0.0]])
    dx = obs.flow_map(x, 0.0, 0, np.zeros(obs.input_dim))
    return np.concatenate([[dx[0]], -dx[1:n + 1]]), dx[n + 1]


@pytest.mark.parametrize("z_mode,g2", [("max", 1.0), ("max", 0.0), ("abs", 0.0)])
def test_observer_error_field_is_homogeneous_of_degree_minus_mu(z_mode, g2):
    """(4) with rho = -mu for the closed loop (9) (Section IV), checked on the
    implemented flow map at random points (floating-point tolerance)."""
    mu = 0.2
    obs = DynamicGainObserver(L_PAPER, mu, 1.0, g2, z_mode=z_mode, z_min=1e-30)
    r = weights(3, mu)
    rng = np.random.default_rng(1)
    for _ in range(5):
        e, v = rng.normal(size=4), abs(rng.normal()) + 0.1
        fe, fv = _error_field(obs, e, v)
        for lam in [0.1, 7.0]:
            ge, gv = _error_field(obs, lam ** r * e, lam * v)
            assert np.allclose(ge, lam ** -mu * lam ** r * fe, rtol=1e-10, atol=1e-12)
            assert gv == pytest.approx(lam ** -mu * lam * fv, rel=1e-10, abs=1e-12)


def test_observer_bad_inputs():
    with pytest.raises(ValueError, match=r"L must be a vector .* got shape \(2, 2\)"):
        DynamicGainObserver(np.eye(2), 0.2, 1.0)
    with pytest.raises(ValueError, match="strictly negative"):
        DynamicGainObserver([-1.0, 2.0], 0.2, 1.0)
    with pytest.raises(ValueError, match=r"mu must lie in \(0, 0.25\] for n = 3, got 0.3"):
        DynamicGainObserver(L_PAPER, 0.3, 1.0)
    DynamicGainObserver(L_PAPER, 0.25, 1.0)          # Section IV allows mu = 1/(n+1)
    with pytest.raises(ValueError, match="gamma2 must be >= 0, got -1"):
        DynamicGainObserver(L_PAPER, 0.2, 1.0, -1.0)
    with pytest.raises(TypeError, match="gamma1 must be a real number, got str"):
        DynamicGainObserver(L_PAPER, 0.2, "a")
    with pytest.raises(ValueError, match="z_mode must be 'max' or 'abs', got 'min'"):
        DynamicGainObserver(L_PAPER, 0.2, 1.0, z_mode="min")
    with pytest.raises(ValueError, match=r"b must be a finite \(3, m\) matrix, got shape \(2, 1\)"):
        DynamicGainObserver(L_PAPER, 0.2, 1.0, b=np.ones((2, 1)))
    obs = DynamicGainObserver(L_PAPER, 0.2, 1.0)
    with pytest.raises(ValueError, match=r"x_hat0 must have shape \(3,\), got \(2,\)"):
        obs.initial_state(np.zeros(2))
    with pytest.raises(ValueError, match="v0 must be > z_min"):
        obs.initial_state(v0=0.0)
