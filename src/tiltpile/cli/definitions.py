"""``tiltpile definitions DIR --out FILE``: every figure number of one ensemble under each
plausible definition the paper leaves open (:mod:`tiltpile.figures.definitions`), for the
report's "What the disagreements depend on"."""

from __future__ import annotations

import sys
from pathlib import Path

from tiltpile.cli._common import ConfigError


def add_parser(sub) -> None:
    p = sub.add_parser("definitions", help="every figure number of an ensemble under each contact "
                                           "rule, frame spacing and peak definition")
    p.add_argument("dir", type=Path, metavar="DIR",
                   help="an ensemble directory of run_*.h5 (records are not enough: near pairs come "
                        "from every frame's positions)")
    p.add_argument("--out", type=Path, required=True, metavar="FILE",
                   help="the study's JSON (the report reads figures/definitions.json)")
    p.add_argument("--g", type=float, default=None, metavar="G",
                   help="the contact list's gap in d (default: fitted by <z> = 3.5 on the quiet frames)")
    p.add_argument("--records", type=Path, default=None, metavar="ROOT",
                   help="evaluate from records: DIR the records at the default parameters, "
                        "ROOT/<definition>/ those written at each definition's (tiltpile record "
                        "--params); needs --g")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def run(args) -> int:
    """Check the ensemble, g and the output first, then run the study and write it."""
    from tiltpile.figures import definitions as df
    from tiltpile.paths import check_output

    from .same_piles import _preset_of

    from tiltpile.record import record_files

    if not args.dir.is_dir():
        raise ConfigError(f"{args.dir}: no such ensemble directory")
    if args.records is None and not sorted(args.dir.glob("run_*.h5")):
        raise ConfigError(f"{args.dir}: no run_*.h5 files (the definitions need the run files, or "
                          "--records ROOT with the records of each definition)")
    if args.records is not None:
        if not record_files(args.dir):
            raise ConfigError(f"{args.dir}: no records run_*.npz (with --records, DIR holds the "
                              "records at the default parameters)")
        if not args.records.is_dir():
            raise ConfigError(f"--records {args.records}: no such directory")
        if args.g is None:
            raise ConfigError("--records needs --g (the fit of g needs the run files)")
    if args.g is not None and not args.g > 0:
        raise ConfigError(f"--g must be > 0 (d), got {args.g}")
    check_output(args.out, "--out")
    command = "tiltpile definitions " + " ".join(
        [str(args.dir) if args.records is not None else args.dir.name]
        + ([f"--g {args.g:g}"] if args.g is not None else [])
        + ([f"--records {args.records}"] if args.records is not None else []))
    doc = df.study(args.dir, _preset_of(args.dir), g=args.g, progress=not args.quiet,
                   command=command, records=args.records)
    path = df.write_study(doc, args.out)
    print(f"{len(doc['definitions'])} definitions of {doc['n_runs']} runs, g = {doc['fit']['g']:g} d; "
          f"{path}", file=sys.stdout)
    return 0
