"""The reproduction report judges each claim from the figures' numbers, and says when it cannot."""

from __future__ import annotations

import json

import pytest

from tiltpile import report


def _doc(name, numbers):
    return {"figure": name, "preset": "smoke", "n_runs": 3, "n_grains": 250, "numbers": numbers}


def _write(tmp_path, docs):
    for d in docs:
        (tmp_path / f"{d['figure']}.json").write_text(json.dumps(d))


def _row(text: str, claim_text: str) -> str:
    return next(line for line in text.splitlines() if line.startswith(f"| {claim_text}"))


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


def test_no_figures_is_an_error_and_writes_nothing(tmp_path):
    with pytest.raises(FileNotFoundError, match="no fig"):
        report.write_report(tmp_path, tmp_path / "R.md")
    assert not (tmp_path / "R.md").exists()
