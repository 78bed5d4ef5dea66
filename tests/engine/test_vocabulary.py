"""One vocabulary: the maps' keywords are the HybridSystem methods' names
(flow_map, jump_map, flow_set, jump_set, jump_guard, flow_guard,
jump_map_values) in HybridSystem.from_functions, CompiledSystem and
Component; the former names work with a DeprecationWarning naming the new
one, and build the same system."""
import warnings

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.compiled import CompiledSystem, Component


def _ball_maps():
    return dict(flow_map=lambda x: np.array([x[1], -9.81]),
                jump_map=lambda x: np.array([0.0, -0.8 * x[1]]),
                flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0)


def _same_run(a, b):
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.j, b.j)
    np.testing.assert_array_equal(a.x, b.x)


def test_from_functions_old_keywords_warn_and_build_the_same_system():
    new = _ball_maps()
    old = dict(zip(("f", "g", "C", "D"), new.values()))
    with pytest.warns(DeprecationWarning) as record:
        was = hs.HybridSystem.from_functions(**old, state_dim=2)
    said = [str(w.message) for w in record]
    for o, n in zip(old, new):
        assert any(f"keyword {o}= is deprecated, use {n}=" in s for s in said), (o, said)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        now = hs.HybridSystem.from_functions(**new, state_dim=2)
        positional = hs.HybridSystem.from_functions(*new.values(), state_dim=2)
    for s in (was, positional):
        _same_run(hs.simulate(s, [1.0, 0.0], t_max=3.0, j_max=5),
                  hs.simulate(now, [1.0, 0.0], t_max=3.0, j_max=5))


def test_from_functions_old_set_valued_keyword():
    succ = lambda x: [np.array([0.0]), np.array([0.5])]          # noqa: E731
    kw = dict(flow_map=lambda x: np.array([1.0]), jump_set=lambda x: x[0] >= 1.0,
              flow_set=lambda x: x[0] <= 1.0, state_dim=1)
    with pytest.warns(DeprecationWarning, match="g_values= is deprecated, use jump_map_values="):
        was = hs.HybridSystem.from_functions(g_values=succ, **kw)
    now = hs.HybridSystem.from_functions(jump_map_values=succ, **kw)
    assert was.jump_map_values is now.jump_map_values is succ
    _same_run(hs.simulate(was, [0.0], t_max=3.0, j_max=2),
              hs.simulate(now, [0.0], t_max=3.0, j_max=2))


def test_a_map_under_both_names_or_an_unknown_keyword_is_refused():
    f = lambda x: -x                                             # noqa: E731
    with pytest.raises(TypeError, match="f= is the deprecated name of flow_map=; give one"):
        hs.HybridSystem.from_functions(flow_map=f, f=f, state_dim=1)
    with pytest.raises(TypeError, match="unexpected keyword argument 'flow'"):
        hs.HybridSystem.from_functions(flow=f, state_dim=1)
    with pytest.raises(TypeError, match="jump= is the deprecated name of jump_map="):
        CompiledSystem(lambda x, t, j, p: -x, jump_map=lambda x, t, j, p: x,
                       jump=lambda x, t, j, p: x, state_dim=1)
    with pytest.raises(TypeError, match="unexpected keyword argument 'f'"):
        Component(state_dim=1, f=lambda x, u, t, j, p: -x)


def test_compiled_system_old_keywords_warn_and_build_the_same_system():
    flow = lambda x, t, j, p: np.array([x[1], -p[0]])            # noqa: E731
    jump = lambda x, t, j, p: np.array([0.0, -p[1] * x[1]])      # noqa: E731
    rest = dict(jump_guard=lambda x, t, j, p: -x[0], flow_guard=lambda x, t, j, p: x[0],
                jump_set=lambda x, t, j, p: x[0] <= 0.0 and x[1] <= 0.0,
                state_dim=2, params=[9.81, 0.8])
    with pytest.warns(DeprecationWarning) as record:
        was = CompiledSystem(flow=flow, jump=jump, **rest)
    said = " | ".join(str(w.message) for w in record)
    assert "CompiledSystem: the keyword flow= is deprecated, use flow_map=" in said
    assert "the keyword jump= is deprecated, use jump_map=" in said
    now = CompiledSystem(flow_map=flow, jump_map=jump, **rest)
    assert was.maps == now.maps
    _same_run(hs.simulate(was, [1.0, 0.0], t_max=2.0, j_max=3),
              hs.simulate(now, [1.0, 0.0], t_max=2.0, j_max=3))


def test_component_old_keywords_warn_and_build_the_same_component():
    flow = lambda x, u, t, j, p: -p[0] * x + u                   # noqa: E731
    jump = lambda x, u, t, j, p: 0.0 * x                         # noqa: E731
    with pytest.warns(DeprecationWarning, match="Component: the keyword flow= is deprecated, "
                                                "use flow_map="):
        was = Component(state_dim=1, input_dim=1, flow=flow, jump=jump, params=[2.0])
    now = Component(state_dim=1, input_dim=1, flow_map=flow, jump_map=jump, params=[2.0])
    assert was.maps == now.maps
    np.testing.assert_array_equal(was.params, now.params)
