"""The speed x accuracy chart (``python -m benchmarks.chart``, ``make bench``) in its quick mode on a tiny pile.

No timing assertions: only the files, their columns, and facts that must hold whatever the machine.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from benchmarks.chart import (ACCURACY_COLUMNS, DEFAULT_DT, DEFAULT_SLOP, DEFAULT_TOL,
                                  SCALING_COLUMNS, ChartSpec, grid_points, pareto_front, run_chart,
                                  tile)


@pytest.fixture(scope="module")
def chart(tmp_path_factory):
    out = tmp_path_factory.mktemp("perf")
    summary = run_chart(out, ChartSpec.quick_spec(), progress=False, command="test")
    return out, summary


def test_files_written(chart):
    out, summary = chart
    for name in ("accuracy.csv", "scaling.csv", "pareto.png", "scaling.png", "summary.json"):
        assert (out / name).stat().st_size > 0, name
        assert name in summary["files"]
    assert not list(out.glob(".*tmp*")), "temporary files left behind"
    s = json.loads((out / "summary.json").read_text())
    for key in ("cpu_count", "platform", "numba"):
        assert key in s["machine"]
    assert s["command"] == "test" and s["date"]
    assert (out / "pareto.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_accuracy_table(chart):
    out, _ = chart
    acc = pd.read_csv(out / "accuracy.csv")
    assert list(acc.columns) == ACCURACY_COLUMNS
    spec = ChartSpec.quick_spec()
    assert len(acc) == len(spec.seeds) * len(grid_points(spec))
    assert acc["is_reference"].sum() == len(spec.seeds)
    assert acc["is_default"].sum() == len(spec.seeds)
    ref = acc[acc["is_reference"]]
    assert np.all(ref[["z_shift", "n_m_shift"]].to_numpy() == 0)
    for dt, d in acc[acc["slop"] == DEFAULT_SLOP].groupby("dt"):
        d = d.set_index("tol")
        loose, tight = d.loc[1e-2], d.loc[1e-6]
        # a tighter tolerance leaves a smaller residual ... (not always at more sweeps per step:
        # a loose solve can set the pile moving, and a moving pile costs more sweeps per step than
        # a quiet one; measured at dt 0.02, seed 3: 18.9, 13.8, 7.7 sweeps at tol 1e-2, 1e-4, 1e-6)
        assert tight["residual_median"] < loose["residual_median"]
        assert tight["residual_median"] <= 1e-6 * 1.0001 or tight["cap_hit_fraction"] > 0
        # ... and the pile held at a fixed angle creeps less
        assert loose["creep_mean"] > tight["creep_mean"]
    assert np.all(acc["max_overlap"] >= 0) and np.all(acc["steps"] > 0)
    assert np.all(acc["ms_per_deg"] > 0)
    assert np.all(acc["drift_per_deg"] >= 0)
    # the overlap slop, varied alone at the default tol and dt: the plain gap term (slop 0)
    # re-injects the solver's error every step, so it takes more sweeps than the default slop
    # (sim/step.py, "Overlap slop")
    at = acc[(acc["tol"] == DEFAULT_TOL) & (acc["dt"] == DEFAULT_DT)].set_index("slop")
    assert at.loc[0.0, "sweeps_mean"] > at.loc[DEFAULT_SLOP, "sweeps_mean"]


def test_scaling_table(chart):
    out, summary = chart
    sc = pd.read_csv(out / "scaling.csv")
    assert list(sc.columns) == SCALING_COLUMNS
    spec = ChartSpec.quick_spec()
    fixed = sc[sc["fixed_sweeps"] > 0]
    # tol 0 never converges: every timed step makes exactly fixed_sweeps sweeps
    assert sorted(fixed["n"]) == [spec.base_n * k for k in spec.copies]
    assert np.all(fixed["sweeps_mean"] == spec.fixed_sweeps) and np.all(fixed["cap_hits"] == fixed["steps"])
    assert np.all(fixed["steps"] == spec.fixed_steps * spec.fixed_rounds)
    assert summary["scaling_fit"]["fixed_sweeps"]["sweeps"] == spec.fixed_sweeps
    sc = sc[sc["fixed_sweeps"] == 0]
    # the default sweep (interleaved) at every N, the other sweeps at the variant N
    assert summary["scaling_fit"]["sweep"] == "interleaved" and set(fixed["sweep"]) == {"interleaved"}
    fwd = sc[(sc["sweep"] == "interleaved") & (sc["relax"] == 1.0) & (sc["slop"] > 0)]
    assert sorted(fwd["n"]) == [spec.base_n * k for k in spec.copies]
    assert {("random", 1.0, 0.0), ("forward", 1.0, 1e-6), ("forward", 1.0, 0.0), ("forward", 1.5, 1e-6)} <= set(
        zip(sc["sweep"], sc["relax"], sc["slop"]))
    # contacts grow with the width of the pile, the box is k times wider
    fwd = fwd.sort_values("n")
    assert np.all(np.diff(fwd["contacts"]) > 0)
    assert np.allclose(fwd["box_length"] / fwd["copies"], fwd["box_length"].iloc[0])
    assert np.all(sc["ns_per_update"] > 0)
    assert "loglog_slope" in summary["scaling_fit"]


def test_tile_keeps_grains_and_ordering(chart):
    from tiltpile import config
    from tiltpile.sim import protocol

    cfg = config.load("smoke", None, ["scene.n=20", "scene.box_length=6.0"])
    s = protocol.make_system(cfg, 0)
    s.params.update(slop=3e-6, relax=1.3)  # not the defaults: the tiled pile must keep them
    t = tile(s, 3)
    assert t.n == 3 * s.n and t.params["box_length"] == 3 * s.params["box_length"]
    assert dict(t.params, box_length=None) == dict(s.params, box_length=None)
    assert t.fixed.sum() == 3 * s.fixed.sum()
    # copy m of grain i is grain 3 i + m, shifted by m L
    assert np.allclose(t.pos[3 * 5 + 2], s.pos[5] + [2 * 6.0, 0.0])
    assert np.all(t.pos[:, 0] < t.params["box_length"] + 1)


def test_grid_points():
    full = ChartSpec.full()
    pts = grid_points(full)  # cross: each of tol, dt, slop varied alone, the others at the default
    assert len(pts) == len(full.tols) + len(full.dts) + len(full.slops) - 2
    assert (DEFAULT_TOL, DEFAULT_DT, DEFAULT_SLOP) in pts
    assert (1e-6, 0.005, DEFAULT_SLOP) in pts and (1e-2, 0.01, DEFAULT_SLOP) in pts
    assert (1e-6, 0.01, 0.0) in pts
    assert (1e-2, 0.02, DEFAULT_SLOP) not in pts and (1e-6, 0.005, 0.0) not in pts
    from dataclasses import replace
    assert len(grid_points(replace(full, grid="full"))) == (
        len(full.tols) * len(full.dts) * len(full.slops))


def test_pareto_front():
    x = np.array([1.0, 2.0, 3.0, 0.5, np.nan])
    y = np.array([5.0, 1.0, 0.5, 9.0, 0.1])
    assert list(pareto_front(x, y)) == [3, 0, 1, 2]
    assert list(pareto_front([1, 2], [1, 2])) == [0]


def test_chart_command_rejects_an_unknown_part_before_writing(tmp_path, capsys):
    import benchmarks.chart as chart

    with pytest.raises(SystemExit) as exc:
        chart.main([str(tmp_path / "out"), "--quick", "--parts", "accuracy,bogus"])
    assert exc.value.code == 2 and "unknown part(s) ['bogus']" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_scaling_part_with_an_old_accuracy_table(tmp_path, monkeypatch):
    """--parts scaling summarises an accuracy.csv already in the directory; one written before a
    column existed is not summarised (a warning names the missing column) and the scaling part
    still runs."""
    import benchmarks.chart as chart
    from benchmarks.chart import plots, scaling

    monkeypatch.setattr(scaling, "scaling_sweep", lambda spec, progress: pd.DataFrame())
    monkeypatch.setattr(scaling, "scaling_fit", lambda sc: {})
    monkeypatch.setattr(plots, "plot_scaling", lambda *a, **k: None)
    monkeypatch.setattr(chart, "atomic_csv", lambda df, path: None)
    old = pd.DataFrame({c: [1.0] for c in ACCURACY_COLUMNS if c not in ("slop", "drift_per_deg")})
    old.to_csv(tmp_path / "accuracy.csv", index=False)
    with pytest.warns(UserWarning, match="lacks the column.s. slop, drift_per_deg"):
        summary = run_chart(tmp_path, ChartSpec.quick_spec(), progress=False, parts=("scaling",))
    assert "accuracy_points" not in summary and "accuracy_from_file" not in summary
    assert "scaling_fit" in summary


def test_the_committed_accuracy_table_is_read_back():
    """figures/performance/accuracy.csv (make bench) has every column the plots read."""
    from pathlib import Path

    from benchmarks.chart import read_accuracy

    path = Path(__file__).resolve().parents[2] / "figures" / "performance" / "accuracy.csv"
    acc = read_accuracy(path)
    assert acc is not None and list(acc.columns) == ACCURACY_COLUMNS and len(acc) > 0
