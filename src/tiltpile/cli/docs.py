"""``tiltpile docs``: re-render the generated blocks of the README and the docs from the figures' JSON."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("docs", help="re-render the README's and the docs' generated blocks from "
                                    "the figures' JSON",
                       description="Every number the README and the docs quote from the figures "
                                   "lives between '<!-- generated: NAME ... -->' and '<!-- end "
                                   "generated: NAME -->' lines and is rendered from the figures' "
                                   "JSON (tiltpile.report.blocks). make docs; make reports runs it.")
    p.add_argument("--repo", default=".", help="the repository's root (default .)")
    p.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 naming the files whose blocks are stale")
    p.set_defaults(func=run)


def run(args) -> int:
    from tiltpile.report.blocks import BlockError, update
    from tiltpile.cli._common import ConfigError

    try:
        changed = update(args.repo, check=args.check)
    except BlockError as e:
        raise ConfigError(str(e)) from None
    for p in changed:
        print(f"{'stale' if args.check else 'updated'}: {p}")
    return 1 if (args.check and changed) else 0
