"""Fig. 5: cluster-size distributions approaching the avalanche, their cutoff xi and <S_max>.

Paper, Fig. 5: "Cluster size distribution rho(s) at different distances from the avalanche onset,
ensemble averaged over an angular interval of Delta theta = 0.5 deg. [...] (theta - theta_m)-values:
-14.4 deg, -4.6 deg, -0.75 deg, -0.25 deg; and during the avalanche. Lines are fits to Eq. 3, and
the dashed line indicates a slope of -2.5. Insets: (a) xi, (b) maximum cluster size S_max as a
function of theta - theta_m." Text: "We have estimated delta = 2.5 +- 0.25 from the distribution
just above onset (see dashed line) and the inset (a) displays the cluster scale xi".

How it is computed here (all fits by :func:`tiltpile.analysis.stats.fit_power_law_cutoff`, the
maximum-likelihood fit of the discrete law P(s) = s^-delta exp(-s/xi) / Z, s >= s_min):

1. delta: one fit, delta and xi free, of the sizes of all clusters of quiet frames with
   theta - theta_m in [delta_pool[0], delta_pool[1]) ("just above onset").
2. Each window of the main panel (quiet frames with |theta - theta_m - center| < width / 2,
   :func:`tiltpile.analysis.stats.cluster_size_windows`) and the avalanching frames are fitted
   twice: with delta free (the window's own exponent, reported as a check), and with delta held at
   the pooled estimate of step 1 (xi alone: the lines of the main panel and the inset xi; if the
   pooled fit is refused, delta_guide is used instead).
3. Inset: xi (delta held fixed as in 2) and <S_max> in windows of ``width`` tiling
   [inset_lo, 0).

Densities: :func:`tiltpile.analysis.stats.discrete_log_binned_density` (mean P(s) over the
integers of each log bin), normalised like the fits over s >= s_min.
A window with too few clusters is refused by the fit (InsufficientDataError): its numbers are NaN
and its reason is kept in ``data``; the figure still draws what exists.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from tiltpile.analysis import (InsufficientDataError, cluster_size_windows,
                               discrete_log_binned_density, fit_power_law_cutoff)
from tiltpile.analysis.stats import bootstrap_runs_ci
from tiltpile.paper_values import DELTA, FIG5_WINDOWS_DEG

from . import style
from .data import Reads

# the table columns the figure reads (from records, only these are checked)
READS = Reads("Fig. 5",
              frames=("largest_cluster", "avalanching", "theta_to_onset"),
              clusters=("avalanching", "theta_to_onset", "size"))

NAME = "fig5_cluster_sizes"

XI_UNCONSTRAINED = 1e6   # a fitted xi above this (the fit's bound is 1e7) is "no visible cutoff"


def _round_theta(df: pd.DataFrame, decimals: int = 6) -> pd.DataFrame:
    """``theta_to_onset`` rounded to ``decimals``.

    theta - theta_m is a difference of tilt angles on a grid (0.1 deg for the presets), so window
    edges such as -0.5 coincide with frames; rounding removes the 1e-15 jitter that would put such
    a frame on either side of an edge depending on floating-point luck.
    """
    return df.assign(theta_to_onset=df["theta_to_onset"].round(decimals))


def _fit(sizes, s_min: int, delta: float | None, min_samples: int) -> dict:
    """Fit or refusal of one set of sizes, as plain numbers (NaN when refused)."""
    sizes = np.asarray(sizes)
    out = {"n_clusters": int(sizes.size), "n_fit": int((sizes >= s_min).sum()), "delta": np.nan, "delta_err": np.nan,
           "xi": np.nan, "xi_err": np.nan, "fit_error": "", "fit": None}
    try:
        f = fit_power_law_cutoff(np.asarray(sizes), s_min=s_min, delta=delta,
                                 min_samples=min_samples)
    except InsufficientDataError as exc:
        out["fit_error"] = str(exc)
        return out
    out.update(delta=f.delta, delta_err=f.delta_err, xi=f.xi, xi_err=f.xi_err, fit=f)
    return out


def xi_trend(center, xi) -> dict:
    """Does xi grow towards the onset? Over the windows with a finite, constrained xi:

    spearman: Spearman rank correlation of xi with theta - theta_m (> 0: xi grows towards the
    onset), computed as the Pearson correlation of the average ranks; slope: least-squares slope
    of log10 xi versus theta - theta_m (per degree); n: windows used. NaN for fewer than 3 windows.
    """
    c = np.asarray(center, float)
    x = np.asarray(xi, float)
    ok = np.isfinite(c) & np.isfinite(x) & (x > 0) & (x < XI_UNCONSTRAINED)
    c, x = c[ok], x[ok]
    if c.size < 3:
        return {"spearman": np.nan, "slope_log10_xi_per_deg": np.nan, "n": int(c.size)}
    rc = pd.Series(c).rank().to_numpy()
    rx = pd.Series(x).rank().to_numpy()
    rho = np.corrcoef(rc, rx)[0, 1] if rc.std() > 0 and rx.std() > 0 else np.nan
    slope = np.polyfit(c, np.log10(x), 1)[0]
    return {"spearman": float(rho), "slope_log10_xi_per_deg": float(slope), "n": int(c.size)}


def compute(ens, windows=FIG5_WINDOWS_DEG, width: float = 0.5, s_min: int = 2,
            delta_pool=(-1.0, 0.0), delta_guide: float = DELTA.value, inset_lo: float = -15.0,
            far_below: float = -4.0, min_samples: int = 50, bins_per_decade: int = 5,
            delta_bootstrap: int = 199):
    """P(s) per window of theta - theta_m and during avalanches, fits, xi and <S_max> insets.

    ens: :class:`tiltpile.figures.data.Ensemble`. windows: centres (deg) of the theta - theta_m
    windows of the main panel, each ``width`` wide; s_min: smallest size fitted and drawn;
    delta_pool: [lo, hi) of theta - theta_m whose quiet clusters give the pooled delta;
    delta_guide: slope of the guide line, and delta of the xi fits if the pooled fit is refused;
    inset_lo: left end of the inset windows; far_below: <S_max> "far from onset" averages the
    quiet frames with theta - theta_m < far_below; min_samples: fewest clusters for a fit;
    bins_per_decade: log bins of the densities; delta_bootstrap: resamples of the runs for the
    interval of the pooled delta (:func:`tiltpile.analysis.stats.bootstrap_runs_ci`; 0: none).

    numbers:
      delta_pooled, delta_pooled_err, n_pooled: the exponent (step 1 of the module docstring) and
        the number of clusters (of size >= s_min) it was fitted to;
      delta_pooled_ci_low, _ci_high, delta_pooled_n_runs: 95% percentile bootstrap interval of
        delta over runs (whole runs resampled; the Fisher error assumes independent clusters,
        but clusters of one run and neighbouring frames are correlated);
      xi_delta: the delta held fixed in the xi fits;
      windows: one dict per main-panel window then ``avalanche``: center (None for the
        avalanche), n_frames, n_clusters (all sizes), delta, delta_err (free fit), xi, xi_err
        (delta fixed),
        mean_largest (<S_max>); NaN where the fit was refused; xi >= XI_UNCONSTRAINED (1e6)
        means the sizes show no cutoff (xi at the fit's bound);
      xi_spearman, xi_slope_log10_per_deg, xi_n_windows: trend of the inset xi with
        theta - theta_m (:func:`xi_trend`; positive: xi grows towards the onset);
      s_max_far, s_max_near: <S_max> over quiet frames with theta - theta_m < far_below, and in the
        last window before the onset [-width, 0).
    """
    fr = _round_theta(ens.frames)
    cl = ens.clusters[["run", "frame", "size", "avalanching", "theta_to_onset"]]
    cl = _round_theta(cl)
    with warnings.catch_warnings():
        # a window whose sizes show no cutoff drives xi to the fit's upper bound; the library warns
        # (RuntimeWarning "xi = ... is at its bound"). Here that is an expected outcome of a small
        # window, recorded as xi >= XI_UNCONSTRAINED (not drawn in the inset), not a notebook warning.
        warnings.filterwarnings("ignore", message="fit_power_law_cutoff: xi = ",
                                category=RuntimeWarning)
        pooled, boot, n_runs = _pooled_delta(cl, delta_pool, s_min, min_samples, delta_bootstrap)
        xi_delta = pooled["delta"] if np.isfinite(pooled["delta"]) else float(delta_guide)
        rows, curves = _window_fits(cl, fr, windows, width, s_min, min_samples, xi_delta)
        row, curve = _avalanche_fit(cl, fr, s_min, min_samples, xi_delta)
        rows.append(row)
        curves.append(curve)
        inset = cluster_size_windows(cl, fr, width=width, lo=inset_lo, hi=0.0, s_min=s_min,
                                     delta=xi_delta, min_samples=min_samples)

    dens = [discrete_log_binned_density(cv["sizes"][cv["sizes"] >= s_min], bins_per_decade,
                                        s_min=s_min) for cv in curves]
    trend = xi_trend(inset["center"], inset["xi"])
    far, near = _s_max_far_near(fr, far_below, width)
    keys = ("center", "n_frames", "n_clusters", "delta", "delta_err", "xi", "xi_err",
            "mean_largest")
    numbers = {
        "delta_pooled": pooled["delta"], "delta_pooled_err": pooled["delta_err"],
        "n_pooled": pooled["n_fit"], "delta_pool_range": list(delta_pool),
        "delta_pooled_ci_low": boot["low"] if boot else np.nan,
        "delta_pooled_ci_high": boot["high"] if boot else np.nan,
        "delta_pooled_n_runs": n_runs,
        "xi_delta": float(xi_delta), "s_min": int(s_min), "width": float(width),
        "windows": {r["label"]: {k: r[k] for k in keys} for r in rows},
        "xi_spearman": trend["spearman"], "xi_slope_log10_per_deg": trend["slope_log10_xi_per_deg"],
        "xi_n_windows": trend["n"],
        "s_max_far": far, "s_max_near": near,
    }
    data = {"rows": pd.DataFrame(rows), "densities": dens,
            "fits": [cv["fit"] for cv in curves], "inset": inset, "s_min": int(s_min),
            "delta_guide": float(delta_guide), "xi_delta": float(xi_delta),
            "far_below": float(far_below)}
    return numbers, data


def _pooled_delta(cl: pd.DataFrame, delta_pool, s_min: int, min_samples: int,
                  delta_bootstrap: int) -> tuple[dict, dict | None, int]:
    """Step 1 of the module docstring: one fit (delta and xi free) of the quiet clusters with
    theta - theta_m in [delta_pool[0], delta_pool[1]), and its interval over runs (whole runs
    resampled, their clusters pooled and refitted; None with fewer than 2 runs or no resamples).
    Returns (the fit of :func:`_fit`, the interval, the number of runs with such clusters)."""
    quiet = ~cl["avalanching"].to_numpy(bool)
    t = cl["theta_to_onset"].to_numpy(float)
    sel = quiet & (t >= delta_pool[0]) & (t < delta_pool[1])
    pooled = _fit(cl.loc[sel, "size"].to_numpy(), s_min, None, min_samples)
    by_run = [g["size"].to_numpy() for _, g in cl[sel].groupby("run")]

    def _delta_of(groups):
        sizes = np.concatenate(groups) if groups else np.zeros(0, int)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return _fit(sizes, s_min, None, min_samples)["delta"]
    boot = (bootstrap_runs_ci(by_run, _delta_of, n_resamples=delta_bootstrap, seed=0)
            if delta_bootstrap and len(by_run) >= 2 else None)
    return pooled, boot, len(by_run)


def _window_fits(cl: pd.DataFrame, fr: pd.DataFrame, windows, width: float, s_min: int,
                 min_samples: int, xi_delta: float) -> tuple[list, list]:
    """Step 2 of the module docstring for the main panel's windows of theta - theta_m (centres
    ``windows``, each ``width`` wide): the free fit and <S_max>
    (:func:`tiltpile.analysis.stats.cluster_size_windows`) and xi with delta held at ``xi_delta``.
    Returns (one row per window, one curve per window: its sizes and the fixed-delta fit)."""
    quiet = ~cl["avalanching"].to_numpy(bool)
    t = cl["theta_to_onset"].to_numpy(float)
    rows, curves = [], []
    for c in windows:
        lo, hi = round(c - width / 2, 6), round(c + width / 2, 6)
        free = cluster_size_windows(cl, fr, width=width, lo=lo, hi=hi, s_min=s_min,
                                    min_samples=min_samples)
        sel = cl[quiet & (t >= lo) & (t < hi)]["size"].to_numpy()
        fix = _fit(sel, s_min, xi_delta, min_samples)
        f0 = free.iloc[0]
        rows.append({"label": f"{c:g}", "center": float(c), "n_frames": int(f0["n_frames"]),
                     "n_clusters": int(f0["n_clusters"]), "delta": f0["delta"],
                     "delta_err": f0["delta_err"], "xi": fix["xi"], "xi_err": fix["xi_err"],
                     "mean_largest": f0["mean_largest"],
                     "fit_error": fix["fit_error"] or f0["fit_error"]})
        curves.append({"sizes": sel, "fit": fix["fit"]})
    return rows, curves


def _avalanche_fit(cl: pd.DataFrame, fr: pd.DataFrame, s_min: int, min_samples: int,
                   xi_delta: float) -> tuple[dict, dict]:
    """Step 2 of the module docstring for the clusters of the avalanching frames: the row
    ``avalanche`` (free delta, xi at ``xi_delta``, <S_max> of the avalanching frames) and its
    curve."""
    av = cl["avalanching"].to_numpy(bool)
    sel = cl.loc[av, "size"].to_numpy()
    afree = _fit(sel, s_min, None, min_samples)
    afix = _fit(sel, s_min, xi_delta, min_samples)
    fav = fr["avalanching"].to_numpy(bool)
    row = {"label": "avalanche", "center": None, "n_frames": int(fav.sum()),
           "n_clusters": int(sel.size), "delta": afree["delta"],
           "delta_err": afree["delta_err"], "xi": afix["xi"], "xi_err": afix["xi_err"],
           "mean_largest": float(fr.loc[fav, "largest_cluster"].mean()) if fav.any()
           else np.nan,
           "fit_error": afix["fit_error"] or afree["fit_error"]}
    return row, {"sizes": sel, "fit": afix["fit"]}


def _s_max_far_near(fr: pd.DataFrame, far_below: float, width: float) -> tuple[float, float]:
    """<S_max> over the quiet frames with theta - theta_m < far_below, and over those of the last
    window before the onset [-width, 0) (NaN where there are none)."""
    fq = fr[~fr["avalanching"].to_numpy(bool)]
    ft = fq["theta_to_onset"].to_numpy(float)
    far = fq.loc[ft < far_below, "largest_cluster"]
    near = fq.loc[(ft >= -width) & (ft < 0.0), "largest_cluster"]
    return (float(far.mean()) if len(far) else np.nan,
            float(near.mean()) if len(near) else np.nan)


def delta_label(numbers: dict) -> str:
    """The pooled delta as the legend gives it, as the report gives it: ' (fit: delta = x
    [lo, hi])' with the 95% interval over runs (delta_pooled_ci_low, _ci_high); without an
    interval (fewer than 2 runs, no resamples) the fit's own error, ' (fit: delta = x +- e)';
    '' without a fit."""
    d = _num(numbers.get("delta_pooled"))
    if not np.isfinite(d):
        return ""
    lo, hi = _num(numbers.get("delta_pooled_ci_low")), _num(numbers.get("delta_pooled_ci_high"))
    if np.isfinite(lo) and np.isfinite(hi):
        return rf" (fit: $\delta = {d:.2f}$ [{lo:.2f}, {hi:.2f}])"
    e = _num(numbers.get("delta_pooled_err"))
    if not np.isfinite(e):
        return rf" (fit: $\delta = {d:.2f}$)"
    return rf" (fit: $\delta = {d:.2f} \pm {e:.2f}$)"


def _num(x) -> float:
    """A number of the JSON as a float (None, from NaN, as NaN)."""
    return float("nan") if x is None else float(x)


def plot(data: dict, numbers: dict):
    """Main panel: P(s) per window with fits and the -delta_guide slope; insets xi, <S_max>."""
    fig, ax = style.figure(1, 1, height=3.1)
    rows = data["rows"]
    smax_plot = 1
    ymin = np.inf
    empty = []
    for i, (row, dens, fit) in enumerate(zip(rows.itertuples(), data["densities"], data["fits"])):
        color = style.CYCLE[i % len(style.CYCLE)]
        marker = style.MARKERS[i % len(style.MARKERS)]
        name = (r"$\theta-\theta_m = %s^\circ$" % row.label if row.label != "avalanche"
                else "avalanche")
        if len(dens) == 0:
            empty.append(name)
            continue
        d = dens[dens["count"] > 0]
        mfc = color if marker not in ("+", "x") else None
        ax.plot(d["center"], d["density"], marker=marker, ls="none", color=color, mfc=mfc,
                label=name + ("" if fit is not None else " (no fit)"))
        ymin = min(ymin, d["density"].min())
        smax_plot = max(smax_plot, int(d["right"].max()))
        if fit is not None:
            s = np.unique(np.geomspace(data["s_min"], d["right"].max(), 200).astype(int))
            ax.plot(s, fit.pmf(s), color=color, lw=0.8)
    # slope guide on the data: through the window closest to the onset (the paper estimates delta
    # "from the distribution just above onset"), fitted in log-log with the slope held at -delta
    # over its bins s_min <= s < 10 s_min, where the cut-off has not set in
    dg = data["delta_guide"]
    ref = None
    for row, dens in list(zip(rows.itertuples(), data["densities"]))[::-1]:
        if len(dens) and row.label != "avalanche":
            ref = dens[dens["count"] > 0]
            break
    if ref is None:
        ref = next((d[d["count"] > 0] for d in data["densities"] if len(d)), None)
    if ref is not None and len(ref):
        head = ref[ref["center"] < 10.0 * data["s_min"]]
        head = head if len(head) else ref
        c = np.mean(np.log10(head["density"]) + dg * np.log10(head["center"]))
        s = np.array([float(data["s_min"]), 20.0 * data["s_min"]])
        ax.plot(s, 10 ** (c - dg * np.log10(s)), ls="--", lw=1.0, color=style.COLORS["guide"],
                zorder=0, label=rf"slope $-{dg:g}$" + delta_label(numbers))
    if empty:
        ax.text(0.02, 0.015, "no clusters: " + ", ".join(empty) + " (no quiet frame that far "
                "before an onset)", transform=ax.transAxes, ha="left", va="bottom", fontsize=5.0,
                color=style.COLORS["guide"])
    ax.set_xscale("log")
    ax.set_yscale("log")
    if np.isfinite(ymin):
        ax.set_ylim(ymin / 3.0, None)
    ax.set_xlim(data["s_min"] * 0.8, smax_plot * 1.3)
    ax.set_xlabel(r"cluster size $s$")
    ax.set_ylabel(r"$P(s)$")
    ax.legend(loc="lower left", fontsize=6, bbox_to_anchor=(0.0, 0.05 if empty else 0.0))
    inset = data["inset"]
    ok = np.isfinite(inset["xi"]) & (inset["xi"] < XI_UNCONSTRAINED)
    ia = ax.inset_axes([0.50, 0.63, 0.22, 0.33])
    ia.errorbar(inset.loc[ok, "center"], inset.loc[ok, "xi"], yerr=inset.loc[ok, "xi_err"],
                fmt="o", ms=2, lw=0.6, color=style.COLORS["quiet"])
    if ok.any():
        ia.set_yscale("log")
        # a range of about one decade would label the minor ticks too, over one another
        from matplotlib.ticker import NullFormatter
        ia.yaxis.set_minor_formatter(NullFormatter())
    ia.set_ylabel(r"$\xi$", labelpad=1)
    ib = ax.inset_axes([0.80, 0.63, 0.19, 0.33])
    okb = np.isfinite(inset["mean_largest"])
    ib.plot(inset.loc[okb, "center"], inset.loc[okb, "mean_largest"], "s", ms=2,
            color=style.COLORS["quiet"])
    ib.set_ylabel(r"$\langle S_{max}\rangle$", labelpad=1)
    for a, letter in ((ia, "a"), (ib, "b")):
        a.tick_params(labelsize=5, length=2, pad=1)
        a.set_xlabel(r"$\theta-\theta_m$ (deg)", fontsize=5.5, labelpad=1)
        a.yaxis.label.set_size(6)
        a.text(0.93, 0.06, letter, transform=a.transAxes, ha="right", va="bottom", fontsize=6,
               fontstyle="italic")
    xs = inset.loc[okb, "center"]
    if len(xs):
        for a in (ia, ib):
            a.set_xlim(xs.min() - 0.5, 0.2)
    return fig
