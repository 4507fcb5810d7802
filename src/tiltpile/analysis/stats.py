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


def dz_distribution(clusters: pd.DataFrame, size_lo: int, size_hi: int | None = None) -> pd.DataFrame:
    """Distribution of delta z for clusters with size_lo <= size < size_hi (paper Fig. 5a).

    For a cluster of s grains, z = sum z_i / s and n_m = sum m_i / (2 s), so delta z = z - n_m is
    a multiple of 1 / (2 s): the bins are centred on multiples of 1 / (2 size_lo) with that width,
    which respects this discreteness (exactly for a single size). Returns DataFrame center,
    count, density (integrating to 1).
    """
    size_hi = size_lo + 1 if size_hi is None else size_hi
    sel = clusters[(clusters["size"] >= size_lo) & (clusters["size"] < size_hi)]
    dz = sel["dz"].to_numpy(float)
    dz = dz[np.isfinite(dz)]
    if dz.size == 0:
        return pd.DataFrame(columns=["center", "count", "density"])
    w = 1.0 / (2.0 * size_lo)
    q = np.round(dz / w).astype(np.int64)
    vals, count = np.unique(q, return_counts=True)
    return pd.DataFrame({"center": vals * w, "count": count, "density": count / (dz.size * w)})
