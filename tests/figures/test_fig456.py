"""Figs. 4-6 compute functions on small synthetic ensembles with known answers."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tiltpile.analysis import stats
from tiltpile.figures import data, fig4, fig5, fig6

CLUSTER_COLS = ["run", "frame", "theta_deg", "avalanching", "theta_to_onset", "cluster", "size",
                "z", "n_m", "dz"]


def ensemble(frames: pd.DataFrame, clusters: pd.DataFrame) -> data.Ensemble:
    if "dz" not in clusters:
        clusters = clusters.assign(dz=clusters["z"] - clusters["n_m"])   # the library's z - n_m
    seeds = sorted(int(r) for r in frames["run"].unique())
    return data.Ensemble(Path("synthetic"), frames.reset_index(drop=True),
                         clusters.reset_index(drop=True), {}, seeds, {"preset": "synthetic"})


def frames_table(theta_to_onset, avalanching, z_rest=None, largest=None, run=1) -> pd.DataFrame:
    n = len(theta_to_onset)
    return pd.DataFrame({
        "run": run, "frame": np.arange(n), "theta_to_onset": np.asarray(theta_to_onset, float),
        "avalanching": np.asarray(avalanching, bool),
        "z_rest": np.full(n, 3.2) if z_rest is None else np.asarray(z_rest, float),
        "largest_cluster": np.zeros(n, int) if largest is None else np.asarray(largest, int)})


def clusters_table(rows, frames: pd.DataFrame) -> pd.DataFrame:
    """rows: (frame, size, z, n_m); run, avalanching, theta_to_onset copied from the frame."""
    cl = pd.DataFrame(rows, columns=["frame", "size", "z", "n_m"])
    cl = cl.merge(frames[["run", "frame", "avalanching", "theta_to_onset"]], on="frame")
    cl["cluster"] = cl.groupby("frame").cumcount()
    cl["theta_deg"] = 0.0
    return cl


# ---------------------------------------------------------------------------------------------
# Fig. 4


def test_fig4_cluster_positions_relative_to_marginal_line():
    fr = frames_table([-1.0, -0.5, -0.2, 0.0, 0.1], [False, False, False, True, True],
                      z_rest=[3.2, 3.1, 2.9, 3.0, np.nan])
    quiet = [(3.0, 0.5), (3.0, 0.5), (2.5, 0.5), (3.5, 0.5), (4.0, 0.5), (3.75, 0.75)]
    rows = [(k % 3, 2, z, nm) for k, (z, nm) in enumerate(quiet)]
    rows += [(3, 3, 3.0, 0.75), (4, 1, 2.0, 0.5)]
    ens = ensemble(fr, clusters_table(rows, fr))
    numbers, d = fig4.compute(ens, z_range=(1.5, 5.0), nm_range=(0.5, 1.0))
    # delta z_gen = z - 3 - n_m: -0.5, -0.5, -1, 0, 0.5, 0 (quiet); -0.75, -1.5 (avalanche)
    assert numbers["quiet_n"] == 6 and numbers["avalanche_n"] == 2
    assert numbers["quiet_frac_below"] == pytest.approx(3 / 6)
    assert numbers["quiet_frac_on"] == pytest.approx(2 / 6)
    assert numbers["quiet_frac_above"] == pytest.approx(1 / 6)
    assert numbers["quiet_z_mean"] == pytest.approx(19.75 / 6)
    assert numbers["quiet_n_m_mean"] == pytest.approx(3.25 / 6)
    assert numbers["quiet_dz_gen_mean"] == pytest.approx(-1.5 / 6)
    assert numbers["avalanche_dz_gen_mean"] == pytest.approx(-1.125)
    assert numbers["avalanche_frac_below"] == 1.0
    assert numbers["z_rest_mean_quiet"] == pytest.approx(3.2 / 3 + 3.1 / 3 + 2.9 / 3)
    assert numbers["z_rest_mean_avalanche"] == pytest.approx(3.0)
    assert numbers["z_rest_frac_below_iso_quiet"] == pytest.approx(1 / 3)
    assert numbers["frac_outside_range_quiet"] == 0.0
    # each cluster of s grains is spread over its lattice cell, 1/s in z by 1/(2s) in n_m: the
    # five quiet pairs at n_m = 0.5 have cells [0.375, 0.625], of which 0.6 lies inside the
    # n_m range [0.475, 1.025]; the pair at n_m = 0.75 lies inside: the density holds 4/6
    xe, ye = d["xedges"], d["yedges"]
    assert np.allclose(0.5 * (xe[:-1] + xe[1:])[[0, -1]], [1.5, 5.0])
    h = d["density"]["quiet"]
    assert (h * np.outer(np.diff(xe), np.diff(ye))).sum() == pytest.approx(4 / 6)
    i, j = np.searchsorted(xe, 3.0) - 1, np.searchsorted(ye, 0.5) - 1
    assert h[i, j] == pytest.approx(h.max())        # two of six clusters at (3, 0.5)


def test_fig4_without_avalanches_gives_nan():
    fr = frames_table([-1.0, -0.5], [False, False])
    ens = ensemble(fr, clusters_table([(0, 2, 3.0, 0.5)], fr))
    numbers, d = fig4.compute(ens)
    assert numbers["avalanche_n"] == 0 and np.isnan(numbers["avalanche_z_mean"])
    assert np.isnan(numbers["z_rest_mean_avalanche"]) and d["density"]["avalanche"] is None


# ---------------------------------------------------------------------------------------------
# Fig. 5


def _fig5_ensemble(n_per_frame=200, delta=2.5):
    """Quiet frames at theta - theta_m = -5.0 .. -0.1 (grid 0.1 with float jitter), then five
    avalanching frames; P(s) = s^-delta e^{-s/xi} with xi growing from 3 to 60 towards onset."""
    theta = np.arange(60) * 0.1
    theta_m = theta[50]
    rel = theta - theta_m                              # -5.0000000000000004 etc.
    av = np.arange(60) >= 50
    rng = np.random.default_rng(2024)
    rows, largest = [], []
    for k in range(55):
        if k < 50:
            xi = 3.0 * (60.0 / 3.0) ** (k / 49)
        else:
            xi = 100.0
        s = stats.sample_power_law_cutoff(delta, xi, n_per_frame, s_min=2, rng=rng)
        s = np.concatenate([s, [1] * 20])             # size-1 clusters: below s_min, not fitted
        rows += [(k, int(v), 3.0, 0.5) for v in s]
        largest.append(int(s.max()))
    fr = frames_table(rel[:55], av[:55], largest=largest)
    return ensemble(fr, clusters_table(rows, fr)), fr


def test_fig5_recovers_delta_and_growing_xi():
    ens, fr = _fig5_ensemble()
    numbers, d = fig5.compute(ens, windows=(-14.4, -4.6, -0.75, -0.25), width=0.5, s_min=2,
                              delta_pool=(-1.0, 0.0), inset_lo=-5.0, min_samples=50)
    # pooled fit over the 10 frames of [-1, 0): delta back within its error
    assert numbers["n_pooled"] == 10 * 200
    assert abs(numbers["delta_pooled"] - 2.5) < 3 * numbers["delta_pooled_err"]
    assert numbers["delta_pooled_err"] < 0.25
    assert numbers["xi_delta"] == numbers["delta_pooled"]
    w = numbers["windows"]
    # windows of 0.5 deg hold exactly 5 frames although the edges fall on frames
    assert w["-0.25"]["n_frames"] == 5 and w["-0.75"]["n_frames"] == 5
    assert w["-0.25"]["n_clusters"] == 5 * 220
    assert w["-4.6"]["n_frames"] == 5
    # nothing 14.4 deg before onset: refused, NaN, no crash
    assert w["-14.4"]["n_clusters"] == 0 and np.isnan(w["-14.4"]["xi"])
    assert "fit_power_law_cutoff" in d["rows"].loc[0, "fit_error"]
    assert d["fits"][0] is None and len(d["densities"][0]) == 0
    # per-window free exponents agree with the truth
    for key in ("-0.75", "-0.25"):
        assert abs(w[key]["delta"] - 2.5) < 3 * w[key]["delta_err"]
    # xi grows towards the onset
    assert w["-0.25"]["xi"] > 3 * w["-4.6"]["xi"]
    assert numbers["xi_spearman"] > 0.8 and numbers["xi_slope_log10_per_deg"] > 0
    assert numbers["xi_n_windows"] == 10
    # avalanche: all five avalanching frames
    assert w["avalanche"]["n_frames"] == 5 and w["avalanche"]["n_clusters"] == 5 * 220
    assert w["avalanche"]["center"] is None and np.isfinite(w["avalanche"]["xi"])
    # <S_max> near (last 5 frames) and far (theta - theta_m < -4: frames -5.0 .. -4.1)
    lg = fr["largest_cluster"].to_numpy()
    assert numbers["s_max_near"] == pytest.approx(lg[45:50].mean())
    assert numbers["s_max_far"] == pytest.approx(lg[0:10].mean())


def test_fig5_refuses_every_fit_without_crashing():
    fr = frames_table([-0.3, -0.2, 0.0], [False, False, True], largest=[2, 2, 3])
    ens = ensemble(fr, clusters_table([(0, 2, 3.0, 0.5), (1, 2, 3.0, 0.5), (2, 3, 3.0, 0.5)], fr))
    numbers, d = fig5.compute(ens, delta_guide=2.5)
    assert np.isnan(numbers["delta_pooled"]) and numbers["xi_delta"] == 2.5
    assert all(np.isnan(v["xi"]) for v in numbers["windows"].values())
    assert np.isnan(numbers["xi_spearman"]) and np.isnan(numbers["s_max_far"])
    assert numbers["s_max_near"] == pytest.approx(2.0)


# ---------------------------------------------------------------------------------------------
# Fig. 6


def _fig6_ensemble():
    fr = frames_table([-1.0, -0.5, 0.0], [False, False, True])
    q = [(1, 2.0, 0.5), (1, 2.0, 0.5), (1, 3.0, 0.5), (1, 3.0, 0.5),    # -1.5, -1.5, -0.5, -0.5
         (2, 3.0, 0.5)] * 1 + [(2, 3.0, 0.5)] * 3 + [                     # -0.5 (x4)
        (3, 10 / 3, 0.5), (4, 3.5, 0.75),                                  # -1/6, -0.25
        (6, 3.5, 0.5), (6, 3.5, 0.5),                                      # 0, 0
        (20, 3.6, 0.5), (20, 3.6, 0.5), (20, 3.6, 0.5), (50, 3.7, 0.6)]    # 0.1 (x4)
    rows = [(k % 2, s, z, nm) for k, (s, z, nm) in enumerate(q)]
    rows.append((2, 1, 1.0, 0.5))                                          # avalanching: -2.5
    return ensemble(fr, clusters_table(rows, fr))


def test_fig6_dz_by_size_class():
    numbers, d = fig6.compute(_fig6_ensemble(), size_classes=(1, 2, 3, 5, 10), min_samples=1)
    c = numbers["classes"]
    assert list(c) == ["1", "2", "3-4", "5-9", "10+"]
    assert [c[k]["n"] for k in c] == [4, 4, 2, 2, 4]
    assert c["1"]["dz_mean"] == pytest.approx(-1.0) and c["1"]["dz_min"] == pytest.approx(-1.5)
    assert c["2"]["dz_mean"] == pytest.approx(-0.5)
    assert c["3-4"]["dz_mean"] == pytest.approx((-1 / 6 - 0.25) / 2)
    assert c["3-4"]["dz_min"] == pytest.approx(-0.25)
    assert c["5-9"]["dz_mean"] == pytest.approx(0.0, abs=1e-12)
    assert c["10+"]["dz_mean"] == pytest.approx(0.1) and c["10+"]["dz_min"] == pytest.approx(0.1)
    assert numbers["dz_global"] == 0.0 and numbers["dz_single_grain"] == -1.5
    assert numbers["n_clusters"] == 16
    assert numbers["frac_below_single_grain"] == 0.0          # the -2.5 cluster is avalanching
    assert numbers["frac_single_on_bound"] == pytest.approx(0.5)
    # log bins [1,2) [2,3) [3,4) [4,7) [16,26) [40,64): means -1, -0.5, -1/6, -1/12, 0.1, 0.1
    assert numbers["s_cross"] == 16.0
    assert numbers["slope_per_decade"] > 0
    assert numbers["largest_bin"]["size_lo"] == 40 and numbers["largest_bin"]["n"] == 1
    # distributions: normalised, on the 1 / (2 s) lattice
    for (lo, dist) in zip((1, 2, 3, 5, 10), d["distributions"]):
        w = 1.0 / (2 * lo)
        assert (dist["density"] * w).sum() == pytest.approx(1.0)
        assert np.allclose(dist["center"] / w, np.round(dist["center"] / w))


def test_fig6_all_clusters_and_empty_classes():
    numbers, _ = fig6.compute(_fig6_ensemble(), size_classes=(1, 100), quiet_only=False,
                              min_samples=100)
    assert numbers["classes"]["1-99"]["n"] == 17
    assert numbers["classes"]["1-99"]["dz_min"] == pytest.approx(-2.5)
    assert numbers["classes"]["100+"]["n"] == 0 and np.isnan(numbers["classes"]["100+"]["dz_mean"])
    assert numbers["frac_below_single_grain"] == pytest.approx(1 / 17)
    # no bin has 100 clusters: no trend, no crash
    assert np.isnan(numbers["slope_per_decade"]) and np.isnan(numbers["s_cross"])
    assert numbers["largest_bin"] is None


def test_fig6_no_clusters():
    fr = frames_table([-1.0], [False])
    empty = pd.DataFrame({c: pd.Series(dtype=float) for c in CLUSTER_COLS})
    numbers, d = fig6.compute(ensemble(fr, empty))
    assert numbers["n_clusters"] == 0 and all(v["n"] == 0 for v in numbers["classes"].values())
    assert np.isnan(numbers["frac_below_single_grain"])


def test_fig6_leaves_out_clusters_with_a_locally_unstable_grain():
    ens = _fig6_ensemble()
    cl = ens.clusters.copy()
    # a quiet single grain with one sliding contact (z = 1, n_m = 1/2: delta z = -2.5), moving
    bad = cl.iloc[[0]].assign(z=1.0, n_m=0.5)
    cl = pd.concat([cl, bad], ignore_index=True)
    cl["n_unstable"] = 0
    cl.loc[cl.index[-1], "n_unstable"] = 1
    cl["speed_max"] = 1e-5
    cl.loc[cl.index[-1], "speed_max"] = 0.03
    ens = data.Ensemble(ens.data_dir, ens.frames, cl, {}, ens.seeds, ens.meta)
    numbers, _ = fig6.compute(ens, min_samples=1)
    assert numbers["n_clusters_before_stability"] == 17 and numbers["n_clusters_unstable"] == 1
    assert numbers["frac_below_single_grain_before_stability"] == pytest.approx(1 / 17)
    assert numbers["speed_max_median_unstable"] == pytest.approx(0.03)
    assert numbers["speed_max_median_stable"] == pytest.approx(1e-5)
    assert numbers["n_clusters"] == 16 and numbers["frac_below_single_grain"] == 0.0
    assert numbers["dz_min_all"] == pytest.approx(-1.5)
    assert list(numbers["classes"]) == ["1", "2-3", "4-7", "8-15", "16+"]
    kept, _ = fig6.compute(ens, min_samples=1, stable_only=False)
    assert kept["n_clusters"] == 17 and kept["dz_min_all"] == pytest.approx(-2.5)


def test_dz_distribution_of_several_sizes_spreads_over_cells():
    cl = pd.DataFrame({"size": [2, 3, 3], "dz": [0.0, 0.0, 1 / 6]})
    d = stats.dz_distribution(cl, 2, 4)                 # bins of 1/4 centred on multiples of 1/4
    w = 0.25
    assert (d["density"] * w).sum() == pytest.approx(1.0)
    assert d["count"].sum() == pytest.approx(3.0)
    # bin [-1/8, 1/8): the size-2 cluster and the size-3 cell [-1/12, 1/12] whole, and a quarter
    # of the cell [1/12, 1/4] of the cluster at 1/6
    assert float(d.loc[np.isclose(d["center"], 0.0), "count"].iloc[0]) == pytest.approx(2.25)


# ---------------------------------------------------------------------------------------------
# what the figures draw (issue 74 item 5): on the figure objects, not on pixels


def test_fig5_legend_gives_the_interval_the_report_gives():
    import json

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tiltpile.report.judging import show_ci

    # the committed paper-scale numbers: the legend's delta is the report's "x [lo, hi]"
    doc = json.loads((Path(__file__).resolve().parents[2] / "figures" / "paper"
                      / "fig5_cluster_sizes.json").read_text())
    n = doc["numbers"]
    x, interval = show_ci(n, "delta_pooled", ".2f").split(" ", 1)
    assert fig5.delta_label(n) == rf" (fit: $\delta = {x}$ {interval})"
    assert r"\pm" not in fig5.delta_label(n)
    # drawn: the legend of a computed figure, with the interval set as a bootstrap gives it
    ens, _ = _fig5_ensemble()
    numbers, d = fig5.compute(ens, windows=(-14.4, -4.6, -0.75, -0.25), inset_lo=-5.0)
    assert np.isnan(numbers["delta_pooled_ci_low"])          # one run: no interval over runs
    for ci, want in (((np.nan, np.nan), rf"\pm {numbers['delta_pooled_err']:.2f}"),
                     ((2.35, 2.61), "[2.35, 2.61]")):
        shown = dict(numbers, delta_pooled_ci_low=ci[0], delta_pooled_ci_high=ci[1])
        fig = fig5.plot(d, shown)
        try:
            texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
            guide = [t for t in texts if t.startswith("slope")]
            assert len(guide) == 1 and want in guide[0]
            assert f"{numbers['delta_pooled']:.2f}" in guide[0]
        finally:
            plt.close(fig)


def test_fig6b_error_bars_are_drawn_above_the_markers():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.container import ErrorbarContainer

    numbers, d = fig6.compute(_fig6_ensemble(), min_samples=1)
    fig = fig6.plot(d, numbers)
    try:
        bx = fig.axes[1]
        marker = next(ln for ln in bx.get_lines() if ln.get_marker() == "s")
        assert marker.get_markerfacecolor() in ("white", (1.0, 1.0, 1.0, 1.0))   # open
        bars = [c for c in bx.containers if isinstance(c, ErrorbarContainer)]
        assert len(bars) == 2                                   # s.d. and s.e. of the mean
        for c in bars:
            _, caps, cols = c.lines
            for artist in (*caps, *cols):
                assert artist.get_zorder() > marker.get_zorder()
        b = d["bins"]
        sem = (b["dz_std"] / np.sqrt(b["n"])).to_numpy(float)
        heights = {}
        for c in bars:
            segs = c.lines[2][0].get_segments()
            heights[c.get_label()] = np.array([s[1, 1] - s[0, 1] for s in map(np.asarray, segs)
                                               if s.shape == (2, 2)])
        got = next(v for k, v in heights.items() if "s.e." in k)
        assert got == pytest.approx(2 * sem[np.isfinite(sem)])
        sd = next(v for k, v in heights.items() if "s.d." in k)
        assert sd == pytest.approx(2 * b["dz_std"].dropna().to_numpy(float))
    finally:
        plt.close(fig)
