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
moved numbers must be within what chance moves, measured by exchanging the two runs of each
seed at random (:func:`tiltpile.figures.same_piles.null_moved`; at most its 95th percentile),
and every verdict must be the same. The literal rule's count is reported beside it.
"""

from __future__ import annotations

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
    """The paper's claims whose verdict is not the same on both sides (claim (ref; other))."""
    ref, other = (judged[s] for s in pair)
    out = []
    for c, a, b in zip(claims, ref, other):
        if c.paper == BEYOND or MISSING in (a[2], b[2]) or a[2] == b[2]:
            continue
        out.append(f"{c.text} ({pair[0]} {a[1]}, {a[2]}; {pair[1]} {b[1]}, {b[2]})")
    return out


def decision(study: dict, n_differ: int) -> str:
    """"passes", "fails", or "open" (no null measured); the rule: module docstring."""
    null = study.get("null")
    if not null:
        return "open"
    return "passes" if study["n_moved"] <= null["p95"] and n_differ == 0 else "fails"


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
        lines += ["", f"Every figure number ensemble against ensemble: {moved}; chance alone "
                  f"moves a median of {null['median']:g} (95th percentile {null['p95']:g}) in "
                  f"{null['flips']} random exchanges of each seed's two runs (p = "
                  f"{null['p_value']:.2f} for {study['n_moved']} or more)."]
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
        word = decision(study, len(diff))
        rule = ("the count of moved numbers within chance's 95th percentile and every verdict "
                "the same; the literal rule, no number moved, fails by chance alone with "
                f"{study['n_with_error']} numbers")
        if n < want:
            lines += ["", f"**Decision: not yet** ({n} of {want} seeds). So far {fast} "
                      f"{'would pass' if word == 'passes' else 'would fail' if word == 'fails' else 'is undecided'}"
                      f" by the rule: {rule}."]
        else:
            verdict = {"passes": f"{fast} passes: it stands in for {ref} in new paper-scale "
                                 "studies", "fails": f"{fast} fails: its history's rate moves "
                                 "the figures", "open": "open: measure what chance moves"}[word]
            lines += ["", f"**Decision: {verdict}** (the rule: {rule})."]
    cost = _cost(fig2_docs or {}, pair)
    if cost:
        lines += ["", f"Cost (each ensemble's own runs, as their records time them): {cost}."]
    return lines
