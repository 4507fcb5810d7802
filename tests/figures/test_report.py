"""The reproduction report judges each claim from the figures' numbers, and says when it cannot.

The judges are tested on what they return (a Judgement: verdict, reason, values), not on the
sentences: those are the template's, each rendered once for every reason a judge gives
(test_every_judgement_renders_for_every_reason)."""

from __future__ import annotations

import json
import math

import pytest

from tiltpile import config, report
from tiltpile.report import judging


def _doc(name, numbers):
    return {"figure": name, "preset": "smoke", "n_runs": 3, "n_grains": 250, "numbers": numbers}


def _write(tmp_path, docs):
    tmp_path.mkdir(parents=True, exist_ok=True)
    for d in docs:
        (tmp_path / f"{d['figure']}.json").write_text(json.dumps(d))


def _row(text: str, claim_text: str) -> str:
    return next(line for line in text.splitlines() if line.startswith(f"| {claim_text}"))


def _judge(key: str, doc: dict) -> judging.Judgement:
    """Claim ``key``'s judgement on a figure document, as the report judges it."""
    return judging.judge_document(next(c for c in report.CLAIMS if c.key == key), doc)


def test_verdicts_follow_the_numbers(tmp_path):
    _write(tmp_path, [
        _doc("fig5_cluster_sizes", {"delta_pooled": 2.45, "delta_pooled_err": 0.1, "n_pooled": 800,
                                    "s_min": 2, "xi_spearman": -0.5, "xi_slope_log10_per_deg": -0.1,
                                    "xi_n_windows": 10, "s_max_far": 3.0, "s_max_near": None}),
        _doc("fig3_clusters_failure", {"C_argmax_tau": 2, "C_tau0": 0.3, "orientation_mean_deg": 61.0,
                                       "n_clusters_orientation": 500}),
    ])
    out = report.write_report(tmp_path, tmp_path / "R.md")
    text = out.read_text()
    by = {c.key: c.text for c in report.CLAIMS}
    assert "**agrees**" in _row(text, by["delta"])            # 2.45 within 0.25 of 2.5
    assert "**disagrees**" in _row(text, by["xi_grows"])      # xi falls towards the onset
    assert "**inconclusive**" in _row(text, by["smax_grows"])  # NaN near the onset
    assert "**disagrees**" in _row(text, by["c_peak"])        # peak at tau = 2, not 0
    assert "**agrees**" in _row(text, by["orientation"])
    # claims whose figure is missing are reported, not dropped
    assert "**not measured**" in _row(text, by["theta_m"])
    assert "smoke, 3 runs of 250 grains" in _row(text, by["delta"])
    assert len([l for l in text.splitlines() if l.startswith("| ") and "**" in l]) == len(report.CLAIMS)


def test_delta_far_from_the_paper_disagrees_with_a_reason(tmp_path):
    _write(tmp_path, [_doc("fig5_cluster_sizes", {"delta_pooled": 1.5, "delta_pooled_err": 0.05,
                                                  "n_pooled": 900, "s_min": 2})])
    text = report.write_report(tmp_path, tmp_path / "R.md").read_text()
    assert "**disagrees**" in _row(text, [c.text for c in report.CLAIMS if c.key == "delta"][0])
    assert "## Notes" in text
    j = _judge("delta", _doc("fig5_cluster_sizes", {"delta_pooled": 1.5, "delta_pooled_err": 0.05}))
    assert (j.verdict, j.reason) == ("disagrees", "fit_misses_band")    # no interval over runs
    assert j.values["delta"][0] == 1.5 and j.note in text


def test_no_figures_is_an_error_and_writes_nothing(tmp_path):
    with pytest.raises(FileNotFoundError, match="no fig"):
        report.write_report(tmp_path, tmp_path / "R.md")
    assert not (tmp_path / "R.md").exists()


def _fig2(**numbers):
    base = {"cutoff": 0.02, "theta_m_mean": 9.7, "theta_m_min": 7.1, "theta_m_max": 11.7,
            "theta_m_ci_low": 8.1, "theta_m_ci_high": 10.9, "n_runs_with_onset": 6,
            "theta_slide_per_run": [18.4, None, 18.65, None, None, None], "slide_ke": 4e-4,
            "slide_sustain_deg": 0.5, "theta_end_min": 22.0,
            "theta_avalanche_per_run": [18.4, None, 18.65, None, None, None], "avalanche_ke": 1e-3,
            "z_quiet_run_mean": 3.215, "z_quiet_run_mean_ci_low": 3.209,
            "z_quiet_run_mean_ci_high": 3.22, "lost_zero_fraction": 0.49,
            "lost_bimodality": {"ashman_d": 3.3, "delta_bic": 280.0, "valley_depth": 0.6,
                                "valley": 0.002, "means": [-3.1, -2.05], "sds": [0.2, 0.4],
                                "cutoff_between_means": False, "cutoff_density_ratio": 0.72},
            "onset_shift_median_frames": 5.0, "onset_shift_max_frames": 10.0,
            "onset_unmatched_fraction": 0.22}
    base.update(numbers)
    return _doc("fig2_avalanche_criterion", base)


def _verdicts(tmp_path, docs):
    _write(tmp_path, docs)
    text = report.write_report(tmp_path, tmp_path / "R.md").read_text()
    out = {}
    for c in report.CLAIMS:
        row = _row(text, c.text)
        out[c.key] = row.rsplit("**", 2)[-2]
    return out, text


def _verdict(key: str, doc: dict) -> str:
    return _judge(key, doc).verdict


def test_onset_claims_compare_like_with_like(tmp_path):
    v, _ = _verdicts(tmp_path, [_fig2()])                 # the report's rows are the judges'
    assert v["theta_m"] == "disagrees"            # no run quiet up to 14.4 deg
    assert v["theta_slide"] == "inconclusive"     # 4 of 6 runs do not slide before 22 deg
    assert v["z_mean"] == "disagrees"             # 3.5 far outside the interval
    assert v["two_populations"] == "agrees" and v["cutoff_in_gap"] == "disagrees"
    assert v["robust"] == "disagrees"             # median 5 frames
    slide = _judge("theta_slide", _fig2())
    assert slide.reason == "median_bounded" and not slide.values["median_known"]
    assert slide.values["end"] == 22.0 and (slide.values["n_slid"], slide.values["n_runs"]) == (2, 6)
    # more than half the runs slide: the median is known and judged against 21 +- 2 deg
    known = _fig2(theta_avalanche_per_run=[20.1, 21.5, 19.9, 22.6, None], theta_m_max=15.0,
                  onset_shift_median_frames=1.0, z_quiet_run_mean_ci_high=3.46)
    assert [_verdict(k, known) for k in ("theta_slide", "theta_m", "robust", "z_mean")] == ["agrees"] * 4
    slide = _judge("theta_slide", known)
    assert slide.reason == "median_within" and slide.values["median"] == 21.5
    assert slide.values["avalanche_ke"] == 1e-3                 # the threshold it was judged at
    assert _judge("theta_m", known).reason == "quiet_run_found"
    assert _verdict("theta_slide", _fig2(theta_avalanche_per_run=[15.0, 15.5, 16.0, None])) == "disagrees"
    # the avalanche angle is judged at its fixed threshold, not at the first sustained flow above
    # the Fig. 2a threshold (with 4000 grains a slow flow some 3 deg before the slide)
    assert _verdict("theta_slide", _fig2(theta_slide_per_run=[15.0, 15.5, 16.0, 17.0],
                                         theta_avalanche_per_run=[21.2, 20.8, 22.2, 21.25])) == "agrees"
    # the cutoff between the means but on the upper population's peak is not in the gap, even
    # where the density there is a little below the lower peak's (the upper population is the
    # lower peak: 4000 cycled grains, upper mean at 2.4% lost, cutoff 0.17 sd below it)
    bm = dict(_fig2()["numbers"]["lost_bimodality"], cutoff_between_means=True,
              means=[-3.40, -1.62], sds=[0.39, 0.48], cutoff_density_ratio=0.99)
    gap = _judge("cutoff_in_gap", _fig2(lost_bimodality=bm))
    assert (gap.verdict, gap.reason) == ("disagrees", "cutoff_on_population")
    assert round(gap.values["above"], 2) == 0.0 and round(gap.values["below"], 2) == 0.43
    assert gap.values["population"] == "upper" and round(gap.values["split_share"], 2) == 0.43
    # one standard deviation from both means: separated; a little less: not
    c = math.log10(0.02)
    for k, verdict in ((1.05, "agrees"), (0.95, "disagrees")):
        far = dict(bm, means=[c - 2.0, c + k * 0.3], sds=[0.5, 0.3], cutoff_density_ratio=0.2)
        assert _verdict("cutoff_in_gap", _fig2(lost_bimodality=far)) == verdict, k
        far = dict(bm, means=[c - k * 0.5, c + 2.0], sds=[0.5, 0.3], cutoff_density_ratio=0.2)
        assert _verdict("cutoff_in_gap", _fig2(lost_bimodality=far)) == verdict, k
    # without the populations' widths (a JSON before they were written) nothing is judged
    gap = _judge("cutoff_in_gap", _fig2(lost_bimodality=dict(bm, sds=None)))
    assert (gap.verdict, gap.reason) == ("inconclusive", "no_fit")
    # onsets without partners: the median move is "more than 10 frames"
    robust = _judge("robust", _fig2(onset_shift_median_frames=None))
    assert (robust.verdict, robust.reason) == ("disagrees", "median_beyond")
    assert robust.values["median_shift"] == math.inf


def test_onset_and_slide_notes_give_their_own_numbers():
    """The first-onset note quotes the kinetic energy of each scale's own first onsets (not the
    1000-grain range), the slide note says on which side of 21 deg the median misses, and runs
    that end at different angles are not said to share the end of their tilt."""
    doc = _fig2(ke_first_onset_per_run=[2e-5, None, 7e-9, 1.2e-4],
                theta_avalanche_per_run=[17.45, 18.3, 20.65, 19.0])
    onset = _judge("theta_m", doc)
    assert onset.reason == "no_quiet_run" and onset.values["ke_first_onset"] == [7e-9, 1.2e-4]
    slide = _judge("theta_slide", doc)
    assert (slide.verdict, slide.reason) == ("disagrees", "median_off")
    assert slide.values["median"] == pytest.approx(18.65)
    assert slide.values["literature"] - slide.values["median"] > slide.values["tol"] == 2   # below
    assert (slide.values["n_slid"], slide.values["n_runs"], slide.values["end"]) == (4, 4, 22.0)
    # a JSON written before fig2 kept the energies: the note says nothing of them
    assert _judge("theta_m", _fig2()).values["ke_first_onset"] == []
    slide = _judge("theta_slide", _fig2(theta_avalanche_per_run=[23.5, 23.1, 24.0, None]))
    assert slide.reason == "median_off" and slide.values["median"] == pytest.approx(23.75)
    assert slide.values["median"] - slide.values["literature"] > slide.values["tol"]      # above
    assert slide.values["history"] is None                      # no history given: not "fresh"
    fresh = _fig2(theta_avalanche_per_run=[17.45, 18.3, 20.65, 19.0])
    fresh["history"] = {"pretilt_deg": [], "label": "fresh"}
    assert _judge("theta_slide", fresh).values["history"] == "fresh"


def test_fig6_minimum_below_the_single_grain_bound_disagrees():
    six = {"classes": {"1": {"dz_min": -2.5, "dz_mean": -1.0}}, "frac_below_single_grain": 0.001,
           "largest_bin": {"size_lo": 40, "dz_min": -0.39, "dz_mean": -0.18},
           "slope_per_decade": 0.39}

    def fig6():
        return _doc("fig6_cluster_stability", six)
    assert _verdict("dz_min", fig6()) == "disagrees" and _verdict("dz_shift", fig6()) == "disagrees"
    six.update(classes={"1": {"dz_min": -1.5, "dz_mean": -1.0}}, frac_below_single_grain=0.0,
               n_clusters_unstable=1310, frac_clusters_unstable=0.012)
    dz_min = _judge("dz_min", fig6())
    assert dz_min.verdict == "agrees" and dz_min.values["n_unstable"] == 1310
    shift = _judge("dz_shift", fig6())
    assert shift.reason == "stays_negative" and shift.values["plateau"] == []   # no class of 8 up
    # the note gives where the rise levels off (the classes from 8 grains up), at every scale
    six["classes"].update({"2-3": {"dz_mean": -0.3}, "8-15": {"dz_mean": -0.114},
                           "16+": {"dz_mean": -0.116}})
    shift = _judge("dz_shift", fig6())
    assert shift.values["plateau"] == [["8-15", -0.114], ["16+", -0.116]] and shift.values["flat"]
    six["classes"]["16+"]["dz_mean"] = 0.2                      # still rising: not called level
    shift = _judge("dz_shift", fig6())
    assert shift.values["plateau"] == [["8-15", -0.114], ["16+", 0.2]] and not shift.values["flat"]


def test_crossing_uses_the_interval_over_runs():
    one = {"quiet_below_run_mean": 0.032, "quiet_below_run_mean_ci_low": 0.018,
           "quiet_below_run_mean_ci_high": 0.062, "avalanche_below_fraction": 0.73,
           "dz_gen_pre_onset": 0.021}
    j = _judge("crossing", _doc("fig1_isostaticity", one))
    assert (j.verdict, j.reason) == ("disagrees", "quiet_below_line")
    assert j.values["quiet_below"] == [0.032, 0.018, 0.062]
    j = _judge("crossing", _doc("fig1_isostaticity", dict(one, quiet_below_run_mean_ci_low=0.004)))
    assert (j.verdict, j.reason) == ("agrees", "both_halves_hold")


def test_crossing_is_judged_on_both_halves():
    """Quiet frames above the line and just above it before the onsets, but no avalanching frame
    below it: the quiet half alone (the judge before issue 51) agreed; the pile never crosses
    after the onset, so the claim disagrees, and the reason says which half failed."""
    quiet_above = {"quiet_below_run_mean": 0.002, "quiet_below_run_mean_ci_low": 0.001,
                   "quiet_below_run_mean_ci_high": 0.004, "dz_gen_pre_onset": 0.4}
    never_below = dict(quiet_above, avalanche_below_fraction=0.0)
    lo, pre = never_below["quiet_below_run_mean_ci_low"], never_below["dz_gen_pre_onset"]
    assert lo <= 0.01 and pre > 0                         # what the quiet-only judge tested

    def crossing(numbers):
        return _judge("crossing", _doc("fig1_isostaticity", numbers))
    j = crossing(never_below)
    assert (j.verdict, j.reason) == ("disagrees", "avalanche_not_across")   # the quiet half held
    assert j.values["avalanche_below"] == 0.0
    # at least half of the avalanching frames below: agrees; just under half: disagrees
    assert crossing(dict(quiet_above, avalanche_below_fraction=0.5)).verdict == "agrees"
    assert crossing(dict(quiet_above, avalanche_below_fraction=0.49)).verdict == "disagrees"
    # both halves fail: both reasons; avalanching frames not measured: only the quiet half can
    # decide (it fails here, so disagrees; were it to hold, inconclusive)
    both = dict(never_below, quiet_below_run_mean_ci_low=0.03)
    assert (crossing(both).verdict, crossing(both).reason) == ("disagrees", "both_halves_fail")
    j = crossing(dict(both, avalanche_below_fraction=None))
    assert (j.verdict, j.reason) == ("disagrees", "quiet_below_line")
    j = crossing(quiet_above)
    assert (j.verdict, j.reason) == ("inconclusive", "not_measured")
    # the rule the report prints says what the judge tests
    rule = report.RULES["crossing"].test
    assert "at least half of the avalanching frames" in rule and "1%" in rule


def _fig3(**kw):
    return _doc("fig3_clusters_failure", dict({"C_argmax_tau": 0, "C_tau0": 0.75,
                                               "enhancement_tau0": 2.23, "n_peaks": 1050}, **kw))


def test_enhancement_names_the_peak_rule_its_numbers_were_computed_with():
    """fig3 writes peak_rule only off its default ("sigma"): without it the judgement names the
    default peak; with it, that rule; with "c0" the number is C(0) and is judged as one. Our
    value and the note describe the peak the rule names."""
    from tiltpile.analysis import stats
    from tiltpile.report import paper

    assert set(paper.PEAKS) | {"c0"} == set(stats.PEAK_RULES)
    assert paper.PEAK_DEFAULT == stats.DEFAULT_PEAK_RULE
    j = _judge("enhancement", _fig3())
    assert (j.verdict, j.reason) == ("disagrees", "out_of_band")
    assert (j.values["enhancement"], j.values["n_peaks"], j.values["peak_rule"]) == (2.23, 1050, "sigma")
    assert j.values["others"] == ["local", "decile", "c0"]
    assert "(ours: a local maximum more than one standard deviation above" in j.note
    j = _judge("enhancement", _fig3(peak_rule="local", enhancement_tau0=-0.07, n_peaks=5397))
    assert (j.verdict, j.reason) == ("disagrees", "out_of_band")
    assert (j.values["enhancement"], j.values["n_peaks"], j.values["peak_rule"]) == (-0.07, 5397, "local")
    assert "(ours: any local maximum of S_m within a quiet period" in j.note
    assert "(peak: any local maximum" in j.ours
    j = _judge("enhancement", _fig3(peak_rule="decile", enhancement_tau0=0.41, n_peaks=200))
    assert j.verdict == "agrees" and "top decile" in j.ours
    j = _judge("enhancement", _fig3(peak_rule="c0", enhancement_tau0=0.75, n_peaks=18470))
    assert (j.verdict, j.reason) == ("disagrees", "out_of_band")
    assert (j.values["enhancement"], j.values["n_peaks"], j.values["peak_rule"]) == (0.75, 18470, "c0")
    assert "read as C(0)" in j.note
    assert _verdict("enhancement", _fig3(peak_rule="c0", enhancement_tau0=0.4, n_peaks=18470)) == "agrees"
    # fewer peaks than the judge needs: inconclusive, wherever the number lies
    j = _judge("enhancement", _fig3(n_peaks=9))
    assert (j.verdict, j.reason, j.values["in_band"]) == ("inconclusive", "too_few_peaks", False)


def test_scales_table_says_not_yet_run(tmp_path):
    _write(tmp_path, [_fig2()])
    text = report.write_studies(tmp_path, tmp_path / "R.md").read_text()
    assert "## The same numbers at every scale" in text
    row = next(line for line in text.splitlines() if line.startswith("| first 2% onset"))
    assert row.count("not yet run") == len(report.SCALES) - 1 and "9.7 [8.1, 10.9]" in row   # all but the default
    assert all(c.key in report.RULES for c in report.CLAIMS)


def test_preparation_section_counts_runs_quiet_past_the_papers_window(tmp_path):
    from tiltpile.report import render_preparation

    assert render_preparation(tmp_path) == []  # no study run: no section

    def ens(onsets):
        return {"n_runs": len(onsets), "per_run": {"theta_first_onset": onsets},
                "theta_first_onset_mean": 1.0, "theta_first_onset_ci_low": 0.5,
                "theta_first_onset_ci_high": 1.5, "n_runs_with_slide": 1}

    doc = {"numbers": {"reference": "fresh", "below_deg": 15.0,
                       "ensembles": {"fresh": ens([9.0, 10.0, None]), "prepared": ens([14.4, 16.0, 12.0])},
                       "differences": {"prepared": {"theta_first_onset": {"estimate": 3.1, "low": 1.0,
                                                                          "high": 5.0}}}}}
    (tmp_path / "preparation.json").write_text(json.dumps(doc))
    text = "\n".join(render_preparation(tmp_path))
    # a run with no onset to the end of its tilt stayed quiet past 14.4 deg, as one whose first
    # onset comes at 14.4 deg (the paper's Fig. 5 window starts there)
    assert "| fresh | 3 | 1.00 [0.50, 1.50] | 1 of 3 |" in text
    assert "| prepared | 3 | 1.00 [0.50, 1.50] | 2 of 3 |" in text
    assert "**prepared** brings the most runs past the paper's 14.4 deg" in text
    # the count the study writes wins over the per-run onsets
    doc["numbers"]["ensembles"]["prepared"]["n_runs_quiet_past"] = 3
    (tmp_path / "preparation.json").write_text(json.dumps(doc))
    text = "\n".join(render_preparation(tmp_path))
    assert "| prepared | 3 | 1.00 [0.50, 1.50] | 3 of 3 |" in text
    assert "**prepared** brings the most runs past the paper's 14.4 deg" in text and "(3 of 3; fresh piles: 1)" in text
    assert "- prepared: first onset +3.10 deg [+1.00, +5.00] against the fresh piles." in text
    # the slide's difference only when every run of both slid (a mean over the runs that slid
    # favours the early ones); the threshold named is the study's own when it set one
    doc["numbers"]["differences"]["prepared"]["theta_first_slide"] = {"estimate": 2.3, "low": 1.5,
                                                                      "high": 3.2}
    (tmp_path / "preparation.json").write_text(json.dumps(doc))
    assert "fresh piles, first slide" not in "\n".join(render_preparation(tmp_path))
    for e in doc["numbers"]["ensembles"].values():
        e["n_runs_with_slide"] = 3
    doc["numbers"]["slide_ke_reference"] = 1e-3
    doc["ensembles"] = [{"label": "fresh", "analysis": {"slide_ke": 1e-3}}, {"label": "prepared"}]
    (tmp_path / "preparation.json").write_text(json.dumps(doc))
    text = "\n".join(render_preparation(tmp_path))
    assert ("- prepared: first onset +3.10 deg [+1.00, +5.00] against the fresh piles, first slide "
            "in the ramp +2.30 deg [+1.50, +3.20].") in text
    assert "above 1.0e-03 (the study's slide_ke)" in text and "Read from their records" not in text


def test_the_studies_are_read_from_the_default_scales_directory(tmp_path):
    """The preparation and <z>-counting studies are read from the default scale's figures
    directory, also for the paper scale's."""
    from tiltpile import report

    (tmp_path / "preparation.json").write_text(json.dumps({"numbers": {}}))
    (tmp_path / "zcount.json").write_text(json.dumps({"ensembles": {}}))
    (tmp_path / "paper").mkdir()
    assert set(report.load_studies(tmp_path / "paper")) == {"preparation", "zcount"}
    assert report.load_studies(tmp_path / "nowhere") == {}


def test_the_report_names_the_piles_history(tmp_path):
    """The source column names the piles' history from the figure's header, and the theta_m
    judgement says whether the piles were fresh or cycled (a cycled pile is not called fresh)."""
    claim = next(c.text for c in report.CLAIMS if c.key == "theta_m")
    fresh = dict(_fig2(), history={"pretilt_deg": [], "pretilt_per_step_deg": 0.0, "label": "fresh"})
    _, text = _verdicts(tmp_path, [fresh])
    assert "smoke, 3 runs of 250 grains, fresh |" in _row(text, claim)
    assert _judge("theta_m", fresh).values["history"] == "fresh"
    cyc = dict(_fig2(), history={"pretilt_deg": [16.0, -16.0, 16.0, -16.0, 16.0, 0.0],
                                 "pretilt_per_step_deg": 0.0, "label": "±16° 2 cycles"})
    _, text = _verdicts(tmp_path, [cyc])
    assert "smoke, 3 runs of 250 grains, ±16° 2 cycles |" in _row(text, claim)
    j = _judge("theta_m", cyc)
    assert (j.values["history"], j.values["history_label"]) == ("cycled", "±16° 2 cycles")
    # a figure written before the header named the history: neither is claimed
    assert _judge("theta_m", _fig2()).values["history"] is None


def test_scales_table_gives_each_scales_cost(tmp_path):
    """Sweeps, wall time and core-hours per scale from the JSON's cost record; a scale whose runs
    were resumed without a summed wall time says so instead of quoting a part."""
    from tiltpile.report.scales import render_scales

    timed = dict(_fig2(), cost={"runs_timed": 3, "seconds_per_run": 1800.0, "steps_per_run": 1e4,
                                "sweeps_per_run": 9.3e7, "capped_steps_per_run": 10.0})
    _write(tmp_path, [timed])
    lines = render_scales(tmp_path)

    def row(name):
        return next(line for line in lines if line.startswith(f"| {name} |")).split(" | ")[2]

    assert row("NLGS sweeps per run") == "93.0 M"
    assert row("wall time per run") == "30.0 min (median of 3 of 3 runs)"
    assert row("core-hours, all runs") == "~1.5 (median x 3 runs)"
    # the paper ensemble's 50 runs at 2 h 05 min: whole core-hours, never '1e+02'
    _write(tmp_path, [dict(timed, n_runs=50, cost=dict(timed["cost"], seconds_per_run=7542.0))])
    lines = render_scales(tmp_path)
    assert row("core-hours, all runs") == "~105 (median x 50 runs)"
    _write(tmp_path, [dict(timed, cost=dict(timed["cost"], runs_timed=0, seconds_per_run=None))])
    lines = render_scales(tmp_path)
    assert row("wall time per run") == "not recorded whole (resumed runs)"
    assert row("core-hours, all runs") == "n/a"


def test_every_claim_at_every_scale_and_why_a_verdict_changes(tmp_path):
    """The report sets the verdicts of each compared scale side by side (smoke left out, "not yet
    run" where a scale has no figures) and, for a claim whose verdict changes, gives each scale's
    value and the note of the scale where it does not agree (scale-aware: the grains count)."""
    root = tmp_path / "figures"
    bm = {"ashman_d": 3.3, "delta_bic": 280.0, "valley_depth": 0.6, "valley": 0.002,
          "means": [-3.1, -2.05], "sds": [0.2, 0.4], "cutoff_between_means": False,
          "cutoff_density_ratio": 0.72}
    _write(root, [_fig2(lost_bimodality=bm, n_active_mean=1800.0)])
    paper = dict(_fig2(lost_bimodality=dict(bm, cutoff_between_means=True, means=[-3.1, -1.0],
                                            sds=[0.3, 0.3], cutoff_density_ratio=0.5),
                       theta_avalanche_per_run=[21.2, 20.8, 22.2], n_active_mean=7200.0),
                 preset="paper", n_grains=4000)
    _write(root / "paper", [paper])
    _write(root / "smoke", [_fig2()])
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    sec = text.split("## Each claim at every scale")[1].split("\n## ")[0]
    from tiltpile.report.document import COMPARED
    assert "| claim | " + " | ".join(COMPARED) + " |" in sec and "smoke" not in sec
    assert COMPARED[:2] == ("default", "default-fresh") and "paper" in COMPARED

    def cells(name):
        return dict(zip(COMPARED, _row(sec, name).rstrip(" |").split(" | ")[1:]))

    by = {c.key: c.text for c in report.CLAIMS}
    assert cells(by["cutoff_in_gap"]) == {**dict.fromkeys(COMPARED, "not yet run"),
                                          "default": "disagrees", "paper": "agrees"}
    assert [cells(by["theta_slide"])[s] for s in ("default", "default-fresh", "paper")] == [
        "inconclusive", "not yet run", "agrees"]
    assert [cells("piles")[s] for s in ("default", "default-fresh", "paper")] == [
        "250 x 3", "not yet run", "4000 x 3"]
    changed = [line for line in sec.splitlines() if line.startswith("- **")]
    assert {line.split("**")[1] for line in changed} == {by["cutoff_in_gap"], by["theta_slide"]}
    gap = next(line for line in changed if by["cutoff_in_gap"] in line)
    # the note said is the default scale's own judgement (its grains, its active contacts)
    default = _judge("cutoff_in_gap", _fig2(lost_bimodality=bm, n_active_mean=1800.0))
    assert default.reason == "cutoff_beyond_means" and f"At default: {default.note}" in gap
    assert default.values["n_grains"] == 250 and default.values["contacts_at_cutoff"] == 36.0
    assert "At paper" not in gap
    # a note several scales share is said once, naming them
    _write(root / "default-fresh", [_fig2(lost_bimodality=bm, n_active_mean=1800.0)])
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    sec = text.split("## Each claim at every scale")[1].split("\n## ")[0]
    gap = next(line for line in sec.splitlines() if line.startswith(f"- **{by['cutoff_in_gap']}"))
    assert gap.count("the gap between our two populations") == 1
    assert "At default and default-fresh: the gap" in gap
    # one scale alone: no such section
    only = tmp_path / "alone"
    _write(only, [_fig2()])
    assert "## Each claim at every scale" not in report.write_studies(only, tmp_path / "A.md").read_text()


def test_what_changes_a_verdict_is_named_scale_or_history(tmp_path):
    """For each claim whose verdict changes, the contrast table gives its verdicts across the
    pairs that differ in one thing (history at one size, size at one history), "same" where they
    agree and "not yet run" where a scale is missing; a sentence sorts the claims by what moves
    them, and a size pair whose histories differ says so."""
    root = tmp_path / "figures"
    bm = {"ashman_d": 3.3, "delta_bic": 280.0, "valley_depth": 0.6, "valley": 0.002,
          "means": [-3.1, -2.05], "sds": [0.2, 0.4], "cutoff_between_means": False,
          "cutoff_density_ratio": 0.72}
    gap = dict(bm, cutoff_between_means=True, means=[-3.1, -1.0], sds=[0.3, 0.3],
               cutoff_density_ratio=0.5)
    quiet = {"theta_m_min": 15.0, "theta_m_max": 19.0}           # some run quiet past 14.4 deg

    def scale(preset, n, label, **numbers):
        return dict(_fig2(**numbers), preset=preset, n_grains=n, history={"label": label})

    _write(root, [scale("default", 1000, "cycled fast", lost_bimodality=bm, **quiet)])
    _write(root / "default-fresh", [scale("default-fresh", 1000, "fresh", lost_bimodality=bm)])
    _write(root / "paper-fresh", [scale("paper-fresh", 4000, "fresh", lost_bimodality=bm)])
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    sec = text.split("### What changes with scale and history")[1].split("\n## ")[0]
    by = {c.key: c.text for c in report.CLAIMS}
    assert ("| claim | history: default-fresh → default | history: paper-fresh → paper | "
            "scale: default-fresh → paper-fresh | scale: default → paper | "
            "engine: default → default-dem |") in sec
    assert _row(sec, by["theta_m"]).split(" | ")[1:] == [
        "disagrees → agrees", "not yet run", "same", "not yet run", "not yet run |"]
    assert f"Changes with the history: {by['theta_m']}." in sec
    assert by["cutoff_in_gap"] not in sec                       # the same verdict everywhere
    assert "also changes the history" not in sec                # default → paper not run
    _write(root / "paper", [scale("paper", 4000, "cycled", lost_bimodality=gap, **quiet)])
    sec = report.write_studies(root, tmp_path / "R.md").read_text().split(
        "### What changes with scale and history")[1].split("\n## ")[0]
    assert _row(sec, by["cutoff_in_gap"]).split(" | ")[1:] == [
        "same", "disagrees → agrees", "same", "disagrees → agrees", "not yet run |"]
    assert _row(sec, by["theta_m"]).split(" | ")[1:] == [
        "disagrees → agrees", "disagrees → agrees", "same", "same", "not yet run |"]
    line = next(x for x in sec.splitlines() if x.startswith("Changes with both"))
    assert by["cutoff_in_gap"] in line and by["theta_m"] not in line
    assert ("The pair default → paper also changes the history (1000 x 3, cycled fast → "
            "4000 x 3, cycled)") in sec


def test_the_report_reads_every_figure_of_the_compared_scales(tmp_path):
    root = tmp_path / "figures"
    _write(root, [_fig2()])
    _write(root / "paper", [_fig2(), _doc("fig5_cluster_sizes", {})])
    _write(root / "smoke", [_fig2(), _doc("fig5_cluster_sizes", {})])
    read = {p.relative_to(root).as_posix() for p in report.root_inputs(root)}
    assert {"fig2_avalanche_criterion.json", "paper/fig2_avalanche_criterion.json",
            "paper/fig5_cluster_sizes.json", "smoke/fig2_avalanche_criterion.json"} <= read
    assert "smoke/fig5_cluster_sizes.json" not in read      # smoke is compared by Fig. 2 only



def test_the_scale_table_gives_many_angles_as_a_range_and_their_median(tmp_path):
    """With more than eight runs sliding, the per-scale table gives the range and the median (of
    an even count: the mean of the middle two), not every angle."""
    angles = [20.0 + 0.25 * k for k in range(10)] + [None]
    _write(tmp_path, [_fig2(theta_avalanche_per_run=angles)])
    text = report.write_studies(tmp_path, tmp_path / "R.md").read_text()
    row = _row(text, "avalanche angle: first large slide (deg)")
    assert "10 of 11 runs: 20.0-22.2, median 21.1; tilts end >= 22" in row


COMMITTED_REPORTS = [("figures", "figures/REPRODUCTION.md")] + [   # every scale of the report's
    (p.figures, f"{p.figures}/REPRODUCTION.md")
    for p in config.PRESET_TABLE if p.report and p.name != "default"]


@pytest.mark.parametrize("figures, committed", COMMITTED_REPORTS, ids=[c for _, c in COMMITTED_REPORTS])
def test_each_committed_report_is_what_its_committed_json_gives(figures, committed, tmp_path, monkeypatch):
    """A report is never edited by hand nor left behind its figures: rewritten from the committed
    JSON (`make reports` does it for all five), it is the committed file, byte for byte. Figures of
    one scale move the others' per-scale tables, so a landing that forgets one fails here."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    monkeypatch.chdir(root)
    out = tmp_path / "REPRODUCTION.md"
    report.write_report(figures, str(out))
    assert out.read_text() == (root / committed).read_text(), f"{committed} is stale: run `make reports`"


def test_the_per_scale_table_flags_a_threshold_one_run_moves():
    """fig2's leave-one-run-out stability reaches the per-scale table: a bistable threshold is
    flagged with the other value and how many left-out runs give it; a firm one is not."""
    from tiltpile.report.scales import _loo_flag, _loo_range
    bistable = {"ke_threshold": 0.04, "stability": {"ke_threshold": {
        "values": [4e-6, 0.04], "counts": [20, 30], "firm": False, "n": 50},
        "lost_valley": {"low": 0.00279, "high": 0.00286}}}
    assert _loo_flag(bistable, "ke_threshold") == " (bistable: 4.0e-06 for 20 of 50 runs left out)"
    assert _loo_range(bistable, "lost_valley") == " (0.28%-0.29% leaving one run out)"
    firm = {"ke_threshold": 0.04, "stability": {"ke_threshold": {
        "values": [0.04], "counts": [50], "firm": True, "n": 50}}}
    assert _loo_flag(firm, "ke_threshold") == "" and _loo_flag({}, "ke_threshold") == ""
    # left out, three runs take the threshold away (default-dem's): said, not left blank
    gone = {"ke_threshold": 2.5e-4, "stability": {"ke_threshold": {
        "per_run_left_out": [2.5e-4, None, 2.5e-4, 2.5e-4, None, None], "values": [2.5e-4],
        "counts": [3], "firm": False, "n": 6}}}
    assert _loo_flag(gone, "ke_threshold") == " (unstable: none for 3 of 6 runs left out)"


def _same_piles_study(seeds=(0, 1, 2)):
    """A same_piles.json as `tiltpile same-piles` writes it (figures.same_piles.study), of three
    seeds: the DEM's first onset 1 deg later on every pile, its <z> 0.05 higher."""
    from tiltpile.figures import same_piles as sp
    per, diff = {}, {}
    for k in sp.PER_SEED:
        ref = [10.0 + s for s in seeds]
        d = {"theta_first_onset": 1.0, "z_quiet": 0.05}.get(k, 0.0)
        per[k] = {"ref": ref, "value": [r + d for r in ref], "difference": [d] * len(seeds)}
        diff[k] = {"mean": d, "ci_low": d, "ci_high": d, "n": len(seeds), "median": d}
    return {"study": sp.NAME, "ref": "default", "label": "default-dem", "seeds": list(seeds),
            "sigma_limit": 2.0, "n_numbers": 40, "n_with_error": 30, "n_moved": 4, "moved": [],
            "pile_against_pile": {"seeds": list(seeds), "per_seed": per, "difference": diff}}


def test_the_engines_section_says_which_disagreements_both_engines_share(tmp_path):
    """The default piles in both engines: the pile-against-pile table from the study, and the
    paper's claims sorted by which engine disagrees with them. Here <z> disagrees in both; the
    first onset quiet past 14.4 deg only in CD (the DEM's piles quiet far longer); no section
    without the DEM's figures, and the claims without the study (which it says how to make)."""
    root = tmp_path / "figures"
    cd = dict(_fig2(theta_m_min=7.0, theta_m_max=11.7), preset="default", n_grains=1000)
    _write(root, [cd])
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    assert "## Same piles, another model" not in text
    dem = dict(_fig2(theta_m_min=7.0, theta_m_max=16.0), preset="default-dem", n_grains=1000,
               engine="lammps")
    _write(root / "default-dem", [dem])
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    sec = text.split("## Same piles, another model")[1].split("\n## ")[0]
    by = {c.key: c.text for c in report.CLAIMS}
    both = next(x for x in sec.splitlines() if x.startswith("- **In both engines**"))
    cd_only = next(x for x in sec.splitlines() if x.startswith("- **In Contact Dynamics only**"))
    assert by["z_mean"] in both and by["theta_m"] not in both
    assert by["theta_m"] in cd_only and by["z_mean"] not in cd_only
    assert "- **In the DEM only**: none." in sec
    assert "not yet made (`make engines`)" in sec
    study = root / "default-dem" / "same-piles" / "same_piles.json"
    study.parent.mkdir(parents=True)
    study.write_text(json.dumps(_same_piles_study()))
    sec = report.write_studies(root, tmp_path / "R.md").read_text().split(
        "## Same piles, another model")[1].split("\n## ")[0]
    assert "| first 2% onset (deg) | 11.00 | 12.00 | +1.00 [+1.00, +1.00] (3) |" in sec
    assert "| <z> of the quiet frames | 11.000 | 11.050 | +0.050 [+0.050, +0.050] (3) |" in sec
    assert "4 of 30 numbers with a jackknife error differ by more than 2 combined" in sec
    assert root / "default-dem" / "fig2_avalanche_criterion.json" in report.root_inputs(root)
    assert study in report.root_inputs(root)


def test_the_engines_section_at_4000_grains_judges_each_sides_figures_of_the_pair(tmp_path,
                                                                                 monkeypatch):
    """paper-fast's piles in both engines: one line while the pair is not computed, then the
    pile-against-pile table, marked preliminary below the DEM preset's piles (3 here), saying
    that two piles give no figure number an error, and the claims on the figure documents the
    study wrote of each side, sorted like the default pair's."""
    from tiltpile.report import engines
    monkeypatch.setattr(engines, "target", lambda pair=engines.PAPER_PAIR: 3)
    root = tmp_path / "figures"
    _write(root, [dict(_fig2(), preset="default", n_grains=1000)])
    _write(root / "default-dem", [dict(_fig2(), preset="default-dem", n_grains=1000)])

    def sub():
        text = report.write_studies(root, tmp_path / "R.md").read_text()
        return text.split("### At 4000 grains\n")[1].split("\n#")[0]
    assert "is not yet computed" in sub() and "make engines ENGINES=paper-fast" in sub()
    # the paper's own history (paper-dem against the committed paper records): its own subsection
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    own = text.split("### At 4000 grains, with paper's history\n")[1].split("\n#")[0]
    assert ("(preset `paper-dem`: 3 of `paper`'s piles, cycled twice to +-16 deg at the ramp's "
            "rate, in the DEM, several hours each) is not yet computed") in own
    assert "make engines ENGINES=paper`" in own
    # paper-5x's history, which passed its check against paper's (paper-5x-dem): its own too
    own = text.split("### At 4000 grains, with paper-5x's history\n")[1].split("\n#")[0]
    assert ("(preset `paper-5x-dem`: 3 of `paper-5x`'s piles, cycled twice to +-16 deg at 5x the "
            "ramp's rate, in the DEM, several hours each) is not yet computed") in own
    assert "make engines ENGINES=paper-5x`" in own
    big = root / "paper-fast-dem" / "same-piles"
    study = dict(_same_piles_study((0, 1)), ref="paper-fast", label="paper-fast-dem",
                 n_with_error=0, n_moved=0)
    big.mkdir(parents=True)
    (big / "same_piles.json").write_text(json.dumps(study))
    sec = sub()
    assert "2 of 3 piles so far (**preliminary**)" in sec
    assert "| first 2% onset (deg) | 10.50 | 11.50 | +1.00 [+1.00, +1.00] (2) |" in sec
    assert "On 2 piles no figure number has a jackknife error" in sec
    assert "Every figure number ensemble against ensemble" not in sec
    assert "In both engines" not in sec          # no sides' figures yet: no claims judged
    _write(big / "paper-fast", [dict(_fig2(theta_m_min=7.0), preset="paper-fast", n_grains=4000)])
    _write(big / "paper-fast-dem", [dict(_fig2(theta_m_min=16.0, theta_m_max=17.0),
                                         preset="paper-fast-dem", n_grains=4000)])
    sec = sub()
    by = {c.key: c.text for c in report.CLAIMS}
    cd_only = next(x for x in sec.splitlines() if x.startswith("- **In Contact Dynamics only**"))
    both = next(x for x in sec.splitlines() if x.startswith("- **In both engines**"))
    assert by["theta_m"] in cd_only and by["z_mean"] in both
    assert big / "same_piles.json" in report.root_inputs(root)
    assert big / "paper-fast-dem" / "fig2_avalanche_criterion.json" in report.root_inputs(root)
    study.update(seeds=[0, 1, 2], n_with_error=30, n_moved=4)
    (big / "same_piles.json").write_text(json.dumps(study))
    sec = sub()
    assert "**preliminary**" not in sec and "no figure number has a jackknife error" not in sec
    assert "4 of 30 numbers with a jackknife error differ by more than 2" in sec


def _friction_study(mus=(0.2, 0.5, 1.0), orientation=(50.0, 51.0, 52.0), repose=(11.0, 14.7, 16.0),
                    slope=(0.1, -0.2, 0.4), verdict="flat", key="scene.mu"):
    """A friction study's JSON as `tiltpile study` writes it, its numbers given."""
    def c(x):
        return {"estimate": x, "low": x - 0.5, "high": x + 0.5}
    labels = [f"{m:g}" if m != 1.0 else "1.0" for m in mus]
    per_value = {}
    for lab, m, o, r in zip(labels, mus, orientation, repose):
        numbers = {k: c(1.0) for k in ("theta_first_onset", "repose_box", "z_quiet", "n_m_quiet",
                                       "quiet_below", "delta", "s_max_near", "rigid_near")}
        numbers.update(orientation=c(o), repose_surface=c(r),
                       theta_avalanche=dict(c(r + 7.0), n_runs_with=3))
        per_value[lab] = {"value": m, "n_runs": 3, "seeds": [0, 1, 2], "theta_rev_deg": round(r + 1),
                          "repose_piles": "fresh", "numbers": numbers, "per_run": {}}
    mc = {"mu": list(mus), "measured_deg": list(orientation),
          "predicted_deg": [45 + 0.5 * math.degrees(math.atan(m)) for m in mus],
          "fit": {"slope": slope[0], "slope_low": slope[1], "slope_high": slope[2],
                  "intercept": 45.0, "n_resamples": 999}, "verdict": verdict}
    return {"figure": "study",
            "study": {"name": "friction", "key": key, "preset": "default", "runs": 3,
                      "history": "repose+1", "history_offset_deg": 1.0,
                      "command": f"tiltpile study --key {key} --values 0.2 0.5 1.0 --preset default "
                                 "--runs 3 --name friction --history repose+1"},
            "ensembles": [{"n_grains": 1000, "label": lab} for lab in labels],
            "numbers": {"key": key, "values": list(mus), "labels": labels, "confidence": 0.95,
                        "per_value": per_value, "mohr_coulomb": mc if key == "scene.mu" else None}}


def test_the_friction_section_answers_mohr_coulomb_and_sets_the_literature_beside_ours(tmp_path):
    """figures/study-friction/study.json gives the section "Friction": whether the Mohr-Coulomb
    reading survives (by the fit's verdict), the study's table with each friction's history
    amplitude, and the literature's angles beside ours at their friction; none without it, or
    for a study of another key; the report reads the file (its inputs, the Makefile's)."""
    root = tmp_path / "figures"
    _write(root, [dict(_fig2(), preset="default", n_grains=1000)])
    assert "## Friction" not in report.write_studies(root, tmp_path / "R.md").read_text()
    study = root / "study-friction" / "study.json"
    study.parent.mkdir(parents=True)
    study.write_text(json.dumps(_friction_study()))
    assert study in report.root_inputs(root)
    sec = report.write_studies(root, tmp_path / "R.md").read_text().split("\n## Friction")[1]
    sec = sec.split("\n## ")[0]
    assert "**The paper's Mohr-Coulomb reading does not survive a change of friction in our " \
           "piles:** the clusters' orientation does not move with friction (slope 0.10 " \
           "[-0.20, 0.40] against Mohr-Coulomb's 1)" in sec
    assert "the amplitudes (deg): 0.2: 12, 0.5: 16, 1.0: 17." in sec
    assert "| 0.5 | 3 | 16 |" in sec                     # the study's table
    assert "| repose angle theta_r | ~15 deg | 14.7 deg (mu = 0.5) |" in sec
    assert "| avalanche angle theta_a | ~21 deg | 21.7 deg (mu = 0.5) |" in sec
    assert "11.0 (mu = 0.2), 14.7 (mu = 0.5), 16.0 (mu = 1) deg |" in sec     # the trend row
    assert "the repose angle changes by +3.7 deg from mu = 0.2 to 0.5 and by +1.3 deg" in sec
    doc = _friction_study()                 # only the mu = 0.2 piles slide within the ramp
    for lab, v in doc["numbers"]["per_value"].items():
        if lab != "0.2":
            v["numbers"]["theta_avalanche"] = {"estimate": None, "low": None, "high": None,
                                               "n_runs_with": 0}
        else:
            v["numbers"]["theta_avalanche"]["n_runs_with"] = 1
    study.write_text(json.dumps(doc))
    sec = report.write_studies(root, tmp_path / "R.md").read_text().split("\n## Friction")[1]
    assert "| ~21 deg | none: no pile slid within the ramp (mu = 0.5) |" in sec
    assert "the avalanche angle is out of the ramp's reach: 1 of 9 piles slid before its end" in sec
    assert "n/a deg" not in sec
    study.write_text(json.dumps(_friction_study(slope=(0.9, 0.6, 1.3), verdict="consistent")))
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    assert "**The paper's Mohr-Coulomb reading survives a change of friction in our piles:**" in text
    study.write_text(json.dumps(_friction_study(key="scene.polydispersity")))
    assert "## Friction" not in report.write_studies(root, tmp_path / "R.md").read_text()


def test_the_history_rate_section_decides_against_what_chance_moves(tmp_path):
    """paper-fast against paper: no section without the study; with it, the pile table, the
    moved count against the null's, the claims whose verdict differs between the two sides'
    documents, and the decision: preliminary before the preset's 16 seeds, then passes only
    when the count is within chance's 95th percentile and every verdict is the same."""
    from tiltpile.report import history_rate as hr

    root = tmp_path / "figures"
    _write(root, [dict(_fig2(), preset="default", n_grains=1000)])
    assert "## The history at 10x" not in report.write_studies(root, tmp_path / "R.md").read_text()
    fast = root / "paper-fast" / "same-piles"
    study = dict(_same_piles_study(), ref="paper", label="paper-fast", n_moved=20,
                 n_with_error=149, moved=[{"figure": "fig3_clusters_failure", "key": "n_peaks"},
                                          {"figure": "fig5_cluster_sizes", "key": "delta_pooled"}],
                 numbers=[{"figure": "fig3_clusters_failure", "key": "n_peaks", "sigma": -2.345}],
                 null={"flips": 40, "seed": 0, "counts": [], "median": 14.0, "p95": 24.0,
                       "observed": 20, "p_value": 0.2})
    fast.mkdir(parents=True)
    (fast / "same_piles.json").write_text(json.dumps(study))
    paper_side = dict(_fig2(), preset="paper", n_grains=4000,
                      cost={"sweeps_per_run": 95.9e6, "seconds_per_run": 7540.0, "runs_timed": 44})
    fast_side = dict(_fig2(), preset="paper-fast", n_grains=4000,
                     cost={"sweeps_per_run": 38.8e6, "seconds_per_run": 6500.0, "runs_timed": 6})
    _write(fast / "paper", [paper_side])
    _write(fast / "paper-fast", [fast_side])
    read = report.root_inputs(root)
    assert fast / "same_piles.json" in read and fast / "paper-fast" / "fig2_avalanche_criterion.json" in read

    def section():
        return report.write_studies(root, tmp_path / "R.md").read_text().split(
            "## The history at 10x the ramp's rate")[1].split("\n## ")[0]

    sec = section()
    assert "3 of the 16 seeds the decision waits for have run so far: **preliminary**." in sec
    assert "| first 2% onset (deg) | 11.00 | 12.00 | +1.00 [+1.00, +1.00] (3) |" in sec
    assert ("20 of 149 figure numbers with a jackknife error move by more than 2 combined standard "
            "errors; chance alone moves a median of 14 (95th percentile 24) in 40 random "
            "exchanges of each seed's two runs (p = 0.200 +- 0.063 for 20 or more)") in sec
    assert ("Moved (paper-fast minus paper, in combined standard errors): fig3.n_peaks (-2.3), "
            "fig5.delta_pooled.") in sec
    assert "the same verdict for every claim." in sec
    assert "**Decision: not yet** (3 of 16 seeds). So far paper-fast: no difference detected" in sec
    assert "paper 95.9 M sweeps per run, 2.09 h of wall time per run (44 runs timed whole); " \
           "paper-fast 38.8 M sweeps per run" in sec
    # sixteen seeds, a claim that changes its verdict: fails
    study["seeds"] = list(range(16))
    (fast / "same_piles.json").write_text(json.dumps(study))
    _write(fast / "paper-fast", [dict(fast_side, numbers=dict(fast_side["numbers"],
                                                             z_quiet_run_mean=3.5,
                                                             z_quiet_run_mean_ci_low=3.47,
                                                             z_quiet_run_mean_ci_high=3.53))])
    sec = section()
    by = {c.key: c.text for c in report.CLAIMS}
    assert f"different verdicts for {by['z_mean']} (paper" in sec
    assert "**Decision: paper-fast's history's rate moves the figures**" in sec
    assert hr.decide(dict(study, null=dict(study["null"], p_value=0.01, flips=500)), 0) == "moved"
    assert hr.decide(study, 0) == "no difference detected"                 # p = 0.20 +- 0.063
    assert hr.decide(dict(study, null=dict(study["null"], p_value=0.06)), 0) == "undecided"
    assert hr.decide(dict(study, null=None), 0) == "open"
    assert "## The history at 5x" not in report.write_studies(root, tmp_path / "R.md").read_text()

    # paper-5x (issue 53's next step): its own section beside paper-fast's, at its own rate,
    # against its own 8 seeds, with its own side's figures and cost
    five = root / "paper-5x" / "same-piles"
    five.mkdir(parents=True)
    (five / "same_piles.json").write_text(json.dumps(dict(study, label="paper-5x", seeds=[0, 1, 2, 3, 4, 5, 6, 7],
                                                          n_moved=3)))
    _write(five / "paper", [paper_side])
    _write(five / "paper-5x", [dict(fast_side, preset="paper-5x", cost={"sweeps_per_run": 60.1e6})])
    assert five / "paper-5x" / "fig2_avalanche_criterion.json" in report.root_inputs(root)
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    assert "## The history at 10x the ramp's rate: paper-fast against paper" in text
    five_sec = text.split("## The history at 5x the ramp's rate: paper-5x against paper")[1].split("\n## ")[0]
    assert "tilted at 0.005 deg per step instead of the ramp's 0.001 (preset `paper-5x`)" in five_sec
    assert "8 of the 8 seeds the decision waits for have run." in five_sec
    assert "Moved (paper-5x minus paper, in combined standard errors)" in five_sec
    assert "**Decision: no difference detected between paper-5x and paper: a mean shift of the slide below" in five_sec
    assert "paper-5x 60.1 M sweeps per run" in five_sec
    assert hr.speedup(("paper", "paper-5x")) == 5.0 and hr.target(("paper", "paper-5x")) == 8


def test_the_definitions_section_at_4000_grains_says_when_it_is_preliminary(tmp_path):
    """figures/paper-fast/definitions.json gives the section a second time at the larger scale,
    marked preliminary below the 16 piles its verdicts wait for (a study document of the
    committed 1000-grain study, relabelled)."""
    from pathlib import Path

    root = tmp_path / "figures"
    _write(root, [dict(_fig2(), preset="default", n_grains=1000)])
    committed = Path(__file__).resolve().parents[2] / "figures" / "definitions.json"
    doc = dict(json.loads(committed.read_text()), n_runs=5, n_grains=4000)
    (root / "paper-fast").mkdir(parents=True)
    study = root / "paper-fast" / "definitions.json"
    study.write_text(json.dumps(doc))
    assert study in report.root_inputs(root)
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    assert ("## What the disagreements depend on (5 cycled piles of 4000 grains, `paper-fast`; "
            "preliminary, 5 of the 16 piles the verdicts wait for)") in text
    study.write_text(json.dumps(dict(doc, n_runs=16)))
    text = report.write_studies(root, tmp_path / "R.md").read_text()
    assert "## What the disagreements depend on (16 cycled piles of 4000 grains, `paper-fast`)" in text


# ------------------------------------------------------------------------------------------------
# every reason of every judge, rendered: (claim key, numbers, reason, verdict); small synthetic
# numbers, several for a reason whose sentences have branches of their own (history, peak rule, ...)

_Q = {"quiet_below_run_mean": 0.002, "quiet_below_run_mean_ci_low": 0.001,
      "quiet_below_run_mean_ci_high": 0.004, "dz_gen_pre_onset": 0.4}
_BM = {"ashman_d": 3.3, "delta_bic": 280.0, "valley_depth": 0.6, "valley": 0.002,
       "means": [-3.1, -2.05], "sds": [0.2, 0.4], "cutoff_between_means": False,
       "cutoff_density_ratio": 0.72}
_FRESH = {"pretilt_deg": [], "label": "fresh"}
_CYCLED = {"pretilt_deg": [16.0, -16.0, 0.0], "label": "±16° 2 cycles"}
_CI = {"estimate": 0.7, "low": 0.6, "high": 0.8}
_XI = {"xi_spearman": 0.8, "xi_slope_log10_per_deg": 0.1, "xi_n_windows": 10}
_C6 = {"classes": {"1": {"dz_min": -1.5, "dz_mean": -1.0}}, "frac_below_single_grain": 0.0,
       "largest_bin": {"size_lo": 40, "dz_min": -0.3, "dz_mean": 0.05}, "slope_per_decade": 0.4}
_R7 = {"n_onsets": 40, "spanning_before_fraction": 0.2, "spanning_at_fraction": 0.1,
       "loss_to_onset_median": 0.5}


def _every_reason():
    f2 = _fig2()["numbers"]
    yield from [
        ("theta_m", dict(f2, theta_m_max=15.0), "quiet_run_found", "agrees"),
        ("theta_m", dict(f2, history=_FRESH, ke_first_onset_per_run=[1e-5, 2e-4]), "no_quiet_run", "disagrees"),
        ("theta_m", dict(f2, history=_CYCLED, ke_first_onset_per_run=[1e-5]), "no_quiet_run", "disagrees"),
        ("theta_m", f2, "no_quiet_run", "disagrees"),
        ("theta_m", dict(f2, theta_m_max=None), "no_onset", "inconclusive"),
        ("theta_slide", dict(f2, theta_avalanche_per_run=[20.1, 21.5, 19.9]), "median_within", "agrees"),
        ("theta_slide", dict(f2, theta_avalanche_per_run=[15.0, 16.0, None], history=_FRESH),
         "median_off", "disagrees"),
        ("theta_slide", dict(f2, theta_avalanche_per_run=[24.0, 25.0, None]), "median_off", "disagrees"),
        ("theta_slide", dict(f2, theta_avalanche_per_run=[None, None, 25.0], theta_end_min=24.0,
                             history=_FRESH), "median_bounded_beyond", "disagrees"),
        ("theta_slide", f2, "median_bounded", "inconclusive"),
        ("theta_slide", dict(f2, theta_avalanche_per_run=[]), "no_runs", "inconclusive"),
        ("z_mean", dict(f2, z_quiet_run_mean_ci_high=3.46), "interval_meets_band", "agrees"),
        ("z_mean", f2, "interval_misses_band", "disagrees"),
        ("z_mean", dict(f2, z_quiet_run_mean_ci_low=None), "no_interval", "inconclusive"),
        ("z_mean", {}, "not_measured", "inconclusive"),
        ("two_populations", f2, "two_separated", "agrees"),
        ("two_populations", dict(f2, lost_bimodality=dict(_BM, ashman_d=1.2)), "not_separated", "disagrees"),
        ("two_populations", {}, "no_fit", "inconclusive"),
        ("cutoff_in_gap", dict(f2, lost_bimodality=dict(_BM, means=[-4.0, -0.5], sds=[0.3, 0.3])),
         "cutoff_separates", "agrees"),
        ("cutoff_in_gap", dict(f2, n_active_mean=1800.0), "cutoff_beyond_means", "disagrees"),
        ("cutoff_in_gap", f2, "cutoff_beyond_means", "disagrees"),
        ("cutoff_in_gap", dict(f2, lost_bimodality=dict(_BM, cutoff_between_means=True, means=[-3.4, -1.62],
                                                        sds=[0.39, 0.48])), "cutoff_on_population", "disagrees"),
        ("cutoff_in_gap", dict(f2, lost_bimodality=dict(_BM, cutoff_between_means=True, means=[-1.75, -1.0],
                                                        sds=[0.1, 0.3])), "cutoff_on_population", "disagrees"),
        ("cutoff_in_gap", {}, "no_fit", "inconclusive"),
        ("robust", dict(f2, onset_shift_median_frames=1.0), "median_within", "agrees"),
        ("robust", f2, "median_beyond", "disagrees"),
        ("robust", dict(f2, onset_shift_median_frames=None), "median_beyond", "disagrees"),
        ("robust", {}, "not_measured", "inconclusive"),
        ("crossing", dict(_Q, avalanche_below_fraction=0.7), "both_halves_hold", "agrees"),
        ("crossing", dict(_Q, avalanche_below_fraction=0.7, quiet_below_run_mean_ci_low=0.03),
         "quiet_below_line", "disagrees"),
        ("crossing", dict(_Q, avalanche_below_fraction=0.1), "avalanche_not_across", "disagrees"),
        ("crossing", dict(_Q, avalanche_below_fraction=0.1, quiet_below_run_mean_ci_low=0.03),
         "both_halves_fail", "disagrees"),
        ("crossing", _Q, "not_measured", "inconclusive"),
        ("orientation", {"orientation_mean_deg": 61.0, "orientation_median_deg": 60.0,
                         "n_clusters_orientation": 500}, "within_tol", "agrees"),
        ("orientation", {"orientation_mean_deg": 45.0}, "off", "disagrees"),
        ("orientation", {}, "not_measured", "inconclusive"),
        ("failure_in_clusters", {"failing_in_cluster_excess": 0.3, "failing_in_cluster_enrichment": 2.0},
         "enriched", "agrees"),
        ("failure_in_clusters", {"failing_in_cluster_excess": 0.1, "failing_in_cluster_enrichment": 1.2},
         "not_enriched", "disagrees"),
        ("failure_in_clusters", {}, "not_measured", "inconclusive"),
        ("c_peak", {"C_argmax_tau": 0, "C_tau0": 0.75, "C_max": 0.75}, "peak_at_zero", "agrees"),
        ("c_peak", {"C_argmax_tau": -1, "C_tau0": 0.7, "C_max": 0.75}, "peak_off_zero", "disagrees"),
        ("c_peak", {"C_argmax_tau": 2, "C_tau0": 0.7, "C_max": 0.75}, "peak_off_zero", "disagrees"),
        ("c_peak", {}, "no_peak", "inconclusive"),
        ("enhancement", {"enhancement_tau0": 0.4, "n_peaks": 50}, "in_band", "agrees"),
        ("enhancement", {"enhancement_tau0": 0.4, "n_peaks": 50, "peak_rule": "decile"}, "in_band", "agrees"),
        ("enhancement", {"enhancement_tau0": 2.2, "n_peaks": 50}, "out_of_band", "disagrees"),
        ("enhancement", {"enhancement_tau0": 2.2, "n_peaks": 50, "peak_rule": "local"}, "out_of_band", "disagrees"),
        ("enhancement", {"enhancement_tau0": 2.2, "n_peaks": 50, "peak_rule": "next"}, "out_of_band", "disagrees"),
        ("enhancement", {"enhancement_tau0": 0.75, "n_peaks": 50, "peak_rule": "c0"}, "out_of_band", "disagrees"),
        ("enhancement", {"enhancement_tau0": 2.2, "n_peaks": 5}, "too_few_peaks", "inconclusive"),
        ("enhancement", {"enhancement_tau0": 0.4, "n_peaks": 5}, "too_few_peaks", "inconclusive"),
        ("enhancement", {}, "not_measured", "inconclusive"),
        ("clusters_straddle", {"quiet_frac_below": 0.3, "quiet_frac_on": 0.2, "quiet_frac_above": 0.5,
                               "quiet_n": 300}, "straddle", "agrees"),
        ("clusters_straddle", {"quiet_frac_below": 0.0, "quiet_frac_on": 0.2, "quiet_frac_above": 0.8},
         "one_side", "disagrees"),
        ("clusters_straddle", {}, "not_measured", "inconclusive"),
        ("rest_stable", {"z_rest_mean_quiet": 3.8, "z_rest_frac_below_iso_quiet": 0}, "always_above", "agrees"),
        ("rest_stable", {"z_rest_mean_quiet": 3.8, "z_rest_frac_below_iso_quiet": 0.01}, "frames_below",
         "disagrees"),
        ("rest_stable", {"z_rest_mean_quiet": 2.9, "z_rest_frac_below_iso_quiet": 0}, "mean_not_above",
         "disagrees"),
        ("rest_stable", {}, "not_measured", "inconclusive"),
        ("delta", {"delta_pooled": 2.4, "delta_pooled_ci_low": 2.2, "delta_pooled_ci_high": 2.6,
                   "n_pooled": 800, "delta_pooled_n_runs": 6, "s_min": 2}, "interval_meets_band", "agrees"),
        ("delta", {"delta_pooled": 1.5, "delta_pooled_ci_low": 1.4, "delta_pooled_ci_high": 1.6},
         "interval_misses_band", "disagrees"),
        ("delta", {"delta_pooled": 2.45, "delta_pooled_err": 0.1}, "fit_meets_band", "agrees"),
        ("delta", {"delta_pooled": 1.5, "delta_pooled_err": 0.05}, "fit_misses_band", "disagrees"),
        ("delta", {}, "not_measured", "inconclusive"),
        ("xi_grows", {}, "too_few_windows", "inconclusive"),
        ("xi_grows", dict(_XI, xi_spearman=-0.5), "no_growth", "disagrees"),
        ("xi_grows", _XI, "no_late_fit", "inconclusive"),
        ("xi_grows", dict(_XI, windows={"-0.75": {"xi": 2.0}, "-0.25": {"xi": 4.0}}), "upturn", "agrees"),
        ("xi_grows", dict(_XI, windows={"-0.75": {"xi": 2.0}, "-0.25": {"xi": 2.1}}), "no_upturn", "disagrees"),
        ("smax_grows", {"s_max_far": 3.0, "s_max_near": 5.0}, "grows", "agrees"),
        ("smax_grows", {"s_max_far": 3.0, "s_max_near": 2.0}, "does_not_grow", "disagrees"),
        ("smax_grows", {"s_max_far": 3.0}, "not_measured", "inconclusive"),
        ("dz_min", dict(_C6, n_clusters_unstable=1310, frac_clusters_unstable=0.012), "bounds_hold", "agrees"),
        ("dz_min", dict(_C6, frac_below_single_grain=0.001), "bounds_fail", "disagrees"),
        ("dz_min", {}, "not_measured", "inconclusive"),
        ("dz_shift", _C6, "shifts_positive", "agrees"),
        ("dz_shift", dict(_C6, largest_bin={"size_lo": 40, "dz_mean": -0.18}), "stays_negative", "disagrees"),
        ("dz_shift", dict(_C6, largest_bin={"size_lo": 40, "dz_mean": -0.18},
                          classes={"1": {"dz_mean": -1.0}, "8-15": {"dz_mean": -0.114},
                                   "16+": {"dz_mean": -0.116}}), "stays_negative", "disagrees"),
        ("dz_shift", dict(_C6, largest_bin={"size_lo": 40, "dz_mean": -0.18},
                          classes={"1": {"dz_mean": -1.0}, "8-15": {"dz_mean": -0.3},
                                   "16+": {"dz_mean": -0.1}}), "stays_negative", "disagrees"),
        ("dz_shift", {"classes": {}}, "not_measured", "inconclusive"),
        ("rigid_spans", {"quiet_spanning_fraction": _CI, "quiet_rigid_fraction": _CI}, "spans", "agrees"),
        ("rigid_spans", {"quiet_spanning_fraction": dict(_CI, low=0.3)}, "does_not_span", "disagrees"),
        ("rigid_spans", {}, "not_measured", "inconclusive"),
        ("rigid_shrinks", {"rigid_fraction_shrink": {"estimate": -0.1, "low": -0.2, "high": -0.05},
                           "rigid_fraction_far": _CI, "rigid_fraction_near": _CI, "far_deg": 4,
                           "near_deg": 1}, "shrinks", "agrees"),
        ("rigid_shrinks", {"rigid_fraction_shrink": {"estimate": 0.0, "low": -0.1, "high": 0.1}},
         "does_not_shrink", "disagrees"),
        ("rigid_shrinks", {}, "not_measured", "inconclusive"),
        ("rigid_loses_spanning", _R7, "lost_before", "agrees"),
        ("rigid_loses_spanning", dict(_R7, spanning_before_fraction=0.9), "still_spans", "disagrees"),
        ("rigid_loses_spanning", dict(_R7, n_onsets=3, spanning_before_fraction=0.9), "too_few_onsets",
         "inconclusive"),
        ("rigid_loses_spanning", dict(_R7, n_onsets=3), "too_few_onsets", "inconclusive"),
        ("rigid_loses_spanning", {}, "not_measured", "inconclusive"),
        ("rigid_vs_marginal", {}, "neither_before_onset", "agrees"),
        ("rigid_vs_marginal", {"spanning_loss_theta_to_onset": -1.2, "marginal_crossing_theta_to_onset": -0.8},
         "together", "agrees"),
        ("rigid_vs_marginal", {"spanning_loss_theta_to_onset": -2.5}, "apart", "disagrees"),
    ]


def test_every_judgement_renders_for_every_reason():
    """Each judge gives the reason and verdict its numbers call for, with values that are plain
    data (JSON); every sentence of the template renders on them (StrictUndefined: a value a
    sentence names and the judge does not give fails here), every claim has its own sentences,
    and every sentence of the template is one a judge can reach (none orphaned by a typo)."""
    import jinja2

    cases = list(_every_reason())
    assert judging.environment().undefined is jinja2.StrictUndefined
    macros = {name for name in dir(judging._sentences()) if "__" in name and not name.startswith("_")}
    assert len(macros) > 2 * len(report.CLAIMS)
    reached = {"default__ours"}
    for key, numbers, reason, verdict in cases:
        j = _judge(key, _doc("fig", numbers))
        assert (j.claim, j.reason, j.verdict) == (key, reason, verdict), (key, numbers)
        json.dumps(j.values)                                   # plain data
        assert f"{key}__ours" in macros, key                   # the claim's own sentences
        assert j.ours and j.ours == j.ours.strip() and "  " not in j.ours, (key, j.ours)
        note = j.note
        assert note == note.strip() and "\n" not in note, (key, note)
        reached |= {f"{key}__ours", f"{key}__{reason}"}
    assert {c.key for c in report.CLAIMS} == {k for k, *_ in cases}
    m = judging.missing(report.CLAIMS[0])
    assert (m.verdict, m.reason, m.ours) == (judging.MISSING, judging.NO_FIGURE, "n/a")
    assert m.note == f"no {report.CLAIMS[0].figure}_*.json in the figures directory"
    reached |= {"no_figure__ours", "no_figure__note"}
    assert macros <= reached, f"sentences no judge reaches: {sorted(macros - reached)}"
    # a claim without sentences of its own prints its values
    plain = judging.Judgement("new_claim", judging.AGREES, "ok", {"mean": 3.14159, "label": "x"})
    assert (plain.ours, plain.note) == ("mean = 3.14; label = x", "")


def test_a_sentence_naming_a_value_the_judge_did_not_give_fails():
    import jinja2

    with pytest.raises(jinja2.UndefinedError):
        judging.Judgement("theta_m", judging.DISAGREES, "no_quiet_run", {"max": 1.0}).note
