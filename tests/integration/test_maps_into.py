"""Maps written into an argument: a plain model's rewritten flow and jump maps,
and a CompiledSystem's jump map so written, give the arcs of the maps returning
arrays; a compiled run of a rate system makes no array per flow evaluation."""
import numpy as np
import pytest

import hybridsim as hs
from hybridsim.library import AIMD, BouncingBall

pytest.importorskip("numba")

from hybridsim.compiled import CompiledSystem, lower


def test_a_plain_models_flow_and_jump_are_written_into_out():
    for system in (BouncingBall(), AIMD()):
        cs = lower(system)
        assert set(cs.maps_into) == {"flow", "jump"}
        x = np.array([0.7, -1.3])[:system.state_dim]
        for role in ("flow", "jump"):
            out = np.full(system.state_dim, np.nan)
            assert cs.maps_into[role](x, 0.0, 0, cs.params, out) is None
            np.testing.assert_array_equal(out, cs.maps[role](x, 0.0, 0, cs.params))
    a = hs.simulate(BouncingBall(), [1.0, 0.0], 3.0, 10, backend="compiled")
    b = hs.simulate(BouncingBall(), [1.0, 0.0], 3.0, 10, backend="python")
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)


def test_a_jump_map_written_into_out_gives_the_same_arc():
    def flow(x, t, j, p):
        return np.array([x[1], -9.81])

    def jump(x, t, j, p):
        return np.array([0.0, -0.8 * x[1]])

    def jump_into(x, t, j, p, out):
        out[0] = 0.0
        out[1] = -0.8 * x[1]

    def guard(x, t, j, p):
        return -x[0] if x[1] <= 0 else -1.0
    arcs = [hs.simulate(CompiledSystem(flow_map=flow, jump_map=g, jump_guard=guard,
                                       state_dim=2), [1.0, 0.0], 3.0, 10, backend="compiled")
            for g in (jump, jump_into)]
    assert arcs[0].jump_count == arcs[1].jump_count > 3
    np.testing.assert_array_equal(arcs[0].t, arcs[1].t)
    np.testing.assert_array_equal(arcs[0].x, arcs[1].x)


def test_a_rate_systems_compiled_run_makes_no_array_a_flow_evaluation():
    """numba's allocations of a compiled AIMD run (the generic kernel): the
    augmented flow map's array an evaluation (its returning form) and the jump's,
    no more (the rewritten maps write into the augmented maps' own arrays)."""
    from numba.core.runtime import _nrt_python, rtsys
    s = AIMD()
    hs.simulate(s, [1.0], 5.0, backend="compiled", seed=1)          # compiled
    was = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        a0 = rtsys.get_allocation_stats().alloc
        arc = hs.simulate(s, [1.0], 100.0, backend="compiled", seed=2)
        made = rtsys.get_allocation_stats().alloc - a0
    finally:
        if not was:
            _nrt_python.memsys_disable_stats()
    assert arc.jump_count > 50
    assert made <= arc.stats["nfev"] + 2 * arc.jump_count + 40, (made, arc.stats)
