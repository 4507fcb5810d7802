"""Per-run observables, cached beside the runs; the tables every figure starts from.

``run_observables(run)`` turns one run (a path, or a reader from :func:`tiltpile.store.open_run`)
into two DataFrames:

per frame (one row per stored frame k)
    run, frame, step, time, theta_deg, iterations, residual,
    n_mobile, n_bulk, n_rattlers, z, n_m, dz_gen            bulk, rattlers removed (contacts.py)
    z_all, n_m_all, dz_gen_all                              all mobile grains, rattlers removed
    z_rest, n_rest                                          bulk non-rattlers in no cluster
    n_active, n_mobilized                                   active / mobilized contacts of the frame
                                                            with at least one mobile grain (walls
                                                            and fixed grains included)
    ke_trans, ke_rot                                        kinetic energy per mobile grain
    n_lost, lost_fraction, n_failing, n_failing_in_cluster, failing_in_cluster_fraction
        contacts active at k and not at k + 1 (forward; NaN/-1 at the last frame); failing =
        mobile grains at an end of a lost contact; "in cluster" = in a critical cluster at frame k
    largest_cluster, n_clusters, n_in_clusters, cluster_fraction (= n_in_clusters / n_mobile)
    avalanching, onset, period, theta_m, theta_to_onset     avalanche.py, cutoff 2% by default
    mean_displacement, max_displacement                     mobile grains, since the period's start

per cluster (one row per critical cluster per frame)
    run, frame, theta_deg, avalanching, theta_to_onset, cluster, size, z, n_m, dz,
    orientation_deg, phi_deg, rg_long, rg_short, x_com, y_com   (clusters.py)
    n_unstable   grains of the cluster with z_i - m_i / 2 < 3/2 (single-grain criterion)
    speed_max    largest speed of a grain of the cluster (sqrt(g d))

``compute_observables(DIR)`` does this for every ``DIR/run_*.h5`` whose cache
``DIR/observables/run_*.npz`` is missing or stale (run file size or mtime changed, or other
analysis parameters, or a new ANALYSIS_VERSION), in parallel processes, with a progress bar.
``load_observables(DIR)`` returns the two tables for the whole ensemble.

Cache format: one ``.npz`` per run (numpy only: no pyarrow / pytables here) holding each column
as ``frames__<col>`` / ``clusters__<col>`` plus ``meta`` (JSON: source size, mtime, parameters,
version); written to a temporary name and renamed.
"""

from __future__ import annotations

import json
import os
import re
import time
import warnings
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd

from . import avalanche as _av
from . import clusters as _cl
from . import contacts as _ct

ANALYSIS_VERSION = 2   # 2: cluster columns n_unstable, speed_max
CACHE_DIRNAME = "observables"

DEFAULT_PARAMS = {
    "cutoff": 0.02,          # avalanche cutoff on the lost fraction
    "eps": None,             # None: mobilized = sliding status; else |f_t| >= mu f_n (1 - eps)
    "link": "contacts",      # cluster links: "contacts" | "mobilized"
    "cluster_region": "mobile",  # grains that may form clusters: "mobile" | "bulk"
    "min_contacts": 2,       # rattler threshold
    "ray_spacing": 0.1,      # top-layer ray spacing (d)
    "touch_tol": 0.05,       # bottom-layer touching tolerance (d)
    "merge_gap": 0,          # avalanche merging of short quiet gaps (frames)
    "lost_gap": None,        # None: a contact is lost when its f_n drops to 0 (force definition);
                             # a gap g (d): only if it has also opened by more than g (geometric)
    # first large slide of a run (run_table; avalanche.first_slide), not part of the cached tables:
    "slide_ke": None,        # KE per grain (m g d) above which a frame flows; None: the ensemble's
                             # Fig. 2a threshold (stats.ke_threshold)
    "slide_sustain_deg": 0.5,  # least tilt span of consecutive flowing frames that is a slide
}
# parameters of the per-run table only: they do not enter the per-frame cache or its freshness
RUN_TABLE_PARAMS = ("slide_ke", "slide_sustain_deg")

FRAME_COLUMNS = [
    "run", "frame", "step", "time", "theta_deg", "iterations", "residual",
    "n_mobile", "n_bulk", "n_rattlers", "z", "n_m", "dz_gen", "z_all", "n_m_all", "dz_gen_all",
    "z_rest", "n_rest", "n_active", "n_mobilized", "ke_trans", "ke_rot",
    "n_lost", "lost_fraction", "n_failing", "n_failing_in_cluster", "failing_in_cluster_fraction",
    "largest_cluster", "n_clusters", "n_in_clusters", "cluster_fraction",
    "avalanching", "onset", "period", "theta_m", "theta_to_onset",
    "mean_displacement", "max_displacement",
]
CLUSTER_COLUMNS = [
    "run", "frame", "theta_deg", "avalanching", "theta_to_onset", "cluster", "size", "z", "n_m",
    "dz", "orientation_deg", "phi_deg", "rg_long", "rg_short", "x_com", "y_com",
    "n_unstable", "speed_max",
]


def _params(overrides: dict) -> dict:
    unknown = set(overrides) - set(DEFAULT_PARAMS)
    if unknown:
        raise TypeError(f"unknown analysis parameter(s) {sorted(unknown)}; "
                        f"allowed: {sorted(DEFAULT_PARAMS)}")
    p = dict(DEFAULT_PARAMS, **overrides)
    if p["link"] not in ("contacts", "mobilized"):
        raise ValueError(f"link must be 'contacts' or 'mobilized', got {p['link']!r}")
    if p["cluster_region"] not in ("mobile", "bulk"):
        raise ValueError(f"cluster_region must be 'mobile' or 'bulk', got {p['cluster_region']!r}")
    if not 0.0 < p["cutoff"] < 1.0:
        raise ValueError(f"cutoff must be in (0, 1), got {p['cutoff']}")
    if p["lost_gap"] is not None and not p["lost_gap"] >= 0.0:
        raise ValueError(f"lost_gap must be None or >= 0 (d), got {p['lost_gap']}")
    if p["slide_ke"] is not None and not p["slide_ke"] > 0.0:
        raise ValueError(f"slide_ke must be None or > 0 (m g d per grain), got {p['slide_ke']}")
    if not p["slide_sustain_deg"] >= 0.0:
        raise ValueError(f"slide_sustain_deg must be >= 0 (deg), got {p['slide_sustain_deg']}")
    return p


def _open_run(path):
    """Open a run file with the store's reader (the only module that knows the HDF5 layout)."""
    from tiltpile.store import open_run
    return open_run(path)


def _run_id(run, path) -> int:
    seed = getattr(run, "seed", None)
    if seed is not None:
        return int(seed)
    m = re.search(r"(\d+)", Path(path).stem) if path is not None else None
    if m is None:
        raise ValueError("cannot tell the run id: the run has no seed and its file name no number")
    return int(m.group(1))


def frame_contacts(radius, fixed, box_length, position, pair, force, status, mu=0.5,
                   mu_wall=None, eps=None, link="contacts", cluster_region="mobile",
                   ray_spacing=0.1, touch_tol=0.05) -> dict:
    """The contacts of one frame as every observable sees them (also the pile pictures).

    Contacts without a mobile grain (fixed-fixed, fixed-wall) carry no information and are
    dropped; active = f_n > 0; mobilized by :func:`~tiltpile.analysis.contacts.mobilized_mask`
    (sliding flag, or the threshold ``eps`` with mu / mu_wall); bulk grains by
    :func:`~tiltpile.analysis.contacts.bulk_mask`; critical clusters over mobile (or bulk) grains.
    Returns dict pair, force, status (the kept contacts), active, mobilized (per kept contact),
    bulk (N,) bool and labels (N,) cluster labels (-1: none).
    """
    fixed = np.asarray(fixed, dtype=bool)
    n = fixed.size
    mobile = ~fixed
    pair = np.asarray(pair).reshape(-1, 2)
    force = np.asarray(force, dtype=float).reshape(-1, 2)
    jj = np.maximum(pair[:, 1], 0)
    moving = mobile[pair[:, 0]] | ((pair[:, 1] >= 0) & mobile[jj])
    pair, force = pair[moving], force[moving]
    status = None if status is None else np.asarray(status)[moving]
    active = _ct.active_mask(force)
    mu_c = mu if mu_wall is None else np.where(pair[:, 1] < 0, mu_wall, mu)
    mobil = _ct.mobilized_mask(force, status, mu_c, eps)
    bulk = _ct.bulk_mask(position, radius, fixed, pair, box_length, ray_spacing, touch_tol)
    include = bulk if cluster_region == "bulk" else mobile
    labels = _cl.critical_clusters(n, pair, active, mobil, include, link)
    return {"pair": pair, "force": force, "status": status, "active": active,
            "mobilized": mobil, "bulk": bulk, "labels": labels}


def frame_observables(radius, fixed, box_length, position, velocity, omega, pair, force, status,
                      theta_deg, mu=0.5, mu_wall=None, eps=None, link="contacts",
                      cluster_region="mobile", min_contacts=2, ray_spacing=0.1,
                      touch_tol=0.05) -> tuple[dict, pd.DataFrame, dict]:
    """Observables of one frame (arrays in, scalars and a cluster table out).

    radius (N,), fixed (N,) bool, box_length L, position (N, 2), velocity (N, 2), omega (N,),
    pair (C, 2), force (C, 2) [f_n, f_t], status (C,), theta_deg; mu / mu_wall friction of grain
    and wall contacts (only used with the threshold criterion eps).

    Contacts without a mobile grain (fixed-fixed, fixed-wall) are dropped first.

    Returns (row, clusters, keep): row a dict of per-frame scalars (bulk z, n_m, dz_gen, ...),
    clusters the :func:`tiltpile.analysis.clusters.cluster_table` of the frame, and keep a dict
    of arrays needed to compare with the next frame (pair, active, labels, position).
    """
    fixed = np.asarray(fixed, dtype=bool)
    n = fixed.size
    mobile = ~fixed
    fc = frame_contacts(radius, fixed, box_length, position, pair, force, status, mu=mu,
                        mu_wall=mu_wall, eps=eps, link=link, cluster_region=cluster_region,
                        ray_spacing=ray_spacing, touch_tol=touch_tol)
    pair, active, mobil, bulk, labels = (fc["pair"], fc["active"], fc["mobilized"], fc["bulk"],
                                         fc["labels"])
    bc = _ct.bulk_coordination(pair, active, mobil, bulk, fixed, min_contacts)
    z_all, n_m_all, _ = _ct.coordination(bc["z_i"], bc["m_i"], mobile & ~bc["rattler"])
    z_full = _ct.contact_counts(n, pair, active)
    m_full = _ct.contact_counts(n, pair, mobil)
    ctab = _cl.cluster_table(labels, position, z_full, m_full, theta_deg)
    # grains failing the single-grain criterion z_i - m_i / 2 >= (d + 1) / 2 (paper, Fig. 6), and
    # the fastest grain: a cluster holding a grain that cannot be at rest (docs/figures.md, Fig. 6)
    inc = labels >= 0
    unstable = inc & (z_full - m_full / 2.0 < 1.5 - 1e-9)
    speed = np.hypot(*np.asarray(velocity, dtype=float).reshape(-1, 2).T)
    k = len(ctab)
    ctab["n_unstable"] = np.bincount(labels[unstable], minlength=k)[:k].astype(np.int64)
    vmax = np.zeros(k)
    if k:
        np.maximum.at(vmax, labels[inc], speed[inc])
    ctab["speed_max"] = vmax
    rest = bulk & ~bc["rattler"] & (labels < 0)
    z_rest, _, n_rest = _ct.coordination(bc["z_i"], bc["m_i"], rest)
    e_t, e_r = _ct.kinetic_energy(radius, velocity, omega)
    nmob = int(mobile.sum())
    sizes = ctab["size"].to_numpy()
    row = {
        "n_mobile": nmob, "n_bulk": bc["n"], "n_rattlers": bc["n_rattlers"],
        "z": bc["z"], "n_m": bc["n_m"], "dz_gen": bc["dz_gen"],
        "z_all": z_all, "n_m_all": n_m_all, "dz_gen_all": float(_ct.dz_gen(z_all, n_m_all)),
        "z_rest": z_rest, "n_rest": n_rest,
        "n_active": int(active.sum()), "n_mobilized": int(mobil.sum()),
        "ke_trans": float(e_t[mobile].mean()) if nmob else np.nan,
        "ke_rot": float(e_r[mobile].mean()) if nmob else np.nan,
        "largest_cluster": int(sizes.max()) if sizes.size else 0,
        "n_clusters": int(sizes.size), "n_in_clusters": int(sizes.sum()),
        "cluster_fraction": float(sizes.sum() / nmob) if nmob else np.nan,
    }
    return row, ctab, {"pair": pair, "active": active, "labels": labels, "position": position}


def lost_between(prev: dict, cur: dict, n: int, radius=None, box_length=None,
                 lost_gap: float | None = None) -> np.ndarray:
    """Which contacts of frame k (``prev``: pair, active, and position if ``lost_gap``) are lost
    by frame k + 1 (``cur``: pair, active, position): not active any more, and with ``lost_gap``
    also opened by more than lost_gap (d) (:func:`failure_between`). Returns (C_k,) bool."""
    lost = _ct.lost_contacts(prev["pair"], prev["active"], cur["pair"], cur["active"], n)
    if lost_gap is not None:
        gap = _ct.contact_gaps(prev["pair"], cur["position"], radius, box_length)
        lost = lost & (gap > lost_gap)
    return lost


def failure_between(prev: dict, cur: dict, fixed: np.ndarray, radius=None, box_length=None,
                    lost_gap: float | None = None) -> dict:
    """Lost contacts and failing grains from frame k (``prev``) to k + 1 (``cur``).

    prev, cur: the ``keep`` dicts of :func:`frame_observables`. A contact active at k is lost
    when it is not active at k + 1 (force definition); with ``lost_gap`` (d; needs ``radius`` and
    ``box_length``) it must also have opened: its surface gap at k + 1 exceeds lost_gap (geometric
    definition; a rigid hyperstatic pile can shift its load off a contact that stays closed, which
    the force definition counts as a loss). Returns dict n_lost, lost_fraction (n_lost / active
    contacts at k), n_failing, n_failing_in_cluster (failing grains that were in a cluster at
    frame k), failing_in_cluster_fraction.
    """
    n = fixed.size
    lost = lost_between(prev, cur, n, radius, box_length, lost_gap)
    failing = _ct.failing_grains(n, prev["pair"], lost, fixed)
    n_act = int(prev["active"].sum())
    nf = int(failing.sum())
    nfc = int((failing & (prev["labels"] >= 0)).sum())
    return {"n_lost": int(lost.sum()), "lost_fraction": lost.sum() / n_act if n_act else np.nan,
            "n_failing": nf, "n_failing_in_cluster": nfc,
            "failing_in_cluster_fraction": nfc / nf if nf else np.nan}


def run_observables(run, run_id: int | None = None, **params) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per-frame and per-cluster observables of one run (module docstring for the columns).

    run: path of a run file, or an open reader with the :func:`tiltpile.store.open_run` API.
    params: overrides of DEFAULT_PARAMS (cutoff, eps, link, cluster_region, min_contacts,
    ray_spacing, touch_tol, merge_gap, lost_gap).
    """
    p = _params(params)
    if isinstance(run, (str, os.PathLike)):
        with _open_run(run) as r:
            return run_observables(r, run_id=_run_id(r, run) if run_id is None else run_id, **params)
    rid = _run_id(run, None) if run_id is None else int(run_id)
    scene = run.config.get("scene", {}) if isinstance(run.config, dict) else {}
    mu = float(scene.get("mu", 0.5))
    mu_wall = float(scene.get("mu_wall", mu))
    radius = np.asarray(run.radius, dtype=float)
    fixed = np.asarray(run.fixed, dtype=bool)
    L = float(run.box_length)
    nfr = int(run.n_frames)
    theta = np.asarray(run.theta_deg, dtype=float)
    mobile = ~fixed
    positions = np.empty((nfr, int(mobile.sum()), 2))
    rows, tabs = [], []
    prev = None
    for k in range(nfr):
        pos = np.asarray(run.position(k), dtype=float)
        positions[k] = pos[mobile]
        pair, force, status = run.contacts(k)
        row, ctab, keep = frame_observables(
            radius, fixed, L, pos, run.velocity(k), run.omega(k), pair, force, status, theta[k],
            mu=mu, mu_wall=mu_wall, eps=p["eps"], link=p["link"],
            cluster_region=p["cluster_region"], min_contacts=p["min_contacts"],
            ray_spacing=p["ray_spacing"], touch_tol=p["touch_tol"])
        if prev is not None:
            rows[-1].update(failure_between(prev, keep, fixed, radius, L, p["lost_gap"]))
        row.update(n_lost=-1, lost_fraction=np.nan, n_failing=-1, n_failing_in_cluster=-1,
                   failing_in_cluster_fraction=np.nan)
        rows.append(row)
        ctab.insert(0, "frame", k)
        tabs.append(ctab)
        prev = keep
    frames = pd.DataFrame(rows)
    frames.insert(0, "frame", np.arange(nfr, dtype=np.int64))
    frames.insert(0, "run", rid)
    frames["step"] = np.asarray(run.step, dtype=np.int64)
    frames["time"] = np.asarray(run.time, dtype=float)
    frames["theta_deg"] = theta
    frames["iterations"] = np.asarray(run.iterations)
    frames["residual"] = np.asarray(run.residual, dtype=float)
    seg = _av.segment_avalanches(frames["lost_fraction"].to_numpy(), p["cutoff"], p["merge_gap"],
                                 n_contacts=frames["n_active"].to_numpy())
    rel = _av.theta_relative_to_onset(theta, seg["avalanching"], seg["onsets"])
    onset = np.zeros(nfr, dtype=bool)
    onset[seg["onsets"]] = True
    frames["avalanching"] = seg["avalanching"]
    frames["onset"] = onset
    frames["period"] = seg["period"]
    frames["theta_m"] = rel["theta_m"]
    frames["theta_to_onset"] = rel["theta_to_onset"]
    mean_d, max_d = _av.displacement_since_period_start(positions, seg["period_start"])
    frames["mean_displacement"] = mean_d
    frames["max_displacement"] = max_d
    frames = frames[FRAME_COLUMNS]
    clusters = pd.concat(tabs, ignore_index=True) if tabs else pd.DataFrame(columns=CLUSTER_COLUMNS)
    fi = clusters["frame"].to_numpy(np.int64)
    clusters.insert(0, "run", rid)
    clusters["theta_deg"] = theta[fi]
    clusters["avalanching"] = seg["avalanching"][fi]
    clusters["theta_to_onset"] = rel["theta_to_onset"][fi]
    clusters = clusters[CLUSTER_COLUMNS].astype({"run": np.int64, "frame": np.int64,
                                                 "cluster": np.int64, "size": np.int64})
    return frames, clusters


# ----------------------------------------------------------------------------------------------
# cache


def _cache_path(run_path: Path) -> Path:
    return run_path.parent / CACHE_DIRNAME / (run_path.stem + ".npz")


def table_params(**params) -> dict:
    """The analysis parameters the per-frame and per-cluster tables depend on (DEFAULT_PARAMS
    with ``params`` applied and checked, without the per-run table's RUN_TABLE_PARAMS)."""
    return {k: v for k, v in _params(params).items() if k not in RUN_TABLE_PARAMS}


def _source_meta(run_path: Path, params: dict) -> dict:
    st = run_path.stat()
    cached = {k: v for k, v in params.items() if k not in RUN_TABLE_PARAMS}
    return {"source": run_path.name, "size": st.st_size, "mtime_ns": st.st_mtime_ns,
            "params": cached, "version": ANALYSIS_VERSION}


def _read_meta(cache: Path) -> dict | None:
    try:
        with np.load(cache, allow_pickle=False) as z:
            return json.loads(str(z["meta"]))
    except (OSError, KeyError, ValueError):
        return None


def _is_fresh(run_path: Path, params: dict) -> bool:
    meta = _read_meta(_cache_path(run_path))
    return meta is not None and meta == json.loads(json.dumps(_source_meta(run_path, params)))


def _write_cache(cache: Path, meta: dict, frames: pd.DataFrame, clusters: pd.DataFrame) -> None:
    cache.parent.mkdir(parents=True, exist_ok=True)
    arrays = {"meta": np.array(json.dumps(meta))}
    for prefix, df in (("frames", frames), ("clusters", clusters)):
        arrays[f"{prefix}__columns"] = np.array(list(df.columns))
        for c in df.columns:
            arrays[f"{prefix}__{c}"] = df[c].to_numpy()
    tmp = cache.with_name(f".{cache.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        os.replace(tmp, cache)
    except BaseException:  # a full disk, a kill: no half-written temporary stays behind
        tmp.unlink(missing_ok=True)
        raise


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
    _write_cache(_cache_path(path), meta, frames, clusters)
    return run_path, time.perf_counter() - t0


def run_files(ensemble_dir) -> list[Path]:
    """The run files ``run_*.h5`` of an ensemble directory, sorted by name."""
    d = Path(ensemble_dir)
    if not d.is_dir():
        raise FileNotFoundError(f"ensemble directory {d} does not exist")
    return sorted(d.glob("run_*.h5"))


def compute_observables(ensemble_dir, workers: int | None = None, progress: bool = True,
                        force: bool = False, **params) -> pd.DataFrame:
    """Compute and cache the observables of every run of an ensemble that needs it.

    Incremental: a run is (re)computed when its cache ``DIR/observables/<run>.npz`` is missing,
    or when the run file's size or mtime, the analysis parameters or ANALYSIS_VERSION changed
    (``force=True`` recomputes everything). Runs are processed in parallel by ``workers``
    processes (default: number of CPUs, at most the number of pending runs; 1 = in this
    process), with a tqdm progress bar when ``progress``.

    Returns a DataFrame with one row per run file: run_file, cache, status ("cached" or
    "computed"), seconds.
    """
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
    return pd.DataFrame([{"run_file": f, "cache": str(_cache_path(Path(f))), "status": s, "seconds": t}
                         for f, (s, t) in status.items()])


def load_observables(ensemble_dir, compute_missing: bool = True, workers: int | None = None,
                     progress: bool = False, **params) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The ensemble's per-frame and per-cluster tables (module docstring for the columns).

    Reads the caches of every ``run_*.h5`` in ``ensemble_dir``. Missing or stale caches are
    computed first when ``compute_missing`` (via :func:`compute_observables`), else a
    FileNotFoundError names them. Returns (frames, clusters) sorted by run and frame.
    """
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
    fr, cl = zip(*(_read_cache(_cache_path(f)) for f in files))
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
    frames, clusters = _read_cache(_cache_path(path))
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
    thr = p["slide_ke"]
    if thr is None:
        thr = _st.ke_threshold(frames, "ke_trans")[0]["threshold"]
    out = _av.run_onsets(frames, float(thr), float(p["slide_sustain_deg"]), "ke_trans")
    out["slide_ke"] = float(thr)
    out["slide_sustain_deg"] = float(p["slide_sustain_deg"])
    return out
