"""The competition's input spaces, and a requirement made a falsification problem.

ARCH-COMP's two instances (the benchmark files' ``requirements.txt``):

1. any piecewise continuous inputs within their ranges; each tool chooses
   its parameterisation. Here: piecewise linear through control points
   (AT: every 2.5 s, 13 points on [0, 30]; CC: every 10 s, 11 points on
   [0, 100]), each value free in its range.
2. piecewise constant inputs whose discontinuities are at least 5 s apart:
   here a value every 5 s (AT: 6 pieces on [0, 30]; CC: 20 pieces on
   [0, 100]).

Ranges: AT throttle [0, 100] %, brake [0, 325] lb ft; CC throttle and
brake [0, 1]. After the grid's end (AT5x reads to 32.6 s) the last value
is held.

F16 has no input signal, one instance: its initial roll in [pi/4 - pi/20,
pi/4 + pi/30], pitch in [-2 pi/5, -2 pi/5 + pi/20] and yaw in [-pi/4 - pi/8,
-pi/4 + pi/8] (rad; the benchmark's README), from 2338 ft (its
``initF16.m``), the model the competition runs (``F16(pilot="arch")``: the
GCAS on from t = 0, then the waypoint follower), its switches located.

Examples
--------
>>> s = space("AT", 2)
>>> s.dim, s.entries["u"].times.tolist()
(12, [0.0, 5.0, 10.0, 15.0, 20.0, 25.0])
>>> space("CC", 1).dim
22
>>> space("F16", 1).dim
3
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..falsification import ControlPoints, Interval, Space, batch_run
from .f16 import F16
from .models import AutomaticTransmission, ChasingCars
from .requirements import REQUIREMENTS

__all__ = ["INSTANCES", "space", "model", "problem", "MODELS", "F16_RANGES", "f16_state"]

MODELS = {"AT": AutomaticTransmission, "CC": ChasingCars, "F16": F16}
#: (t_end, points, interpolation) of each model's instance 1 and 2
INSTANCES = {
    ("AT", 1): (30.0, 13, "linear"),
    ("AT", 2): (30.0, 6, "previous"),
    ("CC", 1): (100.0, 11, "linear"),
    ("CC", 2): (100.0, 20, "previous"),
    ("F16", 1): (15.0, 0, None),
}
#: F16's initial attitudes (rad): (lo, hi) of roll, pitch, yaw
F16_RANGES = {"roll": (math.pi / 4 - math.pi / 20, math.pi / 4 + math.pi / 30),
              "pitch": (-2 * math.pi / 5, -2 * math.pi / 5 + math.pi / 20),
              "yaw": (-math.pi / 4 - math.pi / 8, -math.pi / 4 + math.pi / 8)}
#: the autopilot of the F16 instance and its logic's sampling (:class:`F16`'s ``pilot``
#: and ``sample``; None: switches located)
F16_PILOT, F16_SAMPLE = "arch", None


def _key(system, instance):
    if (system, instance) not in INSTANCES:
        raise ValueError(f"no instance {instance!r} of {system!r}: have "
                         f"{sorted(INSTANCES)}")
    return system, instance


def space(system, instance):
    """The input space of ``system`` ("AT" or "CC") in ``instance`` (1 or 2): one
    entry ``u``, the two inputs (throttle, brake) as :class:`ControlPoints`;
    of "F16" (instance 1): its initial roll, pitch and yaw as :class:`Interval`."""
    t_end, points, interp = INSTANCES[_key(system, instance)]
    if system == "F16":
        return Space(**{k: Interval(lo, hi) for k, (lo, hi) in F16_RANGES.items()})
    m = MODELS[system]
    lo, hi = [m.THROTTLE[0], m.BRAKE[0]], [m.THROTTLE[1], m.BRAKE[1]]
    return Space(u=ControlPoints(lo, hi, t_end, points, interp))


@functools.cache
def model(system, instance):
    """The model whose inputs are ``instance``'s control points (one per process:
    its compiled maps are reused by every requirement)."""
    interp = INSTANCES[_key(system, instance)][2]
    if system == "F16":
        return F16(pilot=F16_PILOT, sample=F16_SAMPLE)
    return MODELS[system](times=space(system, instance).entries["u"].times,
                          interpolation=interp)


def problem(name, instance, backend="auto"):
    """(run, space, claim, t_max) of requirement ``name`` on ``instance``.

    ``run`` is a population run (:func:`hybridsim.falsification.batch_run`:
    compiled and parallel where numba is installed), each run as long as
    the requirement's horizon; ``claim`` is the requirement's robustness on
    the run's samples, crossings and window ends (``refine=1``: the search's
    judge; :func:`hybridsim.arch.runner.validate` checks each counterexample
    again in the dense semantics, ``refine=4``).

    Examples
    --------
    >>> run, s, claim, t_max = problem("AT2", 2)
    >>> t_max, s.dim, run.batch
    (10.0, 12, True)
    """
    if name not in REQUIREMENTS:
        raise ValueError(f"no requirement {name!r}: have {list(REQUIREMENTS)}")
    req = REQUIREMENTS[name]
    sys_ = model(req.system, instance)
    sp = space(req.system, instance)

    def claim(arc):
        return req(arc, refine=1)
    if req.system == "F16":
        def x0_of(point):
            return f16_state(sys_, point["roll"], point["pitch"], point["yaw"])
        return batch_run(sys_, x0_of, req.horizon, backend=backend), sp, claim, req.horizon
    x0 = sys_.initial_state()

    def params_of(point):               # the point's input signal: the row's params
        vals = point["u"].values
        return {"params": sys_.input_params(vals[:, 0], vals[:, 1])}
    run = batch_run(sys_, lambda point: x0, req.horizon, attributes_of=params_of,
                    backend=backend)
    return run, sp, claim, req.horizon


def f16_state(m, roll, pitch, yaw):
    """The F16 instance's initial state of these attitudes (rad)."""
    return m.initial_state(roll, pitch, yaw)


def input_matrix(point):
    """The point's inputs in the competition's format ``[t a b; ...]`` (F16:
    ``[roll pitch yaw]``)."""
    if "u" not in point:
        return "[" + " ".join(repr(float(point[k])) for k in F16_RANGES) + "]"
    u = point["u"]
    return "[" + "; ".join(" ".join(repr(float(v)) for v in (t, *row))
                           for t, row in zip(u.times, u.values)) + "]"


def parse_input(text):
    """``[t a b; ...]`` as (times (k,), values (k, 2)); the inverse of :func:`input_matrix`."""
    rows = [r.split() for r in text.strip().strip("[]").split(";") if r.strip()]
    try:
        a = np.array([[float(v) for v in r] for r in rows])
    except ValueError as e:
        raise ValueError(f"input must read '[t a b; ...]', got {text[:60]!r}") from e
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"input must have rows of 3 numbers (t, throttle, brake), got "
                         f"{text[:60]!r}")
    return a[:, 0], a[:, 1:]
