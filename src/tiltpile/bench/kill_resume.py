"""How often a SIGKILL leaves a run resumable: kill one ``tiltpile simulate`` at random moments.

Usage: python -m tiltpile.bench.kill_resume [N] [--min-frames K] [--max-delay S] [--seed R]
                                            [--preset P] [--set section.key=value ...]
  N             kills (default 50)
  --min-frames  wait until the run's checkpoint follows at least K frames (default 1) ...
  --max-delay   ... then kill after a uniform random delay in [0, S] seconds (default 0.6)
  --seed        seed of the random delays (default 0); the run is always seed 0
  --preset/--set the run (default: smoke with 60 grains in a 10 d box, tilted to 2 deg, a frame
                every 2 steps and a checkpoint every 5 frames: ~100 frames, a second or two)

Each kill runs the simulation in a process of its own, in a new temporary directory, and
SIGKILLs the process group; then asks ``RunWriter.resume`` (what a rerun does) whether the
``.part`` can be resumed, and why not. Outcomes: ``resumable``, ``finished`` (the run ended
before the kill) or ``refused: <reason>``. A refused ``.part`` is not a wrong result (the rerun
starts afresh and says why, ``discarded`` in its summary), but the work up to the kill is lost.
HDF5 does not keep a file readable through a kill in the middle of its own writes, so the
refused share estimates the share of a run's time spent writing its ``.part``.

docs/performance-log.md ("The paper ensemble landed at forty runs; kills mid-write") records what it
measured.
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


def _checkpoint_frames(ckpt: Path) -> int:
    import h5py

    try:
        with h5py.File(ckpt, "r", locking=False) as g:  # replaced atomically: never half-written
            return int(g.attrs["n_frames"])
    except (OSError, KeyError):
        return -1


def kill_once(preset: str, overrides: list[str], min_frames: int, delay: float, work: Path) -> str:
    """Start the run in ``work``, SIGKILL it ``delay`` s after its checkpoint follows
    ``min_frames`` frames, and say what a rerun would find."""
    from tiltpile import config
    from tiltpile.store.files import checkpoint_path
    from tiltpile.store.writer import RunWriter

    cfg = config.load(preset, overrides=overrides)
    out = work / "run_0000.h5"
    proc = subprocess.Popen([sys.executable, "-c", _CHILD, preset, str(out), *overrides],
                            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
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
    resumed = RunWriter.resume(out, cfg.hash(), why=why)
    if resumed is None:
        return f"refused: {why[0] if why else 'nothing to resume'}"
    resumed[0].close()
    return "resumable"


def study(n: int, preset: str = "smoke", overrides=None, min_frames: int = 1, max_delay: float = 0.6,
          seed: int = 0, progress: bool = True) -> Counter:
    """Counts of the outcomes of ``n`` kills (:func:`kill_once`)."""
    if n < 1:
        raise ValueError(f"N must be >= 1, got {n}")
    if max_delay < 0:
        raise ValueError(f"--max-delay must be >= 0, got {max_delay}")
    overrides = SMALL if overrides is None else list(overrides)
    rng = random.Random(seed)
    counts: Counter = Counter()
    for i in range(n):
        with tempfile.TemporaryDirectory(prefix="kill_resume.") as d:
            counts[kill_once(preset, overrides, min_frames, rng.uniform(0.0, max_delay), Path(d))] += 1
        if progress:
            print(f"\r{i + 1}/{n} kills: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())),
                  end="", file=sys.stderr, flush=True)
    if progress:
        print(file=sys.stderr)
    return counts


def main(argv=None) -> Counter:
    ap = argparse.ArgumentParser(prog="python -m tiltpile.bench.kill_resume", description=__doc__.splitlines()[0])
    ap.add_argument("n", nargs="?", type=int, default=50, help="kills (default 50)")
    ap.add_argument("--min-frames", type=int, default=1)
    ap.add_argument("--max-delay", type=float, default=0.6)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--preset", default="smoke")
    ap.add_argument("--set", action="append", default=None, metavar="section.key=value")
    a = ap.parse_args(argv)
    overrides = SMALL if a.set is None else a.set
    try:  # bad N, delay or settings (ConfigError is a ValueError) stop before the first run starts
        counts = study(a.n, a.preset, overrides, a.min_frames, a.max_delay, a.seed, progress=True)
    except ValueError as e:
        ap.exit(2, f"kill_resume: {e}\n")
    killed = a.n - counts["finished"]
    print(f"{a.n} kills of {a.preset} {' '.join(overrides)} (checkpoint >= {a.min_frames} frames, "
          f"then 0-{a.max_delay:g} s): " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    if killed:
        print(f"refused {killed - counts['resumable']} of the {killed} killed before their end")
    return counts


if __name__ == "__main__":
    main(sys.argv[1:])
