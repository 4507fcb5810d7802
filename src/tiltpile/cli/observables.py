"""``tiltpile observables DIR``: per-run observables of an ensemble, cached in ``DIR/observables/``."""

from __future__ import annotations

from pathlib import Path

from tiltpile.cli._common import ConfigError, ensemble_files


def add_parser(sub) -> None:
    o = sub.add_parser("observables", help="compute (incrementally) the observables of an ensemble")
    o.add_argument("dir", help="ensemble directory holding run_*.h5")
    o.add_argument("--workers", type=int, default=None, help="processes (default: one per core)")
    o.add_argument("--force", action="store_true", help="recompute cached runs too")
    o.add_argument("--quiet", action="store_true", help="no progress bar")
    o.set_defaults(func=run)


def run(args) -> int:
    """Print the per-run table. Refuses a directory whose runs hold more than one configuration
    (or another than its ``ensemble.json``) and any run file whose layout is damaged; a damaged
    dataset stops the computation with one line naming the file and the dataset."""
    from tiltpile.analysis import compute_observables
    from tiltpile.ensemble import read_manifest
    from tiltpile.paths import check_output
    from tiltpile.store import common_config

    d = Path(args.dir)
    files = ensemble_files(d, args.workers, "run_*.h5 files to analyse")
    manifest = read_manifest(d)
    common_config(files, manifest["config_hash"] if manifest else None)
    check_output(d / "observables", "cache directory", directory=True)
    table = compute_observables(d, workers=args.workers, progress=not args.quiet, force=args.force)
    if len(table) == 0:
        raise ConfigError(f"{d}: no run_*.h5 files to analyse")
    print(table.to_string(index=False))
    return 0
