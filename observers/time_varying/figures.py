r"""The figures of paper 001: ``FIGURES`` (their numbers, then their drawing) and ``reproduce``.

Fig. 1 of the paper (the closed loop (44) under the output feedback (58))
and our figure of Section II (exactness of (15) and the noise bound (28) on
a random LTI system). Each :class:`observers._common.Figure` computes its
numbers once (:func:`fig1_data`, :func:`lti_data`, cached: the claims read
the same runs) and draws them with :mod:`hybridsim`'s plots: flows solid,
jumps dotted from a filled (pre-jump) to an open (post-jump) circle,
references dashed in grey/black, errors on log axes. Each PNG has a
``.txt`` caption beside it saying what it shows, which values came from
the paper and which were chosen. What the runs measure goes to this
module's logger.

Examples
--------
>>> from observers.time_varying import FIGURES
>>> [f.name for f in FIGURES]
['fig1_closed_loop', 'lti_exactness']
>>> d = fig1_data(8.0)                       # a short run of the loop of Fig. 1
>>> bool(d.err_band < 1e-5), bool(d.err_after < 1e-8)
(True, True)
"""
from __future__ import annotations

import dataclasses
import functools
import logging

import numpy as np
from scipy import linalg

import hybridsim as hs

from .._common import Figure, reproduce_figures
from .design import TAU_EXAMPLE, _n2, noise_gain, residual_58
from .example import (
    errors,
    loop_functions,
    loop_signals,
    simulate,
    tracking_initial_state,
)
from .systems import lti_observer, tracking_loop

__all__ = ["FIGURES", "NOT_REPRODUCED", "reproduce", "Fig1Data", "fig1_data", "LtiData",
           "lti_data"]

log = logging.getLogger(__name__)

#: Styles of the reference lines (distinct from the engine's dotted jumps).
_REF = dict(color="0.25", linewidth=0.9)
#: Floor of the errors on log axes (an exact zero cannot be drawn there).
_FLOOR = 1e-16
#: Initial state of Fig. 1: x1(0) = 0.5 is the paper's, the others ours.
_INIT = dict(xi4=1.0, xi3=-1.0, xi2=0.5, x1=0.5)

#: The paper's figures left out (none: Fig. 1 is its only figure).
NOT_REPRODUCED = {}


# ---------------------------------------------------------------------------
# Fig. 1: the closed loop (44) + (58)
# ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Fig1Data:
    r"""The numbers of Fig. 1: one run of the loop (44) + (58) and what it measures.

    Attributes
    ----------
    T : float
        Horizon.
    init : dict
        xi4(0), xi3(0), xi2(0), x1(0).
    arc, loop, v2
        The run (dense), the interconnection and its control (58).
    signals : dict
        :func:`~observers.time_varying.loop_signals` of the run.
    T0 : float
        2 pi + sqrt|x1(0)|: from then on (50) is exact.
    err : ndarray
        |xhat2 - xi2| at the samples.
    err_band, t_band : float
        The largest error of (50) on [2 pi, T0) once the observer's window
        is filled (its jump at 2 pi; before it the estimate is held at
        ``xr_init``), and where it is.
    err_after : float
        The largest error for t >= T0.
    zeta_norm : ndarray
        |zeta| of (52) at the samples.
    t_settle : float
        The last sampled time with |zeta| > 0.05 (inf if none).
    v2_max : float
        max |v2| along the run.
    residual : float
        The largest |residual of (58)| at t = 2 pi + 1 and (2 pi + T) / 2.
    ref_t, ref_xi1 : ndarray
        The reference xi1r = 2 sin t of (41) on a fine grid.
    """

    T: float
    init: dict
    arc: object
    loop: object
    v2: object
    signals: dict
    T0: float
    err: np.ndarray
    err_band: float
    t_band: float
    err_after: float
    zeta_norm: np.ndarray
    t_settle: float
    v2_max: float
    residual: float
    ref_t: np.ndarray
    ref_xi1: np.ndarray


@functools.cache
def fig1_data(T=60.0):
    r"""Run the loop (44) + (58) of Fig. 1 on [0, T] and measure it (cached per T).

    RK45 at rtol 1e-10, atol 1e-12, dense output (for (58) evaluated
    literally); x1(0) = 0.5 (paper), xi4(0) = 1, xi3(0) = -1, xi2(0) = 0.5
    (ours).

    Parameters
    ----------
    T : float
        Horizon (60 in the figure; the tests use shorter runs, whose
        samples are the same as the first samples of the long one).

    Returns
    -------
    Fig1Data
    """
    loop, v2 = tracking_loop()
    arc = hs.simulate(loop, tracking_initial_state(loop, **_INIT), t_max=T, rtol=1e-10,
                      atol=1e-12, progress=False, dense=True)
    S = loop_signals(arc, loop, v2)
    t = S["t"]
    T0 = TAU_EXAMPLE + np.sqrt(_INIT["x1"])
    err = np.abs(S["xhat2"] - S["xi"][:, 1])
    band = (t >= TAU_EXAMPLE) & (t < T0) & S["filled"]
    kb = np.flatnonzero(band)[np.argmax(err[band])]
    err_after = float(err[t >= T0].max()) if np.any(t >= T0) else np.nan
    zn = np.linalg.norm(S["zeta"], axis=1)
    k_set = np.flatnonzero(zn > 0.05)
    t_set = float(t[k_set[-1]]) if k_set.size and k_set[-1] < len(t) - 1 else np.inf
    funs = loop_functions(arc, loop, v2)
    res = max(abs(residual_58(s, *funs, points=arc.jump_times))
              for s in (TAU_EXAMPLE + 1.0, 0.5 * (TAU_EXAMPLE + T)))
    ref_t = np.linspace(0.0, T, 2000)
    d = Fig1Data(T=float(T), init=dict(_INIT), arc=arc, loop=loop, v2=v2, signals=S, T0=T0,
                 err=err, err_band=float(err[kb]), t_band=float(t[kb]), err_after=err_after,
                 zeta_norm=zn, t_settle=t_set, v2_max=float(np.abs(S["v2"]).max()),
                 residual=float(res), ref_t=ref_t, ref_xi1=2 * np.sin(ref_t))
    log.info("Fig. 1: run %s, jumps at t = %s (x1 -> 0 at 1/sqrt2 = %.6f; window filled at "
             "2 pi)", arc.termination.name, ", ".join(f"{s:.6f}" for s in arc.jump_times),
             1 / np.sqrt(2))
    log.info("|xhat2 - xi2| of (50): max %.2e on [2pi, 2pi + 1/sqrt2) once the window is filled "
             "(at t = %.6f), max %.2e for t >= 2pi + 1/sqrt2", d.err_band, d.t_band, err_after)
    log.info("|zeta(t)|: %.3f at 0, %.3f at 2pi+1/sqrt2, %.4f at t = %g; last time above 0.05: "
             "%.2f; max |v2| = %.3f; (58) residual %.1e", zn[0],
             zn[t >= T0][0] if np.any(t >= T0) else np.nan, zn[-1], T, t_set, d.v2_max, res)
    return d


def _time_band(axs, t0, t1, label):
    """A light band over [t0, t1) on every Axes, behind the curves (not a line: it
    cannot hide the dotted jump segments at t0)."""
    for k, a in enumerate(np.ravel(axs)):
        a.axvspan(t0, t1, color="0.88", zorder=0, linewidth=0, label=label if k == 0 else None)


def draw_fig1(d):
    """Fig. 1 from :func:`fig1_data`: four panels against t (a matplotlib Figure)."""
    from matplotlib.figure import Figure as MplFigure

    arc, S = d.arc, d.signals
    sl = d.loop.components["plant"]
    fig = MplFigure(figsize=(7.5, 10.0))
    ax = fig.subplots(4, 1, sharex=True)
    hs.plot_flows(arc, S["xi"][:, 0], ax=ax[0], labels=[r"$\xi_1$"], ylabel=r"$\xi_1,\ x_1$",
                  xlabel="", legend=False)
    ax[0].plot(d.ref_t, d.ref_xi1, "--", color="k", linewidth=0.9,
               label=r"$\xi_{1r} = 2\sin t$ (41)")
    hs.plot_flows(arc, sl.start + 3, ax=ax[0], labels=[r"$x_1 = \xi_1 - 2\sin t$ (42)"],
                  xlabel="", legend=False)
    hs.plot_flows(arc, [sl.start + k for k in (0, 1, 2)], ax=ax[1],
                  labels=[r"$\xi_4$", r"$\xi_3$", r"$\xi_2$"], ylabel="states", xlabel="",
                  legend=False)
    hs.plot_flows(arc, S["xhat2"], ax=ax[1], labels=[r"$\hat\xi_2$ (50)"], color="k",
                  flow_kw={"linewidth": 1.0, "linestyle": (0, (6, 2))}, xlabel="", legend=False)
    hs.plot_flows(arc, np.maximum(d.err, _FLOOR), ax=ax[2], labels=[r"$|\hat\xi_2 - \xi_2|$"],
                  yscale="log", xlabel="", legend=False)
    hs.plot_flows(arc, np.maximum(d.zeta_norm, _FLOOR), ax=ax[2], labels=[r"$|\zeta|$ (52)"],
                  yscale="log", ylabel="error, norm", xlabel="", legend=False)
    hs.plot_flows(arc, S["v2"], ax=ax[3], labels=[r"$v_2$ (58)"], ylabel=r"$v_2$",
                  legend=False)
    _time_band(ax, TAU_EXAMPLE, d.T0, r"$[2\pi, 2\pi + 1/\sqrt{2})$: (50) not yet exact")
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
    return fig


def caption_fig1(d):
    """The caption of Fig. 1, with the numbers the run measured."""
    init = d.init
    return f"""
Fig. 1 of Mazenc-Ahmed-Malisoff (CDC 2018): the chained form (40) under v1 of (43) and the output
feedback v2 of (58) (the bounded state feedback (57) with xi2 replaced by the reduced-order \
finite-time
estimate (50), tau = 2 pi, L(t) = -2 cos t, Lambda = 1 - e^(4 pi)), simulated with \
hybridsim.simulate
(RK45, rtol 1e-10, atol 1e-12) on t in [0, {d.T:g}] and drawn with hybridsim.plot_flows.
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
Measured: error of (50) once the window is filled {d.err_band:.1e} on [2pi, 2pi + 1/sqrt2) \
(largest
at t = {d.t_band:.4f} = 2 pi, just after the window fills; the sample before that jump holds the \
initial 0),
{d.err_after:.1e} after; |zeta| = {d.zeta_norm[0]:.2f} at t = 0, {d.zeta_norm[-1]:.3f} at \
t = {d.T:g}.
"""


# ---------------------------------------------------------------------------
# our figure of Section II: a random LTI system
# ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class LtiData:
    r"""The numbers of the LTI figure: two runs of the observer (15)/(27) and the bound (28).

    Attributes
    ----------
    runs : tuple of (label, arc, error norm at the samples)
        Without noise (the exact (15)) and with eps = 0.01 (sin 5t, sin 7t)
        (the approximate observer (27)).
    l_a : float
        l_a of (28) by :func:`~observers.time_varying.noise_gain` (constant
        data: l(t) is constant, so l_a = l(tau)).
    e_exact, e_noise : float
        The largest error for t >= tau (after the observer's jump) of each run.
    """

    runs: tuple
    l_a: float
    e_exact: float
    e_noise: float


@functools.cache
def lti_data():
    r"""Run the LTI observer of Section II (n = 4, p = 2, numpy seed 0, tau = 1) twice.

    Returns
    -------
    LtiData
    """
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
        runs.append((label, arc, errors(arc, obs).norm()))
    H = rc.A2 + obs.L(0.0) @ rc.A1
    l_a = noise_gain(1.0, 1.0, rc.A1, rc.A2, obs.L(0.0), lambda s, r: linalg.expm(-rc.A2 * (s - r)),
                     lambda s, r: linalg.expm(-H * (s - r)), lip1=_n2(rc.A11), lip2=_n2(rc.A21))
    # t >= tau after the observer's jump (j >= 1): the pre-jump sample at t = tau still holds
    # xr_init
    e_ex = float(runs[0][2][runs[0][1].j >= 1].max())
    e_no = float(runs[1][2][runs[1][1].j >= 1].max())
    log.info("LTI (n=4, p=2, seed 0, tau=1): max |xhat_r - x_r| for t >= tau: %.1e (exact), "
             "%.2e under noise vs l_a |eps|_inf = %.2e (l_a = %.2f)", e_ex, e_no, l_a * 0.01, l_a)
    return LtiData(runs=tuple(runs), l_a=float(l_a), e_exact=e_ex, e_noise=e_no)


def draw_lti(d):
    """The LTI figure from :func:`lti_data`: error norms against t, log scale."""
    from matplotlib.figure import Figure as MplFigure

    fig = MplFigure(figsize=(7, 3.8))
    ax = fig.subplots()
    for label, arc, e in d.runs:
        hs.plot_flows(arc, np.maximum(e, _FLOOR), ax=ax, labels=[label], yscale="log",
                      legend=False)
    ax.axhline(d.l_a * 0.01, linestyle="--", label=r"$l_a |\epsilon|_\infty$ (28)", **_REF)
    ax.annotate(r"$t = \tau$: the observer's jump", xy=(1.0, 1e-7), xytext=(1.25, 1e-7),
                fontsize=8, va="center", arrowprops=dict(arrowstyle="->", color="0.25", lw=0.8))
    ax.set_ylabel(r"$|\hat x_r - x_r|$")
    ax.set_ylim(1e-14, 10.0)
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    return fig


def caption_lti(d):
    """The caption of the LTI figure."""
    return f"""
Section II of Mazenc-Ahmed-Malisoff (not a figure of the paper; ours): a random observable LTI \
system
xdot = A x + b sin 2t, y = C x (n = 4, p = 2, numpy seed 0), observer (15) with tau = 1 and L \
placing
the eigenvalues of H = A2 + L A1 at -1, -1.5, x(0) drawn from the same seed (our choices), run with
observers.time_varying.simulate (RK45, rtol 1e-10, atol 1e-12). Error norm of the reduced-order
estimate at the solver's samples, log scale: before tau the estimate is held at 0 (both runs
coincide there); at t = tau the observer jumps (dotted segment, filled circle before, open circle
after) and the error is at the integrator's accuracy ({d.e_exact:.0e}) from then on. With \
measurement noise
eps = 0.01 (sin 5t, sin 7t), the approximate observer (27) stays below l_a |eps|_inf of (28)
(dashed, l_a = {d.l_a:.2f} computed by noise_gain); max error after tau {d.e_noise:.1e}.
"""


#: The figures, in the order the report shows them.
FIGURES = [
    Figure(name="fig1_closed_loop", title="Fig. 1", data=fig1_data, draw=draw_fig1,
           caption=caption_fig1),
    Figure(name="lti_exactness", title="Exactness of (15) and the bound (28), LTI (ours)",
           data=lti_data, draw=draw_lti, caption=caption_lti),
]


def reproduce(outdir):
    r"""Write Fig. 1 (closed loop (44) with (58)) and the LTI figure into ``outdir``.

    Parameters
    ----------
    outdir : str or pathlib.Path
        An existing folder.

    Returns
    -------
    list of pathlib.Path
        The PNG files (each with a ``.txt`` caption next to it).
    """
    return reproduce_figures(FIGURES, outdir)
