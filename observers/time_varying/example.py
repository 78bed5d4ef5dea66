r"""Section IV of paper 001 (the chained-form example): its data, how a run is made and read.

The paper's example
    :func:`tracking_initial_state` (x1(0) = 0.5 of Section IV-D and our
    xi4(0), xi3(0), xi2(0)) for the loop (44) + (58) of
    :func:`~observers.time_varying.tracking_loop`; :func:`loop_signals`
    reads a run of it (xi, the estimate (50), v2 and the argument of sigma
    in (58), zeta of (52)); :func:`loop_functions` gives v2, xi3, xi4 as
    functions of time on a dense run, for
    :func:`~observers.time_varying.residual_58`. The design data (47)-(48)
    are :func:`~observers.time_varying.example_data` (``design.py``).
Runs (the calling pattern of :mod:`observers`)
    :func:`simulate` (observer with its plant through
    :func:`hybridsim.simulate`), :func:`estimates`, :func:`errors` (an
    :class:`observers._common.Errors`, the error xhat_r - x_r under ``"e"``),
    :func:`error_norm`, :func:`bounded_noise` (a seeded measurement
    disturbance eps of (17)).

Decisions (a careful reading of the paper)
------------------------------------------
* **Validity range of (50).** The observer uses the model (45), which holds
  only where x1 = 0, i.e. for t >= sqrt|x1(0)|. The identity (50)
  integrates the model over the whole window [t - 2 pi, t], so it holds for
  t >= 2 pi + sqrt|x1(0)|, not for t >= max{2 pi, sqrt|x1(0)|} as printed.
* **(58) is a distributed-delay equation, not an algebraic loop.** v2(t)
  enters (58) only inside int_{t-2 pi}^t (1 - e^{M(m, t)}) v2(m) dm, whose
  value does not depend on v2 at the single instant t;
  :func:`~observers.time_varying.tracking_loop` builds it as the observer
  (whose states integrate v2) fed back through (57), and
  :func:`~observers.time_varying.residual_58` checks (58) literally along a
  run.
* **Before 2 pi** the window is not filled: the feedback uses the estimate
  ``xr_init`` (0 by default), our choice.

Examples
--------
>>> import numpy as np
>>> from observers import time_varying as tv
>>> obs = tv.chained_form_observer()
>>> arc = tv.simulate(obs, [0.8, -0.4, 0.6, 0.0], t_max=2 * np.pi + 0.5,
...                   w=lambda t: [0.5 * np.cos(1.3 * t)])
>>> E = tv.errors(arc, obs)                        # xhat_r - x_r under "e", shape (N, 1)
>>> bool(np.abs(E.e[arc.j >= 1]).max() < 1e-8)    # exact once the window is filled (50)
True
"""
from __future__ import annotations

import numpy as np

import hybridsim as hs

from .._common import Errors, scalar, vector
from .design import v2_argument, zeta_of
from .systems import ChainedFormPlant, ReducedOrderObserver

__all__ = ["tracking_initial_state", "loop_signals", "loop_functions", "simulate", "estimates",
           "errors", "error_norm", "bounded_noise"]


def tracking_initial_state(loop, xi4=1.0, xi3=-1.0, xi2=0.5, x1=0.5):
    """Stacked x0 of :func:`~observers.time_varying.tracking_loop`: plant and a fresh observer.

    x1(0) = 0.5 is the paper's (Section IV-D); xi4(0) = 1, xi3(0) = -1,
    xi2(0) = 0.5 are ours (the paper does not give them).

    Examples
    --------
    >>> from observers.time_varying import tracking_loop
    >>> loop, v2 = tracking_loop()
    >>> tracking_initial_state(loop).tolist()      # plant [xi4, xi3, xi2, x1, q], observer
    [1.0, -1.0, 0.5, 0.5, 1.0, 0.0, 0.0, 0.0, 0.0]
    """
    obs = loop.systems["observer"]
    return loop.stack(plant=ChainedFormPlant.initial_state(xi4, xi3, xi2, x1),
                      observer=obs.initial_state())


def loop_signals(arc, loop, v2):
    r"""Along a run of :func:`~observers.time_varying.tracking_loop`, time-major, one row a sample.

    Returns a dict: ``t``, ``j``, ``xi`` (N, 4: xi1..xi4, xi1 = x1 + 2 sin t
    (42)), ``x1``, ``xhat2`` (the estimate (50) the feedback uses),
    ``v2`` (the control (58) as the loop applied it), ``v2_arg`` (the
    argument of sigma in (58): v2 = sigma(v2_arg)), ``zeta`` (N, 3, eq. 52)
    and ``filled`` (the observer's window is filled: q = 1).

    Examples
    --------
    >>> import hybridsim as hs
    >>> from observers.time_varying import tracking_loop
    >>> loop, v2 = tracking_loop()
    >>> arc = hs.simulate(loop, tracking_initial_state(loop), t_max=1.0, progress=False)
    >>> S = loop_signals(arc, loop, v2)
    >>> S["xi"].shape[1], bool(S["filled"].any())
    (4, False)
    """
    obs = loop.systems["observer"]
    P = arc.component("plant").x
    out = arc.outputs("observer")
    xh = obs.estimate(out, P[:, 1:2])[:, 0]
    vv = np.array([v2(tt, loop.outputs(x, tt, jj)) for x, tt, jj in zip(arc.x, arc.t, arc.j)])
    xi = np.column_stack([P[:, 3] + 2 * np.sin(arc.t), P[:, 2], P[:, 1], P[:, 0]])
    zeta = zeta_of(arc.t, P[:, 2], P[:, 1], P[:, 0]).T
    return dict(t=arc.t, j=arc.j, xi=xi, xhat2=xh, v2=vv,
                v2_arg=v2_argument(arc.t, xh, P[:, 1], P[:, 0]), zeta=zeta, x1=P[:, 3],
                filled=arc.component("observer").x[:, -1] >= 0.5)


def loop_functions(arc, loop, v2):
    r"""v2, xi3, xi4 as functions s -> float on a dense run of the loop (``dense=True``).

    What :func:`~observers.time_varying.residual_58` integrates: read off
    the arc's interpolant, independently of the observer's states.

    Examples
    --------
    >>> import hybridsim as hs
    >>> from observers.time_varying import tracking_loop
    >>> loop, v2 = tracking_loop()
    >>> arc = hs.simulate(loop, tracking_initial_state(loop), t_max=1.0, dense=True,
    ...                   progress=False)
    >>> v, xi3, xi4 = loop_functions(arc, loop, v2)
    >>> xi3(0.0), xi4(0.0)
    (-1.0, 1.0)
    """
    sl = loop.components["plant"]
    return (lambda s: v2(s, loop.outputs(arc.at(s), s, 0)),
            lambda s: float(arc.at(s)[sl][1]),
            lambda s: float(arc.at(s)[sl][0]))


# ---------------------------------------------------------------------------
# runs: simulate, estimates, errors
# ---------------------------------------------------------------------------
def bounded_noise(eps_bar, p, *, seed, terms=3):
    r"""A seeded measurement disturbance eps(t) of (17) with |eps(t)| <= eps_bar.

    eps_i(t) = eps_bar / sqrt(p) sum_k a_ik sin(w_ik t + phi_ik) with
    a_i >= 0, sum_k a_ik = 1, w_ik in [1, 10), phi_ik in [0, 2 pi), drawn
    from ``seed``; so |eps(t)| <= eps_bar (Euclidean norm) for all t, the
    bound eps_bar of (17) that (28) multiplies.

    Parameters
    ----------
    eps_bar : float >= 0
    p : int >= 1
        Number of outputs.
    seed : int or numpy.random.Generator
    terms : int >= 1
        Sinusoids per component.

    Returns
    -------
    callable t -> (p,) array

    Examples
    --------
    >>> import numpy as np
    >>> eps = bounded_noise(0.01, 2, seed=0)
    >>> bool(max(np.linalg.norm(eps(t)) for t in np.linspace(0, 10, 101)) <= 0.01)
    True
    """
    eps_bar = scalar("eps_bar", eps_bar, nonneg=True)
    for nm, v in (("p", p), ("terms", terms)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{nm} must be an int >= 1, got {v!r}")
    if seed is None:
        raise TypeError("seed must be an int or a numpy Generator (nothing is random without it)")
    rng = np.random.default_rng(seed)
    a = rng.dirichlet(np.ones(terms), size=p)
    w = rng.uniform(1.0, 10.0, size=(p, terms))
    ph = rng.uniform(0.0, 2 * np.pi, size=(p, terms))
    c = eps_bar / np.sqrt(p)
    return lambda t: c * np.sum(a * np.sin(w * t + ph), axis=1)


def _signal(name, f, dim):
    """A callable t -> (dim,) array, checked once at t = 0."""
    if not callable(f):
        raise TypeError(f"{name} must be a callable t -> ({dim},) array, got {type(f).__name__}")
    v = np.atleast_1d(np.asarray(f(0.0), dtype=float))
    if v.shape != (dim,):
        raise ValueError(f"{name}(t) must return shape ({dim},), got {v.shape} at t = 0")
    return lambda t: np.atleast_1d(np.asarray(f(t), dtype=float))


def simulate(observer, x0, xhat0=None, *, t_max, noise=None, seed=None, w=None, **simulate_kwargs):
    r"""Run an observer with its plant; the arc of the interconnection.

    The plant is ``observer.plant_model`` (the LTI plant (2)-(3) of
    :func:`lti_observer`, the chained form (44) of
    :func:`chained_form_observer`, else (16) with the observer's own data);
    the observer's input is [z + eps (17), w].

    Parameters
    ----------
    observer : ReducedOrderObserver
    x0 : array_like
        The plant's initial state (see ``observer.plant_model.description``).
    xhat0 : array_like, optional
        The observer's initial state: None (J_A = J_H = 0), [J_A, J_H]
        (2m,), or the full [J_A, J_H, s, q] (2m + 2,). By Theorem 1 the
        estimate after tau does not depend on it; before tau the estimate
        is the observer's ``xr_init``.
    t_max : float
        Horizon.
    noise : None, callable t -> (p,), or float
        The measurement disturbance eps of (17); a number eps_bar draws
        :func:`bounded_noise` (eps_bar, p, seed=seed).
    seed : int or numpy.random.Generator, optional
        Draws the noise when ``noise`` is a number (required then).
    w : callable t -> (w_dim,), optional
        The known signals of the observer's maps (required when
        ``observer.w_dim > 0``; e.g. v2 for the chained form), also fed to
        the plant.
    **simulate_kwargs
        Passed to :func:`hybridsim.simulate`; defaults rtol 1e-10, atol
        1e-12, progress False.

    Returns
    -------
    hybridsim.HybridArc
        Components ``"plant"`` and ``"observer"``.

    Raises
    ------
    TypeError, ValueError
        An argument of the wrong type or shape, naming it.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.time_varying import lti_observer, simulate, errors
    >>> obs, rc = lti_observer([[0.0, 1.0], [-2.0, -3.0]], [[1.0, 0.0]], tau=0.5)
    >>> arc = simulate(obs, [1.0, -1.0], t_max=1.0)
    >>> bool(np.abs(errors(arc, obs).e[arc.j >= 1]).max() < 1e-8)   # (14): exact for t >= tau
    True
    """
    if not isinstance(observer, ReducedOrderObserver):
        raise TypeError(f"observer must be a ReducedOrderObserver, got {type(observer).__name__}")
    pm, p, m = observer.plant_model, observer.p, observer.m
    xp0 = pm.initial_state(x0)
    if xhat0 is None:
        xo0 = observer.initial_state()
    else:
        v = vector("xhat0", xhat0)
        if v.shape == (2 * m,):
            xo0 = observer.initial_state(J_A=v[:m], J_H=v[m:])
        elif v.shape == (observer.state_dim,):
            xo0 = v
        else:
            raise ValueError(f"xhat0 must have shape ({2 * m},) = [J_A, J_H] or "
                             f"({observer.state_dim},) = [J_A, J_H, s, q], got {v.shape}")
    if noise is None:
        eps = lambda t: np.zeros(p)  # noqa: E731
    elif callable(noise):
        eps = _signal("noise", noise, p)
    else:
        if seed is None:
            raise TypeError("noise given as an amplitude needs seed= "
                            "(nothing is random without it)")
        eps = bounded_noise(scalar("noise", noise, nonneg=True), p, seed=seed)
    if observer.w_dim:
        if w is None:
            raise TypeError(f"w is required: the observer's maps read w_dim={observer.w_dim} "
                            "known signals (for the chained form: v2)")
        wf = _signal("w", w, observer.w_dim)
    elif w is not None:
        raise ValueError("w must be None: the observer has w_dim = 0")
    else:
        wf = lambda t: np.zeros(0)  # noqa: E731
    plant = pm.make()
    inputs = {"observer": lambda t, y: np.concatenate(
        [np.asarray(pm.measure(y["plant"]), dtype=float).reshape(p) + eps(t), wf(t)])}
    if int(plant.input_dim or 0):
        inputs["plant"] = lambda t, y: wf(t)
    sys = hs.Interconnection({"plant": plant, "observer": observer}, inputs=inputs)
    kwargs = dict(rtol=1e-10, atol=1e-12, progress=False)
    kwargs.update(simulate_kwargs)
    return hs.simulate(sys, sys.stack(plant=xp0, observer=xo0), t_max=t_max, **kwargs)


def _interconnection(arc, observer):
    sys = getattr(arc, "system", None)
    if (not isinstance(observer, ReducedOrderObserver) or sys is None
            or getattr(sys, "systems", {}).get("observer") is not observer
            or "plant" not in sys.systems):
        raise ValueError("arc must be a run of this observer with its plant: an interconnection "
                         "with components 'plant' and 'observer' (simulate() or tracking_loop())")
    return sys


def estimates(arc, observer):
    r"""The estimate xhat_r (23)/(27) at the arc's samples, shape (N, m).

    xhat_r = P + G y with the observer's output [P, G] and the measurement y
    it received (its input, noise included), see
    :meth:`ReducedOrderObserver.estimate`. Before tau: ``xr_init``.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.time_varying import lti_observer, simulate, estimates
    >>> obs, rc = lti_observer([[0.0, 1.0], [-2.0, -3.0]], [[1.0, 0.0]], tau=0.5)
    >>> estimates(simulate(obs, [1.0, -1.0], t_max=1.0), obs).shape[1]
    1
    """
    sys = _interconnection(arc, observer)
    u_of = sys.inputs["observer"]
    Y = np.array([np.atleast_1d(np.asarray(u_of(t, sys.outputs(x, t, j)),
                                           dtype=float))[: observer.p]
                  for x, t, j in zip(arc.x, arc.t, arc.j)])
    return observer.estimate(arc.outputs("observer"), Y.reshape(len(arc.t), observer.p))


def errors(arc, observer):
    r"""The estimation error xhat_r - x_r at the arc's samples, as an :class:`Errors`.

    ``errors(arc, observer).e`` (also ``["e"]``) is xhat_r - x_r, shape
    (N, m): zero (to the integrator's accuracy) at every sample with t >= tau
    after the observer's jump (Theorem 1, (24)); bounded by l_a |eps|_inf
    under unknown noise ((28)). x_r is read from the plant's state by
    ``observer.plant_model.x_r``; the samples' hybrid times are ``.t``,
    ``.j``.

    Parameters
    ----------
    arc : hybridsim.HybridArc
        A run of :func:`simulate` (or of
        :func:`~observers.time_varying.tracking_loop`) with this observer.
    observer : ReducedOrderObserver

    Returns
    -------
    observers._common.Errors

    Examples
    --------
    >>> import numpy as np
    >>> from observers.time_varying import lti_observer, simulate, errors
    >>> obs, rc = lti_observer([[0.0, 1.0], [-2.0, -3.0]], [[1.0, 0.0]], tau=0.5)
    >>> arc = simulate(obs, [1.0, -1.0], t_max=1.0)
    >>> E = errors(arc, obs)
    >>> E.e.shape == (arc.t.size, 1), bool(np.abs(E.e[arc.j == 0]).max() > 0.1)   # xr_init = 0
    (True, True)
    """
    xh = estimates(arc, observer)
    e = xh - np.asarray(observer.plant_model.x_r(arc["plant"].x), dtype=float).reshape(xh.shape)
    return Errors(arc.t, arc.j, e=e)


def error_norm(arc, observer, floor=0.0):
    r"""``fn(x, t, j) -> max(|xhat_r - x_r|, floor)`` on the arc's interconnection, for plots.

    The same quantity as ``errors(arc, observer).norm()``,
    as a function of the stacked state, for :func:`hybridsim.plot_flows`'s
    ``fn=`` (e.g. with ``yscale="log"``; ``floor`` > 0 keeps exact zeros on
    a log axis).

    Examples
    --------
    >>> import numpy as np
    >>> from observers.time_varying import lti_observer, simulate, errors, error_norm
    >>> obs, rc = lti_observer([[0.0, 1.0], [-2.0, -3.0]], [[1.0, 0.0]], tau=0.5)
    >>> arc = simulate(obs, [1.0, -1.0], t_max=1.0)
    >>> fn = error_norm(arc, obs)
    >>> bool(np.isclose(fn(arc.x[-1], arc.t[-1], arc.j[-1]), errors(arc, obs).norm()[-1]))
    True
    """
    sys = _interconnection(arc, observer)
    u_of, sl, pm = sys.inputs["observer"], sys.components["plant"], observer.plant_model
    floor = scalar("floor", floor, nonneg=True)

    def fn(x, t, j):
        outs = sys.outputs(x, t, j)
        y = np.atleast_1d(np.asarray(u_of(t, outs), dtype=float))[: observer.p]
        xh = observer.estimate(outs["observer"], y)
        xr = np.asarray(pm.x_r(np.asarray(x, dtype=float)[sl][None, :]), dtype=float).ravel()
        return max(float(np.linalg.norm(xh - xr)), floor)
    return fn
