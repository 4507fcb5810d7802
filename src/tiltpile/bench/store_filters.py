"""Cost of the run file's integrity record and of compression.

Rewrites the frames of an existing run file through ``store.RunWriter`` with different HDF5
filters and reports, per variant, the file size, the writer's time (all appends to the frame
log, checkpoints left out, and the final build of the run file from it), the time of ``store.verify`` (every chunk of every dataset)
and the time of a frame-by-frame read as the analysis does it (``open_run``, then position,
velocity, omega and contacts of every frame)::

    python -m tiltpile.bench.store_filters RUN.h5 [--repeat 3]

Variants: ``plain`` (no filter), ``fletcher32`` (HDF5's checksum on
every chunk, what the writer does now), ``sha256`` (plain, plus a SHA-256 digest per dataset fed
at every append: the alternative integrity record), and Fletcher32 with shuffle + ``lzf`` or
``gzip`` (levels 1 and 4). The simulator's time is not included: compare with a run's
``seconds`` (a default-preset run takes 3-4 min of one core) to judge the share.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from tiltpile import store

VARIANTS = {
    "plain": {},
    "fletcher32": {"fletcher32": True},
    "sha256": {},
    "fletcher32+shuffle+lzf": {"fletcher32": True, "shuffle": True, "compression": "lzf"},
    "fletcher32+shuffle+gzip1": {"fletcher32": True, "shuffle": True, "compression": "gzip",
                                 "compression_opts": 1},
    "fletcher32+shuffle+gzip4": {"fletcher32": True, "shuffle": True, "compression": "gzip",
                                 "compression_opts": 4},
}


def _frames(source: Path) -> tuple[dict, list]:
    """The source run's particles and frames, in memory (as ``protocol.Frame``-like objects)."""
    with store.open_run(source) as run:
        head = dict(radius=run.radius, fixed=run.fixed, box_length=run.box_length,
                    config=json.dumps(run.config), config_hash=run.config_hash, seed=run.seed)
        frames = []
        for k in range(run.n_frames):
            pair, force, status = run.contacts(k)
            frames.append(SimpleNamespace(
                position=run.position(k), velocity=run.velocity(k), rotation=run.rotation(k),
                omega=run.omega(k), pair=pair, force=force, status=status,
                **{name: getattr(run, name)[k] for name in store.FRAME_SCALARS}))
    return head, frames


def _write(head: dict, frames: list, out: Path, variant: str) -> float:
    filters = VARIANTS[variant]
    saved = store.writer.FILTERS  # what the writer creates its datasets with
    store.writer.FILTERS = filters
    digests = {} if variant == "sha256" else None

    class Writer(store.RunWriter):
        def _before_close(self, f):
            if not filters.get("fletcher32"):
                del f.attrs["integrity"]  # no checksums: read as a file written before them
            for name, h in (digests or {}).items():
                group = "contacts" if name in store.CONTACT_SETS else "frames"
                f[f"{group}/{name}"].attrs["sha256"] = h.hexdigest()

    try:
        t0 = time.perf_counter()
        w = Writer(out, config_json=head["config"], config_hash=head["config_hash"],
                   seed=head["seed"], radius=head["radius"], fixed=head["fixed"],
                   box_length=head["box_length"], jit={})
        for fr in frames:
            w.append(fr)
            if digests is not None:
                for name in (*store.FRAME_SCALARS, *store.FRAME_ARRAYS, *store.CONTACT_SETS):
                    digests.setdefault(name, hashlib.sha256()).update(
                        np.ascontiguousarray(getattr(fr, name)).tobytes())
        w.finish()
        return time.perf_counter() - t0
    finally:
        store.writer.FILTERS = saved


def _read_all(path: Path) -> float:
    """Seconds of ``store.verify`` (layout, attributes, every chunk of every dataset)."""
    t0 = time.perf_counter()
    problems = store.verify(path)
    if problems:
        raise RuntimeError(f"{path}: {problems[0]}")
    return time.perf_counter() - t0


def _read_frames(path: Path) -> float:
    t0 = time.perf_counter()
    with store.open_run(path) as run:
        for k in range(run.n_frames):
            run.position(k), run.velocity(k), run.omega(k), run.contacts(k)
    return time.perf_counter() - t0


def measure(source: Path, repeat: int = 3) -> list[dict]:
    head, frames = _frames(source)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for variant in VARIANTS:
            best_w = best_r = best_f = float("inf")
            for i in range(repeat):
                out = Path(d) / f"{variant}-{i}.h5"
                best_w = min(best_w, _write(head, frames, out, variant))
                best_r = min(best_r, _read_all(out))
                best_f = min(best_f, _read_frames(out))
                size = out.stat().st_size
                out.unlink()
            rows.append({"variant": variant, "bytes": size, "write_s": round(best_w, 4),
                         "read_s": round(best_r, 4), "read_frames_s": round(best_f, 4),
                         "frames": len(frames)})
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m tiltpile.bench.store_filters", description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="a complete run file to rewrite")
    p.add_argument("--repeat", type=int, default=3, help="best of this many writes per variant")
    a = p.parse_args(argv)
    rows = measure(a.run, a.repeat)
    base = rows[0]
    print(f"{'variant':<26} {'MB':>8} {'size':>6} {'write s':>8} {'x plain':>7} {'read s':>7} "
          f"{'frames s':>8}")
    for r in rows:
        print(f"{r['variant']:<26} {r['bytes'] / 1e6:8.2f} {r['bytes'] / base['bytes']:6.2f} "
              f"{r['write_s']:8.3f} {r['write_s'] / base['write_s']:7.2f} {r['read_s']:7.3f} "
              f"{r['read_frames_s']:8.3f}")
    print(json.dumps({"source": str(a.run), "rows": rows}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
