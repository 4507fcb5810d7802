"""Fig. 3 -- critical clusters and local failure (paper Fig. 3).

(a, top) The pile about 0.3 deg before the avalanche angle theta_m (first onset) of a sample
run.
Grains in critical clusters are dark, fully mobilized (critical) contacts green lines between the
centres (to the wall or floor for wall contacts), grains with a contact lost before the next frame
("failing") red when they were in a cluster, blue otherwise; the arrow is gravity.

(b, bottom left) Spatial correlation. Over the quiet frames, the fraction of the failing grains
that were in a cluster, N^f_c / N^f, against the fraction of the grains in clusters, N_c / N,
binned in N_c / N; failure uncorrelated with clusters would put the points on y = x.

(c, bottom right) Temporal correlation C(tau) (paper Eq. 2) between the largest cluster S_m(k)
and the failure N^f(k + tau), pooled over the quiet periods of all runs
(:func:`tiltpile.analysis.correlation_function_ensemble`). The paper's text defines N^f as the
number of contacts that fail ("the number of contacts N^f that fail in the following frames")
while its caption speaks of failing particles; the primary curve uses lost contacts
(``n_lost``), the failing grains (``n_failing``) are drawn for comparison.

Frame convention (analysis.avalanche): n_lost, n_failing, n_failing_in_cluster of frame k count
what is lost between k and k + 1, for grains as they were at frame k; the last frame of a run has
no successor (lost_fraction NaN, counts -1) and is dropped here.

The snapshot helpers (:func:`snapshot_layers`, :func:`load_snapshot`, :func:`draw_snapshot`) are
shared with Fig. 1b.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tiltpile.analysis import DEFAULT_PARAMS
from tiltpile.analysis import observables as _ob
from tiltpile.analysis import contacts as _ct
from tiltpile.analysis import stats as _st

from . import style

NAME = "fig3_clusters_failure"
SNAPSHOT_OFFSET_DEG = 0.3   # panel a: the quiet frame closest to theta_m minus this (deg)

# grain categories of a snapshot (index into CATEGORY_COLORS)
GRAIN, FIXED, CLUSTER, FAIL_IN_CLUSTER, FAIL_OUTSIDE = range(5)
CATEGORY_COLORS = [style.COLORS["grain"], style.COLORS["fixed"], style.COLORS["cluster"],
                   style.COLORS["fail_in_cluster"], style.COLORS["fail_outside"]]


# ----------------------------------------------------------------------------------------------
# helpers shared with the other figure modules


def analysis_params(ens) -> dict:
    """The analysis parameters the ensemble's tables were computed with (defaults filled in)."""
    return dict(DEFAULT_PARAMS, **(ens.meta.get("analysis") or {}))


def frame_before_onset(frames: pd.DataFrame, seed: int,
                       offset_deg: float = SNAPSHOT_OFFSET_DEG) -> int:
    """The quiet frame of run ``seed`` closest to theta_m - offset_deg (theta_m: first onset).

    Only quiet frames before the first onset are candidates (ties: the earlier frame). Without an
    onset, the last quiet frame; with no candidate at all, the run's first frame.
    """
    g = frames[frames["run"] == seed].sort_values("frame", kind="stable")
    if g.empty:
        raise ValueError(f"run {seed} is not in the table")
    quiet = ~g["avalanching"].to_numpy(bool)
    onset = g["onset"].to_numpy(bool)
    if not onset.any():
        return int(g["frame"].to_numpy()[quiet][-1]) if quiet.any() else int(g["frame"].iloc[0])
    i0 = int(np.flatnonzero(onset)[0])
    cand = np.flatnonzero(quiet[:i0])
    if cand.size == 0:
        return int(g["frame"].iloc[0])
    theta = g["theta_deg"].to_numpy(float)
    target = theta[i0] - offset_deg
    best = cand[np.argmin(np.abs(theta[cand] - target))]     # argmin: first of ties
    return int(g["frame"].to_numpy()[best])


def snapshot_layers(snap: dict, mu: float = 0.5, mu_wall: float | None = None,
                    eps: float | None = None, link: str = "contacts",
                    cluster_region: str = "mobile", ray_spacing: float = 0.1,
                    touch_tol: float = 0.05, lost_gap: float | None = None) -> dict:
    """What the pile pictures of Figs. 1b and 3 draw, from one frame (a :func:`data.snapshot`).

    The contacts, mobilized contacts and clusters are those of the observables
    (:func:`tiltpile.analysis.observables.frame_contacts`); failing grains are the mobile ends of
    the contacts lost by the next frame (:func:`~tiltpile.analysis.observables.lost_between`, with
    the same ``lost_gap``).

    Returns dict: position (N, 2), radius (N,), category (N,) int8 (GRAIN, FIXED, CLUSTER,
    FAIL_IN_CLUSTER, FAIL_OUTSIDE), segments (M, 2, 2) one per fully mobilized contact (centre to
    centre, or centre to the wall/floor contact point), theta_deg, box_length, and the counts
    n_clusters, n_in_clusters, n_failing, n_failing_in_cluster, n_critical_contacts.
    """
    pos = np.asarray(snap["position"], dtype=float)
    radius = np.asarray(snap["radius"], dtype=float)
    fixed = np.asarray(snap["fixed"], dtype=bool)
    L = float(snap["box_length"])
    n = radius.size
    fc = _ob.frame_contacts(radius, fixed, L, pos, snap["pair"], snap["force"], snap.get("status"),
                            mu=mu, mu_wall=mu_wall, eps=eps, link=link,
                            cluster_region=cluster_region, ray_spacing=ray_spacing,
                            touch_tol=touch_tol)
    pair, mobil, labels = fc["pair"], fc["mobilized"], fc["labels"]
    in_cluster = labels >= 0
    failing = np.zeros(n, dtype=bool)
    if snap.get("next") is not None:
        p2, f2 = np.asarray(snap["next"][0]).reshape(-1, 2), snap["next"][1]
        cur = {"pair": p2, "active": _ct.active_mask(f2), "position": snap.get("next_position")}
        lost = _ob.lost_between({"pair": pair, "active": fc["active"]}, cur, n, radius, L, lost_gap)
        failing = _ct.failing_grains(n, pair, lost, fixed)
    cat = np.full(n, GRAIN, dtype=np.int8)
    cat[fixed] = FIXED
    cat[in_cluster] = CLUSTER
    cat[failing & in_cluster] = FAIL_IN_CLUSTER
    cat[failing & ~in_cluster] = FAIL_OUTSIDE
    i, j = pair[mobil, 0], pair[mobil, 1]
    a = pos[i]
    b = pos[np.maximum(j, 0)].copy()           # wall contacts: the point on the wall
    fl, le, ri = j == _ct.WALL_FLOOR, j == _ct.WALL_LEFT, j == _ct.WALL_RIGHT
    b[fl] = np.c_[a[fl, 0], np.zeros(fl.sum())]
    b[le] = np.c_[np.zeros(le.sum()), a[le, 1]]
    b[ri] = np.c_[np.full(ri.sum(), L), a[ri, 1]]
    return {"position": pos, "radius": radius, "category": cat,
            "segments": np.stack([a, b], axis=1) if i.size else np.zeros((0, 2, 2)),
            "theta_deg": float(snap["theta_deg"]), "box_length": L,
            "n_clusters": int(labels.max() + 1) if in_cluster.any() else 0,
            "n_in_clusters": int(in_cluster.sum()), "n_failing": int(failing.sum()),
            "n_failing_in_cluster": int((failing & in_cluster).sum()),
            "n_critical_contacts": int(i.size)}


def load_snapshot(ens, seed: int, frame: int) -> dict:
    """:func:`snapshot_layers` of one stored frame, with the ensemble's friction and analysis
    parameters; adds seed and frame."""
    from . import data
    p = analysis_params(ens)
    scene = (ens.config or {}).get("scene", {})
    mu = float(scene.get("mu", 0.5))
    lay = snapshot_layers(data.snapshot(ens, seed, frame), mu=mu,
                          mu_wall=float(scene.get("mu_wall", mu)), eps=p["eps"], link=p["link"],
                          cluster_region=p["cluster_region"], ray_spacing=p["ray_spacing"],
                          touch_tol=p["touch_tol"], lost_gap=p["lost_gap"])
    lay.update(seed=int(seed), frame=int(frame))
    return lay


def snapshot_extent(lay: dict) -> tuple[float, float]:
    """(width, height) in d of the picture :func:`draw_snapshot` makes (for the figure layout)."""
    y = lay["position"][:, 1]
    dmax = 2.0 * float(np.max(lay["radius"]))
    h = float(np.ptp(y)) + 2.0 * dmax
    return lay["box_length"] + _gravity_margin(h), h


def _gravity_margin(h: float) -> float:
    return 0.42 * h


def draw_snapshot(ax, lay: dict | None, legend: bool = True) -> None:
    """Draw a :func:`snapshot_layers` picture: grains by category, critical contacts, the box
    walls, and gravity as an arrow right of the box (in data units, so its angle is true)."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    if lay is None:
        ax.text(0.5, 0.5, "no snapshot", transform=ax.transAxes, ha="center", va="center")
        ax.set_xticks([])
        ax.set_yticks([])
        return
    L = lay["box_length"]
    colors = np.asarray(CATEGORY_COLORS, dtype=object)[lay["category"]]
    style.draw_pile(ax, lay["position"], lay["radius"], list(colors), box_length=L)
    if len(lay["segments"]):
        ax.add_collection(LineCollection(lay["segments"], colors=style.COLORS["critical_contact"],
                                         linewidths=0.7, capstyle="round", zorder=3))
    y0, y1 = ax.get_ylim()
    h = y1 - y0
    m = _gravity_margin(h)
    ax.set_xlim(0.0, L + m)
    ax.plot([0, 0, L, L], [y1, 0, 0, y1], color=style.COLORS["fixed"], lw=0.6, zorder=0)
    for side in ("top", "right", "bottom", "left"):
        ax.spines[side].set_visible(False)
    t = np.radians(lay["theta_deg"])
    lg = 0.5 * h
    g = np.array([np.sin(t), -np.cos(t)]) * lg
    cx, cy = L + 0.4 * m, y0 + 0.6 * h
    ax.annotate("", xy=(cx + g[0] / 2, cy + g[1] / 2), xytext=(cx - g[0] / 2, cy - g[1] / 2),
                xycoords="data", textcoords="data", annotation_clip=False,
                arrowprops=dict(arrowstyle="-|>", color=style.COLORS["gravity"], lw=1.2,
                                shrinkA=0, shrinkB=0))
    ax.text(cx + 0.12 * m, cy - g[1] / 2, r"$\mathbf{g}$", color=style.COLORS["gravity"],
            ha="left", va="top")
    ax.text(cx, cy + g[1] / 2 - 0.04 * h, rf"$\theta = {lay['theta_deg']:.1f}^\circ$",
            ha="center", va="top", fontsize=6.5)
    if legend:
        def dot(c):
            return Line2D([], [], ls="none", marker="o", ms=4, mfc=c, mec="none")
        cat = np.asarray(lay["category"])
        items = [(np.any(cat == CLUSTER), dot(style.COLORS["cluster"]), "in cluster"),
                 (len(lay["segments"]) > 0,
                  Line2D([], [], color=style.COLORS["critical_contact"], lw=1.2),
                  "critical contact"),
                 (np.any(cat == FAIL_IN_CLUSTER), dot(style.COLORS["fail_in_cluster"]),
                  "failing, in cluster"),
                 (np.any(cat == FAIL_OUTSIDE), dot(style.COLORS["fail_outside"]),
                  "failing, outside")]
        handles = [h for shown, h, _ in items if shown]      # only what the picture holds
        labels = [t for shown, _, t in items if shown]
        ax.legend(handles, labels, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=4,
                  handlelength=1.2, handletextpad=0.3, columnspacing=0.8, borderaxespad=0.1)


def stacked_layout(rows_in, gaps_in, top_in: float, bottom_in: float, left: float = 0.15,
                   right: float = 0.97) -> tuple[float, dict]:
    """Figure height and ``gridspec_kw`` for rows of given heights (inches) separated by given
    gaps (inches), so that an aspect-locked pile picture fills its row without blank bands."""
    rows_in = [float(r) for r in rows_in]
    gap = float(np.mean(gaps_in)) if len(gaps_in) else 0.0
    h = top_in + sum(rows_in) + gap * (len(rows_in) - 1) + bottom_in
    return h, {"height_ratios": rows_in, "hspace": gap / float(np.mean(rows_in)),
               "top": 1.0 - top_in / h, "bottom": bottom_in / h, "left": left, "right": right}


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
            failure_column: str = "n_lost", taus=range(-10, 11), enhancement_taus=range(0, 6),
            fraction_bin_width: float = 0.05, min_failing: int = 5,
            orientation_min_size: int = 5, snapshot: bool = True) -> tuple[dict, dict]:
    """Numbers and plot data of Fig. 3 (module docstring).

    sample_seed: run of the snapshot (None: the first run with an onset); snapshot_offset_deg:
    the snapshot is the quiet frame closest to theta_m - offset; failure_column: N^f of C(tau)
    and of the enhancement ("n_lost" contacts or "n_failing" grains); taus: lags of C(tau);
    enhancement_taus: lags of the failure enhancement after cluster peaks
    (:func:`tiltpile.analysis.failure_enhancement_ensemble`); fraction_bin_width, min_failing:
    binning of the spatial correlation (:func:`failure_in_clusters`); orientation_min_size:
    smallest cluster whose orientation enters the mean; snapshot: read the snapshot from the run
    file (False for tables without run files).

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
      enhancement_max, enhancement_argmax_tau   its maximum over enhancement_taus and where
      n_peaks                     cluster-size peaks entering enhancement_tau0
      orientation_mean_deg, orientation_median_deg, n_clusters_orientation
                                  angle of the long axis of quiet-frame clusters of size >=
                                  orientation_min_size to gravity (0 = along g; isotropic
                                  clusters would give 45 on average; paper ~60)
      orientation_mean_avalanche_deg, n_clusters_orientation_avalanche   same, avalanching frames
    """
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
    c = _st.correlation_function_ensemble(fr, a="largest_cluster", b=failure_column, taus=taus)
    c_alt = _st.correlation_function_ensemble(fr, a="largest_cluster", b=alt, taus=taus)
    tmax, cmax = _argmax_tau(c)
    numbers.update(failure_column=failure_column, C_tau0=_at(c, "C", 0), C_max=cmax,
                   C_argmax_tau=tmax, C_tau0_alt=_at(c_alt, "C", 0))
    enh = _st.failure_enhancement_ensemble(fr, a="largest_cluster", b=failure_column,
                                           taus=enhancement_taus)
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
    return numbers, d


def plot(data: dict, numbers: dict):
    """(a) snapshot; (b) N^f_c / N^f versus N_c / N; (c) C(tau)."""
    lay = data["snapshot"]
    ew, eh = snapshot_extent(lay) if lay is not None else (2.0, 1.0)
    left, right = 0.15, 0.97
    h_top = (right - left) * style.SINGLE_COLUMN_IN * eh / ew
    height, gkw = stacked_layout([h_top, 1.3], [0.22], top_in=0.3, bottom_in=0.4, left=left,
                                 right=right)
    fig, axs = style.figure(2, 2, height=height, gridspec_kw=dict(gkw, wspace=0.45))
    gs = axs[0, 0].get_gridspec()
    for a in axs[0]:
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
    return fig
