"""What a user looks at when a run looks wrong: its per-frame series against theta, and the
first onsets of an ensemble (``notebooks/run_diagnostics.ipynb`` draws them).

``run_series(path)`` -- one row per stored frame: theta_deg, ke_per_grain (kinetic energy of the
mobile grains per grain, m g d), lost_fraction (contacts active at frame k lost by k + 1),
onset, z, n_m, dz_gen (bulk, rattlers removed; :mod:`tiltpile.analysis.observables`),
iterations (NLGS sweeps of the frame's step), max_iterations and cap_hits (the worst step and the
steps at the iteration cap since the previous frame), residual, max_overlap, energy_gain (from the
run file). ``onset_summary(frames)`` -- per run of an ensemble table, the tilt of the first onset.
``plot(series, onsets, ...)`` -- the figure.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile.analysis import DEFAULT_PARAMS, run_observables
from tiltpile.analysis.ensemble_data import first_onsets
from tiltpile.store import open_run

RUN_COLUMNS = ("iterations", "max_iterations", "cap_hits", "residual", "max_overlap",
               "energy_gain", "ke")


def run_series(path) -> tuple[pd.DataFrame, dict]:
    """Per-frame series of one run (module docstring) and its facts (seed, n_mobile, max_iter,
    tol, cutoff, path)."""
    frames, _ = run_observables(path)
    with open_run(path) as run:
        cols = {c: np.asarray(getattr(run, c)) for c in RUN_COLUMNS}
        n_mobile = int((~np.asarray(run.fixed, dtype=bool)).sum())
        solver = run.config.get("solver", {})
        facts = {"path": str(path), "seed": run.seed, "n_mobile": n_mobile,
                 "max_iter": solver.get("max_iter"), "tol": solver.get("tol"),
                 "cutoff": DEFAULT_PARAMS["cutoff"]}
    s = frames[["frame", "theta_deg", "lost_fraction", "onset", "avalanching", "z", "n_m",
                "dz_gen"]].copy()
    for c in RUN_COLUMNS:
        s[c] = cols[c]
    s["ke_per_grain"] = s.pop("ke") / n_mobile
    return s, facts


def onset_summary(frames: pd.DataFrame) -> pd.DataFrame:
    """Per run of an ensemble's per-frame table: theta of its first onset
    (:func:`tiltpile.analysis.ensemble_data.first_onsets`; NaN: none), its number of onsets and
    its last tilt. Columns run, theta_first_onset, n_onsets, theta_end."""
    f = frames.sort_values(["run", "frame"], kind="stable")
    by = f.groupby("run", sort=True)
    runs = [int(r) for r in by.groups]
    return pd.DataFrame({"run": runs, "theta_first_onset": first_onsets(f, runs),
                         "n_onsets": [int(g["onset"].astype(bool).sum()) for _, g in by],
                         "theta_end": [float(g["theta_deg"].iloc[-1]) for _, g in by]},
                        columns=["run", "theta_first_onset", "n_onsets", "theta_end"])


def plot(series: pd.DataFrame, facts: dict, onsets: pd.DataFrame | None = None):
    """Seven panels against theta (kinetic energy, lost fraction with the cutoff, z and n_m,
    delta z_gen, sweeps and cap hits, residual, overlap and energy gain) and, with ``onsets``,
    the histogram of the first onsets over the ensemble's runs. Returns the figure."""
    import matplotlib.pyplot as plt

    nrows = 4 + (onsets is not None)
    fig, axes = plt.subplots(nrows, 2, figsize=(10, 2.3 * nrows), squeeze=False,
                             layout="constrained")
    th = series["theta_deg"].to_numpy(float)
    on = th[series["onset"].to_numpy(bool)]

    def mark(ax):
        for t in on:
            ax.axvline(t, color="#D55E00", lw=0.6, alpha=0.5)

    ax = axes[0, 0]
    ax.semilogy(th, series["ke_per_grain"].clip(lower=1e-16), color="k", lw=0.8)
    ax.set_ylabel(r"$E_k$ / grain [$m g d$]")
    ax = axes[0, 1]
    ax.semilogy(th, series["lost_fraction"].clip(lower=1e-5), ".-", color="k", lw=0.6, ms=2)
    ax.axhline(facts["cutoff"], color="#D55E00", ls="--", lw=1, label=f"cutoff {facts['cutoff']:.0%}")
    ax.set_ylabel("lost-contact fraction")
    ax.legend(loc="lower right", fontsize=8)
    ax = axes[1, 0]
    ax.plot(th, series["z"], color="#0072B2", lw=0.8, label="z (bulk)")
    ax.set_ylabel("z")
    ax2 = ax.twinx()
    ax2.plot(th, series["n_m"], color="#009E73", lw=0.8, label=r"$n_m$")
    ax2.set_ylabel(r"$n_m$", color="#009E73")
    ax.legend(loc="upper left", fontsize=8)
    ax = axes[1, 1]
    ax.plot(th, series["dz_gen"], color="k", lw=0.8)
    ax.axhline(0.0, color="#7F7F7F", lw=0.6)
    ax.set_ylabel(r"$\Delta z_{gen} = z - 3 - n_m$")
    ax = axes[2, 0]
    ax.semilogy(th, series["iterations"].clip(lower=1), color="k", lw=0.6, label="frame's step")
    ax.semilogy(th, series["max_iterations"].clip(lower=1), color="#0072B2", lw=0.6,
                label="worst step since previous frame")
    if facts.get("max_iter"):
        ax.axhline(facts["max_iter"], color="#D55E00", ls="--", lw=1, label="cap (max_iter)")
    ax.set_ylabel("NLGS sweeps per step")
    ax.legend(loc="lower right", fontsize=7)
    ax = axes[2, 1]
    ax.plot(th, series["cap_hits"], color="#D55E00", lw=0.8)
    ax.set_ylabel("steps at the cap\nsince previous frame")
    ax = axes[3, 0]
    ax.semilogy(th, series["residual"].clip(lower=1e-16), color="k", lw=0.6)
    if facts.get("tol"):
        ax.axhline(facts["tol"], color="#D55E00", ls="--", lw=1, label="tol")
        ax.legend(loc="lower right", fontsize=8)
    ax.set_ylabel("final NLGS residual")
    ax = axes[3, 1]
    ax.semilogy(th, series["max_overlap"].clip(lower=1e-12), color="k", lw=0.6, label="max overlap [d]")
    ax.semilogy(th, series["energy_gain"].clip(lower=1e-16), color="#CC79A7", lw=0.6,
                label=r"energy gain [$m g d$]")
    ax.legend(loc="lower right", fontsize=7)
    for ax in axes[:4].ravel():
        mark(ax)
        ax.set_xlabel(r"$\theta$ [deg]")
    fig.suptitle(f"{Path(facts['path']).name}: seed {facts['seed']}, {facts['n_mobile']} mobile "
                 f"grains, {on.size} onset(s) (red lines)", fontsize=10)
    if onsets is not None:
        gs = axes[4, 0].get_gridspec()
        for ax in axes[4]:
            ax.remove()
        ax = fig.add_subplot(gs[4, :])
        t = onsets["theta_first_onset"].to_numpy(float)
        ok = t[np.isfinite(t)]
        if ok.size:
            ax.hist(ok, bins=max(5, min(30, ok.size)), color="#7F7F7F", edgecolor="k")
        ax.set_xlabel(r"first onset $\theta$ [deg] (2% lost-contact criterion)")
        ax.set_ylabel("runs")
        ax.set_title(f"{len(t)} runs, {ok.size} with an onset"
                     + (f"; median {np.median(ok):.2f} deg" if ok.size else ""), fontsize=9)
    return fig


def save(fig, path) -> Path:
    """Write the figure as PNG to a temporary name of this process, synced, then renamed
    (:func:`tiltpile.outputs.replaced_whole`)."""
    from tiltpile.outputs import replaced_whole

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with replaced_whole(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120, metadata={"Software": None})
    return path
