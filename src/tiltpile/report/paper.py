"""The paper's claims (Figs. 1-6 and the avalanche angle of its piles), each declared once, in
report order: its judge, then its :class:`Claim` (key, text, the paper's value, the figure whose
numbers it reads, the judge, and the :class:`Rule` the report prints), appended to
``CLAIMS_123`` or ``CLAIMS_456``; ``RULES_PAPER`` is read from them. The paper's numbers come
from :mod:`tiltpile.paper_values`, a tolerance of ours from a constant beside its judge; the
judge compares with them and the rule's text is formatted from them, so the two cannot say
different things. The keys of the numbers are those written by ``tiltpile.figures.figN.compute``.
"""

from __future__ import annotations

import math

from tiltpile.paper_values import (AVALANCHE_DEG, DELTA, ENHANCEMENT, FIG5_WINDOWS_DEG,
                                   ONSET_SHIFT_FRAMES, ORIENTATION_DEG, QUIET_DEG, SLIDE_KE, Z_MEAN)

from .judging import (AGREES, DISAGREES, INCONCLUSIVE, SEPARATION, Claim, Rule, num, overlaps,
                      show, show_ci, verdict_of, wrong_side)


def _sci(x: float) -> str:
    """1e-3 as '1e-3' (one significant digit, the exponent without padding)."""
    mant, exp = f"{x:.0e}".split("e")
    return f"{mant}e{int(exp)}"


# ------------------------------------------------------------------------------------------------
# Figs. 1-3

CLAIMS_123: list[Claim] = []      # in report order: each appended right after its judge


def _theta_m(n: dict):
    q = QUIET_DEG.value
    mx = num(n.get("theta_m_max"))
    k = n.get("n_runs_with_onset")
    ours = (f"first onset {show_ci(n, 'theta_m', '.1f', 'theta_m_mean')} deg (mean [95% CI], {k} runs; "
            f"range {show(num(n.get('theta_m_min')), '.1f')}-{show(mx, '.1f')})")
    ok = mx >= q
    legs = ((n.get("history") or {}).get("pretilt_deg"))
    why = ("Our piles are freshly deposited; the paper's had been tilted back and forth before, "
           "which suppresses precursors below the earlier angle." if legs == [] else
           f"Our piles were tilted back and forth before the ramp "
           f"({(n.get('history') or {}).get('label')}), as the paper's." if legs else "")
    note = "" if ok or not math.isfinite(mx) else (
        f"no run stays quiet up to {q:g} deg: the paper's Fig. 5 has quiet frames {q:g} deg before an "
        f"onset, so some of its piles had no 2% event before {q:g} deg; ours all have one by "
        f"{show(mx, '.1f')} deg. These first onsets are precursor rearrangements"
        f"{_ke_range(n.get('ke_first_onset_per_run'))}; the large slide comes later (next claim). "
        + why).strip()
    return ours, verdict_of(ok, math.isfinite(mx)), note


def _ke_range(per_run) -> str:
    """' (kinetic energy per grain a to b at the first onsets)' from fig2's
    ke_first_onset_per_run, or '' where fig2 did not write it."""
    ke = sorted(v for v in (num(x) for x in (per_run or [])) if math.isfinite(v) and v > 0)
    if not ke:
        return ""
    span = show(ke[0], ".0e") if len(ke) == 1 else f"{show(ke[0], '.0e')} to {show(ke[-1], '.0e')}"
    return f" (kinetic energy per grain {span} at the first onsets)"


CLAIMS_123.append(Claim(
    "theta_m", "Failure angle theta_m: first onset by the 2% criterion (Fig. 2, 5)",
    f"very variable; quiet up to >= {QUIET_DEG.value:g} deg in some runs", "fig2", _theta_m,
    Rule("\"theta_m, the failure angle [...] known to show considerable statistical variance\"; "
         f"Fig. 5 shows quiet clusters at theta - theta_m = -{QUIET_DEG.value:g} deg.",
         "the first onset by the 2% criterion of each run; agrees if at least one run stays "
         f"quiet up to {QUIET_DEG.value:g} deg (the paper's Fig. 5 needs such runs). Mean with a "
         "BCa bootstrap interval over runs, for information.")))


def _theta_slide(n: dict):
    """The avalanche angle: each run's first large slide at the fixed threshold ``avalanche_ke``
    (fig2), the same at every scale (the first sustained flow above the Fig. 2a threshold is
    reported beside it in the per-scale table)."""
    a = AVALANCHE_DEG
    per = [num(v) for v in (n.get("theta_avalanche_per_run") or [])]
    k = sum(math.isfinite(v) for v in per)
    m = len(per)
    end = num(n.get("theta_end_min"))
    fin = sorted(v for v in per if math.isfinite(v))
    if m and k > m / 2:
        # the median is known when more than half of the runs slide before the end of the tilt
        vals = fin + [math.inf] * (m - k)
        med = vals[(m - 1) // 2] if m % 2 else 0.5 * (vals[m // 2 - 1] + vals[m // 2])
        med_txt, measurable = show(med, ".1f"), math.isfinite(med)
        ok = abs(med - a.value) <= a.tol
    else:
        med = math.nan
        med_txt = f"> {show(end, '.1f')}" if m else "n/a"
        measurable = m > 0 and end > a.hi        # a median beyond the band is known to disagree
        ok = False
    ours = (f"first large slide: median {med_txt} deg; {k} of {m} runs slide before the end of "
            f"their tilt (the earliest end: {show(end, '.1f')} deg)" + (f", at {', '.join(show(v, '.2f') for v in fin)} deg"
                                               if fin else "")
            + f" (KE per grain > {show(num(n.get('avalanche_ke')), '.0e')} over "
            f">= {show(num(n.get('slide_sustain_deg')), 'g')} deg)")
    note = ""
    if not measurable:
        note = ("fewer than half of the runs slide before the end of the tilt, so the median slide "
                "angle is only known to lie above the last angle; more runs or a longer tilt "
                "decide it; the per-scale table shows how it changes with the number of grains, "
                "and `tiltpile repose` (the preparation study) tilts the runs on into their slides.")
    elif not ok:
        note = (f"our median first large slide ({med_txt} deg) is more than {a.tol:g} deg "
                f"{'below' if med < a.value else 'above'} the literature's ~{a.value:g} deg.")
        if (n.get("history") or {}).get("pretilt_deg") == []:
            note += (" Our piles are freshly deposited; Deboeuf et al. measured theirs after two "
                     "cycles past theta_rev (the preparation study compares the two histories).")
    return ours, verdict_of(ok, measurable), note


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


def _z_mean(n: dict):
    lo, hi = num(n.get("z_quiet_run_mean_ci_low")), num(n.get("z_quiet_run_mean_ci_high"))
    z = num(n.get("z_quiet_run_mean"))
    ok = overlaps(lo, hi, Z_MEAN.lo, Z_MEAN.hi)
    note = "" if ok or not math.isfinite(z) else (
        "we count force-bearing contacts (f_n > 0) of bulk grains without rattlers (top and bottom "
        "layers removed); the paper does not say which contacts its <z> counts. A contact list of "
        "the pairs within a small gap counts ~3.5 (the definitions study), and our soft-sphere DEM "
        "counts more than CD on the same piles (the engines' section). Our piles are also "
        "deposited differently (loose random fill, settling under gravity at mu = 0.5), which "
        "sets z.")
    return (f"{show_ci(n, 'z_quiet_run_mean', '.3f')} (quiet frames, bulk without rattlers)",
            verdict_of(ok, math.isfinite(lo)), note)


CLAIMS_123.append(Claim(
    "z_mean", "Mean contact number <z> of the pile", f"~{Z_MEAN.value:g}", "fig2", _z_mean,
    Rule(f"\"The average number of contacts for the whole pile is <z> ~ {Z_MEAN.value:g}.\"",
         "mean over runs of the quiet-frame mean z (bulk, no rattlers) with a bootstrap interval "
         f"over runs; agrees if the interval meets [{Z_MEAN.lo:g}, {Z_MEAN.hi:g}], the values "
         f"that round to {Z_MEAN.value:g}.")))


# two populations: the two-Gaussian mixture fits better by more than this BIC difference, and
# separates by more than this Ashman's D (beyond 2 the mixture has two modes)
BIC_GAIN, ASHMAN_D = 10, 2


def _two_populations(n: dict):
    b = n.get("lost_bimodality") or {}
    d, bic, depth = num(b.get("ashman_d")), num(b.get("delta_bic")), num(b.get("valley_depth"))
    ours = (f"Ashman D = {show(d, '.1f')}, valley depth {show(depth, '.2f')} at "
            f"{show(num(b.get('valley')), '.2%')} lost, BIC(1) - BIC(2) = {show(bic, '.0f')}; "
            f"{show(num(n.get('lost_zero_fraction')), '.0%')} of frames lose no contact")
    ok = d > ASHMAN_D and bic > BIC_GAIN
    note = "" if ok or not math.isfinite(d) else (
        "the lost fractions of the frames losing at least one contact are not two separated "
        "populations (one skewed population, or two overlapping ones).")
    return ours, verdict_of(ok, math.isfinite(d)), note


CLAIMS_123.append(Claim(
    "two_populations", "Lost fraction between frames: two distinct populations (Fig. 2b)",
    "two populations", "fig2", _two_populations,
    Rule("\"the data clearly fall into two distinct sub-populations\" (Fig. 2b, lost fraction "
         "between frames)",
         "log10 of the lost fraction of the frames losing >= 1 contact (counts dequantized), one "
         f"against two Gaussians; agrees if two fit better (BIC difference > {BIC_GAIN:g}) and "
         f"separate (Ashman's D > {ASHMAN_D:g}, the mixture then has two modes). Frames losing "
         "nothing are reported apart.")))


def _cutoff_in_gap(n: dict):
    b = n.get("lost_bimodality") or {}
    between = b.get("cutoff_between_means")
    means = b.get("means") or [None, None]
    cutoff = num(n.get("cutoff"))
    above, below = wrong_side(b, cutoff)
    ms = ", ".join(show(10 ** num(m), ".2%") if m is not None else "n/a" for m in means)
    ours = (f"population means at {ms} lost; the {show(cutoff, '.0%')} cutoff leaves "
            f"{show(above, '.0%')} of the lower population above it and {show(below, '.0%')} of the "
            f"upper one below it (density there {show(num(b.get('cutoff_density_ratio')), '.2f')} "
            "of the lower peak)")
    measurable = math.isfinite(above) and math.isfinite(below)
    ok = measurable and above <= SEPARATION and below <= SEPARATION
    note = "" if ok or not measurable else (
        f"the gap between our two populations is at {show(num(b.get('valley')), '.2%')} lost, and "
        "the 2% cutoff is not in it: "
        + ("it lies beyond both population means, on the far side of the upper one (at "
           f"{_contacts_at_cutoff(n)}, and precursor rearrangements of the top layers lose that "
           "many)." if not between else
           f"it lies between the means but within one standard deviation of the "
           f"{'upper' if below > above else 'lower'} population's mean, so it splits that population "
           f"({show(max(above, below), '.0%')} of its frames on the other side) instead of "
           "separating the two."))
    return ours, verdict_of(ok, measurable), note


def _contacts_at_cutoff(n: dict) -> str:
    """'N grains the 2% cutoff is ~k contacts' (k from the mean active contacts of a frame, fig2's
    n_active_mean; without it, the cutoff as a share of the contacts)."""
    cutoff, active = num(n.get("cutoff")), num(n.get("n_active_mean"))
    head = f"{n.get('n_grains')} grains the {show(cutoff, '.0%')} cutoff"
    return (f"{head} is ~{show(cutoff * active, '.0f')} contacts" if math.isfinite(active)
            else f"{head} is that share of the active contacts")


CLAIMS_123.append(Claim(
    "cutoff_in_gap", "The 2% cutoff separates the two populations (Fig. 2b)", "cutoff in the gap",
    "fig2", _cutoff_in_gap,
    Rule("\"The good separation between the two populations allows us to apply a cutoff of a "
         "maximum of 2%\"",
         "agrees if the 2% cutoff separates the two fitted populations (Gaussians in log10 of "
         f"the lost fraction): at most {SEPARATION:.0%} of either lies on its wrong side, i.e. "
         "the cutoff is at least one standard deviation from both means, in the valley between "
         "them and not on a population.")))


def _robust(n: dict):
    raw, unmatched = n.get("onset_shift_median_frames"), num(n.get("onset_unmatched_fraction"))
    # null with onsets compared: most onsets have no partner (a move larger than 10 frames)
    med = math.inf if raw is None and math.isfinite(unmatched) else num(raw)
    f = num(n.get("onset_shift_max_frames"))
    ours = (f"median shift {show(med, '.0f') if math.isfinite(med) else '> 10'} frames (max "
            f"{show(f, '.0f')}, {show(num(n.get('onset_shift_max_deg')), '.2f')} deg); "
            f"{show(unmatched, '.0%')} of onsets have no partner within 10 frames at another cutoff")
    ok = med <= ONSET_SHIFT_FRAMES.value
    note = "" if ok or math.isnan(med) else (
        "the lost fraction of our quiet frames is not far below 2% (Fig. 2b: the upper population "
        "straddles the cutoff), so 1% and 4% cut through a population rather than through a gap, "
        "and onsets appear, vanish or move by several frames.")
    return ours, verdict_of(ok, not math.isnan(med)), note


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


def _crossing(n: dict):
    """Both halves of "crosses the marginal stability line only after the start of the
    avalanche": quiet frames above the line (up to a frame-resolution allowance, and above it
    just before an onset) and avalanching frames across it (Fig. 2d: the avalanche occupies a
    region well separated from the quiet one, on the other side of the line)."""
    lo = num(n.get("quiet_below_run_mean_ci_low"))
    a = num(n.get("avalanche_below_fraction"))
    pre = num(n.get("dz_gen_pre_onset"))
    ours = (f"{show_ci(n, 'quiet_below_run_mean', '.1%')} of quiet and {show(a, '.0%')} of avalanching "
            f"frames below the line; mean delta z_gen just before an onset {show(pre, '+.3f')}")
    quiet_measured = math.isfinite(lo) and math.isfinite(pre)
    quiet_ok, across = lo <= QUIET_BELOW_ALLOWED and pre > 0, a >= AVALANCHE_ACROSS
    notes = []
    if quiet_measured and not quiet_ok:
        notes.append(
            f"quiet frames below the marginal line are more than the {QUIET_BELOW_ALLOWED:.0%} a "
            "frame-resolution effect would explain, in every resampling of the runs: our pile "
            "does reach the line during quiet periods (mostly just before onsets), although on "
            "average it stays above it until the onset; fig1 shows the mean quiet path.")
    if math.isfinite(a) and not across:
        notes.append(
            f"only {show(a, '.0%')} of our avalanching frames are below the marginal line, fewer "
            f"than {AVALANCHE_ACROSS_WORDS}: most of the avalanching frames stay on the stable "
            "side, so the crossing after the onset that the paper's Fig. 2d shows (the avalanche "
            "in a region of its own, across the line) does not happen in most of them.")
    if notes:
        return ours, DISAGREES, " ".join(notes)
    return ours, verdict_of(True, quiet_measured and math.isfinite(a)), ""


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


def _orientation(n: dict):
    o = ORIENTATION_DEG
    m, k = num(n.get("orientation_mean_deg")), n.get("n_clusters_orientation")
    ours = f"{show(m, '.0f')} deg (median {show(num(n.get('orientation_median_deg')), '.0f')}; {k} clusters of >= 5 grains)"
    return ours, verdict_of(abs(m - o.value) <= o.tol, math.isfinite(m)), ""


CLAIMS_123.append(Claim(
    "orientation", "Cluster orientation to gravity (Fig. 3 top)", f"~{ORIENTATION_DEG.value:g} deg",
    "fig3", _orientation,
    Rule(f"clusters align at \"roughly {ORIENTATION_DEG.value:g} deg\" to gravity",
         "mean angle of the long axis of clusters of >= 5 grains to gravity; agrees within "
         f"{ORIENTATION_DEG.tol:g} deg (\"roughly\").")))


# "much higher than if both events were uncorrelated": at least this many times the
# uncorrelated line
ENRICHMENT_MIN = 1.5


def _failure_in_clusters(n: dict):
    x, r = num(n.get("failing_in_cluster_excess")), num(n.get("failing_in_cluster_enrichment"))
    ours = f"{show(x, '+.2f')} above the uncorrelated line ({show(r, '.1f')}x more failure in clusters)"
    return ours, verdict_of(x > 0 and r >= ENRICHMENT_MIN, math.isfinite(x) and math.isfinite(r)), ""


CLAIMS_123.append(Claim(
    "failure_in_clusters", "Failure happens preferentially in clusters (Fig. 3 bottom left)",
    "much above the uncorrelated line", "fig3", _failure_in_clusters,
    Rule("the fraction of failure in clusters \"is much higher than if both events were "
         "uncorrelated\"",
         "failing grains in clusters against the fraction of grains in clusters; agrees if above "
         f"the uncorrelated line and >= {ENRICHMENT_MIN:g} times it (\"much higher\").")))


def _c_peak(n: dict):
    t, c0 = n.get("C_argmax_tau"), num(n.get("C_tau0"))
    cmax = num(n.get("C_max"))
    ours = f"max of C at tau = {t} ({show(cmax, '.2f')}), C(0) = {show(c0, '.2f')}"
    note = "" if t == 0 or t is None else (
        f"our maximum sits {abs(t)} frame(s) {'before' if t < 0 else 'after'} tau = 0 and exceeds "
        f"C(0) by {show(cmax - c0, '.2f')}: large clusters and failure move together within about a "
        "frame. Our N^f(k) counts the contacts lost from frame k to k + 1; counted from k - 1 to "
        "k instead (the paper does not say which), the same data put the maximum at tau = "
        f"{t + 1}. The difference from the paper is within this one-frame convention.")
    return ours, verdict_of(t == 0, t is not None and math.isfinite(c0)), note


CLAIMS_123.append(Claim(
    "c_peak", "C(tau) peaks at tau = 0 (Fig. 3 bottom right)", "tau = 0", "fig3", _c_peak,
    Rule("\"the maximum correlation happens at tau = 0\"", "argmax of C(tau) == 0.")))


# what fig3's peak_rule calls a peak of S_m (tiltpile.analysis.stats.PEAK_RULES; "c0" reads the
# +40% as C(0) and has no peaks); fig3 writes peak_rule into its numbers only off the default
PEAK_DEFAULT = "sigma"
PEAKS = {"sigma": "a local maximum more than one standard deviation above the quiet-period mean",
         "local": "any local maximum of S_m within a quiet period, without a threshold",
         "decile": "any quiet frame in the top decile of its run's quiet S_m, a local maximum or "
                   "not"}
MIN_PEAKS = 10      # fewest peaks (or pairs of quiet frames for "c0") the enhancement is judged on


def _enhancement(n: dict):
    en, forty = ENHANCEMENT, f"{ENHANCEMENT.value:+.0%}"
    rule = n.get("peak_rule") or PEAK_DEFAULT
    e, k = num(n.get("enhancement_tau0")), n.get("n_peaks")
    ok = en.lo <= e <= en.hi
    others = ", ".join(f'"{r}"' for r in (*PEAKS, "c0") if r != rule)
    if rule == "c0":
        ours = f"C(0) = {show(e, '.2f')} read as the {forty} ({k} pairs of quiet frames)"
        note = "" if ok or not math.isfinite(e) else (
            f"read as C(0) (fig3's peak_rule \"c0\": the paper's {forty} as the correlation at "
            f"tau = 0, not as a rate after peaks), our C(0) is outside {en.lo:g}-{en.hi:g}; the "
            f"other readings are fig3's peak_rule {others}.")
        return ours, verdict_of(ok, math.isfinite(e) and (k or 0) >= MIN_PEAKS), note
    ours = f"{show(e, '+.0%')} right after {k} peaks of the largest cluster"
    if rule != PEAK_DEFAULT:
        ours += f" (peak: {PEAKS.get(rule, rule)})"
    note = "" if ok or not math.isfinite(e) else (
        "the size of the enhancement depends on what counts as a peak of S_m (ours: "
        f"{PEAKS.get(rule, rule)}, stats.cluster_peaks); the paper does not define it. fig3's "
        f"peak_rule gives the other readings ({others}; \"c0\" reads the {forty} as C(0)); "
        "docs/figures.md (Fig. 3) gives what each measures.")
    return ours, verdict_of(ok, math.isfinite(e) and (k or 0) >= MIN_PEAKS), note


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


def _clusters_straddle(n: dict):
    below, on, above = (num(n.get(k)) for k in ("quiet_frac_below", "quiet_frac_on", "quiet_frac_above"))
    ours = f"{below:.0%} below, {on:.0%} on, {above:.0%} above the line ({n.get('quiet_n')} clusters)"
    ok = below >= STRADDLE_SHARE and (on + above) >= STRADDLE_SHARE
    note = "" if ok else ("quiet clusters lie mostly on one side of the marginal line; cluster z counts "
                          "contacts with rattlers and walls, see fig4 module docstring")
    return ours, verdict_of(ok, math.isfinite(below)), note


CLAIMS_456.append(Claim(
    "clusters_straddle", "Clusters straddle the marginal line in the quiet period (Fig. 4)",
    "straddle", "fig4", _clusters_straddle,
    Rule("\"the clusters straddle the marginal stability line during the quiet period\"",
         f"agrees if at least {STRADDLE_SHARE:.0%} of quiet clusters are below and at least "
         f"{STRADDLE_SHARE:.0%} on or above the line.")))


Z_ISO = 3.0     # the isostatic contact number of frictional disks, d + 1 in d = 2


def _rest_stable(n: dict):
    z, fb = num(n.get("z_rest_mean_quiet")), num(n.get("z_rest_frac_below_iso_quiet"))
    ours = f"<z_rest> = {show(z, '.3f')}; {show(fb, '.1%')} of quiet frames with z_rest < {Z_ISO:g}"
    note = "" if fb == 0 or not math.isfinite(fb) else (
        f"in some quiet frames the rest of the pile is at or below z_iso = {Z_ISO:g}.")
    return ours, verdict_of(fb == 0 and z > Z_ISO, math.isfinite(fb) and math.isfinite(z)), note


CLAIMS_456.append(Claim(
    "rest_stable", f"The rest of the pile (no critical contact) is always above z_iso = {Z_ISO:g} "
    "(Fig. 4)", f"z > {Z_ISO:g}, always", "fig4", _rest_stable,
    Rule("\"the remainder of the system is always far removed from isostaticity during the "
         "quiet period\"",
         f"agrees if no quiet frame has z_rest < {Z_ISO:g} (\"always\") and the mean is above "
         f"{Z_ISO:g}.")))


def _delta(n: dict):
    d, cnt = num(n.get("delta_pooled")), n.get("n_pooled")
    lo, hi = num(n.get("delta_pooled_ci_low")), num(n.get("delta_pooled_ci_high"))
    ours = (f"{show_ci(n, 'delta_pooled', '.2f')} ({cnt} clusters of {n.get('delta_pooled_n_runs')} "
            f"runs, s >= {n.get('s_min')}; interval: runs resampled)")
    if math.isfinite(lo):
        ok, meas = overlaps(lo, hi, DELTA.lo, DELTA.hi), True
    else:                                   # no interval: the fit's own error
        e = num(n.get("delta_pooled_err"))
        ok, meas = abs(d - DELTA.value) <= DELTA.tol + 2 * e, math.isfinite(d)
    note = "" if ok or not meas else (
        f"our delta lies outside the paper's {DELTA.value:g} +- {DELTA.tol:g} for every "
        "resampling of the runs. The fit window, s_min and the cluster definition (links through "
        "any contact of a grain with a critical contact) all move delta; with few runs the tail "
        "is short.")
    return ours, verdict_of(ok, meas), note


CLAIMS_456.append(Claim(
    "delta", "Cluster-size exponent delta just above onset (Fig. 5)",
    f"{DELTA.value:g} +- {DELTA.tol:g}", "fig5", _delta,
    Rule(f"\"delta = {DELTA.value:g} +- {DELTA.tol:g} from the distribution just above onset\"",
         "maximum-likelihood delta of the quiet clusters in the last degree before onsets, 95% "
         f"interval by resampling whole runs; agrees if it meets [{DELTA.lo:g}, {DELTA.hi:g}].")))


# the upturn of xi: its log-slope between the paper's last two windows before the onset
XI_LATE = FIG5_WINDOWS_DEG[-2:]


def _xi_grows(n: dict):
    rho, slope, k = num(n.get("xi_spearman")), num(n.get("xi_slope_log10_per_deg")), n.get("xi_n_windows")
    w = n.get("windows") or {}
    wa, wb = XI_LATE
    a, b = ((w.get(f"{c:g}") or {}).get("xi") for c in XI_LATE)
    late = (math.log10(num(b)) - math.log10(num(a))) / (wb - wa) if a and b and a > 0 and b > 0 else math.nan
    ours = (f"Spearman {show(rho, '.2f')}, d log10 xi / d theta = {show(slope, '.2f')} per deg over "
            f"{k} windows, {show(late, '.2f')} per deg in the last {-wa:g} deg")
    if not (math.isfinite(rho) and (k or 0) >= 3):
        return ours, INCONCLUSIVE, ""
    if not (rho > 0 and slope > 0):
        return ours, DISAGREES, "xi does not grow towards the onset."
    if not math.isfinite(late):
        return ours, INCONCLUSIVE, "xi grows, but the windows next to the onset have no fit."
    ok = late > slope
    note = "" if ok else "xi grows, but not faster just before the onset (no upturn)."
    return ours, verdict_of(ok), note


CLAIMS_456.append(Claim(
    "xi_grows", "Cut-off size xi grows towards the onset, with an upturn (Fig. 5a)",
    "sharp upturn", "fig5", _xi_grows,
    Rule("\"a sharp upturn close to the avalanche, especially in the last 10 frames\"",
         "xi in 0.5-deg windows: rank correlation and log-slope with theta - theta_m > 0, and the "
         f"log-slope between the {XI_LATE[0]:g} and {XI_LATE[1]:g} deg windows larger than the "
         "average one (the upturn).")))


def _smax_grows(n: dict):
    far, near = num(n.get("s_max_far")), num(n.get("s_max_near"))
    ours = f"{show(far, '.1f')} far from onset -> {show(near, '.1f')} in the last 0.5 deg"
    return ours, verdict_of(near > far, math.isfinite(far) and math.isfinite(near)), ""


CLAIMS_456.append(Claim(
    "smax_grows", "Largest cluster <S_max> grows towards the onset (Fig. 5b)",
    "grows to system size", "fig5", _smax_grows,
    Rule("\"the ensemble-averaged size of the largest cluster also grows\"",
         "<S_max> in the last 0.5 deg larger than more than 4 deg before onsets. (That the "
         "clusters reach system size is not tested.)")))


# the single-grain bound of delta z (the local criterion, Fig. 6b) and how close to the global
# line (delta z = 0) the largest clusters' minimum must come
DZ_SINGLE_GRAIN, DZ_NEAR_GLOBAL = -1.5, 0.5


def _dz_min(n: dict):
    mn1 = num(((n.get("classes") or {}).get("1") or {}).get("dz_min"))
    below = num(n.get("frac_below_single_grain"))
    big = n.get("largest_bin") or {}
    mn_big = num(big.get("dz_min"))
    left = n.get("n_clusters_unstable")
    ours = (f"min dz {show(mn1, '.2f')} (s = 1) -> {show(mn_big, '.2f')} (s >= {big.get('size_lo')}); "
            f"{show(below, '.1%')} of the clusters below {DZ_SINGLE_GRAIN:g}")
    if left is not None:
        ours += (f" ({left} clusters, {show(num(n.get('frac_clusters_unstable')), '.1%')}, holding "
                 "a locally unstable grain left out: moving grains, docs/figures.md)")
    ok = below == 0 and abs(mn1 - DZ_SINGLE_GRAIN) < 1e-6 and abs(mn_big) <= DZ_NEAR_GLOBAL
    note = ""
    if math.isfinite(below) and not ok:
        note = ("the smallest clusters do not sit on the single-grain bound, clusters fall below "
                "it, or the largest clusters' minimum stays far from the global line.")
    return ours, verdict_of(ok, math.isfinite(below) and math.isfinite(mn_big)), note


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


def _dz_shift(n: dict):
    cls = n.get("classes", {})
    slope = num(n.get("slope_per_decade"))
    big = n.get("largest_bin") or {}
    mean_big = num(big.get("dz_mean"))
    ours = (f"<dz> {show(num((cls.get('1') or {}).get('dz_mean')), '.2f')} (s = 1) -> "
            f"{show(mean_big, '.2f')} (s >= {big.get('size_lo')}), "
            f"{show(slope, '+.2f')} per decade of size")
    ok = slope > 0 and mean_big > 0
    # the size classes from 8 grains up ("8-15", "16+"), said to level off when their means lie
    # within 0.05 of each other
    big_classes = [(k, num(c.get("dz_mean"))) for k, c in cls.items()
                   if int(k.split("-")[0].rstrip("+")) >= 8]
    means = [m for _, m in big_classes]
    flat = len(means) > 1 and max(means) - min(means) < 0.05
    plateau = ", ".join(f"{show(m, '+.2f')} (s {'>= ' + k[:-1] if k.endswith('+') else '= ' + k})"
                        for k, m in big_classes)
    note = "" if ok or not math.isfinite(mean_big) else (
        "our mean delta z rises with size but stays below the global line (negative) for the "
        "largest clusters we have"
        + (f"; from 8 grains up {'it levels off: ' if flat else ''}{plateau}" if plateau else "")
        + "; the paper's distributions end slightly positive.")
    return ours, verdict_of(ok, math.isfinite(slope) and math.isfinite(mean_big)), note


CLAIMS_456.append(Claim(
    "dz_shift", "delta z distributions shift from negative to slightly positive with size (Fig. 6a)",
    "negative -> slightly positive", "fig6", _dz_shift,
    Rule("\"the distributions progressively shift from negative delta z to a slightly positive "
         "one\"",
         "<delta z> rises with log size (slope > 0) and the largest size bin's <delta z> is > 0.")))


# the rule of each claim, by key (the report prints them in its "How each claim is tested")
RULES_PAPER: dict[str, Rule] = {c.key: c.rule for c in CLAIMS_123 + CLAIMS_456}
