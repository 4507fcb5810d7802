"""Fig. 4: the critical clusters in the generalized isostaticity diagram (z, n_m).

Paper, Fig. 4: "Probability density of the position of the clusters in the generalized
isostaticity diagram, before the avalanche in black, and during the avalanche in red. The clusters
straddle the marginal stability line during the quiet period. The z-distribution of the remainder
of the system is shown below - note that since n_m = 0 for this subset, we have z_iso = 3."

Top: density of the per-cluster (z, n_m) of the clusters table, quiet frames (grey scale, a) and
avalanching frames (red, b), each with a colour bar (probability per unit z per unit n_m, log
scale), with the marginal line z = z_iso^gen = (d + 1) + 2 n_m / d (2D: z = 3 + n_m). Axes as the
paper's Fig. 2d: z across, n_m up. Each cluster is one sample (whatever its size). A cluster of s
grains has z in steps of 1/s and n_m in steps of 1/(2s); a plain histogram of values on these many
lattices shows comb stripes where they beat against the bins, so each cluster is spread over its
own lattice cell (:func:`tiltpile.analysis.stats.cell_density_2d`).
Bottom: density of ``z_rest`` (frames table: bulk non-rattlers in no cluster, so n_m = 0 and
z_iso = 3), quiet versus avalanching frames.

The distance to the marginal line is delta z_gen = z - 3 - n_m
(:func:`tiltpile.analysis.contacts.dz_gen`); the clusters table's own ``dz`` column is the paper's
z - 2 n_m / d = z - n_m (Fig. 6), which is delta z_gen + 3.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tiltpile.analysis import InsufficientDataError, dz_gen
from tiltpile.analysis.stats import cell_density_2d

from . import style
from .data import Reads

# the table columns the figure reads (from records, only these are checked)
READS = Reads("Fig. 4",
              frames=("z", "n_m", "z_rest", "avalanching"),
              clusters=("avalanching", "size", "z", "n_m"))

NAME = "fig4_cluster_isostaticity"

D = 2                    # dimension
Z_ISO_MU = D + 1         # isostatic z of mu = infinity frictional packings (paper Eq. 1)
ON_LINE_TOL = 1e-9       # |delta z_gen| below this counts as "on" the marginal line


def centred_edges(lo: float, hi: float, width: float) -> np.ndarray:
    """Bin edges of width ``width`` whose bin centres are lo, lo + width, ..., hi.

    Cluster z and n_m are rational numbers with small denominators (multiples of 1/s and 1/(2s)
    for a cluster of s grains), so the common values (2, 2.5, 3, ... and 0.5, 0.75, ...) must sit
    at bin centres, not on edges where rounding would split them between two bins.
    """
    n = int(round((hi - lo) / width)) + 1
    return lo - 0.5 * width + width * np.arange(n + 1)


def _summary(cl: pd.DataFrame) -> dict:
    """Means and position relative to the marginal line of a set of clusters (NaN when empty)."""
    if len(cl) == 0:
        return {"n": 0, "z_mean": np.nan, "n_m_mean": np.nan, "dz_gen_mean": np.nan,
                "frac_below": np.nan, "frac_on": np.nan, "frac_above": np.nan}
    g = dz_gen(cl["z"].to_numpy(float), cl["n_m"].to_numpy(float), D)
    return {"n": int(len(cl)), "z_mean": float(cl["z"].mean()), "n_m_mean": float(cl["n_m"].mean()),
            "dz_gen_mean": float(g.mean()),
            "frac_below": float(np.mean(g < -ON_LINE_TOL)),
            "frac_on": float(np.mean(np.abs(g) <= ON_LINE_TOL)),
            "frac_above": float(np.mean(g > ON_LINE_TOL))}


def compute(ens, z_range=(1.5, 5.0), nm_range=(0.5, 1.0), z_bin: float = 0.1,
            nm_bin: float = 0.05, z_rest_bin: float = 0.02, min_size: int = 1):
    """Densities of the clusters in (z, n_m), quiet versus avalanching, and of z_rest.

    ens: :class:`tiltpile.figures.data.Ensemble`. z_range, nm_range: centres of the first and last
    bins of the (z, n_m) histogram, z_bin, nm_bin their widths (:func:`centred_edges`);
    z_rest_bin: bin width of the z_rest histogram; min_size: only clusters of at least this many
    grains (1: all).

    numbers: for quiet (``quiet_*``) and avalanching (``avalanche_*``) clusters: n (clusters),
    z_mean, n_m_mean, dz_gen_mean (mean z - 3 - n_m), frac_below / frac_on / frac_above (fractions
    with delta z_gen < 0, = 0, > 0: below, on, above the marginal line); z_rest_mean_quiet,
    z_rest_mean_avalanche (mean over frames of z_rest), z_rest_frac_below_iso_quiet (fraction of
    quiet frames with z_rest < 3), frac_outside_range_quiet (clusters outside the histogram).
    Empty selections give NaN (n = 0).
    """
    cl = ens.clusters
    cl = cl[cl["size"] >= int(min_size)]
    av = cl["avalanching"].to_numpy(bool)
    groups = {"quiet": cl[~av], "avalanche": cl[av]}
    xe = centred_edges(z_range[0], z_range[1], z_bin)
    ye = centred_edges(nm_range[0], nm_range[1], nm_bin)
    numbers, dens = {}, {}
    for name, g in groups.items():
        for k, v in _summary(g).items():
            numbers[f"{name}_{k}"] = v
        try:
            size = g["size"].to_numpy(float)
            h, _ = cell_density_2d(g["z"], g["n_m"], 1.0 / size, 0.5 / size, xe, ye)
            dens[name] = h
        except InsufficientDataError:
            dens[name] = None
    q = groups["quiet"]
    inside = ((q["z"] >= xe[0]) & (q["z"] < xe[-1]) & (q["n_m"] >= ye[0]) & (q["n_m"] < ye[-1]))
    numbers["frac_outside_range_quiet"] = float(1.0 - inside.mean()) if len(q) else np.nan

    fr = ens.frames
    fav = fr["avalanching"].to_numpy(bool)
    zr = {"quiet": fr.loc[~fav, "z_rest"].to_numpy(float),
          "avalanche": fr.loc[fav, "z_rest"].to_numpy(float)}
    zr = {k: v[np.isfinite(v)] for k, v in zr.items()}
    allz = np.concatenate([zr["quiet"], zr["avalanche"]])
    rest = {}
    if allz.size:
        lo = np.floor(allz.min() / z_rest_bin) * z_rest_bin
        hi = np.ceil(allz.max() / z_rest_bin) * z_rest_bin
        edges = centred_edges(lo, hi, z_rest_bin)
        for k, v in zr.items():
            rest[k] = np.histogram(v, bins=edges, density=True)[0] if v.size else None
        rest["edges"] = edges
    numbers["z_rest_mean_quiet"] = float(zr["quiet"].mean()) if zr["quiet"].size else np.nan
    numbers["z_rest_mean_avalanche"] = (float(zr["avalanche"].mean()) if zr["avalanche"].size
                                        else np.nan)
    numbers["z_rest_frac_below_iso_quiet"] = (float(np.mean(zr["quiet"] < Z_ISO_MU))
                                              if zr["quiet"].size else np.nan)
    data = {"xedges": xe, "yedges": ye, "density": dens, "z_rest": rest, "min_size": int(min_size)}
    return numbers, data


def plot(data: dict, numbers: dict):
    """Top: (z, n_m) densities of quiet / avalanching clusters with the marginal line; bottom: z_rest."""
    from matplotlib.colors import LinearSegmentedColormap, LogNorm
    fig, axes = style.figure(2, 2, height=4.4, sharex="row", sharey="row",
                             gridspec_kw={"height_ratios": [2.0, 1.0]})
    gs = axes[1, 0].get_gridspec()
    for a in axes[1]:
        a.remove()
    bx = fig.add_subplot(gs[1, :])
    xe, ye = data["xedges"], data["yedges"]
    nm = np.array([ye[0], ye[-1]])
    for ax, key, label, letter in ((axes[0, 0], "quiet", "quiet", "a"),
                                   (axes[0, 1], "avalanche", "avalanching", "b")):
        h = data["density"][key]
        cmap = LinearSegmentedColormap.from_list(key, ["#F7F7F7", style.COLORS[key]])
        if h is not None and np.any(h > 0):
            pos = h[h > 0]
            mesh = ax.pcolormesh(xe, ye, np.ma.masked_less_equal(h, 0.0).T, cmap=cmap,
                                 shading="flat", rasterized=True,
                                 norm=LogNorm(vmin=max(pos.min(), pos.max() * 1e-4),
                                              vmax=pos.max()))
            cb = fig.colorbar(mesh, ax=ax, orientation="horizontal", location="bottom",
                              pad=0.28, fraction=0.06, aspect=25)
            cb.set_label(r"density per unit $z$ per unit $n_m$", fontsize=5.5)
            cb.ax.tick_params(labelsize=5, length=2)
        else:
            ax.text(0.5, 0.5, "no clusters", transform=ax.transAxes, ha="center", va="center")
        ax.plot(Z_ISO_MU + 2.0 * nm / D, nm, color=style.COLORS["marginal"], lw=1.2,
                label=r"$z = 3 + n_m$")
        ax.set_xlim(xe[0], xe[-1])
        ax.set_ylim(ye[0], ye[-1])
        ax.set_xlabel(r"cluster $z$")
        n = numbers[f"{key}_n"]
        title = f"{label}, {n} clusters"
        if n:
            title += (f"\n{100 * numbers[f'{key}_frac_below']:.0f}% below, "
                      f"{100 * numbers[f'{key}_frac_on']:.0f}% on the line")
        ax.set_title(title, fontsize=6.5, color=style.COLORS[key])
        style.panel_label(ax, letter)
    axes[0, 0].set_ylabel(r"cluster $n_m$")
    axes[0, 1].legend(loc="upper right", handlelength=1.2)

    rest = data["z_rest"]
    if rest:
        e = rest["edges"]
        for key, label in (("quiet", "quiet"), ("avalanche", "avalanching")):
            if rest.get(key) is not None:
                bx.stairs(rest[key], e, color=style.COLORS[key], label=label)
        bx.set_xlim(min(e[0], Z_ISO_MU - 0.05), max(e[-1], Z_ISO_MU + 0.05))
    bx.axvline(Z_ISO_MU, color=style.COLORS["marginal"], lw=1.2, label=r"$z_{iso} = 3$")
    bx.set_xlabel(r"$z$ of the rest of the system (bulk, no cluster: $n_m = 0$)")
    bx.set_ylabel("density")
    bx.legend(loc="upper left", bbox_to_anchor=(0.06, 1.0))
    style.panel_label(bx, "c")
    fig.tight_layout(h_pad=0.5, w_pad=0.3)
    return fig
