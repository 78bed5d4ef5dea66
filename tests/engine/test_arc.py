"""HybridArc: fields, selection, interpolation, evaluation, save/load, pandas."""
import numpy as np
import pytest

import hybridsim as hs


def ball():
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([x[1], -9.81]), jump_map=lambda x: np.array([0.0, -0.8 * x[1]]),
        flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0, state_dim=2)


@pytest.fixture(scope="module")
def arc():
    return hs.simulate(ball(), [1.0, 0.0], t_max=3.0, j_max=4, rtol=1e-10, atol=1e-12,
                       dense=True)


def test_fields(arc):
    assert arc.t.shape == arc.j.shape == (len(arc),)
    assert arc.x.shape == (len(arc), 2)
    assert np.all(np.diff(arc.t) >= 0) and np.all(np.diff(arc.j) >= 0)
    assert arc.jump_count == 4 == len(arc.jump_times)
    np.testing.assert_array_equal(arc.x0, [1.0, 0.0])
    np.testing.assert_array_equal(arc.xf, arc.x[-1])
    assert arc.jf == 4 and arc.tf == arc.t[-1] and arc.t0 == 0.0
    iv = arc.flow_intervals
    assert len(iv) == 5 and [j for *_, j in iv] == [0, 1, 2, 3, 4]
    np.testing.assert_allclose([b for _, b, _ in iv[:-1]], arc.jump_times)
    np.testing.assert_allclose(arc.flow_lengths[0], np.sqrt(2 / 9.81))
    assert arc.termination is hs.Termination.J_MAX and arc.success
    assert arc.termination_cause is arc.termination
    assert "j_max" in arc.message and "HybridArc" in repr(arc)


def test_select(arc):
    s = arc.select(j=1)
    assert np.all(s.j == 1)
    s = arc.select(t=(0.0, 0.5), j=(0, 1))
    assert s.t.max() <= 0.5 and set(s.j) <= {0, 1}
    with pytest.raises(ValueError, match="no sample"):
        arc.select(j=99)


def test_at_uses_dense_output_and_hybrid_time(arc):
    # on j = 0 the ball falls: x = 1 - g t^2 / 2, exact to the dense output
    for t in np.linspace(0, 0.4, 7):
        np.testing.assert_allclose(arc.at(t, 0)[0], 1 - 0.5 * 9.81 * t ** 2, atol=1e-10)
    tj = arc.jump_times[0]
    assert arc.at(tj, 0)[1] < 0 < arc.at(tj, 1)[1]        # pre- and post-jump velocity
    assert arc.at(tj)[1] > 0                              # j=None: after the jump
    with pytest.raises(ValueError, match="not in the hybrid time domain"):
        arc.at(2.9, 0)
    with pytest.raises(ValueError, match="outside the arc's time range"):
        arc.at(10.0)


def test_at_without_dense_interpolates_linearly():
    a = hs.simulate(ball(), [1.0, 0.0], t_max=0.3, refine=20)
    np.testing.assert_allclose(a.at(0.2)[0], 1 - 0.5 * 9.81 * 0.04, atol=1e-3)


def test_evaluate(arc):
    energy = arc.evaluate(lambda x: 9.81 * x[0] + 0.5 * x[1] ** 2)
    assert energy.shape == (len(arc),)
    tj = arc.evaluate(lambda x, t, j: t + j)
    np.testing.assert_allclose(tj, arc.t + arc.j)


def test_save_load_roundtrip(arc, tmp_path):
    p = tmp_path / "arc.npz"
    arc.save(p)
    b = hs.HybridArc.load(p)
    np.testing.assert_array_equal(b.t, arc.t)
    np.testing.assert_array_equal(b.j, arc.j)
    np.testing.assert_array_equal(b.x, arc.x)
    assert b.termination is arc.termination and b.message == arc.message


def test_save_load_components(tmp_path):
    sysm = hs.Interconnection({"a": ball(), "b": ball()})
    a = hs.simulate(sysm, [1, 0, 2, 0], t_max=1.0, j_max=3)
    a.save(tmp_path / "c.npz")
    b = hs.HybridArc.load(tmp_path / "c.npz")
    np.testing.assert_array_equal(b["b"].x, a["b"].x)


def test_to_pandas(arc):
    pd = pytest.importorskip("pandas")
    df = arc.to_pandas()
    assert isinstance(df, pd.DataFrame)
    assert list(df.columns) == ["t", "j", "x0", "x1"] and len(df) == len(arc)
    df = arc.to_pandas(names=["height", "velocity"])
    assert "velocity" in df
    with pytest.raises(ValueError, match="names must have length 2"):
        arc.to_pandas(names=["h"])


def test_component_errors(arc):
    with pytest.raises(KeyError, match="not the solution of an interconnection"):
        arc.component("plant")


def test_constructor_checks_shapes():
    with pytest.raises(ValueError, match=r"expected t \(N,\), j \(N,\), x \(N, n\)"):
        hs.HybridArc([0, 1], [0, 0], np.zeros((3, 2)), hs.Termination.T_MAX)


def test_issue_reproductions_have_clear_answers(arc):
    """Issues 12 and 16: array at(), a window without samples, list(arc), select(t=5)."""
    v = arc.at(np.array([0.1, 0.2]))
    np.testing.assert_allclose(v[:, 0], 1 - 0.5 * 9.81 * np.array([0.01, 0.04]), atol=1e-10)
    k = np.flatnonzero(np.diff(arc.t) > 1e-3)[0]          # a gap between two samples
    a, b = arc.t[k] + 1e-4, arc.t[k + 1] - 1e-4
    w = arc.select(t=(a, b))
    np.testing.assert_array_equal(w.t, [a, b])
    np.testing.assert_allclose(w.x, arc.at([a, b], arc.j[k]), atol=0)
    with pytest.raises(TypeError, match="not iterable"):
        list(arc)
    with pytest.raises(TypeError, match=r"pair \(a, b\)"):
        arc.select(t=5)


def test_copies_keep_the_system(arc):
    import copy
    for c in (copy.copy(arc), copy.deepcopy(arc)):
        assert c.system is not None
        np.testing.assert_array_equal(c.x, arc.x)
        np.testing.assert_array_equal(c.at(0.2), arc.at(0.2))
