"""What every writer of ``tiltpile.view`` shares: a progress bar over the frames, and a file
written under a temporary name that replaces ``out`` only when complete."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path


def progress_frames(frames, desc: str, progress: bool):
    """Yield ``frames`` in order, with a tqdm bar (unit "frame") when ``progress``."""
    if not progress:
        yield from frames
        return
    from tqdm.auto import tqdm

    with tqdm(total=len(frames), desc=desc, unit="frame") as bar:
        for k in frames:
            yield k
            bar.update(1)


@contextlib.contextmanager
def replaced_when_complete(out: Path, tmp: Path):
    """Yield ``tmp`` to write; on success rename it to ``out``, on any error remove it."""
    try:
        yield tmp
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, out)
