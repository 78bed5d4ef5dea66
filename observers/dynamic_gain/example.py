r"""Section VI's example of paper 000 and how a run is made and read.

==============================  ================================================
:data:`EXAMPLE`                 Section VI's data (n, b, K, x(0), mu, gamma1, v(0), L)
:func:`simulate`                a run: plant (1) + observer through hs.simulate
                                (or the Euler scheme of ref. [8], ``euler_dt0=``)
:func:`errors`                  e = (w, x - x_hat), x - x_hat, v, q along a run
:func:`settle_time`             last time max|e_i| > tol (the 1e-6 crossing), located
:func:`switch_time`             the settled switch (v = z_min, decision 1)
:func:`gain_settling_time`      the time the gain v reaches 0 (Proposition 4's T)
:func:`example_norm`            ||xi||_r on the interconnection's state vector
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
  ``max_i |e_i| > 1e-6``, located between the samples on the arc's
  interpolant: 4.79 s for gamma2 = 0 and 7.28 s for gamma2 = 1. It is
  earlier because e ~ v^{r_i} shrinks faster than v near the end.

Examples
--------
>>> from observers.dynamic_gain import EXAMPLE, prescribed_time_observer, simulate, errors
>>> obs = prescribed_time_observer(EXAMPLE["L"], EXAMPLE["mu"], EXAMPLE["gamma1"],
...                                b=EXAMPLE["b"])
>>> arc = simulate(obs, None, None, t_max=1.0)     # Section VI's x(0), x_hat(0)
>>> errors(arc, obs).e.shape[1]                    # (w, x - x_hat): n + 1 columns
4
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

import hybridsim as hs
from observers._common import Errors, scalar
from observers.lmi import PAPER_L

from .design import weights
from .systems import ConsistentEuler, DynamicGainObserver, example_plant

__all__ = ["EXAMPLE", "E0_EXAMPLE", "simulate", "errors", "settle_time", "switch_time",
           "gain_settling_time", "example_norm"]

#: Section VI: n = 3, b = (0, 0, 1), K = -[6, 11, 6], x(0) = (10, 0, -5),
#: mu = 0.2, gamma1 = 1, v(0) = 1, L printed in the paper.
EXAMPLE = dict(n=3, b=np.array([[0.0], [0.0], [1.0]]), K=-np.array([6.0, 11.0, 6.0]),
               x0=np.array([10.0, 0.0, -5.0]), mu=0.2, gamma1=1.0, v0=1.0, L=PAPER_L,
               t_max=10.0)

#: e(0) = (w(0), x(0) - x_hat(0)) of Section VI.
E0_EXAMPLE = np.concatenate([[0.0], EXAMPLE["x0"]])


def simulate(observer, x0=None, xhat0=None, *, t_max, noise=None, seed=None, v0=1.0,
             w0=0.0, euler_dt0=None, **kw):
    """Run ``observer`` on Section VI's plant (1) through :func:`hybridsim.simulate`.

    The interconnection ``hs.connect(example_plant(...), observer)``, from
    the plant's x(0) and the observer's ``(w0, xhat0, v0, q = 0)``.

    Parameters
    ----------
    observer : DynamicGainObserver
        Built with the plant's ``b = e_n``: ``b=EXAMPLE["b"]`` (n = 3) or
        ``b=np.eye(n)[:, -1:]``.
    x0 : (n,) array_like or None
        The plant's x(0); None: Section VI's (10, 0, -5) (n = 3) or
        (10, 0, ..., 0, -5).
    xhat0 : (n,) array_like or None
        The estimate x_hat(0); None: 0 (Section VI).
    t_max : float
        Horizon (keyword, required).
    noise : None or bool
        None/False: d = 0 (Fig. 1); True: Section VI's disturbances (Fig. 2).
    seed : int, numpy.random.Generator or None
        Seed of the noise; None means 0, so a run is always reproducible.
    v0, w0 : float
        The filters' initial states v(0), w(0) (Section VI: 1 and 0).
    euler_dt0 : float, optional
        Run the paper's own integrator instead, the explicit Euler scheme with
        state-dependent step of ref. [8] with this basic step (Section VI:
        1e-2): the interconnection wrapped in :class:`ConsistentEuler`, a jump
        per step. Its arc has the interconnection's components and
        ``"scheme"`` (timer, step).
    **kw
        :func:`hybridsim.simulate`'s keywords. Defaults: ``method`` Radau
        without noise, RK45 with noise (decision 7); ``rtol`` 1e-8 without
        noise, 1e-6 with noise (the interpolated noise has a kink every
        0.01 s, so tight tolerances only multiply the steps); ``atol``
        1e-10; ``max_norm`` 1e3 (the finite-time escape of gamma2 = 0 under
        noise ends as a clean BLOWUP); ``j_max`` 5 (``inf`` with
        ``euler_dt0``).

    Returns
    -------
    hybridsim.HybridArc
        Components ``"plant"`` and ``"observer"``.

    Raises
    ------
    TypeError
        ``observer`` is not a :class:`DynamicGainObserver`, or ``noise`` is
        neither None nor a bool.
    ValueError
        The observer was built without ``b=`` (or with a b other than the
        plant's b = e_n): the plant is driven by u = Kx + cos(10 t) through
        b = e_n, and an observer that does not add b u to its flow never
        converges (its error has the unknown forcing u); build it with
        ``b=EXAMPLE["b"]`` (n = 3) or ``b=np.eye(n)[:, -1:]``. Or x0 of the
        wrong shape.

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, proposed_observer
    >>> obs = proposed_observer(EXAMPLE["L"], 0.2, 1.0, 1.0, b=EXAMPLE["b"])
    >>> arc = simulate(obs, [10.0, 0.0, -5.0], [0.0, 0.0, 0.0], t_max=0.5)
    >>> arc["observer"].x.shape[1], arc.termination.name   # (w, x_hat_1..3, v, q)
    (6, 'T_MAX')
    """
    if not isinstance(observer, DynamicGainObserver):
        raise TypeError(f"observer must be a DynamicGainObserver, got {type(observer).__name__}")
    if noise is None:
        noise = False
    if not isinstance(noise, (bool, np.bool_)):
        raise TypeError(f"noise must be None or a bool (Section VI's disturbances), "
                        f"got {type(noise).__name__}")
    noise = bool(noise)
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
    plant = example_plant(noise=noise, seed=0 if seed is None else seed, t_max=t_max, n=n)
    sys = hs.connect(plant, observer, names=("plant", "observer"))
    if x0 is None:
        x0 = EXAMPLE["x0"] if n == 3 else np.r_[10.0, np.zeros(n - 2), -5.0]
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (n,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 must be a finite vector of shape ({n},) (the plant's state, "
                         f"n = observer.n), got shape {x0.shape}")
    z0 = np.concatenate([x0, observer.initial_state(xhat0, w0, v0)])
    opts = dict(method="RK45" if noise else "Radau", rtol=1e-6 if noise else 1e-8,
                atol=1e-10, max_norm=1e3, j_max=5, progress=False)
    if euler_dt0 is not None:
        sys = ConsistentEuler(sys, example_norm(observer), observer.mu,
                              dt0=scalar("euler_dt0", euler_dt0, positive=True))
        z0 = sys.initial_state(z0)
        opts.update(method="RK23", j_max=np.inf)
    opts.update(kw)
    # scipy's finite-difference Jacobian overflows harmlessly where the gain is
    # non-Lipschitz (z -> 0); a real overflow of the state ends the run (BLOWUP)
    with np.errstate(over="ignore"):
        return hs.simulate(sys, z0, **opts, t_max=t_max)


def errors(arc, observer, *, plant="plant", name="observer"):
    """The error signals of a run (the contract's ``errors``).

    Parameters
    ----------
    arc : hybridsim.HybridArc
        A run of :func:`simulate` (components ``plant`` and ``name``).
    observer : DynamicGainObserver
    plant, name : str
        The components' names.

    Returns
    -------
    observers._common.Errors
        ``"e"``: (N, n+1), the paper's e = (w, x - x_hat) of (9)/(19)
        (column 0 the filter state w, columns 1..n the estimation error);
        ``"x"``: (N, n), the estimation error x - x_hat alone; ``"v"``: (N,),
        the filter (8); ``"q"``: (N,), the settled flag (decision 1).

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, proposed_observer, simulate
    >>> obs = proposed_observer(EXAMPLE["L"], 0.2, 1.0, 1.0, b=EXAMPLE["b"])
    >>> err = errors(simulate(obs, t_max=0.1), obs)
    >>> sorted(err), err["x"][0].tolist(), err.e[0].tolist()   # e(0) = (w(0), x(0) - x_hat(0))
    (['e', 'q', 'v', 'x'], [10.0, 0.0, -5.0], [0.0, 10.0, 0.0, -5.0])
    """
    e = _error(arc[plant].x, arc[name].x, observer.n)
    xo = arc[name].x
    n = observer.n
    return Errors(arc.t, arc.j, e=e, x=e[:, 1:], v=xo[:, n + 1], q=xo[:, n + 2])


def _error(xp, xo, n):
    """e = (w, x - x_hat) from plant and observer states (rows)."""
    return np.column_stack([xo[:, 0], xp[:, :n] - xo[:, 1:n + 1]])


def example_norm(observer):
    """``y -> ||xi||_r`` on the state vector of ``hs.connect(plant, observer)``.

    The plant's x first, then the observer's (w, x_hat, v, q): the norm of
    Section VI that drives the state-dependent step of :class:`ConsistentEuler`.

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


def settle_time(arc, observer, *, tol=1e-6):
    """The 1e-6 crossing: the last time at which ``max_i |e_i| > tol``, located.

    The last sample above ``tol`` and the next one bracket the crossing;
    where they are a jump (one t) the crossing is the jump time, else it is
    found by :func:`scipy.optimize.brentq` on the arc's interpolant
    (``arc.at``: the dense output where kept, else cubic Hermite with the
    stored flow), to 1e-12 s. Not Proposition 4's settling time (see
    :func:`gain_settling_time` and the module notes).

    Returns
    -------
    float
        ``arc.t[0]`` when no sample is above ``tol``; ``nan`` when the error
        is above ``tol`` at the end of the arc.

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, prescribed_time_observer, simulate
    >>> obs = prescribed_time_observer(EXAMPLE["L"], 0.2, 1.0, b=EXAMPLE["b"])
    >>> round(settle_time(simulate(obs, t_max=5.1), obs), 4)     # closed form (13)-(16): 4.7968
    4.7967
    """
    m = np.abs(errors(arc, observer).e).max(axis=1)
    above = np.flatnonzero(m > tol)
    if above.size == 0:
        return float(arc.t[0])
    k = int(above[-1])
    if k == m.size - 1:
        return np.nan
    ta, tb = float(arc.t[k]), float(arc.t[k + 1])
    if tb == ta or arc.j[k + 1] != arc.j[k]:
        return ta
    jk = int(arc.j[k])
    sp, so = arc.components["plant"], arc.components["observer"]

    def excess(s):
        X = arc.at(s, jk)
        return float(np.abs(_error(X[None, sp], X[None, so], observer.n)).max()) - tol

    return float(brentq(excess, ta, tb, xtol=1e-12, rtol=4 * np.finfo(float).eps))


def switch_time(arc, observer):
    """The time of the settled switch (v reaches z_min, decision 1); ``nan`` if none.

    Examples
    --------
    >>> from observers.dynamic_gain import EXAMPLE, prescribed_time_observer, simulate
    >>> obs = prescribed_time_observer(EXAMPLE["L"], 0.2, 1.0, b=EXAMPLE["b"])
    >>> round(switch_time(simulate(obs, t_max=5.1), obs), 4)      # T - z_min^mu/(mu gamma1)
    4.9801
    """
    q = arc["observer"].x[:, observer.n + 2]
    k = np.flatnonzero(q >= 0.5)
    return float(arc.t[k[0]]) if k.size else np.nan


def gain_settling_time(arc, observer):
    """Proposition 4's settling time on a run: the time at which v reaches 0.

    The run switches to the settled mode (decision 1) when v reaches
    ``z_min`` (:func:`switch_time`); from there (8) with e = 0,
    ``v' = -gamma1 v^{1-mu}``, takes ``z_min^mu / (mu gamma1)`` more to reach
    0. So this is the switch time plus that, where e and v vanish together
    (T of (17), (18)).

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
    if observer.gamma1 <= 0:
        return np.nan
    rest = observer.z_min ** observer.mu / (observer.mu * observer.gamma1)
    return switch_time(arc, observer) + rest
