"""A frozen copy of src/tiltpile/store/writer.py as of fb26164, the last writer before the frame
log: it writes NAME.part as HDF5, appending in place. Tests use it to make the .part and .ckpt
files the runs in progress when the frame log came had, and resume them with today's writer."""

# ruff: noqa

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import time
from pathlib import Path

import h5py
import numpy as np

import tiltpile
from tiltpile.store.digest import _attrs_digest, _digest_frame
from tiltpile.store.errors import RunBusyError, RunFileError, RunWriteError
from tiltpile.store.files import (_describe_os_error, _fsync, acquire_lock, checkpoint_path,
                                  is_write_failure, part_path, release_lock, write_error)
from tiltpile.store.layout import (ATTRS_DIGEST, CONTACT_SETS, FILTERS, FRAME_ARRAYS,
                                   FRAME_SCALARS, INTEGRITY, LAYOUT, RESERVE_BYTES)

_BROKEN: list = []  # HDF5 files whose writes failed: never closed (closing them crashes HDF5)


def _create(group, name: str, **kw):
    """A chunked dataset with the run file's filters and its ``units`` / ``description`` attrs."""
    kw.setdefault("chunks", True)
    ds = group.create_dataset(name, **kw, **FILTERS)
    units, description = LAYOUT[f"{group.name.strip('/')}/{name}"]
    ds.attrs["units"] = units
    ds.attrs["description"] = description
    return ds

class RunWriter:
    """Append frames and checkpoints to ``NAME.part``; ``finish`` renames it to ``NAME``."""

    def __init__(self, path: str | Path, *, config_json: str, config_hash: str, seed: int,
                 radius: np.ndarray, fixed: np.ndarray, box_length: float, jit: dict):
        self.path = Path(path)
        self.part = part_path(self.path)
        self.ckpt = checkpoint_path(self.path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise RunWriteError(f"cannot write {self.path}: {_describe_os_error(e)}") from None
        acquire_lock(self.path)  # before anything is opened or truncated
        self._locked = True
        self._interval_bytes = self._max_interval = 0
        self._start_clock(0.0, True)
        try:
            self._check_space()
            self._create_file(config_json, config_hash, seed, radius, fixed, box_length, jit)
        except BaseException:
            self.close()
            raise

    def _create_file(self, config_json, config_hash, seed, radius, fixed, box_length, jit) -> None:
        self.f = None
        if self.part.exists():  # a writer without our lock (an older tiltpile) holds HDF5's own lock
            try:
                h5py.File(self.part, "r").close()
            except OSError as e:
                if "lock" in str(e).lower():
                    raise RunBusyError(
                        f"{self.part} is being written by another process (it holds the file's HDF5 "
                        "lock); wait for it to finish or use another output file (nothing was "
                        "changed)") from None
        f = self.f = h5py.File(self.part, "w")
        # a checkpoint left by an earlier .part is not this one's (the digest would refuse it too)
        self.ckpt.unlink(missing_ok=True)
        self._remove_temporaries()
        self.digest = hashlib.sha256()
        f.attrs.update(tiltpile_version=tiltpile.__version__, seed=int(seed), config=config_json,
                       config_hash=config_hash, box_length=float(box_length), jit=json.dumps(jit),
                       complete=False, integrity=INTEGRITY)
        n = radius.shape[0]
        g = f.create_group("particles")
        _create(g, "radius", data=np.asarray(radius, np.float64))
        _create(g, "fixed", data=np.asarray(fixed, np.bool_))
        fr = f.create_group("frames")
        for name, dt in FRAME_SCALARS.items():
            _create(fr, name, shape=(0,), dtype=dt, maxshape=(None,), chunks=(1024,))
        for name, shape in zip(FRAME_ARRAYS, ((n, 2), (n, 2), (n,), (n,))):
            _create(fr, name, shape=(0, *shape), dtype=np.float64, maxshape=(None, *shape),
                    chunks=(1, *shape))
        c = f.create_group("contacts")
        _create(c, "offset", data=np.zeros(1, np.int64), maxshape=(None,), chunks=(1024,))
        for name, (dt, shape) in CONTACT_SETS.items():
            _create(c, name, shape=(0, *shape), dtype=dt, maxshape=(None, *shape),
                    chunks=(16384, *shape))

    @property
    def n_frames(self) -> int:
        return self._d("frames/step").shape[0]

    def _d(self, name: str):
        """Dataset ``name``, opened once and kept: an h5py Dataset dropped after a failed write
        (a full disk) crashes HDF5 when it is deallocated, so the writer creates none on the fly."""
        cache = self.__dict__.setdefault("_datasets", {})
        if name not in cache:
            cache[name] = self.f[name]
        return cache[name]

    def _failed(self, e: BaseException) -> RunWriteError:
        """After a failed write: keep the file and its datasets alive, never closed (closing or
        deallocating them crashes HDF5), and return the one-line error to raise."""
        self._broken = True
        _BROKEN.append(self)
        return write_error(e, self.part)

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
        """How the tilt ended and what the run cost (``protocol.Ended``): root attrs end_reason,
        end_theta_deg, steps, sweeps, capped_steps."""
        self.f.attrs.update(end_reason=str(ended.reason), end_theta_deg=float(ended.theta_deg),
                            steps=int(ended.steps), sweeps=int(ended.sweeps),
                            capped_steps=int(ended.capped_steps))

    def _start_clock(self, before: float, whole: bool) -> None:
        """Count this invocation's wall time on top of ``before`` seconds, those of the earlier
        invocations up to their last checkpoints (``whole``: all of them were counted)."""
        self._wall_before, self._wall_whole, self._wall_t0 = float(before), bool(whole), time.perf_counter()

    def wall_seconds(self, now: float | None = None) -> float:
        """The run's wall time at ``now`` (``time.perf_counter()``; None: this moment): the
        earlier invocations' up to their last checkpoints (the work an interruption loses is done
        again, and counted, by the next one) plus this invocation's."""
        return self._wall_before + ((time.perf_counter() if now is None else now) - self._wall_t0)

    def write_timing(self, t0: float, resumed_from_frame: int | None) -> None:
        """Wall seconds of the invocation that finished the run since ``t0`` (its
        ``time.perf_counter()`` at the start; root attr ``seconds``), the frame it resumed from if
        it resumed an interrupted one (``resumed_from_frame``, else -1), and the run's wall time
        summed over its invocations (``wall_seconds``; ``wall_seconds_whole`` false when an
        invocation before this accounting existed went uncounted). Both are read off one clock
        reading, so a run of one invocation, whose writer starts its clock after ``t0``, never
        has a sum above its ``seconds``."""
        now = time.perf_counter()
        self.f.attrs.update(seconds=float(now - t0),
                            resumed_from_frame=-1 if resumed_from_frame is None else int(resumed_from_frame),
                            wall_seconds=float(self.wall_seconds(now)),
                            wall_seconds_whole=bool(self._wall_whole))

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

    def _check_space(self) -> None:
        """RunWriteError while the file can still be closed whole (``RESERVE_BYTES``)."""
        try:
            st = os.statvfs(self.part.parent)
        except OSError:
            return
        free = st.f_bavail * st.f_frsize
        need = RESERVE_BYTES + 2 * max(getattr(self, "_max_interval", 0), getattr(self, "_interval_bytes", 0))
        if free < need:
            raise RunWriteError(
                f"no space left on device while writing {self.part} ({free / 1e6:.1f} MB free; a run "
                f"stops below {need / 1e6:.1f} MB so that its file stays whole); rerun to resume")

    def append(self, frame) -> None:
        """Append one ``protocol.Frame``."""
        self._check_space()
        self._interval_bytes = getattr(self, "_interval_bytes", 0) + sum(
            np.asarray(getattr(frame, name)).nbytes for name in (*FRAME_ARRAYS, *CONTACT_SETS)) + 200
        k = self.n_frames
        _digest_frame(self.digest, lambda name: getattr(frame, name))
        try:
            for name in FRAME_SCALARS:
                ds = self._d(f"frames/{name}")
                ds.resize((k + 1,))
                ds[k] = getattr(frame, name)
            for name in FRAME_ARRAYS:
                ds = self._d(f"frames/{name}")
                ds.resize((k + 1, *ds.shape[1:]))
                ds[k] = getattr(frame, name)
            off = self._d("contacts/offset")
            start = int(off[k])
            m = frame.pair.shape[0]
            for name in CONTACT_SETS:
                ds = self._d(f"contacts/{name}")
                ds.resize((start + m, *ds.shape[1:]))
                ds[start:] = getattr(frame, name)
            off.resize((k + 2,))
            off[k + 1] = start + m
        except (OSError, RuntimeError) as e:
            if not is_write_failure(e):
                raise
            raise self._failed(e) from None

    def checkpoint(self, state: dict) -> None:
        """Store the simulator state as of the frames written so far (``NAME.ckpt``, atomically).

        The frames go to disk first; the checkpoint file is then written under a temporary name,
        synced and renamed over the previous one (the package docstring).
        """
        self._check_space()
        self._max_interval = max(getattr(self, "_max_interval", 0), getattr(self, "_interval_bytes", 0))
        self._interval_bytes = 0
        try:
            self.f.flush()
        except (OSError, RuntimeError) as e:
            if not is_write_failure(e):
                raise
            raise self._failed(e) from None
        _fsync(self.part)
        tmp = self.ckpt.with_name(f".{self.ckpt.name}.tmp{os.getpid()}")
        g = None
        try:
            g = h5py.File(tmp, "w")
            for key, value in state.items():
                if key == "scalars":
                    g.attrs["scalars"] = json.dumps(value)
                else:
                    g.create_dataset(key, data=value)
            g.attrs.update(n_frames=self.n_frames, config_hash=self.f.attrs["config_hash"],
                           seed=int(self.f.attrs["seed"]), frames_digest=self.digest.hexdigest(),
                           wall_seconds=self.wall_seconds(), wall_seconds_whole=self._wall_whole)
            g.close()
            _fsync(tmp)
        except BaseException as e:
            if g is not None and g.id.valid:
                try:
                    g.close()
                except (OSError, RuntimeError):
                    _BROKEN.append(g)  # never closed again (like the file itself)
            tmp.unlink(missing_ok=True)
            if isinstance(e, (OSError, RuntimeError)) and is_write_failure(e) and not isinstance(e, RunFileError):
                raise write_error(e, tmp) from None
            raise
        os.replace(tmp, self.ckpt)

    def finish(self) -> Path:
        """Mark the file complete, sync it and rename it to ``NAME`` (replacing an older run
        file only now, when the new one is whole); then drop the checkpoint and the lock."""
        try:
            self.f.attrs["complete"] = True
            self.f.attrs[ATTRS_DIGEST] = _attrs_digest(self.f)
            self.__dict__.pop("_datasets", None)
            self.f.close()
        except (OSError, RuntimeError) as e:
            if not is_write_failure(e):
                raise
            raise self._failed(e) from None
        _fsync(self.part)
        os.replace(self.part, self.path)
        self.ckpt.unlink(missing_ok=True)  # a kill before this leaves it: remove_stale_checkpoint
        self._remove_temporaries()
        self._unlock()
        return self.path

    def _unlock(self) -> None:
        if getattr(self, "_locked", False):
            self._locked = False
            release_lock(self.path)

    def _remove_temporaries(self) -> None:
        """Checkpoint files a killed process left half-written under their temporary names."""
        for tmp in self.ckpt.parent.glob(f".{self.ckpt.name}.tmp*"):
            tmp.unlink(missing_ok=True)

    def close(self) -> None:
        """Close without completing (the .part file stays for a resume); never raises for a
        file that cannot be flushed any more (a full disk): the resume checks what is on disk."""
        try:
            f = getattr(self, "f", None)
            if getattr(self, "_broken", False):
                f = None  # a file whose writes failed is never closed: HDF5 would crash
            else:
                self.__dict__.pop("_datasets", None)
            if f is not None and f.id.valid:
                try:
                    f.close()
                except (OSError, RuntimeError, ValueError):
                    _BROKEN.append(f)  # closing again (or deallocating it) crashes HDF5
        finally:
            self._remove_temporaries()
            self._unlock()

    @classmethod
    def resume(cls, path: str | Path, config_hash: str,
               why: list | None = None) -> tuple[RunWriter, dict] | None:
        """Reopen ``NAME.part`` at its last checkpoint; None if there is nothing usable to resume.

        Frames and contacts written after the checkpoint are truncated: the simulation redoes
        them exactly. A ``.part`` without its ``NAME.ckpt``, of another configuration or seed,
        one that cannot be read (a process killed while writing), or whose frames up to the
        checkpoint differ from what was written (``frames_digest``) is not resumed; the caller
        then starts afresh, which removes both files.
        """
        part = part_path(path)
        if not part.exists():
            return None
        acquire_lock(path)  # RunBusyError while another process writes it
        try:
            out = cls._resume(path, config_hash)
        except BaseException:
            release_lock(path)
            raise
        if isinstance(out, str):
            release_lock(path)
            if why is not None:
                why.append(out)
            return None
        writer, state = out
        writer._locked = True
        return writer, state

    @classmethod
    def _resume(cls, path, config_hash: str) -> tuple[RunWriter, dict] | str:
        """``resume`` under the lock: the writer and state, or why the .part cannot be resumed."""
        part, ckpt = part_path(path), checkpoint_path(path)
        if not part.exists():
            return "it is gone"
        if not ckpt.exists():
            return f"it has no checkpoint ({ckpt.name})"
        try:
            with h5py.File(ckpt, "r") as g:
                if g.attrs.get("config_hash") != config_hash:
                    return (f"it is a run of another configuration (hash "
                            f"{str(g.attrs.get('config_hash'))[:12]}, this one {config_hash[:12]})")
                state = {k: g[k][()] for k in g}
                state["scalars"] = json.loads(g.attrs["scalars"])
                k = int(g.attrs["n_frames"])
                digest = str(g.attrs["frames_digest"])
                seed = int(g.attrs["seed"])
                # checkpoints written before the wall time was summed lack it: counted from here
                wall = (float(g.attrs["wall_seconds"]), bool(g.attrs["wall_seconds_whole"])) \
                    if "wall_seconds" in g.attrs else (0.0, False)
        except (OSError, RuntimeError, KeyError, ValueError):
            return f"its checkpoint {ckpt.name} cannot be read"
        try:
            f = h5py.File(part, "r+")
        except (OSError, RuntimeError):
            return "it cannot be read"
        try:
            fr, c = f["frames"], f["contacts"]
            if f.attrs.get("config_hash") != config_hash or int(f.attrs["seed"]) != seed:
                f.close()
                return "it is a run of another configuration or seed than its checkpoint"
            if fr["step"].shape[0] < k or c["offset"].shape[0] < k + 1:
                f.close()
                return "it holds fewer frames than its checkpoint follows"
            # the frames the checkpoint follows must be on disk exactly as they were written
            h = hashlib.sha256()
            off = c["offset"][: k + 1]
            for i in range(k):
                a, b = int(off[i]), int(off[i + 1])
                _digest_frame(h, lambda name: c[name][a:b] if name in CONTACT_SETS else fr[name][i])
            if h.hexdigest() != digest:
                f.close()
                return "its frames differ from those its checkpoint follows"
            for name in fr:
                fr[name].resize((k, *fr[name].shape[1:]))
            c["offset"].resize((k + 1,))
            end = int(off[k])
            for name in CONTACT_SETS:
                c[name].resize((end, *c[name].shape[1:]))
        except (OSError, RuntimeError, KeyError, ValueError):
            with contextlib.suppress(Exception):
                f.close()
            return "its frames cannot be read back"
        writer = cls.__new__(cls)  # reopened, not created: skip __init__'s layout
        writer.path, writer.part, writer.ckpt, writer.f = Path(path), part, ckpt, f
        writer.digest = h
        writer._start_clock(*wall)
        return writer, state
