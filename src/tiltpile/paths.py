"""Output paths: refuse one that cannot be written before anything is (one line naming it)."""

from __future__ import annotations

import os
from pathlib import Path

from tiltpile.config import ConfigError


def check_output(path: Path, what: str, *, directory: bool = False) -> None:
    """Refuse (ConfigError, one line naming the path) an output that cannot be written, before
    anything is: ``path`` a directory where a file is wanted (or the reverse), an ancestor that is
    a regular file, or a first existing ancestor that is not writable (read-only, /proc)."""
    path = Path(path)
    if path.exists():
        if directory and not path.is_dir():
            raise ConfigError(f"{what} {path} exists and is not a directory")
        if not directory and path.is_dir():
            raise ConfigError(f"{what} {path} is a directory")
    parent = path if directory and path.is_dir() else path.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise ConfigError(f"{what} {path}: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK) or _read_only_fs(parent):
        raise ConfigError(f"{what} {path}: {parent} is not writable")


def _read_only_fs(path: Path) -> bool:
    """A directory on a file system that refuses new files even to root (/proc, a ro mount)."""
    try:
        st = os.statvfs(path)
    except OSError:
        return False
    if st.f_flag & os.ST_RDONLY:
        return True
    try:  # /proc and /sys are mounted rw but create nothing: look at their file system type
        with open("/proc/self/mounts") as fh:
            best, fstype = "", ""
            real = os.path.realpath(path)
            for line in fh:
                parts = line.split()
                if len(parts) >= 3 and (real == parts[1] or real.startswith(parts[1].rstrip("/") + "/")):
                    if len(parts[1]) > len(best):
                        best, fstype = parts[1], parts[2]
        return fstype in ("proc", "sysfs", "cgroup", "cgroup2", "devpts")
    except OSError:
        return False
