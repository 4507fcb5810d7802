"""The definitions study (tiltpile definitions) and the report's section built from it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tiltpile.figures import definitions as fd
from tiltpile.report import definitions as rd
from tiltpile.report.claims import CLAIMS
from tiltpile.report.document import judgements, load_figures
from tiltpile.report.judging import AGREES, DISAGREES

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def smoke_study(smoke_ensemble):
    """The study on the three smoke piles, with the force rule, the list and the peak rules."""
    return fd.study(smoke_ensemble, "smoke", progress=False, only=("list", "peaks-c0"),
                    notebooks_dir=ROOT / "notebooks")


def test_the_list_fitted_to_three_and_a_half_gives_it(smoke_study):
    """The one number fitted: the gap at which the quiet frames' <z> of the list is 3.5. The
    tables of that list (every observable on it) give the quiet <z> within 0.1 of 3.5, where the
    force rule's is far below, and the fit's curve rises through 3.5 at g."""
    fit = smoke_study["fit"]
    g = fit["g"]
    assert 1e-4 < g < 2e-2
    z = dict(zip(fit["grid"], fit["z"]))
    assert min(z.values()) < 3.5 < max(z.values())
    assert all(v < 3.5 for k, v in z.items() if k < g / 1.2)
    assert all(v > 3.5 for k, v in z.items() if k > g * 1.2)
    by_key = {d["key"]: d for d in smoke_study["definitions"]}
    assert by_key["list"]["params"] == {"contact_rule": f"gap:{g:g}"}

    def z_quiet(key):
        return by_key[key]["documents"]["fig2_avalanche_criterion"]["numbers"]["z_quiet_run_mean"]

    assert abs(z_quiet("list") - 3.5) < 0.1
    assert z_quiet("force") < 3.4


def test_a_notebook_parameter_recomputes_its_figure_only(smoke_study):
    """peaks-c0 sets Fig. 3's peak rule: its Fig. 3 reads the enhancement as C(0), and every
    other figure is the force rule's, document for document."""
    by_key = {d["key"]: d for d in smoke_study["definitions"]}
    force, c0 = by_key["force"]["documents"], by_key["peaks-c0"]["documents"]
    for stem in force:
        if stem != "fig3_clusters_failure":
            assert c0[stem] == force[stem]
    n = c0["fig3_clusters_failure"]["numbers"]
    assert n["enhancement_tau0"] == pytest.approx(n["C_tau0"])
    assert force["fig3_clusters_failure"]["numbers"]["enhancement_tau0"] != n["enhancement_tau0"]


def test_the_report_judges_each_definition_as_the_figures(tmp_path):
    """A study whose definitions are the committed figures of two scales: each column of the
    section is the judgements' verdicts on that scale's JSON, and a claim disagreeing under the first
    names the definitions that flip it."""
    a, b = load_figures(ROOT / "figures"), load_figures(ROOT / "figures" / "paper")
    doc = {"n_runs": 6, "n_grains": 1000, "fit": {"g": 0.002, "target": 3.5},
           "definitions": [
               {"key": "force", "label": "force (ours)", "what": "ours", "params": {},
                "notebook": {}, "documents": a},
               {"key": "list", "label": "other", "what": "the paper scale's numbers",
                "params": {"contact_rule": "gap:0.002"}, "notebook": {}, "documents": b}]}
    v = rd.verdicts(doc, CLAIMS)
    for key, figs in (("force", a), ("list", b)):
        assert {c.key: j.verdict for c, j, _ in judgements(figs, CLAIMS)} == \
            {k: verdict for k, (_, verdict) in v[key].items()}
    lines = rd.render(doc, CLAIMS)
    assert lines[1] == "## What the disagreements depend on (6 runs of 1000 grains)"
    table = [ln for ln in lines if ln.startswith("| ") and "claim" not in ln and "*agree" not in ln]
    fixes = {ln.split("**")[1]: ln for ln in lines if ln.startswith("- **") and " fixes " in ln}
    assert list(fixes) == ["other"]
    for c in CLAIMS:
        broke = v["force"][c.key][1] == AGREES and v["list"][c.key][1] != AGREES
        assert (f"*{c.text}*" in fixes["other"].split("; breaks ")[1]) == broke
    assert len(table) == len(CLAIMS)
    for c in CLAIMS:
        if v["force"][c.key][1] == DISAGREES:
            dep = rd.depends_on(doc, CLAIMS, c.key)
            flipped = v["list"][c.key][1] != DISAGREES
            assert ("under other" in dep) == flipped
            assert ("every definition tried" in dep) == (not flipped)
    tally = rd.counts(v["force"])
    assert tally[AGREES] == sum(1 for _, verdict in v["force"].values() if verdict == AGREES)


def test_the_reports_take_the_definitions_axis_from_the_study(tmp_path):
    """With a definitions study beside the figures, paper/STUDIES.md has its section and the main
    report's best and worst definition of each claim are the study's verdicts; without it,
    neither."""
    from tiltpile.report.document import render_studies
    from tiltpile.report.main import context

    figs = tmp_path / "figures"
    (figs / "paper").mkdir(parents=True)
    for p in (ROOT / "figures").glob("fig*.json"):
        shutil.copy(p, figs / p.name)
    for p in (ROOT / "figures" / "paper").glob("fig*.json"):
        shutil.copy(p, figs / "paper" / p.name)
    assert "What the disagreements depend on" not in render_studies(figs)
    assert context(figs)["definitions"]["4000"] == {}
    a = load_figures(figs)
    doc = {"n_runs": 6, "n_grains": 1000, "fit": {"g": 0.002, "target": 3.5},
           "definitions": [{"key": "force", "label": "force (ours)", "what": "ours", "params": {},
                            "notebook": {}, "documents": a}]}
    (figs / "definitions.json").write_text(json.dumps(doc))
    assert "## What the disagreements depend on (6 runs of 1000 grains)" in render_studies(figs)
    (figs / "paper-fast").mkdir()
    (figs / "paper-fast" / "definitions.json").write_text(
        json.dumps(dict(doc, n_runs=16, n_grains=4000, seeds=list(range(2, 18)))))
    ctx = context(figs)
    d4 = ctx["definitions"]["4000"]
    assert d4["piles"] == 16 and d4["seeds"] == "2-17"
    verdicts = {c.key: j.verdict for c, j, _ in judgements(a, CLAIMS)}
    for r in ctx["rows"]:
        e = r["definitions"]
        if verdicts[r["key"]] in ("agrees", "disagrees", "inconclusive"):
            assert e["best"] == e["worst"] == (verdicts[r["key"]], ["force (ours)"]), r["key"]
    assert any(v == DISAGREES for v in verdicts.values())


def test_bad_input_stops_in_one_line_with_nothing_written(tmp_path, capsys):
    from tiltpile.cli import main

    out = tmp_path / "defs.json"
    empty = tmp_path / "empty"
    empty.mkdir()
    for argv, words in ((["definitions", str(tmp_path / "nope"), "--out", str(out)], "no such"),
                        (["definitions", str(empty), "--out", str(out)], "no run_*.h5"),
                        (["definitions", str(empty), "--out", str(tmp_path)], "no run_*.h5")):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert words in err and "\n" not in err
    assert not out.exists()


def test_an_unknown_definition_is_refused_before_anything_runs(tmp_path):
    (tmp_path / "run_0000.h5").write_bytes(b"")   # never opened: the keys are checked first
    with pytest.raises(ValueError, match="no definition \\['nope'\\]"):
        fd.study(tmp_path, only=("nope",), progress=False, notebooks_dir=ROOT / "notebooks")


def test_the_pictures_follow_the_rules():
    """Two grains on the floor, touching; from frame k to k + 1 every force vanishes and nothing
    moves: by force both grains fail, on the contact list (gap:0.01) none does, and with the
    mixed rule (losses by force) both do again."""
    import numpy as np

    from tiltpile.figures.snapshot import FAIL_OUTSIDE, GRAIN, snapshot_layers

    pos = np.array([[1.0, 0.5], [2.0, 0.5]])
    pair = np.array([[0, 1], [0, -1], [1, -1]], dtype=np.int32)
    loaded = np.column_stack([np.ones(3), np.zeros(3)])
    empty = (np.empty((0, 2), np.int32), np.empty((0, 2)), np.empty(0, np.int8))
    snap = {"position": pos, "radius": np.full(2, 0.5), "fixed": np.zeros(2, bool),
            "box_length": 4.0, "pair": pair, "force": loaded, "status": np.ones(3, np.int8),
            "theta_deg": 0.0, "next": empty, "next_position": pos}
    assert snapshot_layers(snap)["category"].tolist() == [FAIL_OUTSIDE] * 2
    assert snapshot_layers(snap, contact_rule="gap:0.01")["category"].tolist() == [GRAIN] * 2
    assert snapshot_layers(snap, contact_rule="gap:0.01", lost_rule="force")["n_failing"] == 2


def test_from_records_the_study_gives_what_the_run_files_give(smoke_ensemble, smoke_study, tmp_path):
    """Records at the default parameters and at the list's (tiltpile record --params) give the
    study's documents of the run files, number for number; a definition without records is left
    out and named."""
    from tiltpile.figures.records import write_records

    g = smoke_study["fit"]["g"]
    by_key = {d["key"]: d for d in smoke_study["definitions"]}
    write_records(smoke_ensemble, tmp_path / "records", workers=1, progress=False)
    write_records(smoke_ensemble, tmp_path / "defs" / "list", workers=1, progress=False,
                  params=by_key["list"]["params"])
    doc = fd.study(tmp_path / "records", "smoke", g=g, progress=False, only=("list", "mixed"),
                   notebooks_dir=ROOT / "notebooks", records=tmp_path / "defs")
    assert doc["missing"] == ["mixed"] and doc["from"] == "records"
    got = {d["key"]: d for d in doc["definitions"]}
    assert list(got) == ["force", "list"]
    for key in got:
        for stem, fig in by_key[key]["documents"].items():
            assert got[key]["documents"][stem]["numbers"] == fig["numbers"], (key, stem)
    with pytest.raises(ValueError, match="give g"):
        fd.study(tmp_path / "records", "smoke", records=tmp_path / "defs", progress=False)


def test_the_cli_writes_each_definitions_records_and_studies_a_chosen_few(smoke_ensemble, smoke_study,
                                                                          tmp_path, capsys):
    """`tiltpile definitions DIR --write-records ROOT --g G --only KEYS` writes ROOT/<key>/ at
    each definition's parameters (what the study reads back), and `--only` chooses the
    definitions a study evaluates, named in its command."""
    from tiltpile.cli import main
    from tiltpile.figures import style
    from tiltpile.figures.records import write_records

    g = smoke_study["fit"]["g"]
    root = tmp_path / "defs"
    assert main(["definitions", str(smoke_ensemble), "--write-records", str(root), "--g", f"{g!r}",
                 "--only", "list", "--workers", "1", "--quiet"]) == 0
    assert capsys.readouterr().out.splitlines() == [f"list: 3 record(s) written; {root / 'list'}"]
    assert sorted(p.name for p in root.iterdir()) == ["list"]
    assert main(["definitions", str(smoke_ensemble), "--write-records", str(root), "--g", f"{g!r}",
                 "--only", "list", "--quiet"]) == 0                        # up to date: none again
    assert capsys.readouterr().out.splitlines() == [f"list: 0 record(s) written; {root / 'list'}"]

    write_records(smoke_ensemble, tmp_path / "records", workers=1, progress=False)
    out = tmp_path / "study.json"
    assert main(["definitions", str(tmp_path / "records"), "--records", str(root), "--g", f"{g!r}",
                 "--only", "list", "--out", str(out), "--quiet"]) == 0
    doc = json.loads(out.read_text())
    assert doc["command"].endswith("--only list") and doc["missing"] == []
    assert [d["key"] for d in doc["definitions"]] == ["force", "list"]
    want = {d["key"]: d for d in smoke_study["definitions"]}["list"]["documents"]
    for stem, fig in want.items():   # as write_study writes them (NaN as null)
        assert doc["definitions"][1]["documents"][stem]["numbers"] == \
            json.loads(json.dumps(style.jsonable(fig["numbers"]))), stem


def test_compacted_definition_records_give_the_same_tables_and_study(smoke_ensemble, smoke_study,
                                                                      tmp_path, capsys):
    """`tiltpile definitions RECORDS --compact ROOT` rewrites each definition's records holding
    only what the default records (or an earlier definition's) do not hold bit for bit: every
    table reads back the same, column for column and bit for bit, the study's JSON is the same
    (but for the --records directory its command names), the records stay up to date for the
    writer, and a second pass changes nothing."""
    from tiltpile.analysis.ensemble_data import load_records
    from tiltpile.cli import main
    from tiltpile.figures.records import write_records
    from tiltpile.record import read_record, record_differences, record_files

    g = smoke_study["fit"]["g"]
    keys = ("list", "mixed", "stride-2", "mixed-stride-2")
    write_records(smoke_ensemble, tmp_path / "records", workers=1, progress=False)
    whole, small = tmp_path / "whole", tmp_path / "small"
    for _ in fd.write_definition_records(smoke_ensemble, whole, g, only=keys, workers=1,
                                         progress=False):
        pass
    shutil.copytree(whole, small)
    argv = ["definitions", str(tmp_path / "records"), "--compact", str(small), "--quiet"]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in lines] == list(keys)
    assert all(" 3 record(s) compacted" in line for line in lines), lines
    params = {d["key"]: d["params"] for d in fd.definitions(g, ROOT / "notebooks")}
    for key in keys:
        assert sum(p.stat().st_size for p in record_files(small / key)) < \
            sum(p.stat().st_size for p in record_files(whole / key))
        for a, b in zip(record_files(whole / key), record_files(small / key)):
            assert record_differences(read_record(a), read_record(b)) == [], (key, b.name)
        ea = load_records(whole / key, "smoke", **params[key])
        eb = load_records(small / key, "smoke", **params[key])
        for table in ("frames", "clusters"):
            ta, tb = getattr(ea, table), getattr(eb, table)
            pd.testing.assert_frame_equal(ta, tb, check_exact=True)
            assert all(ta[c].to_numpy().tobytes() == tb[c].to_numpy().tobytes() for c in ta), (key, table)
    # mixed: the list's clusters and the force rule's losses; nothing of its own but what differs
    with np.load(record_files(small / "mixed")[0]) as z:
        assert not {"clusters__size", "clusters__z", "clusters__speed_max"} & set(z.files)
    docs = []
    for root in (whole, small):
        out = tmp_path / f"{root.name}.json"
        assert main(["definitions", str(tmp_path / "records"), "--records", str(root), "--g", f"{g!r}",
                     "--out", str(out), "--quiet"]) == 0
        docs.append(json.loads(out.read_text()))
    docs[1]["command"] = docs[1]["command"].replace(str(small), str(whole))
    assert json.dumps(docs[0], sort_keys=True) == json.dumps(docs[1], sort_keys=True)
    capsys.readouterr()
    # up to date for the writer (nothing rewritten), unchanged by a second pass
    before = {p: p.read_bytes() for key in keys for p in record_files(small / key)}
    for key, n, _ in fd.write_definition_records(smoke_ensemble, small, g, only=keys, progress=False):
        assert n == 0, key
    assert main(argv) == 0
    assert all(" 0 record(s) compacted" in line for line in capsys.readouterr().out.splitlines())
    assert {p: p.read_bytes() for p in before} == before


@pytest.mark.parametrize("extra, words", [
    (["--only", "list,nope"], "--only list,nope: no definition nope"),
    (["--only", ","], "no definition (none given)"),
    (["--write-records", "ROOT"], "--write-records needs --g"),
    (["--write-records", "ROOT", "--g", "0.002", "--out", "x.json"], "leave out --records and --out"),
    (["--write-records", "ROOT", "--g", "0.002", "--workers", "0"], "--workers must be >= 1"),
    (["--workers", "2", "--out", "x.json"], "--workers is only for --write-records"),
    ([], "--out FILE is required"),
    (["--compact", "ROOT", "--out", "x.json"], "--compact rewrites records, not the study"),
    (["--compact", "ROOT", "--g", "0.002"], "--compact rewrites records, not the study"),
    (["--compact", "ROOT"], "no records run_*.npz (with --compact, DIR holds the records"),
])
def test_bad_options_stop_in_one_line_with_nothing_written(smoke_ensemble, tmp_path, capsys, extra, words):
    from tiltpile.cli import main

    argv = ["definitions", str(smoke_ensemble)] + [
        str(tmp_path / a) if a in ("ROOT", "x.json") else a for a in extra]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err, err
    assert list(tmp_path.iterdir()) == []


def test_every_definition_on_fewer_piles_says_what_it_adds_and_where_its_verdicts_differ(tmp_path):
    """figures/paper-fast/definitions-all.json (every definition, on the piles whose run files
    outlived the larger study) gets its own section, naming its seeds, the definitions only it
    holds, and each verdict of a shared definition that differs from the larger study's; the
    section goes once the larger study holds all of its definitions on all of its piles."""
    a, b = load_figures(ROOT / "figures"), load_figures(ROOT / "figures" / "paper")

    def d(key, figs):
        return {"key": key, "label": key, "what": key, "params": {}, "notebook": {}, "documents": figs}

    fast = tmp_path / "paper-fast"
    fast.mkdir()
    assert rd.render_every(fast, CLAIMS) == []
    big = {"n_runs": 16, "n_grains": 4000, "fit": {"g": 0.002, "given": True},
           "definitions": [d("force", a), d("list", a)]}
    every = {"n_runs": 5, "n_grains": 4000, "seeds": [13, 14, 15, 16, 17], "fit": {"g": 0.002, "given": True},
             "definitions": [d("force", a), d("list", b), d("touching", b)]}
    (fast / rd.FILE).write_text(json.dumps(big))
    (fast / rd.EVERY_FILE).write_text(json.dumps(every))
    lines = rd.render_every(fast, CLAIMS)
    assert lines[1] == ("## What the disagreements depend on (5 cycled piles of 4000 grains, "
                        "`paper-fast`, every definition)")
    v = rd.verdicts(every, CLAIMS)
    w = rd.verdicts(big, CLAIMS)
    differ = [c.text for c in CLAIMS if v["list"][c.key][1] != w["list"][c.key][1]]
    assert differ                                   # the two scales' figures differ somewhere
    said = lines[3]
    assert said.startswith("These 5 piles (seeds 13-17) are the ones whose run files outlived")
    assert "carry *touching*" in said
    assert f"{len(differ)} of {2 * len(CLAIMS)} verdicts differ" in said
    assert all(f"{c} under list" in said for c in differ)
    every["definitions"][1] = d("list", a)          # the same verdicts as the larger study
    (fast / rd.EVERY_FILE).write_text(json.dumps(every))
    assert "every verdict is the same on these piles as on the 16 piles" in rd.render_every(fast, CLAIMS)[3]
    big["seeds"] = list(range(2, 18))               # the larger study on seeds 13-17 too, but
    (fast / rd.FILE).write_text(json.dumps(big))    # without touching: the section still adds it
    assert rd.render_every(fast, CLAIMS)[1].startswith("## What the disagreements depend on (5 ")
    big["definitions"].append(d("touching", b))     # now it holds every definition on every pile
    (fast / rd.FILE).write_text(json.dumps(big))
    assert rd.render_every(fast, CLAIMS) == []
    big["seeds"] = list(range(2, 17))               # ... but not seed 17: the section is back
    (fast / rd.FILE).write_text(json.dumps(big))
    assert rd.render_every(fast, CLAIMS)[1].startswith("## What the disagreements depend on (5 ")


def test_writing_the_records_of_an_unknown_definition_is_refused_before_anything_is_written(tmp_path):
    with pytest.raises(ValueError, match="no definition \\['nope'\\]"):
        next(fd.write_definition_records(tmp_path / "runs", tmp_path / "defs", 0.002, only=("list", "nope")))
    assert not (tmp_path / "defs").exists()
