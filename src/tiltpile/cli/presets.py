"""``tiltpile presets [--scale S] [--history H] [--engine E] [--name | --json | --make]``: the
presets as three axes (``config.PRESET_AXES``), one preset per triple: the named ones
(``config.PRESET_TABLE``, aliases of their triples) and the others under their systematic names
(``config.systematic_name``, ``<scale>[-<history>][-dem]``).

Without an axis: a table of every preset (scale, history, engine, grains, the steps a run tilts,
runs and figures directory of its ``make figures``, its measured cost per run where committed
figures hold it: ``report.blocks.preset_axes``). With one or more axes: the preset of that triple,
an axis left out taking its default (scale ``default``, the scale's own history, engine ``cd``);
``--name`` prints its name alone. An axis value off its axis is refused in one line naming the
axis's values, exit status 2.

The Makefile reads the presets with ``python -m tiltpile.cli.presets`` (``--make``: every preset's
``name:runs:report`` on one line; ``--name`` for ``SCALE=``/``HISTORY=``/``ENGINE=``): run so, this
module needs the standard library alone (it imports ``tiltpile.config``, and ``tiltpile.report``
only for the table), so make reads the presets before ``make setup`` has built the venv.
"""

from __future__ import annotations

import argparse
import json
import sys

from tiltpile import config as cfgmod


def _options(p: argparse.ArgumentParser) -> None:
    axes = cfgmod.PRESET_AXES
    p.add_argument("--scale", metavar="S",
                   help=f"the scale: {', '.join(axes['scale'])} (default: default)")
    p.add_argument("--history", metavar="H",
                   help=f"the history: {', '.join(axes['history'])} (default: the scale's own)")
    p.add_argument("--engine", metavar="E", help=f"the engine: {', '.join(axes['engine'])} (default: cd)")
    out = p.add_mutually_exclusive_group()
    out.add_argument("--name", action="store_true",
                     help="print the preset's name alone (without an axis: every preset's, one a line)")
    out.add_argument("--json", action="store_true", help="print the rows as JSON")
    out.add_argument("--make", action="store_true",
                     help="what the Makefile reads: every preset's name:runs:report on one line")
    p.add_argument("--root", default="figures",
                   help="the committed figures, for the measured costs (default figures)")


def add_parser(sub) -> None:
    p = sub.add_parser("presets", help="the presets: scale x history x engine, and what each costs",
                       description="Every preset is one scale, one history and one engine. "
                                   "Without an axis, a table of them all; with --scale, --history "
                                   "or --engine, the preset of that triple (docs/presets.md).")
    _options(p)
    p.set_defaults(func=run)


def _chosen(args) -> tuple[cfgmod.Preset, ...]:
    if args.scale is None and args.history is None and args.engine is None:
        return cfgmod.ALL_PRESETS
    return (cfgmod.preset_of_axes(args.scale, args.history, args.engine),)


def _cost(r: dict) -> str:
    parts = ([f"{r['sweeps'] / 1e6:.1f} M sweeps"] if r["sweeps"] else []) + \
            ([f"{r['dem_steps'] / 1e6:.1f} M DEM steps"] if r["dem_steps"] else []) + \
            ([f"{r['hours']:.2g} h"] if r["hours"] else [])
    return ", ".join(parts) or ("not measured" if r["alias"] else "not run")


def _table(rows: list[dict]) -> str:
    head = ("preset", "scale", "history", "engine", "grains", "steps (history + ramp)", "runs",
            "figures", "cost a run", "for")
    body = [(r["name"], r["scale"], r["history"], r["engine"], str(r["grains"]),
             f"{r['steps_history']} + {r['steps_ramp']}", str(r["runs"]), r["figures"], _cost(r),
             r["use"] or "-") for r in rows]
    widths = [max(len(c[i]) for c in [head, *body]) for i in range(len(head))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(cells, widths)).rstrip()
                     for cells in [head, *body])


def run(args) -> int:
    chosen = _chosen(args)
    if args.make:
        print(" ".join(f"{p.name}:{p.runs}:{p.report}" for p in cfgmod.ALL_PRESETS))
        return 0
    if args.name:
        print("\n".join(p.name for p in chosen))
        return 0
    from tiltpile.report.blocks import preset_axes

    names = {p.name for p in chosen}
    rows = [r for r in preset_axes(args.root) if r["name"] in names]
    print(json.dumps(rows, indent=1) if args.json else _table(rows))
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m tiltpile.cli.presets ARGS``: this command alone, without the others' imports
    (what the Makefile runs); a refused value is one line on stderr, exit status 2."""
    p = argparse.ArgumentParser(prog="tiltpile presets",
                                description="the presets: scale x history x engine")
    _options(p)
    args = p.parse_args(argv)
    try:
        return run(args)
    except cfgmod.ConfigError as e:
        print(f"tiltpile presets: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
