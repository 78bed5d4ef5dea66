"""The ARCH-COMP falsification benchmarks AT and CC on hybridsim.

:mod:`~hybridsim.arch.models` (the automatic transmission and the chasing
cars as hybrid systems), :mod:`~hybridsim.arch.requirements` (AT1-AT6abc,
CC1-CCx in signal temporal logic), :mod:`~hybridsim.arch.spaces` (the
competition's two input instances as falsification spaces) and
:mod:`~hybridsim.arch.runner` (``python -m hybridsim.arch --out DIR``, and
``python -m hybridsim.arch validate DIR``).
"""
from .models import AutomaticTransmission, ChasingCars
from .requirements import REQUIREMENTS, Requirement
from .spaces import problem, space

__all__ = ["AutomaticTransmission", "ChasingCars", "REQUIREMENTS", "Requirement", "problem",
           "space"]

# documented here, under the name users import it by
Requirement.__module__ = __name__
