"""``tiltpile ensemble``: many seeds, resumable, on dask.distributed (``tiltpile.ensemble``)."""

from __future__ import annotations

import json
from pathlib import Path

from tiltpile.cli._common import ConfigError, add_config_args, load_config, seed

INTERRUPTED = "interrupted; unfinished runs stay as run_SSSS.h5.part and resume next time"


def add_parser(sub) -> None:
    p = sub.add_parser("ensemble", help="run many seeds (resumable) on dask.distributed",
                       description="Run seeds S..S+M-1 of one configuration into DIR, resumably.")
    add_config_args(p)
    p.add_argument("--runs", type=int, required=True, metavar="M", help="number of runs (seeds S..S+M-1)")
    p.add_argument("--first-seed", type=seed, default=0, metavar="S", help="first seed (default 0)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR",
                   help="ensemble directory: DIR/run_SSSS.h5 and the manifest DIR/ensemble.json")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of a running dask scheduler (tcp://host:port); default: a LocalCluster")
    p.add_argument("--workers", type=int, metavar="W",
                   help="LocalCluster worker processes (default: one per core, at most one per run)")
    p.add_argument("--skip-recorded", type=Path, metavar="RECORDS",
                   help="skip the seeds whose record (RECORDS/run_SSSS.npz, `tiltpile record`) "
                        "exists: a run whose record is committed is not computed again when its "
                        "run file is gone (records of another configuration are refused)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run, interrupted=INTERRUPTED)


def recorded_seeds(records: Path, config_hash: str) -> set[int]:
    """The seeds of the records in ``records`` (``run_*.npz``), all of which must be records of
    the configuration ``config_hash``; ConfigError (one line) for a missing directory, a damaged
    record or one of another configuration."""
    from tiltpile.cli._common import record_metas

    if not records.is_dir():
        raise ConfigError(f"--skip-recorded {records}: not a directory")
    seeds = set()
    for path, meta in record_metas(records, "--skip-recorded"):
        if meta.get("config_hash") != config_hash:
            raise ConfigError(f"--skip-recorded: {path} is a record of another configuration "
                              f"(hash {str(meta.get('config_hash'))[:12]}, this one "
                              f"{config_hash[:12]}): give the records of this ensemble")
        seeds.add(int(meta["seed"]))
    return seeds


def run(args) -> int:
    """Validate, run, print a one-line JSON summary; 0 if every run is done, 1 if any failed."""
    from tiltpile.ensemble import MANIFEST, failed_runs, run_ensemble

    if args.runs < 1:
        raise ConfigError(f"--runs must be at least 1, got {args.runs}")
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    if args.workers is not None and args.scheduler is not None:
        raise ConfigError("--workers sizes the LocalCluster; with --scheduler the cluster brings its own")
    cfg = load_config(args)
    seeds = range(args.first_seed, args.first_seed + args.runs)
    skipped = (sorted(recorded_seeds(args.skip_recorded, cfg.hash()) & set(seeds))
               if args.skip_recorded is not None else [])
    todo = [s for s in seeds if s not in skipped]
    summary = {"out": str(args.out), "manifest": str(Path(args.out) / MANIFEST), "runs": len(seeds)}
    if skipped:
        summary["recorded"] = skipped
    if not todo:
        print(json.dumps({**summary, "done": len(skipped), "failed": []}))
        return 0
    manifest = run_ensemble(cfg, todo, args.out, scheduler=args.scheduler, workers=args.workers,
                            progress=not args.quiet)
    failed = [s for s in failed_runs(manifest) if s in todo]
    done = sum(manifest["runs"][str(s)]["status"] == "done" for s in todo)
    print(json.dumps({**summary, "done": done + len(skipped), "failed": failed}))
    return 1 if failed else 0
