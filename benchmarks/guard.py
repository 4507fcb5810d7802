"""The accuracy guard of a cheaper setting: what each ensemble costs against how far it moves the
figure numbers, in units of their statistical error.

Usage: python -m benchmarks.guard REF DIR [DIR ...] --out OUTDIR
  REF, DIR  ensemble directories (``tiltpile ensemble ... --out DIR``); REF is the reference
  OUTDIR    where ``guard.csv`` and ``guard.png`` go (e.g. figures/performance)

Per ensemble, from :func:`benchmarks.compare_ensembles.compare`: the setting (configuration
keys that differ from REF's), and per figure number (theta_m, <z>, <n_m> and the fraction of
quiet frames below the marginal line, delta) its mean over the runs, standard error, shift from
REF, the shift in units of the combined standard error sqrt(sem^2 + sem_ref^2) (``*_sigma``) and
Welch's p; and the cost per run from the manifest (median seconds of the runs, mean capped
steps). ``guard.png`` plots, for each number, |shift| / combined error against the median
seconds per run, with the 1 and 2 sigma lines: a setting is acceptable where it stays below 2
for every number, and worth it where it sits left of the reference.

Run times come from the manifests: ensembles that ran side by side on a shared machine are
comparable only roughly; ``notes/performance-log.md`` records the conditions of each measurement.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.compare_ensembles import METRICS, compare

LABELS = {"theta_m": "first onset theta_m", "z_quiet": "<z> quiet", "n_m_quiet": "<n_m> quiet",
          "below_quiet": "quiet frames below z = 3 + n_m", "delta": "cluster exponent delta"}


def cost(data_dir, sweeps_per_run=None) -> dict:
    """Median and mean seconds per finished run, mean capped steps per run and failed runs (from
    the manifest); ``sweeps_per_run`` (the ensemble's ``meta["cost"]``, None if its run files do
    not count them) is passed through."""
    m = json.loads((Path(data_dir) / "ensemble.json").read_text())
    runs = [r for r in m["runs"].values() if r.get("status") == "done" and r.get("seconds")]
    sec = np.array([r["seconds"] for r in runs], float)
    caps = np.array([r.get("cap_hits", np.nan) for r in runs], float)
    failed = sum(r.get("status") == "failed" for r in m["runs"].values())
    return dict(runs_done=len(runs), runs_failed=failed, seconds_median=float(np.median(sec)) if sec.size else np.nan,
                seconds_mean=float(sec.mean()) if sec.size else np.nan,
                cap_hits_mean=float(np.nanmean(caps)) if caps.size else np.nan,
                sweeps_per_run=np.nan if sweeps_per_run is None else sweeps_per_run)


def table(dirs) -> pd.DataFrame:
    """One row per ensemble (module docstring); the first is the reference."""
    rows = compare(dirs)
    ref = rows[0]
    out = []
    for r in rows:
        diff = ", ".join(f"{k}={v[1]}" for k, v in r["diff"].items()) or "reference"
        row = dict(dir=r["dir"], setting=diff, runs=len(r["seeds"]),
                   **cost(r["dir"], r["cost"].get("sweeps_per_run")))
        for m in METRICS:
            err = float(np.hypot(r[f"{m}_sem"], ref[f"{m}_sem"]))
            row.update({f"{m}_mean": r[f"{m}_mean"], f"{m}_sem": r[f"{m}_sem"],
                        f"{m}_shift": r[f"{m}_shift"], f"{m}_p": r[f"{m}_p"],
                        f"{m}_sigma": r[f"{m}_shift"] / err if err > 0 else np.nan})
        out.append(row)
    return pd.DataFrame(out)


def plot(t: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(METRICS), figsize=(3.0 * len(METRICS), 3.4), sharey=True,
                             constrained_layout=True)
    markers = "osD^v<>ph*"
    for ax, m in zip(axes, METRICS):
        for k, r in t.iterrows():
            y = abs(r[f"{m}_sigma"]) if k else 0.0
            label = r["setting"] + (f" ({r['runs_failed']} of {r['runs_done'] + r['runs_failed']} runs "
                                    "failed, left out)" if r["runs_failed"] else "")
            ax.plot(r["seconds_median"], y, markers[k % len(markers)], ms=7,
                    label=label if m == METRICS[0] else None, color=f"C{k}")
        for level, ls in ((1, ":"), (2, "--")):
            ax.axhline(level, color="0.5", ls=ls, lw=0.8)
        ax.set_title(LABELS[m], fontsize=9)
        ax.set_xlabel("median seconds per run")
    axes[0].set_ylabel("|shift| / combined standard error")
    fig.suptitle("Accuracy guard: each setting against the reference ensemble (run seconds depend on "
                 "the machine's load at the time; sweeps in guard.csv)", fontsize=8)
    fig.legend(loc="outside lower center", ncol=min(len(t), 3), fontsize=8, frameon=False)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def main(argv=None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.guard", description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", help="ensemble directories; the first is the reference")
    ap.add_argument("--out", type=Path, required=True, help="directory for guard.csv and guard.png")
    a = ap.parse_args(argv)
    if len(a.dirs) < 2:
        ap.error("give the reference and at least one ensemble to compare with it")
    t = table(a.dirs)
    a.out.mkdir(parents=True, exist_ok=True)
    t.to_csv(a.out / "guard.csv", index=False, float_format="%.6g")
    plot(t, a.out / "guard.png")
    with pd.option_context("display.width", 200, "display.max_columns", 40):
        cols = ["setting", "runs", "seconds_median"] + [f"{m}_{x}" for m in METRICS for x in ("mean", "sigma")]
        print(t[cols].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    return t


if __name__ == "__main__":
    main(sys.argv[1:])
