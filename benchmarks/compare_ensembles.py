"""Does a setting change the physics? The onset angle and the quiet contact network of ensembles
that differ in one setting, against the first.

Usage: python -m benchmarks.compare_ensembles DIR [DIR ...]
  DIR  an ensemble directory (``tiltpile ensemble ... --out DIR``); its observables are computed
       if missing (``tiltpile observables``). The first DIR is the reference.

Per ensemble: the configuration keys that differ from the reference's; the runs; five numbers
per run: the first onset theta_m (Fig. 2's definition, :func:`tiltpile.analysis.ensemble_data.first_onsets`),
the mean coordination z and mobilized fraction n_m over the run's quiet frames, the fraction of
its quiet frames below the marginal line (z < 3 + n_m; Fig. 1) and the cluster-size exponent
delta of its quiet clusters just before its onsets (Fig. 5's pooled fit, one run at a time); their mean
over the runs with its standard error, and the difference from the reference's with Welch's
t-test (two-sided p); and the fraction of avalanching frames. Different
settings usually deposit different piles, so the comparison is between ensembles, not run by
run: with ~6 runs and a seed-to-seed spread of ~2 deg only shifts of 2-3 deg stand out.
notes/performance-log.md ("Speed and accuracy") records what it measured (time step and tolerance at the default scale).
"""
from __future__ import annotations

import argparse
import sys

import numpy as np


def config_diff(ref: dict, cfg: dict, prefix: str = "") -> dict:
    """{"section.key": (ref value, value)} for every key whose value differs (or is missing)."""
    out = {}
    for k in sorted(set(ref) | set(cfg)):
        a, b = ref.get(k), cfg.get(k)
        name = f"{prefix}{k}"
        if isinstance(a, dict) and isinstance(b, dict):
            out.update(config_diff(a, b, name + "."))
        elif a != b:
            out[name] = (a, b)
    return out


METRICS = ("theta_m", "z_quiet", "n_m_quiet", "below_quiet", "delta")
DELTA_POOL = (-1.0, 0.0)  # theta - theta_m window of the clusters delta is fitted to (Fig. 5's)


def _run_delta(clusters, seeds, s_min: int = 2, min_samples: int = 50) -> np.ndarray:
    """Per run, delta of the quiet clusters with theta - theta_m in ``DELTA_POOL`` (Fig. 5's pooled
    fit, one run at a time; NaN where the fit is refused)."""
    import warnings

    from tiltpile.analysis.stats import InsufficientDataError, fit_power_law_cutoff

    cl = clusters[~clusters["avalanching"].to_numpy(bool)]
    t = cl["theta_to_onset"].to_numpy(float)
    cl = cl[(t >= DELTA_POOL[0] - 1e-9) & (t < DELTA_POOL[1] - 1e-9)]
    out = []
    for s in seeds:
        sizes = cl.loc[cl["run"] == s, "size"].to_numpy()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out.append(fit_power_law_cutoff(sizes, s_min=s_min, min_samples=min_samples).delta)
        except InsufficientDataError:
            out.append(np.nan)
    return np.array(out, float)


def summarize(ens) -> dict:
    """The numbers of one ensemble (module docstring): per metric the per-run values (seeds in
    ``ens.seeds`` order, NaN where a run has none), ``<metric>_mean`` and ``<metric>_sem``."""
    from tiltpile.analysis.ensemble_data import first_onsets

    f = ens.frames
    av = f["avalanching"].to_numpy(bool)
    quiet = f[~av].groupby("run")[["z", "n_m"]].mean()
    q = f[~av]
    below = (q["z"] - 3.0 - q["n_m"] < 0).groupby(q["run"]).mean()
    per_run = {"theta_m": first_onsets(f, ens.seeds),
               "z_quiet": np.array([quiet["z"].get(s, np.nan) for s in ens.seeds], float),
               "n_m_quiet": np.array([quiet["n_m"].get(s, np.nan) for s in ens.seeds], float),
               "below_quiet": np.array([below.get(s, np.nan) for s in ens.seeds], float),
               "delta": _run_delta(ens.clusters, ens.seeds)}
    out = dict(config=ens.config, seeds=list(ens.seeds), cost=ens.meta.get("cost") or {},
               avalanching_fraction=float(av.mean()) if av.size else np.nan)
    for name, x in per_run.items():
        ok = x[np.isfinite(x)]
        out[name] = x
        out[f"{name}_mean"] = float(ok.mean()) if ok.size else np.nan
        out[f"{name}_sem"] = float(ok.std(ddof=1) / np.sqrt(ok.size)) if ok.size > 1 else np.nan
    out["n_onset"] = int(np.isfinite(per_run["theta_m"]).sum())
    return out


def welch(a, b) -> tuple[float, float]:
    """(mean(b) - mean(a), two-sided p of Welch's t-test); NaN where either has < 2 values."""
    from scipy import stats

    a = np.asarray(a, float)
    b = np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size < 2 or b.size < 2:
        return np.nan, np.nan
    if np.array_equal(np.sort(a), np.sort(b)):  # scipy gives p = 1 here too, but NaN (and a
        return 0.0, 1.0                          # warning) when the values are all equal
    return float(b.mean() - a.mean()), float(stats.ttest_ind(a, b, equal_var=False).pvalue)


def compare(dirs) -> list[dict]:
    """One row per directory: ``summarize`` plus ``diff`` (config keys) and, per metric of
    ``METRICS``, ``<metric>_shift`` and ``<metric>_p`` against the first (``welch``)."""
    from tiltpile.analysis.ensemble_data import load_ensemble

    rows = []
    for d in dirs:
        row = summarize(load_ensemble(d))
        row["dir"] = str(d)
        ref = rows[0] if rows else row
        row["diff"] = config_diff(ref["config"], row["config"])
        for m in METRICS:
            row[f"{m}_shift"], row[f"{m}_p"] = welch(ref[m], row[m])
        rows.append(row)
    return rows


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.compare_ensembles",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", help="ensemble directories; the first is the reference")
    a = ap.parse_args(argv)
    rows = compare(a.dirs)
    for k, r in enumerate(rows):
        diff = ", ".join(f"{key} = {v[1]!r} (ref {v[0]!r})" for key, v in r["diff"].items())
        diff = diff or ("reference" if k == 0 else "the reference's configuration")
        th = " ".join("-" if not np.isfinite(x) else f"{x:.2f}" for x in r["theta_m"])
        print(f"{r['dir']}: {diff}")
        print(f"  runs {len(r['seeds'])} (seeds {r['seeds']}), onsets {r['n_onset']}: theta_m {th}; "
              f"avalanching {r['avalanching_fraction']:.3f} of the frames")
        for m, unit, fmt in (("theta_m", " deg", ".2f"), ("z_quiet", "", ".4f"), ("n_m_quiet", "", ".4f"),
                             ("below_quiet", "", ".4f"), ("delta", "", ".3f")):
            print(f"  {m:9s} {r[m + '_mean']:{fmt}} +- {r[m + '_sem']:{fmt}}{unit}   shift "
                  f"{r[m + '_shift']:+{fmt}}, Welch p {r[m + '_p']:.2f}", flush=True)
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
