"""The stiffness study (``tiltpile stiffness-study``, tiltpile.studies.stiffness; issue 73): the plan
refused in one line before anything runs (a stiffness whose time step is too long for it), the
extrapolation's rule on synthetic numbers, and the study end to end on tiny piles: 80 smoke grains
in the DEM at a tenth of the default stiffness (k_n = 2e4, dt = 2.5e-4: each run ~0.03-0.1 M DEM
steps, a few seconds) tilted fast to 30 deg, 2 piles at each of k_n, 4 k_n and 16 k_n, against
Contact Dynamics' runs of the same 2 piles; its numbers against the records and comparisons they
come from, and a rerun that computes nothing again."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tiltpile import config
from tiltpile.cli import main
from tiltpile.studies import settings as st
from tiltpile.studies import stiffness

ROOT = Path(__file__).resolve().parents[2]
TINY_SETS = ["scene.n=80", "scene.box_length=12", "protocol.theta_max_deg=30",
             "protocol.tilt_per_step_deg=0.05"]
SOFT = ["dem.kn=20000.0", "dem.dt=0.00025"]
TINY = ["--preset", "smoke", *(a for s in TINY_SETS + SOFT for a in ("--set", s))]
RUNS = 2


# ----------------------------------------------------------------------------------------------
# the plan


def test_the_plan_is_k_n_then_4_and_16_k_n_with_the_time_step_shrunk_alike():
    p = stiffness.plan()
    ref = p.reference.config
    assert p.preset == "default-dem" and ref.dem.kn == 2e5 and ref.dem.dt == 8e-5
    assert [(e.setting.name, e.config.dem.kn, e.config.dem.dt, len(e.seeds)) for e in p.entries] == [
        ("reference", 2e5, 8e-5, 6), ("4kn_dt2", 8e5, 4e-5, 6), ("16kn_dt4", 3.2e6, 2e-5, 3)]
    assert p.entries[1].setting.overrides == ("dem.kn=800000.0", "dem.dt=4e-05")
    steps = [config.dem_contact_steps(e.config) for e in p.entries]
    assert steps == pytest.approx([steps[0]] * 3) and steps[0] >= config.DEM_MIN_CONTACT_STEPS
    # apart from the DEM's k_n and dt, every setting is the committed one
    for e in p.entries:
        assert dataclasses.replace(e.config, dem=ref.dem).hash() == ref.hash()
    # the shares of the runs: half at 16 k_n, rounded up, at least the two a comparison needs
    assert [len(e.seeds) for e in stiffness.plan(runs=2).entries] == [2, 2, 2]
    assert [len(e.seeds) for e in stiffness.plan(runs=5).entries] == [5, 5, 3]
    assert [e.setting.name for e in stiffness.plan(only=["8kn_dt3"]).entries] == ["reference", "8kn_dt3"]


@pytest.mark.parametrize("args, named", [
    (["--only", "16kn_dt2"], "setting 16kn_dt2: dem.dt = 4e-05 is too long for dem.kn = 3200000.0: "
                             "a collision of the two smallest grains lasts 27.3 steps, fewer than 30"),
    (["--only", "4kn"], "neither a setting of the study"),
    (["--only", "1kn_dt1"], "is the configuration of reference"),
    (["--preset", "default"], "a Contact Dynamics configuration (no [dem] section)"),
    (["--set", "dem.kn=-1"], "--set: dem.kn"),
    (["--runs", "0"], "--runs must be at least 1"),
    (["--runs-only", "--no-runs"], "give one of them"),
])
def test_a_bad_stiffness_is_refused_in_one_line_before_anything_runs(tmp_path, capsys, args, named):
    base = ["stiffness-study", "--data", str(tmp_path / "data"), "--figures", str(tmp_path / "fig"),
            "--runs", "2"]
    assert main(base + args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tiltpile stiffness-study: error:") and named in err[0], err
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------------------------
# the extrapolation's rule


X = [1.0, 0.25, 0.0625]


def test_a_linear_trend_extrapolates_exactly():
    f = stiffness.extrapolate(X, [3.0 + 0.2 * x for x in X], [0.01, 0.01, 0.02])
    assert f["status"] == "extrapolated" and f["reason"] is None
    assert f["value"] == pytest.approx(3.0, abs=1e-12) and f["slope"] == pytest.approx(0.2, abs=1e-12)
    assert max(map(abs, f["residuals"])) < 1e-12
    # the limit's error: the line's, propagated from the points' (weights 1 / err^2)
    w = np.array([1 / 0.01**2, 1 / 0.01**2, 1 / 0.02**2])
    xs = np.array(X)
    assert f["error"] == pytest.approx(math.sqrt((w * xs**2).sum() / (w.sum() * (w * xs**2).sum()
                                                                       - (w * xs).sum() ** 2)))
    # exact without errors too, and whatever the order of the points
    g = stiffness.extrapolate(X[::-1], [5.0 - x for x in X[::-1]], [0.0] * 3)
    assert g["status"] == "extrapolated" and g["value"] == pytest.approx(5.0, abs=1e-12)


def test_on_shared_piles_the_errors_are_the_jackknifes_over_the_piles():
    """Three piles, each linear in x with its own offset (the spread from pile to pile that every
    stiffness shares) and the same slope: the limit is the piles' mean intercept, its error the
    jackknife of the intercepts; the steps' and residuals' errors are 0, and a line still fits."""
    offsets = [3.0, 3.1, 2.95]
    piles = [[o + 0.2 * x for x in X] for o in offsets]
    y = np.mean(piles, axis=0).tolist()
    loo = [np.mean([p for j, p in enumerate(piles) if j != i], axis=0).tolist() for i in range(3)]
    err = [stiffness.jackknife_se([r[k] for r in loo]) for k in range(3)]
    f = stiffness.extrapolate(X, y, err, loo=loo)
    assert f["status"] == "extrapolated"
    assert f["value"] == pytest.approx(np.mean(offsets))
    assert f["error"] == pytest.approx(np.std(offsets, ddof=1) / math.sqrt(3))
    assert f["value_loo"] == pytest.approx([np.mean(offsets[:i] + offsets[i + 1:]) for i in range(3)])
    assert max(f["residual_errors"]) < 1e-9
    # a bend that the shared spread would hide is seen against the paired errors
    bent = [[o + 0.2 * x + 0.01 * (x == 0.25) for x in X] for o in offsets]
    yb = np.mean(bent, axis=0).tolist()
    loob = [np.mean([p for j, p in enumerate(bent) if j != i], axis=0).tolist() for i in range(3)]
    assert stiffness.extrapolate(X, yb, err, loo=loob)["status"] == "not linear"
    assert stiffness.extrapolate(X, yb, err)["status"] == "extrapolated"     # errors not paired


@pytest.mark.parametrize("x, y, err, status", [
    (X[:2], [3.0, 3.1], [0.01, 0.01], "too few stiffnesses"),
    ([1.0, 1.0, 0.25], [3.0, 3.0, 3.1], [0.01] * 3, "too few stiffnesses"),     # two distinct k_n
    (X, [3.0, math.nan, 3.1], [0.01] * 3, "too few stiffnesses"),
    (X, [3.0, 3.1, 3.2], [0.01, math.nan, 0.01], "no error"),
    (X, [3.0, 3.5, 3.0], [0.01] * 3, "not monotone"),
    (X, [3.0, 3.6, 3.62], [0.01] * 3, "not linear"),         # saturates: no straight line
])
def test_too_few_points_or_a_trend_that_is_no_line_does_not_extrapolate(x, y, err, status):
    f = stiffness.extrapolate(x, y, err)
    assert f["status"] == status and f["reason"] and math.isnan(f["value"]) and math.isnan(f["error"])


def test_a_flat_trend_within_its_errors_is_monotone_and_extrapolates():
    f = stiffness.extrapolate(X, [3.000, 3.004, 2.998], [0.005] * 3)
    assert f["status"] == "extrapolated" and abs(f["value"] - 3.0) < 0.01


def test_records_made_elsewhere_are_taken_over_where_missing(tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    src.mkdir()
    dst.mkdir()
    for s in (0, 1, 2):
        (src / f"run_{s:04d}.npz").write_bytes(b"committed %d" % s)
    (dst / "run_0001.npz").write_bytes(b"mine")
    assert st.seed_records(src, dst, [0, 1, 3]) == [0]
    assert (dst / "run_0000.npz").read_bytes() == b"committed 0"
    assert (dst / "run_0001.npz").read_bytes() == b"mine" and not (dst / "run_0002.npz").exists()


# ----------------------------------------------------------------------------------------------
# the study end to end


def _study(data, figures, cd, *extra):
    cmd = [sys.executable, "-m", "tiltpile", "stiffness-study", "--data", str(data), "--figures",
           str(figures), "--runs", str(RUNS), "--cd", str(cd), "--workers", "1", "--quiet", *TINY,
           *extra]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """Contact Dynamics' runs of the 2 tiny piles and their records, then the study."""
    from tiltpile.figures.records import write_records
    from tiltpile.runner import simulate

    d = tmp_path_factory.mktemp("stiffness_study")
    cfg = config.load("smoke", None, TINY_SETS)
    for s in range(RUNS):
        simulate(cfg, s, d / "cd-runs" / f"run_{s:04d}.h5", progress=False)
    write_records(d / "cd-runs", d / "cd", workers=1, progress=False)
    r = _study(d / "data", d / "figures", d / "cd")
    assert r.returncode == 0, r.stderr[-3000:]
    return d, json.loads((d / "figures" / "stiffness_study.json").read_text()), r


def _by_name(doc):
    return {s["name"]: s for s in doc["numbers"]["settings"]}


@pytest.mark.slow
def test_the_jsons_numbers_are_those_of_its_records_and_comparisons(study):
    from tiltpile.record import read_meta
    from tiltpile.report.claims import CLAIMS

    d, doc, r = study
    n, by = doc["numbers"], _by_name(doc)
    assert doc["figure"] == "stiffness_study" and doc["study"]["preset"] == "smoke"
    assert list(by) == ["reference", "4kn_dt2", "16kn_dt4"]
    assert all(s["status"] == "done" and s["seeds_done"] == [0, 1] for s in by.values())
    assert [s["dem"]["factor"] for s in by.values()] == [1, 4, 16]
    assert [s["dem"]["kn"] for s in by.values()] == [2e4, 8e4, 3.2e5]
    # cost: the records' DEM steps, about twice and four times k_n's (dt / 2, dt / 4)
    for s in by.values():
        rec = d / "figures" / "records" / s["name"]
        steps = [read_meta(rec / f"run_{k:04d}.npz")["cost"]["steps"] for k in range(RUNS)]
        assert s["cost"]["steps_per_run"] == pytest.approx(np.mean(steps))
    ratio = [s["cost"]["steps_per_run"] / by["reference"]["cost"]["steps_per_run"] for s in by.values()]
    assert 1.6 < ratio[1] < 2.2 and 3.0 < ratio[2] < 4.4
    # each number's points: the mean over the piles of the per-pile numbers the engines'
    # comparison reads, for the DEM and for Contact Dynamics alike
    assert n["fit_seeds"] == [0, 1] and n["cd"]["available"] and n["cd"]["seeds"] == [0, 1]
    for m in n["measures"]:
        f = m["fit"]
        again = stiffness.extrapolate([p["x"] for p in m["points"]], [p["value"] for p in m["points"]],
                                      [p["error"] for p in m["points"]])
        if f["status"] == "extrapolated":
            assert again["status"] == "extrapolated"
        if m["key"] not in stiffness.ENGINE_KEYS:
            continue
        for p in m["points"]:
            sp = json.loads((d / "figures" / "same-piles" / "cd" / p["name"] / "same_piles.json").read_text())
            per = sp["pile_against_pile"]["per_seed"][m["key"]]
            if all(v is not None for v in per["value"]):
                assert p["value"] == pytest.approx(np.mean(per["value"]))
                assert m["cd"]["value"] == pytest.approx(np.mean(per["ref"]))
    # the claims: a stiffer k_n flips a claim exactly when its comparison with k_n says so
    for c in n["claims"]:
        flips = [s["name"] for s in by.values() if c["key"] in (s["flipped"] or [])]
        assert [f["name"] for f in c["stiffness"]["flips"]] == flips
        assert (c["stiffness"]["outcome"] == "flips") == bool(flips)
        for p in c["per_setting"]:
            assert p["verdict"] == by[p["name"]]["own_verdicts"][c["key"]]
            assert p["dem_same_piles"] == by[p["name"]]["engines"]["verdicts"][c["key"]]["dem"]
    assert {c["key"] for c in n["claims"]} == {c.key for c in CLAIMS}
    # the report section is render() of the JSON, beside it with the figure
    md = (d / "figures" / "stiffness_study.md").read_text()
    assert md == stiffness.render(doc) and md.startswith("## The second engine in its rigid limit")
    for f in ("stiffness_study.png", "stiffness_study.pdf"):
        assert (d / "figures" / f).stat().st_size > 0
    assert "16kn_dt4: 2 of 2 runs" in r.stdout


@pytest.mark.slow
def test_a_rerun_computes_nothing_again(study):
    d, doc, _ = study
    kept = (sorted((d / "data").glob("*/run_*.h5")) + sorted((d / "figures" / "records").glob("*/*"))
            + sorted((d / "figures" / "same-piles").rglob("*.json")))
    before = {p: p.stat().st_mtime_ns for p in kept}
    r = _study(d / "data", d / "figures", d / "cd")
    assert r.returncode == 0, r.stderr[-3000:]
    assert {p: p.stat().st_mtime_ns for p in kept} == before
    assert "ensemble" not in r.stderr and "against" not in r.stderr
    again = json.loads((d / "figures" / "stiffness_study.json").read_text())
    assert again["numbers"]["measures"] == doc["numbers"]["measures"]
    assert again["numbers"]["claims"] == doc["numbers"]["claims"]


@pytest.mark.slow
def test_records_of_another_configuration_are_refused_as_contact_dynamics(study, tmp_path, capsys):
    d, _, _ = study
    assert main(["stiffness-study", "--data", str(tmp_path / "data"), "--figures",
                 str(tmp_path / "fig"), "--runs", "2", "--cd", str(d / "figures" / "records" / "4kn_dt2"),
                 *TINY]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--cd" in err[0] and "another configuration" in err[0], err
    assert list(tmp_path.iterdir()) == []
