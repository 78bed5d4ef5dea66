r"""The paper's example (Section V, DC motor (64)-(67)) and how a run is made and read.

* :func:`dc_motor` -- the single-link manipulator (65) in the coordinates
  (66), with (67)'s A1, A2, F1, F2, the design and the plant, a :class:`DCMotor`.
* :func:`simulate` -- an observer with its plant on :func:`hybridsim.simulate`
  (components ``"plant"`` and ``"observer"``).
* :func:`errors` -- xi_1 - xi_e at the arc's samples, (N, n - q).

Examples
--------
>>> import numpy as np
>>> from observers import gramian_delay as gd
>>> ex = gd.dc_motor(k=100.0, tau=0.1, disturbed=False)          # (65)-(67)
>>> obs = ex.continuous_observer()                               # (7)
>>> arc = gd.simulate(obs, ex.chi0, None, t_max=0.3)
>>> e = gd.errors(arc, obs)                                      # xi_1 - xi_e (13)
>>> bool(np.abs(e[arc.t >= 0.1]).max() < 1e-8)                  # Theorem 1: exact after tau
True
"""
from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Callable

import numpy as np

import hybridsim as hs

from .._common import scalar, vector
from .design import GramianDesign, ObserverForm, gramian_design, observer_form
from .systems import GramianObserver, Plant, SampledGramianObserver, _signal

__all__ = ["DCMotor", "DC_PARAMS", "dc_motor", "simulate", "errors", "smooth_noise"]


@dataclasses.dataclass
class DCMotor:
    """The DC-motor example (65)-(67) with everything a run needs.

    Attributes
    ----------
    params : dict
        b0, b1, a1..a4 (the paper's values, "as in [6]").
    form : ObserverForm
        (65) in the coordinates (66): xi1 = (chi2, chi3), xi2 = chi1.
    design : GramianDesign
    plant : Plant
        (65) in chi coordinates, output Y = chi1 + delta2.
    K1, K2 : float
        Lipschitz constants a1 and k of F1, F2 (Section V).
    u, delta1, delta2 : callable
        Control and disturbances (our choices: the paper cites them from
        its ref. [6], which we do not have).
    chi0 : (3,) array
        Plant initial state (our choice).
    """

    params: dict
    form: ObserverForm
    design: GramianDesign
    plant: Plant
    K1: float
    K2: float
    u: Callable
    delta1: Callable
    delta2: Callable
    chi0: np.ndarray

    def xi(self, chi):
        """(66)'s coordinates of plant states (time-major (N, 3) or (3,))."""
        return self.form.to_xi(chi)

    def continuous_observer(self, t0=0.0, *, realisation="literal"):
        """The observer (7) of Theorem 1 for this motor.

        It carries ``plant`` and ``form`` so that :func:`simulate` and
        :func:`errors` need nothing else.
        """
        obs = GramianObserver(self.design, self.form.F1, self.form.F2, t0=t0,
                              realisation=realisation)
        obs.plant, obs.form = self.plant, self.form
        return obs

    def sampled_observer(self, **kw):
        """The observer (39) of Theorem 2 (keywords of SampledGramianObserver)."""
        obs = SampledGramianObserver(self.design, self.form.F1, self.form.F2, **kw)
        obs.plant, obs.form = self.plant, self.form
        return obs


DC_PARAMS = dict(b0=40.0, b1=15.0, a1=35.0, a2=1.0, a3=36.4, a4=200.0)


def dc_motor(k=100.0, tau=0.1, *, disturbed=True, u=None, delta1=None, delta2=None,
             chi0=None, oracle=False) -> DCMotor:
    r"""The single-link manipulator with DC motor (64)-(67).

    Parameters
    ----------
    k, tau : float
        The paper uses tau = 0.1 and k = 100 (Fig. 1), 75 and 150 (Fig. 2).
    disturbed : bool
        False: delta1 = delta2 = 0 (the setting of Theorem 1's exactness).
        True: our default disturbances (below) unless given.
    u, delta1, delta2 : callable, optional
        Control ``t -> float``, ``t -> (3,)`` and ``t -> (1,)``. The paper
        takes them from its ref. [6]; we choose (and say so in the figures):
        ``u(t) = 2 sin(2t)``, ``delta1(t) = (0, 0.5 sin(5t), 0.5 cos(3t))``
        and ``delta2(t) = 1e-3 sin(20t)``.
    chi0 : (3,) array_like, optional
        Plant initial state; default (our choice) (0.5, -1, 0.2).
    oracle : bool
        Plant output (Y, chi1) instead of Y (for estimate="xi2").

    Returns
    -------
    DCMotor

    References
    ----------
    Mazenc & Malisoff (2022), Section V, eqs. (64)-(67).
    """
    p = DC_PARAMS
    M = np.array([[0.0, 1.0, 0.0], [0.0, -p["a2"], p["b1"]], [0.0, -p["a3"], -p["a4"]]])
    Nmat = np.array([[1.0, 0.0, 0.0]])
    if u is None:
        u = lambda t: 2.0 * np.sin(2.0 * t)  # noqa: E731
    elif not callable(u):
        raise TypeError(f"u must be callable t -> float, got {type(u).__name__}")
    if disturbed:
        if delta1 is None:
            delta1 = lambda t: np.array([0.0, 0.5 * np.sin(5 * t), 0.5 * np.cos(3 * t)])  # noqa: E731
        if delta2 is None:
            delta2 = lambda t: np.array([1e-3 * np.sin(20 * t)])  # noqa: E731
    else:
        if delta1 is not None or delta2 is not None:
            raise ValueError("delta1 and delta2 must be None when disturbed=False")
        delta1 = lambda t: np.zeros(3)  # noqa: E731
        delta2 = lambda t: np.zeros(1)  # noqa: E731
    d1 = _signal("delta1", delta1, 3)
    d2 = _signal("delta2", delta2, 1)

    def Psi(y, t):
        return np.array([0.0, -p["a1"] * np.sin(y[0]), p["b0"] * float(u(t))])

    form = observer_form(M, Nmat, Psi, P=[[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], k=k)
    design = gramian_design(form.A1, form.A2, form.k, tau)
    plant = Plant(M, Nmat, Psi, delta1=d1, delta2=d2, oracle=oracle)
    chi0 = np.array([0.5, -1.0, 0.2]) if chi0 is None else vector("chi0", chi0, 3)
    return DCMotor(params=dict(p), form=form, design=design, plant=plant, K1=p["a1"],
                   K2=float(k), u=u, delta1=d1, delta2=d2, chi0=chi0)


#: Integrator settings of a run: tight for (7) (exactness checks amplify the integration
#: error by |S^{-1}| ~ 1e5), LSODA for (39) (a delay equation with jumps).
CONTINUOUS_RUN = dict(method="DOP853", rtol=1e-11, atol=1e-12, dense=True, progress=False)
SAMPLED_RUN = dict(method="LSODA", rtol=1e-9, atol=1e-11, dense=True, progress=False)


def smooth_noise(sigma, dim=1, *, seed=None, n_modes=8, f_max=50.0):
    r"""A seeded smooth random signal t -> (dim,) of RMS about ``sigma``.

    ``sum_i a_i sin(2 pi f_i t + phi_i)`` with ``n_modes`` frequencies drawn
    uniformly in (0, f_max] Hz, Gaussian amplitudes scaled so that the RMS
    over a long horizon is ``sigma``, uniform phases. Smooth, so the
    integrator is not forced to resolve a discontinuous input.

    Parameters
    ----------
    sigma : float
        RMS (>= 0).
    dim : int
    seed : int or numpy Generator, optional
    n_modes : int
    f_max : float

    Returns
    -------
    callable
        ``t -> (dim,)`` array.

    Examples
    --------
    >>> n = smooth_noise(1e-3, seed=0)
    >>> n(0.5).shape
    (1,)
    """
    sigma = scalar("sigma", sigma, nonneg=True)
    f_max = scalar("f_max", f_max, positive=True)
    if isinstance(dim, bool) or not isinstance(dim, numbers.Integral) or dim < 1:
        raise ValueError(f"dim must be a positive int, got {dim!r}")
    if isinstance(n_modes, bool) or not isinstance(n_modes, numbers.Integral) or n_modes < 1:
        raise ValueError(f"n_modes must be a positive int, got {n_modes!r}")
    rng = np.random.default_rng(seed)
    f = rng.uniform(0.0, f_max, size=(n_modes, dim)) + f_max / (10 * n_modes)
    a = rng.normal(size=(n_modes, dim))
    a *= sigma * np.sqrt(2.0) / np.maximum(np.linalg.norm(a, axis=0), 1e-300)
    ph = rng.uniform(0.0, 2 * np.pi, size=(n_modes, dim))

    def noise(t):
        return np.sum(a * np.sin(2 * np.pi * f * t + ph), axis=0)
    return noise


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
        :func:`smooth_noise` drawn with ``seed``. Replaces the plant's own
        delta_2; default: the plant's.
    seed : int or numpy Generator, optional
        For a float ``noise`` (nothing else here is random).
    plant : Plant, optional
        Default: the plant attached by :class:`DCMotor`'s constructors.
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
    from .systems import _ObserverBase
    if not isinstance(observer, _ObserverBase):
        raise TypeError(f"observer must be a GramianObserver or SampledGramianObserver, "
                        f"got {type(observer).__name__}")
    plant = _plant_of(observer, plant)
    t_max = scalar("t_max", t_max, positive=True)
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
    opts = dict(SAMPLED_RUN if isinstance(observer, SampledGramianObserver) else CONTINUOUS_RUN)
    opts.update(simulate_kwargs)
    return hs.simulate(sysc, x0, t_max=t_max, j_max=j_max, **opts)


def errors(arc, observer, *, y=None, form=None, name="observer"):
    r"""xi_1 - xi_e (13) at the arc's samples, time-major (N, n - q); the pattern's step 4.

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
    (N, n - q) array
        The error of the reduced-order estimate (the observer estimates
        xi_1 only; xi_2 is measured).

    Examples
    --------
    >>> import numpy as np
    >>> from observers import gramian_delay as gd
    >>> ex = gd.dc_motor(150.0, 0.1, disturbed=False)
    >>> obs = ex.continuous_observer()
    >>> arc = gd.simulate(obs, ex.chi0, None, t_max=0.2)
    >>> gd.errors(arc, obs).shape == (len(arc.t), 2)
    True
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
    else:
        if y is None:
            y = arc.outputs("plant")[:, :observer.design.q]
        xe = observer.estimate(arc, y, name=name)
    return xi[:, :m] - xe


def _run_dc(k, *, sampled, T=0.1, estimate="xi2", t_max=1.0, disturbed=True, max_norm=1e6,
            realisation="literal", **simulate_kwargs):
    """One run of (66) with an observer as in Figs. 1-2; returns (t, error (N, 2), arc).

    Without a warning where the run ends on a failure (``BLOWUP`` at k = 75, or
    a sampled observer that diverges): the callers report ``arc.termination``.
    """
    ex = dc_motor(k, 0.1, disturbed=disturbed, oracle=sampled and estimate == "xi2")
    obs = (ex.sampled_observer(period=T, estimate=estimate, realisation=realisation) if sampled
           else ex.continuous_observer(realisation=realisation))
    arc = simulate(obs, ex.chi0, None, t_max=t_max, max_norm=max_norm,
                   **{**SAMPLED_RUN, "warn": False, **simulate_kwargs})
    return arc.t, errors(arc, obs), arc


def _err_at(t, e, s):
    """|e| at the first sample at or after s (the last sample when the run stopped before s)."""
    i = min(int(np.searchsorted(t, s)), len(t) - 1)
    return float(np.linalg.norm(e[i]))
