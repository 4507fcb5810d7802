"""``tiltpile export RUN.h5 --format extxyz|vtk --out PATH``: the run for OVITO or ParaView."""

from __future__ import annotations

import json
from pathlib import Path

from tiltpile.cli._common import ConfigError


def add_parser(sub) -> None:
    p = sub.add_parser("export", help="write a run as extended XYZ (OVITO, ASE) or VTK XML "
                                      "(ParaView) with the paper's per-grain fields")
    p.add_argument("run_file", help="run file (RUN.h5)")
    p.add_argument("--format", dest="fmt", choices=("extxyz", "vtk"), required=True,
                   help="extxyz: one multi-frame .xyz file; vtk: OUT.pvd and OUT/*.vtu")
    p.add_argument("--frames", metavar="START:STOP:STEP", default=None,
                   help="stored frames to export (Python slice, 0-based; default all)")
    p.add_argument("--out", type=Path, required=True, help="NAME.xyz (extxyz) or NAME.pvd (vtk)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    from tiltpile.store import RunFileError
    from tiltpile.view.export import export

    if args.fmt == "vtk" and args.out.suffix != ".pvd":
        raise ConfigError(f"--out {args.out}: the VTK export is a collection, give NAME.pvd")
    if not args.out.parent.is_dir():
        raise ConfigError(f"--out {args.out}: no such directory {args.out.parent}")
    try:
        result = export(args.run_file, args.out, args.fmt, args.frames, progress=not args.quiet)
    except (RunFileError, ValueError) as e:
        raise ConfigError(str(e)) from None
    print(json.dumps(result))
    return 0
