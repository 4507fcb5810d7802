"""Reading a run file: ``open_run`` (a ``Run``, layout checked on opening, checksums on every
read), ``verify`` (every chunk of every dataset), ``common_config`` and
``has_integrity_record``."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import h5py
import numpy as np

from tiltpile.store.digest import _attrs_digest, _digest_frame
from tiltpile.store.errors import MixedConfigError, RunFileError
from tiltpile.store.files import part_path
from tiltpile.store.layout import (ATTRS_DIGEST, FRAME_ARRAYS, FRAME_SCALARS, INTEGRITY, LAYOUT,
                                   OPTIONAL)


class Run:
    """Read-only view of a complete run file (``open_run``). Frame arrays are read on demand.

    Opening checks the layout (``RunFileError`` naming the file and the dataset for a missing
    dataset or inconsistent shapes); every read checks the data's checksums, and a damaged
    chunk raises ``RunFileError`` naming the file and the dataset."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.exists():
            hint = " (an incomplete .part file exists)" if part_path(self.path).exists() else ""
            raise RunFileError(f"no run file {self.path}{hint}")
        try:
            self.f = h5py.File(self.path, "r")
        except OSError as e:
            raise RunFileError(f"{self.path}: not a readable HDF5 file ({e})") from None
        try:
            self._load()
        except BaseException:
            self.f.close()
            raise

    def _load(self) -> None:
        a = self.f.attrs
        if "config" not in a or "frames" not in self.f:
            raise RunFileError(f"{self.path}: not a tiltpile run file")
        problems = _layout_problems(self.f)
        if problems:
            raise RunFileError(f"{self.path}: {problems[0]}")
        try:
            self.seed = int(a["seed"])
            self.config = json.loads(a["config"])
            self.config_hash = str(a.get("config_hash", ""))
            self.box_length = float(a["box_length"])
            self.tiltpile_version = str(a["tiltpile_version"])
        except (KeyError, ValueError, TypeError) as e:
            raise RunFileError(f"{self.path}: damaged root attributes ({e})") from None
        self.integrity = str(a.get("integrity", "")) or None
        # SHA-256 over the attributes (complete files with an integrity record; else None)
        self.attrs_digest = str(a[ATTRS_DIGEST]) if ATTRS_DIGEST in a else None
        self.radius = self._read("particles/radius")
        self.fixed = self._read("particles/fixed")
        fr = self.f["frames"]
        self.n_frames = int(fr["step"].shape[0])
        for name in FRAME_SCALARS:
            key = f"frames/{name}"
            setattr(self, name, self._read(key) if name in fr else np.full(self.n_frames, np.nan))
        self.offset = self._read("contacts/offset")
        dep = self.f.get("deposition")
        self.deposition = dict(dep.attrs) if dep is not None else {}
        prep = self.f.get("preparation")
        self.preparation = {k: np.asarray(v) for k, v in prep.attrs.items()} if prep is not None else {}
        self.end_reason = str(a.get("end_reason", "theta_max"))  # files before the end-of-run rule
        self.end_theta_deg = float(a["end_theta_deg"]) if "end_theta_deg" in a else None
        # the run's solver work (files before it was counted: absent)
        self.cost = {k: int(a[k]) for k in ("steps", "sweeps", "capped_steps") if k in a}
        if "seconds" in a:  # wall time of the invocation that finished it
            self.cost.update(seconds=float(a["seconds"]), resumed_from_frame=int(a["resumed_from_frame"]))
        if "wall_seconds" in a:  # summed over the invocations (files before it: absent)
            self.cost.update(wall_seconds=float(a["wall_seconds"]),
                             wall_seconds_whole=bool(a["wall_seconds_whole"]))
        h = self.f.get("health")
        self.health = {k: json.loads(v) if k == "warnings" else v
                       for k, v in (h.attrs.items() if h is not None else ())}

    def _read(self, name: str, sel=()):
        """``self.f[name][sel]``; a read failing its checksum is a RunFileError naming both."""
        try:
            return self.f[name][sel]
        except OSError as e:
            raise RunFileError(f"{self.path}: dataset {name} is damaged ({e}); the file cannot be "
                               "used (`tiltpile verify` checks every dataset)") from None

    def _check(self, k: int) -> int:
        if not -self.n_frames <= k < self.n_frames:
            raise IndexError(f"frame {k} out of range: the run has {self.n_frames} frames")
        return k % self.n_frames

    def position(self, k: int) -> np.ndarray:
        return self._read("frames/position", self._check(k))

    def rotation(self, k: int) -> np.ndarray:
        return self._read("frames/rotation", self._check(k))

    def velocity(self, k: int) -> np.ndarray:
        return self._read("frames/velocity", self._check(k))

    def omega(self, k: int) -> np.ndarray:
        return self._read("frames/omega", self._check(k))

    def contacts(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pair (C_k, 2) int32, force (C_k, 2) [f_n, f_t], status (C_k,) int8) of frame k."""
        k = self._check(k)
        a, b = int(self.offset[k]), int(self.offset[k + 1])
        return (self._read("contacts/pair", slice(a, b)), self._read("contacts/force", slice(a, b)),
                self._read("contacts/status", slice(a, b)))

    def frames_digest(self) -> str:
        """SHA-256 (hex) over every frame and its contact rows, in order, as stored: the digest a
        writer's checkpoint carries (``frames_digest``), computed from the finished file, so that
        a copy of some of its numbers can be traced to it. Reads the whole file (checksums
        checked). In files written before ``frames/energy_gain`` it covers the NaN read in its
        place."""
        h = hashlib.sha256()
        scalars = {name: getattr(self, name) for name in FRAME_SCALARS}
        for k in range(self.n_frames):
            arrays = {name: self._read(f"frames/{name}", k) for name in FRAME_ARRAYS}
            pair, force, status = self.contacts(k)
            sets = {"pair": pair, "force": force, "status": status}
            _digest_frame(h, lambda name: scalars[name][k] if name in scalars
                          else arrays[name] if name in arrays else sets[name])
        return h.hexdigest()

    def close(self) -> None:
        self.f.close()

    def __enter__(self) -> Run:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_run(path: str | Path) -> Run:
    """Open a complete run file for reading (use as a context manager)."""
    return Run(path)


def _layout_problems(f) -> list[str]:
    """What is wrong with the layout of an open run file (cheap: shapes and attrs, no data)."""
    problems = []
    for name in LAYOUT:
        if name not in f:
            if name not in OPTIONAL:
                problems.append(f"dataset {name} is missing")
            continue
        if not isinstance(f[name], h5py.Dataset):
            problems.append(f"{name} is not a dataset")
    if problems:
        return problems
    n_frames = f["frames/step"].shape[0]
    n = f["particles/radius"].shape[0]
    for name in LAYOUT:
        if name not in f:
            continue
        shape = f[name].shape
        if name.startswith("frames/") and shape[:1] != (n_frames,):
            problems.append(f"dataset {name} has {shape[0] if shape else 0} frames, frames/step {n_frames}")
        if name in ("frames/position", "frames/velocity") and shape[1:] != (n, 2):
            problems.append(f"dataset {name} has shape {shape}, expected ({n_frames}, {n}, 2)")
        if name in ("frames/rotation", "frames/omega", "particles/fixed") and shape[-1:] != (n,):
            problems.append(f"dataset {name} has shape {shape}, expected {n} grains")
    n_contacts = f["contacts/pair"].shape[0]
    if f["contacts/offset"].shape != (n_frames + 1,):
        problems.append(f"dataset contacts/offset has {f['contacts/offset'].shape[0]} rows, "
                        f"expected {n_frames + 1} (frames + 1)")
    for name in ("contacts/force", "contacts/status"):
        if f[name].shape[0] != n_contacts:
            problems.append(f"dataset {name} has {f[name].shape[0]} rows, contacts/pair {n_contacts}")
    if not problems and not bool(f.attrs.get("complete", False)):
        problems.append("the run is not marked complete")
    if f.attrs.get("integrity") == INTEGRITY:
        for name in LAYOUT:
            if name in f and not f[name].fletcher32:
                problems.append(f"dataset {name} has no checksum (the file says every dataset has one)")
            elif name in f and f[name].attrs.get("units") != LAYOUT[name][0]:
                problems.append(f"dataset {name} has units {f[name].attrs.get('units')!r}, "
                                f"expected {LAYOUT[name][0]!r}")
    return problems


def common_config(files, expected_hash: str | None = None) -> tuple[str, dict]:
    """(config_hash, config) shared by the run files ``files`` (opened, layout checked);
    ``RunFileError`` naming the odd files if they hold more than one configuration, or another
    than ``expected_hash`` (an ensemble manifest's)."""
    by_hash: dict[str, list[Path]] = {}
    configs = {}
    for path in files:
        with open_run(path) as run:
            by_hash.setdefault(run.config_hash, []).append(Path(path))
            configs[run.config_hash] = run.config
    if not by_hash:
        raise RunFileError("no run files")
    if expected_hash is not None:
        main = expected_hash
    else:  # the configuration most files hold; ties to the first file's
        main = sorted(by_hash, key=lambda h: (-len(by_hash[h]), str(min(by_hash[h]))))[0]
    odd = sorted(p for h, ps in by_hash.items() if h != main for p in ps)
    if odd:
        names = ", ".join(p.name for p in odd[:5]) + (f" and {len(odd) - 5} more" if len(odd) > 5 else "")
        raise MixedConfigError(
            f"{odd[0].parent}: {names} {'is a run' if len(odd) == 1 else 'are runs'} of another "
            f"configuration than the {'ensemble manifest' if expected_hash else 'other runs'} "
            f"(hash {main[:12]}); move {'it' if len(odd) == 1 else 'them'} away: one directory "
            "holds one configuration")
    return main, configs.get(main, {})


def has_integrity_record(path: str | Path) -> bool:
    """Whether a run file carries checksums on every dataset (written by this version or later)."""
    with h5py.File(path, "r") as f:
        return f.attrs.get("integrity") == INTEGRITY


def verify(path: str | Path, block_bytes: int = 1 << 26) -> list[str]:
    """Check a run file completely: its layout, and every chunk of every dataset against its
    checksum (reads the whole file). Returns the problems, one line each naming the dataset
    (empty: the file is sound). A file without an integrity record (written before it existed)
    is checked for layout and readability only: ``has_integrity_record`` tells them apart."""
    path = Path(path)
    if not path.exists():
        hint = " (an incomplete .part file exists)" if part_path(path).exists() else ""
        return [f"no run file {path}{hint}"]
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        return [f"not a readable HDF5 file ({e})"]
    with f:
        if "config" not in f.attrs or "frames" not in f:
            return ["not a tiltpile run file"]
        problems = _layout_problems(f)
        names = []
        f.visititems(lambda name, obj: names.append(name) if isinstance(obj, h5py.Dataset) else None)
        for name in sorted(names):
            ds = f[name]
            if ds.shape is None or ds.size == 0:
                continue
            row = max(1, ds.size // max(1, ds.shape[0]) * ds.dtype.itemsize) if ds.ndim else 1
            step = max(1, block_bytes // row)
            try:
                if ds.ndim == 0:
                    ds[()]
                else:
                    for a in range(0, ds.shape[0], step):
                        ds[a:a + step]
            except OSError as e:
                problems.append(f"dataset {name} is damaged ({e})")
        if ATTRS_DIGEST in f.attrs and str(f.attrs[ATTRS_DIGEST]) != _attrs_digest(f):
            problems.append("the attributes (configuration, seed, deposition, health, ...) changed "
                            f"since the run was written ({ATTRS_DIGEST} does not match)")
        if "offset" in f.get("contacts", {}) and not problems:
            off = f["contacts/offset"][()]
            if off[0] != 0 or np.any(np.diff(off) < 0) or off[-1] != f["contacts/pair"].shape[0]:
                problems.append("dataset contacts/offset does not index contacts/pair")
    return problems
