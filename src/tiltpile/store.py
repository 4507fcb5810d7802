"""The run file: one HDF5 file per run. The only module that knows the layout.

Layout (F frames, N grains including the fixed bottom row, C contacts over all frames)::

    /                     attrs: tiltpile_version, seed, config (JSON text), config_hash,
                                 box_length, jit (JSON text: numba flags), complete (bool)
    /particles/radius     (N,)      float64  [d]
    /particles/fixed      (N,)      bool     grains of the rough bottom row
    /frames/step          (F,)      int64    global step (deposition steps included)
    /frames/time          (F,)      float64  [sqrt(d/g)]
    /frames/theta_deg     (F,)      float64  inclination of the box
    /frames/position      (F, N, 2) float64  [d], box frame (x along the floor, y up)
    /frames/rotation      (F, N)    float64  [rad]
    /frames/velocity      (F, N, 2) float64  [sqrt(g d)]
    /frames/omega         (F, N)    float64  [sqrt(g/d)]
    /frames/iterations    (F,)      int64    NLGS sweeps of the frame's step
    /frames/residual      (F,)      float64  final NLGS residual of the frame's step
    /frames/ke            (F,)      float64  kinetic energy of the mobile grains [m g d]
    /frames/max_overlap   (F,)      float64  largest overlap since the previous frame [d]
    /frames/max_iterations(F,)      int64    most sweeps in a step since the previous frame
    /frames/cap_hits      (F,)      int64    steps since the previous frame that hit max_iter
    /frames/missed        (F,)      int64    steps where a grain outran the alert distance
    /frames/energy_gain   (F,)      float64  largest per-step gain of kinetic energy beyond the work
                                             of gravity since the previous frame [m g d]; <= 0 up
                                             to solver error (contacts only dissipate)
    /contacts/offset      (F+1,)    int64    contacts of frame k are rows offset[k]:offset[k+1]
    /contacts/pair        (C, 2)    int32    grain ids (i < j); walls: -1 floor, -2 left (x = 0),
                                             -3 right (x = L)
    /contacts/force       (C, 2)    float64  normal, tangential force = impulse / dt [m g]
    /contacts/status      (C,)      int8     0 open (touching, no force), 1 sticking,
                                             2 sliding (fully mobilized, |f_t| = mu f_n)
    /deposition           attrs: steps, time, ke_per_grain, height, max_overlap, missed
    /preparation          attrs (only with protocol.pretilt_deg): target_deg, tilt_steps,
                          hold_steps, ke_per_grain, one entry per leg
    / attrs end_reason, end_theta_deg: "theta_max" or "slide" (protocol.end_ke), last frame's angle
    /health               attrs (complete runs): the health summary of ``runner.simulate`` --
                          counts of flagged frames and steps, worst values, and ``warnings``
                          (JSON list of the warning texts, empty when healthy)

The file is written as ``NAME.part`` and renamed to ``NAME`` when complete, so a file with the
final name is always whole. An interrupted ``.part`` file resumes from its checkpoint
(``RunWriter.resume``): frames past the checkpoint are dropped and recomputed.

Checkpoints live in their own file, ``NAME.ckpt`` (HDF5: the simulator's full state as datasets,
attrs ``scalars`` (JSON), ``n_frames``, ``config_hash``, ``seed`` and ``frames_digest``), written
to a temporary name, synced and renamed, so a process killed at any moment leaves either the old
checkpoint or the new one, never a mixture. (It used to be a group inside the ``.part`` file,
deleted and rewritten at every checkpoint. HDF5 is not crash-safe: the new state's data could
land in the space the old one freed while the file's last flushed metadata still described the
old one, so a run killed during a checkpoint could resume from a state mixing two times and end
differently -- seen once in ``test_sigkill_then_rerun_is_bit_identical``.) The ``.part`` file is
flushed and synced before the checkpoint names its frame count; ``frames_digest`` (SHA-256 over
every frame and contact row written up to the checkpoint, in order) is checked on resume, so a
``.part`` file that lost or changed frames in a crash is started afresh rather than resumed.

Files written before a column existed (``frames/energy_gain``, ``/health``) still open: the
reader fills a missing per-frame column with NaN and ``Run.health`` is then empty.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import h5py
import numpy as np

import tiltpile

FRAME_SCALARS = {"step": np.int64, "time": np.float64, "theta_deg": np.float64,
                 "iterations": np.int64, "residual": np.float64, "ke": np.float64,
                 "max_overlap": np.float64, "max_iterations": np.int64, "cap_hits": np.int64,
                 "missed": np.int64, "energy_gain": np.float64}
FRAME_ARRAYS = ("position", "velocity", "rotation", "omega")  # per grain, float64
CONTACT_SETS = {"pair": (np.int32, (2,)), "force": (np.float64, (2,)), "status": (np.int8, ())}


class RunFileError(RuntimeError):
    """A run file is missing, incomplete or not a tiltpile run."""


def part_path(path: str | Path) -> Path:
    path = Path(path)
    return path.with_name(path.name + ".part")


def checkpoint_path(path: str | Path) -> Path:
    path = Path(path)
    return path.with_name(path.name + ".ckpt")


def _fsync(path: Path) -> None:
    """Push a file's written data to the disk (survives a reboot, not only a killed process)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _digest_frame(h, get) -> None:
    """Feed one frame, as stored (dataset dtypes), to the hash ``h`` in a fixed order;
    ``get(name)`` gives its value for each name of FRAME_SCALARS, FRAME_ARRAYS and CONTACT_SETS."""
    for name, dt in FRAME_SCALARS.items():
        h.update(np.asarray(get(name), dt).tobytes())
    for name in FRAME_ARRAYS:
        h.update(np.ascontiguousarray(get(name), np.float64).tobytes())
    h.update(np.int64(get("pair").shape[0]).tobytes())
    for name, (dt, _) in CONTACT_SETS.items():
        h.update(np.ascontiguousarray(get(name), dt).tobytes())


class RunWriter:
    """Append frames and checkpoints to ``NAME.part``; ``finish`` renames it to ``NAME``."""

    def __init__(self, path: str | Path, *, config_json: str, config_hash: str, seed: int,
                 radius: np.ndarray, fixed: np.ndarray, box_length: float, jit: dict):
        self.path = Path(path)
        self.part = part_path(self.path)
        self.ckpt = checkpoint_path(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        f = self.f = h5py.File(self.part, "w")  # fails here if another process holds the .part
        # a checkpoint left by an earlier .part is not this one's (the digest would refuse it too)
        self.ckpt.unlink(missing_ok=True)
        self._remove_temporaries()
        self.digest = hashlib.sha256()
        f.attrs.update(tiltpile_version=tiltpile.__version__, seed=int(seed), config=config_json,
                       config_hash=config_hash, box_length=float(box_length), jit=json.dumps(jit),
                       complete=False)
        n = radius.shape[0]
        g = f.create_group("particles")
        g["radius"] = np.asarray(radius, np.float64)
        g["fixed"] = np.asarray(fixed, np.bool_)
        fr = f.create_group("frames")
        for name, dt in FRAME_SCALARS.items():
            fr.create_dataset(name, (0,), dtype=dt, maxshape=(None,), chunks=(1024,))
        for name, shape in zip(FRAME_ARRAYS, ((n, 2), (n, 2), (n,), (n,))):
            fr.create_dataset(name, (0, *shape), dtype=np.float64, maxshape=(None, *shape),
                              chunks=(1, *shape))
        c = f.create_group("contacts")
        c.create_dataset("offset", data=np.zeros(1, np.int64), maxshape=(None,), chunks=(1024,))
        for name, (dt, shape) in CONTACT_SETS.items():
            c.create_dataset(name, (0, *shape), dtype=dt, maxshape=(None, *shape), chunks=(16384, *shape))

    @property
    def n_frames(self) -> int:
        return self.f["frames/step"].shape[0]

    @property
    def n_mobile(self) -> int:
        return int((~self.f["particles/fixed"][()]).sum())

    def write_deposition(self, summary) -> None:
        g = self.f.require_group("deposition")
        g.attrs.update(steps=int(summary.steps), time=float(summary.time),
                       ke_per_grain=float(summary.ke_per_grain), height=float(summary.height),
                       max_overlap=float(summary.max_overlap), missed=int(summary.missed))

    def write_preparation(self, legs: list[dict]) -> None:
        """The preparation history (``protocol.Prepared``): one entry per leg, as arrays."""
        g = self.f.require_group("preparation")
        for key in ("target_deg", "tilt_steps", "hold_steps", "ke_per_grain"):
            g.attrs[key] = np.array([leg[key] for leg in legs])

    def write_end(self, ended) -> None:
        """How the tilt ended (``protocol.Ended``): root attrs end_reason, end_theta_deg."""
        self.f.attrs.update(end_reason=str(ended.reason), end_theta_deg=float(ended.theta_deg))

    def frame_columns(self, names) -> dict:
        """Per-frame scalar columns written so far (e.g. for the health summary at the end)."""
        return {name: self.f["frames"][name][()] for name in names}

    def deposition_attrs(self) -> dict:
        dep = self.f.get("deposition")
        return dict(dep.attrs) if dep is not None else {}

    def write_health(self, summary: dict) -> None:
        """Store the health summary as attrs of ``/health`` (``warnings`` as JSON text)."""
        g = self.f.require_group("health")
        for key, value in summary.items():
            g.attrs[key] = json.dumps(value) if isinstance(value, (list, dict)) else value

    def append(self, frame) -> None:
        """Append one ``protocol.Frame``."""
        fr, c = self.f["frames"], self.f["contacts"]
        k = self.n_frames
        _digest_frame(self.digest, lambda name: getattr(frame, name))
        for name in FRAME_SCALARS:
            ds = fr[name]
            ds.resize((k + 1,))
            ds[k] = getattr(frame, name)
        for name in FRAME_ARRAYS:
            ds = fr[name]
            ds.resize((k + 1, *ds.shape[1:]))
            ds[k] = getattr(frame, name)
        off = c["offset"]
        start = int(off[k])
        m = frame.pair.shape[0]
        for name in CONTACT_SETS:
            ds = c[name]
            ds.resize((start + m, *ds.shape[1:]))
            ds[start:] = getattr(frame, name)
        off.resize((k + 2,))
        off[k + 1] = start + m

    def checkpoint(self, state: dict) -> None:
        """Store the simulator state as of the frames written so far (``NAME.ckpt``, atomically).

        The frames go to disk first; the checkpoint file is then written under a temporary name,
        synced and renamed over the previous one (module docstring).
        """
        self.f.flush()
        _fsync(self.part)
        tmp = self.ckpt.with_name(f".{self.ckpt.name}.tmp{os.getpid()}")
        with h5py.File(tmp, "w") as g:
            for key, value in state.items():
                if key == "scalars":
                    g.attrs["scalars"] = json.dumps(value)
                else:
                    g.create_dataset(key, data=value)
            g.attrs.update(n_frames=self.n_frames, config_hash=self.f.attrs["config_hash"],
                           seed=int(self.f.attrs["seed"]), frames_digest=self.digest.hexdigest())
        _fsync(tmp)
        os.replace(tmp, self.ckpt)

    def finish(self) -> Path:
        self.f.attrs["complete"] = True
        self.f.close()
        os.replace(self.part, self.path)
        self.ckpt.unlink(missing_ok=True)
        self._remove_temporaries()
        return self.path

    def _remove_temporaries(self) -> None:
        """Checkpoint files a killed process left half-written under their temporary names."""
        for tmp in self.ckpt.parent.glob(f".{self.ckpt.name}.tmp*"):
            tmp.unlink(missing_ok=True)

    def close(self) -> None:
        """Close without completing (the .part file stays for a resume)."""
        if self.f.id.valid:
            self.f.close()

    @classmethod
    def resume(cls, path: str | Path, config_hash: str) -> tuple[RunWriter, dict] | None:
        """Reopen ``NAME.part`` at its last checkpoint; None if there is nothing usable to resume.

        Frames and contacts written after the checkpoint are truncated: the simulation redoes
        them exactly. A ``.part`` without its ``NAME.ckpt``, of another configuration or seed,
        one that cannot be read (a process killed while writing), or whose frames up to the
        checkpoint differ from what was written (``frames_digest``) is not resumed; the caller
        then starts afresh, which removes both files.
        """
        part, ckpt = part_path(path), checkpoint_path(path)
        if not part.exists() or not ckpt.exists():
            return None
        try:
            with h5py.File(ckpt, "r") as g:
                if g.attrs.get("config_hash") != config_hash:
                    return None
                state = {k: g[k][()] for k in g}
                state["scalars"] = json.loads(g.attrs["scalars"])
                k = int(g.attrs["n_frames"])
                digest = str(g.attrs["frames_digest"])
                seed = int(g.attrs["seed"])
        except (OSError, RuntimeError, KeyError):
            return None
        try:
            f = h5py.File(part, "r+")
        except (OSError, RuntimeError):
            return None
        try:
            fr, c = f["frames"], f["contacts"]
            if (f.attrs.get("config_hash") != config_hash or int(f.attrs["seed"]) != seed
                    or fr["step"].shape[0] < k or c["offset"].shape[0] < k + 1):
                f.close()
                return None
            # the frames the checkpoint follows must be on disk exactly as they were written
            h = hashlib.sha256()
            off = c["offset"][: k + 1]
            for i in range(k):
                a, b = int(off[i]), int(off[i + 1])
                _digest_frame(h, lambda name: c[name][a:b] if name in CONTACT_SETS else fr[name][i])
            if h.hexdigest() != digest:
                f.close()
                return None
            for name in fr:
                fr[name].resize((k, *fr[name].shape[1:]))
            c["offset"].resize((k + 1,))
            end = int(off[k])
            for name in CONTACT_SETS:
                c[name].resize((end, *c[name].shape[1:]))
        except (OSError, RuntimeError, KeyError, ValueError):
            f.close()
            return None
        writer = cls.__new__(cls)  # reopened, not created: skip __init__'s layout
        writer.path, writer.part, writer.ckpt, writer.f = Path(path), part, ckpt, f
        writer.digest = h
        return writer, state


class Run:
    """Read-only view of a complete run file (``open_run``). Frame arrays are read on demand."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.exists():
            hint = " (an incomplete .part file exists)" if part_path(self.path).exists() else ""
            raise RunFileError(f"no run file {self.path}{hint}")
        try:
            self.f = h5py.File(self.path, "r")
        except OSError as e:
            raise RunFileError(f"{self.path}: not a readable HDF5 file ({e})") from None
        a = self.f.attrs
        if "config" not in a or "frames" not in self.f:
            self.f.close()
            raise RunFileError(f"{self.path}: not a tiltpile run file")
        self.seed = int(a["seed"])
        self.config = json.loads(a["config"])
        self.config_hash = str(a.get("config_hash", ""))
        self.box_length = float(a["box_length"])
        self.tiltpile_version = str(a["tiltpile_version"])
        self.radius = self.f["particles/radius"][()]
        self.fixed = self.f["particles/fixed"][()]
        fr = self.f["frames"]
        self.n_frames = int(fr["step"].shape[0])
        for name in FRAME_SCALARS:
            setattr(self, name, fr[name][()] if name in fr else np.full(self.n_frames, np.nan))
        self.offset = self.f["contacts/offset"][()]
        dep = self.f.get("deposition")
        self.deposition = dict(dep.attrs) if dep is not None else {}
        prep = self.f.get("preparation")
        self.preparation = {k: np.asarray(v) for k, v in prep.attrs.items()} if prep is not None else {}
        self.end_reason = str(a.get("end_reason", "theta_max"))  # files before the end-of-run rule
        h = self.f.get("health")
        self.health = {k: json.loads(v) if k == "warnings" else v
                       for k, v in (h.attrs.items() if h is not None else ())}

    def _check(self, k: int) -> int:
        if not -self.n_frames <= k < self.n_frames:
            raise IndexError(f"frame {k} out of range: the run has {self.n_frames} frames")
        return k % self.n_frames

    def position(self, k: int) -> np.ndarray:
        return self.f["frames/position"][self._check(k)]

    def rotation(self, k: int) -> np.ndarray:
        return self.f["frames/rotation"][self._check(k)]

    def velocity(self, k: int) -> np.ndarray:
        return self.f["frames/velocity"][self._check(k)]

    def omega(self, k: int) -> np.ndarray:
        return self.f["frames/omega"][self._check(k)]

    def contacts(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pair (C_k, 2) int32, force (C_k, 2) [f_n, f_t], status (C_k,) int8) of frame k."""
        k = self._check(k)
        a, b = int(self.offset[k]), int(self.offset[k + 1])
        c = self.f["contacts"]
        return c["pair"][a:b], c["force"][a:b], c["status"][a:b]

    def close(self) -> None:
        self.f.close()

    def __enter__(self) -> Run:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_run(path: str | Path) -> Run:
    """Open a complete run file for reading (use as a context manager)."""
    return Run(path)
