"""Theorems 4.7, 4.9 and 4.11 of Li & Sanfelice as falsification problems.

Each :class:`observers.falsification.Problem` of :data:`PROBLEMS` searches a
space of hypotheses (designs, initial states in S_n, noise in its class) for
a run of H_n (10)-(12) with plant (1) that breaks a bound of the paper:

==============================  ==========================================  ==============
id                              statement                                   expected
==============================  ==========================================  ==============
002-thm4.7-printed-some-P       Thm 4.7 as printed, for some P (witness)    none
002-thm4.7-printed-fixed-P      Thm 4.7 printed, P_i = I/(2 k_i) fixed      counterexample
002-thm4.7-corrected            Thm 4.7 with sqrt(3 c2/c1), P fixed (d. 9)  none
002-thm4.9-pwc, -sin            Thm 4.9, distance <= C |m|_inf (dec. 12)    none
002-thm4.11-pwc, -sin           Thm 4.11, bound (16)                        none
==============================  ==========================================  ==============

The family searched
-------------------
Every run is one row of a population of
:class:`~observers.li_sanfelice.systems.RotatingFamily`: the plant
of Section V.B (A = J = [[0, 1], [-1, 0]], H = [[1, 2], [2, 1]]) with the
gains L_i = (A - F_i) H^{-1} that place

    F_i = A - L_i H = -k_i I + w_i J,    0 < k1 < k2,

and the jump period delta, all carried in the state so that a population
of designs is one vectorized batch. Example V.B is k1 = 5, k2 = 8,
w1 = w2 = 1, delta = 1 (:data:`VB_PARAMS`). The family meets every
hypothesis of the theorems searched: F_i Hurwitz (A1); e^{F2 t} e^{-F1 t}
= e^{-(k2 - k1) t} R((w2 - w1) t), R(theta) = e^{theta J} a rotation, has
norm < 1 for t > 0, so A2 holds for every delta (Lemma 4.2: alpha(F2) = -k2
< alpha(F1) = -k1 < 0); sym(F_i) = -k_i I, so F_i is dissipative with
mu_bar(F_i) = mu_(F_i) = -k_i and mu_bar(F2) < mu_(F1) (Theorems 4.10,
4.11; p = n = 2, decision 8). Everything the bounds need has a closed form
here: P_i = I / (2 k_i) solves F_i^T P_i + P_i F_i = -I, so c1 = 1/(2 k2),
c2 = 1/(2 k1), lambda_min(P) = 1 and Theorem 4.7's printed bound is
sqrt(k2/k1) |z(0,0)|_A e^{-k1 t}; K2 = (I - e^{-(k2-k1) delta}
R((w2 - w1) delta))^{-1}, K1 = I - K2 (12).

Why the printed Theorem 4.7 fails
---------------------------------
From S_n (x̂1 = x̂2, e_i(0) = e0) without noise, e_i(t) = e^{-k_i t}
R(w_i t) e0 and |z|_A^2 = (2/3)(|e1|^2 + |e2|^2 - e1 . e2), so

    |z(t, 0)|_A / (sqrt(k2/k1) |z(0, 0)|_A e^{-k1 t})
        = sqrt(k1/k2 (1 + s^2 - s cos((w1 - w2) t))),   s = e^{-(k2 - k1) t}

(:func:`thm47_ratio`). Copies that rotate apart (cos = -1) with close rates
(s near 1, k1/k2 near 1) reach sqrt(3) times the printed bound, never more
(1 + s + s^2 <= 3, k1 < k2): the printed constant is violated on an open
set of the family, the corrected one sqrt(3 c2/c1) (decision 9,
:func:`~observers.li_sanfelice.design.theorem_4_7_bound`) is not. The paper's
own examples never violate it: their copies rotate together (w1 = w2 for
V.B; n = 1 for III and V.A), where the ratio is at most sqrt(k1/k2) < 1.

Which P: the two readings
-------------------------
Theorem 4.7 prints its constants "for some P_1 = P_1^T > 0, P_2 = P_2^T > 0
such that P > 0": existential over P. Read so, the statement is
"there are P_i for which the bound holds on every solution", which a search
over solutions checks with a witness, not refutes run by run (a run that
violates one P's bound says nothing of another's). In the family it holds:
P* = (3 I, I) is admissible (-He(F_1, 3I) = 6 k1 I, -He(F_2, I) = 2 k2 I),
c1 = 1, c2 = 3, lambda_min(P*) = min(6 k1, 2 k2), so the bound is
sqrt(3) |z(0, 0)|_A e^{-min(k1, k2/3) t}, and |z(t, 0)|_A / |z(0, 0)|_A =
e^{-k1 t} sqrt(1 + s^2 - s cos((w1 - w2) t)) <= sqrt(3) e^{-k1 t}: problem
``002-thm4.7-printed-some-P`` searches for a solution above P*'s bound
(expected: none). In general too: any admissible P gives the Lyapunov bound
on |(e1, e2)|, sqrt(3) times too small for |z|_A, and (P_1, kappa P_2) with
kappa large trades that sqrt(3) for a slower rate. The erratum is in the
reading with P fixed, where the constants are those of the P one solved
for: ``002-thm4.7-printed-fixed-P`` takes P_i = I / (2 k_i), the solution of
F_i^T P_i + P_i F_i = -I (:func:`~observers.li_sanfelice.design.theorem_4_7_bound`), and
``002-thm4.7-corrected`` the same P with sqrt(3 c2/c1).

Noise
-----
The noise classes are :class:`hybridsim.falsification.PiecewiseConstant`
(8 pieces over the horizon) and :class:`hybridsim.falsification.Sinusoids`
(2 terms per component up to 2 Hz), each component |m_i| <= eps, so the
Euclidean |m(t)| <= sqrt(2) eps. The bounds are evaluated with the realized
sup norms |m|_delta (over [0, delta]) and |m|_inf (over the simulated
horizon: ē(t) depends on m over [0, t] only): exact for the piecewise
constant signals, a grid maximum plus the most |m| can grow between grid
points for the sinusoids (decision 13). The coefficients live in the state
too (constant during flows), so a population of noise realisations is one
batch, as with :class:`~observers.li_sanfelice.systems.BoundedNoiseGenerator`.

Examples
--------
>>> from observers.li_sanfelice.falsification import PROBLEMS, thm47_ratio
>>> [p.id for p in PROBLEMS][:3]
['002-thm4.7-printed-some-P', '002-thm4.7-printed-fixed-P', '002-thm4.7-corrected']
>>> round(thm47_ratio(1.0, 1.0, 1.0, -1.0, np.pi / 2), 6)    # copies rotating apart
1.732051
"""
from __future__ import annotations

import math

import numpy as np

from hybridsim.falsification import (
    Box,
    Interval,
    PiecewiseConstant,
    Sinusoids,
    Space,
    batch_run,
)
from hybridsim.testing import Margin, all_of
from observers.falsification import Problem

from .design import dist_to_A
from .systems import (
    _A,
    _C1,
    _C2,
    _DELTA,
    _F,
    _H,
    _HINV,
    _K1,
    _X,
    _XH1,
    _XH2,
    RotatingFamily,
)

__all__ = ["PROBLEMS", "VB_PARAMS", "thm47_ratio", "family_design"]

_ID = "002"
#: Example V.B in the family: (k1, k2, w1, w2, delta).
VB_PARAMS = (5.0, 8.0, 1.0, 1.0, 1.0)

#: Integration of every population (the batch integrator, RK45).
_SIM = dict(rtol=1e-8, atol=1e-11)
_T_END = 4.0                                    # horizon: twice the largest delta


def family_design(k1, k2, w1, w2, delta):
    """The :class:`~observers.li_sanfelice.design.Design` of one member of the family.

    Plant of Section V.B, L_i = (A - F_i) H^{-1} with F_i = -k_i I + w_i J;
    ``family_design(*VB_PARAMS)`` is example V.B (exact gains 5 H^-1, 8 H^-1).
    """
    from .design import Design
    L1 = (_A - _F(k1, w1)) @ _HINV
    L2 = (_A - _F(k2, w2)) @ _HINV
    return Design(A=_A, H=_H, L1=L1, L2=L2, delta=float(delta))


# -----------------------------------------------------------------------------
# closed forms of the family
# -----------------------------------------------------------------------------
def thm47_ratio(k1, k2, w1, w2, t):
    """|z(t, 0)|_A over Theorem 4.7's printed bound, in closed form (any z(0, 0) in S_n).

    sqrt(k1/k2 (1 + s^2 - s cos((w1 - w2) t))), s = e^{-(k2 - k1) t}: above 1
    is a counterexample to the printed statement; the corrected one allows
    sqrt(3) (:mod:`module docstring <observers.li_sanfelice.falsification>`).
    """
    s = np.exp(-(k2 - k1) * np.asarray(t, float))
    return np.sqrt(k1 / k2 * (1 + s * s - s * np.cos((w1 - w2) * np.asarray(t, float))))


def _coeffs(p):
    """(|L1|, |L2|, w1 of Thm 4.10, gamma1(1), gamma(1)) of the design p = (k1, k2, w1, w2, d)."""
    k1, k2, o1, o2, d = p
    n1 = np.linalg.norm((_A - _F(k1, o1)) @ _HINV, 2)
    n2 = np.linalg.norm((_A - _F(k2, o2)) @ _HINV, 2)
    w = 1.0 / (1.0 - math.exp((k1 - k2) * d))         # mu_bar(F2) - mu_(F1) = k1 - k2
    g1 = (1 + w) * n1 / k1 + w * n2 / k2              # Theorem 4.10 / gamma_1 of (16)
    g = max(n1 / k1, n2 / k2)                         # gamma of (16)
    return n1, n2, w, g1, g


# -----------------------------------------------------------------------------
# margins (arc -> float: positive holds, negative violated)
# -----------------------------------------------------------------------------
#: Theorem 4.7's bound C |z(0, 0)|_A e^{-r t} of a member (k1, k2): (C, r) by the P used.
_THM47_P = {
    "fixed": lambda k1, k2: (math.sqrt(k2 / k1), k1),                  # P_i = I / (2 k_i)
    "witness": lambda k1, k2: (math.sqrt(3.0), min(k1, k2 / 3.0)),      # P* = (3 I, I)
}


def _thm47_margin(factor, which="fixed"):
    """Theorem 4.7 on an arc: 1 - |z|_A / (factor C |z0|_A e^{-r t}) while j = 0, (C, r)
    those of P_i = I / (2 k_i) (``"fixed"``: sqrt(c2/c1) = sqrt(k2/k1), r = k1) or of the
    witness P* = (3 I, I) (``"witness"``: sqrt(3), min(k1, k2/3)),
    and exactness after the jump: 1 - |z|_A / tol, tol = 1e-7 (1 + |K1| + |K2|) (|x(0)| +
    |e(0)|). RK45 at rtol 1e-8 leaves |z|_A <= 1.5e-9 (1 + |K1| + |K2|) (|x(0)| + |e(0)|)
    after the jump on 400 random members of the family (the integration error scales
    with the state, the reset (12) amplifies it by at most 1 + |K1| + |K2|): 70 times
    below tol."""
    def margin(arc):
        X = arc.x
        p = X[0, _K1:_DELTA + 1]
        k1, k2 = p[0], p[1]
        z = dist_to_A(X[:, _X], X[:, _XH1], X[:, _XH2])
        z0 = float(z[0])
        pre = arc.j == 0
        C, rate = _THM47_P[which](k1, k2)
        bound = factor * C * z0 * np.exp(-rate * arc.t[pre])
        r = z[pre] / bound
        i = int(np.argmax(r))
        m_pre = Margin(1.0 - r[i], arc.t[pre][i], 0, "Thm 4.7, j = 0",
                       series=(arc.t[pre], arc.j[pre], 1.0 - r))
        post = arc.j >= 1
        if not post.any():
            return m_pre
        K1, K2 = RotatingFamily().gains(X[0])
        scale = np.linalg.norm(X[0, _X]) + np.linalg.norm(X[0, _XH1] - X[0, _X])
        tol = 1e-7 * (1 + np.linalg.norm(K1[0], 2) + np.linalg.norm(K2[0], 2)) * scale
        r1 = z[post] / tol
        i1 = int(np.argmax(r1))
        m = all_of(m_pre, Margin(1.0 - r1[i1], arc.t[post][i1], int(arc.j[post][i1]),
                                 "Thm 4.7, exact after the jump"))
        m.series = (arc.t, arc.j, np.concatenate([1.0 - r, 1.0 - r1]))   # pre, then post
        return m
    return margin


def _thm411_margin(system):
    """(16) on an arc, relative: 1 - max |ē(t, j)| / (16)(t, j) (a1 = a2 = 1/2)."""
    def margin(arc):
        X = arc.x
        x0 = X[0]
        p = x0[_K1:_DELTA + 1]
        k1, d = p[0], p[4]
        _, _, _, g1, g = _coeffs(p)
        m_delta, m_inf = system.sup_norms(x0, float(arc.t[-1]))
        ebar = (X[:, _XH1] + X[:, _XH2]) / 2 - X[:, _X]
        err = np.linalg.norm(ebar, axis=1)
        t, j = arc.t, np.minimum(arc.j, 1)
        bound = ((1 - j) * (err[0] * np.exp(-k1 * np.minimum(t, d)) + g1 * m_delta)
                 + j * (g1 * m_delta * np.exp(-k1 * np.maximum(t - d, 0.0)) + g * m_inf))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(bound > 0, err / bound, np.where(err > 0, np.inf, 0.0))
        i = int(np.argmax(r))
        return Margin(1.0 - r[i], t[i], int(arc.j[i]), "Thm 4.11, (16)")
    return margin


def _thm49_margin(system):
    """Theorem 4.9 with decision 12's constant, relative: 1 - max dist / (C |m|_inf),
    dist = |(x̂1, x̂2) - (x̂1, x̂2)_{m=0}| at equal (t, j), C = sqrt(2) (gamma1(1) + gamma(1))."""
    def margin(arc):
        X = arc.x
        _, _, _, g1, g = _coeffs(X[0, _K1:_DELTA + 1])
        _, m_inf = system.sup_norms(X[0], float(arc.t[-1]))
        dist = np.sqrt(np.sum((X[:, _XH1] - X[:, _C1]) ** 2 + (X[:, _XH2] - X[:, _C2]) ** 2,
                              axis=1))
        C = math.sqrt(2) * (g1 + g)
        if m_inf == 0.0:
            r = np.where(dist > 0, np.inf, 0.0)
        else:
            r = dist / (C * m_inf)
        i = int(np.argmax(r))
        return Margin(1.0 - r[i], arc.t[i], int(arc.j[i]), "Thm 4.9, dist <= C |m|_inf")
    return margin


# -----------------------------------------------------------------------------
# spaces and runs
# -----------------------------------------------------------------------------
def _design_entries():
    """The design family: k1 in [1, 5], k2 - k1 in [0.1, 3] (so k2 > k1, Lemma 4.2),
    w1, w2 in [-4, 4], delta in [0.5, 2] (every delta is admissible, A2); example
    V.B (5, 8, 1, 1, 1) is a point of it."""
    return dict(k1=Interval(1.0, 5.0), dk=Interval(0.1, 3.0), w1=Interval(-4.0, 4.0),
                w2=Interval(-4.0, 4.0), delta=Interval(0.5, 2.0))


def _state_entries(away_from_A=False):
    """z_m(0, 0) in S_n: x(0) within 1 of V.B's (0.3, 0.4), x̂1 = x̂2 = x(0) + e0 with e0 in
    [-1, 1]^2, or in [0.1, 1] x [-1, 1] when ``away_from_A`` (Theorem 4.7's bound is
    relative to |z(0, 0)|_A, which must not shrink to the integration error, rtol |x|;
    the family commutes with rotations, e^{F_i t} R = R e^{F_i t}, and its ratio to the
    bound does not depend on z(0, 0), so this loses no generality)."""
    e0 = Box([0.1, -1.0], [1.0, 1.0]) if away_from_A else Box.around([0.0, 0.0], 1.0)
    return dict(x0=Box.around([0.3, 0.4], 1.0), e0=e0)


def _params(pt):
    return (pt["k1"], pt["k1"] + pt["dk"], pt["w1"], pt["w2"], pt["delta"])


def _run(system):
    size = system.noise_size

    def x0_of(pt):
        noise = pt.z[pt.z.size - size:] if size else ()
        return system.state(pt["x0"], pt["x0"] + pt["e0"], _params(pt), noise)
    return batch_run(system, x0_of, t_max=system.t_end, **_SIM)


_EPS = 0.2                                     # |m_i| <= eps: the noise level of the claims
_NOISY = {
    "pwc": (lambda: PiecewiseConstant(_EPS, _T_END, pieces=8, dim=2),
            dict(pieces=8), "piecewise constant on 8 pieces of [0, 4]"),
    "sin": (lambda: Sinusoids(_EPS, bandwidth=2.0, terms=2, dim=2),
            dict(terms=2), "a sum of 2 sinusoids per component up to 2 Hz"),
}


def _thm47_problem(printed, some_P=False):
    system = RotatingFamily("none")
    space = Space(**_state_entries(away_from_A=True), **_design_entries())
    factor = 1.0 if printed else math.sqrt(3.0)
    if some_P:
        return Problem(
            id="002-thm4.7-printed-some-P", paper=_ID, where="Thm 4.7",
            statement="Theorem 4.7 as printed, in its reading: for some P_1, P_2 > 0 with "
                      "P > 0 every solution of H_n and plant (1) from S_n without noise has "
                      "|z(t, j)|_A <= (1 - j) sqrt(c2/c1) |z(0, 0)|_A exp(-lambda_min(P) t / "
                      "(2 c2)); checked with the witness P* = (3 I, I) (c2/c1 = 3, "
                      "lambda_min(P*) = min(6 k1, 2 k2)), over the designs F_i = -k_i I + w_i J "
                      "of V.B's plant (0 < k1 < k2, any delta) and z(0, 0) (margin: 1 - |z|_A / "
                      "P*'s bound while j = 0; after the jump |z|_A within the integration "
                      "tolerance).",
            space=space, run=_run(system), margin=_thm47_margin(1.0, "witness"),
            budget=2000, expect="none",
            reason="existential over P, the statement is true: P*'s bound sqrt(3) |z0|_A "
                   "e^{-min(k1, k2/3) t} covers |z|_A <= sqrt(3) |z0|_A e^{-k1 t} (module "
                   "docstring); the erratum is in the reading with P fixed "
                   "(002-thm4.7-printed-fixed-P)")
    which = ("as printed with P fixed (P_i = I/(2 k_i)), sqrt(c2/c1)" if printed
             else "corrected, sqrt(3 c2/c1) (decision 9), P fixed (P_i = I/(2 k_i))")
    reason = ("erratum (claim 002-thm4.7-constant): the Lyapunov argument bounds |(e1, e2)| "
              "and |z|_A <= |(e1, e2)| <= sqrt(3) |z|_A; copies rotating apart (w1 != w2) "
              "with close rates (k2/k1 < 3) exceed the printed bound by up to sqrt(3)"
              if printed else
              "the corrected constant covers |z|_A <= |(e1, e2)| <= sqrt(3) |z|_A; in the "
              "family the ratio to the printed bound is at most sqrt(k1/k2 (1 + s + s^2)) "
              "< sqrt(3) (k2 - k1 >= 0.1)")
    return Problem(
        id="002-thm4.7-" + ("printed-fixed-P" if printed else "corrected"), paper=_ID,
        where="Thm 4.7",
        statement=f"Theorem 4.7 {which}: every solution of H_n and plant (1) from S_n without "
                  "noise has |z(t, j)|_A <= (1 - j) C |z(0, 0)|_A exp(-lambda_min(P) t / (2 c2)), "
                  "P_i solving F_i^T P_i + P_i F_i = -I; searched over the designs "
                  "F_i = -k_i I + w_i J of V.B's plant (0 < k1 < k2, any delta) and z(0, 0) "
                  "(margin: 1 - |z|_A / bound while j = 0; after the jump |z|_A within the "
                  "integration tolerance, relative to |z(0, 0)|_A).",
        space=space, run=_run(system), margin=_thm47_margin(factor),
        budget=2000, expect="counterexample" if printed else "none", reason=reason)


def _thm411_problem(kind):
    make, kw, what = _NOISY[kind]
    system = RotatingFamily(kind, eps=_EPS, **kw)
    space = Space(**_state_entries(), **_design_entries(), m=make())
    return Problem(
        id=f"002-thm4.11-{kind}", paper=_ID, where="Thm 4.11, (16)",
        statement="Theorem 4.11: every solution of H_n and plant (1) from S_n under noise m, "
                  f"|m_i(t)| <= {_EPS} ({what}), satisfies (16) with beta(s, t) = s "
                  "exp(mu_bar(F1) t), gamma, gamma1 as printed; searched over the designs "
                  "F_i = -k_i I + w_i J of V.B's plant, z(0, 0) and m (margin: 1 - |ē| / (16), "
                  "with the realized |m|_delta and |m|_inf).",
        space=space, run=_run(system), margin=_thm411_margin(system), budget=2000,
        expect="none",
        reason="the family meets the hypotheses (dissipative F_i, mu_bar(F2) = -k2 < "
               "mu_(F1) = -k1, alpha likewise, p = n) and (16) follows from variation of "
               "constants: before the jump |ē| <= e^{-k1 t} |ē0| + gamma |m|_delta, gamma <= "
               "gamma1; after it |e(delta, 1)| <= gamma1 |m|_delta (Thm 4.10)")


def _thm49_problem(kind):
    make, kw, what = _NOISY[kind]
    system = RotatingFamily(kind, eps=_EPS, **kw)
    space = Space(**_state_entries(), **_design_entries(), m=make())
    return Problem(
        id=f"002-thm4.9-{kind}", paper=_ID, where="Thm 4.9",
        statement="Theorem 4.9 with the constant of decision 12: the solutions of H_n and plant "
                  f"(1) from the same z_m(0, 0) in S_n with noise |m_i| <= {_EPS} ({what}) and "
                  "with m = 0 stay within C |m|_inf at equal (t, j), C = sqrt(2) (gamma1(1) + "
                  "gamma(1)), so sigma* = eps / C gives (T, J, eps)-closeness; searched over "
                  "the designs F_i = -k_i I + w_i J of V.B's plant, z(0, 0) and m (margin: "
                  "1 - distance / (C |m|_inf)).",
        space=space, run=_run(system), margin=_thm49_margin(system), budget=2000,
        expect="none",
        reason="H_n is linear in m, so the distance is the response of each copy to m alone "
               "from zero: at most gamma |m|_inf before the jump and (gamma1 + gamma) |m|_inf "
               "after it (Thm 4.10 and variation of constants, decision 12)")


#: The problems of this paper (observers.falsification.Problem).
PROBLEMS = [
    _thm47_problem(printed=True, some_P=True),
    _thm47_problem(printed=True),
    _thm47_problem(printed=False),
    _thm49_problem("pwc"),
    _thm49_problem("sin"),
    _thm411_problem("pwc"),
    _thm411_problem("sin"),
]
