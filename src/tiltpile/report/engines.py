"""The report's section "Same piles, another model": the default piles carried through the same
history and ramp by the second engine (the soft-sphere DEM, preset ``default-dem``), pile against
pile (``same_piles.json`` of ``tiltpile same-piles``, ``make engines``), and the paper's claims
judged on both: which disagreements with the paper both engines share (then not our engine's)
and which only one has. Its subsections at 4000 grains do the same for each pair of
``PAPER_PAIRS``: paper-fast's piles (preset ``paper-fast-dem`` against ``paper-fast``'s records of
the same seeds, ``make engines ENGINES=paper-fast``), paper-5x's (``paper-5x-dem``, ``make engines
ENGINES=paper-5x``) and the paper's own (``paper-dem`` against the committed ``paper`` records,
``make engines ENGINES=paper``), the claims judged on the
figure documents the study writes of each side.

The per-claim verdicts are the report's own (:func:`tiltpile.report.document.judgements` on each
scale's figures), handed in by :func:`tiltpile.report.document.render_studies`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from tiltpile import config as cfgmod

from .judging import DISAGREES, MISSING, Claim, num as _num, show as _f
from .rigidity import BEYOND

#: (the reference scale, the scale of the other engine): their figures directories are the
#: report's (``scales.scale_dirs``)
PAIR = ("default", "default-dem")
#: the same at 4000 grains, one subsection each: paper-fast's piles (their history at 10x the
#: ramp's rate), paper-5x's (5x, the history that passed its check against paper's) and the
#: paper's own (the history at the ramp's rate, the committed records)
PAPER_PAIRS = (("paper-fast", "paper-fast-dem"), ("paper-5x", "paper-5x-dem"), ("paper", "paper-dem"))
PAPER_PAIR = PAPER_PAIRS[0]
#: where ``make engines`` writes the pile-against-pile study, below the other engine's figures
STUDY = Path("same-piles") / "same_piles.json"
# the per-seed numbers of the study (figures.same_piles.PER_SEED), as the table names them
ROWS = (("theta_first_onset", "first 2% onset (deg)", ".2f"),
        ("theta_first_slide", "first large slide (deg)", ".2f"),
        ("n_onsets", "onsets by the 2% criterion", ".1f"),
        ("theta_first_change", "first change above 0.5% (deg)", ".2f"),
        ("z_start", "bulk z at frame 0 (after the history)", ".3f"),
        ("z_quiet", "<z> of the quiet frames", ".3f"),
        ("n_m_quiet", "<n_m> of the quiet frames", ".3f"),
        ("phi_start", "packing fraction at frame 0", ".4f"),
        ("fabric_start", "fabric anisotropy at frame 0", ".3f"),
        ("ke_quiet", "median KE per grain, quiet frames (m g d)", ".2e"))


def load(figures_dir) -> dict | None:
    """The pile-against-pile study of the other engine's figures directory (None without one)."""
    p = Path(figures_dir) / STUDY
    return json.loads(p.read_text()) if p.is_file() else None


def side_dirs(figures_dir, pair=PAPER_PAIR) -> dict[str, Path]:
    """{label: the directory of that side's figure documents} of the ``same-piles`` study below
    ``figures_dir`` (``tiltpile same-piles`` writes them there); also history_rate's."""
    d = (Path(figures_dir) / STUDY).parent
    return {label: d / label for label in pair}


def target(pair=PAPER_PAIR) -> int:
    """The piles a 4000-grain pair is planned for: the DEM preset's ensemble."""
    return cfgmod.preset_info(pair[1]).runs


def _history(ref: str) -> str:
    """How the reference preset's piles were prepared, from its configuration."""
    p = cfgmod.load(ref).protocol
    a = max((abs(x) for x in p.pretilt_deg), default=0.0)
    if tuple(p.pretilt_deg) != cfgmod.deboeuf_history(2, a):
        return f"history {cfgmod.history_label(p.pretilt_deg)}"
    at = "the ramp's rate" if p.history_rate == 1 else f"{p.history_rate:g}x the ramp's rate"
    return f"cycled twice to +-{a:g} deg at {at}"


def _mean(values) -> float:
    v = [_num(x) for x in values]
    v = [x for x in v if math.isfinite(x)]
    return sum(v) / len(v) if v else math.nan


def pile_table(study: dict) -> list[str]:
    """Markdown rows: per number, the mean of each engine over the seeds, and the mean paired
    difference with its 95% bootstrap interval over the seeds that have both."""
    pp = study["pile_against_pile"]
    ref, other = study["ref"], study["label"]
    lines = [f"| per pile | {ref} | {other} | {other} - {ref} (95% interval, seeds with both) |",
             "|---|---|---|---|"]
    for key, label, fmt in ROWS:
        if key not in pp["per_seed"]:
            continue
        s, d = pp["per_seed"][key], pp["difference"][key]
        diff = (f"{_f(_num(d['mean']), '+' + fmt)} [{_f(_num(d['ci_low']), '+' + fmt)}, "
                f"{_f(_num(d['ci_high']), '+' + fmt)}] ({d['n']})" if math.isfinite(_num(d["mean"]))
                else f"n/a ({d['n']})")
        c = d.get("censored")
        if c:
            diff += (f"; {c['bound']} {_f(_num(c['mean']), '+' + fmt)} [{_f(_num(c['ci_low']), '+' + fmt)}, "
                     f"{_f(_num(c['ci_high']), '+' + fmt)}] ({c['n']}) counting the {c['n_censored']} "
                     "without the event at the end of its tilt")
        lines.append(f"| {label} | {_f(_mean(s['ref']), fmt)} | {_f(_mean(s['value']), fmt)} | {diff} |")
    return lines


def shared(judged: dict[str, list], claims: list[Claim], pair=PAIR) -> dict[str, list[str]]:
    """{kind: [claim text (ours; theirs)]} of the claims of the paper that either engine's
    figures disagree with: "both" (not our engine's), "cd" (ours only), "dem" (the other engine
    only); ``judged``: {scale: :func:`~.document.judgements`' rows} of the two scales of
    ``pair``."""
    ref, other = (judged[s] for s in pair)
    out = {"both": [], "cd": [], "dem": []}
    for c, (_, a, _), (_, b, _) in zip(claims, ref, other):
        va, vb = a.verdict, b.verdict
        if c.paper == BEYOND or DISAGREES not in (va, vb) or MISSING in (va, vb):
            continue
        kind = "both" if va == vb == DISAGREES else "cd" if va == DISAGREES else "dem"
        out[kind].append(f"{c.text} (paper {c.paper}; CD {a.ours}, {va}; DEM {b.ours}, {vb})")
    return out


def _kinds(k: dict[str, list[str]]) -> list[str]:
    return ["- **In both engines** (not our engine's doing): "
            + ("; ".join(k["both"]) if k["both"] else "none") + ".",
            "- **In Contact Dynamics only** (the DEM agrees): "
            + ("; ".join(k["cd"]) if k["cd"] else "none") + ".",
            "- **In the DEM only**: " + ("; ".join(k["dem"]) if k["dem"] else "none") + "."]


def render_paper(study: dict | None, judged: dict[str, list], claims: list[Claim],
                 pair=PAPER_PAIR) -> list[str]:
    """Markdown lines of the subsection "At 4000 grains" of one pair of ``PAPER_PAIRS``: the
    reference preset's piles in both engines, pile against pile, and the claims on each side's
    figure documents (``judged``: {scale: judgements' rows} of ``pair``, from
    :func:`side_dirs`). Without the study, one line saying it is not yet computed and how to
    make it."""
    ref, other = pair
    n_target, history = target(pair), _history(ref)
    title = "At 4000 grains" if pair == PAPER_PAIR else f"At 4000 grains, with {ref}'s history"
    lines = ["", f"### {title}", ""]
    if study is None:
        return lines + [f"The paper-scale pair (preset `{other}`: {n_target} of `{ref}`'s "
                        f"piles, {history}, in the DEM, several hours each) is not yet computed "
                        f"(docs/dem.md; then `make engines ENGINES={ref}`)."]
    n = len(study["seeds"])
    lines += [f"`{ref}`'s piles (4000 grains, {history}) "
              f"carried through the same history and ramp by the DEM (preset `{other}`), against "
              f"`{ref}`'s records of the same seeds: {n} of {n_target} piles"
              + ("." if n >= n_target else " so far (**preliminary**)."), ""]
    lines += pile_table(study)
    if study["n_with_error"]:
        lines += ["", f"Every figure number ensemble against ensemble: {study['n_moved']} of "
                  f"{study['n_with_error']} numbers with a jackknife error differ by more than "
                  f"{study['sigma_limit']:g} combined standard errors."]
    else:
        lines += ["", f"On {n} piles no figure number has a jackknife error (it needs 3 runs): "
                  "the two engines' figures meet through the claims' verdicts below."]
    if all(s in judged for s in pair):
        lines += ["", f"The paper's claims on each engine's {n} piles (few piles: a verdict whose "
                  "number needs many runs may turn on one pile):", ""]
        lines += _kinds(shared(judged, claims, pair))
    return lines


def render(study: dict | None, judged: dict[str, list], claims: list[Claim],
           paper: list[str] | None = None) -> list[str]:
    """Markdown lines of the section; empty unless both scales of ``PAIR`` have figures. Without
    the study, the claims only (and how to make it). ``paper``: the lines of
    :func:`render_paper`, appended."""
    if any(s not in judged for s in PAIR):
        return []
    ref, other = PAIR
    lines = ["", "## Same piles, another model", "",
             f"The {ref} piles (the same seeds, so Contact Dynamics deposits the same piles) carried "
             f"through the same history and ramp by a second, independent engine: the soft-sphere "
             f"DEM of LAMMPS (preset `{other}`; Hookean contacts, k_n = 2e5 m g / d, restitution "
             "0.1, tangential springs k_t = 2/7 k_n, mu = 0.5; docs/dem.md), analysed by the same "
             f"library. Its verdicts are the `{other}` column of the tables above."]
    if study is None:
        lines += ["", "The pile-against-pile study is not yet made (`make engines`)."]
    else:
        n = len(study["seeds"])
        lines += ["", f"Pile against pile on {n} seeds (`make engines`, `tiltpile same-piles`): "
                  "the mean of each engine over the seeds, and the mean paired difference.", ""]
        lines += pile_table(study)
        lines += ["", f"Every figure number ensemble against ensemble: {study['n_moved']} of "
                  f"{study['n_with_error']} numbers with a jackknife error differ by more than "
                  f"{study['sigma_limit']:g} combined standard errors "
                  f"({study['n_numbers']} numbers in all)."]
    lines += ["", "Where the paper and our piles disagree:", ""]
    lines += _kinds(shared(judged, claims))
    return lines + (paper or [])


