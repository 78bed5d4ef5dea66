"""hybridsim: simulation of hybrid dynamical systems H = (C, f, D, g).

The public face: :class:`HybridSystem` (the data), :func:`simulate` (one run),
:class:`HybridArc` (its solution on a hybrid time domain), interconnections
(:func:`connect`, :class:`Interconnection`, :func:`network`,
:class:`LinearPlant`), batches (:func:`simulate_many`, :func:`sweep`) and plots
in hybrid time (:func:`plot_flows`, :func:`plot_jumps`, :func:`plot_hybrid`,
:func:`plot_phase`, :func:`plot_time_domain`). Theorem-check helpers live in
:mod:`hybridsim.testing`.
"""
from ._version import __version__
from .arc import HybridArc, Termination
from .system import HybridSystem
from .rules import MapError, SimulationError, SimulationWarning
from .solve import simulate, METHODS
from .history import History, HistoryError
from .compose import Interconnection, LinearPlant, connect, network
from .batch import BatchError, BatchWarning, simulate_many, sweep
from .batch_vectorized import simulate_vectorized
from .plot import plot_flows, plot_jumps, plot_hybrid, plot_phase, plot_time_domain
from . import compiled, library, rules, testing


__all__ = [
    "HybridSystem", "HybridArc", "Termination", "simulate", "MapError",
    "SimulationError", "SimulationWarning", "METHODS", "History", "HistoryError",
    "Interconnection", "LinearPlant", "connect", "network",
    "simulate_many", "sweep", "simulate_vectorized", "BatchError", "BatchWarning",
    "plot_flows", "plot_jumps", "plot_hybrid", "plot_phase", "plot_time_domain",
]
