"""Interconnections check every component's map values (issue 22).

A component's flow_map / jump_map value must be a finite real array of shape (n_i,)
(over a batch: (N, n_i)); a violation raises a MapError naming the component
(``map_name="plant.flow_map"``), t and j, on the Python path (hs.simulate) and on
the vectorized batch path (simulate_vectorized / simulate_many), instead of numpy
stretching the value over the component's slice of the state.
"""
import warnings

import numpy as np
import pytest

import hybridsim as hs
from hybridsim.batch_vectorized import simulate_vectorized

# simulate_many warns of its failed rows: here they are the point
pytestmark = pytest.mark.filterwarnings("ignore::hybridsim.BatchWarning")

Termination = hs.Termination
T_BAD = 0.5                     # the maps break after this time (or at a jump there)


def _good(x):
    """A timer's flow (1, 0) on one state (2,) or a batch (N, 2)."""
    return np.stack([np.ones_like(x[..., 0]), np.zeros_like(x[..., 0])], axis=-1)


# wrong values: (the value from x, the words of the message)
SINGLE = {
    "scalar": (lambda x: -1.0, "must return an array of shape (2,), got shape ()"),
    "n+1": (lambda x: np.zeros(3), "must return an array of shape (2,), got shape (3,)"),
    "one": (lambda x: np.zeros(1), "must return an array of shape (2,), got shape (1,)"),
    "complex": (lambda x: np.array([1j, 0.0]), "returned complex values"),
    "nan": (lambda x: np.array([np.nan, 0.0]), "returned non-finite values"),
}
BATCH = {
    "scalar": (lambda x: -1.0, "must return an array of shape ({k}, 2) (vectorized: one "
                               "row per trajectory), got shape ()"),
    "n+1": (lambda x: np.zeros((len(x), 3)), "must return an array of shape ({k}, 2) "
                                             "(vectorized: one row per trajectory), got "
                                             "shape ({k}, 3)"),
    "one": (lambda x: np.zeros((len(x), 1)), "must return an array of shape ({k}, 2) "
                                             "(vectorized: one row per trajectory), got "
                                             "shape ({k}, 1)"),
    "complex": (lambda x: np.zeros((len(x), 2)) + 1j, "returned complex values"),
    "nan": (lambda x: np.full((len(x), 2), np.nan), "returned non-finite values"),
}
KINDS = list(SINGLE)


def _component(kind, bad, *, vectorized=False, when="x0"):
    """A 2-state timer whose flow (``kind="flow_map"``) or jump map returns ``bad``:
    from the start (``when="x0"``) or after T_BAD (flow) / at its jump at T_BAD."""
    if kind == "flow_map":
        if when == "x0":
            f = bad
        elif vectorized:
            def f(x, t):
                return _good(x) if np.all(t <= T_BAD) else bad(x)
        else:
            def f(x, t):
                return _good(x) if t <= T_BAD else bad(x)
        g = None
    else:
        f, g = _good, bad
    return hs.HybridSystem.from_functions(
        flow_map=f, jump_map=g, jump_guard=(None if g is None else lambda x: x[..., 0] - T_BAD),
        flow_guard=(None if g is None else lambda x: T_BAD - x[..., 0]),
        state_dim=2, vectorized=vectorized)


def _ic(comp):
    ok = hs.LinearPlant([[-1.0]])                       # vectorized: no callables of t
    return hs.Interconnection({"ok": ok, "plant": comp})


def _assert_names(e, kind, words, t=None):
    assert isinstance(e, hs.MapError)
    msg = str(e)
    assert msg.startswith(f"component 'plant': {kind} "), msg
    assert words in msg, msg
    assert e.map_name == f"plant.{kind}"
    if t is not None:
        assert e.t == pytest.approx(t) and isinstance(e.j, int)


def test_issue_22_scalar_flow_no_longer_stretched():
    comp = hs.HybridSystem.from_functions(flow_map=lambda x: -1.0, state_dim=2)
    with pytest.raises(hs.MapError):
        hs.simulate(comp, [1.0, 1.0], t_max=1.0)                   # alone
    with pytest.raises(hs.MapError) as ei:
        hs.simulate(_ic(comp), [1.0, 1.0, 1.0], t_max=1.0)         # inside: the same
    _assert_names(ei.value, "flow_map", "must return an array of shape (2,), got shape ()",
                  t=0.0)
    assert str(ei.value) == ("component 'plant': flow_map must return an array of shape "
                             "(2,), got shape () (at t=0, j=0)")
    assert ei.value.j == 0


# ------------------------------------------------------------------ the Python path
@pytest.mark.parametrize("bad", KINDS)
@pytest.mark.parametrize("kind", ["flow_map", "jump_map"])
def test_python_path_at_x0_raises_naming_the_component(kind, bad):
    fn, words = SINGLE[bad]
    comp = _component(kind, fn)
    x0 = [T_BAD, 0.0] if kind == "jump_map" else [0.0, 0.0]         # a jump: x0 in D
    # alone, a wrong value at x0 raises even with throw=False; so does the interconnection
    with pytest.raises(hs.MapError):
        hs.simulate(comp, x0, t_max=1.0, throw=False)
    with pytest.raises(hs.MapError) as ei:
        hs.simulate(_ic(comp), [1.0, *x0], t_max=1.0, throw=False)
    _assert_names(ei.value, kind, words, t=0.0)
    assert ei.value.arc is not None


@pytest.mark.parametrize("bad", KINDS)
@pytest.mark.parametrize("kind", ["flow_map", "jump_map"])
def test_python_path_during_the_run(kind, bad):
    fn, words = SINGLE[bad]
    comp = _component(kind, fn, when="run")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hs.SimulationWarning)
        ref = hs.simulate(comp, [0.0, 0.0], t_max=1.0, throw=False)
    arc = hs.simulate(_ic(comp), [1.0, 0.0, 0.0], t_max=1.0, throw=False)
    assert arc.termination is Termination.MAP_ERROR
    _assert_names(arc.exception, kind, words)
    assert "component 'plant'" in arc.message
    assert arc.exception.t >= T_BAD - 1e-9 and arc.t[-1] <= arc.exception.t
    if not (kind == "flow_map" and bad == "nan"):
        # alone: MAP_ERROR too (a NaN flow during a run ends NON_FINITE there)
        assert ref.termination is Termination.MAP_ERROR
    with pytest.raises(hs.MapError) as ei:
        hs.simulate(_ic(comp), [1.0, 0.0, 0.0], t_max=1.0)
    _assert_names(ei.value, kind, words)
    assert ei.value.arc.termination is Termination.MAP_ERROR


# ------------------------------------------------------------------ the batch path
@pytest.mark.parametrize("bad", KINDS)
@pytest.mark.parametrize("kind", ["flow_map", "jump_map"])
def test_vectorized_path_at_x0(kind, bad):
    fn, words = BATCH[bad]
    comp = _component(kind, fn, vectorized=True)
    ic = _ic(comp)
    assert ic.vectorized
    X = np.zeros((3, 3))
    X[:, 0] = 1.0
    if kind == "jump_map":
        X[:, 1] = T_BAD                                     # in D at x0
    with pytest.raises(hs.MapError) as ei:
        simulate_vectorized(ic, X, t_max=1.0)
    _assert_names(ei.value, kind, words.format(k=3), t=0.0)
    if bad in ("scalar", "n+1", "one"):                     # alone: raised at x0 too
        with pytest.raises(hs.MapError):
            simulate_vectorized(comp, X[:, 1:], t_max=1.0)
    # simulate_many isolates the rows: each a MAP_ERROR arc naming the component
    arcs = hs.simulate_many(ic, X, t_max=1.0)
    assert [a.termination for a in arcs] == [Termination.MAP_ERROR] * 3
    for a in arcs:
        _assert_names(a.exception, kind, words.format(k=1))


@pytest.mark.parametrize("bad", KINDS)
@pytest.mark.parametrize("kind", ["flow_map", "jump_map"])
def test_vectorized_path_during_the_run(kind, bad):
    fn, words = BATCH[bad]
    comp = _component(kind, fn, vectorized=True, when="run")
    ic = _ic(comp)
    X = np.zeros((3, 3))
    X[:, 0] = 1.0
    X[2, 1] = -10.0            # its timer reaches T_BAD after t_max (jump_map: unharmed)
    with warnings.catch_warnings():
        warnings.simplefilter("error", np.exceptions.ComplexWarning)
        arcs = simulate_vectorized(ic, X, t_max=1.0)
        many = hs.simulate_many(ic, X, t_max=1.0)
    expect = [Termination.MAP_ERROR] * 2 + [Termination.MAP_ERROR if kind == "flow_map"
                                            else Termination.T_MAX]
    for got in (arcs, many):
        assert [a.termination for a in got] == expect
        for a in got[:2]:      # retried row by row: the failing rows, one at a time
            _assert_names(a.exception, kind, words.format(k=1))
            assert "component 'plant'" in a.message
            assert a.exception.t >= T_BAD - 1e-9
    if bad in ("scalar", "n+1", "one") or (kind == "jump_map" and bad == "nan"):
        ref = simulate_vectorized(comp, X[:, 1:], t_max=1.0)      # alone: MAP_ERROR too
        assert [a.termination for a in ref] == expect
    with pytest.raises(hs.SimulationError) as ei:
        simulate_vectorized(ic, X, t_max=1.0, throw=True)
    _assert_names(ei.value.arc.exception, kind, words.format(k=1))


# ------------------------------------------------------------ outputs, guards, sets
def test_outputs_of_a_declared_dimension_are_checked():
    bad = hs.HybridSystem.from_functions(flow_map=lambda x: -x, output=lambda x: x, output_dim=1,
                                         state_dim=2)
    obs = hs.HybridSystem.from_functions(flow_map=lambda x, t, j, u: u - x, state_dim=1,
                                         input_dim=1)
    ic = hs.connect(bad, obs)
    with pytest.raises(hs.MapError) as ei:
        hs.simulate(ic, [1.0, 2.0, 0.0], t_max=1.0)
    assert ei.value.map_name == "plant.output"
    assert "component 'plant': output must return an array of shape (1,) or a scalar " \
           "(output_dim=1), got shape (2,)" in str(ei.value)
    cplx = hs.HybridSystem.from_functions(flow_map=lambda x: -x, output=lambda x: x[:1] * 1j,
                                          output_dim=1, state_dim=2)
    with pytest.raises(hs.MapError, match="component 'plant': output returned complex"):
        hs.simulate(hs.connect(cplx, obs), [1.0, 2.0, 0.0], t_max=1.0)
    # a scalar output of dimension 1, and an undeclared 1-D output, are fine
    for out, dim in ((lambda x: x[0], 1), (lambda x: x[:1], None)):
        fine = hs.HybridSystem.from_functions(flow_map=lambda x: -x, output=out, output_dim=dim,
                                              state_dim=2)
        arc = hs.simulate(hs.connect(fine, obs), [1.0, 2.0, 0.0], t_max=1.0)
        assert arc.termination is Termination.T_MAX


def test_batch_outputs_guards_and_sets_are_checked():
    def vec(**kw):
        return hs.HybridSystem.from_functions(state_dim=2, vectorized=True, **kw)
    obs = hs.LinearPlant([[0.0]], B=[[1.0]])               # vectorized, with an input
    X = np.zeros((4, 3))
    cases = [
        (vec(flow_map=_good, output=lambda x: x, output_dim=1), "plant.output",
         "output must return an array of shape (4, 1) or (4,)"),
        (vec(flow_map=_good, jump_map=_good, jump_guard=lambda x: -1.0), "plant.jump_guard",
         "jump_guard must return an array of shape (4,) or (4, m)"),
        (vec(flow_map=_good, jump_map=_good, jump_set=lambda x: False), "plant.jump_set",
         "jump_set must return a boolean array of shape (4,)"),
        (vec(flow_map=_good, flow_set=lambda x: np.ones((len(x), 2), bool)), "plant.flow_set",
         "flow_set must return a boolean array of shape (4,)"),
    ]
    for comp, name, words in cases:
        ic = hs.Interconnection({"plant": comp, "obs": obs},
                                inputs={"obs": lambda t, y: y["plant"][..., :1]})
        assert ic.vectorized
        with pytest.raises(hs.MapError) as ei:
            simulate_vectorized(ic, X, t_max=1.0)
        assert ei.value.map_name == name
        assert f"component 'plant': {words}" in str(ei.value)


def test_good_values_of_other_kinds_pass():
    """Int arrays and lists (converted, as simulate converts them) and float32 pass."""
    for f in (lambda x: [1, 0], lambda x: np.array([1, 0]),
              lambda x: np.array([1.0, 0.0], dtype=np.float32)):
        comp = hs.HybridSystem.from_functions(flow_map=f, state_dim=2)
        arc = hs.simulate(_ic(comp), [1.0, 0.0, 0.0], t_max=1.0)
        np.testing.assert_allclose(arc.xf[1:], [1.0, 0.0], atol=1e-9)
