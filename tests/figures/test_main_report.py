"""The main report, paper/REPRODUCTION.md: the paper's scale first, every axis beside it, short
enough to read in minutes, and what the committed figures' JSON gives."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tiltpile.report import history_rate as hr
from tiltpile.report import main as rm
from tiltpile.report.claims import CLAIMS
from tiltpile.report.document import judgements, load_figures
from tiltpile.report.judging import AGREES, DISAGREES, INCONCLUSIVE

ROOT = Path(__file__).resolve().parents[2]
MAIN = ROOT / "paper" / "REPRODUCTION.md"


def test_the_committed_main_report_is_what_the_committed_json_gives():
    assert MAIN.read_text() == rm.render(ROOT / "figures")


def test_the_main_report_is_short_and_its_first_table_is_the_papers_scale():
    lines = MAIN.read_text().splitlines()
    assert len(lines) < 250
    assert max(len(x) for x in lines) < 400
    first = next(i for i, x in enumerate(lines) if x.startswith("|"))
    assert first < 15                                          # on the first screen
    head = [c.strip() for c in lines[first].strip("|").split("|")]
    assert head[:4] == ["claim", "paper", "ours", "verdict"]
    assert {"1000 grains", "definitions: best / worst", "DEM 4000"} <= set(head)
    # every claim, in order, with the paper-scale verdict its judge returns
    paper = judgements(load_figures(ROOT / "figures" / "paper"), CLAIMS)
    rows = lines[first + 2:first + 2 + len(CLAIMS)]
    for k, (row, (c, j, _)) in enumerate(zip(rows, paper)):
        cells = [x.strip() for x in row.strip("|").split("|")]
        assert cells[0] == f"{k + 1}. {c.text}" and cells[3].strip("*") == j.verdict


def test_the_context_is_the_judges_data():
    ctx = rm.context(ROOT / "figures")
    paper = judgements(load_figures(ROOT / "figures" / "paper"), CLAIMS)
    assert [r["key"] for r in ctx["rows"]] == [c.key for c in CLAIMS]
    assert [r["verdict"] for r in ctx["rows"]] == [j.verdict for _, j, _ in paper]
    n_paper = sum(1 for r in ctx["rows"] if not r["beyond"])
    assert sum(ctx["counts"].values()) == n_paper == ctx["n_paper_claims"]
    small = judgements(load_figures(ROOT / "figures"), CLAIMS)
    assert [r["small"] for r in ctx["rows"]] == [j.verdict for _, j, _ in small]
    # the best and worst definition are the extremes of the study's verdicts
    d4 = ctx["definitions"]["4000"]
    for r in ctx["rows"]:
        got = set(d4["verdicts"][r["key"]].values())
        e = r["definitions"]
        assert e["best"][0] == min(got, key=rm._RANK.get) and e["worst"][0] == max(got, key=rm._RANK.get)


def test_headline_keeps_the_number_and_drops_the_asides():
    assert rm.headline("first onset 14.8 [13.9, 15.4] deg (mean [95% CI], 50 runs; range 4.9-18.6)") \
        == "first onset 14.8 [13.9, 15.4] deg"
    assert rm.headline("BIC(1) - BIC(2) = 8; 14% of frames (x (y))") == "BIC(1) - BIC(2) = 8"
    assert rm.headline("") == ""


def test_extremes_pick_the_best_and_the_worst_definition():
    labels = {"a": "A", "b": "B", "c": "C"}
    e = rm._extremes({"a": DISAGREES, "b": AGREES, "c": INCONCLUSIVE}, labels)
    assert e == {"best": (AGREES, ["B"]), "worst": (DISAGREES, ["A"]), "n": 3}
    assert rm._extremes({"a": "not measured"}, labels) is None


def test_without_the_papers_figures_nothing_is_written(tmp_path):
    (tmp_path / "figures").mkdir()
    out = tmp_path / "REPRODUCTION.md"
    with pytest.raises(FileNotFoundError, match="make figures PRESET=paper"):
        rm.write_main_report(tmp_path / "figures", out)
    assert not out.exists()


def test_the_main_report_follows_the_json(tmp_path):
    """A verdict changed at the paper's scale changes the first table's row and the counts."""
    root = tmp_path / "figures"
    shutil.copytree(ROOT / "figures" / "paper", root / "paper",
                    ignore=shutil.ignore_patterns("records", "*.png", "*.md"))
    f = root / "paper" / "fig2_avalanche_criterion.json"
    doc = json.loads(f.read_text())
    doc["numbers"]["z_quiet_run_mean"] = 3.5
    doc["numbers"]["z_quiet_run_mean_ci_low"], doc["numbers"]["z_quiet_run_mean_ci_high"] = 3.45, 3.55
    f.write_text(json.dumps(doc))
    ctx = rm.context(root)
    assert next(r for r in ctx["rows"] if r["key"] == "z_mean")["verdict"] == AGREES
    before = rm.context(ROOT / "figures")["counts"]
    assert ctx["counts"][AGREES] == before[AGREES] + 1
    text = rm.render(root)
    assert "3.500 [3.450, 3.550]" in text
    assert "not run" in text            # the axes without their figures say so


def test_report_on_one_scale_needs_its_out(tmp_path):
    r = subprocess.run([sys.executable, "-m", "tiltpile", "report", "--figures", "figures/paper"],
                       cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "--out" in r.stderr


def test_the_solver_studys_section_is_its_json_in_brief_once_written(tmp_path):
    root = tmp_path / "figures"
    shutil.copytree(ROOT / "figures" / "paper", root / "paper",
                    ignore=shutil.ignore_patterns("records", "*.png", "*.md"))
    assert "Not yet computed: `make solver-study`" in rm.render(root)
    (root / rm.SOLVER_STUDY).parent.mkdir(parents=True)
    committed = json.loads((ROOT / "figures" / rm.SOLVER_STUDY).read_text())
    (root / rm.SOLVER_STUDY).write_text(json.dumps(committed))
    text = rm.render(root)
    assert "Not yet computed: `make solver-study`" not in text
    assert text.count("## What the solver's choice changes") == 1
    n = committed["numbers"]
    shown = [st for st in n["settings"] if not st["committed"] and (st["seeds_done"] or st["health_stops"])]
    for st in shown:
        row = next(x for x in text.splitlines() if x.startswith(f"| `{st['name']}`"))
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[1].startswith(f"{len(st['seeds_done'])} of {st['seeds_planned']}")
        if st.get("comparison"):
            assert cells[3] == f"{st['comparison']['n_moved']} of {st['comparison']['n_with_error']}"
            assert cells[4] == str(len(st["flipped"]))

def test_the_same_piles_decision_says_what_the_null_can_say():
    """p below 0.05 moves, above it detects no difference, within two Monte-Carlo errors of it is
    undecided; an exact null has no Monte-Carlo error; a flipped verdict moves whatever p says."""
    def study(p, flips, method=None):
        null = {"p_value": p, "flips": flips, "median": 3, "p95": 10, "observed": 5}
        if method:
            null["method"] = method
        return {"null": null}

    assert hr.decide(study(0.049, 40), 0) == "undecided"              # +- 0.034
    assert hr.null_of(study(0.049, 40))["mc_error"] == pytest.approx((0.049 * 0.951 / 40) ** 0.5)
    assert hr.decide(study(0.01, 500), 0) == "moved"                   # 0.01 +- 0.0045
    assert hr.decide(study(0.24, 500), 0) == "no difference detected"
    assert hr.decide(study(0.049, 128, "exact"), 0) == "moved"         # exact: no error
    assert hr.null_of(study(0.049, 128, "exact"))["mc_error"] == 0.0
    assert hr.decide(study(0.5, 500), 1) == "moved"
    assert hr.decide({"null": None}, 0) == "open"
    # the smallest detectable mean shift: 2.80 sd / sqrt(n) of the per-seed differences
    d = [0.5, -0.5, 1.0, -1.0]
    got = hr.detectable({"pile_against_pile": {"per_seed": {
        "theta_first_slide": {"difference": d}, "theta_first_onset": {"difference": [None, 1.0]}}}})
    import statistics
    assert got["theta_first_slide"] == pytest.approx(hr.Z_DETECT * statistics.stdev(d) / 2)
    assert got["theta_first_onset"] != got["theta_first_onset"]          # one seed: NaN


def test_the_committed_paper_5x_check_is_exact():
    ctx = rm.context(ROOT / "figures")
    x = next(r for r in ctx["rates"] if r["faster"] == "paper-5x")
    assert x["null"]["method"] == "exact" and x["null"]["flips"] == 2 ** (x["seeds"] - 1)
    assert x["decision"] == ("no difference detected" if x["null"]["p_value"] >= hr.ALPHA else "moved")


def test_the_committed_studies_document_is_what_the_committed_json_gives():
    from tiltpile.report.document import render_studies

    assert (ROOT / "paper" / "STUDIES.md").read_text() == render_studies(ROOT / "figures")
