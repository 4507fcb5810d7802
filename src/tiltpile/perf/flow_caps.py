"""The iteration cap in a flowing pile: cost and error of NLGS settings from one frame of a run.

Usage: python -m tiltpile.perf.flow_caps RUN FRAME STEPS [--warm W] [variant ...]
  RUN    a run file (``tiltpile simulate``); FRAME its frame index, e.g. 340 = 17 deg in the
         paper preset (a frame every 0.05 deg)
  STEPS  steps per variant
  --warm W  steps at max_iter 20 000 before the variants (default 10): a frame stores
         positions and velocities but not the impulses, which these steps rebuild
  variant = max_iter[:relax[:prune]], e.g. 20000 1000 300:1.5 1000:1:1 (prune 0 or 1; default:
         the run's solver.prune), default 20000 1000 500 300 200 100

The state is rebuilt with the run's own configuration: the pile of its seed, the frame's
positions, rotations and velocities, a fresh contact list; then W steps that end at the frame's
angle. Every variant starts from that same state and tilts STEPS steps at the run's rate, in one
process. Per variant: ms per step, the median natural residual of the steps'
end states (solver.natural_residual), the mean kinetic energy per grain, the mean displacement
of the mobile grains over the STEPS steps and its change against the first variant, and the
mean distance between their final positions and those of the first variant.
README "Speed and accuracy" lists what it measured on the paper run.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from tiltpile import config as cfgmod
from tiltpile.sim import protocol
from tiltpile.sim.solver import natural_residual
from tiltpile.store import open_run

DEFAULT_VARIANTS = ("20000", "1000", "500", "300", "200", "100")


def rebuilt_state(run_path, frame: int, warm: int):
    """(config, seed, theta [deg], state) of ``frame`` of a run, its impulses rebuilt by
    ``warm`` steps at max_iter 20 000 ending at the frame's angle."""
    with open_run(run_path) as r:
        cfg = cfgmod.from_dict(r.config)
        seed = r.seed
        theta = float(r.theta_deg[frame])
        s = protocol.make_system(cfg, seed)
        s.pos[:] = r.position(frame)
        s.rot[:] = r.rotation(frame)
        s.vel[: s.n, :2] = r.velocity(frame)
        s.vel[: s.n, 2] = r.omega(frame) * s.radius
    dth = cfg.protocol.tilt_per_step_deg
    s.params.update(max_iter=20_000)
    s.advance(warm, theta - warm * dth, dth)
    return cfg, seed, theta, s.state()


def measure(cfg, seed: int, theta, state, steps: int, variants) -> list[dict]:
    """One row per variant (module docstring), every one from ``state``."""
    s = protocol.make_system(cfg, seed)
    dth = cfg.protocol.tilt_per_step_deg
    mob = ~s.fixed
    rows, ref = [], None
    for spec in variants:
        parts = spec.split(":")
        cap, relax = int(parts[0]), float(parts[1]) if len(parts) > 1 else 1.0
        prune = bool(int(parts[2])) if len(parts) > 2 else cfg.solver.prune
        s.restore(state)
        s.params.update(max_iter=cap, relax=relax, prune=prune)
        p0 = s.pos.copy()
        ke, nat, wall = [], [], 0.0
        for k in range(steps):
            t0 = time.perf_counter()
            s.advance(1, theta + k * dth, dth)
            wall += time.perf_counter() - t0
            ke.append(s.kinetic_energy() / int(mob.sum()))
            nat.append(natural_residual(s.ci, s.cj, s.c, s.vel))
        disp = float(np.hypot(*(s.pos - p0)[mob].T).mean())
        if ref is None:
            ref = (disp, s.pos.copy())
        rows.append(dict(variant=spec, ms_per_step=1e3 * wall / steps,
                         natural_residual=float(np.median(nat)), ke=float(np.mean(ke)), disp=disp,
                         disp_change=disp / ref[0] - 1.0 if ref[0] > 0 else np.nan,
                         pos_distance=float(np.hypot(*(s.pos - ref[1])[mob].T).mean())))
    return rows


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(prog="python -m tiltpile.perf.flow_caps",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("run")
    ap.add_argument("frame", type=int)
    ap.add_argument("steps", type=int)
    ap.add_argument("--warm", type=int, default=10)
    ap.add_argument("variants", nargs="*", default=list(DEFAULT_VARIANTS))
    a = ap.parse_intermixed_args(argv)
    if a.steps < 1 or a.warm < 0:
        ap.error("steps must be >= 1 and --warm >= 0")
    cfg, seed, theta, state = rebuilt_state(a.run, a.frame, a.warm)
    print(f"{a.run} frame {a.frame} theta {theta:.2f} deg, {a.steps} steps per variant")
    print(f"{'variant':>12s} {'ms/step':>8s} {'nat.res.':>9s} {'ke/grain':>9s} {'disp [d]':>9s} "
          f"{'change':>7s} {'|pos-pos0|':>10s}")
    rows = measure(cfg, seed, theta, state, a.steps, a.variants)
    for r in rows:
        print(f"{r['variant']:>12s} {r['ms_per_step']:8.1f} {r['natural_residual']:9.1e} "
              f"{r['ke']:9.2e} {r['disp']:9.3e} {100 * r['disp_change']:+6.1f}% "
              f"{r['pos_distance']:10.1e}", flush=True)
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
