"""C(tau) between the largest cluster and the failing grains over quiet frames (paper Eq. 2), and
the failure enhancement after cluster-size peaks (Fig. 3).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import checks as _ck


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


def _series(fn: str, period=None, **arrays) -> None:
    """Check per-frame series (name=array): one-dimensional, of one length, numbers (a mask for
    ``quiet``), and ``period`` (if given) of that length too."""
    for name, x in arrays.items():
        if name == "quiet":
            _ck.boolean(fn, name, x, None)
        else:
            _ck.asarray(fn, name, x)
    if period is not None:
        arrays["period"] = _ck.asarray(fn, "period", period)
    _ck.same_length(fn, **arrays)


def _lags(fn: str, taus) -> None:
    """Check lags: whole numbers (of frames); an iterator is taken as it comes."""
    if hasattr(taus, "__next__"):
        return
    t = _ck.shaped(fn, "taus", taus, ("K",), finite=True, empty_ok=True)
    if t.size and (t != np.round(t)).any():
        _ck.fail(fn, "taus", "be whole numbers of frames", _ck.short(t.tolist()))


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
    fn = "correlation_function"
    _series(fn, period, a=a, b=b, quiet=quiet)
    _lags(fn, taus)
    _ck.count(fn, "min_pairs", min_pairs, floats_ok=True)
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
    _ck.table("ensemble_periods", "frames", frames, ("run", "period"))
    return frames.groupby(["run", "period"], sort=False).ngroup().to_numpy()


def correlation_function_ensemble(frames: pd.DataFrame, a: str = "largest_cluster",
                                  b: str = "n_lost", taus=range(-10, 11)) -> pd.DataFrame:
    """C(tau) of :func:`correlation_function` pooled over all runs of a per-frame table.

    frames needs columns run, frame, period, avalanching and the two named columns. Pairs never
    straddle two runs or two periods; means and variances are over the pooled pairs.
    """
    fn = "correlation_function_ensemble"
    _ck.table(fn, "frames", frames, ("run", "frame", "period", "avalanching", a, b))
    _lags(fn, taus)
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


# what counts as a peak of the largest cluster in the failure enhancement (the paper's "just after
# the cluster size peaks, the failure rate is enhanced by about 40%" defines none): see
# cluster_peaks; "c0" reads the +40% as C(0) of Eq. 2 instead of a rate after peaks
PEAK_RULES = ("local", "sigma", "decile", "c0")
DEFAULT_PEAK_RULE = "sigma"
# the share of a run's quiet frames the "decile" rule takes as peaks
TOP_SHARE = 0.1


def check_peak_rule(peak_rule) -> str:
    """``peak_rule`` if it is one of :data:`PEAK_RULES`, else a one-line ValueError."""
    if not isinstance(peak_rule, str) or peak_rule not in PEAK_RULES:
        raise ValueError(f"peak_rule must be one of {', '.join(map(repr, PEAK_RULES))}, "
                         f"not {peak_rule!r}")
    return peak_rule


def cluster_peaks(s_max, quiet, period=None, threshold_sigma: float = 1.0,
                  peak_rule: str = DEFAULT_PEAK_RULE) -> np.ndarray:
    """Frames where the largest cluster size peaks during a quiet period, by ``peak_rule``:

    "local"   a quiet frame k whose neighbours k - 1 and k + 1 are in the same quiet period, with
              S(k) > S(k - 1) and S(k) >= S(k + 1) (a plateau counts once, at its first frame);
    "sigma"   (default) such a local maximum with S(k) > mean + threshold_sigma * std of S over
              the quiet frames;
    "decile"  every quiet frame in the top decile of the quiet frames' S, local maximum or not:
              S(k) at least the m-th largest quiet S, m = ceil(n / 10) of n quiet frames, i.e.
              fewer than n / 10 quiet frames have a larger S (frames tied with the m-th all count,
              so with ties more than a tenth may).

    Quiet frames with a non-finite S are never peaks and do not enter the mean, std or decile.
    "c0" defines no peaks (:func:`failure_enhancement`): ValueError. Returns the frame indices
    (int64), ascending.
    """
    if check_peak_rule(peak_rule) == "c0":
        raise ValueError("peak_rule 'c0' defines no peaks: it reads the enhancement as C(0)")
    _series("cluster_peaks", period, s_max=s_max, quiet=quiet)
    _ck.real("cluster_peaks", "threshold_sigma", threshold_sigma)
    s = np.asarray(s_max, dtype=float)
    quiet = np.asarray(quiet, dtype=bool)
    per = _period_labels(quiet, period)
    sq = s[quiet & np.isfinite(s)]
    if peak_rule == "decile":
        if not sq.size:
            return np.zeros(0, dtype=np.int64)
        m = int(np.ceil(TOP_SHARE * sq.size))
        thr = np.sort(sq)[::-1][m - 1]
        return np.flatnonzero(quiet & np.isfinite(s) & (s >= thr)).astype(np.int64)
    if s.size < 3:
        return np.zeros(0, dtype=np.int64)
    k = np.arange(1, s.size - 1)
    inner = quiet[k] & quiet[k - 1] & quiet[k + 1] & (per[k] == per[k - 1]) & (per[k] == per[k + 1])
    peak = inner & (s[k] > s[k - 1]) & (s[k] >= s[k + 1])
    if peak_rule == "sigma":
        thr = sq.mean() + threshold_sigma * sq.std() if sq.size else np.inf
        peak &= s[k] > thr
    return k[peak]


def _c_as_enhancement(c: pd.DataFrame) -> pd.DataFrame:
    """A C(tau) table as an enhancement table: enhancement = C, n_peaks = the frame pairs."""
    return pd.DataFrame({"tau": c["tau"].astype(int), "enhancement": c["C"].astype(float),
                         "n_peaks": c["n_pairs"].astype(int)})


def failure_enhancement(s_max, n_fail, quiet, taus=range(0, 6), period=None,
                        threshold_sigma: float = 1.0,
                        peak_rule: str = DEFAULT_PEAK_RULE) -> pd.DataFrame:
    """Failure rate after peaks of the largest cluster, relative to the quiet-period mean.

    enhancement(tau) = <N^f(k + tau)>_{k in peaks, k + tau in the same quiet period}
                       / <N^f>_{quiet frames} - 1
    (the paper: "just after the cluster size peaks, the failure rate is enhanced by about 40%").
    Peaks from :func:`cluster_peaks` by ``peak_rule`` ("local", "sigma", "decile"). With
    peak_rule "c0" the enhancement is C(tau) of :func:`correlation_function` (the +40% read as
    C(0) ~ 0.4) and n_peaks its frame pairs. Returns DataFrame tau, enhancement, n_peaks.
    """
    fn = "failure_enhancement"
    check_peak_rule(peak_rule)
    _series(fn, period, s_max=s_max, n_fail=n_fail, quiet=quiet)
    _lags(fn, taus)
    _ck.real(fn, "threshold_sigma", threshold_sigma)
    nf = np.asarray(n_fail, dtype=float)
    quiet = np.asarray(quiet, dtype=bool)
    per = _period_labels(quiet, period)
    if check_peak_rule(peak_rule) == "c0":
        return _c_as_enhancement(correlation_function(s_max, nf, quiet, taus, period=per))
    peaks = cluster_peaks(s_max, quiet, per, threshold_sigma, peak_rule)
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
                                 threshold_sigma: float = 1.0,
                                 peak_rule: str = DEFAULT_PEAK_RULE) -> pd.DataFrame:
    """:func:`failure_enhancement` pooled over runs (peak threshold or top decile per run).

    With peak_rule "c0": C(tau) of :func:`correlation_function_ensemble` as the enhancement, its
    frame pairs as n_peaks.
    """
    fn = "failure_enhancement_ensemble"
    check_peak_rule(peak_rule)
    _ck.table(fn, "frames", frames, ("run", "frame", "period", "avalanching", a, b))
    _lags(fn, taus)
    _ck.real(fn, "threshold_sigma", threshold_sigma)
    if check_peak_rule(peak_rule) == "c0":
        return _c_as_enhancement(correlation_function_ensemble(frames, a, b, taus))
    parts = []
    for _, g in frames.sort_values(["run", "frame"]).groupby("run", sort=False):
        quiet = ~g["avalanching"].to_numpy(bool)
        per = g["period"].to_numpy()
        s = _column(g, a)
        nf = _column(g, b)
        peaks = cluster_peaks(s, quiet, per, threshold_sigma, peak_rule)
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
