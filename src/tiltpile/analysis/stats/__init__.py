"""Ensemble statistics of the per-frame and per-cluster observables: one module per concern
(``densities``, ``powerlaw``, ``sizes``, ``correlation``, ``thresholds``, ``bootstrap``, and
``errors``), every public name importable from here.

* :func:`log_binned_density`, :func:`discrete_log_binned_density`, :func:`density_2d` --
  probability densities (paper Figs. 2a, 2b, 2d, 4, 5a).
* :func:`fit_power_law_cutoff` -- maximum-likelihood fit of the discrete cluster-size law
  P(s) = s^-delta exp(-s / xi) / Z, s >= s_min (paper Eq. 3, Fig. 4), with Fisher-information
  uncertainties; :func:`sample_power_law_cutoff` draws from it.
* :func:`cluster_size_windows` -- P(s) fits, xi and <S_max> in windows of theta - theta_m.
* :func:`correlation_function` -- C(tau) between S_m(k) and N^f(k + tau) over quiet frames
  (paper Eq. 2); :func:`failure_enhancement` after cluster-size peaks (what a peak is:
  :data:`PEAK_RULES`, :func:`cluster_peaks`).
* :func:`dz_by_size`, :func:`dz_distribution` -- delta z of clusters versus their size (Fig. 5).
* :func:`power_law_departure`, :func:`ke_threshold` -- where the kinetic-energy density leaves the
  power law of the quiet frames (Fig. 2a).
* :func:`lost_fraction_edges`, :func:`bimodality` -- the lost-fraction density on bins that respect
  the integer counts, and how clearly it splits into two populations (Fig. 2b).
* :func:`bootstrap_ci` -- confidence intervals by resampling runs (ensemble means of few runs);
  :func:`leave_one_run_out`, :func:`loo_stability` -- how firm a number chosen from the pooled
  runs is when any one run is left out.
"""

from __future__ import annotations

from .errors import (
    InsufficientDataError,
    PoorFitWarning,
)
from .densities import (
    cell_density_2d,
    density_2d,
    discrete_log_binned_density,
    log_binned_density,
    log_int_edges,
)
from .powerlaw import (
    MAX_DELTA_ERR,
    PowerLawCutoffFit,
    fit_power_law_cutoff,
    sample_power_law_cutoff,
)
from .sizes import (
    cluster_size_windows,
    dz_by_size,
    dz_distribution,
    parity_log_edges,
    window_edges,
)
from .correlation import (
    DEFAULT_PEAK_RULE,
    FORWARD_COLUMNS,
    PEAK_RULES,
    check_peak_rule,
    cluster_peaks,
    correlation_function,
    correlation_function_ensemble,
    ensemble_periods,
    failure_enhancement,
    failure_enhancement_ensemble,
)
from .thresholds import (
    bimodality,
    dequantized_log_fraction,
    fd_bins_per_decade,
    ke_threshold,
    lost_fraction_edges,
    mixture_pdf,
    power_law_departure,
)
from .bootstrap import (
    bootstrap_ci,
    bootstrap_runs_ci,
    diff_ci,
    leave_one_run_out,
    loo_stability,
)

__all__ = [
    "DEFAULT_PEAK_RULE",
    "FORWARD_COLUMNS",
    "InsufficientDataError",
    "MAX_DELTA_ERR",
    "PEAK_RULES",
    "PoorFitWarning",
    "PowerLawCutoffFit",
    "bimodality",
    "bootstrap_ci",
    "bootstrap_runs_ci",
    "cell_density_2d",
    "check_peak_rule",
    "cluster_peaks",
    "cluster_size_windows",
    "correlation_function",
    "correlation_function_ensemble",
    "density_2d",
    "dequantized_log_fraction",
    "diff_ci",
    "leave_one_run_out",
    "loo_stability",
    "discrete_log_binned_density",
    "dz_by_size",
    "dz_distribution",
    "ensemble_periods",
    "failure_enhancement",
    "failure_enhancement_ensemble",
    "fd_bins_per_decade",
    "fit_power_law_cutoff",
    "ke_threshold",
    "log_binned_density",
    "log_int_edges",
    "lost_fraction_edges",
    "mixture_pdf",
    "parity_log_edges",
    "power_law_departure",
    "sample_power_law_cutoff",
    "window_edges",
]
