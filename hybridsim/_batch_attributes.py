"""A batch whose rows set the system's attributes: ``simulate_many(..., attributes=)``.

A plain model keeps its parameters where its author put them, as attributes
its maps read (``self.e``, ``self.K``); a
:class:`~hybridsim.compiled.CompiledSystem` keeps them in ``params``. Row
``i`` of a batch runs with the attributes of ``attributes[i]`` set. On the
compiled path the rows' ``p`` (what the lowered maps read of the system,
:func:`hybridsim.compiled.lower`) are read once per row and the batch runs
as one parallel kernel call (:func:`simulate_many_compiled`'s ``params``);
on the other paths the rows run one after another, each with its attributes
set. The system's attributes are as they were afterwards.
"""
from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["check_attributes", "Attributes", "row_params"]

_UNSET = object()
_LOCK = threading.Lock()


def check_attributes(attributes, N):
    """``attributes``, checked: a sequence of ``N`` dicts of attribute names
    (str) to values; returned as a list."""
    if isinstance(attributes, (str, bytes, Mapping)) or not isinstance(attributes, Sequence):
        raise TypeError(f"attributes must be a sequence of dicts, one per row of x0s "
                        f"(e.g. [{{'e': 0.8}}, {{'e': 0.9}}]), got {type(attributes).__name__}")
    rows = list(attributes)
    if len(rows) != N:
        raise ValueError(f"attributes must hold one dict per row of x0s: {N} rows, got "
                         f"{len(rows)}")
    for i, d in enumerate(rows):
        if not isinstance(d, Mapping):
            raise TypeError(f"attributes[{i}] must be a dict of the system's attributes, got "
                            f"{type(d).__name__}")
        for name in d:
            if not isinstance(name, str) or not name.isidentifier():
                raise TypeError(f"attributes[{i}]: attribute names must be identifiers, got "
                                f"{name!r}")
    return rows


class Attributes:
    """Sets rows' attributes on ``system``; :meth:`restore` puts back what
    was there (an instance attribute, a property's value, or nothing).
    Called with a row's dict it sets them and returns the system, as
    :func:`hybridsim.sweep`'s ``make_system``. ``copies=True`` (a batch
    over an executor, whose workers may be threads sharing the system):
    each row gets a copy of the system (``copy.deepcopy``) with its
    attributes, the system itself untouched."""

    def __init__(self, system, copies=False):
        self.system, self.copies = system, copies
        self.saved = {}

    def __call__(self, values):
        if self.copies:
            import copy
            s = copy.deepcopy(self.system)
            for name, v in values.items():
                setattr(s, name, v)
            return s
        s = self.system
        for name, v in values.items():
            if name not in self.saved:
                own = vars(s) if hasattr(s, "__dict__") else {}
                self.saved[name] = own[name] if name in own else (
                    getattr(s, name) if hasattr(type(s), name) else _UNSET)
            setattr(s, name, v)
        return s

    def restore(self):
        s = self.system
        for name, v in self.saved.items():
            if v is _UNSET:
                if name in vars(s):
                    delattr(s, name)
            else:
                setattr(s, name, v)
        self.saved = {}

    def __getstate__(self):
        return {"system": self.system, "copies": self.copies, "saved": {}}


def row_params(system, rows):
    """``(cs, P)``: the compiled form the rows share and their ``p``, one row
    each (``P`` (N, len(cs.params))), each read with the row's attributes
    set, under one lock; ``None`` where a row changes the compiled form itself
    (an attribute of another shape: the rows then run one by one). A
    :class:`~hybridsim.compiled.CompiledSystem` whose rows set only
    ``params`` takes them as they are, setting nothing."""
    from .compiled import CompiledSystem
    from .compiled._lower import lower
    if isinstance(system, CompiledSystem) and all(set(d) == {"params"} for d in rows):
        # its p is the rows' own: nothing set on the system (a population run in
        # threads while the search judges the last one's arcs reads the system as it is)
        m = system.params.size
        try:
            P = np.array([np.asarray(d["params"], dtype=np.float64).reshape(-1) for d in rows])
        except (TypeError, ValueError) as e:
            raise TypeError(f"attributes: each row's 'params' must be an array of {m} floats, "
                            f"got {e}") from e
        if P.shape != (len(rows), m):
            raise ValueError(f"attributes: each row's 'params' must hold {m} floats (the "
                             f"system's params), got rows of shape {P.shape[1:]}")
        return system, np.ascontiguousarray(P)
    with _LOCK:           # populations of one search may read their p in threads at once
        return _set_and_read(system, rows, lower)


def _set_and_read(system, rows, lower):
    setter = Attributes(system)
    cs0, P = None, []
    try:
        for d in rows:
            setter(d)
            cs = lower(system)
            if cs0 is None:
                cs0 = cs
            elif cs is not cs0 or cs.params.size != cs0.params.size:
                return None
            P.append(np.array(cs.params, dtype=np.float64))
    finally:
        setter.restore()
        if cs0 is not None:
            lower(system)                 # the compiled form's params as the system's again
    m = cs0.params.size if cs0 is not None else 0
    return cs0, np.ascontiguousarray(np.array(P, dtype=np.float64).reshape(len(rows), m))
