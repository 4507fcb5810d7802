"""Generated blocks of the hand-written documents: every number the README (and any doc) quotes
from the figures' JSON is rendered here, between two marker lines, never typed.

A block in a Markdown file::

    <!-- generated: NAME (tiltpile docs; do not edit) -->
    ...
    <!-- end generated: NAME -->

``tiltpile docs`` (``make docs``, also run by ``make reports``) re-renders every block of the
files in ``FILES`` from the templates ``templates/<NAME>.md.j2`` with the main report's context
(:func:`tiltpile.report.main.context`) and the presets' tables (:func:`presets`, the named
ones; :func:`preset_axes`, every triple of the axes); ``--check``
changes nothing and exits 1 when a block is stale (the freshness test runs it). A block name
with no template, or a marker without its end, is an error naming the file and the line.

Beside the report's context the templates read the committed JSON through small loaders, each
returning the file's numbers as they are (or a number derived from them alone, as named):
``figs`` (:func:`figure_numbers`), ``meta`` (:func:`figure_meta`: runs, grains, history, cost),
``derived`` (:func:`derived`: Fig. 2's two populations and per-run angles summarized),
``same_piles`` (:func:`same_piles`: the pile-against-pile studies and their sides' figures),
``preparation`` (:func:`preparation`: the preparation studies at 1000 and 4000 grains),
``definitions_study`` (:func:`definitions`: each definition's figure numbers) and ``dem_z``
(:func:`dem_z`: each DEM record's z beside its Contact Dynamics twin's).
"""

from __future__ import annotations

import re
from pathlib import Path

from tiltpile import config as cfgmod
from tiltpile.outputs import replaced_whole

#: the documents that hold generated blocks, from the repository's root, and the prefix of the
#: templates their blocks are rendered from (``templates/<prefix>_<name>.md.j2``)
DOCUMENTS = {"README.md": "readme", "docs/presets.md": "presets", "docs/figures.md": "figures",
             "docs/dem.md": "dem", "docs/performance.md": "performance", "docs/cli.md": "cli",
             "docs/method.md": "method"}
FILES = tuple(DOCUMENTS)
BEGIN = re.compile(r"^<!-- generated: ([a-z0-9_-]+) \(tiltpile docs; do not edit\) -->$")
END = "<!-- end generated: {name} -->"


class BlockError(ValueError):
    """A document's generated block is malformed or names no template."""


def _measured(p: cfgmod.Preset, root) -> dict:
    """The measured cost per run of preset ``p`` where a committed figure document holds it (its
    own Fig. 2's, or a pile-against-pile study's side of it): the document's ``cost`` (sweeps,
    steps) with its runs' wall time from the committed records (:mod:`.wall`); {} without one."""
    from . import wall

    cost = {}
    base = Path(root).parent / p.figures
    for f in sorted(base.glob("fig2_*.json")) + sorted(base.glob(f"same-piles/{p.name}/fig2_*.json")):
        cost = wall.load(f).get("cost") or {}
    return cost


def presets(root="figures") -> list[dict]:
    """One row per named preset: its name, grains, history, engine, the runs of its ``make
    figures``, and its measured cost per run where a committed figure document holds it: the
    sweeps (the document's ``cost``) and the wall time (its runs' committed records, :mod:`.wall`;
    None without them)."""
    out = []
    for p in cfgmod.PRESET_TABLE:
        cfg = cfgmod.load(p.name)
        label = cfgmod.history_label(cfg.protocol.pretilt_deg) if cfg.protocol.pretilt_deg else "fresh"
        cost = _measured(p, root)
        step = cfg.protocol.pretilt_per_step_deg or cfg.protocol.tilt_per_step_deg
        rate = step / cfg.protocol.tilt_per_step_deg
        out.append({"name": p.name, "grains": cfg.scene.n, "runs": p.runs,
                    "history": ("fresh" if not cfg.protocol.pretilt_deg else
                                "cycled, at the ramp's rate" if rate == 1 else
                                f"cycled, {rate:g}x the ramp's rate"),
                    "label": label, "engine": "DEM" if cfg.dem is not None else "CD",
                    "sweeps": cost.get("sweeps_per_run"), "hours": (cost.get("seconds_per_run") or 0) / 3600
                    or None, "figures": p.figures})
    return out


def preset_axes(root="figures") -> list[dict]:
    """One row per preset, every triple of the axes (``config.ALL_PRESETS``), in the axes' order
    (scale, engine, history): ``name``, ``scale``, ``history``, ``engine`` (the axes' values),
    ``history_label`` (``config.History.label``), ``alias`` (a named preset), ``use``,
    ``grains``, ``runs`` and ``figures`` of its ``make figures``, ``steps_history`` and
    ``steps_ramp`` (``config.tilt_steps``: at most, of solver.dt), and its measured cost per run
    where committed figures hold it (:func:`_measured`): ``sweeps``, ``dem_steps`` (a DEM run's
    steps) and ``hours`` (None without)."""
    axes = cfgmod.PRESET_AXES
    order = {(s, e, h): k for k, (s, e, h) in enumerate(
        (s, e, h) for s in axes["scale"] for e in axes["engine"] for h in axes["history"])}
    labels = {h.name: h.label for h in cfgmod.PRESET_HISTORIES}
    named = set(cfgmod.PRESETS)
    out = []
    for p in sorted(cfgmod.ALL_PRESETS, key=lambda p: order[(p.scale, p.engine, p.history)]):
        cfg = cfgmod.load(p.name)
        steps = cfgmod.tilt_steps(cfg)
        cost = _measured(p, root)
        dem = p.engine == "dem"
        out.append({"name": p.name, "scale": p.scale, "history": p.history, "engine": p.engine,
                    "history_label": labels[p.history], "alias": p.name in named, "use": p.use,
                    "grains": cfg.scene.n, "runs": p.runs, "figures": p.figures,
                    "steps_history": steps["history"], "steps_ramp": steps["ramp"],
                    "sweeps": None if dem else cost.get("sweeps_per_run"),
                    "dem_steps": cost.get("steps_per_run") if dem else None,
                    "hours": (cost.get("seconds_per_run") or 0) / 3600 or None})
    return out


def figure_numbers(root="figures") -> dict[str, dict[str, dict]]:
    """{preset: {figure stem: the figure's ``numbers``}} of every preset whose figures directory
    holds figure JSON (the templates read any number as ``figs[preset][stem][key]``)."""
    from .document import load_figures

    out = {}
    for p in cfgmod.PRESET_TABLE:
        d = Path(root).parent / p.figures
        if d.is_dir():
            figs = load_figures(d)
            if figs:
                out[p.name] = {stem: doc.get("numbers", {}) for stem, doc in figs.items()}
    return out


def figure_meta(root="figures") -> dict[str, dict]:
    """{preset: what its figure documents say beside their numbers}: ``n_runs``, ``n_grains``,
    ``seeds``, ``history`` (the label, "fresh" without one), ``engine`` ("lammps" for the DEM,
    "cd" otherwise) and ``cost`` (the runs' own cost record, ``ensemble_data.ensemble_cost``:
    mean sweeps and DEM steps from the document, median wall seconds of the runs timed whole
    from their committed records, :mod:`.wall`, absent without them), of every preset whose
    figures directory holds a Fig. 2 document."""
    from . import wall

    out = {}
    for p in cfgmod.PRESET_TABLE:
        f = Path(root).parent / p.figures / "fig2_avalanche_criterion.json"
        if f.is_file():
            out[p.name] = _meta(wall.load(f))
    return out


def _meta(doc: dict) -> dict:
    return {"n_runs": doc.get("n_runs"), "n_grains": doc.get("n_grains"), "seeds": doc.get("seeds") or [],
            "history": (doc.get("history") or {}).get("label") or "fresh",
            "engine": doc.get("engine") or "cd", "cost": doc.get("cost") or {}}


def populations(fig2: dict) -> dict:
    """The two populations Fig. 2b fits to log10 of the lost fraction, in lost fractions: the
    ``lower`` and ``upper`` means, the share of the lower one above the cutoff and of the upper
    one below it (``judging.wrong_side``), ``separated`` (both shares at most
    ``judging.SEPARATION``: the cutoff_in_gap claim's rule), and the cutoff as a number of
    contacts of a mean frame (``cutoff`` x ``n_active_mean``); {} without a fit."""
    import math

    from .judging import SEPARATION, num, wrong_side

    b = fig2.get("lost_bimodality") or {}
    means = b.get("means") or []
    if len(means) != 2:
        return {}
    cutoff = num(fig2.get("cutoff"))
    above, below = wrong_side(b, cutoff)
    return {"lower": 10.0 ** num(means[0]), "upper": 10.0 ** num(means[1]),
            "lower_above": above, "upper_below": below,
            "separated": bool(above <= SEPARATION and below <= SEPARATION),
            "cutoff_contacts": cutoff * num(fig2.get("n_active_mean")) if math.isfinite(cutoff) else math.nan}


def angles(per_run) -> dict:
    """A per-run list of angles (None where a run has none), summarized: ``runs``, ``n`` (runs
    with one), ``values`` (theirs, sorted), ``min``, ``max``, ``median`` (of those with one;
    None without any) and ``none`` (runs without one)."""
    import statistics

    per = list(per_run or [])
    got = sorted(float(v) for v in per if v is not None)
    return {"runs": len(per), "n": len(got), "none": len(per) - len(got), "values": got,
            "min": got[0] if got else None, "max": got[-1] if got else None,
            "median": statistics.median(got) if got else None}


def derived(root="figures") -> dict[str, dict]:
    """{preset: numbers derived from its committed Fig. 2 document alone}: ``populations``
    (:func:`populations`), ``onset``, ``slide``, ``avalanche`` (:func:`angles` of its first 2%
    onsets, first sustained flows and avalanche angles per run), ``quiet_past`` (runs whose first
    onset comes at or after 14.4 deg, the paper's earliest window of Fig. 5, or never: the
    preparation study's ``n_runs_quiet_past``) and ``slide_after_avalanche`` (:func:`angles` of
    each run's first sustained flow minus its avalanche angle, over the runs with both)."""
    from tiltpile.paper_values import QUIET_DEG

    QUIET_PAST_DEG = QUIET_DEG.value      # as the preparation study counts its runs
    figs = figure_numbers(root)
    out = {}
    for name, f in figs.items():
        n = f.get("fig2_avalanche_criterion")
        if not n:
            continue
        onsets = n.get("theta_m_per_run") or []
        both = [(s, a) for s, a in zip(n.get("theta_slide_per_run") or [], n.get("theta_avalanche_per_run") or [])
                if s is not None and a is not None]
        out[name] = {"populations": populations(n), "onset": angles(onsets),
                     "slide": angles(n.get("theta_slide_per_run")),
                     "avalanche": angles(n.get("theta_avalanche_per_run")),
                     "quiet_past": sum(1 for v in onsets if v is None or v >= QUIET_PAST_DEG),
                     "slide_after_avalanche": angles([s - a for s, a in both])}
    return out


def same_piles(root="figures") -> dict[str, dict]:
    """{preset: its committed pile-against-pile study} (``<figures>/same-piles/same_piles.json``
    of ``tiltpile same-piles``: the history-rate checks below ``paper-fast`` and ``paper-5x``, the
    engines' comparisons below the DEM presets), each with what the templates read:
    ``ref``, ``label``, ``seeds``, ``n_moved``, ``n_with_error``, ``null`` (None where not
    measured) as the study holds them; ``rows`` {per-seed number: {"ref", "value" (each side's
    mean over the seeds), "diff", "low", "high" (the mean paired difference and its interval),
    "n" (seeds with both), "ratio" (value / ref)}}; ``sides`` {label: {figure stem: numbers}} and
    ``meta`` {label: :func:`figure_meta`'s entry} of the figure documents the study wrote of each
    side; ``populations`` {label: :func:`populations` of that side's Fig. 2}."""
    import json
    import math

    from .document import load_figures
    from .engines import _mean
    from .judging import num

    out = {}
    for p in cfgmod.PRESET_TABLE:
        d = Path(root).parent / p.figures / "same-piles"
        f = d / "same_piles.json"
        if not f.is_file():
            continue
        study = json.loads(f.read_text())
        pp = study.get("pile_against_pile") or {}
        rows = {}
        for key, s in (pp.get("per_seed") or {}).items():
            diff = (pp.get("difference") or {}).get(key) or {}
            ref, value = _mean(s.get("ref") or []), _mean(s.get("value") or [])
            rows[key] = {"ref": ref, "value": value, "diff": num(diff.get("mean")),
                         "low": num(diff.get("ci_low")), "high": num(diff.get("ci_high")),
                         "n": diff.get("n", 0), "censored": diff.get("censored"),
                         "ratio": value / ref if ref and math.isfinite(ref) else math.nan}
        sides, meta, pops = {}, {}, {}
        for label in (study.get("ref"), study.get("label")):
            figs = load_figures(d / label) if label and (d / label).is_dir() else {}
            if figs:
                sides[label] = {stem: doc.get("numbers", {}) for stem, doc in figs.items()}
                meta[label] = _meta(figs.get("fig2_avalanche_criterion") or next(iter(figs.values())))
                pops[label] = populations(sides[label].get("fig2_avalanche_criterion") or {})
        out[p.name] = {"ref": study.get("ref"), "label": study.get("label"),
                       "seeds": study.get("seeds") or [], "n_moved": study.get("n_moved"),
                       "n_with_error": study.get("n_with_error"), "null": study.get("null"),
                       "rows": rows, "sides": sides, "meta": meta, "populations": pops}
    return out


def definitions(root="figures") -> dict[str, dict]:
    """{preset: its committed definitions study} (``definitions.json`` of ``tiltpile
    definitions``: ``figures/definitions.json`` of the default piles, ``figures/paper-fast/`` at
    4000 grains), each {"n_runs", "n_grains", "seeds" (the piles the study read; [] where it does
    not say), "labels" {definition key: label}, "figs" {definition key: {figure stem: numbers}}},
    the definitions in the study's order."""
    from . import definitions as _definitions

    out = {}
    for p in cfgmod.PRESET_TABLE:
        doc = _definitions.load(Path(root).parent / p.figures)
        if not doc:
            continue
        out[p.name] = {"n_runs": doc.get("n_runs"), "n_grains": doc.get("n_grains"),
                       "seeds": sorted(doc.get("seeds") or []),
                       "labels": {d["key"]: d["label"] for d in doc["definitions"]},
                       "figs": {d["key"]: {stem: f.get("numbers", {}) for stem, f in d["documents"].items()}
                                for d in doc["definitions"]}}
    return out


#: the per-run numbers compared between two histories of the same amplitude at different rates
#: (:func:`preparation`'s ``between``)
BETWEEN = ("theta_first_onset", "z_quiet")


def _history_key(label: str, pretilt) -> str:
    """A preparation ensemble's short name, as ``make preparation PREP_HISTORIES`` names them:
    "fresh", "cyc<amplitude>", "cyc<amplitude>r<N>" for a history at N times the ramp's rate."""
    if not pretilt:
        return "fresh"
    amp = max(abs(float(x)) for x in pretilt)
    m = re.search(r"at (\d+(?:\.\d+)?)x rate", label)
    return f"cyc{amp:g}" + (f"r{m.group(1)}" if m else "")


def preparation(root="figures") -> dict[str, dict]:
    """The committed preparation studies, {"default": ``figures/preparation.json`` (1000 grains),
    "paper": ``figures/paper/preparation.json`` (4000 grains)} (those present), each {"reference":
    the short name of the reference ensemble, "ensembles": {short name: the study's numbers of
    that ensemble (its means, intervals, ``per_run``, ``repose``, ...) with its ``label`` and its
    runs' ``cost``}, "differences": {short name: the study's differences from the reference},
    "between": {(faster, slower) as "faster:slower": {number: interval}}}. Short names:
    :func:`_history_key`. ``between`` compares each history run faster than the ramp with the same
    history at the ramp's rate, by the study's own interval (``stats.bootstrap.diff_ci`` of the
    per-run values, its seed): the ``BETWEEN`` numbers."""
    import json

    from tiltpile.analysis.stats.bootstrap import diff_ci

    out = {}
    for name in ("default", "paper"):
        p = Path(root).parent / cfgmod.preset_info(name).figures / "preparation.json"
        if not p.is_file():
            continue
        doc = json.loads(p.read_text())
        n = doc.get("numbers") or {}
        keys = {e["label"]: _history_key(e["label"], e.get("pretilt_deg")) for e in doc.get("ensembles", [])}
        cost = {e["label"]: e.get("cost") or {} for e in doc.get("ensembles", [])}
        ens = {keys.get(lab, lab): {**e, "label": lab, "cost": cost.get(lab, {})}
               for lab, e in (n.get("ensembles") or {}).items()}
        between = {}
        for k, e in ens.items():
            base = re.sub(r"r[\d.]+$", "", k)
            if base != k and base in ens:
                between[f"{k}:{base}"] = {q: diff_ci(e["per_run"][q], ens[base]["per_run"][q]) for q in BETWEEN}
        out[name] = {"reference": keys.get(n.get("reference"), n.get("reference")), "ensembles": ens,
                     "differences": {keys.get(lab, lab): d for lab, d in (n.get("differences") or {}).items()},
                     "between": between}
    return out


#: the DEM presets whose committed records docs/method.md's table of z reads
DEM_Z_PRESETS = ("default-dem", "paper-fast-dem", "paper-5x-dem")


def dem_z(root="figures") -> dict:
    """Each committed DEM record's bulk z beside that of the Contact Dynamics run of the same seed:
    {"rows": [{"preset", "seed", "z0", "z_quiet", "quiet", "frames", "cd_z0", "cd_z_quiet"}],
    "presets": {name: {"runs", "grains", "z0": [min, max, mean], "z_quiet": [min, max, mean]}},
    "cd": {"z0": [min, max], "z_quiet": [min, max]}, "difference": {"z0": [min, max], "z_quiet":
    [min, max]}}. DEM: the record's ``frames.z`` at its first frame and its mean over the frames
    not avalanching (``frames.avalanching``: the 2% criterion, as the figures); CD: the ``ref``
    side of the preset's committed ``same-piles/same_piles.json`` (None for a seed it lacks)."""
    import json

    import numpy as np

    from tiltpile.record import read_record, record_files

    rows, presets = [], {}
    for name in DEM_Z_PRESETS:
        base = Path(root).parent / cfgmod.preset_info(name).figures
        recs = record_files(base / "records")
        if not recs:
            continue
        sp = base / "same-piles" / "same_piles.json"
        pap = json.loads(sp.read_text())["pile_against_pile"] if sp.is_file() else {"seeds": [], "per_seed": {}}
        mine = []
        for path in recs:
            rec = read_record(path, pictures=False)
            fr = rec.frames
            order = np.argsort(np.asarray(fr["frame"]), kind="stable")
            z, quiet = np.asarray(fr["z"])[order], ~np.asarray(fr["avalanching"], bool)[order]
            seed = int(rec.meta["seed"])
            k = pap["seeds"].index(seed) if seed in pap["seeds"] else None

            def ref(q):
                return None if k is None else float(pap["per_seed"][q]["ref"][k])
            mine.append({"preset": name, "seed": seed, "z0": float(z[0]),
                         "z_quiet": float(z[quiet].mean()), "quiet": int(quiet.sum()),
                         "frames": int(z.size), "cd_z0": ref("z_start"), "cd_z_quiet": ref("z_quiet"),
                         "grains": cfgmod.load(name).scene.n})
        rows += mine
        presets[name] = {"runs": len(mine), "grains": mine[0]["grains"],
                         **{q: [min(r[q] for r in mine), max(r[q] for r in mine),
                                sum(r[q] for r in mine) / len(mine)] for q in ("z0", "z_quiet")}}

    def span(vals):
        vals = [v for v in vals if v is not None]
        return [min(vals), max(vals)] if vals else None
    return {"rows": rows, "presets": presets,
            "cd": {q: span(r[f"cd_{q}"] for r in rows) for q in ("z0", "z_quiet")},
            "difference": {q: span(r[q] - r[f"cd_{q}"] for r in rows if r[f"cd_{q}"] is not None)
                           for q in ("z0", "z_quiet")}}


def _environment():
    from .main import _environment as env

    return env()


def render_all(root="figures") -> dict[str, str]:
    """{block name: its Markdown} of every template ``templates/<prefix>_<name>.md.j2`` of a
    document's prefix (``DOCUMENTS``), rendered with the context of the module docstring."""
    from .main import context

    env = _environment()
    ctx = {**context(root), "presets": presets(root), "preset_axes": preset_axes(root),
           "figs": figure_numbers(root),
           "meta": figure_meta(root), "derived": derived(root), "same_piles": same_piles(root),
           "preparation": preparation(root), "definitions_study": definitions(root),
           "dem_z": dem_z(root),
           # docs/cli.md's keys and the presets' pile depths (tiltpile config prints the same)
           "config_keys": cfgmod.describe_keys(),
           "pile_depths": [{"name": p.name, **cfgmod.describe_depth(cfgmod.load(p.name))}
                           for p in cfgmod.PRESET_TABLE]}
    names = [n[:-len(".md.j2")] for n in env.list_templates() if n.endswith(".md.j2")
             and n.split("_")[0] in DOCUMENTS.values()]
    return {n: env.get_template(f"{n}.md.j2").render(**ctx).rstrip("\n") for n in names}


def fill(text: str, blocks: dict[str, str], where: str = "") -> str:
    """``text`` with every generated block replaced by ``blocks[name]`` (BlockError naming
    ``where`` and the line for an unknown name or a block without its end)."""
    lines = text.split("\n")
    out, i = [], 0
    while i < len(lines):
        m = BEGIN.match(lines[i])
        out.append(lines[i])
        if not m:
            i += 1
            continue
        name = m.group(1)
        if name not in blocks:
            raise BlockError(f"{where}:{i + 1}: generated block {name!r} has no template "
                             f"(known: {', '.join(sorted(blocks))})")
        end = END.format(name=name)
        try:
            j = lines.index(end, i + 1)
        except ValueError:
            raise BlockError(f"{where}:{i + 1}: generated block {name!r} has no end line "
                             f"{end!r}") from None
        out += blocks[name].split("\n") + [end]
        i = j + 1
    return "\n".join(out)


def update(repo=".", root="figures", check: bool = False) -> list[Path]:
    """Re-render every block of ``FILES`` under ``repo``; the files that changed (with ``check``,
    that would change: nothing is written). Each file is written whole or not at all."""
    repo = Path(repo)
    blocks = render_all(repo / root)
    changed = []
    for name in FILES:
        p = repo / name
        if not p.exists():
            continue
        old = p.read_text()
        new = fill(old, blocks, name)
        if new != old:
            changed.append(p)
            if not check:
                with replaced_whole(p) as tmp:
                    tmp.write_text(new)
    return changed
