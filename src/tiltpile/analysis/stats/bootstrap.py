"""Uncertainties over runs: bootstrap confidence intervals (ensemble means of few runs).
"""

from __future__ import annotations

import warnings

import numpy as np

from .. import checks as _ck
from .errors import InsufficientDataError


def _resampling(fn: str, confidence, n_resamples, least: int = 1) -> None:
    """Check a confidence level in (0, 1) and a number of resamples >= ``least``."""
    _ck.real(fn, "confidence", confidence, lo=0, hi=1, lo_open=True, hi_open=True)
    _ck.count(fn, "n_resamples", n_resamples, lo=least)


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
    fn = "bootstrap_ci"
    _ck.asarray(fn, "values", values)
    _ck.function(fn, "statistic", statistic)
    _resampling(fn, confidence, n_resamples)
    if not isinstance(method, str) or method.lower() not in ("percentile", "basic", "bca"):
        _ck.fail(fn, "method", "be 'BCa', 'percentile' or 'basic'", _ck.short(method))
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
    fn = "bootstrap_runs_ci"
    if isinstance(groups, (str, bytes)) or not (hasattr(groups, "__len__")
                                                and hasattr(groups, "__getitem__")):
        _ck.fail(fn, "groups", "be a list (one item per run)", type(groups).__name__, TypeError)
    _ck.function(fn, "statistic", statistic)
    _resampling(fn, confidence, n_resamples, least=0)
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
    _ck.asarray("diff_ci", "x", x)
    _ck.asarray("diff_ci", "y", y)
    _resampling("diff_ci", confidence, n_resamples)
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


def leave_one_run_out(frames, seeds, statistic) -> list:
    """``statistic`` of the per-frame (or per-cluster) table ``frames`` with each run of ``seeds``
    left out in turn (rows of column ``run`` equal to it dropped): one value per seed, in
    ``seeds`` order. What a number chosen from the pooled runs (a bin of a density, a fitted
    valley) owes to any single run."""
    _ck.table("leave_one_run_out", "frames", frames, ("run",))
    _ck.shaped("leave_one_run_out", "seeds", seeds, ("K",), empty_ok=True)
    _ck.function("leave_one_run_out", "statistic", statistic)
    run = frames["run"].to_numpy()
    return [statistic(frames[run != s]) for s in seeds]


def loo_stability(full: float, values, discrete: bool = False) -> dict:
    """How firm a number is under leave-one-run-out (``values``: one per run left out, NaN where
    it is undefined without that run; ``full``: the number on all runs).

    Returns dict low, high (smallest and largest finite value), jackknife_se (sqrt((n - 1) / n
    sum (v_i - mean)^2), NaN if any value is not finite) and n (runs). With ``discrete`` (a number
    picked from bins takes few values) also values (the distinct finite values, sorted), counts
    (how many left-out runs give each), flip_share (the share of the runs whose removal changes the
    number: a value other than ``full``, NaN included) and firm (flip_share == 0)."""
    _ck.real("loo_stability", "full", full, nonfinite_ok=True)
    _ck.asarray("loo_stability", "values", values)
    v = np.asarray(values, dtype=float).ravel()
    n = int(v.size)
    fin = v[np.isfinite(v)]
    se = (float(np.sqrt((n - 1) / n * ((v - v.mean()) ** 2).sum()))
          if n >= 2 and fin.size == n else float("nan"))
    out = {"low": float(fin.min()) if fin.size else float("nan"),
           "high": float(fin.max()) if fin.size else float("nan"), "jackknife_se": se, "n": n}
    if discrete:
        same = (v == full) | (np.isnan(v) & bool(np.isnan(full)))
        distinct, counts = np.unique(fin, return_counts=True)
        flip = float((~same).mean()) if n else float("nan")
        out.update(values=[float(x) for x in distinct], counts=[int(c) for c in counts],
                   flip_share=flip, firm=bool(n and flip == 0.0))
    return out
