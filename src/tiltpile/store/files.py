"""The files around a run file: ``NAME.part`` (written), ``NAME.ckpt`` (its checkpoint) and
``NAME.lock`` (the writer lock, an exclusive ``flock``: :func:`tiltpile.outputs.lock_file`); syncing to disk, and one-line messages
for failed writes."""

from __future__ import annotations

import contextlib
import errno
import os
import threading
from pathlib import Path

from tiltpile.outputs import LockHeld, lock_file, unlock_file
from tiltpile.store.errors import RunBusyError, RunFileError, RunWriteError


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
    lock = lock_path(path)
    key = str(lock.absolute())
    with _held_lock:
        if key in _held:
            _held[key][1] += 1
            return
        try:
            fd = lock_file(lock)
        except LockHeld as e:
            raise RunBusyError(
                f"{part_path(path)} is being written by another process"
                f"{' (' + e.holder + ')' if e.holder else ''}; wait for it to finish or use another "
                "output file (nothing was changed)") from None
        except OSError as e:
            raise RunWriteError(f"cannot write {Path(path)}: {_describe_os_error(e)} "
                                f"(creating {lock})") from None
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
        unlock_file(lock, entry[0])  # removed while still held: a waiting process retries


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
