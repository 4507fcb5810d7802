"""perf.flow_caps: the cap study rebuilds a run's frame and compares settings from one state."""

from __future__ import annotations

import numpy as np
import pytest

from tiltpile.bench import flow_caps
from tiltpile.store import open_run


def test_flow_caps_from_a_frame_of_the_smoke_run(smoke_run, capsys):
    """Frame 110 (11 deg, the smoke pile of seed 1 rearranging): the rebuilt state sits at the
    frame's angle; a setting repeated gives the same numbers bit for bit (every variant starts
    from the same state), the first row is the reference, and a starved solve leaves a larger
    natural residual (measured: 6.3e-6 converged to the smoke tol, 1.7e-5 at 3 sweeps a step; the
    warm start from the previous step keeps even 1 sweep at 2.2e-5 over 5 steps)."""
    path, _ = smoke_run
    rows = flow_caps.main([str(path), "110", "5", "--warm", "2", "20000", "20000", "3"])
    out = capsys.readouterr().out
    assert "theta 11.00 deg" in out and len(rows) == 3
    ref, again, starved = rows
    assert ref["disp_change"] == 0.0 and ref["pos_distance"] == 0.0
    assert again["disp"] == ref["disp"] and again["pos_distance"] == 0.0
    assert again["natural_residual"] == ref["natural_residual"]
    assert starved["natural_residual"] > 2 * ref["natural_residual"]
    assert np.isfinite(starved["disp_change"]) and starved["pos_distance"] > 0.0
    with open_run(path) as r:
        assert r.theta_deg[110] == pytest.approx(11.0)


def test_flow_caps_refuses_bad_arguments(smoke_run):
    path, _ = smoke_run
    with pytest.raises(SystemExit):
        flow_caps.main([str(path), "110", "0"])


def test_one_step_profile_on_the_smoke_run(smoke_run, capsys):
    """--one-step from frame 110: the largest cap is the reference; a cap the step does not
    reach (it converges to the smoke tol first) gives the reference bit for bit; a starved step
    (2 sweeps) ends farther from it in velocities and impulses."""
    path, _ = smoke_run
    rows = flow_caps.main([str(path), "110", "--one-step", "--warm", "2", "2", "20000", "5000"])
    out = capsys.readouterr().out
    assert "one step per max_iter" in out
    assert [r["max_iter"] for r in rows] == [20000, 5000, 2]  # sorted, largest first
    ref, unreached, starved = rows
    assert ref["sweeps"] < 5000  # converged to tol: both larger caps make the same step
    assert unreached["sweeps"] == ref["sweeps"]
    for k in ("dv_rel", "dx_max", "dp_rel", "status_changed"):
        assert ref[k] == 0 and unreached[k] == 0
    assert starved["sweeps"] == 2
    assert starved["dv_rel"] > 0 and starved["dp_rel"] > 0
    assert starved["natural_residual"] > ref["natural_residual"]


def test_one_step_refuses_a_single_cap(smoke_run):
    path, _ = smoke_run
    with pytest.raises(SystemExit):
        flow_caps.main([str(path), "110", "--one-step", "1000"])
    with pytest.raises(SystemExit):
        flow_caps.main([str(path), "110", "--one-step", "1000", "0"])
