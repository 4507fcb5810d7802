"""Fig. 1 -- the generalized isostaticity diagram and the pile during an avalanche (paper Fig. 1).

(a) The (z, n_m) plane of the bulk (top and bottom single layers and rattlers excluded, as the
paper's Fig. 2d), with the line of marginal stability of Eq. (1) in d = 2,
z = z_iso^gen = 3 + n_m (stable below/right of it, delta z_gen = z - 3 - n_m > 0). The paper's
panel is a schematic: it asks whether a slowly tilted pile follows a path from the stable region
to the marginal line and fails there. Drawn here:

* the hypothesis, as an arrow from the ensemble's mean state at the start of the tilt straight up
  to the line (z quenched, n_m growing until delta z_gen = 0: failure exactly at marginality);
* the measured mean quiet-period path towards the avalanche: z and n_m averaged over the quiet
  frames of all runs in windows of theta - theta_m (theta_m: the next onset, column
  ``theta_to_onset``), from far from the onset to just before it (:func:`mean_path`);
* the mean position of the avalanching frames.

(b) A snapshot of the sample run during an avalanche, coloured as Fig. 3 (grains in critical
clusters dark, critical contacts green, failing grains red in a cluster / blue outside).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tiltpile.analysis import contacts as _ct
from tiltpile.analysis.stats import bootstrap_ci, window_edges

from . import data, style
from .data import Reads
from .snapshot import draw_snapshot, load_snapshot, pick_avalanche_frame, snapshot_extent

# the table columns the figure reads (from records, only these are checked)
READS = Reads("Fig. 1",
              frames=("theta_deg", "z", "n_m", "dz_gen", "lost_fraction", "avalanching", "onset",
                      "theta_m", "theta_to_onset"),
              clusters=())

NAME = "fig1_isostaticity"


def mean_path(frames: pd.DataFrame, lo: float = -15.0, width: float = 0.5,
              min_frames: int = 3) -> pd.DataFrame:
    """Mean (z, n_m) of the quiet frames in windows of theta - theta_m, far to near the onset.

    frames: per-frame table (avalanching, theta_to_onset, z, n_m). Quiet frames with a next onset
    (finite theta_to_onset < 0) in windows [left, right) of ``width`` degrees tiling [lo, 0)
    (:func:`tiltpile.analysis.stats.window_edges`); windows with fewer than ``min_frames`` frames
    are dropped. Each point sits at the mean theta - theta_m of its frames, so a path linear in
    theta - theta_m is reproduced exactly whatever the window alignment.

    Returns a DataFrame left, right, n_frames, theta_to_onset (mean), z, n_m, dz_gen
    (= z - 3 - n_m of the means), z_sem, n_m_sem (standard errors over the frames), ordered from
    far (most negative) to near.
    """
    cols = ["left", "right", "n_frames", "theta_to_onset", "z", "n_m", "dz_gen", "z_sem", "n_m_sem"]
    t = frames["theta_to_onset"].to_numpy(float)
    sel = ~frames["avalanching"].to_numpy(bool) & np.isfinite(t) & (t < 0) & (t >= lo)
    sel &= np.isfinite(frames["z"].to_numpy(float)) & np.isfinite(frames["n_m"].to_numpy(float))
    f = frames[sel]
    edges = window_edges(width, lo, 0.0)
    if f.empty or edges.size < 2:
        return pd.DataFrame(columns=cols)
    k = np.searchsorted(edges, f["theta_to_onset"].to_numpy(float), side="right") - 1
    k = np.clip(k, 0, edges.size - 2)
    rows = []
    for b in np.unique(k):
        g = f[k == b]
        n = len(g)
        if n < min_frames:
            continue
        z, nm = g["z"].to_numpy(float), g["n_m"].to_numpy(float)
        rows.append({"left": edges[b], "right": edges[b + 1], "n_frames": n,
                     "theta_to_onset": g["theta_to_onset"].mean(), "z": z.mean(), "n_m": nm.mean(),
                     "dz_gen": float(_ct.dz_gen(z.mean(), nm.mean())),
                     "z_sem": z.std(ddof=1) / np.sqrt(n) if n > 1 else np.nan,
                     "n_m_sem": nm.std(ddof=1) / np.sqrt(n) if n > 1 else np.nan})
    return pd.DataFrame(rows, columns=cols)


def path_crossing(path: pd.DataFrame) -> float:
    """theta - theta_m where the mean path first reaches the marginal line (delta z_gen = 0).

    Walking from far to near: linear interpolation in theta - theta_m between the last point
    with delta z_gen >= 0 and the first with delta z_gen < 0; the first point itself if the path
    starts below the line; NaN if it never goes below.
    """
    return data.first_below(path, "dz_gen", 0.0)


def _mean(x) -> float:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else np.nan


def compute(ens, sample_seed: int | None = None, avalanche_frame: int | None = None,
            path_lo: float = -15.0, path_width: float = 0.5, min_frames: int = 3,
            snapshot: bool = True) -> tuple[dict, dict]:
    """Numbers and plot data of Fig. 1 (module docstring).

    sample_seed: run of the snapshot (None: the first run with an onset); avalanche_frame: its
    frame (None: :func:`~tiltpile.figures.snapshot.pick_avalanche_frame`); path_lo, path_width,
    min_frames: windows of the mean path (:func:`mean_path`); snapshot: read the snapshot from the
    run file.

    numbers:
      z_start, n_m_start, dz_gen_start   mean over runs of the first frame (start of the tilt)
      z_pre_onset, n_m_pre_onset, dz_gen_pre_onset
                                    mean over all avalanche onsets of the quiet frame just
                                    before the onset
      n_onsets                      onsets entering the pre-onset mean
      z_avalanche, n_m_avalanche    mean over avalanching frames
      path_crosses                  whether the mean quiet path goes below the marginal line
      path_crossing_theta_to_onset  where (theta - theta_m, deg; :func:`path_crossing`)
      path_min_dz_gen               closest approach of the mean path to the line (delta z_gen)
      path_n_windows                windows on the path
      quiet_below_fraction          fraction of quiet frames with delta z_gen < 0
      avalanche_below_fraction      fraction of avalanching frames with delta z_gen < 0
      quiet_below_per_run, quiet_below_run_mean (_ci_low, _ci_high), quiet_below_run_max
                                    the same per run, its mean over runs with a bootstrap
                                    interval over runs (stats.bootstrap_ci), and the largest
      dz_gen_pre_onset_run_mean (_ci_low, _ci_high)
                                    mean over runs of each run's pre-onset mean, with interval
      snapshot                      seed, frame, theta_deg of panel b
    """
    f = ens.frames.sort_values(["run", "frame"], kind="stable")
    av = f["avalanching"].to_numpy(bool)
    first = f.groupby("run", sort=False).head(1)
    nxt_onset = f.groupby("run", sort=False)["onset"].shift(-1, fill_value=False).to_numpy(bool)
    pre = f[nxt_onset & ~av]
    numbers: dict = {
        "z_start": _mean(first["z"]), "n_m_start": _mean(first["n_m"]),
        "dz_gen_start": _mean(first["dz_gen"]),
        "z_pre_onset": _mean(pre["z"]), "n_m_pre_onset": _mean(pre["n_m"]),
        "dz_gen_pre_onset": _mean(pre["dz_gen"]), "n_onsets": int(len(pre)),
        "z_avalanche": _mean(f["z"][av]), "n_m_avalanche": _mean(f["n_m"][av]),
    }
    path = mean_path(f, path_lo, path_width, min_frames)
    cross = path_crossing(path)
    numbers.update(path_crosses=bool(np.isfinite(cross)), path_crossing_theta_to_onset=cross,
                   path_min_dz_gen=float(path["dz_gen"].min()) if len(path) else np.nan,
                   path_n_windows=int(len(path)))
    dz = f["dz_gen"].to_numpy(float)
    ok = np.isfinite(dz)
    q, a = ~av & ok, av & ok
    numbers.update(quiet_below_fraction=float((dz[q] < 0).mean()) if q.any() else np.nan,
                   avalanche_below_fraction=float((dz[a] < 0).mean()) if a.any() else np.nan)
    # per run, so that the ensemble value carries a bootstrap interval over runs
    runs = f["run"].to_numpy()
    per_run = [float((dz[q & (runs == r)] < 0).mean()) if (q & (runs == r)).any() else np.nan
               for r in ens.seeds]
    pre_run = [_mean(pre.loc[pre["run"] == r, "dz_gen"]) for r in ens.seeds]
    ci = bootstrap_ci(per_run)
    ci_pre = bootstrap_ci(pre_run)
    numbers.update(quiet_below_per_run=per_run, quiet_below_run_mean=ci["estimate"],
                   quiet_below_run_mean_ci_low=ci["low"], quiet_below_run_mean_ci_high=ci["high"],
                   quiet_below_run_max=float(np.nanmax(per_run)) if np.isfinite(per_run).any()
                   else np.nan,
                   dz_gen_pre_onset_run_mean=ci_pre["estimate"],
                   dz_gen_pre_onset_ci_low=ci_pre["low"], dz_gen_pre_onset_ci_high=ci_pre["high"])

    seed = ens.sample_seed(sample_seed)
    frame = pick_avalanche_frame(f, seed) if avalanche_frame is None else int(avalanche_frame)
    row = f[(f["run"] == seed) & (f["frame"] == frame)]
    if row.empty:
        raise ValueError(f"frame {frame} is not in run {seed}")
    numbers["snapshot"] = {"seed": seed, "frame": frame,
                           "theta_deg": float(row["theta_deg"].iloc[0])}
    d = {"path": path, "start": (numbers["z_start"], numbers["n_m_start"]),
         "pre_onset": (numbers["z_pre_onset"], numbers["n_m_pre_onset"]),
         "avalanche": (numbers["z_avalanche"], numbers["n_m_avalanche"]),
         "snapshot": load_snapshot(ens, seed, frame) if snapshot else None}
    return numbers, d


def plot(data: dict, numbers: dict):
    """(a) the (z, n_m) diagram with the marginal line, hypothesis and mean path; (b) snapshot."""
    from matplotlib.collections import LineCollection
    lay = data["snapshot"]
    ew, eh = snapshot_extent(lay) if lay is not None else (2.0, 1.0)
    left, right = 0.16, 0.97
    h_b = (right - left) * style.SINGLE_COLUMN_IN * eh / ew
    height, gkw = style.stacked_layout([1.9, h_b], [0.62], top_in=0.5, bottom_in=0.05, left=left,
                                       right=right)
    fig, (ax, bx) = style.figure(2, 1, height=height, gridspec_kw=gkw)
    path = data["path"]
    z0, m0 = data["start"]
    pts = [(z0, m0), data["pre_onset"], data["avalanche"]]
    pts += list(zip(path["z"], path["n_m"])) if len(path) else []
    zs = np.array([p[0] for p in pts if np.isfinite(p[0])] or [3.3])
    ms = np.array([p[1] for p in pts if np.isfinite(p[1])] or [0.1])
    zlo = min(zs.min(), 3.0) - 0.05
    zhi = max(zs.max(), 3.0) + 0.1
    mhi = max(ms.max() * 1.25, zhi - 3.0 + 0.02, 0.1)
    # stable / unstable regions and the marginal line n_m = z - 3
    zz = np.array([zlo, zhi])
    ax.fill_between(zz, zz - 3.0, mhi, color=style.COLORS["marginal"], alpha=0.07, lw=0)
    ax.plot(zz, zz - 3.0, color=style.COLORS["marginal"], lw=1.2,
            label=r"marginal: $z = 3 + n_m$")
    ax.text(0.97, 0.04, "stable", transform=ax.transAxes, ha="right", va="bottom",
            color=style.COLORS["marginal"])
    ax.text(0.08, 0.96, "unstable", transform=ax.transAxes, ha="left", va="top",
            color=style.COLORS["marginal"])
    # hypothesis: z fixed, n_m grows up to the line
    if np.isfinite(z0) and np.isfinite(m0) and z0 - 3.0 > m0:
        ax.annotate("", xy=(z0, z0 - 3.0), xytext=(z0, m0),
                    arrowprops=dict(arrowstyle="-|>", color=style.COLORS["hypothesis"], lw=1.4,
                                    ls="--", shrinkA=0, shrinkB=0))
        ax.plot([], [], color=style.COLORS["hypothesis"], ls="--", lw=1.4, label="hypothesis")
    # measured mean quiet path, shaded from far (light) to near (dark)
    if len(path) > 1:
        xy = path[["z", "n_m"]].to_numpy(float)
        seg = np.stack([xy[:-1], xy[1:]], axis=1)
        shade = np.linspace(0.65, 0.0, len(seg))
        ax.add_collection(LineCollection(seg, colors=[str(s) for s in shade], lw=1.0))
        ax.scatter(xy[:, 0], xy[:, 1], s=6, c=[str(s) for s in np.linspace(0.65, 0.0, len(xy))],
                   zorder=3, linewidths=0)
        t = path["theta_to_onset"].to_numpy(float)
        for i, ha in ((0, "right"), (-1, "left")):
            ax.annotate(f"{t[i]:.1f}$^\\circ$", xy=xy[i], xytext=(-4 if i == 0 else 4, 2),
                        textcoords="offset points", ha=ha, va="bottom", fontsize=6,
                        color=style.COLORS["quiet"])
    ax.plot([], [], color=style.COLORS["quiet"], marker="o", ms=2.5, lw=1.0,
            label=r"quiet, mean vs $\theta-\theta_m$")
    ax.plot([z0], [m0], ls="none", marker="o", mfc="white", mec=style.COLORS["quiet"], ms=5,
            zorder=4, label=r"start ($\theta = 0$)")
    zp, mp = data["pre_onset"]
    ax.plot([zp], [mp], ls="none", marker="o", color=style.COLORS["quiet"], ms=5, zorder=4,
            label="just before onset")
    za, ma = data["avalanche"]
    ax.plot([za], [ma], ls="none", marker="D", color=style.COLORS["avalanche"], ms=4.5, zorder=4,
            label="avalanching")
    ax.set_xlim(zlo, zhi)
    ax.set_ylim(0, mhi)
    ax.set_xlabel(r"$z$ (contacts per grain)")
    ax.set_ylabel(r"$n_m$ (mobilized contacts per grain)")
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=2, handlelength=1.8,
              columnspacing=1.0)
    style.panel_label(ax, "a")
    draw_snapshot(bx, lay)
    style.panel_label(bx, "b", x=0.0, y=1.0)
    return fig
