"""bench.guard: the cost of an ensemble against how far it moves the figure numbers."""

from __future__ import annotations

import json
import shutil

import numpy as np

from benchmarks import guard


def _ensemble(tmp_path, name, run_path, seconds):
    d = tmp_path / name
    d.mkdir()
    shutil.copy(run_path, d / run_path.name)
    runs = {"1": {"status": "done", "seconds": seconds, "cap_hits": 7}}
    (d / "ensemble.json").write_text(json.dumps({"runs": runs}))
    return d


def test_guard_table_and_chart(smoke_run, tmp_path):
    path, _ = smoke_run
    a = _ensemble(tmp_path, "a", path, 10.0)
    b = _ensemble(tmp_path, "b", path, 4.0)
    out = tmp_path / "out"
    t = guard.main([str(a), str(b), "--out", str(out)])
    assert (out / "guard.csv").exists() and (out / "guard.png").stat().st_size > 10_000
    assert list(t["setting"]) == ["reference", "reference"] and list(t["seconds_median"]) == [10.0, 4.0]
    assert t["cap_hits_mean"].tolist() == [7.0, 7.0]
    from tiltpile.store import open_run

    with open_run(path) as run:
        assert t["sweeps_per_run"].tolist() == [run.cost["sweeps"]] * 2
    assert t["runs_failed"].tolist() == [0, 0]
    # the same run in both: every number equal, shifts zero
    for m in guard.METRICS:
        assert t[f"{m}_mean"][0] == t[f"{m}_mean"][1] or np.isnan(t[f"{m}_mean"][0])
    assert np.isnan(t["z_quiet_shift"][1])  # one run each: no Welch test, no shift claimed
    # the fraction below the marginal line is that of the quiet frames (Fig. 1's test)
    from tiltpile.analysis.ensemble_data import load_ensemble

    f = load_ensemble(a).frames
    q = f[~f["avalanching"].astype(bool)]
    assert t["below_quiet_mean"][0] == (q["z"] - 3 - q["n_m"] < 0).mean()
