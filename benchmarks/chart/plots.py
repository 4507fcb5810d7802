"""Part 2 of the chart: the plots. ``pareto.png`` (time per degree against each error measure of
the accuracy sweep, with the Pareto front) and ``scaling.png``; both can be redrawn from the CSV
files alone (``python -m benchmarks.chart --replot DIR``)."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.chart.spec import ACCURACY_COLUMNS, DEFAULT_DT, DEFAULT_SLOP, DEFAULT_TOL


def atomic_png(fig, path: Path) -> None:
    """Save ``fig`` as PNG to a temporary name beside ``path``, then rename it."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    fig.savefig(tmp, format="png", dpi=130)
    tmp.replace(path)


def pareto_front(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Indices of the points no other point beats in both x and y (lower is better), by x."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
    order = ok[np.lexsort((y[ok], x[ok]))]
    front, best = [], np.inf
    for i in order:
        if y[i] < best:
            front.append(i)
            best = y[i]
    return np.array(front, dtype=int)


def aggregate_points(acc: pd.DataFrame) -> pd.DataFrame:
    """Per (tol, dt, slop): median time per degree, mean error measures over seeds."""
    g = acc.assign(abs_theta_shift=acc["theta_m_shift"].abs(), abs_z_shift=acc["z_shift"].abs(),
                   abs_n_m_shift=acc["n_m_shift"].abs())
    return g.groupby(["tol", "dt", "slop"], as_index=False).agg(
        ms_per_deg=("ms_per_deg", "median"), sweeps_mean=("sweeps_mean", "mean"),
        creep_mean=("creep_mean", "mean"), creep_median=("creep_median", "mean"),
        drift_per_deg=("drift_per_deg", "mean"),
        residual_median=("residual_median", "median"),
        abs_theta_shift=("abs_theta_shift", "mean"), abs_z_shift=("abs_z_shift", "mean"),
        abs_n_m_shift=("abs_n_m_shift", "mean"), max_overlap=("max_overlap", "max"),
        is_default=("is_default", "any"), is_reference=("is_reference", "any"))


def point_label(r) -> str:
    """tol/dt, plus /s<slop> where the overlap slop is not the default."""
    lab = f"{r['tol']:g}/{r['dt']:g}"
    return lab if r["slop"] == DEFAULT_SLOP else f"{lab}/s{r['slop']:g}"


def read_accuracy(path: Path) -> pd.DataFrame | None:
    """The accuracy table an earlier chart left in ``path``, or None with a warning when it lacks
    one of ``ACCURACY_COLUMNS`` (written by an older tiltpile, before that column was measured)."""
    acc = pd.read_csv(path)
    missing = [c for c in ACCURACY_COLUMNS if c not in acc]
    if missing:
        warnings.warn(f"{path} lacks the column(s) {', '.join(missing)} (written by an older "
                      "tiltpile): not summarised; rerun the chart with --parts accuracy",
                      stacklevel=2)
        return None
    return acc


def place_labels(ax, x, y, labels, fontsize: float = 7) -> list:
    """Annotate the points (x[i], y[i]) of ``ax`` with ``labels[i]`` where the text overlaps
    neither another label nor a point: the first free spot of 8 positions around the point at
    growing distances (a leader line beyond the first ring); the nearest spot if none is free.
    Returns the annotations."""
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    pts = ax.transData.transform(np.column_stack([x, y]))
    dpi = fig.dpi / 72.0
    marker = [(px - 6 * dpi, py - 6 * dpi, px + 6 * dpi, py + 6 * dpi) for px, py in pts]  # s=60 markers
    frame = ax.get_window_extent(renderer)
    placed, out = [], []
    dirs = [(1, 1), (1, -1), (-1, 1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1)]

    from matplotlib.text import Text

    def clash(bb, own):
        box = (bb.x0, bb.y0, bb.x1, bb.y1)
        inside = frame.x0 <= box[0] and box[2] <= frame.x1 and frame.y0 <= box[1] and box[3] <= frame.y1
        others = placed + [m for k, m in enumerate(marker) if k != own]
        hit = any(box[0] < o[2] and o[0] < box[2] and box[1] < o[3] and o[1] < box[3] for o in others)
        return hit or not inside

    for i in np.argsort(pts[:, 0]):
        if not np.all(np.isfinite(pts[i])):
            continue
        best = None
        for dist in (5, 14, 26, 40):
            for dx, dy in dirs:
                off = (dx * dist, dy * dist * 0.8)
                ann = ax.annotate(labels[i], (x[i], y[i]), xytext=off, textcoords="offset points",
                                  fontsize=fontsize, ha="left" if dx > 0 else "right" if dx < 0 else "center",
                                  va="bottom" if dy > 0 else "top" if dy < 0 else "center",
                                  arrowprops=(dict(arrowstyle="-", color="0.5", lw=0.5) if dist > 5 else None),
                                  zorder=4)
                ann.update_positions(renderer)
                bb = Text.get_window_extent(ann, renderer)  # the text alone, not its leader line
                if not clash(bb, i):
                    best = (ann, bb)
                    break
                ann.remove()
            if best:
                break
        if best is None:  # crowded: the first position, overlapping
            ann = ax.annotate(labels[i], (x[i], y[i]), xytext=(5, 4), textcoords="offset points",
                              fontsize=fontsize, zorder=4)
            ann.update_positions(renderer)
            best = (ann, Text.get_window_extent(ann, renderer))
        placed.append((best[1].x0, best[1].y0, best[1].x1, best[1].y1))
        out.append(best[0])
    return out


def plot_pareto(acc: pd.DataFrame, path: Path, hold_deg: float = 10.0,
                tilt_per_step: float = 0.001) -> None:
    """``pareto.png``: per (tol, dt, slop) point averaged over seeds (:func:`aggregate_points`),
    wall time per degree against each error measure (creep, drift, |shift of theta_m|, final
    residual), the default setting outlined in red, the Pareto front dashed; labels tol/dt[/slop]
    placed so they do not overlap, the legend outside the panels."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    agg = aggregate_points(acc)
    measures = [("creep_mean", f"creep held at {hold_deg:g} deg: mean displacement [d]", True),
                ("drift_per_deg", "drift while tilting: mean displacement per degree [d]\n"
                                  "(median over the quiet frames before the onset)", True),
                ("abs_theta_shift", "|shift of first onset theta_m| [deg] (vs tightest)", False),
                ("residual_median", "final NLGS residual (median per step)", True)]
    fig, axes = plt.subplots(2, 2, figsize=(13, 10))
    axes = axes.ravel()
    dts = sorted(agg["dt"].unique())
    markers = dict(zip(dts, "os^Dv"))
    cmap = plt.get_cmap("viridis")
    tols = sorted(agg["tol"].unique())
    labels = [point_label(r) for _, r in agg.iterrows()]
    drawn = []
    for ax, (col, label, logx) in zip(axes, measures):
        x = agg[col].to_numpy(float)
        y = agg["ms_per_deg"].to_numpy(float)
        ax.set_xlabel(label)
        ax.set_ylabel("wall time per degree of tilt [ms] (median)")
        if not np.any(np.isfinite(x) & np.isfinite(y)):
            ax.text(0.5, 0.5, "no data (no onset found before theta_cap)", ha="center",
                    transform=ax.transAxes)
            continue
        if logx:
            pos = x[np.isfinite(x) & (x > 0)]
            floor = pos.min() / 3 if pos.size else 1e-12
            x = np.where(np.isfinite(x) & (x <= 0), floor, x)
        for i, r in agg.iterrows():
            c = cmap(tols.index(r["tol"]) / max(1, len(tols) - 1))
            ax.scatter(x[i], y[i], marker=markers[r["dt"]], s=60, zorder=3,
                       color=c if r["slop"] == DEFAULT_SLOP else "none",
                       edgecolor=("red" if r["is_default"] else
                                  "k" if r["slop"] == DEFAULT_SLOP else c),
                       linewidth=2.5 if r["is_default"] or r["slop"] != DEFAULT_SLOP else 0.5)
        f = pareto_front(x, y)
        if f.size:
            ax.step(x[f], y[f], where="post", color="0.4", lw=1, ls="--", zorder=2)
        if logx:
            ax.set_xscale("log")
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both")
        ax.margins(0.12)
        drawn.append((ax, x, y))
    n = int(acc["n_grains"].iloc[0])
    fig.suptitle(f"Speed vs accuracy, {n}-grain pile, {tilt_per_step:g} deg/step, seeds "
                 f"{', '.join(map(str, sorted(acc['seed'].unique())))}\n(labels tol/dt[/slop]; errors "
                 "averaged over seeds, 0 plotted at the axis floor)", fontsize=10)
    handles = [Line2D([], [], marker=markers[d], ls="", color="0.5", label=f"dt {d:g}") for d in dts]
    handles += [Line2D([], [], marker="o", ls="", color=cmap(i / max(1, len(tols) - 1)),
                       label=f"tol {t:g}") for i, t in enumerate(tols)]
    handles += [Line2D([], [], marker="o", ls="", mfc="none", mec="0.3", mew=2.5,
                       label=f"hollow: overlap slop\nother than {DEFAULT_SLOP:g} (label /s...)"),
                Line2D([], [], marker="o", ls="", mfc="none", mec="red", mew=2.5,
                       label=f"default: tol {DEFAULT_TOL:g},\ndt {DEFAULT_DT:g}, slop {DEFAULT_SLOP:g}"),
                Line2D([], [], ls="--", color="0.4", label="Pareto front")]
    fig.legend(handles=handles, fontsize=8, loc="center right", frameon=False)
    fig.tight_layout(rect=(0, 0, 0.83, 1))
    for ax, x, y in drawn:  # after the layout, so the labels see the final axes
        place_labels(ax, x, y, labels)
    atomic_png(fig, path)
    plt.close(fig)


def plot_scaling(sc: pd.DataFrame, fit: dict, path: Path, tilt_per_step: float = 0.001) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(16, 6))
    sweep0 = fit.get("sweep", "forward")
    styles = {(sweep0, 1.0, True): ("o-", "C0", f"{sweep0}, relax 1, overlap slop (default)"),
              ("forward", 1.0, True): ("<", "C5", "forward, relax 1, overlap slop"),
              ("random", 1.0, False): ("s", "C3", "random, relax 1, slop 0 (plain NLGS reference)"),
              ("forward", 1.0, False): ("v", "C1", "forward, relax 1, slop 0"),
              ("forward", 1.5, True): ("^", "C2", "forward, relax 1.5 (SOR), slop")}
    fixed = sc[sc["fixed_sweeps"] > 0].sort_values("n")
    if len(fixed):
        lab = f"{sweep0}, exactly {int(fixed['fixed_sweeps'].iloc[0])} sweeps per step"
        axes[0].plot(fixed["n"], fixed["ms_per_step"], "D-", color="C4", label=lab)
        axes[1].plot(fixed["n"], fixed["ns_per_update"], "D-", color="C4", label=lab)
        fx = fit.get("fixed_sweeps", {})
        if "ms_per_grain_origin_fit" in fx:
            nn = np.geomspace(sc["n"].min(), sc["n"].max(), 50)
            axes[0].plot(nn, fx["ms_per_grain_origin_fit"] * nn, "--", color="C4", lw=1,
                         label=f"linear (fixed sweeps): slope {fx['loglog_slope']:.2f} log-log")
    for (sweep, relax, slop), d in sc[sc["fixed_sweeps"] == 0].groupby(["sweep", "relax", "slop"]):
        d = d.sort_values("n")
        st, c, lab = styles.get((sweep, relax, slop > 0), ("x", "k", f"{sweep} {relax:g} slop {slop:g}"))
        axes[0].plot(d["n"], d["ms_per_step"], st, color=c, label=lab)
        axes[1].plot(d["n"], d["ns_per_update"], st, color=c, label=lab)
        axes[2].plot(d["n"], d["sweeps_mean"], st, color=c, label=lab)
    if "ms_per_grain_origin_fit" in fit:
        nn = np.geomspace(sc["n"].min(), sc["n"].max(), 50)
        axes[0].plot(nn, fit["ms_per_grain_origin_fit"] * nn, "k--", lw=1,
                     label=f"linear through origin: {1e3 * fit['ms_per_grain_origin_fit']:.2f} us/grain")
        axes[0].plot(nn, fit["loglog_prefactor"] * nn ** fit["loglog_slope"], ":", color="0.5",
                     label=f"log-log fit: slope {fit['loglog_slope']:.2f}")
    for ax, lab in zip(axes, ["ms per step (median)", "ns per contact update",
                              "NLGS sweeps per step (mean)"]):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("mobile grains N (fixed depth, box 120 d * N / 4000)")
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3, which="both")
    fig.suptitle(f"Scaling at fixed depth (tiled settled pile), tilting at {tilt_per_step:g} deg/step, "
                 f"tol {sc['tol'].iloc[0]:g}", fontsize=10)
    handles, labels = axes[0].get_legend_handles_labels()  # every series is on the first panel
    fig.legend(handles, labels, fontsize=8, loc="lower center", ncol=3, frameon=False)
    fig.tight_layout(rect=(0, 0.16, 1, 1))
    atomic_png(fig, path)
    plt.close(fig)
