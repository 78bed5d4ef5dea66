r"""The figures of paper 001: ``reproduce(outdir)``.

Fig. 1 of the paper (the closed loop (44) under the output feedback (58))
and our figure of Section II (exactness of (15) and the noise bound (28) on
a random LTI system), drawn with :mod:`hybridsim`'s plots: flows solid,
jumps dotted from a filled (pre-jump) to an open (post-jump) circle,
references dashed or dash-dotted in grey/black, errors on log axes
(``fn=`` and ``yscale="log"``). Each PNG has a ``.txt`` caption beside it
saying what it shows, which values came from the paper and which were
chosen.

Examples
--------
>>> import tempfile, pathlib
>>> from observers.time_varying import reproduce
>>> paths = reproduce(tempfile.mkdtemp(), T=8.0)            # doctest: +SKIP
>>> [p.name for p in paths]                                   # doctest: +SKIP
['fig1_closed_loop.png', 'lti_exactness.png']
"""
from __future__ import annotations

import pathlib

import numpy as np
from scipy import linalg

import hybridsim as hs

from .._common import save_figure
from .design import _n2, noise_gain
from .example import (
    TAU_EXAMPLE,
    error_norm,
    errors,
    loop_signals,
    residual_58,
    simulate,
    tracking_initial_state,
    tracking_loop,
)
from .systems import lti_observer

__all__ = ["reproduce"]

#: Styles of the reference lines (distinct from the engine's dotted jumps).
_REF = dict(color="0.25", linewidth=0.9)
_FLOOR = 1e-16


def _time_band(axs, t0, t1, label):
    """A light band over [t0, t1) on every Axes, behind the curves (not a line: it
    cannot hide the dotted jump segments at t0)."""
    for k, a in enumerate(np.ravel(axs)):
        a.axvspan(t0, t1, color="0.88", zorder=0, linewidth=0, label=label if k == 0 else None)


def _fig1(outdir, T):
    import matplotlib.pyplot as plt

    init = dict(xi4=1.0, xi3=-1.0, xi2=0.5, x1=0.5)
    loop, v2 = tracking_loop()
    arc = hs.simulate(loop, tracking_initial_state(loop, **init), t_max=T, rtol=1e-10,
                      atol=1e-12, progress=False, dense=True)
    obs = loop.systems["observer"]
    S = loop_signals(arc, loop, v2)
    t = S["t"]
    T0 = TAU_EXAMPLE + np.sqrt(init["x1"])
    err = np.abs(S["xhat2"] - S["xi"][:, 1])
    before = (t >= TAU_EXAMPLE) & (t < T0)
    after = t >= T0
    zn = np.linalg.norm(S["zeta"], axis=1)
    k_set = np.flatnonzero(zn > 0.05)
    t_set = t[k_set[-1]] if k_set.size and k_set[-1] < len(t) - 1 else np.inf
    res = [residual_58(arc, loop, v2, s) for s in (TAU_EXAMPLE + 1.0, 0.5 * (TAU_EXAMPLE + T))]
    print(f"[time_varying] Fig. 1: run {arc.termination.name}, jumps at t = "
          f"{', '.join(f'{s:.6f}' for s in arc.jump_times)} (x1 -> 0 at 1/sqrt2 = "
          f"{1 / np.sqrt(2):.6f}; window filled at 2 pi)")
    print(f"[time_varying] |xhat2 - xi2|: max {err[before].max():.2e} on [2pi, 2pi + 1/sqrt2), "
          f"max {err[after].max():.2e} for t >= 2pi + 1/sqrt2")
    print(f"[time_varying] |zeta(t)|: {zn[0]:.3f} at 0, {zn[after][0]:.3f} at 2pi+1/sqrt2, "
          f"{zn[-1]:.4f} at t = {T:g}; last time above 0.05: {t_set:.2f}; max |v2| = "
          f"{np.abs(S['v2']).max():.3f}; (58) residual {max(abs(r) for r in res):.1e}")

    sl = loop.components["plant"]

    def xi1(x, t):                      # (42): xi1 = x1 + 2 sin t
        return x[sl][3] + 2 * np.sin(t)

    def xhat2(x, t, j):                 # (50) inside the loop: P + G xi3
        return obs.estimate(loop.outputs(x, t, j)["observer"], x[sl][1:2])[0]

    def zeta_norm(x, t):                # |zeta| of (52)
        p = x[sl]
        return max(float(np.linalg.norm([p[0] - 2 * np.sin(t) * p[1] - np.cos(2 * t) * p[2],
                                         p[1] - 2 * np.sin(t) * p[2], p[2]])), _FLOOR)

    def v2_of(x, t, j):                 # (58)
        return v2(t, loop.outputs(x, t, j))

    fig, ax = plt.subplots(4, 1, figsize=(7.5, 10.0), sharex=True)
    tt = np.linspace(0.0, T, 2000)
    hs.plot_flows(arc, fn=xi1, ax=ax[0], labels=[r"$\xi_1$"], ylabel=r"$\xi_1,\ x_1$",
                  xlabel="", legend=False)
    ax[0].plot(tt, 2 * np.sin(tt), "--", color="k", linewidth=0.9,
               label=r"$\xi_{1r} = 2\sin t$ (41)")
    hs.plot_flows(arc, sl.start + 3, ax=ax[0], labels=[r"$x_1 = \xi_1 - 2\sin t$ (42)"],
                  xlabel="", legend=False)
    hs.plot_flows(arc, [sl.start + k for k in (0, 1, 2)], ax=ax[1],
                  labels=[r"$\xi_4$", r"$\xi_3$", r"$\xi_2$"], ylabel="states", xlabel="",
                  legend=False)
    hs.plot_flows(arc, fn=xhat2, ax=ax[1], labels=[r"$\hat\xi_2$ (50)"], smooth=4, color="k",
                  flow_kw={"linewidth": 1.0, "linestyle": (0, (6, 2))}, xlabel="", legend=False)
    hs.plot_flows(arc, fn=error_norm(arc, obs, floor=_FLOOR), ax=ax[2], smooth=False,
                  labels=[r"$|\hat\xi_2 - \xi_2|$"], yscale="log", xlabel="", legend=False)
    hs.plot_flows(arc, fn=zeta_norm, ax=ax[2], labels=[r"$|\zeta|$ (52)"], yscale="log",
                  ylabel="error, norm", xlabel="", legend=False)
    hs.plot_flows(arc, fn=v2_of, ax=ax[3], labels=[r"$v_2$ (58)"], smooth=4, ylabel=r"$v_2$",
                  legend=False)
    _time_band(ax, TAU_EXAMPLE, T0, r"$[2\pi, 2\pi + 1/\sqrt{2})$: (50) not yet exact")
    for a, yl in zip(ax, (r"$\xi_1$, $x_1$", r"$\xi_4, \xi_3, \xi_2, \hat\xi_2$",
                          "error, norm (log)", r"$v_2$")):
        a.set_ylabel(yl)
    ax[0].legend(loc="upper right", fontsize=7, ncol=2)
    for a in ax[1:]:
        a.legend(loc="upper right", fontsize=7, ncol=2)
    ax[0].set_ylim(-2.6, 3.4)
    ax[2].set_ylim(1e-16, 1e3)
    fig.suptitle("Closed loop (44) with the output feedback (58)")
    fig.tight_layout()
    caption = f"""
Fig. 1 of Mazenc-Ahmed-Malisoff (CDC 2018): the chained form (40) under v1 of (43) and the output
feedback v2 of (58) (the bounded state feedback (57) with xi2 replaced by the reduced-order \
finite-time
estimate (50), tau = 2 pi, L(t) = -2 cos t, Lambda = 1 - e^(4 pi)), simulated with \
hybridsim.simulate
(RK45, rtol 1e-10, atol 1e-12) on t in [0, {T:g}] and drawn with hybridsim.plot_flows.
Panels: (1) xi1 tracks 2 sin t (dashed, the reference (41)): x1 = xi1 - 2 sin t reaches 0 at
1/sqrt(2) and stays there; (2) xi4, xi3, xi2 and the estimate of xi2 (black, long dashes);
(3) the estimation error and |zeta| of (52), log scale, the error drawn at the solver's samples;
(4) the control v2 (|v2| < 1).
Jumps of the hybrid solution (x1's arrival at 0 at t = 0.707, modelled as a jump; the observer's
window filling at t = 2 pi) are dotted segments from a filled circle (before) to an open circle
(after); a jump that leaves a curve unchanged shows the two circles only.
Grey band: [2 pi, 2 pi + 1/sqrt(2)): the observer's window is filled at 2 pi (its jump; before it
the estimate is held at 0, our choice) but reaches back to where x1 != 0, so (50) is exact only from
the band's right end on (the printed range t >= max(2 pi, sqrt|x1(0)|) is too wide).
From the paper: x1(0) = 0.5, tau, L, sigma, (57)-(59). Chosen by us (not given in the paper):
xi4(0) = {init['xi4']}, xi3(0) = {init['xi3']}, xi2(0) = {init['xi2']}, the horizon, and the \
modelling of
x1's arrival at 0 as a jump (eta = 1e-10).
Measured: estimation error {err[before].max():.1e} on [2pi, 2pi + 1/sqrt2), {err[after].max():.1e} \
after;
|zeta| = {zn[0]:.2f} at t = 0, {zn[-1]:.3f} at t = {T:g}.
"""
    return save_figure(fig, outdir, "fig1_closed_loop", caption)


def _fig_lti(outdir):
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(0)
    A, C = rng.normal(size=(4, 4)), rng.normal(size=(2, 4))
    b = rng.normal(size=4)
    xp0 = rng.normal(size=4)

    def delta(s):
        return b * np.sin(2.0 * s)

    def eps(s):
        return 0.01 * np.sin(np.array([5.0, 7.0]) * s)

    runs = []
    for label, noise in (("exact (15), no noise", None),
                         (r"(27) with $|\epsilon| \leq 0.01$", eps)):
        obs, rc = lti_observer(A, C, tau=1.0, delta=delta)
        arc = simulate(obs, xp0, t_max=4.0, noise=noise)
        runs.append((label, arc, obs, np.linalg.norm(errors(arc, obs), axis=1)))
    H = rc.A2 + obs.L(0.0) @ rc.A1
    l_a = noise_gain(1.0, 1.0, rc.A1, rc.A2, obs.L(0.0), lambda s, r: linalg.expm(-rc.A2 * (s - r)),
                     lambda s, r: linalg.expm(-H * (s - r)), lip1=_n2(rc.A11), lip2=_n2(rc.A21))
    # t >= tau after the observer's jump (j >= 1): the pre-jump sample at t = tau still holds
    # xr_init
    e_ex = runs[0][3][runs[0][1].j >= 1].max()
    e_no = runs[1][3][runs[1][1].j >= 1].max()
    print(f"[time_varying] LTI (n=4, p=2, seed 0, tau=1): max |xhat_r - x_r| for t >= tau: "
          f"{e_ex:.1e} (exact), {e_no:.2e} under noise vs l_a |eps|_inf = {l_a * 0.01:.2e} "
          f"(l_a = {l_a:.2f})")
    fig, ax = plt.subplots(figsize=(7, 3.8))
    for label, arc, obs, _ in runs:
        hs.plot_flows(arc, fn=error_norm(arc, obs, floor=_FLOOR), ax=ax, smooth=False,
                      labels=[label], yscale="log", legend=False)
    ax.axhline(l_a * 0.01, linestyle="--", label=r"$l_a |\epsilon|_\infty$ (28)", **_REF)
    ax.annotate(r"$t = \tau$: the observer's jump", xy=(1.0, 1e-7), xytext=(1.25, 1e-7),
                fontsize=8, va="center", arrowprops=dict(arrowstyle="->", color="0.25", lw=0.8))
    ax.set_ylabel(r"$|\hat x_r - x_r|$")
    ax.set_ylim(1e-14, 10.0)
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    caption = f"""
Section II of Mazenc-Ahmed-Malisoff (not a figure of the paper; ours): a random observable LTI \
system
xdot = A x + b sin 2t, y = C x (n = 4, p = 2, numpy seed 0), observer (15) with tau = 1 and L \
placing
the eigenvalues of H = A2 + L A1 at -1, -1.5, x(0) drawn from the same seed (our choices), run with
observers.time_varying.simulate (RK45, rtol 1e-10, atol 1e-12). Error norm of the reduced-order
estimate at the solver's samples, log scale: before tau the estimate is held at 0 (both runs
coincide there); at t = tau the observer jumps (dotted segment, filled circle before, open circle
after) and the error is at the integrator's accuracy ({e_ex:.0e}) from then on. With measurement \
noise
eps = 0.01 (sin 5t, sin 7t), the approximate observer (27) stays below l_a |eps|_inf of (28)
(dashed, l_a = {l_a:.2f} computed by noise_gain); max error after tau {e_no:.1e}.
"""
    return save_figure(fig, outdir, "lti_exactness", caption)


def reproduce(outdir, T=60.0):
    r"""Regenerate Fig. 1 (closed loop (44) with (58)) and an LTI exactness figure.

    Parameters
    ----------
    outdir : str or pathlib.Path
        Folder for the PNGs (created if missing).
    T : float
        Horizon of Fig. 1 (default 60).

    Returns
    -------
    list of pathlib.Path
        The PNG files (each with a ``.txt`` caption next to it).
    """
    import matplotlib
    matplotlib.use("Agg")

    outdir = pathlib.Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    return [_fig1(outdir, T), _fig_lti(outdir)]
