"""Interconnections: plant -> observer, feedback, simultaneous jumps, networks."""
import networkx as nx
import numpy as np
import pytest
from scipy.linalg import expm

import hybridsim as hs

A = np.array([[0.0, 1.0], [-2.0, -0.5]])
C = np.array([[1.0, 0.0]])
L = np.array([4.0, 3.0])


class Luenberger(hs.HybridSystem):
    state_dim = 2
    input_dim = 1

    def flow_map(self, xh, t, j, y):
        return A @ xh + L * (y[0] - C[0] @ xh)


class FakeStateSpace:
    """Duck-typed like python-control's StateSpace."""

    def __init__(self, A, B, C, D):
        self.A, self.B, self.C, self.D = A, B, C, D


def test_plant_feeds_observer_error_matches_expm():
    plant = hs.LinearPlant(A, C=C)
    sysm = hs.connect(plant, Luenberger())
    x0 = np.array([1.0, -1.0, 0.0, 0.0])
    arc = hs.simulate(sysm, x0, t_max=4.0, rtol=1e-10, atol=1e-12)
    e = arc["observer"].xf - arc["plant"].xf
    expected = expm((A - np.outer(L, C[0])) * 4.0) @ (x0[2:] - x0[:2])
    np.testing.assert_allclose(e, expected, atol=1e-8)
    assert arc.components == {"plant": slice(0, 2), "observer": slice(2, 4)}
    np.testing.assert_allclose(arc.outputs("plant")[:, 0], arc["plant"].x[:, 0])


def test_feedback_loop_matches_closed_loop_matrix():
    B = np.array([[0.0], [1.0]])
    K = np.array([[-3.0, -2.0]])
    plant = hs.LinearPlant(A, B, C)

    class Obs(hs.HybridSystem):
        state_dim, input_dim = 2, 1

        def flow_map(self, xh, t, j, y):
            return A @ xh + B[:, 0] * (K[0] @ xh) + L * (y[0] - C[0] @ xh)

    sysm = hs.Interconnection({"plant": plant, "obs": Obs()},
                              inputs={"plant": lambda t, y: K @ y["obs"],
                                      "obs": lambda t, y: y["plant"]})
    x0 = np.array([1.0, 0.5, 0.0, 0.0])
    arc = hs.simulate(sysm, x0, t_max=3.0, rtol=1e-10, atol=1e-12)
    Acl = np.block([[A, B @ K], [np.outer(L, C[0]), A + B @ K - np.outer(L, C[0])]])
    np.testing.assert_allclose(arc.xf, expm(Acl * 3.0) @ x0, atol=1e-8)


def test_linear_plant_exogenous_input_noise_and_statespace():
    B = np.array([[0.0], [1.0]])
    ss = FakeStateSpace(A, B, C, np.zeros((1, 1)))
    plant = hs.LinearPlant(ss, u=lambda t: np.array([1.0]), noise=lambda t: np.array([0.1]))
    assert plant.input_dim == 0 and plant.output_dim == 1
    arc = hs.simulate(plant, [0.0, 0.0], t_max=100.0, rtol=1e-10, atol=1e-12)
    # steady state of A x + B = 0
    np.testing.assert_allclose(arc.xf, -np.linalg.solve(A, B[:, 0]), atol=1e-6)
    np.testing.assert_allclose(arc.outputs()[-1], C @ arc.xf + 0.1)


@pytest.mark.parametrize("kw, match", [
    (dict(A=np.ones((2, 3))), r"A must be square"),
    (dict(A=A, B=np.ones((3, 1))), r"B must have shape \(2, 1\)"),
    (dict(A=A, C=np.ones((1, 3))), r"C must have shape \(1, 2\)"),
    (dict(A=A, B=np.ones((2, 1)), C=C, D=np.ones((2, 1))), r"D must have shape \(1, 1\)"),
    (dict(A=A, B=np.ones((2, 1)), C=C, D=np.ones((1, 1))), "D must be zero when"),
    (dict(A=[[np.nan, 0], [0, 0]]), "A must be finite"),
    (dict(A=A, noise=lambda t: np.zeros(3)), r"noise\(t\) must return shape \(2,\)"),
    (dict(A=A, u=lambda t: 1.0), "u is given but B is None"),
])
def test_linear_plant_bad_input(kw, match):
    with pytest.raises(ValueError, match=match):
        hs.LinearPlant(**kw)


def timer(period):
    return hs.HybridSystem.from_functions(
        flow_map=lambda x: np.array([1.0]), jump_map=lambda x: np.array([0.0]),
        jump_guard=lambda x: x[0] - period, flow_guard=lambda x: period - x[0], state_dim=1)


def test_simultaneous_jumps_are_one_jump_of_the_interconnection():
    # two identical clocks are in their jump sets at once: one jump of the
    # interconnection resets both
    sysm = hs.Interconnection({"a": timer(1.0), "b": timer(1.0)})
    arc = hs.simulate(sysm, [0.0, 0.0], t_max=3.5)
    np.testing.assert_allclose(arc.jump_times, [1, 2, 3], atol=1e-12)
    np.testing.assert_array_equal(arc.x[arc.jump_index], np.zeros((3, 2)))


def test_jumps_that_coincide_up_to_rounding():
    # a 1-clock and a 2-clock reach their thresholds at t = 2 only up to
    # rounding: either one jump resets both, or two jumps at the same t
    # (within the 4-ulp event bracket). Either way both are reset at t = 2
    # and the fast one alone jumps at t = 1 and 3.
    sysm = hs.Interconnection({"fast": timer(1.0), "slow": timer(2.0)})
    arc = hs.simulate(sysm, [0.0, 0.0], t_max=4.5)
    np.testing.assert_allclose(np.unique(np.round(arc.jump_times, 9)), [1, 2, 3, 4])
    jt = arc.jump_index[np.abs(arc.jump_times - 2.0) < 1e-12]
    assert len(jt) in (1, 2)
    np.testing.assert_allclose(arc.x[jt[-1]], [0.0, 0.0], atol=1e-12)
    k1 = arc.jump_index[0]
    np.testing.assert_allclose(arc.x[k1], [0.0, 1.0], atol=1e-12)   # t = 1: fast only


def test_jump_of_one_component_leaves_the_other_unchanged():
    plant = hs.LinearPlant(A, C=C)
    sysm = hs.Interconnection({"plant": plant, "clock": timer(0.5)})
    arc = hs.simulate(sysm, [1.0, 0.0, 0.0], t_max=2.2, rtol=1e-10, atol=1e-12)
    k = arc.jump_index
    np.testing.assert_array_equal(arc.x[k, :2], arc.x[k - 1, :2])
    np.testing.assert_allclose(arc["plant"].xf, expm(A * 2.2) @ [1.0, 0.0], atol=1e-8)


def test_interconnection_bad_wiring():
    with pytest.raises(ValueError, match="component 'observer' has input_dim=1"):
        hs.Interconnection({"plant": hs.LinearPlant(A, C=C), "observer": Luenberger()})
    with pytest.raises(ValueError, match="'nope' is not a component"):
        hs.Interconnection({"plant": hs.LinearPlant(A)}, inputs={"nope": lambda t, y: 0})
    with pytest.raises(TypeError, match="must be a HybridSystem"):
        hs.Interconnection({"plant": object()})
    with pytest.raises(ValueError, match="connect\\(\\) wires only"):
        hs.connect(hs.LinearPlant(A, np.ones((2, 1)), C), Luenberger())


@pytest.mark.parametrize("N", [3, 12])
def test_network_consensus_on_directed_ring(N):
    # N > 9: no cap on the number of components (the MATLAB toolbox has 9)
    G = nx.DiGraph([(i, (i + 1) % N) for i in range(N)])

    class Node(hs.HybridSystem):
        state_dim, input_dim = 1, 1

        def flow_map(self, x, t, j, u):
            return u - x

    net = hs.network(G, {v: Node() for v in G},
                     inputs=lambda v, t, rec, exo: sum(rec.values()))
    rng = np.random.default_rng(N)
    x0 = rng.normal(size=N)
    arc = hs.simulate(net, x0, t_max=60.0 * N, rtol=1e-9, atol=1e-12)
    # a directed ring is balanced: consensus on the average
    np.testing.assert_allclose(arc.xf, np.full(N, x0.mean()), atol=1e-6)
    assert set(arc.components) == set(range(N))
    assert arc[N - 1].x.shape == (len(arc), 1)


def test_network_with_exogenous_plant_and_bad_input():
    G = nx.DiGraph([("a", "b"), ("b", "a")])
    plant = hs.LinearPlant(A, C=C)

    class Node(hs.HybridSystem):
        state_dim, input_dim = 2, 1

        def flow_map(self, xh, t, j, u):
            return A @ xh + L * (u[0] - C[0] @ xh)

    net = hs.network(G, lambda v: Node(), lambda v, t, rec, exo: exo["plant"],
                     exogenous={"plant": plant}, nodelist=["b", "a"])
    assert list(net.components) == ["plant", "b", "a"]
    arc = hs.simulate(net, [1, 0, 0, 0, 0, 0], t_max=8.0, rtol=1e-10, atol=1e-12)
    for v in "ab":
        np.testing.assert_allclose(arc[v].xf, arc["plant"].xf, atol=1e-5)
    with pytest.raises(TypeError, match="G must be a networkx.DiGraph"):
        hs.network(nx.Graph(), {}, lambda *a: 0)
    with pytest.raises(ValueError, match="nodelist must list every node"):
        hs.network(G, lambda v: Node(), lambda *a: 0, nodelist=["a"])
    with pytest.raises(ValueError, match="exogenous names clash"):
        hs.network(G, lambda v: Node(), lambda *a: 0, exogenous={"a": plant})


def test_split_and_stack():
    sysm = hs.connect(hs.LinearPlant(A, C=C), Luenberger())
    x = sysm.stack(plant=[1, 2], observer=[3, 4])
    np.testing.assert_array_equal(x, [1, 2, 3, 4])
    parts = sysm.split(np.vstack([x, x]))
    np.testing.assert_array_equal(parts["observer"], [[3, 4], [3, 4]])
    with pytest.raises(ValueError, match="missing parts"):
        sysm.stack(plant=[1, 2])
    with pytest.raises(ValueError, match=r"part 'plant' must have shape \(2,\)"):
        sysm.stack(plant=[1, 2, 3], observer=[3, 4])


def test_interconnection_pickles_after_a_run():
    import pickle
    sysm = hs.connect(hs.LinearPlant(A, C=C), Luenberger())
    x0 = [1.0, -1.0, 0.0, 0.0]
    a = hs.simulate(sysm, x0, t_max=1.0)
    clone = pickle.loads(pickle.dumps(sysm))
    b = hs.simulate(clone, x0, t_max=1.0)
    np.testing.assert_array_equal(a.x, b.x)
    pickle.loads(pickle.dumps(a))            # arcs travel back from worker processes


def test_direct_feedthrough_outputs_and_algebraic_loops():
    class Gain(hs.HybridSystem):
        """y = x + u: an output that reads the input."""

        state_dim, input_dim = 1, 1

        def flow_map(self, x, t, j, u):
            return -x

        def output(self, x, t, j, u):
            return x + u

    src = hs.HybridSystem.from_functions(flow_map=lambda x: np.zeros(1), state_dim=1)
    sysm = hs.Interconnection({"src": src, "g1": Gain(), "g2": Gain()},
                              inputs={"g1": lambda t, y: y["src"], "g2": lambda t, y: y["g1"]})
    y = sysm.outputs(np.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(y["g2"], [3.0 + 2.0 + 1.0])       # evaluated in dependency order
    arc = hs.simulate(sysm, [1.0, 2.0, 3.0], t_max=1.0)
    np.testing.assert_allclose(arc.outputs("g2")[0], [6.0])
    loop = hs.Interconnection({"g1": Gain(), "g2": Gain()},
                              inputs={"g1": lambda t, y: y["g2"], "g2": lambda t, y: y["g1"]})
    with pytest.raises(ValueError, match="algebraic loop"):
        loop.outputs(np.zeros(2))


class Agent(hs.HybridSystem):
    """x' = u - x (a consensus agent)."""

    state_dim, input_dim = 1, 1

    def flow_map(self, x, t, j, u):
        return u - x


@pytest.mark.parametrize("nodes", [[0, 1, 2], [(0, "a"), (1, "b"), (2, "c")]])
def test_network_with_hashable_node_names_stacks_and_splits(nodes):
    G = nx.DiGraph([(nodes[i], nodes[(i + 1) % 3]) for i in range(3)])
    net = hs.network(G, lambda v: Agent(), lambda v, t, rec, exo: sum(rec.values()))
    x0 = net.stack({nodes[2]: 3.0, nodes[0]: 1.0, nodes[1]: [2.0]})
    np.testing.assert_array_equal(x0, [1.0, 2.0, 3.0])
    parts = net.split(x0)
    assert list(parts) == nodes
    assert {v: float(p[0]) for v, p in parts.items()} == {nodes[0]: 1.0, nodes[1]: 2.0,
                                                          nodes[2]: 3.0}
    arc = hs.simulate(net, x0, t_max=1.0)
    per_node = net.split(arc.x)                 # (N, n) states: one (N, 1) array per node
    for v in nodes:
        np.testing.assert_array_equal(per_node[v], arc[v].x)
    np.testing.assert_array_equal(net.stack(net.split(arc.xf)), arc.xf)    # round trip


def test_stack_mapping_and_keywords_checked():
    plant = hs.LinearPlant(A, C=C)
    sysm = hs.connect(plant, Luenberger())
    np.testing.assert_array_equal(sysm.stack({"plant": [1, 2]}, observer=[3, 4]), [1, 2, 3, 4])
    with pytest.raises(ValueError, match=r"stack: parts for \['plant'\] given twice"):
        sysm.stack({"plant": [1, 2]}, plant=[1, 2], observer=[3, 4])
    with pytest.raises(ValueError, match=r"stack: \['obs'\] are not components; have "
                                         r"\['plant', 'observer'\]"):
        sysm.stack(plant=[1, 2], observer=[3, 4], obs=[0, 0])
    with pytest.raises(TypeError, match="stack: parts must be a mapping"):
        sysm.stack([[1, 2], [3, 4]])
    with pytest.raises(ValueError, match=r"split: x must have shape \(4,\) or \(N, 4\).*"
                                         r"got \(3,\)"):
        sysm.split([1.0, 2.0, 3.0])


def test_network_rejects_self_loops():
    G = nx.DiGraph([(0, 1), (1, 1), (1, 0), (0, 0)])
    with pytest.raises(ValueError, match=r"G has self-loops at nodes \[0, 1\]"):
        hs.network(G, lambda v: Agent(), lambda v, t, rec, exo: 0.0)


def test_connect_checks_plant_output_against_observer_input():
    two_outputs = hs.LinearPlant(A, C=np.eye(2))
    with pytest.raises(ValueError, match=r"connect: the plant's output has dimension 2 "
                                         r"\(LinearPlant\) but the observer takes an input of "
                                         r"dimension input_dim=1 \(Luenberger\)"):
        hs.connect(two_outputs, Luenberger())

    class Measured(hs.HybridSystem):     # no output_dim: the output is measured at x = 0
        state_dim = 2

        def flow_map(self, x):
            return A @ x

        def output(self, x, t, j):
            return np.array([x[0], x[1], x[0] + x[1]])

    with pytest.raises(ValueError, match="output has dimension 3"):
        hs.connect(Measured(), Luenberger())
    bare = hs.HybridSystem.from_functions(flow_map=lambda x: A @ x, state_dim=2)   # y = x: 2
    with pytest.raises(ValueError, match="output has dimension 2"):
        hs.connect(bare, Luenberger())
    with pytest.raises(TypeError, match="observer must be a HybridSystem"):
        hs.connect(hs.LinearPlant(A, C=C), object())
    hs.connect(hs.LinearPlant(A, C=C), Luenberger())        # matching: fine


# ---------------------------------------------------------------- vectorized interconnections
class Sampler(hs.HybridSystem):
    """Zero-order hold of its input every ``period``: state (held value, timer).

    Its maps take a single state (n,) or a batch (N, n) (written with x[..., k])."""

    state_dim, input_dim, vectorized = 2, 1, True

    def __init__(self, period):
        self.period = period

    def flow_map(self, x, t, j, u):
        dx = np.zeros_like(x)
        dx[..., 1] = 1.0
        return dx

    def jump_map(self, x, t, j, u):
        xn = np.array(x)
        xn[..., 0] = u[..., 0]
        xn[..., 1] = 0.0
        return xn

    def jump_guard(self, x, t, j, u):
        return x[..., 1] - self.period

    def flow_guard(self, x, t, j, u):
        return self.period - x[..., 1]


class SamplerBySets(Sampler):
    """The same sampler with set indicators only (no guards): bisection."""

    jump_guard = None
    flow_guard = None

    def jump_set(self, x, t, j, u):
        return x[..., 1] >= self.period

    def flow_set(self, x, t, j, u):
        return x[..., 1] <= self.period


def _two_samplers(cls=Sampler):
    """Plant -> two samplers of different periods: they jump at different rows' times."""
    plant = hs.LinearPlant([[0.0, 1.0], [-1.0, -0.1]], C=[[1.0, 0.0]])
    return hs.Interconnection({"plant": plant, "fast": cls(0.3), "slow": cls(0.7)},
                              inputs={"fast": lambda t, y: y["plant"],
                                      "slow": lambda t, y: y["plant"]})


@pytest.mark.parametrize("cls", [Sampler, SamplerBySets])
def test_vectorized_interconnection_batch_equals_single_runs(cls):
    """A batch of the interconnection (simulate_many: one numpy integration) makes the
    jumps a loop of simulate makes: the same jump times (the timers are linear, both
    bracket events to 4 ulp), the same number of samples, states within 1e-8 (both are
    RK45 at rtol 1e-9, but their step sequences differ by ~1e-11 in time, so the states
    agree to the integrator's tolerance over the 2 s, not to rounding)."""
    ic = _two_samplers(cls)
    assert ic.vectorized
    rng = np.random.default_rng(3)
    X = np.zeros((6, ic.state_dim))
    X[:, :2] = rng.normal(size=(6, 2))
    X[:, 3] = rng.uniform(0, 0.3, 6)           # timers at different phases
    X[:, 5] = rng.uniform(0, 0.7, 6)
    kw = dict(t_max=2.0, rtol=1e-9, atol=1e-12)
    arcs = hs.simulate_many(ic, X, **kw)
    for x0, a in zip(X, arcs):
        ref = hs.simulate(ic, x0, **kw)
        assert len(a) == len(ref) and a.jump_count == ref.jump_count > 4
        np.testing.assert_allclose(a.jump_times, ref.jump_times, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.x, ref.x, rtol=0, atol=1e-8)
        # the held values are the plant's output at the jump times
        k = np.flatnonzero(a.is_jump_end & (a["fast"].x[:, 1] == 0.0))
        np.testing.assert_allclose(a["fast"].x[k, 0], a["plant"].x[k, 0], atol=1e-14)


def test_vectorized_interconnection_maps_over_rows():
    """Batch maps equal the single-state maps row by row; at a jump only the components in
    their own jump set jump, on the rows where they are (the others keep their state)."""
    ic = _two_samplers()
    rng = np.random.default_rng(0)
    X = rng.normal(size=(5, ic.state_dim))
    X[:, 3] = [0.3, 0.1, 0.3, 0.0, 0.2]          # fast sampler in D on rows 0 and 2
    X[:, 5] = [0.1, 0.7, 0.7, 0.0, 0.9]          # slow one on rows 1, 2 and 4
    t, j = np.linspace(0, 1, 5), np.arange(5)
    D = ic.jump_set(X, t, j)
    np.testing.assert_array_equal(D, [True, True, True, False, True])
    np.testing.assert_array_equal(ic.flow_set(X, t, j), [True, True, True, True, False])
    G = ic.jump_map(X, t, j)
    for i in range(5):
        assert D[i] == ic.jump_set(X[i], t[i], j[i])
        np.testing.assert_allclose(ic.flow_map(X, t, j)[i], ic.flow_map(X[i], t[i], j[i]),
                                   rtol=1e-15, atol=1e-15)
        assert ic.jump_guard(X, t, j)[i] == pytest.approx(ic.jump_guard(X[i], t[i], j[i]))
        assert ic.flow_guard(X, t, j)[i] == pytest.approx(ic.flow_guard(X[i], t[i], j[i]))
        if D[i]:
            np.testing.assert_array_equal(G[i], ic.jump_map(X[i], t[i], j[i]))
    np.testing.assert_array_equal(G[3], X[3])                   # not in D: untouched
    np.testing.assert_array_equal(G[0, 4:], X[0, 4:])           # only "fast" jumped on row 0
    assert G[0, 2] == X[0, 0] and G[0, 3] == 0.0


def test_vectorized_only_when_every_component_is():
    plain = hs.HybridSystem.from_functions(flow_map=lambda x, t, j, u: u - x, state_dim=1,
                                           input_dim=1)
    plant = hs.LinearPlant([[0.0]], C=[[1.0]])
    assert plant.vectorized and not hs.LinearPlant([[0.0]], noise=lambda t: [0.0]).vectorized
    assert not hs.connect(plant, plain).vectorized
    assert hs.connect(plant, Sampler(0.5)).vectorized
    noisy = hs.LinearPlant([[0.0]], C=[[1.0]], noise=lambda t: np.array([0.0]))
    assert not hs.connect(noisy, Sampler(0.5)).vectorized


def test_simulate_many_loops_a_vectorized_system_for_options_the_batch_lacks():
    """RK23 (or dense=True) is not in the batch integrator: the rows run through
    simulate one by one, with the results simulate gives. DOP853 is: one
    batch, equal to single DOP853 runs to the integrator's tolerance (jump
    times to 1e-9, states at rtol 1e-9 over a unit horizon to 1e-8)."""
    ic = _two_samplers()
    X = np.zeros((2, ic.state_dim))
    X[:, 0] = [1.0, -0.5]
    for kw in (dict(method="RK23"), dict(dense=True)):
        arcs = hs.simulate_many(ic, X, t_max=1.0, rtol=1e-9, atol=1e-12, **kw)
        for x0, a in zip(X, arcs):
            ref = hs.simulate(ic, x0, t_max=1.0, rtol=1e-9, atol=1e-12, **kw)
            np.testing.assert_array_equal(a.x, ref.x)
    arcs = hs.simulate_many(ic, X, t_max=1.0, rtol=1e-9, atol=1e-12, method="DOP853")
    for x0, a in zip(X, arcs):
        ref = hs.simulate(ic, x0, t_max=1.0, rtol=1e-9, atol=1e-12, method="DOP853")
        assert a.jump_count == ref.jump_count > 0
        np.testing.assert_allclose(a.jump_times, ref.jump_times, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.xf, ref.xf, rtol=0, atol=1e-8)
    with pytest.raises(TypeError, match="no_such_option"):
        hs.simulate_many(ic, X, t_max=1.0, no_such_option=1)


def test_vectorized_plant_with_input_over_a_batch():
    """LinearPlant's batch flow x A^T + u B^T and output x C^T equal the single ones."""
    plant = hs.LinearPlant(A, B=[[0.0], [1.0]], C=C)
    X, U = np.random.default_rng(1).normal(size=(4, 2)), np.random.default_rng(2).normal(
        size=(4, 1))
    F = plant.flow_map(X, np.zeros(4), np.zeros(4, int), U)
    for i in range(4):
        np.testing.assert_allclose(F[i], plant.flow_map(X[i], 0.0, 0, U[i]), rtol=1e-15)
        np.testing.assert_allclose(plant.output(X, 0, 0)[i], plant.output(X[i], 0, 0))
