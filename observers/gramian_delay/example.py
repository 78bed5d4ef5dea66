r"""The paper's example (Section V, DC motor (64)-(67)) and how a run is made and read.

* :data:`DC_PARAMS` and :func:`dc_motor` -- the single-link manipulator (65)
  with the paper's parameters and our choices of control, disturbances and
  initial state (decision 7), a :class:`~observers.gramian_delay.DCMotor`.
* :data:`CONTINUOUS_RUN`, :data:`SAMPLED_RUN` -- the integrator settings of
  the runs of (7) and (39).
* :func:`simulate` -- an observer with its plant on :func:`hybridsim.simulate`
  (components ``"plant"`` and ``"observer"``).
* :func:`population` -- a batch of runs for :func:`hybridsim.simulate_many`
  (one plant initial state per row, integrated together).
* :func:`explore_samples` -- every solution over the sampling sequences of
  (36) (:func:`hybridsim.explore`).
* :func:`errors` -- xi_1 - xi_e of (13) at the arc's samples, an
  :class:`~observers._common.Errors` (``"e"``, and ``"w_tilde"`` = xi_2 - omega
  of (44) for the sampled observer).

Examples
--------
>>> import numpy as np
>>> from observers import gramian_delay as gd
>>> ex = gd.dc_motor(k=100.0, tau=0.1, disturbed=False)          # (65)-(67)
>>> obs = ex.continuous_observer()                               # (7)
>>> arc = gd.simulate(obs, ex.chi0, None, t_max=0.3)
>>> e = gd.errors(arc, obs).e                                    # xi_1 - xi_e (13)
>>> bool(np.abs(e[arc.t >= 0.1]).max() < 1e-8)                  # Theorem 1: exact after tau
True
"""
from __future__ import annotations

import numpy as np

import hybridsim as hs

from .._common import Errors, scalar, vector
from .design import ObserverForm
from .systems import DCMotor, Plant, SampledGramianObserver, _ObserverBase, smooth_noise

__all__ = ["DC_PARAMS", "dc_motor", "CONTINUOUS_RUN", "SAMPLED_RUN", "simulate",
           "population", "explore_samples", "errors"]

#: The motor's parameters (65), "as in [6]" (Section V).
DC_PARAMS = dict(b0=40.0, b1=15.0, a1=35.0, a2=1.0, a3=36.4, a4=200.0)


# decision 7's signals, on the last axis: a time, or a batch of times (N,) -> rows (N, dim)
def _example_u(t):
    return 2.0 * np.sin(2.0 * t)


def _example_delta1(t):
    t = np.asarray(t, dtype=float)
    out = np.zeros(t.shape + (3,))
    out[..., 1] = 0.5 * np.sin(5 * t)
    out[..., 2] = 0.5 * np.cos(3 * t)
    return out


def _example_delta2(t):
    t = np.asarray(t, dtype=float)
    out = np.zeros(t.shape + (1,))
    out[..., 0] = 1e-3 * np.sin(20 * t)
    return out


_example_u.batch = _example_delta1.batch = _example_delta2.batch = True


def dc_motor(k=100.0, tau=0.1, *, disturbed=True, u=None, delta1=None, delta2=None,
             chi0=None, oracle=False) -> DCMotor:
    r"""The single-link manipulator with DC motor (64)-(67) of Section V.

    Parameters
    ----------
    k, tau : float
        The paper uses tau = 0.1 and k = 100 (Fig. 1), 75 and 150 (Fig. 2).
    disturbed : bool
        False: delta1 = delta2 = 0 (the setting of Theorem 1's exactness).
        True: our default disturbances (below) unless given.
    u, delta1, delta2 : callable, optional
        Control ``t -> float``, ``t -> (3,)`` and ``t -> (1,)``. The paper
        takes them from its ref. [6]; we choose (and say so in the figures,
        decision 7): ``u(t) = 2 sin(2t)``,
        ``delta1(t) = (0, 0.5 sin(5t), 0.5 cos(3t))`` and
        ``delta2(t) = 1e-3 sin(20t)``.
    chi0 : (3,) array_like, optional
        Plant initial state; default (our choice) (0.5, -1, 0.2).
    oracle : bool
        Plant output (Y, chi1) instead of Y (for estimate="xi2").

    Returns
    -------
    DCMotor
        The plant (65), with its coordinates (66)-(67), design (5)-(6) and
        Lipschitz constants K1 = a1, K2 = k.

    Examples
    --------
    >>> from observers.gramian_delay import dc_motor
    >>> ex = dc_motor(100.0, 0.1)
    >>> ex.form.A1.tolist(), f"{ex.design.cond_S:.3g}"                 # (67), (5)
    ([[-1.0, 15.0], [-36.4, -200.0]], '1.41e+05')

    References
    ----------
    Mazenc & Malisoff (2022), Section V, eqs. (64)-(67).
    """
    if u is None:
        u = _example_u
    if disturbed:
        if delta1 is None:
            delta1 = _example_delta1
        if delta2 is None:
            delta2 = _example_delta2
    elif delta1 is not None or delta2 is not None:
        raise ValueError("delta1 and delta2 must be None when disturbed=False")
    chi0 = np.array([0.5, -1.0, 0.2]) if chi0 is None else chi0
    return DCMotor(DC_PARAMS, k, tau, u=u, delta1=delta1, delta2=delta2, chi0=chi0,
                   oracle=oracle)


#: Integrator settings of a run: tight for (7) (exactness checks amplify the integration
#: error by |S^{-1}| ~ 1e5), LSODA for (39) (a delay equation with jumps).
CONTINUOUS_RUN = dict(method="DOP853", rtol=1e-11, atol=1e-12, dense=True, progress=False)
SAMPLED_RUN = dict(method="LSODA", rtol=1e-9, atol=1e-11, dense=True, progress=False)


def _plant_of(observer, plant):
    if plant is None:
        plant = getattr(observer, "plant", None)
    if plant is None:
        raise TypeError("plant must be given (a gramian_delay.Plant): the observer was not "
                        "built by DCMotor.continuous_observer / sampled_observer, which "
                        "attach it")
    if not isinstance(plant, Plant):
        raise TypeError(f"plant must be a gramian_delay.Plant, got {type(plant).__name__}")
    return plant


def simulate(observer, x0, xhat0=None, *, t_max, noise=None, seed=None, plant=None,
             j_max=10**6, **simulate_kwargs):
    r"""Run an observer of this paper with its plant (1); the calling pattern's step 3.

    Parameters
    ----------
    observer : GramianObserver or SampledGramianObserver
    x0 : (n,) array_like
        The plant's initial state chi(0).
    xhat0 : (state_dim,) array_like, optional
        The observer's initial state; default ``observer.initial_state()``.
    t_max : float
    noise : callable or float, optional
        Measurement noise delta_2 of (1): ``t -> (q,)``, or an RMS for
        :func:`~observers.gramian_delay.smooth_noise` drawn with ``seed``. Replaces the plant's own
        delta_2; default: the plant's.
    seed : int or numpy Generator, optional
        For a float ``noise`` (nothing else here is random).
    plant : Plant, optional
        Default: the plant the observer carries (a
        :class:`~observers.gramian_delay.DCMotor` attaches itself to the
        observers it builds).
    j_max : int
        Jump bound (samples of (39), resets of the reset realisation).
    **simulate_kwargs
        To :func:`hybridsim.simulate`; defaults :data:`CONTINUOUS_RUN` for
        (7), :data:`SAMPLED_RUN` for (39).

    Returns
    -------
    hybridsim.HybridArc
        Of the interconnection, components ``"plant"`` and ``"observer"``.

    Examples
    --------
    >>> from observers import gramian_delay as gd
    >>> ex = gd.dc_motor(100.0, 0.1)
    >>> arc = gd.simulate(ex.continuous_observer(), ex.chi0, None, t_max=0.05)
    >>> sorted(arc.components)
    ['observer', 'plant']
    """
    t_max = scalar("t_max", t_max, positive=True)
    sysc, x0 = _loop(observer, x0, xhat0, noise, seed, plant)
    opts = dict(SAMPLED_RUN if isinstance(observer, SampledGramianObserver) else CONTINUOUS_RUN)
    opts.update(simulate_kwargs)
    return hs.simulate(sysc, x0, t_max=t_max, j_max=j_max, **opts)


def _loop(observer, x0, xhat0, noise, seed, plant):
    """The interconnection plant -> observer and its initial state (simulate, explore_samples)."""
    if not isinstance(observer, _ObserverBase):
        raise TypeError(f"observer must be a GramianObserver or SampledGramianObserver, "
                        f"got {type(observer).__name__}")
    plant = _plant_of(observer, plant)
    if noise is not None:
        q = plant.N.shape[0]
        if not callable(noise):
            noise = smooth_noise(noise, q, seed=seed)
        plant = Plant(plant.M, plant.N, plant.Psi, delta1=plant.delta1, delta2=noise,
                      oracle=plant.oracle)
    sysc = hs.connect(plant, observer, names=("plant", "observer"))
    z0 = observer.initial_state() if xhat0 is None else vector("xhat0", xhat0,
                                                                  observer.state_dim)
    x0 = sysc.stack(plant=vector("x0", x0, plant.state_dim), observer=z0)
    return sysc, x0


def population(observer, x0s, xhat0=None, *, noise=None, seed=None, plant=None,
               instants=None):
    r"""A batch of runs of an observer with its plant: ``(system, rows)`` for
    :func:`hybridsim.simulate_many`, one row per plant initial state.

    The plant (1) and the observers (7) and (39) (literal realisation) take
    batches when the plant's Psi has a batch form (the DC motor's does):
    the rows are integrated together in numpy, each reading its own past
    (:class:`hybridsim.BatchHistory`). Read each arc with
    :func:`~observers.gramian_delay.errors` as a single run's.

    Parameters
    ----------
    observer : GramianObserver or SampledGramianObserver
    x0s : (N, n) array_like
        The plants' initial states chi(0).
    xhat0, noise, seed, plant
        As in :func:`~observers.gramian_delay.simulate` (the same for every
        row).
    instants : list of 1-D array_like, optional
        Each row's own sampling instants (a :class:`SampledGramianObserver`
        built with ``instants=``): the observer's instants become the rows'
        sequences one after the other, each closed by an instant past every
        horizon, and row i's counter kappa starts at its sequence's index.

    Returns
    -------
    system : hybridsim.Interconnection
        Components ``"plant"`` and ``"observer"``; ``system.vectorized`` is
        False where a part has no batch form (``simulate_many`` then runs
        the rows one by one).
    rows : (N, r) array

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> from observers import gramian_delay as gd
    >>> ex = gd.dc_motor(100.0, 0.1)
    >>> obs = ex.sampled_observer(period=0.01)
    >>> system, rows = gd.population(obs, ex.chi0 + [[0.0, 0, 0], [0.1, 0, 0]])
    >>> arcs = hs.simulate_many(system, rows, t_max=0.05, rtol=1e-8, atol=1e-10)
    >>> system.vectorized, [len(a.jump_times) for a in arcs]
    (True, [6, 6])
    """
    if not isinstance(observer, _ObserverBase):
        raise TypeError(f"observer must be a GramianObserver or SampledGramianObserver, "
                        f"got {type(observer).__name__}")
    n = _plant_of(observer, plant).state_dim
    X = np.asarray(x0s, dtype=float)
    if X.ndim != 2 or X.shape[0] < 1 or X.shape[1] != n:
        raise ValueError(f"x0s must have shape (N, {n}) (one plant state per row), "
                         f"got {X.shape}")
    if instants is not None:
        if not isinstance(observer, SampledGramianObserver) or observer.instants is None:
            raise ValueError("instants: the observer must be a SampledGramianObserver built "
                             "with instants=")
        if len(instants) != len(X):
            raise ValueError(f"instants: one sequence per row, got {len(instants)} for "
                             f"{len(X)} rows")
        segs = [np.asarray(s, dtype=float).reshape(-1) for s in instants]
        close = max(float(s[-1]) for s in segs) + 1.0
        segs = [np.append(s, close) for s in segs]
        ins = np.concatenate(segs)
        # padded (never reached: each row stops at its close) to a power of two, so that
        # populations of other sizes share the compiled maps (their parameters' length)
        size = 1 << max(0, int(ins.size - 1).bit_length())
        observer.instants = np.concatenate([ins, np.full(size - ins.size, close)])
    system, first = _loop(observer, X[0], xhat0, noise, seed, plant)
    rows = np.repeat(first[None, :], len(X), axis=0)
    rows[:, system.components["plant"]] = X
    if instants is not None:
        rows[:, system.components["observer"].start + observer.i_kappa] = np.cumsum(
            [0] + [len(s) for s in segs[:-1]])
    return system, rows


def explore_samples(observer, x0, xhat0=None, *, samples, dwell_grid, t_max=10.0, noise=None,
                    seed=None, plant=None, **explore_kwargs):
    r"""Every solution of (37), (39) over the sampling sequences of (36), as a tree.

    The observer must be built with ``gaps=(T_low, T_bar)``: C ∩ D is then
    T_low <= sigma <= T_bar, and :func:`hybridsim.explore` follows, at each
    sample, a gap of T_low, of T_low + each dwell of ``dwell_grid``, and of
    T_bar (Theorem 2 holds for every such sequence). Each branch continues
    its parent's past (the delay of (13)); branches are never merged.

    Parameters
    ----------
    observer : SampledGramianObserver
        With ``gaps`` set.
    x0, xhat0, noise, seed, plant
        As in :func:`~observers.gramian_delay.simulate`.
    samples : int
        Samples per solution (the one at t0 included): the tree's depth.
    dwell_grid : sequence of float
        Dwells in C ∩ D (each in (0, T_bar - T_low)).
    t_max : float
        Each solution also stops here.
    **explore_kwargs
        To :func:`hybridsim.explore` (``max_branches``, ``max_seconds``...);
        the integrator settings default to :data:`SAMPLED_RUN`'s.

    Returns
    -------
    hybridsim.SolutionTree
        Its leaves are arcs of the interconnection (components ``"plant"``
        and ``"observer"``), read with :func:`~observers.gramian_delay.errors`.

    Examples
    --------
    Gaps of 0.05 or 0.1 s, three samples: 2 x 2 sequences.

    >>> from observers import gramian_delay as gd
    >>> ex = gd.dc_motor(100.0, 0.1, oracle=True)
    >>> obs = ex.sampled_observer(gaps=(0.05, 0.1), estimate="xi2")
    >>> tree = gd.explore_samples(obs, ex.chi0, samples=3, dwell_grid=())
    >>> sorted(tuple(a.jump_times.round(3)) for a in tree)[:2]
    [(0.0, 0.05, 0.1), (0.0, 0.05, 0.15)]
    """
    if not isinstance(observer, SampledGramianObserver) or observer.gaps is None:
        raise TypeError("observer must be a SampledGramianObserver built with gaps=(T_low, "
                        f"T_bar), got {observer!r}")
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ValueError(f"samples must be a positive int, got {samples!r}")
    t_max = scalar("t_max", t_max, positive=True)
    sysc, x0 = _loop(observer, x0, xhat0, noise, seed, plant)
    opts = {k: v for k, v in SAMPLED_RUN.items() if k not in ("dense", "progress")}
    opts.update(explore_kwargs)
    return hs.explore(sysc, x0, t_max=t_max, j_max=samples, dwell_grid=dwell_grid, **opts)


def errors(arc, observer, *, y=None, form=None, name="observer"):
    r"""xi_1 - xi_e (13) at the arc's samples; the calling pattern's step 4.

    Parameters
    ----------
    arc : HybridArc
        A run of :func:`simulate` (components ``"plant"`` and ``name``).
    observer : GramianObserver or SampledGramianObserver
    y : (N, q) array_like, optional
        The signal standing for xi_2(t) in (13). Default: the measured
        Y(t) for (7) (implementable; decision 4), omega(t) for (39) with
        ``estimate="omega"``, the true xi_2(t) for ``estimate="xi2"``.
    form : ObserverForm, optional
        The coordinates (2) of the plant; default the observer's (attached
        by :class:`DCMotor`).
    name : str
        The observer's component name.

    Returns
    -------
    Errors
        ``"e"``: xi_1 - xi_e, shape (N, n - q), the error of the
        reduced-order estimate (the observer estimates xi_1 only; xi_2 is
        measured). For the sampled observer (39) also ``"w_tilde"``:
        xi_2 - omega of (44), shape (N, q), the signal of Theorem 2's
        bound (62).

    Examples
    --------
    >>> import numpy as np
    >>> from observers import gramian_delay as gd
    >>> ex = gd.dc_motor(150.0, 0.1, disturbed=False)
    >>> obs = ex.continuous_observer()
    >>> arc = gd.simulate(obs, ex.chi0, None, t_max=0.2)
    >>> E = gd.errors(arc, obs)
    >>> E.e.shape == (len(arc.t), 2), list(E)
    (True, ['e'])
    """
    form = getattr(observer, "form", None) if form is None else form
    if not isinstance(form, ObserverForm):
        raise TypeError("form must be an ObserverForm (the plant's coordinates (2)); the "
                        "observer carries none (build it with DCMotor, or pass form=)")
    xi = form.to_xi(arc["plant"].x)
    m = observer.design.m
    if isinstance(observer, SampledGramianObserver):
        if y is None and observer.estimate_source == "xi2":
            y = xi[:, m:]
        xe = observer.estimate(arc, y=y, name=name)
        w_tilde = xi[:, m:] - arc.component(name).x[:, observer.sl_omega]        # (44)
        return Errors(arc.t, arc.j, e=xi[:, :m] - xe, w_tilde=w_tilde)
    if y is None:
        y = arc.outputs("plant")[:, :observer.design.q]
    xe = observer.estimate(arc, y, name=name)
    return Errors(arc.t, arc.j, e=xi[:, :m] - xe)


def _run_dc(k, *, sampled, T=0.1, estimate="xi2", t_max=1.0, disturbed=True, max_norm=1e6,
            realisation="literal", read=True, **simulate_kwargs):
    """One run of (66) with an observer as in Figs. 1-2; returns ``(arc, errors)``.

    Both observers with :data:`SAMPLED_RUN`'s settings, tau = 0.1, sampling
    period T. Without a warning where the run ends on a failure (``BLOWUP``
    at k = 75, or a sampled observer that diverges): these are expected, and
    the callers report ``arc.termination``. With ``read=False`` the errors
    are read only when the run reached t_max (else None).
    """
    ex = dc_motor(k, 0.1, disturbed=disturbed, oracle=sampled and estimate == "xi2")
    obs = (ex.sampled_observer(period=T, estimate=estimate, realisation=realisation) if sampled
           else ex.continuous_observer(realisation=realisation))
    arc = simulate(obs, ex.chi0, None, t_max=t_max, max_norm=max_norm,
                   **{**SAMPLED_RUN, "warn": False, **simulate_kwargs})
    if not read and arc.termination is not hs.Termination.T_MAX:
        return arc, None
    return arc, errors(arc, obs)


def _err_at(E, s):
    """|e| at the first sample at or after s (the last sample when the run stopped before s)."""
    i = min(int(np.searchsorted(E.t, s)), len(E.t) - 1)
    return float(np.linalg.norm(E.e[i]))
