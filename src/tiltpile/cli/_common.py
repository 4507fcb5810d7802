"""What every command shares: the configuration options, the seed type, and one error path.

A command module (``tiltpile/cli/<name>.py``) defines ``add_parser(subparsers)`` and registers
``func=run``; ``run(args) -> int`` returns the exit status. Bad input is reported by raising
``ConfigError`` (``tiltpile.config``); ``tiltpile.cli.main`` turns it into one line
``tiltpile <command>: error: ...`` and exit status 2.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from tiltpile import config as cfgmod
from tiltpile.paths import check_output  # noqa: F401  (re-exported for the command modules)

ConfigError = cfgmod.ConfigError


def add_config_args(p: argparse.ArgumentParser, default_preset: str | None = None) -> None:
    """``--preset``, ``--config FILE.toml``, ``--set SECTION.KEY=VALUE`` (repeatable).

    ``--preset`` is required unless ``default_preset`` is given (a measurement's default, which
    ``--help`` shows and :func:`resolve_preset` prints): a command that makes runs never picks a
    scale the user did not name."""
    sizes = ", ".join(f"{s.name} {cfgmod.preset_dict(s.name)['scene']['n']} grains"
                      for s in cfgmod.PRESET_SCALES)
    what = (f"a named preset ({', '.join(cfgmod.PRESETS)}) or another triple of scale "
            f"({sizes}), history ({', '.join(cfgmod.PRESET_AXES['history'])}) and engine as "
            "<scale>[-<history>][-dem] (tiltpile presets lists them)")
    if default_preset is None:
        p.add_argument("--preset", choices=cfgmod.ALL_PRESET_NAMES, required=True, metavar="P",
                       help=f"base configuration (required): {what}")
    else:   # None until resolve_preset, so that a given --preset is told from the default
        p.add_argument("--preset", choices=cfgmod.ALL_PRESET_NAMES, default=None, metavar="P",
                       help=f"base configuration (default: {default_preset}): {what}")
        p.set_defaults(default_preset=default_preset)
    p.add_argument("--config", type=Path, help="TOML file overriding the preset")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one value, e.g. --set solver.dt=0.005 (repeatable)")


def resolve_preset(args, command: str) -> str:
    """``args.preset``, the command's default when none was given, saying so on stderr before the
    work starts (one line: the preset, and whether it is the default)."""
    if args.preset is None:
        args.preset = args.default_preset
        print(f"tiltpile {command}: preset {args.preset} (the default; --preset to choose)",
              file=sys.stderr)
    else:
        print(f"tiltpile {command}: preset {args.preset}", file=sys.stderr)
    return args.preset


def load_config(args) -> cfgmod.Config:
    """The validated configuration of ``add_config_args``' options (raises ``ConfigError``)."""
    return cfgmod.load(args.preset, args.config, args.overrides)


def seed(text: str) -> int:
    """argparse type of a seed: decimal digits only (not ``1_0``, ``+5``, `` 5``), 0..2**63-1."""
    if not re.fullmatch(r"[0-9]+", text):
        raise argparse.ArgumentTypeError(f"seed must be a non-negative integer (digits 0-9 only), got {text!r}")
    try:
        return cfgmod.check_seed(int(text))
    except cfgmod.ConfigError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def record_metas(directory, what: str):
    """(path, meta) of every record ``run_*.npz`` in ``directory``, read cheaply
    (``record.read_meta``); ConfigError naming ``what`` (one line) for a damaged one."""
    from tiltpile.record import RecordError, read_meta, record_files

    for path in record_files(directory):
        try:
            meta = read_meta(path)
        except RecordError as e:
            raise ConfigError(f"{what}: {' '.join(str(e).split())}") from None
        yield path, meta


def ensemble_files(directory, workers, what: str) -> list[Path]:
    """The finished run files of an ensemble directory given on the command line, sorted; one-line
    ConfigError for a directory that does not exist, ``workers`` below 1, or no run file
    (``what``: what the command would do with them, for the message)."""
    d = Path(directory)
    if not d.is_dir():
        raise ConfigError(f"{d}: no such ensemble directory")
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    files = sorted(d.glob("run_*.h5"))
    if not files:
        raise ConfigError(f"{d}: no {what}")
    return files


def add_run_file_args(s) -> None:
    """The options of a command that writes one run file, resumably (``simulate``, ``dem``):
    --out, --force, --no-resume, --quiet."""
    s.add_argument("--out", required=True, help="run file to write (NAME.h5; NAME.h5.part while running)")
    s.add_argument("--force", action="store_true",
                   help="replace an existing complete run file (only once the new run is complete)")
    s.add_argument("--no-resume", action="store_true", help="ignore an interrupted NAME.h5.part")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
