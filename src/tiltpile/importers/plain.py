"""The plain format (docs/import.md, "The plain format"): the fields of a frame by name, in one
NPZ file per frame or in a CSV set of three tables.

NPZ: one ``.npz`` per frame (``numpy.savez``), holding the frame's fields (``FRAME_FIELDS``,
0-d), the grains' (``GRAIN_FIELDS``, (N,) each) and the contacts' (``CONTACT_FIELDS``, (C,)
each); the frames are the files given, or a directory's ``*.npz``, in the order of their names
(numbers in names compared as numbers: frame_2 before frame_10).
CSV: a directory holding ``frames.csv`` (a row per frame: ``frame`` and the frame fields),
``grains.csv`` and ``contacts.csv`` (a row per grain and per contact of each frame: ``frame``
and their fields); the frames in the order of frames.csv.
A field the format does not know is refused (a misspelt optional field would be lost silently).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from tiltpile.importers.frame import InputError, RawFrame, flags, integers

# field -> required (True), optional (False); with theta_deg or gx and gy for the angle
FRAME_FIELDS = {"step": True, "time": False, "theta_deg": False, "gx": False, "gy": False}
GRAIN_FIELDS = {"id": False, "x": True, "y": True, "radius": True, "fixed": False, "vx": False,
                "vy": False, "omega": False, "rotation": False}
CONTACT_FIELDS = {"id1": True, "id2": True, "fn": True, "ft": True, "sliding": False}
CSV_FILES = ("frames.csv", "grains.csv", "contacts.csv")


def natural_key(path: Path):
    """Sort key comparing the numbers in a name as numbers (frame_2 before frame_10)."""
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name)]


def kind_of(inputs) -> str | None:
    """"npz" or "csv" when ``inputs`` are plain-format frames, else None."""
    paths = [Path(p) for p in inputs]
    if len(paths) == 1 and paths[0].is_dir():
        d = paths[0]
        if (d / "frames.csv").is_file():
            return "csv"
        if any(d.glob("*.npz")):
            return "npz"
        return None
    if paths and all(p.suffix == ".npz" for p in paths):
        return "npz"
    return None


def numbers(values, field: str, where: str) -> np.ndarray:
    """``values`` as float64 (NaN kept: the converter names it with its frame)."""
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {field} must hold numbers") from None


def raw_frame(fields: dict, where: str) -> RawFrame:
    """A ``RawFrame`` from the fields of one frame ({name: array}); InputError naming a missing,
    unknown or misshapen field and ``where``."""
    known = {**FRAME_FIELDS, **GRAIN_FIELDS, **CONTACT_FIELDS}
    unknown = sorted(set(fields) - set(known))
    if unknown:
        raise InputError(f"{where}: unknown field {unknown[0]!r}; the fields are "
                         f"{', '.join(known)}")
    missing = [k for k, req in known.items() if req and k not in fields]
    if missing:
        raise InputError(f"{where}: no field {missing[0]!r} (required: "
                         f"{', '.join(k for k, r in known.items() if r)})")
    angle = [k for k in ("theta_deg", "gx", "gy") if k in fields]
    if angle not in (["theta_deg"], ["gx", "gy"]):
        raise InputError(f"{where}: give the tilt angle as theta_deg, or the gravity vector as "
                         f"gx and gy (found: {', '.join(angle) or 'neither'})")
    for group in (("vx", "vy"),):
        if sum(k in fields for k in group) == 1:
            raise InputError(f"{where}: give both {' and '.join(group)} (the velocity) or neither")

    def scalar(name):
        a = np.asarray(fields[name])
        if a.size != 1:
            raise InputError(f"{where}: {name} holds {a.size} values; it is one number per frame")
        return a.reshape(())

    def column(name, n, what):
        a = np.asarray(fields[name])
        if a.ndim != 1 or (n is not None and a.shape[0] != n):
            raise InputError(f"{where}: {name} has shape {a.shape}, expected ({n},) like "
                             f"{'x' if what == 'grain' else 'id1'}")
        return a

    n = np.asarray(fields["x"]).reshape(-1).size if np.ndim(fields["x"]) == 1 else None
    if n is None:
        raise InputError(f"{where}: x has shape {np.shape(fields['x'])}; it is one value per grain")
    c = np.asarray(fields["id1"]).shape[0] if np.ndim(fields["id1"]) == 1 else None
    if c is None:
        raise InputError(f"{where}: id1 has shape {np.shape(fields['id1'])}; it is one value per "
                         "contact")
    g = {k: column(k, n, "grain") for k in GRAIN_FIELDS if k in fields}
    k = {name: column(name, c, "contact") for name in CONTACT_FIELDS if name in fields}
    step = integers(scalar("step").reshape(1), "step", where)[0]
    time = float(numbers(scalar("time"), "time", where)) if "time" in fields else math.nan
    if "theta_deg" in fields:   # NaN kept: the converter names it with its frame
        theta = float(numbers(scalar("theta_deg"), "theta_deg", where))
    else:
        gx = float(numbers(scalar("gx"), "gx", where))
        gy = float(numbers(scalar("gy"), "gy", where))
        theta = math.degrees(math.atan2(gx, -gy))
    ids = integers(g["id"], "id", where) if "id" in g else np.arange(n, dtype=np.int64)
    position = np.column_stack([numbers(g["x"], "x", where), numbers(g["y"], "y", where)])
    velocity = None
    if "vx" in g:
        velocity = np.column_stack([numbers(g["vx"], "vx", where), numbers(g["vy"], "vy", where)])
    return RawFrame(
        where=where, step=int(step), time=time, theta_deg=theta, id=ids, position=position,
        radius=g["radius"], fixed=flags(g["fixed"], "fixed", where) if "fixed" in g else np.zeros(n, bool),
        velocity=velocity, omega=g.get("omega"), rotation=g.get("rotation"),
        id1=k["id1"], id2=k["id2"], fn=k["fn"], ft=k["ft"],
        sliding=flags(k["sliding"], "sliding", where) if "sliding" in k else None)


class NpzReader:
    """The frames of NPZ files (one per frame) or of a directory of them."""

    def __init__(self, inputs):
        paths = [Path(p) for p in inputs]
        if len(paths) == 1 and paths[0].is_dir():
            paths = sorted(paths[0].glob("*.npz"), key=natural_key)
        for p in paths:
            if not p.is_file():
                raise InputError(f"{p}: no such file")
        if not paths:
            raise InputError("no .npz frames to import")
        self.paths = paths

    def describe(self) -> dict:
        return {"format": "npz", "files": [p.name for p in self.paths]}

    def __iter__(self):
        for p in self.paths:
            try:
                with np.load(p, allow_pickle=False) as z:
                    fields = {name: z[name] for name in z.files}
            except (OSError, ValueError, EOFError) as e:
                raise InputError(f"{p.name}: not a readable .npz file "
                                 f"({' '.join(str(e).split())})") from None
            yield raw_frame(fields, p.name)


class CsvReader:
    """The frames of a CSV set: a directory holding frames.csv, grains.csv and contacts.csv."""

    def __init__(self, inputs):
        paths = [Path(p) for p in inputs]
        if len(paths) != 1 or not paths[0].is_dir():
            raise InputError("a CSV set is one directory holding frames.csv, grains.csv and "
                             "contacts.csv")
        self.dir = paths[0]
        for name in CSV_FILES:
            if not (self.dir / name).is_file():
                raise InputError(f"{self.dir}: no {name} (a CSV set holds {', '.join(CSV_FILES)})")

    def describe(self) -> dict:
        return {"format": "csv", "files": list(CSV_FILES)}

    def _table(self, name: str, fields: dict):
        import pandas as pd

        path = self.dir / name
        try:
            t = pd.read_csv(path, skipinitialspace=True, comment="#")
        except (OSError, ValueError) as e:
            raise InputError(f"{name}: cannot be read as CSV ({' '.join(str(e).split())})") from None
        t.columns = [str(c).strip() for c in t.columns]
        if "frame" not in t.columns:
            raise InputError(f"{name}: no column 'frame' (each row names its frame)")
        unknown = [c for c in t.columns if c != "frame" and c not in fields]
        if unknown:
            raise InputError(f"{name}: unknown column {unknown[0]!r}; its columns are frame, "
                             f"{', '.join(fields)}")
        frame = integers(t["frame"].to_numpy(), "frame", name)
        return t, frame

    def __iter__(self):
        frames, fnum = self._table("frames.csv", FRAME_FIELDS)
        grains, gnum = self._table("grains.csv", GRAIN_FIELDS)
        contacts, cnum = self._table("contacts.csv", CONTACT_FIELDS)
        if np.unique(fnum).size != fnum.size:
            dup = np.sort(fnum)[np.flatnonzero(np.diff(np.sort(fnum)) == 0)[0]]
            raise InputError(f"frames.csv: frame {int(dup)} has two rows")
        for name, num in (("grains.csv", gnum), ("contacts.csv", cnum)):
            stray = np.setdiff1d(num, fnum)
            if stray.size:
                raise InputError(f"{name}: rows of frame {int(stray[0])}, which frames.csv does not list")
        for name, table, fields in (("grains.csv", grains, GRAIN_FIELDS),
                                    ("contacts.csv", contacts, CONTACT_FIELDS)):
            need = [c for c, req in fields.items() if req and c not in table.columns]
            if need:
                raise InputError(f"{name}: no column {need[0]!r} (required: frame, "
                                 f"{', '.join(c for c, r in fields.items() if r)})")
        g_at = _groups(gnum)
        c_at = _groups(cnum)
        empty = np.zeros(0, dtype=np.int64)
        for row, f in enumerate(fnum.tolist()):
            where = f"frame {f} of {self.dir.name}/ (frames.csv row {row})"
            fields = {c: frames[c].to_numpy()[row] for c in frames.columns
                      if c != "frame" and not (c == "time" and _missing(frames[c].to_numpy()[row]))}
            gi = g_at.get(f, empty)
            if gi.size == 0:
                raise InputError(f"{where}: grains.csv holds no grain of it")
            fields.update({c: grains[c].to_numpy()[gi] for c in grains.columns if c != "frame"})
            ci = c_at.get(f, empty)
            fields.update({c: contacts[c].to_numpy()[ci] for c in contacts.columns if c != "frame"})
            yield raw_frame(fields, where)


def _missing(v) -> bool:
    """An empty cell of frames.csv's time (a frame without its time)."""
    return isinstance(v, float) and math.isnan(v)


def _groups(num: np.ndarray) -> dict:
    """{frame: the row indices of that frame}, rows in file order."""
    order = np.argsort(num, kind="stable")
    keys, starts = np.unique(num[order], return_index=True)
    ends = list(starts[1:]) + [order.size]
    return {int(k): order[a:b] for k, a, b in zip(keys, starts, ends)}
