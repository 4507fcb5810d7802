"""The run record's layout (tiltpile.record) on hand-made tables: written and read back bit for
bit, deterministic bytes, and a damaged, truncated or foreign file refused in one line."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pandas as pd
import pytest

from tiltpile import record
from tiltpile.record import RecordError, read_meta, read_record, write_record

N = 6


def _tables():
    frames = pd.DataFrame({
        "run": np.full(4, 7, np.int64), "frame": np.arange(4, dtype=np.int64),
        "theta_deg": np.array([0.0, 0.05, 0.1, 0.15]), "z": [3.2, 3.1, np.nan, 3.0],
        "onset": np.array([False, False, True, False]), "n_lost": np.array([0, 3, 40000, -1]),
        "step": np.array([0, 2**40, 2**41, 2**42], np.int64)})
    clusters = pd.DataFrame({
        "run": np.full(3, 7, np.int64), "frame": np.array([0, 2, 2], np.int64),
        "cluster": np.array([0, 0, 1], np.int64), "size": np.array([5, 2, 1], np.int64),
        "orientation_deg": [12.5, np.nan, np.nan], "avalanching": [False, True, True],
        "speed_max": np.float32([1e-5, 0.3, 7e-12]).astype(np.float64),
        "z": [3.1, -0.0, 4.0]})
    return frames, clusters


def _picture(k, c):
    rng = np.random.default_rng(k)
    return {"position": rng.random((N, 2)), "pair": rng.integers(-3, N, (c, 2)).astype(np.int32),
            "force": rng.random((c, 2)), "status": rng.integers(0, 3, c).astype(np.int8),
            "theta_deg": 0.05 * k}


def _write(path, n_frames=4, pictures=(1, 2), **meta):
    frames, clusters = _tables()
    m = {"seed": 7, "config": {"scene": {"n": N - 2, "mu": 0.5}}, "config_hash": "abc" * 8,
         "n_frames": n_frames, "box_length": 4.0, "cost": {"steps": np.int64(10), "seconds": 1.5},
         "deposition": {"height": np.float64(2.5)}, "end_theta_deg": np.nan}
    m.update(meta)
    return write_record(path, meta=m, frames=frames, clusters=clusters,
                        radius=np.linspace(0.4, 0.6, N), fixed=np.arange(N) < 2,
                        preparation={"target_deg": np.array([10.0, -10.0, 0.0]),
                                     "tilt_steps": np.array([5, 10, 5])},
                        pictures={k: _picture(k, 3 + k) for k in pictures})


def test_a_record_reads_back_bit_for_bit(tmp_path):
    path = _write(tmp_path / "run_0007.npz")
    rec = read_record(path)
    frames, clusters = _tables()
    pd.testing.assert_frame_equal(rec.frames, frames, check_exact=True)
    pd.testing.assert_frame_equal(rec.clusters, clusters, check_exact=True)
    assert rec.seed == 7 and rec.meta["config"] == {"scene": {"n": N - 2, "mu": 0.5}}
    assert rec.meta["cost"] == {"steps": 10, "seconds": 1.5} and np.isnan(rec.meta["end_theta_deg"])
    assert rec.meta["format_version"] == record.FORMAT_VERSION
    assert rec.preparation["tilt_steps"].dtype == np.int64
    np.testing.assert_array_equal(rec.preparation["target_deg"], [10.0, -10.0, 0.0])
    np.testing.assert_array_equal(rec.fixed, np.arange(N) < 2)
    # ids and counts are stored in the smallest integer type that holds them, read back as int64
    with np.load(path) as z:
        assert z["frames__frame"].dtype == np.int8 and z["frames__n_lost"].dtype == np.int32
        assert z["frames__step"].dtype == np.int64 and z["clusters__size"].dtype == np.int8
        # float64 columns of float32 numbers as float32; the others (3.1, 0.05) as they are
        assert z["clusters__speed_max"].dtype == np.float32
        assert z["clusters__orientation_deg"].dtype == np.float32
        assert z["clusters__z"].dtype == np.float64 and z["frames__theta_deg"].dtype == np.float64
    assert np.signbit(rec.clusters["z"].iloc[1])
    # the meta member alone (cheap) says the same
    assert read_meta(path) == rec.meta
    assert [p.name for p in record.record_files(tmp_path)] == ["run_0007.npz"]


def test_snapshot_of_a_stored_frame_and_its_successor(tmp_path):
    rec = read_record(_write(tmp_path / "run_0007.npz", pictures=(1, 2, 3)))
    assert rec.picture_frames == [1, 2, 3]
    s = rec.snapshot(1)
    p1, p2 = _picture(1, 4), _picture(2, 5)
    for key in ("position", "pair", "force", "status"):
        np.testing.assert_array_equal(s[key], p1[key])
    assert s["theta_deg"] == pytest.approx(0.05) and s["box_length"] == 4.0
    np.testing.assert_array_equal(s["radius"], np.linspace(0.4, 0.6, N))
    for got, want in zip(s["next"], (p2["pair"], p2["force"], p2["status"])):
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(s["next_position"], p2["position"])
    last = rec.snapshot(3)          # the run's last frame: no successor
    assert last["next"] is None and last["next_position"] is None
    with pytest.raises(RecordError, match=r"frame 0 of run 7 is not in its record .*\[1, 2, 3\]") as e:
        rec.snapshot(0)
    assert "\n" not in str(e.value)
    with pytest.raises(RecordError, match="frame 2 of run 7"):   # stored, but not its successor
        read_record(_write(tmp_path / "c.npz", n_frames=5, pictures=(1, 2))).snapshot(2)


def test_same_content_same_bytes_and_no_temporary_left(tmp_path):
    a = _write(tmp_path / "a" / "run_0007.npz").read_bytes()
    b = _write(tmp_path / "b" / "run_0007.npz").read_bytes()
    assert a == b
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["run_0007.npz"]


@pytest.mark.parametrize("damage", ["flip", "truncate", "not_a_zip", "empty"])
def test_a_damaged_record_is_refused_in_one_line(tmp_path, damage):
    path = _write(tmp_path / "run_0007.npz")
    raw = bytearray(path.read_bytes())
    if damage == "flip":                # a byte inside the compressed data of the largest member
        with zipfile.ZipFile(path) as zf:
            info = max(zf.infolist(), key=lambda i: i.compress_size)
        raw[info.header_offset + 30 + len(info.filename) + info.compress_size // 2] ^= 0x40
    elif damage == "truncate":
        raw = raw[: len(raw) // 2]
    elif damage == "not_a_zip":
        raw = bytearray(b"\x93NUMPY" + bytes(100))
    else:
        raw = bytearray()
    path.write_bytes(bytes(raw))
    with pytest.raises(RecordError) as e:
        read_record(path)
    msg = str(e.value)
    assert "\n" not in msg and str(path) in msg and ("damaged" in msg or "not a" in msg)


def test_another_format_version_is_refused(tmp_path, monkeypatch):
    path = tmp_path / "run_0007.npz"
    monkeypatch.setattr(record, "FORMAT_VERSION", record.FORMAT_VERSION + 1)
    _write(path)
    monkeypatch.undo()
    with pytest.raises(RecordError, match=r"record format version \d+, this tiltpile reads version"):
        read_record(path)
    with pytest.raises(RecordError, match="format version"):
        read_meta(path)


def test_a_table_of_objects_is_refused(tmp_path):
    frames, clusters = _tables()
    with pytest.raises(RecordError, match="numbers only"):
        write_record(tmp_path / "x.npz", meta={"seed": 1}, frames=frames.assign(name="a"),
                     clusters=clusters, radius=np.ones(2), fixed=np.zeros(2, bool))
    assert list(tmp_path.iterdir()) == []


def test_meta_is_plain_json(tmp_path):
    path = _write(tmp_path / "run_0007.npz")
    with np.load(path) as z:
        doc = json.loads(str(z["meta"][()]))
    assert doc["format"] == record.FORMAT and doc["deposition"] == {"height": 2.5}
    assert [c for c, _ in doc["columns"]["frames"]] == list(_tables()[0].columns)


class _Killed(BaseException):
    """Stands for the process dying at a chosen point (not an Exception: nothing may catch it)."""


def test_a_record_killed_mid_write_leaves_the_old_one_whole(tmp_path, monkeypatch):
    """Killed while writing a record over an older one: the older record stays, byte for byte,
    and no temporary either (a SIGKILL, which runs no cleanup, leaves its dot-named temporary,
    which ``record_files`` never lists)."""
    path = _write(tmp_path / "run_0007.npz")
    before = path.read_bytes()
    real = zipfile.ZipFile.writestr
    calls = []

    def dying(self, *a, **kw):
        calls.append(1)
        if len(calls) == 3:
            raise _Killed
        return real(self, *a, **kw)

    monkeypatch.setattr(zipfile.ZipFile, "writestr", dying)
    with pytest.raises(_Killed):
        _write(path, n_frames=5)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run_0007.npz"]
    (tmp_path / ".run_0008.npz.123.tmp").write_bytes(b"PK half")
    assert record.record_files(tmp_path) == [path]
