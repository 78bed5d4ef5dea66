r"""Section IV of paper 001 (the chained-form example), and how a run is made and read.

The paper's example
    :func:`example_data` (47)-(48) (Lambda = 1 - e^{4 pi}), :func:`estimate_49`
    (49)/(50) by quadrature, :func:`sigma`, :func:`zeta_of` (52),
    :func:`v2_feedback` (57), :func:`chained_form_observer` (Section IV-B),
    :func:`tracking_loop` the output feedback (58)-(59), :func:`loop_signals`,
    :func:`residual_58`.
Runs (the calling pattern of :mod:`observers`)
    :func:`simulate` (observer with its plant through
    :func:`hybridsim.simulate`), :func:`estimates`, :func:`errors`,
    :func:`bounded_noise` (a seeded measurement disturbance eps of (17)).

Decisions (a careful reading of the paper)
------------------------------------------
* **Validity range of (50).** The observer uses the model (45), which holds
  only where x1 = 0, i.e. for t >= sqrt|x1(0)|. The identity (50)
  integrates the model over the whole window [t - 2 pi, t], so it holds for
  t >= 2 pi + sqrt|x1(0)|, not for t >= max{2 pi, sqrt|x1(0)|} as printed.
* **(58) is a distributed-delay equation, not an algebraic loop.** v2(t)
  enters (58) only inside int_{t-2 pi}^t (1 - e^{M(m, t)}) v2(m) dm, whose
  value does not depend on v2 at the single instant t; :func:`tracking_loop`
  builds it as the observer (whose states integrate v2) fed back through
  (57), and :func:`residual_58` checks (58) literally along a run.
* **Before 2 pi** the window is not filled: the feedback uses the estimate
  ``xr_init`` (0 by default), our choice.

Examples
--------
>>> import numpy as np
>>> from observers import time_varying as tv
>>> obs = tv.chained_form_observer()
>>> arc = tv.simulate(obs, [0.8, -0.4, 0.6, 0.0], t_max=2 * np.pi + 0.5,
...                   w=lambda t: [0.5 * np.cos(1.3 * t)])
>>> e = tv.errors(arc, obs)                        # xhat_r - x_r, shape (N, 1)
>>> bool(np.abs(e[arc.j >= 1]).max() < 1e-8)      # exact once the window is filled (50)
True
"""
from __future__ import annotations

import numpy as np
from scipy import integrate

import hybridsim as hs

from .._common import scalar, vector
from .systems import ChainedFormPlant, PlantModel, ReducedOrderObserver

__all__ = ["TAU_EXAMPLE", "example_data", "estimate_49", "sigma", "zeta_of", "v2_feedback",
           "chained_form_observer", "tracking_loop", "tracking_initial_state", "loop_signals",
           "residual_58", "simulate", "estimates", "errors", "error_norm", "bounded_noise"]

#: tau of the example (Section IV-B): the period 2 pi of A1(t) = 2 cos t.
TAU_EXAMPLE = 2.0 * np.pi


def example_data():
    r"""The data (47)-(48) of the example, as a dict of callables and constants.

    Keys: ``A1`` (2 cos t), ``A2`` (0), ``L`` (-2 cos t), ``Ldot``
    (2 sin t), ``H`` (-4 cos^2 t), ``D`` (2 sin t - 8 cos^3 t, eq. 22),
    ``Phi_A2`` (1), ``Phi_H`` (e^{4 int_s^t cos^2} =
    e^{2(t - s) + sin 2t - sin 2s}, eq. 48), ``tau`` (2 pi), ``Lambda``
    (1 - e^{4 pi}). All matrices are 1 x 1.

    References
    ----------
    [1] eqs. (45)-(48).
    """
    one = lambda v: np.array([[v]])  # noqa: E731
    return dict(
        A1=lambda t: one(2 * np.cos(t)),
        A2=lambda t: one(0.0),
        L=lambda t: one(-2 * np.cos(t)),
        Ldot=lambda t: one(2 * np.sin(t)),
        H=lambda t: one(-4 * np.cos(t) ** 2),
        D=lambda t: one(2 * np.sin(t) - 8 * np.cos(t) ** 3),
        Phi_A2=lambda t, s: one(1.0),
        Phi_H=lambda t, s: one(np.exp(2 * (t - s) + np.sin(2 * t) - np.sin(2 * s))),
        tau=TAU_EXAMPLE,
        Lambda=1.0 - np.exp(4 * np.pi),
    )


def _M(m, t):
    """script M(m, t) = 2(m - t + 2 pi) + sin 2m - sin 2t (after (58))."""
    return 2 * (m - t + 2 * np.pi) + np.sin(2 * m) - np.sin(2 * t)


def estimate_49(t, xi3, v2, epsrel=1e-11):
    r"""The estimate (49) of xi2(t), printed form, by quadrature.

    Parameters
    ----------
    t : float, t >= 2 pi
    xi3, v2 : callable s -> float
        The measured xi3 and the input v2 on [t - 2 pi, t].

    Returns
    -------
    float
        xhat_r(t); equals xi2(t) (50) when (45) holds on the whole window,
        i.e. for t >= 2 pi + sqrt|x1(0)| on the full system (44).

    References
    ----------
    [1] eqs. (49)-(50).
    """
    if not (callable(xi3) and callable(v2)):
        raise TypeError("xi3 and v2 must be callables s -> float")
    if t < TAU_EXAMPLE:
        raise ValueError(f"t must be >= 2 pi (the window [t - 2 pi, t] must be measured), got {t}")
    c = 1.0 / (1.0 - np.exp(4 * np.pi))
    a = 2 * np.cos(t) * c * (-np.exp(4 * np.pi) * xi3(t) + xi3(t - TAU_EXAMPLE))
    f = lambda m: (c * (1 - np.exp(_M(m, t))) * v2(m)  # noqa: E731
                   + 2 * c * np.exp(_M(m, t)) * (4 * np.cos(m) ** 3 - np.sin(m)) * xi3(m))
    return float(a + integrate.quad(f, t - TAU_EXAMPLE, t, epsrel=epsrel, epsabs=1e-13,
                                    limit=400)[0])


def sigma(s):
    r"""sigma(s) = s / sqrt(1 + s^2) (after (54))."""
    s = np.asarray(s, dtype=float)
    return s / np.sqrt(1.0 + s * s)


def zeta_of(t, xi2, xi3, xi4):
    r"""(zeta1, zeta2, zeta3) of (52); arrays broadcast (time-major use: columns)."""
    return np.array([xi4 - 2 * np.sin(t) * xi3 - np.cos(2 * t) * xi2,
                     xi3 - 2 * np.sin(t) * xi2,
                     xi2 * np.ones_like(np.asarray(t, float))])


def v2_feedback(t, xi2, xi3, xi4):
    r"""The bounded state feedback (57), grouped form.

    v2 = sigma(cos 2t xi4 + 2 [1 - cos 2t] sin t xi3
               - [cos^2 2t + 4 sin^2 t + 1] xi2).

    With xi2 replaced by the estimate (50) this is (58).

    References
    ----------
    [1] eqs. (54), (57), (58).
    """
    return sigma(np.cos(2 * t) * xi4 + 2 * (1 - np.cos(2 * t)) * np.sin(t) * xi3
                 - (np.cos(2 * t) ** 2 + 4 * np.sin(t) ** 2 + 1) * xi2)




def chained_form_observer(xr_init=0.0, z_history=None):
    r"""The observer of Section IV-B for (45): tau = 2 pi, L = -2 cos t, Lambda = 1 - e^{4 pi}.

    Input [xi3, v2] (w = v2, delta2 = v2, delta1 = 0), closed forms (48) for
    Phi_H and Phi_A2 = 1.

    References
    ----------
    [1] eqs. (45)-(50).
    """
    ex = example_data()
    obs = ReducedOrderObserver(ex["tau"], ex["A1"], ex["A2"], ex["L"], ex["Phi_A2"], ex["Phi_H"],
                               Ldot=ex["Ldot"], delta2=lambda t, z, w: w, p=1, m=1, w_dim=1,
                               xr_init=[xr_init], z_history=z_history)
    obs.plant_model = PlantModel(
        make=ChainedFormPlant, measure=lambda y: np.asarray(y)[1:2],
        x_r=lambda X: np.asarray(X)[:, 2:3],
        initial_state=lambda x0: ChainedFormPlant.initial_state(*vector("x0", x0, 4)),
        description="ChainedFormPlant: (44) with input v2; x0 = (xi4, xi3, xi2, x1)")
    return obs


def tracking_loop(xr_init=0.0, feedback="estimate"):
    r"""The output-feedback tracking loop (44) + (58) as an interconnection.

    Components ``"plant"`` (:class:`ChainedFormPlant`) and ``"observer"``
    (:func:`chained_form_observer`). The plant's input is

        v2(t) = (57) with xi2 replaced by xhat2(t) = P(t) + G(t) xi3(t),

    which is (58): v2(t) depends on the past of v2 only through the
    observer's states, so there is no algebraic loop (module docstring).
    Before 2 pi (window not filled) xhat2 = ``xr_init``. The observer reads
    xi3(t - 2 pi) from the plant's history.

    Parameters
    ----------
    xr_init : float
        Estimate used before t = 2 pi.
    feedback : {"estimate", "state"}
        "state" feeds back the true xi2 (the state feedback (57)), for
        comparison.

    Returns
    -------
    loop : hybridsim.Interconnection
    v2 : callable (t, y) -> float
        The control, from the interconnection's outputs dict y.

    References
    ----------
    [1] eqs. (51)-(59).
    """
    if feedback not in ("estimate", "state"):
        raise ValueError(f"feedback must be 'estimate' or 'state', got {feedback!r}")
    plant = ChainedFormPlant()
    obs = chained_form_observer(xr_init, z_history=lambda s: np.array([plant.history(s)[1]]))
    if feedback == "state":
        plant.output_dim = 4
        plant.output = lambda x, t, j: np.array([x[0], x[1], x[3], x[2]])

    def v2(t, y):
        yp = y["plant"]
        if feedback == "state":
            xi2h = yp[3]
        else:
            xi2h = obs.estimate(y["observer"], yp[1:2])[0]
        return float(v2_feedback(t, xi2h, yp[1], yp[0]))

    loop = hs.Interconnection({"plant": plant, "observer": obs},
                              inputs={"plant": lambda t, y: np.array([v2(t, y)]),
                                      "observer": lambda t, y: np.array([y["plant"][1], v2(t, y)])})
    return loop, v2


def tracking_initial_state(loop, xi4=1.0, xi3=-1.0, xi2=0.5, x1=0.5):
    """Stacked x0 of :func:`tracking_loop`: plant (xi4, xi3, xi2, x1) and a fresh observer."""
    obs = loop.systems["observer"]
    return loop.stack(plant=ChainedFormPlant.initial_state(xi4, xi3, xi2, x1),
                      observer=obs.initial_state())


def loop_signals(arc, loop, v2):
    r"""Along a run of :func:`tracking_loop`: t, xi (N, 4: xi1..xi4), xhat2, v2, zeta (N, 3).

    xi1 = x1 + 2 sin t (42). Time-major arrays, one row per sample.
    """
    obs = loop.systems["observer"]
    P = arc.component("plant").x
    out = arc.outputs("observer")
    xh = obs.estimate(out, P[:, 1:2])[:, 0]
    vv = np.array([v2(tt, loop.outputs(x, tt, jj)) for x, tt, jj in zip(arc.x, arc.t, arc.j)])
    xi = np.column_stack([P[:, 3] + 2 * np.sin(arc.t), P[:, 2], P[:, 1], P[:, 0]])
    zeta = zeta_of(arc.t, P[:, 2], P[:, 1], P[:, 0]).T
    return dict(t=arc.t, j=arc.j, xi=xi, xhat2=xh, v2=vv, zeta=zeta, x1=P[:, 3])


def residual_58(arc, loop, v2, t):
    r"""v2(t) minus the right-hand side of (58) evaluated literally along a run.

    The right-hand side integrates the recorded v2 and xi3 over
    [t - 2 pi, t] with adaptive quadrature on the arc's dense output, i.e.
    independently of the observer's states. The run must use ``dense=True``.

    References
    ----------
    [1] eqs. (58)-(59).
    """
    if t < TAU_EXAMPLE:
        raise ValueError(f"t must be >= 2 pi (the window of (58) must lie in the run), got {t}")
    plant = lambda s: arc.at(s)[loop.components["plant"]]  # noqa: E731
    vfun = lambda s: v2(s, loop.outputs(arc.at(s), s, 0))  # noqa: E731
    cL = (np.cos(2 * t) ** 2 + 4 * np.sin(t) ** 2 + 1) / (1 - np.exp(4 * np.pi))
    a = t - TAU_EXAMPLE
    # breakpoints: the jumps (v2 is discontinuous where the observer's window fills)
    pts = [s for s in arc.jump_times if a < s < t] or None
    I1 = integrate.quad(lambda s: (1 - np.exp(_M(s, t))) * vfun(s), a, t, limit=400,
                        epsrel=1e-10, epsabs=1e-12, points=pts)[0]
    I2 = integrate.quad(lambda s: np.exp(_M(s, t)) * (4 * np.cos(s) ** 3 - np.sin(s)) * plant(s)[1],
                        a, t, limit=400, epsrel=1e-10, epsabs=1e-12, points=pts)[0]
    xt = plant(t)
    rhs = sigma(np.cos(2 * t) * xt[0] + 2 * (1 - np.cos(2 * t)) * np.sin(t) * xt[1]
                - cL * I1 - 2 * cL * I2
                - 2 * np.cos(t) * cL * (-np.exp(4 * np.pi) * xt[1] + plant(a)[1]))
    return float(vfun(t) - rhs)




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
    >>> bool(np.abs(errors(arc, obs)[arc.j >= 1]).max() < 1e-8)   # (14): exact for t >= tau
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
    r"""The estimation error xhat_r - x_r at the arc's samples, shape (N, m).

    Zero (to the integrator's accuracy) at every sample with t >= tau after
    the observer's jump (Theorem 1, (24)); bounded by l_a |eps|_inf under
    unknown noise ((28)). x_r is read from the plant's state by
    ``observer.plant_model.x_r``.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.time_varying import lti_observer, simulate, errors
    >>> obs, rc = lti_observer([[0.0, 1.0], [-2.0, -3.0]], [[1.0, 0.0]], tau=0.5)
    >>> arc = simulate(obs, [1.0, -1.0], t_max=1.0)
    >>> bool(np.abs(errors(arc, obs)[arc.j == 0]).max() > 0.1)   # before tau: xr_init = 0
    True
    """
    xh = estimates(arc, observer)
    return xh - np.asarray(observer.plant_model.x_r(arc["plant"].x), dtype=float).reshape(xh.shape)


def error_norm(arc, observer, floor=0.0):
    r"""``fn(x, t, j) -> max(|xhat_r - x_r|, floor)`` on the arc's interconnection, for plots.

    The same quantity as ``np.linalg.norm(errors(arc, observer), axis=1)``,
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
    >>> bool(np.isclose(fn(arc.x[-1], arc.t[-1], arc.j[-1]), np.linalg.norm(errors(arc, obs)[-1])))
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
