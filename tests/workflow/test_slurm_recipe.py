"""The SLURM array recipe (docs/slurm.md, examples/slurm/) run here, without SLURM, on tiny runs.

``run_seed.sh`` is what every array task runs: as task 3 of an array it writes the run file of seed 3,
the same bit for bit as the run ``tiltpile ensemble`` makes of that seed, and done again it does
nothing; ``finish.sbatch`` (plain bash under its #SBATCH lines) then verifies the runs and writes
their records. ``ensemble.sbatch`` is an array of the paper preset's 50 seeds calling
``run_seed.sh``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RECIPE = ROOT / "examples" / "slurm"
TINY = "scene.n=60 scene.box_length=10.0 protocol.theta_max_deg=1.0"


def _env(**kw) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("SLURM_")}
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".venv" / "numba-cache"))
    env["TILTPILE"] = f"{sys.executable} -m tiltpile"
    env.update({k: str(v) for k, v in kw.items()})
    return env


def _bash(script: Path, **env) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(script)], env=_env(**env), capture_output=True, text=True,
                          timeout=600)


def test_a_task_runs_its_seed_resumably_and_the_records_follow(tmp_path):
    from tiltpile import config
    from tiltpile.runner import simulate
    from tiltpile.store import open_run

    out = tmp_path / "runs"
    r = _bash(RECIPE / "run_seed.sh", PRESET="smoke", SET=TINY, OUT=out, SLURM_ARRAY_TASK_ID=3)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.splitlines()[-1])["seed"] == 3
    run = out / "run_0003.h5"
    stamp = run.stat().st_mtime_ns

    again = _bash(RECIPE / "run_seed.sh", PRESET="smoke", SET=TINY, OUT=out, SEED=3)
    assert again.returncode == 0 and "is finished" in again.stdout
    assert run.stat().st_mtime_ns == stamp

    # the same run as the ensemble's of seed 3
    cfg = config.load("smoke", overrides=TINY.split())
    simulate(cfg, 3, tmp_path / "ref.h5", progress=False)
    with open_run(run) as a, open_run(tmp_path / "ref.h5") as b:
        assert a.config_hash == b.config_hash and a.frames_digest() == b.frames_digest()

    done = _bash(RECIPE / "finish.sbatch", OUT=out)
    assert done.returncode == 0, done.stderr
    assert (out / "records" / "run_0003.npz").stat().st_size > 0


def test_a_task_without_preset_or_seed_stops_naming_it(tmp_path):
    r = _bash(RECIPE / "run_seed.sh", OUT=tmp_path, SEED=1)
    assert r.returncode != 0 and "PRESET" in r.stderr
    r = _bash(RECIPE / "run_seed.sh", PRESET="smoke", OUT=tmp_path)
    assert r.returncode != 0 and "SEED" in r.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("line", ["#SBATCH --array=0-49", "#SBATCH --cpus-per-task=1",
                                  "#SBATCH --requeue", 'PRESET=${PRESET:-paper}',
                                  "examples/slurm/run_seed.sh"])
def test_the_array_is_the_paper_ensemble(line):
    assert line in (RECIPE / "ensemble.sbatch").read_text()


def test_the_array_script_runs_the_task_script(tmp_path):
    """ensemble.sbatch as SLURM would start it for task 5, from the checkout (a tiny smoke run)."""
    out = tmp_path / "runs"
    r = subprocess.run(["bash", str(RECIPE / "ensemble.sbatch")], cwd=ROOT, capture_output=True,
                       text=True, timeout=600,
                       env=_env(PRESET="smoke", SET=TINY, OUT=out, SLURM_ARRAY_TASK_ID=5,
                                SLURM_SUBMIT_DIR=ROOT))
    assert r.returncode == 0, r.stderr
    assert (out / "run_0005.h5").exists()
