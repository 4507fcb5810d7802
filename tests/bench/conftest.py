"""Fixtures of the bench studies' tests."""

from __future__ import annotations

import pytest

from tiltpile import config
from tiltpile.bench.flow_caps import rebuilt_state
from tiltpile.runner import simulate

TINY_CAP = 40  # the tiny run's solver.max_iter: most of its tilt steps stop there


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """A 60-grain smoke run tilted to 3 deg at solver.max_iter TINY_CAP, tol 1e-7 (so that its
    steps meet the cap), simulated once per session."""
    path = tmp_path_factory.mktemp("tiny") / "run.h5"
    cfg = config.load("smoke", overrides=["scene.n=60", "scene.box_length=10.0",
                                          "protocol.theta_max_deg=3.0", f"solver.max_iter={TINY_CAP}",
                                          "solver.tol=1e-7"])
    simulate(cfg, 1, path, progress=False)
    return path


@pytest.fixture(scope="session")
def tiny_state(tiny_run):
    """(config, seed, theta, state) of frame 20 of the tiny run, impulses rebuilt (2 steps)."""
    return rebuilt_state(tiny_run, 20, 2)
