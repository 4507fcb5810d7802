"""Outputs written safely: one writer at a time per output, and files replaced whole (the
standard library alone: the figures, the records, the report and the Makefile use it).

Two builds on one output at once (two ``make figures`` of one preset in two terminals, a cron job
beside a hand run) must neither interleave their work nor leave a file half-written:

* ``output_lock(DIR, NAME, WHAT, wait=...)``: hold ``DIR/NAME``, an advisory ``flock`` that the
  kernel releases when the process dies (a ``SIGKILL`` too), the file holding a note of who
  holds it (WHAT, pid and host). Another holder is waited for (``wait=True``: one line on stderr
  says what it waits for) or refused: ``OutputBusy``, one line naming the directory, the holder
  and the lock file (``tiltpile`` then exits with status 2, nothing changed). The last holder
  removes the lock file, so that none is left in a committed directory. Who takes which lock, and waits or refuses:
  docs/faults.md ("two builds at once").
* ``lock_file`` / ``unlock_file``: the same lock on any file; also the run file's writer lock
  (``NAME.lock``, :mod:`tiltpile.store.files`).
* ``replaced_whole(PATH)``: a temporary path beside PATH (dot-named, with this process's pid)
  which, once written, is synced to disk and renamed over PATH; on any error it is removed and
  PATH is as it was. Every figure's PNG, PDF and JSON, every record and observables cache goes
  through it: a reader sees the old file or the new one, whole.
* ``python -m tiltpile.outputs hold DIR NAME --what WHAT --pid PID``: take ``DIR/NAME`` on behalf
  of process PID and keep it until PID exits (a background process watches it); the Makefile's
  lock of a figures directory (``make figures``: ``FIGURES/.build.lock``, refused when held).
"""

from __future__ import annotations

import contextlib
import os
import socket
import sys
import threading
from pathlib import Path

NOTE_BYTES = 400  # what is read of a holder's note


class OutputBusy(RuntimeError):
    """Another process holds the output's lock; the message is one line naming the output, the
    holder and the lock file (nothing was changed)."""


class LockHeld(Exception):
    """``lock_file`` found ``lock`` held by another process; ``holder`` is its note ("" if none)."""

    def __init__(self, lock: Path, holder: str):
        super().__init__(f"{lock} is held by {holder or 'another process'}")
        self.lock, self.holder = lock, holder


def note(what: str | None = None, pid: int | None = None) -> str:
    """Who holds a lock: ``WHAT (pid N on HOST)``, or ``pid N on HOST`` without WHAT."""
    who = f"pid {os.getpid() if pid is None else pid} on {socket.gethostname()}"
    return f"{what} ({who})" if what else who


def _read_note(fd: int) -> str:
    try:
        text = os.pread(fd, NOTE_BYTES, 0).decode(errors="replace")
    except OSError:
        return ""
    return " ".join(text.split())


def _noted(text: str, over: int = 0) -> bytes:
    """A note as written into a lock, padded with blanks to the ``over`` bytes of an older note
    that it replaces: one ``pwrite`` then replaces it whole (no truncation, no moment without a
    note; :func:`_read_note` drops the blanks)."""
    return (text + "\n").encode().ljust(over, b" ")


def _held_new(lock: Path, text: str) -> int | None:
    """Create ``lock`` already held and already holding its note (:func:`_link_held`), so that
    no other process ever sees ``lock`` without its holder: written unnamed (``O_TMPFILE``), or
    under a hidden name beside it where that cannot be made or linked. The descriptor, or None
    if ``lock`` exists."""
    try:
        return _link_held(lock, text, unnamed=True)
    except FileExistsError:
        return None
    except (AttributeError, OSError):
        pass   # no O_TMPFILE, no /proc, or a file system that cannot link it: by name
    try:
        return _link_held(lock, text, unnamed=False)
    except FileExistsError:
        return None


def _link_held(lock: Path, text: str, unnamed: bool) -> int:
    """A new file holding ``text``, flocked, then linked to ``lock``: its descriptor.
    FileExistsError if ``lock`` exists; the new file is closed and nothing is left behind on any
    error."""
    import fcntl

    tmp = None if unnamed else lock.with_name(f".{lock.name}.{os.getpid()}.{threading.get_ident()}")
    fd = (os.open(lock.parent, os.O_TMPFILE | os.O_RDWR, 0o644) if unnamed
          else os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o644))
    try:
        os.pwrite(fd, _noted(text), 0)
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)    # a new file: nobody else has it
        if unnamed:   # linkat(2) of /proc/self/fd/N, as open(2) documents for O_TMPFILE
            fds = os.open("/proc/self/fd", os.O_RDONLY)
            try:      # (a src_dir_fd makes Python call linkat with AT_SYMLINK_FOLLOW)
                os.link(str(fd), lock, src_dir_fd=fds, follow_symlinks=True)
            finally:
                os.close(fds)
        else:
            os.link(tmp, lock)
    except BaseException:
        os.close(fd)
        raise
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                tmp.unlink()
    return fd


def lock_file(lock: str | Path, holder: str | None = None, *, wait: bool = False,
              on_wait=None) -> int:
    """Take the exclusive advisory ``flock`` of file ``lock`` and write ``holder`` (default
    :func:`note`) into it; returns the descriptor that holds it (give it to
    :func:`unlock_file`). A missing ``lock`` appears already held with its note
    (:func:`_held_new`); one left by a holder that died without removing it is taken over and
    its note replaced in one write. Held by another process: ``LockHeld`` (``wait=False``), or
    ``on_wait(its note)`` once and a wait until it is free (``wait=True``). An OSError of the
    file itself (no permission, a full disk) propagates."""
    import fcntl

    lock = Path(lock)
    text = note() if holder is None else holder
    told = False
    while True:
        fd = _held_new(lock, text)
        if fd is not None:
            return fd
        try:
            fd = os.open(lock, os.O_RDWR)
        except FileNotFoundError:      # released and removed meanwhile: create it again
            continue
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                held_by = _read_note(fd)
                if not wait:
                    raise LockHeld(lock, held_by) from None
                if on_wait is not None and not told:
                    on_wait(held_by)
                    told = True
                fcntl.flock(fd, fcntl.LOCK_EX)
            # the holder before us removes the file while holding it: ours may be that old one
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(lock))
            except FileNotFoundError:
                same = False
        except BaseException:
            os.close(fd)
            raise
        if same:     # a lock file left by a holder that died: ours now
            break
        os.close(fd)
    try:
        os.pwrite(fd, _noted(text, os.fstat(fd).st_size), 0)
    except OSError:
        pass  # the lock holds without its note
    return fd


def unlock_file(lock: str | Path, fd: int) -> None:
    """Release what :func:`lock_file` took: remove the file while still holding it (a process
    waiting on it sees it gone and takes a new one), then close it."""
    with contextlib.suppress(OSError):
        Path(lock).unlink()
    os.close(fd)


_taken: set[str] = set()  # output locks held by this process: taking one twice would wait forever
_taken_lock = threading.Lock()


def _busy(directory: Path, lock: Path, holder: str, then: str) -> str:
    return f"{directory} is busy: {holder or 'another process'} is writing it (lock {lock}); {then}"


@contextlib.contextmanager
def output_lock(directory: str | Path, name: str, what: str, *, wait: bool = False):
    """Hold ``directory/name`` (created with its directory) while the block writes the output
    ``directory``; module docstring. ``what`` names the writer in the lock's note (e.g. "tiltpile
    ensemble"). Held elsewhere: ``OutputBusy`` (one line, ``wait=False``), or one line on stderr
    and a wait (``wait=True``)."""
    directory = Path(directory)
    lock = directory / name
    key = str(lock.absolute())
    with _taken_lock:
        if key in _taken:
            raise RuntimeError(f"{lock} is already held by this process")
        _taken.add(key)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        try:
            fd = lock_file(lock, note(what), wait=wait, on_wait=lambda held_by: print(
                _busy(directory, lock, held_by, "waiting for it to finish"), file=sys.stderr, flush=True))
        except LockHeld as e:
            raise OutputBusy(_busy(directory, lock, e.holder, "wait for it to finish or stop it "
                                                              "(nothing was changed)")) from None
        try:
            yield lock
        finally:
            unlock_file(lock, fd)
    finally:
        with _taken_lock:
            _taken.discard(key)


@contextlib.contextmanager
def replaced_whole(path: str | Path):
    """Yield a temporary path beside ``path`` for the block to write; when the block ends, sync
    it to disk and rename it over ``path``; on any error (a full disk, an exception standing for
    a kill) remove it, leaving ``path`` as it was. A SIGKILL leaves the dot-named temporary
    (``.NAME.PID.tmp``), which no reader takes for the file."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


# -- the Makefile's lock: held for another process until it exits ------------------------------------

def _wait_for_exit(pid: int, pidfd: int | None) -> None:
    import select
    import time

    if pidfd is not None:
        select.select([pidfd], [], [])   # readable once the process has exited
        return
    while True:                          # no pidfd (not Linux): look twice a second
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return
        except PermissionError:
            pass
        time.sleep(0.5)


def hold(directory: str | Path, name: str, what: str, pid: int) -> None:
    """Take ``directory/name`` for process ``pid`` and return at once, leaving a background
    process that holds it until ``pid`` exits (then releases it and removes the file). Held
    elsewhere: ``OutputBusy`` (one line)."""
    directory = Path(directory)
    lock = directory / name
    directory.mkdir(parents=True, exist_ok=True)
    try:
        fd = lock_file(lock, note(what, pid))
    except LockHeld as e:
        raise OutputBusy(_busy(directory, lock, e.holder, "wait for it to finish or stop it "
                                                          "(nothing was changed)")) from None
    try:
        pidfd = os.pidfd_open(pid)
    except ProcessLookupError:   # gone already
        unlock_file(lock, fd)
        return
    except (AttributeError, OSError):
        pidfd = None
    if os.fork():
        os.close(fd)             # the child's descriptor holds the lock now
        if pidfd is not None:
            os.close(pidfd)
        return
    try:                         # the child: its own session, no terminal, no descriptor of make's
        os.setsid()
        devnull = os.open(os.devnull, os.O_RDWR)
        for k in (0, 1, 2):
            os.dup2(devnull, k)
        keep = sorted({fd, devnull} | ({pidfd} if pidfd is not None else set()))
        start = 3
        for k in keep:
            os.closerange(start, k)
            start = k + 1
        os.closerange(start, os.sysconf("SC_OPEN_MAX") if hasattr(os, "sysconf") else 1024)
        _wait_for_exit(pid, pidfd)
        unlock_file(lock, fd)
    finally:
        os._exit(0)


def main(argv: list[str] | None = None) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="python -m tiltpile.outputs",
                                description="hold an output directory's lock for another process")
    sub = p.add_subparsers(dest="command", required=True)
    h = sub.add_parser("hold", help="take DIR/NAME for process PID until it exits")
    h.add_argument("dir", help="the output directory")
    h.add_argument("name", help="the lock file's name in it")
    h.add_argument("--what", required=True, help="who holds it, for the message of a refused one")
    h.add_argument("--pid", type=int, required=True, help="the process that holds it (make's pid)")
    args = p.parse_args(argv)
    try:
        hold(args.dir, args.name, args.what, args.pid)
    except OutputBusy as e:
        print(e, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
