"""``tiltpile simulate``: deposit and tilt one pile into a run file (``tiltpile.runner.simulate``)."""

from __future__ import annotations

import json
from pathlib import Path

from tiltpile.cli._common import (ConfigError, add_config_args, add_run_file_args, check_output,
                                  load_config, seed)

INTERRUPTED = "interrupted; an unfinished run file stays as NAME.h5.part and resumes next time"


def add_parser(sub) -> None:
    s = sub.add_parser("simulate", help="deposit and tilt one pile into a run file")
    add_config_args(s)
    s.add_argument("--seed", type=seed, required=True,
                   help="the pile's seed (deposition and every random draw): same config and seed, same bits")
    add_run_file_args(s)
    s.set_defaults(func=run, interrupted=INTERRUPTED)


def run(args) -> int:
    """Print the run's summary as one JSON line; health warnings come as one RuntimeWarning."""
    from tiltpile.runner import simulate

    cfg = load_config(args)
    out = Path(args.out)
    if out.suffix != ".h5":
        raise ConfigError(f"--out {out}: run files end in .h5")
    check_output(out, "--out")
    if out.exists() and not args.force:
        from tiltpile.store import remove_stale_checkpoint, writer_lock

        with writer_lock(out):  # a checkpoint a kill left beside the finished file is garbage
            remove_stale_checkpoint(out)
        raise ConfigError(f"--out {out} exists; pass --force to replace it")
    # --force: the old file stays until the new run is complete (the final rename replaces it)
    summary = simulate(cfg, args.seed, out, progress=not args.quiet, resume=not args.no_resume,
                       overwrite=args.force)
    print(json.dumps(summary))
    return 0
