"""HybridArc that travel and last: pickling whatever the system holds, and the
versioned ``.npz`` format with its validation of damaged or foreign files."""
import json
import pickle
import zipfile

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.arc import FORMAT_VERSION, ArcFileError
from hybridsim.library import BouncingBall, Timer


def lambda_system():
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[1], -9.81]), jump_map=lambda x: np.array([0.0, -0.8 * x[1]]),
        flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0, state_dim=2)


def with_extras(a):
    xd = np.array([[x[1], -9.81] for x in a.x])
    return hs.HybridArc(a.t, a.j, a.x, a.termination, a.message, components=a.components,
                        segments=a._segments, system=a.system, xdot=xd,
                        stats={"steps": 12, "nfev": np.int64(80), "rejected": 0})


def assert_same_samples(b, a):
    np.testing.assert_array_equal(b.t, a.t)
    np.testing.assert_array_equal(b.j, a.j)
    np.testing.assert_array_equal(b.x, a.x)
    assert b.j.dtype == np.int64
    assert b.termination is a.termination and b.message == a.message


# ----------------------------------------------------------------- pickle
def test_pickle_arc_whose_system_holds_a_lambda():
    a = with_extras(hs.simulate(lambda_system(), [1.0, 0.0], t_max=2.0, j_max=3,
                                dense=True))
    with pytest.raises((pickle.PicklingError, AttributeError, TypeError)):
        pickle.dumps(a.system)               # the system itself does not travel
    b = pickle.loads(pickle.dumps(a))
    assert_same_samples(b, a)
    np.testing.assert_array_equal(b.xdot, a.xdot)
    assert b.stats == a.stats
    assert b.system is None and "HybridSystem" in b.system_description
    # the dense outputs (scipy's) pickle: at() is still exact to them
    assert b._segments is not None
    for s in (0.1, 0.3, 0.9):
        np.testing.assert_array_equal(b.at(s), a.at(s))
    # the live arc still has its system and its outputs
    assert a.system is not None and a.outputs().shape == (len(a), 2)
    with pytest.raises(ValueError, match="no longer holds its system.*HybridSystem"):
        b.outputs()


def test_pickle_keeps_a_picklable_system():
    a = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=1.0, j_max=2, dense=True)
    b = pickle.loads(pickle.dumps(a))
    assert isinstance(b.system, BouncingBall) and b.system.e == 0.8
    np.testing.assert_array_equal(b.outputs(), a.outputs())
    np.testing.assert_array_equal(b.at(0.2), a.at(0.2))


def test_pickle_interconnection_with_a_lambda_component():
    sysm = hs.Interconnection({"ball": BouncingBall(), "f": lambda_system()})
    a = hs.simulate(sysm, [1.0, 0.0, 2.0, 0.0], t_max=1.0, j_max=3)
    np.testing.assert_array_equal(a.outputs("ball"), a["ball"].x)   # live
    b = pickle.loads(pickle.dumps(a))
    assert_same_samples(b, a)
    np.testing.assert_array_equal(b["f"].x, a["f"].x)              # components work
    assert "component 'f'" in b["f"].system_description
    with pytest.raises(ValueError, match="no longer holds its system"):
        b.outputs("ball")


def test_pickle_drops_unpicklable_dense_outputs_and_exceptions():
    a = hs.simulate(BouncingBall(), [1.0, 0.0], t_max=1.0, j_max=2, dense=True)
    h = a.transform(lambda x: x[0])          # its dense outputs hold the lambda
    b = pickle.loads(pickle.dumps(h))
    assert b._segments is None
    np.testing.assert_array_equal(b.x, h.x)
    # without dense outputs (and xdot) at() is linear between the samples
    np.testing.assert_allclose(b.at(0.2)[0], np.interp(0.2, h.t[h.j == 0], h.x[h.j == 0, 0]),
                               rtol=1e-14)

    class Odd(Exception):
        def __init__(self):
            super().__init__("odd")
            self.fn = lambda: 0
    c = hs.HybridArc([0.0], [0], [[1.0]], hs.Termination.MAP_ERROR, exception=Odd())
    d = pickle.loads(pickle.dumps(c))
    assert isinstance(d.exception, RuntimeError) and "Odd: odd" in str(d.exception)


def test_pickled_arcs_cross_process_boundaries_like_a_sweep_result():
    # what ProcessPoolExecutor does with a result: pickle it with the default protocol
    arcs = [hs.simulate(lambda_system(), [h, 0.0], t_max=1.0, j_max=2) for h in (1.0, 2.0)]
    back = pickle.loads(pickle.dumps(arcs))
    for b, a in zip(back, arcs):
        assert_same_samples(b, a)


# --------------------------------------------------------------- save/load
@pytest.fixture(scope="module")
def ball():
    return with_extras(hs.simulate(BouncingBall(), [1.0, 0.0], t_max=2.0, j_max=3))


def test_roundtrip_exact_with_xdot_stats(ball, tmp_path):
    p = ball.save(tmp_path / "ball.npz")
    assert p == tmp_path / "ball.npz"
    b = hs.HybridArc.load(p)
    assert_same_samples(b, ball)
    np.testing.assert_array_equal(b.xdot, ball.xdot)
    assert b.stats == {"steps": 12, "nfev": 80, "rejected": 0}
    assert b.system is None and "BouncingBall" in b.system_description
    with pytest.raises(ValueError, match="loaded from a file"):
        b.outputs()
    with np.load(p) as d:
        assert int(d["format_version"]) == FORMAT_VERSION
        assert all(arr.dtype != object for arr in (d[k] for k in d.files))


def test_suffix_agreement(ball, tmp_path):
    p = ball.save(str(tmp_path / "f"))
    assert p.name == "f.npz" and p.exists() and not (tmp_path / "f").exists()
    assert_same_samples(hs.HybridArc.load(str(tmp_path / "f")), ball)
    assert_same_samples(hs.HybridArc.load(tmp_path / "f.npz"), ball)
    with pytest.raises(FileNotFoundError, match="nor with .npz"):
        hs.HybridArc.load(tmp_path / "g")


def test_roundtrip_file_object_empty_arc_and_names(tmp_path):
    sysm = hs.Interconnection({"a": BouncingBall(), "b": Timer(0.5)})
    a = hs.simulate(sysm, [1.0, 0.0, 0.0], t_max=1.0, j_max=4)
    # components with int and tuple names survive with their types
    odd = hs.HybridArc(a.t, a.j, a.x, a.termination,
                       components={3: slice(0, 2), (1, "x"): slice(2, 3)})
    with open(tmp_path / "o.npz", "wb") as fh:
        odd.save(fh)
    with open(tmp_path / "o.npz", "rb") as fh:
        b = hs.HybridArc.load(fh)
    assert b.components == {3: slice(0, 2), (1, "x"): slice(2, 3)}
    np.testing.assert_array_equal(b[(1, "x")].x, a["b"].x)
    assert b.xdot is None and b.stats is None
    e = a.restrict(t=(5.0, 6.0))
    assert len(e) == 0
    e.save(tmp_path / "e")
    f = hs.HybridArc.load(tmp_path / "e")
    assert len(f) == 0 and f.x.shape == (0, 3)


def test_loads_the_version_1_layout(ball, tmp_path):
    np.savez_compressed(tmp_path / "v1.npz", t=ball.t, j=ball.j, x=ball.x,
                        termination=np.array("J_MAX"), message=np.array("m"),
                        comp_names=np.array(["p"]), comp_bounds=np.array([[0, 2]]))
    b = hs.HybridArc.load(tmp_path / "v1.npz")
    assert_same_samples(b, hs.HybridArc(ball.t, ball.j, ball.x, hs.Termination.J_MAX, "m"))
    assert b.components == {"p": slice(0, 2)}


def test_non_finite_last_sample_allowed_only_for_non_finite_runs(tmp_path):
    x = [[0.0], [np.nan]]
    hs.HybridArc([0, 1], [0, 0], x, hs.Termination.NON_FINITE).save(tmp_path / "n")
    assert np.isnan(hs.HybridArc.load(tmp_path / "n").x[-1, 0])
    bad = hs.HybridArc([0, 1], [0, 0], x, hs.Termination.T_MAX)
    with pytest.raises(ValueError, match=r"save: x\[1\] .* is not finite"):
        bad.save(tmp_path / "m")              # save validates: nothing written
    assert not (tmp_path / "m.npz").exists()
    f = fields(bad)
    with pytest.raises(ArcFileError, match=r"x\[1\] .* is not finite"):
        hs.HybridArc.load(write(tmp_path / "m.npz", **f))


# ---------------------------------------------------------- damaged files
def fields(arc):
    """The arrays save() writes, to damage one at a time."""
    return dict(format_version=np.array(FORMAT_VERSION), t=arc.t, j=arc.j, x=arc.x,
                termination=np.array("T_MAX"), message=np.array(""),
                components=np.array("[]"), stats=np.array(""),
                system_description=np.array(""))


def write(path, **kw):
    np.savez(path, **kw)
    return path


def test_truncated_and_corrupt_files(ball, tmp_path):
    p = ball.save(tmp_path / "good.npz")
    raw = p.read_bytes()
    for cut in (10, len(raw) // 2, len(raw) - 30):
        bad = tmp_path / f"cut{cut}.npz"
        bad.write_bytes(raw[:cut])
        with pytest.raises(ValueError, match=rf"load: '.*cut{cut}.npz'.*(truncated|corrupt)"):
            hs.HybridArc.load(bad)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"this is not a zip archive at all" * 10)
    with pytest.raises(ValueError, match="junk.npz.*truncated or corrupt"):
        hs.HybridArc.load(junk)
    # a zip whose member is damaged (CRC/deflate error when read)
    flipped = bytearray(raw)
    with zipfile.ZipFile(p) as z:
        info = z.getinfo("x.npy")
    mid = info.header_offset + 30 + len(info.filename) + info.compress_size // 2
    flipped[mid] ^= 0xFF
    (tmp_path / "flip.npz").write_bytes(bytes(flipped))
    with pytest.raises(ValueError, match="flip.npz.*(truncated|corrupt)"):
        hs.HybridArc.load(tmp_path / "flip.npz")
    np.save(tmp_path / "single.npy", ball.x)
    with pytest.raises(ValueError, match="single.npy.*not an .npz archive"):
        hs.HybridArc.load(tmp_path / "single.npy")


def test_missing_keys_older_and_newer_layouts(ball, tmp_path):
    f = fields(ball)
    del f["x"]
    with pytest.raises(ValueError, match=r"missing \['x'\] for format version 2"):
        hs.HybridArc.load(write(tmp_path / "a.npz", **f))
    # an old layout without comp_names (the KeyError 'comp_names is not a file')
    with pytest.raises(ValueError, match=r"missing \['comp_names', 'comp_bounds'\].*"
                                         r"no format_version key \(version 1 layout\)"):
        hs.HybridArc.load(write(tmp_path / "b.npz", t=ball.t, j=ball.j, x=ball.x,
                                termination=np.array(""), message=np.array("")))
    f = fields(ball)
    f["format_version"] = np.array(99)
    with pytest.raises(ValueError, match="format version 99 was written by a newer"):
        hs.HybridArc.load(write(tmp_path / "c.npz", **f))


def test_pickled_content_is_refused(ball, tmp_path):
    f = fields(ball)
    f["message"] = np.array([{"evil": 1}], dtype=object)
    with pytest.raises(ValueError, match="d.npz.*(pickled|Object arrays|corrupt)"):
        hs.HybridArc.load(write(tmp_path / "d.npz", **f))


@pytest.mark.parametrize("change, message", [
    (lambda f: f["t"].__setitem__(5, -1.0), "t goes backwards at sample 5"),
    (lambda f: f.update(t=f["t"][::-1].copy()), "sample 1 .* repeats the sample before it"),
    (lambda f: f["t"].__setitem__(3, np.nan), r"t\[3\] = nan is not finite"),
    (lambda f: f["x"].__setitem__((2, 1), np.inf), r"x\[2\] .* is not finite"),
    (lambda f: f.update(j=f["j"] + 0.5), "j must hold integers"),
    (lambda f: f["j"].__setitem__(slice(-2, None), f["j"][-1] + 2),
     "j must increase by 0 or 1"),
    (lambda f: f.update(j=f["j"][::-1].copy()), "j must increase by 0 or 1"),
    (lambda f: f["t"].__setitem__(slice(None), np.arange(len(f["t"]), dtype=float)),
     "the jump at sample .* changes t"),
    (lambda f: f.update(termination=np.array("FELL_OVER")), "unknown termination 'FELL_OVER'"),
    (lambda f: f.update(x=f["x"][:-1]), r"x must be a float array of shape \(N, n\)"),
    (lambda f: f.update(j=f["j"][:-1]), "j must be an integer array of shape"),
    (lambda f: f.update(xdot=np.zeros((2, 2))), "xdot must have the shape of x"),
    (lambda f: f.update(stats=np.array("[1, 2]")), "stats must be a JSON object"),
    (lambda f: f.update(components=np.array("{oops")), "components/stats are not valid JSON"),
    (lambda f: f.update(components=np.array(json.dumps([["a", 0, 9]]))),
     "component 'a' has bounds"),
])
def test_invalid_content_is_named(ball, tmp_path, change, message):
    f = {k: np.array(v, copy=True) for k, v in fields(ball).items()}
    change(f)
    p = write(tmp_path / "bad.npz", **f)
    with pytest.raises(ValueError, match=r"load: '.*bad.npz': " + message):
        hs.HybridArc.load(p)


def make_lambda_ball(restitution):
    """Module-level (picklable) factory of a system that holds lambdas."""
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[1], -9.81]),
        jump_map=lambda x: np.array([0.0, -restitution * x[1]]),
        flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0, state_dim=2)


def test_sweep_over_a_process_pool_returns_every_arc():
    from concurrent.futures import ProcessPoolExecutor
    params = [0.5, 0.8]
    with ProcessPoolExecutor(max_workers=1) as ex:
        arcs = hs.sweep(make_lambda_ball, params, [1.0, 0.0], t_max=2.0, j_max=2,
                        executor=ex)
    serial = hs.sweep(make_lambda_ball, params, [1.0, 0.0], t_max=2.0, j_max=2)
    assert len(arcs) == 2
    for b, a in zip(arcs, serial):
        assert_same_samples(b, a)
        assert b.system is None and "HybridSystem" in b.system_description
