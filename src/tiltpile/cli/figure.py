"""``tiltpile figure NAME DATA [--set key=value ...] [--out DIR]``: one figure from any data
(:mod:`tiltpile.figures.build`), as its notebook makes it."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from tiltpile.cli._common import ConfigError

FIGURES = ("fig1", "fig2", "fig3", "fig4", "fig5", "fig6", "fig7")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "figure", help="one figure from an ensemble directory (run files) or records, at its "
                       "defaults or other parameters",
        description="Compute one figure of the paper (fig1 ... fig6, and fig7, the rigid "
                    "clusters) from DATA, an ensemble directory of run files or a directory of "
                    "their records, as `make figures` and the figure's notebook compute it; "
                    "print its numbers as JSON, and with --out write OUT/<stem>.png, .pdf and "
                    ".json. --set changes a parameter (--list shows them all with their "
                    "defaults).")
    p.add_argument("name", metavar="NAME", help=f"the figure: {', '.join(FIGURES)} (or its stem, "
                                                "fig5_cluster_sizes)")
    p.add_argument("data", nargs="?", type=Path, metavar="DATA",
                   help="ensemble directory (run_*.h5) or records directory (run_*.npz)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="sets",
                   help="a parameter away from its default (repeatable); VALUE in JSON "
                        "(0.03, null, [1, 2]) or a plain string (gap:0.01)")
    p.add_argument("--preset", default=None, help="preset name recorded in the figure's JSON")
    p.add_argument("--out", type=Path, metavar="DIR", default=None,
                   help="write the figure's PNG, PDF and JSON to DIR")
    p.add_argument("--list", action="store_true",
                   help="list the figure's parameters with their defaults, and stop")
    p.set_defaults(func=run, interrupted="interrupted; nothing was written")


def parse_set(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` as (key, value): VALUE in JSON, ``None`` as null, else the string."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set {text!r}: give KEY=VALUE")
    if value.strip() == "None":
        return key.strip(), None
    try:
        return key.strip(), json.loads(value)
    except ValueError:
        return key.strip(), value


def run(args) -> int:
    from tiltpile.figures import build, style

    try:
        name = build.figure_name(args.name)
    except ValueError as e:
        raise ConfigError(str(e)) from None
    if args.list:
        print(build.describe(name))
        return 0
    if args.data is None:
        raise ConfigError("give DATA, an ensemble or records directory (or --list)")
    if not args.data.is_dir():
        raise ConfigError(f"{args.data}: no such directory")
    overrides = dict(parse_set(s) for s in args.sets)
    try:
        params = build.given(name, overrides)
    except (ValueError, TypeError) as e:
        raise ConfigError(str(e)) from None
    from tiltpile.record import RecordError

    try:
        numbers = build.build(name, args.data, args.preset, args.out, **params)
    except RecordError as e:     # records that cannot serve these parameters or columns
        raise ConfigError(str(e)) from None
    json.dump(style.jsonable(numbers), sys.stdout, indent=1)
    print()
    if args.out is not None:
        print(f"wrote {args.out / build.STEMS[name]}.png, .pdf and .json", file=sys.stderr)
    return 0
