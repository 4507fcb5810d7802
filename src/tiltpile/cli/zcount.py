"""``tiltpile zcount DIR [DIR ...] --out PREFIX``: <z> of the quiet frames under each counting rule."""

from __future__ import annotations

import math
import shlex
from pathlib import Path

from tiltpile.cli._common import ConfigError


def add_parser(sub) -> None:
    p = sub.add_parser("zcount", help="<z> of ensembles' quiet frames against the counting rule "
                                      "(force and gap thresholds, walls, rattlers, bulk)")
    p.add_argument("dirs", nargs="+", metavar="DIR", help="ensemble directories holding run_*.h5")
    p.add_argument("--out", type=Path, default=Path("zcount"), metavar="PREFIX",
                   help="write PREFIX.json and PREFIX.png (default ./zcount)")
    p.add_argument("--every", type=int, default=1, metavar="K",
                   help="every K-th quiet frame of each run (default 1: all)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes for observables not cached yet (default: one per core)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def _validate(args) -> tuple[list[Path], Path]:
    from tiltpile.ensemble import read_manifest
    from tiltpile.paths import check_output
    from tiltpile.store import common_config

    if args.every < 1:
        raise ConfigError(f"--every must be at least 1, got {args.every}")
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    dirs = [Path(d) for d in args.dirs]
    seen = set()
    for d in dirs:
        if not d.is_dir():
            raise ConfigError(f"{d}: no such ensemble directory")
        if d.resolve() in seen:
            raise ConfigError(f"{d}: given twice")
        seen.add(d.resolve())
        files = sorted(d.glob("run_*.h5"))
        if not files:
            raise ConfigError(f"{d}: no run_*.h5 files to analyse")
        manifest = read_manifest(d)
        common_config(files, manifest["config_hash"] if manifest else None)  # one configuration
    prefix = args.out
    if prefix.suffix in (".json", ".png"):
        prefix = prefix.with_suffix("")
    if not prefix.name or prefix.name in (".", ".."):
        raise ConfigError(f"--out {args.out}: give a file name prefix, e.g. results/zcount")
    for ext in ("json", "png"):
        check_output(prefix.with_name(f"{prefix.name}.{ext}"), "--out")
    return dirs, prefix


def run(args) -> int:
    """Validate everything first (directories, one configuration each, output paths), then run
    :func:`tiltpile.figures.zcount.study` and write its JSON and PNG."""
    from tiltpile.figures.zcount import study, write_study

    dirs, prefix = _validate(args)
    command = " ".join(["tiltpile zcount", *(shlex.quote(str(d)) for d in args.dirs),
                        "--out", shlex.quote(str(prefix))]
                       + (["--every", str(args.every)] if args.every > 1 else []))
    doc = study(dirs, every=args.every, workers=args.workers, progress=not args.quiet,
                command=command)
    out_json, out_png = write_study(doc, prefix)
    from tiltpile.analysis.zcount import ANALYSIS_VARIANT

    for label, s in doc["ensembles"].items():
        a = s["table"][s["analysis_rule"]]
        ci = f" [{a['low']:.3f}, {a['high']:.3f}]" if math.isfinite(a["low"]) else ""
        g = s["reaches_paper_z"]["first_gap"][ANALYSIS_VARIANT.key]
        where = (f"from gap <= {g['threshold']:g} d (interpolated {g['interpolated']:.2g} d)"
                 if g["threshold"] is not None else "by no gap up to the alert distance")
        print(f"{label}: {s['n_runs']} runs, {sum(s['frames_per_run'].values())} quiet frames; "
              f"<z> = {a['z']:.3f}{ci} by the analysis's rule (f_n > 0, walls in, rattlers out, "
              f"bulk); {doc['paper_z']} reached {where}")
    print(f"wrote {out_json} and {out_png}")
    return 0
