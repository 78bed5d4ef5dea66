r"""Theorem 2's conclusion (42) over every sampling sequence, on an example where (40) holds.

On the DC motor (40) fails by ~20 orders of magnitude (claim 004-eq40-holds),
so Theorem 2 promises nothing there. This module checks (42) where it does
promise something: the plant (1)

.. math::
    \dot\chi = M\chi,\quad M = \begin{bmatrix}-1 & 0\\ 1 & -0.5\end{bmatrix},\quad
    Y = N\chi = \chi_2,

already in the coordinates (2) (``xi1 = chi1``, ``xi2 = chi2``, P = [1 0]):
A1 = -1, A2 = 1, M12 = 0, M22 = -k with k = 0.5, so F1 = F2 = 0 and
K1 = K2 = 0 in (3); tau = 1 (:data:`EXAMPLE`). Then (40) asks T_bar < 0.129
(xi_2 in (13), as printed) or T_bar < 0.112 (omega in (13), decision 2), and
the gaps are taken in [T_low, T_bar] = [0.05, 0.1]. (The plant
M = [[0, 1], [-1, -1]] with N = [1 0] has the same A1, A2 but
F1(y) = -y and F2(y) = k y: K1 = 1, K2 = 0.5, and (40) asks T_bar < 0.027.)

Without disturbances (42) reads, with a1 and R* of Remark 4 and (43),

.. math::
    |\xi_1(t) - \xi_e(t)| \le a_1 |\xi_2 - \omega|_{[r - 2\tau - \bar T, r]}
    e^{R_*(t - r)}\quad\text{for all } r \ge 2\tau + \bar T,\ t \ge r + \tau.

:func:`margin42` is its margin along a run, in decades: the minimum over
the samples t of log10(B(t) / |e(t)|), B(t) the smallest right side over
r (the samples r in [2 tau + T_bar, t - tau]). The error decays far faster
than the bound (about e^{-4 t} against R* = -0.23): by t ~ 4.5-5.5 s it is
integration noise (runs at rtol 1e-8, 1e-10, 1e-12 agree to 10 % until
then), and so is the bound, which r = t - tau then makes
~q1 |xi_2 - omega| over [t - 3.1, t - 1]. A sample is therefore judged only
where the error exceeds :data:`FLOOR` (100 rtol for |chi(0)| = 1; the
populations' noise on e measures up to 1e-8 = 10 rtol); below it (42)
cannot be decided, and a run whose error grew back above it would be
judged there. At rtol 1e-9 the samples judged are those up to t ~ 4.2 s,
and the margin is decided at the first, t ~ 3.1 s.

Two ways to cover "every gap sequence":

* :func:`tree_data` -- :func:`~observers.gramian_delay.explore_samples` over
  every sequence of gaps from {T_low, T_bar} on the first :data:`PREFIX`
  samples (2^(PREFIX - 1) solutions), each continued with gaps T_bar to the
  horizon in one population (:func:`sequence_run`);
* :func:`search_data` -- :func:`hybridsim.falsify` over the whole horizon,
  every gap free in [T_low, T_bar] (a ``Gaps`` entry covering the horizon)
  and the direction of chi(0) free, beside random sampling of the same
  budget and seed.

The rows of one population sample at their own instants: the observer (39)
with ``instants`` reads the instant of index kappa (its sample counter), so
the rows' sequences are stored one after another in one array, each closed
by an instant after the horizon, and each row's kappa starts at the index of
its own.

Examples
--------
>>> from observers.gramian_delay.every_gap import constants
>>> c = constants("xi2")
>>> bool(c.holds), round(c.T_bar_max, 3), round(c.rate, 3)
(True, 0.129, -0.233)
"""
from __future__ import annotations

import functools
import math

import numpy as np

import hybridsim as hs
from hybridsim.falsification import Gaps, Interval, Space
from hybridsim.testing import Margin

from .design import gramian_design, observer_form, theorem2_constants
from .example import errors, explore_samples, population
from .systems import Plant, SampledGramianObserver

__all__ = ["EXAMPLE", "T_LOW", "T_BAR", "HORIZON", "PREFIX", "RTOL", "FLOOR", "BUDGET",
           "constants", "observer", "sequence_run", "margin42", "tree_data", "search_data"]

#: The plant and design: M, N of (1) (Psi = 0), k of (2), the delay tau.
EXAMPLE = dict(M=((-1.0, 0.0), (1.0, -0.5)), N=((0.0, 1.0),), k=0.5, tau=1.0)
T_LOW, T_BAR = 0.05, 0.1       # (36), below 1/mu of (40) in both readings
#: Horizon (s): the first judged instant 3 tau + T_bar = 3.1, then 1 / |R*| (xi_2 reading).
HORIZON = 7.5
PREFIX = 6                     # samples of the explored tree (t0 = 0 one of them)
RTOL = 1e-9                    # the populations' RK45 (atol = rtol / 100)
#: The error below which (42) is not judged: 100 rtol (|chi(0)| = 1).
FLOOR = 100 * RTOL
BUDGET = 48                    # runs of the search, and of the random baseline
_K1 = _K2 = 0.0                # F1 = F2 = 0


@functools.cache
def _form_design():
    M, N = np.array(EXAMPLE["M"]), np.array(EXAMPLE["N"])
    form = observer_form(M, N, None, P=[[1.0, 0.0]], k=EXAMPLE["k"])
    return form, gramian_design(form.A1, form.A2, form.k, EXAMPLE["tau"])


def constants(estimate):
    """Theorem 2's constants (38)-(43), Remark 4, at T_bar = :data:`T_BAR` (K1 = K2 = 0)."""
    return theorem2_constants(_form_design()[1], _K1, _K2, T_BAR, estimate=estimate)


def observer(estimate, **sampling):
    """The observer (39) for the example (``gaps=``, ``period=`` or ``instants=``), carrying
    its plant (oracle output for ``estimate="xi2"``) and coordinates."""
    form, d = _form_design()
    obs = SampledGramianObserver(d, form.F1, form.F2, estimate=estimate, **sampling)
    obs.plant = Plant(np.array(EXAMPLE["M"]), np.array(EXAMPLE["N"]),
                      oracle=estimate == "xi2")
    obs.form = form
    return obs


def _instants(gaps, t_max):
    """t_0 = 0 and the instants of ``gaps`` up to t_max."""
    ts = np.concatenate([[0.0], np.cumsum(np.asarray(gaps, dtype=float))])
    return ts[ts <= t_max]


def sequence_run(estimate, sequences, chi0s, *, t_max=HORIZON, rtol=RTOL):
    r"""One population of (39): row i samples at ``sequences[i]`` from ``chi0s[i]``.

    Parameters
    ----------
    estimate : {"xi2", "omega"}
    sequences : list of 1-D array_like
        Each row's gaps t_{j+1} - t_j (t_0 = 0); they must cover ``t_max``.
    chi0s : (P, 2) array_like
        The plants' initial states (the observers start at 0).
    t_max, rtol : float

    Returns
    -------
    arcs : list of HybridArc
    obs : SampledGramianObserver
        To read the arcs with (:func:`~observers.gramian_delay.errors`).
    """
    segs = [_instants(g, t_max) for g in sequences]
    short = [i for i, g in enumerate(sequences) if np.sum(g) < t_max]
    if short:
        raise ValueError(f"sequences {short[:5]} do not cover t_max = {t_max}")
    obs = observer(estimate, instants=segs[0])
    system, rows = population(obs, chi0s, instants=segs)      # row i at its own instants
    arcs = hs.simulate_many(system, rows, t_max=t_max, j_max=10**6, rtol=rtol,
                            atol=rtol / 100, backend="python", warn=False)
    return list(arcs), obs


def _window_max(t, v, width):
    """max of v over the samples in [t_i - width, t_i], at every sample i (sparse table)."""
    n = len(v)
    lo = np.searchsorted(t, t - width, side="left")
    table = [v]
    while (1 << len(table)) <= n:
        prev, s = table[-1], 1 << (len(table) - 1)
        table.append(np.concatenate([np.maximum(prev[:n - s], prev[s:]), prev[n - s:]]))
    table = np.array(table)
    idx = np.arange(n)
    lev = np.floor(np.log2(idx - lo + 1)).astype(int)
    return np.maximum(table[lev, lo], table[lev, idx - (1 << lev) + 1])


def margin42(arc, obs, c, *, floor=FLOOR):
    r"""The margin of (42) without disturbances along a run, in decades (a ``Margin``).

    .. math::
        \min_t \log_{10}\frac{B(t)}{|\xi_1(t) - \xi_e(t)|},\quad
        B(t) = a_1 \min_{r} |\xi_2 - \omega|_{[r - 2\tau - \bar T, r]} e^{R_*(t - r)},

    r over the samples in [2 tau + T_bar, t - tau], t over the samples with
    t >= 3 tau + T_bar where |e(t)| > ``floor`` (module docstring).
    Negative iff the error exceeds the bound at a judged sample. The
    suprema are over the samples (w_tilde is 0 just after each sample and
    grows between them), which can only lower B.

    Parameters
    ----------
    arc : HybridArc
        A run of ``obs`` with its plant.
    obs : SampledGramianObserver
    c : Theorem2Constants
        Of ``obs``'s design and reading (``a1``, ``rate``, ``T_bar``).
    floor : float
    """
    if not c.holds:
        raise ValueError(f"(40) fails (T_bar mu = {c.T_bar_mu:.3g}): (42) promises nothing")
    E = errors(arc, obs)
    t, e = arc.t, E.norm()
    w = np.abs(E["w_tilde"]).max(axis=1)
    tau = obs.design.tau
    W = _window_max(t, w, 2 * tau + c.T_bar)
    G = np.where(t >= 2 * tau + c.T_bar, W * np.exp(-c.rate * t), np.inf)
    run_min = np.minimum.accumulate(G)                  # min over r <= t of W(r) e^{-R* r}
    judged = (t >= 3 * tau + c.T_bar) & (e > floor)
    if not judged.any():
        return Margin(math.inf, what="(42): no error above the floor")
    k = np.flatnonzero(judged)
    r_last = np.searchsorted(t, t[k] - tau, side="right") - 1     # the last r <= t - tau
    B = c.a1 * np.exp(c.rate * t[k]) * run_min[r_last]
    dec = np.log10(B) - np.log10(e[k])
    i = int(np.argmin(dec))
    return Margin(dec[i], t[k[i]], arc.j[k[i]], "(42) in decades",
                  series=(t[k], arc.j[k], dec))


def _chi0(angle):
    return np.array([np.cos(angle), np.sin(angle)])


#: The tree's plant initial state (unit norm).
CHI0 = _chi0(-np.pi / 4)


@functools.cache
def tree_data(estimate):
    r"""(42) on every solution with gaps in {T_low, T_bar} over the first :data:`PREFIX` samples.

    :func:`~observers.gramian_delay.explore_samples` gives the tree (the
    observer with ``gaps=(T_low, T_bar)``, no dwell grid: at each sample a
    gap of T_low or T_bar); each leaf's sampling sequence is continued with
    gaps T_bar to :data:`HORIZON` and run in one population from :data:`CHI0`.

    Returns
    -------
    dict
        ``count`` (solutions), ``margins`` (one per solution, decades),
        ``margin`` (their minimum), ``worst`` (its gaps), ``tree``, ``arcs``,
        ``obs``.
    """
    tree = explore_samples(observer(estimate, gaps=(T_LOW, T_BAR)), CHI0, samples=PREFIX,
                           dwell_grid=(), t_max=HORIZON)
    if not tree.complete:
        raise RuntimeError(f"the tree is incomplete ({tree.end}): not every sequence explored")
    seqs = []
    for leaf in tree:
        head = np.diff(leaf.jump_times)
        tail = np.full(math.ceil((HORIZON - leaf.jump_times[-1]) / T_BAR) + 1, T_BAR)
        seqs.append(np.concatenate([head, tail]))
    arcs, obs = sequence_run(estimate, seqs, np.tile(CHI0, (len(seqs), 1)))
    c = constants(estimate)
    margins = [margin42(a, obs, c) for a in arcs]
    i = int(np.argmin(margins))
    return dict(count=len(tree), margins=margins, margin=float(margins[i]),
                worst=np.diff(tree.leaves[i].jump_times), tree=tree, arcs=arcs, obs=obs)


def _space():
    count = math.ceil(HORIZON / T_LOW)
    return Space(gaps=Gaps(T_LOW, T_BAR, count), angle=Interval(0.0, np.pi))


def _search_run(estimate):
    c = constants(estimate)

    def run(points):
        arcs, obs = sequence_run(estimate, [p["gaps"] for p in points],
                                 np.array([_chi0(p["angle"]) for p in points]))
        for a in arcs:
            a.observer = obs
        return arcs
    run.batch = True

    def margin(arc):
        return margin42(arc, arc.observer, c)
    return run, margin


@functools.cache
def search_data(estimate, budget=BUDGET, seed=0):
    r"""(42) over the whole horizon, every gap free in [T_low, T_bar]: a search and a baseline.

    :func:`hybridsim.falsify` (differential evolution after its seeded first
    population, then the compass search) over ``Gaps(T_low, T_bar,
    ceil(HORIZON / T_low))`` and the direction of chi(0) in [0, pi) (the
    error and the bound are linear in chi(0), so its norm does not
    matter), and random sampling of the same budget and seed.

    Returns
    -------
    dict
        ``search``, ``random``: the two FalsificationResults.
    """
    run, margin = _search_run(estimate)
    kw = dict(budget=budget, seed=seed, stop=False, progress=False)
    return dict(search=hs.falsify(run, _space(), margin, **kw),
                random=hs.falsify(run, _space(), margin, method="random", **kw))
