"""The ensemble runner: LocalCluster and external scheduler, skip, retry, kill and resume, refusals.

Runs use the smoke preset shrunk to 60 grains in a 10 d box (about two seconds each) so the
whole file stays well under a minute on two cores.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

from simhelpers import assert_same_run
from tiltpile import config
from tiltpile.config import ConfigError
from tiltpile.cli import main as _tiltpile_main
from tiltpile.cli.ensemble import add_parser
from tiltpile.cli.ensemble import run as cmd_ensemble
from tiltpile.ensemble import MANIFEST, run_ensemble, run_file
from tiltpile.runner import simulate
from tiltpile.store import checkpoint_path, open_run, part_path

SMALL = ["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=2.0"]
# a frame every step and a checkpoint every 5 frames: about 2 s of tilt to be killed in
KILLABLE = ["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=2.0", "protocol.frame_every=2",
            "protocol.checkpoint_every=5"]
BIN = Path(sys.executable).parent


def main(argv):
    """The ``tiltpile ensemble`` command."""
    return _tiltpile_main(["ensemble", *argv])


def _cli(out, *extra, overrides=SMALL):
    args = ["--preset", "smoke"]
    for o in overrides:
        args += ["--set", o]
    return args + ["--out", str(out), *extra]


def _snapshot(d: Path) -> dict:
    """Every file under d (hidden ones too): (mtime_ns, sha256)."""
    return {str(p.relative_to(d)): (p.stat().st_mtime_ns, hashlib.sha256(p.read_bytes()).hexdigest())
            for p in sorted(d.rglob("*")) if p.is_file()}


def _manifest(d: Path) -> dict:
    return json.loads((d / MANIFEST).read_text())


@pytest.fixture(scope="module")
def small_config():
    return config.load("smoke", overrides=SMALL)


@pytest.fixture(scope="module")
def local_ensemble(tmp_path_factory, small_config):
    """Seeds 0 and 1 through a LocalCluster of two workers, done once for the module."""
    out = tmp_path_factory.mktemp("ens") / "local"
    t0 = time.perf_counter()
    manifest = run_ensemble(small_config, [0, 1], out, workers=2, progress=False)
    return out, manifest, time.perf_counter() - t0


def test_local_cluster_two_runs_then_skip(local_ensemble, small_config):
    out, manifest, _ = local_ensemble
    assert manifest == _manifest(out)
    assert manifest["config_hash"] == small_config.hash()
    assert config.from_json(json.dumps(manifest["config"])) == small_config
    assert manifest["seeds"] == [0, 1] and manifest["tiltpile_version"]
    assert manifest["invocations"][-1]["engine"] == "LocalCluster(2 workers)"
    workers = set()
    for seed in (0, 1):
        r = manifest["runs"][str(seed)]
        assert r["status"] == "done" and r["error"] is None and r["attempts"] == 1
        assert r["seconds"] > 0 and r["started"] <= r["finished"]
        assert r["numba_cache_misses"] == 0, "a worker recompiled the kernels"
        workers.add(r["worker"])
        path = run_file(out, seed)
        assert path.exists() and not part_path(path).exists()
        with open_run(path) as run:
            assert run.seed == seed and run.config_hash == small_config.hash()
    assert len(workers) == 2, "the two runs did not go to the two workers"
    assert sorted(p.name for p in out.glob("run_*")) == ["run_0000.h5", "run_0001.h5"]

    before = _snapshot(out)
    t0 = time.perf_counter()
    again = run_ensemble(small_config, [0, 1], out, workers=2, progress=False)
    assert time.perf_counter() - t0 < 2.0, "finished runs were not skipped"
    assert again["runs"] == manifest["runs"]
    assert _snapshot(out) == before


@pytest.fixture
def dask_cluster(tmp_path):
    """`dask scheduler` and one `dask worker` on loopback, started and stopped here."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    procs = []
    try:
        for cmd in ([str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                     "--no-dashboard"],
                    [str(BIN / "dask"), "worker", address, "--nthreads", "1", "--nworkers", "1",
                     "--no-dashboard", "--host", "127.0.0.1", "--local-directory", str(tmp_path / "dask")]):
            procs.append(subprocess.Popen(cmd, env=env, cwd=tmp_path, start_new_session=True,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout="30s") as c:
            c.wait_for_workers(1, timeout=60)
        yield address
    finally:
        for p in reversed(procs):
            _stop_group(p, signal.SIGTERM)


def _stop_group(p: subprocess.Popen, sig) -> None:
    try:
        os.killpg(p.pid, sig)
        p.wait(timeout=15)
    except ProcessLookupError:
        pass
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait(timeout=15)


def test_external_scheduler_records_a_failure_and_retries_it(dask_cluster, tmp_path, small_config, capsys):
    out = tmp_path / "ext"
    out.mkdir()
    blocker = part_path(run_file(out, 4))
    blocker.mkdir()  # seed 4 cannot write its run file: it fails, seed 3 goes on
    args = _cli(out, "--runs", "2", "--first-seed", "3", "--scheduler", dask_cluster, "--quiet")
    assert main(args) == 1
    m = _manifest(out)
    assert m["invocations"][-1]["engine"] == dask_cluster
    assert m["runs"]["3"]["status"] == "done" and run_file(out, 3).exists()
    assert m["runs"]["3"]["numba_cache_misses"] == 0
    assert m["runs"]["4"]["status"] == "failed" and m["runs"]["4"]["error"]
    assert not run_file(out, 4).exists()
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["failed"] == [4] and summary["done"] == 1

    blocker.rmdir()
    done3 = _snapshot(out)["run_0003.h5"]
    assert main(args) == 0
    m = _manifest(out)
    assert m["runs"]["4"]["status"] == "done" and m["runs"]["4"]["error"] is None
    assert m["runs"]["4"]["attempts"] == 2 and m["runs"]["3"]["attempts"] == 1
    assert _snapshot(out)["run_0003.h5"] == done3, "a finished run was redone"
    with open_run(run_file(out, 4)) as run:
        assert run.seed == 4 and run.config_hash == small_config.hash()


def _checkpointed_part(out: Path, min_frames: int) -> bool:
    """True when some .part file has a checkpoint past ``min_frames`` frames (read without locking
    while the writer runs: the checkpoint is replaced atomically). The kill then lands wherever
    that run is: appending a frame, checkpointing, or building its run file."""
    for part in out.glob("run_*.h5.part"):
        try:
            with h5py.File(checkpoint_path(part.with_suffix("")), "r", locking=False) as g:
                if int(g.attrs["n_frames"]) >= min_frames:
                    return True
        except Exception:
            pass
    return False


def _resumable(out: Path) -> dict[str, int]:
    """{seed: frames of its checkpoint} for the .part files that can be reopened after the kill."""
    found = {}
    for part in sorted(out.glob("run_*.h5.part")):
        try:
            with h5py.File(checkpoint_path(part.with_suffix("")), "r") as g:
                found[str(int(g.attrs["seed"]))] = int(g.attrs["n_frames"])
        except OSError:  # killed before its first checkpoint: the run starts afresh
            pass
    return found


def test_sigkill_then_rerun_is_bit_identical(tmp_path):
    cfg = config.load("smoke", overrides=KILLABLE)
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "tiltpile", "ensemble", *_cli(out, "--runs", "2", "--workers", "2", "--quiet",
                                                            overrides=KILLABLE)]
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 90
        while not _checkpointed_part(out, 41):
            assert proc.poll() is None, f"ensemble ended before it could be killed: {proc.stderr.read()!r}"
            assert time.monotonic() < deadline, "no checkpoint appeared"
            time.sleep(0.02)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        proc.stderr.close()
    deadline = time.monotonic() + 30
    while True:  # the whole group (workers included) is gone before the rerun
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        assert time.monotonic() < deadline, "workers outlived the killed ensemble"
        time.sleep(0.05)
    resumable = _resumable(out)
    assert resumable, "no interrupted run file with a checkpoint survived the kill"
    assert _manifest(out)["runs"]["0"]["status"] in ("pending", "running", "done")

    m = run_ensemble(cfg, [0, 1], out, workers=2, progress=False)
    assert [m["runs"][s]["status"] for s in ("0", "1")] == ["done", "done"]
    assert not list(out.glob("*.part")) and not list(out.glob("*.ckpt"))
    # Every run with a checkpoint resumes from it, wherever the kill caught it: the run the kill
    # was timed on had just checkpointed, the other one was at a random point of its own (before
    # the frame log, a kill inside an HDF5 write of the .part left it unreadable: 1 of ~120 runs
    # of this test on a loaded 2-core machine started afresh).
    for seed, k in resumable.items():
        r = m["runs"][seed]
        assert r["resumed_from_frame"] == k and r["discarded"] is None, (seed, r)

    ref = tmp_path / "reference"
    for seed in (0, 1):
        simulate(cfg, seed, run_file(ref, seed), progress=False, resume=False)
        assert_same_run(run_file(out, seed), run_file(ref, seed))


def test_config_mismatch_is_refused_and_touches_nothing(local_ensemble, tmp_path, capsys):
    src, _, _ = local_ensemble
    out = tmp_path / "copy"
    shutil.copytree(src, out)
    before = _snapshot(out)
    other = config.load("smoke", overrides=SMALL + ["solver.tol=1e-6"])
    with pytest.raises(ConfigError, match="another configuration"):
        run_ensemble(other, [0, 1], out, workers=2, progress=False)
    assert main(_cli(out, "--runs", "3", "--workers", "2", overrides=SMALL + ["solver.tol=1e-6"])) == 2
    assert "another configuration" in capsys.readouterr().err
    assert _snapshot(out) == before
    # without its manifest, the run files still identify the configuration
    (out / MANIFEST).unlink()
    before = _snapshot(out)
    with pytest.raises(ConfigError, match="run of another configuration"):
        run_ensemble(other, [5], out, progress=False)
    assert _snapshot(out) == before


def test_bad_input_fails_clearly_and_writes_nothing(tmp_path, small_config, capsys):
    out = tmp_path / "never"
    assert main(_cli(out, "--runs", "0")) == 2
    assert "--runs must be at least 1" in capsys.readouterr().err
    assert main(_cli(out, "--runs", "2", "--workers", "0")) == 2
    assert main(_cli(out, "--runs", "2", "--set", "scene.n=-3")) == 2
    assert "scene.n" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(_cli(out, "--runs", "2", "--first-seed", "-1"))
    assert e.value.code == 2
    assert "non-negative" in capsys.readouterr().err
    for seeds, match in (([], "no runs"), ([-1], "negative"), ([1.5], "not an integer"), ([2, 2], "repeat")):
        with pytest.raises(ConfigError, match=match):
            run_ensemble(small_config, seeds, out, progress=False)
    with pytest.raises(ConfigError, match="workers"):
        run_ensemble(small_config, [0], out, workers=0, progress=False)
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ConfigError, match="not a directory"):
        run_ensemble(small_config, [0], tmp_path / "afile", progress=False)
    assert not out.exists()


def test_seeds_with_a_record_are_not_run_again(local_ensemble, tmp_path, capsys):
    """--skip-recorded: when the run files are gone (a new machine) but the records are
    committed, those seeds are not computed again; the other seeds run as usual. Records of
    another configuration, or damaged ones, are refused in one line before anything is written."""
    import warnings

    from tiltpile.figures.records import write_records

    src, _, _ = local_ensemble
    records = tmp_path / "records"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")         # 60 grains: the cutoff's resolution warning
        write_records(src, records, workers=1, progress=False)
    assert sorted(p.name for p in records.glob("run_*.npz")) == ["run_0000.npz", "run_0001.npz"]
    # every seed recorded: nothing runs, nothing is written
    out = tmp_path / "new"
    assert main(_cli(out, "--runs", "2", "--workers", "1", "--skip-recorded", str(records))) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert (summary["recorded"], summary["done"], summary["runs"]) == ([0, 1], 2, 2)
    assert not out.exists()
    # seed 2 has no record: it alone runs
    assert main(_cli(out, "--runs", "3", "--workers", "1", "--skip-recorded", str(records),
                     "--quiet")) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert (summary["recorded"], summary["done"], summary["failed"]) == ([0, 1], 3, [])
    assert sorted(p.name for p in out.glob("run_*.h5")) == ["run_0002.h5"]
    # records of another configuration: refused, nothing written
    other = tmp_path / "other"
    assert main(_cli(other, "--runs", "3", "--skip-recorded", str(records),
                     overrides=SMALL + ["solver.tol=1e-6"])) == 2
    err = capsys.readouterr().err
    assert "run_0000.npz is a record of another configuration" in err and len(err.splitlines()) == 1
    (records / "run_0001.npz").write_bytes(b"not a record")
    assert main(_cli(other, "--runs", "3", "--skip-recorded", str(records))) == 2
    assert "run_0001.npz" in capsys.readouterr().err
    assert main(_cli(other, "--runs", "3", "--skip-recorded", str(tmp_path / "none"))) == 2
    assert "not a directory" in capsys.readouterr().err
    assert not other.exists()


def test_add_parser_registers_the_command():
    p = argparse.ArgumentParser(prog="tiltpile")
    sub = p.add_subparsers(dest="command", required=True)
    add_parser(sub)
    args = p.parse_args(["ensemble", "--preset", "paper", "--runs", "50", "--out", "data/paper",
                         "--scheduler", "tcp://10.0.0.1:8786"])
    assert args.func is cmd_ensemble
    assert (args.runs, args.first_seed, args.scheduler, args.workers) == (50, 0, "tcp://10.0.0.1:8786", None)
    assert args.out == Path("data/paper") and args.preset == "paper" and args.overrides == []


def test_progress_sender_throttles_angle_events():
    from tiltpile.ensemble import _progress_sender
    from tiltpile.sim.protocol import Progress

    sent = []
    send = _progress_sender(lambda topic, msg: sent.append((topic, msg)), "t", 7, every=3600.0)
    send(Progress("tilt", 10, 1.25, 3.0))
    send(Progress("tilt", 20, 1.5, 3.0))  # within the interval: dropped
    assert sent == [("t", {"seed": 7, "event": "progress", "phase": "tilt", "theta": 1.25})]

def test_simulate_reports_progress_to_the_ensemble_callback(tmp_path, small_config):
    """The ensemble's per-run angle comes from runner.simulate's on_progress (once a dead path)."""
    from tiltpile.runner import simulate
    from tiltpile.sim.protocol import Progress

    events = []
    simulate(small_config, 0, tmp_path / "r.h5", progress=False, on_progress=events.append)
    assert events and all(isinstance(e, Progress) for e in events)
    tilt = [e.theta_deg for e in events if e.phase == "tilt"]
    assert tilt and tilt[-1] == pytest.approx(small_config.protocol.theta_max_deg)
    assert any(e.phase == "deposit" for e in events)


def test_the_local_cluster_runs_without_dask_housekeeping_it_does_not_need():
    """The LocalCluster's workers and scheduler run with ensemble.QUIET_DASK (no statistical
    profiler, slow ticks and monitors, no work stealing) and one thread per library; the caller's
    dask configuration is left as it was."""
    import dask
    import distributed  # noqa: F401  (its defaults join dask's configuration on import)

    from tiltpile import ensemble

    def worker_view():
        import os

        import dask
        return ({k: dask.config.get(k) for k in ensemble.QUIET_DASK},
                os.environ.get("NUMBA_NUM_THREADS"))

    before = dask.config.get("distributed.worker.profile.enabled")
    with ensemble._client(None, 1, 1) as (client, engine):
        assert engine == "LocalCluster(1 workers)"
        (got, threads), = client.run(worker_view).values()
        assert got == ensemble.QUIET_DASK and threads == "1"
        assert client.run_on_scheduler(
            lambda: dask.config.get("distributed.scheduler.work-stealing")) is False
    assert dask.config.get("distributed.worker.profile.enabled") == before


def test_the_local_cluster_silences_its_workers_dask_logs_before_it_closes(monkeypatch):
    """A worker's heartbeat meeting the closing scheduler logged an error with a traceback to
    the ensemble's stderr after every result was in (tests/workflow/test_faults.py failed on it
    once, under load): the LocalCluster's workers are silenced on the way out, and only then."""
    import logging

    from tiltpile import ensemble

    def level():
        return logging.getLogger("distributed.worker").getEffectiveLevel()

    seen = []
    real = ensemble._quiet_teardown

    def spy(client):
        real(client)
        seen.extend(client.run(level).values())

    monkeypatch.setattr(ensemble, "_quiet_teardown", spy)
    with ensemble._client(None, 1, 1) as (client, _):
        during = list(client.run(level).values())
    assert during and all(v < logging.CRITICAL for v in during)
    assert seen == [logging.CRITICAL]
