"""Analysis of tiltpile runs: every quantity the paper measures, as pure functions.

Modules (imports point down; none reads HDF5 except through :mod:`tiltpile.store`):

``contacts``      active / fully mobilized contacts under a contact rule, bulk layers, z, n_m,
                  delta z_gen, lost contacts, failing grains, kinetic energy, displacements
``clusters``      critical clusters, their size, z, n_m, delta z and orientation to gravity
``rigidity``      rigid clusters of a frame: the (3,3) pebble game on the body-bar framework
                  (Fig. 7)
``avalanche``     quiet / avalanching periods, onsets, theta_m, theta - theta_m, cutoff
                  robustness, the first large slide
``stats``         log-binned densities, P(s) maximum-likelihood fit, C(tau), failure enhancement,
                  delta z versus cluster size, thresholds, bootstrap intervals
``tables``        the per-frame and per-cluster columns, each declared once (``FRAME_DOCS``,
                  ``CLUSTER_DOCS``) and computed by one registered producer of a version,
                  which gives each column its code (``column_code``); every analysis parameter
                  (``DEFAULT_PARAMS``)
``legacy_codes``  the column codes of records written with one digest of the whole table code
                  (``LEGACY``), and of changes of code that kept the values (``SUPERSEDED``)
``observables``   per-run tables (per frame, per cluster), cached beside the runs; per-run onsets
                  (first 2% onset, first large slide: ``run_table``)
``ensemble_data`` an ensemble directory (run files or their records) as tables, with the columns
                  a reader declares (``Reads``); the records checked column by column
``structure``     the pile's structure: packing fraction, contact fabric and the tilt of the
                  free surface (the preparation study, ``tiltpile repose``)
``zcount``        z = 2 N_c / N under other counting rules (force and gap thresholds, walls,
                  rattlers, bulk), for ``tiltpile zcount``
``mohr_coulomb``  the Mohr-Coulomb reading of the clusters' orientation and its test across a
                  friction study (``tiltpile study``)
``checks``        the checks of the public functions' inputs: a wrong shape, length, index, NaN,
                  radius, column or parameter is refused in one line naming the argument
                  (``"contact_counts: pair must ..., got ..."``; ValueError or TypeError)

Quick use::

    from tiltpile.analysis import load_observables
    frames, clusters = load_observables("data/default")
"""

from .avalanche import (
    ResolutionWarning,
    criterion_resolution,
    displacement_since_period_start,
    first_slide,
    frame_spacing_check,
    onset_robustness,
    onset_robustness_ensemble,
    resegment,
    run_onsets,
    segment_avalanches,
    stretches,
    theta_relative_to_onset,
)
from .clusters import (
    cluster_sizes,
    cluster_table,
    critical_clusters,
    critical_grains,
    gyration_axes,
    orientation_to_gravity,
)
from .contacts import (
    active_mask,
    bottom_layer,
    bulk_coordination,
    bulk_mask,
    contact_counts,
    contact_gaps,
    coordination,
    displacement,
    dz_gen,
    dz_local,
    failing_grains,
    gravity_vector,
    kinetic_energy,
    lost_contacts,
    mobilized_mask,
    pair_keys,
    rattler_mask,
    top_layer,
)
from .tables import column_code  # noqa: F401
from .observables import (
    CLUSTER_COLUMNS,
    DEFAULT_PARAMS,
    FRAME_COLUMNS,
    compute_observables,
    frame_observables,
    load_observables,
    run_files,
    run_observables,
    run_table,
)
from .stats import (
    InsufficientDataError,
    PoorFitWarning,
    PowerLawCutoffFit,
    bimodality,
    bootstrap_ci,
    bootstrap_runs_ci,
    cluster_peaks,
    cluster_size_windows,
    correlation_function,
    correlation_function_ensemble,
    density_2d,
    discrete_log_binned_density,
    dz_by_size,
    dz_distribution,
    failure_enhancement,
    failure_enhancement_ensemble,
    fit_power_law_cutoff,
    ke_threshold,
    log_binned_density,
    lost_fraction_edges,
    power_law_departure,
    sample_power_law_cutoff,
)

__all__ = [name for name in dir() if not name.startswith("_")
           and name not in ("avalanche", "checks", "clusters", "contacts", "observables", "stats")]
