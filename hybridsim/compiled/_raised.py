"""A map that raises on the compiled path: its exception caught while a kernel
runs (:class:`_CatchRaised`) and the run reported as the map's error
(:func:`_raised_arc`). Used by :mod:`._run`.
"""
from __future__ import annotations

import sys
import threading

from ..arc import HybridArc
from ..rules import MapError, Termination, message

# ---------------------------------------------------------------- a map that raises
# numba compiles ``raise`` in a map; the map's C wrapper, which the kernels call,
# cannot pass the exception on: it reports it to ``sys.unraisablehook`` (with the
# GIL) and returns an unspecified value. While a run is under way its thread's
# reports are caught here: the first is kept and the run's stop flag is set, so
# the run ends at its next step (kept so far) and is reported as the map's error.
_RAISED = threading.local()
_HOOK_LOCK = threading.Lock()
_HOOK = {"depth": 0, "prev": None}
#: the Python path's names of a CompiledSystem's maps
_MAP_NAMES = {"flow": "flow_map", "jump": "jump_map", "jump_guard": "jump_guard",
              "flow_guard": "flow_guard", "jump_set": "jump_set", "flow_set": "flow_set"}


#: the boxes of parallel batches under way: their worker threads' reports
_BATCHES = []


def _unraisable(u):
    box = getattr(_RAISED, "box", None)
    if box is None and _BATCHES:
        box = _BATCHES[-1]
    if box is None or "numba" not in repr(u.object):
        prev = _HOOK["prev"] or sys.__unraisablehook__
        return prev(u)
    if not box["exc"]:
        box["exc"].append((u.exc_type, u.exc_value, u.exc_traceback))
    if box["stop"] is not None:
        box["stop"][0] = 1


class _CatchRaised:
    """While a kernel runs in this thread: a map's exception ends the run
    (``stop[0] = 1``) and is kept in ``self.box["exc"]``. ``stop=None``: a
    parallel batch's, which records the reports of its worker threads and
    stops nothing (its rows are then run again one by one, each caught)."""

    def __init__(self, stop):
        self.box = {"exc": [], "stop": stop}

    def __enter__(self):
        if self.box["stop"] is None:
            _BATCHES.append(self.box)
        with _HOOK_LOCK:
            if _HOOK["depth"] == 0 or sys.unraisablehook is not _unraisable:
                if sys.unraisablehook is not _unraisable:
                    _HOOK["prev"] = sys.unraisablehook
                sys.unraisablehook = _unraisable
            _HOOK["depth"] += 1
        self.outer = getattr(_RAISED, "box", None)
        if self.box["stop"] is not None:
            _RAISED.box = self.box
        return self

    def __exit__(self, *exc):
        if self.box["stop"] is None:
            _BATCHES.remove(self.box)
        _RAISED.box = self.outer
        with _HOOK_LOCK:
            _HOOK["depth"] -= 1
            if _HOOK["depth"] == 0 and sys.unraisablehook is _unraisable:
                sys.unraisablehook = _HOOK["prev"] or sys.__unraisablehook__
                _HOOK["prev"] = None
        return False

    @property
    def raised(self):
        return self.box["exc"][0] if self.box["exc"] else None


def _raising_map(system, tb):
    """The Python path's name of the map whose code raised (by the traceback's
    frames), or None."""
    frames = []
    while tb is not None:
        frames.append((tb.tb_frame.f_code.co_filename, tb.tb_frame.f_code.co_name,
                       tb.tb_lineno))
        tb = tb.tb_next
    for role, fn in system.maps.items():
        code = getattr(getattr(fn, "py_func", fn), "__code__", None)
        if code is None:
            continue
        lines = {ln for _, _, ln in code.co_lines() if ln is not None}
        for fname, name, line in reversed(frames):
            if fname == code.co_filename and name == code.co_name and line in lines:
                return _MAP_NAMES.get(role, role)
    return None


def _raised_arc(system, arc, raised):
    """A run whose map raised: ``MAP_ERROR`` with the map's exception, the arc so far."""
    etype, evalue, tb = raised
    name = _raising_map(system, tb)
    t, j = float(arc.t[-1]), int(arc.j[-1])
    text = (f"{name or 'a map'} raised {etype.__name__}: {evalue} (compiled: near t={t:.10g}, "
            f"j={j}, the run's last sample; numba passes on no t)")
    exc = MapError(text, name, t, j)
    exc.__cause__ = evalue
    return HybridArc._trusted(arc.t, arc.j, arc.x, Termination.MAP_ERROR,
                              message(Termination.MAP_ERROR, error=text), exc,
                              system=system, xdot=arc.xdot, stats=arc.stats,
                              description=arc.system_description), exc
