"""Per-run observables, cached beside the runs; the tables every figure starts from.

``run_observables(run)`` (:mod:`tiltpile.analysis.tables`, where every column and every analysis
parameter is declared with its meaning) turns one run into two DataFrames: one row per stored
frame, and one row per critical cluster per frame.

``compute_observables(DIR)`` does this for every ``DIR/run_*.h5`` whose cache
``DIR/observables/run_*.npz`` (``DIR/observables/params-<digest>/run_*.npz`` at other analysis
parameters than the defaults, so that each parameter set keeps its own) is missing or stale (run file size or mtime changed, other
analysis parameters, or a column added or computed by another version of its producer: the
per-column codes of :func:`tiltpile.analysis.tables.column_code`), in parallel processes, with a progress bar: where
the run files exist, a new column is computed by the first load after it is declared. ``load_observables(DIR)`` returns the two tables for the
whole ensemble.

Cache format: one ``.npz`` per run (numpy only: no pyarrow / pytables here) holding each column
as ``frames__<col>`` / ``clusters__<col>`` plus ``meta`` (JSON: source size, mtime, parameters,
``columns``: the code of every column); written to a temporary name, synced and renamed
(:func:`tiltpile.outputs.replaced_whole`: a cache is replaced whole or not at all). One
computation at a time per cache directory: ``compute_observables`` holds its
``.observables.lock`` (:func:`tiltpile.outputs.output_lock`) while it computes, and a second one
waits for it, saying so in one line on stderr, then computes only what is still missing.
"""

from __future__ import annotations

import json
import os
import time
import warnings
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile.outputs import output_lock, replaced_whole

from . import avalanche as _av
from . import checks as _ck
from .legacy_codes import recorded_column_code
from .tables import (CLUSTER_COLUMNS, CLUSTER_DOCS, DEFAULT_PARAMS, FRAME_COLUMNS,  # noqa: F401
                     FRAME_DOCS, RUN_TABLE_PARAMS, _params, failure_between, frame_contacts,
                     frame_observables, lost_between, run_observables, column_code)

CACHE_DIRNAME = "observables"
LOCK = ".observables.lock"  # in the cache directory, held while its caches are computed


# ----------------------------------------------------------------------------------------------
# cache


def _cache_path(run_path: Path, params: dict | None = None) -> Path:
    """The run's cache: ``observables/<run>.npz`` at the default table parameters, and
    ``observables/params-<digest>/<run>.npz`` at others (a digest of those that differ), so that
    the tables of several parameter sets stay cached side by side."""
    base = run_path.parent / CACHE_DIRNAME
    if params is not None:
        other = {k: v for k, v in table_params(**params).items()
                 if json.dumps(v) != json.dumps(DEFAULT_PARAMS[k])}
        if other:
            import hashlib
            key = hashlib.sha256(json.dumps(other, sort_keys=True).encode()).hexdigest()[:12]
            base = base / f"params-{key}"
    return base / (run_path.stem + ".npz")


def table_params(**params) -> dict:
    """The analysis parameters the per-frame and per-cluster tables depend on (DEFAULT_PARAMS
    with ``params`` applied and checked, without the per-run table's RUN_TABLE_PARAMS)."""
    return {k: v for k, v in _params(params).items() if k not in RUN_TABLE_PARAMS}


def _source_meta(run_path: Path, params: dict) -> dict:
    st = run_path.stat()
    cached = {k: v for k, v in params.items() if k not in RUN_TABLE_PARAMS}
    return {"source": run_path.name, "size": st.st_size, "mtime_ns": st.st_mtime_ns,
            "params": cached, "columns": column_code()}


def _read_meta(cache: Path) -> dict | None:
    try:
        with np.load(cache, allow_pickle=False) as z:
            return json.loads(str(z["meta"]))
    except (OSError, KeyError, ValueError):
        return None


def _is_fresh(run_path: Path, params: dict) -> bool:
    meta = _read_meta(_cache_path(run_path, params))
    if meta is None:
        return False
    if isinstance(meta.get("columns"), dict):    # codes a value-keeping change superseded
        meta["columns"] = recorded_column_code({"column_code": meta["columns"]})
    return meta == json.loads(json.dumps(_source_meta(run_path, params)))


def _write_cache(cache: Path, meta: dict, frames: pd.DataFrame, clusters: pd.DataFrame) -> None:
    cache.parent.mkdir(parents=True, exist_ok=True)
    arrays = {"meta": np.array(json.dumps(meta))}
    for prefix, df in (("frames", frames), ("clusters", clusters)):
        arrays[f"{prefix}__columns"] = np.array(list(df.columns))
        for c in df.columns:
            arrays[f"{prefix}__{c}"] = df[c].to_numpy()
    with replaced_whole(cache) as tmp, open(tmp, "wb") as fh:  # a full disk, a kill: no temporary left
        np.savez_compressed(fh, **arrays)


def _read_cache(cache: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    with np.load(cache, allow_pickle=False) as z:
        out = []
        for prefix in ("frames", "clusters"):
            cols = [str(c) for c in z[f"{prefix}__columns"]]
            out.append(pd.DataFrame({c: z[f"{prefix}__{c}"] for c in cols}, columns=cols))
    return out[0], out[1]


def _compute_one(run_path: str, params: dict) -> tuple[str, float]:
    """Worker: compute one run's observables and write its cache. Returns (path, seconds)."""
    t0 = time.perf_counter()
    path = Path(run_path)
    meta = _source_meta(path, params)
    frames, clusters = run_observables(path, **params)
    if _source_meta(path, params) != meta:
        raise RuntimeError(f"{path} changed while its observables were computed; run again")
    _write_cache(_cache_path(path, params), meta, frames, clusters)
    return run_path, time.perf_counter() - t0


def _check_dir(fn: str, ensemble_dir) -> None:
    if not isinstance(ensemble_dir, (str, os.PathLike)):
        _ck.fail(fn, "ensemble_dir", "be a directory's path", _ck.kind_of(ensemble_dir), TypeError)


def run_files(ensemble_dir) -> list[Path]:
    """The run files ``run_*.h5`` of an ensemble directory, sorted by name."""
    _check_dir("run_files", ensemble_dir)
    d = Path(ensemble_dir)
    if not d.is_dir():
        raise FileNotFoundError(f"ensemble directory {d} does not exist")
    return sorted(d.glob("run_*.h5"))


def compute_observables(ensemble_dir, workers: int | None = None, progress: bool = True,
                        force: bool = False, **params) -> pd.DataFrame:
    """Compute and cache the observables of every run of an ensemble that needs it.

    Incremental: a run is (re)computed when its cache ``DIR/observables/<run>.npz`` is missing,
    or when the run file's size or mtime, the analysis parameters or a column's code changed (or
    a column was added)
    (``force=True`` recomputes everything). Runs are processed in parallel by ``workers``
    processes (default: number of CPUs, at most the number of pending runs; 1 = in this
    process), with a tqdm progress bar when ``progress``. While it computes it holds the cache
    directory's lock (``LOCK``); another computation holding it is waited for (one line on
    stderr), and the runs it computed are not computed again (but with ``force``).

    Returns a DataFrame with one row per run file: run_file, cache, status ("cached" or
    "computed"), seconds.
    """
    _check_dir("compute_observables", ensemble_dir)
    p = _params(params)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ValueError(f"workers must be a positive integer or None, got {workers!r}")
    files = run_files(ensemble_dir)
    if files:  # one configuration per directory (store.MixedConfigError names the odd files)
        from tiltpile.store import common_config
        common_config(files)
    pending = [f for f in files if force or not _is_fresh(f, p)]
    status = {str(f): ("cached", 0.0) for f in files}
    if pending:
        # one computation at a time per cache: another one's is waited for, and what it
        # computed is not computed again
        with output_lock(_cache_path(files[0], p).parent, LOCK, "an observables computation",
                         wait=True):
            if not force:
                pending = [f for f in pending if not _is_fresh(f, p)]
            _compute(pending, p, workers, progress, status)
    return pd.DataFrame([{"run_file": f, "cache": str(_cache_path(Path(f), p)), "status": s,
                          "seconds": t}
                         for f, (s, t) in status.items()])


def _compute(pending: list[Path], p: dict, workers: int | None, progress: bool, status: dict) -> None:
    """Compute and cache the observables of the ``pending`` run files (``workers`` processes),
    entering each one's (``"computed"``, seconds) in ``status``."""
    if not pending:
        return
    nw = workers if workers is not None else (os.cpu_count() or 1)
    nw = max(1, min(int(nw), len(pending)))
    bar = None
    if progress:
        from tqdm.auto import tqdm
        bar = tqdm(total=len(pending), desc="observables", unit="run")
    try:
        if nw == 1:
            for f in pending:
                path, sec = _compute_one(str(f), p)
                status[path] = ("computed", sec)
                if bar is not None:
                    bar.update(1)
        else:
            with ProcessPoolExecutor(max_workers=nw, mp_context=get_context("spawn")) as ex:
                futs = [ex.submit(_compute_one, str(f), p) for f in pending]
                for fut in as_completed(futs):
                    path, sec = fut.result()
                    status[path] = ("computed", sec)
                    if bar is not None:
                        bar.update(1)
    finally:
        if bar is not None:
            bar.close()


def load_observables(ensemble_dir, compute_missing: bool = True, workers: int | None = None,
                     progress: bool = False, **params) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The ensemble's per-frame and per-cluster tables (module docstring for the columns).

    Reads the caches of every ``run_*.h5`` in ``ensemble_dir``. Missing or stale caches are
    computed first when ``compute_missing`` (via :func:`compute_observables`), else a
    FileNotFoundError names them. Returns (frames, clusters) sorted by run and frame.
    """
    _check_dir("load_observables", ensemble_dir)
    p = _params(params)
    files = run_files(ensemble_dir)
    if not files:
        raise FileNotFoundError(f"no run_*.h5 files in {ensemble_dir}")
    stale = [f for f in files if not _is_fresh(f, p)]
    if stale:
        if not compute_missing:
            raise FileNotFoundError(
                f"observables missing or stale for {len(stale)} run(s) (e.g. {stale[0].name}); "
                f"run `tiltpile observables {ensemble_dir}` first")
        compute_observables(ensemble_dir, workers=workers, progress=progress, **params)
    fr, cl = zip(*(_read_cache(_cache_path(f, p)) for f in files))
    frames = pd.concat(fr, ignore_index=True).sort_values(["run", "frame"], kind="stable")
    clusters = pd.concat(cl, ignore_index=True).sort_values(["run", "frame", "cluster"], kind="stable")
    if frames[["run", "frame"]].duplicated().any():
        warnings.warn("several run files share a run id (seed); rows of the same run id mix",
                      RuntimeWarning, stacklevel=2)
    return frames.reset_index(drop=True), clusters.reset_index(drop=True)


def load_run_observables(run_path, compute_missing: bool = True,
                         **params) -> tuple[pd.DataFrame, pd.DataFrame]:
    """One run's per-frame and per-cluster tables, as :func:`load_observables` gives its rows of
    the ensemble: from the run's cache, computed first (in this process) if missing or stale
    and ``compute_missing``, else FileNotFoundError."""
    p = _params(params)
    path = Path(run_path)
    if not _is_fresh(path, p):
        if not compute_missing:
            raise FileNotFoundError(f"observables missing or stale for {path.name}; run "
                                    f"`tiltpile observables {path.parent}` first")
        _compute_one(str(path), p)
    frames, clusters = _read_cache(_cache_path(path, p))
    frames = frames.sort_values(["run", "frame"], kind="stable")
    clusters = clusters.sort_values(["run", "frame", "cluster"], kind="stable")
    return frames.reset_index(drop=True), clusters.reset_index(drop=True)


def run_table(frames: pd.DataFrame, **params) -> pd.DataFrame:
    """Per run: the first onset by the lost-contact cutoff and the first large slide.

    frames: the ensemble's per-frame table (:func:`load_observables`, same params). params:
    overrides of DEFAULT_PARAMS; ``slide_ke`` (None: the Fig. 2a threshold of these frames,
    :func:`tiltpile.analysis.stats.ke_threshold` on ke_trans) and ``slide_sustain_deg`` set the
    slide (:func:`tiltpile.analysis.avalanche.first_slide`). Returns
    :func:`tiltpile.analysis.avalanche.run_onsets` plus the columns slide_ke and
    slide_sustain_deg (the values used).
    """
    from . import stats as _st
    p = _params(params)
    _ck.table("run_table", "frames", frames,
              ("run", "frame", "theta_deg", "onset", "ke_trans")
              + (("avalanching",) if p["slide_ke"] is None else ()))
    thr = p["slide_ke"]
    if thr is None:
        thr = _st.ke_threshold(frames, "ke_trans")[0]["threshold"]
    out = _av.run_onsets(frames, float(thr), float(p["slide_sustain_deg"]), "ke_trans")
    out["slide_ke"] = float(thr)
    out["slide_sustain_deg"] = float(p["slide_sustain_deg"])
    return out
