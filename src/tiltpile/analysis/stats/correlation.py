"""C(tau) between the largest cluster and the failing grains over quiet frames (paper Eq. 2), and
the failure enhancement after cluster-size peaks (Fig. 3).
"""

from __future__ import annotations

import numpy as np
import pandas as pd


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
