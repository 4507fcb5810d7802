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
    """A repository of the committed figures' JSON (no records, no pictures) and the documents
    with generated blocks."""
    for p in (ROOT / "figures").rglob("*.json"):
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
    # what a fixing definition breaks: the claims agreeing under ours and not under it
    d4 = ctx["definitions"]["4000"]
    for name, broken in d4["breaks"].items():
        ours = {r["text"]: r["definitions"] for r in paper}
        for text in broken:
            assert text in ours


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
