"""Fault injection: two writers, a killed --force rerun, damaged and mixed run files,
a full disk, bad paths and inputs. Each test reproduces one way to lose data or to get a wrong
answer silently, and checks that it is now refused (one line, nothing written) or survived.

All runs are the 60-grain pile tilted to 2 deg (about 0.5 s each once numba's cache is warm).
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from simhelpers import assert_same_run
from tiltpile import config, store
from tiltpile.cli import main
from tiltpile.runner import simulate
from tiltpile.sim.protocol import SimulationError
from tiltpile.store import checkpoint_path, lock_path, open_run, part_path

TINY = ["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=2.0", "protocol.checkpoint_every=5"]
SETS = ["--preset", "smoke", *[a for t in TINY for a in ("--set", t)]]
ENV = dict(os.environ, NUMBA_CACHE_DIR=os.environ.get("NUMBA_CACHE_DIR", str(
    Path(__file__).resolve().parents[2] / ".venv" / "numba-cache")))


class _Killed(BaseException):
    """Stands for the process dying at a chosen point (not an Exception: nothing may catch it)."""


@pytest.fixture(scope="module")
def tiny():
    return config.load("smoke", overrides=TINY)


@pytest.fixture(scope="module")
def ref(tmp_path_factory, tiny):
    """The tiny run of seed 3, uninterrupted: what every survivor must equal."""
    path = tmp_path_factory.mktemp("ref") / "run_0003.h5"
    simulate(tiny, 3, path, progress=False, resume=False)
    return path


def _sha(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _cli(capsys, *argv) -> tuple[int, list[str]]:
    """Run ``tiltpile ARGV`` in this process; (exit status, stderr lines)."""
    capsys.readouterr()
    rc = main([str(a) for a in argv])
    return rc, capsys.readouterr().err.strip().splitlines()


def _one_error_line(lines, *words) -> None:
    assert len(lines) == 1, lines
    assert lines[0].startswith("tiltpile ") and ": error: " in lines[0], lines
    for w in words:
        assert str(w) in lines[0], (w, lines)


def _dying_append(at_frame: int, owner=store.RunWriter):
    original = owner.append

    def append(self, frame):
        if self.n_frames == at_frame:
            raise _Killed
        original(self, frame)
    return append


# -- 1. one writer per run file ---------------------------------------------------------------------

def test_second_writer_is_refused_while_the_first_writes(tmp_path, tiny, ref):
    """A second `simulate` on the same file (with or without --force) must not open the .part
    with mode "w": that truncates it under the first writer (radius all zero)."""
    out = tmp_path / "run.h5"
    seen = []

    def on_progress(ev):
        if not seen and ev.phase == "tilt":
            assert lock_path(out).exists() and part_path(out).exists()
            before = _sha(part_path(out))
            for extra in ([], ["--force"]):
                p = subprocess.run([sys.executable, "-m", "tiltpile", "simulate", *SETS, "--seed", "3",
                                    "--out", str(out), "--quiet", *extra],
                                   capture_output=True, text=True, env=ENV, timeout=120)
                seen.append((p.returncode, p.stderr.strip().splitlines()))
            assert _sha(part_path(out)) == before  # the second writer touched nothing

    simulate(tiny, 3, out, progress=False, on_progress=on_progress)
    assert len(seen) == 2
    for rc, lines in seen:
        assert rc == 2
        _one_error_line(lines, f"{part_path(out)} is being written by another process", "pid")
    assert store.verify(out) == []
    assert_same_run(out, ref)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]  # lock and checkpoint gone


def test_lock_held_elsewhere_blocks_the_resume_then_is_released_by_the_holders_death(
        tmp_path, tiny, ref, monkeypatch):
    """The lock is taken before anything is opened: a .part held by another process is neither
    resumed nor truncated; once that process is gone (killed: flock dies with it), the run resumes."""
    out = tmp_path / "run.h5"
    monkeypatch.setattr(store.RunWriter, "append", _dying_append(9))
    with pytest.raises(_Killed):
        simulate(tiny, 3, out, progress=False)
    monkeypatch.undo()
    before = _sha(part_path(out))
    holder = subprocess.Popen([sys.executable, "-c", "import sys; from tiltpile import store; "
                               "store.acquire_lock(sys.argv[1]); print('held', flush=True); sys.stdin.read()",
                               str(out)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=ENV)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(store.RunBusyError, match="being written by another process"):
            simulate(tiny, 3, out, progress=False)
        assert _sha(part_path(out)) == before
    finally:
        holder.kill()
        holder.wait()
    summary = simulate(tiny, 3, out, progress=False)
    assert summary["resumed_from_frame"] is not None and summary["resumed_from_frame"] > 0
    assert_same_run(out, ref)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


# -- 2. --force replaces the old run only when the new one is complete ---------------------------

def test_force_rerun_killed_midway_keeps_the_old_run(tmp_path, ref, monkeypatch, capsys):
    out = tmp_path / "run.h5"
    shutil.copy(ref, out)
    before = _sha(out)
    monkeypatch.setattr(store.RunWriter, "append", _dying_append(8))
    with pytest.raises(_Killed):
        main(["simulate", *SETS, "--seed", "3", "--out", str(out), "--force", "--quiet"])
    monkeypatch.undo()
    assert _sha(out) == before and part_path(out).exists()  # the finished run is still there
    rc, _ = _cli(capsys, "simulate", *SETS, "--seed", "3", "--out", out, "--force", "--quiet")
    assert rc == 0
    assert_same_run(out, ref)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


# -- 3. integrity: flipped bytes, deleted datasets ------------------------------------------------

def _flip(path: Path, dataset: str, coord) -> None:
    """Flip one bit in the middle of the stored chunk of ``dataset`` holding ``coord``."""
    with h5py.File(path, "r") as f:
        info = f[dataset].id.get_chunk_info_by_coord(coord)
    with open(path, "r+b") as fh:
        fh.seek(info.byte_offset + info.size // 2)
        b = fh.read(1)
        fh.seek(info.byte_offset + info.size // 2)
        fh.write(bytes([b[0] ^ 0x10]))


@pytest.mark.parametrize("dataset, coord", [("frames/position", (5, 0, 0)), ("contacts/force", (0, 0)),
                                            ("particles/radius", (0,)), ("frames/theta_deg", (0,))])
def test_flipped_bit_is_found_by_verify(tmp_path, ref, capsys, dataset, coord):
    path = tmp_path / "run_0003.h5"
    shutil.copy(ref, path)
    _flip(path, dataset, coord)
    problems = store.verify(path)
    assert len(problems) == 1 and dataset in problems[0]
    capsys.readouterr()
    assert main(["verify", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert f"{path}: DAMAGED: dataset {dataset}" in out


def test_flipped_position_is_refused_by_the_reader_observables_and_the_figures(tmp_path, ref, capsys):
    """A flipped byte (a grain at x = 5.8e-182) must not reach the observables or the figures."""
    d = tmp_path / "ens"
    d.mkdir()
    path = d / "run_0003.h5"
    shutil.copy(ref, path)
    _flip(path, "frames/position", (5, 0, 0))
    with open_run(path) as run:  # the layout is fine: opening works, reading the frame does not
        run.position(4)
        with pytest.raises(store.RunFileError, match=r"run_0003.h5: dataset frames/position is damaged"):
            run.position(5)
    rc, lines = _cli(capsys, "observables", d, "--workers", "1", "--quiet")
    assert rc == 1
    _one_error_line(lines, path, "frames/position")
    assert not list((d / "observables").glob("*.npz"))
    from tiltpile.analysis.ensemble_data import load_ensemble

    with pytest.raises(store.RunFileError, match=r"run_0003.h5: dataset frames/position is damaged"):
        load_ensemble(d)


def test_missing_dataset_is_an_error_except_the_documented_ones(tmp_path, ref, capsys):
    """A deleted frames/theta_deg is an error naming it, not NaN everywhere."""
    path = tmp_path / "run_0003.h5"
    shutil.copy(ref, path)
    with h5py.File(path, "r+") as f:
        del f["frames/theta_deg"]
    with pytest.raises(store.RunFileError, match="dataset frames/theta_deg is missing"):
        open_run(path)
    assert any("frames/theta_deg is missing" in p for p in store.verify(path))
    rc, lines = _cli(capsys, "observables", tmp_path, "--quiet")
    assert rc == 1
    _one_error_line(lines, path, "frames/theta_deg")
    # energy_gain is documented as absent from files written before it existed
    shutil.copy(ref, path)
    with h5py.File(path, "r+") as f:
        del f["frames/energy_gain"]
    with open_run(path) as run:
        assert np.isnan(run.energy_gain).all() and np.isfinite(run.theta_deg).all()
    assert store.verify(path) == []


def test_every_dataset_has_units_description_and_a_checksum(ref):
    """Self-describing run files (units and description on every dataset) and the integrity
    record."""
    with h5py.File(ref, "r") as f:
        assert f.attrs["integrity"] == store.INTEGRITY
        names = []
        f.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
        assert sorted(names) == sorted(store.LAYOUT)
        for n in names:
            ds = f[n]
            assert ds.attrs["units"] == store.LAYOUT[n][0] and ds.attrs["description"], n
            assert ds.fletcher32, n
    assert store.verify(ref) == [] and store.has_integrity_record(ref)


def test_ensemble_moves_a_damaged_run_aside_and_runs_it_again(tmp_path, tiny, ref, capsys):
    """`tiltpile ensemble` does not call a damaged file done."""
    from tiltpile.ensemble import run_ensemble

    d = tmp_path / "ens"
    d.mkdir()
    shutil.copy(ref, d / "run_0003.h5")
    _flip(d / "run_0003.h5", "contacts/force", (0, 0))
    m = run_ensemble(tiny, [3], d, workers=1, progress=False)
    assert m["runs"]["3"]["status"] == "done"
    assert "run_0003.h5.damaged" in capsys.readouterr().err
    assert (d / "run_0003.h5.damaged").exists()
    assert store.verify(d / "run_0003.h5") == []
    assert_same_run(d / "run_0003.h5", ref)
    # found sound once, recorded by size and mtime: not read again while unchanged ...
    run_ensemble(tiny, [3], d, workers=1, progress=False)
    stamp = json.loads((d / "ensemble.json").read_text())["runs"]["3"]["verified"]
    assert stamp == [(d / "run_0003.h5").stat().st_size, (d / "run_0003.h5").stat().st_mtime_ns]
    # ... and read again once changed
    (d / "run_0003.h5.damaged").unlink()
    _flip(d / "run_0003.h5", "frames/position", (3, 0, 0))
    m = run_ensemble(tiny, [3], d, workers=1, progress=False)
    assert m["runs"]["3"]["status"] == "done" and (d / "run_0003.h5.damaged").exists()
    assert_same_run(d / "run_0003.h5", ref)


# -- 4. one configuration per directory -------------------------------------------------------------

def test_observables_refuses_a_directory_of_mixed_configurations(tmp_path, ref, capsys):
    d = tmp_path / "ens"
    d.mkdir()
    shutil.copy(ref, d / "run_0003.h5")
    shutil.copy(ref, d / "run_0005.h5")
    other = config.load("smoke", overrides=[*TINY[:2], "protocol.theta_max_deg=1.0"])
    simulate(other, 4, d / "run_0004.h5", progress=False)
    rc, lines = _cli(capsys, "observables", d, "--quiet")
    assert rc == 2
    _one_error_line(lines, "run_0004.h5", "another configuration")
    assert not (d / "observables").exists()  # nothing computed or written


# -- 5. a full disk ---------------------------------------------------------------------------------

def test_disk_full_at_write_time_is_one_line_and_resumes(tmp_path, ref, monkeypatch, capsys):
    """An OSError(ENOSPC) from the writer: one line, no temporary file, and the rerun resumes."""
    out = tmp_path / "run.h5"
    original = store.RunWriter.append

    def full(self, frame):
        if self.n_frames == 12:
            raise OSError(errno.ENOSPC, "No space left on device")
        original(self, frame)

    monkeypatch.setattr(store.RunWriter, "append", full)
    rc, lines = _cli(capsys, "simulate", *SETS, "--seed", "3", "--out", out, "--quiet")
    monkeypatch.undo()
    assert rc == 1
    _one_error_line(lines, f"no space left on device while writing {part_path(out)}; rerun to resume")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5.ckpt", "run.h5.part"]
    rc, _ = _cli(capsys, "simulate", *SETS, "--seed", "3", "--out", out, "--quiet")
    assert rc == 0
    assert_same_run(out, ref)


def test_disk_full_while_checkpointing_leaves_no_temporary_file(tmp_path, ref, monkeypatch, capsys):
    out = tmp_path / "run.h5"
    original = store.writer._fsync  # the writer calls it: patch it there

    def full(path):
        if ".tmp" in Path(path).name:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        original(path)

    monkeypatch.setattr(store.writer, "_fsync", full)
    rc, lines = _cli(capsys, "simulate", *SETS, "--seed", "3", "--out", out, "--quiet")
    monkeypatch.undo()
    assert rc == 1
    _one_error_line(lines, "no space left on device while writing")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5.part"]


def test_disk_full_manifest_leaves_no_temporary_file(tmp_path, monkeypatch):
    from tiltpile.ensemble import _Manifest

    man = _Manifest(tmp_path / "ensemble.json", {"runs": {}})
    man.save()

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(store.RunWriteError, match="no space left on device while writing .*ensemble.json"):
        man.save()
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ensemble.json"]


def _can_mount() -> bool:
    return hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("mount") is not None


@contextlib.contextmanager
def _tmpfs(path, size_k: int):
    """A tmpfs of ``size_k`` kB mounted at the new directory ``path`` (the test is skipped if it
    cannot be mounted), unmounted at the end."""
    path.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_k}k", "tmpfs", str(path)]).returncode:
        pytest.skip("cannot mount a tmpfs here")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)])


@pytest.mark.skipif(not _can_mount(), reason="mounting a tmpfs needs root")
def test_disk_full_on_a_real_tiny_tmpfs(tmp_path, ref):
    """A real full disk: HDF5 cannot close a file whose writes failed (h5py crashed with 30
    tracebacks and a segfault); the writer stops while the file can still be closed whole."""
    with _tmpfs(tmp_path / "mnt", store.RESERVE_BYTES // 1024 + 600) as mnt:
        out = mnt / "run.h5"
        cmd = [sys.executable, "-m", "tiltpile", "simulate", *SETS, "--seed", "3", "--out", str(out), "--quiet"]
        p = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=120)
        assert p.returncode == 1, p.stderr
        _one_error_line(p.stderr.strip().splitlines(), "no space left on device while writing", "rerun to resume")
        assert "Traceback" not in p.stderr
        assert not [q.name for q in mnt.iterdir() if q.name not in ("run.h5.part", "run.h5.ckpt")]
        subprocess.run(["mount", "-o", "remount,size=64m", str(mnt)], check=True)
        p = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=120)
        assert p.returncode == 0, p.stderr
        assert_same_run(out, ref)
        assert sorted(q.name for q in mnt.iterdir()) == ["run.h5"]


# -- 6. output paths --------------------------------------------------------------------------------

def _bad_outputs(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    (tmp_path / "adir.h5").mkdir()
    return [("/proc/tiltpile_run.h5", "/proc"), (afile / "run.h5", afile), (tmp_path / "adir.h5", "adir.h5")]


def test_unwritable_output_paths_are_one_line_and_nothing_is_written(tmp_path, capsys):
    for out, named in _bad_outputs(tmp_path):
        before = sorted(p.name for p in tmp_path.iterdir())
        for force in ([], ["--force"]):
            rc, lines = _cli(capsys, "simulate", *SETS, "--seed", "3", "--out", out, "--quiet", *force)
            assert rc == 2
            _one_error_line(lines, named)
        assert sorted(p.name for p in tmp_path.iterdir()) == before
    rc, lines = _cli(capsys, "ensemble", *SETS, "--runs", "1", "--out", "/proc/tiltpile_ens", "--quiet")
    assert rc == 2
    _one_error_line(lines, "/proc")


def test_read_only_directory_is_refused(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    if _can_mount():
        if subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(ro)]).returncode:
            pytest.skip("cannot mount a read-only tmpfs")
    else:
        ro.chmod(0o555)
    try:
        rc, lines = _cli(capsys, "simulate", *SETS, "--seed", "3", "--out", ro / "run.h5", "--quiet")
        assert rc == 2
        _one_error_line(lines, ro, "not writable")
        assert list(ro.iterdir()) == []
    finally:
        if _can_mount():
            subprocess.run(["umount", "-l", str(ro)])
        ro.chmod(0o755)


# -- 7. a health stop -------------------------------------------------------------------------------

def test_health_stop_is_one_line_and_promises_no_missing_checkpoint(tmp_path, capsys):
    out = tmp_path / "run.h5"
    rc, lines = _cli(capsys, "simulate", "--preset", "smoke", "--set", "scene.box_length=2.8", "--seed", "1",
                     "--out", out, "--quiet")
    assert rc == 1
    _one_error_line(lines, "health.overlap_stop exceeded", "Nothing was kept")
    assert "resumes it from its last checkpoint" not in lines[0]
    assert list(tmp_path.iterdir()) == []


# -- 8, 9. configuration files and seeds ------------------------------------------------------------

def test_config_that_is_not_a_text_file_is_one_line(tmp_path, capsys):
    binary = tmp_path / "binary.toml"
    binary.write_bytes(bytes(range(256)) * 4)
    out = tmp_path / "out" / "run.h5"
    for cfg, words in ((binary, "not a text"), (tmp_path, "is a directory"), ("/dev/zero", "not a regular file")):
        rc, lines = _cli(capsys, "simulate", "--preset", "smoke", "--config", cfg, "--seed", "1", "--out", out)
        assert rc == 2
        _one_error_line(lines, cfg, words)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("text", [str(2**64), str(2**63), "1_0", "+5", " 5", "0x10", "-1"])
def test_seed_must_be_plain_digits_within_range(tmp_path, capsys, text):
    with pytest.raises(SystemExit) as e:
        main(["simulate", "--preset", "smoke", "--seed", text, "--out", str(tmp_path / "run.h5")])
    assert e.value.code == 2
    assert "seed" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_seed_range_is_checked_before_anything_is_written(tmp_path, tiny, capsys):
    from tiltpile.ensemble import run_ensemble

    rc, lines = _cli(capsys, "ensemble", *SETS, "--runs", "2", "--first-seed", str(2**63 - 1),
                     "--out", tmp_path / "ens", "--quiet")
    assert rc == 2
    _one_error_line(lines, "out of range")
    with pytest.raises(config.ConfigError, match="out of range"):
        simulate(tiny, 2**64, tmp_path / "run.h5", progress=False)
    with pytest.raises(config.ConfigError, match="out of range"):
        run_ensemble(tiny, [2**64], tmp_path / "ens2", progress=False)
    assert list(tmp_path.iterdir()) == []


# -- 10. smaller -------------------------------------------------------------------------------------

def test_stale_checkpoint_of_a_finished_run_is_removed(tmp_path, tiny, ref, monkeypatch, capsys):
    """A kill between the final rename and the removal of the frame log and the checkpoint left
    them forever (NAME.ckpt alone, before the log): the log's DONE record names the finished file."""
    out = tmp_path / "run.h5"
    real = os.replace

    def dying(src, dst):
        real(src, dst)
        if Path(dst) == out:
            raise _Killed

    monkeypatch.setattr(store.writer.os, "replace", dying)
    with pytest.raises(_Killed):
        simulate(tiny, 3, out, progress=False)
    monkeypatch.undo()
    assert out.exists() and checkpoint_path(out).exists() and part_path(out).exists()
    assert store.verify(out) == []
    rc, lines = _cli(capsys, "simulate", *SETS, "--seed", "3", "--out", out, "--quiet")
    assert rc == 2  # exists: refused, but the stale log and checkpoint are gone
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]
    assert_same_run(out, ref)
    # the checkpoint alone (killed after the log's removal) goes too
    checkpoint_path(out).write_bytes(b"stale")
    assert store.remove_stale_checkpoint(out) and sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


def test_a_killed_force_rerun_beside_a_finished_run_is_resumed_not_removed(tmp_path, tiny, ref, monkeypatch):
    """NAME + NAME.part + NAME.ckpt is also what a --force rerun killed midway leaves: its log has
    no DONE record naming NAME, so it stays and resumes."""
    out = tmp_path / "run.h5"
    shutil.copy(ref, out)
    monkeypatch.setattr(store.RunWriter, "append", _dying_append(8))
    with pytest.raises(_Killed):
        simulate(tiny, 3, out, progress=False)
    monkeypatch.undo()
    assert not store.remove_stale_checkpoint(out) and part_path(out).exists()
    assert simulate(tiny, 3, out, progress=False)["resumed_from_frame"] > 0


def test_observables_workers_must_be_positive(tmp_path, ref, capsys):
    shutil.copy(ref, tmp_path / "run_0003.h5")
    for w in ("0", "-3"):
        rc, lines = _cli(capsys, "observables", tmp_path, "--workers", w, "--quiet")
        assert rc == 2
        _one_error_line(lines, "--workers", w)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run_0003.h5"]


def test_part_of_another_configuration_is_discarded_with_a_message(tmp_path, tiny, monkeypatch):
    out = tmp_path / "run.h5"
    monkeypatch.setattr(store.RunWriter, "append", _dying_append(9))
    with pytest.raises(_Killed):
        simulate(tiny, 3, out, progress=False)
    monkeypatch.undo()
    other = config.load("smoke", overrides=[*TINY[:2], "protocol.theta_max_deg=1.0"])
    with pytest.warns(RuntimeWarning, match=r"discarded .*run.h5.part: it is a run of another configuration"):
        simulate(other, 3, out, progress=False)


def test_deposition_limit_names_the_limit(tmp_path):
    cfg = config.load("smoke", overrides=[*TINY, "protocol.max_deposition_steps=1"])
    with pytest.raises(SimulationError, match=r"max_deposition_steps = 1"):
        simulate(cfg, 3, tmp_path / "run.h5", progress=False)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("runs", ["missing", None, [], "x"])
def test_manifest_without_a_runs_table_is_one_line(tmp_path, tiny, capsys, runs):
    d = tmp_path / "ens"
    d.mkdir()
    m = {"format": "tiltpile-ensemble/1", "config_hash": tiny.hash(), "seeds": [], "invocations": []}
    if runs != "missing":
        m["runs"] = runs
    (d / "ensemble.json").write_text(json.dumps(m))
    rc, lines = _cli(capsys, "ensemble", *SETS, "--runs", "1", "--out", d, "--quiet")
    assert rc == 2
    _one_error_line(lines, "ensemble.json", '"runs"')
    assert sorted(p.name for p in d.iterdir()) == ["ensemble.json"]


@pytest.mark.skipif(not _can_mount(), reason="mounting a tmpfs needs root")
def test_ensemble_on_a_full_disk_is_one_line_per_run_and_resumes(tmp_path, ref):
    """`ensemble` printed 181 tracebacks and left an empty ensemble.json.tmp on a full disk."""
    with _tmpfs(tmp_path / "mnt", store.RESERVE_BYTES // 1024 + 600) as mnt:
        d = mnt / "ens"
        cmd = [sys.executable, "-m", "tiltpile", "ensemble", *SETS, "--runs", "1", "--first-seed", "3",
               "--out", str(d), "--workers", "1"]
        p = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=300)
        assert p.returncode == 1, p.stderr
        assert "Traceback" not in p.stderr and "Compute Failed" not in p.stderr, p.stderr
        failed = [ln for ln in p.stderr.splitlines() if "FAILED" in ln]
        assert len(failed) == 1 and "no space left on device while writing" in failed[0]
        assert not list(d.glob("*.tmp*"))
        subprocess.run(["mount", "-o", "remount,size=64m", str(mnt)], check=True)
        p = subprocess.run([*cmd, "--quiet"], capture_output=True, text=True, env=ENV, timeout=300)
        assert p.returncode == 0, p.stderr
        assert_same_run(d / "run_0003.h5", ref)


def test_observables_on_a_full_disk_is_one_line_and_leaves_no_temporary(tmp_path, ref, monkeypatch, capsys):
    from tiltpile.analysis import observables as obs

    shutil.copy(ref, tmp_path / "run_0003.h5")

    def full(fh, **arrays):
        fh.write(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(obs.np, "savez_compressed", full)
    rc, lines = _cli(capsys, "observables", tmp_path, "--workers", "1", "--quiet")
    assert rc == 1
    _one_error_line(lines, "no space left on device")
    assert list((tmp_path / "observables").iterdir()) == []


def test_compute_observables_refuses_mixed_configurations_and_bad_workers(tmp_path, ref):
    from tiltpile.analysis import compute_observables

    shutil.copy(ref, tmp_path / "run_0003.h5")
    with pytest.raises(ValueError, match="workers"):
        compute_observables(tmp_path, workers=0, progress=False)
    other = config.load("smoke", overrides=[*TINY[:2], "protocol.theta_max_deg=1.0"])
    simulate(other, 4, tmp_path / "run_0004.h5", progress=False)
    shutil.copy(ref, tmp_path / "run_0005.h5")
    with pytest.raises(store.MixedConfigError, match="run_0004.h5 is a run of another configuration"):
        compute_observables(tmp_path, workers=1, progress=False)
    assert not (tmp_path / "observables").exists()


@pytest.mark.parametrize("where, key, value", [("/", "seed", 4), ("/", "box_length", 10.5),
                                               ("/deposition", "steps", 1), ("/health", "cap_hits", 0)])
def test_changed_attribute_is_found_by_verify(tmp_path, ref, where, key, value):
    """Attributes are metadata, outside the datasets' checksums: attrs_sha256 covers them."""
    path = tmp_path / "run_0003.h5"
    shutil.copy(ref, path)
    with h5py.File(path, "r+") as f:
        f[where].attrs[key] = value
    problems = store.verify(path)
    assert len(problems) == 1 and "attributes" in problems[0] and store.ATTRS_DIGEST in problems[0]


@pytest.mark.skipif(not _can_mount(), reason="mounting a tmpfs needs root")
@pytest.mark.parametrize("size_k", [300, 500])
def test_disk_filled_by_someone_else_mid_write_is_still_one_line(tmp_path, ref, size_k):
    """Without the writer's reserve (as when another process fills the disk between two frames)
    HDF5's own writes fail: still one line, no crash, no temporary file, and the rerun works."""
    with _tmpfs(tmp_path / "mnt", size_k) as mnt:
        out = mnt / "run.h5"
        argv = ["simulate", *SETS, "--seed", "3", "--out", str(out), "--quiet"]
        code = ("import sys; import tiltpile.store as s; s.RESERVE_BYTES = 0; from tiltpile.cli import main; "
                "raise SystemExit(main(sys.argv[1:]))")
        p = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, env=ENV,
                           timeout=120)
        assert p.returncode == 1, p.stderr
        _one_error_line(p.stderr.strip().splitlines(), f"no space left on device while writing {part_path(out)}")
        assert not [q.name for q in mnt.iterdir() if q.name not in ("run.h5.part", "run.h5.ckpt")]
        subprocess.run(["mount", "-o", "remount,size=64m", str(mnt)], check=True)
        p = subprocess.run([sys.executable, "-m", "tiltpile", *argv], capture_output=True, text=True,
                           env=ENV, timeout=120)
        assert p.returncode == 0, p.stderr
        assert_same_run(out, ref)


def test_part_held_open_by_a_writer_without_our_lock_is_not_truncated(tmp_path, tiny, monkeypatch):
    """A writer of an older tiltpile takes no NAME.lock, only HDF5's own file lock: its .part is
    still not truncated."""
    import legacy_writer
    from tiltpile import runner

    out = tmp_path / "run.h5"
    monkeypatch.setattr(runner, "RunWriter", legacy_writer.RunWriter)  # an HDF5 .part, as before the log
    monkeypatch.setattr(legacy_writer.RunWriter, "append", _dying_append(9, legacy_writer.RunWriter))
    with pytest.raises(_Killed):
        simulate(tiny, 3, out, progress=False)
    monkeypatch.undo()
    checkpoint_path(out).unlink()  # not resumable: the new writer would start afresh
    holder = subprocess.Popen([sys.executable, "-c", "import sys, h5py; f = h5py.File(sys.argv[1], 'r+'); "
                               "print('held', flush=True); sys.stdin.read()", str(part_path(out))],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=ENV)
    try:
        assert holder.stdout.readline().strip() == "held"
        before = _sha(part_path(out))  # (opening it r+ marks the file in use)
        with pytest.raises(store.RunBusyError, match="HDF5 lock"):
            simulate(tiny, 3, out, progress=False)
        assert _sha(part_path(out)) == before
    finally:
        holder.kill()
        holder.wait()


def test_a_second_ensemble_on_one_directory_is_refused(tmp_path, tiny):
    """Two `tiltpile ensemble` on one DIR at once: the second is refused in one line naming the
    directory, the first and the lock (DIR/.ensemble.lock, held here by this test as a first
    invocation holds it) before it writes anything."""
    from tiltpile.ensemble import LOCK, run_ensemble
    from tiltpile.outputs import OutputBusy, lock_file, note, unlock_file

    d = tmp_path / "ens"
    d.mkdir()
    fd = lock_file(d / LOCK, note("tiltpile ensemble"))
    try:
        with pytest.raises(OutputBusy) as e:
            run_ensemble(tiny, [3], d, progress=False)
        assert str(e.value) == (f"{d} is busy: tiltpile ensemble (pid {os.getpid()} on "
                                f"{socket.gethostname()}) is writing it (lock {d / LOCK}); wait for "
                                "it to finish or stop it (nothing was changed)")
        assert sorted(p.name for p in d.iterdir()) == [LOCK]
    finally:
        unlock_file(d / LOCK, fd)
    assert sorted(p.name for p in d.iterdir()) == []


def test_verify_against_records_tells_a_recomputed_run_from_another(tmp_path, tiny, ref, capsys,
                                                                    monkeypatch):
    """A run file computed again (its first one lost) reproduces its record's frames bit for bit:
    `tiltpile verify DIR --against RECORDS` says so and exits 0. A run of another configuration,
    a run without a record and frames that differ from the record's digest each exit 1, naming
    why, one line per file."""
    from tiltpile.figures.records import write_record_of

    records = tmp_path / "records"
    write_record_of(ref, records)
    again = tmp_path / "again"
    simulate(tiny, 3, again / "run_0003.h5", progress=False, resume=False)
    assert main(["verify", str(again), "--against", str(records)]) == 0
    assert capsys.readouterr().out.strip() == f"{again / 'run_0003.h5'}: ok, reproduces its record bit for bit"

    other = tmp_path / "other"
    simulate(config.load("smoke", overrides=TINY + ["solver.tol=1e-7"]), 3, other / "run_0003.h5",
             progress=False, resume=False)
    simulate(tiny, 4, other / "run_0004.h5", progress=False, resume=False)
    assert main(["verify", str(other), "--against", str(records)]) == 1
    out = capsys.readouterr().out.strip().splitlines()
    assert "DIFFERS: another run than its record's" in out[0]
    assert "DIFFERS: no record run_0004.npz in" in out[1]
    assert out[2] == f"2 of 2 run files sound; 0 reproduce their records in {records}"

    monkeypatch.setattr(store.reader.Run, "frames_digest", lambda self: "0" * 64)
    assert main(["verify", str(again), "--against", str(records), "--json"]) == 1
    row = json.loads(capsys.readouterr().out)
    assert row["ok"] and not row["reproduces_record"]
    assert "its frames differ from those its record run_0003.npz was made from" == row["record_problem"]
    assert main(["verify", str(again), "--against", str(tmp_path / "nowhere")]) == 2
    assert "no such records directory" in capsys.readouterr().err
