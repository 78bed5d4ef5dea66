"""The example scripts run, write their figures and show what they claim.

Only the engine's own examples are run here (the papers' examples,
``examples/<paper>_example.py``, are tested with their observers). Each
script is run twice: once as a user runs it (``python examples/x.py DIR``, as
``__main__`` with runpy; one script also in a real subprocess with no
argument), once through its ``main(out)`` to check a property of the arc it
returns.
"""
import os
import runpy
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

FIGURES = {
    "bouncing_ball.py": {"bouncing_ball_flows.png", "bouncing_ball_jumps.png",
                         "bouncing_ball_hybrid.png"},
    "thermostat.py": {"thermostat_flows.png", "thermostat_time_domain.png"},
    "sample_and_hold.py": {"sample_and_hold_flows.png", "sample_and_hold_phase.png"},
    "timer.py": {"timer_time_domain.png"},
}

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _check_pngs(folder, names):
    written = {p.name for p in Path(folder).glob("*.png")}
    assert written == names
    for name in names:
        data = (Path(folder) / name).read_bytes()
        assert data[:8] == PNG_MAGIC and len(data) > 5000, name   # a real, non-empty figure


def _load(script):
    return runpy.run_path(str(EXAMPLES / script))


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.mark.parametrize("script", sorted(FIGURES))
def test_script_from_the_command_line(script, tmp_path, monkeypatch, capsys):
    """``python examples/<script> DIR`` (run in-process: the interpreter's
    start-up would cost more than the script)."""
    out = tmp_path / "figs"
    monkeypatch.setattr(sys, "argv", [str(EXAMPLES / script), str(out)])
    runpy.run_path(str(EXAMPLES / script), run_name="__main__")
    assert f"figures written to {out}" in capsys.readouterr().out
    _check_pngs(out, FIGURES[script])


def test_script_default_folder_is_the_working_folder(tmp_path):
    """With no argument the figures go to $HYBRIDSIM_FIGURES, else to the
    working folder (never to a folder the user did not ask for)."""
    env = {k: v for k, v in os.environ.items() if k != "HYBRIDSIM_FIGURES"}
    # this checkout's package, installed or not
    path = os.pathsep.join(p for p in (str(EXAMPLES.parent), env.get("PYTHONPATH")) if p)
    env.update(MPLBACKEND="Agg", TMPDIR=str(tmp_path / "tmp"), PYTHONPATH=path)
    (tmp_path / "tmp").mkdir()
    res = subprocess.run([sys.executable, str(EXAMPLES / "timer.py")], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120, env=env)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().splitlines()[-1] == "figures written to ."
    _check_pngs(tmp_path, FIGURES["timer.py"])
    assert not any((tmp_path / "tmp").iterdir())


def test_script_folder_from_the_environment(tmp_path, monkeypatch, capsys):
    out = tmp_path / "from_env"
    monkeypatch.setenv("HYBRIDSIM_FIGURES", str(out))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", [str(EXAMPLES / "timer.py")])
    runpy.run_path(str(EXAMPLES / "timer.py"), run_name="__main__")
    assert f"figures written to {out}" in capsys.readouterr().out
    _check_pngs(out, FIGURES["timer.py"])
    assert not list(tmp_path.glob("*.png"))


def test_bouncing_ball(tmp_path):
    ns = _load("bouncing_ball.py")
    arc = ns["main"](tmp_path)
    _check_pngs(tmp_path, FIGURES["bouncing_ball.py"])
    assert arc.termination.name == "J_MAX" and arc.jump_count == 20
    # rtol 1e-10 on a polynomial flow: the located jumps are within 1e-9 of t_k
    np.testing.assert_allclose(arc.jump_times, ns["analytic_jump_times"](20), rtol=0, atol=1e-9)
    assert arc.x[:, 0].min() >= -1e-9          # never sinks below the floor
    # each bounce keeps the height and scales the velocity by -E
    k = arc.jump_index
    np.testing.assert_allclose(arc.x[k, 1], -ns["E"] * arc.x[k - 1, 1], rtol=1e-12)


def test_thermostat_stays_in_its_band(tmp_path):
    ns = _load("thermostat.py")
    arc = ns["main"](tmp_path)
    _check_pngs(tmp_path, FIGURES["thermostat.py"])
    zmin, zmax = ns["Z_MIN"], ns["Z_MAX"]
    assert arc.success and arc.jump_count == 11
    z, q = arc.x[:, 0], arc.x[:, 1]
    assert set(np.unique(q)) == {0.0, 1.0}
    after = arc.t >= arc.jump_times[0]
    # guards locate the switch to ~1e-15 in t; z moves at most 20/unit time
    assert z[after].min() >= zmin - 1e-9 and z[after].max() <= zmax + 1e-9
    # the heater alternates, switching off at z_max and on at z_min
    k = arc.jump_index
    np.testing.assert_array_equal(q[k], np.arange(len(k)) % 2 == 1)
    np.testing.assert_allclose(z[k], np.where(q[k] == 0, zmax, zmin), atol=1e-9)
    np.testing.assert_allclose(arc.jump_times, ns["switch_times"](65.0, 11), rtol=0, atol=1e-9)


@pytest.mark.parametrize("priority", ["jumps", "flows"])
def test_thermostat_on_a_threshold_switches_at_once(priority):
    """z = z_min with the heater off is in C ∩ D and the flow leaves C at once:
    both priorities switch the heater on at t = 0."""
    import hybridsim as hs
    ns = _load("thermostat.py")
    arc = hs.simulate(ns["Thermostat"](), [ns["Z_MIN"], 0.0], t_max=0.5, priority=priority)
    assert arc.success and arc.jump_count == 1
    assert abs(arc.jump_times[0]) <= 1e-12
    assert arc.x[arc.jump_index[0], 1] == 1.0


def test_sample_and_hold_converges(tmp_path):
    ns = _load("sample_and_hold.py")
    arc = ns["main"](tmp_path)
    _check_pngs(tmp_path, FIGURES["sample_and_hold.py"])
    T, N, K = ns["T"], ns["N"], ns["K"]
    assert arc.success
    # sampling instants at 0, T, 2T, ... (the first at t = 0: tau0 = T)
    ts = arc.jump_times
    np.testing.assert_allclose(ts, T * np.arange(len(ts)), rtol=0, atol=1e-9)
    # each sample sets u = K x and resets the timer
    k = arc.jump_index
    np.testing.assert_allclose(arc.x[k, N:-1], arc.x[k, :N] @ K.T, rtol=1e-12, atol=1e-15)
    assert np.all(arc.x[k, -1] == 0.0)
    # the held loop follows its ZOH discretisation and decays
    phi = ns["zoh_closed_loop"]()
    rho = max(abs(np.linalg.eigvals(phi)))
    assert rho < 1
    x0 = arc.x[0, :N]
    expected = np.array([np.linalg.matrix_power(phi, m) @ x0 for m in range(len(k))])
    np.testing.assert_allclose(arc.x[k, :N], expected, rtol=0, atol=1e-8)
    norms = np.linalg.norm(arc.x[:, :N], axis=1)
    assert norms[-1] < 1e-4 * norms[0]
    late = arc.t >= arc.tf / 2
    assert norms[late].max() < 1e-2 * norms[0]


def test_timer(tmp_path):
    ns = _load("timer.py")
    arc = ns["main"](tmp_path)
    _check_pngs(tmp_path, FIGURES["timer.py"])
    assert arc.success and arc.jump_count == 5
    np.testing.assert_allclose(arc.jump_times, np.arange(1.0, 6.0), rtol=0, atol=8e-15)
    np.testing.assert_allclose(arc.flow_lengths, [1, 1, 1, 1, 1, 0.5], atol=1e-13)
    assert arc.x[:, 0].min() >= 0 and arc.x[:, 0].max() <= 1 + 1e-14


@pytest.mark.slow
def test_falsify_overshoot_finds_the_half_degree_claim_false(capsys):
    """The worked falsification example: with |m| <= 1 the temperature reaches
    z_max + 1 (or z_min - 1) exactly, so "within 0.5" fails by 0.5 and
    "within 1" holds with margin equal to the slack TOL (1e-6)."""
    ns = runpy.run_path(str(EXAMPLES / "falsify_overshoot.py"), run_name="__main__")
    claimed, corrected, baseline = ns["claimed"], ns["corrected"], ns["baseline"]
    assert claimed.verdict == "counterexample"
    assert abs(claimed.margin + 0.5) < 1e-5          # 0.5 beyond, to the runs' accuracy
    assert corrected.verdict == "none found" and 0 <= corrected.margin <= 2e-6
    assert claimed.margin <= baseline.margin
    z = claimed.arc.x[:, 0]
    assert max(z.max() - 80.0, 70.0 - z.min()) == pytest.approx(1.0, abs=1e-5)
    assert "claim: within 0.5 degree" in capsys.readouterr().out
