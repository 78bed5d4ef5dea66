"""Maps whose arrays have shapes known when rewritten: straight-line code, the same numbers."""
import numpy as np
import pytest

import hybridsim as hs
from hybridsim import _source

pytest.importorskip("numba")

from hybridsim.compiled import _from_source
from observers import li_sanfelice as ls


def _maps(system, unrolled, monkeypatch):
    monkeypatch.setattr(_source, "_UNROLLED", ("flow", "jump", "output") if unrolled else ())
    _source._BY_CLASS.clear()
    system.__dict__.pop("_source_component", None)
    pl = _source.plan(system, component=True)
    maps, out, p, _ = _from_source.component_maps(system)
    return pl.source, maps, out, p


def test_li_sanfelice_hc_flow_is_straight_line(monkeypatch):
    """H_c's flow is rewritten into straight-line code (no matrix product left);
    without the unroll it keeps them. Its numbers: the slow test below (the
    rewritten maps compiled cold take about 12 s of CPU)."""
    hc = ls.ConstantNoiseObserver(ls.example_VB())
    src, *_ = _maps(hc, True, monkeypatch)
    flow = src[src.index("def _hs_flow"):src.index("def ", src.index("def _hs_flow") + 4)]
    assert "_hs_matmul" not in flow and "swapaxes" not in flow and "_hs_e1 =" in flow
    src0, *_ = _maps(hc, False, monkeypatch)
    assert "_hs_matmul" in src0
    _source._BY_CLASS.clear()


@pytest.mark.slow
def test_li_sanfelice_hc_straight_line_has_the_same_numbers(monkeypatch):
    """H_c's unrolled maps, compiled, give the numbers of the rewrite that keeps
    the matrix products, bit for bit."""
    hc = ls.ConstantNoiseObserver(ls.example_VB())
    _, maps, out, p = _maps(hc, True, monkeypatch)
    _, maps0, out0, p0 = _maps(hc, False, monkeypatch)
    rng = np.random.default_rng(1)
    for _ in range(5):
        x, u = rng.standard_normal(hc.state_dim), rng.standard_normal(hc.input_dim)
        x[-1] = 0.0
        for role in ("flow", "jump"):
            np.testing.assert_array_equal(maps[role](x, u, 0.1, 0, p),
                                          maps0[role](x, u, 0.1, 0, p0))
        np.testing.assert_array_equal(out(x, 0.1, 0, p), out0(x, 0.1, 0, p0))
    _source._BY_CLASS.clear()


class _Branchy(hs.HybridSystem):
    """A flow whose test is decided when it runs: kept as the rewrite wrote it."""

    state_dim, input_dim = 2, 1

    def __init__(self):
        self.M = np.array([[0.0, 1.0], [-1.0, -0.1]])

    def flow_map(self, x, t, j, u):
        dx = self.M @ x
        if x[0] > 0:
            dx = dx + u[0]
        return dx


def test_a_test_decided_at_run_time_keeps_the_rewrite(monkeypatch):
    src, maps, _, p = _maps(_Branchy(), True, monkeypatch)
    assert "_hs_e1" not in src and "if x[0] > 0" in src
    x = np.array([0.5, -0.2])
    np.testing.assert_allclose(maps["flow"](x, np.array([1.0]), 0.0, 0, p),
                               np.array([[0.0, 1.0], [-1.0, -0.1]]) @ x + 1.0)
    _source._BY_CLASS.clear()


def _noise():
    from observers.li_sanfelice.systems import BoundedNoiseGenerator
    return BoundedNoiseGenerator(2, 3)


def _node():
    from observers.distributed import example_observer
    return example_observer().nodes[1]


@pytest.mark.parametrize("make, role", [(_noise, "output"), (_node, "flow")],
                         ids=["noise-sum-of-sines", "node-copysign-power"])
def test_sums_binary_ufuncs_and_a_times_axes_are_straight_line(make, role, monkeypatch):
    """np.sum(..., axis=-1) of a few terms (numpy's order: from the first), np.copysign
    of arrays and a number's t[..., None, None]: written as numbers, the same ones."""
    system = make()
    src, maps, out, p = _maps(system, True, monkeypatch)
    body = src[src.index(f"def _hs_{role}("):]
    body = body[:body.find("\ndef ")] if "\ndef " in body else body
    assert "_hs_e1 =" in body and "sum(" not in body and "_hs_pmv" not in body
    src0, maps0, out0, p0 = _maps(system, False, monkeypatch)
    assert "_hs_e1 =" not in src0
    rng = np.random.default_rng(2)
    for _ in range(5):
        x, u = rng.standard_normal(system.state_dim), rng.standard_normal(system.input_dim)
        np.testing.assert_array_equal(maps["flow"](x, u, 0.3, 0, p),
                                      maps0["flow"](x, u, 0.3, 0, p0))
        np.testing.assert_array_equal(out(x, 0.3, 0, p), out0(x, 0.3, 0, p0))
    _source._BY_CLASS.clear()


class _ElementSet(hs.HybridSystem):
    """A flow that sets one element of a new array as ``dx[..., 1]``."""

    state_dim = 2

    def flow_map(self, x, t):
        dx = np.zeros(x.shape)
        dx[..., 0] = x[..., 1]
        dx[..., 1] = -x[..., 0]
        return dx


def test_an_element_set_on_the_last_axis_is_straight_line(monkeypatch):
    src, maps, _, p = _maps(_ElementSet(), True, monkeypatch)
    assert "_hs_r[1] =" in src and "dx[1]" not in src          # written as numbers
    np.testing.assert_array_equal(maps["flow"](np.array([0.5, -0.2]), np.zeros(0), 0.0, 0, p),
                                  [-0.2, -0.5])
    _source._BY_CLASS.clear()
