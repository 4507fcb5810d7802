"""Command line: ``tiltpile simulate | ensemble | observables | report | bench`` (also ``python -m tiltpile``).

Every command validates its whole input first; on bad input it prints one line naming the
problem and exits with status 2, having written nothing.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from tiltpile import config as cfgmod


def _add_config_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", choices=cfgmod.PRESETS, default="smoke", help="base configuration")
    p.add_argument("--config", type=Path, help="TOML file overriding the preset")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one value, e.g. --set solver.dt=0.005 (repeatable)")


def _load_config(args) -> cfgmod.Config:
    return cfgmod.load(args.preset, args.config, args.overrides)


def _seed(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"seed must be a non-negative integer, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"seed must be a non-negative integer, got {v}")
    return v


def cmd_simulate(args) -> int:
    from tiltpile.runner import simulate

    cfg = _load_config(args)
    out = Path(args.out)
    if out.suffix != ".h5":
        raise cfgmod.ConfigError(f"--out {out}: run files end in .h5")
    if out.exists() and not args.force:
        raise cfgmod.ConfigError(f"--out {out} exists; pass --force to overwrite it")
    if out.exists():
        out.unlink()
    summary = simulate(cfg, args.seed, out, progress=not args.quiet, resume=not args.no_resume)
    # health warnings past the [health] warn limits come as one RuntimeWarning on stderr
    print(json.dumps(summary))
    return 0


def cmd_bench(args) -> int:
    if args.chart is not None:
        return _bench_chart(args)
    if args.quick or args.parts:
        raise cfgmod.ConfigError("--quick and --parts only apply to --chart DIR")
    from tiltpile.bench import bench

    result = bench(n=args.n, steps=args.steps, preset=args.preset, config_file=args.config,
                   overrides=args.overrides, seed=args.seed, progress=not args.json)
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:>24}: {v}")
    return 0


def _bench_chart(args) -> int:
    """``bench --chart DIR``: the speed x accuracy chart (tiltpile.perfchart)."""
    given = [name for name, value, default in (
        ("--n", args.n, 4000), ("--steps", args.steps, 200), ("--seed", args.seed, 0),
        ("--set", args.overrides, []), ("--config", args.config, None), ("--preset", args.preset, "paper"))
        if value != default]
    if given:
        raise cfgmod.ConfigError(f"{', '.join(given)} do not apply to --chart (its scenes are fixed: "
                                 "tiltpile.perfchart.ChartSpec)")
    from tiltpile.perfchart import ChartSpec, run_chart

    spec = ChartSpec.quick_spec() if args.quick else ChartSpec.full()
    parts = tuple(args.parts.split(",")) if args.parts else ("accuracy", "scaling")
    bad = set(parts) - {"accuracy", "scaling"}
    if bad:
        raise cfgmod.ConfigError(f"--parts: unknown part(s) {sorted(bad)}; allowed: accuracy, scaling")
    summary = run_chart(args.chart, spec, progress=not args.json,
                        command="tiltpile bench --chart " + str(args.chart)
                        + (" --quick" if args.quick else "")
                        + (f" --parts {args.parts}" if args.parts else ""), parts=parts)
    if args.json:
        print(json.dumps(summary, default=float))
    else:
        print(f"wrote {', '.join(summary['files'])} to {args.chart} in "
              f"{summary['timings_s']['total']:.0f} s")
    return 0


def cmd_observables(args) -> int:
    from tiltpile.analysis import compute_observables

    d = Path(args.dir)
    if not d.is_dir():
        raise cfgmod.ConfigError(f"{d}: no such ensemble directory")
    table = compute_observables(d, workers=args.workers, progress=not args.quiet, force=args.force)
    if len(table) == 0:
        raise cfgmod.ConfigError(f"{d}: no run_*.h5 files to analyse")
    print(table.to_string(index=False))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="tiltpile", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("simulate", help="deposit and tilt one pile into a run file")
    _add_config_args(s)
    s.add_argument("--seed", type=_seed, required=True)
    s.add_argument("--out", required=True, help="run file to write (NAME.h5; NAME.h5.part while running)")
    s.add_argument("--force", action="store_true", help="overwrite an existing complete run file")
    s.add_argument("--no-resume", action="store_true", help="ignore an interrupted NAME.h5.part")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_simulate)

    b = sub.add_parser("bench", help="time NLGS steps on a settled pile")
    _add_config_args(b)
    b.set_defaults(preset="paper")
    b.add_argument("--n", type=int, default=4000, help="mobile grains (box length scales with n)")
    b.add_argument("--steps", type=int, default=200, help="steps to time")
    b.add_argument("--seed", type=_seed, default=0)
    b.add_argument("--json", action="store_true", help="print one JSON object")
    b.add_argument("--chart", type=Path, metavar="DIR",
                   help="measure the speed x accuracy chart instead (tolerance and time-step sweep, "
                        "Pareto plot, scaling in N) and write CSV, PNG and summary.json to DIR")
    b.add_argument("--quick", action="store_true", help="with --chart: a tiny pile, a few points")
    b.add_argument("--parts", default=None, help="with --chart: accuracy,scaling (default both)")
    b.set_defaults(func=cmd_bench)

    o = sub.add_parser("observables", help="compute (incrementally) the observables of an ensemble")
    o.add_argument("dir", help="ensemble directory holding run_*.h5")
    o.add_argument("--workers", type=int, default=None, help="processes (default: one per core)")
    o.add_argument("--force", action="store_true", help="recompute cached runs too")
    o.add_argument("--quiet", action="store_true", help="no progress bar")
    o.set_defaults(func=cmd_observables)

    from tiltpile.ensemble import add_parser as add_ensemble
    from tiltpile.report import add_parser as add_report
    add_ensemble(sub)
    add_report(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except cfgmod.ConfigError as e:
        print(f"tiltpile {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted; an unfinished run file stays as NAME.h5.part and resumes next time",
              file=sys.stderr)
        return 130
