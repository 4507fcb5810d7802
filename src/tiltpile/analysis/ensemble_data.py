"""An ensemble directory as tables: the per-frame and per-cluster observables of every run, the
configuration they share, and the first avalanche onset of each run.

What the figure notebooks and the measurement studies (``tiltpile.bench.compare_ensembles``)
start from. The tables are those of :func:`tiltpile.analysis.load_observables` (columns in
:mod:`tiltpile.analysis.observables`); run files are read through :mod:`tiltpile.store` only.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile import __version__
from tiltpile.analysis.observables import load_observables, run_files


@dataclass
class Ensemble:
    """An ensemble directory's per-frame and per-cluster tables and a description for the JSON.

    data_dir: the directory of ``run_SSSS.h5``; frames, clusters: the observables tables of all
    runs (column ``run`` = seed); config: the runs' shared configuration (dict); seeds: sorted by
    run file name; meta: preset, run count, seeds, grains, config hash, tiltpile version and the
    analysis parameters (what each figure's JSON records).
    """

    data_dir: Path
    frames: pd.DataFrame
    clusters: pd.DataFrame
    config: dict
    seeds: list[int]
    meta: dict = field(default_factory=dict)

    @property
    def n_runs(self) -> int:
        return len(self.seeds)

    def run_path(self, seed: int) -> Path:
        """The run file of ``seed`` (``DIR/run_SSSS.h5``)."""
        p = self.data_dir / f"run_{int(seed):04d}.h5"
        if not p.exists():
            raise FileNotFoundError(f"{p}: no run file for seed {seed} in {self.data_dir}")
        return p

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
    """Load (computing if missing) the observables of every ``run_*.h5`` in ``data_dir``.

    Refuses (ValueError) an ensemble whose runs have different configurations, and
    (FileNotFoundError) a directory without run files. ``analysis_params`` go to
    :func:`tiltpile.analysis.load_observables` (cutoff, eps, lost_gap, ...).
    """
    from tiltpile.store import open_run

    data_dir = Path(data_dir)
    files = run_files(data_dir)
    if not files:
        raise FileNotFoundError(f"no run_*.h5 files in {data_dir}: run `tiltpile ensemble` first")
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
    meta = {"preset": preset, "n_runs": len(seeds), "seeds": seeds, "n_grains": cfg["scene"]["n"],
            "config_hash": hashes.pop()[:12], "tiltpile_version": __version__,
            "analysis": dict(analysis_params), "cost": ensemble_cost(costs)}
    return Ensemble(data_dir, frames, clusters, cfg, seeds, meta)


def ensemble_cost(costs: list[dict]) -> dict:
    """What the runs cost, from each run file's ``Run.cost``: per run, the median wall seconds of
    the runs simulated in one invocation (``seconds_per_run``; a resumed run's seconds cover only
    its last part, so it is left out), and the mean time steps, NLGS sweeps and capped steps.
    Keys are None where no run file records them (files written before they were counted)."""
    def mean(key):
        x = [c[key] for c in costs if key in c]
        return float(np.mean(x)) if x else None

    whole = [c["seconds"] for c in costs if "seconds" in c and c.get("resumed_from_frame", -1) < 0]
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
