"""Run one simulation and SIGKILL the process at a chosen point inside a write.

    python tests/killhooks.py POINT OUT SET...    (SET: section.key=value over the smoke preset)

POINT: ``frame`` (half of the 9th frame record handed to the kernel), ``checkpoint`` (inside
HDF5's write of the 4th tilt checkpoint, after its first array), ``build`` (inside HDF5's write
of the finished run file: frame 7's grain arrays written, its contacts not), ``rename`` (the
run file built and its DONE record synced, not yet renamed to OUT), ``history`` (the 2nd
frame-log record after the first checkpoint of a run with a history, half written),
``legacy`` (the writer before the frame log, inside HDF5's write of frame 9 of its .part).
Nothing can catch a SIGKILL: the process ends there, as with ``kill -9``.
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path


def _die() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def main(point: str, out: str, sets: list[str]) -> None:
    import h5py

    from tiltpile import config, runner
    from tiltpile.store import framelog, writer

    cfg = config.load("smoke", overrides=sets)
    if point in ("frame", "history"):
        real = framelog.LogWriter._write
        seen = {"frames": 0, "after_ckpt": 0}

        def write(self, buffers):
            if point == "frame" and bytes(buffers[0][:4]) == b"FRAM":
                seen["frames"] += 1
                if seen["frames"] == 9:
                    flat = b"".join(bytes(b) for b in buffers)
                    os.pwrite(self.fd, flat[: len(flat) // 2], self.size)
                    _die()
            if point == "history" and Path(runner.store.checkpoint_path(out)).exists():
                seen["after_ckpt"] += 1
                if seen["after_ckpt"] == 2:
                    flat = b"".join(bytes(b) for b in buffers)
                    os.pwrite(self.fd, flat[: max(1, len(flat) // 2)], self.size)
                    _die()
            return real(self, buffers)
        framelog.LogWriter._write = write
    elif point == "checkpoint":
        real_create = h5py.Group.create_dataset
        real_ckpt = writer.RunWriter.checkpoint
        seen = {"tilt": 0}

        def dying(group, name, *a, **kw):
            d = real_create(group, name, *a, **kw)
            group.file.flush()  # the first array on disk, the file not closed
            _die()
            return d

        def checkpoint(self, state):
            if state["scalars"].get("phase") == "tilt":
                seen["tilt"] += 1
                if seen["tilt"] == 4:
                    h5py.Group.create_dataset = dying
            return real_ckpt(self, state)
        writer.RunWriter.checkpoint = checkpoint
    elif point == "build":
        real_append = writer._Builder.append

        def append(self, frame):
            if self.n_frames == 7:
                for name in ("step", "time"):
                    ds = self._d(f"frames/{name}")
                    ds.resize((8,))
                    ds[7] = frame[name]
                for name in ("position", "velocity"):
                    ds = self._d(f"frames/{name}")
                    ds.resize((8, *ds.shape[1:]))
                    ds[7] = frame[name]
                self.f.flush()
                _die()
            return real_append(self, frame)
        writer._Builder.append = append
    elif point == "rename":
        real_replace = os.replace

        def replace(src, dst):
            if Path(dst) == Path(out):
                _die()
            return real_replace(src, dst)
        writer.os.replace = replace
    elif point == "legacy":
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import legacy_writer

        real_append = legacy_writer.RunWriter.append

        def append(self, frame):
            if self.n_frames == 9:
                k = self.n_frames
                for name in ("step", "time", "theta_deg"):
                    ds = self._d(f"frames/{name}")
                    ds.resize((k + 1,))
                    ds[k] = getattr(frame, name)
                ds = self._d("frames/position")
                ds.resize((k + 1, *ds.shape[1:]))
                ds[k] = frame.position
                _die()
            return real_append(self, frame)
        legacy_writer.RunWriter.append = append
        runner.RunWriter = legacy_writer.RunWriter
    else:
        raise SystemExit(f"unknown point {point!r}")
    runner.simulate(cfg, 2, out, progress=False, resume=False)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3:])
