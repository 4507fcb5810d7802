"""Fig. 2 -- the avalanche criterion and the generalized isostaticity diagram (paper Fig. 2).

(a) Probability density of the kinetic energy per mobile grain over all frames and runs
    (log-binned, :func:`tiltpile.analysis.log_binned_density`), with the threshold where it leaves
    the power law of the quiet region (:func:`tiltpile.analysis.stats.power_law_departure`,
    estimator below); beneath it the density divided by the fitted law, with the rule's band of a
    factor ``ke_factor`` either side of 1, where the break the threshold stands for is seen (on a
    density spanning twenty decades a factor of 2 is not).
(b) Density (per decade) of the fraction of contacts lost between successive frames, for the
    frames that lose at least one contact, on bins that respect the integer counts
    (:func:`tiltpile.analysis.stats.lost_fraction_edges`, Freedman-Diaconis width on log10);
    the frames losing none (about half of them: they cannot be placed on the log axis) are given
    as a fraction on the panel and stay in the normalisation. The avalanche cutoff (2% by default)
    is drawn, with a two-Gaussian fit in log10 of the fraction whose separation (Ashman's D,
    valley depth, BIC against one Gaussian; :func:`tiltpile.analysis.stats.bimodality`) tells
    whether the frames fall into two populations, as the paper says, with the cutoff between them.
(c) delta z_gen = z - 3 - n_m of the bulk against theta for a sample run, avalanching frames
    shaded, the run's first sustained flow (dotted, "flow") and its avalanche angle (dash-dotted,
    "slide").
(d) Probability density of (z, n_m) over all frames (:func:`tiltpile.analysis.density_2d`), with
    the sample run's trace (quiet black, avalanching red) and the marginal line z = 3 + n_m.

Three onsets per run (:func:`tiltpile.analysis.run_table`), each with a bootstrap interval over
runs: the first frame losing more than the cutoff (the paper's theta_m); the first sustained flow
("slide" in the numbers' names), the first stretch of frames whose kinetic energy per grain stays
above the panel-a threshold over at least ``slide_sustain_deg`` of tilt
(:func:`tiltpile.analysis.first_slide`); and the avalanche angle, the same with a fixed threshold
``avalanche_ke`` (1e-3 m g d per grain: the large slide of ``tiltpile repose`` and the paper
preset's ``protocol.end_ke``), the angle Deboeuf et al. (2005) call theta_a. With 1000 grains the
panel-a threshold is of the same order (4e-4 to 1.6e-3) and the two coincide where both are seen;
with 4000 grains it falls to a few 1e-6, below a slow flow of 1e-5 to 6e-4 per grain that comes
some 3 deg before the slide (docs/figures.md).

Kinetic-energy threshold (paper: "the value above which the distribution escapes the power law
reported in the quiet region"): a straight line log10 P = a + b log10 E is fitted, weighted by
sqrt(count) (Poisson error of log P), to the log bins whose centres lie between two quantiles of
the quiet frames' energies (default 30% and 80%: above the rest peak of the freshly deposited
pile, below the energies of the frames just before failure); going up from the fitted range, the
threshold is the lower edge of the first bin from which ``n_consecutive`` successive bins all lie
off the line by more than ``factor`` (empty bins count as off).

How firm the numbers picked from the pooled runs are (``stability``): the threshold, the ends of
its fitted range and panel b's valley are recomputed with each run left out in turn. A bin-picked
threshold takes a few distinct values; where one left-out run moves it (``firm`` false) panel a
draws its other values too (dashed) and says in its top that the threshold is not stable, with how
many left-out runs give each value and the criteria the analysis uses instead (the onsets: the
lost-contact cutoff of panel b; the avalanche angle: the fixed ``avalanche_ke``;
:func:`ke_stability_note`), and the report's per-scale table flags it: on the cycled
4000-grain piles the departure rule sits on its factor of 2 and the threshold is bistable
(docs/figures.md).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from tiltpile.analysis import run_table
from tiltpile.analysis.ensemble_data import first_onsets
from tiltpile.analysis import stats as _st
from tiltpile.analysis.avalanche import (SPACING_LIMIT, ResolutionWarning, frame_spacing_check,
                                         onset_robustness_ensemble, stretches)
from tiltpile.analysis.stats import power_law_departure  # noqa: F401  (the estimator of panel a)
from tiltpile.paper_values import SLIDE_KE

from . import style
from .data import Reads, analysis_params, per_run_quiet

# the table columns the figure reads (from records, only these are checked)
READS = Reads("Fig. 2",
              frames=("theta_deg", "z", "n_m", "dz_gen", "n_active", "ke_trans", "ke_rot",
                      "n_lost", "lost_fraction", "avalanching", "onset", "theta_m"),
              clusters=())

NAME = "fig2_avalanche_criterion"
# the first large slide is read from the per-run table: its analysis parameters are this figure's
READS_RUN_TABLE = True
AVALANCHE_KE = SLIDE_KE.value    # m g d per mobile grain: the avalanche angle's threshold


def _stats(x) -> dict:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return {"mean": float(x.mean()) if x.size else np.nan,
            "std": float(x.std(ddof=1)) if x.size > 1 else np.nan,
            "min": float(x.min()) if x.size else np.nan,
            "max": float(x.max()) if x.size else np.nan, "n": int(x.size)}


def _max_abs(x) -> float:
    x = np.abs(np.asarray(x, dtype=float))
    x = x[np.isfinite(x)]
    return float(x.max()) if x.size else np.nan


def _ci(prefix: str, ci: dict) -> dict:
    """{prefix_ci_low, prefix_ci_high} of a :func:`tiltpile.analysis.stats.bootstrap_ci` result."""
    return {f"{prefix}_ci_low": ci["low"], f"{prefix}_ci_high": ci["high"]}


def compute(ens, sample_seed: int | None = None, ke_column: str = "ke_trans",
            ke_bins_per_decade: int = 5, ke_fit_quantiles=(0.3, 0.8), ke_factor: float = 2.0,
            ke_consecutive: int = 2, lost_bins_per_decade: int | None = None, zn_bins=30,
            robustness_cutoffs=(0.01, 0.02, 0.03, 0.04), max_shift: int = 10,
            slide_sustain_deg: float | None = None, avalanche_ke: float = AVALANCHE_KE,
            confidence: float = 0.95) -> tuple[dict, dict]:
    """Numbers and plot data of Fig. 2 (module docstring).

    sample_seed: run of panels c, d (None: the first run with an onset); ke_column: "ke_trans"
    or "ke_rot"; ke_bins_per_decade, ke_fit_quantiles, ke_factor, ke_consecutive: the KE density
    and threshold estimator (:func:`tiltpile.analysis.stats.ke_threshold`); lost_bins_per_decade:
    panel b (None: Freedman-Diaconis on log10 of the lost fraction,
    :func:`tiltpile.analysis.stats.lost_fraction_edges`); zn_bins: bins of the (z, n_m) density
    (numpy.histogram2d); robustness_cutoffs, max_shift:
    :func:`tiltpile.analysis.onset_robustness_ensemble` against the ensemble's cutoff;
    slide_sustain_deg: the least span of a slide (None: the analysis parameter,
    :data:`tiltpile.analysis.DEFAULT_PARAMS`); avalanche_ke: the avalanche angle's threshold (KE per
    grain, m g d; > 0); confidence: of the bootstrap intervals over runs
    (:func:`tiltpile.analysis.stats.bootstrap_ci`, BCa, 9999 resamples, seed 0).

    numbers:
      cutoff                       the avalanche cutoff on the lost fraction
      theta_m_per_run              theta of each run's first onset by the cutoff (deg, seeds in
                                   ens.seeds order; null without onset)
      theta_m_mean, _std (ddof 1), _min, _max, n_runs_with_onset, theta_m_ci_low, _ci_high
      n_onsets                     all onsets of all runs
      slide_ke, slide_sustain_deg  the slide detector: KE per grain threshold (the panel-a
                                   threshold unless the analysis parameter slide_ke is set) and
                                   the least span (:func:`tiltpile.analysis.first_slide`)
      theta_slide_per_run          theta of each run's first sustained slide (null: none before
                                   the end of the tilt, theta_end_min)
      theta_slide_mean, _std, _min, _max, n_runs_with_slide, theta_slide_ci_low, _ci_high
      slide_minus_onset_mean       mean over runs with both of (first slide - first onset), deg
      theta_end_min                smallest final tilt of a run (a later slide is not seen)
      avalanche_ke                 the avalanche angle's threshold (KE per grain), with the same
                                   least span slide_sustain_deg
      theta_avalanche_per_run      theta of each run's avalanche (null: none before the end)
      theta_avalanche_mean, _std, _min, _max, n_runs_with_avalanche, theta_avalanche_ci_low,
      _ci_high, avalanche_minus_onset_mean   as for the slide
      avalanching_fraction         fraction of all frames that are avalanching
      z_quiet_mean, n_m_quiet_mean, dz_gen_quiet_mean   over quiet frames (bulk, pooled)
      quiet_below_fraction         fraction of quiet frames with delta z_gen < 0 (pooled)
      z_quiet_run_mean, n_m_quiet_run_mean, quiet_below_run_mean   means over runs of the
                                   per-run quiet means, each with _ci_low, _ci_high
      ke_column, ke_threshold      KE per grain where the density leaves the quiet power law
      ke_slope, ke_fit_range       fitted exponent and the fitted KE range
      ke_threshold_avalanching_above, ke_threshold_quiet_above
                                   fraction of avalanching / quiet frames with KE above the
                                   threshold (how well the KE criterion agrees with the
                                   lost-contact one)
      ke_first_onset_per_run       KE per grain (ke_column) of each run's first onset frame, in
                                   theta_m_per_run's order (null without onset): how much the
                                   pile moves when the 2% criterion first fires
      lost_zero_fraction           frames that lose no contact (drawn apart in panel b)
      n_active_mean                mean number of active contacts of a frame (the cutoff's scale)
      lost_bins_per_decade         the bins of panel b (Freedman-Diaconis unless given)
      lost_bimodality              :func:`tiltpile.analysis.stats.bimodality` of log10 of the
                                   lost fraction of the frames losing >= 1 contact (counts
                                   dequantized): delta_bic, ashman_d, valley_depth, valley (as a
                                   fraction, not log10), means/sds (log10), cutoff_between_means,
                                   cutoff_density_ratio
      onset_shift_max_frames       max |shift| of matched onsets over the robustness cutoffs
      onset_shift_median_frames    median |shift| over (onset, cutoff != reference) pairs, an
                                   onset without partner counting as more than max_shift
      onset_shift_max_frames_by_cutoff   the same per cutoff
      onset_shift_max_deg          max |shift| in degrees
      first_onset_shift_max_frames max |shift| of each run's first onset
      onset_unmatched_fraction     (onset, cutoff) pairs with no onset within max_shift frames
      onset_cutoffs_unresolved     robustness cutoffs that the frame spacing does not resolve in
                                   some run (:func:`tiltpile.analysis.frame_spacing_check`)
      stability                    leave-one-run-out of the numbers picked from the pooled runs
                                   (:func:`tiltpile.analysis.stats.loo_stability`): ke_threshold
                                   (per_run_left_out in seeds order, its distinct values and
                                   their counts, flip_share, firm; low, high, jackknife_se),
                                   ke_fit_lo, ke_fit_hi (the fitted range's ends) and
                                   lost_valley (panel b's valley, per_run_left_out): low, high,
                                   jackknife_se
      sample_seed
    """
    if not avalanche_ke > 0.0:
        raise ValueError(f"avalanche_ke must be > 0 (m g d per grain), got {avalanche_ke}")
    p = analysis_params(ens)
    cutoff = float(p["cutoff"])
    f = ens.frames.sort_values(["run", "frame"], kind="stable")
    av = f["avalanching"].to_numpy(bool)
    dep, ke_dens = _st.ke_threshold(f, ke_column, ke_bins_per_decade, ke_fit_quantiles, ke_factor,
                                    ke_consecutive)                                     # (a)
    sustain = p["slide_sustain_deg"] if slide_sustain_deg is None else float(slide_sustain_deg)
    slide_ke = p["slide_ke"] if p["slide_ke"] is not None else dep["threshold"]
    th, onset_numbers = _first_onsets(f, ens.seeds, confidence)
    sl, slide_numbers = _first_slides(f, ens.seeds, th, slide_ke, sustain, confidence)
    aa, avalanche_numbers = _first_slides(f, ens.seeds, th, avalanche_ke, sustain, confidence,
                                          "avalanche")
    lost_numbers, lost_data = _lost_fraction(f, cutoff, lost_bins_per_decade)         # (b)
    stability = _stability(f, ens.seeds, dep, lost_numbers["lost_bimodality"], ke_column,
                           ke_bins_per_decade, ke_fit_quantiles, ke_factor, ke_consecutive)
    seed = ens.sample_seed(sample_seed)
    numbers = {"cutoff": cutoff, **onset_numbers, **slide_numbers, **avalanche_numbers,
               "avalanching_fraction": float(av.mean()) if av.size else np.nan,
               **_quiet_network(f, av, ens.seeds, confidence),
               **_ke_numbers(f, av, dep, ke_column),
               "ke_first_onset_per_run": _ke_at_first_onsets(f, ens.seeds, ke_column),
               **lost_numbers,
               **_robustness(f, cutoff, robustness_cutoffs, max_shift, p["merge_gap"]),
               "stability": stability, "sample_seed": seed}
    data = {"cutoff": cutoff, "ke_density": ke_dens, "ke_fit": dep, "ke_column": ke_column,
            "ke_stability": stability["ke_threshold"], "ke_factor": float(ke_factor),
            "avalanche_ke": float(avalanche_ke),
            **lost_data, **_sample(f, ens.seeds, seed, sl, aa, ke_column, zn_bins)}       # (c), (d)
    return numbers, data


def _first_onsets(f: pd.DataFrame, seeds, confidence: float) -> tuple[np.ndarray, dict]:
    """Each run's first onset by the cutoff (theta_m, deg, in ``seeds`` order; NaN without one)
    and its numbers: per run, summary, bootstrap interval over runs, and the count of all onsets."""
    th = first_onsets(f, seeds)
    st = _stats(th)
    return th, dict(theta_m_per_run=th, theta_m_mean=st["mean"], theta_m_std=st["std"],
                    theta_m_min=st["min"], theta_m_max=st["max"], n_runs_with_onset=st["n"],
                    **_ci("theta_m", _st.bootstrap_ci(th, confidence=confidence)),
                    n_onsets=int(f["onset"].astype(bool).sum()))


def _first_slides(f: pd.DataFrame, seeds, th: np.ndarray, slide_ke, sustain,
                  confidence: float, name: str = "slide") -> tuple[np.ndarray, dict]:
    """Each run's first slide (deg, in ``seeds`` order; NaN: none before the end of its tilt):
    kinetic energy per grain above ``slide_ke`` over at least ``sustain`` deg
    (:func:`tiltpile.analysis.run_table`; no slide is looked for when ``slide_ke`` is not finite),
    and its numbers, with the gap to the first onsets ``th`` and the smallest final tilt. ``name``
    names the numbers (theta_<name>_per_run, <name>_ke, ...); the span and the final tilt, which
    every detector shares, are written by the "slide" one only."""
    rt = (run_table(f, slide_ke=float(slide_ke), slide_sustain_deg=sustain)
          if np.isfinite(slide_ke) else None)
    if rt is not None:
        by = rt.set_index("run")
        sl = np.array([float(by["theta_first_slide"].get(s, np.nan)) for s in seeds])
        ends = rt["theta_end"].to_numpy(float)
    else:
        sl = np.full(len(seeds), np.nan)
        ends = np.array([float(g["theta_deg"].max()) for _, g in f.groupby("run")])
    ss = _stats(sl)
    both = np.isfinite(sl) & np.isfinite(th)
    t = f"theta_{name}"
    out = {f"{name}_ke": float(slide_ke),
           **({"slide_sustain_deg": float(sustain)} if name == "slide" else {}),
           f"{t}_per_run": sl, f"{t}_mean": ss["mean"], f"{t}_std": ss["std"],
           f"{t}_min": ss["min"], f"{t}_max": ss["max"], f"n_runs_with_{name}": ss["n"],
           **_ci(t, _st.bootstrap_ci(sl, confidence=confidence)),
           f"{name}_minus_onset_mean": float(np.mean(sl[both] - th[both])) if both.any() else np.nan}
    if name == "slide":
        out["theta_end_min"] = float(np.min(ends)) if ends.size else np.nan
    return sl, out


def _quiet_network(f: pd.DataFrame, av: np.ndarray, seeds, confidence: float) -> dict:
    """z, n_m and delta z_gen of the quiet frames (``av`` false): pooled means, the fraction below
    the marginal line, and the means over runs of the per-run quiet means with their intervals."""
    q = f[~av]
    dzq = q["dz_gen"].to_numpy(float)
    dzq = dzq[np.isfinite(dzq)]
    out = dict(z_quiet_mean=_stats(q["z"])["mean"], n_m_quiet_mean=_stats(q["n_m"])["mean"],
               dz_gen_quiet_mean=float(dzq.mean()) if dzq.size else np.nan,
               quiet_below_fraction=float((dzq < 0).mean()) if dzq.size else np.nan)
    pr = per_run_quiet(f, seeds)
    for col, key in (("z", "z_quiet_run_mean"), ("n_m", "n_m_quiet_run_mean"),
                     ("below", "quiet_below_run_mean")):
        ci = _st.bootstrap_ci(pr[col], confidence=confidence)
        out[key] = ci["estimate"]
        out.update(_ci(key, ci))
    return out


def _ke_numbers(f: pd.DataFrame, av: np.ndarray, dep: dict, ke_column: str) -> dict:
    """Panel a's numbers: the threshold and its fit (``dep``, :func:`tiltpile.analysis.stats.
    ke_threshold`), and the fractions of avalanching and quiet frames above the threshold."""
    thr = dep["threshold"]
    ke = f[ke_column].to_numpy(float)
    ok = np.isfinite(ke)
    above = ke > thr if np.isfinite(thr) else np.zeros_like(ok)
    return dict(ke_column=ke_column, ke_threshold=thr, ke_slope=dep["slope"],
                ke_fit_range=[dep["fit_lo"], dep["fit_hi"]],
                ke_threshold_avalanching_above=float(above[av & ok].mean())
                if (av & ok).any() and np.isfinite(thr) else np.nan,
                ke_threshold_quiet_above=float(above[~av & ok].mean())
                if (~av & ok).any() and np.isfinite(thr) else np.nan)


def _stability(f: pd.DataFrame, seeds, dep: dict, bm: dict, ke_column: str, *ke_args) -> dict:
    """How firm the numbers chosen from the pooled runs are: each with one run left out in turn
    (:func:`tiltpile.analysis.stats.loo_stability`). The panel-a threshold (a bin: its distinct
    leave-one-out values, how many left-out runs give each, the share whose removal flips it) and
    the ends of its fitted range (their spread); the valley of panel b's two populations (its
    spread), refitted from the full fit (``bimodality(init=...)``) on the same dequantized samples
    less the run's."""
    from tiltpile.analysis.stats import leave_one_run_out, loo_stability

    def threshold(g):
        return _st.ke_threshold(g, ke_column, *ke_args)[0]

    deps = leave_one_run_out(f, seeds, threshold)
    thr = [d["threshold"] for d in deps]
    out = {"ke_threshold": {"per_run_left_out": thr,
                            **loo_stability(dep["threshold"], thr, discrete=True)},
           "ke_fit_lo": loo_stability(dep["fit_lo"], [d["fit_lo"] for d in deps]),
           "ke_fit_hi": loo_stability(dep["fit_hi"], [d["fit_hi"] for d in deps])}
    nl = np.where(np.isfinite(f["lost_fraction"].to_numpy(float)), f["n_lost"].to_numpy(float), np.nan)
    na = f["n_active"].to_numpy(float)
    y = _st.dequantized_log_fraction(nl, na, seed=0)
    ok = np.isfinite(nl) & np.isfinite(na) & (nl >= 1) & (na > 0)     # the samples y holds
    run = f["run"].to_numpy()[ok]
    valleys = []
    for s in seeds:
        if not np.isfinite(bm["valley"]):
            valleys.append(np.nan)
            continue
        b = _st.bimodality(y[run != s], init=bm)
        valleys.append(float(10 ** b["valley"]) if np.isfinite(b["valley"]) else np.nan)
    out["lost_valley"] = {"per_run_left_out": valleys, **loo_stability(bm["valley"], valleys)}
    return out


def _ke_at_first_onsets(f: pd.DataFrame, seeds, ke_column: str) -> np.ndarray:
    """KE per grain (``ke_column``) of each run's first onset frame, in ``seeds`` order (NaN for a
    run without onset; the frame is the one :func:`tiltpile.analysis.first_onsets` takes)."""
    on = f[f["onset"].astype(bool)].sort_values(["run", "frame"], kind="stable")
    first = on.groupby("run")[ke_column].first()
    return np.array([float(first.get(s, np.nan)) for s in seeds])


def _lost_fraction(f: pd.DataFrame, cutoff: float,
                   lost_bins_per_decade: int | None) -> tuple[dict, dict]:
    """Panel b: the density per decade of the lost fraction of the frames losing >= 1 contact, on
    count-respecting log bins (the frames losing none apart, in the normalisation), and the two
    populations (:func:`tiltpile.analysis.stats.bimodality` of the dequantized log10 fraction).
    Returns (numbers, plot data)."""
    lf = f["lost_fraction"].to_numpy(float)
    fin = np.isfinite(lf)
    nl = np.where(fin, f["n_lost"].to_numpy(float), np.nan)
    na = f["n_active"].to_numpy(float)
    bpd = (_st.fd_bins_per_decade(lf[fin & (lf > 0)]) if lost_bins_per_decade is None
           else int(lost_bins_per_decade))
    edges = _st.lost_fraction_edges(nl, na, bpd)
    pos = lf[fin & (lf > 0)]
    n_fin = int(fin.sum())
    if edges.size >= 2 and pos.size:
        count, _ = np.histogram(pos, bins=edges)
        lw = np.log10(edges[1:] / edges[:-1])
        lost = pd.DataFrame({"left": edges[:-1], "right": edges[1:],
                             "center": np.sqrt(edges[:-1] * edges[1:]), "count": count,
                             "density": count / (n_fin * lw)})    # per decade of the fraction
    else:
        lost = pd.DataFrame(columns=["left", "right", "center", "count", "density"])
    zero = float(np.mean(lf[fin] <= 0)) if n_fin else np.nan
    y = _st.dequantized_log_fraction(nl, na, seed=0)
    bm = _st.bimodality(y, cutoff=np.log10(cutoff))
    bm["valley"] = float(10 ** bm["valley"]) if np.isfinite(bm["valley"]) else np.nan
    numbers = {"lost_zero_fraction": zero, "lost_bins_per_decade": int(bpd), "lost_bimodality": bm,
               "n_active_mean": float(np.nanmean(na)) if np.isfinite(na).any() else np.nan}
    data = {"lost_density": lost, "lost_zero_fraction": zero, "lost_mixture": bm,
            "lost_n_finite": n_fin}
    return numbers, data


def _robustness(f: pd.DataFrame, cutoff: float, robustness_cutoffs, max_shift: int,
                merge_gap) -> dict:
    """How far the onsets move when the cutoff is varied
    (:func:`tiltpile.analysis.onset_robustness_ensemble` against ``cutoff``).

    The cutoffs are varied on purpose, so the library's ResolutionWarning (frames too far apart
    for a cutoff: the quiet frames' median lost fraction exceeds half of it) is not issued here but
    reported: onset_cutoffs_unresolved lists the cutoffs it flags in at least one run."""
    unresolved = sorted({float(c) for c in robustness_cutoffs for _, g in f.groupby("run")
                         if frame_spacing_check(g["lost_fraction"].to_numpy(float), c,
                                                warn=False) > SPACING_LIMIT})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResolutionWarning)
        rob = onset_robustness_ensemble(f, cutoffs=robustness_cutoffs, reference=cutoff,
                                        max_shift=max_shift, merge_gap=merge_gap)
    out: dict = {"onset_cutoffs_unresolved": unresolved}
    if len(rob):
        by_cut = {f"{c:g}": _max_abs(g["shift_frames"]) for c, g in rob.groupby("cutoff")}
        first = rob[rob["onset"] == 0]
        other = rob[~np.isclose(rob["cutoff"], cutoff)]
        sh = np.abs(other["shift_frames"].to_numpy(float))
        sh[~np.isfinite(sh)] = np.inf                # no partner: moved by more than max_shift
        med = float(np.median(sh)) if sh.size else np.nan
        out.update(onset_shift_max_frames=_max_abs(rob["shift_frames"]),
                   onset_shift_median_frames=med if np.isfinite(med) else None,
                   onset_shift_max_frames_by_cutoff=by_cut,
                   onset_shift_max_deg=_max_abs(rob["shift_deg"]),
                   first_onset_shift_max_frames=_max_abs(first["shift_frames"]),
                   onset_unmatched_fraction=float(rob["shift_frames"].isna().mean()))
    else:
        out.update(onset_shift_max_frames=np.nan, onset_shift_median_frames=np.nan,
                   onset_shift_max_frames_by_cutoff={},
                   onset_shift_max_deg=np.nan, first_onset_shift_max_frames=np.nan,
                   onset_unmatched_fraction=np.nan)
    return out


def _sample(f: pd.DataFrame, seeds, seed, sl: np.ndarray, aa: np.ndarray, ke_column: str,
            zn_bins) -> dict:
    """Plot data of panels c and d: the sample run ``seed`` (its frames, its first sustained flow
    and its avalanche angle, from the per-run angles ``sl`` and ``aa`` in ``seeds`` order) and
    the (z, n_m) density of all frames (None when there are too few)."""
    i = list(seeds).index(seed) if seed in seeds else None
    out = {"sample": f[f["run"] == seed][["frame", "theta_deg", "z", "n_m", "dz_gen",
                                           "avalanching", ke_column]].reset_index(drop=True),
           "sample_slide": float(sl[i]) if i is not None else np.nan,
           "sample_avalanche": float(aa[i]) if i is not None else np.nan}
    try:
        out["zn_density"] = _st.density_2d(f["z"], f["n_m"], bins=zn_bins)
    except _st.InsufficientDataError:
        out["zn_density"] = None
    out["sample_seed"] = seed
    return out


# panel a's parts (inches): the density, the ratio to its law below it, and per line of the note
# (when there is one) the room added above the density
KE_PANEL_IN, KE_RATIO_IN, NOTE_LINE_IN, NOTE_PAD_IN = 1.3, 0.6, 0.096, 0.06


def plot(data: dict, numbers: dict):
    """Panels a-d (module docstring). Panel a is split: the density over its power law, and
    below it the density divided by the law, where the departure the threshold stands for is
    seen (the rule's band of a factor ``ke_factor`` either side of 1). Where the threshold is
    not stable (:func:`ke_stability_note`), the top of the panel says so, above the data."""
    note = ke_stability_note(data, numbers)
    room_in = NOTE_LINE_IN * (note.count("\n") + 1) + NOTE_PAD_IN if note else 0.0
    top_in = KE_PANEL_IN + room_in + KE_RATIO_IN
    height, gkw = style.stacked_layout([top_in, 1.45], [0.5], top_in=0.05, bottom_in=0.38,
                                       left=0.14, right=0.97)
    fig, axs = style.figure(2, 2, height=height, gridspec_kw=dict(gkw, wspace=0.42))
    (a, b), (c, dd) = axs
    sub = a.get_subplotspec().subgridspec(2, 1, height_ratios=[KE_PANEL_IN + room_in, KE_RATIO_IN],
                                          hspace=0.0)
    a.remove()
    a = fig.add_subplot(sub[0])
    ar = fig.add_subplot(sub[1], sharex=a)
    room = room_in / (KE_PANEL_IN + room_in)
    _plot_ke(a, data, room=room)
    _plot_ke_ratio(ar, data)
    _note_ke_stability(a, note, room)
    _plot_lost(b, data)
    _plot_dz_gen(c, data)
    _plot_zn(dd, data)
    return fig


def _plot_ke(a, data: dict, room: float = 0.0) -> None:
    """Panel a: the kinetic-energy density, the fitted power law over its range, and the
    threshold where the density leaves it; the top share ``room`` of the panel is left to the
    note (:func:`_note_ke_stability`)."""
    from matplotlib.ticker import NullFormatter
    ke, dep = data["ke_density"], data["ke_fit"]
    if len(ke):
        nz = ke["count"].to_numpy() > 0
        a.loglog(ke["center"][nz], ke["density"][nz], ls="none", marker="o", ms=2.5,
                 color=style.COLORS["quiet"])
        xc = ke["center"].to_numpy(float)
        if np.isfinite(dep["slope"]):
            x_hi = dep["threshold"] * 3 if np.isfinite(dep["threshold"]) else xc[-1]
            x = np.array([dep["fit_lo"] / 30, x_hi])
            a.loglog(x, 10 ** (dep["intercept"] + dep["slope"] * np.log10(x)), ls="--", lw=0.8,
                     color=style.COLORS["fit"], label=rf"$\propto E^{{{dep['slope']:.2f}}}$")
            a.axvspan(dep["fit_lo"], dep["fit_hi"], ymax=1.0 - room, color=style.COLORS["guide"],
                      alpha=0.15, lw=0)
        if np.isfinite(dep["threshold"]):
            # the threshold as a line through both parts of the panel (the ratio below shows
            # the departure it marks); its values with one run left out, where they differ,
            # dashed (the JSON's stability; the note says how many left-out runs give each)
            a.axvline(dep["threshold"], ymax=1.0 - room, color=style.COLORS["avalanche"], lw=1.0,
                      label=f"threshold {dep['threshold']:.1e}".replace("e-0", "e-"),
                      gid="ke_threshold")
            st = data.get("ke_stability") or {}
            other = [v for v in st.get("values", [])
                     if v is not None and v != dep["threshold"] and np.isfinite(v)]
            for v in other:
                a.axvline(v, ymax=1.0 - room, color=style.COLORS["avalanche"], lw=0.7, ls="--",
                          gid="ke_threshold_one_run_out")
        a.legend(loc="lower left", handlelength=1.5)
    unit = _ke_unit(data)
    a.set_ylabel(r"$P($" + unit + r"$)$")
    style.panel_label(a, "a", x=0.88)
    a.xaxis.set_minor_formatter(NullFormatter())
    a.yaxis.set_minor_formatter(NullFormatter())
    a.tick_params(labelbottom=False)


def _ke_unit(data: dict) -> str:
    return {"ke_trans": r"$E_t$", "ke_rot": r"$E_r$"}.get(data["ke_column"], "E")


def _plot_ke_ratio(ar, data: dict) -> None:
    """Panel a, below: the density divided by the fitted power law, with the rule's band (a
    factor ``ke_factor`` either side of 1), the fitted range shaded and the threshold (solid;
    its values with one run left out, where they differ, dashed). The break the threshold
    stands for is where the points leave the band for good."""
    from matplotlib.ticker import NullFormatter
    ke, dep = data["ke_density"], data["ke_fit"]
    factor = float(data.get("ke_factor", 2.0))
    ar.axhline(1.0, color=style.COLORS["fit"], lw=0.6, ls="--")
    ar.axhspan(1.0 / factor, factor, color=style.COLORS["marginal"], alpha=0.12, lw=0)
    if len(ke) and np.isfinite(dep["slope"]):
        nz = ke["count"].to_numpy() > 0
        xc = ke["center"].to_numpy(float)[nz]
        law = 10 ** (dep["intercept"] + dep["slope"] * np.log10(xc))
        ratio = ke["density"].to_numpy(float)[nz] / law
        lo, hi = 0.2 / factor, 2.5 * factor
        ar.semilogx(xc, np.clip(ratio, lo, hi), ls="none", marker="o", ms=1.6,
                    color=style.COLORS["quiet"], clip_on=True)
        ar.axvspan(dep["fit_lo"], dep["fit_hi"], color=style.COLORS["guide"], alpha=0.15, lw=0)
        if np.isfinite(dep["threshold"]):
            ar.axvline(dep["threshold"], color=style.COLORS["avalanche"], lw=1.0)
        st = data.get("ke_stability") or {}
        for v in st.get("values", []):
            if v is not None and np.isfinite(v) and v != dep["threshold"]:
                ar.axvline(v, color=style.COLORS["avalanche"], lw=0.7, ls="--")
        ar.set_yscale("log")
        ar.set_ylim(lo, hi)
        ar.set_yticks([1.0 / factor, 1.0, factor])
        ar.set_yticklabels([f"{1.0 / factor:g}", "1", f"{factor:g}"])
        ar.yaxis.set_minor_formatter(NullFormatter())
        ar.tick_params(axis="y", which="minor", left=False, right=False)
    ar.tick_params(axis="y", labelsize=5.5)
    ar.set_ylabel(r"$P$ / law", fontsize=6, labelpad=1)
    ar.set_xlabel(_ke_unit(data) + r" per grain ($\rho g d^3$)")
    ar.xaxis.set_minor_formatter(NullFormatter())


def ke_stability_note(data: dict, numbers: dict) -> str:
    """The panel-a note where leaving one run out moves the threshold (fig2's ``stability``,
    ``firm`` false): its other values, and the criteria the analysis uses instead (the onsets:
    the lost-contact cutoff of panel b; the avalanche angle: the fixed ``avalanche_ke``). ''
    where the threshold is firm or its stability was not measured."""
    st = (numbers.get("stability") or {}).get("ke_threshold") or data.get("ke_stability") or {}
    if not st or st.get("firm", True):
        return ""
    full = data["ke_fit"]["threshold"]
    n = st.get("n")
    other = [f"{v:.1e} ({k} of {n} runs)".replace("e-0", "e-")
             for v, k in zip(st.get("values", []), st.get("counts", []))
             if v is not None and v != full]
    none = sum(1 for v in st.get("per_run_left_out", []) if v is None or not np.isfinite(v))
    if none:
        other.append(f"none ({none} of {n} runs)")
    cutoff = data.get("cutoff", numbers.get("cutoff"))
    ake = data.get("avalanche_ke", numbers.get("avalanche_ke"))
    return ("threshold not stable:\none run left out gives\n" + ",\n".join(other) + ";\n"
            f"the onsets use {100 * cutoff:g}% of contacts\n"
            f"lost (b), the avalanche angle\n"
            + f"{_ke_unit(data)} > {ake:.0e} per grain".replace("e-0", "e-"))


def _note_ke_stability(a, txt: str, room: float) -> None:
    """Panel a: the note ``txt`` (:func:`ke_stability_note`) in the top share ``room`` of the
    panel, the data below it (the threshold lines and the fitted range stop under it). The
    density's tick labels stay off the note and off the bottom edge, where the ratio's are."""
    if a.get_yscale() == "log":          # else nothing was drawn: no density to keep below
        y0, y1 = a.get_ylim()
        span = np.log10(y1) - np.log10(y0)
        ticks = [t for t in a.get_yticks() if t <= y1 and np.log10(t / y0) > 0.05 * span]
        if txt:
            a.set_ylim(y0, 10 ** (np.log10(y0) + span / (1.0 - room)))
        a.set_yticks(ticks)
        a.set_ylim(y0, a.get_ylim()[1])
    if txt:
        a.text(0.03, 0.97, txt, transform=a.transAxes, ha="left", va="top", fontsize=5.0,
               color=style.COLORS["avalanche"], linespacing=1.15)


def _plot_lost(b, data: dict) -> None:
    """Panel b: density per decade of the frames losing >= 1 contact (quiet and avalanching bins
    either side of the cutoff), the two-Gaussian fit of the module docstring, the cutoff, and the
    frames losing none (not on a log axis) as a number."""
    from matplotlib.ticker import NullFormatter
    lo = data["lost_density"]
    bm = data["lost_mixture"]
    if len(lo):
        nz = lo["count"].to_numpy() > 0
        qq = lo["center"].to_numpy() <= data["cutoff"]
        for sel, col, lab in ((qq, style.COLORS["quiet"], "quiet"),
                              (~qq, style.COLORS["avalanche"], "avalanching")):
            b.semilogx(lo["center"][nz & sel], lo["density"][nz & sel], ls="none", marker="s",
                       ms=2.5, color=col, label=lab)
        b.semilogx(lo["center"][nz], lo["density"][nz], ls="-", lw=0.5,
                   color=style.COLORS["guide"], zorder=0)
        if np.isfinite(bm["ashman_d"]):
            n_pos = float(lo["count"].sum())
            scale = n_pos / max(float(data["lost_n_finite"]), 1.0)
            xs = np.linspace(np.log10(lo["left"].iloc[0]), np.log10(lo["right"].iloc[-1]), 300)
            b.semilogx(10 ** xs, scale * _st.mixture_pdf(xs, bm["weights"], bm["means"], bm["sds"]),
                       color=style.COLORS["fit"], lw=0.8, ls="--", label="2 Gaussians", zorder=1)
        b.set_xlim(lo["left"].iloc[0], lo["right"].iloc[-1])
        b.set_ylim(0, float(lo["density"].max()) * 2.4)      # room above the data for the key
    b.axvline(data["cutoff"], color=style.COLORS["avalanche"], lw=1.0,
              label=f"cutoff {100 * data['cutoff']:g}%")
    z0 = data.get("lost_zero_fraction", np.nan)
    txt = f"no contact lost: {100 * z0:.0f}% of frames" if np.isfinite(z0) else ""
    if np.isfinite(bm["ashman_d"]):
        txt += (f"\nAshman $D$ = {bm['ashman_d']:.1f}, valley {bm['valley_depth']:.2f}")
    b.text(0.13, 0.965, txt, transform=b.transAxes, ha="left", va="top", fontsize=5.5)
    b.set_xlabel("fraction of contacts lost")
    b.set_ylabel("density per decade")
    b.legend(loc="upper right", bbox_to_anchor=(1.0, 0.83), handlelength=1.2, fontsize=5.5,
             borderaxespad=0.2, labelspacing=0.25)
    style.panel_label(b, "b")
    b.xaxis.set_minor_formatter(NullFormatter())


def _plot_dz_gen(c, data: dict) -> None:
    """Panel c: delta z_gen of the sample run against theta, its avalanches shaded, its first
    sustained flow dotted and its avalanche angle (the large slide) dash-dotted."""
    s = data["sample"]
    th = s["theta_deg"].to_numpy(float)
    dth = float(np.median(np.diff(th))) if th.size > 1 else 0.1
    for i, j in zip(*stretches(s["avalanching"].to_numpy(bool))):
        c.axvspan(th[i] - dth / 2, th[j - 1] + dth / 2, color=style.COLORS["avalanche_shade"],
                  alpha=0.45, lw=0)
    c.axhline(0, color=style.COLORS["marginal"], lw=0.8)
    c.plot(th, s["dz_gen"], color=style.COLORS["quiet"], lw=0.7)
    for key, ls, label, y in (("sample_slide", ":", "flow ", 0.965), ("sample_avalanche", "-.",
                                                                     "slide ", 0.88)):
        t = data.get(key, np.nan)
        if np.isfinite(t):
            c.axvline(t, color=style.COLORS["avalanche"], lw=0.8, ls=ls)
            c.text(t, y, label, transform=c.get_xaxis_transform(), ha="right", va="top",
                   fontsize=5.5, color=style.COLORS["avalanche"])
    c.set_xlabel(r"$\theta$ (deg)")
    c.set_ylabel(r"$\delta z^{gen} = z - 3 - n_m$")
    c.set_xlim(th.min() if th.size else 0, th.max() if th.size else 1)
    dzs = s["dz_gen"].to_numpy(float)
    dzs = dzs[np.isfinite(dzs)]
    if dzs.size:
        r = max(dzs.max(), 0.0) - min(dzs.min(), 0.0)
        c.set_ylim(min(dzs.min(), 0.0) - 0.05 * r, max(dzs.max(), 0.0) + 0.25 * r)
    style.panel_label(c, "c")
    c.text(0.1, 0.965, f"run {data['sample_seed']}", transform=c.transAxes, ha="left", va="top",
           fontsize=6.5)


def _plot_zn(dd, data: dict) -> None:
    """Panel d: the (z, n_m) density of all frames, the sample run's trace (quiet and
    avalanching frames) and the marginal line z = 3 + n_m."""
    from matplotlib.colors import LogNorm
    s = data["sample"]
    zd = data["zn_density"]
    if zd is not None:
        h, xe, ye = zd
        hm = np.ma.masked_less_equal(h.T, 0)
        if hm.count():
            dd.pcolormesh(xe, ye, hm, cmap="Greys", norm=LogNorm(vmin=hm.min(), vmax=hm.max() * 3),
                          rasterized=True)
        dd.set_xlim(xe[0], xe[-1])
        dd.set_ylim(ye[0], ye[-1])
    avs = s["avalanching"].to_numpy(bool)
    dd.plot(s["z"], s["n_m"], color=style.COLORS["guide"], lw=0.3, zorder=2)
    dd.plot(s["z"][~avs], s["n_m"][~avs], ls="none", marker="o", ms=1.6, mew=0,
            color=style.COLORS["quiet"], zorder=3, label="quiet")
    dd.plot(s["z"][avs], s["n_m"][avs], ls="none", marker="o", ms=2.0, mew=0,
            color=style.COLORS["avalanche"], zorder=4, label="avalanching")
    x0, x1 = dd.get_xlim()
    dd.plot([x0, x1], [x0 - 3.0, x1 - 3.0], color=style.COLORS["marginal"], lw=1.0,
            label="marginal", zorder=5)
    dd.set_xlim(x0, x1)
    y0, y1 = dd.get_ylim()
    dd.set_ylim(min(y0, 0.0), y0 + (y1 - y0) * 1.45)          # room for the legend
    dd.set_xlabel(r"$z$")
    dd.set_ylabel(r"$n_m$")
    dd.legend(loc="upper right", handlelength=1.2, markerscale=1.8)
    style.panel_label(dd, "d")
