"""A build of a committed preset leaves the committed tree as it was: the figures' JSON hold no wall
time (a fact of the machine and the session, which changes each time the runs are simulated
afresh), and the reports take the wall time of the runs from their committed records
(tiltpile.report.wall) instead, as the figures' JSON gave it before."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tiltpile.figures import same_piles, style
from tiltpile.report import wall

ROOT = Path(__file__).resolve().parents[2]
FIGURES = ROOT / "figures"


def _keys(x, path=""):
    """Every (path, key) of the mappings in ``x``, at any depth."""
    if isinstance(x, dict):
        for k, v in x.items():
            yield path, k
            yield from _keys(v, f"{path}/{k}")
    elif isinstance(x, list):
        for v in x:
            yield from _keys(v, f"{path}[]")


def _meta(seconds: float, runs_timed: int) -> dict:
    cost = {"runs_timed": runs_timed, "seconds_per_run": seconds, "steps_per_run": 4450.0,
            "sweeps_per_run": 1671823.5, "capped_steps_per_run": 1103.5}
    return {"preset": "smoke", "n_runs": 4, "seeds": [0, 1, 2, 3], "config_hash": "f49370597528",
            "cost": cost, "ensembles": [{"label": "fresh", "cost": dict(cost)}]}


def test_the_figure_writer_leaves_out_the_wall_time_and_keeps_the_rest(tmp_path):
    """style.save, the figures' one writer: the same runs timed on another machine (or resumed)
    give the same bytes; the header's deterministic costs and the numbers stay as they are."""
    import matplotlib.pyplot as plt

    # a study's numbers may hold a cost of its own (the solver study's, from its records): kept
    numbers = {"x": 1.5, "cost": {"seconds_per_run": 12.0, "sweeps_per_run": 3.0}}
    written = []
    for seconds, timed in ((20.695795061500576, 4), (14.2395744785008, 3)):
        fig, _ = plt.subplots()
        try:
            paths = style.save(fig, "fig9_test", numbers, tmp_path / str(timed), _meta(seconds, timed))
        finally:
            plt.close(fig)
        written.append(paths["json"].read_bytes())
    assert written[0] == written[1]
    doc = json.loads(written[0])
    header = {k: v for k, v in doc.items() if k != "numbers"}
    found = [f"{p}/{k}" for p, k in _keys(header) if k in style.WALL_CLOCK]
    assert found == [], f"wall-clock fields in the figure's JSON: {found}"
    for cost in (doc["cost"], doc["ensembles"][0]["cost"]):
        assert cost == {"steps_per_run": 4450.0, "sweeps_per_run": 1671823.5, "capped_steps_per_run": 1103.5}
    assert doc["numbers"] == numbers and doc["seeds"] == [0, 1, 2, 3]
    assert list(doc) == ["figure", "preset", "n_runs", "seeds", "config_hash", "cost", "ensembles", "numbers"]
    # the pile-against-pile study's documents are the same documents
    assert same_piles.document(_meta(1.0, 1), "fig9_test", numbers) == doc
    assert style.WALL_CLOCK == wall.WALL_KEYS


def _documents():
    """(path, header) of every committed figure document: fig*.json, preparation.json, and those
    of the definitions studies."""
    for p in sorted(FIGURES.rglob("*.json")):
        if "records" in p.relative_to(FIGURES).parts:
            continue
        doc = json.loads(p.read_text())
        if p.name.startswith("fig") or p.name == "preparation.json":
            yield str(p.relative_to(ROOT)), {k: v for k, v in doc.items() if k != "numbers"}
        elif p.name == "definitions.json":
            for d in doc.get("definitions") or []:
                for stem, fig in (d.get("documents") or {}).items():
                    yield (f"{p.relative_to(ROOT)}:{d.get('key')}:{stem}",
                           {k: v for k, v in fig.items() if k != "numbers"})


def test_no_committed_figure_document_holds_a_wall_time():
    docs = list(_documents())
    assert len(docs) > 150
    held = [f"{name}: {p}/{k}" for name, header in docs for p, k in _keys(header) if k in style.WALL_CLOCK]
    assert held == [], held[:5]
    # the deterministic costs stayed
    assert all("sweeps_per_run" in h["cost"] for name, h in docs if "cost" in h)


def _doc(rel: str) -> dict:
    return json.loads((FIGURES / rel / "fig2_avalanche_criterion.json").read_text())


@pytest.mark.parametrize("rel, records, timed, seconds", [
    # a preset's figures from its records (all 50: 44 timed whole)
    ("paper", "paper/records", 44, 7540.652284326002),
    # `make figures PRESET=paper-fast RUNS=16`: the first 16 of its records
    ("paper-fast", "paper-fast/records", 16, 3554.9080417555006),
    # a side of a pile-against-pile study: the whole ensemble it compared, the preset's records
    ("paper-5x/same-piles/paper", "paper/records", 44, 7540.652284326002),
    ("paper-fast-dem/same-piles/paper-fast-dem", "paper-fast-dem/records", 2, 6900.503803700001),
    # the solver study's sides: the study's own records of each setting
    ("solver-study/same-piles/solver.tol=1e-4/solver.tol=1e-4", "solver-study/records/solver.tol=1e-4",
     6, 141.4728630274999),
    ("solver-study/same-piles/solver.dt=0.02/reference", "solver-study/records/reference", 6, 647.8285331174999),
])
def test_the_wall_time_comes_from_the_committed_records_as_the_json_held_it(rel, records, timed, seconds):
    """The numbers are those the figures' JSON held before they left it (the records do not change)."""
    d = FIGURES / rel
    assert wall.records_of(d)[0] == FIGURES / records
    doc = _doc(rel)
    assert "seconds_per_run" not in doc["cost"]
    assert wall.wall_time(d, doc) == {"runs_timed": timed, "seconds_per_run": seconds}
    got = wall.load(d / "fig2_avalanche_criterion.json")["cost"]
    assert got == {**doc["cost"], "runs_timed": timed, "seconds_per_run": seconds}
    assert set(wall.inputs(d)) == set((FIGURES / records).glob("run_*.npz"))


def test_no_wall_time_without_records_of_the_same_runs(tmp_path):
    """No records committed (smoke), records of another configuration or without one of the
    document's seeds: no wall time, rather than another ensemble's. A document holding its own
    (written before) keeps it."""
    smoke = _doc("smoke")
    assert wall.records_of(FIGURES / "smoke") is None and wall.wall_time(FIGURES / "smoke", smoke) == {}
    assert wall.with_wall_time(smoke, FIGURES / "smoke") is smoke
    paper = tmp_path / "paper"
    paper.mkdir()
    for p in sorted((FIGURES / "paper" / "records").glob("run_000[0-3].npz")):
        (paper / "records").mkdir(exist_ok=True)
        shutil.copyfile(p, paper / "records" / p.name)
    doc = dict(_doc("paper"), seeds=[0, 1, 2, 3])
    assert set(wall.wall_time(paper, doc)) == set(wall.WALL_KEYS)
    assert wall.wall_time(paper, dict(doc, seeds=[0, 1, 2, 3, 4])) == {}
    assert wall.wall_time(paper, dict(doc, config_hash="f49370597528")) == {}
    own = dict(doc, cost=dict(doc["cost"], runs_timed=3, seconds_per_run=1800.0))
    assert wall.with_wall_time(own, paper) is own


def test_the_reports_quote_the_records_wall_time(tmp_path):
    """The per-scale cost rows read the wall time through tiltpile.report.wall: the paper's from
    its records, 'not committed' for a scale without any."""
    from tiltpile.report.scales import render_scales

    root = tmp_path / "figures"
    for rel in ("paper", "smoke"):
        (root / rel).mkdir(parents=True)
        shutil.copyfile(FIGURES / rel / "fig2_avalanche_criterion.json", root / rel / "fig2_avalanche_criterion.json")
    (root / "paper" / "records").symlink_to(FIGURES / "paper" / "records", target_is_directory=True)
    lines = render_scales(root)
    head = next(line for line in lines if line.startswith("| | "))
    cols = [c.strip() for c in head.strip("|").split("|")]
    wall_row = [c.strip() for c in next(line for line in lines if line.startswith("| wall time per run |")).strip("|").split("|")]
    hours = [c.strip() for c in next(line for line in lines if line.startswith("| core-hours, all runs |")).strip("|").split("|")]
    assert wall_row[cols.index("paper")] == "125.7 min (median of 44 of 50 runs)"
    assert hours[cols.index("paper")] == "~105 (median x 50 runs)"
    assert wall_row[cols.index("smoke")] == "not committed (no records)"
    assert hours[cols.index("smoke")] == "n/a"
