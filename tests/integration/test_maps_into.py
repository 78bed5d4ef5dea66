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


def test_the_held_sample_buffers_are_released_at_every_end():
    """The run core holds its sample buffers by hand (``_types._hold``): at every
    end of a run (t_max, a map's raise, max_steps, max_samples, a batch, a rate
    system's coin flips) numba's live allocations come back to where they were
    once the arcs are dropped: no buffer leaks."""
    import gc

    from numba.core.runtime import _nrt_python, rtsys

    from hybridsim.compiled import CompiledSystem, lower, simulate_compiled
    from hybridsim.library import BouncingBall

    def raises_above(x, t, j, p):
        if x[0] > p[0]:
            raise ValueError("x above its range")
        return np.array([1.0])
    bad = CompiledSystem(state_dim=1, params=[0.5], flow_map=raises_above)
    ball = lower(BouncingBall())
    x0s = np.column_stack([np.linspace(1.0, 2.0, 40), np.zeros(40)])
    ends = {"t_max": lambda: simulate_compiled(ball, [1.0, 0.0], t_max=10.0),
            "map error": lambda: simulate_compiled(bad, [0.0], t_max=2.0, max_step=0.1,
                                                   throw=False),
            "max_steps": lambda: simulate_compiled(ball, [1.0, 0.0], t_max=10.0, max_steps=7,
                                                   warn=False),
            "max_samples": lambda: simulate_compiled(ball, [1.0, 0.0], t_max=10.0,
                                                     max_samples=5, warn=False),
            "batch": lambda: hs.simulate_many(BouncingBall(), x0s, t_max=10.0,
                                              backend="compiled"),
            "rate": lambda: hs.simulate(AIMD(), [1.0], t_max=50.0, seed=1,
                                        backend="compiled")}
    for run in ends.values():                   # compiled, its one-off arrays made
        run()
    was = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()

    def live():
        gc.collect()
        s = rtsys.get_allocation_stats()
        return s.alloc - s.free, s.mi_alloc - s.mi_free
    # the process's objects so far out of the collector's sight: each collection
    # then walks what the runs made (in a test process holding the suite's
    # objects, twelve full collections took about 3 s)
    gc.collect()
    gc.freeze()
    try:
        for end, run in ends.items():
            before = live()
            for _ in range(3):
                arc = run()
                del arc
            assert live() == before, end
    finally:
        gc.unfreeze()
        if not was:
            _nrt_python.memsys_disable_stats()
