"""Part 3 of the chart: cost per step against the number of grains (``scaling.csv``), on settled
piles tiled side by side (:func:`tile`) at fixed depth; the columns are
:data:`~benchmarks.chart.spec.SCALING_COLUMNS`, the fit :func:`scaling_fit`."""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from tiltpile import config as cfgmod
from benchmarks.chart.spec import SCALING_COLUMNS, ChartSpec, log, starting_pile
from tiltpile.sim import solver
from tiltpile.sim.step import System


def tile(sysm: System, copies: int) -> System:
    """``copies`` copies of a settled pile side by side in a box ``copies`` times wider.

    Grain i of copy m gets id i * copies + m (ids stay ordered by height as in the original);
    positions, rotations and velocities are copied, contacts are rebuilt on the first step.
    """
    n = sysm.n
    L = sysm.params["box_length"]
    k = int(copies)
    idx = np.arange(n * k)
    orig, m = idx // k, idx % k
    pos = sysm.pos[orig].copy()
    # odd copies mirrored (x -> L - x): each seam joins a pile to its mirror image, so grains that
    # leaned on a side wall now lean on their mirror twin (plain copies leave ragged seams that
    # kept rearranging: every step at max_iter after 300 settling steps)
    odd = m % 2 == 1
    pos[odd, 0] = L - pos[odd, 0]
    pos[:, 0] += m * L
    p = sysm.params
    out = System(sysm.radius[orig], sysm.fixed[orig], pos, sysm.vel[orig, 3], sysm.rng.copy(),
                 box_length=k * L, dt=p["dt"], alert=p["alert"], mu=p["mu"], mu_wall=p["mu_wall"],
                 tol=p["tol"], max_iter=p["max_iter"], mode=p["mode"])
    # every other parameter as the original's (listing them one by one once dropped the slop)
    out.params = dict(p, box_length=k * L)
    out.rot[:] = np.where(odd, -1.0, 1.0) * sysm.rot[orig]
    vel = sysm.vel[orig, :3].copy()
    vel[odd, 0] *= -1.0
    vel[odd, 2] *= -1.0
    out.vel[: n * k, :3] = vel
    out.scalars = {}
    return out


def _time_steps(sysm: System, steps: int, theta0: float, dth: float) -> dict:
    """Time ``steps`` single steps: the table's columns, plus ``walls`` (each step's seconds) and
    ``updates`` (contact updates) for pooling several calls."""
    walls, its, upd = [], [], 0
    for k in range(steps):
        t0 = time.perf_counter()
        rec = sysm.advance(1, theta0 + k * dth, dth)
        walls.append(time.perf_counter() - t0)
        its.append(int(rec.iterations[0]))
        upd += int(rec.updates[0])
    walls, its = np.array(walls), np.array(its)
    return dict(steps=steps, contacts=int(sysm.ci.shape[0]),
                active_contacts=int((sysm.c[:, solver.C_PN] > 0).sum()),
                ms_per_step=1e3 * float(np.median(walls)), ms_per_step_mean=1e3 * float(walls.mean()),
                ns_per_update=1e9 * float(walls.sum()) / max(1, upd),
                sweeps_mean=float(its.mean()), sweeps_median=float(np.median(its)),
                cap_hits=int((its >= sysm.params["max_iter"]).sum()), updates=upd, walls=walls)


def scaling_sweep(spec: ChartSpec, progress: bool = True) -> pd.DataFrame:
    from benchmarks.pile import bench_config

    cfg = bench_config(spec.base_n)
    if spec.quick:
        cfg = cfgmod.load("smoke", None, [*spec.scene])
    t0 = time.perf_counter()
    base = starting_pile(cfg, 0, spec.cache)
    log(f"[scaling] base pile of {spec.base_n} grains ({cfg.scene.box_length:g} d box) ready in "
         f"{time.perf_counter() - t0:.1f} s", progress)
    dth = cfg.protocol.tilt_per_step_deg
    rows, fixed_jobs = [], []
    for k in spec.copies:
        t1 = time.perf_counter()
        s = tile(base, k)
        n = spec.base_n * k
        s.params.update(tol=1e-4, mode=solver.FORWARD, relax=1.0)
        s.advance(spec.tile_settle_steps, 0.0, 0.0)
        s.params.update(tol=spec.scaling_tol)
        s.advance(20, 0.0, dth)
        settle = time.perf_counter() - t1
        start = s.state()
        slop = cfg.solver.overlap_slop
        sweep0 = cfg.solver.sweep  # the default sweep: the scaling line, and the fixed sweeps
        variants = [(sweep0, 1.0, slop)]
        if n in spec.variant_ns:
            variants += [v for v in (("forward", 1.0, slop), ("random", 1.0, 0.0), ("forward", 1.0, 0.0),
                                     ("forward", 1.5, slop)) if v != variants[0]]
        for sweep, relax, sl in variants:
            s.restore(start)
            s.params.update(mode=solver.SWEEPS[sweep], relax=relax, slop=sl)
            steps = spec.scaling_steps if n <= 4000 else spec.scaling_steps_large
            if (sweep, relax, sl) != variants[0]:
                steps = min(steps, spec.variant_steps)
            r = dict(n=n, copies=k, box_length=s.params["box_length"], sweep=sweep, relax=relax,
                     slop=sl, tol=spec.scaling_tol, settle_s=settle, fixed_sweeps=0)
            r.update(_time_steps(s, steps, 20 * dth, dth))
            rows.append(r)
            log(f"[scaling] n {n} {sweep} relax {relax:g} slop {sl:g}: {r['ms_per_step']:.1f} ms/step, "
                 f"{r['sweeps_mean']:.0f} sweeps/step, {r['ns_per_update']:.1f} ns/update, "
                 f"{r['contacts']} contacts", progress)
        fixed_jobs.append((k, n, s, start, settle))
    # the cost of a step at a fixed number of sweeps (tol 0: never converged, exactly
    # fixed_sweeps sweeps): valid whether or not the tiled pile has settled, and the part of the
    # cost per step that must be linear in N; sweeps per step are measured above. fixed_rounds
    # rounds, each timing every N in turn from its same start state; the median over all steps.
    rounds = {n: [] for _, n, *_ in fixed_jobs}
    for _ in range(spec.fixed_rounds):
        for k, n, s, start, settle in fixed_jobs:
            s.restore(start)
            s.params.update(mode=solver.SWEEPS[cfg.solver.sweep], relax=1.0, slop=cfg.solver.overlap_slop,
                            tol=0.0, max_iter=spec.fixed_sweeps)
            rounds[n].append(_time_steps(s, spec.fixed_steps, 20 * dth, dth))
    for k, n, s, start, settle in fixed_jobs:
        rs = rounds[n]
        w = np.concatenate([x["walls"] for x in rs])
        r = dict(n=n, copies=k, box_length=s.params["box_length"], sweep=cfg.solver.sweep, relax=1.0,
                 slop=cfg.solver.overlap_slop, tol=0.0, settle_s=settle, fixed_sweeps=spec.fixed_sweeps)
        r.update(rs[-1], steps=int(w.size), ms_per_step=1e3 * float(np.median(w)),
                 ms_per_step_mean=1e3 * float(w.mean()),
                 ns_per_update=1e9 * float(w.sum()) / max(1, sum(x["updates"] for x in rs)),
                 sweeps_mean=float(np.mean([x["sweeps_mean"] for x in rs])),
                 cap_hits=sum(x["cap_hits"] for x in rs))
        rows.append(r)
        log(f"[scaling] n {n} {cfg.solver.sweep}, {spec.fixed_sweeps} sweeps fixed ({spec.fixed_rounds} rounds): "
             f"{r['ms_per_step']:.1f} ms/step, {r['ns_per_update']:.1f} ns/update", progress)
    return pd.DataFrame(rows)[SCALING_COLUMNS]


def scaling_fit(df: pd.DataFrame) -> dict:
    fixed = df[df["fixed_sweeps"] > 0].sort_values("n")
    sweep0 = fixed["sweep"].iloc[0] if len(fixed) else "forward"  # the default sweep of the chart
    out = _linear_fit(df[(df["sweep"] == sweep0) & (df["relax"] == 1.0) & (df["slop"] > 0)
                         & (df["fixed_sweeps"] == 0)])
    out["sweep"] = sweep0
    if len(fixed) >= 2:
        f = _linear_fit(fixed)
        out["fixed_sweeps"] = {k: f[k] for k in f if k in (
            "n", "ms_per_step", "ms_per_grain_origin_fit", "loglog_slope",
            "cost_per_grain_max_over_min_1000_up", "loglog_slope_1000_up", "ratio_to_line")}
        out["fixed_sweeps"]["sweeps"] = int(fixed["fixed_sweeps"].iloc[0])
    return out


def _linear_fit(d: pd.DataFrame) -> dict:
    d = d.sort_values("n")
    n = d["n"].to_numpy(float)
    ms = d["ms_per_step"].to_numpy(float)
    out = {"n": n.tolist(), "ms_per_step": ms.tolist()}
    if n.size >= 2:
        a = float(np.sum(n * ms) / np.sum(n * n))
        slope, icpt = np.polyfit(np.log(n), np.log(ms), 1)
        big = n >= 1000
        out.update(ms_per_grain_origin_fit=a, loglog_slope=float(slope),
                   loglog_prefactor=float(math.exp(icpt)),
                   ratio_to_line=(ms / (a * n)).tolist())
        if big.sum() >= 2:
            # the target: cost per step within 1.3x of linear in N from 1000 to 16000 grains
            per = ms[big] / n[big]
            out["cost_per_grain_max_over_min_1000_up"] = float(per.max() / per.min())
            s2, _ = np.polyfit(np.log(n[big]), np.log(ms[big]), 1)
            out["loglog_slope_1000_up"] = float(s2)
        ns = d["ns_per_update"].to_numpy(float)
        sw = d["sweeps_mean"].to_numpy(float)
        out["ns_per_update"] = ns.tolist()
        out["sweeps_mean"] = sw.tolist()
        out["loglog_slope_sweeps"] = float(np.polyfit(np.log(n), np.log(sw), 1)[0])
        out["loglog_slope_ns_per_update"] = float(np.polyfit(np.log(n), np.log(ns), 1)[0])
    return out
