"""Fig. 6: stability of the critical clusters versus their size.

Paper, Fig. 6: "Cluster size effects on stability: a - Distribution of delta z for different
cluster sizes, with binning that reflects the fundamental discreteness of the distributions. The
curves have been shifted for clarity. b - In black (squares) is <delta z> for different cluster
sizes and the global stability criterion (dash-dot). The blue dots are the minimal delta z obtained
for each cluster size; the dashed line is the marginal stability criterion for a single grain."

Which delta z
-------------
The text defines delta z = z - 2 n_m / d (the clusters table's ``dz`` column, 2D: z - n_m), but
then says the distributions "progressively shift from negative delta z to a slightly positive one"
and that the minimum goes "from the marginal local criterion [...] to close to the global
stability criterion". z - n_m is never negative (each grain has z_i >= m_i), so the figure must
measure delta z from the generalized isostaticity line of Eq. (1),

    delta z = z - z_iso^gen = z - (d + 1) - 2 n_m / d     (2D: z - 3 - n_m),

i.e. :func:`tiltpile.analysis.contacts.dz_gen` of the cluster's z and n_m (= dz - 3). This is what
this module uses. Then

* global criterion (Eq. 1, the whole cluster counted as one packing): delta z = 0 (dash-dot);
* single-grain criterion, quoted by the paper: "for one particle to be stable, it must satisfy
  the local stability criterion z - 2 n_m / d >= (d + 1) / 2, which states that the d z - 2 n_m
  force components need to be able to constrain the d (d + 1) / 2 degrees of freedom of the
  particle". In the units above: delta z >= (d + 1) / 2 - (d + 1) = -(d + 1) / 2 = -1.5 in 2D
  (dashed). A single critical grain (n_m = 1/2) with z = 2 contacts sits exactly on it.

Which clusters
--------------
The paper: "all studied clusters must be composed of locally stable particles". A grain of a
cluster is locally stable when z_i - m_i / 2 >= 3/2; a cluster of such grains has
z - n_m = mean(z_i - m_i / 2) >= 3/2, i.e. delta z >= -1.5, whatever its size. In our piles about
1% of the grains of the clusters fail the criterion: grains with a single contact (z_i = 1, a
sliding contact) or with two contacts that both slide (z_i = 2, m_i = 2). They are grains in
motion, not rattlers caught at rest: their median speed is two to three orders of magnitude above
that of the other cluster grains (``speed_max`` of their clusters, reported below), and about a
third sit in the surface layer; almost none touch a wall or a fixed grain, so no counting
convention for those contacts is involved. A rigid grain with those contacts cannot be in
equilibrium, so a cluster holding one is not a static cluster; with ``stable_only`` (default)
such clusters (column ``n_unstable`` > 0 of the clusters table) are left out, and how many were
left out is reported. ``docs/figures.md`` gives the numbers of the default ensemble.

Only the clusters of quiet frames are used unless ``quiet_only=False``.
Library: :func:`tiltpile.analysis.stats.dz_distribution` (top),
:func:`tiltpile.analysis.stats.dz_by_size` (bottom, classes and log-spaced size bins).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tiltpile.analysis import dz_by_size, dz_distribution, dz_gen
from tiltpile.analysis import stats as _st

from . import style
from .data import Reads

# the table columns the figure reads (from records, only these are checked); n_unstable and
# speed_max are optional to compute() (an older table without them leaves nothing out), never
# to the figure
READS = Reads("Fig. 6",
              frames=("z", "n_m", "avalanching"),
              clusters=("avalanching", "size", "z", "n_m", "n_unstable", "speed_max"))

NAME = "fig6_cluster_stability"

D = 2
DZ_GLOBAL = 0.0                          # Eq. (1): z = z_iso^gen
DZ_SINGLE_GRAIN = (D + 1) / 2 - (D + 1)  # z - 2 n_m / d >= (d + 1) / 2, i.e. -1.5 in 2D
TOL = 1e-9


def class_label(lo: int, hi: int | None) -> str:
    """"1", "3-4", "10+" for the sizes [lo, hi) (hi None: no upper end)."""
    if hi is None:
        return f"{lo}+"
    return f"{lo}" if hi == lo + 1 else f"{lo}-{hi - 1}"


def _slope(x, y) -> float:
    """Least-squares slope of y versus x (NaN with fewer than 2 distinct x)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    if np.unique(x[ok]).size < 2:
        return float("nan")
    return float(np.polyfit(x[ok], y[ok], 1)[0])


def compute(ens, size_classes=(1, 2, 4, 8, 16), bins_per_decade: int = 5,
            quiet_only: bool = True, stable_only: bool = True, min_samples: int = 10):
    """delta z (from the generalized isostaticity line) of clusters by size.

    ens: :class:`tiltpile.figures.data.Ensemble`. size_classes: increasing lower bounds of the
    size classes of the top panel, the last one open-ended ((1, 2, 4, 8, 16): 1, 2-3, 4-7, 8-15,
    16+: after size 1, each class holds as many odd as even sizes); bins_per_decade: size bins of
    the bottom panel (:func:`tiltpile.analysis.stats.parity_log_edges`); quiet_only: clusters of
    quiet frames only; stable_only: leave out the clusters holding a locally unstable grain
    (module docstring; needs the clusters column ``n_unstable``, else nothing is left out);
    min_samples: fewest clusters for a size bin to enter the trend numbers.

    numbers:
      classes: per class label: n, dz_mean, dz_min, dz_std (NaN when empty);
      dz_global, dz_single_grain: the two criteria (0 and -1.5);
      n_clusters: clusters used; stable_only;
      n_clusters_before_stability, n_clusters_unstable, frac_clusters_unstable: the clusters
        (quiet if quiet_only) before the selection, those holding an unstable grain, their share
        (NaN without the n_unstable column);
      frac_below_single_grain_before_stability: their share below the single-grain bound;
      speed_max_median_unstable, speed_max_median_stable: median over clusters of the fastest
        grain's speed (sqrt(g d)), clusters with / without an unstable grain;
      frac_below_single_grain: fraction of the clusters used with delta z below the bound;
      dz_min_all: the smallest delta z of the clusters used;
      frac_single_on_bound: fraction of size-1 clusters exactly on it;
      slope_per_decade: least-squares slope of <delta z> versus log10(size) over the size bins
        with >= min_samples clusters (> 0: larger clusters are closer to / above the global line);
      s_cross: lower edge of the first such bin with <delta z> >= 0 (the size from which clusters
        are on average globally stable; NaN if none);
      largest_bin: the last such bin's size_lo, n, dz_mean, dz_min.
    """
    cl = ens.clusters
    if quiet_only:
        cl = cl[~cl["avalanching"].to_numpy(bool)]
    cl = cl.assign(dz=dz_gen(cl["z"].to_numpy(float), cl["n_m"].to_numpy(float), D))
    has_u = "n_unstable" in cl
    unstable = cl["n_unstable"].to_numpy() > 0 if has_u else np.zeros(len(cl), bool)
    before = {
        "n_clusters_before_stability": int(len(cl)),
        "n_clusters_unstable": int(unstable.sum()) if has_u else None,
        "frac_clusters_unstable": float(unstable.mean()) if has_u and len(cl) else np.nan,
        "frac_below_single_grain_before_stability": (
            float(np.mean(cl["dz"] < DZ_SINGLE_GRAIN - TOL)) if len(cl) else np.nan),
        "speed_max_median_unstable": (float(cl.loc[unstable, "speed_max"].median())
                                      if has_u and unstable.any() and "speed_max" in cl
                                      else np.nan),
        "speed_max_median_stable": (float(cl.loc[~unstable, "speed_max"].median())
                                    if has_u and (~unstable).any() and "speed_max" in cl
                                    else np.nan),
    }
    if stable_only:
        cl = cl[~unstable]
    s_max = int(cl["size"].max()) if len(cl) else 1
    lows = [int(v) for v in size_classes]
    if any(b <= a for a, b in zip(lows[:-1], lows[1:])):
        raise ValueError(f"size_classes must increase, got {size_classes}")
    highs = lows[1:] + [max(s_max, lows[-1]) + 1]
    labels = [class_label(a, b) for a, b in zip(lows, lows[1:] + [None])]
    by_class = dz_by_size(cl, np.array(lows + [highs[-1]]))
    by_class = (pd.DataFrame({"size_lo": lows, "size_hi": highs, "label": labels})
                .merge(by_class.drop(columns="size_hi"), on="size_lo", how="left"))
    by_class["n"] = by_class["n"].fillna(0).astype(int)
    dists = [dz_distribution(cl, a, b) for a, b in zip(lows, highs)]

    bins = dz_by_size(cl, _st.parity_log_edges(s_max, bins_per_decade)) if len(cl) else \
        pd.DataFrame(columns=["size_lo", "size_hi", "n", "dz_mean", "dz_min", "dz_std"])
    bins = bins.astype({"size_lo": float, "size_hi": float})
    bins["center"] = np.sqrt(bins["size_lo"] * (bins["size_hi"] - 1.0))
    good = bins[bins["n"] >= min_samples]
    cross = good[good["dz_mean"] >= DZ_GLOBAL - TOL]
    last = good.iloc[-1] if len(good) else None
    one = cl[cl["size"] == 1]["dz"]
    numbers = {
        "classes": {r.label: {"n": int(r.n), "dz_mean": r.dz_mean, "dz_min": r.dz_min,
                              "dz_std": r.dz_std} for r in by_class.itertuples()},
        "dz_global": DZ_GLOBAL, "dz_single_grain": DZ_SINGLE_GRAIN,
        "n_clusters": int(len(cl)), "quiet_only": bool(quiet_only),
        "stable_only": bool(stable_only), **before,
        "frac_below_single_grain": (float(np.mean(cl["dz"] < DZ_SINGLE_GRAIN - TOL))
                                    if len(cl) else np.nan),
        "dz_min_all": float(cl["dz"].min()) if len(cl) else np.nan,
        "frac_single_on_bound": (float(np.mean(np.abs(one - DZ_SINGLE_GRAIN) <= TOL))
                                 if len(one) else np.nan),
        "slope_per_decade": _slope(np.log10(good["center"].to_numpy(float)), good["dz_mean"]),
        "s_cross": float(cross["size_lo"].iloc[0]) if len(cross) else np.nan,
        "largest_bin": ({"size_lo": int(last["size_lo"]), "n": int(last["n"]),
                         "dz_mean": float(last["dz_mean"]), "dz_min": float(last["dz_min"])}
                        if last is not None else None),
    }
    data = {"classes": by_class, "distributions": dists, "bins": bins,
            "min_samples": int(min_samples)}
    return numbers, data


def plot(data: dict, numbers: dict):
    """Top: delta z distributions per size class (shifted, labelled at their right end); bottom:
    <delta z>, min delta z versus size with the two criteria (legend below the axes)."""
    fig, (ax, bx) = style.figure(2, 1, height=5.0, gridspec_kw={"height_ratios": [1.2, 1]})
    classes = data["classes"]
    dists = data["distributions"]
    peak = max([float(d["density"].max()) for d in dists if len(d)] + [1.0])
    shift = 0.6 * peak
    x_hi = max([float(d["center"].max()) for d in dists if len(d)] + [0.5])
    for i, (row, d) in enumerate(zip(classes.itertuples(), dists)):
        color = style.CYCLE[i % len(style.CYCLE)]
        marker = style.MARKERS[i % len(style.MARKERS)]
        off = i * shift
        ax.axhline(off, color=color, lw=0.4, alpha=0.5)
        text = f"$s$ = {row.label} ({row.n})" if len(d) else f"$s$ = {row.label}: none"
        if len(d):
            mfc = color if marker not in ("+", "x") else None
            ax.plot(d["center"], d["density"] + off, color=color, lw=0.7, marker=marker,
                    ms=2.5, mfc=mfc)
        ax.text(x_hi + 0.15, off + 0.08 * shift, text, color=color, fontsize=5.5, ha="left",
                va="bottom")
    ax.axvline(DZ_GLOBAL, color=style.COLORS["quiet"], ls="-.", lw=0.9)
    ax.axvline(DZ_SINGLE_GRAIN, color=style.CYCLE[1], ls="--", lw=0.9)
    x0 = ax.get_xlim()[0]
    ax.set_xlim(min(x0, DZ_SINGLE_GRAIN - 0.3), x_hi + 1.6)
    ax.set_xlabel(r"$\delta z = z - 3 - n_m$")
    ax.set_ylabel(r"$P(\delta z)$ (shifted)")
    ax.set_yticks([])
    style.panel_label(ax, "a", x=0.03)

    b = data["bins"]
    if len(b):
        _plot_means(bx, b)
        bx.plot(b["center"], b["dz_min"], "o", ms=3, color=style.CYCLE[1],
                label=r"min $\delta z$", zorder=2)
        bx.set_xscale("log")
    bx.axhline(DZ_GLOBAL, color=style.COLORS["quiet"], ls="-.", lw=0.9,
               label="global (generalized isostaticity)")
    bx.axhline(DZ_SINGLE_GRAIN, color=style.CYCLE[1], ls="--", lw=0.9, label="single grain")
    lo = min([DZ_SINGLE_GRAIN] + ([float(b["dz_min"].min())] if len(b) else []))
    bx.set_ylim(lo - 0.25, 0.35)
    bx.set_xlabel(r"cluster size $s$")
    bx.set_ylabel(r"$\delta z$")
    bx.legend(loc="upper center", bbox_to_anchor=(0.5, -0.28), ncol=2, fontsize=6,
              frameon=False)
    style.panel_label(bx, "b", x=0.03)
    if numbers.get("stable_only") and numbers.get("n_clusters_unstable") is not None:
        bx.text(0.98, 0.04, f"left out: {numbers['n_clusters_unstable']} clusters with a "
                "locally unstable grain", transform=bx.transAxes, ha="right", va="bottom",
                fontsize=5.0, color=style.COLORS["guide"])
    fig.tight_layout(h_pad=0.6)
    return fig


# the drawing order of panel b: the markers of <delta z> under its error bars, so that a bar
# shorter than the marker still shows across it (open markers)
MEAN_MARKER_ZORDER = 3
ERRORBAR_ZORDER = 4


def _plot_means(bx, b) -> None:
    """Panel b: <delta z> per size bin as open squares, with two bars drawn above them: the
    spread of delta z over the bin's clusters (+-1 standard deviation, thin grey) and the
    standard error of the mean (black, capped), which the bins' hundreds to millions of clusters
    make smaller than the marker for most of them (the note says how small)."""
    n = b["n"].to_numpy(float)
    sd = b["dz_std"].to_numpy(float)
    sem = sd / np.sqrt(n)
    x, y = b["center"].to_numpy(float), b["dz_mean"].to_numpy(float)
    spread = bx.errorbar(x, y, yerr=sd, fmt="none", lw=0.6, capsize=0,
                         ecolor=style.COLORS["guide"], label=r"$\pm 1$ s.d. of $\delta z$",
                         zorder=ERRORBAR_ZORDER)
    err = bx.errorbar(x, y, yerr=sem, fmt="none", lw=0.9, capsize=1.8, capthick=0.7,
                      ecolor=style.COLORS["quiet"], label=r"$\pm$ s.e. of the mean",
                      zorder=ERRORBAR_ZORDER + 0.1)
    bx.plot(x, y, ls="none", marker="s", ms=3.2, mfc="white", mec=style.COLORS["quiet"],
            mew=0.8, color=style.COLORS["quiet"], label=r"$\langle \delta z \rangle$",
            zorder=MEAN_MARKER_ZORDER)
    for container in (spread, err):          # errorbar() puts its lines at the given zorder;
        for artist in container.lines[1] + container.lines[2]:   # caps and bars alike
            artist.set_zorder(container.lines[2][0].get_zorder())
    ok = np.isfinite(sem)
    if ok.any():
        bx.text(0.98, 0.12, rf"s.e. of the mean $\leq$ {np.nanmax(sem[ok]):.2g}",
                transform=bx.transAxes, ha="right", va="bottom", fontsize=5.0,
                color=style.COLORS["guide"])
