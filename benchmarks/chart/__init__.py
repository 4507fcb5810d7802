"""``python -m benchmarks.chart DIR`` (``make bench``): the speed x accuracy chart of the solver.

Three measurements, all on one core, one after the other, written to ``DIR`` (each file to a
temporary name, then renamed):

1. Accuracy sweep (``accuracy.csv``, ``pareto.png``). One settled smoke pile per seed (250 grains,
   20 d box; ``protocol.deposited`` with the point-independent deposition at
   ``solver.deposition_tol``, settled at the tightest tol; cached under ``data/bench``). For every
   (tol, dt, overlap slop) point of the grid (``ChartSpec.grid``) the pile is copied and
   * settled ``SETTLE_STEPS`` steps at theta = 0 at the point's own setting (as frame 0 of a run),
   * tilted at 0.001 deg per step (the paper's rate per step, so dt also sets the physical tilt
     rate 0.001 deg / dt) with a frame every 50 steps (0.05 deg, as in the paper), until the first
     avalanche onset (2% lost-contact criterion, ``analysis.segment_avalanches`` over the frames'
     ``frame_observables``) plus ``margin_deg``, or ``theta_cap`` degrees;
     measured: wall time per degree of tilt (median over the frame chunks of the run, solver
     only, analysis excluded), NLGS sweeps per step (mean, median), the per-step final residual
     (median), steps at ``max_iter``, largest overlap, first onset theta_m, and <z>, <n_m> (bulk,
     rattlers removed) averaged over the quiet frames before the onset, and the drift: mean
     displacement of the mobile grains per degree of tilt, median over those quiet frames;
   * separately, creep: a copy tilted to ``hold_deg`` in ``creep_tilt_steps`` equal steps, left
     ``creep_settle_time`` to take the last increment, then held for ``creep_hold_time``
     (physical time, so ``creep_hold_time / dt`` steps) at fixed gravity: mean and max
     displacement of the mobile grains over the hold.
   Shifts (theta_m, <z>, <n_m>) are against the tightest setting (smallest tol, smallest dt, the
   default slop) of the same seed.
2. Pareto plot: time per degree against each error measure (creep, drift, |shift of theta_m|,
   final residual), per (tol, dt, slop) averaged over seeds; the default setting highlighted; the
   Pareto front (points that no other point beats in both time and error) drawn.
3. Scaling (``scaling.csv``, ``scaling.png``). A pile of ``base_n`` grains at the paper's depth
   (the timing's pile, ``benchmarks.pile``: box 120 d * n / 4000, paper preset, cached under data/bench) is
   tiled k times side by side in a k-times wider box: grain (copy m, original id i) gets id
   i * k + m, so ids stay ordered bottom-up as in a deposited pile (the forward and interleaved
   sweeps rely on it), fixed bottom rows included; the inner walls disappear. The tiled pile settles
   ``tile_settle_steps`` steps at tol 1e-4 at theta = 0 (the seams relax), then 20 untimed tilt
   steps at the timed tolerance, then ``scaling_steps`` timed tilt steps, each timed alone:
   median ms per step, ns per contact update (time / local solves made,
   ``StepRecord.updates``), sweeps per step. The default sweep (``solver.sweep``, interleaved)
   relax 1 with the default overlap slop at every N; at ``variant_ns`` also, from the same state: forward relax 1 with the slop (the
   key order, the default before the interleaved sweep), random relax 1 with slop 0 (plain NLGS
   with the plain gap term, the speed reference), forward relax 1 with slop 0, and forward
   relax 1.5 (projected SOR). Last, the cost of a step of the default sweep at exactly
   ``fixed_sweeps`` sweeps (tol 0), ``fixed_rounds`` rounds of
   ``fixed_steps`` steps, each round over every N in turn: median over all those steps.

``summary.json``: machine (``os.cpu_count()``, platform, numba version), date, command, timings
of each part, the settings, and the fitted scaling (line through the origin, log-log slope).

Modules: ``spec`` (:class:`ChartSpec`, the columns, the piles), ``accuracy`` (part 1),
``plots`` (part 2), ``scaling`` (part 3); this one writes the files (:func:`run_chart`,
:func:`replot`). ``python -m benchmarks.chart DIR [--quick] [--parts ...] [--replot]``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.chart import accuracy, plots, scaling
from benchmarks.chart.accuracy import accuracy_sweep
from benchmarks.chart.plots import aggregate_points, pareto_front, read_accuracy
from benchmarks.chart.scaling import scaling_fit, scaling_sweep, tile
from benchmarks.chart.spec import (ACCURACY_COLUMNS, DEFAULT_DT, DEFAULT_SLOP, DEFAULT_TOL,
                                       SCALING_COLUMNS, ChartSpec, grid_points)

__all__ = ["ACCURACY_COLUMNS", "SCALING_COLUMNS", "DEFAULT_TOL", "DEFAULT_DT", "DEFAULT_SLOP",
           "ChartSpec", "grid_points", "accuracy_sweep", "scaling_sweep", "scaling_fit", "tile",
           "pareto_front", "aggregate_points", "read_accuracy", "run_chart", "replot", "main"]


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to a temporary name beside ``path``, then rename it."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    tmp.replace(path)


def atomic_csv(df: pd.DataFrame, path: Path) -> None:
    atomic_write_text(path, df.to_csv(index=False, float_format="%.6g"))


def machine_info() -> dict:
    import numba
    return dict(cpu_count=os.cpu_count(), platform=platform.platform(), machine=platform.machine(),
                processor=platform.processor(), python=platform.python_version(),
                numba=numba.__version__, numpy=np.__version__)


def run_chart(outdir, spec: ChartSpec | None = None, progress: bool = True,
              command: str | None = None, parts=("accuracy", "scaling")) -> dict:
    """Measure and write accuracy.csv, pareto.png, scaling.csv, scaling.png and summary.json.

    ``parts``: "accuracy" and/or "scaling". Without "accuracy", an accuracy.csv already in
    ``outdir`` is re-plotted and summarised (one written before a column existed is skipped with
    a warning). Returns the summary (also written as summary.json).
    """
    spec = spec or ChartSpec.full()
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    summary = dict(date=datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
                   command=command or " ".join(sys.argv), machine=machine_info(),
                   spec=asdict(spec), default=dict(tol=DEFAULT_TOL, dt=DEFAULT_DT, slop=DEFAULT_SLOP),
                   timings_s={},
                   files=[])
    if "accuracy" in parts:
        t0 = time.perf_counter()
        acc = accuracy.accuracy_sweep(spec, progress)
        atomic_csv(acc, out / "accuracy.csv")
        plots.plot_pareto(acc, out / "pareto.png", spec.hold_deg, spec.tilt_per_step)
        summary["timings_s"]["accuracy"] = time.perf_counter() - t0
        summary["files"] += ["accuracy.csv", "pareto.png"]
    elif (out / "accuracy.csv").exists():  # --parts scaling: summarise the accuracy run on disk
        acc = read_accuracy(out / "accuracy.csv")
        if acc is not None:
            plots.plot_pareto(acc, out / "pareto.png", spec.hold_deg, spec.tilt_per_step)
            summary["accuracy_from_file"] = True
            summary["files"] += ["accuracy.csv", "pareto.png"]
    else:
        acc = None
    if acc is not None:
        summary.update(accuracy_summary(acc))
    if "scaling" in parts:
        t0 = time.perf_counter()
        sc = scaling.scaling_sweep(spec, progress)
        fit = scaling.scaling_fit(sc)
        atomic_csv(sc, out / "scaling.csv")
        plots.plot_scaling(sc, fit, out / "scaling.png", 0.01 if spec.quick else 0.001)
        summary["timings_s"]["scaling"] = time.perf_counter() - t0
        summary["scaling_fit"] = fit
        summary["files"] += ["scaling.csv", "scaling.png"]
    summary["timings_s"]["total"] = time.perf_counter() - t_start
    summary["files"].append("summary.json")
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=1, default=float) + "\n")
    return summary


def accuracy_summary(acc: pd.DataFrame) -> dict:
    """The accuracy points averaged over seeds (``accuracy_points``) and, per error measure, the
    labels (tol/dt[/slop]) of the points on its Pareto front against time per degree."""
    agg = aggregate_points(acc)
    out = {"accuracy_points": json.loads(agg.to_json(orient="records"))}
    for name, col in (("pareto_front_creep", "creep_mean"),
                      ("pareto_front_drift", "drift_per_deg"),
                      ("pareto_front_theta_m", "abs_theta_shift"),
                      ("pareto_front_residual", "residual_median")):
        f = pareto_front(agg[col].to_numpy(float), agg["ms_per_deg"].to_numpy(float))
        out[name] = [plots.point_label(agg.iloc[i]) for i in f]
    return out


def replot(outdir, spec: ChartSpec | None = None) -> list[str]:
    """Redraw pareto.png and scaling.png from the accuracy.csv and scaling.csv in ``outdir``
    (nothing is measured; summary.json is left as it is). Returns the PNG files written."""
    spec = spec or ChartSpec.full()
    out = Path(outdir)
    written = []
    if (out / "accuracy.csv").exists():
        acc = read_accuracy(out / "accuracy.csv")
        if acc is not None:
            plots.plot_pareto(acc, out / "pareto.png", spec.hold_deg, spec.tilt_per_step)
            written.append("pareto.png")
    if (out / "scaling.csv").exists():
        sc = pd.read_csv(out / "scaling.csv")
        plots.plot_scaling(sc, scaling.scaling_fit(sc), out / "scaling.png", spec.tilt_per_step)
        written.append("scaling.png")
    return written


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.chart DIR [--quick] [--parts accuracy,scaling] [--replot]``."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.chart",
                                 description="the speed x accuracy chart (make bench)")
    ap.add_argument("dir", type=Path, help="output directory (make bench: figures/performance)")
    ap.add_argument("--quick", action="store_true", help="a tiny pile, a few points (the test's chart)")
    ap.add_argument("--parts", default="accuracy,scaling", help="accuracy,scaling (default both)")
    ap.add_argument("--replot", action="store_true", help="only redraw the PNGs from the CSVs in DIR")
    a = ap.parse_args(argv)
    spec = ChartSpec.quick_spec() if a.quick else ChartSpec.full()
    if a.replot:
        print("wrote", ", ".join(replot(a.dir, spec)) or "nothing (no CSV files)", "to", a.dir)
        return 0
    parts = tuple(a.parts.split(","))
    if set(parts) - {"accuracy", "scaling"}:
        ap.error(f"--parts: unknown part(s) {sorted(set(parts) - {'accuracy', 'scaling'})}")
    summary = run_chart(a.dir, spec, parts=parts)
    print(f"wrote {', '.join(summary['files'])} to {a.dir} in {summary['timings_s']['total']:.0f} s")
    return 0
