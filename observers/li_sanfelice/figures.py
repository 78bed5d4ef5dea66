"""Figs. 1-3 of Li & Sanfelice, redrawn from engine runs: :func:`reproduce`.

Every trajectory is a run of :func:`observers.li_sanfelice.simulate` (DOP853,
rtol 1e-10, atol 1e-12); the closed forms (6) and (15) are drawn as lines
with engine-simulated markers on them. Each PNG gets a ``.txt`` caption
saying which values are the paper's and which were chosen.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np

import hybridsim as hs
from observers._common import write_caption

from .design import (
    Design,
    PiecewiseConstantNoise,
    error_after_jump,
    scalar_error_after_jump,
    theorem_4_10_bound,
)
from .example import example_III, example_VA, example_VB, observer_errors, simulate_with_plant
from .systems import (
    ConstantNoiseObserver,
    LuenbergerObserver,
    NominalObserver,
    PiecewiseConstantNoiseObserver,
)

__all__ = ["reproduce"]

_SIM = dict(method="DOP853", rtol=1e-10, atol=1e-12)


def _estimate(obs, i, n):
    """The i-th component of x̄ = a1 x̂1 + a2 x̂2 (footnote 2) from the interconnection state
    (x, ζ) of :func:`simulate_with_plant` (plant first, n states)."""
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


def reproduce(outdir):
    """Regenerate Figs. 1(a), 1(b), 2(a), 2(b) and 3 of the paper as PNG files (with .txt captions).

    Every trajectory is an engine run (:func:`simulate_with_plant`, DOP853,
    rtol 1e-10, atol 1e-12); the closed forms (6) and (15) are drawn as lines
    with engine-simulated markers on them. Prints the key numbers.

    Parameters
    ----------
    outdir : str or pathlib.Path

    Returns
    -------
    list of pathlib.Path
        The PNG files written.

    References
    ----------
    Li & Sanfelice, Sections III and V, Figs. 1-3.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = pathlib.Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []

    # ---- Fig. 1(a): |e1+(delta)| against delta, formula (6) ----------------------------------
    a, L1, L2, m = -0.05, 0.01, 0.02, 0.2
    deltas = np.linspace(0.25, 60, 400)
    e6 = np.abs(scalar_error_after_jump(a, L1, L2, deltas, m))
    dsim = [1.0, 2.0, 5.0, 10.0, 20.0, 40.0]
    esim = []
    for dl in dsim:
        obs = NominalObserver(Design(A=[[a]], H=[[1.0]], L1=[[L1]], L2=[[L2]], delta=dl))
        arc = simulate_with_plant(obs, [1.0], [0.0], noise=[m], t_max=dl * 1.01, **_SIM)
        E = observer_errors(arc, obs)
        esim.append(abs(E["e1"][arc.j == 1][0, 0]))
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(deltas, e6, "b-", label="formula (6)")
    ax.plot(dsim, esim, "ko", mfc="none", label="engine run of (3) (H_n)")
    ax.set_xlabel(r"jump time $\delta$")
    ax.set_ylabel(r"$|e_1^+(\delta)|$")
    ax.set_title("Fig. 1(a): error after the reset under a constant bias")
    ax.legend()
    ax.grid(alpha=0.3)
    p = out / "fig1a_error_vs_delta.png"
    fig.tight_layout()
    fig.savefig(p, dpi=120)
    plt.close(fig)
    write_caption(p, f"""
Fig. 1(a) of Li & Sanfelice: error |e1+(delta)| right after the single reset of the finite-time \
observer (3)
against the reset time delta, scalar plant (5) with constant noise. Paper values: a = -0.05, \
L1 = 0.01,
L2 = 0.02, m = 0.2. Line: closed form (6); circles: engine runs of H_n (= (3)) from x(0) = 1, \
x̂(0) = 0
(chosen; (6) does not depend on them). Chosen: the delta range [0.25, 60]. The smaller delta, the \
larger
the error: at delta = 1 it is {esim[0]:.3f}, at delta = 40 {esim[-1]:.3f}.""")
    paths.append(p)
    dev6 = max(abs(abs(scalar_error_after_jump(a, L1, L2, d_, m)) - e_)
               for d_, e_ in zip(dsim, esim))
    print(f"  Fig. 1(a): |e+| = {esim[0]:.4f} (delta=1), {esim[1]:.4f} (delta=2), "
          f"{esim[-1]:.4f} (delta=40); "
          f"max |(6) - engine| = {dev6:.1e}")

    # ---- Fig. 1(b): (3) against the Luenberger observer (2), zero solution of (1) --------------
    d1 = example_III(delta=2.0)
    obs_n = NominalObserver(d1)
    obs_l = LuenbergerObserver([[a]], [[1.0]], [[0.02]])
    tf = 60.0
    arc_n = simulate_with_plant(obs_n, [0.0], [1.0], noise=[m], t_max=tf, refine=8, **_SIM)
    arc_l = simulate_with_plant(obs_l, [0.0], [1.0], noise=[m], t_max=tf, refine=8, **_SIM)
    En, El = observer_errors(arc_n, obs_n), observer_errors(arc_l, obs_l)
    fig, ax = plt.subplots(figsize=(7, 4))
    _plot_fn(ax, arc_n, lambda X: X[0], "plant $x$ (zero solution)", color="r", linestyle="--",
             jumps=False)
    _plot_fn(ax, arc_l, _estimate(obs_l, 0, 1), r"Luenberger (2), $L_0 = 0.02$", color="k")
    _plot_fn(ax, arc_n, _estimate(obs_n, 0, 1), r"(3): $\bar x$, $\delta = 2$", color="b",
             linestyle="-.")
    ax.set_xlabel(r"time $t$ (dimensionless, as in the paper)")
    ax.set_ylabel(r"state $x$ and estimates")
    ax.set_title("Fig. 1(b): finite-time observer (3) vs Luenberger (2), bias m = 0.2")
    ax.legend()
    ax.grid(alpha=0.3)
    p = out / "fig1b_luenberger_comparison.png"
    fig.tight_layout()
    fig.savefig(p, dpi=120)
    plt.close(fig)
    kj = np.flatnonzero(arc_n.j == 1)[0]
    e_l2 = float(np.interp(2.0, arc_l.t, El["e0"][:, 0]))

    def t10(t, v):
        return float(t[np.flatnonzero(np.abs(v) > 0.1)[-1]]) if np.any(np.abs(v) > 0.1) else 0.0
    write_caption(p, f"""
Fig. 1(b) of Li & Sanfelice: estimate of the zero solution of the scalar plant (5) by the \
finite-time
observer (3) (= H_n, estimate x̄ = (x̂1 + x̂2)/2, delta = 2, blue dash-dot) and by the Luenberger \
observer (2)
(L0 = 0.02, black); plant x = 0 in red dashes. Paper values: a = -0.05, L1 = 0.01, L2 = 0.02, \
L0 = 0.02,
delta = 2. Chosen (not in the text): initial estimates x̂(0) = 1, constant noise m = 0.2 (the \
value of
Fig. 1(a)), horizon 60. After its jump at t = 2, (3) is at {En['xbar'][kj, 0]:.3f} (formula (6)), \
while
the Luenberger estimate is at {e_l2:.3f}; both then settle near the biased values \
L_i m / (L_i - a).""")
    paths.append(p)
    print(f"  Fig. 1(b): x̄ after the jump at t=2: {En['xbar'][kj, 0]:.4f}; "
          f"Luenberger at t=2: {e_l2:.4f}; "
          f"|error| > 0.1 until t = {t10(arc_n.t, En['ebar'][:, 0]):.2f} for (3), "
          f"{t10(arc_l.t, El['e0'][:, 0]):.2f} "
          "for (2)")

    # ---- Fig. 2(a): H_c on the scalar plant of Section V.A ---------------------------------------
    dA = example_VA(delta=2.0)
    obs_c = ConstantNoiseObserver(dA)
    obs_n = NominalObserver(dA)
    tf = 12.0
    arc_c = simulate_with_plant(obs_c, [1.0], [0.0], noise=[m], t_max=tf, refine=8, **_SIM)
    arc_n = simulate_with_plant(obs_n, [1.0], [0.0], noise=[m], t_max=tf, refine=8, **_SIM)
    Ec, En = observer_errors(arc_c, obs_c), observer_errors(arc_n, obs_n)
    fig, axs = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
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
    axs[2].axhline(m, color="r", ls="--", label="noise $m$")
    _plot_fn(axs[2], arc_c, _mhat(obs_c, 0, 1), r"$\hat m$ ($H_c$)", color="m")
    axs[2].set_ylabel(r"noise $m$ and estimate $\hat m$")
    axs[2].set_xlabel(r"time $t$ (dimensionless, as in the paper)")
    for ax in axs[:-1]:
        ax.set_xlabel("")                       # shared t axis: labelled once, at the bottom
    axs[2].legend()
    for ax in axs:
        ax.grid(alpha=0.3)
    p = out / "fig2a_Hc_constant_noise.png"
    fig.tight_layout()
    fig.savefig(p, dpi=120)
    plt.close(fig)
    post = arc_c.j == 1
    errc = float(np.max(np.abs(Ec["ebar"][post])))
    mh = float(Ec["mhat"][post][0, 0])
    write_caption(p, f"""
Fig. 2(a) of Li & Sanfelice: the observer H_c (17)-(18) on the scalar plant of Section V.A with a \
constant
measurement bias. Paper values: a = -0.05, L1 = 0.1, L2 = 0.2, H = 1. Chosen (not in the text): \
delta = 2,
m = 0.2, x(0) = 1, x̂1(0) = x̂2(0) = 0, m̂(0) = 0, horizon 12. Top: plant x (red dashes), H_c's \
estimate x̄
(blue) and, for comparison, H_n's (green dash-dot). Middle (log scale): |ē| of both. Bottom: H_c's \
noise
estimate m̂ against m.
After the jump at t = delta, H_c's error is {errc:.1e} (integrator level; \
exactly 0 by Theorem 4.13) and
m̂ = {mh:.12f}; H_n keeps the error of (15), {abs(En['ebar'][arc_n.j == 1][0, 0]):.4f} right after \
its
jump. |(H T - 1)^(-1)| = {dA.HT_inv_norm:.1f} (the m̂ update's amplification).""")
    paths.append(p)
    print(f"  Fig. 2(a): H_c max |ē| after the jump = {errc:.2e}, m̂ = {mh:.10f} (m = 0.2), "
          f"|(HT-1)^-1| = {dA.HT_inv_norm:.2f}; "
          f"H_n |e(delta,1)| = {abs(En['ebar'][arc_n.j == 1][0, 0]):.4f}")

    # ---- Fig. 2(b): error after the jump (15) of H_n, delta = 1 and 3 ------------------------
    ms = np.linspace(0.0, 1.0, 101)
    omegas = np.linspace(0.05, 6.0, 150)
    fig, axs = plt.subplots(1, 2, figsize=(11, 4))
    lines = []
    for dl, col in ((1.0, "b"), (3.0, "r")):
        dd = example_VA(delta=dl)
        obs = NominalObserver(dd)
        b410 = theorem_4_10_bound(dd, 1.0)
        # left: constant noise of size m
        axs[0].plot(ms, np.abs(dd.T[0, 0]) * ms, col + "-", label=rf"(15), $\delta = {dl:g}$")
        axs[0].plot(ms, b410 * ms, col + ":", lw=1, label=rf"Thm 4.10 bound, $\delta = {dl:g}$")
        msim = np.array([0.25, 0.5, 0.75, 1.0])
        es = []
        for mm in msim:
            arc = simulate_with_plant(obs, [1.0], [0.0], noise=[mm], t_max=dl * 1.01, **_SIM)
            es.append(abs(observer_errors(arc, obs)["e1"][arc.j == 1][0, 0]))
        axs[0].plot(msim, es, col + "o", mfc="none")
        # right: unit sinusoidal noise m(t) = sin(omega t)
        e_w = [abs(error_after_jump(dd, lambda s, w=w: [math.sin(w * s)])[0]) for w in omegas]
        axs[1].plot(omegas, e_w, col + "-", label=rf"(15), $\delta = {dl:g}$")
        axs[1].axhline(b410, color=col, ls=":", lw=1, label=rf"Thm 4.10 bound, $\delta = {dl:g}$")
        wsim = omegas[::30]
        es_w = []
        for w in wsim:
            arc = simulate_with_plant(obs, [1.0], [0.0],
                                      noise=lambda t, w=w: np.array([math.sin(w * t)]),
                                      t_max=dl * 1.01, **_SIM)
            es_w.append(abs(observer_errors(arc, obs)["e1"][arc.j == 1][0, 0]))
        axs[1].plot(wsim, es_w, col + "o", mfc="none")
        dev15 = max(abs(a_ - b_) for a_, b_ in zip(es_w, e_w[::30]))
        lines.append((dl, dd.T[0, 0], b410, max(e_w), float(omegas[int(np.argmax(e_w))]), dev15))
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
    p = out / "fig2b_error_after_jump_delta.png"
    fig.tight_layout()
    fig.savefig(p, dpi=120)
    plt.close(fig)
    write_caption(p, f"""
Fig. 2(b) of Li & Sanfelice: error right after the jump of H_n, formula (15) (lines), with engine \
runs (circles)
and the bound of Theorem 4.10 (dotted), for delta = 1 (blue) and delta = 3 (red). Paper values: \
a = -0.05,
L1 = 0.1, L2 = 0.2, delta in {{1, 3}}. The text only says (15) is evaluated for delta = 1 and 3; \
chosen here:
left, a constant noise of size m in [0, 1] (|e(delta,1)| = |T| m with |T| = {abs(lines[0][1]):.4f} \
for delta = 1,
{abs(lines[1][1]):.4f} for delta = 3: little sensitivity); right, a unit sinusoid \
m(t) = sin(omega t),
omega in [0.05, 6], where delta matters: the largest error is {lines[0][3]:.3f} \
(omega = {lines[0][4]:.2f}) for
delta = 1 and {lines[1][3]:.3f} (omega = {lines[1][4]:.2f}) for delta = 3. Theorem 4.10 bounds per \
unit
|m|_inf: {lines[0][2]:.2f} and {lines[1][2]:.2f}. Runs from x(0) = 1, x̂(0) = 0 (chosen; (15) does \
not depend
on them).""")
    paths.append(p)
    print(f"  Fig. 2(b): constant noise |e(delta,1)|/m = {abs(lines[0][1]):.4f} (delta=1), "
          f"{abs(lines[1][1]):.4f} "
          f"(delta=3); sinusoid max |e(delta,1)| = {lines[0][3]:.3f} (delta=1), "
          f"{lines[1][3]:.3f} (delta=3); "
          f"Thm 4.10 bound/|m| = {lines[0][2]:.3f}, {lines[1][2]:.3f}; max |(15) - engine| = "
          f"{max(lines[0][5], lines[1][5]):.1e}")

    # ---- Fig. 3: H_pc on the plant of Section V.B with piecewise-constant noise ------------------
    dB = example_VB()
    noise = PiecewiseConstantNoise([2.5, 4.5], [[0.3, 0.2], [0.4, 0.4], [0.2, 0.3]])
    obs = PiecewiseConstantNoiseObserver(dB)
    tf = 8.0
    arc = simulate_with_plant(obs, [0.3, 0.4], [0.0, 0.0], noise=noise, t_max=tf, refine=8, **_SIM)
    E = observer_errors(arc, obs)
    fig, axs = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    for i, col in ((0, "b"), (1, "r")):
        _plot_fn(axs[0], arc, lambda X, i=i: X[i], rf"$x_{i + 1}$", color=col, linestyle="--",
                 jumps=False)
        _plot_fn(axs[0], arc, _estimate(obs, i, 2), rf"$\bar x_{i + 1}$", color=col)
        _plot_fn(axs[1], arc, _error(obs, i, 2, sign=-1.0),
                 rf"$\bar e_{i + 1} = x_{i + 1} - \bar x_{i + 1}$", color=col)
        tt = np.linspace(0, tf, 801)
        axs[2].plot(tt, [noise(s)[i] for s in tt], col + "--", label=rf"$m_{i + 1}$")
        _plot_fn(axs[2], arc, _mhat(obs, i, 2), rf"$\hat m_{i + 1}$", color=col)
    for ax in axs:
        for s in noise.d:
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
    p = out / "fig3_Hpc_piecewise_noise.png"
    fig.tight_layout()
    fig.savefig(p, dpi=120)
    plt.close(fig)
    err = np.linalg.norm(E["ebar"], axis=1)
    msgs = []
    for k, d_k in enumerate([0.0, *noise.d]):
        J = int(np.flatnonzero(arc.jump_times >= d_k + dB.delta - 1e-9)[0])
        tJ = arc.jump_times[J]
        nxt = noise.d[k] if k < len(noise.d) else tf
        msk = ((arc.t > tJ) | ((arc.t == tJ) & (arc.j >= J + 1))) & (arc.t < nxt)
        msgs.append((d_k, tJ, float(err[msk].max())))
    write_caption(p, f"""
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
({msgs[2][2]:.1e}).""")
    paths.append(p)
    print("  Fig. 3: exact again (max |ē| until the next switch) " + "; ".join(
        f"after d={d_k:g}: from t={tJ:g} ({e:.1e})" for d_k, tJ, e in msgs)
        + f"; cond(HT-I) = {dB.HT_cond:.2f}, |(HT-I)^-1| = {dB.HT_inv_norm:.2f}")
    return paths
