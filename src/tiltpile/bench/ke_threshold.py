"""How stable is Fig. 2a's kinetic-energy threshold? The threshold as runs are added, and with one run left out.

Usage: python -m tiltpile.bench.ke_threshold DIR [--every K] [--ke-column ke_trans]
  DIR  an ensemble directory: its records ``run_*.npz`` (``tiltpile record``) if it holds any,
       else its run files (their observables are computed if missing)
  --every K  the cumulative rows: the first K, 2K, ... runs in seed order, and all of them
       (default 2)

The threshold is the one Fig. 2a reports (:func:`tiltpile.analysis.stats.ke_threshold` at its
defaults: five bins per decade, the power law fitted between the 30% and 80% quantiles of the
quiet frames' energies, the first of two consecutive bins more than twice above it). It is the
lower edge of a bin, so it moves in steps of 10^(1/5) = 1.58. Per row: the threshold, the fitted
slope, and each run's first sustained flow at that threshold (the per-scale table's row of that
name: the first stretch above it held for ``slide_sustain_deg`` of tilt,
:func:`tiltpile.analysis.avalanche.first_slide`), as its median and range over the runs.

Leave one out: the threshold of the whole ensemble without each run in turn, and how many of
those thresholds take each value. A threshold that sits at a gap of the density comes back the
same whichever run is left out; one that sits on a gradual departure from the power law moves by
a bin or two with the runs that make the ensemble.

docs/performance-log.md ("The paper ensemble, twenty-four runs") records what it measured on the
paper ensemble's records.
"""
from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile.analysis.avalanche import first_slide
from tiltpile.analysis.stats import ke_threshold
from tiltpile.analysis.tables import DEFAULT_PARAMS


def load(data_dir) -> tuple[pd.DataFrame, list[int]]:
    """(frames of every run sorted by run and frame, seeds) of ``data_dir``: from its records if
    it holds any, else from its run files."""
    from tiltpile.analysis.ensemble_data import load_ensemble, load_records
    from tiltpile.record import record_files

    d = Path(data_dir)
    if not d.is_dir():
        raise FileNotFoundError(f"{d}: no such directory")
    ens = load_records(d) if record_files(d) else load_ensemble(d)
    return ens.frames.sort_values(["run", "frame"], kind="stable"), list(ens.seeds)


def row(frames: pd.DataFrame, seeds, ke_column: str = "ke_trans",
        sustain_deg: float = DEFAULT_PARAMS["slide_sustain_deg"]) -> dict:
    """The Fig. 2a threshold of the runs ``seeds`` of ``frames``, its slope, and each run's first
    sustained flow at it (NaN: none)."""
    f = frames[frames["run"].isin(list(seeds))]
    dep, _ = ke_threshold(f, ke_column)
    thr = float(dep["threshold"])
    flow = np.array([first_slide(g["theta_deg"].to_numpy(), g[ke_column].to_numpy(), thr, sustain_deg)
                     for _, g in f.groupby("run", sort=True)])
    return {"seeds": list(seeds), "threshold": thr, "slope": float(dep["slope"]), "flow": flow}


def stability(frames: pd.DataFrame, seeds, every: int = 2, ke_column: str = "ke_trans") -> dict:
    """{"cumulative": rows of the first every, 2 every, ... runs and of all, "left_out": {seed:
    threshold without it}} (:func:`row`)."""
    if every < 1:
        raise ValueError(f"--every must be >= 1, got {every}")
    seeds = list(seeds)
    sizes = sorted(set(range(every, len(seeds), every)) | {len(seeds)})
    cumulative = [row(frames, seeds[:n], ke_column) for n in sizes]
    left_out = {s: row(frames, [t for t in seeds if t != s], ke_column)["threshold"]
                for s in seeds} if len(seeds) > 1 else {}
    return {"cumulative": cumulative, "left_out": left_out}


def _angles(x: np.ndarray) -> str:
    ok = x[np.isfinite(x)]
    none = f"; {x.size - ok.size} of {x.size} none" if ok.size < x.size else ""
    if not ok.size:
        return f"none of {x.size} runs"
    return f"median {np.median(ok):.2f}, {ok.min():.2f}-{ok.max():.2f} deg{none}"


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(prog="python -m tiltpile.bench.ke_threshold",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("dir", help="ensemble directory (records or run files)")
    ap.add_argument("--every", type=int, default=2, help="runs added per cumulative row (default 2)")
    ap.add_argument("--ke-column", default="ke_trans", choices=("ke_trans", "ke_rot"))
    a = ap.parse_args(argv)
    if a.every < 1:
        ap.error(f"--every must be >= 1, got {a.every}")
    try:
        frames, seeds = load(a.dir)
    except (FileNotFoundError, ValueError) as e:
        ap.exit(2, f"ke_threshold: {e}\n")
    out = stability(frames, seeds, a.every, a.ke_column)
    print(f"{a.dir}: {len(seeds)} runs, Fig. 2a threshold on {a.ke_column} (m g d per grain)")
    print(f"{'runs':>5s}  {'threshold':>9s}  {'slope':>6s}  first sustained flow at it")
    for r in out["cumulative"]:
        print(f"{len(r['seeds']):5d}  {r['threshold']:9.1e}  {r['slope']:6.2f}  {_angles(r['flow'])}")
    if out["left_out"]:
        counts = Counter(f"{t:.1e}" for t in out["left_out"].values())
        print("one run left out: " + ", ".join(f"{v} ({n} of {len(seeds)})"
                                               for v, n in sorted(counts.items(), key=lambda kv: float(kv[0]))))
    return out


if __name__ == "__main__":
    main(sys.argv[1:])
