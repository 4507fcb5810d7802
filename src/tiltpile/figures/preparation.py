"""The preparation study: do piles tilted before the analysed ramp fail differently?

The paper's piles had "several histories of inclination, including several back and forth
oscillations"; ours fall fresh from a loose lattice unless ``protocol.pretilt_deg`` tilts them
back and forth first (each leg at the ramp's rate, held until at rest, the analysed ramp then
starting at 0 deg; the run file records it, ``Run.preparation``). This module compares several
ensembles -- the first one is the reference, normally fresh piles -- run by run:

* the first onset by the lost-contact cutoff (the paper's theta_m, 2% by default) and the first
  large slide, both exactly as in Fig. 2 (:func:`tiltpile.figures.fig2.compute` is called per
  ensemble: its slide threshold is that ensemble's Fig. 2a kinetic-energy threshold unless the
  analysis parameter ``slide_ke`` is set, its least span ``slide_sustain_deg``);
* the precursor events: onsets by the cutoff whose avalanche (the stretch of avalanching frames
  it starts) ends before the first slide begins (:func:`tiltpile.analysis.avalanche.precursor_count`); for a run without a
  slide, every onset before the end of the tilt (such runs are marked: a lower bound on what a
  longer tilt would count); and the onsets below the study's largest pretilt angle (a pile
  tilted there before should rearrange less below it);
* <z> and <n_m> over the run's quiet frames (bulk, force contacts; :func:`tiltpile.figures.data.per_run_quiet`);

and per ensemble the Fig. 2b two-population measure of the lost fraction (Ashman's D, valley
depth, delta BIC; :func:`tiltpile.analysis.stats.bimodality` as Fig. 2 applies it) and the
fraction of frames losing no contact. Means over runs carry bootstrap intervals
(:func:`tiltpile.analysis.stats.bootstrap_ci`, BCa, 9999 resamples, seed 0); each prepared
ensemble's difference of means from the reference carries a two-sample percentile bootstrap
interval (:func:`tiltpile.analysis.stats.diff_ci`; the runs of each ensemble resampled independently).

A run without slide before the end of its tilt has no slide angle: the slide mean is over the
runs that slid (``n_runs_with_slide`` says how many), which favours early slides when few slid.

An ensemble may be given by its records (a directory of ``run_*.npz`` and no run file,
:mod:`tiltpile.record`; the paper-scale ensembles are committed so): everything above comes from
the per-frame tables the records keep, but the pile at frame 0 (packing fraction, fabric, surface
tilt) needs the positions only the run files hold, so those columns are NaN for it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile.analysis import stats as _st
from tiltpile.analysis.avalanche import precursor_count, run_onsets
from tiltpile.analysis.stats import diff_ci
from tiltpile.analysis.observables import run_files

from tiltpile.config import history_label, rate_suffix
from tiltpile.paper_values import QUIET_DEG

from . import fig2, style
from .data import Reads, per_run_quiet

# the table columns the study reads (from records, only these are checked): Fig. 2's, whose
# computation it runs on every ensemble, hold all it reads besides
READS = Reads("The preparation study", fig2.READS.frames, fig2.READS.clusters)

NAME = "preparation"

# the per-run quantities compared between ensembles (column of the per-run table: description)
PER_RUN = {
    "theta_first_onset": "first onset by the lost-contact cutoff (deg)",
    "theta_first_slide": "first large slide (deg; NaN: none before the end of the tilt)",
    "n_precursors": "onsets whose avalanche ends before the first slide (or before the end)",
    "n_onsets_below": "onsets below the largest pretilt angle of the study (below_deg)",
    "n_onsets": "all onsets of the ramp (to the end of the tilt; no slide threshold involved)",
    "z_quiet": "mean z of the quiet frames (bulk, force contacts)",
    "n_m_quiet": "mean n_m of the quiet frames",
    # the memory of the history (Deboeuf et al. 2005): quiet until about theta_rev?
    "theta_first_change": "first frame losing more than CHANGE_CUTOFF of its contacts (deg): "
                          "where irreversible change returns",
    "onset_over_rev": "first onset / the ensemble's own largest history angle theta_rev "
                      "(NaN: fresh)",
    "n_onsets_below_rev": "onsets below the ensemble's own theta_rev (NaN: fresh)",
    # what the history leaves in the pile at frame 0 (analysis.structure)
    "phi_start": "packing fraction of the bulk window at frame 0",
    "fabric_start": "contact fabric anisotropy 2 (l1 - l2) of the bulk at frame 0",
    "fabric_major_start": "direction of the fabric's major axis from the vertical at frame 0 "
                          "(deg, positive towards the downhill wall x = L)",
    "surface_tilt_start": "tilt of the free surface against the floor at frame 0 (deg, positive "
                          "rising towards x = L): a history whose cycles flowed leaves it tilted",
}

# the per-run columns that need the positions of frame 0 (run files, not records)
STRUCTURE = ("phi_start", "fabric_start", "fabric_major_start", "surface_tilt_start")

# the packing fraction's window keeps 2 d (two grains) from the walls, the rough bottom and the
# lowest surface grain's centre
BULK_MARGIN = 2.0

# the paper's Fig. 5 has quiet frames 14.4 deg before an onset: some of its piles had their
# first onset at 14.4 deg or later
QUIET_PAST_DEG = QUIET_DEG.value

# a loss of contacts well below the onset cutoff (9 of ~1800 contacts at 1000 grains): the first
# irreversible rearrangement of the ramp, however small
CHANGE_CUTOFF = 0.005


# ----------------------------------------------------------------------------------------------
# preparation history and its label


def preparation_history(data_dir) -> list[float]:
    """The preparation history shared by the runs of ``data_dir``: the target angles (deg) of the
    pretilt legs from each run file's ``preparation`` record (``protocol.pretilt_deg`` of the
    run's configuration when the file has no record; [] for fresh piles); in a directory of
    records without run files, ``protocol.pretilt_deg`` of each record's configuration.
    ValueError when the runs disagree or the directory holds neither."""
    from tiltpile.record import read_meta, record_files
    from tiltpile.store import open_run
    files = run_files(Path(data_dir))
    records = [] if files else record_files(Path(data_dir))
    if not files and not records:
        raise ValueError(f"{data_dir}: no run_*.h5 files (nor records run_*.npz)")
    seen = {}
    for f in files:
        with open_run(f) as r:
            prep = r.preparation.get("target_deg")
            t = (np.atleast_1d(prep).astype(float).tolist() if prep is not None
                 else [float(x) for x in r.config.get("protocol", {}).get("pretilt_deg", ())])
        seen.setdefault(tuple(t), []).append(f.name)
    for f in records:
        legs = read_meta(f)["config"].get("protocol", {}).get("pretilt_deg") or ()
        seen.setdefault(tuple(float(x) for x in legs), []).append(f.name)
    if len(seen) > 1:
        what = "; ".join(f"{list(k)} in {', '.join(v)}" for k, v in seen.items())
        raise ValueError(f"{data_dir}: the runs have different preparation histories ({what})")
    return list(next(iter(seen)))


def check_inputs(data_dirs, labels=None) -> list[str]:
    """Refuse (ValueError, one message listing every problem) a study that cannot be made:
    no directory, a directory that does not exist or holds neither run files nor records, labels
    (when given, non-empty) not one per directory or repeated. Returns the labels ([] when none
    given)."""
    from tiltpile.record import record_files
    dirs = [Path(d) for d in (data_dirs or [])]
    labels = [str(x) for x in (labels or [])]
    problems = []
    if not dirs:
        problems.append("no ensemble directory given (data_dirs is empty)")
    for d in dirs:
        if not d.is_dir():
            problems.append(f"{d} is not a directory")
        elif not run_files(d) and not record_files(d):
            problems.append(f"{d} holds no run_*.h5 files nor records run_*.npz "
                            "(run `tiltpile ensemble` first)")
    if labels and len(labels) != len(dirs):
        problems.append(f"{len(labels)} labels for {len(dirs)} ensemble directories: give one "
                        "label per directory, or none to name them by their preparation")
    if labels and len(set(labels)) != len(labels):
        problems.append(f"labels repeat: {labels}")
    if problems:
        raise ValueError("preparation study: " + "; ".join(problems))
    return labels


def load(data_dirs, labels=None, **analysis_params) -> tuple[list, list[str], list[list[float]]]:
    """The ensembles of ``data_dirs`` (:func:`tiltpile.figures.data.load`, with
    ``analysis_params``, holding the columns of ``READS``), their labels and preparation histories, after :func:`check_inputs`.
    Labels not given are derived from the run files' preparation (:func:`history_label`, with
    the history's rate when it has its own, :func:`rate_suffix`; the directory name is appended
    where two would be equal)."""
    from . import data
    labels = check_inputs(data_dirs, labels)
    hist = [preparation_history(d) for d in data_dirs]
    ens = [data.load(d, None, READS, **analysis_params) for d in data_dirs]
    if not labels:
        derived = [history_label(h) + (rate_suffix(e.config) if h else "")
                   for h, e in zip(hist, ens)]
        labels = [f"{x} ({Path(d).name})" if derived.count(x) > 1 else x
                  for x, d in zip(derived, data_dirs)]
    return ens, labels, hist


# ----------------------------------------------------------------------------------------------
# per-run numbers


def start_structure(ens) -> pd.DataFrame:
    """Per run of ``ens`` (seeds order): packing fraction (``phi_start``) and contact fabric
    (``fabric_start``, ``fabric_major_start``) and the tilt of its free surface
    (``surface_tilt_start``) at frame 0, after its history
    (:mod:`tiltpile.analysis.structure`, bulk window 3 d inside the pile; fabric of the active
    contacts of bulk grains). NaN where the pile leaves no window, and for every run of an
    ensemble read from its records (they keep no frame's positions)."""
    from tiltpile.analysis.contacts import active_mask, bulk_mask
    from tiltpile.analysis.structure import bulk_window, fabric, packing_fraction, surface_tilt_deg
    from tiltpile.store import open_run
    if getattr(ens, "records", None):
        return pd.DataFrame({c: np.full(len(ens.seeds), np.nan) for c in STRUCTURE})
    rows = []
    for s in ens.seeds:
        with open_run(ens.run_path(s)) as r:
            pos, (pair, force, _) = r.position(0), r.contacts(0)
            radius, fixed, length = r.radius, r.fixed, r.box_length
        try:
            phi = packing_fraction(pos, radius, bulk_window(pos, radius, fixed, length,
                                                            margin=BULK_MARGIN))
        except ValueError:
            phi = np.nan
        fab = fabric(pair, pos, active_mask(force), select=bulk_mask(pos, radius, fixed, pair, length))
        rows.append({"phi_start": phi, "fabric_start": fab["anisotropy"],
                     "fabric_major_start": fab["major_deg"],
                     "surface_tilt_start": surface_tilt_deg(pos, radius, fixed, length)})
    return pd.DataFrame(rows)


REPOSE_FILE = "repose.json"


def repose_numbers(ens) -> dict | None:
    """The repose angle of the ensemble's piles (:mod:`tiltpile.repose`), from
    ``DIR/repose.json`` as ``tiltpile repose DIR --json DIR/repose.json`` writes it: the stop
    angle (our repose angle, the box's), the free surface's slope to the horizontal once stopped,
    and the slide angle, mean and bootstrap interval over runs, and per seed. None when the file is absent; ValueError when its runs are not the ensemble's."""
    import json
    p = Path(ens.data_dir) / REPOSE_FILE
    if not p.exists():
        return None
    doc = json.loads(p.read_text())
    seeds = sorted(int(r["seed"]) for r in doc["runs"])
    if seeds != sorted(int(s) for s in ens.seeds):
        raise ValueError(f"{p}: measured on seeds {seeds}, the ensemble has {list(ens.seeds)}; "
                         f"rerun `tiltpile repose {ens.data_dir} --json {p}`")
    by_seed = {int(r["seed"]): r for r in doc["runs"]}
    summ = doc["summary"]
    return {"stop_deg": summ["stop_deg"], "slide_deg": summ["slide_deg"],
            "surface_deg": summ.get("surface_deg"),
            "outcomes": summ["outcomes"],
            "stop_deg_per_run": [by_seed[int(s)].get("stop_deg") for s in ens.seeds],
            "slide_deg_per_run": [by_seed[int(s)].get("slide_deg") for s in ens.seeds],
            "params": doc.get("params")}


def per_run_table(ens, theta_onset, theta_slide, below_deg: float = np.nan,
                  theta_rev: float = np.nan) -> pd.DataFrame:
    """Per run of ``ens`` (seeds order): theta_first_onset, theta_first_slide, slid, theta_end,
    n_onsets, n_precursors, n_onsets_below (onsets at theta < below_deg; NaN without it),
    z_quiet, n_m_quiet, z_start (bulk z at frame 0), the memory measures theta_first_change,
    onset_over_rev and n_onsets_below_rev (``theta_rev``: the ensemble's own largest history
    angle; NaN for fresh piles) and the structure at frame 0 (:func:`start_structure`)."""
    f = ens.frames.sort_values(["run", "frame"], kind="stable")
    q = per_run_quiet(f, ens.seeds)
    struct = start_structure(ens)
    rows = []
    for k, s in enumerate(ens.seeds):
        g = f[f["run"] == s]
        th = g["theta_deg"].to_numpy(float)
        sl = float(theta_slide[k])
        lf = g["lost_fraction"].to_numpy(float)
        changed = np.flatnonzero(np.nan_to_num(lf) > CHANGE_CUTOFF)
        onset_th = th[g["onset"].to_numpy(bool)]
        rows.append({"run": int(s), "theta_first_onset": float(theta_onset[k]),
                     "theta_first_slide": sl, "slid": bool(np.isfinite(sl)),
                     "theta_end": float(th[-1]) if th.size else np.nan,
                     "n_onsets": int(g["onset"].astype(bool).sum()),
                     "n_precursors": precursor_count(th, g["onset"].to_numpy(bool),
                                                     g["avalanching"].to_numpy(bool), sl),
                     "n_onsets_below": (float((th[g["onset"].to_numpy(bool)] < below_deg).sum())
                                        if np.isfinite(below_deg) else np.nan),
                     "z_quiet": float(q["z"].iloc[k]), "n_m_quiet": float(q["n_m"].iloc[k]),
                     "z_start": float(g["z"].iloc[0]) if len(g) else np.nan,
                     "theta_first_change": float(th[changed[0]]) if changed.size else np.nan,
                     "onset_over_rev": float(theta_onset[k]) / theta_rev,
                     "n_onsets_below_rev": (float((onset_th < theta_rev).sum())
                                            if np.isfinite(theta_rev) else np.nan),
                     **struct.iloc[k].to_dict()})
    return pd.DataFrame(rows)


def _config_differences(ens_list) -> list[str]:
    """Configuration keys (section.key) whose values differ between the ensembles, apart from
    protocol.pretilt_deg (configurations normalised by :func:`tiltpile.config.from_dict`)."""
    from tiltpile import config as _cfg
    dicts = [_cfg.from_dict(e.config).to_dict() for e in ens_list]
    out = []
    for sec in dicts[0]:
        for key in dicts[0][sec]:
            if (sec, key) == ("protocol", "pretilt_deg"):
                continue
            vals = [d[sec][key] for d in dicts]
            if any(v != vals[0] for v in vals[1:]):
                out.append(f"{sec}.{key}")
    return out


# ----------------------------------------------------------------------------------------------
# the study


def compute(ens_list, labels, histories=None, confidence: float = 0.95, **fig2_kwargs
            ) -> tuple[dict, dict]:
    """Numbers and plot data of the preparation study (module docstring).

    ens_list: ensembles (:class:`tiltpile.figures.data.Ensemble`), the first the reference;
    labels: one per ensemble; histories: their preparation histories (target angles, deg; None:
    read from the run files, :func:`preparation_history`); confidence: of every interval;
    fig2_kwargs: passed to :func:`tiltpile.figures.fig2.compute` (ke_* of the slide threshold,
    slide_sustain_deg, lost_bins_per_decade, ...), so that onsets, slides and the bimodality are
    Fig. 2's.

    numbers:
      reference                    label of the first ensemble
      config_differences           configuration keys other than protocol.pretilt_deg whose values
                                   differ between the ensembles (empty: only the preparation does)
      below_deg                    the largest |pretilt angle| of the study (NaN: all fresh): a
                                   pile tilted before is expected to rearrange less below it
      ensembles                    {label: per-ensemble dict}, in input order, each with
        pretilt_deg, n_runs, seeds, theta_end_min
        per_run                    {column: list over seeds} of :func:`per_run_table`
        <q>_mean, <q>_ci_low, <q>_ci_high  for q in PER_RUN (bootstrap over runs; the slide over
                                   the runs that slid), and n_runs_with_onset, n_runs_with_slide
        z_start_mean (+ CI)        bulk z of the runs' first frame (the pile as the ramp starts)
        n_precursors_slid_mean     mean precursor count over the runs that slid (the others count
                                   to the end of the tilt)
        slide_ke, slide_sustain_deg, cutoff   the slide detector and onset cutoff used (Fig. 2)
        lost_bimodality            Fig. 2b's: delta_bic, ashman_d, valley_depth, valley, ...
        lost_zero_fraction         fraction of the frames that lose no contact
        theta_rev_deg, n_runs_quiet_past, quiet_past_deg   the history's amplitude (NaN: fresh)
                                   and the runs whose first onset comes after 14.4 deg
        repose                     the repose and slide angles of :func:`repose_numbers` (None
                                   without DIR/repose.json)
        theta_m_mean_fig2          Fig. 2's theta_m_mean of the same ensemble (check)
        theta_first_slide_ref_ke_mean, n_precursors_ref_ke_mean (+ CI, per_run),
        n_runs_with_slide_ref_ke   the first slide and the precursors before it with the
                                   reference ensemble's threshold (slide_ke_reference) instead
                                   of the ensemble's own
      differences                  {label: {q: diff_ci(ensemble, reference)}} for q in PER_RUN
                                   and the two _ref_ke quantities, each prepared ensemble
                                   against the reference
    """
    ens_list = list(ens_list)
    labels = [str(x) for x in labels]
    if not ens_list:
        raise ValueError("preparation study: no ensemble")
    if len(labels) != len(ens_list):
        raise ValueError(f"preparation study: {len(labels)} labels for {len(ens_list)} ensembles")
    if len(set(labels)) != len(labels):
        raise ValueError(f"preparation study: labels repeat: {labels}")
    if histories is None:
        histories = [preparation_history(e.data_dir) for e in ens_list]
    amp = [abs(float(x)) for h in histories for x in h]
    below = max(amp) if amp and max(amp) > 0 else np.nan
    numbers: dict = {"reference": labels[0], "config_differences": _config_differences(ens_list),
                     "below_deg": below, "ensembles": {}, "differences": {}}
    tables = {}
    for e, lab, hist in zip(ens_list, labels, histories):
        n2, _ = fig2.compute(e, confidence=confidence, **fig2_kwargs)
        rev = max((abs(float(x)) for x in hist), default=0.0) or np.nan
        t = per_run_table(e, n2["theta_m_per_run"], n2["theta_slide_per_run"], below, rev)
        tables[lab] = t
        out = {"pretilt_deg": [float(x) for x in hist], "theta_rev_deg": rev,
               "n_runs": int(e.n_runs), "quiet_past_deg": QUIET_PAST_DEG,
               "n_runs_quiet_past": int((np.nan_to_num(t["theta_first_onset"], nan=np.inf)
                                         >= QUIET_PAST_DEG).sum()),
               "seeds": [int(s) for s in e.seeds], "theta_end_min": n2["theta_end_min"],
               "per_run": {c: t[c].tolist() for c in t.columns if c != "run"}}
        for q in list(PER_RUN) + ["z_start"]:
            ci = _st.bootstrap_ci(t[q], confidence=confidence)
            out.update({f"{q}_mean": ci["estimate"], f"{q}_ci_low": ci["low"],
                        f"{q}_ci_high": ci["high"]})
        slid = t["slid"].to_numpy(bool)
        out.update(n_runs_with_onset=int(np.isfinite(t["theta_first_onset"]).sum()),
                   n_runs_with_slide=int(slid.sum()),
                   n_precursors_slid_mean=float(t["n_precursors"][slid].mean()) if slid.any()
                   else np.nan,
                   slide_ke=n2["slide_ke"], slide_sustain_deg=n2["slide_sustain_deg"],
                   cutoff=n2["cutoff"], lost_bimodality=n2["lost_bimodality"],
                   lost_zero_fraction=n2["lost_zero_fraction"],
                   theta_m_mean_fig2=n2["theta_m_mean"],
                   repose=repose_numbers(e))
        numbers["ensembles"][lab] = out
    # the slide again with the reference's kinetic-energy threshold for every ensemble: each
    # ensemble's own Fig. 2a threshold differs, and a lower one finds slides earlier and more often
    ref_ke = numbers["ensembles"][labels[0]]["slide_ke"]
    numbers["slide_ke_reference"] = ref_ke
    for e, lab in zip(ens_list, labels):
        out = numbers["ensembles"][lab]
        if np.isfinite(ref_ke):
            ro = run_onsets(e.frames, float(ref_ke), float(out["slide_sustain_deg"])
                            ).set_index("run")
            sl = np.array([float(ro["theta_first_slide"].get(s, np.nan)) for s in e.seeds])
        else:
            sl = np.full(e.n_runs, np.nan)
        f = e.frames.sort_values(["run", "frame"], kind="stable")
        npre = np.array([precursor_count(g["theta_deg"].to_numpy(float), g["onset"].to_numpy(bool),
                                         g["avalanching"].to_numpy(bool), sl[k])
                         for k, g in ((k, f[f["run"] == s]) for k, s in enumerate(e.seeds))],
                        dtype=float)
        out["n_runs_with_slide_ref_ke"] = int(np.isfinite(sl).sum())
        for q, v in (("theta_first_slide_ref_ke", sl), ("n_precursors_ref_ke", npre)):
            tables[lab][q] = v
            out["per_run"][q] = v.tolist()
            ci = _st.bootstrap_ci(v, confidence=confidence)
            out.update({f"{q}_mean": ci["estimate"], f"{q}_ci_low": ci["low"],
                        f"{q}_ci_high": ci["high"]})
    ref = tables[labels[0]]
    for lab in labels[1:]:
        numbers["differences"][lab] = {q: diff_ci(tables[lab][q], ref[q], confidence=confidence)
                                       for q in list(PER_RUN) + ["theta_first_slide_ref_ke",
                                                                 "n_precursors_ref_ke"]}
    data = {"labels": labels, "tables": tables, "confidence": confidence,
            "n_grains": [e.meta.get("n_grains") for e in ens_list]}
    return numbers, data


def meta(ens_list, labels, histories) -> dict:
    """What the JSON records beside the numbers: per ensemble its directory, label, preparation
    history, preset, runs, seeds, grains, config hash, analysis parameters and whether it was
    read from its records (``from_records``: no frame-0 structure)."""
    return {"ensembles": [dict(e.meta, data_dir=str(e.data_dir), label=lab,
                               pretilt_deg=[float(x) for x in h],
                               from_records=bool(getattr(e, "records", None)))
                          for e, lab, h in zip(ens_list, labels, histories)]}


# ----------------------------------------------------------------------------------------------
# the figure


def _mean_ci(ax, x, ens_numbers, q, color, marker="_"):
    """The mean over runs and its bootstrap interval, at x + 0.07 (beside the points)."""
    x = x + 0.07
    m = ens_numbers[f"{q}_mean"]
    lo, hi = ens_numbers[f"{q}_ci_low"], ens_numbers[f"{q}_ci_high"]
    if not np.isfinite(m):
        return
    yerr = (np.array([[m - lo], [hi - m]]) if np.isfinite(lo) and np.isfinite(hi) else None)
    ax.errorbar([x], [m], yerr=yerr, color=color, marker=marker, ms=9, mew=1.6, lw=1.2,
                capsize=2.5, zorder=4)


def _points(ax, x, y, color, marker, filled=None, jitter=0.05):
    """Per-run values as points spread over x - 0.07 +- jitter (the mean sits at x + 0.07)."""
    y = np.asarray(y, dtype=float)
    xs = x - 0.07 + jitter * (np.arange(y.size) - (y.size - 1) / 2) / max(y.size - 1, 1) * 2
    filled = np.ones(y.size, bool) if filled is None else np.asarray(filled, bool)
    for sel, face in ((filled, color), (~filled, "white")):
        ax.plot(xs[sel], y[sel], ls="none", marker=marker, ms=3.2, mew=0.7, mec=color, mfc=face,
                zorder=3)


def plot(data: dict, numbers: dict):
    """(a) first onset and first slide per ensemble, (b) precursor events before the slide and
    onsets below the study's largest pretilt angle, (c) <z>, (d) <n_m> of the quiet frames: per
    run (points; open: the run did not slide before the end of its tilt, shown at that angle in
    a and counted to it in b) and mean with its bootstrap interval (bar); the memory of the
    history, (e) the first change and first onset against the history's amplitude; what the
    history leaves at frame 0, (f) packing fraction, (g) fabric anisotropy, (h) its direction."""
    labels = data["labels"]
    nens = len(labels)
    ens = numbers["ensembles"]
    onset_c, slide_c = style.OKABE_ITO["blue"], style.COLORS["avalanche"]
    below_c, below = style.OKABE_ITO["purple"], numbers.get("below_deg")
    below = np.nan if below is None else float(below)
    fig, axs = style.figure(2, 4, width=style.DOUBLE_COLUMN_IN, height=5.6 + 0.1 * nens,
                            gridspec_kw=dict(wspace=0.42, hspace=0.8, left=0.06, right=0.99,
                                             bottom=0.1 + 0.018 * nens, top=0.87))
    a, b, c, d = axs[0]
    e_ax, f_ax, g_ax, h_ax = axs[1]
    x = np.arange(nens, dtype=float)
    for i, lab in enumerate(labels):
        t, e = data["tables"][lab], ens[lab]
        slid = t["slid"].to_numpy(bool)
        _points(a, x[i] - 0.2, t["theta_first_onset"], onset_c, "o")
        _mean_ci(a, x[i] - 0.2, e, "theta_first_onset", onset_c)
        ys = np.where(slid, t["theta_first_slide"], t["theta_end"])
        _points(a, x[i] + 0.2, ys, slide_c, "s", filled=slid)
        _mean_ci(a, x[i] + 0.2, e, "theta_first_slide", slide_c)
        a.text(x[i] + 0.2, 1.0, f"{int(slid.sum())}/{len(t)}\nslid",
               transform=a.get_xaxis_transform(), ha="center", va="bottom", fontsize=5.5,
               color=slide_c)
        _points(b, x[i] - 0.2, t["n_precursors"], style.COLORS["quiet"], "D", filled=slid)
        _mean_ci(b, x[i] - 0.2, e, "n_precursors", style.COLORS["quiet"])
        if np.isfinite(below):
            _points(b, x[i] + 0.2, t["n_onsets_below"], below_c, "v")
            _mean_ci(b, x[i] + 0.2, e, "n_onsets_below", below_c)
        _points(c, x[i], t["z_quiet"], style.COLORS["quiet"], "o")
        _mean_ci(c, x[i], e, "z_quiet", style.COLORS["quiet"])
        _points(d, x[i], t["n_m_quiet"], style.COLORS["quiet"], "o")
        _mean_ci(d, x[i], e, "n_m_quiet", style.COLORS["quiet"])
        # the memory: where irreversible change returns, against the history's amplitude
        _points(e_ax, x[i] - 0.2, t["theta_first_change"], below_c, "^")
        _mean_ci(e_ax, x[i] - 0.2, e, "theta_first_change", below_c)
        _points(e_ax, x[i] + 0.2, t["theta_first_onset"], onset_c, "o")
        _mean_ci(e_ax, x[i] + 0.2, e, "theta_first_onset", onset_c)
        rev = e.get("theta_rev_deg")
        if rev is not None and np.isfinite(rev):
            e_ax.plot([x[i] - 0.4, x[i] + 0.4], [rev, rev], color="k", lw=0.8, ls="--")
        for ax, q in ((f_ax, "phi_start"), (g_ax, "fabric_start"), (h_ax, "fabric_major_start")):
            _points(ax, x[i], t[q], style.COLORS["quiet"], "o")
            _mean_ci(ax, x[i], e, q, style.COLORS["quiet"])
    # one word per line, so that the labels of neighbouring ensembles never overlap
    names = ["\n".join(lab.split()) + f"\n{len(data['tables'][lab])} runs" for lab in labels]
    for ax, lab, ylab in ((a, "a", r"$\theta$ (deg)"), (b, "b", "onsets per run"),
                          (c, "c", r"$\langle z\rangle$ quiet frames"),
                          (d, "d", r"$\langle n_m\rangle$ quiet frames"),
                          (e_ax, "e", r"$\theta$ (deg)"),
                          (f_ax, "f", r"packing fraction at $0\degree$"),
                          (g_ax, "g", r"fabric anisotropy at $0\degree$"),
                          (h_ax, "h", r"fabric major axis (deg from normal)")):
        ax.set_xticks(x, names, fontsize=6)
        ax.set_xlim(-0.6, nens - 0.4)
        ax.set_ylabel(ylab)
        ax.tick_params(axis="x", which="both", top=False)
        ax.text(-0.02, 1.02, lab, transform=ax.transAxes, ha="right", va="bottom",
                fontstyle="italic", fontweight="bold")
    from matplotlib.ticker import MaxNLocator
    for ax, q in ((f_ax, "phi_start"), (g_ax, "fabric_start"), (h_ax, "fabric_major_start")):
        if not any(np.isfinite(data["tables"][lab][q]).any() for lab in labels):
            # every ensemble read from its records: they keep no frame's positions
            ax.text(0.5, 0.5, "n/a: records keep\nno positions", transform=ax.transAxes,
                    ha="center", va="center", fontsize=6, color=style.COLORS["guide"])
            ax.set_yticks([])
    b.set_ylim(-0.6, max(b.get_ylim()[1], 2.0))
    b.yaxis.set_major_locator(MaxNLocator(integer=True))
    a.set_ylim(bottom=0)
    e_ax.set_ylim(bottom=0)
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], ls="none", marker="o", color=onset_c, ms=4,
                      label=f"first onset ({100 * ens[labels[0]]['cutoff']:g}% contacts lost)"),
               Line2D([], [], ls="none", marker="s", color=slide_c, ms=4,
                      label="first large slide (mean: runs that slid)"),
               Line2D([], [], ls="none", marker="s", mfc="white", mec=slide_c, ms=4,
                      label=r"no slide: end of tilt (a), events to the end (b)"),
               Line2D([], [], ls="none", marker="D", color=style.COLORS["quiet"], ms=3.5,
                      label="(b) onsets before the first slide"),
               *([Line2D([], [], ls="none", marker="v", color=below_c, ms=4,
                         label=rf"(b) onsets below {below:g}$\degree$")]
                 if np.isfinite(below) else []),
               Line2D([], [], ls="none", marker="^", color=below_c, ms=4,
                      label=f"(e) first frame losing > {100 * CHANGE_CUTOFF:g}% of contacts"),
               Line2D([], [], ls="--", color="k", lw=0.8,
                      label=r"(e) the history's amplitude $\theta_{rev}$"),
               Line2D([], [], ls="none", marker="_", color="k", ms=9, mew=1.6,
                      label=f"mean, {100 * data['confidence']:g}% bootstrap CI over runs")]
    fig.legend(handles=handles, loc="upper center", ncol=3, bbox_to_anchor=(0.5, 1.0),
               handletextpad=0.3, columnspacing=1.2)
    def fmt(v, spec):
        return format(v, spec) if v is not None and np.isfinite(v) else "n/a"

    # one line per ensemble, so that the footer never outgrows the figure
    ref_ke = numbers.get("slide_ke_reference")
    show_ref = ref_ke is not None and np.isfinite(ref_ke)
    # one threshold for all: the study's slide_ke (each ensemble's Fig. 2a threshold differs)
    same = len({ens[lab]["slide_ke"] for lab in labels}) == 1 and nens > 1
    lines = []
    for lab in labels:
        e = ens[lab]
        line = (f"{lab}: Fig. 2b Ashman D = {fmt(e['lost_bimodality']['ashman_d'], '.1f')}, valley "
                f"{fmt(e['lost_bimodality']['valley_depth'], '.2f')}, no contact lost in "
                f"{fmt(100 * e['lost_zero_fraction'], '.0f')}% of frames; slide KE threshold "
                f"{'' if same else '(Fig. 2a) '}{e['slide_ke']:.1e}")
        if show_ref and not same and "n_runs_with_slide_ref_ke" in e:
            line += (f"; at the reference's {ref_ke:.1e}: {e['n_runs_with_slide_ref_ke']}/"
                     f"{e['n_runs']} slid, {fmt(e['n_precursors_ref_ke_mean'], '.1f')} onsets before")
        lines.append(line)
    fig.text(0.5, 0.005, "\n".join(lines), ha="center", va="bottom", fontsize=5.5)
    return fig
