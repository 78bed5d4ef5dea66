"""Delay equations lowered onto the compiled path (issue 27, deliverable 4).

A part whose flow reads its own past declares its delays (``self.delays``
for a plain model, whose ``self.history(t - tau)`` is rewritten; or its
compiled form's ``Component(delays=...)``); :func:`hybridsim.compiled.lower`
hands it its slice of x(t - tau_i) after its parameters and the lowered
``CompiledSystem`` reads its past with ``delays`` (the union of the parts').
The case that needs it: Mazenc-Malisoff's sampled observer (39) with the DC
motor (65) (``observers.gramian_delay``), whose flow reads psi(t - tau) in
(13).

Each lowered system runs three ways against the original interconnection
on the Python path (``hs.simulate``, its maps reading ``self.history``):
the lowered maps (numba-compiled) on the Python engine, the compiled
engine, and a compiled batch against its single runs.

Tolerances: every run is RK45 at rtol 1e-10, atol 1e-12. The lowered maps
compute the same formulas in the same order, but with loops where numpy
calls BLAS and libm's sin where numpy has its own, so they differ by a few
ulp. That is enough for the step sizes to part: (13) cancels terms about
1e5 times larger than omega (|S^-1| ~ 1e5), so the error estimate of
omega's flow at atol 1e-12 is made of round-off, and the samples between
jumps are at times up to ~1e-7 apart. The arcs are therefore compared where
both have a sample of the same instant: each jump (the jump times equal to
JUMP_TOL = 1e-9; they come out equal to the bit, the samples being set by
the timer or the instants) and the end. There the states agree to 2e-13 of
each component's size at most (2e-15 on (39)): two integrations of the same
equation to rtol 1e-10 whose own errors are far smaller than the rtol
here. STATE_RTOL = 1e-11 leaves a margin of 50 over the largest measured.
"""
import numpy as np
import pytest

import hybridsim as hs
from observers.gramian_delay.design import sampling_instants
from observers.gramian_delay.example import DC_PARAMS, population
from observers.gramian_delay.systems import DCMotor, smooth_noise

numba = pytest.importorskip("numba")

from hybridsim.compiled import CompiledSystem, Component, lower, lowerable  # noqa: E402
from hybridsim.compiled._system import keywords  # noqa: E402
from observers import gramian_delay as gd  # noqa: E402

RUN = dict(method="RK45", rtol=1e-10, atol=1e-12)
JUMP_TOL = 1e-9          # jump times: located to ~1e-15 on both engines
STATE_RTOL = 1e-11       # of each component's largest size over the run (module notes)


def python_path(cs):
    """The lowered system on the Python engine: its maps compiled by numba, called
    from ``hs.simulate`` (which fills the flow's past from ``hs.History``)."""
    return CompiledSystem(**keywords({r: numba.njit(f) for r, f in cs.maps.items()}),
                          state_dim=cs.state_dim, params=cs.params, delays=cs.delays,
                          max_step=cs.max_step)


def assert_same_run(arc, ref):
    """Same termination and jumps (times to JUMP_TOL), the post-jump states and the
    final state to STATE_RTOL of each component's size."""
    assert arc.termination == ref.termination
    assert len(arc.jump_times) == len(ref.jump_times)
    np.testing.assert_allclose(arc.jump_times, ref.jump_times, rtol=0, atol=JUMP_TOL)
    scale = np.maximum(np.abs(ref.x).max(axis=0), 1e-300)

    def marks(a):            # the first sample of each jump count, and the last
        return np.r_[np.flatnonzero(np.diff(a.j)) + 1, len(a.t) - 1]
    np.testing.assert_array_less(np.abs(arc.x[marks(arc)] - ref.x[marks(ref)]) / scale,
                                 STATE_RTOL)


# ---------------------------------------------------------------- a generic delay pair
# plain models: their self.history(t - tau) reads run compiled as written
class Lag(hs.HybridSystem):
    """x' = -a x(t - tau), output x."""

    state_dim, needs_history = 1, True

    def __init__(self, a=1.0, tau=1.0):
        self.a, self.tau = a, tau
        self.delays, self.max_step = (tau,), tau

    def flow_map(self, x, t, j, u):
        return np.array([-self.a * self.history(t - self.tau)[0]])


class Pair(hs.HybridSystem):
    """y0' = -a y0(t - tau_a) + u, y1' = y0(t - tau_b) - y1: two delays, an input."""

    state_dim, input_dim, needs_history = 2, 1, True

    def __init__(self, a=0.5, taus=(0.5, 1.0)):
        self.a, self.taus = a, taus
        self.delays, self.max_step = taus, min(taus)

    def flow_map(self, x, t, j, u):
        pa = self.history(t - self.taus[0])
        pb = self.history(t - self.taus[1])
        return np.array([-self.a * pa[0] + u[0], pb[0] - x[1]])


def pair_system(tau=1.0, taus=(0.5, 1.0)):
    return hs.connect(Lag(1.0, tau), Pair(0.5, taus), names=("lag", "pair"))


@pytest.mark.slow
@pytest.mark.parametrize("taus", [(1.0, (0.5, 1.0)), (0.8, (0.3, 0.6))])
def test_parts_reading_their_past_lower_with_their_own_slices(taus):
    """Two parts, delays (1.0) and (0.5, 1.0) (then (0.8) and (0.3, 0.6)): the
    lowered system reads at the union of the delays, each part its own slice; the
    Python engine and the compiled one agree with the original interconnection,
    and x' = -x(t - 1) with the method of steps."""
    sysc = pair_system(*taus)
    x0 = np.array([1.0, 0.2, -0.1])
    ref = hs.simulate(sysc, x0, t_max=3.0, **RUN)
    cs = lower(sysc)
    assert cs.delays == tuple(sorted({taus[0], *taus[1]}))
    assert cs.max_step == min(cs.delays)
    for arc in (hs.simulate(python_path(cs), x0, t_max=3.0, **RUN),
                hs.simulate(sysc, x0, t_max=3.0, backend="compiled", **RUN)):
        assert_same_run(arc, ref)
    if taus[0] == 1.0:       # the method of steps (1e-9: the integrator's rtol over 2 s)
        arc = hs.simulate(sysc, x0, t_max=2.0, backend="compiled", **RUN)
        t = arc.t
        exact = np.where(t <= 1.0, 1.0 - t, 1.0 - t + (t - 1.0) ** 2 / 2)
        np.testing.assert_allclose(arc.x[:, 0], exact, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_a_structure_serves_other_delays_and_a_compiled_system_is_a_part():
    """The maps lowered for delays (1.0; 0.5, 1.0) serve (0.8; 0.4, 0.8) (same
    places in the union: nothing recompiles), run at the new delays; a
    CompiledSystem with delays (its flow's past after its params, as a
    Component's) is a part like any other."""
    first, other = lower(pair_system()), lower(pair_system(0.8, (0.4, 0.8)))
    assert other.maps["flow"] is first.maps["flow"]
    assert other.delays == (0.4, 0.8) and other.max_step == 0.4
    x0 = np.array([1.0, 0.2, -0.1])
    sysc = pair_system(0.8, (0.4, 0.8))
    ref = hs.simulate(sysc, x0, t_max=3.0, **RUN)
    assert_same_run(hs.simulate(sysc, x0, t_max=3.0, backend="compiled", **RUN), ref)
    lag = CompiledSystem(lambda x, t, j, p: np.array([-p[0] * p[1]]), state_dim=1,
                         params=[1.0], delays=(0.8,))
    mixed = hs.connect(lag, Pair(0.5, (0.4, 0.8)), names=("lag", "pair"))
    assert_same_run(hs.simulate(mixed, x0, t_max=3.0, backend="compiled", **RUN), ref)


@pytest.mark.slow
def test_systems_lowered_from_one_structure_run_at_their_own_delays():
    """Unions (0.5, 1.0) and (0.5, 1.2) share the lowered maps and the smallest
    delay (the max_step): the second run, with the same options, reads its past
    at 1.2, not at the first system's 1.0 (the packed options are memoized per
    structure; the delays are part of their key)."""
    x0 = np.array([1.0, 0.2, -0.1])
    first, second = pair_system(1.0, (0.5, 1.0)), pair_system(1.2, (0.5, 1.2))
    assert lower(second).maps["flow"] is lower(first).maps["flow"]
    hs.simulate(first, x0, t_max=3.0, backend="compiled", **RUN)
    arc = hs.simulate(second, x0, t_max=3.0, backend="compiled", **RUN)
    assert_same_run(arc, hs.simulate(second, x0, t_max=3.0, **RUN))


def _lag_flow(x, u, t, j, p):               # x' = -p0 x(t - tau): the past after p0
    return np.array([-p[0] * p[1]])


def test_a_history_reader_without_declared_delays_is_refused_by_name():
    class Undeclared(Lag):
        def compiled_component(self):
            return Component(state_dim=1, flow_map=_lag_flow, params=[self.a])

    class NoDelays(Lag):
        def __init__(self):
            super().__init__()
            self.delays = ()

    class Elsewhere(Lag):               # the past read by a jump map (NaN on the kernel)
        def jump_map(self, x, t, j, u):
            return self.history(t - self.tau)

        def jump_set(self, x, t, j, u):
            return x[0] > 2.0

    class Anywhen(Lag):
        def flow_map(self, x, t, j, u):
            return -self.history(0.5 * t)

    with pytest.raises(TypeError, match="reads its history .* declares no delays"):
        lower(Undeclared())
    with pytest.raises(TypeError, match="reads its history .* NoDelays has no compiled form "
                                        "declaring the delays it reads"):
        lower(NoDelays())
    for cls, why in ((Elsewhere, r"Elsewhere.jump_map \(.*\): it reads self.history "
                                 r"outside the flow map"),
                     (Anywhen, r"Anywhen.flow_map \(.*\): self.history is read at t - tau "
                               r"only")):
        with pytest.raises(TypeError, match=why):
            lower(cls())
        assert not lowerable(cls())
    assert not lowerable(NoDelays()) and lowerable(Lag())
    for bad, err, msg in (((0.0,), ValueError, "positive"), ((0.1, 0.1), ValueError, "distinct"),
                          ("x", TypeError, "sequence")):
        with pytest.raises(err, match=msg):
            Component(state_dim=1, flow_map=_lag_flow, delays=bad)
    with pytest.raises(ValueError, match="needs flow"):
        Component(state_dim=1, delays=(0.1,))


# ---------------------------------------------------------------- (39) with the DC motor
T_MAX = 0.3              # three windows of tau = 0.1: decision 3's early window and after


def _loop(obs, x0=None, **kw):
    plant = obs.plant
    return gd.example._loop(obs, plant.chi0 if x0 is None else x0, None, kw.get("noise"),
                            kw.get("seed"), None)


CASES = {
    "period": lambda ex: ex.sampled_observer(period=0.01),
    "instants": lambda ex: ex.sampled_observer(
        instants=sampling_instants(0.005, 0.02, T_MAX, seed=1)),
    "gaps": lambda ex: ex.sampled_observer(gaps=(0.01, 0.02)),
}


@pytest.fixture(scope="module")
def motor():
    return gd.dc_motor(100.0, 0.1)           # decision 7's u, delta1, delta2


# period in the default suite; instants and gaps (their own compiled maps, 8-14 s
# each to compile) with the slow tests
@pytest.mark.slow
@pytest.mark.parametrize("case", [pytest.param(c, marks=() if c == "period" else
                                               pytest.mark.slow) for c in sorted(CASES)])
def test_39_lowered_agrees_with_its_python_path(motor, case):
    """(39) with the DC motor, samples by period, instants and gaps: the lowered
    interconnection on the Python engine and on the compiled one against the
    observer's own Python path (``hs.simulate`` of ``plant -> observer``)."""
    obs = CASES[case](motor)
    sysc, x0 = _loop(obs)
    ref = hs.simulate(sysc, x0, t_max=T_MAX, **RUN)
    assert ref.termination is hs.Termination.T_MAX and len(ref.jump_times) > 10
    cs = lower(sysc)
    assert cs.delays == (0.1,) and cs.max_step == 0.1
    assert_same_run(hs.simulate(python_path(cs), x0, t_max=T_MAX, **RUN), ref)
    arc = hs.simulate(sysc, x0, t_max=T_MAX, backend="compiled", **RUN)
    assert_same_run(arc, ref)
    assert arc.system is sysc and list(arc.components) == ["plant", "observer"]


@pytest.mark.slow
def test_39_with_the_oracle_and_smooth_noise_agrees(motor):
    """estimate="xi2" (13) reads xi_2 from the oracle plant's output (the input's
    second half), and a measurement noise of smooth_noise (its compiled form)."""
    ex = gd.dc_motor(100.0, 0.1, oracle=True)
    for obs, noise in ((ex.sampled_observer(period=0.01, estimate="xi2"), None),
                       (motor.sampled_observer(period=0.01), smooth_noise(1e-3, seed=3))):
        sysc, x0 = gd.example._loop(obs, obs.plant.chi0, None, noise, None, None)
        ref = hs.simulate(sysc, x0, t_max=T_MAX, **RUN)
        assert_same_run(hs.simulate(sysc, x0, t_max=T_MAX, backend="compiled", **RUN), ref)


@pytest.mark.slow
def test_39_compiled_batch_equals_its_single_runs(motor):
    """``simulate_many(..., backend="compiled")`` over five motors: each row equal
    to its single compiled run to the bit (the same kernel, the same arithmetic),
    and the estimates of (13) read from the arcs agree with the Python path's."""
    obs = motor.sampled_observer(period=0.01)
    X = motor.chi0 + np.random.default_rng(0).uniform(-0.3, 0.3, (5, 3))
    sysc, rows = population(obs, X)
    batch = hs.simulate_many(sysc, rows, t_max=T_MAX, backend="compiled", **RUN)
    for arc, row in zip(batch, rows):
        one = hs.simulate(sysc, row, t_max=T_MAX, backend="compiled", **RUN)
        np.testing.assert_array_equal(arc.t, one.t)
        np.testing.assert_array_equal(arc.x, one.x)
    ref = hs.simulate(sysc, rows[-1], t_max=T_MAX, **RUN)
    assert_same_run(batch[-1], ref)
    # xi_1 - xi_e of (13) at the end, psi read at t - tau = 0.2 (a sample, a jump, on
    # both arcs): the states agree to ~1e-15 and (13) multiplies a difference by at
    # most |S^-1| ~ 1e5 (measured: 2e-15)
    e_c, e_p = gd.errors(batch[-1], obs).e[-1], gd.errors(ref, obs).e[-1]
    np.testing.assert_allclose(e_c, e_p, rtol=0, atol=1e-10)


@pytest.mark.slow
def test_39_specialised_agrees(motor):
    """The lowered (39) with its maps compiled into its own kernel (specialize=True,
    about 15 s once per machine) agrees with the Python path as the shared kernel does."""
    obs = motor.sampled_observer(period=0.01)
    sysc, x0 = _loop(obs)
    ref = hs.simulate(sysc, x0, t_max=T_MAX, **RUN)
    lower(sysc, specialize=True)
    assert_same_run(hs.simulate(sysc, x0, t_max=T_MAX, backend="compiled", **RUN), ref)


def test_what_has_no_compiled_form_is_refused_by_name(motor):
    """The reset realisation, a control u or a disturbance without a compiled form:
    lower names it, lowerable says no (and backend="auto" then runs in Python)."""
    reset = motor.sampled_observer(period=0.01, realisation="reset")
    with pytest.raises(TypeError, match="realisation='reset' has no compiled form"):
        lower(_loop(reset)[0])
    sine = DCMotor(DC_PARAMS, 100.0, 0.1, u=np.sin, chi0=motor.chi0)
    with pytest.raises(TypeError, match="its control u is a Python callable"):
        lower(sine)
    with pytest.raises(TypeError, match="the Psi of its form is a Python callable"):
        sine.sampled_observer(period=0.01).compiled_component()
    rough = gd.dc_motor(100.0, 0.1, delta2=lambda t: [0.0])
    with pytest.raises(TypeError, match="its delta2 is a Python callable of t"):
        lower(_loop(rough.sampled_observer(period=0.01))[0])
    for sysc in (_loop(reset)[0], _loop(sine.sampled_observer(period=0.01))[0],
                 _loop(rough.sampled_observer(period=0.01))[0]):
        assert not lowerable(sysc)
    assert lowerable(_loop(motor.sampled_observer(period=0.01))[0])
