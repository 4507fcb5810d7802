"""``tiltpile bench --chart DIR`` (``make bench``): the speed x accuracy chart of issue 6.

Three measurements, all on one core, one after the other, written to ``DIR`` (each file to a
temporary name, then renamed):

1. Accuracy sweep (``accuracy.csv``, ``pareto.png``). One settled smoke pile per seed (250 grains,
   20 d box; ``protocol.deposited`` with the point-independent deposition at
   ``solver.deposition_tol``, settled at the tightest tol; cached under ``data/bench``). For every
   (tol, dt, overlap slop) point of the grid (``ChartSpec.grid``) the pile is copied and
   * settled ``SETTLE_STEPS`` steps at theta = 0 at the point's own setting (as frame 0 of a run),
   * tilted at 0.001 deg per step (the paper's rate per step, so dt also sets the physical tilt
     rate 0.001 deg / dt) with a frame every 50 steps (0.05 deg, as in the paper), until the first
     avalanche onset (2% lost-contact criterion, ``analysis.segment_avalanches`` over the frames'
     ``frame_observables``) plus ``margin_deg``, or ``theta_cap`` degrees;
     measured: wall time per degree of tilt (median over the frame chunks of the run, solver
     only, analysis excluded), NLGS sweeps per step (mean, median), the per-step final residual
     (median), steps at ``max_iter``, largest overlap, first onset theta_m, and <z>, <n_m> (bulk,
     rattlers removed) averaged over the quiet frames before the onset, and the drift: mean
     displacement of the mobile grains per degree of tilt, median over those quiet frames;
   * separately, creep: a copy tilted to ``hold_deg`` in ``creep_tilt_steps`` equal steps, left
     ``creep_settle_time`` to take the last increment, then held for ``creep_hold_time``
     (physical time, so ``creep_hold_time / dt`` steps) at fixed gravity: mean and max
     displacement of the mobile grains over the hold.
   Shifts (theta_m, <z>, <n_m>) are against the tightest setting (smallest tol, smallest dt, the
   default slop) of the same seed.
2. Pareto plot: time per degree against each error measure (creep, drift, |shift of theta_m|,
   final residual), per (tol, dt, slop) averaged over seeds; the default setting highlighted; the
   Pareto front (points that no other point beats in both time and error) drawn.
3. Scaling (``scaling.csv``, ``scaling.png``). A pile of ``base_n`` grains at the paper's depth
   (the ``tiltpile bench`` pile: box 120 d * n / 4000, paper preset, cached under data/bench) is
   tiled k times side by side in a k-times wider box: grain (copy m, original id i) gets id
   i * k + m, so ids stay ordered bottom-up as in a deposited pile (the forward and interleaved
   sweeps rely on it), fixed bottom rows included; the inner walls disappear. The tiled pile settles
   ``tile_settle_steps`` steps at tol 1e-4 at theta = 0 (the seams relax), then 20 untimed tilt
   steps at the timed tolerance, then ``scaling_steps`` timed tilt steps, each timed alone:
   median ms per step, ns per contact update (time / local solves made,
   ``StepRecord.updates``), sweeps per step. The default sweep (``solver.sweep``, interleaved)
   relax 1 with the default overlap slop at every N; at ``variant_ns`` also, from the same state: forward relax 1 with the slop (the
   key order, the default before the interleaved sweep), random relax 1 with slop 0 (plain NLGS
   with the plain gap term, the reference of issue 6), forward relax 1 with slop 0, and forward
   relax 1.5 (projected SOR). Last, the cost of a step of the default sweep at exactly
   ``fixed_sweeps`` sweeps (tol 0), ``fixed_rounds`` rounds of
   ``fixed_steps`` steps, each round over every N in turn: median over all those steps.

``summary.json``: machine (``os.cpu_count()``, platform, numba version), date, command, timings
of each part, the settings, and the fitted scaling (line through the origin, log-log slope).
"""

from __future__ import annotations

import datetime
import json
import math
import os
import platform
import sys
import time
import warnings
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile import config as cfgmod
from tiltpile.analysis.observables import DEFAULT_PARAMS
from tiltpile.sim import protocol, solver
from tiltpile.sim.step import System

SETTLE_STEPS = 50           # steps at theta = 0 at the point's own setting before the tilt
CUTOFF = DEFAULT_PARAMS["cutoff"]  # avalanche criterion on the lost-contact fraction
# the simulator's defaults, highlighted in the chart
DEFAULT_TOL, DEFAULT_DT = cfgmod.SolverConfig().tol, cfgmod.SolverConfig().dt
DEFAULT_SLOP = cfgmod.SolverConfig().overlap_slop

ACCURACY_COLUMNS = [
    "seed", "tol", "dt", "slop", "is_default", "is_reference", "n_grains", "contacts",
    "ms_per_deg", "ms_per_deg_mean", "ms_per_step", "sweeps_mean", "sweeps_median", "cap_hit_fraction",
    "residual_median", "max_overlap", "theta_end", "steps", "wall_s",
    "theta_m", "z_quiet", "n_m_quiet", "quiet_frames", "drift_per_deg",
    "creep_mean", "creep_median", "creep_max", "creep_steps", "creep_max_overlap",
    "theta_m_shift", "z_shift", "n_m_shift", "resolution_warning",
]
SCALING_COLUMNS = [
    "n", "copies", "box_length", "sweep", "relax", "slop", "tol", "steps", "contacts", "active_contacts",
    "ms_per_step", "ms_per_step_mean", "ns_per_update", "sweeps_mean", "sweeps_median", "cap_hits",
    "settle_s", "fixed_sweeps",
]


@dataclass(frozen=True)
class ChartSpec:
    """What the chart measures; ``full()`` is ``make bench``, ``quick()`` the test's tiny version."""

    seeds: tuple = (3, 1)
    tols: tuple = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
    dts: tuple = (0.005, 0.01, 0.02)
    # the overlap slop (solver.overlap_slop): 0 is the plain gap term b = g / dt
    slops: tuple = (0.0, 1e-6, 1e-5)
    # "full": every (tol, dt, slop); "cross": each of the three varied alone, the other two at
    # their defaults (the full (tol, dt) grid on 2 seeds took ~20 min for the accuracy part
    # alone: points at tol <= 1e-5 tilt to 14-15 deg at ~500 sweeps per step, 90-100 s each)
    grid: str = "cross"
    scene: tuple = ("scene.n=250", "scene.box_length=20.0")  # on the smoke preset
    max_iter: int = 1000
    tilt_per_step: float = 0.001
    frame_every: int = 50
    theta_cap: float = 20.0
    margin_deg: float = 0.5
    hold_deg: float = 10.0
    creep_tilt_steps: int = 500
    creep_settle_time: float = 2.0
    creep_hold_time: float = 10.0
    base_n: int = 500
    copies: tuple = (1, 2, 4, 8, 16, 32)
    tile_settle_steps: int = 300
    scaling_tol: float = 1e-6
    scaling_steps: int = 100
    scaling_steps_large: int = 50   # for n > 4000
    variant_ns: tuple = (1000, 4000)
    variant_steps: int = 50
    fixed_sweeps: int = 100         # scaling at a fixed number of sweeps per step (tol 0)
    fixed_steps: int = 10
    # rounds of the fixed-sweep timing, each over every N in turn, so that a slow spell of the
    # shared machine falls on all N alike (one round of 10 steps per N gave per-grain spreads of
    # 1.41-1.76x from chart to chart)
    fixed_rounds: int = 5
    cache: str | None = "data/bench"
    quick: bool = False

    @classmethod
    def full(cls) -> "ChartSpec":
        return cls()

    @classmethod
    def quick_spec(cls) -> "ChartSpec":
        return cls(seeds=(3,), tols=(1e-2, 1e-4, 1e-6), dts=(0.01, 0.02), slops=(0.0, 1e-6),
                   scene=("scene.n=60", "scene.box_length=8.0"), theta_cap=3.0, margin_deg=0.2,
                   hold_deg=5.0, creep_tilt_steps=500, creep_settle_time=2.0, creep_hold_time=2.0,
                   base_n=60, copies=(1, 2), tile_settle_steps=50, scaling_steps=10,
                   scaling_steps_large=10, variant_ns=(120,), variant_steps=10, cache=None,
                   fixed_sweeps=20, fixed_steps=3, fixed_rounds=2,
                   grid="full", quick=True)


# ----------------------------------------------------------------------------------------------
# small helpers


def _atomic_write_text(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    tmp.replace(path)


def _atomic_csv(df: pd.DataFrame, path: Path) -> None:
    _atomic_write_text(path, df.to_csv(index=False, float_format="%.6g"))


def _atomic_png(fig, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    fig.savefig(tmp, format="png", dpi=130)
    tmp.replace(path)


def _copy(sysm: System) -> System:
    other = System.__new__(System)
    other.params = dict(sysm.params)
    other.restore(sysm.state())
    return other


def _pile(cfg: cfgmod.Config, seed: int, cache: str | None) -> System:
    """A deposited pile for ``cfg`` (cached under ``cache`` when given)."""
    if cache is None:
        return protocol.deposited(cfg, seed)
    from tiltpile import bench
    return bench.settled_pile(cfg, seed, progress=False, cache=Path(cache))


def _log(msg: str, progress: bool) -> None:
    if progress:
        print(msg, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------------------------
# 1. accuracy


def accuracy_config(spec: ChartSpec) -> cfgmod.Config:
    return cfgmod.load("smoke", None, [*spec.scene, f"solver.tol={min(spec.tols)!r}",
                                       f"solver.dt={min(spec.dts)!r}", f"solver.max_iter={spec.max_iter}",
                                       f"protocol.tilt_per_step_deg={spec.tilt_per_step!r}",
                                       f"protocol.frame_every={spec.frame_every}"])


def grid_points(spec: ChartSpec) -> list[tuple[float, float, float]]:
    """The (tol, dt, slop) points of the sweep, by slop, dt, then tol (``ChartSpec.grid``)."""
    pts = [(t, d, s) for s in spec.slops for d in spec.dts for t in spec.tols]
    if spec.grid == "cross":
        pts = [p for p in pts if sum(v != dv for v, dv in zip(p, (DEFAULT_TOL, DEFAULT_DT, DEFAULT_SLOP))) <= 1]
    elif spec.grid != "full":
        raise ValueError(f"grid must be 'full' or 'cross', got {spec.grid!r}")
    return pts


def _tilt_to_onset(sysm: System, cfg: cfgmod.Config, spec: ChartSpec) -> dict:
    """Tilt from theta = 0 with frames every ``frame_every`` steps until onset + margin (or cap)."""
    from tiltpile.analysis import ResolutionWarning, segment_avalanches
    from tiltpile.analysis.observables import failure_between, frame_observables

    dth = spec.tilt_per_step
    fe = spec.frame_every
    L = sysm.params["box_length"]
    mu, mu_w = sysm.params["mu"], sysm.params["mu_wall"]

    def observe(theta):
        pair, force, status = sysm.contacts()
        row, _, keep = frame_observables(sysm.radius, sysm.fixed, L, sysm.pos, sysm.velocity,
                                         sysm.omega, pair, force, status, theta, mu=mu, mu_wall=mu_w)
        return row, keep

    row, prev = observe(0.0)
    thetas, lost, z, nm, nact = [0.0], [], [row["z"]], [row["n_m"]], [row["n_active"]]
    chunk_wall, its, res, ovl, disp = [], [], [], [], []
    mob = ~sysm.fixed
    onset_frame = None
    total_chunks = int(round(spec.theta_cap / (dth * fe)))
    margin_chunks = max(1, int(round(spec.margin_deg / (dth * fe))))
    k = 0
    t_all = time.perf_counter()
    while k < total_chunks:
        theta0 = k * fe * dth
        p0 = sysm.pos[mob]
        t0 = time.perf_counter()
        rec = sysm.advance(fe, theta0, dth)
        chunk_wall.append(time.perf_counter() - t0)
        disp.append(float(np.hypot(*(sysm.pos[mob] - p0).T).mean()))
        its.append(rec.iterations)
        res.append(rec.residual)
        ovl.append(rec.overlap.max())
        k += 1
        theta = k * fe * dth
        if not np.all(np.isfinite(sysm.pos)):
            break
        row, keep = observe(theta)
        lost.append(failure_between(prev, keep, sysm.fixed)["lost_fraction"])
        prev = keep
        thetas.append(theta)
        z.append(row["z"])
        nm.append(row["n_m"])
        nact.append(row["n_active"])
        if onset_frame is None and lost[-1] > CUTOFF:
            onset_frame = len(lost) - 1
        if onset_frame is not None and len(thetas) - 1 >= onset_frame + margin_chunks:
            break
    wall = time.perf_counter() - t_all
    lf = np.array(lost + [np.nan])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ResolutionWarning)
        seg = segment_avalanches(lf, CUTOFF, n_contacts=np.array(nact))
    resolution = any(issubclass(w.category, ResolutionWarning) for w in caught)
    thetas = np.array(thetas)
    if seg["onsets"].size:
        first = int(seg["onsets"][0])
        theta_m = float(thetas[first])
    else:
        first, theta_m = len(thetas), float("nan")
    quiet = slice(0, max(first, 1))
    its = np.concatenate(its)
    res = np.concatenate(res)
    per_deg = 1e3 * np.array(chunk_wall) / (fe * dth)
    # drift: mean displacement of the mobile grains per degree, median over the quiet chunks (a
    # chunk with a rearrangement is an outlier the median ignores; what is left is the creep the
    # solver's residual error and the overlap slop allow while tilting)
    drift = float(np.median(disp[:max(first, 1)])) / (fe * dth)
    return dict(ms_per_deg=float(np.median(per_deg)), ms_per_deg_mean=float(per_deg.mean()),
                ms_per_step=1e3 * float(np.median(chunk_wall)) / fe,
                sweeps_mean=float(its.mean()), sweeps_median=float(np.median(its)),
                cap_hit_fraction=float((its >= sysm.params["max_iter"]).mean()),
                residual_median=float(np.median(res)), max_overlap=float(max(ovl)),
                theta_end=float(thetas[-1]), steps=int(its.size), wall_s=wall,
                theta_m=theta_m, z_quiet=float(np.nanmean(z[quiet])),
                n_m_quiet=float(np.nanmean(nm[quiet])), quiet_frames=int(max(first, 1)),
                drift_per_deg=drift,
                resolution_warning=bool(resolution), contacts=int(np.median(nact)))


def _creep(sysm: System, spec: ChartSpec, dt: float) -> dict:
    """Tilt to hold_deg in creep_tilt_steps, settle, then hold: displacement of mobile grains."""
    n = spec.creep_tilt_steps
    sysm.advance(n, 0.0, spec.hold_deg / n)
    sysm.advance(max(1, int(round(spec.creep_settle_time / dt))), spec.hold_deg, 0.0)
    hold = max(1, int(round(spec.creep_hold_time / dt)))
    before = sysm.pos.copy()
    rec = sysm.advance(hold, spec.hold_deg, 0.0)
    mob = ~sysm.fixed
    d = np.hypot(*(sysm.pos - before)[mob].T)
    if not np.all(np.isfinite(d)):
        return dict(creep_mean=float("inf"), creep_median=float("inf"), creep_max=float("inf"),
                    creep_steps=hold, creep_max_overlap=float("inf"))
    return dict(creep_mean=float(d.mean()), creep_median=float(np.median(d)),
                creep_max=float(d.max()), creep_steps=hold,
                creep_max_overlap=float(rec.overlap.max()))


def accuracy_sweep(spec: ChartSpec, progress: bool = True) -> pd.DataFrame:
    cfg = accuracy_config(spec)
    rows = []
    for seed in spec.seeds:
        t0 = time.perf_counter()
        pile = _pile(cfg, seed, spec.cache)
        _log(f"[accuracy] seed {seed}: pile of {int((~pile.fixed).sum())} grains ready in "
             f"{time.perf_counter() - t0:.1f} s", progress)
        for tol, dt, slop in grid_points(spec):
            t1 = time.perf_counter()
            s = _copy(pile)
            s.params.update(tol=float(tol), dt=float(dt), slop=float(slop), max_iter=spec.max_iter)
            s.advance(SETTLE_STEPS, 0.0, 0.0)
            c = _copy(s)
            row = dict(seed=seed, tol=tol, dt=dt, slop=slop, n_grains=int((~s.fixed).sum()))
            row.update(_tilt_to_onset(s, cfg, spec))
            row.update(_creep(c, spec, dt))
            rows.append(row)
            _log(f"[accuracy] seed {seed} tol {tol:g} dt {dt:g} slop {slop:g}: theta_m "
                 f"{row['theta_m']:.2f}, {row['sweeps_mean']:.0f} sweeps/step, {row['ms_per_deg']:.0f} "
                 f"ms/deg, creep {row['creep_mean']:.2g} d, drift {row['drift_per_deg']:.2g} d/deg "
                 f"({time.perf_counter() - t1:.0f} s)", progress)
    df = pd.DataFrame(rows)
    ref_tol, ref_dt = min(spec.tols), min(spec.dts)
    df["is_reference"] = (df["tol"] == ref_tol) & (df["dt"] == ref_dt) & (df["slop"] == DEFAULT_SLOP)
    df["is_default"] = ((df["tol"] == DEFAULT_TOL) & (df["dt"] == DEFAULT_DT)
                        & (df["slop"] == DEFAULT_SLOP))
    for col, out in (("theta_m", "theta_m_shift"), ("z_quiet", "z_shift"), ("n_m_quiet", "n_m_shift")):
        ref = df[df["is_reference"]].set_index("seed")[col]
        df[out] = df[col] - df["seed"].map(ref)
    return df[ACCURACY_COLUMNS]


# ----------------------------------------------------------------------------------------------
# 3. scaling


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
                active_contacts=int((sysm.c[:, 6] > 0).sum()),
                ms_per_step=1e3 * float(np.median(walls)), ms_per_step_mean=1e3 * float(walls.mean()),
                ns_per_update=1e9 * float(walls.sum()) / max(1, upd),
                sweeps_mean=float(its.mean()), sweeps_median=float(np.median(its)),
                cap_hits=int((its >= sysm.params["max_iter"]).sum()), updates=upd, walls=walls)


def scaling_sweep(spec: ChartSpec, progress: bool = True) -> pd.DataFrame:
    from tiltpile import bench

    cfg = bench.bench_config(spec.base_n)
    if spec.quick:
        cfg = cfgmod.load("smoke", None, [*spec.scene])
    t0 = time.perf_counter()
    base = _pile(cfg, 0, spec.cache)
    _log(f"[scaling] base pile of {spec.base_n} grains ({cfg.scene.box_length:g} d box) ready in "
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
            _log(f"[scaling] n {n} {sweep} relax {relax:g} slop {sl:g}: {r['ms_per_step']:.1f} ms/step, "
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
        _log(f"[scaling] n {n} {cfg.solver.sweep}, {spec.fixed_sweeps} sweeps fixed ({spec.fixed_rounds} rounds): "
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
            # issue 6: "cost per step within 1.3x of linear in N from 1000 to 16000"
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


# ----------------------------------------------------------------------------------------------
# 2. plots


def pareto_front(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Indices of the points no other point beats in both x and y (lower is better), by x."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
    order = ok[np.lexsort((y[ok], x[ok]))]
    front, best = [], np.inf
    for i in order:
        if y[i] < best:
            front.append(i)
            best = y[i]
    return np.array(front, dtype=int)


def aggregate_points(acc: pd.DataFrame) -> pd.DataFrame:
    """Per (tol, dt, slop): median time per degree, mean error measures over seeds."""
    g = acc.assign(abs_theta_shift=acc["theta_m_shift"].abs(), abs_z_shift=acc["z_shift"].abs(),
                   abs_n_m_shift=acc["n_m_shift"].abs())
    return g.groupby(["tol", "dt", "slop"], as_index=False).agg(
        ms_per_deg=("ms_per_deg", "median"), sweeps_mean=("sweeps_mean", "mean"),
        creep_mean=("creep_mean", "mean"), creep_median=("creep_median", "mean"),
        drift_per_deg=("drift_per_deg", "mean"),
        residual_median=("residual_median", "median"),
        abs_theta_shift=("abs_theta_shift", "mean"), abs_z_shift=("abs_z_shift", "mean"),
        abs_n_m_shift=("abs_n_m_shift", "mean"), max_overlap=("max_overlap", "max"),
        is_default=("is_default", "any"), is_reference=("is_reference", "any"))


def _point_label(r) -> str:
    """tol/dt, plus /s<slop> where the overlap slop is not the default."""
    lab = f"{r['tol']:g}/{r['dt']:g}"
    return lab if r["slop"] == DEFAULT_SLOP else f"{lab}/s{r['slop']:g}"


def read_accuracy(path: Path) -> pd.DataFrame | None:
    """The accuracy table an earlier chart left in ``path``, or None with a warning when it lacks
    one of ``ACCURACY_COLUMNS`` (written by an older tiltpile, before that column was measured)."""
    acc = pd.read_csv(path)
    missing = [c for c in ACCURACY_COLUMNS if c not in acc]
    if missing:
        warnings.warn(f"{path} lacks the column(s) {', '.join(missing)} (written by an older "
                      "tiltpile): not summarised; rerun the chart with --parts accuracy",
                      stacklevel=2)
        return None
    return acc


def plot_pareto(acc: pd.DataFrame, path: Path, hold_deg: float = 10.0,
                tilt_per_step: float = 0.001) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    agg = aggregate_points(acc)
    measures = [("creep_mean", f"creep held at {hold_deg:g} deg: mean displacement [d]", True),
                ("drift_per_deg", "drift while tilting: mean displacement per degree [d]\n"
                                  "(median over the quiet frames before the onset)", True),
                ("abs_theta_shift", "|shift of first onset theta_m| [deg] (vs tightest)", False),
                ("residual_median", "final NLGS residual (median per step)", True)]
    fig, axes = plt.subplots(1, 4, figsize=(21, 5.4))
    dts = sorted(agg["dt"].unique())
    markers = dict(zip(dts, "os^Dv"))
    cmap = plt.get_cmap("viridis")
    tols = sorted(agg["tol"].unique())
    for ax, (col, label, logx) in zip(axes, measures):
        x = agg[col].to_numpy(float)
        y = agg["ms_per_deg"].to_numpy(float)
        if not np.any(np.isfinite(x) & np.isfinite(y)):
            ax.text(0.5, 0.5, "no data (no onset found before theta_cap)", ha="center",
                    transform=ax.transAxes)
            ax.set_xlabel(label)
            continue
        if logx:
            pos = x[np.isfinite(x) & (x > 0)]
            floor = pos.min() / 3 if pos.size else 1e-12
            x = np.where(np.isfinite(x) & (x <= 0), floor, x)
        for i, r in agg.iterrows():
            c = cmap(tols.index(r["tol"]) / max(1, len(tols) - 1))
            ax.scatter(x[i], y[i], marker=markers[r["dt"]], s=60, zorder=3,
                       color=c if r["slop"] == DEFAULT_SLOP else "none",
                       edgecolor=("red" if r["is_default"] else
                                  "k" if r["slop"] == DEFAULT_SLOP else c),
                       linewidth=2.5 if r["is_default"] or r["slop"] != DEFAULT_SLOP else 0.5)
            ax.annotate(_point_label(r), (x[i], y[i]), fontsize=7,
                        xytext=(4, 3), textcoords="offset points")
        f = pareto_front(x, y)
        if f.size:
            ax.step(x[f], y[f], where="post", color="0.4", lw=1, ls="--", zorder=2,
                    label="Pareto front")
        if logx:
            ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("wall time per degree of tilt [ms] (median)")
        ax.grid(alpha=0.3, which="both")
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], marker=markers[d], ls="", color="0.5", label=f"dt {d:g}") for d in dts]
    handles += [Line2D([], [], marker="o", ls="", color=cmap(i / max(1, len(tols) - 1)),
                       label=f"tol {t:g}") for i, t in enumerate(tols)]
    handles += [Line2D([], [], marker="o", ls="", mfc="none", mec="0.3", mew=2.5,
                       label=f"hollow: overlap slop other than {DEFAULT_SLOP:g} (label s...)"),
                Line2D([], [], marker="o", ls="", mfc="none", mec="red", mew=2.5,
                       label=f"default tol {DEFAULT_TOL:g} / dt {DEFAULT_DT:g} / slop {DEFAULT_SLOP:g}"),
                Line2D([], [], ls="--", color="0.4", label="Pareto front")]
    axes[0].legend(handles=handles, fontsize=7, loc="best")
    n = int(acc["n_grains"].iloc[0])
    fig.suptitle(f"Speed vs accuracy, {n}-grain pile, {tilt_per_step:g} deg/step, seeds "
                 f"{', '.join(map(str, sorted(acc['seed'].unique())))} (labels tol/dt[/slop]; errors "
                 "averaged over seeds, 0 plotted at the axis floor)", fontsize=10)
    fig.tight_layout()
    _atomic_png(fig, path)
    plt.close(fig)


def plot_scaling(sc: pd.DataFrame, fit: dict, path: Path, tilt_per_step: float = 0.001) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(16, 5))
    sweep0 = fit.get("sweep", "forward")
    styles = {(sweep0, 1.0, True): ("o-", "C0", f"{sweep0}, relax 1, overlap slop (default)"),
              ("forward", 1.0, True): ("<", "C5", "forward, relax 1, overlap slop"),
              ("random", 1.0, False): ("s", "C3", "random, relax 1, slop 0 (plain NLGS reference)"),
              ("forward", 1.0, False): ("v", "C1", "forward, relax 1, slop 0"),
              ("forward", 1.5, True): ("^", "C2", "forward, relax 1.5 (SOR), slop")}
    fixed = sc[sc["fixed_sweeps"] > 0].sort_values("n")
    if len(fixed):
        lab = f"{sweep0}, exactly {int(fixed['fixed_sweeps'].iloc[0])} sweeps per step"
        axes[0].plot(fixed["n"], fixed["ms_per_step"], "D-", color="C4", label=lab)
        axes[1].plot(fixed["n"], fixed["ns_per_update"], "D-", color="C4", label=lab)
        fx = fit.get("fixed_sweeps", {})
        if "ms_per_grain_origin_fit" in fx:
            nn = np.geomspace(sc["n"].min(), sc["n"].max(), 50)
            axes[0].plot(nn, fx["ms_per_grain_origin_fit"] * nn, "--", color="C4", lw=1,
                         label=f"linear (fixed sweeps): slope {fx['loglog_slope']:.2f} log-log")
    for (sweep, relax, slop), d in sc[sc["fixed_sweeps"] == 0].groupby(["sweep", "relax", "slop"]):
        d = d.sort_values("n")
        st, c, lab = styles.get((sweep, relax, slop > 0), ("x", "k", f"{sweep} {relax:g} slop {slop:g}"))
        axes[0].plot(d["n"], d["ms_per_step"], st, color=c, label=lab)
        axes[1].plot(d["n"], d["ns_per_update"], st, color=c, label=lab)
        axes[2].plot(d["n"], d["sweeps_mean"], st, color=c, label=lab)
    if "ms_per_grain_origin_fit" in fit:
        nn = np.geomspace(sc["n"].min(), sc["n"].max(), 50)
        axes[0].plot(nn, fit["ms_per_grain_origin_fit"] * nn, "k--", lw=1,
                     label=f"linear through origin: {1e3 * fit['ms_per_grain_origin_fit']:.2f} us/grain")
        axes[0].plot(nn, fit["loglog_prefactor"] * nn ** fit["loglog_slope"], ":", color="0.5",
                     label=f"log-log fit: slope {fit['loglog_slope']:.2f}")
    for ax, lab in zip(axes, ["ms per step (median)", "ns per contact update",
                              "NLGS sweeps per step (mean)"]):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("mobile grains N (fixed depth, box 120 d * N / 4000)")
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.suptitle(f"Scaling at fixed depth (tiled settled pile), tilting at {tilt_per_step:g} deg/step, "
                 f"tol {sc['tol'].iloc[0]:g}", fontsize=10)
    fig.tight_layout()
    _atomic_png(fig, path)
    plt.close(fig)


# ----------------------------------------------------------------------------------------------
# driver


def machine_info() -> dict:
    import numba
    return dict(cpu_count=os.cpu_count(), platform=platform.platform(), machine=platform.machine(),
                processor=platform.processor(), python=platform.python_version(),
                numba=numba.__version__, numpy=np.__version__)


def run_chart(outdir, spec: ChartSpec | None = None, progress: bool = True,
              command: str | None = None, parts=("accuracy", "scaling")) -> dict:
    """Measure and write accuracy.csv, pareto.png, scaling.csv, scaling.png and summary.json."""
    spec = spec or ChartSpec.full()
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    summary = dict(date=datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
                   command=command or " ".join(sys.argv), machine=machine_info(),
                   spec=asdict(spec), default=dict(tol=DEFAULT_TOL, dt=DEFAULT_DT, slop=DEFAULT_SLOP),
                   timings_s={},
                   files=[])
    if "accuracy" in parts:
        t0 = time.perf_counter()
        acc = accuracy_sweep(spec, progress)
        _atomic_csv(acc, out / "accuracy.csv")
        plot_pareto(acc, out / "pareto.png", spec.hold_deg, spec.tilt_per_step)
        summary["timings_s"]["accuracy"] = time.perf_counter() - t0
        summary["files"] += ["accuracy.csv", "pareto.png"]
    elif (out / "accuracy.csv").exists():  # --parts scaling: summarise the accuracy run on disk
        acc = read_accuracy(out / "accuracy.csv")
        if acc is not None:
            plot_pareto(acc, out / "pareto.png", spec.hold_deg, spec.tilt_per_step)
            summary["accuracy_from_file"] = True
            summary["files"] += ["accuracy.csv", "pareto.png"]
    else:
        acc = None
    if acc is not None:
        agg = aggregate_points(acc)
        summary["accuracy_points"] = json.loads(agg.to_json(orient="records"))
        for name, col in (("pareto_front_creep", "creep_mean"),
                          ("pareto_front_drift", "drift_per_deg"),
                          ("pareto_front_theta_m", "abs_theta_shift"),
                          ("pareto_front_residual", "residual_median")):
            f = pareto_front(agg[col].to_numpy(float), agg["ms_per_deg"].to_numpy(float))
            summary[name] = [_point_label(agg.iloc[i]) for i in f]
    if "scaling" in parts:
        t0 = time.perf_counter()
        sc = scaling_sweep(spec, progress)
        fit = scaling_fit(sc)
        _atomic_csv(sc, out / "scaling.csv")
        plot_scaling(sc, fit, out / "scaling.png", 0.01 if spec.quick else 0.001)
        summary["timings_s"]["scaling"] = time.perf_counter() - t0
        summary["scaling_fit"] = fit
        summary["files"] += ["scaling.csv", "scaling.png"]
    summary["timings_s"]["total"] = time.perf_counter() - t_start
    summary["files"].append("summary.json")
    _atomic_write_text(out / "summary.json", json.dumps(summary, indent=1, default=float) + "\n")
    return summary
