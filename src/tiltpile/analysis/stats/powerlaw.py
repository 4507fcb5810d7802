"""The cluster-size law P(s) = s^-delta exp(-s / xi) / Z, s >= s_min (paper Eq. 3, Fig. 4):
maximum-likelihood fit with Fisher-information uncertainties, and sampling from it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import integrate, optimize

from .. import checks as _ck
from .errors import InsufficientDataError, PoorFitWarning


# Largest one-sigma error of a free delta for which fit_power_law_cutoff stays silent. Measured
# (20 samples of P(s) with delta = 2, fitted freely; the Fisher error agrees with the spread of
# the estimates): delta_err ~ 1.3 / 0.73 / 0.52 / 0.37 / 0.25 at n = 20 / 50 / 100 / 200 / 500
# for xi = 5, and 0.77 / 0.38 / 0.27 / 0.19 at n = 20 / 50 / 100 / 200 for xi = 20. An exponent
# known to +-0.5 cannot tell the paper's delta from its neighbours, so past that the fit warns.
MAX_DELTA_ERR = 0.5

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


def _bounds(fn: str, name: str, b, positive: bool = False) -> None:
    """Check a (low, high) pair of finite numbers, low < high (both > 0 if ``positive``)."""
    a = _ck.shaped(fn, name, b, (2,), finite=True)
    if not a[0] < a[1] or (positive and not a[0] > 0):
        _ck.fail(fn, name, "be (low, high) with " + ("0 < " if positive else "") + "low < high",
                 _ck.short(tuple(a.tolist())))


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
    fn = "fit_power_law_cutoff"
    _ck.asarray(fn, "s", s)
    _ck.count(fn, "s_min", s_min, lo=1, floats_ok=True)
    _ck.real(fn, "delta", delta, none_ok=True)
    _ck.count(fn, "min_samples", min_samples, floats_ok=True)
    _bounds(fn, "xi_bounds", xi_bounds, positive=True)
    _bounds(fn, "delta_bounds", delta_bounds)
    _ck.real(fn, "max_delta_err", max_delta_err, lo=0, none_ok=True,
             nonfinite_ok=True)
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
    fn = "sample_power_law_cutoff"
    _ck.real(fn, "delta", delta)
    _ck.real(fn, "xi", xi, lo=0, lo_open=True)
    _ck.count(fn, "size", size)
    _ck.count(fn, "s_min", s_min, lo=1, floats_ok=True)
    if s_max is not None:
        _ck.count(fn, "s_max", s_max, lo=s_min, floats_ok=True)
    rng = np.random.default_rng(rng)
    if s_max is None:
        s_max = int(s_min + 50 * xi + 1000)
    s = np.arange(s_min, s_max + 1, dtype=float)
    logw = -delta * np.log(s) - s / xi
    w = np.exp(logw - logw.max())
    cdf = np.cumsum(w)
    cdf /= cdf[-1]
    return (s_min + np.searchsorted(cdf, rng.random(size), side="right")).astype(np.int64)
