"""The public analysis functions check their inputs (src/tiltpile/analysis/checks.py): a wrong
shape, length, index, NaN, radius, column or parameter is refused in one line naming the function
and the argument, and what they admit is computed as before (the golden values:
tests/analysis/test_golden_columns.py)."""

from __future__ import annotations

import inspect
import re

import numpy as np
import pandas as pd
import pytest

from tiltpile import analysis
from tiltpile.analysis import checks, stats, tables
from tiltpile.analysis import clusters as cl
from tiltpile.analysis import contacts as ct

# a small frame: 12 grains on a 4 x 3 lattice, the bottom row fixed, 8 contacts
N = 12
POS = np.column_stack([np.arange(N) % 4 + 0.5, np.arange(N) // 4 + 0.5])
RAD = np.full(N, 0.5)
FIXED = np.arange(N) < 4
PAIR = np.array([[0, 4], [1, 5], [4, 5], [4, 8], [5, 9], [8, 9], [4, -2], [11, -3]], np.int32)
C = len(PAIR)
FORCE = np.column_stack([np.linspace(0.0, 1.0, C), np.full(C, 0.1)])
STATUS = np.array([0, 1, 2, 1, 2, 1, 1, 2], np.int8)
ACT = FORCE[:, 0] > 0
VEL = np.zeros((N, 2))
OMEGA = np.zeros(N)
LABELS = cl.critical_clusters(N, PAIR, ACT, STATUS == 2)
Z_I = ct.contact_counts(N, PAIR, ACT)
LF = np.r_[np.full(10, 0.005), 0.05, 0.08, 0.01, np.nan]
THETA = np.linspace(0.0, 13.0, LF.size)
FRAMES = pd.DataFrame({"run": 0, "frame": np.arange(LF.size), "theta_deg": THETA,
                       "lost_fraction": LF, "n_active": 400, "ke_trans": LF * 1e-2,
                       "n_lost": np.nan_to_num(LF * 400, nan=-1).round(),
                       "largest_cluster": np.arange(LF.size) % 5 + 1})
FRAMES = analysis.resegment(FRAMES)
FRAMES["theta_to_onset"] = np.linspace(-5.0, 1.0, LF.size)
CLUSTERS = pd.DataFrame({"run": 0, "frame": np.arange(60) % LF.size, "size": np.arange(60) % 7 + 1,
                         "z": 3.0, "n_m": 0.5, "dz": 2.5})
DENSITY = stats.log_binned_density(np.geomspace(1.0, 100.0, 200))

# (function, call with one wrong argument, exception, what the message says): the message must
# start with "<function>: <argument> must"
BAD = [
    # contacts
    ("active_mask", lambda: ct.active_mask(FORCE[:, :1]), ValueError, r"force must have shape \(C, 2\)"),
    ("active_mask", lambda: ct.active_mask(np.where(FORCE == 0.1, np.nan, FORCE)), ValueError,
     "force must be finite"),
    ("mobilized_mask", lambda: ct.mobilized_mask(FORCE, STATUS[:-1]), ValueError,
     r"status must have shape \(8,\) like force \(C=8\), got \(7,\)"),
    ("mobilized_mask", lambda: ct.mobilized_mask(FORCE, STATUS + 1), ValueError,
     r"status must hold 0 \(open\), 1 \(sticking\) or 2 \(sliding\)"),
    ("mobilized_mask", lambda: ct.mobilized_mask(FORCE, mu=-0.5, eps=0.01), ValueError, "mu must be >= 0"),
    ("mobilized_mask", lambda: ct.mobilized_mask(FORCE, mu=0.5, eps=1.0), ValueError, r"eps must be in \[0, 1\)"),
    ("contact_counts", lambda: ct.contact_counts(N, PAIR + 5, ACT), ValueError,
     r"pair must hold grain indices in \[0, 12\)"),
    ("contact_counts", lambda: ct.contact_counts(N, PAIR.astype(float), ACT), TypeError,
     "pair must hold integers"),
    ("contact_counts", lambda: ct.contact_counts(N, [], []), TypeError,
     r"pair must hold integers .*no contacts: np.empty"),
    ("contact_counts", lambda: ct.contact_counts(N, PAIR[:, 0], ACT), ValueError,
     r"pair must have shape \(C, 2\)"),
    ("contact_counts", lambda: ct.contact_counts(N, PAIR, ACT[:-1]), ValueError,
     r"mask must have shape \(8,\) like pair \(C=8\), got \(7,\)"),
    ("contact_counts", lambda: ct.contact_counts(N, PAIR, np.arange(C)), ValueError,
     "mask must be a boolean mask"),
    ("contact_counts", lambda: ct.contact_counts(12.0, PAIR, ACT), TypeError, "n must be an integer"),
    ("coordination", lambda: ct.coordination(Z_I, Z_I[:-1], ~FIXED), ValueError,
     r"m_i must have shape \(12,\) like z_i \(N=12\)"),
    ("coordination", lambda: ct.coordination(Z_I, Z_I, ~FIXED[:-1]), ValueError, "select must have shape"),
    ("dz_gen", lambda: ct.dz_gen(np.ones(3), np.ones(4)), ValueError,
     r"z and n_m must have the same shape \(or broadcast\), got z \(3,\), n_m \(4,\)"),
    ("dz_gen", lambda: ct.dz_gen(3.5, "0.2"), TypeError, "n_m must hold numbers"),
    ("dz_gen", lambda: ct.dz_gen(3.5, 0.2, d=0), ValueError, "d must be an integer >= 1"),
    ("dz_local", lambda: ct.dz_local(np.ones(3), np.ones(2)), ValueError, "z and n_m must have the same shape"),
    ("rattler_mask", lambda: ct.rattler_mask(Z_I, FIXED[:5]), ValueError, "fixed must have shape"),
    ("rattler_mask", lambda: ct.rattler_mask(Z_I, FIXED, min_contacts=-1), ValueError,
     "min_contacts must be >= 0"),
    ("contact_gaps", lambda: ct.contact_gaps(PAIR, POS, -RAD, 4.0), ValueError, r"radius must be > 0 \(d\)"),
    ("contact_gaps", lambda: ct.contact_gaps(PAIR, POS[:, :1], RAD, 4.0), ValueError,
     r"position must have shape \(12, 2\) like radius \(N=12\), got \(12, 1\)"),
    ("contact_gaps", lambda: ct.contact_gaps(PAIR, POS, RAD, 0.0), ValueError, "box_length must be > 0"),
    ("top_layer", lambda: ct.top_layer(np.column_stack([POS, POS[:, 0]]), RAD, FIXED, 4.0), ValueError,
     r"position must have shape \(12, 2\) like radius \(N=12\), got \(12, 3\)"),
    ("top_layer", lambda: ct.top_layer(np.where(POS > 3, np.nan, POS), RAD, FIXED, 4.0), ValueError,
     "position must be finite"),
    ("top_layer", lambda: ct.top_layer(POS, RAD, FIXED, 4.0, ray_spacing=0), ValueError,
     "ray_spacing must be > 0"),
    ("top_layer", lambda: ct.top_layer(POS, RAD, FIXED, "4"), TypeError, "box_length must be a number"),
    ("bottom_layer", lambda: ct.bottom_layer(PAIR, np.zeros(C + 1), FIXED), ValueError,
     r"gaps must have shape \(8,\) like pair \(C=8\)"),
    ("bottom_layer", lambda: ct.bottom_layer(PAIR, np.zeros(C), FIXED[:6]), ValueError,
     r"pair must hold grain indices in \[0, 6\)"),
    ("bulk_mask", lambda: ct.bulk_mask(POS, RAD, FIXED, PAIR, 4.0, top=np.ones(3, bool)), ValueError,
     r"top must have shape \(12,\)"),
    ("bulk_mask", lambda: ct.bulk_mask(POS, RAD[:-1], FIXED, PAIR, 4.0), ValueError, "position must have shape"),
    ("bulk_coordination", lambda: ct.bulk_coordination(PAIR, ACT, STATUS == 2, ~FIXED[:-1], FIXED),
     ValueError, r"bulk must have shape \(12,\) like fixed \(N=12\)"),
    ("bulk_coordination", lambda: ct.bulk_coordination(PAIR, ACT[:3], STATUS == 2, ~FIXED, FIXED),
     ValueError, "active must have shape"),
    ("pair_keys", lambda: ct.pair_keys(PAIR - 3, N), ValueError, "pair must hold grain indices"),
    ("lost_contacts", lambda: ct.lost_contacts(PAIR, ACT, PAIR[:4], ACT, N), ValueError,
     r"active_b must have shape \(4,\) like pair_b \(C=4\)"),
    ("failing_grains", lambda: ct.failing_grains(N, PAIR, ACT, FIXED[:3]), ValueError,
     "fixed must have shape"),
    ("kinetic_energy", lambda: ct.kinetic_energy(RAD, np.nan, OMEGA), ValueError,
     r"velocity must have shape \(12, 2\) like radius \(N=12\), got \(\)"),
    ("kinetic_energy", lambda: ct.kinetic_energy(RAD, VEL, OMEGA[:3]), ValueError, "omega must have shape"),
    ("displacement", lambda: ct.displacement(POS, POS[:, :1]), ValueError, r"reference must have shape \(N, 2\)"),
    ("displacement", lambda: ct.displacement(POS, POS[:3]), ValueError,
     "position and reference must have the same shape"),
    ("gravity_vector", lambda: ct.gravity_vector("steep"), TypeError, "theta_deg must hold numbers"),
    # clusters
    ("critical_grains", lambda: cl.critical_grains(N, PAIR, ACT, include=np.ones(3, bool)), ValueError,
     r"include must have shape \(12,\) like n = 12"),
    ("critical_clusters", lambda: cl.critical_clusters(N, PAIR, ACT, STATUS[:3] == 2), ValueError,
     "mobilized must have shape"),
    ("critical_clusters", lambda: cl.critical_clusters(5, PAIR, ACT, STATUS == 2), ValueError,
     r"pair must hold grain indices in \[0, 5\)"),
    ("cluster_sizes", lambda: cl.cluster_sizes(LABELS.astype(float)), TypeError, "labels must hold integers"),
    ("cluster_sizes", lambda: cl.cluster_sizes(LABELS - 2), ValueError, "labels must be cluster labels"),
    ("gyration_axes", lambda: cl.gyration_axes(LABELS, POS[:-1]), ValueError,
     r"position must have shape \(12, 2\) like labels \(N=12\)"),
    ("orientation_to_gravity", lambda: cl.orientation_to_gravity(np.ones(3), np.ones(2)), ValueError,
     "phi_deg and theta_deg must have the same shape"),
    ("cluster_table", lambda: cl.cluster_table(LABELS, POS, Z_I, Z_I[:4], 10.0), ValueError,
     r"m_i must have shape \(12,\) like labels \(N=12\)"),
    ("cluster_table", lambda: cl.cluster_table(LABELS, POS, Z_I, Z_I, np.array([10.0, 20.0])), TypeError,
     "theta_deg must be a number"),
    ("cluster_table", lambda: cl.cluster_table(LABELS, POS, Z_I, Z_I, np.nan), ValueError,
     "theta_deg must be a finite number"),
    # avalanche
    ("criterion_resolution", lambda: analysis.criterion_resolution(400, cutoff=0), ValueError,
     r"cutoff must be in \(0, 1\)"),
    ("frame_spacing_check", lambda: analysis.frame_spacing_check(LF, cutoff="2%"), TypeError,
     "cutoff must be a number"),
    ("segment_avalanches", lambda: analysis.segment_avalanches(LF * 100), ValueError,
     r"lost_fraction must be in \[0, 1\] or NaN, got 5.0 at frame 10"),
    ("segment_avalanches", lambda: analysis.segment_avalanches(LF[None, :]), ValueError,
     r"lost_fraction must have shape \(F,\)"),
    ("segment_avalanches", lambda: analysis.segment_avalanches(LF, merge_gap=-1), ValueError,
     "merge_gap must be an integer >= 0"),
    ("stretches", lambda: analysis.stretches(LF), ValueError, "mask must be a boolean mask"),
    ("theta_relative_to_onset", lambda: analysis.theta_relative_to_onset(THETA, LF > 0.02, [11, 10]),
     ValueError, "onsets must be increasing frame indices"),
    ("theta_relative_to_onset", lambda: analysis.theta_relative_to_onset(THETA, LF > 0.02, [10, 99]),
     ValueError, r"onsets must hold frame indices in \[0, 14\)"),
    ("theta_relative_to_onset", lambda: analysis.theta_relative_to_onset(THETA, (LF > 0.02)[:-1], [10]),
     ValueError, r"avalanching must have shape \(14,\) like theta_deg \(F=14\)"),
    ("onset_robustness", lambda: analysis.onset_robustness(LF, THETA[:-1]), ValueError,
     r"theta_deg must have the length of lost_fraction \(14\)"),
    ("onset_robustness", lambda: analysis.onset_robustness(LF, THETA, cutoffs=(0.01, 2.0)), ValueError,
     r"cutoffs must be in \(0, 1\)"),
    ("onset_robustness_ensemble", lambda: analysis.onset_robustness_ensemble(FRAMES.drop(columns="theta_deg")),
     ValueError, "frames must have the column.*'theta_deg'"),
    ("displacement_since_period_start",
     lambda: analysis.displacement_since_period_start(np.zeros((5, 4)), np.zeros(5, int)), ValueError,
     r"positions must have shape \(F, N, 2\)"),
    ("displacement_since_period_start",
     lambda: analysis.displacement_since_period_start(np.zeros((5, 4, 2)), np.full(5, 7)), ValueError,
     r"period_start must hold frame indices in \[0, 5\)"),
    ("resegment", lambda: analysis.resegment(FRAMES.drop(columns="lost_fraction")), ValueError,
     "frames must have the column.*'lost_fraction'"),
    ("resegment", lambda: analysis.resegment(FRAMES.to_dict()), TypeError, "frames must be a pandas DataFrame"),
    ("first_slide", lambda: analysis.first_slide(THETA, LF, "high", 0.5), TypeError, "threshold must be a number"),
    ("run_onsets", lambda: analysis.run_onsets(FRAMES, 1e-4, 0.5, ke_column="ke"), ValueError,
     "frames must have the column.*'ke'"),
    ("run_onsets", lambda: analysis.run_onsets(FRAMES, 1e-4, -0.5), ValueError, "sustain_deg must be >= 0"),
    # observables, tables
    ("frame_observables", lambda: analysis.frame_observables(RAD, FIXED, 4.0, POS, VEL[:, 0], OMEGA, PAIR,
                                                             FORCE, STATUS, 10.0), ValueError,
     r"velocity must have shape \(12, 2\) like radius \(N=12\), got \(12,\)"),
    ("frame_observables", lambda: analysis.frame_observables(RAD, FIXED, 4.0, POS, VEL, OMEGA, PAIR,
                                                             FORCE[:-1], STATUS, 10.0), ValueError,
     r"force must have shape \(8, 2\) like pair \(C=8\), got \(7, 2\)"),
    ("frame_observables", lambda: analysis.frame_observables(RAD, FIXED, 4.0, POS, VEL, OMEGA, PAIR + 4,
                                                             FORCE, STATUS, 10.0), ValueError,
     r"pair must hold grain indices in \[0, 12\) \(radius \(N=12\)\)"),
    ("frame_contacts", lambda: tables.frame_contacts(RAD, FIXED[:-1], 4.0, POS, PAIR, FORCE, STATUS),
     ValueError, r"fixed must have shape \(12,\) like radius \(N=12\)"),
    ("frame_contacts", lambda: tables.frame_contacts(RAD, FIXED, 4.0, POS, PAIR, FORCE, STATUS, mu=-1.0),
     ValueError, "mu must be >= 0"),
    ("run_observables", lambda: analysis.run_observables(object(), run_id=1), TypeError,
     "run must be a run file's path or a reader"),
    ("run_observables", lambda: analysis.run_observables("tests/analysis/golden/run.h5", run_id=-1),
     ValueError, "run_id must be an integer >= 0"),
    ("run_table", lambda: analysis.run_table(FRAMES.drop(columns="ke_trans")), ValueError,
     "frames must have the column.*'ke_trans'"),
    ("run_files", lambda: analysis.run_files(None), TypeError, "ensemble_dir must be a directory's path"),
    ("compute_observables", lambda: analysis.compute_observables(3), TypeError,
     "ensemble_dir must be a directory's path"),
    ("load_observables", lambda: analysis.load_observables(["data"]), TypeError,
     "ensemble_dir must be a directory's path"),
    # stats
    ("log_binned_density", lambda: stats.log_binned_density(LF, bins_per_decade=0), ValueError,
     "bins_per_decade must be an integer >= 1"),
    ("log_binned_density", lambda: stats.log_binned_density(LF, xmin=1.0, xmax=0.1), ValueError,
     r"xmin must be <= xmax \(0.1\)"),
    ("log_int_edges", lambda: stats.log_int_edges(100, s_min=0), ValueError, "s_min must be an integer >= 1"),
    ("discrete_log_binned_density", lambda: stats.discrete_log_binned_density([1.0, 2.5]), ValueError,
     r"s must hold integers \(sizes\)"),
    ("density_2d", lambda: stats.density_2d(np.ones(3), np.ones(4)), ValueError,
     r"y must have as many samples as x \(3\), got 4"),
    ("cell_density_2d", lambda: stats.cell_density_2d(np.ones(3), np.ones(3), -np.ones(3), np.ones(3),
                                                       [0.0, 1.0], [0.0, 1.0]), ValueError,
     r"wx must be >= 0 \(cell widths\)"),
    ("cell_density_2d", lambda: stats.cell_density_2d(np.ones(3), np.ones(3), np.ones(3), np.ones(3),
                                                       [1.0, 0.0], [0.0, 1.0]), ValueError,
     "xedges must be at least 2 increasing bin edges"),
    ("fit_power_law_cutoff", lambda: stats.fit_power_law_cutoff(np.arange(1, 100), s_min=0), ValueError,
     "s_min must be an integer >= 1"),
    ("fit_power_law_cutoff", lambda: stats.fit_power_law_cutoff(np.arange(1, 100), xi_bounds=(10, 1)),
     ValueError, r"xi_bounds must be \(low, high\) with 0 < low < high"),
    ("sample_power_law_cutoff", lambda: stats.sample_power_law_cutoff(2.0, -5.0, 10), ValueError,
     "xi must be > 0"),
    ("sample_power_law_cutoff", lambda: stats.sample_power_law_cutoff(2.0, 5.0, 10.5), TypeError,
     "size must be an integer"),
    ("window_edges", lambda: stats.window_edges(0.0), ValueError, "width must be > 0"),
    ("cluster_size_windows", lambda: stats.cluster_size_windows(CLUSTERS, FRAMES.drop(columns="largest_cluster")),
     ValueError, "frames must have the column.*'largest_cluster'"),
    ("cluster_size_windows", lambda: stats.cluster_size_windows(CLUSTERS, FRAMES, lo=1.0, hi=0.0),
     ValueError, r"lo must be <= hi \(0.0\)"),
    ("dz_by_size", lambda: stats.dz_by_size(CLUSTERS.drop(columns="dz")), ValueError,
     "clusters must have the column.*'dz'"),
    ("dz_by_size", lambda: stats.dz_by_size(CLUSTERS, [5, 2]), ValueError,
     "size_edges must be at least 2 increasing bin edges"),
    ("parity_log_edges", lambda: stats.parity_log_edges(-1), ValueError, "s_max must be an integer >= 0"),
    ("dz_distribution", lambda: stats.dz_distribution(CLUSTERS, 3, 3), ValueError,
     "size_hi must be an integer >= 4"),
    ("correlation_function", lambda: stats.correlation_function(LF, LF[:-1], LF > 0.02), ValueError,
     r"b must have the length of a \(14\), got 13"),
    ("correlation_function", lambda: stats.correlation_function(LF, LF, LF < 0.02, taus=[0, 0.5]),
     ValueError, "taus must be whole numbers of frames"),
    ("correlation_function_ensemble",
     lambda: stats.correlation_function_ensemble(FRAMES, b="n_failing"), ValueError,
     "frames must have the column.*'n_failing'"),
    ("ensemble_periods", lambda: stats.ensemble_periods(FRAMES.drop(columns="period")), ValueError,
     "frames must have the column.*'period'"),
    ("cluster_peaks", lambda: stats.cluster_peaks(LF, LF < 0.02, period=np.zeros(3)), ValueError,
     r"period must have the length of s_max \(14\)"),
    ("cluster_peaks", lambda: stats.cluster_peaks(LF, LF < 0.02, threshold_sigma=None), TypeError,
     "threshold_sigma must be a number"),
    ("failure_enhancement", lambda: stats.failure_enhancement(LF, LF[:5], LF < 0.02), ValueError,
     r"n_fail must have the length of s_max \(14\)"),
    ("failure_enhancement_ensemble",
     lambda: stats.failure_enhancement_ensemble(FRAMES, a="largest"), ValueError,
     "frames must have the column.*'largest'"),
    ("check_peak_rule", lambda: stats.check_peak_rule("top"), ValueError, None),
    ("power_law_departure", lambda: stats.power_law_departure(DENSITY.drop(columns="count"), 1.0, 10.0),
     ValueError, "density must have the column.*'count'"),
    ("power_law_departure", lambda: stats.power_law_departure(DENSITY, 1.0, 10.0, factor=0.5), ValueError,
     "factor must be >= 1"),
    ("ke_threshold", lambda: stats.ke_threshold(FRAMES, fit_quantiles=(0.8, 0.3)), ValueError,
     r"fit_quantiles must be \(low, high\) with 0 <= low <= high <= 1"),
    ("ke_threshold", lambda: stats.ke_threshold(FRAMES, "ke_rot"), ValueError,
     "frames must have the column.*'ke_rot'"),
    ("fd_bins_per_decade", lambda: stats.fd_bins_per_decade(LF, lo=5, hi=3), ValueError,
     "hi must be an integer >= 5"),
    ("lost_fraction_edges", lambda: stats.lost_fraction_edges([1, 2, 3], [100, 100]), ValueError,
     r"n_active must have the shape of n_lost \(3,\), got \(2,\)"),
    ("mixture_pdf", lambda: stats.mixture_pdf(0.0, [0.5, 0.5], [0.0, 1.0], [1.0, 0.0]), ValueError,
     "sds must be > 0"),
    ("mixture_pdf", lambda: stats.mixture_pdf(0.0, [0.5, 0.5], [0.0, 1.0, 2.0], [1.0, 1.0]), ValueError,
     r"means must have the length of weights \(2\), got 3"),
    ("bimodality", lambda: stats.bimodality(LF, init={"means": [0, 1]}), TypeError,
     "init must be a dict of weights, means and sds"),
    ("dequantized_log_fraction", lambda: stats.dequantized_log_fraction([1, 2], [100]), ValueError,
     "n_active must have the shape of n_lost"),
    ("bootstrap_ci", lambda: stats.bootstrap_ci(LF, confidence=95), ValueError, r"confidence must be in \(0, 1\)"),
    ("bootstrap_ci", lambda: stats.bootstrap_ci(LF, statistic="mean"), TypeError, "statistic must be a function"),
    ("bootstrap_ci", lambda: stats.bootstrap_ci(LF, method="normal"), ValueError,
     "method must be 'BCa', 'percentile' or 'basic'"),
    ("bootstrap_runs_ci", lambda: stats.bootstrap_runs_ci(5, np.mean), TypeError,
     r"groups must be a list \(one item per run\)"),
    ("diff_ci", lambda: stats.diff_ci(LF, LF, n_resamples=0), ValueError, "n_resamples must be an integer >= 1"),
    ("leave_one_run_out", lambda: stats.leave_one_run_out(FRAMES, [0], "len"), TypeError,
     "statistic must be a function"),
    ("loo_stability", lambda: stats.loo_stability("1.0", [1.0]), TypeError, "full must be a number"),
]


@pytest.mark.parametrize("name, call, exc, what", BAD,
                         ids=[f"{b[0]}-{k}" for k, b in enumerate(BAD)])
def test_a_wrong_argument_is_refused_in_one_line_naming_it(name, call, exc, what):
    with pytest.raises(exc) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg and msg.strip() == msg, msg
    if what is not None:      # check_peak_rule keeps its own words (test_analysis_stats.py)
        assert msg.startswith(f"{name}: "), msg
        arg = what.split(" must")[0].split(" and ")[0]
        assert f": {arg}" in msg or f" {arg} " in msg, msg
        assert re.search(what, msg), (what, msg)


def _public_functions():
    """The functions of the public analysis API: tiltpile.analysis's and
    tiltpile.analysis.stats's names, and frame_contacts (the tutorial's)."""
    names = {n for n in analysis.__all__ + stats.__all__
             if inspect.isfunction(getattr(analysis, n, None) or getattr(stats, n, None))}
    return sorted(names - {"column_code"} | {"frame_contacts"})   # column_code takes nothing


def test_every_public_function_has_a_refused_input_here():
    covered = {b[0] for b in BAD}
    assert sorted(set(_public_functions()) - covered) == []


def test_what_the_checks_admit_is_computed_as_before():
    """The edge cases the functions handle stay admitted: no contacts (any empty array for the
    masks and forces), no cluster, no mobile grain, NaN velocities (a run without them), NaN in
    the lost fraction, integral floats for whole-number parameters."""
    empty = np.empty((0, 2), np.int32)
    row, clus, _ = analysis.frame_observables(RAD, FIXED, 4.0, POS, VEL, OMEGA, empty, [], [], 5.0)
    assert row["n_active"] == 0 and len(clus) == 0 and np.isnan(row["z"])
    row, _, _ = analysis.frame_observables(RAD, np.ones(N, bool), 4.0, POS, np.full((N, 2), np.nan),
                                           np.full(N, np.nan), PAIR, FORCE, STATUS, 5.0)
    assert np.isnan(row["ke_trans"]) and row["n_mobile"] == 0
    assert ct.contact_counts(N, empty, []).tolist() == [0] * N
    assert cl.cluster_sizes(np.full(N, -1)).size == 0
    assert np.isnan(ct.dz_gen(np.nan, 0.5))
    assert analysis.segment_avalanches(LF)["onsets"].tolist() == [10]
    assert np.isnan(analysis.first_slide(THETA, LF, np.nan, 0.5))
    assert np.isnan(analysis.frame_spacing_check(LF, cutoff=0.0))
    assert stats.log_binned_density(LF, bins_per_decade=5.0).equals(stats.log_binned_density(LF, 5))
    assert len(stats.power_law_departure(pd.DataFrame(), 1.0, 10.0)) > 0


class _Reader:
    """A stand-in run reader (tiltpile.store.open_run's attributes) whose frame 2 has a contact
    with grain 99."""

    config = {"scene": {"mu": 0.5}}
    radius, fixed, box_length, n_frames, seed = RAD, FIXED, 4.0, 3, 5
    theta_deg = np.array([0.0, 1.0, 2.0])
    step, time, iterations, residual = np.arange(3), np.arange(3.0), np.ones(3), np.zeros(3)

    def contacts(self, k):
        return (PAIR if k < 2 else np.r_[PAIR, [[0, 99]]].astype(np.int32),
                FORCE if k < 2 else np.r_[FORCE, [[1.0, 0.0]]],
                STATUS if k < 2 else np.r_[STATUS, [1]].astype(np.int8))

    def position(self, k):
        return POS

    def velocity(self, k):
        return VEL

    def omega(self, k):
        return OMEGA


def test_a_readers_bad_frame_is_named():
    with pytest.raises(ValueError, match=r"^run_observables: frame 2: pair must hold grain indices "
                                         r"in \[0, 12\)") as info:
        analysis.run_observables(_Reader())
    assert "\n" not in str(info.value)
    r = _Reader()
    r.theta_deg = np.zeros(2)
    with pytest.raises(ValueError, match=r"^run_observables: run.theta_deg must have shape \(3,\) "
                                         r"like run.n_frames \(3\), got \(2,\)$"):
        analysis.run_observables(r)


def test_the_messages_are_of_the_two_kinds_the_callers_catch():
    """A refusal is a ValueError or a TypeError (checks.InputValueError / InputTypeError), so
    that code catching those (bootstrap_runs_ci's resamples) keeps working."""
    assert issubclass(checks.InputValueError, ValueError)
    assert issubclass(checks.InputTypeError, TypeError)
    with pytest.raises(checks.InputValueError):
        ct.contact_counts(N, PAIR, ACT[:-1])
