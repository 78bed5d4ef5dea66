"""A plain model, as written, on the compiled path (hybridsim.compiled._from_source).

README's ``BouncingBall`` class and ``from_functions`` systems run compiled
unchanged: their maps are rewritten as functions of (x, t, j, p), the
numbers they read from ``self``, closures and defaults read into ``p``
before each run; what cannot be rewritten is refused naming the method and
its line, and ``backend="auto"`` then warns once and runs the Python path.
"""
from __future__ import annotations

import random
import warnings

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.compiled import lowerable
from hybridsim.library import bouncing_ball_jump_times

numba = pytest.importorskip("numba")

from hybridsim.compiled import CompileError, lower  # noqa: E402
from hybridsim.compiled._from_source import FallbackWarning  # noqa: E402


class BouncingBall(hs.HybridSystem):             # README's, as written
    state_dim = 2                                         # x = (height, velocity)
    def flow_map(self, x):  return np.array([x[1], -9.81])
    def jump_map(self, x):  return np.array([0.0, -0.8 * x[1]])
    def flow_set(self, x):  return x[0] >= 0
    def jump_set(self, x):  return x[0] <= 0 and x[1] <= 0


class Ball(hs.HybridSystem):
    """A ball whose numbers are attributes, read through a helper method."""
    state_dim = 2

    def __init__(self, g=9.81, e=0.8):
        self.g, self.e = g, e

    def accel(self, v):
        return -self.g + 0.0 * v

    def flow_map(self, x, t):
        return np.array([x[1], self.accel(x[1])])

    def jump_map(self, x):
        return np.array([0.0, -self.e * x[1]])

    def flow_set(self, x):
        return x[0] >= 0

    def jump_set(self, x):
        return x[0] <= 0 and x[1] <= 0


TIGHT = dict(rtol=1e-10, atol=1e-12)


def _as_hand_written(a, b):
    """The run of the rewritten maps is the run of the same maps written by
    hand as a CompiledSystem: bit for bit (one kernel, the same arithmetic)."""
    assert a.termination is b.termination
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.x, b.x)


def _same_arcs(a, b, rtol=1e-12):
    """The same arcs to round-off: the same samples, jump times within
    ``rtol`` relative (events are located to 4 ulp on each path; over 20
    bounces their round-off accumulates to a few 1e-14 here), states within
    1e-9 (a sample just after a jump carries the velocity times the jump
    times' difference)."""
    assert a.jump_count == b.jump_count and len(a.t) == len(b.t)
    assert a.termination is b.termination
    np.testing.assert_allclose(a.jump_times, b.jump_times, rtol=rtol, atol=0)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-9)


@pytest.mark.parametrize("backend", ["auto", "compiled"])
def test_readme_ball_runs_compiled_with_the_python_paths_arcs(backend, monkeypatch):
    import hybridsim.compiled as hc
    calls = []
    real = hc.simulate_compiled
    monkeypatch.setattr(hc, "simulate_compiled", lambda *a, **k: calls.append(1) or real(*a, **k))
    ball = BouncingBall()
    kw = dict(x0=[1.0, 0.0], t_max=5.0, j_max=20, **TIGHT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fast = hs.simulate(ball, backend=backend, **kw)
    assert calls == [1] and fast.system is ball
    _same_arcs(fast, hs.simulate(ball, **kw))
    np.testing.assert_allclose(fast.jump_times, bouncing_ball_jump_times(1.0, 20),
                               rtol=1e-12)
    assert lowerable(ball) and repr(lowerable(ball)) == "Lowerable(True)"


def test_a_batch_of_the_readme_ball_runs_compiled():
    x0s = np.column_stack([np.linspace(0.5, 2.0, 16), np.zeros(16)])
    arcs = hs.simulate_many(BouncingBall(), x0s, t_max=10.0, j_max=10, backend="auto", **TIGHT)
    jt = np.array([a.jump_times for a in arcs])
    np.testing.assert_allclose(jt, bouncing_ball_jump_times(x0s[:, 0], 10), rtol=1e-12)


def test_changing_an_attribute_changes_the_next_run():
    ball = Ball(e=0.8)
    kw = dict(x0=[1.0, 0.0], t_max=10.0, j_max=6, backend="compiled", **TIGHT)
    a = hs.simulate(ball, **kw)
    ball.e = 0.5
    b = hs.simulate(ball, **kw)
    ball.g = 3.0
    c = hs.simulate(ball, **kw)
    for arc, g, e in ((a, 9.81, 0.8), (b, 9.81, 0.5), (c, 3.0, 0.5)):
        np.testing.assert_allclose(arc.jump_times, bouncing_ball_jump_times(1.0, 6, g, e),
                                   rtol=1e-12)
    # the layout is named; one compiled form serves every instance of the class
    cs = lower(ball)
    assert set(cs.layout.names()) == {"g", "e"}
    assert cs.params[cs.layout.names()["e"][0]] == 0.5
    assert lower(Ball(e=0.3)).maps["flow"] is cs.maps["flow"]


def test_an_attribute_that_changes_shape_rewrites_the_maps():
    class Gains(hs.HybridSystem):
        state_dim = 2

        def __init__(self, k):
            self.k = k

        def flow_map(self, x):
            return -self.k * x
    s = Gains(1.0)
    a = hs.simulate(s, [1.0, 1.0], t_max=1.0, backend="compiled", **TIGHT)
    s.k = np.array([1.0, 2.0])
    b = hs.simulate(s, [1.0, 1.0], t_max=1.0, backend="compiled", **TIGHT)
    np.testing.assert_allclose(a.xf, np.exp(-1.0) * np.ones(2), rtol=1e-9)
    np.testing.assert_allclose(b.xf, np.exp([-1.0, -2.0]), rtol=1e-9)


@pytest.mark.slow
def test_from_functions_with_closures_and_defaults_over_numbers():
    def make(rate):
        return hs.HybridSystem.from_functions(
            flow_map=lambda x: -rate * x,
            jump_map=lambda x, floor=0.25: np.array([x[0] + floor]),
            jump_set=lambda x: x[0] <= 0.5, state_dim=1)
    from hybridsim.compiled import CompiledSystem
    for rate in (1.0, 2.0):
        s = make(rate)
        hand = CompiledSystem(flow_map=lambda x, t, j, p: -p[0] * x,
                              jump_map=lambda x, t, j, p: np.array([x[0] + p[1]]),
                              jump_guard=lambda x, t, j, p: 0.5 - x[0],
                              jump_set=lambda x, t, j, p: x[0] <= 0.5,
                              state_dim=1, params=[rate, 0.25])
        kw = dict(x0=[1.0], t_max=3.0, j_max=3, **TIGHT)
        a = hs.simulate(s, backend="compiled", **kw)
        _as_hand_written(a, hs.simulate(hand, backend="compiled", **kw))
        # and the Python path's run to the integrator's tolerance
        b = hs.simulate(s, **kw)
        assert a.jump_count == b.jump_count == 3
        np.testing.assert_allclose(a.jump_times, b.jump_times, rtol=1e-8)


@pytest.mark.slow
def test_a_matrix_attribute_and_module_functions():
    class Osc(hs.HybridSystem):
        state_dim = 2

        def __init__(self):
            self.A = np.array([[0.0, 1.0], [-4.0, 0.0]])

        def flow_map(self, x):
            return self.A @ x

        def jump_map(self, x):
            return np.array([1.0, 0.0])

        def jump_set(self, x):
            return np.linalg.norm(x) >= 1.9 or x[0] >= 2.0
    kw = dict(x0=[1.0, 0.0], t_max=3.0, **TIGHT)
    a, b = hs.simulate(Osc(), backend="compiled", **kw), hs.simulate(Osc(), **kw)
    assert a.jump_count == b.jump_count >= 1
    np.testing.assert_allclose(a.jump_times, b.jump_times, rtol=1e-8)
    np.testing.assert_allclose(a.xf, b.xf, atol=1e-8)


# ------------------------------------------------------------ refusals, by name and line
class Table(hs.HybridSystem):
    state_dim = 1

    def __init__(self):
        self.table = {"rate": 1.0}

    def flow_map(self, x):
        return -self.table.get("rate") * x      # a dict as a value: refused


_LINE = Table.flow_map.__code__.co_firstlineno + 1

COUNT = [0]


class Noisy(hs.HybridSystem):
    state_dim = 1

    def flow_map(self, x):
        return -x + np.random.normal()  # noqa: NPY002 - random draws: refused


class Counting(hs.HybridSystem):
    state_dim = 1

    def flow_map(self, x):
        self.calls = 1                           # writes the system: refused
        return -x


class Global(hs.HybridSystem):
    state_dim = 1

    def flow_map(self, x):
        COUNT[0] += 1                            # writes global state: refused
        return -x


class PyRandom(hs.HybridSystem):
    state_dim = 1

    def flow_map(self, x):
        return -x * random.random()              # the random module: refused


@pytest.mark.slow
@pytest.mark.parametrize("cls, words", [
    (Table, f"Table.flow_map \\(.*test_one_definition.py:{_LINE}\\): it reads self.table, "
            f"a dict \\(not a number or an array of numbers\\)"),
    (Noisy, r"Noisy.flow_map \(.*:\d+\): it draws random numbers \(np.random.normal\)"),
    (Counting, r"Counting.flow_map \(.*:\d+\): it writes self.calls"),
    (Global, r"Global.flow_map \(.*:\d+\): it writes into 'COUNT'"),
    (PyRandom, r"PyRandom.flow_map \(.*:\d+\): .*random"),
])
def test_what_cannot_be_rewritten_is_refused_naming_the_method_and_line(cls, words):
    s = cls()
    why = lowerable(s)
    assert not why and "cannot be rewritten" in why.reason
    with pytest.raises(TypeError, match=words):
        hs.simulate(s, [1.0], t_max=1.0, backend="compiled")
    # auto: one warning naming the reason, then the Python path
    with pytest.warns(FallbackWarning, match=words):
        arc = hs.simulate(s, [1.0], t_max=0.1, backend="auto")
    assert arc.t[-1] == 0.1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hs.simulate(s, [1.0], t_max=0.1, backend="auto")        # once per class and reason


def test_what_numba_cannot_compile_is_named_by_method_and_line():
    class Untyped(hs.HybridSystem):
        state_dim = 1

        def flow_map(self, x):
            return -x * len(object.__doc__)
    line = Untyped.flow_map.__code__.co_firstlineno + 1
    with pytest.raises(CompileError, match=rf"Untyped.flow_map \(.*:{line}\)"):
        hs.simulate(Untyped(), [1.0], t_max=1.0, backend="compiled")
    with pytest.warns(FallbackWarning, match="numba could not compile Untyped.flow_map"):
        arc = hs.simulate(Untyped(), [1.0], t_max=0.1, backend="auto")
    assert arc.t[-1] == 0.1
    # as a part of an interconnection: auto says so once and runs the Python path
    ic = hs.Interconnection({"plant": hs.LinearPlant([[-1.0]]), "u": Untyped()})
    with pytest.warns(FallbackWarning, match=r"runs Interconnection on the Python path: .*"
                                             r"numba could not compile Untyped.flow_map"):
        arc = hs.simulate(ic, [1.0, 1.0], t_max=0.1, backend="auto")
    assert arc.t[-1] == 0.1


def test_the_rewritten_source_is_kept_on_disk_and_verified():
    import os

    from hybridsim.compiled._cache import _spec_dirs
    ball = BouncingBall()
    cs = lower(ball)
    flow = cs.maps_into.get("flow", cs.maps["flow"])      # (written into out: its own form)
    path = flow.py_func.__code__.co_filename
    with open(path) as fh:
        assert fh.read() == ball.__dict__["_source_plan"][1].source
    # in the generated modules' one folder (a planted text: the test below)
    assert os.path.dirname(path) == _spec_dirs()[0]


def test_the_wrapped_maps_are_cached_on_disk_keyed_by_their_digest():
    """The engine's wrapper of each map (its value as the kernels' signature types
    it) is a generated module's, named by the map's digest and cached by numba
    with the map's code: a new process compiles nothing for a model it has run
    before (the subprocess test below), where a wrapper made in memory cost
    0.5 s and 1-2 MB a map. A map reading a value no digest keys is wrapped in
    memory, as before."""
    from hybridsim.compiled import CompiledSystem
    from hybridsim.compiled._cache import wrap_map
    cs = lower(BouncingBall())
    names = set()
    for role, kind in (("flow", "vec"), ("jump", "vec"), ("flow_set", "bool"),
                       ("jump_set", "bool")):
        w = wrap_map(cs.maps[role], kind)
        assert w.py_func.__module__.startswith("hybridsim_wrap_")
        assert w._cache._cache_path is not None and w.overloads
        names.add(w.py_func.__module__)
    assert len(names) == 4
    # the same map (the same code reading the same values) has the same wrapper;
    # a value it reads changed, another
    c = 9.81

    def fall(x, t, j, p):
        return np.array([x[1], -c])
    a = wrap_map(fall, "vec")
    assert wrap_map(fall, "vec") is a
    c = 1.62
    assert wrap_map(fall, "vec") is not a
    x = np.array([1.0, 0.5])
    assert a(x, 0.0, 0, np.zeros(0))[1] == -9.81
    assert wrap_map(fall, "vec")(x, 0.0, 0, np.zeros(0))[1] == -1.62
    arc = hs.simulate(CompiledSystem(fall, state_dim=2), [1.0, 0.0], t_max=1.0,
                      backend="compiled")
    assert arc.xf[1] == pytest.approx(-1.62)
    # a map reading an object the digest cannot key has no module (wrapped in memory)
    from hybridsim.compiled._cache import wrapper_module
    box = [object()]

    def odd(x, t, j, p):
        return -x if box else x
    assert wrapper_module(odd, "vec") is None


_SECOND_PROCESS = """
import sys
sys.path.insert(0, sys.argv[1])
from numba.core import event
import hybridsim as hs
from ball_model import Ball
with event.install_recorder("numba:compile") as rec:
    arc = hs.simulate(Ball(0.7), [1.0, 0.0], t_max=3.0, j_max=5, backend="compiled")
# the model's own functions compiled here (numba loading from its cache is no event)
own = sorted({e.data["dispatcher"].py_func.__qualname__ for _, e in rec.buffer
              if e.is_start and (e.data["dispatcher"].py_func.__module__ or "").startswith(
                  ("hybridsim_src_", "hybridsim_wrap_", "hybridsim.compiled._types"))})
print(len(arc.jump_times), own)
"""


@pytest.mark.slow
def test_a_second_process_compiles_nothing_for_a_plain_model(tmp_path):
    import subprocess
    import sys
    (tmp_path / "ball_model.py").write_text(
        "import numpy as np\nimport hybridsim as hs\n\n\n"
        "class Ball(hs.HybridSystem):\n"
        "    state_dim = 2\n\n"
        "    def __init__(self, e=0.8):\n        self.e = e\n\n"
        "    def flow_map(self, x, t, j):\n        return np.array([x[1], -9.80665])\n\n"
        "    def jump_map(self, x, t, j):\n        return np.array([0.0, -self.e * x[1]])\n\n"
        "    def flow_set(self, x, t, j):\n        return x[0] >= 0\n\n"
        "    def jump_set(self, x, t, j):\n        return x[0] <= 0 and x[1] <= 0\n")
    outs = [subprocess.run([sys.executable, "-W", "ignore", "-c", _SECOND_PROCESS,
                            str(tmp_path)], capture_output=True, text=True, timeout=600)
            for _ in range(2)]
    assert all(o.returncode == 0 for o in outs), outs[-1].stderr
    assert outs[0].stdout.split()[0] == outs[1].stdout.split()[0] == "5"
    assert outs[1].stdout.strip().splitlines()[-1] == "5 []"   # maps, wrappers: the cache


def test_a_file_at_the_modules_path_that_is_not_its_text_is_never_run(tmp_path, monkeypatch):
    from hybridsim import _source
    from hybridsim.compiled import _cache, _from_source

    class Decay(hs.HybridSystem):
        state_dim = 1

        def flow_map(self, x):
            return -0.75 * x
    plan = _source.plan(Decay())
    name = f"hybridsim_src_{_from_source._digest(plan)}"
    monkeypatch.setattr(_cache, "_spec_dirs", lambda: [str(tmp_path)])
    monkeypatch.setattr(_from_source, "_MODULES", {})
    (tmp_path / f"{name}.py").write_text("raise SystemExit('planted')\n")
    mod, _ = _from_source._module(plan)
    assert mod.__file__ == f"<hybridsim {name}>"           # compiled in memory instead
    arc = hs.simulate(Decay(), [1.0], t_max=1.0, backend="compiled", **TIGHT)
    np.testing.assert_allclose(arc.xf, [np.exp(-0.75)], rtol=1e-9)


GRAVITY = 9.81


def _fall(x):
    return np.array([x[1], -GRAVITY])


@pytest.mark.slow
def test_module_globals_and_followed_functions_are_read_per_run():
    global GRAVITY
    scale = 1.0

    def accel(v):                   # a function of the closure: followed
        return -scale * GRAVITY + 0.0 * v
    kw = dict(x0=[1.0, 0.0], t_max=10.0, j_max=4, backend="compiled", **TIGHT)
    for make in (lambda: hs.HybridSystem.from_functions(
                     flow_map=_fall, jump_map=lambda x: np.array([0.0, -0.8 * x[1]]),
                     flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0,
                     state_dim=2),
                 lambda: hs.HybridSystem.from_functions(
                     flow_map=lambda x: np.array([x[1], accel(x[1])]),
                     jump_map=lambda x: np.array([0.0, -0.8 * x[1]]),
                     flow_set=lambda x: x[0] >= 0, jump_set=lambda x: x[0] <= 0 and x[1] <= 0,
                     state_dim=2)):
        s = make()
        try:
            for g in (9.81, 4.0):
                GRAVITY = g
                np.testing.assert_allclose(hs.simulate(s, **kw).jump_times,
                                           bouncing_ball_jump_times(1.0, 4, g, 0.8), rtol=1e-12)
        finally:
            GRAVITY = 9.81


@pytest.mark.slow
def test_an_interconnection_of_plain_models_runs_compiled():
    """Each part's own maps rewritten (as functions of (x, u, t, j, p)): two
    README balls side by side, each with its own impacts, on both paths."""
    ic = hs.Interconnection({"a": BouncingBall(), "b": Ball(g=4.0, e=0.5)})
    assert lowerable(ic)
    kw = dict(x0=[1.0, 0.0, 2.0, 0.0], t_max=3.0, j_max=12, **TIGHT)
    fast, slow = hs.simulate(ic, backend="compiled", **kw), hs.simulate(ic, **kw)
    _same_arcs(fast, slow)
    expect = np.sort(np.concatenate([bouncing_ball_jump_times(1.0, 12),
                                     bouncing_ball_jump_times(2.0, 12, 4.0, 0.5)]))[:12]
    np.testing.assert_allclose(fast.jump_times, expect, rtol=1e-11)


def test_an_attribute_tested_against_none_is_decided_when_the_maps_are_rewritten():
    """``self.bias is None`` is folded (the branch not taken, which numba could
    not type, is dropped); setting the attribute rewrites the maps."""
    class Biased(hs.HybridSystem):
        state_dim = 1

        def __init__(self):
            self.bias = None

        def flow_map(self, x):
            if self.bias is None:
                return -x
            return -x + self.bias
    s = Biased()
    kw = dict(t_max=1.0, backend="compiled", **TIGHT)
    a = hs.simulate(s, [1.0], **kw)
    s.bias = 1.0
    b = hs.simulate(s, [1.0], **kw)
    np.testing.assert_allclose(a.xf, [np.exp(-1.0)], rtol=1e-9)
    np.testing.assert_allclose(b.xf, [1.0], rtol=1e-9)       # x' = 1 - x from 1
    assert set(lower(s).layout.names()) == {"bias"}


@pytest.mark.slow                   # numba compiles the 2-D products: 2.2 s of CPU
def test_a_matrix_attribute_times_a_matrix_is_that_product():
    """``self.M @ X`` with X a matrix is M X (and ``X @ self.M.T`` is X Mᵀ), as
    numpy computes them, also where it accumulates (``Y += self.M @ X``)."""
    class Products(hs.HybridSystem):
        state_dim = 4

        def __init__(self):
            self.M = np.array([[1.0, 2.0], [3.0, 4.0]])

        def flow_map(self, x):
            X = x.reshape((2, 2))
            Y = X @ self.M.T
            Y += self.M @ X
            return (self.M @ X + Y).reshape(4)
    s = Products()
    x = np.array([1.0, -2.0, 0.5, 3.0])
    np.testing.assert_allclose(lower(s).flow_map(x, 0.0, 0), s.flow_map(x), rtol=1e-15)


class _Gains:
    def __init__(self, k):
        self.K = np.array([[-k, 0.0], [0.0, -2 * k]])
        self.offset = 0.0

    def drift(self, x):
        return self.K @ x + self.offset


class Parts(hs.HybridSystem):
    """Maps reading a part of the system (``self.gains.K``, through a local
    name and a method of the part) and a str choosing a branch."""
    state_dim = 2

    def __init__(self, k, mode):
        self.gains, self.mode = _Gains(k), mode

    def flow_map(self, x):
        g = self.gains
        if self.mode == "drift":
            return g.drift(x)
        return g.K @ x


@pytest.mark.slow
def test_parts_of_the_system_and_str_branches_are_read_when_the_maps_are_rewritten():
    """``self.gains.K`` is a slot of p read through the part; a str compared
    in a branch is a constant there (the branch not taken is dropped); another
    part, or another str, rewrites the maps."""
    s = Parts(1.0, "drift")
    kw = dict(x0=[1.0, 1.0], t_max=1.0, backend="compiled", **TIGHT)
    np.testing.assert_allclose(hs.simulate(s, **kw).xf, np.exp([-1.0, -2.0]), rtol=1e-9)
    assert set(lower(s).layout.names()) == {"gains.K", "gains.offset"}
    s.gains.offset = 1.0                        # x' = K x + 1
    np.testing.assert_allclose(hs.simulate(s, **kw).xf,
                               [1.0, (1 + np.exp(-2.0)) / 2], rtol=1e-9)
    s.gains = _Gains(2.0)                       # another part
    np.testing.assert_allclose(hs.simulate(s, **kw).xf, np.exp([-2.0, -4.0]), rtol=1e-9)
    s.mode = "plain"                            # the other branch
    assert set(lower(s).layout.names()) == {"gains.K"}
    np.testing.assert_allclose(hs.simulate(s, **kw).xf, np.exp([-2.0, -4.0]), rtol=1e-9)


@pytest.mark.slow
def test_the_observers_maps_as_written_are_their_compiled_forms():
    """The source rewrite of observer maps written over batches (parts of self,
    ``d = self.design``, ``self.slices[...]``, bool flags, ``x[..., k]``,
    ``swapaxes``, the reshape of a transpose, ``np.copysign``, ``np.sum`` of
    ``t[..., None, None]``) gives the numbers of the maps as numpy runs them,
    to round-off."""
    from hybridsim.compiled import _from_source
    from observers import li_sanfelice as ls
    from observers.distributed import example_observer
    rng = np.random.default_rng(0)
    node = example_observer().nodes[1]
    hc = ls.ConstantNoiseObserver(ls.example_VB())
    method = {"flow": "flow_map", "jump": "jump_map", "jump_guard": "jump_guard",
              "jump_set": "jump_set"}
    noise = ls.BoundedNoiseGenerator(2, 3)
    for system in (node, hc, noise):
        maps, output, p, _ = _from_source.component_maps(system)
        for _ in range(5):
            x = rng.standard_normal(system.state_dim)
            x[-1] = 0.0 if system is hc else x[-1]          # H_c before its jump: q = 0
            u = rng.standard_normal(system.input_dim)
            for role, fn in maps.items():
                ref = getattr(system, method[role])(x, 0.3, 0, u)
                np.testing.assert_allclose(fn(x, u, 0.3, 0, p), ref, rtol=1e-13, atol=1e-14)
            np.testing.assert_allclose(output(x, 0.3, 0, p), system.output(x, 0.3, 0),
                                       rtol=1e-14)


class TwoCopies(hs.HybridSystem):
    """Maps written over batches the way the observers write them: sizes as
    ints, ``x[..., k]``, sums of products with matrices of ``self`` written
    into slices of a new array, ``np.where`` of numbers, a transpose reshaped."""
    vectorized = True

    def __init__(self, n, scale=1.0):
        self.n = n
        self.state_dim = 2 * n + 1
        self.F = -scale * (np.eye(n) + np.triu(np.ones((n, n)), 1))
        self.G = scale * np.arange(n * n, dtype=float).reshape(n, n) / n ** 2
        self.W = np.linspace(-1.0, 1.0, 2 * n).reshape(1, 2 * n)

    def flow_map(self, x, t, j):
        n = self.n
        x = np.asarray(x, dtype=float)
        dx = np.zeros(x.shape)
        dx[..., :n] = x[..., :n] @ self.F.T + x[..., n:2 * n] @ self.G.T
        dx[..., n:2 * n] = self.F @ x[..., n:2 * n] - self.G @ x[..., :n]
        M = x[..., :n].reshape((1, n)).swapaxes(-1, -2)        # (n, 1): a transpose
        dx[..., n:2 * n] += M.reshape(n)
        dx[..., 2 * n] = np.where(x[..., 2 * n] > 0.0, -1.0, 1.0)
        w = np.concatenate((x[..., :n], x[..., n:2 * n]), axis=-1) @ self.W.T
        dx[..., 2 * n] += np.sum(w)                 # one state: W's one row
        return dx


@pytest.mark.slow
def test_the_observers_patterns_compile_to_loops_with_numpys_numbers():
    """Products with matrices of ``self`` summed into slices of a new array are
    loops in the map (no product helper is called), one of a concatenation
    reads the pieces, ``x[..., k]`` is ``x[k]``, ints are constants; the
    numbers are numpy's (the same sums, in the same order)."""
    from hybridsim import _source
    s = TwoCopies(3)
    src = _source.plan(s).source
    assert "_hs_pmv(" not in src and "_hs_mpv" not in src and "..." not in src
    assert "_hs_pmv_cat(" in src and "concatenate" not in src
    assert "for _hs_i in range(3)" in src
    x = np.array([0.3, -1.0, 2.0, 0.5, 0.25, -0.75, 1.0])
    np.testing.assert_allclose(lower(s).flow_map(x, 0.0, 0), s.flow_map(x, 0.0, 0), rtol=1e-14)
    x[-1] = -1.0
    np.testing.assert_allclose(lower(s).flow_map(x, 0.0, 0), s.flow_map(x, 0.0, 0), rtol=1e-14)


@pytest.mark.slow
def test_a_plan_made_once_serves_every_instance_of_the_class():
    """A second instance of a class takes the first one's plan (its source: one
    rewrite, no second planning) with its own numbers read into p; another int
    (a constant of the rewrite) gets a plan of its own."""
    from hybridsim import _source
    a, b, c = TwoCopies(3), TwoCopies(3, scale=2.0), TwoCopies(2)
    pa, pb, pc = _source.plan(a), _source.plan(b), _source.plan(c)
    assert pb.source is pa.source and pc.source is not pa.source
    assert "range(2)" in pc.source
    x = np.linspace(-1.0, 1.0, 7)
    np.testing.assert_allclose(lower(b).flow_map(x, 0.0, 0), b.flow_map(x, 0.0, 0), rtol=1e-14)
    np.testing.assert_allclose(lower(a).flow_map(x, 0.0, 0), a.flow_map(x, 0.0, 0), rtol=1e-14)
    b.F = 3 * b.F                                   # b's own numbers, read again
    np.testing.assert_allclose(lower(b).flow_map(x, 0.0, 0), b.flow_map(x, 0.0, 0), rtol=1e-14)


class _Spring(hs.HybridSystem):
    """x'' = -k x, its state's halves read through slices of self."""

    state_dim = 2

    def __init__(self, k=4.0):
        self.k = k
        self.sl_q, self.sl_v = slice(0, 1), slice(1, 2)

    def flow_map(self, x, t):
        dx = np.zeros(x.shape)
        dx[..., self.sl_q] = x[..., self.sl_v]
        dx[..., self.sl_v] = -self.k * x[..., self.sl_q]
        return dx


class _Damped(_Spring):
    """The spring's flow (super()) with damping c v, c read from another object's
    method stored on the system (a bound method of a part)."""

    def __init__(self, k, gains):
        super().__init__(k)
        self._damping = gains.damping

    def flow_map(self, x, t):
        dx = super().flow_map(x, t)
        dx[..., self.sl_v] -= self._damping(x[..., self.sl_v])
        return dx


class _DampingGain:
    def __init__(self, c):
        self.c = c

    def damping(self, v):
        return self.c * v


def test_super_slices_and_a_parts_bound_method_are_followed():
    """super().flow_map(...) is the base class's map (same self), a slice attribute of
    ints is a constant of the rewrite, and a method of another object stored on the
    system is followed with that object as its self (its numbers in the parameters,
    read before every run)."""
    gains = _DampingGain(0.5)
    sys_ = _Damped(4.0, gains)
    kw = dict(x0=[1.0, 0.0], t_max=2.0, rtol=1e-10, atol=1e-12)
    ref = hs.simulate(sys_, backend="python", **kw)
    arc = hs.simulate(sys_, backend="compiled", **kw)
    np.testing.assert_allclose(arc.xf, ref.xf, rtol=1e-12, atol=1e-14)
    w = np.sqrt(4.0 - 0.25 ** 2)                 # x'' + 0.5 x' + 4 x = 0, x(0) = 1
    exact = np.exp(-0.25 * 2.0) * (np.cos(w * 2.0) + 0.25 / w * np.sin(w * 2.0))
    np.testing.assert_allclose(arc.xf[0], exact, rtol=1e-7)
    gains.c = 0.0                                # the part's number, read again
    np.testing.assert_allclose(hs.simulate(sys_, backend="compiled", **kw).xf[0],
                               np.cos(4.0), rtol=1e-7)
