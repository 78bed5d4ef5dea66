"""The folders the compiled path reads generated code from, checked private.

numba's disk cache and the specialised kernels' modules are code this
process runs: a folder another user can write to lets that user run code in
every process that reads it (a planted numba index is a pickle). The engine
reads them only from a folder owned by the user (or root) and writable by no
one else, under folders writable by no one else unless sticky (as ``/tmp``:
others cannot replace what is in it). Needs no numba.

Examples
--------
>>> import os, tempfile
>>> d = os.path.join(tempfile.mkdtemp(), "cache")
>>> private_folder(d) is None            # made, mode 0700
True
>>> os.chmod(d, 0o777)
>>> "writable by others" in private_folder(d)
True
"""
from __future__ import annotations

import os
import stat

__all__ = ["private_folder", "unsafe"]


def _owner_ok(st):
    return st.st_uid in (os.getuid(), 0)


def _check(path, strict):
    try:
        st = os.stat(path)
    except OSError as e:
        return f"{path}: {e.strerror}"
    if not stat.S_ISDIR(st.st_mode):
        return f"{path} is not a folder"
    if not _owner_ok(st):
        return f"{path} belongs to another user (uid {st.st_uid})"
    mode = st.st_mode
    writers = mode & (0o022 if not _own_group(st.st_gid) else 0o002)
    if writers and (strict or not mode & stat.S_ISVTX):
        who = "others" if mode & 0o002 else "its group"
        return f"{path} is writable by {who} (mode {oct(mode & 0o7777)})"
    return None


def _own_group(gid):
    """Whether the group ``gid`` is the user's own private group (its primary
    group, named as the user, with no other members: the convention under
    which a umask of 002 makes folders group-writable harmlessly)."""
    try:
        import grp
        import pwd
        user = pwd.getpwuid(os.getuid()).pw_name
        g = grp.getgrgid(gid)
    except (ImportError, KeyError, OSError):
        return False
    return gid == os.getgid() and g.gr_name == user and set(g.gr_mem) <= {user}


def unsafe(path):
    """Why code read from the folder ``path`` could be someone else's, or None.

    The folder must be owned by the user (or root) and writable by no one
    else (its group may write where it is the user's own private group);
    each folder above it (as written and with links resolved) owned
    by the user or root and writable by no one else unless sticky.
    On systems without POSIX owners (Windows) the answer is None.
    """
    if not hasattr(os, "getuid"):
        return None
    path = os.path.abspath(path)
    for p in dict.fromkeys((path, os.path.realpath(path))):
        why = _check(p, True)
        while why is None:
            parent = os.path.dirname(p)
            if parent == p:
                break
            p = parent
            why = _check(p, False)
        if why is not None:
            return why
    return None


def private_folder(path):
    """Make the folder ``path`` (mode 0700 where new); None where it is private
    (:func:`unsafe`), else why not (it is then not to be read from)."""
    try:
        os.makedirs(path, mode=0o700, exist_ok=True)
    except OSError as e:
        return f"{path}: {e.strerror}"
    return unsafe(path)
