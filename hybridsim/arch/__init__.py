"""The ARCH-COMP falsification benchmarks AT, CC and F16 on hybridsim.

:mod:`~hybridsim.arch.models` (the automatic transmission and the chasing
cars as hybrid systems), :mod:`~hybridsim.arch.f16` (the F-16's ground
collision avoidance), :mod:`~hybridsim.arch.requirements` (AT1-AT6abc,
CC1-CCx, F16 in signal temporal logic), :mod:`~hybridsim.arch.spaces` (the
competition's two input instances as falsification spaces) and
:mod:`~hybridsim.arch.runner` (``python -m hybridsim.arch --out DIR``, and
``python -m hybridsim.arch validate DIR``).
"""
from .f16 import F16
from .models import AutomaticTransmission, ChasingCars
from .requirements import REQUIREMENTS, Requirement
from .spaces import problem, space

__all__ = ["AutomaticTransmission", "ChasingCars", "F16", "REQUIREMENTS", "Requirement", "problem",
           "space"]

# documented here, under the name users import it by
Requirement.__module__ = __name__
