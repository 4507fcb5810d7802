"""The summary of one run file (:func:`run_info`), as text.

The configuration as TOML (every key, defaults included: ``tiltpile simulate --config FILE`` with
it reproduces the run's configuration hash whatever the preset), seed, version, grains, frames,
theta range, the deposition and health summaries stored in the file, the first onsets by the
lost-contact criterion (the paper's: a frame losing more than ``cutoff`` of its active contacts
before the next one, computed with :mod:`tiltpile.analysis`: :func:`onsets`), whether the run is
complete, and its size on disk. :func:`run_summary` gives the same facts as a dict (also one line
of :func:`tiltpile.view.info.ensemble.dir_info`).

A file that is missing, truncated or not a tiltpile run raises
:class:`~tiltpile.view.info.common.InfoError` naming the file and what is wrong.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from tiltpile.analysis import DEFAULT_PARAMS
from tiltpile.analysis import avalanche as _av
from tiltpile.analysis import observables as _ob
from tiltpile.store import RunFileError, open_run

from ..fields import FrameFields
from .common import InfoError, config_lines, duration, human_size


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
        out.append(f"wall time  {duration(cost['wall_seconds'])} summed over the invocations"
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
    out += config_lines(cfg, s["seed"])
    return "\n".join(out)
