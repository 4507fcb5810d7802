"""``tiltpile record DIR --out RECORDS``: a small record of every finished run of an ensemble,
what the figures read from it (``tiltpile.figures.records``), to commit in place of the run
files."""

from __future__ import annotations

import sys
from pathlib import Path

from tiltpile.cli._common import ConfigError, ensemble_files

# what a committed record may weigh: the paper's 50 runs in 100 MB (docs/run-file.md)
RECORD_BUDGET_BYTES = 2_000_000


def add_parser(sub) -> None:
    p = sub.add_parser("record", help="write the records of an ensemble's finished runs (what the "
                                      "figures read; committed in place of the run files)")
    p.add_argument("dir", help="ensemble directory holding run_*.h5")
    p.add_argument("--out", type=Path, required=True, metavar="RECORDS",
                   help="records directory: RECORDS/run_SSSS.npz, one per run file")
    p.add_argument("--workers", type=int, default=None,
                   help="processes for observables not cached yet (default: one per core)")
    p.add_argument("--params", metavar="JSON", default=None,
                   help="the tables at these analysis parameters, a JSON object such as "
                        "'{\"contact_rule\": \"gap:0.005\"}' (default: the defaults); such records "
                        "go in a directory of their own, one parameter set per directory")
    p.add_argument("--force", action="store_true", help="rewrite the records that are up to date too")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    """Validate everything, then write the missing and stale records and print one line per run
    file (record, written / up to date, size), with a warning on stderr for a record above
    ``RECORD_BUDGET_BYTES``. Refused before anything is written: DIR without
    run files or mixing configurations (or another than its ``ensemble.json``), --out that is DIR
    itself or its observables cache or cannot be written, --out holding records of another
    configuration or of other analysis parameters, --params that is not a JSON object of the
    tables' analysis parameters with values in range."""
    from tiltpile.ensemble import read_manifest
    from tiltpile.figures.records import foreign_records, refuse_foreign_params, write_records
    from tiltpile.paths import check_output
    from tiltpile.record import RecordError
    from tiltpile.store import common_config

    d = Path(args.dir)
    files = ensemble_files(d, args.workers, "finished run files (run_*.h5) to record")
    params = parse_params(args.params)
    out = args.out
    if out.exists() and out.resolve() in (d.resolve(), (d / "observables").resolve()):
        raise ConfigError(f"--out {out} is the ensemble directory or its observables cache; "
                          "give the records their own directory")
    check_output(out, "records directory", directory=True)
    manifest = read_manifest(d)
    config_hash, _ = common_config(files, manifest["config_hash"] if manifest else None)
    odd = foreign_records(out, config_hash)
    if odd:
        raise ConfigError(f"{out}: {odd[0].name}{f' and {len(odd) - 1} more' if len(odd) > 1 else ''} "
                          f"hold runs of another configuration than {d} (hash {config_hash[:12]}); "
                          "one records directory holds one configuration")
    try:
        refuse_foreign_params(out, params)
    except RecordError as e:
        raise ConfigError(str(e)) from None
    try:
        table = write_records(d, out, workers=args.workers, force=args.force,
                              progress=not args.quiet, params=params)
    except RecordError as e:
        print(f"tiltpile record: error: {' '.join(str(e).split())}", file=sys.stderr)
        return 1
    for rec, status, size in zip(table["record"], table["status"], table["bytes"]):
        print(f"{rec}  {status}  {size / 1e6:.2f} MB")
        if size > RECORD_BUDGET_BYTES:
            print(f"tiltpile record: warning: {rec} is {size / 1e6:.2f} MB, above the "
                  f"{RECORD_BUDGET_BYTES / 1e6:g} MB a committed record may weigh (docs/run-file.md)",
                  file=sys.stderr)
    written = int((table["status"] == "written").sum())
    print(f"{len(table)} records in {out}: {written} written, {len(table) - written} up to date, "
          f"{table['bytes'].sum() / 1e6:.2f} MB")
    return 0


def parse_params(text: str | None) -> dict:
    """``--params``: the full table parameters of a JSON object of analysis parameters (None: the
    defaults), checked (:func:`tiltpile.figures.records.check_params`); ConfigError (one line)
    for text that is not a JSON object, a name that is not a parameter of the tables, or a value
    out of its range."""
    import json

    from tiltpile.figures.records import check_params

    if text is None:
        return check_params(None)
    try:
        given = json.loads(text)
    except json.JSONDecodeError as e:
        raise ConfigError(f"--params {text!r}: not JSON ({e.msg} at character {e.pos})") from None
    if not isinstance(given, dict):
        raise ConfigError(f"--params {text!r}: give a JSON object of analysis parameters, "
                          '{"name": value, ...}')
    try:
        return check_params(given)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"--params: {' '.join(str(e).split())}") from None
