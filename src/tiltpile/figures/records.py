"""Records of an ensemble's runs: what the figures and the report read from each run file, small
enough to commit (``tiltpile record DIR --out RECORDS``; layout: :mod:`tiltpile.record`).

A record holds, for one finished run:

* the per-frame table and the per-cluster table of :func:`tiltpile.analysis.load_observables` at
  the default analysis parameters, every per-frame column and the per-cluster columns the figures
  read: all but ``DROPPED_CLUSTER_COLUMNS`` (the clusters' position, gyration radii and
  long-axis angle in the box frame: read by no figure, study or report, and 60% of the bytes);
* the run's configuration and hash, seed, cost, how it ended, its deposition, preparation and
  health records, the writer's tiltpile version and the code digest of every column it holds
  (``column_code``: :func:`tiltpile.analysis.tables.column_code`);
* ``source``: the run file's name, size, attribute digest (``attrs_sha256``) and frames digest
  (``store.Run.frames_digest``), so that the record can be traced to its run file;
* the frames of the pile pictures (Figs. 1b and 3): for every run, the frames the pictures
  choose when it is the sample run -- :func:`~tiltpile.figures.snapshot.pick_avalanche_frame`
  and :func:`~tiltpile.figures.snapshot.frame_before_onset` with its default offset -- each with
  its successor (failing grains need the next frame's contacts): the sample run is the first
  with an onset, which a record written when its run finishes cannot know, and any run may be
  asked for (``sample_seed``). Up to four frames: ~0.17 MB at 1000 grains.

Sizes (measured): 0.55 MB for a 1000-grain run of 441 frames (18 600 cluster rows at ~20 bytes,
four picture frames 0.17 MB), 0.15 MB for a smoke run, 1.7-1.8 MB for a 4000-grain paper run of
~480 frames (~96 000 cluster rows ~1 MB, the four picture frames 0.7 MB): the cluster columns
held to float32 precision are stored as float32 (:mod:`tiltpile.record`). With every cluster
column a record would be ~2x larger. What a record keeps and drops: docs/run-file.md.

A record is up to date when it was written by this format version and ``WRITER`` choice, holds
every column this tiltpile computes (but the dropped ones) with this tiltpile's code for each
(records of the whole-table digest through :mod:`tiltpile.analysis.legacy_codes`), and comes from
the same run file (same name, size and ``attrs_sha256``; for files without it, the same mtime);
``write_records`` rewrites only the others: where the run files exist, a column added or
recomputed reaches the records with ``make records``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile.analysis.observables import (compute_observables, load_run_observables, run_files,
                                           table_params)
from tiltpile.analysis.legacy_codes import recorded_column_code
from tiltpile.analysis.tables import column_code
from tiltpile.record import (FORMAT_VERSION, RecordError, read_meta, record_files, record_name,
                             write_record)

from . import snapshot

# per-cluster columns a record leaves out: read by no figure (nor the report or the studies)
DROPPED_CLUSTER_COLUMNS = ("phi_deg", "rg_long", "rg_short", "x_com", "y_com")
# what the writer keeps, in the record's meta: a record written under another choice is stale
# (the text of "pictures" is a name of the choice, kept as written so that records stay current;
# the functions it names are snapshot.pick_avalanche_frame and snapshot.frame_before_onset)
WRITER = {"dropped_cluster_columns": list(DROPPED_CLUSTER_COLUMNS),
          "pictures": "fig1.pick_avalanche_frame and fig3.frame_before_onset "
                      f"(offset {snapshot.SNAPSHOT_OFFSET_DEG} deg), each with its successor"}


def picture_frames(frames: pd.DataFrame, seed: int) -> list[int]:
    """The frames of run ``seed`` the pile pictures draw when it is the sample run (Fig. 1b:
    :func:`snapshot.pick_avalanche_frame`; Fig. 3a: :func:`snapshot.frame_before_onset`), each
    with its successor if the run has one. frames: the run's per-frame table (default parameters)."""
    g = frames[frames["run"] == seed]
    n = int(g["frame"].max()) + 1 if len(g) else 0
    chosen = (snapshot.pick_avalanche_frame(frames, seed),
              snapshot.frame_before_onset(frames, seed, snapshot.SNAPSHOT_OFFSET_DEG))
    return sorted({k for f in chosen for k in (f, f + 1) if k < n})


def _source(run, path: Path) -> dict:
    st = path.stat()
    out = {"file": path.name, "size": int(st.st_size), "attrs_sha256": run.attrs_digest}
    if run.attrs_digest is None:     # files written before the digest: tell them by their mtime
        out["mtime_ns"] = int(st.st_mtime_ns)
    return out


def _kept_code() -> dict:
    """The column codes a record written now holds: every column but the dropped ones."""
    codes = column_code()
    return {"frames": codes["frames"],
            "clusters": {c: d for c, d in codes["clusters"].items()
                         if c not in DROPPED_CLUSTER_COLUMNS}}


def _wanted_meta() -> dict:
    """What an up-to-date record's meta says besides its source."""
    return {"format_version": FORMAT_VERSION, "column_code": _kept_code(),
            "analysis_params": table_params(), "writer": WRITER}


def _fresh(record: Path, run_path: Path) -> bool:
    """Whether ``record`` is up to date for the run file ``run_path`` (module docstring)."""
    import json

    from tiltpile.store import RunFileError, open_run
    try:
        meta = read_meta(record)
    except RecordError:
        return False
    want = json.loads(json.dumps(_wanted_meta()))
    held = recorded_column_code(meta) or {}
    present = {t: [c for c, _ in cols] for t, cols in (meta.get("columns") or {}).items()}
    if {t: {c: held.get(t, {}).get(c) for c in present.get(t, [])} for t in ("frames", "clusters")} \
            != want.pop("column_code"):
        return False
    if any(meta.get(k) != v for k, v in want.items()):
        return False
    try:
        with open_run(run_path) as r:
            src = _source(r, run_path)
    except RunFileError:
        return False
    return {k: meta.get("source", {}).get(k) for k in src} == src


def record_status(data_dir, out_dir) -> pd.DataFrame:
    """Per run file of ``data_dir``: run_file, record (its path in ``out_dir``), fresh (bool)."""
    out = Path(out_dir)
    rows = []
    for f in run_files(data_dir):
        rec = out / record_name(f.name)
        rows.append({"run_file": str(f), "record": str(rec), "fresh": rec.exists() and _fresh(rec, f)})
    return pd.DataFrame(rows, columns=["run_file", "record", "fresh"])


def foreign_records(out_dir, config_hash: str) -> list[Path]:
    """Records in ``out_dir`` of another configuration than ``config_hash`` (damaged or
    unreadable ones are not counted: they are rewritten)."""
    odd = []
    for p in record_files(out_dir):
        try:
            if read_meta(p).get("config_hash") != config_hash:
                odd.append(p)
        except RecordError:
            continue
    return odd


def write_record_of(run_path, out_dir, frames: pd.DataFrame | None = None,
                    clusters: pd.DataFrame | None = None) -> Path:
    """Write the record of one run file into ``out_dir`` (``run_SSSS.npz``); returns its path.

    frames, clusters: the run's tables at the default analysis parameters (None: from its
    observables cache, computed if missing, :func:`load_run_observables`).
    """
    from tiltpile.store import open_run

    run_path = Path(run_path)
    if frames is None or clusters is None:
        frames, clusters = load_run_observables(run_path)
    keep = [c for c in clusters.columns if c not in DROPPED_CLUSTER_COLUMNS]
    with open_run(run_path) as r:
        source = _source(r, run_path)
        seed = r.seed
        if len(frames) != r.n_frames or (len(frames) and set(frames["run"]) != {seed}):
            raise RecordError(f"{run_path}: its observables table does not match the run file "
                              f"({len(frames)} rows for {r.n_frames} frames of seed {seed})")
        pictures = {}
        for k in picture_frames(frames, seed):
            pair, force, status = r.contacts(k)
            pictures[k] = {"position": r.position(k), "pair": pair, "force": force,
                           "status": status, "theta_deg": float(r.theta_deg[k])}
        source["frames_sha256"] = r.frames_digest()
        meta = dict(_wanted_meta(), seed=seed, config=r.config, config_hash=r.config_hash,
                    n_grains=int(r.radius.size), n_frames=int(r.n_frames),
                    box_length=float(r.box_length), cost=dict(r.cost), end_reason=r.end_reason,
                    end_theta_deg=r.end_theta_deg, deposition=dict(r.deposition),
                    health=dict(r.health), source=source)
        radius, fixed, preparation = r.radius, r.fixed, dict(r.preparation)
    st = run_path.stat()
    if st.st_size != source["size"]:
        raise RecordError(f"{run_path} changed while its record was written; run again")
    return write_record(Path(out_dir) / record_name(run_path.name), meta=meta, frames=frames,
                        clusters=clusters[keep], radius=radius, fixed=fixed,
                        preparation=preparation, pictures=pictures)


def write_records(data_dir, out_dir, workers: int | None = None, force: bool = False,
                  progress: bool = True) -> pd.DataFrame:
    """Write the record of every run file of ``data_dir`` into ``out_dir`` whose record is missing
    or stale (all with ``force``); observables not cached yet are computed first (``workers``
    processes). Returns per run file: run_file, record, status ("written" or "up to date"),
    bytes (the record's size)."""
    out = Path(out_dir)
    status = record_status(data_dir, out)
    pending = [Path(f) for f, fresh in zip(status["run_file"], status["fresh"]) if force or not fresh]
    if pending:
        compute_observables(data_dir, workers=workers, progress=False)
        bar = None
        if progress:
            from tqdm.auto import tqdm
            bar = tqdm(total=len(pending), desc="records", unit="run")
        try:
            for f in pending:
                write_record_of(f, out, *load_run_observables(f, compute_missing=False))
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
    done = {str(f) for f in pending}
    rows = [{"run_file": f, "record": rec, "status": "written" if f in done else "up to date",
             "bytes": os.path.getsize(rec) if os.path.exists(rec) else np.nan}
            for f, rec in zip(status["run_file"], status["record"])]
    return pd.DataFrame(rows, columns=["run_file", "record", "status", "bytes"])
