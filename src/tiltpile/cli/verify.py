"""``tiltpile verify RUN.h5|DIR [--against RECORDS]``: check run files completely (layout and every
checksum), and with ``--against`` that each reproduces, frame for frame, the run its committed
record was made from (a run file computed again after its first one was lost)."""

from __future__ import annotations

import json
from pathlib import Path

from tiltpile.cli._common import ConfigError


def add_parser(sub) -> None:
    p = sub.add_parser("verify", help="check run files: every dataset present and its checksums",
                       description="Read every dataset of each run file and check it against its "
                                   "checksum (HDF5 Fletcher32) and the layout. Exit status 0 if all "
                                   "are sound, 1 if any is damaged.")
    p.add_argument("paths", nargs="+", metavar="RUN.h5|DIR", help="run files, or directories of run_*.h5")
    p.add_argument("--json", action="store_true", help="one JSON object per file instead of text")
    p.add_argument("--against", metavar="RECORDS", type=Path,
                   help="a records directory (`tiltpile record`): also check that each sound run "
                        "file's frames are, bit for bit, those its record there was made from "
                        "(the SHA-256 the record holds); exit status 1 if any differ or has no "
                        "record")
    p.set_defaults(func=run)


def against_record(run_path: Path, records: Path) -> str | None:
    """None if the record of ``run_path`` in ``records`` was made from the same configuration,
    seed and frames, bit for bit (its ``source.frames_sha256``); else why not, in a few words."""
    from tiltpile.record import RecordError, read_meta, record_name
    from tiltpile.store import open_run

    rec = records / record_name(run_path.name)
    if not rec.is_file():
        return f"no record {rec.name} in {records}"
    try:
        meta = read_meta(rec)
    except RecordError as e:
        return f"its record is unreadable ({' '.join(str(e).split())})"
    want = (meta.get("source") or {}).get("frames_sha256")
    if not want:
        return f"its record {rec.name} holds no frames digest"
    with open_run(run_path) as r:
        if r.config_hash != meta.get("config_hash") or r.seed != meta.get("seed"):
            return (f"another run than its record's (config {r.config_hash[:12]}, seed {r.seed}; "
                    f"record: {str(meta.get('config_hash'))[:12]}, seed {meta.get('seed')})")
        if r.frames_digest() != want:
            return f"its frames differ from those its record {rec.name} was made from"
    return None


def _files(paths) -> list[Path]:
    out = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(p.glob("run_*.h5"))
            if not found:
                raise ConfigError(f"{p}: no run_*.h5 files to verify")
            out += found
        elif p.exists() or p.with_name(p.name + ".part").exists():
            out.append(p)
        else:
            raise ConfigError(f"{p}: no such run file or directory")
    return out


def run(args) -> int:
    from tiltpile.store import has_integrity_record, verify

    if args.against is not None and not args.against.is_dir():
        raise ConfigError(f"--against {args.against}: no such records directory")
    files = _files(args.paths)
    bad = differ = 0
    for f in files:
        problems = verify(f)
        legacy = not problems and not has_integrity_record(f)
        bad += bool(problems)
        odd = against_record(f, args.against) if args.against is not None and not problems else None
        differ += odd is not None
        if args.json:
            row = {"file": str(f), "ok": not problems, "problems": problems, "checksums": not legacy}
            if args.against is not None and not problems:
                row["reproduces_record"] = odd is None
                row["record_problem"] = odd
            print(json.dumps(row))
        elif problems:
            for p in problems:
                print(f"{f}: DAMAGED: {p}")
        else:
            print(f"{f}: ok" + (" (layout only: written before run files had checksums)" if legacy else "")
                  + ("" if args.against is None else
                     ", reproduces its record bit for bit" if odd is None else f", DIFFERS: {odd}"))
    if len(files) > 1 and not args.json:
        print(f"{len(files) - bad} of {len(files)} run files sound" + (f", {bad} damaged" if bad else "")
              + ("" if args.against is None else
                 f"; {len(files) - bad - differ} reproduce their records in {args.against}"))
    return 1 if bad or differ else 0
