"""Ensemble statistics of the per-frame and per-cluster observables.

* :func:`log_binned_density`, :func:`discrete_log_binned_density`, :func:`density_2d` --
  probability densities (paper Figs. 2a, 2b, 2d, 4, 5a).
* :func:`fit_power_law_cutoff` -- maximum-likelihood fit of the discrete cluster-size law
  P(s) = s^-delta exp(-s / xi) / Z, s >= s_min (paper Eq. 3, Fig. 4), with Fisher-information
  uncertainties; :func:`sample_power_law_cutoff` draws from it.
* :func:`cluster_size_windows` -- P(s) fits, xi and <S_max> in windows of theta - theta_m.
* :func:`correlation_function` -- C(tau) between S_m(k) and N^f(k + tau) over quiet frames
  (paper Eq. 2); :func:`failure_enhancement` after cluster-size peaks.
* :func:`dz_by_size`, :func:`dz_distribution` -- delta z of clusters versus their size (Fig. 5).
* :func:`power_law_departure`, :func:`ke_threshold` -- where the kinetic-energy density leaves the
  power law of the quiet frames (Fig. 2a).
* :func:`lost_fraction_edges`, :func:`bimodality` -- the lost-fraction density on bins that respect
  the integer counts, and how clearly it splits into two populations (Fig. 2b).
* :func:`bootstrap_ci` -- confidence intervals by resampling runs (ensemble means of few runs).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import integrate, optimize


class InsufficientDataError(ValueError):
    """Too few samples for a meaningful estimate (the message says how many and how many needed)."""


class PoorFitWarning(RuntimeWarning):
    """A fit ran but its result is not determined by the data (the message says why)."""


# Largest one-sigma error of a free delta for which fit_power_law_cutoff stays silent. Measured
# (20 samples of P(s) with delta = 2, fitted freely; the Fisher error agrees with the spread of
# the estimates): delta_err ~ 1.3 / 0.73 / 0.52 / 0.37 / 0.25 at n = 20 / 50 / 100 / 200 / 500
# for xi = 5, and 0.77 / 0.38 / 0.27 / 0.19 at n = 20 / 50 / 100 / 200 for xi = 20. An exponent
# known to +-0.5 cannot tell the paper's delta from its neighbours, so past that the fit warns.
MAX_DELTA_ERR = 0.5


# ----------------------------------------------------------------------------------------------
# densities


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


# ----------------------------------------------------------------------------------------------
# P(s) = s^-delta exp(-s/xi) / Z  for integer s >= s_min


_HEAD = 2000          # terms summed exactly; the rest of the series by a midpoint integral


def _series(delta: float, lam: float, s_min: int, powers=((0, 0),)) -> np.ndarray:
    """sum_{s >= s_min} s^p (log s)^q s^-delta e^{-lam s} for each (p, q) in powers.

    Exact sum for s < s_min + _HEAD, plus the Euler-Maclaurin midpoint integral
    int_{s_min + _HEAD - 1/2}^inf of the same function for the rest (relative error ~1e-10).
    """
    s = np.arange(s_min, s_min + _HEAD, dtype=float)
    ls = np.log(s)
    w = np.exp(-delta * ls - lam * s)
    out = np.empty(len(powers))
    a = s_min + _HEAD - 0.5
    for n, (p, q) in enumerate(powers):
        head = np.sum(w * s ** p * ls ** q)
        tail = 0.0
        if lam * (a - s_min) < 80.0:     # else tail / head < e^-80 * poly(a): negligible
            def f(t, p=p, q=q):
                return np.exp((p - delta) * np.log(t) - lam * t) * np.log(t) ** q
            tail = integrate.quad(f, a, np.inf, limit=200, epsabs=0.0, epsrel=1e-10)[0]
        out[n] = head + tail
    return out


@dataclass(frozen=True)
class PowerLawCutoffFit:
    """Maximum-likelihood estimate of P(s) = s^-delta exp(-s/xi) / Z(delta, xi), s >= s_min.

    delta, xi: estimates; delta_err, xi_err: one-sigma errors from the inverse Fisher information
    (xi_err by the delta method, xi_err = lambda_err * xi^2 with lambda = 1/xi); cov: (2, 2)
    covariance of (delta, lambda) (delta row/column zero when delta was held fixed); n: number of
    samples >= s_min; loglik: maximum log-likelihood; delta_fixed: whether delta was held fixed.
    """

    delta: float
    xi: float
    delta_err: float
    xi_err: float
    cov: np.ndarray
    n: int
    s_min: int
    loglik: float
    delta_fixed: bool

    def pmf(self, s) -> np.ndarray:
        """Fitted P(s) for integer s >= s_min (0 below s_min)."""
        s = np.asarray(s, dtype=float)
        z = _series(self.delta, 1.0 / self.xi, self.s_min)[0]
        with np.errstate(divide="ignore"):
            p = np.exp(-self.delta * np.log(s) - s / self.xi) / z
        return np.where(s >= self.s_min, p, 0.0)


def fit_power_law_cutoff(s, s_min: int = 1, delta: float | None = None, min_samples: int = 50,
                         xi_bounds=(1e-2, 1e7), delta_bounds=(-5.0, 10.0),
                         max_delta_err: float | None = MAX_DELTA_ERR) -> PowerLawCutoffFit:
    """Fit the discrete law P(s) = s^-delta exp(-s/xi) / Z, s = s_min, s_min + 1, ... (paper Eq. 3).

    Maximises the exact discrete log-likelihood
    l(delta, lambda) = -delta sum log s - lambda sum s - n log Z(delta, lambda), lambda = 1/xi,
    with Z = sum_{s >= s_min} s^-delta e^{-lambda s}; the model is an exponential family, so the
    Fisher information is n Cov_model(log s, s), which gives the error bars.
    Pass ``delta`` to hold it fixed and fit xi alone (as the paper does, delta = 2.5).

    s: cluster sizes (integers; values < s_min are ignored). Raises InsufficientDataError when
    fewer than ``min_samples`` sizes are >= s_min or when they take fewer than 3 distinct values
    (2 with delta fixed): the likelihood then has no finite maximum. Warns (``PoorFitWarning``)
    when a free delta comes out with an error above ``max_delta_err`` (default ``MAX_DELTA_ERR`` =
    0.5; None: never): ``min_samples`` = 50 is the least that can be fitted, but a short cutoff
    (xi ~ 5) needs 100-200 clusters to pin delta to +-0.5. Warns (RuntimeWarning) when xi ends at
    its bound.
    """
    s = np.asarray(s).ravel()
    s = s[np.isfinite(s)]
    if np.any(s != np.round(s)):
        raise ValueError("fit_power_law_cutoff: sizes must be integers")
    s = s[s >= s_min].astype(float)
    n = s.size
    distinct = np.unique(s).size
    need_distinct = 2 if delta is not None else 3
    if n < min_samples or distinct < need_distinct:
        raise InsufficientDataError(
            f"fit_power_law_cutoff: only {n} sizes >= s_min={s_min} ({distinct} distinct values); "
            f"need at least {min_samples} samples and {need_distinct} distinct values")
    mean_log = np.log(s).mean()
    mean_s = s.mean()
    u_lo, u_hi = np.log(xi_bounds[0]), np.log(xi_bounds[1])

    def nll(params):
        d, u = params
        lam = np.exp(-u)
        z, e_log, e_s = _series(d, lam, s_min, ((0, 0), (0, 1), (1, 0)))
        e_log, e_s = e_log / z, e_s / z
        f = d * mean_log + lam * mean_s + np.log(z)
        grad_d = mean_log - e_log
        grad_lam = mean_s - e_s
        return f, np.array([grad_d, -lam * grad_lam])

    if delta is None:
        # -l is convex in the natural parameters (delta, lambda) (log Z is a cumulant generating
        # function), so the maximum is unique and one start suffices.
        x0 = np.array([2.0, np.log(max(mean_s, 1.0))])
        best = optimize.minimize(nll, x0, jac=True, method="L-BFGS-B",
                                 bounds=[delta_bounds, (u_lo, u_hi)])
        d_hat, u_hat = best.x
        fun = best.fun
    else:
        def nll1(u):
            f, g = nll((delta, u[0]))
            return f, g[1:]
        best = optimize.minimize(nll1, np.array([np.log(max(mean_s, 1.0))]), jac=True,
                                 method="L-BFGS-B", bounds=[(u_lo, u_hi)])
        d_hat, u_hat, fun = float(delta), best.x[0], best.fun
    lam = np.exp(-u_hat)
    xi = 1.0 / lam
    if not (u_lo + 1e-6 < u_hat < u_hi - 1e-6):
        warnings.warn(f"fit_power_law_cutoff: xi = {xi:.3g} is at its bound {xi_bounds}; "
                      "the data do not constrain the cutoff", RuntimeWarning, stacklevel=2)
    z, m1, m2, m11, m22, m12 = _series(d_hat, lam, s_min,
                                       ((0, 0), (0, 1), (1, 0), (0, 2), (2, 0), (1, 1)))
    e_l, e_s = m1 / z, m2 / z
    var_l = m11 / z - e_l ** 2
    var_s = m22 / z - e_s ** 2
    cov_ls = m12 / z - e_l * e_s
    if delta is None:
        info = n * np.array([[var_l, cov_ls], [cov_ls, var_s]])
        try:
            cov = np.linalg.inv(info)
        except np.linalg.LinAlgError:
            cov = np.full((2, 2), np.nan)
    else:
        cov = np.zeros((2, 2))
        cov[1, 1] = 1.0 / (n * var_s) if var_s > 0 else np.nan
    d_err = float(np.sqrt(cov[0, 0])) if delta is None else 0.0
    if delta is None and max_delta_err is not None and not d_err <= max_delta_err:
        warnings.warn(f"fit_power_law_cutoff: delta = {d_hat:.2f} +- {d_err:.2f} from {n} sizes: the "
                      f"error exceeds max_delta_err = {max_delta_err:g}, the data do not determine "
                      "the exponent (more clusters, or hold delta fixed)", PoorFitWarning,
                      stacklevel=2)
    xi_err = float(np.sqrt(cov[1, 1]) * xi * xi)
    return PowerLawCutoffFit(delta=float(d_hat), xi=float(xi), delta_err=d_err, xi_err=xi_err,
                             cov=cov, n=int(n), s_min=int(s_min), loglik=float(-n * fun),
                             delta_fixed=delta is not None)


def sample_power_law_cutoff(delta: float, xi: float, size: int, s_min: int = 1,
                            rng: np.random.Generator | int | None = None,
                            s_max: int | None = None) -> np.ndarray:
    """Draw integer sizes from P(s) = s^-delta exp(-s/xi) / Z, s >= s_min.

    Inverse-CDF sampling on s_min..s_max, with s_max (default s_min + 50 xi + 1000) chosen so the
    truncated mass is negligible (< e^-50 of the exponential factor). Returns (size,) int64.
    """
    rng = np.random.default_rng(rng)
    if s_max is None:
        s_max = int(s_min + 50 * xi + 1000)
    s = np.arange(s_min, s_max + 1, dtype=float)
    logw = -delta * np.log(s) - s / xi
    w = np.exp(logw - logw.max())
    cdf = np.cumsum(w)
    cdf /= cdf[-1]
    return (s_min + np.searchsorted(cdf, rng.random(size), side="right")).astype(np.int64)


# ----------------------------------------------------------------------------------------------
# windows in theta - theta_m


def window_edges(width: float = 0.5, lo: float = -15.0, hi: float = 0.0) -> np.ndarray:
    """Window edges hi, hi - width, ... down to >= lo, ascending (theta - theta_m, degrees)."""
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
# C(tau) and failure enhancement (quiet frames only)


def _period_labels(quiet: np.ndarray, period: np.ndarray | None) -> np.ndarray:
    """Period id per frame: given, or the maximal stretches of equal ``quiet`` value."""
    quiet = np.asarray(quiet, dtype=bool)
    if period is not None:
        return np.asarray(period)
    change = np.ones(quiet.size, dtype=bool)
    change[1:] = quiet[1:] != quiet[:-1]
    return np.cumsum(change)


def _lag_pairs(quiet: np.ndarray, period: np.ndarray, tau: int) -> np.ndarray:
    """Frames k such that k and k + tau are both quiet and in the same period."""
    nf = quiet.size
    k = np.arange(max(0, -tau), min(nf, nf - tau))
    ok = quiet[k] & quiet[k + tau] & (period[k] == period[k + tau])
    return k[ok]


def correlation_function(a, b, quiet, taus=range(-10, 11), period=None,
                         min_pairs: int = 3) -> pd.DataFrame:
    """C(tau), paper Eq. (2): correlation of a(k) (S_m) with b(k + tau) (N^f) over quiet frames.

        C(tau) = sum_k (a_k - <a>)(b_{k+tau} - <b>) / (n_tau sqrt(Var a Var b))

    where the sum runs over the n_tau frames k such that k and k + tau both lie in the same
    quiet period, and the means and variances are taken over that same set of frames (<a> over
    the k, <b> over the k + tau). (Eq. 2 as printed omits the 1/n_tau that makes C a correlation
    coefficient in [-1, 1]; it is included here.)

    a, b, quiet: (F,) arrays (quiet bool); period: (F,) period ids (default: stretches of equal
    ``quiet``; for several runs concatenated pass ids unique per run and period). Non-finite
    values of a or b drop the pair. Returns DataFrame tau, C, n_pairs (C NaN below min_pairs or
    for a constant series).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    quiet = np.asarray(quiet, dtype=bool)
    per = _period_labels(quiet, period)
    rows = []
    for tau in taus:
        k = _lag_pairs(quiet, per, int(tau))
        x, y = a[k], b[k + int(tau)]
        ok = np.isfinite(x) & np.isfinite(y)
        x, y = x[ok], y[ok]
        c = np.nan
        if x.size >= min_pairs:
            sx, sy = x.std(), y.std()
            if sx > 0 and sy > 0:
                c = float(np.mean((x - x.mean()) * (y - y.mean())) / (sx * sy))
        rows.append({"tau": int(tau), "C": c, "n_pairs": int(x.size)})
    return pd.DataFrame(rows)


def ensemble_periods(frames: pd.DataFrame) -> np.ndarray:
    """Period ids unique across runs for a per-frame table sorted by (run, frame)."""
    return frames.groupby(["run", "period"], sort=False).ngroup().to_numpy()


def correlation_function_ensemble(frames: pd.DataFrame, a: str = "largest_cluster",
                                  b: str = "n_lost", taus=range(-10, 11)) -> pd.DataFrame:
    """C(tau) of :func:`correlation_function` pooled over all runs of a per-frame table.

    frames needs columns run, frame, period, avalanching and the two named columns. Pairs never
    straddle two runs or two periods; means and variances are over the pooled pairs.
    """
    f = frames.sort_values(["run", "frame"])
    return correlation_function(_column(f, a), _column(f, b), ~f["avalanching"].to_numpy(bool),
                                taus, period=ensemble_periods(f))


# per-frame columns counted forward, from frame k to k + 1: undefined at a run's last frame,
# where observables.py writes lost_fraction = NaN and -1 in the integer counts
FORWARD_COLUMNS = ("n_lost", "lost_fraction", "n_failing", "n_failing_in_cluster",
                   "failing_in_cluster_fraction")


def _column(frames: pd.DataFrame, name: str) -> np.ndarray:
    """A per-frame column as float; a forward column is NaN where it is undefined (the last frame
    of each run, lost_fraction NaN), so the -1 placeholder never enters a mean or a correlation."""
    x = frames[name].to_numpy(float).copy()
    if name in FORWARD_COLUMNS and "lost_fraction" in frames:
        x[~np.isfinite(frames["lost_fraction"].to_numpy(float))] = np.nan
    return x


def cluster_peaks(s_max, quiet, period=None, threshold_sigma: float = 1.0) -> np.ndarray:
    """Frames where the largest cluster size peaks during a quiet period.

    A peak is a quiet frame k whose neighbours k - 1 and k + 1 are in the same quiet period, with
    S(k) > S(k - 1), S(k) >= S(k + 1), and S(k) > mean + threshold_sigma * std of S over the quiet
    frames. Returns the frame indices (int64).
    """
    s = np.asarray(s_max, dtype=float)
    quiet = np.asarray(quiet, dtype=bool)
    per = _period_labels(quiet, period)
    if s.size < 3:
        return np.zeros(0, dtype=np.int64)
    k = np.arange(1, s.size - 1)
    inner = quiet[k] & quiet[k - 1] & quiet[k + 1] & (per[k] == per[k - 1]) & (per[k] == per[k + 1])
    sq = s[quiet & np.isfinite(s)]
    thr = sq.mean() + threshold_sigma * sq.std() if sq.size else np.inf
    peak = inner & (s[k] > s[k - 1]) & (s[k] >= s[k + 1]) & (s[k] > thr)
    return k[peak]


def failure_enhancement(s_max, n_fail, quiet, taus=range(0, 6), period=None,
                        threshold_sigma: float = 1.0) -> pd.DataFrame:
    """Failure rate after peaks of the largest cluster, relative to the quiet-period mean.

    enhancement(tau) = <N^f(k + tau)>_{k in peaks, k + tau in the same quiet period}
                       / <N^f>_{quiet frames} - 1
    (the paper: "just after the cluster size peaks, the failure rate is enhanced by about 40%").
    Peaks from :func:`cluster_peaks`. Returns DataFrame tau, enhancement, n_peaks.
    """
    nf = np.asarray(n_fail, dtype=float)
    quiet = np.asarray(quiet, dtype=bool)
    per = _period_labels(quiet, period)
    peaks = cluster_peaks(s_max, quiet, per, threshold_sigma)
    base = np.nanmean(nf[quiet]) if quiet.any() else np.nan
    rows = []
    for tau in taus:
        k = peaks + int(tau)
        ok = (k >= 0) & (k < nf.size)
        k, p = k[ok], peaks[ok]
        ok = quiet[k] & (per[k] == per[p]) & np.isfinite(nf[k])
        m = nf[k[ok]].mean() if ok.any() else np.nan
        rows.append({"tau": int(tau), "enhancement": m / base - 1.0 if base > 0 else np.nan,
                     "n_peaks": int(ok.sum())})
    return pd.DataFrame(rows)


def failure_enhancement_ensemble(frames: pd.DataFrame, a: str = "largest_cluster",
                                 b: str = "n_lost", taus=range(0, 6),
                                 threshold_sigma: float = 1.0) -> pd.DataFrame:
    """:func:`failure_enhancement` pooled over runs (peak threshold per run)."""
    parts = []
    for _, g in frames.sort_values(["run", "frame"]).groupby("run", sort=False):
        quiet = ~g["avalanching"].to_numpy(bool)
        per = g["period"].to_numpy()
        s = _column(g, a)
        nf = _column(g, b)
        peaks = cluster_peaks(s, quiet, per, threshold_sigma)
        base_sum, base_n = np.nansum(nf[quiet]), int(np.isfinite(nf[quiet]).sum())
        for tau in taus:
            k = peaks + int(tau)
            ok = (k >= 0) & (k < nf.size)
            k, p = k[ok], peaks[ok]
            ok = quiet[k] & (per[k] == per[p]) & np.isfinite(nf[k])
            parts.append((int(tau), nf[k[ok]].sum(), int(ok.sum()), base_sum, base_n))
    df = pd.DataFrame(parts, columns=["tau", "sum", "n", "base_sum", "base_n"])
    rows = []
    for tau in taus:
        t = df[df["tau"] == int(tau)]
        base = t["base_sum"].sum() / t["base_n"].sum() if t["base_n"].sum() else np.nan
        m = t["sum"].sum() / t["n"].sum() if t["n"].sum() else np.nan
        rows.append({"tau": int(tau), "enhancement": m / base - 1.0 if base > 0 else np.nan,
                     "n_peaks": int(t["n"].sum())})
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------------------------
# delta z versus cluster size


def dz_by_size(clusters: pd.DataFrame, size_edges=None) -> pd.DataFrame:
    """<delta z>, min delta z and spread per cluster size (paper Fig. 5b).

    clusters: per-cluster table with size, z, n_m, dz. size_edges: None for one row per exact
    size, or integer bin edges [a, b). Returns DataFrame size_lo, size_hi (exclusive), n,
    dz_mean, dz_min, dz_std, z_mean, n_m_mean.
    """
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


# ----------------------------------------------------------------------------------------------
# kinetic-energy threshold (Fig. 2a)


def power_law_departure(density: pd.DataFrame, fit_lo: float, fit_hi: float,
                        factor: float = 2.0, n_consecutive: int = 2,
                        min_count: int = 3) -> dict:
    """Fit a power law to part of a log-binned density and find where the density leaves it.

    density: a :func:`log_binned_density` table (left, right, center, count, density). The fit:
    least squares of log10(density) on log10(center) over the bins with fit_lo <= center <= fit_hi
    and count >= min_count, weights sqrt(count) (Poisson error of log P). The departure: the first
    bin with center > fit_hi such that it and the next ``n_consecutive - 1`` bins (fewer at the end
    of the table) all differ from the fit by more than ``factor`` (|log10 ratio| > log10 factor;
    empty bins always differ).

    Returns dict slope, intercept (log10 P = intercept + slope log10 x), n_fit_bins, fit_lo,
    fit_hi, threshold (left edge of the departing bin; NaN if none or if fewer than 2 bins were
    fitted), threshold_center.
    """
    out = {"slope": np.nan, "intercept": np.nan, "n_fit_bins": 0, "fit_lo": float(fit_lo),
           "fit_hi": float(fit_hi), "threshold": np.nan, "threshold_center": np.nan}
    if len(density) == 0 or not (np.isfinite(fit_lo) and np.isfinite(fit_hi)):
        return out
    c = density["center"].to_numpy(float)
    n = density["count"].to_numpy(float)
    p = density["density"].to_numpy(float)
    fit = (c >= fit_lo) & (c <= fit_hi) & (n >= min_count)
    out["n_fit_bins"] = int(fit.sum())
    if fit.sum() < 2:
        return out
    slope, intercept = np.polyfit(np.log10(c[fit]), np.log10(p[fit]), 1, w=np.sqrt(n[fit]))
    out.update(slope=float(slope), intercept=float(intercept))
    with np.errstate(divide="ignore"):
        off = np.abs(np.log10(p) - (intercept + slope * np.log10(c))) > np.log10(factor)
    off |= n == 0
    above = np.flatnonzero(c > fit_hi)
    for i in above:
        j = min(i + max(1, int(n_consecutive)), c.size)
        if off[i:j].all():
            out.update(threshold=float(density["left"].iloc[i]), threshold_center=float(c[i]))
            break
    return out


def ke_threshold(frames: pd.DataFrame, ke_column: str = "ke_trans", bins_per_decade: int = 5,
                 fit_quantiles=(0.3, 0.8), factor: float = 2.0,
                 n_consecutive: int = 2) -> tuple[dict, pd.DataFrame]:
    """The kinetic energy per grain where its density leaves the quiet power law (paper Fig. 2a).

    frames: per-frame table with ``ke_column`` and ``avalanching``. The density of the energy of
    all frames is log-binned (:func:`log_binned_density`); a power law is fitted between the
    ``fit_quantiles`` of the quiet frames' energies (default 30% and 80%: above the rest peak of the
    freshly deposited pile, below the frames just before failure) and the threshold is where the
    density departs from it (:func:`power_law_departure`). Returns (the departure dict, the density).
    """
    ke = frames[ke_column].to_numpy(float)
    av = frames["avalanching"].to_numpy(bool)
    dens = log_binned_density(ke, bins_per_decade)
    kq = ke[~av & np.isfinite(ke) & (ke > 0)]
    lo, hi = (np.quantile(kq, fit_quantiles) if kq.size else (np.nan, np.nan))
    return power_law_departure(dens, lo, hi, factor, n_consecutive), dens


# ----------------------------------------------------------------------------------------------
# the lost-fraction density and its two populations (Fig. 2b)


def fd_bins_per_decade(x, lo: int = 3, hi: int = 20) -> int:
    """Bins per decade for positive samples x by the Freedman-Diaconis rule on log10 x
    (width 2 IQR n^(-1/3)), clipped to [lo, hi]; ``lo`` when the IQR vanishes."""
    y = np.log10(np.asarray(x, dtype=float)[np.isfinite(x) & (np.asarray(x, dtype=float) > 0)])
    if y.size < 4:
        return int(lo)
    iqr = np.subtract(*np.percentile(y, [75, 25]))
    if iqr <= 0:
        return int(lo)
    return int(np.clip(round(1.0 / (2.0 * iqr * y.size ** (-1.0 / 3.0))), lo, hi))


def lost_fraction_edges(n_lost, n_active, bins_per_decade: int | None = None) -> np.ndarray:
    """Bin edges for the fraction of contacts lost between frames that respect its integer counts.

    A frame losing k of its C contacts has lost fraction k / C. At small k consecutive values are
    further apart on a log axis than any sensible bin, so plain log bins alternate between empty
    and full (or several counts share a bin by accident of the edges). Here the edges are set in
    contacts, on half-integers k - 1/2 (each bin holds whole counts; the small counts each alone
    in their bin), widening geometrically by 10^(1 / bins_per_decade) once the integers are that
    close on a log axis, and divided by the median C.
    bins_per_decade: None for :func:`fd_bins_per_decade` of the positive fractions. n_lost,
    n_active: per frame (frames with n_lost <= 0 or non-finite values are ignored). Returns
    ascending edges (fractions) covering the positive fractions.
    """
    k = np.asarray(n_lost, dtype=float)
    c = np.asarray(n_active, dtype=float)
    ok = np.isfinite(k) & np.isfinite(c) & (k > 0) & (c > 0)
    if not ok.any():
        return np.zeros(0)
    k, c = k[ok], c[ok]
    x = k / c
    bpd = fd_bins_per_decade(x) if bins_per_decade is None else int(bins_per_decade)
    c_med = float(np.median(c))
    top = float(x.max() * c_med) + 1.0          # in contacts, past the largest loss
    step = 10.0 ** (1.0 / bpd)
    edges = [0.5]
    while edges[-1] < top:
        nxt = np.round(edges[-1] * step - 0.5) + 0.5      # stays on half-integers
        edges.append(max(nxt, edges[-1] + 1.0))
    return np.asarray(edges) / c_med


def _mixture_em(y: np.ndarray, k: int, n_init: int = 5, seed: int = 0, iters: int = 500,
                tol: float = 1e-10) -> dict:
    """Maximum-likelihood Gaussian mixture of ``k`` components in 1D (EM, best of n_init starts
    from quantile-spread and random means). Returns dict weights, means, sds (sorted by mean),
    loglik."""
    y = np.asarray(y, dtype=float)
    rng = np.random.default_rng(seed)
    n = y.size
    floor = 1e-6 * max(float(np.std(y)), 1e-12)
    best = None
    for start in range(n_init):
        if start == 0:
            mu = np.quantile(y, (np.arange(k) + 0.5) / k)
        else:
            mu = rng.choice(y, size=k, replace=False)
        sd = np.full(k, max(float(np.std(y)), floor))
        w = np.full(k, 1.0 / k)
        ll_old = -np.inf
        for _ in range(iters):
            logp = (np.log(w) - np.log(sd) - 0.5 * np.log(2 * np.pi)
                    - 0.5 * ((y[:, None] - mu) / sd) ** 2)
            m = logp.max(axis=1, keepdims=True)
            lse = m[:, 0] + np.log(np.exp(logp - m).sum(axis=1))
            ll = float(lse.sum())
            r = np.exp(logp - lse[:, None])
            nk = r.sum(axis=0) + 1e-300
            w = nk / n
            mu = (r * y[:, None]).sum(axis=0) / nk
            sd = np.sqrt((r * (y[:, None] - mu) ** 2).sum(axis=0) / nk)
            sd = np.maximum(sd, floor)
            if ll - ll_old < tol * max(1.0, abs(ll)):
                break
            ll_old = ll
        if best is None or ll > best["loglik"]:
            o = np.argsort(mu)
            best = {"weights": w[o], "means": mu[o], "sds": sd[o], "loglik": ll}
    return best


def mixture_pdf(x, weights, means, sds) -> np.ndarray:
    """Density of a 1D Gaussian mixture at x."""
    x = np.asarray(x, dtype=float)[..., None]
    w, m, s = (np.asarray(v, dtype=float) for v in (weights, means, sds))
    return (w / (s * np.sqrt(2 * np.pi)) * np.exp(-0.5 * ((x - m) / s) ** 2)).sum(axis=-1)


def bimodality(y, cutoff: float | None = None, seed: int = 0) -> dict:
    """How clearly samples y (e.g. log10 of the lost fraction) split into two populations.

    One and two Gaussian components are fitted by maximum likelihood (EM). Reported:

    * ``delta_bic`` = BIC(1) - BIC(2) (BIC = -2 log L + p ln n; p = 2 and 5): > 10 is strong
      evidence that two components describe the data better than one -- but also true of one
      skewed population, so it is necessary, not sufficient;
    * ``ashman_d`` = sqrt(2) |m1 - m2| / sqrt(s1^2 + s2^2) of the two components: > 2 is needed for
      the mixture to separate into two populations (a density with a valley);
    * ``valley_depth`` = 1 - p(valley) / p(lower peak) of the fitted two-component density: 0 when it
      has a single maximum, towards 1 for two populations separated by an empty gap;
    * ``valley`` (location of the minimum between the peaks, NaN if unimodal), the components
      (``weights``, ``means``, ``sds``), and with ``cutoff`` (same units as y)
      ``cutoff_between_means`` and ``cutoff_density_ratio`` = p(cutoff) / p(lower peak).

    Non-finite samples are dropped; fewer than 10 samples give NaNs.
    """
    y = np.asarray(y, dtype=float).ravel()
    y = y[np.isfinite(y)]
    nan = float("nan")
    out = {"n": int(y.size), "delta_bic": nan, "ashman_d": nan, "valley_depth": nan, "valley": nan,
           "weights": [nan, nan], "means": [nan, nan], "sds": [nan, nan],
           "cutoff_between_means": None, "cutoff_density_ratio": nan}
    if y.size < 10 or np.ptp(y) == 0:
        return out
    one = _mixture_em(y, 1, n_init=1, seed=seed)
    two = _mixture_em(y, 2, n_init=8, seed=seed)
    n = y.size
    bic1 = -2 * one["loglik"] + 2 * np.log(n)
    bic2 = -2 * two["loglik"] + 5 * np.log(n)
    (m1, m2), (s1, s2) = two["means"], two["sds"]
    grid = np.linspace(m1, m2, 2001)
    p = mixture_pdf(grid, two["weights"], two["means"], two["sds"])
    # peaks: local maxima of the fitted density on [m1, m2] (including its ends)
    inner = np.flatnonzero((p[1:-1] >= p[:-2]) & (p[1:-1] >= p[2:])) + 1
    is_max = np.zeros(p.size, bool)
    is_max[inner] = True
    is_max[0] = p[0] >= p[1]
    is_max[-1] = p[-1] >= p[-2]
    peaks = np.flatnonzero(is_max)
    depth, valley, lower = 0.0, nan, float(p.max())
    if peaks.size >= 2:
        a, b = peaks[0], peaks[-1]
        j = a + int(np.argmin(p[a:b + 1]))
        lower = float(min(p[a], p[b]))
        depth = float(1.0 - p[j] / lower)
        valley = float(grid[j]) if depth > 0 else nan
    out.update(delta_bic=float(bic1 - bic2),
               ashman_d=float(np.sqrt(2.0) * abs(m2 - m1) / np.sqrt(s1 ** 2 + s2 ** 2)),
               valley_depth=depth, valley=valley, weights=[float(v) for v in two["weights"]],
               means=[float(m1), float(m2)], sds=[float(s1), float(s2)])
    if cutoff is not None and np.isfinite(cutoff):
        out["cutoff_between_means"] = bool(m1 < cutoff < m2)
        out["cutoff_density_ratio"] = float(
            mixture_pdf(cutoff, two["weights"], two["means"], two["sds"]) / lower)
    return out


def dequantized_log_fraction(n_lost, n_active, seed: int = 0) -> np.ndarray:
    """log10 of the lost fraction with its integer count spread over its unit interval:
    log10((k - 1/2 + u) / C), u uniform in [0, 1), for frames with k >= 1 lost of C contacts.

    A frame losing k contacts stands for every loss rate that rounds to k; without this the
    small counts (1, 2, 3 contacts) are spikes on a log axis, and a mixture fit spends a
    component on the spike of k = 1 instead of on a population. Seeded: reproducible.
    """
    k = np.asarray(n_lost, dtype=float)
    c = np.asarray(n_active, dtype=float)
    ok = np.isfinite(k) & np.isfinite(c) & (k >= 1) & (c > 0)
    u = np.random.default_rng(seed).random(int(ok.sum()))
    return np.log10((k[ok] - 0.5 + u) / c[ok])


# ----------------------------------------------------------------------------------------------
# uncertainties over runs


def bootstrap_ci(values, statistic=np.mean, confidence: float = 0.95, n_resamples: int = 9999,
                 seed: int = 0, method: str = "BCa") -> dict:
    """Estimate and bootstrap confidence interval of ``statistic`` over per-run values.

    values: one number per run (NaN runs dropped). The runs are resampled with replacement
    (scipy.stats.bootstrap; ``method`` "BCa" by default, which corrects for bias and skew and does
    not assume a normal sampling distribution; it falls back to "percentile" when BCa is undefined,
    e.g. for a degenerate resampling distribution). With fewer than 3 runs, or all values equal,
    the interval is [estimate, estimate] when they are equal and NaN otherwise.

    Returns dict estimate, low, high, n, confidence, method (the one used).
    """
    from scipy import stats as _sst
    x = np.asarray(values, dtype=float).ravel()
    x = x[np.isfinite(x)]
    out = {"estimate": float(statistic(x)) if x.size else float("nan"), "low": float("nan"),
           "high": float("nan"), "n": int(x.size), "confidence": float(confidence),
           "method": method}
    if x.size and np.all(x == x[0]):
        out.update(low=float(x[0]), high=float(x[0]), method="degenerate")
        return out
    if x.size < 3:
        return out
    for m in (method, "percentile"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = _sst.bootstrap((x,), statistic, confidence_level=confidence,
                                 n_resamples=n_resamples, method=m, vectorized=False,
                                 rng=np.random.default_rng(seed))
        lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
        if np.isfinite(lo) and np.isfinite(hi):
            out.update(low=lo, high=hi, method=m)
            break
    return out


def bootstrap_runs_ci(groups: list, statistic, confidence: float = 0.95, n_resamples: int = 999,
                      seed: int = 0) -> dict:
    """Percentile bootstrap over runs of a statistic of pooled per-run data (e.g. a fit of the
    clusters of resampled runs): ``statistic(list of the groups of one resample) -> float``.

    groups: one item per run (anything ``statistic`` understands). Resamples whose statistic is
    not finite are dropped (reported as ``n_failed``). Returns dict estimate (on all runs), low,
    high, n (runs), n_resamples, n_failed, confidence, method "percentile".
    """
    rng = np.random.default_rng(seed)
    k = len(groups)
    est = float(statistic(list(groups))) if k else float("nan")
    vals = []
    for _ in range(n_resamples if k >= 2 else 0):
        pick = rng.integers(0, k, size=k)
        try:
            v = float(statistic([groups[i] for i in pick]))
        except (InsufficientDataError, ValueError, FloatingPointError):
            v = float("nan")
        vals.append(v)
    vals = np.asarray(vals)
    ok = vals[np.isfinite(vals)]
    a = (1.0 - confidence) / 2.0
    lo, hi = (np.quantile(ok, [a, 1.0 - a]) if ok.size >= 10 else (np.nan, np.nan))
    return {"estimate": est, "low": float(lo), "high": float(hi), "n": int(k),
            "n_resamples": int(vals.size), "n_failed": int(vals.size - ok.size),
            "confidence": float(confidence), "method": "percentile"}


def diff_ci(x, y, confidence: float = 0.95, n_resamples: int = 9999, seed: int = 0) -> dict:
    """mean(x) - mean(y) of two independent sets of per-run values (NaN dropped) with a
    percentile bootstrap interval (scipy.stats.bootstrap, each set resampled on its own).
    Fewer than 2 values in a set: the interval is NaN. Returns dict estimate, low, high, n_x,
    n_y, confidence."""
    from scipy import stats as _sst
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    x, y = x[np.isfinite(x)], y[np.isfinite(y)]
    est = float(x.mean() - y.mean()) if x.size and y.size else np.nan
    out = {"estimate": est, "low": np.nan, "high": np.nan, "n_x": int(x.size), "n_y": int(y.size),
           "confidence": float(confidence)}
    if x.size < 2 or y.size < 2:
        return out
    if np.ptp(x) == 0 and np.ptp(y) == 0:
        out.update(low=est, high=est)
        return out
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = _sst.bootstrap((x, y), lambda a, b: np.mean(a) - np.mean(b), paired=False,
                             confidence_level=confidence, n_resamples=n_resamples,
                             method="percentile", vectorized=False,
                             rng=np.random.default_rng(seed))
    out.update(low=float(res.confidence_interval.low), high=float(res.confidence_interval.high))
    return out
