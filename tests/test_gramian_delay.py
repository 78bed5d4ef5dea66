"""Tests of observers.gramian_delay (Mazenc & Malisoff, LCSYS 2022).

Design computations first (no engine), then the theorem checks on the engine.
"""
import numpy as np
import pytest
import scipy.linalg

from observers import gramian_delay as gd

# DC motor (65)-(67) parameters, "as in [6]"
a1, a2, a3, a4, b0, b1 = 35.0, 1.0, 36.4, 200.0, 40.0, 15.0
A1_DC = np.array([[-a2, b1], [-a3, -a4]])
A2_DC = np.array([[1.0, 0.0]])


def random_pair(seed, m, q=1):
    """A seeded random observable (A1, A2) with m = n - q unmeasured states."""
    rng = np.random.default_rng(seed)
    while True:
        A1 = rng.normal(size=(m, m))
        A2 = rng.normal(size=(q, m))
        O = np.vstack([A2 @ np.linalg.matrix_power(A1, i) for i in range(m)])
        if np.linalg.svd(O, compute_uv=False)[-1] > 0.1:
            return A1, A2


# ---------------------------------------------------------------------------
# Section II: coordinates
# ---------------------------------------------------------------------------
def dc_M_N():
    M = np.array([[0, 1, 0], [0, -a2, b1], [0, -a3, -a4]], dtype=float)
    N = np.array([[1.0, 0, 0]])
    return M, N


def test_observer_form_reproduces_67():
    M, N = dc_M_N()
    u = np.sin
    Psi = lambda y, t: np.array([0.0, -a1 * np.sin(y[0]), b0 * u(t)])  # noqa: E731
    P = np.array([[0, 1.0, 0], [0, 0, 1.0]])
    form = gd.observer_form(M, N, Psi, P=P, k=100.0)
    np.testing.assert_allclose(form.A1, A1_DC, atol=1e-12)
    np.testing.assert_allclose(form.A2, A2_DC, atol=1e-12)
    y, t = np.array([0.7]), 0.3
    np.testing.assert_allclose(form.F1(y, t), [-a1 * np.sin(0.7), b0 * np.sin(0.3)], atol=1e-12)
    np.testing.assert_allclose(form.F2(y, t), [100.0 * 0.7], atol=1e-12)   # F2(s) = k s
    chi = np.array([0.1, 0.2, 0.3])
    np.testing.assert_allclose(form.to_xi(chi), [0.2, 0.3, 0.1])
    np.testing.assert_allclose(form.to_chi(form.to_xi(chi)), chi)


@pytest.mark.parametrize("seed,n,q", [(0, 3, 1), (1, 4, 2), (2, 4, 1), (3, 5, 2)])
def test_observer_form_random_vector_field(seed, n, q):
    """T (M chi + Psi(N chi, t)) equals the right side of (2) at random points."""
    rng = np.random.default_rng(seed)
    M, N = rng.normal(size=(n, n)), rng.normal(size=(q, n))
    W = rng.normal(size=(n, q))
    Psi = lambda y, t: W @ np.tanh(y) * np.cos(t)  # noqa: E731
    form = gd.observer_form(M, N, Psi)
    m = n - q
    # default P: orthonormal rows orthogonal to N; default k: spectral radius + 1
    np.testing.assert_allclose(form.P @ N.T, 0, atol=1e-12)
    assert form.k == pytest.approx(np.max(np.abs(np.linalg.eigvals(form.A1))) + 1)
    assert np.linalg.matrix_rank(np.vstack([form.A2 @ np.linalg.matrix_power(form.A1, i)
                                            for i in range(m)])) == m
    for _ in range(3):
        chi, t = rng.normal(size=n), rng.normal()
        xi = form.to_xi(chi)
        lhs = form.T @ (M @ chi + Psi(N @ chi, t))
        x1, x2 = xi[:m], xi[m:]
        rhs = np.concatenate([form.A1 @ x1 + form.F1(x2, t),
                              form.A2 @ x1 - form.k * x2 + form.F2(x2, t)])
        np.testing.assert_allclose(lhs, rhs, rtol=1e-10, atol=1e-10)


def test_observer_form_bad_input():
    M, N = dc_M_N()
    with pytest.raises(ValueError, match="M must be square"):
        gd.observer_form(np.ones((3, 2)), N)
    with pytest.raises(ValueError, match=r"N must have shape \(\*, 3\), got \(1, 2\)"):
        gd.observer_form(M, [[1.0, 0.0]])
    with pytest.raises(ValueError, match="N must have full row rank 2"):
        gd.observer_form(M, [[1.0, 0, 0], [2.0, 0, 0]])
    with pytest.raises(ValueError, match="N must have between 1 and n-1"):
        gd.observer_form(M, np.eye(3))
    with pytest.raises(ValueError, match=r"\(M, N\) must be observable"):
        gd.observer_form(np.diag([1.0, 2.0, 3.0]), [[1.0, 0, 0]])
    with pytest.raises(ValueError, match="M must be finite"):
        gd.observer_form(M * np.nan, N)
    with pytest.raises(TypeError, match="Psi must be callable"):
        gd.observer_form(M, N, Psi=3)
    with pytest.raises(ValueError, match="P must complete N"):
        gd.observer_form(M, N, P=[[1.0, 0, 0], [0, 1.0, 0]])
    with pytest.raises(ValueError, match=r"P must have shape \(2, 3\)"):
        gd.observer_form(M, N, P=[[0, 1.0, 0]])
    with pytest.raises(ValueError, match="k must be finite and > 0"):
        gd.observer_form(M, N, k=-1.0)
    with pytest.raises(TypeError, match="k must be a real number"):
        gd.observer_form(M, N, k="1")
    # k^2 - 201 k + 746 = 0 makes A1 + kI singular (Section V)
    k_bad = (201 - np.sqrt(201**2 - 4 * 746)) / 2
    with pytest.raises(ValueError, match="k must make A1 \\+ k I invertible"):
        gd.observer_form(M, N, P=[[0, 1.0, 0], [0, 0, 1.0]], k=k_bad)


# ---------------------------------------------------------------------------
# lambda (4), S (5), N, R, H (6)
# ---------------------------------------------------------------------------
def test_lambda_properties_appendix():
    """lambda(0) = 0 and lambda^{(j)}(0) = -A2 (A1 + kI)^{j-1} (appendix)."""
    k = 100.0
    B = A1_DC + k * np.eye(2)
    np.testing.assert_allclose(gd.lam(0.0, A1_DC, A2_DC, k), 0, atol=1e-14)
    # analytic derivative: lambda'(r) = -A2 e^{B r}; check by central differences
    h = 1e-6
    d1 = (gd.lam(h, A1_DC, A2_DC, k) - gd.lam(-h, A1_DC, A2_DC, k)) / (2 * h)
    np.testing.assert_allclose(d1, -A2_DC, rtol=1e-6, atol=1e-8)
    h = 1e-4   # second derivative -A2 (A1 + kI); truncation error ~ h^2 |A2 B^3| / 12
    d2 = (gd.lam(h, A1_DC, A2_DC, k) + gd.lam(-h, A1_DC, A2_DC, k)) / h**2
    np.testing.assert_allclose(d2, -A2_DC @ B, rtol=1e-4)
    # identity after (23): lambda(s - t) = H^T Delta_*(t - s) e^{A1 (s - t)}
    d = gd.gramian_design(A1_DC, A2_DC, k, 0.1)
    for r in (-0.1, -0.03, 0.0):
        Dstar = scipy.linalg.expm(-A1_DC * r) - np.exp(k * r) * np.eye(2)
        np.testing.assert_allclose(d.lam(r), d.H.T @ Dstar @ scipy.linalg.expm(A1_DC * r),
                                   rtol=1e-9, atol=1e-12)
    assert gd.lam([-0.1, 0.0], A1_DC, A2_DC, k).shape == (2, 1, 2)
    np.testing.assert_allclose(d.H, np.linalg.inv(B).T @ A2_DC.T)


def test_scalar_gramian_closed_form():
    """m = q = 1: S = [tau - 2(1-e^{-b tau})/b + (1-e^{-2b tau})/(2b)] / b^2, b = a + k."""
    for a, k, tau in [(-1.0, 2.0, 0.5), (3.0, 0.5, 1.0), (0.2, 5.0, 0.05)]:
        b = a + k
        S = (tau - 2 * (1 - np.exp(-b * tau)) / b + (1 - np.exp(-2 * b * tau)) / (2 * b)) / b**2
        N = (tau - (1 - np.exp(-b * tau)) / b) / b
        for method in ("expm", "quad"):
            d = gd.gramian_design([[a]], [[1.0]], k, tau, method=method)
            assert d.S[0, 0] == pytest.approx(S, rel=1e-10)
            assert d.N[0, 0] == pytest.approx(N, rel=1e-10)
            assert d.R[0, 0] == pytest.approx(N / S, rel=1e-9)


@pytest.mark.parametrize("k", [75.0, 100.0, 150.0])
def test_dc_motor_S_expm_vs_quad(k):
    """S, N by Van Loan's augmented exponential vs adaptive quadrature.

    cond(S) ranges from ~1.5e2 (k = 150) to ~5.9e6 (k = 75); R = S^{-1} N then
    loses about log10(cond(S)) digits from S's rounding, hence rtol 1e-8 on R
    and 1e-11 on S and N (both computed to ~1e-13).
    """
    de = gd.gramian_design(A1_DC, A2_DC, k, 0.1)
    dq = gd.gramian_design(A1_DC, A2_DC, k, 0.1, method="quad")
    np.testing.assert_allclose(de.S, dq.S, rtol=1e-11, atol=1e-11 * np.abs(de.S).max())
    np.testing.assert_allclose(de.N, dq.N, rtol=1e-11)
    np.testing.assert_allclose(de.R, dq.R, rtol=1e-8)
    assert de.cond_S == pytest.approx(dq.cond_S, rel=1e-6)
    assert de.cond_S > 100                   # badly conditioned, as the issue warns
    np.testing.assert_allclose(de.S, de.S.T)
    assert np.all(np.linalg.eigvalsh(de.S) > 0)
    np.testing.assert_allclose(de.S @ de.R, de.N, rtol=1e-9, atol=1e-12 * np.abs(de.N).max())
    # N closed form: tau G^T - B^{-T} (I - e^{-B^T tau}) G^T, G = A2 B^{-1}
    B = A1_DC + k * np.eye(2)
    G = A2_DC @ np.linalg.inv(B)
    Ncf = 0.1 * G.T - np.linalg.solve(B.T, np.eye(2) - scipy.linalg.expm(-B.T * 0.1)) @ G.T
    np.testing.assert_allclose(de.N, Ncf, rtol=1e-10)


@pytest.mark.parametrize("seed,m,q", [(10, 1, 1), (11, 2, 1), (12, 3, 1), (13, 3, 2)])
def test_random_S_expm_vs_quad(seed, m, q):
    A1, A2 = random_pair(seed, m, q)
    k = np.max(np.abs(np.linalg.eigvals(A1))) + 1
    for tau in (0.3, 1.0):
        de = gd.gramian_design(A1, A2, k, tau)
        dq = gd.gramian_design(A1, A2, k, tau, method="quad")
        np.testing.assert_allclose(de.S, dq.S, rtol=1e-10, atol=1e-12 * np.abs(de.S).max())
        np.testing.assert_allclose(de.R, dq.R, rtol=1e-7 * max(1.0, de.cond_S / 1e3))


def test_gramian_design_bad_input():
    with pytest.raises(ValueError, match="tau must be finite and > 0"):
        gd.gramian_design(A1_DC, A2_DC, 100.0, 0.0)
    with pytest.raises(ValueError, match="method must be 'expm' or 'quad'"):
        gd.gramian_design(A1_DC, A2_DC, 100.0, 0.1, method="simpson")
    with pytest.raises(ValueError, match=r"A2 must have shape \(\*, 2\), got \(1, 3\)"):
        gd.gramian_design(A1_DC, [[1.0, 0, 0]], 100.0, 0.1)
    with pytest.raises(ValueError, match="A1 must be square"):
        gd.gramian_design(np.ones((2, 3)), A2_DC, 100.0, 0.1)
    with pytest.raises(ValueError, match=r"\(A1, A2\) must be observable"):
        gd.gramian_design(np.diag([1.0, 2.0]), [[1.0, 0.0]], 5.0, 0.1)
    with pytest.raises(ValueError, match="A1 must be 2-dimensional"):
        gd.gramian_design(np.ones((2, 2, 2)), A2_DC, 100.0, 0.1)
    with pytest.raises(ValueError, match="A2 must be finite"):
        gd.gramian_design(A1_DC, [[np.inf, 0.0]], 100.0, 0.1)
    with pytest.raises(ValueError, match="k must make A1 \\+ k I invertible"):
        gd.gramian_design([[-2.0]], [[1.0]], 2.0, 0.1)
    with pytest.raises(ValueError, match="S \\(5\\) is numerically singular"):
        # observable but with e^{(A1+kI) r} ~ 1 + O(1e-9): S ~ 1e-20
        gd.gramian_design([[-1.0]], [[1.0]], 1.0 + 1e-6, 1e-3)
    with pytest.raises(ValueError, match="r must be finite"):
        gd.lam(np.nan, A1_DC, A2_DC, 100.0)


# ---------------------------------------------------------------------------
# (11), (15), Theorem 2's constants, sampling instants
# ---------------------------------------------------------------------------
def test_theorem1_bound_scaling_and_errors():
    d = gd.gramian_design(A1_DC, A2_DC, 100.0, 0.1)
    assert gd.theorem1_bound(d, 0.5) == 0.0
    e1 = lambda t: np.array([np.sin(t), 1.0])  # noqa: E731
    d2 = lambda t: np.array([0.01 * np.cos(3 * t)])  # noqa: E731
    b = gd.theorem1_bound(d, 0.5, eps1=e1, delta2=d2, K1=a1, K2=100.0)
    b2 = gd.theorem1_bound(d, 0.5, eps1=lambda t: 2 * e1(t), delta2=lambda t: 2 * d2(t),
                           K1=a1, K2=100.0)
    assert b > 0 and b2 == pytest.approx(2 * b, rel=1e-12)         # positively homogeneous
    # constant eps1 = c: first term is c_Delta * c * int_0^tau |lambda(-r)| r dr
    c = 0.3
    b3 = gd.theorem1_bound(d, 0.5, eps1=lambda t: np.array([c, 0.0]), n_grid=4001)
    r = np.linspace(0, 0.1, 20001)
    ref = gd.c_Delta(d) * c * np.trapezoid([np.linalg.norm(d.lam(-ri), 2) * ri for ri in r], r)
    assert b3 == pytest.approx(ref, rel=1e-5)
    with pytest.raises(ValueError, match="t must be >= tau"):
        gd.theorem1_bound(d, 0.05)
    with pytest.raises(ValueError, match="n_grid must be an odd int"):
        gd.theorem1_bound(d, 0.5, n_grid=10)
    with pytest.raises(ValueError, match=r"eps1\(t\) must have shape \(2,\), got \(3,\)"):
        gd.theorem1_bound(d, 0.5, eps1=lambda t: np.zeros(3))
    with pytest.raises(TypeError, match="delta2 must be callable"):
        gd.theorem1_bound(d, 0.5, delta2=0.1)
    with pytest.raises(ValueError, match="K1 must be finite and >= 0"):
        gd.theorem1_bound(d, 0.5, K1=-1.0)


def test_theorem2_constants_relations():
    d = gd.gramian_design(A1_DC, A2_DC, 100.0, 0.1)
    cx = gd.theorem2_constants(d, a1, 100.0, 0.1, estimate="xi2")
    co = gd.theorem2_constants(d, a1, 100.0, 0.1, estimate="omega")
    # (41)
    assert cx.q1 == pytest.approx((cx.varsigma[0] + cx.varsigma[2]) * a1
                                  + cx.varsigma[1] * 100.0 + cx.varsigma[3], rel=1e-12)
    assert cx.mu == pytest.approx(cx.q1 + 100.0 + 100.0, rel=1e-12)        # |A2| = 1
    assert co.mu == pytest.approx(cx.mu + np.linalg.norm(d.R, 2), rel=1e-12)
    assert cx.T_bar_mu == pytest.approx(0.1 * cx.mu)
    assert cx.T_bar_max == pytest.approx(1 / cx.mu)
    # the paper's example violates (40) by ~20 orders of magnitude (reported, not hidden)
    assert not cx.holds and cx.rate > 0 and cx.T_bar_mu > 1e15
    assert np.all(cx.varsigma > 0)
    # (40) holds below 1/mu and the rate (43) is then negative; a1 of Remark 4
    c_ok = gd.theorem2_constants(d, a1, 100.0, 0.5 * cx.T_bar_max, estimate="xi2")
    assert c_ok.holds and c_ok.rate < 0
    assert c_ok.a1 == pytest.approx(c_ok.q1 * np.exp(-c_ok.rate * 0.1))
    # varsigma_2 by hand for a scalar case: (1/k) S_bar int |lambda(s)| (1 - e^{ks}) ds
    ds = gd.gramian_design([[-1.0]], [[1.0]], 3.0, 0.5)
    s = np.linspace(-0.5, 0, 200001)
    lam_s = (1 - np.exp(2.0 * s)) / 2.0
    v2 = ds.S_bar / 3.0 * np.trapezoid(np.abs(lam_s) * (1 - np.exp(3.0 * s)), s)
    assert gd.theorem2_constants(ds, 0.0, 0.0, 0.01).varsigma[1] == pytest.approx(v2, rel=1e-8)
    with pytest.raises(ValueError, match="estimate must be 'omega' or 'xi2'"):
        gd.theorem2_constants(d, a1, 100.0, 0.1, estimate="Y")
    with pytest.raises(ValueError, match="T_bar must be finite and > 0"):
        gd.theorem2_constants(d, a1, 100.0, 0.0)


def test_sampling_instants():
    ts = gd.sampling_instants(0.01, 0.03, 1.0, seed=4)
    h = np.diff(ts)
    assert ts[0] == 0.0 and ts[-1] >= 1.0 and ts[-2] < 1.0
    assert np.all(h >= 0.01) and np.all(h <= 0.03) and h.std() > 0
    np.testing.assert_array_equal(ts, gd.sampling_instants(0.01, 0.03, 1.0, seed=4))
    np.testing.assert_allclose(np.diff(gd.sampling_instants(0.1, 0.1, 0.5)), 0.1)
    with pytest.raises(ValueError, match="T_max must be >= T_min"):
        gd.sampling_instants(0.1, 0.05, 1.0)
    with pytest.raises(ValueError, match="T_min must be finite and > 0"):
        gd.sampling_instants(0.0, 0.05, 1.0)
    with pytest.raises(ValueError, match="t_end must be finite and >= t0"):
        gd.sampling_instants(0.1, 0.2, -1.0)
