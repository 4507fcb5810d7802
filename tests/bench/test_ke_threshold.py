"""bench.ke_threshold: Fig. 2a's threshold as runs are added and with one run left out."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from tiltpile.analysis.stats import ke_threshold
from tiltpile.bench import ke_threshold as kt


def _frames(flow_deg, rng, quiet_top=None) -> pd.DataFrame:
    """Runs of 400 frames 0.05 deg apart. Quiet frames: energy log-uniform on [1e-9, quiet_top]
    (a density falling as 1/x; quiet_top per run, default 1e-6). From the run's flow_deg on:
    log-uniform on [1e-3, 1e-2], far above, with nothing between (a gap)."""
    out = []
    for seed, start in enumerate(flow_deg):
        top = -6.0 if quiet_top is None else np.log10(quiet_top[seed])
        theta = 0.05 * np.arange(400)
        flowing = theta >= start - 1e-9
        ke = np.where(flowing, 10 ** rng.uniform(-3, -2, theta.size), 10 ** rng.uniform(-9, top, theta.size))
        out.append(pd.DataFrame({"run": seed, "frame": np.arange(400), "theta_deg": theta,
                                 "ke_trans": ke, "avalanching": flowing}))
    return pd.concat(out, ignore_index=True)


def test_a_threshold_at_a_gap_does_not_move():
    """Known answer: where the quiet power law ends in a gap, the threshold is its end (1e-6: an
    empty bin departs from the fit) whichever runs make the ensemble, and each run's first
    sustained flow above it is where its flow starts."""
    starts = [15.0, 16.5, 14.25, 18.0, 17.5, 15.75]
    frames = _frames(starts, np.random.default_rng(0))
    out = kt.stability(frames, list(range(6)), every=4)
    assert [len(r["seeds"]) for r in out["cumulative"]] == [4, 6]
    for r in out["cumulative"]:
        assert r["threshold"] == pytest.approx(1e-6)
        assert np.allclose(r["flow"], starts[:len(r["seeds"])])
    assert sorted(out["left_out"]) == list(range(6))
    assert np.allclose(list(out["left_out"].values()), 1e-6)


def test_rows_are_fig2a_thresholds_of_those_runs():
    """Each row is ke_threshold of exactly its runs, and each left-out value that of all runs but
    one: the runs' quiet power laws end at different energies, so the sets differ in threshold."""
    tops = [1e-6, 1e-5, 1e-4, 1e-7, 1e-6]
    frames = _frames([15.0, 16.0, 17.0, 18.0, 19.0], np.random.default_rng(1), tops)
    seeds = [0, 1, 2, 3, 4]
    out = kt.stability(frames, seeds, every=2)
    assert [r["seeds"] for r in out["cumulative"]] == [[0, 1], [0, 1, 2, 3], seeds]

    def direct(runs):
        return ke_threshold(frames[frames["run"].isin(runs)])[0]["threshold"]

    for r in out["cumulative"]:
        assert r["threshold"] == direct(r["seeds"])
    for s, t in out["left_out"].items():
        assert t == direct([x for x in seeds if x != s])
    assert len({r["threshold"] for r in out["cumulative"]} | set(out["left_out"].values())) > 1


def test_every_must_be_positive():
    with pytest.raises(ValueError, match="--every must be >= 1"):
        kt.stability(_frames([15.0], np.random.default_rng(2)), [0], every=0)


def test_main_on_a_run_directory_and_a_missing_one(smoke_run, tmp_path, capsys):
    """The command reads run files when there are no records, prints one row per cumulative set
    and the leave-one-out line only with two runs or more; a missing directory is one line."""
    path, _ = smoke_run
    d = tmp_path / "ens"
    d.mkdir()
    shutil.copy(path, d / path.name)
    out = kt.main([str(d)])
    text = capsys.readouterr().out
    assert "1 runs" in text and "one run left out" not in text
    assert len(out["cumulative"]) == 1 and out["left_out"] == {}
    with pytest.raises(SystemExit) as e:
        kt.main([str(tmp_path / "nowhere")])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("ke_threshold:") and "no such directory" in err and "\n" not in err
