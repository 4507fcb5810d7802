"""What every figure notebook starts from: the ensemble tables, its description, sample frames."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile import __version__
from tiltpile.analysis import load_observables, run_files


@dataclass
class Ensemble:
    """An ensemble directory's per-frame and per-cluster tables and a description for the JSON."""

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

    Refuses an ensemble whose runs have different configurations. ``analysis_params`` go to
    :func:`tiltpile.analysis.load_observables` (cutoff, eps, ...).
    """
    from tiltpile.store import open_run
    data_dir = Path(data_dir)
    files = run_files(data_dir)
    if not files:
        raise FileNotFoundError(f"no run_*.h5 files in {data_dir}: run `tiltpile ensemble` first")
    hashes, seeds, cfg = set(), [], None
    for f in files:
        with open_run(f) as r:
            hashes.add(r.config_hash)
            seeds.append(r.seed)
            cfg = r.config
    if len(hashes) > 1:
        raise ValueError(f"{data_dir} mixes runs of {len(hashes)} configurations")
    frames, clusters = load_observables(data_dir, progress=False, **analysis_params)
    meta = {"preset": preset, "n_runs": len(seeds), "seeds": seeds, "n_grains": cfg["scene"]["n"],
            "config_hash": hashes.pop()[:12], "tiltpile_version": __version__,
            "analysis": dict(analysis_params)}
    return Ensemble(data_dir, frames, clusters, cfg, seeds, meta)


def snapshot(ens: Ensemble, seed: int, frame: int) -> dict:
    """Positions, radii, contacts of one stored frame, and the contacts and positions of the next
    (``next``, ``next_position``; None at the last frame), for the pile pictures of Figs. 1b and 3."""
    from tiltpile.store import open_run
    with open_run(ens.run_path(seed)) as r:
        pair, force, status = r.contacts(frame)
        last = frame + 1 >= r.n_frames
        return {"position": r.position(frame), "radius": r.radius, "fixed": r.fixed,
                "pair": pair, "force": force, "status": status, "theta_deg": float(r.theta_deg[frame]),
                "box_length": r.box_length, "next": None if last else r.contacts(frame + 1),
                "next_position": None if last else r.position(frame + 1)}
