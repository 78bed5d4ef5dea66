"""What :func:`hybridsim.explore` returns, and the bookkeeping of its
branches: :class:`SolutionTree` (the tree of solutions, its leaves as arcs
from x0), :class:`Node` (one branch), :class:`ExploreEnd` (why the
exploration ended), and the points seen so far, found again within
``merge_tol`` (``_Merger``). Re-exported by :mod:`hybridsim.explore`.
"""
from __future__ import annotations

import collections
import enum
import math
from dataclasses import dataclass, field

import numpy as np

from .arc import Choice, HybridArc


class ExploreEnd(enum.Enum):
    """Why an exploration ended. ``.message`` is a sentence for the user."""

    COMPLETE = "every branch was followed to its end"
    MAX_BRANCHES = ("the budget of branches (max_branches) was spent before every branch "
                    "was followed: raise it, lower t_max/j_max or coarsen dwell_grid")
    MAX_SECONDS = ("the time budget (max_seconds) was spent before every branch was "
                   "followed: raise it, lower t_max/j_max or coarsen dwell_grid")
    INTERRUPTED = ("interrupted (KeyboardInterrupt): the branches followed so far are "
                   "kept, the branch under way ends CANCELED with its arc so far, the "
                   "others are pending")

    @property
    def message(self) -> str:
        return self.value


@dataclass
class Node:
    """One branch: a run of the engine between two branch points.

    ``end`` is ``"branch"`` (a branch point with a choice: jump or flow
    on), ``"forced"`` (a forced jump: only the successors), ``"leaf"`` (the
    run ended: ``arc.termination``), ``"merged"`` (its end is another node's
    branch point: ``merged_into``) or ``"pending"`` (not run: the budget
    ended the exploration).
    """

    index: int
    parent: int | None
    choice: Choice | None           # the choice that started it (None: the root)
    start: tuple                    # (t, j, x) where it starts
    first: float | None = None      # its dwell at the start: inf flows on, None none
    arc: HybridArc | None = None    # its own samples (from its start)
    end: str = "pending"
    children: list = field(default_factory=list)
    merged_into: int | None = None
    history: object = None          # its run's past (systems that read their history)


class SolutionTree:
    """The tree of solutions returned by :func:`explore`.

    Iterating over it (or :attr:`leaves`) gives every leaf as a
    :class:`hybridsim.HybridArc` from x0 to its end, with its termination
    cause and ``arc.choices`` (the :class:`Choice` list taken on the way);
    ``len(tree)`` is the number of leaves. :attr:`nodes` holds the
    structure (parent, start, choice, end of each branch).

    Attributes
    ----------
    nodes : list of Node
    end : ExploreEnd
        Why the exploration ended; :attr:`complete` is ``end is COMPLETE``.
    merges : int
        Branches not followed because another reached the same point (a
        dwell that outlasts C ∩ D, or a "flow on" where the flow leaves C at
        once, counts too: it is its sibling's branch).
    seconds : float
        Wall time of the exploration.
    """

    def __init__(self, system, nodes, end, merges, seconds):
        self.system = system
        self.nodes = nodes
        self.end = end
        self.merges = merges
        self.seconds = seconds
        self._leaves = None
        self._parts = {}        # node index -> (its arc, its samples in a path, stats)

    @property
    def complete(self) -> bool:
        return self.end is ExploreEnd.COMPLETE

    @property
    def message(self) -> str:
        return self.end.message

    @property
    def pending(self) -> int:
        """Branches left unexplored by the budget."""
        return sum(n.end == "pending" for n in self.nodes)

    def path(self, index):
        """The nodes from the root to node ``index``."""
        out = []
        k = index
        while k is not None:
            out.append(self.nodes[k])
            k = self.nodes[k].parent
        return out[::-1]

    @property
    def leaf_nodes(self):
        """The leaves' nodes, depth first in the order of the choices."""
        out, stack = [], [0]
        while stack:
            n = self.nodes[stack.pop()]
            if n.end == "leaf":
                out.append(n)
            stack.extend(reversed(n.children))
        return out

    @property
    def branch_points(self):
        """``(t, j, x)`` of every node's end where the tree branches (more than one child)."""
        return [(float(n.arc.t[-1]), int(n.arc.j[-1]), n.arc.x[-1]) for n in self.nodes
                if n.end in ("branch", "forced") and len(n.children) > 1]

    @property
    def leaves(self):
        """Every leaf as a HybridArc (built once, on first use)."""
        if self._leaves is None:
            self._leaves = [self._leaf(n) for n in self.leaf_nodes]
        return self._leaves

    @property
    def merged(self):
        """Each merged branch's arc from x0 to where it met another branch.

        Its future is the other branch's (on a leaf), so the leaves and
        these prefixes hold every sample of every solution explored (to
        ``merge_tol``): what :mod:`hybridsim.testing` checks, given a tree.
        ``arc.termination`` is None, ``arc.merged_into`` the other node.
        """
        return [self._leaf(n) for n in self.nodes
                if n.end == "merged" and n.merged_into != n.parent]

    def solutions(self):
        """Every solution explored, each a HybridArc from x0 to its end.

        A leaf is one; a merged branch is continued by every solution of the
        branch it met (its future), so there are at least as many solutions
        as leaves: 2^k choices that meet again make few leaves and many
        solutions. Branches left pending by a budget end where they stop.

        Returns
        -------
        list of HybridArc
            ``arc.choices`` the choices of each, ``arc.node`` the node it ends on.

        Examples
        --------
        >>> import hybridsim as hs
        >>> from hybridsim.library import BouncingBall
        >>> tree = hs.explore(BouncingBall(), [1.0, 0.0], 1.0, 1)
        >>> len(tree.solutions()) >= len(tree)
        True
        """
        nodes = self.nodes

        def paths(k):
            n = nodes[k]
            if n.end == "merged":
                if n.merged_into == n.parent:   # its sibling's branch, not a solution
                    return []
                o = nodes[n.merged_into]
                if n.arc is None:               # met at its start: o's future, after
                    return [[("from", o.parent), *p] for p in paths(o.index)]  # o's parent's end
                # met at o's end: o's children, from o's end sample (within merge_tol)
                return [[(k, o.index), *p] for c in o.children for p in paths(c)]
            if n.end in ("branch", "forced") and n.children:
                return [[(k, p[0][1]), *p[1:]] if isinstance(p[0], tuple) and p[0][0] == "from"
                        else [k, *p] for c in n.children for p in paths(c)]
            return [[k]]
        out = []
        for p in paths(0):
            tails = dict(i for i in p if isinstance(i, tuple))
            parts = [nodes[i[0] if isinstance(i, tuple) else i] for i in p]
            arc = self._arc_of(parts, parts[-1], tails)
            arc.node = parts[-1].index
            out.append(arc)
        return out

    def _leaf(self, node):
        return self._arc_of(self.path(node.index), node)

    def _arc_of(self, parts, node, tails=None):
        """The arc through the nodes ``parts`` (from the root), ending as ``node``;
        ``tails[i] = o``: node i's last sample at node o's end time (they met there,
        within ``merge_tol``, and the arc goes on from o's)."""
        tails = tails or {}
        ts, js, xs, ds = [], [], [], []
        stats = collections.Counter()
        for p in parts:
            a = p.arc
            if a is None:           # merged at its start (after a jump): that sample
                t, j, x = p.start
                ts.append(np.array([t]))
                js.append(np.array([j], dtype=np.int64))
                xs.append(np.reshape(x, (1, -1)))
                ds.append(np.full((1, len(x)), np.nan))
                continue
            hit = self._parts.get(p.index)
            if hit is None or hit[0] is not a:
                # a branch that starts where its parent ends (flow on, dwell, no
                # jump left) repeats the parent's last sample
                k = 1 if (p.choice is not None and (p.choice.kind != "jump"
                                                    or p.choice.value is None)) else 0
                d_ = a.xdot[k:] if a.xdot is not None else np.full_like(a.x[k:], np.nan)
                hit = (a, (a.t[k:], a.j[k:], a.x[k:], d_),
                       [(key, int(v)) for key, v in (a.stats or {}).items()
                        if isinstance(v, (int, np.integer))])
                self._parts[p.index] = hit     # read by every path through the node
            t_, j_, x_, d_ = hit[1]
            if p.index in tails and len(t_):     # its end at the other's time (a jump keeps t)
                t_ = np.concatenate([t_[:-1], self.nodes[tails[p.index]].arc.t[-1:]])
            ts.append(t_)
            js.append(j_)
            xs.append(x_)
            ds.append(d_)
            for key, v in hit[2]:
                stats[key] += v
        last = node.arc
        if node.end == "merged":
            cause, msg, exc = None, f"merged into branch {node.merged_into}", None
        else:
            cause, msg, exc = last.termination, last.message, last.exception
        # the runs' dense output, where every part kept it (systems that read their past)
        segs = []
        for p in parts:
            if p.arc is not None and p.arc._segments:
                segs.extend(p.arc._segments)
            elif p.arc is not None and len(p.arc.t) > 1:
                segs = None
                break
        arc = HybridArc._trusted(np.concatenate(ts), np.concatenate(js), np.concatenate(xs),
                                 cause, msg, exc, components=self.system.components,
                                 segments=segs or None, system=self.system,
                                 xdot=np.concatenate(ds), stats=dict(stats))
        arc.choices = [p.choice for p in parts if p.choice is not None]
        arc.node = node.index
        arc.merged_into = node.merged_into
        return arc

    def __iter__(self):
        return iter(self.leaves)

    def __len__(self):
        return len(self.leaf_nodes)

    def __repr__(self):
        return (f"<SolutionTree: {len(self)} leaves, {len(self.nodes)} branches, "
                f"{self.merges} merged, {self.end.name}>")


class _Merger:
    """Points seen so far, found again within ``tol`` (absolute, on t and every x_i)."""

    def __init__(self, tol):
        self.tol = tol
        self.seen = {}

    def _key(self, kind, t, j, x):
        w = self.tol
        if w == 0:
            return (kind, j, t, x.tobytes())
        return (kind, j, math.floor(t / w), math.floor(x[0] / w))

    def find(self, kind, t, j, x):
        if self.tol is None:
            return None
        w = self.tol
        if w == 0:
            return self.seen.get(self._key(kind, t, j, x))
        kt, kx = math.floor(t / w), math.floor(x[0] / w)
        for dt in (-1, 0, 1):
            for dx in (-1, 0, 1):
                for (tt, xx, node) in self.seen.get((kind, j, kt + dt, kx + dx), ()):
                    if abs(tt - t) <= w and float(np.max(np.abs(xx - x))) <= w:
                        return node
        return None

    def add(self, kind, t, j, x, node):
        if self.tol is None:
            return
        if self.tol == 0:
            self.seen[self._key(kind, t, j, x)] = node
        else:
            self.seen.setdefault(self._key(kind, t, j, x), []).append((t, x, node))
