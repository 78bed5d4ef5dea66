"""The ``.npz`` file format of a :class:`hybridsim.HybridArc`: its version
and layout, the validating reader (every array checked against its spec
before its data is read; nothing unpickled) and the writer behind
:meth:`~hybridsim.HybridArc.save` and :meth:`~hybridsim.HybridArc.load`.
A base class of :class:`hybridsim.HybridArc` holds the methods.
"""
from __future__ import annotations

import json
import math
import os
import stat
import struct
import zipfile
from pathlib import Path

import numpy as np

from ._arc_checks import _check_made
from ._arc_records import Choice, Crossings
from .rules import Termination

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

_KEYS_V1 = ("t", "j", "x", "termination", "message", "comp_names", "comp_bounds")
_KEYS_V2 = ("format_version", "t", "j", "x", "termination", "message",
            "components", "stats", "system_description")


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


class _ArcFile:
    """Saving and loading an arc (a base of :class:`HybridArc`)."""

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

    def _save(self, path):
        """:meth:`HybridArc.save`."""
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
    def _load(cls, path, max_bytes):
        """:meth:`HybridArc.load`."""
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
