"""The report's sections "The history at Nx the ramp's rate", one per pair of ``PAIRS``: the
piles of a preset whose history's legs tilt faster than the ramp (``paper-fast``: 0.01 deg per
step, 10x; ``paper-5x``: 0.005, 5x) against the committed ``paper`` runs of the same seeds, pile
against pile and every figure number ensemble against ensemble (``tiltpile same-piles
figures/paper/records figures/paper-fast/records --null K``, written to
``figures/paper-fast/same-piles/``; likewise for paper-5x), the paper's claims judged on both
sides' figure documents, the decision and the cost. A pair without its study has no section.

The decision rule. The issue that asked for paper-fast set it as: paper-fast passes if no figure
number moves by more than 2 of its standard errors and the verdicts of the paper's claims are the
same. With ~150 numbers and 2 standard errors, chance alone moves several of them (a t
distribution of N - 1 degrees of freedom puts 6-10% of its mass beyond 2), so that rule fails
for any two ensembles of different runs. The rule applied here keeps its intent: the count of
moved numbers is set against what chance moves, measured by exchanging the two runs of each
seed (:func:`tiltpile.figures.same_piles.null_moved`: every exchange where affordable, else
random draws with p's Monte-Carlo error), and every verdict must be the same (:func:`decide`:
"moved", "no difference detected" with the smallest shift the seeds could have detected,
:func:`detectable`, or "undecided" while p lies within FIRM Monte-Carlo errors of ALPHA). The
literal rule's count is reported beside it.
"""

from __future__ import annotations

import numpy as np

import math
from pathlib import Path

from tiltpile import config as cfgmod

from .engines import STUDY as _engines_study, load as _load_study, pile_table, side_dirs as _side_dirs
from .judging import MISSING, Claim
from .rigidity import BEYOND

#: (the reference scale, a scale with a faster history), each checked the same way
PAIRS = (("paper", "paper-fast"), ("paper", "paper-5x"))
#: the first pair (the 10x history)
PAIR = PAIRS[0]
#: the study, below the faster scale's figures directory; each side's figure documents beside it
STUDY = _engines_study


def target(pair=PAIR) -> int:
    """The seeds the decision of ``pair`` waits for (its faster preset's ensemble)."""
    return cfgmod.preset_info(pair[1]).runs


def speedup(pair=PAIR) -> float:
    """How many times faster than the ramp the history of ``pair``'s faster preset tilts."""
    return cfgmod.load(pair[1]).protocol.history_rate


#: the study of the faster scale's figures directory (None without one): the same file as the
#: engines' pile-against-pile study
load = _load_study


def side_dirs(figures_dir, pair=PAIR) -> dict[str, Path]:
    """{label: the directory of that side's figure documents} of the study."""
    return _side_dirs(figures_dir, pair)


def differing(judged: dict[str, list], claims: list[Claim], pair=PAIR) -> list[str]:
    """The paper's claims whose verdict is not the same on both sides (claim (ref; other));
    ``judged``: {scale: :func:`~.document.judgements`' rows} of the two sides of ``pair``."""
    ref, other = (judged[s] for s in pair)
    out = []
    for c, (_, a, _), (_, b, _) in zip(claims, ref, other):
        if c.paper == BEYOND or MISSING in (a.verdict, b.verdict) or a.verdict == b.verdict:
            continue
        out.append(f"{c.text} ({pair[0]} {a.ours}, {a.verdict}; {pair[1]} {b.ours}, {b.verdict})")
    return out


#: the significance level of the same-piles decision, and how far (in Monte-Carlo errors) p must
#: lie from it for a decision by random exchanges to be firm
ALPHA, FIRM = 0.05, 2.0
#: (z_0.975 + z_0.8): the smallest mean difference a paired test detects with power 0.8 on n
#: seeds is Z_DETECT sd / sqrt(n) (as tiltpile.figures.same_piles.min_detectable)
Z_DETECT = 1.959963984540054 + 0.8416212335729143


def null_of(study: dict) -> dict | None:
    """The same-piles study's null, with what every study has: ``method`` ("exact": every
    exchange of each seed's two runs counted; "random": ``flips`` drawn), p and its Monte-Carlo
    error (0 when exact; sqrt(p (1 - p) / flips) for random draws of a study written before the
    error was), and whether the decision at ALPHA is firm (p more than FIRM errors from it)."""
    null = study.get("null")
    if not null:
        return None
    p, k = float(null["p_value"]), int(null["flips"])
    method = null.get("method", "random")
    err = null.get("mc_error")
    if err is None:
        err = 0.0 if method == "exact" else math.sqrt(p * (1 - p) / k)
    return {**null, "method": method, "mc_error": float(err),
            "firm": abs(p - ALPHA) > FIRM * float(err)}


def decide(study: dict, n_differ: int) -> str:
    """"moved" (the setting moves the figures: more numbers moved than chance moves, p < ALPHA,
    firmly, or a claim's verdict flips), "no difference detected" (p >= ALPHA, firmly, and every
    verdict the same: not a proof of equality; :func:`detectable` says how large a shift could
    have hidden), "undecided" (p within FIRM Monte-Carlo errors of ALPHA: more exchanges decide)
    or "open" (no null measured)."""
    if n_differ:
        return "moved"
    null = null_of(study)
    if null is None:
        return "open"
    if not null["firm"]:
        return "undecided"
    return "moved" if null["p_value"] < ALPHA else "no difference detected"


def detectable(study: dict) -> dict:
    """{number: the smallest mean difference of it the seeds could have detected} for the first
    onset and the first large slide, from the per-seed differences (80% power at ALPHA)."""
    out = {}
    pp = study.get("pile_against_pile") or {}
    for key in ("theta_first_onset", "theta_first_slide"):
        d = np.asarray([math.nan if x is None else float(x) for x in ((pp.get("per_seed") or {}).get(key) or {}).get("difference", [])], float)
        d = d[np.isfinite(d)]
        out[key] = float(Z_DETECT * d.std(ddof=1) / math.sqrt(d.size)) if d.size >= 2 else math.nan
    return out


def _cost(docs: dict[str, dict], pair=PAIR) -> str:
    parts = []
    for label in pair:
        cost = (docs.get(label) or {}).get("cost") or {}
        sw, sec = cost.get("sweeps_per_run"), cost.get("seconds_per_run")
        if sw is None:
            continue
        wall = f", {sec / 3600:.2f} h of wall time per run ({cost.get('runs_timed')} runs timed whole)" \
            if sec else ""
        parts.append(f"{label} {sw / 1e6:.1f} M sweeps per run{wall}")
    return "; ".join(parts)


def render(study: dict | None, judged: dict[str, list], claims: list[Claim],
           fig2_docs: dict[str, dict] | None = None, pair=PAIR) -> list[str]:
    """Markdown lines of the section of ``pair`` (none without the study)."""
    if study is None:
        return []
    ref, fast = pair
    proto = cfgmod.load(fast).protocol
    n, want, x = len(study["seeds"]), target(pair), proto.history_rate
    lines = ["", f"## The history at {x:g}x the ramp's rate: {fast} against {ref}", "",
             f"The paper's piles with Deboeuf's history tilted at {proto.pretilt_per_step_deg:g} deg "
             f"per step instead of the ramp's {proto.tilt_per_step_deg:g} (preset `{fast}`), against "
             f"the committed `{ref}` runs of the same seeds, which deposit the same piles (`tiltpile "
             f"same-piles`). {n} of the {want} seeds the decision waits for "
             + ("have run." if n >= want else "have run so far: **preliminary**.") , "",
             "Pile against pile: the mean of each over the seeds, and the mean paired difference "
             "(the packing at frame 0 is not in the paper's records).", ""]
    lines += pile_table(study)
    null = study.get("null")
    moved = (f"{study['n_moved']} of {study['n_with_error']} figure numbers with a jackknife "
             f"error move by more than {study['sigma_limit']:g} combined standard errors")
    if null:
        nl = null_of(study)
        how = (f"all {nl['flips']} distinct exchanges of each seed's two runs (p = "
               f"{nl['p_value']:.3f}" if nl["method"] == "exact" else
               f"{nl['flips']} random exchanges of each seed's two runs (p = {nl['p_value']:.3f} "
               f"+- {nl['mc_error']:.3f}")
        lines += ["", f"Every figure number ensemble against ensemble: {moved}; chance alone "
                  f"moves a median of {null['median']:g} (95th percentile {null['p95']:g}) in "
                  f"{how} for {study['n_moved']} or more)."]
    else:
        lines += ["", f"Every figure number ensemble against ensemble: {moved}; what chance "
                  "moves is not measured (`tiltpile same-piles --null K`)."]
    sig = {(r["figure"], r["key"]): r.get("sigma") for r in study.get("numbers", [])}

    def _moved(m):
        name, s = f"{m['figure'].split('_')[0]}.{m['key']}", sig.get((m["figure"], m["key"]))
        return f"{name} ({s:+.1f})" if s is not None and math.isfinite(s) else name
    names = ", ".join(_moved(m) for m in study.get("moved", []))
    if names:
        lines += ["", f"Moved ({fast} minus {ref}, in combined standard errors): {names}."]
    if all(s in judged for s in pair):
        diff = differing(judged, claims, pair)
        lines += ["", "The paper's claims on both sides' figures: "
                  + ("the same verdict for every claim." if not diff else
                     "different verdicts for " + "; ".join(diff) + ".")]
        word = decide(study, len(diff))
        det = detectable(study)
        rule = (f"moved when p < {ALPHA:g} or a verdict changes, no difference detected when p "
                f">= {ALPHA:g}, undecided when p lies within {FIRM:g} Monte-Carlo errors of "
                f"{ALPHA:g}; the literal rule, no number moved, fails by chance alone with "
                f"{study['n_with_error']} numbers")
        if n < want:
            lines += ["", f"**Decision: not yet** ({n} of {want} seeds). So far {fast}: {word}, "
                      f"by the rule: {rule}."]
        else:
            verdict = {"moved": f"{fast}'s history's rate moves the figures",
                       "no difference detected": (
                           f"no difference detected between {fast} and {ref}: a mean shift of "
                           f"the slide below {det['theta_first_slide']:.2f} deg or of the first "
                           f"onset below {det['theta_first_onset']:.2f} deg could have hidden "
                           f"(80% power on {n} seeds)"),
                       "undecided": "undecided: more exchanges decide",
                       "open": "open: measure what chance moves"}[word]
            lines += ["", f"**Decision: {verdict}** (the rule: {rule})."]
    cost = _cost(fig2_docs or {}, pair)
    if cost:
        lines += ["", f"Cost (each ensemble's own runs, as their records time them): {cost}."]
    return lines
