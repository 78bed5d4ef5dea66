"""HybridArc.load and hs.load: only regular files of bounded size, only arcs
a run of the engine makes, and an explore leaf's choices kept."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.arc import ArcFileError

HERE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def fields(t=(0.0, 1.0, 1.0, 2.0), j=(0, 0, 1, 1), x=None, termination="T_MAX"):
    t = np.asarray(t, dtype=float)
    x = np.arange(2.0 * len(t)).reshape(len(t), 2) if x is None else np.asarray(x, float)
    return dict(format_version=np.array(2), t=t, j=np.asarray(j, dtype=np.int64), x=x,
                termination=np.array(termination), message=np.array(""),
                components=np.array("[]"), stats=np.array(""),
                system_description=np.array(""))


def write(path, **kw):
    np.savez(path, **kw)
    return path


def refused(path, match, **kw):
    with pytest.raises(ArcFileError, match=r"load: '.*" + os.path.basename(path) + "': .*"
                       + match):
        hs.HybridArc.load(path, **kw)


@pytest.mark.skipif(not hasattr(os, "mkfifo") or not os.path.exists("/dev/zero"),
                    reason="POSIX FIFOs and /dev/zero")
def test_paths_that_never_end_are_refused_before_reading(tmp_path):
    """A FIFO (no writer: opening it used to block), a symlink to /dev/zero
    (read until the OOM killer), /dev/null, a directory and an open device:
    each refused at once. Run in a child process limited to 1 GiB of memory
    and 120 s, so that a regression fails here instead of hanging the suite
    or exhausting the machine."""
    os.mkfifo(tmp_path / "fifo.npz")
    os.symlink("/dev/zero", tmp_path / "zero.npz")
    os.symlink("/dev/null", tmp_path / "null.npz")
    (tmp_path / "dir.npz").mkdir()
    script = textwrap.dedent(f"""
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))
        import hybridsim as hs
        from hybridsim.arc import ArcFileError
        d = {str(tmp_path)!r}
        for name in ("fifo.npz", "zero.npz", "null.npz", "dir.npz", "open /dev/zero"):
            try:
                if name.startswith("open"):
                    with open("/dev/zero", "rb") as fh:
                        hs.HybridArc.load(fh)
                else:
                    hs.load(d + "/" + name)
                print(name, "LOADED")
            except ArcFileError as e:
                print(name, "REFUSED", str(e).split("': ", 1)[1])
            except BaseException as e:
                print(name, "OTHER", type(e).__name__)
            sys.stdout.flush()
    """)
    out = subprocess.run([sys.executable, "-c", script], cwd=HERE, capture_output=True,
                         text=True, timeout=120)
    lines = dict(line.split(" ", 1) for line in out.stdout.splitlines()
                 if not line.startswith("open"))
    assert lines == {
        "fifo.npz": "REFUSED is a FIFO, not a regular file written by HybridArc.save",
        "zero.npz": "REFUSED is a character device, not a regular file written by "
                    "HybridArc.save",
        "null.npz": "REFUSED is a character device, not a regular file written by "
                    "HybridArc.save",
        "dir.npz": "REFUSED is a directory, not a regular file written by HybridArc.save",
    }, out.stdout + out.stderr
    assert "open /dev/zero REFUSED is a character device" in out.stdout


def test_size_bounds(tmp_path):
    a = hs.HybridArc([0.0, 1.0], [0, 0], [[0.0], [1.0]], hs.Termination.T_MAX)
    p = a.save(tmp_path / "a")
    refused(p, r"the file holds \d+ bytes, more than max_bytes = 100", max_bytes=100)
    # a file whose arrays decompress to 6 MB, 20 times its size (a zip bomb in
    # miniature): refused on what its members declare, before reading them
    n = 250_000
    big = fields(t=np.arange(n, dtype=float), j=np.zeros(n), x=np.zeros((n, 1)))
    np.savez_compressed(tmp_path / "bomb.npz", **big)
    assert os.path.getsize(tmp_path / "bomb.npz") < 1_000_000
    refused(tmp_path / "bomb.npz", r"its arrays declare \d+ bytes once decompressed, more "
            r"than max_bytes = 1000000", max_bytes=1_000_000)
    assert len(hs.load(tmp_path / "bomb.npz")) == n         # the default bound: 16 GiB
    with pytest.raises(ValueError, match="max_bytes must be a positive int"):
        hs.load(p, max_bytes=0)


@pytest.mark.parametrize("change, message", [
    (dict(x=np.zeros((4, 0))), r"the state has dimension 0"),
    (dict(t=[], j=[], x=np.zeros((0, 2))), r"no samples, yet the run ended T_MAX"),
    (dict(j=(-1, -1, 0, 0)), r"sample 0 has the negative jump count j = -1"),
    (dict(t=(0.0, 2.0, 2.0, 1.0)), r"t goes backwards at sample 3"),
    (dict(t=(0.0, 1.0, 1.0, 2.0), j=(0, 0, 2, 2)), r"j must increase by 0 or 1"),
    (dict(t=(0.0, 1.0, 1.5), j=(0, 0, 1, 1)), r"j must be an integer array of shape \(3,\)"),
])
def test_arcs_no_run_makes_are_refused(tmp_path, change, message):
    f = fields(**{k: v for k, v in change.items() if k in ("t", "j", "x")})
    refused(write(tmp_path / "c.npz", **f), message)


def test_save_writes_only_what_load_reads(tmp_path):
    flat = hs.HybridArc([0.0, 1.0], [0, 0], np.zeros((2, 0)), hs.Termination.T_MAX)
    with pytest.raises(ValueError, match="save: the state has dimension 0"):
        flat.save(tmp_path / "flat")
    assert not (tmp_path / "flat.npz").exists()
    # an empty window of a run has no end: saved (and loaded) without a cause
    arc = hs.simulate(hs.library.Timer(1.0), [0.0], t_max=2.5)
    empty = arc.restrict(t=(5.0, 6.0))
    assert len(empty) == 0 and empty.termination is hs.Termination.T_MAX
    back = hs.load(empty.save(tmp_path / "empty"))
    assert len(back) == 0 and back.termination is None and back.x.shape == (0, 1)


def _chooser():
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        flow_set=lambda x: x[0] <= 2.0, jump_set=lambda x: x[0] >= 1.0, state_dim=1)


def test_an_explore_leaf_keeps_its_choices(tmp_path):
    tree = hs.explore(_chooser(), [0.0], t_max=10.0, j_max=2, dwell_grid=[0.5],
                      merge_tol=None)
    for k, leaf in enumerate(tree):
        back = hs.load(leaf.save(tmp_path / f"leaf{k}"))
        assert [str(c) for c in back.choices] == [str(c) for c in leaf.choices]
        for c, d in zip(back.choices, leaf.choices, strict=True):
            assert (c.t, c.j, c.kind, c.value) == (d.t, d.j, d.kind, d.value)
            np.testing.assert_array_equal(c.x, d.x)
            assert isinstance(c, hs.Choice)
        np.testing.assert_array_equal(back.x, leaf.x)
    plain = hs.load(hs.simulate(hs.library.Timer(1.0), [0.0], t_max=1.5)
                    .save(tmp_path / "plain"))
    assert "choices" not in plain.__dict__


@pytest.mark.parametrize("choices", [
    "[[0.0, 0, [1.0, 2.0], \"jump\", 0]]",          # x of the wrong length
    "[[0.0, 0, [1.0], \"teleport\", 0]]",           # an unknown kind
    "[[0.0, -1, [1.0], \"flow\", null]]",           # a negative j
    "{\"t\": 0}",                                    # not a list
    "[[0.0, 0, [1.0], \"dwell\"]]",                  # four fields
])
def test_crafted_choices_are_refused(tmp_path, choices):
    f = fields(x=np.zeros((4, 1)))
    f["choices"] = np.array(choices)
    json.loads(choices)                              # well-formed JSON, wrong content
    refused(write(tmp_path / "ch.npz", **f), r"choices are not of the expected form")
