"""The report's section "What the disagreements depend on": every claim judged under each
definition of the definitions study (``definitions.json`` of ``tiltpile definitions``, one per
scale's figures directory), and for each claim that disagrees under the analysis's own
definition the definitions that change its verdict, by measurement.

The judges are the claims' own (:mod:`.claims`), applied to each definition's figure documents
as to the figures' JSON (:func:`tiltpile.report.document.judgements`' rule: each claim's
:class:`~.judging.Judgement` on its figure document, without the notes).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from .judging import AGREES, DISAGREES, INCONCLUSIVE, MISSING, Claim, judge_document, missing, num, show

FILE = "definitions.json"
#: the definition the analysis uses (the study's first)
OURS = "force"
_MARK = {AGREES: "agrees", DISAGREES: "**disagrees**", INCONCLUSIVE: "inconclusive",
         MISSING: "n/a"}


def load(figures_dir) -> dict | None:
    """The study's JSON of ``figures_dir`` (None when it was not run there)."""
    return load_file(Path(figures_dir) / FILE)


def verdicts(doc: dict, claims: list[Claim]) -> dict[str, dict[str, tuple[str, str]]]:
    """{definition key: {claim key: (ours, verdict)}} of every definition of the study (its
    claims' :class:`~.judging.Judgement`, our value rendered)."""
    out = {}
    for d in doc["definitions"]:
        figs = d["documents"]
        row = {}
        for c in claims:
            stem = next((s for s in figs if s.startswith(c.figure + "_")), None)
            j = missing(c) if stem is None else judge_document(c, figs[stem])
            row[c.key] = (j.ours, j.verdict)
        out[d["key"]] = row
    return out


def depends_on(doc: dict, claims: list[Claim], key: str) -> str | None:
    """One line: what the verdict of claim ``key`` depends on in the study: the definitions
    that flip it from the analysis's own, or that none of those tried does (None when the
    claim is not in the study)."""
    v = verdicts(doc, claims)
    if OURS not in v or key not in v[OURS]:
        return None
    base = v[OURS][key][1]
    labels = {d["key"]: d["label"] for d in doc["definitions"]}
    moved = {}
    for dk, row in v.items():
        if dk != OURS and row[key][1] != base:
            moved.setdefault(row[key][1], []).append(labels[dk])
    if not moved:
        return f"{base} under every definition tried ({len(v)})"
    return "; ".join(f"{verdict} under {'; '.join(names)}" for verdict, names in moved.items())


def counts(row: dict) -> dict[str, int]:
    """How many claims of a definition's verdicts agree, disagree, are inconclusive."""
    out = {AGREES: 0, DISAGREES: 0, INCONCLUSIVE: 0, MISSING: 0}
    for _, verdict in row.values():
        out[verdict] += 1
    return out


def render(doc: dict | None, claims: list[Claim], scale: str = "", preface: str = "") -> list[str]:
    """Markdown lines of the section for one scale's study ([] without one); ``preface``: a
    paragraph before the study's own."""
    if not doc:
        return []
    v = verdicts(doc, claims)
    defs = doc["definitions"]
    fit = doc.get("fit") or {}
    g = num(fit.get("g"))
    how = ("given" if fit.get("given") else
           f"fitted by <z> = {show(num(fit.get('target')), '.2g')} on the quiet frames "
           f"({fit.get('n_quiet_frames')} frames)")
    z_list = _z_of(doc, "list")
    where = scale or f"{doc.get('n_runs')} runs of {doc.get('n_grains')} grains"
    lines = ["", f"## What the disagreements depend on ({where})", ""]
    lines += [preface, ""] if preface else []
    lines += [f"From `{doc.get('command') or 'tiltpile definitions'}`: {doc.get('n_runs')} runs of "
             f"{doc.get('n_grains')} grains ({(doc.get('history') or {}).get('label', '')}), every "
             "claim judged by its own rule on the figure numbers each definition gives. The one "
             f"number fitted is the gap of the contact list, g = {show(g, '.3g')} d ({how}); the "
             f"tables on that list give quiet-frame <z> = {show(z_list, '.3f')}.", ""]
    lines += [f"- **{d['label']}**: {d['what']}" + (f" (`{_params_text(d)}`)" if _params_text(d)
                                                     else "") for d in defs]
    lines += ["", "| claim | " + " | ".join(d["label"] for d in defs) + " |",
              "|---|" + "---|" * len(defs)]
    for c in claims:
        lines.append(f"| {c.text} | " + " | ".join(_MARK[v[d['key']][c.key][1]] for d in defs) + " |")
    tally = [counts(v[d["key"]]) for d in defs]
    lines.append("| *agree / disagree / inconclusive* | "
                 + " | ".join(f"{t[AGREES]} / {t[DISAGREES]} / {t[INCONCLUSIVE]}" for t in tally)
                 + " |")
    lines += ["", "What each disagreement under our definition depends on:", ""]
    base = v.get(OURS, {})
    for c in claims:
        if base.get(c.key, ("", ""))[1] == DISAGREES:
            lines.append(f"- **{c.text}**: {depends_on(doc, claims, c.key)}.")
    lines += ["", "What each definition fixes and breaks against ours (a claim that disagrees "
              "under ours and agrees under it; one that agrees under ours and not under it):", ""]
    text = {c.key: c.text for c in claims}
    for d in defs:
        if d["key"] == OURS:
            continue
        fixed = [text[k] for k, (_, vd) in v[d["key"]].items()
                 if vd == AGREES and base[k][1] == DISAGREES]
        broken = [text[k] for k, (_, vd) in v[d["key"]].items()
                  if vd != AGREES and base[k][1] == AGREES]
        lines.append(f"- **{d['label']}** fixes {_list(fixed)}; breaks {_list(broken)}.")
    keeps = [d for d, t in zip(defs, tally) if d["key"] != OURS
             and _keeps_agreements(v, d["key"], claims)]
    best = max(zip(defs, tally), key=lambda x: (x[1][AGREES], -x[1][DISAGREES]))
    lines += ["", f"Most agreements: **{best[0]['label']}** ({best[1][AGREES]} agree, "
              f"{best[1][DISAGREES]} disagree). Definitions that break none of the agreements "
              "under ours: " + ("; ".join(d["label"] for d in keeps) if keeps else "none") + "."]
    return lines


#: the 4000-grain study waits for this many piles (issue 51: 16 or more)
LARGE_RUNS = 16


def render_large(fast_dir, claims: list[Claim]) -> list[str]:
    """The section again at 4000 grains, from the paper-fast figures directory's study
    (``tiltpile definitions figures/paper-fast/records --records figures/paper-fast/definitions
    ...``, its gap g fixed at 1000 grains, so out of sample); marked preliminary below
    ``LARGE_RUNS`` piles. [] without the study."""
    doc = load(fast_dir)
    if not doc:
        return []
    n = doc.get("n_runs") or 0
    where = (f"{n} cycled piles of {doc.get('n_grains')} grains, `paper-fast`"
             + (f"; preliminary, {n} of the {LARGE_RUNS} piles the verdicts wait for"
                if n < LARGE_RUNS else ""))
    return render(doc, claims, scale=where)


#: every definition on the piles whose run files outlived the 16-pile study's records
#: (``tiltpile definitions ... --out figures/paper-fast/definitions-all.json``)
EVERY_FILE = "definitions-all.json"


def render_every(fast_dir, claims: list[Claim]) -> list[str]:
    """The section at 4000 grains for every definition, on the fewer piles that hold the records
    of all of them (``EVERY_FILE``), with how far its verdicts of the definitions the 16-pile
    study holds too differ from that study's: what the fewer piles cost. [] without it, and []
    once the larger study holds every one of its definitions on every one of its piles (it then
    says all this section would)."""
    doc = load_file(Path(fast_dir) / EVERY_FILE)
    if not doc:
        return []
    where = (f"{doc.get('n_runs')} cycled piles of {doc.get('n_grains')} grains, `paper-fast`, "
             "every definition")
    big = load(fast_dir)
    if not big:
        return render(doc, claims, scale=where)
    if subsumes(big, doc):
        return []
    v, w = verdicts(doc, claims), verdicts(big, claims)
    labels = {d["key"]: d["label"] for d in doc["definitions"]}
    shared = [k for k in v if k in w]
    differ = [f"{c.text} under {labels[k]}" for k in shared for c in claims
              if v[k][c.key][1] != w[k][c.key][1]]
    n_big = big.get("n_runs")
    said = (f"every verdict is the same on these piles as on the {n_big}" if not differ else
            f"{len(differ)} of {len(shared) * len(claims)} verdicts differ from those on the {n_big}")
    seeds = doc.get("seeds") or []
    preface = (f"These {len(seeds)} piles (seeds {_seeds(seeds)}) are the ones whose run files "
               f"outlived the study above, so they alone carry {_list([labels[k] for k in v if k not in w])}. "
               f"Of the {len(shared)} definitions both studies hold, {said} piles of the study above"
               + (": " + "; ".join(differ) if differ else "") + ".")
    return render(doc, claims, scale=where, preface=preface)


def subsumes(big: dict, small: dict) -> bool:
    """True when study ``big`` holds every definition of study ``small`` and every one of its
    seeds (a study without seeds is taken to hold none)."""
    keys = {d["key"] for d in big["definitions"]}
    seeds = set(big.get("seeds") or [])
    return ({d["key"] for d in small["definitions"]} <= keys
            and bool(small.get("seeds")) and set(small["seeds"]) <= seeds)


def load_file(path) -> dict | None:
    p = Path(path)
    return json.loads(p.read_text()) if p.is_file() else None


def _seeds(seeds: list[int]) -> str:
    s = sorted(int(x) for x in seeds)
    if s and s == list(range(s[0], s[-1] + 1)) and len(s) > 2:
        return f"{s[0]}-{s[-1]}"
    return ", ".join(str(x) for x in s)


def _list(items: list[str]) -> str:
    return "nothing" if not items else "; ".join(f"*{x}*" for x in items)


def _keeps_agreements(v: dict, key: str, claims: list[Claim]) -> bool:
    return all(v[key][c.key][1] == AGREES for c in claims if v[OURS][c.key][1] == AGREES)


def _z_of(doc: dict, key: str) -> float:
    for d in doc["definitions"]:
        if d["key"] == key:
            n = (d["documents"].get("fig2_avalanche_criterion") or {}).get("numbers", {})
            return num(n.get("z_quiet_run_mean"))
    return math.nan


def _params_text(d: dict) -> str:
    p = {**d.get("params", {}), **d.get("notebook", {})}
    return " ".join(f"-p {k} {v}" for k, v in p.items())


