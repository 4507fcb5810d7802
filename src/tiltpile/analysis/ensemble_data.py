"""An ensemble directory as tables: the per-frame and per-cluster observables of every run, the
configuration they share, and the first avalanche onset of each run.

What the figure notebooks and the measurement studies (``tiltpile.bench.compare_ensembles``)
start from. The tables are those of :func:`tiltpile.analysis.load_observables` (columns in
:mod:`tiltpile.analysis.observables`); run files are read through :mod:`tiltpile.store` only.

A directory without run files may hold their records instead (``run_SSSS.npz``,
:mod:`tiltpile.record`, written by ``tiltpile record``): the same tables at the default analysis
parameters (without the cluster columns no figure reads), the same configuration, seeds and
description, and the frames of the pile pictures.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile import __version__
from tiltpile.analysis.observables import load_observables, run_files, table_params
from tiltpile.analysis.tables import table_code


@dataclass
class Ensemble:
    """An ensemble directory's per-frame and per-cluster tables and a description for the JSON.

    data_dir: the directory of ``run_SSSS.h5`` (or of their records); frames, clusters: the
    observables tables of all runs (column ``run`` = seed); config: the runs' shared
    configuration (dict); seeds: sorted by run file name; meta: preset, run count, seeds, grains,
    config hash, tiltpile version, the analysis parameters and the runs' cost (what each figure's
    JSON records); records: {seed: record path} when loaded from records, else empty.
    """

    data_dir: Path
    frames: pd.DataFrame
    clusters: pd.DataFrame
    config: dict
    seeds: list[int]
    meta: dict = field(default_factory=dict)
    records: dict = field(default_factory=dict)

    @property
    def n_runs(self) -> int:
        return len(self.seeds)

    def run_path(self, seed: int) -> Path:
        """The run file of ``seed`` (``DIR/run_SSSS.h5``)."""
        p = self.data_dir / f"run_{int(seed):04d}.h5"
        if not p.exists():
            how = " (the ensemble was loaded from records)" if self.records else ""
            raise FileNotFoundError(f"{p}: no run file for seed {seed} in {self.data_dir}{how}")
        return p

    def record_path(self, seed: int) -> Path:
        """The record of ``seed`` (an ensemble loaded from records)."""
        if int(seed) not in self.records:
            raise FileNotFoundError(f"no record of seed {seed} in {self.data_dir}")
        return self.records[int(seed)]

    def sample_seed(self, seed: int | None = None) -> int:
        """``seed`` if given (checked), else the first seed whose run has an avalanche onset."""
        if seed is not None:
            if int(seed) not in self.seeds:
                raise ValueError(f"sample seed {seed} is not in the ensemble (seeds {self.seeds})")
            return int(seed)
        onsets = self.frames.groupby("run")["theta_m"].first()
        ok = [s for s in self.seeds if s in onsets.index and np.isfinite(onsets[s])]
        return ok[0] if ok else self.seeds[0]


def load_ensemble(data_dir, preset: str | None = None, **analysis_params) -> Ensemble:
    """Load (computing if missing) the observables of every ``run_*.h5`` in ``data_dir``; in a
    directory without run files, those of its records ``run_*.npz`` (:func:`load_records`).

    Refuses (ValueError) an ensemble whose runs have different configurations, and
    (FileNotFoundError) a directory without run files or records. ``analysis_params`` go to
    :func:`tiltpile.analysis.load_observables` (cutoff, eps, lost_gap, ...).
    """
    from tiltpile.record import record_files
    from tiltpile.store import open_run

    data_dir = Path(data_dir)
    files = run_files(data_dir)
    if not files:
        if record_files(data_dir):
            return load_records(data_dir, preset, **analysis_params)
        raise FileNotFoundError(f"no run_*.h5 files (nor their records run_*.npz) in {data_dir}: "
                                "run `tiltpile ensemble` first")
    hashes, seeds, cfg, costs = set(), [], None, []
    for f in files:
        with open_run(f) as r:
            hashes.add(r.config_hash)
            seeds.append(r.seed)
            cfg = r.config
            costs.append(dict(r.cost))
    if len(hashes) > 1:
        raise ValueError(f"{data_dir} mixes runs of {len(hashes)} configurations")
    frames, clusters = load_observables(data_dir, progress=False, **analysis_params)
    meta = _describe(preset, seeds, cfg, hashes.pop(), analysis_params, costs)
    return Ensemble(data_dir, frames, clusters, cfg, seeds, meta)


def _describe(preset, seeds, cfg, config_hash, analysis_params, costs) -> dict:
    """An ensemble's ``meta`` (the same from run files and from records); ``history``: the piles'
    preparation before the ramp: its legs ``pretilt_deg`` ([] for fresh piles), their own rate
    (0: the ramp's) and a ``label`` (:func:`tiltpile.config.history_label`, "fresh", "±16° 2
    cycles at 10x rate", ...)."""
    from tiltpile.config import history_label, rate_suffix

    proto = cfg.get("protocol", {})
    legs = [float(a) for a in proto.get("pretilt_deg") or []]
    history = {"pretilt_deg": legs,
               "pretilt_per_step_deg": float(proto.get("pretilt_per_step_deg") or 0.0),
               "label": history_label(legs) + (rate_suffix(cfg) if legs else "")}
    return {"preset": preset, "n_runs": len(seeds), "seeds": seeds, "n_grains": cfg["scene"]["n"],
            "config_hash": config_hash[:12], "tiltpile_version": __version__,
            "analysis": dict(analysis_params), "history": history, "cost": ensemble_cost(costs)}


def _same(a, b) -> bool:
    """Equal as JSON would write them (tuples as lists, NaN equal to NaN)."""
    import json
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def load_records(data_dir, preset: str | None = None, **analysis_params) -> Ensemble:
    """The ensemble of the records ``run_*.npz`` in ``data_dir`` (:mod:`tiltpile.record`): the
    same Ensemble as :func:`load_ensemble` gives from their run files, except the cluster
    columns the records leave out, with ``records`` set (pile pictures:
    :func:`tiltpile.figures.data.snapshot`).

    A record holds the tables of one table code at the default parameters: records of other
    code (:func:`tiltpile.analysis.tables.table_code`), or ``analysis_params`` that change the
    tables (cutoff, lost_gap, ...), are
    refused (``tiltpile.record.RecordError``, one line); so are damaged records (every member's
    checksum is checked) and records of other format versions. Records of different
    configurations are refused (ValueError), a directory without records is FileNotFoundError.
    """
    from tiltpile.record import RecordError, read_record, record_files

    data_dir = Path(data_dir)
    paths = record_files(data_dir)
    if not paths:
        raise FileNotFoundError(f"no records run_*.npz in {data_dir}: write them with "
                                "`tiltpile record`")
    wanted = table_params(**analysis_params)
    hashes, seeds, cfg, costs, fr, cl, records = set(), [], None, [], [], [], {}
    for path in paths:
        rec = read_record(path)    # every member, so that every checksum is checked
        m = rec.meta
        if m.get("analysis_code") != table_code():
            raise RecordError(f"{path}: a record of table code {m.get('analysis_code')}, this "
                              f"tiltpile computes the tables with code {table_code()}; rewrite the "
                              "records from the run files (`make records`, `tiltpile record`)")
        if not _same(m.get("analysis_params"), wanted):
            held = m.get("analysis_params") or {}
            diff = sorted(k for k in wanted if not _same(wanted[k], held.get(k)))
            raise RecordError(f"{path}: records hold the tables at the default analysis parameters; "
                              f"{', '.join(f'{k}={wanted[k]!r}' for k in diff)} needs the run files")
        hashes.add(m["config_hash"])
        seeds.append(rec.seed)
        cfg = m["config"]
        costs.append(dict(m.get("cost") or {}))
        fr.append(rec.frames)
        cl.append(rec.clusters)
        records[rec.seed] = path
    if len(hashes) > 1:
        raise ValueError(f"{data_dir} mixes records of {len(hashes)} configurations")
    frames = pd.concat(fr, ignore_index=True).sort_values(["run", "frame"], kind="stable")
    clusters = pd.concat(cl, ignore_index=True).sort_values(["run", "frame", "cluster"], kind="stable")
    meta = _describe(preset, seeds, cfg, hashes.pop(), analysis_params, costs)
    return Ensemble(data_dir, frames.reset_index(drop=True), clusters.reset_index(drop=True), cfg,
                    seeds, meta, records)


def ensemble_cost(costs: list[dict]) -> dict:
    """What the runs cost, from each run file's ``Run.cost``: per run, the median wall seconds
    (``seconds_per_run``) over the runs whose whole wall time is known: the sum over invocations
    (``wall_seconds``) where every invocation was counted, else the seconds of a run simulated in
    one invocation (a resumed run's ``seconds`` cover only its last part, so such a run is left
    out); and the mean time steps, NLGS sweeps and capped steps. Keys are None where no run file
    records them (files written before they were counted)."""
    def mean(key):
        x = [c[key] for c in costs if key in c]
        return float(np.mean(x)) if x else None

    def whole_seconds(c):
        if c.get("wall_seconds_whole"):
            return c["wall_seconds"]
        return c["seconds"] if "seconds" in c and c.get("resumed_from_frame", -1) < 0 else None

    whole = [w for w in map(whole_seconds, costs) if w is not None]
    return {"runs_timed": len(whole),
            "seconds_per_run": float(np.median(whole)) if whole else None,
            "steps_per_run": mean("steps"), "sweeps_per_run": mean("sweeps"),
            "capped_steps_per_run": mean("capped_steps")}


def first_onsets(frames: pd.DataFrame, seeds) -> np.ndarray:
    """theta [deg] of the first avalanche onset of each run, in the order of ``seeds``.

    frames: per-frame table with columns run, frame, theta_deg, onset (bool; the lost-contact
    criterion of :func:`tiltpile.analysis.segment_avalanches`). Returns a float array of
    len(seeds), NaN for a run without onset.
    """
    on = frames[frames["onset"].astype(bool)].sort_values(["run", "frame"], kind="stable")
    first = on.groupby("run")["theta_deg"].first()
    return np.array([float(first.get(s, np.nan)) for s in seeds])
