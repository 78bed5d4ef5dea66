"""Figs. 1-3 of Li & Sanfelice, redrawn from engine runs: :data:`FIGURES`, :func:`reproduce`.

Each figure is a :class:`observers._common.Figure`: a ``*_data()`` function
runs the engine and returns the figure's numbers as a frozen dataclass
(cached, so that the claims and the tests reuse the runs), a ``draw_*``
function draws them on a :class:`matplotlib.figure.Figure` with
:mod:`hybridsim`'s plots, and a ``*_caption`` function writes the caption
saying which values are the paper's and which were chosen.

Every trajectory is a run of :func:`observers.li_sanfelice.simulate` (DOP853,
rtol 1e-10, atol 1e-12); the closed forms (6) and (15) are drawn as lines
with engine-simulated markers on them. What the old ``reproduce`` printed
(the key numbers of each figure) goes to this module's logger.

Examples
--------
>>> from observers.li_sanfelice.figures import fig1a_data
>>> D = fig1a_data()                       # (6) on a grid, engine runs at six deltas
>>> round(D.esim[0], 4), D.dev6 < 1e-9     # |e1+(1)| = 0.1951, engine = (6)
(0.1951, True)
"""
from __future__ import annotations

import dataclasses
import functools
import logging
import math

import numpy as np
from matplotlib.figure import Figure as MplFigure

import hybridsim as hs
from observers._common import Figure, reproduce_figures

from .design import (
    Design,
    PiecewiseConstantNoise,
    error_after_jump,
    scalar_error_after_jump,
    theorem_4_10_bound,
)
from .example import errors, example_III, example_VA, example_VB, simulate
from .monte_carlo import (
    caption_delta_noise,
    caption_random_noise,
    delta_noise_data,
    draw_delta_noise,
    draw_random_noise,
    random_noise_data,
)
from .systems import (
    ConstantNoiseObserver,
    LuenbergerObserver,
    NominalObserver,
    PiecewiseConstantNoiseObserver,
)

__all__ = [
    "FIGURES",
    "NOT_REPRODUCED",
    "reproduce",
    "Fig1aData",
    "Fig1bData",
    "Fig2aData",
    "Fig2bCurves",
    "Fig2bData",
    "Fig3Data",
    "fig1a_data",
    "fig1b_data",
    "fig2a_data",
    "fig2b_data",
    "fig3_data",
]

log = logging.getLogger(__name__)

_SIM = dict(method="DOP853", rtol=1e-10, atol=1e-12)


def _estimate(obs, i, n):
    """The i-th component of x̄ = a1 x̂1 + a2 x̂2 (footnote 2) from the interconnection state
    (x, ζ) of :func:`simulate` (plant first, n states)."""
    if isinstance(obs, LuenbergerObserver):
        return lambda X: X[n + i]
    d, sl = obs.design, obs.slices
    o1, o2 = n + sl["xh1"].start + i, n + sl["xh2"].start + i
    return lambda X: d.a1 * X[o1] + d.a2 * X[o2]


def _error(obs, i, n, sign=1.0):
    """sign * (x̄_i - x_i) as a function of the interconnection state."""
    est = _estimate(obs, i, n)
    return lambda X: sign * (est(X) - X[i])


def _mhat(obs, i, n):
    """m̂_i of H_c / H_pc (18) as a function of the interconnection state."""
    k = n + obs.slices["mhat"].start + i
    return lambda X: X[k]


def _plot_fn(ax, arc, fn, label, **kw):
    """A function of the state against t, flows drawn smooth through the arc's interpolant and
    jumps dotted (the engine's plot); ``kw`` are Line2D properties (solid or dash-dot for data,
    never ":" which is the jumps' style)."""
    hs.plot_flows(arc, fn=fn, ax=ax, labels=[label], **kw)


def _after_jump_e1(arc, obs):
    """|e1| at the first sample after the (single) jump of H_n."""
    return abs(float(errors(arc, obs)["e1"][arc.j == 1][0, 0]))


# ---------------------------------------------------------------------------
# Fig. 1(a): |e1+(delta)| against delta, formula (6)
# ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Fig1aData:
    """The numbers of Fig. 1(a) (Section III, formula (6)).

    Attributes
    ----------
    a, L1, L2, m : float
        The paper's scalar data (plant (5), gains, constant noise).
    deltas, e6 : ndarray
        The delta grid on [0.25, 60] and |(6)| on it.
    dsim, esim : tuple of float
        Reset times of the engine runs of H_n (= (3)) and their |e1(delta, 1)|.
    dev6 : float
        max |(6) - engine| over the runs.
    """

    a: float
    L1: float
    L2: float
    m: float
    deltas: np.ndarray
    e6: np.ndarray
    dsim: tuple
    esim: tuple
    dev6: float


@functools.cache
def fig1a_data():
    """Fig. 1(a): formula (6) on a delta grid and engine runs of (3) at six deltas.

    Returns
    -------
    Fig1aData

    References
    ----------
    Li & Sanfelice, Section III, (5)-(6), Fig. 1(a).
    """
    a, L1, L2, m = -0.05, 0.01, 0.02, 0.2
    deltas = np.linspace(0.25, 60, 400)
    e6 = np.abs(scalar_error_after_jump(a, L1, L2, deltas, m))
    dsim = (1.0, 2.0, 5.0, 10.0, 20.0, 40.0)
    esim = []
    for dl in dsim:
        obs = NominalObserver(Design(A=[[a]], H=[[1.0]], L1=[[L1]], L2=[[L2]], delta=dl))
        arc = simulate(obs, [1.0], [0.0], noise=[m], t_max=dl * 1.01, **_SIM)
        esim.append(_after_jump_e1(arc, obs))
    dev6 = max(abs(abs(scalar_error_after_jump(a, L1, L2, d_, m)) - e_)
               for d_, e_ in zip(dsim, esim))
    D = Fig1aData(a, L1, L2, m, deltas, e6, dsim, tuple(esim), float(dev6))
    log.info("  Fig. 1(a): |e+| = %.4f (delta=1), %.4f (delta=2), %.4f (delta=40); "
             "max |(6) - engine| = %.1e", D.esim[0], D.esim[1], D.esim[-1], D.dev6)
    return D


def draw_fig1a(D):
    """Draw :class:`Fig1aData`: the line (6) and the engine's circles."""
    fig = MplFigure(figsize=(6, 4), layout="tight")
    ax = fig.add_subplot()
    ax.plot(D.deltas, D.e6, "b-", label="formula (6)")
    ax.plot(D.dsim, D.esim, "ko", mfc="none", label="engine run of (3) (H_n)")
    ax.set_xlabel(r"jump time $\delta$")
    ax.set_ylabel(r"$|e_1^+(\delta)|$")
    ax.set_title("Fig. 1(a): error after the reset under a constant bias")
    ax.legend()
    ax.grid(alpha=0.3)
    return fig


def fig1a_caption(D):
    """The caption of Fig. 1(a)."""
    return f"""
Fig. 1(a) of Li & Sanfelice: error |e1+(delta)| right after the single reset of the finite-time \
observer (3)
against the reset time delta, scalar plant (5) with constant noise. Paper values: a = -0.05, \
L1 = 0.01,
L2 = 0.02, m = 0.2. Line: closed form (6); circles: engine runs of H_n (= (3)) from x(0) = 1, \
x̂(0) = 0
(chosen; (6) does not depend on them). Chosen: the delta range [0.25, 60]. The smaller delta, the \
larger
the error: at delta = 1 it is {D.esim[0]:.3f}, at delta = 40 {D.esim[-1]:.3f}."""


# ---------------------------------------------------------------------------
# Fig. 1(b): (3) against the Luenberger observer (2), zero solution of (1)
# ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Fig1bData:
    """The runs of Fig. 1(b): observer (3) (= H_n) and Luenberger (2) on the zero solution.

    Attributes
    ----------
    obs_n, arc_n : NominalObserver, hybridsim.HybridArc
        Observer (3), delta = 2, and its run.
    obs_l, arc_l : LuenbergerObserver, hybridsim.HybridArc
        Observer (2), L0 = 0.02, and its run.
    xbar_after_jump : float
        x̄ of (3) right after its jump at t = 2 (formula (6)).
    luenberger_at_2 : float
        The Luenberger estimate's error at t = 2.
    t_above_01 : tuple of float
        The last time |error| > 0.1, for (3) and for (2).
    """

    obs_n: NominalObserver
    arc_n: hs.HybridArc
    obs_l: LuenbergerObserver
    arc_l: hs.HybridArc
    xbar_after_jump: float
    luenberger_at_2: float
    t_above_01: tuple


def _last_above(t, v, level=0.1):
    return float(t[np.flatnonzero(np.abs(v) > level)[-1]]) if np.any(np.abs(v) > level) else 0.0


@functools.cache
def fig1b_data():
    """Fig. 1(b): (3) and (2) from x̂(0) = 1 on the zero solution, bias m = 0.2, horizon 60.

    Returns
    -------
    Fig1bData

    References
    ----------
    Li & Sanfelice, Section III, (2)-(3), Fig. 1(b).
    """
    a, m = -0.05, 0.2
    obs_n = NominalObserver(example_III(delta=2.0))
    obs_l = LuenbergerObserver([[a]], [[1.0]], [[0.02]])
    tf = 60.0
    arc_n = simulate(obs_n, [0.0], [1.0], noise=[m], t_max=tf, refine=8, **_SIM)
    arc_l = simulate(obs_l, [0.0], [1.0], noise=[m], t_max=tf, refine=8, **_SIM)
    En, El = errors(arc_n, obs_n), errors(arc_l, obs_l)
    kj = np.flatnonzero(arc_n.j == 1)[0]
    D = Fig1bData(obs_n, arc_n, obs_l, arc_l, float(En["xbar"][kj, 0]),
                  float(np.interp(2.0, arc_l.t, El["e0"][:, 0])),
                  (_last_above(arc_n.t, En["ebar"][:, 0]), _last_above(arc_l.t, El["e0"][:, 0])))
    log.info("  Fig. 1(b): x̄ after the jump at t=2: %.4f; Luenberger at t=2: %.4f; "
             "|error| > 0.1 until t = %.2f for (3), %.2f for (2)", D.xbar_after_jump,
             D.luenberger_at_2, *D.t_above_01)
    return D


def draw_fig1b(D):
    """Draw :class:`Fig1bData` with ``hs.plot_flows`` (jumps dotted)."""
    fig = MplFigure(figsize=(7, 4), layout="tight")
    ax = fig.add_subplot()
    _plot_fn(ax, D.arc_n, lambda X: X[0], "plant $x$ (zero solution)", color="r", linestyle="--",
             jumps=False)
    _plot_fn(ax, D.arc_l, _estimate(D.obs_l, 0, 1), r"Luenberger (2), $L_0 = 0.02$", color="k")
    _plot_fn(ax, D.arc_n, _estimate(D.obs_n, 0, 1), r"(3): $\bar x$, $\delta = 2$", color="b",
             linestyle="-.")
    ax.set_xlabel(r"time $t$ (dimensionless, as in the paper)")
    ax.set_ylabel(r"state $x$ and estimates")
    ax.set_title("Fig. 1(b): finite-time observer (3) vs Luenberger (2), bias m = 0.2")
    ax.legend()
    ax.grid(alpha=0.3)
    return fig


def fig1b_caption(D):
    """The caption of Fig. 1(b)."""
    return f"""
Fig. 1(b) of Li & Sanfelice: estimate of the zero solution of the scalar plant (5) by the \
finite-time
observer (3) (= H_n, estimate x̄ = (x̂1 + x̂2)/2, delta = 2, blue dash-dot) and by the Luenberger \
observer (2)
(L0 = 0.02, black); plant x = 0 in red dashes. Paper values: a = -0.05, L1 = 0.01, L2 = 0.02, \
L0 = 0.02,
delta = 2. Chosen (not in the text): initial estimates x̂(0) = 1, constant noise m = 0.2 (the \
value of
Fig. 1(a)), horizon 60. After its jump at t = 2, (3) is at {D.xbar_after_jump:.3f} (formula (6)), \
while
the Luenberger estimate is at {D.luenberger_at_2:.3f}; both then settle near the biased values \
L_i m / (L_i - a)."""


# ---------------------------------------------------------------------------
# Fig. 2(a): H_c on the scalar plant of Section V.A
# ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Fig2aData:
    """The runs of Fig. 2(a): H_c and H_n on example V.A (delta = 2) under the bias m.

    Attributes
    ----------
    m : float
        The constant noise (0.2, chosen).
    obs_c, arc_c : ConstantNoiseObserver, hybridsim.HybridArc
    obs_n, arc_n : NominalObserver, hybridsim.HybridArc
    err_c : float
        H_c's max |ē| after its jump (0 by Theorem 4.13, integrator level here).
    mhat : float
        H_c's m̂ right after its jump.
    err_n : float
        H_n's |ē(delta, 1)| (formula (15)).
    HT_inv_norm : float
        |(H T - 1)^-1|, the m̂ update's amplification.
    """

    m: float
    obs_c: ConstantNoiseObserver
    arc_c: hs.HybridArc
    obs_n: NominalObserver
    arc_n: hs.HybridArc
    err_c: float
    mhat: float
    err_n: float
    HT_inv_norm: float


@functools.cache
def fig2a_data():
    """Fig. 2(a): H_c (17)-(18) and H_n on example V.A, delta = 2, m = 0.2, horizon 12.

    Returns
    -------
    Fig2aData

    References
    ----------
    Li & Sanfelice, Section V.A, (17)-(18), Theorem 4.13, Fig. 2(a).
    """
    m = 0.2
    dA = example_VA(delta=2.0)
    obs_c, obs_n = ConstantNoiseObserver(dA), NominalObserver(dA)
    tf = 12.0
    arc_c = simulate(obs_c, [1.0], [0.0], noise=[m], t_max=tf, refine=8, **_SIM)
    arc_n = simulate(obs_n, [1.0], [0.0], noise=[m], t_max=tf, refine=8, **_SIM)
    Ec, En = errors(arc_c, obs_c), errors(arc_n, obs_n)
    post = arc_c.j == 1
    D = Fig2aData(m, obs_c, arc_c, obs_n, arc_n, float(np.max(np.abs(Ec["ebar"][post]))),
                  float(Ec["mhat"][post][0, 0]), abs(float(En["ebar"][arc_n.j == 1][0, 0])),
                  float(dA.HT_inv_norm))
    log.info("  Fig. 2(a): H_c max |ē| after the jump = %.2e, m̂ = %.10f (m = 0.2), "
             "|(HT-1)^-1| = %.2f; H_n |e(delta,1)| = %.4f", D.err_c, D.mhat, D.HT_inv_norm,
             D.err_n)
    return D


def draw_fig2a(D):
    """Draw :class:`Fig2aData`: estimates, |ē| (log scale), m̂ against m."""
    fig = MplFigure(figsize=(7, 8), layout="tight")
    axs = fig.subplots(3, 1, sharex=True)
    obs_c, obs_n, arc_c, arc_n = D.obs_c, D.obs_n, D.arc_c, D.arc_n
    _plot_fn(axs[0], arc_c, lambda X: X[0], "plant $x$", color="r", linestyle="--", jumps=False)
    _plot_fn(axs[0], arc_c, _estimate(obs_c, 0, 1), r"$H_c$: $\bar x$", color="b")
    _plot_fn(axs[0], arc_n, _estimate(obs_n, 0, 1), r"$H_n$: $\bar x$", color="g", linestyle="-.")
    axs[0].set_ylabel(r"state $x$ and estimates $\bar x$")
    axs[0].legend()
    axs[0].set_title(r"Fig. 2(a): $H_c$ compensates a constant bias after one jump")
    ec, en = _error(obs_c, 0, 1), _error(obs_n, 0, 1)
    _plot_fn(axs[1], arc_c, lambda X: abs(ec(X)) + 1e-17, r"$|\bar e|$, $H_c$", color="b")
    _plot_fn(axs[1], arc_n, lambda X: abs(en(X)) + 1e-17, r"$|\bar e|$, $H_n$", color="g",
             linestyle="-.")
    axs[1].set_yscale("log")
    axs[1].set_ylabel(r"estimation error $|\bar e| = |\bar x - x|$")
    axs[1].legend()
    axs[2].axhline(D.m, color="r", ls="--", label="noise $m$")
    _plot_fn(axs[2], arc_c, _mhat(obs_c, 0, 1), r"$\hat m$ ($H_c$)", color="m")
    axs[2].set_ylabel(r"noise $m$ and estimate $\hat m$")
    axs[2].set_xlabel(r"time $t$ (dimensionless, as in the paper)")
    for ax in axs[:-1]:
        ax.set_xlabel("")                       # shared t axis: labelled once, at the bottom
    axs[2].legend()
    for ax in axs:
        ax.grid(alpha=0.3)
    return fig


def fig2a_caption(D):
    """The caption of Fig. 2(a)."""
    return f"""
Fig. 2(a) of Li & Sanfelice: the observer H_c (17)-(18) on the scalar plant of Section V.A with a \
constant
measurement bias. Paper values: a = -0.05, L1 = 0.1, L2 = 0.2, H = 1. Chosen (not in the text): \
delta = 2,
m = 0.2, x(0) = 1, x̂1(0) = x̂2(0) = 0, m̂(0) = 0, horizon 12. Top: plant x (red dashes), H_c's \
estimate x̄
(blue) and, for comparison, H_n's (green dash-dot). Middle (log scale): |ē| of both. Bottom: H_c's \
noise
estimate m̂ against m.
After the jump at t = delta, H_c's error is {D.err_c:.1e} (integrator level; \
exactly 0 by Theorem 4.13) and
m̂ = {D.mhat:.12f}; H_n keeps the error of (15), {D.err_n:.4f} right after \
its
jump. |(H T - 1)^(-1)| = {D.HT_inv_norm:.1f} (the m̂ update's amplification)."""


# ---------------------------------------------------------------------------
# Fig. 2(b): error after the jump (15) of H_n, delta = 1 and 3
# ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Fig2bCurves:
    """One delta's curves of Fig. 2(b).

    Attributes
    ----------
    delta : float
    T : float
        T(delta) of (18) (scalar): |e(delta, 1)| = |T| m under a constant m.
    bound : float
        Theorem 4.10's bound per unit |m|_inf.
    const_line, bound_line : ndarray
        |T| m and the bound times m on the grid ``Fig2bData.ms``.
    msim, const_sim : ndarray
        Constant noises of the engine runs and their |e1(delta, 1)|.
    sine_line : ndarray
        |(15)| for m(t) = sin(omega t) on the grid ``Fig2bData.omegas``.
    wsim, sine_sim : ndarray
        Frequencies of the engine runs and their |e1(delta, 1)|.
    sine_max, omega_at_max : float
        The largest |(15)| on the grid, and where.
    dev15 : float
        max |(15) - engine| over the sinusoid runs.
    """

    delta: float
    T: float
    bound: float
    const_line: np.ndarray
    bound_line: np.ndarray
    msim: np.ndarray
    const_sim: np.ndarray
    sine_line: np.ndarray
    wsim: np.ndarray
    sine_sim: np.ndarray
    sine_max: float
    omega_at_max: float
    dev15: float


@dataclasses.dataclass(frozen=True)
class Fig2bData:
    """The numbers of Fig. 2(b): grids ``ms`` (constant noise), ``omegas`` (sinusoid), and
    ``curves`` (one :class:`Fig2bCurves` per delta, 1 then 3)."""

    ms: np.ndarray
    omegas: np.ndarray
    curves: tuple


@functools.cache
def fig2b_data():
    """Fig. 2(b): (15) of H_n on example V.A, delta = 1 and 3, with engine runs and Thm 4.10.

    Returns
    -------
    Fig2bData

    References
    ----------
    Li & Sanfelice, Section V.A, (15), Theorem 4.10, Fig. 2(b).
    """
    ms = np.linspace(0.0, 1.0, 101)
    omegas = np.linspace(0.05, 6.0, 150)
    curves = []
    for dl in (1.0, 3.0):
        dd = example_VA(delta=dl)
        obs = NominalObserver(dd)
        b410 = theorem_4_10_bound(dd, 1.0)
        msim = np.array([0.25, 0.5, 0.75, 1.0])
        es = []
        for mm in msim:
            arc = simulate(obs, [1.0], [0.0], noise=[mm], t_max=dl * 1.01, **_SIM)
            es.append(_after_jump_e1(arc, obs))
        e_w = np.array([abs(error_after_jump(dd, lambda s, w=w: [math.sin(w * s)])[0])
                        for w in omegas])
        wsim = omegas[::30]
        es_w = []
        for w in wsim:
            arc = simulate(obs, [1.0], [0.0], noise=lambda t, w=w: np.array([math.sin(w * t)]),
                           t_max=dl * 1.01, **_SIM)
            es_w.append(_after_jump_e1(arc, obs))
        dev15 = max(abs(a_ - b_) for a_, b_ in zip(es_w, e_w[::30]))
        curves.append(Fig2bCurves(
            dl, float(dd.T[0, 0]), float(b410), np.abs(dd.T[0, 0]) * ms, b410 * ms, msim,
            np.array(es), e_w, wsim, np.array(es_w), float(max(e_w)),
            float(omegas[int(np.argmax(e_w))]), float(dev15)))
    D = Fig2bData(ms, omegas, tuple(curves))
    c1, c3 = D.curves
    log.info("  Fig. 2(b): constant noise |e(delta,1)|/m = %.4f (delta=1), %.4f (delta=3); "
             "sinusoid max |e(delta,1)| = %.3f (delta=1), %.3f (delta=3); "
             "Thm 4.10 bound/|m| = %.3f, %.3f; max |(15) - engine| = %.1e", abs(c1.T), abs(c3.T),
             c1.sine_max, c3.sine_max, c1.bound, c3.bound, max(c1.dev15, c3.dev15))
    return D


def draw_fig2b(D):
    """Draw :class:`Fig2bData`: constant noise (left) and a unit sinusoid (right)."""
    fig = MplFigure(figsize=(11, 4), layout="tight")
    axs = fig.subplots(1, 2)
    for c, col in zip(D.curves, ("b", "r")):
        dl = c.delta
        axs[0].plot(D.ms, c.const_line, col + "-", label=rf"(15), $\delta = {dl:g}$")
        axs[0].plot(D.ms, c.bound_line, col + ":", lw=1,
                    label=rf"Thm 4.10 bound, $\delta = {dl:g}$")
        axs[0].plot(c.msim, c.const_sim, col + "o", mfc="none")
        axs[1].plot(D.omegas, c.sine_line, col + "-", label=rf"(15), $\delta = {dl:g}$")
        axs[1].axhline(c.bound, color=col, ls=":", lw=1,
                       label=rf"Thm 4.10 bound, $\delta = {dl:g}$")
        axs[1].plot(c.wsim, c.sine_sim, col + "o", mfc="none")
    axs[0].set_xlabel("constant noise m")
    axs[0].set_ylabel(r"$|e(\delta, 1)|$ of $H_n$")
    axs[0].set_title("constant noise")
    axs[1].set_xlabel(r"frequency $\omega$ of $m(t) = \sin(\omega t)$")
    axs[1].set_yscale("log")
    axs[1].set_title("sinusoidal noise, $|m|_\\infty = 1$")
    for ax in axs:
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.suptitle(r"Fig. 2(b): effect of $\delta$ on $H_n$'s error after the jump, formula (15)")
    return fig


def fig2b_caption(D):
    """The caption of Fig. 2(b)."""
    c1, c3 = D.curves
    return f"""
Fig. 2(b) of Li & Sanfelice: error right after the jump of H_n, formula (15) (lines), with engine \
runs (circles)
and the bound of Theorem 4.10 (dotted), for delta = 1 (blue) and delta = 3 (red). Paper values: \
a = -0.05,
L1 = 0.1, L2 = 0.2, delta in {{1, 3}}. The text only says (15) is evaluated for delta = 1 and 3; \
chosen here:
left, a constant noise of size m in [0, 1] (|e(delta,1)| = |T| m with |T| = {abs(c1.T):.4f} \
for delta = 1,
{abs(c3.T):.4f} for delta = 3: little sensitivity); right, a unit sinusoid \
m(t) = sin(omega t),
omega in [0.05, 6], where delta matters: the largest error is {c1.sine_max:.3f} \
(omega = {c1.omega_at_max:.2f}) for
delta = 1 and {c3.sine_max:.3f} (omega = {c3.omega_at_max:.2f}) for delta = 3. Theorem 4.10 \
bounds per \
unit
|m|_inf: {c1.bound:.2f} and {c3.bound:.2f}. Runs from x(0) = 1, x̂(0) = 0 (chosen; (15) does \
not depend
on them)."""


# ---------------------------------------------------------------------------
# Fig. 3: H_pc on the plant of Section V.B with piecewise-constant noise
# ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Fig3Data:
    """The run of Fig. 3: H_pc on example V.B under the piecewise-constant noise.

    Attributes
    ----------
    noise : PiecewiseConstantNoise
        m = c1 on [0, 2.5), c2 on [2.5, 4.5), c3 after.
    obs, arc : PiecewiseConstantNoiseObserver, hybridsim.HybridArc
    tt, m_grid : ndarray
        A time grid on [0, 8] and m on it, (801,) and (801, 2).
    exact_from : tuple of (float, float, float)
        For each noise value: the switch time d_k (0 first), the time of
        the second jump after it from which the estimate is exact, and the
        max |ē| from there to the next switch.
    HT_cond, HT_inv_norm : float
        cond(H T - I) and |(H T - I)^-1| of example V.B.
    """

    noise: PiecewiseConstantNoise
    obs: PiecewiseConstantNoiseObserver
    arc: hs.HybridArc
    tt: np.ndarray
    m_grid: np.ndarray
    exact_from: tuple
    HT_cond: float
    HT_inv_norm: float


@functools.cache
def fig3_data():
    """Fig. 3: H_pc (Section IV-E) on example V.B, switches at 2.5 and 4.5, horizon 8.

    Returns
    -------
    Fig3Data

    References
    ----------
    Li & Sanfelice, Section V.B, Theorem 4.14, Fig. 3.
    """
    dB = example_VB()
    noise = PiecewiseConstantNoise([2.5, 4.5], [[0.3, 0.2], [0.4, 0.4], [0.2, 0.3]])
    obs = PiecewiseConstantNoiseObserver(dB)
    tf = 8.0
    arc = simulate(obs, [0.3, 0.4], [0.0, 0.0], noise=noise, t_max=tf, refine=8, **_SIM)
    err = errors(arc, obs).norm("ebar")
    msgs = []
    for k, d_k in enumerate([0.0, *noise.d]):
        J = int(np.flatnonzero(arc.jump_times >= d_k + dB.delta - 1e-9)[0])
        tJ = arc.jump_times[J]
        nxt = noise.d[k] if k < len(noise.d) else tf
        msk = ((arc.t > tJ) | ((arc.t == tJ) & (arc.j >= J + 1))) & (arc.t < nxt)
        msgs.append((float(d_k), float(tJ), float(err[msk].max())))
    tt = np.linspace(0, tf, 801)
    D = Fig3Data(noise, obs, arc, tt, np.array([noise(s) for s in tt]), tuple(msgs),
                 float(dB.HT_cond), float(dB.HT_inv_norm))
    log.info("  Fig. 3: exact again (max |ē| until the next switch) %s; cond(HT-I) = %.2f, "
             "|(HT-I)^-1| = %.2f", "; ".join(f"after d={d_k:g}: from t={tJ:g} ({e:.1e})"
                                             for d_k, tJ, e in D.exact_from),
             D.HT_cond, D.HT_inv_norm)
    return D


def draw_fig3(D):
    """Draw :class:`Fig3Data`: states and estimates, errors, noise and m̂ (switches dotted)."""
    fig = MplFigure(figsize=(7, 8), layout="tight")
    axs = fig.subplots(3, 1, sharex=True)
    arc, obs = D.arc, D.obs
    for i, col in ((0, "b"), (1, "r")):
        _plot_fn(axs[0], arc, lambda X, i=i: X[i], rf"$x_{i + 1}$", color=col, linestyle="--",
                 jumps=False)
        _plot_fn(axs[0], arc, _estimate(obs, i, 2), rf"$\bar x_{i + 1}$", color=col)
        _plot_fn(axs[1], arc, _error(obs, i, 2, sign=-1.0),
                 rf"$\bar e_{i + 1} = x_{i + 1} - \bar x_{i + 1}$", color=col)
        axs[2].plot(D.tt, D.m_grid[:, i], col + "--", label=rf"$m_{i + 1}$")
        _plot_fn(axs[2], arc, _mhat(obs, i, 2), rf"$\hat m_{i + 1}$", color=col)
    for ax in axs:
        for s in D.noise.d:
            ax.axvline(s, color="gray", lw=0.6, ls=":")
        ax.legend(fontsize=8, ncol=2)
        ax.grid(alpha=0.3)
    axs[0].set_title(r"Fig. 3: $H_{pc}$ under piecewise-constant noise "
                     r"(recursive jumps, $\delta = 1$)")
    axs[0].set_ylabel(r"states $x_i$, estimates $\bar x_i$")
    axs[1].set_ylabel(r"errors $\bar e_i = x_i - \bar x_i$")
    axs[2].set_ylabel(r"noise $m_i$, estimate $\hat m_i$")
    axs[2].set_xlabel(r"time $t$ (dimensionless, as in the paper)")
    for ax in axs[:-1]:
        ax.set_xlabel("")                       # shared t axis: labelled once, at the bottom
    return fig


def fig3_caption(D):
    """The caption of Fig. 3."""
    msgs = D.exact_from
    return f"""
Fig. 3 of Li & Sanfelice: the observer H_pc (jumps every delta) on the plant of Section V.B. Paper \
values:
A = [[0, 1], [-1, 0]], H = [[1, 2], [2, 1]], delta = 1, L1 = 5 H^-1, L2 = 8 H^-1 (the exact values \
whose
two-decimal roundings the paper prints), m = c1 on [0, 2.5), c2 on [2.5, 4.5), c3 after, \
c1 = (0.3, 0.2),
c2 = (0.4, 0.4), c3 = (0.2, 0.3), x(0) = (0.3, 0.4), x̂1(0) = x̂2(0) = 0. Chosen: m̂(0) = 0, horizon 8.
Top: plant states (dashed) and estimates x̄ = (x̂1 + x̂2)/2; middle: errors ē_i = x_i - x̄_i; \
bottom: noise and
its estimate m̂ (switches dotted). Each time the noise changes, the estimate is exact again from \
the second
jump after the switch: exact from t = {msgs[0][1]:g} (max |ē| {msgs[0][2]:.1e}), from \
t = {msgs[1][1]:g} after
the switch at 2.5 ({msgs[1][2]:.1e}), from t = {msgs[2][1]:g} after the switch at 4.5 \
({msgs[2][2]:.1e})."""


# ---------------------------------------------------------------------------
# the registry
# ---------------------------------------------------------------------------
#: Figs. 1(a), 1(b), 2(a), 2(b) and 3 of the paper, in this order, then the two noise studies
#: restated as estimates (:mod:`observers.li_sanfelice.monte_carlo`).
FIGURES = [
    Figure("fig1a_error_vs_delta", "Fig. 1(a)", fig1a_data, draw_fig1a, fig1a_caption),
    Figure("fig1b_luenberger_comparison", "Fig. 1(b)", fig1b_data, draw_fig1b, fig1b_caption),
    Figure("fig2a_Hc_constant_noise", "Fig. 2(a)", fig2a_data, draw_fig2a, fig2a_caption),
    Figure("fig2b_error_after_jump_delta", "Fig. 2(b)", fig2b_data, draw_fig2b, fig2b_caption),
    Figure("fig3_Hpc_piecewise_noise", "Fig. 3", fig3_data, draw_fig3, fig3_caption),
    Figure("mc_Hn_random_noise", "Theorem 4.10 under random noise: P(error after the jump "
           "<= b)", random_noise_data, draw_random_noise, caption_random_noise),
    Figure("mc_Hn_delta_random_noise", "Fig. 2(b) under random noise: P(error after the jump "
           "<= b) against delta", delta_noise_data, draw_delta_noise, caption_delta_noise),
]

#: Every figure of the paper is reproduced.
NOT_REPRODUCED = {}


def reproduce(outdir):
    """Regenerate Figs. 1(a), 1(b), 2(a), 2(b) and 3 of the paper as PNG files (with .txt captions).

    Parameters
    ----------
    outdir : str or pathlib.Path
        An existing folder.

    Returns
    -------
    list of pathlib.Path
        The PNG files written (the :data:`FIGURES` in order).

    References
    ----------
    Li & Sanfelice, Sections III and V, Figs. 1-3.
    """
    return reproduce_figures(FIGURES, outdir)
