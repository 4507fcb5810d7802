"""<z> by its definition: the contact number of ensembles' quiet frames under each counting rule.

``tiltpile zcount DIR [DIR ...] --out PREFIX`` (:mod:`tiltpile.cli.zcount`) runs this study. For
every ensemble directory (its runs of one configuration, observables cached or computed):

1. the quiet frames: frames not avalanching by the 2% lost-contact criterion (the ``avalanching``
   column of :func:`tiltpile.analysis.load_observables`), every ``every``-th of each run's;
2. per quiet frame, z under every rule of :mod:`tiltpile.analysis.zcount` (force thresholds
   f_n > t <f_n>, gap thresholds gap <= g up to the run's ``solver.alert``, walls in or out,
   rattlers in or out, bulk or all mobile grains), with the bulk grains found as the analysis
   finds them (:func:`tiltpile.analysis.contacts.bulk_mask` on the listed contacts);
3. per rule: each run's mean over its quiet frames, and their mean over runs with a 95% bootstrap
   interval over runs (:func:`tiltpile.analysis.stats.bootstrap_ci`, BCa, 9999 resamples;
   no interval with fewer than 3 runs); which rules reach the paper's <z> ~ 3.5, and for each
   variant the least gap threshold that does.

As a check, the analysis's own rule (f_n > 0, walls in, rattlers out, bulk) is compared with the
cached ``z`` column frame by frame (``check.analysis_rule_max_abs_diff``, ~1e-15).

Outputs ``PREFIX.json`` (the table, :func:`study`) and ``PREFIX.png`` (:func:`chart`), each
written to a temporary name and renamed when both are complete.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np

from tiltpile.analysis import zcount as zc
from tiltpile.outputs import replaced_whole

from . import style

N_RESAMPLES = 9999


def _finite_mean(x) -> float:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else float("nan")


def quiet_frames(frames, every: int = 1) -> dict[int, np.ndarray]:
    """{run: frame ids} of the quiet frames (``avalanching`` False) of an observables table,
    every ``every``-th of each run's (the first quiet frame always)."""
    if every < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    q = frames[~frames["avalanching"].to_numpy(bool)]
    return {int(r): g["frame"].to_numpy(np.int64)[::every] for r, g in q.groupby("run", sort=True)}


def run_z(run, frame_ids, force_thresholds=zc.FORCE_THRESHOLDS, gap_thresholds=zc.GAP_THRESHOLDS,
          variants=zc.VARIANTS, min_contacts: int = 2, ray_spacing: float = 0.1,
          touch_tol: float = 0.05, bar=None) -> dict:
    """z of the frames ``frame_ids`` of one open run (:func:`tiltpile.store.open_run`) under
    every rule (:func:`tiltpile.analysis.zcount.frame_z`). Returns dict frame (F,), z (F, R, V),
    n (F, R, V) (grains counted). ``bar``: a tqdm bar advanced once per frame."""
    from tiltpile.analysis import contacts as ct

    radius = np.asarray(run.radius, dtype=float)
    fixed = np.asarray(run.fixed, dtype=bool)
    L = float(run.box_length)
    frame_ids = np.asarray(frame_ids, dtype=np.int64)
    nr = len(force_thresholds) + len(gap_thresholds)
    z = np.full((frame_ids.size, nr, len(variants)), np.nan)
    n = np.zeros(z.shape, dtype=np.int64)
    for a, k in enumerate(frame_ids):
        pos = np.asarray(run.position(int(k)), dtype=float)
        pair, force, _ = run.contacts(int(k))
        pair = np.asarray(pair).reshape(-1, 2)
        keep = zc.mobile_contacts(pair, fixed)
        bulk = ct.bulk_mask(pos, radius, fixed, pair[keep], L, ray_spacing, touch_tol)
        z[a], n[a] = zc.frame_z(pos, radius, fixed, L, pair, force, bulk, force_thresholds,
                                gap_thresholds, variants, min_contacts)
        if bar is not None:
            bar.update(1)
    return {"frame": frame_ids, "z": z, "n": n}


def ensemble_z(directory, every: int = 1, workers: int | None = None, progress: bool = True,
               bar=None, frames=None) -> dict:
    """Step 1 and 2 of the module docstring for one ensemble directory.

    Returns dict dir, config_hash, alert, force_thresholds, gap_thresholds, runs {seed: run_z
    result}, n_quiet (quiet frames of the ensemble before subsampling), check (max |z - cached z|
    of the analysis's rule). ``frames``: the directory's observables table if already loaded
    (else loaded here, computed where missing with ``workers`` processes); ``bar``: a tqdm bar
    advanced once per frame."""
    from tiltpile.analysis import load_observables, run_files
    from tiltpile.store import common_config, open_run

    d = Path(directory)
    files = run_files(d)
    config_hash, config = common_config(files)
    alert = float(config.get("solver", {}).get("alert", 0.1))
    gaps = zc.gap_grid(alert)
    if frames is None:
        frames, _ = load_observables(d, workers=workers, progress=progress)
    pick = quiet_frames(frames, every)
    iv = zc.VARIANTS.index(zc.ANALYSIS_VARIANT)
    runs, worst = {}, 0.0
    for f in files:
        with open_run(f) as run:
            seed = int(run.seed)
            ids = pick.get(seed, np.empty(0, dtype=np.int64))
            res = run_z(run, ids, zc.FORCE_THRESHOLDS, gaps, zc.VARIANTS, bar=bar)
        cached = frames[frames["run"] == seed].set_index("frame")["z"]
        if ids.size:
            diff = np.abs(res["z"][:, 0, iv] - cached.loc[ids].to_numpy(float))
            if np.isfinite(diff).any():
                worst = max(worst, float(np.nanmax(diff)))
        runs[seed] = res
    n_quiet = int((~frames["avalanching"].to_numpy(bool)).sum())
    return {"dir": str(d), "config_hash": config_hash, "alert": alert,
            "force_thresholds": list(zc.FORCE_THRESHOLDS), "gap_thresholds": list(gaps),
            "runs": runs, "n_quiet": n_quiet, "check": {"analysis_rule_max_abs_diff": worst}}


def summarize(ens: dict, n_resamples: int = N_RESAMPLES) -> dict:
    """Step 3 of the module docstring: the table of one :func:`ensemble_z` result.

    Returns dict with table {rule key: family, threshold, walls, rattlers, bulk, z (mean over runs
    of each run's quiet-frame mean), low, high (95% bootstrap over runs), n_runs, per_run,
    n_grains (mean grains counted)}, analysis_rule (its key), reaches_paper_z (rules with
    z >= 3.5; first_gap per variant: :func:`tiltpile.analysis.zcount.first_reaching`;
    force_rule_reaches: whether a force rule does), and the ensemble's thresholds, runs, frames
    and check."""
    from tiltpile.analysis.stats import bootstrap_ci

    rl = zc.rules(ens["force_thresholds"], ens["gap_thresholds"])
    seeds = sorted(ens["runs"])
    empty = np.full((len(rl), len(zc.VARIANTS)), np.nan)

    def run_mean(key, s):  # the run's mean over its quiet frames (NaN: none, or no grain counted)
        a = np.asarray(ens["runs"][s][key], dtype=float)
        if not len(a):
            return empty
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmean(a, axis=0)

    per_run = np.array([run_mean("z", s) for s in seeds]).reshape(len(seeds), len(rl), -1)
    n_grains = np.array([run_mean("n", s) for s in seeds]).reshape(len(seeds), len(rl), -1)
    table = {}
    for a, rule in enumerate(rl):
        for b, v in enumerate(zc.VARIANTS):
            ci = bootstrap_ci(per_run[:, a, b], n_resamples=n_resamples)
            if ci["n"] < 3:  # no interval from one or two runs (not even a degenerate one)
                ci.update(low=float("nan"), high=float("nan"))
            table[zc.rule_key(rule, v)] = {
                "family": rule.family, "threshold": rule.threshold, "walls": v.walls,
                "rattlers": v.rattlers, "bulk": v.bulk, "z": ci["estimate"], "low": ci["low"],
                "high": ci["high"], "n_runs": ci["n"], "per_run": per_run[:, a, b],
                "n_grains": _finite_mean(n_grains[:, a, b])}
    reaching = [k for k, r in table.items() if np.isfinite(r["z"]) and r["z"] >= zc.PAPER_Z]
    first_gap = {}
    for v in zc.VARIANTS:
        zs = [table[zc.rule_key(zc.Rule("gap", g), v)]["z"] for g in ens["gap_thresholds"]]
        first_gap[v.key] = zc.first_reaching(ens["gap_thresholds"], zs, zc.PAPER_Z)
    force_reaches = any(table[k]["family"] == "force" for k in reaching)
    return {
        "dir": ens["dir"], "config_hash": ens["config_hash"], "alert": ens["alert"],
        "runs": seeds, "n_runs": len(seeds),
        "force_thresholds": list(ens["force_thresholds"]), "gap_thresholds": list(ens["gap_thresholds"]),
        "frames_per_run": {s: int(len(ens["runs"][s]["frame"])) for s in seeds},
        "n_quiet": ens["n_quiet"], "check": ens["check"],
        "analysis_rule": zc.rule_key(zc.Rule("force", 0.0), zc.ANALYSIS_VARIANT),
        "reaches_paper_z": {"any": bool(reaching), "rules": reaching,
                            "force_rule_reaches": force_reaches, "first_gap": first_gap},
        "table": table,
    }


def labels_of(dirs) -> list[str]:
    """A short label per ensemble directory: its name, or parent/name where names repeat."""
    names = [Path(d).resolve().name for d in dirs]
    out = []
    for d, name in zip(dirs, names):
        p = Path(d).resolve()
        out.append(f"{p.parent.name}/{name}" if names.count(name) > 1 else name)
    return out


# one colour per ensemble (style.CYCLE); the paper's value as a grey guide
CYCLE, GUIDE = style.CYCLE, style.COLORS["guide"]
LINESTYLES = {(True, False): "-", (True, True): (0, (1, 1.2)), (False, False): "--",
              (False, True): "-."}


def chart(summaries: dict, path) -> None:
    """<z> against the gap threshold and against the force threshold (PNG at ``path``).

    Rows: bulk grains, all mobile grains; columns: gap threshold g (d), force threshold t
    (relative to <f_n>), both on a symmetric-log axis so that 0 shows. One colour per ensemble,
    the line style for walls in/out and rattlers in/out; the band is the 95% interval over runs
    of the solid curve (walls in, rattlers out); the paper's <z> ~ 3.5 dashed grey."""
    import matplotlib
    from matplotlib.figure import Figure  # no pyplot: no backend or global state involved

    with matplotlib.rc_context(style.RC):
        fig = Figure(figsize=(7.0, 5.2))
        axes = fig.subplots(2, 2, sharey=True)
        _draw(fig, axes, summaries)
        fig.savefig(path, format="png", dpi=200, metadata={"Software": None})


def _draw(fig, axes, summaries: dict) -> None:
    from matplotlib.lines import Line2D

    colors = CYCLE
    for c, (label, s) in enumerate(summaries.items()):
        color = colors[c % len(colors)]
        rows = list(s["table"].values())
        for r_i, bulk in enumerate((True, False)):
            for c_i, fam in enumerate(("gap", "force")):
                ax = axes[r_i, c_i]
                for (walls, ratt), ls in LINESTYLES.items():
                    sel = [r for r in rows if r["family"] == fam and r["bulk"] == bulk
                           and r["walls"] == walls and r["rattlers"] == ratt]
                    x = np.array([r["threshold"] for r in sel])
                    y = np.array([r["z"] for r in sel], dtype=float)
                    ax.plot(x, y, ls=ls, color=color, marker="o", ms=2.0, lw=1.0)
                    if walls and not ratt:
                        lo = np.array([r["low"] for r in sel], dtype=float)
                        hi = np.array([r["high"] for r in sel], dtype=float)
                        if np.isfinite(lo).any():
                            ax.fill_between(x, lo, hi, color=color, alpha=0.2, lw=0)
    for r_i, grains in enumerate(("bulk grains", "all mobile grains")):
        for c_i, (xl, lin) in enumerate((("gap threshold g (d): gap <= g", 1e-7),
                                         ("force threshold t: f_n > t <f_n>", 1e-5))):
            ax = axes[r_i, c_i]
            ax.set_xscale("symlog", linthresh=lin, linscale=0.5)
            ax.axhline(zc.PAPER_Z, color=GUIDE, ls="--", lw=0.8)
            ax.set_xlim(left=0)
            if r_i == 1:
                ax.set_xlabel(xl)
            if c_i == 0:
                ax.set_ylabel(f"<z>, quiet frames ({grains})")
            ax.text(0.02, 0.96, "abcd"[2 * r_i + c_i], transform=ax.transAxes, ha="left",
                    va="top", fontstyle="italic", fontweight="bold")
    handles = [Line2D([], [], color=colors[c % len(colors)], label=label)
               for c, label in enumerate(summaries)]
    handles += [Line2D([], [], color="k", ls=ls, label=f"walls {'in' if w else 'out'}, "
                       f"rattlers {'in' if r else 'out'}") for (w, r), ls in LINESTYLES.items()]
    handles.append(Line2D([], [], color=GUIDE, ls="--", label=f"paper <z> ~ {zc.PAPER_Z:g}"))
    fig.legend(handles=handles, loc="upper center", ncol=4, bbox_to_anchor=(0.5, 1.0))
    fig.tight_layout(rect=(0, 0, 1, 0.9))


def study(dirs, every: int = 1, workers: int | None = None, progress: bool = True,
          n_resamples: int = N_RESAMPLES, command: str | None = None) -> dict:
    """The whole study over ensemble directories ``dirs`` (module docstring): the JSON document."""
    from tiltpile.analysis import load_observables

    labels = labels_of(dirs)
    tables = [load_observables(d, workers=workers, progress=progress)[0] for d in dirs]
    total = sum(len(v) for t in tables for v in quiet_frames(t, every).values())
    bar = None
    if progress:
        from tqdm.auto import tqdm
        bar = tqdm(total=total, desc="zcount", unit="frame")
    try:
        summaries = {lab: summarize(ensemble_z(d, every, bar=bar, frames=t), n_resamples)
                     for lab, d, t in zip(labels, dirs, tables)}
    finally:
        if bar is not None:
            bar.close()
    return {
        "study": "zcount", "command": command, "paper_z": zc.PAPER_Z, "every": every,
        "quiet": "frames not avalanching by the 2% lost-contact criterion (observables' "
                 "avalanching column)" + (f", every {every}th of each run's" if every > 1 else ""),
        "interval": f"95% BCa bootstrap over runs of the per-run quiet-frame means "
                    f"({n_resamples} resamples; none with fewer than 3 runs)",
        "rules": {
            "force": "listed contacts with f_n > t <f_n>, <f_n> the frame's mean over f_n > 0",
            "gap": "every pair of bodies (grains, fixed grains, walls, floor) with surface gap "
                   "<= g (d), from positions and radii; g up to solver.alert",
            "walls": "contacts with side walls, floor and fixed grains counted (in) or dropped (out)",
            "rattlers": "grains with fewer than 2 contacts of the rule (walls included) kept (in) or "
                        "removed with their contacts (out)",
            "grains": "bulk: top and bottom single layers excluded; all: every mobile grain",
            "analysis": "f_n>0 walls=in rattlers=out grains=bulk is the analysis's z",
        },
        "ensembles": summaries,
    }


def write_study(doc: dict, prefix) -> tuple[Path, Path]:
    """Write ``PREFIX.json`` and ``PREFIX.png`` of a :func:`study` document: both to temporary
    names first, synced and renamed only when both are complete (on any error neither temporary
    is left behind; :func:`tiltpile.outputs.replaced_whole`)."""
    prefix = Path(prefix)
    prefix.parent.mkdir(parents=True, exist_ok=True)
    out_json, out_png = prefix.with_name(prefix.name + ".json"), prefix.with_name(prefix.name + ".png")
    with replaced_whole(out_json) as tmp_json, replaced_whole(out_png) as tmp_png:
        tmp_json.write_text(json.dumps(style.jsonable(doc), indent=1) + "\n")
        chart(doc["ensembles"], tmp_png)
    return out_json, out_png
