"""An ensemble directory as tables: the per-frame and per-cluster observables of every run, the
configuration they share, and the first avalanche onset of each run.

What the figure notebooks and the measurement studies (``benchmarks.compare_ensembles``)
start from. The tables are those of :func:`tiltpile.analysis.load_observables` (columns in
:mod:`tiltpile.analysis.observables`); run files are read through :mod:`tiltpile.store` only.

A directory without run files may hold their records instead (``run_SSSS.npz``,
:mod:`tiltpile.record`, written by ``tiltpile record``): the same tables (without the cluster
columns no figure reads) at the analysis parameters they were written at (the defaults, or those
of ``tiltpile record --params``: one parameter set per directory, :func:`record_params`), the
same configuration, seeds and description, and the frames of the pile pictures.

A reader (a figure, a study) declares the columns it reads (:class:`Reads`) and gets tables of
those columns only, from run files and records alike, so that a column it reads undeclared fails
where it is read. From records, only the declared columns are checked: a record serves a column
when it holds it computed by the code this tiltpile computes it with (per-column digests,
:func:`tiltpile.analysis.tables.column_code`; records of the whole-table digest through
:mod:`tiltpile.analysis.legacy_codes`). A column the records lack or hold from other code is
refused in one line naming it: the run files are needed for it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from tiltpile import __version__
from tiltpile.analysis.legacy_codes import recorded_column_code
from tiltpile.analysis.observables import load_observables, run_files, table_params
from tiltpile.analysis.tables import CLUSTER_DOCS, DEFAULT_PARAMS, FRAME_DOCS, column_code

# the columns every table keeps, read or not: what its rows are sorted and joined by
KEYS = {"frames": ("run", "frame"), "clusters": ("run", "frame", "cluster")}


@dataclass(frozen=True)
class Reads:
    """The table columns a reader reads: ``reader`` names it in messages ("Fig. 2"), ``frames``
    and ``clusters`` its per-frame and per-cluster columns (FRAME_DOCS, CLUSTER_DOCS; ValueError
    for another name). The tables' keys (``KEYS``) are always included; the columns are kept in
    table order."""

    reader: str
    frames: tuple = ()
    clusters: tuple = ()

    def __post_init__(self):
        for table, docs in (("frames", FRAME_DOCS), ("clusters", CLUSTER_DOCS)):
            cols = set(getattr(self, table))
            unknown = sorted(cols - set(docs))
            if unknown:
                raise ValueError(f"{self.reader} reads {table} column(s) {unknown}, which the "
                                 "tables do not have (tiltpile.analysis.tables)")
            object.__setattr__(self, table,
                               tuple(c for c in docs if c in cols or c in KEYS[table]))

    def __or__(self, other: "Reads") -> "Reads":
        """What both read, named after the first reader."""
        return Reads(self.reader, self.frames + other.frames, self.clusters + other.clusters)


def _select(df: pd.DataFrame, columns) -> pd.DataFrame:
    keep = set(columns)
    return df[[c for c in df.columns if c in keep]]


@dataclass
class Ensemble:
    """An ensemble directory's per-frame and per-cluster tables and a description for the JSON.

    data_dir: the directory of ``run_SSSS.h5`` (or of their records); frames, clusters: the
    observables tables of all runs (column ``run`` = seed); config: the runs' shared
    configuration (dict); seeds: sorted by run file name; meta: preset, run count, seeds, grains,
    config hash, tiltpile version, the analysis parameters and the runs' cost (what each figure's
    JSON records); records: {seed: record path} when loaded from records, else empty.
    """

    data_dir: Path
    frames: pd.DataFrame
    clusters: pd.DataFrame
    config: dict
    seeds: list[int]
    meta: dict = field(default_factory=dict)
    records: dict = field(default_factory=dict)

    @property
    def n_runs(self) -> int:
        return len(self.seeds)

    def run_path(self, seed: int) -> Path:
        """The run file of ``seed`` (``DIR/run_SSSS.h5``)."""
        p = self.data_dir / f"run_{int(seed):04d}.h5"
        if not p.exists():
            how = " (the ensemble was loaded from records)" if self.records else ""
            raise FileNotFoundError(f"{p}: no run file for seed {seed} in {self.data_dir}{how}")
        return p

    def record_path(self, seed: int) -> Path:
        """The record of ``seed`` (an ensemble loaded from records)."""
        if int(seed) not in self.records:
            raise FileNotFoundError(f"no record of seed {seed} in {self.data_dir}")
        return self.records[int(seed)]

    def sample_seed(self, seed: int | None = None) -> int:
        """``seed`` if given (checked), else the first seed whose run has an avalanche onset."""
        if seed is not None:
            if int(seed) not in self.seeds:
                raise ValueError(f"sample seed {seed} is not in the ensemble (seeds {self.seeds})")
            return int(seed)
        onsets = self.frames.groupby("run")["theta_m"].first()
        ok = [s for s in self.seeds if s in onsets.index and np.isfinite(onsets[s])]
        return ok[0] if ok else self.seeds[0]


def load_ensemble(data_dir, preset: str | None = None, reads: Reads | None = None,
                  **analysis_params) -> Ensemble:
    """Load (computing if missing or stale) the observables of every ``run_*.h5`` in
    ``data_dir``; in a directory without run files, those of its records ``run_*.npz``
    (:func:`load_records`). With ``reads``, the tables hold only its columns.

    Refuses (ValueError) an ensemble whose runs have different configurations, and
    (FileNotFoundError) a directory without run files or records. ``analysis_params`` go to
    :func:`tiltpile.analysis.load_observables` (cutoff, eps, lost_gap, ...).
    """
    from tiltpile.record import record_files
    from tiltpile.store import open_run

    data_dir = Path(data_dir)
    files = run_files(data_dir)
    if not files:
        if record_files(data_dir):
            return load_records(data_dir, preset, reads, **analysis_params)
        raise FileNotFoundError(f"no run_*.h5 files (nor their records run_*.npz) in {data_dir}: "
                                "run `tiltpile ensemble` first")
    hashes, seeds, cfg, costs = set(), [], None, []
    for f in files:
        with open_run(f) as r:
            hashes.add(r.config_hash)
            seeds.append(r.seed)
            cfg = r.config
            costs.append(dict(r.cost))
    if len(hashes) > 1:
        raise ValueError(f"{data_dir} mixes runs of {len(hashes)} configurations")
    frames, clusters = load_observables(data_dir, progress=False, **analysis_params)
    if reads is not None:
        frames, clusters = _select(frames, reads.frames), _select(clusters, reads.clusters)
    meta = _describe(preset, seeds, cfg, hashes.pop(), analysis_params, costs)
    return Ensemble(data_dir, frames, clusters, cfg, seeds, meta)


def _describe(preset, seeds, cfg, config_hash, analysis_params, costs) -> dict:
    """An ensemble's ``meta`` (the same from run files and from records); ``history``: the piles'
    preparation before the ramp: its legs ``pretilt_deg`` ([] for fresh piles), their own rate
    (0: the ramp's) and a ``label`` (:func:`tiltpile.config.history_label`, "fresh", "±16° 2
    cycles at 10x rate", ...); ``engine`` "lammps" for the soft-sphere DEM's runs (a ``[dem]``
    section), absent for Contact Dynamics'."""
    from tiltpile.config import history_label, rate_suffix

    proto = cfg.get("protocol", {})
    legs = [float(a) for a in proto.get("pretilt_deg") or []]
    history = {"pretilt_deg": legs,
               "pretilt_per_step_deg": float(proto.get("pretilt_per_step_deg") or 0.0),
               "label": history_label(legs) + (rate_suffix(cfg) if legs else "")}
    return {"preset": preset, "n_runs": len(seeds), "seeds": seeds, "n_grains": cfg["scene"]["n"],
            "config_hash": config_hash[:12], "tiltpile_version": __version__,
            "analysis": dict(analysis_params), "history": history, "cost": ensemble_cost(costs),
            **({"engine": "lammps"} if cfg.get("dem") is not None else {})}


def _same(a, b) -> bool:
    """Equal as JSON would write them (tuples as lists, NaN equal to NaN)."""
    import json
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def record_params(meta: dict) -> dict:
    """The table parameters (:func:`tiltpile.analysis.observables.table_params`) a record's tables
    were computed at, from its ``meta``: its ``analysis_params``, a parameter the record predates
    at its default (the code that reads it is in the digests of the columns it reaches,
    :func:`record_columns`; a parameter no longer in the tables is left out)."""
    given = meta.get("analysis_params") or {}
    return {k: given.get(k, v) for k, v in table_params().items()}


def params_differ(a: dict, b: dict) -> list[str]:
    """The keys of ``a`` whose value ``b`` gives otherwise (compared as JSON writes them)."""
    return sorted(k for k in a if not _same(a[k], b.get(k)))


def describe_params(params: dict) -> str:
    """One phrase for a set of table parameters: "the default analysis parameters", or
    "analysis parameters k=v, ..." naming those that differ from their defaults."""
    other = [k for k in params if k in DEFAULT_PARAMS and not _same(params[k], DEFAULT_PARAMS[k])]
    if not other:
        return "the default analysis parameters"
    return "analysis parameters " + ", ".join(f"{k}={params[k]!r}" for k in other)


def load_records(data_dir, preset: str | None = None, reads: Reads | None = None,
                 **analysis_params) -> Ensemble:
    """The ensemble of the records ``run_*.npz`` in ``data_dir`` (:mod:`tiltpile.record`): the
    same Ensemble as :func:`load_ensemble` gives from their run files, except the cluster
    columns the records leave out, with ``records`` set (pile pictures:
    :func:`tiltpile.figures.data.snapshot`).

    ``reads``: the columns wanted (the tables then hold those only); None: every column of the
    tables but those the records' writer leaves out. Each wanted column must be held by every
    record as this tiltpile computes it (:func:`tiltpile.analysis.tables.column_code`; the
    legacy whole-table digest through :mod:`tiltpile.analysis.legacy_codes`): a column a record
    lacks, leaves out or holds from other code is refused (``tiltpile.record.RecordError``, one
    line naming the column and saying the run files are needed); so are records of an unknown
    whole-table digest, damaged records (every member's checksum is checked) and records of other
    format versions.

    ``analysis_params``: the tables' parameters asked for (cutoff, lost_gap, contact_rule, ...;
    those of the per-run table, slide_ke and slide_sustain_deg, do not enter the records). The
    records serve them when they were written at them (:func:`record_params`: the defaults, or
    ``tiltpile record --params``); other parameters are refused (RecordError, one line naming the
    parameters the records hold and those asked for), and so is a directory mixing records of
    several parameter sets. Records of different configurations are refused (ValueError), a
    directory without records is FileNotFoundError.
    """
    from tiltpile.record import RecordError, read_meta, read_record, record_files

    data_dir = Path(data_dir)
    paths = record_files(data_dir)
    if not paths:
        raise FileNotFoundError(f"no records run_*.npz in {data_dir}: write them with "
                                "`tiltpile record`")
    wanted = table_params(**analysis_params)
    who = f"{reads.reader} ({data_dir})" if reads is not None else str(data_dir)
    # the parameter set first, from the metas alone (cheap): one per directory, the one asked for
    held = [record_params(read_meta(path)) for path in paths]
    odd = next((i for i, h in enumerate(held) if params_differ(h, held[0])), None)
    if odd is not None:
        raise RecordError(f"{data_dir} mixes records of several analysis parameter sets "
                          f"({paths[0].name}: {describe_params(held[0])}; {paths[odd].name}: "
                          f"{describe_params(held[odd])}); one records directory holds one set")
    diff = params_differ(wanted, held[0])
    if diff:
        raise RecordError(f"{paths[0]}: records hold the tables at {describe_params(held[0])}; "
                          f"{', '.join(f'{k}={wanted[k]!r}' for k in diff)} needs the run files "
                          "(or records written at those parameters: tiltpile record --params)")
    hashes, seeds, cfg, costs, fr, cl, records = set(), [], None, [], [], [], {}
    for path in paths:
        rec = read_record(path)    # every member, so that every checksum is checked
        m = rec.meta
        need = record_columns(path, m, reads, who)
        tables = {"frames": _select(rec.frames, need["frames"]),
                  "clusters": _select(rec.clusters, need["clusters"])}
        hashes.add(m["config_hash"])
        seeds.append(rec.seed)
        cfg = m["config"]
        costs.append(dict(m.get("cost") or {}))
        fr.append(tables["frames"])
        cl.append(tables["clusters"])
        records[rec.seed] = path
    if len(hashes) > 1:
        raise ValueError(f"{data_dir} mixes records of {len(hashes)} configurations")
    frames = pd.concat(fr, ignore_index=True).sort_values(["run", "frame"], kind="stable")
    clusters = pd.concat(cl, ignore_index=True).sort_values(["run", "frame", "cluster"], kind="stable")
    meta = _describe(preset, seeds, cfg, hashes.pop(), analysis_params, costs)
    return Ensemble(data_dir, frames.reset_index(drop=True), clusters.reset_index(drop=True), cfg,
                    seeds, meta, records)


def record_columns(path, meta: dict, reads: Reads | None = None, who: str | None = None) -> dict:
    """The columns a record (``path``, its ``meta``: :func:`tiltpile.record.read_meta`) serves
    to ``reads`` (None: every column of the tables but those its writer left out): {"frames":
    [...], "clusters": [...]}, or RecordError (one line, naming the column, ``who`` needing it
    and that the run files are needed) for a column the record lacks, leaves out or holds from
    other code than this tiltpile's (:func:`tiltpile.analysis.tables.column_code`), and for a
    record of a whole-table digest :mod:`tiltpile.analysis.legacy_codes` does not know."""
    from tiltpile.record import RecordError

    path = Path(path)
    who = who or (reads.reader if reads is not None else str(path.parent))
    held = recorded_column_code(meta)
    if held is None:
        raise RecordError(f"{path}: a record of table code {meta.get('analysis_code')}, whose "
                          "columns this tiltpile cannot tell (tiltpile.analysis.legacy_codes); "
                          "rewrite the records from the run files (`make records`, "
                          "`tiltpile record`)")
    current = column_code()
    dropped = set((meta.get("writer") or {}).get("dropped_cluster_columns") or ())
    out = {}
    for table in ("frames", "clusters"):
        present = {c for c, _ in (meta.get("columns") or {}).get(table, [])}
        need = (list(getattr(reads, table)) if reads is not None else
                [c for c in current[table] if not (table == "clusters" and c in dropped)])
        for c in need:
            if c not in present:
                why = ("its records leave it out" if table == "clusters" and c in dropped
                       else "its records predate it")
                raise RecordError(f"{who} needs column {table}.{c}; {why}; the run files are "
                                  f"needed (first: {path.name})")
            if held.get(table, {}).get(c) != current[table][c]:
                raise RecordError(f"{who} needs column {table}.{c}; its records hold it as other "
                                  f"code computed it (code {held.get(table, {}).get(c)}, this "
                                  f"tiltpile's {current[table][c]}); the run files are needed "
                                  f"(first: {path.name})")
        out[table] = need
    return out


def ensemble_cost(costs: list[dict]) -> dict:
    """What the runs cost, from each run file's ``Run.cost``: per run, the median wall seconds
    (``seconds_per_run``) over the runs whose whole wall time is known: the sum over invocations
    (``wall_seconds``) where every invocation was counted, else the seconds of a run simulated in
    one invocation (a resumed run's ``seconds`` cover only its last part, so such a run is left
    out); and the mean time steps, NLGS sweeps and capped steps. Keys are None where no run file
    records them (files written before they were counted)."""
    def mean(key):
        x = [c[key] for c in costs if key in c]
        return float(np.mean(x)) if x else None

    def whole_seconds(c):
        if c.get("wall_seconds_whole"):
            return c["wall_seconds"]
        return c["seconds"] if "seconds" in c and c.get("resumed_from_frame", -1) < 0 else None

    whole = [w for w in map(whole_seconds, costs) if w is not None]
    return {"runs_timed": len(whole),
            "seconds_per_run": float(np.median(whole)) if whole else None,
            "steps_per_run": mean("steps"), "sweeps_per_run": mean("sweeps"),
            "capped_steps_per_run": mean("capped_steps")}


def first_onsets(frames: pd.DataFrame, seeds) -> np.ndarray:
    """theta [deg] of the first avalanche onset of each run, in the order of ``seeds``.

    frames: per-frame table with columns run, frame, theta_deg, onset (bool; the lost-contact
    criterion of :func:`tiltpile.analysis.segment_avalanches`). Returns a float array of
    len(seeds), NaN for a run without onset.
    """
    on = frames[frames["onset"].astype(bool)].sort_values(["run", "frame"], kind="stable")
    first = on.groupby("run")["theta_deg"].first()
    return np.array([float(first.get(s, np.nan)) for s in seeds])
