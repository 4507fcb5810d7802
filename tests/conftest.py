"""Shared fixtures: one settled smoke pile per session (see simhelpers for hand-built cases)."""

from __future__ import annotations

import pytest

from tiltpile import config
from tiltpile.sim import protocol


@pytest.fixture(scope="session")
def smoke_config():
    """The smoke preset, as the figure notebooks run it."""
    return config.load("smoke")


@pytest.fixture(scope="session")
def settled_pile(smoke_config):
    """A deposited smoke pile (System) at theta = 0, computed once per session."""
    return protocol.deposited(smoke_config, seed=3)
