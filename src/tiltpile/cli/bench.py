"""``tiltpile bench``: NLGS cost on a settled pile, or (``--chart DIR``) the speed x accuracy chart."""

from __future__ import annotations

import json
from pathlib import Path

from tiltpile.cli._common import ConfigError, add_config_args, resolve_preset, seed


def add_parser(sub) -> None:
    b = sub.add_parser("bench", help="time NLGS steps on a settled pile")
    add_config_args(b, default_preset="paper-fresh")
    b.add_argument("--n", type=int, default=4000, help="mobile grains (box length scales with n)")
    b.add_argument("--steps", type=int, default=200, help="steps to time")
    b.add_argument("--seed", type=seed, default=0, help="seed of the settled pile to time (cached in data/bench/)")
    b.add_argument("--json", action="store_true", help="print one JSON object")
    b.add_argument("--chart", type=Path, metavar="DIR",
                   help="measure the speed x accuracy chart instead (tolerance and time-step sweep, "
                        "Pareto plot, scaling in N) and write CSV, PNG and summary.json to DIR")
    b.add_argument("--quick", action="store_true", help="with --chart: a tiny pile, a few points")
    b.add_argument("--parts", default=None, help="with --chart: accuracy,scaling (default both)")
    b.set_defaults(func=run)


def run(args) -> int:
    if args.chart is not None:
        return _chart(args)
    if args.quick or args.parts:
        raise ConfigError("--quick and --parts only apply to --chart DIR")
    from tiltpile.bench.timing import print_result, time_pile

    resolve_preset(args, "bench")
    result = time_pile(n=args.n, steps=args.steps, preset=args.preset, config_file=args.config,
                       overrides=args.overrides, seed=args.seed, progress=not args.json)
    print_result(result, args.json)
    return 0


def _chart(args) -> int:
    """``bench --chart DIR``: the speed x accuracy chart (tiltpile.bench.chart)."""
    given = [name for name, value, default in (
        ("--n", args.n, 4000), ("--steps", args.steps, 200), ("--seed", args.seed, 0),
        ("--set", args.overrides, []), ("--config", args.config, None), ("--preset", args.preset, None))
        if value != default]
    if given:
        raise ConfigError(f"{', '.join(given)} do not apply to --chart (its scenes are fixed: "
                          "tiltpile.bench.chart.ChartSpec)")
    from tiltpile.bench.chart import ChartSpec, run_chart

    spec = ChartSpec.quick_spec() if args.quick else ChartSpec.full()
    parts = tuple(args.parts.split(",")) if args.parts else ("accuracy", "scaling")
    bad = set(parts) - {"accuracy", "scaling"}
    if bad:
        raise ConfigError(f"--parts: unknown part(s) {sorted(bad)}; allowed: accuracy, scaling")
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
