"""Caches that cannot be turned against their user (issue 45).

The compiled path runs code it reads from disk: numba's cache of the
engine's kernels (index files are pickles) and the specialised kernels'
generated modules. Each attack of the issue, tried here: a cache folder
others can write to, a planted ``.pyc`` beside a checked module, a symlink at
the temporary name a module used to be written under, and a planted numba
index. None of them runs the attacker's code, and the engine says why it
does not use such a folder.
"""
import importlib.util
import marshal
import os
import subprocess
import sys
import textwrap

import pytest

numba = pytest.importorskip("numba", reason="the compiled path needs numba "
                                            "(pip install 'hybridsim[fast]')")

from hybridsim.compiled import _cache as k  # noqa: E402
from hybridsim.compiled._private import private_folder, unsafe  # noqa: E402

posix = pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX owners and modes")
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _key(c):
    return c * 32


@pytest.fixture
def spec_dirs(tmp_path, monkeypatch):
    """``_spec_dirs`` patched to the folders a test names (a list to fill)."""
    dirs = []
    monkeypatch.setattr(k, "_spec_dirs", lambda: [str(d) for d in dirs])
    yield dirs
    for name in [m for m in sys.modules if m.startswith("hybridsim_spec_")]:
        if len(name) == len("hybridsim_spec_") + 32 and name[-32:] in (
                _key("e"), _key("f"), _key("a"), _key("b")):
            sys.modules.pop(name)


# ------------------------------------------------------------------ folders
@posix
def test_a_folder_others_can_write_is_unsafe(tmp_path, monkeypatch):
    import hybridsim.compiled._private as priv
    d = tmp_path / "cache"
    assert private_folder(str(d)) is None and (d.stat().st_mode & 0o777) == 0o700
    os.chmod(d, 0o777)
    assert "writable by others" in unsafe(str(d))
    os.chmod(d, 0o770)
    # its group may write only where that is the user's own private group (umask 002)
    monkeypatch.setattr(priv, "_own_group", lambda gid: False)
    assert "writable by its group" in unsafe(str(d))
    monkeypatch.setattr(priv, "_own_group", lambda gid: True)
    assert unsafe(str(d)) is None
    monkeypatch.undo()
    os.chmod(d, 0o755)
    assert unsafe(str(d)) is None
    # a folder above it that others can write (not sticky) could swap it
    os.chmod(tmp_path, 0o777)
    try:
        assert "writable by others" in unsafe(str(d))
        os.chmod(tmp_path, 0o1777)              # sticky, as /tmp: nothing can be swapped
        assert unsafe(str(d)) is None
    finally:
        os.chmod(tmp_path, 0o755)
    (tmp_path / "file").write_text("")
    assert "not a folder" in unsafe(str(tmp_path / "file"))


@posix
def test_a_shared_spec_folder_is_passed_over_for_a_private_one(tmp_path, spec_dirs):
    shared, mine = tmp_path / "shared", tmp_path / "mine"
    shared.mkdir()
    os.chmod(shared, 0o777)
    spec_dirs += [shared, mine]
    mod = k.spec_module(_key("e"))
    assert mod is not None and os.path.dirname(mod.__file__) == str(mine)
    assert list(shared.iterdir()) == []                 # nothing written or read there
    assert (mine.stat().st_mode & 0o022) == 0


# ------------------------------------------------------------------ planted code
def test_a_planted_pyc_beside_a_checked_module_is_never_run(tmp_path, spec_dirs):
    """The module's text is checked, then that text itself is run: a ``.pyc``
    in ``__pycache__`` that the import system would pick (its stamp matching
    the source) is not."""
    d = tmp_path / "spec"
    spec_dirs.append(d)
    key = _key("f")
    name = f"hybridsim_spec_{key}"
    mod = k.spec_module(key)                    # written (and run) once, as the engine does
    sys.modules.pop(name)
    src = d / f"{name}.py"
    marker = tmp_path / "pwned"
    code = compile(f"open({str(marker)!r}, 'w').close()\nf = g = None\none = None\n",
                   str(src), "exec")
    st = src.stat()
    pyc = importlib.util.cache_from_source(str(src))
    os.makedirs(os.path.dirname(pyc), exist_ok=True)
    with open(pyc, "wb") as fh:                 # a valid timestamp pyc for the source
        fh.write(importlib.util.MAGIC_NUMBER + b"\0\0\0\0"
                 + int(st.st_mtime).to_bytes(4, "little")
                 + (st.st_size & 0xFFFFFFFF).to_bytes(4, "little") + marshal.dumps(code))
    again = k.spec_module(key)
    assert not marker.exists()
    assert again is not None and again is not mod and again.one is not None


@posix
def test_a_symlink_at_a_temporary_name_is_not_followed(tmp_path, spec_dirs):
    """A module is written under an unpredictable name, created exclusively:
    links an attacker leaves at names derived from the module's (the old
    ``<module>.py.<pid>.tmp``) do not make the engine overwrite their target."""
    d = tmp_path / "spec"
    d.mkdir()
    spec_dirs.append(d)
    key = _key("a")
    victim = tmp_path / "victim"
    victim.write_text("precious")
    base = d / f"hybridsim_spec_{key}.py"
    for pid in {os.getpid(), os.getpid() + 1}:
        os.symlink(victim, f"{base}.{pid}.tmp")
    assert k.spec_module(key) is not None
    assert victim.read_text() == "precious"
    assert base.read_text() == k._spec_source(key) and not base.is_symlink()
    assert not [p for p in d.iterdir() if p.name.endswith(".tmp") and not p.is_symlink()]


@posix
@pytest.mark.slow       # two fresh interpreters importing numba: about 3 s
def test_a_shared_numba_cache_folder_is_refused_and_its_index_never_read(tmp_path):
    """``NUMBA_CACHE_DIR`` writable by others: the engine keeps no kernel there
    (it compiles them in memory, and says so once), so an index planted there
    (a pickle that runs code when loaded) is never read. In a private folder
    the same engine caches as before."""
    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    marker = tmp_path / "pwned"
    script = textwrap.dedent("""
        import glob, os, pickle, sys, warnings
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            from hybridsim.compiled import _cache as k, _types
        print("cache", k.cache_dir())
        print("kept", _types.CACHE)
        print("warned", sum("not private" in str(x.message) for x in w))
    """)
    # the index numba would read for the engine's first cached kernel, planted
    # in the shared folder at the path a private one has it
    probe = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                           text=True, timeout=600,
                           env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "private")))
    assert probe.returncode == 0, probe.stderr
    assert "kept True" in probe.stdout and "warned 0" in probe.stdout
    private_cache = probe.stdout.split("cache ")[1].split("\n")[0]
    rel = os.path.relpath(private_cache, tmp_path / "private")

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))
    planted = shared / rel
    planted.mkdir(parents=True)
    for index in os.listdir(private_cache):
        if index.endswith(".nbi"):
            import pickle
            (planted / index).write_bytes(pickle.dumps(Payload()))
    assert list(planted.iterdir())
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                         text=True, timeout=600, env=dict(os.environ, NUMBA_CACHE_DIR=str(shared)))
    assert out.returncode == 0, out.stderr
    assert "cache None" in out.stdout and "kept False" in out.stdout
    assert "warned 1" in out.stdout
    assert not marker.exists()
