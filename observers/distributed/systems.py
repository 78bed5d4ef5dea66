"""The hybrid systems of paper 003: observer nodes (7)-(8) / (4)-(5), the
network with its plant (1), and the error system (6)-(9) itself.

* :class:`DistributedObserverNode` -- node i of (7)-(8) (or (4)-(5)) as a
  ``hs.HybridSystem`` (empty jump set); :func:`observer_network` wires plant
  (1) and nodes with ``hs.network`` over the graph; :func:`initial_state`
  stacks their initial states.
* :class:`DistributedObserver` -- the observer of the contract
  (``simulate(observer, ...)``, ``errors(arc, observer)``): holds the design,
  its nodes, and builds the interconnection and the error system.
* :class:`BandLimitedNoise` -- measurement noise as a component whose
  state holds one realisation (Remark 2), so that a batch of realisations
  runs through :func:`hybridsim.simulate_many` as a batch of initial states
  (:func:`observers.distributed.noise_batch`). The plant, the nodes and the
  generator are ``vectorized``: such a batch is integrated all rows at once.
* :class:`ErrorSystem` / :func:`error_system` -- the paper's analysis object:
  the estimation errors E = (E_o, E_u) of every node in the local
  coordinates of (2), ordered as in (6), flowing by the error of (7) (each
  node's observable part) and by (9) (the unobservable part of the network;
  (6) for the linear observer). It does not contain the plant, so an
  unstable plant leaves no rounding floor on the error: it can be followed
  down to 1e-12 and below. :func:`error_initial_state` gives E(0) from x(0)
  and the estimates x̃^i(0).

Examples
--------
>>> import numpy as np
>>> from observers.distributed import design, example_system, error_system
>>> A, C, G = example_system()
>>> dsg = design(A, C, G, nodelist=[1, 2, 3, 4])
>>> es = error_system(dsg)
>>> es.state_dim, es.n_obs                      # (E_o, E_u): sum n_i = 14, sum (n - n_i) = 10
(24, 14)
>>> bool(np.allclose(es.flow_map(np.zeros(24)), 0))   # E = 0 is an equilibrium
True
"""
from __future__ import annotations

import itertools

import numpy as np
import scipy.linalg as sla

import hybridsim as hs

from .._common import vector
from .design import DistributedDesign, signed_power

__all__ = [
    "DistributedObserver",
    "DistributedObserverNode",
    "BandLimitedNoise",
    "observer_network",
    "initial_state",
    "ErrorSystem",
    "error_system",
    "error_initial_state",
    "split_errors",
    "PopulationErrorSystem",
]


# --------------------------------------------------------------------------
# the node dynamics (7)-(8) and (4)-(5)
# --------------------------------------------------------------------------
class _NodeData:
    """Pre-computed matrices of one node (local coordinates ``(x̃_o, x̃_u)``)."""

    def __init__(self, dsg: DistributedDesign, k: int):
        d = dsg.decomp[k]
        self.k, self.node = k, dsg.nodelist[k]
        self.n_o, self.n_u, self.n = d.n_o, d.n_u, dsg.n
        self.T_o, self.T_u = d.T_o, d.T_u
        self.T = d.T
        self.A_o, self.A_r, self.A_u, self.C_o = d.A_o, d.A_r, d.A_u, d.C_o
        self.m = dsg.C[k].shape[0]
        self.alpha = float(dsg.alpha[k])
        self.finite_time = dsg.kind == "finite-time"
        self.beta = dsg.beta
        self.L_lin = dsg.L_lin[k]
        self.neighbours = dsg.in_neighbours(self.node)
        n, no, nu_, m, K = self.n, self.n_o, self.n_u, self.m, len(self.neighbours)
        if self.finite_time and no:
            Th, p, L = dsg.Theta[k], dsg.p[k], dsg.L[k]
            self.pt = Th @ p                                              # Θ p
            # Θ 𝓘 Θ^{-1} = A_o + Θ p C_o (same matrix; avoids inverting a
            # possibly ill-conditioned Θ)
            self.At_o = self.A_o + np.outer(self.pt, self.C_o[0])
            self.Lt_o = Th @ np.diag(L)                                   # Θ diag(L_o)
            self.gamma = 1.0 + np.arange(1, no + 1) * dsg.nu[k]          # γ_k = 1 + k ν
        # The flow as one matrix product and one signed power (decision 3):
        #   f = (H w)[:n] − N ⌈(H w)[n:]⌋^κ,   w = (z, u),
        # z = (x̃_o, x̃_u), u = (y, x̃^{j_1}, ..., x̃^{j_K}). The rows of H give
        #   0..n-1   the linear terms: [Ã_o x̃_o − Θ p y ; A_r x̃_o + A_u x̃_u − α s]
        #            ((7), (8)), or [A_o x̃_o − L (C_o x̃_o − y) ; same] ((4), (5));
        #   then     s = Σ_j (x̃_u − T_uᵀ x̃^j) (n − n_i rows, the argument of (8)'s
        #            power, exponent β) and the output error C_o x̃_o − y copied into
        #            n_i rows ("1 (C_o x̃_o − y)" of (7), exponents γ_1..γ_{n_i});
        # N = [[0, L̃_o], [I, 0]] puts L̃_o ⌈1 err⌋^γ in the observable rows and
        # ⌈s⌋^β in the others. For the linear observer H has the first n rows only.
        TuT = self.T_u.T
        powers = self.finite_time
        H = np.zeros((n + (nu_ + no if powers else 0), n + m + K * n))
        if no and powers:
            H[:no, :no] = self.At_o
            H[:no, n] = -self.pt
            H[n + nu_:, :no] = self.C_o[0]
            H[n + nu_:, n] = -1.0
        elif no:
            H[:no, :no] = self.A_o - self.L_lin @ self.C_o
            H[:no, n:n + m] = self.L_lin
        if nu_:
            H[no:n, :no] = self.A_r
            H[no:n, no:n] = self.A_u - self.alpha * K * np.eye(nu_)
            if powers:
                H[n:n + nu_, no:n] = K * np.eye(nu_)
            for q in range(K):
                cols = slice(n + m + q * n, n + m + (q + 1) * n)
                H[no:n, cols] = self.alpha * TuT
                if powers:
                    H[n:n + nu_, cols] = -TuT
        self.H = H
        self._powers = powers
        if powers:
            self.kappa = np.concatenate([np.full(nu_, float(self.beta)),
                                         self.gamma if no else np.zeros(0)])
            Nm = np.zeros((n, nu_ + no))
            Nm[no:, :nu_] = np.eye(nu_)
            if no:
                Nm[:no, nu_:] = self.Lt_o
            self.N_pow = Nm

    def flow(self, z, u):
        """The node's flow at its state ``z`` (n,) and input ``u = (y, x̃^{j_1}, ...)``.

        On the last axis: ``z`` (N, n) and ``u`` (N, m + |𝒩_i| n) give the
        (N, n) flows of a batch.
        """
        r = np.concatenate((z, u), axis=-1) @ self.H.T
        if not self._powers:
            return r
        q = r[..., self.n:]
        return r[..., :self.n] - np.copysign(np.abs(q) ** self.kappa, q) @ self.N_pow.T

    def rhs(self, z, y, xhat_nb):
        """Right-hand side of node ``k``: (7)-(8) or (4)-(5).

        Parameters
        ----------
        z : (n_o + n_u,) or (N, n_o + n_u) array
            ``(x̃_o, x̃_u)`` (one state or a batch, on the last axis).
        y : (m,) or (N, m) array
            The node's measurement ``y^i``.
        xhat_nb : (|𝒩_i|, n) or (N, |𝒩_i|, n) array
            The in-neighbours' full estimates ``x̃^j``.

        Returns
        -------
        (n,) or (N, n) ndarray
            ``(dx̃_o, dx̃_u)``: ``dx̃_o = Ã_o x̃_o − Θ p y − L̃_o ⌈1 (C_o x̃_o − y)⌋^γ``
            (7) (or ``A_o x̃_o − L (C_o x̃_o − y)``, (4)) and ``dx̃_u = A_r x̃_o +
            A_u x̃_u − α s − ⌈s⌋^β`` (8) (without the power, (5)) with
            ``s = Σ_j (x̃_u − T_uᵀ x̃^j)``.
        """
        z = np.asarray(z, dtype=float)
        lead = z.shape[:-1] + (-1,)
        u = np.concatenate([np.asarray(y, dtype=float).reshape(lead),
                            np.asarray(xhat_nb, dtype=float).reshape(lead)], axis=-1)
        return self.flow(z, u)

    def estimate(self, z):
        """Full estimate ``x̃^i = T_o x̃_o + T_u x̃_u`` (z of shape (n,) or (N, n))."""
        return z @ self.T.T


# --------------------------------------------------------------------------
# the observer network on the engine
# --------------------------------------------------------------------------
class DistributedObserverNode(hs.HybridSystem):
    """Observer node ``i`` of (7)-(8) (or (4)-(5)) as a hybrid system.

    A purely continuous system (empty jump set).  State: the local
    coordinates ``(x̃_o^i, x̃_u^i)`` of (2) (length ``n``).  Input:
    ``u = (y^i, x̃^{j_1}, ..., x̃^{j_k})`` with ``j_1..j_k`` the in-neighbours
    ``𝒩_i`` in ``nodelist`` order.  Output: the full estimate
    ``x̃^i = T_o x̃_o + T_u x̃_u`` (what the out-neighbours receive).

    Parameters
    ----------
    dsg : DistributedDesign
    node : hashable
        A node of ``dsg.G``.

    References
    ----------
    Silm et al. (2020), eqs. (3)-(5), (7), (8).
    """

    vectorized = True       # the maps also take batches (N, n)

    def __init__(self, dsg: DistributedDesign, node):
        if node not in dsg.nodelist:
            raise ValueError(f"node must be a node of the design's graph; got {node!r}")
        self.data = _NodeData(dsg, dsg.nodelist.index(node))
        self.node = node
        self.state_dim = dsg.n
        self.output_dim = dsg.n
        self.input_dim = self.data.m + len(self.data.neighbours) * dsg.n

    def flow_map(self, x, t, j, u):
        return self.data.flow(np.asarray(x, dtype=float), np.asarray(u, dtype=float))

    def output(self, x, t, j):
        return self.data.estimate(np.asarray(x, dtype=float))


def observer_network(dsg: DistributedDesign, *, noise=None, disturbance=None):
    """Plant (1) and the observer nodes as one interconnected hybrid system.

    Built with :func:`hybridsim.network` over ``dsg.G``: the component
    ``"plant"`` (a :class:`hybridsim.LinearPlant` with ``C = [C^1; ...; C^N]``)
    is stacked first, then one :class:`DistributedObserverNode` per node in
    ``dsg.nodelist`` order.

    Parameters
    ----------
    dsg : DistributedDesign
    noise : callable or hybridsim.HybridSystem, optional
        Measurement noise added to the outputs (Remark 2): ``t -> (Σ m_i,)``,
        or a generator system whose output is the noise (e.g.
        :class:`BandLimitedNoise`), stacked after the plant as component
        ``"noise"``: its state is the realisation, so a batch of
        realisations is a batch of initial states.
    disturbance : callable, optional
        ``t -> (n,)`` added to the plant's flow.

    Returns
    -------
    hybridsim.Interconnection
        ``vectorized`` (a batch is integrated all rows at once) when no
        callable of t is given.
    """
    for name in ("plant", "noise"):
        if name in dsg.nodelist:
            raise ValueError(f"no node of G may be named {name!r}")
    generator = noise if isinstance(noise, hs.HybridSystem) else None
    if generator is not None:
        p = sum(Ci.shape[0] for Ci in dsg.C)
        if generator.output_dim != p:
            raise ValueError(f"noise: the generator's output_dim must be the number of "
                             f"outputs Σ m_i = {p}, got {generator.output_dim}")
        noise = None
    plant = hs.LinearPlant(dsg.A, C=np.vstack(dsg.C), noise=noise, disturbance=disturbance)
    exo = {"plant": plant} if generator is None else {"plant": plant, "noise": generator}
    nodes = {v: DistributedObserverNode(dsg, v) for v in dsg.nodelist}
    return hs.network(dsg.G, nodes, _wiring(dsg, generator is not None),
                      nodelist=dsg.nodelist, exogenous=exo)


def _wiring(dsg, noisy):
    """Each node's input u = (y^i (+ m^i), x̃^{j_1}, ..., x̃^{j_K}) as a
    :class:`hybridsim.LinearInput` (selection matrices: the same numbers as
    concatenating, on every path, the compiled one included)."""
    p = sum(Ci.shape[0] for Ci in dsg.C)
    out, k = {}, 0
    for v, Ci in zip(dsg.nodelist, dsg.C):
        m = Ci.shape[0]
        nb = dsg.in_neighbours(v)
        dim = m + len(nb) * dsg.n
        S = np.zeros((dim, p))
        S[np.arange(m), k + np.arange(m)] = 1.0
        terms = {"plant": S}
        if noisy:
            terms["noise"] = S
        for q, w in enumerate(nb):
            E = np.zeros((dim, dsg.n))
            E[m + q * dsg.n + np.arange(dsg.n), np.arange(dsg.n)] = 1.0
            terms[w] = E
        out[v] = hs.LinearInput(terms)
        k += m
    return out


class DistributedObserver:
    """The distributed observer of a design: what ``simulate`` and ``errors`` take.

    One :class:`DistributedObserverNode` per node of the design's graph
    ((7)-(8), or (4)-(5) for ``kind="linear"``); :meth:`interconnection`
    wires them with the plant (1) through :func:`hybridsim.network`
    (:func:`observer_network`), :meth:`error_system` gives the error system
    (6)-(9) of the same design. A plain class holding the design: the hybrid
    systems it builds are the interconnection and the error system.

    Parameters
    ----------
    dsg : DistributedDesign
        From :func:`observers.distributed.design`.

    Attributes
    ----------
    design : DistributedDesign
    nodes : dict
        node -> :class:`DistributedObserverNode`, in ``design.nodelist`` order.

    Examples
    --------
    >>> from observers.distributed import DistributedObserver, design, example_system
    >>> A, C, G = example_system()
    >>> obs = DistributedObserver(design(A, C, G, nodelist=[1, 2, 3, 4]))
    >>> list(obs.interconnection().systems), obs.error_system().state_dim
    (['plant', 1, 2, 3, 4], 24)

    References
    ----------
    Silm et al. (2020), eqs. (1), (3)-(8).
    """

    def __init__(self, dsg: DistributedDesign):
        if not isinstance(dsg, DistributedDesign):
            raise TypeError("dsg must be a DistributedDesign (from observers.distributed."
                            f"design), got {type(dsg).__name__}")
        self.design = dsg
        self.nodes = {v: DistributedObserverNode(dsg, v) for v in dsg.nodelist}

    def __repr__(self):
        d = self.design
        return (f"DistributedObserver({d.kind}, N={d.N} nodes {d.nodelist}, n={d.n}, "
                f"n_i={d.n_o})")

    def interconnection(self, *, noise=None, disturbance=None):
        """Plant (1) and the nodes as one hybrid system (:func:`observer_network`)."""
        return observer_network(self.design, noise=noise, disturbance=disturbance)

    def initial_state(self, x0, xhat0=None):
        """The interconnection's initial state (:func:`initial_state`)."""
        return initial_state(self.design, x0, xhat0)

    def error_system(self):
        """The error system (6)-(9) of the design (:class:`ErrorSystem`)."""
        return ErrorSystem(self.design)


class BandLimitedNoise(hs.HybridSystem):
    """Band-limited white noise (Simulink's block) as a generator component.

    Gaussian samples of variance ``power / ts`` on the grid ``0, ts, 2 ts,
    ...`` up to ``t_max + ts``, joined by straight lines (``numpy.interp``'s
    formula). The state is the samples, (grid size, dim) row-major, constant
    in time (flow 0, no jumps); the output is the noise at t. One initial
    state is one realisation (:meth:`realisation`), so a batch of them is a
    Monte Carlo of noise (:func:`observers.distributed.noise_batch`); the
    callable :func:`observers.distributed.band_limited_noise` draws the same
    samples for a seed.

    Parameters
    ----------
    ts : float
        Sample time (> 0).
    t_max : float
        Horizon covered (the last sample holds beyond it).
    dim : int
        Number of noise channels (the outputs Σ m_i).

    Examples
    --------
    >>> import numpy as np
    >>> from observers.distributed import BandLimitedNoise, band_limited_noise
    >>> gen = BandLimitedNoise(0.1, 1.0, 2)
    >>> w = gen.realisation(1e-2, seed=3)
    >>> m = band_limited_noise(1e-2, 0.1, 1.0, 2, seed=3)
    >>> bool(np.allclose(gen.output(w, 0.37, 0), m(0.37), rtol=1e-14, atol=0))
    True
    """

    vectorized = True

    def __init__(self, ts, t_max, dim):
        self.ts = float(ts)
        if not (self.ts > 0 and np.isfinite(self.ts)):
            raise ValueError(f"ts must be a positive finite float, got {ts!r}")
        if not (np.isfinite(t_max) and t_max >= 0):
            raise ValueError(f"t_max must be a finite float >= 0, got {t_max!r}")
        if isinstance(dim, bool) or int(dim) != dim or dim < 1:
            raise ValueError(f"dim must be a positive int, got {dim!r}")
        self.dim = int(dim)
        self.grid = np.arange(0.0, float(t_max) + 2 * self.ts, self.ts)
        self.state_dim = self.grid.size * self.dim
        self.output_dim = self.dim

    def realisation(self, power, seed=None):
        """The samples of one realisation (the initial state), drawn with ``seed``."""
        if not (np.isfinite(power) and power >= 0):
            raise ValueError(f"power must be a finite float >= 0, got {power!r}")
        rng = np.random.default_rng(seed)
        return (rng.standard_normal((self.grid.size, self.dim))
                * np.sqrt(power / self.ts)).ravel()

    def flow_map(self, x, t, j, u):
        return np.zeros(np.shape(x))

    def output(self, x, t, j):
        G, grid = self.grid.size, self.grid
        S = np.asarray(x, dtype=float)
        S = S.reshape(S.shape[:-1] + (G, self.dim))          # (..., G, dim)
        t = np.broadcast_to(np.asarray(t, dtype=float), S.shape[:-2])
        # numpy.interp's formula: the segment [grid[k], grid[k+1]] holding t,
        # the first (last) sample held before (after) the grid
        k = np.clip(np.searchsorted(grid, t, side="right") - 1, 0, G - 2)
        lo = np.take_along_axis(S, k[..., None, None], axis=-2)[..., 0, :]
        hi = np.take_along_axis(S, k[..., None, None] + 1, axis=-2)[..., 0, :]
        slope = (hi - lo) / (grid[k + 1] - grid[k])[..., None]
        y = slope * (t - grid[k])[..., None] + lo
        y = np.where((t >= grid[-1])[..., None], S[..., -1, :], y)
        return np.where((t < grid[0])[..., None], S[..., 0, :], y)


def initial_state(dsg: DistributedDesign, x0, xhat0=None):
    """Stacked initial state ``(x(0), T^{1ᵀ} x̃^1(0), ..., T^{Nᵀ} x̃^N(0))``.

    Parameters
    ----------
    x0 : (n,) array_like
        Plant state.
    xhat0 : (n,) or (N, n) array_like, optional
        Initial estimates ``x̃^i(0)`` (default 0).
    """
    n, N = dsg.n, dsg.N
    x0 = vector("x0", x0, n)
    xh = np.zeros((N, n)) if xhat0 is None else np.asarray(xhat0, dtype=float)
    if xh.shape == (n,):
        xh = np.tile(xh, (N, 1))
    if xh.shape != (N, n):
        raise ValueError(f"xhat0 must have shape ({n},) or ({N}, {n}); got {xh.shape}")
    return np.concatenate([x0] + [d.T.T @ xh[k] for k, d in enumerate(dsg.decomp)])


# --------------------------------------------------------------------------
# the error system (6)-(9): the paper's analysis object
# --------------------------------------------------------------------------
class ErrorSystem(hs.HybridSystem):
    """The network's estimation error as a hybrid system (empty jump set).

    State ``E = (E_o, E_u)`` with ``E_o = (e_o^1, ..., e_o^N)`` and
    ``E_u = (e_u^1, ..., e_u^N)``, ``e_o^i = x̃_o^i − x_o^i`` and
    ``e_u^i = x̃_u^i − x_u^i`` in node i's coordinates of (2) (Section 2.2:
    the order of (6)). The flow is, for the finite-time observer,

    * observable part, from (7) with ``y^i = C_o^i x_o^i``::

          ė_o^i = Ã_o^i e_o^i − L̃_o^i ⌈1 (C_o^i e_o^i)⌋^{γ^i}          (7)

      (``Ã_o^i = Θ^i 𝓘 Θ^{i-1} = A_o^i + Θ^i p^i C_o^i``,
      ``L̃_o^i = Θ^i diag(L_o^i)``, ``γ^i_k = 1 + k ν_i``);
    * unobservable part, (9)::

          Ė_u = (A_u − α M) E_u + (A_r + α K) E_o − ⌈M E_u − K E_o⌋^β     (9)

      with ``M = T_uᵀ(𝓛⊗I)T_u`` and ``K = T_uᵀ(𝒜⊗I)T_o`` (decision 2);

    and for the linear observer (3)-(5) the linear system (6),
    ``Ė = F E`` with ``F`` = :meth:`DistributedDesign.error_matrix`.
    The plant does not enter: the error dynamics do not depend on ``x``.

    Parameters
    ----------
    dsg : DistributedDesign
        From :func:`observers.distributed.design`.

    Attributes
    ----------
    n_obs : int
        ``Σ n_i``, the length of ``E_o``.
    design : DistributedDesign

    Examples
    --------
    >>> import numpy as np
    >>> from observers.distributed import design, example_system, ErrorSystem
    >>> A, C, G = example_system()
    >>> lin = design(A, C, G, nodelist=[1, 2, 3, 4], kind="linear")
    >>> E = np.random.default_rng(0).standard_normal(24)
    >>> bool(np.allclose(ErrorSystem(lin).flow_map(E), lin.error_matrix() @ E))   # (6)
    True
    """

    def __init__(self, dsg: DistributedDesign):
        if not isinstance(dsg, DistributedDesign):
            raise TypeError("dsg must be a DistributedDesign (from observers.distributed."
                            f"design), got {type(dsg).__name__}")
        self.design = dsg
        self.n_obs = int(sum(dsg.n_o))
        self.state_dim = self.n_obs + int(sum(dsg.n_u))
        self.finite_time = dsg.kind == "finite-time"
        if not self.finite_time:
            self._F = dsg.error_matrix()                                   # (6)
            return
        blocks_A, blocks_L, blocks_C, gammas = [], [], [], []
        for k, d in enumerate(dsg.decomp):
            if not d.n_o:
                continue
            Th, p, L = dsg.Theta[k], dsg.p[k], dsg.L[k]
            blocks_A.append(d.A_o + np.outer(Th @ p, d.C_o[0]))            # Θ 𝓘 Θ^{-1}
            blocks_L.append(Th @ np.diag(L))                               # Θ diag(L_o)
            blocks_C.append(np.outer(np.ones(d.n_o), d.C_o[0]))            # 1 (C_o e_o)
            gammas.append(1.0 + np.arange(1, d.n_o + 1) * dsg.nu[k])      # γ_k = 1 + k ν
        self._Ato = sla.block_diag(*blocks_A)
        self._Lto = sla.block_diag(*blocks_L)
        self._Co1 = sla.block_diag(*blocks_C)
        self._gamma = np.concatenate(gammas)
        M, K, alpha = dsg.M, dsg.K, dsg.bold_alpha
        self._M, self._K, self._beta = M, K, dsg.beta
        self._Fu = dsg.bold_A_u - alpha @ M                                # (9), linear part
        self._Gu = dsg.bold_A_r + alpha @ K

    def flow_map(self, x):
        E = np.asarray(x, dtype=float)
        if not self.finite_time:
            return self._F @ E
        Eo, Eu = E[:self.n_obs], E[self.n_obs:]
        dEo = self._Ato @ Eo - self._Lto @ signed_power(self._Co1 @ Eo, self._gamma)  # (7)
        s = self._M @ Eu - self._K @ Eo
        dEu = self._Fu @ Eu + self._Gu @ Eo - signed_power(s, self._beta)            # (9)
        return np.concatenate([dEo, dEu])

    def split(self, E):
        """``E`` (..., state_dim) as per-node lists ``(e_o, e_u)`` (:func:`split_errors`)."""
        return split_errors(self.design, E)


def split_errors(dsg: DistributedDesign, E):
    """Stacked errors ``(E_o, E_u)`` of (6), shape (..., Σ n), as per-node lists.

    Returns
    -------
    e_o, e_u : list of ndarray
        ``e_o[k]`` (..., n_k) and ``e_u[k]`` (..., n − n_k), node ``dsg.nodelist[k]``.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.distributed import design, example_system, split_errors
    >>> A, C, G = example_system()
    >>> e_o, e_u = split_errors(design(A, C, G, nodelist=[1, 2, 3, 4]), np.arange(24.0))
    >>> e_o[1].tolist(), e_u[3].tolist()
    ([2.0, 3.0], [23.0])
    """
    E = np.asarray(E, dtype=float)
    cuts_o = np.cumsum([0] + list(dsg.n_o))
    cuts_u = cuts_o[-1] + np.cumsum([0] + list(dsg.n_u))
    if E.shape[-1] != cuts_u[-1]:
        raise ValueError(f"E must have {cuts_u[-1]} entries in its last axis (sum n_i + "
                         f"sum (n - n_i)), got shape {E.shape}")
    e_o = [E[..., a:b] for a, b in itertools.pairwise(cuts_o)]
    e_u = [E[..., a:b] for a, b in itertools.pairwise(cuts_u)]
    return e_o, e_u


def error_system(dsg: DistributedDesign) -> ErrorSystem:
    """The error system (6)-(9) of a design: an :class:`ErrorSystem`.

    Examples
    --------
    >>> from observers.distributed import design, example_system, error_system
    >>> A, C, G = example_system()
    >>> error_system(design(A, C, G, nodelist=[1, 2, 3, 4])).state_dim
    24
    """
    return ErrorSystem(dsg)


def error_initial_state(dsg: DistributedDesign, x0, xhat0=None):
    """``E(0) = (E_o(0), E_u(0))`` from the plant's ``x(0)`` and the estimates.

    ``e^i = T^{iᵀ} (x̃^i(0) − x(0))`` split into ``(e_o^i, e_u^i)`` and
    stacked in the order of (6).

    Parameters
    ----------
    dsg : DistributedDesign
    x0 : (n,) array_like
    xhat0 : (n,) or (N, n) array_like, optional
        Initial estimates (default 0), as in :func:`initial_state`.

    Examples
    --------
    >>> import numpy as np
    >>> from observers.distributed import design, example_system, error_initial_state
    >>> A, C, G = example_system()
    >>> dsg = design(A, C, G, nodelist=[1, 2, 3, 4])
    >>> error_initial_state(dsg, np.ones(6), np.ones(6)).shape
    (24,)
    """
    z = initial_state(dsg, x0, xhat0)
    n = dsg.n
    x = z[:n]
    e = [z[n * (k + 1):n * (k + 2)] - d.T.T @ x for k, d in enumerate(dsg.decomp)]
    return np.concatenate([ek[:d.n_o] for ek, d in zip(e, dsg.decomp)]
                          + [ek[d.n_o:] for ek, d in zip(e, dsg.decomp)])


# --------------------------------------------------------------------------
# the error system over batches, with noise (observers.distributed.falsification)
# --------------------------------------------------------------------------
class PopulationErrorSystem(hs.HybridSystem):
    """The error system (6)-(9) written over batches, with measurement noise.

    State ``(E, w)``: ``E = (E_o, E_u)`` as in :class:`ErrorSystem` (order of
    (6)) and ``w`` the coefficients of a noise of ``terms`` sinusoids per
    output, as :class:`hybridsim.falsification.Sinusoids` lays them out
    (amplitudes ``a``, frequencies ``f`` in Hz, phases ``φ``, each (N, terms)
    row-major; constant: their flow is zero). Node i's measurement is
    ``y^i = C^i x + m_i`` with ``m_i(t) = bound / terms Σ_k a_ik sin(2π f_ik t
    + φ_ik)``; the flow is, from (7) with that ``y^i`` and (9),

    ``ė_o^i = Ã_o^i e_o^i − Θ^i p^i m_i − L̃_o^i ⌈1 (C_o^i e_o^i − m_i)⌋^{γ^i}``

    ``Ė_u = (𝐀_u − α M) E_u + (𝐀_r + α K) E_o − ⌈M E_u − K E_o⌋^β``  (9)

    (the unobservable part receives no measurement: the neighbours'
    estimates carry the noise through ``E_o``). With ``terms = 0`` it is
    :class:`ErrorSystem` over batches.

    Parameters
    ----------
    dsg : DistributedDesign
        A finite-time design whose nodes all have ``n_i >= 1`` and scalar
        outputs (the example's).
    terms : int
        Sinusoids per output (0: no noise).
    bound : float
        The noise bound ε (|m_i| <= ε).

    Examples
    --------
    >>> import numpy as np
    >>> from observers.distributed import PopulationErrorSystem, example_observer, error_system
    >>> dsg = example_observer().design
    >>> pes = PopulationErrorSystem(dsg)
    >>> E = np.random.default_rng(0).standard_normal((3, 24))
    >>> bool(np.allclose(pes.flow_map(E, np.zeros(3))[1], error_system(dsg).flow_map(E[1])))
    True
    """

    vectorized = True

    def __init__(self, dsg: DistributedDesign, terms: int = 0, bound: float = 0.0):
        if dsg.kind != "finite-time":
            raise ValueError("PopulationErrorSystem needs a finite-time design (7)-(8)")
        if any(d.n_o == 0 for d in dsg.decomp) or any(c.shape[0] != 1 for c in dsg.C):
            raise ValueError("every node needs a scalar output and n_i >= 1")
        es = ErrorSystem(dsg)
        self.design, self.es = dsg, es
        self.n_err, self.n_obs = es.state_dim, es.n_obs
        self.terms, self.bound, self.p = int(terms), float(bound), dsg.N
        self.state_dim = self.n_err + 3 * self.terms * self.p
        cuts = np.cumsum([0] + list(dsg.n_o))
        self._R = np.zeros((self.n_obs, self.p))            # 1 m_i in node i's rows
        self._Pt = np.zeros((self.n_obs, self.p))           # Θ^i p^i m_i
        for k in range(self.p):
            self._R[cuts[k]:cuts[k + 1], k] = 1.0
            self._Pt[cuts[k]:cuts[k + 1], k] = dsg.Theta[k] @ dsg.p[k]

    def noise(self, x, t):
        """The noise ``m(t)`` (..., N outputs) encoded in the states ``x``."""
        x = np.asarray(x, dtype=float)
        if not self.terms:
            return np.zeros(x.shape[:-1] + (self.p,))
        w = x[..., self.n_err:]
        k = self.terms * self.p
        a = w[..., :k].reshape(w.shape[:-1] + (self.p, self.terms))
        f = w[..., k:2 * k].reshape(a.shape)
        ph = w[..., 2 * k:].reshape(a.shape)
        t = np.asarray(t, dtype=float).reshape(np.shape(t) + (1, 1))
        return self.bound / self.terms * np.sum(a * np.sin(2 * np.pi * f * t + ph), axis=-1)

    def flow_map(self, x, t):
        es = self.es
        x = np.asarray(x, dtype=float)
        Eo, Eu = x[..., :self.n_obs], x[..., self.n_obs:self.n_err]
        arg = Eo @ es._Co1.T
        dEo = Eo @ es._Ato.T
        if self.terms:
            m = self.noise(x, t)
            arg = arg - m @ self._R.T
            dEo = dEo - m @ self._Pt.T
        dEo = dEo - signed_power(arg, es._gamma) @ es._Lto.T                    # (7)
        s = Eu @ es._M.T - Eo @ es._K.T
        dEu = Eu @ es._Fu.T + Eo @ es._Gu.T - signed_power(s, es._beta)          # (9)
        return np.concatenate([dEo, dEu, np.zeros(x.shape[:-1] + (self.state_dim
                                                                   - self.n_err,))],
                              axis=-1)
