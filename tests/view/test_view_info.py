"""``tiltpile info`` on a run, on an ensemble directory, and on files that are not whole runs."""

from __future__ import annotations

import json
import tomllib

import h5py
import numpy as np
import pytest

from tiltpile import config
from tiltpile.analysis import run_observables
from tiltpile.cli import main
from tiltpile.store import open_run


def test_info_of_a_run(tiny_run, tmp_path, capsys):
    assert main(["info", str(tiny_run), "--quiet"]) == 0
    text = capsys.readouterr().out
    with open_run(tiny_run) as run:
        seed, nf, hash_ = run.seed, run.n_frames, run.config_hash
        n, nfix = run.radius.size, int(run.fixed.sum())
    assert f"seed       {seed}" in text and "complete" in text and "NOT complete" not in text
    assert f"{n} ({n - nfix} mobile, {nfix} fixed bottom)" in text
    assert f"frames     {nf}, theta 0.000 .. 20.000 deg" in text
    assert "deposition steps" in text and "0 warning(s)" in text and "kB" in text
    with open_run(tiny_run) as run:
        cost = run.cost
    assert (f"ended      by theta_max; {cost['steps']} steps, {cost['sweeps']} sweeps, "
            f"{cost['capped_steps']} capped") in text and "prepared" not in text
    assert "wall time  " in text and "summed over the invocations" in text and "partial" not in text
    # first onsets as the observables find them
    frames, _ = run_observables(tiny_run)
    th = frames.loc[frames["onset"], "theta_deg"].to_numpy()
    assert th.size > 0
    assert f"onsets     {th.size} by the 2% lost-contact criterion, first at theta = " \
           + ", ".join(f"{t:.2f}" for t in th[:6]) in text
    # the TOML block reproduces the configuration exactly
    toml = text.split("# configuration")[1].split("\n", 1)[1]
    cfg_file = tmp_path / "again.toml"
    cfg_file.write_text(toml)
    assert tomllib.loads(toml)["scene"]["n"] == 60
    assert config.load("paper", cfg_file).hash() == hash_


def test_info_of_an_ensemble_directory(tiny_ensemble, capsys):
    assert main(["info", str(tiny_ensemble)]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = {ln.split()[0]: ln for ln in lines if ln.startswith("run_")}
    assert set(rows) == {"run_0002.h5", "run_0003.h5", "run_0004.h5.part"}
    assert rows["run_0002.h5"].split()[1:4] == ["2", "70", "41"]
    assert "incomplete" in rows["run_0004.h5.part"]
    assert any(ln.startswith("manifest") and "3 seed(s), 2 done, 1 running" in ln for ln in lines)
    assert any("tiltpile observables" in ln for ln in lines)   # no cache: says how to get onsets


def test_an_interrupted_run_says_where_its_checkpoint_stands(tiny_ensemble, tmp_path, capsys):
    """The line under an incomplete run: its checkpoint's history leg (of the manifest's legs) or
    ramp angle, step, sweeps and wall time so far; nothing without a checkpoint."""
    import json
    import shutil

    d = tmp_path / "ens"
    shutil.copytree(tiny_ensemble, d)
    man = json.loads((d / "ensemble.json").read_text())
    man["config"]["protocol"]["pretilt_deg"] = [16.0, -16.0, 0.0]
    (d / "ensemble.json").write_text(json.dumps(man))
    rate = man["config"]["protocol"]["tilt_per_step_deg"]

    def lines_after_part(scalars, wall=None):
        with h5py.File(d / "run_0004.h5.ckpt", "w") as g:
            g.attrs["scalars"] = json.dumps(scalars)
            if wall is not None:
                g.attrs["wall_seconds"] = wall
        assert main(["info", str(d)]) == 0
        lines = capsys.readouterr().out.splitlines()
        k = next(i for i, ln in enumerate(lines) if ln.startswith("run_0004.h5.part"))
        return lines[k + 1]

    line = lines_after_part({"phase": "pretilt", "leg": 1, "step": 1200, "sweeps": 3_400_000},
                            wall=5400.0)
    assert "checkpoint " in line and ": history leg 2 of 3, step 1200, 3.4 M sweeps, 1.5 h so far" in line
    line = lines_after_part({"phase": "tilt", "tilt_step": 500, "step": 9000, "sweeps": 12_000_000})
    assert f": ramp at {500 * rate:.2f} deg, step 9000, 12.0 M sweeps" in line and "so far" not in line
    (d / "run_0004.h5.ckpt").unlink()
    assert main(["info", str(d)]) == 0
    assert "checkpoint" not in capsys.readouterr().out


def test_an_ensemble_says_what_its_runs_cost_and_what_is_left(tiny_ensemble, capsys):
    """Below the manifest: the finished runs' sweeps and wall time per run and core-hours, then
    the runs left at that median, the running ones less their checkpoints' time so far, and the
    wall time on the last invocation's workers."""
    from tiltpile.view.info.ensemble import cost_lines

    assert main(["info", str(tiny_ensemble)]) == 0
    out = capsys.readouterr().out
    assert "  cost     2 finished: " in out and "(median of 2 timed whole)" in out
    assert "  left     1 run(s) (0 pending, 1 running)" in out
    assert "  to go    run_0004.h5 ? (at its pace so far)" in out
    whole = {"sweeps": 90e6, "seconds": 7200.0, "resumed_from_frame": -1}
    resumed = {"sweeps": 100e6, "seconds": 60.0, "resumed_from_frame": 400}
    lines = cost_lines([whole, dict(whole, seconds=9000.0), resumed], 4, [3600.0, None], 2)
    assert lines[0] == ("  cost     3 finished: 93.3 M sweeps per run (mean), 2 h 15 min per run "
                        "(median of 2 timed whole), ~6.75 core-hours (median x 3)")
    # 6 runs at 2.25 h, less the 1 h one running run has spent: 12.5 core-hours, 6.25 h on 2
    assert lines[1] == ("  left     6 run(s) (4 pending, 2 running): ~12.5 core-hours at that "
                        "median, ~6.25 h on 2 worker(s)")
    assert cost_lines([whole, dict(whole, seconds=9000.0)], 0, [3600.0, None], 2,
                      ["run_0012.h5", "run_0013.h5"])[2] == (
        "  to go    run_0012.h5 ~1.2 h, run_0013.h5 ? (at its pace so far)")
    # with its sweeps: the mean's 90 M less its 30 M, at its 30 M per hour (slower than the
    # finished runs' 45 M per hour): 2 h to go, not the median's 1.25 h
    assert cost_lines([whole, dict(whole, seconds=9000.0)], 0, [3600.0], 2, ["run_0012.h5"],
                      [30e6])[2] == (
        "  to go    run_0012.h5 ~2.0 h (33% of the mean sweeps done) (at its pace so far)")
    assert cost_lines([resumed], 3, [], None) == [
        "  cost     1 finished: 100.0 M sweeps per run (mean), wall time not recorded whole "
        "(resumed runs)"]
    assert cost_lines([whole], 0, [], 2) == [
        "  cost     1 finished: 90.0 M sweeps per run (mean), 2 h 00 min per run "
        "(median of 1 timed whole), ~2 core-hours (median x 1)"]
    assert cost_lines([], 5, [], 2) == []
    # a cluster's ensemble: 500 runs at 2 h 15 min are ~1125 core-hours, not '1.12e+03'
    assert cost_lines([dict(whole, seconds=8100.0)] * 500, 0, [], 2)[0].endswith(
        "~1125 core-hours (median x 500)")


def _foreign_h5(path):
    with h5py.File(path, "w") as f:
        f["x"] = np.arange(3)


def _truncated(src, path):
    path.write_bytes(src.read_bytes()[:50_000])


def _damaged(src, path):
    path.write_bytes(src.read_bytes())
    with h5py.File(path, "r+") as f:
        del f["particles/radius"]


@pytest.mark.parametrize("kind, message", [
    ("truncated", "not a readable HDF5 file"), ("foreign", "not a tiltpile run file"),
    ("text", "not a readable HDF5 file"), ("damaged", "radius"),
    ("missing", "no such run file"),
])
def test_info_on_broken_files_names_them(tiny_run, tmp_path, capsys, kind, message):
    path = tmp_path / f"{kind}.h5"
    if kind == "truncated":
        _truncated(tiny_run, path)
    elif kind == "foreign":
        _foreign_h5(path)
    elif kind == "text":
        path.write_text("not a run\n")
    elif kind == "damaged":
        _damaged(tiny_run, path)
    assert main(["info", str(path), "--quiet"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err
    assert err.startswith(f"tiltpile info: error: {path}") and message in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_info_on_a_part_file_and_a_bad_run_in_a_directory(tiny_run, tmp_path, capsys):
    part = tmp_path / "run_0001.h5.part"
    part.write_bytes(b"x" * 10)
    assert main(["info", str(part)]) == 2
    assert "an incomplete run" in capsys.readouterr().err
    _truncated(tiny_run, tmp_path / "run_0005.h5")
    assert main(["info", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "run_0005.h5" in out and "unreadable: not a readable HDF5 file" in out
    assert "manifest   none" in out


def test_ensemble_onsets_come_from_the_observables_cache(tiny_ensemble, tmp_path, capsys):
    import shutil

    from tiltpile.analysis import compute_observables, load_observables

    ens = tmp_path / "ens"
    shutil.copytree(tiny_ensemble, ens)
    compute_observables(ens, workers=1, progress=False)
    frames, _ = load_observables(ens, compute_missing=False)
    assert main(["info", str(ens)]) == 0
    rows = {ln.split()[0]: ln.split() for ln in capsys.readouterr().out.splitlines()
            if ln.startswith("run_") and ".part" not in ln}
    for seed, g in frames.groupby("run"):
        on = g["onset"].to_numpy(bool)
        row = rows[f"run_{seed:04d}.h5"]
        assert int(row[5]) == on.sum()
        assert row[6] == (f"{g['theta_deg'].to_numpy()[on][0]:.2f}" if on.any() else "-")


def test_info_of_a_prepared_run_that_ended_in_its_slide(tmp_path, capsys):
    from tiltpile.runner import simulate

    cfg = config.load("smoke", overrides=["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=40.0",
                                          "protocol.pretilt_deg=[2.0, 0.0]", "protocol.end_ke=1e-4",
                                          "protocol.end_span_deg=0.5"])
    simulate(cfg, 1, tmp_path / "r.h5", progress=False)
    assert main(["info", str(tmp_path / "r.h5"), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "prepared   tilted to +2 deg (200 + " in text and ", +0 deg (200 + " in text
    assert "ended      by the slide (protocol.end_ke); " in text


def test_info_into_a_closed_pipe_is_quiet(tiny_run):
    """`tiltpile info RUN | head -1`: the reader goes away; no error line, exit status 0."""
    import subprocess
    import sys

    p = subprocess.run(f"{sys.executable} -m tiltpile info {tiny_run} --quiet | head -c 10",
                       shell=True, capture_output=True, text=True, executable="/bin/bash",
                       env={"PATH": "/usr/bin:/bin", "PYTHONUNBUFFERED": "1",
                            "NUMBA_CACHE_DIR": __import__("os").environ.get("NUMBA_CACHE_DIR", "")})
    assert p.stdout == "run file  " and p.stderr == ""


def test_durations_read_as_hours_minutes_or_seconds():
    from tiltpile.view.info.common import duration

    assert duration(12.34) == "12.3 s"
    assert duration(185) == "3 min 05 s"
    assert duration(3 * 3600 + 2 * 60 + 59) == "3 h 02 min"


def test_an_ensemble_counts_the_recorded_runs_whose_files_are_gone(tiny_ensemble, tmp_path,
                                                                   capsys):
    """--records: the runs recorded whose run files are not in the directory (lost with a disk,
    the ensemble restarted with --skip-recorded) count as finished in the cost and what is
    left; a run file that is here is not counted twice; records of another configuration, or no
    records, are refused in one line."""
    import shutil

    from tiltpile.figures.records import write_record_of

    d = tmp_path / "ens"
    shutil.copytree(tiny_ensemble, d)
    rec = tmp_path / "records"
    for s in (2, 3):
        write_record_of(d / f"run_{s:04d}.h5", rec)
    assert main(["info", str(d), "--quiet", "--records", str(rec)]) == 0
    assert "to record" not in capsys.readouterr().out
    (rec / "run_0003.npz").unlink()
    assert main(["info", str(d), "--quiet", "--records", str(rec)]) == 0
    assert (f"  to record run_0003.h5: finished, with no up-to-date record in {rec} (tiltpile "
            f"record {d} --out {rec}, then commit it)") in capsys.readouterr().out
    write_record_of(d / "run_0003.h5", rec)
    (d / "run_0002.h5").unlink()
    assert main(["info", str(d), "--quiet"]) == 0
    assert "  cost     1 finished: " in capsys.readouterr().out
    assert main(["info", str(d), "--quiet", "--records", str(rec)]) == 0
    out = capsys.readouterr().out
    assert (f"  records  {rec}: 1 finished run(s) recorded whose run file is not here (seeds 2)"
            in out)
    assert "  cost     2 finished: " in out and "(median of 2 timed whole)" in out
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["info", str(d), "--records", str(empty)]) == 2
    assert "no records (run_*.npz) there" in capsys.readouterr().err
    man = json.loads((d / "ensemble.json").read_text())
    (d / "ensemble.json").write_text(json.dumps(dict(man, config_hash="f" * 64)))
    assert main(["info", str(d), "--records", str(rec)]) == 2
    err = capsys.readouterr().err
    assert "is a record of another configuration" in err and len(err.strip().splitlines()) == 1
    assert main(["info", str(d / "run_0003.h5"), "--records", str(rec)]) == 2
    assert "is not an ensemble directory" in capsys.readouterr().err


def test_info_of_records_and_of_a_record(tiny_ensemble, tmp_path, capsys):
    """A directory of records (the committed figures/paper/records/) and one record: what the run
    recorded, from the record alone: one line per record with its onsets as the recorded frame
    table has them, the cost of the recorded runs; for one record also how it ended, its health
    warnings, the run file it came from and its configuration as TOML (the run's hash)."""
    from tiltpile.figures.records import write_record_of
    from tiltpile.record import read_record

    rec = tmp_path / "records"
    for s in (2, 3):
        write_record_of(tiny_ensemble / f"run_{s:04d}.h5", rec)
    assert main(["info", str(rec)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"records    {rec}  (2 record(s), config hash ")
    for s in (2, 3):
        f = read_record(rec / f"run_{s:04d}.npz").frames
        th = f["theta_deg"].to_numpy(float)[f["onset"].to_numpy(bool)]
        line = next(x for x in out.splitlines() if x.startswith(f"run_{s:04d}.npz"))
        assert line.split()[1] == str(s) and line.split()[6] == str(th.size), line
    assert "  cost     2 finished: " in out
    assert main(["info", str(rec / "run_0003.npz")]) == 0
    out = capsys.readouterr().out
    with open_run(tiny_ensemble / "run_0003.h5") as run:
        hash_, cost, end = run.config_hash, run.cost, run.end_reason
    assert f"seed       3    tiltpile " in out and f"config hash {hash_[:12]}" in out
    assert (f"ended      by {'theta_max' if end != 'slide' else 'the slide (protocol.end_ke)'}"
            in out and f"{cost['steps']} steps, {cost['sweeps']} sweeps" in out)
    assert "from       run_0003.h5 (" in out and "0 warning(s)" in out
    cfg_file = tmp_path / "c.toml"
    cfg_file.write_text(out.split("--out RUN.h5)\n", 1)[1])
    assert config.load("smoke", cfg_file).hash() == hash_
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "run_0000.npz").write_bytes(b"not a record")
    assert main(["info", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip()
    assert "run_0000.npz" in err and len(err.splitlines()) == 1
