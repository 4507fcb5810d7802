"""``tiltpile definitions DIR --out FILE``: every figure number of one ensemble under each
plausible definition the paper leaves open (:mod:`tiltpile.figures.definitions`), for the
report's "What the disagreements depend on". ``--write-records ROOT`` writes each definition's
records, ``--compact ROOT`` rewrites them holding only what the default records do not."""

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
    p.add_argument("--out", type=Path, default=None, metavar="FILE",
                   help="the study's JSON (the report reads figures/definitions.json)")
    p.add_argument("--g", type=float, default=None, metavar="G",
                   help="the contact list's gap in d (default: fitted by <z> = 3.5 on the quiet frames)")
    p.add_argument("--records", type=Path, default=None, metavar="ROOT",
                   help="evaluate from records: DIR the records at the default parameters, "
                        "ROOT/<definition>/ those written at each definition's (tiltpile record "
                        "--params); needs --g")
    p.add_argument("--only", default=None, metavar="KEYS",
                   help="evaluate (or write the records of) only these definitions, comma-separated "
                        "keys such as list,mixed,stride-2 (force is always evaluated; default: all)")
    p.add_argument("--write-records", type=Path, default=None, metavar="ROOT",
                   help="instead of the study: the records of DIR's finished runs at each "
                        "definition's analysis parameters, into ROOT/<definition>/ (up-to-date ones "
                        "skipped), what --records reads; needs --g; --out not used")
    p.add_argument("--compact", type=Path, default=None, metavar="ROOT",
                   help="instead of the study: rewrite the records ROOT/<definition>/ leaving out "
                        "what DIR's records (the default parameters, the same runs) or an earlier "
                        "definition's hold bit for bit, each checked to read back the same record; "
                        "what --records reads, unchanged; --out, --g not used")
    p.add_argument("--workers", type=int, default=None,
                   help="with --write-records: processes for observables not cached yet")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def _records_and_root(records, option: str, root) -> None:
    """ConfigError unless ``records`` holds records and ``root`` (given as ``option``) is a
    directory."""
    from tiltpile.record import record_files

    if not record_files(records):
        raise ConfigError(f"{records}: no records run_*.npz (with {option}, DIR holds the "
                          "records at the default parameters)")
    if not root.is_dir():
        raise ConfigError(f"{option} {root}: no such directory")


def run(args) -> int:
    """Check the ensemble, g and the output first, then run the study and write it."""
    from tiltpile.figures import definitions as df
    from tiltpile.paths import check_output

    from .same_piles import _preset_of

    if not args.dir.is_dir():
        raise ConfigError(f"{args.dir}: no such ensemble directory")
    if args.compact is not None and (args.write_records is not None or args.records is not None
                                     or args.out is not None or args.g is not None):
        raise ConfigError("--compact rewrites records, not the study: leave out --write-records, "
                          "--records, --out and --g")
    if args.records is None and args.compact is None and not sorted(args.dir.glob("run_*.h5")):
        raise ConfigError(f"{args.dir}: no run_*.h5 files (the definitions need the run files, or "
                          "--records ROOT with the records of each definition)")
    if args.records is not None:
        _records_and_root(args.dir, "--records", args.records)
        if args.g is None:
            raise ConfigError("--records needs --g (the fit of g needs the run files)")
    if args.g is not None and not args.g > 0:
        raise ConfigError(f"--g must be > 0 (d), got {args.g}")
    only = None
    if args.only is not None:
        only = [k.strip() for k in args.only.split(",") if k.strip()]
        unknown, keys = df.unknown_keys(only)
        if unknown or not only:
            raise ConfigError(f"--only {args.only}: no definition {', '.join(unknown) or '(none given)'}; "
                              f"the study has {', '.join(keys)}")
    if args.workers is not None and args.write_records is None:
        raise ConfigError("--workers is only for --write-records")
    if args.compact is not None:
        _records_and_root(args.dir, "--compact", args.compact)
        for key, n, before, after, root in df.compact_definition_records(args.dir, args.compact, only,
                                                                         progress=not args.quiet):
            print(f"{key}: {n} record(s) compacted, {before / 1e6:.2f} MB -> {after / 1e6:.2f} MB; "
                  f"{root}", file=sys.stdout)
        return 0
    if args.write_records is not None:
        if args.records is not None or args.out is not None:
            raise ConfigError("--write-records writes records, not the study: leave out --records and --out")
        if not sorted(args.dir.glob("run_*.h5")):
            raise ConfigError(f"{args.dir}: no run_*.h5 files (--write-records needs the run files)")
        if args.g is None:
            raise ConfigError("--write-records needs --g (the gap of the list definitions)")
        if args.workers is not None and args.workers < 1:
            raise ConfigError(f"--workers must be >= 1, got {args.workers}")
        check_output(args.write_records, "records root", directory=True)
        for key, n, root in df.write_definition_records(args.dir, args.write_records, args.g, only,
                                                        workers=args.workers,
                                                        progress=not args.quiet):
            print(f"{key}: {n} record(s) written; {root}", file=sys.stdout)
        return 0
    if args.out is None:
        raise ConfigError("--out FILE is required (the study's JSON), unless --write-records")
    check_output(args.out, "--out")
    command = "tiltpile definitions " + " ".join(
        [str(args.dir) if args.records is not None else args.dir.name]
        + ([f"--g {args.g:g}"] if args.g is not None else [])
        + ([f"--records {args.records}"] if args.records is not None else [])
        + ([f"--only {','.join(only)}"] if only is not None else []))
    doc = df.study(args.dir, _preset_of(args.dir), g=args.g, progress=not args.quiet,
                   command=command, records=args.records, only=only)
    path = df.write_study(doc, args.out)
    print(f"{len(doc['definitions'])} definitions of {doc['n_runs']} runs, g = {doc['fit']['g']:g} d; "
          f"{path}", file=sys.stdout)
    return 0
