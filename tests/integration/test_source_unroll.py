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


def test_li_sanfelice_hc_flow_is_straight_line_with_the_same_numbers(monkeypatch):
    hc = ls.ConstantNoiseObserver(ls.example_VB())
    src, maps, out, p = _maps(hc, True, monkeypatch)
    flow = src[src.index("def _hs_flow"):src.index("def ", src.index("def _hs_flow") + 4)]
    assert "_hs_matmul" not in flow and "swapaxes" not in flow and "_hs_e1 =" in flow
    src0, maps0, out0, p0 = _maps(hc, False, monkeypatch)
    assert "_hs_matmul" in src0
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
