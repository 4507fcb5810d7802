"""The Mohr-Coulomb reading of the clusters' orientation, and its test across a parameter study.

The paper explains the orientation of the critical clusters by Mohr-Coulomb: the failure plane
lies at 1/2 (pi/2 - atan mu) to the contacts, so that a cluster lying in it leans at
90 - 1/2 (90 - atan mu) = 45 + 1/2 atan(mu) deg to gravity (:func:`failure_plane_deg`: 50.7,
55.9, 58.3, 64.3 and 67.5 deg for mu = 0.2, 0.4, 0.5, 0.8, 1.0; "roughly 60 deg" at the paper's
mu = 0.5). One friction cannot test it; a study over mu can.

:func:`slope_test` fits the measured angle against the predicted one across the values of a
study, y = a + b x by ordinary least squares over the values, with a bootstrap interval in
which the runs of each value are resampled (with replacement, within that value) and the
per-value statistic recomputed from them: the interval says how far the run-to-run scatter
moves the slope. Mohr-Coulomb, as the paper reads it, predicts b = 1 (and a = 0); an
orientation that does not follow friction gives b = 0.
"""

from __future__ import annotations

import numpy as np


def failure_plane_deg(mu) -> np.ndarray:
    """45 + 1/2 atan(mu) in deg (``mu`` >= 0, scalar or array): the angle to gravity of a
    cluster in the Mohr-Coulomb failure plane, as the paper reads Fig. 3 (~60 deg at mu = 0.5);
    the angle Fig. 3 measures (``orientation_deg``, 0 = along gravity)."""
    mu = np.asarray(mu, dtype=float)
    if np.any(~np.isfinite(mu)) or np.any(mu < 0):
        raise ValueError(f"friction coefficients must be finite and >= 0, got {mu.tolist()}")
    return 45.0 + 0.5 * np.degrees(np.arctan(mu))


def pooled_mean(groups) -> float:
    """Mean of the concatenated arrays of ``groups`` (one array per run; NaN dropped): the
    statistic of Fig. 3's orientation, every cluster of the runs counted once. NaN if empty."""
    parts = [np.asarray(g, dtype=float).ravel() for g in groups]
    x = np.concatenate(parts) if parts else np.zeros(0)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else float("nan")


def _ols(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(intercept, slope) of y = a + b x over the finite pairs; NaN with fewer than two distinct x."""
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 2 or np.ptp(x) == 0:
        return float("nan"), float("nan")
    b = float(np.sum((x - x.mean()) * (y - y.mean())) / np.sum((x - x.mean()) ** 2))
    return float(y.mean() - b * x.mean()), b


def slope_test(x, groups, statistic=pooled_mean, confidence: float = 0.95,
               n_resamples: int = 999, seed: int = 0) -> dict:
    """Least-squares line of a per-value statistic against ``x``, with its bootstrap interval.

    x: one predictor per value of the study (e.g. :func:`failure_plane_deg` of each mu, deg);
    groups: per value, the list of its runs' data (e.g. each run's cluster orientations);
    statistic(list of run data) -> float, the value's number (default :func:`pooled_mean`).
    The estimate fits y_k = statistic(groups[k]) against x_k (values whose y is not finite left
    out); each of ``n_resamples`` resamples draws, for every value, as many runs as it has from its
    own runs with replacement (``numpy.random.default_rng(seed)``), and refits. Percentile
    interval of the finite resampled fits (NaN with fewer than 10 of them, or when a value has a
    single run: its scatter is then unknown).

    Returns dict slope, intercept, slope_low, slope_high, intercept_low, intercept_high, y (the
    per-value statistic), residual (y - (a + b x)), n_values (with finite y), n_runs (per value),
    n_resamples, n_failed (resamples without a fit), confidence, method.
    """
    x = np.asarray(x, dtype=float).ravel()
    groups = [list(g) for g in groups]
    if len(groups) != x.size:
        raise ValueError(f"{x.size} predictors for {len(groups)} groups of runs")
    y = np.array([statistic(g) if g else np.nan for g in groups], dtype=float)
    a, b = _ols(x, y)
    rng = np.random.default_rng(seed)
    fits = []
    runs = [len(g) for g in groups]
    if min(runs, default=0) >= 2 and np.isfinite(b):
        for _ in range(n_resamples):
            yr = np.array([statistic([g[i] for i in rng.integers(0, len(g), len(g))])
                           for g in groups], dtype=float)
            fits.append(_ols(x, yr))
    fits = np.array(fits, dtype=float).reshape(-1, 2)
    ok = np.all(np.isfinite(fits), axis=1)
    q = (1.0 - confidence) / 2.0
    if ok.sum() >= 10:
        (a_lo, a_hi), (b_lo, b_hi) = (np.quantile(fits[ok, k], [q, 1.0 - q]) for k in (0, 1))
    else:
        a_lo = a_hi = b_lo = b_hi = float("nan")
    return {"slope": b, "intercept": a, "slope_low": float(b_lo), "slope_high": float(b_hi),
            "intercept_low": float(a_lo), "intercept_high": float(a_hi), "y": y.tolist(),
            "residual": (y - (a + b * x)).tolist(), "n_values": int(np.isfinite(y).sum()),
            "n_runs": runs, "n_resamples": int(fits.shape[0]),
            "n_failed": int(fits.shape[0] - ok.sum()), "confidence": float(confidence),
            "method": "percentile; runs resampled within each value"}


def verdict(fit: dict, predicted_slope: float = 1.0) -> str:
    """One word for a :func:`slope_test` fit against a prediction: "consistent" (the interval
    holds ``predicted_slope``), "flat" (it holds 0 but not the prediction), "shallower" or
    "steeper" (it holds neither, below or above the prediction), "undetermined" (no interval)."""
    lo, hi = fit.get("slope_low"), fit.get("slope_high")
    if lo is None or hi is None or not (np.isfinite(lo) and np.isfinite(hi)):
        return "undetermined"
    if lo <= predicted_slope <= hi:
        return "consistent"
    if lo <= 0.0 <= hi:
        return "flat"
    return "shallower" if hi < predicted_slope else "steeper"
