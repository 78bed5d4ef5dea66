"""Many runs: initial conditions, noise realisations, parameter sweeps.

:func:`simulate_many` and :func:`sweep` are the front door's
(:mod:`hybridsim.run`); the batch policy (:func:`finish_batch`,
:class:`BatchWarning`, :class:`BatchError`) is :mod:`hybridsim.rules`'s. This
module keeps their names importable from here.
"""
from __future__ import annotations

from .rules import FAILED, BatchError, BatchWarning, finish_batch
from .run import GRACE, simulate_many, sweep

__all__ = ["BatchError", "BatchWarning", "simulate_many", "sweep", "finish_batch", "FAILED",
           "GRACE"]
