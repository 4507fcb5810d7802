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

Borrowed members (:func:`compact_record`): a record may leave out what other records of the
same run file hold bit for bit, and say in ``meta["borrowed"]`` where each piece is::

    sources    [path, ...]  the records it borrows from, relative to its own directory (records
                            of the same run: seed, config_hash, n_frames, source file and
                            frames_sha256 agree, checked when read)
    columns    {table: {column: {from, every, sha256}}}  a table column absent from the record:
                            the column of source ``from``'s table at the rows whose frame is a
                            multiple of ``every`` (1: every row; 2: a source at every frame serves
                            a record at frame_stride 2), as the dtype ``columns`` gives
    members    {name: {from, sha256}}   particles__radius, particles__fixed, preparation__<key>
    pictures   {frame: {from, sha256}}  a picture frame absent from pictures__*

``sha256`` is the digest of the piece as the record gives it (:func:`_digest`: dtype, shape and
bytes), checked when it is read: a source that is missing, of another run, or whose piece has
changed is refused (RecordError, one line naming both records), so a record that borrows gives
its tables, grains and pictures bit for bit or nothing. A source may itself borrow (not in a
circle). :func:`read_record` gives every record whole, whatever it borrows; :func:`read_meta`
gives ``meta`` as stored. The definitions study's records borrow from the default rule's records
of the same runs and from each other (:func:`tiltpile.figures.definitions.compact_definition_records`).

Integrity: every member carries the zip's CRC-32, checked when it is read; a damaged or
truncated record, or one of another format version, is refused with ``RecordError`` (one line
naming the file). (A flipped bit in the zip's own bookkeeping that no reader uses, such as a
member's time stamp, is not content and goes unnoticed.) The file is written deterministically (fixed member times, sorted members)
to a temporary name, synced and renamed, so the same content gives the same bytes and nothing is
ever half-written.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
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
BORROWED = "borrowed"   # meta key of what a record borrows (module docstring)
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
    tiltpile_version and columns are filled in here, a ``borrowed`` left out: this record holds
    everything); frames, clusters: the run's tables (numeric columns); radius (N,), fixed (N,);
    preparation: {key: array} or None;
    pictures: {frame: dict(position (N, 2), pair (C, 2), force (C, 2), status (C,), theta_deg)}.
    """
    members, columns = _members(frames, clusters, radius, fixed, preparation, pictures)
    doc = jsonable(dict(meta))
    doc.pop(BORROWED, None)
    doc.update(format=FORMAT, format_version=FORMAT_VERSION, tiltpile_version=__version__,
               columns=columns)
    return _write_members(Path(path), members, doc)


def _members(frames, clusters, radius, fixed, preparation, pictures) -> tuple[dict, dict]:
    """Every member of a record but ``meta``, and its ``columns`` ({table: [[column, dtype]]})."""
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
    return members, {"frames": fd, "clusters": cd}


def _write_members(path: Path, members: dict, doc: dict) -> Path:
    """Write ``members`` and ``doc`` (the meta, JSON-able) as a record at ``path``, atomically
    and deterministically (sorted members, fixed times)."""
    members = dict(members, meta=np.array(json.dumps(doc, sort_keys=True, allow_nan=True)))
    path.parent.mkdir(parents=True, exist_ok=True)
    # synced and renamed when complete; a full disk, a kill: no half-written temporary stays behind
    with replaced_whole(path) as tmp, open(tmp, "wb") as fh:
        _write_zip(fh, members)
    return path


def _write_zip(fh, members: dict) -> None:
    """The record's zip of ``members`` (name -> array) into the binary file ``fh``."""
    with zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as zf:
        for name in sorted(members):
            buf = io.BytesIO()
            a = np.asarray(members[name])   # (ascontiguousarray would make 0-d 1-d)
            np.lib.format.write_array(buf, a if a.flags.c_contiguous else a.copy(order="C"),
                                      allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue())


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


def _table(z, stored: set, prefix: str, dtypes: list, lender: "_Lender") -> pd.DataFrame:
    cols = {}
    for c, dt in dtypes:
        name = f"{prefix}__{c}"
        cols[c] = (z[name].astype(np.dtype(dt)) if name in stored
                   else lender.column(prefix, c, np.dtype(dt)))
    if len({a.shape[0] for a in cols.values()}) > 1:
        raise ValueError(f"the columns of {prefix} differ in length")
    return pd.DataFrame(cols, columns=[c for c, _ in dtypes])


def read_record(path, tables: bool = True, pictures: bool = True, _chain: tuple = ()) -> Record:
    """Read a record (``tables``: the per-frame and per-cluster tables, ``pictures``: the stored
    frames), whole: what it borrows (module docstring) is read from its sources and checked
    against its digest. Every member read is checked against its CRC-32; RecordError (one line)
    if the record is damaged, truncated or of another format version, or if what it borrows is
    missing or not what it was."""
    path = Path(path)
    here = os.path.realpath(path)
    if here in _chain:
        raise RecordError(f"{path}: its borrowed members lead back to it "
                          f"({' -> '.join(_chain + (here,))})")
    with _open(path) as z:
        meta = _check_meta(path, z)
        try:
            stored = set(z.files)
            lender = _Lender(path, meta, _chain + (here,), tables, pictures)
            rec = Record(path, meta)
            rec.radius = (z["particles__radius"] if "particles__radius" in stored
                          else lender.member("particles__radius"))
            rec.fixed = (z["particles__fixed"] if "particles__fixed" in stored
                         else lender.member("particles__fixed"))
            names = sorted({n for n in stored if n.startswith("preparation__")}
                           | {n for n in lender.members if n.startswith("preparation__")})
            rec.preparation = {n[len("preparation__"):]: z[n] if n in stored else lender.member(n)
                               for n in names}
            if tables:
                rec.frames = _table(z, stored, "frames", meta["columns"]["frames"], lender)
                rec.clusters = _table(z, stored, "clusters", meta["columns"]["clusters"], lender)
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
                for k in lender.pictures:
                    if k in rec.pictures:
                        raise ValueError(f"picture frame {k} both stored and borrowed")
                    rec.pictures[k] = lender.picture(k)
                rec.pictures = dict(sorted(rec.pictures.items()))
        except RecordError:
            raise
        except _DAMAGE as e:
            raise _damaged(path, e) from None
    return rec


# ----------------------------------------------------------------------------------------------
# borrowing (module docstring): what other records of the same run hold bit for bit


def _digest(*arrays) -> str:
    """SHA-256 of arrays as a record gives them: each one's dtype, shape and bytes."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.asarray(a)
        h.update(f"{a.dtype.str}{a.shape};".encode())
        h.update((a if a.flags.c_contiguous else a.copy(order="C")).tobytes())
    return h.hexdigest()


def _picture_digest(p: dict) -> str:
    return _digest(p["position"], p["pair"], p["force"], p["status"],
                   np.array([p["theta_deg"]], np.float64))


def _rows(table: pd.DataFrame, every: int) -> np.ndarray:
    """The rows of a table whose frame is a multiple of ``every`` (boolean)."""
    return table["frame"].to_numpy() % int(every) == 0


def _run_of(meta: dict) -> dict:
    """What makes two records records of the same run file."""
    src = meta.get("source") or {}
    return {"seed": meta.get("seed"), "config_hash": meta.get("config_hash"),
            "n_frames": meta.get("n_frames"), "file": src.get("file"),
            "frames_sha256": src.get("frames_sha256")}


def _same_run(a: dict, b: dict) -> list[str]:
    """The keys of :func:`_run_of` in which two records' metas differ (one without a frames
    digest is never of the same run: nothing can be borrowed from it)."""
    ra, rb = _run_of(a), _run_of(b)
    if ra["frames_sha256"] is None or rb["frames_sha256"] is None:
        return ["frames_sha256"]
    return [k for k in ra if ra[k] != rb[k]]


class _Lender:
    """What one record borrows (``meta["borrowed"]``), read from its sources when asked and
    checked against its digest; each source is read once, with what is borrowed from it."""

    def __init__(self, path: Path, meta: dict, chain: tuple, tables: bool, pictures: bool):
        self.path, self.meta, self.chain = path, meta, chain
        b = meta.get(BORROWED) or {}
        self.sources = list(b.get("sources") or [])
        self.columns = b.get("columns") or {}
        self.members = b.get("members") or {}
        self.pictures = sorted(int(k) for k in (b.get("pictures") or {}))
        self._pictures = b.get("pictures") or {}
        self.need = {}
        for table in ("frames", "clusters"):
            for e in self.columns.get(table, {}).values():
                self.need.setdefault(int(e["from"]), [False, False])[0] |= tables
        for e in self._pictures.values():
            self.need.setdefault(int(e["from"]), [False, False])[1] |= pictures
        self._read: dict[int, Record] = {}

    def _source(self, i: int) -> Record:
        if i not in self._read:
            rel = self.sources[i]
            p = Path(self.chain[-1]).parent / rel     # beside the record itself, links followed
            if not p.is_file():
                raise RecordError(f"{self.path}: borrows from {rel}, which is missing; restore it "
                                  "(or rewrite this record whole from its run file)")
            tables, pictures = self.need.get(i, (False, False))
            src = read_record(p, tables=tables, pictures=pictures, _chain=self.chain)
            odd = _same_run(self.meta, src.meta)
            if odd:
                raise RecordError(f"{self.path}: borrows from {rel}, a record of another run "
                                  f"({', '.join(odd)} differ)")
            self._read[i] = src
        return self._read[i]

    def _check(self, what: str, entry: dict, got: str):
        if got != entry["sha256"]:
            raise RecordError(f"{self.path}: {what}, borrowed from {self.sources[int(entry['from'])]}, "
                              "is not what it was (its digest differs): that record changed; "
                              "restore it, or rewrite this record whole from its run file")

    def column(self, table: str, column: str, dtype: np.dtype) -> np.ndarray:
        entry = self.columns.get(table, {}).get(column)
        if entry is None:
            raise RecordError(f"{self.path}: damaged record (column {table}.{column} neither "
                              "stored nor borrowed)")
        src = getattr(self._source(int(entry["from"])), table)
        a = src[column].to_numpy()[_rows(src, entry["every"])].astype(dtype)
        self._check(f"column {table}.{column}", entry, _digest(a))
        return a

    def member(self, name: str) -> np.ndarray:
        entry = self.members.get(name)
        if entry is None:
            raise RecordError(f"{self.path}: damaged record ({name} neither stored nor borrowed)")
        src = self._source(int(entry["from"]))
        if name.startswith("preparation__"):
            a = src.preparation.get(name[len("preparation__"):])
        else:
            a = {"particles__radius": src.radius, "particles__fixed": src.fixed}[name]
        got = None if a is None else _digest(a)
        self._check(name, entry, got)
        return a

    def picture(self, k: int) -> dict:
        entry = self._pictures[str(k)]
        p = self._source(int(entry["from"])).pictures.get(k)
        self._check(f"picture frame {k}", entry, None if p is None else _picture_digest(p))
        return p


def record_differences(a: Record, b: Record) -> list[str]:
    """What differs between two records read whole (:func:`read_record`): meta (but
    ``borrowed``), each table's columns, dtypes and bytes, the grains, the preparation and the
    pictures, bit for bit. Empty when they give the same record."""
    out = []
    ma, mb = ({k: v for k, v in jsonable(r.meta).items() if k != BORROWED} for r in (a, b))
    if json.dumps(ma, sort_keys=True) != json.dumps(mb, sort_keys=True):
        out.append("meta")
    for table in ("frames", "clusters"):
        ta, tb = getattr(a, table), getattr(b, table)
        if (ta is None) != (tb is None):
            out.append(table)
            continue
        if ta is None:
            continue
        if list(ta.columns) != list(tb.columns):
            out.append(f"{table} columns")
            continue
        out += [f"{table}.{c}" for c in ta.columns
                if _digest(ta[c].to_numpy()) != _digest(tb[c].to_numpy())]
    for name in ("radius", "fixed"):
        if _digest(getattr(a, name)) != _digest(getattr(b, name)):
            out.append(f"particles__{name}")
    if sorted(a.preparation) != sorted(b.preparation):
        out.append("preparation keys")
    else:
        out += [f"preparation__{k}" for k in a.preparation
                if _digest(a.preparation[k]) != _digest(b.preparation[k])]
    if sorted(a.pictures) != sorted(b.pictures):
        out.append("picture frames")
    else:
        out += [f"picture frame {k}" for k in a.pictures
                if _picture_digest(a.pictures[k]) != _picture_digest(b.pictures[k])]
    return out


def _pieces(rec: Record) -> dict:
    """Every piece a record may borrow and its digest: {("columns", table, column): digest,
    ("members", name): ..., ("pictures", frame): ...}."""
    out = {}
    for table in ("frames", "clusters"):
        for c in getattr(rec, table).columns:
            a = getattr(rec, table)[c].to_numpy()
            out[("columns", table, c)] = _digest(a)
    out[("members", "particles__radius")] = _digest(rec.radius)
    out[("members", "particles__fixed")] = _digest(rec.fixed)
    for k, v in rec.preparation.items():
        out[("members", f"preparation__{k}")] = _digest(v)
    for k, p in rec.pictures.items():
        out[("pictures", k)] = _picture_digest(p)
    return out


def _piece_name(piece: tuple) -> str:
    kind = piece[0]
    return (f"{piece[1]}.{piece[2]}" if kind == "columns" else piece[1] if kind == "members"
            else f"picture:{piece[1]}")


def _depends_on(path: Path, seen=None) -> set:
    """The real paths of every record ``path`` borrows from, directly or not (from the metas)."""
    seen = set() if seen is None else seen
    meta = read_meta(path)
    for rel in (meta.get(BORROWED) or {}).get("sources") or []:
        p = os.path.realpath(Path(os.path.realpath(path)).parent / rel)
        if p not in seen:
            seen.add(p)
            if Path(p).is_file():
                _depends_on(Path(p), seen)
    return seen


def compact_record(path, sources, borrow=None) -> dict:
    """Rewrite the record ``path`` so that it leaves out every piece (table column, grains,
    preparation array, picture frame: module docstring) one of ``sources`` holds bit for bit,
    borrowing it from the first that does; what no source holds so stays in the record.
    ``sources``: records of the same run (seed, configuration, run file and its frames digest;
    RecordError otherwise), in order of preference; a missing one is skipped. ``borrow``: the
    pieces to borrow ("frames.z", "clusters.size", "particles__radius", "preparation__<key>",
    "picture:<frame>"), each of which must be held bit for bit by a source (RecordError naming
    it otherwise, nothing written); None: every piece a source holds.

    The record is read whole first (what it borrows already included), the new one written to a
    temporary beside it, read back whole and compared with it (:func:`record_differences`): only
    if they are the same, bit for bit, does it replace the record (RecordError otherwise, the
    record left as it was). A record whose content would not change is not rewritten. Returns
    {"path", "status" ("compacted" or "unchanged"), "bytes_before", "bytes_after", "borrowed"
    (pieces borrowed), "stored" (pieces kept), "sources" (those used)}."""
    path = Path(path)
    before = path.stat().st_size if path.is_file() else 0
    rec = read_record(path)
    mine = _pieces(rec)
    every = sorted({1, int((rec.meta.get("analysis_params") or {}).get("frame_stride") or 1)})
    here = os.path.realpath(path)
    srcs = []
    for s in sources:
        s = Path(s)
        if not s.is_file():
            continue
        if os.path.realpath(s) == here or here in _depends_on(s):
            raise RecordError(f"{path}: cannot borrow from {s}, which borrows from it")
        src = read_record(s)
        odd = _same_run(rec.meta, src.meta)
        if odd:
            raise RecordError(f"{path}: {s} is a record of another run ({', '.join(odd)} differ); "
                              "a record borrows only from records of its own run")
        srcs.append((s, src))
    plan = {}
    for piece, digest in mine.items():
        for i, (s, src) in enumerate(srcs):
            got = _offer(src, piece, digest, every)
            if got is not None:
                plan[piece] = (i, got)
                break
    if borrow is not None:
        names = {_piece_name(p): p for p in mine}
        unknown = [b for b in borrow if b not in names]
        if unknown:
            raise RecordError(f"{path}: holds no {', '.join(unknown)}")
        refused = [b for b in borrow if names[b] not in plan]
        if refused:
            raise RecordError(f"{path}: {', '.join(refused)} not held bit for bit by "
                              f"{', '.join(str(s) for s, _ in srcs) or 'any source'}; kept, "
                              "nothing written")
        plan = {names[b]: plan[names[b]] for b in borrow}
    # the sources used, renumbered in order
    order = sorted({i for i, _ in plan.values()})
    renum = {i: j for j, i in enumerate(order)}
    rel = [os.path.relpath(os.path.realpath(srcs[i][0]), os.path.dirname(here)).replace(os.sep, "/")
           for i in order]
    b = {"sources": rel, "columns": {}, "members": {}, "pictures": {}}
    for piece, (i, extra) in sorted(plan.items(), key=lambda kv: str(kv[0])):
        entry = {"from": renum[i], "sha256": mine[piece]}
        if piece[0] == "columns":
            b["columns"].setdefault(piece[1], {})[piece[2]] = dict(entry, every=extra)
        elif piece[0] == "members":
            b["members"][piece[1]] = entry
        else:
            b["pictures"][str(piece[1])] = entry
    pics = {k: p for k, p in rec.pictures.items() if ("pictures", k) not in plan}
    members, columns = _members(rec.frames, rec.clusters, rec.radius, rec.fixed, rec.preparation, pics)
    for piece in plan:
        if piece[0] == "columns":
            del members[f"{piece[1]}__{piece[2]}"]
        elif piece[0] == "members":
            del members[piece[1]]
    doc = jsonable(dict(rec.meta))
    doc.pop(BORROWED, None)
    if columns != doc.get("columns"):
        raise RecordError(f"{path}: its tables do not read back as its meta declares them")
    if plan:
        doc[BORROWED] = b
    result = {"path": path, "bytes_before": before,
              "borrowed": sorted(_piece_name(p) for p in plan),
              "stored": sorted(_piece_name(p) for p in mine if p not in plan),
              "sources": [str(srcs[i][0]) for i in order]}
    body = dict(members, meta=np.array(json.dumps(doc, sort_keys=True, allow_nan=True)))
    buf = io.BytesIO()
    _write_zip(buf, body)
    if buf.getvalue() == path.read_bytes():
        return dict(result, status="unchanged", bytes_after=before)
    with replaced_whole(path) as tmp:
        tmp.write_bytes(buf.getvalue())
        odd = record_differences(rec, read_record(tmp))
        if odd:
            raise RecordError(f"{path}: the compacted record does not read back as it was "
                              f"({', '.join(odd[:5])}); left as it was")
    return dict(result, status="compacted", bytes_after=path.stat().st_size)


def _offer(src: Record, piece: tuple, digest: str, every: list) -> int | bool | None:
    """Whether ``src`` holds ``piece`` (of digest ``digest``) bit for bit: for a column, the
    ``every`` (frames multiple) at which its rows give it; True for another piece; None if not."""
    kind = piece[0]
    if kind == "columns":
        _, table, c = piece
        t = getattr(src, table)
        if c not in t.columns:
            return None
        for k in every:
            a = t[c].to_numpy()[_rows(t, k)]
            if _digest(a) == digest:
                return k
        return None
    if kind == "members":
        name = piece[1]
        if name.startswith("preparation__"):
            a = src.preparation.get(name[len("preparation__"):])
        else:
            a = {"particles__radius": src.radius, "particles__fixed": src.fixed}[name]
        return True if a is not None and _digest(a) == digest else None
    p = src.pictures.get(piece[1])
    return True if p is not None and _picture_digest(p) == digest else None
