"""The pile pictures of Figs. 1b and 3, and the frames they show.

Frames. :func:`pick_avalanche_frame` (Fig. 1b: the sample run's avalanching frame losing most
contacts) and :func:`frame_before_onset` (Fig. 3a: the quiet frame closest to theta_m -
``SNAPSHOT_OFFSET_DEG``). The records keep these frames of every run
(:mod:`tiltpile.figures.records`), so that the pictures can be drawn without the run files.

Pictures. :func:`snapshot_layers` turns one stored frame (:func:`tiltpile.figures.data.snapshot`)
into what is drawn: grains by category (in a critical cluster, failing inside or outside one, fixed,
other), the fully mobilized contacts as segments; :func:`load_snapshot` does it for a frame of an
ensemble with its friction and analysis parameters; :func:`draw_snapshot` draws it with the box and
gravity, and :func:`snapshot_extent` gives its size for the figure layout.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tiltpile.analysis import contacts as _ct
from tiltpile.analysis import observables as _ob

from . import data, style

SNAPSHOT_OFFSET_DEG = 0.3   # Fig. 3a: the quiet frame closest to theta_m minus this (deg)

# grain categories of a snapshot (index into CATEGORY_COLORS)
GRAIN, FIXED, CLUSTER, FAIL_IN_CLUSTER, FAIL_OUTSIDE = range(5)
CATEGORY_COLORS = [style.COLORS["grain"], style.COLORS["fixed"], style.COLORS["cluster"],
                   style.COLORS["fail_in_cluster"], style.COLORS["fail_outside"]]


# ----------------------------------------------------------------------------------------------
# the frames the pictures show


def pick_avalanche_frame(frames: pd.DataFrame, seed: int) -> int:
    """The avalanching frame of run ``seed`` with the largest lost fraction (ties: the earliest);
    without avalanche, the run's frame with the largest lost fraction."""
    g = frames[frames["run"] == seed].sort_values("frame", kind="stable")
    if g.empty:
        raise ValueError(f"run {seed} is not in the table")
    lf = g["lost_fraction"].to_numpy(float)
    av = g["avalanching"].to_numpy(bool) & np.isfinite(lf)
    cand = np.flatnonzero(av) if av.any() else np.flatnonzero(np.isfinite(lf))
    if cand.size == 0:
        return int(g["frame"].iloc[0])
    return int(g["frame"].to_numpy()[cand[np.argmax(lf[cand])]])


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


# ----------------------------------------------------------------------------------------------
# the picture of one frame


def snapshot_layers(snap: dict, mu: float = 0.5, mu_wall: float | None = None,
                    eps: float | None = None, link: str = "contacts",
                    cluster_region: str = "mobile", ray_spacing: float = 0.1,
                    touch_tol: float = 0.05, lost_gap: float | None = None,
                    contact_rule: str = "force", lost_rule: str | None = None) -> dict:
    """What the pile pictures of Figs. 1b and 3 draw, from one frame (a :func:`data.snapshot`).

    The contacts, mobilized contacts and clusters are those of the observables
    (:func:`tiltpile.analysis.observables.frame_contacts`); failing grains are the mobile ends of
    the contacts lost by the next frame (:func:`~tiltpile.analysis.observables.lost_between`, with
    the same ``lost_gap``), under the same ``contact_rule`` and ``lost_rule``: a gap rule finds
    the next frame's list from its positions too.

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
                            touch_tol=touch_tol, contact_rule=contact_rule, lost_rule=lost_rule)
    pair, mobil, labels = fc["pair"], fc["mobilized"], fc["labels"]
    in_cluster = labels >= 0
    failing = np.zeros(n, dtype=bool)
    if snap.get("next") is not None:
        p2, f2 = np.asarray(snap["next"][0]).reshape(-1, 2), snap["next"][1]
        cur = {"pair": p2, "active": _ct.active_mask(f2), "position": snap.get("next_position")}
        if (contact_rule, lost_rule) != ("force", None):   # the next frame's list by the rules
            nxt = _ob.frame_contacts(radius, fixed, L, snap["next_position"], p2, f2,
                                     snap["next"][2], mu=mu, mu_wall=mu_wall, eps=eps, link=link,
                                     cluster_region=cluster_region, ray_spacing=ray_spacing,
                                     touch_tol=touch_tol, contact_rule=contact_rule,
                                     lost_rule=lost_rule)
            cur = {"pair": nxt["pair"], "active": nxt["lost_active"],
                   "position": snap["next_position"]}
        lost = _ob.lost_between({"pair": pair, "active": fc["lost_active"]}, cur, n, radius, L,
                                lost_gap)
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
    p = data.analysis_params(ens)
    scene = (ens.config or {}).get("scene", {})
    mu = float(scene.get("mu", 0.5))
    lay = snapshot_layers(data.snapshot(ens, seed, frame), mu=mu,
                          mu_wall=float(scene.get("mu_wall", mu)), eps=p["eps"], link=p["link"],
                          cluster_region=p["cluster_region"], ray_spacing=p["ray_spacing"],
                          touch_tol=p["touch_tol"], lost_gap=p["lost_gap"],
                          contact_rule=p["contact_rule"], lost_rule=p["lost_rule"])
    lay.update(seed=int(seed), frame=int(frame))
    return lay


def snapshot_extent(lay: dict) -> tuple[float, float]:
    """(width, height) in d of the picture :func:`draw_snapshot` makes (for the figure layout)."""
    y = lay["position"][:, 1]
    dmax = 2.0 * float(np.max(lay["radius"]))
    h = float(np.ptp(y)) + 2.0 * dmax
    return lay["box_length"] + _gravity_margin(h, lay["box_length"]), h


def _gravity_margin(h: float, box_length: float) -> float:
    """Room right of the box for the gravity arrow and the tilt label: the arrow scales with the
    pile's height, the label (fixed font size) with the picture's width, which a long flat pile
    (4000 grains) sets."""
    return max(0.42 * h, 0.2 * box_length)


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
    m = _gravity_margin(h, L)
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
    ax.text(L + 0.06 * m, cy + g[1] / 2 - 0.04 * h, rf"$\theta = {lay['theta_deg']:.1f}^\circ$",
            ha="left", va="top", fontsize=6.5)
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
