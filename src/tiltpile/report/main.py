"""The main report, ``paper/REPRODUCTION.md``: the paper's claims at the paper's scale, each with
its verdict along every axis measured (1000 grains, the best and worst contact definition, the
second engine), then per claim its rule and a short note, then the side studies, each once.

:func:`context` gathers the data (verdicts, numbers, judges' notes) from the figures' JSON under
one root (``figures/``: the default scale there, the others in ``figures/<preset>/``); the
sentences live in the Jinja2 template ``templates/main.md.j2`` (:func:`render`). Nothing here
writes a number into a sentence: the template formats the numbers it is given.
"""

from __future__ import annotations

import math
import re

import numpy as np
from pathlib import Path

from tiltpile.outputs import replaced_whole

from . import definitions as _definitions
from . import engines as _engines
from . import friction as _friction
from . import history_rate as _rate
from .claims import CLAIMS, RULES
from .document import judgements, load_figures
from .judging import AGREES, DISAGREES, INCONCLUSIVE, MISSING, Claim, Judgement
from .rigidity import BEYOND
from .scales import preset_dir, scale_dirs

#: the scale the report leads with, and the scale of its first axis
PAPER, SMALL = "paper", "default"
#: the columns of the cross-scale table, in order
SCALES = ("default-fresh", "default", "paper-fresh", "paper", "paper-fast", "paper-5x")
#: a verdict's rank when the best and the worst over the contact definitions are picked
_RANK = {AGREES: 0, INCONCLUSIVE: 1, DISAGREES: 2}
TEMPLATE = "main.md.j2"
#: the solver study's JSON, as `tiltpile solver-study` writes it (its full section, solver_study.md
#: beside it, is linked; the main report gives it in brief)
SOLVER_STUDY = Path("solver-study") / "solver_study.json"
#: the stiffness study's section, as `tiltpile stiffness-study` writes it (likewise)
STIFFNESS_SECTION = Path("stiffness-study") / "stiffness_study.md"


def headline(ours: str) -> str:
    """The headline of a judge's "ours": without parenthesised asides, up to the first "; "."""
    s = ours
    while True:
        t = re.sub(r"\s+\([^()]*\)", "", s)
        if t == s:
            break
        s = t
    return s.split("; ")[0].strip()


def _doc(figs: dict) -> dict:
    return next(iter(figs.values()), {})


def _judged(figures_dir, claims) -> tuple[dict, dict[str, Judgement]]:
    """(a figure document of the directory, {claim key: its Judgement}); ({}, {}) when the
    directory holds no figure."""
    figs = load_figures(figures_dir) if Path(figures_dir).is_dir() else {}
    if not figs:
        return {}, {}
    return _doc(figs), {c.key: j for c, j, _ in judgements(figs, claims)}


def _extremes(by_def: dict[str, str], labels: dict[str, str]) -> dict | None:
    """{"best": (verdict, [definitions]), "worst": (...), "n": definitions} over the contact
    definitions' verdicts of one claim ({definition key: verdict}); None without any."""
    known = {k: v for k, v in by_def.items() if v in _RANK}
    if not known:
        return None
    lo = min(_RANK[v] for v in known.values())
    hi = max(_RANK[v] for v in known.values())
    pick = lambda r: sorted(labels.get(k, k) for k, v in known.items() if _RANK[v] == r)  # noqa: E731
    verdict = {r: v for v, r in _RANK.items()}
    return {"best": (verdict[lo], pick(lo)), "worst": (verdict[hi], pick(hi)), "n": len(known)}


def _definitions_axis(figures_dir, claims) -> dict:
    """The definitions study of one scale: {"piles", "labels", "order", "verdicts": {claim key:
    {definition key: verdict}}, "extremes": {claim key: _extremes}}; {} without the study."""
    doc = _definitions.load(figures_dir)
    if not doc:
        return {}
    v = _definitions.verdicts(doc, claims)
    labels = {d["key"]: d["label"] for d in doc["definitions"]}
    per_claim = {c.key: {dk: row[c.key][1] for dk, row in v.items() if c.key in row} for c in claims}
    ours = v.get(_definitions.OURS, {})
    breaks = {labels[dk]: [c.text for c in claims if c.key in row and c.key in ours
                           and ours[c.key][1] == AGREES and row[c.key][1] != AGREES]
              for dk, row in v.items()}
    seeds = sorted(doc.get("seeds") or [])
    return {"piles": len(seeds) or doc.get("n_runs"), "seeds": _definitions._seeds(seeds) if seeds else "",
            "breaks": breaks,
            "labels": labels, "order": [d["key"] for d in doc["definitions"]],
            "verdicts": per_claim,
            "extremes": {k: _extremes(d, labels) for k, d in per_claim.items()}}


def _engine_pairs(root, claims) -> list[dict]:
    """Each CD/DEM pair measured: {"ref", "dem", "grains", "piles", "cd": {claim: verdict}, "other":
    {claim: verdict}, "study": its same-piles JSON or None, "rows": pile table rows}."""
    out = []
    pairs = [(_engines.PAIR, None)] + [(p, True) for p in _engines.PAPER_PAIRS]
    for pair, big in pairs:
        d = preset_dir(root, pair[1])
        if big:
            sides = {s: load_figures(p) if p.is_dir() else {} for s, p in
                     _engines.side_dirs(d, pair).items()}
        else:
            sides = {s: load_figures(preset_dir(root, s)) if preset_dir(root, s).is_dir() else {}
                     for s in pair}
        if not all(sides.values()):
            continue
        judged = {s: {c.key: j.verdict for c, j, _ in judgements(f, claims)} for s, f in sides.items()}
        doc = _doc(sides[pair[1]])
        study = _engines.load(d)
        out.append({"ref": pair[0], "dem": pair[1], "grains": doc.get("n_grains"),
                    "piles": doc.get("n_runs"), "cd": judged[pair[0]], "other": judged[pair[1]],
                    "study": study, "rows": _pile_rows(study)})
    return out


def _pile_rows(study: dict | None) -> list[dict]:
    """The pile-against-pile numbers of a same-piles study: label, each side's mean over the
    seeds, the mean paired difference and its 95% interval, the seeds with both."""
    if not study:
        return []
    pp = study["pile_against_pile"]
    rows = []
    for key, label, fmt in _engines.ROWS:
        if key not in pp["per_seed"]:
            continue
        s, d = pp["per_seed"][key], pp["difference"][key]
        if not d.get("n"):
            continue
        rows.append({"label": label, "fmt": fmt, "ref": _engines._mean(s["ref"]),
                     "value": _engines._mean(s["value"]), "diff": _num(d["mean"]),
                     "low": _num(d["ci_low"]), "high": _num(d["ci_high"]), "n": d["n"],
                     "censored": d.get("censored")})
    return rows


def _slides(per_run) -> dict:
    """{"n": runs that slid in the ramp, "runs": runs, "median": their median angle (NaN unless
    more than half slid, when the median of all runs is known)}."""
    got = sorted(_num(x) for x in (per_run or []) if x is not None and math.isfinite(_num(x)))
    runs = len(per_run or [])
    med = float(np.median(got + [math.inf] * (runs - len(got)))) if runs else math.nan
    return {"n": len(got), "runs": runs, "median": med if math.isfinite(med) else math.nan}


def _num(x) -> float:
    return float("nan") if x is None else float(x)


def _rates(root, claims) -> list[dict]:
    """Each history-rate check measured: the faster preset, its same-piles study's counts, the
    null's, the claims whose verdict differs, the decision, each side's cost."""
    out = []
    for pair in _rate.PAIRS:
        faster = preset_dir(root, pair[1])
        study = _rate.load(faster)
        if not study:
            continue
        sides = {s: load_figures(d) if d.is_dir() else {} for s, d in _rate.side_dirs(faster, pair).items()}
        if not all(sides.values()):
            continue
        judged = {s: judgements(f, claims) for s, f in sides.items()}
        differ = _rate.differing(judged, claims, pair)
        cost = {s: (_doc(f).get("cost") or {}) for s, f in sides.items()}
        out.append({"ref": pair[0], "faster": pair[1], "speedup": _rate.speedup(pair),
                    "seeds": len(study.get("seeds") or []), "n_moved": study.get("n_moved"),
                    "n_with_error": study.get("n_with_error"), "null": _rate.null_of(study),
                    "differ": differ, "decision": _rate.decide(study, len(differ)),
                    "detectable": _rate.detectable(study),
                    "sweeps": {s: (c.get("sweeps_per_run") or math.nan) for s, c in cost.items()},
                    "rows": _pile_rows(study)})
    return out


def _solver(path: Path) -> dict | None:
    """The solver study in brief, from its JSON: per setting its name, status, piles done of
    planned, core-hours per run, numbers moved of those with an error, claims flipped and the
    relative shift of <n_m> in the quiet frames (pile against pile); the settings still to run."""
    import json

    if not path.is_file():
        return None
    n = json.loads(path.read_text())["numbers"]
    rows, pending = [], []
    for st in n["settings"]:
        if st["committed"]:
            continue
        if not st["seeds_done"] and not st["health_stops"]:
            pending.append(st["name"])
            continue
        cmp_ = st.get("comparison") or {}
        nm = (st.get("pile_against_pile") or {}).get("n_m_quiet") or {}
        rows.append({"name": st["name"], "status": st["status"], "done": len(st["seeds_done"]),
                     "planned": st["seeds_planned"], "stops": len(st["health_stops"]),
                     "hours": (st.get("cost") or {}).get("core_hours_per_run"),
                     "moved": cmp_.get("n_moved"), "with_error": cmp_.get("n_with_error"),
                     "flipped": st.get("flipped") or [],
                     "n_m": _num(nm.get("relative")), "compared": len(st.get("seeds_compared") or [])})
    ref = next(st for st in n["settings"] if st["committed"])
    return {"rows": rows, "pending": pending, "ref_hours": (ref.get("cost") or {}).get("core_hours_per_run"),
            "runs": n["runs"]}


def _scale_table(root, claims) -> list[dict]:
    """Per scale of ``SCALES`` with figures: its piles, a few headline numbers of Fig. 2 and its
    claims' verdict counts."""
    out = []
    for name in SCALES:
        d = preset_dir(root, name)
        doc, judged = _judged(d, claims)
        if not judged:
            continue
        n2 = (load_figures(d).get("fig2_avalanche_criterion") or {}).get("numbers", {})
        counts = {v: sum(1 for j in judged.values() if j.verdict == v)
                  for v in (AGREES, DISAGREES, INCONCLUSIVE)}
        out.append({"name": name, "grains": doc.get("n_grains"), "runs": doc.get("n_runs"),
                    "history": (doc.get("history") or {}).get("label") or "fresh",
                    "onset": [_num(n2.get(k)) for k in ("theta_m_mean", "theta_m_ci_low", "theta_m_ci_high")],
                    "slide": _slides(n2.get("theta_avalanche_per_run")),
                    "z": [_num(n2.get(k)) for k in ("z_quiet_run_mean", "z_quiet_run_mean_ci_low",
                                                   "z_quiet_run_mean_ci_high")],
                    "n_m": [_num(n2.get(k)) for k in ("n_m_quiet_run_mean", "n_m_quiet_run_mean_ci_low",
                                                     "n_m_quiet_run_mean_ci_high")],
                    "verdicts": {k: j.verdict for k, j in judged.items()}, "counts": counts})
    return out


def context(root="figures", claims: list[Claim] | None = None) -> dict:
    """Everything the main report says, as data (module docstring)."""
    claims = CLAIMS if claims is None else claims
    root = Path(root)
    paper_doc, paper = _judged(preset_dir(root, PAPER), claims)
    if not paper:
        raise FileNotFoundError(f"no fig*.json in {preset_dir(root, PAPER)}: the main report leads "
                                "with the paper's scale (make figures PRESET=paper)")
    _, small = _judged(scale_dirs(root)[SMALL], claims)
    defs = {"4000": _definitions_axis(preset_dir(root, "paper-fast"), claims),
            "1000": _definitions_axis(scale_dirs(root)[SMALL], claims)}
    engines = _engine_pairs(root, claims)
    big_dem = [e for e in engines if e["grains"] == paper_doc.get("n_grains")]
    small_dem = [e for e in engines if e["grains"] != paper_doc.get("n_grains")]
    rows = []
    for i, c in enumerate(claims):
        j = paper[c.key]
        ours = j.ours
        rows.append({"n": i + 1, "key": c.key, "text": c.text, "paper": c.paper, "beyond": c.paper == BEYOND,
                     "ours": ours, "headline": headline(ours), "verdict": j.verdict, "note": j.note,
                     "reason": j.reason, "values": j.values, "rule": RULES.get(c.key),
                     "small": small[c.key].verdict if c.key in small else MISSING,
                     "definitions": defs["4000"].get("extremes", {}).get(c.key),
                     "dem_big": [e["other"].get(c.key, MISSING) for e in big_dem],
                     "dem_small": [e["other"].get(c.key, MISSING) for e in small_dem]})
    counts = {v: sum(1 for r in rows if r["verdict"] == v and not r["beyond"])
              for v in (AGREES, DISAGREES, INCONCLUSIVE)}
    friction = _friction.load(scale_dirs(root)[SMALL])
    mc = friction["numbers"].get("mohr_coulomb") if friction else None
    return {"paper_doc": paper_doc, "rows": rows, "counts": counts,
            "n_paper_claims": sum(1 for r in rows if not r["beyond"]),
            "scales": _scale_table(root, claims), "definitions": defs,
            "engines": engines, "big_dem": big_dem, "small_dem": small_dem,
            "rates": _rates(root, claims),
            "friction": {"answer": _friction.answer(mc)} if friction else None,
            "solver": _solver(Path(root) / SOLVER_STUDY),
            "stiffness": (stiff.read_text().strip("\n") if (stiff := Path(root) / STIFFNESS_SECTION).is_file()
                          else None),
            "verdicts": (AGREES, DISAGREES, INCONCLUSIVE, MISSING)}


def _environment():
    import jinja2

    env = jinja2.Environment(loader=jinja2.PackageLoader("tiltpile.report", "templates"),
                             undefined=jinja2.StrictUndefined, trim_blocks=True,
                             lstrip_blocks=True, keep_trailing_newline=True)
    env.filters["f"] = _fmt
    env.filters["ci"] = _ci
    env.filters["v"] = _verdict
    env.filters["wrap"] = _wrap
    return env


def _fmt(x, spec: str = ".3g") -> str:
    """A number formatted with ``spec``; "n/a" for None or NaN."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return format(x, spec)


def _ci(xs, spec: str = ".3g") -> str:
    """[estimate, low, high] as 'e [l, h]' ('e' without an interval, 'n/a' without a value)."""
    e, lo, hi = xs
    if not math.isfinite(e):
        return "n/a"
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return _fmt(e, spec)
    return f"{_fmt(e, spec)} [{_fmt(lo, spec)}, {_fmt(hi, spec)}]"


def _verdict(v: str) -> str:
    """A verdict as the tables print it: a disagreement in bold."""
    return f"**{v}**" if v == DISAGREES else v


def _wrap(text: str, width: int = 200) -> str:
    """A paragraph broken into lines of at most ``width`` characters (Markdown joins them)."""
    import textwrap

    return textwrap.fill(text, width=width, break_long_words=False, break_on_hyphens=False)


def render(root="figures", claims: list[Claim] | None = None) -> str:
    """The main report's Markdown (module docstring)."""
    return _environment().get_template(TEMPLATE).render(**context(root, claims))


def write_main_report(root="figures", out="paper/REPRODUCTION.md",
                      claims: list[Claim] | None = None) -> Path:
    """Render the main report into ``out`` (whole or not at all)."""
    text = render(root, claims)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with replaced_whole(out) as tmp:
        tmp.write_text(text)
    return out
