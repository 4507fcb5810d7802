"""How often a SIGKILL leaves a run resumable: kill one run at random moments.

Usage: python -m benchmarks.kill_resume [N] [--pattern smoke|paper] [--min-frames K]
                                            [--max-delay S] [--seed R]
                                            [--preset P] [--set section.key=value ...]
  N             kills (default 50)
  --pattern     smoke (default): ``tiltpile simulate`` of the run below; paper: the paper
                preset's write pattern without its simulation (``paper_pattern``): 4120 grains
                (4000 and the bottom row), 6185 contacts a frame, a 1.07 MB checkpoint every 20
                frames, 481 frames, written back to back by the real writer, so that a kill
                lands in a write nearly always
  --min-frames  wait until the run's checkpoint follows at least K frames (default 1) ...
  --max-delay   ... then kill after a uniform random delay in [0, S] seconds (default 0.6;
                pattern paper: 4)
  --seed        seed of the random delays (default 0); the run is always seed 0
  --preset/--set the run of pattern smoke (default: smoke with 60 grains in a 10 d box, tilted
                to 2 deg, a frame every 2 steps and a checkpoint every 5 frames: ~100 frames, a
                second or two)

Each kill runs the writer in a process of its own, in a new temporary directory, and SIGKILLs
the process group; then asks ``RunWriter.resume`` (what a rerun does) whether the ``.part`` can
be resumed, and why not. Outcomes: ``resumable``, ``finished`` (the run ended before the kill)
or ``refused: <reason>``. A refused ``.part`` is not a wrong result (the rerun starts afresh and
says why, ``discarded`` in its summary), but the work up to the kill is lost. Before the frame
log (``store.framelog``) a kill in the middle of an HDF5 write of the ``.part`` left it
unreadable; now the ``.part`` is only ever appended to, and the run file is built from it at
the end under another name.

notes/performance-log.md ("The paper ensemble landed at forty runs; kills mid-write") records what
the HDF5 ``.part`` measured; docs/faults.md what the frame log does.
"""
from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

SMALL = ["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=2.0", "protocol.frame_every=2",
         "protocol.checkpoint_every=5"]

_CHILD = ("import sys; from tiltpile import config; from tiltpile.runner import simulate; "
          "cfg = config.load(sys.argv[1], overrides=sys.argv[3:]); "
          "simulate(cfg, 0, sys.argv[2], progress=False, resume=False)")
_PAPER_CHILD = ("import sys; from benchmarks.kill_resume import paper_pattern; "
                "paper_pattern(sys.argv[1], int(sys.argv[2]))")

# The paper preset's write pattern (measured on the paper runs): grains with the bottom row,
# contacts per frame (a record's picture frames), frames of a run to its slide, frames between
# checkpoints, and the checkpoint's arrays (a paper run's NAME.ckpt: 1.07 MB)
PAPER = dict(n=4120, contacts=6185, frames=481, checkpoint_every=20, candidates=9026)
PAPER_HASH = "paper write pattern, no simulation"


class _Frame:
    """A frame of the paper pattern (``protocol.Frame``'s fields); arrays shared, scalars its own."""

    def __init__(self, k: int, arrays: dict):
        self.__dict__.update(arrays)
        self.step, self.time, self.theta_deg = 50 * k, 0.5 * k, 0.05 * k
        self.iterations, self.residual, self.ke = 1000, 1e-6, 1e-3
        self.max_overlap, self.max_iterations, self.cap_hits = 1e-4, 1000, k % 50
        self.missed, self.energy_gain = 0, -1e-9


def paper_pattern(out, frames: int | None = None) -> None:
    """Write run file ``out`` with the paper preset's write pattern (``PAPER``) through
    ``store.RunWriter``, no simulation: deposition, ten history checkpoints, then the frames with
    a checkpoint every 20, the end, the health record and the final file. Deterministic: every
    frame and state is a function of its index only. ``frames`` (default ``PAPER["frames"]``)."""
    import numpy as np

    from tiltpile.store import RunWriter

    p = PAPER
    n, m, c = p["n"], p["contacts"], p["candidates"]
    frames = p["frames"] if frames is None else int(frames)
    rng = np.random.default_rng(0)
    radius = rng.uniform(0.4, 0.6, n)
    fixed = np.arange(n) < 120
    arrays = dict(position=rng.uniform(0, 120, (n, 2)), velocity=rng.normal(0, 1e-3, (n, 2)),
                  rotation=rng.normal(0, 1, n), omega=rng.normal(0, 1e-3, n),
                  pair=rng.integers(0, n, (m, 2)).astype(np.int32), force=rng.uniform(0, 1, (m, 2)),
                  status=rng.integers(0, 3, m).astype(np.int8))
    state = dict(c=rng.normal(size=(c, 8)), ci=rng.integers(0, n, c).astype(np.int32),
                 cj=rng.integers(0, n, c).astype(np.int32), fixed=fixed,
                 key=rng.integers(0, 2**40, c), pos=arrays["position"], radius=radius,
                 ref=arrays["position"], rng=np.array([7], np.uint64), rot=arrays["rotation"],
                 status=arrays["status"][:1].repeat(c), vel=rng.normal(size=(n + 3, 4)))
    w = RunWriter(out, config_json="{}", config_hash=PAPER_HASH, seed=0, radius=radius, fixed=fixed,
                  box_length=120.0, jit={})
    try:
        w.write_deposition(type("D", (), dict(steps=60000, time=600.0, ke_per_grain=1e-9,
                                              height=36.0, max_overlap=1e-4, missed=0))())
        for leg in range(10):
            w.checkpoint({**state, "scalars": {"phase": "pretilt", "leg": leg}})
        w.write_preparation([dict(target_deg=16.0, tilt_steps=16000, hold_steps=500, ke_per_grain=1e-9)])
        for k in range(frames):
            w.append(_Frame(k, arrays))
            if k % p["checkpoint_every"] == 0 or k == frames - 1:
                w.checkpoint({**state, "scalars": {"phase": "tilt", "frame": k}})
        w.write_end(type("E", (), dict(reason="slide", theta_deg=24.0, steps=190000, sweeps=9.6e7,
                                       capped_steps=80000))())
        w.write_health({"warnings": [], "cap_hits": 0})
        w.write_timing(0.0, None)
        w.finish()
    except BaseException:
        w.close()
        raise


def _checkpoint_frames(ckpt: Path) -> int:
    import h5py

    try:
        with h5py.File(ckpt, "r", locking=False) as g:  # replaced atomically: never half-written
            return int(g.attrs["n_frames"])
    except (OSError, KeyError):
        return -1


def kill_once(preset: str, overrides: list[str], min_frames: int, delay: float, work: Path,
              pattern: str = "smoke", frames: int = PAPER["frames"]) -> str:
    """Start the run in ``work`` (``pattern`` smoke: ``preset`` with ``overrides``; paper:
    ``paper_pattern`` with ``frames`` frames), SIGKILL it ``delay`` s after its checkpoint follows ``min_frames``
    frames, and say what a rerun would find."""
    from tiltpile import config
    from tiltpile.store.files import checkpoint_path
    from tiltpile.store.writer import RunWriter

    out = work / "run_0000.h5"
    if pattern == "paper":
        config_hash = PAPER_HASH
        argv = [sys.executable, "-c", _PAPER_CHILD, str(out), str(frames)]
    else:
        config_hash = config.load(preset, overrides=overrides).hash()
        argv = [sys.executable, "-c", _CHILD, preset, str(out), *overrides]
    # the child imports this package: the repository's root (benchmarks/'s parent) on its path
    root = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [root] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])}
    proc = subprocess.Popen(argv, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=env)
    try:
        while proc.poll() is None and _checkpoint_frames(checkpoint_path(out)) < min_frames:
            time.sleep(0.002)
        time.sleep(delay)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        err = proc.stderr.read().decode(errors="replace").strip()
        proc.stderr.close()
    if out.exists():
        return "finished"
    if proc.returncode != -signal.SIGKILL:
        raise RuntimeError(f"the run failed before it was killed: {err.splitlines()[-1] if err else proc.returncode}")
    why: list[str] = []
    resumed = RunWriter.resume(out, config_hash, why=why)
    if resumed is None:
        return f"refused: {why[0] if why else 'nothing to resume'}"
    resumed[0].close()
    return "resumable"


def study(n: int, preset: str = "smoke", overrides=None, min_frames: int = 1, max_delay: float = 0.6,
          seed: int = 0, progress: bool = True, pattern: str = "smoke",
          frames: int = PAPER["frames"]) -> Counter:
    """Counts of the outcomes of ``n`` kills (:func:`kill_once`)."""
    if pattern not in ("smoke", "paper"):
        raise ValueError(f"--pattern must be smoke or paper, got {pattern!r}")
    if n < 1:
        raise ValueError(f"N must be >= 1, got {n}")
    if frames < 1:
        raise ValueError(f"--frames must be >= 1, got {frames}")
    if max_delay < 0:
        raise ValueError(f"--max-delay must be >= 0, got {max_delay}")
    overrides = SMALL if overrides is None else list(overrides)
    rng = random.Random(seed)
    counts: Counter = Counter()
    for i in range(n):
        with tempfile.TemporaryDirectory(prefix="kill_resume.") as d:
            counts[kill_once(preset, overrides, min_frames, rng.uniform(0.0, max_delay), Path(d),
                             pattern, frames)] += 1
        if progress:
            print(f"\r{i + 1}/{n} kills: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())),
                  end="", file=sys.stderr, flush=True)
    if progress:
        print(file=sys.stderr)
    return counts


def main(argv=None) -> Counter:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.kill_resume", description=__doc__.splitlines()[0])
    ap.add_argument("n", nargs="?", type=int, default=50, help="kills (default 50)")
    ap.add_argument("--min-frames", type=int, default=1)
    ap.add_argument("--max-delay", type=float, default=None)
    ap.add_argument("--pattern", default="smoke")
    ap.add_argument("--frames", type=int, default=PAPER["frames"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--preset", default="smoke")
    ap.add_argument("--set", action="append", default=None, metavar="section.key=value")
    a = ap.parse_args(argv)
    overrides = SMALL if a.set is None else a.set
    if a.max_delay is None:
        a.max_delay = 4.0 if a.pattern == "paper" else 0.6
    try:  # bad N, delay or settings (ConfigError is a ValueError) stop before the first run starts
        counts = study(a.n, a.preset, overrides, a.min_frames, a.max_delay, a.seed, progress=True,
                       pattern=a.pattern, frames=a.frames)
    except ValueError as e:
        ap.exit(2, f"kill_resume: {e}\n")
    killed = a.n - counts["finished"]
    what = f"the paper write pattern ({a.frames} frames)" if a.pattern == "paper" else f"{a.preset} {' '.join(overrides)}"
    print(f"{a.n} kills of {what} (checkpoint >= {a.min_frames} frames, "
          f"then 0-{a.max_delay:g} s): " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    if killed:
        print(f"refused {killed - counts['resumable']} of the {killed} killed before their end")
    return counts


if __name__ == "__main__":
    main(sys.argv[1:])
