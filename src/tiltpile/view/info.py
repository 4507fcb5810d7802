"""One-screen summaries of a run file (:func:`run_info`) and of an ensemble directory
(:func:`dir_info`), as text.

A run: the configuration as TOML (every key, defaults included: ``tiltpile simulate --config
FILE`` with it reproduces the run's configuration hash whatever the preset), seed, version,
grains, frames, theta range, the deposition and health summaries stored in the file, the first
onsets by the lost-contact criterion (the paper's: a frame losing more than ``cutoff`` of its
active contacts before the next one, computed with :mod:`tiltpile.analysis`), whether the run is
complete, and its size on disk.

A directory: one line per run file (``run_*.h5``, and any ``.part`` still being written or
interrupted, with where its last checkpoint stands: history leg or ramp angle, steps, sweeps and
wall time so far), then the manifest ``ensemble.json`` (configuration hash, versions, run
statuses) and what the finished runs cost and the rest will (:func:`cost_lines`). With
``records`` (a directory of ``tiltpile record`` files of the same configuration, e.g. the committed
ones of an ensemble whose run files were lost), the recorded runs without a run file here count as
finished too (:func:`recorded_costs`).
The onsets of a directory come from its observables cache (``tiltpile observables DIR``); they
are not computed here.

A record (``run_SSSS.npz``, ``tiltpile record``) or a directory of records (e.g. the committed
``figures/paper/records/``): what the run recorded, from the record alone (:func:`record_info`,
:func:`records_info`): seed, grains, frames and theta range, how and where the run ended, its
cost, health warnings, onsets (from the recorded frame table) and the run file it was written
from; for a directory one line per record, then the cost of the recorded runs.

A file that is missing, truncated or not a tiltpile run raises :class:`InfoError` naming the
file and what is wrong.
"""

from __future__ import annotations

import json
import math
import re
import warnings
from pathlib import Path

import numpy as np

from tiltpile.analysis import DEFAULT_PARAMS
from tiltpile.analysis import avalanche as _av
from tiltpile.analysis import observables as _ob
from tiltpile.config import config_toml
from tiltpile.store import RunFileError, checkpoint_path, open_run, part_path

from .fields import FrameFields


class InfoError(ValueError):
    """A path that is not a readable run file or ensemble directory (the message names it)."""


# ----------------------------------------------------------------------------------------------
# formatting helpers

def _duration(seconds: float) -> str:
    """``1 h 02 min``, ``3 min 05 s`` or ``12.3 s``."""
    if seconds >= 3600:
        return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"
    if seconds >= 60:
        return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"
    return f"{seconds:.1f} s"


def human_size(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n:.1f} GB"


def _g(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.4g}"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return str(v)


# ----------------------------------------------------------------------------------------------
# onsets


def lost_fraction(run, progress: bool = False) -> np.ndarray:
    """Per frame k, the fraction of its active contacts lost by frame k + 1 (NaN at the last
    frame), with the analysis' definitions (:func:`tiltpile.analysis.observables.failure_between`)."""
    ff = FrameFields(run, keep=2)
    nf = int(run.n_frames)
    out = np.full(nf, np.nan)
    bar = None
    if progress and nf > 1:
        from tqdm.auto import tqdm
        bar = tqdm(total=nf - 1, desc="onsets", unit="frame", leave=False)
    for k in range(nf - 1):
        fb = _ob.failure_between(ff.contacts(k), ff.contacts(k + 1), ff.fixed, ff.radius,
                                 ff.box_length, ff.settings["lost_gap"])
        out[k] = fb["lost_fraction"]
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return out


def onsets(run, cutoff: float | None = None, progress: bool = False) -> dict:
    """Avalanche onsets of a run by the lost-contact criterion (default cutoff: the analysis
    default, 2%). Returns dict cutoff, frames (onset frame indices), theta_deg (their tilt),
    max_lost_fraction, notes (resolution warnings of :func:`tiltpile.analysis.segment_avalanches`)."""
    cutoff = DEFAULT_PARAMS["cutoff"] if cutoff is None else cutoff
    lf = lost_fraction(run, progress)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        seg = _av.segment_avalanches(lf, cutoff)
    theta = np.asarray(run.theta_deg, dtype=float)
    fin = lf[np.isfinite(lf)]
    return {"cutoff": cutoff, "frames": seg["onsets"], "theta_deg": theta[seg["onsets"]],
            "max_lost_fraction": float(fin.max()) if fin.size else float("nan"),
            "notes": [str(w.message) for w in caught]}


# ----------------------------------------------------------------------------------------------
# one run


def _open(path: Path):
    try:
        return open_run(path)
    except RunFileError as e:
        raise InfoError(str(e)) from None
    except (OSError, KeyError, ValueError) as e:
        raise InfoError(f"{path}: not a readable tiltpile run file ({type(e).__name__}: {e})") from None


def _part_line(path: Path) -> str:
    return (f"{path}: an incomplete run ({human_size(path.stat().st_size)}), being written or "
            "interrupted; `tiltpile simulate` with the same configuration and seed resumes it")


def complete_config(config: dict) -> dict:
    """Every key of the configuration, the ones a run file leaves out at their defaults included
    (``config.LATER_KEYS`` are stored only when set), so that the TOML of
    :func:`tiltpile.config.config_toml`
    reproduces the run over any preset. A configuration this version cannot validate (a run of
    another version) is returned as stored."""
    from tiltpile import config as cfgmod

    try:
        return cfgmod.from_dict(config).to_dict()
    except (cfgmod.ConfigError, TypeError, ValueError):
        return config


def run_summary(path, with_onsets: bool = True, progress: bool = False) -> dict:
    """The facts :func:`run_info` prints, as a dict (also one line of :func:`dir_info`)."""
    path = Path(path)
    if path.name.endswith(".part"):
        raise InfoError(_part_line(path))
    run = _open(path)
    try:
        try:
            theta = np.asarray(run.theta_deg, dtype=float)
            s = {
                "path": str(path), "size": path.stat().st_size, "seed": run.seed,
                "version": run.tiltpile_version, "config": run.config,
                "config_hash": run.config_hash, "complete": bool(run.f.attrs.get("complete", False)),
                "n_grains": int(run.radius.size), "n_fixed": int(np.sum(run.fixed)),
                "n_frames": run.n_frames,
                "theta_min": float(theta.min()) if theta.size else float("nan"),
                "theta_max": float(theta.max()) if theta.size else float("nan"),
                "dtheta": float(np.median(np.diff(theta))) if theta.size > 1 else float("nan"),
                "steps": int(run.step[-1]) if theta.size else 0,
                "time": float(run.time[-1]) if theta.size else float("nan"),
                "deposition": dict(run.deposition), "health": dict(run.health),
                "jit": run.f.attrs.get("jit", ""),
                "preparation": {k: np.asarray(v).tolist() for k, v in run.preparation.items()},
                "end_reason": run.end_reason, "cost": dict(run.cost),
            }
            if with_onsets and run.n_frames > 1:
                s["onsets"] = onsets(run, progress=progress)
        except (OSError, KeyError, ValueError, IndexError) as e:
            raise InfoError(f"{path}: damaged tiltpile run file ({type(e).__name__}: {e})") from None
    finally:
        run.close()
    return s


def run_info(path, progress: bool = False) -> str:
    """The one-screen text summary of a run file (module docstring)."""
    s = run_summary(path, progress=progress)
    cfg = s["config"]
    out = [f"run file   {s['path']}  ({human_size(s['size'])}, "
           f"{'complete' if s['complete'] else 'NOT complete'})",
           f"seed       {s['seed']}    tiltpile {s['version']}    config hash {s['config_hash'][:12]}",
           f"grains     {s['n_grains']} ({s['n_grains'] - s['n_fixed']} mobile, {s['n_fixed']} fixed "
           f"bottom), box length {cfg.get('scene', {}).get('box_length', '?')} d",
           f"frames     {s['n_frames']}, theta {s['theta_min']:.3f} .. {s['theta_max']:.3f} deg "
           f"(every {s['dtheta']:.3g} deg), {s['steps']} steps, t = {s['time']:.4g} sqrt(d/g)"]
    dep = s["deposition"]
    if dep:
        out.append("deposition " + ", ".join(
            f"{k} {_g(dep[k])}" for k in ("steps", "time", "height", "ke_per_grain", "max_overlap",
                                         "missed") if k in dep))
    prep = s["preparation"]
    if prep:
        legs = ", ".join(f"{t:+g} deg ({n} + {hold} steps)" for t, n, hold in
                         zip(prep["target_deg"], prep["tilt_steps"], prep["hold_steps"]))
        out.append(f"prepared   tilted to {legs} before the ramp")
    cost = s["cost"]
    out.append(f"ended      by {'the slide (protocol.end_ke)' if s['end_reason'] == 'slide' else 'theta_max'}"
               + (f"; {cost['steps']} steps, {cost['sweeps']} sweeps, {cost['capped_steps']} capped"
                  if cost else ""))
    if "wall_seconds" in cost:
        out.append(f"wall time  {_duration(cost['wall_seconds'])} summed over the invocations"
                   + ("" if cost["wall_seconds_whole"] else
                      " since it was resumed from a checkpoint without this sum (partial)"))
    h = s["health"]
    if h:
        warn = h.get("warnings") or []
        keys = ("cap_hit_fraction", "max_overlap", "max_energy_gain", "missed_steps")
        out.append("health     " + ", ".join(f"{k} {_g(h[k])}" for k in keys if k in h)
                   + f"; {len(warn)} warning(s)")
        out += [f"  ! {w}" for w in warn]
    else:
        out.append("health     no summary stored (written before health checks, or not complete)")
    on = s.get("onsets")
    if on is not None:
        th = on["theta_deg"]
        first = ", ".join(f"{t:.2f}" for t in th[:6]) + (" ..." if th.size > 6 else "")
        out.append(f"onsets     {th.size} by the {on['cutoff']:.0%} lost-contact criterion"
                   + (f", first at theta = {first} deg" if th.size else
                      f" (largest lost fraction {on['max_lost_fraction']:.2%})"))
        out += [f"  note: {n}" for n in on["notes"]]
    out.append("")
    out.append("# configuration (reuse: tiltpile simulate --config FILE.toml --seed "
               f"{s['seed']} --out RUN.h5)")
    out.append(config_toml(complete_config(cfg)).rstrip())
    return "\n".join(out)


# ----------------------------------------------------------------------------------------------
# a directory


def _dir_onsets(d: Path) -> dict:
    """{seed: (n_onsets, first onset theta)} from the ensemble's fresh observables cache; {} if
    the cache is missing or stale for any run."""
    try:
        frames, _ = _ob.load_observables(d, compute_missing=False)
    except (FileNotFoundError, OSError, KeyError, ValueError):
        return {}
    out = {}
    for seed, g in frames.groupby("run"):
        on = g["onset"].to_numpy(bool)
        th = g["theta_deg"].to_numpy(float)
        out[int(seed)] = (int(on.sum()), float(th[on][0]) if on.any() else float("nan"))
    return out


def _checkpoint_state(ckpt: Path) -> tuple[dict, float | None] | None:
    """(scalars, wall seconds so far or None) of a checkpoint; None if it cannot be read."""
    import h5py
    try:
        with h5py.File(ckpt, "r") as g:
            sc = json.loads(g.attrs["scalars"])
            wall = float(g.attrs["wall_seconds"]) if "wall_seconds" in g.attrs else None
    except (OSError, KeyError, ValueError):
        return None
    return sc, wall


def cost_lines(costs: list[dict], n_pending: int, running_walls: list[float | None],
               workers: int | None, running_names: list[str] | None = None,
               running_sweeps: list[float | None] | None = None) -> list[str]:
    """What an ensemble's finished runs cost and what is left, from their cost records
    (``Run.cost``): sweeps per run (mean), wall time per run (median of the runs timed whole,
    :func:`tiltpile.analysis.ensemble_data.ensemble_cost`) and its core-hours; the runs left
    (``n_pending`` not started, one per entry of ``running_walls``, the wall seconds their
    checkpoints have spent, None if unknown) at that median, the running ones less what they have
    spent, and in hours of wall time on ``workers`` workers; with ``running_names`` (one per
    running run), what each has to go: the finished runs' mean sweeps less its own at its own
    pace so far where ``running_sweeps`` gives them (a run on a slower machine, or beside other
    work, takes longer than the median), else the median less its time so far. [] without a
    finished run."""
    from tiltpile.analysis.ensemble_data import ensemble_cost
    from tiltpile.report.judging import approx

    if not costs:
        return []
    c = ensemble_cost(costs)
    n = len(costs)
    sweeps = f"{c['sweeps_per_run'] / 1e6:.1f} M sweeps per run (mean)" if c["sweeps_per_run"] else ""
    sec = c["seconds_per_run"]
    if sec is None:
        return [f"  cost     {n} finished: " + ", ".join(
            x for x in (sweeps, "wall time not recorded whole (resumed runs)") if x)]
    out = [f"  cost     {n} finished: " + ", ".join(x for x in (
        sweeps, f"{_duration(sec)} per run (median of {c['runs_timed']} timed whole)",
        f"~{approx(sec * n / 3600, 3)} core-hours (median x {n})") if x)]
    left = n_pending + len(running_walls)
    if left:
        hours = (left * sec - sum(w for w in running_walls if w is not None)) / 3600
        hours = max(hours, 0.0)
        wall = f", ~{approx(hours / workers, 3)} h on {workers} worker(s)" if workers else ""
        out.append(f"  left     {left} run(s) ({n_pending} pending, {len(running_walls)} running): "
                   f"~{approx(hours, 3)} core-hours at that median{wall}")
    if running_names:
        mean_sweeps = c["sweeps_per_run"]
        to_go = []
        for name, w, sw in zip(running_names, running_walls,
                               running_sweeps or [None] * len(running_names)):
            if w is None:
                to_go.append(f"{name} ?")
            elif sw and mean_sweeps and w > 0:
                to_go.append(f"{name} ~{max(mean_sweeps - sw, 0.0) / (sw / w) / 3600:.1f} h "
                             f"({sw / mean_sweeps:.0%} of the mean sweeps done)")
            else:
                to_go.append(f"{name} ~{max(sec - w, 0.0) / 3600:.1f} h")
        out.append("  to go    " + ", ".join(to_go) + " (at its pace so far)")
    return out


def checkpoint_progress(ckpt: Path, protocol: dict) -> str:
    """Where an interrupted or running run stands, from its checkpoint ``ckpt``: 'checkpoint
    2026-11-26 17:13: history leg 6 of 6, step 157800, 80.7 M sweeps, 2.2 h so far' (the leg
    count and the ramp's angle from the ensemble's ``protocol`` when given); '' without a
    readable checkpoint."""
    import time

    got = _checkpoint_state(ckpt)
    if got is None:
        return ""
    sc, wall = got
    phase = sc.get("phase")
    if phase == "pretilt":
        legs = protocol.get("pretilt_deg") or []
        what = f"history leg {int(sc.get('leg', 0)) + 1}" + (f" of {len(legs)}" if legs else "")
    elif phase == "tilt" and protocol.get("tilt_per_step_deg"):
        what = f"ramp at {int(sc.get('tilt_step', 0)) * float(protocol['tilt_per_step_deg']):.2f} deg"
    else:
        what = str(phase)
    when = time.strftime("%Y-%m-%d %H:%M", time.localtime(ckpt.stat().st_mtime))
    spent = f", {wall / 3600:.1f} h so far" if wall is not None else ""
    return (f"checkpoint {when}: {what}, step {int(sc.get('step', 0))}, "
            f"{float(sc.get('sweeps', 0)) / 1e6:.1f} M sweeps{spent}")


def recorded_costs(records, config_hash: str | None, have: set[int]) -> tuple[list[int], list[dict]]:
    """(seeds, cost records) of the records in ``records`` whose seed is not in ``have``, sorted
    by seed. InfoError (one line) for a directory without records, a damaged record or one of
    another configuration than ``config_hash`` (None: they must agree with each other)."""
    from tiltpile.record import RecordError, read_meta, record_files

    records = Path(records)
    files = record_files(records) if records.is_dir() else []
    if not files:
        raise InfoError(f"--records {records}: no records (run_*.npz) there")
    got = {}
    for path in files:
        try:
            meta = read_meta(path)
        except RecordError as e:
            raise InfoError(str(e)) from None
        h = meta.get("config_hash")
        config_hash = config_hash or h
        if h != config_hash:
            raise InfoError(f"{path} is a record of another configuration (hash {str(h)[:12]}, "
                            f"this ensemble {str(config_hash)[:12]})")
        if int(meta["seed"]) not in have:
            got[int(meta["seed"])] = dict(meta.get("cost") or {})
    seeds = sorted(got)
    return seeds, [got[s] for s in seeds]


def _unrecorded_lines(d: Path, records) -> list[str]:
    """A reminder naming the finished run files of ``d`` without an up-to-date record in
    ``records`` (a run file is lost with its disk; its record, committed, is not)."""
    from tiltpile.figures.records import record_status

    st = record_status(d, records)
    todo = [Path(f).name for f, fresh in zip(st["run_file"], st["fresh"]) if not fresh]
    if not todo:
        return []
    return [f"  to record {', '.join(todo)}: finished, with no up-to-date record in {records} "
            f"(tiltpile record {d} --out {records}, then commit it)"]


def _seed_ranges(seeds: list[int]) -> str:
    """'0-11, 14' of sorted seeds."""
    out, start = [], None
    for i, s in enumerate(seeds):
        start = s if start is None else start
        if i + 1 == len(seeds) or seeds[i + 1] != s + 1:
            out.append(f"{start}" if start == s else f"{start}-{s}")
            start = None
    return ", ".join(out)


def dir_info(d, records=None) -> str:
    """One line per run of an ensemble directory, then its manifest (module docstring)."""
    from tiltpile.config import ConfigError
    from tiltpile.ensemble import read_manifest

    d = Path(d)
    files = sorted(d.glob("run_*.h5"))
    parts = sorted(p for p in d.glob("run_*.h5.part") if not p.with_suffix("").exists())
    try:
        man = read_manifest(d)
    except ConfigError as e:
        man, man_error = None, str(e)
    else:
        man_error = None
    if not files and not parts and man is None:
        raise InfoError(f"{d}: no run files (run_*.h5) and no ensemble manifest here")
    ons = _dir_onsets(d) if files else {}
    out = [f"ensemble   {d}  ({len(files)} run file(s), {len(parts)} incomplete)"]
    head = f"{'file':<18} {'seed':>5} {'grains':>6} {'frames':>6} {'theta max':>9} {'onsets':>6} " \
           f"{'first':>6} {'warn':>4} {'size':>9}  state"
    out.append(head)
    total = 0
    costs = []
    for p in files:
        size = p.stat().st_size
        total += size
        try:
            s = run_summary(p, with_onsets=False)
        except InfoError as e:
            out.append(f"{p.name:<18} {'':>5} unreadable: {str(e).removeprefix(str(p) + ': ')}")
            continue
        if s["complete"] and s["cost"]:
            costs.append(s["cost"])
        n_on, first = ons.get(s["seed"], (None, float("nan")))
        warn = len(s["health"].get("warnings") or []) if s["health"] else "-"
        out.append(f"{p.name:<18} {s['seed']:>5} {s['n_grains']:>6} {s['n_frames']:>6} "
                   f"{s['theta_max']:>9.2f} {('-' if n_on is None else n_on):>6} "
                   f"{('-' if math.isnan(first) else f'{first:.2f}'):>6} {warn:>4} "
                   f"{human_size(size):>9}  {'complete' if s['complete'] else 'NOT complete'}")
    rec_lines = []
    if records is not None:
        here = {int(m.group(1)) for p in files if (m := re.match(r"run_(\d+)\.h5$", p.name))}
        rec_seeds, rec_costs = recorded_costs(records, (man or {}).get("config_hash"), here)
        costs += rec_costs
        rec_lines = [f"  records  {records}: {len(rec_seeds)} finished run(s) recorded whose run "
                     f"file is not here" + (f" (seeds {_seed_ranges(rec_seeds)})" if rec_seeds else "")]
        rec_lines += _unrecorded_lines(d, records)
    protocol = ((man or {}).get("config") or {}).get("protocol") or {}
    for p in parts:
        size = p.stat().st_size
        total += size
        out.append(f"{p.name:<18} {'':>5} {'':>6} {'':>6} {'':>9} {'':>6} {'':>6} {'':>4} "
                   f"{human_size(size):>9}  incomplete (running or interrupted)")
        where = checkpoint_progress(checkpoint_path(p.with_suffix("")), protocol)
        if where:
            out.append(f"{'':<18} {where}")
    out.append(f"total size {human_size(total)}")
    if files and not ons:
        out.append(f"onsets: no fresh observables cache; run `tiltpile observables {d}`")
    out.append("")
    if man_error:
        out.append(f"manifest   {man_error}")
    elif man is None:
        out.append("manifest   none (not made by `tiltpile ensemble`)")
    else:
        runs = man.get("runs", {})
        counts = {}
        for r in runs.values():
            counts[r.get("status", "?")] = counts.get(r.get("status", "?"), 0) + 1
        out.append(f"manifest   {d / 'ensemble.json'}: {len(man.get('seeds', []))} seed(s), "
                   + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
        out.append(f"  config hash {str(man.get('config_hash', ''))[:12]}, tiltpile "
                   f"{man.get('tiltpile_version', '?')}, versions "
                   + ", ".join(f"{k} {v}" for k, v in (man.get("versions") or {}).items()))
        failed = [r for r in runs.values() if r.get("status") == "failed"]
        for r in failed:
            out.append(f"  failed: seed {r.get('seed')}: {r.get('error')}")
        inv = man.get("invocations") or []
        if inv:
            out.append(f"  {len(inv)} invocation(s), last {inv[-1].get('started', '?')}")
        running = [Path(d / r["file"]) for r in runs.values()
                   if r.get("status") == "running" and r.get("file")]
        states = [_checkpoint_state(checkpoint_path(p)) or ({}, None) for p in running]
        walls = [w for _, w in states]
        sweeps = [float(sc["sweeps"]) if "sweeps" in sc else None for sc, _ in states]
        m = re.search(r"(\d+) workers?", str(inv[-1].get("engine", ""))) if inv else None
        out += rec_lines
        out += cost_lines(costs, counts.get("pending", 0), walls, int(m.group(1)) if m else None,
                          [p.name for p in running], sweeps)
    if man is None and rec_lines:
        out += rec_lines + cost_lines(costs, 0, [], None)
    return "\n".join(out)


# ----------------------------------------------------------------------------------------------
# records


def _read_record(path: Path):
    from tiltpile.record import RecordError, read_record

    try:
        return read_record(path, tables=True, pictures=False)
    except RecordError as e:
        raise InfoError(str(e)) from None


def record_summary(path) -> dict:
    """The facts of one record (:func:`record_info`, a line of :func:`records_info`)."""
    path = Path(path)
    r = _read_record(path)
    m, f = r.meta, r.frames
    th = f["theta_deg"].to_numpy(float)
    on = f["onset"].to_numpy(bool)
    return {"path": str(path), "size": path.stat().st_size, "seed": int(m["seed"]),
            "config": m.get("config") or {}, "config_hash": str(m.get("config_hash", "")),
            "version": m.get("tiltpile_version", "?"), "n_grains": int(m["n_grains"]),
            "n_frames": int(m["n_frames"]),
            "theta_min": float(th.min()) if th.size else float("nan"),
            "theta_max": float(th.max()) if th.size else float("nan"),
            "end_reason": m.get("end_reason"), "end_theta_deg": m.get("end_theta_deg"),
            "cost": dict(m.get("cost") or {}), "health": dict(m.get("health") or {}),
            "source": dict(m.get("source") or {}), "onsets": th[on]}


def _ended(s: dict) -> str:
    end = s["end_theta_deg"]
    where = f" at {end:.2f} deg" if isinstance(end, (int, float)) else ""
    return ("the slide (protocol.end_ke)" if s["end_reason"] == "slide" else "theta_max") + where


def record_info(path) -> str:
    """The one-screen text summary of a record (module docstring)."""
    s = record_summary(path)
    cost, src, th = s["cost"], s["source"], s["onsets"]
    out = [f"record     {s['path']}  ({human_size(s['size'])}; written by `tiltpile record`)",
           f"seed       {s['seed']}    tiltpile {s['version']}    config hash {s['config_hash'][:12]}",
           f"grains     {s['n_grains']}",
           f"frames     {s['n_frames']}, theta {s['theta_min']:.3f} .. {s['theta_max']:.3f} deg",
           f"ended      by {_ended(s)}"
           + (f"; {cost['steps']} steps, {cost['sweeps']} sweeps, {cost['capped_steps']} capped"
              if "steps" in cost else "")]
    if "wall_seconds" in cost:
        out.append(f"wall time  {_duration(cost['wall_seconds'])} summed over the invocations"
                   + ("" if cost.get("wall_seconds_whole") else " (partial: resumed before this sum)"))
    warn = s["health"].get("warnings") or []
    out.append(f"health     {len(warn)} warning(s)")
    out += [f"  ! {w}" for w in warn]
    first = ", ".join(f"{t:.2f}" for t in th[:6]) + (" ..." if th.size > 6 else "")
    out.append(f"onsets     {th.size} by the {DEFAULT_PARAMS['cutoff']:.0%} lost-contact criterion"
               + (f", first at theta = {first} deg" if th.size else ""))
    if src:
        out.append(f"from       {src.get('file', '?')} ({human_size(int(src.get('size', 0)))}, "
                   f"frames sha256 {str(src.get('frames_sha256', ''))[:12]})")
    out.append("")
    out.append("# configuration (reuse: tiltpile simulate --config FILE.toml --seed "
               f"{s['seed']} --out RUN.h5)")
    out.append(config_toml(complete_config(s["config"])).rstrip())
    return "\n".join(out)


def records_info(d) -> str:
    """One line per record of a directory, then the recorded runs' cost (module docstring)."""
    from tiltpile.record import record_files

    d = Path(d)
    files = record_files(d)
    if not files:
        raise InfoError(f"{d}: no records (run_*.npz) here")
    rows = [record_summary(p) for p in files]
    hashes = sorted({r["config_hash"][:12] for r in rows})
    out = [f"records    {d}  ({len(rows)} record(s), config hash {', '.join(hashes)}"
           + (": records of different configurations" if len(hashes) > 1 else "") + ")",
           f"{'record':<14} {'seed':>5} {'grains':>6} {'frames':>6} {'theta max':>9} {'end':>5} "
           f"{'onsets':>6} {'first':>6} {'warn':>4} {'size':>9}"]
    total = 0
    for r in rows:
        total += r["size"]
        th = r["onsets"]
        out.append(f"{Path(r['path']).name:<14} {r['seed']:>5} {r['n_grains']:>6} "
                   f"{r['n_frames']:>6} {r['theta_max']:>9.2f} "
                   f"{('slide' if r['end_reason'] == 'slide' else 'max'):>5} {th.size:>6} "
                   f"{(f'{th[0]:.2f}' if th.size else '-'):>6} "
                   f"{len(r['health'].get('warnings') or []):>4} {human_size(r['size']):>9}")
    out.append(f"total size {human_size(total)}")
    out += cost_lines([r["cost"] for r in rows if r["cost"]], 0, [], None)
    return "\n".join(out)


def info(path, progress: bool = False, records=None) -> str:
    """:func:`run_info` of a file, :func:`dir_info` of a directory (with ``records``, see there)."""
    p = Path(path)
    if records is not None and not p.is_dir():
        raise InfoError(f"--records: {p} is not an ensemble directory")
    if p.is_dir():
        if records is None and not any(p.glob("run_*.h5*")) and not (p / "ensemble.json").exists() \
                and any(p.glob("run_*.npz")):
            return records_info(p)
        return dir_info(p, records=records)
    if p.suffix == ".npz" and p.exists():
        return record_info(p)
    if not p.exists():
        hint = " (an incomplete .part file exists)" if part_path(p).exists() else ""
        raise InfoError(f"{p}: no such run file or directory{hint}")
    return run_info(p, progress=progress)
