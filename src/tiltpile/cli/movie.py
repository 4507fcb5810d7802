"""``tiltpile movie RUN.h5 --out run.mp4``: the pile as in the paper's Fig. 3, frame by frame."""

from __future__ import annotations

import json
from pathlib import Path

from tiltpile.cli._common import ConfigError


def _positive(text: str) -> int:
    import argparse
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {v}")
    return v


def add_parser(sub) -> None:
    p = sub.add_parser("movie", help="render a run to mp4 (or gif, or a png still of one frame)")
    p.add_argument("run_file", help="run file (RUN.h5)")
    p.add_argument("--out", type=Path, required=True,
                   help="NAME.mp4, NAME.gif, or NAME.png (one frame: --frames K)")
    p.add_argument("--color", choices=("clusters", "force", "speed"), default="clusters",
                   help="clusters: critical clusters and failing grains (Fig. 3); force: force "
                        "chains; speed: |v| of each grain")
    p.add_argument("--forces", action="store_true",
                   help="also draw the force chains (line width ~ f_n)")
    p.add_argument("--frames", metavar="START:STOP:STEP", default=None,
                   help="stored frames to draw (Python slice, 0-based; default all)")
    p.add_argument("--fps", type=_positive, default=20, help="frames per second (default 20)")
    p.add_argument("--width", type=_positive, default=1280, help="width in pixels (default 1280)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    from tiltpile.store import RunFileError
    from tiltpile.view.movie import render

    if args.out.suffix not in (".mp4", ".gif", ".png"):
        raise ConfigError(f"--out {args.out}: give NAME.mp4, NAME.gif or NAME.png")
    if not args.out.parent.is_dir():
        raise ConfigError(f"--out {args.out}: no such directory {args.out.parent}")
    try:
        result = render(args.run_file, args.out, color=args.color, frames=args.frames,
                        forces=args.forces, fps=args.fps, width_px=args.width,
                        progress=not args.quiet)
    except (RunFileError, ValueError) as e:
        raise ConfigError(str(e)) from None
    print(json.dumps(result))
    return 0
