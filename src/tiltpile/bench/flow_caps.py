"""The iteration cap in a flowing pile: cost and error of NLGS settings from one frame of a run.

Usage: python -m tiltpile.bench.flow_caps RUN FRAME STEPS [--warm W] [variant ...]
       python -m tiltpile.bench.flow_caps RUN FRAME --one-step [--warm W] [max_iter ...]
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

``--one-step``: how far one step's solve is from converged after a given number of sweeps.
From the same state, one step at each max_iter (default 20000 5000 2000 1000 500 300 200 100;
the largest is the reference); per cap: the sweeps made, the natural residual, and the distance
of the end-of-step velocities and impulses from the reference's (rms over the mobile grains and
over the contacts, relative to the reference's rms), the largest difference of a velocity
component times dt (the position error the step leaves) and the contacts whose state (open,
sticking, sliding) differs. The contact list is the same for every cap: a rebuild is decided
before the solve (checked).

docs/performance-log.md ("Speed and accuracy") records what it measured on the paper run.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from tiltpile import config as cfgmod
from tiltpile.sim import protocol
from tiltpile.sim.solver import IMPULSE, natural_residual
from tiltpile.store import open_run

DEFAULT_VARIANTS = ("20000", "1000", "500", "300", "200", "100")
DEFAULT_ONE_STEP = ("20000", "5000", "2000", "1000", "500", "300", "200", "100")


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


def one_step(cfg, seed: int, theta, state, caps) -> list[dict]:
    """One row per cap (module docstring, ``--one-step``), against the largest cap."""
    caps = sorted({int(k) for k in caps}, reverse=True)
    s = protocol.make_system(cfg, seed)
    mob = ~s.fixed
    ends = []
    for cap in caps:
        s.restore(state)
        s.params.update(max_iter=cap)
        rec = s.advance(1, theta, cfg.protocol.tilt_per_step_deg)
        if ends and not np.array_equal(s.key, ends[0][-1]):
            raise RuntimeError(f"max_iter {cap} ends on another contact list than {caps[0]}")
        ends.append((cap, int(rec.iterations[0]), natural_residual(s.ci, s.cj, s.c, s.vel),
                     s.vel[: s.n][mob, :3].copy(), s.c[:, IMPULSE].copy(), s.status.copy(),
                     s.key.copy()))
    v_ref, p_ref, st_ref = ends[0][3:6]

    def rms(x):
        return float(np.sqrt(np.mean(x * x)))

    rows = []
    for cap, sweeps, nat, v, p, st, _ in ends:
        dv = v - v_ref
        rows.append(dict(max_iter=cap, sweeps=sweeps, natural_residual=nat,
                         dv_rel=rms(dv[:, :2]) / rms(v_ref[:, :2]),
                         dx_max=float(np.abs(dv[:, :2]).max()) * cfg.solver.dt,
                         dp_rel=rms(p - p_ref) / rms(p_ref), status_changed=int((st != st_ref).sum())))
    return rows


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(prog="python -m tiltpile.bench.flow_caps",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("run")
    ap.add_argument("frame", type=int)
    ap.add_argument("steps", type=int, nargs="?")
    ap.add_argument("--warm", type=int, default=10)
    ap.add_argument("--one-step", action="store_true",
                    help="one step at each max_iter given, against the largest")
    ap.add_argument("variants", nargs="*")
    a = ap.parse_intermixed_args(argv)
    if a.one_step:
        if a.steps is not None:  # argparse fills the optional positional first
            a.variants.insert(0, str(a.steps))
        caps = a.variants or list(DEFAULT_ONE_STEP)
        if a.warm < 0 or not all(k.isdigit() and int(k) >= 1 for k in caps) or len(set(caps)) < 2:
            ap.error("--one-step needs --warm >= 0 and at least two different max_iter >= 1")
        cfg, seed, theta, state = rebuilt_state(a.run, a.frame, a.warm)
        print(f"{a.run} frame {a.frame} theta {theta:.2f} deg, one step per max_iter")
        print(f"{'max_iter':>8s} {'sweeps':>6s} {'nat.res.':>9s} {'|dv|/|v|':>9s} {'max dv dt':>9s} "
              f"{'|dp|/|p|':>9s} {'states':>6s}")
        rows = one_step(cfg, seed, theta, state, caps)
        for r in rows:
            print(f"{r['max_iter']:8d} {r['sweeps']:6d} {r['natural_residual']:9.1e} {r['dv_rel']:9.2e} "
                  f"{r['dx_max']:9.1e} {r['dp_rel']:9.2e} {r['status_changed']:6d}", flush=True)
        return rows
    if a.steps is None or a.steps < 1 or a.warm < 0:
        ap.error("steps must be >= 1 and --warm >= 0")
    a.variants = a.variants or list(DEFAULT_VARIANTS)
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
