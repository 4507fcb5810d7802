"""Cluster sizes against the tilt: P(s) fits, xi and <S_max> in windows of theta - theta_m, and
delta z of the clusters against their size (paper Figs. 4 and 5).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from .. import checks as _ck
from .densities import log_int_edges
from .errors import InsufficientDataError
from .powerlaw import fit_power_law_cutoff


def _windows(fn: str, width, lo, hi) -> None:
    """Check windows of ``width`` > 0 tiling [lo, hi], lo <= hi, all finite."""
    _ck.real(fn, "width", width, lo=0, lo_open=True)
    _ck.real(fn, "lo", lo)
    _ck.real(fn, "hi", hi)
    if lo > hi:
        _ck.fail(fn, "lo", f"be <= hi ({hi})", repr(lo))


def window_edges(width: float = 0.5, lo: float = -15.0, hi: float = 0.0) -> np.ndarray:
    """Window edges hi, hi - width, ... down to >= lo, ascending (theta - theta_m, degrees)."""
    _windows("window_edges", width, lo, hi)
    n = int(np.floor((hi - lo) / width + 1e-9))
    return hi - width * np.arange(n, -1, -1)


def cluster_size_windows(clusters: pd.DataFrame, frames: pd.DataFrame, width: float = 0.5,
                         lo: float = -15.0, hi: float = 0.0, s_min: int = 1,
                         delta: float | None = None, min_samples: int = 50) -> pd.DataFrame:
    """P(s) fits and <S_max> in windows of theta - theta_m (paper Fig. 4 and its insets).

    clusters: per-cluster table (run, frame, size); frames: per-frame table (run, frame,
    theta_to_onset, avalanching, largest_cluster). Only quiet frames enter a window
    [left, right) of theta - theta_m; windows of ``width`` degrees tile [lo, hi).
    delta: hold the exponent fixed (e.g. 2.5) and fit xi only.

    Returns a DataFrame, one row per window: left, right, center, n_frames, n_clusters,
    mean_largest (<S_max> over the window's frames), delta, delta_err, xi, xi_err,
    fit_error (empty, or why the fit was refused: fewer than ``min_samples`` clusters), and
    fit_warning (empty, or the warnings of the fit: delta_err above ``MAX_DELTA_ERR``, xi at its
    bound). The fit's warnings are recorded there, one per window, not issued.
    """
    fn = "cluster_size_windows"
    _ck.table(fn, "clusters", clusters, ("run", "frame", "size"))
    _ck.table(fn, "frames", frames, ("run", "frame", "theta_to_onset", "avalanching",
                                     "largest_cluster"))
    _windows(fn, width, lo, hi)
    _ck.count(fn, "s_min", s_min, lo=1, floats_ok=True)
    _ck.real(fn, "delta", delta, none_ok=True)
    _ck.count(fn, "min_samples", min_samples, floats_ok=True)
    fr = frames[~frames["avalanching"].astype(bool) & np.isfinite(frames["theta_to_onset"])]
    fr = fr[["run", "frame", "theta_to_onset", "largest_cluster"]]
    cl = clusters[["run", "frame", "size"]].merge(fr[["run", "frame", "theta_to_onset"]],
                                                   on=["run", "frame"], how="inner")
    edges = window_edges(width, lo, hi)
    rows = []
    for a, b in zip(edges[:-1], edges[1:]):
        f = fr[(fr["theta_to_onset"] >= a) & (fr["theta_to_onset"] < b)]
        c = cl[(cl["theta_to_onset"] >= a) & (cl["theta_to_onset"] < b)]
        row = {"left": a, "right": b, "center": 0.5 * (a + b), "n_frames": len(f),
               "n_clusters": len(c), "mean_largest": f["largest_cluster"].mean() if len(f) else np.nan,
               "delta": np.nan, "delta_err": np.nan, "xi": np.nan, "xi_err": np.nan, "fit_error": "",
               "fit_warning": ""}
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                fit = fit_power_law_cutoff(c["size"].to_numpy(), s_min=s_min, delta=delta,
                                           min_samples=min_samples)
            row.update(delta=fit.delta, delta_err=fit.delta_err, xi=fit.xi, xi_err=fit.xi_err,
                       fit_warning="; ".join(str(w.message) for w in caught))
        except InsufficientDataError as exc:
            row["fit_error"] = str(exc)
        rows.append(row)
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------------------------
# delta z versus cluster size


def dz_by_size(clusters: pd.DataFrame, size_edges=None) -> pd.DataFrame:
    """<delta z>, min delta z and spread per cluster size (paper Fig. 5b).

    clusters: per-cluster table with size, z, n_m, dz. size_edges: None for one row per exact
    size, or integer bin edges [a, b). Returns DataFrame size_lo, size_hi (exclusive), n,
    dz_mean, dz_min, dz_std, z_mean, n_m_mean.
    """
    _ck.table("dz_by_size", "clusters", clusters, ("size", "z", "n_m", "dz"))
    if size_edges is not None:
        e = _ck.shaped("dz_by_size", "size_edges", size_edges, ("K",), finite=True)
        if e.size < 2 or not (np.diff(e) > 0).all():
            _ck.fail("dz_by_size", "size_edges", "be at least 2 increasing bin edges",
                     _ck.short(e.tolist()))
    s = clusters["size"].to_numpy()
    if size_edges is None:
        lo = s
        hi = s + 1
    else:
        e = np.asarray(size_edges)
        idx = np.searchsorted(e, s, side="right") - 1
        keep = (idx >= 0) & (idx < e.size - 1)
        clusters = clusters[keep]
        lo, hi = e[idx[keep]], e[idx[keep] + 1]
    g = clusters.assign(size_lo=lo, size_hi=hi).groupby(["size_lo", "size_hi"])
    out = g.agg(n=("dz", "size"), dz_mean=("dz", "mean"), dz_min=("dz", "min"),
                dz_std=("dz", "std"), z_mean=("z", "mean"), n_m_mean=("n_m", "mean"))
    return out.reset_index()


def parity_log_edges(s_max: int, bins_per_decade: int = 5) -> np.ndarray:
    """Integer size-bin edges [a, b) like :func:`log_int_edges`, with every edge after 1 even: size 1
    alone, then bins holding as many even as odd sizes ([2, 4), [4, 8), ...). Cluster delta z
    depends on the parity of the size (a critical contact inside a cluster counts for two of
    its grains), so bins mixing one odd and two even sizes and the next the reverse zig-zag from
    the binning alone."""
    _ck.count("parity_log_edges", "s_max", s_max, floats_ok=True)
    _ck.count("parity_log_edges", "bins_per_decade", bins_per_decade, lo=1, floats_ok=True)
    e = log_int_edges(s_max, bins_per_decade)
    top = int(e[-1])
    inner = e[(e > 1) & (e < top)]
    inner = np.unique(np.where(inner % 2 == 1, inner + 1, inner))
    inner = inner[inner < top]
    last = top + (top % 2 == 1)              # the last bin too holds whole pairs of sizes
    return np.unique(np.r_[1, inner, last]).astype(np.int64) if top > 1 else e


def dz_distribution(clusters: pd.DataFrame, size_lo: int, size_hi: int | None = None) -> pd.DataFrame:
    """Distribution of delta z for clusters with size_lo <= size < size_hi (paper Fig. 5a).

    For a cluster of s grains, z = sum z_i / s and n_m = sum m_i / (2 s), so delta z = z - n_m is
    a multiple of 1 / (2 s): the bins are centred on multiples of 1 / (2 size_lo) with that width,
    which respects this discreteness exactly for a single size; for a range of sizes each
    cluster is spread evenly over its own lattice cell (width 1 / (2 s)), so that the lattices
    of the different sizes leave no comb. Returns DataFrame center, count (fractional for a
    range of sizes), density (integrating to 1).
    """
    fn = "dz_distribution"
    _ck.table(fn, "clusters", clusters, ("size", "dz"))
    _ck.count(fn, "size_lo", size_lo, lo=1, floats_ok=True)
    if size_hi is not None:
        _ck.count(fn, "size_hi", size_hi, lo=size_lo + 1, floats_ok=True)
    size_hi = size_lo + 1 if size_hi is None else size_hi
    sel = clusters[(clusters["size"] >= size_lo) & (clusters["size"] < size_hi)]
    dz = sel["dz"].to_numpy(float)
    ok = np.isfinite(dz)
    dz, s = dz[ok], sel["size"].to_numpy(float)[ok]
    if dz.size == 0:
        return pd.DataFrame(columns=["center", "count", "density"])
    w = 1.0 / (2.0 * size_lo)
    if size_hi == size_lo + 1:           # one size: one lattice, exact counts
        q = np.round(dz / w).astype(np.int64)
        vals, count = np.unique(q, return_counts=True)
        return pd.DataFrame({"center": vals * w, "count": count.astype(float),
                             "density": count / (dz.size * w)})
    # several sizes: each cluster is spread evenly over its own lattice cell [dz -+ 1 / (4 s)],
    # so the lattices of different sizes do not beat against the bins
    half = 1.0 / (4.0 * s)
    k0 = int(np.floor((dz - half).min() / w - 0.5))
    k1 = int(np.ceil((dz + half).max() / w + 0.5))
    centers = w * np.arange(k0, k1 + 1)
    lo_e, hi_e = centers - w / 2, centers + w / 2
    over = np.clip(np.minimum(hi_e[None, :], (dz + half)[:, None])
                   - np.maximum(lo_e[None, :], (dz - half)[:, None]), 0.0, None)
    count = (over / (2 * half)[:, None]).sum(axis=0)
    keep = count > 1e-12
    return pd.DataFrame({"center": centers[keep], "count": count[keep],
                         "density": count[keep] / (dz.size * w)})
