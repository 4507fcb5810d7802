"""Shared fixtures: one settled smoke pile, one smoke run and one smoke ensemble per session (see
simhelpers for hand-built cases); each is built once, and only when a test asks for it."""

from __future__ import annotations

import pytest

from tiltpile import config
from tiltpile.runner import simulate
from tiltpile.sim import protocol


@pytest.fixture(scope="session")
def smoke_config():
    """The smoke preset, as the figure notebooks run it."""
    return config.load("smoke")


@pytest.fixture(scope="session")
def settled_pile(smoke_config):
    """A deposited smoke pile (System) at theta = 0, computed once per session."""
    return protocol.deposited(smoke_config, seed=3)


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory, smoke_config):
    """The smoke run of seed 1 (file path, summary), simulated once per session."""
    out = tmp_path_factory.mktemp("smoke") / "run_0001.h5"
    summary = simulate(smoke_config, 1, out, progress=False)
    return out, summary


SMOKE_SEEDS = [1, 2, 3]


@pytest.fixture(scope="session")
def smoke_ensemble(tmp_path_factory):
    """Three smoke runs and their observables, as `make figures PRESET=smoke RUNS=3
    ENSEMBLE_ARGS="--first-seed 1"` makes them: shared by the notebook and record tests
    (tests/figures/) and the test of two builds at once (tests/workflow/test_two_builds.py)."""
    from tiltpile.analysis import compute_observables
    from tiltpile.ensemble import failed_runs, run_ensemble

    out = tmp_path_factory.mktemp("smoke_ensemble")
    manifest = run_ensemble(config.load("smoke"), SMOKE_SEEDS, out, workers=2, progress=False)
    assert failed_runs(manifest) == []
    compute_observables(out, workers=2, progress=False)
    return out
