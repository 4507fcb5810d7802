"""Frames that survive any kill (issue 55): the frame log, the run file built from it, and the
HDF5 .part files of the writer before it.

A run is SIGKILLed at chosen points inside its writes (tests/killhooks.py, a process of its own:
nothing catches a SIGKILL) and resumed; it must resume from its last checkpoint and end as the
run never interrupted, bit for bit, and its file byte for byte but for the wall times. The runs
are the 60-grain pile tilted to 1 deg, a frame every 2 steps, a checkpoint every 3 frames.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import legacy_writer
from simhelpers import assert_same_run
from tiltpile import config, runner, store
from tiltpile.runner import simulate
from tiltpile.store import checkpoint_path, framelog, part_path

SMALL = ["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=1.0",
         "protocol.frame_every=2", "protocol.checkpoint_every=3"]
# a history of two legs at the smoke rate before the ramp: checkpoints inside it, no frames yet
HISTORY = [*SMALL, "protocol.pretilt_deg=[3.0, 0.0]"]
ENV = dict(os.environ, NUMBA_CACHE_DIR=os.environ.get("NUMBA_CACHE_DIR", str(
    Path(__file__).resolve().parents[2] / ".venv" / "numba-cache")))
HOOKS = Path(__file__).resolve().parents[1] / "killhooks.py"
TIMING = ("seconds", "wall_seconds", "resumed_from_frame", "wall_seconds_whole", store.ATTRS_DIGEST)


class _Killed(BaseException):
    """Stands for the process dying at a chosen point (not an Exception: nothing may catch it)."""


@pytest.fixture(scope="module")
def refs(tmp_path_factory):
    """Seed 2 uninterrupted, with and without the history, by today's writer and by the writer
    before the frame log."""
    d = tmp_path_factory.mktemp("refs")
    out = {}
    for name, sets in (("small", SMALL), ("history", HISTORY)):
        cfg = config.load("smoke", overrides=sets)
        simulate(cfg, 2, d / f"{name}.h5", progress=False, resume=False)
        out[name] = (cfg, d / f"{name}.h5")
    saved = runner.RunWriter
    runner.RunWriter = legacy_writer.RunWriter
    try:
        simulate(out["small"][0], 2, d / "legacy.h5", progress=False, resume=False)
    finally:
        runner.RunWriter = saved
    out["legacy"] = d / "legacy.h5"
    return out


def _attrs(path) -> dict:
    """Every attribute of every group but the wall times and the digest over them."""
    got = {}
    with h5py.File(path, "r") as f:
        groups = [("/", f)]
        f.visititems(lambda n, o: groups.append((n, o)) if isinstance(o, h5py.Group) else None)
        for name, g in groups:
            for k, v in g.attrs.items():
                if not (name == "/" and k in TIMING):
                    got[(name, k)] = np.asarray(v).tolist() if not isinstance(v, str) else v
    return got


def assert_same_file(a, b) -> None:
    """Run files ``a`` and ``b`` are the same bytes but for the values of the wall-time
    attributes and the attribute digest (found in ``b``: one place each)."""
    x, y = Path(a).read_bytes(), Path(b).read_bytes()
    assert len(x) == len(y), (a, b)
    allowed = np.zeros(len(y), bool)
    with h5py.File(b, "r") as f:
        spans = []
        for key in ("seconds", "wall_seconds", store.ATTRS_DIGEST):
            raw = f.attrs[key].encode() if key == store.ATTRS_DIGEST else np.float64(f.attrs[key]).tobytes()
            at = y.find(raw)
            assert at >= 0 and y.find(raw, at + 1) < 0, key
            spans.append((at, at + len(raw)))
    allowed[spans[2][0]:spans[2][1]] = True
    allowed[spans[0][0]:spans[1][1]] = True  # seconds .. wall_seconds: resumed_from_frame between
    differ = np.frombuffer(x, np.uint8) != np.frombuffer(y, np.uint8)
    assert not np.any(differ & ~allowed), f"{a} and {b} differ at {np.flatnonzero(differ & ~allowed)[:5]}"


def _kill(point: str, out: Path, sets: list[str]) -> None:
    p = subprocess.run([sys.executable, str(HOOKS), point, str(out), *sets], env=ENV,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == -9, f"{point}: not killed (status {p.returncode}): {p.stderr[-2000:]}"


def _checkpoint_frames(out: Path) -> int:
    with h5py.File(checkpoint_path(out), "r") as g:
        return int(g.attrs["n_frames"])


def test_the_finished_file_is_the_old_writers_byte_for_byte(refs):
    """The frame log changed how a run is written, not the file: the same HDF5 calls in the same
    order (flushes at the checkpoints included) give the same bytes, but for the wall times."""
    _, ref = refs["small"]
    assert_same_file(ref, refs["legacy"])
    assert store.verify(ref) == [] and _attrs(ref) == _attrs(refs["legacy"])


@pytest.mark.parametrize("point, sets", [("frame", SMALL), ("checkpoint", SMALL), ("build", SMALL),
                                         ("history", HISTORY)])
def test_sigkill_inside_a_write_resumes_from_the_last_checkpoint_bit_identically(tmp_path, refs, point, sets):
    cfg, ref = refs["history" if sets is HISTORY else "small"]
    out = tmp_path / "run.h5"
    _kill(point, out, sets)
    assert part_path(out).exists() and not out.exists()
    k = _checkpoint_frames(out)
    if point in ("frame", "build"):  # a frame record cut in half / an HDF5 file half written
        assert framelog.is_frame_log(part_path(out)) and k > 0
    summary = simulate(cfg, 2, out, progress=False)
    assert summary["resumed_from_frame"] == k and summary["discarded"] is None
    assert store.verify(out) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]  # no log, checkpoint, temporary
    assert_same_run(out, ref)
    assert _attrs(out) == _attrs(ref)
    assert_same_file(out, ref)


def test_sigkill_between_the_build_and_the_rename_leaves_a_run_that_resumes(tmp_path, refs):
    cfg, ref = refs["small"]
    out = tmp_path / "run.h5"
    _kill("rename", out, SMALL)
    assert not out.exists() and framelog.last_record(part_path(out))[0] == b"DONE"
    assert not store.remove_stale_checkpoint(out)  # no NAME: nothing to clean up
    k = _checkpoint_frames(out)
    assert simulate(cfg, 2, out, progress=False)["resumed_from_frame"] == k
    assert_same_run(out, ref)
    assert_same_file(out, ref)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


# -- the .part and .ckpt files of the writer before the frame log (runs in progress then) -------

def _legacy_part(monkeypatch, cfg, out: Path, at_frame: int | None, phase: str | None = None) -> int:
    """Run seed 2 with the old writer (HDF5 .part), 'killed' at its frame ``at_frame`` (or at its
    first checkpoint of ``phase``); the frames its checkpoint follows."""
    original_append = legacy_writer.RunWriter.append
    original_ckpt = legacy_writer.RunWriter.checkpoint
    seen = []

    def append(self, frame):
        if at_frame is not None and self.n_frames == at_frame:
            raise _Killed
        original_append(self, frame)

    def checkpoint(self, state):
        original_ckpt(self, state)
        if phase is not None and state["scalars"]["phase"] == phase:
            seen.append(1)
            if len(seen) == 1:
                raise _Killed

    monkeypatch.setattr(runner, "RunWriter", legacy_writer.RunWriter)
    monkeypatch.setattr(legacy_writer.RunWriter, "append", append)
    monkeypatch.setattr(legacy_writer.RunWriter, "checkpoint", checkpoint)
    with pytest.raises(_Killed):
        simulate(cfg, 2, out, progress=False)
    monkeypatch.undo()
    assert not framelog.is_frame_log(part_path(out))
    with h5py.File(part_path(out), "r") as f:
        assert f.attrs["complete"] == False  # noqa: E712 (an HDF5 bool)
    with h5py.File(checkpoint_path(out), "r") as g:
        assert "log_bytes" not in g.attrs  # the old checkpoint format
    return _checkpoint_frames(out)


@pytest.mark.parametrize("where", ["ramp", "history"])
def test_an_hdf5_part_of_the_old_writer_resumes_bit_identically(tmp_path, refs, monkeypatch, where):
    """The paper ensemble running when the frame log came wrote HDF5 .part files: today's writer
    reads them (never writes them), turns their checkpointed frames into a frame log and goes on."""
    cfg, ref = refs["small" if where == "ramp" else "history"]
    out = tmp_path / "run.h5"
    k = _legacy_part(monkeypatch, cfg, out, 9 if where == "ramp" else None,
                     None if where == "ramp" else "pretilt")
    assert (k > 0) == (where == "ramp")
    summary = simulate(cfg, 2, out, progress=False)
    assert summary["resumed_from_frame"] == k and summary["discarded"] is None
    assert store.verify(out) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]
    assert_same_run(out, ref)
    assert _attrs(out) == _attrs(ref)  # the deposition (and history) attributes carried over


def test_an_hdf5_part_killed_inside_an_hdf5_write_still_resumes_or_restarts_cleanly(tmp_path, refs):
    """The old writer SIGKILLed inside its HDF5 write of frame 9: its .part resumes if its
    metadata on disk is whole (or is discarded with its reason, as before), and the run ends
    bit-identical either way."""
    cfg, ref = refs["small"]
    out = tmp_path / "run.h5"
    _kill("legacy", out, SMALL)
    k = _checkpoint_frames(out)
    summary = simulate(cfg, 2, out, progress=False)
    assert summary["resumed_from_frame"] == k or summary["discarded"] in (
        "it cannot be read", "its frames cannot be read back")
    assert_same_run(out, ref)


@pytest.mark.parametrize("dies_at", ["log", "checkpoint"])
def test_a_conversion_killed_midway_resumes(tmp_path, refs, monkeypatch, dies_at):
    """Killed while converting an HDF5 .part: after writing the log under its temporary name
    (``log``: the old pair is untouched), or after replacing the checkpoint but before renaming
    the log (``checkpoint``: the HDF5 .part resumes with the new checkpoint)."""
    cfg, ref = refs["small"]
    out = tmp_path / "run.h5"
    k = _legacy_part(monkeypatch, cfg, out, 9)
    real = os.replace

    def dying(src, dst):
        if dies_at == "log" and Path(dst) == checkpoint_path(out):
            raise _Killed
        real(src, dst)
        if dies_at == "checkpoint" and Path(dst) == checkpoint_path(out):
            raise _Killed

    monkeypatch.setattr(store.writer.os, "replace", dying)
    with pytest.raises(_Killed):
        simulate(cfg, 2, out, progress=False)
    monkeypatch.undo()
    assert not framelog.is_frame_log(part_path(out))
    summary = simulate(cfg, 2, out, progress=False)
    assert summary["resumed_from_frame"] == k and summary["discarded"] is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]
    assert_same_run(out, ref)


def test_a_log_cut_short_or_changed_before_its_checkpoint_is_not_resumed(tmp_path, refs, monkeypatch):
    cfg, ref = refs["small"]
    out = tmp_path / "run.h5"
    original = store.RunWriter.append

    def append(self, frame):
        if self.n_frames == 10:
            raise _Killed
        original(self, frame)

    monkeypatch.setattr(store.RunWriter, "append", append)
    with pytest.raises(_Killed):
        simulate(cfg, 2, out, progress=False)
    monkeypatch.undo()
    with h5py.File(checkpoint_path(out), "r") as g:
        end = int(g.attrs["log_bytes"])
    os.truncate(part_path(out), end - 1)
    why: list = []
    assert store.RunWriter.resume(out, cfg.hash(), why=why) is None
    assert why == ["it holds fewer frames than its checkpoint follows"]
    with pytest.warns(RuntimeWarning, match="discarded .*run.h5.part: it holds fewer frames"):
        assert simulate(cfg, 2, out, progress=False)["resumed_from_frame"] is None
    assert_same_run(out, ref)
