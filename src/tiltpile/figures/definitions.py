"""What the paper's claims depend on: every figure number under each plausible definition the
paper leaves open, on one ensemble, for the report to judge claim by claim.

``tiltpile definitions DATA --out FILE`` (``make definitions``) runs this study:

1. **The one number fitted.** The surface gap g at which a contact list reaches the paper's
   <z> = 3.5 (:func:`fit_gap`): on the quiet frames of the analysis's own rule (frames not
   avalanching by the 2% criterion on force-bearing contacts), z of the bulk without rattlers,
   walls in, counting every pair of bodies within a gap g (:func:`tiltpile.figures.zcount.run_z`
   on a fine grid of g), each run's mean over its quiet frames, their mean over runs, and the
   crossing of 3.5 interpolated in log g (:func:`tiltpile.analysis.zcount.first_reaching`),
   rounded to three digits. ``--g`` gives it instead (the g fitted on another ensemble, to test
   it out of sample).
2. **The definitions** (:func:`definitions`), each a set of analysis parameters
   (:data:`tiltpile.analysis.DEFAULT_PARAMS`) or notebook parameters:

   * ``force``: the analysis's own (contacts carry f_n > 0, lost when f_n drops to 0);
   * ``list``, ``list-half``, ``list-double``: the contact list at g, g/2, 2g (``contact_rule
     gap:<g>``): z, rattlers, clusters, rigidity and lost contacts all on the list (a pair is
     lost when its gap opens beyond g);
   * ``touching``: every contact the run file lists, loaded or touching;
   * ``mixed``: z, rattlers, clusters and rigidity on the list at g, losses by force
     (``lost_rule force``);
   * ``stride-2``, ``mixed-stride-2``: every second stored frame (0.1 deg apart at the paper's
     presets, the spacing of the paper's Fig. 3 caption), with the force and the mixed rule;
   * ``peaks-*``: the peaks after which the failure rate is measured (Fig. 3's
     ``peak_rule``), when the notebook declares it.
3. **Every figure number** under each definition, as the figures' notebooks compute them
   (:func:`tiltpile.figures.same_piles.figure_documents`, the notebook's parameters with the
   definition's applied), the tables computed from the run files (their caches kept per
   parameter set, :mod:`tiltpile.analysis.observables`).

The JSON holds the fit and, per definition, its parameters and the figure documents, which the
report judges (``tiltpile.report``: "What the disagreements depend on"). It needs the run files
(near pairs come from the positions, which records do not hold for every frame), or, with
``--records ROOT`` and a given g, the records each definition's parameters were written at
(``tiltpile record --params``: ROOT/<key>/), which carry the study at 4000 grains across the
sessions that compute its runs.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from tiltpile.analysis import zcount as zc

from . import style

NAME = "definitions"
#: the surface gaps (d) on which <z> of the list is measured for the fit
GAP_GRID = tuple(float(g) for g in np.geomspace(1e-4, 2e-2, 34))


def _round(g: float, digits: int = 3) -> float:
    return float(f"{g:.{digits}g}")


def fit_gap(data_dir, frames=None, target: float = zc.PAPER_Z, grid=GAP_GRID, bar=None) -> dict:
    """The gap g (d) at which the quiet frames' <z> of a contact list reaches ``target``
    (module docstring, step 1). ``frames``: the ensemble's per-frame table at the default
    parameters (loaded if None). Returns dict g (rounded to 3 digits; None if no g of the grid
    reaches it), interpolated, target, grid, z (ensemble mean per grid point), per_run {seed:
    [...]}, n_quiet_frames."""
    from tiltpile.analysis import load_observables, run_files
    from tiltpile.store import open_run

    from .zcount import quiet_frames, run_z

    if frames is None:
        frames, _ = load_observables(data_dir, progress=False)
    pick = quiet_frames(frames)
    variant = (zc.ANALYSIS_VARIANT,)
    per_run, n_quiet = {}, 0
    for f in run_files(data_dir):
        with open_run(f) as run:
            seed = int(run.seed)
            ids = pick.get(seed, np.empty(0, dtype=np.int64))
            res = run_z(run, ids, (), tuple(grid), variant, bar=bar)
        n_quiet += int(ids.size)
        z = res["z"][:, :, 0]
        per_run[seed] = [float(x) for x in np.nanmean(z, axis=0)] if len(z) else [math.nan] * len(grid)
    mean = np.nanmean(np.array(list(per_run.values()), dtype=float), axis=0)
    hit = zc.first_reaching(grid, mean, target)
    g = hit["interpolated"]
    return {"target": float(target), "g": None if g is None else _round(g), "interpolated": g,
            "grid": list(grid), "z": [float(x) for x in mean], "per_run": per_run,
            "n_quiet_frames": n_quiet}


def definitions(g: float, notebooks_dir="notebooks") -> list[dict]:
    """The definitions of the study (module docstring, step 2) at the fitted gap ``g`` (d): dicts
    key, label, what (one line), params (analysis parameters), notebook (other notebook
    parameters)."""
    from . import build

    def gap(x):
        return f"gap:{_round(x)}"

    out = [
        {"key": "force", "label": "force (ours)", "params": {}, "notebook": {},
         "what": "contacts carry f_n > 0; a contact is lost when its f_n drops to 0"},
        {"key": "list", "label": f"list g = {_round(g):g}", "params": {"contact_rule": gap(g)},
         "notebook": {}, "what": f"every pair within a gap g = {_round(g):g} d is a contact, and "
                                 "is lost when its gap opens beyond g"},
        {"key": "list-half", "label": "list g/2", "params": {"contact_rule": gap(g / 2)},
         "notebook": {}, "what": f"the list at g/2 = {_round(g / 2):g} d"},
        {"key": "list-double", "label": "list 2g", "params": {"contact_rule": gap(2 * g)},
         "notebook": {}, "what": f"the list at 2g = {_round(2 * g):g} d"},
        {"key": "touching", "label": "touching", "params": {"contact_rule": "touching"},
         "notebook": {}, "what": "every contact the run file lists, loaded or touching (gap <= 0)"},
        {"key": "mixed", "label": "mixed", "params": {"contact_rule": gap(g), "lost_rule": "force"},
         "notebook": {}, "what": f"z, rattlers, clusters and rigidity on the list at g, losses by "
                                 "force"},
        {"key": "stride-2", "label": "stride 2", "params": {"frame_stride": 2}, "notebook": {},
         "what": "force rule on every second stored frame"},
        {"key": "mixed-stride-2", "label": "mixed + stride 2",
         "params": {"contact_rule": gap(g), "lost_rule": "force", "frame_stride": 2},
         "notebook": {}, "what": "the mixed rule on every second stored frame"},
    ]
    fig3 = build.figure_parameters("fig3")
    if "peak_rule" in fig3:
        for rule, what in PEAK_RULES:
            if rule != fig3["peak_rule"]:
                out.append({"key": f"peaks-{rule}", "label": f"peaks: {rule}", "params": {},
                            "notebook": {"peak_rule": rule}, "what": what})
    return out


def unknown_keys(only, notebooks_dir="notebooks") -> tuple[list[str], list[str]]:
    """(the keys of ``only`` that name no definition, sorted; every definition's key). The keys
    do not depend on g."""
    keys = [d["key"] for d in definitions(1.0, notebooks_dir)]
    return sorted(set(only) - set(keys)), keys


#: Fig. 3's peak rules other than its default, and what each takes as a peak of S_max
PEAK_RULES = (("local", "failure after every quiet local maximum of the largest cluster"),
              ("decile", "failure after the quiet frames of the largest clusters' top decile"),
              ("c0", "the enhancement read as C(0), the correlation at lag 0"))


def study(data_dir, preset: str | None = None, g: float | None = None, target: float = zc.PAPER_Z,
          notebooks_dir="notebooks", progress: bool = True, command: str | None = None,
          only=None, records=None) -> dict:
    """The whole study (module docstring) on the ensemble of run files in ``data_dir``;
    ``only``: the keys of the definitions to evaluate (None: every one; "force" always).

    ``records``: instead of run files, records (:mod:`tiltpile.figures.records`): ``data_dir``
    the records at the default parameters, ``records/<key>/`` those of each definition
    (``tiltpile record --params``, at the definition's parameters); ``g`` must be given (the fit
    needs the run files). A definition without records is left out (``missing``), and every
    definition is evaluated on the seeds all of them hold (``seeds``)."""
    from tiltpile.analysis import run_files
    from tiltpile.record import record_files

    from . import data as _data
    from .same_piles import FIGURES, figure_documents, subset

    if records is None and not run_files(data_dir):
        raise FileNotFoundError(f"no run_*.h5 in {data_dir}: the definitions need the run files "
                                "(near pairs come from every frame's positions), or records of "
                                "each definition (records=)")
    if records is not None and g is None:
        raise ValueError("from records, give g (the fit needs the run files)")
    if only is not None:
        unknown, keys = unknown_keys(only, notebooks_dir)
        if unknown:
            raise ValueError(f"no definition {unknown}; the study has {', '.join(keys)}")
    say = (lambda line: print(line, flush=True)) if progress else (lambda line: None)
    base = _data.load(data_dir, preset)
    if g is None:
        say("fitting the gap at which the contact list gives <z> = 3.5")
        fit = fit_gap(data_dir, base.frames, target)
        if fit["g"] is None:
            raise ValueError(f"no gap up to {GAP_GRID[-1]} d gives <z> = {target} on {data_dir}")
        g = fit["g"]
    else:
        if not g > 0:
            raise ValueError(f"g must be > 0 (d), got {g}")
        fit = {"target": float(target), "g": float(g), "given": True}
    defs = definitions(g, notebooks_dir)
    if only is not None:
        defs = [d for d in defs if d["key"] == "force" or d["key"] in only]
    missing, loaded = [], {}
    for d in defs:
        if not d["params"]:
            continue
        src = data_dir if records is None else Path(records) / d["key"]
        if records is not None and not record_files(src):
            missing.append(d["key"])
            continue
        say(f"tables of {d['label']}")
        loaded[d["key"]] = _data.load(src, preset, None, **d["params"])
    defs = [d for d in defs if d["key"] not in missing]
    seeds = sorted(set(int(x) for x in base.seeds).intersection(
        *(set(int(x) for x in e.seeds) for e in loaded.values())))
    if len(seeds) < len(base.seeds) or any(len(e.seeds) > len(seeds) for e in loaded.values()):
        base = subset(base, seeds)
        loaded = {k: subset(e, seeds) for k, e in loaded.items()}
    out, plain = [], None
    for k, d in enumerate(defs):
        say(f"[{k + 1}/{len(defs)}] {d['label']}")
        ens = loaded.get(d["key"], base)
        over = {**d["params"], **d["notebook"]}
        if d["params"] or plain is None:
            docs = figure_documents(ens, FIGURES, notebooks_dir, over)
            if not d["params"] and not d["notebook"]:
                plain = docs
        else:  # a notebook parameter of one figure: the others are the plain ones
            docs = dict(plain)
            for stem in FIGURES:
                if _declares(stem, d["notebook"], notebooks_dir):
                    docs.update(figure_documents(ens, (stem,), notebooks_dir, over))
        out.append({**d, "documents": docs})
    meta = base.meta
    return {"study": NAME, "command": command, "data_dir": str(data_dir), "preset": preset,
            "n_runs": meta.get("n_runs"), "n_grains": meta.get("n_grains"),
            "history": meta.get("history"), "seeds": seeds, "from": "records" if records else "runs",
            "missing": missing, "fit": fit, "definitions": out}


def write_definition_records(data_dir, root, g: float, only=None, workers: int | None = None,
                             progress: bool = True):
    """The records of every finished run of ``data_dir`` at the analysis parameters of each
    definition that has some (``only``: of these keys), into ``root/<key>/``
    (:func:`tiltpile.figures.records.write_records`, up-to-date ones skipped): what
    :func:`study` reads with ``records=root``. Yields (key, records written, directory)."""
    from .records import write_records

    if not g > 0:
        raise ValueError(f"g must be > 0 (d), got {g}")
    unknown, keys = unknown_keys(only or ())
    if unknown:
        raise ValueError(f"no definition {unknown}; the study has {', '.join(keys)}")
    for d in definitions(g):
        if not d["params"] or (only is not None and d["key"] not in only):
            continue
        out = Path(root) / d["key"]
        done = write_records(data_dir, out, workers=workers, progress=progress, params=d["params"])
        yield d["key"], int((done["status"] == "written").sum()), out


def compact_definition_records(base, root, only=None, progress: bool = True):
    """Leave out of the records of each definition (``root/<key>/``: :func:`write_definition_records`)
    what the records at the default parameters (``base``, the same runs: ``run_SSSS.npz`` of the
    same name) or those of an earlier definition (in the order of :func:`definitions`) hold bit
    for bit (:func:`tiltpile.record.compact_record`): the grains, the preparation, the picture
    frames the rules choose alike, and every table column they compute alike (the force rule's
    losses and kinetic columns for every list; the list's clusters for the mixed rule; the
    clusters and most frame columns of stride 2 are those of every frame at even frames). Each
    record is written again only if it is the same record, bit for bit, read back whole; what
    differs stays in it. ``only``: these keys. Holds each directory's records lock
    (:data:`tiltpile.figures.records.LOCK`). Yields (key, records rewritten, bytes before, bytes
    after, directory)."""
    from tiltpile.outputs import output_lock
    from tiltpile.record import compact_record, record_files

    from .records import LOCK

    unknown, keys = unknown_keys(only or ())
    if unknown:
        raise ValueError(f"no definition {unknown}; the study has {', '.join(keys)}")
    base, root = Path(base), Path(root)
    if not record_files(base):
        raise FileNotFoundError(f"no records run_*.npz in {base} (the records at the default "
                                "parameters, which the definitions' records borrow from)")
    earlier = []
    for d in definitions(1.0):
        if not d["params"]:
            continue
        out = root / d["key"]
        todo = record_files(out) if only is None or d["key"] in only else []
        if todo:
            n, before, after = 0, 0, 0
            with output_lock(out, LOCK, "a records writer", wait=True):
                bar = None
                if progress:
                    from tqdm.auto import tqdm
                    bar = tqdm(total=len(todo), desc=d["key"], unit="record")
                for rec in todo:
                    sources = [base / rec.name] + [root / k / rec.name for k in earlier]
                    res = compact_record(rec, sources)
                    n += res["status"] == "compacted"
                    before += res["bytes_before"]
                    after += res["bytes_after"]
                    if bar is not None:
                        bar.update()
                if bar is not None:
                    bar.close()
            yield d["key"], n, before, after, out
        earlier.append(d["key"])


def _declares(stem: str, params: dict, notebooks_dir) -> bool:
    """Whether the figure ``stem`` has any parameter of ``params``."""
    from . import build

    return any(k in build.parameters(stem) for k in params)


def write_study(doc: dict, path) -> Path:
    """Write the study's JSON (NaN as null) to ``path`` whole (a temporary name, then renamed)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    style.write_json(path, style.jsonable(doc))
    return path
