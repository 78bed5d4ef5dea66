"""Design computations of paper 003: graph, decompositions, gains, bounds, LMIs.

Pure numpy/scipy (cvxpy for the LMIs). Every function names its equation
of Silm, Efimov, Michiels, Ushirobira and Richard (SCL 2020):

* :func:`graph_matrices` -- 𝒜, 𝒟 and 𝓛 = 𝒟 − 𝒜 of Section 2 (decision 1 of
  :mod:`observers.distributed`: the text's 𝓛 = 𝒜 − 𝒟 has the wrong sign).
* :func:`check_network` -- Assumption 1, Theorem 1, Remark 1.
* :func:`observability_decomposition` -- the orthogonal decomposition (2).
* :func:`observer_canonical_form` -- Θ and p of Section 3.1, before (7).
* :func:`proposition2_bound` -- η and the bound on ν_i of Prop. 2.
* :func:`luenberger_gain` -- L_o of (3)-(4).
* :func:`design` -- all of it for one network: a :class:`DistributedDesign`
  (bold block-diagonal matrices of (6) and (9), :meth:`~DistributedDesign.error_matrix` of (6)).
* :func:`proposition1_lyapunov` -- the diagonal Lyapunov matrix of Prop. 1.
* :func:`lmi11_data`, :func:`lmi11`, :func:`choose_alpha` -- (10)-(11) of
  Lemma 1 and the proof of Theorem 1.

Examples
--------
>>> from observers.distributed import design, example_system
>>> A, C, G = example_system()
>>> dsg = design(A, C, G, nodelist=[1, 2, 3, 4])
>>> dsg.n_o, dsg.n_u
([2, 2, 5, 5], [4, 4, 1, 1])
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import networkx as nx
import numpy as np
import scipy.linalg as sla

from .._common import matrix

__all__ = [
    "DEFAULT_RTOL",
    "signed_power",
    "GraphMatrices",
    "graph_matrices",
    "NetworkCheck",
    "check_network",
    "observability_matrix",
    "ObservabilityDecomposition",
    "observability_decomposition",
    "observer_canonical_form",
    "hurwitz_coefficients",
    "proposition2_bound",
    "luenberger_gain",
    "split_vector_outputs",
    "DistributedDesign",
    "design",
    "proposition1_lyapunov",
    "LMI11Result",
    "lmi11_data",
    "lmi11",
    "choose_alpha",
]

DEFAULT_RTOL = 1e-9


# --------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------
def signed_power(a, b):
    """Sign-preserving element-wise power ``⌈a⌋^b = sgn(a) |a|^b``.

    Parameters
    ----------
    a : array_like
        Base.
    b : array_like
        Exponents (broadcast against ``a``), non-negative.

    Returns
    -------
    numpy.ndarray

    References
    ----------
    Silm et al. (2020), Notation.
    """
    a = np.asarray(a, dtype=float)
    return np.sign(a) * np.abs(a) ** np.asarray(b, dtype=float)


def _row_matrix(name, M, cols):
    """``M`` as a matrix of ``cols`` columns; a 1-D array is one row (an output row C^i)."""
    return matrix(name, M, shape=(1, cols) if np.ndim(M) == 1 else (None, cols))


def _check_graph(G):
    if not isinstance(G, nx.DiGraph):
        raise TypeError(f"G must be a networkx.DiGraph; got {type(G).__name__}")
    if G.is_multigraph():
        raise TypeError("G must be a simple networkx.DiGraph, not a MultiDiGraph")
    loops = list(nx.selfloop_edges(G))
    if loops:
        raise ValueError(f"G must have no self-loops; got {loops}")
    if G.number_of_nodes() == 0:
        raise ValueError("G must have at least one node")


def _nodelist(G, nodelist):
    if nodelist is None:
        return list(G.nodes)
    nodelist = list(nodelist)
    if len(nodelist) != G.number_of_nodes() or set(nodelist) != set(G.nodes):
        raise ValueError(
            f"nodelist must list every node of G exactly once; got {nodelist} "
            f"for nodes {list(G.nodes)}")
    if len(set(nodelist)) != len(nodelist):
        raise ValueError(f"nodelist has repeated nodes: {nodelist}")
    return nodelist


def _output_list(C, nodelist, n):
    """C as a list aligned with nodelist (C: mapping node -> C^i, or sequence)."""
    if isinstance(C, Mapping):
        missing = [v for v in nodelist if v not in C]
        if missing:
            raise ValueError(f"C has no output matrix for nodes {missing}")
        Cs = [C[v] for v in nodelist]
    else:
        Cs = list(C)
        if len(Cs) != len(nodelist):
            raise ValueError(
                f"C must have one output matrix per node: expected {len(nodelist)}, "
                f"got {len(Cs)}")
    return [_row_matrix(f"C[{v!r}]", Ci, n) for Ci, v in zip(Cs, nodelist)]


# --------------------------------------------------------------------------
# graph
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class GraphMatrices:
    """Adjacency ``𝒜``, in-degree ``𝒟`` and Laplacian ``𝓛 = 𝒟 − 𝒜``."""

    adjacency: np.ndarray
    degree: np.ndarray
    laplacian: np.ndarray
    nodelist: list


def graph_matrices(G, nodelist=None) -> GraphMatrices:
    """Adjacency, in-degree and Laplacian matrices of a communication graph.

    Row/column ``k`` belongs to ``nodelist[k]``; ``a_ik = 1`` when ``G`` has the
    edge ``k -> i`` (node ``i`` receives from node ``k``); edge weights are
    ignored (the paper's graph is simple and unweighted).  ``𝒟`` is the
    diagonal in-degree matrix and ``𝓛 = 𝒟 − 𝒜`` (rows sum to zero).

    Decision: the paper writes ``𝓛 = 𝒜 − 𝒟``; the error system (6), derived
    from (5), and the Appendix need ``𝒟 − 𝒜`` (see the module docstring).
    networkx's ``laplacian_matrix`` uses out-degrees for a DiGraph, so the
    matrices are built here explicitly.

    Parameters
    ----------
    G : networkx.DiGraph
        Simple directed graph, no self-loops.
    nodelist : sequence, optional
        Node order (default ``list(G.nodes)``).

    Returns
    -------
    GraphMatrices

    References
    ----------
    Silm et al. (2020), Section 2 (definition of 𝓛), eq. (6), Appendix.
    """
    _check_graph(G)
    nodes = _nodelist(G, nodelist)
    index = {v: k for k, v in enumerate(nodes)}
    N = len(nodes)
    Adj = np.zeros((N, N))
    for j, i in G.edges:  # edge j -> i: i receives from j
        Adj[index[i], index[j]] = 1.0
    D = np.diag(Adj.sum(axis=1))
    return GraphMatrices(Adj, D, D - Adj, nodes)


# --------------------------------------------------------------------------
# observability
# --------------------------------------------------------------------------
def observability_matrix(A, C):
    """Observability matrix ``[C; CA; ...; CA^{n-1}]`` of shape ``(n m, n)``."""
    A = matrix("A", A, square=True)
    n = A.shape[0]
    C = _row_matrix("C", C, n)
    blocks = [C]
    for _ in range(n - 1):
        blocks.append(blocks[-1] @ A)
    return np.vstack(blocks)


def _rank(M, rtol):
    if M.size == 0:
        return 0
    s = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(s > rtol * s[0])) if s[0] > 0 else 0


@dataclass(frozen=True)
class ObservabilityDecomposition:
    """Orthogonal observability decomposition (2) of one node.

    ``T = [T_o, T_u]`` is orthogonal, the columns of ``T_u`` span the kernel of
    the observability matrix of ``(A, C^i)``, and
    ``Tᵀ A T = [[A_o, 0], [A_r, A_u]]``, ``C^i T = [C_o, 0]``.
    """

    T_o: np.ndarray
    T_u: np.ndarray
    A_o: np.ndarray
    A_r: np.ndarray
    A_u: np.ndarray
    C_o: np.ndarray
    singular_values: np.ndarray
    rtol: float

    @property
    def n_o(self) -> int:
        """Dimension ``n_i`` of the locally observable part."""
        return self.T_o.shape[1]

    @property
    def n_u(self) -> int:
        """Dimension ``n − n_i`` of the locally unobservable part."""
        return self.T_u.shape[1]

    @property
    def T(self) -> np.ndarray:
        return np.hstack([self.T_o, self.T_u])


def observability_decomposition(A, C, rtol=DEFAULT_RTOL) -> ObservabilityDecomposition:
    """Orthogonal observability decomposition (2) of the pair ``(A, C)``.

    The SVD ``O = U S Vᵀ`` of the observability matrix gives ``T_o`` (right
    singular vectors of the singular values ``> rtol * σ_max``) and ``T_u``
    (the others: an orthonormal basis of ``ker O``).  ``T_o`` and ``T_u`` are
    not unique (any orthogonal change of basis inside each part); the
    invariants are the spectra of ``A_o``, ``A_u`` and ``C T_u = 0``.

    Parameters
    ----------
    A : (n, n) array_like
    C : (m, n) array_like
    rtol : float
        Relative rank tolerance on the singular values.

    Returns
    -------
    ObservabilityDecomposition

    References
    ----------
    Silm et al. (2020), Section 2.1, eq. (2).
    """
    A = matrix("A", A, square=True)
    n = A.shape[0]
    C = _row_matrix("C", C, n)
    if not (0 < rtol < 1):
        raise ValueError(f"rtol must be in (0, 1); got {rtol}")
    O = observability_matrix(A, C)
    _, s, Vt = np.linalg.svd(O)
    r = int(np.sum(s > rtol * s[0])) if s[0] > 0 else 0
    T_o, T_u = Vt[:r].T.copy(), Vt[r:].T.copy()
    return ObservabilityDecomposition(
        T_o=T_o, T_u=T_u,
        A_o=T_o.T @ A @ T_o, A_r=T_u.T @ A @ T_o, A_u=T_u.T @ A @ T_u,
        C_o=C @ T_o, singular_values=s, rtol=rtol)


def observer_canonical_form(A_o, C_o):
    """Observer canonical form ``Θ`` of an observable single-output pair.

    Returns ``Θ`` and ``p`` with ``Θ^{-1} A_o Θ = 𝓘 − p e_1ᵀ`` and
    ``C_o Θ = e_1ᵀ``, where ``𝓘`` is the upper shift (integrator chain
    ``ż_k = z_{k+1}``) and ``det(sI − A_o) = s^n + p_1 s^{n-1} + ... + p_n``.
    ``Θ = O(A_o, C_o)^{-1} O(𝓘 − p e_1ᵀ, e_1ᵀ)`` is unique.

    Parameters
    ----------
    A_o : (n_i, n_i) array_like
    C_o : (1, n_i) array_like
        A single output row (vector outputs: see :func:`split_vector_outputs`).

    Returns
    -------
    Theta : (n_i, n_i) ndarray
    p : (n_i,) ndarray

    References
    ----------
    Silm et al. (2020), Section 3.1, text before eq. (7).
    """
    A_o = matrix("A_o", A_o, square=True)
    n = A_o.shape[0]
    C_o = _row_matrix("C_o", C_o, n)
    if C_o.shape[0] != 1:
        raise ValueError(
            f"C_o must have exactly one row (scalar output); got shape {C_o.shape}; "
            "for vector outputs use split_vector_outputs")
    if n == 0:
        return np.zeros((0, 0)), np.zeros(0)
    p = np.real(np.poly(A_o))[1:]
    Ac = np.eye(n, k=1) - np.outer(p, np.eye(n)[0])
    O = observability_matrix(A_o, C_o)
    if _rank(O, DEFAULT_RTOL) < n:
        raise ValueError("(A_o, C_o) must be observable")
    Oc = observability_matrix(Ac, np.eye(n)[:1])
    Theta = np.linalg.solve(O, Oc)
    return Theta, p


def hurwitz_coefficients(poles):
    """Coefficients ``[L_1..L_n]`` of the monic ``Π (s − pole_k)``."""
    poles = np.atleast_1d(np.asarray(poles, dtype=complex))
    if np.any(poles.real >= 0):
        raise ValueError(f"poles must have negative real parts; got {poles}")
    c = np.poly(poles)
    if np.max(np.abs(c.imag)) > 1e-9 * max(1.0, np.max(np.abs(c.real))):
        raise ValueError("poles must be closed under complex conjugation")
    return np.real(c[1:])


def proposition2_bound(L, Q=None, optimize=False):
    """``η`` and the admissible range of ``ν_i`` of Proposition 2.

    Solves ``(𝓘 − L e_1ᵀ)ᵀ P + P (𝓘 − L e_1ᵀ) = −Q``, rescales ``(P, Q)`` so that
    ``λ_min(P) = 1`` (``P ⪰ I``, the scaling that maximises ``η``) and returns
    ``η = λ_min(Q)/λ_max(P) · e / (2 ‖P diag(L)‖₂)`` and
    ``ν_min = −η / (n (√n + η))``: Proposition 2 guarantees finite-time
    convergence of (7) for ``ν_min < ν_i < 0``.  The condition is only
    sufficient.

    Parameters
    ----------
    L : (n,) array_like
        Coefficients of a monic Hurwitz polynomial.
    Q : (n, n) array_like, optional
        Positive definite right-hand side (default identity).
    optimize : bool
        If True, maximise ``η`` over diagonal ``Q`` (Nelder-Mead on log-entries,
        started from ``Q``); ``Q`` must then be diagonal or None.

    Returns
    -------
    eta : float
    nu_min : float
    Q : (n, n) ndarray
        The ``Q`` used (after rescaling).

    References
    ----------
    Silm et al. (2020), Proposition 2.
    """
    L = np.asarray(L, dtype=float)
    if L.ndim != 1 or L.size == 0:
        raise ValueError(f"L must be a non-empty 1-D array; got shape {L.shape}")
    n = L.size
    F = np.eye(n, k=1) - np.outer(L, np.eye(n)[0])
    if np.max(np.linalg.eigvals(F).real) >= 0:
        raise ValueError(f"L must hold the coefficients of a Hurwitz polynomial; got {L}")
    Q = np.eye(n) if Q is None else matrix("Q", Q, shape=(n, n))
    if np.min(np.linalg.eigvalsh((Q + Q.T) / 2)) <= 0:
        raise ValueError("Q must be positive definite")

    def eta_of(Qm):
        P = sla.solve_continuous_lyapunov(F.T, -Qm)
        P = (P + P.T) / 2
        ev = np.linalg.eigvalsh(P)
        s = ev[0]
        P, Qs = P / s, Qm / s
        return (np.min(np.linalg.eigvalsh((Qs + Qs.T) / 2)) / (ev[-1] / s)
                * math.e / (2 * np.linalg.norm(P @ np.diag(L), 2))), Qs

    eta, Qs = eta_of(Q)
    if optimize:
        from scipy.optimize import minimize
        if np.count_nonzero(Q - np.diag(np.diag(Q))):
            raise ValueError("Q must be diagonal when optimize=True")
        res = minimize(lambda w: -eta_of(np.diag(np.exp(w)))[0],
                       np.log(np.diag(Q)), method="Nelder-Mead",
                       options={"xatol": 1e-6, "fatol": 1e-12, "maxiter": 4000})
        eta2, Qs2 = eta_of(np.diag(np.exp(res.x)))
        if eta2 > eta:
            eta, Qs = eta2, Qs2
    nu_min = -eta / (n * (math.sqrt(n) + eta))
    return float(eta), float(nu_min), Qs


def luenberger_gain(A_o, C_o, poles):
    """Gain ``L_o`` with ``eig(A_o − L_o C_o) = poles`` (observer (4)).

    Scalar output: Ackermann's formula through the canonical form,
    ``L_o = Θ (l − p)`` (``l`` the coefficients of ``Π (s − pole)``; repeated
    poles allowed).  Vector output: ``scipy.signal.place_poles`` (a pole may be
    repeated at most ``m`` times).

    References
    ----------
    Silm et al. (2020), eqs. (3)-(4).
    """
    A_o = matrix("A_o", A_o, square=True)
    n = A_o.shape[0]
    C_o = _row_matrix("C_o", C_o, n)
    poles = np.atleast_1d(np.asarray(poles, dtype=complex))
    if poles.size != n:
        raise ValueError(f"poles must have {n} entries; got {poles.size}")
    if n == 0:
        return np.zeros((0, C_o.shape[0]))
    if C_o.shape[0] == 1:
        Theta, p = observer_canonical_form(A_o, C_o)
        return (Theta @ (hurwitz_coefficients(poles) - p))[:, None]
    from scipy.signal import place_poles
    return place_poles(A_o.T, C_o.T, poles).gain_matrix.T


# --------------------------------------------------------------------------
# network checks
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class NetworkCheck:
    """Result of :func:`check_network`."""

    strongly_connected: bool
    source_components: list
    jointly_observable: bool
    locally_observable: list  # nodes i with (A, C^i) observable


def check_network(A, C, G, nodelist=None, rtol=DEFAULT_RTOL, *, warn=True) -> NetworkCheck:
    """Check the conditions of Theorem 1 (with Remark 1's generalisation).

    Requires that every source component of ``G`` (strongly connected
    component without incoming edges) is jointly observable (Assumption 1 on
    that component's outputs); for a strongly connected graph this is joint
    observability.  Raises ``ValueError`` otherwise.  Warns (``UserWarning``)
    when a single pair ``(A, C^i)`` is observable: the paper assumes none is,
    but the design still applies (that node has no unobservable part).

    Parameters
    ----------
    A : (n, n) array_like
    C : sequence or mapping
        ``C^i`` per node (aligned with ``nodelist`` or keyed by node).
    G : networkx.DiGraph
    nodelist : sequence, optional
    rtol : float
        Rank tolerance (see :func:`observability_decomposition`).

    Returns
    -------
    NetworkCheck

    References
    ----------
    Silm et al. (2020), Assumption 1, Theorem 1, Remark 1.
    """
    A = matrix("A", A, square=True)
    n = A.shape[0]
    _check_graph(G)
    nodes = _nodelist(G, nodelist)
    Cs = _output_list(C, nodes, n)
    Cmap = dict(zip(nodes, Cs))
    strong = nx.is_strongly_connected(G)
    cond = nx.condensation(G)
    sources = [sorted(cond.nodes[c]["members"], key=nodes.index)
               for c in cond.nodes if cond.in_degree(c) == 0]
    joint = _rank(observability_matrix(A, np.vstack(Cs)), rtol) == n
    local = [v for v in nodes if _rank(observability_matrix(A, Cmap[v]), rtol) == n]
    for comp in sources:
        Ccomp = np.vstack([Cmap[v] for v in comp])
        if _rank(observability_matrix(A, Ccomp), rtol) < n:
            what = ("the system is not jointly observable (Assumption 1)" if strong else
                    f"source component {comp} of G is not jointly observable (Remark 1)")
            raise ValueError(f"C, G: {what}")
    if warn and local:
        warnings.warn(f"(A, C^i) is observable for nodes {local}: the paper assumes no "
                      "single node can observe the state (the design still applies)",
                      UserWarning, stacklevel=2)
    return NetworkCheck(strong, sources, joint, local)


def split_vector_outputs(G, C, nodelist=None):
    """Give each entry of a vector output to an imaginary node.

    Following the paper's Conclusion, node ``v`` with ``m_v > 1`` outputs is
    replaced by nodes ``(v, 0), ..., (v, m_v − 1)``, each measuring one row of
    ``C^v``.  They form a complete digraph (they sit on the same device) and
    each inherits ``v``'s in- and out-edges, so strong connectivity and joint
    observability are preserved.  Scalar-output nodes keep their name.

    Returns
    -------
    G2 : networkx.DiGraph
    C2 : dict
        node -> (1, n) output row.
    groups : dict
        original node -> list of its new nodes.

    References
    ----------
    Silm et al. (2020), Section 3.1 (vector outputs) and Section 5.
    """
    _check_graph(G)
    nodes = _nodelist(G, nodelist)
    first = next(iter(C.values())) if isinstance(C, Mapping) else next(iter(C), None)
    if first is None:
        raise ValueError("C must hold one output matrix per node; got none")
    Cs = _output_list(C, nodes, np.atleast_2d(np.asarray(first)).shape[1])
    groups = {}
    C2 = {}
    G2 = nx.DiGraph()
    for v, Ci in zip(nodes, Cs):
        if Ci.shape[0] == 1:
            groups[v] = [v]
            C2[v] = Ci
        else:
            groups[v] = [(v, k) for k in range(Ci.shape[0])]
            for k, w in enumerate(groups[v]):
                C2[w] = Ci[k:k + 1]
        G2.add_nodes_from(groups[v])
        G2.add_edges_from((a, b) for a in groups[v] for b in groups[v] if a != b)
    for u, v in G.edges:
        G2.add_edges_from((a, b) for a in groups[u] for b in groups[v])
    return G2, C2, groups


# --------------------------------------------------------------------------
# the design of the whole network
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class DistributedDesign:
    """Every matrix of the distributed observer (3)-(8) for one network.

    Per-node quantities are lists aligned with ``nodelist``; bold quantities
    of the paper (block-diagonal over the nodes) are attributes with a ``bold_``
    prefix.  Build with :func:`design`.
    """

    A: np.ndarray
    C: list
    G: Any
    nodelist: list
    kind: str
    graph: GraphMatrices
    decomp: list  # ObservabilityDecomposition per node
    Theta: list  # Θ^i (finite-time kind; None for vector outputs)
    p: list
    L: list  # L_o^i of (7) (coefficients of the Hurwitz polynomial)
    L_lin: list  # Luenberger gain of (3)/(4) in x_o^i coordinates, (n_i, m_i)
    nu: np.ndarray
    alpha: np.ndarray
    beta: float | None
    eta: np.ndarray  # Proposition 2 per node (nan when not applicable)
    nu_min: np.ndarray
    check: NetworkCheck
    rtol: float = DEFAULT_RTOL

    # -- sizes -----------------------------------------------------------
    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def N(self) -> int:
        return len(self.nodelist)

    @property
    def n_o(self) -> list:
        return [d.n_o for d in self.decomp]

    @property
    def n_u(self) -> list:
        return [d.n_u for d in self.decomp]

    @property
    def meets_proposition2(self) -> np.ndarray:
        """Per node: does ``ν_i`` lie in Proposition 2's sufficient range."""
        return (self.nu > self.nu_min) & (self.nu < 0)

    def in_neighbours(self, v) -> list:
        """``𝒩_i`` in ``nodelist`` order."""
        preds = set(self.G.predecessors(v))
        return [w for w in self.nodelist if w in preds]

    # -- bold block-diagonal matrices of Section 2.2 ----------------------
    @property
    def bold_T_o(self):
        return sla.block_diag(*[d.T_o for d in self.decomp])

    @property
    def bold_T_u(self):
        return sla.block_diag(*[d.T_u for d in self.decomp])

    @property
    def bold_A_o(self):
        return sla.block_diag(*[d.A_o for d in self.decomp])

    @property
    def bold_A_r(self):
        return sla.block_diag(*[d.A_r for d in self.decomp])

    @property
    def bold_A_u(self):
        return sla.block_diag(*[d.A_u for d in self.decomp])

    @property
    def bold_alpha(self):
        """``α = blkdiag(α_i I_{n − n_i})``."""
        return np.diag(np.repeat(self.alpha, self.n_u))

    @property
    def M(self):
        """``T_uᵀ (𝓛 ⊗ I_n) T_u`` (Proposition 1, (9))."""
        Tu = self.bold_T_u
        return Tu.T @ np.kron(self.graph.laplacian, np.eye(self.n)) @ Tu

    @property
    def K(self):
        """``T_uᵀ (𝒜 ⊗ I_n) T_o`` ((6), (9); decision 2)."""
        return (self.bold_T_u.T @ np.kron(self.graph.adjacency, np.eye(self.n))
                @ self.bold_T_o)

    def error_matrix(self):
        """The matrix of the linear error system (6), state ``(E_o, E_u)``.

        Uses the Luenberger gains :attr:`L_lin` (the linearisation of (7) at
        ``ν = 0``).
        """
        LC = sla.block_diag(*[Ll @ d.C_o for Ll, d in zip(self.L_lin, self.decomp)])
        no, nu_ = sum(self.n_o), sum(self.n_u)
        top = np.hstack([self.bold_A_o - LC, np.zeros((no, nu_))])
        bot = np.hstack([self.bold_A_r + self.bold_alpha @ self.K,
                         self.bold_A_u - self.bold_alpha @ self.M])
        return np.vstack([top, bot])


def design(A, C, G, nodelist=None, *, kind="finite-time", poles=-3.0, nu=-0.1,
           alpha=10.0, beta=0.7, rtol=DEFAULT_RTOL, warn=True) -> DistributedDesign:
    """Design the distributed observer (3)-(5) or (7)-(8) of a network.

    Parameters
    ----------
    A : (n, n) array_like
        Plant matrix of (1).
    C : sequence or mapping
        Output matrices ``C^i`` (aligned with ``nodelist`` or keyed by node).
    G : networkx.DiGraph
        Communication graph; edge ``j -> i``: node ``i`` receives ``x̃^j``.
    nodelist : sequence, optional
        Node order of every stacked quantity (default ``list(G.nodes)``).
    kind : {"finite-time", "linear"}
        (7)-(8) (scalar outputs only) or the linear observer (3)-(5).
    poles : float or sequence
        Eigenvalues of the observable error dynamics at ``ν = 0``: a scalar
        (repeated ``n_i`` times, the paper's ``−3``), or a mapping node ->
        poles.
    nu : float or sequence
        ``ν_i`` of (7), ``−1/n_i < ν_i ≤ 0`` (ignored for ``kind="linear"``).
    alpha : float or sequence
        Consensus gains ``α_i > 0``.
    beta : float
        Exponent ``0 < β < 1`` of (8) (ignored for ``kind="linear"``).
    rtol : float
        Rank tolerance of the observability decompositions.
    warn : bool
        Warn when a node is locally observable (:func:`check_network`).

    Returns
    -------
    DistributedDesign

    References
    ----------
    Silm et al. (2020), eqs. (2)-(8), Proposition 2, Theorem 1.
    """
    if kind not in ("finite-time", "linear"):
        raise ValueError(f"kind must be 'finite-time' or 'linear'; got {kind!r}")
    A = matrix("A", A, square=True)
    n = A.shape[0]
    _check_graph(G)
    nodes = _nodelist(G, nodelist)
    N = len(nodes)
    Cs = _output_list(C, nodes, n)
    check = check_network(A, Cs, G, nodes, rtol, warn=warn)

    def per_node(val, name):
        arr = np.asarray(val, dtype=float)
        if arr.ndim == 0:
            return np.full(N, float(arr))
        if arr.shape != (N,):
            raise ValueError(f"{name} must be a scalar or have shape ({N},); got {arr.shape}")
        return arr.copy()

    alpha = per_node(alpha, "alpha")
    if np.any(alpha <= 0):
        raise ValueError(f"alpha must be positive; got {alpha}")
    if kind == "finite-time":
        nu = per_node(nu, "nu")
        if beta is None or not (0 < beta < 1):
            raise ValueError(f"beta must be in (0, 1); got {beta}")
        beta = float(beta)
    else:
        nu = np.zeros(N)
        beta = None

    decomp, Thetas, ps, Ls, Llins = [], [], [], [], []
    eta = np.full(N, np.nan)
    nu_min = np.full(N, np.nan)
    for k, (v, Ci) in enumerate(zip(nodes, Cs)):
        d = observability_decomposition(A, Ci, rtol)
        decomp.append(d)
        pol = poles[v] if isinstance(poles, Mapping) else poles
        try:
            pol = np.atleast_1d(np.asarray(pol, dtype=complex))
        except (TypeError, ValueError) as exc:
            raise TypeError(f"poles for node {v!r} must be numbers (a scalar or a sequence); "
                            f"got {pol!r}") from exc
        if not np.all(np.isfinite(pol)) or not np.all(pol.real < 0):
            raise ValueError(f"poles for node {v!r} must be finite with negative real parts; "
                             f"got {pol}")
        if pol.size == 1:
            pol = np.repeat(pol, d.n_o)
        if pol.size != d.n_o:
            raise ValueError(f"poles for node {v!r} must have {d.n_o} entries; got {pol.size}")
        if Ci.shape[0] == 1:
            Theta, p = observer_canonical_form(d.A_o, d.C_o)
            Lk = hurwitz_coefficients(pol) if d.n_o else np.zeros(0)
            Llin = (Theta @ (Lk - p))[:, None]
            if d.n_o:
                eta[k], nu_min[k], _ = proposition2_bound(Lk)
        else:
            if kind == "finite-time":
                raise ValueError(
                    f"C[{v!r}] has {Ci.shape[0]} rows: the finite-time observer (7) needs "
                    "scalar outputs; use split_vector_outputs (paper, Section 5)")
            Theta, p, Lk = None, None, None
            Llin = luenberger_gain(d.A_o, d.C_o, pol)
        if kind == "finite-time" and d.n_o and not (-1.0 / d.n_o < nu[k] <= 0):
            raise ValueError(f"nu for node {v!r} must lie in (-1/n_i, 0] = "
                             f"({-1.0 / d.n_o:.4g}, 0]; got {nu[k]}")
        Thetas.append(Theta)
        ps.append(p)
        Ls.append(Lk)
        Llins.append(Llin)
    return DistributedDesign(
        A=A, C=Cs, G=G, nodelist=nodes, kind=kind, graph=graph_matrices(G, nodes),
        decomp=decomp, Theta=Thetas, p=ps, L=Ls, L_lin=Llins, nu=nu, alpha=alpha,
        beta=beta, eta=eta, nu_min=nu_min, check=check, rtol=rtol)


# --------------------------------------------------------------------------
# LMIs: Proposition 1 and (11)
# --------------------------------------------------------------------------
def _lmi():
    """The generic SDP helpers of :mod:`observers.lmi` (Clarabel + verification)."""
    from observers import lmi
    return lmi


def proposition1_lyapunov(dsg: DistributedDesign, method="appendix"):
    """Diagonal Lyapunov matrix ``P`` of Proposition 1.

    ``−Mᵀ P − P M ≺ 0`` with ``M = T_uᵀ (𝓛 ⊗ I) T_u`` and ``P`` diagonal
    positive definite.

    Parameters
    ----------
    dsg : DistributedDesign
    method : {"appendix", "lmi"}
        ``"appendix"``: ``P = blkdiag(r_i I_{n − n_i})`` with ``r > 0`` the left
        null vector of ``𝓛`` (needs a strongly connected graph), as in the
        Appendix; ``"lmi"``: a diagonal ``P ⪰ I`` with ``Mᵀ P + P M ⪰ I`` found by
        cvxpy/Clarabel (works too under Remark 1's conditions).

    Returns
    -------
    P : ndarray
        Diagonal matrix, verified: ``λ_min(Mᵀ P + P M) > 0``.
    margin : float
        ``λ_min(Mᵀ P + P M) / λ_max(P)``.

    Raises
    ------
    ValueError
        Bad ``method``; ``"appendix"`` on a graph that is not strongly
        connected; verification failed.

    References
    ----------
    Silm et al. (2020), Proposition 1 and its proof (Appendix).
    """
    M = dsg.M
    if M.shape[0] == 0:
        return np.zeros((0, 0)), np.inf
    if method == "appendix":
        if not dsg.check.strongly_connected:
            raise ValueError("method='appendix' needs a strongly connected graph; "
                             "use method='lmi'")
        Lap = dsg.graph.laplacian
        _, _, Vt = np.linalg.svd(Lap.T)
        r = Vt[-1]
        r = r * np.sign(r.sum())
        if np.any(r <= 0):  # pragma: no cover - excluded by strong connectivity
            raise ValueError("left null vector of the Laplacian is not positive")
        P = np.diag(np.repeat(r / r.max(), dsg.n_u))
    elif method == "lmi":
        lmi = _lmi()
        cp = lmi.require_cvxpy()
        m = M.shape[0]
        w = cp.Variable(m)
        S = M.T @ cp.diag(w) + cp.diag(w) @ M
        try:
            lmi.solve_sdp(cp.Minimize(cp.sum(w)), [w >= 1, (S + S.T) / 2 >> np.eye(m)])
        except lmi.LMISolverError as exc:
            raise ValueError(f"Proposition 1 LMI not solved: {exc}") from exc
        P = np.diag(np.asarray(w.value))
    else:
        raise ValueError(f"method must be 'appendix' or 'lmi'; got {method!r}")
    lam = np.linalg.eigvalsh(M.T @ P + P @ M)[0]
    if lam <= 0 or np.min(np.diag(P)) <= 0:
        raise ValueError(f"Proposition 1 verification failed: λ_min = {lam:.3g}")
    return P, float(lam / np.max(np.diag(P)))


@dataclass(frozen=True)
class LMI11Result:
    """Outcome of :func:`lmi11`.

    ``feasible`` is True only when the returned ``P ≻ 0``, diagonal
    ``Λ ≻ 0``, ``Υ ≻ 0`` make ``Φ`` of (11) negative definite when
    recomputed in numpy (``max_eig_Phi < 0``).
    """

    feasible: bool
    status: str
    alpha: np.ndarray
    P: np.ndarray | None
    Lambda: np.ndarray | None
    Upsilon: np.ndarray | None
    max_eig_Phi: float
    min_eig_vars: float
    M1: np.ndarray
    M2: np.ndarray


def lmi11_data(dsg: DistributedDesign, alpha=None):
    """``M_1`` and ``M_2`` of (10) for the unobservable error network (9).

    ``M_1 = M A_u M^{-1} − M α`` and ``M_2 = −M`` with ``M = T_uᵀ(𝓛⊗I)T_u``,
    ``α = blkdiag(α_i I)`` (proof of Theorem 1).
    """
    a = dsg.alpha if alpha is None else np.broadcast_to(
        np.asarray(alpha, dtype=float), (dsg.N,))
    if np.any(a <= 0):
        raise ValueError(f"alpha must be positive; got {a}")
    M = dsg.M
    if M.shape[0] and np.linalg.matrix_rank(M) < M.shape[0]:
        raise ValueError("T_u^T (L kron I) T_u is singular: check connectivity and "
                         "joint observability")
    Alpha = np.diag(np.repeat(a, dsg.n_u))
    M1 = M @ dsg.bold_A_u @ np.linalg.inv(M) - M @ Alpha if M.size else M
    return M1, -M, np.asarray(a, dtype=float)


def lmi11(dsg: DistributedDesign, alpha=None, *, eps=1e-4) -> LMI11Result:
    """Check LMI (11) of Lemma 1 for the error network (9).

    Finds ``P ≻ 0``, diagonal ``Λ ≻ 0`` and ``Υ ≻ 0`` minimising ``t`` with
    ``Φ ⪯ t I`` under the normalisation ``P, Λ, Υ ⪰ ε I`` and
    ``tr P + tr Λ + tr Υ = 3 m`` (``Φ`` is homogeneous in the variables, so the
    normalisation loses nothing but fixes the scale).  The solution is then
    verified in numpy: feasible means ``λ_max(Φ) < 0`` and the three matrices
    positive definite.

    Parameters
    ----------
    dsg : DistributedDesign
    alpha : float or (N,) array_like, optional
        Consensus gains (default ``dsg.alpha``).
    eps : float
        Lower bound of the variables' eigenvalues.

    Returns
    -------
    LMI11Result

    References
    ----------
    Silm et al. (2020), Lemma 1 (eq. (11)) and the proof of Theorem 1.
    """
    lmi = _lmi()
    cp = lmi.require_cvxpy()
    M1, M2, a = lmi11_data(dsg, alpha)
    m = M1.shape[0]
    if m == 0:
        e = np.zeros((0, 0))
        return LMI11Result(True, "trivial", a, e, e, e, -np.inf, np.inf, M1, M2)
    P = cp.Variable((m, m), symmetric=True)
    lam = cp.Variable(m)
    ups = cp.Variable(m)
    t = cp.Variable()
    Lam, Ups = cp.diag(lam), cp.diag(ups)
    B = M1.T @ Lam + P @ M2 + Ups
    Phi = cp.bmat([[M1.T @ P + P @ M1, B], [B.T, M2.T @ Lam + Lam @ M2]])
    cons = [P >> eps * np.eye(m), lam >= eps, ups >= eps,
            cp.trace(P) + cp.sum(lam) + cp.sum(ups) == 3 * m,
            (Phi + Phi.T) / 2 << t * np.eye(2 * m)]
    try:
        lmi.solve_sdp(cp.Minimize(t), cons)
    except lmi.LMISolverError as exc:
        return LMI11Result(False, str(exc), a, None, None, None, np.nan, np.nan, M1, M2)
    # verify the solution in numpy, not by the solver's status
    Pv = (P.value + P.value.T) / 2
    Lv, Uv = np.diag(lam.value), np.diag(ups.value)
    Bv = M1.T @ Lv + Pv @ M2 + Uv
    Phiv = np.block([[M1.T @ Pv + Pv @ M1, Bv], [Bv.T, M2.T @ Lv + Lv @ M2]])
    Phiv = (Phiv + Phiv.T) / 2
    max_eig = -lmi.lmi_margin(Phiv, "< 0", name="(11)")
    min_var = min(lmi.lmi_margin(X, "> 0") for X in (Pv, Lv, Uv))
    try:
        lmi.verify_lmis([("(11) Phi", Phiv, "< 0"), ("P", Pv, "> 0"),
                         ("Lambda", Lv, "> 0"), ("Upsilon", Uv, "> 0")])
        feasible, status = True, "verified"
    except lmi.LMIVerificationError as exc:
        feasible, status = False, str(exc)
    return LMI11Result(feasible, status, a, Pv, Lv, Uv, float(max_eig), float(min_var),
                       M1, M2)


def choose_alpha(dsg: DistributedDesign, candidates=(0.5, 1, 2, 5, 10, 20, 50, 100, 200,
                                                     500, 1000)):
    """Smallest common consensus gain ``α`` in ``candidates`` passing LMI (11).

    The proof of Theorem 1 shows (11) is feasible for ``α_1 = ... = α_N = α``
    large enough; the candidates are tried in increasing order.

    Returns
    -------
    alpha : float
    result : LMI11Result

    Raises
    ------
    ValueError
        When no candidate passes.

    References
    ----------
    Silm et al. (2020), proof of Theorem 1 and the text after it.
    """
    cands = sorted(float(c) for c in candidates)
    if not cands or cands[0] <= 0:
        raise ValueError(f"candidates must be positive; got {candidates}")
    last = None
    for c in cands:
        last = lmi11(dsg, c)
        if last.feasible:
            return c, last
    raise ValueError(f"LMI (11) infeasible for every alpha in {cands} "
                     f"(last max eig Phi = {last.max_eig_Phi:.3g})")


