"""simulate_many (looped) and sweep: one arc per initial state or parameter."""
import numpy as np
import pytest

import hybridsim as hs


class Decay(hs.HybridSystem):
    """x' = -a x (a picklable module-level system)."""

    state_dim = 1

    def __init__(self, a=1.0):
        self.a = a

    def flow_map(self, x):
        return -self.a * x


def make_decay(a):
    return Decay(a)


def test_simulate_many_one_arc_per_row():
    x0s = np.array([[1.0], [2.0], [-3.0]])
    arcs = hs.simulate_many(Decay(), x0s, t_max=1.0, rtol=1e-10, atol=1e-12)
    assert len(arcs) == 3
    for x0, arc in zip(x0s, arcs):
        np.testing.assert_allclose(arc.xf, x0 * np.exp(-1.0), rtol=1e-8)


def test_sweep_over_parameters():
    arcs = hs.sweep(make_decay, [0.5, 1.0, 2.0], [1.0], t_max=1.0, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose([a.xf[0] for a in arcs], np.exp(-np.array([0.5, 1.0, 2.0])),
                               rtol=1e-8)
    arcs = hs.sweep(make_decay, [1.0, 2.0], lambda a: [a], t_max=0.0)
    assert [a.x0[0] for a in arcs] == [1.0, 2.0]


def test_sweep_and_many_with_a_process_pool():
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(2) as ex:
        arcs = hs.sweep(make_decay, [0.5, 1.0, 2.0, 4.0], [1.0], t_max=1.0, executor=ex,
                        rtol=1e-10, atol=1e-12)
        many = hs.simulate_many(Decay(), np.ones((5, 1)), t_max=1.0, executor=ex)
    np.testing.assert_allclose([a.xf[0] for a in arcs], np.exp(-np.array([0.5, 1, 2, 4])),
                               rtol=1e-8)
    assert len(many) == 5


def test_bad_batch_input():
    with pytest.raises(ValueError, match=r"x0s must have shape \(N, 1\), got \(3,\)"):
        hs.simulate_many(Decay(), np.ones(3), t_max=1.0)
    with pytest.raises(TypeError, match="system must be a HybridSystem"):
        hs.simulate_many(object(), np.ones((3, 1)), t_max=1.0)
    with pytest.raises(TypeError, match="make_system must be a callable"):
        hs.sweep(3, [1], [1.0], t_max=1.0)


# ------------------------------------------------------------------ progress bars
class _TTY:
    """A stderr that says it is a terminal."""

    def __init__(self):
        import io
        self.buf = io.StringIO()

    def isatty(self):
        return True

    def write(self, s):
        return self.buf.write(s)

    def flush(self):
        pass


class _Shell:
    def __init__(self, config):
        self.config = config


def _fake_ipython(monkeypatch, config):
    import sys
    import types
    mod = types.ModuleType("IPython")
    mod.get_ipython = lambda: _Shell(config)
    monkeypatch.setitem(sys.modules, "IPython", mod)


def test_progress_automatic_at_a_terminal_and_in_a_notebook(monkeypatch):
    import io
    import sys

    from hybridsim._progress import in_notebook, progress_enabled
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setitem(sys.modules, "IPython", None)
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert progress_enabled(None) is False                  # redirected: off
    assert progress_enabled(True) is True and progress_enabled(False) is False
    monkeypatch.setattr(sys, "stderr", _TTY())
    assert progress_enabled(None) is True                   # a terminal: on
    monkeypatch.setenv("CI", "true")
    assert progress_enabled(None) is False                  # CI: off
    monkeypatch.setenv("CI", "0")
    assert progress_enabled(None) is True
    monkeypatch.delenv("CI")
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    _fake_ipython(monkeypatch, {"IPKernelApp": {}})        # a Jupyter kernel: on
    assert in_notebook() and progress_enabled(None) is True
    _fake_ipython(monkeypatch, {"TerminalIPythonApp": {}})  # terminal IPython, piped: off
    assert not in_notebook() and progress_enabled(None) is False


def test_progress_argument_checked():
    from hybridsim._progress import make_bar
    with pytest.raises(TypeError, match=r"progress must be True, False or None.*str 'yes'"):
        make_bar("yes", total=1, desc="x")
    with pytest.raises(TypeError, match="desc must be a str"):
        make_bar(True, total=1, desc=3)
    assert make_bar(False, total=1, desc="x") is None
    assert make_bar(np.bool_(False), total=1, desc="x") is None


def test_single_run_bar_shows_t_and_j():
    import io

    from hybridsim._progress import make_bar
    out = io.StringIO()
    bar = make_bar(True, total=5.0, desc="simulate", unit="t", postfix="j=0", file=out,
                   bar_format="{desc}: t={n:.3g}/{total:.3g}{postfix}", mininterval=0)
    bar.update(1.25)
    bar.set_postfix_str("j=3")
    assert str(bar) == "simulate: t=1.25/5, j=3"
    bar.refresh()
    assert "t=1.25/5, j=3" in out.getvalue()
    bar.close()
    bar = make_bar(True, total=None, desc="simulate", unit="jump", postfix={"j": 2}, file=out)
    assert "j=2" in str(bar) and "jump" in str(bar)
    bar.close()


def _one_line(err):
    """The text a one-line bar left: what follows its last carriage return."""
    assert "\n" not in err and "\x1b[" not in err, repr(err)   # one line, no cursor moves
    return err.rstrip("\r").rsplit("\r", 1)[-1]


def test_notebook_without_widgets_gets_one_clean_line(monkeypatch, capsys):
    """A Jupyter kernel without ipywidgets: tqdm's widget bar cannot be made
    (it raised, and left a half-made bar printing a traceback when
    collected); the bar is one line of text, a second bar while it is open
    is refused (a run inside a batch), and a closed bar leaves no stale
    0% line behind."""
    from hybridsim import _progress
    from hybridsim._progress import make_bar
    monkeypatch.delenv("CI", raising=False)
    _fake_ipython(monkeypatch, {"IPKernelApp": {}})
    monkeypatch.setattr(_progress, "_widgets_available", lambda: False)
    bar = make_bar(None, total=2.0, desc="simulate", unit="t", postfix="j=0", delay=0,
                   mininterval=0, bar_format="{desc}: t={n:.3g}/{total:.3g}{postfix}")
    assert bar is not None
    assert make_bar(None, total=3, desc="simulate_many", unit="run") is None   # nested
    bar.update(1.5)
    bar.set_postfix_str("j=2")
    err = capsys.readouterr().err
    assert _one_line(err) == "simulate: t=1.5/2, j=2"
    bar.close()
    err = capsys.readouterr().err
    assert _one_line(err).strip() == ""                  # erased: no stale bar
    assert "Exception ignored" not in err
    # the line is free again; a run shorter than the bar's delay draws nothing
    later = make_bar(None, total=1, desc="simulate_many", unit="run")
    assert later is not None
    later.close()
    hs.simulate_many(Decay(), np.ones((3, 1)), t_max=0.1, progress=None)
    hs.simulate(Decay(), [1.0], t_max=0.1, progress=None)
    err = capsys.readouterr().err                      # "" unless the machine is slow
    assert err == "" or _one_line(err).strip() == ""


def test_batches_draw_one_bar_over_runs(capsys):
    hs.simulate_many(Decay(), np.ones((3, 1)), t_max=0.1, progress=True)
    err = capsys.readouterr().err
    assert "simulate_many" in err and "3/3" in err and "run" in err
    hs.sweep(make_decay, [1.0, 2.0], [1.0], t_max=0.1, progress=True)
    assert "2/2" in capsys.readouterr().err
    hs.simulate_many(Decay(), np.ones((3, 1)), t_max=0.1, progress=False)
    assert capsys.readouterr().err == ""


# ------------------------------------------------------------------ the batch's arrays
from paths import Ball  # noqa: E402


def _batch(path, x0s, **kw):
    """hs.simulate_many of a ball on ``path``: the looped Python path, the vectorized batch,
    the compiled batch."""
    system = Ball(sets="both").build(path)
    backend = "compiled" if path == "compiled" else "python"
    return hs.simulate_many(system, x0s, warn=False, backend=backend, **kw)


def _fields_of_arcs(arcs):
    """The batch's fields, each read from the arcs."""
    jt = [a.jump_times for a in arcs]
    K = max(map(len, jt))
    pad = np.array([np.concatenate([t, np.full(K - len(t), np.nan)]) for t in jt])
    return dict(final_states=np.array([a.xf for a in arcs]),
                final_times=np.array([a.tf for a in arcs]),
                final_jumps=np.array([a.jf for a in arcs]),
                jump_counts=np.array([a.jump_count for a in arcs]),
                success=np.array([a.success for a in arcs]),
                jump_times=pad, jump_times_flat=np.concatenate(jt),
                jump_offsets=np.concatenate([[0], np.cumsum(list(map(len, jt)))]))


@pytest.mark.paths(compiled_slow=True)
def test_batch_fields_are_the_arcs_on_every_path(path, monkeypatch):
    # rows ending at j_max and at t_max (different jump counts), and a failed row
    import hybridsim.arc as arc_mod
    monkeypatch.setattr(arc_mod, "CHECK_ARCS", False)     # (it makes every arc whole)
    if path == "compiled":       # 12 short rows would run one by one, none pooled
        import hybridsim.compiled._run as run_mod
        monkeypatch.setattr(run_mod, "_ALONE", 0)
    h0 = np.linspace(0.3, 2.0, 12)
    x0s = np.column_stack([h0, np.zeros_like(h0)])
    x0s[4, 0] = np.nan
    batch = _batch(path, x0s, t_max=2.0, j_max=4, rtol=1e-8, atol=1e-10)
    assert isinstance(batch, hs.ArcBatch) and isinstance(batch, list) and len(batch) == 12
    # the fields first: the compiled path reads them off its pool, its arcs left as views
    pooled = [i for i, a in enumerate(batch) if "_pool" in a.__dict__]
    got = {k: getattr(batch, k) for k in ("final_states", "final_times", "final_jumps",
                                           "jump_counts", "success", "jump_times",
                                           "jump_times_flat", "jump_offsets")}
    causes = batch.causes
    assert pooled == [i for i, a in enumerate(batch) if "_pool" in a.__dict__]
    assert (len(pooled) >= 7) == (path == "compiled")   # all but a few rows run alone first
    want = _fields_of_arcs(batch)
    again = hs.ArcBatch(list(batch))         # the same arcs, no record of the engine's
    for k, v in want.items():
        np.testing.assert_array_equal(got[k], v, err_msg=k)
        np.testing.assert_array_equal(getattr(again, k), v, err_msg=k)
    assert [c.name for c in causes] == [a.termination.name for a in batch]
    assert causes[4] is hs.Termination.NON_FINITE and not batch.success[4]
    assert set(batch.jump_counts[batch.causes == hs.Termination.J_MAX]) == {4}
    assert (batch.causes == hs.Termination.T_MAX).sum() >= 1       # the highest drops
    # row i's jump times, padded and ragged
    o = batch.jump_offsets
    for i, arc in enumerate(batch):
        np.testing.assert_array_equal(batch.jump_times_flat[o[i]:o[i + 1]], arc.jump_times)
        assert np.isnan(batch.jump_times[i, arc.jump_count:]).all()


def test_batch_is_the_list_it_was(path):
    x0s = np.column_stack([np.linspace(0.5, 1.5, 5), np.zeros(5)])
    batch = _batch(path, x0s, t_max=1.5, j_max=3)
    arcs = list(batch)
    assert batch == arcs and len(batch) == 5 and batch[-1] is arcs[-1]
    part = batch[1:4]
    assert isinstance(part, hs.ArcBatch) and part == arcs[1:4]
    np.testing.assert_array_equal(part.final_times, batch.final_times[1:4])
    assert [a.jump_count for a in batch] == batch.jump_counts.tolist()
    import pickle
    back = pickle.loads(pickle.dumps(batch))
    assert isinstance(back, hs.ArcBatch) and len(back) == 5
    np.testing.assert_array_equal(back.jump_times, batch.jump_times)
    # a change to the list: the fields follow it
    batch.append(batch[0])
    batch[1] = batch[2]
    assert batch.final_times.tolist() == [a.tf for a in batch]
    del batch[0]
    batch.reverse()
    assert batch.jump_counts.tolist() == [a.jump_count for a in batch]
    batch.sort(key=lambda a: a.tf)
    assert batch.final_times.tolist() == sorted(a.tf for a in batch)
    import copy
    twin = copy.copy(batch)
    assert isinstance(twin, hs.ArcBatch) and twin == batch
    np.testing.assert_array_equal(twin.final_times, batch.final_times)
    assert (batch + arcs)[:6] == list(batch) + arcs[:1]


def test_batch_empty_mixed_and_bad():
    empty = hs.simulate_many(Decay(), np.zeros((0, 1)), t_max=1.0)
    assert empty == [] and empty.final_states.shape == (0, 1)
    assert empty.jump_times.shape == (0, 0) and empty.jump_offsets.tolist() == [0]
    assert hs.sweep(make_decay, [], [1.0], t_max=1.0).jump_counts.shape == (0,)
    mixed = hs.ArcBatch([hs.HybridArc([0.0], [0], [[1.0]], None),
                         hs.HybridArc([0.0], [0], [[1.0, 2.0]], None)])
    assert mixed.final_times.tolist() == [0.0, 0.0] and mixed.jump_counts.tolist() == [0, 0]
    with pytest.raises(ValueError, match="different dimensions"):
        _ = mixed.final_states
    with pytest.raises(TypeError, match="row 1 is a str, not a HybridArc"):
        _ = hs.ArcBatch([mixed[0], "arc"]).final_times
    with pytest.raises(ValueError, match="row 0's arc is empty"):
        _ = hs.ArcBatch([hs.HybridArc([], [], np.zeros((0, 1)), None)]).jump_counts


def test_a_plain_model_run_compiled_gets_its_arcs_back():
    # the lowered model's arcs are given back to the model in place: the batch keeps its
    # record of the pooled rows (its fields read off the pools) and every arc names the model
    pytest.importorskip("numba")
    from hybridsim.library import BouncingBall
    ball = BouncingBall()
    h0 = np.linspace(0.5, 2.0, 7)
    batch = hs.simulate_many(ball, np.column_stack([h0, 0 * h0]), 1e9, 3, backend="compiled")
    assert isinstance(batch, hs.ArcBatch)
    assert all(a.system is ball and "BouncingBall" in a.system_description for a in batch)
    np.testing.assert_allclose(batch.jump_times,
                               hs.library.bouncing_ball_jump_times(h0, 3), atol=1e-7)
    assert batch.jump_counts.tolist() == [3] * 7 and batch.success.all()


def test_a_small_batch_gives_the_rows_of_a_large_one_from_any_thread():
    """A batch of fewer than 16 rows runs its rows in the calling thread (the
    single-run kernel from the main thread, the batch kernel with the GIL
    released from another): the arcs of the same rows in a batch of 40 that
    the worker threads run."""
    pytest.importorskip("numba")
    import concurrent.futures

    from hybridsim.library import BouncingBall
    ball = BouncingBall()
    h0 = np.linspace(0.5, 2.0, 40)
    X = np.column_stack([h0, 0 * h0])
    kw = dict(t_max=1e9, j_max=3, backend="compiled", rtol=1e-9, atol=1e-11)
    big = hs.simulate_many(ball, X, **kw)
    small = hs.simulate_many(ball, X[:5], **kw)
    with concurrent.futures.ThreadPoolExecutor(1) as ex:
        off_main = ex.submit(hs.simulate_many, ball, X[:5], **kw).result()
    for batch in (small, off_main):
        for a, b in zip(batch, big[:5], strict=True):
            assert a.termination is b.termination
            np.testing.assert_array_equal(a.t, b.t)
            np.testing.assert_array_equal(a.j, b.j)
            np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(batch.jump_times, big.jump_times[:5])
