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


def test_run_files_record_their_cost_and_the_ensemble_meta_carries_it(tmp_path):
    cfg = config.load("smoke", overrides=["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=2.0"])
    summary = simulate(cfg, 4, tmp_path / "run_0004.h5", progress=False)
    with open_run(tmp_path / "run_0004.h5") as run:
        cost = run.cost
    assert cost["resumed_from_frame"] == -1 and 0 < cost["seconds"] <= summary["seconds"]
    assert cost["sweeps"] == summary["sweeps"] >= cost["steps"] == summary["steps"] > 0
    meta = load_ensemble(tmp_path).meta["cost"]
    assert meta["runs_timed"] == 1 and meta["seconds_per_run"] == pytest.approx(cost["seconds"])
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
