"""hybridsim: simulation of hybrid dynamical systems H = (C, f, D, g).

The public face: :class:`HybridSystem` (the data), :func:`simulate` (one run),
:class:`HybridArc` (its solution on a hybrid time domain), interconnections
(:func:`connect`, :class:`Interconnection`, :func:`network`,
:class:`LinearPlant`), batches (:func:`simulate_many`, :func:`sweep`, returning an
:class:`ArcBatch`: the list of arcs with their fields as arrays) and plots
in hybrid time (:func:`plot_flows`, :func:`plot_jumps`, :func:`plot_hybrid`,
:func:`plot_phase`, :func:`plot_time_domain`); every solution of a hybrid inclusion
(:func:`explore`, drawn by :func:`plot_solutions`). Theorem-check helpers live in
:mod:`hybridsim.testing`; the search for counterexamples over a declared
uncertainty space, :func:`falsify`, in :mod:`hybridsim.falsification`;
derivatives through jumps, :func:`simulate_sensitivity`, in
:mod:`hybridsim.sensitivity`; signal temporal logic over arcs, with robustness as a
margin, in :mod:`hybridsim.stl`. Monte Carlo answers with confidence
(``estimate``, streaming ``Stats``, ``splitting`` for rare events) live in
:mod:`hybridsim.estimate`; SDE flows (a system's
``diffusion``) and jumps at a rate (``jump_rate``) run on the Python and
compiled paths (the same draws per seed), random jump maps (``jump_law``)
on the Python path, driven by :class:`BrownianPath`.
"""
from . import compiled as compiled
from . import estimate as estimate
from . import falsification as falsification
from . import library as library
from . import rules as rules
from . import stl as stl
from . import testing as testing
from ._compose_network import connect, network
from ._version import __version__ as __version__
from .arc import Crossings, HybridArc, Termination, load
from .arc_batch import ArcBatch
from .batch_vectorized import simulate_vectorized
from .brownian import BrownianPath
from .compose import Interconnection, LinearInput, LinearPlant
from .explore import Choice, ExploreEnd, SolutionTree, explore
from .falsification import falsify
from .history import BatchHistory, History, HistoryError
from .options import METHODS
from .plot import (
    plot_flows,
    plot_hybrid,
    plot_jumps,
    plot_phase,
    plot_solutions,
    plot_time_domain,
)
from .rules import BatchError, BatchWarning, MapError, SimulationError, SimulationWarning
from .run import simulate, simulate_many, sweep
from .sensitivity import simulate_sensitivity
from .system import HybridSystem

__all__ = [
    "HybridSystem", "HybridArc", "Termination", "simulate", "MapError",
    "SimulationError", "SimulationWarning", "METHODS", "History", "BatchHistory", "HistoryError",
    "Interconnection", "LinearInput", "LinearPlant", "connect", "network",
    "simulate_many", "sweep", "simulate_vectorized", "BatchError", "BatchWarning",
    "plot_flows", "plot_jumps", "plot_hybrid", "plot_phase", "plot_time_domain",
    "falsify", "simulate_sensitivity", "explore", "SolutionTree", "Choice", "ExploreEnd",
    "plot_solutions", "load", "BrownianPath", "Crossings", "ArcBatch",
]
