"""The paper's claims (Figs. 1-6 and the avalanche angle of its piles), each declared once, in
report order: its judge, then its :class:`Claim` (key, text, the paper's value, the figure whose
numbers it reads, the judge, and the :class:`Rule` the report prints), appended to
``CLAIMS_123`` or ``CLAIMS_456``; ``RULES_PAPER`` is read from them. The paper's numbers come
from :mod:`tiltpile.paper_values`, a tolerance of ours from a constant beside its judge; the
judge compares with them and the rule's text is formatted from them, so the two cannot say
different things. The keys of the numbers are those written by ``tiltpile.figures.figN.compute``.

A judge returns a :class:`Judgement`: its verdict, the code of its reason and the numbers its
sentences quote; the sentences (our value, the note of each reason) are the macros of
``templates/claims.md.j2`` named after the claim's key.
"""

from __future__ import annotations

import math

from tiltpile.paper_values import (AVALANCHE_DEG, DELTA, ENHANCEMENT, FIG5_WINDOWS_DEG,
                                   ONSET_SHIFT_FRAMES, ORIENTATION_DEG, QUIET_DEG, SLIDE_KE, Z_MEAN)

from .judging import (DISAGREES, INCONCLUSIVE, SEPARATION, Claim, Judgement, Rule,
                      interval_of, num, overlaps, verdict_of, wrong_side)
from .judging import sci as _sci


def _history(n: dict) -> str | None:
    """"fresh" for piles freshly deposited (no pretilt), "cycled" for piles tilted back and forth
    before the ramp, None where the figure does not say (written before the header named it)."""
    legs = (n.get("history") or {}).get("pretilt_deg")
    return "fresh" if legs == [] else "cycled" if legs else None


# ------------------------------------------------------------------------------------------------
# Figs. 1-3

CLAIMS_123: list[Claim] = []      # in report order: each appended right after its judge


def _theta_m(n: dict) -> Judgement:
    """Some run stays quiet up to the paper's window: "quiet_run_found"; none does:
    "no_quiet_run" (the note names the kinetic energy of the first onsets, from fig2's
    ke_first_onset_per_run where it wrote them, and the piles' history); no onset: "no_onset"."""
    q = QUIET_DEG.value
    mx = num(n.get("theta_m_max"))
    ke = sorted(v for v in (num(x) for x in (n.get("ke_first_onset_per_run") or []))
                if math.isfinite(v) and v > 0)
    values = {"theta_m": interval_of(n, "theta_m", "theta_m_mean"),
              "n_runs": n.get("n_runs_with_onset"), "min": num(n.get("theta_m_min")), "max": mx,
              "quiet_deg": q, "ke_first_onset": [ke[0], ke[-1]] if len(ke) > 1 else ke,
              "history": _history(n), "history_label": (n.get("history") or {}).get("label")}
    ok = mx >= q
    reason = "no_onset" if not math.isfinite(mx) else "quiet_run_found" if ok else "no_quiet_run"
    return Judgement("theta_m", verdict_of(ok, math.isfinite(mx)), reason, values)


CLAIMS_123.append(Claim(
    "theta_m", "Failure angle theta_m: first onset by the 2% criterion (Fig. 2, 5)",
    f"very variable; quiet up to >= {QUIET_DEG.value:g} deg in some runs", "fig2", _theta_m,
    Rule("\"theta_m, the failure angle [...] known to show considerable statistical variance\"; "
         f"Fig. 5 shows quiet clusters at theta - theta_m = -{QUIET_DEG.value:g} deg.",
         "the first onset by the 2% criterion of each run; agrees if at least one run stays "
         f"quiet up to {QUIET_DEG.value:g} deg (the paper's Fig. 5 needs such runs). Mean with a "
         "BCa bootstrap interval over runs, for information.")))


def _theta_slide(n: dict) -> Judgement:
    """The avalanche angle: each run's first large slide at the fixed threshold ``avalanche_ke``
    (fig2), the same at every scale (the first sustained flow above the Fig. 2a threshold is
    reported beside it in the per-scale table). The median known (more than half of the runs
    slide before the end of their tilt): "median_within" or "median_off" the literature's band;
    only bounded from below: "median_bounded_beyond" (the bound beyond the band) or
    "median_bounded"; no run: "no_runs"."""
    a = AVALANCHE_DEG
    per = [num(v) for v in (n.get("theta_avalanche_per_run") or [])]
    k = sum(math.isfinite(v) for v in per)
    m = len(per)
    end = num(n.get("theta_end_min"))
    fin = sorted(v for v in per if math.isfinite(v))
    known = bool(m and k > m / 2)
    if known:
        # the median is known when more than half of the runs slide before the end of the tilt
        vals = fin + [math.inf] * (m - k)
        med = vals[(m - 1) // 2] if m % 2 else 0.5 * (vals[m // 2 - 1] + vals[m // 2])
        measurable = math.isfinite(med)
        ok = abs(med - a.value) <= a.tol
        reason = "median_within" if ok else "median_off"
    else:
        med = math.nan
        measurable = m > 0 and end > a.hi        # a median beyond the band is known to disagree
        ok = False
        reason = "no_runs" if not m else "median_bounded_beyond" if measurable else "median_bounded"
    values = {"median": med, "median_known": known, "n_slid": k, "n_runs": m, "end": end,
              "slides": fin, "avalanche_ke": num(n.get("avalanche_ke")),
              "sustain_deg": num(n.get("slide_sustain_deg")), "literature": a.value, "tol": a.tol,
              "history": _history(n)}
    return Judgement("theta_slide", verdict_of(ok, measurable), reason, values)


CLAIMS_123.append(Claim(
    "theta_slide", "Avalanche angle: first large slide (Deboeuf et al. 2005)",
    f"~{AVALANCHE_DEG.value:g} deg (4000 grains)", "fig2", _theta_slide,
    Rule(f"the avalanche angle of these piles, theta_a ~ {AVALANCHE_DEG.value:g} deg (Deboeuf et "
         "al. 2005, 4000 grains): the large surface avalanche.",
         "each run's first large slide: kinetic energy per mobile grain above fig2's avalanche_ke "
         f"({_sci(SLIDE_KE.value)} m g d unless given: the slide of `tiltpile repose` and the "
         "paper preset's end of run) over >= slide_sustain_deg of tilt; the same threshold at "
         "every scale, since the Fig. 2a threshold falls from ~1e-3 with 1000 grains to a few "
         "1e-6 with 4000, below a slow flow that precedes the slide (it is reported in the "
         "per-scale table as the first sustained flow). Agrees if the median over runs is within "
         f"{AVALANCHE_DEG.tol:g} deg of {AVALANCHE_DEG.value:g} (the value is quoted without "
         f"error; {AVALANCHE_DEG.tol:g} deg is wider than the frame spacing and the time-step "
         "dependence of the onset, narrower than the gap to the 2% onsets). Runs that do not "
         "slide before the tilt ends count as later; with half of them or more, the median is "
         f"only bounded: inconclusive unless the bound exceeds {AVALANCHE_DEG.hi:g} deg.")))


def _z_mean(n: dict) -> Judgement:
    """The interval of <z> over runs meets the paper's band ("interval_meets_band") or misses it
    ("interval_misses_band"); no interval: "no_interval" (inconclusive, with the note of a
    miss), or "not_measured" without <z> either."""
    lo, hi = num(n.get("z_quiet_run_mean_ci_low")), num(n.get("z_quiet_run_mean_ci_high"))
    z = num(n.get("z_quiet_run_mean"))
    ok = overlaps(lo, hi, Z_MEAN.lo, Z_MEAN.hi)
    reason = ("interval_meets_band" if ok else "interval_misses_band" if math.isfinite(lo) else
              "no_interval" if math.isfinite(z) else "not_measured")
    return Judgement("z_mean", verdict_of(ok, math.isfinite(lo)), reason,
                     {"z": interval_of(n, "z_quiet_run_mean"), "band": [Z_MEAN.lo, Z_MEAN.hi]})


CLAIMS_123.append(Claim(
    "z_mean", "Mean contact number <z> of the pile", f"~{Z_MEAN.value:g}", "fig2", _z_mean,
    Rule(f"\"The average number of contacts for the whole pile is <z> ~ {Z_MEAN.value:g}.\"",
         "mean over runs of the quiet-frame mean z (bulk, no rattlers) with a bootstrap interval "
         f"over runs; agrees if the interval meets [{Z_MEAN.lo:g}, {Z_MEAN.hi:g}], the values "
         f"that round to {Z_MEAN.value:g}.")))


# two populations: the two-Gaussian mixture fits better by more than this BIC difference, and
# separates by more than this Ashman's D (beyond 2 the mixture has two modes)
BIC_GAIN, ASHMAN_D = 10, 2


def _two_populations(n: dict) -> Judgement:
    """"two_separated" (Ashman's D and the BIC gain both above their thresholds),
    "not_separated", or "no_fit" (no mixture fitted)."""
    b = n.get("lost_bimodality") or {}
    d, bic = num(b.get("ashman_d")), num(b.get("delta_bic"))
    ok = d > ASHMAN_D and bic > BIC_GAIN
    reason = "two_separated" if ok else "not_separated" if math.isfinite(d) else "no_fit"
    values = {"ashman_d": d, "valley_depth": num(b.get("valley_depth")),
              "valley": num(b.get("valley")), "delta_bic": bic,
              "zero_fraction": num(n.get("lost_zero_fraction"))}
    return Judgement("two_populations", verdict_of(ok, math.isfinite(d)), reason, values)


CLAIMS_123.append(Claim(
    "two_populations", "Lost fraction between frames: two distinct populations (Fig. 2b)",
    "two populations", "fig2", _two_populations,
    Rule("\"the data clearly fall into two distinct sub-populations\" (Fig. 2b, lost fraction "
         "between frames)",
         "log10 of the lost fraction of the frames losing >= 1 contact (counts dequantized), one "
         f"against two Gaussians; agrees if two fit better (BIC difference > {BIC_GAIN:g}) and "
         f"separate (Ashman's D > {ASHMAN_D:g}, the mixture then has two modes). Frames losing "
         "nothing are reported apart.")))


def _cutoff_in_gap(n: dict) -> Judgement:
    """"cutoff_separates" (at most SEPARATION of either population on its wrong side); else
    "cutoff_beyond_means" (beyond both means) or "cutoff_on_population" (between them, on one
    population: which, and its share on the other side); "no_fit" without the populations. The
    contacts at the cutoff: the cutoff times fig2's n_active_mean (NaN without it)."""
    b = n.get("lost_bimodality") or {}
    cutoff = num(n.get("cutoff"))
    above, below = wrong_side(b, cutoff)
    measurable = math.isfinite(above) and math.isfinite(below)
    ok = measurable and above <= SEPARATION and below <= SEPARATION
    reason = ("cutoff_separates" if ok else "no_fit" if not measurable else
              "cutoff_on_population" if b.get("cutoff_between_means") else "cutoff_beyond_means")
    values = {"means_lost": [10 ** num(m) if m is not None else math.nan
                             for m in b.get("means") or [None, None]],
              "cutoff": cutoff, "above": above, "below": below,
              "density_ratio": num(b.get("cutoff_density_ratio")), "valley": num(b.get("valley")),
              "population": "upper" if below > above else "lower",
              "split_share": max(above, below), "n_grains": n.get("n_grains"),
              "contacts_at_cutoff": cutoff * num(n.get("n_active_mean"))}
    return Judgement("cutoff_in_gap", verdict_of(ok, measurable), reason, values)


CLAIMS_123.append(Claim(
    "cutoff_in_gap", "The 2% cutoff separates the two populations (Fig. 2b)", "cutoff in the gap",
    "fig2", _cutoff_in_gap,
    Rule("\"The good separation between the two populations allows us to apply a cutoff of a "
         "maximum of 2%\"",
         "agrees if the 2% cutoff separates the two fitted populations (Gaussians in log10 of "
         f"the lost fraction): at most {SEPARATION:.0%} of either lies on its wrong side, i.e. "
         "the cutoff is at least one standard deviation from both means, in the valley between "
         "them and not on a population.")))


def _robust(n: dict) -> Judgement:
    """The median shift of the onsets between cutoffs within the paper's frames
    ("median_within") or beyond them ("median_beyond", infinite where most onsets have no
    partner); "not_measured" without onsets compared."""
    raw, unmatched = n.get("onset_shift_median_frames"), num(n.get("onset_unmatched_fraction"))
    # null with onsets compared: most onsets have no partner (a move larger than 10 frames)
    med = math.inf if raw is None and math.isfinite(unmatched) else num(raw)
    ok = med <= ONSET_SHIFT_FRAMES.value
    reason = "median_within" if ok else "not_measured" if math.isnan(med) else "median_beyond"
    values = {"median_shift": med, "max_frames": num(n.get("onset_shift_max_frames")),
              "max_deg": num(n.get("onset_shift_max_deg")), "unmatched": unmatched}
    return Judgement("robust", verdict_of(ok, not math.isnan(med)), reason, values)


CLAIMS_123.append(Claim(
    "robust", "Onset robust to the cutoff (1-4%) within 1-2 frames (Fig. 2b)", "1-2 frames",
    "fig2", _robust,
    Rule("\"varying the cutoff between 1% and 4% [...] typically changes the location of the "
         "onset of the avalanche by 1-2 frames\"",
         "for every onset at 2% the nearest onset at 1, 3 and 4% (none within 10 frames: counted "
         f"as a larger move); agrees if the median |shift| is <= {ONSET_SHIFT_FRAMES.value:g} "
         "frames (\"typically\": the median, not the maximum).")))


# the crossing's first half: the quiet frames below the marginal line (mean over runs, the low
# end of its interval) are at most this share, a frame-resolution allowance; its second half: the
# avalanching frames lie across the line when at least this share of them is below it
# (delta z_gen < 0), said in words
QUIET_BELOW_ALLOWED = 0.01
AVALANCHE_ACROSS, AVALANCHE_ACROSS_WORDS = 0.5, "half"


def _crossing(n: dict) -> Judgement:
    """Both halves of "crosses the marginal stability line only after the start of the
    avalanche": quiet frames above the line (up to a frame-resolution allowance, and above it
    just before an onset) and avalanching frames across it (Fig. 2d: the avalanche occupies a
    region well separated from the quiet one, on the other side of the line). Reasons:
    "both_halves_hold", "quiet_below_line", "avalanche_not_across", "both_halves_fail", and
    "not_measured" (a half that holds, the other unmeasured)."""
    lo = num(n.get("quiet_below_run_mean_ci_low"))
    a = num(n.get("avalanche_below_fraction"))
    pre = num(n.get("dz_gen_pre_onset"))
    quiet_measured = math.isfinite(lo) and math.isfinite(pre)
    quiet_ok, across = lo <= QUIET_BELOW_ALLOWED and pre > 0, a >= AVALANCHE_ACROSS
    quiet_fails, across_fails = quiet_measured and not quiet_ok, math.isfinite(a) and not across
    values = {"quiet_below": interval_of(n, "quiet_below_run_mean"), "avalanche_below": a,
              "dz_gen_pre_onset": pre, "quiet_allowed": QUIET_BELOW_ALLOWED,
              "across_words": AVALANCHE_ACROSS_WORDS}
    if quiet_fails or across_fails:
        reason = ("both_halves_fail" if quiet_fails and across_fails else
                  "quiet_below_line" if quiet_fails else "avalanche_not_across")
        return Judgement("crossing", DISAGREES, reason, values)
    measured = quiet_measured and math.isfinite(a)
    return Judgement("crossing", verdict_of(True, measured),
                     "both_halves_hold" if measured else "not_measured", values)


CLAIMS_123.append(Claim(
    "crossing", "The pile crosses the marginal line only after the onset (Figs. 1, 2d)",
    "quiet frames above the line, avalanching frames across it", "fig1", _crossing,
    Rule("\"the system crosses the marginal stability line only after the start of the "
         "avalanche\"",
         "both halves: before the onset, the fraction of quiet frames with delta z_gen < 0, mean "
         f"over runs with a bootstrap interval, reaches down to {QUIET_BELOW_ALLOWED:.0%} (a "
         "frame-resolution allowance) and the mean delta z_gen of the frames just before an "
         f"onset is > 0; after it, at least {AVALANCHE_ACROSS_WORDS} of the avalanching frames "
         "have delta z_gen < 0 (the paper's Fig. 2d puts the avalanche in a region of its own, "
         "across the line from the quiet one). Agrees if both hold, disagrees if either fails.")))


def _orientation(n: dict) -> Judgement:
    """The mean orientation "within_tol" of the paper's or "off" it; "not_measured"."""
    o = ORIENTATION_DEG
    m = num(n.get("orientation_mean_deg"))
    ok = abs(m - o.value) <= o.tol
    reason = "within_tol" if ok else "off" if math.isfinite(m) else "not_measured"
    values = {"mean": m, "median": num(n.get("orientation_median_deg")),
              "n_clusters": n.get("n_clusters_orientation")}
    return Judgement("orientation", verdict_of(ok, math.isfinite(m)), reason, values)


CLAIMS_123.append(Claim(
    "orientation", "Cluster orientation to gravity (Fig. 3 top)", f"~{ORIENTATION_DEG.value:g} deg",
    "fig3", _orientation,
    Rule(f"clusters align at \"roughly {ORIENTATION_DEG.value:g} deg\" to gravity",
         "mean angle of the long axis of clusters of >= 5 grains to gravity; agrees within "
         f"{ORIENTATION_DEG.tol:g} deg (\"roughly\").")))


# "much higher than if both events were uncorrelated": at least this many times the
# uncorrelated line
ENRICHMENT_MIN = 1.5


def _failure_in_clusters(n: dict) -> Judgement:
    """"enriched" (above the uncorrelated line, by ENRICHMENT_MIN or more), "not_enriched",
    "not_measured"."""
    x, r = num(n.get("failing_in_cluster_excess")), num(n.get("failing_in_cluster_enrichment"))
    ok, measurable = x > 0 and r >= ENRICHMENT_MIN, math.isfinite(x) and math.isfinite(r)
    reason = "enriched" if ok else "not_enriched" if measurable else "not_measured"
    return Judgement("failure_in_clusters", verdict_of(ok, measurable), reason,
                     {"excess": x, "enrichment": r})


CLAIMS_123.append(Claim(
    "failure_in_clusters", "Failure happens preferentially in clusters (Fig. 3 bottom left)",
    "much above the uncorrelated line", "fig3", _failure_in_clusters,
    Rule("the fraction of failure in clusters \"is much higher than if both events were "
         "uncorrelated\"",
         "failing grains in clusters against the fraction of grains in clusters; agrees if above "
         f"the uncorrelated line and >= {ENRICHMENT_MIN:g} times it (\"much higher\").")))


def _c_peak(n: dict) -> Judgement:
    """The maximum of C(tau) "peak_at_zero" or "peak_off_zero" (the note: by how much, and
    where the other counting convention puts it); "no_peak" without C."""
    t, c0 = n.get("C_argmax_tau"), num(n.get("C_tau0"))
    cmax = num(n.get("C_max"))
    reason = "no_peak" if t is None else "peak_at_zero" if t == 0 else "peak_off_zero"
    return Judgement("c_peak", verdict_of(t == 0, t is not None and math.isfinite(c0)), reason,
                     {"tau": t, "c0": c0, "c_max": cmax, "excess": cmax - c0})


CLAIMS_123.append(Claim(
    "c_peak", "C(tau) peaks at tau = 0 (Fig. 3 bottom right)", "tau = 0", "fig3", _c_peak,
    Rule("\"the maximum correlation happens at tau = 0\"", "argmax of C(tau) == 0.")))


# what fig3's peak_rule calls a peak of S_m (tiltpile.analysis.stats.PEAK_RULES; "c0" reads the
# +40% as C(0) and has no peaks; each described in templates/claims.md.j2); fig3 writes
# peak_rule into its numbers only off the default
PEAK_DEFAULT = "sigma"
PEAKS = ("sigma", "local", "decile")
MIN_PEAKS = 10      # fewest peaks (or pairs of quiet frames for "c0") the enhancement is judged on


def _enhancement(n: dict) -> Judgement:
    """The enhancement (or C(0), with peak_rule "c0") "in_band" or "out_of_band" of the paper's
    "about"; "too_few_peaks" below MIN_PEAKS (its note that of a miss, where it misses);
    "not_measured". The values name the peak rule and the others fig3 offers."""
    en = ENHANCEMENT
    rule = n.get("peak_rule") or PEAK_DEFAULT
    e, k = num(n.get("enhancement_tau0")), n.get("n_peaks")
    ok = en.lo <= e <= en.hi
    measurable = math.isfinite(e) and (k or 0) >= MIN_PEAKS
    reason = ("not_measured" if not math.isfinite(e) else "too_few_peaks" if not measurable else
              "in_band" if ok else "out_of_band")
    values = {"enhancement": e, "n_peaks": k, "in_band": ok, "peak_rule": rule,
              "peak_default": PEAK_DEFAULT, "others": [r for r in (*PEAKS, "c0") if r != rule],
              "paper": en.value, "band": [en.lo, en.hi]}
    return Judgement("enhancement", verdict_of(ok, measurable), reason, values)


CLAIMS_123.append(Claim(
    "enhancement", "Failure rate right after a cluster-size peak (Fig. 3)",
    f"{ENHANCEMENT.value:+.0%}", "fig3", _enhancement,
    Rule("\"just after the cluster size peaks, the failure rate is enhanced by about "
         f"{ENHANCEMENT.value:.0%}\"",
         "failure rate right after a peak of S_m over its quiet mean, minus 1; agrees in "
         f"[{ENHANCEMENT.lo:.0%}, {ENHANCEMENT.hi:.0%}] (\"about\": "
         f"+-{(ENHANCEMENT.hi - ENHANCEMENT.value) / ENHANCEMENT.value:.0%} of the value). Needs "
         f">= {MIN_PEAKS} peaks. A peak is fig3's peak_rule, by default a quiet local maximum "
         "more than one standard deviation above its run's quiet mean; with peak_rule \"c0\" the "
         f"{ENHANCEMENT.value:+.0%} is read as C(0), judged in the same interval.")))


# ------------------------------------------------------------------------------------------------
# Figs. 4-6

CLAIMS_456: list[Claim] = []      # likewise


# "the clusters straddle the marginal stability line": at least this share of the quiet clusters
# on each side of it (below; on or above)
STRADDLE_SHARE = 0.1


def _clusters_straddle(n: dict) -> Judgement:
    """"straddle" (STRADDLE_SHARE of the quiet clusters on each side), "one_side", or
    "not_measured" (which says what "one_side" does)."""
    below, on, above = (num(n.get(k)) for k in ("quiet_frac_below", "quiet_frac_on", "quiet_frac_above"))
    ok = below >= STRADDLE_SHARE and (on + above) >= STRADDLE_SHARE
    reason = "straddle" if ok else "one_side" if math.isfinite(below) else "not_measured"
    return Judgement("clusters_straddle", verdict_of(ok, math.isfinite(below)), reason,
                     {"below": below, "on": on, "above": above, "n_clusters": n.get("quiet_n")})


CLAIMS_456.append(Claim(
    "clusters_straddle", "Clusters straddle the marginal line in the quiet period (Fig. 4)",
    "straddle", "fig4", _clusters_straddle,
    Rule("\"the clusters straddle the marginal stability line during the quiet period\"",
         f"agrees if at least {STRADDLE_SHARE:.0%} of quiet clusters are below and at least "
         f"{STRADDLE_SHARE:.0%} on or above the line.")))


Z_ISO = 3.0     # the isostatic contact number of frictional disks, d + 1 in d = 2


def _rest_stable(n: dict) -> Judgement:
    """"always_above" (no quiet frame with z_rest below Z_ISO, the mean above it),
    "frames_below" (some quiet frames below), "mean_not_above" (none below, the mean not above),
    "not_measured"."""
    z, fb = num(n.get("z_rest_mean_quiet")), num(n.get("z_rest_frac_below_iso_quiet"))
    reason = ("not_measured" if not math.isfinite(fb) else "frames_below" if fb != 0 else
              "not_measured" if not math.isfinite(z) else
              "always_above" if z > Z_ISO else "mean_not_above")
    return Judgement("rest_stable", verdict_of(fb == 0 and z > Z_ISO, math.isfinite(fb) and math.isfinite(z)),
                     reason, {"z_rest": z, "below_iso": fb, "z_iso": Z_ISO})


CLAIMS_456.append(Claim(
    "rest_stable", f"The rest of the pile (no critical contact) is always above z_iso = {Z_ISO:g} "
    "(Fig. 4)", f"z > {Z_ISO:g}, always", "fig4", _rest_stable,
    Rule("\"the remainder of the system is always far removed from isostaticity during the "
         "quiet period\"",
         f"agrees if no quiet frame has z_rest < {Z_ISO:g} (\"always\") and the mean is above "
         f"{Z_ISO:g}.")))


def _delta(n: dict) -> Judgement:
    """With an interval over runs: "interval_meets_band" or "interval_misses_band"; without one,
    the fit's own error: "fit_meets_band" or "fit_misses_band"; "not_measured"."""
    d = num(n.get("delta_pooled"))
    lo, hi = num(n.get("delta_pooled_ci_low")), num(n.get("delta_pooled_ci_high"))
    if math.isfinite(lo):
        ok, meas = overlaps(lo, hi, DELTA.lo, DELTA.hi), True
        reason = "interval_meets_band" if ok else "interval_misses_band"
    else:                                   # no interval: the fit's own error
        e = num(n.get("delta_pooled_err"))
        ok, meas = abs(d - DELTA.value) <= DELTA.tol + 2 * e, math.isfinite(d)
        reason = "fit_meets_band" if ok else "fit_misses_band" if meas else "not_measured"
    values = {"delta": interval_of(n, "delta_pooled"), "n_clusters": n.get("n_pooled"),
              "n_runs": n.get("delta_pooled_n_runs"), "s_min": n.get("s_min"),
              "paper": DELTA.value, "tol": DELTA.tol}
    return Judgement("delta", verdict_of(ok, meas), reason, values)


CLAIMS_456.append(Claim(
    "delta", "Cluster-size exponent delta just above onset (Fig. 5)",
    f"{DELTA.value:g} +- {DELTA.tol:g}", "fig5", _delta,
    Rule(f"\"delta = {DELTA.value:g} +- {DELTA.tol:g} from the distribution just above onset\"",
         "maximum-likelihood delta of the quiet clusters in the last degree before onsets, 95% "
         f"interval by resampling whole runs; agrees if it meets [{DELTA.lo:g}, {DELTA.hi:g}].")))


# the upturn of xi: its log-slope between the paper's last two windows before the onset
XI_LATE = FIG5_WINDOWS_DEG[-2:]


def _xi_grows(n: dict) -> Judgement:
    """"too_few_windows" (fewer than 3, or no rank correlation), "no_growth", "no_late_fit"
    (xi grows, the windows next to the onset have no fit), "upturn" (the late log-slope larger
    than the average one) or "no_upturn"."""
    rho, slope, k = num(n.get("xi_spearman")), num(n.get("xi_slope_log10_per_deg")), n.get("xi_n_windows")
    w = n.get("windows") or {}
    wa, wb = XI_LATE
    a, b = ((w.get(f"{c:g}") or {}).get("xi") for c in XI_LATE)
    late = (math.log10(num(b)) - math.log10(num(a))) / (wb - wa) if a and b and a > 0 and b > 0 else math.nan
    values = {"spearman": rho, "slope": slope, "n_windows": k, "late_slope": late, "late_deg": -wa}
    if not (math.isfinite(rho) and (k or 0) >= 3):
        return Judgement("xi_grows", INCONCLUSIVE, "too_few_windows", values)
    if not (rho > 0 and slope > 0):
        return Judgement("xi_grows", DISAGREES, "no_growth", values)
    if not math.isfinite(late):
        return Judgement("xi_grows", INCONCLUSIVE, "no_late_fit", values)
    ok = late > slope
    return Judgement("xi_grows", verdict_of(ok), "upturn" if ok else "no_upturn", values)


CLAIMS_456.append(Claim(
    "xi_grows", "Cut-off size xi grows towards the onset, with an upturn (Fig. 5a)",
    "sharp upturn", "fig5", _xi_grows,
    Rule("\"a sharp upturn close to the avalanche, especially in the last 10 frames\"",
         "xi in 0.5-deg windows: rank correlation and log-slope with theta - theta_m > 0, and the "
         f"log-slope between the {XI_LATE[0]:g} and {XI_LATE[1]:g} deg windows larger than the "
         "average one (the upturn).")))


def _smax_grows(n: dict) -> Judgement:
    """"grows", "does_not_grow" or "not_measured"."""
    far, near = num(n.get("s_max_far")), num(n.get("s_max_near"))
    measurable = math.isfinite(far) and math.isfinite(near)
    reason = "grows" if near > far else "does_not_grow" if measurable else "not_measured"
    return Judgement("smax_grows", verdict_of(near > far, measurable), reason,
                     {"far": far, "near": near})


CLAIMS_456.append(Claim(
    "smax_grows", "Largest cluster <S_max> grows towards the onset (Fig. 5b)",
    "grows to system size", "fig5", _smax_grows,
    Rule("\"the ensemble-averaged size of the largest cluster also grows\"",
         "<S_max> in the last 0.5 deg larger than more than 4 deg before onsets. (That the "
         "clusters reach system size is not tested.)")))


# the single-grain bound of delta z (the local criterion, Fig. 6b) and how close to the global
# line (delta z = 0) the largest clusters' minimum must come
DZ_SINGLE_GRAIN, DZ_NEAR_GLOBAL = -1.5, 0.5


def _dz_min(n: dict) -> Judgement:
    """"bounds_hold" (no cluster below the single-grain bound, the smallest on it, the largest
    near the global line), "bounds_fail", "not_measured". The values give how many clusters
    holding an unstable grain were left out (None where fig6 did not say)."""
    mn1 = num(((n.get("classes") or {}).get("1") or {}).get("dz_min"))
    below = num(n.get("frac_below_single_grain"))
    big = n.get("largest_bin") or {}
    mn_big = num(big.get("dz_min"))
    ok = below == 0 and abs(mn1 - DZ_SINGLE_GRAIN) < 1e-6 and abs(mn_big) <= DZ_NEAR_GLOBAL
    reason = "bounds_hold" if ok else "bounds_fail" if math.isfinite(below) else "not_measured"
    values = {"dz_min_single": mn1, "dz_min_largest": mn_big, "size_lo": big.get("size_lo"),
              "below": below, "single_grain": DZ_SINGLE_GRAIN,
              "n_unstable": n.get("n_clusters_unstable"),
              "frac_unstable": num(n.get("frac_clusters_unstable"))}
    return Judgement("dz_min", verdict_of(ok, math.isfinite(below) and math.isfinite(mn_big)),
                     reason, values)


CLAIMS_456.append(Claim(
    "dz_min", "Min delta z of clusters: single-grain bound for the smallest, near the global "
    "line for the largest (Fig. 6b)", f"{DZ_SINGLE_GRAIN:g} -> ~0", "fig6", _dz_min,
    Rule("\"the minimal value of delta z goes from the marginal local criterion for the smallest "
         "one (all studied clusters must be composed of locally stable particles) to close to "
         "the global stability criterion for the largest one\"",
         f"among the clusters made of locally stable grains: none below {DZ_SINGLE_GRAIN:g}, the "
         f"smallest (s = 1) reach {DZ_SINGLE_GRAIN:g}, and the largest size bin's minimum within "
         f"{DZ_NEAR_GLOBAL:g} of 0 (a third of the way between the two criteria). How many "
         "clusters hold an unstable grain is reported with the verdict: before the selection "
         f"they are the ones below {DZ_SINGLE_GRAIN:g}.")))


def _dz_shift(n: dict) -> Judgement:
    """"shifts_positive" (<delta z> rises with size and the largest bin's is > 0),
    "stays_negative" (the note gives the size classes from 8 grains up and whether they level
    off), "not_measured"."""
    cls = n.get("classes", {})
    slope = num(n.get("slope_per_decade"))
    big = n.get("largest_bin") or {}
    mean_big = num(big.get("dz_mean"))
    ok = slope > 0 and mean_big > 0
    # the size classes from 8 grains up ("8-15", "16+"), said to level off when their means lie
    # within 0.05 of each other
    big_classes = [[k, num(c.get("dz_mean"))] for k, c in cls.items()
                   if int(k.split("-")[0].rstrip("+")) >= 8]
    means = [m for _, m in big_classes]
    reason = "shifts_positive" if ok else "stays_negative" if math.isfinite(mean_big) else "not_measured"
    values = {"dz_mean_single": num((cls.get("1") or {}).get("dz_mean")),
              "dz_mean_largest": mean_big, "size_lo": big.get("size_lo"), "slope": slope,
              "plateau": big_classes, "flat": len(means) > 1 and max(means) - min(means) < 0.05}
    return Judgement("dz_shift", verdict_of(ok, math.isfinite(slope) and math.isfinite(mean_big)),
                     reason, values)


CLAIMS_456.append(Claim(
    "dz_shift", "delta z distributions shift from negative to slightly positive with size (Fig. 6a)",
    "negative -> slightly positive", "fig6", _dz_shift,
    Rule("\"the distributions progressively shift from negative delta z to a slightly positive "
         "one\"",
         "<delta z> rises with log size (slope > 0) and the largest size bin's <delta z> is > 0.")))


# the rule of each claim, by key (the report prints them in its "How each claim is tested")
RULES_PAPER: dict[str, Rule] = {c.key: c.rule for c in CLAIMS_123 + CLAIMS_456}
