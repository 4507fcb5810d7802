"""Statistics with known answers: densities, the P(s) fit, C(tau), failure enhancement, delta z."""

import numpy as np
import pandas as pd
import pytest

from tiltpile.analysis import stats as st


# ---------------------------------------------------------------------------------------------
# P(s) = s^-delta exp(-s/xi)

@pytest.mark.parametrize("delta, xi, s_min, n", [(2.5, 40.0, 1, 20000), (1.5, 200.0, 2, 5000),
                                                 (0.5, 10.0, 1, 5000)])
def test_fit_recovers_parameters_within_its_error_bars(delta, xi, s_min, n):
    s = st.sample_power_law_cutoff(delta, xi, n, s_min=s_min, rng=12345)
    assert s.min() >= s_min
    fit = st.fit_power_law_cutoff(s, s_min=s_min)
    assert fit.n == n and not fit.delta_fixed
    assert abs(fit.delta - delta) < 3 * fit.delta_err
    assert abs(fit.xi - xi) < 3 * fit.xi_err
    # the error bars are informative, not just wide
    assert fit.delta_err < 0.1
    assert fit.xi_err < 0.5 * xi
    assert fit.pmf(np.arange(s_min, 200_000)).sum() == pytest.approx(1.0, abs=1e-9)


def test_fit_with_fixed_delta():
    s = st.sample_power_law_cutoff(2.5, 20.0, 20000, rng=7)
    fit = st.fit_power_law_cutoff(s, delta=2.5)
    assert fit.delta == 2.5 and fit.delta_fixed and fit.delta_err == 0.0
    assert abs(fit.xi - 20.0) < 3 * fit.xi_err and fit.xi_err < 5.0


def test_fit_error_bars_have_one_sigma_coverage():
    # over 40 independent samples the true value lies within one sigma ~68% of the time
    inside_d, inside_lam = [], []
    for seed in range(40):
        fit = st.fit_power_law_cutoff(st.sample_power_law_cutoff(1.5, 50.0, 2000, rng=seed))
        inside_d.append(abs(fit.delta - 1.5) < fit.delta_err)
        lam_err = fit.xi_err / fit.xi**2
        inside_lam.append(abs(1 / fit.xi - 1 / 50.0) < lam_err)
    assert 0.5 <= np.mean(inside_d) <= 0.86
    assert 0.5 <= np.mean(inside_lam) <= 0.86


def test_fit_refuses_too_few_samples():
    s = st.sample_power_law_cutoff(2.5, 40.0, 30, rng=1)
    with pytest.raises(st.InsufficientDataError, match="only 30 sizes.*need at least 50"):
        st.fit_power_law_cutoff(s)
    with pytest.raises(st.InsufficientDataError, match="distinct"):
        st.fit_power_law_cutoff(np.r_[[1] * 100, [2] * 100])           # two values, two parameters
    with pytest.raises(st.InsufficientDataError):
        st.fit_power_law_cutoff(np.arange(1, 200), s_min=190)          # only 10 above s_min
    with pytest.raises(ValueError, match="integers"):
        st.fit_power_law_cutoff(np.array([1.5, 2.0] * 50))


# ---------------------------------------------------------------------------------------------
# densities

def test_log_binned_density_of_log_uniform_samples():
    rng = np.random.default_rng(0)
    x = 10 ** rng.uniform(0.0, 2.0, 100_000)
    x = np.r_[x, np.zeros(1000)]                               # zeros: dropped, still normalised
    df = st.log_binned_density(x, bins_per_decade=10, xmin=1.0, xmax=100.0)
    assert len(df) == 20
    assert (df["density"] * (df["right"] - df["left"])).sum() == pytest.approx(100 / 101)
    expect = (100 / 101) / (df["center"] * np.log(100.0))     # p(x) = 1 / (x ln 100)
    assert np.abs(df["density"] / expect - 1).max() < 0.06     # ~5000 per bin: 1.4% noise
    assert df.attrs["n_nonpositive"] == 1000


def test_discrete_log_binned_density_normalised_per_integer():
    s = np.r_[[1] * 50, [2] * 25, [3] * 10, [10] * 10, [100] * 5]
    df = st.discrete_log_binned_density(s, bins_per_decade=5)
    assert (df["density"] * (df["right"] - df["left"])).sum() == pytest.approx(1.0)
    assert df["left"].iloc[:3].tolist() == [1, 2, 3] and df["right"].iloc[:3].tolist() == [2, 3, 4]
    assert df["density"].iloc[0] == pytest.approx(0.5)
    last = df.iloc[-1]
    assert last["left"] <= 100 < last["right"]
    assert last["density"] == pytest.approx(0.05 / (last["right"] - last["left"]))


def test_density_2d_integrates_to_one():
    rng = np.random.default_rng(1)
    h, xe, ye = st.density_2d(rng.normal(3.5, 0.1, 1000), rng.uniform(0, 0.5, 1000), bins=(10, 5))
    assert (h * np.outer(np.diff(xe), np.diff(ye))).sum() == pytest.approx(1.0)


# ---------------------------------------------------------------------------------------------
# C(tau)

def test_correlation_peaks_at_the_known_lag():
    rng = np.random.default_rng(5)
    n, lag = 3000, 3
    a = rng.normal(size=n)
    b = np.r_[rng.normal(size=lag), a[:-lag]] + 0.5 * rng.normal(size=n)
    quiet = np.ones(n, bool)
    c = st.correlation_function(a, b, quiet, taus=range(-5, 8))
    assert c.loc[c["C"].idxmax(), "tau"] == lag
    assert c.set_index("tau").loc[lag, "C"] == pytest.approx(1 / np.sqrt(1.25), abs=0.02)
    assert np.abs(c[c["tau"] != lag]["C"]).max() < 0.08


def test_correlation_uses_quiet_frames_of_one_period_only():
    rng = np.random.default_rng(6)
    a = rng.normal(size=400)
    b = a.copy()
    quiet = np.ones(400, bool)
    quiet[100:120] = False
    b[100:120] = 1e6 * rng.normal(size=20)      # avalanching frames: garbage that must not enter
    c = st.correlation_function(a, b, quiet, taus=[0, 2]).set_index("tau")
    assert c.loc[0, "C"] == pytest.approx(1.0)
    assert c.loc[0, "n_pairs"] == 380
    assert c.loc[2, "n_pairs"] == (100 - 2) + (280 - 2)      # no pair straddles the avalanche


def test_correlation_ensemble_pools_runs_without_crossing_them():
    rng = np.random.default_rng(8)
    rows = []
    for run in (1, 2):
        a = rng.normal(size=200)
        b = np.r_[0.0, a[:-1]]
        rows.append(pd.DataFrame({"run": run, "frame": np.arange(200), "largest_cluster": a,
                                  "n_lost": b, "avalanching": False, "period": 0}))
    c = st.correlation_function_ensemble(pd.concat(rows), taus=[1]).set_index("tau")
    assert c.loc[1, "C"] == pytest.approx(1.0) and c.loc[1, "n_pairs"] == 2 * 199


# ---------------------------------------------------------------------------------------------
# failure enhancement

def test_failure_enhancement_after_cluster_peaks():
    n = 200
    s = np.ones(n)
    nf = np.full(n, 10.0)
    peaks = np.arange(10, 190, 20)              # 9 peaks
    s[peaks] = 10.0
    nf[peaks + 1] = 14.0                        # failure one frame after each peak
    quiet = np.ones(n, bool)
    assert st.cluster_peaks(s, quiet).tolist() == peaks.tolist()
    enh = st.failure_enhancement(s, nf, quiet, taus=[0, 1, 2]).set_index("tau")
    base = nf.mean()
    assert enh.loc[1, "enhancement"] == pytest.approx(14.0 / base - 1.0)
    assert enh.loc[0, "enhancement"] == pytest.approx(10.0 / base - 1.0)
    assert enh.loc[1, "n_peaks"] == 9
    frames = pd.DataFrame({"run": 0, "frame": np.arange(n), "largest_cluster": s, "n_lost": nf,
                           "avalanching": False, "period": 0})
    ens = st.failure_enhancement_ensemble(frames, taus=[1]).set_index("tau")
    assert ens.loc[1, "enhancement"] == pytest.approx(enh.loc[1, "enhancement"])


# what a peak is (peak_rule): a series whose answer is read off by hand. Frames 0-11, one quiet
# period. Local maxima (S(k) > S(k - 1), S(k) >= S(k + 1), k = 1..10): 1 (3), 3 (5, the first
# frame of the 5-5 plateau), 6 (4), 8 (8), 10 (5). Quiet mean 39 / 12 = 3.25, std
# sqrt(52.25 / 12) = 2.087: mean + 1 sd = 5.34 leaves frame 8 only, mean + 0.5 sd = 4.29 frames
# 3, 8, 10. Top decile: m = ceil(1.2) = 2, the 2nd largest S is 5, so every frame with S >= 5:
# 3, 4, 8, 10 (the ties with the 2nd all count). N^f: 1 except 4 at frames 3 and 10 and 7 at 8,
# quiet mean 24 / 12 = 2.
PEAK_S = np.array([1, 3, 2, 5, 5, 1, 4, 2, 8, 1, 5, 2], dtype=float)
PEAK_NF = np.array([1, 1, 1, 4, 1, 1, 1, 1, 7, 1, 4, 1], dtype=float)


def test_each_peak_rule_finds_the_peaks_counted_by_hand():
    quiet = np.ones(PEAK_S.size, bool)
    assert st.cluster_peaks(PEAK_S, quiet, peak_rule="local").tolist() == [1, 3, 6, 8, 10]
    assert st.cluster_peaks(PEAK_S, quiet, peak_rule="sigma").tolist() == [8]
    assert st.cluster_peaks(PEAK_S, quiet).tolist() == [8]                 # the default
    assert st.cluster_peaks(PEAK_S, quiet, threshold_sigma=0.5).tolist() == [3, 8, 10]
    assert st.cluster_peaks(PEAK_S, quiet, peak_rule="decile").tolist() == [3, 4, 8, 10]
    # frame 5 avalanching: frame 6 loses its left neighbour in the period (no longer a local
    # maximum); the decile is over the 11 quiet frames (m = ceil(1.1) = 2: still S >= 5)
    quiet[5] = False
    assert st.cluster_peaks(PEAK_S, quiet, peak_rule="local").tolist() == [1, 3, 8, 10]
    assert st.cluster_peaks(PEAK_S, quiet, peak_rule="decile").tolist() == [3, 4, 8, 10]
    # distinct values: the top decile is exactly ceil(n / 10) frames (here 2 of 11, 3 of 21)
    for n in (11, 21):
        s = np.arange(n, dtype=float)[::-1]
        assert st.cluster_peaks(s, np.ones(n, bool), peak_rule="decile").tolist() == \
            list(range(int(np.ceil(n / 10))))


def test_each_peak_rule_gives_the_enhancement_counted_by_hand():
    quiet = np.ones(PEAK_S.size, bool)

    def enh0(rule):
        e = st.failure_enhancement(PEAK_S, PEAK_NF, quiet, taus=[0], peak_rule=rule)
        return e["enhancement"].iloc[0], e["n_peaks"].iloc[0]

    assert enh0("local") == (pytest.approx((1 + 4 + 1 + 7 + 4) / 5 / 2 - 1), 5)   # +70%
    assert enh0("sigma") == (pytest.approx(7 / 2 - 1), 1)                          # +250%
    assert enh0("decile") == (pytest.approx((4 + 1 + 7 + 4) / 4 / 2 - 1), 4)       # +100%
    # "c0": the +40% read as C(0), the Pearson correlation of S and N^f over the 12 frames
    assert enh0("c0") == (pytest.approx(np.corrcoef(PEAK_S, PEAK_NF)[0, 1]), 12)
    c = st.correlation_function(PEAK_S, PEAK_NF, quiet, taus=[0, 1, 2]).set_index("tau")
    e = st.failure_enhancement(PEAK_S, PEAK_NF, quiet, taus=[0, 1, 2],
                               peak_rule="c0").set_index("tau")
    assert e["enhancement"].tolist() == c["C"].tolist()
    assert e["n_peaks"].tolist() == c["n_pairs"].tolist() == [12, 11, 10]


def test_peak_rules_pool_runs_with_a_threshold_per_run():
    """Two runs: the series above and the same series doubled (S and N^f x 2). The peaks are
    the same frames in both (mean, sd and decile scale with S); the pooled rate after them is
    the N^f sum over both runs' peaks over the pooled quiet mean (24 + 48) / 24 = 3."""
    frames = pd.concat([pd.DataFrame({"run": r, "frame": np.arange(PEAK_S.size),
                                      "largest_cluster": f * PEAK_S, "n_lost": f * PEAK_NF,
                                      "avalanching": False, "period": 0})
                        for r, f in ((1, 1.0), (2, 2.0))])
    for rule, peak_nf in (("local", 17), ("sigma", 7), ("decile", 16)):
        e = st.failure_enhancement_ensemble(frames, taus=[0], peak_rule=rule)
        n = {"local": 5, "sigma": 1, "decile": 4}[rule]
        assert e["enhancement"].iloc[0] == pytest.approx(3 * peak_nf / (2 * n) / 3 - 1), rule
        assert e["n_peaks"].iloc[0] == 2 * n
    e = st.failure_enhancement_ensemble(frames, taus=[0, 1], peak_rule="c0")
    c = st.correlation_function_ensemble(frames, taus=[0, 1])
    assert e["enhancement"].tolist() == c["C"].tolist() and e["n_peaks"].tolist() == [24, 22]


def test_the_sigma_rule_is_the_peak_definition_it_always_was():
    """The default "sigma" is the original definition (a local maximum within a quiet period
    above mean + threshold_sigma sd of the quiet frames), written out here independently, on
    random series with avalanches."""
    rng = np.random.default_rng(11)
    for _ in range(20):
        n = 300
        s = rng.poisson(4.0, n).astype(float)
        nf = rng.poisson(3.0, n).astype(float)
        quiet = rng.random(n) > 0.1
        per = np.cumsum(np.r_[True, quiet[1:] != quiet[:-1]])
        sq = s[quiet]
        thr = sq.mean() + sq.std()
        want = [k for k in range(1, n - 1)
                if quiet[k - 1] and quiet[k] and quiet[k + 1] and per[k - 1] == per[k] == per[k + 1]
                and s[k] > s[k - 1] and s[k] >= s[k + 1] and s[k] > thr]
        assert st.cluster_peaks(s, quiet, peak_rule="sigma").tolist() == want
        a = st.failure_enhancement(s, nf, quiet, taus=[0, 1])
        b = st.failure_enhancement(s, nf, quiet, taus=[0, 1], peak_rule="sigma")
        pd.testing.assert_frame_equal(a, b)
        base = nf[quiet].mean()
        k = np.array(want)
        ok = quiet[k + 1] & (per[k + 1] == per[k])
        assert a["enhancement"].iloc[1] == pytest.approx(nf[k + 1][ok].mean() / base - 1)


@pytest.mark.parametrize("call", [
    lambda r: st.cluster_peaks(PEAK_S, np.ones(12, bool), peak_rule=r),
    lambda r: st.failure_enhancement(PEAK_S, PEAK_NF, np.ones(12, bool), peak_rule=r),
    lambda r: st.failure_enhancement_ensemble(pd.DataFrame({"run": 0, "frame": np.arange(12),
                                                            "largest_cluster": PEAK_S,
                                                            "n_lost": PEAK_NF,
                                                            "avalanching": False, "period": 0}),
                                              peak_rule=r)])
def test_an_unknown_peak_rule_is_a_one_line_error(call):
    with pytest.raises(ValueError, match=r"^peak_rule must be one of 'local', 'sigma', 'decile', "
                                         r"'c0', not 'top'$"):
        call("top")
    with pytest.raises(ValueError, match="one of"):
        call(None)


def test_c0_defines_no_peaks():
    with pytest.raises(ValueError, match="'c0' defines no peaks"):
        st.cluster_peaks(PEAK_S, np.ones(12, bool), peak_rule="c0")


# ---------------------------------------------------------------------------------------------
# delta z versus size, windows

def _clusters():
    return pd.DataFrame({"size": [1, 1, 2, 2, 2, 5],
                         "z": [2.0, 3.0, 2.5, 3.0, 3.5, 3.4],
                         "n_m": [0.5, 0.5, 0.5, 0.75, 0.5, 0.6]}).assign(dz=lambda d: d.z - d.n_m)


def test_dz_by_size():
    out = st.dz_by_size(_clusters()).set_index("size_lo")
    assert out.loc[1, "n"] == 2 and out.loc[1, "dz_mean"] == pytest.approx(2.0)
    assert out.loc[1, "dz_min"] == pytest.approx(1.5)
    assert out.loc[2, "dz_mean"] == pytest.approx((2.0 + 2.25 + 3.0) / 3)
    binned = st.dz_by_size(_clusters(), size_edges=[1, 2, 10]).set_index("size_lo")
    assert binned.loc[2, "n"] == 4 and binned.loc[2, "size_hi"] == 10


def test_dz_distribution_respects_discreteness():
    d = st.dz_distribution(_clusters(), 2)
    assert d["center"].tolist() == pytest.approx([2.0, 2.25, 3.0])     # multiples of 1/(2*2)
    assert (d["density"] * 0.25).sum() == pytest.approx(1.0)


def test_cluster_size_windows():
    rng = np.random.default_rng(2)
    frames = pd.DataFrame({"run": 0, "frame": np.arange(40), "theta_to_onset": -(40 - np.arange(40)) / 20,
                           "avalanching": False, "largest_cluster": np.arange(40)})
    frames.loc[39, "avalanching"] = True
    cl = pd.DataFrame({"run": 0, "frame": np.repeat(np.arange(40), 100),
                       "size": st.sample_power_law_cutoff(2.0, 30.0, 4000, rng=rng)})
    w = st.cluster_size_windows(cl, frames, width=1.0, lo=-2.0, hi=0.0, min_samples=50)
    # theta - theta_m = -(40 - k)/20: [-2, -1) holds frames 0-19, [-1, 0) frames 20-38 (39 avalanches)
    assert w["n_frames"].tolist() == [20, 19]
    assert w["n_clusters"].tolist() == [2000, 1900]
    assert w["mean_largest"].tolist() == pytest.approx([9.5, 29.0])
    assert (w["fit_error"] == "").all()
    assert (np.abs(w["delta"] - 2.0) < 3 * w["delta_err"]).all()
    few = st.cluster_size_windows(cl, frames, width=1.0, lo=-2.0, hi=0.0, min_samples=5000)
    assert few["fit_error"].str.contains("need at least 5000").all() and few["xi"].isna().all()


def test_last_frame_placeholder_never_enters_the_correlation():
    # observables.py writes n_lost = -1 and lost_fraction = NaN at a run's last frame (no k + 1);
    # a perfectly correlated series must stay perfectly correlated with that row present
    rows = []
    for run in (1, 2):
        a = np.r_[np.arange(1.0, 21.0), 0.0]
        b = np.r_[2 * np.arange(1.0, 21.0), -1.0]
        lf = np.r_[np.full(20, 0.001), np.nan]
        rows.append(pd.DataFrame({"run": run, "frame": np.arange(21), "largest_cluster": a,
                                  "n_lost": b, "lost_fraction": lf, "avalanching": False,
                                  "period": 0}))
    c = st.correlation_function_ensemble(pd.concat(rows), taus=[0]).set_index("tau")
    assert c.loc[0, "C"] == pytest.approx(1.0) and c.loc[0, "n_pairs"] == 2 * 20


# ---------------------------------------------------------------------------------------------
# Fig. 2b: two populations, bins on integer counts; bootstrap over runs


def test_bimodality_tells_two_populations_from_one():
    rng = np.random.default_rng(3)
    two = np.r_[rng.normal(-3.0, 0.3, 3000), rng.normal(-1.3, 0.2, 300)]
    b = st.bimodality(two, cutoff=np.log10(0.02))
    assert b["delta_bic"] > 100 and b["ashman_d"] > 4 and b["valley_depth"] > 0.8
    assert b["means"][0] == pytest.approx(-3.0, abs=0.05)
    assert b["means"][1] == pytest.approx(-1.3, abs=0.05)
    assert b["weights"][1] == pytest.approx(300 / 3300, abs=0.02)
    assert b["cutoff_between_means"] and b["cutoff_density_ratio"] < 0.5
    assert -2.5 < b["valley"] < -1.5
    # one population, even a skewed one (a log-normal tail), has no valley
    for one in (rng.normal(-3.0, 0.5, 3000), np.log10(rng.lognormal(0.0, 1.0, 3000) + 1.0)):
        b1 = st.bimodality(one)
        assert b1["valley_depth"] == 0.0 and np.isnan(b1["valley"])
        assert b1["ashman_d"] < 2
    assert np.isnan(st.bimodality([1.0, 2.0])["ashman_d"])        # too few samples


def test_lost_fraction_edges_put_each_small_count_alone():
    c = np.full(200, 1000.0)
    k = np.r_[np.arange(1, 101), np.arange(1, 101)]
    e = st.lost_fraction_edges(k, c, bins_per_decade=10)
    counts, _ = np.histogram(k / c, bins=e)
    assert counts.sum() == k.size                                  # every positive frame binned
    # counts 1..4: one integer per bin, each bin holds exactly its two frames
    assert counts[:4].tolist() == [2] * 4
    # every edge on a half-integer count: each bin holds whole counts, two frames per count
    assert np.allclose(e * 1000.0 % 1.0, 0.5) and np.all(counts % 2 == 0)
    assert np.all(np.diff(np.log10(e))[10:] <= 0.1 + 0.02)        # log-spaced above
    assert st.lost_fraction_edges([0, 0], [10, 10]).size == 0


def test_bootstrap_ci_covers_and_handles_degenerate_runs():
    x = [7.1, 11.7, 10.1, 7.55, 11.45, 10.1]
    ci = st.bootstrap_ci(x)
    assert ci["estimate"] == pytest.approx(np.mean(x)) and ci["n"] == 6
    assert min(x) < ci["low"] < np.mean(x) < ci["high"] < max(x)
    assert st.bootstrap_ci([2.0, 2.0, 2.0])["low"] == 2.0
    assert np.isnan(st.bootstrap_ci([1.0, 2.0])["low"])           # two runs: no interval
    assert st.bootstrap_ci([1.0, np.nan, 3.0, 2.0])["n"] == 3
    # coverage: the 95% interval of the mean of 6 normal runs holds the true mean most times
    rng = np.random.default_rng(0)
    hit = [(lambda c: c["low"] <= 0.0 <= c["high"])(st.bootstrap_ci(rng.normal(0, 1, 6),
                                                                   n_resamples=999))
           for _ in range(40)]
    assert 0.7 <= np.mean(hit) <= 1.0


def test_bootstrap_runs_ci_resamples_whole_runs():
    runs = [np.full(10, v) for v in (1.0, 2.0, 3.0, 4.0)]
    ci = st.bootstrap_runs_ci(runs, lambda g: float(np.mean(np.concatenate(g))), n_resamples=500)
    assert ci["estimate"] == pytest.approx(2.5) and ci["n"] == 4 and ci["n_failed"] == 0
    assert 1.0 <= ci["low"] < 2.5 < ci["high"] <= 4.0


def test_cell_density_2d_spreads_each_sample_over_its_cell_and_has_no_comb():
    xe = np.linspace(0.0, 4.0, 41)                  # bins of 0.1
    ye = np.linspace(0.0, 1.0, 11)
    # one sample on a cell of 0.4 x 0.2 spreads over 4 x 2 bins, evenly
    h, out = st.cell_density_2d([2.0], [0.5], [0.4], [0.2], xe, ye)
    assert out == pytest.approx(0.0) and (h * 0.1 * 0.1).sum() == pytest.approx(1.0)
    nz = np.argwhere(h > 1e-9)
    assert sorted(set(nz[:, 0])) == list(range(18, 22)) and sorted(set(nz[:, 1])) == [4, 5]
    assert np.allclose(h[h > 1e-9], h[h > 1e-9][0])
    # uniform values on lattices 1/s for s = 2..9, each sample over its cell: flat, no comb
    rng = np.random.default_rng(0)
    s = rng.integers(2, 10, 20000)
    x = np.round(rng.uniform(1.0, 3.0, s.size) * s) / s
    h, _ = st.cell_density_2d(x, np.full(s.size, 0.55), 1.0 / s, np.full(s.size, 0.1), xe, ye)
    col = h[12:28, 5]                                # x in 1.2 .. 2.8, away from the ends
    assert col.std() / col.mean() < 0.05
    plain, _, _ = np.histogram2d(x, np.full(s.size, 0.55), bins=(xe, ye), density=True)
    assert plain[12:28, 5].std() / plain[12:28, 5].mean() > 0.3    # the comb it removes
    with pytest.raises(st.InsufficientDataError):
        st.cell_density_2d([np.nan], [0.0], [1.0], [1.0], xe, ye)


def test_parity_log_edges_balance_odd_and_even_sizes():
    for s_max in (3, 17, 100, 1000):
        e = st.parity_log_edges(s_max)
        assert e[0] == 1 and e[1] == 2 and e[-1] > s_max
        assert np.all(np.diff(e) > 0) and np.all(e[1:] % 2 == 0)
        widths = np.diff(e)[1:]                       # every bin after size 1 holds whole pairs
        assert np.all(widths % 2 == 0)


def test_fd_bins_per_decade_follows_the_spread_and_sample_size():
    rng = np.random.default_rng(1)
    narrow = 10 ** rng.normal(-3, 0.1, 5000)
    wide = 10 ** rng.normal(-3, 1.0, 5000)
    assert st.fd_bins_per_decade(narrow) > st.fd_bins_per_decade(wide)
    assert st.fd_bins_per_decade(wide, lo=3, hi=20) >= 3
    assert st.fd_bins_per_decade([1e-3, 1e-3, 1e-3, 1e-3]) == 3      # no spread: the floor


def test_diff_ci():
    from tiltpile.analysis.stats import diff_ci

    x, y = np.array([10.0, 11.0, 12.0, 13.0]), np.array([7.0, 8.0, 9.0])
    r = diff_ci(x, y)
    assert r["estimate"] == pytest.approx(3.5)
    assert r["low"] < 3.5 < r["high"] and r["high"] - r["low"] < 4.0
    assert (r["n_x"], r["n_y"]) == (4, 3)
    assert np.isnan(diff_ci([1.0], y)["low"])


# -- leave one run out ---------------------------------------------------------------------------

def test_leave_one_run_out_drops_each_run_in_turn():
    frames = pd.DataFrame({"run": [3, 3, 5, 7, 7, 7], "x": [1.0, 2.0, 10.0, 4.0, 4.0, 4.0]})
    got = st.leave_one_run_out(frames, [3, 5, 7], lambda g: float(g["x"].sum()))
    assert got == [22.0, 15.0, 13.0]


def test_loo_stability_of_a_bistable_and_of_a_firm_number():
    """A bin-picked number that 2 of 5 left-out runs move to another bin: bistable, flip share
    0.4; the same number unmoved by every run: firm. A continuous one gets its spread only."""
    b = st.loo_stability(1e-2, [1e-2, 1e-6, 1e-2, 1e-6, 1e-2], discrete=True)
    assert b["values"] == [1e-6, 1e-2] and b["counts"] == [2, 3]
    assert b["flip_share"] == pytest.approx(0.4) and not b["firm"]
    assert (b["low"], b["high"], b["n"]) == (1e-6, 1e-2, 5)
    f = st.loo_stability(0.5, [0.5] * 4, discrete=True)
    assert f["firm"] and f["flip_share"] == 0.0 and f["jackknife_se"] == 0.0
    # a left-out run without which the number is undefined flips it, and leaves no error
    u = st.loo_stability(0.5, [0.5, np.nan, 0.5], discrete=True)
    assert u["flip_share"] == pytest.approx(1 / 3) and np.isnan(u["jackknife_se"])
    c = st.loo_stability(2.0, [1.0, 2.0, 3.0])
    assert "firm" not in c and c["jackknife_se"] == pytest.approx(np.sqrt(2 / 3 * 2.0))


def test_bimodality_from_an_earlier_fit_finds_the_same_optimum():
    """Started from the fit of the same samples, the two-component fit stays there: the valley
    of the leave-one-run-out refits moves only by what the samples do."""
    rng = np.random.default_rng(1)
    y = np.concatenate([rng.normal(-3.0, 0.3, 4000), rng.normal(-1.5, 0.4, 1500)])
    full = st.bimodality(y)
    again = st.bimodality(y, init=full)
    # EM goes on from the converged fit by its own tolerance (1e-10 of the log-likelihood):
    # the valley, on a grid of 7.5e-4 between the means, moves by far less than a grid step;
    # another optimum would put it tenths away
    assert again["valley"] == pytest.approx(full["valley"], abs=1e-4)
    assert again["ashman_d"] == pytest.approx(full["ashman_d"], rel=1e-4)
