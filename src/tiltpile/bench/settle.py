"""Do the velocities settle before the impulses? NLGS logged every few sweeps in steps of a run.

Usage: python -m tiltpile.bench.settle RUN --frames F [F ...] [--steps S] [--every K] [--long L]
                                       [--warm W] [--vtol T] [--json OUT] [--chart PNG] [--quiet]
       python -m tiltpile.bench.settle --plot JSON [JSON ...] --chart PNG
  RUN      a run file (``tiltpile simulate``); FRAMES frame indices (paper preset: a frame every
           0.05 deg, frame 160 = 8 deg; ``tiltpile info RUN`` lists the angles)
  --steps  tilt steps measured after each frame (default 50)
  --every  sweeps between two log points up to the run's cap (default 25); past the cap every
           ten times as many
  --long   sweeps of the reference solve of every step (default 20 000)
  --warm   steps at max_iter 20 000 that rebuild the impulses (``flow_caps.rebuilt_state``; default 10)
  --vtol   the tolerance the velocity norms are normalised by (default 1.666e-4, LMGC90's 2D
           disk examples)
  --json   write every step's series and the summaries; --chart draw them (PNG, matplotlib)
  --plot   draw the chart of earlier ``--json`` files instead of measuring

From each frame's rebuilt state the pile tilts S steps at the run's rate, each step exactly as
the run makes it (``solver.tol``, ``solver.max_iter``). Within every step the same Gauss-Seidel
iteration is also continued to ``--long`` sweeps (or to ``solver.tol``, whichever comes first),
in chunks: the production solver ``nlgs`` is called again and again with max_iter = K from the
impulses and velocities the last call left. That is the same iteration as one call (the state of
the iteration is the impulses and the velocities; each call's sweeps past the 20th are pruned but
a chunk ends on a full sweep, which changes nothing as long as no contact left out closes; the
random order would restart its permutation each call and relax != 1 would make each chunk's first
sweep plain). Every step checks it: the chunked iterate at the production solve's last sweep is
compared with one call at the cap, bit for bit (``chunk_equal``), and the pile goes on from the
one call, so the tilt is the run's own. The step's preparation (free velocities, contact list,
geometry, warm start) is ``System.advance`` itself, run with max_iter 0 and its position update
undone (``prepare_step``; ``tests/bench/test_settle.py`` checks the step against ``advance``).

At every log point (sweep k):
- ``residual``: our stopping residual, the relative impulse change of sweep k (what nlgs returns);
- ``natural``: ``solver.natural_residual``, the contact law's residual at the iterate;
- ``quad_dv``, ``quad_dvr``, ``mean_dvor``: LMGC90's velocity norms (``mod_nlgs.f90``,
  ``compute_convergence_norms_nlgs``), as LMGC90 computes them in its check pass: every contact's
  local problem is solved from the current velocities without applying the result (a Jacobi
  pass), and dV = W_aa (R - R'), the velocity jump that solve would make (R the iterate's impulse,
  R' the local solution, W_aa the contact's diagonal Delassus block: here diag(W_nn, W_tt) with
  W_tt = 3 W_nn for disks). With Rm = (R + R') / 2, over the N_act contacts with Rm != 0:
  QuadWR = sqrt(sum (|W R|^2 + |W R'|^2) / 2 / N_act), QuadDV = sqrt(sum |dV|^2 / N_act) /
  (QuadWR tol), MeanWRR = sum (W R.R + W R'.R') / 2 / N_act, QuadDVR = sqrt(sum |dV|^2 |Rm|^2 /
  N_act) / (MeanWRR tol), MeanDVoR = sum dV.Rm / (N_act MeanWRR tol) (signed; the test takes
  |.|). LMGC90's 'Quad' test stops when all three are below 1;
- ``inc_quad_dv``, ``inc_quad_dvr``, ``inc_mean_dvor``: the same norms of the change of the
  local contact velocities (u_n, u_t) over the chunk that ends at k, dV = u(k) - u(previous log
  point), Rm the mean of the impulses at the two ends (over every contact of the list: an open
  one whose velocity changes counts in dV, not in N_act);
- ``disp_err_mean``, ``disp_err_max``: the displacement dt v of the mobile grains if the step
  stopped at k, against the reference solve's end: mean_i |dx_i(k) - dx_i(ref)| / mean_i
  |dx_i(ref)|, and max over max (|.| per grain, Euclidean).
A solve that stops on ``solver.tol`` keeps its last values at the later log points (its
increments are 0 there).

Per frame: the steps' series and a summary (medians over the steps): the production solve's
sweeps and capped fraction, the first log point where LMGC90's test passes at ``--vtol`` and
the displacement error there, and the sweep from which the displacement stays within 1% and
0.1% of the reference. ``docs/performance-log.md`` records what it measured.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from tiltpile.bench.flow_caps import rebuilt_state
from tiltpile.sim import protocol
from tiltpile.sim.jit import njit
from tiltpile.sim.solver import (C_IWN, C_IWT, C_NX, C_NY, C_PN, C_PT, IMPULSE, V_IM, V_S,
                                 V_X, V_Y, _local_solution, nlgs)

LMGC_TOL = 1.666e-4   # LMGC90's tolerance in its 2D disk examples
PAST_CAP = 10         # past the cap, a log point every PAST_CAP x --every sweeps
SERIES = ("residual", "natural", "quad_dv", "quad_dvr", "mean_dvor", "inc_quad_dv", "inc_quad_dvr",
          "inc_mean_dvor", "disp_err_mean", "disp_err_max")
AGREE = (1e-2, 1e-3)  # displacement agreement levels of the summary
NORMS = ("quad_dv", "quad_dvr", "mean_dvor")


# -- the norms -------------------------------------------------------------------------------------

@njit
def check_pass(ci, cj, c, vel):
    """LMGC90's check pass at the current iterate (module docstring): every contact's plain local
    solution R' from the current velocities, not applied. Returns the sums
    [sum |dV|^2, sum |dV|^2 |Rm|^2, sum dV.Rm, sum WR.R, sum |WR|^2, N_act, sum |R' - R|^2, sum |R|^2]
    (the last two give ``solver.natural_residual``)."""
    out = np.zeros(8)
    for a in range(ci.shape[0]):
        pn = c[a, C_PN]
        pt = c[a, C_PT]
        # the plain local solution, as the sweeps and solver.natural_residual compute it
        pn2, pt2 = _local_solution(ci, cj, c, vel, a, 1.0)
        wn = 1.0 / c[a, C_IWN]
        wt = 1.0 / c[a, C_IWT]
        _accumulate(out, wn * (pn - pn2), wt * (pt - pt2), pn, pt, pn2, pt2, wn, wt)
        out[6] += (pn2 - pn) ** 2 + (pt2 - pt) ** 2
        out[7] += pn * pn + pt * pt
    return out


@njit(inline="always")
def _accumulate(out, dvn, dvt, pn, pt, pn2, pt2, wn, wt):
    rn = 0.5 * (pn + pn2)
    rt = 0.5 * (pt + pt2)
    dvdv = dvn * dvn + dvt * dvt
    rr = rn * rn + rt * rt
    out[0] += dvdv
    out[1] += dvdv * rr
    out[2] += dvn * rn + dvt * rt
    out[3] += 0.5 * (wn * (pn * pn + pn2 * pn2) + wt * (pt * pt + pt2 * pt2))
    out[4] += 0.5 * (wn * wn * (pn * pn + pn2 * pn2) + wt * wt * (pt * pt + pt2 * pt2))
    if rr != 0.0:
        out[5] += 1.0


@njit
def increment_sums(c, u0, p0, u1):
    """The check pass's sums for the change of the local velocities from (u0, p0) to the current
    (u1, c's impulses): dV = u1 - u0, Rm the mean impulse (module docstring, ``inc_*``)."""
    out = np.zeros(8)
    for a in range(c.shape[0]):
        wn = 1.0 / c[a, C_IWN]
        wt = 1.0 / c[a, C_IWT]
        _accumulate(out, u1[a, 0] - u0[a, 0], u1[a, 1] - u0[a, 1], p0[a, 0], p0[a, 1],
                    c[a, C_PN], c[a, C_PT], wn, wt)
    return out


@njit
def local_velocities(ci, cj, c, vel):
    """(C, 2): u_n and u_t of every contact at the current velocities."""
    u = np.empty((ci.shape[0], 2))
    for a in range(ci.shape[0]):
        i = ci[a]
        j = cj[a]
        dvx = vel[i, V_X] - vel[j, V_X]
        dvy = vel[i, V_Y] - vel[j, V_Y]
        u[a, 0] = dvx * c[a, C_NX] + dvy * c[a, C_NY]
        u[a, 1] = -dvx * c[a, C_NY] + dvy * c[a, C_NX] - (vel[i, V_S] + vel[j, V_S])
    return u


def lmgc_norms(sums, tol: float) -> tuple[float, float, float]:
    """(QuadDV, QuadDVR, MeanDVoR) from the sums of ``check_pass`` or ``increment_sums``, as
    LMGC90's ``compute_convergence_norms_nlgs`` forms them; 0 when no contact carries a load."""
    n_act, s_wrr, s_wrwr = sums[5], sums[3], sums[4]
    if n_act < 1 or s_wrr <= 0.0 or s_wrwr <= 0.0:
        return 0.0, 0.0, 0.0
    quad_wr = math.sqrt(s_wrwr / n_act)
    mean_wrr = s_wrr / n_act
    return (math.sqrt(sums[0] / n_act) / (quad_wr * tol),
            math.sqrt(sums[1] / n_act) / (mean_wrr * tol),
            sums[2] / (s_wrr * tol))


def natural_from(sums) -> float:
    """``solver.natural_residual`` from the check pass's last two sums."""
    num, den = sums[6], sums[7]
    return math.sqrt(num / den) if den > 0.0 else (0.0 if num == 0.0 else math.inf)


# -- one step ------------------------------------------------------------------------------------

def prepare_step(s, theta0_deg: float, dtheta_deg: float) -> None:
    """Everything ``System.advance`` does in one step before the solve: free velocities, the
    contact list (rebuilt if due), the geometry and the warm start. ``advance`` itself runs, at
    max_iter 0 (no sweep), and its position update is undone."""
    pos, rot = s.pos.copy(), s.rot.copy()
    cap = s.params["max_iter"]
    s.params["max_iter"] = 0
    try:
        s.advance(1, theta0_deg, dtheta_deg)
    finally:
        s.params["max_iter"] = cap
    s.pos[:] = pos
    s.rot[:] = rot


def finish_step(s) -> None:
    """The position update that ends ``advance``'s step (implicit Euler) from the current
    velocities; mobile grains only."""
    n, dt = s.n, s.params["dt"]
    m = s.vel[:n, V_IM] > 0.0
    v = s.vel[:n]
    s.pos[m, 0] += dt * v[m, V_X]
    s.pos[m, 1] += dt * v[m, V_Y]
    s.rot[m] += dt * v[m, V_S] / s.radius[m]


def log_points(every: int, cap: int, long: int) -> np.ndarray:
    """Sweeps at which a step is logged: every ``every`` up to the cap (the cap included), then
    every PAST_CAP x ``every`` up to ``long`` (included)."""
    pts = set(range(every, min(cap, long) + 1, every)) | {min(cap, long)}
    pts |= set(range(cap + PAST_CAP * every, long + 1, PAST_CAP * every)) | {long}
    return np.array(sorted(p for p in pts if 0 < p <= long), dtype=np.int64)


def solve_step(s, points, vtol: float) -> dict:
    """Solve the prepared step of ``s`` twice from the same start: once as the run does (one
    ``nlgs`` call at the cap; ``s`` is left in that state) and once in chunks to ``points[-1]``,
    logged at ``points`` (module docstring). Returns the series and the step's record."""
    p = s.params
    tol, cap, mode, relax, prune, dt = p["tol"], p["max_iter"], p["mode"], p["relax"], p["prune"], p["dt"]
    ci, cj = s.ci, s.cj
    mob = s.vel[: s.n, V_IM] > 0.0
    # the production solve, one call, on copies
    c1, v1, st1, rng1 = s.c.copy(), s.vel.copy(), s.status.copy(), s.rng.copy()
    it1, res1, _ = nlgs(ci, cj, c1, st1, v1, tol, cap, mode, rng1, np.empty(ci.shape[0], np.int64),
                        relax, prune)
    # the same iteration in chunks, on s itself
    c, vel, st, rng = s.c, s.vel, s.status, s.rng.copy()
    perm = np.empty(ci.shape[0], np.int64)
    u0, p0 = local_velocities(ci, cj, c, vel), c[:, IMPULSE].copy()
    rows = {k: np.full(len(points), np.nan) for k in SERIES}
    disp = np.empty((len(points), int(mob.sum()), 2))
    done, equal, stop_at = 0, False, len(points) - 1
    for k, target in enumerate(points):
        want = int(target) - done
        it, res, _ = nlgs(ci, cj, c, st, vel, tol, want, mode, rng, perm, relax, prune)
        done += int(it)
        sums = check_pass(ci, cj, c, vel)
        rows["residual"][k] = res
        rows["natural"][k] = natural_from(sums)
        rows["quad_dv"][k], rows["quad_dvr"][k], rows["mean_dvor"][k] = lmgc_norms(sums, vtol)
        u1 = local_velocities(ci, cj, c, vel)
        inc = increment_sums(c, u0, p0, u1)
        rows["inc_quad_dv"][k], rows["inc_quad_dvr"][k], rows["inc_mean_dvor"][k] = lmgc_norms(inc, vtol)
        u0, p0 = u1, c[:, IMPULSE].copy()
        disp[k] = dt * vel[: s.n][mob, :2]
        if done == it1:
            equal = bool(np.array_equal(c[:, IMPULSE], c1[:, IMPULSE]) and np.array_equal(vel, v1))
        if it < want or res <= tol:  # the impulse criterion stopped the solve
            stop_at = k
            break
    # a stopped solve keeps its state: the same values at the later log points, no increment
    for name in SERIES[:5]:
        rows[name][stop_at + 1:] = rows[name][stop_at]
    for name in SERIES[5:8]:
        rows[name][stop_at + 1:] = 0.0
    ref = disp[stop_at]
    mag = np.hypot(ref[:, 0], ref[:, 1])
    for k in range(stop_at + 1):
        err = np.hypot(*(disp[k] - ref).T)
        rows["disp_err_mean"][k] = err.mean() / mag.mean() if mag.mean() > 0 else 0.0
        rows["disp_err_max"][k] = err.max() / mag.max() if mag.max() > 0 else 0.0
    rows["disp_err_mean"][stop_at + 1:] = 0.0
    rows["disp_err_max"][stop_at + 1:] = 0.0
    # the pile goes on from the production solve
    s.c, s.status = c1, st1
    s.vel[:] = v1
    s.rng[:] = rng1
    return dict(series=rows, sweeps=int(it1), residual=float(res1), long_sweeps=done,
                chunk_equal=equal, disp_ref_mean=float(mag.mean()), disp_ref_max=float(mag.max()))


# -- a frame -----------------------------------------------------------------------------------

def first_pass(points, norms: np.ndarray) -> float:
    """The first log point where LMGC90's 'Quad' test passes (all three |norms| < 1), else inf
    (not within the log points; a solve stopped on solver.tol before it never passes)."""
    ok = np.all(np.abs(norms) < 1.0, axis=0)
    return float(points[np.argmax(ok)]) if ok.any() else math.inf


def stays_below(points, err: np.ndarray, level: float) -> float:
    """The first log point from which ``err`` stays below ``level``, else inf."""
    bad = np.nonzero(err >= level)[0]
    if bad.size == 0:
        return float(points[0])
    return float(points[bad[-1] + 1]) if bad[-1] + 1 < len(points) else math.inf


def _med(x) -> float:
    x = np.asarray(x, float)
    return float(np.nanmedian(x)) if np.isfinite(x).any() else np.nan


def summarize(points, steps: list[dict], cap: int, vtol: float = LMGC_TOL) -> dict:
    """Medians over the steps of a frame (module docstring); ``vtol_needed_*``: the tolerance at
    which LMGC90's test would just pass at the first log point, the cap and the last one."""
    k_cap = int(np.searchsorted(points, cap))
    stop = [first_pass(points, np.array([r["series"][n] for n in NORMS])) for r in steps]
    inc_stop = [first_pass(points, np.array([r["series"][n] for n in ("inc_quad_dv", "inc_quad_dvr",
                                                                      "inc_mean_dvor")])) for r in steps]
    at_stop = [r["series"]["disp_err_mean"][int(np.searchsorted(points, k))] if np.isfinite(k) else np.nan
               for r, k in zip(steps, stop)]
    at_stop_max = [r["series"]["disp_err_max"][int(np.searchsorted(points, k))] if np.isfinite(k)
                   else np.nan for r, k in zip(steps, stop)]
    out = dict(steps=len(steps), capped=float(np.mean([r["sweeps"] >= cap for r in steps])),
               sweeps=_med([r["sweeps"] for r in steps]),
               long_sweeps=_med([r["long_sweeps"] for r in steps]),
               chunk_equal=int(sum(r["chunk_equal"] for r in steps)),
               disp_ref_mean=_med([r["disp_ref_mean"] for r in steps]),
               vstop=_med(stop), vstop_q=[float(np.nanpercentile(stop, q, method="nearest"))
                                          for q in (25, 75)],
               vstop_within_cap=float(np.mean([k <= cap for k in stop])),
               vstop_before_ours=float(np.mean([k < r["sweeps"] for k, r in zip(stop, steps)])),
               inc_vstop=_med(inc_stop),
               err_at_vstop=_med(at_stop), err_at_vstop_p90=float(np.nanpercentile(at_stop, 90))
               if np.isfinite(at_stop).any() else np.nan, err_max_at_vstop=_med(at_stop_max),
               err_at_cap=_med([r["series"]["disp_err_mean"][k_cap] for r in steps]),
               err_max_at_cap=_med([r["series"]["disp_err_max"][k_cap] for r in steps]))
    for level in AGREE:
        at = [stays_below(points, r["series"]["disp_err_mean"], level) for r in steps]
        out[f"agree_{level:g}"] = _med(at)
        out[f"agree_{level:g}_within_cap"] = float(np.mean([k <= cap for k in at]))
    for name in ("quad_dv", "quad_dvr", "mean_dvor", "natural", "residual"):
        out[f"{name}_at_cap"] = _med([abs(r["series"][name][k_cap]) for r in steps])
    # the tolerance at which LMGC90's test would just pass: max |norm| x vtol
    for key, k in (("first", 0), ("cap", k_cap), ("last", len(points) - 1)):
        out[f"vtol_needed_{key}"] = _med([vtol * max(abs(r["series"][n][k]) for n in NORMS)
                                          for r in steps])
    return out


def study(run_path, frames, steps: int, every: int, long: int, warm: int = 10,
          vtol: float = LMGC_TOL, progress: bool = True, out=sys.stdout) -> dict:
    """The measurement of the module docstring: one row per frame, the log points' sweeps."""
    from tqdm.auto import tqdm

    rows, points = [], None
    with tqdm(total=len(frames) * steps, unit="step", desc="settle", disable=not progress,
              file=sys.stderr) as bar:
        for f, cfg, theta, s in frame_systems(run_path, frames, warm, bar):
            cap, dth = cfg.solver.max_iter, cfg.protocol.tilt_per_step_deg
            points = log_points(every, cap, max(long, cap))
            recs, t0 = [], time.perf_counter()
            for k in range(steps):
                prepare_step(s, theta + k * dth, dth)
                recs.append(solve_step(s, points, vtol))
                finish_step(s)
                bar.update(1)
            summ = summarize(points, recs, cap, vtol)
            rows.append(dict(frame=int(f), theta=theta, cap=cap, tol=cfg.solver.tol,
                             seconds=time.perf_counter() - t0, summary=summ,
                             step_sweeps=[r["sweeps"] for r in recs],
                             step_long_sweeps=[r["long_sweeps"] for r in recs],
                             chunk_equal=[r["chunk_equal"] for r in recs],
                             disp_ref_mean=[r["disp_ref_mean"] for r in recs],
                             series={n: [[float(f"{x:.4g}") for x in r["series"][n]] for r in recs]
                                     for n in SERIES}))
            print(_line(f, theta, summ, cap), file=out, flush=True)
    return dict(run=str(run_path), steps=steps, every=every, long=long, warm=warm, vtol=vtol,
                sweeps=[] if points is None else points.tolist(), rows=rows)


def _line(f, theta, m, cap) -> str:
    return (f"frame {f:4d} ({theta:5.2f} deg), {m['steps']} steps: ours {m['sweeps']:.0f} sweeps "
            f"(capped {m['capped']:.2f}); LMGC90 Quad test passes at {m['vstop']:.0f} "
            f"({m['vstop_within_cap']:.2f} of the steps within {cap}), displacement error there "
            f"{100 * m['err_at_vstop']:.2g}% (max {100 * m['err_max_at_vstop']:.2g}%); "
            f"at the cap {100 * m['err_at_cap']:.2g}%; within 1% from {m['agree_0.01']:.0f}, "
            f"0.1% from {m['agree_0.001']:.0f} sweeps; chunks equal in {m['chunk_equal']}/{m['steps']}")


# -- the chart -----------------------------------------------------------------------------------

def plot(results: list[dict], path) -> None:
    """Medians over the capped steps (those that stopped at the run's cap; all steps if none did)
    against the sweep, a column per frame (angle) and a line style per run: our residual and the
    natural residual; LMGC90's three norms; the displacement error (band: its quartiles)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    thetas = sorted({round(r["theta"], 2) for res in results for r in res["rows"]})
    fig, axes = plt.subplots(3, len(thetas), figsize=(4.4 * len(thetas), 10), sharex=True,
                             squeeze=False)
    styles = ("-", "--", ":", "-.")
    colors = dict(residual="k", natural="0.5", quad_dv="C0", quad_dvr="C1", mean_dvor="C2",
                  disp_err_mean="C3", disp_err_max="C4")
    counts = {th: [] for th in thetas}
    for r_i, res in enumerate(results):
        x = np.array(res["sweeps"])
        ls = styles[r_i % len(styles)]
        name = Path(res["run"]).stem
        for row in res["rows"]:
            col = thetas.index(round(row["theta"], 2))
            capped = np.array(row["step_sweeps"]) >= row["cap"]
            sel = capped if capped.any() else np.ones_like(capped)
            counts[round(row["theta"], 2)].append(f"{int(capped.sum())}/{capped.size}")

            def series(n):
                return np.abs(np.array(row["series"][n], float))[sel]

            ax = axes[0, col]
            ax.plot(x, np.median(series("residual"), 0), ls, color=colors["residual"],
                    label=f"ours ({name})")
            ax.plot(x, np.median(series("natural"), 0), ls, color=colors["natural"],
                    label=f"natural ({name})")
            ax = axes[1, col]
            for n, lab in (("quad_dv", "QuadDV"), ("quad_dvr", "QuadDVR"), ("mean_dvor", "|MeanDVoR|")):
                ax.plot(x, np.median(series(n), 0), ls, color=colors[n], label=f"{lab} ({name})")
            ax = axes[2, col]
            for n, lab in (("disp_err_mean", "mean"), ("disp_err_max", "max")):
                y = series(n)
                med = np.median(y, 0)
                med[med <= 0] = np.nan
                ax.plot(x, med, ls, color=colors[n], label=f"{lab} ({name})")
                if r_i == 0 and n == "disp_err_mean":
                    lo, hi = np.percentile(y, [25, 75], axis=0)
                    ax.fill_between(x, np.where(lo > 0, lo, np.nan), np.where(hi > 0, hi, np.nan),
                                    color=colors[n], alpha=0.15, lw=0)
    cap = results[0]["rows"][0]["cap"] if results and results[0]["rows"] else None
    tol = results[0]["rows"][0]["tol"] if results and results[0]["rows"] else None
    for col, th in enumerate(thetas):
        axes[0, col].set_title(f"{th:.2f} deg: capped steps {', '.join(counts[th])}", fontsize=10)
        for row_i in range(3):
            ax = axes[row_i, col]
            ax.set_xscale("log")
            ax.set_yscale("log")
            if cap:
                ax.axvline(cap, color="0.7", lw=0.8)
        if tol:
            axes[0, col].axhline(tol, color="k", lw=0.6, ls=":")
        axes[1, col].axhline(1.0, color="k", lw=0.6, ls=":")
        for level in AGREE:
            axes[2, col].axhline(level, color="k", lw=0.6, ls=":")
        axes[2, col].set_xlabel("NLGS sweeps in the step")
    axes[0, 0].set_ylabel("impulse residuals\n(ours stops at solver.tol)")
    axes[1, 0].set_ylabel(f"LMGC90 norms, tol {results[0]['vtol']:g}\n(its test: all three < 1)")
    axes[2, 0].set_ylabel("displacement error against v_ref\n(mobile grains: mean, max)")
    for row_i in range(3):
        axes[row_i, -1].legend(fontsize=7, loc="lower left")
    fig.suptitle("NLGS within the capped tilt steps of a paper run: medians over the steps (grey line: "
                 "the cap; v_ref: the same step at the last sweep shown)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# -- command line --------------------------------------------------------------------------------

def _fail(msg: str):
    raise SystemExit(f"python -m tiltpile.bench.settle: error: {msg}")


def read_results(paths, fail=_fail) -> list[dict]:
    """The JSON files of earlier ``--json`` measurements (``--plot``), one-line errors through
    ``fail``."""
    results = []
    for p in paths:
        try:
            results.append(json.loads(Path(p).read_text()))
        except (OSError, ValueError) as e:
            fail(f"cannot read {p}: {e}")
    return results


def check_outputs(paths, fail=_fail) -> None:
    """A one-line error (through ``fail``) for an output file whose directory does not exist."""
    for p in paths:
        if p and not Path(p).resolve().parent.is_dir():
            fail(f"no such directory for {p}")


def frame_systems(run_path, frames, warm: int, bar):
    """For each frame: (frame, config, theta [deg], system) rebuilt at the frame
    (``flow_caps.rebuilt_state``, ``warm`` steps), telling the progress bar ``bar``."""
    for f in frames:
        bar.set_postfix_str(f"frame {f}: rebuilding the impulses ({warm} steps)")
        cfg, seed, theta, state = rebuilt_state(run_path, f, warm)
        s = protocol.make_system(cfg, seed)
        s.restore(state)
        bar.set_postfix_str(f"frame {f} ({theta:.2f} deg)")
        yield f, cfg, theta, s


def check_run(path, frames, fail=_fail) -> None:
    """One-line errors (through ``fail``) for a run file that cannot be read and frames it does
    not have."""
    from tiltpile.store import RunFileError, open_run

    try:
        with open_run(path) as r:
            n = r.n_frames
    except RunFileError as e:
        fail(str(e))
    bad = [f for f in frames if not 0 <= f < n]
    if bad:
        fail(f"frame {bad[0]} out of range: {path} has frames 0 to {n - 1}")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(prog="python -m tiltpile.bench.settle",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("run", nargs="?")
    ap.add_argument("--frames", type=int, nargs="+")
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--every", type=int, default=25)
    ap.add_argument("--long", type=int, default=20_000)
    ap.add_argument("--warm", type=int, default=10)
    ap.add_argument("--vtol", type=float, default=LMGC_TOL)
    ap.add_argument("--json", help="write the rows (with every step's series) to this file")
    ap.add_argument("--chart", help="draw the chart (PNG) of this measurement, or of --plot's files")
    ap.add_argument("--plot", nargs="+", metavar="JSON",
                    help="chart earlier --json files, no measurement")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    a = ap.parse_args(argv)
    if a.plot:
        if not a.chart:
            _fail("--plot needs --chart PNG")
        results = read_results(a.plot)
        plot(results, a.chart)
        return dict(results=results)
    if not a.run or not a.frames:
        _fail("give a run file and --frames (or --plot JSON ... --chart PNG)")
    if a.steps < 1 or a.every < 1 or a.long < 1 or a.warm < 0 or not a.vtol > 0:
        _fail("--steps, --every and --long must be >= 1, --warm >= 0 and --vtol > 0")
    check_outputs((a.json, a.chart))
    check_run(a.run, a.frames)
    result = study(a.run, a.frames, a.steps, a.every, a.long, a.warm, a.vtol, progress=not a.quiet)
    if a.json:
        Path(a.json).write_text(json.dumps(result))
    if a.chart:
        plot([result], a.chart)
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
