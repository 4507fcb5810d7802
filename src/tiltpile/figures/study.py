"""A parameter study: the figures' numbers of one preset's ensembles, one per value of a key.

``tiltpile study`` (``make study KEY=section.key VALUES="..."``) runs, for each value of one
configuration key, an ensemble of a preset with that key set, its observables, records and repose
angles; this module turns those ensembles into the study's numbers, one summary figure and the
JSON beside it. Per value, run by run where the number is a run's, and as a mean over runs with a
bootstrap interval (:func:`tiltpile.analysis.stats.bootstrap_ci`, BCa, 9999 resamples, seed 0):

* the first 2% onset and the avalanche angle (first large slide: kinetic energy per grain above
  1e-3 m g d), as Fig. 2 computes them (:func:`tiltpile.figures.fig2.compute`);
* the repose angle (``tiltpile repose``: the free surface's slope once the flow has stopped, and
  the box's angle then), from the ensemble's ``repose.json`` -- of the study's piles, or with the
  history ``repose+D`` of the fresh piles whose repose angle set the history;
* <z>, <n_m> and the fraction of quiet frames below the marginal line z = 3 + n_m, over each
  run's quiet frames (:func:`tiltpile.figures.data.per_run_quiet`, as Fig. 2);
* the clusters' orientation to gravity, Fig. 3's: every quiet-frame cluster of >= 5 grains
  pooled (:func:`quiet_orientations`), its interval by resampling whole runs
  (:func:`tiltpile.analysis.stats.bootstrap_runs_ci`);
* delta, Fig. 5's pooled exponent of the cluster sizes within 1 deg before an onset, with Fig. 5's
  interval over runs (:func:`tiltpile.figures.fig5.compute`);
* <S_max> near the onset: each run's mean largest cluster over its quiet frames in the last
  0.5 deg before an onset (Fig. 5's last window), and the largest rigid cluster's share of the
  grains over the quiet frames within 1 deg of an onset (Fig. 7's ``rigid_fraction_near``).

For the key ``scene.mu`` the orientation is tested against Mohr-Coulomb, 45 + 1/2 atan(mu) deg
(:mod:`tiltpile.analysis.mohr_coulomb`): the slope of the measured against the predicted angle,
its interval from the runs resampled within each value.

The history option ``repose+D`` (:func:`parse_history`): per value, the fresh piles' repose
angle (surface slope) r sets Deboeuf's history of the study's piles, two full cycles to
theta_rev = r + D deg, rounded to the nearest whole degree (:func:`history_amplitude`; 14.7 + 1
gives the default preset's 16 deg at mu = 0.5).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from tiltpile.analysis import mohr_coulomb as _mc
from tiltpile.analysis.stats import bootstrap_ci, bootstrap_runs_ci

from . import style
from .data import per_run_quiet

NAME = "study"

# the study's numbers, in the order of the figure's panels (key: what it is)
QUANTITIES = {
    "theta_first_onset": "first 2% onset (deg): first frame losing more than the cutoff of its "
                         "contacts (Fig. 2's theta_m)",
    "theta_avalanche": "avalanche angle (deg): first large slide, kinetic energy per grain above "
                       "1e-3 m g d (Fig. 2; runs without one before the end of the tilt left out)",
    "repose_surface": "repose angle (deg): the free surface's slope to the horizontal once the "
                      "flow has stopped (tiltpile repose)",
    "repose_box": "the box's angle when the flow stops (deg; tiltpile repose's stop angle)",
    "z_quiet": "<z> of the quiet frames (bulk grains, force contacts)",
    "n_m_quiet": "<n_m> of the quiet frames",
    "quiet_below": "fraction of the quiet frames below the marginal line z = 3 + n_m",
    "orientation": "cluster orientation to gravity (deg): quiet-frame clusters of >= 5 grains, "
                   "pooled (Fig. 3)",
    "delta": "delta: exponent of the cluster sizes within 1 deg before an onset (Fig. 5, pooled "
             "fit; interval over runs)",
    "s_max_near": "<S_max> (grains) of the quiet frames within 0.5 deg before an onset (Fig. 5)",
    "rigid_near": "largest rigid cluster's share of the grains, quiet frames within 1 deg before "
                  "an onset (Fig. 7)",
}
# the panels' axis labels
LABELS = {"theta_first_onset": "first 2% onset (deg)", "theta_avalanche": "avalanche angle (deg)",
          "repose_surface": "repose angle: surface (deg)", "repose_box": "repose angle: box (deg)",
          "z_quiet": r"$\langle z\rangle$ quiet", "n_m_quiet": r"$\langle n_m\rangle$ quiet",
          "quiet_below": r"quiet frames below $z = 3 + n_m$", "orientation":
          "cluster orientation (deg)", "delta": r"$\delta$",
          "s_max_near": r"$\langle S_{max}\rangle$ near onset",
          "rigid_near": "rigid cluster share near onset"}
ORIENTATION_MIN_SIZE = 5   # Fig. 3's orientation_min_size
S_MAX_NEAR_DEG = 0.5       # Fig. 5's last window [-width, 0)
RIGID_NEAR_DEG = 1.0       # Fig. 7's near_deg
CYCLES = 2                 # Deboeuf et al.'s two full cycles
MU_KEY = "scene.mu"        # the key whose study tests Mohr-Coulomb


# ----------------------------------------------------------------------------------------------
# the plan: values, their directory names, the history


def value_label(value) -> str:
    """The directory name and label of a validated configuration value: floats by ``repr`` (0.2,
    1.0: the shortest text that reads back to the same number, so "1" and "1.0" are one value),
    integers as digits, booleans true/false, strings as they are."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


HISTORY_RE = re.compile(r"repose\+([0-9]+(?:\.[0-9]+)?)")


def parse_history(text: str | None) -> float | None:
    """The history option: None or "preset" (the preset's own history: None), or "repose+D" (D
    deg >= 0 above each value's fresh repose angle: returns D). ValueError otherwise."""
    if text is None or text == "preset":
        return None
    m = HISTORY_RE.fullmatch(text.strip())
    if not m:
        raise ValueError(f"history {text!r}: give 'preset' (the preset's own) or 'repose+D' "
                         "(two cycles to each value's fresh repose angle + D deg, e.g. repose+1)")
    return float(m.group(1))


def history_amplitude(repose_deg: float, offset_deg: float) -> float:
    """theta_rev of the history ``repose+D``: repose_deg + offset_deg rounded to the nearest
    whole degree (halves up), so that the fresh piles' 14.7 deg + 1 at mu = 0.5 gives the default
    preset's 16; a repose angle is known to ~1 deg over 6 piles (docs/figures.md), finer steps
    would only carry its noise. ValueError unless the repose angle is finite and the amplitude
    lies in (0, 90] deg."""
    if not (isinstance(repose_deg, (int, float)) and math.isfinite(repose_deg)):
        raise ValueError(f"no repose angle to set the history from (got {repose_deg!r})")
    a = float(math.floor(repose_deg + offset_deg + 0.5))
    if not 0.0 < a <= 90.0:
        raise ValueError(f"history amplitude {a:g} deg (repose {repose_deg:.2f} + {offset_deg:g}) "
                         "is outside (0, 90] deg")
    return a


def history_overrides(theta_rev_deg: float | None) -> list[str]:
    """The configuration overrides of a value's ensembles: None, the fresh piles (no history);
    else Deboeuf's ``CYCLES`` cycles to ``theta_rev_deg`` (the preset's history rate kept)."""
    if theta_rev_deg is None:
        return ["protocol.cycles=0", "protocol.theta_rev_deg=0.0",
                "protocol.pretilt_per_step_deg=0.0"]
    return [f"protocol.cycles={CYCLES}", f"protocol.theta_rev_deg={float(theta_rev_deg)!r}"]


# ----------------------------------------------------------------------------------------------
# repose angles


def read_repose(path) -> dict | None:
    """The per-seed stop (box) and surface angles of a ``tiltpile repose --json`` document
    (``{"seeds", "stop_deg", "surface_deg", "outcomes", "params"}``; NaN where a run did not
    stop); None when ``path`` does not exist."""
    p = Path(path)
    if not p.exists():
        return None
    doc = json.loads(p.read_text())
    runs = sorted(doc["runs"], key=lambda r: int(r["seed"]))

    def num(v):
        return float("nan") if v is None else float(v)

    return {"seeds": [int(r["seed"]) for r in runs],
            "stop_deg": [num(r.get("stop_deg")) for r in runs],
            "surface_deg": [num(r.get("surface_deg")) for r in runs],
            "outcomes": doc["summary"]["outcomes"], "params": doc.get("params")}


def repose_surface_mean(rep: dict) -> float:
    """Mean surface repose angle over the runs that stopped (NaN: none did)."""
    x = np.asarray(rep["surface_deg"], dtype=float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else float("nan")


# ----------------------------------------------------------------------------------------------
# per-value numbers


def quiet_orientations(clusters, seeds, min_size: int = ORIENTATION_MIN_SIZE) -> list[np.ndarray]:
    """Per run (order of ``seeds``): the orientations to gravity (deg) of its quiet-frame clusters
    of at least ``min_size`` grains with a defined orientation -- the clusters Fig. 3's
    ``orientation_mean_deg`` pools."""
    o = clusters["orientation_deg"].to_numpy(float)
    sel = ((clusters["size"].to_numpy() >= min_size) & np.isfinite(o)
           & ~clusters["avalanching"].to_numpy(bool))
    run = clusters["run"].to_numpy()
    return [o[sel & (run == s)] for s in seeds]


def quiet_near_means(frames, seeds, column: str, near_deg: float) -> np.ndarray:
    """Per run (order of ``seeds``): the mean of ``column`` over its quiet frames within
    ``near_deg`` before an onset (-near_deg <= theta - theta_m < 0; NaN without such frames)."""
    t = frames["theta_to_onset"].to_numpy(float)
    sel = (~frames["avalanching"].to_numpy(bool) & np.isfinite(t) & (t < 0) & (t >= -near_deg))
    m = frames[sel].groupby("run")[column].mean()
    return np.array([float(m.get(s, np.nan)) for s in seeds])


def _ci(values, confidence: float) -> dict:
    """Mean over runs and its interval (:func:`bootstrap_ci`); a single run has no interval
    (NaN), not the degenerate [x, x]."""
    ci = bootstrap_ci(values, confidence=confidence)
    out = {k: ci[k] for k in ("estimate", "low", "high", "n", "method")}
    if out["n"] < 2:
        out.update(low=float("nan"), high=float("nan"), method="one run: no interval")
    return out


def value_numbers(ens, repose: dict | None, confidence: float = 0.95) -> tuple[dict, dict]:
    """(numbers, per_run) of one value's ensemble ``ens`` (:class:`tiltpile.figures.data.Ensemble`)
    with the repose angles ``repose`` (:func:`read_repose`, or None): numbers {quantity: {estimate,
    low, high, n, method}} for every key of QUANTITIES; per_run {quantity: one value per seed of
    ens.seeds} (delta has none: it is one fit of the pooled clusters)."""
    import warnings

    from . import fig2, fig5

    seeds = list(ens.seeds)
    n2, _ = fig2.compute(ens, confidence=confidence)
    q = per_run_quiet(ens.frames.sort_values(["run", "frame"], kind="stable"), seeds)
    per_run = {"theta_first_onset": [float(x) for x in n2["theta_m_per_run"]],
               "theta_avalanche": [np.nan if x is None else float(x)
                                   for x in n2["theta_avalanche_per_run"]],
               "z_quiet": q["z"].tolist(), "n_m_quiet": q["n_m"].tolist(),
               "quiet_below": q["below"].tolist()}
    if repose is not None:
        by = dict(zip(repose["seeds"], zip(repose["stop_deg"], repose["surface_deg"])))
        missing = [s for s in seeds if s not in by]
        if missing and repose.get("piles") != "fresh":
            raise ValueError(f"repose angles of seeds {repose['seeds']}, the ensemble has {seeds}")
        per_run["repose_box"] = [by.get(s, (np.nan, np.nan))[0] for s in seeds]
        per_run["repose_surface"] = [by.get(s, (np.nan, np.nan))[1] for s in seeds]
    else:
        per_run["repose_box"] = per_run["repose_surface"] = [np.nan] * len(seeds)
    orient = quiet_orientations(ens.clusters, seeds)
    per_run["orientation"] = [float(o.mean()) if o.size else np.nan for o in orient]
    per_run["s_max_near"] = quiet_near_means(ens.frames, seeds, "largest_cluster",
                                             S_MAX_NEAR_DEG).tolist()
    per_run["rigid_near"] = (quiet_near_means(ens.frames, seeds, "rigid_fraction", RIGID_NEAR_DEG)
                             .tolist() if "rigid_fraction" in ens.frames else [np.nan] * len(seeds))
    numbers = {k: _ci(v, confidence) for k, v in per_run.items() if k != "orientation"}
    o = bootstrap_runs_ci(orient, _mc.pooled_mean, confidence=confidence)
    numbers["orientation"] = {"estimate": o["estimate"], "low": o["low"], "high": o["high"],
                              "n": o["n"], "n_clusters": int(sum(x.size for x in orient)),
                              "method": "percentile; runs resampled, clusters pooled"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # a window too small to fit is a NaN, not a warning
        n5, _ = fig5.compute(ens)
    numbers["delta"] = {"estimate": n5["delta_pooled"], "low": n5["delta_pooled_ci_low"],
                        "high": n5["delta_pooled_ci_high"], "n": n5["delta_pooled_n_runs"],
                        "n_clusters": n5["n_pooled"], "method": "percentile; runs resampled"}
    numbers["theta_avalanche"]["n_runs_with"] = int(np.isfinite(per_run["theta_avalanche"]).sum())
    return {k: numbers[k] for k in QUANTITIES}, {k: per_run[k] for k in QUANTITIES if k in per_run}


def compute(key: str, entries: list[dict], confidence: float = 0.95) -> dict:
    """The study's numbers. ``entries``: one dict per value, in order: value (the validated
    configuration value), label (:func:`value_label`), ens (its Ensemble), repose
    (:func:`read_repose` or None), repose_piles ("fresh" or "study": whose repose angles),
    theta_rev_deg (the history's amplitude with ``repose+D``, else None).

    Returns {key, values, labels, quantities, per_value: {label: {value, n_runs, seeds,
    theta_rev_deg, repose_piles, numbers, per_run}}, mohr_coulomb (key scene.mu only, else None):
    {mu, predicted_deg, measured_deg, fit (:func:`tiltpile.analysis.mohr_coulomb.slope_test` of
    the pooled orientations against the prediction, runs resampled within each value), verdict}}.
    """
    per_value, orient_runs = {}, []
    for e in entries:
        ens = e["ens"]
        rep = e.get("repose")
        if rep is not None:
            rep = dict(rep, piles=e.get("repose_piles"))
        numbers, per_run = value_numbers(ens, rep, confidence)
        per_value[e["label"]] = {"value": e["value"], "n_runs": int(ens.n_runs),
                                 "seeds": [int(s) for s in ens.seeds],
                                 "theta_rev_deg": e.get("theta_rev_deg"),
                                 "repose_piles": e.get("repose_piles"),
                                 "numbers": numbers, "per_run": per_run}
        orient_runs.append(quiet_orientations(ens.clusters, list(ens.seeds)))
    out = {"key": key, "values": [e["value"] for e in entries],
           "labels": [e["label"] for e in entries], "quantities": dict(QUANTITIES),
           "confidence": float(confidence), "per_value": per_value, "mohr_coulomb": None}
    if key == MU_KEY:
        mu = np.array([float(e["value"]) for e in entries])
        pred = _mc.failure_plane_deg(mu)
        fit = _mc.slope_test(pred, orient_runs, confidence=confidence)
        out["mohr_coulomb"] = {"mu": mu.tolist(), "predicted_deg": pred.tolist(),
                               "measured_deg": fit["y"], "fit": fit,
                               "verdict": _mc.verdict(fit),
                               "prediction": "45 + 1/2 atan(mu) deg to gravity; slope 1"}
    return out


# ----------------------------------------------------------------------------------------------
# the figure


def _x(numbers: dict) -> tuple[np.ndarray, list[str], bool]:
    """Positions of the values on the x axis: the values themselves when all are numbers, else
    0, 1, 2, ... with the labels as ticks."""
    vals = numbers["values"]
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals)
    x = np.array(vals, dtype=float) if numeric else np.arange(len(vals), dtype=float)
    return x, list(numbers["labels"]), numeric


def plot(numbers: dict):
    """One panel per quantity against the parameter: per run (points) and the mean with its
    bootstrap interval (bar); for scene.mu the orientation panel carries Mohr-Coulomb's
    45 + 1/2 atan(mu) (dashed) and the fitted line; a last panel the history's amplitudes."""
    x, labels, numeric = _x(numbers)
    keys = list(QUANTITIES)
    fig, axs = style.figure(3, 4, width=style.DOUBLE_COLUMN_IN, height=6.2,
                            gridspec_kw=dict(wspace=0.5, hspace=0.55, left=0.07, right=0.99,
                                             bottom=0.08, top=0.93))
    span = float(np.ptp(x)) or 1.0
    pc, mc = style.COLORS["quiet"], style.OKABE_ITO["blue"]
    for ax, k in zip(axs.flat, keys):
        for i, lab in enumerate(labels):
            pv = numbers["per_value"][lab]
            y = np.asarray(pv["per_run"].get(k, []), dtype=float)
            if y.size:
                jit = 0.012 * span * (np.arange(y.size) - (y.size - 1) / 2) / max(y.size - 1, 1)
                ax.plot(x[i] - 0.03 * span + jit, y, ls="none", marker="o", ms=2.6, mfc="none",
                        mec=pc, mew=0.6, zorder=2)
            c = pv["numbers"][k]
            m, lo, hi = (float("nan") if c.get(f) is None else float(c[f])
                         for f in ("estimate", "low", "high"))
            if math.isfinite(m):
                err = ([[m - lo], [hi - m]] if math.isfinite(lo) and math.isfinite(hi) else None)
                ax.errorbar([x[i] + 0.02 * span], [m], yerr=err, color=mc, marker="_", ms=8,
                            mew=1.5, lw=1.1, capsize=2.2, zorder=3)
        ax.set_ylabel(LABELS[k], fontsize=6.5)
    mcn = numbers.get("mohr_coulomb")
    ax_o = axs.flat[keys.index("orientation")]
    if mcn:
        mu = np.linspace(min(mcn["mu"]), max(mcn["mu"]), 50)
        ax_o.plot(mu, _mc.failure_plane_deg(mu), ls="--", color="k", lw=0.8,
                  label=r"$45 + \frac{1}{2}\arctan\mu$")
        f = mcn["fit"]
        if math.isfinite(f["slope"]):
            ax_o.plot(mu, f["intercept"] + f["slope"] * _mc.failure_plane_deg(mu),
                      color=mc, lw=0.8, label=f"fit: slope {f['slope']:.2f}")
        ax_o.legend(fontsize=5.5, loc="upper left", frameon=False)
    last = axs.flat[len(keys)]
    amps = [numbers["per_value"][lab].get("theta_rev_deg") for lab in labels]
    if any(a is not None for a in amps):
        last.plot(x, [np.nan if a is None else a for a in amps], marker="s", color="k", ms=3,
                  lw=0.8)
        last.set_ylabel(r"history amplitude $\theta_{rev}$ (deg)", fontsize=6.5)
    else:
        last.axis("off")
    for ax in axs.flat[: len(keys) + 1]:
        if not numeric:
            ax.set_xticks(x, labels)
        ax.set_xlim(x.min() - 0.12 * span, x.max() + 0.12 * span)
        ax.set_xlabel(numbers["key"], fontsize=6.5)
        ax.tick_params(labelsize=6)
    runs = sorted({numbers["per_value"][lab]["n_runs"] for lab in labels})
    fig.suptitle(f"{numbers['key']}: {len(labels)} values, {'/'.join(map(str, runs))} "
                 f"run{'s' if runs != [1] else ''} each; "
                 f"points: runs, bars: mean and {100 * numbers['confidence']:g}% bootstrap "
                 "interval over runs", fontsize=7)
    return fig


def write(numbers: dict, meta: dict, figures_dir) -> dict[str, Path]:
    """``figures_dir/study.{png,pdf,json}`` (:func:`tiltpile.figures.style.save`): the figure of
    :func:`plot` and the JSON {figure, **meta, numbers}."""
    import matplotlib.pyplot as plt

    style.use()
    fig = plot(numbers)
    try:
        return style.save(fig, NAME, numbers, figures_dir, meta)
    finally:
        plt.close(fig)
