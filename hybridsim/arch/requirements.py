"""The ARCH-COMP falsification requirements of AT, CC and F16, in signal temporal logic.

Each requirement is a :class:`Requirement`: its name, its model ("AT",
"CC" or "F16"), its formula (a :mod:`hybridsim.stl` formula, whose robustness on a
run is a :class:`hybridsim.testing.Margin`) and the text of the
competition's benchmark file it renders. The definitions are those of the
competition's ``requirements.txt`` files (ARCH-COMP 2020 on, as shipped with
the benchmarks, e.g. FalCAuN-ARCH-COMP's ``AT/requirements.txt`` and the
ARCH 2020 benchmark folder's ``chasing-cars/requirements.txt``) and of the
category reports (Ernst et al., "ARCH-COMP 2020/2021 Category Report:
Falsification"). Where the descriptions differ, the benchmark files decide:
CC4's innermost window is [0, 5] (``always_[0,5]``), as in the competition's
file, FalCAuN's and MoonLight's scripts.

Signals: AT speed (mph), RPM (engine speed, rpm), gear; CC y1..y5 (the
cars' positions); F16 altitude (ft). F16: ``G[0,15] (altitude > 0)``, the
benchmark's README (ARCH-COMP FALS, e.g. MoonLight's ``benchmarks/F16``).

AT51-AT54 on hybrid arcs. The competition's signals are right-continuous: at
a gear change's instant t_s the gear is already the new one. On a hybrid arc
the instant t_s carries both gears, (t_s, j) the old and (t_s, j + 1) the new;
a window of :mod:`hybridsim.stl` opened at a hybrid instant never reads back
before it, so ``F[0.001,0.1] G[0,2.5] gear == i`` read at t_s - 0.1 meets the
post-jump instant (t_s, j + 1), where the new gear holds: the formulas are
the competition's as written, and a shift into gear i that is held 2.5 s
satisfies AT5i (full throttle: +0.5 for AT51-AT54).

Examples
--------
>>> REQUIREMENTS["AT1"].text
'G[0,20] (speed < 120)'
>>> REQUIREMENTS["AT1"].horizon, REQUIREMENTS["CC4"].horizon
(20.0, 100.0)
>>> sorted(r for r in REQUIREMENTS if r.startswith("CC"))
['CC1', 'CC2', 'CC3', 'CC4', 'CC5', 'CCx']
"""
from __future__ import annotations

import dataclasses

from .. import stl
from .f16 import F16
from .models import AutomaticTransmission, ChasingCars

__all__ = ["Requirement", "REQUIREMENTS"]


@dataclasses.dataclass(frozen=True)
class Requirement:
    """One requirement of the competition.

    Attributes
    ----------
    name : str
        "AT1", ..., "CCx".
    system : str
        "AT", "CC" or "F16": the model it constrains.
    formula : hybridsim.stl.Formula
        Its robustness on a run of the model (``formula(arc)``) is the margin.
    text : str
        The competition's formula, as its benchmark file writes it.
    """

    name: str
    system: str
    formula: object
    text: str

    @property
    def horizon(self) -> float:
        """How long a run must be for the formula (its horizon from t = 0)."""
        return float(self.formula.horizon)

    def __call__(self, arc, refine=4):
        """The robustness on ``arc`` (:meth:`hybridsim.stl.Formula.robustness`;
        ``refine=1``: the samples, crossings and window ends only, several
        times cheaper on arcs of many samples, what the searches use)."""
        return self.formula.robustness(arc, refine=refine)


speed = stl.state(AutomaticTransmission.SPEED, "speed")
rpm = stl.state(AutomaticTransmission.RPM, "RPM")
gear = stl.state(AutomaticTransmission.GEAR, "gear")
y = [stl.state(i, f"y{k + 1}") for k, i in enumerate(ChasingCars.POSITIONS)]
altitude = stl.state(F16.ALTITUDE, "altitude")


def _at5(i):
    is_i = stl.equals(gear, i)
    return stl.always(stl.implies(~is_i & stl.eventually(is_i, 0.001, 0.1),
                                  stl.eventually(stl.always(is_i, 0.0, 2.5), 0.001, 0.1)),
                       0.0, 30.0)


def _at6(*parts):
    conclusion = None
    for T, v in parts:
        c = stl.always(speed < v, 0.0, T)
        conclusion = c if conclusion is None else conclusion & c
    return stl.implies(stl.always(rpm < 3000, 0.0, 30.0), conclusion)


_d21, _d54 = y[1] - y[0], y[4] - y[3]
_TABLE = [
    ("AT1", "AT", stl.always(speed < 120, 0.0, 20.0), "G[0,20] (speed < 120)"),
    ("AT2", "AT", stl.always(rpm < 4750, 0.0, 10.0), "G[0,10] (RPM < 4750)"),
    *[(f"AT5{i}", "AT", _at5(i),
       f"G[0,30] ((gear != {i} & F[0.001,0.1] gear == {i}) -> "
       f"F[0.001,0.1] G[0,2.5] gear == {i})") for i in (1, 2, 3, 4)],
    ("AT6a", "AT", _at6((4.0, 35.0)), "G[0,30] (RPM < 3000) -> G[0,4] (speed < 35)"),
    ("AT6b", "AT", _at6((8.0, 50.0)), "G[0,30] (RPM < 3000) -> G[0,8] (speed < 50)"),
    ("AT6c", "AT", _at6((20.0, 65.0)), "G[0,30] (RPM < 3000) -> G[0,20] (speed < 65)"),
    ("AT6abc", "AT", _at6((4.0, 35.0), (8.0, 50.0), (20.0, 65.0)),
     "G[0,30] (RPM < 3000) -> (G[0,4] (speed < 35) & G[0,8] (speed < 50) & "
     "G[0,20] (speed < 65))"),
    ("CC1", "CC", stl.always(_d54 <= 40, 0.0, 100.0), "G[0,100] (y5 - y4 <= 40)"),
    ("CC2", "CC", stl.always(stl.eventually(_d54 >= 15, 0.0, 30.0), 0.0, 70.0),
     "G[0,70] F[0,30] (y5 - y4 >= 15)"),
    ("CC3", "CC", stl.always(stl.always(_d21 <= 20, 0.0, 20.0)
                             | stl.eventually(_d54 >= 40, 0.0, 20.0), 0.0, 80.0),
     "G[0,80] ((G[0,20] (y2 - y1 <= 20)) | (F[0,20] (y5 - y4 >= 40)))"),
    ("CC4", "CC", stl.always(stl.eventually(stl.always(_d54 >= 8, 0.0, 5.0), 0.0, 30.0),
                             0.0, 65.0),
     "G[0,65] F[0,30] G[0,5] (y5 - y4 >= 8)"),
    ("CC5", "CC", stl.always(stl.eventually(stl.implies(stl.always(_d21 >= 9, 0.0, 5.0),
                                                        stl.always(_d54 >= 9, 5.0, 20.0)),
                                            0.0, 8.0), 0.0, 72.0),
     "G[0,72] F[0,8] ((G[0,5] (y2 - y1 >= 9)) -> (G[5,20] (y5 - y4 >= 9)))"),
    ("CCx", "CC", stl.always((y[1] - y[0] > 7.5) & (y[2] - y[1] > 7.5)
                             & (y[3] - y[2] > 7.5) & (y[4] - y[3] > 7.5), 0.0, 50.0),
     "G[0,50] (y2 - y1 > 7.5 & y3 - y2 > 7.5 & y4 - y3 > 7.5 & y5 - y4 > 7.5)"),
    ("F16", "F16", stl.always(altitude > 0, 0.0, 15.0), "G[0,15] (altitude > 0)"),
]

#: every requirement by name, in the competition's order
REQUIREMENTS = {name: Requirement(name, system, formula, text)
                for name, system, formula, text in _TABLE}
