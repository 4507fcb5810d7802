"""Where the populations split: the kinetic-energy density's departure from the power law of the
quiet frames (Fig. 2a), the lost-fraction density on bins that respect the integer counts and
how clearly it splits into two populations (Fig. 2b).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import checks as _ck
from .densities import log_binned_density


def _departure(fn: str, factor, n_consecutive) -> None:
    """Check the departure rule: a ratio ``factor`` >= 1, a whole number of bins."""
    _ck.real(fn, "factor", factor, lo=1)
    _ck.count(fn, "n_consecutive", n_consecutive, floats_ok=True)


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
    fn = "power_law_departure"
    _ck.table(fn, "density", density)
    if len(density):
        _ck.table(fn, "density", density, ("left", "center", "count", "density"))
    _ck.real(fn, "fit_lo", fit_lo, nonfinite_ok=True)
    _ck.real(fn, "fit_hi", fit_hi, nonfinite_ok=True)
    _departure(fn, factor, n_consecutive)
    _ck.real(fn, "min_count", min_count)
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
    fn = "ke_threshold"
    _ck.table(fn, "frames", frames, (ke_column, "avalanching"))
    _ck.count(fn, "bins_per_decade", bins_per_decade, lo=1, floats_ok=True)
    q = _ck.shaped(fn, "fit_quantiles", fit_quantiles, (2,), finite=True)
    if not 0 <= q[0] <= q[1] <= 1:
        _ck.fail(fn, "fit_quantiles", "be (low, high) with 0 <= low <= high <= 1",
                 _ck.short(tuple(q.tolist())))
    _departure(fn, factor, n_consecutive)
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
    _ck.asarray("fd_bins_per_decade", "x", x)
    _ck.count("fd_bins_per_decade", "lo", lo, lo=1, floats_ok=True)
    _ck.count("fd_bins_per_decade", "hi", hi, lo=lo, floats_ok=True)
    y = np.log10(np.asarray(x, dtype=float)[np.isfinite(x) & (np.asarray(x, dtype=float) > 0)])
    if y.size < 4:
        return int(lo)
    iqr = np.subtract(*np.percentile(y, [75, 25]))
    if iqr <= 0:
        return int(lo)
    return int(np.clip(round(1.0 / (2.0 * iqr * y.size ** (-1.0 / 3.0))), lo, hi))


def _counts_per_frame(fn: str, n_lost, n_active) -> None:
    """Check per-frame lost and active contact counts: numbers, of one shape."""
    a = _ck.asarray(fn, "n_lost", n_lost)
    b = _ck.asarray(fn, "n_active", n_active)
    if a.shape != b.shape:
        _ck.fail(fn, "n_active", f"have the shape of n_lost {a.shape}", str(b.shape))


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
    _counts_per_frame("lost_fraction_edges", n_lost, n_active)
    if bins_per_decade is not None:
        _ck.count("lost_fraction_edges", "bins_per_decade", bins_per_decade, lo=1, floats_ok=True)
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
                tol: float = 1e-10, init: dict | None = None) -> dict:
    """Maximum-likelihood Gaussian mixture of ``k`` components in 1D (EM, best of n_init starts
    from quantile-spread and random means; with ``init``, a dict weights, means, sds of k
    components, the one start from there). Returns dict weights, means, sds (sorted by mean),
    loglik."""
    y = np.asarray(y, dtype=float)
    rng = np.random.default_rng(seed)
    n = y.size
    floor = 1e-6 * max(float(np.std(y)), 1e-12)
    best = None
    for start in range(1 if init is not None else n_init):
        if init is not None:
            mu = np.asarray(init["means"], float).copy()
            sd = np.maximum(np.asarray(init["sds"], float), floor)
            w = np.asarray(init["weights"], float).copy()
        else:
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


def _mixture(fn: str, k: int | None = None, **parts) -> None:
    """Check a Gaussian mixture's weights, means and sds: one-dimensional, one per component
    (``k`` of them if given), sds > 0 (NaN allowed: a fit that could not be made gives NaN);
    and ``x`` (if given) numbers."""
    if "x" in parts:
        _ck.asarray(fn, "x", parts.pop("x"))
    arrays = {name: _ck.shaped(fn, name, v, ("K",) if k is None else (k,))
              for name, v in parts.items()}
    _ck.same_length(fn, **arrays)
    if (arrays["sds"] <= 0).any():
        _ck.fail(fn, "sds", "be > 0", _ck.short(arrays["sds"].tolist()))


def mixture_pdf(x, weights, means, sds) -> np.ndarray:
    """Density of a 1D Gaussian mixture at x (weights, means, sds: one per component, sds > 0)."""
    _mixture("mixture_pdf", x=x, weights=weights, means=means, sds=sds)
    x = np.asarray(x, dtype=float)[..., None]
    w, m, s = (np.asarray(v, dtype=float) for v in (weights, means, sds))
    return (w / (s * np.sqrt(2 * np.pi)) * np.exp(-0.5 * ((x - m) / s) ** 2)).sum(axis=-1)


def bimodality(y, cutoff: float | None = None, seed: int = 0, init: dict | None = None) -> dict:
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

    Non-finite samples are dropped; fewer than 10 samples give NaNs. ``init`` (the weights, means
    and sds of an earlier two-component fit, e.g. of the same samples with one run more) starts
    the two-component fit from there alone instead of from 8 starts: the fit that a small change of
    the samples moves the earlier one to (leave-one-run-out).
    """
    fn = "bimodality"
    _ck.asarray(fn, "y", y)
    _ck.real(fn, "cutoff", cutoff, none_ok=True, nonfinite_ok=True)
    if init is not None:
        if not isinstance(init, dict) or not {"weights", "means", "sds"} <= set(init):
            _ck.fail(fn, "init", "be a dict of weights, means and sds (a two-component fit)",
                     _ck.short(init), TypeError)
        for k in ("weights", "means", "sds"):     # sds below a floor are raised to it
            _ck.shaped(fn, f"init['{k}']", init[k], (2,), "a two-component fit")
    y = np.asarray(y, dtype=float).ravel()
    y = y[np.isfinite(y)]
    nan = float("nan")
    out = {"n": int(y.size), "delta_bic": nan, "ashman_d": nan, "valley_depth": nan, "valley": nan,
           "weights": [nan, nan], "means": [nan, nan], "sds": [nan, nan],
           "cutoff_between_means": None, "cutoff_density_ratio": nan}
    if y.size < 10 or np.ptp(y) == 0:
        return out
    one = _mixture_em(y, 1, n_init=1, seed=seed)
    two = _mixture_em(y, 2, n_init=8, seed=seed, init=init)
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
    _counts_per_frame("dequantized_log_fraction", n_lost, n_active)
    k = np.asarray(n_lost, dtype=float)
    c = np.asarray(n_active, dtype=float)
    ok = np.isfinite(k) & np.isfinite(c) & (k >= 1) & (c > 0)
    u = np.random.default_rng(seed).random(int(ok.sum()))
    return np.log10((k[ok] - 0.5 + u) / c[ok])
