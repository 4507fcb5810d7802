"""The same piles under two settings: pile against pile, and every figure number ensemble against
ensemble in units of its statistical error.

Two ensembles of the same seeds deposit the same piles when only what comes after the deposition
differs (the history's rate: ``paper-fast`` against ``paper``; another engine on the same piles).
This study says whether the second setting may stand in for the first (``tiltpile same-piles``):

* **pile against pile** (:func:`pile_against_pile`): per seed, the numbers of
  :func:`tiltpile.figures.preparation.per_run_table` (first onset by the 2% criterion, first
  large slide at the avalanche threshold, onsets, <z> and <n_m> of the quiet frames, the first
  change above 0.5%, the pile at frame 0 where run files hold it, the median kinetic energy of
  the quiet frames) of each ensemble, their paired
  difference per seed, and the mean difference with a BCa bootstrap interval over the seeds
  (:func:`tiltpile.analysis.stats.bootstrap_ci` of the per-seed differences);
* **ensemble against ensemble** (:func:`ensemble_against_ensemble`): every scalar number of every
  figure, computed as the figure's notebook computes it (:func:`figure_documents`:
  :func:`tiltpile.figures.build.document`, without the plot), for both ensembles; its standard
  error by the jackknife over runs (leave one run out, :func:`jackknife`; sqrt((n - 1) / n * sum (x_i -
  x)^2)); the shift in units of the combined error sqrt(se_ref^2 + se^2), as
  ``benchmarks.guard`` measures settings, and the paired jackknife of the shift (the same
  seed left out of both) beside it. A number whose leave-one-out values are not all finite has
  no error (NaN): it depends on a single run. With two common seeds (two piles of an expensive
  setting) there is no jackknife: both sides' numbers are computed and compared without an
  error, and nothing counts as moved.

The figure documents of both ensembles on the common seeds are written beside the comparison, so
that the report judges the paper's claims on each (``tiltpile.report``) and says whether every
verdict is the same.

How many numbers chance moves (:func:`null_moved`, ``--null``): the runs of each seed exchanged
between the two sides, every exchange scored as the real pair is. All 2^(n - 1) distinct
exchanges when that is affordable (``exact``), else K random ones, and a one-sided p value with
its Monte-Carlo error; its decision is data: "moved" (p < ALPHA) or "no difference detected",
which is a failure to reject, not a proof of equality. Beside it the smallest shift each check
could have detected at this number of seeds (``min_detectable``, 80% power): per pile-against-pile
number (:func:`min_detectable`) and per figure number (:func:`ensemble_against_ensemble`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
from dataclasses import replace
from pathlib import Path
from statistics import NormalDist

import numpy as np
import pandas as pd

from tiltpile import ensemble as _ensemble
from tiltpile.analysis.stats import bootstrap_ci

from . import build as _build
from . import style

NAME = "same_piles"
#: relative spread below which leave-one-out values are the same number, rounded differently
#: (:func:`jackknife`): ~4500 units in the last place of a double, far below any run-to-run error
ROUNDING = 1e-12
# the figures' stems, as their notebooks are named (notebooks/<stem>.ipynb)
#: the figures' stems, in order (every figure of tiltpile.figures.build)
FIGURES = tuple(_build.STEMS.values())
# the per-seed numbers compared pile against pile (columns of preparation.per_run_table)
PER_SEED = ("theta_first_onset", "theta_first_slide", "n_onsets", "z_quiet", "n_m_quiet",
            "z_start", "theta_first_change", "phi_start", "fabric_start", "ke_quiet")
#: the per-seed angles of an event a run may not reach before its tilt ends: a run without one
#: is censored at its last angle (its event comes later, if at all), not left out
CENSORED = ("theta_first_onset", "theta_first_slide", "theta_first_change")
# a shift larger than this many combined standard errors moves a figure number
SIGMA_LIMIT = 2.0
# the fewest common seeds compared (pile against pile, the figure numbers without an error) and
# the fewest that give the figure numbers a jackknife error and chance's count (--null)
MIN_SEEDS, JACKKNIFE_SEEDS = 2, 3
# the null's decision: a p value below ALPHA says the figure numbers moved
ALPHA = 0.05
# --null auto: every distinct exchange when there are at most EXACT_LIMIT (up to 9 seeds: 2^8),
# else RANDOM_FLIPS random ones, whose Monte-Carlo error of p is sqrt(0.05 0.95 / 500) = 0.0097
# < MC_ERROR_LIMIT near p = ALPHA; --null exact is refused above EXACT_MAX exchanges (14 seeds)
EXACT_LIMIT, RANDOM_FLIPS, EXACT_MAX, MC_ERROR_LIMIT = 256, 500, 4096, 0.01
# the power at which the smallest detectable shift is given, and its normal quantiles:
# Z_POWER = z_0.8 = 0.8416, Z_DETECT = z_0.975 + z_0.8 = 2.8016
POWER = 0.8
Z_POWER = NormalDist().inv_cdf(POWER)
Z_DETECT = NormalDist().inv_cdf(1.0 - ALPHA / 2.0) + Z_POWER


# ----------------------------------------------------------------------------------------------
# the ensembles


def common_seeds(a, b) -> list[int]:
    """The seeds both ensembles hold, sorted."""
    return sorted(set(int(s) for s in a.seeds) & set(int(s) for s in b.seeds))


def subset(ens, seeds):
    """The ensemble ``ens`` restricted to ``seeds`` (tables, seeds, meta's run count and seeds);
    ValueError for a seed it does not hold."""
    seeds = [int(s) for s in seeds]
    missing = sorted(set(seeds) - set(int(s) for s in ens.seeds))
    if missing:
        raise ValueError(f"seeds {missing} are not in the ensemble {ens.data_dir} (seeds {list(ens.seeds)})")
    keep = set(seeds)
    fr = ens.frames[ens.frames["run"].isin(keep)].reset_index(drop=True)
    cl = ens.clusters[ens.clusters["run"].isin(keep)].reset_index(drop=True)
    meta = dict(ens.meta, n_runs=len(seeds), seeds=list(seeds))
    records = {s: p for s, p in ens.records.items() if s in keep}
    return replace(ens, frames=fr, clusters=cl, seeds=list(seeds), meta=meta, records=records)


# ----------------------------------------------------------------------------------------------
# a figure's numbers as its notebook computes them


def figure_documents(ens, stems=FIGURES, notebooks_dir="notebooks",
                     overrides: dict | None = None) -> dict[str, dict]:
    """{stem: JSON document} of each figure on ``ens``, as its notebook and ``make figures``
    compute it (:func:`tiltpile.figures.build.document`: the figure's parameters at their
    defaults, with ``overrides`` of those it has applied, as ``NB="-p NAME VALUE"`` would),
    without drawing. Each document is what the figure's JSON would hold (``style.save``:
    ``figure``, the ensemble's description, ``numbers``). ``notebooks_dir`` is not read (the
    notebooks compute nothing of their own); it stays for the callers that pass it."""
    from . import build

    return {stem: build.document(ens, stem, overrides) for stem in stems}


@contextlib.contextmanager
def _environ(values: dict[str, str]):
    """``os.environ`` with ``values`` set inside the block, as it was after it."""
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def worker_pool(workers: int):
    """A ProcessPoolExecutor of ``workers`` fresh interpreters ("spawn") started in the
    ensemble's ``WORKER_ENV`` (one thread of BLAS, OpenMP and numba), for :func:`documents_each`.
    One process's numpy keeps ~1.4 cores busy for no gain, and a forked worker keeps the threads
    its parent started with, so W such workers oversubscribe W cores; with one thread each, two
    workers compute a paper-scale comparison about twice as fast as one process
    (notes/performance-log.md). The caller's environment is as it was after the block."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with _environ(_ensemble.WORKER_ENV), ProcessPoolExecutor(
            workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        yield pool


def documents_each(jobs, stems=FIGURES, notebooks_dir="notebooks", workers: int = 1,
                   progress=None, evaluate=None):
    """:func:`figure_documents` of each ensemble of ``jobs``, an iterable of (progress line or
    None, ensemble), yielded in the order of ``jobs`` (``evaluate``: another module-level
    function of the same arguments and result, e.g. :func:`_memo_documents`). A generator of jobs is advanced only as
    evaluations are due, so it makes its ensembles as they are needed. With ``workers`` > 1 they
    are computed in that many processes, at most two per worker made and waiting at a time; each
    document is a function of its ensemble alone (the figures' bootstraps draw from generators of
    fixed seeds), so the documents are those of one process, bit for bit. ``progress`` is called
    with a job's line as its evaluation starts (one process) or ends (several)."""
    say = progress or (lambda line: None)
    evaluate = evaluate or figure_documents
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if workers == 1:
        for line, e in jobs:
            if line:
                say(line)
            yield evaluate(e, stems, notebooks_dir)
        return
    import collections

    with worker_pool(workers) as pool:
        waiting = collections.deque()

        def ready():
            line, fut = waiting.popleft()
            docs = fut.result()
            if line:
                say(line)
            return docs

        for line, e in jobs:
            waiting.append((line, pool.submit(evaluate, e, stems, notebooks_dir)))
            if len(waiting) >= 2 * workers:
                yield ready()
        while waiting:
            yield ready()


def document(meta: dict, stem: str, numbers: dict) -> dict:
    """The figure's JSON document as ``style.save`` writes it (:func:`style.document`: no wall
    time in its header), in JSON form (NaN as None)."""
    return json.loads(json.dumps(style.document(stem, numbers, meta)))


def scalars(numbers: dict) -> dict[str, float]:
    """The scalar numbers of a figure (int, float, bool; None as NaN), in their order; lists,
    strings and mappings are left out."""
    out = {}
    for k, v in numbers.items():
        if isinstance(v, np.generic):
            v = v.item()
        if v is None:
            out[k] = math.nan
        elif isinstance(v, (bool, int, float)):
            out[k] = float(v)
    return out


# ----------------------------------------------------------------------------------------------
# standard errors over runs


def jackknife(values_full: dict, values_loo: list[dict]) -> dict[str, float]:
    """Jackknife standard error of each key of ``values_full`` from its leave-one-run-out values
    (one dict per run left out): sqrt((n - 1) / n * sum_i (x_i - mean)^2); NaN where the full
    value is not finite or any leave-one-out value is not (the number hangs on a single run).
    Leave-one-out values that differ only by rounding (a spread below ROUNDING times their
    magnitude, as a maximum over runs summed in another order) give 0, not a spread of a few
    units in the last place: a shift divided by such an error would count as moved by 1e13
    standard errors."""
    n = len(values_loo)
    out = {}
    for k, full in values_full.items():
        x = np.array([v.get(k, math.nan) for v in values_loo], float)
        if n < 2 or not math.isfinite(full) or not np.isfinite(x).all():
            out[k] = math.nan
            continue
        se = float(math.sqrt((n - 1) / n * float(((x - x.mean()) ** 2).sum())))
        out[k] = 0.0 if se <= ROUNDING * max(abs(full), float(np.abs(x).max())) else se
    return out


def _all_scalars(docs: dict) -> dict[str, float]:
    return {f"{stem}.{k}": v for stem, doc in docs.items() for k, v in scalars(doc["numbers"]).items()}


def ensemble_against_ensemble(ref, ens, stems=FIGURES, notebooks_dir="notebooks",
                              progress=None, workers: int = 1) -> tuple[pd.DataFrame, dict, dict]:
    """Every scalar figure number of ``ens`` against ``ref`` on their common seeds (module
    docstring). Returns (table, numbers_ref, numbers) where table has one row per number:
    figure, key, ref, value, shift, se_ref, se, sigma (shift / sqrt(se_ref^2 + se^2); 0 where
    the shift is 0, NaN where an error is), se_paired (jackknife of the shift, the same seed left
    out of both), sigma_paired, moved (|sigma| > SIGMA_LIMIT), min_detectable (the smallest shift
    that moves the number with probability POWER: (SIGMA_LIMIT + z_0.8) sqrt(se_ref^2 + se^2) =
    2.84 combined errors, the measured shift taken as normal about the true one with the combined
    error as its sd and the far tail neglected; NaN without an error); and the figure documents of both
    on the common seeds ({stem: document}). ``progress``: called with a line per evaluation;
    ``workers``: processes evaluating the figures (:func:`documents_each`; the same table).
    With 2 common seeds no number has an error (NaN; the jackknife needs 3 runs)."""
    seeds = common_seeds(ref, ens)
    if len(seeds) < MIN_SEEDS:
        raise ValueError(f"the ensembles share {len(seeds)} seeds: the comparison needs "
                         f"{MIN_SEEDS} or more")
    a, b = subset(ref, seeds), subset(ens, seeds)
    jackknifed = seeds if len(seeds) >= JACKKNIFE_SEEDS else []

    def jobs():
        yield f"all {len(seeds)} seeds", a
        yield None, b
        for k, s in enumerate(jackknifed):
            rest = [t for t in seeds if t != s]
            yield f"leaving out seed {s} ({k + 1} of {len(seeds)})", subset(a, rest)
            yield None, subset(b, rest)

    docs = documents_each(jobs(), stems, notebooks_dir, workers, progress)
    na, nb = next(docs), next(docs)
    fa, fb = _all_scalars(na), _all_scalars(nb)
    loo_a, loo_b = [], []
    for _ in jackknifed:
        loo_a.append(_all_scalars(next(docs)))
        loo_b.append(_all_scalars(next(docs)))
    docs.close()
    shift_full = {k: fb[k] - fa[k] for k in fa if k in fb}
    if loo_a:
        se_a, se_b = jackknife(fa, loo_a), jackknife(fb, loo_b)
        se_d = jackknife(shift_full, [{k: lb.get(k, math.nan) - la.get(k, math.nan)
                                       for k in shift_full} for la, lb in zip(loo_a, loo_b)])
    else:
        se_a = se_b = se_d = {k: math.nan for k in fa.keys() | fb.keys()}
    rows = []
    for key, d in shift_full.items():
        stem, name = key.split(".", 1)
        comb = math.hypot(se_a[key], se_b[key])
        rows.append({"figure": stem, "key": name, "ref": fa[key], "value": fb[key], "shift": d,
                     "se_ref": se_a[key], "se": se_b[key],
                     "sigma": _in_sigma(d, comb), "se_paired": se_d[key],
                     "sigma_paired": _in_sigma(d, se_d[key])})
    t = pd.DataFrame(rows)
    t["moved"] = t["sigma"].abs() > SIGMA_LIMIT
    t["min_detectable"] = (SIGMA_LIMIT + Z_POWER) * np.hypot(t["se_ref"].to_numpy(float),
                                                             t["se"].to_numpy(float))
    return t, na, nb


def _in_sigma(shift: float, se: float) -> float:
    if shift == 0.0:
        return 0.0
    if not (math.isfinite(shift) and math.isfinite(se)) or se == 0.0:
        return math.nan
    return shift / se


# ----------------------------------------------------------------------------------------------
# pile against pile


def per_seed(ens, numbers_fig2: dict) -> pd.DataFrame:
    """Per run of ``ens`` the ``PER_SEED`` numbers (preparation.per_run_table, with Fig. 2's
    first onsets and its avalanche angle, the first large slide at ``avalanche_ke``)."""
    from .preparation import per_run_table
    onset = np.asarray([_nan(v) for v in numbers_fig2["theta_m_per_run"]], float)
    slide = np.asarray([_nan(v) for v in numbers_fig2["theta_avalanche_per_run"]], float)
    t = per_run_table(ens, onset, slide)
    t["ke_quiet"] = quiet_kinetic_energy(ens.frames, ens.seeds)
    return t[["run", *PER_SEED]]


def quiet_kinetic_energy(frames: pd.DataFrame, seeds) -> np.ndarray:
    """Per run (seeds order): the median kinetic energy per mobile grain, translational plus
    rotational (m g d), of its quiet frames (not avalanching by the lost-contact criterion, as
    ``data.per_run_quiet`` takes them); NaN for a run without one. How much the pile moves
    between events, where two engines may differ most (docs/dem.md)."""
    out = []
    for s in seeds:
        g = frames[(frames["run"] == s) & ~frames["avalanching"].astype(bool)]
        ke = (g["ke_trans"] + g["ke_rot"]).to_numpy(float)
        out.append(float(np.median(ke)) if ke.size else math.nan)
    return np.asarray(out, float)


def _nan(v) -> float:
    return math.nan if v is None else float(v)


def min_detectable(differences) -> tuple[float, float]:
    """(sd, smallest detectable mean difference) of per-seed paired differences (NaN dropped):
    sd = their standard deviation (ddof 1) and (z_0.975 + z_0.8) sd / sqrt(n) = 2.80 sd / sqrt(n),
    the true mean difference that a two-sided test at ALPHA = 0.05 on n seeds detects with power
    0.8 (normal approximation; the t test on few seeds needs a little more). NaN for fewer than
    2 finite differences."""
    d = np.asarray(differences, float)
    d = d[np.isfinite(d)]
    if d.size < 2:
        return math.nan, math.nan
    sd = float(d.std(ddof=1))
    return sd, Z_DETECT * sd / math.sqrt(d.size)


def pile_against_pile(ref, ens, fig2_ref: dict, fig2: dict, confidence: float = 0.95) -> dict:
    """Per seed of the two ensembles (the same seeds, ``subset`` to them): each ``PER_SEED``
    number of both and their difference (``ens`` - ``ref``), and per number the mean difference
    with a bootstrap interval over the seeds that have both values (``n``), the differences' sd
    and the smallest mean difference detectable on these seeds (``min_detectable``, 80% power:
    :func:`min_detectable`). fig2_ref, fig2: the Fig. 2 numbers of each ensemble on these seeds
    (of :func:`figure_documents`)."""
    ta, tb = per_seed(ref, fig2_ref), per_seed(ens, fig2)
    if list(ta["run"]) != list(tb["run"]):
        raise ValueError("pile against pile needs the same seeds in the same order")
    out = {"seeds": [int(s) for s in ta["run"]], "per_seed": {}, "difference": {}}
    end_x, end_y = tilt_ends(ref), tilt_ends(ens)
    out["tilt_end"] = {"ref": end_x.tolist(), "value": end_y.tolist()}
    for c in PER_SEED:
        x, y = ta[c].to_numpy(float), tb[c].to_numpy(float)
        d = y - x
        ci = bootstrap_ci(d, confidence=confidence)
        sd, mdd = min_detectable(d)
        out["per_seed"][c] = {"ref": x.tolist(), "value": y.tolist(), "difference": d.tolist()}
        out["difference"][c] = {"mean": ci["estimate"], "ci_low": ci["low"], "ci_high": ci["high"],
                                "n": ci["n"], "median": float(np.nanmedian(d)) if np.isfinite(d).any()
                                else math.nan, "sd": sd, "min_detectable": mdd}
        if c in CENSORED:
            cens = censored_difference(x, y, end_x, end_y, confidence)
            if cens is not None:
                out["difference"][c]["censored"] = cens
    return out


def tilt_ends(ens) -> np.ndarray:
    """Per run of ``ens`` (its seeds' order): the last angle its frames reach (deg)."""
    f = ens.frames
    return np.asarray([float(f.loc[f["run"] == s, "theta_deg"].max()) if (f["run"] == s).any()
                       else math.nan for s in ens.seeds], float)


def censored_difference(x, y, end_x, end_y, confidence: float = 0.95) -> dict | None:
    """The paired difference y - x of an event's angle with the pairs where one run has no event
    by the end of its tilt counted at their bound instead of left out: a run without it is
    censored at its last angle (``end_x``, ``end_y``), so where x has none, x >= end_x and
    y - x <= y - end_x; where y has none, y - x >= end_y - x. Returns None when no pair is
    censored; else {"n_censored", "bound": "at most" (every censored pair bounded above),
    "at least" (below) or "mixed" (both: the mean is not bounded), "mean", "ci_low", "ci_high",
    "n"}: the mean over every pair with both or one event, the censored ones at their bound, with
    its bootstrap interval; with "at most" the true mean lies at or below it, with "at least" at
    or above. Pairs where neither run has the event stay out."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ex, ey = np.asarray(end_x, float), np.asarray(end_y, float)
    up = ~np.isfinite(x) & np.isfinite(y)           # x later than its end: y - x at most y - end_x
    down = np.isfinite(x) & ~np.isfinite(y)         # y later than its end: y - x at least end_y - x
    if not (up.any() or down.any()):
        return None
    d = y - x
    d[up] = y[up] - ex[up]
    d[down] = ey[down] - x[down]
    ci = bootstrap_ci(d, confidence=confidence)
    bound = "mixed" if up.any() and down.any() else "at most" if up.any() else "at least"
    return {"n_censored": int(up.sum() + down.sum()), "bound": bound, "mean": ci["estimate"],
            "ci_low": ci["low"], "ci_high": ci["high"], "n": ci["n"]}


# ----------------------------------------------------------------------------------------------
# how many numbers move by chance: the paired sign-flip null


def mixed(a, b, flip, scratch=None):
    """Two ensembles of the seeds ``a`` and ``b`` share, with the runs of the seeds where ``flip``
    is true exchanged: the first holds b's run of such a seed, the second a's. Run files (for the
    figures' pictures) are reached through links in ``scratch``/{0,1} when the ensembles were
    loaded from run files; from records, through the records' paths."""
    import os

    seeds = common_seeds(a, b)
    if len(flip) != len(seeds):
        raise ValueError(f"{len(flip)} flips for {len(seeds)} common seeds")
    swap = {s for s, f in zip(seeds, flip) if f}
    out = []
    for k, (x, y) in enumerate(((a, b), (b, a))):
        keep_x = [s for s in seeds if s not in swap]
        take_y = [s for s in seeds if s in swap]
        fr = pd.concat([x.frames[x.frames["run"].isin(keep_x)], y.frames[y.frames["run"].isin(take_y)]])
        cl = pd.concat([x.clusters[x.clusters["run"].isin(keep_x)],
                        y.clusters[y.clusters["run"].isin(take_y)]])
        fr = fr.sort_values(["run", "frame"], kind="stable").reset_index(drop=True)
        cl = cl.sort_values(["run", "frame"], kind="stable").reset_index(drop=True)
        records = {s: (y if s in swap else x).records[s] for s in seeds
                   if s in (y if s in swap else x).records}
        data_dir = x.data_dir
        if not records and scratch is not None:
            data_dir = Path(scratch) / str(k)
            data_dir.mkdir(parents=True, exist_ok=True)
            for s in seeds:
                link = data_dir / f"run_{s:04d}.h5"
                if link.is_symlink() or link.exists():
                    link.unlink()
                os.symlink((y if s in swap else x).run_path(s).resolve(), link)
        meta = dict(x.meta, n_runs=len(seeds), seeds=list(seeds))
        out.append(replace(x, data_dir=data_dir, frames=fr, clusters=cl, seeds=list(seeds),
                           meta=meta, records=records))
    return out[0], out[1]


def null_plan(spec, n_seeds: int) -> tuple[str, int]:
    """How chance's count is drawn on ``n_seeds`` common seeds: ("exact", 2^(n - 1)) for
    ``spec`` "exact" (every distinct exchange, :func:`exact_flips`; ValueError above EXACT_MAX of
    them), ("random", K) for an integer ``spec`` K >= 1, and for "auto" the exact null when
    2^(n - 1) <= EXACT_LIMIT, else ("random", RANDOM_FLIPS). ValueError for anything else."""
    distinct = 2 ** (n_seeds - 1) if n_seeds >= 1 else 0
    if spec == "auto":
        return ("exact", distinct) if distinct <= EXACT_LIMIT else ("random", RANDOM_FLIPS)
    if spec == "exact":
        if distinct > EXACT_MAX:
            raise ValueError(f"the exact null on {n_seeds} seeds is {distinct} exchanges, more than "
                             f"{EXACT_MAX}: give a number of random ones (e.g. {RANDOM_FLIPS})")
        return "exact", distinct
    if isinstance(spec, (int, np.integer)) and not isinstance(spec, bool):
        if spec < 1:
            raise ValueError(f"flips must be at least 1, got {spec}")
        return "random", int(spec)
    raise ValueError(f"the null is 'exact', 'auto' or a number of random flips, got {spec!r}")


def exact_flips(n: int) -> list[np.ndarray]:
    """Every distinct exchange of the runs of ``n`` seeds: the 2^(n - 1) that leave the first
    seed's runs in place, in binary order of the others (the first exchanges nothing: the real
    pair). Exchanging the complement of a set of seeds gives the same two mixed ensembles in the
    other order (:func:`mixed`: the first of one is the second of the other, run for run and
    record for record; the figures read no other part of an ensemble), so every shift changes
    sign only and the same numbers move: the 2^n exchanges are these 2^(n - 1) twice over, and
    their counts have the distribution of all 2^n."""
    if n < 1:
        raise ValueError(f"no exchange of {n} seeds")
    rest = (np.arange(2 ** (n - 1))[:, None] >> np.arange(n - 1)) & 1
    return [np.concatenate([[False], row.astype(bool)]) for row in rest]


def random_flips(n: int, k: int, seed: int = 0) -> list[np.ndarray]:
    """``k`` random exchanges of the runs of ``n`` seeds, each seed's exchanged with probability
    1/2 (a numpy generator of ``seed``; the first k of more are the same k)."""
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 2, n).astype(bool) for _ in range(k)]


def canonical(flip) -> tuple[bool, ...]:
    """The exchange, or its complement, that leaves the first seed in place: both count alike
    (:func:`exact_flips`)."""
    f = np.asarray(flip, bool)
    return tuple(bool(v) for v in (~f if f[0] else f))


def mc_error(p: float, flips: int) -> float:
    """Monte-Carlo standard error of a p value estimated from ``flips`` random exchanges:
    sqrt(p (1 - p) / flips) (0.0097 at p = 0.05 and 500 flips)."""
    return math.sqrt(p * (1.0 - p) / flips)


def decide(p: float, error: float) -> dict:
    """The null's decision as data: ``decision`` "moved" when p < ALPHA, else "no difference
    detected" (a failure to reject: the shifts the check could have seen are ``min_detectable``
    beside each number, not a proof that there are none); ``decision_firm``: whether p lies more
    than two Monte-Carlo errors from ALPHA (always, for the exact null)."""
    return {"alpha": ALPHA, "decision": "moved" if p < ALPHA else "no difference detected",
            "decision_firm": bool(abs(p - ALPHA) > 2.0 * error)}


def moved_count(numbers_a: dict, numbers_b: dict, comb: dict) -> int:
    """How many of the numbers ``comb`` ({figure.key: combined error}) with a finite error move
    by more than SIGMA_LIMIT of it between the scalars ``numbers_a`` and ``numbers_b``
    (:func:`_all_scalars` of each side's documents)."""
    n = 0
    for key, c in comb.items():
        if key in numbers_a and key in numbers_b and math.isfinite(c):
            sig = _in_sigma(numbers_b[key] - numbers_a[key], c)
            n += bool(math.isfinite(sig) and abs(sig) > SIGMA_LIMIT)
    return n


# the figures' power-law fits met before, while the null evaluates (:func:`fit_memo`)
_FIT_CACHE: dict | None = None
FIT_CACHE_MAX = 100_000   # entries (~1 kB each); past it, nothing more is kept


def _memo_fit(fit):
    def memo(sizes, *args, **kwargs):
        a = np.ascontiguousarray(np.asarray(sizes))
        key = (hashlib.blake2b(a.tobytes(), digest_size=20).digest(), a.dtype.str, a.shape,
               args, tuple(sorted(kwargs.items())))
        hit = _FIT_CACHE.get(key)
        if hit is None:
            hit = fit(sizes, *args, **kwargs)
            if len(_FIT_CACHE) < FIT_CACHE_MAX:
                _FIT_CACHE[key] = hit
        return dict(hit)
    memo.real = fit
    return memo


def _install_fit_memo() -> bool:
    """Fig. 5's fits (``fig5._fit``) memoized in this process; False if they already were."""
    global _FIT_CACHE
    from . import fig5
    if _FIT_CACHE is not None:
        return False
    _FIT_CACHE = {}
    fig5._fit = _memo_fit(fig5._fit)
    return True


def _remove_fit_memo() -> None:
    global _FIT_CACHE
    from . import fig5
    fig5._fit = getattr(fig5._fit, "real", fig5._fit)
    _FIT_CACHE = None


@contextlib.contextmanager
def fit_memo():
    """Inside the block, Fig. 5's fits of a set of cluster sizes (``fig5._fit``, a function of
    the sizes, in their order, and the fit's settings alone) are computed once per set and
    returned again when the same set comes back, as it does across exchanges: the interval of the
    pooled delta refits 199 resamples of whole runs, and a resample's sizes are the same whenever
    two exchanges agree on the ~5 of 8 seeds it draws: over all 128 exchanges of 8 seeds ~80% of
    these refits come back (at 16 seeds, ~10 of 16 drawn, 500 random exchanges: ~13%). The
    documents are the same, bit for bit (tests/figures/test_same_piles.py). Nested blocks share
    the outer one's memo."""
    mine = _install_fit_memo()
    try:
        yield
    finally:
        if mine:
            _remove_fit_memo()


def _memo_documents(ens, stems=FIGURES, notebooks_dir="notebooks") -> dict:
    """:func:`figure_documents` with Fig. 5's fits memoized for the rest of the process's life:
    what the null's worker processes evaluate (each pool is the null's own)."""
    _install_fit_memo()
    return figure_documents(ens, stems, notebooks_dir)


def null_moved(ref, ens, table: pd.DataFrame, flips, seed: int = 0, stems=FIGURES,
               notebooks_dir="notebooks", scratch=None, progress=None, workers: int = 1) -> dict:
    """The number of figure numbers that move by more than SIGMA_LIMIT when nothing but chance
    separates the two ensembles: exchanges of the two runs of some seeds, each scored as
    :func:`ensemble_against_ensemble` scores the real pair, its shift over the real pair's
    combined standard error (``table``'s se_ref, se), so that each exchange costs two
    evaluations of the figures instead of 2 (N + 1). Under the hypothesis that the two settings
    give the same piles' statistics the runs of a seed are exchangeable, and the observed count is
    a draw of this distribution.

    ``flips`` (:func:`null_plan`): "exact", every distinct exchange (2^(n - 1) of them: an
    exchange and its complement count alike, :func:`exact_flips`), p = #(count >= observed) /
    2^(n - 1), the real pair among them, with no Monte-Carlo error; an integer K, K random
    exchanges (:func:`random_flips` of ``seed``), p = (1 + #(count >= observed)) / (1 + K), with
    Monte-Carlo error sqrt(p (1 - p) / K) (:func:`mc_error`; below 0.01 near p = 0.05 from K =
    500 on); "auto", exact up to EXACT_LIMIT exchanges, else RANDOM_FLIPS random ones. Each
    distinct exchange is evaluated once (random draws that repeat one, or its complement, reuse
    its count), Fig. 5's fits are memoized across exchanges (:func:`fit_memo`), and ``workers``
    processes evaluate the figures (:func:`documents_each`): the same counts in every case. Each
    exchange's run-file links (:func:`mixed`) go to its own folder of ``scratch``.

    Returns method ("exact" or "random"), flips (the exchanges counted), evaluated (the distinct
    ones evaluated), seed (None for exact), counts (one per exchange), their median and 95th
    percentile, observed, p_value, mc_error, and the decision as data (:func:`decide`: alpha,
    decision, decision_firm)."""
    seeds = common_seeds(ref, ens)
    method, k = null_plan(flips, len(seeds))
    if len(seeds) < JACKKNIFE_SEEDS:
        raise ValueError(f"the ensembles share {len(seeds)} seeds: what chance moves needs "
                         f"{JACKKNIFE_SEEDS} or more (an error to move by)")
    a, b = subset(ref, seeds), subset(ens, seeds)
    comb = {f"{r['figure']}.{r['key']}": math.hypot(r["se_ref"], r["se"])
            for r in table.to_dict("records")}
    pairs = exact_flips(len(seeds)) if method == "exact" else random_flips(len(seeds), k, seed)
    keys = [canonical(f) for f in pairs]
    distinct = list(dict.fromkeys(keys))

    def jobs():
        for i, key in enumerate(distinct):
            flip = np.array(key, bool)
            x, y = mixed(a, b, flip, None if scratch is None else Path(scratch) / f"flip{i}")
            yield (f"null: flip {i + 1} of {len(distinct)} ({int(flip.sum())} of {len(seeds)} "
                   "seeds exchanged)"), x
            yield None, y

    if workers == 1:
        with fit_memo():
            docs = documents_each(jobs(), stems, notebooks_dir, 1, progress)
            count = {key: moved_count(_all_scalars(next(docs)), _all_scalars(next(docs)), comb)
                     for key in distinct}
            docs.close()
    else:
        docs = documents_each(jobs(), stems, notebooks_dir, workers, progress,
                              evaluate=_memo_documents)
        count = {key: moved_count(_all_scalars(next(docs)), _all_scalars(next(docs)), comb)
                 for key in distinct}
        docs.close()
    counts = [count[key] for key in keys]
    observed = int(table["moved"].sum())
    c = np.array(counts)
    if method == "exact":
        p, err = float((c >= observed).sum() / c.size), 0.0
    else:
        p = float((1 + (c >= observed).sum()) / (1 + c.size))
        err = mc_error(p, c.size)
    return {"method": method, "flips": len(pairs), "evaluated": len(distinct),
            "seed": seed if method == "random" else None, "counts": counts,
            "median": float(np.median(c)), "p95": float(np.percentile(c, 95)),
            "observed": observed, "p_value": p, "mc_error": err, **decide(p, err)}


# ----------------------------------------------------------------------------------------------
# the study


def study(ref, ens, ref_label: str, label: str, notebooks_dir="notebooks", progress=None,
          null_flips=0, scratch=None, workers: int = 1) -> dict:
    """The whole comparison (module docstring) as one JSON-able document: the labels, the
    common seeds, ``pile_against_pile``, the ensemble table as rows, the count of numbers moved by
    more than SIGMA_LIMIT, with ``null_flips`` ("exact", "auto" or a number K > 0; 0 or None:
    none) the counts chance gives, p and its decision (:func:`null_moved`, under ``null``), and
    ``documents``: {label: {stem: figure document}} of both on the common seeds (for the report's
    judges). ``workers``: processes evaluating the figures (the same document)."""
    table, na, nb = ensemble_against_ensemble(ref, ens, FIGURES, notebooks_dir, progress, workers)
    null = (null_moved(ref, ens, table, null_flips, notebooks_dir=notebooks_dir, scratch=scratch,
                       progress=progress, workers=workers) if null_flips else None)
    seeds = common_seeds(ref, ens)
    a, b = subset(ref, seeds), subset(ens, seeds)
    fig2 = "fig2_avalanche_criterion"
    pp = pile_against_pile(a, b, na[fig2]["numbers"], nb[fig2]["numbers"])
    finite = table[np.isfinite(table["sigma"])]
    return {"study": NAME, "ref": ref_label, "label": label, "seeds": seeds,
            "sigma_limit": SIGMA_LIMIT,
            "n_numbers": int(len(table)), "n_with_error": int(len(finite)),
            "n_moved": int(table["moved"].sum()),
            "moved": table.loc[table["moved"], ["figure", "key"]].to_dict("records"),
            "pile_against_pile": pp,
            "null": null,
            "numbers": table.to_dict("records"),
            "documents": {ref_label: na, label: nb}}


def write_study(doc: dict, out_dir) -> Path:
    """Write ``out_dir/same_piles.json`` (NaN as null) and, per side, the figure documents as
    ``out_dir/<label>/<stem>.json`` (what ``tiltpile report`` reads). Returns the study's path."""
    out = Path(out_dir)
    for label, docs in doc["documents"].items():
        d = out / label
        d.mkdir(parents=True, exist_ok=True)
        for stem, fig_doc in docs.items():
            style.write_json(d / f"{stem}.json", fig_doc)
    body = {k: v for k, v in doc.items() if k != "documents"}
    path = out / f"{NAME}.json"
    style.write_json(path, style.jsonable(body))
    return path
