"""Beyond the paper: the rigidity claims (Fig. 7), judged from the rigid clusters of the
(3,3) pebble game, each declared once as the paper's are (:mod:`.paper`): its judge, then its
:class:`Claim` with the :class:`Rule` it applies; the claims in report order.
"""

from __future__ import annotations

import math

from .judging import Claim, Rule, num, show, show_interval, verdict_of

BEYOND = "beyond the paper"     # the paper's value of a claim the paper does not make

CLAIMS_RIGIDITY: list[Claim] = []   # in report order: each appended right after its judge


def _rigid_spans(n: dict):
    d = n.get("quiet_spanning_fraction") or {}
    lo = num(d.get("low"))
    ours = (f"{show_interval(d)} of the quiet frames span; largest rigid cluster "
            f"{show_interval(n.get('quiet_rigid_fraction'))} of the grains")
    ok = lo > 0.5
    note = "" if ok or not math.isfinite(lo) else (
        "in most quiet frames the largest rigid cluster does not reach from the ground to the "
        "free surface.")
    return ours, verdict_of(ok, math.isfinite(lo)), note


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


def _rigid_shrinks(n: dict):
    d = n.get("rigid_fraction_shrink") or {}
    hi = num(d.get("high"))
    ours = (f"{show_interval(n.get('rigid_fraction_far'))} further than {show(n.get('far_deg'), 'g')} "
            f"deg -> {show_interval(n.get('rigid_fraction_near'))} within {show(n.get('near_deg'), 'g')} "
            f"deg of onsets (difference {show_interval(d, '+.3f')})")
    return ours, verdict_of(hi < 0, math.isfinite(hi)), ""


CLAIMS_RIGIDITY.append(Claim(
    "rigid_shrinks", "The largest rigid cluster shrinks towards the onset (Fig. 7b)", BEYOND,
    "fig7", _rigid_shrinks,
    Rule("beyond the paper: as the critical clusters grow towards the onset, the rigid cluster "
         "should shrink.",
         "per run, the mean largest-rigid-cluster fraction of the quiet frames within near_deg of "
         "an onset minus that further than far_deg; agrees if the bootstrap interval of the mean "
         "difference lies below 0.")))


MIN_ONSETS = 5      # fewest onsets after a quiet frame the loss of spanning is judged on


def _rigid_loses_spanning(n: dict):
    k = n.get("n_onsets") or 0
    before = num(n.get("spanning_before_fraction"))
    at = num(n.get("spanning_at_fraction"))
    lost = 1.0 - before
    ours = (f"{show(lost, '.0%')} of {k} onsets follow a quiet frame that does not span (median "
            f"{show(num(n.get('loss_to_onset_median')), '.2f')} deg before the onset); "
            f"{show(at, '.0%')} still span at the onset frame")
    ok = lost > 0.5
    note = "" if ok or not math.isfinite(lost) else (
        "the spanning rigid cluster is mostly still there at the last quiet frame, and at the "
        "onset frame itself: it breaks during the avalanche, it does not announce it.")
    return ours, verdict_of(ok, k >= MIN_ONSETS and math.isfinite(lost)), note


CLAIMS_RIGIDITY.append(Claim(
    "rigid_loses_spanning", "The pile loses its spanning rigid cluster at or before theta_m "
    "(Fig. 7)", BEYOND, "fig7", _rigid_loses_spanning,
    Rule("beyond the paper: if rigidity is what fails, the pile should lose its spanning rigid "
         "cluster at or before theta_m.",
         "for every onset after a quiet frame, whether that last quiet frame spans; agrees if "
         f"more than half of them do not (needs {MIN_ONSETS} onsets).")))


TOGETHER_DEG = 1.0  # the loss of spanning and the marginal crossing at most this far apart


def _rigid_vs_marginal(n: dict):
    sp = num(n.get("spanning_loss_theta_to_onset"))
    mz = num(n.get("marginal_crossing_theta_to_onset"))
    both_after = not math.isfinite(sp) and not math.isfinite(mz)
    if both_after:
        ours = ("neither before the onset: up to theta_m most quiet frames span and their mean "
                "delta z_gen stays above 0")
    else:
        ours = (f"spanning lost (windows below 1/2) at {show(sp, '.2f')} deg, marginal line crossed "
                f"at {show(mz, '.2f')} deg (n/a: not before the onset)")
    together = math.isfinite(sp) and math.isfinite(mz) and abs(sp - mz) <= TOGETHER_DEG
    return ours, verdict_of(both_after or together), ""


CLAIMS_RIGIDITY.append(Claim(
    "rigid_vs_marginal", "Rigidity is lost where the marginal line is crossed (Figs. 1, 7b)",
    BEYOND, "fig7", _rigid_vs_marginal,
    Rule("beyond the paper: the loss of rigidity against the paper's global criterion, the "
         "crossing of z = 3 + n_m.",
         "where the quiet-frame windows' spanning fraction first drops below 1/2 and where their "
         "mean delta z_gen first drops below 0 (theta - theta_m); agrees if both happen within "
         f"{TOGETHER_DEG:g} deg of each other, or neither before the onset.")))


RULES_RIGIDITY: dict[str, Rule] = {c.key: c.rule for c in CLAIMS_RIGIDITY}
