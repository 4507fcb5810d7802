"""The paper's values live once (src/tiltpile/paper_values.py): every value has its source and
holds its band; what cannot import them (the paper presets' TOML, the notebooks' parameters, texts
that quote a value) states the same; the code reads them; and the judges compare with them and
the rules say them: a number just inside a band's edge agrees, just outside disagrees, and a
value moved in the module moves its judge and its rule's text with it."""

from __future__ import annotations

import ast
import importlib
import inspect
import json
from pathlib import Path

import nbformat
import pytest

from tiltpile import config, paper_values as pv
from tiltpile.paper_values import Value
from tiltpile.report.judging import AGREES, DISAGREES, INCONCLUSIVE

ROOT = Path(__file__).resolve().parents[1]


def test_every_value_has_a_source_and_holds_its_band():
    assert set(pv.VALUES) >= {"QUIET_DEG", "AVALANCHE_DEG", "Z_MEAN", "DELTA", "ENHANCEMENT",
                              "ORIENTATION_DEG", "SLIDE_KE"}
    for name, v in pv.VALUES.items():
        assert len(v.source) > 20, f"{name} says not where the paper gives it"
        assert v.tol is None or v.band is None, f"{name}: a tolerance or a band, not both"
        if v.tol is not None or v.band is not None:
            assert v.lo < v.value < v.hi, f"{name}: {v.value} outside its band [{v.lo}, {v.hi}]"
    assert pv.FIG5_WINDOWS_DEG[0] == -pv.QUIET_DEG.value      # Fig. 5's farthest window
    assert list(pv.FIG5_WINDOWS_DEG) == sorted(pv.FIG5_WINDOWS_DEG)


def _parameters(notebook: str) -> dict:
    """{name: value} of a notebook's parameters cell (literal values)."""
    book = nbformat.read(ROOT / "notebooks" / notebook, as_version=4)
    cell = next(c for c in book.cells if "parameters" in c.get("metadata", {}).get("tags", []))
    return {node.targets[0].id: ast.literal_eval(node.value) for node in ast.parse(cell.source).body}


def test_what_cannot_import_the_values_states_the_same():
    # the paper presets end their runs in the large slide (a TOML cannot import)
    for name in ("paper", "paper-fresh", "paper-fast"):
        assert config.load(name).protocol.end_ke == pv.SLIDE_KE.value, name
    # the notebooks restate no figure parameter: they take the modules' (test_the_code_reads_the_values)
    for nb in ("fig2_avalanche_criterion.ipynb", "fig5_cluster_sizes.ipynb"):
        assert set(_parameters(nb)) == {"data_dir", "preset", "figures_dir", "overrides"}
    # texts that quote the slide's threshold without formatting it
    from tiltpile.figures import study
    from tiltpile.report import paper

    sci = paper._sci(pv.SLIDE_KE.value)
    assert sci == "1e-3"
    assert f"avalanche_ke ({sci} unless given)" in (ROOT / "src/tiltpile/report/scales.py").read_text()
    assert f"above {sci} m g d" in " ".join(study.QUANTITIES["theta_avalanche"].split())


def test_the_code_reads_the_values():
    from tiltpile import repose
    from tiltpile.analysis import zcount
    from tiltpile.cli import repose as cli_repose
    from tiltpile.figures import fig2, fig5, preparation
    from tiltpile.report import studies

    assert fig2.AVALANCHE_KE == repose.KE_SLIDE == cli_repose.DEFAULTS["ke_slide"] == pv.SLIDE_KE.value
    assert inspect.signature(fig2.compute).parameters["avalanche_ke"].default == pv.SLIDE_KE.value
    assert inspect.signature(repose.repose).parameters["ke_slide"].default == pv.SLIDE_KE.value
    assert studies.QUIET_WINDOW_DEG == preparation.QUIET_PAST_DEG == pv.QUIET_DEG.value
    assert zcount.PAPER_Z == pv.Z_MEAN.value
    sig = inspect.signature(fig5.compute).parameters
    assert tuple(sig["windows"].default) == pv.FIG5_WINDOWS_DEG
    assert sig["delta_guide"].default == pv.DELTA.value


# ------------------------------------------------------------------------------------------------
# the judges and the rules

FIGURE = {"fig2": "fig2_avalanche_criterion", "fig3": "fig3_clusters_failure",
          "fig5": "fig5_cluster_sizes"}


def edge_cases(v):
    """(claim key, figure, numbers, verdict) on both sides of every band's edges, computed from
    the values of ``v`` (the module, or one with its values moved); each step 1% of the band."""
    q = v.QUIET_DEG.value
    onset = {"theta_m_min": q - 5, "theta_m_mean": q - 2, "n_runs_with_onset": 3}
    yield "theta_m", "fig2", dict(onset, theta_m_max=q), AGREES
    yield "theta_m", "fig2", dict(onset, theta_m_max=q - 0.01 * q), DISAGREES

    a = v.AVALANCHE_DEG
    e = 0.01 * a.tol
    slide = {"theta_end_min": a.hi + 5, "avalanche_ke": v.SLIDE_KE.value, "slide_sustain_deg": 0.5}
    for x, want in ((a.hi - e, AGREES), (a.lo + e, AGREES), (a.hi + e, DISAGREES),
                    (a.lo - e, DISAGREES)):
        yield "theta_slide", "fig2", dict(slide, theta_avalanche_per_run=[x, x, x]), want
    # no run slides before the end of its tilt: known to disagree only once the end passes the band
    for end, want in ((a.hi + e, DISAGREES), (a.hi - e, INCONCLUSIVE)):
        yield "theta_slide", "fig2", dict(slide, theta_avalanche_per_run=[None] * 3,
                                          theta_end_min=end), want

    z = v.Z_MEAN
    e = 0.01 * (z.hi - z.lo)
    for lo, hi, want in ((z.lo - 0.1, z.lo - e, DISAGREES), (z.lo - 0.1, z.lo + e, AGREES),
                         (z.hi + e, z.hi + 0.1, DISAGREES), (z.hi - e, z.hi + 0.1, AGREES)):
        yield "z_mean", "fig2", {"z_quiet_run_mean": (lo + hi) / 2, "z_quiet_run_mean_ci_low": lo,
                                 "z_quiet_run_mean_ci_high": hi}, want

    s = v.ONSET_SHIFT_FRAMES.value
    for med, want in ((s, AGREES), (s + 1, DISAGREES)):
        yield "robust", "fig2", {"onset_shift_median_frames": med, "onset_unmatched_fraction": 0.1}, want

    o = v.ORIENTATION_DEG
    e = 0.01 * o.tol
    for x, want in ((o.hi - e, AGREES), (o.lo + e, AGREES), (o.hi + e, DISAGREES),
                    (o.lo - e, DISAGREES)):
        yield "orientation", "fig3", {"orientation_mean_deg": x, "n_clusters_orientation": 50}, want

    en = v.ENHANCEMENT
    e = 0.01 * (en.hi - en.lo)
    for x, want in ((en.lo + e, AGREES), (en.lo - e, DISAGREES), (en.hi - e, AGREES),
                    (en.hi + e, DISAGREES)):
        yield "enhancement", "fig3", {"enhancement_tau0": x, "n_peaks": 100}, want

    d = v.DELTA
    e = 0.01 * d.tol
    for lo, hi, want in ((d.lo - 1, d.lo - e, DISAGREES), (d.lo - 1, d.lo + e, AGREES),
                         (d.hi + e, d.hi + 1, DISAGREES), (d.hi - e, d.hi + 1, AGREES)):
        yield "delta", "fig5", {"delta_pooled": (lo + hi) / 2, "delta_pooled_ci_low": lo,
                                "delta_pooled_ci_high": hi, "n_pooled": 500, "s_min": 2}, want
    # without an interval over runs: the fit's own error widens the band by twice itself
    err = 0.1
    for x, want in ((d.value + d.tol + 2 * err - e, AGREES), (d.value + d.tol + 2 * err + e, DISAGREES)):
        yield "delta", "fig5", {"delta_pooled": x, "delta_pooled_err": err, "n_pooled": 500}, want


def _verdict(claims, key, figure, numbers) -> str:
    """The verdict of claim ``key`` on a figure JSON holding ``numbers`` (as the report judges)."""
    from tiltpile.report.document import judgements

    doc = json.loads(json.dumps({"figure": FIGURE[figure], "preset": "smoke", "n_runs": 3,
                                 "n_grains": 250, "numbers": numbers}))
    rows = judgements({FIGURE[figure]: doc}, [c for c in claims if c.key == key])
    return rows[0][1].verdict


CASES = list(edge_cases(pv))


@pytest.mark.parametrize("key, figure, numbers, want", CASES,
                         ids=[f"{k}-{i}" for i, (k, *_) in enumerate(CASES)])
def test_the_judges_turn_at_the_values_band_edges(key, figure, numbers, want):
    from tiltpile.report import CLAIMS

    assert _verdict(CLAIMS, key, figure, numbers) == want


# values far from the paper's, each formatted differently from the one it stands for
MOVED = {"QUIET_DEG": Value(12.5, "moved"), "AVALANCHE_DEG": Value(30.0, "moved", tol=3.0),
         "Z_MEAN": Value(4.1, "moved", band=(4.05, 4.2)),
         "ONSET_SHIFT_FRAMES": Value(3, "moved"), "ORIENTATION_DEG": Value(45.0, "moved", tol=5.0),
         "ENHANCEMENT": Value(0.3, "moved", band=(0.1, 0.5)),
         "DELTA": Value(3.0, "moved", tol=0.5)}


@pytest.fixture
def moved_paper():
    """tiltpile.report.paper imported anew with the values of MOVED; restored after."""
    from tiltpile.report import paper

    saved = {k: getattr(pv, k) for k in MOVED}
    try:
        for k, val in MOVED.items():
            setattr(pv, k, val)
        yield importlib.reload(paper)
    finally:
        for k, val in saved.items():
            setattr(pv, k, val)
        importlib.reload(paper)


def test_a_moved_value_moves_its_judge_and_its_rule(moved_paper):
    class Moved:
        SLIDE_KE = pv.SLIDE_KE

    for k, val in MOVED.items():
        setattr(Moved, k, val)
    claims = moved_paper.CLAIMS_123 + moved_paper.CLAIMS_456
    for key, figure, numbers, want in edge_cases(Moved):
        assert _verdict(claims, key, figure, numbers) == want, (key, numbers)
    # the real values' edges are no edges of the moved judges
    assert _verdict(claims, "orientation", "fig3", {"orientation_mean_deg": 60.0}) == DISAGREES

    rules, paper = moved_paper.RULES_PAPER, {c.key: c.paper for c in claims}
    z, d = MOVED["Z_MEAN"], MOVED["DELTA"]
    assert "quiet up to 12.5 deg" in rules["theta_m"].test and "12.5" in paper["theta_m"]
    assert "within 3 deg of 30" in rules["theta_slide"].test
    assert "the bound exceeds 33 deg" in rules["theta_slide"].test
    assert "theta_a ~ 30 deg" in rules["theta_slide"].sentence and paper["theta_slide"].startswith("~30 deg")
    assert f"meets [{z.lo:g}, {z.hi:g}]" in rules["z_mean"].test and paper["z_mean"] == "~4.1"
    assert "<= 3 frames" in rules["robust"].test
    assert "within 5 deg" in rules["orientation"].test and paper["orientation"] == "~45 deg"
    assert "[10%, 50%]" in rules["enhancement"].test and paper["enhancement"] == "+30%"
    assert f"meets [{d.lo:g}, {d.hi:g}]" in rules["delta"].test and paper["delta"] == "3 +- 0.5"
    assert "21" not in rules["theta_slide"].test and "3.5" not in rules["z_mean"].sentence


def test_the_report_module_is_restored_after_the_move():
    from tiltpile.report import paper

    assert paper.RULES_PAPER["theta_slide"].test.count("within 2 deg of 21") == 1
