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
    with pytest.warns(DeprecationWarning) as record:
        was = Component(state_dim=1, input_dim=1, flow=flow, jump=jump, params=[2.0])
    assert sorted(str(w.message) for w in record) == [
        "Component: the keyword flow= is deprecated, use flow_map=",
        "Component: the keyword jump= is deprecated, use jump_map="]
    assert all(w.filename == __file__ for w in record)      # the caller's line
    now = Component(state_dim=1, input_dim=1, flow_map=flow, jump_map=jump, params=[2.0])
    assert was.maps == now.maps
    np.testing.assert_array_equal(was.params, now.params)


# ------------------------------------------------------------------ the runners
def _runners():
    from hybridsim.batch_vectorized import simulate_vectorized
    from hybridsim.compiled import simulate_compiled, simulate_many_compiled
    from hybridsim.falsification import falsify
    return {f.__name__: f for f in (
        hs.simulate, hs.simulate_many, hs.sweep, hs.explore, hs.simulate_sensitivity,
        falsify, simulate_vectorized, simulate_compiled, simulate_many_compiled)}


#: what a runner's leading positional parameters are called, by what it runs
_HEAD = {"simulate": ("system", "x0", "t_max", "j_max"),
         "simulate_many": ("system", "x0s", "t_max", "j_max"),
         "sweep": ("make_system", "params", "x0", "t_max", "j_max"),
         "explore": ("system", "x0", "t_max", "j_max"),
         "simulate_sensitivity": ("system", "x0", "t_max", "j_max"),
         "falsify": ("run", "space", "claim"),
         "simulate_vectorized": ("system", "x0s", "t_max", "j_max"),
         "simulate_compiled": ("system", "x0", "t_max", "j_max"),
         "simulate_many_compiled": ("system", "x0s", "t_max", "j_max")}

#: names other libraries use for a concept these runners name otherwise
_SYNONYMS = {"x_0": "x0", "x_init": "x0", "y0": "x0", "initial_state": "x0",
             "x0_batch": "x0s", "tmax": "t_max", "t_end": "t_max", "t_final": "t_max",
             "T": "t_max", "jmax": "j_max", "max_jumps": "j_max", "n_jumps": "j_max",
             "tmin": "t0", "t_start": "t0", "reltol": "rtol", "abstol": "atol",
             "rel_tol": "rtol", "abs_tol": "atol", "solver": "method",
             "integrator": "method", "engine": "backend", "path": "backend",
             "rng": "seed", "random_state": "seed", "raise_on_error": "throw",
             "raises": "throw", "verbose": "progress", "show_progress": "progress",
             "hmax": "max_step", "dt_max": "max_step", "h0": "first_step",
             "kwargs": "options", "kw": "options"}

#: a name shared with another meaning, on purpose: falsify's search
#: (method "de"/"random", refine the worst point, seed of the search)
_OTHER_MEANING = {("falsify", "method"), ("falsify", "refine"), ("falsify", "seed")}


def test_the_runners_share_one_parameter_vocabulary():
    import inspect
    runners = _runners()
    sigs = {name: inspect.signature(f) for name, f in runners.items()}
    for name, sig in sigs.items():
        params = list(sig.parameters.values())
        assert tuple(p.name for p in params[:len(_HEAD[name])]) == _HEAD[name], name
        assert sig.return_annotation is not inspect.Signature.empty, name
        for p in params:
            assert p.annotation is not inspect.Parameter.empty, f"{name}({p.name}) unannotated"
            assert p.name not in _SYNONYMS, \
                f"{name}({p.name}): this vocabulary's name is {_SYNONYMS[p.name]}"
            if p.kind is p.VAR_KEYWORD:    # forwarded to simulate, or refused by name
                assert p.name in ("options", "unsupported"), (name, p.name)
    # one name, one meaning: the same annotation everywhere, the same default
    # where the default is not the runner's own (a batch keeps going: throw=False)
    seen = {}
    for name, sig in sigs.items():
        for p in sig.parameters.values():
            if (name, p.name) not in _OTHER_MEANING and p.kind is p.KEYWORD_ONLY:
                seen.setdefault(p.name, []).append((name, p))
    shared = {k: v for k, v in seen.items() if len(v) > 1}
    assert {"t0", "j0", "rtol", "atol", "method", "seed", "backend", "priority", "max_step",
            "throw", "warn", "progress"} <= set(shared)
    for pname, where in shared.items():
        notes = {str(p.annotation) for _, p in where}
        assert len(notes) == 1, (pname, [(n, str(p.annotation)) for n, p in where])
        if pname not in ("throw", "progress", "backend"):
            defaults = {repr(p.default) for _, p in where}
            assert len(defaults) == 1, (pname, [(n, p.default) for n, p in where])
    # the simulation runners' options are simulate's (or forwarded to it), but for
    # the compiled batch's own (threads, memory, the reduction simulate_many's
    # stats= hands it and the rows' p its attributes= does)
    front = sigs["simulate"].parameters
    for name in ("simulate_vectorized", "simulate_compiled", "simulate_many_compiled"):
        for p in sigs[name].parameters.values():
            if p.kind is p.KEYWORD_ONLY and p.name not in ("parallel", "chunk_bytes", "reduce",
                                                          "params"):
                assert p.name in front, (name, p.name)
                assert str(p.annotation) == str(front[p.name].annotation), (name, p.name)
