r"""Section VI's example of paper 000 and how a run is made and read.

==============================  ================================================
:data:`EXAMPLE`                 Section VI's data (n, b, K, x(0), mu, gamma1, v(0), L)
:func:`simulate`                the calling pattern's run: plant + observer
:func:`simulate_example`        the same with this paper's keywords (v0, w0...)
:func:`errors`                  the calling pattern's errors: dict, main one "e"
:func:`error_components`        e = (w, x - x_hat), v, q along a run
:func:`settle_time`             last time max|e_i| > tol (the 1e-6 crossing)
:func:`gain_settling_time`      the time the gain v reaches 0 (Proposition 4's T)
:func:`example_norm`            ||xi||_r on the interconnection's state vector
:func:`consistent_euler`        the explicit Euler of ref. [8] as a scipy OdeSolver
==============================  ================================================

Two settling times are measured on a run, and they are not the same thing:

* the **settling time** T(e(0), v(0)) of Proposition 4 ((17), (18)) is the time
  at which e and v reach 0 together (proof of Theorem 3: e = D_r(v) eps with
  eps bounded, so e -> 0 exactly as v -> 0). :func:`gain_settling_time` measures
  it: the run switches to the settled mode when v reaches ``z_min`` (decision
  1), and v' = -gamma1 v^{1-mu} (8) then needs ``z_min^mu/(mu gamma1)`` more
  (0.0199 s for the example) to reach 0. For gamma2 = 0 this is T = 5 of (18);
  for gamma2 = 1 it is 7.81 s.
* the **1e-6 crossing** (:func:`settle_time`) is the last time at which
  ``max_i |e_i| > 1e-6``: 4.79 s for gamma2 = 0 and 7.27 s for gamma2 = 1. It
  is earlier because e ~ v^{r_i} shrinks faster than v near the end.

Examples
--------
>>> from observers.dynamic_gain import EXAMPLE, prescribed_time_observer, simulate, errors
>>> obs = prescribed_time_observer(EXAMPLE["L"], EXAMPLE["mu"], EXAMPLE["gamma1"],
...                                b=EXAMPLE["b"])
>>> arc = simulate(obs, None, None, t_max=1.0)     # Section VI's x(0), x_hat(0)
>>> errors(arc, obs)["e"].shape[1]                 # (w, x - x_hat): n + 1 columns
4
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import DenseOutput, OdeSolver

import hybridsim as hs
from hybridsim.testing import settling_time as _hs_settling_time
from observers._common import scalar
from observers.lmi import PAPER_L

from .design import weights
from .systems import DynamicGainObserver, example_plant

__all__ = ["EXAMPLE", "E0_EXAMPLE", "simulate", "simulate_example", "errors",
           "error_components", "settle_time", "gain_settling_time", "example_norm",
           "consistent_euler"]

#: Section VI: n = 3, b = (0, 0, 1), K = -[6, 11, 6], x(0) = (10, 0, -5),
#: mu = 0.2, gamma1 = 1, v(0) = 1, L printed in the paper.
EXAMPLE = dict(n=3, b=np.array([[0.0], [0.0], [1.0]]), K=-np.array([6.0, 11.0, 6.0]),
               x0=np.array([10.0, 0.0, -5.0]), mu=0.2, gamma1=1.0, v0=1.0, L=PAPER_L,
               t_max=10.0)

#: e(0) = (w(0), x(0) - x_hat(0)) of Section VI.
E0_EXAMPLE = np.concatenate([[0.0], EXAMPLE["x0"]])


def simulate_example(observer, *, noise=False, seed=0, t_max=10.0, x0=None, v0=1.0,
                     x_hat0=None, w0=0.0, method="Radau", rtol=None, atol=1e-10,
                     max_norm=1e3, **kw):
    """Simulate the plant of :func:`example_plant` with ``observer`` through hs.simulate.

    Parameters
    ----------
    observer : DynamicGainObserver
        Built with the plant's ``b = e_n`` (``b=EXAMPLE["b"]`` for n = 3).
    noise : bool
        Section VI's disturbances d_x, d_y (seeded by ``seed``).
    seed : int or numpy.random.Generator
    t_max : float
    x0 : (n,) array_like, optional
        The plant's x(0); default Section VI's (10, 0, -5) (n = 3) or
        (10, 0, ..., 0, -5).
    v0, x_hat0, w0 : optional
        The observer's initial state (Section VI: 1, 0, 0).
    method, rtol, atol, max_norm, **kw
        Passed to :func:`hybridsim.simulate`. ``max_norm`` turns the finite-time
        escape of gamma2 = 0 under noise into a clean BLOWUP termination.
        ``rtol`` defaults to 1e-8 without noise and 1e-6 with noise (the
        interpolated noise has a kink every 0.01 s, so tight tolerances only
        multiply the steps).

    Returns
    -------
    hybridsim.HybridArc
        Of ``hs.connect(plant, observer)``, components "plant" and "observer".

    Raises
    ------
    TypeError
        ``observer`` is not a :class:`DynamicGainObserver`.
    ValueError
        The observer was built without ``b=`` (or with a b other than the
        plant's b = e_n): the plant is driven by u = Kx + cos(10 t) through
        b = e_n, and an observer that does not add b u to its flow never
        converges (its error has the unknown forcing u); build it with
        ``b=EXAMPLE["b"]`` (n = 3) or ``b=np.eye(n)[:, -1:]``.

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, proposed_observer
    >>> obs = proposed_observer(EXAMPLE["L"], 0.2, 1.0, 1.0, b=EXAMPLE["b"])
    >>> simulate_example(obs, t_max=0.5).termination.name
    'T_MAX'
    """
    if not isinstance(observer, DynamicGainObserver):
        raise TypeError(f"observer must be a DynamicGainObserver, got {type(observer).__name__}")
    if rtol is None:
        rtol = 1e-6 if noise else 1e-8
    n = observer.n
    b_plant = np.eye(n)[:, -1:]
    if observer.m == 0:
        raise ValueError(
            f"observer was built without b=: the example plant is driven by the known control "
            f"u = Kx + cos(10 t) through b = e_{n}, and an observer without b never sees it, "
            f"so its estimate cannot converge; build the observer with "
            f"b=np.eye({n})[:, -1:] (EXAMPLE['b'] for n = 3)")
    if observer.b.shape != (n, 1) or not np.allclose(observer.b, b_plant, rtol=0, atol=1e-12):
        raise ValueError(
            f"observer.b must be the example plant's input matrix b = e_{n} (shape ({n}, 1)) "
            f"for the estimate to converge, got {observer.b.tolist()}")
    plant = example_plant(noise=noise, seed=seed, t_max=t_max, n=n)
    sys = hs.connect(plant, observer, names=("plant", "observer"))
    if x0 is None:
        x0 = EXAMPLE["x0"] if n == 3 else np.r_[10.0, np.zeros(n - 2), -5.0]
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (n,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 must be a finite vector of shape ({n},) (the plant's state, "
                         f"n = observer.n), got shape {x0.shape}")
    z0 = np.concatenate([x0, observer.initial_state(x_hat0, w0, v0)])
    # scipy's finite-difference Jacobian overflows harmlessly where the gain is
    # non-Lipschitz (z -> 0); a real overflow of the state ends the run (BLOWUP)
    with np.errstate(over="ignore"):
        return hs.simulate(sys, z0, t_max=t_max, j_max=5, method=method, rtol=rtol,
                           atol=atol, max_norm=max_norm, progress=False, **kw)


def simulate(observer, x0=None, xhat0=None, *, t_max, noise=None, seed=None, **kw):
    """Run ``observer`` with Section VI's plant: the calling pattern's ``simulate``.

    The same run as :func:`simulate_example` (which it calls), under the names
    every paper package uses.

    Parameters
    ----------
    observer : DynamicGainObserver
        Built with ``b=EXAMPLE["b"]`` (n = 3) or ``b=np.eye(n)[:, -1:]``.
    x0 : (n,) array_like or None
        The plant's x(0); None: Section VI's (10, 0, -5).
    xhat0 : (n,) array_like or None
        The estimate x_hat(0); None: 0 (Section VI).
    t_max : float
        Horizon (keyword, required).
    noise : None or bool
        None/False: d = 0 (Fig. 1); True: Section VI's disturbances (Fig. 2).
    seed : int, numpy.random.Generator or None
        Seed of the noise; None means 0, so a run is always reproducible.
    **kw
        ``v0``, ``w0`` (the filter's initial state, default 1 and 0), and
        :func:`hybridsim.simulate`'s keywords (``method``, ``rtol``, ``atol``,
        ``max_norm``...), as in :func:`simulate_example`.

    Returns
    -------
    hybridsim.HybridArc
        Components ``"plant"`` and ``"observer"``.

    Raises
    ------
    TypeError
        ``noise`` is neither None nor a bool.

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, proposed_observer
    >>> obs = proposed_observer(EXAMPLE["L"], 0.2, 1.0, 1.0, b=EXAMPLE["b"])
    >>> arc = simulate(obs, [10.0, 0.0, -5.0], [0.0, 0.0, 0.0], t_max=0.5)
    >>> arc["observer"].x.shape[1]                   # (w, x_hat_1..3, v, q)
    6
    """
    if noise is None:
        noise = False
    if not isinstance(noise, (bool, np.bool_)):
        raise TypeError(f"noise must be None or a bool (Section VI's disturbances), "
                        f"got {type(noise).__name__}")
    return simulate_example(observer, noise=bool(noise), seed=0 if seed is None else seed,
                            t_max=t_max, x0=x0, x_hat0=xhat0, **kw)


def error_components(arc, observer, plant="plant", name="observer"):
    """e = (w, x - x_hat) (N, n+1), v (N,), q (N,) along an interconnection arc.

    e is the state of the error system (9) (d = 0) or (19).

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, proposed_observer, simulate
    >>> obs = proposed_observer(EXAMPLE["L"], 0.2, 1.0, 1.0, b=EXAMPLE["b"])
    >>> e, v, q = error_components(simulate(obs, t_max=0.1), obs)
    >>> e[0].tolist(), float(v[0]), float(q[0])           # e(0) = (w(0), x(0) - x_hat(0))
    ([0.0, 10.0, 0.0, -5.0], 1.0, 0.0)
    """
    xp = arc[plant].x
    xo = arc[name].x
    n = observer.n
    e = np.column_stack([xo[:, 0], xp[:, :n] - xo[:, 1:n + 1]])
    return e, xo[:, n + 1], xo[:, n + 2]


def errors(arc, observer):
    """The error signals of a run, by name: the calling pattern's ``errors``.

    Returns
    -------
    dict
        ``"e"``: (N, n+1), the paper's e = (w, x - x_hat) of (9) (column 0 the
        filter state w, columns 1..n the estimation error); ``"x"``: (N, n),
        the estimation error x - x_hat alone; ``"v"``: (N,), the filter (8);
        ``"q"``: (N,), the settled flag (decision 1). The same arrays as
        :func:`error_components`.

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, proposed_observer, simulate
    >>> obs = proposed_observer(EXAMPLE["L"], 0.2, 1.0, 1.0, b=EXAMPLE["b"])
    >>> err = errors(simulate(obs, t_max=0.1), obs)
    >>> sorted(err), err["x"][0].tolist()
    (['e', 'q', 'v', 'x'], [10.0, 0.0, -5.0])
    """
    e, v, q = error_components(arc, observer)
    return {"e": e, "x": e[:, 1:], "v": v, "q": q}


def example_norm(observer):
    """``y -> ||xi||_r`` on the state vector of ``hs.connect(plant, observer)``.

    The plant's x first, then the observer's (w, x_hat, v, q): the norm of
    Section VI that drives the state-dependent step of :func:`consistent_euler`.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.dynamic_gain import EXAMPLE, proposed_observer
    >>> obs = proposed_observer(EXAMPLE["L"], 0.2, 1.0, 1.0, b=EXAMPLE["b"])
    >>> example_norm(obs)(np.r_[1.0, 0, 0, 0, 0, 0, 0, 2.0, 0])       # |v| + |e_2|^(1/0.8)
    3.0
    """
    n, mu = observer.n, observer.mu
    r_inv = 1.0 / weights(n, mu)

    def norm(y):
        e0 = y[n]
        ex = y[:n] - y[n + 1:2 * n + 1]
        return (abs(y[2 * n + 1]) + abs(e0) ** r_inv[0]
                + float(np.sum(np.abs(ex) ** r_inv[1:])))
    return norm


def settle_time(arc, observer, *, tol=1e-6, name="observer"):
    """The 1e-6 crossing: the last sample time at which ``max_i |e_i| > tol``.

    A thin wrapper of :func:`hybridsim.testing.settling_time` (infinity norm) on
    the error e = (w, x - x_hat) of :func:`error_components`; ``nan`` when the
    error is above ``tol`` at the end of the arc. Not Proposition 4's settling
    time (see :func:`gain_settling_time` and the module notes).

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, prescribed_time_observer, simulate
    >>> obs = prescribed_time_observer(EXAMPLE["L"], 0.2, 1.0, b=EXAMPLE["b"])
    >>> round(settle_time(simulate(obs, t_max=5.1), obs), 2)
    4.79
    """
    e, _, _ = error_components(arc, observer, name=name)
    t, _ = _hs_settling_time(arc, e, threshold=tol, norm="inf")
    return float(t) if np.isfinite(t) else np.nan


def gain_settling_time(arc, observer):
    """Proposition 4's settling time on a run: the time at which v reaches 0.

    The run switches to the settled mode (decision 1) when v reaches
    ``z_min``; from there (8) with e = 0, ``v' = -gamma1 v^{1-mu}``, takes
    ``z_min^mu / (mu gamma1)`` more to reach 0. So this is the switch time
    plus that, where e and v vanish together (T of (17), (18)).

    Returns
    -------
    float
        ``nan`` when the run has not switched (v never reached z_min).

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, prescribed_time_observer, simulate
    >>> obs = prescribed_time_observer(EXAMPLE["L"], 0.2, 1.0, b=EXAMPLE["b"])
    >>> round(gain_settling_time(simulate(obs, t_max=5.1), obs), 4)     # T = 5 of (18)
    5.0
    """
    if arc.jump_times.size == 0 or observer.gamma1 <= 0:
        return np.nan
    rest = observer.z_min ** observer.mu / (observer.mu * observer.gamma1)
    return float(arc.jump_times[0] + rest)


# ---------------------------------------------------------------------------
# the consistent explicit Euler scheme of [8], as a scipy OdeSolver for hs.simulate
# ---------------------------------------------------------------------------
class _LinearDense(DenseOutput):
    def __init__(self, t_old, t, y_old, y):
        super().__init__(t_old, t)
        self.y_old, self.dy = y_old, y - y_old
        self.h = t - t_old

    def _call_impl(self, t):
        s = (np.asarray(t) - self.t_old) / self.h
        if np.ndim(t) == 0:
            return self.y_old + s * self.dy
        return self.y_old[:, None] + s[None, :] * self.dy[:, None]


def consistent_euler(norm, mu, dt0=1e-2, h_min=1e-5):
    """An explicit Euler OdeSolver with the state-dependent step of [8].

    Step ``h_k = dt0 * min(1, norm(y_k))^mu``: for a system r-homogeneous of degree
    ``-mu`` (the error system (9)) this is the uniform step of the time-rescaled,
    degree-0 system, so the discretisation keeps finite-time convergence (the steps
    shrink geometrically as the state approaches 0).  Far from the origin the step
    is capped at ``dt0`` (the paper's basic step 1e-2); ``h_min`` (default 1e-5,
    reached when ``norm <= 1e-15``) keeps it from stalling once the error is at
    rounding level (the paper stops at N_max = 1e6 iterations instead).  Pass the
    returned class as ``method=`` to ``hs.simulate``; rtol/atol are ignored.

    Parameters
    ----------
    norm : callable
        ``norm(y) -> float``: the homogeneous norm of the solver's state vector
        (for plant+observer: :func:`example_norm`).
    mu : float
    dt0, h_min : float

    Returns
    -------
    type
        A subclass of :class:`scipy.integrate.OdeSolver`.

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, prescribed_time_observer
    >>> obs = prescribed_time_observer(EXAMPLE["L"], 0.2, 1.0, b=EXAMPLE["b"])
    >>> consistent_euler(example_norm(obs), 0.2).__name__
    'ConsistentEuler(dt0=0.01, mu=0.2)'

    References
    ----------
    [8] Efimov, Polyakov, Aleksandrov, Automatica 109, 2019; Section VI of [1].
    """
    if not callable(norm):
        raise TypeError(f"norm must be callable, got {type(norm).__name__}")
    mu = scalar("mu", mu, positive=True)
    dt0 = scalar("dt0", dt0, positive=True)
    h_min = scalar("h_min", h_min, positive=True)

    class ConsistentEuler(OdeSolver):
        def __init__(self, fun, t0, y0, t_bound, max_step=np.inf, rtol=None, atol=None,
                     first_step=None, **extraneous):
            super().__init__(fun, t0, y0, t_bound, vectorized=False)
            self.max_step = max_step
            self.t_old = None
            self.y_old = None
            self.steps = 0

        def _step_impl(self):
            y = self.y
            f = self.fun(self.t, y)
            h = dt0 * min(1.0, float(norm(y))) ** mu
            h = min(max(h, h_min), self.max_step, abs(self.t_bound - self.t))
            self.t_old, self.y_old = self.t, y
            self.t = self.t + h
            self.y = y + h * f
            self.steps += 1
            return True, None

        def _dense_output_impl(self):
            return _LinearDense(self.t_old, self.t, self.y_old, self.y)

    ConsistentEuler.__name__ = f"ConsistentEuler(dt0={dt0:g}, mu={mu:g})"
    return ConsistentEuler
