"""What every figure notebook starts from: the ensemble tables, its description, sample frames,
and what several figures read from them alike.

:class:`Ensemble` and :func:`load_ensemble` live in :mod:`tiltpile.analysis.ensemble_data` (the
measurement studies use them too); they are re-exported here for the notebooks.
:func:`load` is what the notebooks call: :func:`load_ensemble` with every analysis parameter the
notebook declares and the columns its figure reads (each figure module's ``READS``, a
:class:`Reads`: from records, only those are checked; the tables hold only those). :func:`analysis_params` gives the parameters an ensemble's tables were computed
with, :func:`per_run_quiet` the per-run means over quiet frames (Fig. 2 and the preparation study).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tiltpile.analysis import DEFAULT_PARAMS
from tiltpile.analysis.ensemble_data import Ensemble, Reads, load_ensemble

__all__ = ["Ensemble", "Reads", "load", "load_ensemble", "snapshot", "analysis_params",
           "per_run_quiet", "first_below", "recorded_params"]

# what a figure's JSON names under "analysis" whatever their values: the lost-contact criterion
ALWAYS_RECORDED = ("cutoff", "lost_gap")


def load(data_dir, preset: str | None = None, reads: Reads | None = None, **params) -> Ensemble:
    """The ensemble of ``data_dir`` (:func:`load_ensemble`) analysed with ``params``, any of
    :data:`tiltpile.analysis.DEFAULT_PARAMS` (TypeError for another name), its tables holding
    the columns ``reads`` declares (a figure's ``READS``; None: every column). Its
    ``meta["analysis"]``, which the figure's JSON records, names ``cutoff``, ``lost_gap`` and
    every other parameter whose value differs from its default (the others are the defaults)."""
    unknown = sorted(set(params) - set(DEFAULT_PARAMS))
    if unknown:
        raise TypeError(f"unknown analysis parameter(s) {unknown}; allowed: {sorted(DEFAULT_PARAMS)}")
    return load_ensemble(data_dir, preset, reads, **recorded_params(params))


def recorded_params(params: dict) -> dict:
    """What :func:`load` passes on of the analysis ``params`` (and an ensemble's JSON records):
    ``ALWAYS_RECORDED`` and every other parameter whose value differs from its default."""
    return {k: v for k, v in params.items()
            if k in ALWAYS_RECORDED or not _same_value(v, DEFAULT_PARAMS[k])}


def _same_value(a, b) -> bool:
    return type(a) is type(b) and a == b


def analysis_params(ens: Ensemble) -> dict:
    """The analysis parameters the ensemble's tables were computed with (defaults filled in)."""
    return dict(DEFAULT_PARAMS, **(ens.meta.get("analysis") or {}))


def per_run_quiet(frames: pd.DataFrame, seeds) -> pd.DataFrame:
    """Per run (rows in the order of seeds): mean z, n_m, delta z_gen over its quiet frames and
    the fraction of its quiet frames with delta z_gen < 0 (NaN for a run without quiet frame)."""
    rows = []
    for s in seeds:
        g = frames[(frames["run"] == s) & ~frames["avalanching"].astype(bool)]
        dz = g["dz_gen"].to_numpy(float)
        dz = dz[np.isfinite(dz)]
        rows.append({"run": s, "z": float(g["z"].mean()) if len(g) else np.nan,
                     "n_m": float(g["n_m"].mean()) if len(g) else np.nan,
                     "dz_gen": float(dz.mean()) if dz.size else np.nan,
                     "below": float((dz < 0).mean()) if dz.size else np.nan})
    return pd.DataFrame(rows)


def snapshot(ens: Ensemble, seed: int, frame: int) -> dict:
    """Positions, radii, contacts of one stored frame, and the contacts and positions of the next
    (``next``, ``next_position``; None at the last frame), for the pile pictures of Figs. 1b and 3.

    From the run file, or, for an ensemble loaded from records, from the run's record, which
    holds the frames the pictures choose by default (``tiltpile.record.RecordError`` for another)."""
    if ens.records:
        from tiltpile.record import read_record
        return read_record(ens.record_path(seed), tables=False).snapshot(frame)
    from tiltpile.store import open_run
    with open_run(ens.run_path(seed)) as r:
        pair, force, status = r.contacts(frame)
        last = frame + 1 >= r.n_frames
        return {"position": r.position(frame), "radius": r.radius, "fixed": r.fixed,
                "pair": pair, "force": force, "status": status, "theta_deg": float(r.theta_deg[frame]),
                "box_length": r.box_length, "next": None if last else r.contacts(frame + 1),
                "next_position": None if last else r.position(frame + 1)}


def first_below(path: pd.DataFrame, column: str, level: float) -> float:
    """theta - theta_m where ``path[column]`` first drops below ``level``, walking from far to near
    (linear interpolation between windows; the first window if it starts below; NaN if it never
    does). With ``spanning`` and 1/2: where most quiet frames stop spanning; with ``dz_gen`` and 0:
    where the mean quiet frame crosses the marginal line z = 3 + n_m (Figs. 1 and 7)."""
    s = path[column].to_numpy(float) - level
    t = path["theta_to_onset"].to_numpy(float)
    below = np.flatnonzero(s < 0)
    if below.size == 0:
        return np.nan
    i = int(below[0])
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (t[i] - t[i - 1]) * s[i - 1] / (s[i - 1] - s[i]))
