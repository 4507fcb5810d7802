"""The summary of an ensemble directory (:func:`dir_info`), as text.

One line per run file (``run_*.h5``, and any ``.part`` still being written or interrupted, with
where its last checkpoint stands: history leg or ramp angle, steps, sweeps and wall time so far:
:func:`checkpoint_progress`), then the manifest ``ensemble.json`` (configuration hash, versions,
run statuses) and what the finished runs cost and the rest will (:func:`cost_lines`). With
``records`` (a directory of ``tiltpile record`` files of the same configuration, e.g. the committed
ones of an ensemble whose run files were lost), the recorded runs without a run file here count as
finished too (:func:`recorded_costs`).
The onsets of a directory come from its observables cache (``tiltpile observables DIR``); they
are not computed here.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

from tiltpile.analysis import observables as _ob
from tiltpile.store import checkpoint_path

from .common import InfoError, duration, human_size
from .run import run_summary


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
        sweeps, f"{duration(sec)} per run (median of {c['runs_timed']} timed whole)",
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
