"""``tiltpile zcount`` (cli/zcount.py, figures/zcount.py): a hand-built ensemble with known answers,
the smoke run, bad input and the write-then-rename of its two outputs."""

import json
import os

import numpy as np
import pytest

from tiltpile.analysis import load_observables
from tiltpile.analysis import zcount as zc
from tiltpile.cli import main

# the hand-built runs have 3 frames and ~40 contacts, far below what the 2% cutoff resolves
pytestmark = pytest.mark.filterwarnings("ignore::tiltpile.analysis.ResolutionWarning")

ANALYSIS = "f_n>0 walls=in rattlers=out grains=bulk"


@pytest.fixture
def hand_ensemble(tmp_path, pile_factory, contacts_factory, run_writer):
    """Three runs of the 4 x 4 triangular pile (bulk z = 36/7; test_analysis_observables), three
    identical frames each (no contact lost: all quiet); in run 9
    the bulk contact (8, 9) carries no force, so its force count is 34/7, its gap count 36/7."""
    pos, rad, fixed, _ = pile_factory(4, 4)
    pair = contacts_factory(pos, rad, 4.0)
    d = tmp_path / "hand"
    d.mkdir()
    for seed in (7, 8, 9):
        force = np.column_stack([np.ones(len(pair)), np.zeros(len(pair))])
        status = np.ones(len(pair), np.int8)
        if seed == 9:
            k = np.flatnonzero((pair[:, 0] == 8) & (pair[:, 1] == 9))[0]
            force[k] = 0.0
            status[k] = 0
        run_writer(d / f"run_{seed:04d}.h5", rad, fixed, 4.0, [pos] * 3, [(pair, force, status)] * 3,
                   [0.0, 0.05, 0.1], seed=seed)
    return d


def test_hand_built_ensemble(hand_ensemble, tmp_path, capsys):
    prefix = tmp_path / "out" / "zc"
    assert main(["zcount", str(hand_ensemble), "--out", str(prefix), "--quiet", "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "hand: 3 runs, 9 quiet frames" in out and "wrote" in out
    assert prefix.with_suffix(".png").stat().st_size > 0
    assert sorted(os.listdir(prefix.parent)) == ["zc.json", "zc.png"]   # no temporary left
    doc = json.loads(prefix.with_suffix(".json").read_text())
    assert doc["paper_z"] == 3.5 and doc["every"] == 1
    s = doc["ensembles"]["hand"]
    assert s["runs"] == [7, 8, 9] and s["frames_per_run"] == {"7": 3, "8": 3, "9": 3}
    assert s["check"]["analysis_rule_max_abs_diff"] == pytest.approx(0.0, abs=1e-12)
    assert s["analysis_rule"] == ANALYSIS
    a = s["table"][ANALYSIS]
    assert a["per_run"] == pytest.approx([36 / 7, 36 / 7, 34 / 7])
    assert a["z"] == pytest.approx(106 / 21) and a["n_runs"] == 3
    assert a["low"] <= a["z"] <= a["high"] and a["low"] < a["high"]
    g = s["table"]["gap<=1e-07 walls=in rattlers=out grains=bulk"]
    assert g["per_run"] == pytest.approx([36 / 7] * 3)
    assert (g["low"], g["high"]) == (pytest.approx(36 / 7), pytest.approx(36 / 7))   # degenerate
    # every family x threshold x variant: 6 force + 14 gap thresholds (alert 0.1), 8 variants
    assert len(s["table"]) == (len(zc.FORCE_THRESHOLDS) + len(zc.GAP_THRESHOLDS)) * 8
    assert s["reaches_paper_z"]["any"] and s["reaches_paper_z"]["force_rule_reaches"]
    assert ANALYSIS in s["reaches_paper_z"]["rules"]


def test_smoke_run(smoke_run, tmp_path, capsys):
    """The command on a small ensemble: the smoke run (250 grains) of the session."""
    path, _ = smoke_run
    d = tmp_path / "smoke"
    d.mkdir()
    os.symlink(path, d / path.name)
    prefix = tmp_path / "smoke_zcount"
    assert main(["zcount", str(d), "--out", str(prefix), "--quiet", "--workers", "1"]) == 0
    doc = json.loads(prefix.with_suffix(".json").read_text())
    s = doc["ensembles"]["smoke"]
    frames, _ = load_observables(d, compute_missing=False)
    quiet = frames[~frames["avalanching"]]
    assert sum(s["frames_per_run"].values()) == len(quiet) > 50
    # the analysis's own rule is the cached z, frame by frame
    assert s["check"]["analysis_rule_max_abs_diff"] < 1e-12
    assert s["table"][ANALYSIS]["z"] == pytest.approx(quiet["z"].mean())
    z_all = s["table"]["f_n>0 walls=in rattlers=out grains=all"]["z"]
    assert z_all == pytest.approx(quiet["z_all"].mean())
    assert s["table"][ANALYSIS]["low"] is None   # one run: no interval
    # with rattlers kept, more gap tolerance only adds contacts and a force threshold only removes
    for v in zc.VARIANTS:
        if not v.rattlers:
            continue
        zg = [s["table"][zc.rule_key(zc.Rule("gap", g), v)]["z"] for g in s["gap_thresholds"]]
        zf = [s["table"][zc.rule_key(zc.Rule("force", t), v)]["z"] for t in zc.FORCE_THRESHOLDS]
        assert np.all(np.diff(zg) >= -1e-12) and np.all(np.diff(zf) <= 1e-12)
    assert 2.5 < s["table"][ANALYSIS]["z"] < 3.5
    assert s["table"]["gap<=0.1 walls=in rattlers=out grains=bulk"]["z"] > s["table"][ANALYSIS]["z"]


@pytest.mark.parametrize("case", ["missing", "empty", "every", "twice", "out_under_file"])
def test_bad_input_is_one_line_and_writes_nothing(case, hand_ensemble, tmp_path, capsys):
    d = str(hand_ensemble)
    prefix = tmp_path / "res" / "zc"
    args = {"missing": [str(tmp_path / "nope")], "empty": [str(tmp_path)], "every": [d, "--every", "0"],
            "twice": [d, d]}.get(case, [d])
    if case == "out_under_file":
        (tmp_path / "res").write_text("a file")
    assert main(["zcount", *args, "--out", str(prefix), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("tiltpile zcount: error:") and "\n" not in err
    assert not list(tmp_path.glob("res/zc*")) and not (hand_ensemble / "observables").exists()


def test_a_failure_while_writing_leaves_no_output(hand_ensemble, tmp_path, monkeypatch):
    import tiltpile.figures.zcount as zs

    def broken_chart(summaries, path):
        open(path, "wb").write(b"half a png")
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(zs, "chart", broken_chart)
    prefix = tmp_path / "out" / "zc"
    assert main(["zcount", str(hand_ensemble), "--out", str(prefix), "--quiet", "--workers", "1"]) == 1
    assert os.listdir(prefix.parent) == []
