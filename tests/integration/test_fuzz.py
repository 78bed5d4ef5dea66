"""A fuzzed engine (issue 16, item 7): random hybrid systems, the invariants of
a hybrid arc asserted on every run.

Random linear flows x' = A x, affine jump maps x+ = G x + c, random affine
guards for D = {a.x - b >= 0} and (half the time) C = {e.x - d >= 0} or
C = everything, both priorities, random limits. On each run:

* t is non-decreasing, j starts at j0 and grows by 0 or 1;
* a jump is two samples with the same t and j, j + 1;
* every sample from which the run flows is in C (to the event tolerance);
* every pre-jump sample is in D (to the event tolerance);
* under jump priority, no flow passes through the interior of D without a
  jump: the guard along the dense output of each flow stays <= tol before
  the flow's last point;
* the cause agrees with the last sample (T_MAX at t_max, J_MAX after j_max
  jumps, LEFT_SETS/ZENO outside C, MAX_STEPS...);
* save/load and pickling give the arc back exactly.

Tolerances: events are bracketed to 4 ulp of t, so the state at an event is
off the guard by at most |guard'| * 4 ulp; with the flows' growth bounded
below that is < 1e-9 here. Interior points are compared with 1e-7 (rtol
1e-9 of states of order 10).
"""
import math
import pickle

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from paths import random_linear

import hybridsim as hs
from hybridsim import Termination

FUZZ = settings(max_examples=60, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])
TOL_EVENT = 1e-8
TOL_INSIDE = 1e-7


@st.composite
def hybrid_systems(draw):
    """A random case of ``tests/paths.py`` (flows that come back to the
    guard, jumps that land outside D, x0 in C) on the Python path."""
    n = draw(st.integers(1, 3))
    seed = draw(st.integers(0, 2**32 - 1))
    with_C = draw(st.booleans())
    case, x0 = random_linear(seed, n, with_C)
    priority = draw(st.sampled_from(["jumps", "flows"]))
    t_max = draw(st.floats(2.0, 6.0))
    j_max = draw(st.integers(6, 20))
    return case.python(), x0, priority, t_max, j_max, case.hD, (case.hC if with_C else None)


def run(sysm, x0, priority, t_max, j_max):
    return hs.simulate(sysm, x0, t_max=t_max, j_max=j_max, priority=priority, rtol=1e-9,
                       atol=1e-11, dense=True, max_norm=1e6, max_steps=20_000, warn=False)


@pytest.mark.slow
@FUZZ
@given(case=hybrid_systems())
def test_arcs_of_random_hybrid_systems_keep_their_invariants(case, tmp_path_factory):
    sysm, x0, priority, t_max, j_max, hD, hC = case
    arc = run(sysm, x0, priority, t_max, j_max)
    t, j, x = arc.t, arc.j, arc.x
    # the time domain
    assert np.all(np.diff(t) >= 0)
    dj = np.diff(j)
    assert j[0] == 0 and np.all((dj == 0) | (dj == 1))
    jumps = np.flatnonzero(dj == 1)
    assert np.all(t[jumps] == t[jumps + 1])
    assert arc.jump_count == len(jumps) <= j_max
    # pre-jump samples are in D; under flows priority they are also out of C
    for k in jumps:
        assert hD(x[k]) >= -TOL_EVENT
        if priority == "flows" and hC is not None and arc.termination is not Termination.ZENO:
            assert hC(x[k]) <= TOL_EVENT or hD(x[k]) >= -TOL_EVENT
    # samples from which the run flows are in C
    flows_from = np.flatnonzero((dj == 0) & (np.diff(t) > 0))
    if hC is not None:
        for k in flows_from:
            assert hC(x[k]) >= -TOL_EVENT
    # no flow through the interior of D without a jump (jump priority)
    if priority == "jumps":
        for ta, tb, jj in arc.flow_intervals:
            if tb <= ta:
                continue
            grid = np.linspace(ta, tb, 41)[1:-1]
            vals = [hD(v) for v in arc.at(grid, jj)]
            assert max(vals) <= TOL_INSIDE, (ta, tb, jj, max(vals))
    # the cause agrees with the last sample
    cause = arc.termination
    if cause is Termination.T_MAX:
        assert t[-1] == t_max
    elif cause is Termination.J_MAX:
        assert arc.jump_count == j_max
    elif cause in (Termination.LEFT_SETS, Termination.NOT_IN_SETS):
        assert hC is not None and hC(x[-1]) <= TOL_EVENT and hD(x[-1]) < TOL_EVENT
    elif cause is Termination.BLOWUP:
        assert np.linalg.norm(x[-1]) > 1e6
    else:
        assert cause in (Termination.ZENO, Termination.MAX_STEPS), cause
    # the arc travels and lasts exactly
    path = tmp_path_factory.mktemp("arc") / "a"
    arc.save(path)
    back = hs.HybridArc.load(path)
    for name in ("t", "j", "x"):
        assert np.array_equal(getattr(back, name), getattr(arc, name))
    assert back.termination is cause
    again = pickle.loads(pickle.dumps(arc))
    assert np.array_equal(again.x, arc.x) and again.termination is cause
    assert math.isclose(float(again.at(t[-1], j[-1])[0]), float(x[-1, 0]), abs_tol=1e-12)
