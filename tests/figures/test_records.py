"""Records of the smoke ensemble (tiltpile.figures.records, ``tiltpile record``): a directory
holding only the records gives the same Ensemble and the same numbers of every figure as the run
files; ``tiltpile record`` is idempotent; a stale, damaged or foreign record is rewritten or
refused in one line; the Makefile builds from records without running an ensemble."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from makehelpers import MAKE_ENV

from tiltpile.figures import build, data, fig2, fig3, fig4, fig5, snapshot, style
from tiltpile.figures.records import (DROPPED_CLUSTER_COLUMNS, picture_frames, write_record_of,
                                      write_records)
from tiltpile.record import RecordError, read_meta, read_record, record_files, write_record

ROOT = Path(__file__).resolve().parents[2]
FIGURES = tuple(build.MODULES.values())     # every figure


def _cli(*args) -> int:
    from tiltpile.cli import main
    return main([str(a) for a in args])


@pytest.fixture(scope="module")
def records_only(smoke_ensemble, tmp_path_factory):
    """The smoke ensemble's records, copied alone into a new directory."""
    written = tmp_path_factory.mktemp("records_written")
    write_records(smoke_ensemble, written, workers=1, progress=False)
    only = tmp_path_factory.mktemp("records_only")
    for p in record_files(written):
        shutil.copy2(p, only / p.name)
    return only


@pytest.fixture(scope="module")
def both(smoke_ensemble, records_only):
    """(from the run files, from the records), as the notebooks load them."""
    kw = {"cutoff": 0.02, "lost_gap": None}
    return (data.load_ensemble(smoke_ensemble, "smoke", **kw),
            data.load_ensemble(records_only, "smoke", **kw))


def _same_tree(a, b, where=""):
    """Equal numbers, arrays, DataFrames (NaN equal to NaN), recursively."""
    if isinstance(a, pd.DataFrame):
        pd.testing.assert_frame_equal(a, b, check_exact=True, obj=where)
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            _same_tree(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, (list, tuple)) and not isinstance(a, str):
        assert len(a) == len(b), where
        try:                                   # a list of numbers at once
            x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        except (TypeError, ValueError):
            for i, (x, y) in enumerate(zip(a, b)):
                _same_tree(x, y, f"{where}[{i}]")
        else:
            np.testing.assert_array_equal(x, y, err_msg=where)
    elif isinstance(a, (np.ndarray, float, np.floating)):
        np.testing.assert_array_equal(a, b, err_msg=where)
    elif dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            _same_tree(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    else:
        assert a == b, where


# ---------------------------------------------------------------------------------------------
# without run files: the same Ensemble, the same figures


@pytest.mark.slow
def test_records_give_the_same_ensemble(both, records_only):
    runs, recs = both
    assert recs.records and sorted(recs.records) == recs.seeds == runs.seeds == [1, 2, 3]
    assert not list(records_only.glob("*.h5"))
    pd.testing.assert_frame_equal(recs.frames, runs.frames, check_exact=True)
    pd.testing.assert_frame_equal(recs.clusters,
                                  runs.clusters.drop(columns=list(DROPPED_CLUSTER_COLUMNS)),
                                  check_exact=True)
    assert recs.meta == runs.meta and recs.meta["cost"]["sweeps_per_run"] > 0
    assert recs.config == runs.config


@pytest.mark.slow
@pytest.mark.parametrize("module", FIGURES, ids=[m.__name__.rsplit(".", 1)[1] for m in FIGURES])
def test_every_figure_computes_the_same_numbers_from_records(both, records_only, module):
    runs, recs = both
    kw = {"delta_bootstrap": 19} if module is fig5 else {}    # fewer resamples: seconds, not a minute
    n_runs, d_runs = module.compute(runs, **kw)
    n_recs, d_recs = module.compute(recs, **kw)
    assert json.dumps(style.jsonable(n_recs), sort_keys=True) == \
        json.dumps(style.jsonable(n_runs), sort_keys=True)
    _same_tree(d_recs, d_runs, module.__name__)    # the pile pictures included
    # with the tables holding only the columns the figure declares (as the notebooks load
    # them): the same numbers, so that READS names every column the figure's numbers depend on
    only = data.load(records_only, "smoke", module.READS, cutoff=0.02, lost_gap=None)
    assert set(only.frames.columns) == set(module.READS.frames)
    n_only, _ = module.compute(only, **kw)
    assert json.dumps(style.jsonable(n_only), sort_keys=True) == \
        json.dumps(style.jsonable(n_runs), sort_keys=True)


@pytest.mark.slow
def test_records_hold_the_pictures_of_every_run(both, smoke_ensemble):
    runs, recs = both
    for seed in runs.seeds:
        frames = picture_frames(runs.frames, seed)
        n = int((runs.frames["run"] == seed).sum())
        for k in frames:
            if k + 1 in frames or k + 1 == n:
                _same_tree(data.snapshot(recs, seed, k), data.snapshot(runs, seed, k), f"{seed}:{k}")
        missing = next(k for k in range(n) if k not in frames)
        with pytest.raises(RecordError, match=f"frame {missing} of run {seed} is not in its record"):
            data.snapshot(recs, seed, missing)


@pytest.mark.slow
def test_a_record_traces_to_its_run_file(smoke_ensemble, records_only):
    from tiltpile.store import open_run
    for path in record_files(records_only):
        meta = read_meta(path)
        with open_run(smoke_ensemble / f"{path.stem}.h5") as r:
            assert meta["seed"] == r.seed and meta["config_hash"] == r.config_hash
            assert meta["cost"] == r.cost and meta["n_frames"] == r.n_frames
            assert meta["end_reason"] == r.end_reason and meta["end_theta_deg"] == r.end_theta_deg
            assert meta["source"]["frames_sha256"] == r.frames_digest()
            assert meta["source"]["attrs_sha256"] == r.attrs_digest
            assert r.attrs_digest is not None
            assert meta["health"]["frames"] == r.health["frames"]
        assert path.stat().st_size < 400_000          # smoke: ~0.15 MB


@pytest.mark.slow
def test_records_of_another_analysis_are_refused_in_one_line(both, records_only, tmp_path):
    _, recs = both
    with pytest.raises(RecordError, match=r"default analysis parameters; cutoff=0.03 needs the run"):
        data.load_ensemble(records_only, "smoke", cutoff=0.03)
    # a record of other table code (written by another tiltpile)
    for p in record_files(records_only):
        shutil.copy2(p, tmp_path / p.name)
    first = record_files(tmp_path)[0]
    r = read_record(first)
    legacy = {k: v for k, v in r.meta.items() if k != "column_code"}
    write_record(first, meta=dict(legacy, analysis_code="0" * 16),
                 frames=r.frames, clusters=r.clusters, radius=r.radius, fixed=r.fixed,
                 preparation=r.preparation, pictures=r.pictures)
    with pytest.raises(RecordError) as e:
        data.load_ensemble(tmp_path, "smoke")
    assert "table code 0000000000000000" in str(e.value) and "\n" not in str(e.value)
    # a record whose column z other code computed: refused by a reader of z, naming it, and
    # served to a reader of other columns
    codes = json.loads(json.dumps(r.meta["column_code"]))
    codes["frames"]["z"] = "0" * 16
    write_record(first, meta=dict(r.meta, column_code=codes),
                 frames=r.frames, clusters=r.clusters, radius=r.radius, fixed=r.fixed,
                 preparation=r.preparation, pictures=r.pictures)
    with pytest.raises(RecordError) as e:
        data.load(tmp_path, "smoke", fig4.READS)
    assert str(e.value).startswith(f"Fig. 4 ({tmp_path}) needs column frames.z; its records hold "
                                   "it as other code computed it") and "\n" not in str(e.value)
    assert "the run files are needed" in str(e.value)
    with pytest.raises(RecordError, match="needs column frames.z"):
        data.load(tmp_path, "smoke")                  # every column
    ens = data.load(tmp_path, "smoke", fig5.READS)
    assert list(ens.frames.columns) == list(fig5.READS.frames) and "z" not in ens.frames
    # a column the records predate (a record written before it was added)
    write_record(first, meta=r.meta, frames=r.frames.drop(columns="theta_m"),
                 clusters=r.clusters, radius=r.radius, fixed=r.fixed,
                 preparation=r.preparation, pictures=r.pictures)
    with pytest.raises(RecordError, match=r"^Fig. 2 \(.*\) needs column frames.theta_m; its "
                                          r"records predate it; the run files are needed"):
        data.load(tmp_path, "smoke", fig2.READS)
    assert len(data.load(tmp_path, "smoke", fig4.READS).frames) == len(recs.frames)
    # a column the writer leaves out
    with pytest.raises(RecordError, match="needs column clusters.x_com; its records leave it out"):
        data.load(tmp_path, "smoke", data.Reads("a study", clusters=("x_com",)))
    # a damaged record: a flipped bit in the pictures, which no table needs, is seen too
    shutil.copy2(record_files(records_only)[0], first)
    with zipfile.ZipFile(first) as zf:
        info = zf.getinfo("pictures__force.npy")
    raw = bytearray(first.read_bytes())
    raw[info.header_offset + 30 + len(info.filename) + info.compress_size // 2] ^= 0x08
    first.write_bytes(bytes(raw))
    with pytest.raises(RecordError, match="damaged record"):
        data.load_ensemble(tmp_path, "smoke")


@pytest.mark.slow
def test_notebooks_run_from_records(records_only, both, tmp_path):
    """One notebook end to end (papermill, as `make figures` runs it) on the records alone: its
    JSON is what the run files give."""
    import papermill as pm
    runs, _ = both
    nb = ROOT / "notebooks" / "fig3_clusters_failure.ipynb"
    pm.execute_notebook(str(nb), str(tmp_path / "out.ipynb"), kernel_name="tiltpile", cwd=str(ROOT),
                        progress_bar=False, log_output=False,
                        parameters={"data_dir": str(records_only), "preset": "smoke",
                                    "figures_dir": str(tmp_path)})
    doc = json.loads((tmp_path / "fig3_clusters_failure.json").read_text())
    numbers, _ = fig3.compute(runs)
    assert doc["numbers"] == json.loads(json.dumps(style.jsonable(numbers)))
    assert {k: v for k, v in doc.items() if k not in ("figure", "numbers")} == \
        json.loads(json.dumps(style.jsonable(style.without_wall_clock(runs.meta))))


# ---------------------------------------------------------------------------------------------
# the command


@pytest.mark.slow
def test_record_command_is_idempotent(smoke_ensemble, tmp_path, capsys, monkeypatch):
    out = tmp_path / "records"
    assert _cli("record", smoke_ensemble, "--out", out, "--workers", 1, "--quiet") == 0
    assert capsys.readouterr().out.count(" written ") == 3
    before = {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in record_files(out)}
    assert sorted(before) == ["run_0001.npz", "run_0002.npz", "run_0003.npz"]
    assert _cli("record", smoke_ensemble, "--out", out, "--quiet") == 0
    assert capsys.readouterr().out.count(" up to date ") == 3
    assert {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in record_files(out)} == before
    # --force rewrites them, byte for byte the same; nothing else is left in the directory
    assert _cli("record", smoke_ensemble, "--out", out, "--force", "--quiet") == 0
    assert {p.name: p.read_bytes() for p in record_files(out)} == {k: v[0] for k, v in before.items()}
    assert sorted(p.name for p in out.iterdir()) == sorted(before)
    # a damaged or stale record is rewritten, the others are left alone
    (out / "run_0002.npz").write_bytes(b"garbage")
    assert _cli("record", smoke_ensemble, "--out", out, "--quiet") == 0
    text = capsys.readouterr().out
    assert "run_0002.npz  written" in text and text.count(" up to date ") == 2
    assert (out / "run_0002.npz").read_bytes() == before["run_0002.npz"][0]
    # a record above the budget of a committed record is written, with a warning naming it
    import tiltpile.cli.record as cli_record

    budget = len(before["run_0002.npz"][0]) - 1
    monkeypatch.setattr(cli_record, "RECORD_BUDGET_BYTES", budget)
    assert _cli("record", smoke_ensemble, "--out", out, "--quiet") == 0
    warned = [line for line in capsys.readouterr().err.splitlines()
              if "a committed record may weigh" in line]
    over = [n for n, (data, _) in sorted(before.items()) if len(data) > budget]
    assert "run_0002.npz" in over
    assert [line.split("warning: ")[1].split(" is ")[0] for line in warned] == [str(out / n) for n in over]


@pytest.mark.slow
def test_a_record_of_a_whole_table_digest_serves_and_stays_current(smoke_ensemble, records_only,
                                                                  tmp_path, monkeypatch):
    """A record written with one digest of the whole table code (as the committed paper records
    were) is read through legacy_codes: served to every figure and up to date for `tiltpile
    record` while its columns' code is the entry's, bytes untouched; without an entry it is
    refused and rewritten."""
    from tiltpile.analysis import legacy_codes
    from tiltpile.analysis.tables import column_code
    from tiltpile.figures.records import record_status

    for p in record_files(records_only):
        r = read_record(p)
        meta = {k: v for k, v in r.meta.items() if k != "column_code"}
        write_record(tmp_path / p.name, meta=dict(meta, analysis_code="f" * 16), frames=r.frames,
                     clusters=r.clusters, radius=r.radius, fixed=r.fixed,
                     preparation=r.preparation, pictures=r.pictures)
    before = {p.name: p.read_bytes() for p in record_files(tmp_path)}
    monkeypatch.setattr(legacy_codes, "LEGACY", {"f" * 16: column_code()})
    assert record_status(smoke_ensemble, tmp_path)["fresh"].all()
    for module in FIGURES:
        ens = data.load(tmp_path, "smoke", module.READS)
        assert len(ens.frames) == len(data.load(records_only, "smoke", module.READS).frames)
    assert {p.name: p.read_bytes() for p in record_files(tmp_path)} == before
    monkeypatch.setattr(legacy_codes, "LEGACY", {})
    assert not record_status(smoke_ensemble, tmp_path)["fresh"].any()
    with pytest.raises(RecordError, match="a record of table code f{16}, whose columns"):
        data.load(tmp_path, "smoke", fig2.READS)


@pytest.mark.slow
def test_record_command_refuses_bad_input_in_one_line(smoke_ensemble, tmp_path, capsys):
    def refused(*args, match):
        assert _cli("record", *args) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("tiltpile record: error:") and "\n" not in err and match in err, err

    refused(tmp_path / "nothing", "--out", tmp_path / "r", match="no such ensemble directory")
    (tmp_path / "empty").mkdir()
    refused(tmp_path / "empty", "--out", tmp_path / "r", match="no finished run files")
    refused(smoke_ensemble, "--out", smoke_ensemble, match="their own directory")
    refused(smoke_ensemble, "--out", smoke_ensemble / "observables", match="their own directory")
    refused(smoke_ensemble, "--out", "/proc/records", match="not writable")
    refused(smoke_ensemble, "--out", tmp_path / "r", "--workers", 0, match="--workers")
    # a records directory of another configuration
    foreign = tmp_path / "foreign"
    path = write_record_of(smoke_ensemble / "run_0001.h5", foreign)
    r = read_record(path)
    write_record(path, meta=dict(r.meta, config_hash="0" * 64), frames=r.frames,
                 clusters=r.clusters, radius=r.radius, fixed=r.fixed, pictures=r.pictures)
    refused(smoke_ensemble, "--out", foreign, match="another configuration")
    assert sorted(p.name for p in foreign.iterdir()) == ["run_0001.npz"]
    assert not (tmp_path / "r").exists()


# ---------------------------------------------------------------------------------------------
# fast: the pictures' frames, the Makefile's choice


def test_picture_frames_are_the_figures_choices_with_their_successors():
    theta = 0.1 * np.arange(12)
    lost = np.r_[[0.001] * 8, 0.05, 0.08, 0.001, np.nan]
    from tiltpile.analysis import resegment
    f = resegment(pd.DataFrame({"run": 4, "frame": np.arange(12), "theta_deg": theta,
                                "lost_fraction": lost, "n_active": 1000}), cutoff=0.02)
    a = snapshot.pick_avalanche_frame(f, 4)
    b = snapshot.frame_before_onset(f, 4)
    assert (a, b) == (9, 5)           # most lost while avalanching; 0.3 deg before the onset at 0.8
    assert picture_frames(f, 4) == [5, 6, 9, 10]
    g = f[f["frame"] <= 9]            # the chosen frame is the last: no successor
    assert picture_frames(g, 4) == [5, 6, 9]


def _make_n(*args) -> str:
    r = subprocess.run(["make", "-n", "figures", *args], cwd=ROOT, capture_output=True, text=True,
                       timeout=60, env=MAKE_ENV)
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_make_builds_from_records_when_there_are_no_run_files(tmp_path):
    recs, empty = tmp_path / "records", tmp_path / "runs"
    recs.mkdir()
    empty.mkdir()
    (recs / "run_0000.npz").write_bytes(b"")
    common = [f"RECORDS={recs}", f"FIGURES={tmp_path}/figs", f"EXECUTED={tmp_path}/executed",
              f"REPORT={tmp_path}/figs/REPRODUCTION.md", "PRESET=paper"]
    plan = _make_n(f"DATA={empty}", *common)
    assert "tiltpile ensemble" not in plan and "run_diagnostics" not in plan
    assert f"-p data_dir {recs} " in plan and "sha256sum run_0000.npz)" in plan
    # with run files: the ensemble as before, then the existing records brought up to date
    (empty / "run_0000.h5").write_bytes(b"")
    plan = _make_n(f"DATA={empty}", *common)
    assert "tiltpile ensemble --preset paper" in plan and f"-p data_dir {empty} " in plan
    assert f"tiltpile record {empty} --out {recs}" in plan
    plan = _make_n(f"DATA={empty}", "FROM=records", *common)
    assert "tiltpile ensemble" not in plan and f"-p data_dir {recs} " in plan


def test_runs_takes_the_first_records_by_seed(tmp_path):
    """RUNS=M from records: the notebooks read links to the first M records by seed (the committed
    figures of an earlier stage, while later records sit beside them), the stamp hashes those
    alone; M at or above the number of records reads the directory itself; a RUNS that is not a
    whole number >= 1 stops make in one line, before anything runs."""
    recs, empty = tmp_path / "records", tmp_path / "runs"
    recs.mkdir()
    empty.mkdir()
    for seed in (3, 0, 12, 1):
        (recs / f"run_{seed:04d}.npz").write_bytes(bytes([seed]))
    ex = tmp_path / "executed"
    common = [f"RECORDS={recs}", f"FIGURES={tmp_path}/figs", f"EXECUTED={ex}", f"DATA={empty}",
              f"REPORT={tmp_path}/figs/REPRODUCTION.md", "PRESET=paper"]
    plan = _make_n("RUNS=4", *common)
    assert f"-p data_dir {recs} " in plan and f"{ex}/records-" not in plan
    plan = _make_n("RUNS=2", *common)
    assert f"-p data_dir {ex}/records-2 " in plan and f"-p data_dir {recs} " not in plan
    assert "first 2 of the 4 records" in plan
    # the stamp target itself, run: the links and the stamp name run_0000 and run_0001 alone
    r = subprocess.run(["make", f"{ex}/.records", "RUNS=2", *common], cwd=ROOT,
                       capture_output=True, text=True, timeout=60, env=MAKE_ENV)
    assert r.returncode == 0, r.stderr
    links = sorted((ex / "records-2").iterdir())
    assert [p.name for p in links] == ["run_0000.npz", "run_0001.npz"]
    assert [p.resolve() for p in links] == [recs.resolve() / f"run_000{i}.npz" for i in (0, 1)]
    assert [line.split()[1] for line in (ex / ".records").read_text().splitlines()] == \
        ["run_0000.npz", "run_0001.npz"]
    for bad in ("0", "two", "1.5"):
        r = subprocess.run(["make", "-n", "figures", f"RUNS={bad}", *common], cwd=ROOT,
                           capture_output=True, text=True, timeout=60, env=MAKE_ENV)
        assert r.returncode != 0 and not r.stdout
        assert f"RUNS={bad}: give the number of runs, a whole number >= 1" in r.stderr


@pytest.mark.parametrize("preset", ["paper", "paper-fresh"])
def test_committed_figures_are_those_of_the_first_records(preset):
    """Each committed figure of a recorded preset is made of the first n_runs records by seed, so
    that `make figures PRESET=P RUNS=n_runs` rebuilds it from the committed records while records
    of later runs sit beside them."""
    recorded = [int(p.stem.split("_")[1]) for p in record_files(ROOT / "figures" / preset / "records")]
    jsons = sorted((ROOT / "figures" / preset).glob("fig*.json"))
    assert recorded and jsons
    for path in jsons:
        doc = json.loads(path.read_text())
        assert doc["seeds"] == recorded[: doc["n_runs"]], path.name
