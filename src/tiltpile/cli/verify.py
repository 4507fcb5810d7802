"""``tiltpile verify RUN.h5|DIR``: check run files completely (layout and every checksum)."""

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
    p.set_defaults(func=run)


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

    files = _files(args.paths)
    bad = 0
    for f in files:
        problems = verify(f)
        legacy = not problems and not has_integrity_record(f)
        bad += bool(problems)
        if args.json:
            print(json.dumps({"file": str(f), "ok": not problems, "problems": problems,
                              "checksums": not legacy}))
        elif problems:
            for p in problems:
                print(f"{f}: DAMAGED: {p}")
        else:
            print(f"{f}: ok" + (" (layout only: written before run files had checksums)" if legacy else ""))
    if len(files) > 1 and not args.json:
        print(f"{len(files) - bad} of {len(files)} run files sound" + (f", {bad} damaged" if bad else ""))
    return 1 if bad else 0
