"""The documents quote the figures' numbers through generated blocks, never by hand: the blocks are
fresh (rendering them again changes nothing), a number changed in one figure JSON reaches every
place that quotes it, the block markers fail loudly when broken; and the few facts the docs state
by hand twice (the paper ensemble's estimated cost in docs/performance.md and docs/slurm.md) are
stated the same."""

import json
import re
import shutil
from pathlib import Path

import pytest

from tiltpile.report import blocks
from tiltpile.report.judging import AGREES, DISAGREES

ROOT = Path(__file__).resolve().parents[1]
PERF = (ROOT / "docs" / "performance.md").read_text()
SLURM = (ROOT / "docs" / "slurm.md").read_text()


def _section(text: str, heading: str) -> str:
    start = text.index(heading)
    end = text.find("\n## ", start + len(heading))
    return text[start:end if end > 0 else None]


def test_the_generated_blocks_are_fresh():
    """`make docs` on the committed figures' JSON changes nothing."""
    assert blocks.update(ROOT, check=True) == []


def test_the_readme_holds_every_generated_block_it_is_built_from():
    text = (ROOT / "README.md").read_text()
    for name in ("readme_findings", "readme_verdicts", "readme_presets"):
        assert f"<!-- generated: {name} (tiltpile docs; do not edit) -->" in text, name
        assert f"<!-- end generated: {name} -->" in text, name


def _copy_json(tmp_path: Path) -> Path:
    """A repository of the committed figures' JSON (no pictures), the records the documents'
    wall times come from (links to the committed ``figures/*/records/``:
    tiltpile.report.wall) and the documents with generated blocks."""
    for r in sorted((ROOT / "figures").glob("*/records")) + [ROOT / "figures" / "records"]:
        if any(r.glob("run_*.npz")):
            dest = tmp_path / r.relative_to(ROOT)
            dest.parent.mkdir(parents=True, exist_ok=True)
            dest.symlink_to(r, target_is_directory=True)
    for p in (ROOT / "figures").rglob("*.json"):
        if (tmp_path / p.relative_to(ROOT)).exists():   # in a linked records directory
            continue
        dest = tmp_path / p.relative_to(ROOT)
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(p, dest)
    for name in blocks.FILES:
        dest = tmp_path / name
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(ROOT / name, dest)
    return tmp_path


def test_a_number_changed_in_one_json_reaches_every_place_that_quotes_it(tmp_path):
    """The paper-scale delta, changed in fig5's JSON: the README's verdict table and the main
    report follow with no hand edit, and the old value is gone from both."""
    from tiltpile.report.main import render

    repo = _copy_json(tmp_path)
    f5 = repo / "figures" / "paper" / "fig5_cluster_sizes.json"
    doc = json.loads(f5.read_text())
    n = doc["numbers"]
    old = f"{n['delta_pooled']:.2f} [{n['delta_pooled_ci_low']:.2f}, {n['delta_pooled_ci_high']:.2f}]"
    n["delta_pooled"], n["delta_pooled_ci_low"], n["delta_pooled_ci_high"] = 2.91, 2.87, 2.95
    f5.write_text(json.dumps(doc))
    readme = (repo / "README.md").read_text()
    assert old in readme
    assert blocks.update(repo) == [repo / "README.md"]
    readme = (repo / "README.md").read_text()
    assert old not in readme and "2.91 [2.87, 2.95]" in readme
    report = render(repo / "figures")
    assert old not in report and "2.91 [2.87, 2.95]" in report
    # 2.91 is outside 2.5 +- 0.25: the verdict follows the number, in both places
    row = next(line for line in readme.splitlines() if "2.91 [2.87, 2.95]" in line)
    assert row.rstrip().endswith(f"**{DISAGREES}** |")


def test_a_broken_block_is_an_error_naming_the_file_and_line():
    known = {"a": "x"}
    assert blocks.fill("t\n<!-- generated: a (tiltpile docs; do not edit) -->\nold\n"
                       "<!-- end generated: a -->\nu", known) == (
        "t\n<!-- generated: a (tiltpile docs; do not edit) -->\nx\n<!-- end generated: a -->\nu")
    with pytest.raises(blocks.BlockError, match=r"README.md:2: generated block 'b' has no template"):
        blocks.fill("t\n<!-- generated: b (tiltpile docs; do not edit) -->\n"
                    "<!-- end generated: b -->", known, "README.md")
    with pytest.raises(blocks.BlockError, match=r"X.md:1: generated block 'a' has no end line"):
        blocks.fill("<!-- generated: a (tiltpile docs; do not edit) -->\nold", known, "X.md")


def test_the_findings_say_what_the_judges_and_the_studies_return():
    """The README's findings are the judges' data: the counts of the paper-scale verdicts, the
    claims that disagree, which of them some contact definition fixes."""
    from tiltpile.report.main import context

    ctx = context(ROOT / "figures")
    text = (ROOT / "README.md").read_text()
    found = text[text.index("<!-- generated: readme_findings"):text.index("<!-- end generated: readme_findings")]
    paper = [r for r in ctx["rows"] if not r["beyond"]]
    agree = sum(r["verdict"] == AGREES for r in paper)
    assert f"**{agree} of the paper's {len(paper)} claims agree**" in found
    dis = [str(r["n"]) for r in paper if r["verdict"] == DISAGREES]
    listed = ", ".join(dis[:-1]) + " and " + dis[-1] if len(dis) > 1 else dis[0]
    assert f"claims {listed} of the table below disagree" in found
    fixed = [str(r["n"]) for r in paper if r["verdict"] == DISAGREES and r["definitions"]["best"][0] == AGREES]
    stuck = [str(r["n"]) for r in paper if r["verdict"] == DISAGREES and r["definitions"]["best"][0] == DISAGREES]
    assert set(fixed) | set(stuck) == set(dis)
    assert f"{', '.join(stuck[:-1])} and {stuck[-1]} disagree under every one" in found
    # what a fixing definition breaks: exactly the claims agreeing under ours and not under it
    d4 = ctx["definitions"]["4000"]
    key_of = {d4["labels"][k]: k for k in d4["order"]}
    for name, broken in d4["breaks"].items():
        want = [r["text"] for r in ctx["rows"] if r["key"] in d4["verdicts"]
                and d4["verdicts"][r["key"]].get("force") == AGREES
                and d4["verdicts"][r["key"]].get(key_of[name]) != AGREES]
        assert broken == want, name
    assert any(d4["breaks"].values())


def test_the_paper_ensembles_cost_is_the_same_everywhere():
    """The estimate of docs/performance.md's "Where things stand" (hours per cycled run and
    core-hours for 50) is the one docs/slurm.md quotes, and no other is quoted."""
    now = " ".join(_section(PERF, "## Where things stand").split())
    m = re.search(r"(\d+(?:\.\d+)?-\d+(?:\.\d+)?) hours on one core, "
                  r"(\d+-\d+) core-hours for the paper's 50", now)
    assert m, "docs/performance.md states no estimate for the paper ensemble"
    hours, core_hours = m.groups()
    one = " ".join(SLURM.split())
    assert f"{hours} hours" in one and f"{core_hours} core-hours" in one
    quoted = set(re.findall(r"(\d+(?:\.\d+)?-\d+(?:\.\d+)?) (?:core-)?hours (?:per run|on one)", one))
    assert quoted <= {hours}, quoted
    for where, text in (("docs/performance.md", now), ("docs/slurm.md", SLURM)):
        assert "20-30 min" in " ".join(text.split()), where          # a fresh paper run


def test_every_document_quotes_the_figures_through_generated_blocks():
    """Each document of blocks.DOCUMENTS holds at least one generated block, each block is one of
    its own prefix's templates, and every template of the four reference documents' prefixes is
    quoted where it belongs (a template no document holds would be a number nobody reads)."""
    rendered = blocks.render_all(ROOT / "figures")
    for name, prefix in blocks.DOCUMENTS.items():
        found = [m.group(1) for m in map(blocks.BEGIN.match, (ROOT / name).read_text().splitlines()) if m]
        assert found, f"{name} holds no generated block"
        assert all(b.split("_")[0] == prefix for b in found), (name, found)
        assert all(rendered[b].strip() for b in found), (name, [b for b in found if not rendered[b].strip()])
    for name in ("docs/presets.md", "docs/figures.md", "docs/dem.md", "docs/performance.md"):
        prefix = blocks.DOCUMENTS[name]
        text = (ROOT / name).read_text()
        unused = [b for b, md in rendered.items() if b.startswith(prefix + "_") and md.strip()
                  and f"<!-- generated: {b} (tiltpile docs; do not edit) -->" not in text]
        assert not unused, (name, unused)


def test_a_number_changed_in_a_json_reaches_docs_presets(tmp_path):
    """paper-fast's slide against paper's (its same_piles.json) and the default piles' contacts per
    frame (fig2's n_active_mean), changed in the JSON: docs/presets.md follows with no hand edit."""
    repo = _copy_json(tmp_path)
    f = repo / "figures" / "paper-fast" / "same-piles" / "same_piles.json"
    study = json.loads(f.read_text())
    d = study["pile_against_pile"]["difference"]["theta_first_slide"]
    old = f"{d['mean']:+.2f} [{d['ci_low']:+.2f}, {d['ci_high']:+.2f}]"
    d["mean"], d["ci_low"], d["ci_high"] = 1.23, 0.45, 2.01
    f.write_text(json.dumps(study))
    f2 = repo / "figures" / "fig2_avalanche_criterion.json"
    doc = json.loads(f2.read_text())
    doc["numbers"]["n_active_mean"] = 2500.0
    f2.write_text(json.dumps(doc))
    presets = repo / "docs" / "presets.md"
    assert old in presets.read_text()
    assert presets in blocks.update(repo)
    text = presets.read_text()
    assert old not in text and "+1.23 [+0.45, +2.01]" in text
    # 2% of 2500 contacts: the cutoff's count follows the contacts per frame
    assert "holds 2500 force-bearing contacts on average, so the 2% cutoff is about 50 lost" in text


def test_the_docs_read_the_pile_against_pile_numbers_the_report_reads():
    """blocks.same_piles, which the documents' templates read, gives each history-rate check's
    pile-against-pile rows as the main report's context does (the same study, the same means)."""
    from tiltpile.report.engines import ROWS
    from tiltpile.report.main import context

    studies = blocks.same_piles(ROOT / "figures")
    for x in context(ROOT / "figures")["rates"]:
        rows = studies[x["faster"]]["rows"]
        assert studies[x["faster"]]["ref"] == x["ref"]
        for r in x["rows"]:
            key = next(k for k, label, _ in ROWS if label == r["label"])
            for ours, theirs in (("ref", "ref"), ("value", "value"), ("diff", "diff"), ("low", "low"),
                                 ("high", "high"), ("n", "n")):
                a, b = rows[key][ours], r[theirs]
                assert a == b or (a != a and b != b), (x["faster"], key, ours, a, b)


def test_the_preparation_helper_compares_a_faster_history_with_the_study_s_own_rule():
    """blocks.preparation's "between" (a history at N x the ramp's rate against the same history
    at the ramp's rate, quoted in docs/figures.md and docs/presets.md) is the difference of the
    per-run means of the committed study, with the study's own interval (diff_ci)."""
    import numpy as np

    p = blocks.preparation(ROOT / "figures")["default"]
    assert p["reference"] == "fresh" and "cyc16r10:cyc16" in p["between"]
    fast, slow = p["ensembles"]["cyc16r10"]["per_run"], p["ensembles"]["cyc16"]["per_run"]
    for q, d in p["between"]["cyc16r10:cyc16"].items():
        a = np.array([np.nan if v is None else v for v in fast[q]], float)
        b = np.array([np.nan if v is None else v for v in slow[q]], float)
        assert d["estimate"] == pytest.approx(np.nanmean(a) - np.nanmean(b))
        assert d["low"] <= d["estimate"] <= d["high"]


def test_the_dem_z_table_reads_the_same_runs_as_the_same_piles_studies():
    """docs/method.md's DEM z (blocks.dem_z, read from the committed DEM records) is, seed for seed,
    the ``value`` side of each DEM preset's committed same-piles study, and its CD column that
    study's ``ref`` side: the table and the engines' comparison read the same runs."""
    import json

    from tiltpile import config
    from tiltpile.report import blocks

    d = blocks.dem_z(ROOT / "figures")
    assert {r["preset"] for r in d["rows"]} == set(blocks.DEM_Z_PRESETS)
    checked = 0
    for r in d["rows"]:
        sp = ROOT / config.preset_info(r["preset"]).figures / "same-piles" / "same_piles.json"
        pap = json.loads(sp.read_text())["pile_against_pile"]
        if r["seed"] not in pap["seeds"]:
            assert r["cd_z0"] is None
            continue
        k = pap["seeds"].index(r["seed"])
        for q, col in (("z_start", "z0"), ("z_quiet", "z_quiet")):
            assert r[col] == pytest.approx(pap["per_seed"][q]["value"][k], abs=1e-12), (r, q)
            assert r[f"cd_{col}"] == pap["per_seed"][q]["ref"][k]
        checked += 1
    assert checked >= 10
