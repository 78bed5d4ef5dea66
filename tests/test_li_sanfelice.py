"""Tests of observers.li_sanfelice: design computations and theorem checks (Li & Sanfelice).

Tolerances. Every "exact" claim of the paper (error 0 after a jump) is checked
against a tolerance set by the integrator, not by the theorem: the runs use
DOP853 with rtol = 1e-10, atol = 1e-12, so the pre-jump states carry errors of
order 1e-10 relative to the state's size, and the jump multiplies them by up
to |K1| + |K2| (and, for H_c / H_pc, by |T| |(H T - I)^{-1}|). Hence
``_tol(design)`` = 1e-8 * (1 + |K1| + |K2|) * (1 + |T| |(HT - I)^{-1}|) * scale.
"""
import math

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

from observers import li_sanfelice as ls

SEEDS = [0, 1, 2]
SHAPES = [(1, 1), (2, 1), (3, 1), (3, 2), (4, 2), (2, 2)]


def _tol(d, scale=1.0, noise_comp=False):
    # integrator-limited: 1e-8 relative, amplified by the reset gains (see module docstring)
    amp = 1 + np.linalg.norm(d.K1, 2) + np.linalg.norm(d.K2, 2)
    if noise_comp:
        amp *= 1 + np.linalg.norm(d.T, 2) * d.HT_inv_norm
    return 1e-8 * amp * max(1.0, scale)


def _examples():
    return {"III": ls.example_III(), "VA": ls.example_VA(), "VB": ls.example_VB(),
            "VB_rounded": ls.example_VB(rounded=True)}


def _random_cases():
    return [ls.random_design(s, n, p) for s in SEEDS[:2] for (n, p) in SHAPES]


# ---------------------------------------------------------------------------
# design computations
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("d", list(_examples().values()) + _random_cases())
def test_K_gains_reset_equal_errors_to_zero(d):
    # (12): K1 + K2 = I (x passes) and K1 e^{F1 delta} + K2 e^{F2 delta} = 0 (equal errors cancel)
    I = np.eye(d.n)
    assert np.allclose(d.K1 + d.K2, I, atol=1e-12)
    Z = d.K1 @ scipy.linalg.expm(d.F1 * d.delta) + d.K2 @ scipy.linalg.expm(d.F2 * d.delta)
    assert np.linalg.norm(Z) <= 1e-11 * (1 + np.linalg.norm(d.K2))
    K1, K2 = ls.gains_K(d.A, d.H, d.L1, d.L2, d.delta)
    assert np.allclose(K1, d.K1) and np.allclose(K2, d.K2)


@pytest.mark.parametrize("a,L1,L2", [(-0.05, 0.01, 0.02), (-0.05, 0.1, 0.2), (0.3, 1.0, 2.5)])
def test_formula_6_equals_formula_15_scalar(a, L1, L2):
    # (6) is (15) for the scalar plant (5) under a constant bias m
    m = 0.2
    for delta in [0.1, 0.5, 1.0, 2.0, 3.0, 10.0]:
        d = ls.Design(A=[[a]], H=[[1.0]], L1=[[L1]], L2=[[L2]], delta=delta)
        e6 = ls.scalar_error_after_jump(a, L1, L2, delta, m)
        e15 = ls.error_after_jump(d, [m])[0]
        e15q = ls.error_after_jump(d, lambda s: [m])[0]
        assert e6 == pytest.approx(e15, rel=1e-9)
        assert e15q == pytest.approx(e15, rel=1e-8)


def test_fig1a_tradeoff_error_decreases_with_delta():
    # Section III's claim behind Fig. 1(a): the sooner the jump, the larger the error after it
    deltas = np.linspace(0.5, 60, 200)
    e = np.abs(ls.scalar_error_after_jump(-0.05, 0.01, 0.02, deltas, 0.2))
    assert np.all(np.diff(e) < 0)


@pytest.mark.parametrize("n,p", [(2, 1), (3, 2), (4, 2)])
def test_footnote7_Xi_and_L_tilde(n, p):
    rng = np.random.default_rng(n + 10 * p)
    F = rng.normal(size=(n, n)) - 3 * np.eye(n)
    L = rng.normal(size=(n, p))
    # L_tilde stacks the columns; Xi_matrix puts the k-th n-piece in column k
    Lt = ls.L_tilde(L)
    assert np.array_equal(ls.Xi_matrix(Lt, n, p), L)
    # Xi(t) = int_0^t e^{F(t-s)} ds L, checked by quadrature
    t = 0.7
    ref, _ = scipy.integrate.quad_vec(lambda s: scipy.linalg.expm(F * (t - s)) @ L, 0, t, epsabs=1e-13)
    X = ls.Xi_of_t(F, L, t)
    assert np.allclose(X, ref, atol=1e-11)
    # and it solves the xi flow of (17) piecewise: d/dt Xi = F Xi + L
    h = 1e-6
    dX = (ls.Xi_of_t(F, L, t + h) - ls.Xi_of_t(F, L, t - h)) / (2 * h)
    assert np.allclose(dX, F @ X + L, atol=1e-7)


def test_example_VB_printed_gains_are_rounded_exact_ones():
    # decision 4: printed L1, L2 are 5 H^{-1}, 8 H^{-1} rounded to two decimals
    d, dr = ls.example_VB(), ls.example_VB(rounded=True)
    assert np.max(np.abs(dr.L1 - d.L1)) <= 0.005 and np.max(np.abs(dr.L2 - d.L2)) <= 0.005
    assert np.allclose(d.F1, d.A - 5 * np.eye(2)) and np.allclose(d.F2, d.A - 8 * np.eye(2))
    for des in (d, dr):
        assert ls.lemma_4_2_condition(des.A, des.H, des.L1, des.L2)
        assert ls.admissible_delta(des.A, des.H, des.L1, des.L2, t_max=5.0, num=300) is None
        assert des.HT_cond < 20


def test_admissible_delta_touching_zero_rotation():
    # F1 = -I + th J, F2 = -I - th J: e^{F2 t} e^{-F1 t} = rotation by 2 th t; p(t) = 2 - 2 cos(2 th t) >= 0,
    # a double zero at t = pi / th
    th = 2.0
    J = np.array([[0.0, 1.0], [-1.0, 0.0]])
    A, H = np.zeros((2, 2)), np.eye(2)
    L1, L2 = A - (-np.eye(2) + th * J), A - (-np.eye(2) - th * J)
    tz = ls.admissible_delta(A, H, L1, L2, t_max=5.0, num=500)
    assert tz == pytest.approx(math.pi / th, abs=1e-9)
    with pytest.raises(ValueError, match="K2 is undefined"):
        ls.gains_K(A, H, L1, L2, math.pi / th)
    ls.gains_K(A, H, L1, L2, 0.9 * tz)
    # a faster F2 removes the zero
    L2b = A - (-2 * np.eye(2) - th * J)
    assert ls.admissible_delta(A, H, L1, L2b, t_max=5.0, num=500) is None


def test_admissible_delta_sign_change_random():
    rng = np.random.default_rng(0)
    A, H = np.zeros((2, 2)), np.eye(2)
    found = 0
    for _ in range(60):
        F1 = rng.normal(size=(2, 2)) - 2 * np.eye(2)
        F2 = rng.normal(size=(2, 2)) - 2 * np.eye(2)
        if ls.alpha_max(F1) >= 0 or ls.alpha_max(F2) >= 0:
            continue
        tz = ls.admissible_delta(A, H, -F1, -F2, t_max=5.0, num=300)
        if tz is None:
            continue
        found += 1
        # p(t*) = 0 and p keeps one sign on (0, t*)
        scale = np.linalg.norm(scipy.linalg.expm(F2 * tz) @ scipy.linalg.expm(-F1 * tz), 2) ** 2
        assert abs(ls.p_det(F1, F2, tz)) <= 1e-9 * max(1.0, scale)
        ts = np.linspace(tz / 300, tz * (1 - 1e-6), 300)
        pv = ls.p_det(F1, F2, ts)
        assert np.all(pv > 0) or np.all(pv < 0)
        if found == 2:
            break
    assert found >= 1


def test_lemma_4_2_condition_false_when_spectra_interlace():
    A, H = np.zeros((1, 1)), np.eye(1)
    assert not ls.lemma_4_2_condition(A, H, [[2.0]], [[1.0]])   # alpha(F2) = -1 > alpha(F1) = -2
    assert ls.lemma_4_2_condition(A, H, [[1.0]], [[2.0]])


def test_HT_conditioning_reported():
    d = ls.example_VA()
    # scalar: cond is always 1; the amplification of the m̂ update is 1/|T - 1|
    assert d.HT_cond == pytest.approx(1.0)
    assert d.HT_inv_norm == pytest.approx(1 / abs(d.T[0, 0] - 1.0))
    cond, inv = ls.example_VB().check_HT_invertible()
    assert cond >= 1 and inv > 0


# ---------------------------------------------------------------------------
# bounds: Theorem 4.10 (formula) and the sqrt(3) decision for Theorem 4.7
# ---------------------------------------------------------------------------
def _bound_designs():
    return [ls.example_III(), ls.example_VA(), ls.example_VA(delta=1.0), ls.example_VA(delta=3.0),
            ls.example_VB(), ls.example_VB(rounded=True)] + \
        [ls.random_design(s, n, n, normal=True) for s in SEEDS for n in (1, 2)]


@pytest.mark.parametrize("d", _bound_designs())
def test_theorem_4_10_bound_on_formula_15(d):
    rng = np.random.default_rng(7)
    b = ls.theorem_4_10_bound(d, 1.0)
    for _ in range(20):   # constant noise on the unit sphere
        m = rng.normal(size=d.p)
        m /= np.linalg.norm(m)
        assert np.linalg.norm(ls.error_after_jump(d, m)) <= b
    # a time-varying noise with |m|_inf <= 1
    w = rng.uniform(0.5, 5, size=d.p)
    mfun = lambda s: np.cos(w * s) / math.sqrt(d.p)  # noqa: E731
    assert np.linalg.norm(ls.error_after_jump(d, mfun)) <= b


def test_theorem_4_10_hypotheses_need_full_rank_H():
    d = ls.random_design(0, 3, 1)
    with pytest.raises(ValueError, match=r"Theorem 4.10 needs .*rank H < n"):
        ls.theorem_4_10_bound(d, 1.0)
    with pytest.raises(ValueError, match=r"Theorem 4.11 needs"):
        ls.theorem_4_11_bound(d, 1.0, 0.1, 0.1, 0.5, 0)


def test_theorem_4_7_needs_sqrt3_for_rotating_errors():
    # decision 9: F1 = -I + th J, F2 = -I - th J, P_i = I/2: errors rotate apart and
    # |z|_A reaches sqrt(3) times the paper's bound at th t = pi/2 (e1 = -e2)
    th = 1.0
    J = np.array([[0.0, 1.0], [-1.0, 0.0]])
    A, H = np.zeros((2, 2)), np.eye(2)
    F1, F2 = -np.eye(2) + th * J, -np.eye(2) - th * J
    d = ls.Design(A=A, H=H, L1=A - F1, L2=A - F2, delta=2.0)
    e0 = np.array([1.0, 0.0])
    x = np.zeros(2)
    z0 = ls.dist_to_A(x, e0, e0)
    t = math.pi / 2
    e1, e2 = scipy.linalg.expm(F1 * t) @ e0, scipy.linalg.expm(F2 * t) @ e0
    zt = ls.dist_to_A(x, e1, e2)
    P = np.eye(2) / 2
    b = ls.theorem_4_7_bound(d, z0, t, 0, P1=P, P2=P)
    assert zt > b / math.sqrt(3) * 1.5          # the bound without sqrt(3) fails
    assert zt <= b * (1 + 1e-12)                 # with it, it holds (here with equality)
    assert zt == pytest.approx(b, rel=1e-12)


# ---------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------
def test_bad_shapes_and_types():
    A, H = np.zeros((2, 2)), np.eye(2)
    with pytest.raises(ValueError, match=r"A must be square"):
        ls.Design(A=np.zeros((2, 3)), H=H, L1=H, L2=H, delta=1.0)
    with pytest.raises(ValueError, match=r"H must have shape \(p, 2\)"):
        ls.Design(A=A, H=np.eye(3), L1=H, L2=H, delta=1.0)
    with pytest.raises(ValueError, match=r"L1 must have shape \(2, 2\) \(n x p\), got \(2, 1\)"):
        ls.Design(A=A, H=H, L1=np.ones((2, 1)), L2=H, delta=1.0)
    with pytest.raises(ValueError, match=r"L2 must have shape \(2, 2\)"):
        ls.Design(A=A, H=H, L1=H, L2=np.ones((3, 2)), delta=1.0)
    with pytest.raises(ValueError, match=r"A must be 2-dimensional"):
        ls.Design(A=np.zeros((2, 2, 2)), H=H, L1=H, L2=H, delta=1.0)
    with pytest.raises(TypeError, match=r"A must be an array, got None"):
        ls.Design(A=None, H=H, L1=H, L2=H, delta=1.0)
    with pytest.raises(ValueError, match=r"H must be finite"):
        ls.Design(A=A, H=[[np.nan, 0], [0, 1]], L1=H, L2=H, delta=1.0)
    with pytest.raises(TypeError, match=r"delta must be a real number, got str"):
        ls.Design(A=A, H=H, L1=H, L2=2 * H, delta="1")
    with pytest.raises(ValueError, match=r"delta must be positive and finite, got -1.0"):
        ls.Design(A=A, H=H, L1=H, L2=2 * H, delta=-1.0)
    with pytest.raises(ValueError, match=r"a1 \+ a2 must equal 1"):
        ls.Design(A=A, H=H, L1=H, L2=2 * H, delta=1.0, a1=0.5, a2=0.6)
    with pytest.raises(TypeError, match=r"a1 must be a real number"):
        ls.Design(A=A, H=H, L1=H, L2=2 * H, delta=1.0, a1="x")
    with pytest.raises(ValueError, match=r"num must be an integer >= 3"):
        ls.admissible_delta(A, H, H, 2 * H, num=2)


def test_not_hurwitz_names_the_gain():
    A, H = np.zeros((2, 2)), np.eye(2)
    with pytest.raises(ValueError, match=r"F1 = A - L1 H is not Hurwitz"):
        ls.Design(A=A, H=H, L1=-H, L2=2 * H, delta=1.0)
    with pytest.raises(ValueError, match=r"F2 = A - L2 H is not Hurwitz"):
        ls.gains_K(A, H, H, 0 * H, 1.0)


def test_HT_singular_is_refused_before_a_run():
    # scalar plant, L1 = 3, L2 = 5, delta = 1, H = 1 and a found by brentq so that T(a) = 1: H T - I = 0
    import scipy.optimize
    L1, L2, delta, h = 3.0, 5.0, 1.0, 1.0

    def g(a):
        return ls.Design(A=[[a]], H=[[h]], L1=[[L1]], L2=[[L2]], delta=delta).T[0, 0] - 1.0

    assert g(-1.0) < 0 < g(2.0)
    a = scipy.optimize.brentq(g, -1.0, 2.0, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    d = ls.Design(A=[[a]], H=[[h]], L1=[[L1]], L2=[[L2]], delta=delta)
    with pytest.raises(ValueError, match=r"H T - I is singular"):
        d.check_HT_invertible()
    with pytest.raises(ValueError, match=r"H T - I is singular"):
        ls.ConstantNoiseObserver(d)
    with pytest.raises(ValueError, match=r"H T - I is singular"):
        ls.PiecewiseConstantNoiseObserver(d)
    ls.NominalObserver(d)   # H_n does not need it


def test_bad_noise_and_misc_input():
    with pytest.raises(ValueError, match=r"c must have len\(d\) \+ 1 = 3 rows"):
        ls.PiecewiseConstantNoise([1.0, 2.0], [[0.1], [0.2]])
    with pytest.raises(ValueError, match=r"d must be positive and strictly increasing"):
        ls.PiecewiseConstantNoise([2.0, 1.0], [[0.1], [0.2], [0.3]])
    with pytest.raises(ValueError, match=r"side must be 'right' or 'left'"):
        ls.PiecewiseConstantNoise([1.0], [[0.1], [0.2]], side="middle")
    d = ls.example_VB()
    with pytest.raises(ValueError, match=r"m must have shape \(2,\), got \(3,\)"):
        ls.error_after_jump(d, [0.1, 0.2, 0.3])
    with pytest.raises(TypeError, match=r"design must be a Design"):
        ls.error_after_jump("VB", [0.1, 0.2])
    with pytest.raises(ValueError, match=r"m_inf must be a nonnegative real"):
        ls.theorem_4_10_bound(d, -1.0)
    with pytest.raises(ValueError, match=r"j must be 0 or 1"):
        ls.theorem_4_11_bound(d, 1.0, 0.1, 0.1, 2.0, 2)
    with pytest.raises(ValueError, match=r"formula \(6\) needs"):
        ls.scalar_error_after_jump(0.0, 0.0, 0.1, 1.0, 0.2)
    with pytest.raises(TypeError, match=r"pass either a Design or"):
        ls.NominalObserver(d, d.H)
    with pytest.raises(TypeError, match=r"delta is required"):
        ls.NominalObserver(d.A, d.H, d.L1, d.L2)
    with pytest.raises(TypeError, match=r"observer must be one of this module's observers"):
        ls.simulate_with_plant(object(), [0, 0], [0, 0], t_max=1.0)
    with pytest.raises(ValueError, match=r"xhat0 must have shape \(2,\), got \(3,\)"):
        ls.simulate_with_plant(ls.NominalObserver(d), [0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match=r"L0 must have shape \(2, 2\)"):
        ls.LuenbergerObserver(d.A, d.H, np.ones((2, 1)))
    with pytest.raises(ValueError, match=r"noise must have shape \(2,\)"):
        ls.simulate_with_plant(ls.NominalObserver(d), [0, 0], [0, 0], noise=[0.1])
