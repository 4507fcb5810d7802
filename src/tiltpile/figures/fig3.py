"""Fig. 3 -- critical clusters and local failure (paper Fig. 3).

(a, top) The pile about 0.3 deg before the avalanche angle theta_m (first onset) of a sample
run.
Grains in critical clusters are dark, fully mobilized (critical) contacts green lines between the
centres (to the wall or floor for wall contacts), grains with a contact lost before the next frame
("failing") red when they were in a cluster, blue otherwise; the arrow is gravity.

(b, middle left) Spatial correlation. Over the quiet frames, the fraction of the failing grains
that were in a cluster, N^f_c / N^f, against the fraction of the grains in clusters, N_c / N,
binned in N_c / N; failure uncorrelated with clusters would put the points on y = x.

(c, middle right) Temporal correlation C(tau) (paper Eq. 2) between the largest cluster S_m(k)
and the failure N^f(k + tau), pooled over the quiet periods of all runs
(:func:`tiltpile.analysis.correlation_function_ensemble`). The paper's text defines N^f as the
number of contacts that fail ("the number of contacts N^f that fail in the following frames")
while its caption speaks of failing particles; the primary curve uses lost contacts
(``n_lost``), the failing grains (``n_failing``) are drawn for comparison.

(d, bottom) Orientation of the clusters: the distribution of the angle between the long axis of
a cluster of at least ``orientation_min_size`` grains and gravity (0 = along g, 90 = across;
isotropic clusters would spread evenly over 0-90, mean 45), quiet frames filled, avalanching
frames as a line, with our median and mean and the paper's "roughly 60 deg"
(:data:`tiltpile.paper_values.ORIENTATION_DEG`, the text on its Fig. 3 top) marked.

Frame convention (analysis.avalanche): n_lost, n_failing, n_failing_in_cluster of frame k count
what is lost between k and k + 1, for grains as they were at frame k; the last frame of a run has
no successor (lost_fraction NaN, counts -1) and is dropped here.

The pile picture and the frame it shows are those of :mod:`tiltpile.figures.snapshot` (shared with
Fig. 1b).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tiltpile.analysis import stats as _st
from tiltpile.paper_values import ORIENTATION_DEG

from . import style
from .data import Reads
from .snapshot import (SNAPSHOT_OFFSET_DEG, draw_snapshot, frame_before_onset, load_snapshot,
                       snapshot_extent)

# the table columns the figure reads (from records, only these are checked)
READS = Reads("Fig. 3",
              frames=("theta_deg", "n_lost", "lost_fraction", "n_failing",
                      "n_failing_in_cluster", "largest_cluster", "cluster_fraction",
                      "avalanching", "onset", "period", "theta_m", "theta_to_onset"),
              clusters=("avalanching", "size", "orientation_deg"))

NAME = "fig3_clusters_failure"


# ----------------------------------------------------------------------------------------------
# spatial correlation of failure and clusters


def failure_in_clusters(frames: pd.DataFrame, bin_width: float = 0.05,
                        min_failing: int = 5) -> tuple[pd.DataFrame, dict]:
    """Failing grains that were in a cluster versus the fraction of grains in clusters.

    frames: quiet frames with a successor (columns cluster_fraction = N_c / N, n_failing = N^f,
    n_failing_in_cluster = N^f_c). Frames are binned by N_c / N in bins [k w, (k + 1) w); per bin
    the pooled fraction N^f_c / N^f = sum N^f_c / sum N^f, plotted at the failure-weighted mean
    x = sum N^f N_c/N / sum N^f of the bin (the value of y if failure were uncorrelated with
    clusters, since a failing grain would then be in a cluster with probability N_c / N). Bins
    with fewer than ``min_failing`` failing grains are dropped.

    Returns (bins, summary): bins a DataFrame left, right, n_frames, n_failing, x, fraction,
    excess (= fraction - x); summary a dict:
      fraction_pooled   sum N^f_c / sum N^f over all frames
      expected_pooled   sum N^f N_c/N / sum N^f (what uncorrelated failure would give)
      excess_pooled     fraction_pooled - expected_pooled
      enrichment        fraction_pooled / expected_pooled
      excess_binned     mean of ``excess`` over the kept bins (unweighted)
      n_failing         sum N^f
    """
    x = frames["cluster_fraction"].to_numpy(float)
    nf = frames["n_failing"].to_numpy(float)
    nfc = frames["n_failing_in_cluster"].to_numpy(float)
    ok = np.isfinite(x) & np.isfinite(nf) & np.isfinite(nfc) & (nf > 0)
    x, nf, nfc = x[ok], nf[ok], nfc[ok]
    cols = ["left", "right", "n_frames", "n_failing", "x", "fraction", "excess"]
    tot = nf.sum()
    summary = {"fraction_pooled": np.nan, "expected_pooled": np.nan, "excess_pooled": np.nan,
               "enrichment": np.nan, "excess_binned": np.nan, "n_failing": float(tot)}
    if tot == 0:
        return pd.DataFrame(columns=cols), summary
    frac, expd = nfc.sum() / tot, (nf * x).sum() / tot
    summary.update(fraction_pooled=frac, expected_pooled=expd, excess_pooled=frac - expd,
                   enrichment=frac / expd if expd > 0 else np.nan)
    k = np.floor(x / bin_width + 1e-9).astype(np.int64)
    rows = []
    for b in np.unique(k):
        s = k == b
        n_b = nf[s].sum()
        if n_b < min_failing:
            continue
        xb = (nf[s] * x[s]).sum() / n_b
        fb = nfc[s].sum() / n_b
        rows.append({"left": b * bin_width, "right": (b + 1) * bin_width, "n_frames": int(s.sum()),
                     "n_failing": float(n_b), "x": xb, "fraction": fb, "excess": fb - xb})
    bins = pd.DataFrame(rows, columns=cols)
    if len(bins):
        summary["excess_binned"] = float(bins["excess"].mean())
    return bins, summary


def _argmax_tau(c: pd.DataFrame) -> tuple[float, float]:
    """(tau, C) at the maximum of a C(tau) table (NaN, NaN if all NaN; ties: smallest |tau|)."""
    v = c["C"].to_numpy(float)
    if not np.isfinite(v).any():
        return np.nan, np.nan
    t = c["tau"].to_numpy()
    order = np.lexsort((t, np.abs(t), -np.where(np.isfinite(v), v, -np.inf)))
    return int(t[order[0]]), float(v[order[0]])


def _at(df: pd.DataFrame, col: str, tau: int) -> float:
    r = df.loc[df["tau"] == tau, col]
    return float(r.iloc[0]) if len(r) else np.nan


# ----------------------------------------------------------------------------------------------


def compute(ens, sample_seed: int | None = None, snapshot_offset_deg: float = SNAPSHOT_OFFSET_DEG,
            failure_column: str = "n_lost", tau_max: int = 10, enhancement_tau_max: int = 5,
            fraction_bin_width: float = 0.05, min_failing: int = 5,
            orientation_min_size: int = 5, snapshot: bool = True,
            peak_rule: str = _st.DEFAULT_PEAK_RULE) -> tuple[dict, dict]:
    """Numbers and plot data of Fig. 3 (module docstring).

    sample_seed: run of the snapshot (None: the first run with an onset); snapshot_offset_deg:
    the snapshot is the quiet frame closest to theta_m - offset; failure_column: N^f of C(tau)
    and of the enhancement ("n_lost" contacts or "n_failing" grains); tau_max: C(tau) at lags
    -tau_max..tau_max; enhancement_tau_max: the failure enhancement after cluster peaks at lags
    0..enhancement_tau_max
    (:func:`tiltpile.analysis.failure_enhancement_ensemble`); fraction_bin_width, min_failing:
    binning of the spatial correlation (:func:`failure_in_clusters`); orientation_min_size:
    smallest cluster whose orientation enters the mean; snapshot: read the snapshot from the run
    file (False for tables without run files); peak_rule: what counts as a peak of S_m in the
    enhancement (:data:`tiltpile.analysis.stats.PEAK_RULES`, :func:`~tiltpile.analysis.cluster_peaks`):
    "sigma" (default) a quiet local maximum more than one standard deviation above its run's
    quiet mean, "local" any quiet local maximum, "decile" any quiet frame in the top decile of
    its run's quiet S_m, "c0" no peaks: the paper's +40% read as C(0), so that the enhancement
    numbers are C(tau) at tau >= 0 (enhancement_tau0 = C_tau0) and n_peaks the frame pairs of
    C(0).

    numbers:
      snapshot                    seed, frame, theta_deg, theta_to_onset of the top panel, and
                                  its grains in clusters / failing / failing in a cluster
      failing_in_cluster_*        from :func:`failure_in_clusters` over quiet frames
                                  (fraction, expected, excess pooled; excess binned;
                                  enrichment = fraction / expected)
      failure_column              which N^f the C(tau) and enhancement use
      C_tau0, C_max, C_argmax_tau C(tau) at tau = 0, its maximum and where (frames)
      C_tau0_alt                  C(0) with the other failure measure (n_failing / n_lost)
      enhancement_tau0            failure rate just after cluster-size peaks (tau = 0: failure
                                  between the peak frame and the next) relative to the quiet
                                  mean, minus 1 (paper: ~ +40%)
      enhancement_max, enhancement_argmax_tau   its maximum over those lags and where
      n_peaks                     cluster-size peaks entering enhancement_tau0
      peak_rule                   the peak_rule, written only when it is not the default
                                  ("sigma"), so that the default's numbers stay as they were
      orientation_mean_deg, orientation_median_deg, n_clusters_orientation
                                  angle of the long axis of quiet-frame clusters of size >=
                                  orientation_min_size to gravity (0 = along g; isotropic
                                  clusters would give 45 on average; paper ~60)
      orientation_mean_avalanche_deg, n_clusters_orientation_avalanche   same, avalanching frames
    """
    _st.check_peak_rule(peak_rule)
    # the library's C(tau) and enhancement skip the last frame's forward counts themselves
    fr = ens.frames.sort_values(["run", "frame"], kind="stable")
    quiet_all = ~fr["avalanching"].to_numpy(bool)
    has_next = np.isfinite(fr["lost_fraction"].to_numpy(float))
    qf = fr[quiet_all & has_next]
    numbers: dict = {}
    d: dict = {}

    # snapshot
    seed = ens.sample_seed(sample_seed)
    frame = frame_before_onset(fr, seed, snapshot_offset_deg)
    row = fr[(fr["run"] == seed) & (fr["frame"] == frame)].iloc[0]
    numbers["snapshot"] = {"seed": seed, "frame": frame, "theta_deg": float(row["theta_deg"]),
                           "theta_to_onset": float(row["theta_to_onset"])}
    d["snapshot"] = load_snapshot(ens, seed, frame) if snapshot else None
    if d["snapshot"] is not None:
        s = d["snapshot"]
        numbers["snapshot"].update(n_in_clusters=s["n_in_clusters"], n_failing=s["n_failing"],
                                   n_failing_in_cluster=s["n_failing_in_cluster"])

    # spatial correlation
    bins, summ = failure_in_clusters(qf, fraction_bin_width, min_failing)
    numbers.update(failing_in_cluster_fraction=summ["fraction_pooled"],
                   failing_in_cluster_expected=summ["expected_pooled"],
                   failing_in_cluster_excess=summ["excess_pooled"],
                   failing_in_cluster_excess_binned=summ["excess_binned"],
                   failing_in_cluster_enrichment=summ["enrichment"],
                   n_failing_grains=summ["n_failing"])
    d["fraction_bins"] = bins

    # temporal correlation
    alt = "n_failing" if failure_column == "n_lost" else "n_lost"
    taus, enhancement_taus = range(-tau_max, tau_max + 1), range(0, enhancement_tau_max + 1)
    c = _st.correlation_function_ensemble(fr, a="largest_cluster", b=failure_column, taus=taus)
    c_alt = _st.correlation_function_ensemble(fr, a="largest_cluster", b=alt, taus=taus)
    tmax, cmax = _argmax_tau(c)
    numbers.update(failure_column=failure_column, C_tau0=_at(c, "C", 0), C_max=cmax,
                   C_argmax_tau=tmax, C_tau0_alt=_at(c_alt, "C", 0))
    enh = _st.failure_enhancement_ensemble(fr, a="largest_cluster", b=failure_column,
                                           taus=enhancement_taus, peak_rule=peak_rule)
    e = enh["enhancement"].to_numpy(float)
    if np.isfinite(e).any():
        i = int(np.nanargmax(e))
        e_max, e_tau = float(e[i]), int(enh["tau"].iloc[i])
    else:
        e_max, e_tau = np.nan, np.nan
    n_peaks = _at(enh, "n_peaks", 0)
    numbers.update(enhancement_tau0=_at(enh, "enhancement", 0), enhancement_max=e_max,
                   enhancement_argmax_tau=e_tau,
                   n_peaks=int(n_peaks) if np.isfinite(n_peaks) else 0)
    if peak_rule != _st.DEFAULT_PEAK_RULE:
        numbers["peak_rule"] = peak_rule
    dtheta = fr.groupby("run")["theta_deg"].diff().to_numpy(float)
    d.update(C=c, C_alt=c_alt, failure_column=failure_column, alt_column=alt,
             dtheta_frame=float(np.nanmedian(dtheta)) if np.isfinite(dtheta).any() else np.nan)

    # orientation of the clusters
    cl = ens.clusters
    big = (cl["size"].to_numpy() >= orientation_min_size) & np.isfinite(
        cl["orientation_deg"].to_numpy(float))
    av = cl["avalanching"].to_numpy(bool)
    oq = cl["orientation_deg"].to_numpy(float)[big & ~av]
    oa = cl["orientation_deg"].to_numpy(float)[big & av]
    numbers.update(orientation_mean_deg=float(oq.mean()) if oq.size else np.nan,
                   orientation_median_deg=float(np.median(oq)) if oq.size else np.nan,
                   n_clusters_orientation=int(oq.size),
                   orientation_mean_avalanche_deg=float(oa.mean()) if oa.size else np.nan,
                   n_clusters_orientation_avalanche=int(oa.size))
    # the angles themselves, for the orientation panel (d): plot data only, not in the JSON
    d.update(orientation_quiet=oq, orientation_avalanche=oa,
             orientation_min_size=int(orientation_min_size))
    return numbers, d


def plot(data: dict, numbers: dict):
    """(a) snapshot; (b) N^f_c / N^f versus N_c / N; (c) C(tau); (d) cluster orientation."""
    lay = data["snapshot"]
    ew, eh = snapshot_extent(lay) if lay is not None else (2.0, 1.0)
    left, right = 0.15, 0.97
    h_top = (right - left) * style.SINGLE_COLUMN_IN * eh / ew
    # rows: the pile, b and c, a spacer (room for b's and c's axis labels), d
    height, gkw = style.stacked_layout([h_top, 1.3, 0.06, 1.05], [0.22, 0.22, 0.22], top_in=0.3,
                                       bottom_in=0.4, left=left, right=right)
    fig, axs = style.figure(4, 2, height=height, gridspec_kw=dict(gkw, wspace=0.45))
    gs = axs[0, 0].get_gridspec()
    for a in (*axs[0], *axs[2], *axs[3]):
        a.remove()
    top = fig.add_subplot(gs[0, :])
    draw_snapshot(top, lay)
    style.panel_label(top, "a", x=0.0, y=1.0)

    # bottom left: spatial correlation
    ax = axs[1, 0]
    b = data["fraction_bins"]
    ax.plot([0, 1], [0, 1], ls="--", color=style.COLORS["guide"], lw=0.8, label="uncorrelated")
    if len(b):
        ax.plot(b["x"], b["fraction"], ls="-", marker="s", ms=3, color=style.COLORS["quiet"],
                label="quiet frames")
    xmax = max(0.1, float(b["right"].max())) if len(b) else 1.0
    ax.set_xlim(0, min(1.0, xmax))
    ax.set_ylim(0, 1.02)
    ax.set_xlabel(r"$N_c/N$ (grains in clusters)")
    ax.set_ylabel(r"$N^f_c/N^f$ (failing in clusters)")
    ax.legend(loc="lower right", handlelength=1.5)
    style.panel_label(ax, "b", x=0.04, y=0.96)

    # bottom right: C(tau)
    ax = axs[1, 1]
    c, ca = data["C"], data["C_alt"]
    names = {"n_lost": "lost contacts", "n_failing": "failing grains"}
    ax.axhline(0, color=style.COLORS["guide"], lw=0.6)
    ax.axvline(0, color=style.COLORS["guide"], lw=0.6, ls=":")
    # the two measures of N^f give nearly the same C(tau): the main one as filled black dots, the
    # other as large open blue triangles on top, so that both stay visible where they coincide
    ax.plot(c["tau"], c["C"], ls="-", marker="o", ms=2.5, lw=0.8, color=style.COLORS["quiet"],
            label=names.get(data["failure_column"], data["failure_column"]), zorder=3)
    ax.plot(ca["tau"], ca["C"], ls=(0, (3, 2)), marker="^", ms=4.5, mew=0.7, lw=0.8,
            color=style.CYCLE[1], mfc="none",
            label=names.get(data["alt_column"], data["alt_column"]), zorder=4)
    dt = data.get("dtheta_frame", np.nan)
    unit = f" (frames, {dt:.2g}$^\\circ$)" if np.isfinite(dt) else " (frames)"
    ax.set_xlabel(r"$\tau$" + unit)
    ax.set_ylabel(r"$C(\tau)$")
    vals = np.r_[c["C"].to_numpy(float), ca["C"].to_numpy(float)]
    vals = vals[np.isfinite(vals)]
    hi = max(0.1, float(vals.max())) if vals.size else 1.0
    lo = min(-0.05, float(vals.min())) if vals.size else -0.1
    ax.set_ylim(lo - 0.05 * (hi - lo), hi + 1.1 * (hi - lo))
    ax.legend(loc="upper right", handlelength=1.8, title=r"$N^f$:", title_fontsize=6.5,
              alignment="left")
    style.panel_label(ax, "c", x=0.04, y=0.96)

    plot_orientation(fig.add_subplot(gs[3, :]), data, numbers)
    return fig


ORIENTATION_BIN_DEG = 5.0   # bins of panel d (deg)


def plot_orientation(ax, data: dict, numbers: dict) -> None:
    """Panel d: the density (per degree) of the clusters' orientation to gravity, quiet frames
    filled and avalanching frames as a line, with the isotropic level 1/90, our median and mean
    over the quiet clusters (the JSON's orientation_median_deg, orientation_mean_deg) and the
    paper's ~60 deg (``ORIENTATION_DEG``) as vertical lines (gids orientation_median,
    orientation_mean, orientation_paper)."""
    edges = np.arange(0.0, 90.0 + ORIENTATION_BIN_DEG / 2, ORIENTATION_BIN_DEG)
    oq = np.asarray(data.get("orientation_quiet", []), float)
    oa = np.asarray(data.get("orientation_avalanche", []), float)
    top = 1.0 / 90.0
    smin = data.get("orientation_min_size", 5)
    if oq.size:
        h, _ = np.histogram(oq, bins=edges, density=True)
        ax.stairs(h, edges, fill=True, color=style.COLORS["grain"], lw=0,
                  label=f"quiet ({oq.size} clusters, $s \\geq {smin}$)")
        ax.stairs(h, edges, color=style.COLORS["guide"], lw=0.6)
        top = max(top, float(h.max()))
    if oa.size:
        h, _ = np.histogram(oa, bins=edges, density=True)
        ax.stairs(h, edges, color=style.COLORS["avalanche"], lw=0.8, label="avalanching")
        top = max(top, float(h.max()))
    ax.axhline(1.0 / 90.0, color=style.COLORS["guide"], lw=0.6, ls=":", label="isotropic")
    med, mean = numbers.get("orientation_median_deg"), numbers.get("orientation_mean_deg")
    headroom = 1.75                      # the top of the panel (above the data) holds the key
    below = 1.08 / headroom              # the vertical lines stop under the key
    if med is not None and np.isfinite(med):
        ax.axvline(med, ymax=below, color=style.COLORS["quiet"], lw=1.0, gid="orientation_median",
                   label=f"median {med:.0f}$^\\circ$")
    if mean is not None and np.isfinite(mean):
        ax.axvline(mean, ymax=below, color=style.COLORS["quiet"], lw=0.8, ls=(0, (1, 1)),
                   gid="orientation_mean", label=f"mean {mean:.0f}$^\\circ$")
    ax.axvline(ORIENTATION_DEG.value, ymax=below, color=style.COLORS["marginal"], lw=1.0, ls="--",
               gid="orientation_paper", label=f"paper ~{ORIENTATION_DEG.value:g}$^\\circ$")
    ax.set_xlim(0.0, 90.0)
    ax.set_xticks(np.arange(0, 91, 15))
    ax.set_ylim(0.0, headroom * top)
    ax.set_xlabel(r"long axis of a cluster to gravity (deg)")
    ax.set_ylabel("density (1/deg)")
    ax.legend(loc="upper left", ncol=2, fontsize=5.5, handlelength=1.5, columnspacing=1.0,
              borderaxespad=0.3, bbox_to_anchor=(0.06, 1.0))
    style.panel_label(ax, "d", x=0.015, y=0.96)
