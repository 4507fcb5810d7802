"""``tiltpile repose RUN.h5|DIR``: the slide and repose angles of finished runs (``tiltpile.repose``)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

from tiltpile.cli._common import ConfigError, check_output
from tiltpile.paper_values import SLIDE_KE

FORMAT = "tiltpile-repose/1"


# the library's defaults (tiltpile.repose; not imported here: it loads the simulator, and every
# command builds this parser; the slide's threshold is the paper's value, paper_values.SLIDE_KE);
# tests/test_repose.py checks that they agree
DEFAULTS = dict(ke_slide=SLIDE_KE.value, ke_stop=1e-5, slide_span=1.0, stop_span=0.5, max_deg=35.0)


def add_parser(sub) -> None:
    d = DEFAULTS
    p = sub.add_parser(
        "repose", help="tilt finished runs on into a large slide, then back: where the flow stops",
        description="Continue the pile of each run file from its last frame: tilt on at the run's "
                    "rate until a slide is established (kinetic energy per mobile grain above "
                    "--ke-slide for --slide-span deg), then tilt back at the same rate until it "
                    "stays below --ke-stop for --stop-span deg: the first of those frames is the "
                    "stop (repose) angle. If the run's own frames establish a slide, the pile is "
                    "continued from the frame that does, and turned back there. Prints one line per run, and for several runs the mean "
                    "stop and slide angles with bootstrap 95% intervals.")
    p.add_argument("path", metavar="RUN.h5|DIR", help="run file, or directory of run_*.h5")
    p.add_argument("--ke-slide", type=float, default=d["ke_slide"], metavar="KE",
                   help=f"kinetic energy per mobile grain [m g d] of a slide (default {d['ke_slide']:g})")
    p.add_argument("--ke-stop", type=float, default=d["ke_stop"], metavar="KE",
                   help=f"... below which the flow has stopped (default {d['ke_stop']:g})")
    p.add_argument("--slide-span", type=float, default=d["slide_span"], metavar="DEG",
                   help=f"tilt over which the slide must last (default {d['slide_span']:g})")
    p.add_argument("--stop-span", type=float, default=d["stop_span"], metavar="DEG",
                   help=f"tilt over which the pile must stay quiet (default {d['stop_span']:g})")
    p.add_argument("--max-deg", type=float, default=d["max_deg"], metavar="DEG",
                   help=f"no slide by this angle: outcome 'no slide' (default {d['max_deg']:g})")
    p.add_argument("--from-last-frame", action="store_true",
                   help="continue from the run's last frame even if the run itself established "
                        "a slide (default: from the frame that established it)")
    p.add_argument("--workers", type=int, default=1, metavar="W",
                   help="processes for a directory's runs (default 1)")
    p.add_argument("--json", type=Path, metavar="OUT",
                   help="write the parameters, every run (with its per-frame trace) and the "
                        "summary to OUT (replaced only when complete)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run, interrupted="interrupted; nothing was written")


def _files(path: Path) -> list[Path]:
    from tiltpile.store import part_path

    if path.is_dir():
        files = sorted(path.glob("run_*.h5"))
        if not files:
            raise ConfigError(f"{path}: no run_*.h5 files")
        return files
    if path.exists():
        return [path]
    if part_path(path).exists():
        raise ConfigError(f"{path}: an incomplete run (only {part_path(path).name} exists)")
    raise ConfigError(f"{path}: no such run file or directory")


def _check_numbers(args) -> dict:
    from tiltpile.repose import MIN_DEG, check_params

    for flag, v in (("--ke-slide", args.ke_slide), ("--ke-stop", args.ke_stop),
                    ("--slide-span", args.slide_span), ("--stop-span", args.stop_span)):
        if not (math.isfinite(v) and v > 0):
            raise ConfigError(f"{flag} must be a finite number > 0, got {v:g}")
    if args.ke_stop >= args.ke_slide:
        raise ConfigError(f"--ke-stop {args.ke_stop:g} must be below --ke-slide {args.ke_slide:g}")
    if not (math.isfinite(args.max_deg) and MIN_DEG < args.max_deg <= 90):
        raise ConfigError(f"--max-deg must be in ({MIN_DEG:g}, 90], got {args.max_deg:g}")
    if args.workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {args.workers}")
    params = dict(ke_slide=args.ke_slide, ke_stop=args.ke_stop, slide_span_deg=args.slide_span,
                  stop_span_deg=args.stop_span, max_deg=args.max_deg)
    check_params(min_deg=MIN_DEG, **params)  # the library's own check agrees
    return dict(params, from_last=args.from_last_frame)


def _line(r) -> str:
    name = Path(r.run).name
    cost = f"{r.steps} steps, {r.sweeps} sweeps, {r.seconds:.1f} s"
    if r.outcome == "stopped":
        return (f"{name}: slide from {r.slide_deg:.2f} deg, reversed at {r.reverse_deg:.2f} deg, "
                f"flow stops at {r.stop_deg:.2f} deg, its surface then at {r.surface_deg:.2f} deg "
                f"to the horizontal ({cost})")
    if r.outcome == "no slide":
        return f"{name}: no slide from {r.start_deg:.2f} up to {r.params['max_deg']:.2f} deg ({cost})"
    if r.outcome == "no stop":
        return (f"{name}: slide from {r.slide_deg:.2f} deg still flowing when tilted back to "
                f"{r.params['min_deg']:.2f} deg ({cost})")
    return f"{name}: failed: {r.error}"


def _summary_line(s: dict) -> str:
    o = s["outcomes"]

    def ci(d):
        if d["estimate"] is None:
            return "none"
        lo = "nan" if d["low"] is None else f"{d['low']:.2f}"
        hi = "nan" if d["high"] is None else f"{d['high']:.2f}"
        return f"{d['estimate']:.2f} deg [{lo}, {hi}]"

    return (f"stop angle {ci(s['stop_deg'])} (surface {ci(s['surface_deg'])}), slide angle "
            f"{ci(s['slide_deg'])} (mean, bootstrap "
            f"95% over runs; {o['stopped']} of {s['runs']} runs stopped, {o['no slide']} no slide, "
            f"{o['no stop']} no stop, {o['failed']} failed)")


def run(args) -> int:
    """Validate everything, then measure; exit status 1 if a run failed (a health stop)."""
    import tiltpile
    from tiltpile.repose import repose_many, summarize, write_json
    from tiltpile.store import RunFileError, common_config, open_run

    params = _check_numbers(args)
    path = Path(args.path)
    files = _files(path)
    if args.json is not None:
        check_output(args.json, "--json")
    try:
        if path.is_dir():
            common_config(files)  # one configuration per directory; opens (checks) every file
        else:
            with open_run(path) as r:
                if r.n_frames < 1:
                    raise ConfigError(f"{path}: the run has no frames")
    except RunFileError as e:
        if type(e) is not RunFileError:  # MixedConfigError and co.: refused as they are
            raise
        raise ConfigError(str(e)) from None

    def report(r) -> None:
        line = _line(r)
        if r.outcome == "failed":
            print(f"tiltpile repose: error: {line}", file=sys.stderr)
        else:
            print(line, flush=True)

    results = repose_many(files, workers=args.workers, progress=not args.quiet, on_result=report,
                          **params)
    summary = summarize(results)
    if len(results) > 1:
        print(_summary_line(summary))
    if args.json is not None:
        from tiltpile.repose import MIN_DEG

        write_json(args.json, {
            "format": FORMAT, "tiltpile_version": tiltpile.__version__, "path": str(path),
            "params": {**{k: v if isinstance(v, bool) else float(v) for k, v in params.items()},
                       "min_deg": MIN_DEG},
            "summary": summary, "runs": [r.to_dict() for r in results]})
    return 1 if any(r.outcome == "failed" for r in results) else 0
