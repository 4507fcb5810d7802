"""Writing a run file: ``RunWriter`` appends frames and checkpoints to the frame log
``NAME.part``, resumes an interrupted one (also an HDF5 ``.part`` an older writer left) and, when
the run is complete, builds ``NAME`` from the log (the package docstring says how)."""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import shutil
import time
from pathlib import Path

import h5py
import numpy as np

import tiltpile
from tiltpile.store import framelog
from tiltpile.store.digest import _attrs_digest, _digest_frame
from tiltpile.store.errors import RunBusyError, RunFileError, RunWriteError
from tiltpile.store.files import (_describe_os_error, _fsync, acquire_lock, checkpoint_path,
                                  is_write_failure, part_path, release_lock, write_error)
from tiltpile.store.layout import (ATTRS_DIGEST, CONTACT_SETS, FILTERS, FRAME_ARRAYS,
                                   FRAME_SCALARS, INTEGRITY, LAYOUT, RESERVE_BYTES)

_BROKEN: list = []  # HDF5 files whose writes failed: never closed (closing them crashes HDF5)
# groups whose attributes a run writes before a checkpoint (the rest comes after the last one)
_LOGGED_GROUPS = ("deposition", "preparation")


def _create(group, name: str, **kw):
    """A chunked dataset with the run file's filters and its ``units`` / ``description`` attrs."""
    kw.setdefault("chunks", True)
    ds = group.create_dataset(name, **kw, **FILTERS)
    units, description = LAYOUT[f"{group.name.strip('/')}/{name}"]
    ds.attrs["units"] = units
    ds.attrs["description"] = description
    return ds


class _Builder:
    """The HDF5 run file, written by the same calls, in the same order, as the writer made before
    the frame log existed (one ``_Builder`` call per log record), so that the file is the same
    byte for byte: layout, chunks, filters and the place of every chunk."""

    def __init__(self, path: Path, head: framelog.Head):
        f = self.f = h5py.File(path, "w")
        self._datasets: dict = {}
        f.attrs.update(dict(head.attrs))
        n = head.n
        g = f.create_group("particles")
        _create(g, "radius", data=np.asarray(head.radius, np.float64))
        _create(g, "fixed", data=np.asarray(head.fixed, np.bool_))
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
        self.n_frames = 0

    def _d(self, name: str):
        """Dataset ``name``, opened once and kept: an h5py Dataset dropped after a failed write
        (a full disk) crashes HDF5 when it is deallocated, so none is created on the fly."""
        if name not in self._datasets:
            self._datasets[name] = self.f[name]
        return self._datasets[name]

    def attrs(self, group: str, items: list) -> None:
        g = self.f if group == "/" else self.f.require_group(group)
        for key, value in items:
            g.attrs[key] = value

    def append(self, frame: dict) -> None:
        k = self.n_frames
        for name in FRAME_SCALARS:
            ds = self._d(f"frames/{name}")
            ds.resize((k + 1,))
            ds[k] = frame[name]
        for name in FRAME_ARRAYS:
            ds = self._d(f"frames/{name}")
            ds.resize((k + 1, *ds.shape[1:]))
            ds[k] = frame[name]
        off = self._d("contacts/offset")
        start = int(off[k])
        m = frame["pair"].shape[0]
        for name in CONTACT_SETS:
            ds = self._d(f"contacts/{name}")
            ds.resize((start + m, *ds.shape[1:]))
            ds[start:] = frame[name]
        off.resize((k + 2,))
        off[k + 1] = start + m
        self.n_frames = k + 1

    def flush(self) -> None:
        self.f.flush()

    def close(self) -> None:
        self._datasets.clear()
        self.f.close()


class RunWriter:
    """Append frames and checkpoints to ``NAME.part``; ``finish`` builds ``NAME`` from it."""

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
        self.log = None
        self._interval_bytes = self._max_interval = 0
        self._start_clock(0.0, True)
        try:
            self._check_space()
            head = framelog.Head(
                n=int(radius.shape[0]),
                attrs=[("tiltpile_version", tiltpile.__version__), ("seed", int(seed)),
                       ("config", config_json), ("config_hash", config_hash),
                       ("box_length", float(box_length)), ("jit", json.dumps(jit)),
                       ("complete", False), ("integrity", INTEGRITY)],
                radius=np.asarray(radius, np.float64), fixed=np.asarray(fixed, np.bool_))
            self._create_log(head)
        except BaseException:
            self.close()
            raise

    def _init_state(self, head: framelog.Head) -> None:
        self.head = head
        self.config_hash = str(dict(head.attrs)["config_hash"])
        self.seed = int(dict(head.attrs)["seed"])
        self._n = 0
        self._columns = {name: [] for name in FRAME_SCALARS}
        self._groups: dict = {}
        self.digest = hashlib.sha256()

    def _create_log(self, head: framelog.Head) -> None:
        if self.part.exists() and not framelog.is_frame_log(self.part):
            # an HDF5 .part written by an older tiltpile, whose writer (without our lock) may
            # hold HDF5's own lock: never truncate it under that writer
            try:
                h5py.File(self.part, "r").close()
            except OSError as e:
                if "lock" in str(e).lower():
                    raise RunBusyError(
                        f"{self.part} is being written by another process (it holds the file's HDF5 "
                        "lock); wait for it to finish or use another output file (nothing was "
                        "changed)") from None
        # a checkpoint left by an earlier .part is not this one's (the digest would refuse it too)
        self.ckpt.unlink(missing_ok=True)
        self._remove_temporaries()
        self._init_state(head)
        try:
            self.log = framelog.LogWriter.create(self.part)
            self.log.record(b"HEAD", [framelog.head_payload(head.attrs, head.radius, head.fixed)])
        except OSError as e:
            raise write_error(e, self.part) from None

    @property
    def n_frames(self) -> int:
        return self._n

    @property
    def n_mobile(self) -> int:
        return int((~self.head.fixed).sum())

    def _log_attrs(self, group: str, items: list) -> None:
        """Append one ATTR record (the attributes of ``group``, "/" the root, in order)."""
        try:
            self.log.record(b"ATTR", [framelog.attr_payload(group, items)])
        except OSError as e:
            raise write_error(e, self.part) from None
        self._groups.setdefault(group, {}).update(
            (k, framelog.decode_value(framelog.encode_value(v))) for k, v in items)

    def write_deposition(self, summary) -> None:
        self._log_attrs("deposition", [
            ("steps", int(summary.steps)), ("time", float(summary.time)),
            ("ke_per_grain", float(summary.ke_per_grain)), ("height", float(summary.height)),
            ("max_overlap", float(summary.max_overlap)), ("missed", int(summary.missed))])

    def write_preparation(self, legs: list[dict]) -> None:
        """The preparation history (``protocol.Prepared``): one entry per leg, as arrays."""
        self._log_attrs("preparation", [(key, np.array([leg[key] for leg in legs]))
                                        for key in ("target_deg", "tilt_steps", "hold_steps", "ke_per_grain")])

    def write_end(self, ended) -> None:
        """How the tilt ended and what the run cost (``protocol.Ended``): root attrs end_reason,
        end_theta_deg, steps, sweeps, capped_steps."""
        self._log_attrs("/", [("end_reason", str(ended.reason)), ("end_theta_deg", float(ended.theta_deg)),
                              ("steps", int(ended.steps)), ("sweeps", int(ended.sweeps)),
                              ("capped_steps", int(ended.capped_steps))])

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
        self._log_attrs("/", [("seconds", float(now - t0)),
                              ("resumed_from_frame", -1 if resumed_from_frame is None else int(resumed_from_frame)),
                              ("wall_seconds", float(self.wall_seconds(now))),
                              ("wall_seconds_whole", bool(self._wall_whole))])

    def frame_columns(self, names) -> dict:
        """Per-frame scalar columns written so far (e.g. for the health summary at the end)."""
        return {name: np.array(self._columns[name], dtype=FRAME_SCALARS[name]) for name in names}

    def deposition_attrs(self) -> dict:
        return dict(self._groups.get("deposition", {}))

    def write_health(self, summary: dict) -> None:
        """Store the health summary as attrs of ``/health`` (``warnings`` as JSON text)."""
        self._log_attrs("health", [(key, json.dumps(value) if isinstance(value, (list, dict)) else value)
                                   for key, value in summary.items()])

    def _check_space(self, more: int = 0) -> None:
        """RunWriteError while the file can still be closed whole (``RESERVE_BYTES``), and while
        ``more`` bytes (the run file built at the end) still fit."""
        try:
            st = os.statvfs(self.part.parent)
        except OSError:
            return
        free = st.f_bavail * st.f_frsize
        need = RESERVE_BYTES + more + 2 * max(getattr(self, "_max_interval", 0),
                                              getattr(self, "_interval_bytes", 0))
        if free < need:
            raise RunWriteError(
                f"no space left on device while writing {self.part} ({free / 1e6:.1f} MB free; a run "
                f"stops below {need / 1e6:.1f} MB so that its file stays whole); rerun to resume")

    def append(self, frame) -> None:
        """Append one ``protocol.Frame``."""
        self._check_space()
        payload = framelog.frame_payload(frame)
        self._interval_bytes = getattr(self, "_interval_bytes", 0) + sum(len(b) for b in payload) + 200
        try:
            self.log.record(b"FRAM", payload)
        except OSError as e:
            raise write_error(e, self.part) from None
        for b in payload:
            self.digest.update(b)
        for name, dt in FRAME_SCALARS.items():
            self._columns[name].append(dt(getattr(frame, name)))
        self._n += 1

    def checkpoint(self, state: dict) -> None:
        """Store the simulator state as of the frames written so far (``NAME.ckpt``, atomically).

        The frame log is synced first; the checkpoint file, which names the log's length
        (``log_bytes``), is then written under a temporary name, synced and renamed over the
        previous one (the package docstring).
        """
        self._check_space()
        self._max_interval = max(getattr(self, "_max_interval", 0), getattr(self, "_interval_bytes", 0))
        self._interval_bytes = 0
        try:
            self.log.record(b"SYNC", [])
            self.log.sync()
        except OSError as e:
            raise write_error(e, self.part) from None
        tmp = self._tmp(self.ckpt)
        g = None
        try:
            g = h5py.File(tmp, "w")
            for key, value in state.items():
                if key == "scalars":
                    g.attrs["scalars"] = json.dumps(value)
                else:
                    g.create_dataset(key, data=value)
            g.attrs.update(n_frames=self.n_frames, config_hash=self.config_hash,
                           seed=self.seed, frames_digest=self.digest.hexdigest(),
                           wall_seconds=self.wall_seconds(), wall_seconds_whole=self._wall_whole,
                           log_bytes=self.log.size)
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

    def _file_bytes(self) -> int:
        """A bound on the size of the run file ``finish`` builds (its chunks are allocated whole:
        1024 frames of a scalar column, 16384 contact rows), 10% and 64 kB over."""
        def whole(rows: int, chunk: int) -> int:
            return -(-rows // chunk) * chunk

        f, n = self.n_frames, self.head.n
        m = (self.log.size - f * framelog.frame_nbytes(n, 0)) // framelog.CONTACT_BYTES if f else 0
        size = (8 * len(FRAME_SCALARS) * whole(f, 1024) + 8 * whole(f + 1, 1024) + 48 * n * f
                + 25 * whole(max(m, 0), 16384) + 9 * n)
        return int(1.1 * size) + (64 << 10)

    def _tmp(self, path: Path) -> Path:
        """A temporary name beside ``path`` (``_remove_temporaries`` finds what a kill left)."""
        return path.with_name(f".{path.name}.tmp{os.getpid()}")

    def _build(self, out: Path) -> str:
        """Write the run file to ``out`` from the log, mark it complete and sync it; its
        attribute digest. A failed write leaves nothing at ``out`` (RunWriteError)."""
        b = None
        try:
            recs = framelog.read_records(self.part, self.log.size)
            kind, payload, _ = next(recs)
            b = _Builder(out, framelog.parse_head(payload))
            for kind, payload, _ in recs:
                if kind == b"FRAM":
                    b.append(framelog.parse_frame(payload, self.head.n))
                elif kind == b"ATTR":
                    b.attrs(*framelog.parse_attrs(payload))
                elif kind == b"SYNC":
                    b.flush()
            b.f.attrs["complete"] = True
            digest = b.f.attrs[ATTRS_DIGEST] = _attrs_digest(b.f)
            b.close()
            _fsync(out)
            return str(digest)
        except (OSError, RuntimeError) as e:
            if b is not None and b.f.id.valid:
                _BROKEN.append(b)  # closing (or deallocating) a file whose writes failed crashes HDF5
            out.unlink(missing_ok=True)
            if not is_write_failure(e):
                raise
            raise write_error(e, self.part) from None

    def finish(self) -> Path:
        """Build ``NAME`` from the log under a temporary name (complete, synced), note its
        attribute digest at the log's end, rename it to ``NAME`` (replacing an older run file
        only now, when the new one is whole); then drop the log, the checkpoint and the lock."""
        self._check_space(more=self._file_bytes())
        tmp = self._tmp(self.path)
        digest = self._build(tmp)
        try:
            self.log.record(b"DONE", [digest.encode()])
            self.log.sync()
        except OSError as e:
            tmp.unlink(missing_ok=True)
            raise write_error(e, self.part) from None
        os.replace(tmp, self.path)
        self.log.close()
        self.part.unlink(missing_ok=True)  # a kill before these leaves them: remove_stale_checkpoint
        self.ckpt.unlink(missing_ok=True)
        self._remove_temporaries()
        self._unlock()
        return self.path

    def _unlock(self) -> None:
        if getattr(self, "_locked", False):
            self._locked = False
            release_lock(self.path)

    def _remove_temporaries(self) -> None:
        """Files a killed process left half-written under their temporary names (checkpoints,
        run files being built, logs being converted)."""
        for tmp in self.path.parent.glob(f".{self.path.name}.*tmp*"):
            tmp.unlink(missing_ok=True)

    def close(self) -> None:
        """Close without completing (the .part file stays for a resume); never raises."""
        try:
            if getattr(self, "log", None) is not None:
                with contextlib.suppress(OSError):
                    self.log.close()
        finally:
            self._remove_temporaries()
            self._unlock()

    @classmethod
    def resume(cls, path: str | Path, config_hash: str,
               why: list | None = None) -> tuple[RunWriter, dict] | None:
        """Reopen ``NAME.part`` at its last checkpoint; None if there is nothing usable to resume.

        Records past the checkpoint are cut off: the simulation redoes them exactly. A ``.part``
        without its ``NAME.ckpt``, of another configuration or seed, one that cannot be read, or
        whose frames up to the checkpoint differ from what was written (``frames_digest``) is
        not resumed; the caller then starts afresh, which removes both files. An HDF5 ``.part``
        (written by a tiltpile before the frame log) is read, never written: its frames up to
        the checkpoint become a frame log (``_convert``) and the run goes on from there.
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
                log_bytes = int(g.attrs["log_bytes"]) if "log_bytes" in g.attrs else None
                # checkpoints written before the wall time was summed lack it: counted from here
                wall = (float(g.attrs["wall_seconds"]), bool(g.attrs["wall_seconds_whole"])) \
                    if "wall_seconds" in g.attrs else (0.0, False)
        except (OSError, RuntimeError, KeyError, ValueError):
            return f"its checkpoint {ckpt.name} cannot be read"
        writer = cls.__new__(cls)  # reopened, not created
        writer.path, writer.part, writer.ckpt, writer.log = Path(path), part, ckpt, None
        writer._interval_bytes = writer._max_interval = 0
        if not framelog.is_frame_log(part):
            why = writer._convert(ckpt, config_hash, seed, k, digest)
            if why is not None:
                return why
            log_bytes = writer._converted_bytes
        elif log_bytes is None:
            return "its checkpoint does not say where its frame log ends"
        why = writer._read_log(config_hash, seed, k, digest, log_bytes)
        if why is not None:
            return why
        try:
            writer.log = framelog.LogWriter.reopen(part, log_bytes)
        except OSError as e:
            raise write_error(e, part) from None
        writer._remove_temporaries()
        writer._start_clock(*wall)
        return writer, state

    def _read_log(self, config_hash: str, seed: int, k: int, digest: str, end: int) -> str | None:
        """Check the log up to byte ``end`` against its checkpoint and take up its state (frame
        count, columns, digest, group attributes); why it cannot be resumed, or None."""
        try:
            recs = framelog.read_records(self.part, end)
            kind, payload, _ = next(recs, (None, None, None))
            if kind != b"HEAD":
                return "its frames cannot be read back"
            self._init_state(framelog.parse_head(payload))
            if self.config_hash != config_hash or self.seed != seed:
                return "it is a run of another configuration or seed than its checkpoint"
            for kind, payload, _ in recs:
                if kind == b"FRAM":
                    fr = framelog.parse_frame(payload, self.head.n)
                    self.digest.update(payload)
                    for name in FRAME_SCALARS:
                        self._columns[name].append(fr[name])
                    self._n += 1
                elif kind == b"ATTR":
                    group, items = framelog.parse_attrs(payload)
                    self._groups.setdefault(group, {}).update(items)
        except (OSError, framelog.LogError, ValueError, KeyError) as e:
            if isinstance(e, framelog.LogError) and "fewer than" in str(e):
                return "it holds fewer frames than its checkpoint follows"
            return "its frames cannot be read back"
        if self._n != k:
            return f"its frame log holds {self._n} frames up to its checkpoint, which follows {k}"
        if self.digest.hexdigest() != digest:
            return "its frames differ from those its checkpoint follows"
        return None

    def _convert(self, ckpt: Path, config_hash: str, seed: int, k: int, digest: str) -> str | None:
        """Turn an HDF5 ``.part`` (a tiltpile before the frame log wrote it) into a frame log of
        its first ``k`` frames, read-only on the old file; why it cannot be, or None.

        Order, so that a kill at any moment leaves a pair that resumes: the log is written and
        synced under a temporary name, then the checkpoint is replaced by a copy naming the
        log's length (``log_bytes``; the HDF5 ``.part`` still resumes with it), then the log is
        renamed over the ``.part``."""
        part = self.part
        try:
            f = h5py.File(part, "r")
        except (OSError, RuntimeError):
            return "it cannot be read"
        tmp_log, tmp_ckpt = self._tmp(part), self._tmp(ckpt)
        try:
            with f:
                fr, c = f["frames"], f["contacts"]
                if f.attrs.get("config_hash") != config_hash or int(f.attrs["seed"]) != seed:
                    return "it is a run of another configuration or seed than its checkpoint"
                if fr["step"].shape[0] < k or c["offset"].shape[0] < k + 1:
                    return "it holds fewer frames than its checkpoint follows"
                head = framelog.Head(
                    n=int(f["particles/radius"].shape[0]),
                    attrs=[(key, _plain(f.attrs[key])) for key in
                           ("tiltpile_version", "seed", "config", "config_hash", "box_length",
                            "jit", "complete", "integrity") if key in f.attrs],
                    radius=f["particles/radius"][()], fixed=f["particles/fixed"][()])
                log = framelog.LogWriter.create(tmp_log)
                try:
                    log.record(b"HEAD", [framelog.head_payload(head.attrs, head.radius, head.fixed)])
                    for group in _LOGGED_GROUPS:
                        if group in f:
                            log.record(b"ATTR", [framelog.attr_payload(
                                group, [(key, f[group].attrs[key]) for key in f[group].attrs])])
                    h = hashlib.sha256()
                    off = c["offset"][: k + 1]
                    scalars = {name: fr[name][:k] for name in FRAME_SCALARS if name in fr}
                    for i in range(k):
                        a, b = int(off[i]), int(off[i + 1])
                        frame = _Row({name: scalars[name][i] for name in scalars},
                                     {name: fr[name][i] for name in FRAME_ARRAYS},
                                     {name: c[name][a:b] for name in CONTACT_SETS})
                        payload = framelog.frame_payload(frame)
                        for buf in payload:
                            h.update(buf)
                        log.record(b"FRAM", payload)
                    if h.hexdigest() != digest:
                        return "its frames differ from those its checkpoint follows"
                    log.record(b"SYNC", [])
                    log.sync()
                    size = log.size
                finally:
                    log.close()
            shutil.copyfile(ckpt, tmp_ckpt)
            with h5py.File(tmp_ckpt, "r+") as g:
                g.attrs["log_bytes"] = size
            _fsync(tmp_ckpt)
            os.replace(tmp_ckpt, ckpt)
            os.replace(tmp_log, part)
        except (OSError, RuntimeError, KeyError, ValueError) as e:
            if _is_full(e):
                raise write_error(e, part) from None
            return "its frames cannot be read back"  # (a damaged HDF5 file reads as OSError)
        finally:
            for t in (tmp_log, tmp_ckpt):
                t.unlink(missing_ok=True)
        self._converted_bytes = size
        return None


class _Row:
    """One frame of an HDF5 ``.part``, shaped like a ``protocol.Frame``."""

    def __init__(self, *parts: dict):
        for p in parts:
            self.__dict__.update(p)

    def __getattr__(self, name):
        if name == "energy_gain":  # a .part written before this column: NaN, as the reader
            return np.float64(np.nan)
        raise AttributeError(name)


def _is_full(e: BaseException) -> bool:
    """A write refused by the disk (full, over quota, read-only), h5py's RuntimeError included."""
    codes = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES)
    return getattr(e, "errno", None) in codes or any(f"errno = {c}," in str(e) for c in codes)


def _plain(v):
    """An attribute as read by h5py, back to the Python value it was written as."""
    return v.item() if isinstance(v, np.generic) else v


def remove_stale_checkpoint(path: str | Path) -> bool:
    """Remove what a finished run left when killed between its last steps: ``NAME.ckpt``
    without a ``NAME.part`` (killed after the log's removal), or the log and the checkpoint
    when the log's ``DONE`` record names ``NAME``'s attribute digest (killed between the rename
    and their removal). True if anything was removed."""
    path = Path(path)
    ckpt, part = checkpoint_path(path), part_path(path)
    if not path.exists():
        return False
    if part.exists():
        last = framelog.last_record(part)
        if last is None or last[0] != b"DONE":
            return False
        try:
            with h5py.File(path, "r") as f:
                done = str(f.attrs.get(ATTRS_DIGEST, "")) == last[1].decode(errors="replace")
        except OSError:
            return False
        if not done:
            return False
        part.unlink(missing_ok=True)
        ckpt.unlink(missing_ok=True)
        return True
    if ckpt.exists():
        ckpt.unlink(missing_ok=True)
        return True
    return False
