"""The solver study (``tiltpile solver-study``, tiltpile.studies.solver; issue 72) end to end on
tiny piles: 80 smoke grains tilted fast to 30 deg, 3 runs per setting, the committed setting
against one other (a cap of 300 sweeps) and one the health rules stop (dt = 0.5: the grains
overlap in the deposition). The plan refused in one line before anything runs, a health stop
recorded as a failed setting, a rerun that computes nothing again, a resume that runs only the
missing seed, a setting read from its records, the JSON's numbers against the comparisons and
records they come from, and a regression test of the chart's numbers."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tiltpile.cli import main
from tiltpile.studies import solver

ROOT = Path(__file__).resolve().parents[2]
TINY_SETS = ["scene.n=80", "scene.box_length=12", "protocol.theta_max_deg=30",
             "protocol.tilt_per_step_deg=0.05"]
TINY = ["--preset", "smoke", *(a for s in TINY_SETS for a in ("--set", s))]
SETTINGS = ("solver.max_iter=300", "solver.dt=0.5")
RUNS = 3


def _study(data, figures, *extra, runs=RUNS, only=",".join(SETTINGS)):
    cmd = [sys.executable, "-m", "tiltpile", "solver-study", "--data", str(data), "--figures",
           str(figures), "--runs", str(runs), "--only", only, "--workers", "1", "--quiet", *TINY,
           *extra]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    d = tmp_path_factory.mktemp("solver_study")
    r = _study(d / "data", d / "figures")
    assert r.returncode == 0, r.stderr[-3000:]
    return d, json.loads((d / "figures" / "solver_study.json").read_text()), r


def _by_name(doc):
    return {s["name"]: s for s in doc["numbers"]["settings"]}


# ----------------------------------------------------------------------------------------------
# the plan


def test_the_plan_is_the_studys_settings_each_one_key_off_the_committed_one():
    p = solver.plan()
    names = [e.setting.name for e in p.entries]
    assert names == ["reference", "solver.max_iter=300", "solver.tol=1e-4", "solver.tol=1e-5",
                     "solver.dt=0.02", "solver.sweep=random", "solver.sweep=alternating",
                     "solver.sweep=forward", "solver.max_iter=3000", "solver.dt=0.005",
                     "solver.max_iter=10000", "solver.tol=1e-7"]
    ref = p.reference.config
    assert p.preset == "default" and p.runs == 6 and ref.scene.n == 1000
    for e in p.entries[1:]:
        section, key = e.setting.key.split(".")
        differ = [k for k in ("sweep", "max_iter", "tol", "dt")
                  if getattr(e.config.solver, k) != getattr(ref.solver, k)]
        assert section == "solver" and differ == [key], e.setting
        assert str(getattr(e.config.solver, key)) == str(type(getattr(ref.solver, key))(
            e.setting.value)), e.setting
        assert e.setting.axis == solver.AXES[e.setting.key]
    assert len({e.config.hash() for e in p.entries}) == len(p.entries)


@pytest.mark.parametrize("args, named", [
    (["--only", "solver.bogus=3"], "unknown key solver.bogus"),
    (["--only", "solver.max_iter=300,solver.tol=5"], "solver.tol = 5.0 is out of range"),
    (["--only", "solver.sweep=zigzag"], "'zigzag' is not one of"),
    (["--only", "scene.mu=0.3"], "varies a solver.* key"),
    (["--only", "tighter"], "neither a setting of the study"),
    (["--only", "solver.tol=1e-5"], "is the configuration of reference"),   # smoke's own tol
    (["--set", "protocol.theta_max_deg=100"], "--set: protocol.theta_max_deg = 100.0 is out of range"),
    (["--runs", "0"], "--runs must be at least 1"),
    (["--runs-only", "--records-only"], "give one of them"),
    (["--runs-only", "--no-runs"], "give one of them"),
])
def test_a_bad_key_or_value_is_refused_in_one_line_before_anything_runs(tmp_path, capsys, args,
                                                                         named):
    base = ["solver-study", "--data", str(tmp_path / "data"), "--figures", str(tmp_path / "fig"),
            "--runs", "2", *TINY]
    if "--only" not in args:
        base += ["--only", "solver.max_iter=300"]
    assert main(base + args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tiltpile solver-study: error:") and named in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_a_directory_of_another_configuration_is_refused(tmp_path, capsys):
    (tmp_path / "data" / "reference").mkdir(parents=True)
    (tmp_path / "data" / "reference" / "ensemble.json").write_text(json.dumps(
        {"format": "tiltpile-ensemble/1", "config_hash": "0" * 64, "seeds": [], "runs": {},
         "invocations": []}))
    assert main(["solver-study", "--data", str(tmp_path / "data"), "--figures",
                 str(tmp_path / "fig"), "--only", "solver.max_iter=300", *TINY]) == 2
    assert "another configuration" in capsys.readouterr().err
    assert not (tmp_path / "fig").exists()


def test_stop_rules_are_read_from_the_manifests_errors():
    assert solver.stop_rule("SimulationError: health.energy_stop exceeded: ...") == "health.energy_stop"
    assert solver.stop_rule("SimulationError: 3 grains left the box at step 9") == "runaway"
    assert solver.stop_rule("SimulationError: non-finite positions or velocities") == "runaway"
    assert solver.stop_rule("RunWriteError: no space left on device") is None   # retried
    assert solver.stop_rule(None) is None


# ----------------------------------------------------------------------------------------------
# the study end to end


@pytest.mark.slow
def test_a_health_stop_is_a_failed_setting_not_a_crash(study):
    d, doc, r = study
    s = _by_name(doc)["solver.dt=0.5"]
    assert s["status"] == "failed" and s["seeds_done"] == [] and s["comparison"] is None
    assert [h["seed"] for h in s["health_stops"]] == [0, 1, 2]
    assert {h["rule"] for h in s["health_stops"]} == {"health.overlap_stop"}
    assert all(h["message"].startswith("SimulationError: health.overlap_stop exceeded")
               for h in s["health_stops"])
    # the manifest holds them as failed runs, the records directory their stops (no record)
    man = json.loads((d / "data" / "solver.dt=0.5" / "ensemble.json").read_text())
    assert {r_["status"] for r_ in man["runs"].values()} == {"failed"}
    runs = json.loads((d / "figures" / "records" / "solver.dt=0.5" / "runs.json").read_text())
    assert {v["stop"] for v in runs["runs"].values()} == {"health.overlap_stop"}
    assert not list((d / "figures" / "records" / "solver.dt=0.5").glob("run_*.npz"))
    point = next(p for p in doc["numbers"]["chart"] if p["name"] == "solver.dt=0.5")
    assert point["numbers_moved"] is None and point["claims_flipped"] is None
    assert "seed 0 stopped by health.overlap_stop" in r.stderr
    md = (d / "figures" / "solver_study.md").read_text()
    assert "Stopped by the health rules" in md and "seeds 0, 1, 2: health.overlap_stop" in md


@pytest.mark.slow
def test_the_jsons_numbers_are_those_of_its_comparisons_and_records(study):
    from tiltpile.record import read_meta
    from tiltpile.report.claims import CLAIMS

    d, doc, _ = study
    n = doc["numbers"]
    assert doc["figure"] == "solver_study" and doc["study"]["preset"] == "smoke"
    assert doc["study"]["settings"] == ["reference", *SETTINGS] and n["runs"] == RUNS
    ref, cap = _by_name(doc)["reference"], _by_name(doc)["solver.max_iter=300"]
    assert ref["status"] == cap["status"] == "done" and ref["committed"] and not cap["committed"]
    assert cap["seeds_compared"] == [0, 1, 2] and cap["solver"]["max_iter"] == 300
    # cost: the mean of the records' sweeps; seconds in core-hours
    for s in (ref, cap):
        rec = d / "figures" / "records" / s["name"]
        sweeps = [read_meta(rec / f"run_{k:04d}.npz")["cost"]["sweeps"] for k in range(RUNS)]
        assert s["cost"]["sweeps_per_run"] == pytest.approx(np.mean(sweeps))
        assert s["cost"]["core_hours_per_run"] == pytest.approx(s["cost"]["seconds_per_run"] / 3600)
    assert cap["cost"]["sweeps_per_run"] < ref["cost"]["sweeps_per_run"]   # a lower cap costs less
    # the comparison is same-piles' own, as written beside the study
    sp = json.loads((d / "figures" / "same-piles" / "solver.max_iter=300" / "same_piles.json").read_text())
    sig = [r_["sigma"] for r_ in sp["numbers"]]
    moved = sum(1 for x in sig if x is not None and abs(x) > 2.0)
    assert cap["comparison"]["n_moved"] == sp["n_moved"] == moved == len(cap["comparison"]["moved"])
    assert cap["comparison"]["n_with_error"] == sum(1 for x in sig if x is not None)
    diff = sp["pile_against_pile"]["per_seed"]["n_m_quiet"]["difference"]
    nan = [math.nan if x is None else x for x in diff]
    assert cap["n_m_shift"]["mean"] == pytest.approx(np.nanmean(nan))
    ref_nm = [math.nan if x is None else x for x in sp["pile_against_pile"]["per_seed"]["n_m_quiet"]["ref"]]
    assert cap["n_m_shift"]["ref_mean"] == pytest.approx(np.nanmean(ref_nm))
    # the claims: every claim judged on both sides; flipped = the verdicts that differ
    assert set(cap["verdicts"]) == {c.key for c in CLAIMS}
    assert cap["flipped"] == [k for k, v in cap["verdicts"].items() if v["reference"] != v["setting"]
                              and "not measured" not in (v["reference"], v["setting"])]
    for c in n["claims"]:
        assert c["depends_on_solver"] == (c["key"] in cap["flipped"])
        assert [f["name"] for f in c["flipped_by"]] == (["solver.max_iter=300"]
                                                       if c["key"] in cap["flipped"] else [])
        assert c["reference"] == ref["verdicts"][c["key"]]["reference"]
        assert (c["n_m_based"] is None) == (c["figure"] == "fig2")
    # the chart's points are the settings' numbers
    pts = {p["name"]: p for p in n["chart"]}
    assert pts["reference"]["numbers_moved"] == 0 and pts["reference"]["claims_flipped"] == 0
    assert pts["solver.max_iter=300"]["numbers_moved"] == cap["comparison"]["n_moved"]
    assert pts["solver.max_iter=300"]["claims_flipped"] == len(cap["flipped"])
    # the report section is render() of the JSON, in the figures directory beside it
    md = (d / "figures" / "solver_study.md").read_text()
    assert md == solver.render(doc) and md.startswith("## What the solver's choice changes")
    for f in ("solver_study.png", "solver_study.pdf"):
        assert (d / "figures" / f).stat().st_size > 0


@pytest.mark.slow
def test_a_rerun_computes_nothing_again(study):
    d, doc, _ = study
    kept = (sorted((d / "data").glob("*/run_*.h5")) + sorted((d / "figures" / "records").glob("*/*"))
            + sorted((d / "figures" / "same-piles").rglob("*.json")))
    before = {p: p.stat().st_mtime_ns for p in kept}
    r = _study(d / "data", d / "figures")
    assert r.returncode == 0, r.stderr[-3000:]
    assert {p: p.stat().st_mtime_ns for p in kept} == before
    assert "against reference" not in r.stderr                 # the comparison was reused
    assert "seed 1 was stopped by health.overlap_stop (recorded; not run again)" in r.stderr
    again = json.loads((d / "figures" / "solver_study.json").read_text())
    for s in again["numbers"]["settings"]:
        s["cost"].pop("seconds_per_run"), s["cost"].pop("core_hours_per_run")
    for s in doc["numbers"]["settings"]:
        s = dict(s, cost={k: v for k, v in s["cost"].items()
                          if k not in ("seconds_per_run", "core_hours_per_run")})
        assert s == _by_name(again)[s["name"]]


@pytest.mark.slow
def test_a_resume_skips_the_finished_runs_and_resumes_the_interrupted_one(study, tmp_path):
    """The study's runs of two settings, seed 2 of the capped one interrupted at 20 deg (its
    .part and checkpoint left): --runs-only touches no finished run and resumes seed 2 from its
    checkpoint, to the run the uninterrupted study made."""
    from tiltpile.runner import simulate
    from tiltpile.store import open_run

    d, _, _ = study
    data, name = tmp_path / "data", "solver.max_iter=300"
    for s in ("reference", name):
        shutil.copytree(d / "data" / s, data / s)
    (data / name / "run_0002.h5").unlink()
    cfg = solver.plan("smoke", TINY_SETS, [name], RUNS).entries[1].config

    def interrupt(ev):
        if ev.phase == "tilt" and ev.theta_deg > 20:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        simulate(cfg, 2, data / name / "run_0002.h5", progress=False, on_progress=interrupt,
                 overwrite=False)
    assert (data / name / "run_0002.h5.part").exists() and (data / name / "run_0002.h5.ckpt").exists()
    others = sorted(data.glob("*/run_*.h5"))
    before = {p: p.stat().st_mtime_ns for p in others}
    r = _study(data, tmp_path / "figures", "--runs-only", only=name)
    assert r.returncode == 0, r.stderr[-3000:]
    assert {p: p.stat().st_mtime_ns for p in others} == before
    man = json.loads((data / name / "ensemble.json").read_text())
    assert man["invocations"][-1]["seeds"] == [2] and man["runs"]["2"]["resumed_from_frame"] > 0
    with open_run(data / name / "run_0002.h5") as a, open_run(d / "data" / name / "run_0002.h5") as b:
        assert a.frames_digest() == b.frames_digest()       # the same run as uninterrupted
    assert not (tmp_path / "figures").exists()          # --runs-only: no records, no study


@pytest.mark.slow
def test_records_only_runs_nothing_and_writes_the_records(study, tmp_path):
    d, _, _ = study
    data = tmp_path / "data"
    shutil.copytree(d / "data", data)
    runs = {p: p.stat().st_mtime_ns for p in data.glob("*/run_*.h5")}
    r = _study(data, tmp_path / "figures", "--records-only")
    assert r.returncode == 0, r.stderr[-3000:]
    assert {p: p.stat().st_mtime_ns for p in data.glob("*/run_*.h5")} == runs
    assert "ensemble" not in r.stderr
    for s in ("reference", *SETTINGS):
        mine = sorted((tmp_path / "figures" / "records" / s).iterdir())
        theirs = sorted((d / "figures" / "records" / s).iterdir())
        assert [p.name for p in mine] == [p.name for p in theirs] and mine
        assert all(a.read_bytes() == b.read_bytes() for a, b in zip(mine, theirs))
    assert not (tmp_path / "figures" / "solver_study.json").exists()


@pytest.mark.slow
def test_without_its_run_files_a_setting_is_read_from_its_records(study, tmp_path):
    d, doc, _ = study
    shutil.copytree(d / "figures", tmp_path / "figures")
    data = tmp_path / "data"
    shutil.copytree(d / "data", data)
    for f in (data / "solver.max_iter=300").glob("run_*.h5"):
        f.unlink()
    r = _study(data, tmp_path / "figures")
    assert r.returncode == 0, r.stderr[-3000:]
    assert "solver.max_iter=300: seeds [0, 1, 2] from their records (no run files)" in r.stderr
    assert not list((data / "solver.max_iter=300").glob("run_*.h5"))
    new = _by_name(json.loads((tmp_path / "figures" / "solver_study.json").read_text()))
    old = _by_name(doc)
    for k in ("comparison", "n_m_shift", "verdicts", "flipped", "status", "seeds_done"):
        assert new["solver.max_iter=300"][k] == old["solver.max_iter=300"][k], k


@pytest.mark.slow
def test_no_runs_studies_what_is_finished_and_names_the_rest(study, tmp_path):
    d, doc, _ = study
    shutil.copytree(d / "figures", tmp_path / "figures")
    shutil.copytree(d / "data", tmp_path / "data")
    r = _study(tmp_path / "data", tmp_path / "figures", "--no-runs",
               only="solver.max_iter=300,solver.tol=1e-4")
    assert r.returncode == 0, r.stderr[-3000:]
    assert not (tmp_path / "data" / "solver.tol=1e-4").exists() and "ensemble" not in r.stderr
    new = json.loads((tmp_path / "figures" / "solver_study.json").read_text())
    assert [s["name"] for s in new["numbers"]["settings"]] == ["reference", "solver.max_iter=300",
                                                               "solver.tol=1e-4"]
    assert _by_name(new)["solver.tol=1e-4"]["status"] == "pending"
    assert _by_name(new)["solver.max_iter=300"]["comparison"] == _by_name(doc)["solver.max_iter=300"]["comparison"]
    assert "Not yet computed: solver.tol=1e-4." in (tmp_path / "figures" / "solver_study.md").read_text()


@pytest.mark.slow
def test_the_chart_draws_chance_and_pending_settings(study, tmp_path):
    """The chart's two optional parts on the study's numbers: chance's 95th percentile (a null
    computed) and a setting not yet run, named below the panels and in the report section."""
    from tiltpile.figures import style

    _, doc, _ = study
    n = json.loads(json.dumps(doc["numbers"]))
    n["chart"][1]["chance_p95"] = 2.0
    pending = dict(n["settings"][1], name="solver.tol=1e-7", status="pending", comparison=None,
                   flipped=None, n_m_shift=None, verdicts=None, seeds_done=[])
    n["settings"].append(pending)
    style.use()
    fig = solver.plot(n)
    fig.savefig(tmp_path / "chart.png")
    texts = " ".join(t.get_text() for t in fig.texts)
    assert "not yet computed: tol=1e-7" in texts and "stopped by the health rules: dt=0.5" in texts
    assert "Not yet computed: solver.tol=1e-7." in solver.render(dict(doc, numbers=n))


@pytest.mark.slow
def test_the_charts_numbers(study, num_regression, data_regression):
    """The chart's JSON numbers on the tiny study (timings left out: they are the machine's)."""
    _, doc, _ = study
    pts = doc["numbers"]["chart"]

    def col(key):
        return np.array([math.nan if p[key] is None else float(p[key]) for p in pts])

    num_regression.check({k: col(k) for k in ("sweeps_per_run", "numbers_moved",
                                                "numbers_with_error", "claims_flipped",
                                                "n_m_shift", "seeds")},
                         default_tolerance=dict(rtol=1e-9, atol=1e-12))
    data_regression.check({"points": [{k: p[k] for k in ("name", "axis", "committed", "status")}
                                      for p in pts],
                           "flipped": {s["name"]: s["flipped"] for s in doc["numbers"]["settings"]},
                           "decisions": {k: v for k, v in doc["numbers"]["decisions"].items()
                                         if isinstance(v, str) or v is None}})


def test_reference_records_of_another_configuration_are_refused(tmp_path, capsys):
    """--reference-records: a directory of the committed setting's records; records of another
    configuration (here the committed 1000-grain study's, not the tiny piles') are refused in one
    line before anything runs, and a missing directory too."""
    src = ROOT / "figures" / "solver-study" / "records" / "reference"
    assert main(["solver-study", "--data", str(tmp_path / "data"), "--figures", str(tmp_path / "fig"),
                 "--only", "solver.max_iter=300", "--reference-records", str(src), *TINY]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is a record of another configuration than the committed setting" in err[0]
    assert main(["solver-study", "--data", str(tmp_path / "data"), "--figures", str(tmp_path / "fig"),
                 "--only", "solver.max_iter=300", "--reference-records", str(tmp_path / "nope"),
                 *TINY]) == 2
    assert "not a directory" in capsys.readouterr().err
    assert not (tmp_path / "fig").exists() and not (tmp_path / "data").exists()


@pytest.mark.slow
def test_reference_records_are_taken_in_and_their_seeds_not_run(study, tmp_path):
    """The committed setting's records made elsewhere are copied into FIGURES/records/reference/
    and its seeds are not run: with --records-only nothing runs at all, and the reference's
    records are the given ones, byte for byte."""
    d, _, _ = study
    given = d / "figures" / "records" / "reference"
    r = _study(tmp_path / "data", tmp_path / "figures", "--records-only", "--reference-records",
               str(given), only=SETTINGS[0])
    assert r.returncode == 0, r.stderr[-3000:]
    assert "reference: the records of seeds [0, 1, 2] from" in r.stderr
    mine = sorted((tmp_path / "figures" / "records" / "reference").glob("run_*.npz"))
    assert [p.name for p in mine] == [f"run_{s:04d}.npz" for s in range(RUNS)]
    assert all(p.read_bytes() == (given / p.name).read_bytes() for p in mine)
    assert not (tmp_path / "data" / "reference").exists()
