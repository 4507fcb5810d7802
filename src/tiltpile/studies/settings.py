"""What the side studies share: a study is a list of settings (data), each one ensemble of the
study's preset with the setting's overrides on the same seeds as the committed setting's
(``reference``), each compared with it on the same piles.

* **the plan** (:func:`check_runs`, :func:`check_preset`, :func:`configure`): every setting's
  configuration is validated through the configuration module before anything runs (an unknown
  key, a value out of range, a setting named twice or one whose configuration is another's is
  one ``ConfigError`` line naming the setting); :class:`Planned` holds a setting, its
  configuration and its seeds (a study may run fewer piles of an expensive setting);
* **the runs as the manifest recorded them** (:func:`runs_doc`, ``RUNS_FILE`` in the setting's
  records directory): done, stopped by the health rules (:func:`stop_rule`: a failed setting,
  listed with its rule, not compared, not a crash) or failed otherwise (retried);
* **the records, their cost and the comparisons** (:func:`recorded`, :func:`cost`,
  :func:`compare`, :func:`documents`): each comparison is the same-piles study
  (:func:`tiltpile.figures.same_piles.study`) kept in its directory with the digest of its
  inputs (:func:`fingerprint`: the records used, the figures' and analysis' code, the
  notebooks) and reused while that digest holds; :func:`compare_settings` compares every
  setting with the committed one;
* **the claims** (:func:`verdicts`, :func:`flipped`): the report's judges on a side's figure
  documents, and the claims whose verdict differs between two sides;
* **a setting's entry** of a study's JSON (:func:`setting_entry`: status, seeds done and
  compared, health stops, cost, the comparison's counts, the claims' verdicts and flips);
* **the stages a study's command runs** (:func:`run_ensembles`, :func:`write_setting_records`,
  :func:`seed_records`, :func:`in_fresh_process`): the ensembles (resumable; a seed the health
  rules stopped is not run again; a seed whose record exists and whose run file is gone is read
  from its record), the records with ``runs.json``, records made elsewhere taken over, the
  analysis in a fresh process of one BLAS thread;
* **the words of a report section** (:func:`fmt`, :func:`shift_text`, :func:`seeds_text`,
  :func:`stops_text`).

Users: :mod:`tiltpile.studies.solver` (the solver's choice) and
:mod:`tiltpile.studies.stiffness` (the DEM's stiffness).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tiltpile import config as cfgmod

REFERENCE = "reference"
#: a setting's runs as the manifest recorded them, kept in its records directory (the format is
#: named after the first study that wrote it; every study writes the same)
RUNS_FILE = "runs.json"
RUNS_FORMAT = "tiltpile-solver-study-runs/1"
#: below a study's FIGURES: the comparisons, one directory each
COMPARISONS = "same-piles"
INPUTS = "inputs.json"
#: a setting's name names directories: letters, digits and _ . = + - only
NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.=+-]*")


# ----------------------------------------------------------------------------------------------
# the plan, validated before anything runs


@dataclass(frozen=True)
class Planned:
    """A setting of a study (any object with ``name``, ``overrides``: a tuple of
    ``section.key=value``, empty for the committed setting, and ``axis``), its validated
    configuration and its seeds."""
    setting: Any
    config: cfgmod.Config
    seeds: tuple[int, ...] = ()


@dataclass(frozen=True)
class Plan:
    """A study's preset, its overrides of every setting (``base``), its runs (the committed
    setting's seeds 0 .. runs - 1) and its settings with their validated configurations and
    seeds, the committed one first."""
    preset: str
    base: tuple[str, ...]
    runs: int
    entries: tuple[Planned, ...]

    @property
    def seeds(self) -> list[int]:
        return list(range(self.runs))

    @property
    def reference(self) -> Planned:
        return self.entries[0]


def check_runs(runs) -> None:
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise cfgmod.ConfigError(f"--runs must be at least 1, got {runs!r}")


def check_preset(preset: str) -> None:
    if preset not in cfgmod.PRESETS:
        raise cfgmod.ConfigError(f"--preset {preset!r}: unknown; known presets: "
                                 f"{', '.join(cfgmod.PRESETS)}")


def configure(preset: str, base, settings, seeds_of=None) -> tuple[Planned, ...]:
    """The settings' entries of a plan: each configuration the preset with ``base`` and the
    setting's overrides (``config.load``), its seeds ``seeds_of(setting)`` (None: none);
    ConfigError (one line naming the setting, the key or the value) for a bad key or value, a
    setting named twice or one whose configuration is another's."""
    entries, names, hashes = [], set(), {}
    for s in settings:
        if s.name in names:
            raise cfgmod.ConfigError(f"--only: setting {s.name} named twice")
        names.add(s.name)
        try:
            cfg = cfgmod.load(preset, None, [*base, *s.overrides])
        except cfgmod.ConfigError as e:
            where = "--set" if not s.overrides else f"setting {s.name}"
            raise cfgmod.ConfigError(f"{where}: {e}") from None
        h = cfg.hash()
        if h in hashes:
            raise cfgmod.ConfigError(f"setting {s.name} is the configuration of {hashes[h]}: "
                                     "nothing to compare")
        hashes[h] = s.name
        entries.append(Planned(s, cfg, tuple(seeds_of(s)) if seeds_of else ()))
    return tuple(entries)


# ----------------------------------------------------------------------------------------------
# the runs as the manifest recorded them: done, stopped by the health rules, failed otherwise


def stop_rule(error: str | None) -> str | None:
    """The rule that stopped a run, from the error its manifest records: the health limit
    (``health.energy_stop``, ...), "runaway" (non-finite positions or grains out of the box),
    "not at rest" (a deposition or history leg that did not settle), "simulation stop" (another
    ``SimulationError``); None for a failure that is not a stop of the simulation (a crash, a
    full disk, a busy file: the run is retried)."""
    if not error or not str(error).startswith("SimulationError"):
        return None
    text = str(error)
    m = re.search(r"health\.\w+", text)
    if m:
        return m.group(0)
    if "non-finite" in text or "left the box" in text:
        return "runaway"
    if "not at rest" in text:
        return "not at rest"
    return "simulation stop"


def one_line(text, limit: int = 300) -> str | None:
    if text is None:
        return None
    t = " ".join(str(text).split())
    return t if len(t) <= limit else t[: limit - 3] + "..."


def runs_doc(manifest: dict | None, old: dict | None, config_hash: str) -> dict:
    """{format, config_hash, runs: {seed: {status, stop, error, seconds, sweeps, steps,
    capped_steps}}} of a setting: the manifest's runs (their last attempt), over ``old`` (the
    same document as written before, kept for seeds the manifest no longer lists, e.g. after its
    run files were moved away; dropped when of another configuration)."""
    runs = {}
    if old and old.get("config_hash") == config_hash:
        runs.update(old.get("runs") or {})
    for s, r in ((manifest or {}).get("runs") or {}).items():
        if r.get("status") == "pending":
            continue
        err = r.get("error") if r.get("status") == "failed" else None
        runs[str(int(s))] = {"status": r.get("status"), "stop": stop_rule(err),
                             "error": one_line(err),
                             **{k: r.get(k) for k in ("seconds", "sweeps", "steps", "capped_steps")}}
    return {"format": RUNS_FORMAT, "config_hash": config_hash,
            "runs": {k: runs[k] for k in sorted(runs, key=int)}}


def read_runs(rec_dir) -> dict | None:
    p = Path(rec_dir) / RUNS_FILE
    if not p.is_file():
        return None
    try:
        doc = json.loads(p.read_text())
    except ValueError:
        return None
    return doc if isinstance(doc, dict) and doc.get("format") == RUNS_FORMAT else None


def write_runs(rec_dir, manifest: dict | None, config_hash: str) -> dict:
    """Write ``rec_dir/runs.json`` (:func:`runs_doc` over the one there); returns it."""
    from tiltpile.figures import style

    old = read_runs(rec_dir)
    doc = runs_doc(manifest, old, config_hash)
    if doc != old:      # an unchanged file is left as it is (its time stamp too)
        Path(rec_dir).mkdir(parents=True, exist_ok=True)
        style.write_json(Path(rec_dir) / RUNS_FILE, doc)
    return doc


def health_stops(doc: dict | None, seeds) -> list[dict]:
    """[{seed, rule, message}] of the runs of ``seeds`` the health rules stopped."""
    runs = (doc or {}).get("runs") or {}
    out = []
    for s in seeds:
        r = runs.get(str(s))
        if r and r.get("status") == "failed" and r.get("stop"):
            out.append({"seed": int(s), "rule": r["stop"], "message": r.get("error")})
    return out


def failures(doc: dict | None, seeds) -> list[dict]:
    """[{seed, error}] of the runs of ``seeds`` that failed otherwise (retried next time)."""
    runs = (doc or {}).get("runs") or {}
    return [{"seed": int(s), "error": runs[str(s)].get("error")} for s in seeds
            if str(s) in runs and runs[str(s)].get("status") == "failed"
            and not runs[str(s)].get("stop")]


# ----------------------------------------------------------------------------------------------
# records, cost, inputs' digest


def recorded(rec_dir, seeds) -> list[int]:
    """The seeds of ``seeds`` whose record ``rec_dir/run_SSSS.npz`` exists."""
    d = Path(rec_dir)
    return [s for s in seeds if (d / f"run_{s:04d}.npz").is_file()]


def cost(rec_dir, seeds) -> dict:
    """What a run of the setting costs, from its records of ``seeds``
    (:func:`tiltpile.analysis.ensemble_data.ensemble_cost`): sweeps, steps (DEM steps in the
    DEM) and capped steps per run (means), seconds per run (median wall seconds of the runs
    timed whole) and ``core_hours_per_run`` (the same in hours: one run is one single-threaded
    process)."""
    from tiltpile.analysis.ensemble_data import ensemble_cost
    from tiltpile.record import read_meta

    costs = [dict(read_meta(Path(rec_dir) / f"run_{s:04d}.npz").get("cost") or {})
             for s in recorded(rec_dir, seeds)]
    c = ensemble_cost(costs) if costs else {"runs_timed": 0, "seconds_per_run": None,
                                            "steps_per_run": None, "sweeps_per_run": None,
                                            "capped_steps_per_run": None}
    sec = c.get("seconds_per_run")
    return {**c, "core_hours_per_run": None if sec is None else sec / 3600.0}


def code_digest(notebooks_dir="notebooks") -> str:
    """SHA-256 of the code a comparison's numbers come from: the figures' notebooks
    (``same_piles.FIGURES``), the figures and analysis packages' sources and tiltpile's
    version."""
    import tiltpile
    from tiltpile import analysis, figures
    from tiltpile.figures import same_piles as sp

    files = (sorted(Path(figures.__file__).parent.glob("*.py"))
             + sorted(Path(analysis.__file__).parent.rglob("*.py"))
             + [Path(notebooks_dir) / f"{stem}.ipynb" for stem in sp.FIGURES])
    h = hashlib.sha256(tiltpile.__version__.encode())
    for f in files:
        h.update(f"{f.parent.name}/{f.name}\0".encode())
        h.update(f.read_bytes() if f.is_file() else b"(missing)")
    return h.hexdigest()


def _records_digest(rec_dir, seeds) -> dict[str, str]:
    return {str(s): hashlib.sha256((Path(rec_dir) / f"run_{s:04d}.npz").read_bytes()).hexdigest()
            for s in seeds}


def fingerprint(code: str, sides: dict, seeds, null_flips: int) -> dict:
    """What a cached comparison was computed from: the code digest, the seeds, the flips of the
    null and, per side ({label: records directory}), the SHA-256 of each record used."""
    return {"code": code, "seeds": [int(s) for s in seeds], "null_flips": int(null_flips),
            "records": {label: _records_digest(d, seeds) for label, d in sides.items()}}


def load_side(rec_dir, preset: str, seeds):
    """The ensemble of the records ``rec_dir`` on ``seeds``, at the figures' analysis (2%
    cutoff, no lost gap)."""
    from tiltpile.figures import data
    from tiltpile.figures import same_piles as sp

    ens = data.load(rec_dir, preset, cutoff=0.02, lost_gap=None)
    return sp.subset(ens, seeds)


def read_kept(out: Path, fp: dict, labels) -> dict | None:
    """The comparison kept in ``out`` when its inputs' digest is ``fp``, with its documents."""
    from tiltpile.figures import same_piles as sp

    try:
        if json.loads((out / INPUTS).read_text()) != fp:
            return None
        doc = json.loads((out / f"{sp.NAME}.json").read_text())
        doc["documents"] = {lab: {stem: json.loads((out / lab / f"{stem}.json").read_text())
                                  for stem in sp.FIGURES} for lab in labels}
    except (OSError, ValueError):
        return None
    return doc


def compare(ref_dir, rec_dir, name: str, seeds, out_dir, preset: str, *, code: str,
            ref_label: str = REFERENCE, ref_preset: str | None = None, null_flips: int = 0,
            workers: int = 1, notebooks_dir="notebooks", progress=None) -> dict:
    """The same-piles study (:func:`tiltpile.figures.same_piles.study`) of the setting's records
    ``rec_dir`` (label ``name``) against ``ref_dir`` (label ``ref_label``: the committed
    setting's by default; described as of ``ref_preset``, default ``preset``) on ``seeds``,
    written to ``out_dir`` (:func:`tiltpile.figures.same_piles.write_study`) with its inputs'
    digest; the one kept there when the digest is the same. Returns it in JSON form (NaN as
    None), with ``documents``."""
    import tempfile

    from tiltpile.figures import same_piles as sp
    from tiltpile.figures import style

    out = Path(out_dir)
    fp = fingerprint(code, {ref_label: ref_dir, name: rec_dir}, seeds, null_flips)
    kept = read_kept(out, fp, (ref_label, name))
    if kept is not None:
        return kept
    ref, ens = load_side(ref_dir, ref_preset or preset, seeds), load_side(rec_dir, preset, seeds)
    with tempfile.TemporaryDirectory(prefix="tiltpile-study-") as scratch:
        doc = sp.study(ref, ens, ref_label, name, notebooks_dir=notebooks_dir, progress=progress,
                       null_flips=null_flips, scratch=scratch, workers=workers)
    (out / INPUTS).unlink(missing_ok=True)
    sp.write_study(doc, out)
    style.write_json(out / INPUTS, fp)
    return read_kept(out, fp, (ref_label, name))


def documents(rec_dir, seeds, out_dir, preset: str, *, code: str, label: str = REFERENCE,
              notebooks_dir="notebooks", progress=None) -> dict[str, dict]:
    """{stem: figure document} of one side (``label``, the committed setting by default) on
    ``seeds`` (its verdicts), kept in ``out_dir`` with its inputs' digest like a comparison."""
    from tiltpile.figures import same_piles as sp
    from tiltpile.figures import style

    out = Path(out_dir)
    fp = fingerprint(code, {label: rec_dir}, seeds, 0)
    try:
        if json.loads((out / INPUTS).read_text()) == fp:
            return {stem: json.loads((out / f"{stem}.json").read_text()) for stem in sp.FIGURES}
    except (OSError, ValueError):
        pass
    if progress:
        progress(f"{label}: the figures on its {len(seeds)} seeds")
    docs = sp.figure_documents(load_side(rec_dir, preset, seeds), sp.FIGURES, notebooks_dir)
    (out / INPUTS).unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    for stem, d in docs.items():
        style.write_json(out / f"{stem}.json", d)
    style.write_json(out / INPUTS, fp)
    return {stem: json.loads((out / f"{stem}.json").read_text()) for stem in sp.FIGURES}


def compare_settings(entries, records_root, comparisons_root, preset: str, *, code: str,
                     null_flips: int = 0, workers: int = 1, notebooks_dir="notebooks",
                     progress=None) -> tuple[list[int], dict, dict | None]:
    """Every setting of ``entries`` (the committed one first) with 2 or more seeds in common with
    the committed one and no health stop compared with it (:func:`compare`, kept in
    ``comparisons_root/<name>/``; chance's count with ``null_flips`` where the comparison has a
    jackknife). Returns (the committed setting's recorded seeds, {name: comparison or None},
    the committed setting's figure documents on its recorded seeds or None): those of a
    comparison on all of them, else :func:`documents` kept in ``comparisons_root/reference/``."""
    from tiltpile.figures import same_piles as sp

    records_root, comparisons_root = Path(records_root), Path(comparisons_root)
    ref = entries[0]
    ref_dir = records_root / REFERENCE
    ref_done = recorded(ref_dir, ref.seeds)
    comps: dict[str, dict | None] = {}
    for p in entries[1:]:
        name = p.setting.name
        rec = records_root / name
        runs = read_runs(rec)
        common = sorted(set(recorded(rec, p.seeds)) & set(ref_done))
        if health_stops(runs, p.seeds) or len(common) < sp.MIN_SEEDS:
            comps[name] = None
            continue
        say = None if progress is None else (lambda line, n=name: progress(f"{n}: {line}"))
        if progress:
            progress(f"{name} against {REFERENCE} on {len(common)} seeds")
        comps[name] = compare(ref_dir, rec, name, common, comparisons_root / name, preset,
                              code=code, null_flips=null_flips if len(common) >= sp.JACKKNIFE_SEEDS
                              else 0, workers=workers, notebooks_dir=notebooks_dir, progress=say)
    ref_docs = None
    if len(ref_done) >= 1:
        full = next((c for c in comps.values() if c is not None and c["seeds"] == ref_done), None)
        ref_docs = (full["documents"][REFERENCE] if full is not None else
                    documents(ref_dir, ref_done, comparisons_root / REFERENCE, preset, code=code,
                              notebooks_dir=notebooks_dir, progress=progress))
    return ref_done, comps, ref_docs


# ----------------------------------------------------------------------------------------------
# claims


def verdicts(docs: dict[str, dict]) -> dict[str, dict]:
    """{claim key: {verdict, ours}} of every claim of the report on the figure documents
    ``docs`` ({stem: document}), as the report judges them."""
    from tiltpile.report.claims import CLAIMS
    from tiltpile.report.document import judgements

    return {c.key: {"verdict": j.verdict, "ours": j.ours} for c, j, _src in judgements(docs, CLAIMS)}


def flipped(ref: dict, other: dict) -> list[str]:
    """The claims whose verdict differs between two :func:`verdicts` (neither "not measured")."""
    from tiltpile.report.judging import MISSING

    return [k for k, r in ref.items() if k in other and MISSING not in (r["verdict"], other[k]["verdict"])
            and r["verdict"] != other[k]["verdict"]]


# ----------------------------------------------------------------------------------------------
# a setting's entry


def num(x) -> float:
    return math.nan if x is None else float(x)


def shift(pp: dict, key: str) -> dict:
    """The mean paired difference of a per-seed number, its interval, seeds, and the reference
    side's mean, from a pile-against-pile document; ``relative``: the shift over that mean."""
    d = pp["difference"][key]
    ref = [x for x in map(num, pp["per_seed"][key]["ref"]) if math.isfinite(x)]
    ref_mean = sum(ref) / len(ref) if ref else math.nan
    m = num(d.get("mean"))
    rel = m / ref_mean if math.isfinite(m) and math.isfinite(ref_mean) and ref_mean else math.nan
    return {"mean": m, "ci_low": num(d.get("ci_low")), "ci_high": num(d.get("ci_high")),
            "n": d.get("n"), "ref_mean": ref_mean, "relative": rel}


def setting_entry(head: dict, p: Planned, runs: dict | None, rec_dir, seeds, ref_done,
                  comparison: dict | None, ref_verdicts: dict | None) -> dict:
    """One setting's entry of a study: ``head`` (what the study says of the setting: name,
    override, ...), then status (done, partial, pending, failed), seeds done and compared, health
    stops and other failures, cost, the comparison's counts, the pile-against-pile shifts
    (``n_m_shift``: <n_m> of the quiet frames), the claims' verdicts beside the committed
    setting's on the same seeds and the claims flipped."""
    from tiltpile.figures import same_piles as sp

    s = p.setting
    done = recorded(rec_dir, seeds)
    stops = health_stops(runs, seeds)
    status = ("failed" if stops else "done" if len(done) == len(seeds)
              else "partial" if len(set(done) & set(ref_done)) >= sp.MIN_SEEDS else "pending")
    out = {**head, "status": status, "seeds_planned": len(seeds), "seeds_done": done,
           "health_stops": stops, "failures": failures(runs, seeds), "cost": cost(rec_dir, seeds),
           "seeds_compared": [], "comparison": None, "pile_against_pile": None, "n_m_shift": None,
           "verdicts": None, "flipped": None}
    if comparison is not None:
        docs = comparison["documents"]
        mine, theirs = verdicts(docs[s.name]), verdicts(docs[REFERENCE])
        pp = comparison["pile_against_pile"]
        out.update(
            seeds_compared=comparison["seeds"],
            comparison={k: comparison[k] for k in ("n_numbers", "n_with_error", "n_moved",
                                                   "sigma_limit")}
            | {"moved": [f"{m['figure']}.{m['key']}" for m in comparison["moved"]],
               "null": (None if not comparison.get("null") else
                        {k: comparison["null"][k] for k in ("flips", "median", "p95", "p_value",
                                                            "observed")})},
            pile_against_pile={k: shift(pp, k) for k in pp["difference"]},
            n_m_shift=shift(pp, "n_m_quiet"),
            verdicts={k: {"reference": theirs[k]["verdict"], "setting": mine[k]["verdict"],
                          "ours_reference": theirs[k]["ours"], "ours": mine[k]["ours"]}
                      for k in theirs},
            flipped=flipped(theirs, mine))
    elif s.name == REFERENCE and ref_verdicts is not None:
        out["verdicts"] = {k: {"reference": v["verdict"], "setting": v["verdict"],
                               "ours_reference": v["ours"], "ours": v["ours"]}
                           for k, v in ref_verdicts.items()}
        out["seeds_compared"] = list(done)
        out["flipped"] = []
    return out


# ----------------------------------------------------------------------------------------------
# the stages a study's command runs


def stopped_seeds(d: Path, rec: Path, seeds, config_hash: str) -> dict[int, str]:
    """{seed: rule} of the seeds the health rules stopped, from the manifest in ``d`` or the
    ``runs.json`` in ``rec``."""
    from tiltpile.ensemble import read_manifest

    m = read_manifest(d) if Path(d).is_dir() else None
    doc = runs_doc(m if m and m.get("config_hash") == config_hash else None, read_runs(rec),
                   config_hash)
    return {h["seed"]: h["rule"] for h in health_stops(doc, seeds)}


def run_ensembles(entries, data_root, records_root, *, workers=None, progress=True,
                  say=print) -> list[str]:
    """Each setting's ensemble into ``data_root/<name>/`` (``ensemble.run_ensemble``: finished
    runs skipped, interrupted ones resumed), in the plan's order, on the setting's seeds but those
    the health rules stopped (they would stop at the same place) and those recorded in
    ``records_root/<name>/`` whose run file is gone. ``say``: one line per event. Returns the
    names of the settings whose runs failed otherwise than by a health stop (retried next
    time); a setting another process is running (``OutputBusy``) is skipped with one line."""
    from tiltpile.ensemble import failed_runs, run_ensemble, run_file
    from tiltpile.outputs import OutputBusy

    crashed = []
    for p in entries:
        name, cfg, seeds = p.setting.name, p.config, list(p.seeds)
        d, rec = Path(data_root) / name, Path(records_root) / name
        on_record = set(recorded(rec, seeds))
        stopped = stopped_seeds(d, rec, seeds, cfg.hash())
        todo = [s for s in seeds if s not in stopped
                and (run_file(d, s).exists() or s not in on_record)]
        for s, rule in sorted(stopped.items()):
            say(f"{name}: seed {s} was stopped by {rule} (recorded; not run again)")
        gone = sorted(s for s in on_record if not run_file(d, s).exists())
        if gone:
            say(f"{name}: seeds {gone} from their records (no run files)")
        if not todo:
            continue
        new = [s for s in todo if not run_file(d, s).exists()]
        if new:
            say(f"{name}: ensemble {d} ({len(new)} of {len(seeds)} runs to compute or resume)")
        try:
            man = run_ensemble(cfg, todo, d, workers=workers, progress=progress)
        except OutputBusy as e:
            say(f"{name}: skipped: {' '.join(str(e).split())}")
            continue
        failed = [s for s in failed_runs(man) if s in todo]
        doc = runs_doc(man, None, cfg.hash())
        stops = {h["seed"]: h["rule"] for h in health_stops(doc, failed)}
        for s in failed:
            if s in stops:
                say(f"{name}: seed {s} stopped by {stops[s]}: the setting is failed (recorded)")
            else:
                crashed.append(name)
                say(f"{name}: seed {s} failed: {doc['runs'][str(s)]['error']}")
    return sorted(set(crashed))


def write_setting_records(entries, data_root, records_root, *, workers=None, say=print) -> list[str]:
    """The records of every finished run of each setting (``figures.records.write_records``) in
    ``records_root/<name>/`` with its ``runs.json``; returns the settings holding records."""
    from tiltpile.ensemble import read_manifest
    from tiltpile.figures.records import write_records

    held = []
    for p in entries:
        name = p.setting.name
        d, rec = Path(data_root) / name, Path(records_root) / name
        m = read_manifest(d) if d.is_dir() else None
        if any(d.glob("run_*.h5")):
            table = write_records(d, rec, workers=workers, progress=False)
            written = int((table["status"] == "written").sum())
            if written:
                say(f"{name}: {written} records written in {rec}")
        if m is not None and m.get("config_hash") == p.config.hash():
            write_runs(rec, m, p.config.hash())
        if recorded(rec, p.seeds) or (rec / RUNS_FILE).is_file():
            held.append(name)
    return held


def seed_records(src, dst, seeds) -> list[int]:
    """Copy the records of ``seeds`` that ``dst`` lacks from ``src`` (records of the same
    configuration made elsewhere, checked by the caller), so that a study holds every record it
    uses and does not run those seeds again; returns the seeds copied. A copy of a committed
    file is the same blob to git."""
    import shutil

    from tiltpile.outputs import replaced_whole

    have = set(recorded(dst, seeds))
    copied = []
    for s in recorded(src, seeds):
        if s in have:
            continue
        Path(dst).mkdir(parents=True, exist_ok=True)
        target = Path(dst) / f"run_{s:04d}.npz"
        with replaced_whole(target) as tmp:
            shutil.copyfile(Path(src) / target.name, tmp)
        copied.append(s)
    return copied


def in_fresh_process(fn, *args, workers: int = 1, **kw):
    """``fn(*args, workers=workers, **kw)``; with one worker in a fresh process of one BLAS
    thread (``same_piles.worker_pool``), as the figures are evaluated with several: Fig. 5's
    fits run 7x faster there than under a multi-threaded OpenBLAS on a busy machine (measured on
    the tiny test piles), and give the same numbers."""
    from tiltpile.figures import same_piles as sp

    if workers > 1:       # the figures are evaluated in single-threaded workers already
        return fn(*args, workers=workers, **kw)
    with sp.worker_pool(1) as pool:
        return pool.submit(fn, *args, workers=workers, **kw).result()


# ----------------------------------------------------------------------------------------------
# the words of a report section


def write_outputs(name: str, plot, render, numbers: dict, meta: dict, figures_dir) -> dict[str, Path]:
    """``figures_dir/<name>.{png,pdf,json}`` of a study's figure (``plot(numbers)``, saved by
    :func:`tiltpile.figures.style.save`: the JSON is {figure, **meta, numbers}) and
    ``<name>.md``, its report section (``render`` of that JSON); each written whole or not at all."""
    import matplotlib.pyplot as plt

    from tiltpile.figures import style
    from tiltpile.outputs import replaced_whole

    style.use()
    fig = plot(numbers)
    try:
        paths = style.save(fig, name, numbers, figures_dir, meta)
    finally:
        plt.close(fig)
    md = Path(figures_dir) / f"{name}.md"
    with replaced_whole(md) as tmp:
        tmp.write_text(render(json.loads(paths["json"].read_text())))
    paths["md"] = md
    return paths


def fmt(x, spec: str) -> str:
    v = num(x)
    return "n/a" if not math.isfinite(v) else format(v, spec)


def shift_text(sh: dict | None) -> str:
    """'+0.0123 [+0.0100, +0.0150] (+1.2%)' of a :func:`shift`; "n/a" without one."""
    if not sh or not math.isfinite(num(sh.get("mean"))):
        return "n/a"
    band = (f" [{fmt(sh['ci_low'], '+.4f')}, {fmt(sh['ci_high'], '+.4f')}]"
            if math.isfinite(num(sh.get("ci_low"))) and math.isfinite(num(sh.get("ci_high"))) else "")
    rel = f" ({fmt(100 * num(sh['relative']), '+.1f')}%)" if math.isfinite(num(sh.get("relative"))) else ""
    return f"{fmt(sh['mean'], '+.4f')}{band}{rel}"


def seeds_text(seeds) -> str:
    s = sorted(int(x) for x in seeds)
    if not s:
        return "none"
    return f"{s[0]}-{s[-1]}" if s == list(range(s[0], s[-1] + 1)) and len(s) > 2 else ", ".join(map(str, s))


def stops_text(stops: list[dict]) -> list[str]:
    """'seeds 0, 2: health.energy_stop' per rule of a setting's health stops."""
    rules: dict[str, list[int]] = {}
    for h in stops:
        rules.setdefault(h["rule"], []).append(h["seed"])
    return [f"seed{'s' if len(v) > 1 else ''} {', '.join(map(str, v))}: {r}" for r, v in rules.items()]
