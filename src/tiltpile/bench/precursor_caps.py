"""Is the motion between precursor events physics or the unconverged NLGS iterate?

Usage: python -m tiltpile.bench.precursor_caps RUN --frames F [F ...] [--steps S] [--warm W]
                                              [--caps K [K ...]] [--json OUT]
  RUN     a run file (``tiltpile simulate``); FRAMES frame indices in the precursor regime
          (paper preset: frame 100 = 5 deg, a frame every 0.05 deg)
  --steps tilt steps after each frame (default 500 = 10 frames of the paper preset)
  --warm  steps at max_iter 20 000 that rebuild the impulses (``flow_caps.rebuilt_state``; default 10)
  --caps  iteration caps to compare (default 300 1000 5000); the largest is the reference

From each frame's rebuilt state, every cap tilts the same ``S`` steps at the run's rate. A
*sub-frame* is every ``frame_every`` steps (the run's frame spacing). Per (frame, cap): the
kinetic energy per mobile grain at the sub-frames (mean, median), the fraction of sub-frames
*at rest* (below ``REST_KE`` per grain, the floor the soft-sphere comparison used), the
sub-frames losing more than 2% of their active contacts (the paper's avalanche criterion), the
mean displacement of the mobile grains over the S steps, its distance from the reference's end
positions, the fraction of steps at the cap and the time per step.

If the reference comes to rest where a lower cap keeps moving, the motion between events is made
by the cap, not by the pile. ``docs/performance-log.md`` records what it measured.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from tiltpile.analysis.contacts import lost_contacts
from tiltpile.bench.flow_caps import rebuilt_state
from tiltpile.sim import protocol

REST_KE = 1e-6   # [m g d] per grain: "at rest"
CUTOFF = 0.02    # the paper's lost-contact fraction of an avalanching frame


def _active(s):
    pair, force, _ = s.contacts()
    return pair, force[:, 0] > 0


def continue_tilt(cfg, seed: int, theta: float, state: dict, steps: int, cap: int) -> dict:
    """Tilt ``steps`` steps from ``state`` at ``cap`` sweeps; per-sub-frame series and totals."""
    s = protocol.make_system(cfg, seed)
    s.restore(state)
    s.params.update(max_iter=cap)
    every, dth = cfg.protocol.frame_every, cfg.protocol.tilt_per_step_deg
    mob = ~s.fixed
    n_mob = int(mob.sum())
    p0 = s.pos.copy()
    prev = _active(s)
    ke, lost, sweeps, caps = [], [], [], 0
    wall = 0.0
    done = 0
    while done < steps:
        k = min(every, steps - done)
        t0 = time.perf_counter()
        rec = s.advance(k, theta + done * dth, dth)
        wall += time.perf_counter() - t0
        done += k
        sweeps.append(rec.iterations)
        caps += int((rec.iterations >= cap).sum())
        ke.append(s.kinetic_energy() / n_mob)
        cur = _active(s)
        n_act = int(prev[1].sum())
        n_lost = int(lost_contacts(prev[0], prev[1], cur[0], cur[1], s.n).sum())
        lost.append(n_lost / n_act if n_act else np.nan)
        prev = cur
    ke, lost = np.array(ke), np.array(lost)
    return dict(cap=cap, ke=ke, lost=lost, ke_mean=float(ke.mean()), ke_median=float(np.median(ke)),
                rest_fraction=float((ke < REST_KE).mean()),
                avalanching=int((lost > CUTOFF).sum()), lost_max=float(np.nanmax(lost)),
                disp=float(np.hypot(*(s.pos - p0)[mob].T).mean()), end_pos=s.pos.copy(),
                cap_fraction=caps / steps, sweeps_mean=float(np.concatenate(sweeps).mean()),
                ms_per_step=1e3 * wall / steps)


def study(run_path, frames, steps: int, caps, warm: int = 10, out=sys.stdout) -> list[dict]:
    """One row per (frame, cap) (module docstring), the largest cap as each frame's reference."""
    caps = sorted({int(k) for k in caps})
    rows, mob = [], None
    for f in frames:
        cfg, seed, theta, state = rebuilt_state(run_path, f, warm)
        if mob is None:  # the same pile at every frame
            mob = ~protocol.make_system(cfg, seed).fixed
        res = {k: continue_tilt(cfg, seed, theta, state, steps, k) for k in caps[::-1]}
        ref_pos = res[caps[-1]]["end_pos"]
        for k in caps:
            r = res[k]
            dist = float(np.hypot(*(r.pop("end_pos") - ref_pos)[mob].T).mean())
            row = dict(frame=int(f), theta=theta, steps=steps, dist_to_ref=dist,
                       **{key: v for key, v in r.items() if key not in ("ke", "lost")},
                       ke_series=r["ke"].tolist(), lost_series=r["lost"].tolist())
            rows.append(row)
            print(f"frame {f:4d} ({theta:5.2f} deg) cap {k:6d}: ke mean {row['ke_mean']:.2e} "
                  f"median {row['ke_median']:.2e} rest {row['rest_fraction']:.2f} "
                  f"aval {row['avalanching']:2d} lost max {row['lost_max']:.3f} disp {row['disp']:.2e} d "
                  f"|x - x_ref| {dist:.1e} d, capped {row['cap_fraction']:.2f}, "
                  f"{row['sweeps_mean']:.0f} sweeps, {row['ms_per_step']:.1f} ms/step",
                  file=out, flush=True)
    return rows


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(prog="python -m tiltpile.bench.precursor_caps",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("run")
    ap.add_argument("--frames", type=int, nargs="+", required=True)
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--warm", type=int, default=10)
    ap.add_argument("--caps", type=int, nargs="+", default=[300, 1000, 5000])
    ap.add_argument("--json", help="write the rows (with the per-sub-frame series) to this file")
    a = ap.parse_args(argv)
    if a.steps < 1 or a.warm < 0 or min(a.caps) < 1 or len(set(a.caps)) < 2 or min(a.frames) < 0:
        ap.error("--steps >= 1, --warm >= 0, frames >= 0 and at least two different caps >= 1")
    rows = study(a.run, a.frames, a.steps, a.caps, a.warm)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(dict(run=str(a.run), steps=a.steps, warm=a.warm, caps=sorted(set(a.caps)),
                           rest_ke=REST_KE, rows=rows), fh, indent=1)
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
