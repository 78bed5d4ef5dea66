"""The ARCH-COMP falsification benchmarks on hybridsim (models, requirements,
input spaces and a runner: ``python -m hybridsim.arch --out DIR``)."""
from .models import AutomaticTransmission, ChasingCars

__all__ = ["AutomaticTransmission", "ChasingCars"]
