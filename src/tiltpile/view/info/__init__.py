"""One-screen summaries of what ``tiltpile info PATH`` is given, as text: :func:`info` reads the
path and hands it to the module of what it reads.

``run``       a run file (``RUN.h5``): configuration as TOML, seed, grains, frames, deposition,
              health, the first onsets by the lost-contact criterion, completeness and size
              (:func:`run_info`; :func:`~tiltpile.view.info.run.onsets`)
``ensemble``  an ensemble directory: one line per run file or ``.part`` (with where its
              checkpoint stands), the manifest, what the finished runs cost and the rest will
              (:func:`dir_info`, also with the records of runs whose files are gone)
``records``   a record (``run_SSSS.npz``, ``tiltpile record``) or a directory of records: what
              the run recorded, from the record alone (:func:`record_info`, :func:`records_info`)
``common``    what they share: :class:`InfoError`, durations and sizes as text, and the
              configuration block (the TOML comes from :func:`tiltpile.config.config_toml`)

A path that is missing, truncated or not a tiltpile run file, ensemble directory or record raises
:class:`InfoError` naming it and what is wrong.
"""

from __future__ import annotations

from pathlib import Path

from tiltpile.store import part_path

from .common import InfoError
from .ensemble import dir_info
from .records import record_info, records_info
from .run import run_info

__all__ = ["InfoError", "dir_info", "info", "record_info", "records_info", "run_info"]


def info(path, progress: bool = False, records=None) -> str:
    """:func:`run_info` of a run file, :func:`record_info` of a record, :func:`records_info` of a
    directory of records only, else :func:`dir_info` of a directory (with ``records``, see
    there)."""
    p = Path(path)
    if records is not None and not p.is_dir():
        raise InfoError(f"--records: {p} is not an ensemble directory")
    if p.is_dir():
        if records is None and not any(p.glob("run_*.h5*")) and not (p / "ensemble.json").exists() \
                and any(p.glob("run_*.npz")):
            return records_info(p)
        return dir_info(p, records=records)
    if p.suffix == ".npz" and p.exists():
        return record_info(p)
    if not p.exists():
        hint = " (an incomplete .part file exists)" if part_path(p).exists() else ""
        raise InfoError(f"{p}: no such run file or directory{hint}")
    return run_info(p, progress=progress)
