"""One look for every figure: single-column size, a colour-blind-safe palette, saving.

Palette: Okabe & Ito, "Color Universal Design" (2008), safe for the common colour-vision
deficiencies. Semantic names keep the figures consistent with each other and with the paper's
captions (quiet periods black, avalanching periods red-orange, critical contacts green, failing
grains red in a cluster and blue outside).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from tiltpile.outputs import replaced_whole
from tiltpile.record import jsonable as _record_jsonable

OKABE_ITO = {
    "black": "#000000", "orange": "#E69F00", "skyblue": "#56B4E9", "green": "#009E73",
    "yellow": "#F0E442", "blue": "#0072B2", "vermillion": "#D55E00", "purple": "#CC79A7",
}
COLORS = {
    "quiet": OKABE_ITO["black"],
    "avalanche": OKABE_ITO["vermillion"],
    "avalanche_shade": OKABE_ITO["orange"],
    "marginal": OKABE_ITO["blue"],
    "hypothesis": OKABE_ITO["skyblue"],
    "cluster": "#404040",
    "grain": "#D9D9D9",
    "fixed": "#8C8C8C",
    "critical_contact": OKABE_ITO["green"],
    "fail_in_cluster": OKABE_ITO["vermillion"],
    "fail_outside": OKABE_ITO["blue"],
    "gravity": OKABE_ITO["vermillion"],
    "fit": OKABE_ITO["black"],
    "guide": "#7F7F7F",
}
# several curves (P(s) windows, cluster sizes): distinct and colour-blind safe, in this order
CYCLE = [OKABE_ITO[k] for k in ("green", "blue", "vermillion", "black", "purple", "orange", "skyblue")]
MARKERS = ["+", "^", "s", "o", "D", "v", "x"]

SINGLE_COLUMN_IN = 3.4   # PRL single column width (inches)
DOUBLE_COLUMN_IN = 7.0

RC = {
    "figure.dpi": 100, "savefig.dpi": 300, "savefig.bbox": "tight", "savefig.pad_inches": 0.02,
    "font.size": 8, "axes.labelsize": 8, "axes.titlesize": 8, "legend.fontsize": 6.5,
    "xtick.labelsize": 7, "ytick.labelsize": 7, "axes.linewidth": 0.6,
    "lines.linewidth": 1.0, "lines.markersize": 3.5, "legend.frameon": False,
    "xtick.direction": "in", "ytick.direction": "in", "xtick.top": True, "ytick.right": True,
    "mathtext.fontset": "dejavusans", "image.cmap": "viridis",
    "svg.hashsalt": "tiltpile", "pdf.fonttype": 42,
}


def use() -> None:
    """Apply the style (Agg backend outside notebooks, the rcParams above, the colour cycle)."""
    import matplotlib
    if "ipykernel" not in os.environ.get("MPLBACKEND", "") and matplotlib.get_backend().lower() == "":
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from cycler import cycler
    plt.rcParams.update(RC)
    plt.rcParams["axes.prop_cycle"] = cycler(color=CYCLE)


def figure(nrows: int = 1, ncols: int = 1, height: float | None = None, width: float = SINGLE_COLUMN_IN,
           **kw):
    """``plt.subplots`` at single-column width (height default: golden ratio per row)."""
    import matplotlib.pyplot as plt
    use()
    if height is None:
        height = width / ncols * 0.75 * nrows
    return plt.subplots(nrows, ncols, figsize=(width, height), **kw)


def stacked_layout(rows_in, gaps_in, top_in: float, bottom_in: float, left: float = 0.15,
                   right: float = 0.97) -> tuple[float, dict]:
    """Figure height and ``gridspec_kw`` for rows of given heights (inches) separated by given
    gaps (inches), so that an aspect-locked pile picture fills its row without blank bands."""
    rows_in = [float(r) for r in rows_in]
    gap = float(np.mean(gaps_in)) if len(gaps_in) else 0.0
    h = top_in + sum(rows_in) + gap * (len(rows_in) - 1) + bottom_in
    return h, {"height_ratios": rows_in, "hspace": gap / float(np.mean(rows_in)),
               "top": 1.0 - top_in / h, "bottom": bottom_in / h, "left": left, "right": right}


def panel_label(ax, text: str, x: float = 0.02, y: float = 0.96) -> None:
    """An italic panel letter (a, b, ...) in the top-left corner, as in the paper."""
    ax.text(x, y, text, transform=ax.transAxes, ha="left", va="top", fontstyle="italic",
            fontweight="bold")


def draw_pile(ax, position, radius, facecolor, edgecolor="none", box_length: float | None = None,
              theta_deg: float | None = None, linewidth: float = 0.0) -> None:
    """Disks as circles in data units (x right, y up); gravity arrow when ``theta_deg`` is given.

    position (N, 2), radius (N,), facecolor a colour or (N,) list of colours.
    """
    from matplotlib.collections import EllipseCollection
    position = np.asarray(position, float)
    d = 2.0 * np.asarray(radius, float)
    ax.add_collection(EllipseCollection(d, d, np.zeros_like(d), units="xy", offsets=position,
                                        offset_transform=ax.transData, facecolors=facecolor,
                                        edgecolors=edgecolor, linewidths=linewidth))
    if box_length is None:
        ax.set_xlim(position[:, 0].min() - d.max(), position[:, 0].max() + d.max())
    else:
        ax.set_xlim(0.0, box_length)
    ax.set_ylim(position[:, 1].min() - d.max(), position[:, 1].max() + d.max())
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    if theta_deg is not None:
        draw_gravity(ax, theta_deg)


def draw_gravity(ax, theta_deg: float, where=(0.9, 0.85), length: float = 0.12) -> None:
    """Arrow along gravity, rotated by theta from the -y axis towards +x (the pile's frame)."""
    t = math.radians(theta_deg)
    g = np.array([math.sin(t), -math.cos(t)]) * length   # box frame: g = (sin, -cos), sim.scene
    x, y = where
    ax.annotate("", xy=(x + g[0] / 2, y + g[1] / 2), xytext=(x - g[0] / 2, y - g[1] / 2),
                xycoords="axes fraction", textcoords="axes fraction",
                arrowprops=dict(arrowstyle="-|>", color=COLORS["gravity"], lw=1.2))
    ax.text(x + 0.04, y, "g", transform=ax.transAxes, color=COLORS["gravity"], ha="left",
            va="center", fontstyle="italic")


def jsonable(x):
    """``x`` with numpy scalars and arrays as plain numbers and lists, NaN and inf as None (JSON)."""
    return _record_jsonable(x, nan_as_none=True)


#: The fields of an ensemble's ``cost`` (``ensemble_data.ensemble_cost``) that are facts of the
#: machine and the session rather than of the runs: the median wall seconds per run and how many
#: runs were timed whole (a resumed run is not). A figure document leaves them out, so that the
#: same runs give the same bytes on any machine and a build of a committed preset leaves the tree
#: as it was; each run's wall time stays in its run file and its record, where
#: ``tiltpile info`` and the reports read it (:mod:`tiltpile.report.wall`). The deterministic
#: costs (steps, sweeps, capped steps per run) stay.
WALL_CLOCK = ("runs_timed", "seconds_per_run")


def without_wall_clock(meta):
    """``meta`` with the :data:`WALL_CLOCK` fields of every ``cost`` mapping in it left out, at
    any depth (the preparation study's header holds one per ensemble); a copy, the rest as is."""
    if isinstance(meta, dict):
        return {k: ({f: x for f, x in v.items() if f not in WALL_CLOCK}
                    if k == "cost" and isinstance(v, dict) else without_wall_clock(v))
                for k, v in meta.items()}
    if isinstance(meta, (list, tuple)):
        return [without_wall_clock(v) for v in meta]
    return meta


def document(name: str, numbers: dict, meta: dict | None = None) -> dict:
    """A figure's JSON document, ``{"figure": name, **meta, "numbers": numbers}``, as plain JSON
    types (:func:`jsonable`), its header without the machine's wall times
    (:func:`without_wall_clock`)."""
    return {"figure": name, **jsonable(without_wall_clock(meta or {})), "numbers": jsonable(numbers)}


def save(fig, name: str, numbers: dict, figures_dir, meta: dict | None = None) -> dict[str, Path]:
    """Write ``figures_dir/name.pdf``, ``.png`` and ``.json`` (each to a temporary name of this
    process, synced, then renamed: :func:`tiltpile.outputs.replaced_whole`).

    The JSON is :func:`document`: ``{"figure": name, **meta, "numbers": numbers}`` with numpy
    scalars and arrays turned into plain numbers and lists, NaN and inf written as null, and no
    wall time in the header's ``cost`` (:data:`WALL_CLOCK`). Returns the three paths.
    """
    out = Path(figures_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {ext: out / f"{name}.{ext}" for ext in ("pdf", "png", "json")}
    for ext in ("pdf", "png"):
        kw = {"metadata": {"CreationDate": None}} if ext == "pdf" else {"metadata": {"Software": None}}
        with replaced_whole(paths[ext]) as tmp:
            fig.savefig(tmp, format=ext, **kw)
    write_json(paths["json"], document(name, numbers, meta))
    return paths


def write_json(path, doc) -> Path:
    """Write ``doc`` (plain JSON types) to ``path`` as the figures' JSON are written (indent 1,
    keys in their order, a final newline): to a temporary name of this process, synced, then
    renamed, so that the file is replaced whole or not at all."""
    path = Path(path)
    with replaced_whole(path) as tmp:
        tmp.write_text(json.dumps(doc, indent=1, sort_keys=False) + "\n")
    return path
