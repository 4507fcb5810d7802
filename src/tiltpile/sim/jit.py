"""One place for numba JIT flags (PySDM's ``impl_numba/conf.py`` idea).

Every kernel in ``tiltpile.sim`` is compiled with ``JIT``. ``fastmath`` stays off: it lets LLVM
reassociate sums, which changes results between builds and breaks bit-for-bit determinism across
machines; ``cache=True`` keeps compiled kernels on disk (``NUMBA_CACHE_DIR`` or ``__pycache__``).
The flags are recorded in every run file (``store``), so a result can always be traced to them.
"""

import numba

JIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy", boundscheck=False)



def njit(fn=None, **overrides):
    """``numba.njit`` with the project's flags; ``@njit`` or ``@njit(inline="always")``."""
    opts = dict(JIT, **overrides)
    if fn is None:
        return numba.njit(**opts)
    return numba.njit(**opts)(fn)


def flags() -> dict:
    return dict(JIT, numba_version=numba.__version__)
