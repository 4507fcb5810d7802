"""Avalanche segmentation on synthetic lost-fraction series."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tiltpile.analysis import avalanche as av

Q = 0.001   # a quiet frame's lost fraction


def _series():
    # frames 0-9 quiet, 10-12 avalanche, 13-17 quiet, 18-19 avalanche, 20-22 quiet, 23 last (NaN)
    lf = np.r_[[Q] * 10, [0.05, 0.1, 0.03], [0.005] * 5, [0.5, 0.2], [Q] * 3, [np.nan]]
    return lf, 0.05 * np.arange(lf.size)


def test_segmentation_periods_and_onsets():
    lf, theta = _series()
    seg = av.segment_avalanches(lf, cutoff=0.02)
    expect = np.zeros(lf.size, bool)
    expect[10:13] = True
    expect[18:20] = True
    assert np.array_equal(seg["avalanching"], expect)
    assert seg["onsets"].tolist() == [10, 18]
    assert seg["period"].tolist() == [0] * 10 + [1] * 3 + [2] * 5 + [3] * 2 + [4] * 4
    assert seg["period_start"][[0, 9, 10, 12, 13, 19, 23]].tolist() == [0, 0, 10, 10, 13, 18, 20]


def test_stretches_are_the_avalanches():
    lf, _ = _series()
    starts, ends = av.stretches(av.segment_avalanches(lf, cutoff=0.02)["avalanching"])
    np.testing.assert_array_equal(starts, [10, 18])
    np.testing.assert_array_equal(ends, [13, 20])
    for mask in ([], [False], [True, True]):
        s, e = av.stretches(np.array(mask, bool))
        assert (s.tolist(), e.tolist()) == (([0], [2]) if len(mask) == 2 else ([], []))


def test_theta_relative_to_next_onset():
    lf, theta = _series()
    seg = av.segment_avalanches(lf, cutoff=0.02)
    rel = av.theta_relative_to_onset(theta, seg["avalanching"], seg["onsets"])
    t = rel["theta_to_onset"]
    assert t[5] == pytest.approx(theta[5] - theta[10]) and t[5] == pytest.approx(-0.25)
    assert t[9] == pytest.approx(-0.05)
    assert t[11] == pytest.approx(0.05)                   # inside the first avalanche
    assert t[13] == pytest.approx(theta[13] - theta[18])  # quiet: relative to the next onset
    assert np.isnan(t[20]) and np.isnan(t[23])            # no onset follows
    assert rel["theta_m"][0] == pytest.approx(theta[10])
    assert rel["onset_index"][[0, 12, 17, 19, 21]].tolist() == [10, 10, 18, 18, -1]


def test_cutoff_moves_the_onset():
    lf, _ = _series()
    # 3%: frame 12 (0.03) is not above the cutoff; 6%: frame 10 (0.05) neither
    assert av.segment_avalanches(lf, 0.03)["avalanching"][10:13].tolist() == [True, True, False]
    assert av.segment_avalanches(lf, 0.06)["onsets"].tolist() == [11, 18]


def test_nan_inherits_the_state_of_the_previous_frame():
    lf = np.array([Q, 0.3, np.nan, Q, np.nan])
    assert av.segment_avalanches(lf)["avalanching"].tolist() == [False, True, True, False, False]


def test_merge_gap_joins_flickering_avalanche():
    lf = np.r_[[Q] * 5, 0.1, Q, 0.1, Q, Q, 0.1, [Q] * 3]
    assert av.segment_avalanches(lf)["onsets"].tolist() == [5, 7, 10]
    seg = av.segment_avalanches(lf, merge_gap=2)
    assert seg["onsets"].tolist() == [5, 10]
    assert seg["avalanching"][5:8].all()
    assert av.segment_avalanches(lf, merge_gap=3)["onsets"].tolist() == [5]


def test_onset_robustness_on_a_ramp():
    # lost fraction ramps through the cutoffs one frame at a time
    lf = np.r_[[Q] * 20, 0.015, 0.025, 0.035, 0.045, 0.3, 0.3, [Q] * 5]
    theta = 0.05 * np.arange(lf.size)
    rob = av.onset_robustness(lf, theta, cutoffs=(0.01, 0.02, 0.03, 0.04), reference=0.02)
    assert rob["ref_frame"].tolist() == [21] * 4
    assert rob["frame"].tolist() == [20, 21, 22, 23]
    assert rob["shift_frames"].tolist() == [-1, 0, 1, 2]
    assert rob["shift_deg"].to_numpy() == pytest.approx([-0.05, 0.0, 0.05, 0.1])
    far = av.onset_robustness(lf, theta, cutoffs=(0.2,), max_shift=1)
    assert np.isnan(far["frame"].iloc[0])                   # nearest onset (24) is 3 frames away


def test_displacement_since_period_start():
    pos = np.zeros((5, 3, 2))
    pos[1, 0] = [0.01, 0.0]          # quiet period 0-2: grain 0 creeps
    pos[2, 0] = [0.02, 0.0]
    pos[3, 1] = [1.0, 0.0]           # period 3-4 starts at frame 3
    pos[4, 1] = [1.0, 0.5]
    mean, mx = av.displacement_since_period_start(pos, np.array([0, 0, 0, 3, 3]))
    assert mx.tolist() == pytest.approx([0.0, 0.01, 0.02, 0.0, 0.5])
    assert mean.tolist() == pytest.approx([0.0, 0.01 / 3, 0.02 / 3, 0.0, 0.5 / 3])


def test_resegment_a_frame_table():
    lf, theta = _series()
    frames = pd.DataFrame({"run": np.r_[[1] * lf.size, [2] * 4], "frame": np.r_[np.arange(lf.size), np.arange(4)],
                           "theta_deg": np.r_[theta, theta[:4]], "lost_fraction": np.r_[lf, [Q, 0.5, Q, Q]]})
    out = av.resegment(frames, cutoff=0.02)
    r1 = out[out["run"] == 1]
    assert np.flatnonzero(r1["onset"].to_numpy()).tolist() == [10, 18]
    r2 = out[out["run"] == 2]
    assert r2["avalanching"].tolist() == [False, True, False, False]
    assert r2["theta_to_onset"].iloc[0] == pytest.approx(-0.05)


def test_onset_robustness_ensemble_per_run():
    lf = np.r_[[Q] * 20, 0.015, 0.025, 0.035, 0.045, 0.3, 0.3, [Q] * 5]
    n = lf.size
    frames = pd.DataFrame({"run": np.r_[[3] * n, [4] * n], "frame": np.r_[np.arange(n), np.arange(n)],
                           "theta_deg": np.r_[0.05 * np.arange(n), 0.05 * np.arange(n)],
                           "lost_fraction": np.r_[lf, np.roll(lf, -5)]})
    rob = av.onset_robustness_ensemble(frames)
    assert rob.groupby("run")["ref_frame"].first().tolist() == [21, 16]
    assert rob.groupby("run")["shift_frames"].apply(list).tolist() == [[-1, 0, 1, 2]] * 2


# ---------------------------------------------------------------------------------------------
# first large slide: kinetic energy above a threshold, sustained over a span of tilt


def _ke_series():
    theta = 0.05 * np.arange(60)                       # 0 .. 2.95 deg
    ke = np.full(60, 1e-6)
    ke[10:13] = 1e-3                                   # precursor: 3 frames, span 0.10 deg
    ke[20] = np.nan                                    # a missing value breaks a stretch
    ke[18:20] = 1e-3
    ke[21:25] = 1e-3                                   # 18-24 with a hole: spans 0.05 and 0.15
    ke[30:45] = 2e-3                                   # slide: 15 frames, span 0.70 deg
    ke[55:60] = 1e-2                                   # runs to the end: span 0.20 deg
    return theta, ke


def test_first_slide_needs_the_span():
    theta, ke = _ke_series()
    assert av.first_slide(theta, ke, 5e-4, 0.5) == pytest.approx(theta[30])
    assert av.first_slide(theta, ke, 5e-4, 0.0) == pytest.approx(theta[10])   # any frame above
    assert av.first_slide(theta, ke, 5e-4, 0.1) == pytest.approx(theta[10])   # 10-12 spans 0.10
    assert av.first_slide(theta, ke, 5e-4, 0.15) == pytest.approx(theta[21])  # NaN at 20 splits
    # the threshold decides which frames flow: above the slide's energy only the last stretch
    assert av.first_slide(theta, ke, 5e-3, 0.15) == pytest.approx(theta[55])
    assert np.isnan(av.first_slide(theta, ke, 5e-3, 0.5))    # still short when the run ends
    assert np.isnan(av.first_slide(theta, ke, 1.0, 0.0))      # nothing above
    assert np.isnan(av.first_slide(theta, ke, np.nan, 0.5))   # no threshold: no slide
    with pytest.raises(ValueError):
        av.first_slide(theta, ke[:-1], 5e-4, 0.5)
    with pytest.raises(ValueError):
        av.first_slide(theta, ke, 5e-4, -1.0)


def test_run_onsets_both_ways_per_run():
    theta, ke = _ke_series()
    lf = np.full(60, 0.001)
    lf[10] = 0.05                                       # the precursor loses 5% of its contacts
    lf[-1] = np.nan
    seg = av.segment_avalanches(lf, 0.02)
    onset = np.zeros(60, bool)
    onset[seg["onsets"]] = True
    one = pd.DataFrame({"run": 7, "frame": np.arange(60), "theta_deg": theta, "ke_trans": ke,
                        "onset": onset, "avalanching": seg["avalanching"]})
    calm = one.assign(run=3, ke_trans=1e-6, onset=False)
    t = av.run_onsets(pd.concat([one, calm]), 5e-4, 0.5)
    assert t["run"].tolist() == [3, 7]
    r3, r7 = t.iloc[0], t.iloc[1]
    assert r7["theta_first_onset"] == pytest.approx(theta[10])
    assert r7["theta_first_slide"] == pytest.approx(theta[30])
    assert r7["slide_minus_onset"] == pytest.approx(theta[30] - theta[10])
    assert r7["n_onsets"] == 1 and r7["theta_end"] == pytest.approx(theta[-1])
    assert np.isnan(r3["theta_first_onset"]) and np.isnan(r3["theta_first_slide"])


def test_run_table_takes_the_slide_parameters_of_the_analysis():
    from tiltpile.analysis import observables as ob
    theta, ke = _ke_series()
    fr = pd.DataFrame({"run": 1, "frame": np.arange(60), "theta_deg": theta, "ke_trans": ke,
                       "onset": False, "avalanching": False})
    t = ob.run_table(fr, slide_ke=5e-4)                          # default span 0.5 deg
    assert t["theta_first_slide"].iloc[0] == pytest.approx(theta[30])
    assert t["slide_ke"].iloc[0] == 5e-4 and t["slide_sustain_deg"].iloc[0] == 0.5
    t = ob.run_table(fr, slide_ke=5e-4, slide_sustain_deg=0.1)
    assert t["theta_first_slide"].iloc[0] == pytest.approx(theta[10])
    for bad in ({"slide_ke": 0.0}, {"slide_sustain_deg": -0.5}, {"slide_span": 1.0}):
        with pytest.raises((ValueError, TypeError)):
            ob.run_table(fr, **bad)
    # the slide parameters do not make the per-frame caches stale
    assert "slide_ke" not in ob._source_meta(Path(__file__), ob._params({}))["params"]


def test_precursor_count_known_answers():
    from tiltpile.analysis.avalanche import precursor_count

    th = 0.1 * np.arange(12)
    av = np.zeros(12, bool)
    av[[2, 3, 6, 9, 10, 11]] = True         # avalanches at 0.2-0.3, 0.6, 0.9-1.1
    on = np.zeros(12, bool)
    on[[2, 6, 9]] = True
    assert precursor_count(th, on, av, np.nan) == 3       # no slide: every onset
    assert precursor_count(th, on, av, 1.0) == 2          # 0.9-1.1 runs into it
    assert precursor_count(th, on, av, 0.9) == 2          # slide starts with it
    assert precursor_count(th, on, av, 0.6) == 1          # 0.6 is the slide's own
    assert precursor_count(th, on, av, 0.3) == 0          # still running at 0.3
    assert precursor_count(th, on, av, 0.35) == 1
    with pytest.raises(ValueError, match="differ in length"):
        precursor_count(th, on[:-1], av, 1.0)
