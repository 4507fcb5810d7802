"""Records at other analysis parameters (``tiltpile record --params``, ``write_records(params=)``):
they hold the tables and the pile pictures at those parameters, the figures computed from them
give the numbers the run files give at the same parameters, they are up to date only at their
own parameters, one parameter set per directory, and the loader serves them only when asked for
their parameters, refusing others in one line naming what the records hold."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pandas as pd
import pytest
from makehelpers import MAKE_ENV

from tiltpile.analysis.observables import load_run_observables, table_params
from tiltpile.figures import data
from tiltpile.figures.records import (DROPPED_CLUSTER_COLUMNS, check_params, picture_frames,
                                      record_status, write_records)
from tiltpile.figures.same_piles import FIGURES, figure_documents
from tiltpile.record import RecordError, read_meta, read_record, record_files, write_record

ROOT = Path(__file__).resolve().parents[2]
# the study's "mixed-stride-2" kind of definition: z, rattlers, clusters and rigidity on a contact
# list, losses by force, every second stored frame (so the pictures' frames differ from the
# defaults' on the smoke piles, and the rows from the stored frames)
PARAMS = {"contact_rule": "gap:0.005", "lost_rule": "force", "frame_stride": 2}
FAST = {"delta_bootstrap": 19}        # Fig. 5's resamples: seconds, not a minute


def _cli(*args) -> int:
    from tiltpile.cli import main
    return main([str(a) for a in args])


def _copy(src: Path, dst: Path) -> Path:
    dst.mkdir(parents=True, exist_ok=True)
    for p in record_files(src):
        shutil.copy2(p, dst / p.name)
    return dst


@pytest.fixture(scope="module")
def written(smoke_ensemble, tmp_path_factory):
    """The smoke ensemble's records at the default parameters and at PARAMS, each directory
    holding the records alone."""
    root = tmp_path_factory.mktemp("records_params")
    write_records(smoke_ensemble, root / "default", workers=1, progress=False)
    table = write_records(smoke_ensemble, root / "params", workers=1, progress=False,
                          params=PARAMS)
    assert list(table["status"]) == ["written"] * 3
    return {"default": _copy(root / "default", root / "only-default"),
            "params": _copy(root / "params", root / "only-params"),
            "written": root / "params"}


@pytest.mark.slow
def test_records_hold_the_tables_and_pictures_at_their_parameters(smoke_ensemble, written):
    from tiltpile.store import open_run

    moved = False
    for path in record_files(written["params"]):
        rec = read_record(path)
        assert rec.meta["analysis_params"] == json.loads(json.dumps(table_params(**PARAMS)))
        run = smoke_ensemble / f"{path.stem}.h5"
        frames, clusters = load_run_observables(run, **PARAMS)
        pd.testing.assert_frame_equal(rec.frames, frames, check_exact=True)
        pd.testing.assert_frame_equal(rec.clusters,
                                      clusters.drop(columns=list(DROPPED_CLUSTER_COLUMNS)),
                                      check_exact=True)
        with open_run(run) as r:
            assert len(frames) == (r.n_frames + 1) // 2       # every second stored frame
            assert rec.picture_frames == picture_frames(frames, rec.seed, r.n_frames)
        default = read_record(written["default"] / path.name).picture_frames
        moved |= rec.picture_frames != default
    # the pictures' frames move with the parameters: the default records' would not serve them
    assert moved


@pytest.mark.slow
def test_figures_from_records_at_params_are_those_of_the_run_files(smoke_ensemble, written):
    """Every figure's numbers, as its notebook computes them (the pile pictures' counts of Figs.
    3 and 7 included), from the records at PARAMS and from the run files at PARAMS."""
    recs = data.load(written["params"], "smoke", **PARAMS)
    runs = data.load(smoke_ensemble, "smoke", **PARAMS)
    assert recs.records and not runs.records and recs.meta == runs.meta
    a = figure_documents(recs, FIGURES, ROOT / "notebooks", {**PARAMS, **FAST})
    b = figure_documents(runs, FIGURES, ROOT / "notebooks", {**PARAMS, **FAST})
    assert list(a) == list(FIGURES)
    for stem in FIGURES:
        assert a[stem]["numbers"] == b[stem]["numbers"], stem
    assert a["fig7_rigidity"]["numbers"]["sample"]["largest_size"] > 0    # a picture was read
    assert a["fig3_clusters_failure"]["analysis"]["contact_rule"] == "gap:0.005"
    # the default records give other numbers: the records at PARAMS hold other tables
    d = figure_documents(data.load(written["default"], "smoke"), ("fig7_rigidity",),
                         ROOT / "notebooks")
    assert d["fig7_rigidity"]["numbers"] != a["fig7_rigidity"]["numbers"]


@pytest.mark.slow
def test_the_loader_serves_records_only_at_their_parameters(written, tmp_path):
    ens = data.load(written["params"], "smoke", **PARAMS)
    assert sorted(ens.records) == ens.seeds == [1, 2, 3]
    one_line = r"[^\n]*"
    with pytest.raises(RecordError, match=r"records hold the tables at analysis parameters "
                       r"contact_rule='gap:0.005', lost_rule='force', frame_stride=2; "
                       r"contact_rule='force', frame_stride=1, lost_rule=None needs the run files"
                       + one_line + "$"):
        data.load(written["params"], "smoke")
    with pytest.raises(RecordError, match=r"frame_stride=2; cutoff=0.03 needs the run files"):
        data.load(written["params"], "smoke", cutoff=0.03, **PARAMS)
    with pytest.raises(RecordError, match=r"records hold the tables at the default analysis "
                       r"parameters; contact_rule='gap:0.005', frame_stride=2, lost_rule='force' "
                       "needs the run files"):
        data.load(written["default"], "smoke", **PARAMS)
    # one directory, two parameter sets: refused whatever is asked
    mixed = _copy(written["default"], tmp_path / "mixed")
    shutil.copy2(written["params"] / "run_0002.npz", mixed / "run_0002.npz")
    for asked in ({}, PARAMS):
        with pytest.raises(RecordError, match=r"mixes records of several analysis parameter sets "
                           r"\(run_0001.npz: the default analysis parameters; run_0002.npz: "
                           r"analysis parameters contact_rule='gap:0.005'"):
            data.load(mixed, "smoke", **asked)


@pytest.mark.slow
def test_a_parameter_a_record_predates_counts_as_its_default(smoke_ensemble, written, tmp_path):
    """A record written before contact_rule, lost_rule and frame_stride existed (as the committed
    paper records were) holds the tables at the defaults: served at the defaults, refused at
    PARAMS, up to date at the defaults and foreign to a directory of PARAMS."""
    old = tmp_path / "old"
    for path in record_files(written["default"]):
        r = read_record(path)
        params = {k: v for k, v in r.meta["analysis_params"].items()
                  if k not in ("contact_rule", "lost_rule", "frame_stride")}
        write_record(old / path.name, meta=dict(r.meta, analysis_params=params), frames=r.frames,
                     clusters=r.clusters, radius=r.radius, fixed=r.fixed,
                     preparation=r.preparation, pictures=r.pictures)
    before = {p.name: p.read_bytes() for p in record_files(old)}
    assert record_status(smoke_ensemble, old)["fresh"].all()
    assert not record_status(smoke_ensemble, old, PARAMS)["fresh"].any()
    pd.testing.assert_frame_equal(data.load(old, "smoke").frames,
                                  data.load(written["default"], "smoke").frames, check_exact=True)
    with pytest.raises(RecordError, match="records hold the tables at the default analysis"):
        data.load(old, "smoke", **PARAMS)
    assert write_records(smoke_ensemble, old, workers=1, progress=False)["status"].eq(
        "up to date").all()
    assert {p.name: p.read_bytes() for p in record_files(old)} == before
    with pytest.raises(RecordError, match="one records directory holds one parameter set"):
        write_records(smoke_ensemble, old, workers=1, progress=False, params=PARAMS)


@pytest.mark.slow
def test_up_to_date_compares_the_parameters(smoke_ensemble, written, capsys):
    out = written["written"]
    before = {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in record_files(out)}
    assert record_status(smoke_ensemble, out, PARAMS)["fresh"].all()
    assert not record_status(smoke_ensemble, out)["fresh"].any()
    assert not record_status(smoke_ensemble, out, {"contact_rule": "gap:0.005",
                                                   "lost_rule": "force"})["fresh"].any()
    text = json.dumps(PARAMS)
    assert _cli("record", smoke_ensemble, "--out", out, "--params", text, "--quiet") == 0
    assert capsys.readouterr().out.count(" up to date ") == 3
    # the same parameters written otherwise (key order, a default named) are the same set
    same = json.dumps({"frame_stride": 2, "lost_rule": "force", "cutoff": 0.02,
                       "contact_rule": "gap:0.005"})
    assert _cli("record", smoke_ensemble, "--out", out, "--params", same, "--quiet") == 0
    assert capsys.readouterr().out.count(" up to date ") == 3
    assert {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in record_files(out)} == before
    # a stale one is rewritten at its directory's parameters, byte for byte as before
    (out / "run_0003.npz").write_bytes(b"garbage")
    assert _cli("record", smoke_ensemble, "--out", out, "--params", text, "--quiet") == 0
    assert "run_0003.npz  written" in capsys.readouterr().out
    assert (out / "run_0003.npz").read_bytes() == before["run_0003.npz"][0]
    # another parameter set into this directory, or PARAMS into the defaults': refused, untouched
    for where, params in ((out, None), (out, '{"contact_rule": "gap:0.005"}'),
                          (written["default"], text)):
        was = {p.name: p.read_bytes() for p in record_files(where)}
        assert _cli("record", smoke_ensemble, "--out", where, "--quiet",
                    *(["--params", params] if params else [])) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("tiltpile record: error:") and "\n" not in err, err
        assert "one records directory holds one parameter set" in err
        assert {p.name: p.read_bytes() for p in record_files(where)} == was
    assert read_meta(out / "run_0001.npz")["analysis_params"]["frame_stride"] == 2


# ---------------------------------------------------------------------------------------------
# fast: --params refused in one line before anything is read or written; make records PARAMS=


@pytest.mark.parametrize("text, match", [
    ('{"contact_rule": "gap:0.005",', "not JSON"),
    ('["contact_rule"]', "give a JSON object of analysis parameters"),
    ('{"contact": "force"}', "contact: not analysis parameters of the tables"),
    ('{"slide_ke": 0.001}', "slide_ke: parameters of the per-run table"),
    ('{"contact_rule": "gap:-1"}', "a contact rule is"),
    ('{"cutoff": "0.03"}', "cutoff must be a number"),
    ('{"cutoff": 1.5}', "cutoff must be in (0, 1)"),
    ('{"frame_stride": 2.0}', "frame_stride must be an integer"),
    ('{"min_contacts": true}', "min_contacts must be an integer"),
    ('{"ray_spacing": 0}', "ray_spacing must be > 0"),
    ('{"eps": 1}', "eps must be None or in [0, 1)"),
    ('{"lost_rule": 3}', "lost_rule must be a string or null"),
])
def test_bad_params_are_refused_in_one_line(tmp_path, capsys, text, match):
    d = tmp_path / "runs"
    d.mkdir()
    (d / "run_0000.h5").write_bytes(b"")       # never opened: --params is refused first
    out = tmp_path / "records"
    assert _cli("record", d, "--out", out, "--params", text) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("tiltpile record: error: --params") and "\n" not in err, err
    assert match in err, err
    assert not out.exists()


def test_check_params_gives_the_full_table_parameters():
    assert check_params(None) == check_params({}) == table_params()
    p = check_params({"contact_rule": "touching", "eps": 0.1})
    assert p == dict(table_params(), contact_rule="touching", eps=0.1)
    assert "slide_ke" not in p


def _make_n(*args):
    return subprocess.run(["make", "-n", "records", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=60, env=MAKE_ENV)


def test_make_records_passes_params_into_a_directory_of_its_own(tmp_path):
    params = '{"contact_rule": "gap:0.00218", "lost_rule": "force"}'
    r = _make_n("PRESET=smoke", f"DATA={tmp_path}/runs", f"PARAMS={params}",
                f"RECORDS={tmp_path}/gap")
    assert r.returncode == 0, r.stderr
    assert f"tiltpile record {tmp_path}/runs --out {tmp_path}/gap" in r.stdout
    assert f"--params '{params}'" in r.stdout
    plain = _make_n("PRESET=smoke", f"DATA={tmp_path}/runs")
    assert plain.returncode == 0 and "--params" not in plain.stdout
    # PARAMS without RECORDS would write into the preset's records: stopped before anything runs
    r = _make_n("PRESET=smoke", f"DATA={tmp_path}/runs", f"PARAMS={params}")
    assert r.returncode != 0 and "tiltpile record" not in r.stdout
    assert "give RECORDS=dir, a directory of its own" in r.stderr
