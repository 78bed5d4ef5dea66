"""The paper's examples, and how a run is made and read.

* Designs of the paper's examples: :func:`example_III` (Section III, Fig. 1),
  :func:`example_VA` (Section V.A, Fig. 2), :func:`example_VB` (Section V.B,
  Fig. 3).
* A run: :func:`simulate` wires the engine's ``hs.LinearPlant`` (plant (1)
  with output noise m, (14)) to an observer with ``hs.connect`` and runs
  ``hs.simulate``; :func:`errors` reads the estimation errors off the arc
  (an :class:`observers._common.Errors`).
* Batches of noise realisations: :func:`noise_batch` with
  :class:`~observers.li_sanfelice.systems.BoundedNoiseGenerator`, run by
  ``hs.simulate_many``.

Examples
--------
>>> from observers.li_sanfelice import ConstantNoiseObserver, example_VA, simulate, errors
>>> obs = ConstantNoiseObserver(example_VA(delta=2.0))
>>> arc = simulate(obs, [1.0], [0.0], t_max=4.0, noise=[0.2])        # Fig. 2(a)
>>> E = errors(arc, obs)
>>> bool(abs(E["mhat"][-1, 0] - 0.2) < 1e-7)           # Theorem 4.13: m̂ = m after one jump
True
"""
from __future__ import annotations

import numpy as np

import hybridsim as hs
from observers._common import Errors, vector

from .design import Design
from .systems import LuenbergerObserver, _TwoCopyObserver

__all__ = [
    "example_III",
    "example_VA",
    "example_VB",
    "simulate",
    "errors",
    "noise_batch",
]


def example_III(delta=2.0):
    """Section III / Fig. 1: a = -0.05, L1 = 0.01, L2 = 0.02 (H = 1), m = 0.2;
    delta = 2 (Fig. 1(b)), L0 = 0.02."""
    return Design(A=[[-0.05]], H=[[1.0]], L1=[[0.01]], L2=[[0.02]], delta=delta)


def example_VA(delta=2.0):
    """Section V.A: a = -0.05, L1 = 0.1, L2 = 0.2, H = 1.
    delta is not given in the text (default 2, chosen)."""
    return Design(A=[[-0.05]], H=[[1.0]], L1=[[0.1]], L2=[[0.2]], delta=delta)


def example_VB(rounded=False):
    """Section V.B: A = [[0,1],[-1,0]], H = [[1,2],[2,1]], delta = 1, L1 = 5 H^{-1}, L2 = 8 H^{-1}.

    ``rounded=True`` uses the two-decimal values printed in the paper
    (decision 4).
    """
    A = np.array([[0.0, 1.0], [-1.0, 0.0]])
    H = np.array([[1.0, 2.0], [2.0, 1.0]])
    if rounded:
        L1 = np.array([[-1.67, 3.33], [3.33, -1.67]])
        L2 = np.array([[-2.67, 5.33], [5.33, -2.67]])
    else:
        Hi = np.linalg.inv(H)
        L1, L2 = 5 * Hi, 8 * Hi
    return Design(A=A, H=H, L1=L1, L2=L2, delta=1.0)


def _noise_callable(noise, p):
    if noise is None:
        return None
    if callable(noise):
        return noise
    c = vector("noise", noise, p)
    return lambda t: c


def simulate(observer, x0, xhat0=None, *, t_max=None, noise=None, seed=None, j_max=None,
             mhat0=None, method="DOP853", rtol=1e-10, atol=1e-12, **simulate_kwargs):
    """Simulate plant (1), y = H x + m (14), with an observer: hs.connect + hs.simulate.

    Parameters
    ----------
    observer : observer of this module
        A NominalObserver, ConstantNoiseObserver, PiecewiseConstantNoiseObserver or
        LuenbergerObserver.
    x0 : (n,) array_like
        Plant initial state.
    xhat0 : (n,) array_like, optional
        Observer initial estimate (x̂1 = x̂2 = xhat0: the sets S_n, S_c, S_pc;
        x̂0 of (2) for the Luenberger observer). Default zeros (the paper's
        examples start from x̂ = 0).
    t_max : float, optional
        Horizon (default 3 delta; required for a LuenbergerObserver).
    noise : None, (p,) array_like or callable t -> (p,)
        Output noise m(t) of (14) (a constant vector is a bias).
    seed : int or numpy.random.Generator, optional
        Passed to :func:`hybridsim.simulate` (it only matters with
        ``priority="random"``: nothing here draws random numbers).
    j_max : int, optional
    mhat0 : (p,) array_like, optional
        Initial noise estimate (H_c, H_pc).
    method, rtol, atol, **simulate_kwargs
        Passed to :func:`hybridsim.simulate` (defaults DOP853, 1e-10, 1e-12:
        the tolerances every claim's threshold is set from).

    Returns
    -------
    hybridsim.HybridArc
        Components "plant" and "observer".

    Examples
    --------
    >>> from observers.li_sanfelice import NominalObserver, example_VB, simulate, errors
    >>> obs = NominalObserver(example_VB())
    >>> arc = simulate(obs, [0.3, 0.4], [0.0, 0.0], t_max=2.0)
    >>> arc.jump_times                    # one jump, at t = delta (10)-(12)
    array([1.])
    >>> bool(abs(errors(arc, obs).e[arc.j == 1]).max() < 1e-8)    # Theorem 4.7
    True
    """
    if isinstance(observer, LuenbergerObserver):
        A, H = observer.A, observer.H
        z0 = vector("xhat0", np.zeros(A.shape[0]) if xhat0 is None else xhat0, A.shape[0])
        if t_max is None:
            raise TypeError("t_max is required for a LuenbergerObserver")
    elif isinstance(observer, _TwoCopyObserver):
        A, H = observer.design.A, observer.design.H
        z0 = observer.initial_state(np.zeros(observer.design.n) if xhat0 is None else xhat0,
                                    mhat0)
        if t_max is None:
            t_max = 3 * observer.design.delta
    else:
        raise TypeError(f"observer must be one of this module's observers, "
                        f"got {type(observer).__name__}")
    x0 = vector("x0", x0, A.shape[0])
    plant = hs.LinearPlant(A, C=H, noise=_noise_callable(noise, H.shape[0]))
    sys = hs.connect(plant, observer, names=("plant", "observer"))
    kwargs = dict(method=method, rtol=rtol, atol=atol, **simulate_kwargs)
    if j_max is not None:
        kwargs["j_max"] = j_max
    if seed is not None:
        kwargs["seed"] = seed
    return hs.simulate(sys, np.concatenate([x0, z0]), t_max=t_max, **kwargs)


def errors(arc, observer):
    """The estimation errors along an arc of :func:`simulate` (or of :func:`noise_batch`).

    Parameters
    ----------
    arc : hybridsim.HybridArc
        With components "plant" and "observer" (as :func:`simulate` and
        :func:`noise_batch` name them).
    observer : the observer that was run

    Returns
    -------
    observers._common.Errors
        The main error ``e`` = ē = a1 e1 + a2 e2 (N, n), e_i = x̂_i - x
        (footnote 2; for the Luenberger observer (2), ``e`` = x̂0 - x), and
        the signals ``x``, ``xbar``, ``e1``, ``e2``, ``ebar`` (= ``e``) (N, n),
        ``tau`` (N, 1), ``mhat`` (N, p) for H_c / H_pc; for the Luenberger
        observer ``x``, ``xhat0``, ``e0`` (= ``e``). The samples' hybrid times
        are ``.t`` and ``.j``.

    Examples
    --------
    >>> from observers.li_sanfelice import LuenbergerObserver, simulate, errors
    >>> obs = LuenbergerObserver([[-0.05]], [[1.0]], [[0.02]])       # (2), Fig. 1(b)
    >>> E = errors(simulate(obs, [0.0], [1.0], t_max=1.0), obs)
    >>> sorted(E), E.e.shape == (E.t.size, 1)
    (['e', 'e0', 'x', 'xhat0'], True)
    """
    x = arc.component("plant").x
    Z = arc.component("observer").x
    if isinstance(observer, LuenbergerObserver):
        return Errors(arc.t, arc.j, e=Z - x, x=x, xhat0=Z, e0=Z - x)
    parts = observer.split(Z)
    d = observer.design
    e1, e2 = parts["xh1"] - x, parts["xh2"] - x
    ebar = d.a1 * e1 + d.a2 * e2
    more = {"mhat": parts["mhat"]} if "mhat" in parts else {}
    return Errors(arc.t, arc.j, e=ebar, x=x, e1=e1, e2=e2, ebar=ebar,
                  xbar=d.a1 * parts["xh1"] + d.a2 * parts["xh2"], tau=parts["tau"], **more)




def noise_batch(observer, x0, xhat0, noise_states, generator):
    """Interconnection noise -> (plant, observer) and the (N, n_total) initial states of a batch.

    The observer's input is y = H x + m with m the generator's output; each row of ``noise_states``
    is one realisation. Run it with ``hs.simulate_many(system, x0s, t_max=..., ...)``.

    Returns
    -------
    system : hybridsim.Interconnection
        Components "noise", "plant", "observer".
    x0s : (N, n_total) ndarray
    """
    d = observer.design
    plant = hs.LinearPlant(d.A, C=d.H)
    sys = hs.Interconnection({"noise": generator, "plant": plant, "observer": observer},
                                      inputs={"observer": hs.LinearInput({"plant": None,
                                                                          "noise": None})})
    z0 = np.concatenate([vector("x0", x0, d.n), observer.initial_state(xhat0)])
    S = np.atleast_2d(np.asarray(noise_states, dtype=float))
    if S.shape[1] != generator.state_dim:
        raise ValueError(f"noise_states must have shape (N, {generator.state_dim}), got {S.shape}")
    return sys, np.hstack([S, np.tile(z0, (S.shape[0], 1))])

