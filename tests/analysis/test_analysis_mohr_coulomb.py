"""The Mohr-Coulomb test of the clusters' orientation (tiltpile.analysis.mohr_coulomb) on
synthetic studies whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from tiltpile.analysis import mohr_coulomb as mc

MU = np.array([0.2, 0.4, 0.5, 0.8, 1.0])


def test_the_prediction_is_the_issues_table():
    # 45 + 1/2 atan(mu): 50.7, 55.9, 58.3, 64.3, 67.5 deg (issue 56)
    assert np.round(mc.failure_plane_deg(MU), 1).tolist() == [50.7, 55.9, 58.3, 64.3, 67.5]
    assert mc.failure_plane_deg(0.0) == 45.0
    assert mc.failure_plane_deg(1e12) == pytest.approx(90.0)
    with pytest.raises(ValueError, match="friction"):
        mc.failure_plane_deg([-0.1])


def _study(slope, intercept, runs=6, clusters=40, scatter=3.0, seed=1):
    """Per value, ``runs`` runs of ``clusters`` orientations around intercept + slope x, each run
    shifted by its own offset (run-to-run scatter) and its clusters spread around it."""
    rng = np.random.default_rng(seed)
    x = mc.failure_plane_deg(MU)
    groups = [[intercept + slope * xi + rng.normal(0, scatter) + rng.normal(0, 8.0, clusters)
               for _ in range(runs)] for xi in x]
    return x, groups


def test_a_line_without_scatter_is_found_exactly():
    x = mc.failure_plane_deg(MU)
    groups = [[np.full(10, 3.0 + 0.5 * xi), np.full(7, 3.0 + 0.5 * xi)] for xi in x]
    fit = mc.slope_test(x, groups)
    assert fit["slope"] == pytest.approx(0.5, abs=1e-12)
    assert fit["intercept"] == pytest.approx(3.0, abs=1e-9)
    assert fit["slope_low"] == pytest.approx(0.5, abs=1e-12)
    assert fit["slope_high"] == pytest.approx(0.5, abs=1e-12)
    assert np.allclose(fit["residual"], 0.0, atol=1e-9)
    assert fit["n_runs"] == [2] * 5 and fit["n_values"] == 5


def test_mohr_coulomb_is_recognised_and_a_flat_orientation_is_not():
    x, groups = _study(1.0, 0.0)
    fit = mc.slope_test(x, groups)
    assert fit["slope_low"] < 1.0 < fit["slope_high"]
    assert mc.verdict(fit) == "consistent"
    x, groups = _study(0.0, 52.0)
    flat = mc.slope_test(x, groups)
    assert flat["slope_low"] < 0.0 < flat["slope_high"] < 1.0
    assert mc.verdict(flat) == "flat"
    x, groups = _study(0.5, 20.0, scatter=0.5)
    half = mc.slope_test(x, groups)
    assert 0.0 < half["slope_low"] < 0.5 < half["slope_high"] < 1.0
    assert mc.verdict(half) == "shallower"


def test_the_interval_narrows_with_more_runs_and_is_reproducible():
    x, few = _study(1.0, 0.0, runs=3)
    x, many = _study(1.0, 0.0, runs=24)
    a, b = mc.slope_test(x, few), mc.slope_test(x, many)
    assert b["slope_high"] - b["slope_low"] < a["slope_high"] - a["slope_low"]
    assert mc.slope_test(x, few) == a


def test_one_run_per_value_has_no_interval():
    x = mc.failure_plane_deg(MU)
    fit = mc.slope_test(x, [[np.array([50.0 + k])] for k in range(5)])
    assert np.isfinite(fit["slope"])
    assert np.isnan(fit["slope_low"]) and np.isnan(fit["slope_high"])
    assert mc.verdict(fit) == "undetermined"


def test_the_pooled_mean_counts_every_cluster_once():
    assert mc.pooled_mean([np.array([1.0, 2.0, np.nan]), np.array([6.0])]) == 3.0
    assert np.isnan(mc.pooled_mean([np.zeros(0)]))
    with pytest.raises(ValueError, match="groups"):
        mc.slope_test([1.0, 2.0], [[np.ones(2)]])
