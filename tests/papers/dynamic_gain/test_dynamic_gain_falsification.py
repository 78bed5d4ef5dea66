"""Paper 000's falsification problems (observers.dynamic_gain.falsification).

Tolerances: the auxiliary system (13)+(16) is run by RK45 (rtol 1e-4 where the
margins are 0.4-1, rtol 1e-6 / atol 1e-12 for the printed decay); its settling
time agrees with the observer's Radau run (gain_settling_time) to 1e-3 s here
(Radau's located switch is good to ~1e-5 s, RK45 at rtol 1e-4 to ~1e-4 relative).
"""
import numpy as np
import pytest

import hybridsim as hs
from observers.dynamic_gain import EXAMPLE, proposed_observer, simulate
from observers.dynamic_gain.example import gain_settling_time
from observers.dynamic_gain.falsification import (
    PROBLEMS,
    AuxiliarySystem,
    iss_constant,
    iss_worst_cases,
    lmi_alpha,
)
from observers.falsification import run_problem, validate_problems
from observers.lmi import lmi10_matrices

BY_ID = {p.id: p for p in PROBLEMS}


def test_problems_are_valid():
    validate_problems(PROBLEMS, paper="000")
    assert BY_ID["000-thm3-eps-decay-printed"].expect == "counterexample"
    for pid in ("000-thm3-eps-decay-corrected", "000-eq17-bound-printed",
                "000-eq17-bound-corrected"):
        assert BY_ID[pid].expect == "none" and BY_ID[pid].budget >= 2000


def test_alpha_is_the_claims():
    assert abs(lmi_alpha()[0] - 18.0) < 0.01          # claim 000-eq17-bound: 18.00


@pytest.mark.slow
def test_auxiliary_system_settles_as_the_observer():
    aux = AuxiliarySystem(EXAMPLE["L"], EXAMPLE["mu"], EXAMPLE["gamma1"], 1.0)
    e0, v0 = np.array([0.3, 4.0, -2.0, 1.0]), 1.2
    arc = hs.simulate(aux, aux.initial_state(e0, v0), t_max=30.0, rtol=1e-9, atol=1e-12,
                      progress=False)
    obs = proposed_observer(EXAMPLE["L"], EXAMPLE["mu"], EXAMPLE["gamma1"], 1.0,
                            b=EXAMPLE["b"])
    x0 = EXAMPLE["x0"]
    run = simulate(obs, x0, x0 - e0[1:], t_max=float(aux.settling_time(arc.x[-1])) + 0.2,
                   v0=v0, w0=e0[0])
    assert abs(gain_settling_time(run, obs) - float(aux.settling_time(arc.x[-1]))) < 1e-3


def test_printed_decay_is_falsified_at_the_predicted_rate():
    r = run_problem(BY_ID["000-thm3-eps-decay-printed"], seed=0)
    assert r.found == "counterexample" and r.passed
    arc = r.search.arc
    # the ratio grows like e^{0.307 tau} with an oscillation of period 11.7: its
    # largest value is in the last oscillation's peak, near the end (tau <= 25)
    assert 25.0 - 11.7 / 2 <= r.search.where[0] <= 25.0
    # closed form: ||eps|| e^tau grows like e^{(1 + Re lambda) tau}, lambda the slowest
    # eigenvalue of A + LC + gamma1 H; slope over tau in [15, 25], tol 0.05: the pair
    # -0.693 +- 0.539i makes ||eps|| oscillate with period 11.7 > the 10-long window
    A, C, H = lmi10_matrices(3, EXAMPLE["mu"])
    lam = np.linalg.eigvals(A + np.outer(EXAMPLE["L"], C[0]) + EXAMPLE["gamma1"] * H)
    rate = 1.0 + lam.real.max()
    sel = arc.t >= 15.0
    lr = np.log(np.linalg.norm(arc.x[sel, :4], axis=1)) + arc.t[sel]
    slope = np.polyfit(arc.t[sel], lr, 1)[0]
    assert rate == pytest.approx(0.3067, abs=1e-3)
    assert slope == pytest.approx(rate, abs=0.05)
    assert r.margin < -10


@pytest.mark.slow
@pytest.mark.parametrize("pid", ["000-thm3-eps-decay-corrected", "000-eq17-bound-printed",
                                 "000-eq17-bound-corrected"])
def test_survives_2000(pid):
    r = run_problem(BY_ID[pid], seed=0)
    assert r.search.evaluations >= 2000 and r.baseline.evaluations >= 2000
    assert r.found == "none" and r.passed
    if "eq17" in pid:           # the bound's exponent is far from used (module notes)
        assert r.margin > 0.9


@pytest.mark.slow
def test_iss_worst_case_record():
    C, top = iss_constant()
    assert C == pytest.approx(4.0 * top)
    (w,) = iss_worst_cases((0.1,), budget=100)
    assert w.margin >= 0 and w.ratio <= w.bound and w.ratio >= top * 0.5
    assert w.values.shape == (5, 4) and np.abs(w.values).max() <= 0.1


def test_the_worst_run_is_drawn_with_its_margin_at_each_sample():
    """draw_worst's third panel is the worst run itself: the claim's margin at
    each sample (the problem's Margin.series), its minimum at the deciding
    sample, the zero line; and the margins of hybridsim.testing keep it."""
    from hybridsim.testing import margin_bounded
    from observers.falsification import draw_worst
    r = run_problem(BY_ID["000-thm3-eps-decay-printed"], seed=0)
    fig = draw_worst(r)
    ax_run = fig.axes[2]
    line = ax_run.lines[0]
    assert line.get_label() == "margin at each sample of the worst run"
    t, v = line.get_xdata(), line.get_ydata()
    np.testing.assert_array_equal(t, r.search.arc.t)
    assert v.min() == pytest.approx(r.margin, rel=1e-12)
    dec = [ln for ln in ax_run.lines if ln.get_label().startswith("deciding sample")]
    assert len(dec) == 1 and dec[0].get_xdata()[0] == pytest.approx(r.search.where[0])
    assert "margin" in ax_run.get_ylabel() and ax_run.get_xlabel().startswith("t")
    assert any(ln.get_ydata()[0] == 0 for ln in ax_run.lines[1:])        # the zero line
    arc = r.search.arc
    m = margin_bounded(arc, arc.x[:, :1], 1.0)
    mt, mj, mv = m.series
    assert mt.size == arc.t.size and float(m) == mv.min()
