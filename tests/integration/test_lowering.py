"""Ordinary systems on the compiled path (issue 27, deliverable 4).

``backend="compiled"`` lowers a ``LinearPlant``, a system with a compiled
form and interconnections of them wired by ``hs.LinearInput`` to one
``CompiledSystem`` (``hybridsim.compiled.lower``), and refuses the rest by
name. The same systems run on the three paths (``path`` parameter of
``tests/paths.py``): Python, the vectorized batch, compiled.

Tolerances: the paths take the same Dormand-Prince steps in exact
arithmetic; in floating point the error estimate (a difference of two
nearly equal solutions) magnifies round-off, so the step sizes part by about
1e-10 relative and runs at rtol 1e-10 agree to 1e-8 (the integrator's
tolerance over the horizon), as in ``tests/integration/test_paths.py``.
"""
import networkx as nx
import numpy as np
import pytest
from paths import HAS_NUMBA, NO_NUMBA

import hybridsim as hs
from hybridsim.compiled import CompiledSystem, Component, lower, lowerable
from observers.distributed.example import EXAMPLE_V0, example_observer, stable_initial_state
from observers.distributed.example import noise_batch as dist_noise_batch
from observers.distributed.systems import initial_state
from observers.li_sanfelice.example import noise_batch as ls_noise_batch
from observers.li_sanfelice.systems import BoundedNoiseGenerator

needs_numba = pytest.mark.skipif(not HAS_NUMBA, reason=NO_NUMBA)
RTOL, ATOL = 1e-10, 1e-12
A = np.array([[0.0, 1.0], [-1.0, -0.2]])
C = np.array([[1.0, 0.0]])
L = np.array([[1.5], [0.8]])


def luenberger():
    """Plant (A, C) and the Luenberger observer xhat' = (A - L C) xhat + L y."""
    plant = hs.LinearPlant(A, C=C)
    obs = hs.LinearPlant(A - L @ C, B=L)
    return hs.connect(plant, obs)


def _run(path, system, x0, **kw):
    kw = dict(rtol=RTOL, atol=ATOL, **kw)
    if path == "python":
        return hs.simulate(system, x0, **kw)
    if path == "vectorized":
        return hs.simulate_vectorized(system, [x0], **kw)[0]
    return hs.simulate(system, x0, backend="compiled", **kw)


@pytest.mark.paths(compiled_slow=True)
def test_a_cascade_runs_on_every_path_and_agrees(path):
    """Luenberger observer of a damped oscillator: the error e = xhat - x obeys
    e' = (A - L C) e on every path (checked against expm to 1e-8)."""
    from scipy.linalg import expm
    sys = luenberger()
    x0 = np.array([1.0, -0.5, 0.0, 0.0])
    arc = _run(path, sys, x0, t_max=4.0)
    ref = _run("python", sys, x0, t_max=4.0)
    np.testing.assert_allclose(arc.xf, ref.xf, rtol=0, atol=1e-8)
    e = arc["observer"].x - arc["plant"].x
    e4 = expm(4.0 * (A - L @ C)) @ (x0[2:] - x0[:2])
    np.testing.assert_allclose(e[-1], e4, rtol=0, atol=1e-8)
    assert arc.system is sys and list(arc.components) == ["plant", "observer"]


# a component with jumps: a sampler that holds its input every period
class Sampler(hs.HybridSystem):
    """z = (held value, timer): z+ = (u, 0) when the timer reaches the period
    (one definition: the compiled path rewrites these maps)."""

    state_dim, input_dim = 2, 1
    vectorized = True               # the maps take batches (N, 2) too

    def __init__(self, period):
        self.period = period

    def flow_map(self, x, t, j, u):
        out = np.zeros_like(x)
        out[..., 1] = 1.0
        return out

    def jump_guard(self, x, t, j, u):
        return x[..., 1] - self.period

    def jump_map(self, x, t, j, u):
        out = np.zeros_like(x)
        out[..., 0] = u[..., 0]
        return out


@pytest.mark.paths(compiled_slow=True)
def test_a_component_with_jumps_samples_a_linear_combination(path):
    """plant x' = A x; a sampler holding u = 2 x1 - x2 (a LinearInput matrix)
    every 0.3 s: jumps at k 0.3, the held value equal to u at the jump."""
    plant = hs.LinearPlant(A)
    sys = hs.Interconnection({"plant": plant, "s": Sampler(0.3)},
                             inputs={"s": hs.LinearInput({"plant": [[2.0, -1.0]]})})
    x0 = np.array([1.0, 0.0, 0.0, 0.0])
    arc = _run(path, sys, x0, t_max=1.0)
    np.testing.assert_allclose(arc.jump_times, [0.3, 0.6, 0.9], rtol=0, atol=1e-12)
    for k, tj in enumerate(arc.jump_times):
        before = arc.at(tj, k)
        after = arc.at(tj, k + 1)
        assert after[2] == pytest.approx(2 * before[0] - before[1], abs=1e-12)
    ref = _run("python", sys, x0, t_max=1.0)
    np.testing.assert_allclose(arc.xf, ref.xf, rtol=0, atol=1e-8)


class Agent(hs.HybridSystem):
    """x' = sum of received - deg x (consensus; its maps rewritten on the compiled path)."""

    state_dim = 1
    vectorized = True

    def __init__(self, deg):
        self.deg = float(deg)
        self.input_dim = 1

    def flow_map(self, x, t, j, u):
        return u - self.deg * x


@pytest.mark.paths(compiled_slow=True)
def test_a_network_over_a_graph_reaches_consensus_on_every_path(path):
    """Directed ring of 5 agents, x_i' = x_{i-1} - x_i: the average is kept
    (the Laplacian of a ring is balanced) and every agent reaches it."""
    G = nx.cycle_graph(5, create_using=nx.DiGraph)
    net = hs.network(G, lambda v: Agent(1.0),
                     {v: hs.LinearInput({w: None}) for v in G for w in G.predecessors(v)})
    x0 = net.stack({v: float(v) for v in G})
    arc = _run(path, net, x0, t_max=30.0)
    np.testing.assert_allclose(arc.xf, np.full(5, 2.0), rtol=0, atol=1e-6)
    ref = _run("python", net, x0, t_max=30.0)
    np.testing.assert_allclose(arc.xf, ref.xf, rtol=0, atol=1e-8)


@needs_numba
def test_the_lowered_maps_are_a_generated_modules_and_their_wrappers_cached():
    """The stacked maps are generated in a module with a file (named by the digest
    of their text and of every part's maps), so the engine's wrappers of them
    are cached on disk with the parts' code: a new process loads them (they were
    compiled in memory in every process: 10 s for paper 004's loop)."""
    from hybridsim.compiled._cache import wrap_map
    cs = lower(luenberger())
    mod = cs.maps["flow"].__module__
    assert mod.startswith("hybridsim_lowered_")
    w = wrap_map(cs.maps["flow"], "vec")
    assert w.py_func.__module__.startswith("hybridsim_wrap_")
    assert w._cache._cache_path is not None and w.overloads


@needs_numba
def test_a_second_system_of_the_same_structure_compiles_nothing():
    """The lowered maps read every number from the parameters: another plant
    of the same dimensions reuses them, and runs with its own numbers."""
    s1 = hs.LinearPlant(-np.eye(2))
    s2 = hs.LinearPlant(-2.0 * np.eye(2))
    c1, c2 = lower(s1), lower(s2)
    assert c2._nb is c1._nb or c2.maps is c1.maps
    a = hs.simulate(s2, [1.0, 1.0], t_max=1.0, rtol=RTOL, atol=ATOL, backend="compiled")
    np.testing.assert_allclose(a.xf, np.exp(-2.0) * np.ones(2), rtol=1e-9)
    assert lower(s1) is c1                       # cached on the system


@pytest.mark.slow
@needs_numba
def test_a_compiled_system_is_a_component_too():
    """A CompiledSystem (maps of (x, t, j, p)) stacks with a LinearPlant."""
    timer = CompiledSystem(flow_map=lambda x, t, j, p: np.ones(1),
                           jump_map=lambda x, t, j, p: np.zeros(1),
                           jump_guard=lambda x, t, j, p: x[0] - p[0], state_dim=1,
                           params=[0.25])
    sys = hs.Interconnection({"timer": timer, "plant": hs.LinearPlant([[-1.0]])})
    arc = hs.simulate(sys, [0.0, 1.0], t_max=1.0, backend="compiled", rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(arc.jump_times, [0.25, 0.5, 0.75, 1.0], atol=1e-12)
    assert arc["plant"].xf[0] == pytest.approx(np.exp(-1.0), rel=1e-9)


# ------------------------------------------------------------------ refusals, by name
class NoForm(hs.HybridSystem):
    state_dim = 1

    def flow_map(self, x):
        return -x


class Labelled(NoForm):
    """A plain part whose map reads a list of strings: not rewritable for numba."""
    labels = ("decay",)

    def flow_map(self, x):
        return -x if self.labels[0] == "decay" else x


@pytest.mark.paths(compiled_slow=True)
def test_a_plain_part_runs_compiled_from_its_own_maps(path):
    """A plain model with an input (no compiled form) wired in an interconnection
    beside a LinearPlant: its maps and the plant's are rewritten as functions of
    (x, u, t, j, p) on the compiled path; the Python path's solution."""
    class Follower(hs.HybridSystem):
        state_dim, input_dim, vectorized = 1, 1, True

        def __init__(self, k):
            self.k = k

        def flow_map(self, x, t, j, u):
            return self.k * (u - x)

    class Decay(NoForm):
        vectorized = True
    sys = hs.Interconnection({"a": hs.LinearPlant([[-1.0]]), "b": Decay(),
                              "f": Follower(2.0)}, inputs={"f": hs.LinearInput({"a": None})})
    assert lowerable(sys)
    x0 = np.array([1.0, 1.0, 0.0])
    arc = _run(path, sys, x0, t_max=2.0)
    # f' = 2 (e^-t - f), f(0) = 0: f = 2 (e^-t - e^-2t)
    exact = [np.exp(-2.0), np.exp(-2.0), 2 * (np.exp(-2.0) - np.exp(-4.0))]
    np.testing.assert_allclose(arc.xf, exact, rtol=1e-8)


@pytest.mark.parametrize("make, match", [
    (lambda: hs.Interconnection({"a": hs.LinearPlant([[-1.0]]), "b": Labelled()}),
     r"component 'b' \(Labelled\) cannot run compiled: Labelled has no compiled form and "
     r"its maps cannot be rewritten for numba: Labelled.flow_map \(.*test_lowering.py:\d+\): "
     r"it reads self.labels, a tuple"),
    (lambda: hs.Interconnection({"plant": hs.LinearPlant([[-1.0]]), "observer": Agent(1.0)},
                                inputs={"observer": lambda t, y: y["plant"]}),
     r"the input of component 'observer' cannot run compiled: it is a Python callable"),
    (lambda: hs.LinearPlant([[-1.0]], noise=lambda t: np.zeros(1)),
     r"LinearPlant cannot run compiled: its noise is a Python callable of t"),
    (lambda: Agent(1.0), r"Agent cannot run compiled: Agent has no compiled form .*: it "
                         r"has an input \(input_dim=1\); connect it in an Interconnection"),
])
def test_what_cannot_be_lowered_is_refused_by_name(make, match):
    system = make()
    assert not lowerable(system)
    if not HAS_NUMBA and isinstance(system, hs.Interconnection):
        pytest.skip(NO_NUMBA)
    with pytest.raises(TypeError, match=match):
        hs.simulate(system, np.zeros(system.state_dim), t_max=1.0, backend="compiled")


def test_an_output_reading_its_input_is_refused_by_name():
    class Feedthrough(Agent):
        def output(self, x, t, j, u):
            return x + u
    with pytest.raises(TypeError, match="its output reads its input"):
        lower(Feedthrough(1.0))
    # lowerable reads the same refusals (auto must not pick what lower refuses)
    ic = hs.Interconnection({"p": hs.LinearPlant([[-1.0]]), "a": Feedthrough(1.0)},
                            inputs={"a": hs.LinearInput({"p": None})})
    assert not lowerable(ic)


def test_a_set_valued_jump_map_is_refused_by_name():
    class Branching(Agent):
        def jump_map_values(self, x, t, j, u):
            return [x, -x]
    with pytest.raises(TypeError, match="its jump map is set-valued"):
        lower(Branching(1.0))
    assert not lowerable(Branching(1.0))


def test_a_system_reading_its_history_is_refused_by_name():
    s = NoForm()
    s.needs_history = True
    with pytest.raises(TypeError, match="it reads its history"):
        lower(s)


def test_components_and_lowering_check_their_arguments():
    def _agent_flow(x, u, t, j, p):
        return u - p[0] * x
    with pytest.raises(ValueError, match="params must be finite"):
        Component(state_dim=1, flow_map=_agent_flow, params=[np.nan])
    with pytest.raises(TypeError, match="params must be an array of floats"):
        Component(state_dim=1, flow_map=_agent_flow, params=object())
    with pytest.raises(ValueError, match="state_dim must be a positive int"):
        Component(state_dim=0, flow_map=_agent_flow)
    with pytest.raises(TypeError, match="flow_map must be callable"):
        Component(state_dim=1, flow_map=3.0)
    with pytest.raises(TypeError, match="system must be a hybridsim.HybridSystem"):
        lowerable(5)
    with pytest.raises(TypeError, match="system must be a hybridsim.HybridSystem"):
        lower("plant")


def test_linear_input_checks_its_terms():
    with pytest.raises(TypeError, match="terms must be a non-empty dict"):
        hs.LinearInput({})
    with pytest.raises(ValueError, match="the same number of rows"):
        hs.LinearInput({"a": np.ones((2, 1)), "b": np.ones((3, 1))})
    with pytest.raises(ValueError, match=r"reads \['nope'\], which are not components"):
        hs.Interconnection({"p": hs.LinearPlant([[-1.0]]), "a": Agent(1.0)},
                           inputs={"a": hs.LinearInput({"nope": None})})
    G = nx.DiGraph([(0, 1), (1, 0)])
    with pytest.raises(ValueError, match=r"neither in-neighbours of 1 in G nor exogenous"):
        hs.network(G, lambda v: Agent(1.0), {0: hs.LinearInput({1: None}),
                                              1: hs.LinearInput({1: None})})


@needs_numba
def test_a_component_of_the_wrong_size_is_named_before_compiling():
    class Bad(hs.HybridSystem):
        state_dim = 2

        def flow_map(self, x):
            return -x

        def compiled_component(self):
            return Component(state_dim=2, flow_map=lambda x, u, t, j, p: np.zeros(3))
    with pytest.raises(ValueError, match=r"the system: its compiled flow map returns shape "
                                         r"\(3,\), expected \(2,\)"):
        lower(Bad())


@pytest.mark.slow
@needs_numba
def test_auto_picks_compiled_where_the_system_allows_it(monkeypatch):
    """backend="auto": compiled for a lowerable system at RK45 or DOP853, the
    numpy batch otherwise (another method, or a callable input)."""
    import hybridsim.compiled as hc
    calls = []
    real = hc.simulate_many_compiled
    monkeypatch.setattr(hc, "simulate_many_compiled",
                        lambda *a, **k: calls.append(1) or real(*a, **k))
    sys = luenberger()
    x0s = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
    arcs = hs.simulate_many(sys, x0s, t_max=1.0, backend="auto")
    assert calls == [1] and arcs[0].system is sys
    hs.simulate_many(sys, x0s, t_max=1.0, backend="auto", method="DOP853")
    assert calls == [1, 1]
    hs.simulate_many(sys, x0s, t_max=1.0, backend="auto", method="RK23")
    assert calls == [1, 1]


def test_reads_input_sees_through_the_bytecode():
    from hybridsim.compiled._lower import _reads_input
    assert _reads_input(lambda x, u, t, j, p: u - x)
    assert not _reads_input(lambda x, u, t, j, p: x[0] - p[0])


# ------------------------------------------------------------------ the papers' observers
def _ls_batch(kind, noise_states):
    from observers import li_sanfelice as ls
    d = ls.example_VB()
    obs = {"H_n": ls.NominalObserver, "H_c": ls.ConstantNoiseObserver,
           "H_pc": ls.PiecewiseConstantNoiseObserver}[kind](d)
    gen = BoundedNoiseGenerator(d.p, 1)
    sysm, x0s = ls_noise_batch(obs, [1.0, -0.5], np.zeros(d.n), noise_states, gen)
    return d, obs, sysm, x0s


@needs_numba
@pytest.mark.slow
@pytest.mark.parametrize("kind", ["H_n", "H_c", "H_pc"])
def test_li_sanfelice_observers_run_compiled_and_agree_with_python(kind):
    """H_n (10)-(12), H_c (17)-(18) and H_pc (jumping every delta) with a noise
    generator, lowered: the
    compiled run agrees with the Python path to 1e-9 (their arithmetic is the
    same products; measured 1e-15), and under constant noise (generator with
    omega = 0, phi = pi/2) H_c is exact after its jump on the compiled path
    as on the Python path (Theorem 4.13): the errors after the jump within
    10x the Python path's, and m̂ = m."""
    from observers import li_sanfelice as ls
    m = np.array([0.3, -0.2])
    S = np.array([[m[0], m[1], 0.0, 0.0, np.pi / 2, np.pi / 2]])  # (a, omega, phi), p = 2, K = 1
    d, obs, sysm, x0s = _ls_batch(kind, S)
    kw = dict(t_max=2 * d.delta, rtol=RTOL, atol=ATOL)
    py = hs.simulate(sysm, x0s[0], **kw)
    cc = hs.simulate(sysm, x0s[0], backend="compiled", **kw)
    assert cc.jump_count == py.jump_count == (2 if kind == "H_pc" else 1)
    np.testing.assert_allclose(cc.jump_times, py.jump_times, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cc.xf, py.xf, rtol=0, atol=1e-9)
    e_py, e_cc = (ls.errors(a, obs) for a in (py, cc))
    post_py, post_cc = py.j >= 1, cc.j >= 1
    if kind in ("H_c", "H_pc"):
        worst_py = np.abs(e_py["e1"][post_py]).max()
        assert np.abs(e_cc["e1"][post_cc]).max() <= 10 * worst_py + 1e-12
        np.testing.assert_allclose(e_cc["mhat"][post_cc][-1], m, rtol=0, atol=1e-8)
    else:                                    # H_n under constant noise: e(delta, 1) = T m (15)
        np.testing.assert_allclose(e_cc["e1"][post_cc][0], d.T @ m, rtol=0, atol=1e-8)


@needs_numba
@pytest.mark.slow
def test_a_noise_monte_carlo_of_hc_agrees_between_the_batch_paths():
    """200 bounded sinusoidal noise realisations (seeded): the compiled batch
    and the vectorized numpy batch give the same error after the jump to 1e-8
    (both RK45 at rtol 1e-10), and each arc is the interconnection's."""
    from observers import li_sanfelice as ls
    d = ls.example_VB()
    gen = BoundedNoiseGenerator(d.p, 3)
    obs = ls.ConstantNoiseObserver(d)
    sysm, x0s = ls_noise_batch(obs, [1.0, -0.5], np.zeros(d.n),
                               gen.random_states(200, 0.3, seed=3), gen)
    kw = dict(t_max=1.2 * d.delta, rtol=RTOL, atol=ATOL)
    vec = hs.simulate_many(sysm, x0s, **kw)
    cc = hs.simulate_many(sysm, x0s, backend="compiled", **kw)

    def after_jump(arcs):
        return np.array([ls.errors(a, obs).e[np.flatnonzero(a.j == 1)[0]] for a in arcs])
    np.testing.assert_allclose(after_jump(cc), after_jump(vec), rtol=0, atol=1e-8)
    assert all(a.system is sysm for a in cc)


@needs_numba
@pytest.mark.slow
def test_the_distributed_observer_runs_compiled_with_band_limited_noise():
    """The finite-time distributed observer (7)-(8) of Section 4 over its ring,
    with a band-limited noise component: compiled and Python runs agree to
    the integrator's tolerance (rtol 1e-8: the signed powers' steep slopes
    near 0 part the step sequences, so to 1e-5 of the error's scale), and
    without noise the compiled run settles (Theorem 1: every node's error
    below 1e-6 by t = 8)."""
    from observers import distributed as dist
    obs = example_observer()
    dsg = obs.design
    x0 = stable_initial_state(dsg.A, EXAMPLE_V0)
    sysm, X = dist_noise_batch(obs, x0, power=1e-4, seeds=[0], t_max=4.0)
    kw = dict(t_max=4.0, rtol=1e-8, atol=1e-10)
    py = hs.simulate(sysm, X[0], **kw)
    cc = hs.simulate(sysm, X[0], backend="compiled", **kw)
    scale = np.abs(py.x).max()
    np.testing.assert_allclose(cc.xf, py.xf, rtol=0, atol=1e-5 * scale)
    clean = hs.simulate(obs.interconnection(), initial_state(dsg, x0), t_max=8.0,
                        rtol=1e-10, atol=1e-12, backend="compiled")
    E = dist.errors(clean, obs)
    assert E["norm"][-1] < 1e-6


def _random_loop(seed):
    """Three linear plants in a feedback loop, wired by random (dense) LinearInput
    matrices, and a sampler of a combination of their outputs: the same
    structure for every seed (one compilation), random numbers."""
    rng = np.random.default_rng(seed)
    dims, ins, outs = (2, 1, 3), (1, 2, 1), (1, 1, 2)
    plants = {}
    for k, (n, m, q) in enumerate(zip(dims, ins, outs)):
        A = rng.normal(size=(n, n)) - 2.0 * np.eye(n)
        plants[f"p{k}"] = hs.LinearPlant(A, B=rng.normal(size=(n, m)),
                                         C=rng.normal(size=(q, n)))
    inputs = {"p0": hs.LinearInput({"p2": rng.normal(size=(1, 2))}),
              "p1": hs.LinearInput({"p0": rng.normal(size=(2, 1)),
                                    "p2": rng.normal(size=(2, 2))}),
              "p2": hs.LinearInput({"p1": rng.normal(size=(1, 1))}),
              "s": hs.LinearInput({"p0": [[1.0]], "p1": [[-0.5]]})}
    sys = hs.Interconnection({**plants, "s": Sampler(float(rng.uniform(0.1, 0.4)))}, inputs)
    x0 = np.concatenate([rng.normal(size=6), [0.0, 0.0]])
    return sys, x0


@pytest.mark.paths(compiled_slow=True)
@pytest.mark.parametrize("seed", range(4))
def test_random_feedback_loops_agree_with_the_python_path(path, seed):
    """Seeded random feedback loops of linear plants with a sampler: jump times
    to 1e-10 (events located to 4 ulp on runs whose steps part by round-off)
    and final states to 1e-8 of the Python path's, on every path."""
    sys, x0 = _random_loop(seed)
    ref = _run("python", sys, x0, t_max=2.0)
    arc = _run(path, sys, x0, t_max=2.0)
    assert arc.jump_count == ref.jump_count > 3
    np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=1e-10)
    np.testing.assert_allclose(arc.xf, ref.xf, rtol=0, atol=1e-8 * max(1.0, np.abs(ref.x).max()))


@needs_numba
def test_a_lowered_system_still_pickles():
    """The lowered maps are generated code: dropped when the system is pickled
    (an executor ships it), rebuilt by the next compiled run."""
    import pickle
    sys = luenberger()
    lower(sys)
    again = pickle.loads(pickle.dumps(sys))
    assert "_lowered" not in again.__dict__
    arc = hs.simulate(again, [1.0, 0.0, 0.0, 0.0], t_max=1.0, backend="compiled")
    assert arc.system is again and list(arc.components) == ["plant", "observer"]


@needs_numba
@pytest.mark.slow
def test_lowering_specialised_runs_the_same_solutions():
    """lower(system, specialize=True): the maps compiled into the kernel (cached
    on disk by structure); the same arcs as the generic lowering, bit for bit
    (the same arithmetic, inlined), and simulate picks the specialised one."""
    sys, x0 = _random_loop(7)
    generic = hs.simulate(sys, x0, t_max=2.0, backend="compiled", **dict(rtol=RTOL, atol=ATOL))
    spec = lower(sys, specialize=True)
    assert spec.specialize and lower(sys) is spec
    arc = hs.simulate(sys, x0, t_max=2.0, backend="compiled", **dict(rtol=RTOL, atol=ATOL))
    np.testing.assert_array_equal(arc.t, generic.t)
    np.testing.assert_array_equal(arc.x, generic.x)
    with pytest.raises(TypeError, match="specialize must be True, False or None"):
        lower(sys, specialize="yes")
