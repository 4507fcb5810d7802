"""``tiltpile solver-study [--data DIR] [--figures DIR] [--runs 6] [--workers W] [--only S,...]``: the
solver's choice (issue 72; :mod:`tiltpile.studies.solver`).

For each setting of the study (``studies.solver.SETTINGS``, or those of ``--only``; the
committed setting, ``reference``, always): its ensemble (``tiltpile ensemble``'s code: finished
runs skipped, interrupted ones resumed), into DATA/<setting>/ -- the layout of the session's
driver, whose runs are reused; then each setting's records (``tiltpile record``) into
FIGURES/records/<setting>/ with ``runs.json`` (its runs as the manifest recorded them: the health
stops survive the run files); then every setting compared with the committed one (same piles,
claim by claim; each comparison kept in FIGURES/same-piles/<setting>/ and reused while its inputs
are the same), and FIGURES/solver_study.{json,png,pdf,md}.

A seed whose record exists and whose run file is gone is not run again (the setting is read from
its records); a seed the health rules stopped is not run again either (it would stop at the same
place: the run resumes bit for bit) and makes its setting *failed*, which the study records: a
health stop is not a crash (exit status 0). A setting whose directory another process is running
(``OutputBusy``) is skipped with one line. Everything is validated before anything runs: an
unknown setting, key or preset, a value out of range, a directory or records of another
configuration are refused in one line (exit status 2).

``--runs-only`` runs the ensembles only; ``--records-only`` runs nothing and writes the records of
every finished run (so that a study spread over sessions commits what it has); ``--no-runs`` runs
nothing and makes the study of what is finished (while another process runs the rest).
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from tiltpile import config as cfgmod
from tiltpile.cli._common import ConfigError

DEFAULT_DATA = Path("data") / "solver-study"
DEFAULT_FIGURES = Path("figures") / "solver-study"
INTERRUPTED = ("interrupted; finished runs are kept, unfinished ones resume and kept comparisons "
               "are reused next time")


def add_parser(sub) -> None:
    p = sub.add_parser("solver-study", help="the solver's choice: one ensemble per NLGS setting, "
                                            "each against the committed one pile by pile and claim "
                                            "by claim; the cost-against-change chart",
                       description="Run (resumably) the ensemble of every setting of the solver "
                                   "study, write their records, compare each with the committed "
                                   "setting on the same piles and write the chart, its JSON and "
                                   "the report section (issue 72; docs/cli.md).")
    p.add_argument("--data", type=Path, default=DEFAULT_DATA, metavar="DIR",
                   help=f"where the runs go: DIR/<setting>/, the committed setting's DIR/reference/ "
                        f"(default {DEFAULT_DATA})")
    p.add_argument("--figures", type=Path, default=DEFAULT_FIGURES, metavar="DIR",
                   help=f"where the chart, JSON, report section, records and comparisons go "
                        f"(default {DEFAULT_FIGURES})")
    p.add_argument("--runs", type=int, default=6, metavar="M", help="runs (seeds 0..M-1) per setting "
                                                                     "(default 6)")
    p.add_argument("--workers", type=int, metavar="W",
                   help="processes for the runs, observables and records (default: one per core), "
                        "and for the figures' evaluation (default 1)")
    p.add_argument("--only", metavar="S,...",
                   help="these settings only (comma-separated names of the study's settings, or "
                        "overrides solver.key=value), with the committed one")
    p.add_argument("--preset", default="default", choices=cfgmod.PRESETS, metavar="P",
                   help=f"the configuration every setting starts from (default: default; one of "
                        f"{', '.join(cfgmod.PRESETS)})")
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="SECTION.KEY=VALUE",
                   help="override of every setting, the committed one included (repeatable)")
    p.add_argument("--null", type=int, default=0, metavar="K",
                   help="also count the figure numbers chance moves: K exchanges of each seed's two "
                        "runs per setting (tiltpile same-piles --null; default 0: none)")
    p.add_argument("--reference-records", type=Path, metavar="DIR",
                   help="the committed setting's records made elsewhere (e.g. "
                        "figures/paper-5x/records with --preset paper-5x), taken into "
                        "FIGURES/records/reference/: its seeds are not run again")
    add_stage_options(p)
    p.set_defaults(func=run, interrupted=INTERRUPTED)


def add_stage_options(p) -> None:
    """The options of a settings study's stages (solver-study, stiffness-study)."""
    p.add_argument("--runs-only", action="store_true", help="only the ensembles")
    p.add_argument("--no-runs", action="store_true",
                   help="run no ensemble: the records and the study of the runs finished so far "
                        "(while another process runs the rest; incomplete settings preliminary)")
    p.add_argument("--records-only", action="store_true",
                   help="run nothing: write the records of every finished run (and each setting's "
                        "runs.json), to commit them while the rest runs")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


# ----------------------------------------------------------------------------------------------
# validation


def only(text: str | None) -> list[str] | None:
    """--only S1,S2,... as a list (None without it); an empty name refused in one line."""
    if text is None:
        return None
    names = [t.strip() for t in text.split(",")]
    if not all(names):
        raise ConfigError(f"--only {text!r}: an empty name; give S1,S2,... without blanks")
    return names


def check_options(args) -> None:
    """The options every settings study shares (--workers, --null, one of --runs-only,
    --records-only, --no-runs), refused in one line."""
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    if args.null < 0:
        raise ConfigError(f"--null must be 0 or more, got {args.null}")
    given = [o for o, v in (("--runs-only", args.runs_only), ("--records-only", args.records_only),
                            ("--no-runs", args.no_runs)) if v]
    if len(given) > 1:
        raise ConfigError(f"{' and '.join(given)}: give one of them")


def check_study(args, the_plan, override_of) -> None:
    """What every settings study checks of its plan before anything runs, each in one line: the
    null needs a jackknife, --data and --figures, the notebooks when it analyses, every
    setting's ensemble directory and records (``override_of(planned)``: the override its
    records were written with, for :func:`tiltpile.cli.study._check_records`)."""
    from tiltpile.cli.ensemble import recorded_seeds
    from tiltpile.cli.study import _check_dir, _check_records
    from tiltpile.figures import same_piles as sp
    from tiltpile.paths import check_output

    if args.null and args.runs < sp.JACKKNIFE_SEEDS:
        raise ConfigError(f"--null {args.null}: on {args.runs} runs no figure number has an error "
                          f"to move by; chance's count needs --runs {sp.JACKKNIFE_SEEDS} or more")
    check_output(args.data, "--data", directory=True)
    check_output(args.figures, "--figures", directory=True)
    if args.data.resolve() == args.figures.resolve():
        raise ConfigError("--data and --figures are the same directory")
    if not (args.runs_only or args.records_only):
        missing = [s for s in sp.FIGURES if not (Path("notebooks") / f"{s}.ipynb").is_file()]
        if missing:
            raise ConfigError(f"notebooks/{missing[0]}.ipynb not found: run from the checkout's "
                              "root (the figures' numbers are their notebooks')")
    for p in the_plan.entries:
        rec = args.figures / "records" / p.setting.name
        _check_dir(args.data / p.setting.name, p.config)
        _check_records(rec, args, override_of(p), p.config)
        if rec.is_dir():
            recorded_seeds(rec, p.config.hash())      # a damaged record: refused now, in one line


def check_foreign(d: Path, what: str, config_hash: str, describe: str) -> None:
    """Refuse (one line) a damaged record in ``d`` or one of another configuration."""
    from tiltpile.cli._common import record_metas

    for path, meta in record_metas(d, what):
        if meta.get("config_hash") != config_hash:
            raise ConfigError(f"{what} {d}: {path.name} is a record of another configuration than "
                              f"{describe} (hash {str(meta.get('config_hash'))[:12]}, "
                              f"{config_hash[:12]})")


def check_reference_records(args, the_plan, describe: str) -> None:
    """``--reference-records DIR``: a directory of records of the plan's committed setting."""
    if args.reference_records is None:
        return
    if not args.reference_records.is_dir():
        raise ConfigError(f"--reference-records {args.reference_records}: not a directory")
    check_foreign(args.reference_records, "--reference-records", the_plan.reference.config.hash(),
                  describe)


def _validate(args):
    """The plan (``studies.solver.plan``) and the directories, refused in one line before
    anything runs."""
    from tiltpile.studies import solver

    check_options(args)
    the_plan = solver.plan(args.preset, args.overrides, only(args.only), args.runs)
    check_study(args, the_plan, lambda p: p.setting.override)
    check_reference_records(args, the_plan, f"the committed setting ({args.preset} with --set)")
    return the_plan


# ----------------------------------------------------------------------------------------------
# the steps


def _say(line: str) -> None:
    print(f"tiltpile solver-study: {line}", file=sys.stderr, flush=True)


def _stopped_seeds(d: Path, rec: Path, seeds, config_hash: str) -> dict[int, str]:
    """{seed: rule} of the seeds the health rules stopped, from the manifest or runs.json."""
    from tiltpile.ensemble import read_manifest
    from tiltpile.studies import solver

    m = read_manifest(d) if d.is_dir() else None
    doc = solver.runs_doc(m if m and m.get("config_hash") == config_hash else None,
                          solver.read_runs(rec), config_hash)
    return {h["seed"]: h["rule"] for h in solver.health_stops(doc, seeds)}


def _ensembles(args, the_plan) -> list[str]:
    """Each setting's ensemble, in the plan's order; returns the names of the settings whose runs
    failed otherwise than by a health stop (retried next time)."""
    from tiltpile.cli.ensemble import recorded_seeds
    from tiltpile.ensemble import failed_runs, run_ensemble, run_file
    from tiltpile.outputs import OutputBusy
    from tiltpile.studies import solver

    crashed = []
    for p in the_plan.entries:
        name, cfg = p.setting.name, p.config
        d, rec = args.data / name, args.figures / "records" / name
        seeds = the_plan.seeds
        on_record = recorded_seeds(rec, cfg.hash()) if rec.is_dir() else set()
        stopped = _stopped_seeds(d, rec, seeds, cfg.hash())
        todo = [s for s in seeds if s not in stopped
                and (run_file(d, s).exists() or s not in on_record)]
        for s, rule in sorted(stopped.items()):
            _say(f"{name}: seed {s} was stopped by {rule} (recorded; not run again)")
        gone = sorted(s for s in on_record if s in seeds and not run_file(d, s).exists())
        if gone:
            _say(f"{name}: seeds {gone} from their records (no run files)")
        if not todo:
            continue
        new = [s for s in todo if not run_file(d, s).exists()]
        if new:
            _say(f"{name}: ensemble {d} ({len(new)} of {len(seeds)} runs to compute or resume)")
        try:
            man = run_ensemble(cfg, todo, d, workers=args.workers, progress=not args.quiet)
        except OutputBusy as e:
            _say(f"{name}: skipped: {' '.join(str(e).split())}")
            continue
        failed = [s for s in failed_runs(man) if s in todo]
        stops = {h["seed"]: h["rule"] for h in
                 solver.health_stops(solver.runs_doc(man, None, cfg.hash()), failed)}
        for s in failed:
            if s in stops:
                _say(f"{name}: seed {s} stopped by {stops[s]}: the setting is failed (recorded)")
            else:
                crashed.append(name)
                _say(f"{name}: seed {s} failed: {solver.runs_doc(man, None, cfg.hash())['runs'][str(s)]['error']}")
    return sorted(set(crashed))


def _records(args, the_plan) -> list[str]:
    """The records of every finished run of each setting and its runs.json; returns the settings
    holding records."""
    from tiltpile.ensemble import read_manifest
    from tiltpile.figures.records import write_records
    from tiltpile.studies import solver

    held = []
    for p in the_plan.entries:
        name = p.setting.name
        d, rec = args.data / name, args.figures / "records" / name
        m = read_manifest(d) if d.is_dir() else None
        if any(d.glob("run_*.h5")):
            table = write_records(d, rec, workers=args.workers, progress=False)
            written = int((table["status"] == "written").sum())
            if written:
                _say(f"{name}: {written} records written in {rec}")
        if m is not None and m.get("config_hash") == p.config.hash():
            solver.write_runs(rec, m, p.config.hash())
        if solver.recorded(rec, the_plan.seeds) or (rec / solver.RUNS_FILE).is_file():
            held.append(name)
    return held


def _analyse(args, the_plan) -> dict:
    """``studies.solver.analyse``; with one worker in a fresh process of one BLAS thread
    (``same_piles.worker_pool``), as the figures are evaluated with several: Fig. 5's fits run
    7x faster there than under a multi-threaded OpenBLAS on a busy machine (measured on the tiny
    test piles), and give the same numbers."""
    from tiltpile.figures import same_piles as sp
    from tiltpile.studies import solver

    kw = dict(null_flips=args.null, workers=args.workers or 1, progress=None if args.quiet else _say)
    where = (the_plan, args.figures / "records", args.figures / solver.COMPARISONS)
    if kw["workers"] > 1:       # the figures are evaluated in single-threaded workers already
        return solver.analyse(*where, **kw)
    with sp.worker_pool(1) as pool:
        return pool.submit(solver.analyse, *where, **kw).result()


def _command(args) -> str:
    parts = ["tiltpile solver-study", "--data", str(args.data), "--figures", str(args.figures),
             "--runs", str(args.runs), "--preset", args.preset]
    for o in args.overrides:
        parts += ["--set", o]
    if args.only:
        parts += ["--only", args.only]
    if args.null:
        parts += ["--null", str(args.null)]
    if args.reference_records is not None:
        parts += ["--reference-records", str(args.reference_records)]
    return " ".join(shlex.quote(p) if p != "tiltpile solver-study" else p for p in parts)


def run(args) -> int:
    """Validate everything, then the ensembles, the records and (unless --runs-only or
    --records-only) the comparisons, chart, JSON and report section. Exit status 1, one line, when
    a run failed otherwise than by a health stop, or a record cannot be read."""
    from tiltpile.record import RecordError
    from tiltpile.studies import solver

    the_plan = _validate(args)
    if args.reference_records is not None:
        from tiltpile.studies import settings as st

        got = st.seed_records(args.reference_records, args.figures / "records" / st.REFERENCE,
                              the_plan.seeds)
        if got:
            _say(f"reference: the records of seeds {got} from {args.reference_records}")
    crashed = [] if args.records_only or args.no_runs else _ensembles(args, the_plan)
    if args.runs_only:
        return _end(crashed)
    try:
        held = _records(args, the_plan)
        if args.records_only:
            print(f"wrote the records of {', '.join(held) if held else 'no setting'} in "
                  f"{args.figures / 'records'}")
            return 0
        numbers = _analyse(args, the_plan)
    except RecordError as e:
        print(f"tiltpile solver-study: error: {' '.join(str(e).split())}", file=sys.stderr)
        return 1
    ref = the_plan.reference.config
    meta = {"study": {"name": "solver", "preset": the_plan.preset, "n_grains": ref.scene.n,
                      "base_overrides": list(the_plan.base), "runs": the_plan.runs,
                      "settings": [p.setting.name for p in the_plan.entries],
                      "null_flips": args.null, "command": _command(args)}}
    paths = solver.write(numbers, meta, args.figures)
    for pt, s in zip(numbers["chart"], numbers["settings"]):
        moved = ("committed" if s["committed"] else s["status"] if s["comparison"] is None else
                 f"{s['comparison']['n_moved']} of {s['comparison']['n_with_error']} numbers moved, "
                 f"{len(s['flipped'])} claims flipped")
        sweeps = pt["sweeps_per_run"]
        print(f"{s['name']}: {len(s['seeds_done'])} of {s['seeds_planned']} runs, "
              f"{'n/a' if sweeps is None else f'{sweeps:.3g}'} sweeps per run; {moved}")
    print(f"wrote {paths['json']}, {paths['png']}, {paths['pdf']} and {paths['md']}")
    return _end(crashed)


def _end(crashed: list[str]) -> int:
    if crashed:
        print(f"tiltpile solver-study: error: runs of {', '.join(crashed)} failed (not by a health "
              "stop; see their ensemble.json); rerun to retry", file=sys.stderr)
        return 1
    return 0
