"""Shared fixtures: one settled smoke pile per session (see simhelpers for hand-built cases)."""

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
