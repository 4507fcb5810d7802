"""One place for numba JIT flags (PySDM's ``impl_numba/conf.py`` idea), and a guard on numba's cache.

Every kernel in ``tiltpile.sim`` is compiled with ``JIT``. ``fastmath`` stays off: it lets LLVM
reassociate sums, which changes results between builds and breaks bit-for-bit determinism across
machines, for a gain on the sweep too small to pay for that (``docs/performance.md``; CHANGELOG).
``cache=True`` keeps compiled kernels on disk (``NUMBA_CACHE_DIR`` or ``__pycache__``).
The flags are recorded in every run file (``store``), so a result can always be traced to them.

Stale caches. numba checks a cached kernel only against its *own* source file, but a kernel
carries the compiled code of the kernels it calls: after an edit of ``solver.py`` the cached
``step.advance`` went on running the old NLGS sweep, and could as well have run old physics.
So at import this module hashes all of ``sim/*.py`` and, when the hash differs from the one
stamped in the cache directory, deletes the cached ``sim`` kernels there before anything is
compiled.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numba

JIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy", boundscheck=False)
SIM_DIR = Path(__file__).resolve().parent
STAMP = "tiltpile-sim-sources.sha256"


def njit(fn=None, **overrides):
    """``numba.njit`` with the project's flags; ``@njit`` or ``@njit(inline="always")``."""
    opts = dict(JIT, **overrides)
    if fn is None:
        return numba.njit(**opts)
    return numba.njit(**opts)(fn)


def flags() -> dict:
    return dict(JIT, numba_version=numba.__version__)


def sources_hash() -> str:
    """sha256 over the names and bytes of ``sim/*.py``."""
    h = hashlib.sha256()
    for path in sorted(SIM_DIR.glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def cache_dir() -> Path:
    """Where numba caches the ``sim`` kernels: under ``NUMBA_CACHE_DIR`` if set, else in-tree."""
    if numba.config.CACHE_DIR:
        from numba.core.caching import _CacheLocator

        sub = _CacheLocator.get_suitable_cache_subpath(str(SIM_DIR / "jit.py"))
        return Path(numba.config.CACHE_DIR) / sub
    return SIM_DIR / "__pycache__"


def drop_stale_cache(directory: Path | None = None) -> bool:
    """Delete cached kernels in ``directory`` unless they were built from the current sources.

    Returns True if the cache was (re)stamped. Filesystem errors are ignored: a cache that cannot
    be written is not used by numba either.
    """
    directory = cache_dir() if directory is None else directory
    current = sources_hash()
    stamp = directory / STAMP
    try:
        if stamp.read_text() == current:
            return False
    except OSError:
        pass
    try:
        directory.mkdir(parents=True, exist_ok=True)
        for f in directory.iterdir():
            if f.suffix in (".nbi", ".nbc"):
                f.unlink(missing_ok=True)
        tmp = directory / f"{STAMP}.{os.getpid()}"
        tmp.write_text(current)
        os.replace(tmp, stamp)
    except OSError:
        return False
    return True


drop_stale_cache()
