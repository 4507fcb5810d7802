"""Records that borrow (tiltpile.record.compact_record): a record leaves out what another record
of the same run holds bit for bit and reads back whole, bit for bit; a piece that differs is
never dropped, and a source that is missing, of another run or changed is refused in one line.
On hand-made tables; the definitions study's records: tests/figures/test_definitions.py."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pandas as pd
import pytest

from tiltpile.record import (RecordError, compact_record, read_meta, read_record,
                             record_differences, write_record)

N = 6
SOURCE = {"file": "run_0007.h5", "size": 10, "frames_sha256": "f" * 64}


def _tables(n=8, stride=1, z_shift=0.0):
    """Tables of a run of ``n`` stored frames analysed every ``stride``-th: z moves with
    ``z_shift`` (another contact rule), the rest does not."""
    f = np.arange(0, n, stride, dtype=np.int64)
    frames = pd.DataFrame({"run": np.full(f.size, 7, np.int64), "frame": f,
                           "theta_deg": 0.05 * f, "ke": np.exp(-f / 3.0),
                           "z": 3.0 + np.sin(f) + z_shift, "n_lost": (f * 7) % 5,
                           "onset": f == 4})
    cf = np.repeat(f, 2)
    clusters = pd.DataFrame({"run": np.full(cf.size, 7, np.int64), "frame": cf,
                             "cluster": np.tile([0, 1], f.size), "size": (cf * 3) % 11 + 1,
                             "speed_max": np.float32(np.cos(cf)).astype(np.float64)})
    return frames, clusters


def _picture(k):
    rng = np.random.default_rng(k)
    c = 3 + k
    return {"position": rng.random((N, 2)), "pair": rng.integers(0, N, (c, 2)).astype(np.int32),
            "force": rng.random((c, 2)), "status": rng.integers(0, 3, c).astype(np.int8),
            "theta_deg": 0.05 * k}


def _write(path, pictures=(1, 2), stride=1, z_shift=0.0, radius=None, **meta):
    frames, clusters = _tables(stride=stride, z_shift=z_shift)
    m = {"seed": 7, "config_hash": "abc" * 8, "n_frames": 8, "n_grains": N, "box_length": 4.0,
         "source": SOURCE, "analysis_params": {"frame_stride": stride}}
    m.update(meta)
    return write_record(path, meta=m, frames=frames, clusters=clusters,
                        radius=np.linspace(0.4, 0.6, N) if radius is None else radius,
                        fixed=np.arange(N) < 2,
                        preparation={"target_deg": np.array([10.0, -10.0, 0.0])},
                        pictures={k: _picture(k) for k in pictures})


def _members(path):
    with zipfile.ZipFile(path) as zf:
        return {i.filename[:-4] for i in zf.infolist()}


def test_a_compacted_record_reads_back_whole_and_holds_only_what_differs(tmp_path):
    base = _write(tmp_path / "records" / "run_0007.npz")
    rec = _write(tmp_path / "defs" / "list" / "run_0007.npz", pictures=(2, 3), z_shift=0.25)
    whole = read_record(rec)
    res = compact_record(rec, [base])
    assert res["status"] == "compacted" and res["bytes_after"] < res["bytes_before"]
    # z differs (the contact rule), picture 3 is not in the base: both stay in the record
    assert "frames.z" in res["stored"] and "picture:3" in res["stored"]
    assert {"frames.theta_deg", "frames.ke", "clusters.speed_max", "particles__radius",
            "preparation__target_deg", "picture:2"} <= set(res["borrowed"])
    got = read_record(rec)
    assert record_differences(whole, got) == []
    pd.testing.assert_frame_equal(got.frames, whole.frames, check_exact=True)
    pd.testing.assert_frame_equal(got.clusters, whole.clusters, check_exact=True)
    assert got.picture_frames == [2, 3]
    assert got.snapshot(2)["next"] is not None          # the successor comes from the record
    held = _members(rec)
    assert "frames__z" in held and "frames__theta_deg" not in held
    assert "particles__radius" not in held and "clusters__speed_max" not in held
    assert read_meta(rec)["borrowed"]["sources"] == ["../../records/run_0007.npz"]
    # the meta is the record's own but for what it borrows
    assert {k: v for k, v in read_meta(rec).items() if k != "borrowed"} == \
        {k: v for k, v in whole.meta.items()}
    # again: nothing to do, the same bytes
    before = rec.read_bytes()
    assert compact_record(rec, [base])["status"] == "unchanged" and rec.read_bytes() == before


def test_a_record_at_a_frame_stride_borrows_the_rows_of_its_frames(tmp_path):
    base = _write(tmp_path / "records" / "run_0007.npz")
    rec = _write(tmp_path / "defs" / "stride-2" / "run_0007.npz", stride=2)
    whole = read_record(rec)
    res = compact_record(rec, [base])
    # every column is the base's at the even frames: none stays in the record
    assert not [s for s in res["stored"] if s.startswith(("frames.", "clusters."))]
    entry = read_meta(rec)["borrowed"]["columns"]["clusters"]["speed_max"]
    assert entry["every"] == 2 and entry["from"] == 0
    assert record_differences(whole, read_record(rec)) == []


def test_a_piece_that_differs_is_never_dropped(tmp_path):
    """Asked to borrow a column a source does not hold bit for bit (one ulp off), compaction
    refuses, naming it, and leaves the record as it was."""
    base = _write(tmp_path / "records" / "run_0007.npz")
    rec = _write(tmp_path / "defs" / "list" / "run_0007.npz", z_shift=np.finfo(float).eps * 4)
    whole = read_record(rec)
    before = rec.read_bytes()
    assert not np.array_equal(read_record(rec).frames["z"], read_record(base).frames["z"])
    with pytest.raises(RecordError, match=r"frames\.z not held bit for bit") as e:
        compact_record(rec, [base], borrow=["frames.theta_deg", "frames.z"])
    assert "\n" not in str(e.value)
    assert rec.read_bytes() == before
    with pytest.raises(RecordError, match="holds no frames.nope"):
        compact_record(rec, [base], borrow=["frames.nope"])
    # what is asked and identical is borrowed, nothing else
    res = compact_record(rec, [base], borrow=["frames.theta_deg"])
    assert res["borrowed"] == ["frames.theta_deg"] and "frames.ke" in res["stored"]
    assert record_differences(whole, read_record(rec)) == []


def test_grains_that_differ_by_one_bit_stay(tmp_path):
    base = _write(tmp_path / "records" / "run_0007.npz")
    r = np.linspace(0.4, 0.6, N)
    r[3] = np.nextafter(r[3], 1.0)
    rec = _write(tmp_path / "defs" / "x" / "run_0007.npz", radius=r)
    res = compact_record(rec, [base])
    assert "particles__radius" in res["stored"] and "particles__fixed" in res["borrowed"]
    np.testing.assert_array_equal(read_record(rec).radius, r)


def test_a_source_of_another_run_is_refused(tmp_path):
    base = _write(tmp_path / "records" / "run_0007.npz",
                  source=dict(SOURCE, frames_sha256="0" * 64))
    rec = _write(tmp_path / "defs" / "x" / "run_0007.npz")
    before = rec.read_bytes()
    with pytest.raises(RecordError, match=r"another run \(frames_sha256 differ\)"):
        compact_record(rec, [base])
    other = _write(tmp_path / "other" / "run_0007.npz", seed=8)
    with pytest.raises(RecordError, match=r"another run \(seed differ\)"):
        compact_record(rec, [other])
    assert rec.read_bytes() == before
    # a missing source is no source
    assert compact_record(rec, [tmp_path / "nowhere" / "run_0007.npz"])["status"] == "unchanged"


def test_a_source_that_changed_or_went_is_refused_in_one_line(tmp_path):
    base = _write(tmp_path / "records" / "run_0007.npz")
    rec = _write(tmp_path / "defs" / "x" / "run_0007.npz", z_shift=1.0)
    compact_record(rec, [base])
    # the source rewritten with another pile's grains (same run in its meta): refused
    _write(base, radius=np.linspace(0.4, 0.61, N))
    with pytest.raises(RecordError, match=r"particles__radius, borrowed from \.\./\.\./records/run_0007\.npz, "
                                          r"is not what it was") as e:
        read_record(rec)
    assert "\n" not in str(e.value) and str(rec) in str(e.value)
    base.unlink()
    with pytest.raises(RecordError, match=r"borrows from \.\./\.\./records/run_0007\.npz, which is missing"):
        read_record(rec, tables=False, pictures=False)
    # read_meta needs no source
    assert read_meta(rec)["seed"] == 7


def test_sources_chain_but_never_circle(tmp_path):
    base = _write(tmp_path / "records" / "run_0007.npz")
    a = _write(tmp_path / "defs" / "a" / "run_0007.npz", z_shift=1.0, pictures=(2, 3))
    b = _write(tmp_path / "defs" / "b" / "run_0007.npz", z_shift=1.0, pictures=(3, 4))
    whole_b = read_record(b)
    compact_record(a, [base])
    res = compact_record(b, [base, a])
    # z from a (the same rule), theta from the base (the first that holds it), picture 3 from a
    assert read_meta(b)["borrowed"]["columns"]["frames"]["z"]["from"] == 1
    assert read_meta(b)["borrowed"]["columns"]["frames"]["theta_deg"]["from"] == 0
    assert "picture:3" in res["borrowed"] and "picture:4" in res["stored"]
    assert record_differences(whole_b, read_record(b)) == []
    with pytest.raises(RecordError, match="which borrows from it"):
        compact_record(a, [b])


def test_a_full_record_written_from_a_compacted_ones_meta_borrows_nothing(tmp_path):
    base = _write(tmp_path / "records" / "run_0007.npz")
    rec = _write(tmp_path / "defs" / "x" / "run_0007.npz")
    compact_record(rec, [base])
    r = read_record(rec)
    out = write_record(tmp_path / "again" / "run_0007.npz", meta=r.meta, frames=r.frames,
                       clusters=r.clusters, radius=r.radius, fixed=r.fixed,
                       preparation=r.preparation, pictures=r.pictures)
    assert "borrowed" not in read_meta(out)
    assert record_differences(r, read_record(out)) == []
    assert json.loads(json.dumps(read_meta(out)))["seed"] == 7


def test_a_link_to_a_record_that_borrows_reads_it_beside_its_target(tmp_path):
    """The sources are named relative to the record itself: a symbolic link to it elsewhere (as
    `make figures RUNS=n` links records) reads the same record."""
    base = _write(tmp_path / "records" / "run_0007.npz")
    rec = _write(tmp_path / "defs" / "x" / "run_0007.npz", z_shift=1.0)
    whole = read_record(rec)
    compact_record(rec, [base])
    (tmp_path / "elsewhere").mkdir()
    link = tmp_path / "elsewhere" / "run_0007.npz"
    link.symlink_to(rec)
    assert record_differences(whole, read_record(link)) == []


def test_tiltpile_info_says_what_a_record_borrows(tmp_path):
    from tiltpile.view.info.records import record_info

    base = _write(tmp_path / "records" / "run_0007.npz", end_reason="slide", end_theta_deg=20.0)
    rec = _write(tmp_path / "defs" / "x" / "run_0007.npz", z_shift=1.0, end_reason="slide",
                 end_theta_deg=20.0)
    assert "borrows" not in record_info(rec)
    res = compact_record(rec, [base])
    line = [s for s in record_info(rec).splitlines() if s.startswith("borrows")]
    assert line == [f"borrows    {len(res['borrowed'])} piece(s) from ../../records/run_0007.npz "
                    "(held bit for bit there, checked when read)"]


def test_a_compacted_record_that_would_not_read_back_the_same_is_not_written(tmp_path, monkeypatch):
    """The check after writing: were a borrowed piece to come back other than it was (here a
    reader made to lose the last bit of a column), the record stays as it was and no temporary
    is left."""
    from tiltpile import record

    base = _write(tmp_path / "records" / "run_0007.npz")
    rec = _write(tmp_path / "defs" / "x" / "run_0007.npz", z_shift=1.0)
    before = rec.read_bytes()
    real = record._Lender.column

    def off_by_one_ulp(self, table, column, dtype):
        a = real(self, table, column, dtype)
        return np.nextafter(a, np.inf) if column == "theta_deg" else a

    monkeypatch.setattr(record._Lender, "column", off_by_one_ulp)
    with pytest.raises(RecordError, match=r"does not read back as it was \(frames\.theta_deg\)"):
        compact_record(rec, [base])
    assert rec.read_bytes() == before
    assert sorted(p.name for p in rec.parent.iterdir()) == ["run_0007.npz"]
