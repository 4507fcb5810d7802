"""`make study` end to end at the smoke scale: a second key (scene.polydispersity, two values,
one run each) through the same command as the friction study, the structure of what it writes,
a rerun that computes nothing again, and bad keys and values refused with nothing written."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from makehelpers import MAKE_ENV

from tiltpile.cli import main
from tiltpile.figures.study import QUANTITIES

ROOT = Path(__file__).resolve().parents[2]


def _make(*args, timeout=600):
    return subprocess.run(["make", "--no-print-directory", "study", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout, env=MAKE_ENV)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    d = tmp_path_factory.mktemp("study")
    args = ("KEY=scene.polydispersity", "VALUES=0.1 0.3", "PRESET=smoke", "RUNS=1", "NAME=poly",
            f"DATA={d}/data", f"STUDY_FIGURES={d}/figures", "WORKERS=1")
    r = _make(*args)
    assert r.returncode == 0, r.stderr[-3000:]
    return d, args


def test_the_study_writes_its_figure_json_report_and_records(study):
    d, _ = study
    fig = d / "figures"
    assert {p.name for p in fig.iterdir()} == {"study.json", "study.png", "study.pdf", "study.md",
                                              "records"}
    doc = json.loads((fig / "study.json").read_text())
    assert doc["figure"] == "study"
    assert doc["study"]["key"] == "scene.polydispersity" and doc["study"]["history"] == "preset"
    n = doc["numbers"]
    assert n["labels"] == ["0.1", "0.3"] and n["values"] == [0.1, 0.3]
    assert n["mohr_coulomb"] is None       # not a friction study
    for label in n["labels"]:
        pv = n["per_value"][label]
        assert pv["n_runs"] == 1 and pv["seeds"] == [0] and pv["theta_rev_deg"] is None
        assert list(pv["numbers"]) == list(QUANTITIES)
        for q, c in pv["numbers"].items():
            assert {"estimate", "low", "high", "n"} <= set(c), q
        assert set(pv["per_run"]) == set(QUANTITIES) - {"delta"}
        # every number of a run that onsets, slides and stops is there
        assert all(c["estimate"] is not None for q, c in pv["numbers"].items()
                   if q != "theta_avalanche"), pv["numbers"]
        # the runs, their repose angles, records
        assert (d / "data" / label / "run_0000.h5").exists()
        assert (d / "data" / label / "repose.json").exists()
        assert (fig / "records" / label / "run_0000.npz").exists()
        assert json.loads((fig / "records" / label / "repose.json").read_text())["runs"][0]["seed"] == 0
    ens = {e["label"]: e for e in doc["ensembles"]}
    assert ens["0.1"]["config_hash"] != ens["0.3"]["config_hash"]
    md = (fig / "study.md").read_text()
    assert md.startswith("## Parameter study: scene.polydispersity (poly)")
    assert "| 0.1 | 1 | preset |" in md and "| 0.3 | 1 | preset |" in md


def test_a_rerun_computes_no_run_again(study):
    d, args = study
    runs = sorted((d / "data").glob("*/run_*.h5")) + sorted((d / "data").glob("*/repose.json"))
    before = {p: p.stat().st_mtime_ns for p in runs}
    r = _make(*args)
    assert r.returncode == 0, r.stderr[-3000:]
    assert {p: p.stat().st_mtime_ns for p in runs} == before


def test_without_the_run_files_the_study_is_rebuilt_from_its_records(study, tmp_path):
    import shutil

    d, args = study
    shutil.copytree(d / "figures" / "records", tmp_path / "figures" / "records")
    args = [a for a in args if not a.startswith(("DATA=", "STUDY_FIGURES="))]
    r = _make(*args, f"DATA={tmp_path}/nodata", f"STUDY_FIGURES={tmp_path}/figures")
    assert r.returncode == 0, r.stderr[-3000:]
    assert "from its records" in r.stderr and not (tmp_path / "nodata").exists()
    new = json.loads((tmp_path / "figures" / "study.json").read_text())["numbers"]
    assert new == json.loads((d / "figures" / "study.json").read_text())["numbers"]


def test_records_only_writes_the_done_values_and_runs_nothing(study, tmp_path):
    """RECORDS_ONLY=1 over the study's runs with a third value not run: the two done values'
    records, byte for byte the study's own, the third named, no run started, no study written."""
    d, args = study
    args = [a for a in args if not a.startswith(("VALUES=", "STUDY_FIGURES="))]
    r = _make(*args, "VALUES=0.1 0.3 0.2", f"STUDY_FIGURES={tmp_path}/figures", "RECORDS_ONLY=1")
    assert r.returncode == 0, r.stderr[-3000:]
    assert "scene.polydispersity = 0.2: not done yet" in r.stderr
    assert not (d / "data" / "0.2").exists() and not (tmp_path / "figures" / "study.json").exists()
    for label in ("0.1", "0.3"):
        mine = sorted((tmp_path / "figures" / "records" / label).iterdir())
        theirs = sorted((d / "figures" / "records" / label).iterdir())
        assert [p.name for p in mine] == [p.name for p in theirs] and mine
        assert all(a.read_bytes() == b.read_bytes() for a, b in zip(mine, theirs))


def test_records_of_another_configuration_are_refused(study, tmp_path):
    import shutil

    d, args = study
    shutil.copytree(d / "figures" / "records" / "0.1", tmp_path / "figures" / "records" / "0.1")
    r = _make("KEY=scene.polydispersity", "VALUES=0.1 0.3", "PRESET=default", "RUNS=1",
              f"DATA={tmp_path}/data", f"STUDY_FIGURES={tmp_path}/figures", timeout=60)
    assert r.returncode == 2 and "another configuration" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figures"]


@pytest.mark.parametrize("key, values, named", [
    ("scene.polydisperse", "0.1 0.3", "scene.polydisperse"),
    ("scene.polydispersity", "0.1 1.5", "scene.polydispersity = 1.5 is out of range"),
    ("scene.polydispersity", "0.1 much", "--values much"),
    ("scene.polydispersity", "0.1 0.10", "the same value"),
    ("protocol.pretilt_deg", "1 2", "list-valued"),
])
def test_a_bad_key_or_value_stops_before_anything_is_written(tmp_path, key, values, named):
    r = _make(f"KEY={key}", f"VALUES={values}", "PRESET=smoke", "RUNS=1",
              f"DATA={tmp_path}/data", f"STUDY_FIGURES={tmp_path}/figures", timeout=60)
    assert r.returncode != 0
    errors = [line for line in r.stderr.splitlines() if line.startswith("tiltpile study: error:")]
    assert len(errors) == 1 and named in errors[0], r.stderr
    assert list(tmp_path.iterdir()) == []


def test_the_command_refuses_a_bad_history_and_a_key_it_sets_itself(tmp_path, capsys):
    base = ["study", "--values", "0.2", "0.5", "--preset", "smoke", "--runs", "1", "--name", "x",
            "--data", str(tmp_path / "d"), "--figures", str(tmp_path / "f")]
    assert main(base + ["--key", "scene.mu", "--history", "repose-1"]) == 2
    assert "--history" in capsys.readouterr().err
    assert main(base[:2] + ["10", "16"] + base[4:] + ["--key", "protocol.theta_rev_deg",
                                                        "--history", "repose+1"]) == 2
    assert "sets the history itself" in capsys.readouterr().err
    assert main(base + ["--key", "scene.mu", "--name", "../x"]) == 2
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_the_history_follows_each_values_own_repose_angle(study, tmp_path):
    """HISTORY=repose+1 on the same two values: the smoke preset has no history, so the study's
    piles above are the fresh piles (copied, so that only the cycled runs are computed, ~1 min):
    each value's piles are cycled twice to its own repose angle + 1 deg, and the JSON says so."""
    import shutil

    from tiltpile import config
    from tiltpile.figures.study import history_amplitude, read_repose, repose_surface_mean

    d, _ = study
    data = tmp_path / "data"
    for label in ("0.1", "0.3"):
        shutil.copytree(d / "data" / label, data / f"{label}-fresh")
    args = ("KEY=scene.polydispersity", "VALUES=0.1 0.3", "PRESET=smoke", "RUNS=1", "NAME=polyh",
            "HISTORY=repose+1", f"DATA={data}", f"STUDY_FIGURES={tmp_path}/figures", "WORKERS=1")
    r = _make(*args)
    assert r.returncode == 0, r.stderr[-3000:]
    doc = json.loads((tmp_path / "figures" / "study.json").read_text())
    assert doc["study"]["history"] == "repose+1" and doc["study"]["history_offset_deg"] == 1.0
    for label in ("0.1", "0.3"):
        want = history_amplitude(repose_surface_mean(read_repose(data / f"{label}-fresh" / "repose.json")), 1.0)
        pv = doc["numbers"]["per_value"][label]
        assert pv["theta_rev_deg"] == want and pv["repose_piles"] == "fresh"
        cfg = config.load("smoke", None, [f"scene.polydispersity={label}"])
        run_cfg = json.loads((data / label / "ensemble.json").read_text())["config"]
        assert run_cfg["protocol"]["pretilt_deg"] == [want, -want, want, -want, want, 0.0]
        assert config.from_dict(run_cfg).scene == cfg.scene
    assert "cycled twice to its own fresh repose angle (surface) + 1 deg" in \
        (tmp_path / "figures" / "study.md").read_text()
