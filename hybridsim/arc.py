"""Hybrid arcs: solutions on hybrid time domains.

A :class:`HybridArc` holds the samples ``(t, j, x)`` of a solution, time-major,
with a jump stored as two samples at the same t with j and j + 1. Besides the
samples it offers interpolation inside the flows (:meth:`HybridArc.at`,
:meth:`HybridArc.interpolate`), windows of hybrid time
(:meth:`HybridArc.restrict`, :meth:`HybridArc.select`), maps of the state
(:meth:`HybridArc.transform`), pickling whatever the system holds, and a
versioned, validated ``.npz`` format (:meth:`HybridArc.save`,
:meth:`HybridArc.load`).
"""
from __future__ import annotations

import json
import math
import numbers
import os
import pickle
import stat
import struct
import zipfile
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .rules import Termination  # one source of the causes

__all__ = ["HybridArc", "Termination", "ArcValues", "ArcFileError", "FORMAT_VERSION", "load",
           "MAX_FILE_BYTES", "Crossings"]

#: Version of the ``.npz`` layout written by :meth:`HybridArc.save`.
#: 1: t, j, x, termination, message, comp_names, comp_bounds (no version key).
#: 2: adds format_version, components (JSON, any hashable names), xdot, stats,
#:    system_description; choices (JSON, optional, like xdot: the choices of a
#:    leaf of :func:`hybridsim.explore`); crossings (optional: crossing_t,
#:    crossing_j, crossing_which, crossing_direction, crossing_x, the crossings
#:    of a system's watched functions, :class:`Crossings`).
FORMAT_VERSION = 2
#: What :meth:`HybridArc.load` reads at most by default: the file, and the
#: arrays it declares once decompressed (16 GiB; ``max_bytes=`` for more)
MAX_FILE_BYTES = 1 << 34
_CHOICE_KINDS = ("jump", "flow", "dwell")

_AT_JUMP = ("start", "end", "mean", "nan", "both")
#: validate every arc an integration path returns (``HYBRIDSIM_CHECK_ARCS=1``;
#: the test suite sets it): a defect of the engine then fails at its run
CHECK_ARCS = os.environ.get("HYBRIDSIM_CHECK_ARCS", "") not in ("", "0")
#: the attributes a pooled arc makes on first access (``HybridArc._pooled``)
_POOLED = frozenset(("t", "j", "x", "xdot", "stats"))
_KEYS_V1 = ("t", "j", "x", "termination", "message", "comp_names", "comp_bounds")
_KEYS_V2 = ("format_version", "t", "j", "x", "termination", "message",
            "components", "stats", "system_description")


class ArcValues(NamedTuple):
    """Values of an arc on a grid of ordinary time, from :meth:`HybridArc.interpolate`.

    Unpack it as ``t, j, x = arc.interpolate(grid)``.

    Attributes
    ----------
    t : ndarray, shape (m,)
        The times (the grid; with ``at_jump="both"`` a jump time appears twice).
    j : ndarray of int, shape (m,)
        The jump count of each row.
    x : ndarray, shape (m, n)
        The state at (t, j).
    """

    t: np.ndarray
    j: np.ndarray
    x: np.ndarray


def _describe(system):
    """A short description of a system, kept when the object cannot travel."""
    if system is None:
        return None
    cls = type(system)
    desc = f"{cls.__module__}.{cls.__qualname__}"
    comps = getattr(system, "components", None)
    if comps:
        desc += f" with components {list(comps)}"
    return desc


def _picklable(obj) -> bool:
    try:
        pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - any failure means: does not travel
        return False
    return True


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (Termination,)):
        return o.name
    return str(o)


def _encode_name(name):
    """Component names (str, int, tuples of them...) as JSON values, typed."""
    if isinstance(name, tuple):
        return {"tuple": [_encode_name(v) for v in name]}
    if isinstance(name, (np.integer, np.floating)):
        return name.item()
    if isinstance(name, (str, int, float, bool)) or name is None:
        return name
    return {"str": str(name)}


def _decode_name(v, depth=0):
    """A component name from its JSON form (see :func:`_encode_name`), strictly."""
    if isinstance(v, (str, int, float, bool)) or v is None:
        return v
    if isinstance(v, dict) and len(v) == 1 and depth < 32:
        if isinstance(v.get("tuple"), list):
            return tuple(_decode_name(u, depth + 1) for u in v["tuple"])
        if isinstance(v.get("str"), str):
            return v["str"]
    raise ValueError(f"not a component name: {str(v)[:80]}")


class Crossings:
    """The crossings of a system's watched functions along a run's flows.

    A system's ``watch`` (rule 11 of :class:`hybridsim.HybridSystem`)
    returns m values; each time one of them crosses 0 during a flow the run
    records it here, in hybrid-time order, without a jump and without
    changing the solution.

    Attributes
    ----------
    t : ndarray, shape (K,)
        The crossing times, each located to 4 ulp on the step's dense
        output: the first time, within that bracket, at which the function
        has crossed (on or past 0).
    j : ndarray of int, shape (K,)
        The jump count of the flow it happened on.
    which : ndarray of int, shape (K,)
        The index of the function (0 for a scalar ``watch``).
    direction : ndarray of int, shape (K,)
        1 rising (from below 0 to 0 or above), -1 falling.
    x : ndarray, shape (K, n)
        The state at ``(t, j)``.

    Examples
    --------
    >>> c = Crossings([0.5, 1.5], [0, 0], [0, 0], [1, -1], [[0.0], [0.0]])
    >>> len(c), c.select(direction=-1).t
    (2, array([1.5]))
    """

    _FIELDS = ("t", "j", "which", "direction", "x")

    def __init__(self, t, j, which, direction, x):
        self.t = np.asarray(t, dtype=float).reshape(-1)
        self.j = np.asarray(j, dtype=np.int64).reshape(-1)
        self.which = np.asarray(which, dtype=np.int64).reshape(-1)
        self.direction = np.asarray(direction, dtype=np.int64).reshape(-1)
        k = len(self.t)
        x = np.asarray(x, dtype=float)
        self.x = x.reshape(k, -1) if k else x.reshape(0, x.shape[-1] if x.ndim == 2 else 0)
        if not (len(self.j) == len(self.which) == len(self.direction) == len(self.x) == k):
            raise ValueError(f"Crossings: t, j, which, direction and x must have one row "
                             f"per crossing; got lengths {k}, {len(self.j)}, "
                             f"{len(self.which)}, {len(self.direction)}, {len(self.x)}")
        if not np.isin(self.direction, (-1, 1)).all():
            raise ValueError("Crossings: direction must be 1 (rising) or -1 (falling)")

    def __len__(self):
        return len(self.t)

    def __repr__(self):
        return f"<Crossings: {len(self)} crossings>"

    def __eq__(self, other):
        if not isinstance(other, Crossings):
            return NotImplemented
        return all(np.array_equal(getattr(self, k), getattr(other, k))
                   for k in self._FIELDS)

    __hash__ = None

    def select(self, which=None, direction=None):
        """The crossings of function ``which`` and/or of one ``direction`` (1 or -1)."""
        keep = np.ones(len(self), bool)
        if which is not None:
            keep &= self.which == which
        if direction is not None:
            if direction not in (-1, 1):
                raise ValueError(f"direction must be 1 (rising) or -1 (falling), got "
                                 f"{direction!r}")
            keep &= self.direction == direction
        return Crossings(self.t[keep], self.j[keep], self.which[keep], self.direction[keep],
                         self.x[keep])


class ArcFileError(ValueError):
    """A file :meth:`HybridArc.load` cannot read as an arc: damaged, foreign or crafted.

    A ``ValueError``; the message names the file and what is wrong with it.
    """


#: What each array of the format must be: (ndim, dtype kinds, description).
_SPECS = {
    "format_version": (0, "iu", "an integer"),
    "t": (1, "iuf", "a 1-D float array"),
    "j": (1, "iuf", "an integer array of shape (N,)"),
    "x": (2, "iuf", "a float array of shape (N, n)"),
    "xdot": (2, "iuf", "a float array of shape (N, n)"),
    "comp_names": (1, "USiu", "a 1-D array of names"),
    "comp_bounds": (2, "iu", "an integer array of shape (m, 2)"),
    "crossing_t": (1, "iuf", "a 1-D float array"),
    "crossing_j": (1, "iu", "a 1-D integer array"),
    "crossing_which": (1, "iu", "a 1-D integer array"),
    "crossing_direction": (1, "i", "a 1-D integer array"),
    "crossing_x": (2, "iuf", "a float array of shape (K, n)"),
}
_CROSSING_KEYS = ("crossing_t", "crossing_j", "crossing_which", "crossing_direction",
                  "crossing_x")
_STRING = (0, "US", "a string")
_SUPPORTED = (f"this hybridsim reads format versions 1 (files without format_version) "
              f"to {FORMAT_VERSION}")
_CHUNK = 1 << 20


def _read_member(z, info, key, size, bad):
    """One array of an npz archive, checked against its spec before its data is read.

    The ``.npy`` header's dtype and shape are checked first, and the data
    they declare against the bytes the member holds, so that a crafted
    header never allocates more than the file can fill; object dtypes are
    refused (nothing is unpickled).
    """
    ndim, kinds, what = _SPECS.get(key, _STRING)
    if info.flag_bits & 0x1:
        raise bad(f"array {key!r} is encrypted")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise bad(f"array {key!r} uses zip compression method {info.compress_type}, "
                  f"not one numpy writes")
    # deflate expands at most ~1032x: a larger declared size is a lie
    if info.compress_size > size or info.file_size > 1100 * info.compress_size + 1024:
        raise bad(f"array {key!r} declares {info.file_size} bytes ({info.compress_size} "
                  f"compressed) in a file of {size} bytes")
    with z.open(info) as f:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(f)
        elif version == (2, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(f)
        else:
            raise bad(f"array {key!r} has .npy format version {version}, not 1.0 or 2.0")
        if dtype.hasobject:
            raise bad(f"array {key!r} holds Python objects (pickled data), which load "
                      f"never unpickles")
        if len(shape) != ndim or dtype.kind not in kinds:
            if key == "format_version":
                raise bad(f"format_version must be an integer, got dtype {dtype}, shape "
                          f"{shape}; {_SUPPORTED}")
            raise bad(f"{key} must be {what}, got dtype {dtype}, shape {shape}")
        nbytes = math.prod(shape) * dtype.itemsize
        held = info.file_size - f.tell()
        if nbytes != held:
            raise bad(f"array {key!r} declares shape {shape} of {dtype} ({nbytes} bytes) "
                      f"but holds {held} bytes")
        buf = np.empty(nbytes, dtype=np.uint8)
        pos = 0
        while pos < nbytes:                 # in chunks: memory only as data arrives
            chunk = f.read(min(_CHUNK, nbytes - pos))
            if not chunk:
                raise bad(f"array {key!r} is truncated ({pos} of {nbytes} bytes)")
            buf[pos:pos + len(chunk)] = np.frombuffer(chunk, dtype=np.uint8)
            pos += len(chunk)
        f.read(1)                           # at the end: zipfile checks the CRC
    arr = buf.view(dtype) if nbytes else np.zeros(math.prod(shape), dtype=dtype)
    return arr.reshape(shape, order="F" if fortran else "C")


def _read_npz(fh, bad, max_bytes=MAX_FILE_BYTES):
    """The arrays of an arc file open in ``fh`` and its format version.

    Raises ``bad(...)`` for what it recognises; anything else a damaged
    file raises is named by the caller. The file, and the arrays its members
    declare (decompressed), hold at most ``max_bytes``.
    """
    start = fh.tell()
    head = fh.read(6)
    size = fh.seek(0, os.SEEK_END) - start
    fh.seek(start)
    if size > max_bytes:
        raise bad(f"the file holds {size} bytes, more than max_bytes = {max_bytes}; pass "
                  f"max_bytes= to read a larger arc")
    if head == b"\x93NUMPY":
        raise bad("not an .npz archive (a single .npy array?); expected a file "
                  "written by HybridArc.save")
    # the entry count of the zip's end record: a damaged directory may list fewer
    fh.seek(max(start, start + size - (1 << 16) - 22))
    tail = fh.read()
    fh.seek(start)
    k = len(tail) - 22 if tail[-22:-18] == b"PK\x05\x06" else tail.rfind(b"PK\x05\x06")
    count = struct.unpack("<H", tail[k + 10:k + 12])[0] if 0 <= k <= len(tail) - 22 else None
    with zipfile.ZipFile(fh) as z:
        infos = z.infolist()
        if count is not None and count != 0xFFFF and count != len(infos):
            raise bad(f"the zip directory is damaged: its end record counts {count} "
                      f"members, it lists {len(infos)}")
        members = {}
        for info in infos:
            name = info.filename
            key = name[:-4] if name.endswith(".npy") else name
            if key in members:
                raise bad(f"the archive holds {name!r} twice")
            members[key] = info
        if "format_version" in members:
            fv = _read_member(z, members["format_version"], "format_version", size, bad)
            version = int(fv)
            if version > FORMAT_VERSION:
                raise bad(f"format version {version} was written by a newer hybridsim; "
                          f"{_SUPPORTED}")
            if version < 1:
                raise bad(f"format version {version} is not a version of the format; "
                          f"{_SUPPORTED}")
        else:
            version = 1
        need = _KEYS_V1 if version == 1 else _KEYS_V2
        missing = [k for k in need if k not in members]
        if missing:
            found = (f"format version {version}" if "format_version" in members
                     else "no format_version key (version 1 layout)")
            raise bad(f"missing {missing} for format version {version} ({found}); "
                      f"present: {sorted(members)}")
        want = [k for k in need if k != "format_version"]
        if version > 1 and "xdot" in members:
            want.append("xdot")
        if version > 1 and "choices" in members:
            want.append("choices")
        if version > 1 and any(k in members for k in _CROSSING_KEYS):
            want.extend(_CROSSING_KEYS)
            missing = [k for k in _CROSSING_KEYS if k not in members]
            if missing:
                raise bad(f"missing {missing}: an arc's crossings are stored as all of "
                          f"{list(_CROSSING_KEYS)}")
        declared = sum(members[k].file_size for k in want if k in members)
        if declared > max_bytes:
            raise bad(f"its arrays declare {declared} bytes once decompressed, more than "
                      f"max_bytes = {max_bytes}; pass max_bytes= to read a larger arc")
        # anything else is damage (a member's name changed) or another format
        extra = sorted(set(members) - set(want) - {"format_version"})
        if extra or any(not members[k].filename.endswith(".npy") for k in want):
            raise bad(f"unexpected members {extra or sorted(members)} for format version "
                      f"{version}; expected {need} (and xdot) as .npy arrays")
        return {k: _read_member(z, members[k], k, size, bad) for k in want}, version


def _regular(st, name):
    """Refuse what is not a regular file (a FIFO, a device, a socket...)."""
    if not stat.S_ISREG(st.st_mode):
        kind = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else
                "a character device" if stat.S_ISCHR(st.st_mode) else
                "a block device" if stat.S_ISBLK(st.st_mode) else
                "a socket" if stat.S_ISSOCK(st.st_mode) else
                "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file")
        raise ArcFileError(f"load: {name!r}: is {kind}, not a regular file written by "
                           f"HybridArc.save")


def _check_made(arc, where, empty_ok=False):
    """Refuse an arc no run of the engine makes (after :meth:`HybridArc.validate`)."""
    if arc.x.shape[1] == 0:
        raise ValueError(f"{where}: the state has dimension 0 (x of shape {arc.x.shape}); "
                         f"a hybrid system's state has at least one component")
    if len(arc.j) and int(arc.j.min()) < 0:
        k = int(np.argmax(arc.j < 0))
        raise ValueError(f"{where}: sample {k} has the negative jump count j = {arc.j[k]}")
    if not len(arc.t) and arc.termination is not None and not empty_ok:
        raise ValueError(f"{where}: no samples, yet the run ended {arc.termination.name}: a "
                         f"run has at least its initial sample (an empty window is "
                         f"saved without a termination cause)")


def _encode_choices(arc):
    """An explore leaf's choices as JSON, or None."""
    choices = arc.__dict__.get("choices")
    if choices is None:
        return None
    return json.dumps([[float(c.t), int(c.j), np.asarray(c.x, dtype=float).tolist(),
                        str(c.kind), c.value if c.value is None or isinstance(c.value, int)
                        else float(c.value)] for c in choices])


def _decode_choices(text, n, bad):
    """An explore leaf's choices from their JSON form, strictly."""
    try:
        raw = json.loads(text)
    except (ValueError, RecursionError):
        raw = None
    out = []
    for c in raw if isinstance(raw, list) else [None]:
        ok = isinstance(c, list) and len(c) == 5
        if ok:
            t, j, x, kind, value = c
            ok = (isinstance(t, (int, float)) and math.isfinite(t)
                  and isinstance(j, int) and not isinstance(j, bool) and j >= 0
                  and isinstance(x, list) and len(x) == n
                  and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in x)
                  and kind in _CHOICE_KINDS
                  and (value is None or (isinstance(value, (int, float))
                                         and not isinstance(value, bool))))
        if not ok:
            raise bad(f"choices are not of the expected form (a list of [t, j, x of "
                      f"{n} floats, kind in {list(_CHOICE_KINDS)}, value]): "
                      f"{str(c)[:80]}")
        out.append(Choice(float(t), j, np.array(x, dtype=float), kind, value))
    return out


def _decode_crossings(d, arc, bad):
    """An arc's crossings from their arrays, checked against the arc."""
    t, j, w, dr, x = (d[k] for k in _CROSSING_KEYS)
    k, n = len(t), arc.x.shape[1]
    if not (j.shape == w.shape == dr.shape == (k,)) or x.shape != (k, n):
        raise bad(f"crossings must be {k} rows each (crossing_x of shape ({k}, {n})), got "
                  f"shapes {[a.shape for a in (t, j, w, dr, x)]}")
    if not (np.isfinite(t).all() and np.isfinite(x).all()):
        raise bad("crossing_t and crossing_x must be finite")
    if not np.isin(dr, (-1, 1)).all():
        raise bad("crossing_direction must hold 1 (rising) or -1 (falling)")
    if k and (int(j.min()) < 0 or int(w.min()) < 0):
        raise bad("crossing_j and crossing_which must be non-negative")
    if k and len(arc.t) and not (arc.t[0] <= t.min() and t.max() <= arc.t[-1]
                                 and arc.j[0] <= j.min() and j.max() <= arc.j[-1]):
        raise bad("crossings lie outside the arc's hybrid time domain")
    return Crossings(t, j, w, dr, x)


def load(path, *, max_bytes: int = MAX_FILE_BYTES):
    """Load what :meth:`HybridArc.save` wrote: a :class:`HybridArc` (an
    explore leaf with its ``choices``). The file format holds arcs only.

    Parameters and errors as :meth:`HybridArc.load`.

    Examples
    --------
    >>> import os, tempfile, hybridsim as hs
    >>> tree = hs.explore(hs.HybridSystem.from_functions(
    ...     f=lambda x: np.array([1.0]), g=lambda x: np.array([0.0]),
    ...     C=lambda x: x[0] <= 2.0, D=lambda x: x[0] >= 1.0, state_dim=1),
    ...     [0.0], t_max=3.0, j_max=1)
    >>> path = tree.leaves[0].save(os.path.join(tempfile.mkdtemp(), "leaf"))
    >>> [str(c) for c in hs.load(path).choices]
    ['jump to successor 0 at (t=1, j=0)']
    """
    return HybridArc.load(path, max_bytes=max_bytes)


class Choice(NamedTuple):
    """A choice taken at a branch point (t, j, x).

    ``kind``: ``"jump"`` (to successor ``value`` of the jump map, 0 for a
    single-valued one; None where j_max allows no more jumps: the solution
    ends there, as :func:`hybridsim.simulate`'s), ``"flow"`` (flow on through C ∩ D) or ``"dwell"``
    (jump after ``value`` time units in C ∩ D).
    """

    t: float
    j: int
    x: np.ndarray
    kind: str
    value: float | int | None

    def __str__(self):
        at = f"(t={self.t:.10g}, j={self.j})"
        if self.kind == "jump" and self.value is None:
            return f"jump, with no jump left (j_max), at {at}"
        if self.kind == "jump":
            return f"jump to successor {self.value} at {at}"
        if self.kind == "flow":
            return f"flow on at {at}"
        return f"dwell {self.value:.10g} in C ∩ D from {at}"


class HybridArc:
    """A solution of a hybrid system on its hybrid time domain.

    Parameters
    ----------
    t, j, x : array_like, shapes (N,), (N,), (N, n)
        The samples (N may be 0: an empty arc).
    termination : Termination or None
        Why the run stopped.
    message, exception, components :
        See the attributes.
    segments : list of (t_a, t_b, j, dense), optional
        The solver's dense outputs: ``dense(s)`` is the state at s in
        [t_a, t_b] on the flow of jump count j (scipy's ``DenseOutput``
        convention: an array of m times gives an (n, m) array).
    system : HybridSystem, optional
        The system the arc solves (dropped, keeping its description, when
        the arc is pickled and the system does not pickle).
    xdot : array_like, shape (N, n), optional
        The flow map f at each sample (NaN rows where unknown, e.g. at
        samples that are not in C). Used for cubic Hermite interpolation.
    stats : dict, optional
        Statistics of the run (steps, function evaluations, events...),
        carried through :meth:`restrict`, :meth:`component` and files.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Ordinary time of each sample (non-decreasing).
    j : ndarray of int, shape (N,)
        Jump counter of each sample. A jump appears as two consecutive samples
        with the same t and j, j + 1.
    x : ndarray, shape (N, n)
        The state at each sample (time-major).
    xdot : ndarray, shape (N, n), or None
        The flow derivative at each sample where known.
    stats : dict or None
        Statistics of the run.
    termination : Termination
        Why the run stopped; ``termination.message`` explains it.
    message : str
        A sentence saying why the run stopped (with details where known).
    exception : BaseException or None
        The exception a user map raised (``termination is MAP_ERROR``).
    components : dict or None
        ``{name: slice}`` of an interconnection's parts (see :meth:`component`).
    system : HybridSystem or None
        The system, where the arc still holds it.
    system_description : str or None
        The system's class (and components), kept when the object is not.
    crossings : Crossings or None
        The crossings of the system's watched functions (``watch``, rule 11
        of :class:`hybridsim.HybridSystem`) along the run, or None where it
        watches nothing (and on arcs made from a run's: windows, components,
        transforms).

    Notes
    -----
    ``arc[name]`` is :meth:`component`; an arc is not iterable (``list(arc)``
    raises a ``TypeError`` that says where the samples are:
    ``zip(arc.t, arc.j, arc.x)`` iterates them). Pickling keeps the system
    and the dense outputs only when they pickle.

    Examples
    --------
    >>> import numpy as np
    >>> arc = HybridArc([0.0, 1.0, 1.0, 2.0], [0, 0, 1, 1],
    ...                 [[0.0], [1.0], [0.0], [1.0]], Termination.T_MAX)
    >>> arc.jump_times, arc.jump_count
    (array([1.]), 1)
    >>> arc.at(0.5), arc.at(1.0, j=0), arc.at(1.0)
    (array([0.5]), array([1.]), array([0.]))
    """

    #: the crossings of the system's watched functions (:class:`Crossings`), or
    #: None where the system watches nothing
    crossings = None

    def __init__(self, t, j, x, termination, message=None, exception=None,
                 components=None, segments=None, system=None, *, xdot=None,
                 stats=None):
        self.t = np.asarray(t, dtype=float)
        jj = np.asarray(j)
        self.j = jj.astype(np.int64)
        self.x = np.asarray(x, dtype=float)
        if self.t.ndim != 1 or self.j.ndim != 1 or self.x.ndim != 2 \
                or len(self.x) != len(self.t) or len(self.j) != len(self.t):
            raise ValueError(f"HybridArc: expected t (N,), j (N,), x (N, n); got shapes "
                             f"{self.t.shape}, {self.j.shape}, {self.x.shape}")
        if jj.dtype.kind == "f" and not np.array_equal(jj, self.j):
            raise ValueError("HybridArc: j must hold integers (jump counts), got "
                             f"non-integer values such as {jj[jj != self.j][0]!r}")
        if xdot is not None:
            xdot = np.asarray(xdot, dtype=float)
            if xdot.shape != self.x.shape:
                raise ValueError(f"HybridArc: xdot must have the shape of x, (N, n) = "
                                 f"{self.x.shape}; got {xdot.shape}")
        if stats is not None and not isinstance(stats, dict):
            raise TypeError(f"HybridArc: stats must be a dict or None, got "
                            f"{type(stats).__name__}")
        self.xdot = xdot
        self.stats = stats
        self.termination = termination
        self.message = message or (termination.message if termination else "")
        self.exception = exception
        self.components = components
        self.system = system
        self.system_description = _describe(system)
        self._segments = segments  # list of (t_a, t_b, j, dense) or None
        self._cache = {}

    @classmethod
    def _trusted(cls, t, j, x, termination, message=None, exception=None,
                 components=None, segments=None, system=None, xdot=None, stats=None,
                 description=None):
        """An arc from the engine's own output, without re-validating it.

        ``t`` (N,) float, ``j`` (N,) int64 and ``x``/``xdot`` (N, n) float
        arrays, as every integration path produces them; saves the checks of
        :meth:`__init__` (a large share of a short run in a batch of
        thousands). ``description``: ``_describe(system)``, where the caller
        keeps it.
        """
        arc = cls.__new__(cls)
        # one dict, set at once (faster than an attribute at a time: a short
        # compiled run's arc is made in about a microsecond)
        arc.__dict__ = {
            "t": t, "j": j, "x": x, "xdot": xdot, "stats": stats, "termination": termination,
            "message": message or (termination.message if termination else ""),
            "exception": exception, "components": components, "system": system,
            "system_description": description if description is not None else
            _describe(system), "_segments": segments, "_cache": {}}
        if CHECK_ARCS:
            arc.validate(where="the engine's arc")
        return arc

    @classmethod
    def _pooled(cls, pool, starts, ends, termination, message, system, stats_of):
        """Arcs of a batch's runs, run ``i``'s samples rows ``starts[i]:ends[i]``
        of the batch's compact pool ``pool = (t, j, x, xdot)`` and its stats
        ``stats_of(i)`` (a dict), made on first access: a batch of thousands
        of short runs otherwise spends most of its Python time slicing.
        ``termination`` and ``message``: one each, for every run. The arcs
        share one record of the pool (each holds its index): two objects an
        arc for the garbage collector to visit, not four.
        """
        like = {"termination": termination, "message": message, "exception": None,
                "components": None, "system": system, "system_description": _describe(system),
                "_segments": None, "_cache": None, "_pool": (pool, starts, ends, stats_of),
                "_row": 0}
        new, copy = cls.__new__, like.copy
        out = []
        for i in range(len(starts)):
            arc = new(cls)
            arc.__dict__ = d = copy()
            d["_cache"] = {}
            d["_row"] = i
            out.append(arc)
        if CHECK_ARCS:
            for arc in out:
                arc.validate(where="the engine's arc")
        return out

    def _unpool(self):
        """A pooled arc's samples and stats, set (see :meth:`_pooled`)."""
        d = self.__dict__
        pooled, i = d.get("_pool"), d.get("_row")
        # the fields are set before the keys are dropped: threads may race here
        if pooled is not None and i is not None:
            (t, j, x, xdot), starts, ends, stats_of = pooled
            a, b = starts[i], ends[i]
            self.t, self.j, self.x, self.xdot = t[a:b], j[a:b], x[a:b], xdot[a:b]
            self.stats = stats_of(i)
            d.pop("_pool", None)
            d.pop("_row", None)

    def __getattr__(self, name):
        # only for attributes not set: a pooled arc's samples and stats
        if name in _POOLED and "_pool" in self.__dict__:
            self._unpool()
            return self.__dict__[name]
        raise AttributeError(f"'{type(self).__name__}' object has no attribute {name!r}")

    def _like(self, t, j, x, *, xdot=None, segments=None, components=None,
              system=None, keep=True):
        """A new arc with other samples and this arc's run information."""
        arc = HybridArc(t, j, x, self.termination, self.message, self.exception,
                        self.components if keep else components,
                        self._segments if keep else segments,
                        self.system if keep else system, xdot=xdot,
                        stats=None if self.stats is None else dict(self.stats))
        if keep and self.system is None:
            arc.system_description = self.system_description
        return arc

    # ------------------------------------------------------------------ basics
    def __len__(self):
        return len(self.t)

    def __repr__(self):
        term = self.termination.name if self.termination else None
        if len(self.t) == 0:
            return f"<HybridArc: empty (0 samples), termination={term}>"
        return (f"<HybridArc: {len(self.t)} samples, t in [{self.t[0]:.6g}, "
                f"{self.t[-1]:.6g}], {self.jump_count} jumps, termination={term}>")

    def __iter__(self):
        raise TypeError(
            "a HybridArc is not iterable: its samples are arc.t (N,), arc.j (N,) and "
            "arc.x (N, n) (iterate rows with zip(arc.t, arc.j, arc.x)); arc[name] is "
            "a component of an interconnection (names: arc.components)")

    def __contains__(self, name):
        """True when ``name`` is a component of this interconnection's arc."""
        return bool(self.components) and name in self.components

    def __copy__(self):
        self._unpool()
        new = object.__new__(HybridArc)
        new.__dict__.update(self.__dict__)
        new._cache = {}
        return new

    def __deepcopy__(self, memo):
        import copy
        self._unpool()
        new = object.__new__(HybridArc)
        memo[id(self)] = new
        state = {k: v for k, v in self.__dict__.items() if k != "_cache"}
        new.__dict__.update(copy.deepcopy(state, memo))
        new._cache = {}
        return new

    def __getstate__(self):
        """Pickle state: the system and dense outputs only when they pickle."""
        self._unpool()
        state = self.__dict__.copy()
        state.pop("_cache", None)
        state.pop("_seg_starts", None)
        if state.get("system") is not None and not _picklable(state["system"]):
            state["system"] = None
        if state.get("_segments") and not _picklable(state["_segments"]):
            state["_segments"] = None
        exc = state.get("exception")
        if exc is not None and not _picklable(exc):
            state["exception"] = RuntimeError(f"{type(exc).__name__}: {exc}")
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.__dict__.setdefault("xdot", None)
        self.__dict__.setdefault("stats", None)
        self.__dict__.setdefault("system_description", None)
        self._cache = {}

    def _nonempty(self, what):
        if len(self.t) == 0:
            raise ValueError(f"{what}: the arc is empty (no samples)")

    @property
    def termination_cause(self):
        """Alias of :attr:`termination` (HyEQ toolbox name)."""
        return self.termination

    @property
    def success(self) -> bool:
        """True when the run stopped at t_max or j_max."""
        return bool(self.termination is not None and self.termination.success)

    @property
    def state_dim(self) -> int:
        """The length n of the state."""
        return self.x.shape[1]

    @property
    def x0(self):
        """The first sample of the state."""
        self._nonempty("x0")
        return self.x[0]

    @property
    def xf(self):
        """The last sample of the state."""
        self._nonempty("xf")
        return self.x[-1]

    @property
    def t0(self) -> float:
        """The first time."""
        self._nonempty("t0")
        return float(self.t[0])

    @property
    def tf(self) -> float:
        """The last time."""
        self._nonempty("tf")
        return float(self.t[-1])

    @property
    def jf(self) -> int:
        """The last jump count."""
        self._nonempty("jf")
        return int(self.j[-1])

    @property
    def jump_index(self):
        """Indices k of the post-jump samples (``j[k] == j[k-1] + 1``)."""
        return np.flatnonzero(np.diff(self.j) > 0) + 1

    @property
    def is_jump_start(self):
        """Boolean mask (N,): True at each pre-jump sample (the next one has j + 1).

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> arc.is_jump_start, arc.is_jump_end
        (array([False,  True, False, False]), array([False, False,  True, False]))
        """
        m = np.zeros(len(self.t), dtype=bool)
        m[self.jump_index - 1] = True
        return m

    @property
    def is_jump_end(self):
        """Boolean mask (N,): True at each post-jump sample (j one more than before)."""
        m = np.zeros(len(self.t), dtype=bool)
        m[self.jump_index] = True
        return m

    @property
    def jump_times(self):
        """Times t at which the jumps happened, shape (jump_count,)."""
        return self.t[self.jump_index]

    @property
    def jump_count(self) -> int:
        """The number of jumps, ``j[-1] - j[0]`` (0 for an empty arc)."""
        return int(self.j[-1] - self.j[0]) if len(self.j) else 0

    @property
    def flow_intervals(self):
        """List of ``(t_start, t_end, j)``: the interval [t_j, t_{j+1}] of each j."""
        if len(self.t) == 0:
            return []
        out = []
        starts = np.concatenate(([0], self.jump_index))
        ends = np.concatenate((self.jump_index - 1, [len(self.t) - 1]))
        for a, b in zip(starts, ends):
            out.append((float(self.t[a]), float(self.t[b]), int(self.j[a])))
        return out

    @property
    def flow_lengths(self):
        """Length t_{j+1} - t_j of each interval of flow, shape (jump_count + 1,)."""
        return np.array([b - a for a, b, _ in self.flow_intervals])

    # --------------------------------------------------------- interpolation
    def _dense_index(self):
        """``{j: (starts, ends, sols)}`` of the dense segments, built once."""
        idx = self._cache.get("dense")
        if idx is None:
            by_j = {}
            for a, b, jj, sol in self._segments or ():
                by_j.setdefault(int(jj), ([], [], []))
                by_j[int(jj)][0].append(a)
                by_j[int(jj)][1].append(b)
                by_j[int(jj)][2].append(sol)
            idx = {k: (np.asarray(s, float), np.asarray(e, float), f)
                   for k, (s, e, f) in by_j.items()}
            self._cache["dense"] = idx
        return idx

    def _call_dense(self, sol, ts):
        """Values of one dense output at times ``ts`` (m,), as (m, n)."""
        n = self.state_dim
        if len(ts) > 1:
            try:
                y = np.asarray(sol(ts), dtype=float)
                if y.shape == (n, len(ts)):
                    return y.T
            except Exception:  # noqa: BLE001 - a callable of scalars only: one call per time
                pass
        return np.array([np.asarray(sol(s), dtype=float).reshape(n) for s in ts])

    def _interp(self, t, j, where, deriv=False):
        """State (and d/dt where known) at the points (t[i], j[i]), 1-D arrays.

        Best available: the stored sample at its own time; the dense output;
        cubic Hermite where both neighbours have a finite xdot; else linear.
        """
        m, n = len(t), self.state_dim
        out = np.empty((m, n))
        dout = np.full((m, n), np.nan) if deriv else None
        if m == 0:
            return out, dout
        self._nonempty(where)
        uj, inv = np.unique(j, return_inverse=True)
        order = np.argsort(inv, kind="stable")
        bounds = np.searchsorted(inv[order], np.arange(len(uj) + 1))
        los = np.searchsorted(self.j, uj, side="left")
        his = np.searchsorted(self.j, uj, side="right")
        dense = self._dense_index() if self._segments else {}
        for g, jj in enumerate(uj):
            sel = order[bounds[g]:bounds[g + 1]]
            a, b = los[g], his[g]
            if a == b:
                raise ValueError(f"{where}: the arc has no sample with j={int(jj)} "
                                 f"(j runs from {self.j[0]} to {self.j[-1]})")
            ts = self.t[a:b]
            tq = t[sel]
            bad = (tq < ts[0]) | (tq > ts[-1])
            if bad.any():
                raise ValueError(
                    f"{where}: (t={tq[bad][0]}, j={int(jj)}) is not in the hybrid time "
                    f"domain (for j={int(jj)}, t lies in [{ts[0]}, {ts[-1]}])")
            k = np.searchsorted(ts, tq, side="right") - 1
            exact = ts[k] == tq
            out[sel[exact]] = self.x[a + k[exact]]
            if deriv and self.xdot is not None:
                dout[sel[exact]] = self.xdot[a + k[exact]]
            rest = np.flatnonzero(~exact)
            if rest.size == 0:
                continue
            k0 = a + k[rest]          # tq strictly between samples k0 and k0 + 1
            tr = tq[rest]
            x0, x1 = self.x[k0], self.x[k0 + 1]
            h = (self.t[k0 + 1] - self.t[k0])[:, None]
            s = ((tr - self.t[k0]) / (self.t[k0 + 1] - self.t[k0]))[:, None]
            val = (1 - s) * x0 + s * x1
            if self.xdot is not None:
                m0, m1 = self.xdot[k0], self.xdot[k0 + 1]
                herm = np.all(np.isfinite(m0), axis=1) & np.all(np.isfinite(m1), axis=1)
                if herm.any():
                    s2 = s * s
                    # written from x0 so that a constant component stays exact
                    hv = (x0 + s2 * (3 - 2 * s) * (x1 - x0)
                          + s * (1 - s) ** 2 * h * m0 + s2 * (s - 1) * h * m1)
                    val[herm] = hv[herm]
                    if deriv:
                        hd = ((6 * s2 - 6 * s) * (x0 - x1) / h
                              + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1)
                        dsel = sel[rest[herm]]
                        dout[dsel] = hd[herm]
            if jj in dense:
                starts, ends, sols = dense[int(jj)]
                q = np.searchsorted(starts, tr, side="right") - 1
                cov = (q >= 0) & (tr <= ends[np.maximum(q, 0)])
                for sq in np.unique(q[cov]):
                    pick = np.flatnonzero(cov & (q == sq))
                    val[pick] = self._call_dense(sols[sq], tr[pick])
            out[sel[rest]] = val
        return out, dout

    def _hybrid_times(self, t, j, where):
        """Validate (t, j) of :meth:`at` into flat arrays; j=None: after jumps."""
        try:
            tt = np.asarray(t, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(f"{where}: t must be a float or an array of floats, "
                            f"got {type(t).__name__}") from None
        flat = tt.ravel()
        if not np.all(np.isfinite(flat)):
            raise ValueError(f"{where}: t must be finite, got {flat[~np.isfinite(flat)][0]}")
        self._nonempty(where)
        if j is None:
            k = np.searchsorted(self.t, flat, side="right") - 1
            out = (k < 0) | (flat > self.t[-1])
            if out.any():
                raise ValueError(f"{where}: t={flat[out][0]} is outside the arc's time "
                                 f"range [{self.t[0]}, {self.t[-1]}]")
            jf = self.j[k]
        else:
            jarr = np.asarray(j)
            if jarr.dtype.kind not in "iuf" or (jarr.dtype.kind == "f" and not np.all(
                    np.mod(jarr, 1) == 0)):
                raise TypeError(f"{where}: j must be an int or an array of ints, got {j!r}")
            try:
                jf = np.broadcast_to(jarr.astype(np.int64), tt.shape).ravel()
            except ValueError:
                raise ValueError(f"{where}: j must be a scalar or have the shape of t "
                                 f"{tt.shape}, got shape {jarr.shape}") from None
        return tt, flat, jf

    def _at_scalar(self, t, j):
        """:meth:`at` for one float t and an int j or None (the fast path)."""
        T = self.t
        if not math.isfinite(t):
            raise ValueError(f"at: t must be finite, got {t}")
        self._nonempty("at")
        if j is None:
            k = int(np.searchsorted(T, t, side="right")) - 1
            if k < 0 or t > T[-1]:
                raise ValueError(f"at: t={t} is outside the arc's time range "
                                 f"[{T[0]}, {T[-1]}]")
            j = int(self.j[k])
        else:
            j = int(j)
        a = int(np.searchsorted(self.j, j, side="left"))
        b = int(np.searchsorted(self.j, j, side="right"))
        if a == b:
            raise ValueError(f"at: the arc has no sample with j={j} "
                             f"(j runs from {self.j[0]} to {self.j[-1]})")
        if t < T[a] or t > T[b - 1]:
            raise ValueError(f"at: (t={t}, j={j}) is not in the hybrid time domain "
                             f"(for j={j}, t lies in [{T[a]}, {T[b - 1]}])")
        k = a + int(np.searchsorted(T[a:b], t, side="right")) - 1
        if T[k] == t:
            return self.x[k].copy()
        if self._segments:
            seg = self._dense_index().get(j)
            if seg is not None:
                q = int(np.searchsorted(seg[0], t, side="right")) - 1
                if q >= 0 and t <= seg[1][q]:
                    return np.asarray(seg[2][q](t), dtype=float).reshape(self.state_dim)
        h = T[k + 1] - T[k]
        w = (t - T[k]) / h
        x0, x1 = self.x[k], self.x[k + 1]
        if self.xdot is not None:
            m0, m1 = self.xdot[k], self.xdot[k + 1]
            if np.isfinite(m0).all() and np.isfinite(m1).all():
                w2 = w * w
                return ((1 + 2 * w) * (1 - w) ** 2 * x0 + w * (1 - w) ** 2 * h * m0
                        + w2 * (3 - 2 * w) * x1 + w2 * (w - 1) * h * m1)
        return (1 - w) * x0 + w * x1

    def at(self, t, j=None):
        """The state at hybrid time (t, j), interpolated.

        Parameters
        ----------
        t : float or array_like of floats
            Ordinary time(s).
        j : int or array_like of int, optional
            Jump count(s): a scalar, or one per time (the shape of ``t``).
            ``None``: the last j at each t, i.e. the value after any jumps at t.

        Returns
        -------
        ndarray
            Shape (n,) for a scalar t, else ``np.shape(t) + (n,)``.

        Notes
        -----
        At a stored sample's time the stored sample is returned. Between
        samples the best available interpolant is used: the solver's dense
        output where the run kept it (``simulate(..., dense=True)``), else a
        cubic Hermite polynomial where both neighbouring samples have a finite
        :attr:`xdot` (exact for polynomial flows of degree <= 3, e.g. a
        falling ball), else linear interpolation.

        Raises
        ------
        ValueError
            When (t, j) is not in the hybrid time domain.

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> arc.at([0.25, 1.0, 1.5])[:, 0]
        array([0.25, 0.  , 0.5 ])
        >>> arc.at([1.0, 1.0], j=[0, 1])[:, 0]
        array([1., 0.])
        """
        if isinstance(t, (float, int, np.floating, np.integer)) and not isinstance(t, bool) \
                and (j is None or isinstance(j, (int, np.integer))):
            return self._at_scalar(float(t), j)
        tt, flat, jf = self._hybrid_times(t, j, "at")
        val, _ = self._interp(flat, jf, "at")
        return val.reshape(tt.shape + (self.state_dim,))

    __call__ = at

    def interpolate(self, t_grid, at_jump="end"):
        """The arc on a grid of ordinary time (HyEQ's ``interpolateToArray``).

        Parameters
        ----------
        t_grid : array_like, shape (m,)
            Non-decreasing finite times inside ``[arc.t0, arc.tf]``.
        at_jump : {"end", "start", "mean", "nan", "both"}
            The value at a time where the arc jumps: ``"end"`` after the
            jumps, ``"start"`` before them, ``"mean"`` the average of the two,
            ``"nan"`` NaN, ``"both"`` two rows (before, then after, with their
            j). Elsewhere all rules agree.

        Returns
        -------
        ArcValues
            ``(t, j, x)``: t (m,) the grid (with ``"both"`` each jump time
            twice), j (m,) the jump count used ("start": before the jumps;
            "end", "mean", "nan": after), x (m, n).

        Raises
        ------
        ValueError
            For a grid outside the arc's time range, unsorted or not finite,
            or an unknown ``at_jump``.

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> t, j, x = arc.interpolate([0.5, 1.0, 1.5], at_jump="mean")
        >>> x[:, 0], j
        (array([0.5, 0.5, 0.5]), array([0, 1, 1]))
        >>> arc.interpolate([1.0], at_jump="both").j
        array([0, 1])
        """
        if at_jump not in _AT_JUMP:
            raise ValueError(f"interpolate: at_jump must be one of {_AT_JUMP}, "
                             f"got {at_jump!r}")
        try:
            tg = np.asarray(t_grid, dtype=float)
        except (TypeError, ValueError):
            raise TypeError("interpolate: t_grid must be a 1-D array of floats, got "
                            f"{type(t_grid).__name__}") from None
        if tg.ndim == 0:
            tg = tg.reshape(1)
        if tg.ndim != 1:
            raise ValueError(f"interpolate: t_grid must be 1-D, got shape {tg.shape}")
        if not np.all(np.isfinite(tg)):
            raise ValueError("interpolate: t_grid must be finite, got "
                             f"{tg[~np.isfinite(tg)][0]}")
        if np.any(np.diff(tg) < 0):
            k = int(np.flatnonzero(np.diff(tg) < 0)[0])
            raise ValueError(f"interpolate: t_grid must be sorted (non-decreasing); "
                             f"t_grid[{k + 1}] = {tg[k + 1]} < t_grid[{k}] = {tg[k]}")
        self._nonempty("interpolate")
        if tg.size and (tg[0] < self.t[0] or tg[-1] > self.t[-1]):
            v = tg[0] if tg[0] < self.t[0] else tg[-1]
            raise ValueError(f"interpolate: t_grid value {v} is outside the arc's time "
                             f"range [{self.t[0]}, {self.t[-1]}]")
        j_start = self.j[np.searchsorted(self.t, tg, side="left")]
        j_end = self.j[np.searchsorted(self.t, tg, side="right") - 1]
        if at_jump == "both":
            rep = 1 + (j_start != j_end)
            t_out = np.repeat(tg, rep)
            j_out = np.repeat(j_end, rep)
            first = np.cumsum(rep) - rep
            j_out[first] = j_start
            x, _ = self._interp(t_out, j_out, "interpolate")
            return ArcValues(t_out, j_out, x)
        if at_jump == "start":
            x, _ = self._interp(tg, j_start, "interpolate")
            return ArcValues(tg, j_start, x)
        x, _ = self._interp(tg, j_end, "interpolate")
        jumps = j_start != j_end
        if jumps.any():
            if at_jump == "nan":
                x[jumps] = np.nan
            elif at_jump == "mean":
                xs, _ = self._interp(tg[jumps], j_start[jumps], "interpolate")
                x[jumps] = 0.5 * (x[jumps] + xs)
        return ArcValues(tg, j_end, x)

    def evaluate(self, fn):
        """Evaluate ``fn(x, t, j)`` (or ``fn(x)``, ``fn(x, t)``) at every sample.

        Returns an array of shape (N, ...) stacking the results.

        Raises
        ------
        ValueError
            fn's values have different shapes at different samples (naming
            the first sample whose shape differs from the first one's).

        Examples
        --------
        >>> arc = HybridArc([0, 1], [0, 0], [[1.0], [2.0]], None)
        >>> arc.evaluate(lambda x, t: x[0] + t)
        array([1., 3.])
        """
        from .system import as_map
        f = as_map(fn, "fn")
        vals = [np.asarray(f(x, t, j, None)) for x, t, j in zip(self.x, self.t, self.j)]
        if vals:
            s0 = vals[0].shape
            for k, v in enumerate(vals):
                if v.shape != s0:
                    raise ValueError(
                        f"evaluate: fn must return values of one shape at every sample; "
                        f"sample 0 (t={float(self.t[0])!r}, j={int(self.j[0])}) gave shape "
                        f"{s0}, sample {k} (t={float(self.t[k])!r}, j={int(self.j[k])}) shape "
                        f"{v.shape}")
        return np.array(vals)

    def transform(self, fn):
        """A new arc with the state replaced by ``fn(x, t, j)`` at each sample.

        Parameters
        ----------
        fn : callable
            ``fn(x)``, ``fn(x, t)`` or ``fn(x, t, j)`` returning a scalar or a
            1-D array of the same length at every sample.

        Returns
        -------
        HybridArc
            Same t, j, termination and stats; x of shape (N, m). Dense
            outputs are mapped through ``fn`` (so :meth:`at` stays exact);
            xdot, components and the system are dropped (they describe the
            original state).

        Raises
        ------
        ValueError
            When fn returns complex, non-numeric or non-finite values (naming
            the sample and its (t, j)), arrays of more than one dimension, or
            arrays of different lengths. Non-finite values pass only at the
            last sample of a ``NON_FINITE`` run where x itself is not finite
            (as :meth:`validate` allows); the mapped dense outputs refuse
            them too when evaluated.

        Examples
        --------
        >>> arc = HybridArc([0, 1], [0, 0], [[3.0, 4.0], [0.0, 1.0]], None)
        >>> arc.transform(lambda x: np.hypot(*x)).x[:, 0]
        array([5., 1.])
        """
        from .system import as_map
        f = as_map(fn, "transform: fn")

        def row(x, t, j, k=None):
            y = np.asarray(f(x, t, j, None))
            place = (f"(t={float(t)!r}, j={int(j)})" if k is None
                     else f"sample {k} (t={float(t)!r}, j={int(j)})")
            if np.iscomplexobj(y):
                raise ValueError(f"transform: fn returned complex values at t={t}, j={j}")
            if y.ndim > 1:
                raise ValueError(f"transform: fn must return a scalar or a 1-D array, "
                                 f"got shape {y.shape} at t={t}, j={j}")
            try:
                y = np.atleast_1d(y).astype(float)
            except (TypeError, ValueError):
                raise ValueError(f"transform: fn must return numbers, got {y!r} at "
                                 f"{place}") from None
            # NaN/inf only where validate allows them: a NON_FINITE run's last sample
            if not np.isfinite(y).all() and not (k is not None and k == last
                                                  and not np.isfinite(x).all()):
                raise ValueError(f"transform: fn returned non-finite values {y} at {place}; "
                                 f"a transformed arc holds finite states only")
            return y

        last = len(self.t) - 1 if self.termination is Termination.NON_FINITE else None
        rows = [row(x, t, j, k) for k, (x, t, j) in enumerate(zip(self.x, self.t, self.j))]
        if rows and len({r.shape for r in rows}) > 1:
            raise ValueError("transform: fn must return arrays of one length, got "
                             f"lengths {sorted({len(r) for r in rows})}")
        X = np.array(rows, dtype=float) if rows else np.zeros((0, 0))
        segs = None if not self._segments else [
            (a, b, jj, _Mapped(sol, row, jj)) for (a, b, jj, sol) in self._segments]
        arc = self._like(self.t, self.j, X, keep=False, segments=segs)
        arc.system_description = None
        return arc

    # ------------------------------------------------------------ selection
    def _subset(self, mask):
        mask = np.asarray(mask, dtype=bool)
        return self._like(self.t[mask], self.j[mask], self.x[mask],
                          xdot=None if self.xdot is None else self.xdot[mask])

    @staticmethod
    def _window(w, what, where, integer):
        """``(lo, hi)`` from a pair (None: unbounded) or, for j, one int."""
        if w is None:
            return -math.inf, math.inf
        if integer and isinstance(w, (numbers.Integral, np.integer)) \
                and not isinstance(w, bool):
            return int(w), int(w)
        if isinstance(w, (str, bytes)) or np.ndim(w) != 1 or len(w) != 2:
            kind = "an int or a pair (lo, hi) of ints" if integer else \
                "a pair (a, b) of times (a closed interval)"
            hint = "" if integer else (
                f"; for the state at one time use arc.at({w!r})"
                if isinstance(w, numbers.Real) else "")
            raise TypeError(f"{where}: {what} must be {kind}, got {w!r}{hint}")
        lo, hi = w
        out = []
        for v, inf in ((lo, -math.inf), (hi, math.inf)):
            if v is None:
                out.append(inf)
                continue
            if not isinstance(v, (numbers.Real, np.integer, np.floating)) \
                    or isinstance(v, bool) or math.isnan(v):
                raise TypeError(f"{where}: {what} bounds must be numbers or None, "
                                f"got {w!r}")
            if integer and v != math.floor(v) and math.isfinite(v):
                raise TypeError(f"{where}: {what} bounds must be ints, got {w!r}")
            out.append(float(v))
        if out[0] > out[1]:
            raise ValueError(f"{where}: {what} = {w!r} is empty (lower bound above "
                             f"upper bound)")
        return out[0], out[1]

    def restrict(self, t=None, j=None):
        """The arc on a window of hybrid time: t in [a, b] and j in [lo, hi].

        Parameters
        ----------
        t : (float, float), optional
            Closed interval [a, b] of ordinary time (``None`` for an open end).
        j : int or (int, int), optional
            One jump count, or a closed range of them.

        Returns
        -------
        HybridArc
            The stored samples in the window, plus samples interpolated (as by
            :meth:`at`) at a and b where they fall inside a flow between
            stored samples; empty (0 samples) when the window does not meet
            the hybrid time domain. Termination, components, system, dense
            outputs and stats are kept. Never raises for a valid window.

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> r = arc.restrict(t=(0.5, 1.5))
        >>> r.t, r.j, r.x[:, 0]
        (array([0.5, 1. , 1. , 1.5]), array([0, 0, 1, 1]), array([0.5, 1. , 0. , 0.5]))
        >>> len(arc.restrict(t=(0.2, 0.4), j=1))
        0
        """
        return self._restrict(t, j, "restrict")

    def _restrict(self, t, j, where):
        a, b = self._window(t, "t", where, integer=False)
        lo, hi = self._window(j, "j", where, integer=True)
        mask = (self.t >= a) & (self.t <= b) & (self.j >= lo) & (self.j <= hi)
        extra_t = []
        if len(self.t):
            for s in sorted({a, b}):
                if not (self.t[0] < s < self.t[-1]):
                    continue
                k = int(np.searchsorted(self.t, s, side="right")) - 1
                if self.t[k] != s and lo <= self.j[k] <= hi:
                    extra_t.append(s)  # strictly inside the flow of sample k
        if not extra_t:
            return self._subset(mask)
        et = np.array(extra_t)
        ej = self.j[np.searchsorted(self.t, et, side="right") - 1]
        ex, ed = self._interp(et, ej, where, deriv=self.xdot is not None)
        idx = np.flatnonzero(mask)
        T = np.concatenate((self.t[idx], et))
        J = np.concatenate((self.j[idx], ej))
        X = np.concatenate((self.x[idx], ex))
        order = np.lexsort((J, T))
        XD = None if self.xdot is None else np.concatenate((self.xdot[idx], ed))[order]
        return self._like(T[order], J[order], X[order], xdot=XD)

    def select(self, t=None, j=None):
        """The arc on a window of hybrid time; like :meth:`restrict` but raises
        when the window does not meet the hybrid time domain.

        Parameters
        ----------
        t : (float, float), optional
            Closed interval [a, b] of ordinary time.
        j : int or (int, int), optional
            One jump count, or a closed range of them.

        Raises
        ------
        TypeError
            When ``t`` is not an (a, b) pair (``select(t=5)``).
        ValueError
            When no (t, j) of the arc's domain lies in the window.

        Examples
        --------
        >>> arc = HybridArc([0, 1, 1, 2], [0, 0, 1, 1], [[0], [1], [0], [1]], None)
        >>> arc.select(j=1).t
        array([1., 2.])
        """
        r = self._restrict(t, j, "select")
        if len(r) == 0:
            dom = ("the arc is empty" if len(self.t) == 0 else
                   f"the arc has t in [{self.t[0]}, {self.t[-1]}], j in "
                   f"[{self.j[0]}, {self.j[-1]}]")
            raise ValueError(f"select: no sample with t in {t} and j in {j}: the window "
                             f"does not meet the hybrid time domain ({dom})")
        return r

    # ---------------------------------------------------------- components
    def component(self, name):
        """The part of an interconnection's state named ``name``, as an arc.

        Examples
        --------
        >>> arc = HybridArc([0.0], [0], [[1.0, 2.0]], None,
        ...                 components={"a": slice(0, 1), "b": slice(1, 2)})
        >>> arc["b"].x
        array([[2.]])
        """
        if not self.components:
            raise KeyError("component: this arc is not the solution of an "
                           "interconnection (it has no named components)")
        if name not in self.components:
            raise KeyError(f"component: no component named {name!r}; "
                           f"have {list(self.components)}")
        sl = self.components[name]
        sub = self.system.systems[name] if self.system is not None and hasattr(
            self.system, "systems") else None
        segs = None if not self._segments else [
            (a, b, j, _Sliced(sol, sl)) for (a, b, j, sol) in self._segments]
        arc = self._like(self.t, self.j, self.x[:, sl], keep=False, segments=segs,
                         components=getattr(sub, "components", None), system=sub,
                         xdot=None if self.xdot is None else self.xdot[:, sl])
        if sub is None and self.system_description is not None:
            arc.system_description = f"component {name!r} of {self.system_description}"
        return arc

    def __getitem__(self, name):
        return self.component(name)

    def _dropped(self, what):
        if self.system_description is not None:
            return (f"{what}: this arc no longer holds its system ({self.system_description}):"
                    f" an arc loaded from a file, or pickled with a system that does not "
                    f"pickle (e.g. one holding a lambda), keeps only its description; "
                    f"evaluate arc.evaluate(system.output) with the system at hand, or "
                    f"write the system's maps as module-level functions or methods so "
                    f"that it pickles")
        return (f"{what}: the arc does not know its system (built without one); "
                f"evaluate arc.evaluate(system.output) instead")

    def outputs(self, name=None):
        """The output map evaluated along the arc, shape (N, q).

        ``name`` selects a component of an interconnection. Needs the system:
        an arc loaded from a file, or pickled with a system that does not
        pickle, raises a ``ValueError`` saying so.
        """
        if name is not None and self.system is not None and hasattr(self.system, "outputs"):
            # through the interconnection: feedthrough outputs see their inputs
            out = self.system.outputs
            return np.array([np.atleast_1d(np.asarray(out(x, t, j)[name], dtype=float))
                             for x, t, j in zip(self.x, self.t, self.j)])
        if self.system is None:
            raise ValueError(self._dropped("outputs"))
        arc = self.component(name) if name is not None else self
        if arc.system is None:
            raise ValueError(arc._dropped("outputs"))
        c = arc.system._compile()
        if c.h_u:
            raise ValueError("outputs: this system's output reads its input u, which the "
                             "arc does not know; evaluate it through its interconnection")
        return np.array([np.atleast_1d(np.asarray(c.h(x, t, j, None), dtype=float))
                         for x, t, j in zip(arc.x, arc.t, arc.j)])

    # ----------------------------------------------------------------- checks
    def validate(self, *, t_max=None, j_max=None, where="validate"):
        """Check the invariants of a hybrid arc; return self, or raise ValueError.

        Vectorized and O(N): cheap enough to run after every simulation.

        Parameters
        ----------
        t_max : float, optional
            The run's ``t_max``: no sample after it, and a run that ended
            ``T_MAX`` has its last sample at ``t_max``.
        j_max : int, optional
            The run's ``j_max``: at most that many jumps, and a run that
            ended ``J_MAX`` made exactly ``j_max``.
        where : str, optional
            Prefix of the error messages.

        Returns
        -------
        HybridArc
            ``self``, so that ``arc.validate()`` chains.

        Raises
        ------
        ValueError
            At the first sample k that breaks one of (message naming k and
            its (t, j)): shapes t (N,), j (N,) of ints, x (N, n), xdot
            (N, n); t finite and non-decreasing; j stepping by 0 or 1; a jump
            (j + 1) at the t of the sample before it; no duplicate sample
            (same t and j as the one before); x finite (except the last
            sample of a run that ended ``NON_FINITE``); the limits above.

        Examples
        --------
        >>> HybridArc([0, 1], [0, 0], [[0], [1]], Termination.T_MAX).validate(t_max=1).t
        array([0., 1.])
        >>> HybridArc([0, 1, 1], [0, 0, 0], [[0], [1], [1]], None).validate()
        ... # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        ValueError: validate: sample 2 (t=1.0, j=0) repeats the sample before it ...
        """
        from .options import check_count, check_real
        if t_max is not None:
            t_max = check_real("t_max", t_max, allow_inf=True)
        if j_max is not None:
            j_max = check_count("j_max", j_max, allow_inf=True)
        t, j, x, xdot = self.t, self.j, self.x, self.xdot
        shapes = (getattr(t, "shape", None), getattr(j, "shape", None),
                  getattr(x, "shape", None), getattr(xdot, "shape", None))
        if not (isinstance(t, np.ndarray) and isinstance(j, np.ndarray)
                and isinstance(x, np.ndarray) and t.ndim == 1 and j.shape == t.shape
                and x.ndim == 2 and len(x) == len(t)
                and (xdot is None or (isinstance(xdot, np.ndarray)
                                      and xdot.shape == x.shape))):
            raise ValueError(f"{where}: expected t (N,), j (N,), x (N, n) and xdot None or "
                             f"(N, n) arrays; got shapes t {shapes[0]}, j {shapes[1]}, "
                             f"x {shapes[2]}, xdot {shapes[3]}")
        if j.dtype.kind not in "iu" or t.dtype.kind not in "iuf" or x.dtype.kind not in "iuf":
            raise ValueError(f"{where}: expected t and x of floats and j of ints; got "
                             f"dtypes t {t.dtype}, j {j.dtype}, x {x.dtype}")
        n = len(t)
        if n == 0:
            return self

        def at(k):
            return f"sample {k} (t={float(t[k])!r}, j={int(j[k])})"

        # one mask per check over the samples; the first sample any breaks is named
        dt, dj = np.diff(t), np.diff(j)
        bad_x = ~np.all(np.isfinite(x), axis=1)
        if self.termination is Termination.NON_FINITE:
            bad_x[-1] = False                 # the state that stopped the run
        first = np.inf, None
        checks = (
            (~np.isfinite(t), 0,
             lambda k: f"t[{k}] = {t[k]} is not finite at {at(k)}"),
            (dt < 0, 1,
             lambda k: f"t goes backwards at sample {k} (t[{k - 1}] = {t[k - 1]}, "
                       f"t[{k}] = {t[k]}; j = {j[k]})"),
            ((dj != 0) & (dj != 1), 1,
             lambda k: f"j must increase by 0 or 1 between samples; j[{k - 1}] = "
                       f"{j[k - 1]}, j[{k}] = {j[k]} at {at(k)}"),
            ((dj == 1) & (dt != 0), 1,
             lambda k: f"the jump at sample {k} (j {j[k - 1]} -> {j[k]}) changes t "
                       f"({t[k - 1]} -> {t[k]}); a jump keeps t"),
            ((dj == 0) & (dt == 0), 1,
             lambda k: f"{at(k)} repeats the sample before it (same t and j): a "
                       f"duplicate sample"),
            (bad_x, 0,
             lambda k: f"x[{k}] (t = {t[k]}, j = {j[k]}) is not finite: {x[k]}"),
        )
        for mask, shift, msg in checks:
            hit = np.flatnonzero(mask)
            if hit.size and hit[0] + shift < first[0]:
                first = int(hit[0]) + shift, msg
        if first[1] is not None:
            raise ValueError(f"{where}: {first[1](first[0])}")
        # where the run's limits are known: no sample beyond, the cause's sample at them
        term = self.termination
        if t_max is not None:
            over = np.flatnonzero(t > t_max)
            if over.size:
                raise ValueError(f"{where}: {at(int(over[0]))} lies after t_max = {t_max}")
            if term is Termination.T_MAX and t[-1] != t_max:
                raise ValueError(f"{where}: the run ended T_MAX but its last {at(n - 1)} "
                                 f"is not at t_max = {t_max}")
        if j_max is not None:
            count = j - j[0]
            over = np.flatnonzero(count > j_max)
            if over.size:
                raise ValueError(f"{where}: {at(int(over[0]))} is after jump "
                                 f"{int(count[over[0]])}, beyond j_max = {j_max}")
            if term is Termination.J_MAX and count[-1] != j_max:
                raise ValueError(f"{where}: the run ended J_MAX but its last {at(n - 1)} "
                                 f"is after {int(count[-1])} jumps, not j_max = {j_max}")
        return self

    # ----------------------------------------------------------------- I/O
    @staticmethod
    def _npz_path(path, where="save"):
        """The file to write: ``.npz`` appended when missing; never a directory."""
        if hasattr(path, "write") or hasattr(path, "read"):
            return path
        raw = os.fsdecode(os.fspath(path))
        p = Path(raw)
        seps = tuple(s for s in (os.sep, os.altsep) if s)
        if raw.endswith(seps) or p.is_dir():
            raise IsADirectoryError(f"{where}: {raw!r} is a directory; give a file name "
                                    f"such as {str(p / 'arc.npz')!r}")
        target = p if p.suffix == ".npz" else p.with_name(p.name + ".npz")
        if target.is_dir():
            raise IsADirectoryError(f"{where}: {str(target)!r} is a directory; give "
                                    f"another file name")
        return target

    def save(self, path):
        """Validate the arc and save it to an ``.npz`` file (format :data:`FORMAT_VERSION`).

        Parameters
        ----------
        path : str, path-like or binary file
            ``.npz`` is appended when missing (as :meth:`load` does).

        Returns
        -------
        pathlib.Path or the file object
            Where the arc was written.

        Raises
        ------
        ValueError
            When the arc is not valid (:meth:`validate`), or not one the
            engine makes (a state of dimension 0, a negative jump count);
            nothing is written.
        IsADirectoryError
            When ``path`` names a directory (``"results/"``, an existing
            directory, or one named ``path + ".npz"``).

        Notes
        -----
        Stores t, j, x, the termination and message, the components (any
        names of str, int, float or tuples of them), xdot and stats (as JSON)
        when present, the system's description, an explore leaf's
        ``choices``, and the :attr:`crossings` of watched functions. Not
        stored: the system, the dense outputs, the exception (its text is in
        the message); an empty arc (a window with no
        samples) is stored without its termination cause.

        Examples
        --------
        >>> import tempfile, os
        >>> arc = HybridArc([0, 1], [0, 0], [[0.0], [1.0]], Termination.T_MAX)
        >>> d = tempfile.mkdtemp()
        >>> arc.save(os.path.join(d, "run")).name
        'run.npz'
        >>> HybridArc.load(os.path.join(d, "run")).x[:, 0]
        array([0., 1.])
        """
        target = self._npz_path(path)
        self.validate(where="save")
        _check_made(self, "save", empty_ok=True)
        comps = [] if not self.components else [
            [_encode_name(k), s.start, s.stop] for k, s in self.components.items()]
        # an empty window (restrict) has no end: saved without a cause
        term = self.termination.name if self.termination and len(self.t) else ""
        data = dict(
            format_version=np.array(FORMAT_VERSION, dtype=np.int64),
            t=self.t, j=self.j, x=self.x,
            termination=np.array(term),
            message=np.array(self.message or ""),
            components=np.array(json.dumps(comps)),
            stats=np.array("" if self.stats is None else
                           json.dumps(self.stats, default=_json_default)),
            system_description=np.array(self.system_description or ""))
        if self.xdot is not None:
            data["xdot"] = self.xdot
        choices = _encode_choices(self)
        if choices is not None:
            data["choices"] = np.array(choices)
        c = self.crossings
        if c is not None:
            data.update(crossing_t=c.t, crossing_j=c.j, crossing_which=c.which,
                        crossing_direction=c.direction, crossing_x=c.x)
        np.savez_compressed(target, **data)
        return target

    @classmethod
    def load(cls, path, *, max_bytes: int = MAX_FILE_BYTES):
        """Load and validate an arc written by :meth:`save`.

        Parameters
        ----------
        path : str, path-like or binary file
            When ``path`` does not exist and ``path + ".npz"`` does, that file.
            It must be a regular file (or a symlink to one): a FIFO, a
            device (``/dev/zero``), a socket or a directory is refused before
            anything is read.
        max_bytes : int
            The most the file, and its arrays once decompressed, may hold
            (default :data:`MAX_FILE_BYTES`, 16 GiB).

        Returns
        -------
        HybridArc
            With ``system`` None (``system_description`` says what it was).

        Raises
        ------
        FileNotFoundError
            When neither ``path`` nor ``path.npz`` exists.
        ArcFileError
            (a ``ValueError``) naming the file and what is wrong, for every
            damaged, foreign or crafted file: truncated or corrupt, not an
            ``.npz`` archive, a damaged zip directory, missing or unexpected
            arrays (naming them and the format version found), an
            unsupported ``format_version`` (not an int among the versions
            this hybridsim reads), arrays of the wrong
            dtype or shape or declaring more data than they hold, object
            arrays (pickled data is never loaded), components/stats that are
            not JSON of the expected form, an unknown termination name,
            samples that break :meth:`validate`, and arcs no run of the
            engine makes (a state of dimension 0, a negative jump count, no
            samples with a termination cause); a path that is not a regular
            file, or more than ``max_bytes``.

        Examples
        --------
        See :meth:`save`.
        """
        if isinstance(max_bytes, bool) or not isinstance(max_bytes, (int, np.integer)) \
                or max_bytes < 1:
            raise ValueError(f"load: max_bytes must be a positive int, got {max_bytes!r}")
        if hasattr(path, "read"):
            name = getattr(path, "name", repr(path))
            try:
                fd = path.fileno()
            except (AttributeError, OSError, ValueError):
                fd = None                   # in memory (BytesIO): bounded already
            if fd is not None:
                _regular(os.fstat(fd), name)
            return cls._load_from(path, name, max_bytes)
        p = Path(os.fspath(path))
        if not p.exists() and p.suffix != ".npz" and p.with_name(p.name + ".npz").exists():
            p = p.with_name(p.name + ".npz")
        if not p.exists():
            raise FileNotFoundError(f"load: no such file {str(p)!r}"
                                    + ("" if p.suffix == ".npz" else " (nor with .npz)"))
        # opened without blocking (a FIFO with no writer) and checked before a
        # byte is read: a device or a pipe never ends
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
        try:
            _regular(os.fstat(fd), str(p))
        except BaseException:
            os.close(fd)
            raise
        with os.fdopen(fd, "rb") as fh:
            return cls._load_from(fh, str(p), max_bytes)

    @classmethod
    def _load_from(cls, fh, name, max_bytes=MAX_FILE_BYTES):
        def bad(msg):
            return ArcFileError(f"load: {name!r}: {msg}")

        try:
            arrays, version = _read_npz(fh, bad, max_bytes)
            return cls._from_arrays(arrays, version, bad)
        except ArcFileError:
            raise
        except Exception as e:  # whatever else a damaged file raises: named
            raise bad(f"not a readable HybridArc .npz file (truncated or corrupt?): "
                      f"{type(e).__name__}: {e}") from e

    @classmethod
    def _from_arrays(cls, d, version, bad):
        def scalar_str(key):
            v = d[key].item()
            return v.decode("utf-8") if isinstance(v, bytes) else str(v)

        def from_json(key):
            s = scalar_str(key)
            try:
                return json.loads(s) if s else None
            except (ValueError, RecursionError) as e:
                why = "nested too deeply" if isinstance(e, RecursionError) else str(e)
                raise bad(f"components/stats are not valid JSON of the expected form "
                          f"({key}: {why})") from None

        t, j, x = d["t"], d["j"], d["x"]
        if j.shape != t.shape:
            raise bad(f"j must be an integer array of shape {t.shape}, got dtype "
                      f"{j.dtype}, shape {j.shape}")
        if len(x) != len(t):
            raise bad(f"x must be a float array of shape (N, n) with N = {len(t)}, got "
                      f"dtype {x.dtype}, shape {x.shape}")
        if len(j) and j.dtype.kind == "f" and not (
                np.all(np.isfinite(j)) and np.all(np.mod(j, 1) == 0)
                and np.all(np.abs(j) < 2.0 ** 53)):
            raise bad("j must hold integers (jump counts)")
        if len(j) and j.dtype.kind == "u" and j.max() > np.iinfo(np.int64).max:
            raise bad(f"j holds a jump count {j.max()} beyond int64")
        term = scalar_str("termination")
        if term and term not in Termination.__members__:
            raise bad(f"unknown termination {term!r}; known: {list(Termination.__members__)}")
        message = scalar_str("message")
        n = x.shape[1]
        if version == 1:
            names, bounds = d["comp_names"], d["comp_bounds"]
            if bounds.shape != (len(names), 2):
                raise bad(f"comp_bounds must have shape ({len(names)}, 2), got {bounds.shape}")
            raw = [[k.item(), int(a), int(b)] for k, (a, b) in zip(names, bounds)]
            xdot, stats, desc = None, None, None
        else:
            raw = from_json("components")
            stats = from_json("stats")
            if stats is not None and not isinstance(stats, dict):
                raise bad(f"stats must be a JSON object, got {type(stats).__name__}")
            xdot = d.get("xdot")
            if xdot is not None and xdot.shape != x.shape:
                raise bad(f"xdot must have the shape of x {x.shape}, got {xdot.shape}")
            desc = scalar_str("system_description") or None
        if not isinstance(raw, list) or not all(
                isinstance(c, list) and len(c) == 3 for c in raw):
            raise bad(f"components/stats are not valid JSON of the expected form "
                      f"(components: a list of [name, start, stop], got {str(raw)[:80]})")
        comps = {}
        for k, a, b in raw:
            try:
                k = _decode_name(k) if version > 1 else str(k)
            except (KeyError, TypeError, ValueError, RecursionError):
                raise bad(f"component name {str(k)[:80]} is not of the expected form "
                          f"(str, int, float, bool, null, or a tuple/str object)") from None
            ints = all(isinstance(v, (int, np.integer)) and not isinstance(v, bool)
                       for v in (a, b))
            if not ints or not (0 <= a <= b <= n):
                raise bad(f"component {k!r} has bounds ({a}, {b}) outside the state of "
                          f"length {n}" if ints else
                          f"component {k!r} has bounds ({a!r}, {b!r}) that are not ints")
            if k in comps:
                raise bad(f"component {k!r} appears twice")
            comps[k] = slice(int(a), int(b))
        arc = cls(t, j, x, Termination[term] if term else None, message,
                  components=comps or None, xdot=xdot, stats=stats)
        arc.system_description = desc
        try:
            arc.validate(where="")
            _check_made(arc, "")
        except ValueError as e:
            raise bad(str(e)[2:]) from None
        if "choices" in d:
            arc.choices = _decode_choices(scalar_str("choices"), n, bad)
        if "crossing_t" in d:
            arc.crossings = _decode_crossings(d, arc, bad)
        return arc

    def to_pandas(self, names=None):
        """A pandas DataFrame with columns t, j and one per state component.

        Requires the optional ``pandas`` extra.
        """
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover
            raise ImportError("to_pandas needs pandas: pip install 'hybridsim[pandas]'") from e
        n = self.state_dim
        if names is None:
            names = [f"x{i}" for i in range(n)]
            if self.components:
                names = [None] * n
                for cname, sl in self.components.items():
                    for k, i in enumerate(range(*sl.indices(n))):
                        names[i] = f"{cname}[{k}]"
        if len(names) != n:
            raise ValueError(f"to_pandas: names must have length {n}, got {len(names)}")
        df = pd.DataFrame(self.x, columns=list(names))
        df.insert(0, "j", self.j)
        df.insert(0, "t", self.t)
        return df


class _Sliced:
    """A dense output restricted to a slice of the state."""

    __slots__ = ("sol", "sl")

    def __init__(self, sol, sl):
        self.sol, self.sl = sol, sl

    def __call__(self, t):
        return np.asarray(self.sol(t))[self.sl]


class _Mapped:
    """A dense output mapped through ``fn(x, t, j)`` (see :meth:`HybridArc.transform`)."""

    __slots__ = ("sol", "fn", "j")

    def __init__(self, sol, fn, j):
        self.sol, self.fn, self.j = sol, fn, j

    def __call__(self, t):
        if np.ndim(t) == 0:
            return self.fn(np.asarray(self.sol(t), dtype=float), float(t), self.j)
        t = np.asarray(t, dtype=float)
        return np.stack([self.fn(np.asarray(self.sol(s), dtype=float), float(s), self.j)
                         for s in t], axis=1)


def _one_sample(x0, kwargs, cause, detail, exc=None, system=None):
    """A one-sample arc at (t0, j0, x0) ending with ``cause`` (x0 None: unknown)."""
    try:
        x = np.empty((1, 0)) if x0 is None else np.array(x0, dtype=float).reshape(1, -1)
    except (TypeError, ValueError):
        x = np.empty((1, 0))
    return HybridArc([float(kwargs.get("t0", 0.0))], [int(kwargs.get("j0", 0))], x, cause,
                     f"{cause.message}: {detail}", exc,
                     components=getattr(system, "components", None), system=system)
