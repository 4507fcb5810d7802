"""Fig. 7 (beyond the paper): the rigid clusters of the pile through the tilt.

The paper counts constraints globally (z = 3 + n_m) and locally (clusters of fully mobilized
contacts). Its authors' next step (Henkes, Quint, Fily & Schwarz, PRL 116, 028301 (2016)) was to
find the rigid clusters themselves by a (3,3) pebble game on the contact network, a sticking
contact counting 2 constraints and a sliding one 1 (:mod:`tiltpile.analysis.rigidity`). Here the
pebble game runs on every stored frame (per-frame columns rigid_fraction, floppy_per_grain,
rigid_spanning of :mod:`tiltpile.analysis.tables`).

(a) One run (the sample run: the first with an onset): the largest rigid cluster's fraction of
    the mobile grains and the floppy modes per grain against theta, the onsets marked.
(b) The ensemble's quiet frames in windows of theta - theta_m: the mean largest-rigid-cluster
    fraction, the fraction of frames whose largest rigid cluster spans the pile (holds the ground
    and a free-surface grain), and delta z_gen = z - 3 - n_m of Fig. 1 beside them.
(c) The rigid clusters of the sample run's frame of Fig. 3a (the quiet frame closest to
    theta_m - 0.3 deg): the ground's cluster, the other clusters of two grains or more, and the
    grains rigid with nothing (floppy).

The claims it tests (paper/REPRODUCTION.md): the largest rigid cluster spans the pile during
quiet periods; it shrinks towards the onset; it loses spanning at or before theta_m; and where
that happens compared with the mean path's crossing of the marginal line (Fig. 1).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tiltpile.analysis import rigidity as _rg
from tiltpile.analysis import tables as _tb
from tiltpile.analysis.stats import bootstrap_ci, window_edges

from . import data, style
from .data import Reads
from .snapshot import SNAPSHOT_OFFSET_DEG, frame_before_onset, snapshot_extent

# the table columns the figure reads (from records, only these are checked)
READS = Reads("Fig. 7",
              frames=("theta_deg", "dz_gen", "rigid_fraction", "floppy_per_grain",
                      "rigid_spanning", "avalanching", "onset", "theta_m", "theta_to_onset"),
              clusters=())

NAME = "fig7_rigidity"
RIGID_COLUMNS = ("rigid_fraction", "floppy_per_grain", "rigid_spanning")


def _quiet_before_onset(frames: pd.DataFrame, lo: float) -> pd.DataFrame:
    """Quiet frames with a next onset no further than ``lo`` degrees ahead."""
    t = frames["theta_to_onset"].to_numpy(float)
    sel = ~frames["avalanching"].to_numpy(bool) & np.isfinite(t) & (t < 0) & (t >= lo)
    return frames[sel]


def window_means(frames: pd.DataFrame, lo: float = -15.0, width: float = 0.5,
                 min_frames: int = 3) -> pd.DataFrame:
    """Means over the quiet frames in windows of theta - theta_m (far to near), as Fig. 1's
    :func:`~tiltpile.figures.fig1.mean_path`: rigid_fraction, floppy_per_grain, the spanning
    fraction (mean of rigid_spanning) and dz_gen. Windows with fewer than ``min_frames`` frames
    are dropped; each point sits at the mean theta - theta_m of its frames.

    Returns a DataFrame left, right, n_frames, theta_to_onset, rigid_fraction, floppy_per_grain,
    spanning, dz_gen.
    """
    cols = ["left", "right", "n_frames", "theta_to_onset", "rigid_fraction", "floppy_per_grain",
            "spanning", "dz_gen"]
    f = _quiet_before_onset(frames, lo)
    edges = window_edges(width, lo, 0.0)
    if f.empty or edges.size < 2:
        return pd.DataFrame(columns=cols)
    k = np.clip(np.searchsorted(edges, f["theta_to_onset"].to_numpy(float), side="right") - 1,
                0, edges.size - 2)
    rows = []
    for b in np.unique(k):
        g = f[k == b]
        if len(g) < min_frames:
            continue
        rows.append({"left": edges[b], "right": edges[b + 1], "n_frames": len(g),
                     "theta_to_onset": g["theta_to_onset"].mean(),
                     "rigid_fraction": g["rigid_fraction"].mean(),
                     "floppy_per_grain": g["floppy_per_grain"].mean(),
                     "spanning": g["rigid_spanning"].astype(float).mean(),
                     "dz_gen": g["dz_gen"].mean()})
    return pd.DataFrame(rows, columns=cols)


def onset_states(frames: pd.DataFrame) -> pd.DataFrame:
    """For every onset preceded by a quiet frame: whether the largest rigid cluster spans at the
    last quiet frame before it and at the onset frame, and how long before the onset the pile
    last lost spanning within that quiet period (theta - theta_m of the first frame of the final
    run of non-spanning frames; NaN if it spans at the last quiet frame).

    Returns a DataFrame run, frame (of the onset), theta_m, spanning_before, spanning_at,
    rigid_fraction_before, rigid_fraction_at, loss_to_onset.
    """
    rows = []
    for run, g in frames.sort_values(["run", "frame"], kind="stable").groupby("run", sort=True):
        av = g["avalanching"].to_numpy(bool)
        on = g["onset"].to_numpy(bool)
        sp = g["rigid_spanning"].to_numpy(bool)
        rf = g["rigid_fraction"].to_numpy(float)
        th = g["theta_deg"].to_numpy(float)
        for i in np.flatnonzero(on):
            if i == 0 or av[i - 1]:
                continue
            j = i - 1                    # last quiet frame; walk back over its non-spanning run
            loss = np.nan
            if not sp[j]:
                while j - 1 >= 0 and not av[j - 1] and not sp[j - 1]:
                    j -= 1
                loss = float(th[j] - th[i])
            rows.append({"run": run, "frame": int(g["frame"].to_numpy()[i]), "theta_m": th[i],
                         "spanning_before": bool(sp[i - 1]), "spanning_at": bool(sp[i]),
                         "rigid_fraction_before": rf[i - 1], "rigid_fraction_at": rf[i],
                         "loss_to_onset": loss})
    return pd.DataFrame(rows, columns=["run", "frame", "theta_m", "spanning_before", "spanning_at",
                                       "rigid_fraction_before", "rigid_fraction_at",
                                       "loss_to_onset"])


def snapshot_rigidity(snap: dict, mu: float = 0.5, mu_wall: float | None = None,
                      **params) -> dict:
    """The rigid clusters of one stored frame (:func:`tiltpile.figures.data.snapshot`) with the
    observables' contacts and parameters: dict position, radius, fixed, grain_cluster (labels of
    :func:`tiltpile.analysis.rigidity.rigid_clusters`), cluster_size, n_floppy, spanning,
    theta_deg, box_length."""
    pos = np.asarray(snap["position"], dtype=float)
    radius = np.asarray(snap["radius"], dtype=float)
    fixed = np.asarray(snap["fixed"], dtype=bool)
    L = float(snap["box_length"])
    p = {k: v for k, v in params.items() if k in _tb.DEFAULT_PARAMS}
    fc = _tb.frame_contacts(radius, fixed, L, pos, snap["pair"], snap["force"], snap.get("status"),
                            mu=mu, mu_wall=mu_wall, **p)
    rig = _rg.rigid_clusters(radius.size, fc["pair"], fc["active"], fc["mobilized"], fixed,
                             min_contacts=p.get("min_contacts", _tb.DEFAULT_PARAMS["min_contacts"]))
    return {"position": pos, "radius": radius, "fixed": fixed, "grain_cluster": rig.grain_cluster,
            "cluster_size": rig.cluster_size, "n_floppy": int(rig.n_floppy),
            "spanning": _rg.spans(rig, fc["top"]), "largest_size": int(rig.largest_size),
            "theta_deg": float(snap["theta_deg"]), "box_length": L}


def _run_means(frames: pd.DataFrame, seeds, column: str, lo: float, hi: float) -> np.ndarray:
    """Per run, the mean of ``column`` over its quiet frames with lo <= theta - theta_m < hi."""
    f = _quiet_before_onset(frames, lo)
    f = f[f["theta_to_onset"].to_numpy(float) < hi]
    m = f.groupby("run")[column].mean()
    return np.array([float(m.get(s, np.nan)) for s in seeds])


def compute(ens, sample_seed: int | None = None, snapshot_offset_deg: float = SNAPSHOT_OFFSET_DEG,
            path_lo: float = -15.0, path_width: float = 0.5, min_frames: int = 3,
            near_deg: float = 1.0, far_deg: float = 3.0, snapshot: bool = True) -> tuple[dict, dict]:
    """Numbers and plot data of Fig. 7 (module docstring).

    sample_seed: run of panels (a) and (c) (None: the first run with an onset);
    snapshot_offset_deg: panel (c) is the quiet frame closest to theta_m - offset (Fig. 3a's);
    path_lo, path_width, min_frames: the windows of panel (b) (:func:`window_means`); near_deg,
    far_deg: the shrinking test compares, run by run, the quiet frames within ``near_deg`` of the
    onset with those further than ``far_deg`` (and within -path_lo); snapshot: draw panel (c).

    numbers:
      n_quiet_frames, quiet_spanning_fraction (CI over runs), quiet_rigid_fraction (CI),
      quiet_floppy_per_grain (CI)                 quiet frames of every run
      rigid_fraction_near, rigid_fraction_far     per-run means near / far from the onset (CI)
      rigid_fraction_shrink                       near - far, paired by run (CI of the mean of
                                                  the per-run differences)
      n_onsets, spanning_before_fraction, spanning_at_fraction
                                                  onsets preceded by a quiet frame; fraction of
                                                  them whose last quiet frame / onset frame spans
      loss_to_onset_median                        median theta - theta_m at which spanning was
                                                  lost before the onsets that lost it
      spanning_loss_theta_to_onset                where the spanning fraction of panel (b) drops
                                                  below 1/2 (NaN: never)
      marginal_crossing_theta_to_onset            where the windows' mean delta z_gen drops below
                                                  0 (the marginal line z = 3 + n_m; NaN: never)
      sample                                      seed, frame, theta_deg, theta_to_onset,
                                                  largest_size, n_floppy, spanning of panel (c)
    """
    fr = ens.frames
    missing = [c for c in RIGID_COLUMNS if c not in fr.columns]
    if missing:
        raise ValueError(f"the tables lack {missing}: recompute the observables (or records) "
                         "with this tiltpile")
    seeds = list(ens.seeds)
    numbers: dict = {}
    q = fr[~fr["avalanching"].to_numpy(bool)]
    numbers["n_quiet_frames"] = int(len(q))
    for key, col in (("quiet_spanning_fraction", "rigid_spanning"),
                     ("quiet_rigid_fraction", "rigid_fraction"),
                     ("quiet_floppy_per_grain", "floppy_per_grain")):
        per_run = q.assign(v=q[col].astype(float)).groupby("run")["v"].mean()
        numbers[key] = bootstrap_ci([float(per_run.get(s, np.nan)) for s in seeds])
    near = _run_means(fr, seeds, "rigid_fraction", -near_deg, 0.0)
    far = _run_means(fr, seeds, "rigid_fraction", path_lo, -far_deg)
    numbers["rigid_fraction_near"] = bootstrap_ci(near)
    numbers["rigid_fraction_far"] = bootstrap_ci(far)
    numbers["rigid_fraction_shrink"] = bootstrap_ci(near - far)
    numbers["near_deg"], numbers["far_deg"] = float(near_deg), float(far_deg)
    on = onset_states(fr)
    numbers["n_onsets"] = int(len(on))
    numbers["spanning_before_fraction"] = (float(on["spanning_before"].mean()) if len(on)
                                           else np.nan)
    numbers["spanning_at_fraction"] = float(on["spanning_at"].mean()) if len(on) else np.nan
    loss = on["loss_to_onset"].to_numpy(float)
    loss = loss[np.isfinite(loss)]
    numbers["loss_to_onset_median"] = float(np.median(loss)) if loss.size else np.nan
    path = window_means(fr, path_lo, path_width, min_frames)
    numbers["spanning_loss_theta_to_onset"] = (data.first_below(path, "spanning", 0.5) if len(path)
                                               else np.nan)
    numbers["marginal_crossing_theta_to_onset"] = (data.first_below(path, "dz_gen", 0.0) if len(path)
                                                   else np.nan)

    seed = ens.sample_seed(sample_seed)
    g = fr[fr["run"] == seed].sort_values("frame", kind="stable")
    frame = frame_before_onset(fr, seed, snapshot_offset_deg)
    row = g[g["frame"] == frame].iloc[0]
    numbers["sample"] = {"seed": seed, "frame": frame, "theta_deg": float(row["theta_deg"]),
                         "theta_to_onset": float(row["theta_to_onset"])}
    lay = None
    if snapshot:
        scene = (ens.config or {}).get("scene", {})
        mu = float(scene.get("mu", 0.5))
        lay = snapshot_rigidity(data.snapshot(ens, seed, frame), mu=mu,
                                mu_wall=float(scene.get("mu_wall", mu)),
                                **data.analysis_params(ens))
        numbers["sample"].update(largest_size=lay["largest_size"], n_floppy=lay["n_floppy"],
                                 spanning=bool(lay["spanning"]))
    d = {"run": g[["theta_deg", "rigid_fraction", "floppy_per_grain", "rigid_spanning", "onset",
                   "avalanching"]].reset_index(drop=True),
         "seed": seed, "path": path, "snapshot": lay}
    return numbers, d


def _cluster_colors(lay: dict) -> list:
    """Grain colours of panel (c): fixed grains, the ground's cluster, other clusters of two
    grains or more (a cycle of colours, by decreasing size), grains rigid with nothing, left out."""
    lab = np.asarray(lay["grain_cluster"])
    size = np.asarray(lay["cluster_size"])
    palette = ["#4C72B0", "#DD8452", "#55A868", "#C44E52", "#8172B3", "#937860", "#DA8BC3",
               "#8C8C8C", "#CCB974", "#64B5CD"]
    out = []
    for i, c in enumerate(lab):
        if lay["fixed"][i]:
            out.append(style.COLORS["fixed"])
        elif c < 0:
            out.append("white")
        elif c == _rg.GROUND and size[c] > 0:
            out.append("#2F4F6F")
        elif size[c] >= 2:
            out.append(palette[(int(c) - 1) % len(palette)])
        else:
            out.append("#E8E8E8")
    return out


def plot(data: dict, numbers: dict):
    """(a) one run against theta; (b) ensemble windows against theta - theta_m; (c) clusters."""
    lay = data["snapshot"]
    if lay is not None:
        # the box alone: panel c draws no gravity arrow, so no margin for one
        ew = float(lay["box_length"])
        eh = snapshot_extent({"position": lay["position"], "radius": lay["radius"],
                              "box_length": ew})[1]
    else:
        ew, eh = 2.0, 1.0
    left, right = 0.16, 0.86
    h_c = (right - left) * style.SINGLE_COLUMN_IN * eh / ew
    height, gkw = style.stacked_layout([1.5, 1.5, h_c], [0.45, 0.6], top_in=0.36,
                                       bottom_in=0.05, left=left, right=right)
    fig, (ax, bx, cx) = style.figure(3, 1, height=height, gridspec_kw=gkw)

    r = data["run"]
    th = r["theta_deg"].to_numpy(float)
    ax.plot(th, r["rigid_fraction"], color=style.COLORS["quiet"], lw=0.9,
            label="largest rigid cluster / grains")
    ax.set_ylim(-0.02, 1.05)
    ax.set_xlabel(r"$\theta$ (deg)")
    ax.set_ylabel("largest rigid fraction")
    ax2 = ax.twinx()
    ax2.plot(th, r["floppy_per_grain"], color=style.COLORS["avalanche"], lw=0.8,
             label="floppy modes / grain")
    ax2.set_ylabel("floppy modes / grain", color=style.COLORS["avalanche"])
    ax2.tick_params(axis="y", colors=style.COLORS["avalanche"])
    for t in th[r["onset"].to_numpy(bool)]:
        ax.axvline(t, color=style.COLORS["marginal"], lw=0.5, ls=":", zorder=0)
    ax.plot([], [], color=style.COLORS["marginal"], lw=0.5, ls=":", label="onsets")
    ax.plot([], [], color=style.COLORS["avalanche"], lw=0.8, label="floppy modes / grain")
    # above the panel: inside it, the legend would hide the twin axis's curve at any corner
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=3, fontsize=5.5,
              handlelength=1.5, columnspacing=1.0, frameon=False, title=f"run {data['seed']}",
              title_fontsize=6.5)
    style.panel_label(ax, "a")

    path = data["path"]
    if len(path):
        t = path["theta_to_onset"].to_numpy(float)
        bx.plot(t, path["rigid_fraction"], color=style.COLORS["quiet"], marker="o", ms=2,
                lw=0.9, label="largest rigid fraction")
        bx.plot(t, path["spanning"], color=style.COLORS["cluster"], marker="s", ms=2, lw=0.9,
                label="spanning frames")
        bx2 = bx.twinx()
        bx2.plot(t, path["dz_gen"], color=style.COLORS["marginal"], lw=0.9, ls="--")
        bx2.axhline(0.0, color=style.COLORS["marginal"], lw=0.5)
        bx2.set_ylabel(r"$\delta z_{gen} = z - 3 - n_m$", color=style.COLORS["marginal"])
        bx2.tick_params(axis="y", colors=style.COLORS["marginal"])
        bx.plot([], [], color=style.COLORS["marginal"], lw=0.9, ls="--",
                label=r"$\delta z_{gen}$ (Fig. 1)")
    else:
        bx.text(0.5, 0.5, "no quiet frame before an onset", transform=bx.transAxes,
                ha="center", va="center")
    bx.set_ylim(-0.02, 1.05)
    bx.set_xlabel(r"$\theta - \theta_m$ (deg)")
    bx.set_ylabel("quiet-frame mean")
    bx.legend(loc="lower left", fontsize=5.5, handlelength=1.5)
    style.panel_label(bx, "b")

    if lay is None:
        cx.text(0.5, 0.5, "no snapshot", transform=cx.transAxes, ha="center", va="center")
        cx.set_xticks([])
        cx.set_yticks([])
    else:
        style.draw_pile(cx, lay["position"], lay["radius"], _cluster_colors(lay),
                        box_length=lay["box_length"])
        cx.set_xlim(0.0, lay["box_length"])
        for side in ("top", "right", "bottom", "left"):
            cx.spines[side].set_visible(False)
        s = numbers["sample"]
        cx.set_title(rf"$\theta = {s['theta_deg']:.1f}^\circ$, $\theta - \theta_m = "
                     rf"{s['theta_to_onset']:.1f}^\circ$: largest rigid cluster "
                     f"{s.get('largest_size', 0)} grains, "
                     f"{'spanning' if s.get('spanning') else 'not spanning'}", fontsize=6)
    style.panel_label(cx, "c", x=0.0, y=1.0)
    return fig
