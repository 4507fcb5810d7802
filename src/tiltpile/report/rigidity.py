"""Beyond the paper: the rigidity claims (Fig. 7), judged from the rigid clusters of the
(3,3) pebble game, each declared once as the paper's are (:mod:`.paper`): its judge, then its
:class:`Claim` with the :class:`Rule` it applies; the claims in report order. Each judge returns
a :class:`Judgement` (verdict, reason, values); its sentences are the macros of
``templates/claims.md.j2`` named after the claim's key.
"""

from __future__ import annotations

import math

from .judging import Claim, Judgement, Rule, estimate_of, num, verdict_of

BEYOND = "beyond the paper"     # the paper's value of a claim the paper does not make

CLAIMS_RIGIDITY: list[Claim] = []   # in report order: each appended right after its judge


def _rigid_spans(n: dict) -> Judgement:
    """"spans" (the interval of the spanning fraction above 1/2), "does_not_span",
    "not_measured"."""
    d = estimate_of(n.get("quiet_spanning_fraction"))
    lo = d[1]
    ok = lo > 0.5
    reason = "spans" if ok else "does_not_span" if math.isfinite(lo) else "not_measured"
    return Judgement("rigid_spans", verdict_of(ok, math.isfinite(lo)), reason,
                     {"spanning": d, "rigid_fraction": estimate_of(n.get("quiet_rigid_fraction"))})


CLAIMS_RIGIDITY.append(Claim(
    "rigid_spans", "A rigid cluster spans the pile in quiet periods (Fig. 7)", BEYOND, "fig7",
    _rigid_spans,
    Rule("beyond the paper: Henkes, Quint, Fily & Schwarz (PRL 2016) find the rigid clusters of "
         "frictional packings by a (3,3) pebble game; a pile at rest should be held by one rigid "
         "cluster from its base to its surface.",
         "the largest rigid cluster (sticking contacts 2 constraints, sliding ones 1, rattlers "
         "left out; fixed grains and walls one body) holds the ground and a free-surface grain; "
         "per run the fraction of its quiet frames where it does, bootstrap interval over runs; "
         "agrees if the interval lies above 1/2.")))


def _rigid_shrinks(n: dict) -> Judgement:
    """"shrinks" (the interval of the difference below 0), "does_not_shrink", "not_measured"."""
    d = estimate_of(n.get("rigid_fraction_shrink"))
    hi = d[2]
    reason = "shrinks" if hi < 0 else "does_not_shrink" if math.isfinite(hi) else "not_measured"
    values = {"far": estimate_of(n.get("rigid_fraction_far")), "far_deg": n.get("far_deg"),
              "near": estimate_of(n.get("rigid_fraction_near")), "near_deg": n.get("near_deg"),
              "shrink": d}
    return Judgement("rigid_shrinks", verdict_of(hi < 0, math.isfinite(hi)), reason, values)


CLAIMS_RIGIDITY.append(Claim(
    "rigid_shrinks", "The largest rigid cluster shrinks towards the onset (Fig. 7b)", BEYOND,
    "fig7", _rigid_shrinks,
    Rule("beyond the paper: as the critical clusters grow towards the onset, the rigid cluster "
         "should shrink.",
         "per run, the mean largest-rigid-cluster fraction of the quiet frames within near_deg of "
         "an onset minus that further than far_deg; agrees if the bootstrap interval of the mean "
         "difference lies below 0.")))


MIN_ONSETS = 5      # fewest onsets after a quiet frame the loss of spanning is judged on


def _rigid_loses_spanning(n: dict) -> Judgement:
    """"lost_before" (more than half of the onsets follow a quiet frame that does not span),
    "still_spans", "too_few_onsets" (below MIN_ONSETS; its note that of "still_spans" where it
    holds), "not_measured"."""
    k = n.get("n_onsets") or 0
    lost = 1.0 - num(n.get("spanning_before_fraction"))
    ok = lost > 0.5
    reason = ("not_measured" if not math.isfinite(lost) else "too_few_onsets" if k < MIN_ONSETS
              else "lost_before" if ok else "still_spans")
    values = {"lost": lost, "n_onsets": k, "lost_before_onset": ok,
              "loss_median_deg": num(n.get("loss_to_onset_median")),
              "at": num(n.get("spanning_at_fraction"))}
    return Judgement("rigid_loses_spanning", verdict_of(ok, k >= MIN_ONSETS and math.isfinite(lost)),
                     reason, values)


CLAIMS_RIGIDITY.append(Claim(
    "rigid_loses_spanning", "The pile loses its spanning rigid cluster at or before theta_m "
    "(Fig. 7)", BEYOND, "fig7", _rigid_loses_spanning,
    Rule("beyond the paper: if rigidity is what fails, the pile should lose its spanning rigid "
         "cluster at or before theta_m.",
         "for every onset after a quiet frame, whether that last quiet frame spans; agrees if "
         f"more than half of them do not (needs {MIN_ONSETS} onsets).")))


TOGETHER_DEG = 1.0  # the loss of spanning and the marginal crossing at most this far apart


def _rigid_vs_marginal(n: dict) -> Judgement:
    """"neither_before_onset" (neither happens before the onset), "together" (within
    TOGETHER_DEG of each other) or "apart"."""
    sp = num(n.get("spanning_loss_theta_to_onset"))
    mz = num(n.get("marginal_crossing_theta_to_onset"))
    both_after = not math.isfinite(sp) and not math.isfinite(mz)
    together = math.isfinite(sp) and math.isfinite(mz) and abs(sp - mz) <= TOGETHER_DEG
    reason = "neither_before_onset" if both_after else "together" if together else "apart"
    return Judgement("rigid_vs_marginal", verdict_of(both_after or together), reason,
                     {"spanning_loss": sp, "marginal_crossing": mz,
                      "neither_before_onset": both_after})


CLAIMS_RIGIDITY.append(Claim(
    "rigid_vs_marginal", "Rigidity is lost where the marginal line is crossed (Figs. 1, 7b)",
    BEYOND, "fig7", _rigid_vs_marginal,
    Rule("beyond the paper: the loss of rigidity against the paper's global criterion, the "
         "crossing of z = 3 + n_m.",
         "where the quiet-frame windows' spanning fraction first drops below 1/2 and where their "
         "mean delta z_gen first drops below 0 (theta - theta_m); agrees if both happen within "
         f"{TOGETHER_DEG:g} deg of each other, or neither before the onset.")))


RULES_RIGIDITY: dict[str, Rule] = {c.key: c.rule for c in CLAIMS_RIGIDITY}
