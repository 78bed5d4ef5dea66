r"""explore(): every solution of a hybrid inclusion, as a tree of arcs.

A hybrid system is an inclusion: where C and D overlap a solution may jump
or flow on, and a set-valued jump map (``jump_map_values``) offers several
successors. :func:`hybridsim.simulate` follows one solution (its
``priority``); :func:`explore` follows them all, as a tree:

* a **branch point** at each entry into C ∩ D where flowing is possible:
  jump now (one branch per successor), or flow on, and optionally jump
  after each dwell time of a grid (``dwell_grid``) while still in C ∩ D;
* a **forced jump** (the flow leaves C inside D, x in D \ C, or a dwell
  has elapsed): one branch per successor of the jump map.

"Flow on" flows while in C ∩ D and past it: a flow that leaves D does not
jump there (the next entry into D is a new branch point); one that leaves C
inside D jumps where it leaves (the last point where flowing is possible).
Each branch is an ordinary run of the engine (:func:`hybridsim.simulate`
restarted at the branch point with ``t0``, ``j0`` and the random priority's
dwell law, stopped at the next branch point by ``j_max=0``), so the events,
rules and termination causes are those of ``simulate``.

The branches of one level of the tree (those queued together) run as
batches on the fastest path the system has (``backend``): a model that
compiles (:func:`hybridsim.compiled.lower`, a plain model from its own maps)
runs them with :func:`hybridsim.compiled.simulate_many_compiled`, one batch
per branch-point time (t, j), each row restarted from its branch point. A
batch row is the same run as the branch's own: a branch that starts with a
jump (or the root) is the ``"jumps"`` priority's run to its first jump, its
end a branch point where that point is in C as well (flowing was possible);
a "flow on" branch whose flow leaves C at once (the ``"flows"`` priority's
run ends at its start) is its sibling's. Every other branch, and every row
whose batch run ended other than at t_max or at a jump (a failure, a map
error, Ctrl-C), runs as before, with :func:`hybridsim.simulate` and the
dwell law, so failures and Ctrl-C end the exploration as they always did.

Branches reaching the same hybrid time and state are merged: two branch
points (or two starts after a jump) merge when their j are equal and
``|t - t'| <= merge_tol`` and ``max_i |x_i - x'_i| <= merge_tol`` (absolute,
in the units of t and x): their futures are the same solutions, explored
once. Choose ``merge_tol`` above the solver's error on the states (about
``rtol`` times their size) and below the differences that matter.

A system that reads its past (``needs_history`` or ``delays``: a delay
equation, an observer with a window) is explored too: each branch's run
takes its parent's recorded past as its ``prehistory`` (a chain back to the
root's), so a map reading ``self.history(t - tau)`` sees the past of its
own solution, across branch points. Such branches are never merged: two
solutions at the same (t, j, x) with different pasts have different futures.
"""
from __future__ import annotations

import collections
import math
import time
import warnings
import weakref
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ._explore_tree import ExploreEnd, Node, SolutionTree, _Merger
from .arc import Choice, HybridArc
from .options import check_count, check_map_value, check_real, check_x0
from .rules import MapError, SimulationError, SimulationWarning, Termination, event_tolerance, warns
from .run import simulate
from .system import HybridSystem, successors

__all__ = ["explore", "SolutionTree", "Node", "Choice", "ExploreEnd"]


def _describe(choices):
    return "; ".join(str(c) for c in choices) or "no choice (the root's run)"


#: options of simulate that explore decides itself, or cannot take
_NOT_OPTIONS = {"priority": "explore follows every choice in C ∩ D",
                "dwell": "explore follows every dwell of dwell_grid",
                "seed": "explore draws nothing",
                "dense": "explore's leaves are joined from the branches' samples",
                "progress": "explore runs the engine once per branch",
                "j0": "give j0 to explore itself", "t0": "give t0 to explore itself"}


#: merge_tol's default: 1e-9, or None (never merge) for a system that reads its past
_AUTO = "auto"

_BACKENDS = ("auto", "compiled", "python")

#: backend="auto" runs a level as compiled batches from this many branches on
#: (a model's maps compile once per machine, in seconds: a batch of hundreds pays),
#: and every level of a system whose class has run batched in this process (its
#: compile paid: a batch of two branches costs less than their two runs)
BATCH_LEVEL = 512

#: the classes of the systems whose branches have run as compiled batches here
_BATCHED = weakref.WeakSet()

#: the options of simulate the compiled path runs at these values only
_COMPILED_ONLY_AT = {"inputs": (None,), "prehistory": (None,), "dense": (False,),
                     "t_eval": (None,)}


def explore(system: HybridSystem, x0: ArrayLike, t_max: float, j_max: float = math.inf, *,
            t0: float = 0.0, j0: int = 0, dwell_grid: Iterable[float] = (),
            merge_tol: float | str | None = _AUTO, max_branches: int = 100_000,
            max_seconds: float = 60.0, throw: bool = True, warn: bool = True,
            backend: str = "auto", **options: Any) -> SolutionTree:
    r"""Every solution of a hybrid inclusion from x0, as a tree of arcs.

    At each entry into C ∩ D where flowing is possible the tree branches:
    jump now, flow on, or (``dwell_grid``) jump after each of the given
    dwell times while still in C ∩ D; at each jump, one branch per
    successor of a set-valued jump map (``jump_map_values``). See the module
    docstring for the rules, :class:`SolutionTree` for the result.

    Parameters
    ----------
    system : HybridSystem
        The data (C, f, D, g) or (C, f, D, G) with G set-valued. It may read
        its history (each branch continues its parent's past; module
        docstring).
    x0 : array_like, shape (n,)
        Initial state.
    t_max, j_max : float, int or inf
        Every solution stops at t_max or after j_max jumps, as in
        :func:`hybridsim.simulate`.
    t0, j0 : float, int
        Initial hybrid time.
    dwell_grid : sequence of float, optional
        Dwell times (> 0) in C ∩ D after which a branch jumps, beside "jump
        now" and "flow on". A dwell that outlasts C ∩ D is the "flow on"
        branch and is not repeated.
    merge_tol : float, None or "auto"
        Absolute tolerance on t and on each state component for merging
        branches that reach the same (t, j, x); 0 merges exact equality
        only, None never merges. ``"auto"`` (default): 1e-9, or None for a
        system that reads its history (a number is then refused: equal
        states with different pasts are different solutions).
    max_branches : int
        At most this many branches (runs of the engine); then the
        exploration ends with ``tree.end = ExploreEnd.MAX_BRANCHES``.
    max_seconds : float
        Wall-time budget, checked before each branch (before each level
        where the levels run batched); then ``ExploreEnd.MAX_SECONDS``. Ctrl-C
        (KeyboardInterrupt) ends the exploration too, with what was explored
        (``ExploreEnd.INTERRUPTED``: the branch under way a leaf ending
        ``CANCELED``, the others pending).
    throw : bool
        Raise :class:`hybridsim.MapError` when a branch ends on a user map's
        error (its message names the branch's choices); False: that leaf
        ends with cause ``MAP_ERROR``.
    warn : bool
        One :class:`hybridsim.SimulationWarning` when leaves end on a
        numerical failure, or when the budget ends the exploration.
    backend : {"auto", "compiled", "python"}
        Where the branches run. ``"python"``: each its own run of
        :func:`hybridsim.simulate`. ``"compiled"``: each level's branches as
        compiled batches (module docstring); a system that cannot run
        compiled (its reason), or options the compiled path does not take
        (``inputs``, ``prehistory``, ``dense``, ``t_eval``; a system that
        reads its history), are refused by name. ``"auto"`` (default):
        from the first level of at least :data:`BATCH_LEVEL` (512)
        branches (from the first level, once a system of its class has run
        batched in this process), compiled batches where numba is installed and the system
        and options run compiled (its maps compile then, once per machine:
        seconds), else ``"python"``. The tree is the same on every backend;
        the samples agree to the integrator's round-off.
    **options
        Passed to :func:`hybridsim.simulate` for every branch (``method``,
        ``rtol``, ``atol``, ``max_step``, ``inputs``, ``max_norm``...);
        ``prehistory`` is the root's (the branches read their parents').

    Returns
    -------
    SolutionTree
        Iterate over it for the leaves (HybridArcs, ``arc.choices`` the
        choices taken); ``tree.nodes`` for the structure.

    Raises
    ------
    TypeError, ValueError
        Bad arguments, each naming the argument.
    MapError
        A user map failed on a branch (``throw=True``).

    Examples
    --------
    A timer that may reset anywhere in [1, 2]: jump at 1, after a dwell of
    0.5, or at 2, where it must; two resets give 3 x 3 solutions, which end
    at 5 distinct times (merged, the default, one branch per end):

    >>> import numpy as np, hybridsim as hs
    >>> timer = hs.HybridSystem.from_functions(
    ...     flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
    ...     flow_set=lambda x: x[0] <= 2.0, jump_set=lambda x: x[0] >= 1.0, state_dim=1)
    >>> tree = hs.explore(timer, [0.0], t_max=10.0, j_max=2, dwell_grid=[0.5],
    ...                   merge_tol=None)
    >>> len(tree), tree.complete
    (9, True)
    >>> print(tree.leaves[2].choices[1])
    dwell 0.5 in C ∩ D from (t=2, j=1)
    >>> tree = hs.explore(timer, [0.0], t_max=10.0, j_max=2, dwell_grid=[0.5])
    >>> sorted(round(float(a.jump_times[-1]), 6) for a in tree)
    [2.0, 2.5, 3.0, 3.5, 4.0]
    """
    if not isinstance(system, HybridSystem):
        raise TypeError(f"system must be a hybridsim.HybridSystem, got {type(system).__name__}")
    for name in options:
        if name in _NOT_OPTIONS:
            raise TypeError(f"explore() does not take {name}=: {_NOT_OPTIONS[name]}")
    past = bool(system.needs_history or tuple(system.delays or ()))
    if isinstance(merge_tol, str) and merge_tol == _AUTO:
        merge_tol = None if past else 1e-9
    elif past and merge_tol is not None:
        raise ValueError(f"merge_tol must be None (or 'auto') for {type(system).__name__}, "
                         f"which reads its history: two branches at the same (t, j, x) "
                         f"with different pasts are different solutions; got {merge_tol!r}")
    n = int(system.state_dim) if isinstance(system.state_dim, (int, np.integer)) else None
    if n is None or n < 1:
        raise ValueError(f"{type(system).__name__}.state_dim must be a positive int, "
                         f"got {system.state_dim!r}")
    x0 = check_x0(x0, n)
    t0 = check_real("t0", t0)
    t_max = check_real("t_max", t_max, allow_inf=True)
    j_max = check_count("j_max", j_max, allow_inf=True)
    j0 = check_count("j0", j0)
    try:
        grid = sorted({check_real("dwell_grid", float(d), positive=True)
                       for d in np.atleast_1d(np.asarray(dwell_grid, dtype=float))})
    except (TypeError, ValueError) as e:
        raise type(e)(f"dwell_grid must be a sequence of positive finite floats: {e}") from e
    if merge_tol is not None:
        merge_tol = check_real("merge_tol", merge_tol, nonneg=True)
    max_branches = check_count("max_branches", max_branches, minimum=1)
    max_seconds = check_real("max_seconds", max_seconds, allow_inf=True, positive=True)
    for name, v in (("throw", throw), ("warn", warn)):
        if not isinstance(v, (bool, np.bool_)):
            raise TypeError(f"{name} must be True or False, got {v!r}")
    if not isinstance(backend, str) or backend not in _BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(map(repr, _BACKENDS))}, "
                         f"got {backend!r}")
    ex = _Explorer(system, n, t_max, j_max, j0, grid, merge_tol, options)
    ex.batches = _Batches(system, options, past, backend)
    tree = ex.run(x0, t0, max_branches, max_seconds)
    _report(tree, throw, warn)
    return tree


def _report(tree, throw, warn):
    bad = [n for n in tree.nodes if n.end == "leaf" and n.arc.termination is not None
           and n.arc.termination.failure]
    if throw:
        for n in bad:
            if n.arc.termination is Termination.MAP_ERROR:
                choices = [p.choice for p in tree.path(n.index) if p.choice is not None]
                err = MapError(f"{n.arc.message} (on the branch: {_describe(choices)})",
                               getattr(n.arc.exception, "map_name", None))
                err.tree = tree
                raise err from n.arc.exception
    if warn:
        failed = [n for n in bad if warns(n.arc.termination, True)]
        if failed:
            warnings.warn(f"{len(failed)} of {len(tree)} leaves ended on a numerical "
                          f"failure, the first {failed[0].arc.termination.name}: "
                          f"{failed[0].arc.message}", SimulationWarning, stacklevel=3)
        if not tree.complete:
            warnings.warn(f"explore: {tree.end.name}: {tree.message} ({tree.pending} "
                          f"branches unexplored)", SimulationWarning, stacklevel=3)


class _Explorer:
    def __init__(self, system, n, t_max, j_max, j0, grid, tol, options):
        self.system, self.n = system, n
        self.t_max, self.j_max, self.j0 = t_max, j_max, j0
        self.grid, self.options = grid, options
        self.maps = system._compile()
        self.inputs = options.get("inputs")
        self.past = bool(system.needs_history or tuple(system.delays or ()))
        self.prehistory = options.pop("prehistory", None)
        self.starts = _Merger(tol)
        self.ends = _Merger(tol)
        self.merges = 0
        self.nodes = []

    def _new(self, parent, choice, start, first=None):
        node = Node(len(self.nodes), parent, choice, start, first)
        self.nodes.append(node)
        if parent is not None:
            self.nodes[parent].children.append(node.index)
        return node

    def run(self, x0, t0, max_branches, max_seconds):
        clock = time.perf_counter()
        queue = collections.deque([self._new(None, None, (t0, self.j0, x0)).index])
        end = ExploreEnd.COMPLETE
        runs = 0
        while queue:
            if runs >= max_branches:
                end = ExploreEnd.MAX_BRANCHES
                break
            if time.perf_counter() - clock > max_seconds:
                end = ExploreEnd.MAX_SECONDS
                break
            if self.batches.wanted(len(queue)):
                level = [self.nodes[queue.popleft()]
                         for _ in range(min(len(queue), max_branches - runs))]
                runs += len(level)
                children, stopped = self._level(level)
                queue.extend(children)
                if stopped:
                    end = ExploreEnd.INTERRUPTED
                    break
                continue
            node = self.nodes[queue.popleft()]
            runs += 1
            count = len(self.nodes)
            try:
                queue.extend(self._expand(node))
            except (KeyboardInterrupt, SimulationError) as e:
                # Ctrl-C between the engine's runs, or as one started (the engine's
                # SimulationError from it): this branch is the one under way
                if isinstance(e, SimulationError) and not isinstance(e.__cause__,
                                                                     KeyboardInterrupt):
                    raise
                self._cancel(node, count)
                end = ExploreEnd.INTERRUPTED
                break
            if node.arc is not None and node.arc.termination is Termination.CANCELED:
                end = ExploreEnd.INTERRUPTED    # Ctrl-C inside the branch's run
                break
        return SolutionTree(self.system, self.nodes, end, self.merges,
                            time.perf_counter() - clock)

    def _cancel(self, node, count):
        """A node whose expansion Ctrl-C cut short: a CANCELED leaf (its run's
        arc, or its start), its new children dropped."""
        for k in range(count, len(self.nodes)):
            if self.nodes[k].index in node.children:
                node.children.remove(self.nodes[k].index)
        del self.nodes[count:]
        if node.arc is None:
            t, j, x = node.start
            node.arc = self._leaf_arc(t, j, np.asarray(x, dtype=float), Termination.CANCELED,
                                      Termination.CANCELED.message)
        else:
            node.arc.termination = Termination.CANCELED
            node.arc.message = Termination.CANCELED.message
        node.end = "leaf"

    # ------------------------------------------------------------------ a level
    def _level(self, level):
        """Run the nodes of a level in order, those a batch can run batched
        (:class:`_Batches`): ``(children to run next, interrupted)``. The tree,
        merges and Ctrl-C are those of running the nodes one by one."""
        decided = {}                # node index -> its children, decided before running
        todo = []
        ran = {}
        try:
            for node in level:
                done = self._start(node)
                if done is not None:
                    decided[node.index] = done
                elif node.first is None:
                    todo.append((node, "jumps"))
                elif node.first == math.inf:
                    todo.append((node, "flows"))
            ran = self.batches.run(todo, self.t_max, self.maps)
        except KeyboardInterrupt:
            ran = {node.index: None for node, _ in todo}
        out = []
        for i, node in enumerate(level):
            if node.index in decided:
                out.extend(decided[node.index])
                continue
            count = len(self.nodes)
            try:
                got = ran.get(node.index, False)
                if got is None:             # Ctrl-C before its batch ran
                    raise KeyboardInterrupt
                if got is False:            # not batched, or its batch row is not its run
                    t, j, x = node.start
                    got = self._simulate(x, t, j, node.first, self._past(node))
                out.extend(self._finish(node, *got))
            except (KeyboardInterrupt, SimulationError) as e:
                if isinstance(e, SimulationError) and not isinstance(e.__cause__,
                                                                     KeyboardInterrupt):
                    raise
                self._cancel(node, count)
                self._pend(level[i + 1:], decided)
                return out, True
            if node.arc is not None and node.arc.termination is Termination.CANCELED:
                self._pend(level[i + 1:], decided)
                return out, True
        return out, False

    def _pend(self, nodes, decided):
        """Nodes after the one Ctrl-C stopped: pending, as if never reached."""
        for node in nodes:
            if node.index in decided:
                if node.end == "merged":
                    self.merges -= 1
                node.end, node.merged_into, node.arc = "pending", None, None

    # ------------------------------------------------------------------ one branch
    def _simulate(self, x, t, j, first, pre):
        """The engine from (t, j, x) to the next branch point; ``(arc, chose)``,
        ``chose`` True where it stopped at an entry into C ∩ D with a choice.
        ``pre`` is the past before t (the parent's history), or None."""
        calls = [0, False]

        def law(rng):
            calls[0] += 1
            if calls[0] == 1 and first is not None:
                return first
            calls[1] = True
            return 0.0
        extra = {"prehistory": pre} if pre is not None else {}
        arc = simulate(self.system, x, self.t_max, 0, t0=t, j0=j, priority="random",
                       dwell=law, seed=0, throw=False, warn=False, **extra, **self.options)
        return arc, calls[1]

    def _past(self, node):
        """The past a node's run continues: its parent's history (or the root's)."""
        if node.parent is None:
            return self.prehistory
        return self.nodes[node.parent].history

    def _leaf_arc(self, t, j, x, cause, message=None, exc=None):
        xd = np.full((1, self.n), np.nan)
        return HybridArc._trusted(np.array([t]), np.array([j], dtype=np.int64),
                                  x.reshape(1, self.n).copy(), cause, message, exc,
                                  components=self.system.components, system=self.system,
                                  xdot=xd, stats={})

    def _expand(self, node):
        """Run a node; its children's indices to run next."""
        done = self._start(node)
        if done is not None:
            return done
        t, j, x = node.start
        return self._finish(node, *self._simulate(x, t, j, node.first, self._past(node)))

    def _start(self, node):
        """What a node's start decides without running it (merged with another
        start, or no jump left): its children ([]), or None (it must run)."""
        t, j, x = node.start
        if node.choice is not None and node.choice.kind == "jump":
            other = self.starts.find("start", t, j, x)
            if other is not None:
                node.end, node.merged_into = "merged", other
                self.merges += 1
                return []
            self.starts.add("start", t, j, x, node.index)
            if j - self.j0 >= self.j_max:       # the last jump: simulate stops here too
                node.arc = self._leaf_arc(t, j, x, Termination.J_MAX)
                node.end = "leaf"
                return []
        return None

    def _finish(self, node, arc, chose):
        """A node's run ``arc`` (``chose``: it ended at an entry into C ∩ D with a
        choice): its end, and its children's indices to run next."""
        t, j, x = node.start
        node.arc = arc
        if self.past:
            node.history = self.system.history       # the past its children continue
        cause = arc.termination
        if node.choice is not None and node.choice.kind == "dwell":
            # a dwell that did not elapse inside C ∩ D is the "flow on" branch
            if not (cause is Termination.J_MAX and not chose
                    and abs(arc.t[-1] - (t + node.choice.value)) <= 1e-9 * max(1.0, abs(t))):
                node.end = "merged"
                node.merged_into = node.parent
                self.merges += 1
                self.nodes[node.parent].children.remove(node.index)
                return []
        if node.choice is not None and node.choice.kind == "flow" and cause is \
                Termination.J_MAX and not chose and arc.j[-1] == j and \
                arc.t[-1] - t <= 64.0 * event_tolerance(t, t):
            # flowing was impossible (the flow leaves C at once): "jump now" again
            node.end = "merged"
            node.merged_into = node.parent
            self.merges += 1
            self.nodes[node.parent].children.remove(node.index)
            return []
        if cause is not Termination.J_MAX:
            if cause is Termination.NOT_IN_SETS and node.parent is not None:
                arc.termination = Termination.LEFT_SETS
                arc.message = (f"{Termination.LEFT_SETS.message}: the state after the "
                               f"jump, x={x}, is in neither C nor D (t={t:.10g}, j={j})")
            node.end = "leaf"
            return []
        tp, jp, xp = float(arc.t[-1]), int(arc.j[-1]), arc.x[-1].copy()
        kind = "branch" if chose else "forced"
        other = self.ends.find(kind, tp, jp, xp)
        if other is not None:
            node.end, node.merged_into = "merged", other
            self.merges += 1
            return []
        self.ends.add(kind, tp, jp, xp, node.index)
        node.end = kind
        out = []
        if jp - self.j0 >= self.j_max:
            # no jump left (j_max = 0): "jump" ends here, as simulate's run does
            stop = self._new(node.index, Choice(tp, jp, xp, "jump", None), (tp, jp, xp))
            stop.arc, stop.end = self._leaf_arc(tp, jp, xp, Termination.J_MAX), "leaf"
            return self._flow_children(node, tp, jp, xp, chose)
        u = self.inputs(tp) if self.inputs is not None else None
        try:
            if self.maps.G is not None:
                succ = successors(self.maps.G(xp, tp, jp, u), self.n, tp, jp)
            else:
                succ = [check_map_value("jump_map", self.maps.g(xp, tp, jp, u), self.n,
                                        tp, jp).copy()]
        except MapError as e:
            # the branch ends where its jump map failed (as simulate's run would)
            arc.termination, arc.message, arc.exception = Termination.MAP_ERROR, str(e), e
            node.end = "leaf"
            return []
        for i, xs in enumerate(succ):
            c = Choice(tp, jp, xp, "jump", i)
            out.append(self._new(node.index, c, (tp, jp + 1, np.array(xs, dtype=float))).index)
        return out + self._flow_children(node, tp, jp, xp, chose)

    def _flow_children(self, node, tp, jp, xp, chose):
        """At a branch point: flow on, and jump after each dwell of the grid."""
        out = []
        if chose:
            out.append(self._new(node.index, Choice(tp, jp, xp, "flow", None),
                                 (tp, jp, xp), math.inf).index)
            for d in self.grid:
                out.append(self._new(node.index, Choice(tp, jp, xp, "dwell", d),
                                     (tp, jp, xp), d).index)
        return out


class _Batches:
    """A level's branches as batches (module docstring), or none of them.

    ``backend="compiled"`` lowers the system at once (a refusal names why);
    ``"auto"`` chooses from the first level of :data:`BATCH_LEVEL` branches:
    compiled batches where the system and options run compiled, else
    (silently, but for a plain model's :class:`hybridsim.compiled.FallbackWarning`
    naming the map that does not compile) each branch alone, as before. Not
    the numpy batch of a ``vectorized`` system: its event locations differ
    from :func:`hybridsim.simulate`'s by round-off, and at a boundary of
    C ∩ D that changes which points branch (the doubling tree written on the
    last axis: 6 of its first 31 branch points)."""

    def __init__(self, system, options, past, backend):
        self.system, self.options, self.past = system, options, past
        self.proxy = self.ok = None
        self.batch = None               # (X, t_max, t, j, priority) -> arcs, once chosen
        self.off = backend == "python"
        if backend == "compiled":
            why = self._refusal()
            if why is not None:
                raise ValueError(f"explore(backend='compiled'): the branches of "
                                 f"{type(system).__name__} cannot run compiled: {why}")
            self.batch = self._compiled(self._lower(auto=False))

    def _common(self):
        """Why no batch runs the branches, or None."""
        if self.past:
            return "it reads its history (each branch continues its parent's past)"
        for k, ok in _COMPILED_ONLY_AT.items():
            if self.options.get(k, ok[0]) not in ok:
                return f"{k}= runs on the Python path only"
        if any(getattr(self.system, k, None) is not None
               for k in ("diffusion", "jump_rate", "jump_law")):
            return "its noise (diffusion, jump_rate or jump_law) runs on the Python path only"
        self.proxy = _proxy(self.system)
        return None

    def _refusal(self):
        """Why the branches cannot run compiled, or None."""
        import importlib.util

        from .compiled import lowerable
        from .options import method_on
        if importlib.util.find_spec("numba") is None:
            return "numba is not installed (pip install 'hybridsim[fast]')"
        why = self._common()
        if why is not None:
            return why
        try:
            method_on("compiled", self.options.get("method"), self.system)
        except (TypeError, ValueError) as e:
            return str(e)
        self.ok = lowerable(self.proxy)
        return None if self.ok else self.ok.reason

    def _lower(self, auto):
        from .compiled import lower
        from .compiled._from_source import auto_choice
        if auto and auto_choice(self.proxy, self.ok) != "compiled":
            return None     # a plain model whose maps do not compile: a FallbackWarning
        return lower(self.proxy)

    def _options(self):
        return {k: v for k, v in self.options.items() if k not in _COMPILED_ONLY_AT}

    def _compiled(self, cs):
        from .compiled import simulate_many_compiled
        opts = self._options()
        _BATCHED.add(type(self.system))

        def batch(X, t_max, t, j, priority):
            return simulate_many_compiled(cs, X, t_max, 0, t0=t, j0=j, priority=priority,
                                          throw=False, warn=False, **opts)
        return batch

    def _choose(self):
        """backend="auto"'s batch: compiled, or None."""
        try:
            why = self._refusal()
            # no refusal, or the model's own (auto_choice says why, once)
            if why is None or self.ok is not None:
                cs = self._lower(auto=True)
                if cs is not None:
                    return self._compiled(cs)
        except (TypeError, ValueError, ImportError):     # CompileError: a TypeError
            pass
        return None

    def wanted(self, size):
        """Whether a level of ``size`` branches runs batched."""
        if self.off:
            return False
        if self.batch is None:
            if size < BATCH_LEVEL and type(self.system) not in _BATCHED:
                return False
            self.batch = self._choose()
            if self.batch is None:
                self.off = True
                return False
        return True

    def run(self, todo, t_max, maps):
        """Run ``todo`` = [(node, "jumps" or "flows")] in batches of one (t, j):
        {node index: (arc, chose)} for the rows whose batch run is the node's
        own run, False for the others (run them alone, as before), None for
        rows Ctrl-C kept from running."""
        from .compiled._lower import rebind
        groups = {}
        for node, kind in todo:
            t, j, _ = node.start
            groups.setdefault((kind, t, j), []).append(node)
        out = {}
        stopped = False
        for (kind, t, j), nodes in groups.items():
            if stopped:
                out.update((node.index, None) for node in nodes)
                continue
            X = np.array([node.start[2] for node in nodes], dtype=float)
            try:
                arcs = self.batch(X, t_max, t, j, kind)
            except SimulationError as e:
                if isinstance(e.__cause__, KeyboardInterrupt):
                    raise KeyboardInterrupt from e
                # a map failing in the batch: each branch alone says where, as before
                out.update((node.index, False) for node in nodes)
                continue
            for node, arc in zip(nodes, arcs, strict=True):
                arc = rebind(arc, self.system)
                if arc.termination is Termination.CANCELED:
                    stopped = True
                    out[node.index] = (arc, False) if len(arc.t) > 1 or arc.stats else None
                else:
                    out[node.index] = _accept(arc, kind, t, j, maps)
        return out


def _accept(arc, kind, t, j, maps):
    """``(arc, chose)`` where a batch row's run is the branch's own run (see
    the module docstring), else False."""
    cause = arc.termination
    if kind == "flows":
        # the flow leaves C at once: the "flow on" branch is its sibling's
        if cause is Termination.J_MAX and arc.j[-1] == j and \
                arc.t[-1] - t <= 64.0 * event_tolerance(t, t):
            return arc, False
        return False
    if cause is Termination.T_MAX:
        return arc, False
    if cause is not Termination.J_MAX or len(arc.t) < 2:
        # a failure or other end, or a stop at its start (where the run checks
        # the jump map): the Python path's run, as before
        return False
    try:
        chose = (not maps.has_C) or bool(maps.C(arc.x[-1], float(arc.t[-1]),
                                                int(arc.j[-1]), None))
    except MapError:
        return False
    return arc, chose


def _proxy(system):
    """The system a batch runs: itself, or for a set-valued jump map (which a
    run to its first jump never applies) a copy without it."""
    if not system.set_valued:
        return system
    import copy
    proxy = copy.copy(system)
    proxy.jump_map_values = None
    return proxy
