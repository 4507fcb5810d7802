"""``tiltpile stiffness-study [--data DIR] [--figures DIR] [--preset default-dem] [--runs 6] ...``: the
second engine in its rigid limit (issue 73; :mod:`tiltpile.studies.stiffness`).

For each stiffness of the study (``studies.stiffness.SETTINGS``: the preset's k_n, 4 k_n at dt / 2,
16 k_n at dt / 4 on half the piles; or those of ``--only``; the committed k_n, ``reference``,
always): its DEM ensemble (``tiltpile ensemble``'s code: finished runs skipped, interrupted ones
resumed) into DATA/<setting>/; its records (``tiltpile record``) into FIGURES/records/<setting>/
with ``runs.json``; then each stiffer setting compared with k_n on the same piles, each setting
with Contact Dynamics' records of the same piles (``--cd``), every number followed against 1 / k_n
and extrapolated to the rigid limit where the trend allows it, and
FIGURES/stiffness_study.{json,png,pdf,md}. The machinery is the solver study's
(:mod:`tiltpile.studies.settings`).

``--cd DIR`` is a directory of records (``tiltpile record``) of the preset without its ``[dem]``
section: for default-dem the default preset's, e.g. the solver study's committed setting's
(figures/solver-study/records/reference/) or ``tiltpile record data/default --out DIR``; records
of another configuration are refused, none there yet leaves the engines uncompared.
``--paper-records DIR`` prices a run and 50 piles of the DEM at the paper's scale at each k_n.

``--reference-records DIR`` takes the committed setting's records made elsewhere (default-dem's,
figures/default-dem/records/) into FIGURES/records/reference/ (those of seeds it lacks), so that
k_n is not run again. A seed whose record exists and whose run file is gone is not run again; a
seed the health rules stopped is not run again either and makes its setting *failed* (exit
status 0). Everything is validated before anything runs: an unknown setting, key or preset, a
stiffness whose time step would be too long for it, a directory or records of another
configuration, and without LAMMPS, are refused in one line (exit status 2).

``--runs-only`` runs the ensembles only; ``--records-only`` runs nothing and writes the records of
every finished run; ``--no-runs`` runs nothing and makes the study of what is finished.
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from tiltpile import config as cfgmod
from tiltpile.cli._common import ConfigError

COMMAND = "stiffness-study"
DEFAULT_DATA = Path("data") / "stiffness-study"
DEFAULT_FIGURES = Path("figures") / "stiffness-study"
INTERRUPTED = ("interrupted; finished runs are kept, unfinished ones resume and kept comparisons "
               "are reused next time")


def add_parser(sub) -> None:
    p = sub.add_parser(COMMAND, help="the DEM in its rigid limit: one ensemble per stiffness, each "
                                     "against k_n and against Contact Dynamics on the same piles; "
                                     "every number against 1/k_n, extrapolated where it may be",
                       description="Run (resumably) the DEM ensemble of every stiffness of the "
                                   "study, write their records, compare them with k_n and with "
                                   "Contact Dynamics on the same piles, and write the figure, its "
                                   "JSON and the report section (issue 73; docs/dem.md).")
    p.add_argument("--data", type=Path, default=DEFAULT_DATA, metavar="DIR",
                   help=f"where the runs go: DIR/<setting>/, the committed k_n's DIR/reference/ "
                        f"(default {DEFAULT_DATA})")
    p.add_argument("--figures", type=Path, default=DEFAULT_FIGURES, metavar="DIR",
                   help=f"where the figure, JSON, report section, records and comparisons go "
                        f"(default {DEFAULT_FIGURES})")
    p.add_argument("--runs", type=int, default=6, metavar="M",
                   help="runs (seeds 0..M-1) at k_n and 4 k_n; half of them, rounded up, at 16 k_n "
                        "(default 6)")
    p.add_argument("--workers", type=int, metavar="W",
                   help="processes for the runs, observables and records (default: one per core), "
                        "and for the figures' evaluation (default 1)")
    p.add_argument("--only", metavar="S,...",
                   help="these stiffnesses only (comma-separated names of the study's settings, or "
                        "<F>kn_dt<D>: F times the preset's k_n at its dem.dt over D), with k_n")
    p.add_argument("--preset", default="default-dem", choices=cfgmod.PRESETS, metavar="P",
                   help="the DEM configuration every setting starts from (default: default-dem)")
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="SECTION.KEY=VALUE",
                   help="override of every setting, the committed one included (repeatable)")
    p.add_argument("--cd", type=Path, metavar="DIR",
                   help="Contact Dynamics' records of the same piles (the preset without its "
                        "[dem] section; e.g. figures/solver-study/records/reference); none there "
                        "yet: the engines are not compared")
    p.add_argument("--reference-records", type=Path, metavar="DIR",
                   help="the committed k_n's records made elsewhere (e.g. "
                        "figures/default-dem/records), taken into FIGURES/records/reference/")
    p.add_argument("--paper-records", type=Path, metavar="DIR",
                   help="the DEM's records at the paper's scale at the preset's k_n (e.g. "
                        "figures/paper-5x-dem/records): what 50 piles there cost at each k_n")
    p.add_argument("--null", type=int, default=0, metavar="K",
                   help="also count the figure numbers chance moves against k_n: K exchanges of "
                        "each seed's two runs per setting (tiltpile same-piles --null; default 0)")
    from tiltpile.cli.solver_study import add_stage_options

    add_stage_options(p)
    p.set_defaults(func=run, interrupted=INTERRUPTED)


# ----------------------------------------------------------------------------------------------
# validation


def _validate(args):
    """The plan (``studies.stiffness.plan``), the directories and LAMMPS, refused in one line
    before anything runs."""
    from tiltpile.record import RecordError, read_meta, record_files
    from tiltpile.studies import stiffness

    from tiltpile.cli.solver_study import (check_foreign, check_options, check_reference_records,
                                           check_study, only)

    check_options(args)
    the_plan = stiffness.plan(args.preset, args.overrides, only(args.only), args.runs)
    check_study(args, the_plan, lambda p: None)
    check_reference_records(args, the_plan, f"the study's k_n ({args.preset} with --set)")
    if args.cd is not None:
        if args.cd.exists() and not args.cd.is_dir():
            raise ConfigError(f"--cd {args.cd}: not a directory")
        check_foreign(args.cd, "--cd", stiffness.cd_config(the_plan).hash(),
                       "Contact Dynamics' of these piles (the preset without [dem])")
    if args.paper_records is not None:
        files = record_files(args.paper_records)
        if not files:
            raise ConfigError(f"--paper-records {args.paper_records}: no records (run_*.npz)")
        try:
            dem = read_meta(files[0])["config"].get("dem")
        except RecordError as e:
            raise ConfigError(f"--paper-records: {' '.join(str(e).split())}") from None
        if dem is None:
            raise ConfigError(f"--paper-records {args.paper_records}: records of Contact Dynamics, "
                              "not of the DEM")
    if not (args.records_only or args.no_runs):
        from tiltpile.dem import lmp

        lmp.check_available()       # DemUnavailable: one line saying what to install
    return the_plan


# ----------------------------------------------------------------------------------------------
# the steps


def _say(line: str) -> None:
    print(f"tiltpile {COMMAND}: {line}", file=sys.stderr, flush=True)


def _command(args) -> str:
    parts = [f"tiltpile {COMMAND}", "--data", str(args.data), "--figures", str(args.figures),
             "--runs", str(args.runs), "--preset", args.preset]
    for o in args.overrides:
        parts += ["--set", o]
    for opt, v in (("--only", args.only), ("--cd", args.cd),
                   ("--reference-records", args.reference_records),
                   ("--paper-records", args.paper_records)):
        if v is not None:
            parts += [opt, str(v)]
    if args.null:
        parts += ["--null", str(args.null)]
    return " ".join(shlex.quote(p) if i else p for i, p in enumerate(parts))


def run(args) -> int:
    """Validate everything, take over the committed k_n's records, then the ensembles, the
    records and (unless --runs-only or --records-only) the comparisons, fits, figure, JSON and
    report section. Exit status 1, one line, when a run failed otherwise than by a health stop,
    or a record cannot be read."""
    from tiltpile.record import RecordError
    from tiltpile.studies import settings as st
    from tiltpile.studies import stiffness

    the_plan = _validate(args)
    records = args.figures / "records"
    if args.reference_records is not None:
        got = st.seed_records(args.reference_records, records / st.REFERENCE,
                              the_plan.reference.seeds)
        if got:
            _say(f"reference: the records of seeds {got} from {args.reference_records}")
    crashed = ([] if args.records_only or args.no_runs else
               st.run_ensembles(the_plan.entries, args.data, records, workers=args.workers,
                                progress=not args.quiet, say=_say))
    if args.runs_only:
        return _end(crashed)
    try:
        held = st.write_setting_records(the_plan.entries, args.data, records, workers=args.workers,
                                        say=_say)
        if args.records_only:
            print(f"wrote the records of {', '.join(held) if held else 'no setting'} in {records}")
            return 0
        if args.cd is not None and not st.recorded(args.cd, range(args.runs)):
            _say(f"--cd {args.cd} holds no record of these seeds yet: the engines are not compared")
        numbers = st.in_fresh_process(
            stiffness.analyse, the_plan, records, args.figures / stiffness.COMPARISONS, args.cd,
            args.paper_records, null_flips=args.null, workers=args.workers or 1,
            progress=None if args.quiet else _say)
    except RecordError as e:
        print(f"tiltpile {COMMAND}: error: {' '.join(str(e).split())}", file=sys.stderr)
        return 1
    ref = the_plan.reference.config
    meta = {"study": {"name": "stiffness", "preset": the_plan.preset, "n_grains": ref.scene.n,
                      "base_overrides": list(the_plan.base), "runs": the_plan.runs,
                      "settings": [p.setting.name for p in the_plan.entries],
                      "null_flips": args.null, "command": _command(args)}}
    paths = stiffness.write(numbers, meta, args.figures)
    for s in numbers["settings"]:
        steps = s["cost"].get("steps_per_run")
        vs = ("committed" if s["committed"] else s["status"] if s["comparison"] is None else
              f"{s['comparison']['n_moved']} of {s['comparison']['n_with_error']} numbers moved, "
              f"{len(s['flipped'])} claims flipped against k_n")
        print(f"{s['name']}: {len(s['seeds_done'])} of {s['seeds_planned']} runs, "
              f"{'n/a' if steps is None else f'{steps / 1e6:.3g} M'} DEM steps per run; {vs}")
    for m in numbers["measures"]:
        f = m["fit"]
        print(f"{m['key']}: " + (f"rigid limit {f['value']:.4g} +- {f['error']:.2g}"
                                 if f["status"] == "extrapolated" else
                                 f"does not extrapolate ({f['reason']})"))
    print(f"wrote {paths['json']}, {paths['png']}, {paths['pdf']} and {paths['md']}")
    return _end(crashed)


def _end(crashed: list[str]) -> int:
    if crashed:
        print(f"tiltpile {COMMAND}: error: runs of {', '.join(crashed)} failed (not by a health "
              "stop; see their ensemble.json); rerun to retry", file=sys.stderr)
        return 1
    return 0
