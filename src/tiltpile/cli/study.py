"""``tiltpile study --key SECTION.KEY --values V [V ...] --preset P --runs M``: a parameter study.

For each value: the ensemble of the preset with the key set (``tiltpile ensemble``: finished runs
skipped, interrupted ones resumed), its repose angles (``tiltpile repose``, redone when a run file
is newer than ``repose.json``), its observables and records (``tiltpile record``); then the
study's numbers, figure and JSON (:mod:`tiltpile.figures.study`) and its report section
(:func:`tiltpile.report.studies.render_study`). With ``--history repose+D`` each value first gets
an ensemble of fresh piles and their repose angle r, then the study's piles cycled twice to
r + D deg (rounded to the whole degree).

Layout: DATA/<value>/ (the study's runs; DATA/<value>-fresh/ the fresh piles of ``repose+D``),
FIGURES/study.{png,pdf,json}, FIGURES/study.md, FIGURES/records/<value>/ (each run's record and
the repose angles, ``repose.json``, without their per-frame traces). A value whose run files are
gone is read from its records. ``--records-only`` runs nothing and writes the records of the values
whose runs and repose angles are done (``make study ... RECORDS_ONLY=1``), so that a study spread
over sessions keeps what it has computed.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shlex
import sys
from pathlib import Path

from tiltpile import config as cfgmod
from tiltpile.cli._common import ConfigError

NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
HISTORY_KEYS = ("protocol.cycles", "protocol.theta_rev_deg", "protocol.pretilt_deg")


def add_parser(sub) -> None:
    p = sub.add_parser("study", help="a parameter study: one ensemble per value of a key, its "
                                     "figures' numbers, one figure, JSON and report section",
                       description="For each value of a configuration key: the ensemble of "
                                   "the preset with it, its repose angles, observables and "
                                   "records; then every figure's numbers per value with "
                                   "bootstrap intervals over runs, one figure, its JSON and a "
                                   "report section (make study; docs/cli.md).")
    p.add_argument("--key", required=True, metavar="SECTION.KEY",
                   help="the configuration key varied, e.g. scene.mu")
    p.add_argument("--values", required=True, nargs="+", metavar="V",
                   help="its values (TOML syntax, as --set), at least two, e.g. 0.2 0.5 1.0")
    p.add_argument("--preset", required=True, choices=cfgmod.ALL_PRESET_NAMES,
                   help="the configuration every value starts from")
    p.add_argument("--runs", type=int, required=True, metavar="M",
                   help="runs (seeds 0..M-1) per value")
    p.add_argument("--name", required=True, metavar="NAME",
                   help="the study's name (letters, digits, _ . -): DATA and FIGURES default to "
                        "data/study-NAME and figures/study-NAME")
    p.add_argument("--data", type=Path, metavar="DIR", help="where the runs go (DIR/<value>/)")
    p.add_argument("--figures", type=Path, metavar="DIR",
                   help="where the figure, JSON, report section and records go")
    p.add_argument("--history", default="preset", metavar="preset|repose+D",
                   help="the piles' history: the preset's own (default), or repose+D: two cycles "
                        "to each value's fresh repose angle + D deg")
    p.add_argument("--workers", type=int, metavar="W",
                   help="processes for the runs, repose angles and observables (default: one per core)")
    p.add_argument("--runs-only", action="store_true",
                   help="only the ensembles and repose angles (make study runs the analysis "
                        "after them in its own environment)")
    p.add_argument("--records-only", action="store_true",
                   help="run nothing: write the records of the values whose runs and repose "
                        "angles are all done, so they can be committed before the rest is (a "
                        "study spread over sessions); the others are named and left")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run, interrupted="interrupted; finished runs are kept and unfinished ones "
                                         "resume next time")


# ----------------------------------------------------------------------------------------------
# the plan, validated before anything runs


def _value_configs(args, offset):
    """[(label, value, override text, fresh Config or None, study Config or None)]: every value
    validated (ConfigError naming the key or the value); the study's Config is None under
    repose+D until the repose angle is known (validated with a placeholder amplitude)."""
    from tiltpile.figures.study import history_overrides, value_label

    key = args.key
    if key.count(".") != 1 or not all(key.split(".")):
        raise ConfigError(f"--key {key!r}: give section.key, e.g. scene.mu")
    section, name = key.split(".")
    if section not in cfgmod.SECTIONS:
        raise ConfigError(f"--key {key}: unknown section {section!r}; known sections: "
                          f"{', '.join(cfgmod.SECTIONS)}")
    known = {f.name: f for f in dataclasses.fields(cfgmod.SECTIONS[section])}
    shorthand = section == "protocol" and name in cfgmod.HISTORY_SHORTHAND
    if name not in known and not shorthand:
        raise ConfigError(f"--key {key}: unknown key; known keys of {section}: "
                          f"{', '.join(sorted(known))}")
    if not shorthand and known[name].type in (tuple, "tuple"):
        raise ConfigError(f"--key {key}: a list-valued key; a study varies one number, word or "
                          "switch")
    if offset is not None and key in HISTORY_KEYS + ("protocol.pretilt_per_step_deg",):
        raise ConfigError(f"--key {key}: --history {args.history} sets the history itself")
    plans, seen = [], {}
    for text in args.values:
        kv = f"{key}={text}"
        try:
            base = cfgmod.load(args.preset, None, [kv])
            if shorthand:   # protocol.cycles / theta_rev_deg: written into pretilt_deg
                given = cfgmod.parse_override(kv)["protocol"][name]
                value = int(given) if name == "cycles" else float(given)
            else:
                value = getattr(getattr(base, section), name)
            if offset is None:
                fresh, study = None, base
            else:
                fresh = cfgmod.load(args.preset, None, [kv, *history_overrides(None)])
                cfgmod.load(args.preset, None, [kv, *history_overrides(16.0)])
                study = None
        except ConfigError as e:
            raise ConfigError(f"--values {text}: {e}") from None
        label = value_label(value)
        if label in seen:
            raise ConfigError(f"--values: {text} and {seen[label]} are the same value ({label})")
        seen[label] = text
        plans.append([label, value, kv, fresh, study])
    if len(plans) < 2:
        raise ConfigError(f"--values: give at least two values of {key} (got {len(plans)})")
    return plans


def _check_dir(d: Path, cfg) -> None:
    """Refuse an existing ensemble directory made with another configuration (one line)."""
    from tiltpile.ensemble import read_manifest

    m = read_manifest(d) if d.is_dir() else None
    if m is not None and cfg is not None and m.get("config_hash") != cfg.hash():
        raise ConfigError(f"{d} holds an ensemble of another configuration (hash "
                          f"{str(m.get('config_hash'))[:12]}, this value's {cfg.hash()[:12]}): "
                          "give another --name or --data")


def _check_records(rec: Path, args, kv: str, cfg) -> None:
    """Refuse records of another configuration than the value's (one line): ``cfg``, or under
    repose+D (``cfg`` None) the study's configuration at the amplitude the records' runs had."""
    from tiltpile.figures.records import foreign_records
    from tiltpile.record import RecordError, read_meta, record_files

    files = record_files(rec) if rec.is_dir() else []
    if not files:
        return
    if cfg is None:
        try:
            legs = read_meta(files[0])["config"].get("protocol", {}).get("pretilt_deg") or [0.0]
        except RecordError:
            return
        amp = max(abs(float(a)) for a in legs)
        cfg = _study_config(args, kv, amp) if amp > 0 else None
    odd = foreign_records(rec, cfg.hash()) if cfg is not None else files
    if odd:
        raise ConfigError(f"{rec}: {odd[0].name} is a record of another configuration than this "
                          "value's: give another --name or --figures")


def _amplitude(rep_path: Path, offset: float) -> float | None:
    from tiltpile.figures.study import history_amplitude, read_repose, repose_surface_mean

    rep = read_repose(rep_path)
    if rep is None:
        return None
    try:
        return history_amplitude(repose_surface_mean(rep), offset)
    except ValueError as e:
        raise ConfigError(f"{rep_path}: {e}") from None


def _validate(args):
    from tiltpile.figures.study import parse_history
    from tiltpile.paths import check_output

    if args.runs < 1:
        raise ConfigError(f"--runs must be at least 1, got {args.runs}")
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    if not NAME_RE.fullmatch(args.name):
        raise ConfigError(f"--name {args.name!r}: letters, digits, _ . - only")
    try:
        offset = parse_history(args.history)
    except ValueError as e:
        raise ConfigError(f"--history: {e}") from None
    plans = _value_configs(args, offset)
    data = args.data or Path("data") / f"study-{args.name}"
    figures = args.figures or Path("figures") / f"study-{args.name}"
    check_output(data, "--data", directory=True)
    check_output(figures, "--figures", directory=True)
    for label, value, kv, fresh, study in plans:
        _check_records(figures / "records" / label, args, kv, study if offset is None else None)
        if offset is None:
            _check_dir(data / label, study)
        else:
            _check_dir(data / f"{label}-fresh", fresh)
            amp = _amplitude(data / f"{label}-fresh" / "repose.json", offset)
            if amp is not None:
                _check_dir(data / label, _study_config(args, kv, amp))
    return offset, plans, data, figures


def _study_config(args, kv: str, amplitude: float):
    from tiltpile.figures.study import history_overrides

    return cfgmod.load(args.preset, None, [kv, *history_overrides(amplitude)])


# ----------------------------------------------------------------------------------------------
# the steps


def _ensemble(cfg, runs: int, out: Path, args) -> None:
    from tiltpile.ensemble import failed_runs, run_ensemble

    print(f"tiltpile study: ensemble {out} ({runs} runs)", file=sys.stderr, flush=True)
    man = run_ensemble(cfg, range(runs), out, workers=args.workers, progress=not args.quiet)
    failed = failed_runs(man)
    if failed:
        raise RuntimeError(f"{out}: runs {failed} failed (see {out}/ensemble.json); rerun to retry")


def _repose(d: Path, args) -> Path:
    """DIR/repose.json, measured unless it is newer than every run file and covers their seeds."""
    import tiltpile
    from tiltpile.cli.repose import FORMAT
    from tiltpile.repose import MIN_DEG, repose_many, summarize, write_json

    out = d / "repose.json"
    files = sorted(d.glob("run_*.h5"))
    if out.exists() and all(f.stat().st_mtime <= out.stat().st_mtime for f in files):
        runs = json.loads(out.read_text())["runs"]
        if sorted(Path(r["run"]).name for r in runs) == [f.name for f in files]:
            return out
    print(f"tiltpile study: repose angles of {d}", file=sys.stderr, flush=True)
    workers = args.workers or min(len(files), os.cpu_count() or 1)
    results = repose_many(files, workers=workers, progress=not args.quiet)
    failed = [r for r in results if r.outcome == "failed"]
    if failed:
        raise RuntimeError(f"repose of {failed[0].run} failed: {failed[0].error}")
    params = {**results[0].params, "min_deg": MIN_DEG}
    write_json(out, {"format": FORMAT, "tiltpile_version": tiltpile.__version__, "path": str(d),
                     "params": params, "summary": summarize(results),
                     "runs": [r.to_dict() for r in results]})
    return out


def _records(d: Path, rec: Path, repose: Path, args) -> None:
    """RECORDS/<value>/: the run files' records and repose.json without its per-frame traces."""
    from tiltpile.figures.records import write_records
    from tiltpile.repose import write_json

    write_records(d, rec, workers=args.workers, progress=False)
    doc = json.loads(repose.read_text())
    keep = {"theta_deg", "ke", "direction", "sweeps_per_frame"}
    doc["runs"] = [{k: v for k, v in r.items() if k not in keep} for r in doc["runs"]]
    write_json(rec / "repose.json", doc)


def run(args) -> int:
    """Validate everything, then run the ensembles and repose angles, then (unless --runs-only)
    the observables, records, numbers, figure, JSON and report section. Exit status 1, one
    line, when a run or a repose measurement fails."""
    offset, plans, data, figures = _validate(args)
    if args.records_only and args.runs_only:
        raise ConfigError("--records-only and --runs-only: give one of them")
    try:
        if args.records_only:
            return _records_of_done_values(args, offset, plans, data, figures)
        return _run(args, offset, plans, data, figures)
    except RuntimeError as e:
        print(f"tiltpile study: error: {' '.join(str(e).split())}", file=sys.stderr)
        return 1


def _done(d: Path, runs: int) -> bool:
    """Every run of seeds 0 .. runs - 1 finished in ``d`` (its run file there)."""
    return all((d / f"run_{s:04d}.h5").is_file() for s in range(runs))


def _records_of_done_values(args, offset, plans, data, figures) -> int:
    """--records-only: for each value whose study runs and repose angles are done, its
    observables and records (``_records``); the others named. Nothing is simulated."""
    from tiltpile.analysis.observables import compute_observables

    records, done = figures / "records", []
    for label, value, kv, fresh, study in plans:
        d = data / label
        rep = d / "repose.json" if offset is None else data / f"{label}-fresh" / "repose.json"
        if _from_records(d, records / label):
            print(f"tiltpile study: {args.key} = {label}: records only, nothing to write",
                  file=sys.stderr, flush=True)
        elif not (_done(d, args.runs) and rep.is_file()):
            print(f"tiltpile study: {args.key} = {label}: not done yet (runs or repose angles)",
                  file=sys.stderr, flush=True)
        else:
            compute_observables(d, workers=args.workers, progress=False)
            _records(d, records / label, rep, args)
            done.append(label)
    print(f"wrote the records of {', '.join(done) if done else 'no value'} in {records}")
    return 0


def _from_records(d: Path, rec: Path) -> bool:
    """A value whose run files are gone and whose records are there is read from the records."""
    return not any(d.glob("run_*.h5")) and any(rec.glob("run_*.npz"))


def _run(args, offset, plans, data, figures) -> int:
    records = figures / "records"
    steps = []
    for label, value, kv, fresh, study in plans:
        if _from_records(data / label, records / label):
            print(f"tiltpile study: {args.key} = {label} from its records in {records / label} "
                  "(no run files)", file=sys.stderr, flush=True)
            steps.append((label, value, records / label, records / label / "repose.json", None))
        elif offset is None:
            _ensemble(study, args.runs, data / label, args)
            steps.append((label, value, data / label, _repose(data / label, args), None))
        else:
            fd = data / f"{label}-fresh"
            _ensemble(fresh, args.runs, fd, args)
            rep = _repose(fd, args)
            amp = _amplitude(rep, offset)
            print(f"tiltpile study: {args.key} = {label}: fresh repose angle -> theta_rev = "
                  f"{amp:g} deg", file=sys.stderr, flush=True)
            _ensemble(_study_config(args, kv, amp), args.runs, data / label, args)
            steps.append((label, value, data / label, rep, amp))
    if args.runs_only:
        return 0
    from tiltpile.analysis.observables import compute_observables
    from tiltpile.figures import study as st
    from tiltpile.figures.data import load
    from tiltpile.outputs import replaced_whole
    from tiltpile.report.studies import render_study

    entries, ensembles = [], []
    for label, value, d, rep, amp in steps:
        if d != records / label:
            compute_observables(d, workers=args.workers, progress=False)
            _records(d, records / label, rep, args)
        ens = load(d, args.preset)
        if offset is not None and amp is None:   # from records: the amplitude their runs had
            amp = max(abs(float(a)) for a in ens.config["protocol"]["pretilt_deg"])
        ensembles.append(dict(ens.meta, data_dir=str(d), label=label, theta_rev_deg=amp,
                              repose=str(rep)))
        entries.append({"value": value, "label": label, "ens": ens, "repose": st.read_repose(rep),
                        "repose_piles": "study" if offset is None else "fresh",
                        "theta_rev_deg": amp})
    numbers = st.compute(args.key, entries)
    command = " ".join(["tiltpile study", "--key", args.key, "--values",
                        *map(shlex.quote, args.values), "--preset", args.preset,
                        "--runs", str(args.runs), "--name", args.name]
                       + (["--history", args.history] if offset is not None else []))
    meta = {"study": {"name": args.name, "key": args.key, "preset": args.preset,
                      "runs": args.runs, "history": "preset" if offset is None else args.history,
                      "history_offset_deg": offset,
                      "amplitude_rule": (None if offset is None else
                                         "theta_rev = fresh repose angle (surface, mean over runs "
                                         f"that stopped) + {offset:g} deg, rounded to the nearest "
                                         f"whole degree; {st.CYCLES} full cycles"),
                      "command": command},
            "ensembles": ensembles}
    paths = st.write(numbers, meta, figures)
    doc = json.loads(paths["json"].read_text())
    md = figures / "study.md"
    with replaced_whole(md) as tmp:
        tmp.write_text("\n".join(render_study(doc)).lstrip("\n") + "\n")
    for label in numbers["labels"]:
        c = numbers["per_value"][label]["numbers"]
        print(f"{args.key} = {label}: first onset {c['theta_first_onset']['estimate']:.2f} deg, "
              f"orientation {c['orientation']['estimate']:.1f} deg, <z> "
              f"{c['z_quiet']['estimate']:.3f}")
    print(f"wrote {paths['json']}, {paths['png']}, {paths['pdf']} and {md}")
    return 0
