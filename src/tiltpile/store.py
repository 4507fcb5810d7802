"""The run file: one HDF5 file per run. The only module that knows the layout.

Layout: ``LAYOUT`` declares every dataset (units and meaning, written with it as attributes
``units`` and ``description``) and ``ATTRS`` the attributes of the root and of the groups that
hold only attributes; docs/run-file.md shows both with shapes and types, and
tests/workflow/test_run_file_doc.py checks the page and a written file against them.

The file is written as ``NAME.part`` and renamed to ``NAME`` when complete, so a file with the
final name is always whole. An interrupted ``.part`` file resumes from its checkpoint
(``RunWriter.resume``): frames past the checkpoint are dropped and recomputed.

Checkpoints live in their own file, ``NAME.ckpt`` (HDF5: the simulator's full state as datasets,
attrs ``scalars`` (JSON), ``n_frames``, ``config_hash``, ``seed`` and ``frames_digest``), written
to a temporary name, synced and renamed, so a process killed at any moment leaves either the old
checkpoint or the new one, never a mixture. (HDF5 is not crash-safe for data rewritten in place:
a state rewritten inside the ``.part`` file could land in space the old one freed while the last
flushed metadata still described the old one, and a run killed then would resume from a mixture;
``test_sigkill_then_rerun_is_bit_identical`` kills runs at random moments.) The ``.part`` file is
flushed and synced before the checkpoint names its frame count; ``frames_digest`` (SHA-256 over
every frame and contact row written up to the checkpoint, in order) is checked on resume, so a
``.part`` file that lost or changed frames in a crash is started afresh rather than resumed.

One writer per run file. ``RunWriter`` (and ``runner.simulate`` around it) holds an exclusive
``flock`` on ``NAME.lock`` from before anything is opened or truncated until the run is finished
or closed; a second writer is refused with ``RunBusyError`` naming the ``.part`` file the other
process writes, and the lock file is removed by the last holder. (HDF5's own file lock is no
guard: ``h5py.File(part, "w")`` truncates the other writer's file before that lock refuses it.)

Integrity. A complete run file (root attr ``integrity = "fletcher32"``) has HDF5's Fletcher32
checksum on every chunk of every dataset (and ``attrs_sha256``, a SHA-256 over every attribute,
which ``verify`` checks): HDF5 checks the chunks' checksums on every read, so flipped bytes make a
read fail (``Run`` turns that into ``RunFileError`` naming the file and the dataset) instead of
returning wrong numbers. ``verify(path)`` reads every chunk and checks the layout (every dataset
present, the shapes consistent, ``complete``); ``open_run`` checks the layout, reads check the
checksums. Files written before the record existed have no ``integrity`` attr; they are checked
for layout only (``has_integrity_record``). A missing dataset is an error, except the
documented late additions ``frames/energy_gain`` (read as NaN) and ``/health`` (``Run.health``
empty) of files written before them.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import socket
import threading
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

# every dataset of a run file: (units, one-line description); written as its attrs
LAYOUT = {
    "particles/radius": ("d", "grain radius"),
    "particles/fixed": ("1", "true for the grains of the rough bottom row (they never move)"),
    "frames/step": ("1", "global step of the frame (deposition steps included)"),
    "frames/time": ("sqrt(d/g)", "simulated time of the frame"),
    "frames/theta_deg": ("deg", "inclination of the box"),
    "frames/position": ("d", "grain centres (x along the floor, y up), box frame"),
    "frames/rotation": ("rad", "grain rotation angle"),
    "frames/velocity": ("sqrt(g d)", "grain velocity, box frame"),
    "frames/omega": ("sqrt(g/d)", "grain angular velocity"),
    "frames/iterations": ("1", "NLGS sweeps of the frame's step"),
    "frames/residual": ("1", "final NLGS residual of the frame's step (relative change of the impulses)"),
    "frames/ke": ("m g d", "kinetic energy of the mobile grains"),
    "frames/max_overlap": ("d", "largest overlap since the previous frame"),
    "frames/max_iterations": ("1", "most NLGS sweeps in a step since the previous frame"),
    "frames/cap_hits": ("1", "steps since the previous frame that hit solver.max_iter"),
    "frames/missed": ("1", "steps since the previous frame where a grain outran the alert distance"),
    "frames/energy_gain": ("m g d", "largest per-step gain of kinetic energy beyond the work of "
                                    "gravity since the previous frame (<= 0 up to solver error)"),
    "contacts/offset": ("1", "contacts of frame k are rows offset[k]:offset[k+1]"),
    "contacts/pair": ("1", "grain ids (i < j); walls: -1 floor, -2 left (x = 0), -3 right (x = L)"),
    "contacts/force": ("m g", "normal, tangential contact force (impulse / dt)"),
    "contacts/status": ("1", "0 open (touching, no force), 1 sticking, 2 sliding (|f_t| = mu f_n)"),
}
# The attributes of the root and of the groups that hold only attributes, each with its meaning
# (docs/run-file.md); /preparation only with protocol.pretilt_deg (one entry per leg), /health
# only in complete runs, its keys those of tiltpile.health.summarize (None here).
ATTRS = {
    "/": {
        "tiltpile_version": "version of tiltpile that wrote the file",
        "seed": "the run's seed",
        "config": "the validated configuration (JSON text)",
        "config_hash": "SHA-256 of the configuration's canonical JSON",
        "box_length": "box length L [d]",
        "jit": "the numba flags the kernels were compiled with (JSON text)",
        "complete": "true once the run is finished",
        "integrity": '"fletcher32": every dataset carries HDF5\'s Fletcher32 checksum',
        "attrs_sha256": "SHA-256 over the attributes of the root and the groups (verify checks it)",
        "end_reason": '"theta_max" (the ramp reached theta_max_deg) or "slide" (protocol.end_ke)',
        "end_theta_deg": "tilt of the last frame [deg]",
        "steps": "time steps of the whole run, deposition and preparation included",
        "sweeps": "NLGS sweeps of the whole run",
        "capped_steps": "steps of the whole run that stopped at solver.max_iter",
        "seconds": "wall time of the invocation that finished the run [s]",
        "resumed_from_frame": "the frame that invocation resumed from; -1: not resumed",
    },
    "deposition": {
        "steps": "deposition steps",
        "time": "simulated time of the deposition [sqrt(d/g)]",
        "ke_per_grain": "kinetic energy per mobile grain at its end [m g d]",
        "height": "highest grain top [d]",
        "max_overlap": "largest overlap of any deposition step [d]",
        "missed": "deposition steps where a grain outran the alert distance",
    },
    "preparation": {
        "target_deg": "the leg's target tilt [deg]",
        "tilt_steps": "steps tilting to it",
        "hold_steps": "steps held there until at rest",
        "ke_per_grain": "kinetic energy per mobile grain at the leg's end [m g d]",
    },
    "health": None,
}
# datasets that files written before they existed lack (the reader fills energy_gain with NaN)
OPTIONAL = frozenset({"frames/energy_gain"})
INTEGRITY = "fletcher32"  # root attr ``integrity`` of files whose every dataset is checksummed
# HDF5 filters of every dataset: the checksum (compression measured, not adopted: docs/performance.md)
FILTERS = {"fletcher32": True}
# A writer stops with "no space left on device" while this much space (plus twice what one
# checkpoint interval writes) is still free: HDF5 cannot close a file whose writes failed (h5py
# then crashes the process), so the run stops while its file can still be closed whole.
RESERVE_BYTES = 4 << 20
_BROKEN: list = []  # HDF5 files whose writes failed: never closed (closing them crashes HDF5)


class RunFileError(RuntimeError):
    """A run file is missing, incomplete, damaged or not a tiltpile run."""


class RunBusyError(RunFileError):
    """Another process is writing this run file (its ``NAME.lock`` is held)."""


class RunExistsError(RunFileError):
    """The run file exists and was not to be replaced."""


class MixedConfigError(RunFileError):
    """Run files of more than one configuration where one is expected (``common_config``)."""


class RunWriteError(RunFileError):
    """Writing a run file failed (disk full, no permission, ...); the message is one line."""


def lock_path(path: str | Path) -> Path:
    path = Path(path)
    return path.with_name(path.name + ".lock")


_held: dict[str, list] = {}  # lock file -> [fd, count]: re-entrant within one process
_held_lock = threading.Lock()


def _describe_os_error(e: OSError) -> str:
    """'no space left on device' and the like, from an OSError (h5py's included)."""
    code = getattr(e, "errno", None)
    text = str(e)
    if code is None:
        for c in (errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EROFS, errno.EIO):
            if f"errno = {c}," in text or os.strerror(c).lower() in text.lower():
                code = c
                break
    if code == errno.ENOSPC:
        return "no space left on device"
    if code is not None:
        return os.strerror(code).lower()
    return text.splitlines()[0] if text else type(e).__name__


def is_write_failure(e: BaseException) -> bool:
    """An OSError, or h5py's RuntimeError for a failed write/flush (it carries the errno in its
    text, e.g. 'file write failed: ... errno = 28')."""
    return isinstance(e, OSError) or (isinstance(e, RuntimeError) and not isinstance(e, RunFileError)
                                      and ("write failed" in str(e) or "errno = " in str(e)))


def write_error(e: OSError, path) -> RunWriteError:
    """A one-line ``RunWriteError`` for an OSError raised while writing run file ``path``."""
    return RunWriteError(f"{_describe_os_error(e)} while writing {path}; rerun to resume")


@contextlib.contextmanager
def writer_lock(path: str | Path):
    """Hold the exclusive writer lock of run file ``path`` (``NAME.lock``, an advisory ``flock``
    released when the process dies); ``RunBusyError`` if another process holds it. Re-entrant
    within a process; the last release removes the lock file."""
    acquire_lock(path)
    try:
        yield
    finally:
        release_lock(path)


def acquire_lock(path: str | Path) -> None:
    import fcntl

    lock = lock_path(path)
    key = str(lock.absolute())
    with _held_lock:
        if key in _held:
            _held[key][1] += 1
            return
        while True:
            try:
                fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                raise RunWriteError(f"cannot write {Path(path)}: {_describe_os_error(e)} "
                                    f"(creating {lock})") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                try:
                    holder = os.pread(fd, 200, 0).decode(errors="replace").strip()
                except OSError:
                    holder = ""
                os.close(fd)
                raise RunBusyError(
                    f"{part_path(path)} is being written by another process"
                    f"{' (' + holder + ')' if holder else ''}; wait for it to finish or use another "
                    "output file (nothing was changed)") from None
            # the previous holder may have removed the file between our open and our lock
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(lock))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{socket.gethostname()} pid {os.getpid()}\n".encode(), 0)
        except OSError:
            pass  # the lock holds without the note
        _held[key] = [fd, 1]


def release_lock(path: str | Path) -> None:
    lock = lock_path(path)
    key = str(lock.absolute())
    with _held_lock:
        entry = _held.get(key)
        if entry is None:
            return
        entry[1] -= 1
        if entry[1] > 0:
            return
        del _held[key]
        with contextlib.suppress(OSError):
            lock.unlink()  # while still holding it: a waiting process sees the file gone and retries
        os.close(entry[0])


def remove_stale_checkpoint(path: str | Path) -> bool:
    """Remove ``NAME.ckpt`` of a finished run (``NAME`` exists, no ``NAME.part``): what a process
    killed between the final rename and the checkpoint's removal leaves. True if one was removed."""
    path = Path(path)
    ckpt = checkpoint_path(path)
    if path.exists() and ckpt.exists() and not part_path(path).exists():
        ckpt.unlink(missing_ok=True)
        return True
    return False


ATTRS_DIGEST = "attrs_sha256"  # root attr of complete files: SHA-256 over every attribute


def _attrs_digest(f) -> str:
    """SHA-256 over the attributes of the root and the groups (configuration, seed, deposition,
    health, ...; names sorted), as read back from the file: metadata, which the datasets'
    checksums do not cover. (The datasets' ``units`` and ``description`` are checked against
    ``LAYOUT`` instead.)"""
    h = hashlib.sha256()
    objects = [("/", f)]
    f.visititems(lambda name, obj: objects.append((name, obj)) if isinstance(obj, h5py.Group) else None)
    for path, obj in sorted(objects, key=lambda t: t[0]):
        for key in sorted(obj.attrs):
            if path == "/" and key == ATTRS_DIGEST:
                continue
            v = obj.attrs[key]
            h.update(f"{path}\0{key}\0".encode())
            if isinstance(v, (str, bytes)):
                h.update(v.encode() if isinstance(v, str) else v)
            else:
                a = np.asarray(v)
                if a.dtype.kind in "OUS":
                    h.update(repr(a.tolist()).encode())
                else:
                    h.update(f"{a.dtype.str}{a.shape}".encode() + a.tobytes())
    return h.hexdigest()


def _create(group, name: str, **kw):
    """A chunked dataset with the run file's filters and its ``units`` / ``description`` attrs."""
    kw.setdefault("chunks", True)
    ds = group.create_dataset(name, **kw, **FILTERS)
    units, description = LAYOUT[f"{group.name.strip('/')}/{name}"]
    ds.attrs["units"] = units
    ds.attrs["description"] = description
    return ds


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
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise RunWriteError(f"cannot write {self.path}: {_describe_os_error(e)}") from None
        acquire_lock(self.path)  # before anything is opened or truncated
        self._locked = True
        self._interval_bytes = self._max_interval = 0
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

    def write_timing(self, seconds: float, resumed_from_frame: int | None) -> None:
        """Wall seconds of the invocation that finished the run (root attr ``seconds``) and, if it
        resumed an interrupted one, the frame it resumed from (``resumed_from_frame``, else -1)."""
        self.f.attrs.update(seconds=float(seconds),
                            resumed_from_frame=-1 if resumed_from_frame is None else int(resumed_from_frame))

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
        synced and renamed over the previous one (module docstring).
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
                           seed=int(self.f.attrs["seed"]), frames_digest=self.digest.hexdigest())
            g.close()
            _fsync(tmp)
        except BaseException as e:
            if g is not None and g.id.valid:
                try:
                    g.close()
                except (OSError, RuntimeError):
                    _BROKEN.append(g)  # never closed again (module docstring)
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
        return writer, state


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
