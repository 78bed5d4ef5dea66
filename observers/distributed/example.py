"""The paper's example (Section 4), random networks, and how a run is made and read.

* :func:`example_system` -- A and C^1..C^4 of Section 4 on our graph (Fig. 1
  is missing from the text: the ring 1 → 2 → 3 → 4 → 1);
  :func:`random_system` -- seeded jointly observable plants over rings and
  random strongly connected digraphs.
* :func:`example_observer` -- the observer of Section 4 with the paper's gains.
* :func:`simulate` -- plant (1) and observer network (7)-(8) of a
  :class:`~observers.distributed.systems.DistributedObserver` through
  :func:`hybridsim.simulate`; :func:`errors` -- the errors of (6) from the arc
  (an :class:`observers._common.Errors`).
* :func:`simulate_errors` -- the error system (6)-(9) alone
  (:class:`~observers.distributed.systems.ErrorSystem`), and
  :func:`settling_time` -- the last time the largest error exceeds a
  threshold, refined on the solver's dense output (Theorem 1).

Examples
--------
>>> from observers.distributed import (errors, example_observer, simulate,
...                                    stable_initial_state, EXAMPLE_V0)
>>> obs = example_observer()
>>> arc = simulate(obs, stable_initial_state(obs.design.A, EXAMPLE_V0), t_max=0.5)
>>> E = errors(arc, obs)
>>> E.e.shape == (arc.t.size, 24), arc.termination.name
(True, 'T_MAX')
"""
from __future__ import annotations

import networkx as nx
import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq

import hybridsim as hs

from .._common import Errors, matrix, scalar, vector
from .design import DistributedDesign, design
from .systems import (
    BandLimitedNoise,
    DistributedObserver,
    error_initial_state,
    initial_state,
    observer_network,
    split_errors,
)

__all__ = [
    "EXAMPLE_NODES",
    "EXAMPLE_V0",
    "example_system",
    "random_system",
    "example_observer",
    "simulate",
    "errors",
    "simulate_errors",
    "settling_time",
    "stable_initial_state",
    "band_limited_noise",
    "noise_batch",
]

#: Node order of the example (Section 4).
EXAMPLE_NODES = [1, 2, 3, 4]
#: Our initial plant state before projection on A's stable subspace (the paper gives none).
EXAMPLE_V0 = np.array([1.0, -1.0, 0.5, 0.0, 1.0, -0.5])


# --------------------------------------------------------------------------
# the paper's example (Section 4)
# --------------------------------------------------------------------------
def example_system():
    """The plant and outputs of Section 4 and our choice of graph.

    Fig. 1 (the graph) is missing from the text: we use the directed ring
    ``1 -> 2 -> 3 -> 4 -> 1`` (the sparsest strongly connected graph on four
    nodes).

    Returns
    -------
    A : (6, 6) ndarray
    C : dict
        node -> (1, 6) output matrix, nodes 1..4.
    G : networkx.DiGraph

    References
    ----------
    Silm et al. (2020), Section 4.
    """
    A = np.array([[-1, 0, 0, 0, 0, 0],
                  [-1, 1, 1, 0, 0, 0],
                  [1, -2, -1, -1, 1, 1],
                  [0, 0, 0, 1, 0, 0],
                  [-8, 1, 1, -1, -2, 0],
                  [4, -0.5, 0.5, 0, 0, -4]], dtype=float)
    C = {1: np.array([[1.0, 0, 0, 2, 0, 0]]),
         2: np.array([[2.0, 0, 0, 1, 0, 0]]),
         3: np.array([[0.0, 0, 1, 0, 0, 0]]),
         4: np.array([[2.0, 0, 5, 0, 0, 0]])}
    G = nx.DiGraph([(1, 2), (2, 3), (3, 4), (4, 1)])
    return A, C, G


def random_system(N, seed=None, *, graph="ring", n_blocks=None, p_edge=0.3):
    """A seeded random jointly observable plant over a strongly connected graph.

    ``A = S blkdiag(A_1, ..., A_K) S^{-1}`` with ``K`` random blocks (real
    eigenvalues in ``[−1.5, 0.5]`` or complex pairs ``a ± ib``,
    ``a ∈ [−1, 0.3]``) and a random well-conditioned ``S``; node ``i``'s scalar
    output ``C^i = c^i S^{-1}`` sees a random proper subset of the blocks, every
    block is seen by some node, so the plant is jointly observable while no
    single node observes it (for ``K ≥ 2``).

    Parameters
    ----------
    N : int
        Number of nodes (>= 2).
    seed : int or numpy.random.Generator, optional
    graph : {"ring", "random"}
        A directed ring through a random permutation of the nodes, or that ring
        plus every other edge with probability ``p_edge``.
    n_blocks : int, optional
        ``K`` (default: random in ``[2, 3]``).
    p_edge : float

    Returns
    -------
    A : (n, n) ndarray
    C : dict
        node -> (1, n) output row, nodes ``0..N-1``.
    G : networkx.DiGraph
    """
    if not isinstance(N, (int, np.integer)) or N < 2:
        raise ValueError(f"N must be an integer >= 2; got {N!r}")
    if graph not in ("ring", "random"):
        raise ValueError(f"graph must be 'ring' or 'random'; got {graph!r}")
    rng = np.random.default_rng(seed)
    K = int(rng.integers(2, 4)) if n_blocks is None else int(n_blocks)
    if K < 2:
        raise ValueError(f"n_blocks must be >= 2; got {K}")
    blocks = []
    for _ in range(K):
        if rng.random() < 0.5:
            blocks.append(np.array([[rng.uniform(-1.5, 0.5)]]))
        else:
            a, b = rng.uniform(-1.0, 0.3), rng.uniform(0.5, 2.0)
            blocks.append(np.array([[a, b], [-b, a]]))
    sizes = [b.shape[0] for b in blocks]
    n = sum(sizes)
    starts = np.cumsum([0] + sizes)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    S = Q @ (np.eye(n) + np.triu(rng.uniform(-0.5, 0.5, (n, n)), 1))
    Sinv = np.linalg.inv(S)
    A = S @ sla.block_diag(*blocks) @ Sinv
    # which blocks each node sees: a proper non-empty subset, all blocks covered
    seen = [set() for _ in range(N)]
    for k in range(K):
        seen[int(rng.integers(N))].add(k)
    for i in range(N):
        if not seen[i]:
            seen[i].add(int(rng.integers(K)))
        while len(seen[i]) == K:
            seen[i].discard(int(rng.integers(K)))
    # re-cover blocks possibly dropped above
    for k in range(K):
        if not any(k in s for s in seen):
            for i in range(N):
                if len(seen[i]) < K - 1:
                    seen[i].add(k)
                    break
    C = {}
    for i in range(N):
        c = np.zeros(n)
        for k in seen[i]:
            sl = slice(starts[k], starts[k + 1])
            c[sl] = rng.choice([-1, 1], sizes[k]) * rng.uniform(0.5, 1.5, sizes[k])
        C[i] = (c @ Sinv)[None, :]
    perm = [int(v) for v in rng.permutation(N)]
    G = nx.DiGraph()
    G.add_nodes_from(range(N))
    G.add_edges_from((perm[k], perm[(k + 1) % N]) for k in range(N))
    if graph == "random":
        for i in range(N):
            for j in range(N):
                if i != j and rng.random() < p_edge:
                    G.add_edge(i, j)
    return A, C, G


def _observer(observer, what="observer"):
    """``observer``, checked to be a :class:`DistributedObserver` (TypeError else)."""
    if isinstance(observer, DistributedObserver):
        return observer
    if isinstance(observer, DistributedDesign):
        raise TypeError(f"{what} must be a DistributedObserver, got its design: pass "
                        "DistributedObserver(design)")
    raise TypeError(f"{what} must be a DistributedObserver, got {type(observer).__name__}")


def example_observer(kind="finite-time"):
    """The observer of Section 4: :func:`example_system` designed with the paper's gains.

    Poles −3 at ``ν = 0``, ``ν_i = −0.1``, ``α_i = 10``, ``β = 0.7`` (the
    defaults of :func:`~observers.distributed.design`), nodes ``[1, 2, 3, 4]``.

    Parameters
    ----------
    kind : {"finite-time", "linear"}
        (7)-(8) or the linear observer (3)-(5) with the same gains.

    Returns
    -------
    DistributedObserver

    Examples
    --------
    >>> from observers.distributed import example_observer
    >>> example_observer().design.n_o
    [2, 2, 5, 5]
    """
    A, C, G = example_system()
    return DistributedObserver(design(A, C, G, nodelist=EXAMPLE_NODES, kind=kind))


def simulate(observer, x0, xhat0=None, *, t_max, noise=None, seed=None, noise_ts=0.1,
             method="RK45", rtol=1e-10, atol=1e-13, max_step=np.inf, **simulate_kwargs):
    """Simulate plant (1) and the observer network (7)-(8) with :func:`hybridsim.simulate`.

    The run is the observer's :meth:`~DistributedObserver.interconnection`
    (plant and nodes over ``hs.network``). The non-Lipschitz powers of
    (7)-(8) make the flow stiff near zero error; the explicit RK45 at
    ``rtol = 1e-10`` copes (the error chatters at the 1e-13 level after
    convergence) and was faster than Radau/LSODA here.

    Parameters
    ----------
    observer : DistributedObserver
        (A :class:`DistributedDesign` is wrapped in one.)
    x0 : (n,) array_like
        Plant state x(0).
    xhat0 : (n,) or (N, n) array_like, optional
        Initial estimates x̃^i(0) (default 0).
    t_max : float
    noise : callable or float, optional
        Measurement noise on the stacked outputs (Remark 2): a callable
        ``t -> (Σ m_i,)``, or a number, the power of band-limited white noise
        (:func:`band_limited_noise`, sample time ``noise_ts``) drawn with ``seed``.
    seed : int or numpy.random.Generator, optional
        Seed of the noise when ``noise`` is a power (nothing else is random).
    noise_ts : float
        Sample time of that noise.
    method, rtol, atol, max_step, **simulate_kwargs
        Passed to :func:`hybridsim.simulate`.

    Returns
    -------
    hybridsim.HybridArc
        Components ``"plant"`` and one per node (by its name): the observer
        is distributed, so there is no single ``"observer"`` component. Read
        the errors with :func:`errors`.

    Examples
    --------
    >>> from observers.distributed import example_observer, simulate
    >>> arc = simulate(example_observer(), [0.0] * 6, t_max=0.1, noise=1e-2, seed=0)
    >>> list(arc.components)[:2], arc.termination.name
    (['plant', 1], 'T_MAX')
    """
    observer = _observer(observer)
    dsg = observer.design
    if noise is not None and not callable(noise):
        power = scalar("noise", noise, nonneg=True)
        noise = band_limited_noise(power, noise_ts, t_max, sum(Ci.shape[0] for Ci in dsg.C),
                                   seed=seed)
    sys_ = observer.interconnection(noise=noise)
    return hs.simulate(sys_, observer.initial_state(x0, xhat0), t_max=t_max, j_max=0,
                       method=method, rtol=rtol, atol=atol, max_step=max_step,
                       progress=False, **simulate_kwargs)


def simulate_errors(observer, x0=None, xhat0=None, *, E0=None, t_max=10.0,
                    method="RK45", rtol=1e-10, atol=1e-14, max_step=np.inf, **kw):
    """Simulate the error system (6)-(9) itself with :func:`hybridsim.simulate`.

    The paper's analysis object (:class:`ErrorSystem`): the errors of every
    node in the coordinates of (2), without the plant. Theorem 1 concerns
    these errors; in a plant-observer run they are differences of two
    states of size ``|x|``, so an unstable plant (the example's) leaves a
    rounding floor ``~ 1e-16 |x|``; here nothing does, and the settling time
    can be measured to 1e-10 and below.

    Parameters
    ----------
    observer : DistributedObserver
    x0, xhat0 : array_like, optional
        Plant state and estimates at t = 0, giving ``E(0)`` through
        :func:`error_initial_state` (the same initial errors as
        ``simulate(observer, x0, xhat0)``).
    E0 : (Σ n, ) array_like, optional
        The initial error ``(E_o, E_u)`` directly (instead of x0, xhat0).
    t_max : float
    method, rtol, atol, max_step, **kw
        Passed to :func:`hybridsim.simulate`. The default ``atol = 1e-14``
        lets the error be followed well below 1e-8 (the relative tolerance
        governs while it is large): on the example the 1e-8 crossing agrees
        with scipy's DOP853 at rtol 1e-12, atol 1e-16 to 1e-8 s.

    Returns
    -------
    hybridsim.HybridArc
        State ``(E_o, E_u)`` in the order of (6); :func:`errors` reads it
        like a plant-observer arc.

    Examples
    --------
    >>> from observers.distributed import example_observer, simulate_errors, EXAMPLE_V0
    >>> arc = simulate_errors(example_observer("linear"), EXAMPLE_V0, t_max=1.0)
    >>> arc.x.shape[1]
    24
    """
    observer = _observer(observer)
    dsg = observer.design
    es = observer.error_system()
    if E0 is not None:
        if x0 is not None or xhat0 is not None:
            raise ValueError("give either E0 or x0 (and xhat0), not both")
        E0 = vector("E0", E0, es.state_dim)
    else:
        if x0 is None:
            raise ValueError("x0 (with xhat0) or E0 is required: the initial error")
        E0 = error_initial_state(dsg, x0, xhat0)
    return hs.simulate(es, E0, t_max=t_max, j_max=0, method=method, rtol=rtol, atol=atol,
                       max_step=max_step, progress=False, **kw)


def _state_errors(X, dsg, from_network):
    """Per-node (e_o, e_u) lists from states X (K, dim) of either kind of arc."""
    if not from_network:
        return split_errors(dsg, X)
    n = dsg.n
    x = X[:, :n]
    e_o, e_u = [], []
    for k, d in enumerate(dsg.decomp):
        e = X[:, n * (k + 1):n * (k + 2)] - x @ d.T
        e_o.append(e[:, :d.n_o])
        e_u.append(e[:, d.n_o:])
    return e_o, e_u


def errors(arc, observer):
    """Errors in transformed coordinates ``e_o^i = x̃_o^i − T_o^{iᵀ} x``, ``e_u^i`` of (6).

    Reads a plant-observer arc (:func:`simulate`) or an error-system arc
    (:func:`simulate_errors`) alike.

    Parameters
    ----------
    arc : hybridsim.HybridArc
    observer : DistributedObserver
        The observer the arc was run with.

    Returns
    -------
    observers._common.Errors
        ``"e"`` (K, Σ n): the stacked errors ``(E_o, E_u)`` in the order of
        (6); ``"e_o"`` (K, Σ n_i) and ``"e_u"`` (K, Σ (n − n_i)): ``E_o`` and
        ``E_u`` (per node: :func:`split_errors` of ``"e"``); ``"norm"`` (K,):
        the largest absolute entry of all errors (``max_i ‖x̃^i − x‖_∞`` in the
        nodes' orthonormal coordinates); the samples' times as ``.t``, ``.j``.

    Examples
    --------
    >>> from observers.distributed import errors, example_observer, simulate_errors
    >>> obs = example_observer()
    >>> E = errors(simulate_errors(obs, [1.0, 0, 0, 0, 0, 0], t_max=0.1), obs)
    >>> list(E), E.e.shape[1], E["e_o"].shape[1]
    (['e', 'e_o', 'e_u', 'norm'], 24, 14)
    """
    dsg = _observer(observer).design
    from_network = "plant" in arc
    X = np.asarray(arc.x)
    if from_network and "noise" in arc:              # a generator component: not an error
        X = np.delete(X, np.arange(X.shape[1])[arc.components["noise"]], axis=1)
    width = dsg.n * (dsg.N + 1) if from_network else int(sum(dsg.n_o) + sum(dsg.n_u))
    if X.shape[1] != width:
        raise ValueError(f"arc has {X.shape[1]} state components, but a "
                         f"{'plant-observer' if from_network else 'error-system'} arc of "
                         f"this design has {width}: was it run with this observer?")
    e_o, e_u = _state_errors(X, dsg, from_network)
    Eo, Eu = np.hstack(e_o), np.hstack(e_u)
    allerr = np.hstack([Eo, Eu])
    return Errors(arc.t, arc.j, e=allerr, e_o=Eo, e_u=Eu,
                  norm=np.max(np.abs(allerr), axis=1))


def _settling(t, norm, threshold):
    """First sample time after which ``norm`` stays below ``threshold`` (nan if never)."""
    above = np.nonzero(norm > threshold)[0]
    if above.size == 0:
        return float(t[0])
    if above[-1] == len(t) - 1:
        return float("nan")
    return float(t[above[-1] + 1])


def settling_time(arc, observer, threshold=1e-8, *, xtol=1e-12):
    """The last time the largest error of any node exceeds ``threshold`` (Theorem 1).

    The last sample above the threshold and the next one bracket the last
    down-crossing of ``max |E|``; it is refined by Brent's method on the
    arc's interpolant (:meth:`hybridsim.HybridArc.at`: the solver's dense
    output for ``dense=True`` runs, else cubic Hermite).

    Parameters
    ----------
    arc : hybridsim.HybridArc
        From :func:`simulate` or :func:`simulate_errors`.
    observer : DistributedObserver
    threshold : float
        > 0.
    xtol : float
        Tolerance of the root in t.

    Returns
    -------
    float
        The crossing time; ``arc.t[0]`` if the error never exceeds the
        threshold, nan if it still does at the arc's end.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.distributed import example_observer, simulate_errors
    >>> lin = example_observer("linear")
    >>> arc = simulate_errors(lin, E0=np.full(24, 1e-3), t_max=5.0)
    >>> 0 < settling_time(arc, lin, 1e-4) < 5
    True
    """
    threshold = scalar("threshold", threshold, positive=True)
    dsg = _observer(observer).design
    E = errors(arc, _observer(observer))
    t, norm = E.t, E["norm"]
    above = np.flatnonzero(norm > threshold)
    if above.size == 0:
        return float(t[0])
    k = int(above[-1])
    if k == len(t) - 1:
        return float("nan")
    from_network = "plant" in arc

    def excess(s):
        X = np.asarray(arc.at(s, int(arc.j[k])), dtype=float)[None, :]
        e_o, e_u = _state_errors(X, dsg, from_network)
        return float(np.max(np.abs(np.hstack(e_o + e_u)))) - threshold

    a, b = float(t[k]), float(t[k + 1])
    if not (excess(a) > 0 >= excess(b)):     # interpolant disagrees with the samples
        return b
    return float(brentq(excess, a, b, xtol=xtol))


def stable_initial_state(A, v):
    """Projection of ``v`` on the stable invariant subspace of ``A``.

    Used for the example: the plant of Section 4 is unstable, and the
    errors, not the state, are the point; starting the plant in its stable
    subspace keeps ``|x|`` small, so that the floating-point error of
    ``x̃ − x`` (relative to ``|x|``) does not hide the convergence.
    """
    A = matrix("A", A, square=True)
    _, Z, sdim = sla.schur(A, output="real", sort="lhp")
    Zs = Z[:, :sdim]
    return Zs @ (Zs.T @ np.asarray(v, dtype=float))


def band_limited_noise(power, ts, t_max, dim, seed=None):
    """Band-limited white noise as in Simulink, interpolated linearly.

    Gaussian samples of variance ``power / ts`` every ``ts`` seconds
    (Simulink's "Band-Limited White Noise" block), joined by straight lines
    so that the flow stays continuous for the integrator. The samples are
    those of :meth:`BandLimitedNoise.realisation` for the same seed.

    Returns
    -------
    callable
        ``t -> (dim,)``.
    """
    if power < 0 or ts <= 0:
        raise ValueError(f"power must be >= 0 and ts > 0; got power={power}, ts={ts}")
    gen = BandLimitedNoise(ts, t_max, dim)
    grid = gen.grid
    samples = gen.realisation(power, seed).reshape(grid.size, dim)

    def noise(t):
        return np.array([np.interp(t, grid, samples[:, k]) for k in range(dim)])
    return noise


def noise_batch(observer, x0, xhat0=None, *, power, seeds, t_max, noise_ts=0.1):
    """A Monte Carlo of measurement noise: the network and one initial state per realisation.

    The noise is a :class:`BandLimitedNoise` component of
    :func:`observer_network` (its state is the realisation), so each seed
    is a row of ``x0s`` and the whole study is one call of
    :func:`hybridsim.simulate_many`, integrated all rows at once (every
    component is vectorized). Row r draws the samples of
    ``band_limited_noise(power, noise_ts, t_max, Σ m_i, seed=seeds[r])``, so
    it is the run ``simulate(observer, x0, xhat0, noise=power, seed=seeds[r])``
    to the integrator's tolerance.

    Parameters
    ----------
    observer : DistributedObserver
    x0, xhat0 : array_like
        As in :func:`simulate`.
    power : float
        Power of the band-limited white noise (>= 0).
    seeds : sequence of int
        One seed per realisation.
    t_max : float
        The horizon the noise covers (pass the same to ``simulate_many``).
    noise_ts : float
        Sample time of the noise.

    Returns
    -------
    system : hybridsim.Interconnection
        Components ``"plant"``, ``"noise"`` and the nodes.
    x0s : (len(seeds), state_dim) ndarray

    Examples
    --------
    >>> import hybridsim as hs
    >>> from observers.distributed import errors, example_observer, noise_batch
    >>> obs = example_observer()
    >>> sysm, x0s = noise_batch(obs, [1.0] * 6, power=1e-4, seeds=[0, 1, 2], t_max=0.2)
    >>> arcs = hs.simulate_many(sysm, x0s, t_max=0.2, rtol=1e-8, atol=1e-10)
    >>> sysm.vectorized, [a.termination.name for a in arcs], errors(arcs[0], obs).e.shape[1]
    (True, ['T_MAX', 'T_MAX', 'T_MAX'], 24)
    """
    dsg = _observer(observer).design
    power = scalar("power", power, nonneg=True)
    p = sum(Ci.shape[0] for Ci in dsg.C)
    gen = BandLimitedNoise(noise_ts, t_max, p)
    net = observer_network(dsg, noise=gen)
    z0 = initial_state(dsg, x0, xhat0)
    seeds = list(seeds)
    if not seeds:
        raise ValueError("seeds must name at least one realisation")
    W = np.array([gen.realisation(power, s) for s in seeds])
    X = np.zeros((len(seeds), net.state_dim))
    n = dsg.n
    X[:, net.components["plant"]] = z0[:n]
    X[:, net.components["noise"]] = W
    for k, v in enumerate(dsg.nodelist):
        X[:, net.components[v]] = z0[n * (k + 1):n * (k + 2)]
    return net, X
