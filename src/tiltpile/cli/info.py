"""``tiltpile info RUN.h5|DIR``: a one-screen summary of a run file or an ensemble directory."""

from __future__ import annotations

from tiltpile.cli._common import ConfigError


def add_parser(sub) -> None:
    p = sub.add_parser("info", help="summarize a run file (config as TOML, health, onsets) "
                                    "or an ensemble directory")
    p.add_argument("path", help="run file (RUN.h5) or ensemble directory")
    p.add_argument("--quiet", action="store_true", help="no progress bar while finding the onsets")
    p.add_argument("--records", metavar="RECORDS",
                   help="of a directory: count the runs recorded in RECORDS (tiltpile record) "
                        "whose run files are not here as finished, in the cost and what is left "
                        "(an ensemble restarted with --skip-recorded after its run files were lost)")
    p.set_defaults(func=run)


def run(args) -> int:
    from tiltpile.view.info import InfoError, info

    try:
        text = info(args.path, progress=not args.quiet, records=args.records)
    except InfoError as e:
        raise ConfigError(str(e)) from None
    print(text)
    return 0
