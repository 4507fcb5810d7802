"""Sweeps per step, cost and true error of NLGS variants on a settled bench pile while tilting.

Usage: python -m benchmarks.solver_variants N STEPS [EVAL_EVERY] [variant ...]
  variant = sweep:relax[:tol[:slop]], e.g. random:1  forward:1.6  forward:1.6:3e-7
  random:1:1e-6:0 (plain random NLGS with the plain gap term: the speed reference)
  pile_slop=S (anywhere among the variants): deposit the pile with solver.overlap_slop = S
  (default: the preset's). Compare schemes on piles deposited with their own slop: a pile
  deposited with the slop holds overlaps up to 1e-6 d, which slop 0 then pushes out at once.
All variants start from the same state (the cached bench pile of data/bench, tilted 20 steps with
the plain forward sweep) and run STEPS steps of the tilt at 0.001 deg/step, in one process.
Per step: NLGS sweeps, wall time; every EVAL_EVERY steps the true error of the step's end state:
  nat    natural residual (solver.natural_residual: one Jacobi pass of exact local solves, relative
         L2 change it would make), independent of sweep order and relaxation;
  dv     force imbalance per mobile grain relative to its weight: max over grains of |v - v_ref| /
         (g dt), where v_ref is reached from the step's end state by 4000 further plain forward
         sweeps (tol 1e-13): the unbalanced force the solver left, in units of m g (rms also given);
  dp     relative L2 change of the impulses over those further sweeps;
  drift  median displacement of the mobile grains over the STEPS steps, per degree of tilt [d/deg]
         (a rigid pile below its failure angle should not move at all).
"""
from __future__ import annotations

import sys
import time

import numpy as np

DEFAULT_VARIANTS = ("random:1", "forward:1", "alternating:1", "forward:1.3", "forward:1.5", "forward:1.7",
                    "forward:1.8", "random:1.5", "random:1.7")


def main(argv: list[str] | None = None) -> int:
    """Parse ``N STEPS [EVAL_EVERY] [variant ...]`` (module docstring), measure, print one row per variant."""
    from benchmarks import pile as bench
    from tiltpile.sim import solver

    argv = sys.argv[1:] if argv is None else list(argv)
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    n, steps = int(argv[0]), int(argv[1])
    every = int(argv[2]) if len(argv) > 2 else 1
    rest = argv[3:]
    pile_over = [f"solver.overlap_slop={a.split('=')[1]}" for a in rest if a.startswith("pile_slop=")]
    specs = [a for a in rest if not a.startswith("pile_slop=")] or list(DEFAULT_VARIANTS)
    cfg = bench.bench_config(n, overrides=pile_over)
    s = bench.settled_pile(cfg, 0, progress=False)  # the cached pile of exactly this config
    dth = cfg.protocol.tilt_per_step_deg
    dt = cfg.solver.dt
    s.params.update(mode=solver.FORWARD, relax=1.0)
    s.advance(20, 0.0, dth)
    start = s.state()
    mob = s.vel[: s.n, 3] > 0
    print(f"n={n} contacts={s.ci.shape[0]} steps={steps} tol={cfg.solver.tol} max_iter={cfg.solver.max_iter}")
    print(f"{'variant':18s} {'sweeps/step':>11s} {'ms/step':>8s} {'ns/upd':>7s} {'nat':>8s} {'dv_max':>8s} "
          f"{'dv_rms':>8s} {'dp':>8s} {'capped':>6s} {'drift':>8s}")
    for spec in specs:
        parts = spec.split(":")
        mode = solver.SWEEPS[parts[0]]
        relax = float(parts[1])
        tol = float(parts[2]) if len(parts) > 2 else cfg.solver.tol
        slop = float(parts[3]) if len(parts) > 3 else cfg.solver.overlap_slop
        s.restore(start)
        s.params.update(mode=mode, relax=relax, tol=tol, slop=slop)
        its, wall, upd, nat, dvm, dvr, dps = [], 0.0, 0, [], [], [], []
        pos0 = s.pos.copy()
        for k in range(steps):
            t0 = time.perf_counter()
            rec = s.advance(1, (20 + k) * dth, dth)
            w = time.perf_counter() - t0
            wall += w
            its.append(int(rec.iterations[0]))
            upd += int(rec.updates[0])
            if (k + 1) % every == 0:
                nat.append(solver.natural_residual(s.ci, s.cj, s.c, s.vel))
                c = s.c.copy(); vel = s.vel.copy()
                solver.nlgs(s.ci, s.cj, c, s.status.copy(), vel, 1e-13, 4000, solver.FORWARD, s.rng.copy(),
                            np.empty(s.ci.shape[0], np.int64), 1.0)
                dv = np.hypot(vel[: s.n, 0] - s.vel[: s.n, 0], vel[: s.n, 1] - s.vel[: s.n, 1])[mob] / dt
                dvm.append(dv.max()); dvr.append(np.sqrt(np.mean(dv ** 2)))
                dps.append(np.sqrt(np.sum((c[:, solver.IMPULSE] - s.c[:, solver.IMPULSE]) ** 2) / np.sum(c[:, solver.IMPULSE] ** 2)))
        its = np.array(its)
        print(f"{spec:18s} {its.mean():8.1f} ({np.median(its):5.0f}) {1e3 * wall / steps:8.2f} {1e9 * wall / upd:7.2f} "
              f"{np.median(nat):8.1e} {np.median(dvm):8.1e} {np.median(dvr):8.1e} {np.median(dps):8.1e} "
              f"{int((its >= cfg.solver.max_iter).sum()):6d} "
              f"{np.median(np.hypot(*(s.pos - pos0)[mob].T)) / (steps * dth):8.1e}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
