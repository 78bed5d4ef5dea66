"""The builders of common interconnections: :func:`connect` (a plant feeding an
observer) and :func:`network` (one component per node of a directed graph),
both returning a :class:`hybridsim.Interconnection`."""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .compose import Interconnection, LinearInput
from .system import HybridSystem

__all__ = ["connect", "network"]


def connect(plant, observer, names=("plant", "observer")):
    """The cascade plant -> observer: the observer's input is the plant's output.

    Parameters
    ----------
    plant : HybridSystem
        A system without input (exogenous signals inside it).
    observer : HybridSystem
        A system whose ``input_dim`` equals the plant's output dimension.
    names : (str, str)
        Component names in the interconnection (and its arcs).

    Returns
    -------
    Interconnection

    Raises
    ------
    ValueError
        The plant has an input, or the plant's output dimension (its
        ``output_dim``, else the length of its output at x = 0) differs from
        the observer's ``input_dim``.
    TypeError
        plant or observer is not a HybridSystem.

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> class Copy(hs.HybridSystem):
    ...     state_dim, input_dim = 1, 1
    ...     def flow_map(self, x, t, j, y):
    ...         return y - x
    >>> sysm = hs.connect(hs.LinearPlant([[0.0, 1.0], [0.0, 0.0]], C=[[1.0, 0.0]]), Copy())
    >>> sysm.components
    {'plant': slice(0, 2, None), 'observer': slice(2, 3, None)}
    """
    p, o = names
    for what, s in (("plant", plant), ("observer", observer)):
        if not isinstance(s, HybridSystem):
            raise TypeError(f"{what} must be a HybridSystem, got {type(s).__name__}")
    if int(plant.input_dim or 0) > 0:
        raise ValueError(f"plant has input_dim={plant.input_dim}: connect() wires only the "
                         "plant's output; use Interconnection with inputs for a feedback loop")
    m = int(observer.input_dim or 0)
    if m <= 0:
        raise ValueError(f"connect: the observer ({type(observer).__name__}) has "
                         f"input_dim={observer.input_dim}, so it would never read the plant's "
                         f"output; set its input_dim to the plant's output dimension "
                         f"(the observer's maps take it as u)")
    q = _output_dim(plant)
    if m > 0 and q is not None and q != m:
        raise ValueError(f"connect: the plant's output has dimension {q} "
                         f"({type(plant).__name__}) but the observer takes an input of "
                         f"dimension input_dim={m} ({type(observer).__name__}); they must "
                         f"agree (check the plant's C matrix / output_dim and the observer's "
                         f"output matrix)")
    return Interconnection({p: plant, o: observer}, inputs={o: LinearInput({p: None})})


def _output_dim(system):
    """A system's output dimension: declared, the state's, or measured at x = 0; else None."""
    q = getattr(system, "output_dim", None)
    if q is not None:
        return int(q)
    if not system._overrides("output"):
        return int(system.state_dim)
    try:
        y = system._compile().h(np.zeros(int(system.state_dim)), 0.0, 0, None)
        return int(np.size(y))
    except Exception:  # noqa: BLE001 - unknown: the run will tell
        return None


class _NodeInput:
    """Input wiring of one node of a network (a picklable callable)."""

    def __init__(self, inputs, node, preds, exo_names):
        self.inputs, self.node, self.preds, self.exo_names = inputs, node, preds, exo_names

    def __call__(self, t, y):
        return self.inputs(self.node, t, {i: y[i] for i in self.preds},
                           {e: y[e] for e in self.exo_names})


def network(G, systems, inputs, *, nodelist=None, exogenous=None):
    """An interconnection of one component per node of a directed graph.

    Parameters
    ----------
    G : networkx.DiGraph
        Edge i -> k: node k receives node i's output.
    systems : dict or callable
        ``{node: HybridSystem}``, or ``node -> HybridSystem``.
    inputs : callable or dict
        ``inputs(node, t, received, exo) -> u`` where ``received`` maps each
        in-neighbour of ``node`` to its output and ``exo`` maps each
        exogenous component's name to its output; or ``{node:
        LinearInput}`` for nodes with an input, each term's source an
        in-neighbour of the node or an exogenous component (the wiring the
        compiled path runs, ``backend="compiled"``).
    nodelist : list, optional
        Order of the nodes in the stacked state (default: ``list(G)``).
    exogenous : dict, optional
        ``{name: HybridSystem}`` simulated alongside the nodes (a plant),
        stacked first. Their names must differ from the nodes'.

    Returns
    -------
    Interconnection
        Its components are the exogenous systems and the nodes, named as
        in G (any hashable: ints, tuples...); ``net.stack({node: x0})`` and
        ``net.split(x)`` go between per-node states and the stacked one.

    Raises
    ------
    ValueError
        G has self-loops, ``nodelist`` does not list G's nodes, or an
        exogenous name clashes with a node.

    Examples
    --------
    >>> import networkx as nx, numpy as np, hybridsim as hs
    >>> class Agent(hs.HybridSystem):
    ...     state_dim, input_dim = 1, 1
    ...     def flow_map(self, x, t, j, u):
    ...         return u
    >>> G = nx.DiGraph([(0, 1), (1, 0)])
    >>> net = hs.network(G, lambda v: Agent(),
    ...                  lambda v, t, received, exo: sum(received.values()))
    >>> x0 = net.stack({0: 1.0, 1: -1.0})
    >>> net.split(x0)
    {0: array([1.]), 1: array([-1.])}
    """
    try:
        import networkx as nx
    except ImportError as e:  # pragma: no cover
        raise ImportError("network() needs networkx") from e
    if not isinstance(G, nx.DiGraph):
        raise TypeError(f"G must be a networkx.DiGraph, got {type(G).__name__}")
    if not callable(inputs) and not isinstance(inputs, Mapping):
        raise TypeError("inputs must be a callable (node, t, received, exo) -> u, or a "
                        "dict {node: LinearInput}")
    loops = list(nx.selfloop_edges(G))
    if loops:
        raise ValueError(f"G has self-loops at nodes {[u for u, _ in loops]}: an edge v -> v "
                         "would feed a node its own output; remove them (a node's own "
                         "state is available to its maps already)")
    nodes = list(G) if nodelist is None else list(nodelist)
    if set(nodes) != set(G) or len(nodes) != len(G):
        raise ValueError("nodelist must list every node of G exactly once")
    exogenous = {} if exogenous is None else dict(exogenous)
    clash = set(exogenous) & set(nodes)
    if clash:
        raise ValueError(f"exogenous names clash with node names: {sorted(map(str, clash))}")
    comps = dict(exogenous)
    factory = callable(systems) and not isinstance(systems, Mapping)
    if not factory and not isinstance(systems, Mapping):
        raise TypeError(f"systems must be a dict {{node: HybridSystem}} or a callable "
                        f"node -> HybridSystem, got {type(systems).__name__}")
    for v in nodes:
        if factory:
            s = systems(v)
            if not isinstance(s, HybridSystem):
                raise TypeError(f"systems({v!r}) must return a HybridSystem, got "
                                f"{type(s).__name__}")
        else:
            if v not in systems:
                raise ValueError(f"systems has no entry for node {v!r} of G: it must map "
                                 f"every node (nodes {nodes}, systems {list(systems)})")
            s = systems[v]
        comps[v] = s
    exo_names = list(exogenous)
    if isinstance(inputs, Mapping):
        wiring = {}
        for v, w in inputs.items():
            if v not in G:
                raise ValueError(f"inputs: {v!r} is not a node of G")
            if not isinstance(w, LinearInput):
                raise TypeError(f"inputs[{v!r}] must be a hybridsim.LinearInput, got "
                                f"{type(w).__name__}")
            allowed = set(G.predecessors(v)) | set(exo_names)
            bad = [s for s in w.terms if s not in allowed]
            if bad:
                raise ValueError(f"inputs[{v!r}] reads {bad}, which are neither in-neighbours "
                                 f"of {v!r} in G nor exogenous components")
            wiring[v] = w
    else:
        wiring = {v: _NodeInput(inputs, v, list(G.predecessors(v)), exo_names)
                  for v in nodes if int(comps[v].input_dim or 0) > 0}
    ic = Interconnection(comps, wiring)
    ic.graph = G
    ic.nodelist = nodes
    return ic
