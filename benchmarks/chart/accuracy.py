"""Part 1 of the chart: the accuracy sweep (``accuracy.csv``). Each (tol, dt, slop) point of
:func:`~benchmarks.chart.spec.grid_points` settles a copy of the smoke pile, tilts it to its
first avalanche onset (plus a margin) and holds another copy at a fixed angle; the columns are
:data:`~benchmarks.chart.spec.ACCURACY_COLUMNS` (what each means: :mod:`benchmarks.chart`)."""

from __future__ import annotations

import time
import warnings

import numpy as np
import pandas as pd

from tiltpile import config as cfgmod
from benchmarks.chart.spec import (ACCURACY_COLUMNS, CUTOFF, DEFAULT_DT, DEFAULT_SLOP, DEFAULT_TOL,
                                       SETTLE_STEPS, ChartSpec, accuracy_config, copy_system, grid_points,
                                       log, starting_pile)
from tiltpile.sim.step import System


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
        pile = starting_pile(cfg, seed, spec.cache)
        log(f"[accuracy] seed {seed}: pile of {int((~pile.fixed).sum())} grains ready in "
             f"{time.perf_counter() - t0:.1f} s", progress)
        for tol, dt, slop in grid_points(spec):
            t1 = time.perf_counter()
            s = copy_system(pile)
            s.params.update(tol=float(tol), dt=float(dt), slop=float(slop), max_iter=spec.max_iter)
            s.advance(SETTLE_STEPS, 0.0, 0.0)
            c = copy_system(s)
            row = dict(seed=seed, tol=tol, dt=dt, slop=slop, n_grains=int((~s.fixed).sum()))
            row.update(_tilt_to_onset(s, cfg, spec))
            row.update(_creep(c, spec, dt))
            rows.append(row)
            log(f"[accuracy] seed {seed} tol {tol:g} dt {dt:g} slop {slop:g}: theta_m "
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
