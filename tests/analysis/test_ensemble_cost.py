"""What an ensemble cost, as the figure JSON records it (``ensemble_data.ensemble_cost``)."""

from __future__ import annotations

import pytest

from tiltpile import config
from tiltpile.analysis.ensemble_data import ensemble_cost, load_ensemble
from tiltpile.runner import simulate
from tiltpile.store import open_run


def test_ensemble_cost_known_answer():
    costs = [dict(steps=10, sweeps=100, capped_steps=1, seconds=5.0, resumed_from_frame=-1),
             dict(steps=20, sweeps=300, capped_steps=3, seconds=9.0, resumed_from_frame=-1),
             dict(steps=30, sweeps=500, capped_steps=5, seconds=1.0, resumed_from_frame=4)]  # resumed
    c = ensemble_cost(costs)
    assert c == dict(runs_timed=2, seconds_per_run=7.0, steps_per_run=20.0, sweeps_per_run=300.0,
                     capped_steps_per_run=3.0)
    old = ensemble_cost([{}, {}])  # files from before the counts
    assert old["runs_timed"] == 0 and old["seconds_per_run"] is None and old["sweeps_per_run"] is None
    # a resumed run counts when its wall time was summed over every invocation
    summed = costs[:2] + [dict(costs[2], wall_seconds=30.0, wall_seconds_whole=True),
                          dict(costs[2], wall_seconds=2.0, wall_seconds_whole=False)]
    c = ensemble_cost(summed)
    assert c["runs_timed"] == 3 and c["seconds_per_run"] == 9.0


def test_a_delay_at_the_end_cannot_put_the_summed_wall_time_above_the_invocations(tmp_path, monkeypatch):
    """A run of one invocation: its summed wall time starts when the writer opens the file, after
    the invocation's own clock, so it is at most the invocation's seconds, however long the
    process waits between clock readings. Forced here: every reading of the writer's clock comes
    10 s after the one before. When the end read it twice (once for each number), a 2.9 s run
    had a sum of 32.9 s here, and on a loaded machine a sum 7 ms above its seconds."""
    import time as real_time
    from types import SimpleNamespace

    from tiltpile.store import writer as writer_module

    delay = iter(range(0, 10**6, 10))
    monkeypatch.setattr(writer_module, "time",
                        SimpleNamespace(perf_counter=lambda: real_time.perf_counter() + next(delay)))
    cfg = config.load("smoke", overrides=["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=1.0"])
    simulate(cfg, 4, tmp_path / "run_0004.h5", progress=False)
    with open_run(tmp_path / "run_0004.h5") as run:
        cost = run.cost
    assert cost["wall_seconds_whole"] and 0 < cost["wall_seconds"] <= cost["seconds"]
    assert cost["seconds"] >= 10.0                      # the writer's clock did jump


class _Killed(BaseException):
    """Stands for the process being ended (not an Exception: nothing may catch it)."""


def _interrupted(cfg, out, seed=4):
    """Simulate ``seed`` into ``out`` and end it once its first checkpoint is on disk; returns
    the checkpoint's wall_seconds and wall_seconds_whole."""
    import h5py

    from tiltpile.store import checkpoint_path

    def stop(_event):
        if checkpoint_path(out).exists():
            raise _Killed

    with pytest.raises(_Killed):
        simulate(cfg, seed, out, progress=False, on_progress=stop)
    with h5py.File(checkpoint_path(out), "r") as g:
        return float(g.attrs["wall_seconds"]), bool(g.attrs["wall_seconds_whole"])


def test_a_resumed_run_sums_the_wall_time_of_its_invocations(tmp_path):
    cfg = config.load("smoke", overrides=["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=2.0",
                                          "protocol.checkpoint_every=3"])
    out = tmp_path / "run_0004.h5"
    before, whole = _interrupted(cfg, out)
    assert before > 0 and whole
    summary = simulate(cfg, 4, out, progress=False)
    assert summary["resumed_from_frame"] > 0
    with open_run(out) as run:
        cost = run.cost
    # the earlier invocation's time up to its checkpoint, plus this one's (which began before
    # its writer reopened the file)
    assert cost["wall_seconds_whole"] and before < cost["wall_seconds"] <= before + cost["seconds"]
    assert cost["wall_seconds"] > cost["seconds"]
    meta = load_ensemble(tmp_path).meta["cost"]
    assert meta["runs_timed"] == 1 and meta["seconds_per_run"] == pytest.approx(cost["wall_seconds"])


def test_a_checkpoint_from_before_the_sum_leaves_the_runs_wall_time_partial(tmp_path):
    """Resumed from a checkpoint without ``wall_seconds`` (written by an older tiltpile), the run
    counts only from there and says so; the ensemble's seconds per run leave it out."""
    import h5py

    from tiltpile.store import checkpoint_path

    cfg = config.load("smoke", overrides=["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=2.0",
                                          "protocol.checkpoint_every=3"])
    out = tmp_path / "run_0004.h5"
    _interrupted(cfg, out)
    with h5py.File(checkpoint_path(out), "r+") as g:
        del g.attrs["wall_seconds"], g.attrs["wall_seconds_whole"]
    simulate(cfg, 4, out, progress=False)
    with open_run(out) as run:
        cost = run.cost
    assert not cost["wall_seconds_whole"] and 0 < cost["wall_seconds"] <= cost["seconds"]
    assert load_ensemble(tmp_path).meta["cost"]["runs_timed"] == 0


def test_run_files_record_their_cost_and_the_ensemble_meta_carries_it(tmp_path):
    cfg = config.load("smoke", overrides=["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=2.0"])
    summary = simulate(cfg, 4, tmp_path / "run_0004.h5", progress=False)
    with open_run(tmp_path / "run_0004.h5") as run:
        cost = run.cost
    assert cost["resumed_from_frame"] == -1 and 0 < cost["seconds"] <= summary["seconds"]
    assert cost["wall_seconds_whole"] and 0 < cost["wall_seconds"] <= cost["seconds"]
    assert cost["sweeps"] == summary["sweeps"] >= cost["steps"] == summary["steps"] > 0
    meta = load_ensemble(tmp_path).meta["cost"]
    assert meta["runs_timed"] == 1 and meta["seconds_per_run"] == pytest.approx(cost["wall_seconds"])
    assert meta["sweeps_per_run"] == cost["sweeps"] and meta["capped_steps_per_run"] == cost["capped_steps"]


def test_the_ensemble_meta_names_the_piles_history():
    """``history`` of an ensemble's meta: the legs, their own rate and the label the preparation
    study and the report print (fresh piles: [], "fresh")."""
    from tiltpile.analysis.ensemble_data import _describe

    for preset, legs, rate, label in (
            ("default-fresh", [], 0.0, "fresh"),
            ("default", [16.0, -16.0, 16.0, -16.0, 16.0, 0.0], 0.02, "±16° 2 cycles at 10x rate"),
            ("paper", [16.0, -16.0, 16.0, -16.0, 16.0, 0.0], 0.0, "±16° 2 cycles")):
        cfg = config.load(preset).to_dict()
        h = _describe(preset, [0], cfg, "x" * 64, {}, [{}])["history"]
        assert h == {"pretilt_deg": legs, "pretilt_per_step_deg": rate, "label": label}, preset
