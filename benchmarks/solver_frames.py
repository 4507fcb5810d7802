"""n_m against the solver, frame by frame: one step re-solved at each sweep cap, order and start.

Usage: python -m benchmarks.solver_frames [--run RUN.h5 --frames K,...] [--bench N:DEG[:capped] ...]
       [--caps 300,1000,3000,10000,100000] [--orders forward,interleaved,alternating,random]
       [--starts warm,cold] [--out DIR]

The states (issue 72, item 1). ``--run FILE --frames K``: the step that produced frame K of a
finished Contact Dynamics run. The simulator is rebuilt at frame K - 1
(``runner.system_from_frame``: positions, velocities, the stored impulses as warm start) and
advanced with the run's own solver settings up to the step before frame K; that last step is the
one re-solved. The run's own setting re-solved there must give frame K back: the table says how
closely it does (sweeps, z, n_m, largest position difference against the stored frame).
``--bench N:DEG``: a bench pile of N grains (``bench.pile``, cached in ``--cache``) tilted to DEG
degrees, at 10x the preset's rate up to DEG - 0.2 and at the preset's rate (0.001 deg per step
in paper-fresh) for the last 0.2 deg; the re-solved step is the next one, or with ``:capped``
the first later step (at the preset's rate, within 1000 steps) that hits the preset's cap.

Each state is re-solved from the same start of step (positions, velocities after gravity,
contact list) once per sweep order, cap and start: ``solver.max_iter`` = cap, the run's
``solver.tol`` (a step that reaches it stops there: every cap above its sweep count gives the
same step, bit for bit), the run's pruning; ``warm`` starts from the previous step's impulses as
every run does, ``cold`` from zero impulses. Per solve: the sweeps it made, whether it
converged (reached tol before the cap), its final per-sweep residual and the natural residual
(``solver.natural_residual``), and of the state it leaves, measured as the analysis measures a
frame (``analysis.tables.frame_observables``, the paper's definitions): z and n_m of the bulk
(rattlers removed; n_m = fully mobilized contacts per grain, a contact mobilized when the solver
left it sliding, |f_t| = mu f_n), the number of sliding contacts (``n_mobilized``) and of active
ones, and dv, the step's velocity spread: the relative L2 distance of the mobile grains'
velocities (vx, vy, r omega) after the step to those of the reference solve (the run's own sweep
order, warm start, the largest cap). Writes ``solver_frames.json`` and ``solver_frames.md`` to
``--out``.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

CAPS = (300, 1000, 3000, 10_000, 100_000)
ORDERS = ("forward", "interleaved", "alternating", "random")
STARTS = ("warm", "cold")
APPROACH_SPEEDUP = 10     # bench piles: the approach runs at this multiple of the preset's rate
SLOW_SPAN_DEG = 0.2       # ... and the last SLOW_SPAN_DEG at the preset's rate
CAPPED_SEARCH_STEPS = 1000  # ``:capped``: steps searched for one that hits the cap


class InputError(ValueError):
    """Bad input, said in one line."""


@dataclass
class StepState:
    """The start of one step to re-solve: the System just before it and how to take it."""

    label: str
    source: dict
    cfg: object              # tiltpile.config.Config of the run (or bench pile)
    system: object           # tiltpile.sim.step.System, before the step
    theta0_deg: float        # the step is taken with gravity at theta0 + dtheta
    dtheta_deg: float
    run_cap: int             # the sweep cap the run had at this step
    stored: dict | None = None  # frame K as the run file holds it (run states only)
    start: dict = field(default_factory=dict)  # System.state() before the step

    @property
    def run_order(self) -> str:
        return self.cfg.solver.sweep

    @property
    def theta_deg(self) -> float:
        return self.theta0_deg + self.dtheta_deg


# ------------------------------------------------------------------------------------------------
# states


def _frame_row(cfg, radius, fixed, box_length, pos, vel, omega, pair, force, status, theta):
    """The analysis' per-frame row (z, n_m, n_mobilized, n_active, ...) of one state."""
    from tiltpile.analysis.tables import frame_observables

    row, _, _ = frame_observables(radius, fixed, box_length, pos, vel, omega, pair, force, status,
                                  theta, mu=cfg.scene.mu, mu_wall=cfg.scene.mu_wall)
    return row


def state_from_run(path, frame: int) -> StepState:
    """The start of the step that produced frame ``frame`` of the run file ``path`` (module
    docstring). Raises InputError for a file that is not a finished CD run or a frame it lacks."""
    from tiltpile import config as cfgmod
    from tiltpile import store
    from tiltpile.runner import system_from_frame

    path = Path(path)
    try:
        run = store.open_run(path)
    except store.RunFileError as e:
        raise InputError(str(e)) from None
    with run:
        cfg = cfgmod.from_dict(run.config)
        if cfg.engine != "cd":
            raise InputError(f"{path} is a {cfg.engine} run: it has no NLGS step to re-solve")
        if not 1 <= frame < run.n_frames:
            raise InputError(f"--frames: frame {frame} out of range: {path.name} has frames "
                             f"1..{run.n_frames - 1} (frame 0 ends the settling, not a tilt step)")
        steps = int(run.step[frame] - run.step[frame - 1])
        if steps != cfg.protocol.frame_every:
            raise InputError(f"--frames: frame {frame} of {path.name} is {steps} steps after the "
                             f"one before it, not frame_every = {cfg.protocol.frame_every}")
        _, sysm = system_from_frame(run, frame - 1)
        n_mobile = int((~np.asarray(run.fixed, bool)).sum())
        sol = cfg.solver
        sliding = sol.max_iter_slide > 0 and run.ke[frame - 1] / n_mobile > sol.slide_cap_ke
        run_cap = int(sol.max_iter_slide if sliding else sol.max_iter)
        pair, force, status = run.contacts(frame)
        row = _frame_row(cfg, run.radius, run.fixed, run.box_length, run.position(frame),
                         run.velocity(frame), run.omega(frame), pair, force, status,
                         float(run.theta_deg[frame]))
        stored = {"sweeps": int(run.iterations[frame]), "z": row["z"], "n_m": row["n_m"],
                  "sliding": row["n_mobilized"], "active": row["n_active"],
                  "position": np.asarray(run.position(frame), dtype=float)}
        theta_prev = float(run.theta_deg[frame - 1])
        dth = cfg.protocol.tilt_per_step_deg
    sysm.params["max_iter"] = run_cap
    if steps > 1:
        sysm.advance(steps - 1, theta_prev, dth)
    st = StepState(label=f"{path.name} frame {frame}",
                   source={"run": str(path), "frame": frame, "seed": int(run.seed)},
                   cfg=cfg, system=sysm, theta0_deg=theta_prev + (steps - 1) * dth,
                   dtheta_deg=dth, run_cap=run_cap, stored=stored)
    st.start = sysm.state()
    return st


def parse_bench(spec: str) -> tuple[int, float, bool]:
    """``N:DEG`` or ``N:DEG:capped`` -> (n, deg, capped); InputError naming the problem."""
    parts = spec.split(":")
    try:
        if len(parts) not in (2, 3) or (len(parts) == 3 and parts[2] != "capped"):
            raise ValueError
        n, deg = int(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"--bench {spec!r}: expected N:DEG or N:DEG:capped, e.g. 4000:6:capped") from None
    if n < 1:
        raise InputError(f"--bench {spec!r}: N must be >= 1")
    if not 0.0 <= deg < 90.0:
        raise InputError(f"--bench {spec!r}: DEG must be in [0, 90)")
    return n, deg, len(parts) == 3


def state_from_bench(n: int, deg: float, capped: bool = False, *, seed: int = 0,
                     preset: str = "paper-fresh", cache=None, progress: bool = False) -> StepState:
    """The start of a step of a bench pile of ``n`` grains tilted to ``deg`` (module docstring)."""
    from benchmarks import pile as bench

    cfg = bench.bench_config(n, preset)
    kw = {} if cache is None else {"cache": Path(cache)}
    s = bench.settled_pile(cfg, seed, progress=progress, **kw)
    dth = cfg.protocol.tilt_per_step_deg
    fast = APPROACH_SPEEDUP * dth
    th = 0.0
    n_fast = max(0, int(math.floor((deg - SLOW_SPAN_DEG) / fast + 1e-9)))
    if n_fast:
        s.advance(n_fast, 0.0, fast)
        th = n_fast * fast
    n_slow = max(0, int(round((deg - th) / dth)))
    if n_slow:
        s.advance(n_slow, th, dth)
        th += n_slow * dth
    cap = int(cfg.solver.max_iter)
    searched = 0
    if capped:
        while True:
            before = s.state()
            rec = s.advance(1, th, dth)
            if rec.iterations[0] >= cap:
                s.restore(before)
                break
            th += dth
            searched += 1
            if searched >= CAPPED_SEARCH_STEPS:
                raise InputError(f"--bench {n}:{deg:g}:capped: no step hit the cap of {cap} sweeps "
                                 f"within {CAPPED_SEARCH_STEPS} steps past {deg:g} deg")
    label = f"bench {n} grains, {th + dth:.3f} deg" + (" (capped step)" if capped else "")
    st = StepState(label=label, source={"bench": n, "tilt_deg": deg, "capped": capped,
                                        "seed": seed, "preset": preset, "steps_searched": searched},
                   cfg=cfg, system=s, theta0_deg=th, dtheta_deg=dth, run_cap=cap)
    st.start = s.state()
    return st


# ------------------------------------------------------------------------------------------------
# solves


def resolve(st: StepState, order: str, cap: int, start: str) -> dict:
    """Re-solve the step of ``st`` once (module docstring); returns its row, and the mobile
    grains' velocities after it under ``"_v"`` (for dv; left out of the JSON)."""
    from tiltpile.sim import solver

    s = st.system
    s.restore(st.start)
    s.params.update(mode=solver.SWEEPS[order], max_iter=int(cap), tol=float(st.cfg.solver.tol))
    if start == "cold":
        s.c[:, solver.IMPULSE] = 0.0
    t0 = time.perf_counter()
    rec = s.advance(1, st.theta0_deg, st.dtheta_deg)
    wall = time.perf_counter() - t0
    nat = float(solver.natural_residual(s.ci, s.cj, s.c, s.vel))
    pair, force, status = s.contacts()
    row = _frame_row(st.cfg, s.radius, s.fixed, s.params["box_length"], s.pos, s.velocity,
                     s.omega, pair, force, status, st.theta_deg)
    sweeps = int(rec.iterations[0])
    mob = ~s.fixed
    out = {"order": order, "start": start, "cap": int(cap), "sweeps": sweeps,
           "converged": bool(sweeps < cap or rec.residual[0] <= st.cfg.solver.tol),
           "residual": float(rec.residual[0]), "natural_residual": nat,
           "z": float(row["z"]), "n_m": float(row["n_m"]), "sliding": int(row["n_mobilized"]),
           "active": int(row["n_active"]), "energy_gain": float(rec.energy_gain[0]),
           "wall_s": wall, "_v": s.vel[: s.n][mob, :3].copy(), "_pos": s.pos.copy()}
    return out


def measure(states, caps=CAPS, orders=ORDERS, starts=STARTS, progress: bool = True) -> list[dict]:
    """Every state re-solved at every cap, order and start; one dict per state (``states`` as
    from ``state_from_run`` / ``state_from_bench``)."""
    caps = sorted({int(c) for c in caps})
    out = []
    for st in states:
        t0 = time.perf_counter()
        rows = []
        for order in orders:
            for start in starts:
                for cap in caps:
                    r = resolve(st, order, cap, start)
                    rows.append(r)
                    if progress:
                        print(f"  {st.label}: {order:11s} {start} cap {cap:>6d}: {r['sweeps']:>6d} "
                              f"sweeps, z {r['z']:.4f}, n_m {r['n_m']:.4f}, sliding "
                              f"{r['sliding']}, {r['wall_s']:.2f} s", file=sys.stderr, flush=True)
        ref = resolve(st, st.run_order, caps[-1], "warm") if st.run_order not in orders or \
            "warm" not in starts else next(r for r in rows if r["order"] == st.run_order
                                            and r["start"] == "warm" and r["cap"] == caps[-1])
        vref = ref["_v"]
        gdt = float(st.system.params["gravity"] * st.system.params["dt"])
        as_run = resolve(st, st.run_order, st.run_cap, "warm")
        for r in (*rows, as_run):
            r.update(_spread(r["_v"], vref, gdt))
        rec = {"label": st.label, "source": st.source, "n_grains": int(st.system.n),
               "n_mobile": int((~st.system.fixed).sum()), "contacts": int(st.start["ci"].shape[0]),
               "theta_deg": st.theta_deg, "tol": float(st.cfg.solver.tol),
               "run_order": st.run_order, "run_cap": st.run_cap,
               "reference": {"order": st.run_order, "start": "warm", "cap": caps[-1]},
               "reference_speed_gdt": float(np.sqrt(np.mean(np.sum(vref ** 2, axis=1)))) / gdt,
               "as_run": {k: as_run[k] for k in ("sweeps", "converged", "z", "n_m", "sliding",
                                                 "active", "dv", "dv_gdt")},
               "rows": [{k: v for k, v in r.items() if not k.startswith("_")} for r in rows]}
        if st.stored is not None:
            stored = dict(st.stored)
            dx = float(np.max(np.abs(as_run["_pos"] - stored.pop("position"))))
            rec["stored"] = {**{k: (float(v) if isinstance(v, float) else int(v)) for k, v in stored.items()},
                             "max_position_difference": dx}
        rec["summary"] = summarize(rec["rows"], caps)
        rec["wall_s"] = time.perf_counter() - t0
        out.append(rec)
    return out


def _spread(v, vref, gdt: float) -> dict:
    """dv: |v - vref| / |vref| (L2 over the mobile grains' vx, vy, r omega; 0 when both are 0,
    inf when only vref is); dv_gdt: the rms over grains of |v - vref| in units of g dt (the
    velocity a grain's weight gives it in one step)."""
    d2 = np.sum((v - vref) ** 2, axis=1)
    norm = float(np.sqrt(np.sum(vref ** 2)))
    diff = float(np.sqrt(np.sum(d2)))
    rel = diff / norm if norm > 0 else (0.0 if diff == 0 else math.inf)
    return {"dv": rel, "dv_gdt": float(np.sqrt(np.mean(d2))) / gdt if d2.size else 0.0}


def summarize(rows: list[dict], caps) -> dict:
    """Per order and start: the cap from which n_m no longer changed up to the largest cap
    (``settled_from``; None when it still changed between the two largest caps, or when only
    the largest gives it and did not converge), whether the largest cap converged; over all
    solves at the largest cap: the range of n_m, of the sliding count and the largest dv."""
    caps = sorted(caps)
    per = {}
    for r in rows:
        per.setdefault((r["order"], r["start"]), {})[r["cap"]] = r
    series = []
    for (order, start), by_cap in per.items():
        nm = [by_cap[c]["n_m"] for c in caps]
        top = by_cap[caps[-1]]
        settled = None
        for i in range(len(caps)):
            if all(x == nm[-1] for x in nm[i:]) and (i < len(caps) - 1 or top["converged"]):
                settled = caps[i]
                break
        series.append({"order": order, "start": start, "settled_from": settled,
                       "converged_at_top": top["converged"], "sweeps_at_top": top["sweeps"],
                       "converged_sweeps": min((by_cap[c]["sweeps"] for c in caps if by_cap[c]["converged"]),
                                               default=None)})
    top = [r for r in rows if r["cap"] == caps[-1]]
    nm = [r["n_m"] for r in top]
    sl = [r["sliding"] for r in top]
    return {"series": series,
            "top_cap": {"n_m_min": min(nm), "n_m_max": max(nm), "sliding_min": min(sl),
                        "sliding_max": max(sl), "dv_max": max(r["dv"] for r in top),
                        "all_converged": all(r["converged"] for r in top)},
            "settled_everywhere": all(s["settled_from"] is not None for s in series)}


# ------------------------------------------------------------------------------------------------
# the table


def _cap_name(c: int) -> str:
    return f"{c // 1000}k" if c >= 1000 and c % 1000 == 0 else str(c)


def _pct(x: float) -> str:
    return f"{100 * x:.2g}%" if math.isfinite(x) else "inf"


def markdown(result: dict) -> str:
    """The Markdown tables of a ``run()`` result: per state, n_m [sliding contacts] and z; dv by
    cap for each order and start (``*``: the solve converged before the cap)."""
    caps = result["caps"]
    lines = [f"Command: `{result['command']}`", "",
             f"Measured {result['date']} on {result['host']}, {result['wall_s']:.0f} s in all.", ""]
    for st in result["states"]:
        ar = st["as_run"]
        lines += [f"### {st['label']}", "",
                  f"{st['n_mobile']} mobile grains, {st['contacts']} candidate contacts, step at "
                  f"{st['theta_deg']:.3f} deg; tol {st['tol']:g}; the run's setting: "
                  f"{st['run_order']}, cap {st['run_cap']}, warm start: {ar['sweeps']} sweeps, "
                  f"z {ar['z']:.4f}, n_m {ar['n_m']:.4f}, {ar['sliding']} sliding of {ar['active']} "
                  f"active contacts, dv {_pct(ar['dv'])}."]
        if "stored" in st:
            sd = st["stored"]
            lines[-1] += (f" The run file's frame: {sd['sweeps']} sweeps, z {sd['z']:.4f}, n_m "
                          f"{sd['n_m']:.4f}, {sd['sliding']} sliding; replay's largest position "
                          f"difference from it {sd['max_position_difference']:.1e} d.")
        lines += ["", "n_m [sliding contacts] by cap (`*`: converged before the cap):", "",
                  "| order | start | " + " | ".join(_cap_name(c) for c in caps) + " | n_m settled from |",
                  "|---|---|" + "---:|" * len(caps) + "---|"]
        by = {}
        for r in st["rows"]:
            by.setdefault((r["order"], r["start"]), {})[r["cap"]] = r
        settled = {(s["order"], s["start"]): s["settled_from"] for s in st["summary"]["series"]}
        for key, rs in by.items():
            cells = [f"{rs[c]['n_m']:.4f} [{rs[c]['sliding']}]{'*' if rs[c]['converged'] else ''}"
                     for c in caps]
            sf = settled[key]
            lines.append(f"| {key[0]} | {key[1]} | " + " | ".join(cells)
                         + f" | {_cap_name(sf) if sf is not None else 'not settled'} |")
        lines += ["", "z; dv (relative to the reference's velocities); dv_gdt (rms, in g dt) by "
                      f"cap (the reference's rms speed: {st['reference_speed_gdt']:.2g} g dt):", "",
                  "| order | start | " + " | ".join(_cap_name(c) for c in caps) + " | sweeps at "
                  + _cap_name(caps[-1]) + " |",
                  "|---|---|" + "---:|" * len(caps) + "---:|"]
        for key, rs in by.items():
            cells = [f"{rs[c]['z']:.4f}; {_pct(rs[c]['dv'])}; {rs[c]['dv_gdt']:.1e}" for c in caps]
            lines.append(f"| {key[0]} | {key[1]} | " + " | ".join(cells)
                         + f" | {rs[caps[-1]]['sweeps']} |")
        tc = st["summary"]["top_cap"]
        lines += ["", f"At cap {_cap_name(caps[-1])}: n_m {tc['n_m_min']:.4f}-{tc['n_m_max']:.4f}, "
                      f"{tc['sliding_min']}-{tc['sliding_max']} sliding contacts, dv up to "
                      f"{_pct(tc['dv_max'])} over the orders and starts; "
                      f"{'every' if tc['all_converged'] else 'not every'} solve converged. "
                      f"({st['wall_s']:.0f} s)", ""]
    return "\n".join(lines)


def run(states, out: Path | None, caps=CAPS, orders=ORDERS, starts=STARTS, command: str = "",
        progress: bool = True) -> dict:
    """Measure ``states`` and write ``solver_frames.json`` and ``.md`` to ``out`` (if given)."""
    import platform

    t0 = time.perf_counter()
    res = measure(states, caps, orders, starts, progress)
    result = {"command": command, "date": time.strftime("%Y-%m-%d"), "host": platform.node(),
              "caps": sorted({int(c) for c in caps}), "orders": list(orders), "starts": list(starts),
              "states": res, "wall_s": time.perf_counter() - t0}
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "solver_frames.json").write_text(json.dumps(result, indent=1) + "\n")
        (out / "solver_frames.md").write_text(markdown(result) + "\n")
    return result


# ------------------------------------------------------------------------------------------------
# command line


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, not usage + error
        raise InputError(message)


def _ints(text: str, what: str, lo: int) -> list[int]:
    try:
        vals = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError(f"{what}: expected comma-separated integers, got {text!r}") from None
    if not vals or min(vals) < lo:
        raise InputError(f"{what}: expected integers >= {lo}, got {text!r}")
    return vals


def _names(text: str, what: str, allowed) -> list[str]:
    vals = [x.strip() for x in text.split(",") if x.strip()]
    bad = [v for v in vals if v not in allowed]
    if bad or not vals:
        raise InputError(f"{what}: unknown {bad or text!r}; allowed: {', '.join(allowed)}")
    return list(dict.fromkeys(vals))


def parse(argv) -> dict:
    """The command line as checked values; InputError (one line) for anything wrong."""
    ap = _Parser(prog="python -m benchmarks.solver_frames", description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, help="a finished CD run file")
    ap.add_argument("--frames", help="with --run: the frames whose step to re-solve, e.g. 140,294")
    ap.add_argument("--bench", action="append", default=[], metavar="N:DEG[:capped]",
                    help="a bench pile of N grains tilted to DEG (repeatable)")
    ap.add_argument("--preset", default="paper-fresh", help="preset of the bench piles")
    ap.add_argument("--seed", type=int, default=0, help="seed of the bench piles")
    ap.add_argument("--cache", type=Path, default=None, help="cache of the bench piles (data/bench)")
    ap.add_argument("--caps", default=",".join(map(str, CAPS)))
    ap.add_argument("--orders", default=",".join(ORDERS))
    ap.add_argument("--starts", default=",".join(STARTS))
    ap.add_argument("--out", type=Path, default=None, help="write solver_frames.json and .md here")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    from tiltpile.sim.solver import SWEEPS

    if (a.run is None) != (a.frames is None):
        raise InputError("--run and --frames go together")
    if a.run is None and not a.bench:
        raise InputError("nothing to measure: give --run FILE --frames K,... and/or --bench N:DEG")
    if a.run is not None and not a.run.is_file():
        raise InputError(f"--run: no such file {a.run}")
    from tiltpile import config as cfgmod
    if a.preset not in cfgmod.PRESETS:
        raise InputError(f"--preset: unknown preset {a.preset!r}; choose one of {', '.join(cfgmod.PRESETS)}")
    return {"run": a.run, "frames": _ints(a.frames, "--frames", 0) if a.frames else [],
            "bench": [parse_bench(b) for b in a.bench], "preset": a.preset, "seed": a.seed,
            "cache": a.cache, "caps": _ints(a.caps, "--caps", 1),
            "orders": _names(a.orders, "--orders", tuple(SWEEPS)),
            "starts": _names(a.starts, "--starts", STARTS), "out": a.out, "quiet": a.quiet}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    prog = "python -m benchmarks.solver_frames"
    try:
        p = parse(argv)
        states = [state_from_run(p["run"], k) for k in p["frames"]]
        for n, deg, capped in p["bench"]:
            states.append(state_from_bench(n, deg, capped, seed=p["seed"], preset=p["preset"],
                                           cache=p["cache"], progress=not p["quiet"]))
    except InputError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    result = run(states, p["out"], p["caps"], p["orders"], p["starts"],
                 command=" ".join([prog, *argv]), progress=not p["quiet"])
    if p["out"] is None:
        print(markdown(result))
    else:
        print(f"wrote {p['out'] / 'solver_frames.json'} and .md in {result['wall_s']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
