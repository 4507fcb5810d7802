"""Records of an ensemble's runs: what the figures and the report read from each run file, small
enough to commit (``tiltpile record DIR --out RECORDS``; layout: :mod:`tiltpile.record`).

A record holds, for one finished run:

* the per-frame table and the per-cluster table of :func:`tiltpile.analysis.load_observables` at
  the default analysis parameters, or at those given (``params``, ``tiltpile record --params
  JSON``; meta ``analysis_params``), every per-frame column and the per-cluster columns the
  figures read: all but ``DROPPED_CLUSTER_COLUMNS`` (the clusters' position, gyration radii and
  long-axis angle in the box frame: read by no figure, study or report, and 60% of the bytes);
* the run's configuration and hash, seed, cost, how it ended, its deposition, preparation and
  health records, the writer's tiltpile version and the code of every column it holds
  (``column_code``: :func:`tiltpile.analysis.tables.column_code`);
* ``source``: the run file's name, size, attribute digest (``attrs_sha256``) and frames digest
  (``store.Run.frames_digest``), so that the record can be traced to its run file;
* the frames of the pile pictures (Figs. 1b and 3): for every run, the frames the pictures
  choose when it is the sample run -- :func:`~tiltpile.figures.snapshot.pick_avalanche_frame`
  and :func:`~tiltpile.figures.snapshot.frame_before_onset` with its default offset, chosen from
  the record's own tables -- each with its successor (failing grains need the next stored
  frame's contacts): the sample run is the first with an onset, which a record written when its
  run finishes cannot know, and any run may be asked for (``sample_seed``). Up to four frames:
  ~0.17 MB at 1000 grains.

Other analysis parameters. Records at parameters P (``params``: any of the tables' parameters,
:data:`tiltpile.analysis.DEFAULT_PARAMS` but those of the per-run table, ``RUN_TABLE_PARAMS``)
go in a directory of their own, one parameter set per directory (``write_records`` and
``tiltpile record`` refuse a directory holding records of another set, as they refuse one of
another configuration); :func:`tiltpile.analysis.ensemble_data.load_records` serves them when
asked for P and refuses other parameters, naming those the records hold. The tables are those
of the run's observables cache at P (``DIR/observables/params-<digest>/``, computed if missing).
Such a record keeps its own pictures, chosen from its own tables: the frames the pictures
choose move with P (measured on the smoke piles: every run's at ``{"contact_rule": "gap:0.005"}``,
whose lost contacts leave the list; two of three at ``touching``; all three at ``frame_stride``
2; none at ``{"contact_rule": "gap:0.005", "lost_rule": "force"}``, whose losses, and so
avalanches, are the defaults'; a 1000-grain run's avalanche frame 380 instead of 297 at
``gap:0.00218``), and the figures' numbers read the picture of the sample run (Fig. 3: grains
in clusters and failing; Fig. 7: the largest rigid cluster, floppy modes, spanning): records
without them could not give those numbers. The pictures hold positions and contact lists, from
which every contact rule's near pairs follow, so the figures computed from records at P give the
numbers the run files give at P (tests/figures/test_records_params.py). What they cost,
measured: a smoke run's record is 0.12 MB at the defaults and at ``{"contact_rule": "gap:0.005",
"lost_rule": "force"}`` alike, its pictures 0.04 MB of it; a 1000-grain run of the default
preset (441 frames, no onset: three picture frames) 0.33 MB at the defaults, 0.32 MB at
``gap:0.00218`` and at gap:0.005 with losses by force, its pictures 0.125 MB of each: the
pictures are ~40% of a record at both sizes and the tables at P weigh what the defaults' do, so
a 4000-grain record at P should weigh about the default one's 1.7-1.8 MB (not measured there).

A record is up to date when it was written by this format version and ``WRITER`` choice, holds
every column this tiltpile computes (but the dropped ones) with this tiltpile's code for each
(records of the whole-table digest through :mod:`tiltpile.analysis.legacy_codes`), holds the
tables at the parameters asked for (a parameter the record predates counts as its default:
:func:`tiltpile.analysis.ensemble_data.record_params`), and comes from the same run file (same
name, size and ``attrs_sha256``; for files without it, the same mtime); ``write_records``
rewrites only the others: where the run files exist, a column added or recomputed reaches the
records with ``make records`` (``make records PARAMS='{...}' RECORDS=dir`` for another
parameter set).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile.analysis.ensemble_data import describe_params, params_differ, record_params
from tiltpile.analysis.observables import (compute_observables, load_run_observables, run_files,
                                           table_params)
from tiltpile.analysis.legacy_codes import recorded_column_code
from tiltpile.analysis.tables import RUN_TABLE_PARAMS, column_code
from tiltpile.outputs import output_lock
from tiltpile.record import (FORMAT_VERSION, RecordError, read_meta, record_files, record_name,
                             write_record)

from . import snapshot

LOCK = ".record.lock"  # in a records directory, held while records are written into it
# per-cluster columns a record leaves out: read by no figure (nor the report or the studies)
DROPPED_CLUSTER_COLUMNS = ("phi_deg", "rg_long", "rg_short", "x_com", "y_com")
# what the writer keeps, in the record's meta: a record written under another choice is stale
# (the text of "pictures" is a name of the choice, kept as written so that records stay current;
# the functions it names are snapshot.pick_avalanche_frame and snapshot.frame_before_onset)
WRITER = {"dropped_cluster_columns": list(DROPPED_CLUSTER_COLUMNS),
          "pictures": "fig1.pick_avalanche_frame and fig3.frame_before_onset "
                      f"(offset {snapshot.SNAPSHOT_OFFSET_DEG} deg), each with its successor"}


def picture_frames(frames: pd.DataFrame, seed: int, n_frames: int | None = None) -> list[int]:
    """The frames of run ``seed`` the pile pictures draw when it is the sample run (Fig. 1b:
    :func:`snapshot.pick_avalanche_frame`; Fig. 3a: :func:`snapshot.frame_before_onset`), each
    with its successor (the next stored frame) if the run has one. frames: the run's per-frame
    table at the record's parameters; n_frames: the run's stored frames (None: the table's last
    frame + 1, which at a frame_stride above 1 may miss the last stored frame)."""
    g = frames[frames["run"] == seed]
    n = n_frames if n_frames is not None else (int(g["frame"].max()) + 1 if len(g) else 0)
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


# the JSON type of each table parameter (checked by check_params before its range)
_KINDS = {"cutoff": "a number", "ray_spacing": "a number", "touch_tol": "a number",
          "min_contacts": "an integer", "merge_gap": "an integer", "frame_stride": "an integer",
          "eps": "a number or null", "lost_gap": "a number or null", "link": "a string",
          "cluster_region": "a string", "contact_rule": "a string", "lost_rule": "a string or null"}


def _of_kind(v, kind: str) -> bool:
    if v is None:
        return kind.endswith("or null")
    if "string" in kind:
        return isinstance(v, str)
    if isinstance(v, bool):
        return False
    return isinstance(v, int) if "integer" in kind else isinstance(v, (int, float))


def check_params(params: dict | None) -> dict:
    """The full table parameters of records written at ``params`` (None or {}: the defaults):
    :func:`~tiltpile.analysis.observables.table_params`, refusing in one line (TypeError) a name
    that is not a parameter of the tables (the per-run table's, ``RUN_TABLE_PARAMS``, do not
    enter a record) or a value of another type, and (ValueError) a value out of its range,
    those the tables' own check leaves to the computation included (min_contacts, merge_gap,
    ray_spacing, touch_tol, eps), so that nothing is computed or written with them."""
    params = dict(params or {})
    tables = table_params()
    unknown = sorted(set(params) - set(tables))
    if unknown:
        why = ("parameters of the per-run table, which records do not hold (they apply when the "
               "figures read the records)" if set(unknown) <= set(RUN_TABLE_PARAMS)
               else f"not analysis parameters of the tables ({', '.join(sorted(tables))})")
        raise TypeError(f"{', '.join(unknown)}: {why}")
    for k, v in params.items():
        if k in _KINDS and not _of_kind(v, _KINDS[k]):
            raise TypeError(f"{k} must be {_KINDS[k]}, got {v!r}")
    p = table_params(**params)
    for k, ok, what in (("min_contacts", p["min_contacts"] >= 0, ">= 0"),
                        ("merge_gap", p["merge_gap"] >= 0, ">= 0 (frames)"),
                        ("ray_spacing", p["ray_spacing"] > 0, "> 0 (d)"),
                        ("touch_tol", p["touch_tol"] >= 0, ">= 0 (d)"),
                        ("eps", p["eps"] is None or 0 <= p["eps"] < 1, "None or in [0, 1)")):
        if not ok:
            raise ValueError(f"{k} must be {what}, got {p[k]!r}")
    return p


def _wanted_meta(params: dict | None = None) -> dict:
    """What an up-to-date record's meta says besides its source (at ``params``: None, the
    defaults)."""
    return {"format_version": FORMAT_VERSION, "column_code": _kept_code(),
            "analysis_params": table_params(**(params or {})), "writer": WRITER}


def _fresh(record: Path, run_path: Path, params: dict | None = None) -> bool:
    """Whether ``record`` is up to date for the run file ``run_path`` at the table parameters
    ``params`` (module docstring)."""
    import json

    from tiltpile.store import RunFileError, open_run
    try:
        meta = read_meta(record)
    except RecordError:
        return False
    want = json.loads(json.dumps(_wanted_meta(params)))
    # the parameters as the loader reads them: one the record predates at its default
    if params_differ(want.pop("analysis_params"), record_params(meta)):
        return False
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


def record_status(data_dir, out_dir, params: dict | None = None) -> pd.DataFrame:
    """Per run file of ``data_dir``: run_file, record (its path in ``out_dir``), fresh (bool: up
    to date at the table parameters ``params``, None: the defaults)."""
    out = Path(out_dir)
    rows = []
    for f in run_files(data_dir):
        rec = out / record_name(f.name)
        rows.append({"run_file": str(f), "record": str(rec),
                     "fresh": rec.exists() and _fresh(rec, f, params)})
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


def foreign_params(out_dir, params: dict | None = None) -> list[Path]:
    """Records in ``out_dir`` holding the tables at other parameters than ``params`` (None: the
    defaults; :func:`~tiltpile.analysis.ensemble_data.record_params`, a parameter a record
    predates at its default). Damaged or unreadable records are not counted: they are rewritten."""
    want = table_params(**(params or {}))
    odd = []
    for p in record_files(out_dir):
        try:
            if params_differ(want, record_params(read_meta(p))):
                odd.append(p)
        except RecordError:
            continue
    return odd


def refuse_foreign_params(out_dir, params: dict | None = None) -> None:
    """RecordError (one line, naming a record and the parameters it holds) if ``out_dir`` holds
    records at other parameters than ``params`` (:func:`foreign_params`)."""
    odd = foreign_params(out_dir, params)
    if odd:
        held = describe_params(record_params(read_meta(odd[0])))
        more = f" and {len(odd) - 1} more" if len(odd) > 1 else ""
        raise RecordError(f"{out_dir}: {odd[0].name}{more} hold the tables at {held}, not at "
                          f"{describe_params(table_params(**(params or {})))}; one records "
                          "directory holds one parameter set")


def write_record_of(run_path, out_dir, frames: pd.DataFrame | None = None,
                    clusters: pd.DataFrame | None = None, params: dict | None = None) -> Path:
    """Write the record of one run file into ``out_dir`` (``run_SSSS.npz``); returns its path.

    params: the analysis parameters of its tables (None: the defaults; :func:`check_params`);
    frames, clusters: the run's tables at those parameters (None: from its observables cache,
    computed if missing, :func:`load_run_observables`).
    """
    from tiltpile.store import open_run

    run_path = Path(run_path)
    p = check_params(params)
    if frames is None or clusters is None:
        frames, clusters = load_run_observables(run_path, **p)
    keep = [c for c in clusters.columns if c not in DROPPED_CLUSTER_COLUMNS]
    with open_run(run_path) as r:
        source = _source(r, run_path)
        seed = r.seed
        analysed = len(range(0, int(r.n_frames), int(p["frame_stride"])))
        if len(frames) != analysed or (len(frames) and set(frames["run"]) != {seed}):
            raise RecordError(f"{run_path}: its observables table does not match the run file "
                              f"({len(frames)} rows for {analysed} analysed frames of seed {seed})")
        pictures = {}
        for k in picture_frames(frames, seed, int(r.n_frames)):
            pair, force, status = r.contacts(k)
            pictures[k] = {"position": r.position(k), "pair": pair, "force": force,
                           "status": status, "theta_deg": float(r.theta_deg[k])}
        source["frames_sha256"] = r.frames_digest()
        meta = dict(_wanted_meta(p), seed=seed, config=r.config, config_hash=r.config_hash,
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
                  progress: bool = True, params: dict | None = None) -> pd.DataFrame:
    """Write the record of every run file of ``data_dir`` into ``out_dir`` whose record is missing
    or stale (all with ``force``), its tables at the analysis parameters ``params`` (None: the
    defaults; checked first, :func:`check_params`); observables not cached yet at those
    parameters are computed first (``workers`` processes). Holds ``out_dir``'s lock (``LOCK``)
    while it writes: another writer of ``out_dir`` is waited for (one line on stderr), and the
    records it wrote are not written again (but with ``force``). Refuses (RecordError, one line, before
    anything is computed or written) an ``out_dir`` holding records at other parameters: one
    parameter set per directory. Returns per run file: run_file, record, status ("written" or
    "up to date"), bytes (the record's size)."""
    out = Path(out_dir)
    p = check_params(params)
    refuse_foreign_params(out, p)

    def todo():
        status = record_status(data_dir, out, p)
        return status, [Path(f) for f, fresh in zip(status["run_file"], status["fresh"])
                        if force or not fresh]

    status, pending = todo()
    if pending:
        # one writer at a time per records directory: another one is waited for, and the
        # records it wrote are not written again
        with output_lock(out, LOCK, "a records writer", wait=True):
            refuse_foreign_params(out, p)
            status, pending = todo()
            if pending:
                compute_observables(data_dir, workers=workers, progress=False, **p)
            bar = None
            if progress and pending:
                from tqdm.auto import tqdm
                bar = tqdm(total=len(pending), desc="records", unit="run")
            try:
                for f in pending:
                    write_record_of(f, out, *load_run_observables(f, compute_missing=False, **p),
                                    params=p)
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
