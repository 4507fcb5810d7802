"""Command line: ``tiltpile <command>`` (also ``python -m tiltpile``), one module per command.

Each module in this package registers its subcommand (``add_parser(subparsers)``) and
implements it (``run(args) -> int``); library modules keep only their Python API. Every command
validates its whole input first; on bad input it prints one line naming the problem and exits
with status 2, having written nothing.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from tiltpile import config as cfgmod

COMMANDS = ("simulate", "ensemble", "observables", "report", "bench", "info", "export", "movie")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="tiltpile", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(f"tiltpile.cli.{name}").add_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except cfgmod.ConfigError as e:
        print(f"tiltpile {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(getattr(args, "interrupted", "interrupted"), file=sys.stderr)
        return 130
