"""The figures of paper 003: Figs. 2-3 of Section 4, each as data, drawing and caption.

:data:`FIGURES` lists them as :class:`observers._common.Figure`;
:func:`fig2_data` and :func:`fig3_data` compute their numbers once
(``functools.cache``: the claims read the same runs), :func:`draw_fig2` /
:func:`draw_fig3` draw them, :func:`reproduce` writes the PNGs. The
mathematics lives in :mod:`~observers.distributed.design`,
:mod:`~observers.distributed.systems` and :mod:`~observers.distributed.example`.

Examples
--------
>>> from observers.distributed import FIGURES, NOT_REPRODUCED
>>> [f.name for f in FIGURES], list(NOT_REPRODUCED)
(['distributed_fig2', 'distributed_fig3'], ['Fig. 1'])
"""
from __future__ import annotations

import dataclasses
import functools
import logging

import numpy as np

from .._common import Figure, reproduce_figures
from .design import lmi11, proposition1_lyapunov
from .example import (
    EXAMPLE_V0,
    _settling,
    _state_errors,
    band_limited_noise,
    errors,
    example_observer,
    settling_time,
    simulate,
    simulate_errors,
    stable_initial_state,
)

__all__ = ["SETTLE_THRESHOLD", "Fig2Data", "Fig3Data", "fig2_data", "fig3_data",
           "error_system_settling", "draw_fig2", "draw_fig3", "caption_fig2", "caption_fig3",
           "FIGURES", "NOT_REPRODUCED", "reproduce"]

log = logging.getLogger(__name__)

# Fig. 2's horizon (s); Fig. 3's (s).
_T_MAX, _T_MAX_NOISE = 20.0, 10.0
#: Theorem 1's threshold on max |e| (claims 003-thm1-settle*).
SETTLE_THRESHOLD = 1e-8
#: hybridsim.plot_flows' sampling of an arc (points inserted in each step so
#: that about 50 000 points are drawn, at most 20 per step): kept so that the
#: curves are those the figures drew before they were data.
_MAX_POINTS, _POINTS_PER_STEP = 50_000, 20


def _x0():
    obs = example_observer()
    return stable_initial_state(obs.design.A, EXAMPLE_V0)


def _resample(arc):
    """Times and states of ``arc`` at its samples and at points of its interpolant
    inside each step (``hybridsim.plot_flows``' sampling; a flow-only arc)."""
    t = np.asarray(arc.t)
    N = t.size
    m = int(np.clip(_MAX_POINTS // max(N, 1) - 1, 0, _POINTS_PER_STEP))
    if m == 0 or N < 2:
        return t, np.asarray(arc.x)
    frac = np.arange(1, m + 1) / (m + 1)
    ti = t[:-1, None] + (t[1:] - t[:-1])[:, None] * frac
    ti = np.minimum(ti, t[1:, None])
    Xi = np.asarray(arc.at(ti.ravel(), np.repeat(arc.j[:-1], m)), dtype=float)
    Xi = Xi.reshape(N - 1, m, -1)
    T = np.concatenate([t[:-1, None], ti], axis=1).ravel()
    X = np.concatenate([np.asarray(arc.x)[:-1, None, :], Xi], axis=1).reshape(-1, Xi.shape[2])
    return np.append(T, t[-1]), np.vstack([X, arc.x[-1]])


def _node_errors(arc, obs):
    """Times and per-node errors (e_o^i, e_u^i) of (6) on the resampled arc."""
    t, X = _resample(arc)
    if "noise" in arc:
        X = np.delete(X, np.arange(X.shape[1])[arc.components["noise"]], axis=1)
    e_o, e_u = _state_errors(X, obs.design, from_network=True)
    return t, e_o, e_u


def _norms(parts):
    """Euclidean norm of each node's part, floored at 1e-18 for the log scale: (K, N)."""
    return np.column_stack([np.maximum(np.linalg.norm(p, axis=1), 1e-18) for p in parts])


@functools.cache
def error_system_settling():
    """Theorem 1's settling time on the example: the last time max |e| of the error
    system (6)-(9) (simulated alone, RK45 rtol 1e-10, atol 1e-14, to t = 6.8 s)
    exceeds :data:`SETTLE_THRESHOLD` (s)."""
    obs = example_observer()
    return settling_time(simulate_errors(obs, _x0(), t_max=6.8), obs, SETTLE_THRESHOLD)


@dataclasses.dataclass(frozen=True)
class Fig2Data:
    """Numbers of Fig. 2: the errors' norms of the example's network runs.

    ``t``, ``eo_norm``, ``eu_norm``: finite-time observer (7)-(8), (K,), (K, 4)
    and (K, 4) (``‖e_o^i‖``, ``‖e_u^i‖`` per node, floored at 1e-18);
    ``t_lin``, ``eu_norm_lin``: the linear observer (3); ``settle`` the first
    sample time after which max |e| stays below 1e-10; ``final``,
    ``final_lin``: max |e| at the end; ``settle_errors``: the error system's
    1e-8 crossing (:func:`error_system_settling`); ``settle_network``: the
    same crossing in the plant-observer run (claim 003-thm1-settle-network).
    """

    nodes: list
    t: np.ndarray
    eo_norm: np.ndarray
    eu_norm: np.ndarray
    t_lin: np.ndarray
    eu_norm_lin: np.ndarray
    settle: float
    final: float
    final_lin: float
    settle_errors: float
    settle_network: float


@functools.cache
def fig2_data():
    """Fig. 2: the example's finite-time network (7)-(8) and linear network (3), no noise.

    Runs ``simulate`` to 20 s (RK45, rtol 1e-10, atol 1e-13) for both
    observers and logs the design's facts (n_i, Proposition 2's bound,
    Proposition 1, LMI (11)).

    Returns
    -------
    Fig2Data
    """
    ft, lin = example_observer(), example_observer("linear")
    dsg = ft.design
    res = lmi11(dsg)
    _, margin1 = proposition1_lyapunov(dsg)
    log.info("n_i = %s; Prop. 2 bound nu_min = %s; nu = -0.1 meets it: %s", dsg.n_o,
             [float(f"{v:.3g}") for v in dsg.nu_min], dsg.meets_proposition2.tolist())
    log.info("Prop. 1 diagonal P = diag(r_i I), margin %.3g; LMI (11) at alpha = 10: "
             "feasible=%s, max eig Phi = %.3g", margin1, res.feasible, res.max_eig_Phi)
    x0 = _x0()
    arc = simulate(ft, x0, t_max=_T_MAX)
    arcl = simulate(lin, x0, t_max=_T_MAX)
    E, El = errors(arc, ft), errors(arcl, lin)
    ts = _settling(E.t, E["norm"], 1e-10)
    log.info("finite-time: errors < 1e-10 for t >= %.3f (final %.2e); linear (3): final "
             "error %.2e", ts, E["norm"][-1], El["norm"][-1])
    t, e_o, e_u = _node_errors(arc, ft)
    tl, _, e_ul = _node_errors(arcl, lin)
    return Fig2Data(nodes=list(dsg.nodelist), t=t, eo_norm=_norms(e_o), eu_norm=_norms(e_u),
                    t_lin=tl, eu_norm_lin=_norms(e_ul), settle=ts,
                    final=float(E["norm"][-1]), final_lin=float(El["norm"][-1]),
                    settle_errors=error_system_settling(),
                    settle_network=settling_time(arc, ft, SETTLE_THRESHOLD))


def draw_fig2(d: Fig2Data):
    """Fig. 2: ‖e_o^i‖ (top) and ‖e_u^i‖ (bottom), semi-log; dotted: the linear observer."""
    from matplotlib.figure import Figure as MplFigure
    fig = MplFigure(figsize=(7, 6))
    ax = fig.subplots(2, 1, sharex=True)
    for k, v in enumerate(d.nodes):
        ax[0].plot(d.t, d.eo_norm[:, k], color=f"C{k}", label=f"node {v}")
        ax[1].plot(d.t, d.eu_norm[:, k], color=f"C{k}", label=f"node {v}")
    for k in range(len(d.nodes)):
        ax[1].plot(d.t_lin, d.eu_norm_lin[:, k], color=f"C{k}", linestyle=":", linewidth=0.8,
                   label="_nolegend_")
    for a in ax:
        a.set_yscale("log")
        a.set_ylim(1e-16, None)
    ax[0].set_ylabel(r"$\|e_o^i\|$")
    ax[1].set_ylabel(r"$\|e_u^i\|$")
    ax[1].set_xlabel(r"$t$ (s)")
    ax[0].set_title("Fig. 2: errors in transformed coordinates, finite-time observer (7)-(8)")
    ax[0].legend(fontsize=7, ncol=2)
    ax[1].plot([], [], "k:", lw=0.8, label="linear observer (3)")
    ax[1].plot([], [], "k-", label="finite-time (7)-(8)")
    ax[1].legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    return fig


def caption_fig2(d: Fig2Data):
    return (
        "Fig. 2 of Silm et al. (2020): norms of the errors e_o^i (top) and e_u^i (bottom) of "
        "the finite-time distributed observer (7)-(8), semi-log, no noise; dotted: the "
        "linear observer (3) with the same gains (exponential only).\n"
        "From the paper: A, C1..C4, observable-part eigenvalues -3 (at nu=0), nu_i = -0.1, "
        "alpha_i = 10, beta = 0.7.\n"
        "Our choices: graph 1->2->3->4->1 (Fig. 1 is missing from the text); x(0) = "
        "projection of (1,-1,0.5,0,1,-0.5) on A's stable subspace (keeps |x| small so "
        "that rounding of x_hat - x stays below 1e-10); x_hat^i(0) = 0; RK45, "
        f"rtol=1e-10, atol=1e-13. Errors < 1e-10 for t >= {d.settle:.2f}; what remains "
        "(~1e-12) is the rounding of x_hat - x, not error. The error system (6)-(9) "
        "simulated alone (no plant, no floor) has max|e| < 1e-8 from "
        f"t = {d.settle_errors:.4f} s (claim 003-thm1-settle, checked against scipy's "
        "solve_ivp).\n")


@dataclasses.dataclass(frozen=True)
class Fig3Data:
    """Numbers of Fig. 3: the components of e_o^i and e_u^i under measurement noise.

    ``t`` (K,); ``e_o``, ``e_u``: per node, (K, n_i) and (K, n − n_i);
    ``peak_late``: max |e| over the second half of the run.
    """

    nodes: list
    t: np.ndarray
    e_o: list
    e_u: list
    peak_late: float


@functools.cache
def fig3_data():
    """Fig. 3: the finite-time network under band-limited white noise of power 1e-2.

    Noise sample time 0.1 s, seed 0, 10 s, RK45 rtol 1e-8, atol 1e-10,
    max_step 0.05.

    Returns
    -------
    Fig3Data
    """
    ft = example_observer()
    noise = band_limited_noise(1e-2, 0.1, _T_MAX_NOISE, ft.design.N, seed=0)
    arcn = simulate(ft, _x0(), t_max=_T_MAX_NOISE, noise=noise, max_step=0.05,
                    rtol=1e-8, atol=1e-10)
    En = errors(arcn, ft)
    peak = float(En["norm"][En.t >= _T_MAX_NOISE / 2].max())
    log.info("noise (power 1e-2): max error over t >= %g: %.3g", _T_MAX_NOISE / 2, peak)
    t, e_o, e_u = _node_errors(arcn, ft)
    return Fig3Data(nodes=list(ft.design.nodelist), t=t, e_o=e_o, e_u=e_u, peak_late=peak)


def draw_fig3(d: Fig3Data):
    """Fig. 3: the components of e_o^i (top) and e_u^i (bottom), linear scale."""
    from matplotlib.figure import Figure as MplFigure
    fig = MplFigure(figsize=(7, 6))
    ax = fig.subplots(2, 1, sharex=True)
    for k, v in enumerate(d.nodes):
        for a, part in zip(ax, (d.e_o[k], d.e_u[k])):
            for c in range(part.shape[1]):
                a.plot(d.t, part[:, c], color=f"C{k}", linewidth=0.8,
                       label=f"node {v}" if c == 0 else "_nolegend_")
    ax[0].set_ylabel(r"$e_o^i$ (components)")
    ax[1].set_ylabel(r"$e_u^i$ (components)")
    ax[1].set_xlabel(r"$t$ (s)")
    ax[0].set_title("Fig. 3: errors with measurement noise of power 1e-2")
    ax[0].legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return fig


def caption_fig3(d: Fig3Data):
    return (
        "Fig. 3 of Silm et al. (2020): components of e_o^i (top) and e_u^i (bottom), "
        "linear scale, with band-limited white noise of power 1e-2 added to each output "
        "(Remark 2: errors stay bounded).\n"
        "From the paper: as Fig. 2, noise power 1e-2.\n"
        "Our choices: noise sample time 0.1 s (variance power/ts = 0.1, Simulink's "
        "convention), samples joined linearly, seed 0; graph, x(0), x_hat(0) as Fig. 2; "
        "RK45 rtol=1e-8, atol=1e-10, max_step=0.05.\n")


FIGURES = [
    Figure("distributed_fig2", "Fig. 2", fig2_data, draw_fig2, caption_fig2),
    Figure("distributed_fig3", "Fig. 3", fig3_data, draw_fig3, caption_fig3),
]

NOT_REPRODUCED = {
    "Fig. 1": "the communication graph: a drawing, missing from the text we have; we use "
              "the directed ring 1 -> 2 -> 3 -> 4 -> 1 (decision 9) and draw no figure of it",
}


def reproduce(outdir):
    """Regenerate Figs. 2 and 3 of the paper into ``outdir`` (an existing folder).

    Fig. 2: errors of the observer network (7)-(8) in transformed
    coordinates, semi-log, without noise (with the linear observer (3)
    for comparison). Fig. 3: the same under band-limited white noise of power
    1e-2 on each output (Remark 2).

    Returns
    -------
    list of pathlib.Path
        The PNG files (each with a ``.txt`` caption beside it).

    References
    ----------
    Silm et al. (2020), Section 4, Figs. 2-3.
    """
    return reproduce_figures(FIGURES, outdir)
