"""Probability densities of the observables (paper Figs. 2a, 2b, 2d, 4, 5a): logarithmic bins
for continuous and integer quantities, 2D histograms, and cell densities of values that live on
per-sample lattices.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import checks as _ck
from .errors import InsufficientDataError


def log_binned_density(x, bins_per_decade: int = 10, xmin: float | None = None,
                       xmax: float | None = None) -> pd.DataFrame:
    """Probability density of a positive quantity on logarithmic bins.

    x: samples (any shape); non-finite values are dropped; values <= 0 cannot be placed on a log
    axis and are dropped too, but they stay in the normalisation (the density integrates to the
    fraction of samples that are > 0 and inside [xmin, xmax]). Edges: 10^(k / bins_per_decade)
    covering [xmin, xmax] (default: the positive data range).

    Returns a DataFrame with columns left, right, center (geometric), count, density
    (= count / (n_total * width)); ``df.attrs`` holds n_total and n_nonpositive.
    """
    fn = "log_binned_density"
    _ck.asarray(fn, "x", x)
    _ck.count(fn, "bins_per_decade", bins_per_decade, lo=1, floats_ok=True)
    _ck.real(fn, "xmin", xmin, lo=0, lo_open=True, none_ok=True)
    _ck.real(fn, "xmax", xmax, lo=0, lo_open=True, none_ok=True)
    if xmin is not None and xmax is not None and xmin > xmax:
        _ck.fail(fn, "xmin", f"be <= xmax ({xmax})", repr(xmin))
    x = np.asarray(x, dtype=float).ravel()
    x = x[np.isfinite(x)]
    n_total = x.size
    pos = x[x > 0]
    cols = ["left", "right", "center", "count", "density"]
    if pos.size == 0:
        df = pd.DataFrame(columns=cols)
        df.attrs.update(n_total=n_total, n_nonpositive=n_total)
        return df
    lo = np.log10(xmin if xmin is not None else pos.min())
    hi = np.log10(xmax if xmax is not None else pos.max())
    k0 = np.floor(lo * bins_per_decade)
    k1 = max(np.ceil(hi * bins_per_decade), k0 + 1)
    edges = 10.0 ** (np.arange(k0, k1 + 1) / bins_per_decade)
    count, _ = np.histogram(pos, bins=edges)
    width = np.diff(edges)
    df = pd.DataFrame({"left": edges[:-1], "right": edges[1:], "center": np.sqrt(edges[:-1] * edges[1:]),
                       "count": count, "density": count / (n_total * width)})
    df.attrs.update(n_total=n_total, n_nonpositive=int((x <= 0).sum()))
    return df


def log_int_edges(s_max: int, bins_per_decade: int = 5, s_min: int = 1) -> np.ndarray:
    """Integer bin edges [a, b) covering s_min..s_max, log-spaced: ceil(s_min 10^(k /
    bins_per_decade)) made distinct (each small size gets its own bin), the last edge s_max + 1."""
    _ck.count("log_int_edges", "s_max", s_max, floats_ok=True)
    _ck.count("log_int_edges", "bins_per_decade", bins_per_decade, lo=1, floats_ok=True)
    _ck.count("log_int_edges", "s_min", s_min, lo=1, floats_ok=True)
    top = int(max(s_max, s_min)) + 1
    k = np.arange(0, int(np.ceil(np.log10(top) * bins_per_decade)) + 2)
    edges = np.unique(np.ceil(s_min * 10.0 ** (k / bins_per_decade)).astype(np.int64))
    return np.append(edges[edges < top], top)


def discrete_log_binned_density(s, bins_per_decade: int = 5, s_min: int = 1) -> pd.DataFrame:
    """Probability mass per integer of an integer quantity (cluster sizes), on log bins.

    Bins are integer ranges [a, b) from :func:`log_int_edges`; density = count / (n * (b - a)), i.e. the mean
    P(s) over the integers of the bin. s >= s_min only. Returns DataFrame left, right (exclusive),
    center (geometric mean of the bin's integers' range), count, density.
    """
    fn = "discrete_log_binned_density"
    _ck.count(fn, "bins_per_decade", bins_per_decade, lo=1, floats_ok=True)
    _ck.count(fn, "s_min", s_min, lo=1, floats_ok=True)
    a = _ck.asarray(fn, "s", s)
    if a.dtype.kind == "f" and a.size:
        big = a[a >= s_min]
        if (big != np.round(big)).any():
            _ck.fail(fn, "s", "hold integers (sizes)", f"{big[big != np.round(big)][0]}")
    s = np.asarray(s).ravel()
    s = s[s >= s_min].astype(np.int64)
    cols = ["left", "right", "center", "count", "density"]
    if s.size == 0:
        return pd.DataFrame(columns=cols)
    edges = log_int_edges(int(s.max()), bins_per_decade, s_min)
    count, _ = np.histogram(s, bins=edges)
    width = np.diff(edges)
    return pd.DataFrame({"left": edges[:-1], "right": edges[1:],
                         "center": np.sqrt(edges[:-1] * (edges[1:] - 1.0)),
                         "count": count, "density": count / (s.size * width)})


def density_2d(x, y, bins=(40, 40), range=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two-dimensional probability density, e.g. of (z, n_m) (paper Figs. 2d, 4).

    x, y: samples (NaN pairs dropped); bins, range as in numpy.histogram2d.
    Returns (H (nx, ny) density integrating to 1, xedges, yedges).
    """
    _ck.asarray("density_2d", "x", x)
    _ck.asarray("density_2d", "y", y)
    if np.size(x) != np.size(y):
        _ck.fail("density_2d", "y", f"have as many samples as x ({np.size(x)})", str(np.size(y)))
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        raise InsufficientDataError("density_2d: no finite (x, y) samples")
    h, xe, ye = np.histogram2d(x[ok], y[ok], bins=bins, range=range, density=True)
    return h, xe, ye


def _cell_overlap(x, w, edges) -> np.ndarray:
    """(n, nbins) fraction of each interval [x - w/2, x + w/2] inside each bin of ``edges``
    (w = 0: the bin holding x, as in numpy.histogram, last edge included)."""
    x = np.asarray(x, float)[:, None]
    w = np.asarray(w, float)[:, None]
    lo, hi = edges[None, :-1], edges[None, 1:]
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.clip(np.minimum(hi, x + w / 2) - np.maximum(lo, x - w / 2), 0.0, None) / w
    point = (w[:, 0] <= 0)
    if point.any():
        idx = np.clip(np.searchsorted(edges, x[point, 0], side="right") - 1, 0, edges.size - 2)
        inside = (x[point, 0] >= edges[0]) & (x[point, 0] <= edges[-1])
        frac[point] = 0.0
        frac[np.flatnonzero(point)[inside], idx[inside]] = 1.0
    return frac


def _edges(fn: str, name: str, e) -> None:
    """Check bin edges: one-dimensional, at least 2, finite, increasing."""
    a = _ck.shaped(fn, name, e, ("K",), finite=True)
    if a.size < 2 or not (np.diff(a) > 0).all():
        _ck.fail(fn, name, "be at least 2 increasing bin edges", _ck.short(a.tolist()))


def cell_density_2d(x, y, wx, wy, xedges, yedges) -> tuple[np.ndarray, float]:
    """Two-dimensional probability density of samples known only to within their lattice cells.

    Sample i is spread evenly over the rectangle [x_i -+ wx_i / 2] x [y_i -+ wy_i / 2] (its
    lattice cell: for a cluster of s grains, z comes in steps of 1/s and n_m in steps of 1/(2s)),
    and the rectangles are binned on (xedges, yedges). A plain histogram of values on lattices
    of many different spacings shows comb stripes where the lattices beat against the bins; the
    spread density has none and still integrates to the fraction of the samples inside the
    edges. NaN samples are dropped. Returns (H (nx, ny) density over all finite samples,
    fraction of the mass outside the edges).
    """
    fn = "cell_density_2d"
    k = np.size(_ck.asarray(fn, "x", x))
    for name, v in (("y", y), ("wx", wx), ("wy", wy)):
        if np.size(_ck.asarray(fn, name, v)) != k:
            _ck.fail(fn, name, f"have as many samples as x ({k})", str(np.size(v)))
        if name != "y":
            w = np.asarray(v, dtype=float)
            if (w < 0).any():
                _ck.fail(fn, name, "be >= 0 (cell widths)", str(w[w < 0][0]))
    for name, e in (("xedges", xedges), ("yedges", yedges)):
        _edges(fn, name, e)
    x, y, wx, wy = (np.asarray(v, dtype=float).ravel() for v in (x, y, wx, wy))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(wx) & np.isfinite(wy)
    if not ok.any():
        raise InsufficientDataError("cell_density_2d: no finite samples")
    xe, ye = np.asarray(xedges, float), np.asarray(yedges, float)
    h = np.zeros((xe.size - 1, ye.size - 1))
    idx = np.flatnonzero(ok)
    for start in range(0, idx.size, 20000):          # bounded memory
        k = idx[start:start + 20000]
        h += _cell_overlap(x[k], wx[k], xe).T @ _cell_overlap(y[k], wy[k], ye)
    inside = h.sum() / idx.size
    area = np.diff(xe)[:, None] * np.diff(ye)[None, :]
    return h / (idx.size * area), float(1.0 - inside)
