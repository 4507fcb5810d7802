"""The cost of the Contact Dynamics step on a settled pile of n grains.

The pile is :func:`benchmarks.pile.settled_pile` (cached). The timed part is ``steps`` steps
of the quasi-static tilt from theta = 0 at the preset's tilt rate, after 20 untimed steps that
bring the solver to the tilt tolerance. This is a measurement, not a test.

Reported (:func:`time_pile`): ``contacts`` (candidate contacts swept by the NLGS),
``active_contacts`` (f_n > 0), ``mean_iterations`` (NLGS sweeps per step), ``ms_per_step`` (wall
time of a whole step) and ``ns_per_contact_update`` (wall time / local solves made, i.e.
contacts x sweeps less those a pruned sweep leaves out: the cost of one local solve, everything
else in the step amortised into it).

Usage: ``python -m benchmarks.timing [--n 4000] [--steps 200] [--preset paper-fresh] [--seed 0]
[--json]``, from the repository's root. It says on stderr which preset it measures.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from tiltpile import config as cfgmod
from benchmarks.pile import bench_config, settled_pile
from tiltpile.sim.solver import C_PN


DEFAULT_PRESET = "paper-fresh"   # what a step costs on a pile of the paper's scale, fresh


def time_pile(n: int = 4000, steps: int = 200, preset: str = DEFAULT_PRESET, config_file=None,
              overrides=(), seed: int = 0, progress: bool = True) -> dict:
    """Time ``steps`` tilt steps of the bench pile of ``n`` grains (module docstring); returns a
    dict of the reported numbers plus n, preset, steps, tol, sweep and dt."""
    if steps < 1:
        raise cfgmod.ConfigError(f"--steps must be >= 1, got {steps}")
    cfg = bench_config(n, preset, config_file, overrides)
    sysm = settled_pile(cfg, seed, progress)  # solves to cfg.solver.tol (make_system)
    dth = cfg.protocol.tilt_per_step_deg
    sysm.advance(20, 0.0, dth)
    t0 = time.perf_counter()
    rec = sysm.advance(steps, 20 * dth, dth)
    wall = time.perf_counter() - t0
    contacts = int(sysm.ci.shape[0])
    return dict(n=n, preset=preset, steps=steps, contacts=contacts,
                active_contacts=int((sysm.c[:, C_PN] > 0).sum()),
                mean_iterations=float(rec.iterations.mean()), ms_per_step=1e3 * wall / steps,
                ns_per_contact_update=1e9 * wall / max(1, int(rec.updates.sum())),
                tol=cfg.solver.tol, sweep=cfg.solver.sweep, dt=cfg.solver.dt)


def print_result(result: dict, as_json: bool) -> None:
    """One JSON object, or one ``name: value`` line per number."""
    if as_json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:>24}: {v}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.timing", description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=4000, help="mobile grains (box length scales with n)")
    ap.add_argument("--steps", type=int, default=200, help="steps to time")
    ap.add_argument("--preset", choices=cfgmod.PRESETS, default=None,
                    help=f"base configuration of the pile (default: {DEFAULT_PRESET})")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                    help="override one configuration key of the preset (repeatable)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the settled pile (cached in data/bench/)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    a = ap.parse_args(argv)
    preset = a.preset or DEFAULT_PRESET
    print(f"{ap.prog}: preset {preset}" + (" (the default; --preset to choose)" if a.preset is None else ""),
          file=sys.stderr)
    try:
        result = time_pile(n=a.n, steps=a.steps, preset=preset, overrides=a.overrides, seed=a.seed,
                           progress=not a.json)
    except cfgmod.ConfigError as e:
        print(f"{ap.prog}: error: {e}", file=sys.stderr)
        return 2
    print_result(result, a.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
