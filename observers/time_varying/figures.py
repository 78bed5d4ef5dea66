r"""The figures of paper 001: ``reproduce(outdir)``.

Fig. 1 of the paper (the closed loop (44) under the output feedback (58))
and our figure of Section II (exactness of (15) and the noise bound (28) on
a random LTI system). Each PNG has a ``.txt`` caption beside it saying what
it shows, which values came from the paper and which were chosen.
"""
from __future__ import annotations

import pathlib

import numpy as np
from scipy import linalg

import hybridsim as hs

from .._common import write_caption
from .design import _n2, noise_gain
from .example import TAU_EXAMPLE, loop_signals, residual_58, tracking_initial_state, tracking_loop
from .systems import lti_observer

__all__ = ["reproduce"]


def reproduce(outdir, T=60.0):
    r"""Regenerate Fig. 1 (closed loop (44) with (58)) and an LTI exactness figure.

    Parameters
    ----------
    outdir : str or pathlib.Path
    T : float
        Horizon of Fig. 1 (default 60).

    Returns
    -------
    list of pathlib.Path
        The PNG files (each with a ``.txt`` caption next to it).
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    outdir = pathlib.Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    paths = []

    # ---- Fig. 1 --------------------------------------------------------------
    init = dict(xi4=1.0, xi3=-1.0, xi2=0.5, x1=0.5)
    loop, v2 = tracking_loop()
    arc = hs.simulate(loop, tracking_initial_state(loop, **init), t_max=T, rtol=1e-10, atol=1e-12,
                      progress=False, dense=True)
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
          f"{', '.join(f'{s:.6f}' for s in arc.jump_times)} (x1 -> 0 at 1/sqrt2 = {1 / np.sqrt(2):.6f}; "
          f"window filled at 2 pi)")
    print(f"[time_varying] |xhat2 - xi2|: max {err[before].max():.2e} on [2pi, 2pi + 1/sqrt2), "
          f"max {err[after].max():.2e} for t >= 2pi + 1/sqrt2")
    print(f"[time_varying] |zeta(t)|: {zn[0]:.3f} at 0, {zn[after][0]:.3f} at 2pi+1/sqrt2, {zn[-1]:.4f} at "
          f"t = {T:g}; last time above 0.05: {t_set:.2f}; max |v2| = {np.abs(S['v2']).max():.3f}; "
          f"(58) residual {max(abs(r) for r in res):.1e}")

    fig, ax = plt.subplots(4, 1, figsize=(7.5, 9.5), sharex=True)
    ax[0].plot(t, S["xi"][:, 0], label=r"$\xi_1$")
    ax[0].plot(t, 2 * np.sin(t), "k:", label=r"$\xi_{1r} = 2\sin t$")
    ax[0].plot(t, S["x1"], label=r"$x_1 = \xi_1 - 2\sin t$")
    ax[0].legend(loc="upper right", fontsize=8)
    for k, nm in ((3, r"$\xi_4$"), (2, r"$\xi_3$"), (1, r"$\xi_2$")):
        ax[1].plot(t, S["xi"][:, k], label=nm)
    ax[1].plot(t, S["xhat2"], "k--", lw=1, label=r"$\hat\xi_2$ (50)")
    ax[1].legend(loc="upper right", fontsize=8)
    ax[2].semilogy(t, np.maximum(err, 1e-16), label=r"$|\hat\xi_2 - \xi_2|$")
    ax[2].semilogy(t, np.maximum(zn, 1e-16), label=r"$|\zeta|$ (52)")
    for s, ls in ((TAU_EXAMPLE, ":"), (T0, "--")):
        for a in ax:
            a.axvline(s, color="gray", ls=ls, lw=0.8)
    ax[2].legend(loc="lower left", fontsize=8)
    ax[3].plot(t, S["v2"], label=r"$v_2$ (58)")
    ax[3].legend(loc="upper right", fontsize=8)
    ax[3].set_xlabel("t")
    fig.suptitle("Closed loop (44) with the output feedback (58)")
    fig.tight_layout()
    p1 = outdir / "fig1_closed_loop.png"
    fig.savefig(p1, dpi=120)
    plt.close(fig)
    write_caption(p1, f"""
Fig. 1 of Mazenc-Ahmed-Malisoff (CDC 2018): the chained form (40) under v1 of (43) and the output
feedback v2 of (58) (the bounded state feedback (57) with xi2 replaced by the reduced-order finite-time
estimate (50), tau = 2 pi, L(t) = -2 cos t, Lambda = 1 - e^(4 pi)), simulated with hybridsim.simulate
(RK45, rtol 1e-10, atol 1e-12) on t in [0, {T:g}].
Panels: (1) xi1 tracks 2 sin t: x1 = xi1 - 2 sin t reaches 0 at 1/sqrt(2) and stays there (41);
(2) xi4, xi3, xi2 and the estimate of xi2; (3) the estimation error and |zeta| of (52), log scale;
(4) the control v2 (|v2| < 1). Dotted line: t = 2 pi (the observer's window is filled; before it
the estimate is held at 0, our choice). Dashed line: t = 2 pi + 1/sqrt(2), from which the window lies
where x1 = 0 and (50) is exact (the printed range t >= max(2 pi, sqrt|x1(0)|) is too wide).
From the paper: x1(0) = 0.5, tau, L, sigma, (57)-(59). Chosen by us (not given in the paper):
xi4(0) = {init['xi4']}, xi3(0) = {init['xi3']}, xi2(0) = {init['xi2']}, the horizon, and the modelling of
x1's arrival at 0 as a jump (eta = 1e-10).
Measured: estimation error {err[before].max():.1e} on [2pi, 2pi + 1/sqrt2), {err[after].max():.1e} after;
|zeta| = {zn[0]:.2f} at t = 0, {zn[-1]:.3f} at t = {T:g}.
""")
    paths.append(p1)

    # ---- LTI exactness (Section II; our figure) --------------------------------
    rng = np.random.default_rng(0)
    A, C = rng.normal(size=(4, 4)), rng.normal(size=(2, 4))
    b = rng.normal(size=4)
    delta = lambda s: b * np.sin(2.0 * s)  # noqa: E731
    eps = lambda s: 0.01 * np.sin(np.array([5.0, 7.0]) * s)  # noqa: E731
    curves = []
    xp0 = rng.normal(size=4)
    for label, noise in (("exact (15), no noise", None), ("(27) with |eps| <= 0.01", eps)):
        obs, rc = lti_observer(A, C, tau=1.0, delta=delta)
        plant = hs.LinearPlant(A, C=C, disturbance=delta, noise=noise)
        sys = hs.connect(plant, obs)
        x0 = sys.stack(plant=xp0, observer=obs.initial_state())
        arc2 = hs.simulate(sys, x0, t_max=4.0, rtol=1e-10, atol=1e-12, progress=False)
        xp = arc2["plant"].x
        e2 = np.linalg.norm(obs.estimate(arc2.outputs("observer"), arc2.outputs("plant")) - rc.x_r(xp),
                            axis=1)
        curves.append((label, arc2.t, e2))
    H = rc.A2 + obs.L(0.0) @ rc.A1
    l_a = noise_gain(1.0, 1.0, rc.A1, rc.A2, obs.L(0.0), lambda s, r: linalg.expm(-rc.A2 * (s - r)),
                     lambda s, r: linalg.expm(-H * (s - r)), lip1=_n2(rc.A11), lip2=_n2(rc.A21))
    e_ex = curves[0][2][curves[0][1] >= 1.0].max()
    e_no = curves[1][2][curves[1][1] >= 1.0].max()
    print(f"[time_varying] LTI (n=4, p=2, seed 0, tau=1): max |xhat_r - x_r| for t >= tau: {e_ex:.1e} "
          f"(exact), {e_no:.2e} under noise vs l_a |eps|_inf = {l_a * 0.01:.2e} (l_a = {l_a:.2f})")
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for label, tt, ee in curves:
        ax.semilogy(tt, np.maximum(ee, 1e-16), label=label)
    ax.axhline(l_a * 0.01, color="k", ls=":", lw=1, label=r"$l_a |\epsilon|_\infty$ (28)")
    ax.axvline(1.0, color="gray", ls="--", lw=0.8)
    ax.set_xlabel("t")
    ax.set_ylabel(r"$|\hat x_r - x_r|$")
    ax.legend(fontsize=8)
    fig.tight_layout()
    p2 = outdir / "lti_exactness.png"
    fig.savefig(p2, dpi=120)
    plt.close(fig)
    write_caption(p2, f"""
Section II of Mazenc-Ahmed-Malisoff (not a figure of the paper; ours): a random observable LTI system
xdot = A x + b sin 2t, y = C x (n = 4, p = 2, numpy seed 0), observer (15) with tau = 1 and L placing
the eigenvalues of H = A2 + L A1 at -1, -1.5, x(0) drawn from the same seed (our choices). Error norm of the reduced-order estimate:
it is at the integrator's accuracy ({e_ex:.0e}) from t = tau on (dashed line); with measurement noise
eps = 0.01 (sin 5t, sin 7t), the approximate observer (27) stays below l_a |eps|_inf of (28)
(dotted line, l_a = {l_a:.2f} computed by noise_gain); max error after tau {e_no:.1e}.
""")
    paths.append(p2)
    return paths
