"""The summary of a record (``run_SSSS.npz``, ``tiltpile record``: :func:`record_info`) or of a
directory of records (e.g. the committed ``figures/paper/records/``: :func:`records_info`), as
text.

What the run recorded, from the record alone: seed, grains, frames and theta range, how and where
the run ended, its cost, health warnings, onsets (from the recorded frame table) and the run file
it was written from, then its configuration as TOML; for a directory one line per record, then
the cost of the recorded runs (:func:`tiltpile.view.info.ensemble.cost_lines`).
"""

from __future__ import annotations

from pathlib import Path

from tiltpile.analysis import DEFAULT_PARAMS

from .common import InfoError, config_lines, duration, human_size
from .ensemble import cost_lines


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
            "source": dict(m.get("source") or {}), "onsets": th[on],
            "borrowed": dict(m.get("borrowed") or {})}


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
        out.append(f"wall time  {duration(cost['wall_seconds'])} summed over the invocations"
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
    b = s["borrowed"]
    if b:     # tiltpile.record.compact_record: pieces other records of the run hold bit for bit
        n = (sum(len(v) for v in (b.get("columns") or {}).values()) + len(b.get("members") or {})
             + len(b.get("pictures") or {}))
        out.append(f"borrows    {n} piece(s) from {', '.join(b.get('sources') or [])} "
                   "(held bit for bit there, checked when read)")
    out += config_lines(s["config"], s["seed"])
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
