"""One arc contract (issue 22): ``HybridArc.validate``, ``transform``'s refusal of
non-finite values, ``save``'s checks, and ``load``'s answer to every damaged or
crafted file (a ``ValueError`` subclass naming the file, never a raw error)."""
import io
import json
import struct
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hybridsim as hs
from hybridsim.arc import FORMAT_VERSION, ArcFileError
from hybridsim.library import BouncingBall, Timer

T = hs.Termination


def arc_of(t, j, x=None, term=None, **kw):
    x = np.zeros((len(t), 1)) if x is None else x
    return hs.HybridArc(t, j, x, term, **kw)


# --------------------------------------------------------------- validate
@pytest.mark.parametrize("kw, t_max, j_max, cause", [
    (dict(), 3.0, 100, T.T_MAX),
    (dict(), 3.0, 2, T.J_MAX),
    (dict(refine=4, dense=True), 2.0, 3, T.J_MAX),
    (dict(j0=3, t0=0.5), 2.5, 100, T.T_MAX),
])
def test_engine_runs_are_valid_at_their_limits(kw, t_max, j_max, cause):
    for sysm, x0 in ((BouncingBall(), [1.0, 0.0]), (Timer(1.0), [0.0])):
        a = hs.simulate(sysm, x0, t_max=t_max, j_max=j_max, **kw)
        if a.termination is cause:
            assert a.validate(t_max=t_max, j_max=j_max) is a


def test_validate_returns_self_and_accepts_edge_arcs():
    a = arc_of([0, 1, 1, 1, 2], [0, 0, 1, 2, 2])          # two jumps at one time
    assert a.validate() is a
    assert arc_of([], []).validate(t_max=1.0, j_max=0).t.shape == (0,)
    assert len(arc_of([0.0], [5]).validate(t_max=0.0, j_max=0)) == 1
    # a batch row whose x0 was not finite: one non-finite sample, NON_FINITE
    hs.HybridArc([0.0], [0], [[np.nan]], T.NON_FINITE).validate()
    # xdot may hold NaN rows (unknown there)
    arc_of([0, 1], [0, 0], xdot=[[np.nan], [1.0]]).validate()


@pytest.mark.parametrize("t, j, x, term, message", [
    ([0, 1, 1], [0, 0, 0], None, None,
     r"validate: sample 2 \(t=1.0, j=0\) repeats the sample before it"),
    ([0, 0], [3, 3], None, None, r"sample 1 \(t=0.0, j=3\) repeats"),
    ([0, 2, 1], [0, 0, 0], None, None,
     r"t goes backwards at sample 2 \(t\[1\] = 2.0, t\[2\] = 1.0; j = 0\)"),
    ([0, 1, 2], [0, 0, 1], None, None, r"the jump at sample 2 \(j 0 -> 1\) changes t"),
    ([0, 1, 1], [0, 0, 2], None, None,
     r"j must increase by 0 or 1.* at sample 2 \(t=1.0, j=2\)"),
    ([0, 1, 1], [1, 1, 0], None, None, r"j must increase by 0 or 1.*sample 2"),
    ([0, np.inf, 3], [0, 0, 0], None, None, r"t\[1\] = inf is not finite at sample 1"),
    ([0, np.nan], [0, 0], None, None, r"t\[1\] = nan is not finite"),
    ([0, 1, 2], [0, 0, 0], [[0], [np.nan], [1]], T.NON_FINITE,
     r"x\[1\] \(t = 1.0, j = 0\) is not finite"),
    ([0, 1], [0, 0], [[0], [np.inf]], T.T_MAX, r"x\[1\] .* is not finite"),
])
def test_each_broken_invariant_is_named(t, j, x, term, message):
    x = np.zeros((len(t), 1)) if x is None else np.asarray(x, float)
    with pytest.raises(ValueError, match=message):
        hs.HybridArc(t, j, x, term).validate()


def test_the_first_violating_sample_is_named():
    # a duplicate at 2 and t backwards at 4: the duplicate is reported
    a = arc_of([0, 1, 1, 3, 2], [0, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="sample 2 .* repeats"):
        a.validate()
    # x not finite at 1 before the jump that changes t at 3
    b = hs.HybridArc([0, 1, 2, 3], [0, 0, 0, 1], [[0], [np.nan], [0], [0]], None)
    with pytest.raises(ValueError, match=r"x\[1\]"):
        b.validate()


def test_shapes_and_dtypes_of_a_mutated_arc():
    a = arc_of([0, 1], [0, 0])
    a.x = np.zeros((3, 1))
    with pytest.raises(ValueError, match=r"expected t \(N,\).*x \(3, 1\)"):
        a.validate()
    a = arc_of([0, 1], [0, 0])
    a.xdot = np.zeros((2, 2))
    with pytest.raises(ValueError, match=r"xdot \(2, 2\)"):
        a.validate()
    a = arc_of([0, 1], [0, 0])
    a.j = np.array([0.0, 0.0])
    with pytest.raises(ValueError, match="j of ints"):
        a.validate()
    a = arc_of([0, 1], [0, 0])
    a.t = [0.0, 1.0]                                   # not an array
    with pytest.raises(ValueError, match="expected t"):
        a.validate()


def test_limits_when_given():
    a = hs.HybridArc([0, 1, 1, 2], [0, 0, 1, 1], np.zeros((4, 1)), T.T_MAX)
    a.validate(t_max=2.0, j_max=1)
    with pytest.raises(ValueError, match=r"ended T_MAX but its last sample 3 \(t=2.0, j=1\) "
                                         r"is not at t_max = 2.5"):
        a.validate(t_max=2.5)
    with pytest.raises(ValueError, match=r"sample 3 \(t=2.0, j=1\) lies after t_max = 1.5"):
        a.validate(t_max=1.5)
    with pytest.raises(ValueError, match=r"sample 2 .* after jump 1, beyond j_max = 0"):
        a.validate(j_max=0)
    b = hs.HybridArc([0, 1, 1], [2, 2, 3], np.zeros((3, 1)), T.J_MAX)
    b.validate(j_max=1, t_max=5.0)                     # j counted from j[0]
    with pytest.raises(ValueError, match=r"ended J_MAX but .* after 1 jumps, not j_max = 2"):
        b.validate(j_max=2)
    # other causes: only "nothing beyond the limits"
    c = hs.HybridArc([0, 1], [0, 0], np.zeros((2, 1)), T.ZENO)
    c.validate(t_max=5.0, j_max=3)


def test_interpolate_both_rows_make_a_valid_arc():
    a = hs.simulate(Timer(1.0), [0.0], t_max=3.5, j_max=10)
    grid = np.unique(np.concatenate((np.linspace(0, 3.5, 15), a.jump_times)))
    b = a.interpolate(grid, at_jump="both")
    hs.HybridArc(b.t, b.j, b.x, None).validate()
    # "nan" gives arrays, not an arc: NaN there is fine
    assert np.isnan(a.interpolate(a.jump_times, at_jump="nan").x).all()


# -------------------------------------------------------------- transform
def test_transform_refuses_non_finite_values():
    a = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=1.0, j_max=2)
    with pytest.raises(ValueError, match=r"transform: fn returned non-finite values "
                                         r"\[nan\] at sample 0 \(t=0.0, j=0\)"):
        a.transform(lambda x: np.nan)
    k = 3
    with pytest.raises(ValueError, match=rf"\[ 1. inf\] at sample {k} "
                                         rf"\(t={float(a.t[k])!r}, j=0\)"):
        a.transform(lambda x, t: [1.0, np.inf if t == a.t[k] else 0.0])
    with pytest.raises(ValueError, match="fn must return numbers"):
        a.transform(lambda x: "abc")


def test_transform_refuses_non_finite_dense_values_when_evaluated():
    a = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=1.0, j_max=2, dense=True)
    s = float(0.5 * (a.t[1] + a.t[2]))              # between two samples: dense only
    h = a.transform(lambda x, t: np.inf if t == s else x[0])
    assert np.isfinite(h.x).all()
    with pytest.raises(ValueError, match=rf"non-finite values \[inf\] at \(t={s!r}, j=0\)"):
        h.at(s)


def test_transform_of_a_non_finite_run_keeps_its_last_sample():
    a = hs.HybridArc([0.0, 1.0], [0, 0], [[1.0], [np.nan]], T.NON_FINITE)
    b = a.transform(lambda x: 2 * x)
    assert np.isnan(b.x[-1, 0]) and b.validate() is b
    with pytest.raises(ValueError, match="non-finite values"):
        a.transform(lambda x: np.inf)                 # sample 0 is finite


# ------------------------------------------------------------------- save
def test_save_validates_and_writes_nothing(tmp_path):
    bad = arc_of([0, 1, 1], [0, 0, 0])
    with pytest.raises(ValueError, match="save: sample 2 .* repeats"):
        bad.save(tmp_path / "bad")
    assert list(tmp_path.iterdir()) == []
    buf = io.BytesIO()
    with pytest.raises(ValueError, match="save:"):
        bad.save(buf)
    assert buf.getvalue() == b""


def test_save_refuses_a_directory(tmp_path):
    a = arc_of([0, 1], [0, 0])
    (tmp_path / "results").mkdir()
    for p in (str(tmp_path / "results") + "/", tmp_path / "results",
              str(tmp_path / "new") + "/"):
        with pytest.raises(IsADirectoryError, match=r"save: '.*(results|new)/?' is a directory"):
            a.save(p)
    (tmp_path / "out.npz").mkdir()
    with pytest.raises(IsADirectoryError, match="out.npz' is a directory"):
        a.save(tmp_path / "out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.npz", "results"]
    assert list((tmp_path / "results").iterdir()) == []


# ---------------------------------------------------------- crafted files
def fields(arc=None):
    a = arc or arc_of([0.0, 1.0, 1.0, 2.0], [0, 0, 1, 1], np.arange(8.0).reshape(4, 2),
                      T.T_MAX)
    return dict(format_version=np.array(FORMAT_VERSION), t=a.t, j=a.j, x=a.x,
                termination=np.array("T_MAX"), message=np.array(""),
                components=np.array("[]"), stats=np.array(""),
                system_description=np.array(""))


def npy_bytes(header, data=b"", version=(1, 0)):
    """A .npy member with a literal header string (crafted)."""
    h = header.encode("latin1")
    h += b" " * (-(len(h) + 11) % 64) + b"\n"
    fmt = "<H" if version == (1, 0) else "<I"
    return b"\x93NUMPY" + bytes(version) + struct.pack(fmt, len(h)) + h + data


def zip_of(path, members):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            if isinstance(data, np.ndarray):
                f = io.BytesIO()
                np.lib.format.write_array(f, data, allow_pickle=True)
                data = f.getvalue()
            z.writestr(name, data)
    return path


def members_of(f, **replace):
    m = {k + ".npy": v for k, v in f.items()}
    m.update({k if "." in k else k + ".npy": v for k, v in replace.items()})
    return {k: v for k, v in m.items() if v is not None}


def refused(path, match):
    with pytest.raises(ArcFileError, match=r"load: '.*" + path.name + "': .*" + match):
        hs.HybridArc.load(path)


def test_a_well_formed_crafted_file_loads(tmp_path):
    a = hs.HybridArc.load(zip_of(tmp_path / "ok.npz", members_of(fields())))
    assert a.jump_count == 1 and a.x.flags.writeable


@pytest.mark.parametrize("value", [0, -7, 2.9, 2.0, "2", True, np.array([2]), 99])
def test_format_version_must_be_a_supported_int(tmp_path, value):
    f = fields()
    f["format_version"] = np.array(value)
    p = zip_of(tmp_path / "v.npz", members_of(f))
    refused(p, r"(format_version must be an integer|format version -?\d+ (is not|was written"
               r" by a newer)).*reads format versions 1 \(files without format_version\) "
               rf"to {FORMAT_VERSION}")


def test_empty_truncated_and_foreign_files(tmp_path):
    for name, data in [("empty.npz", b""), ("text.npz", b"t,j,x\n0,0,1\n"),
                       ("zipstart.npz", b"PK\x03\x04" + b"\0" * 40)]:
        (tmp_path / name).write_bytes(data)
        refused(tmp_path / name, "not a readable HybridArc .npz file")
    raw = (zip_of(tmp_path / "full.npz", members_of(fields()))).read_bytes()
    for cut in range(0, len(raw), 37):
        (tmp_path / "cut.npz").write_bytes(raw[:cut])
        with pytest.raises(ArcFileError, match="cut.npz"):
            hs.HybridArc.load(tmp_path / "cut.npz")


def test_a_zip_that_is_not_an_npz(tmp_path):
    refused(zip_of(tmp_path / "a.npz", {"readme.txt": b"hello"}),
            r"missing \['t', 'j', 'x', 'termination'.*present: \['readme.txt'\]")
    # every key present, but the members are not .npy arrays
    refused(zip_of(tmp_path / "b.npz", {k + ".npy": b"hello, world" for k in fields()}),
            "not a readable HybridArc .npz file .*ValueError")


def test_missing_arrays(tmp_path):
    refused(zip_of(tmp_path / "m.npz", members_of(fields(), t=None, stats=None)),
            r"missing \['t', 'stats'\] for format version 2")


@pytest.mark.parametrize("key, value, match", [
    ("t", np.array(["a", "b", "c", "d"]), r"t must be a 1-D float array, got dtype <U1"),
    ("t", np.zeros((4, 1)), r"t must be a 1-D float array, got dtype float64, shape \(4, 1\)"),
    ("t", np.array([0, 1, 1, 2], dtype=complex), "t must be a 1-D float array"),
    ("j", np.array([True, False, True, True]), "j must be an integer array of shape"),
    ("j", np.array([0, 0, 1, 2**64 - 1], dtype=np.uint64), "beyond int64"),
    ("j", np.array([0, 0, 1e300, 1e300]), "j must hold integers"),
    ("x", np.zeros(4), r"x must be a float array of shape \(N, n\)"),
    ("x", np.zeros((4, 2), dtype="M8[s]"), r"x must be a float array of shape \(N, n\)"),
    ("xdot", np.zeros((4, 3)), "xdot must have the shape of x"),
    ("message", np.array(3.0), "message must be a string, got dtype float64"),
    ("termination", np.array(["T_MAX"]), r"termination must be a string.*shape \(1,\)"),
    ("message", np.array([{"evil": 1}], dtype=object), "holds Python objects"),
    ("t", np.array([0.0, 1.0, 1.0, 2.0], dtype=object), "'t' holds Python objects"),
])
def test_arrays_of_wrong_dtype_or_shape(tmp_path, key, value, match):
    refused(zip_of(tmp_path / "d.npz", members_of(fields(), **{key: value})), match)


@pytest.mark.parametrize("header, data, match", [
    ("[1, 2, 3]", b"", "not a readable.*(not a dictionary|dict)"),
    ("{'descr': '<f8', 'fortran_order': False, 'shape': (4,)" + "}", b"",
     r"declares shape \(4,\) of float64 \(32 bytes\) but holds 0 bytes"),
    ("{'descr': " + "[" * 150 + "]" * 150 + ", 'fortran_order': False, 'shape': (4,), }",
     b"", "not a readable"),
    ("{'descr': '<f8', 'fortran_order': False, 'shape': (10**12,), }", b"\0" * 32,
     "not a readable"),
    ("{'descr': '<f8', 'fortran_order': False, 'shape': (1000000000000,), }", b"\0" * 32,
     r"array 't' declares shape \(1000000000000,\) of float64 \(8000000000000 bytes\) "
     r"but holds 32 bytes"),
    ("{'descr': '<f8', 'fortran_order': False, 'shape': (4,), }", b"\0" * 31,
     r"declares shape \(4,\) .* but holds 31 bytes"),
    ("{'descr': '|O', 'fortran_order': False, 'shape': (4,), }", b"\0" * 32,
     "holds Python objects"),
])
def test_crafted_npy_headers(tmp_path, header, data, match):
    refused(zip_of(tmp_path / "h.npz", members_of(fields(), t=npy_bytes(header, data))),
            match)


def test_npy_format_version_3_and_huge_header(tmp_path):
    hdr = "{'descr': '<f8', 'fortran_order': False, 'shape': (4,), }"
    refused(zip_of(tmp_path / "v3.npz", members_of(fields(), t=npy_bytes(
        hdr, b"\0" * 32, version=(3, 0)))), r"\.npy format version \(3, 0\)")
    refused(zip_of(tmp_path / "big.npz", members_of(fields(), t=npy_bytes(
        hdr + " " * 200_000, b"\0" * 32, version=(2, 0)))), "not a readable.*ValueError")


def test_a_lying_zip_directory(tmp_path):
    p = zip_of(tmp_path / "z.npz", members_of(fields()))
    raw = bytearray(p.read_bytes())
    k = raw.index(b"PK\x01\x02")                     # first central directory entry
    while raw[k + 46:k + 46 + struct.unpack("<H", raw[k + 28:k + 30])[0]] != b"t.npy":
        k = raw.index(b"PK\x01\x02", k + 4)
    raw[k + 24:k + 28] = struct.pack("<I", 0xFFFFFFF0)  # uncompressed size: ~4 GB
    p.write_bytes(bytes(raw))
    refused(p, r"array 't' declares 4294967280 bytes")


def test_members_that_do_not_belong(tmp_path):
    # a renamed member (one damaged byte of its name) must not vanish silently
    a = arc_of([0, 1], [0, 0], xdot=[[1.0], [1.0]], term=T.T_MAX)
    f = dict(fields(a), xdot=a.xdot)
    refused(zip_of(tmp_path / "r.npz", members_of(f, xdot=None, **{"xdoT.npy": a.xdot})),
            r"unexpected members \['xdoT'\] for format version 2")
    refused(zip_of(tmp_path / "s.npz", members_of(f, **{"notes.txt": b"hi"})),
            r"unexpected members \['notes.txt'\]")
    with zipfile.ZipFile(tmp_path / "d.npz", "w") as z, pytest.warns(UserWarning):
        for k, v in members_of(f).items():
            z.writestr(k, b"")
        z.writestr("t.npy", b"")
    refused(tmp_path / "d.npz", "holds 't.npy' twice")


def test_a_damaged_zip_end_record(tmp_path):
    p = zip_of(tmp_path / "e.npz", members_of(fields()))
    raw = bytearray(p.read_bytes())
    k = raw.rindex(b"PK\x05\x06")
    n = struct.unpack("<H", raw[k + 10:k + 12])[0]
    raw[k + 10:k + 12] = struct.pack("<H", n + 1)
    p.write_bytes(bytes(raw))
    refused(p, f"the zip directory is damaged: its end record counts {n + 1} members, "
               f"it lists {n}")


@pytest.mark.parametrize("key, text, match", [
    ("stats", "[" * 100_000 + "]" * 100_000, r"not valid JSON .*stats: nested too deeply"),
    ("components", "[" * 100_000 + "]" * 100_000, "nested too deeply"),
    ("stats", "[1, 2]", "stats must be a JSON object, got list"),
    ("stats", "{bad", "not valid JSON"),
    ("components", '{"a": [0, 1]}', r"a list of \[name, start, stop\]"),
    ("components", '[["a", 0]]', r"a list of \[name, start, stop\]"),
    ("components", '[[["a"], 0, 1]]', r"component name \['a'\] is not of the expected form"),
    ("components", '[[{"tuple": 3}, 0, 1]]', "component name .* not of the expected form"),
    ("components", '[[{"nope": "a"}, 0, 1]]', "not of the expected form"),
    ("components", json.dumps([[{"tuple": [{"tuple": [["x"]]}]}, 0, 1]]),
     "component name"),
    ("components", "[[" + '{"tuple": [' * 50 + "1" + "]}" * 50 + ", 0, 1]]",
     "component name .* not of the expected form"),
    ("components", '[["a", true, 2]]', r"bounds \(True, 2\) that are not ints"),
    ("components", '[["a", 0.5, 2]]', r"bounds \(0.5, 2\) that are not ints"),
    ("components", '[["a", 0, 1e400]]', "not ints"),
    ("components", '[["a", 0, 1], ["a", 1, 2]]', "component 'a' appears twice"),
    ("components", '[["a", 2, 1]]', r"component 'a' has bounds \(2, 1\) outside"),
])
def test_crafted_json(tmp_path, key, text, match):
    refused(zip_of(tmp_path / "j.npz", members_of(fields(), **{key: np.array(text)})), match)


def test_version_1_layout_checks(tmp_path):
    f = fields()
    del f["format_version"], f["components"], f["stats"], f["system_description"]
    ok = dict(comp_names=np.array(["p"]), comp_bounds=np.array([[0, 2]]))
    assert hs.HybridArc.load(zip_of(tmp_path / "v1.npz", members_of(f, **ok))).components \
        == {"p": slice(0, 2)}
    refused(zip_of(tmp_path / "b.npz", members_of(f, comp_names=ok["comp_names"],
                                                  comp_bounds=np.array([[0.0, 2.0]]))),
            "comp_bounds must be an integer array")
    refused(zip_of(tmp_path / "c.npz", members_of(f, comp_names=np.array(["p", "q"]),
                                                  comp_bounds=np.array([[0, 2]]))),
            r"comp_bounds must have shape \(2, 2\)")


def test_every_failure_is_a_value_error_naming_the_file(tmp_path):
    p = zip_of(tmp_path / "named.npz", members_of(fields(), x=np.zeros(3)))
    with pytest.raises(ValueError) as e:
        hs.HybridArc.load(p)
    assert isinstance(e.value, ArcFileError) and str(p) in str(e.value)
    with open(p, "rb") as fh, pytest.raises(ArcFileError, match="named.npz"):
        hs.HybridArc.load(fh)


# ------------------------------------------------- random byte corruption
def _saved():
    a = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=1.0, j_max=2, refine=1)
    a = hs.HybridArc(a.t, a.j, a.x, a.termination, a.message,
                     xdot=np.array([[x[1], -9.81] for x in a.x]),
                     stats={"steps": 3, "note": [1, "b"]},
                     components={"h": slice(0, 1), ("v", 1): slice(1, 2)})
    buf = io.BytesIO()
    a.save(buf)
    return a, buf.getvalue()


ARC, RAW = _saved()


def same_arc(b, a):
    for k in ("t", "j", "x", "xdot"):
        np.testing.assert_array_equal(getattr(b, k), getattr(a, k))
    assert b.j.dtype == np.int64 and b.x.dtype == float
    assert (b.termination, b.message, b.stats, b.components) == \
        (a.termination, a.message, a.stats, a.components)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(edits=st.lists(st.tuples(st.integers(0, len(RAW) - 1), st.integers(0, 255)),
                      min_size=1, max_size=6),
       cut=st.one_of(st.none(), st.integers(0, len(RAW))))
def test_random_corruption_loads_the_same_arc_or_raises_arc_file_error(edits, cut):
    raw = bytearray(RAW)
    for pos, byte in edits:
        raw[pos] = byte
    if cut is not None:
        raw = raw[:cut]
    try:
        b = hs.HybridArc.load(io.BytesIO(bytes(raw)))
    except ArcFileError as e:
        assert str(e).startswith("load: ")
        return
    same_arc(b, ARC)
    b.validate()


def test_the_engine_arcs_are_validated_when_asked(monkeypatch):
    """HYBRIDSIM_CHECK_ARCS=1 (set by the test suite's conftest) makes every arc
    an integration path builds run validate(): a corrupt arc fails at its run."""
    import hybridsim.arc as arc_module

    monkeypatch.setattr(arc_module, "CHECK_ARCS", True)
    t = np.array([0.0, 0.5, 0.5])
    j = np.array([0, 0, 0], dtype=np.int64)          # the sample at 0.5 twice
    x = np.zeros((3, 1))
    with pytest.raises(ValueError, match="the engine's arc"):
        hs.HybridArc._trusted(t, j, x, hs.Termination.T_MAX)
    monkeypatch.setattr(arc_module, "CHECK_ARCS", False)
    assert len(hs.HybridArc._trusted(t, j, x, hs.Termination.T_MAX)) == 3


@pytest.mark.parametrize("kw, error, match", [
    (dict(t_max="x"), TypeError, "t_max must be a real number"),
    (dict(t_max=float("nan")), ValueError, "t_max must be finite"),
    (dict(j_max=2.5), TypeError, "j_max must be a non-negative int"),
    (dict(j_max=-1), ValueError, "j_max must be >= 0"),
])
def test_validate_names_a_bad_limit(kw, error, match):
    arc = hs.simulate(Timer(), [0.0], t_max=2.0)
    with pytest.raises(error, match=match):
        arc.validate(**kw)
