"""The run record: one small file per finished run holding what the figures read from it. The
only module that knows its layout.

A run file (``store``) holds every frame of a run (~40 MB at 1000 grains, ~175 MB and more at
4000) and is not committed; a record (~0.5 MB at 1000 grains) is, so that the figures can be
rebuilt from a clone without the run files (``tiltpile record``; what goes in is chosen by
:mod:`tiltpile.figures.records`, the record is read by
:func:`tiltpile.analysis.ensemble_data.load_ensemble` and
:func:`tiltpile.figures.data.snapshot`).

Layout: a zip of ``.npy`` members (``numpy.load`` reads it; no pickle), ``run_SSSS.npz``::

    meta                  JSON text (0-d str array): see below
    frames__<column>      (F,)  the per-frame table, one member per column
    clusters__<column>    (K,)  the per-cluster table, one member per column
    particles__radius     (N,)  float64 [d]
    particles__fixed      (N,)  bool
    preparation__<key>    (legs,) the run file's /preparation attrs (absent without a history)
    pictures__frame       (P,)  int64   the stored frames, sorted
    pictures__theta_deg   (P,)  float64 their inclination
    pictures__position    (P, N, 2) float64 [d]
    pictures__offset      (P+1,) int64  contacts of picture p are rows offset[p]:offset[p+1]
    pictures__pair        (C, 2) int32, pictures__force (C, 2) float64 [f_n, f_t in m g],
    pictures__status      (C,) int8     as the run file's contacts

Table columns are stored with the smallest integer type that holds their values (ids, counts),
float64 columns whose values are all float32 numbers as float32 (the cluster table's
``FLOAT32_CLUSTER_COLUMNS``), both checked lossless, and read back with their original dtype
(``meta["columns"]``); every other column as it is. A record's tables are those the writer gave, bit for bit.

``meta`` (JSON): format, format_version, tiltpile_version (of the writer), column_code
({table: {column: code}}: the version of the computation of each column held,
``tiltpile.analysis.tables.column_code``; records written before it hold instead analysis_code,
one digest of the whole table code, read through ``tiltpile.analysis.legacy_codes``) and
analysis_params (of the tables), seed, config (dict), config_hash, n_grains, n_frames,
box_length, cost (``store.Run.cost``), end_reason, end_theta_deg, deposition, health, source
(run file name, size, its ``attrs_sha256`` and ``frames_sha256``: ``store.Run.frames_digest``),
columns ({table: [[column, dtype], ...]} in the table's order), and ``writer`` (what the writer
chose to keep: its own description, compared by the writer to decide whether a record is up to
date).

Integrity: every member carries the zip's CRC-32, checked when it is read; a damaged or
truncated record, or one of another format version, is refused with ``RecordError`` (one line
naming the file). (A flipped bit in the zip's own bookkeeping that no reader uses, such as a
member's time stamp, is not content and goes unnoticed.) The file is written deterministically (fixed member times, sorted members)
to a temporary name, synced and renamed, so the same content gives the same bytes and nothing is
ever half-written.
"""

from __future__ import annotations

import io
import json
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import math

import numpy as np
import pandas as pd

from tiltpile import __version__
from tiltpile.outputs import replaced_whole

FORMAT = "tiltpile-run-record"
FORMAT_VERSION = 1
PATTERN = "run_*.npz"
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)
_SMALL_INTS = (np.int8, np.int16, np.int32, np.int64)


class RecordError(ValueError):
    """A record that cannot be used: damaged, truncated, of another format or table code,
    or lacking what was asked of it. The message is one line naming the file."""


def record_name(run_name: str) -> str:
    """The record's file name for run file ``run_SSSS.h5`` (``run_SSSS.npz``)."""
    return Path(run_name).stem + ".npz"


def record_files(directory) -> list[Path]:
    """The records ``run_*.npz`` of a directory, sorted by name (empty if it does not exist)."""
    d = Path(directory)
    return sorted(d.glob(PATTERN)) if d.is_dir() else []


# ----------------------------------------------------------------------------------------------
# writing


def _compact(a: np.ndarray) -> np.ndarray:
    """An integer column in the smallest integer type holding its values, a float64 column
    whose every value is a float32 as float32 (both lossless)."""
    if a.size == 0:
        return a
    if a.dtype == np.float64:
        with np.errstate(over="ignore"):     # beyond float32's range: inf, not equal
            f = a.astype(np.float32)
        same = (f.astype(np.float64) == a) | (np.isnan(a) & np.isnan(f))
        return f if same.all() else a
    if a.dtype.kind not in "iu":
        return a
    lo, hi = int(a.min()), int(a.max())
    for t in _SMALL_INTS:
        info = np.iinfo(t)
        if info.min <= lo and hi <= info.max:
            return a.astype(t) if np.dtype(t).itemsize < a.dtype.itemsize else a
    return a


def _table_members(prefix: str, df: pd.DataFrame) -> tuple[dict, list]:
    members, dtypes = {}, []
    for c in df.columns:
        a = df[c].to_numpy()
        if a.dtype.kind not in "biuf":
            raise RecordError(f"column {prefix}.{c} has dtype {a.dtype}: a record holds numbers only")
        small = _compact(a)
        lossless = np.array_equal(small.astype(a.dtype), a, equal_nan=small.dtype.kind == "f")
        if small is not a and not lossless:   # checked in _compact: never
            raise RecordError(f"column {prefix}.{c} does not fit {small.dtype}")
        members[f"{prefix}__{c}"] = small
        dtypes.append([str(c), a.dtype.str])
    return members, dtypes


def jsonable(x, nan_as_none: bool = False):
    """numpy scalars and arrays as plain Python numbers and lists (for ``meta``); with
    ``nan_as_none``, NaN and inf as None (strict JSON, as the figures write it)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v, nan_as_none) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v, nan_as_none) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist(), nan_as_none)
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, bytes):
        return x.decode()
    if nan_as_none and isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def write_record(path, *, meta: dict, frames: pd.DataFrame, clusters: pd.DataFrame,
                 radius: np.ndarray, fixed: np.ndarray, preparation: dict | None = None,
                 pictures: dict | None = None) -> Path:
    """Write one record (module docstring) to ``path``, atomically. Returns the path.

    meta: the run's description (JSON-able after :func:`jsonable`; format, format_version,
    tiltpile_version and columns are filled in here); frames, clusters: the run's tables
    (numeric columns); radius (N,), fixed (N,); preparation: {key: array} or None;
    pictures: {frame: dict(position (N, 2), pair (C, 2), force (C, 2), status (C,), theta_deg)}.
    """
    path = Path(path)
    members: dict[str, np.ndarray] = {}
    fm, fd = _table_members("frames", frames)
    cm, cd = _table_members("clusters", clusters)
    members.update(fm)
    members.update(cm)
    members["particles__radius"] = np.asarray(radius, np.float64)
    members["particles__fixed"] = np.asarray(fixed, np.bool_)
    for key, v in (preparation or {}).items():
        members[f"preparation__{key}"] = np.asarray(v)
    pics = pictures or {}
    ks = sorted(int(k) for k in pics)
    n = members["particles__radius"].size
    members["pictures__frame"] = np.asarray(ks, np.int64)
    members["pictures__theta_deg"] = np.asarray([float(pics[k]["theta_deg"]) for k in ks], np.float64)
    members["pictures__position"] = (np.stack([np.asarray(pics[k]["position"], np.float64) for k in ks])
                                     if ks else np.zeros((0, n, 2)))
    counts = [np.asarray(pics[k]["pair"]).reshape(-1, 2).shape[0] for k in ks]
    members["pictures__offset"] = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)

    def cat(name, dtype, shape):
        parts = [np.asarray(pics[k][name], dtype).reshape(-1, *shape) for k in ks]
        return np.concatenate(parts) if parts else np.zeros((0, *shape), dtype)

    members["pictures__pair"] = cat("pair", np.int32, (2,))
    members["pictures__force"] = cat("force", np.float64, (2,))
    members["pictures__status"] = cat("status", np.int8, ())
    doc = jsonable(dict(meta))
    doc.update(format=FORMAT, format_version=FORMAT_VERSION, tiltpile_version=__version__,
               columns={"frames": fd, "clusters": cd})
    members["meta"] = np.array(json.dumps(doc, sort_keys=True, allow_nan=True))

    path.parent.mkdir(parents=True, exist_ok=True)
    # synced and renamed when complete; a full disk, a kill: no half-written temporary stays behind
    with replaced_whole(path) as tmp, open(tmp, "wb") as fh, \
            zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as zf:
        for name in sorted(members):
            buf = io.BytesIO()
            a = np.asarray(members[name])   # (ascontiguousarray would make 0-d 1-d)
            np.lib.format.write_array(buf, a if a.flags.c_contiguous else a.copy(order="C"),
                                      allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue())
    return path


# ----------------------------------------------------------------------------------------------
# reading

_DAMAGE = (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, KeyError, TypeError,
           json.JSONDecodeError)


def _damaged(path: Path, e: BaseException) -> RecordError:
    what = " ".join(str(e).split()) or type(e).__name__
    return RecordError(f"{path}: damaged record ({what}); rewrite it from its run file with "
                       "`tiltpile record`")


def _open(path: Path):
    if not path.is_file():
        raise RecordError(f"{path}: no such record")
    try:
        return np.load(path, allow_pickle=False)
    except _DAMAGE as e:
        raise _damaged(path, e) from None


def _check_meta(path: Path, z) -> dict:
    try:
        meta = json.loads(str(z["meta"][()]))
    except _DAMAGE as e:
        raise _damaged(path, e) from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise RecordError(f"{path}: not a tiltpile run record")
    if meta.get("format_version") != FORMAT_VERSION:
        raise RecordError(f"{path}: record format version {meta.get('format_version')}, this "
                          f"tiltpile reads version {FORMAT_VERSION}; rewrite it from its run file "
                          "with `tiltpile record`")
    return meta


def read_meta(path) -> dict:
    """The ``meta`` of a record (cheap: the other members are not read). RecordError if the
    record is damaged or of another format version."""
    path = Path(path)
    with _open(path) as z:
        return _check_meta(path, z)


@dataclass
class Record:
    """A record as read: ``meta`` (module docstring), the two tables, the grains, the
    preparation arrays and the stored picture frames (``snapshot``)."""

    path: Path
    meta: dict
    frames: pd.DataFrame | None = None
    clusters: pd.DataFrame | None = None
    radius: np.ndarray | None = None
    fixed: np.ndarray | None = None
    preparation: dict = field(default_factory=dict)
    pictures: dict = field(default_factory=dict)

    @property
    def seed(self) -> int:
        return int(self.meta["seed"])

    @property
    def picture_frames(self) -> list[int]:
        return sorted(self.pictures)

    def snapshot(self, frame: int) -> dict:
        """Frame ``frame`` as :func:`tiltpile.figures.data.snapshot` gives it from the run file:
        position, radius, fixed, pair, force, status, theta_deg, box_length, next (the contacts of
        frame + 1) and next_position (None at the run's last frame). RecordError naming the
        stored frames if the record does not hold it (or its successor)."""
        k = int(frame)
        if not 0 <= k < int(self.meta["n_frames"]):
            raise IndexError(f"frame {k} out of range: the run has {self.meta['n_frames']} frames")
        last = k + 1 >= int(self.meta["n_frames"])
        if k not in self.pictures or not (last or k + 1 in self.pictures):
            raise RecordError(
                f"{self.path}: frame {k} of run {self.seed} is not in its record (it holds frames "
                f"{self.picture_frames}: the pile pictures' default choice); draw another frame "
                "from the run file")
        p = self.pictures[k]
        nxt = None if last else self.pictures[k + 1]
        return {"position": p["position"].copy(), "radius": self.radius.copy(),
                "fixed": self.fixed.copy(), "pair": p["pair"].copy(), "force": p["force"].copy(),
                "status": p["status"].copy(), "theta_deg": float(p["theta_deg"]),
                "box_length": float(self.meta["box_length"]),
                "next": None if last else (nxt["pair"].copy(), nxt["force"].copy(),
                                           nxt["status"].copy()),
                "next_position": None if last else nxt["position"].copy()}


def _table(z, prefix: str, dtypes: list) -> pd.DataFrame:
    return pd.DataFrame({c: z[f"{prefix}__{c}"].astype(np.dtype(dt)) for c, dt in dtypes},
                        columns=[c for c, _ in dtypes])


def read_record(path, tables: bool = True, pictures: bool = True) -> Record:
    """Read a record (``tables``: the per-frame and per-cluster tables, ``pictures``: the stored
    frames). Every member read is checked against its CRC-32; RecordError (one line) if the
    record is damaged, truncated or of another format version."""
    path = Path(path)
    with _open(path) as z:
        meta = _check_meta(path, z)
        try:
            rec = Record(path, meta)
            rec.radius = z["particles__radius"]
            rec.fixed = z["particles__fixed"]
            rec.preparation = {name[len("preparation__"):]: z[name] for name in z.files
                               if name.startswith("preparation__")}
            if tables:
                rec.frames = _table(z, "frames", meta["columns"]["frames"])
                rec.clusters = _table(z, "clusters", meta["columns"]["clusters"])
            if pictures:
                ks = z["pictures__frame"]
                off = z["pictures__offset"]
                theta, pos = z["pictures__theta_deg"], z["pictures__position"]
                pair, force, status = z["pictures__pair"], z["pictures__force"], z["pictures__status"]
                if off.shape != (ks.size + 1,) or off[-1] != pair.shape[0] or pos.shape[0] != ks.size:
                    raise ValueError("pictures__offset does not index the stored contacts")
                for p, k in enumerate(ks.tolist()):
                    a, b = int(off[p]), int(off[p + 1])
                    rec.pictures[int(k)] = {"position": pos[p], "pair": pair[a:b],
                                            "force": force[a:b], "status": status[a:b],
                                            "theta_deg": float(theta[p])}
        except _DAMAGE as e:
            raise _damaged(path, e) from None
    return rec
