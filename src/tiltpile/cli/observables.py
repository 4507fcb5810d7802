"""``tiltpile observables DIR``: per-run observables of an ensemble, cached in ``DIR/observables/``."""

from __future__ import annotations

from pathlib import Path

from tiltpile.cli._common import ConfigError


def add_parser(sub) -> None:
    o = sub.add_parser("observables", help="compute (incrementally) the observables of an ensemble")
    o.add_argument("dir", help="ensemble directory holding run_*.h5")
    o.add_argument("--workers", type=int, default=None, help="processes (default: one per core)")
    o.add_argument("--force", action="store_true", help="recompute cached runs too")
    o.add_argument("--quiet", action="store_true", help="no progress bar")
    o.set_defaults(func=run)


def run(args) -> int:
    """Print the per-run table."""
    from tiltpile.analysis import compute_observables

    d = Path(args.dir)
    if not d.is_dir():
        raise ConfigError(f"{d}: no such ensemble directory")
    table = compute_observables(d, workers=args.workers, progress=not args.quiet, force=args.force)
    if len(table) == 0:
        raise ConfigError(f"{d}: no run_*.h5 files to analyse")
    print(table.to_string(index=False))
    return 0
